"""RANSAC, written once: a generic loop and ``ransacF`` built on a student's ``eightpoint``.

Randomness comes only from the numpy Generator passed in (``rng``), so a run is reproducible.
A run that lasts (a student's ``eightpoint`` that calls ``refineF`` costs tens of ms a sample)
shows a tqdm progress bar on stdout after two seconds; its carriage returns leave one final
line in a saved notebook, Colab and the PDF alike, and a quick run prints nothing.
"""

from __future__ import annotations

import inspect
import math
import sys
from dataclasses import dataclass
from typing import Callable

import numpy as np
from tqdm import tqdm

from core.geometry import epipolar_distances
from core.validate import as_points, as_positive_scalar, same_length

__all__ = ["ransac", "RansacResult", "adaptive_trials", "hartley_normalization", "eightpoint_hartley", "ransacF"]


def adaptive_trials(inlier_ratio: float, min_samples: int, confidence: float = 0.99) -> float:
    """Trials needed to draw one all-inlier sample with probability ``confidence``.

    Hartley & Zisserman (2004), section 4.7.1: N = log(1 - p) / log(1 - w^s).
    Returns inf when w is 0 and 0 when every point is an inlier.
    """
    good = inlier_ratio ** min_samples
    if good <= 0:
        return np.inf
    if good >= 1:
        return 0.0
    return float(np.log1p(-confidence) / np.log1p(-good))


@dataclass(frozen=True)
class RansacResult:
    """model: the best model (None when no sample gave one); inliers: (N,) bool; trials: samples drawn."""

    model: object
    inliers: np.ndarray
    trials: int


def ransac(n: int, fit: Callable[[np.ndarray], object], residuals: Callable[[object], np.ndarray], *,
           min_samples: int, threshold: float, rng: np.random.Generator, max_trials: int = 1000,
           confidence: float = 0.99, local_fit: Callable[[np.ndarray], object] | None = None,
           progress: str | None = None) -> RansacResult:
    """Generic RANSAC over ``n`` data items, with adaptive stopping.

    Parameters
    ----------
    n : number of data items.
    fit : indices (k,) -> model, or None when the sample is degenerate.
    residuals : model -> (n,) residual of every item (an item is an inlier when its residual
        is below ``threshold``).
    min_samples : size of a minimal sample.
    rng : the numpy Generator every sample is drawn from.
    max_trials : upper bound on samples; fewer are drawn once ``adaptive_trials`` says the
        best model is, with probability ``confidence``, as good as it will get.
    local_fit : optional, inlier indices -> model fitted on all of them (or None); tried on
        every new best sample and kept when it has at least as many inliers.
    progress : a label for a progress bar (tqdm, on stdout, shown only when the run lasts over
        two seconds; its total drops as adaptive stopping lowers the samples needed); None: no bar.
    """
    if n < min_samples:
        raise ValueError(f"n: expected at least {min_samples} data items, got {n}")
    best_model, best_inliers, best_count = None, np.zeros(n, bool), -1
    needed, trials = float(max_trials), 0
    bar = None if progress is None else tqdm(total=max_trials, desc=progress, unit="sample", file=sys.stdout,
                                             delay=2.0, mininterval=0.5, leave=True, dynamic_ncols=False, ncols=90)
    try:
        while trials < min(max_trials, needed):
            trials += 1
            if bar is not None:
                bar.update(1)
            best = _one_trial(n, fit, residuals, min_samples, threshold, rng, local_fit, best_count)
            if best is not None:
                best_model, best_inliers, best_count = best
                needed = adaptive_trials(best_count / n, min_samples, confidence)
                if bar is not None:
                    bar.total = max(trials, int(min(max_trials, math.ceil(needed))))
    finally:
        if bar is not None:
            bar.total = trials  # adaptive stopping: the bar ends full
            bar.close()
    return RansacResult(best_model, best_inliers, trials)


def _one_trial(n, fit, residuals, min_samples, threshold, rng, local_fit, best_count):
    """One sample of :func:`ransac`: (model, inliers, count) when it beats ``best_count``, else None."""
    sample = rng.choice(n, size=min_samples, replace=False)
    model = fit(sample)
    if model is None:
        return None
    inliers = residuals(model) < threshold
    count = int(inliers.sum())
    if count <= best_count:
        return None
    if local_fit is not None and count >= min_samples:
        # Local optimisation (Chum et al. 2003): a fit on all inliers of a new best
        # sample usually finds more of them, so the adaptive bound drops much sooner.
        refit = local_fit(np.flatnonzero(inliers))
        if refit is not None:
            refit_inliers = residuals(refit) < threshold
            if refit_inliers.sum() >= count:
                model, inliers, count = refit, refit_inliers, int(refit_inliers.sum())
    return model, inliers, count


def hartley_normalization(pts: np.ndarray) -> np.ndarray:
    """T (3x3) moving the points' centroid to 0 and their mean distance to it to sqrt(2)."""
    c = pts.mean(axis=0)
    d = np.mean(np.linalg.norm(pts - c, axis=1))
    s = np.sqrt(2) / d if d > 0 else 1.0
    return np.array([[s, 0, -s * c[0]], [0, s, -s * c[1]], [0, 0, 1.0]])


def eightpoint_hartley(eightpoint: Callable, pts1: np.ndarray, pts2: np.ndarray) -> np.ndarray:
    """F (3x3, pixels, x2^T F x1 = 0) from ``eightpoint`` run on Hartley-normalised points.

    The same ``eightpoint(pts1, pts2, M)`` is called with M = 1 on points centred and scaled to a
    mean distance of sqrt(2), and the result is mapped back to pixels.  Not normalised to unit
    norm; exceptions of ``eightpoint`` propagate.
    """
    T1, T2 = hartley_normalization(pts1), hartley_normalization(pts2)
    n1 = pts1 @ T1[:2, :2].T + T1[:2, 2]
    n2 = pts2 @ T2[:2, :2].T + T2[:2, 2]
    return T2.T @ np.asarray(eightpoint(n1, n2, 1.0), dtype=float) @ T1


def _without_refinement(eightpoint: Callable) -> Callable:
    # refineF costs tens of ms a call; a minimal sample is fitted exactly, so skip it when we can.
    try:
        params = inspect.signature(eightpoint).parameters
    except (TypeError, ValueError):
        return eightpoint
    if "refine" in params:
        return lambda p1, p2, M: eightpoint(p1, p2, M, refine=False)
    return eightpoint


def ransacF(pts1, pts2, M, eightpoint: Callable, nIters: int = 1000, tol: float = 1.0,
            rng: np.random.Generator | int | None = None, confidence: float = 0.99, progress: bool = True):
    """Robust fundamental matrix from matches with outliers.

    Draws 8 matches at a time, fits F with the given ``eightpoint(pts1, pts2, M)``, and counts
    the matches whose x2 lies within ``tol`` pixels of its epipolar line F x1.  The best
    hypothesis is then re-fitted on all its inliers, in Hartley-normalised coordinates (the
    same ``eightpoint`` called with M = 1 on normalised points): a 1/M-scaled refit on many
    points can be far worse than the sample it starts from.  The refit is kept only when it
    keeps at least as many inliers.

    Parameters
    ----------
    pts1, pts2 : (N, 2) pixels (x, y) = (column, row), N >= 8; integer arrays are cast to float.
    M : scale used by ``eightpoint`` (max of the image's width and height).
    eightpoint : function (pts1, pts2, M) -> F (3x3), the student's or the reference.  A
        ``refine`` keyword, when it has one, is set to False for the minimal samples.
    nIters : most samples to draw (fewer when adaptive stopping says it is enough).
    tol : inlier threshold in pixels, distance of x2 to the line F x1.
    rng : numpy Generator (or an int seed); None means seed 0, so runs are reproducible.
    progress : show a progress bar when the run lasts over two seconds (see :func:`ransac`).

    Returns
    -------
    F : (3, 3), x2^T F x1 = 0 in pixels, unit Frobenius norm.
    inliers : (N,) bool.
    """
    p1 = as_points(pts1, "pts1", min_count=8)
    p2 = as_points(pts2, "pts2", min_count=8)
    n = same_length(pts1=p1, pts2=p2)
    M = as_positive_scalar(M, "M")
    tol = as_positive_scalar(tol, "tol")
    if int(nIters) < 1:
        raise ValueError(f"nIters: expected a positive number of trials, got {nIters}")
    if not isinstance(rng, np.random.Generator):
        rng = np.random.default_rng(0 if rng is None else rng)
    fit8 = _without_refinement(eightpoint)

    def fit(idx):
        try:
            F = np.asarray(fit8(p1[idx], p2[idx], M), dtype=float)
        except (ValueError, np.linalg.LinAlgError):
            return None  # a degenerate sample (collinear points, say) is skipped, not fatal
        return F if F.shape == (3, 3) and np.all(np.isfinite(F)) and np.any(F) else None

    def residuals(F):
        # core.geometry's distance, without starter.epipolar's input checks: this runs once per trial.
        return epipolar_distances(F, p1, p2)

    def fit_all(idx):
        try:
            F = eightpoint_hartley(fit8, p1[idx], p2[idx])
        except (ValueError, np.linalg.LinAlgError):
            return None
        return F if np.all(np.isfinite(F)) else None

    result = ransac(n, fit, residuals, min_samples=8, threshold=tol, rng=rng,
                    max_trials=int(nIters), confidence=confidence, local_fit=fit_all,
                    progress="RANSAC" if progress else None)
    if result.model is None:
        raise ValueError("pts1, pts2: no sample of 8 matches gave a fundamental matrix (degenerate data)")
    F, inliers = result.model, result.inliers
    for _ in range(3):  # re-fit until the inlier set stops growing
        F_refit = fit_all(np.flatnonzero(inliers)) if inliers.sum() >= 8 else None
        if F_refit is None:
            break
        new_inliers = residuals(F_refit) < tol
        if new_inliers.sum() < inliers.sum():
            break
        grew = new_inliers.sum() > inliers.sum()
        F, inliers = F_refit, new_inliers
        if not grew:
            break
    return F / np.linalg.norm(F), inliers
