"""Q2's figure: the student's epipolar lines in image 2, through the true matches, beside the true F's.

Student side (:func:`run`): ``eightpoint(pts1, pts2, M)`` on the public matches (some_corresp,
float pixels (x, y)), as returned; again with refineF switched off, kept when it called refineF
then (the self-check's switch, ``core.refine_switch``: refineF can hide a transposed F; in the
grader the same switch thrown in the sandbox, see :func:`run`); and on the same points as uint16,
the data files' type.  Each F (3, 3) maps a point of image 1 to its line in image 2 (x2^T F x1 = 0).

Trusted side (:func:`draw`): one row per F; in each, image 2 with the lines F x1 of eight matches
spread over the temple (solid) and of the true F (dashed, default data only), the true matching
points (dots), and from every match a red stick towards its line, MISS_MAGNIFY times its distance;
beside it, zooms on the eight matches farthest from their lines.  A right F's lines pass through
the dots and its sticks vanish; a transposed F's (refineF switched off) miss by up to about twenty
pixels on this near-vertical pencil (sticks a fifth of the image long, the first zoom with the line
beside the dot); an unscaled one's by hundreds; a rank-3 F's lines pass near the dots but do not
meet in one epipole: said in the row's title, and its last zoom gives way to where the lines cross,
far above the image (scattered crossings in a tangle of lines, not one point).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial

import numpy as np

from .arrays import call, matrix3, maybe, need
from .drawing import clip_line, image, line_distances
from .picture import Picture, figure, measure_text, to_picture
from .public import NO_TRUTH, temple

__all__ = ["FUNCTIONS", "MISS_MAGNIFY", "N_DRAWN", "N_ZOOMED", "ZOOM_MAX_PX", "ZOOM_PX", "crossings", "draw",
           "drawn_rows", "lines_row", "run"]

FUNCTIONS = ("eightpoint",)
N_DRAWN = 8
ZOOM_PX = 12
# The zooms of a row with all its matches: the N_ZOOMED farthest from their lines, at most
# ZOOM_MAX_PX wide each way; each match's miss drawn MISS_MAGNIFY times as long (one factor for
# every F: a right F's sub-pixel misses stay invisible, a transposed F's few pixels do not).
N_ZOOMED = 8
ZOOM_MAX_PX = 60.0
MISS_MAGNIFY = 10.0
# outputs name -> panel label
_RUNS = {"F": "your F", "F_refineF_off": "your F, refineF switched off", "F_uint16": "your F from uint16 points"}
_KEYS = {"F": "", "F_refineF_off": "refineF_off_", "F_uint16": "uint16_"}
_FRAME = "#8e24aa"   # the largest miss: its square on the large panel, the frame of its zoom


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


def crossings(lines) -> np.ndarray:
    """(k, 2) the finite points (x, y) where each pair of ``lines`` (n, 3) crosses: one point, repeated,
    when they meet in one epipole (a rank-2 F); scattered when they do not (a full-rank F)."""
    lines = np.asarray(lines, float)
    i, j = np.triu_indices(len(lines), 1)
    with np.errstate(all="ignore"):
        x = np.cross(lines[i], lines[j])
        pts = x[:, :2] / x[:, 2:]
    return pts[np.all(np.isfinite(pts), axis=1)]


def _crossings_panel(ax, lines, width: float, height: float) -> float:
    """Draw ``lines`` (n, 3) where they cross, far outside image 2 (w x h) for this near-vertical pencil,
    and their crossings (dots); return the spread of the crossings (px, 0 when they meet in one point).

    The window is stretched along the pencil (aspect not equal): lines stay lines and a common point
    stays one point, so a rank-2 F's lines form one clean bow tie and a full-rank F's a tangle."""
    pts = crossings(lines)
    if len(pts) == 0:
        return float("inf")
    c = np.median(pts, axis=0)
    spread = float(np.percentile(np.hypot(*(pts - c).T), 90))
    along = int(abs(c[1] - height / 2) < abs(c[0] - width / 2))    # 0: the pencil runs along y; 1: along x
    reach = float(np.hypot(c[0] - width / 2, c[1] - height / 2))
    half = max(0.1 * reach, 1.3 * spread, 1.0)
    lo, hi = c[1 - along] - half, c[1 - along] + half
    ends = []
    for ln in lines:
        a, b = (ln[0], ln[1]) if along == 0 else (ln[1], ln[0])    # the coordinate across the pencil at lo, hi
        if abs(a) < 1e-300:
            continue
        across = [-(b * t + ln[2]) / a for t in (lo, hi)]
        ends.append(across)
        xy = (across, [lo, hi]) if along == 0 else ([lo, hi], across)
        ax.plot(*xy, color="#ffb300", lw=0.8, gid="crossing_line")
    ax.plot(pts[:, 0], pts[:, 1], "o", ms=4, mfc="#e53935", mec="none", gid="crossings")
    if ends:
        ends = np.asarray(ends)
        pad = 0.05 * (ends.max() - ends.min() + 1.0)
        (ax.set_xlim if along == 0 else ax.set_ylim)(ends.min() - pad, ends.max() + pad)
    if along == 0:
        ax.set_ylim(hi, lo)    # y down, as in the images
    else:
        ax.set_xlim(lo, hi)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_facecolor("#f5f5f5")
    return spread


def _misses(ax, lines, pts, magnify: float) -> None:
    """One red stick per point of ``pts`` (n, 2), from the point towards the foot of its perpendicular
    on its line of ``lines`` (n, 3), ``magnify`` times as long as the distance: a right F's sticks
    vanish into the dots, a wrong F's show which way and where its lines miss."""
    from matplotlib.collections import LineCollection

    with np.errstate(all="ignore"):
        n2 = lines[:, 0] ** 2 + lines[:, 1] ** 2
        r = (lines[:, 0] * pts[:, 0] + lines[:, 1] * pts[:, 1] + lines[:, 2]) / n2
        ends = pts - magnify * r[:, None] * lines[:, :2]
    ok = np.all(np.isfinite(ends), axis=1)
    ax.add_collection(LineCollection(np.stack([pts[ok], ends[ok]], axis=1), colors="#ff1744", linewidths=1.6,
                                     zorder=5, gid="miss"), autolim=False)


def lines_row(fig, grid, row, d, label, F, truth_F, h1, p2, zoom, every=None):
    """Row ``row`` of ``grid`` (rows 2*row, 2*row + 1 of a 5-column grid): image 2 with the lines (left),
    then eight zooms of at least ``zoom`` px around a dot each.

    ``d.im2`` is image 2 (H, W[, 3]); ``F`` and ``truth_F`` (3, 3, truth may be None) map points of
    image 1 to lines of image 2; ``h1`` (n, 3) homogeneous points of image 1, ``p2`` (n, 2) their
    matches in image 2, pixels (x, y): their lines are drawn.  ``every`` (h1 (N, 3), p2 (N, 2)), all
    the matches, or None: when given, each of them gets a stick to its line MISS_MAGNIFY times its
    distance, and the zooms go to the N_ZOOMED farthest from their lines, the farthest first (framed
    on the large panel), wide enough to show the line (up to ZOOM_MAX_PX); without it the zooms go
    to the drawn dots.  Returns (the large Axes, the (n,) distances of p2 to F's lines).
    Also Q3.1's figure's rows.
    """
    h, w = d.im2.shape[:2]
    big = fig.add_subplot(grid[2 * row:2 * row + 2, 0])
    image(big, d.im2, label)
    big.tick_params(labelsize=8)
    style_true = dict(color="#4fc3f7", lw=1.0, ls="--", zorder=3, gid="true_line")
    style_own = dict(color="#ffb300", lw=1.4, zorder=2, gid="student_line")
    if truth_F is not None:
        _segments(big, h1 @ truth_F.T, w, h, **style_true)
    lines = h1 @ F.T
    _segments(big, lines, w, h, **style_own)
    big.plot(p2[:, 0], p2[:, 1], "o", ms=5, mfc="#e53935", mec="white", zorder=4, gid="match")
    zh1, zp2, half = h1, p2, float(zoom)
    if every is not None:
        all_h1, all_p2 = (np.asarray(a, float) for a in every)
        all_lines = all_h1 @ F.T
        big.plot(all_p2[:, 0], all_p2[:, 1], "o", ms=2.5, mfc="#e53935", mec="none", zorder=4, gid="all_matches")
        _misses(big, all_lines, all_p2, MISS_MAGNIFY)
        far = np.nan_to_num(line_distances(all_lines, all_p2), nan=np.inf)
        pick = np.argsort(-far, kind="stable")[:N_ZOOMED]
        zh1, zp2 = all_h1[pick], all_p2[pick]
        if np.isfinite(far[pick[0]]):
            half = float(np.clip(1.3 * far[pick[0]], zoom, ZOOM_MAX_PX))
        x, y = zp2[0]
        big.plot([x], [y], "s", ms=14, mfc="none", mec=_FRAME, mew=2.0, zorder=6, gid="largest_miss")
    if row == 0:
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], **style_own), Line2D([], [], marker="o", ls="", mfc="#e53935", mec="white")]
        names = ["your lines", "true matches" if truth_F is not None else "given matches"]
        if truth_F is not None:
            handles.insert(1, Line2D([], [], **style_true))
            names.insert(1, "true F's lines")
        if every is not None:
            handles.append(Line2D([], [], color="#ff1744", lw=1.6))
            names.append(f"miss x{MISS_MAGNIFY:g}")
        big.legend(handles, names, loc="lower right", fontsize=8, framealpha=0.8)
    zlines = zh1 @ F.T
    for k, (x, y) in enumerate(zp2):
        ax = fig.add_subplot(grid[2 * row + k // 4, 1 + k % 4])
        image(ax, d.im2)
        _segments(ax, zlines[k:k + 1], w, h, **style_own)
        if truth_F is not None:
            _segments(ax, zh1[k:k + 1] @ truth_F.T, w, h, **style_true)
        ax.plot([x], [y], "o", ms=6, mfc="#e53935", mec="white", zorder=4, gid="match")
        ax.set_xlim(x - half, x + half)
        ax.set_ylim(y + half, y - half)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(measure_text(line_distances(zlines[k:k + 1], zp2[k:k + 1])[0], "px"), fontsize=10)
        if every is not None and k == 0:
            for side in ax.spines.values():
                side.set_edgecolor(_FRAME)
                side.set_linewidth(2.5)
    return big, line_distances(lines, p2)


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q2 from run()'s outputs (validated here), on the public data of ``root``.

    One row per F (as returned; refineF switched off; from uint16 points): image 2 with the lines of
    the drawn matches and every match's miss magnified (MISS_MAGNIFY), and zooms on the matches
    farthest from their lines (a transposed F misses by a few pixels on this near-vertical pencil of
    lines, up to about twenty: the red sticks and the zooms show it without reading a number).

    measures: mean_distance_px, max_distance_px (the drawn true matches to the lines of the F as
    returned), largest_miss_px (of all the true matches, the first zoom), refineF_off_mean_distance_px,
    refineF_off_largest_miss_px, uint16_mean_distance_px, uint16_largest_miss_px (when those runs exist),
    uint16_F_change (0 when the uint16 points give the same F as the float ones, up to scale; about
    1 when unrelated), true_F_mean_distance_px (default data only), s3_over_s2 (of the F as
    returned, on points / M: about 0 when rank 2), n_lines, lines_in_image (of the F as returned: an
    F that was not unscaled draws its lines outside image 2), crossings_spread_px (only when the F as
    returned has full rank: how far apart its drawn lines cross, 90th percentile from their median
    crossing; its last zoom then shows where they cross instead).
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
    every = (np.column_stack([p1, np.ones(len(p1))]), p2)
    # 9 in at 90 dpi: 810 px, about what Gradescope shows, so its copy keeps the fonts' size
    fig = figure(size=(9.0, 3.5 * len(drawn) + 0.4))[0]
    fig.clear()
    grid = fig.add_gridspec(2 * len(drawn), 5, width_ratios=[3.2, 1, 1, 1, 1])
    measures: dict[str, float] = {"n_lines": float(len(rows))}
    parts, parts_far = [], []
    for row, (key, F) in enumerate(drawn.items()):
        big, dist = lines_row(fig, grid, row, d, _RUNS[key], F, truth_F, h1, p2[rows], ZOOM_PX, every)
        mean = float(np.mean(dist)) if np.all(np.isfinite(dist)) else float("inf")
        far = line_distances(every[0] @ F.T, p2)
        largest = float(np.max(far)) if np.all(np.isfinite(far)) else float("inf")
        note = f"{_RUNS[key]}\ndots {measure_text(mean, 'px')} from their lines on average, up to {measure_text(largest, 'px')}"
        measures[f"{_KEYS[key]}mean_distance_px"] = mean
        measures[f"{_KEYS[key]}largest_miss_px"] = largest
        parts_far.append(f"{_RUNS[key]}: {measure_text(largest, 'px')}")
        if key == "F":
            measures["max_distance_px"] = float(np.max(dist)) if np.all(np.isfinite(dist)) else float("inf")
            h, w = d.im2.shape[:2]
            measures["lines_in_image"] = float(sum(clip_line(ln, w, h) is not None for ln in h1 @ F.T))
        if key == "F_uint16":
            measures["uint16_F_change"] = _change(F, Fs["F"])
            note += f"\ndiffers from the F of float points by {measures['uint16_F_change']:.3g}"
        if key == "F" and _s3_over_s2(F, d.M) > 1e-6:
            note += f"\nfull rank (s3/s2 = {_s3_over_s2(F, d.M):.2g}, not 0): no one epipole"
            # the lines pass the dots but do not meet: the last zoom gives way to where they cross
            fig.delaxes(fig.axes[-1])
            cross = fig.add_subplot(grid[2 * row + 1, 4])
            h, w = d.im2.shape[:2]
            measures["crossings_spread_px"] = _crossings_panel(cross, h1 @ F.T, w, h)
            cross.set_title("where they cross", fontsize=10, color="#c62828")
        # 9 pt: at 10 the longest line ran past the panel into its first zoom
        big.set_title(note, fontsize=9)
        parts.append(f"{_RUNS[key]}: {measure_text(mean, 'px')}")
    if "F_uint16" in Fs and "F_uint16" not in drawn:
        measures["uint16_F_change"] = _change(Fs["F_uint16"], Fs["F"])
        measures["uint16_mean_distance_px"] = measures["mean_distance_px"]
        measures["uint16_largest_miss_px"] = measures["largest_miss_px"]
    if truth_F is not None:
        measures["true_F_mean_distance_px"] = float(np.mean(line_distances(h1 @ truth_F.T, p2[rows])))
    measures["s3_over_s2"] = _s3_over_s2(Fs["F"], d.M)
    rank = "rank 2" if measures["s3_over_s2"] <= 1e-6 else "full rank: its lines do not meet in one epipole"
    alt = (f"Image 2 with {len(rows)} epipolar lines of your F (solid, orange)"
           + (" and of the true F (dashed, blue)" if truth_F is not None else "")
           + f" through {dots} (red dots); a red stick from each of the {len(p1)} matches towards its line, "
           + f"{MISS_MAGNIFY:g} times its distance; and zooms of at least {ZOOM_PX} px on the {N_ZOOMED} matches "
           + "farthest from their lines, the farthest framed in purple (its square on the image). "
           + "Mean distance of the dots to your lines: " + "; ".join(parts)
           + (f"; to the true F's lines: {measure_text(measures['true_F_mean_distance_px'], 'px')}"
              if truth_F is not None else "")
           + ". Largest distance of a match to its line: " + "; ".join(parts_far)
           + (f". The F of uint16 points differs from the F of float points by {measures['uint16_F_change']:.3g} "
              "(0: the same up to scale)" if "uint16_F_change" in measures else "")
           + f". {int(measures['lines_in_image'])} of your {len(rows)} lines cross image 2"
           + f". Your F (as returned) is {rank} (s3/s2 = {measures['s3_over_s2']:.3g})."
           + ("" if s is not None else f" There is {NO_TRUTH[3:]}: the dots are the given matches."))
    return to_picture("Q2", "eightpoint: your epipolar lines in image 2", fig, alt, measures)
