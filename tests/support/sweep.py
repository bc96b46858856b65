"""Grading the corpus in-process under a secret, and reading which hidden concepts a program reached.
"""

from __future__ import annotations

import contextlib
import io
import types
from dataclasses import dataclass

import numpy as np
from hidden_files import questions_graded


HOMEWORK = ("eightpoint", "essentialMatrix", "triangulate", "findM2", "epipolarCorrespondence", "compute3D_pts",
            "rodriguesResidual", "bundleAdjustment", "MultiviewReconstruction")


# Called by the hidden tests but not a homework function of its own (Q6's figure).
GRADED = (*HOMEWORK, "plot_3d_keypoint_video")


def hidden_files_of() -> dict[str, tuple[frozenset, frozenset]]:
    """concept -> (functions its hidden test file calls, questions it grades), read from the files
    that grade a question."""
    from autograder.hidden.plugin import HIDDEN_DIR

    out = {}
    for path in sorted(HIDDEN_DIR.glob("test_*.py")):
        text = path.read_text()
        judged = frozenset(n for n in GRADED if f'"{n}"' in text)
        questions = questions_graded(text)
        if questions:  # a file that grades no question (the unscored picture step) has no verdict to sweep
            out[path.stem.removeprefix("test_")] = (judged, questions)
    return out


def names_used(code: types.CodeType) -> set[str]:
    """Global (and attribute) names a function's code mentions, its nested code included."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= names_used(const)
    return names


def reached_names(namespace: dict, roots) -> set[str]:
    """``roots`` and every name of ``namespace`` they use, through the functions defined there."""
    seen, todo = set(), list(roots)
    while todo:
        name = todo.pop()
        if name in seen or name.startswith("__"):
            continue  # dunders: __name__ is the corpus program's label here, the student's module in the grader
        seen.add(name)
        value = namespace.get(name)
        if isinstance(value, types.FunctionType) and value.__globals__ is namespace:
            todo += names_used(value.__code__)
    return seen


_MISSING = object()


def same_value(a, b) -> bool:
    """The same definition: one object, functions compiled from the same text, or equal values."""
    if a is b:
        return True
    try:
        if isinstance(a, types.FunctionType) and isinstance(b, types.FunctionType):
            return (a.__code__ == b.__code__ and same_value(a.__defaults__, b.__defaults__)
                    and same_value(a.__kwdefaults__, b.__kwdefaults__))
        if isinstance(a, dict) and isinstance(b, dict):
            return a.keys() == b.keys() and all(same_value(a[k], b[k]) for k in a)
        if isinstance(a, tuple) and isinstance(b, tuple):
            return len(a) == len(b) and all(map(same_value, a, b))
        if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            return type(a) is type(b) and a.dtype == b.dtype and bool(np.array_equal(a, b))
        return type(a) is type(b) and isinstance(a, (int, float, str, bytes, frozenset, type(None))) and a == b
    except Exception:  # noqa: BLE001 - what cannot be compared counts as different
        return False


def changed_names(namespace: dict, key: dict, roots) -> set[str]:
    """The names ``roots`` reach (in either namespace) that are defined otherwise than in the key."""
    names = reached_names(namespace, roots) | reached_names(key, roots)
    return {n for n in names if not same_value(namespace.get(n, _MISSING), key.get(n, _MISSING))}


def concepts_reached(namespace: dict, key: dict, files) -> tuple[str, ...]:
    """The hidden test files whose judged functions reach a name defined otherwise than in the key."""
    return tuple(concept for concept, (judged, _) in files.items() if changed_names(namespace, key, judged))


@dataclass(frozen=True)
class Graded:
    """One hidden test's result: name, score, max_score, feedback."""

    name: str
    score: float
    max_score: float
    feedback: str


def grade(functions: dict, hidden, concepts) -> dict[str, tuple[float, float, tuple[Graded, ...]]]:
    """question -> (score, max_score, tests) of the real hidden tests of ``concepts`` on ``functions``."""
    from autograder.hidden.plugin import HIDDEN_DIR, LocalStudent, run_here

    # The hidden session's report is not for this log; pytest's unraisable-exception plugin would
    # collect garbage twice a session (a quarter of a second each with this process's objects).
    with contextlib.redirect_stdout(io.StringIO()):
        result = run_here(LocalStudent(functions), hidden, tests=[HIDDEN_DIR / f"test_{c}.py" for c in concepts],
                          args=["--tb=no", "-p", "no:unraisableexception"])
    return {q.id: (q.score, q.max_score, tuple(Graded(t.name, t.score, t.max_score, t.feedback) for t in q.tests))
            for q in result.questions}
