"""A small vectorised ray caster for the synthetic scenes.

The scene is a union of convex solids: convex polyhedra (boxes, wedges) and finite capped
cylinders.  Every solid is intersected with a whole batch of rays at once in numpy.

Conventions (the same as :mod:`scenes.cameras` and the homework):

- World points are rows of an (N, 3) array; a camera M = [R | t] (3x4) maps them to camera
  coordinates ``R @ X + t``; C = K @ M.
- A pixel is (x, y) = (column, row) and integer coordinates are pixel *centres*: the world
  point that ``cameras.project`` sends to (10.0, 20.0) is seen at the centre of column 10,
  row 20 of the rendered image.
- Rays are ``origin + s * direction``.  Rays cast from a camera have directions scaled so
  that their third camera coordinate is 1, which makes the ray parameter equal to the depth.

Rendering is two passes: one ray per pixel centre, then s x s rays for the pixels where the
visible surface changes (silhouettes, occlusions, creases), whose colours are averaged.
That anti-aliases edges like full supersampling at a fraction of the cost; inside a face the
textures used here have little detail finer than a pixel, so one sample is enough there.

Shading (:func:`shade`) is Lambertian with ambient light, times an albedo that the caller
computes from the 3D hit points, for instance with a :class:`SolidTexture`, which is what
makes the texture stick to the surface in every view.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.fft
from scipy import ndimage

from core.geometry import camera_center, depths, project
from core.validate import as_matrix, as_points, as_positive_scalar

__all__ = [
    "ConvexPolyhedron",
    "Cylinder",
    "GBuffer",
    "Hits",
    "SolidTexture",
    "box",
    "cast_rays",
    "pixel_rays",
    "render_gbuffer",
    "shade",
    "visible_from",
    "wedge",
]

# Intersections closer than this (in ray-parameter units) are ignored, so that a ray
# starting on a surface does not hit that surface again.
_T_MIN = 1e-9


def _as_rays(origins, directions):
    d = np.asarray(directions, float).reshape(-1, 3)
    o = np.asarray(origins, float)
    o = np.broadcast_to(o.reshape(3) if o.size == 3 else o.reshape(-1, 3), d.shape)
    return o, d


def _rowdot(a, b):
    return np.einsum("ij,ij->i", a, b)


@dataclass(frozen=True, eq=False)
class ConvexPolyhedron:
    """The convex solid {X : normals @ X <= offsets}.

    Parameters
    ----------
    normals : ndarray, shape (P, 3)
        Outward unit normals of the P bounding planes.
    offsets : ndarray, shape (P,)
        A point X is inside when ``normals @ X <= offsets`` for every plane.
    vertices : ndarray, shape (V, 3)
        The corners of the solid, only used to bound its image for culling.
    """

    normals: np.ndarray
    offsets: np.ndarray
    vertices: np.ndarray

    def transformed(self, R, t) -> ConvexPolyhedron:
        """The solid moved by X -> R @ X + t (R (3, 3) rotation, t (3,))."""
        R = np.asarray(R, float)
        t = np.asarray(t, float).reshape(3)
        n = self.normals @ R.T
        return ConvexPolyhedron(n, self.offsets + n @ t, self.vertices @ R.T + t)

    def intersect(self, origins, directions):
        """Where N rays enter the solid.

        The slab method generalised to any set of planes: a ray is inside the solid for the
        parameters inside every half-space, an interval that starts at the last plane it
        enters and ends at the first plane it leaves.

        Parameters
        ----------
        origins : array_like, shape (3,) or (N, 3)
        directions : array_like, shape (N, 3)

        Returns
        -------
        t : ndarray, shape (N,)
            Entry parameter, ``inf`` for a miss.
        normal : ndarray, shape (N, 3)
            Outward normal of the entry face.
        face : ndarray, shape (N,), int
            Index of the entry plane.
        """
        o, d = _as_rays(origins, directions)
        denom = d @ self.normals.T  # (N, P); < 0 where the ray enters through that plane
        num = self.offsets - o @ self.normals.T
        with np.errstate(divide="ignore", invalid="ignore"):
            s = num / denom
        s_in = np.where(denom < 0, s, -np.inf)
        s_out = np.where(denom > 0, s, np.inf)
        face = np.argmax(s_in, axis=1)
        t_near = np.take_along_axis(s_in, face[:, None], axis=1)[:, 0]
        t_far = s_out.min(axis=1)
        # A ray parallel to a plane and outside it never enters the solid.
        outside_parallel = np.any((denom == 0) & (num < 0), axis=1)
        hit = (t_near <= t_far) & (t_near > _T_MIN) & ~outside_parallel
        return np.where(hit, t_near, np.inf), self.normals[face], face


@dataclass(frozen=True, eq=False)
class Cylinder:
    """A finite solid cylinder with flat caps.

    Parameters
    ----------
    center : array_like, shape (3,)
        Midpoint of the axis.
    axis : array_like, shape (3,)
        Direction of the axis (normalised on construction).
    radius : float
    half_length : float
        The caps are at ``center +- half_length * axis``.
    """

    center: np.ndarray
    axis: np.ndarray
    radius: float
    half_length: float
    vertices: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        c = np.asarray(self.center, float).reshape(3)
        u = np.asarray(self.axis, float).reshape(3)
        u = u / np.linalg.norm(u)
        if not (self.radius > 0 and self.half_length > 0):
            raise ValueError(f"Cylinder: expected positive radius and half_length, got "
                             f"{self.radius} and {self.half_length}")
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "axis", u)
        # Two unit vectors across the axis give the corners of a bounding box for culling.
        e1 = np.cross(u, [1.0, 0, 0] if abs(u[0]) < 0.9 else [0, 1.0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        signs = np.array([[a, b, c_] for a in (-1, 1) for b in (-1, 1) for c_ in (-1, 1)], float)
        v = (c + signs[:, :1] * self.half_length * u
             + self.radius * (signs[:, 1:2] * e1 + signs[:, 2:] * e2))
        object.__setattr__(self, "vertices", v)

    def transformed(self, R, t) -> Cylinder:
        """The solid moved by X -> R @ X + t (R (3, 3) rotation, t (3,))."""
        R = np.asarray(R, float)
        return Cylinder(R @ self.center + np.asarray(t, float).reshape(3), R @ self.axis,
                        self.radius, self.half_length)

    def intersect(self, origins, directions):
        """Where N rays enter the solid: (t (N,), normal (N, 3), face (N,)).

        The ray is inside the solid where it is both inside the infinite cylinder (the root
        interval of a quadratic) and between the two cap planes (a slab).  ``t`` is ``inf``
        for a miss; ``face`` is 0 for the side, 1 for a cap.
        """
        o, d = _as_rays(origins, directions)
        u = self.axis
        w = o - self.center
        du = d @ u
        wu = w @ u
        d_perp = d - du[:, None] * u
        w_perp = w - wu[:, None] * u
        a = _rowdot(d_perp, d_perp)
        b = 2 * _rowdot(d_perp, w_perp)
        c = _rowdot(w_perp, w_perp) - self.radius**2
        disc = b * b - 4 * a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            root = np.sqrt(np.maximum(disc, 0))
            side_in = (-b - root) / (2 * a)
            side_out = (-b + root) / (2 * a)
            s1 = (-self.half_length - wu) / du
            s2 = (self.half_length - wu) / du
        # A ray along the axis (a == 0) is inside the infinite cylinder everywhere or nowhere.
        along = a <= 1e-300
        inside = c <= 0
        side_in = np.where(along, np.where(inside, -np.inf, np.inf), side_in)
        side_out = np.where(along, np.where(inside, np.inf, -np.inf), side_out)
        side_in = np.where(~along & (disc < 0), np.inf, side_in)
        # A ray parallel to the caps is between them everywhere or nowhere.
        flat = du == 0
        between = np.abs(wu) <= self.half_length
        cap_in = np.where(flat, np.where(between, -np.inf, np.inf), np.minimum(s1, s2))
        cap_out = np.where(flat, np.where(between, np.inf, -np.inf), np.maximum(s1, s2))
        t_near = np.maximum(side_in, cap_in)
        t_far = np.minimum(side_out, cap_out)
        hit = (t_near <= t_far) & (t_near > _T_MIN) & np.isfinite(t_near)
        t = np.where(hit, t_near, np.inf)
        on_cap = cap_in >= side_in
        p_perp = w_perp + np.where(hit, t, 0.0)[:, None] * d_perp
        with np.errstate(divide="ignore", invalid="ignore"):
            n_side = p_perp / np.linalg.norm(p_perp, axis=1, keepdims=True)
        n_cap = -np.sign(du)[:, None] * u
        normal = np.nan_to_num(np.where(on_cap[:, None], n_cap, n_side))
        return t, normal, on_cap.astype(np.intp)


Primitive = ConvexPolyhedron | Cylinder


def box(center, half_extents, R=None) -> ConvexPolyhedron:
    """An oriented box.

    Parameters
    ----------
    center : array_like, shape (3,)
    half_extents : array_like, shape (3,)
        Half sizes along the box's own axes.
    R : array_like, shape (3, 3), optional
        Columns are the box's axes in world coordinates (default: axis-aligned).
    """
    h = np.asarray(half_extents, float).reshape(3)
    if np.any(h <= 0):
        raise ValueError(f"half_extents: expected three positive numbers, got {h.tolist()}")
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
    local = ConvexPolyhedron(np.vstack([np.eye(3), -np.eye(3)]), np.concatenate([h, h]), corners * h)
    return local.transformed(np.eye(3) if R is None else R, center)


def wedge(center, half_width, half_depth, height, R=None) -> ConvexPolyhedron:
    """A triangular prism: a gable roof whose ridge runs along its local y axis.

    In local coordinates the base is the rectangle |x| <= half_width, |y| <= half_depth at
    z = 0 and the ridge is the segment x = 0, z = height.  ``center`` (3,) is the middle of
    the base and ``R`` (3, 3; columns = local axes in world coordinates) orients it.
    """
    if min(half_width, half_depth, height) <= 0:
        raise ValueError("wedge: expected positive half_width, half_depth and height, got "
                         f"{half_width}, {half_depth}, {height}")
    slope = np.array([height, 0.0, half_width]) / np.hypot(height, half_width)
    normals = np.array([[0, 0, -1.0], [0, 1.0, 0], [0, -1.0, 0], slope, slope * [-1, 1, 1]])
    offsets = np.array([0.0, half_depth, half_depth, slope[0] * half_width, slope[0] * half_width])
    v = np.array([[x, y, 0.0] for x in (-half_width, half_width) for y in (-half_depth, half_depth)]
                 + [[0.0, y, height] for y in (-half_depth, half_depth)])
    return ConvexPolyhedron(normals, offsets, v).transformed(np.eye(3) if R is None else R, center)


class Hits(NamedTuple):
    """First intersections of N rays with a scene.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Ray parameter of the first hit (``inf`` where the ray misses everything).
    normal : ndarray, shape (N, 3)
        Outward unit normal of the surface at the hit (zeros where the ray misses).
    prim : ndarray, shape (N,), int
        Index of the primitive hit, -1 where the ray misses.
    face : ndarray, shape (N,), int
        Face of that primitive (plane index of a polyhedron; 0 side, 1 cap of a cylinder).
    """

    t: np.ndarray
    normal: np.ndarray
    prim: np.ndarray
    face: np.ndarray


def _first_hits(prims, origins, directions, candidates=None) -> Hits:
    """First hits of rays; ``candidates(k)`` optionally gives the ray indices worth testing
    against primitive k (the others are known to miss it)."""
    o, d = _as_rays(origins, directions)
    n = len(d)
    best = np.full(n, np.inf)
    normal = np.zeros((n, 3))
    prim = np.full(n, -1, dtype=np.intp)
    face = np.zeros(n, dtype=np.intp)
    for k, p in enumerate(prims):
        idx = np.arange(n) if candidates is None else candidates(k)
        if len(idx) == 0:
            continue
        t, nk, fk = p.intersect(o[idx], d[idx])
        closer = t < best[idx]
        sel = idx[closer]
        best[sel] = t[closer]
        normal[sel] = nk[closer]
        prim[sel] = k
        face[sel] = fk[closer]
    return Hits(best, normal, prim, face)


def cast_rays(prims: Sequence[Primitive], origins, directions) -> Hits:
    """First hit of each ray against a list of primitives.

    Parameters
    ----------
    prims : sequence of ConvexPolyhedron or Cylinder
    origins : array_like, shape (3,) or (N, 3)
        One origin for all rays, or one per ray.
    directions : array_like, shape (N, 3)
        Need not be unit vectors; ``Hits.t`` is in units of each direction's length.
    """
    return _first_hits(prims, origins, directions)


def pixel_rays(K, M, xy) -> tuple[np.ndarray, np.ndarray]:
    """Rays through pixels.

    Parameters
    ----------
    K : array_like, shape (3, 3)
    M : array_like, shape (3, 4)
        [R | t], world to camera.
    xy : array_like, shape (N, 2)
        Pixel positions (x, y) = (column, row), sub-pixel allowed.

    Returns
    -------
    origin : ndarray, shape (3,)
        The camera centre in world coordinates.
    directions : ndarray, shape (N, 3)
        World directions scaled so that the ray parameter equals the depth.
    """
    K = as_matrix(K, "K", (3, 3))
    M = as_matrix(M, "M", (3, 4))
    return _pixel_rays(K, M, as_points(xy, "xy"))


def _pixel_rays(K, M, xy):
    A = M[:, :3].T @ np.linalg.inv(K)
    # Written out rather than as a matmul with a strided slice, which numpy runs slowly.
    return camera_center(M), xy[:, :1] * A[:, 0] + xy[:, 1:] * A[:, 1] + A[:, 2]


def _screen_rect(prim, K, M):
    """Image bounding rectangle (x0, x1, y0, y1) of a primitive, or None when it straddles
    the camera plane (then every pixel has to be tested)."""
    if np.any(depths(M, prim.vertices) <= 1e-9):
        return None
    xy = project(K @ M, prim.vertices)
    (x0, y0), (x1, y1) = xy.min(axis=0) - 1, xy.max(axis=0) + 1
    return x0, x1, y0, y1


def _trace_pixels(prims, K, M, xy, grid: tuple[int, int] | None = None) -> Hits:
    """First hits of the camera rays through sample positions xy (N, 2), each primitive
    tested only against the samples inside its image rectangle.  ``grid`` = (H, W) says that
    xy is the full grid of pixel centres in row-major order, whose rectangles are slices."""
    origin, d = _pixel_rays(K, M, xy)
    rects = [_screen_rect(p, K, M) for p in prims]

    def candidates(k):
        if rects[k] is None:
            return np.arange(len(xy))
        x0, x1, y0, y1 = rects[k]
        if grid is not None:
            H, W = grid
            cols = np.arange(max(int(np.ceil(x0)), 0), min(int(np.floor(x1)), W - 1) + 1)
            rows = np.arange(max(int(np.ceil(y0)), 0), min(int(np.floor(y1)), H - 1) + 1)
            return (rows[:, None] * W + cols[None, :]).ravel()
        return np.flatnonzero((xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1))

    return _first_hits(prims, origin, d, candidates)


class GBuffer(NamedTuple):
    """The geometry seen by a camera, ready to shade.

    Attributes
    ----------
    depth : ndarray, shape (H, W)
        Depth along the optical axis of the surface seen at each pixel centre (``inf`` on
        the background).
    prim : ndarray, shape (H, W), int
        Primitive seen at each pixel centre, -1 on the background.
    coverage : ndarray, shape (H, W)
        Fraction of each pixel's samples that hit a surface.
    pixel : ndarray, shape (S,), int
        For each sample, the flat index (row * W + column) of its pixel.
    weight : ndarray, shape (S,)
        Each sample's share of its pixel (the weights of a pixel sum to 1).
    points : ndarray, shape (S, 3)
        World point hit by each sample (NaN for background samples).
    normal : ndarray, shape (S, 3)
        Outward unit normal at each sample's hit (zeros on the background).
    sample_prim : ndarray, shape (S,), int
        Primitive hit by each sample, -1 on the background.
    """

    depth: np.ndarray
    prim: np.ndarray
    coverage: np.ndarray
    pixel: np.ndarray
    weight: np.ndarray
    points: np.ndarray
    normal: np.ndarray
    sample_prim: np.ndarray


def _changes(label: np.ndarray) -> np.ndarray:
    """Pixels (H, W) bool whose label differs from one of their 8 neighbours."""
    out = np.zeros(label.shape, bool)
    for a, b in [((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                 ((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
                 ((slice(1, None), slice(1, None)), (slice(None, -1), slice(None, -1))),
                 ((slice(1, None), slice(None, -1)), (slice(None, -1), slice(1, None)))]:
        diff = label[a] != label[b]
        out[a] |= diff
        out[b] |= diff
    return out


def render_gbuffer(prims: Sequence[Primitive], K, M, width: int, height: int,
                   supersample: int = 2) -> GBuffer:
    """Find the surfaces a camera sees, anti-aliased where the visible surface changes.

    Parameters
    ----------
    prims : sequence of ConvexPolyhedron or Cylinder
    K : array_like, shape (3, 3)
    M : array_like, shape (3, 4)
        [R | t], world to camera.
    width, height : int
        Image size in pixels.
    supersample : int
        Edge pixels get ``supersample`` x ``supersample`` samples, on a regular grid
        centred in the pixel; other pixels one sample at their centre.
    """
    K = as_matrix(K, "K", (3, 3))
    M = as_matrix(M, "M", (3, 4))
    s = int(supersample)
    if s < 1 or s != supersample:
        raise ValueError(f"supersample: expected a positive integer, got {supersample!r}")
    W, H = int(width), int(height)
    gx, gy = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    centres = np.stack([gx.ravel(), gy.ravel()], axis=1)
    first = _trace_pixels(prims, K, M, centres, grid=(H, W))
    label = np.where(first.prim >= 0, first.prim * 64 + first.face, -1).reshape(H, W)
    edge = np.flatnonzero(_changes(label)) if s > 1 else np.zeros(0, np.intp)

    offsets = (np.arange(s) + 0.5) / s - 0.5
    ox, oy = np.meshgrid(offsets, offsets)
    sub_xy = (centres[edge][:, None, :] + np.stack([ox.ravel(), oy.ravel()], axis=1)).reshape(-1, 2)
    sub = _trace_pixels(prims, K, M, sub_xy)

    keep = np.ones(H * W, bool)
    keep[edge] = False
    pixel = np.concatenate([np.flatnonzero(keep), np.repeat(edge, s * s)])
    weight = np.concatenate([np.ones(keep.sum()), np.full(len(sub_xy), 1.0 / (s * s))])
    xy = np.concatenate([centres[keep], sub_xy])
    t = np.concatenate([first.t[keep], sub.t])
    sample_prim = np.concatenate([first.prim[keep], sub.prim])
    normal = np.concatenate([first.normal[keep], sub.normal])
    origin, d = _pixel_rays(K, M, xy)
    with np.errstate(invalid="ignore"):
        points = origin + np.where(np.isfinite(t), t, np.nan)[:, None] * d
    coverage = np.bincount(pixel, weights=weight * (sample_prim >= 0), minlength=H * W)
    return GBuffer(first.t.reshape(H, W), first.prim.reshape(H, W), coverage.reshape(H, W),
                   pixel, weight, points, normal, sample_prim)


def visible_from(prims: Sequence[Primitive], M, X, *, rel_tol: float = 1e-6) -> np.ndarray:
    """Whether surface points are seen, unoccluded, by the camera M.

    A point counts as visible when it is in front of the camera and the first surface that
    the ray from the camera centre towards it meets is the point itself (to ``rel_tol`` of
    the distance).  Image bounds are not checked here.

    Parameters
    ----------
    prims : sequence of ConvexPolyhedron or Cylinder
    M : array_like, shape (3, 4)
        [R | t], world to camera.
    X : array_like, shape (N, 3)
        World points, normally lying on the surface.

    Returns
    -------
    ndarray, shape (N,), bool
    """
    M = as_matrix(M, "M", (3, 4))
    X = as_points(X, "X", dims=3)
    c = camera_center(M)
    hits = cast_rays(prims, c, X - c)  # the point itself sits at ray parameter 1
    in_front = X @ M[2, :3] + M[2, 3] > 0
    return in_front & (hits.t >= 1 - rel_tol)


def _gauss_power(sigma: float, size: int) -> float:
    """Mean power of unit white noise smoothed by a Gaussian of ``sigma`` cells (to give
    each layer unit variance before weighting)."""
    # The Gaussian's spectrum is separable, so the 3D mean is the cube of the 1D one.
    return float(np.mean(np.exp(-4 * np.pi**2 * sigma**2 * np.fft.fftfreq(size) ** 2)) ** 3)


class SolidTexture:
    """A seeded 3D fractal noise: a scalar function of world points.

    The noise lives on a periodic lattice (``size`` cells per axis) that sums smoothed white
    noise at several scales; it is sampled by trilinear interpolation after a random rotation
    and shift, so the lattice axes do not line up with the scene.  Baking every scale into
    one lattice costs a single interpolation per point.  Values have zero mean and unit
    standard deviation over the lattice.

    Parameters
    ----------
    rng : numpy.random.Generator
    cell : float
        World size of one lattice cell; the texture repeats every ``size * cell``.
    scales : sequence of float
        Smoothing radii (Gaussian sigma, in cells) of the summed noise layers.
    weights : sequence of float
        Relative amplitude of each layer (each is first normalised to unit variance).
    size : int
        Lattice cells per axis.
    """

    def __init__(self, rng: np.random.Generator, *, cell: float, scales=(0.7, 1.5, 3.0),
                 weights=(0.5, 0.8, 1.0), size: int = 64):
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
        cell = as_positive_scalar(cell, "cell")
        if len(scales) != len(weights) or not len(scales):
            raise ValueError("scales, weights: expected two sequences of the same non-zero length, "
                             f"got {len(scales)} and {len(weights)}")
        # Spectral synthesis: white noise shaped by the combined spectrum of the Gaussian
        # layers, the same field statistics as summing separately smoothed layers, one FFT.
        k2 = sum(np.meshgrid(*[np.fft.fftfreq(size) ** 2] * 2 + [np.fft.rfftfreq(size) ** 2],
                             indexing="ij"))
        power = sum(w**2 * np.exp(-4 * np.pi**2 * sigma**2 * k2) / _gauss_power(sigma, size)
                    for sigma, w in zip(scales, weights))
        spectrum = scipy.fft.rfftn(rng.standard_normal((size,) * 3)) * np.sqrt(power)
        lattice = scipy.fft.irfftn(spectrum, s=(size,) * 3, axes=(0, 1, 2))
        lattice -= lattice.mean()
        self._lattice = lattice / lattice.std()
        q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        self._A = q / cell  # world -> lattice coordinates, rotated
        self._shift = rng.uniform(0, size, 3)

    def __call__(self, X) -> np.ndarray:
        """Texture values (N,) at world points X (N, 3)."""
        X = np.asarray(X, float).reshape(-1, 3)
        coords = (X @ self._A.T + self._shift).T
        return ndimage.map_coordinates(self._lattice, coords, order=1, mode="grid-wrap")


def shade(gbuf: GBuffer, albedo: Callable[[np.ndarray], np.ndarray], *, light, ambient: float,
          background: np.ndarray, gain: float = 1.0, noise_sigma: float = 0.0,
          rng: np.random.Generator | None = None) -> np.ndarray:
    """Shade a G-buffer into an 8-bit RGB image.

    Parameters
    ----------
    gbuf : GBuffer
    albedo : callable
        Maps hit points (N, 3) to RGB reflectances (N, 3) in about [0, 1].
    light : array_like, shape (3,)
        Direction towards a distant light, in world coordinates; its length is its strength.
    ambient : float
        Light that reaches every surface whatever its orientation.
    background : ndarray, shape (H, W, 3)
        Linear RGB in [0, 1] shown where no surface is hit.
    gain : float
        Exposure of this view (multiplies the surface radiance).
    noise_sigma : float
        Standard deviation of the Gaussian sensor noise, in grey levels (0-255).
    rng : numpy.random.Generator
        Needed when ``noise_sigma > 0``.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    H, W = gbuf.depth.shape
    background = np.asarray(background, float)
    if background.shape != (H, W, 3):
        raise ValueError(f"background: expected shape {(H, W, 3)}, got {background.shape}")
    if noise_sigma > 0 and not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected a numpy.random.Generator when noise_sigma > 0, got {rng!r}")
    colour = background.reshape(-1, 3)[gbuf.pixel]
    hit = gbuf.sample_prim >= 0
    if np.any(hit):
        lambert = np.maximum(gbuf.normal[hit] @ np.asarray(light, float).reshape(3), 0.0)
        rgb = np.asarray(albedo(gbuf.points[hit]), float)
        colour[hit] = gain * rgb * (ambient + lambert)[:, None]
    img = np.stack([np.bincount(gbuf.pixel, weights=gbuf.weight * colour[:, c], minlength=H * W)
                    for c in range(3)], axis=1).reshape(H, W, 3) * 255.0
    if noise_sigma > 0:
        img += rng.normal(0.0, noise_sigma, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)
