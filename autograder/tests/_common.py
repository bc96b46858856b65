"""Tools shared by the hidden tests: reading what the sandbox sent back, scoring, wording feedback.

Everything a student's code returned is untrusted plain data (``autograder.wire`` decoded it):
any type, shape, dtype or NaN may come.  ``Outcome.items`` unpacks the helper's per-call records
(see ``_child_helpers.py``) and judging.verdict's readers (``as_array``, ``as_number``, ``parts``
here) turn values into float arrays or raise Malformed with a sentence for the student.  Nothing here mentions a hidden input's values.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any


from autograder.results import TestResult
from judging.verdict import Malformed, fmt, log_score, read_array, read_number, read_parts, share_score

__all__ = [
    "Item",
    "Malformed",
    "Outcome",
    "as_array",
    "as_number",
    "collapse",
    "first_problem",
    "fmt",
    "graded",
    "log_score",
    "mistake_note",
    "parts",
    "share_score",
    "tidy",
]

_MESSAGE_LIMIT = 300
_LONG_NUMBER = re.compile(r"-?\d+\.\d{4,}(?:e[+-]?\d+)?")
_NUMBER_RUN = re.compile(r"(?:-?\d[\d.e+-]*[\s,;]+){6,}-?\d[\d.e+-]*")


def tidy(message: str, limit: int = _MESSAGE_LIMIT) -> str:
    """A student's error message, shortened, with long runs of numbers cut.

    Student code sees the hidden inputs and could print them into an exception message; long
    numbers and lists of numbers are replaced so feedback cannot carry the inputs out.
    """
    text = _NUMBER_RUN.sub("[numbers]", str(message))
    text = _LONG_NUMBER.sub(lambda m: m.group(0)[: m.group(0).index(".") + 3], text)
    text = " ".join(text.split())
    return text if len(text) <= limit else text[:limit] + " [...]"


@dataclass(frozen=True)
class Item:
    """One call of a student function made by the in-sandbox helper: its value or its error."""

    ok: bool
    value: Any = None
    error: str = ""


class Outcome:
    """What became of one sandbox call (``CallOutcome``) of a helper, read defensively.

    ``problem`` is None when the helper ran and reported; otherwise a sentence saying why there
    is nothing to judge (function missing, timeout, crash ...), naming ``function``.
    """

    def __init__(self, call_outcome, function: str):
        self.function = function
        self.problem: str | None = None
        self.payload: dict = {}
        status = getattr(call_outcome, "status", "missing")
        if call_outcome is None:
            self.problem = f"{function} was not run"
        elif status != "ok":
            self.problem = _status_sentence(status, function, call_outcome.message)
        elif not isinstance(call_outcome.value, dict) or not isinstance(call_outcome.value.get("status"), str):
            self.problem = f"{function}: the results of the calls could not be read"
        elif call_outcome.value["status"] == "missing":
            name = call_outcome.value.get("name")
            self.problem = f"{name if isinstance(name, str) else function} is not defined in your notebooks"
        elif call_outcome.value["status"] != "ok":
            self.problem = f"{function}: the results of the calls could not be read"
        else:
            self.payload = call_outcome.value

    def items(self, count: int) -> list[Item]:
        """The ``count`` per-call records (failed Items stand in for absent or unreadable ones)."""
        if self.problem is not None:
            return [Item(False, error=self.problem) for _ in range(count)]
        raw = self.payload.get("items")
        raw = raw if isinstance(raw, list) else []
        out = []
        for k in range(count):
            rec = raw[k] if k < len(raw) else None
            if not isinstance(rec, dict) or not isinstance(rec.get("ok"), bool):
                out.append(Item(False, error=f"{self.function}: no result was reported for this call"))
            elif rec["ok"]:
                out.append(Item(True, value=rec.get("value")))
            else:
                err = rec.get("error")
                out.append(Item(False, error=tidy(err if isinstance(err, str) else "failed")))
        return out

    def field(self, name: str, default=None):
        return self.payload.get(name, default) if self.problem is None else default


def _status_sentence(status: str, function: str, message: str) -> str:
    message = tidy(message or "")
    if status == "missing":
        return f"{function} is not defined in your notebooks"
    if status == "timeout":
        return f"{function} {message or 'took too long'}" if message.startswith("took") else \
            f"{function} did not finish in time ({message})"
    if status == "crashed":
        return f"{function}: {message}" if message else f"the process running {function} ended abruptly"
    if status == "malformed":
        return f"{function}: {message}"
    return f"{function} raised {message}" if message else f"{function} raised an exception"


def first_problem(items: Sequence[Item]) -> str:
    """The first error among ``items`` (for a check's feedback), or ''."""
    return next((it.error for it in items if not it.ok and it.error), "")


# ------------------------------------------------------------------------------- readers
# One reader of returned values for the whole kit: judging.verdict (read_array, read_number,
# read_parts raise Malformed with a sentence for the student).  The old names stay for callers.

as_array = read_array
as_number = read_number
parts = read_parts


# ------------------------------------------------------------------------------- scoring


def graded(name: str, points: float, fraction: float, lines: Sequence[str] = (), mistakes: Sequence = ()) -> TestResult:
    """A check worth ``points``, scored ``fraction`` of them (clipped to [0, 1]), with its feedback.

    ``lines`` are sentences (figures of merit beside goals, errors); ``mistakes`` are catalogue
    Mistakes named in the feedback when the check is not fully passed.
    """
    fraction = 0.0 if not math.isfinite(fraction) else min(max(fraction, 0.0), 1.0)
    text = collapse(lines)
    if fraction < 1.0:
        text += [mistake_note(m) for m in _unique(mistakes)]
    score = points * fraction
    # Two trailing spaces: a line break in Gradescope's and the feedback's markdown.
    return TestResult(name, score, points, fraction >= 1.0, "  \n".join(text))


def collapse(lines: Sequence[str]) -> list[str]:
    """Lines "<label>: <text>" with the same text merged into one ("a, b and c: <text>").

    A failing function usually fails the same way on every input; one line says it once.
    """
    merged: dict[str, list[str]] = {}
    for line in lines:
        label, sep, rest = line.partition(": ")
        if sep and len(label) <= 40:
            merged.setdefault(rest, []).append(label)
        else:
            merged.setdefault(line, [])
    out = []
    for text, labels in merged.items():
        if len(labels) <= 1:
            out.append(f"{labels[0]}: {text}" if labels else text)
        else:
            out.append(f"{', '.join(labels[:-1])} and {labels[-1]}: {text}")
    return out


def _unique(mistakes):
    seen, out = set(), []
    for m in mistakes:
        if m is not None and m.code not in seen:
            seen.add(m.code)
            out.append(m)
    return out


def mistake_note(m) -> str:
    """'Likely mistake: <name>. <hint>' for a catalogue Mistake."""
    return f"Likely mistake: {m.name}. {m.hint[0].upper()}{m.hint[1:]}"
