"""A grading worker: the hidden checks' pytest sessions, one submission after another, in one process.

    python -m autograder.hidden.worker FD

Reads one JSON request per line on stdin, ``{"argv": [...], "log": PATH}``, runs
``pytest.main(argv)`` (a fresh pytest session each time, in this same process: numpy, the
judgments and the hidden inputs are imported and loaded once, not once per submission) with its
output written to ``log``, and answers on file descriptor FD with one JSON line ``{"exit": code}``.
Ends at the end of stdin.  Started and fed by ``autograder.grading.workers`` (one worker per concurrent
grading), never by student code: the student's functions run in the sandbox's own processes.
"""

from __future__ import annotations

import json
import os
import sys


def _run(argv: list[str], log: str) -> int:
    import pytest

    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        return int(pytest.main(list(argv)))
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for f in (fd, *saved):
            os.close(f)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1 or not argv[0].isdigit():
        raise SystemExit(f"usage: python -m autograder.hidden.worker FD (got {argv!r})")
    answers = os.fdopen(int(argv[0]), "w", buffering=1)
    # Warm up while the grader gets ready (the first request would pay for these imports).
    import pytest  # noqa: F401
    import autograder.inputs.cases  # noqa: F401
    import autograder.hidden.plugin  # noqa: F401
    import autograder.submission.read  # noqa: F401

    for line in sys.stdin:
        request = json.loads(line)
        try:
            code = _run(request["argv"], request["log"])
        except Exception as exc:  # noqa: BLE001 - reported to the grader, which fails this submission
            answers.write(json.dumps({"exit": -1, "error": f"{type(exc).__name__}: {exc}"}) + "\n")
            continue
        answers.write(json.dumps({"exit": code}) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
