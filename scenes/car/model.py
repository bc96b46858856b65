"""The car model in the car frame (forward, left, up): its convex parts, keypoints and rotation."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from core.skeleton import CAR_KEYPOINTS
from scenes.painter import face_normal, orient_outward

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
class Part:
    """A convex solid of the car: faces (car frame) with outward normals, and its half-spaces."""

    name: str
    faces: tuple[np.ndarray, ...]
    color: tuple[int, int, int]
    normals: np.ndarray  # (F, 3)
    offsets: np.ndarray  # (F,): the solid is {p : normals @ p <= offsets}


def _part(name, faces, color) -> Part:
    centre = np.mean(np.concatenate(faces), axis=0)
    faces = tuple(orient_outward(f, centre) for f in faces)
    normals = np.array([face_normal(f) for f in faces])
    offsets = np.array([n @ f[0] for n, f in zip(normals, faces)])
    return Part(name, faces, color, normals, offsets)


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
def car_parts(m: CarModel = CarModel()) -> tuple[Part, ...]:
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


def lamp_points(m: CarModel, front: bool, side: int) -> np.ndarray:
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
    lamps = [lamp_points(m, True, 1).mean(0), lamp_points(m, True, -1).mean(0),
             lamp_points(m, False, 1).mean(0), lamp_points(m, False, -1).mean(0)]
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
