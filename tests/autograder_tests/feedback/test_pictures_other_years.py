"""Other years' hand-ins get a picture for every graded question, as their checks grade them.

A 2022-24 per-part hand-in (tests/support/realstyles: ``findM2(F, pts1, pts2, intrinsics, filename)``,
five-argument ``compute3D_pts(temple_pts1, intrinsics, F, im1, im2)``, per-part files importing
each other) is graded once by a real grading run with its picture step (sandbox, grading worker,
the real ``starter.checks.pictures``).  The checks call those signatures as their year's course
did (``judging.conventions``); the picture step must call them the same way (the checks'
``signatures``), so every autograded question has a drawn figure, in each channel's feedback:
feedback.html, Gradescope's results.json (its picture tests) and nbgrader's feedback cells.
"""

from __future__ import annotations

import json

import pytest
import realstyles

from autograder.feedback import page as feedback_page
from autograder.channels.gradescope import pictures as gradescope_pictures
from autograder.channels.nbgrader import pictures as nbgrader_pictures
from autograder.inputs.config import quick_config
from autograder.feedback.pictures import NOT_DRAWN, figures_of
from autograder.grading.run import GradingRun
from autograder.sandbox import ResourceLimits

pytestmark = pytest.mark.slow

PROGRAM = "y2022_per_part_refine_raw_full"
LIMITS = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """(result, figures) of the per-part program, graded with its pictures."""
    pytest.importorskip("starter.checks.pictures")
    folder = tmp_path_factory.mktemp("other_years")
    path = realstyles.build(PROGRAM, folder / "built")
    with GradingRun(quick_config(), limits=LIMITS, pictures=True, hide=(folder,)) as run:
        run.open(canary=False)
        result = run.grade(path)
    return result, figures_of(result.pictures)


def test_the_signatures_are_other_years(graded):
    """The program really is another year's: its findM2 and compute3D_pts are called that year's way."""
    result, _ = graded
    text = json.dumps(result.to_dict())
    assert "findM2 was called as its parameters ask: findM2(F, pts1, pts2, intrinsics" in text
    assert "compute3D_pts(temple_pts1, intrinsics, F, im1, im2)" in text
    assert result.failure is None
    lost = [(q.id, q.score, q.max_score) for q in result.questions if q.score < q.max_score - 1e-9]
    assert not lost, lost


def test_every_graded_question_has_its_picture(graded):
    result, figures = graded
    graded_ids = [q.id for q in result.questions if q.tests]
    assert {"Q3.3", "Q4.2"} <= set(graded_ids)
    not_drawn = {q: f for q, f in figures.items() if isinstance(f, str)}
    assert not not_drawn, not_drawn
    assert set(graded_ids) <= set(figures), sorted(set(graded_ids) - set(figures))


def test_each_channel_shows_every_picture(graded, tmp_path):
    result, figures = graded
    graded_ids = [q.id for q in result.questions if q.tests]
    # feedback.html: one <img> in each question's section
    page = feedback_page.write(tmp_path, result, figures).read_text()
    for q in graded_ids:
        section = page.split(f'id="{q}"', 1)[1].split("<section", 1)[0]
        assert "<img" in section and NOT_DRAWN not in section, q
    # Gradescope's results.json: a picture test per question, with its image
    data = gradescope_pictures.add_pictures(result.to_gradescope(), result, result.pictures)
    pictures = {t["name"].split(" ", 1)[0]: t for t in data["tests"] if " picture: " in t["name"]}
    assert set(graded_ids) <= set(pictures)
    assert all("<img" in pictures[q]["output"] for q in graded_ids)
    size = len(json.dumps(data))
    assert size < 400_000, f"results.json is {size // 1000} kB"   # a few hundred kB a student
    # nbgrader's feedback: the verdict, then the figure as an image output
    for q in graded_ids:
        outputs = nbgrader_pictures.cell_outputs(f"{q}: verdict", figures[q])
        assert [o["output_type"] for o in outputs] == ["stream", "display_data"], q
        assert outputs[1]["data"]["image/png"], q
