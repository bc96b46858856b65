"""The picture step's data path and its writers, in this process on a stand-in pictures module.

``autograder.feedback.pictures``: a student function's failure, a missing function, something that cannot
be drawn or a drawing that breaks each cost that question's picture only ("figure not drawn: ...");
what the student's functions return is checked once (sizes, dtypes) and drawn from the checked
arrays in the worker; the grader checks the worker's record again and draws nothing.  The feedback page,
Gradescope's picture tests and the class report's examples escape every student text, keep a
picture no earlier than its question's checks and name no student.  (The browser and the real
sandbox: tests/end_to_end/test_feedback_browser.py and tests/autograder_tests/sandbox/test_picture_step_sandbox.py.)
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from autograder.feedback import page as feedback_page
from autograder.channels.gradescope import pictures as gradescope_pictures
from autograder.feedback import pictures as step
from autograder.hidden.plugin import LocalStudent
from autograder.feedback.results import QuestionResult, SubmissionResult, TestResult
from core import wire
import picture_standin
from picture_cases import HOSTILE, good_triangulate, hostile_eightpoint, result_with

@pytest.fixture(autouse=True)
def standin(monkeypatch):
    monkeypatch.setattr(step, "contract", lambda: picture_standin)
    return picture_standin


def good_eightpoint(pts1, pts2, M):
    return np.arange(9.0).reshape(3, 3)


def run(functions, question="Q2"):
    """The worker's record of ``question``'s picture (``picture_record``), drawn in this process."""
    return step.picture_record(LocalStudent(functions), question)


def test_checked_outputs_are_drawn_and_the_record_read_again():
    outputs = step.run_public(LocalStudent({"triangulate": lambda *a: ([[1, 2, 3]] * 12, 0.5)}), "Q3.2")
    assert set(outputs) == {"P"} and outputs["P"].dtype == np.float64 and outputs["P"].shape == (12, 3)
    raw = {"Q2": run({"eightpoint": good_eightpoint}), "Q3.2": run({"triangulate": good_triangulate}, "Q3.2")}
    raw = json.loads(json.dumps(raw))  # as the worker's results file carries it
    figures = step.figures_of(raw)
    assert set(figures) == {"Q2", "Q3.2"}
    assert figures["Q2"].png.startswith(b"\x89PNG") and figures["Q2"].alt
    assert figures["Q3.2"].measures["numbers"] == 36.0


@pytest.mark.parametrize("functions, says", [
    ({"eightpoint": hostile_eightpoint}, "figure not drawn: eightpoint raised ValueError"),
    ({}, "figure not drawn: eightpoint is not defined"),
    ({"eightpoint": lambda *a: "not a matrix"}, "figure not drawn: the grader could not run this picture"),
])
def test_a_failure_costs_the_picture_only_and_says_why(functions, says):
    record = run(functions)
    assert set(record) == {"error"} and record["error"].startswith(says)
    figures = step.figures_of({"Q2": record, "Q3.2": run({"triangulate": good_triangulate}, "Q3.2")})
    assert isinstance(figures["Q2"], str) and figures["Q2"].startswith("figure not drawn: ")
    assert not isinstance(figures["Q3.2"], str)


def test_a_drawing_that_breaks_is_the_graders_note(monkeypatch):
    def broken(question, outputs, root=None):
        raise RuntimeError("boom")

    monkeypatch.setattr(picture_standin, "draw", broken)
    raw = {"Q2": run({"eightpoint": good_eightpoint})}
    assert raw == {"Q2": {"error": "figure not drawn: the grader could not draw it (RuntimeError)"}}
    assert step.figures_of(raw) == {"Q2": "figure not drawn: the grader could not draw it (RuntimeError)"}


def test_the_worker_draws_and_the_grader_checks_the_drawing_again():
    raw = {"Q2": run({"eightpoint": good_eightpoint}), "Q3.2": run({"eightpoint": hostile_eightpoint}, "Q3.2")}
    assert set(raw["Q2"]) == {"picture"} and raw["Q3.2"]["error"].startswith("figure not drawn: ")
    figures = step.figures_of(json.loads(json.dumps(raw)))
    assert figures["Q2"].png.startswith(b"\x89PNG") and figures["Q2"].alt and figures["Q2"].question == "Q2"
    good = raw["Q2"]["picture"]
    for bad in ({**good, "png": "not base64!"}, {**good, "png": "aGVsbG8="}, {**good, "alt": ""},
                {**good, "png": "A" * (step.MAX_PNG * 2)}, {"png": good["png"]}):
        assert step.figures_of({"Q2": {"picture": bad}}) == {"Q2": "figure not drawn: the picture could not be read"}


@pytest.fixture
def draws(monkeypatch):
    """The questions the stand-in's ``draw`` is asked to draw, in order."""
    asked, draw = [], picture_standin.draw

    def noted(question, outputs, root=None):
        asked.append(question)
        return draw(question, outputs, root=root)

    monkeypatch.setattr(picture_standin, "draw", noted)
    return asked


@pytest.mark.parametrize("outputs, says", [
    ({"F": np.ones((2000, 1000))}, "F: expected at most 1000000 numbers"),
    ({"F": np.ones(3, dtype=complex)}, "F: expected numbers, got complex128"),
    ({"x" * 100: np.ones(3)}, "expected array names of 1 to 64 characters"),
    ({"F": np.ones((1,) * 5)}, "F: expected at most 1000000 numbers in 4 dimensions"),
    ("plain text", "expected at most 32 named arrays, got str"),
])
def test_what_comes_back_is_checked_once_and_not_drawn(monkeypatch, draws, outputs, says):
    monkeypatch.setattr(picture_standin, "public_outputs", lambda question, functions, root=None: outputs)
    said = step.run_public(LocalStudent({}), "Q2")
    assert isinstance(said, str) and said.startswith(step.NOT_DRAWN + says), said
    assert run({}) == {"error": said} and draws == []  # the worker's record: the sentence, nothing drawn


def test_outputs_sent_for_the_grader_to_draw_are_not_drawn(draws):
    # What an old (or a hostile) worker sent: well-formed outputs, which the grader once drew itself.
    outputs = {"F": np.arange(9.0).reshape(3, 3)}
    raw = {"Q2": {"outputs": wire.encode(outputs)}, "Q3.2": run({"triangulate": good_triangulate}, "Q3.2")}
    raw = json.loads(json.dumps(raw))
    figures = step.figures_of(raw)
    assert figures["Q2"] == step.NOT_A_PICTURE and figures["Q2"].startswith("figure not drawn: ")
    assert figures["Q3.2"].png.startswith(b"\x89PNG") and draws == ["Q3.2"]  # the worker's only


def test_unknown_questions_and_junk_are_dropped():
    assert step.figures_of({"Q9": {"error": "x"}, "Q2": 7}) == {}
    assert step.figures_of("junk") == {}
    assert step.figures_of({"Q2": {"error": "raw"}}) == {"Q2": "figure not drawn: raw"}


# ------------------------------------------------------------------------------------------------
# the writers


def figures():
    return step.figures_of({"Q2": run({"eightpoint": hostile_eightpoint}),
                            "Q3.2": run({"triangulate": good_triangulate}, "Q3.2")})


def test_the_page_is_offline_escapes_student_text_and_keeps_hidden_checks_nameless(tmp_path):
    path = feedback_page.write(tmp_path, result_with("eightpoint raised ValueError: " + HOSTILE), figures())
    html = path.read_text()
    assert "<script>" not in html and "&lt;script&gt;" in html
    assert "\x1b" not in html and "\u202e" not in html and "\\u202e" in html
    assert feedback_page.CSP in html and "http://" not in html.replace("http://x", "")
    assert "1 hidden check(s): 10 / 10" in html and ">triangulate (" not in html
    assert html.count("<img ") == 1 and 'alt="A line plot' in html
    assert "figure not drawn: eightpoint raised ValueError" in html
    index = json.loads((tmp_path / "figures" / "figures.json").read_text())
    assert index["Q3.2"]["file"] == "Q3_2.png" and (tmp_path / "figures" / "Q3_2.png").read_bytes()[:4] == b"\x89PNG"
    assert index["Q2"]["error"].startswith("figure not drawn: ")


@pytest.mark.parametrize("layout, q2, q32", [
    (None, "visible", "hidden"),
    ({"checks": "after_published"}, "after_published", "hidden"),
    ({"checks": "after_due_date", "scores": "visible"}, "after_due_date", "hidden"),
])
def test_gradescope_pictures_are_shown_no_earlier_than_their_checks(layout, q2, q32):
    result = result_with("failed: " + HOSTILE)
    data = result.to_gradescope(visibility=layout)
    raw = {"Q2": run({"eightpoint": good_eightpoint}), "Q3.2": run({"triangulate": good_triangulate}, "Q3.2")}
    gradescope_pictures.add_pictures(data, result, raw)
    shown = {t["name"].split()[0]: t for t in data["tests"] if " picture: " in t["name"]}
    assert shown["Q2"]["visibility"] == q2 and shown["Q3.2"]["visibility"] == q32
    assert shown["Q2"]["status"] == "failed" and shown["Q3.2"]["status"] == "passed"  # their question's
    for t in shown.values():
        assert t["output_format"] == "html" and "score" not in t and "max_score" not in t
        assert 'src="data:image/png;base64,' in t["output"] and 'alt="A line plot' in t["output"]
    names = [t["name"] for t in data["tests"]]
    for qid, t in shown.items():  # right after the question's last test
        at = names.index(t["name"])
        assert names[at - 1].startswith(qid + " ") and not any(n.startswith(qid + " ") for n in names[at + 1:])
    assert data["score"] == result.score
    json.dumps(data, allow_nan=False)


def test_gradescope_picture_of_a_failure_is_escaped_and_a_failed_result_gets_none():
    result = result_with("x")
    data = result.to_gradescope(visibility={})
    gradescope_pictures.add_pictures(data, result, {"Q2": run({"eightpoint": hostile_eightpoint})})
    t, = [t for t in data["tests"] if " picture: " in t["name"]]
    assert t["name"] == "Q2 picture: figure not drawn"
    assert "<script>" not in t["output"] and "&lt;script&gt;" in t["output"] and "\x1b" not in t["output"]
    failed = SubmissionResult.failed("unreadable")
    data = failed.to_gradescope(visibility={})
    assert gradescope_pictures.add_pictures(data, failed, {"Q2": run({"eightpoint": good_eightpoint})})["tests"] == []


def test_the_class_report_shows_one_nameless_example_per_named_mistake(tmp_path):
    from autograder.review.examples import mistake_examples

    graded = tmp_path / "graded"
    for name in ("zoe<b>", "adam"):
        feedback_page.write(graded / name, result_with("x", student_id=name), step.figures_of(
            {"Q3.2": run({"triangulate": good_triangulate}, "Q3.2")}))
    examples = mistake_examples(graded, [(("Q3.2", "some mistake"), {"zoe<b>", "adam"}),
                                         (("Q2", "other"), {"adam"})])
    assert set(examples) == {("Q3.2", "some mistake")}
    png, alt = examples[("Q3.2", "some mistake")]
    assert png == (graded / "adam" / "figures" / "Q3_2.png").read_bytes()
    assert "adam" not in alt and "zoe" not in alt


def test_the_report_page_puts_the_example_beside_its_mistake(tmp_path):
    from autograder.review.report import write_report

    graded = tmp_path / "graded"
    figure = step.figures_of({"Q2": run({"eightpoint": good_eightpoint})})
    for name in ("student<i>one", "student-two"):
        result = result_with("Likely mistake: F transposed.", student_id=name)
        feedback_page.write(graded / name, result, figure)
        result.write_gradescope(graded / name / "results.json")
    html = write_report(graded, tmp_path / "report")["html"].read_text()
    row = next(r for r in html.split("<tr>") if "F transposed" in r)
    example = row.split("</td>")[-2]
    assert "<img" in example and "A line plot" in example and "student" not in example
