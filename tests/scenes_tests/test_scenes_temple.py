"""Tests of the synthetic TEMPLE scene generator (scenes/temple.py) and its ray caster
(scenes/render.py).

Most tests run on small scenes (320x240 or less); the default 640x480 scene is made once
for the checks that are about the default data itself (disparities like the official pair's,
window matching).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from PIL import Image

from core.geometry import IDENTITY_POSE, depths, epipolar_distances, homogeneous, project
from scenes.cameras import intrinsics, rotation_about
from scenes.render import (
    Cylinder,
    SolidTexture,
    box,
    cast_rays,
    pixel_rays,
    render_gbuffer,
    shade,
    visible_from,
    wedge,
)
from scenes.temple import TempleScene, make_temple_scene, write_temple

OFFICIAL_LAYOUT = {
    "intrinsics.npz": {"K1": (np.float64, (3, 3)), "K2": (np.float64, (3, 3))},
    "some_corresp.npz": {"pts1": (np.uint16, (110, 2)), "pts2": (np.uint16, (110, 2))},
    "some_corresp_noisy.npz": {"pts1": (np.uint16, (140, 2)), "pts2": (np.uint16, (140, 2))},
    "templeCoords.npz": {"x1": (np.uint16, (288, 1)), "y1": (np.uint16, (288, 1))},
}
MARGIN = 10  # pixels every stored point keeps from the image border
TINY = dict(width=200, height=160, n_corresp=24, n_outliers=8, n_coords=40)
SMALL = dict(width=320, height=240)


# ----------------------------------------------------------------------------- helpers

def ssd_along_line(im1, im2, F, x1, y1, half=7, search=40):
    """Plain SSD matching of a (2 half + 1)^2 RGB window: for each (x1, y1), the candidates
    are the pixels of the line F x1 (one per row, the line being near vertical) within
    ``search`` rows of y1.  Returns the best candidates (N, 2)."""
    a1 = im1.astype(float)
    a2 = im2.astype(float)
    H, W = a2.shape[:2]
    du, dv = np.meshgrid(np.arange(-half, half + 1), np.arange(-half, half + 1))
    out = np.full((len(x1), 2), np.nan)
    for i, (x, y) in enumerate(zip(x1, y1)):
        a, b, c = F @ [x, y, 1.0]
        rows = np.arange(max(half, y - search), min(H - half, y + search + 1))
        cols = np.rint(-(b * rows + c) / a).astype(int)
        ok = (cols >= half) & (cols < W - half)
        rows, cols = rows[ok], cols[ok]
        patch = a1[y - half:y + half + 1, x - half:x + half + 1]
        windows = a2[rows[:, None, None] + dv, cols[:, None, None] + du]  # (n, 15, 15, 3)
        k = np.argmin(np.sum((windows - patch) ** 2, axis=(1, 2, 3)))
        out[i] = cols[k], rows[k]
    return out


def disparity_stats(pts1, pts2):
    d = np.asarray(pts2, float) - np.asarray(pts1, float)  # cast first: uint16 wraps around
    return d.mean(axis=0), d.std(axis=0), d.min(axis=0), d.max(axis=0)


# ----------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="module")
def small() -> TempleScene:
    return make_temple_scene(1, **SMALL)


@pytest.fixture(scope="module")
def default() -> TempleScene:
    return make_temple_scene()


# ----------------------------------------------------------------------------- determinism

def test_same_seed_gives_bit_identical_scene_and_files(tmp_path):
    a = make_temple_scene(5, **TINY)
    b = make_temple_scene(5, **TINY)
    for f in dataclasses.fields(TempleScene):
        va, vb = getattr(a, f.name), getattr(b, f.name)
        if isinstance(va, np.ndarray):
            assert va.dtype == vb.dtype and np.array_equal(va, vb), f.name
    write_temple(a, tmp_path / "a")
    write_temple(b, tmp_path / "b")
    for name in ["im1.png", "im2.png", *OFFICIAL_LAYOUT]:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name


def test_different_seeds_give_different_scenes():
    a = make_temple_scene(1, **TINY)
    b = make_temple_scene(2, **TINY)
    assert not np.allclose(a.M2, b.M2)
    assert np.mean(a.im1 != b.im1) > 0.3
    assert not np.array_equal(a.pts1, b.pts1)


def test_more_points_leave_the_images_unchanged():
    a = make_temple_scene(4, **TINY)
    b = make_temple_scene(4, **{**TINY, "n_corresp": 30, "n_coords": 50})
    assert np.array_equal(a.im1, b.im1) and np.array_equal(a.im2, b.im2)
    assert np.array_equal(a.M2, b.M2)
    assert len(b.pts1) == 30 and len(b.x1) == 50


def test_zero_jitter_gives_the_nominal_pose_for_every_seed():
    a = make_temple_scene(1, jitter=0.0, **TINY)
    b = make_temple_scene(2, jitter=0.0, **TINY)
    assert np.allclose(a.M2, b.M2)
    assert not np.array_equal(a.im1, b.im1)  # the texture still follows the seed


def test_scene_arrays_are_read_only(small):
    with pytest.raises(ValueError):
        small.pts1[0, 0] = 0
    assert not small.im1.flags.writeable


# ----------------------------------------------------------------------------- file format

def test_write_temple_gives_exactly_the_official_layout(tmp_path, default):
    write_temple(default, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["im1.png", "im2.png", *OFFICIAL_LAYOUT])
    for file, arrays in OFFICIAL_LAYOUT.items():
        with np.load(tmp_path / file) as data:
            assert sorted(data.files) == sorted(arrays), file
            for name, (dtype, shape) in arrays.items():
                assert data[name].dtype == dtype and data[name].shape == shape, (file, name)
    for name, im in [("im1.png", default.im1), ("im2.png", default.im2)]:
        with Image.open(tmp_path / name) as png:
            assert png.format == "PNG" and png.mode == "RGB" and png.size == (640, 480)
            assert np.array_equal(np.asarray(png), im)
    with np.load(tmp_path / "some_corresp_noisy.npz") as data:
        assert np.array_equal(data["pts1"], default.pts1_noisy)
        assert np.array_equal(data["pts2"], default.pts2_noisy)
    with np.load(tmp_path / "intrinsics.npz") as data:
        assert np.array_equal(data["K1"], default.K1) and np.array_equal(data["K2"], default.K2)


def test_write_temple_rejects_other_objects(tmp_path):
    with pytest.raises(ValueError, match="scene"):
        write_temple({"im1": np.zeros((4, 4, 3))}, tmp_path)


@pytest.mark.parametrize("kwargs, name", [
    ({"width": 50}, "width"),
    ({"height": 3.5}, "height"),
    ({"n_corresp": 7}, "n_corresp"),
    ({"n_outliers": -1}, "n_outliers"),
    ({"noise_px": -0.1}, "noise_px"),
    ({"epipolar_outliers": 1.5}, "epipolar_outliers"),
    ({"baseline_deg": 0.0}, "baseline_deg"),
    ({"focal": -3.0}, "focal"),
    ({"seed": -1}, "seed"),
    ({"supersample": 0}, "supersample"),
])
def test_bad_arguments_raise_value_errors_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        make_temple_scene(**kwargs)


# ----------------------------------------------------------------------------- geometry

def test_cameras_and_true_matrices_are_consistent(small):
    assert np.array_equal(small.M1, IDENTITY_POSE)
    R, t = small.R, small.t
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(R), 1.0)
    # E = [t]x R, checked through np.cross rather than core.geometry.skew, which E_true uses.
    w = np.random.default_rng(0).normal(size=(3, 5))
    assert np.allclose(small.E_true @ w, np.cross(t, (R @ w).T).T)
    sv = np.linalg.svd(small.E_true, compute_uv=False)
    assert np.isclose(sv[0], sv[1]) and sv[2] < 1e-12 * sv[0]
    F = small.F_true
    assert np.isclose(np.linalg.norm(F), 1.0) and np.linalg.svd(F, compute_uv=False)[2] < 1e-12
    F_from_E = np.linalg.inv(small.K2).T @ small.E_true @ np.linalg.inv(small.K1)
    assert np.allclose(F, F_from_E / np.linalg.norm(F_from_E))
    assert np.allclose(small.C2, small.K2 @ small.M2)
    pair = small.pair
    assert np.array_equal(pair.F, F) and np.array_equal(pair.E, small.E_true)
    assert np.allclose(pair.C1, small.C1) and np.allclose(pair.C2, small.C2)
    assert np.allclose(pair.pts1, small.pts1_true, atol=1e-6) and np.allclose(pair.pts2, small.pts2_true, atol=1e-6)


def test_true_points_project_exactly_and_satisfy_the_true_F(small):
    assert np.allclose(project(small.C1, small.X), small.pts1_true, atol=1e-6)
    assert np.allclose(project(small.C2, small.X), small.pts2_true, atol=1e-6)
    assert epipolar_distances(small.F_true, small.pts1_true, small.pts2_true).max() < 1e-6
    x2 = np.stack([small.x1[:, 0], small.y1[:, 0]], axis=1).astype(float)
    assert np.allclose(project(small.C1, small.X_coords), x2, atol=1e-6)
    assert np.allclose(project(small.C2, small.X_coords), small.x2_true, atol=1e-6)


@pytest.mark.parametrize("noise_px", [0.0, 0.5])
def test_stored_points_are_the_true_ones_plus_noise_rounded(noise_px):
    scene = make_temple_scene(3, noise_px=noise_px, **SMALL)
    for stored, true in [(scene.pts1, scene.pts1_true), (scene.pts2, scene.pts2_true)]:
        assert stored.dtype == np.uint16 and np.array_equal(stored, np.rint(stored))
        err = stored.astype(float) - true
        assert np.abs(err).max() <= 0.5 + 5 * noise_px + 1e-9
        # Two-sided: the noise is really there, at the asked level (rounding adds 1/12).
        expected = np.sqrt(noise_px**2 + 1 / 12)
        assert 0.75 * expected < err.std() < 1.25 * expected


def test_correspondences_are_visible_and_clear_of_the_border(small):
    for M in (small.M1, small.M2):
        assert np.all(depths(M, small.X) > 0)
        assert np.all(visible_from(small.primitives, M, small.X))
    W, H = small.width, small.height
    for pts in (small.pts1, small.pts2, small.pts1_noisy, small.pts2_noisy):
        p = pts.astype(int)
        assert p[:, 0].min() >= MARGIN and p[:, 0].max() <= W - 1 - MARGIN
        assert p[:, 1].min() >= MARGIN and p[:, 1].max() <= H - 1 - MARGIN


def test_temple_coords_are_spread_over_the_temple_and_mostly_visible(small):
    assert small.x1.shape == small.y1.shape == (288, 1) and small.x1.dtype == np.uint16
    xy = np.stack([small.x1[:, 0], small.y1[:, 0]], axis=1).astype(float)
    assert len(np.unique(xy, axis=0)) == len(xy)
    # On the lit temple, not on the dark backdrop.
    grey = small.im1.astype(float).mean(axis=2)
    assert np.percentile(grey[xy[:, 1].astype(int), xy[:, 0].astype(int)], 5) > 80
    # Spread like hand-picked points: they span most of where the temple is.
    on_temple = np.argwhere(grey > 60)
    span = np.ptp(xy, axis=0) / np.ptp(on_temple[:, ::-1], axis=0)
    assert np.all(span > 0.75)
    assert small.visible2.mean() >= 0.9
    inside = (small.x2_true >= 0).all(axis=1) & (small.x2_true[:, 0] <= small.width - 1)
    assert np.all(inside[small.visible2])


@pytest.mark.parametrize("seed", [2, 7, 11])
def test_unseen_variants_keep_every_guarantee(seed):
    scene = make_temple_scene(seed, width=256, height=192, n_corresp=60, n_outliers=20, n_coords=100)
    assert epipolar_distances(scene.F_true, scene.pts1_true, scene.pts2_true).max() < 1e-6
    assert np.all(visible_from(scene.primitives, scene.M2, scene.X))
    out = ~scene.inlier_mask
    assert out.sum() == 20
    assert np.linalg.norm(scene.pts2_noisy[out].astype(float) - scene.pts2_noisy_true[out], axis=1).min() >= 6
    assert scene.visible2.mean() >= 0.85


# ----------------------------------------------------------------------------- outliers

def test_noisy_set_is_the_clean_set_plus_hard_outliers_shuffled(small):
    n, m = len(small.pts1), int((~small.inlier_mask).sum())
    assert (n, m) == (110, 30) and small.pts1_noisy.shape == (140, 2)
    src = small.noisy_source
    inl = small.inlier_mask
    assert np.array_equal(np.sort(src[inl]), np.arange(n)) and np.all(src[~inl] == -1)
    assert np.array_equal(small.pts1_noisy[inl], small.pts1[src[inl]])
    assert np.array_equal(small.pts2_noisy[inl], small.pts2[src[inl]])
    assert np.flatnonzero(~inl).min() < n  # not all piled up at the end
    # Every wrong match is far from the true one ...
    wrong = small.pts2_noisy[~inl].astype(float)
    assert np.linalg.norm(wrong - small.pts2_noisy_true[~inl], axis=1).min() >= 6.0
    # ... yet half of them pass an epipolar test at 1 px, and the rest fail it clearly.
    d = epipolar_distances(small.F_true, small.pts1_noisy[~inl], wrong)
    kind = small.outlier_kind[~inl]
    assert (kind == "epipolar").sum() == 15 and np.all(kind[kind != "epipolar"] == "random")
    assert np.all(d[kind == "epipolar"] <= 1.0)
    assert np.all(d[kind == "random"] >= 6.0)
    # The clean pairs do pass it (noise and rounding only).
    assert np.mean(epipolar_distances(small.F_true, small.pts1, small.pts2) <= 1.5) > 0.9


def test_outlier_mix_follows_the_arguments():
    scene = make_temple_scene(6, epipolar_outliers=0.0, **TINY)
    out = ~scene.inlier_mask
    assert np.all(scene.outlier_kind[out] == "random")
    assert np.all(epipolar_distances(scene.F_true, scene.pts1_noisy[out], scene.pts2_noisy[out]) >= 6)
    clean = make_temple_scene(6, n_outliers=0, **{k: v for k, v in TINY.items() if k != "n_outliers"})
    assert clean.inlier_mask.all()
    assert {tuple(r) for r in np.hstack([clean.pts1_noisy, clean.pts2_noisy]).tolist()} == \
        {tuple(r) for r in np.hstack([clean.pts1, clean.pts2]).tolist()}


# ----------------------------------------------------------------------------- images

def test_images_are_a_bright_textured_temple_on_a_dark_backdrop(small):
    for im in (small.im1, small.im2):
        assert im.dtype == np.uint8 and im.shape == (240, 320, 3)
        grey = im.astype(float).mean(axis=2)
        corners = [grey[:12, :12], grey[:12, -12:], grey[-12:, :12], grey[-12:, -12:]]
        assert max(c.mean() for c in corners) < 40
        temple = grey > 60
        assert 0.15 < temple.mean() < 0.6
        assert grey[temple].mean() > 4 * grey[~temple].mean()
        r, g, b = (im[..., k][temple].mean() for k in range(3))
        assert r > g > b  # warm stone
    # Textured: a 15x15 window around a templeCoords point varies by several grey levels.
    grey = small.im1.astype(float).mean(axis=2)
    stds = [grey[y - 7:y + 8, x - 7:x + 8].std() for x, y in zip(small.x1[:, 0].astype(int),
                                                                 small.y1[:, 0].astype(int))]
    assert np.median(stds) > 6


def test_image_size_variant_scales_the_camera(default):
    scene = make_temple_scene(0, width=320, height=240)
    assert np.allclose(scene.K1[:2, :3], default.K1[:2, :3] / 2)
    ratio = disparity_stats(scene.pts1_true, scene.pts2_true)[1][1] / \
        disparity_stats(default.pts1_true, default.pts2_true)[1][1]
    assert 0.35 < ratio < 0.7


# ----------------------------------------------------------------------------- the ray caster

def test_ray_caster_hits_primitives_where_geometry_says():
    cyl = Cylinder([0, 0, 5.0], [1, 0, 0], 1.0, 2.0)
    hits = cast_rays([cyl], [0, 0, 0], [[0, 0, 1.0], [0, 0.15, 1.0], [0, 3.0, 1.0]])
    assert np.isclose(hits.t[0], 4.0) and np.allclose(hits.normal[0], [0, 0, -1])
    p = hits.t[1] * np.array([0, 0.15, 1.0])  # on the side: at distance r from the axis
    assert np.isclose(np.hypot(p[1], p[2] - 5.0), 1.0) and np.isinf(hits.t[2])
    cap = cast_rays([cyl], [-5.0, 0, 5.0], [[1.0, 0, 0]])
    assert np.isclose(cap.t[0], 3.0) and np.allclose(cap.normal[0], [-1, 0, 0])
    roof = wedge([0, 0, 4.0], 1.0, 1.0, 1.0, R=rotation_about([1, 0, 0], np.pi))  # ridge towards -z
    hit = cast_rays([roof], [0.3, 0.2, 0], [[0, 0, 1.0]])
    q = np.array([0.3, 0.2, hit.t[0]])
    assert np.isclose(q[2], 3.0 + 0.3) and np.allclose(hit.normal[0], [1, 0, -1] / np.sqrt(2))
    # The closest hit wins, whatever the order of the primitives.
    near, far = box([0, 0, 3.0], [1, 1, 0.5]), box([0, 0, 6.0], [3, 3, 0.5])
    both = cast_rays([far, near], [0, 0, 0], [[0, 0, 1.0], [0, 2.8, 5.5]])
    assert np.isclose(both.t[0], 2.5) and both.prim[0] == 1 and both.prim[1] == 0


def test_visibility_sees_occlusion():
    near, far = box([0, 0, 3.0], [1, 1, 0.5]), box([0, 0, 6.0], [3, 3, 0.5])
    M = IDENTITY_POSE
    X = np.array([[0, 0, 2.5],      # front face of the near box: seen
                  [0, 0, 5.5],      # front face of the far box, behind the near box: hidden
                  [0, 2.8, 5.5],    # front face of the far box, beside the near box: seen
                  [0, 0, 6.5]])     # back face of the far box: hidden
    assert visible_from([near, far], M, X).tolist() == [True, False, True, False]
    behind = np.hstack([rotation_about([0, 1, 0], np.pi), [[0], [0], [0]]])  # looks along -z
    assert not visible_from([near, far], behind, X[:1])[0]


def test_render_matches_cast_rays_and_antialiases_edges():
    K = intrinsics(100.0, 31.5, 23.5)
    M = IDENTITY_POSE
    prims = [box([0.1, 0.05, 5.0], [1.0, 0.6, 0.5], R=rotation_about([0, 0, 1], 0.3))]
    g = render_gbuffer(prims, K, M, 64, 48, supersample=2)
    ys, xs = np.nonzero(g.prim >= 0)
    o, d = pixel_rays(K, M, np.stack([xs, ys], axis=1).astype(float))
    assert np.allclose(cast_rays(prims, o, d).t, g.depth[ys, xs])
    partial = (g.coverage > 0) & (g.coverage < 1)
    assert partial.any() and np.all(np.isin(g.coverage[partial], [0.25, 0.5, 0.75]))
    tex = SolidTexture(np.random.default_rng(0), cell=0.05)
    im = shade(g, lambda X: np.repeat(0.5 + 0.1 * tex(X)[:, None], 3, axis=1), light=[0, 0, -0.5],
               ambient=0.5, background=np.zeros((48, 64, 3)))
    assert im.dtype == np.uint8 and im.shape == (48, 64, 3)
    assert im[g.coverage == 0].max() == 0 and im[g.coverage == 1].min() > 20


# ----------------------------------------------------------------------------- the default data

def test_default_scene_has_official_like_disparities(default):
    assert default.im1.shape == (480, 640, 3) and len(default.pts1) == 110 and len(default.x1) == 288
    assert np.isclose(default.K1[0, 0], 1520.0) and np.allclose(default.K1[:2, 2], [302.3, 246.9], atol=0.1)
    mean, std, lo, hi = disparity_stats(default.pts1, default.pts2)
    assert abs(mean[0]) < 2 and -12 < mean[1] < -2
    assert 1 < std[0] < 5 and 6 < std[1] < 20
    assert lo[1] >= -60 and hi[1] <= 40 and lo[0] >= -15 and hi[0] <= 15
    # Epipolar lines within a few degrees of vertical, everywhere the points are.
    lines = homogeneous(default.pts1_true) @ default.F_true.T
    assert np.degrees(np.arctan2(np.abs(lines[:, 1]), np.abs(lines[:, 0]))).max() < 5


def test_window_matching_along_the_true_line_finds_most_templecoords(default):
    x1 = default.x1[:, 0].astype(int)
    y1 = default.y1[:, 0].astype(int)
    found = ssd_along_line(default.im1, default.im2, default.F_true, x1, y1)
    err = np.linalg.norm(found - default.x2_true, axis=1)
    assert np.mean(err <= 2.0) >= 0.85


@pytest.mark.official
def test_default_scene_statistics_are_comparable_to_the_official_pair(default, course_data):
    temple = course_data / "temple"
    with np.load(temple / "some_corresp.npz") as c, np.load(temple / "intrinsics.npz") as k, \
            np.load(temple / "templeCoords.npz") as tc:
        o1, o2, K, ox = c["pts1"], c["pts2"], k["K1"], tc["x1"]
    assert default.pts1.dtype == o1.dtype and default.pts1.shape == o1.shape
    assert default.x1.dtype == ox.dtype and default.x1.shape == ox.shape
    assert np.allclose(default.K1, K, rtol=0.01, atol=1.0)
    ours, theirs = disparity_stats(default.pts1, default.pts2), disparity_stats(o1, o2)
    assert abs(ours[0][1] - theirs[0][1]) < 5  # mean y disparity
    assert 0.5 < ours[1][1] / theirs[1][1] < 2 and 0.5 < ours[1][0] / theirs[1][0] < 2
    # The points cover about the same part of the image.
    for a, b in [(default.pts1.astype(float), o1.astype(float))]:
        assert np.all(np.abs(a.min(axis=0) - b.min(axis=0)) < 60)
        assert np.all(np.abs(a.max(axis=0) - b.max(axis=0)) < 60)
    with Image.open(temple / "im1.png") as png:
        official = np.asarray(png.convert("RGB")).astype(float)
    ours_grey, theirs_grey = default.im1.astype(float).mean(axis=2), official.mean(axis=2)
    assert official.shape == default.im1.shape
    assert abs((ours_grey > 60).mean() - (theirs_grey > 60).mean()) < 0.12
    assert 0.8 < ours_grey[ours_grey > 60].mean() / theirs_grey[theirs_grey > 60].mean() < 1.25


def test_importing_the_camera_helpers_leaves_the_temple_renderer_unloaded():
    # Every sandboxed child that loads a whole hand-in runs Q1's `from scenes.cameras import ...`:
    # the renderer's scipy.ndimage and scipy.spatial load only when a scene is made.
    import subprocess
    import sys

    from core.paths import KIT_ROOT

    probe = ("import sys\nfrom scenes.cameras import intrinsics\nimport scenes\n"
             "before = sorted(m for m in ('scenes.temple', 'scipy.ndimage', 'scipy.spatial') if m in sys.modules)\n"
             "from scenes import make_temple_scene\n"
             "print(before, make_temple_scene.__module__, scenes.car.__name__)\n")
    out = subprocess.run([sys.executable, "-c", probe], cwd=KIT_ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["[]", "scenes.temple", "scenes.car"], out.stdout
