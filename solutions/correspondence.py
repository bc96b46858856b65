"""Q4: matching a point of image 1 along its epipolar line in image 2, and the 3D temple."""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from core.validate import as_matrix, as_points

from .triangulation import triangulate

__all__ = ["epipolarCorrespondence", "compute3D_pts"]


def _check_pair(im1, im2):
    # The full images are only checked for shape and dtype here: scanning every pixel on each of
    # hundreds of calls would cost more than the matching.  The windows used are checked below.
    for name, im in (("im1", im1), ("im2", im2)):
        if not isinstance(im, np.ndarray) or im.ndim not in (2, 3) or (im.ndim == 3 and im.shape[2] not in (1, 3, 4)):
            raise ValueError(f"{name}: expected an image array of shape (H, W) or (H, W, 3), got "
                             f"{getattr(im, 'shape', type(im).__name__)}")
        if not (im.dtype == np.uint8 or np.issubdtype(im.dtype, np.floating)):
            raise ValueError(f"{name}: expected dtype uint8 or float in [0, 1], got {im.dtype}")
    if im1.shape != im2.shape:
        raise ValueError(f"im1, im2: expected images of the same shape, got {im1.shape} and {im2.shape}")


def _as_float_windows(win, name):
    if win.dtype == np.uint8:  # cannot hold NaN; float32 is plenty for 8-bit differences
        return win.astype(np.float32) / np.float32(255.0)
    if not np.all(np.isfinite(win)):
        raise ValueError(f"{name}: NaN or inf in the image near the point")
    return win.astype(np.float32)


# The tuned matching parameters (pixels): the window's odd side, the Gaussian weighting's standard
# deviation, and how far from (x1, y1) along the line candidates are searched.
_WINDOW = 15
_SIGMA = 3.5
_SEARCH = 40


def epipolarCorrespondence(im1, im2, F, x1, y1):
    """The pixel of im2 that best matches (x1, y1) of im1, searched along the epipolar line.

    Parameters
    ----------
    im1, im2 : (H, W) or (H, W, 3) images of the same shape, uint8 or float in [0, 1].
    F : (3, 3) fundamental matrix in pixels, x2^T F x1 = 0: F @ [x1, y1, 1] is the epipolar line
        (a, b, c) of the point in im2, the pixels with a x + b y + c = 0.
    x1, y1 : pixel of im1, x = column, y = row.

    Returns
    -------
    (x2, y2) : floats, the best candidate in pixels of im2 (x = column, y = row), chosen by
    comparing a small window around (x1, y1) in im1 with windows around points of the line.

    Raises
    ------
    ValueError
        Bad images, a point outside im1, or a line F x1 that does not cross im2 near the point.

    Method (answer key only)
    ------------------------
    Candidates: the pixels of the line within _SEARCH pixels of (x1, y1) along the line's main
    direction (the two views differ little, so a true match is close).  Score: the sum of
    squared differences over all colour channels of a _WINDOW x _WINDOW window, weighted by a
    Gaussian of standard deviation _SIGMA so that the centre counts most (which helps near
    depth edges).  The smallest score wins.
    """
    window, sigma, search = _WINDOW, _SIGMA, _SEARCH
    _check_pair(im1, im2)
    F = as_matrix(F, "F", (3, 3))
    (x1, y1), = as_points([[x1, y1]], "(x1, y1)")
    if window < 3 or window % 2 == 0:
        raise ValueError(f"window: expected an odd size >= 3, got {window}")
    H, W = im1.shape[:2]
    if not (0 <= x1 <= W - 1 and 0 <= y1 <= H - 1):
        raise ValueError(f"(x1, y1): expected a pixel inside im1 ({W}x{H}), got ({x1}, {y1})")
    h = window // 2
    a, b, c = F @ np.array([x1, y1, 1.0])
    if np.hypot(a, b) == 0:
        raise ValueError(f"F: the epipolar line of ({x1}, {y1}) is undefined (F x1 has a = b = 0)")
    # Walk the line along its main direction so that consecutive candidates are one pixel apart.
    if abs(a) >= abs(b):  # closer to vertical: one candidate per row
        ys = np.arange(np.floor(y1 - search), np.ceil(y1 + search) + 1)
        xs = -(b * ys + c) / a
    else:
        xs = np.arange(np.floor(x1 - search), np.ceil(x1 + search) + 1)
        ys = -(a * xs + c) / b
    xi, yi = np.rint(xs).astype(int), np.rint(ys).astype(int)
    keep = (xi >= h) & (xi < W - h) & (yi >= h) & (yi < H - h)
    if not np.any(keep):
        raise ValueError(f"F: the epipolar line of ({x1}, {y1}) does not cross im2 within {search} px")
    xs, ys, xi, yi = xs[keep], ys[keep], xi[keep], yi[keep]

    off = np.arange(-h, h + 1)
    g = np.exp(-(off ** 2) / (2.0 * sigma ** 2))
    weights = np.outer(g, g) / np.sum(g) ** 2
    # Near the border of im1 the reference window is clamped (edge pixels repeated).
    r = np.clip(int(round(y1)) + off, 0, H - 1)
    q = np.clip(int(round(x1)) + off, 0, W - 1)
    ref = im1[np.ix_(r, q)]
    if ref.ndim == 3:
        ref = np.moveaxis(ref, 2, 0)  # (C, win, win), the layout of the candidate windows below
    ref = _as_float_windows(ref, "im1")
    # A strided view gathers the candidate windows without copying the image first.
    windows = sliding_window_view(im2, (window, window), axis=(0, 1))
    cand = _as_float_windows(windows[yi - h, xi - h], "im2")      # (K, [C,] win, win)
    diff = cand - ref[None]
    diff *= diff
    # One matrix-vector product weighs every pixel of every channel of every candidate.
    w = np.broadcast_to(weights, cand.shape[1:]).astype(np.float32).ravel()
    scores = diff.reshape(len(diff), -1) @ w
    k = int(np.argmin(scores))
    return float(xs[k]), float(ys[k])


def compute3D_pts(im1, im2, F, x1, y1, C1, C2):
    """The templeCoords points of im1, matched in im2 and triangulated.

    Parameters
    ----------
    im1, im2 : the temple images, (H, W, 3) uint8 or float in [0, 1].
    F : (3, 3) fundamental matrix, x2^T F x1 = 0 (pixels).
    x1, y1 : (N,) or (N, 1) pixel coordinates in im1 (templeCoords.npz).
    C1, C2 : (3, 4) projection matrices of the two cameras (C = K [R | t]).

    Returns
    -------
    w : (N, 3) world points (camera-1 frame when C1 = K1 [I | 0]).
    pts2 : (N, 2) the matches found in im2, pixels (x, y).
    """
    x1 = np.asarray(x1, dtype=float).ravel()
    y1 = np.asarray(y1, dtype=float).ravel()
    if x1.shape != y1.shape:
        raise ValueError(f"x1, y1: expected the same number of coordinates, got {x1.size} and {y1.size}")
    pts1 = as_points(np.stack([x1, y1], axis=1), "x1, y1")
    pts2 = np.array([epipolarCorrespondence(im1, im2, F, x, y) for x, y in pts1]).reshape(-1, 2)
    w, _ = triangulate(C1, pts1, C2, pts2)
    return w, pts2
