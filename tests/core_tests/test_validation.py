"""Bad input fails with a ValueError that names the argument; degenerate data says what was degenerate."""

from __future__ import annotations

import numpy as np
import pytest

from solutions import (MultiviewReconstruction, bundleAdjustment, eightpoint, epipolarCorrespondence, essentialMatrix,
                       findM2, rodriguesResidual, triangulate)
from starter import DegenerateInputError, camera2, invRodrigues, load_temple, ransacF, refineF, rodrigues


@pytest.fixture
def pts(two_view):
    return two_view["pts1"], two_view["pts2"]


@pytest.mark.parametrize("bad, match", [
    (np.zeros((20, 3)), r"pts1: expected shape \(N, 2\)"),
    (np.zeros(20), r"pts1: expected shape \(N, 2\)"),
    (np.zeros((7, 2)), r"pts1: expected at least 8 points, got 7"),
    ("abc", r"pts1: expected a numeric array"),
    (None, r"pts1: expected an array, got None"),
])
def test_eightpoint_names_the_bad_pts1(pts, bad, match):
    with pytest.raises(ValueError, match=match):
        eightpoint(bad, pts[1], 640)


def test_eightpoint_rejects_nan_and_inf(pts):
    p1 = pts[0].copy()
    p1[3, 0] = np.nan
    p1[5, 1] = np.inf
    with pytest.raises(ValueError, match=r"pts1: expected finite values, found 2 NaN or inf"):
        eightpoint(p1, pts[1], 640)


def test_eightpoint_rejects_mismatched_counts(pts):
    with pytest.raises(ValueError, match=r"pts1 has 60, pts2 has 59"):
        eightpoint(pts[0], pts[1][:-1], 640)


@pytest.mark.parametrize("M", [0, -640, np.nan, "big"])
def test_eightpoint_rejects_a_bad_scale(pts, M):
    with pytest.raises(ValueError, match=r"^M: expected a positive"):
        eightpoint(pts[0], pts[1], M)


def test_eightpoint_says_repeated_points_are_degenerate():
    p = np.tile([[100.0, 200.0], [300.0, 50.0]], (6, 1))
    with pytest.raises(DegenerateInputError, match=r"leave F undetermined"):
        eightpoint(p, p + 3, 640)


def test_matrices_are_checked_by_name(two_view, pts):
    with pytest.raises(ValueError, match=r"F: expected shape \(3, 3\), got an array of shape \(3, 4\)"):
        essentialMatrix(np.zeros((3, 4)), two_view["K1"], two_view["K2"])
    with pytest.raises(ValueError, match=r"C2: expected shape \(3, 4\)"):
        triangulate(two_view["C1"], pts[0], np.eye(3), pts[1])
    with pytest.raises(ValueError, match=r"K2: expected finite values"):
        findM2(np.eye(3), pts[0], pts[1], two_view["K1"], np.full((3, 3), np.nan))
    with pytest.raises(ValueError, match=r"R: expected a rotation matrix"):
        invRodrigues(2 * np.eye(3))
    with pytest.raises(ValueError, match=r"r: expected 3 numbers"):
        rodrigues([1.0, 2.0])


def test_camera2_reports_a_rank_deficient_E():
    with pytest.raises(DegenerateInputError, match=r"E: an essential matrix has two equal non-zero singular values"):
        camera2(np.diag([1.0, 0.0, 0.0]))


def test_epipolar_correspondence_checks_the_images():
    im = np.zeros((48, 64, 3), np.uint8)
    F = np.array([[0, 0, 0], [0, 0, -1], [0, 1, 0.0]])
    with pytest.raises(ValueError, match=r"im1, im2: expected images of the same shape"):
        epipolarCorrespondence(im, im[:40], F, 10, 10)
    with pytest.raises(ValueError, match=r"im2: expected dtype uint8 or float"):
        epipolarCorrespondence(im, im.astype(np.int32), F, 10, 10)
    with pytest.raises(ValueError, match=r"\(x1, y1\): expected a pixel inside im1"):
        epipolarCorrespondence(im, im, F, 64, 10)
    bad = np.zeros((48, 64), float)
    bad[10, 10] = np.nan
    with pytest.raises(ValueError, match=r"im1: NaN or inf in the image near the point"):
        epipolarCorrespondence(bad, np.zeros((48, 64)), F, 10, 10)


def test_bundle_adjustment_checks_counts_and_the_baseline(two_view):
    d = two_view
    M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    with pytest.raises(ValueError, match=r"w_init has 59"):
        bundleAdjustment(d["K1"], M1, d["pts1"], d["K2"], d["M2"], d["pts2"], d["X"][:-1])
    zero_t = d["M2"].copy()
    zero_t[:, 3] = 0
    with pytest.raises(ValueError, match=r"M2_init: the translation is zero"):
        bundleAdjustment(d["K1"], M1, d["pts1"], d["K2"], zero_t, d["pts2"], d["X"])
    with pytest.raises(ValueError, match=r"x: expected 3N \+ 6 = 186 values"):
        rodriguesResidual(d["K1"], M1, d["pts1"], d["K2"], d["pts2"], np.zeros(10))


def test_multiview_checks_the_threshold_and_columns(two_view):
    C = two_view["C1"]
    p = np.zeros((12, 3))
    with pytest.raises(ValueError, match=r"pts2: expected shape \(N, 3\)"):
        MultiviewReconstruction(C, p, C, p[:, :2], C, p, 500)
    with pytest.raises(ValueError, match=r"Thres: expected a finite number"):
        MultiviewReconstruction(C, p, C, p, C, p, np.nan)


def test_ransac_and_refine_check_inputs(pts):
    with pytest.raises(ValueError, match=r"tol: expected a positive"):
        ransacF(pts[0], pts[1], 640, eightpoint, tol=0)
    with pytest.raises(ValueError, match=r"pts2: expected at least 8 points, got 5"):
        refineF(np.eye(3), pts[0], pts[1][:5])


def test_loader_names_missing_files_and_arrays(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"no temple data under"):
        load_temple(tmp_path)
    from PIL import Image

    img = Image.fromarray(np.zeros((48, 64, 3), np.uint8))
    img.save(tmp_path / "im1.png")
    img.save(tmp_path / "im2.png")
    np.savez(tmp_path / "intrinsics.npz", K1=np.eye(3), K2=np.eye(3))
    np.savez(tmp_path / "some_corresp.npz", pts1=np.zeros((10, 2), np.uint16), points2=np.zeros((10, 2)))
    with pytest.raises(ValueError, match=r"some_corresp.npz: expected arrays \['pts1', 'pts2'\], missing \['pts2'\]"):
        load_temple(tmp_path)
    np.savez(tmp_path / "some_corresp.npz", pts1=np.zeros((10, 2), np.uint16), pts2=np.zeros((10, 3)))
    with pytest.raises(ValueError, match=r"array pts2 should be numeric of shape Nx2, got \(10, 3\)"):
        load_temple(tmp_path)
    (tmp_path / "im2.png").write_bytes(b"not a png")
    with pytest.raises(ValueError, match=r"im2.png: not a readable image"):
        load_temple(tmp_path)
