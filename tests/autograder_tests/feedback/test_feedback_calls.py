"""A failed call's feedback says how the function was called, never with the hidden values.

For each graded function of the hidden checks (eightpoint's Q2 aside: test_fundamental.py has its
own), a student function that raises, and one that returns something malformed, are graded in
this process (``run_here`` on a ``LocalStudent``, the hidden inputs of the quick config): the
checks of that function lose points, and their feedback

- names the call with the kind of each argument ("called as triangulate(C1: a 3x4 float64 array, ...");
- says what came back ("raised TypeError ...", or "returned a tuple of 1 (...)");
- holds no number of the hidden inputs: every decimal number of the feedback is compared with
  every value of the concept's prepared inputs, at the precision it is printed with.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from autograder.inputs.config import quick_config
from autograder.feedback.words import PARAMETERS, called_as, read_returned, returned
from autograder.inputs.build import build_hidden_inputs
from autograder.inputs.keep import default_keep
from autograder.hidden.plugin import HIDDEN_DIR, LocalStudent, run_here
from autograder.sandbox import CallOutcome
from judging.verdict import Malformed

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

# function -> (concept: autograder/hidden/test_<concept>.py, question, words of the names of its tests)
FUNCTIONS = {
    "essentialMatrix": ("essential", "Q3.1", ("",)),
    "triangulate": ("triangulation", "Q3.2", ("",)),
    "findM2": ("pose", "Q3.3", ("",)),
    "epipolarCorrespondence": ("correspondence", "Q4.1", ("",)),
    "compute3D_pts": ("correspondence", "Q4.2", ("",)),
    "rodriguesResidual": ("bundle", "Q5", ("rodriguesResidual",)),
    "bundleAdjustment": ("bundle", "Q5", ("bundle adjustment", "M2 holds", "o1 and o2")),
    "MultiviewReconstruction": ("multiview", "Q6", ("3D keypoints", "only detections", "err is")),
    "plot_3d_keypoint_video": ("multiview", "Q6", ("plot_3d_keypoint_video",)),
}
LEAK = "the inputs were"


@pytest.fixture(scope="module")
def hidden():
    return build_hidden_inputs(quick_config(), keep=default_keep())  # the suite's keep


def _reference() -> dict:
    import solutions

    return {name: getattr(solutions, name) for name in solutions.__all__}


def raises(*args):
    """Raises, putting its first argument's values into the message (the grader must cut them)."""
    first = np.asarray(args[0], dtype=float).ravel()[:3]
    raise TypeError(f"{LEAK} {' '.join(repr(float(v)) for v in first)}")


def malformed(*args):
    """Returns a tuple of one array of the wrong shape (nothing any contract asks for)."""
    return (np.zeros((2, 2)),)


def _feedback(hidden, function: str, fn) -> tuple[list, str]:
    """(the function's tests, their feedback joined) with ``fn`` in place of the reference's ``function``."""
    concept, qid, words = FUNCTIONS[function]
    functions = dict(_reference(), **{function: fn})
    if function == "compute3D_pts":
        del functions["triangulate"]   # else Q4.2 is graded through the matcher and triangulate instead
    result = run_here(LocalStudent(functions), hidden, tests=[HIDDEN_DIR / f"test_{concept}.py"])
    q = next(q for q in result.questions if q.id == qid)
    tests = [t for t in q.tests if any(w in t.name for w in words)]
    assert tests, f"no test of {function} in {[t.name for t in q.tests]}"
    return tests, "\n".join(t.feedback for t in tests)


def _hidden_values(prepared) -> np.ndarray:
    """Every non-integer float of a concept's prepared inputs (dataclasses, tuples, arrays, numbers)."""
    found = []

    def walk(v):
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            for f in dataclasses.fields(v):
                walk(getattr(v, f.name))
        elif isinstance(v, (tuple, list)):
            for item in v:
                walk(item)
        elif isinstance(v, dict):
            for item in v.values():
                walk(item)
        elif isinstance(v, np.ndarray) and v.dtype.kind == "f":
            found.append(v.ravel().astype(float))
        elif isinstance(v, float):
            found.append(np.array([v]))

    walk(prepared)
    values = np.concatenate(found) if found else np.zeros(0)
    values = values[np.isfinite(values)]
    return values[np.abs(values - np.round(values)) > 1e-9]


def leaked_numbers(text: str, values: np.ndarray) -> list[str]:
    """The decimal numbers of ``text`` equal to a hidden value at the precision they are printed with."""
    out = []
    for m in re.finditer(r"-?\d+\.(\d+)(?:e[+-]?\d+)?", text):
        printed = float(m.group(0))
        decimals = len(m.group(1))
        if decimals < 2 or printed == 0:
            continue
        if "e" in m.group(0):
            close = np.isclose(values, printed, rtol=0.6 * 10.0 ** -decimals, atol=0)
        else:
            close = np.abs(values - printed) <= 0.5 * 10.0 ** -decimals
        if np.any(close):
            out.append(m.group(0))
    return out


@pytest.mark.parametrize("function", list(FUNCTIONS))
@pytest.mark.parametrize("broken", [raises, malformed], ids=["raises", "malformed"])
def test_a_failed_call_says_how_it_was_called_and_no_hidden_value(hidden, function, broken):
    tests, text = _feedback(hidden, function, broken)
    assert all(t.score < t.max_score for t in tests), text
    assert f"called as {function}(" in text, text
    first = PARAMETERS[function][0]
    assert re.search(rf"called as {function}\({first}: an? \w", text), text
    assert "float64 array" in text, text
    if broken is raises:
        assert "raised TypeError" in text, text
    elif function == "plot_3d_keypoint_video":
        assert "drew 0 3D points" in text, text      # a figure call reports what the figures drew
    elif function != "epipolarCorrespondence":
        assert "returned a tuple of 1 (a 2x2 float64 array)" in text, text
    else:
        assert "returned a tuple of 1" in text, text
    concept = FUNCTIONS[function][0]
    leaks = leaked_numbers(text, _hidden_values(hidden.prepared[concept]))
    assert not leaks, (leaks, text)


def test_the_leak_detector_finds_a_hidden_value(hidden):
    """The comparison above can fail: a hidden value printed with its decimals is found."""
    values = _hidden_values(hidden.prepared["triangulation"])
    assert len(values) > 100
    assert leaked_numbers(f"got {values[7]:.4f} and {values[11]:.6g}", values)
    assert not leaked_numbers("called as f(C1: a 3x4 float64 array) returned a tuple of 1", values)


def test_read_returned_names_the_call_and_what_came_back():
    args = (np.zeros((3, 4)), np.zeros((40, 2)), np.zeros((3, 4)), np.zeros((40, 2)))
    with pytest.raises(Malformed) as info:
        read_returned("triangulate", CallOutcome("ok", (np.zeros((40, 3)),)), lambda v: _two(v), args)
    text = str(info.value)
    assert text.startswith("triangulate should return 2 values"), text
    assert ("called as triangulate(C1: a 3x4 float64 array, pts1: a 40x2 float64 array, C2: a 3x4 float64 array, "
            "pts2: a 40x2 float64 array) returned a tuple of 1 (a 40x3 float64 array)") in text, text
    with pytest.raises(Malformed) as info:
        read_returned("triangulate", CallOutcome("exception", message="ZeroDivisionError: division by zero "
                                                                       "(in triangulate, q3.ipynb, cell 4, line 9)"),
                      _two, args)
    assert str(info.value).startswith("triangulate raised ZeroDivisionError: division by zero (in triangulate")
    assert "; called as triangulate(C1: a 3x4 float64 array" in str(info.value)
    with pytest.raises(Malformed) as info:
        read_returned("triangulate", CallOutcome("missing", message="triangulate is not defined"), _two, args)
    assert "called as" not in str(info.value)   # nothing was called
    assert read_returned("triangulate", CallOutcome("ok", (1, 2)), _two, args) == (1, 2)


def _two(value):
    if not isinstance(value, tuple) or len(value) != 2:
        raise Malformed("triangulate should return 2 values (a tuple), got another value")
    return value


def test_kinds_never_print_values():
    assert called_as("findM2", ("F", "pts1", "pts2", "intrinsics"),
                     (np.ones((3, 3)), np.ones((5, 2)), np.ones((5, 2)), {"K1": 1.2345, "K2": 2.5}),
                     {"filename": "q3_3.npz"}) == ("called as findM2(F: a 3x3 float64 array, pts1: a 5x2 float64 "
                                                   "array, pts2: a 5x2 float64 array, intrinsics: a dict with K1, K2, "
                                                   "filename=a str)")
    assert returned((np.ones(3), 1.5, None)) == "a tuple of 3 (a 3 float64 array, a float, None)"
    assert returned(None) == "None" and returned(7) == "an int"


def test_the_mistakes_a_check_names_are_the_ones_its_feedback_says():
    """``named_mistakes`` is what the grader records for the class report; ``notes`` says the same
    mistakes to the student, each once, and none when the check passed."""
    from autograder.feedback.words import named_mistakes, notes
    from judging.mistakes import mistake

    found = [mistake("f_transposed"), None, mistake("f_rank3"), mistake("f_transposed")]
    assert [m.code for m in named_mistakes(found)] == ["f_transposed", "f_rank3"]
    assert named_mistakes(found, passed=True) == [] and notes(["a: x"], found, passed=True) == ["a: x"]
    said = [line for line in notes(["a: x"], found) if line.startswith("Likely mistake: ")]
    assert said == [f"Likely mistake: {m.name}. {m.hint[0].upper()}{m.hint[1:]}" for m in named_mistakes(found)]


def test_a_function_of_another_question_is_named_with_its_question():
    """A check that runs another question's function (Q4.2 falling back to the matcher and triangulate)
    names that question at the function's first mention, as the pictures do; a call, a file, the
    check's own function and a name already followed by its question are left as they are."""
    from autograder.feedback.words import upstream_named

    lines = ["graded through your epipolarCorrespondence and triangulate (compute3D_pts: compute3D_pts raised "
             "KeyError: temple (in compute3D_pts, cell 3, line 2))",
             "epipolarCorrespondence failed on 3 of 40 points",
             "triangulate: triangulate raised ValueError; called as triangulate(C1: a 3x4 float64 array)"]
    named = upstream_named(lines, "Q4.2")
    assert named[0] == ("graded through your epipolarCorrespondence (Q4.1) and triangulate (Q3.2) (compute3D_pts: "
                        "compute3D_pts raised KeyError: temple (in compute3D_pts, cell 3, line 2))")
    assert named[1:] == lines[1:]                                  # the first mention only
    assert upstream_named(lines[2:], "Q4.2") == ["triangulate (Q3.2): " + lines[2].removeprefix("triangulate: ")]
    assert upstream_named(lines[2:], "Q3.2") == lines[2:]          # its own question: nothing to add
    kept = ["triangulate(C1) in triangulate.py", "my_triangulate and triangulated", "triangulate (Q3.2) raised"]
    assert upstream_named(kept, "Q5") == kept
