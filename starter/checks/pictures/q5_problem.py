"""Q5's public problem and the recording of the objective a student's bundleAdjustment evaluates.

The problem: the first N_POINTS matches of the default data (some_corresp, pixels (x, y)), camera
1 = K1 [I | 0], and a start moved away from the truth (camera 2 turned by 2 degrees, its t by 3,
each point by 2 % of its depth; a numpy Generator with a fixed seed), so that a working bundle
adjustment visibly lowers the error.  Both sides build the same problem (it needs the scene's
truth, so the default data only).

The recording: while bundleAdjustment runs, the ``rodriguesResidual`` its code calls (the global
of that name its module sees, as in a notebook) is replaced by a wrapper that records the sum
of squares of each residual vector returned, and scipy.optimize's least_squares, minimize and
leastsq record each value of the objective they are given (for code whose objective does not call
rodriguesResidual by that name); the originals are always put back.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

__all__ = ["N_POINTS", "Problem", "problem", "recording", "start_x"]

N_POINTS = 20
SEED = 2024


@dataclass(frozen=True, eq=False)
class Problem:
    """K1, K2 (3, 3); M1 (3, 4) = [I | 0]; p1, p2 (N, 2) pixels; M2_init (3, 4) [R | t]; w_init (N, 3)."""

    K1: np.ndarray
    K2: np.ndarray
    M1: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    M2_init: np.ndarray
    w_init: np.ndarray


def _turn(v, degrees, rng):
    from starter.rotations import rodrigues

    axis = np.cross(v, rng.normal(size=3)) if v is not None else rng.normal(size=3)
    return rodrigues(np.deg2rad(degrees) * axis / np.linalg.norm(axis))


def problem(scene, data) -> Problem:
    """The public problem of the default data (``scene`` its TempleScene, ``data`` its TempleData)."""
    rng = np.random.default_rng(SEED)
    n = N_POINTS
    R0 = _turn(None, 2.0, rng) @ scene.M2[:, :3]
    t0 = _turn(scene.M2[:, 3], 3.0, rng) @ scene.M2[:, 3]
    X = np.asarray(scene.X[:n], float)
    w0 = X + rng.normal(0.0, 0.02 / np.sqrt(3), (n, 3)) * np.linalg.norm(X, axis=1, keepdims=True)
    M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    return Problem(np.array(data.K1, float), np.array(data.K2, float), M1, np.array(data.pts1[:n], float),
                   np.array(data.pts2[:n], float), np.hstack([R0, t0[:, None]]), w0)


def start_x(pr: Problem) -> np.ndarray:
    """The start as rodriguesResidual's x (3N + 6,) = [w_init.ravel(), r2, t2] of M2_init."""
    from starter.rotations import invRodrigues

    return np.concatenate([pr.w_init.ravel(), invRodrigues(pr.M2_init[:, :3]), pr.M2_init[:, 3]])


def _sum_of_squares(value) -> float:
    try:
        return float(np.sum(np.asarray(value, dtype=float) ** 2))
    except (TypeError, ValueError):
        return float("nan")


def _objective_value(value) -> float:
    """A scalar objective as it is; a residual vector as its sum of squares."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return float("nan")
    return float(a.reshape(())) if a.size == 1 else float(np.sum(a ** 2))


_OPTIMISERS = ("least_squares", "minimize", "leastsq")


@contextmanager
def recording(fn, name: str = "rodriguesResidual"):
    """Within the block, record what ``fn``'s code evaluates; yields {"residual": [...], "optimiser": [...]}.

    "residual": the sum of squares of each value ``fn``'s global ``name`` (when callable) returns;
    "optimiser": each value of the objective given to scipy.optimize's least_squares, minimize or
    leastsq (a vector's sum of squares), whether reached as ``scipy.optimize.X`` or imported into
    ``fn``'s globals.  Everything replaced is put back, also when ``fn`` raises.
    """
    import scipy.optimize as so

    scope = getattr(fn, "__globals__", None)
    scope = scope if isinstance(scope, dict) else {}
    history: dict[str, list[float]] = {"residual": [], "optimiser": []}
    restore: list = []

    original = scope.get(name)
    if callable(original):
        def recorded(*args, **kwargs):
            value = original(*args, **kwargs)
            history["residual"].append(_sum_of_squares(value))
            return value

        recorded.__wrapped__ = original
        scope[name] = recorded
        restore.append((scope, name, original, recorded))

    def recording_optimiser(optimiser):
        def run(fun, *args, **kwargs):
            def objective(*a, **k):
                value = fun(*a, **k)
                history["optimiser"].append(_objective_value(value))
                return value

            return optimiser(objective, *args, **kwargs)

        run.__wrapped__ = optimiser
        return run

    for opt_name in _OPTIMISERS:
        opt = getattr(so, opt_name)
        wrapped = recording_optimiser(opt)
        setattr(so, opt_name, wrapped)
        restore.append((so.__dict__, opt_name, opt, wrapped))
        for key, value in list(scope.items()):
            if value is opt:
                scope[key] = wrapped
                restore.append((scope, key, opt, wrapped))
    try:
        yield history
    finally:
        for where, key, old, new in reversed(restore):
            if where.get(key) is new:
                where[key] = old
