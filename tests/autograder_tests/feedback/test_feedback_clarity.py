"""Feedback that does not mislead a student: a failed check says so in words, a repeated error is
said once with a count, the catalogue names only what its test tells apart, a student's own
definition of a given helper is noted, and NumPy 2's ragged-array error gets a hint.

Hidden checks are graded in this process (``run_here`` on a ``LocalStudent``, the hidden inputs of
the quick config) with the reference's functions and one function changed.  Those tests are in the
full tier (marked slow): making the hidden inputs takes about 8 s, which the full run pays once for
this file and tests/autograder_tests/feedback/test_feedback_calls.py together (the suite's keep).  The self-check's side of
most of them (no hidden inputs) stays in the fast tier.
"""

from __future__ import annotations

import numpy as np
import pytest

import solutions
from autograder.inputs.config import quick_config
from autograder.inputs.build import build_hidden_inputs
from autograder.inputs.keep import default_keep
from autograder.hidden.plugin import HIDDEN_DIR, LocalStudent, run_here


@pytest.fixture(scope="module")
def hidden():
    return build_hidden_inputs(quick_config(), keep=default_keep())  # the suite's keep


def _reference() -> dict:
    return {name: getattr(solutions, name) for name in solutions.__all__}


def _graded(hidden, concept: str, **changed):
    """{test name: TestResult} of autograder/hidden/test_<concept>.py with ``changed`` functions."""
    result = run_here(LocalStudent(dict(_reference(), **changed)), hidden, tests=[HIDDEN_DIR / f"test_{concept}.py"])
    return {t.name: t for q in result.questions for t in q.tests}


# ------------------------------------------------------------------------------------------------
# NumPy 2's ragged-array error


def ragged_essential(F, K1, K2):
    """Stacks rows of different length, as np.array refuses since NumPy 1.24."""
    return np.array([F[0], F[1, :2], F[2]], dtype=float)


@pytest.mark.slow
def test_ragged_array_error_gets_a_hint_in_the_hidden_feedback(hidden):
    tests = _graded(hidden, "essential", essentialMatrix=ragged_essential)
    text = "\n".join(t.feedback for t in tests.values())
    assert "inhomogeneo" in text, text               # the error itself is still quoted
    assert "different lengths or shapes" in text and "np.array" in text, text


def test_ragged_array_error_gets_a_hint_in_the_self_check():
    from starter.checks.report import call

    out = call(ragged_essential, np.eye(3), np.eye(3), np.eye(3))
    assert out.status == "error" and "different lengths or shapes" in out.message, out.message


# ------------------------------------------------------------------------------------------------
# the catalogue names only what its test tells apart (Q6's err)


def err_over_every_detection(C1, pts1, C2, pts2, C3, pts3, Thres):
    """The right P, but err the total over every detection, those at or below Thres too (of the
    points a reconstruction from all of them gives): a sum of squares, over detections not used."""
    P, _ = solutions.MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres)
    P_all, _ = solutions.MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, -1e9)
    from core.geometry import project

    err = sum(float(np.nansum((np.asarray(p, float)[:, :2] - project(C, P_all)) ** 2)) for C, p in
              ((C1, pts1), (C2, pts2), (C3, pts3)))
    return P, err


@pytest.mark.slow
def test_err_over_unused_detections_is_not_called_not_the_sum_of_squares(hidden):
    tests = _graded(hidden, "multiview", MultiviewReconstruction=err_over_every_detection)
    t = tests["err is the total squared reprojection error of P over the detections used"]
    assert t.score < t.max_score, t.feedback       # the check still fails: err is not P's
    assert "not the sum of squares" not in t.feedback, t.feedback


@pytest.mark.slow
def test_err_hint_does_not_say_two_images_for_three_views(hidden):
    from corpus import variants

    namespace = {"MultiviewReconstruction": solutions.MultiviewReconstruction}
    exec(compile(variants.WRAP_MULTIVIEW_MEAN_ERR, "<cell>", "exec"), namespace)  # noqa: S102 - the corpus's cell
    t = _graded(hidden, "multiview", MultiviewReconstruction=namespace["MultiviewReconstruction"])[
        "err is the total squared reprojection error of P over the detections used"]
    assert "Likely mistake: error not the sum of squares" in t.feedback, t.feedback   # a mean: told apart
    assert "both images" not in t.feedback and "image 1 only" not in t.feedback, t.feedback


def test_q6_err_variants_about_one_image_are_not_tried():
    from judging.mistakes import error_not_sum_of_squares

    r = np.random.default_rng(0).normal(size=(9, 2))
    # With the observations of three views in one set, err = 0 is no "image 2 only" (there is none).
    assert error_not_sum_of_squares(0.0, r, only_named=True) is None
    assert "mean squared" in error_not_sum_of_squares(float(np.sum(r ** 2)) / 9, r, only_named=True).evidence


# ------------------------------------------------------------------------------------------------
# a student's own definition of a given helper


def own_rodrigues(r):
    """A student's rodrigues with a sign slip: the transpose of the rotation."""
    from starter import rodrigues

    return rodrigues(r).T


@pytest.mark.slow
def test_own_helper_is_noted_in_the_feedback_of_the_question_using_it(hidden):
    from solutions import bundle

    # The answer key's Q5 functions call the rodrigues of their module: put the student's there, as a
    # notebook's own definition replaces the imported one.
    saved = bundle.rodrigues
    bundle.rodrigues = own_rodrigues
    try:
        tests = _graded(hidden, "bundle", rodrigues=own_rodrigues)
    finally:
        bundle.rodrigues = saved
    lost = [t for t in tests.values() if t.score < t.max_score]
    assert lost, [(t.name, t.feedback) for t in tests.values()]
    for t in lost:
        assert "your own rodrigues was used in place of the given one" in t.feedback, t.feedback
    assert all("your own" not in t.feedback for t in tests.values() if t.score >= t.max_score)


def test_submission_notes_a_given_helper_it_defines(tmp_path):
    from autograder.submission.read import load_submission

    (tmp_path / "submission.py").write_text("import numpy as np\n\ndef camera2(E):\n    return np.zeros((3, 4, 4))\n\n"
                                            "def eightpoint(pts1, pts2, M):\n    return np.eye(3)\n")
    sub = load_submission(tmp_path)
    assert set(sub.own_helpers()) == {"camera2"}
    assert any("your own camera2" in str(n) and "submission.py" in str(n) for n in sub.notes()), sub.notes()


# ------------------------------------------------------------------------------------------------
# a failed check says "failed" in words, and which part failed when its figure meets its goal


@pytest.mark.slow
def test_bundle_result_that_lost_its_shape_says_which_part_failed(hidden):
    from judging import bundle as jb

    pr = hidden.prepared["bundle"].problems[0]
    # The points given back in reverse order: another shape; a known optimum so large that the
    # error alone meets the goal leaves the shape as the part that fails.
    w = pr.w_init[::-1].copy()
    args = (pr.K1, pr.K2, pr.p1, pr.p2, pr.M2_init, pr.w_init)
    v = jb.result(pr.M2_init, w, *args, optimum=1e12)
    assert not v.passed
    assert jb.total_error(pr.K1, pr.K2, pr.p1, pr.p2, pr.M2_init, w) <= jb.result_goal(1e12)   # the figure meets it
    assert "failed (the error meets its goal, but the reconstruction lost its shape)" in v.sentence, v.sentence


@pytest.mark.slow
def test_every_failed_hidden_line_says_failed(hidden):
    def e_without_K(F, K1, K2):
        return K2.T @ F          # a K missing in E: every input fails

    t = _graded(hidden, "essential", essentialMatrix=e_without_K)["E = K2^T F K1 on hidden F, K1, K2"]
    judged = [line for line in t.feedback.split("  \n") if line.startswith("input ")]
    assert judged and all(": failed: " in line for line in judged), t.feedback


def test_failed_self_check_item_says_failed_beside_its_figure():
    from starter.checks.report import CheckReport
    from judging.verdict import Verdict

    report = CheckReport("f")
    report.judged(Verdict.of("error low", False, "1.81e3 px^2", "<= 2.17e3 px^2", because="the shape was lost"))
    report.judged(Verdict.of("rank 2", True, "s3/s2 = 1e-17", "<= 1e-6"))
    lines = report.text().splitlines()
    failed = next(line for line in lines if "error low" in line)
    assert "failed (the shape was lost): 1.81e3 px^2" in failed, failed
    assert "failed" not in next(line for line in lines if "rank 2" in line)
    assert "failed (the shape was lost)" in report._repr_html_()


# ------------------------------------------------------------------------------------------------
# a repeated error is said once, with a count


@pytest.mark.slow
def test_the_same_error_on_every_input_is_one_line_with_a_count(hidden):
    def raises(pts1, pts2, M):
        raise ValueError("singular matrix")

    t = _graded(hidden, "fundamental", eightpoint=raises)["noise-free matches give an exact F"]
    lines = [line for line in t.feedback.split("  \n") if "raised ValueError" in line]
    assert len(lines) == 1, t.feedback
    count = int(lines[0].split("(the same in ")[1].split(" calls)")[0])
    assert count == 2 * len(hidden.prepared["fundamental"].exact), lines[0]   # each scene, as given and refineF off


def test_the_same_error_in_the_self_check_is_one_line_with_a_count():
    from starter.checks.report import CheckReport

    report = CheckReport("f")
    for k in range(5):
        report.add(f"runs on step {k}", False, "ValueError: singular matrix (in f, cell 3, line 2)")
    text = report.text()
    assert text.count("singular matrix") == 1 and "(the same in 5 calls)" in text, text
