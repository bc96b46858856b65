"""The nbgrader course: hidden-check cells, the course folder, and real nbgrader 0.9 end to end.

The end-to-end test builds a course of two notebooks (q2, and q3 which borrows q2's eightpoint),
releases it, and autograds three students: the answer key, the untouched release, and a
student whose extra cell patches the in-kernel bridge and numpy to fake a pass.  Set
HW4_NBGRADER_ALL=1 to use every notebook (several minutes).
"""

from __future__ import annotations

import csv
import dataclasses
import importlib.util
import json
import os
import stat
from pathlib import Path

import nbformat
import pytest

from autograder import nbgrader_course as nc
from autograder.config import quick_config
from core.manifest import NOTEBOOKS, QUESTIONS, question

KIT_ROOT = Path(__file__).resolve().parents[1]
SOURCE = KIT_ROOT / "notebooks" / "nbgrader" / "source" / "hw4"
HAS_NBGRADER = importlib.util.find_spec("nbgrader") is not None
needs_nbgrader = pytest.mark.skipif(not HAS_NBGRADER, reason="nbgrader is not installed (pip install 'nbgrader>=0.9.6,<0.10')")
SECRET = "nbgrader-test-secret-5550123"


def source_notebook(stem: str) -> nbformat.NotebookNode:
    path = SOURCE / f"{stem}.ipynb"
    if not path.is_file():
        pytest.skip(f"{path} not built (python -m kit notebooks)")
    return nbformat.read(path, as_version=4)


def meta(cell) -> dict:
    return cell.get("metadata", {}).get("nbgrader", {})


def autograded(stem: str):
    return [q for q in QUESTIONS if q.notebook == stem and not q.by_hand]


@pytest.fixture
def grading_settings(tmp_path, monkeypatch):
    """The instructor's settings when the course is built: quick scenes and a secret of our own."""
    quick = quick_config(time_scale=1.0)
    settings = {"secret": SECRET, "temples": [dataclasses.asdict(t) for t in quick.temples],
                "match_points": quick.match_points, "ba_points": quick.ba_points, "car_times": quick.car_times}
    path = tmp_path / "grader.json"
    path.write_text(json.dumps(settings))
    monkeypatch.setenv("HW4_GRADER_CONFIG", str(path))
    monkeypatch.delenv("HW4_GRADER_SECRET", raising=False)
    return path


# ------------------------------------------------------------------------------------------------
# hidden-check cells


@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_hidden_checks_carry_the_manifest_points(stem):
    original = source_notebook(stem)
    before = nbformat.writes(original)
    nb = nc.add_hidden_checks(original, stem)
    assert nbformat.writes(original) == before  # the input is not modified
    graded_code = {meta(c)["grade_id"]: meta(c)["points"] for c in nb.cells
                   if c.cell_type == "code" and meta(c).get("grade")}
    assert graded_code == {f"hidden_{q.id.replace('.', '_')}": q.points for q in autograded(stem)}
    # Written answers keep their points, graded by hand.
    by_hand = sum(meta(c)["points"] for c in nb.cells if meta(c).get("grade") and meta(c).get("solution"))
    assert by_hand == sum(q.points for q in QUESTIONS if q.notebook == stem and q.by_hand)
    for cell in nb.cells:
        if meta(cell).get("grade_id", "").startswith("check_"):
            assert meta(cell)["locked"] and not meta(cell)["grade"] and "points" not in meta(cell)


@pytest.mark.parametrize("stem", [s for s in NOTEBOOKS if any(not q.by_hand for q in QUESTIONS if q.notebook == s)])
def test_a_hidden_check_follows_its_questions_last_cell_and_holds_no_inputs(stem):
    nb = nc.add_hidden_checks(source_notebook(stem), stem)
    ids = [meta(c).get("grade_id", "") for c in nb.cells]
    for q in autograded(stem):
        k = ids.index(f"hidden_{q.id.replace('.', '_')}")
        own = {g for f in q.functions for g in (f, f"check_{f}")}
        assert ids[k - 1] in own
        assert not own & set(ids[k + 1:])
        text = nb.cells[k].source
        hidden = text.split("### BEGIN HIDDEN TESTS")[1].split("### END HIDDEN TESTS")[0]
        assert f'hidden_score("{q.id}")' in hidden
        assert "hidden_score" not in text.split("### BEGIN HIDDEN TESTS")[0]


def test_add_hidden_checks_rejects_what_it_cannot_place():
    nb = source_notebook("q2_eightpoint")
    with pytest.raises(ValueError, match="stem"):
        nc.add_hidden_checks(nb, "q9_unknown")
    stripped = nbformat.from_dict(nb)
    stripped.cells = [c for c in stripped.cells if meta(c).get("grade_id") not in ("eightpoint", "check_eightpoint")]
    with pytest.raises(ValueError, match="Q2"):
        nc.add_hidden_checks(stripped, "q2_eightpoint")


def test_in_kernel_bridge_defers_to_kitscores_during_autograde(monkeypatch, capsys):
    monkeypatch.setenv("NBGRADER_EXECUTION", "autograde")
    # Zero, not full marks: without KitScores configured a hidden check must never pass by itself.
    assert nc.hidden_score("Q3.2") == 0.0
    assert "outside this notebook" in capsys.readouterr().out
    with pytest.raises(ValueError, match="qid"):
        nc.hidden_score("Q7")


def test_score_questions_refuses_questions_graded_by_hand(tmp_path):
    with pytest.raises(ValueError, match="by hand"):
        nc.score_questions(tmp_path, ["Q1.1"])


@needs_nbgrader
def test_kitscores_replaces_whatever_the_kernel_printed(monkeypatch):
    nb = nc.add_hidden_checks(source_notebook("q3_metric_reconstruction"), "q3_metric_reconstruction")
    fake_kernel = nbformat.v4.new_output("execute_result", data={"text/plain": "10.0"}, execution_count=1)
    for cell in nb.cells:
        if meta(cell).get("grade_id", "").startswith("hidden_"):
            cell.outputs = [fake_kernel]
    verdicts = {q.id: nc.QuestionScore(q.id, q.points / 2, q.points, f"{q.id} verdict") for q in autograded("q3_metric_reconstruction")}
    seen = []

    def fake_scores(folder, qids, course_root=None):
        seen.append((Path(folder), list(qids)))
        return {q: verdicts[q] for q in qids}

    monkeypatch.setattr(nc, "score_questions", fake_scores)
    resources = {"nbgrader": {"student": "s1", "assignment": "hw4", "notebook": "q3_metric_reconstruction"}}
    out, _ = nc.KitScores().preprocess(nb, resources)
    assert seen and seen[0][0].parts[-3:] == ("submitted", "s1", "hw4")
    for cell in out.cells:
        q = nc._question_of_grade_id(meta(cell).get("grade_id", ""))
        if q is None:
            continue
        kinds = [o.output_type for o in cell.outputs]
        assert kinds == ["stream", "execute_result"] and cell.outputs[0].name == "stdout"
        assert float(cell.outputs[1].data["text/plain"]) == q.points / 2
        assert f"{q.id} verdict" in cell.outputs[0].text


@needs_nbgrader
def test_kitscores_gives_zero_when_the_grader_breaks(monkeypatch):
    nb = nc.add_hidden_checks(source_notebook("q2_eightpoint"), "q2_eightpoint")

    def broken(*args, **kwargs):
        raise RuntimeError("no sandbox here")

    monkeypatch.setattr(nc, "score_questions", broken)
    out, _ = nc.KitScores().preprocess(nb, {"nbgrader": {"student": "s1", "assignment": "hw4"}})
    cell = next(c for c in out.cells if meta(c).get("grade_id") == "hidden_Q2")
    assert [o.output_type for o in cell.outputs] == ["error"]


@pytest.mark.slow
def test_in_kernel_bridge_grades_the_notebooks_beside_it(tmp_path, monkeypatch, grading_settings, capsys):
    # Outside autograde (by hand, nbgrader validate) the cell grades its own folder.
    monkeypatch.delenv("NBGRADER_EXECUTION", raising=False)
    for name, folder in (("key", KIT_ROOT / "notebooks" / "key"), ("student", KIT_ROOT / "notebooks")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "q2_eightpoint.ipynb").write_bytes((folder / "q2_eightpoint.ipynb").read_bytes())
    monkeypatch.chdir(tmp_path / "key")
    assert nc.hidden_score("Q2") == question("Q2").points
    q2 = question("Q2")
    assert f"Q2 {q2.title}: {q2.points} / {q2.points} points" in capsys.readouterr().out
    monkeypatch.chdir(tmp_path / "student")
    assert nc.hidden_score("Q2") == 0


# ------------------------------------------------------------------------------------------------
# the course folder


def test_course_needs_the_courses_own_secret(tmp_path, monkeypatch):
    monkeypatch.delenv("HW4_GRADER_SECRET", raising=False)
    monkeypatch.delenv("HW4_GRADER_CONFIG", raising=False)
    with pytest.raises(ValueError, match="development secret"):
        nc.build_course(tmp_path / "course", stems=["q2_eightpoint"])


def test_course_folder_layout(tmp_path, grading_settings):
    course = nc.build_course(tmp_path / "course", stems=["q1_proofs", "q2_eightpoint"])
    assert sorted(p.name for p in (course / "source" / "hw4").iterdir()) == ["q1_proofs.ipynb", "q2_eightpoint.ipynb"]
    for needed in ("starter/__init__.py", "scenes/__init__.py", "autograder/grade.py", "autograder/nbgrader_course.py",
                   "solutions/__init__.py", "core/manifest.py", "autograder/hidden/pytest.ini", "data/temple", "nbgrader_config.py", "README.md"):
        assert (course / needed).exists(), needed
    assert not (course / "tests").exists() and not (course / "notebooks").exists()
    settings = course / "grader_config.json"
    assert json.loads(settings.read_text())["secret"] == SECRET
    assert stat.S_IMODE(settings.stat().st_mode) == 0o600
    with pytest.raises(ValueError, match="out"):
        nc.build_course(course, stems=["q2_eightpoint"])
    nc.build_course(course, stems=["q2_eightpoint"], force=True)
    assert [p.name for p in (course / "source" / "hw4").iterdir()] == ["q2_eightpoint.ipynb"]
    # --force replaces a course, never any other folder.
    other = tmp_path / "not-a-course"
    other.mkdir()
    (other / "precious.txt").write_text("keep me")
    with pytest.raises(ValueError, match="course folder"):
        nc.build_course(other, stems=["q2_eightpoint"], force=True)
    assert (other / "precious.txt").read_text() == "keep me"


def test_cli_registers_the_nbgrader_command():
    from autograder.__main__ import build_parser

    args = build_parser().parse_args(["nbgrader", "--out", "course", "--notebooks", "q2_eightpoint", "--selftest"])
    assert args.func is nc._cli and args.notebooks == ["q2_eightpoint"] and args.selftest and not args.force


@needs_nbgrader
def test_course_config_puts_kitscores_right_after_execute(tmp_path, grading_settings):
    from nbgrader.preprocessors import Execute
    from traitlets.config.loader import PyFileConfigLoader

    course = nc.build_course(tmp_path / "course", stems=["q2_eightpoint"])
    config = PyFileConfigLoader("nbgrader_config.py", str(course)).load_config()
    steps = list(config.Autograde.autograde_preprocessors)
    assert steps[steps.index(Execute) + 1] == "autograder.nbgrader_course.KitScores"
    assert config.CourseDirectory.root == str(course.resolve())


# ------------------------------------------------------------------------------------------------
# nbgrader end to end


def cheating_submission(course: Path, student: str) -> None:
    """The untouched q2 plus a first cell that fakes passing inside the kernel."""
    folder = nc.submit_release(course, student)
    for path in folder.glob("*.ipynb"):
        if path.stem != "q2_eightpoint":
            path.unlink()
    path = folder / "q2_eightpoint.ipynb"
    nb = nbformat.read(path, as_version=4)
    setup = next(k for k, c in enumerate(nb.cells) if c.cell_type == "code")
    nb.cells.insert(setup + 1, nbformat.v4.new_code_cell(
        "import numpy\nimport autograder.nbgrader_course as bridge\n"
        "numpy.allclose = lambda *a, **k: True\nbridge.hidden_score = lambda qid: 10.0\n"))
    nbformat.write(nb, path)


@pytest.mark.slow
@needs_nbgrader
def test_nbgrader_end_to_end(tmp_path, grading_settings):
    stems = list(NOTEBOOKS) if os.environ.get("HW4_NBGRADER_ALL") == "1" else ["q2_eightpoint", "q3_metric_reconstruction"]
    course = nc.build_course(tmp_path / "course", stems=stems)
    nc.run_nbgrader(course, "generate_assignment", "hw4", "--force")
    release = course / "release" / "hw4"
    assert sorted(p.stem for p in release.glob("*.ipynb")) == sorted(stems)
    for path in release.glob("*.ipynb"):
        text = path.read_text()
        assert "BEGIN HIDDEN TESTS" not in text and "hidden_score" not in text and "BEGIN SOLUTION" not in text

    nc.submit_key(course, "key")
    nc.submit_release(course, "blank")
    cheating_submission(course, "cheater")
    nc.run_nbgrader(course, "autograde", "hw4", "--force")

    expected = {f"hidden_{q.id.replace('.', '_')}": float(q.points) for s in stems for q in autograded(s)}
    key = {k: v for k, v in nc.autograded_scores(course, "key").items() if k.startswith("hidden_")}
    assert key == {k: (p, p) for k, p in expected.items()}
    blank = nc.autograded_scores(course, "blank")
    assert {k for k in blank if k.startswith("hidden_")} == set(expected)
    assert all(score == 0 for score, _ in blank.values())
    # The patched bridge and numpy fooled the kernel, not KitScores.
    assert nc.autograded_scores(course, "cheater")["hidden_Q2"] == (0.0, 10.0)

    nc.run_nbgrader(course, "generate_feedback", "hw4", "--force")
    for student in ("key", "blank"):
        for stem in stems:
            html = course / "feedback" / student / "hw4" / f"{stem}.html"
            assert html.is_file() and "hidden checks" in html.read_text()
    q2 = question("Q2")
    feedback = (course / "feedback" / "key" / "hw4" / "q2_eightpoint.html").read_text()
    assert f"Q2 {q2.title}: {q2.points} / {q2.points} points" in feedback

    nc.run_nbgrader(course, "export")
    rows = {r["student_id"]: r for r in csv.DictReader((course / "grades.csv").open())}
    assert set(rows) == {"key", "blank", "cheater"}
    total = sum(expected.values())
    assert float(rows["key"]["score"]) == pytest.approx(total) and float(rows["key"]["max_score"]) >= total
    assert float(rows["blank"]["score"]) == 0 and float(rows["cheater"]["score"]) == 0
