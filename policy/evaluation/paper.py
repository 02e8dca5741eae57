"""The paper's Table I, verbatim, for side-by-side comparison. None where the paper has '-'.
Columns: (a) loop %, (b) >1 loops %, (c) >100 moves %, (d) optimal %, (e) <10 difference %,
(f) t > t_e %, (g) recovery rate mean, sd, (h) 10-fold CV accuracy mean, sd."""

from __future__ import annotations

COLUMNS = ("loop_pct", "multi_loop_pct", "over_100_pct", "optimal_pct", "diff_lt_10_pct",
           "timeout_pct", "recovery_rate_mean", "recovery_rate_sd", "cv_acc_mean", "cv_acc_sd")

_ROWS = {
    "NS": (None, None, 8.13, 0.34, 5.96, 0, 0.260, 0.113, None, None),
    "DRQN": (None, None, 58.09, 0.02, 2.18, 45.56, 0.237, 0.092, None, None),
    "SSN (PT)": (56.31, 63.16, 23.52, 0.66, 3.89, 0.01, 0.217, 0.112, 68.95, 0.256),
    "Random (CU)": (37.49, 53.01, 9.64, 2.21, 13.76, 0, 0.262, 0.113, 67.84, 0.237),
    "Random (PT)": (32.45, 46.78, 7.57, 2.85, 15.72, 0, 0.265, 0.114, 71.15, 0.233),
    "Fixed Grid": (0.94, 100, 0.76, 99.06, 99.06, 0.63, 0.337, 0.054, 91.47, 0.696),
    "Equidistant": (54, 82.01, 19.63, 21.78, 45.75, 0.91, 0.333, 0.109, 83.66, 0.182),
    "Gaussian": (24.46, 30.17, 0.58, 39.99, 78.61, 0.07, 0.616, 0.143, 75.81, 0.515),
    "Random (+S)": (36.73, 44.94, 6.88, 6.53, 35.72, 0.164, 0.289, 0.109, 73.97, 0.175),
    "Random (+M)": (70.16, 78.9, 25.55, 2.08, 12.67, 0.59, 0.261, 0.115, 70.17, 0.276),
    "Equidistant (+M)": (47.59, 74.79, 7.41, 30.25, 60.87, 0.16, 0.380, 0.085, 84.99, 0.224),
    "Gaussian (+M)": (23.52, 63.6, 3.28, 45.46, 78.28, 0.15, 0.622, 0.141, 77.30, 0.429),
    "Random Walk": (None, None, 79.17, 0.08, 0.93, 12.23, 0.155, 0.176, 60.91, 0.418),
    "Herd Walk": (None, None, 77.18, 0.88, 3.18, 21.39, 0.225, 0.128, 62.33, 0.273),
    "Herd Walk (+S)": (None, None, 61.35, 0.12, 2.90, 5.67, 0.203, 0.098, 63.26, 0.181),
}

PAPER_TABLE1: dict[str, dict[str, float | None]] = {
    row: dict(zip(COLUMNS, vals, strict=True)) for row, vals in _ROWS.items()
}
