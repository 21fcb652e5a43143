"""ROS-level tests: real nodes in subprocesses, real DDS (inside the loopback network namespace)."""
