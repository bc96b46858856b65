"""Small drawing pieces shared by the questions' figures (matplotlib Axes in, nothing returned).

Pixels are (x, y) = (column, row): images are shown with the origin at the top left, x to the
right, y down, so a point (x, y) is drawn at ``ax.plot(x, y)``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["clip_line", "image", "line_distances", "two_bars"]


def image(ax, im, title: str = "") -> None:
    """Show ``im`` (H, W[, 3]) uint8 or float dimmed to grey, pixel axes, (0, 0) at the top left."""
    im = np.asarray(im, float)
    if im.ndim == 3:
        im = im[..., :3].mean(axis=2)
    if im.max(initial=0) > 1.5:
        im = im / 255.0
    h, w = im.shape[:2]
    ax.imshow(0.25 + 0.5 * im, cmap="gray", vmin=0, vmax=1, extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    if title:
        ax.set_title(title, fontsize=9)


def line_distances(lines, pts) -> np.ndarray:
    """(N,) distances in pixels of the points pts (N, 2) to the lines (N, 3) a x + b y + c = 0."""
    lines, pts = np.asarray(lines, float), np.asarray(pts, float)
    with np.errstate(all="ignore"):
        residual = lines[:, 0] * pts[:, 0] + lines[:, 1] * pts[:, 1] + lines[:, 2]
        return np.abs(residual) / np.hypot(lines[:, 0], lines[:, 1])


def clip_line(line, width: float, height: float):
    """The two end points ((x0, x1), (y0, y1)) of the line (3,) inside the image, or None if it misses it."""
    a, b, c = (float(v) for v in line)
    pts = []
    if abs(b) > 1e-12:
        for x in (0.0, width - 1.0):
            y = -(a * x + c) / b
            if 0.0 <= y <= height - 1.0:
                pts.append((x, y))
    if abs(a) > 1e-12:
        for y in (0.0, height - 1.0):
            x = -(b * y + c) / a
            if 0.0 <= x <= width - 1.0:
                pts.append((x, y))
    if len(pts) < 2:
        return None
    pts = sorted(set(pts))
    (x0, y0), (x1, y1) = pts[0], pts[-1]
    return (x0, x1), (y0, y1)


def two_bars(ax, where, heights, colors, labels, title: str, gid: str) -> None:
    """Two bars in an inset of ``ax`` at ``where`` (x, y, width, height in axes fractions), on one
    linear scale from 0: two numbers that should agree (or not) compared at a glance.  A
    non-finite height is drawn as 0; each bar gets ``gid`` (tests find them by it)."""
    inset = ax.inset_axes(where)
    heights = [h if np.isfinite(h) else 0.0 for h in heights]
    for bar in inset.bar([0, 1], heights, color=list(colors), width=0.7):
        bar.set_gid(gid)
    inset.set_ylim(0, 1.15 * max(max(heights), 1e-300))
    inset.set_xticks([0, 1], list(labels), fontsize=6)
    inset.set_yticks([])
    inset.set_title(title, fontsize=7, pad=2)
    inset.tick_params(length=0, pad=1)
