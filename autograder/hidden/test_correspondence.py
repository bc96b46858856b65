"""Q4.1 ``epipolarCorrespondence`` and Q4.2 ``compute3D_pts`` on hidden temple scenes (judging.correspondence).

Q4.1, one test per scene: the scene's easy points (distinctive windows along the true epipolar
line, solutions.matching_styles) are matched with the true F; the share of matches within a few
pixels of the truth is compared with what the weakest of several correct matcher styles (SSD,
SAD, NCC, Gaussian-weighted; 5 to 101 px; local and whole-line search) reaches on those points.
Full marks at 70 % of it, nothing at 20 % of it, linear between (the handout asks for the easy
points, not every point).  The hidden scenes are matching temples of their own, at the official
pair's pixel scale, and the points judged are those whose match no +-10 px box and no point of
the line F^T x1 comes within tolerance of (autograder.inputs.correspondence): searching the
wrong line or never leaving a small box then loses most of the question.

Q4.2, on hidden scene 2's matching temple, its easy points spread over every depth: the
3D points of the easy points must lie on the temple's structure, up to a similarity
(judging.correspondence.right_structure); the pts2 returned with them must be the matches they
were triangulated from.  Graded through the student's ``compute3D_pts(im1, im2, F, x1, y1, C1, C2)`` when it
accepts the reference signature and through their ``epipolarCorrespondence`` + ``triangulate``
pipeline otherwise (the matcher called on Q4.2's points); the better of the two counts, and
the feedback says which was used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from autograder.inputs.cases import SECONDS, matching_labels
from autograder.feedback.words import called_as, failure, read_returned, returned
from autograder.hidden.plugin import config_of
from starter.data import course_image
from judging import correspondence as jc
from judging.conventions import compute3D_pts_five_calls, five_arguments
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
    how: str = ""


def _point(value):
    try:
        arr = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        return None
    return (float(arr[0]), float(arr[1])) if arr.size == 2 else None


# The ways the matcher is called: first as the course's notebooks call it (templeCoords' integer
# pixels as Python ints, images as plt.imread gives a PNG), then as earlier kits did (float
# coordinates, the 8-bit images); the better result counts and the feedback says which was used.
CONVENTIONS = {
    "course": ("integer pixel coordinates (Python ints) and float images in [0, 1] (as plt.imread gives a PNG)",
               lambda x: int(round(float(x))), course_image),
    "uint8": ("float coordinates and uint8 images", float, lambda im: np.asarray(im, dtype=np.uint8)),
}


def _match(student, case, convention: str = "course") -> Matched:
    how, coord, image = CONVENTIONS[convention]
    im1, im2 = image(case.im1), image(case.im2)
    outcomes = student.each(_MATCH, [(coord(x), coord(y)) for x, y in case.pts1], args=(im1, im2, case.F),
                            seconds=SECONDS[_MATCH], slack=5 * student.time_scale + 2)
    pts2 = np.full((len(case.pts1), 2), np.nan)
    example = (im1, im2, case.F, coord(case.pts1[0, 0]), coord(case.pts1[0, 1]))
    called = called_as(_MATCH, ("im1", "im2", "F", "x1", "y1"), example)
    if outcomes and all(o.status == "missing" for o in outcomes):
        return Matched(failure(_MATCH, outcomes[0]), pts2, how=how)
    if outcomes and not any(o.ok for o in outcomes) and outcomes[0].status in ("timeout", "crashed"):
        return Matched(f"{failure(_MATCH, outcomes[0])}; {called}", pts2, how=how)
    errors, first, reached = 0, "", 0
    for k, o in enumerate(outcomes):
        if o.status == "skipped":
            continue
        reached += 1
        point = _point(o.value) if o.ok else None
        if point is None:
            errors += 1
            first = first or (f"{failure(_MATCH, o)}; {called}" if not o.ok
                              else f"{_MATCH} should return the two numbers (x2, y2); {called} returned "
                                   f"{returned(o.value)}")
            continue
        pts2[k] = point
    return Matched(None, pts2, errors, first, reached, how)


def best_match(student, case) -> Matched:
    """The course's call, and the earlier kits' call when the first is not worth full marks: the better one."""
    first = _match(student, case, "course")
    v1 = None if first.problem else jc.matches(first.pts2, case.truth2, case.tol, case.ref_share, case.pts1)
    if v1 is not None and v1.passed and not first.errors:
        return first
    if first.problem and first.problem.endswith("is not defined in your notebooks"):
        return first
    second = _match(student, case, "uint8")
    if second.problem:
        return first
    v2 = jc.matches(second.pts2, case.truth2, case.tol, case.ref_share, case.pts1)
    return second if v1 is None or v2.fraction > v1.fraction else first



@pytest.fixture(scope="session")
def correspondence(hidden):
    """The prepared inputs (``autograder.inputs.correspondence.Correspondence``)."""
    return hidden.prepared["correspondence"]


@pytest.fixture(scope="session")
def matched(student, correspondence) -> dict:
    """``Matched`` of every scene, by case: the student's matcher called once per point, once per run."""
    return {case: best_match(student, case) for case in correspondence.cases}


def test_matches(correspondence, matched, scene_index, score):
    """The share of the student's matches within a few pixels of the true ones, against the reference's."""
    case = correspondence.cases[scene_index]
    m = matched[case]
    if m.problem:
        score.grade(0.0, [m.problem])
    v = jc.matches(m.pts2, case.truth2, case.tol, case.ref_share, case.pts1)
    lines = [f"{case.label}: {len(case.pts1)} easy points (distinctive windows along the true epipolar line) "
             f"judged; {v.measured} of the true ones (full marks from {v.goal[3:]}, set from the weakest of "
             f"{len(case.shares)} correct matcher styles, {case.ref_share:.0%} on these points)",
             *v.lines, f"{_MATCH} was called with {m.how}"]
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
    args = (case.C1, case.pts1[good], case.C2, m.pts2[good])
    o = student.each("triangulate", [args], seconds=SECONDS["compute3D_pts.triangulate"])[0]
    try:
        w[good] = read_returned("triangulate", o, lambda v: _first_points(v, int(good.sum())), args)
    except Malformed as exc:
        return w, f"triangulate: {exc}"
    return w, ""


def _first_points(value, n: int) -> np.ndarray:
    """The (n, 3) points triangulate returned first (or alone), or Malformed."""
    if isinstance(value, (tuple, list)) and value:
        value = value[0]
    try:
        return np.asarray(value, dtype=float).reshape(n, 3)
    except (TypeError, ValueError):
        raise Malformed("triangulate did not return (N, 3) points first") from None


def _five_argument_points(student, c, n, signature):
    """(verdict, how, problem) of compute3D_pts(temple_pts1, intrinsics, F, im1, im2): the points
    come in the frame of the student's own findM2 (|t| = 1), judged up to a similarity; returned
    alone or in a tuple with the cameras ((M2, C2, P) as 2022-2024 hand-ins return them)."""
    K = c.C1[:, :3]
    problem = ""
    for call in compute3D_pts_five_calls(signature, c.pts1, K, K, c.F, course_image(c.im1), course_image(c.im2)):
        o = student.each("compute3D_pts", [call.args], seconds=SECONDS[_MATCH] * n
                         + SECONDS["compute3D_pts.triangulate"] + SECONDS["findM2"])[0]
        try:
            w = read_returned("compute3D_pts", o, lambda v: jc.read_points(v, n), call.args, names=call.names)
        except Malformed as exc:
            problem = problem or str(exc)
            continue
        return _structure(w, c), call.how, ""
    return None, "", problem


def _structure(w, c):
    """The verdict of 3D points w (P, 3) of the case's easy points on its true structure."""
    return jc.points3d(w, c.truth3d, c.tol3d, c.ref_share_3d, c.pts1, flat_share=c.flat_share_3d)


def _linear_error(C1, pts1, C2, pts2) -> float:
    """The total squared reprojection error of the reference's linear triangulation of the matches
    (NaN, which no error is below, when they cannot be triangulated)."""
    from solutions import triangulate

    try:
        with np.errstate(all="ignore"):
            return float(triangulate(C1, pts1, C2, pts2)[1])
    except (ValueError, np.linalg.LinAlgError):
        return float("nan")


@dataclass(frozen=True)
class TemplePoints:
    """Q4.2's result: the verdict of the 3D points counted (None: no route gave points), the feedback
    lines saying how they were got, and the verdict of the pts2 returned with them (None: none was)."""

    points: object
    lines: tuple[str, ...]
    pts2: object = None


@pytest.fixture(scope="session")
def temple_points(student, correspondence, matched, signatures) -> TemplePoints:
    """The student's 3D points of Q4.2's scene, through compute3D_pts or their matcher and triangulate."""
    c = correspondence.points_case
    n = len(c.pts1)
    direct_v, direct_problem, direct_how, direct_pts2 = None, "", "", None
    direct_sig = "compute3D_pts(im1, im2, F, x1, y1, C1, C2)"
    if five_arguments(signatures("compute3D_pts")):
        direct_sig = "compute3D_pts(temple_pts1, intrinsics, F, im1, im2) as the course calls it"
        direct_v, how, direct_problem = _five_argument_points(student, c, n, signatures("compute3D_pts"))
        direct_how = f"{how}, float images in [0, 1]; your points compared up to a similarity"
    for convention in (() if five_arguments(signatures("compute3D_pts")) else CONVENTIONS):
        how, coord, image = CONVENTIONS[convention]
        xy = np.vectorize(coord, otypes=[int if coord is not float else float])(c.pts1)
        args = (image(c.im1), image(c.im2), c.F, xy[:, :1].copy(), xy[:, 1:].copy(), c.C1, c.C2)
        o = student.each("compute3D_pts", [args], seconds=SECONDS[_MATCH] * n + SECONDS["compute3D_pts.triangulate"])[0]
        try:
            w, pts2 = read_returned("compute3D_pts", o, lambda v: jc.read_points_pts2(v, n), args)
            v = _structure(w, c)
        except Malformed as exc:
            direct_problem = direct_problem or str(exc)
            continue
        if direct_v is None or v.fraction > direct_v.fraction:
            direct_v, direct_how = v, how
            direct_pts2 = None if pts2 is None else jc.pts2_reported(pts2, w, c.C1, c.pts1, c.C2, c.tol, _linear_error)
        if v.passed:
            break
    m = matched[c] if c in matched else best_match(student, c)
    w, pipe_problem = _pipeline(student, c, m)
    pipe_v = None if w is None else _structure(w, c)
    if direct_v is not None and (pipe_v is None or direct_v.fraction >= pipe_v.fraction):
        return TemplePoints(direct_v, (f"graded through your {direct_sig}, called with {direct_how}",), direct_pts2)
    # Which function gave no result, and why: a point without one is otherwise only "no result".
    failed = _matcher_failures(m)
    if pipe_v is not None:
        why = f" (compute3D_pts: {direct_problem})" if direct_problem else \
            " (it placed more points right than your compute3D_pts)"
        return TemplePoints(pipe_v, ("graded through your epipolarCorrespondence and triangulate" + why, *failed,
                                     *([pipe_problem] if pipe_problem.startswith("triangulate: ") else [])))
    return TemplePoints(None, (f"compute3D_pts: {direct_problem or 'no result'}",
                               f"epipolarCorrespondence + triangulate: {pipe_problem or 'no result'}", *failed))


def _matcher_failures(m: Matched) -> list[str]:
    """Lines saying where the matcher gave no result on Q4.2's points: how many calls failed (the
    first one's exception, its place and the call) and how many were not reached in time."""
    lines = []
    if m.errors:
        lines.append(f"{_MATCH} failed on {m.errors} of {len(m.pts2)} points"
                     + (f", first: {m.first_error}" if m.first_error else ""))
    if m.reached < len(m.pts2) and not m.problem:
        lines.append(f"{_MATCH}: only {m.reached} of {len(m.pts2)} points were matched in the time allowed")
    return lines


@pytest.mark.points(4, question="Q4.2", name="3D points of the temple")
def test_3D_points_of_the_temple(correspondence, temple_points, score):
    c = correspondence.points_case
    v, lines = temple_points.points, list(temple_points.lines)
    if v is None:
        score.grade(0.0, lines)
    lines.append(f"{c.label}: {v.measured} on the temple's surface, up to a similarity, of its "
                 f"{len(c.pts1)} easy points (full marks from {v.goal[3:]}, set from the weakest of "
                 f"{len(c.shares)} correct matcher styles)")
    lines.extend(v.lines)
    score.grade(v.fraction, lines, v.mistakes)


@pytest.mark.points(1, question="Q4.2", name="pts2 are the matches w was triangulated from")
def test_pts2_are_the_matches_of_w(correspondence, temple_points, score):
    """Judged when compute3D_pts returned (w, pts2) and its points counted.  Without a pts2 (w alone,
    another year's P, the matcher and triangulate) the point follows the 3D points' share, as when
    Q4.2 was one check; with no right point at all, consistency earns nothing."""
    points, v = temple_points.points, temple_points.pts2
    if points is None:
        score.grade(0.0, list(temple_points.lines))
    if points.fraction <= 0:
        score.grade(0.0, ["no 3D point is right: nothing to check pts2 against"])
    if v is None:
        score.grade(points.fraction, ["no pts2 was returned with the points that counted: this point follows theirs"])
        return
    score.grade(v.fraction, [f"{correspondence.points_case.label}: {v.sentence}", *v.lines], v.mistakes)
