"""Q4.1's figure: the student's matches in image 2 against the true ones.

Student side (:func:`run`): ``epipolarCorrespondence(im1, im2, F, x1, y1) -> (x2, y2)`` once per
point, on the easy points of the default data's templeCoords (the rows of matching_goals.json,
the points the self-check judges), with its true F (x2^T F x1 = 0), float images in [0, 1] and
integer pixels (x, y), as the course calls it.

Trusted side (:func:`draw`): image 2 around the temple with the true matches (circles), the
student's (crosses) and a segment from each true match to the student's; the points within the
tolerance are green, the others red.  x and y swapped puts the crosses across the image.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from functools import lru_cache
from pathlib import Path

import numpy as np

from .arrays import call, need, read
from .drawing import image
from .picture import Picture, figure, measure_text, to_picture
from .public import need_truth, temple

__all__ = ["FUNCTIONS", "GOALS_FILE", "draw", "points", "run"]

FUNCTIONS = ("epipolarCorrespondence",)
GOALS_FILE = Path(__file__).resolve().parent.parent / "matching_goals.json"


@lru_cache(maxsize=1)
def _rows() -> tuple[int, ...]:
    return tuple(int(r) for r in json.loads(GOALS_FILE.read_text(encoding="utf-8"))["rows"])


def points(scene) -> tuple[np.ndarray, np.ndarray]:
    """(pts1 (P, 2) of image 1, truth2 (P, 2) their true matches) of the easy rows of ``scene``."""
    rows = np.asarray(_rows(), dtype=int)
    pts1 = np.column_stack([np.ravel(scene.x1)[rows], np.ravel(scene.y1)[rows]]).astype(float)
    return pts1, np.asarray(scene.x2_true, float)[rows]


def run(functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """{"pts2": (P, 2)} the student's matches of the easy points (pixels (x, y))."""
    from judging.correspondence import read_match
    from starter.data import course_image

    s = need_truth(temple(root), "Q4.1")
    fn = functions["epipolarCorrespondence"]
    im1, im2 = course_image(s.im1), course_image(s.im2)
    pts1, _ = points(s)
    pixels = [(int(round(x)), int(round(y))) for x, y in pts1]
    if callable(getattr(fn, "map", None)):  # the grader's sandboxed function: one request, the images sent once
        values = fn.map(pixels, args=(im1, im2, np.array(s.F_true, float)))
    else:
        values = [call(fn, "epipolarCorrespondence", im1.copy(), im2.copy(), np.array(s.F_true, float), x, y)
                  for x, y in pixels]
    found = [read(read_match, value, name="epipolarCorrespondence") for value in values]
    return {"pts2": np.array(found, dtype=float).reshape(-1, 2)}


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q4.1.

    measures: mean_distance_px (of the student's matches to the true ones), median_distance_px,
    share_within_tol (within judging.correspondence.tolerance of the image width), tol_px, n_points.
    """
    from judging.correspondence import tolerance

    s = need_truth(temple(root), "Q4.1")
    pts1, truth = points(s)
    mine = need(outputs, "pts2", (len(pts1), 2))
    tol = tolerance(s.im2.shape[1])
    with np.errstate(invalid="ignore"):
        dist = np.linalg.norm(mine - truth, axis=1)
    ok = dist <= tol
    fig = figure(size=(11.0, 4.2))[0]
    fig.clear()
    grid = fig.add_gridspec(1, 2, width_ratios=[1, 1.6])
    ax1 = fig.add_subplot(grid[0, 0])
    image(ax1, s.im1, "image 1: the points matched")
    ax1.plot(pts1[:, 0], pts1[:, 1], "o", ms=4, mfc="#4fc3f7", mec="white", gid="source")
    ax = fig.add_subplot(grid[0, 1])
    image(ax, s.im2, f"image 2: {int(ok.sum())} of {len(ok)} within {tol:g} px of the true match")
    for (x0, y0), (x1, y1), good in zip(truth, mine, ok):
        if np.all(np.isfinite([x1, y1])):
            ax.plot([x0, x1], [y0, y1], color="#2e7d32" if good else "#e53935", lw=1.0, gid="offset")
    ax.plot(truth[:, 0], truth[:, 1], "o", ms=6, mfc="none", mec="#4fc3f7", mew=1.2, gid="truth")
    ax.plot(mine[ok, 0], mine[ok, 1], "x", ms=5, color="#2e7d32", gid="yours_right")
    ax.plot(mine[~ok, 0], mine[~ok, 1], "x", ms=5, color="#e53935", gid="yours_wrong")
    both = np.vstack([truth, mine[np.all(np.isfinite(mine), axis=1)]])
    h, w = s.im2.shape[:2]
    lo, hi = np.clip(both.min(axis=0) - 30, 0, None), np.minimum(both.max(axis=0) + 30, [w - 1, h - 1])
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])
    ax.set_xlabel("circles: true matches; crosses: yours (green within the tolerance, red beyond)", fontsize=8)
    finite = np.isfinite(dist)
    m = {"mean_distance_px": float(np.mean(dist)) if finite.all() else float("inf"),
         "median_distance_px": float(np.median(dist)) if finite.all() else float("inf"),
         "share_within_tol": float(ok.mean()), "tol_px": float(tol), "n_points": float(len(ok))}
    alt = (f"Image 2 with the true matches of {len(ok)} distinctive templeCoords points and your matches: "
           f"{int(ok.sum())} of {len(ok)} ({ok.mean():.0%}) within {tol:g} px of the true match; distance to the true "
           f"match: median {measure_text(m['median_distance_px'], 'px')}, mean {measure_text(m['mean_distance_px'], 'px')}.")
    return to_picture("Q4.1", "epipolarCorrespondence: your matches and the true ones", fig, alt, m)
