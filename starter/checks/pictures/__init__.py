"""Figures a student can see: each autograded question drawn from the student's own function on the
public data (never a hidden scene), beside the truth or the reference, so that the catalogue's
mistakes (judging.mistakes) show.  Q3.1's figure
also draws the self-check's generated pair, whose intrinsics differ (the public temple's do not).

Two sides, kept apart so that a grader can run the first in its sandbox and the second at home:

- :func:`public_outputs` (question, functions) calls the student's functions on the public default
  data and returns plain float arrays only (JSON-able through core.wire; never pickle);
- :func:`draw` (question, outputs) never calls student code: it checks the arrays (names, shapes),
  computes the truth on the public data itself and draws a :class:`Picture` (PNG, alt text,
  measures).

``QUESTIONS`` lists the questions; ``FUNCTIONS[q]`` the student functions question q uses: the
first is needed, the others are used when given (Q5's rodriguesResidual, whose residuals at the
start are drawn against the handout's layout).  :func:`show` (question, functions) does both in a
notebook and displays the figure; it never raises (a failure prints "figure not drawn: why").
:func:`show_after_check` is what a self-check calls when it has printed its report.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

import numpy as np

from . import q2_eightpoint, q3_essential, q3_findM2, q3_triangulate, q4_matches, q4_temple, q5_bundle, q6_multiview
from .arrays import PictureRunError
from .measures import label as _label, shown as _shown
from .picture import Picture

__all__ = ["FUNCTIONS", "QUESTION_OF", "QUESTIONS", "Picture", "PictureRunError", "draw", "measure_in_words",
           "public_outputs", "show", "show_after_check"]

_MODULES = {
    "Q2": q2_eightpoint, "Q3.1": q3_essential, "Q3.2": q3_triangulate, "Q3.3": q3_findM2, "Q4.1": q4_matches, "Q4.2": q4_temple,
    "Q5": q5_bundle, "Q6": q6_multiview,
}
QUESTIONS: tuple[str, ...] = ("Q2", "Q3.1", "Q3.2", "Q3.3", "Q4.1", "Q4.2", "Q5", "Q6")
FUNCTIONS: Mapping[str, tuple[str, ...]] = MappingProxyType({q: _MODULES[q].FUNCTIONS for q in QUESTIONS})
# The question whose figure follows each function's self-check.
QUESTION_OF: Mapping[str, str] = MappingProxyType({FUNCTIONS[q][0]: q for q in QUESTIONS})


def _module(question: str):
    if question not in QUESTIONS:
        raise ValueError(f"question: expected one of {QUESTIONS}, got {question!r}")
    return _MODULES[question]


def public_outputs(question: str, functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    """Call the student's ``functions`` (name -> callable; FUNCTIONS[question] needed) on the public
    default data (data/, ``root`` or $HW4_DATA); return name -> plain float64 array.

    Raises ValueError when the needed function (FUNCTIONS[question][0]) is missing or the data has
    no truth where the figure needs it, PictureRunError when a function fails (raises, or returns
    something that cannot be drawn), saying which and how.  Honours other years' signatures
    (judging.conventions) and, for Q2, runs eightpoint again with refineF switched off as the
    self-check does.
    """
    module = _module(question)
    needed = FUNCTIONS[question][0]
    if not isinstance(functions, Mapping) or not callable(functions.get(needed)):
        raise ValueError(f"functions: {question} needs {needed}")
    out = module.run(functions, root)
    return {str(k): np.array(v, dtype=np.float64) for k, v in out.items()}


def measure_in_words(question: str, key: str, value: float) -> tuple[str, str]:
    """(what measure ``key`` of ``question``'s picture is, in words; ``value`` in its unit)."""
    return _label(question, key)[0], _shown(question, key, value)


def draw(question: str, outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    """The Picture of ``question`` from ``public_outputs``'s arrays, on the same public data.

    Never calls student code.  ValueError names an array that is missing or of the wrong shape.
    """
    return _module(question).draw(outputs, root)


def show(question: str, functions: Mapping[str, Callable], root=None) -> Picture | None:
    """In a notebook: run, draw and display the figure of ``question`` (PNG with its alt text).

    Never raises: when the figure cannot be made it prints "figure not drawn: <why>" and returns None.
    """
    from .display import show_picture

    try:
        picture = draw(question, public_outputs(question, functions, root), root)
    except Exception as exc:  # noqa: BLE001 - a figure must never break the check it follows
        print(f"figure not drawn: {type(exc).__name__}: {exc}")
        return None
    show_picture(picture)
    return picture


def show_after_check(function_name: str, fn, root=None) -> Picture | None:
    """After the self-check of ``function_name``, in a notebook only: show its question's figure.

    The other functions the figure uses (FUNCTIONS) are taken from ``fn``'s globals, as the
    notebook defines them.  Outside a notebook nothing is drawn (the checks stay fast in scripts
    and tests).  Never raises.
    """
    from .display import in_notebook

    question = QUESTION_OF.get(function_name)
    if question is None or fn is None or not in_notebook():
        return None
    scope = getattr(fn, "__globals__", {})
    functions = {name: scope.get(name) for name in FUNCTIONS[question][1:] if callable(scope.get(name))}
    functions[function_name] = fn
    return show(question, functions, root)
