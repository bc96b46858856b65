"""data/ is exactly what the seeded generator makes, in the official format."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from core.paths import DATA_DIR
from scenes.defaults import write_default_data
from starter import car_times, load_car_frame, load_temple
from starter.data import load_image

OFFICIAL_ARRAYS = {
    "temple/intrinsics.npz": {"K1": ((3, 3), "float64"), "K2": ((3, 3), "float64")},
    "temple/some_corresp.npz": {"pts1": ((None, 2), "uint16"), "pts2": ((None, 2), "uint16")},
    "temple/some_corresp_noisy.npz": {"pts1": ((None, 2), "uint16"), "pts2": ((None, 2), "uint16")},
    "temple/templeCoords.npz": {"x1": ((None, 1), "uint16"), "y1": ((None, 1), "uint16")},
}


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("data")
    write_default_data(out)
    return out


def _files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() and p.name != "README.md")


def test_data_holds_exactly_the_generated_files(regenerated):
    assert _files(DATA_DIR) == _files(regenerated)


def test_arrays_are_identical(regenerated):
    for name in _files(regenerated):
        if name.endswith(".npz"):
            with np.load(DATA_DIR / name) as a, np.load(regenerated / name) as b:
                assert a.files == b.files, name
                for k in a.files:
                    assert a[k].dtype == b[k].dtype, (name, k)
                    if a[k].dtype.kind == "f":
                        # Camera matrices pass through BLAS, whose last bit differs between CPUs.
                        np.testing.assert_allclose(a[k], b[k], rtol=1e-12, atol=1e-12, err_msg=f"{name}:{k}")
                    else:
                        np.testing.assert_array_equal(a[k], b[k], err_msg=f"{name}:{k}")


def test_images_are_identical(regenerated):
    images = [name for name in _files(regenerated) if name.endswith((".png", ".jpg"))]
    assert len(images) >= 2, images  # the temple's pair at least
    for name in images:
        if (DATA_DIR / name).read_bytes() == (regenerated / name).read_bytes():
            continue  # the same file: the same pixels, without decoding both (about 2 s for all)
        if name.endswith(".png"):
            np.testing.assert_array_equal(load_image(DATA_DIR / name), load_image(regenerated / name), err_msg=name)
        elif name.endswith(".jpg"):
            # JPEG decoders may differ by a grey level between library builds, not more.
            a = load_image(DATA_DIR / name).astype(int)
            b = load_image(regenerated / name).astype(int)
            assert a.shape == b.shape and np.abs(a - b).max() <= 2, name


def test_official_names_dtypes_and_shapes():
    for name, arrays in OFFICIAL_ARRAYS.items():
        with np.load(DATA_DIR / name) as z:
            assert sorted(z.files) == sorted(arrays), name
            for k, (shape, dtype) in arrays.items():
                assert str(z[k].dtype) == dtype and z[k].ndim == len(shape), (name, k)
                assert all(s is None or s == d for s, d in zip(shape, z[k].shape)), (name, k)
    for t in range(10):
        with np.load(DATA_DIR / "q6" / f"time{t}.npz") as z:
            assert sorted(z.files) == sorted([f"{p}{i}" for p in ("pts", "K", "M") for i in (1, 2, 3)])
            assert z["pts1"].dtype == np.int64 and z["pts1"].shape == (12, 3)
            assert z["M2"].shape == (3, 4) and z["K3"].shape == (3, 3)


def test_the_loaders_read_the_default_data():
    d = load_temple()
    assert d.im1.shape == (480, 640, 3) and d.M == 640
    assert len(d.pts1) == 110 and len(d.noisy_pts1) == 140 and len(d.x1) == 288
    assert car_times() == list(range(10))
    f = load_car_frame(3)
    assert f.images[2].shape == (1080, 1920, 3)
    assert set(np.unique(np.concatenate([p[:, 2] for p in f.pts]))) <= set(range(300, 1101, 100))


def test_no_ground_truth_in_data():
    names = " ".join(_files(DATA_DIR)).lower()
    for word in ("true", "truth", "gt", "inlier", "mask", "scene"):
        assert word not in names
