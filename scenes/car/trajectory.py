"""The car's path across the intersection and the three cameras that watch it."""

from __future__ import annotations

import numpy as np

from core.geometry import camera_center, depths, project
from scenes.cameras import intrinsics, look_at, projection, rotation_about

from .model import N_CAMERAS, ROAD_HALF_WIDTH

# --------------------------------------------------------------------------------------------
# Trajectory and cameras
# --------------------------------------------------------------------------------------------

def trajectory_of(rng, n_times: int):
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


def fit_cameras(rng, targets_world: np.ndarray, extent_world: np.ndarray, width: int, height: int):
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


def jitter_camera(rng, K: np.ndarray, M: np.ndarray, width: int):
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
