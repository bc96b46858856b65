"""A batch: many submissions graded in parallel into an output folder; it always finishes and loses nothing.

Per submission the batch writes ``<out>/<name>/results.json`` (Gradescope's schema),
``feedback.md`` (what the student reads) and ``grading.json`` (for staff: scores, per-test scores,
digests, the configuration, what the code printed, grader notes), then ``<out>/grades.csv``
(``autograder.channels.gradebook``) with every submission graded into ``<out>``, ``<out>/summary.md`` (for
staff: how it was graded, failures, and the library calls that do the homework's work, found in
the code by ``autograder.review.library_calls``) and ``<out>/configuration.json``.  One
``autograder.grading.run.GradingRun`` grades every submission (hidden inputs, sandboxes, workers and the
canary set up once); this module only schedules, keeps the folder's journal
(``autograder.channels.journal``) and handles Ctrl-C (``autograder.grading.killing`` stops the processes).

What makes it safe to stop and resume:

- **One configuration per folder.**  Every result records how it was graded
  (``autograder.inputs.config.configuration``: versions, secret fingerprint, data, settings, tests'
  digests, isolation level).  A batch whose configuration key differs from the folder's refuses
  to start (``ConfigurationMismatch``) unless ``regrade_all`` (then the folder's other results
  are moved to ``<out>/.superseded-<time>/``); a new folder, or ``autograder.channels.regrade``, keeps both.
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

import contextlib
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

from autograder.inputs.config import GradingConfig, load_config
from .gradebook import BatchRecord, earlier_records, staff_of, write_grades_csv, write_summary
from .journal import (
    DEATHS_TO_FAIL,
    ConfigurationMismatch,
    Journal,
    check_folder,
    lock,
    resumable,
    state_of,
    submission_digest,
    submission_name,
    unique_names,
    write_configuration,
    write_outputs,
)
from autograder.grading.killing import descendants, kill_grading_processes, signal_all
from autograder.feedback.pictures import figures_of
from autograder.feedback.results import SubmissionResult
from autograder.review.library_calls import find_in_class
from autograder.grading.run import GradingRun
from autograder.sandbox import ResourceLimits

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


# ------------------------------------------------------------------------------------------------
# the batch


def grade_batch(paths: Sequence[str | os.PathLike], out: str | os.PathLike, *, jobs: int = 1,
                config: GradingConfig | None = None, resume: bool = True, progress: bool = True,
                isolation: str = "auto", limits: ResourceLimits | None = None,
                on_done: Callable[[BatchRecord], None] | None = None,
                extra_tests: Sequence[str | os.PathLike] | str | os.PathLike | None = (),
                regrade: Sequence[str] = (), regrade_all: bool = False, allow_weak: bool = False,
                canary: bool = True, pictures: bool = True, names: Sequence[str] | None = None,
                hide: Sequence[str | os.PathLike] = (), keep: str | os.PathLike | None = None) -> list[BatchRecord]:
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
    of the configuration: a resumed submission keeps the feedback it was graded with.  ``names``:
    the gradebook names of ``paths`` (default ``unique_names(paths)``; a cluster shard grades part
    of a class named as a whole); ``hide``: more folders student code must not see; ``keep``: the
    keep of hidden inputs (default ``$HW4_KEEP_INPUTS``).

    Raises
    ------
    ConfigurationMismatch
        When ``out`` holds results of another configuration (and not ``regrade_all``).
    autograder.grading.canary.CanaryFailed
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
    names = unique_names(paths) if names is None else [str(n) for n in names]
    if len(names) != len(paths) or len(set(names)) != len(names):
        raise ValueError(f"names: expected one distinct name per path ({len(paths)}), got {len(names)}")
    unknown = sorted(set(regrade) - set(names))
    if unknown:
        raise ValueError(f"regrade: expected names of the submissions given ({', '.join(names[:10])}"
                         f"{'...' if len(names) > 10 else ''}), got {unknown}")
    if isinstance(extra_tests, (str, os.PathLike)):
        extra_tests = [extra_tests]
    # Hidden from student code: the outputs and every folder the submissions live in (the run
    # adds the configuration's file, the official data and the extra tests).
    run = GradingRun(config, hide=[out, *(p.resolve().parent for p in paths), *hide], extra_tests=extra_tests or (),
                     isolation=isolation, limits=limits, allow_weak=allow_weak, pictures=pictures, keep=keep)
    folder_lock = lock(out)
    try:
        note = check_folder(out, run.record, regrade_all, time.strftime("%Y%m%d-%H%M%S"))
        if regrade_all:
            resume = False
        with run:
            return _Batch(run, paths, names, out, jobs=jobs, resume=resume, progress=progress, on_done=on_done,
                          forced=set(regrade), note=note, canary=canary).grade()
    finally:
        os.close(folder_lock)


class _Signals:
    """Ctrl-C (SIGINT or SIGTERM) in one batch: the first sets ``cancel``, the second calls ``hard_exit``."""

    def __init__(self, cancel: threading.Event, hard_exit: Callable[[], None]):
        self.cancel, self.hard_exit, self.count = cancel, hard_exit, 0
        self.setup = True       # nothing is graded yet: the first signal stops the set-up
        self.raising = False    # a set-up step runs in the main thread: the first signal stops it where it is
        self._previous: dict = {}

    def install(self) -> None:
        # Python lets only the main thread set handlers: called from another, the batch has none.
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                self._previous[signum] = signal.signal(signum, self._on_signal)

    def restore(self) -> None:
        for signum, old in self._previous.items():
            signal.signal(signum, old)

    def stoppable(self, step: Callable):
        """``step()``; the first signal while it runs raises ``_SetUpCancelled`` in it, and one that
        came just before (between two steps) stops it before it starts."""
        self.raising = True
        try:
            if self.cancel.is_set():  # the handler ran while nothing could be stopped: stop here
                raise _SetUpCancelled()
            return step()
        finally:
            self.raising = False

    def _on_signal(self, signum, frame) -> None:
        self.count += 1
        if self.count == 1:
            self.cancel.set()
            if self.raising:
                self.raising = False
                raise _SetUpCancelled()
        else:
            self.hard_exit()


class _Batch:
    """One batch in an entered ``GradingRun``: set-up, plan, workers, Ctrl-C, gradebook; ``grade()`` once."""

    def __init__(self, run: GradingRun, paths: list[Path], names: list[str], out: Path, *, jobs: int,
                 resume: bool, progress: bool, on_done, forced: set[str], note: str, canary: bool = True):
        self.run, self.paths, self.names, self.out = run, paths, names, out
        self.jobs, self.resume, self.progress, self.on_done = jobs, resume, progress, on_done
        self.forced, self.note, self.canary = forced, note, canary
        self.record, self.key = run.record, run.record["key"]
        self.cancel = threading.Event()
        self.write_lock = threading.Lock()  # a result is written whole, or not once the batch is cancelled
        self.signals = _Signals(self.cancel, self.hard_exit)
        self.journal: Journal | None = None  # made by the set-up, once the handlers are in place
        self.bar = None
        self.levels: set = set()
        self.records: dict[int, BatchRecord] = {}    # by position in paths: the gradebook keeps their order
        self.cancelled: list[str] = []
        self.suspects: set[int] = set()   # left in flight by a dead grader, not graded yet: graded alone
        self.running: dict[str, int] = {}  # handed to a worker (name: position), result not taken yet
        self.inflight: set[str] = set()    # the same names, kept while cancelling: what a second signal clears
        self.tasks, self.results = queue.Queue(), queue.Queue()  # (to the workers, from them)

    def grade(self) -> list[BatchRecord]:
        self.signals.install()  # set-up included
        pending = self.set_up()
        self.signals.setup = False  # from here a first Ctrl-C cancels the grading
        threads = [threading.Thread(target=self._worker, name=f"grade-{i}", daemon=True)
                   for i in range(min(self.jobs, max(len(pending), 1)))]
        for t in threads:
            t.start()
        try:
            self._schedule(pending)
            if self.cancel.is_set():
                self._cancel_running()
            if not self.cancel.is_set():
                for _ in threads:
                    self.tasks.put(None)
                for t in threads:
                    t.join()
            self.run.close()
            ordered = self.write_gradebook()  # a second signal until here exits at once, with grades.csv written
        finally:
            for _ in threads:
                self.tasks.put(None)
            self.signals.restore()
            self.bar.close()
        if self.cancel.is_set():
            raise BatchInterrupted(ordered, self.cancelled)
        return ordered

    def set_up(self) -> list[tuple]:
        """Configuration, journal, hidden inputs, plan and canary: the tasks to grade, suspects first."""
        try:
            self._check_cancel()
            write_configuration(self.out, self.record, self.levels)
            self.journal = Journal(self.out)
            self.signals.stoppable(self.run.make_inputs)  # made once, before the workers start
            self._check_cancel()
            from tqdm.auto import tqdm

            self.bar = tqdm(total=len(self.paths), desc="grading", unit="sub", disable=not self.progress,
                            dynamic_ncols=True)
            pending = self.plan()
            self._check_cancel()
            if self.canary and pending:
                self._run_canary()
            self._check_cancel()
            return pending
        except BaseException as exc:
            self.signals.raising = False
            if self.bar is not None:
                self.bar.close()
            if isinstance(exc, _SetUpCancelled):
                # Nothing was graded: no journal entry was written, nothing is recorded.  The canary's
                # grading processes (a worker, the key's sandbox) are killed; the same command grades later.
                kill_grading_processes(self.run.sandboxes())
                self.run.close()
                self.signals.restore()
                raise BatchInterrupted([], [], setup=True) from None
            self.signals.restore()
            raise

    def _check_cancel(self) -> None:
        if self.cancel.is_set():
            raise _SetUpCancelled()

    def plan(self) -> list[tuple]:
        """Resume, record as failed, or make a task ``(position, path, name, digest, attempt)`` of each
        submission: the suspects (in flight when a grader died) first."""
        suspects, rest = [], []
        for k, (path, name) in enumerate(zip(self.paths, self.names)):
            if self.cancel.is_set():
                break
            task = self._plan_one(k, path, name)
            if task is not None:
                (suspects if task[4] > 1 else rest).append(task)
        self.suspects = {task[0] for task in suspects}
        return suspects + rest

    def _plan_one(self, k: int, path: Path, name: str) -> tuple | None:
        try:
            digest = submission_digest(path)
        except OSError as exc:  # one unreadable submission is its student's failure, never the batch's
            self._record_failed(k, path, name, "unreadable", {"log": [traceback.format_exc()]},
                                f"the submission could not be read ({type(exc).__name__}: {exc.strerror or exc}); "
                                "the course staff will look at it")
            return None
        deaths = self.journal.deaths(name, digest, self.key)
        if deaths >= DEATHS_TO_FAIL and name not in self.forced:
            staff = {"log": [(f"the grader process died {deaths} times while this submission was being graded "
                              f"(killed or stopped from outside, or by the submission); not graded again. Look at "
                              f"it by hand, or grade it alone with --regrade {name}.")]}
            self._record_failed(k, path, name, digest, staff,
                                "the autograder stopped while grading this submission, more than once, so it was "
                                "not graded; the course staff will look at it", poison=True)
            return None
        if self.resume and name not in self.forced:
            state = resumable(self.out / name, digest, self.key)
            if state is not None:
                iso = state.get("isolation")
                self._done(k, BatchRecord(name, path, self.out / name, float(state.get("score", 0.0)),
                                          dict(state.get("scores", {})), state.get("failure"), True, 0.0, self.key,
                                          iso.get("level") if isinstance(iso, dict) else None,
                                          **staff_of(state.get("staff"))))
                return None
        return (k, path, name, digest, deaths + 1)

    def _record_failed(self, k: int, path: Path, name: str, digest: str, staff: dict, message: str, *,
                       poison: bool = False) -> None:
        rec = self._record(self.run.failed(message, student_id=name), path, name, digest, staff, time.monotonic(),
                           poison=poison)
        if rec is not None:
            self._done(k, rec)

    def _run_canary(self) -> None:
        # In the main thread, before any worker: a refusal must stop the batch, not become an
        # internal error per submission.
        report = self.signals.stoppable(self.run.run_canary)
        level = (report.isolation or {}).get("level", "?")
        weak = " **WEAK isolation: student code ran as the grader's own user**" if (report.isolation or {}).get("weak") else ""
        canary = (f"Canary: the answer key got full marks ({report.score:g} points, base total "
                  f"{report.max_score:g}) in {report.seconds:.1f} s at the {level} level.{weak}")
        self.note = "\n".join(x for x in (self.note, canary) if x)
        changed = report.points_changed()
        if changed:
            # An extra check adds its points to its question: the instructor decides, and is told.
            self.note += "\n\n**Points differ from the handout's:**\n\n" + "\n".join(f"- {line}" for line in changed)
            print("warning: points differ from the handout's: " + "; ".join(changed), file=sys.stderr)
        if level == "uid" and self.jobs > 1:
            # Without namespaces, /dev/shm and other users' world-writable folders are shared:
            # two submissions graded at the same time could pass each other files there.
            self.jobs = 1
            self.note += ("\nAt the uid level submissions are graded one at a time (--jobs was "
                          "lowered to 1): two at once could exchange files through /dev/shm.")

    def _worker(self) -> None:
        while True:
            item = self.tasks.get()
            if item is None:
                return
            k, path, name, digest, attempt = item
            try:
                rec = self._work(path, name, digest, attempt)
            except BaseException:  # noqa: BLE001 - a worker never dies silently
                traceback.print_exc()
                rec = None
            self.results.put((k, name, rec))

    def _work(self, path: Path, name: str, digest: str, attempt: int) -> BatchRecord | None:
        if self.cancel.is_set():
            return None
        start = time.monotonic()
        staff: dict = {"log": []}
        if attempt > 1:
            staff["log"].append(f"graded again: a grader died while grading it (attempt {attempt})")
        self.journal.start(name, digest, self.key, attempt)
        try:
            result = self.run.grade(path, student_id=name, staff=staff)
        except Exception as exc:  # noqa: BLE001 - the catastrophic path: a failed result, never a stop
            if self.cancel.is_set():
                self.journal.clear(name)
                return None
            staff["log"].append(traceback.format_exc())
            staff["internal_error"] = True
            result = self.run.failed(
                f"the autograder hit an internal error ({type(exc).__name__}) while grading it; the course staff "
                f"will grade it again", student_id=name, execution_time=time.monotonic() - start)
        return self._record(result, path, name, digest, staff, start)

    def _record(self, result: SubmissionResult, path: Path, name: str, digest: str, staff: dict, start: float,
                *, poison: bool = False) -> BatchRecord | None:
        # The result comes finished and stamped by the run: written as it is, with the pictures of
        # the public data it carries (feedback.html and figures/).
        level = (result.configuration or {}).get("isolation")
        figures = figures_of(result.pictures)  # the worker's record checked again, outside the lock
        folder = self.out / name
        with self.write_lock:
            if self.cancel.is_set():
                if not self.signals.setup:  # (in the set-up, nothing was started: the journal stays as found)
                    self.journal.clear(name)
                return None  # graded (or broken) while being cancelled: nothing recorded, no strike
            write_outputs(folder, result, state_of(result, path, digest, staff, poison=poison), figures)
            self.journal.clear(name)
        return BatchRecord(name, path, folder, result.score, {q.id: q.score for q in result.questions},
                           result.failure, False, time.monotonic() - start, self.key, level, **staff_of(staff))

    def _done(self, k: int, rec: BatchRecord) -> None:
        self.records[k] = rec
        if rec.isolation:
            self.levels.add(rec.isolation)
        if self.on_done is not None:
            self.on_done(rec)
        self.bar.update(1)
        self.bar.set_postfix_str(for_terminal(f"{rec.name}: {rec.score:g}" + (" (resumed)" if rec.skipped else ""), 80))

    def _schedule(self, pending: list[tuple]) -> None:
        """Hand ``pending`` to the workers and take their results, until all are done or cancelled."""
        last_refresh = time.monotonic()
        while pending or self.running:
            limit = 1 if self.suspects else self.jobs
            while pending and len(self.running) < limit and not self.cancel.is_set():
                task = pending.pop(0)
                self.running[task[2]] = task[0]
                self.inflight.add(task[2])
                self.tasks.put(task)
            if self.cancel.is_set():
                return
            try:
                k, name, rec = self.results.get(timeout=0.2)
            except queue.Empty:
                if time.monotonic() - last_refresh > 1.0:
                    self.bar.refresh()
                    last_refresh = time.monotonic()
                continue
            self.suspects.discard(k)
            self._take(k, name, rec)

    def _take(self, k: int, name: str, rec: BatchRecord | None) -> None:
        self.running.pop(name, None)
        self.inflight.discard(name)
        if rec is not None:
            self._done(k, rec)

    def _cancel_running(self) -> None:
        self.bar.set_description("cancelling")
        with self.write_lock:
            pass  # a result being written now was finished before the signal; any later one is dropped
        while not self.results.empty():  # results that were recorded before the signal (only this thread takes)
            self._take(*self.results.get_nowait())
        self.cancelled = sorted(self.running)
        signal_all(descendants()[0], signal.SIGINT)  # the pytest runs stop and close their sessions
        self._drain(_INTERRUPT_GRACE)
        kill_grading_processes(self.run.sandboxes())
        self._drain(_KILL_WAIT)
        for name in self.cancelled:
            self.journal.clear(name)  # not the student's fault: graded again on resume, no strike

    def _drain(self, seconds: float) -> None:
        """Take finished runs off ``results`` (discarding them: the batch is being cancelled) for up to
        ``seconds``, until nothing runs."""
        end = time.monotonic() + seconds
        while self.running and time.monotonic() < end:
            try:
                _, name, _ = self.results.get(timeout=0.2)
                self.running.pop(name, None)
            except queue.Empty:
                pass

    def write_gradebook(self) -> list[BatchRecord]:
        """grades.csv, configuration.json and summary.md; the records of this batch, in the order given."""
        ordered = [self.records[k] for k in sorted(self.records)]
        everyone = ordered + earlier_records(self.out, {r.name for r in ordered} | set(self.cancelled), self.key)
        write_grades_csv(self.out / "grades.csv", everyone)
        write_configuration(self.out, self.record, self.levels | {r.isolation for r in everyone if r.isolation})
        calls = find_in_class([(r.name, r.path) for r in everyone], self.run.config.library_names())
        write_summary(self.out / "summary.md", everyone, self.record, cancelled=self.cancelled, note=self.note,
                      library_calls=calls)
        return ordered

    def hard_exit(self) -> None:
        """The second Ctrl-C: kill the grading processes, record nothing more, keep what is on disk."""
        got = self.write_lock.acquire(timeout=1.0)  # the main thread (running this) may hold it already
        self.cancel.set()
        kill_grading_processes(self.run.sandboxes())
        for name in list(self.inflight):
            self.journal.clear(name)
        if not self.signals.setup:
            with contextlib.suppress(Exception):  # exiting anyway
                self.cancelled.extend(sorted(self.inflight))
                self.write_gradebook()
        if got:
            self.write_lock.release()
        sys.stderr.write("\ninterrupted twice: stopped at once; grades.csv lists what was finished\n"
                         if not self.signals.setup else "\ninterrupted twice while setting up: nothing was graded\n")
        sys.stderr.flush()
        os._exit(130)
