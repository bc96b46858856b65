"""A batch: many submissions graded in parallel into an output folder; it always finishes and loses nothing.

Per submission the batch writes ``<out>/<name>/results.json`` (Gradescope's schema),
``feedback.md`` (what the student reads) and ``grading.json`` (for staff: scores, per-test scores,
digests, the configuration, what the code printed, grader notes), then ``<out>/grades.csv``
(``autograder.gradebook``) with every submission graded into ``<out>``, ``<out>/summary.md`` (for
staff: how it was graded, failures, and the library calls that do the homework's work, found in
the code by ``autograder.review.library_calls``) and ``<out>/configuration.json``.  Each worker thread has its own Sandbox; each submission is graded
by ``autograder.grade.grade_submission``.

What makes it safe to stop and resume:

- **One configuration per folder.**  Every result records how it was graded
  (``autograder.config.configuration``: versions, secret fingerprint, data, settings, tests'
  digests, isolation level).  A batch whose configuration key differs from the folder's refuses
  to start (``ConfigurationMismatch``) unless ``regrade_all`` (then the folder's other results
  are moved to ``<out>/.superseded-<time>/``); a new folder, or ``autograder.regrade``, keeps both.
- **A journal of what is in flight** (``<out>/.inflight/<name>.json``, written before a
  submission starts, removed once its results are written atomically).  An entry left by a grader
  that died (kill -9, out of memory, a stopped process killed by hand) makes the next batch grade
  that submission again first, alone; one that was in flight when the grader died twice is
  recorded as failed with the reason, and not graded again unless named in ``regrade``.
- **Resume** skips a submission only when its results exist for the same content and the same
  configuration and grading succeeded: failures and internal errors are graded again.
- **Ctrl-C** (SIGINT, or SIGTERM) once: no new work starts, the running grading processes are
  interrupted (then killed), nothing that finished after the signal is recorded (a cancelled
  sandbox must not give a student a zero), grades.csv and summary.md are written for what is done
  and ``BatchInterrupted`` is raised, within about 8 s.  A second Ctrl-C kills the grading
  processes, writes grades.csv from what is on disk and exits the process at once (status 130).
  The handling is in place before the set-up starts (even when the grader was started with
  SIGINT ignored, as a shell starts a background job): Ctrl-C while the hidden inputs are made or
  the canary runs stops the set-up where it is, kills the canary's grading processes and raises
  ``BatchInterrupted`` (``setup``) at once, with nothing graded or recorded (no journal entry, no
  grades.csv); the same command later grades normally.
- One folder, one grader: a lock file (``<out>/.lock``) refuses a second batch into the same folder.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import queue
import re
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

from core.text import write_atomic
from core.untrusted import for_terminal

from . import feedback_page, grade
from .config import GradingConfig, configuration, configuration_changes, load_config, tests_fingerprint
from .gradebook import BatchRecord, earlier_records, read_state, staff_of, write_grades_csv, write_summary
from .canary import check as canary_check
from .grade import KIT_ROOT, hidden_cache
from .pictures import figures_of
from .hidden.inputs import build_hidden_inputs
from .results import SubmissionResult
from .review.library_calls import find_in_class
from .sandbox import ResourceLimits, Sandbox

__all__ = ["BatchInterrupted", "BatchRecord", "ConfigurationMismatch", "grade_batch", "open_sandbox",
           "submission_digest", "submission_name"]

JOURNAL = ".inflight"
CONFIG_FILE = "configuration.json"
DEATHS_TO_FAIL = 2          # grader deaths with a submission in flight before it is recorded as failed
_INTERRUPT_GRACE = 4.0      # seconds the interrupted grading processes get to stop before SIGKILL
_KILL_WAIT = 2.5            # seconds to wait for the workers once their processes are killed
_INTERNAL = "because of an internal error"


class BatchInterrupted(KeyboardInterrupt):
    """The batch was stopped by Ctrl-C: ``records`` are the submissions finished (and recorded),
    ``cancelled`` the names whose grading was cancelled (nothing recorded; graded on resume).
    ``setup``: stopped while being set up (hidden inputs, the canary): nothing was graded or
    recorded, and grades.csv was not written."""

    def __init__(self, records: list, cancelled: list[str], *, setup: bool = False):
        super().__init__("interrupted while setting up: nothing graded" if setup else
                         f"interrupted: {len(records)} done, {len(cancelled)} cancelled")
        self.records = records
        self.cancelled = cancelled
        self.setup = setup


class _SetUpCancelled(KeyboardInterrupt):
    """Raised in the main thread by the first Ctrl-C while the batch is being set up."""


class ConfigurationMismatch(ValueError):
    """The output folder holds results of another grading configuration."""


def submission_name(path: Path) -> str:
    """The gradebook name of a submission: its file name without .zip, made safe for a folder."""
    name = path.name[:-4] if path.name.lower().endswith(".zip") else path.name
    return re.sub(r"[^A-Za-z0-9_.@+-]", "_", name).strip(".") or "submission"


def submission_digest(path: Path) -> str:
    """SHA-256 of a submission's content (a file's bytes, or a folder's relative paths and bytes).

    A path is hashed as the bytes the file system holds (``os.fsencode``): a name that is not
    UTF-8 is still a name, and the same bytes as before for one that is.
    """
    h = hashlib.sha256()
    path = Path(path)
    if path.is_dir():
        for p in sorted(path.rglob("*")):
            if p.is_file() and not p.is_symlink():
                h.update(os.fsencode(p.relative_to(path).as_posix()) + b"\0")
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


def _resumable(folder: Path, digest: str, key: str) -> dict | None:
    """The state of a finished, successful grading of this content under this configuration, else None.

    A failure or an internal error is not finished (it is graded again), except a submission
    recorded as failed because the grader died with it twice (``poison``): only naming it grades it.
    """
    state = read_state(folder)
    if state is None or not (folder / "results.json").is_file():
        return None
    if state.get("sha256") != digest or state.get("configuration_key") != key:
        return None
    if state.get("poison"):
        return state
    if state.get("failure") or state.get("internal_errors"):
        return None
    return state


def _write_outputs(folder: Path, result: SubmissionResult, state: dict, figures: dict | None = None) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    result.write_gradescope(folder / "results.json")
    write_atomic(folder / "feedback.md", result.feedback_markdown())
    feedback_page.write(folder, result, figures or {})  # feedback.html and figures/: the public data's pictures
    # grading.json last: its presence with a matching digest is what marks the work as done.
    write_atomic(_state_path(folder), json.dumps(state, indent=2, allow_nan=False, default=str))


def _state(result: SubmissionResult, path: Path, digest: str, staff: dict, *, poison: bool = False) -> dict:
    config = result.configuration or {}
    internal = sum(_INTERNAL in t.feedback for q in result.questions for t in q.tests)
    return {
        "student_id": result.student_id, "path": str(path), "sha256": digest,
        "configuration_key": config.get("key"), "fingerprint": config.get("key"),
        "grader_version": config.get("grader_version"), "score": result.score, "max_score": result.max_score,
        "scores": {q.id: q.score for q in result.questions},
        "tests": [{"question": q.id, "name": t.name, "score": t.score, "max_score": t.max_score}
                  for q in result.questions for t in q.tests],
        "failure": result.failure, "internal_errors": internal + bool(staff.get("internal_error")),
        "poison": poison, "seconds": result.execution_time, "isolation": result.isolation,
        "configuration": config, "staff": staff,
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
                 attempts: int = 3, allow_weak: bool = False) -> Sandbox:
    """A Sandbox for grading; with "auto" as root, retried when it comes up weaker than namespaces.

    As root the namespaces level normally works, so a weaker one means its probe failed for a
    passing reason (a loaded machine, a uid clash with another grader); a weaker sandbox is
    accepted after ``attempts`` tries, with a warning on stderr.
    """
    options = {"limits": limits} if limits is not None else {}
    for attempt in range(attempts):
        box = Sandbox(KIT_ROOT, hidden=hidden, isolation=isolation, allow_weak=allow_weak, **options)
        if isolation != "auto" or os.geteuid() != 0 or box.isolation.level in ("namespaces", "uid"):
            return box
        if attempt == attempts - 1:
            print(f"warning: the sandbox runs at the {box.isolation.level} level ({'; '.join(box.isolation.notes)})",
                  file=sys.stderr)
            return box
        box.close()
        time.sleep(1.0 + attempt)
    raise AssertionError("unreachable")


# ------------------------------------------------------------------------------------------------
# the folder: its lock, its configuration, its journal


def _lock(out: Path) -> int:
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise RuntimeError(f"out: another grader is writing into {out}; wait for it or use another --out") from None
    return fd


def folder_configuration(out: Path) -> dict | None:
    """The configuration the results in ``out`` were graded with (``configuration.json``, else the
    first result that records one; ``{}`` for results that record none; None for an empty folder)."""
    try:
        data = json.loads((Path(out) / CONFIG_FILE).read_text(encoding="utf-8"))
        if isinstance(data, dict) and isinstance(data.get("configuration"), dict):
            return data["configuration"]
    except (OSError, ValueError):
        pass
    for state_file in sorted(Path(out).glob("*/grading.json")):
        state = read_state(state_file.parent)
        if state is not None:
            return state.get("configuration") or {}
    return None


def _check_folder(out: Path, record: dict, regrade_all: bool, stamp: str) -> str:
    """Refuse another configuration's folder (or, with ``regrade_all``, move its results aside)."""
    found = folder_configuration(out)
    if found is None or found.get("key") == record["key"] or not any(out.glob("*/grading.json")):
        return ""
    why = configuration_changes(found, record) or ["the configuration key differs"]
    if not regrade_all:
        raise ConfigurationMismatch(
            f"out: {out} holds results graded with another configuration ({'; '.join(why)}); refusing to mix "
            f"them in one grades.csv. Use --regrade-all to regrade the whole class into it (its results are "
            f"kept in {out}/.superseded-<time>/), a new --out, or --regrade-into NEW_DIR for a regrade with a "
            f"diff (python -m autograder accept NEW_DIR --into {out} publishes it).")
    aside = out / f".superseded-{stamp}"
    aside.mkdir()
    for state_file in sorted(out.glob("*/grading.json")):
        os.rename(state_file.parent, aside / state_file.parent.name)
    for name in ("grades.csv", "summary.md", CONFIG_FILE):
        if (out / name).exists():
            os.rename(out / name, aside / name)
    return f"Earlier results of another configuration ({'; '.join(why)}) were moved to {aside}."


def _write_configuration(out: Path, record: dict, levels: set) -> None:
    data = {"configuration": {**record, "isolation": None}, "isolation_levels": sorted(levels),
            "dev_secret": record.get("dev_secret"), "written": time.strftime("%Y-%m-%d %H:%M:%S")}
    write_atomic(out / CONFIG_FILE, json.dumps(data, indent=2, default=str))


class _Journal:
    """``<out>/.inflight/<name>.json`` per submission in flight: ``{name, sha256, key, attempts, pid}``."""

    def __init__(self, out: Path):
        self.folder = out / JOURNAL
        self.folder.mkdir(exist_ok=True)
        self.left: dict[str, dict] = {}
        for p in sorted(self.folder.glob("*.json")):
            try:
                entry = json.loads(p.read_text(encoding="utf-8"))
                self.left[str(entry["name"])] = entry
            except (OSError, ValueError, KeyError, TypeError):
                p.unlink(missing_ok=True)

    def deaths(self, name: str, digest: str, key: str) -> int:
        """How many graders died with this content in flight under this configuration."""
        entry = self.left.get(name)
        if entry is None or entry.get("sha256") != digest or entry.get("key") != key:
            return 0
        return int(entry.get("attempts", 1))

    def start(self, name: str, digest: str, key: str, attempts: int) -> None:
        entry = {"name": name, "sha256": digest, "key": key, "attempts": attempts, "pid": os.getpid(),
                 "started": time.time()}
        write_atomic(self.folder / f"{name}.json", json.dumps(entry))

    def clear(self, name: str) -> None:
        (self.folder / f"{name}.json").unlink(missing_ok=True)


# ------------------------------------------------------------------------------------------------
# the grading processes of this grader (to interrupt them on Ctrl-C)


def _process_tree() -> dict[int, list[int]]:
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as fh:
                stat = fh.read().decode(errors="replace")
            ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        children.setdefault(ppid, []).append(int(entry))
    return children


def _descendants() -> tuple[list[int], list[int]]:
    """(this process's children, all their descendants)."""
    tree = _process_tree()
    direct = list(tree.get(os.getpid(), []))
    found, todo = [], list(direct)
    while todo:
        pid = todo.pop()
        found.append(pid)
        todo += tree.get(pid, [])
    return direct, found


def _signal_all(pids: Sequence[int], sig: int) -> None:
    for pid in pids:
        try:
            os.kill(pid, sig)
        except OSError:
            pass


def _kill_grading_processes(boxes: Sequence[Sandbox]) -> None:
    _signal_all(_descendants()[1], signal.SIGKILL)
    from .sandbox.uids import sweep_uid

    for box in boxes:
        uid = box.runtime.uid if box.runtime is not None else None
        if uid is not None and uid not in (0, os.getuid()):
            try:
                sweep_uid(uid, budget=1.0)
            except (OSError, ValueError):
                pass


def _drain(results: queue.Queue, running: dict, seconds: float) -> None:
    """Take finished runs off ``results`` (discarding them: the batch is being cancelled) for up to
    ``seconds``, until nothing runs."""
    end = time.monotonic() + seconds
    while running and time.monotonic() < end:
        try:
            _, name, _ = results.get(timeout=0.2)
            running.pop(name, None)
        except queue.Empty:
            pass


# ------------------------------------------------------------------------------------------------
# the batch


def grade_batch(paths: Sequence[str | os.PathLike], out: str | os.PathLike, *, jobs: int = 1,
                config: GradingConfig | None = None, resume: bool = True, progress: bool = True,
                isolation: str = "auto", limits: ResourceLimits | None = None,
                on_done: Callable[[BatchRecord], None] | None = None,
                extra_tests: Sequence[str | os.PathLike] | str | os.PathLike | None = (),
                regrade: Sequence[str] = (), regrade_all: bool = False, allow_weak: bool = False,
                canary: bool = True) -> list[BatchRecord]:
    """Grade ``paths`` into ``out`` with ``jobs`` workers (threads, each with its own Sandbox).

    Returns one BatchRecord per path, in the order given, and writes ``out/grades.csv``,
    ``out/summary.md`` and ``out/configuration.json``.  Submissions already graded successfully
    with the same content and configuration are skipped when ``resume``; ``regrade``: gradebook
    names graded again anyway; ``regrade_all``: grade everything again, even into a folder of
    another configuration.  ``extra_tests``: test files or folders run beside
    ``autograder/hidden`` (an instructor's new checks); they are part of the configuration.
    ``allow_weak``: accept a sandbox level that runs student code as the grader's own user
    (refused otherwise).  ``canary``: grade the answer key first, in the batch's own sandbox and
    configuration, and grade nothing unless it gets full marks (only the kit's own tests of the
    batch machinery turn it off).

    Raises
    ------
    ConfigurationMismatch
        When ``out`` holds results of another configuration (and not ``regrade_all``).
    autograder.canary.CanaryFailed
        When the answer key loses points in this sandbox and configuration: nothing is graded.
    BatchInterrupted
        After Ctrl-C (SIGINT or SIGTERM, when called from the main thread), once grades.csv is
        written for what finished.
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
    unknown = sorted(set(regrade) - set(names))
    if unknown:
        raise ValueError(f"regrade: expected names of the submissions given ({', '.join(names[:10])}"
                         f"{'...' if len(names) > 10 else ''}), got {unknown}")
    if isinstance(extra_tests, (str, os.PathLike)):
        extra_tests = [extra_tests]
    extra_tests = [Path(p).resolve() for p in extra_tests or ()]
    record = configuration(config, tests=tests_fingerprint(extra_tests))
    lock = _lock(out)
    try:
        note = _check_folder(out, record, regrade_all, time.strftime("%Y%m%d-%H%M%S"))
        if regrade_all:
            resume = False
        return _run(paths, names, out, jobs=jobs, config=config, record=record, resume=resume, progress=progress,
                    isolation=isolation, limits=limits, on_done=on_done, extra_tests=extra_tests,
                    forced=set(regrade), note=note, allow_weak=allow_weak, canary=canary)
    finally:
        os.close(lock)


def _run(paths, names, out: Path, *, jobs, config, record, resume, progress, isolation, limits, on_done,
         extra_tests, forced, note, allow_weak=False, canary=True) -> list[BatchRecord]:
    key = record["key"]
    levels: set = set()
    cancel = threading.Event()
    write_lock = threading.Lock()
    local = threading.local()
    boxes: list[Sandbox] = []
    boxes_lock = threading.Lock()
    inflight: set[str] = set()
    # Ctrl-C is handled from here on, set-up included: "setup" while nothing is graded yet (the
    # first signal stops the set-up), "raise" while the main thread may be stopped where it is.
    sig = {"signals": 0, "setup": True, "raise": False}

    def hard_exit() -> None:
        # Second Ctrl-C: kill the grading processes, record nothing more, keep what is on disk.
        got = write_lock.acquire(timeout=1.0)
        cancel.set()
        _kill_grading_processes(boxes)
        for name in list(inflight):
            journal.clear(name)
        if not sig["setup"]:
            try:
                cancelled.extend(sorted(inflight))
                write_gradebook()
            except Exception:  # noqa: BLE001 - exiting anyway
                pass
        if got:
            write_lock.release()
        sys.stderr.write("\ninterrupted twice: stopped at once; grades.csv lists what was finished\n"
                         if not sig["setup"] else "\ninterrupted twice while setting up: nothing was graded\n")
        sys.stderr.flush()
        os._exit(130)

    def on_signal(signum, frame) -> None:
        sig["signals"] += 1
        if sig["signals"] == 1:
            cancel.set()
            if sig["raise"]:
                sig["raise"] = False
                raise _SetUpCancelled()
        else:
            hard_exit()

    handlers = {}
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            handlers[signum] = signal.signal(signum, on_signal)

    def restore_handlers() -> None:
        for signum, old in handlers.items():
            signal.signal(signum, old)

    def stop_set_up() -> BatchInterrupted:
        # Nothing was graded: no journal entry was written, nothing is recorded.  The canary's
        # grading processes (a worker, the key's sandbox) are killed; the same command grades later.
        sig["raise"] = False
        _kill_grading_processes(boxes)
        with boxes_lock:
            for box in boxes:
                box.close()
        restore_handlers()
        return BatchInterrupted([], [], setup=True)

    def check_cancel() -> None:
        if cancel.is_set():
            raise _SetUpCancelled()

    try:
        check_cancel()
        _write_configuration(out, record, levels)
        journal = _Journal(out)
        sig["raise"] = True  # making the hidden inputs: stopped where it is by the first signal
        hidden_inputs = build_hidden_inputs(config)
        hidden_cache(hidden_inputs)  # made once, before the workers start
        sig["raise"] = False
        check_cancel()
        sandbox_hidden = _hidden_for_sandbox(paths, out, config) + extra_tests
    except _SetUpCancelled:
        raise stop_set_up() from None
    except BaseException:
        sig["raise"] = False
        restore_handlers()
        raise

    def sandbox() -> Sandbox:
        if getattr(local, "box", None) is None:
            box = open_sandbox(hidden=sandbox_hidden, isolation=isolation, limits=limits, allow_weak=allow_weak)
            with boxes_lock:
                boxes.append(box)
            local.box = box
        return local.box

    def finish(result: SubmissionResult, path: Path, name: str, digest: str, staff: dict, start: float,
               *, poison: bool = False, figures: dict | None = None) -> BatchRecord | None:
        iso = result.isolation if isinstance(result.isolation, dict) else None
        if iso is None and getattr(local, "box", None) is not None:
            iso = local.box.isolation.as_dict()
        level = iso.get("level") if iso else None
        draw = (result.configuration or {}).get("draw")  # the digest of the submission's hidden draw
        result = replace(result, configuration={**record, "isolation": level, "draw": draw}, isolation=iso)
        folder = out / name
        with write_lock:
            if cancel.is_set():
                if not sig["setup"]:  # (in the set-up, nothing was started: the journal stays as found)
                    journal.clear(name)
                return None  # graded (or broken) while being cancelled: nothing recorded, no strike
            _write_outputs(folder, result, _state(result, path, digest, staff, poison=poison), figures)
            journal.clear(name)
        return BatchRecord(name, path, folder, result.score, {q.id: q.score for q in result.questions},
                           result.failure, False, time.monotonic() - start, key, level, **staff_of(staff))

    def work(path: Path, name: str, digest: str, attempt: int) -> BatchRecord | None:
        if cancel.is_set():
            return None
        start = time.monotonic()
        staff: dict = {"log": []}
        if attempt > 1:
            staff["log"].append(f"graded again: a grader died while grading it (attempt {attempt})")
        journal.start(name, digest, key, attempt)
        pictures: dict = {}
        try:
            result = grade.grade_submission(path, sandbox=sandbox(), hidden_inputs=hidden_inputs, student_id=name,
                                            staff=staff, extra_tests=extra_tests, pictures=pictures)
        except Exception as exc:  # noqa: BLE001 - the catastrophic path: a failed result, never a stop
            if cancel.is_set():
                journal.clear(name)
                return None
            staff["log"].append(traceback.format_exc())
            staff["internal_error"] = True
            result = SubmissionResult.failed(
                f"the autograder hit an internal error ({type(exc).__name__}) while grading it; the course staff "
                f"will grade it again", student_id=name, execution_time=time.monotonic() - start)
        return finish(result, path, name, digest, staff, start, figures=figures_of(pictures))

    # What to do with each submission: resume it, record it as failed, or grade it (suspects first).
    records: dict[int, BatchRecord] = {}
    suspects: list[tuple] = []
    rest: list[tuple] = []
    bar = _progress(len(paths), progress)

    def done(k: int, rec: BatchRecord) -> None:
        records[k] = rec
        if rec.isolation:
            levels.add(rec.isolation)
        if on_done is not None:
            on_done(rec)
        bar.update(1)
        bar.set_postfix_str(for_terminal(f"{rec.name}: {rec.score:g}" + (" (resumed)" if rec.skipped else ""), 80))

    try:
        for k, (path, name) in enumerate(zip(paths, names)):
            if cancel.is_set():
                break
            try:
                digest = submission_digest(path)
            except OSError as exc:  # one unreadable submission is its student's failure, never the batch's
                result = SubmissionResult.failed(
                    f"the submission could not be read ({type(exc).__name__}: {exc.strerror or exc}); the course "
                    "staff will look at it", student_id=name)
                rec = finish(result, path, name, "unreadable", {"log": [traceback.format_exc()]}, time.monotonic())
                if rec is not None:
                    done(k, rec)
                continue
            deaths = journal.deaths(name, digest, key)
            folder = out / name
            if deaths >= DEATHS_TO_FAIL and name not in forced:
                staff = {"log": [f"the grader process died {deaths} times while this submission was being graded "
                                 f"(killed or stopped from outside, or by the submission); not graded again. Look at "
                                 f"it by hand, or grade it alone with --regrade {name}."]}
                result = SubmissionResult.failed(
                    "the autograder stopped while grading this submission, more than once, so it was not graded; "
                    "the course staff will look at it", student_id=name)
                rec = finish(result, path, name, digest, staff, time.monotonic(), poison=True)
                if rec is not None:
                    done(k, rec)
                continue
            if resume and name not in forced:
                state = _resumable(folder, digest, key)
                if state is not None:
                    iso = state.get("isolation")
                    done(k, BatchRecord(name, path, folder, float(state.get("score", 0.0)),
                                        dict(state.get("scores", {})), state.get("failure"), True, 0.0, key,
                                        iso.get("level") if isinstance(iso, dict) else None,
                                        **staff_of(state.get("staff"))))
                    continue
            (suspects if deaths else rest).append((k, path, name, digest, deaths + 1))

        check_cancel()
        tasks: queue.Queue = queue.Queue()
        results: queue.Queue = queue.Queue()

        def worker() -> None:
            while True:
                item = tasks.get()
                if item is None:
                    return
                k, path, name, digest, attempt = item
                try:
                    rec = work(path, name, digest, attempt)
                except BaseException:  # noqa: BLE001 - a worker never dies silently
                    traceback.print_exc()
                    rec = None
                results.put((k, name, rec))

        pending = suspects + rest
        n_suspects = len(suspects)
        if canary and pending:
            # In the main thread, before any worker: a refusal must stop the batch, not become an
            # internal error per submission.
            sig["raise"] = True  # the key's grading is stopped where it is by the first signal
            report = canary_check(sandbox(), hidden_inputs, extra_tests=extra_tests)
            sig["raise"] = False
            level = (report.isolation or {}).get("level", "?")
            weak = " **WEAK isolation: student code ran as the grader's own user**" if (report.isolation or {}).get("weak") else ""
            note = "\n".join(x for x in (note, f"Canary: the answer key got full marks ({report.score:g} points, base "
                                                 f"total {report.max_score:g}) in {report.seconds:.1f} s at the {level} "
                                                 f"level.{weak}") if x)
            if level == "uid" and jobs > 1:
                # Without namespaces, /dev/shm and other users' world-writable folders are shared:
                # two submissions graded at the same time could pass each other files there.
                jobs = 1
                note += ("\nAt the uid level submissions are graded one at a time (--jobs was "
                         "lowered to 1): two at once could exchange files through /dev/shm.")
        check_cancel()
    except _SetUpCancelled:
        bar.close()
        raise stop_set_up() from None
    except BaseException:
        sig["raise"] = False
        bar.close()
        restore_handlers()
        raise
    sig["setup"] = False  # from here a first Ctrl-C cancels the grading (the loop below)
    threads = [threading.Thread(target=worker, name=f"grade-{i}", daemon=True)
               for i in range(min(jobs, max(len(pending), 1)))]
    for t in threads:
        t.start()
    cancelled: list[str] = []

    def write_gradebook() -> list[BatchRecord]:
        ordered = [records[k] for k in sorted(records)]
        everyone = ordered + earlier_records(out, {r.name for r in ordered} | set(cancelled), key)
        write_grades_csv(out / "grades.csv", everyone)
        _write_configuration(out, record, levels | {r.isolation for r in everyone if r.isolation})
        calls = find_in_class([(r.name, r.path) for r in everyone], config.library_names())
        write_summary(out / "summary.md", everyone, record, cancelled=cancelled, note=note, library_calls=calls)
        return ordered

    running: dict[str, int] = {}
    try:
        last_refresh = time.monotonic()
        while pending or running:
            limit = 1 if n_suspects > 0 else jobs
            while pending and len(running) < limit and not cancel.is_set():
                k, path, name, digest, attempt = pending.pop(0)
                running[name] = k
                inflight.add(name)
                tasks.put((k, path, name, digest, attempt))
            if cancel.is_set():
                break
            try:
                k, name, rec = results.get(timeout=0.2)
            except queue.Empty:
                if time.monotonic() - last_refresh > 1.0:
                    bar.refresh()
                    last_refresh = time.monotonic()
                continue
            running.pop(name, None)
            inflight.discard(name)
            if n_suspects > 0 and k in {s[0] for s in suspects}:
                n_suspects -= 1
            if rec is not None:
                done(k, rec)
        if cancel.is_set():
            bar.set_description("cancelling")
            with write_lock:
                pass  # a result being written now was finished before the signal; any later one is dropped
            while True:  # results that were recorded before the signal
                try:
                    k, name, rec = results.get_nowait()
                except queue.Empty:
                    break
                running.pop(name, None)
                inflight.discard(name)
                if rec is not None:
                    done(k, rec)
            cancelled = sorted(running)
            _signal_all(_descendants()[0], signal.SIGINT)  # the pytest runs stop and close their sessions
            _drain(results, running, _INTERRUPT_GRACE)
            _kill_grading_processes(boxes)
            _drain(results, running, _KILL_WAIT)
            for name in cancelled:
                journal.clear(name)  # not the student's fault: graded again on resume, no strike
        if not cancel.is_set():
            for _ in threads:
                tasks.put(None)
            for t in threads:
                t.join()
        for box in boxes:
            box.close()
        ordered = write_gradebook()  # a second signal until here exits at once, with grades.csv written
    finally:
        for _ in threads:
            tasks.put(None)
        restore_handlers()
        bar.close()
    if cancel.is_set():
        raise BatchInterrupted(ordered, cancelled)
    return ordered


def _progress(total: int, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="grading", unit="sub", disable=not enabled, dynamic_ncols=True)

