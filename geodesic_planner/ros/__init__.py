"""ROS 2 layer: nodes and message conversions only (all maths lives in the library)."""
