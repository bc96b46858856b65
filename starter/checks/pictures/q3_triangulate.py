"""Q3.2's figure: the student's points w reprojected into both images against the observed matches.

Student side (:func:`run`): ``triangulate(C1, pts1, C2, pts2) -> (w, err)`` with the default
data's true cameras C1, C2 (3, 4) and its matches pts1, pts2 (N, 2) (some_corresp, pixels (x, y)).

Trusted side (:func:`draw`): in each image, the observed points (dots) and the reprojections of w
(crosses) joined by a segment, the offsets magnified (a right triangulation's are a fraction of a
pixel), and a bar chart of the err returned beside the sum of squares of what is drawn.  A w not
divided by its last coordinate, or mirrored points, reproject far from the dots; an err that is a
mean or a root differs from the bar beside it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from core.geometry import depths, project

from .arrays import call, count, maybe, need, number, read, said
from .drawing import image
from .picture import Picture, figure, measure_text, to_picture
from .public import need_truth, temple

__all__ = ["FUNCTIONS", "MAGNIFY", "draw", "run"]

FUNCTIONS = ("triangulate",)
MAGNIFY = 20.0


def run(functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """{"w": (N, 3), "err": (1,) (NaN when err is not one number)}."""
    from judging.triangulation import read_w_err

    pub = temple(root)
    s, d = need_truth(pub, "Q3.2"), pub.data
    value = call(functions["triangulate"], "triangulate", s.C1.copy(), d.pts1.copy(), s.C2.copy(), d.pts2.copy())
    w, err = read(read_w_err, value, len(d.pts1), name="triangulate")
    return {"w": np.asarray(w, float), "err": number(err, "err"), "err_size": count(err)}


def _offsets(ax, pts, proj, magnify: float) -> None:
    ax.plot(pts[:, 0], pts[:, 1], "o", ms=3, mfc="#e53935", mec="white", mew=0.5, gid="observed")
    ends = pts + magnify * (proj - pts)
    for (x0, y0), (x1, y1) in zip(pts, ends):
        if np.all(np.isfinite([x1, y1])):
            ax.plot([x0, x1], [y0, y1], color="#ffb300", lw=0.8, gid="offset")
    ax.plot(ends[:, 0], ends[:, 1], "x", ms=3, color="#ffb300", gid="reprojected")


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q3.2.

    measures: mean_reprojection_px_1, mean_reprojection_px_2 (distance of each observed point to
    the reprojection of its w, pixels), err_reported (the err returned), sum_of_squares (of the
    distances drawn, pixels^2), share_in_front (of w in front of both true cameras), magnified (the
    factor the offsets are drawn at: MAGNIFY when 90 % of them are below 1 px, else 1).
    """
    pub = temple(root)
    s, d = need_truth(pub, "Q3.2"), pub.data
    n = len(d.pts1)
    w = need(outputs, "w", (n, 3))
    err = float(need(outputs, "err", (1,))[0])
    err_count = float(outputs["err_size"][0]) if maybe(outputs, "err_size", (1,)) is not None else None
    with np.errstate(all="ignore"):
        q1, q2 = project(s.C1, w), project(s.C2, w)
        d1, d2 = np.linalg.norm(q1 - d.pts1, axis=1), np.linalg.norm(q2 - d.pts2, axis=1)
        total = float(np.sum(d1 ** 2) + np.sum(d2 ** 2))
        front = float(np.mean((depths(s.M1, w) > 0) & (depths(s.M2, w) > 0)))
    m = {"mean_reprojection_px_1": float(np.mean(d1)), "mean_reprojection_px_2": float(np.mean(d2)),
         "err_reported": err, "sum_of_squares": total, "share_in_front": front}
    fig = figure(size=(11.0, 4.0))[0]
    fig.clear()
    grid = fig.add_gridspec(1, 3, width_ratios=[3, 3, 1.3])
    small = bool(np.all(np.isfinite(np.concatenate([d1, d2]))) and np.percentile(np.concatenate([d1, d2]), 90) < 1.0)
    magnify = MAGNIFY if small else 1.0
    m["magnified"] = magnify
    for k, (im, p, q, dist) in enumerate(((d.im1, d.pts1, q1, d1), (d.im2, d.pts2, q2, d2))):
        ax = fig.add_subplot(grid[0, k])
        image(ax, im, f"image {k + 1}: mean distance {measure_text(np.mean(dist), 'px')}")
        _offsets(ax, p, q, magnify)
        ax.set_xlabel("dots: observed; crosses: your w reprojected"
                      + (f", offsets x{magnify:g}" if magnify != 1 else ""), fontsize=8)
    ax = fig.add_subplot(grid[0, 2])
    vals = [err if np.isfinite(err) else 0.0, total if np.isfinite(total) else 0.0]
    ax.bar([0, 1], vals, color=["#ffb300", "#4fc3f7"], gid="errors")
    ax.set_xticks([0, 1], ["err\nreturned", "sum of\nsquares"], fontsize=8)
    ax.set_title("px^2", fontsize=8)
    if min(vals) > 0 and max(vals) / min(vals) > 100:
        ax.set_yscale("log")
    for x, v in zip((0, 1), vals):
        ax.text(x, v, f"{v:.3g}", ha="center", va="bottom", fontsize=7)
    alt = (f"Images 1 and 2 with the {n} observed matches and the reprojections of your w"
           + (f" (offsets magnified {magnify:g} times)" if magnify != 1 else "")
           + f": mean distance {measure_text(m['mean_reprojection_px_1'], 'px')} in image 1 and "
           f"{measure_text(m['mean_reprojection_px_2'], 'px')} in image 2; {front:.0%} of the points in front of both "
           f"cameras. Your {said('err', err, err_count, 'px^2')}; the sum of squares of the distances drawn is "
           f"{measure_text(total, 'px^2')}.")
    return to_picture("Q3.2", "triangulate: your points reprojected", fig, alt, m)
