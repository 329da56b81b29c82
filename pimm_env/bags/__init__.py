"""ROS 2 bags of the simulator's sensor streams: record a scenario, read a bag back as the env's observations."""
