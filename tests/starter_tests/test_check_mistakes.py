"""Every known mistake of the catalogue is named by its self-check, and every valid method passes.

Each student function here is a notebook cell's text executed in a namespace of its own, as a
notebook runs it (``refineF`` is the name the notebook's import cell binds), so that the
self-check can switch refineF off by that name (starter.checks.instrument).  For each code of
``judging.mistakes.KNOWN_MISTAKES`` there is at least one implementation with that mistake alone,
and its self-check must fail and name exactly that mistake; the mistakes of ``eightpoint`` are
tried with refineF called and not called.  Every valid alternative of the corpus (tests/support/corpus:
the programs named "full_marks", and the valid cells of variants.py) must pass every
self-check with no mistake named.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize

import corpus
import solutions as ref
from corpus import variants
from judging.mistakes import KNOWN_MISTAKES
from scenes.car import make_car_scene, write_car
from scenes.temple import make_temple_scene, write_temple
from starter import camera2, invRodrigues, refineF, rodrigues
from starter.checks import (
    CHECKS,
    check_eightpoint,
    check_epipolarCorrespondence,
)
from core.refine_switch import switched_off
from starter.checks.instrument import refineF_switched_off
from starter.checks.multiview import THRES



@pytest.fixture(scope="module")
def no_data(tmp_path_factory):
    return tmp_path_factory.mktemp("empty")


@pytest.fixture(scope="module")
def default_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("default-data")
    write_temple(make_temple_scene(7, width=320, height=240, n_corresp=60, n_outliers=10, n_coords=40,
                                   supersample=1), root / "temple")
    write_car(make_car_scene(7, n_times=1, render=False), root / "q6")
    return root


def cell(source: str, name: str, **given):
    """The function ``name`` defined by the cell ``source``, run in a fresh notebook-like namespace
    holding the notebook's helpers and ``given`` (earlier functions)."""
    namespace = {"__name__": "notebook", "np": np, "refineF": refineF, "camera2": camera2,
                 "rodrigues": rodrigues, "invRodrigues": invRodrigues, **given}
    exec(compile(source, "<student cell>", "exec"), namespace)  # noqa: S102 - the tests' own cells
    return namespace[name]


def codes(report) -> set[str]:
    return {m.code for m in report.mistakes}


# ------------------------------------------------------------------------ one implementation per mistake

def _findM2_wrong_camera(F, pts1, pts2, K1, K2):
    right, _, _ = ref.findM2(F, pts1, pts2, K1, K2)
    cands = camera2(ref.essentialMatrix(F, K1, K2))
    M2 = next(cands[:, :, i] for i in range(4) if not np.allclose(cands[:, :, i], right))
    w, _ = ref.triangulate(K1 @ np.eye(3, 4), pts1, K2 @ M2, pts2)
    return M2, K2 @ M2, w


def _findM2_camera1_depth_only(F, pts1, pts2, K1, K2):
    # Keeps the candidates with every point in front of camera 1 (not camera 2), then the smallest error.
    cands = camera2(ref.essentialMatrix(F, K1, K2))
    best = None
    for i in range(4):
        w, err = ref.triangulate(K1 @ np.eye(3, 4), pts1, K2 @ cands[:, :, i], pts2)
        if np.all(w[:, 2] > 0) and (best is None or err < best[0]):
            best = (err, cands[:, :, i], K2 @ cands[:, :, i], w)
    return best[1:]


def _residual_x_packing(K1, M1, p1, K2, p2, x):
    n = len(p1)
    w = np.asarray(x[:3 * n]).reshape(3, n).T   # x, y, z of all points read as three blocks
    return ref.rodriguesResidual(K1, M1, p1, K2, p2, np.concatenate([w.ravel(), x[3 * n:]]))


def _ba_collapsing(K1, M1, p1, K2, M2_init, p2, w_init):
    """Drifts into the degenerate optimum of every two-view bundle adjustment: t towards 0 and the
    points towards infinity along camera 1's rays, where camera 2 sees a pure rotation.  The error
    drops below the start's, but the scene is gone."""
    rays = np.column_stack([p1, np.ones(len(p1))]) @ np.linalg.inv(K1).T
    w = 1e6 * rays

    def error(r):
        M2 = np.hstack([rodrigues(r), 1e-6 * M2_init[:, 3:]])
        x = np.concatenate([w.ravel(), r, M2[:, 3]])
        return float(np.sum(ref.rodriguesResidual(K1, M1, p1, K2, p2, x) ** 2))

    r = scipy.optimize.minimize(error, invRodrigues(M2_init[:, :3]), method="Powell").x
    M2 = np.hstack([rodrigues(r), 1e-6 * M2_init[:, 3:]])
    x0 = np.concatenate([np.ravel(w_init), invRodrigues(M2_init[:, :3]), M2_init[:, 3]])
    return M2, w, float(np.sum(ref.rodriguesResidual(K1, M1, p1, K2, p2, x0) ** 2)), error(r)


def _threshold(shift):
    return lambda C1, pts1, C2, pts2, C3, pts3, Thres: ref.MultiviewReconstruction(
        C1, pts1, C2, pts2, C3, pts3, Thres + shift)


# code -> [(label, check name, function factory, expected codes)].  A wrong camera puts the
# points behind a camera too, and both are true of it: the one case naming two.
Q2 = ["f_transposed", "f_rank3", "f_not_unscaled", "f_unscaled_wrong_way", "xy_swapped", "uint16_wraparound"]
CASES = {
    "e_k_order": [("K1^T F K2", "essentialMatrix", lambda: cell(variants.ESSENTIAL_K_SWAPPED, "essentialMatrix"))],
    "e_missing_k": [("F K1", "essentialMatrix", lambda: lambda F, K1, K2: F @ K1),
                    ("F alone", "essentialMatrix", lambda: lambda F, K1, K2: F)],
    "e_inverse_k": [("inverses", "essentialMatrix",
                     lambda: lambda F, K1, K2: np.linalg.inv(K2).T @ F @ np.linalg.inv(K1))],
    "e_same_k": [("K2 both sides", "essentialMatrix", lambda: lambda F, K1, K2: K2.T @ F @ K2)],
    "e_transposed": [("transposed", "essentialMatrix", lambda: lambda F, K1, K2: (K2.T @ F @ K1).T)],
    "w_not_divided": [("err of the divided points", "triangulate",
                       lambda: cell(variants.TRIANGULATE_W_NOT_DIVIDED, "triangulate")),
                      ("err of w itself", "triangulate",
                       lambda: cell(variants.TRIANGULATE_W_NOT_DIVIDED_OWN_ERR, "triangulate"))],
    "error_not_sum_of_squares": [("mean", "triangulate", lambda: cell(variants.TRIANGULATE_MEAN_ERROR, "triangulate"))],
    "points_behind": [("mirrored points", "triangulate",
                       lambda: cell(variants.TRIANGULATE_POINTS_MIRRORED, "triangulate"))],
    "wrong_camera": [("another candidate", "findM2", lambda: _findM2_wrong_camera)],
    "depth_one_camera": [("camera 1 only", "findM2", lambda: _findM2_camera1_depth_only)],
    "residual_layout": [("interleaved", "rodriguesResidual",
                         lambda: cell(variants.WRAP_RESIDUAL_INTERLEAVED, "rodriguesResidual",
                                      rodriguesResidual=ref.rodriguesResidual))],
    "x_packing": [("coordinates by blocks", "rodriguesResidual", lambda: _residual_x_packing)],
    "ba_not_decreasing": [("returns its start", "bundleAdjustment",
                           lambda: cell(variants.BA_RETURNS_START, "bundleAdjustment",
                                        rodriguesResidual=ref.rodriguesResidual))],
    "ba_scale_collapse": [("t driven to 0", "bundleAdjustment", lambda: _ba_collapsing)],
    "threshold_inclusive": [(">=", "MultiviewReconstruction",
                             lambda: cell(variants.WRAP_THRESHOLD_INCLUSIVE, "MultiviewReconstruction",
                                          MultiviewReconstruction=ref.MultiviewReconstruction))],
    "threshold_ignored": [("no threshold", "MultiviewReconstruction", lambda: _threshold(-THRES))],
    "threshold_too_strict": [("Thres + 100", "MultiviewReconstruction", lambda: _threshold(+100))],
}
for _code in Q2:
    # refineF returns rank 2, switched off too (its minimisation alone is skipped): without an SVD
    # step of their own, an eightpoint calling it still returns rank 2, which is right.
    CASES[_code] = [(f"refineF {'called' if refine else 'not called'}", "eightpoint",
                     (lambda c=_code, r=refine: cell(variants.eightpoint_cell(c, refine=r), "eightpoint")))
                    for refine in (False, True) if not (refine and _code == "f_rank3")]
CASES["xy_swapped"].append(("matcher returns (y, x)", "epipolarCorrespondence",
                            lambda: cell(variants.WRAP_XY_SWAPPED, "epipolarCorrespondence",
                                         epipolarCorrespondence=ref.epipolarCorrespondence)))
EXPECTED = {"wrong_camera": {"wrong_camera", "points_behind"}}

TABLE = [(code, label, check, make) for code, rows in CASES.items() for label, check, make in rows]


def test_every_known_mistake_has_an_implementation():
    assert set(CASES) == set(KNOWN_MISTAKES)


@pytest.mark.parametrize("code, label, check, make", TABLE, ids=[f"{c}-{lab}" for c, lab, _, _ in TABLE])
def test_the_self_check_names_the_mistake(code, label, check, make, no_data):
    report = CHECKS[check](make(), root=no_data, verbose=False)
    assert not report.passed, report.text()
    assert codes(report) == EXPECTED.get(code, {code}), report.text()


@pytest.mark.parametrize("code", [c for c in Q2 if c != "f_rank3"])
def test_refineF_does_not_hide_the_mistake_on_the_default_data_either(code, default_root):
    report = check_eightpoint(cell(variants.eightpoint_cell(code, refine=True), "eightpoint"), root=default_root,
                              verbose=False)
    assert not report.passed and code in codes(report), report.text()


# ------------------------------------------------------------------------ refineF switched off, and put back

def test_refineF_is_switched_off_for_the_call_and_put_back():
    fn = cell(variants.eightpoint_cell(refine=True), "eightpoint")
    tv_pts = np.random.default_rng(0).uniform(0, 640, (2, 12, 2))
    F, calls = refineF_switched_off(fn, tv_pts[0], tv_pts[1], 640.0)
    assert calls == 1 and F.shape == (3, 3)
    assert fn.__globals__["refineF"] is refineF

    plain = cell(variants.eightpoint_cell(), "eightpoint")
    del plain.__globals__["refineF"]
    _, calls = refineF_switched_off(plain, tv_pts[0], tv_pts[1], 640.0)
    assert calls == 0 and "refineF" not in plain.__globals__   # nothing added, nothing left behind


def test_another_name_for_refineF_is_switched_off_too():
    source = variants.eightpoint_cell(refine=True).replace("refineF(", "polish(")
    fn = cell(source, "eightpoint", polish=refineF)
    _, calls = refineF_switched_off(fn, *np.random.default_rng(1).uniform(0, 640, (2, 12, 2)), 640.0)
    assert calls == 1 and fn.__globals__["polish"] is refineF


def test_the_namespace_is_restored_when_the_student_code_raises():
    # A refineF of the student's own is replaced for the call: it must come back even when the call raises.
    def own_refineF(F, pts1, pts2):
        return F

    source = "def broken(pts1, pts2, M):\n    refineF(np.eye(3), pts1, pts2)\n    raise ZeroDivisionError('boom')\n"
    broken = cell(source, "broken", refineF=own_refineF)
    g = broken.__globals__
    with pytest.raises(ZeroDivisionError):
        with switched_off(broken) as run:
            broken(np.zeros((8, 2)), np.zeros((8, 2)), 1.0)
    assert run.calls == 1 and g["refineF"] is own_refineF
    report = check_eightpoint(broken, verbose=False)
    assert not report.passed and g["refineF"] is own_refineF


def test_the_check_says_when_it_switched_refineF_off(no_data):
    on = check_eightpoint(cell(variants.eightpoint_cell(refine=True), "eightpoint"), root=no_data, verbose=False)
    off = check_eightpoint(cell(variants.eightpoint_cell(), "eightpoint"), root=no_data, verbose=False)
    assert on.passed and off.passed
    assert any("refineF switched off" in i.name for i in on.items)
    assert not any("refineF switched off" in i.name for i in off.items)


# ------------------------------------------------------------------------ errors point to the student's line

_WINDOWS_OF_TWO_SIZES = """\
import numpy as np


def epipolarCorrespondence(im1, im2, F, x1, y1):
    w1 = np.asarray(im1)[int(y1) - 3:int(y1) + 4, int(x1) - 3:int(x1) + 4]
    scores = [float(((w1 - np.asarray(im2)[y:y + 5, :5]) ** 2).sum()) for y in range(3)]
    return x1, y1 + int(np.argmin(scores))
"""


def test_an_error_in_student_code_names_its_function_and_line(no_data):
    source = _WINDOWS_OF_TWO_SIZES
    # A 7x7 window compared with 5x5 ones: the error comes where they are compared, in a list
    # comprehension, on every scene (a border no longer decides it): the function around it is
    # named, with the comprehension's line.
    line = next(k for k, text in enumerate(source.splitlines(), start=1) if "scores = [" in text)
    report = check_epipolarCorrespondence(cell(source, "epipolarCorrespondence"), root=no_data, verbose=False)
    assert not report.passed
    message = report.items[0].value
    assert "could not be broadcast" in message, report.text()
    assert message.endswith(f"(in epipolarCorrespondence, student cell, line {line})"), message


def test_an_error_inside_a_kit_helper_is_placed_at_the_students_call(no_data):
    source = variants.eightpoint_cell(refine=True).replace("F = refineF(F, p1, p2)", "F = refineF(F, p1[:5], p2)")
    report = check_eightpoint(cell(source, "eightpoint"), root=no_data, verbose=False)
    line = next(k for k, text in enumerate(source.splitlines(), start=1) if "refineF(F, p1[:5]" in text)
    assert f"(in eightpoint, student cell, line {line})" in report.items[0].value, report.text()


# ------------------------------------------------------------------------ valid methods pass everything

VALID_PROGRAMS = [n for n in corpus.IN_PROCESS if n.endswith("full_marks") and corpus.CASES[n].base == "key"
                  and n != "duplicated_cells_full_marks"]


def program(name: str) -> dict:
    """The homework functions a corpus submission defines, its notebooks' statements executed in order."""
    namespace = corpus.program_namespace(name, CHECKS)
    return {f: namespace[f] for f in CHECKS}


@pytest.mark.slow
@pytest.mark.parametrize("name", VALID_PROGRAMS)
def test_every_valid_corpus_program_passes_every_self_check(name, default_root):
    functions = program(name)
    for function, check in CHECKS.items():
        report = check(functions[function], root=default_root, verbose=False)
        assert report.passed and report.mistakes == [], f"{name}, {function}:\n{report.text()}"


VALID_CELLS = {
    "eightpoint, refineF before unscaling": ("eightpoint", variants.eightpoint_cell(refine=True)),
    "eightpoint, refineF after unscaling": ("eightpoint", variants.EIGHTPOINT_REFINED_AFTER_UNSCALING),
    "eightpoint, eigh and refineF": ("eightpoint", variants.EIGHTPOINT_EIGH_REFINED),
    "eightpoint, eigh": ("eightpoint", variants.eightpoint_cell(solver="eigh")),
    "eightpoint, Hartley": ("eightpoint", variants.EIGHTPOINT_HARTLEY),
    "eightpoint, no refineF": ("eightpoint", variants.EIGHTPOINT_NO_REFINE),
    "matcher, absolute differences": ("epipolarCorrespondence", variants.EPIPOLAR_SAD),
}


@pytest.mark.parametrize("label", list(VALID_CELLS))
def test_every_valid_cell_passes_its_self_check(label, default_root):
    function, source = VALID_CELLS[label]
    report = CHECKS[function](cell(source, function), root=default_root, verbose=False)
    assert report.passed and report.mistakes == [], report.text()
