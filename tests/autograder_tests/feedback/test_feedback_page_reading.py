"""The feedback page reads in a minute: the total and every question's score first, each
question's failed checks in words before its picture, the picture's measures named in words with
their units (never the keys the pictures module stores), the notes about files and helpers folded
at the end; and Gradescope's copy of a picture is small."""

from __future__ import annotations

import io

import numpy as np

from autograder.feedback import page as feedback_page
from autograder.channels.gradescope import pictures as gradescope_pictures
from autograder.feedback.results import QuestionResult, SubmissionResult, TestResult
from starter.checks.pictures import Picture

NOTES = tuple(f"q{k}.ipynb: helper{k} is defined 2 times; the last one (cell {k}) is used." for k in range(12))


def _png(width: int = 1300, height: int = 620) -> bytes:
    """A plot-like PNG with a photograph-like panel (noise), as the pictures are."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width / 100, height / 100), dpi=100)
    left, right = fig.subplots(1, 2)
    left.imshow(np.random.default_rng(0).uniform(size=(120, 160, 3)))
    right.plot(np.linspace(0, 1, 50) ** 2, "o-")
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _result() -> SubmissionResult:
    q2 = QuestionResult.of("Q2", [TestResult("rank 2", 4.0, 4.0, feedback="rank 2 (s3/s2 = 1e-17)"),
                                  TestResult("F fits the matches", 0.0, 6.0, feedback="mean distance 3.2 px (goal <= 1 px)")])
    q33 = QuestionResult.of("Q3.3", [TestResult("the right camera", 8.0, 8.0), TestResult("C2 = K2 M2", 2.0, 2.0)])
    return SubmissionResult((q2, q33), notes=NOTES)


def _figures() -> dict:
    m2 = {"refineF_off_mean_distance_px": 3.25, "s3_over_s2": 2e-3, "mean_distance_px": 3.2}
    m33 = {"chosen": 0.0, "right": 2.0, "chosen_share_in_front": 0.25}
    return {"Q2": Picture("Q2", "eightpoint: your epipolar lines", _png(), "Your lines.", m2),
            "Q3.3": Picture("Q3.3", "findM2: the four candidates", _png(), "The candidates.", m33)}


def test_the_questions_come_first_and_the_notes_last_folded():
    page = feedback_page.page(_result(), _figures())
    total, summary = page.index("Autograded total"), page.index('class="summary"')
    first_section, notes = page.index('<section class="q"'), page.index("<details")
    assert total < summary < first_section < notes
    assert page.index('href="#Q2"') < page.index('href="#Q3.3"') < first_section
    assert all(page.index(n.split(":")[0]) > notes for n in NOTES), "a note stands before the questions"
    # in a question: the failed check and its feedback before the passed one and before the picture
    q2 = page[page.index('id="Q2"'):page.index('id="Q3.3"')]
    assert q2.index("F fits the matches") < q2.index("rank 2") < q2.index("<img")
    assert "goal &lt;= 1 px" in q2 or "goal <= 1 px" in q2


def test_measures_are_named_in_words_with_their_units():
    page = feedback_page.page(_result(), _figures())
    for key in ("refineF_off_mean_distance_px", "s3_over_s2", "chosen_share_in_front"):
        assert key not in page, key
    assert "with refineF switched off, mean distance of the true matches to your epipolar lines" in page
    assert "3.25 px" in page and "25 %" in page
    assert "M2s[:, :, 0]" in page and "M2s[:, :, 2]" in page   # candidates named as the code indexes them
    assert "width:100%" in page.replace(" ", "")                # pictures at the page's full width


def test_gradescopes_copy_of_a_picture_is_small():
    png = _png()
    mime, data = gradescope_pictures.compact(png)
    assert mime in ("image/png", "image/jpeg") and len(data) < len(png) / 2, (len(data), len(png))
    from PIL import Image

    assert Image.open(io.BytesIO(data)).width <= gradescope_pictures.MAX_WIDTH


def test_one_likely_mistake_per_cause():
    """One findM2 bug fails several checks: each names the mistake (each costs points), the first of a
    question gives the hint, in feedback.md, results.json and the page; the class report counts it once."""
    from autograder.review.report import build_report

    hint = "Keep the candidate with the points in front of both"
    line = f"Likely mistake: depth tested in one camera only. {hint}."
    depth = {"mistakes": ("depth_one_camera",)}
    q33 = QuestionResult.of("Q3.3", [
        TestResult("the right camera", 0.0, 8.0, feedback=f"case 1: wrong  \n{line}", **depth),
        TestResult("C2 = K2 M2", 0.0, 2.0, feedback=line, **depth)])
    q5 = QuestionResult.of("Q5", [
        TestResult("bundle adjustment", 0.0, 20.0, feedback=f"start from findM2\n{line}", **depth)])
    result = SubmissionResult((q33, q5))
    page = feedback_page.page(result, {})
    assert page.count(hint) == 1
    assert page.count("Likely mistake: depth tested in one camera only") == 3   # named where it costs points
    assert "the same cause as above, under Q3.3" in page[page.index('id="Q5"'):]
    md = result.feedback_markdown()
    assert md[md.index("## Q3.3"):md.index("## Q5")].count(hint) == 1 and md.count(hint) == 2   # once per question
    assert "depth tested in one camera only (the same cause as above" in md
    from autograder.channels.nbgrader.grade import question_feedback

    assert question_feedback(q33).count(hint) == 1 and question_feedback(q33).count("Likely mistake: depth tested") == 2   # nbgrader's
    for layout in (None, {"checks": "visible"}):
        q33_outputs = [t["output"] for t in result.to_gradescope(layout)["tests"] if t["name"].startswith("Q3.3 check")
                       or layout is None and t["name"].startswith("Q3.3 ")]
        assert len(q33_outputs) == 2 and [hint in o for o in q33_outputs] == [True, False], q33_outputs
        assert all("Likely mistake: depth tested in one camera only" in o for o in q33_outputs)
    # a hint given only where it is shown later is given again where it is shown at once
    late = QuestionResult.of("Q3.3", [
        TestResult("the right camera", 0.0, 8.0, feedback=line, visibility="after_published"),
        TestResult("C2 = K2 M2", 0.0, 2.0, feedback=line)])
    assert all(hint in t["output"] for t in SubmissionResult((late,)).to_gradescope()["tests"])
    rep = build_report({"adam": result.to_gradescope(), "bea": result.to_gradescope({"checks": "visible"})})
    assert {k: sorted(v) for k, v in rep.mistakes.items()} == {(q, "depth tested in one camera only"): ["adam", "bea"]
                                                              for q in ("Q3.3", "Q5")}
