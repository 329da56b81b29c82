"""Corner features: RANSAC planes of walls and ceilings intersected into corners, and the nearest-corner lookup."""
