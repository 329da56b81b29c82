"""Dataset generation, PointNet training and fingerprint-map building (the perception issue)."""
