"""What a judgment returns, and the one reader of a student's untrusted returned values.

A student's function may return anything: any type, shape, dtype, NaN.  ``read_array``,
``read_number`` and ``read_parts`` turn it into floats of the contract's shape or raise
:class:`Malformed` with a sentence for the student.  A judgment (judging/<concept>.py) turns
the values into a :class:`Verdict`; the public self-checks print it, the hidden tests score it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core.text import fmt  # noqa: F401 - judging's figures are the kit's (re-exported for its modules)

from .mistakes import Mistake

__all__ = ["FAILED", "Malformed", "Verdict", "figure_text", "fmt", "log_score", "read_array", "read_number", "read_parts", "same_error", "share_score"]


FAILED = "failed"


def figure_text(passed: bool, measured: str, goal: str = "", because: str = "") -> str:
    """'<measured> (goal <goal>)', said as failed in words when not ``passed``: the one home of how a
    figure and its goal are shown, in the hidden feedback and the self-checks alike.

    A failed figure reads "failed: 1.81e3 px^2 (goal <= 2.17e3 px^2)"; ``because`` names the part
    that failed when the figure shown may meet its goal (the check failed on something else):
    "failed (the reconstruction lost its shape): 1.81e3 px^2 (goal <= 2.17e3 px^2)".
    """
    text = f"{measured} (goal {goal})" if measured and goal else (measured or (f"goal {goal}" if goal else ""))
    if passed:
        return text
    head = f"{FAILED} ({because})" if because else FAILED
    return f"{head}: {text}" if text else head


def same_error(count: int) -> str:
    """'(the same in 12 calls)': how often one error was seen, for the one line that says it."""
    return f"(the same in {count} calls)"


class Malformed(ValueError):
    """A returned value that is not what the contract says; the message is for the student."""


@dataclass(frozen=True)
class Verdict:
    """One judgment of one returned value against the truth.

    what : what was judged, e.g. "exact matches lie on their epipolar lines".
    passed : the rule holds.  Public and hidden sides must agree on this, nothing else.
    fraction : the share of credit in [0, 1]; 1.0 exactly when passed (partial credit below).
    measured : the figure measured ("max distance 3e-12 px"), or why there was none.
    goal : what it was compared with ("<= 0.064 px"), "" when the rule has no figure.
    lines : further sentences for the feedback (never a hidden input's values).
    mistakes : catalogue mistakes recognised; only ever given when not passed.
    because : when not passed although ``measured`` may meet ``goal``, the part that failed
        ("the reconstruction lost its shape"), so that the figure never reads as a pass.
    """

    what: str
    passed: bool
    fraction: float
    measured: str = ""
    goal: str = ""
    lines: tuple[str, ...] = ()
    mistakes: tuple[Mistake, ...] = ()
    because: str = ""

    def __post_init__(self):
        f = float(self.fraction)
        f = min(max(f, 0.0), 1.0) if math.isfinite(f) else 0.0
        if self.passed:
            f = 1.0
        elif f >= 1.0:
            f = 0.0  # a failed rule never earns full credit
        object.__setattr__(self, "passed", bool(self.passed))
        object.__setattr__(self, "fraction", f)
        object.__setattr__(self, "lines", tuple(self.lines))
        object.__setattr__(self, "mistakes", () if self.passed else tuple(m for m in self.mistakes if m is not None))

    @classmethod
    def of(cls, what: str, passed: bool, measured: str = "", goal: str = "", mistakes=(), lines=(),
           fraction: float | None = None, because: str = "") -> Verdict:
        """A verdict whose fraction is 1 or 0 unless given."""
        return cls(what, bool(passed), float(bool(passed)) if fraction is None else fraction, measured, goal,
                   tuple(lines), tuple(mistakes), "" if passed else str(because))

    @classmethod
    def failed(cls, what: str, reason: str) -> Verdict:
        """Nothing to judge (a crash, a malformed value): not passed, no credit, ``reason`` as the figure."""
        return cls(what, False, 0.0, str(reason))

    @property
    def figure(self) -> str:
        """'<measured> (goal <goal>)', with "failed" (and the part that failed) when not passed."""
        return figure_text(self.passed, self.measured, self.goal, self.because)

    @property
    def sentence(self) -> str:
        """'<what>: <figure>' for a feedback line (see :attr:`figure`)."""
        figure = self.figure
        return f"{self.what}: {figure}" if figure else self.what

    @property
    def codes(self) -> tuple[str, ...]:
        return tuple(m.code for m in self.mistakes)


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


def read_array(value, shape: tuple, what: str) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (an entry None or -1: any length), or Malformed.

    Lists and tuples of numbers count as arrays, integer dtypes (uint16 ...) too; complex values
    only when their imaginary part is zero; extra axes of length 1 are squeezed away.  NaN and
    inf are kept: the judgments count them as wrong.
    """
    shape = tuple(None if s is None or s == -1 else int(s) for s in shape)
    if isinstance(value, (list, tuple)):
        try:
            value = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise Malformed(f"{what} should be an array of shape {_shape_text(shape)}, got a "
                            f"{type(value).__name__} that is not one") from None
    if isinstance(value, (int, float, np.number)) and not isinstance(value, (bool, np.bool_)):
        value = np.asarray(value)
    if not isinstance(value, np.ndarray):
        raise Malformed(f"{what} should be an array of shape {_shape_text(shape)}, got {_kind(value)}")
    if value.dtype.kind == "c":
        if np.any(value.imag != 0):
            raise Malformed(f"{what} has complex values")
        value = value.real
    if value.dtype.kind not in "biuf":
        raise Malformed(f"{what} should hold numbers, got dtype {value.dtype}")
    arr = value.astype(np.float64)
    if len(shape) == 2 and shape[0] is None and shape[1] is not None and arr.ndim == 1 and arr.size == shape[1]:
        arr = arr.reshape(1, -1)
    if arr.ndim != len(shape) or any(w is not None and w != s for w, s in zip(shape, arr.shape)):
        squeezed = arr.squeeze()
        if squeezed.ndim == len(shape) and all(w is None or w == s for w, s in zip(shape, squeezed.shape)):
            return squeezed
        raise Malformed(f"{what} should have shape {_shape_text(shape)}, got {arr.shape}")
    return arr


def read_number(value, what: str) -> float:
    """``value`` as one float (a 1-element array counts), or Malformed."""
    if isinstance(value, (bool, np.bool_)):
        raise Malformed(f"{what} should be a number, got a bool")
    if isinstance(value, (int, float, np.number)):
        return float(value)
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "biuf":
        return float(value.reshape(()))
    if isinstance(value, (list, tuple)) and len(value) == 1:
        return read_number(value[0], what)
    raise Malformed(f"{what} should be a number, got {_kind(value)}")


def read_parts(value, count: int, what: str) -> tuple:
    """The first ``count`` items of a returned tuple or list, or Malformed."""
    if not isinstance(value, (tuple, list)) or len(value) < count:
        raise Malformed(f"{what} should return {count} values (a tuple), got {_kind(value)}")
    return tuple(value[:count])


# ------------------------------------------------------------------------------- partial credit


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
