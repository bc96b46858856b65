"""Q4.1 ``epipolarCorrespondence`` and Q4.2 ``compute3D_pts`` on hidden temple scenes.

Q4.1: points of image 1 whose true match is known (unoccluded, and far enough from the point
itself that returning (x1, y1) or a nearby pixel cannot pass) are matched with the true F; the
share of matches within a few pixels of the truth is compared with the reference matcher's
share on the same points.  Full marks at 70 % of the reference's share, nothing at 20 % of it,
linear between (the handout asks for the easy points, not every point).

Q4.2: the 3D points must reproject within the same few pixels of the point and of its true
match.  Graded through the student's ``compute3D_pts(im1, im2, F, x1, y1, C1, C2)`` when it
accepts the reference signature and through their ``epipolarCorrespondence`` + ``triangulate``
pipeline otherwise; the better of the two counts, and the feedback says which was used.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from autograder.results import QuestionResult
from autograder.hidden.legacy import Call
from judging import correspondence as jc
from judging.verdict import Malformed

from ._common import Outcome, as_array, graded, tidy
from .hidden import Scenes

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "prepare"]

QUESTIONS = ("Q4.1", "Q4.2")
FUNCTIONS = ("epipolarCorrespondence", "compute3D_pts")
_SECONDS_PER_POINT = 0.5
_SECONDS_TRIANGULATE = 5.0
_M1 = np.hstack([np.eye(3), np.zeros((3, 1))])


@dataclass(frozen=True, eq=False)
class Case:
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
class Prepared:
    cases: tuple[Case, ...]
    points_case: Case        # the scene of Q4.2


def _share_2d(pts2, truth2, tol) -> np.ndarray:
    return jc.right_2d(pts2, truth2, tol)


def _right_3d(w, case: Case) -> np.ndarray:
    """Points that reproject within tol of the point in image 1 and of its true match in image 2."""
    return jc.right_3d(w, case.C1, case.C2, case.pts1, case.truth2, case.tol)


def _case(key, label, scene, count, rng) -> Case:
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
    C1, C2 = scene.K1 @ _M1, scene.K2 @ scene.M2
    case = Case(key, label, scene.im1, scene.im2, F, pts1, truth2, C1, C2, tol,
                float(np.mean(_share_2d(ref, truth2, tol))), 0.0)
    w_ref, _ = compute3D_pts(scene.im1, scene.im2, F, pts1[:, :1], pts1[:, 1:], C1, C2)
    return dataclasses.replace(case, ref_share_3d=float(np.mean(_right_3d(w_ref, case))))


def prepare(scenes: Scenes) -> Prepared:
    rng = np.random.default_rng(scenes.config.seed("matching"))
    tcs = [*scenes.hidden[:2], *([scenes.default] if scenes.default else [])]
    cases = tuple(_case(f"scene{k}", tc.label, tc.scene, scenes.config.match_points, rng)
                  for k, tc in enumerate(tcs))
    return Prepared(cases, cases[1])


def calls(p: Prepared, time_scale: float) -> list[Call]:
    out = []
    for c in p.cases:
        budget = _SECONDS_PER_POINT * len(c.pts1) * time_scale
        out.append(Call(f"Q4.1:{c.key}", "__hw4_match", (c.key, c.im1, c.im2, c.F, c.pts1[:, 0], c.pts1[:, 1], budget),
                        timeout=budget + 5 * time_scale + 2))
    c = p.points_case
    budget = (_SECONDS_PER_POINT * len(c.pts1) + _SECONDS_TRIANGULATE) * time_scale
    args = (c.im1, c.im2, c.F, c.pts1[:, :1].copy(), c.pts1[:, 1:].copy(), c.C1, c.C2)
    out.append(Call("Q4.2:compute3D_pts", "__hw4_each", ("compute3D_pts", [(args, {})], budget),
                    timeout=budget + 2))
    out.append(Call("Q4.2:pipeline", "__hw4_pipeline", (c.key, c.im1, c.im2, c.F, c.pts1[:, 0], c.pts1[:, 1], c.C1, c.C2,
                                                        budget), timeout=2 * budget + 2))
    return out


def _judge_matches(p: Prepared, outcomes) -> QuestionResult:
    tests = []
    points = 15 / len(p.cases)
    for c in p.cases:
        out = Outcome(outcomes.get(f"Q4.1:{c.key}"), "epipolarCorrespondence")
        lines, mistakes, fraction = [], [], 0.0
        if out.problem:
            lines.append(out.problem)
        else:
            try:
                pts2 = as_array(out.field("pts2"), (len(c.pts1), 2), "the matches")
            except Malformed as exc:
                pts2 = None
                lines.append(str(exc))
            if pts2 is not None:
                v = jc.matches(pts2, c.truth2, c.tol, c.ref_share)
                fraction, mistakes = v.fraction, list(v.mistakes)
                lines.append(f"{c.label}: {v.measured} of the true ones (full marks from {v.goal[3:]})")
                errors = out.field("errors", 0)
                if isinstance(errors, int) and errors > 0:
                    first = out.field("first_error", "")
                    lines.append(f"epipolarCorrespondence failed on {errors} points"
                                 + (f", first: {tidy(first)}" if isinstance(first, str) and first else ""))
                reached = out.field("reached", len(pts2))
                if isinstance(reached, int) and reached < len(pts2):
                    lines.append(f"only {reached} of {len(pts2)} points were matched in the time allowed "
                                 f"({_SECONDS_PER_POINT:g} s per point)")
        tests.append(graded(f"matches on {c.label}", points, fraction, lines, mistakes))
    return QuestionResult.of("Q4.1", tests)


def _points_verdict(w, c: Case):
    return jc.points3d(w, c.C1, c.C2, c.pts1, c.truth2, c.tol, c.ref_share_3d)


def _judge_points(p: Prepared, outcomes) -> QuestionResult:
    c = p.points_case
    n = len(c.pts1)
    direct = Outcome(outcomes.get("Q4.2:compute3D_pts"), "compute3D_pts").items(1)[0]
    direct_v, direct_problem = None, ""
    try:
        if not direct.ok:
            raise Malformed(direct.error)
        direct_v = _points_verdict(jc.read_points(direct.value, n), c)
    except Malformed as exc:
        direct_problem = str(exc)
    pipe = Outcome(outcomes.get("Q4.2:pipeline"), "the epipolarCorrespondence + triangulate pipeline")
    pipe_v, pipe_problem = None, pipe.problem or ""
    if not pipe.problem:
        try:
            pipe_v = _points_verdict(as_array(pipe.field("w"), (n, 3), "w"), c)
        except Malformed as exc:
            pipe_problem = str(exc)
        err = pipe.field("error", "")
        if isinstance(err, str) and err:
            pipe_problem = tidy(err)
    lines = []
    if direct_v is not None and (pipe_v is None or direct_v.fraction >= pipe_v.fraction):
        v = direct_v
        lines.append("graded through your compute3D_pts(im1, im2, F, x1, y1, C1, C2)")
    elif pipe_v is not None:
        v = pipe_v
        why = f" (compute3D_pts: {direct_problem})" if direct_problem else \
            " (it placed more points right than your compute3D_pts)"
        lines.append("graded through your epipolarCorrespondence and triangulate" + why)
    else:
        v = None
        lines.append(f"compute3D_pts: {direct_problem or 'no result'}")
        lines.append(f"epipolarCorrespondence + triangulate: {pipe_problem or 'no result'}")
    if v is not None:
        lines.append(f"{c.label}: {v.measured} px of the point and its true match in both images "
                     f"(full marks from {v.goal[3:]})")
    fraction = v.fraction if v is not None else 0.0
    return QuestionResult.of("Q4.2", [graded("3D points of the temple", 5, fraction, lines,
                                             v.mistakes if v is not None else ())])


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    return [_judge_matches(p, outcomes), _judge_points(p, outcomes)]
