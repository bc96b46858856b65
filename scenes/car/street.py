"""The street around the car: road, sidewalks and buildings with windows."""

from __future__ import annotations

import numpy as np

from scenes.painter import Face, Layer, Quads, face_normal, orient_outward

from .model import BUILDING_SETBACK, ROAD_HALF_WIDTH, SIDEWALK_OUTER, UP

# --------------------------------------------------------------------------------------------
# The street (static, drawn behind the car)
# --------------------------------------------------------------------------------------------

def _ground_rect(x0, x1, z0, z1, color) -> Face:
    v = np.array([[x0, 0, z0], [x1, 0, z0], [x1, 0, z1], [x0, 0, z1]], float)
    return Face(orient_outward(v, [0.0, 1.0, 0.0]), color, cull=False, shade=False)


def street_layers(rng) -> tuple[Layer, Layer]:
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
