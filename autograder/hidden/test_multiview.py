"""Q6 (extra credit): ``MultiviewReconstruction`` and ``plot_3d_keypoint_video`` on hidden car data (judging.multiview).

- A hidden car sequence (three cameras, a few time steps, noisy detections): on the keypoints the
  reference reconstructs (two confident views or more), the mean distance of the student's
  points from the true ones must be within 1.5 times the reference's plus 1 cm.  Every step has
  keypoints confident in views (1, 3) only and in (2, 3) only, the third detection 40-80 px off, so
  two confident views are not always views 1 and 2.
- Threshold probes: exact detections above ``Thres`` and clearly wrong ones at or below it, built
  so that using a detection at exactly Thres (``>=``), ignoring the threshold, or leaving out a
  detection just above it each puts some keypoints off.  Every keypoint must come out right.
- ``err`` must be the total squared reprojection error of the returned P over the detections
  used (on the sequence's steps; a method using two of three confident views is welcome).
- ``plot_3d_keypoint_video`` must run on a (T, 12, 3) sequence, and its figure (returned, or
  opened with pyplot) must show at least 90 % of the keypoints (axes may be swapped or flipped).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from autograder.inputs.cases import SECONDS
from autograder.feedback.words import called_as, read_returned
from judging import multiview as jm
from judging.verdict import Malformed, figure_text, read_array

_PLOT_SHARE = 0.9
# Plots often show the car with axes swapped or flipped (y up): any signed permutation is fine.
_AXES = [(perm, signs) for perm in itertools.permutations(range(3))
         for signs in itertools.product((1.0, -1.0), repeat=3)]


@pytest.fixture(scope="session")
def multiview(hidden):
    """The prepared inputs (``autograder.inputs.multiview.Multiview``)."""
    return hidden.prepared["multiview"]


@pytest.fixture(scope="session")
def reconstructed(student, multiview) -> dict:
    """The student's (P (12, 3), err as returned) (or the Malformed) of every step, sequence and probes:
    one request."""
    steps = (*multiview.sequence, *multiview.probes)
    inputs = [(s.C[0], s.pts[0], s.C[1], s.pts[1], s.C[2], s.pts[2], s.Thres) for s in steps]
    outcomes = student.each("MultiviewReconstruction", inputs, seconds=SECONDS["MultiviewReconstruction"])
    out = {}
    for step, args, o in zip(steps, inputs, outcomes):
        try:
            out[step] = read_returned("MultiviewReconstruction", o, lambda v, n=len(step.P_true): jm.read_P_err(v, n),
                                     args)
        except Malformed as exc:
            out[step] = exc
    return out


def _grade_steps(steps, reconstructed, judge, line, score) -> None:
    """Grade ``steps`` by the share whose ``judge(step, P, err)`` Verdict passed; one feedback line
    per step, ``line(step, verdict)``, or the failed call's sentence; the verdicts' mistakes named."""
    right, lines, mistakes = 0, [], []
    for step in steps:
        got = reconstructed[step]
        if isinstance(got, Malformed):
            lines.append(f"{step.label}: {got}")
            continue
        v = judge(step, *got)
        right += v.passed
        mistakes += v.mistakes
        lines.append(line(step, v))
    score.grade(right / len(steps), lines, mistakes)


@pytest.mark.points(8, question="Q6", name="3D keypoints of a hidden car sequence")
def test_3D_keypoints_of_a_car_sequence(multiview, reconstructed, score):
    _grade_steps(multiview.sequence, reconstructed,
                 lambda step, P, err: jm.sequence(P, step.P_true, step.judged, step.goal),
                 lambda step, v: f"{step.label}: " + figure_text(v.passed, f"{v.measured} m of your keypoints from the "
                                                                 "true ones", f"{v.goal} m"),
                 score)


@pytest.mark.points(4, question="Q6", name="only detections above Thres are used")
def test_only_detections_above_Thres_are_used(multiview, reconstructed, score):
    _grade_steps(multiview.probes, reconstructed,
                 lambda step, P, err: jm.threshold_probe(P, step.P_true, step.pts[:, :, 2].T, step.Thres, step.goal),
                 lambda step, v: (f"{step.label} (Thres = {step.Thres}): "
                                  + (f"{v.measured.split(' within')[0]} keypoints right" if v.passed else
                                     figure_text(False, f"{v.measured.split(' within')[0]} keypoints right", "all"))),
                 score)


@pytest.mark.points(1, question="Q6", name="err is the total squared reprojection error of P over the detections used")
def test_err_is_the_reprojection_error_of_P(multiview, reconstructed, score):
    _grade_steps(multiview.sequence, reconstructed,
                 lambda step, P, err: jm.err_reported(err, P, step.C, step.pts, step.Thres),
                 lambda step, v: f"{step.label}: " + (v.measured if v.passed else v.figure),
                 score)


def drawn_share(drawn: np.ndarray, video: np.ndarray) -> float:
    """Share of the sequence's keypoints (T, N, 3) that appear among the drawn 3D points (K, 3),
    up to a signed permutation of the axes and 1e-6 of the scene's size."""
    truth = video.reshape(-1, 3)
    truth = truth[np.all(np.isfinite(truth), axis=1)]
    drawn = drawn[np.all(np.isfinite(drawn), axis=1)]
    if len(truth) == 0 or len(drawn) == 0:
        return 0.0
    tol = 1e-6 * max(1.0, float(np.abs(truth).max()))
    order = np.argsort(drawn[:, 0])
    xs = drawn[order, 0]
    best = 0.0
    for perm, signs in _AXES:
        moved = truth[:, perm] * signs
        # Sorting by one coordinate lets each keypoint be looked up among nearby candidates only.
        lo = np.searchsorted(xs, moved[:, 0] - tol)
        hi = np.searchsorted(xs, moved[:, 0] + tol, side="right")
        hits = sum(bool(np.any(np.all(np.abs(drawn[order[a:b]] - m) <= tol, axis=1))) for m, a, b in zip(moved, lo, hi))
        best = max(best, hits / len(truth))
    return best


@pytest.mark.points(2, question="Q6", name="plot_3d_keypoint_video draws a sequence")
def test_plot_3d_keypoint_video_draws_a_sequence(student, multiview, score):
    o = student.each("plot_3d_keypoint_video", [(multiview.video,)], seconds=SECONDS["plot_3d_keypoint_video"],
                     figure=True)[0]
    args = (multiview.video,)
    try:
        # What the sandbox reports for a figure call: the (K, 3) points its 3D figures show.
        drawn = read_returned("plot_3d_keypoint_video", o, lambda v: read_array(v, (None, 3), "the drawn points"),
                              args)
    except Malformed as exc:
        score.grade(0.0, [str(exc)])
    shown = drawn_share(drawn, multiview.video)
    lines = [figure_text(shown >= _PLOT_SHARE, f"your figure shows {shown:.0%} of the keypoints of the sequence",
                         f">= {_PLOT_SHARE:.0%}")]
    if shown < _PLOT_SHARE:
        lines.append(f"{called_as('plot_3d_keypoint_video', None, args)}, its figures (returned or opened with "
                     f"pyplot) drew {len(drawn)} 3D points")
    score.grade(float(shown >= _PLOT_SHARE), lines)
