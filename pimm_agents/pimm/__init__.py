"""PIMM: the particle filter over corners and fingerprint suggestions, and the localizer around it."""
