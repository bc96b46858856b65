"""An nbgrader course for the homework, graded by the kit's own autograder.

``python -m autograder nbgrader --out COURSE_DIR`` writes a course directory for nbgrader 0.9:

=============================  ================================================================
``nbgrader_config.py``         course id, gradebook, execution timeout, and ``KitScores`` (below)
                               right after nbgrader's Execute step of ``autograde``
``source/hw4/<stem>.ipynb``    ``notebooks/nbgrader/source/hw4`` with, under every autograded
                               question, one hidden-check cell worth the manifest's points; the
                               public self-check cells become read-only (students keep them,
                               they no longer carry points, so a question is never counted twice)
``starter/ scenes/ data/``     what the notebooks import and load: their setup cell finds the kit
                               in a parent folder of the notebook
``autograder/ solutions/``     the grader (what ``python -m autograder gradescope`` ships too)
``kit/``
``grader_config.json``         the instructor's grading settings at build time: the secret every
                               hidden seed derives from (mode 600)
=============================  ================================================================

Then, in that folder, the usual nbgrader steps: ``nbgrader generate_assignment hw4``, collect the
submissions into ``submitted/<student>/hw4/``, ``nbgrader autograde hw4``, ``nbgrader
generate_feedback hw4``, ``nbgrader export``.  ``--selftest`` runs them with the answer key as a
student and reports its score.

How a hidden-check cell is scored
---------------------------------
The cell holds no inputs and no expected answers: between nbgrader's ``BEGIN/END HIDDEN TESTS``
markers it only calls :func:`hidden_score` with the question id.  During ``nbgrader autograde``
the points come from :class:`KitScores`, a preprocessor that runs in nbgrader's own process after
the notebook has been executed: it grades the student's submitted notebooks with
``grade_submission`` (the same code as ``python -m autograder grade`` and Gradescope; student
code runs in the sandbox, with the course folder hidden from it) and replaces the cell's outputs
with that question's feedback and its points (nbgrader's partial credit: a number as the cell's
result).  What the student's code did inside the kernel, which it shares with nbgrader's tests,
cannot change those points.  Run outside ``autograde`` (by hand, ``nbgrader validate``), the cell
grades the notebooks of its own folder in the kernel and shows the points.

What nbgrader itself cannot protect (why the kit has its own grader): nbgrader runs student code
with the instructor's rights in the kernel that also runs the tests, so that code can patch
the tests' tools (``numpy.allclose``), read ``source/`` (the hidden tests), the configuration and
``gradebook.db``, write files, and leave processes running.  Here the hidden tests say nothing a
student could use, the scores do not come from the kernel, and student code that grading runs is
sandboxed; but student code still runs unsandboxed in nbgrader's kernel, so grade untrusted
submissions on a machine (or container) that holds nothing else of value.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from core.manifest import NOTEBOOKS, QUESTIONS, Question, question

from .gradescope import CONFIG_NAME, KIT_ROOT, config_file, data_files, grader_files, hideable

if TYPE_CHECKING:
    import nbformat

__all__ = [
    "ASSIGNMENT",
    "COURSE_ID",
    "HIDDEN_PREFIX",
    "KitScores",
    "QuestionScore",
    "add_cli",
    "add_hidden_checks",
    "autograded_scores",
    "build_course",
    "hidden_score",
    "run_nbgrader",
    "score_questions",
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

    credit = ", extra credit" if q.extra_credit else ""
    text = "\n".join([
        f"# {q.id}: hidden checks [{q.points} points{credit}].  The course's autograder runs your",
        "# functions on inputs you have not seen; this cell shows its points once your notebook is graded.",
        _BEGIN_HIDDEN,
        "from autograder.nbgrader_course import hidden_score",
        "",
        f'hidden_score("{q.id}")',
        _END_HIDDEN,
    ])
    cell = nbformat.v4.new_code_cell(text)
    cell.metadata = {"nbgrader": {"grade": True, "grade_id": _grade_id_of(q.id), "locked": True,
                                  "points": q.points, "schema_version": 3, "solution": False, "task": False}}
    cell["id"] = f"{stem}-{_grade_id_of(q.id)}".replace("_", "-")[:64]
    return cell


def add_hidden_checks(nb: nbformat.NotebookNode, stem: str) -> nbformat.NotebookNode:
    """The nbgrader source notebook ``nb`` of ``stem`` with the kit's hidden checks (a new notebook).

    Every autograded question of ``stem`` gets one hidden-check cell worth the manifest's points,
    after the last cell of that question's functions (solution or public check).  The public
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
# scoring with the kit's grader


@dataclass(frozen=True)
class QuestionScore:
    """The kit grader's verdict on one question: points, out of, and feedback for the student."""

    qid: str
    score: float
    max_score: float
    feedback: str


def _fingerprint(folder: Path) -> tuple:
    return tuple(sorted((p.relative_to(folder).as_posix(), p.stat().st_size, p.stat().st_mtime_ns)
                        for p in folder.rglob("*") if p.is_file()))


_CACHE: dict[tuple, dict[str, QuestionScore]] = {}


def _describe(q) -> str:
    lines = [f"{q.id} {q.title}: {q.score:g} / {q.max_score:g} points"]
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


def score_questions(folder: str | Path, qids, *, course_root: str | Path | None = None) -> dict[str, QuestionScore]:
    """Grade the notebooks in ``folder`` with the kit's grader; the verdicts on ``qids``.

    The whole folder is graded once (cached while its files do not change), because a notebook
    may use functions of another one.  Student code runs in the sandbox; ``course_root`` (default:
    the kit this module belongs to) is hidden from it.

    Raises
    ------
    ValueError
        For an unknown or by-hand question id.
    """
    wanted = []
    for qid in qids:
        q = question(qid)
        if q.by_hand:
            raise ValueError(f"qids: expected autograded questions, got {qid} (graded by hand)")
        wanted.append(q)
    folder = Path(folder).resolve()
    root = Path(course_root).resolve() if course_root is not None else KIT_ROOT
    key = (str(folder), str(root), _fingerprint(folder) if folder.is_dir() else ())
    if key not in _CACHE:
        _CACHE[key] = _grade_folder(folder, root)
    return {q.id: _CACHE[key][q.id] for q in wanted}


def _grade_folder(folder: Path, root: Path) -> dict[str, QuestionScore]:
    from .config import load_config
    from .grade import grade_submission
    from .sandbox import Sandbox
    from .hidden.inputs import build_hidden_inputs

    bundled = root / CONFIG_NAME
    # In a course folder only its own settings count; in the kit, the instructor's environment.
    config = load_config(bundled, environ={}) if bundled.is_file() else load_config()
    # All of the course: gradebook, settings, source/ and every student's submission.
    with Sandbox(root, hidden=hideable([root, folder, config.source, config.official_dir()])) as box:
        result = grade_submission(folder, sandbox=box, hidden_inputs=build_hidden_inputs(config))
    by_id = {q.id: q for q in result.questions}
    out = {}
    for q in QUESTIONS:
        if q.by_hand:
            continue
        if result.failure or q.id not in by_id:
            why = result.failure or "not graded"
            out[q.id] = QuestionScore(q.id, 0.0, float(q.points), f"{q.id} {q.title}: 0 / {q.points} points ({why})")
        else:
            qr = by_id[q.id]
            out[q.id] = QuestionScore(q.id, float(qr.score), float(qr.max_score), _describe(qr))
    return out


def hidden_score(qid: str) -> float:
    """The points of question ``qid``, for the last line of a hidden-check cell (in the kernel).

    During ``nbgrader autograde`` this returns 0 at once: :class:`KitScores` then writes the
    real points, computed outside the kernel.  Otherwise it grades the notebooks of the current
    folder as saved on disk, prints the feedback and returns the points.
    """
    q = question(qid)
    if os.environ.get("NBGRADER_EXECUTION") == "autograde":
        print(f"{q.id}: scored outside this notebook by the course's autograder.")
        return 0.0
    verdict = score_questions(Path.cwd(), [q.id])[q.id]
    print(verdict.feedback)
    return verdict.score


def _fill_hidden_cells(nb, resources, config, log):
    """What KitScores does (see there); ``config`` is nbgrader's, ``log`` a logging.Logger."""
    import nbformat
    from nbgrader.coursedir import CourseDirectory

    info = resources.get("nbgrader", {})
    coursedir = CourseDirectory(config=config)
    folder = Path(coursedir.format_path(coursedir.submitted_directory, info["student"], info["assignment"]))
    cells = [(cell, _question_of_grade_id(_nbgrader(cell).get("grade_id", ""))) for cell in nb.cells]
    cells = [(cell, q) for cell, q in cells if q is not None and cell.cell_type == "code"]
    if not cells:
        return nb, resources
    try:
        verdicts = score_questions(folder, [q.id for _, q in cells], course_root=coursedir.root)
    except Exception as exc:  # noqa: BLE001 - a grader failure must cost points visibly, not stop the batch
        log.exception("KitScores could not grade %s", folder)
        for cell, _ in cells:
            # An error output: nbgrader gives the cell zero, and the staff see why.
            cell.outputs = [nbformat.v4.new_output(
                "error", ename="GradingError", evalue=f"the course's autograder could not run ({type(exc).__name__})",
                traceback=[])]
        return nb, resources
    for cell, q in cells:
        v = verdicts[q.id]
        points = min(max(v.score, 0.0), float(_nbgrader(cell).get("points", v.max_score)))
        cell.outputs = [
            nbformat.v4.new_output("stream", name="stdout", text=v.feedback + "\n"),
            nbformat.v4.new_output("execute_result", data={"text/plain": repr(points)},
                                   execution_count=cell.get("execution_count")),
        ]
    log.info("KitScores: %s", ", ".join(f"{q.id} {verdicts[q.id].score:g}" for _, q in cells))
    return nb, resources


def _make_kit_scores():
    from nbconvert.preprocessors import Preprocessor
    from traitlets import Bool

    class KitScores(Preprocessor):
        """nbgrader autograde step: the kit grader's points into the hidden-check cells.

        Placed right after nbgrader's ``Execute`` (see the course's nbgrader_config.py).  It
        grades the student's folder ``submitted/<student>/<assignment>`` and gives every cell
        whose ``grade_id`` is ``hidden_<question>`` a stdout stream with the feedback and an
        execute_result with the points, replacing whatever the kernel produced there.
        """

        enabled = Bool(True).tag(config=True)

        def preprocess(self, nb, resources):
            return _fill_hidden_cells(nb, resources, self.config, self.log)

    KitScores.__module__ = __name__
    return KitScores


def __getattr__(name: str):
    # KitScores subclasses nbconvert's Preprocessor; made on first use so that importing this
    # module (every `python -m autograder` command does) does not load nbconvert.
    if name == "KitScores":
        cls = globals()["KitScores"] = _make_kit_scores()
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ------------------------------------------------------------------------------------------------
# the course directory

_CONFIG = '''\
# nbgrader configuration of the hw4 course, written by `python -m autograder nbgrader`.
import sys
from pathlib import Path

_course = Path(__file__).resolve().parent
if str(_course) not in sys.path:
    sys.path.insert(0, str(_course))  # the course's copy of the kit, for KitScores

from nbgrader.converters import Autograde
from nbgrader.preprocessors import Execute

c = get_config()  # noqa: F821 - traitlets defines it when it runs this file
c.CourseDirectory.course_id = "{course_id}"
c.CourseDirectory.root = str(_course)
c.CourseDirectory.db_url = "sqlite:///" + str(_course / "gradebook.db")
c.Execute.timeout = {timeout}

# Right after the student's notebook has run, KitScores replaces the outputs of the hidden-check
# cells with the points of the kit's grader (computed here, outside the student's kernel).
_steps = list(Autograde.class_traits()["autograde_preprocessors"].default())
_steps.insert(_steps.index(Execute) + 1, "autograder.nbgrader_course.KitScores")
c.Autograde.autograde_preprocessors = _steps
'''

_README = '''\
# hw4 nbgrader course

Written by `python -m autograder nbgrader`.  Run every command in this folder.

    nbgrader generate_assignment {assignment} --force    # release/{assignment}/: what students get
    # put each submission in submitted/<student>/{assignment}/ (with a timestamp.txt)
    nbgrader autograde {assignment}                      # autograded/...; hidden checks by the kit's grader
    nbgrader generate_feedback {assignment}              # feedback/<student>/{assignment}/*.html
    nbgrader export                            # grades.csv

The hidden-check cells carry the points of the autograded questions; the public self-check
cells are read-only and carry none.  Questions answered in writing are graded by hand
(`nbgrader formgrader`).  Q6 is extra credit in the handout; nbgrader has no extra-credit cells,
so its points count in nbgrader's total.

Student code runs unsandboxed in nbgrader's kernel: grade untrusted submissions on a machine
that holds nothing else of value.
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


def build_course(out: str | Path, *, kit_root: str | Path = KIT_ROOT, stems=None, force: bool = False,
                 allow_dev_secret: bool = False) -> Path:
    """Write the nbgrader course directory ``out`` (layout in the module docstring); return it.

    Parameters
    ----------
    out : the folder to write; it must not exist or be empty, unless ``force`` and it is a course
        folder written before (it holds nbgrader_config.py).
    kit_root : the kit whose notebooks and grader are used (default: this one).
    stems : the manifest notebooks to include (default: all of them, in manifest order).
    force : replace what ``out`` holds (the gradebook and submissions included).
    allow_dev_secret : build with the public development secret (for trying the course out only).

    Raises
    ------
    ValueError
        For an unknown stem, an ``out`` that holds files while ``force`` is False, or the
        development secret without ``allow_dev_secret`` (see ``autograder.gradescope.config_file``).
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
        settings = config_file(Path(tmp), allow_dev_secret=allow_dev_secret)
        for name, path in grader_files(root) + data_files(root, Path(tmp)) + settings:
            dest = out / name
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, dest)
    # The secret of the hidden inputs is for the staff's eyes only.
    os.chmod(out / CONFIG_NAME, 0o600)
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
                          stderr=subprocess.STDOUT, text=True, timeout=timeout, check=False)
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
    """``grade_id -> (auto_score, max_score)`` of the autograded code cells of ``student``'s hw4."""
    from nbgrader.api import Gradebook

    course = Path(course)
    out = {}
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}", COURSE_ID) as gb:
        submission = gb.find_submission(ASSIGNMENT, student)
        for notebook in submission.notebooks:
            for grade in notebook.grades:
                if grade.cell_type == "code":
                    out[grade.name] = (float(grade.auto_score or 0.0), float(grade.max_score))
    return out


def selftest(course: str | Path, student: str = "answer-key") -> tuple[float, float]:
    """Run the whole nbgrader workflow in ``course`` with the answer key as ``student``.

    generate_assignment, the key's submission, autograde, generate_feedback and export; returns
    the key's (points, out of) over the hidden-check cells.
    """
    course = Path(course)
    run_nbgrader(course, "generate_assignment", ASSIGNMENT, "--force")
    submit_key(course, student)
    run_nbgrader(course, "autograde", ASSIGNMENT, "--force", f"--student={student}")
    run_nbgrader(course, "generate_feedback", ASSIGNMENT, "--force", f"--student={student}")
    run_nbgrader(course, "export")
    hidden = {k: v for k, v in autograded_scores(course, student).items() if k.startswith(HIDDEN_PREFIX)}
    return sum(s for s, _ in hidden.values()), sum(m for _, m in hidden.values())


def _cli(args) -> int:
    course = build_course(args.out, stems=args.notebooks, force=args.force, allow_dev_secret=args.allow_dev_secret)
    print(f"wrote the nbgrader course {course}")
    if args.selftest:
        score, total = selftest(course)
        print(f"self-test: the answer key scores {score:g} / {total:g} on the hidden checks")
        return 0 if abs(score - total) < 1e-9 else 1
    print(f"next: cd {course} && nbgrader generate_assignment {ASSIGNMENT} --force  (see README.md)")
    return 0


def add_cli(subparsers) -> None:
    """Register ``python -m autograder nbgrader``."""
    p = subparsers.add_parser(
        "nbgrader", help="write an nbgrader course directory graded by the kit's autograder",
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="the course folder to write")
    p.add_argument("--notebooks", nargs="+", default=None, metavar="STEM",
                   help=f"only these notebooks (default: all of {', '.join(NOTEBOOKS)})")
    p.add_argument("--force", action="store_true", help="replace what the folder holds (gradebook included)")
    p.add_argument("--allow-dev-secret", action="store_true",
                   help="build even without the course's grading secret (HW4_GRADER_SECRET / HW4_GRADER_CONFIG)")
    p.add_argument("--selftest", action="store_true",
                   help="then run nbgrader end to end with the answer key as a student (needs nbgrader)")
    p.set_defaults(func=_cli)
