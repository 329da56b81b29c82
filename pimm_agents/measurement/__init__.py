"""Measuring the parts: stage timings (``evaluate.py bench``), perception quality and corner-detector quality."""
