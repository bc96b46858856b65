"""Q3.3's figure: the four candidate cameras of E, their points in front of or behind the cameras,
the one the student's findM2 chose and the right one.

Student side (:func:`run`): ``findM2(F, pts1, pts2, K1, K2)`` (or another year's signature, called
as judging.conventions says) with the default data's true F (3, 3; x2^T F x1 = 0), its matches
(N, 2) pixels (x, y) and intrinsics; M2 = [R | t] (3, 4) maps world (camera-1) coordinates to camera 2.

It is run twice: on the default data, and on the self-check's twisted-pair case (public data
shipped beside the checks, twisted_pair.json: matches near the epipoles where one wrong candidate
puts every point in front of camera 1 and behind camera 2, and reprojects them best).

Trusted side (:func:`draw`): the candidates are M2s = starter.camera2(E) for E = K2^T F K1, named
as code indexes them (``M2s[:, :, k]``, k = 0 to 3, never "candidate 1 to 4"); each is
drawn seen from above (x to the right, z forward, camera-1 coordinates) with the points a linear
triangulation gives under it (precomputed on the grader's side for both cases: a triangulation
cannot ship, see .precomputed): green in front of both cameras, orange in front of camera 1 only,
purple in front of camera 2 only, red behind both.  The right one has every point in front of
both; the chosen one is framed.  A depth test of camera 1 alone picks the all-orange one of the
twisted pair.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from core.geometry import camera_center

from . import precomputed
from .arrays import call, maybe, need, read
from .picture import Picture, figure, to_picture
from .public import need_truth, temple

__all__ = ["FUNCTIONS", "TOL_DEG", "candidate_of", "draw", "run"]

FUNCTIONS = ("findM2",)
TOL_DEG = 1.0


def _chosen(fn, F, pts1, pts2, K1, K2) -> np.ndarray:
    from judging.conventions import findM2_call, signature_of_callable
    from judging.pose import read_findM2

    c = findM2_call(signature_of_callable(fn), np.array(F, float), np.array(pts1, float), np.array(pts2, float),
                    np.array(K1, float), np.array(K2, float))
    M2, _, _ = read(read_findM2, call(fn, "findM2", *c.args), len(pts1), name="findM2")
    return np.asarray(M2, float)


def run(functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """{"M2": (3, 4)} chosen by the student's findM2 on the default data, and "M2_twisted" (3, 4) on the
    twisted-pair case (left out when that run fails)."""
    from ..twisted_pair import public_case

    pub = temple(root)
    s, d = need_truth(pub, "Q3.3"), pub.data
    fn = functions["findM2"]
    out = {"M2": _chosen(fn, s.F_true, d.pts1, d.pts2, d.K1, d.K2)}
    case = public_case()
    try:
        out["M2_twisted"] = _chosen(fn, case.F, case.pts1, case.pts2, case.pair.K1, case.pair.K2)
    except Exception:  # noqa: BLE001 - the second case only adds a row
        pass
    return out


def _angle(u, v) -> float:
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if not (nu > 0 and nv > 0):
        return 180.0
    return float(np.degrees(np.arccos(np.clip(np.dot(u, v) / (nu * nv), -1, 1))))


def _gap(A, B) -> float:
    """Degrees between two poses (3, 4): the larger of the rotation angle and the angle of the t's."""
    c = (np.trace(A[:, :3].T @ B[:, :3]) - 1) / 2
    rot = float(np.degrees(np.arccos(np.clip(c, -1, 1)))) if np.all(np.isfinite(A)) else 180.0
    return max(rot, _angle(A[:, 3], B[:, 3]))


def candidate_of(M2, candidates) -> tuple[int, float]:
    """(index of the candidate (3, 4, 4) nearest to M2, degrees away); -1 when none within TOL_DEG."""
    gaps = [_gap(np.asarray(M2, float), candidates[:, :, k]) for k in range(candidates.shape[2])]
    k = int(np.argmin(gaps))
    return (k if gaps[k] <= TOL_DEG else -1), gaps[k]


_CLASSES = (("in_front", "#2e7d32", True, True), ("front_1_only", "#ff6f00", True, False),
            ("front_2_only", "#8e24aa", False, True), ("behind", "#e53935", False, False))


def _panel(ax, k, M2c, pts: dict, chosen: bool, right: bool, label: str) -> None:
    f1s, f2s = pts["front1"], pts["front2"]
    front = f1s & f2s
    X = np.column_stack([pts["x"], pts["z"]])           # (N, 2): x and z, camera-1 coordinates
    for gid, colour, f1, f2 in _CLASSES:
        sel = (f1s == f1) & (f2s == f2)
        ax.plot(X[sel, 0], X[sel, 1], ".", ms=3, color=colour, gid=gid)
    c2 = camera_center(M2c)
    for centre, R, name in ((np.zeros(3), np.eye(3), "camera 1"), (c2, M2c[:, :3], "camera 2")):
        axis = R.T @ np.array([0.0, 0.0, 1.0])
        ax.plot([centre[0]], [centre[2]], "s", color="k", ms=5)
        ax.annotate("", xy=(centre[0] + axis[0], centre[2] + axis[2]), xytext=(centre[0], centre[2]),
                    arrowprops=dict(arrowstyle="->", color="k"))
        ax.text(centre[0], centre[2], f" {name}", fontsize=7, va="top")
    ax.axhline(0, color="#999", lw=0.5)
    good = np.all(np.isfinite(X), axis=1)
    xs = np.concatenate([np.percentile(X[good, 0], [5, 95]) if good.any() else [], [0.0, c2[0], -1, 1]])
    zs = np.concatenate([np.percentile(X[good, 1], [5, 95]) if good.any() else [], [0.0, c2[2], -1, 1]])
    pad = 0.15 * max(np.ptp(xs), np.ptp(zs))
    ax.set_xlim(xs.min() - pad, xs.max() + pad)
    ax.set_ylim(zs.min() - pad, zs.max() + pad)
    ax.set_aspect("equal", adjustable="box")
    tags = ", ".join(t for t, on in (("yours", chosen), ("right", right)) if on)
    ax.set_title(f"{label}M2s[:, :, {k}]: {int(front.sum())} of {len(front)} in front of both"
                 + (f" ({tags})" if tags else ""), fontsize=8)
    ax.set_xlabel("x", fontsize=7)
    ax.set_ylabel("z (camera 1's axis)", fontsize=7)
    if chosen:
        for side in ax.spines.values():
            side.set_color("#ff6f00")
            side.set_linewidth(3)


def _candidates(case: str, F, pts1, pts2, K1, K2):
    """(candidates (3, 4, 4), their points (4 dicts of .precomputed.candidates)) of one case."""
    from starter.pose import camera2

    cands = camera2(np.asarray(K2, float).T @ np.asarray(F, float) @ np.asarray(K1, float))
    pts = precomputed.candidates(case, (pts1, pts2, K1, K2))
    if pts is None:
        raise ValueError(f"Q3.3's figure: the points under each candidate are {precomputed.NOT_PRECOMPUTED} "
                         "(restore data/ with `python -m kit data`, or write them with `python -m kit check-data`)")
    return cands, pts


def _case(axes, M2, case: str, F, pts1, pts2, K1, K2, label: str, prefix: str, m: dict) -> str:
    """Draw one case's four candidates into ``axes``; add its measures to ``m``; return its sentence."""
    cands, pts = _candidates(case, F, pts1, pts2, K1, K2)
    fronts = [p["front1"] & p["front2"] for p in pts]
    ones = [p["front1"] & ~p["front2"] for p in pts]
    right = int(np.argmax([f.sum() for f in fronts]))
    chosen, gap = candidate_of(M2, cands)
    for k, ax in enumerate(axes):
        _panel(ax, k, cands[:, :, k], pts[k], k == chosen, k == right, label)
    n = len(pts1)
    m.update({f"{prefix}chosen": float(chosen), f"{prefix}chosen_gap_deg": gap, f"{prefix}right": float(right),
              f"{prefix}chosen_share_in_front": float(fronts[chosen].mean()) if chosen >= 0 else float("nan"),
              f"{prefix}chosen_share_front_1_only": float(np.mean(ones[chosen]))
              if chosen >= 0 else float("nan"),
              f"{prefix}right_share_in_front": float(fronts[right].mean())})
    shares = "; ".join(f"M2s[:, :, {k}]: {int(f.sum())} of {n}" for k, f in enumerate(fronts))
    if chosen >= 0:
        one = int(ones[chosen].sum())
        yours = (f"yours is M2s[:, :, {chosen}] (framed), with {int(fronts[chosen].sum())} of {n} points in front "
                 f"of both cameras and {one} in front of camera 1 only")
    else:
        yours = f"your M2 is none of the four (the nearest is {gap:.3g} degrees away)"
    return f"Points in front of both cameras: {shares}; the right one is M2s[:, :, {right}]; {yours}."


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q3.3.

    measures (default data): chosen (candidate index 0-3 of the student's M2, -1 when none),
    chosen_gap_deg (degrees from that candidate), right (the index of the candidate with the most
    points in front of both cameras), chosen_share_in_front, chosen_share_front_1_only,
    right_share_in_front (shares of the points in front of both cameras, or of camera 1 only);
    the same prefixed "twisted_" for the twisted-pair case when M2_twisted is given.
    """
    from ..twisted_pair import public_case

    M2 = need(outputs, "M2", (3, 4))
    twisted = maybe(outputs, "M2_twisted", (3, 4))
    pub = temple(root)
    s, d = need_truth(pub, "Q3.3"), pub.data
    rows = 1 if twisted is None else 2
    fig, axes = figure(4, rows, size=(3.6, 3.4))
    m: dict[str, float] = {}
    text = _case(axes[:4], M2, "default", s.F_true, d.pts1, d.pts2, d.K1, d.K2, "", "", m)
    from matplotlib.lines import Line2D

    names = {"in_front": "in front of both", "front_1_only": "in front of camera 1 only",
             "front_2_only": "in front of camera 2 only", "behind": "behind both"}
    axes[0].legend([Line2D([], [], marker=".", ls="", color=c) for _, c, _, _ in _CLASSES],
                   [names[g] for g, _, _, _ in _CLASSES], fontsize=6, loc="lower left")
    alt = (f"The four candidate cameras of E seen from above, with the {len(d.pts1)} points of the default data "
           "triangulated under each (green in front of both cameras, orange in front of camera 1 only, purple of "
           f"camera 2 only, red behind both). {text}")
    if twisted is not None:
        case = public_case()
        text = _case(axes[4:], twisted, "twisted", case.F, case.pts1, case.pts2, case.pair.K1, case.pair.K2, "twisted pair: ",
                     "twisted_", m)
        alt += f" The twisted-pair case ({len(case.pts1)} matches near the epipoles): {text}"
    return to_picture("Q3.3", "findM2: the four candidates, and yours", fig, alt, m)
