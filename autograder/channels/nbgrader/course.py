"""An nbgrader course for the homework, scored by the kit's own sandboxed grader outside nbgrader.

``python -m autograder nbgrader --out COURSE_DIR`` writes a course directory for nbgrader 0.9:

=============================  ================================================================
``nbgrader_config.py``         course id, gradebook, execution timeout
``source/hw4/<stem>.ipynb``    ``notebooks/nbgrader/source/hw4`` with, under every autograded
                               question, one hidden-check cell: worth the manifest's points, or
                               0 points for an extra-credit question (its points go to nbgrader's
                               ``extra_credit``); the public self-check cells become read-only
                               (students keep them, they carry no points)
``core/ scenes/ starter/``     what the notebooks import and load (``core.shipping``'s sandbox
``judging/ data/``             packages): their setup cell finds them in a parent folder
=============================  ================================================================

No grader code, reference solution or grading secret is in the course: the kernel that nbgrader
starts for a student's notebook runs that student's code with the instructor's rights, and can
read or change anything in the course.

The workflow, in the course folder: ``nbgrader generate_assignment hw4``, collect the submissions
into ``submitted/<student>/hw4/``, ``nbgrader autograde hw4``, then

    python -m autograder nbgrader-grade COURSE_DIR [--assignment hw4] [--student NAME...] [--no-pictures]

(from the instructor's kit, with the grading settings of ``python -m autograder grade``; that step is
``autograder.channels.nbgrader.grade``, this module only builds the course), then
``nbgrader generate_feedback hw4`` and ``nbgrader export``.  ``--selftest`` runs them all with the
answer key as a student and reports its score.

How a hidden-check cell is scored
---------------------------------
The cell holds no grading code: between nbgrader's ``BEGIN/END HIDDEN TESTS`` markers it is the
literal ``0.0``, so ``nbgrader autograde`` records 0 points for it whatever the kernel does (or full
marks only if the kernel fakes its output: either way the next step overwrites it).
``nbgrader-grade`` (:func:`grade_course`), a separate process of the instructor's kit started
after autograde, grades each student's submitted folder with one ``GradingRun`` (the same code
as ``python -m autograder grade`` and Gradescope; student code runs in the sandbox, the course
folder hidden from it) and writes the points into the gradebook through nbgrader's own API
(``nbgrader.api.Gradebook``: the ``Grade`` of each hidden-check cell gets ``auto_score``, or
``extra_credit`` for an extra-credit question), and the question's feedback into that cell's
outputs in ``autograded/``, which ``generate_feedback`` shows: the verdict, then the unscored
picture of what the student's functions returned on the public data, as the other channels show
it (``--no-pictures``: the verdict only).  Nothing the kernel did, to the notebook, to its own
imports or to the course's files, enters those points.

What nbgrader itself cannot protect: student code in nbgrader's kernel can read and write what
the instructor can (other students' files, ``gradebook.db``, the course's copies of ``starter/``),
and leave processes running.  The scores survive that (they come from the submitted files, the
instructor's kit and its sandbox, and are written after autograde), but run ``nbgrader
autograde`` on untrusted submissions on a machine or container that holds nothing else of value.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from core.manifest import NOTEBOOKS, QUESTIONS, Question
from core.paths import KIT_ROOT
from core.shipping import SANDBOX_PACKAGES

from autograder.channels.shipping import data_files, package_files
# Grading in the course is nbgrader_grade's; re-exported, as the course's own workflow (selftest) uses it.
from .grade import (
    ASSIGNMENT,
    COURSE_ID,
    HIDDEN_PREFIX,
    add_grade_cli,
    autograded_scores,
    grade_cli,
    grade_course,
    gradebook,
    grading_config_of,
    kit_scores,
    nbgrader_metadata,
    question_of_grade_id,
    tools_path,
)

if TYPE_CHECKING:
    import nbformat

__all__ = [
    "ASSIGNMENT",
    "COURSE_ID",
    "COURSE_PACKAGES",
    "HIDDEN_PREFIX",
    "add_cli",
    "add_grade_cli",
    "add_hidden_checks",
    "autograded_scores",
    "build_course",
    "grade_course",
    "kit_scores",
    "run_nbgrader",
    "gradebook",
    "selftest",
    "submit_key",
    "submit_release",
]

SOURCE_DIR = Path("notebooks") / "nbgrader" / "source" / ASSIGNMENT
_BEGIN_HIDDEN, _END_HIDDEN = "### BEGIN HIDDEN TESTS", "### END HIDDEN TESTS"
_BEGIN_SOLUTION, _END_SOLUTION = "### BEGIN SOLUTION", "### END SOLUTION"
_EXECUTE_TIMEOUT = 300   # seconds per cell; the slowest reference cell takes a few seconds
COURSE_PACKAGES = SANDBOX_PACKAGES  # what the notebooks import: the packages student code may use
_PLACEHOLDER = "0.0"


# ------------------------------------------------------------------------------------------------
# cells


def _grade_id_of(qid: str) -> str:
    return HIDDEN_PREFIX + qid.replace(".", "_")


def _hidden_cell(q: Question, stem: str) -> nbformat.NotebookNode:
    import nbformat

    credit = f"{q.points} points of extra credit" if q.extra_credit else f"{q.points} points"
    text = "\n".join([
        f"# {q.id}: hidden checks [{credit}].  The course's autograder runs your functions on inputs",
        "# you have not seen, outside this notebook; its points and feedback appear here once your work is graded.",
        _BEGIN_HIDDEN,
        f"{_PLACEHOLDER}  # no grading code here: the points are written into the gradebook after autograding",
        _END_HIDDEN,
    ])
    cell = nbformat.v4.new_code_cell(text)
    # Extra credit is worth 0 in nbgrader's totals; grade_course puts its points in extra_credit.
    cell.metadata = {"nbgrader": {"grade": True, "grade_id": _grade_id_of(q.id), "locked": True,
                                  "points": 0 if q.extra_credit else q.points, "schema_version": 3,
                                  "solution": False, "task": False}}
    cell["id"] = f"{stem}-{_grade_id_of(q.id)}".replace("_", "-")[:64]
    return cell


def add_hidden_checks(nb: nbformat.NotebookNode, stem: str) -> nbformat.NotebookNode:
    """The nbgrader source notebook ``nb`` of ``stem`` with the kit's hidden checks (a new notebook).

    Every autograded question of ``stem`` gets one hidden-check cell worth the manifest's points
    (0 for extra credit, which ``grade_course`` records as nbgrader's extra credit), after the last cell of that question's functions (solution or public check).  The public
    check cells (``grade_id`` ``check_<function>``) stop being graded and stay locked, so the
    notebook's autograded points add up to the manifest's; by-hand answers keep theirs.

    Raises
    ------
    ValueError
        When ``stem`` is not a manifest notebook, or a question of it has no cell of its
        functions to put the hidden checks after.
    """
    import nbformat

    if stem not in NOTEBOOKS:
        raise ValueError(f"stem: expected one of {list(NOTEBOOKS)}, got {stem!r}")
    nb = nbformat.from_dict(nb)  # a deep copy: the caller's notebook stays as it was
    owner = {f: q for q in QUESTIONS if q.notebook == stem and not q.by_hand for f in q.functions}
    last: dict[str, int] = {}
    for k, cell in enumerate(nb.cells):
        meta = nbgrader_metadata(cell)
        grade_id = meta.get("grade_id", "")
        function = grade_id[len("check_"):] if grade_id.startswith("check_") else grade_id
        if function in owner:
            last[owner[function].id] = k
            if meta.get("grade") and not meta.get("solution"):
                meta.update(grade=False, locked=True)
                meta.pop("points", None)
    wanted = [q for q in QUESTIONS if q.notebook == stem and not q.by_hand]
    missing = [q.id for q in wanted if q.id not in last]
    if missing:
        raise ValueError(f"nb: expected a solution or check cell for {missing} in {stem}, found none")
    for q in sorted(wanted, key=lambda q: last[q.id], reverse=True):
        nb.cells.insert(last[q.id] + 1, _hidden_cell(q, stem))
    nbformat.validate(nb)
    return nb


# ------------------------------------------------------------------------------------------------
# scoring with the kit's grader, outside nbgrader


# ------------------------------------------------------------------------------------------------
# the course directory

_CONFIG = '''\
# nbgrader configuration of the hw4 course, written by `python -m autograder nbgrader`.
# The hidden checks are scored after `nbgrader autograde` by `python -m autograder nbgrader-grade`.
from pathlib import Path

_course = Path(__file__).resolve().parent

c = get_config()  # noqa: F821 - traitlets defines it when it runs this file
c.CourseDirectory.course_id = "{course_id}"
c.CourseDirectory.root = str(_course)
c.CourseDirectory.db_url = "sqlite:///" + str(_course / "gradebook.db")
c.Execute.timeout = {timeout}
'''

_README = '''\
# hw4 nbgrader course

Written by `python -m autograder nbgrader`.  Run the nbgrader commands in this folder.

    nbgrader generate_assignment {assignment} --force    # release/{assignment}/: what students get
    # put each submission in submitted/<student>/{assignment}/ (with a timestamp.txt)
    nbgrader autograde {assignment}                      # autograded/...: runs the notebooks
    python -m autograder nbgrader-grade COURSE --assignment {assignment}   # from the kit: the hidden checks' points
    nbgrader generate_feedback {assignment}              # feedback/<student>/{assignment}/*.html (verdicts, pictures)
    nbgrader export                            # grades.csv

The hidden-check cells carry the points of the autograded questions; the kit's sandboxed grader
writes them into the gradebook after autograde (run nbgrader-grade again after any new autograde).
Extra-credit questions (Q6) are worth 0 in nbgrader's totals and their points are recorded as
nbgrader's extra credit.  The public self-check cells are read-only and carry no points.  Questions
answered in writing are graded by hand (`nbgrader formgrader`).

Student code runs unsandboxed in nbgrader's kernel, with your rights: run autograde on untrusted
submissions on a machine that holds nothing else of value.
'''


def _source_notebooks(kit_root: Path, stems) -> dict[str, nbformat.NotebookNode]:
    import nbformat

    folder = kit_root / SOURCE_DIR
    out = {}
    for stem in stems:
        path = folder / f"{stem}.ipynb"
        if path.is_file():
            out[stem] = nbformat.read(path, as_version=4)
        else:
            # Not built yet: build it the way `python -m kit notebooks` would.
            from kit.notebooks import build_notebook

            out[stem] = build_notebook(stem, "nbgrader", src_dir=kit_root / "notebooks" / "src",
                                       solutions_dir=kit_root / "solutions")
    return out


def build_course(out: str | Path, *, kit_root: str | Path = KIT_ROOT, stems=None, force: bool = False) -> Path:
    """Write the nbgrader course directory ``out`` (layout in the module docstring); return it.

    Parameters
    ----------
    out : the folder to write; it must not exist or be empty, unless ``force`` and it is a course
        folder written before (it holds nbgrader_config.py).
    kit_root : the kit whose notebooks and student packages are used (default: this one).
    stems : the manifest notebooks to include (default: all of them, in manifest order).
    force : replace what ``out`` holds (the gradebook and submissions included).

    The course holds no grader, reference solution or secret (``grade_course`` brings them).

    Raises
    ------
    ValueError
        For an unknown stem, or an ``out`` that holds files while ``force`` is False.
    """
    import nbformat

    out = Path(out)
    stems = list(NOTEBOOKS if stems is None else stems)
    unknown = [s for s in stems if s not in NOTEBOOKS]
    if unknown or not stems:
        raise ValueError(f"stems: expected names among {list(NOTEBOOKS)}, got {stems}")
    if out.exists() and any(out.iterdir()):
        if not force:
            raise ValueError(f"out: expected a new or empty folder, got {out} which holds files (use --force)")
        if not (out / "nbgrader_config.py").is_file():
            # --force replaces a course, never an arbitrary folder given by mistake.
            raise ValueError(f"out: expected a course folder (with nbgrader_config.py) to replace, got {out}")
        shutil.rmtree(out)
    root = Path(kit_root).resolve()
    notebooks = {stem: add_hidden_checks(nb, stem) for stem, nb in _source_notebooks(root, stems).items()}
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="hw4-course-") as tmp:
        files = [(p.relative_to(root).as_posix(), p) for pkg in COURSE_PACKAGES for p in package_files(root, pkg)]
        for name, path in files + data_files(root, Path(tmp)):
            dest = out / name
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, dest)
    source = out / "source" / ASSIGNMENT
    source.mkdir(parents=True)
    for stem, nb in notebooks.items():
        nbformat.write(nb, source / f"{stem}.ipynb")
    (out / "nbgrader_config.py").write_text(_CONFIG.format(course_id=COURSE_ID, timeout=_EXECUTE_TIMEOUT))
    (out / "README.md").write_text(_README.format(assignment=ASSIGNMENT))
    return out


# ------------------------------------------------------------------------------------------------
# running nbgrader, submissions, scores


def run_nbgrader(course: str | Path, *args: str, timeout: float = 1800) -> subprocess.CompletedProcess:
    """``nbgrader <args>`` in the course folder with this Python; its output (stdout+stderr).

    Raises
    ------
    RuntimeError
        When nbgrader is not installed or the command fails (with the end of its log).
    """
    proc = subprocess.run([sys.executable, "-m", "nbgrader", *args], cwd=course, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=timeout, check=False,
                          env={**os.environ, "PATH": tools_path()})
    if proc.returncode != 0:
        tail = "\n".join(proc.stdout.splitlines()[-40:])
        raise RuntimeError(f"nbgrader {' '.join(args)} failed (exit code {proc.returncode}):\n{tail}")
    return proc


def _submission_folder(course: Path, student: str) -> Path:
    if not student or not all(c.isalnum() or c in "-_." for c in student) or student.startswith("."):
        raise ValueError(f"student: expected letters, digits and -_. only, got {student!r}")
    folder = course / "submitted" / student / ASSIGNMENT
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S.%f %Z")
    (folder / "timestamp.txt").write_text(stamp + "\n")
    return folder


def _release(course: Path) -> Path:
    release = course / "release" / ASSIGNMENT
    if not any(release.glob("*.ipynb")):
        raise FileNotFoundError(f"course: no release notebooks in {release}; run nbgrader generate_assignment first")
    return release


def submit_release(course: str | Path, student: str) -> Path:
    """Submit the release notebooks untouched as ``student`` (their work left undone)."""
    course = Path(course)
    release = _release(course)
    folder = _submission_folder(course, student)
    for path in sorted(release.glob("*.ipynb")):
        shutil.copyfile(path, folder / path.name)
    return folder


def _unmarked(text: str) -> str:
    return "\n".join(line for line in text.splitlines() if line.strip() not in (_BEGIN_SOLUTION, _END_SOLUTION))


def submit_key(course: str | Path, student: str) -> Path:
    """Submit the answer key as ``student``: the release notebooks with every answer cell
    filled in from the course's source notebooks (their solution regions, markers removed)."""
    import nbformat

    course = Path(course)
    release = _release(course)
    folder = _submission_folder(course, student)
    for path in sorted(release.glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        source = nbformat.read(course / "source" / ASSIGNMENT / path.name, as_version=4)
        answers = {nbgrader_metadata(c).get("grade_id"): c.source for c in source.cells
                   if nbgrader_metadata(c).get("solution")}
        for cell in nb.cells:
            grade_id = nbgrader_metadata(cell).get("grade_id")
            if nbgrader_metadata(cell).get("solution") and grade_id in answers:
                cell.source = _unmarked(answers[grade_id])
        nbformat.write(nb, folder / path.name)
    return folder


def selftest(course: str | Path, student: str = "answer-key", *, config=None) -> tuple[float, float]:
    """Run the whole workflow in ``course`` with the answer key as ``student``.

    generate_assignment, the key's submission, autograde, ``grade_course``, generate_feedback and
    export; returns the key's (points, out of) over the hidden-check cells, extra credit included.
    """
    course = Path(course)
    run_nbgrader(course, "generate_assignment", ASSIGNMENT, "--force")
    submit_key(course, student)
    run_nbgrader(course, "autograde", ASSIGNMENT, "--force", f"--student={student}")
    grade_course(course, students=[student], config=config)
    run_nbgrader(course, "generate_feedback", ASSIGNMENT, "--force", f"--student={student}")
    run_nbgrader(course, "export")
    scores = kit_scores(course, student)
    stems = {p.stem for p in (course / "source" / ASSIGNMENT).glob("*.ipynb")}
    total = sum(q.points for q in QUESTIONS if q.notebook in stems and not q.by_hand)
    return sum(scores.values()), float(total)


def _cli(args) -> int:
    course = build_course(args.out, stems=args.notebooks, force=args.force)
    print(f"wrote the nbgrader course {course}")
    if args.selftest:
        score, total = selftest(course, config=grading_config_of(args))
        print(f"self-test: the answer key scores {score:g} / {total:g} on the hidden checks (extra credit included)")
        return 0 if abs(score - total) < 1e-9 else 1
    print(f"next: cd {course} && nbgrader generate_assignment {ASSIGNMENT} --force  (see README.md)")
    return 0


def add_cli(subparsers) -> None:
    """Register ``python -m autograder nbgrader`` (and ``nbgrader-grade``, see ``add_grade_cli``)."""
    p = subparsers.add_parser(
        "nbgrader", help="write an nbgrader course directory scored by the kit's autograder",
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="the course folder to write")
    p.add_argument("--notebooks", nargs="+", default=None, metavar="STEM",
                   help=f"only these notebooks (default: all of {', '.join(NOTEBOOKS)})")
    p.add_argument("--force", action="store_true", help="replace what the folder holds (gradebook included)")
    p.add_argument("--config", default=None, help="grader settings for --selftest (default: $HW4_GRADER_CONFIG)")
    p.add_argument("--allow-dev-secret", action="store_true",
                   help="--selftest even without the course's grading secret (HW4_GRADER_SECRET / HW4_GRADER_CONFIG)")
    p.add_argument("--selftest", action="store_true",
                   help="then run nbgrader end to end with the answer key as a student (needs nbgrader)")
    p.set_defaults(func=_cli)
    add_grade_cli(subparsers)
