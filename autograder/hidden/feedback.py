"""Words of the hidden tests' feedback: what a failed call of student code says, merged lines, mistakes.

Student code sees the hidden inputs and could put them into an exception's message, so a
failure is quoted only as the exception's type, the student's line and a short first line of
its message, with long numbers, runs of numbers and long unbroken tokens (an encoded dump) cut
(``tidy``, ``exception_sentence``).  Nothing here mentions a hidden input's values.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from judging.hints import numpy2_hint
from judging.verdict import Malformed

__all__ = ["called_as", "collapse", "exception_sentence", "failure", "kind", "mistake_note", "notes", "tidy", "value_of"]

_MESSAGE_LIMIT = 300
_FIRST_LINE_LIMIT = 80
_LONG_NUMBER = re.compile(r"-?\d+\.\d{4,}(?:e[+-]?\d+)?")
_NUMBER_RUN = re.compile(r"(?:-?\d[\d.e+-]*[\s,;]+){6,}-?\d[\d.e+-]*")
_LONG_TOKEN = re.compile(r"[^\s()\[\]{},;:'\"]{33,}")
_EXCEPTION = re.compile(r"^(?P<type>[A-Za-z_][\w.]*)(?::\s?(?P<message>.*?))?(?:\s\(in (?P<where>[^()]*)\))?$", re.S)


def tidy(message: str, limit: int = _MESSAGE_LIMIT) -> str:
    """A line for feedback: long numbers shortened, runs of numbers and long tokens cut, one line,
    at most ``limit`` characters."""
    text = _NUMBER_RUN.sub("[numbers]", str(message))
    text = _LONG_NUMBER.sub(lambda m: m.group(0)[: m.group(0).index(".") + 3], text)
    text = _LONG_TOKEN.sub(lambda m: m.group(0) if m.group(0).endswith((".ipynb", ".py")) else "[...]", text)
    text = " ".join(text.split())
    return text if len(text) <= limit else text[:limit] + " [...]"


def exception_sentence(message: str) -> str:
    """'Type: first line of the message (in f, cell, line L)' from the sandbox's exception message,
    the message's first line cut to a few words (never a dump of data)."""
    m = _EXCEPTION.match(str(message).strip())
    if m is None:
        return tidy(str(message).strip().splitlines()[0] if str(message).strip() else "", _FIRST_LINE_LIMIT)
    first = (m.group("message") or "").strip().splitlines()
    first = tidy(first[0], _FIRST_LINE_LIMIT) if first else ""
    text = m.group("type") + (f": {first}" if first else "")
    return text + (f" (in {tidy(m.group('where'), 120)})" if m.group("where") else "")


def failure(function: str, outcome) -> str:
    """The sentence for a call of ``function`` that did not return (``CallOutcome`` not ok)."""
    status, msg = outcome.status, str(outcome.message or "")
    if status == "missing":
        return f"{function} is not defined in your notebooks"
    if status == "exception":
        if not msg:
            return f"{function} raised an exception"
        return f"{function} raised {exception_sentence(msg)}" + (f". {h}" if (h := numpy2_hint(msg)) else "")
    msg = tidy(msg)
    if status == "timeout":
        return f"{function} {msg}" if msg.startswith("took") else f"{function} did not finish in time ({msg})"
    if status == "skipped":
        return msg or f"{function} was not run"
    if status == "crashed" and not msg:
        return f"the process running {function} ended abruptly"
    return f"{function}: {msg}" if msg else f"{function} failed"


def kind(value) -> str:
    """What sort of argument ``value`` is, never its values: "a 3x3 float64 array", "an int", ..."""
    if hasattr(value, "shape") and hasattr(value, "dtype"):
        return f"a {'x'.join(str(n) for n in value.shape) or 'scalar'} {value.dtype} array"
    if isinstance(value, bool):
        return "a bool"
    if isinstance(value, int):
        return "an int"
    if isinstance(value, float):
        return "a float"
    if isinstance(value, str):
        return "a str"
    if isinstance(value, dict):
        return "a dict with " + (", ".join(str(k) for k in list(value)[:6]) or "no keys")
    if isinstance(value, (tuple, list)):
        return f"a {type(value).__name__} of {len(value)}"
    return f"a {type(value).__name__}"


def called_as(function: str, names: Sequence[str], args: Sequence, kwargs: dict | None = None) -> str:
    """'called as f(F: a 3x3 float64 array, x1: an int, ...)': the call's names and argument kinds."""
    parts = [f"{n}: {kind(a)}" for n, a in zip(names, args)] + [f"{k}={kind(v)}" for k, v in (kwargs or {}).items()]
    return f"called as {function}({', '.join(parts)})"


def value_of(function: str, outcome):
    """What the call returned; ``Malformed`` (with the failure's sentence) when it did not return."""
    if outcome is None:
        raise Malformed(f"{function} was not run")
    if not outcome.ok:
        raise Malformed(failure(function, outcome))
    return outcome.value


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


def mistake_note(m) -> str:
    """'Likely mistake: <name>. <hint>' for a catalogue Mistake."""
    return f"Likely mistake: {m.name}. {m.hint[0].upper()}{m.hint[1:]}"


def notes(lines: Sequence[str], mistakes: Sequence = (), *, passed: bool = False) -> list[str]:
    """The feedback lines of a check: ``lines`` merged, then each mistake named once unless passed."""
    out = collapse([str(line) for line in lines if line])
    if not passed:
        seen: set = set()
        for m in mistakes:
            if m is not None and m.code not in seen:
                seen.add(m.code)
                out.append(mistake_note(m))
    return out
