"""Scoring: pure computation on trials (the thesis's metrics, APE/RPE, log faults, per-scenario summaries).
Nothing here reads or writes files or draws; ``results`` does that, ``experiments`` produces the trials."""
