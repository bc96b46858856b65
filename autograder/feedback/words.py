"""Words of the hidden tests' feedback: what a failed call of student code says, merged lines, mistakes.

Student code sees the hidden inputs and could put them into an exception's message, so a
failure is quoted only as the exception's type, the student's line and a short first line of
its message, with long numbers, runs of numbers and long unbroken tokens (an encoded dump) cut
(``tidy``, ``exception_sentence``).  Nothing here mentions a hidden input's values.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from autograder.feedback.causes import LIKELY
from core.manifest import QUESTIONS
from core.untrusted import visible
from judging.hints import numpy2_hint
from judging.verdict import Malformed, same_error

__all__ = ["PARAMETERS", "called_as", "collapse", "exception_sentence", "failure", "kind", "mistake_note",
           "named_mistakes", "notes", "read_returned", "returned", "tidy", "upstream_named", "value_of"]

# A feedback line of a failed call holds the failure (its message cut to _FIRST_LINE_LIMIT), the
# call with the kind of each argument (seven arguments take about 200 characters) and what came back.
_MESSAGE_LIMIT = 600
_FIRST_LINE_LIMIT = 80
_LONG_NUMBER = re.compile(r"-?\d+\.\d{4,}(?:e[+-]?\d+)?")
_NUMBER_RUN = re.compile(r"(?:-?\d[\d.e+-]*[\s,;]+){6,}-?\d[\d.e+-]*")
_LONG_TOKEN = re.compile(r"[^\s()\[\]{},;:'\"]{33,}")
# Any number with a fractional part or an exponent in a student's exception message: it may be a
# hidden input's value (a message built from the arguments), however few digits it shows.
_DECIMAL = re.compile(r"(?<![\w.])-?(?:\d+\.\d+(?:e[+-]?\d+)?|\d+e[+-]?\d+|\.\d+)(?![\w.])", re.I)
_EXCEPTION = re.compile(r"^(?P<type>[A-Za-z_][\w.]*)(?::\s?(?P<message>.*?))?(?:\s\(in (?P<where>[^()]*)\))?$", re.S)


def tidy(message: str, limit: int = _MESSAGE_LIMIT) -> str:
    """A line for feedback: escape sequences removed and controls shown (core.untrusted.visible),
    long numbers shortened, runs of numbers and long tokens cut, one line, at most ``limit``
    characters."""
    # Student text first loses its escape sequences and shows its controls, so that no reader of
    # it (pytest's own report in a TA's terminal too) meets them; each writer escapes it again.
    text = _NUMBER_RUN.sub("[numbers]", visible(message, limit=10 * limit))
    text = _LONG_NUMBER.sub(lambda m: m.group(0)[: m.group(0).index(".") + 3], text)
    text = _LONG_TOKEN.sub(lambda m: m.group(0) if m.group(0).endswith((".ipynb", ".py")) else "[...]", text)
    text = " ".join(text.split())
    return text if len(text) <= limit else text[:limit] + " [...]"


def exception_sentence(message: str) -> str:
    """'Type: first line of the message (in f, cell, line L)' from the sandbox's exception message,
    the message's first line cut to a few words, its decimal numbers replaced by "[number]" (never
    a dump of data, nor a hidden value however rounded)."""
    m = _EXCEPTION.match(str(message).strip())
    if m is None:
        text = str(message).strip().splitlines()[0] if str(message).strip() else ""
        return tidy(_DECIMAL.sub("[number]", text), _FIRST_LINE_LIMIT)
    first = (m.group("message") or "").strip().splitlines()
    first = tidy(_DECIMAL.sub("[number]", first[0]), _FIRST_LINE_LIMIT) if first else ""
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


# The contract's parameter names of each graded function (the stubs' and the answer key's), for
# the "called as" sentence of a failed call made as the contract says.
PARAMETERS: dict[str, tuple[str, ...]] = {
    "eightpoint": ("pts1", "pts2", "M"),
    "essentialMatrix": ("F", "K1", "K2"),
    "triangulate": ("C1", "pts1", "C2", "pts2"),
    "findM2": ("F", "pts1", "pts2", "K1", "K2"),
    "epipolarCorrespondence": ("im1", "im2", "F", "x1", "y1"),
    "compute3D_pts": ("im1", "im2", "F", "x1", "y1", "C1", "C2"),
    "rodriguesResidual": ("K1", "M1", "p1", "K2", "p2", "x"),
    "bundleAdjustment": ("K1", "M1", "p1", "K2", "M2_init", "p2", "w_init"),
    "MultiviewReconstruction": ("C1", "pts1", "C2", "pts2", "C3", "pts3", "Thres"),
    "plot_3d_keypoint_video": ("pts_3d_video",),
}


def kind(value) -> str:
    """What sort of argument ``value`` is, never its values: "a 3x3 float64 array", "an int", ..."""
    if value is None:
        return "None"
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


def called_as(function: str, names: Sequence[str] | None, args: Sequence, kwargs: dict | None = None) -> str:
    """'called as f(F: a 3x3 float64 array, x1: an int, ...)': the call's names and argument kinds.

    ``names`` None: the contract's (:data:`PARAMETERS`); arguments beyond the names are listed by kind.
    """
    names = tuple(PARAMETERS.get(function, ()) if names is None else names)
    parts = [f"{names[k]}: {kind(a)}" if k < len(names) else kind(a) for k, a in enumerate(args)]
    parts += [f"{k}={kind(v)}" for k, v in (kwargs or {}).items()]
    return f"called as {function}({', '.join(parts)})"


def returned(value) -> str:
    """What a call gave back, by kind only: "a tuple of 2 (a 40x3 float64 array, a float)", "None"."""
    if isinstance(value, (tuple, list)) and value:
        items = ", ".join(kind(v) for v in value[:4]) + (", ..." if len(value) > 4 else "")
        return f"{kind(value)} ({items})"
    return kind(value)


def read_returned(function: str, outcome, read, args: Sequence, *, names: Sequence[str] | None = None,
                  kwargs: dict | None = None):
    """``read(value)`` of what ``function(*args, **kwargs)`` returned (``outcome``, a ``CallOutcome``).

    When the call did not return, or ``read`` finds the value malformed, raises :class:`Malformed`
    whose sentence says what went wrong, how the function was called (argument kinds, under
    ``names``, by default the contract's) and, for a malformed value, what came back: one place
    for every check, never a hidden input's values.
    """
    call = called_as(function, names, args, kwargs)
    if outcome is None or outcome.status in ("missing", "skipped"):
        value_of(function, outcome)   # nothing was called: the sentence says so, with no call
    if not outcome.ok:
        raise Malformed(f"{failure(function, outcome)}; {call}")
    try:
        return read(outcome.value)
    except Malformed as exc:
        raise Malformed(f"{exc}; {call} returned {returned(outcome.value)}") from None


def value_of(function: str, outcome):
    """What the call returned; ``Malformed`` (with the failure's sentence) when it did not return."""
    if outcome is None:
        raise Malformed(f"{function} was not run")
    if not outcome.ok:
        raise Malformed(failure(function, outcome))
    return outcome.value


# A labelled line of a failed call: "<label>: <function> raised <Type: message>[; called as ...]".
_RAISED = re.compile(r"^(?P<error>[A-Za-z_]\w* raised .*?)(?P<call>; called as .*)?$")
_LABEL_LIMIT = 100   # labels such as "noise-free matches of hidden scene 2, enlarged, with refineF switched off"


def collapse(lines: Sequence[str]) -> list[str]:
    """Lines "<label>: <text>" with the same text merged into one ("a, b and c: <text>"); lines of
    calls that raised the same error (whatever the call's argument kinds) merged into one with a
    count ("4 inputs: f raised ValueError: ... (the same in 4 calls); called as f(...)").

    A failing function usually fails the same way on every input; one line says it once.
    """
    merged: dict[str, list[str]] = {}
    calls: dict[str, list[str]] = {}
    for line in lines:
        label, sep, rest = line.partition(": ")
        m = _RAISED.match(rest) if sep and len(label) <= _LABEL_LIMIT and " raised " not in label else None
        if m is not None:
            key = m.group("error")
            merged.setdefault(key, []).append(label)
            calls.setdefault(key, []).append(m.group("call") or "")
        elif sep and len(label) <= 40:
            merged.setdefault(rest, []).append(label)
        else:
            merged.setdefault(line, [])
    out = []
    for text, labels in merged.items():
        labels = list(dict.fromkeys(labels))
        if text in calls:
            seen = [c for c in dict.fromkeys(calls[text]) if c]
            count = len(calls[text])
            who = (labels[0] if len(labels) == 1 else f"{', '.join(labels[:-1])} and {labels[-1]}" if len(labels) <= 3
                   else f"{len(labels)} inputs")
            text = text + (f" {same_error(count)}" if count > 1 else "")
            text += ("; called as " + " or as ".join(c.removeprefix("; called as ") for c in seen)) if seen else ""
            out.append(f"{who}: {text}")
        elif len(labels) <= 1:
            out.append(f"{labels[0]}: {text}" if labels else text)
        else:
            out.append(f"{', '.join(labels[:-1])} and {labels[-1]}: {text}")
    return out


def mistake_note(m) -> str:
    """'Likely mistake: <name>. <hint>' for a catalogue Mistake (its line: ``autograder.feedback.causes``)."""
    return f"{LIKELY}{m.name}. {m.hint[0].upper()}{m.hint[1:]}"


def named_mistakes(mistakes: Sequence = (), *, passed: bool = False) -> list:
    """The catalogue Mistakes a check names: each code once, in order, none when ``passed``.

    ``notes`` writes them for the student; their codes are the ones to record in the check's
    ``TestResult.mistakes``, which the class report counts (never the feedback's words).
    """
    found: dict = {}
    for m in () if passed else mistakes:
        if m is not None:
            found.setdefault(m.code, m)
    return list(found.values())


def notes(lines: Sequence[str], mistakes: Sequence = (), *, passed: bool = False) -> list[str]:
    """The feedback lines of a check: ``lines`` merged, then each mistake named once unless passed."""
    out = collapse([str(line) for line in lines if line])
    return out + [mistake_note(m) for m in named_mistakes(mistakes, passed=passed)]


# Each function a student writes -> its question (core.manifest), for naming it in another's feedback.
_QUESTION_OF = {f: q.id for q in QUESTIONS for f in q.functions}
# A function's name as a word: not part of a longer name, a call "f(", a file "f.py", or already "f (Q3.2)".
_MENTION = {f: re.compile(rf"(?<![\w.]){re.escape(f)}(?![\w(])(?!\.\w)(?! \(Q)") for f in _QUESTION_OF}


def upstream_named(lines: Sequence[str], question: str) -> list[str]:
    """``lines`` of a check of ``question`` with each function of another question named with that
    question at its first mention: "graded through your epipolarCorrespondence (Q4.1) and
    triangulate (Q3.2)".  A check that runs an earlier answer (Q4.2 falling back to the matcher and
    triangulate) so says whose question to look at, as the pictures do; a call ("triangulate(C1:
    ...)") and the check's own functions are left as they are."""
    out, named = [], set()
    for line in lines:
        line = str(line)
        for f, pattern in _MENTION.items():
            if f in named or _QUESTION_OF[f] == question or f not in line:
                continue
            m = pattern.search(line)
            if m is not None:
                line = f"{line[:m.end()]} ({_QUESTION_OF[f]}){line[m.end():]}"
                named.add(f)
        out.append(line)
    return out
