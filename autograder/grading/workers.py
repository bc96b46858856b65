"""Grading workers: ``autograder.hidden.worker`` processes that run one pytest session after another.

A ``WorkerPool`` belongs to one grading run (``autograder.grading.run.GradingRun``), never to the module:
the run starts its workers, lends one to each grading, and stops them all when it closes.  A
process that forks (a test's process pool) therefore inherits no list of workers to talk to;
only the pool's owner (the pid that made it) stops them.
"""

from __future__ import annotations

import json
import os
import selectors
import subprocess
import sys
import threading
from pathlib import Path

from core.paths import KIT_ROOT

__all__ = ["GradingWorker", "WorkerPool"]


class GradingWorker:
    """One ``autograder.hidden.worker`` process: pytest sessions run on request, one at a time."""

    def __init__(self):
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(KIT_ROOT), os.environ.get("PYTHONPATH", "")]),
               "PYTHONDONTWRITEBYTECODE": "1"}
        for var in ("PYTEST_ADDOPTS", "HW4_GRADER_SECRET", "HW4_GRADER_CONFIG"):
            env.pop(var, None)  # the settings are the run's, in the files it writes
        # The hidden inputs' arrays are small: a BLAS thread pool per worker only makes the workers of
        # a --jobs N batch fight over the cores (a class of 30 took 105 s at --jobs 2 with it, see docs/benchmarks.md).
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


class WorkerPool:
    """The idle workers of one run: ``take`` one per grading, ``give_back`` it after, ``close`` at the end.

    A worker whose run was interrupted or broke is killed by the caller (``GradingWorker.kill``),
    never given back: it may still be grading.
    """

    def __init__(self, make=GradingWorker):
        self._make = make
        self._idle: list = []
        self._lock = threading.Lock()
        self._owner = os.getpid()
        self.started = 0   # workers started, for the run's figures

    def warm(self) -> None:
        """Start a worker now (its imports overlap the run's own set-up) unless one is waiting."""
        with self._lock:
            if not any(w.alive() for w in self._idle):
                self._idle.append(self._new())

    def take(self):
        with self._lock:
            while self._idle:
                worker = self._idle.pop()
                if worker.alive():
                    return worker
                worker.stop()
            return self._new()

    def give_back(self, worker) -> None:
        with self._lock:
            self._idle.append(worker)

    def close(self) -> None:
        """Stop the idle workers (only in the process that started them: a forked child's copy
        of the pool is not its own)."""
        with self._lock:
            workers, self._idle = self._idle, []
        if os.getpid() != self._owner:
            return
        for worker in workers:
            worker.stop()

    def _new(self):
        self.started += 1
        return self._make()
