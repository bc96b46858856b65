"""The canary: before a batch grades anyone, the answer key is graded in the batch's own sandbox.

Every channel (``python -m autograder grade``, Gradescope's ``run_autograder``, the nbgrader
course) grades through one ``autograder.grading.run.GradingRun``, which calls :func:`check` once, with
its own grading function and the Sandbox it is about to grade with.  The answer key (``autograder.grading.key``) must get full marks on every check there; if it does
not, the environment is broken for everyone (the sandbox's user cannot read the Python
environment, a package is missing, the machine is too slow for the limits...) and
:class:`CanaryFailed` is raised with what went wrong and how to fix it, so nothing is graded
instead of a whole class being graded wrong.  Grading the key costs one submission's time
(about 4 s).
"""

from __future__ import annotations

import os
import re
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from core.manifest import QUESTIONS, question

from .key import write_key_submission
from autograder.feedback.results import SubmissionResult
from autograder.sandbox import Sandbox, leftovers

__all__ = ["CANARY_ID", "CanaryFailed", "CanaryReport", "check"]

CANARY_ID = "answer-key-canary"
_TOL = 1e-6
# What the key's sandbox is asked to import when it failed, to name the cause.
_IMPORTS = ("numpy", "scipy", "matplotlib", "PIL", "core", "scenes", "starter", "judging")
_ENV_PROBE = '''\
import importlib, os, sys

def _canary_environment(names):
    failed = {}
    for name in names:
        try:
            importlib.import_module(name)
        except BaseException as exc:
            failed[name] = f"{type(exc).__name__}: {exc}"[:300]
    return {"uid": os.getuid(), "prefix": sys.prefix, "executable": sys.executable, "failed": failed}
'''


class CanaryFailed(RuntimeError, ValueError):
    """The answer key did not get full marks in the batch's sandbox: nothing may be graded.
    (A ValueError too, so that a command prints the message as an error, not a traceback.)"""


@dataclass(frozen=True)
class CanaryReport:
    """The key's grading: score and max_score (base points), seconds, the sandbox's isolation;
    totals: each autograded question's points as its checks add up (an instructor's extra check
    adds its points to its question's)."""

    score: float
    max_score: float
    seconds: float
    isolation: dict
    totals: dict = field(default_factory=dict)

    def points_changed(self) -> list[str]:
        """One line per question whose checks add up to other points than the handout's, with the
        new base total; empty when every question keeps its points."""
        lines = [f"{qid}: its checks add up to {total:g} points; the handout gives it {question(qid).points}"
                 for qid, total in self.totals.items() if abs(total - question(qid).points) > _TOL]
        if lines:
            handout = sum(q.points for q in QUESTIONS if not q.by_hand and not q.extra_credit)
            lines.append(f"the autograded base total (extra credit aside) is {self.max_score:g} points; "
                         f"the handout's is {handout}")
        return lines


def check(grade: Callable[..., SubmissionResult], sandbox: Sandbox, *,
          key: str | os.PathLike | None = None) -> CanaryReport:
    """Grade the answer key with ``grade`` in ``sandbox``; it must get every point of every check.

    Parameters
    ----------
    grade : ``grade(path, student_id=..., staff=...) -> SubmissionResult``, the run's own grading
        in ``sandbox`` (same configuration, hidden inputs and extra tests as every submission).
    sandbox : the Sandbox ``grade`` grades in (asked what it can import when the key failed).
    key : the answer-key submission (folder or .zip); default: written now by
        ``autograder.grading.key.write_key_submission`` into a private temporary folder (where the kit's
        notebooks/key or kit/ and solutions/ exist; a Gradescope bundle must ship the key).

    Raises
    ------
    CanaryFailed
        When the key lost any point, could not be graded, or grading it broke; the message
        names the checks that failed, the cause found and the fix.
    """
    start = time.monotonic()
    scratch = scratch_fd = None
    try:
        if key is None:
            scratch, scratch_fd = leftovers.owned_folder("hw4-canary-")  # 0700: the grader's own
            try:
                key = write_key_submission(scratch, zip_it=False)
            except Exception as exc:  # noqa: BLE001 - any failure to make the key stops the batch
                raise CanaryFailed(f"canary: the answer key could not be written ({type(exc).__name__}: {exc}); "
                                   f"give its path (python -m autograder key --out DIR makes it)") from exc
        key = Path(key)
        if not key.exists():
            raise CanaryFailed(f"canary: expected the answer-key submission at {key}, found nothing")
        staff: dict = {"log": []}
        try:
            result = grade(key, student_id=CANARY_ID, staff=staff)
        except Exception as exc:  # noqa: BLE001 - the grading process itself broke
            raise CanaryFailed(_message(sandbox, [f"grading it broke: {_tail(str(exc))}"], staff)) from exc
        lost = _lost(result)
        if lost:
            raise CanaryFailed(_message(sandbox, lost, staff, result))
        totals = {q.id: q.max_score for q in result.questions if q.tests and not q.by_hand}
        return CanaryReport(result.score, result.max_score, time.monotonic() - start, sandbox.isolation.as_dict(),
                            totals)
    finally:
        leftovers.release(scratch, scratch_fd)


def _lost(result: SubmissionResult) -> list[str]:
    """What the key did not get: one line per check short of full marks."""
    if result.failure:
        return [f"it was not graded: {result.failure}"]
    out = [f"{q.id} {t.name}: {t.score:g} / {t.max_score:g} ({_tail(t.feedback, 300)})"
           for q in result.questions for t in q.tests if t.score < t.max_score - _TOL]
    if not out and not any(q.tests for q in result.questions):
        out.append("no check ran")
    return out


def _message(sandbox: Sandbox, lost: list[str], staff: dict, result: SubmissionResult | None = None) -> str:
    iso = sandbox.isolation
    head = (f"canary: the answer key did not get full marks in this grader's sandbox (level {iso.level}, "
            f"uid {iso.uid if iso.uid is not None else 'of the grader'}), so nothing was graded. ")
    causes = _causes(sandbox, lost, staff, result)
    shown = lost[:6] + ([f"... and {len(lost) - 6} more"] if len(lost) > 6 else [])
    return head + " ".join(causes) + " What the key lost: " + "; ".join(shown)


def _causes(sandbox: Sandbox, lost: list[str], staff: dict, result: SubmissionResult | None) -> list[str]:
    text = "\n".join(lost + [str(x) for x in staff.get("log", [])] + [str(staff.get("stderr", ""))]
                     + (list(result.notes) if result is not None else []))
    causes: list[str] = []
    env = _environment(sandbox)
    failed = dict(env.get("failed", {})) if env else {}
    missing = sorted(set(re.findall(r"No module named '([\w.]+)'", text)) | set(failed))
    if env is None:
        causes.append("The sandbox could not even start a program (see the messages below).")
    if missing:
        prefix = Path(sys.prefix)
        real = prefix.resolve()
        blocked = _blocked(real) or _blocked(prefix)
        where = (f"the Python environment {prefix}" + (f" (really {real})" if real != prefix else "")
                 + f" as uid {env.get('uid') if env else sandbox.isolation.uid}")
        if blocked is not None:
            causes.append(f"The sandbox's user cannot import {', '.join(missing)}: it cannot read {where}, because "
                          f"{blocked} (mode {os.stat(blocked).st_mode & 0o777:o}) is closed to other users. Fix: "
                          f"`chmod 755 {blocked}` if nothing private is in it, or move the kit and its virtual "
                          f"environment to a public folder (not a `mktemp -d` folder, not under /root).")
        else:
            causes.append(f"The sandbox's user cannot import {', '.join(missing)} from {where}. Fix: install what "
                          f"is missing (pip install -r requirements.txt) and check that every folder of that "
                          f"environment is readable by other users.")
        if failed:
            causes.append("Import errors in the sandbox: " + "; ".join(f"{k}: {v}" for k, v in failed.items()))
    if re.search(r"took more than|used more than|used up its time|taking too long|time budget ran out|timed? ?out",
                 text) and not missing:
        causes.append("Checks ran out of time: the machine is too slow or too busy for the time limits "
                      "(use fewer --jobs, or raise the limits in the grading configuration).")
    if re.search(r"[Pp]ermission denied", text) and not missing:
        causes.append("Something the key needs is unreadable to the sandbox's user (Permission denied): check "
                      "the modes of the kit's data and of the Python environment.")
    if "internal error" in text and not missing:
        errors = [line.strip() for line in text.splitlines() if re.match(r"\s*(E\s+)?\w+(Error|Exception): ", line)]
        causes.append("The grader itself broke while grading the key (a bug in the grader or its tests, or a broken "
                      "install)" + (f": {_tail(errors[-1], 300)}" if errors else "") + ".")
    if not causes:
        causes.append("No known cause was found: read the key's feedback (python -m autograder key --out DIR "
                      "--grade) and the log below.")
    return causes


def _environment(sandbox: Sandbox) -> dict | None:
    """What the sandbox's user can import (asked only after a failure), or None when nothing ran."""
    try:
        with sandbox.session(_ENV_PROBE, load_timeout=30, budget=60) as session:
            out = session.call("_canary_environment", list(_IMPORTS), seconds=45)
    except Exception:  # noqa: BLE001 - diagnosis only
        return None
    return out.value if out.ok and isinstance(out.value, dict) else None


def _blocked(path: Path) -> Path | None:
    """The outermost folder on the way to ``path`` that other users cannot enter, if any."""
    for anc in reversed(path.parents):
        try:
            if anc != Path("/") and not os.stat(anc).st_mode & 0o001:
                return anc
        except OSError:
            return anc
    return None


def _tail(text: str, limit: int = 600) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else "[...] " + text[-limit:]
