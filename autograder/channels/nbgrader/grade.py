"""Grading in an nbgrader course: after ``nbgrader autograde``, the kit grades each submitted
folder and writes the points into nbgrader's gradebook.

``python -m autograder nbgrader-grade COURSE`` (:func:`grade_course`): one
``autograder.grading.run.GradingRun`` (the course folder hidden from student code, the canary first)
grades every ``submitted/<student>/<assignment>``; nbgrader is used only to write what the run
found into ``gradebook.db`` (``nbgrader.api.Gradebook``) and the feedback into the autograded
notebooks: each hidden-check cell's output is its question's verdict, then (unless ``pictures`` is
off) the unscored figure of what the student's functions returned on the public data
(``autograder.channels.nbgrader.pictures``), so that ``generate_feedback`` shows both.  Building the course
is ``autograder.channels.nbgrader.course``'s job.
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

from core.manifest import QUESTIONS, Question
from core.untrusted import for_terminal

from autograder.feedback.causes import said_once

__all__ = ["ASSIGNMENT", "COURSE_ID", "HIDDEN_PREFIX", "add_grade_cli", "autograded_scores", "grade_course",
           "gradebook", "kit_scores", "tools_path"]

ASSIGNMENT = "hw4"
COURSE_ID = "hw4"
HIDDEN_PREFIX = "hidden_"


# ------------------------------------------------------------------------------------------------
# the hidden-check cells


def nbgrader_metadata(cell) -> dict:
    return cell.get("metadata", {}).get("nbgrader", {})


def question_of_grade_id(grade_id: str) -> Question | None:
    if not grade_id.startswith(HIDDEN_PREFIX):
        return None
    wanted = grade_id[len(HIDDEN_PREFIX):]
    return next((q for q in QUESTIONS if q.id.replace(".", "_") == wanted and not q.by_hand), None)


# ------------------------------------------------------------------------------------------------
# grading


def question_feedback(q) -> str:
    credit = " (extra credit)" if q.extra_credit else ""
    lines = [f"{q.id} {q.title}: {q.score:g} / {q.max_score:g} points{credit}"]
    lines += [f"- {n}" for n in q.notes]
    hidden = [t for t in q.tests if t.visibility == "hidden"]
    said: dict = {}   # one likely mistake per cause: its hint in the first check naming it
    for t in q.tests:
        if t.visibility != "hidden":
            verdict = "passed" if t.passed else "failed"
            feedback = said_once(t.feedback, q.id, said)
            lines.append(f"- {t.name}: {verdict} ({t.score:g} / {t.max_score:g})"
                         + (f". {feedback}" if feedback else ""))
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
            out[q.id] = (float(by_id[q.id].score), question_feedback(by_id[q.id]))
    return out


def _students(course: Path, assignment: str, students) -> list[str]:
    found = sorted(p.parent.name for p in (course / "submitted").glob(f"*/{assignment}") if p.is_dir())
    if students is None:
        return found
    missing = [s for s in students if s not in found]
    if missing:
        raise ValueError(f"students: expected names with a folder submitted/<name>/{assignment}, got {missing}")
    return list(students)


def _write_feedback(course: Path, assignment: str, student: str, verdicts: dict, figures=None) -> None:
    """The kit's feedback as the outputs of each hidden-check cell of the autograded notebooks: the
    question's verdict, then its entry of ``figures`` (question -> ``Picture`` or "figure not
    drawn: ...", ``autograder.feedback.pictures.figures_of``) when it has one."""
    import nbformat

    from .pictures import cell_outputs

    figures = figures or {}

    for path in sorted((course / "autograded" / student / assignment).glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        changed = False
        for cell in nb.cells:
            q = question_of_grade_id(nbgrader_metadata(cell).get("grade_id", ""))
            if q is not None and cell.cell_type == "code":
                cell.outputs = cell_outputs(verdicts[q.id][1], figures.get(q.id))
                changed = True
        if changed:
            nbformat.write(nb, path)


def grade_course(course: str | Path, *, assignment: str = ASSIGNMENT, students=None, config=None,
                 isolation: str = "auto", pictures: bool = True, progress=None, log=print) -> dict:
    """Grade every submission of ``assignment`` with the kit's grader and write the points into
    the course's gradebook; run after ``nbgrader autograde``.  Returns student -> SubmissionResult.

    Each ``submitted/<student>/<assignment>`` folder is graded by one ``autograder.grading.run.GradingRun`` (the
    instructor's kit, never the course's files; student code in the sandbox with the course
    folder hidden).  Then, through ``nbgrader.api.Gradebook``, every hidden-check cell's ``Grade``
    gets the question's points as ``auto_score`` (extra credit: ``auto_score`` 0 and the points as
    ``extra_credit``), replacing whatever autograde recorded, and the question's feedback becomes
    that cell's output in ``autograded/`` (what ``generate_feedback`` shows), followed by the
    question's picture of the public data when ``pictures``.

    First the canary (``autograder.grading.canary.check``): the answer key, graded in the very sandbox and
    with the same hidden inputs, must get every point, or no student is graded.

    Parameters
    ----------
    course : the nbgrader course folder (with nbgrader_config.py and gradebook.db).
    students : names to grade (default: every submitted folder of ``assignment``).
    config : ``GradingConfig`` (default: ``load_config()``, as ``python -m autograder grade``).
    isolation : the sandbox level ("auto": the strongest that works here).
    pictures : run the unscored picture step after each submission's checks and show each
        question's figure (or why there is none) under its verdict; False: text feedback only, a
        few seconds less per submission, the same scores.
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

    from autograder.inputs.config import load_config
    from autograder.feedback.pictures import figures_of
    from autograder.grading.run import GradingRun

    course = Path(course).resolve()
    db = course / "gradebook.db"
    if not (course / "nbgrader_config.py").is_file() or not db.is_file():
        raise ValueError(f"course: expected an nbgrader course with gradebook.db (run nbgrader autograde first), got {course}")
    names = _students(course, assignment, students)
    config = config if config is not None else load_config()
    results = {}
    with gradebook(db) as gb:
        for student in names:
            try:
                gb.find_submission(assignment, student)
            except MissingEntry:
                raise ValueError(f"students: {student} has no autograded submission of {assignment} in "
                                 f"the gradebook; run nbgrader autograde first") from None
    with GradingRun(config, hide=[course], isolation=isolation, pictures=pictures) as run:
        report = run.open().canary_report  # raises CanaryFailed: nothing graded, nothing written
        if log is not None:
            log(f"canary: the answer key got {report.score:g} / {report.max_score:g} in this sandbox "
                f"({run.sandboxes()[0].isolation.summary()}) in {report.seconds:.1f} s; grading {len(names)} submissions")
        for student in names:
            folder = course / "submitted" / student / assignment
            result = run.grade(folder, student_id=student)
            results[student] = result
            verdicts = _verdicts(result)
            with gradebook(db) as gb:
                submission = gb.find_submission(assignment, student)
                for notebook in submission.notebooks:
                    for grade in notebook.grades:
                        q = question_of_grade_id(grade.name)
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
            # Checked (and drawn if need be) here; a failed grading has no pictures to show.
            figures = {} if result.failure else figures_of(result.pictures)
            _write_feedback(course, assignment, student, verdicts, figures)
            if progress is not None:
                progress(student, result)
    return results


# ------------------------------------------------------------------------------------------------
# nbgrader's gradebook


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
        q = question_of_grade_id(grade_id)
        if q is not None:
            out[q.id] = score
    return out


# ------------------------------------------------------------------------------------------------
# command line


def grading_config_of(args):
    from autograder.inputs.config import ENV_CONFIG, ENV_SECRET, load_config

    config = load_config(args.config)
    if config.is_dev and not args.allow_dev_secret:
        raise ValueError(f"secret: expected the course's own grading secret (set {ENV_SECRET}, or {ENV_CONFIG} "
                         f"or --config to a config file), got the public development secret")
    return config


def grade_cli(args) -> int:
    config = grading_config_of(args)

    def report(student, result):
        why = f" (not graded: {result.failure})" if result.failure else ""
        print(for_terminal(f"{student}: {result.score:g} points (base {result.max_score:g}, extra credit on top){why}"))

    results = grade_course(args.course, assignment=args.assignment, students=args.student, config=config,
                           isolation=args.isolation, pictures=not args.no_pictures,
                           progress=None if args.quiet else report)
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
    # Worded as the grade command's (a test compares them): one option should read the same in both commands.
    p.add_argument("--no-pictures", action="store_true",
                   help="feedback without the figures of each student's results on the public data "
                        "(they cost a few seconds per submission; scores do not change)")
    p.set_defaults(func=grade_cli)
