"""The public self-checks (starter/checks) and the catalogue of known mistakes.

The reference solutions must pass every check; each deliberately broken variant below must
fail its check *and* have the report name its mistake; stubs must say "not implemented yet".
The catalogue's functions are also tested directly on arrays.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize

import solutions as ref
from scenes.car import make_car_scene, write_car
from scenes.temple import make_temple_scene, write_temple
from starter import camera2, invRodrigues, rodrigues
from starter.checks import (
    CHECKS,
    CheckReport,
    check_bundleAdjustment,
    check_compute3D_pts,
    check_eightpoint,
    check_epipolarCorrespondence,
    check_essentialMatrix,
    check_findM2,
    check_MultiviewReconstruction,
    check_rodriguesResidual,
    check_triangulate,
)
from judging import mistakes as mk
from starter.checks._scenes import two_view
from starter.checks.multiview import DESIGN_CONFIDENCE, THRES
from starter.checks.report import DISCLAIMER, NOT_IMPLEMENTED, call

# The checks that use the default data: the others would need a reference answer (an F, a
# pose) to use them, and the checks use none (nor OpenCV).
USES_DEFAULT_DATA = {"eightpoint", "essentialMatrix", "MultiviewReconstruction"}


@pytest.fixture(scope="session")
def default_root(tmp_path_factory):
    """A small default data folder in the official layout, as an instructor's data/ would be."""
    root = tmp_path_factory.mktemp("default-data")
    write_temple(make_temple_scene(5, width=320, height=240, n_corresp=60, n_outliers=10, n_coords=40,
                                   supersample=1), root / "temple")
    write_car(make_car_scene(5, n_times=1, render=False), root / "q6")
    return root


@pytest.fixture(scope="session")
def no_data(tmp_path_factory):
    """An empty folder: the checks then run on generated scenes only (faster)."""
    return tmp_path_factory.mktemp("empty")


def codes(report: CheckReport) -> set[str]:
    return {m.code for m in report.mistakes}


def fast_eightpoint(pts1, pts2, M):
    return ref.eightpoint(pts1, pts2, M, refine=False)


# ----------------------------------------------------------------------------- the reference passes

@pytest.mark.parametrize("name", list(CHECKS))
def test_reference_passes_on_generated_and_default_data(name, default_root, capsys):
    report = CHECKS[name](getattr(ref, name), root=default_root)
    printed = capsys.readouterr().out
    assert report.passed, report.text()
    assert report.mistakes == []
    assert printed.strip().endswith(DISCLAIMER)
    assert "\u2717" not in printed and "\u2713" in printed
    if name in USES_DEFAULT_DATA:
        assert any("default data" in i.name for i in report.items), "the default data were not used"
    else:
        assert not any("default data" in i.name for i in report.items)


@pytest.mark.official
@pytest.mark.parametrize("name", sorted(USES_DEFAULT_DATA))
def test_reference_passes_on_the_official_data(name, course_data):
    report = CHECKS[name](getattr(ref, name), root=course_data, verbose=False)
    assert report.passed, report.text()
    assert any("default data" in i.name for i in report.items)


def test_missing_default_data_is_a_note_not_a_failure(no_data):
    report = check_eightpoint(fast_eightpoint, root=no_data, verbose=False)
    assert report.passed
    assert any("no temple data" in n for n in report.notes)
    assert not any("default data" in i.name for i in report.items)


# ----------------------------------------------------------------------------- stubs and crashes

def _stub(*args, **kwargs):
    raise NotImplementedError


def _returns_none(*args, **kwargs):
    return None


@pytest.mark.parametrize("name", list(CHECKS))
@pytest.mark.parametrize("stub", [_stub, _returns_none, lambda *a: (None, None)])
def test_a_stub_is_not_implemented_yet(name, stub, no_data, capsys):
    report = CHECKS[name](stub, root=no_data)
    out = capsys.readouterr().out
    assert not report.passed and report.not_implemented
    assert NOT_IMPLEMENTED in out and "Traceback" not in out
    assert out.strip().endswith(DISCLAIMER)


def test_an_exception_is_one_line_and_fails(no_data, capsys):
    def broken(pts1, pts2, M):
        raise ZeroDivisionError("the usual\nmultiline message")

    report = check_eightpoint(broken, root=no_data)
    out = capsys.readouterr().out
    assert not report.passed and not report.not_implemented
    assert "ZeroDivisionError: the usual multiline message" in out
    assert "Traceback" not in out


def test_call_never_raises():
    assert call(_stub).status == "not implemented"
    assert call(lambda: 1 / 0).status == "error"
    assert call("not a function").status == "error"
    assert call(lambda: (1, 2)).value == (1, 2)


def test_report_text_html_and_passed():
    r = CheckReport("f")
    assert not r.passed  # nothing ran
    r.add("a", True, "1", "< 2")
    r.add("b", None, "skipped")
    assert r.passed
    r.add("c", False, "3", "< 2", [mk.mistake("f_transposed", "seen")])
    assert not r.passed and codes(r) == {"f_transposed"}
    text = r.text()
    assert "\u2713 a" in text and "\u2717 c" in text and "known mistake: F transposed" in text
    assert "<table>" in r._repr_html_() and "F transposed" in r._repr_html_()
    assert "failed" in repr(r)


# ----------------------------------------------------------------------------- broken variants: Q2, Q3

def eightpoint_no_rank2(pts1, pts2, M):
    p1, p2 = np.asarray(pts1, float) / M, np.asarray(pts2, float) / M
    (x1, y1), (x2, y2) = p1.T, p2.T
    A = np.stack([x2 * x1, x2 * y1, x2, y2 * x1, y2 * y1, y2, x1, y1, np.ones_like(x1)], axis=1)
    F = np.linalg.svd(A)[2][-1].reshape(3, 3)
    T = np.diag([1 / M, 1 / M, 1.0])
    return T @ F @ T


def eightpoint_uint16(pts1, pts2, M):
    # The arithmetic happens in the input's dtype: uint16 products wrap around.
    x1, y1 = pts1[:, 0], pts1[:, 1]
    x2, y2 = pts2[:, 0], pts2[:, 1]
    one = np.ones_like(x1)
    A = np.stack([x2 * x1, x2 * y1, x2, y2 * x1, y2 * y1, y2, x1, y1, one], axis=1).astype(float)
    S = np.array([1 / M ** 2, 1 / M ** 2, 1 / M, 1 / M ** 2, 1 / M ** 2, 1 / M, 1 / M, 1 / M, 1.0])
    Fn = np.linalg.svd(A * S)[2][-1].reshape(3, 3)
    U, s, Vt = np.linalg.svd(Fn)
    T = np.diag([1 / M, 1 / M, 1.0])
    return T @ (U @ np.diag([s[0], s[1], 0]) @ Vt) @ T


def unscaled_the_wrong_way(pts1, pts2, M):
    S = np.diag([M, M, 1.0])  # the inverse of the scaling T: the mistake
    return S @ fast_eightpoint(np.asarray(pts1, float) / M, np.asarray(pts2, float) / M, 1.0) @ S


EIGHTPOINT_VARIANTS = {
    "f_transposed": lambda p1, p2, M: fast_eightpoint(p1, p2, M).T,
    "f_not_unscaled": lambda p1, p2, M: fast_eightpoint(np.asarray(p1, float) / M, np.asarray(p2, float) / M, 1.0),
    "f_unscaled_wrong_way": lambda p1, p2, M: unscaled_the_wrong_way(p1, p2, M),
    "xy_swapped": lambda p1, p2, M: fast_eightpoint(np.asarray(p1)[:, ::-1], np.asarray(p2)[:, ::-1], M),
    "f_rank3": eightpoint_no_rank2,
    "uint16_wraparound": eightpoint_uint16,
}


def test_the_noisy_subset_overflows_uint16():
    from starter.checks.fundamental import _N_NOISY

    tv = two_view()
    p1, p2 = tv.pts1_u16[:_N_NOISY].astype(np.int64), tv.pts2_u16[:_N_NOISY].astype(np.int64)
    assert np.any(p1[:, 0] * p2[:, 0] > 65535)


def test_a_correct_unrefined_eightpoint_passes(no_data):
    assert check_eightpoint(fast_eightpoint, root=no_data, verbose=False).passed


@pytest.mark.parametrize("code", list(EIGHTPOINT_VARIANTS))
def test_broken_eightpoint_fails_and_is_named(code, no_data):
    report = check_eightpoint(EIGHTPOINT_VARIANTS[code], root=no_data, verbose=False)
    assert not report.passed
    assert code in codes(report), report.text()


def test_a_mistake_is_named_on_the_default_data_alone(default_root):
    report = check_eightpoint(EIGHTPOINT_VARIANTS["f_not_unscaled"], root=default_root, verbose=False)
    default_items = [i for i in report.items if "default data" in i.name]
    assert default_items and not default_items[0].passed
    assert "f_not_unscaled" in {m.code for m in default_items[0].mistakes}


@pytest.mark.parametrize("code, variant", [
    ("e_k_order", lambda F, K1, K2: K1.T @ F @ K2),
    ("e_missing_k", lambda F, K1, K2: F @ K1),
    ("e_inverse_k", lambda F, K1, K2: np.linalg.inv(K2).T @ F @ np.linalg.inv(K1)),
])
def test_broken_essential_matrix_fails_and_is_named(code, variant, no_data):
    report = check_essentialMatrix(variant, root=no_data, verbose=False)
    assert not report.passed and code in codes(report), report.text()


@pytest.mark.parametrize("kind, variant", [
    ("mean", lambda w, err, n: err / (2 * n)),
    ("square root", lambda w, err, n: np.sqrt(err)),
])
def test_triangulation_error_not_a_sum_is_named(kind, variant, no_data):
    def broken(C1, pts1, C2, pts2):
        w, err = ref.triangulate(C1, pts1, C2, pts2)
        return w, variant(w, err, len(w))

    report = check_triangulate(broken, root=no_data, verbose=False)
    assert not report.passed and "error_not_sum_of_squares" in codes(report)
    assert any(kind in m.evidence for m in report.mistakes), report.text()


def findM2_wrong_camera(F, pts1, pts2, K1, K2):
    right, _, _ = ref.findM2(F, pts1, pts2, K1, K2)
    cands = camera2(ref.essentialMatrix(F, K1, K2))
    M2 = next(cands[:, :, i] for i in range(4) if not np.allclose(cands[:, :, i], right))
    C2 = K2 @ M2
    w, _ = ref.triangulate(K1 @ np.eye(3, 4), pts1, C2, pts2)
    return M2, C2, w


def test_wrong_camera_of_the_four_is_named(no_data):
    report = check_findM2(findM2_wrong_camera, root=no_data, verbose=False)
    assert not report.passed
    assert {"wrong_camera", "points_behind"} <= codes(report), report.text()


# ----------------------------------------------------------------------------- broken variants: Q4, Q5, Q6

def test_swapped_match_coordinates_are_named(no_data):
    def swapped(im1, im2, F, x1, y1):
        x2, y2 = ref.epipolarCorrespondence(im1, im2, F, x1, y1)
        return y2, x2

    report = check_epipolarCorrespondence(swapped, root=no_data, verbose=False)
    assert not report.passed and "xy_swapped" in codes(report), report.text()


def test_compute3D_pts_with_another_signature_says_so(no_data):
    def own_signature(im1, im2, F):
        return np.zeros((3, 3))

    report = check_compute3D_pts(own_signature, root=no_data, verbose=False)
    assert not report.passed
    assert "could not be called as compute3D_pts(im1, im2, F, x1, y1, C1, C2)" in report.text()


def test_compute3D_pts_may_return_w_alone(no_data):
    report = check_compute3D_pts(lambda *a: ref.compute3D_pts(*a)[0], root=no_data, verbose=False)
    assert report.passed, report.text()


def test_residual_packing_and_layout_are_named(no_data):
    def column_wise(K1, M1, p1, K2, p2, x):
        n = len(p1)
        w = np.asarray(x[:3 * n]).reshape(3, n).T
        return ref.rodriguesResidual(K1, M1, p1, K2, p2, np.concatenate([w.ravel(), x[3 * n:]]))

    def interleaved(K1, M1, p1, K2, p2, x):
        r = ref.rodriguesResidual(K1, M1, p1, K2, p2, x)
        return r.reshape(2, -1, 2).transpose(1, 0, 2).ravel()

    report = check_rodriguesResidual(column_wise, verbose=False)
    assert not report.passed and "x_packing" in codes(report), report.text()
    report = check_rodriguesResidual(interleaved, verbose=False)
    assert not report.passed and "residual_layout" in codes(report), report.text()
    flipped = check_rodriguesResidual(lambda *a: -ref.rodriguesResidual(*a), verbose=False)
    assert flipped.passed  # the sign of the residuals does not change the objective


def _error(K1, M1, p1, K2, p2, M2, w):
    x = np.concatenate([np.ravel(w), invRodrigues(M2[:, :3]), M2[:, 3]])
    return float(np.sum(ref.rodriguesResidual(K1, M1, p1, K2, p2, x) ** 2))


def ba_not_decreasing(K1, M1, p1, K2, M2_init, p2, w_init):
    o1 = _error(K1, M1, p1, K2, p2, M2_init, w_init)
    return M2_init, w_init, o1, o1  # the optimiser's result never unpacked


def _least_squares_ba(K1, M1, p1, K2, M2_init, p2, w_init, scale=1.0):
    """A plain scipy least_squares on the handout's residuals (no gauge fixed), the result scaled by ``scale``."""
    n = len(p1)
    x0 = np.concatenate([np.ravel(w_init), invRodrigues(M2_init[:, :3]), M2_init[:, 3]])
    x = scipy.optimize.least_squares(lambda x: ref.rodriguesResidual(K1, M1, p1, K2, p2, x), x0, method="lm").x
    M2 = np.hstack([rodrigues(x[3 * n:3 * n + 3]), scale * x[3 * n + 3:, None]])
    w = scale * x[:3 * n].reshape(n, 3)
    return M2, w, _error(K1, M1, p1, K2, p2, M2_init, w_init), _error(K1, M1, p1, K2, p2, M2, w)


def ba_collapsing(K1, M1, p1, K2, M2_init, p2, w_init):
    # t driven to (almost) 0 while the points stay: camera 2 sits on camera 1, the scene is gone.
    M2 = M2_init.copy()
    M2[:, 3] *= 1e-9
    return M2, w_init, _error(K1, M1, p1, K2, p2, M2_init, w_init), _error(K1, M1, p1, K2, p2, M2, w_init)


@pytest.mark.parametrize("scale", [1.0, 1e-3, 10.0])
def test_bundle_adjustment_in_any_gauge_passes(scale, no_data):
    # The handout fixes no scale: a plain least_squares, and the same result shrunk or grown
    # (points and t together), are right answers.
    report = check_bundleAdjustment(lambda *a: _least_squares_ba(*a, scale=scale), root=no_data, verbose=False)
    assert report.passed and report.mistakes == [], report.text()


@pytest.mark.parametrize("code, variant", [("ba_not_decreasing", ba_not_decreasing),
                                           ("ba_scale_collapse", ba_collapsing)])
def test_broken_bundle_adjustment_fails_and_is_named(code, variant, no_data):
    report = check_bundleAdjustment(variant, root=no_data, verbose=False)
    assert not report.passed and code in codes(report), report.text()


@pytest.mark.parametrize("code, shift", [("threshold_inclusive", -1), ("threshold_ignored", -THRES),
                                         ("threshold_too_strict", +100)])
def test_threshold_mistakes_are_named(code, shift, no_data):
    def broken(C1, pts1, C2, pts2, C3, pts3, Thres):
        # Thres - 1 on confidences in steps of 100 is ">=": the same keypoints, one more level.
        return ref.MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres + shift)

    report = check_MultiviewReconstruction(broken, root=no_data, verbose=False)
    assert not report.passed and codes(report) == {code}, report.text()


# ----------------------------------------------------------------------------- the catalogue on arrays

@pytest.fixture(scope="module")
def tv():
    """The public pair's truths (core.geometry.CameraPair) with its M, as plain attributes."""
    from types import SimpleNamespace

    v = two_view()
    p = v.pair
    return SimpleNamespace(K1=p.K1, K2=p.K2, M1=p.M1, M2=p.M2, X=p.X, pts1=p.pts1, pts2=p.pts2, E=p.E, F=p.F, M=v.M)


def test_fundamental_mistakes_undo_each_known_mistake(tv):
    F, M = tv.F, tv.M
    S = np.diag([M, M, 1.0])
    P = np.array([[0, 1, 0], [1, 0, 0], [0, 0, 1.0]])
    assert mk.fundamental_mistakes(F, tv.pts1, tv.pts2, M) == []
    assert mk.fundamental_mistakes(-3 * F, tv.pts1, tv.pts2, M) == []  # scale and sign are free
    cases = {
        ("f_transposed",): F.T,
        ("f_not_unscaled",): S @ F @ S,
        ("f_unscaled_wrong_way",): S @ S @ F @ S @ S,
        ("xy_swapped",): P @ F @ P,
        ("f_transposed", "f_not_unscaled"): S @ F.T @ S,
    }
    for expected, G in cases.items():
        found = mk.fundamental_mistakes(G, tv.pts1, tv.pts2, M)
        assert tuple(m.code for m in found) == expected
        assert all(m.evidence for m in found)
    rng = np.random.default_rng(0)
    assert mk.fundamental_mistakes(rng.normal(size=(3, 3)), tv.pts1, tv.pts2, M) == []


def test_rank2_and_uint16_on_arrays(tv):
    U, _, Vt = np.linalg.svd(np.random.default_rng(1).normal(size=(3, 3)))
    full = U @ np.diag([1.0, 0.5, 0.01]) @ Vt
    rank2 = U @ np.diag([1.0, 0.5, 0.0]) @ Vt
    assert mk.rank2_not_enforced(full).code == "f_rank3"
    assert mk.rank2_not_enforced(rank2) is None
    T = np.diag([1 / tv.M, 1 / tv.M, 1.0])
    assert mk.rank2_not_enforced(T @ full @ T, tv.M).code == "f_rank3"  # judged in the 1/M coordinates
    assert mk.uint16_wraparound(tv.F, -2 * tv.F) is None
    assert mk.uint16_wraparound(tv.F.T, tv.F).code == "uint16_wraparound"
    assert mk.uint16_wraparound(np.zeros((3, 3)), tv.F).code == "uint16_wraparound"


def test_essential_mistakes_on_arrays(tv):
    F, K1, K2 = tv.F, tv.K1, tv.K2
    assert mk.essential_mistakes(K2.T @ F @ K1, F, K1, K2) == []
    assert [m.code for m in mk.essential_mistakes(K1.T @ F @ K2, F, K1, K2)] == ["e_k_order"]
    assert [m.code for m in mk.essential_mistakes(K2.T @ F, F, K1, K2)] == ["e_missing_k"]
    assert [m.code for m in mk.essential_mistakes(F, F, K1, K2)] == ["e_missing_k"]
    assert [m.code for m in mk.essential_mistakes(K2.T @ F @ K2, F, K1, K2)] == ["e_same_k"]
    assert [m.code for m in mk.essential_mistakes((K2.T @ F @ K1).T, F, K1, K2)] == ["e_transposed"]
    # With K1 == K2 the order cannot be wrong, so it is not reported.
    assert mk.essential_mistakes(K1.T @ F @ K1, F, K1, K1) == []
    assert mk.essential_mistakes(np.eye(3), F, K1, K2) == []


def test_error_kind_on_arrays():
    rng = np.random.default_rng(2)
    r1, r2 = rng.normal(size=(10, 2)), rng.normal(size=(10, 2))
    total = float(np.sum(r1 ** 2) + np.sum(r2 ** 2))
    assert mk.error_not_sum_of_squares(total, r1, r2) is None
    assert mk.error_not_sum_of_squares(np.array([total]), r1, r2) is None
    for value, words in [(total / 20, "mean squared"), (np.sqrt(total), "square root"), (total / 2, "half"),
                         (float(np.sum(r1 ** 2)), "image 1 only")]:
        m = mk.error_not_sum_of_squares(value, r1, r2)
        assert m.code == "error_not_sum_of_squares" and words in m.evidence
    assert "sum of squares of" in mk.error_not_sum_of_squares(total + 5, r1, r2).evidence
    assert mk.error_not_sum_of_squares("x", r1, r2) is not None


def test_cameras_on_arrays(tv):
    cands = camera2(tv.E)
    right = [i for i in range(4) if mk.wrong_camera(cands[:, :, i], tv.M2) is None]
    assert len(right) == 1
    assert np.allclose(cands[:, :3, right[0]], tv.M2[:, :3])
    for i in set(range(4)) - set(right):
        assert mk.wrong_camera(cands[:, :, i], tv.M2).code == "wrong_camera"
    assert mk.wrong_camera(np.hstack([tv.M2[:, :3], 5 * tv.M2[:, 3:]]), tv.M2) is None  # scale of t is free
    assert mk.points_behind_cameras(tv.X, tv.M1, tv.M2) is None
    assert mk.points_behind_cameras(-tv.X, tv.M1, tv.M2).code == "points_behind"


def test_matches_and_residuals_on_arrays():
    rng = np.random.default_rng(3)
    truth = rng.uniform(0, 300, (20, 2))
    assert mk.points_xy_swapped(truth + 0.5, truth) is None
    assert mk.points_xy_swapped(truth[:, ::-1], truth).code == "xy_swapped"
    e = rng.normal(size=40)
    assert mk.residual_layout(e, e) is None and mk.residual_layout(-e, e) is None
    assert mk.residual_layout(e[::-1], e).code == "residual_layout"
    assert mk.residual_layout(e + 1, e) is None  # wrong values are not a layout problem


def test_ba_mistakes_on_arrays():
    t = np.array([0.0, -1.0, 0.1])
    assert mk.ba_mistakes(100.0, 10.0, t, 1.1 * t) == []
    assert [m.code for m in mk.ba_mistakes(100.0, 100.0, t, t)] == ["ba_not_decreasing"]
    assert [m.code for m in mk.ba_mistakes(100.0, np.nan, t, t)] == ["ba_not_decreasing"]
    assert [m.code for m in mk.ba_mistakes(100.0, 10.0, t, 0.01 * t)] == ["ba_scale_collapse"]


def test_threshold_mistakes_on_arrays():
    P_true = np.arange(36, dtype=float).reshape(12, 3)
    conf = DESIGN_CONFIDENCE
    assert mk.threshold_mistakes(P_true + 1e-4, P_true, conf, THRES, 0.01) == []
    at = np.any(conf == THRES, axis=1)
    below = np.any(conf < THRES, axis=1)
    P = P_true.copy()
    P[at] += 1.0
    assert [m.code for m in mk.threshold_mistakes(P, P_true, conf, THRES, 0.01)] == ["threshold_inclusive"]
    P = P_true.copy()
    P[below] += 1.0
    assert [m.code for m in mk.threshold_mistakes(P, P_true, conf, THRES, 0.01)] == ["threshold_ignored"]
    P = P_true.copy()
    P[np.any((conf > THRES) & (conf <= THRES + 100), axis=1)] = np.nan
    assert [m.code for m in mk.threshold_mistakes(P, P_true, conf, THRES, 0.01)] == ["threshold_too_strict"]


def test_the_catalogue_is_complete_and_strict():
    for code, (name, hint) in mk.KNOWN_MISTAKES.items():
        m = mk.mistake(code, "because")
        assert (m.code, m.name, m.hint, m.evidence) == (code, name, hint, "because")
        assert "\n" not in hint and name in str(m)
    with pytest.raises(ValueError, match="code: expected one of"):
        mk.mistake("no_such_mistake")


def test_checks_never_import_the_solutions():
    from core.paths import KIT_ROOT

    for path in KIT_ROOT.joinpath("starter", "checks").glob("*.py"):
        text = path.read_text()
        assert "import solutions" not in text and "from solutions" not in text, path.name


def test_checks_never_use_opencv():
    """The self-checks say the same with and without OpenCV (Colab has it, a local install may not)."""
    import re

    from core.paths import KIT_ROOT as root

    for path in [*root.joinpath("starter", "checks").glob("*.py"), *root.joinpath("judging").glob("*.py")]:
        assert not re.search(r"\bcv2\b", path.read_text()), path.name
