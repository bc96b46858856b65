"""The kit's default data: which seeds make data/, and how to write it.

data/ is committed so that a fresh clone (and Colab) has data without running the generator;
tests/scenes_tests/test_default_data.py proves it is exactly what these functions make.  The ground truth of
the same scenes comes from :func:`default_temple` and :func:`default_car`, never from data/.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from core.paths import DATA_DIR

__all__ = ["TEMPLE_SEED", "CAR_SEED", "default_temple", "default_car", "write_default_data"]

# The temple seed is chosen, not arbitrary: the linear eight-point figures are a lottery on the
# stored points' rounding (seeds 0-74 give reprojection errors of 94 to 11600 without refineF,
# the official data 89.44; the two below 179, seeds 49 and 64, miss the eight-point and shape
# limits against the ground truth), so TEMPLE_SEED is the first seed from 0 upward whose scene gives
# figures like the official data's and passes tests/scenes_tests/test_generated_scenes.py: the criterion is
# kit.default_seed.CRITERION (reprojection error without refineF within a factor 2 of 89.44, a
# transposed F at least 10 times worse, RANSAC 100-125 of 140 at 1 px, bundle adjustment to 8-12,
# the eight-point and bundle-adjustment limits against the ground truth).  Reproduce the choice
# with `python -m kit.default_seed` (it prints each seed's figures and stops at the first that
# qualifies); tests/scenes_tests/test_generated_scenes.py checks that this seed meets the criterion.  Seed 75,
# chosen after camera 2's toe (scenes.temple._poses) changed every scene; seed 0 before it.
TEMPLE_SEED = 75
CAR_SEED = 0


@lru_cache(maxsize=1)
def default_temple():
    """The TempleScene behind data/temple (images and ground truth)."""
    from .temple import make_temple_scene

    return make_temple_scene(TEMPLE_SEED)


@lru_cache(maxsize=2)
def default_car(render: bool = True):
    """The CarScene behind data/q6; ``render=False`` skips the images (same arrays)."""
    from .car import make_car_scene

    return make_car_scene(CAR_SEED, render=render)


def write_default_data(out: str | Path | None = None) -> list[Path]:
    """Write the default data in the official layout: <out>/temple/... and <out>/q6/...; return the files."""
    from .car import write_car
    from .temple import write_temple

    out = Path(out) if out is not None else DATA_DIR
    (out / "temple").mkdir(parents=True, exist_ok=True)
    (out / "q6").mkdir(parents=True, exist_ok=True)
    write_temple(default_temple(), out / "temple")
    write_car(default_car(), out / "q6")
    return sorted(p for p in out.rglob("*") if p.is_file())
