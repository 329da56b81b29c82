"""The thesis's published figures, printed and drawn beside ours: localization (tables 4.2-4.5), segmentation
(table 3.2) and retrieval (table 3.4)."""

from __future__ import annotations

#: Thesis tables 4.2-4.5: convergence rate, mean convergence time (s), position (m) and angle (deg) error.
THESIS_RESULTS: dict[str, dict[str, tuple[float, float | None, float | None, float | None]]] = {
    "area_a": {"amcl": (0.4, 55.93, 1.1, 1.08), "pimm": (1.0, 20.88, 0.84, 3.2)},
    "area_b": {"amcl": (1.0, 2.6, 0.30, 1.91), "pimm": (1.0, 4.53, 0.50, 7.65)},
    "a_c_b": {"amcl": (0.7, 12.54, 0.17, 1.46), "pimm": (1.0, 34.48, 0.89, 3.55)},
    "a_c_b_kidnap": {"amcl": (0.0, None, None, None), "pimm": (1.0, 7.33, 0.33, 2.16)},
}


#: Thesis table 3.2 (segmentation) and table 3.4 (retrieval, on its own training scans, k = 5).
THESIS_IOU = {"floor": 0.930, "ceiling": 0.648, "wall": 0.619, "clutter": 0.483, "mean": 0.69}


THESIS_RETRIEVAL = {
    "A": (1.69, 0.28, 3.54),
    "B": (1.06, 0.10, 2.49),
    "C": (2.88, 0.42, 6.14),
    "total": (1.87, 0.27, 4.01),
}
