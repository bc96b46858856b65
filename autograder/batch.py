"""A batch: many submissions graded in parallel into an output folder, resumable.

Per submission the batch writes ``<out>/<name>/results.json`` (Gradescope's schema),
``feedback.md`` (what the student reads) and ``grading.json`` (for staff: scores, digests, what
the code printed, grader notes), then ``<out>/grades.csv`` (``autograder.gradebook``) with every
submission graded into ``<out>`` so far (this batch's first).  A submission whose results exist
for the same file content and the same grader settings is not graded again.  Nothing a submission
does can stop the batch: the catastrophic path writes a failed result and goes on.  Each worker
thread has its own Sandbox; each submission is graded by ``autograder.grade.grade_submission``.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from core.text import write_atomic

from . import grade
from .config import GRADER_VERSION, GradingConfig, load_config
from .gradebook import BatchRecord, earlier_records, write_grades_csv
from .grade import KIT_ROOT, hidden_cache
from .hidden.inputs import build_hidden_inputs
from .results import SubmissionResult
from .sandbox import ResourceLimits, Sandbox

__all__ = ["BatchRecord", "grade_batch", "open_sandbox", "submission_digest", "submission_name"]


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
                on_done: Callable[[BatchRecord], None] | None = None,
                extra_tests: Sequence[str | os.PathLike] | str | os.PathLike | None = ()) -> list[BatchRecord]:
    """Grade ``paths`` into ``out`` with ``jobs`` workers (threads, each with its own Sandbox).

    Returns one BatchRecord per path, in the order given, and writes ``out/grades.csv``.
    Submissions already graded with the same content and settings are skipped when ``resume``.
    ``extra_tests``: test files or folders run beside ``autograder/hidden`` (an instructor's new
    checks); they are part of the settings, so a batch with other extra tests regrades.
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
    if isinstance(extra_tests, (str, os.PathLike)):
        extra_tests = [extra_tests]
    extra_tests = [Path(p).resolve() for p in extra_tests or ()]
    fingerprint = config.fingerprint() + _tests_digest(extra_tests)
    hidden_inputs = build_hidden_inputs(config)
    hidden_cache(hidden_inputs)  # made once, before the workers start
    sandbox_hidden = _hidden_for_sandbox(paths, out, config) + extra_tests

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
            result = grade.grade_submission(path, sandbox=sandbox(), hidden_inputs=hidden_inputs, student_id=name,
                                            staff=staff, extra_tests=extra_tests)
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
    write_grades_csv(out / "grades.csv", ordered + earlier_records(out, {r.name for r in ordered}))
    return ordered


def _progress(total: int, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="grading", unit="sub", disable=not enabled, dynamic_ncols=True)


def _tests_digest(paths: Sequence[str | os.PathLike]) -> str:
    """'' without extra tests, else a digest of their files' names and bytes."""
    if not paths:
        return ""
    h = hashlib.sha256()
    for p in paths:
        h.update(submission_digest(Path(p)).encode())
    return "+" + h.hexdigest()[:12]
