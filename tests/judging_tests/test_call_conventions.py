"""Calls as the course makes them, and judgments refineF cannot fool.

- Q2 is judged also with refineF switched off inside the sandbox: a polished transposed F (design
  matrix of F^T, then refineF, then unscale) loses the exact-F check, a valid refined one keeps it.
- Q4.1 calls the matcher as the course does (Python int pixels, float images in [0, 1]) and, when
  that is not worth full marks, as earlier kits did (float coordinates, uint8 images): a matcher
  that slices with its coordinates and one that subtracts uint8 windows both get full marks.
- Another year's findM2(F, pts1, pts2, intrinsics, filename=...) is recognised and called that way.
- The feedback of a failing call says how it was called (argument kinds, never values).
- Every returned value is checked against the points the function returned itself: an err that is
  not P's (MultiviewReconstruction) or a pts2 that is not w's matches (compute3D_pts) loses exactly
  that check.

In-process runs (``run_here`` on ``LocalStudent``) for speed, and one batch through the sandbox
with the canary on for the whole path (protocol, submission reading, feedback).
"""

from __future__ import annotations

import json

import corpus
import numpy as np
import pytest
from corpus import variants
from hidden_files import files_grading

from autograder.channels.batch import grade_batch
from autograder.inputs.config import quick_config
from autograder.inputs.build import build_hidden_inputs
from autograder.inputs.keep import default_keep
from autograder.hidden.plugin import LocalStudent, run_here
from autograder.sandbox import ResourceLimits

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

LIMITS = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)


@pytest.fixture(scope="module")
def config():
    return quick_config()


@pytest.fixture(scope="module")
def hidden(config):
    return build_hidden_inputs(config, keep=default_keep())  # the suite's keep


def _reference() -> dict:
    import solutions

    return {name: getattr(solutions, name) for name in solutions.__all__}


def _defined(source: str, name: str):
    import solutions
    from starter.epipolar import refineF

    namespace = {"refineF": refineF, "triangulate": solutions.triangulate}
    exec(compile(source, f"<{name}>", "exec"), namespace)  # noqa: S102 - the corpus's own cell
    return namespace[name]


def _question(hidden, qid: str, **replaced):
    """Question ``qid`` graded here by its hidden test file alone, with ``replaced`` functions and the key's others."""
    result = run_here(LocalStudent(dict(_reference(), **replaced)), hidden, tests=files_grading(qid))
    return next(q for q in result.questions if q.id == qid)


def _test(q, words):
    return next(t for t in q.tests if words in t.name)


# ------------------------------------------------------------------------------------- in-process


def test_polished_transposed_F_loses_the_exact_F_check(hidden):
    q2 = _question(hidden, "Q2", eightpoint=_defined(variants.EIGHTPOINT_TRANSPOSED_REFINED, "eightpoint"))
    exact = _test(q2, "exact F")
    assert exact.score == 0, exact.feedback
    assert "refineF switched off" in exact.feedback
    assert q2.score < q2.max_score


@pytest.mark.parametrize("cell", ["EIGHTPOINT_REFINED_AFTER_UNSCALING", "EIGHTPOINT_EIGH_REFINED",
                                  "EIGHTPOINT_HARTLEY_REFINED"])
def test_valid_refined_eightpoints_keep_full_Q2(hidden, cell):
    q2 = _question(hidden, "Q2", eightpoint=_defined(getattr(variants, cell), "eightpoint"))
    assert q2.score == q2.max_score, [t.feedback for t in q2.tests]


def test_the_refineF_swap_is_undone_after_the_call(hidden):
    from starter.epipolar import refineF

    fn = _defined(variants.EIGHTPOINT_TRANSPOSED_REFINED, "eightpoint")
    _question(hidden, "Q2", eightpoint=fn)
    assert fn.__globals__["refineF"] is refineF


def test_refineF_called_through_a_module_is_switched_off_too(hidden):
    # 2018-2021 hand-ins write "import helper" and call helper.refineF(...): the polished transposed
    # F must lose the exact-F check that way as well, and the module keep its refineF after.
    import types

    import solutions
    from starter.epipolar import refineF

    helper = types.ModuleType("helper")
    helper.refineF = refineF
    source = variants.EIGHTPOINT_TRANSPOSED_REFINED.replace("refineF(", "helper.refineF(")
    assert "helper.refineF(" in source
    namespace = {"helper": helper, "triangulate": solutions.triangulate}
    exec(compile(source, "<helper.refineF>", "exec"), namespace)  # noqa: S102 - the corpus's own cell
    q2 = _question(hidden, "Q2", eightpoint=namespace["eightpoint"])
    exact = _test(q2, "exact F")
    assert exact.score == 0, exact.feedback
    assert "refineF switched off" in exact.feedback
    assert helper.refineF is refineF


@pytest.mark.parametrize("cell", ["EPIPOLAR_SLICES_WITH_COORDINATES", "EPIPOLAR_UINT8_DIFFERENCES"])
def test_matchers_correct_on_the_course_inputs_get_full_Q41(hidden, cell):
    q41 = _question(hidden, "Q4.1", epipolarCorrespondence=_defined(getattr(variants, cell), "epipolarCorrespondence"))
    assert q41.score == q41.max_score, [t.feedback for t in q41.tests]


def test_the_course_call_is_tried_first_and_named(hidden):
    q41 = _question(hidden, "Q4.1")
    assert all("integer pixel coordinates" in t.feedback for t in q41.tests), [t.feedback for t in q41.tests]
    sliced = _question(hidden, "Q4.1", epipolarCorrespondence=_defined(variants.EPIPOLAR_UINT8_DIFFERENCES,
                                                                      "epipolarCorrespondence"))
    assert all("integer pixel coordinates" in t.feedback for t in sliced.tests)


def test_another_years_findM2_signature_gets_full_Q33(hidden):
    q33 = _question(hidden, "Q3.3", findM2=_defined(variants.FINDM2_INTRINSICS, "findM2"))
    assert q33.score == q33.max_score, [t.feedback for t in q33.tests]
    assert "intrinsics" in q33.tests[0].feedback


def test_a_failing_call_says_how_it_was_called(hidden):
    q33 = _question(hidden, "Q3.3", findM2=_defined(variants.FINDM2_INTRINSICS_BROKEN, "findM2"))
    assert q33.score == 0
    text = "\n".join(t.feedback for t in q33.tests)
    assert "called as findM2(F: a 3x3 float64 array" in text and "intrinsics: a dict with K1, K2" in text, text


# ------------------------------------------------------------------------ every returned value is checked


def _wrapped(source: str, name: str):
    """The function ``name`` of a corpus wrapper cell, wrapping the answer key's function of that name."""
    import solutions

    namespace = {name: getattr(solutions, name)}
    exec(compile(source, f"<{name}>", "exec"), namespace)  # noqa: S102 - the corpus's own cell
    return namespace[name]


def test_an_err_inconsistent_with_P_loses_exactly_the_err_check(hidden):
    q6 = _question(hidden, "Q6", MultiviewReconstruction=_wrapped(variants.WRAP_MULTIVIEW_MEAN_ERR,
                                                                  "MultiviewReconstruction"))
    lost = [t for t in q6.tests if t.score < t.max_score]
    assert [t.name for t in lost] == ["err is the total squared reprojection error of P over the detections used"], \
        [(t.name, t.feedback) for t in q6.tests]
    assert lost[0].score == 0 and "Likely mistake: error not the sum of squares" in lost[0].feedback, lost[0].feedback
    assert "from your P" in lost[0].feedback


def test_pts2_inconsistent_with_w_loses_exactly_the_pts2_check(hidden):
    q42 = _question(hidden, "Q4.2", compute3D_pts=_wrapped(variants.WRAP_COMPUTE3D_RETURNS_PTS1, "compute3D_pts"))
    lost = [t for t in q42.tests if t.score < t.max_score]
    assert [t.name for t in lost] == ["pts2 are the matches w was triangulated from"], \
        [(t.name, t.feedback) for t in q42.tests]
    assert "of pts1 and of your pts2 (goal >= 90%)" in lost[0].feedback, lost[0].feedback


def _triangulate_mean_err(C1, pts1, C2, pts2):
    import solutions

    w, err = solutions.triangulate(C1, pts1, C2, pts2)
    return w, err / len(w)


def _findM2_C2_of_K1(F, pts1, pts2, K1, K2):
    import solutions

    M2, C2, w = solutions.findM2(F, pts1, pts2, K1, K2)
    return M2, K1 @ M2, w


def _ba_o2_of_the_start(K1, M1, p1, K2, M2_init, p2, w_init):
    import solutions

    M2, w, o1, o2 = solutions.bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init)
    return M2, w, o1, o1


# function -> (its replacement returning one companion value inconsistent, question, the one check to lose)
INCONSISTENT = {
    "triangulate": (_triangulate_mean_err, "Q3.2", "err is the total squared reprojection error of w"),
    "findM2": (_findM2_C2_of_K1, "Q3.3", "C2 = K2 M2 and w are the points triangulated with it"),
    "bundleAdjustment": (_ba_o2_of_the_start, "Q5", "o1 and o2 are the reprojection errors before and after"),
}


@pytest.mark.parametrize("function", list(INCONSISTENT))
def test_a_companion_value_is_judged_against_the_returned_points(hidden, function):
    fn, qid, check = INCONSISTENT[function]
    q = _question(hidden, qid, **{function: fn})
    assert [t.name for t in q.tests if t.score < t.max_score] == [check], [(t.name, t.feedback) for t in q.tests]


def test_pts2_judged_as_the_matches_w_was_triangulated_from(hidden):
    import numpy as np

    from judging import correspondence as jc
    from solutions import triangulate

    def linear(C1, pts1, C2, pts2):
        return triangulate(C1, pts1, C2, pts2)[1]

    c = hidden.prepared["correspondence"].points_case
    off = c.truth2 + np.random.default_rng(3).normal(0, 1.0, c.truth2.shape)   # matches off their lines
    for pts2 in (c.truth2, np.rint(c.truth2), off, off[:, ::-1]):
        w = triangulate(c.C1, c.pts1, c.C2, pts2)[0]
        assert jc.pts2_reported(pts2, w, c.C1, c.pts1, c.C2, c.tol, linear).passed
    w = triangulate(c.C1, c.pts1, c.C2, c.truth2)[0]
    v = jc.pts2_reported(c.pts1, w, c.C1, c.pts1, c.C2, c.tol, linear)
    assert not v.passed and v.fraction == 0, v.sentence
    assert not jc.pts2_reported(c.truth2[:, ::-1], w, c.C1, c.pts1, c.C2, c.tol, linear).passed


def test_the_reference_err_passes_with_two_or_three_views(hidden):
    from judging import multiview as jm
    from solutions import MultiviewReconstruction

    step = hidden.prepared["multiview"].sequence[0]
    P, err = MultiviewReconstruction(step.C[0], step.pts[0], step.C[1], step.pts[1], step.C[2], step.pts[2],
                                     step.Thres)
    low, high = jm.err_bounds(P, step.C, step.pts, step.Thres)
    assert 0 < low * (1 - 1e-9) <= err <= high * (1 + 1e-9)   # equal when every keypoint has two views
    assert jm.err_reported(err, P, step.C, step.pts, step.Thres).passed
    assert jm.err_reported(low, P, step.C, step.pts, step.Thres).passed       # two best views of each keypoint
    assert not jm.err_reported(err / 10, P, step.C, step.pts, step.Thres).passed
    assert not jm.err_reported(None, P, step.C, step.pts, step.Thres).passed  # P alone: no err to check


def test_numpy2_removals_get_a_hint():
    from autograder.feedback.words import failure
    from autograder.sandbox import CallOutcome

    text = failure("eightpoint", CallOutcome("exception", message="AttributeError: module 'numpy' has no "
                                                                  "attribute 'float' (in eightpoint, q2.ipynb, line 3)"))
    assert text.startswith("eightpoint raised AttributeError") and "np.float" in text, text


# ------------------------------------------------------------------------------------- sandbox


SUBMISSIONS = {
    "transposed_refined_loses_q2": [("eightpoint", variants.EIGHTPOINT_TRANSPOSED_REFINED)],
    "slicing_matcher_full": [("epipolarCorrespondence", variants.EPIPOLAR_SLICES_WITH_COORDINATES)],
    "uint8_matcher_full": [("epipolarCorrespondence", variants.EPIPOLAR_UINT8_DIFFERENCES)],
    "findM2_intrinsics_full": [("findM2", variants.FINDM2_INTRINSICS)],
    "findM2_intrinsics_broken": [("findM2", variants.FINDM2_INTRINSICS_BROKEN)],
}


@pytest.fixture(scope="module")
def graded(tmp_path_factory, config):
    import nbformat

    root = tmp_path_factory.mktemp("conventions")
    paths = []
    for name, replacements in SUBMISSIONS.items():
        nbs = corpus.notebooks("key")
        for function, source in replacements:
            corpus.replace_function(nbs, function, source)
        folder = root / "subs" / name
        folder.mkdir(parents=True)
        for stem, nb in nbs.items():
            nbformat.write(nb, folder / f"{stem}.ipynb")
        paths.append(folder)
    out = root / "out"
    grade_batch(paths, out, jobs=2, config=config, progress=False, pictures=False, limits=LIMITS)
    return {name: json.loads((out / name / "results.json").read_text()) for name in SUBMISSIONS}


def _tests(results, words) -> list:
    return [t for t in results["tests"] if words in t["name"]]


def test_sandbox_polished_transposed_F_loses_q2(graded):
    r = graded["transposed_refined_loses_q2"]
    exact = _tests(r, "exact F")
    assert exact and all(t["score"] == 0 for t in exact), exact
    assert "refineF switched off" in exact[0]["output"]


@pytest.mark.parametrize("name", ["slicing_matcher_full", "uint8_matcher_full"])
def test_sandbox_matchers_get_full_q41(graded, name):
    tests = _tests(graded[name], "matches on")
    assert tests, (graded[name].get("output", "")[:2000], [t["name"] for t in graded[name]["tests"]])
    assert all(t["score"] == t["max_score"] for t in tests), tests


def test_sandbox_findM2_with_intrinsics_gets_full_q33(graded):
    r = graded["findM2_intrinsics_full"]
    tests = [t for t in r["tests"] if "M2" in t["name"] or "C2" in t["name"]]
    assert tests and all(t["score"] == t["max_score"] for t in tests), tests


def test_sandbox_failing_call_says_how_it_was_called(graded):
    r = graded["findM2_intrinsics_broken"]
    tests = [t for t in r["tests"] if "M2 is the camera" in t["name"]]
    assert tests and tests[0]["score"] == 0
    assert "called as findM2(F: a 3x3 float64 array" in tests[0]["output"], tests[0]["output"]


def test_another_years_compute3D_pts_gets_full_Q42(hidden):
    import solutions

    fn = _defined(variants.COMPUTE3D_FIVE_ARGUMENTS, "compute3D_pts")
    fn.__globals__.update(epipolarCorrespondence=solutions.epipolarCorrespondence, findM2=solutions.findM2)
    q42 = _question(hidden, "Q4.2", compute3D_pts=fn, triangulate=lambda *a: None)
    assert q42.score == q42.max_score, [t.feedback for t in q42.tests]
    assert "as the course calls it" in q42.tests[0].feedback


# ------------------------------------------------------------------------------------- one home for the conventions
# judging.conventions says how another year's signature is called; the grader (above) and the public
# self-checks (below) both follow it, so one program gets the same call in both.

def _points_first_findM2():
    """Fall 2023's findM2(pts1, pts2, F, K1, K2), returning five values (M1, C1 first)."""
    import solutions

    def findM2(pts1, pts2, F, K1, K2):
        M2, C2, P = solutions.findM2(F, pts1, pts2, K1, K2)
        M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
        return M1, K1 @ M1, M2, C2, P

    return findM2


def test_conventions_recognise_each_years_signature_by_its_parameters():
    from judging.conventions import Signature, findM2_style, five_arguments, signature_of_callable

    def kit(F, pts1, pts2, K1, K2): ...
    def intr(F, pts1, pts2, intrinsics, filename="q3_3.npz"): ...
    def first(pts1, pts2, F, K1, K2): ...
    def c3d(temple_pts1, intrinsics, F, im1, im2): ...

    assert [findM2_style(signature_of_callable(f)) for f in (kit, intr, first)] == ["kit", "intrinsics", "points_first"]
    assert findM2_style(None) == "kit"
    assert findM2_style(Signature(("p1", "p2", "F", "k1", "k2"))) == "points_first"
    assert findM2_style(Signature(("a", "b", "c", "d", "e"))) == "kit"       # nothing to tell it by: the kit's
    assert findM2_style(Signature(("pts1", "pts2", "F", "K1", "K2"), varargs="rest")) == "kit"
    assert five_arguments(signature_of_callable(c3d)) and not five_arguments(signature_of_callable(kit))


def test_five_returned_values_are_read_by_what_each_is():
    from judging.pose import read_findM2
    from starter.pose import camera2

    rng = np.random.default_rng(0)
    K1, K2 = np.diag([500.0, 500.0, 1.0]), np.diag([520.0, 510.0, 1.0])
    M2 = camera2(np.array([[0.0, -1, 0], [1, 0, -1], [0, 1, 0]]))[:, :, 1]
    M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    P = rng.normal(size=(10, 3))
    for value in ((M1, K1 @ M1, M2, K2 @ M2, P), (M2, K2 @ M2, P, M1, K1 @ M1)):
        got = read_findM2(value, 10)
        assert np.array_equal(got[0], M2) and np.array_equal(got[1], K2 @ M2) and np.array_equal(got[2], P)


def test_points_first_findM2_gets_full_Q33(hidden):
    q33 = _question(hidden, "Q3.3", findM2=_points_first_findM2())
    assert q33.score == q33.max_score, [t.feedback for t in q33.tests]
    assert "findM2(pts1, pts2, F, K1, K2)" in q33.tests[0].feedback


@pytest.mark.parametrize("style", ["intrinsics", "points_first"])
def test_the_self_check_calls_findM2_as_the_grader_does(style):
    from starter.checks import check_findM2

    fn = (_defined(variants.FINDM2_INTRINSICS, "findM2") if style == "intrinsics" else _points_first_findM2())
    report = check_findM2(fn, verbose=False)
    assert report.passed, report.items
    assert any("called as its parameters ask" in n for n in report.notes)


def test_the_self_check_calls_five_argument_compute3D_pts_as_the_grader_does():
    import solutions
    from starter.checks import check_compute3D_pts

    fn = _defined(variants.COMPUTE3D_FIVE_ARGUMENTS, "compute3D_pts")
    fn.__globals__.update(epipolarCorrespondence=solutions.epipolarCorrespondence, findM2=solutions.findM2)
    report = check_compute3D_pts(fn, verbose=False)
    assert report.passed, report.items


def test_the_self_check_counts_the_matcher_and_triangulate_when_compute3D_pts_gives_cameras_only(tmp_path,
                                                                                                   monkeypatch):
    """2022-2024's compute3D_pts that writes result/q4_2.npz and returns M2: the folder is made (as the
    sandbox has it) and the points of the student's matcher and triangulate count, as in the grader."""
    import solutions
    from starter.checks import check_compute3D_pts

    source = variants.COMPUTE3D_FIVE_ARGUMENTS.replace(
        "    return P\n", "    np.savez('result/q4_2.npz', M2=M2, C2=C2)\n    return M2\n")
    fn = _defined(source, "compute3D_pts")
    fn.__globals__.update(epipolarCorrespondence=solutions.epipolarCorrespondence, findM2=solutions.findM2,
                          triangulate=solutions.triangulate)
    monkeypatch.chdir(tmp_path)
    report = check_compute3D_pts(fn, verbose=False)
    assert report.passed, report.items
    assert (tmp_path / "result" / "q4_2.npz").is_file()
    assert any("epipolarCorrespondence and triangulate" in n for n in report.notes)


def test_the_sandbox_and_the_self_checks_make_the_handouts_result_folders():
    from autograder.sandbox.script import RESULT_DIRS
    from core.paths import RESULT_FOLDERS

    assert {"results", "result"} <= set(RESULT_FOLDERS)
    assert {"results", "../results", "result", "../result"} <= set(RESULT_DIRS)
