"""Loading the homework's data: the temple pair (problems 2-5) and the car frames (problem 6).

The layout is the official one, so an instructor can drop the course files in place of the kit's:

    <root>/temple/im1.png, im2.png, intrinsics.npz (K1, K2), some_corresp.npz (pts1, pts2),
                  some_corresp_noisy.npz (pts1, pts2), templeCoords.npz (x1, y1)
    <root>/q6/cam{1,2,3}_time{t}.jpg, time{t}.npz (pts1..pts3: N x 3 [x, y, confidence], K1..K3, M1..M3)

A folder holding the temple files directly (no temple/ level) works too.  ``root`` defaults to
$HW4_DATA when set, else the kit's own data/ folder.  Every integer point array is cast to
float64 on loading: the official files are uint16, where 54 - 55 is 65535.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from core.geometry import eightpoint_scale
from core.paths import data_root

__all__ = ["data_root", "TempleData", "CarFrame", "load_temple", "load_car_frame", "car_times", "load_image",
           "course_image"]

def _temple_dir(root: Path) -> Path:
    for cand in (root / "temple", root):
        if (cand / "im1.png").exists() or (cand / "some_corresp.npz").exists():
            return cand
    raise FileNotFoundError(
        f"no temple data under {root}: expected {root}/temple/im1.png (official layout) or {root}/im1.png")


def course_image(im) -> np.ndarray:
    """An 8-bit image (H, W[, C]) as the course's notebooks read its PNG (``plt.imread``): float32 in [0, 1]."""
    return np.asarray(im, dtype=np.float32) / np.float32(255)


def load_image(path: str | os.PathLike) -> np.ndarray:
    """An image file as uint8 RGB, shape (H, W, 3)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"missing image {path}")
    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"))
    except OSError as exc:
        raise ValueError(f"{path}: not a readable image ({exc})") from None


def _load_npz(path: Path, names: dict[str, tuple]) -> dict[str, np.ndarray]:
    """Read the arrays ``names`` (name -> expected shape, -1 for any length) from an .npz."""
    if not path.exists():
        raise FileNotFoundError(f"missing data file {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in names if k not in z.files]
            if missing:
                raise ValueError(f"{path.name}: expected arrays {list(names)}, missing {missing} (has {z.files})")
            out = {k: z[k] for k in names}
    except (OSError, ValueError) as exc:
        if isinstance(exc, ValueError) and path.name in str(exc):
            raise
        raise ValueError(f"{path}: not a readable .npz of arrays ({exc})") from None
    for k, shape in names.items():
        a = out[k]
        ok = a.ndim == len(shape) and all(s == -1 or s == d for s, d in zip(shape, a.shape))
        if not ok or not np.issubdtype(a.dtype, np.number):
            want = "x".join("N" if s == -1 else str(s) for s in shape)
            raise ValueError(f"{path.name}: array {k} should be numeric of shape {want}, got {a.shape} {a.dtype}")
        out[k] = a.astype(np.float64)
        if not np.all(np.isfinite(out[k])):
            raise ValueError(f"{path.name}: array {k} holds NaN or inf")
    return out


@dataclass(frozen=True)
class TempleData:
    """The temple pair.  Images are uint8 RGB (H, W, 3); points are float64 pixels (x, y) = (column, row).

    pts1, pts2 : (110, 2) hand-picked matches (some_corresp).
    noisy_pts1, noisy_pts2 : (140, 2) matches of which some are wrong (some_corresp_noisy).
    x1, y1 : (288,) the templeCoords points of image 1.
    K1, K2 : (3, 3) intrinsics.
    """

    im1: np.ndarray
    im2: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    pts1: np.ndarray
    pts2: np.ndarray
    noisy_pts1: np.ndarray
    noisy_pts2: np.ndarray
    x1: np.ndarray
    y1: np.ndarray
    folder: Path

    @property
    def M(self) -> float:
        """The eight-point scale: the larger of the image's width and height (``core.geometry.eightpoint_scale``)."""
        return eightpoint_scale(self.im1.shape[1], self.im1.shape[0])


def load_temple(root: str | os.PathLike | None = None) -> TempleData:
    """Load and validate the temple pair from ``root`` (see the module docstring for the layout)."""
    folder = _temple_dir(data_root(root))
    im1, im2 = load_image(folder / "im1.png"), load_image(folder / "im2.png")
    if im1.shape != im2.shape:
        raise ValueError(f"im1.png is {im1.shape[1]}x{im1.shape[0]} but im2.png is {im2.shape[1]}x{im2.shape[0]}")
    K = _load_npz(folder / "intrinsics.npz", {"K1": (3, 3), "K2": (3, 3)})
    c = _load_npz(folder / "some_corresp.npz", {"pts1": (-1, 2), "pts2": (-1, 2)})
    n = _load_npz(folder / "some_corresp_noisy.npz", {"pts1": (-1, 2), "pts2": (-1, 2)})
    t = _load_npz(folder / "templeCoords.npz", {"x1": (-1, 1), "y1": (-1, 1)})
    for name, d in (("some_corresp", c), ("some_corresp_noisy", n)):
        if len(d["pts1"]) != len(d["pts2"]):
            raise ValueError(f"{name}.npz: pts1 has {len(d['pts1'])} rows but pts2 has {len(d['pts2'])}")
    if len(t["x1"]) != len(t["y1"]):
        raise ValueError(f"templeCoords.npz: x1 has {len(t['x1'])} rows but y1 has {len(t['y1'])}")
    return TempleData(im1, im2, K["K1"], K["K2"], c["pts1"], c["pts2"], n["pts1"], n["pts2"],
                      t["x1"].ravel(), t["y1"].ravel(), folder)


@dataclass(frozen=True)
class CarFrame:
    """One time step of problem 6, for the three cameras i = 0, 1, 2 (files' 1, 2, 3).

    images : three uint8 RGB images (H, W, 3).
    pts : three (12, 3) float64 arrays [x, y, confidence] of keypoints in pixels.
    K : three (3, 3) intrinsics; M : three (3, 4) extrinsics [R | t], world -> camera;
    C : three (3, 4) projection matrices K M.
    """

    time: int
    images: tuple
    pts: tuple
    K: tuple
    M: tuple

    @property
    def C(self) -> tuple:
        return tuple(k @ m for k, m in zip(self.K, self.M))


def car_times(root: str | os.PathLike | None = None) -> list[int]:
    """The time steps t for which <root>/q6/time{t}.npz exists, sorted."""
    q6 = data_root(root) / "q6"
    times = sorted(int(p.stem[4:]) for p in q6.glob("time*.npz") if p.stem[4:].isdigit())
    if not times:
        raise FileNotFoundError(f"no car data: expected {q6}/time0.npz ...")
    return times


def load_car_frame(t: int, root: str | os.PathLike | None = None, *, images: bool = True) -> CarFrame:
    """Load time step ``t`` of the car sequence; ``images=False`` skips the JPEGs (faster)."""
    q6 = data_root(root) / "q6"
    names = {f"pts{i}": (-1, 3) for i in (1, 2, 3)}
    names.update({f"K{i}": (3, 3) for i in (1, 2, 3)})
    names.update({f"M{i}": (3, 4) for i in (1, 2, 3)})
    d = _load_npz(q6 / f"time{int(t)}.npz", names)
    ims = tuple(load_image(q6 / f"cam{i}_time{int(t)}.jpg") for i in (1, 2, 3)) if images else ()
    return CarFrame(int(t), ims, tuple(d[f"pts{i}"] for i in (1, 2, 3)),
                    tuple(d[f"K{i}"] for i in (1, 2, 3)), tuple(d[f"M{i}"] for i in (1, 2, 3)))
