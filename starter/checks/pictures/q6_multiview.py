"""Q6's figure: the student's car keypoints reprojected into the three views.

Student side (:func:`run`): ``MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres) -> (P, err)``
on the first time step of the public car data (three (12, 3) arrays [x, y, confidence] of pixels
(x, y), cameras C (3, 4) = K [R | t], world -> camera) at THRES, the self-check's threshold (the
default data holds detections at exactly that confidence, so using them shows).

Trusted side (:func:`draw`): each view with its detections (filled: confidence above Thres, used by
the handout's rule; hollow: at or below), the student's P reprojected (crosses, joined to their
detections) and the true keypoints reprojected (default data); a keypoint the handout's rule
reconstructs and the student's P leaves out is ringed in red, one where P follows detections the
handout's rule leaves out (at or below Thres) in purple; in camera 3's corner, the err returned
beside the sum of squares recomputed.  On the default data the student's P
is also compared with linear triangulations under three rules (confidence > Thres, >= Thres, every
detection; precomputed on the grader's side, see .precomputed): the rule it is nearest names the
threshold the code applied.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from core.geometry import project

from . import precomputed
from .arrays import call, count, maybe, need, number, read, said
from .drawing import two_bars
from .picture import Picture, figure, measure_text, to_picture
from .public import car

__all__ = ["FUNCTIONS", "RULES", "THRES", "draw", "run"]

FUNCTIONS = ("MultiviewReconstruction",)
THRES = 500.0
RULES = ("confidence > Thres", "confidence >= Thres", "every detection")


def run(functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """{"P": (12, 3) (rows of NaN: keypoints not reconstructed), "err": (1,) (NaN when not one number)}."""
    from judging.multiview import read_P_err

    frame = car(root, truth=False).frame
    C, pts = frame.C, frame.pts
    value = call(functions["MultiviewReconstruction"], "MultiviewReconstruction",
                 np.array(C[0], float), np.array(pts[0], float), np.array(C[1], float), np.array(pts[1], float),
                 np.array(C[2], float), np.array(pts[2], float), THRES)
    P, err = read(read_P_err, value, len(pts[0]), name="MultiviewReconstruction")
    return {"P": np.asarray(P, float), "err": number(err, "err"), "err_size": count(err)}


def _handout_rule_reconstructs(pts, Thres) -> np.ndarray:
    """(N,) bool: the keypoints the handout's rule (confidence > Thres) sees in two views or more."""
    return np.sum([np.asarray(p, float)[:, 2] > Thres for p in pts], axis=0) >= 2


def _nearest_rule(P, rules) -> tuple[int, dict[str, float]]:
    """(index of the rule whose points are nearest to P where the rules differ, mean distance per rule)."""
    stack = np.stack(list(rules.values()))                      # (3, N, 3)
    with np.errstate(invalid="ignore"):
        same = np.all(np.isclose(stack, stack[0], atol=1e-9) | (np.isnan(stack) & np.isnan(stack[0])), axis=(0, 2))
    rows = ~same
    gaps = {}
    for rule, Q in rules.items():
        if not rows.any():
            gaps[rule] = float("nan")
            continue
        with np.errstate(invalid="ignore"):
            d = np.linalg.norm(P[rows] - Q[rows], axis=1)
        # a point left out where the rule has one (or the reverse) counts as far
        d = np.where(np.isnan(d) & (np.isnan(P[rows]).any(axis=1) == np.isnan(Q[rows]).any(axis=1)), 0.0, d)
        gaps[rule] = float(np.mean(np.where(np.isnan(d), 1e6, d)))
    finite = [g for g in gaps.values() if np.isfinite(g)]
    return (int(np.argmin([gaps[r] for r in RULES])) if finite else -1), gaps


def _off_rule(P, rules) -> np.ndarray:
    """(N,) bool: the keypoints where the rules differ and P's point is nearer another rule's than the
    handout's (RULES[0]), or where P has a point and the handout's rule none: where another threshold shows."""
    stack = [np.asarray(rules[r], float) for r in RULES]
    with np.errstate(invalid="ignore"):
        d = np.stack([np.linalg.norm(P - Q, axis=1) for Q in stack])        # (3, N), NaN where either has none
    has = np.isfinite(P).all(axis=1)
    handout_has = np.isfinite(stack[0]).all(axis=1)
    nearer = np.nanmin(np.where(np.isnan(d[1:]), np.inf, d[1:]), axis=0) < np.where(np.isnan(d[0]), np.inf, d[0])
    return has & (~handout_has | (handout_has & nearer))


def _err_bars(ax, err: float, sum_of_squares: float) -> None:
    """Two bars in the lower right corner of ``ax`` (camera 3's panel, empty there on the default data):
    the err returned and the sum of squares recomputed, on one linear scale, as Q3.2's figure shows
    them: an err that is a mean, or over other detections, stands apart at a glance."""
    two_bars(ax, (0.83, 0.03, 0.15, 0.3), [err, sum_of_squares], ["#ffb300", "#4fc3f7"], ["err", "sum"],
             "px^2", "err_bars")


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q6.

    measures: mean_reprojection_px (the student's P reprojected, to the detections above Thres of
    the keypoints it reconstructed, pixels), n_reconstructed (finite rows of P), mean_error_3d (to the
    true keypoints, world units; default data only), err_reported, nearest_rule (index in RULES of
    the rule whose triangulation P is nearest, -1 when the rules agree everywhere or are not known:
    other data than the default), gap_<k> (mean distance of P to rule k's points where the rules
    differ, world units; 1e6 for a point one has and the other has not; default data only), detections_at_thres (detections whose confidence is exactly Thres),
    n_left_out (keypoints the handout's rule, confidence > Thres in two views or more, reconstructs and
    P leaves out: ringed in red in every view), sum_of_squares (of the distances of P reprojected to the
    detections above Thres, pixels^2: the handout's err; drawn beside err_reported), n_off_rule (keypoints where P follows another rule:
    nearer that rule's point than the handout's where they differ, or a point the handout's rule
    does not reconstruct; ringed in purple; default data only).
    """
    pub = car(root)
    frame, P_true = pub.frame, pub.P_true
    C, pts = frame.C, frame.pts
    n = len(pts[0])
    P = need(outputs, "P", (n, 3))
    err = float(need(outputs, "err", (1,))[0])
    err_count = float(outputs["err_size"][0]) if maybe(outputs, "err_size", (1,)) is not None else None
    finite = np.all(np.isfinite(P), axis=1)
    rules = precomputed.rules(C, pts)
    nearest, gaps = _nearest_rule(P, rules) if rules is not None else (-1, {})
    # keypoints the handout's rule (RULES[0]) reconstructs that P leaves out: ringed in every view
    left_out = ~finite & _handout_rule_reconstructs(pts, THRES)
    # and those where P follows another rule (a detection at or below Thres used): ringed in purple
    off_rule = _off_rule(P, rules) if rules is not None else np.zeros(n, bool)
    fig, axes = figure(3, 1, size=(4.6, 4.0))
    dists, squares = [], 0.0
    for k, (ax, Ck, p) in enumerate(zip(axes, C, pts)):
        above = p[:, 2] > THRES
        with np.errstate(all="ignore"):
            q = project(Ck, P)
        for (x0, y0), (x1, y1), ok in zip(p[:, :2], q, finite):
            if ok:
                ax.plot([x0, x1], [y0, y1], color="#ffb300", lw=0.8, gid="offset")
        at = p[:, 2] == THRES
        ax.plot(p[above, 0], p[above, 1], "o", ms=6, color="#1565c0", gid="detection_above")
        ax.plot(p[~above & ~at, 0], p[~above & ~at, 1], "o", ms=6, mfc="none", mec="#1565c0", gid="detection_below")
        ax.plot(p[at, 0], p[at, 1], "s", ms=8, mfc="none", mec="#c2185b", mew=1.5, gid="detection_at_thres")
        ax.plot(q[finite, 0], q[finite, 1], "x", ms=6, color="#ff6f00", gid="yours")
        ax.plot(p[left_out, 0], p[left_out, 1], "o", ms=16, mfc="none", mec="#e53935", mew=2, gid="left_out")
        ax.plot(p[off_rule, 0], p[off_rule, 1], "o", ms=16, mfc="none", mec="#8e24aa", mew=2, gid="off_rule")
        if P_true is not None:
            t = project(Ck, P_true)
            ax.plot(t[:, 0], t[:, 1], "+", ms=7, color="#2e7d32", gid="truth")
        for i, (x, y) in enumerate(p[:, :2]):
            ax.text(x, y, f" {i}", fontsize=6, color="#555")
        dists.append(np.linalg.norm(q - p[:, :2], axis=1)[finite & above])
        squares += float(np.sum(dists[-1] ** 2))
        ax.set_title(f"camera {k + 1}", fontsize=8)
        lo, hi = np.nanmin(p[:, :2], axis=0), np.nanmax(p[:, :2], axis=0)
        pad = 0.12 * (hi - lo).max()
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(hi[1] + pad, lo[1] - pad)
    d = np.concatenate(dists)
    m = {"mean_reprojection_px": float(np.mean(d)) if len(d) else float("nan"),
         "n_reconstructed": float(finite.sum()), "err_reported": err, "nearest_rule": float(nearest),
         "detections_at_thres": float(sum(int(np.sum(p[:, 2] == THRES)) for p in pts)),
         "n_left_out": float(left_out.sum()), "n_off_rule": float(off_rule.sum()), "sum_of_squares": squares}
    _err_bars(axes[2], err, squares)
    for k, rule in enumerate(RULES):
        if rule in gaps:
            m[f"gap_{k}"] = gaps[rule]
    if P_true is not None:
        with np.errstate(invalid="ignore"):
            m["mean_error_3d"] = float(np.mean(np.linalg.norm(P[finite] - P_true[finite], axis=1))) if finite.any() \
                else float("nan")
    axes[0].set_xlabel("detections: filled above Thres, square at Thres, hollow below;\nx: your P reprojected; "
                       "+: the true keypoints", fontsize=7)
    missing = (f"{int(left_out.sum())} keypoint(s) that {RULES[0]} reconstructs are not in your P (red rings)"
               if left_out.any() else "")
    if off_rule.any():
        missing += (("; " if missing else "") + f"{int(off_rule.sum())} of your keypoint(s) follow detections "
                    "at or below Thres (purple rings)")
    if rules is None:
        rule = f"the comparison with the three threshold rules is {precomputed.NOT_PRECOMPUTED}"
    elif nearest >= 0:
        rule = f"your P is nearest to a triangulation of the detections with {RULES[nearest]}"
    else:
        rule = "the three rules give the same points here"
    axes[1].set_xlabel(rule.replace("your P is nearest to a", "your P is nearest to the")
                       + (f"\n{missing}" if missing else ""), fontsize=8)
    alt = (f"The three views of time step {frame.time} with the 12 detections of each (Thres = {THRES:g}; "
           f"{int(m['detections_at_thres'])} detections have exactly that confidence) and your {int(finite.sum())} "
           f"reconstructed keypoints reprojected: mean distance {measure_text(m['mean_reprojection_px'], 'px')} to the "
           f"detections above Thres"
           + (f"; mean 3D distance to the true keypoints {measure_text(m['mean_error_3d'])}" if "mean_error_3d" in m else "")
           + (f". Of three rules, {rule}." if rules is not None else f"; {rule}.") + (f" {missing[0].upper()}{missing[1:]}." if missing else "")
           + f" Your {said('err', err, err_count)}; the sum of the squared distances of your keypoints reprojected "
           f"to the detections above Thres is {measure_text(squares, 'px^2')} (two bars in camera 3's corner).")
    return to_picture("Q6", "MultiviewReconstruction: your keypoints in the three views", fig, alt, m)
