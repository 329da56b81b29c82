"""Importers: a ROS map_server map or a building mesh turned into a PIMM world file."""
