"""Grading: one submission in a sandbox, a batch of them in parallel, and the answer-key submission.

One submission is one sandbox job: the student's notebooks are loaded once (imports take seconds)
and every hidden test is a call of that job; a call that hangs or crashes costs only its own
function's questions, because the child restarts for the rest.  The job's code is every kept
statement of every notebook (``Submission.units``: definitions, not the notebooks' self-check and
figure cells; a function taken from its own notebook when it is defined there and borrowed from
another one otherwise), then the grader's helpers.

A batch writes, per submission, ``<out>/<name>/results.json`` (Gradescope's schema),
``feedback.md`` (what the student reads) and ``grading.json`` (for staff: scores, digests,
what the code printed, grader notes), then ``<out>/grades.csv`` with every submission graded
into ``<out>`` so far (this batch's first).  A submission whose results
exist for the same file content and the same grader settings is not graded again.  Nothing a
submission does can stop the batch: the catastrophic path writes a failed result and goes on.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import shutil
import sys
import threading
import time
import traceback
import zipfile
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

from core.manifest import NOTEBOOKS
from core.text import points, write_atomic

from .config import GRADER_VERSION, GradingConfig, load_config
from .results import SubmissionResult, autograded_question_ids, csv_header
from .sandbox import Job, ResourceLimits, Sandbox
from .submission import SourceUnit, Submission, SubmissionError, load_submission
from .tests import HELPER_UNIT, HiddenInputs, all_calls, build_hidden_inputs, judge_all

__all__ = [
    "KIT_ROOT",
    "BatchRecord",
    "grade_batch",
    "grade_submission",
    "job_units",
    "open_sandbox",
    "submission_digest",
    "submission_name",
    "write_key_submission",
]

KIT_ROOT = Path(__file__).resolve().parents[1]
_RESTARTS_BUDGETED = 3      # crashes or timeouts after which the job's time is still enough
_OUTPUT_KEPT = 8000         # characters of the student's stdout/stderr kept for staff


# ------------------------------------------------------------------------------- one submission


def job_units(sub: Submission) -> list[SourceUnit]:
    """The units of the single grading job: the submission's code (``Submission.units``), then the grader's helpers."""
    return list(sub.units()) + [HELPER_UNIT]


def _load_notes(job_result) -> list[str]:
    # Most failures while loading are notebook statements that need files (load_temple(), a
    # sibling notebook) and do not matter here; a failed import does, as it breaks what uses it.
    notes = []
    for origin, message in job_result.load_errors:
        if re.match(r"(ModuleNotFoundError|ImportError)\b", message):
            notes.append(f"{origin}: {message.split(' (in ', 1)[0]}; code that needs it will fail.")
    return list(dict.fromkeys(notes))[:10]


def grade_submission(path: str | os.PathLike, *, sandbox: Sandbox, hidden_inputs: HiddenInputs,
                     student_id: str | None = None, staff: dict | None = None) -> SubmissionResult:
    """Grade the submission at ``path`` (a folder or .zip of notebooks or .py files).

    Parameters
    ----------
    path : the submission.
    sandbox : a Sandbox to run the student's code in (one job at a time; reusable).
    hidden_inputs : from ``autograder.tests.build_hidden_inputs(config)``.
    student_id : the name for the gradebook (default: the file or folder name).
    staff : optional dict that receives what only staff should see: ``stdout``, ``stderr``,
        ``log`` (grader notes and tracebacks), ``spawns`` and ``swept`` (child processes started,
        processes killed after the job).

    Returns
    -------
    SubmissionResult: one QuestionResult per autograded question, or a failed result (worth
    zero, saying why) when the submission cannot be read.  Never raises for anything the
    submission contains or does.
    """
    start = time.monotonic()
    staff = staff if staff is not None else {}
    staff.setdefault("log", [])
    student_id = student_id or submission_name(Path(path))
    isolation = sandbox.isolation.as_dict()
    try:
        sub = load_submission(path)
    except SubmissionError as exc:
        return SubmissionResult.failed(str(exc), student_id=student_id, isolation=isolation,
                                       execution_time=time.monotonic() - start)
    if not sub.notebooks:
        return SubmissionResult.failed(
            "no notebook of the homework was found (expected files such as q2_eightpoint.ipynb)",
            student_id=student_id, isolation=isolation, execution_time=time.monotonic() - start)
    calls = all_calls(hidden_inputs)
    config = hidden_inputs.config
    budget = sum(c.timeout for c in calls) + config.load_timeout * (1 + _RESTARTS_BUDGETED) + 30
    job = Job(job_units(sub), calls, load_timeout=config.load_timeout, job_timeout=budget)
    result = sandbox.run(job)
    staff.update(stdout=result.stdout[:_OUTPUT_KEPT], stderr=result.stderr[:_OUTPUT_KEPT],
                 spawns=result.spawns, swept=result.swept)
    questions = judge_all(hidden_inputs, result.outcomes, staff["log"])
    notes = [str(n) for n in sub.notes()] + _load_notes(result)
    return SubmissionResult(tuple(questions), student_id, isolation, tuple(notes), None,
                            time.monotonic() - start)


# ------------------------------------------------------------------------------- batches


def submission_name(path: Path) -> str:
    """The gradebook name of a submission: its file name without .zip, made safe for a folder."""
    name = path.name[:-4] if path.name.lower().endswith(".zip") else path.name
    return re.sub(r"[^A-Za-z0-9_.@+-]", "_", name).strip(".") or "submission"


def submission_digest(path: Path) -> str:
    """SHA-256 of a submission's content (a file's bytes, or a folder's relative paths and bytes)."""
    h = hashlib.sha256()
    path = Path(path)
    if path.is_dir():
        for p in sorted(path.rglob("*")):
            if p.is_file() and not p.is_symlink():
                h.update(p.relative_to(path).as_posix().encode() + b"\0")
                h.update(hashlib.sha256(p.read_bytes()).digest())
    elif path.is_file():
        with open(path, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
    else:
        h.update(b"missing")
    return h.hexdigest()


@dataclass(frozen=True)
class BatchRecord:
    """One submission of a batch: where its results are, its scores, and whether it was graded now."""

    name: str
    path: Path
    folder: Path
    score: float
    scores: dict
    failure: str | None
    skipped: bool
    seconds: float


def _unique_names(paths: Sequence[Path]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for p in paths:
        base = submission_name(p)
        k = seen.get(base, 0)
        seen[base] = k + 1
        out.append(base if k == 0 else f"{base}-{k + 1}")
    return out


def _state_path(folder: Path) -> Path:
    return folder / "grading.json"


def _resumable(folder: Path, digest: str, fingerprint: str) -> dict | None:
    try:
        state = json.loads(_state_path(folder).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not (folder / "results.json").is_file():
        return None
    if state.get("sha256") != digest or state.get("fingerprint") != fingerprint:
        return None
    return state


def _write_outputs(folder: Path, result: SubmissionResult, state: dict) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    result.write_gradescope(folder / "results.json")
    write_atomic(folder / "feedback.md", result.feedback_markdown())
    # grading.json last: its presence with a matching digest is what marks the work as done.
    write_atomic(_state_path(folder), json.dumps(state, indent=2, allow_nan=False, default=str))


def _state(result: SubmissionResult, path: Path, digest: str, fingerprint: str, staff: dict) -> dict:
    return {
        "student_id": result.student_id, "path": str(path), "sha256": digest, "fingerprint": fingerprint,
        "grader_version": GRADER_VERSION, "score": result.score, "max_score": result.max_score,
        "scores": {q.id: q.score for q in result.questions}, "failure": result.failure,
        "seconds": result.execution_time, "isolation": result.isolation, "staff": staff,
    }


def _hidden_for_sandbox(paths: Sequence[Path], out: Path, config: GradingConfig) -> list[Path]:
    """Folders the student's code must not see: outputs, config, and where the submissions live."""
    hidden = [out]
    if config.source is not None:
        hidden.append(config.source)
    if config.official_dir() is not None:
        hidden.append(config.official_dir())
    python_dirs = {Path(sys.prefix).resolve(), Path(sys.base_prefix).resolve()}
    for p in paths:
        parent = Path(p).resolve().parent
        # Never the root, nor a folder holding the Python installation the sandbox runs.
        if parent != Path("/") and not any(parent == d or parent in d.parents for d in python_dirs):
            hidden.append(parent)
    return list(dict.fromkeys(hidden))


def open_sandbox(*, hidden: Sequence[Path] = (), isolation: str = "auto", limits: ResourceLimits | None = None,
                 attempts: int = 3) -> Sandbox:
    """A Sandbox for grading; with "auto" as root, retried when it comes up weaker than namespaces.

    As root the namespaces level normally works, so a weaker one means its probe failed for a
    passing reason (a loaded machine, a uid clash with another grader); a weaker sandbox is
    accepted after ``attempts`` tries, with a warning on stderr.
    """
    options = {"limits": limits} if limits is not None else {}
    for attempt in range(attempts):
        box = Sandbox(KIT_ROOT, hidden=hidden, isolation=isolation, **options)
        if isolation != "auto" or os.geteuid() != 0 or box.isolation.level == "namespaces":
            return box
        if attempt == attempts - 1:
            print(f"warning: the sandbox runs at the {box.isolation.level} level ({'; '.join(box.isolation.notes)})",
                  file=sys.stderr)
            return box
        box.close()
        time.sleep(1.0 + attempt)
    raise AssertionError("unreachable")


def grade_batch(paths: Sequence[str | os.PathLike], out: str | os.PathLike, *, jobs: int = 1,
                config: GradingConfig | None = None, resume: bool = True, progress: bool = True,
                isolation: str = "auto", limits: ResourceLimits | None = None,
                on_done: Callable[[BatchRecord], None] | None = None) -> list[BatchRecord]:
    """Grade ``paths`` into ``out`` with ``jobs`` workers (threads, each with its own Sandbox).

    Returns one BatchRecord per path, in the order given, and writes ``out/grades.csv``.
    Submissions already graded with the same content and settings are skipped when ``resume``.
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs: expected a positive integer, got {jobs!r}")
    config = config or load_config()
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    paths = [Path(p) for p in paths]
    missing = [str(p) for p in paths if not p.exists()]
    if missing:
        raise FileNotFoundError(f"paths: expected existing submissions, got missing {missing}")
    names = _unique_names(paths)
    fingerprint = config.fingerprint()
    hidden_inputs = build_hidden_inputs(config)
    sandbox_hidden = _hidden_for_sandbox(paths, out, config)

    local = threading.local()
    boxes: list[Sandbox] = []
    boxes_lock = threading.Lock()

    def sandbox() -> Sandbox:
        if getattr(local, "box", None) is None:
            box = open_sandbox(hidden=sandbox_hidden, isolation=isolation, limits=limits)
            with boxes_lock:
                boxes.append(box)
            local.box = box
        return local.box

    def work(path: Path, name: str) -> BatchRecord:
        folder = out / name
        start = time.monotonic()
        digest = submission_digest(path)
        if resume:
            state = _resumable(folder, digest, fingerprint)
            if state is not None:
                return BatchRecord(name, path, folder, float(state.get("score", 0.0)), dict(state.get("scores", {})),
                                   state.get("failure"), True, 0.0)
        staff: dict = {"log": []}
        try:
            result = grade_submission(path, sandbox=sandbox(), hidden_inputs=hidden_inputs, student_id=name,
                                      staff=staff)
        except Exception as exc:  # noqa: BLE001 - the catastrophic path: a failed result, never a stop
            staff["log"].append(traceback.format_exc())
            result = SubmissionResult.failed(
                f"the autograder hit an internal error ({type(exc).__name__}) while grading it",
                student_id=name, execution_time=time.monotonic() - start)
        _write_outputs(folder, result, _state(result, path, digest, fingerprint, staff))
        return BatchRecord(name, path, folder, result.score, {q.id: q.score for q in result.questions},
                           result.failure, False, time.monotonic() - start)

    records: dict[int, BatchRecord] = {}
    bar = _progress(len(paths), progress)
    try:
        with ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="grade") as pool:
            futures = {pool.submit(work, p, n): k for k, (p, n) in enumerate(zip(paths, names))}
            for fut in as_completed(futures):
                rec = fut.result()
                records[futures[fut]] = rec
                if on_done is not None:
                    on_done(rec)
                bar.update(1)
                bar.set_postfix_str(f"{rec.name}: {rec.score:g}" + (" (resumed)" if rec.skipped else ""))
    finally:
        bar.close()
        for box in boxes:
            box.close()
    ordered = [records[k] for k in range(len(paths))]
    write_grades_csv(out / "grades.csv", ordered + _earlier_records(out, {r.name for r in ordered}))
    return ordered


def _earlier_records(out: Path, exclude: set[str]) -> list[BatchRecord]:
    """Submissions graded into ``out`` by earlier batches, so that grades.csv lists the whole class."""
    found = []
    for state_file in sorted(out.glob("*/grading.json")):
        name = state_file.parent.name
        if name in exclude:
            continue
        try:
            state = json.loads(state_file.read_text(encoding="utf-8"))
            found.append(BatchRecord(name, Path(state.get("path", "")), state_file.parent, float(state["score"]),
                                     {k: float(v) for k, v in dict(state["scores"]).items()}, state.get("failure"),
                                     True, 0.0))
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return found


def _progress(total: int, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="grading", unit="sub", disable=not enabled, dynamic_ncols=True)


def write_grades_csv(path: Path, records: Sequence[BatchRecord]) -> Path:
    """``student_id, total, <one column per autograded question>``, one line per record."""
    ids = autograded_question_ids()
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(csv_header(ids))
        for r in records:
            scores = [0.0 if r.failure else float(r.scores.get(q, 0.0)) for q in ids]
            writer.writerow([r.name, points(0.0 if r.failure else r.score)] + [points(s) for s in scores])
    return path


# ------------------------------------------------------------------------------- the answer key


def write_key_submission(out: str | os.PathLike, *, zip_it: bool = True) -> Path:
    """Write the answer-key submission to ``out/hw4_key/`` (and ``out/hw4_key.zip``); return it.

    The notebooks are copied from notebooks/key when all of them are there, else built from
    solutions/ with ``kit.notebooks`` (the same build that writes notebooks/key).
    """
    out = Path(out)
    folder = out / "hw4_key"
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    key_dir = KIT_ROOT / "notebooks" / "key"
    if all((key_dir / f"{stem}.ipynb").is_file() for stem in NOTEBOOKS):
        for stem in NOTEBOOKS:
            shutil.copy2(key_dir / f"{stem}.ipynb", folder / f"{stem}.ipynb")
    else:
        import nbformat

        from kit.notebooks import build_notebook

        for stem in NOTEBOOKS:
            nbformat.write(build_notebook(stem, "key"), folder / f"{stem}.ipynb")
    if not zip_it:
        return folder
    archive = out / "hw4_key.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in sorted(folder.glob("*.ipynb")):
            zf.write(p, p.name)
    return archive
