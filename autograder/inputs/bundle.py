"""Q5: the bundle-adjustment problems, their best reachable error, and the inputs of ``rodriguesResidual``.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.geometry import project
from judging.bundle import ResidualCase, result, total_error
from starter.checks.bundle import BAProblem

from .scenes import Scenes
from .shared import M1


@dataclass(frozen=True, eq=False)
class Bundle:
    problems: tuple[BAProblem, ...]        # the public check's problem type; optimum: the lowest error found
    residual_inputs: tuple[ResidualCase, ...]   # (K1, M1, p1, K2, p2, x) of rodriguesResidual, with their residuals


_SWING_DEG = 20.0
_NOISE_PX = 0.5
_TRIES = 8


def _rotation(axis, degrees) -> np.ndarray:
    from core.rotations import rodrigues

    axis = np.asarray(axis, float)
    return rodrigues(np.radians(degrees) * axis / np.linalg.norm(axis))


def _gauge_fixed_optimum(K1, K2, p1, p2, M2_init, w_init) -> float:
    # t moves on the sphere of its initial length through two tangent coordinates, so the
    # scale cannot collapse; Levenberg-Marquardt from the start converges in a few dozen steps.
    import scipy.optimize

    from core.rotations import invRodrigues
    from solutions import rodriguesResidual

    n = len(p1)
    t0 = M2_init[:, 3]
    radius = np.linalg.norm(t0)
    direction = t0 / radius
    tangent = np.linalg.svd(direction[None, :])[2][1:].T

    def residuals(z):
        # z = [w, r2, two tangent coordinates of t]: the handout's x with t on its sphere.
        d = direction + tangent @ z[-2:]
        return rodriguesResidual(K1, M1, p1, K2, p2, np.concatenate([z[:3 * n + 3], radius * d / np.linalg.norm(d)]))

    z0 = np.concatenate([w_init.ravel(), invRodrigues(M2_init[:, :3]), np.zeros(2)])
    fit = scipy.optimize.least_squares(residuals, z0, method="lm")
    return float(np.sum(fit.fun ** 2))


def _bundle_problem(label, scene, count, rng) -> BAProblem:
    """A problem of the hidden scene (``_draw_problem``) that the reference solves: the handout
    fixes no gauge, and on a few draws its bundle adjustment lets the scene drift away from the
    start's shape; such a draw would fail every right answer, so the next one is taken (each
    submission has its own draw: every draw must be fair).  Up to ``_TRIES`` draws."""
    for _ in range(_TRIES):
        problem, solved = _draw_problem(label, scene, count, rng)
        if solved:
            break
    return problem


def _draw_problem(label, scene, count, rng) -> tuple[BAProblem, bool]:
    """The points of a hidden scene seen from a second camera swung further round (well
    conditioned), 0.5 px of noise; the start 1-2 degrees and 5 degrees off, |t| = 1 as findM2 gives.
    Also whether the reference's result passes the hidden check (``judging.bundle.result``)."""
    from solutions import bundleAdjustment, triangulate

    idx = np.sort(rng.choice(len(scene.X), size=min(count, len(scene.X)), replace=False))
    X = scene.X[idx]
    centre = X.mean(axis=0)
    axis = np.array([rng.normal(), rng.normal(), 0.2 * rng.normal()])
    R = _rotation(axis, _SWING_DEG)
    t = centre - R @ centre                     # turns the world about the points' centre
    K1, K2 = scene.K1, scene.K2
    p1 = project(K1 @ M1, X) + _NOISE_PX * rng.normal(size=(len(X), 2))
    p2 = project(K2 @ np.hstack([R, t[:, None]]), X) + _NOISE_PX * rng.normal(size=(len(X), 2))
    R0 = _rotation(rng.normal(size=3), 2.0) @ R
    t0 = _rotation(rng.normal(size=3), 5.0) @ (t / np.linalg.norm(t))
    M2_init = np.hstack([R0, t0[:, None]])
    w_init, _ = triangulate(K1 @ M1, p1, K2 @ M2_init, p2)
    optimum = _gauge_fixed_optimum(K1, K2, p1, p2, M2_init, w_init)
    M2_ref, w_ref, _, _ = bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init)
    if np.linalg.norm(M2_ref[:, 3]) >= 0.5 * np.linalg.norm(M2_init[:, 3]):  # a collapsed optimum is no goal
        optimum = min(optimum, total_error(K1, K2, p1, p2, M2_ref, w_ref))
    solved = result(M2_ref, w_ref, K1, K2, p1, p2, M2_init, w_init, optimum).passed
    return BAProblem(label, K1, K2, p1, p2, M2_init, w_init, optimum), solved


def _x_of(problem: BAProblem) -> np.ndarray:
    from core.rotations import invRodrigues

    return np.concatenate([problem.w_init.ravel(), invRodrigues(problem.M2_init[:, :3]), problem.M2_init[:, 3]])


def prepare_bundle(scenes: Scenes) -> Bundle:
    from solutions.expected import residual_case

    rng = np.random.default_rng(scenes.seed("bundle"))
    problems = tuple(_bundle_problem(tc.label, tc.scene, scenes.config.ba_points, rng) for tc in scenes.hidden[:2])
    inputs = []
    for k, pr in enumerate(problems):
        x = _x_of(pr)
        if k == 0:
            x = x + rng.normal(scale=0.01, size=x.shape)   # away from the start, where r2 matters too
        inputs.append(residual_case(pr.K1, M1, pr.p1, pr.K2, pr.p2, x))
    return Bundle(problems, tuple(inputs))
