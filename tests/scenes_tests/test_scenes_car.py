"""Tests of the synthetic problem-6 scene (scenes/car/, scenes/painter.py)."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest
from PIL import Image

from core.geometry import camera_center, depths, project
from core.paths import course_data_dir
from core.skeleton import CAR_KEYPOINTS
from scenes.car import (CONFIDENCE_LEVELS, car_keypoints, car_rotation, confidence_sigma, make_car_scene,
                        official_arrays, render_view, write_car)

OFFICIAL_NAMES = ["pts1", "pts2", "pts3", "M1", "M2", "M3", "K1", "K2", "K3"]
SEEDS = range(6)


@pytest.fixture(scope="module")
def scenes():
    return [make_car_scene(seed, render=False) for seed in SEEDS]


@pytest.fixture(scope="module")
def rendered():
    # two time steps keep the rendering cheap
    return make_car_scene(0, n_times=2)


def dlt(Cs: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Linear triangulation of one point from n views: Cs (n, 3, 4), xy (n, 2) -> X (3,)."""
    A = np.concatenate([[x * C[2] - C[0], y * C[2] - C[1]] for C, (x, y) in zip(Cs, xy)])
    X = np.linalg.svd(A)[2][-1]
    return X[:3] / X[3]


# ---------------------------------------------------------------- determinism and shapes

def test_same_seed_gives_the_same_scene_and_other_seeds_differ(scenes):
    again = make_car_scene(0, render=False)
    for name in ("K", "M", "pts", "P_true", "uv_true", "occluded"):
        np.testing.assert_array_equal(getattr(again, name), getattr(scenes[0], name))
    assert not np.array_equal(scenes[0].pts, scenes[1].pts)
    assert not np.allclose(scenes[0].M, scenes[1].M)


def test_rendering_does_not_change_the_data(rendered):
    plain = make_car_scene(0, n_times=2, render=False)
    np.testing.assert_array_equal(plain.pts, rendered.pts)
    np.testing.assert_array_equal(plain.M, rendered.M)
    assert plain.images is None


def test_shapes_dtypes_and_frozen_arrays(scenes):
    s = scenes[0]
    T = s.n_times
    assert T == 10
    assert s.K.shape == (T, 3, 3, 3) and s.M.shape == (T, 3, 3, 4)
    assert s.pts.shape == (T, 3, 12, 3) and s.pts.dtype == np.int64
    assert s.P_true.shape == (T, 12, 3) and s.uv_true.shape == (T, 3, 12, 2)
    assert s.occluded.shape == (T, 3, 12) and s.occluded.dtype == bool
    assert len(CAR_KEYPOINTS) == 12
    with pytest.raises(ValueError):
        s.pts[0, 0, 0, 0] = 5


def test_bad_arguments_name_themselves():
    with pytest.raises(ValueError, match="seed"):
        make_car_scene(-1)
    with pytest.raises(ValueError, match="n_times"):
        make_car_scene(0, n_times=0)
    with pytest.raises(ValueError, match="width"):
        make_car_scene(0, width=10.5)


# ---------------------------------------------------------------- geometry

def test_cameras_are_posed_rotations_that_move_a_little(scenes):
    for s in scenes:
        R = s.M[..., :3]
        np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-9)
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
        assert not np.allclose(s.M[..., :3], np.eye(3))
        centres = np.array([[camera_center(s.M[t, c]) for c in range(3)] for t in range(s.n_times)])
        drift = np.linalg.norm(centres - centres.mean(axis=0), axis=-1)
        assert 0 < drift.max() < 0.2  # hand-held, not moving around
        to_car = np.linalg.norm(centres[:, :, None] - s.car_position[:, None, None], axis=-1)
        assert 5 < to_car.min() and to_car.max() < 25
        assert np.all(centres[..., 1] < -1.5)  # above the ground (y points down)


def test_true_keypoints_project_inside_the_images_in_front_of_the_cameras(scenes):
    for s in scenes:
        for t in range(s.n_times):
            for c in range(3):
                M = s.M[t, c]
                assert np.all(depths(M, s.P_true[t]) > 1.0)
                np.testing.assert_allclose(project(s.C[t, c], s.P_true[t]), s.uv_true[t, c], atol=1e-8)
        uv = s.uv_true
        assert uv[..., 0].min() >= 0 and uv[..., 0].max() <= s.width - 1
        assert uv[..., 1].min() >= 0 and uv[..., 1].max() <= s.height - 1


def test_the_car_is_rigid_and_moves_through_the_intersection(scenes):
    kps = car_keypoints(scenes[0].model)
    d_model = np.linalg.norm(kps[:, None] - kps[None], axis=-1)
    for s in scenes:
        d = np.linalg.norm(s.P_true[:, :, None] - s.P_true[:, None], axis=-1)
        np.testing.assert_allclose(d, np.broadcast_to(d_model, d.shape), atol=1e-9)
        step = np.linalg.norm(np.diff(s.car_position, axis=0), axis=1)
        assert np.all(step > 0.5)
        assert np.linalg.norm(s.car_position.mean(axis=0)) < 4  # around the crossing


def test_hidden_wheel_hubs_are_the_ones_on_the_far_side(scenes):
    # The occlusion comes from a ray test against the body; a wheel hub (on the outer face of
    # its wheel) must be hidden exactly when the camera is on the other side of the car.
    half = scenes[0].model.width / 2 + scenes[0].model.wheel_protrusion
    for s in scenes:
        for t in range(s.n_times):
            R = car_rotation(s.car_heading[t])
            for c in range(3):
                lateral = (R.T @ (camera_center(s.M[t, c]) - s.car_position[t]))[1]
                for k, side in ((0, 1), (1, -1), (2, 1), (3, -1)):
                    assert s.occluded[t, c, k] == (side * lateral < half)
    # roof corners are seen from every camera above the roof
    assert not np.any(np.stack([s.occluded[:, :, 8:] for s in scenes]))


# ---------------------------------------------------------------- observations

def test_confidences_are_official_levels_and_hidden_points_score_low(scenes):
    conf = np.stack([s.pts[..., 2] for s in scenes])
    occ = np.stack([s.occluded for s in scenes])
    assert set(np.unique(conf)) <= set(CONFIDENCE_LEVELS)
    assert np.all(conf % 100 == 0) and conf.min() >= 300 and conf.max() <= 1100
    assert np.all(conf[occ] <= 500) and np.all(conf[~occ] >= 500)
    assert {300, 1100} <= set(np.unique(conf).tolist())


def test_noise_grows_as_confidence_falls(scenes):
    conf = np.concatenate([s.pts[..., 2].ravel() for s in scenes])
    err = np.concatenate([(s.pts[..., :2] - s.uv_true).reshape(-1, 2) for s in scenes])
    rms = {}
    for level in CONFIDENCE_LEVELS:
        e = err[conf == level]
        if len(e) >= 40:
            rms[level] = np.sqrt(np.mean(e ** 2))  # per axis
            # two-sided: the noise is the model's, rounding included, not less and not more
            expected = np.sqrt(confidence_sigma(level) ** 2 + 1 / 12)
            assert 0.75 * expected < rms[level] < 1.3 * expected, (level, rms[level], expected)
    assert len(rms) >= 7
    levels = sorted(rms)
    assert all(rms[a] > rms[b] for a, b in zip(levels, levels[1:]))


def test_threshold_changes_the_views_used(scenes):
    conf = np.stack([s.pts[..., 2] for s in scenes])
    used = [int(np.sum(conf >= thr)) for thr in range(300, 801, 100)]
    assert all(a > b for a, b in zip(used, used[1:])), used
    # at 600 some keypoints keep fewer than two views: the fallback question is real
    views = (conf >= 600).sum(axis=2)
    assert np.any(views < 2) and np.mean(views >= 2) > 0.4


def test_high_confidence_views_triangulate_better_than_all_views(scenes):
    err_high, err_all, err_any = [], [], []
    for s in scenes:
        for t in range(s.n_times):
            for k in range(12):
                conf = s.pts[t, :, k, 2]
                keep = np.flatnonzero(conf >= 600)
                xy = s.pts[t, :, k, :2].astype(float)
                if len(keep) >= 2:
                    e = np.linalg.norm(dlt(s.C[t, keep], xy[keep]) - s.P_true[t, k])
                    err_any.append(e)
                    if len(keep) < 3:  # a view was dropped: compare with keeping it
                        err_high.append(e)
                        err_all.append(np.linalg.norm(dlt(s.C[t], xy) - s.P_true[t, k]))
    assert len(err_high) > 50
    assert np.median(err_any) < 0.04  # metres
    assert np.mean(err_high) < 0.7 * np.mean(err_all)
    assert np.mean(err_all) > 0.03  # the low-confidence views really are bad


# ---------------------------------------------------------------- images

def test_images_are_full_size_rgb(rendered):
    assert len(rendered.images) == 3 and all(len(row) == 2 for row in rendered.images)
    for row in rendered.images:
        for im in row:
            assert im.shape == (1080, 1920, 3) and im.dtype == np.uint8
            assert im.std() > 20  # not a blank canvas


def test_the_car_is_drawn_at_its_keypoints(rendered):
    s = rendered
    for t in range(s.n_times):
        for c in range(3):
            sky = render_view(s, t, c, with_street=False, with_car=False)
            car_only = render_view(s, t, c, with_street=False, with_shadow=False)
            no_car = render_view(s, t, c, with_car=False)
            car_mask = np.any(car_only != sky, axis=-1)
            shows_car = np.any(np.abs(s.images[c][t].astype(int) - no_car) > 25, axis=-1)
            assert 0.01 < car_mask.mean() < 0.5
            for x, y in np.round(s.uv_true[t, c]).astype(int):
                window = (slice(y - 2, y + 3), slice(x - 2, x + 3))
                assert car_mask[window].mean() > 0.2
                assert shows_car[window].any()


# ---------------------------------------------------------------- files

def test_write_car_uses_exactly_the_official_layout(rendered, tmp_path):
    written = write_car(rendered, tmp_path)
    names = sorted(p.name for p in tmp_path.iterdir())
    expected = sorted([f"time{t}.npz" for t in range(2)] + [f"cam{c}_time{t}.jpg" for c in (1, 2, 3) for t in range(2)])
    assert names == expected and sorted(p.name for p in written) == expected
    for t in range(2):
        with zipfile.ZipFile(tmp_path / f"time{t}.npz") as z:
            assert [n[:-4] for n in z.namelist()] == OFFICIAL_NAMES
        data = np.load(tmp_path / f"time{t}.npz")
        for c in range(3):
            assert data[f"pts{c + 1}"].dtype == np.int64 and data[f"pts{c + 1}"].shape == (12, 3)
            assert data[f"M{c + 1}"].dtype == np.float64 and data[f"M{c + 1}"].shape == (3, 4)
            assert data[f"K{c + 1}"].dtype == np.float64 and data[f"K{c + 1}"].shape == (3, 3)
            np.testing.assert_array_equal(data[f"pts{c + 1}"], rendered.pts[t, c])
            np.testing.assert_array_equal(data[f"M{c + 1}"], rendered.M[t, c])
            with Image.open(tmp_path / f"cam{c + 1}_time{t}.jpg") as im:
                assert im.format == "JPEG" and im.mode == "RGB" and im.size == (1920, 1080)
                back = np.asarray(im).astype(int)
            assert np.mean(np.abs(back - rendered.images[c][t])) < 3  # JPEG close to the render


def test_write_car_without_images_writes_only_the_arrays(scenes, tmp_path):
    write_car(scenes[1], tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f"time{t}.npz" for t in range(10))


# ---------------------------------------------------------------- the official data

@pytest.mark.official
def test_values_match_the_official_files(scenes):
    root = course_data_dir()
    q6 = root / "q6" if root is not None else None
    if q6 is None or not (q6 / "time0.npz").exists():
        pytest.skip("official data not found (../shared/course-data/q6 or HW4_COURSE_DATA)")
    ours = official_arrays(scenes[0], 0)
    conf_theirs, focal_theirs = set(), []
    for t in range(10):
        theirs = np.load(q6 / f"time{t}.npz")
        assert list(theirs.keys()) == list(ours.keys())
        for name in OFFICIAL_NAMES:
            assert theirs[name].dtype == ours[name].dtype and theirs[name].shape == ours[name].shape, name
        for c in (1, 2, 3):
            conf_theirs |= set(theirs[f"pts{c}"][:, 2].tolist())
            focal_theirs.append(theirs[f"K{c}"][0, 0])
    conf_ours = set(np.unique(np.stack([s.pts[..., 2] for s in scenes])).tolist())
    assert conf_theirs <= set(CONFIDENCE_LEVELS) and conf_ours <= set(CONFIDENCE_LEVELS)
    assert min(conf_ours) == min(conf_theirs) and max(conf_ours) == max(conf_theirs)
    focal_ours = np.stack([s.K[..., 0, 0] for s in scenes])
    lo, hi = 0.9 * min(focal_theirs), 1.1 * max(focal_theirs)
    assert lo < focal_ours.min() and focal_ours.max() < hi
    with Image.open(q6 / "cam1_time0.jpg") as im:
        assert im.size == (scenes[0].width, scenes[0].height)
