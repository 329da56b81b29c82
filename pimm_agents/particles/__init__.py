"""Particle-filter parts shared by the localizers: resampling, KLD sampling, pose clusters, free space,
odometry motion model."""
