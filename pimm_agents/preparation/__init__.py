"""Preparing a world for the localizers: derived maps, the fingerprint map made with the shipped network, and
generated routes (``evaluate.py world prepare``)."""
