"""Public check of Q3.3: ``findM2(F, pts1, pts2, K1, K2) -> (M2, C2, w)``."""

from __future__ import annotations

import numpy as np

from . import mistakes as mk
from ._common import as_array, fig, finish, run_failed, stop_if_not_implemented
from ._scenes import default_temple, opencv_reference, two_view
from .report import CheckReport, call

__all__ = ["check_findM2"]

_EXACT_DEG = 0.01
_DEFAULT_DEG = 0.5


def _angle(u, v) -> float:
    c = np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _rotation_angle(Ra, Rb) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1.0) / 2.0, -1.0, 1.0))))


def _judge(report, value, K2, M1, M2_true, n, where, tol_deg, min_front):
    """Items for one findM2 result; ``value`` is M2 or a tuple starting with it."""
    parts = tuple(value) if isinstance(value, (tuple, list)) else (value,)
    M2, why = as_array(parts[0], (3, 4), "M2")
    if M2 is None or not np.all(np.isfinite(M2)):
        report.add(f"returns M2 (3x4) first ({where})", False, why or "M2: expected finite numbers")
        return
    R, t = M2[:, :3], M2[:, 3]
    orth = float(np.abs(R @ R.T - np.eye(3)).max())
    proper = orth <= 1e-6 and np.linalg.det(R) > 0
    report.add(f"M2 = [R | t] with R a rotation ({where})", proper,
               f"|R R^T - I| = {fig(orth)}, det R = {fig(np.linalg.det(R))}", "0 and +1")
    if not np.any(t):
        report.add(f"t is not zero ({where})", False, "t = 0")
        return
    rot, dirn = _rotation_angle(R, M2_true[:, :3]), _angle(t, M2_true[:, 3])
    report.add(f"the right camera of the four ({where})", max(rot, dirn) <= tol_deg,
               f"R off by {fig(rot)} deg, t by {fig(dirn)} deg", f"< {tol_deg:g} deg",
               [mk.wrong_camera(M2, M2_true)] if max(rot, dirn) > tol_deg else ())
    if len(parts) >= 2:
        C2, why = as_array(parts[1], (3, 4), "C2")
        ok = C2 is not None and mk.same_up_to_scale(C2, K2 @ M2, 1e-6)
        report.add(f"C2 = K2 M2 ({where})", ok, "" if ok else (why or "C2 differs from K2 @ M2"))
    if len(parts) >= 3:
        w, why = as_array(parts[2], (n, 3), "w")
        if w is None:
            report.add(f"w is (N, 3) ({where})", False, why)
        else:
            z = np.minimum(w @ M1[2, :3] + M1[2, 3], w @ M2[2, :3] + M2[2, 3])
            front = int(np.sum(z > 0))
            ok = front >= min_front * n
            report.add(f"points in front of both cameras ({where})", ok, f"{front} of {n}",
                       "all" if min_front == 1 else f">= {min_front:.0%}",
                       [] if ok else [mk.points_behind_cameras(w, M1, M2)])


def check_findM2(findM2, *, root=None, verbose: bool = True) -> CheckReport:
    """Run ``findM2`` with a known F and known pose, and on the default data.

    Parameters
    ----------
    findM2 : the student's function (F (3, 3), pts1 (N, 2), pts2 (N, 2), K1, K2) -> M2 (3, 4),
        or a tuple starting with M2 (the reference returns (M2, C2, w)).
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked: R is a rotation; M2 is the true camera (R, and t up to a positive scale), not one of
    the other three; C2 = K2 M2 and the points are in front of both cameras when returned.  On
    the default data, M2 is compared with the pose OpenCV recovers from the same F.
    """
    report = CheckReport("findM2")
    tv = two_view()
    out = call(findM2, tv.F.copy(), tv.pts1.copy(), tv.pts2.copy(), tv.K1.copy(), tv.K2.copy())
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "a generated scene"):
        _judge(report, out.value, tv.K2, tv.M1, tv.M2, len(tv.X), "generated", _EXACT_DEG, 1.0)

    data, note = default_temple(root)
    ref, note_cv = opencv_reference(data) if data is not None else (None, "")
    if data is None or ref is None:
        report.notes.append(note or note_cv)
    else:
        out = call(findM2, ref.F.copy(), data.pts1.copy(), data.pts2.copy(), data.K1.copy(), data.K2.copy())
        if not run_failed(report, out, "the default data"):
            _judge(report, out.value, data.K2, tv.M1, ref.M2, len(data.pts1), "default data", _DEFAULT_DEG, 0.95)
    return finish(report, verbose)
