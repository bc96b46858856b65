"""Grading one submission: the hidden checks (``autograder/hidden``, pytest tests) run on it.

``grade_submission`` runs ``pytest autograder/hidden --submission PATH`` (``pytest_command``) in a
grading worker of the grader (``autograder.hidden.worker``: a process that runs one pytest session
after another, so imports and the hidden inputs are loaded once per worker, not per submission;
one worker per concurrent grading, kept for the next submission), with the plugin of
``autograder/hidden/plugin.py``: the student's code is loaded once in a session of the grader's
sandbox (attached, not probed again), every check is a pytest test calling it, and the plugin
writes the ``SubmissionResult`` as JSON into a folder of the grader's own.  The hidden inputs are
made once per batch and cached in that folder (mode 0700, hidden from the sandbox).  The CLI
(``autograder.batch``), Gradescope (``autograder.gradescope``) and the nbgrader course
(``autograder.nbgrader_course``) all grade through this function, so they run the same tests.
"""

from __future__ import annotations

import atexit
import json
import os
import selectors
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path

from .hidden import inputs
from .hidden.inputs import HiddenInputs
from .results import SubmissionResult
from .sandbox import ResourceLimits, Sandbox, leftovers

__all__ = ["HIDDEN_DIR", "KIT_ROOT", "grade_submission", "pytest_command"]

KIT_ROOT = Path(__file__).resolve().parents[1]
HIDDEN_DIR = Path(__file__).resolve().with_name("hidden")
_RESTARTS_BUDGETED = 3      # crashes or timeouts after which the session's time is still enough
_MARGIN = 120.0             # seconds a pytest run may take beyond the session's budget (imports, judging)
_DEADLINE_RESERVE = 30.0   # seconds kept before a deadline for judging what ran and writing the results

_caches: dict[int, tuple[HiddenInputs, Path]] = {}
_caches_lock = threading.Lock()
_idle: list = []                   # grading workers (_Worker) waiting for a submission
_idle_lock = threading.Lock()


def _private_folder(prefix: str) -> Path:
    # Mode 0700, its owner recorded, so that a sweep removes it if this process is killed.
    folder, fd = leftovers.owned_folder(prefix)
    owner = os.getpid()

    def release() -> None:
        if os.getpid() == owner:  # a forked child that exits normally runs this too: not its folder
            leftovers.release(folder, fd)

    atexit.register(release)
    return folder


def _forget_in_child() -> None:
    # A forked child (a process pool of the kit's tests, say) inherits the lists of this process's
    # grading workers and hidden folders: it must neither talk to those workers nor reuse the
    # folders, whose owner is the parent.  It starts its own when it grades.
    global _caches_lock, _idle_lock
    _caches_lock, _idle_lock = threading.Lock(), threading.Lock()  # a parent's thread may have held them
    _caches.clear()
    _idle.clear()


os.register_at_fork(after_in_child=_forget_in_child)


def hidden_cache(hidden: HiddenInputs) -> Path:
    """The folder (0700, the grader's own) holding ``hidden`` for grading processes; written once."""
    with _caches_lock:
        found = _caches.get(id(hidden))
        if found is None or found[0] is not hidden:
            folder = _private_folder("hw4-hidden-")
            inputs.save(hidden, folder)
            found = _caches[id(hidden)] = (hidden, folder)
            _warm_worker()
        return found[1]


def budget_of(hidden: HiddenInputs, limits: ResourceLimits | None = None, deadline: float | None = None) -> float:
    """Wall-clock seconds of one submission's session: every check's time, loading and restarts.

    Under the CPU clock (``limits.clock == "cpu"``, Gradescope) the checks' seconds are CPU
    seconds, which take 1 / ``limits.cpu_share`` wall-clock seconds where the code gets only a
    share of a CPU: that part grows by as much, so that a slow container is never cut short by
    this wall-clock backstop before its CPU limits.  Loading is limited in wall-clock seconds
    (``load_timeout``) whatever the clock.  With a ``deadline`` (``time.monotonic()``, see
    ``grade_submission``) the session ends ``_DEADLINE_RESERVE`` seconds before it, if sooner.
    """
    stretch = limits.wall_per_cpu if limits is not None else 1.0
    budget = (hidden.call_seconds() + 30) * stretch + hidden.config.load_timeout * (1 + _RESTARTS_BUDGETED)
    if deadline is not None:
        budget = max(min(budget, deadline - time.monotonic() - _DEADLINE_RESERVE), 1.0)
    return budget


class _Worker:
    """One ``autograder.hidden.worker`` process: pytest sessions run on request, one at a time."""

    def __init__(self):
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(KIT_ROOT), os.environ.get("PYTHONPATH", "")]),
               "PYTHONDONTWRITEBYTECODE": "1"}
        for var in ("PYTEST_ADDOPTS", "HW4_GRADER_SECRET", "HW4_GRADER_CONFIG"):
            env.pop(var, None)  # the settings are the batch's, in config.json
        # The hidden inputs' arrays are small: a BLAS thread pool per worker only makes the workers of
        # a --jobs N batch fight over the cores (a class of 30 took 105 s at --jobs 2 with it, see README).
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            env.setdefault(var, "1")
        r, w = os.pipe()
        try:
            self.proc = subprocess.Popen([sys.executable, "-m", "autograder.hidden.worker", str(w)], cwd=str(KIT_ROOT),
                                         env=env, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                         stderr=subprocess.DEVNULL, pass_fds=(w,), text=True)
        finally:
            os.close(w)
        self.answers = os.fdopen(r, "r")

    def alive(self) -> bool:
        return self.proc.poll() is None

    def run(self, argv: list[str], log: Path, timeout: float) -> int:
        """pytest's exit code of ``argv``; RuntimeError when the worker died or took over ``timeout`` s."""
        try:
            self.proc.stdin.write(json.dumps({"argv": argv, "log": str(log)}) + "\n")
            self.proc.stdin.flush()
        except OSError as exc:
            self.stop()
            raise RuntimeError(f"the grading worker could not be reached ({exc})") from None
        with selectors.DefaultSelector() as sel:
            sel.register(self.answers, selectors.EVENT_READ)
            if not sel.select(timeout):
                self.stop()
                raise RuntimeError(f"the grading process took more than {timeout:g} s")
        line = self.answers.readline()
        if not line:
            self.stop()
            raise RuntimeError(f"the grading worker ended (exit code {self.proc.returncode})")
        answer = json.loads(line)
        if "error" in answer:
            raise RuntimeError(f"the grading worker failed: {answer['error']}")
        return int(answer["exit"])

    def kill(self) -> None:
        """End the process now (SIGKILL), whatever it is running."""
        if self.alive():
            self.proc.kill()
        self.proc.wait()
        self.answers.close()

    def stop(self) -> None:
        """End the process (gently: end of its input; killed if it does not end in 5 s)."""
        if self.alive():
            try:
                self.proc.stdin.close()
                self.proc.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
        self.proc.wait()
        self.answers.close()


def _warm_worker() -> None:
    """Start a worker now (its imports overlap the grader's own setup) unless one is waiting."""
    with _idle_lock:
        if not any(w.alive() for w in _idle):
            _idle.append(_Worker())


def _take_worker() -> _Worker:
    with _idle_lock:
        while _idle:
            worker = _idle.pop()
            if worker.alive():
                return worker
            worker.stop()
    return _Worker()


@atexit.register
def _stop_workers() -> None:
    with _idle_lock:
        workers = list(_idle)
        _idle.clear()
    for worker in workers:
        worker.stop()


def pytest_command(submission: Path, *, extra_tests: Sequence[Path] = (), options: Sequence[str] = ()) -> list[str]:
    """pytest's arguments (after ``python -m pytest``) that grade ``submission`` with the hidden checks
    (and ``extra_tests``).  Values a student names (the submission, its gradebook name) are joined
    to their option with "=": a separate "-1+1" would be read as an option, "@SUM" as a file of
    arguments (pytest's @file)."""
    return ["-q", "-W", "ignore::pytest.PytestAssertRewriteWarning", "-p", "no:cacheprovider", "-p", "autograder.hidden.plugin",
            "-c", str(HIDDEN_DIR / "pytest.ini"), "--rootdir", str(HIDDEN_DIR), "--no-header", "-o",
            "console_output_style=classic", str(HIDDEN_DIR), *[str(p) for p in extra_tests],
            f"--submission={submission}", *options]


def grade_submission(path: str | os.PathLike, *, sandbox: Sandbox, hidden_inputs: HiddenInputs,
                     student_id: str | None = None, staff: dict | None = None,
                     extra_tests: Sequence[str | os.PathLike] = (), deadline: float | None = None,
                     pictures: dict | None = None) -> SubmissionResult:
    """Grade the submission at ``path`` (a folder or .zip of notebooks or .py files).

    Parameters
    ----------
    path : the submission.
    sandbox : the grader's Sandbox (its sessions run the student's code; reusable).
    hidden_inputs : from ``autograder.hidden.inputs.build_hidden_inputs(config)``.
    student_id : the name for the gradebook (default: the file or folder name; ``autograder.batch``
        gives its own).
    staff : optional dict that receives what only staff should see: ``stdout``, ``stderr``,
        ``log`` (grader notes and tracebacks), ``spawns`` and ``swept`` (child processes started,
        processes killed after the session).
    extra_tests : more test files or folders to run beside ``autograder/hidden`` (an instructor's).
    deadline : ``time.monotonic()`` by which grading must be over (Gradescope's time limit): the
        session's budget shrinks to end ``_DEADLINE_RESERVE`` seconds before it, so that the checks
        that ran are reported rather than lost to the platform's kill.
    pictures : optional dict: when given, the unscored picture step runs after the checks
        (``autograder.pictures``) and this dict receives its raw record (question -> the picture
        the worker drew, or the sentence why not), for ``autograder.pictures.figures_of``.

    Returns
    -------
    SubmissionResult: one QuestionResult per question with checks, or a failed result (worth
    zero, saying why) when the submission cannot be read.  Never raises for anything the
    submission contains or does; RuntimeError when the grading process itself broke.
    """
    start = time.monotonic()
    staff = staff if staff is not None else {}
    staff.setdefault("log", [])
    path = Path(path).resolve()
    student_id = student_id or path.name
    isolation = sandbox.isolation.as_dict()
    cache = hidden_cache(hidden_inputs)
    work = Path(tempfile.mkdtemp(prefix="run-", dir=cache))
    try:
        spec = work / "sandbox.json"
        spec.write_text(json.dumps(sandbox.describe()))
        results = work / "results.json"
        config_file = work / "config.json"
        config_file.write_text(json.dumps(hidden_inputs.config.to_dict()))
        budget = budget_of(hidden_inputs, sandbox.limits, deadline)
        backstop = budget_of(hidden_inputs, sandbox.limits) + _MARGIN * sandbox.limits.wall_per_cpu
        if deadline is not None:
            backstop = max(min(backstop, deadline - time.monotonic() - 5.0), budget)
        argv = pytest_command(path, extra_tests=[Path(p).resolve() for p in extra_tests], options=[
            "--grading-config", str(config_file), "--hidden-cache", str(cache), "--sandbox-spec", str(spec),
            "--results", str(results), f"--student-id={student_id}", "--budget", repr(budget),
            *(["--pictures"] if pictures is not None else [])])
        log = work / "pytest.log"
        worker = _take_worker()
        try:
            code = worker.run(argv, log, backstop)
        except BaseException:
            # Interrupted (Ctrl-C in the main thread): the run is abandoned, its worker and the
            # worker's sandboxes (killed with their parent) are not left grading on unwatched.
            worker.kill()
            raise
        with _idle_lock:
            _idle.append(worker)
        if code not in (0, 1, 5) or not results.is_file():  # 5: no check ran (an unreadable submission)
            tail = log.read_text(errors="replace")[-4000:] if log.is_file() else ""
            raise RuntimeError(f"the grading process failed (exit code {code}):\n{tail}")
        data = json.loads(results.read_text())
    finally:
        shutil.rmtree(work, ignore_errors=True)
    got = data.get("staff", {})
    if pictures is not None:
        pictures.update(data.get("pictures") or {})
    staff["log"] += list(got.get("log", []))
    staff.update({k: v for k, v in got.items() if k != "log"})
    result = SubmissionResult.from_dict(data["result"])
    if result.failure:  # unreadable, or no notebook of the homework (checked by the plugin)
        return SubmissionResult.failed(result.failure, student_id=student_id, isolation=isolation,
                                       execution_time=time.monotonic() - start)
    return SubmissionResult(result.questions, student_id, result.isolation or isolation, result.notes, None,
                            time.monotonic() - start, result.configuration)  # {"draw": digest}
