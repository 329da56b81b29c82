"""One 3D scan from any LiDAR or file: levelled on its floor, segmented, its corners found (``segment.py``)."""
