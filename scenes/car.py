"""Synthetic data for problem 6: a car crossing an intersection, seen by three cameras.

``make_car_scene(seed)`` builds, deterministically per seed, what ``data/q6`` holds in the
official handout (ten time steps, three cameras, twelve keypoints per view with a confidence)
together with the ground truth that the official data lacks; ``write_car`` writes it in the
official layout: ``cam{c}_time{t}.jpg`` and ``time{t}.npz`` with ``pts1..3`` (int64, (12, 3)
rows [x, y, confidence]), ``M1..3`` (float64 (3, 4)) and ``K1..3`` (float64 (3, 3)).

Frames and conventions
----------------------
- World: x east, y down (gravity), z north, metres; the ground is y = 0 and the centre of the
  intersection is the origin.  y points down so that ``cameras.look_at``'s default up vector
  and the official files' habit (cameras with R close to upright) both hold.
- Car frame: (forward, left, up), metres, origin on the ground under the middle of the car.
- M = [R | t] (3x4) maps world to camera coordinates, C = K M, pixels are (x, y) = (column, row).
- Keypoint order is ``core.skeleton.CAR_KEYPOINTS``: wheel hubs (outer face of each wheel),
  head- and taillights (centres of the lamps), roof corners.

Observation model (what makes the confidence threshold of Q6.1 matter)
----------------------------------------------------------------------
A keypoint hidden from a camera by the car itself (a ray test against the convex parts of the
body) gets a confidence of 300, 400 or 500.  A visible one gets 400 + 700 q plus noise,
rounded to a multiple of 100 and clipped to [500, 1100], where q is the cosine between the
direction to the camera and the best-facing surface normal at the keypoint, so grazing views
score lower.  The pixel error is isotropic Gaussian with a standard deviation that falls
geometrically from ``sigma_worst`` at 300 to ``sigma_best`` at 1100 (``confidence_sigma``),
then the pixel is rounded to integers.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
from PIL import Image

from core.geometry import camera_center, depths, project
from core.skeleton import CAR_KEYPOINTS
from scenes.cameras import intrinsics, look_at, projection, rotation_about
from scenes.painter import Face, Layer, Quads, face_normal, orient_outward, render

__all__ = [
    "CarModel",
    "CarScene",
    "CONFIDENCE_LEVELS",
    "confidence_sigma",
    "car_parts",
    "car_keypoints",
    "car_rotation",
    "make_car_scene",
    "render_view",
    "official_arrays",
    "write_car",
]

N_CAMERAS = 3
N_KEYPOINTS = len(CAR_KEYPOINTS)
CONFIDENCE_LEVELS = tuple(range(300, 1101, 100))
UP = np.array([0.0, -1.0, 0.0])

ROAD_HALF_WIDTH = 4.0  # two lanes of 4 m
SIDEWALK_OUTER = 7.0  # 3 m sidewalks
BUILDING_SETBACK = 16.0

CAR_COLORS = ((180, 30, 35), (30, 70, 160), (235, 235, 230), (230, 180, 20), (25, 120, 70), (120, 40, 130))


# --------------------------------------------------------------------------------------------
# The car model, in the car frame (forward, left, up)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CarModel:
    """Dimensions (metres) and paint of the car.

    The lower body is a prism whose side profile is a box with a bevelled front top edge;
    the cabin is the convex hull of a bottom and a smaller roof rectangle; each wheel is a
    12-sided prism whose outer face sticks out ``wheel_protrusion`` beyond the body's side.
    """

    length: float = 4.4
    width: float = 1.8
    clearance: float = 0.3
    hood_height: float = 0.88
    bevel: tuple[float, float] = (0.35, 0.16)  # forward and vertical extent of the hood bevel
    cabin_bottom: tuple[float, float, float] = (-1.5, 0.85, 0.86)  # rear, front, half width
    cabin_top: tuple[float, float, float] = (-1.05, 0.15, 0.72)
    roof_height: float = 1.45
    wheel_radius: float = 0.33
    wheel_width: float = 0.22
    wheel_protrusion: float = 0.03
    axles: tuple[float, float] = (1.3, -1.4)  # front, rear
    color: tuple[int, int, int] = CAR_COLORS[0]


@dataclass(frozen=True, eq=False)
class _Part:
    """A convex solid of the car: faces (car frame) with outward normals, and its half-spaces."""

    name: str
    faces: tuple[np.ndarray, ...]
    color: tuple[int, int, int]
    normals: np.ndarray  # (F, 3)
    offsets: np.ndarray  # (F,): the solid is {p : normals @ p <= offsets}


def _part(name, faces, color) -> _Part:
    centre = np.mean(np.concatenate(faces), axis=0)
    faces = tuple(orient_outward(f, centre) for f in faces)
    normals = np.array([face_normal(f) for f in faces])
    offsets = np.array([n @ f[0] for n, f in zip(normals, faces)])
    return _Part(name, faces, color, normals, offsets)


def _prism(profile: np.ndarray, half_width: float) -> list[np.ndarray]:
    """Faces of the prism of a convex (forward, up) profile (k, 2) extruded over left in [-w, w]."""
    left = np.column_stack([profile[:, 0], np.full(len(profile), half_width), profile[:, 1]])
    right = left * [1, -1, 1]
    faces = [left, right[::-1]]
    k = len(profile)
    for i in range(k):
        j = (i + 1) % k
        faces.append(np.array([left[i], left[j], right[j], right[i]]))
    return faces


def _wheel_faces(m: CarModel, axle: float, side: int, n: int = 12) -> list[np.ndarray]:
    outer = side * (m.width / 2 + m.wheel_protrusion)
    inner = outer - side * m.wheel_width
    a = np.linspace(0, 2 * np.pi, n, endpoint=False) + np.pi / n
    fw = axle + m.wheel_radius * np.cos(a)
    up = m.wheel_radius + m.wheel_radius * np.sin(a)
    cap_out = np.column_stack([fw, np.full(n, outer), up])
    cap_in = np.column_stack([fw, np.full(n, inner), up])
    faces = [cap_out, cap_in]
    for i in range(n):
        j = (i + 1) % n
        faces.append(np.array([cap_out[i], cap_out[j], cap_in[j], cap_in[i]]))
    return faces


@lru_cache(maxsize=16)
def car_parts(m: CarModel = CarModel()) -> tuple[_Part, ...]:
    """The convex solids of the car in the car frame: body, cabin and four wheels.

    Wheels are named ``wheel front-left`` etc. like their keypoints; faces of a wheel are
    [outer cap, inner cap, 12 tread quads].
    """
    L2 = m.length / 2
    bf, bu = m.bevel
    profile = np.array([[-L2, m.clearance], [L2, m.clearance], [L2, m.hood_height - bu],
                        [L2 - bf, m.hood_height], [-L2, m.hood_height]])
    (rb, fb, wb), (rt, ft, wt) = m.cabin_bottom, m.cabin_top
    h0, h1 = m.hood_height, m.roof_height
    # Vertex orders chosen so that bilinear (a, b) runs (forward or across, up) on the
    # window faces; _part may reverse them, _decal copes with that.
    cabin = [
        np.array([[rb, wb, h0], [fb, wb, h0], [ft, wt, h1], [rt, wt, h1]]),  # left
        np.array([[rb, -wb, h0], [fb, -wb, h0], [ft, -wt, h1], [rt, -wt, h1]]),  # right
        np.array([[fb, -wb, h0], [fb, wb, h0], [ft, wt, h1], [ft, -wt, h1]]),  # front
        np.array([[rb, -wb, h0], [rb, wb, h0], [rt, wt, h1], [rt, -wt, h1]]),  # rear
        np.array([[rt, -wt, h1], [ft, -wt, h1], [ft, wt, h1], [rt, wt, h1]]),  # roof
        np.array([[rb, -wb, h0], [fb, -wb, h0], [fb, wb, h0], [rb, wb, h0]]),  # floor
    ]
    parts = [_part("body", _prism(profile, m.width / 2), m.color), _part("cabin", cabin, m.color)]
    for name, axle, side in (("front-left", m.axles[0], 1), ("front-right", m.axles[0], -1),
                             ("rear-left", m.axles[1], 1), ("rear-right", m.axles[1], -1)):
        parts.append(_part(f"wheel {name}", _wheel_faces(m, axle, side), (32, 32, 34)))
    return tuple(parts)


def _lamp(m: CarModel, front: bool, side: int) -> np.ndarray:
    """Corners (4, 3) of a lamp on the front or rear face of the body, car frame."""
    L2 = m.length / 2
    f = L2 if front else -L2
    centre_l = side * (m.width / 2 - (0.27 if front else 0.24))
    u0, u1 = (0.54, 0.66) if front else (0.6, 0.74)
    hw = 0.17 if front else 0.15
    return np.array([[f, centre_l - hw, u0], [f, centre_l + hw, u0], [f, centre_l + hw, u1], [f, centre_l - hw, u1]])


def car_keypoints(m: CarModel = CarModel()) -> np.ndarray:
    """The 12 keypoints (12, 3) in the car frame (forward, left, up), order ``CAR_KEYPOINTS``."""
    out = m.width / 2 + m.wheel_protrusion
    wheels = [[m.axles[0], out, m.wheel_radius], [m.axles[0], -out, m.wheel_radius],
              [m.axles[1], out, m.wheel_radius], [m.axles[1], -out, m.wheel_radius]]
    lamps = [_lamp(m, True, 1).mean(0), _lamp(m, True, -1).mean(0),
             _lamp(m, False, 1).mean(0), _lamp(m, False, -1).mean(0)]
    rt, ft, wt = m.cabin_top
    roof = [[ft, wt, m.roof_height], [ft, -wt, m.roof_height], [rt, wt, m.roof_height], [rt, -wt, m.roof_height]]
    return np.array(wheels + [list(p) for p in lamps] + roof, dtype=float)


def car_rotation(heading: float) -> np.ndarray:
    """Rotation (3, 3) whose columns are the car's forward, left and up axes in world coordinates.

    ``heading`` is in radians, 0 = east (+x), pi/2 = north (+z).  A car-frame point p of a
    car at ``position`` (3,) is at ``position + R @ p`` in the world.
    """
    c, s = np.cos(heading), np.sin(heading)
    return np.column_stack([[c, 0.0, s], [-s, 0.0, c], UP])


# --------------------------------------------------------------------------------------------
# Visibility and the observation model
# --------------------------------------------------------------------------------------------

def _segment_hits(part: _Part, a: np.ndarray, b: np.ndarray, stop: float) -> bool:
    """Does the segment a -> b (car frame), up to ``stop`` metres before b, cross the part's interior?"""
    d = b - a
    length = np.linalg.norm(d)
    hi = 1.0 - stop / length
    lo = 0.0
    # Shrinking the solid by a millimetre keeps rays that graze a face or an edge visible.
    num = part.offsets - 1e-3 - part.normals @ a
    den = part.normals @ d
    for nu, de in zip(num, den):
        if abs(de) < 1e-12:
            if nu < 0:
                return False
        elif de > 0:
            hi = min(hi, nu / de)
        else:
            lo = max(lo, nu / de)
        if lo >= hi:
            return False
    return True


def _keypoint_normals(parts, kps: np.ndarray) -> list[np.ndarray]:
    """For each keypoint (car frame), the outward normals (n, 3) of the faces it lies on."""
    out = []
    for p in kps:
        normals = []
        for part in parts:
            dist = part.normals @ p - part.offsets
            if np.all(dist <= 1e-6):
                normals.extend(part.normals[np.abs(dist) <= 1e-6])
        if not normals:
            raise RuntimeError(f"keypoint {p} lies on no face of the car model")
        out.append(np.array(normals))
    return out


def confidence_sigma(confidence, sigma_best: float = 0.5, sigma_worst: float = 12.0) -> np.ndarray:
    """Standard deviation (pixels, per axis) of the detection error at a given confidence.

    Geometric interpolation from ``sigma_worst`` at 300 to ``sigma_best`` at 1100, so every
    step of 100 multiplies the error by the same factor (about 1.49 with the defaults).

    Parameters
    ----------
    confidence : array_like
        Confidences, in [300, 1100].

    Returns
    -------
    ndarray, the shape of ``confidence``
    """
    c = np.asarray(confidence, float)
    frac = (1100.0 - c) / 800.0
    return sigma_best * (sigma_worst / sigma_best) ** frac


def _observe(rng, parts, kp_normals, kps_car, R_car, pos, centres, C, width, height,
             sigma_best, sigma_worst):
    """Projections, occlusion flags and noisy observations of one time step.

    Returns uv (3, 12, 2), occluded (3, 12) bool, pts (3, 12, 3) int64.
    """
    world = pos + kps_car @ R_car.T
    uv = np.stack([project(Cc, world) for Cc in C])
    occluded = np.zeros((len(C), N_KEYPOINTS), bool)
    quality = np.zeros((len(C), N_KEYPOINTS))
    for c, centre in enumerate(centres):
        cam = R_car.T @ (centre - pos)
        for k, p in enumerate(kps_car):
            occluded[c, k] = any(_segment_hits(part, cam, p, 0.005) for part in parts)
            v = (cam - p) / np.linalg.norm(cam - p)
            quality[c, k] = max(0.0, float(np.max(kp_normals[k] @ v)))
    raw = 400 + 700 * quality + rng.normal(0, 100, quality.shape)
    conf_visible = np.clip(np.round(raw / 100) * 100, 500, 1100)
    conf_hidden = rng.choice([300, 400, 500], size=quality.shape, p=[0.45, 0.4, 0.15])
    conf = np.where(occluded, conf_hidden, conf_visible).astype(np.int64)
    sigma = confidence_sigma(conf, sigma_best, sigma_worst)
    noisy = uv + rng.normal(size=uv.shape) * sigma[..., None]
    xy = np.round(noisy)
    # A detector only reports pixels inside the image.
    xy[..., 0] = np.clip(xy[..., 0], 0, width - 1)
    xy[..., 1] = np.clip(xy[..., 1], 0, height - 1)
    pts = np.concatenate([xy.astype(np.int64), conf[..., None]], axis=-1)
    return uv, occluded, pts


# --------------------------------------------------------------------------------------------
# Trajectory and cameras
# --------------------------------------------------------------------------------------------

def _trajectory(rng, n_times: int):
    """Car positions (T, 3) and headings (T,) driving straight-ish through the intersection.

    The road direction is one of the four, the car keeps to the right-hand lane, moves 0.8 to
    1 m per step and yaws by a constant rate of at most 1.2 degrees per step.
    """
    base = rng.integers(4) * np.pi / 2
    step = rng.uniform(0.8, 1.0)
    yaw_rate = np.deg2rad(rng.uniform(-1.2, 1.2))
    h0 = base + np.deg2rad(rng.normal(0, 1.5)) - yaw_rate * (n_times - 1) / 2
    headings = h0 + yaw_rate * np.arange(n_times)
    fwd = np.column_stack([np.cos(headings), np.zeros(n_times), np.sin(headings)])
    steps = np.vstack([np.zeros(3), np.cumsum(step * fwd[:-1], axis=0)])
    right = np.array([np.sin(base), 0.0, -np.cos(base)])
    lane = (ROAD_HALF_WIDTH / 2 + rng.uniform(-0.3, 0.3)) * right
    start = lane - steps[-1] / 2 + rng.uniform(-1.0, 1.0) * np.array([np.cos(base), 0.0, np.sin(base)])
    return start + steps, headings


def _fit_cameras(rng, targets_world: np.ndarray, extent_world: np.ndarray, width: int, height: int):
    """Base intrinsics (3, 3, 3) and extrinsics (3, 3, 4) of three cameras at street corners.

    Three of the four corners are drawn; each camera starts 8.5 to 10.5 m from both road axes,
    1.9 to 3.2 m above the ground, aims at the middle of the car's path (``targets_world``
    (T, 3)) and steps back horizontally until every point of ``extent_world`` (N, 3)
    projects inside the image with a margin of 7% of the width.
    """
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    chosen = np.sort(rng.choice(4, size=N_CAMERAS, replace=False))
    scale = width / 1920.0
    Ks, Ms = [], []
    margin = 0.07 * width
    target = targets_world.mean(axis=0) + [0.0, -0.7, 0.0]
    for idx in chosen:
        f = rng.uniform(1450, 1850) * scale
        K = intrinsics(f, width / 2 + rng.normal(0, 12 * scale), height / 2 + rng.normal(0, 12 * scale),
                       fy=f * (1 + rng.normal(0, 0.002)))
        centre = np.array([corners[idx, 0] * rng.uniform(8.5, 10.5), -rng.uniform(1.9, 3.2),
                           corners[idx, 1] * rng.uniform(8.5, 10.5)])
        aim = target + rng.normal(0, 0.4, 3) * [1, 0.3, 1]
        roll = rotation_about([0, 0, 1], np.deg2rad(rng.normal(0, 1.5)))
        away = centre - aim
        away[1] = 0.0
        away /= np.linalg.norm(away)
        for _ in range(200):
            M = look_at(centre, aim)
            M = np.hstack([roll @ M[:, :3], roll @ M[:, 3:]])
            uv = project(projection(K, M), extent_world)
            inside = (np.all(uv >= margin) and np.all(uv[:, 0] <= width - margin)
                      and np.all(uv[:, 1] <= height - margin) and np.all(depths(M, extent_world) > 1.0))
            if inside:
                break
            centre = centre + 0.25 * away
        else:
            raise RuntimeError("could not fit the car's path into a camera's view")
        Ks.append(K)
        Ms.append(M)
    return np.array(Ks), np.array(Ms)


def _jitter(rng, K: np.ndarray, M: np.ndarray, width: int):
    """A slightly different K (3, 3) and M (3, 4) for one time step (hand-held camera, re-estimated K)."""
    scale = width / 1920.0
    Kt = K.copy()
    Kt[0, 0] *= 1 + rng.normal(0, 5e-4)
    Kt[1, 1] *= 1 + rng.normal(0, 5e-4)
    Kt[:2, 2] += rng.normal(0, 2.0 * scale, 2)
    axis = rng.normal(size=3)
    dR = rotation_about(axis, np.deg2rad(rng.normal(0, 0.25)))
    R = dR @ M[:, :3]
    centre = camera_center(M) + rng.normal(0, 0.02, 3)
    return Kt, np.hstack([R, (-R @ centre)[:, None]])


# --------------------------------------------------------------------------------------------
# The street (static, drawn behind the car)
# --------------------------------------------------------------------------------------------

def _ground_rect(x0, x1, z0, z1, color) -> Face:
    v = np.array([[x0, 0, z0], [x1, 0, z0], [x1, 0, z1], [x0, 0, z1]], float)
    return Face(orient_outward(v, [0.0, 1.0, 0.0]), color, cull=False, shade=False)


def _street(rng) -> tuple[Layer, Layer]:
    """The ground paint (one unsorted layer) and the buildings (one depth-sorted layer)."""
    far = 3000.0
    r, s = ROAD_HALF_WIDTH, SIDEWALK_OUTER
    ground = [_ground_rect(-far, far, -far, far, (112, 138, 82))]
    sidewalk, asphalt, white, yellow = (178, 176, 170), (78, 80, 84), (232, 232, 228), (226, 190, 50)
    ground += [_ground_rect(-far, far, -s, s, sidewalk), _ground_rect(-s, s, -far, far, sidewalk)]
    ground += [_ground_rect(-far, far, -r, r, asphalt), _ground_rect(-r, r, -far, far, asphalt)]
    for sign in (-1, 1):
        # centre lines (double yellow) outside the box of the intersection
        for off in (-0.15, 0.05):
            ground.append(_ground_rect(*sorted([sign * (s + 1), sign * far]), off, off + 0.1, yellow))
            ground.append(_ground_rect(off, off + 0.1, *sorted([sign * (s + 1), sign * far]), yellow))
        # crosswalks: stripes parallel to the traffic, across the whole road
        lo, hi = sorted([sign * (r + 0.6), sign * (s - 0.4)])
        for z in np.arange(-r + 0.3, r - 0.3, 0.8):
            ground.append(_ground_rect(lo, hi, z, z + 0.45, white))
            ground.append(_ground_rect(z, z + 0.45, lo, hi, white))
        # stop lines on the approaching lane of each road
        a, b = sorted([sign * (s + 0.4), sign * (s + 0.8)])
        ground.append(_ground_rect(a, b, *sorted([0.0, -sign * r]), white))
        ground.append(_ground_rect(*sorted([0.0, sign * r]), a, b, white))

    palette = ((150, 78, 62), (201, 186, 152), (150, 150, 156), (216, 206, 182), (122, 92, 72), (170, 110, 90))
    buildings = []
    for sx in (-1, 1):
        for sz in (-1, 1):
            x = BUILDING_SETBACK
            while x < 70:
                w = rng.uniform(10, 18)
                d = rng.uniform(10, 16)
                hgt = rng.uniform(8, 32)
                buildings.append(_building(sx, sz, x, x + w, BUILDING_SETBACK, BUILDING_SETBACK + d, hgt,
                                           palette[rng.integers(len(palette))], swap=False))
                buildings.append(_building(sx, sz, BUILDING_SETBACK, BUILDING_SETBACK + d, x + 2, x + 2 + w,
                                           rng.uniform(8, 32), palette[rng.integers(len(palette))], swap=True))
                x += w + rng.uniform(1, 4)
    return Layer([ground]), Layer(buildings, sort=True)


def _building(sx, sz, a0, a1, b0, b1, height, color, swap) -> list[Face]:
    """A box building with a grid of windows, in the quadrant of signs (sx, sz)."""
    if swap:
        a0, a1, b0, b1 = b0, b1, a0, a1
    xs = sorted([sx * a0, sx * a1])
    zs = sorted([sz * b0, sz * b1])
    corners = np.array([[x, y, z] for y in (0.0, -height) for z in zs for x in xs])
    centre = corners.mean(axis=0)
    idx = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
    faces = []
    for q in idx:
        v = orient_outward(corners[q], centre)
        n = face_normal(v)
        decals = () if abs(n[1]) > 0.5 else (_windows(v, n, height),)
        faces.append(Face(v, color, decals=decals))
    return faces


def _windows(v: np.ndarray, n: np.ndarray, height: float) -> Quads:
    """A grid of windows on a vertical wall v (4, 3) with outward normal n."""
    bottom = v[v[:, 1] > -1e-9]
    p0, p1 = bottom[0], bottom[1]
    along = p1 - p0
    span = np.linalg.norm(along)
    along /= span
    cols = int(span // 3.2)
    floors = max(0, int((height - 2.0) // 3.3))
    a = (span - cols * 3.2) / 2 + np.arange(cols) * 3.2 + 0.9
    h = 2.2 + np.arange(floors) * 3.3
    base = p0 + 0.02 * n + a[:, None, None] * along + h[None, :, None] * UP  # (cols, floors, 3)
    corners = np.array([[0, 0], [1.4, 0], [1.4, 1.8], [0, 1.8]])
    quads = base.reshape(-1, 1, 3) + corners[:, :1] * along + corners[:, 1:] * UP
    return Quads(quads, (70, 84, 104))


# --------------------------------------------------------------------------------------------
# The scene
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class CarScene:
    """A generated problem-6 data set and its ground truth.

    Indices: t is the time step (0..T-1), c the camera (0..2 for the files' 1..3), k the
    keypoint (order ``CAR_KEYPOINTS``).

    Attributes
    ----------
    images : tuple of 3 tuples of T ndarrays (H, W, 3) uint8, or None
        ``images[c][t]`` is ``cam{c+1}_time{t}.jpg`` before JPEG compression; None when the
        scene was made with ``render=False``.
    K : ndarray, shape (T, 3, 3, 3)
        ``K[t, c]`` intrinsics (the file's ``K{c+1}``).
    M : ndarray, shape (T, 3, 3, 4)
        ``M[t, c]`` = [R | t] world to camera (the file's ``M{c+1}``).
    pts : ndarray, shape (T, 3, 12, 3), int64
        ``pts[t, c]`` is the file's ``pts{c+1}``: rows [x, y, confidence].
    P_true : ndarray, shape (T, 12, 3)
        True keypoints in world coordinates (metres).
    uv_true : ndarray, shape (T, 3, 12, 2)
        Exact projections of ``P_true``, (x, y) pixels, before noise and rounding.
    occluded : ndarray, shape (T, 3, 12), bool
        The keypoint is hidden from the camera by the car itself.
    car_position : ndarray, shape (T, 3)
        Origin of the car frame (on the ground under the middle of the car), world.
    car_heading : ndarray, shape (T,)
        Heading in radians (0 = +x, pi/2 = +z).
    model : CarModel
    width, height : int
        Image size in pixels.
    seed : int
    """

    images: tuple[tuple[np.ndarray, ...], ...] | None
    K: np.ndarray
    M: np.ndarray
    pts: np.ndarray
    P_true: np.ndarray
    uv_true: np.ndarray
    occluded: np.ndarray
    car_position: np.ndarray
    car_heading: np.ndarray
    model: CarModel
    width: int
    height: int
    seed: int
    street: tuple[Layer, Layer] = field(repr=False)

    @property
    def n_times(self) -> int:
        return int(self.pts.shape[0])

    @property
    def C(self) -> np.ndarray:
        """Camera matrices K M, shape (T, 3, 3, 4)."""
        return self.K @ self.M


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def make_car_scene(seed: int = 0, *, n_times: int = 10, width: int = 1920, height: int = 1080,
                   render: bool = True, sigma_best: float = 0.5, sigma_worst: float = 12.0,
                   supersample: int = 2) -> CarScene:
    """Generate the problem-6 data set: a car crossing an intersection, three cameras.

    Parameters
    ----------
    seed : int
        Everything is a function of the seed.  Independent streams (spawned from it) drive
        the layout, the observations and the buildings, so ``render`` never changes the data.
    n_times : int
        Number of time steps T (the official data has 10).
    width, height : int
        Image size in pixels (official: 1920 x 1080); focal lengths scale with the width.
    render : bool
        Draw the 3 x T images (about 0.1 s each); False leaves ``images`` None.
    sigma_best, sigma_worst : float
        Pixel noise (standard deviation per axis) at confidence 1100 and 300.
    supersample : int
        Antialiasing factor of the renderer.

    Returns
    -------
    CarScene
    """
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected a non-negative integer, got {seed!r}")
    for name, value, lo in (("n_times", n_times, 1), ("width", width, 64), ("height", height, 64)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < lo:
            raise ValueError(f"{name}: expected an integer >= {lo}, got {value!r}")
    if not 0 < sigma_best <= sigma_worst:
        raise ValueError(f"sigma_best, sigma_worst: expected 0 < sigma_best <= sigma_worst, "
                         f"got {sigma_best!r} and {sigma_worst!r}")
    rng_layout, rng_obs, rng_street = (np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(3))

    model = CarModel(color=CAR_COLORS[rng_layout.integers(len(CAR_COLORS))])
    parts = car_parts(model)
    kps = car_keypoints(model)
    kp_normals = _keypoint_normals(parts, kps)
    positions, headings = _trajectory(rng_layout, n_times)
    rotations = [car_rotation(h) for h in headings]
    P_true = np.stack([p + kps @ R.T for p, R in zip(positions, rotations)])
    # every vertex of the body and cabin must be in view, not just the keypoints
    hull = np.concatenate([np.concatenate(part.faces) for part in parts[:2]])
    extent = np.concatenate([p + hull @ R.T for p, R in zip(positions, rotations)] + list(P_true))
    K0, M0 = _fit_cameras(rng_layout, positions, extent, width, height)

    K = np.zeros((n_times, N_CAMERAS, 3, 3))
    M = np.zeros((n_times, N_CAMERAS, 3, 4))
    for t in range(n_times):
        for c in range(N_CAMERAS):
            K[t, c], M[t, c] = _jitter(rng_layout, K0[c], M0[c], width)

    uv_true = np.zeros((n_times, N_CAMERAS, N_KEYPOINTS, 2))
    occluded = np.zeros((n_times, N_CAMERAS, N_KEYPOINTS), bool)
    pts = np.zeros((n_times, N_CAMERAS, N_KEYPOINTS, 3), np.int64)
    for t in range(n_times):
        C = [projection(K[t, c], M[t, c]) for c in range(N_CAMERAS)]
        centres = [camera_center(M[t, c]) for c in range(N_CAMERAS)]
        uv_true[t], occluded[t], pts[t] = _observe(rng_obs, parts, kp_normals, kps, rotations[t], positions[t],
                                                   centres, C, width, height, sigma_best, sigma_worst)

    scene = CarScene(
        images=None, K=_readonly(K), M=_readonly(M), pts=_readonly(pts), P_true=_readonly(P_true),
        uv_true=_readonly(uv_true), occluded=_readonly(occluded), car_position=_readonly(positions),
        car_heading=_readonly(headings), model=model, width=int(width), height=int(height), seed=int(seed),
        street=_street(rng_street),
    )
    if render:
        images = tuple(tuple(_readonly(render_view(scene, t, c, supersample=supersample)) for t in range(n_times))
                       for c in range(N_CAMERAS))
        scene = replace(scene, images=images)
    return scene


# --------------------------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------------------------

def _decal(parent: np.ndarray, outward: np.ndarray, quad_ab, color) -> Face:
    """A polygon on the quad ``parent`` (4, 3) at bilinear coordinates ``quad_ab`` [(a, b), ...].

    (a, b) run from ``parent[0]`` towards ``parent[1]`` and ``parent[3]``; the result is
    oriented to face ``outward`` (3,), the normal of the face it is painted on.
    """
    v0, v1, v2, v3 = parent
    pts = np.array([(1 - b) * ((1 - a) * v0 + a * v1) + b * ((1 - a) * v3 + a * v2) for a, b in quad_ab])
    if face_normal(pts) @ outward < 0:
        pts = pts[::-1].copy()
    return Face(pts, color)


def _box_ab(a0, a1, b0, b1):
    return [(a0, b0), (a1, b0), (a1, b1), (a0, b1)]


def _car_solids(scene: CarScene, t: int, centre: np.ndarray) -> list[list[Face]]:
    """The car's faces in world coordinates, in a drawing order valid for a camera at ``centre``.

    Wheels on the far side go first (the body covers them), then the body, the cabin (never
    hidden by the body from a camera above the hood) and the near wheels, of which only the
    outer cap and the tread below the body are drawn: the rest is inside the body.
    """
    m = scene.model
    pos, R = scene.car_position[t], car_rotation(scene.car_heading[t])
    cam = R.T @ (centre - pos)
    parts = car_parts(m)

    def world(v):
        return pos + np.asarray(v) @ R.T

    window = (58, 72, 88)
    body, cabin = parts[0], parts[1]
    body_faces = []
    for f in body.faces:
        n = face_normal(f)
        decals = []
        if n[0] > 0.99:  # front: headlights and a grille
            decals = [Face(world(orient_outward(_lamp(m, True, s), [0, 0, 0.6])), (245, 240, 215), shade=False)
                      for s in (1, -1)]
            front = f[0, 0]
            grille = np.array([[front, -0.42, 0.38], [front, 0.42, 0.38], [front, 0.42, 0.48], [front, -0.42, 0.48]])
            decals.append(Face(world(orient_outward(grille, [0, 0, 0.6])), (40, 40, 42)))
        elif n[0] < -0.99:
            decals = [Face(world(orient_outward(_lamp(m, False, s), [0, 0, 0.6])), (200, 25, 30), shade=False)
                      for s in (1, -1)]
        body_faces.append(Face(world(f), m.color, decals=tuple(decals)))

    cabin_faces = []
    for f in cabin.faces:
        n = face_normal(f)
        decals = []
        if abs(n[1]) > 0.9:  # sides: two windows split by a pillar
            span = sorted(range(4), key=lambda i: (f[i, 2], f[i, 0]))
            bl, br = sorted(span[:2], key=lambda i: f[i, 0])
            tl, tr = sorted(span[2:], key=lambda i: f[i, 0])
            quad, outward = world(f[[bl, br, tr, tl]]), R @ n
            decals = [_decal(quad, outward, _box_ab(0.07, 0.47, 0.12, 0.86), window),
                      _decal(quad, outward, _box_ab(0.53, 0.93, 0.12, 0.86), window)]
        elif abs(n[0]) > 0.3:  # windscreen and rear window
            span = sorted(range(4), key=lambda i: (f[i, 2], f[i, 1]))
            bl, br = sorted(span[:2], key=lambda i: f[i, 1])
            tl, tr = sorted(span[2:], key=lambda i: f[i, 1])
            quad, outward = world(f[[bl, br, tr, tl]]), R @ n
            decals = [_decal(quad, outward, _box_ab(0.06, 0.94, 0.1, 0.9), window)]
        cabin_faces.append(Face(world(f), m.color, decals=tuple(decals)))

    far_wheels, near_wheels = [], []
    for part in parts[2:]:
        side = 1 if "left" in part.name else -1
        outer = m.width / 2 + m.wheel_protrusion
        faces = part.faces
        if side * cam[1] > outer:
            hub = faces[0].mean(axis=0)
            hubcap = hub + 0.55 * (faces[0] - hub)
            cap = Face(world(faces[0]), part.color, decals=(Face(world(hubcap), (188, 190, 196), shade=False),))
            low = [Face(world(f), part.color) for f in faces[2:] if f[:, 2].max() <= m.clearance + 1e-9]
            near_wheels.append(low + [cap])
        else:
            far_wheels.append([Face(world(f), part.color) for f in faces])
    return far_wheels + [body_faces, cabin_faces] + near_wheels


def _shadow(scene: CarScene, t: int) -> Face:
    m = scene.model
    pos, R = scene.car_position[t], car_rotation(scene.car_heading[t])
    L2, W2 = m.length / 2 + 0.1, m.width / 2 + 0.12
    # offset away from the sun (which is up and towards +x, -z in the default renderer)
    rect = np.array([[-L2, -W2, 0], [L2, -W2, 0], [L2, W2, 0], [-L2, W2, 0]], float)
    v = pos + rect @ R.T + np.array([-0.25, 0.0, 0.3])
    v[:, 1] = 0.0
    return Face(orient_outward(v, [0.0, 1.0, 0.0]), (48, 50, 54), cull=False, shade=False)


def render_view(scene: CarScene, t: int, c: int, *, with_street: bool = True, with_car: bool = True,
                with_shadow: bool | None = None, supersample: int = 2) -> np.ndarray:
    """Draw time step ``t`` from camera ``c`` (0-based) of ``scene``.

    Parameters
    ----------
    with_street, with_car, with_shadow : bool
        Leave out the street (the background is then the sky gradient alone), the car, or its
        shadow on the ground (default: drawn with the car).  A view without the street and the
        shadow, compared with the empty sky, gives exactly the car's pixels.
    supersample : int
        Antialiasing factor (see ``painter.render``).

    Returns
    -------
    ndarray, shape (height, width, 3), uint8
    """
    if not (0 <= t < scene.n_times) or not (0 <= c < N_CAMERAS):
        raise ValueError(f"t, c: expected 0 <= t < {scene.n_times} and 0 <= c < {N_CAMERAS}, got {t!r}, {c!r}")
    if with_shadow is None:
        with_shadow = with_car
    K, M = scene.K[t, c], scene.M[t, c]
    layers = []
    if with_street:
        layers.append(scene.street[0])
    if with_shadow:
        layers.append(Layer([[_shadow(scene, t)]]))
    if with_street:
        layers.append(scene.street[1])
    if with_car:
        layers.append(Layer(_car_solids(scene, t, camera_center(M))))
    return render(layers, K, M, scene.width, scene.height, supersample=supersample)


# --------------------------------------------------------------------------------------------
# The official file layout
# --------------------------------------------------------------------------------------------

def official_arrays(scene: CarScene, t: int) -> dict[str, np.ndarray]:
    """The arrays of ``time{t}.npz`` in the official order and dtypes.

    Returns
    -------
    dict
        ``pts1..3`` int64 (12, 3) [x, y, confidence]; ``M1..3`` float64 (3, 4); ``K1..3``
        float64 (3, 3).
    """
    out = {}
    for c in range(N_CAMERAS):
        out[f"pts{c + 1}"] = np.array(scene.pts[t, c], dtype=np.int64)
    for c in range(N_CAMERAS):
        out[f"M{c + 1}"] = np.array(scene.M[t, c], dtype=np.float64)
    for c in range(N_CAMERAS):
        out[f"K{c + 1}"] = np.array(scene.K[t, c], dtype=np.float64)
    return out


def write_car(scene: CarScene, folder, *, quality: int = 90) -> list[Path]:
    """Write ``scene`` in the official ``q6`` layout; return the paths written.

    Writes ``time{t}.npz`` (``official_arrays``, uncompressed like the official files) and,
    when the scene has images, ``cam{c}_time{t}.jpg`` (c = 1..3).  No ground truth is written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for t in range(scene.n_times):
        path = folder / f"time{t}.npz"
        np.savez(path, **official_arrays(scene, t))
        written.append(path)
        if scene.images is not None:
            for c in range(N_CAMERAS):
                path = folder / f"cam{c + 1}_time{t}.jpg"
                Image.fromarray(scene.images[c][t]).save(path, quality=quality)
                written.append(path)
    return written
