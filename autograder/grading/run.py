"""A grading run: everything set up once to grade submissions, the same way for every channel.

The CLI batch (``autograder.channels.batch``), Gradescope's container (``autograder.channels.gradescope.run``) and
the nbgrader course (``autograder.channels.nbgrader.grade``) each make one ``GradingRun`` and call
``grade`` on it; none of them builds a result, a sandbox or hidden inputs of its own::

    with GradingRun(config, hide=[out, *submission_folders]) as run:
        run.open()                               # hidden inputs, then the canary (the answer key)
        result = run.grade(path, student_id="alice")   # finished and stamped SubmissionResult

A run owns, for its whole life:

- the configuration (``GradingConfig``) and its record (``autograder.inputs.config.configuration``),
  which the hidden plugin stamps on every result with the sandbox level and the submission's
  draw, so a result is built once, by the plugin, and never amended;
- the hidden inputs and their cache (a private 0700 folder of the grader's, hidden from
  student code, written once): the inputs, which hold the configuration, saved with the record
  in one file (``autograder.inputs.build.save``), so the plugin, given ``--hidden-cache`` alone,
  reads the one configuration of the run from one place; and the keep that
  holds them and the draws between runs when one is named (``autograder.inputs.keep``);
- the sandboxes (one per concurrent grading, opened when first needed, each hiding the same one
  list: ``hidden_paths``), and the grading workers (``autograder.grading.workers.WorkerPool``);
- the session budget (``autograder.grading.budget``), handed to the plugin as ``--budget``;
- the canary: the answer key graded once, in a sandbox of the run, before anything else, on the
  secret's own scenes (the run's hidden inputs) rather than a draw of its own;
- whether the unscored picture step runs after a submission's checks (``pictures``): its record
  comes back on the result (``SubmissionResult.pictures``) for feedback.html or Gradescope's
  picture tests.  The canary never runs it.

Set-up may be interrupted anywhere (KeyboardInterrupt, raised in the main thread by a signal
handler): what was started is killed and removed, nothing is graded.  ``close`` (or leaving the
``with``) stops the workers and removes the sandboxes and the cache.
"""

from __future__ import annotations

import atexit
import json
import os
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path

from core.paths import KIT_ROOT

from . import canary
from .budget import backstop_of, budget_of, too_late
from autograder.inputs.config import GradingConfig, configuration, load_config, tests_fingerprint
from .grade import run_session
from autograder.inputs import build as inputs
from autograder.inputs.build import HiddenInputs, build_hidden_inputs
from autograder.inputs.keep import Keep, default_keep
from autograder.feedback.results import SubmissionResult
from autograder.sandbox import ResourceLimits, Sandbox, leftovers
from .workers import WorkerPool

__all__ = ["GradingRun", "hidden_paths", "open_sandbox"]


def hidden_paths(*paths) -> list[Path]:
    """The one list of what student code must not see beyond what the sandbox always hides (the
    grader, the solutions, the answer key): ``paths`` (None skipped), resolved, without
    duplicates, never the root nor a folder holding the Python the sandbox runs (hiding it
    would stop every job)."""
    python = {Path(sys.prefix).resolve(), Path(sys.base_prefix).resolve()}
    out = []
    for p in paths:
        if p is None:
            continue
        p = Path(p).resolve()
        if p != Path("/") and not any(p == d or p in d.parents for d in python):
            out.append(p)
    return list(dict.fromkeys(out))


def open_sandbox(*, kit_root: Path = KIT_ROOT, hidden: Sequence[Path] = (), isolation: str = "auto",
                 limits: ResourceLimits | None = None, attempts: int = 3, allow_weak: bool = False) -> Sandbox:
    """A Sandbox for grading; with "auto" as root, retried when it comes up weaker than namespaces.

    As root the namespaces level normally works, so a weaker one means its probe failed for a
    passing reason (a loaded machine, a uid clash with another grader); a weaker sandbox is
    accepted after ``attempts`` tries, with a warning on stderr.
    """
    options = {"limits": limits} if limits is not None else {}
    for attempt in range(attempts):
        box = Sandbox(kit_root, hidden=hidden, isolation=isolation, allow_weak=allow_weak, **options)
        if isolation != "auto" or os.geteuid() != 0 or box.isolation.level in ("namespaces", "uid"):
            return box
        if attempt == attempts - 1:
            print(f"warning: the sandbox runs at the {box.isolation.level} level ({'; '.join(box.isolation.notes)})",
                  file=sys.stderr)
            return box
        box.close()
        time.sleep(1.0 + attempt)
    raise AssertionError("unreachable")


class GradingRun:
    """Grading set up once: configuration, hidden inputs, sandboxes, workers, budget, canary.

    Parameters
    ----------
    config : ``GradingConfig`` (default ``load_config()``), the one the results record.
    hidden_inputs : the hidden inputs to grade with (default: built from ``config``); Gradescope
        passes its bundled ones with its calibrated ``time_scale``.
    hide : folders student code must not see (outputs, submissions, the config's folder...);
        the config's own file and official data are added.  ``extra_tests`` are hidden too.
    extra_tests : an instructor's test files or folders run beside ``autograder/hidden``.
    isolation, limits, allow_weak : the sandbox's level, ``ResourceLimits`` and whether a level
        running student code as the grader's own user is accepted.
    kit_root : what the sandbox imports the kit from (Gradescope: its unpacked bundle).
    deadline : ``time.monotonic()`` by which every submission's grading must end (Gradescope's
        time limit; the canary is not held to it).
    key : the answer-key submission the canary grades (default: written now).
    sandbox : an existing Sandbox to grade in (not closed by the run; tests and tools only).
    pictures : run the unscored picture step after each submission's checks (``autograder.feedback.pictures``,
        the hidden plugin's ``--pictures``); each result then carries its record
        (``SubmissionResult.pictures``).  ``grade(..., pictures=...)`` decides for one call.  The
        canary never runs it.
    keep : a folder of the grader's own where hidden inputs and draws made once are kept for the
        next runs (``autograder.inputs.keep``; default ``$HW4_KEEP_INPUTS``, else none); hidden
        from student code.

    Attributes: ``record`` (the configuration record, isolation not yet known), ``hidden``
    (the hidden inputs, once made), ``timing`` (seconds of each set-up step, for staff),
    ``canary_report`` (``canary.CanaryReport`` once the canary passed), ``canaries`` (how
    many times the key was graded: at most once).
    """

    def __init__(self, config: GradingConfig | None = None, *, hidden_inputs: HiddenInputs | None = None,
                 hide: Sequence[str | os.PathLike | None] = (), extra_tests: Sequence[str | os.PathLike] = (),
                 isolation: str = "auto", limits: ResourceLimits | None = None, allow_weak: bool = False,
                 kit_root: str | os.PathLike = KIT_ROOT, deadline: float | None = None,
                 key: str | os.PathLike | None = None, sandbox: Sandbox | None = None, pictures: bool = False,
                 keep: str | os.PathLike | None = None):
        self.config = config if config is not None else load_config()
        self.extra_tests = [Path(p).resolve() for p in extra_tests]
        self.record = configuration(self.config, tests=tests_fingerprint(self.extra_tests))
        self.hidden = hidden_inputs
        self.keep = Keep(keep) if keep is not None else default_keep()
        self.hide = hidden_paths(*hide, self.config.source, self.config.official_dir(), *self.extra_tests,
                                 self.keep.folder if self.keep is not None else None)
        self.isolation, self.limits, self.allow_weak = isolation, limits, allow_weak
        self.kit_root = Path(kit_root)
        self.deadline = deadline
        self.pictures = bool(pictures)
        self.key = Path(key) if key is not None else None
        self.timing: dict = {}
        self.canary_report: canary.CanaryReport | None = None
        self.canaries = 0
        self.pool = WorkerPool()
        self._given = sandbox
        self._boxes: list[Sandbox] = []      # every sandbox of the run (to kill its uids on Ctrl-C)
        self._idle: list[Sandbox] = []       # those not grading now
        self._specs: dict[int, Path] = {}    # id(box) -> its describe() in the cache folder
        self._lock = threading.Lock()
        self._cache = self._cache_fd = None
        self._owner = os.getpid()
        self._closed = False

    # -- set-up ----------------------------------------------------------------------------------

    def __enter__(self) -> GradingRun:  # noqa: PYI034 - Self needs Python 3.11
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def open(self, *, canary: bool = True) -> GradingRun:
        """Make the hidden inputs, then (``canary``) grade the answer key; returns the run.

        Raises ``autograder.grading.canary.CanaryFailed`` when the key loses a point here.  Interrupted
        (KeyboardInterrupt), it stops where it is and removes what it started."""
        self.make_inputs()
        if canary:
            self.run_canary()
        return self

    def make_inputs(self) -> HiddenInputs:
        """The hidden inputs, made (once) and written with the run's ``record`` into its private cache folder."""
        if self._cache is not None:
            return self.hidden
        try:
            t = time.monotonic()
            if self.hidden is None:
                self.hidden = build_hidden_inputs(self.config, keep=self.keep)
            self.timing["hidden_inputs_seconds"] = round(time.monotonic() - t, 3)
            folder, fd = leftovers.owned_folder("hw4-hidden-")  # 0700; a sweep removes it if we are killed
            self._cache, self._cache_fd = folder, fd
            atexit.register(self._release_cache)
            inputs.save(self.hidden, folder, record=self.record)
            self.pool.warm()  # its imports overlap the rest of the set-up
        except BaseException:
            self.close()
            raise
        return self.hidden

    def run_canary(self) -> canary.CanaryReport:
        """Grade the answer key (once per run) in a sandbox of this run; ``CanaryFailed`` unless full marks."""
        if self.canary_report is not None:
            return self.canary_report
        self.make_inputs()
        t = time.monotonic()
        try:
            box = self._take_sandbox()
            try:
                self.canaries += 1
                # The key gets the full budget: the deadline is the submission's (on Gradescope a
                # short time limit must end the student's session, not fail the canary).  Nor does
                # it draw pictures: the canary checks the grading, not the feedback.
                # It grades on the secret's own scenes, which the run has made already: the key
                # proves the environment, and a draw of its own would cost every run its making.
                self.canary_report = canary.check(
                    lambda path, **kw: self._grade_in(box, Path(path), deadline=None, pictures=False,
                                                      secret_scenes=True, **kw), box, key=self.key)
            finally:
                self._give_back(box)
        except BaseException:
            self.timing["canary_seconds"] = round(time.monotonic() - t, 3)
            if not isinstance(sys.exc_info()[1], Exception):  # interrupted: nothing left running
                self.close()
            raise
        self.timing["canary_seconds"] = round(time.monotonic() - t, 3)
        return self.canary_report

    @property
    def level(self) -> str | None:
        """The isolation level of the run's sandboxes (None before the first one is open)."""
        box = self._given or (self._boxes[0] if self._boxes else None)
        return box.isolation.level if box is not None else None

    def session_budget(self, limits: ResourceLimits | None = None) -> float:
        """Seconds of one submission's session now (``autograder.grading.budget.budget_of``)."""
        return budget_of(self.make_inputs(), limits or self.limits or ResourceLimits(), self.deadline)

    def sandboxes(self) -> list[Sandbox]:
        """Every sandbox the run opened (its own and the one it was given)."""
        with self._lock:
            return list(self._boxes) + ([self._given] if self._given is not None else [])

    # -- grading ---------------------------------------------------------------------------------

    def grade(self, path: str | os.PathLike, *, student_id: str | None = None,
              staff: dict | None = None, pictures: bool | None = None) -> SubmissionResult:
        """The finished, stamped ``SubmissionResult`` of the submission at ``path`` (folder or .zip).

        ``pictures`` (default: the run's): run the unscored picture step after the checks; the
        result then carries its record (``SubmissionResult.pictures``, else None).

        Thread-safe: concurrent calls grade in sandboxes and workers of their own.  ``staff``
        (optional dict) receives what only staff may see: ``log`` (notes, tracebacks),
        ``stdout``, ``stderr``, ``spawns``, ``swept``, ``removed`` (with ``not_removed``), ``over_quota``,
        ``survived``.  Never raises for what the submission contains or does (an unreadable one is
        a failed result); RuntimeError when the grading process itself broke.
        """
        if self._closed:
            raise RuntimeError("grade: this grading run is closed")
        self.make_inputs()
        box = self._take_sandbox()
        try:
            return self._grade_in(box, Path(path), student_id=student_id, staff=staff, deadline=self.deadline,
                                  pictures=self.pictures if pictures is None else bool(pictures))
        finally:
            self._give_back(box)

    def failed(self, reason: str, *, student_id: str | None = None,
               execution_time: float | None = None) -> SubmissionResult:
        """A zero that says why (``reason``) for a submission this run could not grade, stamped
        like every result of the run (its configuration, the sandbox level when known)."""
        box = self._given or (self._boxes[0] if self._boxes else None)
        isolation = box.isolation.as_dict() if box is not None else None
        return SubmissionResult.failed(reason, student_id=student_id, isolation=isolation,
                                       execution_time=execution_time,
                                       configuration={**self.record, "isolation": self.level, "draw": None})

    def _grade_in(self, box: Sandbox, path: Path, *, deadline: float | None, pictures: bool,
                  student_id: str | None = None, staff: dict | None = None,
                  secret_scenes: bool = False) -> SubmissionResult:
        staff = staff if staff is not None else {}
        staff.setdefault("log", [])
        path = path.resolve()
        late = too_late(deadline)
        if late is not None:
            # Not an internal error: the grader is sound, the platform's clock ran out first.
            staff["log"].append(f"not graded: {late}")
            return self.failed(late, student_id=student_id or path.name)
        limits = box.limits
        budget = budget_of(self.hidden, limits, deadline)
        # The cache describes itself (the inputs, their config and the run's record): no other
        # option names a configuration the session could read differently.
        options = ["--hidden-cache", str(self._cache), "--sandbox-spec", str(self._spec(box)),
                   f"--student-id={student_id or path.name}", "--budget", repr(budget),
                   *(["--secret-scenes"] if secret_scenes else []),
                   *(["--keep", str(self.keep.folder)] if self.keep is not None else [])]
        result, got = run_session(self.pool, path, folder=self._cache, options=options,
                                  timeout=backstop_of(self.hidden, limits, deadline),
                                  extra_tests=self.extra_tests, pictures=pictures)
        staff["log"] += list(got.pop("log", []))
        staff.update(got)
        return result

    # -- sandboxes -------------------------------------------------------------------------------

    def _take_sandbox(self) -> Sandbox:
        if self._given is not None:
            return self._given
        with self._lock:
            if self._idle:
                return self._idle.pop()
        box = open_sandbox(kit_root=self.kit_root, hidden=self.hide, isolation=self.isolation, limits=self.limits,
                           allow_weak=self.allow_weak)
        with self._lock:
            self._boxes.append(box)
        return box

    def _give_back(self, box: Sandbox) -> None:
        if box is self._given:
            return
        with self._lock:
            if not self._closed:
                self._idle.append(box)

    def _spec(self, box: Sandbox) -> Path:
        # The sandbox as the plugin attaches it (plain JSON in the run's 0700 folder), written once.
        with self._lock:
            path = self._specs.get(id(box))
            if path is None:
                path = self._specs[id(box)] = self._cache / f"sandbox-{len(self._specs)}.json"
                path.write_text(json.dumps(box.describe()))
            return path

    # -- the end ---------------------------------------------------------------------------------

    def close(self) -> None:
        """Stop the workers, remove the run's sandboxes and its cache (idempotent)."""
        with self._lock:
            self._closed = True
            boxes, self._boxes, self._idle = list(self._boxes), [], []
        self.pool.close()
        if os.getpid() == self._owner:
            for box in boxes:
                box.close()
        self._release_cache()

    def _release_cache(self) -> None:
        if os.getpid() != self._owner:  # a forked child that exits runs atexit too: not its folder
            return
        folder, fd, self._cache, self._cache_fd = self._cache, self._cache_fd, None, None
        if folder is not None:
            leftovers.release(folder, fd)
            atexit.unregister(self._release_cache)

