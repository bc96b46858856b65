"""Q4.1 and Q4.2: the matching problems (images, true F, points with known true matches) and the reference's shares.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from judging import correspondence as jc

from ..scenes import FIXED_LABELS, Scenes
from .base import M1


@dataclass(frozen=True, eq=False)
class CorrespondenceCase:
    """One scene's matching problem: images, the true F, points of image 1 and their true matches."""

    key: str
    label: str
    im1: np.ndarray
    im2: np.ndarray
    F: np.ndarray
    pts1: np.ndarray        # (P, 2)
    truth2: np.ndarray      # (P, 2)
    C1: np.ndarray
    C2: np.ndarray
    tol: float
    ref_share: float        # the reference matcher's share within tol
    ref_share_3d: float     # the reference compute3D_pts's share of right 3D points


@dataclass(frozen=True, eq=False)
class Correspondence:
    cases: tuple[CorrespondenceCase, ...]
    points_case: CorrespondenceCase        # the scene of Q4.2


def _correspondence_case(key, label, scene, count, rng) -> CorrespondenceCase:
    """Points whose true match is known (unoccluded, and far enough from the point itself that
    returning (x1, y1) or a nearby pixel cannot pass), with the reference's shares on them."""
    from solutions import compute3D_pts, epipolarCorrespondence

    W, H = scene.width, scene.height
    tol = jc.tolerance(W)
    p1 = np.column_stack([scene.x1, scene.y1]).astype(float)
    disparity = np.linalg.norm(scene.x2_true - p1, axis=1)
    margin = 8
    inside = np.all((p1 >= margin) & (p1 <= [W - 1 - margin, H - 1 - margin]), axis=1)
    eligible = np.flatnonzero(scene.visible2 & inside & (disparity > 2 * tol))
    if len(eligible) < 8:  # a degenerate hidden scene would make the check meaningless
        eligible = np.flatnonzero(scene.visible2 & inside)
    idx = np.sort(rng.choice(eligible, size=min(count, len(eligible)), replace=False))
    pts1, truth2 = p1[idx], scene.x2_true[idx]
    F = scene.F_true
    ref = np.array([epipolarCorrespondence(scene.im1, scene.im2, F, x, y) for x, y in pts1])
    C1, C2 = scene.K1 @ M1, scene.K2 @ scene.M2
    case = CorrespondenceCase(key, label, scene.im1, scene.im2, F, pts1, truth2, C1, C2, tol,
                              float(np.mean(jc.right_2d(ref, truth2, tol))), 0.0)
    w_ref, _ = compute3D_pts(scene.im1, scene.im2, F, pts1[:, :1], pts1[:, 1:], C1, C2)
    return dataclasses.replace(case, ref_share_3d=float(np.mean(jc.right_3d(w_ref, C1, C2, pts1, truth2, tol))))


def matching_labels(config) -> list[str]:
    """The scenes of Q4.1, as feedback names them (known before the scenes are made: one test each)."""
    return [f"hidden scene {k}" for k in range(1, min(2, len(config.temples)) + 1)] + (
        ["the default data"] if config.use_default_data else [])


def prepare_correspondence(scenes: Scenes) -> Correspondence:
    """The matching problems of the hidden scenes (the first two) and of the default data when
    ``scenes`` holds it (a draw made without it takes the batch's, ``combine_correspondence``)."""
    rng = np.random.default_rng(scenes.seed("matching"))
    tcs = [*scenes.hidden[:2], *([scenes.default] if scenes.default else [])]
    cases = tuple(_correspondence_case(f"scene{k}", tc.label, tc.scene, scenes.config.match_points, rng)
                  for k, tc in enumerate(tcs))
    if scenes.default is not None or not scenes.config.use_default_data:
        _check_labels(cases, scenes.config)
    return Correspondence(cases, cases[1])


def combine_correspondence(drawn: Correspondence, batch: Correspondence, config) -> Correspondence:
    """A draw's hidden problems with the batch's problem of the default data (``FIXED_LABELS``)."""
    cases = tuple(c for c in drawn.cases if c.label not in FIXED_LABELS) + tuple(
        c for c in batch.cases if c.label in FIXED_LABELS)
    _check_labels(cases, config)
    return Correspondence(cases, cases[1])


def _check_labels(cases, config) -> None:
    # The tests are parametrized by matching_labels before any scene exists: they must agree.
    if [c.label for c in cases] != matching_labels(config):
        raise RuntimeError(f"matching_labels: expected {[c.label for c in cases]}, got {matching_labels(config)}")
