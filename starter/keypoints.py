"""Figures of the car keypoints of problem 6: 2D detections on an image, one 3D frame, a video.

Keypoint arrays follow ``q6/time{t}.npz``: row k is keypoint ``CAR_KEYPOINTS[k]``
(``core.skeleton``), pixel rows are (x, y, confidence) with x the column and y the row, and
3D rows are (X, Y, Z) in the world frame of the cameras' extrinsics.  A 3D row of NaN is a
keypoint that was not reconstructed (all its detections were below the confidence threshold):
it is skipped, and so is every skeleton edge that touches it.
"""

from __future__ import annotations

import numpy as np

from .figures import DEFAULT_COLORS, Figure3D, plot_points_3d, points_with_gaps
from core.skeleton import CAR_KEYPOINTS, CAR_SKELETON
from core.validate import as_finite_scalar, as_image, as_points

__all__ = ["visualize_keypoints", "plot_3d_keypoint", "plot_3d_keypoint_frames", "car_view",
           "WORLD_AXIS_TITLES"]

#: Axis titles of the car figures: the world frame of the extrinsics, whose -Y is up.
WORLD_AXIS_TITLES = ("X (world)", "Y (world, down)", "Z (world)")

# Keypoint rows of the front and the rear of the car (CAR_KEYPOINTS order).
_FRONT = [0, 1, 4, 5, 8, 9]
_REAR = [2, 3, 6, 7, 10, 11]


def _horizontal(v: np.ndarray) -> np.ndarray:
    """(x, z) part of a world vector: the ground plane of a world whose -Y is up."""
    return np.array([v[0], v[2]])


def _car_forward(P: np.ndarray) -> np.ndarray | None:
    """Front minus rear of one car (N = 12 rows, NaN allowed), or None when a side is missing."""
    if len(P) != len(CAR_KEYPOINTS):
        return None
    front, rear = P[_FRONT], P[_REAR]
    front, rear = front[np.isfinite(front).all(axis=1)], rear[np.isfinite(rear).all(axis=1)]
    if not len(front) or not len(rear):
        return None
    return front.mean(axis=0) - rear.mean(axis=0)


def car_view(frames, *, elev: float = 45.0, turn: float = 25.0) -> tuple[float, float]:
    """A viewpoint (elev, azim) for ``plot_points_3d(..., up="-y")`` that shows the car moving.

    The viewer looks down on the ground plane (the world's X-Z plane, -Y being up) from
    ``elev`` degrees above it, from the side of the path: the motion runs across the picture,
    from left (first frame) to right (last frame).  The viewer stands ``turn`` degrees behind
    the side (looking a little along the direction of travel), so that successive cars do not
    hide each other and the car's length, width and height all show.  Without
    motion (one frame, or a car that does not move) the car's own front-rear axis takes the
    place of the path.

    Parameters
    ----------
    frames : sequence of T arrays of shape (N, 3)
        World points per time step; NaN rows are missing keypoints.
    elev, turn : float
        Degrees.

    Returns
    -------
    (elev, azim) : tuple of float
        Degrees, in the convention of :func:`starter.figures.plot_points_3d`'s ``view``.
    """
    sets = [np.asarray(f, dtype=float) for f in frames]
    centres = [f[np.isfinite(f).all(axis=1)].mean(axis=0) for f in sets if np.isfinite(f).all(axis=1).any()]
    direction = None
    if len(centres) >= 2:
        path = _horizontal(centres[-1] - centres[0])
        spread = max(np.ptp(np.concatenate([f[np.isfinite(f).all(axis=1)] for f in sets]), axis=0).max(), 1e-12)
        if np.linalg.norm(path) > 0.05 * spread:
            direction = path
    if direction is None:
        forwards = [fw for fw in (_car_forward(f) for f in sets) if fw is not None]
        if forwards:
            direction = _horizontal(np.mean(forwards, axis=0))
    if direction is None or not np.linalg.norm(direction) > 0:
        direction = np.array([1.0, 0.0])
    # plot_points_3d puts the viewer at (cos e sin a, -sin e, -cos e cos a) for up="-y": a path
    # heading at angle phi in the (x, z) plane runs to the right of the picture for azim = phi,
    # and a smaller azim moves the viewer towards the rear.
    phi = np.degrees(np.arctan2(direction[1], direction[0]))
    azim = (phi - turn + 180.0) % 360.0 - 180.0
    return float(elev), float(azim)


def _check_skeleton(skeleton, n_points: int, name: str) -> np.ndarray:
    edges = np.asarray(skeleton)
    if edges.size == 0:
        return np.zeros((0, 2), dtype=int)
    if edges.ndim != 2 or edges.shape[1] != 2 or edges.dtype.kind not in "iu":
        raise ValueError(f"skeleton: expected integer index pairs of shape (E, 2), got an array "
                         f"of shape {edges.shape} and dtype {edges.dtype}")
    if edges.min() < 0 or edges.max() >= n_points:
        raise ValueError(f"{name}: expected at least {edges.max() + 1} keypoint rows for the "
                         f"skeleton, got {n_points}")
    return edges.astype(int)


def visualize_keypoints(image, pts, Thres, ax=None, *, skeleton=CAR_SKELETON,
                        color: str = "#ff3030", point_size: float = 30.0, line_width: float = 2.0,
                        annotate: bool = False):
    """Draw an image with its confident keypoints and the skeleton edges between them.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, 3)
        uint8, or float in [0, 1].
    pts : array_like, shape (N, 3)
        One keypoint per row: (x, y, confidence), x the column and y the row, in pixels.
        N = 12 for the car (the rows of ``pts1``/``pts2``/``pts3``).
    Thres : float
        Confidence threshold: a keypoint is drawn when its confidence is strictly greater
        than ``Thres`` (as in "the points above the threshold"; the official confidences are
        multiples of 100, so ``Thres=300`` drops those at exactly 300).
    ax : matplotlib.axes.Axes, optional
        Where to draw; a new pyplot figure is made when omitted, so a notebook shows it.
    skeleton : sequence of (i, j)
        Edges drawn when both ends are kept.  Defaults to ``CAR_SKELETON``.
    color, point_size, line_width :
        Appearance of points and edges.
    annotate : bool
        Write each kept keypoint's index next to it.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn on.

    Raises
    ------
    ValueError
        When ``image``, ``pts``, ``Thres`` or ``skeleton`` is malformed (the message names it).
    """
    img = as_image(image, "image")
    P = as_points(pts, "pts", dims=3)
    thres = as_finite_scalar(Thres, "Thres")
    edges = _check_skeleton(skeleton, len(P), "pts")
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(8, 8 * img.shape[0] / img.shape[1]))
    keep = P[:, 2] > thres
    ax.imshow(img if img.ndim == 3 and img.shape[2] == 3 else img.reshape(img.shape[:2]),
              cmap="gray", vmin=0, vmax=1)
    for i, j in edges:
        if keep[i] and keep[j]:
            ax.plot(P[[i, j], 0], P[[i, j], 1], "-", color=color, linewidth=line_width)
    ax.scatter(P[keep, 0], P[keep, 1], s=point_size, color=color, edgecolors="white",
               linewidths=0.8, zorder=3)
    if annotate:
        for k in np.flatnonzero(keep):
            ax.annotate(str(k), (P[k, 0], P[k, 1]), xytext=(4, 4), textcoords="offset points",
                        color=color, fontsize=8)
    ax.set_xlim(-0.5, img.shape[1] - 0.5)
    ax.set_ylim(img.shape[0] - 0.5, -0.5)
    ax.set_title(f"{int(keep.sum())} of {len(P)} keypoints with confidence > {thres:g}")
    ax.set_axis_off()
    return ax


def plot_3d_keypoint(P, *, title: str = "car keypoints", label: str = "",
                     color: str = DEFAULT_COLORS[0], skeleton=CAR_SKELETON,
                     **kwargs) -> Figure3D:
    """The reconstructed car of one time step, keypoints joined by the skeleton, in 3D.

    Parameters
    ----------
    P : array_like, shape (N, 3)
        World points, row k being keypoint k (N = 12 for the car).  Rows holding NaN are
        keypoints that were not reconstructed; they and their edges are left out.
    title, label, color :
        Figure title, legend name, colour.
    skeleton : sequence of (i, j)
        Edges to draw.  Defaults to ``CAR_SKELETON``.
    **kwargs :
        Passed to :func:`starter.figures.plot_points_3d` (``view``, ``up``, ``marker_size``...).

    Returns
    -------
    Figure3D
        Rotatable on screen, with a PNG for the PDF.
    """
    pts = points_with_gaps(P, "P")
    if not np.isfinite(pts).all(axis=1).any():
        raise ValueError("P: expected at least one keypoint without NaN, got none")
    edges = _check_skeleton(skeleton, len(pts), "P")
    names = _names(len(pts))
    kwargs.setdefault("axis_titles", WORLD_AXIS_TITLES)
    if kwargs.get("up", "-y") == "-y":
        kwargs.setdefault("view", car_view([pts], elev=30.0, turn=-40.0))
    return plot_points_3d(pts, labels=label, title=title, edges=edges, colors=[color],
                          hover_text=names, **kwargs)


def plot_3d_keypoint_frames(frames, *, frame_labels=None, title: str = "car over time",
                            cmap: str = "viridis", skeleton=CAR_SKELETON,
                            **kwargs) -> Figure3D:
    """All time steps of the car in one 3D figure, one colour per frame.

    Parameters
    ----------
    frames : array_like, shape (T, N, 3), or a sequence of T arrays of shape (N, 3)
        ``frames[t]`` is the car at time t (N = 12).  Rows of NaN are keypoints that were not
        reconstructed at that time; a frame may be entirely NaN.
    frame_labels : sequence of T str, optional
        Legend names; ``"t=0"``, ``"t=1"``... by default.
    title : str
    cmap : str
        Matplotlib colormap sampled from the first frame to the last, so time reads as colour.
    skeleton : sequence of (i, j)
        Edges to draw in every frame.  Defaults to ``CAR_SKELETON``.
    **kwargs :
        Passed to :func:`starter.figures.plot_points_3d`.

    Returns
    -------
    Figure3D
    """
    if isinstance(frames, (list, tuple)):
        sets = [points_with_gaps(f, f"frames[{t}]") for t, f in enumerate(frames)]
    else:
        arr = np.asarray(frames)
        if arr.ndim != 3 or arr.shape[2] != 3:
            raise ValueError(f"frames: expected shape (T, N, 3), got an array of shape "
                             f"{arr.shape} and dtype {arr.dtype}")
        sets = [points_with_gaps(f, f"frames[{t}]") for t, f in enumerate(arr)]
    if not sets:
        raise ValueError("frames: expected at least one frame, got 0")
    sizes = {len(s) for s in sets}
    if len(sizes) != 1:
        raise ValueError(f"frames: expected the same number of keypoints in every frame, "
                         f"got {sorted(sizes)}")
    if not any(np.isfinite(s).all(axis=1).any() for s in sets):
        raise ValueError("frames: expected at least one keypoint without NaN, got none")
    edges = _check_skeleton(skeleton, len(sets[0]), "frames")
    T = len(sets)
    if frame_labels is None:
        frame_labels = [f"t={t}" for t in range(T)]
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    try:
        colormap = colormaps[cmap]
    except KeyError:
        raise ValueError(f"cmap: expected a matplotlib colormap name, got {cmap!r}") from None
    colors = [to_hex(colormap(t / max(T - 1, 1))) for t in range(T)]
    kwargs.setdefault("axis_titles", WORLD_AXIS_TITLES)
    if kwargs.get("up", "-y") == "-y":
        kwargs.setdefault("view", car_view(sets))
    return plot_points_3d(sets, labels=frame_labels, title=title, edges=edges, colors=colors,
                          hover_text=_names(len(sets[0])), **kwargs)


def _names(n: int) -> list[str]:
    if n == len(CAR_KEYPOINTS):
        return list(CAR_KEYPOINTS)
    return [f"keypoint {k}" for k in range(n)]
