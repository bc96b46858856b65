"""The helpers students are given: camera2, rodrigues, RANSAC, refineF, the loaders."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.geometry import essential_from_pose
from scenes.cameras import rotation_about
from solutions import eightpoint
from starter import camera2, epipolar_distances, invRodrigues, ransacF, refineF, rodrigues
from starter.epipolar import symmetric_epipolar_cost
from starter.ransac import adaptive_trials, ransac


def test_camera2_contains_the_true_pose_once(two_view):
    R, t = two_view["M2"][:, :3], two_view["M2"][:, 3]
    M2s = camera2(essential_from_pose(two_view["M2"]) * 3.7)  # any scale of E
    assert M2s.shape == (3, 4, 4)
    matches = [np.allclose(M2s[:, :3, i], R, atol=1e-9) and np.allclose(M2s[:, 3, i], t, atol=1e-9) for i in range(4)]
    assert sum(matches) == 1
    for i in range(4):
        assert np.linalg.det(M2s[:, :3, i]) == pytest.approx(1.0)
        assert np.linalg.norm(M2s[:, 3, i]) == pytest.approx(1.0)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 0.3, math.pi - 1e-6, math.pi])
def test_rodrigues_round_trip(rng, angle):
    axis = rng.normal(size=3)
    R = rotation_about(axis, angle)
    np.testing.assert_allclose(rodrigues(invRodrigues(R)), R, atol=1e-8)
    assert np.linalg.norm(invRodrigues(R)) == pytest.approx(angle, abs=1e-6)


# Hartley & Zisserman (2004), table 4.3: trials for p = 0.99 and a sample of 8, by outlier share.
@pytest.mark.parametrize("outliers, trials", [(0.05, 5), (0.10, 9), (0.20, 26), (0.25, 44), (0.30, 78),
                                              (0.40, 272), (0.50, 1177)])
def test_adaptive_trials_match_the_published_table(outliers, trials):
    assert math.ceil(adaptive_trials(1 - outliers, 8, 0.99)) == trials


def test_generic_ransac_finds_a_line_and_its_outliers(rng):
    x = rng.uniform(0, 10, 100)
    y = 2 * x + 1 + rng.normal(0, 0.02, 100)
    bad = rng.choice(100, 30, replace=False)
    y[bad] += rng.uniform(3, 10, 30) * rng.choice([-1, 1], 30)

    def fit(idx):
        if np.ptp(x[idx]) == 0:
            return None
        return np.polyfit(x[idx], y[idx], 1)

    res = ransac(100, fit, lambda m: np.abs(np.polyval(m, x) - y), min_samples=2, threshold=0.3, rng=rng)
    np.testing.assert_allclose(res.model, [2, 1], atol=0.15)
    assert set(np.flatnonzero(~res.inliers)) == set(bad)
    assert res.trials < 1000  # stopped adaptively


def test_ransacF_separates_outliers_and_is_reproducible(two_view, rng):
    p1 = two_view["pts1"] + rng.normal(0, 0.3, two_view["pts1"].shape)
    p2 = two_view["pts2"] + rng.normal(0, 0.3, two_view["pts2"].shape)
    bad = rng.choice(len(p1), 12, replace=False)
    p2[bad] += rng.uniform(15, 40, (12, 2)) * rng.choice([-1, 1], (12, 2))
    F, inl = ransacF(p1, p2, 640, eightpoint, tol=2.0, rng=np.random.default_rng(5))
    assert set(np.flatnonzero(~inl)) == set(bad)
    assert np.median(epipolar_distances(F, p1[inl], p2[inl])) < 0.5
    F2, inl2 = ransacF(p1, p2, 640, eightpoint, tol=2.0, rng=np.random.default_rng(5))
    np.testing.assert_array_equal(F, F2)
    np.testing.assert_array_equal(inl, inl2)


def test_ransacF_works_with_an_eightpoint_without_refine_keyword(two_view):
    calls = []

    def student_eightpoint(p1, p2, M):
        calls.append(len(p1))
        return eightpoint(p1, p2, M, refine=False)

    F, inl = ransacF(two_view["pts1"], two_view["pts2"], 640, student_eightpoint, tol=1.0)
    assert inl.all() and 8 in calls


def test_refineF_lowers_the_symmetric_epipolar_cost(two_view, rng):
    p1 = two_view["pts1"] / 640 + rng.normal(0, 1e-3, two_view["pts1"].shape)
    p2 = two_view["pts2"] / 640 + rng.normal(0, 1e-3, two_view["pts2"].shape)
    F0 = eightpoint(p1 * 640, p2 * 640, 640, refine=False)
    T = np.diag([640, 640, 1.0])
    F0s = T.T @ F0 @ T  # back in the 1/M coordinates
    F0s += rng.normal(0, 1e-3 * np.abs(F0s).max(), (3, 3))
    before = symmetric_epipolar_cost(F0s, p1, p2)
    F1 = refineF(F0s, p1, p2)
    assert np.linalg.matrix_rank(F1, tol=1e-10) == 2
    assert symmetric_epipolar_cost(F1, p1, p2) < before
