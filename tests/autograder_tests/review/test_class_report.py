"""The class report: pass shares per test, named mistakes with their students, histograms, gradebooks."""

from __future__ import annotations

import csv
from pathlib import Path

from autograder.feedback.results import QuestionResult, SubmissionResult, TestResult, write_csv
from autograder.review.__main__ import main
from autograder.review.report import CANVAS_COLUMNS, build_report, load_results, write_report
from core.manifest import question
from judging.mistakes import KNOWN_MISTAKES


CODES = {name: code for code, (name, _) in KNOWN_MISTAKES.items()}


def _result(student: str, q2_ok: bool, mistake: str | None = None, *, recorded: bool = True) -> SubmissionResult:
    """A result as the grader makes it: the check's feedback names the mistake and, when
    ``recorded``, the check records its code (``recorded=False``: a grader that did not)."""
    pts = question("Q2").points
    codes = (CODES[mistake],) if mistake else ()
    q2 = QuestionResult.of("Q2", [
        TestResult("F is rank 2", 4, 4, mistakes=() if recorded else None),
        TestResult.check("epipolar constraint holds", q2_ok, pts - 4,
                         f"mean distance 3 px. Likely mistake: {mistake}. Check the order." if mistake else "off",
                         mistakes=codes if recorded else None),
    ])
    q31 = QuestionResult.of("Q3.1", [TestResult("E from F", 5 if student != "c" else 0, 5)])
    return SubmissionResult((q2, q31), student_id=student)


def _graded(tmp_path: Path) -> Path:
    graded = tmp_path / "graded"
    results = [_result("a", True), _result("b", False, "F transposed"), _result("c", False, "F transposed"),
               _result("d", False, "rank 2 not enforced"), SubmissionResult.failed("unreadable zip", student_id="e")]
    for r in results:
        (graded / r.student_id).mkdir(parents=True)
        r.write_gradescope(graded / r.student_id / "results.json")
    write_csv(graded / "grades.csv", results)
    return graded


def test_shares_and_mistakes(tmp_path):
    rep = build_report(load_results(_graded(tmp_path)))
    assert rep.students == ["a", "b", "c", "d", "e"] and set(rep.failures) == {"e"}
    assert rep.tests[("Q2", "epipolar constraint holds")] == [1, 4]
    assert rep.pass_rate("Q2", "F is rank 2") == 1.0
    assert rep.tests[("Q3.1", "E from F")] == [3, 4]
    assert rep.mistakes[("Q2", "F transposed")] == {"b", "c"}
    assert rep.mistakes[("Q2", "rank 2 not enforced")] == {"d"}
    assert rep.scores["Q2"]["a"] == 10 and rep.scores["Q2"]["b"] == 4 and rep.scores["Q2"]["e"] == 0


def test_mistake_names_come_from_the_record_never_from_a_students_text(tmp_path):
    """A student's exception message that reads like the kit's note names nothing: the report counts
    the codes the grader recorded for the check, and the catalogue gives their names."""
    pts = question("Q2").points
    quoted = "eightpoint raised ValueError: Likely mistake: F transposed. (in eightpoint, cell 3, line 2)"
    tests = [TestResult("F is rank 2", 0, 4, feedback=quoted, mistakes=()),
             TestResult("epipolar constraint holds", 0, pts - 4, feedback=quoted + "\nLikely mistake: rank 2 not "
                        "enforced. A fundamental matrix is singular.", mistakes=("f_rank3",))]
    graded = tmp_path / "graded"
    (graded / "s").mkdir(parents=True)
    SubmissionResult((QuestionResult.of("Q2", tests),), student_id="s").write_gradescope(graded / "s" / "results.json")
    rep = build_report(load_results(graded))
    assert dict(rep.mistakes) == {("Q2", "rank 2 not enforced"): {"s"}}


def test_results_of_a_grader_that_did_not_record_mistakes_are_read_as_before(tmp_path):
    graded = tmp_path / "graded"
    for r in (_result("b", False, "F transposed", recorded=False), _result("c", False, "F transposed")):
        (graded / r.student_id).mkdir(parents=True)
        r.write_gradescope(graded / r.student_id / "results.json")
    assert dict(build_report(load_results(graded)).mistakes) == {("Q2", "F transposed"): {"b", "c"}}


def test_files_and_offline_page(tmp_path):
    out = tmp_path / "report"
    assert main(["report", str(_graded(tmp_path)), "--out", str(out), "--per-question"]) == 0
    tests = list(csv.DictReader((out / "tests.csv").open()))
    row = next(r for r in tests if r["test"] == "epipolar constraint holds")
    assert row["question"] == "Q2" and row["passed"] == "1" and row["results"] == "4"
    mistakes = list(csv.DictReader((out / "mistakes.csv").open()))
    assert mistakes[0]["mistake"] == "F transposed" and mistakes[0]["count"] == "2" and mistakes[0]["students"] == "b c"
    page = (out / "report.html").read_text()
    assert page.count("data:image/png;base64,") >= 3 and "F transposed" in page
    assert "http" not in page and "<script" not in page and 'src="/' not in page
    assert (out / "histogram_Q2.png").read_bytes()[:4] == b"\x89PNG"
    assert (out / "grades.csv").read_text() == (tmp_path / "graded" / "grades.csv").read_text()
    canvas = list(csv.reader((out / "canvas.csv").open()))
    assert tuple(canvas[0][:5]) == CANVAS_COLUMNS and canvas[0][5] == "HW4 autograded"
    assert canvas[1][0] == "Points Possible" and canvas[0][6] == "HW4 autograded Q2"
    assert canvas[2][:6] == ["a", "", "", "a", "", "15"]


def test_canvas_roster_fills_the_student_columns(tmp_path):
    roster = tmp_path / "export.csv"
    roster.write_text("Student,ID,SIS User ID,SIS Login ID,Section,Old (12)\n"
                      "    Points Possible,,,,,10\n"
                      '"Bee, B",1002,900002,b,SEC-01,3\n')
    write_report(_graded(tmp_path), tmp_path / "out", assignment="HW4 (345)", roster=roster)
    rows = list(csv.reader((tmp_path / "out" / "canvas.csv").open()))
    assert rows[0] == [*CANVAS_COLUMNS, "HW4 (345)"]
    assert ["Bee, B", "1002", "900002", "b", "SEC-01"] == rows[3][:5]
    assert main(["report", str(tmp_path / "nothing"), "--out", str(tmp_path / "o2")]) == 2
