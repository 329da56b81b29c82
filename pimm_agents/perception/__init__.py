"""PIMM's perception: point features, the PointNet segmenter and descriptor, the fingerprint map."""
