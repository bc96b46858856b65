"""Q4.1 ``epipolarCorrespondence`` and Q4.2 ``compute3D_pts`` on hidden temple scenes (judging.correspondence).

Q4.1, one test per scene: points of image 1 whose true match is known are matched with the true
F; the share of matches within a few pixels of the truth is compared with the reference
matcher's share on the same points.  Full marks at 70 % of the reference's share, nothing at
20 % of it, linear between (the handout asks for the easy points, not every point).

Q4.2: the 3D points must reproject within the same few pixels of the point and of its true
match.  Graded through the student's ``compute3D_pts(im1, im2, F, x1, y1, C1, C2)`` when it
accepts the reference signature and through their ``epipolarCorrespondence`` + ``triangulate``
pipeline otherwise (the matches of Q4.1, not asked for again); the better of the two counts, and
the feedback says which was used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from autograder.hidden.cases import SECONDS, matching_labels
from autograder.hidden.feedback import failure, value_of
from autograder.hidden.plugin import config_of
from judging import correspondence as jc
from judging.verdict import Malformed

_MATCH = "epipolarCorrespondence"


def pytest_generate_tests(metafunc):
    # One test per scene of the config, worth an equal share of Q4.1's 15 points.
    if "scene_index" in metafunc.fixturenames:
        labels = matching_labels(config_of(metafunc.config))
        metafunc.parametrize("scene_index", [
            pytest.param(k, id=f"scene{k + 1}", marks=pytest.mark.points(15 / len(labels), question="Q4.1",
                                                                     name=f"matches on {label}"))
            for k, label in enumerate(labels)])


@dataclass(frozen=True)
class Matched:
    """The student's matches of one scene: pts2 (P, 2), NaN where none came back; or the problem."""

    problem: str | None
    pts2: np.ndarray
    errors: int = 0
    first_error: str = ""
    reached: int = 0


def _point(value):
    try:
        arr = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        return None
    return (float(arr[0]), float(arr[1])) if arr.size == 2 else None


def _match(student, case) -> Matched:
    outcomes = student.each(_MATCH, [(float(x), float(y)) for x, y in case.pts1], args=(case.im1, case.im2, case.F),
                            seconds=SECONDS[_MATCH], slack=5 * student.time_scale + 2)
    pts2 = np.full((len(case.pts1), 2), np.nan)
    if outcomes and all(o.status == "missing" for o in outcomes):
        return Matched(failure(_MATCH, outcomes[0]), pts2)
    if outcomes and not any(o.ok for o in outcomes) and outcomes[0].status in ("timeout", "crashed"):
        return Matched(failure(_MATCH, outcomes[0]), pts2)
    errors, first, reached = 0, "", 0
    for k, o in enumerate(outcomes):
        if o.status == "skipped":
            continue
        reached += 1
        point = _point(o.value) if o.ok else None
        if point is None:
            errors += 1
            first = first or (failure(_MATCH, o) if not o.ok else f"{_MATCH} should return the two numbers (x2, y2)")
            continue
        pts2[k] = point
    return Matched(None, pts2, errors, first, reached)


@pytest.fixture(scope="session")
def correspondence(hidden):
    """The prepared inputs (``autograder.hidden.cases.Correspondence``)."""
    return hidden.prepared["correspondence"]


@pytest.fixture(scope="session")
def matched(student, correspondence) -> dict:
    """``Matched`` of every scene, by case: the student's matcher called once per point, once per run."""
    return {case: _match(student, case) for case in correspondence.cases}


def test_matches(correspondence, matched, scene_index, score):
    """The share of the student's matches within a few pixels of the true ones, against the reference's."""
    case = correspondence.cases[scene_index]
    m = matched[case]
    if m.problem:
        score.grade(0.0, [m.problem])
    v = jc.matches(m.pts2, case.truth2, case.tol, case.ref_share)
    lines = [f"{case.label}: {v.measured} of the true ones (full marks from {v.goal[3:]})"]
    if m.errors:
        lines.append(f"{_MATCH} failed on {m.errors} points" + (f", first: {m.first_error}" if m.first_error else ""))
    if m.reached < len(m.pts2):
        lines.append(f"only {m.reached} of {len(m.pts2)} points were matched in the time allowed "
                     f"({SECONDS[_MATCH]:g} s per point)")
    score.grade(v.fraction, lines, v.mistakes)


def _pipeline(student, case, m: Matched) -> tuple[np.ndarray | None, str]:
    """(w, problem) of the student's matches of ``case`` put through their triangulate."""
    if "triangulate" not in student.defined:
        return None, "triangulate is not defined in your notebooks"
    if m.problem:
        return None, m.problem
    w = np.full((len(case.pts1), 3), np.nan)
    good = np.all(np.isfinite(m.pts2), axis=1)
    if not good.any():
        return w, "no point was matched"
    o = student.each("triangulate", [(case.C1, case.pts1[good], case.C2, m.pts2[good])],
                     seconds=SECONDS["compute3D_pts.triangulate"])[0]
    try:
        value = value_of("triangulate", o)
    except Malformed as exc:
        return w, f"triangulate: {exc}"
    if isinstance(value, (tuple, list)) and value:
        value = value[0]
    try:
        w[good] = np.asarray(value, dtype=float).reshape(int(good.sum()), 3)
    except (TypeError, ValueError):
        return w, "triangulate did not return (N, 3) points first"
    return w, ""


@pytest.mark.points(5, question="Q4.2", name="3D points of the temple")
def test_3D_points_of_the_temple(student, correspondence, matched, score):
    c = correspondence.points_case
    n = len(c.pts1)
    o = student.each("compute3D_pts", [(c.im1, c.im2, c.F, c.pts1[:, :1].copy(), c.pts1[:, 1:].copy(), c.C1, c.C2)],
                     seconds=SECONDS[_MATCH] * n + SECONDS["compute3D_pts.triangulate"])[0]
    direct_v, direct_problem = None, ""
    try:
        w = jc.read_points(value_of("compute3D_pts", o), n)
        direct_v = jc.points3d(w, c.C1, c.C2, c.pts1, c.truth2, c.tol, c.ref_share_3d)
    except Malformed as exc:
        direct_problem = str(exc)
    w, pipe_problem = _pipeline(student, c, matched[c])
    pipe_v = None if w is None else jc.points3d(w, c.C1, c.C2, c.pts1, c.truth2, c.tol, c.ref_share_3d)
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
        lines.append(f"compute3D_pts: {direct_problem or 'no result'}")
        lines.append(f"epipolarCorrespondence + triangulate: {pipe_problem or 'no result'}")
        score.grade(0.0, lines)
    lines.append(f"{c.label}: {v.measured} of the point and its true match in both images "
                 f"(full marks from {v.goal[3:]})")
    score.grade(v.fraction, lines, v.mistakes)
