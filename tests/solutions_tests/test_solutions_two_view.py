"""The reference solutions against a two-view scene with known answers (no images)."""

from __future__ import annotations

import numpy as np
import pytest

from core.geometry import IDENTITY_POSE, fundamental_from_pose, project
from scenes.cameras import rotation_about
from solutions import (MultiviewReconstruction, bundleAdjustment, eightpoint, essentialMatrix, findM2,
                       rodriguesResidual, triangulate)
from starter import epipolar_distances, invRodrigues

M1 = IDENTITY_POSE


@pytest.fixture
def true_F(two_view):
    return fundamental_from_pose(two_view["K1"], two_view["K2"], two_view["M2"])


def _same_up_to_sign(A, B, atol):
    return min(np.abs(A - B).max(), np.abs(A + B).max()) < atol


@pytest.mark.parametrize("refine", [False, True])
def test_eightpoint_recovers_F_up_to_scale_and_sign(two_view, true_F, refine):
    F = eightpoint(two_view["pts1"], two_view["pts2"], 640, refine=refine)
    assert np.linalg.norm(F) == pytest.approx(1.0)
    assert np.linalg.svd(F, compute_uv=False)[2] < 1e-12
    assert _same_up_to_sign(F, true_F, 1e-6)
    assert epipolar_distances(F, two_view["pts1"], two_view["pts2"]).max() < 1e-6


def test_eightpoint_is_not_fooled_by_transposition(two_view):
    # F maps image-1 points to image-2 lines: swapping the images must give F transposed.
    F12 = eightpoint(two_view["pts1"], two_view["pts2"], 640, refine=False)
    F21 = eightpoint(two_view["pts2"], two_view["pts1"], 640, refine=False)
    assert _same_up_to_sign(F21, F12.T, 1e-6)
    assert not _same_up_to_sign(F12, F12.T, 1e-3)


def test_essential_matrix_has_two_equal_singular_values(two_view, true_F):
    E = essentialMatrix(true_F, two_view["K1"], two_view["K2"])
    s = np.linalg.svd(E, compute_uv=False)
    assert s[0] == pytest.approx(s[1], rel=1e-9) and s[2] < 1e-9 * s[0]


def test_triangulate_recovers_exact_points(two_view):
    w, err = triangulate(two_view["C1"], two_view["pts1"], two_view["C2"], two_view["pts2"])
    np.testing.assert_allclose(w, two_view["X"], rtol=1e-8)
    assert err < 1e-12


def test_triangulation_error_is_the_sum_of_squared_pixel_errors(two_view, rng):
    p1 = two_view["pts1"] + rng.normal(0, 1.0, two_view["pts1"].shape)
    w, err = triangulate(two_view["C1"], p1, two_view["C2"], two_view["pts2"])
    expected = np.sum((project(two_view["C1"], w) - p1) ** 2) + np.sum((project(two_view["C2"], w) - two_view["pts2"]) ** 2)
    assert err == pytest.approx(expected, rel=1e-9)
    assert 0 < err < np.sum((p1 - two_view["pts1"]) ** 2)


def test_findM2_chooses_the_true_camera(two_view, true_F):
    M2, C2, w = findM2(true_F, two_view["pts1"], two_view["pts2"], two_view["K1"], two_view["K2"])
    np.testing.assert_allclose(M2, two_view["M2"], atol=1e-8)
    np.testing.assert_allclose(C2, two_view["K2"] @ M2)
    np.testing.assert_allclose(w, two_view["X"], rtol=1e-6)


def test_bundle_adjustment_lowers_the_error_and_approaches_the_truth(two_view, rng):
    d = two_view
    p1 = d["pts1"] + rng.normal(0, 0.5, d["pts1"].shape)
    p2 = d["pts2"] + rng.normal(0, 0.5, d["pts2"].shape)
    F = eightpoint(p1, p2, 640, refine=False)
    M2, _, w = findM2(F, p1, p2, d["K1"], d["K2"])
    M2b, wb, o1, o2 = bundleAdjustment(d["K1"], M1, p1, d["K2"], M2, p2, w)
    x = np.concatenate([wb.ravel(), invRodrigues(M2b[:, :3]), M2b[:, 3]])
    assert np.sum(rodriguesResidual(d["K1"], M1, p1, d["K2"], p2, x) ** 2) == pytest.approx(o2)
    assert o2 < o1
    # With 0.5 px noise on 240 coordinates, 183 degrees of freedom left: o2 near 0.25 * 57 ... 0.25 * 240.
    assert 0.25 * 40 < o2 < 0.25 * 240
    # The truth (|t| = 1, like M2) is a feasible point: a real optimum is at least as good.
    x_true = np.concatenate([d["X"].ravel(), invRodrigues(d["M2"][:, :3]), d["M2"][:, 3]])
    assert o2 <= np.sum(rodriguesResidual(d["K1"], M1, p1, d["K2"], p2, x_true) ** 2) + 1e-6
    assert np.abs(M2b[:, :3] - d["M2"][:, :3]).max() < 0.05
    assert np.linalg.norm(M2b[:, 3]) == pytest.approx(1.0)


def test_multiview_uses_only_confident_views(two_view, rng):
    d = two_view
    M3 = np.hstack([rotation_about([0, 1, 0], -0.1), np.array([[-0.8], [0.1], [0.2]])])
    C3 = d["K1"] @ M3
    X = d["X"][:12]
    conf = np.full((3, 12), 900.0)
    pts = [project(C, X) for C in (d["C1"], d["C2"], C3)]
    pts[2][:4] += 40.0          # view 3 is badly wrong for the first four keypoints...
    conf[2, :4] = 300           # ...and says so with a low confidence
    conf[1:, 11] = 200          # keypoint 11 is confident in one view only
    P, err = MultiviewReconstruction(d["C1"], np.column_stack([pts[0], conf[0]]), d["C2"],
                                     np.column_stack([pts[1], conf[1]]), C3, np.column_stack([pts[2], conf[2]]), 500)
    np.testing.assert_allclose(P[:11], X[:11], atol=1e-6)
    assert np.isnan(P[11]).all() and err < 1e-9
    P_all, err_all = MultiviewReconstruction(d["C1"], np.column_stack([pts[0], conf[0]]), d["C2"],
                                             np.column_stack([pts[1], conf[1]]), C3,
                                             np.column_stack([pts[2], conf[2]]), 100)
    assert err_all > 100 and np.isfinite(P_all).all()
