"""Q3.1: the inputs of ``essentialMatrix``: random rank-2 F's with random K1 != K2, and an exact scene's true F.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scenes import Scenes


@dataclass(frozen=True, eq=False)
class Essential:
    inputs: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]   # (F, K1, K2): random rank-2 F's
    true_F: tuple[np.ndarray, np.ndarray, np.ndarray]               # (F, K1, K2) of an exact scene


def _random_K(rng) -> np.ndarray:
    f = rng.uniform(300, 2000)
    return np.array([[f, rng.uniform(-2, 2), rng.uniform(150, 500)],
                     [0.0, f * rng.uniform(0.95, 1.05), rng.uniform(100, 400)],
                     [0.0, 0.0, 1.0]])


def _random_F(rng) -> np.ndarray:
    U = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    V = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    F = U @ np.diag([1.0, rng.uniform(0.2, 0.9), 0.0]) @ V.T
    return F / np.linalg.norm(F)


def prepare_essential(scenes: Scenes) -> Essential:
    """Three random rank-2 F's with random K1 != K2 (swapped, missing or inverted K's all show) and
    the true F of an exact two-view scene."""
    rng = np.random.default_rng(scenes.seed("essential") % 2**63)
    inputs = tuple((_random_F(rng), _random_K(rng), _random_K(rng)) for _ in range(3))
    tv = scenes.two_view
    return Essential(inputs, (tv.F, tv.K1, tv.K2))
