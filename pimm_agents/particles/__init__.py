"""Particle-filter parts shared by the localizers: resampling, KLD sampling, pose clusters, free space,
the likelihood-field scan model, the odometry motion model."""
