"""The 12 car keypoints of problem 6 and the edges drawn between them.

The order is the one of the ``pts1``/``pts2``/``pts3`` rows in ``q6/time{t}.npz``: three layers
of four points, from the ground up (wheels, lights, roof), each layer listed front-left,
front-right, rear-left, rear-right.
"""

from __future__ import annotations

__all__ = ["CAR_KEYPOINTS", "CAR_SKELETON"]

CAR_KEYPOINTS: tuple[str, ...] = (
    "wheel front-left", "wheel front-right", "wheel rear-left", "wheel rear-right",
    "headlight left", "headlight right", "taillight left", "taillight right",
    "roof front-left", "roof front-right", "roof rear-left", "roof rear-right",
)

CAR_SKELETON: tuple[tuple[int, int], ...] = (
    # ground quad through the four wheels
    (0, 1), (1, 3), (3, 2), (2, 0),
    # light pairs
    (4, 5), (6, 7),
    # roof quad
    (8, 9), (9, 11), (11, 10), (10, 8),
    # pillars from the wheels through the lights to the roof
    (0, 4), (4, 8), (1, 5), (5, 9), (2, 6), (6, 10), (3, 7), (7, 11),
)
