"""Q2: the inputs of ``eightpoint`` (hidden scenes, the default data, the official data, noise-free and uint16 matches) and the fit goals.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.geometry import symmetric_epipolar_distances
from judging import fundamental as jf

from ..scenes import Scenes


@dataclass(frozen=True, eq=False)
class FundamentalCase:
    """One eightpoint input: pts1, pts2 (N, 2), M; eval1, eval2 (P, 2) true matches; goal in px."""

    label: str
    pts1: np.ndarray
    pts2: np.ndarray
    M: float
    eval1: np.ndarray
    eval2: np.ndarray
    goal: float


@dataclass(frozen=True, eq=False)
class Fundamental:
    cases: tuple[FundamentalCase, ...]     # hidden scenes, the default data, the official data
    exact: FundamentalCase                 # noise-free matches
    uint16: FundamentalCase                # a scene's matches as the data files' uint16


_EXACT_TOL_PX = 0.05


def _hartley(pts1, pts2):
    """F by the reference eight-point with Hartley's normalisation instead of 1/M (a valid variant)."""
    from solutions import eightpoint
    from starter.ransac import eightpoint_hartley

    F = eightpoint_hartley(lambda a, b, M: eightpoint(a, b, M, refine=False), pts1, pts2)
    return F / np.linalg.norm(F)


def _rms(F, eval1, eval2) -> float:
    d = symmetric_epipolar_distances(F, eval1, eval2)
    return float(np.sqrt(np.mean(d ** 2)))


def _evaluation_matches(case) -> tuple[np.ndarray, np.ndarray]:
    if not case.has_truth:
        return case.pts1, case.pts2  # no ground truth: the given matches, as the handout uses them
    s = case.scene
    keep = s.visible2
    return np.column_stack([s.x1, s.y1]).astype(float)[keep], s.x2_true[keep]


def _fundamental_case(label, pts1, pts2, M, eval1, eval2) -> FundamentalCase:
    from solutions import eightpoint

    p1, p2 = np.asarray(pts1, float), np.asarray(pts2, float)
    variants = [eightpoint(p1, p2, M), eightpoint(p1, p2, M, refine=False), _hartley(p1, p2)]
    worst = max(_rms(F, eval1, eval2) for F in variants)
    return FundamentalCase(label, pts1, pts2, float(M), eval1, eval2, jf.fit_goal([worst]))


def prepare_fundamental(scenes: Scenes) -> Fundamental:
    cases = []
    for tc in scenes.temple_cases():
        e1, e2 = _evaluation_matches(tc)
        cases.append(_fundamental_case(tc.label, tc.pts1, tc.pts2, tc.M, e1, e2))
    base = scenes.default or scenes.hidden[-1]
    s = base.scene
    exact = FundamentalCase("noise-free matches", s.pts1_true.copy(), s.pts2_true.copy(), float(s.M),
                            s.pts1_true, s.pts2_true, _EXACT_TOL_PX)
    e1, e2 = _evaluation_matches(base)
    ref = next(c for c in cases if c.label == base.label)
    uint16 = FundamentalCase(f"{base.label}, as uint16", s.pts1.astype(np.uint16), s.pts2.astype(np.uint16),
                             float(s.M), e1, e2, ref.goal)
    return Fundamental(tuple(cases), exact, uint16)
