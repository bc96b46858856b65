"""Q2, ``eightpoint(pts1, pts2, M) -> F``: is F the fundamental matrix of the matches?

F is defined up to scale and sign and several methods are right (refineF or not, 1/M or
Hartley scaling), so F is never compared entry by entry: every distance is the symmetric
epipolar distance of core.geometry (x2 to the line F x1 and x1 to the line F^T x2, pixels).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from .mistakes import epipolar_statistic, fundamental_mistakes, rank2_not_enforced, uint16_wraparound
from .verdict import Verdict, fmt, read_array

__all__ = ["EXACT_TOL", "RANK_RTOL", "exact_fit", "fit", "fit_goal", "rank_two", "read_F", "uint16_same"]

EXACT_TOL = 1e-4      # noise-free matches: every distance below EXACT_TOL * M pixels (0.064 px at M = 640)
RANK_RTOL = 1e-6      # s3 / s2 of F in the 1/M coordinates
SAME_RTOL = 1e-6      # uint16 and float points: the same F up to scale


def read_F(value) -> np.ndarray:
    """F (3, 3) from a returned value, or Malformed."""
    return read_array(value, (3, 3), "F")


def _usable(F) -> bool:
    return F.shape == (3, 3) and bool(np.all(np.isfinite(F))) and bool(np.any(F))


def exact_fit(F, pts1, pts2, M) -> Verdict:
    """Noise-free matches pts1, pts2 (N, 2) lie on F's epipolar lines: max distance <= EXACT_TOL * M.

    This is the sharp test of F (a noise-free scene has one F up to scale); the catalogue then
    names the mistake (transposed, not unscaled, unscaled the wrong way, x/y swapped) whose
    undoing makes F fit.
    """
    what = "noise-free matches lie on their epipolar lines"
    F = np.asarray(F, float)
    tol = EXACT_TOL * float(M)
    d = epipolar_statistic(F, pts1, pts2, "max") if _usable(F) else np.inf
    ok = d <= tol
    found = () if ok else fundamental_mistakes(F, pts1, pts2, M, tol, statistic="max")
    return Verdict.of(what, ok, f"largest distance {fmt(d)} px", f"<= {fmt(tol)} px", found)


def fit_goal(valid_rms: Iterable[float]) -> float:
    """The goal (pixels) of :func:`fit` from the RMS distances valid methods reach on the same data."""
    worst = max(float(v) for v in valid_rms)
    return 1.5 * worst + 0.25


def fit(F, eval1, eval2, goal_px: float, M) -> Verdict:
    """The matches eval1, eval2 (P, 2) (true ones when known) are near F's lines: RMS distance <= goal_px.

    ``goal_px`` comes from :func:`fit_goal` (the noise of the data through valid methods).
    A known mistake is named when undoing it brings the RMS distance under the goal.
    """
    what = "matches near their epipolar lines"
    F = np.asarray(F, float)
    rms = epipolar_statistic(F, eval1, eval2, "rms") if _usable(F) else np.inf
    ok = rms <= goal_px
    found = () if ok else fundamental_mistakes(F, eval1, eval2, M, goal_px, statistic="rms")
    return Verdict.of(what, ok, f"RMS distance {fmt(rms)} px", f"<= {fmt(goal_px)} px", found)


def rank_two(F, M) -> Verdict:
    """F has rank 2: s3/s2 of diag(M, M, 1) F diag(M, M, 1) <= RANK_RTOL, and s2 > 0 (rank not below 2)."""
    what = "F has rank 2"
    F = np.asarray(F, float)
    if not _usable(F):
        return Verdict.of(what, False, "F is zero or not finite", f"s3/s2 <= {RANK_RTOL:g}")
    S = np.diag([float(M), float(M), 1.0])
    s = np.linalg.svd(S @ F @ S, compute_uv=False)
    if not s[1] > 1e-12 * s[0]:
        return Verdict.of(what, False, "rank below 2", f"s3/s2 <= {RANK_RTOL:g}")
    ratio = s[2] / s[1]
    return Verdict.of(what, ratio <= RANK_RTOL, f"s3/s2 = {fmt(ratio)}", f"<= {RANK_RTOL:g}",
                      [rank2_not_enforced(F, M, RANK_RTOL)])


def uint16_same(F_uint16, F_float) -> Verdict:
    """The same points as uint16 (the data files' dtype) and as float64 give the same F (up to scale)."""
    what = "uint16 points give the same F as float points"
    A, B = np.asarray(F_uint16, float), np.asarray(F_float, float)
    if not _usable(B):
        return Verdict.of(what, False, "no usable F from the float points to compare with", "same F")
    m = uint16_wraparound(A, B, SAME_RTOL)
    return Verdict.of(what, m is None, "same F" if m is None else "a different F", "same F up to scale", [m])
