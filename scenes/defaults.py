"""The kit's default data: which seeds make data/, and how to write it.

data/ is committed so that a fresh clone (and Colab) has data without running the generator;
tests/test_default_data.py proves it is exactly what these functions make.  The ground truth of
the same scenes comes from :func:`default_temple` and :func:`default_car`, never from data/.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

__all__ = ["TEMPLE_SEED", "CAR_SEED", "default_temple", "default_car", "write_default_data", "DATA_DIR"]

TEMPLE_SEED = 0
CAR_SEED = 0
DATA_DIR = Path(__file__).resolve().parents[1] / "data"


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
