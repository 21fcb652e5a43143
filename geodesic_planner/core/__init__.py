"""The maths: kinematics, the paper's metric, geodesics, IK, the planner (numpy + scipy, no ROS)."""
