"""Q3.2: the inputs of ``triangulate``: an exact scene and noisy ones, with the reference's linear error.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera; C = K M.  Nothing here
reaches a student.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scenes import Scenes
from .shared import M1, reference_F


@dataclass(frozen=True, eq=False)
class TriangulationCase:
    label: str
    C1: np.ndarray
    pts1: np.ndarray
    C2: np.ndarray
    pts2: np.ndarray
    M2: np.ndarray
    linear_err: float             # the reference's (linear) triangulation error (noisy cases)
    X: np.ndarray | None = None   # true points (exact case)


@dataclass(frozen=True, eq=False)
class Triangulation:
    exact: TriangulationCase
    noisy: tuple[TriangulationCase, ...]

    @property
    def all(self) -> tuple[TriangulationCase, ...]:
        return (self.exact, *self.noisy)


def prepare_triangulation(scenes: Scenes) -> Triangulation:
    from solutions import findM2, triangulate

    tv = scenes.two_view
    exact = TriangulationCase("noise-free matches", tv.C1, tv.pts1, tv.C2, tv.pts2, tv.M2, 0.0, tv.X)
    noisy = []
    for tc in [*scenes.hidden, *([scenes.official] if scenes.official else [])]:
        C1 = tc.K1 @ M1
        if tc.has_truth:
            M2 = tc.scene.M2
        else:
            M2 = findM2(reference_F(tc), tc.pts1, tc.pts2, tc.K1, tc.K2)[0]
        C2 = tc.K2 @ M2
        _, err = triangulate(C1, tc.pts1, C2, tc.pts2)
        noisy.append(TriangulationCase(tc.label, C1, tc.pts1, C2, tc.pts2, M2, err))
    return Triangulation(exact, tuple(noisy))
