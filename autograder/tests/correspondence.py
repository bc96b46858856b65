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
from autograder.sandbox import Call
from starter.checks.mistakes import points_xy_swapped

from ._common import Malformed, Outcome, as_array, graded, parts, share_score, tidy
from .hidden import Scenes, project

__all__ = ["FUNCTIONS", "QUESTIONS", "calls", "judge", "prepare"]

QUESTIONS = ("Q4.1", "Q4.2")
FUNCTIONS = ("epipolarCorrespondence", "compute3D_pts")
_SECONDS_PER_POINT = 0.5
_SECONDS_TRIANGULATE = 5.0
_GOAL, _FLOOR = 0.7, 0.2
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
    d = np.linalg.norm(np.asarray(pts2, float) - truth2, axis=1)
    return np.where(np.isfinite(d), d, np.inf) <= tol


def _right_3d(w, case: Case) -> np.ndarray:
    """Points that reproject within tol of the point in image 1 and of its true match in image 2."""
    d1 = np.linalg.norm(project(case.C1, w) - case.pts1, axis=1)
    d2 = np.linalg.norm(project(case.C2, w) - case.truth2, axis=1)
    d1, d2 = (np.where(np.isfinite(d), d, np.inf) for d in (d1, d2))
    return (d1 <= case.tol) & (d2 <= case.tol)


def _case(key, label, scene, count, rng) -> Case:
    from solutions import compute3D_pts, epipolarCorrespondence

    W, H = scene.width, scene.height
    tol = max(2.0, 3.0 * W / 640.0)
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
                right = _share_2d(pts2, c.truth2, c.tol)
                share, goal = float(right.mean()), _GOAL * c.ref_share
                fraction = share_score(share, goal, _FLOOR * c.ref_share)
                lines.append(f"{c.label}: {int(right.sum())} of {len(right)} matches within {c.tol:g} px of the true "
                             f"ones ({share:.0%}; full marks from {goal:.0%})")
                errors = out.field("errors", 0)
                if isinstance(errors, int) and errors > 0:
                    first = out.field("first_error", "")
                    lines.append(f"epipolarCorrespondence failed on {errors} points"
                                 + (f", first: {tidy(first)}" if isinstance(first, str) and first else ""))
                reached = out.field("reached", len(right))
                if isinstance(reached, int) and reached < len(right):
                    lines.append(f"only {reached} of {len(right)} points were matched in the time allowed "
                                 f"({_SECONDS_PER_POINT:g} s per point)")
                swapped = points_xy_swapped(np.nan_to_num(pts2, nan=-1e9), c.truth2, c.tol)
                mistakes += [swapped] if swapped else []
        tests.append(graded(f"matches on {c.label}", points, fraction, lines, mistakes))
    return QuestionResult.of("Q4.1", tests)


def _w_from(value, n):
    if isinstance(value, (tuple, list)):
        value = parts(value, 1, "compute3D_pts")[0]
    return as_array(value, (n, 3), "the 3D points")


def _judge_points(p: Prepared, outcomes) -> QuestionResult:
    c = p.points_case
    n = len(c.pts1)
    goal, floor = _GOAL * c.ref_share_3d, _FLOOR * c.ref_share_3d
    direct = Outcome(outcomes.get("Q4.2:compute3D_pts"), "compute3D_pts").items(1)[0]
    direct_share, direct_problem = None, ""
    try:
        if not direct.ok:
            raise Malformed(direct.error)
        direct_share = float(np.mean(_right_3d(_w_from(direct.value, n), c)))
    except Malformed as exc:
        direct_problem = str(exc)
    pipe = Outcome(outcomes.get("Q4.2:pipeline"), "the epipolarCorrespondence + triangulate pipeline")
    pipe_share, pipe_problem = None, pipe.problem or ""
    if not pipe.problem:
        try:
            pipe_share = float(np.mean(_right_3d(as_array(pipe.field("w"), (n, 3), "w"), c)))
        except Malformed as exc:
            pipe_problem = str(exc)
        err = pipe.field("error", "")
        if isinstance(err, str) and err:
            pipe_problem = tidy(err)
    lines = []
    if direct_share is not None and (pipe_share is None or direct_share >= pipe_share):
        share = direct_share
        lines.append("graded through your compute3D_pts(im1, im2, F, x1, y1, C1, C2)")
    elif pipe_share is not None:
        share = pipe_share
        why = f" (compute3D_pts: {direct_problem})" if direct_problem else \
            " (it placed more points right than your compute3D_pts)"
        lines.append("graded through your epipolarCorrespondence and triangulate" + why)
    else:
        share = 0.0
        lines.append(f"compute3D_pts: {direct_problem or 'no result'}")
        lines.append(f"epipolarCorrespondence + triangulate: {pipe_problem or 'no result'}")
    lines.append(f"{c.label}: {share:.0%} of the 3D points reproject within {c.tol:g} px of the point and its true "
                 f"match (full marks from {goal:.0%})")
    fraction = share_score(share, goal, floor)
    return QuestionResult.of("Q4.2", [graded("3D points of the temple", 5, fraction, lines)])


def judge(p: Prepared, outcomes) -> list[QuestionResult]:
    return [_judge_matches(p, outcomes), _judge_points(p, outcomes)]
