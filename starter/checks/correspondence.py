"""Public checks of Q4: ``epipolarCorrespondence`` and ``compute3D_pts``; every verdict is judging.correspondence's.

Another year's ``compute3D_pts(temple_pts1, intrinsics, F, im1, im2)`` is called as its
parameters ask, by the rules the grader uses (judging.conventions); when compute3D_pts gives no
points, the points of the student's own epipolarCorrespondence and triangulate count, as the
grader counts them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from judging import correspondence as jc
from judging.conventions import compute3D_pts_five_calls, five_arguments, signature_of_callable
from judging.verdict import Malformed
from starter.data import course_image

from ._common import finish, read_or_report, run_failed, stop_if_not_implemented
from ._scenes import NO_DEFAULT_DATA
from .report import CheckReport, Outcome, call

__all__ = ["MatchCase", "check_compute3D_pts", "check_epipolarCorrespondence"]

# The generated pair's easy points and the goals several correct matcher styles set on them: the
# styles are answers to Q4.1 and do not ship, so ``python -m kit check-data`` wrote them here.
GOALS_FILE = Path(__file__).with_name("matching_goals.json")
_CALL = "compute3D_pts(im1, im2, F, x1, y1, C1, C2)"


@dataclass(frozen=True, eq=False)
class MatchCase:
    """One matching problem: images, F, points pts1 (P, 2) of image 1 and their true matches truth2 (P, 2).

    C1, C2 (3, 4) the cameras; M2 (3, 4) camera 2's pose or None; tol the pixels a match may be
    off (judging.correspondence.tolerance); ref_share, ref_share_3d what a reference matcher
    reaches on these points (1 when unknown); truth1_3d, truth2_3d (P, 2) where a right 3D point
    reprojects in image 1 and 2 (default pts1 and truth2).
    """

    label: str
    im1: np.ndarray
    im2: np.ndarray
    F: np.ndarray
    pts1: np.ndarray
    truth2: np.ndarray
    C1: np.ndarray
    C2: np.ndarray
    tol: float
    ref_share: float = 1.0
    ref_share_3d: float = 1.0
    M2: np.ndarray | None = None
    truth3d: np.ndarray | None = None
    tol3d: np.ndarray | None = None
    flat_share_3d: float = 0.0


@lru_cache(maxsize=1)
def _default_scene():
    # The scene of data/temple, the images the notebook matches on: its relief tells a flat temple
    # from the true one (a small generated pair's does not), as the hidden scenes' does.
    from scenes.defaults import default_temple

    return default_temple()


@lru_cache(maxsize=1)
def _goals() -> dict:
    return json.loads(GOALS_FILE.read_text(encoding="utf-8"))


def _generated_case() -> MatchCase:
    s, g = _default_scene(), _goals()
    rows = np.asarray(g["rows"], dtype=int)
    pts1 = np.column_stack([np.ravel(s.x1)[rows], np.ravel(s.y1)[rows]]).astype(float)
    return MatchCase("generated", course_image(s.im1), course_image(s.im2), s.F_true, pts1, s.x2_true[rows], s.C1,
                     s.C2, jc.tolerance(s.width), g["ref_share"], g["ref_share_3d"], s.M2, s.X_coords[rows],
                     np.asarray(g["tol3d"], float), g["flat_share_3d"])


def _cases(cases, root) -> tuple[list, list[str]]:
    if cases is not None:
        return list(cases), []
    return [_generated_case()], [NO_DEFAULT_DATA]


def _match_all(fn, case) -> Outcome:
    """Outcome whose value is (P, 2) matches, one call of fn per point, with integer pixels as the course passes."""
    found = []
    for x, y in np.asarray(case.pts1):
        # Fresh copies: code that writes into its inputs must not spoil the next call's images.
        out = call(fn, case.im1.copy(), case.im2.copy(), np.array(case.F, float), int(round(x)), int(round(y)))
        if not out.ok:
            return out
        try:
            found.append(jc.read_match(out.value))
        except Malformed as exc:
            return Outcome("error", message=str(exc))
    return Outcome("ok", np.array(found))


def check_epipolarCorrespondence(epipolarCorrespondence, *, cases=None, root=None, verbose: bool = True) -> CheckReport:
    """Match points of a generated pair (true matches known).

    Parameters
    ----------
    epipolarCorrespondence : the student's function (im1, im2, F, x1, y1) -> (x2, y2), images
        (H, W, 3), F (3, 3) with x2^T F x1 = 0, pixels (x, y) = (column, row).
    cases : the MatchCases to check on (default: a generated 320 x 240 pair with its true F).
    root : accepted like every check's; the default data are not used (they have no F).
    verbose : print the report.

    Checked (judging.correspondence): the easy points (distinctive windows) matched within a few
    pixels of the true ones, as often as the weakest of several correct matcher styles, less 30 %.
    The images are float32 in [0, 1], as the notebooks load them.
    """
    report = CheckReport("epipolarCorrespondence")
    todo, notes = _cases(cases, root)
    report.notes.extend(notes)
    for k, case in enumerate(todo):
        out = _match_all(epipolarCorrespondence, case)
        if k == 0 and stop_if_not_implemented(report, out):
            return finish(report, verbose)
        if not run_failed(report, out, case.label):
            report.judged(jc.matches(out.value, case.truth2, case.tol, case.ref_share, case.pts1), case.label)
    return finish(report, verbose, epipolarCorrespondence, root)


def _explain_call_error(out: Outcome) -> Outcome:
    if out.status == "error" and out.message.startswith("TypeError") and "argument" in out.message:
        return Outcome("error", message=f"could not be called as {_CALL} ({out.message}); the checks use "
                                        "that signature, which the reference uses too")
    return out


def _five_argument_call(compute3D_pts, signature, case, n) -> tuple[Outcome, str]:
    """(outcome, how) of 2022-2024's compute3D_pts(temple_pts1, intrinsics, F, im1, im2) on ``case``:
    the first call whose result holds the points, else the first call's outcome."""
    K1 = np.asarray(case.C1, float)[:, :3]
    M2 = getattr(case, "M2", None)
    K2 = np.asarray(case.C2, float)[:, :3] @ np.asarray(M2, float)[:, :3].T if M2 is not None else K1
    first = None
    for c in compute3D_pts_five_calls(signature, case.pts1, K1, K2, case.F, case.im1.copy(), case.im2.copy()):
        out = call(compute3D_pts, *c.args)
        first = first or (out, c.how)
        if out.ok:
            try:
                jc.read_points(out.value, n)
            except Malformed:
                continue
            return out, c.how
    return first


def _pipeline_points(matcher, triangulate, case) -> Outcome:
    """Outcome whose value is w (P, 3): the student's matches of ``case`` put through their triangulate."""
    matched = _match_all(matcher, case)
    if not matched.ok:
        return matched
    p1 = np.asarray(case.pts1, float)
    out = call(triangulate, np.array(case.C1, float), p1.copy(), np.array(case.C2, float), matched.value)
    if out.ok and isinstance(out.value, (tuple, list)) and out.value:
        return Outcome("ok", out.value[0])
    return out


def check_compute3D_pts(compute3D_pts, *, cases=None, root=None, epipolarCorrespondence=None, triangulate=None,
                        verbose: bool = True) -> CheckReport:
    """Reconstruct points of a generated pair (true 3D known).

    Parameters
    ----------
    compute3D_pts : the student's function (None: a hand-in without one, as 2018-2021's whose
        Q4.2 was a script: the points of epipolarCorrespondence and triangulate are judged, as
        the grader does), called as compute3D_pts(im1, im2, F, x1, y1, C1,
        C2) with x1, y1 (N, 1) integer arrays like templeCoords.npz's; it returns w (N, 3) or
        (w, pts2) with pts2 (N, 2) the matches found.  2022-2024's compute3D_pts(temple_pts1,
        intrinsics, F, im1, im2), returning P (or P among the cameras), is called that way.
    cases : the MatchCases to check on (default as for check_epipolarCorrespondence).
    root : accepted like every check's; the default data are not used (they have no F or cameras).
    epipolarCorrespondence, triangulate : the student's own (default: those compute3D_pts sees
        as globals, as in a notebook); when compute3D_pts returns no points (another year's
        returned only cameras), the points of these two count, as in the grader.
    verbose : print the report.

    Checked (judging.correspondence): the easy points' 3D points lie on the true structure, up to
    a similarity, as often as several correct matcher styles make them (less 30 %).
    """
    report = CheckReport("compute3D_pts")
    todo, notes = _cases(cases, root)
    report.notes.extend(notes)
    signature = signature_of_callable(compute3D_pts)
    five = five_arguments(signature)
    if five:
        report.notes.append("compute3D_pts was called as its parameters ask: compute3D_pts(temple_pts1, intrinsics, "
                            "F, im1, im2); the points are judged up to a similarity")
    scope = getattr(compute3D_pts, "__globals__", {})
    matcher = epipolarCorrespondence or scope.get("epipolarCorrespondence")
    triangulate = triangulate or scope.get("triangulate")
    if compute3D_pts is None:
        if not (callable(matcher) and callable(triangulate)):
            report.add("compute3D_pts is defined", False, "no compute3D_pts, and no epipolarCorrespondence and "
                                                           "triangulate to judge in its place")
            return finish(report, verbose)
        report.notes.append("no compute3D_pts: the points of your epipolarCorrespondence and triangulate are "
                            "judged, as the grader does")
    for k, case in enumerate(todo):
        p1 = np.rint(np.asarray(case.pts1, float)).astype(np.uint16)
        if compute3D_pts is None:
            out = _pipeline_points(matcher, triangulate, case)
        elif five:
            out, how = _five_argument_call(compute3D_pts, signature, case, len(p1))
        else:
            out = _explain_call_error(call(compute3D_pts, case.im1.copy(), case.im2.copy(), np.array(case.F, float),
                                           p1[:, :1].copy(), p1[:, 1:].copy(), np.array(case.C1, float),
                                           np.array(case.C2, float)))
        if k == 0 and stop_if_not_implemented(report, out):
            return finish(report, verbose)
        if run_failed(report, out, case.label):
            continue
        try:
            w = jc.read_points(out.value, len(p1))
        except Malformed as exc:
            w = None
            if callable(matcher) and callable(triangulate):
                piped = _pipeline_points(matcher, triangulate, case)
                if piped.ok:
                    report.notes.append(f"{case.label}: compute3D_pts gave no points ({exc}): the points of your "
                                        "epipolarCorrespondence and triangulate are judged, as the grader does")
                    w = read_or_report(report, jc.read_points, piped.value, len(p1),
                                       label=f"your matches triangulated ({case.label})")
                    if w is None:
                        continue
            if w is None:
                report.add(f"returns w (N, 3) or (w, pts2) ({case.label})", False, str(exc))
                continue
        truth3d, tol3d = getattr(case, "truth3d", None), getattr(case, "tol3d", None)
        if truth3d is None or tol3d is None:
            report.notes.append(f"{case.label}: no true 3D points to judge the structure against")
            continue
        report.judged(jc.points3d(w, truth3d, tol3d, case.ref_share_3d, case.pts1,
                                  None if five else getattr(case, "M2", None),
                                  getattr(case, "flat_share_3d", 0.0)), case.label)
    return finish(report, verbose, compute3D_pts, root)
