"""Trusted-side geometry for the figures: a plain linear triangulation (to place the candidates of
Q3.3 and the truths of Q6), nothing a student's answer is judged by.

C (3, 4) projection matrices K [R | t]; pixels (x, y) = (column, row); points (N, 3) world.
"""

from __future__ import annotations

import numpy as np

__all__ = ["triangulate_views"]


def triangulate_views(Cs, pts) -> np.ndarray:
    """(N, 3) points from V views: Cs a sequence of V (3, 4) cameras, pts V (N, 2) pixel arrays
    (rows of NaN: not seen in that view).  Linear (SVD of the stacked x C3 - C1, y C3 - C2 rows);
    NaN for a point seen in fewer than two views."""
    Cs = [np.asarray(C, float) for C in Cs]
    pts = [np.asarray(p, float) for p in pts]
    n = len(pts[0])
    out = np.full((n, 3), np.nan)
    for i in range(n):
        rows = []
        for C, p in zip(Cs, pts):
            x, y = p[i]
            if np.isfinite(x) and np.isfinite(y):
                rows += [x * C[2] - C[0], y * C[2] - C[1]]
        if len(rows) < 4:
            continue
        X = np.linalg.svd(np.array(rows))[2][-1]
        if X[3] != 0:
            out[i] = X[:3] / X[3]
    return out
