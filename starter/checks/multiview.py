"""Public check of Q6.1: ``MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres) -> (P, err)``;
every verdict is judging.multiview's."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from core.geometry import project
from judging import multiview as jm
from judging.verdict import Malformed, read_number

from ._common import finish, read_or_report, run_failed, stop_if_not_implemented
from ._scenes import PUBLIC_SEED, car_frame, default_car
from .report import CheckReport, call

__all__ = ["DESIGN_CONFIDENCE", "THRES", "check_MultiviewReconstruction"]

THRES = 500
# Confidences (keypoint, camera) of the generated detections.  Every detection at or below THRES
# is moved 40 px off its true pixel, every other one is exact, and each keypoint keeps at least
# two views above THRES: a right answer is the truth, and each threshold mistake shows up in its
# own rows (4-5 and 10: exactly THRES; 6-7 and 11: below; 8-9: need a view at THRES + 100).
DESIGN_CONFIDENCE = np.array([
    [900, 1000, 800], [1000, 900, 900], [800, 800, 1000], [900, 700, 900],
    [900, 800, 500], [1000, 900, 500],
    [900, 300, 1000], [800, 400, 900],
    [600, 900, 400], [600, 1000, 300],
    [500, 700, 900],
    [800, 900, 200],
], dtype=float)
_SHIFT_PX = 40.0
_TOL_M = 0.01
_DEFAULT_MEDIAN_PX = 10.0


def _generated():
    """Cameras (3, 3, 4), true keypoints (12, 3) and detections [(12, 3) per camera]."""
    C, P = car_frame()
    rng = np.random.default_rng(PUBLIC_SEED)
    pts = []
    for c in range(3):
        uv = project(C[c], P)
        bad = DESIGN_CONFIDENCE[:, c] <= THRES
        angle = rng.uniform(0, 2 * np.pi, len(P))
        uv[bad] += _SHIFT_PX * np.column_stack([np.cos(angle), np.sin(angle)])[bad]
        pts.append(np.column_stack([uv, DESIGN_CONFIDENCE[:, c]]))
    return C, P, pts


def _call(fn, C, pts, Thres) -> object:
    C = np.asarray(C, float)
    return call(fn, C[0].copy(), np.array(pts[0], float), C[1].copy(), np.array(pts[1], float), C[2].copy(),
                np.array(pts[2], float), Thres)


def check_MultiviewReconstruction(MultiviewReconstruction, *, probes=None, sequence=None, root=None,
                                  verbose: bool = True) -> CheckReport:
    """Reconstruct generated car keypoints built to expose threshold mistakes, and the default data.

    Parameters
    ----------
    MultiviewReconstruction : the student's function (C1, pts1, C2, pts2, C3, pts3, Thres) ->
        (P (N, 3), err); pts* are (N, 3) rows [x, y, confidence], a detection counts when its
        confidence is above Thres.
    probes : instead of the generated frame, threshold probes to check on: objects with C
        (3, 3, 4), pts (3, N, 3), Thres, P_true (N, 3), goal (the tolerance) and label.
    sequence : further noisy frames with the same fields, ``judged`` (N,) and ``goal`` the mean
        distance allowed (judging.multiview.sequence_goal).
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked (judging.multiview), with Thres = 500 on detections that are exact above it and 40 px
    off at or below it: every keypoint comes out at the truth (so no detection at or below Thres
    was used, and none above it was left out).  On the default data: every keypoint seen
    confidently twice is reconstructed and reprojects near its detections.
    """
    report = CheckReport("MultiviewReconstruction")
    explicit = probes is not None or sequence is not None
    if probes is None:
        C, P_true, pts = _generated()
        probes = [] if explicit else [SimpleNamespace(label="generated", C=C, pts=pts, Thres=THRES, P_true=P_true,
                                                      goal=_TOL_M)]
    todo = [(step, True) for step in probes] + [(step, False) for step in sequence or ()]
    for k, (step, is_probe) in enumerate(todo):
        out = _call(MultiviewReconstruction, step.C, step.pts, step.Thres)
        if k == 0 and stop_if_not_implemented(report, out):
            return finish(report, verbose)
        if run_failed(report, out, step.label):
            continue
        P = read_or_report(report, jm.read_P, out.value, len(step.P_true), label=f"returns (P (N, 3), err) ({step.label})")
        if P is None:
            continue
        if not is_probe:
            report.judged(jm.sequence(P, step.P_true, step.judged, step.goal), step.label)
            continue
        conf = np.stack([np.asarray(p)[:, 2] for p in step.pts], axis=1)
        report.judged(jm.threshold_probe(P, step.P_true, conf, step.Thres, step.goal), step.label)
        try:
            err = read_number(out.value[1], "err") if isinstance(out.value, (tuple, list)) else None
        except (Malformed, IndexError):
            err = None
        if not explicit and not (err is not None and 0 <= err <= 1e-3):
            # Advice only: the hidden tests do not judge err, so neither does the verdict here.
            report.notes.append("err over the detections used should be about 0 on the generated frame "
                                "(every detection used is exact)")

    frame, note = default_car(root) if not explicit else (None, "")
    if not explicit and frame is None:
        report.notes.append(note)
    elif frame is not None:
        out = _call(MultiviewReconstruction, frame.C, frame.pts, THRES)
        if not run_failed(report, out, "the default data"):
            P = read_or_report(report, jm.read_P, out.value, len(frame.pts[0]),
                               label="returns (P (N, 3), err) (default data)")
            if P is not None:
                report.judged(jm.reprojects_near(P, frame.C, frame.pts, THRES, _DEFAULT_MEDIAN_PX), "default data")
    return finish(report, verbose, MultiviewReconstruction, root)
