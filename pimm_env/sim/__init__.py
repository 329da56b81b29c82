"""The simulated robot and its sensors: diff-drive kinematics and odometry, LiDAR patterns, ray casting."""
