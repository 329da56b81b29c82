"""Driving the robot: named scenarios, a pure-pursuit controller, rollouts and their figures."""
