"""``make_car_scene``: the seeded car sequence, observations and (optionally) images."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from core.geometry import camera_center
from scenes.cameras import projection

from .model import (
    CAR_COLORS,
    N_CAMERAS,
    N_KEYPOINTS,
    CarModel,
    car_keypoints,
    car_parts,
    car_rotation,
)
from .observe import keypoint_normals, observe_keypoints
from .render import render_view
from .scene import CarScene, readonly
from .street import street_layers
from .trajectory import fit_cameras, jitter_camera, trajectory_of


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
    kp_normals = keypoint_normals(parts, kps)
    positions, headings = trajectory_of(rng_layout, n_times)
    rotations = [car_rotation(h) for h in headings]
    P_true = np.stack([p + kps @ R.T for p, R in zip(positions, rotations)])
    # every vertex of the body and cabin must be in view, not just the keypoints
    hull = np.concatenate([np.concatenate(part.faces) for part in parts[:2]])
    extent = np.concatenate([p + hull @ R.T for p, R in zip(positions, rotations)] + list(P_true))
    K0, M0 = fit_cameras(rng_layout, positions, extent, width, height)

    K = np.zeros((n_times, N_CAMERAS, 3, 3))
    M = np.zeros((n_times, N_CAMERAS, 3, 4))
    for t in range(n_times):
        for c in range(N_CAMERAS):
            K[t, c], M[t, c] = jitter_camera(rng_layout, K0[c], M0[c], width)

    uv_true = np.zeros((n_times, N_CAMERAS, N_KEYPOINTS, 2))
    occluded = np.zeros((n_times, N_CAMERAS, N_KEYPOINTS), bool)
    pts = np.zeros((n_times, N_CAMERAS, N_KEYPOINTS, 3), np.int64)
    for t in range(n_times):
        C = [projection(K[t, c], M[t, c]) for c in range(N_CAMERAS)]
        centres = [camera_center(M[t, c]) for c in range(N_CAMERAS)]
        uv_true[t], occluded[t], pts[t] = observe_keypoints(rng_obs, parts, kp_normals, kps, rotations[t], positions[t],
                                                   centres, C, width, height, sigma_best, sigma_worst)

    scene = CarScene(
        images=None, K=readonly(K), M=readonly(M), pts=readonly(pts), P_true=readonly(P_true),
        uv_true=readonly(uv_true), occluded=readonly(occluded), car_position=readonly(positions),
        car_heading=readonly(headings), model=model, width=int(width), height=int(height), seed=int(seed),
        street=street_layers(rng_street),
    )
    if render:
        images = tuple(tuple(readonly(render_view(scene, t, c, supersample=supersample)) for t in range(n_times))
                       for c in range(N_CAMERAS))
        scene = replace(scene, images=images)
    return scene
