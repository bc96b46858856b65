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

    python -m autograder nbgrader-grade COURSE_DIR [--assignment hw4] [--student NAME...]

(from the instructor's kit, with the grading settings of ``python -m autograder grade``), then
``nbgrader generate_feedback hw4`` and ``nbgrader export``.  ``--selftest`` runs them all with the
answer key as a student and reports its score.

How a hidden-check cell is scored
---------------------------------
The cell holds no grading code: between nbgrader's ``BEGIN/END HIDDEN TESTS`` markers it is the
literal ``0.0``, so ``nbgrader autograde`` records 0 points for it whatever the kernel does (or full
marks only if the kernel fakes its output: either way the next step overwrites it).
``nbgrader-grade`` (:func:`grade_course`), a separate process of the instructor's kit started
after autograde, grades each student's submitted folder with ``grade_submission`` (the same code
as ``python -m autograder grade`` and Gradescope; student code runs in the sandbox, the course
folder hidden from it) and writes the points into the gradebook through nbgrader's own API
(``nbgrader.api.Gradebook``: the ``Grade`` of each hidden-check cell gets ``auto_score``, or
``extra_credit`` for an extra-credit question), and the question's feedback into that cell's
output in ``autograded/``, which ``generate_feedback`` shows.  Nothing the kernel did, to the
notebook, to its own imports or to the course's files, enters those points.

What nbgrader itself cannot protect: student code in nbgrader's kernel can read and write what
the instructor can (other students' files, ``gradebook.db``, the course's copies of ``starter/``),
and leave processes running.  The scores survive that (they come from the submitted files, the
instructor's kit and its sandbox, and are written after autograde), but run ``nbgrader
autograde`` on untrusted submissions on a machine or container that holds nothing else of value.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from core.manifest import NOTEBOOKS, QUESTIONS, Question

from core.shipping import SANDBOX_PACKAGES
from core.untrusted import for_terminal

from .gradescope import KIT_ROOT, _package_files, data_files, hideable

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
    "selftest",
    "submit_key",
    "submit_release",
]

ASSIGNMENT = "hw4"
COURSE_ID = "hw4"
HIDDEN_PREFIX = "hidden_"
SOURCE_DIR = Path("notebooks") / "nbgrader" / "source" / ASSIGNMENT
_BEGIN_HIDDEN, _END_HIDDEN = "### BEGIN HIDDEN TESTS", "### END HIDDEN TESTS"
_BEGIN_SOLUTION, _END_SOLUTION = "### BEGIN SOLUTION", "### END SOLUTION"
_EXECUTE_TIMEOUT = 300   # seconds per cell; the slowest reference cell takes a few seconds
COURSE_PACKAGES = SANDBOX_PACKAGES  # what the notebooks import: the packages student code may use
_PLACEHOLDER = "0.0"


# ------------------------------------------------------------------------------------------------
# cells


def _nbgrader(cell) -> dict:
    return cell.get("metadata", {}).get("nbgrader", {})


def _grade_id_of(qid: str) -> str:
    return HIDDEN_PREFIX + qid.replace(".", "_")


def _question_of_grade_id(grade_id: str) -> Question | None:
    if not grade_id.startswith(HIDDEN_PREFIX):
        return None
    wanted = grade_id[len(HIDDEN_PREFIX):]
    return next((q for q in QUESTIONS if q.id.replace(".", "_") == wanted and not q.by_hand), None)


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
        meta = _nbgrader(cell)
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


def _describe(q) -> str:
    credit = " (extra credit)" if q.extra_credit else ""
    lines = [f"{q.id} {q.title}: {q.score:g} / {q.max_score:g} points{credit}"]
    lines += [f"- {n}" for n in q.notes]
    hidden = [t for t in q.tests if t.visibility == "hidden"]
    for t in q.tests:
        if t.visibility != "hidden":
            verdict = "passed" if t.passed else "failed"
            lines.append(f"- {t.name}: {verdict} ({t.score:g} / {t.max_score:g})" + (f". {t.feedback}" if t.feedback else ""))
    if hidden:
        lines.append(f"- {len(hidden)} hidden check(s): {sum(t.score for t in hidden):g} / "
                     f"{sum(t.max_score for t in hidden):g}")
    return "\n".join(lines)


def _verdicts(result) -> dict[str, tuple[float, str]]:
    """qid -> (points, feedback) of every autograded question of ``result`` (zero with the reason
    for a question that was not graded)."""
    by_id = {q.id: q for q in result.questions}
    out = {}
    for q in QUESTIONS:
        if q.by_hand:
            continue
        if result.failure or q.id not in by_id:
            why = result.failure or "not graded"
            out[q.id] = (0.0, f"{q.id} {q.title}: 0 / {q.points} points ({why})")
        else:
            out[q.id] = (float(by_id[q.id].score), _describe(by_id[q.id]))
    return out


def _students(course: Path, assignment: str, students) -> list[str]:
    found = sorted(p.parent.name for p in (course / "submitted").glob(f"*/{assignment}") if p.is_dir())
    if students is None:
        return found
    missing = [s for s in students if s not in found]
    if missing:
        raise ValueError(f"students: expected names with a folder submitted/<name>/{assignment}, got {missing}")
    return list(students)


def _write_feedback(course: Path, assignment: str, student: str, verdicts: dict) -> None:
    """The kit's feedback as the output of each hidden-check cell of the autograded notebooks."""
    import nbformat

    for path in sorted((course / "autograded" / student / assignment).glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        changed = False
        for cell in nb.cells:
            q = _question_of_grade_id(_nbgrader(cell).get("grade_id", ""))
            if q is not None and cell.cell_type == "code":
                # A stream output is shown as a terminal would (nbconvert turns ANSI escapes into markup).
                text = for_terminal(verdicts[q.id][1])
                cell.outputs = [nbformat.v4.new_output("stream", name="stdout", text=text + "\n")]
                changed = True
        if changed:
            nbformat.write(nb, path)


def grade_course(course: str | Path, *, assignment: str = ASSIGNMENT, students=None, config=None,
                 isolation: str = "auto", progress=None, log=print) -> dict:
    """Grade every submission of ``assignment`` with the kit's grader and write the points into
    the course's gradebook; run after ``nbgrader autograde``.  Returns student -> SubmissionResult.

    Each ``submitted/<student>/<assignment>`` folder is graded with ``grade_submission`` (the
    instructor's kit, never the course's files; student code in the sandbox with the course
    folder hidden).  Then, through ``nbgrader.api.Gradebook``, every hidden-check cell's ``Grade``
    gets the question's points as ``auto_score`` (extra credit: ``auto_score`` 0 and the points as
    ``extra_credit``), replacing whatever autograde recorded, and the question's feedback becomes
    that cell's output in ``autograded/`` (what ``generate_feedback`` shows).

    First the canary (``autograder.canary.check``): the answer key, graded in the very sandbox and
    with the same hidden inputs, must get every point, or no student is graded.

    Parameters
    ----------
    course : the nbgrader course folder (with nbgrader_config.py and gradebook.db).
    students : names to grade (default: every submitted folder of ``assignment``).
    config : ``GradingConfig`` (default: ``load_config()``, as ``python -m autograder grade``).
    isolation : the sandbox level ("auto": the strongest that works here).
    progress : optional callable(student, result) called after each student.
    log : callable(str) given one line when the canary passed (default ``print``; None: silent).

    Raises
    ------
    ValueError
        When ``course`` has no gradebook or a named student has no submission, or a student
        graded here was not autograded by nbgrader first (no submission in the gradebook).
    CanaryFailed (a ValueError)
        When the answer key did not get full marks here; its message says why and how to fix
        it, and the gradebook is left untouched.
    """
    from nbgrader.api import MissingEntry

    from . import canary
    from .config import load_config
    from .grade import grade_submission
    from .hidden.inputs import build_hidden_inputs
    from .sandbox import Sandbox

    course = Path(course).resolve()
    db = course / "gradebook.db"
    if not (course / "nbgrader_config.py").is_file() or not db.is_file():
        raise ValueError(f"course: expected an nbgrader course with gradebook.db (run nbgrader autograde first), got {course}")
    names = _students(course, assignment, students)
    config = config if config is not None else load_config()
    hidden = build_hidden_inputs(config)
    results = {}
    with gradebook(db) as gb:
        for student in names:
            try:
                gb.find_submission(assignment, student)
            except MissingEntry:
                raise ValueError(f"students: {student} has no autograded submission of {assignment} in "
                                 f"the gradebook; run nbgrader autograde first") from None
    with Sandbox(KIT_ROOT, hidden=hideable([course, config.source, config.official_dir()]), isolation=isolation) as box:
        report = canary.check(box, hidden)  # raises CanaryFailed: nothing graded, nothing written
        if log is not None:
            log(f"canary: the answer key got {report.score:g} / {report.max_score:g} in this sandbox "
                f"({box.isolation.summary()}) in {report.seconds:.1f} s; grading {len(names)} submissions")
        for student in names:
            folder = course / "submitted" / student / assignment
            result = grade_submission(folder, sandbox=box, hidden_inputs=hidden, student_id=student)
            results[student] = result
            verdicts = _verdicts(result)
            with gradebook(db) as gb:
                submission = gb.find_submission(assignment, student)
                for notebook in submission.notebooks:
                    for grade in notebook.grades:
                        q = _question_of_grade_id(grade.name)
                        if q is None:
                            continue
                        score = verdicts[q.id][0]
                        if q.extra_credit:
                            grade.auto_score, grade.extra_credit = 0.0, score
                        else:
                            grade.auto_score, grade.extra_credit = min(score, float(grade.max_score)), None
                        grade.manual_score = None
                        grade.needs_manual_grade = False
                gb.db.commit()
            _write_feedback(course, assignment, student, verdicts)
            if progress is not None:
                progress(student, result)
    return results


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
    nbgrader generate_feedback {assignment}              # feedback/<student>/{assignment}/*.html
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
        files = [(p.relative_to(root).as_posix(), p) for pkg in COURSE_PACKAGES for p in _package_files(root, pkg)]
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


def tools_path() -> str:
    """PATH with the running environment's own scripts folder first.

    nbgrader's Gradebook runs the ``alembic`` command it finds on PATH; a Python started as
    ``.venv/bin/python`` without activating the environment has that command beside it, not on
    PATH, so the run would depend on the shell it came from.
    """
    here = str(Path(sys.executable).parent)   # not resolved: a venv's python is a symlink out of it
    old = os.environ.get("PATH", "")
    return old if here in old.split(os.pathsep) else here + os.pathsep + old


@contextlib.contextmanager
def _own_tools():
    old = os.environ.get("PATH")
    os.environ["PATH"] = tools_path()
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("PATH", None)
        else:
            os.environ["PATH"] = old


@contextlib.contextmanager
def gradebook(db: str | Path):
    """nbgrader's Gradebook of the sqlite file ``db`` for this course, opened with this environment's tools."""
    from nbgrader.api import Gradebook

    with _own_tools(), Gradebook(f"sqlite:///{db}", COURSE_ID) as gb:
        yield gb


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
        answers = {_nbgrader(c).get("grade_id"): c.source for c in source.cells if _nbgrader(c).get("solution")}
        for cell in nb.cells:
            grade_id = _nbgrader(cell).get("grade_id")
            if _nbgrader(cell).get("solution") and grade_id in answers:
                cell.source = _unmarked(answers[grade_id])
        nbformat.write(nb, folder / path.name)
    return folder


def autograded_scores(course: str | Path, student: str) -> dict[str, tuple[float, float]]:
    """``grade_id -> (score, max_score)`` of the autograded code cells of ``student``'s hw4, as
    nbgrader counts them (``score`` includes the cell's extra credit)."""
    course = Path(course)
    out = {}
    with gradebook(course / "gradebook.db") as gb:
        submission = gb.find_submission(ASSIGNMENT, student)
        for notebook in submission.notebooks:
            for grade in notebook.grades:
                if grade.cell_type == "code":
                    out[grade.name] = (float(grade.score or 0.0), float(grade.max_score))
    return out


def kit_scores(course: str | Path, student: str) -> dict[str, float]:
    """question id -> the points ``student``'s hidden-check cells hold in the gradebook (extra
    credit included), for the questions of the course's notebooks."""
    out = {}
    for grade_id, (score, _) in autograded_scores(course, student).items():
        q = _question_of_grade_id(grade_id)
        if q is not None:
            out[q.id] = score
    return out


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


def _grading_config(args):
    from .config import ENV_CONFIG, ENV_SECRET, load_config

    config = load_config(args.config)
    if config.is_dev and not args.allow_dev_secret:
        raise ValueError(f"secret: expected the course's own grading secret (set {ENV_SECRET}, or {ENV_CONFIG} "
                         f"or --config to a config file), got the public development secret")
    return config


def _cli(args) -> int:
    course = build_course(args.out, stems=args.notebooks, force=args.force)
    print(f"wrote the nbgrader course {course}")
    if args.selftest:
        score, total = selftest(course, config=_grading_config(args))
        print(f"self-test: the answer key scores {score:g} / {total:g} on the hidden checks (extra credit included)")
        return 0 if abs(score - total) < 1e-9 else 1
    print(f"next: cd {course} && nbgrader generate_assignment {ASSIGNMENT} --force  (see README.md)")
    return 0


def _grade_cli(args) -> int:
    config = _grading_config(args)

    def report(student, result):
        why = f" (not graded: {result.failure})" if result.failure else ""
        print(for_terminal(f"{student}: {result.score:g} points (base {result.max_score:g}, extra credit on top){why}"))

    results = grade_course(args.course, assignment=args.assignment, students=args.student, config=config,
                           isolation=args.isolation, progress=None if args.quiet else report)
    print(f"{len(results)} submissions scored into {Path(args.course) / 'gradebook.db'}; "
          f"next: nbgrader generate_feedback {args.assignment} && nbgrader export")
    return 0


def add_grade_cli(subparsers) -> None:
    """Register ``python -m autograder nbgrader-grade`` (once, whoever asks first)."""
    if "nbgrader-grade" in subparsers.choices:
        return
    p = subparsers.add_parser(
        "nbgrader-grade", help="score an nbgrader course's submissions with the kit's grader (after nbgrader autograde)",
        description="Grade every submitted/<student>/<assignment> of an nbgrader course with the kit's sandboxed "
                    "grader and write the hidden checks' points into its gradebook (run after nbgrader autograde, "
                    "before generate_feedback and export).")
    p.add_argument("course", help="the course folder (with nbgrader_config.py and gradebook.db)")
    p.add_argument("--assignment", default=ASSIGNMENT, help=f"the assignment (default {ASSIGNMENT})")
    p.add_argument("--student", nargs="+", default=None, metavar="NAME", help="only these students")
    p.add_argument("--config", default=None, help="grader settings (JSON; default: $HW4_GRADER_CONFIG)")
    p.add_argument("--allow-dev-secret", action="store_true", help="grade with the public development secret (trying out only)")
    p.add_argument("--isolation", default="auto", choices=["auto", "namespaces", "user-namespaces", "basic"],
                   help="sandbox level (default: the strongest that works here)")
    p.add_argument("--quiet", action="store_true", help="no line per student")
    p.set_defaults(func=_grade_cli)


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
