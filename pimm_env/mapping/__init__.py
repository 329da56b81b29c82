"""Maps derived from a world: the occupancy grid (ROS map_server format) and the corner map."""
