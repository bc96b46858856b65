"""A small painter's-algorithm renderer for flat-shaded polygons (Pillow ImageDraw).

The synthetic scenes are made of a few hundred planar convex polygons: the ground, road
markings, box buildings, and a car built from convex solids.  Drawing them far to near with
``PIL.ImageDraw.polygon`` is enough when the caller groups them so that depth sorting is
unambiguous; this module does the sorting inside a layer, back-face culling, clipping against
the near plane, projection and Lambert shading.  It knows nothing about cars or streets.

Conventions: world points are (3,) in the scene's world frame; M = [R | t] (3x4) maps them to
camera coordinates (the camera looks along +z, x right, y down) and K (3x3) to pixels
(x, y) = (column, row).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Sequence

import numpy as np
from PIL import Image, ImageDraw

from core.geometry import IDENTITY_POSE, camera_center, project
from core.validate import as_matrix

__all__ = ["Face", "Quads", "Layer", "face_normal", "orient_outward", "render"]

RGB = tuple[int, int, int]


def face_normal(vertices: np.ndarray) -> np.ndarray:
    """Unit normal (3,) of a planar polygon ``vertices`` (k, 3), by Newell's method.

    The normal follows the right-hand rule along the vertex order; Newell's sum is used
    because it stays well defined for any vertex order of a planar polygon, even with
    nearly collinear consecutive vertices.
    """
    v = np.asarray(vertices, float)
    w = np.roll(v, -1, axis=0)
    n = np.array([
        np.sum((v[:, 1] - w[:, 1]) * (v[:, 2] + w[:, 2])),
        np.sum((v[:, 2] - w[:, 2]) * (v[:, 0] + w[:, 0])),
        np.sum((v[:, 0] - w[:, 0]) * (v[:, 1] + w[:, 1])),
    ])
    norm = np.linalg.norm(n)
    if norm == 0:
        raise ValueError(f"vertices: expected a polygon with non-zero area, got {v.tolist()}")
    return n / norm


def orient_outward(vertices: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Return ``vertices`` (k, 3), reversed if needed so that the normal points away from ``inside`` (3,)."""
    v = np.asarray(vertices, float)
    if face_normal(v) @ (v.mean(axis=0) - np.asarray(inside, float)) < 0:
        v = v[::-1].copy()
    return v


@dataclass(frozen=True, eq=False)
class Quads:
    """Many small quadrilaterals of one colour lying on one face (the windows of a wall).

    Only usable as a decal of a ``Face``: they share its normal and visibility, and a quad
    that reaches behind the near plane is dropped rather than clipped (they are small).

    Parameters
    ----------
    vertices : ndarray, shape (n, 4, 3)
        World coordinates of each quad's corners, in drawing order.
    color : tuple of 3 int
    shade : bool
    """

    vertices: np.ndarray
    color: RGB
    shade: bool = True

    def __post_init__(self):
        v = np.asarray(self.vertices, float)
        if v.ndim != 3 or v.shape[1:] != (4, 3):
            raise ValueError(f"vertices: expected shape (n, 4, 3), got {v.shape}")
        object.__setattr__(self, "vertices", v)


@dataclass(frozen=True, eq=False)
class Face:
    """One planar convex polygon to draw.

    Parameters
    ----------
    vertices : ndarray, shape (k, 3)
        World coordinates, k >= 3, ordered so that the right-hand-rule normal points to the
        side it is seen from (see ``orient_outward``).
    color : tuple of 3 int
        Base RGB colour, 0..255, before shading.
    cull : bool
        Skip the face when the camera is behind it (back-face culling).
    shade : bool
        Scale the colour by the Lambert term of the sun; flat paint (road markings) is not.
    decals : tuple of Face or Quads
        Polygons lying on this face (windows, lights), drawn right after it and only when it
        is drawn, so they can never be hidden by their own face.
    """

    vertices: np.ndarray
    color: RGB
    cull: bool = True
    shade: bool = True
    decals: tuple["Face | Quads", ...] = ()
    normal: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        v = np.asarray(self.vertices, float)
        if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 3:
            raise ValueError(f"vertices: expected shape (k, 3) with k >= 3, got {v.shape}")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "normal", face_normal(v))


@dataclass(frozen=True, eq=False)
class Layer:
    """A group of solids drawn after every earlier layer.

    Each solid is a sequence of faces drawn in the given order (for a convex solid with
    back-face culling the order does not matter: its visible faces never overlap).  When
    ``sort`` is true the solids are drawn farthest first by the mean depth of their
    vertices, which is correct for solids that are well separated (buildings); otherwise in
    the given order (coplanar ground paint, or a car whose parts the caller orders itself).
    """

    solids: Sequence[Sequence[Face]]
    sort: bool = False


def _clip_near(cam: np.ndarray, near: float) -> np.ndarray:
    """Clip a convex polygon in camera coordinates (k, 3) to z >= near (Sutherland-Hodgman, one plane)."""
    out = []
    k = len(cam)
    for i in range(k):
        a, b = cam[i], cam[(i + 1) % k]
        a_in, b_in = a[2] >= near, b[2] >= near
        if a_in:
            out.append(a)
        if a_in != b_in:
            s = (near - a[2]) / (b[2] - a[2])
            out.append(a + s * (b - a))
    return np.array(out).reshape(-1, 3)


def _shaded(color: RGB, normal: np.ndarray, sun: np.ndarray, ambient: float) -> RGB:
    lambert = max(0.0, float(normal @ sun))
    gain = ambient + (1.0 - ambient) * lambert
    return tuple(int(min(255, round(c * gain))) for c in color)


@lru_cache(maxsize=4)
def _sky_bytes(width: int, height: int, top: RGB, horizon: RGB) -> bytes:
    s = np.linspace(0.0, 1.0, height)[:, None, None]
    column = ((1 - s) * np.array(top, float) + s * np.array(horizon, float)).round().astype(np.uint8)
    return np.repeat(column, width, axis=1).tobytes()


def _sky(width: int, height: int, top: RGB, horizon: RGB) -> Image.Image:
    # every view of a scene shares the gradient; frombytes copies, so the cache stays intact
    return Image.frombytes("RGB", (width, height), _sky_bytes(width, height, tuple(top), tuple(horizon)))


def render(layers: Sequence[Layer], K, M, width: int, height: int, *,
           sky_top: RGB = (110, 160, 215), sky_horizon: RGB = (200, 222, 240),
           sun=(0.35, -0.85, -0.4), ambient: float = 0.55, near: float = 0.3,
           supersample: int = 1) -> np.ndarray:
    """Draw ``layers`` as seen by the camera C = K M; return an RGB image.

    Parameters
    ----------
    layers : sequence of Layer
        Drawn in order, each over the previous ones.
    K : array_like, shape (3, 3)
        Intrinsics in pixels of the output image.
    M : array_like, shape (3, 4)
        Extrinsics [R | t], world to camera.
    width, height : int
        Output size in pixels.
    sky_top, sky_horizon : tuple of 3 int
        The background is a vertical gradient between these colours (what no face covers).
    sun : array_like, shape (3,)
        Direction towards the sun in world coordinates (normalised here).
    ambient : float
        Brightness, in [0, 1], of a face that the sun does not reach.
    near : float
        Polygons are clipped to camera depth >= near, so faces behind the camera vanish and
        faces crossing the image plane do not wrap around.
    supersample : int
        Draw at this many times the size and box-filter down, which smooths the edges.

    Returns
    -------
    ndarray, shape (height, width, 3), uint8
    """
    K = as_matrix(K, "K", (3, 3))
    M = as_matrix(M, "M", (3, 4))
    s = int(supersample)
    if s < 1:
        raise ValueError(f"supersample: expected an integer >= 1, got {supersample!r}")
    sun = np.asarray(sun, float)
    sun = sun / np.linalg.norm(sun)
    R, t = M[:, :3], M[:, 3]
    centre = camera_center(M)
    # Scaling K by s draws pixel (x, y) of the output at ((x + 0.5) s - 0.5, ...) of the large
    # image, which is what a box filter of size s maps back to (x, y).
    S = np.diag([s, s, 1.0])
    S[:2, 2] = (s - 1) / 2.0
    Ks = S @ K
    Cs = Ks @ IDENTITY_POSE  # camera coordinates (after clipping) -> pixels of the large image

    img = _sky(width * s, height * s, sky_top, sky_horizon)
    draw = ImageDraw.Draw(img)

    def paint(face: Face) -> bool:
        if face.cull and face.normal @ (centre - face.vertices.mean(axis=0)) <= 0:
            return False
        cam = face.vertices @ R.T + t
        cam = _clip_near(cam, near)
        if len(cam) < 3:
            return False
        uv = project(Cs, cam)
        color = _shaded(face.color, face.normal, sun, ambient) if face.shade else tuple(face.color)
        draw.polygon([tuple(p) for p in uv.tolist()], fill=color)
        for decal in face.decals:
            if isinstance(decal, Quads):
                paint_quads(decal, face.normal)
            else:
                paint(decal)
        return True

    def paint_quads(quads: Quads, normal: np.ndarray) -> None:
        cam = quads.vertices @ R.T + t
        keep = np.all(cam[..., 2] >= near, axis=1)
        uv = project(Cs, cam[keep]).reshape(-1, 4, 2)
        color = _shaded(quads.color, normal, sun, ambient) if quads.shade else tuple(quads.color)
        for quad in uv.tolist():
            draw.polygon([tuple(p) for p in quad], fill=color)

    for layer in layers:
        solids = list(layer.solids)
        if layer.sort:
            def depth(solid):
                pts = np.concatenate([f.vertices for f in solid])
                return float(np.mean(pts @ R[2] + t[2]))
            solids.sort(key=depth, reverse=True)
        for solid in solids:
            for face in solid:
                paint(face)

    if s > 1:
        img = img.reduce(s)
    return np.asarray(img)
