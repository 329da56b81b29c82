"""ROS 2 without a ROS 2 install: its messages on the DDS wire (``messages``), a domain with ROS 2's QoS
(``domain``), the graph entry that makes a process a ROS 2 node (``graph``), and the simulator as a ROS 2 robot
(``sim_robot``)."""
