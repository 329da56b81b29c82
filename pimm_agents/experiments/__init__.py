"""Running experiments: the recording wrapper, trials on worker processes or Ray, the trial store that makes a
run resumable, sweeps, bag replays, the run record that repeats a run, and ``Experiment``, which ties them up."""
