"""The nbgrader course: hidden-check cells without grading code, the course folder, and real
nbgrader 0.9 end to end with the kit's scores written into the gradebook by ``grade_course``.

The end-to-end test builds a course of q1, q2 and q3 (q3 borrows q2's eightpoint), releases it,
and autogrades three students: the answer key, a student whose untouched q1 has one extra cell
that appends a fake judge to the course's autograder package and patches numpy (the attack that
used to give 90/100), and an untouched release graded after it.  Set HW4_NBGRADER_ALL=1 to use
every notebook (several minutes).  Its feedback HTML shows each question's picture of the public
data under the verdict (the key's), or why there is none (the untouched release's stubs raise).
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import importlib.util
import json
import os
import re
from html.parser import HTMLParser
from pathlib import Path

import nbformat
import pytest

from autograder.channels.nbgrader import course as nc
from autograder.inputs.config import load_config, quick_config
from core.manifest import NOTEBOOKS, QUESTIONS, question
from core.paths import KIT_ROOT

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

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
    """The instructor's settings: quick scenes and a secret of our own."""
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
def test_hidden_checks_carry_the_manifest_points_and_extra_credit_none(stem):
    original = source_notebook(stem)
    before = nbformat.writes(original)
    nb = nc.add_hidden_checks(original, stem)
    assert nbformat.writes(original) == before  # the input is not modified
    graded_code = {meta(c)["grade_id"]: meta(c)["points"] for c in nb.cells
                   if c.cell_type == "code" and meta(c).get("grade")}
    # Extra credit is worth 0 in nbgrader's totals: grade_course records it as extra_credit.
    assert graded_code == {f"hidden_{q.id.replace('.', '_')}": 0 if q.extra_credit else q.points for q in autograded(stem)}
    by_hand = sum(meta(c)["points"] for c in nb.cells if meta(c).get("grade") and meta(c).get("solution"))
    assert by_hand == sum(q.points for q in QUESTIONS if q.notebook == stem and q.by_hand)
    for cell in nb.cells:
        if meta(cell).get("grade_id", "").startswith("check_"):
            assert meta(cell)["locked"] and not meta(cell)["grade"] and "points" not in meta(cell)


@pytest.mark.parametrize("stem", [s for s in NOTEBOOKS if any(not q.by_hand for q in QUESTIONS if q.notebook == s)])
def test_a_hidden_check_follows_its_questions_last_cell_and_runs_no_grading_code(stem):
    nb = nc.add_hidden_checks(source_notebook(stem), stem)
    ids = [meta(c).get("grade_id", "") for c in nb.cells]
    for q in autograded(stem):
        k = ids.index(f"hidden_{q.id.replace('.', '_')}")
        own = {g for f in q.functions for g in (f, f"check_{f}")}
        assert ids[k - 1] in own
        assert not own & set(ids[k + 1:])
        text = nb.cells[k].source
        hidden = text.split("### BEGIN HIDDEN TESTS")[1].split("### END HIDDEN TESTS")[0]
        code = [line.split("#")[0].strip() for line in hidden.splitlines() if line.split("#")[0].strip()]
        assert code == ["0.0"]  # a constant: nothing to import, call or patch
        assert "import" not in text and "autograder." not in text


def test_add_hidden_checks_rejects_what_it_cannot_place():
    nb = source_notebook("q2_eightpoint")
    with pytest.raises(ValueError, match="stem"):
        nc.add_hidden_checks(nb, "q9_unknown")
    stripped = nbformat.from_dict(nb)
    stripped.cells = [c for c in stripped.cells if meta(c).get("grade_id") not in ("eightpoint", "check_eightpoint")]
    with pytest.raises(ValueError, match="Q2"):
        nc.add_hidden_checks(stripped, "q2_eightpoint")


# ------------------------------------------------------------------------------------------------
# the course folder


def test_course_folder_holds_no_grader_and_no_secret(tmp_path, grading_settings):
    course = nc.build_course(tmp_path / "course", stems=["q1_proofs", "q2_eightpoint"])
    assert sorted(p.name for p in (course / "source" / "hw4").iterdir()) == ["q1_proofs.ipynb", "q2_eightpoint.ipynb"]
    for needed in ("starter/__init__.py", "scenes/__init__.py", "core/manifest.py", "judging/__init__.py",
                   "data/temple", "nbgrader_config.py", "README.md"):
        assert (course / needed).exists(), needed
    for absent in ("autograder", "solutions", "kit", "tests", "notebooks", "grader_config.json"):
        assert not (course / absent).exists(), absent
    assert SECRET not in "".join(p.read_text(errors="replace") for p in course.rglob("*") if p.is_file()
                                 and p.suffix in (".py", ".json", ".md", ".ipynb"))
    with pytest.raises(ValueError, match="out"):
        nc.build_course(course, stems=["q2_eightpoint"])
    nc.build_course(course, stems=["q2_eightpoint"], force=True)
    assert [p.name for p in (course / "source" / "hw4").iterdir()] == ["q2_eightpoint.ipynb"]
    other = tmp_path / "not-a-course"
    other.mkdir()
    (other / "precious.txt").write_text("keep me")
    with pytest.raises(ValueError, match="course folder"):
        nc.build_course(other, stems=["q2_eightpoint"], force=True)
    assert (other / "precious.txt").read_text() == "keep me"


def test_the_gradebook_opens_from_a_shell_without_the_environment_on_path(tmp_path, monkeypatch):
    """nbgrader's Gradebook runs ``alembic`` from PATH: a grader started as .venv/bin/python, its
    environment not activated, still finds the one beside its Python, and PATH is left as it was."""
    pytest.importorskip("nbgrader")
    from autograder.channels.nbgrader.course import gradebook

    bare = os.pathsep.join(p for p in ("/usr/bin", "/bin") if Path(p).is_dir())
    monkeypatch.setenv("PATH", bare)
    with gradebook(tmp_path / "gradebook.db") as gb:
        gb.add_student("ada")
        assert [s.id for s in gb.students] == ["ada"]
    assert os.environ["PATH"] == bare


def test_cli_registers_the_nbgrader_commands():
    from autograder.__main__ import build_parser

    args = build_parser().parse_args(["nbgrader", "--out", "course", "--notebooks", "q2_eightpoint", "--selftest"])
    assert args.func is nc._cli and args.notebooks == ["q2_eightpoint"] and args.selftest and not args.force
    args = build_parser().parse_args(["nbgrader-grade", "course", "--student", "s1", "s2"])
    assert args.func is nc.grade_cli and args.assignment == "hw4" and args.student == ["s1", "s2"]
    assert not args.no_pictures and build_parser().parse_args(["nbgrader-grade", "course", "--no-pictures"]).no_pictures


def test_no_pictures_says_the_same_in_both_grading_commands():
    from autograder.__main__ import build_parser

    def help_of(command):
        sub = next(a for a in build_parser()._actions if getattr(a, "choices", None) and command in a.choices)
        return next(a.help for a in sub.choices[command]._actions if "--no-pictures" in a.option_strings)

    assert help_of("nbgrader-grade") == help_of("grade")


def test_scoring_needs_the_courses_own_secret_and_a_gradebook(tmp_path, monkeypatch):
    from autograder.__main__ import build_parser

    monkeypatch.delenv("HW4_GRADER_SECRET", raising=False)
    monkeypatch.delenv("HW4_GRADER_CONFIG", raising=False)
    args = build_parser().parse_args(["nbgrader-grade", str(tmp_path)])
    with pytest.raises(ValueError, match="development secret"):
        nc.grade_cli(args)
    with pytest.raises(ValueError, match="gradebook"):
        nc.grade_course(tmp_path, config=quick_config())


@needs_nbgrader
def test_the_canary_runs_before_any_student_and_a_failed_one_refuses(tmp_path, monkeypatch):
    from autograder.grading import canary

    course = tmp_path / "course"
    (course / "submitted").mkdir(parents=True)
    (course / "nbgrader_config.py").write_text("c = get_config()\n")
    (course / "gradebook.db").write_bytes(b"")
    seen, lines = [], []

    def fake_check(grade, box, **kw):  # the run's grading function and the sandbox it grades in
        seen.append(box.isolation.level)
        return canary.CanaryReport(75.0, 75.0, 0.5, box.isolation.as_dict())

    monkeypatch.setattr(canary, "check", fake_check)
    assert nc.grade_course(course, config=quick_config(), pictures=False, log=lines.append) == {}
    assert len(seen) == 1 and lines and lines[0].startswith("canary: the answer key got 75 / 75")

    def failing(grade, box, **kw):
        raise canary.CanaryFailed("canary: the answer key did not get full marks (on purpose)")

    monkeypatch.setattr(canary, "check", failing)
    with pytest.raises(ValueError, match="on purpose"):
        nc.grade_course(course, config=quick_config(), pictures=False, log=lines.append)


@needs_nbgrader
def test_course_config_runs_nothing_of_the_kit(tmp_path, grading_settings):
    from traitlets.config.loader import PyFileConfigLoader

    course = nc.build_course(tmp_path / "course", stems=["q2_eightpoint"])
    config = PyFileConfigLoader("nbgrader_config.py", str(course)).load_config()
    assert "autograde_preprocessors" not in config.Autograde
    assert config.CourseDirectory.root == str(course.resolve())


# ------------------------------------------------------------------------------------------------
# pictures in the feedback


class _Images(HTMLParser):
    def __init__(self):
        super().__init__()
        self.found = []

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.found.append(dict(attrs))


def images(page: str) -> list[dict]:
    """The attributes of every ``<img>`` of ``page`` whose source is an embedded PNG."""
    parser = _Images()
    parser.feed(page)
    parser.close()
    return [a for a in parser.found if (a.get("src") or "").startswith("data:image/png;base64,")]


def hidden_cell(page: str, qid: str) -> str:
    """The part of a feedback page from ``qid``'s hidden-check cell (nbgrader's anchor) to the next cell."""
    start = page.index(f'name="hidden_{qid.replace(".", "_")}"')
    end = page.find('<div class="cell ', start)
    return page[start:] if end < 0 else page[start:end]


def tiny_png() -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 3), (200, 80, 0)).save(buf, format="PNG")
    return buf.getvalue()


@needs_nbgrader
def test_a_picture_output_renders_as_an_image_with_its_alt_text_and_quotes_stay_text():
    """The outputs nbgrader-grade writes, through nbconvert's classic template (the base of
    nbgrader's feedback template): the PNG embedded, the alt text as the img's alt, and markup or
    terminal escapes in an alt text or a "figure not drawn" sentence shown, never obeyed."""
    import base64

    from nbconvert import HTMLExporter

    from autograder.channels.nbgrader.pictures import cell_outputs
    from autograder.feedback.pictures import contract

    png = tiny_png()
    alt = 'epipolar lines "><script>alert(1)</script> & \x1b[31mred\u202e'
    nb = nbformat.v4.new_notebook()
    drawn, missing = nbformat.v4.new_code_cell("0.0"), nbformat.v4.new_code_cell("0.0")
    drawn.outputs = cell_outputs("Q2 eightpoint: 10 / 10 points", contract().Picture("Q2", "a title", png, alt, {}))
    missing.outputs = cell_outputs("Q3.1 essentialMatrix: 0 / 5 points",
                                   "figure not drawn: <img src=x onerror=alert(2)>\x1b]8;;http://x\x07link")
    nb.cells = [drawn, missing]
    nbformat.validate(nb)
    page, _ = HTMLExporter(template_name="classic").from_notebook_node(nb)

    [img] = images(page)
    assert base64.b64decode(img["src"].split(",", 1)[1]) == png
    assert img["alt"] == 'epipolar lines "><script>alert(1)</script> & red\\u202e'  # data: the parser gives it back as text
    assert drawn.outputs[1]["data"]["text/plain"] == img["alt"]
    assert "<script>alert" not in page and "<img src=x" not in page and "\x1b" not in page
    assert "figure not drawn: &lt;img src=x onerror=alert(2)&gt;link" in page and "a title" in page


# ------------------------------------------------------------------------------------------------
# nbgrader end to end


TAMPER = """\
# One extra cell in an untouched q1: a fake judge appended to the course's autograder package,
# and numpy patched for whatever runs later in this kernel.
from pathlib import Path
import numpy
course = next(p for p in [Path.cwd(), *Path.cwd().parents] if (p / "nbgrader_config.py").is_file())
target = course / "autograder" / "tests" / "__init__.py"
try:
    with open(target, "a") as fh:
        fh.write("\\n\\ndef judge_all(*args, **kwargs):\\n    return {q: 100.0 for q in ('Q2', 'Q3.1', 'Q3.2', 'Q3.3')}\\n")
except OSError as exc:
    print("tamper failed:", exc)
numpy.allclose = lambda *a, **k: True
"""


def tampering_submission(course: Path, student: str) -> Path:
    folder = nc.submit_release(course, student)
    path = folder / "q1_proofs.ipynb"
    nb = nbformat.read(path, as_version=4)
    setup = next(k for k, c in enumerate(nb.cells) if c.cell_type == "code")
    nb.cells.insert(setup + 1, nbformat.v4.new_code_cell(TAMPER))
    nbformat.write(nb, path)
    return folder


def course_digest(course: Path) -> dict:
    """sha256 of every course file nbgrader does not write itself (its outputs and caches excluded)."""
    skip = {"autograded", "feedback", "__pycache__", ".ipynb_checkpoints"}
    return {p.relative_to(course).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(course.rglob("*")) if p.is_file() and not skip & set(p.relative_to(course).parts)
            and p.name not in ("gradebook.db", "grades.csv")}


@pytest.mark.slow
@needs_nbgrader
def test_nbgrader_end_to_end_with_a_tampering_student(tmp_path, grading_settings):
    stems = list(NOTEBOOKS) if os.environ.get("HW4_NBGRADER_ALL") == "1" else ["q1_proofs", "q2_eightpoint", "q3_metric_reconstruction"]
    course = nc.build_course(tmp_path / "course", stems=stems)
    nc.run_nbgrader(course, "generate_assignment", "hw4", "--force")
    release = course / "release" / "hw4"
    assert sorted(p.stem for p in release.glob("*.ipynb")) == sorted(stems)
    for path in release.glob("*.ipynb"):
        text = path.read_text()
        assert "BEGIN HIDDEN TESTS" not in text and "BEGIN SOLUTION" not in text

    nc.submit_key(course, "a-key")
    tampering_submission(course, "b-tamper")
    nc.submit_release(course, "c-untouched")
    before = course_digest(course)
    nc.run_nbgrader(course, "autograde", "hw4", "--force")
    # Before the kit's step, the hidden-check cells are worth nothing, whatever the kernels did.
    for student in ("a-key", "b-tamper", "c-untouched"):
        assert set(nc.kit_scores(course, student).values()) == {0.0}
    canary_lines = []
    results = nc.grade_course(course, config=load_config(), log=canary_lines.append)
    assert canary_lines and canary_lines[0].startswith("canary: the answer key got")  # the real canary ran
    after = course_digest(course)
    assert after == before, {k for k in set(before) | set(after) if before.get(k) != after.get(k)}

    qids = [q.id for s in stems for q in autograded(s)]
    assert nc.kit_scores(course, "a-key") == {q: float(question(q).points) for q in qids}
    for student in ("b-tamper", "c-untouched"):
        # What the kit's grader gave (zero for untouched work), and nothing the kernel claimed.
        assert nc.kit_scores(course, student) == {q: 0.0 for q in qids}
        by_id = {q.id: q.score for q in results[student].questions}
        assert {q: by_id[q] for q in qids} == nc.kit_scores(course, student)
    hidden = {k: v for k, v in nc.autograded_scores(course, "a-key").items() if k.startswith("hidden_")}
    for grade_id, (score, max_score) in hidden.items():
        q = nc.question_of_grade_id(grade_id)
        assert max_score == (0 if q.extra_credit else q.points) and score == q.points

    nc.run_nbgrader(course, "generate_feedback", "hw4", "--force")
    q2 = question("Q2")
    feedback = (course / "feedback" / "a-key" / "hw4" / "q2_eightpoint.html").read_text()
    assert f"Q2 {q2.title}: {q2.points:g} / {q2.points:g} points" in feedback
    assert "hidden checks" in (course / "feedback" / "c-untouched" / "hw4" / "q2_eightpoint.html").read_text()
    # Under each verdict, the picture of the public data: the key's drawn, with its text as alt;
    # the untouched stubs raise there, so the verdict says why there is no figure instead.
    [key_q2] = images(hidden_cell(feedback, "Q2"))
    assert "epipolar" in key_q2["alt"]
    for qid in qids:
        page = (course / "feedback" / "a-key" / "hw4" / f"{question(qid).notebook}.html").read_text()
        [img] = images(hidden_cell(page, qid))
        assert img["alt"].strip() and "figure not drawn" not in hidden_cell(page, qid)
        for student in ("b-tamper", "c-untouched"):
            page = (course / "feedback" / student / "hw4" / f"{question(qid).notebook}.html").read_text()
            assert "figure not drawn: " in hidden_cell(page, qid) and not images(hidden_cell(page, qid)), (student, qid)

    nc.run_nbgrader(course, "export")
    rows = {r["student_id"]: r for r in csv.DictReader((course / "grades.csv").open())}
    assert set(rows) == {"a-key", "b-tamper", "c-untouched"}
    base = sum(question(q).points for q in qids if not question(q).extra_credit)
    extra = sum(question(q).points for q in qids if question(q).extra_credit)
    assert float(rows["a-key"]["score"]) == pytest.approx(base + extra)
    assert float(rows["b-tamper"]["score"]) == 0 and float(rows["c-untouched"]["score"]) == 0
