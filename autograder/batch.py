"""A batch: many submissions graded in parallel into an output folder; it always finishes and loses nothing.

Per submission the batch writes ``<out>/<name>/results.json`` (Gradescope's schema),
``feedback.md`` (what the student reads) and ``grading.json`` (for staff: scores, per-test scores,
digests, the configuration, what the code printed, grader notes), then ``<out>/grades.csv``
(``autograder.gradebook``) with every submission graded into ``<out>``, ``<out>/summary.md`` (for
staff: how it was graded, failures, and the library calls that do the homework's work, found in
the code by ``autograder.review.library_calls``) and ``<out>/configuration.json``.  One
``autograder.run.GradingRun`` grades every submission (hidden inputs, sandboxes, workers and the
canary set up once); this module only schedules, keeps the folder's journal
(``autograder.journal``) and handles Ctrl-C (``autograder.killing`` stops the processes).

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

import os
import queue
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path

from core.untrusted import for_terminal

from .config import GradingConfig, load_config
from .gradebook import BatchRecord, earlier_records, staff_of, write_grades_csv, write_summary
from .journal import (DEATHS_TO_FAIL, ConfigurationMismatch, Journal, check_folder, lock, resumable, state_of,
                      submission_digest, submission_name, unique_names, write_configuration, write_outputs)
from .killing import descendants, kill_grading_processes, signal_all
from .pictures import figures_of
from .results import SubmissionResult
from .review.library_calls import find_in_class
from .run import GradingRun
from .sandbox import ResourceLimits

# ConfigurationMismatch and the submission's name and digest are re-exported: the command line
# and the kit's tests import them from here.
__all__ = ["BatchInterrupted", "BatchRecord", "ConfigurationMismatch", "grade_batch", "submission_digest",
           "submission_name"]

_INTERRUPT_GRACE = 4.0      # seconds the interrupted grading processes get to stop before SIGKILL
_KILL_WAIT = 2.5            # seconds to wait for the workers once their processes are killed


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
                canary: bool = True, pictures: bool = True) -> list[BatchRecord]:
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
    batch machinery turn it off).  ``pictures``: each feedback.html shows the figures of what the
    student's functions did on the public data (the run's unscored picture step, a few seconds per
    submission); without, the feedback is text only.  Scores never depend on it, so it is not part
    of the configuration: a resumed submission keeps the feedback it was graded with.

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
    names = unique_names(paths)
    unknown = sorted(set(regrade) - set(names))
    if unknown:
        raise ValueError(f"regrade: expected names of the submissions given ({', '.join(names[:10])}"
                         f"{'...' if len(names) > 10 else ''}), got {unknown}")
    if isinstance(extra_tests, (str, os.PathLike)):
        extra_tests = [extra_tests]
    # Hidden from student code: the outputs and every folder the submissions live in (the run
    # adds the configuration's file, the official data and the extra tests).
    run = GradingRun(config, hide=[out, *(p.resolve().parent for p in paths)], extra_tests=extra_tests or (),
                     isolation=isolation, limits=limits, allow_weak=allow_weak, pictures=pictures)
    folder_lock = lock(out)
    try:
        note = check_folder(out, run.record, regrade_all, time.strftime("%Y%m%d-%H%M%S"))
        if regrade_all:
            resume = False
        with run:
            return _run(run, paths, names, out, jobs=jobs, resume=resume, progress=progress, on_done=on_done,
                        forced=set(regrade), note=note, canary=canary)
    finally:
        os.close(folder_lock)


def _run(run: GradingRun, paths, names, out: Path, *, jobs, resume, progress, on_done, forced, note,
         canary=True) -> list[BatchRecord]:
    record = run.record
    key = record["key"]
    levels: set = set()
    cancel = threading.Event()
    write_lock = threading.Lock()
    inflight: set[str] = set()
    # Ctrl-C is handled from here on, set-up included: "setup" while nothing is graded yet (the
    # first signal stops the set-up), "raise" while the main thread may be stopped where it is.
    sig = {"signals": 0, "setup": True, "raise": False}

    def hard_exit() -> None:
        # Second Ctrl-C: kill the grading processes, record nothing more, keep what is on disk.
        got = write_lock.acquire(timeout=1.0)
        cancel.set()
        kill_grading_processes(run.sandboxes())
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
        kill_grading_processes(run.sandboxes())
        run.close()
        restore_handlers()
        return BatchInterrupted([], [], setup=True)

    def check_cancel() -> None:
        if cancel.is_set():
            raise _SetUpCancelled()

    try:
        check_cancel()
        write_configuration(out, record, levels)
        journal = Journal(out)
        sig["raise"] = True  # making the hidden inputs: stopped where it is by the first signal
        run.make_inputs()  # made once, before the workers start
        sig["raise"] = False
        check_cancel()
    except _SetUpCancelled:
        raise stop_set_up() from None
    except BaseException:
        sig["raise"] = False
        restore_handlers()
        raise

    def finish(result: SubmissionResult, path: Path, name: str, digest: str, staff: dict, start: float,
               *, poison: bool = False) -> BatchRecord | None:
        # The result comes finished and stamped by the run: written as it is, with the pictures of
        # the public data it carries (feedback.html and figures/).
        level = (result.configuration or {}).get("isolation")
        figures = figures_of(result.pictures)  # checked (and drawn if need be) outside the lock
        folder = out / name
        with write_lock:
            if cancel.is_set():
                if not sig["setup"]:  # (in the set-up, nothing was started: the journal stays as found)
                    journal.clear(name)
                return None  # graded (or broken) while being cancelled: nothing recorded, no strike
            write_outputs(folder, result, state_of(result, path, digest, staff, poison=poison), figures)
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
        try:
            result = run.grade(path, student_id=name, staff=staff)
        except Exception as exc:  # noqa: BLE001 - the catastrophic path: a failed result, never a stop
            if cancel.is_set():
                journal.clear(name)
                return None
            staff["log"].append(traceback.format_exc())
            staff["internal_error"] = True
            result = run.failed(
                f"the autograder hit an internal error ({type(exc).__name__}) while grading it; the course staff "
                f"will grade it again", student_id=name, execution_time=time.monotonic() - start)
        return finish(result, path, name, digest, staff, start)

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
                result = run.failed(
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
                result = run.failed(
                    "the autograder stopped while grading this submission, more than once, so it was not graded; "
                    "the course staff will look at it", student_id=name)
                rec = finish(result, path, name, digest, staff, time.monotonic(), poison=True)
                if rec is not None:
                    done(k, rec)
                continue
            if resume and name not in forced:
                state = resumable(folder, digest, key)
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
            report = run.run_canary()
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
        write_configuration(out, record, levels | {r.isolation for r in everyone if r.isolation})
        calls = find_in_class([(r.name, r.path) for r in everyone], run.config.library_names())
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
            signal_all(descendants()[0], signal.SIGINT)  # the pytest runs stop and close their sessions
            _drain(results, running, _INTERRUPT_GRACE)
            kill_grading_processes(run.sandboxes())
            _drain(results, running, _KILL_WAIT)
            for name in cancelled:
                journal.clear(name)  # not the student's fault: graded again on resume, no strike
        if not cancel.is_set():
            for _ in threads:
                tasks.put(None)
            for t in threads:
                t.join()
        run.close()
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

