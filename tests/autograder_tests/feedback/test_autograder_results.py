"""The results model: validation, Gradescope's results.json, the failure path, feedback and CSV."""

from __future__ import annotations

import csv
import json

import pytest

from autograder.feedback.results import (
    QuestionResult,
    SubmissionResult,
    TestResult,
    autograded_question_ids,
    clean_feedback,
    csv_header,
    write_csv,
)
from core.manifest import QUESTIONS, question

TRACEBACK = (
    "Traceback (most recent call last):\n"
    '  File "/work/main/autograder/tests/q2_hidden.py", line 41, in check_f\n'
    "    assert np.allclose(F, expected_F), hidden_pts1\n"
    "AssertionError: F does not map points to their epipolar lines"
)


def full_marks(qid: str, checks: int = 2, *, visibility: str = "visible") -> QuestionResult:
    points = question(qid).points
    return QuestionResult.of(qid, [TestResult(f"check {k}", points / checks, points / checks, visibility=visibility)
                                   for k in range(checks)])


def sample() -> SubmissionResult:
    q2 = QuestionResult.of("Q2", [
        TestResult("F is rank 2", 4, 4),
        TestResult("epipolar constraint holds", 1.5, 6, feedback="mean distance 3.2 px, expected < 1 px"),
    ], notes=["eightpoint is defined 2 times; the last one (cell 9) is used."])
    q6 = full_marks("Q6")
    q31 = QuestionResult.of("Q3.1", [TestResult("E from F", 0, 3, feedback=TRACEBACK),
                                     TestResult("secret check", 2, 2, visibility="hidden", feedback="hidden detail")])
    return SubmissionResult((q2, q31, q6), student_id="andrew1", isolation={"level": "namespaces", "uid": 60001,
                            "network_isolated": True, "hidden_paths": ["/kit/solutions"], "notes": []},
                            notes=("q4_temple_3d.ipynb could not be read",), execution_time=12.5)


def test_test_result_validates_its_numbers_and_visibility():
    with pytest.raises(ValueError, match="score"):
        TestResult("x", 3, 2)
    with pytest.raises(ValueError, match="finite"):
        TestResult("x", float("nan"), 2)
    with pytest.raises(ValueError, match="visibility"):
        TestResult("x", 1, 2, visibility="secret")
    with pytest.raises(ValueError, match="name"):
        TestResult(" ", 1, 2)
    assert TestResult("x", 2, 2).passed and not TestResult("x", 1, 2).passed
    assert TestResult.check("y", False, 5, "wrong").score == 0


def test_question_checks_must_add_up_to_the_manifest_points():
    with pytest.raises(ValueError, match="adding up to 10"):
        QuestionResult.of("Q2", [TestResult("only", 5, 5)])
    with pytest.raises(ValueError, match="qid"):
        QuestionResult.of("Q9", [])
    q = full_marks("Q5", 4)
    assert q.max_score == question("Q5").points and q.title == question("Q5").title


def test_gradescope_results_json():
    result = sample()
    data = json.loads(json.dumps(result.to_gradescope(), allow_nan=False))
    assert data["score"] == pytest.approx(4 + 1.5 + 0 + 2 + question("Q6").points)
    assert data["stdout_visibility"] in ("hidden", "visible") and data["visibility"] == "visible"
    # The outputs are escaped for Markdown, so Gradescope must be told to render them as Markdown.
    assert data["output_format"] == data["test_output_format"] == "md"
    assert data["extra_data"]["isolation"]["level"] == "namespaces"
    tests = data["tests"]
    assert len(tests) == 6
    assert sum(t["max_score"] for t in tests) == pytest.approx(sum(q.max_score for q in result.questions))
    for t in tests:
        assert set(t) >= {"name", "score", "max_score", "output", "visibility", "status"}
        assert t["status"] == ("passed" if t["score"] >= t["max_score"] else "failed")
    first = tests[0]
    assert first["name"].startswith("Q2 ") and "defined 2 times" in first["output"]
    assert any("(extra credit)" in t["name"] for t in tests)
    # Extra credit counts in the score but not in the total to reach.
    assert result.max_score == question("Q2").points + question("Q3.1").points


def test_feedback_never_shows_grader_tracebacks():
    result = sample()
    for text in (json.dumps(result.to_gradescope()), result.feedback_markdown(audience="staff")):
        assert "Traceback" not in text and "q2_hidden.py" not in text and "hidden_pts1" not in text
    assert "F does not map points" in result.feedback_markdown()
    assert clean_feedback("x" * 5000, limit=100).endswith("[...]")


def test_student_feedback_hides_hidden_checks_staff_feedback_shows_them():
    result = sample()
    student, staff = result.feedback_markdown(), result.feedback_markdown(audience="staff")
    assert "secret check" not in student and "hidden detail" not in student
    assert "1 hidden check(s): 2 / 2" in student
    assert "secret check" in staff and "Sandbox: namespaces" in staff
    assert "q4_temple_3d.ipynb could not be read" in student
    with pytest.raises(ValueError, match="audience"):
        result.feedback_markdown(audience="everyone")


def test_failure_path_still_writes_valid_results(tmp_path):
    failed = SubmissionResult.failed("the zip archive has an entry outside its folder", student_id="andrew1",
                                     isolation={"level": "basic"})
    path = failed.write_gradescope(tmp_path / "results.json")
    data = json.loads(path.read_text())
    assert data["score"] == 0 and data["tests"] == []
    assert "could not grade" in data["output"] and "outside its folder" in data["output"]
    assert failed.csv_row() == ["andrew1", "0"] + ["0"] * len(autograded_question_ids())
    assert "could not grade" in failed.feedback_markdown()
    with pytest.raises(ValueError, match="reason"):
        SubmissionResult.failed("")


def test_csv_rows_line_up_with_the_header(tmp_path):
    ids = autograded_question_ids()
    assert ids == [q.id for q in QUESTIONS if not q.by_hand] and "Q1.1" not in ids
    path = write_csv(tmp_path / "grades.csv", [sample(), SubmissionResult.failed("broken", student_id="b2")])
    rows = list(csv.reader(path.open()))
    assert rows[0] == csv_header() == ["student_id", "total", *ids]
    assert all(len(r) == len(rows[0]) for r in rows)
    row = dict(zip(rows[0], rows[1]))
    assert float(row["Q2"]) == 5.5 and float(row["Q3.2"]) == 0
    assert float(row["total"]) == pytest.approx(sum(float(row[q]) for q in ids))
    assert rows[2][:2] == ["b2", "0"]


def test_configuration_is_recorded_round_trips_and_keeps_results_json_valid(tmp_path):
    from dataclasses import replace

    from autograder.inputs.config import configuration, quick_config

    record = {**configuration(quick_config()), "isolation": "namespaces"}
    result = replace(sample(), configuration=record)
    assert SubmissionResult.from_dict(json.loads(json.dumps(result.to_dict()))) == result
    data = json.loads(result.write_gradescope(tmp_path / "results.json").read_text())
    shown = data["extra_data"]["configuration"]
    assert shown["key"] == record["key"] and shown["isolation"] == "namespaces" and "files" not in shown["tests"]
    assert quick_config().secret not in json.dumps(data)
    failed = SubmissionResult.failed("broken", configuration=record)
    assert failed.to_gradescope()["extra_data"]["configuration"]["secret_fingerprint"] == record["secret_fingerprint"]
    assert "Graded by grader" in result.feedback_markdown(audience="staff")
    assert "Graded by grader" not in result.feedback_markdown()


def test_a_checks_recorded_mistakes_are_catalogue_codes_kept_through_json():
    named = TestResult("epipolar constraint holds", 0, 6, feedback="Likely mistake: F transposed.",
                       mistakes=["f_transposed", "f_rank3", "f_transposed"])
    assert named.mistakes == ("f_transposed", "f_rank3")  # a tuple, each code once, in order
    assert TestResult("F is rank 2", 4, 4).mistakes is None  # not recorded
    for bad in ("f_transposed", ["F transposed"], [3]):
        with pytest.raises(ValueError, match="mistakes"):
            TestResult("x", 0, 1, mistakes=bad)
    result = SubmissionResult((QuestionResult.of("Q2", [TestResult("F is rank 2", 4, 4, mistakes=()), named]),), "s")
    assert SubmissionResult.from_dict(json.loads(json.dumps(result.to_dict()))) == result
    cli = [t.get("extra_data") for t in result.to_gradescope()["tests"]]
    assert cli == [{"mistakes": []}, {"mistakes": ["f_transposed", "f_rank3"]}]
    checks = [t for t in result.to_gradescope({"checks": "hidden"})["tests"] if "check:" in t["name"]]
    assert [t["extra_data"]["mistakes"] for t in checks] == [[], ["f_transposed", "f_rank3"]]
    assert all("extra_data" not in t for t in sample().to_gradescope()["tests"])  # none recorded, none written
