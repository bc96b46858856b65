"""Q2, ``eightpoint(pts1, pts2, M) -> F``: is F the fundamental matrix of the matches?

F is defined up to scale and sign and several methods are right (refineF or not, 1/M or
Hartley scaling), so F is never compared entry by entry: every distance is the symmetric
epipolar distance of core.geometry (x2 to the line F x1 and x1 to the line F^T x2, pixels).

Every tolerance follows the data: noise-free matches must lie within EXACT_TOL * M of their
lines; on noisy matches the goal is FIT_FACTOR times the larger of the reference's distance on
the same matches and the noise the matches were made with (``fit_goal``), so no goal is an
absolute number of pixels.  ``enlarged`` moves matches to coordinates above 256 in both images
(every product of two coordinates above 65535), where uint16 arithmetic visibly wraps around.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from .mistakes import epipolar_statistic, fundamental_mistakes, rank2_not_enforced, uint16_wraparound
from .verdict import Verdict, fmt, read_array

__all__ = ["DATA_GOAL", "ENLARGE_OFFSET", "ENLARGE_SCALE", "EXACT_TOL", "FIT_FACTOR", "RANK_RTOL", "enlarged",
           "exact_fit", "fit", "fit_goal", "noise_of", "rank_two", "read_F", "uint16_same"]

EXACT_TOL = 1e-4      # noise-free matches: every distance below EXACT_TOL * M pixels (0.064 px at M = 640)
RANK_RTOL = 1e-6      # s3 / s2 of F in the 1/M coordinates
SAME_RTOL = 1e-6      # uint16 and float points: the same F up to scale
# Noisy matches: goal = FIT_FACTOR * max(the reference's RMS distance, the noise).  The handout's
# unrefined 1/M eight-point is the least accurate valid method and defines the reference's
# distance, so each valid method stays at or below 1 / FIT_FACTOR of the goal.
FIT_FACTOR = 2.0
# Data without ground truth nor reference (the public check's default data): RMS distance of the
# given matches <= DATA_GOAL * M (5 px at M = 640), what a valid unrefined 1/M eight-point keeps.
DATA_GOAL = 5.0 / 640.0
# ``enlarged``: x -> ENLARGE_SCALE * x + ENLARGE_OFFSET in both coordinates of both images.
ENLARGE_SCALE, ENLARGE_OFFSET = 2, 256


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


def fit_goal(reference_rms: Iterable[float] | float, noise_px: float | None = None) -> float:
    """The goal (pixels) of :func:`fit`: FIT_FACTOR * max(reference, noise).

    reference_rms : the RMS distance (pixels) of the evaluation matches to the reference's F on
        the same data: one number, or several (the handout's method with and without refineF:
        the larger counts, as every valid method must keep the goal).
    noise_px : the standard deviation (pixels, per coordinate) of the noise of the matches
        F was fitted to (``noise_of``), or None when unknown (data without ground truth).
        The noise keeps the goal from shrinking below what the data allow when the reference
        happens to land very close to the truth.
    """
    refs = [float(reference_rms)] if np.ndim(reference_rms) == 0 else [float(v) for v in reference_rms]
    if not refs or not all(np.isfinite(refs)) or min(refs) < 0:
        raise ValueError(f"reference_rms: expected finite distances >= 0, got {reference_rms!r}")
    if noise_px is not None and not (np.isfinite(noise_px) and noise_px >= 0):
        raise ValueError(f"noise_px: expected None or a finite number >= 0, got {noise_px!r}")
    return FIT_FACTOR * max(*refs, 0.0 if noise_px is None else float(noise_px))


def noise_of(stored1, stored2, exact1, exact2) -> float:
    """The noise (pixels) of stored matches: the RMS, over both images and both coordinates, of
    stored (N, 2) minus the exact projections (N, 2); the rounding to whole pixels counts too."""
    d = np.concatenate([np.asarray(stored1, float) - np.asarray(exact1, float),
                        np.asarray(stored2, float) - np.asarray(exact2, float)])
    if d.ndim != 2 or d.shape[1] != 2 or len(d) == 0:
        raise ValueError(f"stored1, stored2, exact1, exact2: expected (N, 2) arrays, got {d.shape} together")
    return float(np.sqrt(np.mean(d ** 2)))


def enlarged(pts, M) -> tuple[np.ndarray, float]:
    """(points, M) of the same scene seen by cameras with ENLARGE_SCALE times the focal length and
    the principal point moved by ENLARGE_OFFSET (K -> A K, A = [[s, 0, o], [0, s, o], [0, 0, 1]]).

    pts : (N, 2) pixels (x, y) of an image of width and height at most M; the result keeps the
        dtype of ``pts`` (uint16 points stay whole numbers: s and o are integers).  Every
        coordinate becomes at least ENLARGE_OFFSET = 256, so any product of two is above 65535.
    M : the scale of ``pts``; the new one is s * M + 2 * o (the enlarged image's larger side).
    The F of the enlarged matches is A^-T F A^-1: still a two-view scene, with larger numbers.
    """
    p = np.asarray(pts)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"pts: expected an (N, 2) array, got shape {p.shape}")
    s, o = ENLARGE_SCALE, ENLARGE_OFFSET
    if p.dtype.kind not in "iu":
        return p.astype(float) * s + o, float(s * float(M) + 2 * o)
    wide = p.astype(np.int64) * s + o   # computed wide: the result must fit the input's dtype
    if wide.size and (wide.min() < np.iinfo(p.dtype).min or wide.max() > np.iinfo(p.dtype).max):
        raise ValueError(f"pts: expected coordinates that stay within {p.dtype} once enlarged, got up to {p.max()}")
    return wide.astype(p.dtype), float(s * float(M) + 2 * o)


def fit(F, eval1, eval2, goal_px: float, M) -> Verdict:
    """The matches eval1, eval2 (P, 2) (true ones when known) are near F's lines: RMS distance <= goal_px.

    ``goal_px`` comes from :func:`fit_goal` (the reference's distance and the data's noise).
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
