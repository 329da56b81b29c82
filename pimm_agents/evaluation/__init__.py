"""Scoring localizers against the simulator's truth: the recording wrapper, trial logs, metrics,
trial runners, reports, benchmarks, and the quality of perception and corners."""
