"""What the public checks and figures compare a student's answer with, computed with working answers.

The self-checks and the figures run in the student's kernel, where everything they import can be
read and called, so no code that ships computes a graded answer (tests/repository/test_behaviour_leaks.py
calls every shipped callable to prove it).  What they need is computed here, on the grader's side:

- for the public data, by ``python -m kit check-data``, which commits it beside the checks
  (starter/checks/figure_data.json, residual_case.json; tests prove the files fresh);
- for the hidden scenes, by the hidden cases (autograder.inputs.bundle).

Conventions: C (3, 4) = K [R | t] maps world (camera-1) coordinates to pixels (x, y) = (column,
row); M = [R | t].
"""

from __future__ import annotations

import numpy as np

from core.geometry import IDENTITY_POSE, depths
from judging.bundle import ResidualCase, misreadings

from .bundle import rodriguesResidual

__all__ = ["candidate_points", "linear_points", "residual_case", "rule_points"]


def residual_case(K1, M1, p1, K2, p2, x) -> ResidualCase:
    """The input (K1, M1, p1, K2, p2, x) of rodriguesResidual with the handout's residuals (4N,) at x
    and at x misread in each way judging.bundle.misreadings names (for the x_packing mistake)."""
    args = tuple(np.array(a, float) for a in (K1, M1, p1, K2, p2, x))
    n = len(args[2])
    misread = {order: rodriguesResidual(*args[:5], x_read) for order, x_read in misreadings(args[5], n).items()}
    return ResidualCase(args, rodriguesResidual(*args), misread)


def linear_points(Cs, pts) -> np.ndarray:
    """(N, 3) points from V views: Cs V cameras (3, 4), pts V (N, 2) pixel arrays (a row of NaN: not
    seen in that view).  Linear: the right singular vector of the stacked rows x C[2] - C[0],
    y C[2] - C[1] with the smallest singular value.  NaN for a point seen in fewer than two views."""
    Cs = [np.asarray(C, float) for C in Cs]
    pts = [np.asarray(p, float) for p in pts]
    out = np.full((len(pts[0]), 3), np.nan)
    for i in range(len(out)):
        rows = [r for C, p in zip(Cs, pts) if np.all(np.isfinite(p[i]))
                for r in (p[i, 0] * C[2] - C[0], p[i, 1] * C[2] - C[1])]
        if len(rows) < 4:
            continue
        X = np.linalg.svd(np.array(rows))[2][-1]
        if X[3] != 0:
            out[i] = X[:3] / X[3]
    return out


def candidate_points(F, pts1, pts2, K1, K2) -> list[dict[str, np.ndarray]]:
    """Q3.3's figure: for each of the four candidates of starter.camera2(K2^T F K1), in its order, the
    matches triangulated linearly under it: "x", "z" (N,) the points' x and z (camera-1
    coordinates; NaN where the triangulation has none), "front1", "front2" (N,) 1.0 where the point
    is in front of camera 1 or of the candidate camera 2, else 0.0."""
    from starter.pose import camera2

    K1, K2 = np.asarray(K1, float), np.asarray(K2, float)
    cands = camera2(K2.T @ np.asarray(F, float) @ K1)
    M1 = IDENTITY_POSE
    out = []
    for k in range(cands.shape[2]):
        X = linear_points([K1 @ M1, K2 @ cands[:, :, k]], [pts1, pts2])
        with np.errstate(invalid="ignore"):
            z1 = np.nan_to_num(depths(M1, X), nan=-1.0)
            z2 = np.nan_to_num(depths(cands[:, :, k], X), nan=-1.0)
        out.append({"x": X[:, 0], "z": X[:, 2], "front1": (z1 > 0).astype(float), "front2": (z2 > 0).astype(float)})
    return out


def rule_points(Cs, pts, Thres) -> dict[str, np.ndarray]:
    """Q6's figure: rule name (starter.checks.pictures.q6_multiview.RULES) -> (N, 3) linear
    triangulation of the detections the rule keeps (NaN: kept in fewer than two views).

    Cs: three (3, 4) cameras; pts: three (N, 3) detections [x, y, confidence]."""
    from starter.checks.pictures.q6_multiview import RULES

    keeps = (lambda c: c > Thres, lambda c: c >= Thres, lambda c: np.ones_like(c, bool))
    out = {}
    for rule, keep in zip(RULES, keeps):
        views = [np.where(keep(np.asarray(p, float)[:, 2])[:, None], np.asarray(p, float)[:, :2], np.nan) for p in pts]
        out[rule] = linear_points(Cs, views)
    return out
