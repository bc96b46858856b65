"""Public checks of Q4: ``epipolarCorrespondence`` and ``compute3D_pts``."""

from __future__ import annotations

import numpy as np

from starter.epipolar import epipolar_distances

from . import mistakes as mk
from ._common import as_array, finish, run_failed, stop_if_not_implemented
from ._scenes import default_temple, opencv_reference, project, temple_scene
from .report import CheckReport, Outcome, call

__all__ = ["check_compute3D_pts", "check_epipolarCorrespondence"]

_N_POINTS = 30
_NEAR_PX = 3.0
_LINE_PX = 1.5
_SHARE_GENERATED = 0.7
_SHARE_DEFAULT = 0.6
_SHARE_FRONT = 0.9
_CALL = "compute3D_pts(im1, im2, F, x1, y1, C1, C2)"


def _generated_points():
    """Indices of the generated templeCoords points visible in image 2 (at most _N_POINTS)."""
    s = temple_scene()
    return np.flatnonzero(s.visible2)[:_N_POINTS]


def _default_points(data):
    # Every k-th clean match spreads the sample over the object.
    step = max(1, len(data.pts1) // _N_POINTS)
    return np.arange(0, len(data.pts1), step)[:_N_POINTS]


def _match_all(fn, im1, im2, F, xy1):
    """Outcome whose value is (K, 2) matches, one call of fn per point of xy1 (K, 2)."""
    found = []
    for x, y in xy1:
        # Fresh copies: code that writes into its inputs must not spoil the next call's images.
        out = call(fn, im1.copy(), im2.copy(), F.copy(), int(x), int(y))
        if not out.ok:
            return out
        arr = np.asarray(out.value, dtype=object)
        try:
            xy = np.asarray([np.asarray(v, dtype=float).reshape(()) for v in arr.ravel()]) if arr.size == 2 else None
        except (TypeError, ValueError):
            xy = None
        if xy is None:
            return Outcome("error", message=f"expected (x2, y2), two numbers, got {out.value!r:.80}")
        found.append(xy)
    return Outcome("ok", np.array(found))


def _match_items(report, F, xy1, xy2, truth, share_goal, where):
    near = np.linalg.norm(xy2 - truth, axis=1) <= _NEAR_PX
    report.add(f"matches within {_NEAR_PX:g} px of the true ones ({where})", near.mean() >= share_goal,
               f"{int(near.sum())} of {len(near)}", f">= {share_goal:.0%}",
               [mk.points_xy_swapped(xy2, truth, _NEAR_PX)] if near.mean() < share_goal else ())
    on = epipolar_distances(F, xy1, xy2) <= _LINE_PX
    report.add(f"matches on the epipolar line ({where})", on.mean() >= 0.9,
               f"{int(on.sum())} of {len(on)} within {_LINE_PX:g} px", ">= 90%")


def check_epipolarCorrespondence(epipolarCorrespondence, *, root=None, verbose: bool = True) -> CheckReport:
    """Match points of a generated pair (true matches known) and of the default data.

    Parameters
    ----------
    epipolarCorrespondence : the student's function (im1, im2, F, x1, y1) -> (x2, y2), images
        (H, W, 3) uint8, F (3, 3) with x2^T F x1 = 0, pixels (x, y) = (column, row).
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked: most matches within 3 px of the true ones and nearly all on the epipolar line, on a
    generated 320x240 pair with its true F, and on the default data's clean matches with an F
    OpenCV fits to them.
    """
    report = CheckReport("epipolarCorrespondence")
    s = temple_scene()
    idx = _generated_points()
    xy1 = np.column_stack([s.x1[idx, 0], s.y1[idx, 0]]).astype(float)
    out = _match_all(epipolarCorrespondence, s.im1, s.im2, s.F_true, xy1)
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "a generated pair"):
        _match_items(report, s.F_true, xy1, out.value, s.x2_true[idx], _SHARE_GENERATED, "generated")

    data, note = default_temple(root)
    ref, note_cv = opencv_reference(data) if data is not None else (None, "")
    if data is None or ref is None:
        report.notes.append(note or note_cv)
    else:
        k = _default_points(data)
        out = _match_all(epipolarCorrespondence, data.im1, data.im2, ref.F, data.pts1[k])
        if not run_failed(report, out, "the default data"):
            _match_items(report, ref.F, data.pts1[k], out.value, data.pts2[k], _SHARE_DEFAULT, "default data")
    return finish(report, verbose)


def _read_w(report, value, n, where):
    """w (n, 3) from compute3D_pts's result, w alone or (w, pts2); None after reporting why."""
    cand = value[0] if isinstance(value, (tuple, list)) and len(value) in (2, 3) else value
    w, why = as_array(cand, (n, 3), "w")
    if w is None:
        report.add(f"returns w (N, 3) or (w, pts2) ({where})", False, why)
    return w


def _explain_call_error(out: Outcome) -> Outcome:
    if out.status == "error" and out.message.startswith("TypeError") and "argument" in out.message:
        return Outcome("error", message=f"could not be called as {_CALL} ({out.message}); the checks use "
                                        "that signature, which the reference uses too")
    return out


def _reconstruction_items(report, w, w_ref, C1, C2, M1, M2, share_goal, where):
    # Compared in the images, through the same cameras, so that errors of the cameras (on the
    # default data they are an estimate) do not count against the matching.
    with np.errstate(invalid="ignore"):
        d1 = np.linalg.norm(project(C1, w) - project(C1, w_ref), axis=1)
        d2 = np.linalg.norm(project(C2, w) - project(C2, w_ref), axis=1)
    good = (d1 <= _NEAR_PX) & (d2 <= _NEAR_PX)
    report.add(f"3D points near the true ones ({where})", good.mean() >= share_goal,
               f"{int(good.sum())} of {len(good)} within {_NEAR_PX:g} px in both images", f">= {share_goal:.0%}")
    z = np.minimum(w @ M1[2, :3] + M1[2, 3], w @ M2[2, :3] + M2[2, 3])
    front = z > 0
    report.add(f"points in front of both cameras ({where})", front.mean() >= _SHARE_FRONT,
               f"{int(front.sum())} of {len(front)}", f">= {_SHARE_FRONT:.0%}",
               [mk.points_behind_cameras(w, M1, M2)] if front.mean() < _SHARE_FRONT else ())


def check_compute3D_pts(compute3D_pts, *, root=None, verbose: bool = True) -> CheckReport:
    """Reconstruct points of a generated pair (true 3D known) and of the default data.

    Parameters
    ----------
    compute3D_pts : the student's function, called as compute3D_pts(im1, im2, F, x1, y1, C1,
        C2) with x1, y1 (N, 1) uint16 arrays like templeCoords.npz's; it returns w (N, 3) or
        (w, pts2) with pts2 (N, 2) the matches found.
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked: most points project within 3 px of where the true 3D points do, in both images, and
    nearly all are in front of both cameras.  On the default data the "true" points are the
    clean matches triangulated with the cameras OpenCV recovers (the same cameras are given).
    """
    report = CheckReport("compute3D_pts")
    s = temple_scene()
    idx = _generated_points()
    x1, y1 = s.x1[idx].copy(), s.y1[idx].copy()
    out = _explain_call_error(call(compute3D_pts, s.im1.copy(), s.im2.copy(), s.F_true.copy(), x1, y1, s.C1.copy(), s.C2.copy()))
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "a generated pair"):
        w = _read_w(report, out.value, len(idx), "generated")
        if w is not None:
            _reconstruction_items(report, w, s.X_coords[idx], s.C1, s.C2, s.M1, s.M2, _SHARE_GENERATED,
                                  "generated")

    data, note = default_temple(root)
    ref, note_cv = opencv_reference(data) if data is not None else (None, "")
    if data is None or ref is None:
        report.notes.append(note or note_cv)
    else:
        k = _default_points(data)
        p1 = data.pts1[k]
        cx, cy = p1[:, :1].astype(np.uint16), p1[:, 1:].astype(np.uint16)
        out = _explain_call_error(call(compute3D_pts, data.im1.copy(), data.im2.copy(), ref.F.copy(), cx, cy,
                                       ref.C1.copy(), ref.C2.copy()))
        if not run_failed(report, out, "the default data"):
            w = _read_w(report, out.value, len(k), "default data")
            if w is not None:
                M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
                _reconstruction_items(report, w, ref.w[k], ref.C1, ref.C2, M1, ref.M2, _SHARE_DEFAULT,
                                      "default data")
    return finish(report, verbose)
