"""Files in and out: YAML requests, rosbag2 bags (rosbags), plots."""
