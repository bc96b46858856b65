"""Q2's figure: the student's epipolar lines in image 2, through the true matches, beside the true F's.

Student side (:func:`run`): ``eightpoint(pts1, pts2, M)`` on the public matches (some_corresp,
float pixels (x, y)), as returned; again with refineF switched off, kept when it called refineF
then (the self-check's switch, ``core.refine_switch``: refineF can hide a transposed F; in the
grader the same switch thrown in the sandbox, see :func:`run`); and on the same points as uint16,
the data files' type.  Each F (3, 3) maps a point of image 1 to its line in image 2 (x2^T F x1 = 0).

Trusted side (:func:`draw`): one panel per F; in each, image 2 with the lines F x1 of eight matches
spread over the temple (solid) and of the true F (dashed, default data only), and the true
matching points (dots).  A right F's lines pass through the dots; a transposed or unscaled F's miss
them by tens of pixels; a rank-3 F's lines pass near them but do not meet in one epipole.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial

import numpy as np

from .arrays import call, matrix3, maybe, need
from .drawing import clip_line, image, line_distances
from .picture import Picture, figure, fmt, to_picture
from .public import NO_TRUTH, temple

__all__ = ["FUNCTIONS", "N_DRAWN", "ZOOM_PX", "draw", "drawn_rows", "lines_row", "run"]

FUNCTIONS = ("eightpoint",)
N_DRAWN = 8
ZOOM_PX = 12
# outputs name -> panel label
_RUNS = {"F": "your F", "F_refineF_off": "your F, refineF switched off", "F_uint16": "your F from uint16 points"}
_KEYS = {"F": "", "F_refineF_off": "refineF_off_", "F_uint16": "uint16_"}


def _F(value, what: str) -> np.ndarray:
    return matrix3(value, what, "F")


def run(functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """{"F": (3, 3), "F_refineF_off": (3, 3) when eightpoint called refineF in its run with refineF
    switched off, "F_uint16": (3, 3) when the uint16 run succeeds}; PictureRunError when the first
    call fails.

    The switched-off run is ``eightpoint.refineF_switched_off(pts1, pts2, M)`` when the function
    has one (the grader's sandboxed function: the switch thrown in the sandbox, ``(value, calls)``
    reported back), else ``starter.checks.instrument.refineF_switched_off(eightpoint, ...)`` in this
    process (the self-check); either way ``calls`` decides the row, here only.
    """
    from ..instrument import refineF_switched_off

    eightpoint = functions["eightpoint"]
    d = temple(root, truth=False).data
    F = _F(call(eightpoint, "eightpoint", d.pts1.copy(), d.pts2.copy(), d.M), "eightpoint's F")
    out = {"F": F}
    off = getattr(eightpoint, "refineF_switched_off", None)
    if not callable(off):
        off = partial(refineF_switched_off, eightpoint)
    try:
        value, calls = off(d.pts1.copy(), d.pts2.copy(), d.M)
        if calls:
            out["F_refineF_off"] = _F(value, "eightpoint's F with refineF switched off")
    except Exception:  # noqa: BLE001 - a second run that fails only leaves its panel out
        pass
    try:
        out["F_uint16"] = _F(eightpoint(d.pts1.astype(np.uint16), d.pts2.astype(np.uint16), d.M), "F (uint16)")
    except Exception:  # noqa: BLE001
        pass
    return out


def drawn_rows(pts1: np.ndarray, n: int) -> np.ndarray:
    """n rows of pts1 (N, 2) spread over the image: evenly spaced in the order of x (the lines are near vertical)."""
    order = np.argsort(pts1[:, 0] + 1e-3 * pts1[:, 1], kind="stable")
    return order[np.unique(np.linspace(0, len(order) - 1, min(n, len(order))).round().astype(int))]


def _s3_over_s2(F, M) -> float:
    S = np.diag([M, M, 1.0])
    s = np.linalg.svd(S @ F @ S, compute_uv=False)
    return float(s[2] / s[1]) if s[1] > 0 else float("inf")


def _unit(F):
    return F / np.linalg.norm(F) if np.isfinite(np.linalg.norm(F)) and np.linalg.norm(F) > 0 else F


def _change(A, B) -> float:
    """How far A and B (3, 3) are from equal up to scale and sign: 0 when the same, about 1 when unrelated."""
    a, b = _unit(A), _unit(B)
    return float(min(np.abs(a - b).max(), np.abs(a + b).max()))


def _segments(ax, lines, w, h, **style) -> None:
    for ln in lines:
        seg = clip_line(ln, w, h)
        if seg is not None:
            ax.plot(*seg, **style)


def lines_row(fig, grid, row, d, label, F, truth_F, h1, p2, zoom):
    """Row ``row`` of ``grid`` (rows 2*row, 2*row + 1 of a 5-column grid): image 2 with the lines (left),
    then one zoom of ``zoom`` px around each dot (eight zooms).

    ``d.im2`` is image 2 (H, W[, 3]); ``F`` and ``truth_F`` (3, 3, truth may be None) map points of
    image 1 to lines of image 2; ``h1`` (n, 3) homogeneous points of image 1, ``p2`` (n, 2) their
    matches in image 2, pixels (x, y).  Returns (the large Axes, the (n,) distances of p2 to F's lines).
    Also Q3.1's figure's rows.
    """
    h, w = d.im2.shape[:2]
    big = fig.add_subplot(grid[2 * row:2 * row + 2, 0])
    image(big, d.im2, label)
    style_true = dict(color="#4fc3f7", lw=1.0, ls="--", zorder=3, gid="true_line")
    style_own = dict(color="#ffb300", lw=1.4, zorder=2, gid="student_line")
    if truth_F is not None:
        _segments(big, h1 @ truth_F.T, w, h, **style_true)
    lines = h1 @ F.T
    _segments(big, lines, w, h, **style_own)
    big.plot(p2[:, 0], p2[:, 1], "o", ms=5, mfc="#e53935", mec="white", zorder=4, gid="match")
    if row == 0:
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], **style_own), Line2D([], [], marker="o", ls="", mfc="#e53935", mec="white")]
        names = ["your lines", "true matches" if truth_F is not None else "given matches"]
        if truth_F is not None:
            handles.insert(1, Line2D([], [], **style_true))
            names.insert(1, "true F's lines")
        big.legend(handles, names, loc="lower right", fontsize=7, framealpha=0.8)
    for k, (x, y) in enumerate(p2):
        ax = fig.add_subplot(grid[2 * row + k // 4, 1 + k % 4])
        image(ax, d.im2)
        one = [lines[k]] + ([] if truth_F is None else [h1[k] @ truth_F.T])
        _segments(ax, one[:1], w, h, **style_own)
        if truth_F is not None:
            _segments(ax, one[1:], w, h, **style_true)
        ax.plot([x], [y], "o", ms=6, mfc="#e53935", mec="white", zorder=4, gid="match")
        ax.set_xlim(x - zoom, x + zoom)
        ax.set_ylim(y + zoom, y - zoom)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"{line_distances(lines[k:k + 1], p2[k:k + 1])[0]:.2g} px", fontsize=7)
    return big, line_distances(lines, p2)


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q2 from run()'s outputs (validated here), on the public data of ``root``.

    One row per F (as returned; refineF switched off; from uint16 points): image 2 with the lines of
    the drawn matches, and a zoom of ZOOM_PX pixels around each match (a transposed F misses by a
    few pixels on this near-vertical pencil of lines: visible in the zooms).

    measures: mean_distance_px, max_distance_px (the drawn true matches to the lines of the F as
    returned), refineF_off_mean_distance_px, uint16_mean_distance_px (when those runs exist),
    uint16_F_change (0 when the uint16 points give the same F as the float ones, up to scale; about
    1 when unrelated), true_F_mean_distance_px (default data only), s3_over_s2 (of the F as
    returned, on points / M: about 0 when rank 2), n_lines, lines_in_image (of the F as returned: an
    F that was not unscaled draws its lines outside image 2).
    """
    Fs = {"F": need(outputs, "F", (3, 3))}
    for key in ("F_refineF_off", "F_uint16"):
        F = maybe(outputs, key, (3, 3))
        if F is not None:
            Fs[key] = F
    drawn = dict(Fs)
    if "F_uint16" in Fs and _change(Fs["F_uint16"], Fs["F"]) <= 1e-9:
        del drawn["F_uint16"]  # the same F: its row would repeat the first
    pub = temple(root)
    d, s = pub.data, pub.scene
    if s is not None:
        p1, p2, truth_F = np.asarray(s.pts1_true, float), np.asarray(s.pts2_true, float), np.asarray(s.F_true, float)
        dots = "the true matches"
    else:
        p1, p2, truth_F, dots = d.pts1, d.pts2, None, "the given matches (noisy)"
    rows = drawn_rows(p1, N_DRAWN)
    h1 = np.column_stack([p1[rows], np.ones(len(rows))])
    fig = figure(size=(11.0, 3.6 * len(drawn)))[0]
    fig.clear()
    grid = fig.add_gridspec(2 * len(drawn), 5, width_ratios=[3.2, 1, 1, 1, 1])
    measures: dict[str, float] = {"n_lines": float(len(rows))}
    parts = []
    for row, (key, F) in enumerate(drawn.items()):
        big, dist = lines_row(fig, grid, row, d, _RUNS[key], F, truth_F, h1, p2[rows], ZOOM_PX)
        mean = float(np.mean(dist)) if np.all(np.isfinite(dist)) else float("inf")
        note = f"{_RUNS[key]}: dots {fmt(mean, 'px')} from the lines on average"
        measures[f"{_KEYS[key]}mean_distance_px"] = mean
        if key == "F":
            measures["max_distance_px"] = float(np.max(dist)) if np.all(np.isfinite(dist)) else float("inf")
            h, w = d.im2.shape[:2]
            measures["lines_in_image"] = float(sum(clip_line(ln, w, h) is not None for ln in h1 @ F.T))
        if key == "F_uint16":
            measures["uint16_F_change"] = _change(F, Fs["F"])
            note += f"; differs from the F of float points by {measures['uint16_F_change']:.3g}"
        if key == "F" and _s3_over_s2(F, d.M) > 1e-6:
            note += f"\nfull rank (s3/s2 = {_s3_over_s2(F, d.M):.2g}): its lines do not meet in one epipole"
        big.set_title(note, fontsize=9)
        parts.append(f"{_RUNS[key]}: {fmt(mean, 'px')}")
    if "F_uint16" in Fs and "F_uint16" not in drawn:
        measures["uint16_F_change"] = _change(Fs["F_uint16"], Fs["F"])
        measures["uint16_mean_distance_px"] = measures["mean_distance_px"]
    if truth_F is not None:
        measures["true_F_mean_distance_px"] = float(np.mean(line_distances(h1 @ truth_F.T, p2[rows])))
    measures["s3_over_s2"] = _s3_over_s2(Fs["F"], d.M)
    rank = "rank 2" if measures["s3_over_s2"] <= 1e-6 else "full rank: its lines do not meet in one epipole"
    alt = (f"Image 2 with {len(rows)} epipolar lines of your F (solid, orange)"
           + (" and of the true F (dashed, blue)" if truth_F is not None else "")
           + f" through {dots} (red dots), and a zoom of {ZOOM_PX} px around each dot. "
           + "Mean distance of the dots to your lines: " + "; ".join(parts)
           + (f"; to the true F's lines: {fmt(measures['true_F_mean_distance_px'], 'px')}"
              if truth_F is not None else "")
           + (f". The F of uint16 points differs from the F of float points by {measures['uint16_F_change']:.3g} "
              "(0: the same up to scale)" if "uint16_F_change" in measures else "")
           + f". {int(measures['lines_in_image'])} of your {len(rows)} lines cross image 2"
           + f". Your F (as returned) is {rank} (s3/s2 = {measures['s3_over_s2']:.3g})."
           + ("" if s is not None else f" There is {NO_TRUTH[3:]}: the dots are the given matches."))
    return to_picture("Q2", "eightpoint: your epipolar lines in image 2", fig, alt, measures)
