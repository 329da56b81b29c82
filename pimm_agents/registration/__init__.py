"""A 3D global-registration localizer in the manner of hdl_global_localization: FPFH features of the scan
matched against a point cloud of the map, a ground robot's 4-DoF RANSAC over those matches, hypotheses scored
by ICP fitness, then scan-to-map ICP tracking from odometry, with a new global search when the fit fails."""
