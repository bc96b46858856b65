"""Q4.2's figure: the student's temple against the true one.

Student side (:func:`run`): ``compute3D_pts(im1, im2, F, x1, y1, C1, C2)`` (or 2022-2024's
``compute3D_pts(temple_pts1, intrinsics, F, im1, im2)``, called as judging.conventions says) on
all templeCoords of the default data, with its true F and cameras (3, 4); returns w (P, 3).
When compute3D_pts is missing or fails and the student's epipolarCorrespondence and triangulate
are given, the points come from them (the route the hidden check takes too: a 2018-2021 Q4.2
was a script); the picture says which route it drew, and names the function of another question
behind it (findM2, Q3.3, inside 2022-2024's compute3D_pts; the matcher, Q4.1, and triangulate,
Q3.2, on the second route).

Trusted side (:func:`draw`): the student's points moved by the similarity that best fits them to
the true points (a reconstruction is defined up to one; core.geometry.similarity_fit, on the
finite points), drawn seen from above (x, z) and from the side (z, y) over the true points.  A
temple from swapped x and y, or from wrong matches, does not lie on the true one.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from .arrays import PictureRunError, call, maybe, need, read
from .picture import Picture, figure, measure_text, to_picture
from .public import need_truth, temple

__all__ = ["FUNCTIONS", "NEAR_SHARE", "draw", "run"]

FUNCTIONS = ("compute3D_pts", "epipolarCorrespondence", "triangulate")
# How the points were got ("route" of the outputs), and the other questions' functions behind each.
ROUTES = ("your compute3D_pts(im1, im2, F, x1, y1, C1, C2), given the true F and cameras",
          "your compute3D_pts(temple_pts1, intrinsics, F, im1, im2), which finds its cameras with your findM2 (Q3.3)",
          "your epipolarCorrespondence (Q4.1) and triangulate (Q3.2), given the true F and cameras "
          "(compute3D_pts gave no points)")
UPSTREAM = ("", "findM2 (Q3.3): when Q3.3's picture frames a wrong candidate, that is the cause",
            "epipolarCorrespondence (Q4.1) or triangulate (Q3.2): their pictures show which")
NEAR_SHARE = 0.05   # a point is near the truth within this share of the temple's size


def _inputs(s):
    from starter.data import course_image

    xy = np.column_stack([np.ravel(s.x1), np.ravel(s.y1)]).astype(np.uint16)
    return course_image(s.im1), course_image(s.im2), xy


def _direct(fn, s, im1, im2, xy) -> tuple[np.ndarray, int]:
    """(w (P, 3), route 0 or 1) from the student's compute3D_pts; PictureRunError when it fails."""
    from judging.conventions import compute3D_pts_five_calls, five_arguments, signature_of_callable
    from judging.correspondence import read_points

    n = len(xy)
    signature = signature_of_callable(fn)
    if five_arguments(signature):
        K1 = np.asarray(s.K1, float)
        K2 = np.asarray(s.K2, float)
        error = None
        for c in compute3D_pts_five_calls(signature, xy.astype(float), K1, K2, s.F_true, im1.copy(), im2.copy()):
            try:
                return np.asarray(read(read_points, call(fn, "compute3D_pts", *c.args), n, name="compute3D_pts")), 1
            except PictureRunError as exc:  # the next call convention is tried
                error = error or exc
        raise error
    value = call(fn, "compute3D_pts", im1, im2, np.array(s.F_true, float), xy[:, :1].copy(), xy[:, 1:].copy(),
                 np.array(s.C1, float), np.array(s.C2, float))
    return np.asarray(read(read_points, value, n, name="compute3D_pts"), float), 0


def _pipeline(functions, s, im1, im2, xy) -> np.ndarray:
    """w (P, 3) from the student's matcher and triangulate with the true F and cameras."""
    from judging.correspondence import read_match

    match, triangulate = functions["epipolarCorrespondence"], functions["triangulate"]
    F = np.array(s.F_true, float)
    pixels = [(int(x), int(y)) for x, y in xy]
    if callable(getattr(match, "map", None)):  # the grader's sandboxed function: one request, the images sent once
        values = match.map(pixels, args=(im1, im2, F))
    else:
        values = [call(match, "epipolarCorrespondence", im1.copy(), im2.copy(), F, x, y) for x, y in pixels]
    pts2 = np.array([read(read_match, v, name="epipolarCorrespondence (Q4.1)") for v in values], float).reshape(-1, 2)
    value = call(triangulate, "triangulate (Q3.2)", np.array(s.C1, float), xy.astype(float), np.array(s.C2, float), pts2)
    if isinstance(value, (tuple, list)) and value:
        value = value[0]
    try:
        return np.asarray(value, dtype=float).reshape(len(xy), 3)
    except (TypeError, ValueError):
        raise PictureRunError(f"triangulate (Q3.2) did not return ({len(xy)}, 3) points first") from None


def run(functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """{"w": (P, 3) the student's points of every templeCoords point, "route": (1,) the index in
    ROUTES of how they were got}."""
    s = need_truth(temple(root), "Q4.2")
    im1, im2, xy = _inputs(s)
    try:
        w, route = _direct(functions["compute3D_pts"], s, im1, im2, xy)
    except PictureRunError as direct:
        if not all(callable(functions.get(f)) for f in FUNCTIONS[1:]):
            raise
        try:
            w, route = _pipeline(functions, s, im1, im2, xy), 2
        except PictureRunError as pipe:
            raise PictureRunError(f"{direct}; through your epipolarCorrespondence (Q4.1) and triangulate (Q3.2): "
                                  f"{pipe}") from None
    return {"w": np.asarray(w, float), "route": np.array([float(route)])}


def draw(outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of Q4.2.

    measures: temple_size (the true points' RMS distance to their centroid, scene units),
    median_error (distance of the moved points to the true ones, scene units), share_near (within
    NEAR_SHARE of the temple's size), scale (of the similarity), n_finite (points that are numbers),
    route (index in ROUTES of how the points were got; 0 when the outputs do not say).
    """
    from core.geometry import similarity_fit

    s = need_truth(temple(root), "Q4.2")
    X = np.asarray(s.X_coords, float)
    w = need(outputs, "w", (len(X), 3))
    finite = np.all(np.isfinite(w), axis=1)
    fit = similarity_fit(w[finite], X[finite]) if finite.sum() >= 3 else None
    moved = np.full_like(X, np.nan)
    if fit is not None:
        sc, R, t = fit
        moved[finite] = sc * w[finite] @ R.T + t
    size = float(np.sqrt(np.mean(np.sum((X - X.mean(axis=0)) ** 2, axis=1))))
    with np.errstate(invalid="ignore"):
        err = np.linalg.norm(moved - X, axis=1)
    near = err <= NEAR_SHARE * size
    fig, axes = figure(2, 1, size=(5.2, 4.4))
    for ax, (i, j, name) in zip(axes, ((0, 2, "seen from above (x, z)"), (2, 1, "seen from the side (z, y)"))):
        ax.plot(X[:, i], X[:, j], ".", ms=4, color="#4fc3f7", gid="truth", label="true temple")
        ax.plot(moved[near, i], moved[near, j], ".", ms=3, color="#2e7d32", gid="yours_near", label="yours, near")
        ax.plot(moved[~near, i], moved[~near, j], ".", ms=3, color="#e53935", gid="yours_far", label="yours, far")
        span = np.ptp(X[:, [i, j]], axis=0).max()
        c = X[:, [i, j]].mean(axis=0)
        ax.set_xlim(c[0] - span, c[0] + span)
        ax.set_ylim(c[1] - span, c[1] + span)
        if j == 1:
            ax.invert_yaxis()
        ax.set_aspect("equal")
        ax.set_title(name, fontsize=9)
    axes[0].legend(fontsize=7, loc="upper right")
    m = {"temple_size": size, "median_error": float(np.median(err)) if finite.all() else float("inf"),
         "share_near": float(near.mean()), "scale": float(fit[0]) if fit is not None else float("nan"),
         "n_finite": float(finite.sum())}
    route = maybe(outputs, "route", (1,))
    route = int(route[0]) if route is not None and 0 <= route[0] < len(ROUTES) else 0
    m["route"] = float(route)
    upstream = (f" Most of your points are far from the temple: the function of another question behind them "
                f"is {UPSTREAM[route]}." if UPSTREAM[route] and near.mean() < 0.5 else "")
    alt = (f"Points from {ROUTES[route]}. "
           f"Your {len(X)} temple points, moved by the similarity that fits them best (scale {measure_text(m['scale'])}), over "
           f"the true temple, seen from above and from the side: {int(near.sum())} of {len(X)} ({near.mean():.0%}) "
           f"within {NEAR_SHARE:.0%} of the temple's size of the true point; median distance "
           f"{measure_text(m['median_error'])} for a temple of size {measure_text(size)}"
           + ("" if finite.all() else f"; {int((~finite).sum())} points are not numbers") + "." + upstream)
    return to_picture("Q4.2", "compute3D_pts: your temple and the true one", fig, alt, m)
