"""Public check of Q6.1: ``MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres) -> (P, err)``."""

from __future__ import annotations

import numpy as np

from . import mistakes as mk
from ._common import as_array, fig, finish, run_failed, stop_if_not_implemented, unpack
from ._scenes import PUBLIC_SEED, car_frame, default_car, project
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


def _read(report, value, n, where):
    pair, why = unpack(value, 2, "MultiviewReconstruction")
    if pair is None:
        report.add(f"returns (P, err) ({where})", False, why)
        return None, None
    P, why = as_array(pair[0], (n, 3), "P")
    err = float(np.asarray(pair[1], float).reshape(())) if np.size(pair[1]) == 1 else None
    if P is None or err is None:
        report.add(f"returns (P (N, 3), err) ({where})", False, why or "err: expected one number")
        return None, None
    return P, err


def check_MultiviewReconstruction(MultiviewReconstruction, *, root=None, verbose: bool = True) -> CheckReport:
    """Reconstruct generated car keypoints built to expose threshold mistakes, and the default data.

    Parameters
    ----------
    MultiviewReconstruction : the student's function (C1, pts1, C2, pts2, C3, pts3, Thres) ->
        (P (N, 3), err); pts* are (N, 3) rows [x, y, confidence], a detection counts when its
        confidence is above Thres.
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked, with Thres = 500 on detections that are exact above it and 40 px off at or below
    it: every keypoint comes out at the truth (so no detection at or below Thres was used, and
    none above it was left out), and err, over the detections used, is about 0.  On the default
    data: every keypoint seen confidently twice is reconstructed and reprojects near its
    detections.
    """
    report = CheckReport("MultiviewReconstruction")
    C, P_true, pts = _generated()
    out = call(MultiviewReconstruction, C[0].copy(), pts[0].copy(), C[1].copy(), pts[1].copy(), C[2].copy(),
               pts[2].copy(), THRES)
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "a generated frame"):
        P, err = _read(report, out.value, len(P_true), "generated")
        if P is not None:
            right = np.linalg.norm(P - P_true, axis=1) <= _TOL_M
            ok = bool(right.all())
            report.add(f"keypoints at the truth, Thres = {THRES} (generated)", ok,
                       f"{int(right.sum())} of {len(right)} within {_TOL_M * 100:g} cm", "all",
                       () if ok else mk.threshold_mistakes(P, P_true, DESIGN_CONFIDENCE, THRES, _TOL_M))
            report.add("err over the detections used is about 0 (generated)", np.isfinite(err) and 0 <= err <= 1e-3,
                       f"err = {fig(err)}", "0 ... 1e-3 px^2")

    frame, note = default_car(root)
    if frame is None:
        report.notes.append(note)
    else:
        Cs = frame.C
        out = call(MultiviewReconstruction, Cs[0].copy(), frame.pts[0].copy(), Cs[1].copy(), frame.pts[1].copy(),
                   Cs[2].copy(), frame.pts[2].copy(), THRES)
        if not run_failed(report, out, "the default data"):
            n = len(frame.pts[0])
            P, err = _read(report, out.value, n, "default data")
            if P is not None:
                used = np.stack([p[:, 2] > THRES for p in frame.pts], axis=1)
                need = used.sum(axis=1) >= 2
                done = need & np.all(np.isfinite(P), axis=1)
                report.add("default data: keypoints seen confidently twice are reconstructed", done.sum() == need.sum(),
                           f"{int(done.sum())} of {int(need.sum())}", "all")
                d = [np.linalg.norm(project(Cs[c], P[done]) - frame.pts[c][done, :2], axis=1)[used[done, c]]
                     for c in range(3)]
                d = np.concatenate(d) if done.any() else np.array([np.inf])
                med = float(np.median(d))
                report.add("default data: reprojection near the detections used", med <= _DEFAULT_MEDIAN_PX,
                           f"median {fig(med)} px", f"<= {_DEFAULT_MEDIAN_PX:g} px")
    return finish(report, verbose)
