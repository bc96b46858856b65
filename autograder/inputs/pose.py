"""Q3.3: the inputs of ``findM2`` and the right camera of each.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.geometry import IDENTITY_POSE, depths, fundamental_from_pose
from judging.pose import pose_gap

from .scenes import Scenes
from .shared import reference_F


TWISTED_LABEL = "matches near the epipoles of a forward move"


@dataclass(frozen=True, eq=False)
class PoseCase:
    label: str
    F: np.ndarray
    pts1: np.ndarray
    pts2: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    right: np.ndarray    # (3, 4) the right candidate
    X: np.ndarray | None = None   # (N, 3) the true points in ``right``'s scale, where the mistake needs them
    judge_outputs: bool = True    # False: the camera only (C2 and w are not judged on this case)


@dataclass(frozen=True, eq=False)
class Pose:
    cases: tuple[PoseCase, ...]


def _nearest(candidates: np.ndarray, truth: np.ndarray) -> np.ndarray:
    gaps = [max(pose_gap(candidates[:, :, i], truth)) for i in range(candidates.shape[2])]
    return candidates[:, :, int(np.argmin(gaps))]


def _all_in_front(right: np.ndarray, tc) -> bool:
    """Every match of ``tc`` triangulated (the reference's linear triangulation) in front of both
    cameras when camera 2 is ``right``: what a findM2 requiring all points in front needs."""
    from solutions import triangulate

    w, _ = triangulate(tc.K1 @ IDENTITY_POSE, tc.pts1, tc.K2 @ right, tc.pts2)
    return bool(np.all(depths(IDENTITY_POSE, w) > 0) and np.all(depths(right, w) > 0))


def prepare_pose(scenes: Scenes) -> Pose:
    """An exact scene (K1 != K2) with its true F, and hidden scenes with the reference's F of their
    noisy matches; the right candidate is the one nearest the true pose (the reference's choice on
    the official data, which has no truth).  Where the reference's findM2 would not choose the
    camera nearest the truth from the reference's F, or that camera leaves a match behind a camera,
    the scene's true F is given instead.  Last, the
    twisted-pair case of this draw (``solutions.twisted_pair``), judged on the camera only."""
    from solutions import essentialMatrix, findM2
    from solutions.twisted_pair import twisted_pair_case
    from starter import camera2

    tv = scenes.two_view
    cases = [PoseCase("noise-free matches", tv.F, tv.pts1, tv.pts2, tv.K1, tv.K2, tv.M2)]
    for tc in [scenes.hidden[0], *([scenes.official] if scenes.official else [])]:
        F = reference_F(tc)  # Q2's, made once
        if tc.has_truth:
            right = _nearest(camera2(essentialMatrix(F, tc.K1, tc.K2)), tc.scene.M2)
            if not (np.allclose(findM2(F, tc.pts1, tc.pts2, tc.K1, tc.K2)[0], right) and _all_in_front(right, tc)):
                # The points in front of both cameras pick another candidate than the one nearest
                # the truth, or some point lies behind a camera whichever candidate is taken (a
                # findM2 that asks for all points in front, as most do, finds none): this F is too
                # poor, and correct findM2s would lose the case. The scene's true F is given instead.
                F = fundamental_from_pose(tc.K1, tc.K2, tc.scene.M2)
                right = _nearest(camera2(essentialMatrix(F, tc.K1, tc.K2)), tc.scene.M2)
        else:
            right = findM2(F, tc.pts1, tc.pts2, tc.K1, tc.K2)[0]
        cases.append(PoseCase(tc.label, F, tc.pts1, tc.pts2, tc.K1, tc.K2, right))
    # Matches on which depth tested in camera 1 only picks the twisted pair (solutions.twisted_pair,
    # as the public check but from this draw's seed); its linear triangulations are far from optimal
    # by construction, so only the camera is judged there.
    tw = twisted_pair_case(scenes.seed("pose-twisted-pair"))
    cases.append(PoseCase(TWISTED_LABEL, tw.F, tw.pts1, tw.pts2, tw.pair.K1, tw.pair.K2, tw.pair.M2,
                          X=tw.pair.X, judge_outputs=False))
    return Pose(tuple(cases))
