"""Q3.3: ``findM2(F, pts1, pts2, K1, K2) -> (M2, C2, w)``: the right camera of the four.

E fixes camera 2 up to the four candidates of ``camera2`` and the scale of t, so M2 is compared
with the right candidate by rotation angle and direction of t only.  The right candidate is the
one nearest the true pose (the reference's choice on the official data, which has no truth).
Inputs: an exact scene with K1 != K2 and its true F, and hidden scenes with the F the reference
estimates from their noisy matches.  C2 must be K2 M2, and w the points triangulated with it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autograder.results import QuestionResult
from autograder.sandbox import Call
from starter.checks.mistakes import points_behind_cameras, wrong_camera

from ._common import Malformed, Outcome, as_array, first_problem, fmt, graded, parts
from .hidden import Scenes, project

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "pose_gap", "prepare"]

QUESTIONS = ("Q3.3",)
FUNCTIONS = ("findM2",)
_CALL = "Q3.3:findM2"
_SECONDS_PER_CALL = 5.0
_ROT_TOL_DEG = 0.5
_DIR_TOL_DEG = 1.0
_M1 = np.hstack([np.eye(3), np.zeros((3, 1))])


@dataclass(frozen=True, eq=False)
class Case:
    label: str
    F: np.ndarray
    pts1: np.ndarray
    pts2: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    right: np.ndarray    # (3, 4) the right candidate


@dataclass(frozen=True, eq=False)
class Prepared:
    cases: tuple[Case, ...]


def _angle(u, v) -> float:
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if not (np.isfinite(nu) and np.isfinite(nv)) or nu == 0 or nv == 0:
        return 180.0
    return float(np.degrees(np.arccos(np.clip(np.dot(u, v) / (nu * nv), -1.0, 1.0))))


def pose_gap(M2, right) -> tuple[float, float]:
    """(rotation angle between the R's, angle between the t's), degrees; 180 for unusable input."""
    if not np.all(np.isfinite(M2)):
        return 180.0, 180.0
    R, Rr = M2[:, :3], right[:, :3]
    c = (np.trace(R.T @ Rr) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))), _angle(M2[:, 3], right[:, 3])


def _nearest(candidates: np.ndarray, truth: np.ndarray) -> np.ndarray:
    gaps = [max(pose_gap(candidates[:, :, i], truth)) for i in range(candidates.shape[2])]
    return candidates[:, :, int(np.argmin(gaps))]


def prepare(scenes: Scenes) -> Prepared:
    from solutions import eightpoint, essentialMatrix, findM2
    from starter import camera2

    tv = scenes.two_view
    cases = [Case("noise-free matches", tv.F, tv.pts1, tv.pts2, tv.K1, tv.K2, tv.M2)]
    for tc in [scenes.hidden[0], *([scenes.official] if scenes.official else [])]:
        F = eightpoint(tc.pts1, tc.pts2, tc.M)
        if tc.has_truth:
            right = _nearest(camera2(essentialMatrix(F, tc.K1, tc.K2)), tc.scene.M2)
        else:
            right = findM2(F, tc.pts1, tc.pts2, tc.K1, tc.K2)[0]
        cases.append(Case(tc.label, F, tc.pts1, tc.pts2, tc.K1, tc.K2, right))
    return Prepared(tuple(cases))


def calls(p: Prepared, time_scale: float) -> list[Call]:
    items = [((c.F, c.pts1, c.pts2, c.K1, c.K2), {}) for c in p.cases]
    budget = _SECONDS_PER_CALL * len(items) * time_scale
    return [Call(_CALL, "__hw4_each", ("findM2", items, budget), timeout=budget + 2)]


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    from solutions import triangulate

    items = Outcome(outcomes.get(_CALL), "findM2").items(len(p.cases))
    right, lines, mistakes = 0, [], []
    consistent, cons_lines = 0, []
    for case, item in zip(p.cases, items):
        try:
            if not item.ok:
                raise Malformed(item.error)
            value = item.value
            M2 = as_array(value if isinstance(value, np.ndarray) else parts(value, 1, "findM2")[0], (3, 4), "M2")
        except Malformed as exc:
            lines.append(f"{case.label}: {exc}")
            continue
        rot, direction = pose_gap(M2, case.right)
        ok = rot <= _ROT_TOL_DEG and direction <= _DIR_TOL_DEG
        right += ok
        lines.append(f"{case.label}: your M2 is {fmt(rot)} deg (rotation) and {fmt(direction)} deg (direction "
                     f"of t) from the right camera (goal <= {_ROT_TOL_DEG:g} and {_DIR_TOL_DEG:g} deg)")
        if not ok:
            mistakes += [m for m in (wrong_camera(M2, case.right),) if m]
        try:
            C2, w = parts(value, 3, "findM2")[1:]
            C2 = as_array(C2, (3, 4), "C2")
            w = as_array(w, (len(case.pts1), 3), "w")
        except Malformed as exc:
            cons_lines.append(f"{case.label}: {exc}")
            continue
        expected_C2 = case.K2 @ M2
        c2_ok = np.allclose(C2, expected_C2, rtol=1e-6, atol=1e-9 * np.abs(expected_C2).max())
        C1 = case.K1 @ _M1
        _, ref_err = triangulate(C1, case.pts1, C2, case.pts2) if c2_ok else (None, np.inf)
        h = [p_ - project(C, w) for C, p_ in ((C1, case.pts1), (C2, case.pts2))]
        err = float(sum(np.sum(r ** 2) for r in h)) if np.all(np.isfinite(w)) else float("inf")
        w_ok = c2_ok and err <= 1.05 * ref_err + 1e-6
        consistent += w_ok
        behind = points_behind_cameras(w, _M1, M2) if np.all(np.isfinite(w)) else None
        if behind:
            mistakes.append(behind)
        if not c2_ok:
            cons_lines.append(f"{case.label}: C2 is not K2 @ M2")
        else:
            cons_lines.append(f"{case.label}: reprojection error of w with C1 and your C2 {fmt(err)} px^2 "
                              f"(goal <= {fmt(1.05 * ref_err + 1e-6)} px^2)")
    n = len(p.cases)
    if not cons_lines:
        cons_lines.append(first_problem(items) or "no result to check")
    tests = [
        graded("M2 is the camera that puts the points in front of both cameras", 8, right / n, lines, mistakes),
        graded("C2 = K2 M2 and w are the points triangulated with it", 2, consistent / n, cons_lines, mistakes),
    ]
    return [QuestionResult.of("Q3.3", tests)]
