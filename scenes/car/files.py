"""Writing a scene in the official ``data/q6`` layout."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from .model import N_CAMERAS
from .scene import CarScene

# --------------------------------------------------------------------------------------------
# The official file layout
# --------------------------------------------------------------------------------------------

def official_arrays(scene: CarScene, t: int) -> dict[str, np.ndarray]:
    """The arrays of ``time{t}.npz`` in the official order and dtypes.

    Returns
    -------
    dict
        ``pts1..3`` int64 (12, 3) [x, y, confidence]; ``M1..3`` float64 (3, 4); ``K1..3``
        float64 (3, 3).
    """
    out = {}
    for c in range(N_CAMERAS):
        out[f"pts{c + 1}"] = np.array(scene.pts[t, c], dtype=np.int64)
    for c in range(N_CAMERAS):
        out[f"M{c + 1}"] = np.array(scene.M[t, c], dtype=np.float64)
    for c in range(N_CAMERAS):
        out[f"K{c + 1}"] = np.array(scene.K[t, c], dtype=np.float64)
    return out


def write_car(scene: CarScene, folder, *, quality: int = 90) -> list[Path]:
    """Write ``scene`` in the official ``q6`` layout; return the paths written.

    Writes ``time{t}.npz`` (``official_arrays``, uncompressed like the official files) and,
    when the scene has images, ``cam{c}_time{t}.jpg`` (c = 1..3).  No ground truth is written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for t in range(scene.n_times):
        path = folder / f"time{t}.npz"
        np.savez(path, **official_arrays(scene, t))
        written.append(path)
        if scene.images is not None:
            for c in range(N_CAMERAS):
                path = folder / f"cam{c + 1}_time{t}.jpg"
                Image.fromarray(scene.images[c][t]).save(path, quality=quality)
                written.append(path)
    return written
