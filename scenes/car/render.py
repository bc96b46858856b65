"""Rendering one view of the scene: the car's solids, decals, its shadow and the street."""

from __future__ import annotations

import numpy as np

from core.geometry import camera_center
from scenes.painter import Face, Layer, face_normal, orient_outward, render

from .model import N_CAMERAS, lamp_points, car_parts, car_rotation
from .scene import CarScene

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
            decals = [Face(world(orient_outward(lamp_points(m, True, s), [0, 0, 0.6])), (245, 240, 215), shade=False)
                      for s in (1, -1)]
            front = f[0, 0]
            grille = np.array([[front, -0.42, 0.38], [front, 0.42, 0.38], [front, 0.42, 0.48], [front, -0.42, 0.48]])
            decals.append(Face(world(orient_outward(grille, [0, 0, 0.6])), (40, 40, 42)))
        elif n[0] < -0.99:
            decals = [Face(world(orient_outward(lamp_points(m, False, s), [0, 0, 0.6])), (200, 25, 30), shade=False)
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
