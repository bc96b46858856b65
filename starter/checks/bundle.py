"""Public checks of Q5: ``rodriguesResidual`` and ``bundleAdjustment``."""

from __future__ import annotations

import numpy as np

from starter.rotations import invRodrigues, rodrigues

from . import mistakes as mk
from ._common import as_array, fig, finish, run_failed, stop_if_not_implemented, unpack
from ._scenes import PUBLIC_SEED, default_temple, opencv_reference, project, two_view
from .report import CheckReport, call

__all__ = ["check_bundleAdjustment", "check_rodriguesResidual"]

_N_RESIDUAL = 20
# A handout-style BFGS (numerical gradients over 3N + 6 unknowns) slows down steeply with N:
# about 1 s for 12 points here, 10 s for 20, 25 s for 30.
_N_BA = 12
_N_BA_DEFAULT = 12
_OPTIMUM_SLACK = 1.05


def _pack(w, M2) -> np.ndarray:
    return np.concatenate([np.asarray(w, float).ravel(), invRodrigues(M2[:, :3]), M2[:, 3]])


def _residuals(C1, K2, p1, p2, x) -> np.ndarray:
    """The handout's [(p1 - p1_hat).ravel(), (p2 - p2_hat).ravel()] at x = [w.ravel(), r2, t2]."""
    n = len(p1)
    w = x[:3 * n].reshape(n, 3)
    C2 = K2 @ np.hstack([rodrigues(x[3 * n:3 * n + 3]), x[3 * n + 3:, None]])
    return np.concatenate([(p1 - project(C1, w)).ravel(), (p2 - project(C2, w)).ravel()])


def _sse(C1, C2, p1, p2, w):
    r1, r2 = p1 - project(C1, w), p2 - project(C2, w)
    return float(np.sum(r1 ** 2) + np.sum(r2 ** 2)), r1, r2


def _read_residual(report, value, n, where):
    r = np.asarray(value, dtype=float) if np.size(value) == 4 * n else None
    if r is None:
        report.add(f"returns 4N residuals ({where})", False, f"expected {4 * n} numbers for N = {n}, got shape "
                                                            f"{np.shape(value)}")
    return None if r is None else r.ravel()


def check_rodriguesResidual(rodriguesResidual, *, root=None, verbose: bool = True) -> CheckReport:
    """Evaluate ``rodriguesResidual`` at the true configuration of a generated scene.

    Parameters
    ----------
    rodriguesResidual : the student's function (K1, M1, p1 (N, 2), K2, p2 (N, 2), x) -> (4N,)
        residuals, x = [w.ravel(), r2 (3,), t2 (3,)].
    root : accepted like every check's; this one needs no data.
    verbose : print the report.

    Checked: zero residuals for exact matches at the true x; for noisy matches, exactly the
    handout's [(p1 - p1_hat).ravel(), (p2 - p2_hat).ravel()] (an overall sign is accepted).
    """
    report = CheckReport("rodriguesResidual")
    tv = two_view()
    k = slice(0, _N_RESIDUAL)
    x = _pack(tv.X[k], tv.M2)
    out = call(rodriguesResidual, tv.K1.copy(), tv.M1.copy(), tv.pts1[k].copy(), tv.K2.copy(), tv.pts2[k].copy(),
               x.copy())
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "exact matches of a generated scene"):
        r = _read_residual(report, out.value, _N_RESIDUAL, "exact matches")
        if r is not None:
            dev = float(np.max(np.abs(r)))
            found = []
            if not dev <= 1e-6:
                # Points unpacked column-wise (w = x[:3N].reshape(3, N).T) zero the residuals at this x.
                n = _N_RESIDUAL
                alt = np.concatenate([tv.X[k].T.ravel(), x[3 * n:]])
                again = call(rodriguesResidual, tv.K1.copy(), tv.M1.copy(), tv.pts1[k].copy(), tv.K2.copy(),
                             tv.pts2[k].copy(), alt)
                if again.ok and np.size(again.value) == 4 * n and np.max(np.abs(np.asarray(again.value, float))) <= 1e-6:
                    found.append(mk.mistake("x_packing", "your residuals vanish when the points are packed "
                                                         "coordinate by coordinate"))
            report.add("zero at the true x for exact matches", dev <= 1e-6, f"largest |residual| {fig(dev)} px",
                       "< 1e-6 px", found)

    p1, p2 = tv.pts1_u16[k].astype(float), tv.pts2_u16[k].astype(float)
    out = call(rodriguesResidual, tv.K1.copy(), tv.M1.copy(), p1.copy(), tv.K2.copy(), p2.copy(), x.copy())
    if not run_failed(report, out, "noisy matches"):
        r = _read_residual(report, out.value, _N_RESIDUAL, "noisy matches")
        if r is not None:
            e = _residuals(tv.C1, tv.K2, p1, p2, x)
            dev = float(min(np.abs(r - e).max(), np.abs(r + e).max()))
            report.add("the handout's residual vector (noisy matches)", dev <= 1e-6,
                       f"largest difference {fig(dev)} px", "< 1e-6 px",
                       [mk.residual_layout(r, e)] if dev > 1e-6 else ())
    return finish(report, verbose)


def _start(tv, n, rng):
    """A perturbed start: camera 2 turned by 0.5 deg, t by 1 deg (same length), points moved by 0.5%."""
    axis = rng.normal(size=3)
    R0 = rodrigues(np.deg2rad(0.5) * axis / np.linalg.norm(axis)) @ tv.M2[:, :3]
    axis = np.cross(tv.M2[:, 3], rng.normal(size=3))
    t0 = rodrigues(np.deg2rad(1.0) * axis / np.linalg.norm(axis)) @ tv.M2[:, 3]
    depth = np.linalg.norm(tv.X[:n], axis=1, keepdims=True)
    w0 = tv.X[:n] + rng.normal(0.0, 0.005, (n, 3)) * depth
    return np.hstack([R0, t0[:, None]]), w0


def _read_ba(report, value, n, where):
    four, why = unpack(value, 4, "bundleAdjustment")
    if four is None:
        report.add(f"returns (M2, w, o1, o2) ({where})", False, why)
        return None
    M2, why_m = as_array(four[0], (3, 4), "M2")
    w, why_w = as_array(four[1], (n, 3), "w")
    o = [np.asarray(v, dtype=float).reshape(()) if np.size(v) == 1 else None for v in four[2:]]
    if M2 is None or w is None or o[0] is None or o[1] is None:
        report.add(f"returns (M2 (3x4), w (N, 3), o1, o2) ({where})", False,
                   why_m or why_w or "o1, o2: expected two numbers")
        return None
    if not (np.all(np.isfinite(M2)) and np.all(np.isfinite(w))):
        report.add(f"finite M2 and w ({where})", False, "NaN or inf in the result")
        return None
    return M2, w, float(o[0]), float(o[1])


def _ba_items(report, result, K1, M1, K2, p1, p2, M2_init, w_init, where, o_true=None):
    M2, w, o1, o2 = result
    C1 = K1 @ M1
    s1, r1, r2 = _sse(C1, K2 @ M2_init, p1, p2, w_init)
    s2, q1, q2 = _sse(C1, K2 @ M2, p1, p2, w)
    m1 = mk.error_not_sum_of_squares(o1, r1, r2, rtol=1e-3)
    m2 = mk.error_not_sum_of_squares(o2, q1, q2, rtol=1e-3)
    report.add(f"o1, o2 are the sums of squares at the start and at the end ({where})", m1 is None and m2 is None,
               f"o1 = {fig(o1, 6)}, o2 = {fig(o2, 6)}", f"{fig(s1, 6)} and {fig(s2, 6)} from your results",
               [m1 or m2])
    found = mk.ba_mistakes(s1, s2, M2_init[:, 3], M2[:, 3])
    report.add(f"the error decreases ({where})", s2 < s1 * (1 - 1e-9), f"{fig(s1)} -> {fig(s2)}", "lower",
               [m for m in found if m.code == "ba_not_decreasing"])
    ratio = np.linalg.norm(M2[:, 3]) / np.linalg.norm(M2_init[:, 3])
    report.add(f"the scale holds: |t| after / before ({where})", 0.2 <= ratio <= 5, fig(ratio), "0.2 ... 5",
               [m for m in found if m.code == "ba_scale_collapse"])
    if o_true is not None:
        goal = _OPTIMUM_SLACK * o_true
        report.add(f"reaches the optimum: error at most the true scene's ({where})", s2 <= goal, fig(s2),
                   f"<= {fig(goal)} ({_OPTIMUM_SLACK:g} x {fig(o_true)})")


def check_bundleAdjustment(bundleAdjustment, *, root=None, verbose: bool = True) -> CheckReport:
    """Run ``bundleAdjustment`` from a perturbed start of a generated scene, and on the default data.

    Parameters
    ----------
    bundleAdjustment : the student's function (K1, M1, p1, K2, M2_init, p2, w_init) ->
        (M2, w, o1, o2), o1 and o2 the total squared reprojection errors before and after.
    root : data folder for the default data (default: data/ or $HW4_DATA).
    verbose : print the report.

    Checked: o1 and o2 are the sums of squares of the start and of the result; the error drops,
    to no more than the true configuration's (which is one of the candidates); the scale of t
    does not collapse.  On the default data (a subset of the clean matches, started
    from the pose and points OpenCV gives) the error drops and the scale holds.
    """
    report = CheckReport("bundleAdjustment")
    tv = two_view()
    n = _N_BA
    M2_init, w_init = _start(tv, n, np.random.default_rng(PUBLIC_SEED))
    p1, p2 = tv.pts1_u16[:n].astype(float), tv.pts2_u16[:n].astype(float)
    out = call(bundleAdjustment, tv.K1.copy(), tv.M1.copy(), p1.copy(), tv.K2.copy(), M2_init.copy(), p2.copy(),
               w_init.copy())
    if stop_if_not_implemented(report, out):
        return finish(report, verbose)
    if not run_failed(report, out, "a generated scene"):
        result = _read_ba(report, out.value, n, "generated")
        if result is not None:
            o_true = _sse(tv.C1, tv.C2, p1, p2, tv.X[:n])[0]
            _ba_items(report, result, tv.K1, tv.M1, tv.K2, p1, p2, M2_init, w_init, "generated", o_true)

    data, note = default_temple(root)
    ref, note_cv = opencv_reference(data) if data is not None else (None, "")
    if data is None or ref is None:
        report.notes.append(note or note_cv)
    else:
        k = np.unique(np.linspace(0, len(data.pts1) - 1, _N_BA_DEFAULT).astype(int))
        M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
        out = call(bundleAdjustment, data.K1.copy(), M1.copy(), data.pts1[k].copy(), data.K2.copy(), ref.M2.copy(),
                   data.pts2[k].copy(), ref.w[k].copy())
        if not run_failed(report, out, "the default data"):
            result = _read_ba(report, out.value, len(k), "default data")
            if result is not None:
                _ba_items(report, result, data.K1, M1, data.K2, data.pts1[k], data.pts2[k], ref.M2, ref.w[k],
                          "default data")
    return finish(report, verbose)
