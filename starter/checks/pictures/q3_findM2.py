"""Q3.3's figure: the four candidate cameras of E, their points in front of or behind the cameras,
the one the student's findM2 chose and the right one.

Student side (:func:`run`): ``findM2(F, pts1, pts2, K1, K2)`` (or another year's signature, called
as judging.conventions says) with the default data's true F (3, 3; x2^T F x1 = 0), its matches
(N, 2) pixels (x, y) and intrinsics; M2 = [R | t] (3, 4) maps world (camera-1) coordinates to camera 2.

Trusted side (:func:`draw`): the candidates are starter.camera2(E) for E = K2^T F K1; each is
drawn seen from above (x to the right, z forward, camera-1 coordinates) with the points a linear
triangulation gives under it, green in front of both cameras and red behind one.  The right one
has every point in front of both; the chosen one is framed.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from core.geometry import camera_center, depths

from .arrays import call, need, read
from .geometry3d import triangulate_views
from .picture import Picture, figure, to_picture
from .public import need_truth, temple

__all__ = ["FUNCTIONS", "TOL_DEG", "candidate_of", "draw", "run"]

FUNCTIONS = ("findM2",)
TOL_DEG = 1.0


def run(functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """{"M2": (3, 4)} chosen by the student's findM2 on the default data."""
    from judging.conventions import findM2_call, signature_of_callable
    from judging.pose import read_findM2

    pub = temple(root)
    s, d = need_truth(pub, "Q3.3"), pub.data
    fn = functions["findM2"]
    c = findM2_call(signature_of_callable(fn), np.array(s.F_true, float), d.pts1.copy(), d.pts2.copy(),
                    d.K1.copy(), d.K2.copy())
    M2, _, _ = read(read_findM2, call(fn, "findM2", *c.args), len(d.pts1), name="findM2")
    return {"M2": np.asarray(M2, float)}


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


def _panel(ax, k, M2c, X, front, chosen: bool, right: bool) -> None:
    ok = front
    ax.plot(X[ok, 0], X[ok, 2], ".", ms=3, color="#2e7d32", gid="in_front")
    ax.plot(X[~ok, 0], X[~ok, 2], ".", ms=3, color="#e53935", gid="behind")
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
    zs = np.concatenate([np.percentile(X[good, 2], [5, 95]) if good.any() else [], [0.0, c2[2], -1, 1]])
    pad = 0.15 * max(np.ptp(xs), np.ptp(zs))
    ax.set_xlim(xs.min() - pad, xs.max() + pad)
    ax.set_ylim(zs.min() - pad, zs.max() + pad)
    ax.set_aspect("equal", adjustable="datalim")
    tags = ", ".join(t for t, on in (("yours", chosen), ("right", right)) if on)
    ax.set_title(f"candidate {k + 1}: {int(front.sum())} of {len(front)} in front of both"
                 + (f" ({tags})" if tags else ""), fontsize=8)
    ax.set_xlabel("x", fontsize=7)
    ax.set_ylabel("z (camera 1's axis)", fontsize=7)
    if chosen:
        for side in ax.spines.values():
            side.set_color("#ff6f00")
            side.set_linewidth(3)


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q3.3.

    measures: chosen (candidate index 0-3 of the student's M2, -1 when none), chosen_gap_deg
    (degrees from that candidate), right (the index of the candidate with the most points in front
    of both cameras), chosen_share_in_front, right_share_in_front (shares of the points in front of
    both cameras under each).
    """
    from starter.pose import camera2

    M2 = need(outputs, "M2", (3, 4))
    pub = temple(root)
    s, d = need_truth(pub, "Q3.3"), pub.data
    E = d.K2.T @ np.asarray(s.F_true, float) @ d.K1
    cands = camera2(E)
    C1 = d.K1 @ np.hstack([np.eye(3), np.zeros((3, 1))])
    pts, fronts = [], []
    for k in range(4):
        M2c = cands[:, :, k]
        X = triangulate_views([C1, d.K2 @ M2c], [d.pts1, d.pts2])
        with np.errstate(invalid="ignore"):
            fronts.append((depths(np.hstack([np.eye(3), np.zeros((3, 1))]), X) > 0) & (depths(M2c, X) > 0))
        pts.append(X)
    right = int(np.argmax([f.sum() for f in fronts]))
    chosen, gap = candidate_of(M2, cands)
    fig, axes = figure(2, 2, size=(4.6, 3.6))
    for k, ax in enumerate(axes):
        _panel(ax, k, cands[:, :, k], pts[k], fronts[k], k == chosen, k == right)
    n = len(d.pts1)
    m = {"chosen": float(chosen), "chosen_gap_deg": gap, "right": float(right),
         "chosen_share_in_front": float(fronts[chosen].mean()) if chosen >= 0 else float("nan"),
         "right_share_in_front": float(fronts[right].mean())}
    shares = "; ".join(f"candidate {k + 1}: {int(f.sum())} of {n}" for k, f in enumerate(fronts))
    yours = (f"Yours is candidate {chosen + 1} (framed), with {int(fronts[chosen].sum())} of {n} points in front of both"
             if chosen >= 0 else f"Your M2 is none of the four (the nearest is {gap:.3g} degrees away)")
    alt = (f"The four candidate cameras of E seen from above, with the {n} points triangulated under each, green in "
           f"front of both cameras, red behind one. Points in front of both: {shares}. The right one is candidate "
           f"{right + 1}. {yours}.")
    return to_picture("Q3.3", "findM2: the four candidates, and yours", fig, alt, m)
