"""Q4.1's goal, set by several correct matchers, and the points a correct matcher can be expected to get.

Grader-side only (these are working answers to Q4.1: ``core.shipping`` keeps ``solutions/`` from
students).  Two things are computed here, once per scene, from the images, the true F and the
true matches:

- :func:`easy_points`: the points whose window is *distinctive*: along the true epipolar line in
  image 2, the true match's window dissimilarity is clearly lower than that of every candidate
  more than ``tol`` pixels away, at each of several window sizes (the handout's "easy points,
  such as those with distinctive, corner-like windows");
- :func:`match_styles`: what several matchers written the ways hand-ins write them find on those
  points: one parametrised matcher (:class:`Style`: SSD, SAD or NCC, a uniform or Gaussian
  weighting, windows of 5 to 101 px, candidates near (x1, y1) or along the whole line), run on
  float images in [0, 1] as the course gives them.  The goal of Q4.1 is set from the weakest of
  them (``judging.correspondence``), not from one tuned reference.

Conventions: pixels (x, y) = (column, row); F maps a point of image 1 to its epipolar line in
image 2 (x2^T F x1 = 0); images (H, W) or (H, W, C), uint8 or float in [0, 1].  Windows that
would cross the border are filled with the nearest border pixel (edge padding), so a point near
the border is matched, never skipped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import fft as sp_fft

from core.validate import as_matrix, as_points

__all__ = ["BOX", "DISTINCT_RATIO", "DISTINCT_WINDOWS", "STYLES", "EasyProblem", "Style", "easy_points", "easy_problem",
           "NEAR", "along_line", "match_styles", "off_transposed_line", "prepare_images", "scene_problem",
           "surface_tolerance"]

_PAD = 50   # the largest half window (101 px)
_GATHER_MAX = 31   # larger windows are compared by FFT


@dataclass(frozen=True)
class Style:
    """One way of writing epipolarCorrespondence.

    score : "ssd" (sum of squared differences), "sad" (sum of absolute differences) or "ncc"
        (normalised cross-correlation, highest wins).
    window : the window's odd side in pixels, 3 to 101.
    sigma : the standard deviation (px) of a Gaussian weighting of the window; None: uniform.
    search : candidates within this many pixels of (x1, y1) along the line's main direction;
        None: every pixel of the line inside image 2.
    """

    score: str
    window: int
    sigma: float | None = None
    search: int | None = None

    def __post_init__(self):
        if self.score not in ("ssd", "sad", "ncc"):
            raise ValueError(f"score: expected 'ssd', 'sad' or 'ncc', got {self.score!r}")
        if not (3 <= self.window <= 2 * _PAD + 1 and self.window % 2 == 1):
            raise ValueError(f"window: expected an odd size from 3 to {2 * _PAD + 1}, got {self.window}")

    @property
    def name(self) -> str:
        weight = f", Gaussian sigma {self.sigma:g}" if self.sigma else ""
        where = "whole line" if self.search is None else f"within {self.search} px"
        return f"{self.score.upper()} {self.window} px{weight}, {where}"


# The styles the goal is set from: the handout's similarity measures, small to very large
# windows, local and whole-line search.
STYLES = (
    Style("ssd", 5, search=25),
    Style("ssd", 11),
    Style("sad", 9, search=30),
    Style("ncc", 21),
    Style("ssd", 31, sigma=5.0, search=40),
    Style("ssd", 101, sigma=5.0, search=25),
)

# A point is easy when, at each of these window sizes, every candidate of the true line more
# than tol px from the true match scores at least DISTINCT_RATIO times the true match's SSD.
DISTINCT_WINDOWS = (5, 11, 21)
DISTINCT_RATIO = 1.2
MIN_EASY = 4


def prepare_images(im1, im2) -> tuple[np.ndarray, np.ndarray]:
    """(pad1, pad2): the images as float32 in [0, 1], (H + 100, W + 100, C), edge-padded by 50 px.

    Raises ValueError for images that are not (H, W) or (H, W, C) arrays of one shape.
    """
    out = []
    for name, im in (("im1", im1), ("im2", im2)):
        im = np.asarray(im)
        if im.ndim not in (2, 3) or im.size == 0:
            raise ValueError(f"{name}: expected an image of shape (H, W) or (H, W, C), got {im.shape}")
        f = im.astype(np.float32) / np.float32(255) if im.dtype == np.uint8 else im.astype(np.float32)
        if f.ndim == 2:
            f = f[:, :, None]
        out.append(np.pad(f, ((_PAD, _PAD), (_PAD, _PAD), (0, 0)), mode="edge"))
    if out[0].shape != out[1].shape:
        raise ValueError(f"im1, im2: expected the same shape, got {np.shape(im1)} and {np.shape(im2)}")
    return out[0], out[1]


def _line_candidates(F, x1, y1, W, H, search):
    """(xs, ys) floats: one point of the line F [x1, y1, 1] per pixel of its main direction, inside
    the W x H image, within ``search`` px of (x1, y1) along that direction (None: all)."""
    a, b, c = F @ np.array([x1, y1, 1.0])
    if np.hypot(a, b) == 0:
        return np.empty(0), np.empty(0)
    if abs(a) >= abs(b):   # closer to vertical: one candidate per row
        lo, hi = (0, H - 1) if search is None else (max(0, int(np.floor(y1 - search))), min(H - 1, int(np.ceil(y1 + search))))
        ys = np.arange(lo, hi + 1, dtype=float)
        xs = -(b * ys + c) / a
    else:
        lo, hi = (0, W - 1) if search is None else (max(0, int(np.floor(x1 - search))), min(W - 1, int(np.ceil(x1 + search))))
        xs = np.arange(lo, hi + 1, dtype=float)
        ys = -(a * xs + c) / b
    keep = (xs >= 0) & (xs <= W - 1) & (ys >= 0) & (ys <= H - 1)
    return xs[keep], ys[keep]


def _windows(pad, xs, ys, window):
    """(K, window * window * C) float32: the windows of the padded image centred on pixels (xs, ys)."""
    h = window // 2
    view = sliding_window_view(pad, (window, window), axis=(0, 1))   # (.., .., C, win, win)
    r = np.rint(np.asarray(ys)).astype(int) + _PAD - h
    q = np.rint(np.asarray(xs)).astype(int) + _PAD - h
    return view[r, q].reshape(len(r), -1)


def _weights2d(window, sigma):
    """(window, window) float64: a Gaussian of standard deviation sigma (px), or ones (None)."""
    if sigma is None:
        return np.ones((window, window))
    off = np.arange(window) - window // 2
    g = np.exp(-(off ** 2) / (2.0 * sigma ** 2))
    return np.outer(g, g)


def _ssd_along(pad1, pad2, x1, y1, xs, ys, window, weights):
    """(K,) the weighted SSD (weights (window, window)) of the windows of pad2 at the candidates
    (xs, ys) to the window of pad1 at (x1, y1): gathered windows for small ones, FFT correlation
    over the candidates' bounding box for large ones (cheap even for 101 px along a whole line)."""
    h = window // 2
    if window <= _GATHER_MAX:
        w = np.broadcast_to(weights[None], (pad1.shape[2], window, window)).astype(np.float32).ravel()
        return ((_windows(pad2, xs, ys, window) - _windows(pad1, [x1], [y1], window)[0]) ** 2) @ w
    xi, yi = np.rint(xs).astype(int) + _PAD, np.rint(ys).astype(int) + _PAD
    r0, r1, q0, q1 = yi.min(), yi.max(), xi.min(), xi.max()
    crop = pad2[r0 - h:r1 + h + 1, q0 - h:q1 + h + 1]
    cy, cx = int(round(y1)) + _PAD, int(round(x1)) + _PAD
    ref = pad1[cy - h:cy + h + 1, cx - h:cx + h + 1] * weights[:, :, None].astype(np.float32)
    size = [sp_fft.next_fast_len(n + window - 1, real=True) for n in crop.shape[:2]]

    def correlate(image, kernel):   # 'valid' correlation of (H, W, C) with (win, win, C), summed over C
        spectrum = (sp_fft.rfft2(image, size, axes=(0, 1)) * sp_fft.rfft2(kernel[::-1, ::-1], size, axes=(0, 1)))
        return sp_fft.irfft2(spectrum.sum(axis=2), size)[window - 1:image.shape[0], window - 1:image.shape[1]]

    cross = correlate(crop, ref)
    energy = correlate(np.sum(crop ** 2, axis=2, keepdims=True), weights[:, :, None].astype(np.float32))
    own = float(np.sum(ref * pad1[cy - h:cy + h + 1, cx - h:cx + h + 1]))
    k = (yi - r0, xi - q0)
    return np.maximum(energy[k] - 2.0 * cross[k] + own, 0.0)


def _scores(style: Style, pads, x1, y1, xs, ys):
    """(K,) dissimilarities (lower is better) of the candidates (xs, ys) to the window of (x1, y1)."""
    w2 = _weights2d(style.window, style.sigma)
    if style.score == "ssd":
        return _ssd_along(*pads, x1, y1, xs, ys, style.window, w2)
    channels = pads[0].shape[2]
    weights = np.broadcast_to(w2[None], (channels, style.window, style.window)).astype(np.float32).ravel()
    ref = _windows(pads[0], [x1], [y1], style.window)[0]
    cand = _windows(pads[1], xs, ys, style.window)
    if style.score == "sad":
        return np.abs(cand - ref) @ weights
    r = (ref - ref.mean()) * weights
    c = (cand - cand.mean(axis=1, keepdims=True)) * weights
    norm = np.linalg.norm(c, axis=1) * np.linalg.norm(r)
    return -(c @ r) / np.where(norm > 0, norm, np.inf)


def match_styles(im1, im2, F, pts1, styles=STYLES, *, padded=None) -> np.ndarray:
    """(S, P, 2): the match (x2, y2) each style finds for each point (x1, y1) of pts1 (P, 2).

    im1, im2 : the images (see the module docstring); padded : their :func:`prepare_images`
        when already made (one scene, several calls).
    F : (3, 3), x2^T F x1 = 0.  A point whose line misses image 2 gets NaN.
    """
    F = as_matrix(F, "F", (3, 3))
    pts1 = as_points(pts1, "pts1")
    pad1, pad2 = padded if padded is not None else prepare_images(im1, im2)
    H, W = pad1.shape[0] - 2 * _PAD, pad1.shape[1] - 2 * _PAD
    out = np.full((len(styles), len(pts1), 2), np.nan)
    for s, style in enumerate(styles):
        for p, (x1, y1) in enumerate(pts1):
            xs, ys = _line_candidates(F, x1, y1, W, H, style.search)
            if len(xs):
                k = int(np.argmin(_scores(style, (pad1, pad2), x1, y1, xs, ys)))
                out[s, p] = xs[k], ys[k]
    return out


def easy_points(im1, im2, F, pts1, truth2, tol: float, *, padded=None, windows=DISTINCT_WINDOWS,
                ratio: float = DISTINCT_RATIO) -> np.ndarray:
    """(P,) bool: the points of pts1 (P, 2) whose true match truth2 (P, 2) is distinctive on its line.

    For each window size, the SSD of the window at the true match (its nearest candidate on the
    line F x1) to the window of (x1, y1) must be at most 1 / ``ratio`` of the smallest SSD of the
    candidates more than ``tol`` px from the true match along the whole line.  A point whose
    line holds no candidate further than ``tol`` is not easy (nothing shows it distinctive).
    """
    F = as_matrix(F, "F", (3, 3))
    pts1, truth2 = as_points(pts1, "pts1"), as_points(truth2, "truth2")
    if len(pts1) != len(truth2):
        raise ValueError(f"pts1, truth2: expected the same number of points, got {len(pts1)} and {len(truth2)}")
    pad1, pad2 = padded if padded is not None else prepare_images(im1, im2)
    H, W = pad1.shape[0] - 2 * _PAD, pad1.shape[1] - 2 * _PAD
    out = np.zeros(len(pts1), bool)
    for p, ((x1, y1), t2) in enumerate(zip(pts1, truth2)):
        xs, ys = _line_candidates(F, x1, y1, W, H, None)
        if len(xs) == 0:
            continue
        dist = np.hypot(xs - t2[0], ys - t2[1])
        far = dist > tol
        if not far.any():
            continue
        near = dist <= max(1.0, dist.min())
        out[p] = all(d[far].min() >= ratio * d[near].min() for d in
                     (_ssd_along(pad1, pad2, x1, y1, xs, ys, win, _weights2d(win, None)) for win in windows))
    return out


@dataclass(frozen=True, eq=False)
class EasyProblem:
    """The easy points of one scene and the goal the styles set on them.

    index : (P,) sorted indices, into the pool given to :func:`easy_problem`, of the easy points.
    tol3d : (P,) how far (world units) a match ``tol`` px off along its epipolar line moves each
        point: the 3D tolerance of ``judging.correspondence.right_structure``.
    ref_share : the smallest share, over STYLES, of matches within ``tol`` px of the true ones.
    ref_share_3d : the smallest share, over STYLES, of their matches triangulated with the true
        cameras that lie on the structure (judging.correspondence.right_structure), and never
        above ref_share (a style whose matches are right as often may be expected to pass Q4.2).
    shares : ((style name, share, share 3D), ...) of every style, for the feedback and the report.
    flat_share_3d : the share right_structure gives a flat temple: the points triangulated from
        matches that keep (x1, y1), or that all move by the median true disparity (what a window
        so wide that it sees only the whole object's shift finds).  Up to a similarity, such a
        temple lies within tol3d of many points where the relief is small, so Q4.2 asks for more
        (judging.correspondence.structure_goal).
    """

    index: np.ndarray
    tol3d: np.ndarray
    ref_share: float
    ref_share_3d: float
    shares: tuple
    flat_share_3d: float = 0.0


def surface_tolerance(C1, C2, F, truth2, tol: float, pts1) -> np.ndarray:
    """(P,): the mean distance between the triangulation of (pts1, truth2) (P, 2) with C1, C2 (3, 4)
    and those of truth2 moved ``tol`` px either way along its epipolar line F x1."""
    from .triangulation import triangulate

    pts1, truth2 = as_points(pts1, "pts1"), as_points(truth2, "truth2")
    lines = np.column_stack([pts1, np.ones(len(pts1))]) @ np.asarray(F, float).T
    u = np.column_stack([lines[:, 1], -lines[:, 0]])
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    X0 = triangulate(C1, pts1, C2, truth2)[0]
    return np.mean([np.linalg.norm(triangulate(C1, pts1, C2, truth2 + sign * tol * u)[0] - X0, axis=1)
                    for sign in (-1.0, 1.0)], axis=0)


def easy_problem(im1, im2, F, pts1, truth2, truth3d, C1, C2, tol: float, count: int,
                 rng: np.random.Generator | None = None, styles=STYLES) -> EasyProblem:
    """Up to ``count`` easy points (:func:`easy_points`) of the pool pts1 (N, 2) with true matches
    truth2 (N, 2) and true 3D points truth3d (N, 3), and the goal the styles set on them.

    The pool is looked at in the order of ``rng.permutation`` (None: as given) and the search
    stops once ``count`` easy points are found; with fewer than MIN_EASY easy points in the whole
    pool, its first ``count`` points are judged instead (the goal, set on them, stays fair).  C1, C2 (3, 4) the true cameras, F the true F.
    """
    from judging.correspondence import right_2d, right_structure

    from .triangulation import triangulate

    pts1, truth2 = as_points(pts1, "pts1"), as_points(truth2, "truth2")
    truth3d = np.asarray(truth3d, float).reshape(-1, 3)
    padded = prepare_images(im1, im2)
    order = np.arange(len(pts1)) if rng is None else rng.permutation(len(pts1))
    chosen: list[int] = []
    for start in range(0, len(order), max(count, 1)):
        block = order[start:start + max(count, 1)]
        chosen.extend(block[easy_points(None, None, F, pts1[block], truth2[block], tol, padded=padded)].tolist())
        if len(chosen) >= count:
            break
    if len(chosen) < min(MIN_EASY, len(order)):   # hardly a distinctive point: judge the pool's first ones
        chosen = order[:count].tolist()
    index = np.sort(np.array(chosen[:count], dtype=int))
    if not len(index):
        return EasyProblem(index, np.empty(0), 1.0, 1.0, ())
    p1, t2, t3 = pts1[index], truth2[index], truth3d[index]
    tol3d = surface_tolerance(C1, C2, F, t2, tol, p1)
    found = match_styles(None, None, F, p1, styles, padded=padded)
    shares = []
    for style, f in zip(styles, found):
        w = np.full((len(p1), 3), np.nan)
        ok = np.all(np.isfinite(f), axis=1)
        if ok.any():
            w[ok] = triangulate(C1, p1[ok], C2, f[ok])[0]
        shares.append((style.name, float(right_2d(f, t2, tol).mean()), float(right_structure(w, t3, tol3d)[0].mean())))
    ref_share = min(s[1] for s in shares)
    flat = max(float(right_structure(triangulate(C1, p1, C2, p2)[0], t3, tol3d)[0].mean())
               for p2 in (p1, p1 + np.median(t2 - p1, axis=0)))
    return EasyProblem(index, tol3d, ref_share, min(ref_share, *(s[2] for s in shares)), tuple(shares), flat)


# Points are chosen this far from the border in both images, so that a 101-px window fits.
MARGIN = 50
# A matcher that never leaves rows y1 +- BOX (a tutorial's search box) reaches only matches this
# close to (x1, y1) along its line; NEAR: the nearest search of the goal styles.
BOX = 10
NEAR = min(s.search for s in STYLES if s.search is not None)
# One pixel beyond the tolerance: the slips' candidates are rounded to whole pixels.
_ROUNDING = 1.0


def along_line(F, pts1, pts2) -> np.ndarray:
    """(P,) how far pts2 (P, 2) lies from pts1 (P, 2) along the main direction (x or y) of each
    point's epipolar line F x1, as a matcher steps its candidates (one per row or per column)."""
    lines = np.column_stack([pts1, np.ones(len(pts1))]) @ np.asarray(F, float).T
    steps_rows = np.abs(lines[:, 0]) >= np.abs(lines[:, 1])
    d = np.abs(np.asarray(pts2, float) - pts1)
    return np.where(steps_rows, d[:, 1], d[:, 0])


def off_transposed_line(F, pts1, pts2) -> np.ndarray:
    """(P,) the distance (px) of pts2 (P, 2) from the line F^T x1 of each point pts1 (P, 2): the
    line a matcher that mixes up F and its transpose searches."""
    lines = np.column_stack([pts1, np.ones(len(pts1))]) @ np.asarray(F, float)
    return np.abs(np.sum(lines[:, :2] * pts2, axis=1) + lines[:, 2]) / np.hypot(lines[:, 0], lines[:, 1])


def scene_problem(scene, count: int, rng: np.random.Generator | None = None, *,
                  slips: bool = False) -> tuple[np.ndarray, EasyProblem]:
    """(rows, problem): the easy points of a scenes.temple.TempleScene among its templeCoords rows
    whose true match is known (unoccluded in image 2), MARGIN px inside both images and more than
    2 * tol px from the point itself (so that returning (x1, y1) cannot pass); ``rows`` (P,) index
    scene.x1 / x2_true / X_coords.  tol is judging.correspondence.tolerance(scene.width).

    slips : also keep only the points that tell a search along the epipolar line from two slips
        (Q4.1's points): the match lies more than BOX + tol (+ rounding) px from (x1, y1) along
        the line, so that no candidate of a +-BOX px box is within tol of it, and at most NEAR,
        so that every goal style reaches it; and more than tol (+ rounding) px off the line
        F^T x1, so that no candidate of the transposed line is within tol of it.  Not for the 3D
        structure (Q4.2): a band of disparities is a band of depths, nearly flat.
    When fewer than 8 rows qualify, the visible points are judged (a degenerate scene).
    """
    from judging.correspondence import tolerance

    W, H = scene.width, scene.height
    tol = tolerance(W)
    p1 = np.column_stack([np.ravel(scene.x1), np.ravel(scene.y1)]).astype(float)
    disparity = np.linalg.norm(scene.x2_true - p1, axis=1)

    def inside(p, margin):
        return np.all((p >= margin) & (p <= [W - 1 - margin, H - 1 - margin]), axis=1)

    keep = scene.visible2 & inside(p1, MARGIN) & inside(scene.x2_true, MARGIN) & (disparity > 2 * tol)
    if slips:
        along = along_line(scene.F_true, p1, scene.x2_true)
        keep &= (along > BOX + tol + _ROUNDING) & (along <= NEAR)
        keep &= off_transposed_line(scene.F_true, p1, scene.x2_true) > tol + _ROUNDING
    pool = np.flatnonzero(keep)
    if len(pool) < 8:  # a degenerate scene would make the check meaningless
        pool = np.flatnonzero(scene.visible2 & inside(p1, 8))
    problem = easy_problem(scene.im1, scene.im2, scene.F_true, p1[pool], scene.x2_true[pool], scene.X_coords[pool],
                           scene.C1, scene.C2, tol, count, rng)
    return pool[problem.index], problem
