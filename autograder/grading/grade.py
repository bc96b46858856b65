"""One pytest session of the hidden checks (``autograder/hidden``) on one submission, in a grading worker.

``pytest_command`` is the session's arguments; ``run_session`` runs them in a worker
(``autograder.grading.workers.GradingWorker``) and reads back what the plugin wrote: the finished,
stamped ``SubmissionResult`` as plain JSON (never a pickle: the plugin ran beside the student's
sandbox) and what only staff may see.  Everything around one session (the configuration, the
sandbox, the hidden inputs, the budget, the canary) is the grading run's
(``autograder.grading.run.GradingRun``), which every channel grades through.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

from autograder.feedback.results import SubmissionResult

__all__ = ["HIDDEN_DIR", "pytest_command", "run_session"]

HIDDEN_DIR = Path(__file__).resolve().parents[1] / "hidden"


def pytest_command(submission: Path, *, extra_tests: Sequence[Path] = (), options: Sequence[str] = ()) -> list[str]:
    """pytest's arguments (after ``python -m pytest``) that grade ``submission`` with the hidden checks
    (and ``extra_tests``).  Values a student names (the submission, its gradebook name) are joined
    to their option with "=": a separate "-1+1" would be read as an option, "@SUM" as a file of
    arguments (pytest's @file)."""
    # No unraisable-exception plugin: it forces two full garbage collections at the end of every
    # session (a seventh of the worker's time per submission), and the student's code, whose
    # finalizers it would report, never runs in the worker.
    return ["-q", "-W", "ignore::pytest.PytestAssertRewriteWarning", "-p", "no:cacheprovider",
            "-p", "no:unraisableexception", "-p", "autograder.hidden.plugin",
            "-c", str(HIDDEN_DIR / "pytest.ini"), "--rootdir", str(HIDDEN_DIR), "--no-header", "-o",
            "console_output_style=classic", str(HIDDEN_DIR), *[str(p) for p in extra_tests],
            f"--submission={submission}", *options]


def run_session(pool, submission: Path, *, folder: Path, options: Sequence[str], timeout: float,
                extra_tests: Sequence[Path] = (), pictures: bool = False) -> tuple[SubmissionResult, dict]:
    """``(result, staff)`` of one pytest session on ``submission``, run by a worker of ``pool``
(``autograder.grading.workers.WorkerPool``).

    ``folder``: the run's private folder (0700), where this session's files live and are removed
    after; ``options``: the run's plugin options (``--hidden-cache``, which holds the run's
    configuration and record, ``--sandbox-spec``, ``--student-id=``, ``--budget``); ``timeout``: seconds
    before the worker is given up on; ``pictures``: the unscored picture step runs after the checks
    (``--pictures``) and the result carries its record (``SubmissionResult.pictures``: question ->
    the picture the worker drew, or the sentence why not; None when not asked for).  Raises RuntimeError when the session itself broke (the
    worker died, took too long or pytest failed).  A worker whose session was interrupted (Ctrl-C)
    or broke is killed with the sandboxes it started, never given back to the pool.
    """
    work = Path(tempfile.mkdtemp(prefix="run-", dir=folder))
    try:
        results, log = work / "results.json", work / "pytest.log"
        argv = pytest_command(submission, extra_tests=extra_tests,
                              options=[*options, *(["--pictures"] if pictures else []), "--results", str(results)])
        worker = pool.take()
        try:
            code = worker.run(argv, log, timeout)
        except BaseException:
            # Interrupted (Ctrl-C in the main thread) or broken: the session is abandoned, and its
            # worker with its sandboxes is not left grading on unwatched.
            worker.kill()
            raise
        pool.give_back(worker)
        if code not in (0, 1, 5) or not results.is_file():  # 5: no check ran (an unreadable submission)
            tail = log.read_text(errors="replace")[-4000:] if log.is_file() else ""
            raise RuntimeError(f"the grading process failed (exit code {code}):\n{tail}")
        data = json.loads(results.read_text())
    finally:
        shutil.rmtree(work, ignore_errors=True)
    picture_record = dict(data.get("pictures") or {}) if pictures else None
    return SubmissionResult.from_dict(data["result"], pictures=picture_record), dict(data.get("staff", {}))
