"""Tools shared by the hidden tests: reading what the sandbox sent back, scoring, wording feedback.

Everything a student's code returned is untrusted plain data (``autograder.wire`` decoded it):
any type, shape, dtype or NaN may come.  ``Outcome.items`` unpacks the helper's per-call records
(see ``_child_helpers.py``) and the ``as_*`` readers turn values into float arrays or raise
:class:`Malformed` with a sentence for the student.  Nothing here mentions a hidden input's values.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from autograder.results import TestResult

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


class Malformed(Exception):
    """A returned value that is not what the contract says; the message is for the student."""


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


def as_array(value, shape: tuple[int | None, ...], what: str) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (None: any length), or Malformed.

    Lists and tuples of numbers are accepted as arrays; complex values only when their imaginary
    part is zero; NaN and inf are kept (the checks count them as wrong).
    """
    if isinstance(value, (list, tuple)):
        try:
            value = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise Malformed(f"{what} should be an array of shape {_shape_text(shape)}, got a "
                            f"{type(value).__name__} that is not one") from None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = np.asarray(float(value))
    if not isinstance(value, np.ndarray):
        raise Malformed(f"{what} should be an array of shape {_shape_text(shape)}, got {_kind(value)}")
    if value.dtype.kind == "c":
        if np.any(value.imag != 0):
            raise Malformed(f"{what} has complex values")
        value = value.real
    if value.dtype.kind not in "biuf":
        raise Malformed(f"{what} should hold numbers, got dtype {value.dtype}")
    arr = value.astype(np.float64)
    if len(shape) == 2 and shape[1] is not None and arr.ndim == 1 and shape[0] is None and arr.size == shape[1]:
        arr = arr.reshape(1, -1)
    if arr.ndim != len(shape) or any(w is not None and w != s for w, s in zip(shape, arr.shape)):
        squeezed = arr.squeeze()
        if squeezed.ndim == len(shape) and all(w is None or w == s for w, s in zip(shape, squeezed.shape)):
            return squeezed
        raise Malformed(f"{what} should have shape {_shape_text(shape)}, got {arr.shape}")
    return arr


def as_number(value, what: str) -> float:
    """``value`` as one float (a 1-element array counts), or Malformed."""
    if isinstance(value, bool):
        raise Malformed(f"{what} should be a number, got a bool")
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "biuf":
        return float(value.reshape(()))
    raise Malformed(f"{what} should be a number, got {_kind(value)}")


def parts(value, count: int, what: str) -> tuple:
    """The first ``count`` elements of a returned tuple or list, or Malformed."""
    if not isinstance(value, (tuple, list)) or len(value) < count:
        raise Malformed(f"{what} should return {count} values (a tuple), got {_kind(value)}")
    return tuple(value[:count])


def _kind(value) -> str:
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape}"
    if isinstance(value, (tuple, list)):
        return f"a {type(value).__name__} of {len(value)} values"
    if value is None:
        return "None"
    return f"a {type(value).__name__}"


def _shape_text(shape) -> str:
    return "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


# ------------------------------------------------------------------------------- scoring


def fmt(x: float, digits: int = 3) -> str:
    """A figure for feedback: 3 significant digits, 'inf'/'nan' spelled out."""
    if x is None or not math.isfinite(x):
        return "not finite" if x is not None and math.isnan(x) else "infinite"
    return f"{x:.{digits}g}"


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


def share_score(share: float, goal: float, floor: float) -> float:
    """Partial credit for a share: 1 at ``goal`` and above, 0 at ``floor`` and below, linear between."""
    if not math.isfinite(share):
        return 0.0
    if share >= goal:
        return 1.0
    if goal <= floor:
        return 0.0
    return max(0.0, (share - floor) / (goal - floor))


def log_score(value: float, start: float, goal: float) -> float:
    """Partial credit for lowering an error from ``start`` towards ``goal`` (log scale).

    1 when value <= goal, 0 when value >= start, else the share of log(start / goal) achieved.
    """
    if not (math.isfinite(value) and value >= 0):
        return 0.0
    if value <= goal:
        return 1.0
    if value >= start or start <= goal or goal <= 0:
        return 0.0
    return math.log(start / value) / math.log(start / goal)
