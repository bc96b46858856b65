"""refineF switched off: the one switch the kit's ``refineF`` reads, and the one way to throw it.

The handout lets ``eightpoint`` call the given ``refineF``, a local minimisation that can hide a
mistake made before it (the F of a design matrix built for F transposed comes out as a near
miss).  So the public self-check (``starter.checks.instrument``) and the grader (the sandbox
child, ``autograder/sandbox/child.py``) both run ``eightpoint`` a second time inside
:func:`switched_off`, as the FAQ's "temporarily comment out the call to refineF" advises.

Switched off, refineF keeps its contract and drops only the minimisation: it accepts what it
accepts switched on (F as a 3x3 matrix or any 9 numbers, row by row) and returns a (3, 3) float
array of rank 2 with unit Frobenius norm, the closest rank-2 matrix to the F it was given
(smallest singular value set to 0), scaled.  A correct F stays correct (up to scale); a wrong
one stays wrong, since the closest rank-2 matrix to a wrong F is no nearer the right one.

Every route to refineF is covered for the length of one call of ``fn``:

- the kit's ``starter.epipolar.refineF`` however ``fn`` reaches it (its global name, another
  name, ``starter.refineF(...)``, a default argument, an import inside the function, a module of
  the student's re-exporting it): it reads :func:`is_off` itself, so nothing is swapped for it;
- a refineF of the student's own (a global named refineF; the ``refineF`` of a module among the
  globals or already imported, such as their ``helper.refineF``, also when ``fn`` imports it
  inside its body; a default argument of ``fn`` bound to one of these): replaced by
  :func:`stand_in`, and put back after, also when ``fn`` raises.  A module of theirs first
  imported during the call itself is not covered.

It lives in ``core`` because the sandbox child may import only ``core`` of the kit: importing
``starter`` there would load scipy into every child.  Imports numpy and core only.  The switch
is state of this process, so it covers only calls made in it, one at a time.

The switch is the student's own process's state, which the code under test can change.  So in the
grader's sandbox the switch does not decide: the child names a *grader helper*
(:func:`set_grader_helper`) through which the kit's refineF asks the grader for its result, and
the grader answers polished or switched off as its own request said
(``autograder/sandbox/session.py``); the minimisation itself (``starter.refine_polish``) is not
shipped to the sandbox.  The replacement of a student's own refineF still happens here, in the
child: it only concerns their own code.
"""

from __future__ import annotations

import sys
import types
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from core.geometry import enforce_rank2
from core.validate import as_matrix

__all__ = ["Switch", "as_F", "closest_rank2", "count_call", "grader_helper", "is_off", "polish_skipped", "set_grader_helper", "stand_in",
           "switched_off"]

_KIT_HELPER = ("starter.epipolar", "refineF")  # where the helper that reads the switch itself lives
_MISSING = object()


@dataclass(eq=False)
class Switch:
    """One switched-off run.  calls: how many times refineF was called during it (any route)."""

    calls: int = 0


_runs: list[Switch] = []  # the runs in progress, innermost last; refineF is off while any is


_grader: list[Callable] = []  # the sandbox child's way to ask the grader for refineF (at most one)


def is_off() -> bool:
    """True while refineF is switched off (inside :func:`switched_off`)."""
    return bool(_runs)


def set_grader_helper(fn: Callable) -> None:
    """In the sandbox child only, before any student code: the kit's refineF calls
    ``fn(F, pts1, pts2)`` (checked (3, 3) and (N, 2) float arrays) and returns what it returns."""
    _grader[:] = [fn]


def grader_helper() -> Callable | None:
    """The function set by :func:`set_grader_helper`, or None outside the grader's sandbox."""
    return _grader[0] if _grader else None


def count_call() -> None:
    """Count one call of refineF in the innermost switched-off run (if any)."""
    if _runs:
        _runs[-1].calls += 1


def as_F(F) -> np.ndarray:
    """F as refineF takes it: a finite, non-zero (3, 3) float array from a 3x3 or any 9 numbers
    (reshaped row by row, as the course's helper did); ValueError naming F otherwise."""
    F = as_matrix(F, "F", (3, 3), any_layout=True)
    if not np.any(F):
        raise ValueError("F: expected a non-zero matrix, got all zeros")
    return F


def polish_skipped(F: np.ndarray) -> np.ndarray:
    """What refineF returns switched off, for an F already read by :func:`as_F`: the closest
    rank-2 matrix to F, unit Frobenius norm, (3, 3).  Counts the call."""
    count_call()
    return closest_rank2(F)


def closest_rank2(F: np.ndarray) -> np.ndarray:
    """The closest rank-2 matrix to a checked (3, 3) F, unit Frobenius norm (what switched-off
    refineF returns; the grader computes it for the sandbox)."""
    out = enforce_rank2(F)
    return out / np.linalg.norm(out)


def stand_in(F, *args, **kwargs) -> np.ndarray:
    """Takes the place of a student's own refineF while switched off: :func:`polish_skipped` of F.

    The other arguments (the points) are not checked: their helper's idea of them is its own.
    """
    return polish_skipped(as_F(F))


stand_in.__name__ = stand_in.__qualname__ = "refineF"  # what a student's traceback should read


def _kit_helper():
    # Looked up, never imported: the child must not load starter (scipy), and a process that never
    # imported starter has no kit refineF to tell apart.
    return getattr(sys.modules.get(_KIT_HELPER[0]), _KIT_HELPER[1], None)


def _is_own(v) -> bool:
    """A student's own refineF: callable and not the kit's (which reads the switch itself)."""
    return callable(v) and v is not _kit_helper() and v is not stand_in


@contextmanager
def switched_off(fn: Callable) -> Iterator[Switch]:
    """Within the block refineF is switched off for ``fn`` (see the module doc); yields the
    :class:`Switch` counting its calls.  Everything replaced is put back on leaving, whatever
    happened; a name ``fn``'s globals lacked is never added.

    fn : the student's function (its ``__globals__``, ``__defaults__`` and ``__kwdefaults__`` are
        read; a callable without them is covered through the kit's refineF and the modules).
    """
    g = getattr(fn, "__globals__", None)
    g = g if isinstance(g, dict) else {}
    restore: list[tuple[Callable[[object], None], object]] = []
    replaced: set[int] = set()
    run = Switch()
    _runs.append(run)
    try:
        if _is_own(g.get("refineF")):
            replaced.add(id(g["refineF"]))
            restore.append((lambda v: g.__setitem__("refineF", v), g["refineF"]))
            g["refineF"] = stand_in
        # The modules already imported, too: the same in a notebook and in the sandbox, so the
        # self-check and the grader replace the same ones.  Exact module type only: vars() of a
        # lazily loaded module would load it.
        owners = [v for v in list(g.values()) if isinstance(v, types.ModuleType)]
        owners += [m for m in list(sys.modules.values()) if type(m) is types.ModuleType]
        for m in dict.fromkeys(owners):   # each module once, in order
            own = vars(m).get("refineF", _MISSING)
            if own is not _MISSING and _is_own(own):
                replaced.add(id(own))
                restore.append((lambda v, m=m: setattr(m, "refineF", v), own))
                m.refineF = stand_in
        _swap_defaults(fn, replaced, restore)
        yield run
    finally:
        for put_back, old in reversed(restore):
            put_back(old)
        _runs.remove(run)


def _swap_defaults(fn, replaced: set[int], restore: list) -> None:
    """Default arguments of ``fn`` bound to a replaced refineF (``_r=refineF``) get the stand-in too."""
    defaults = getattr(fn, "__defaults__", None)
    if isinstance(defaults, tuple) and any(id(v) in replaced for v in defaults):
        restore.append((lambda v: setattr(fn, "__defaults__", v), defaults))
        fn.__defaults__ = tuple(stand_in if id(v) in replaced else v for v in defaults)
    kw = getattr(fn, "__kwdefaults__", None)
    if isinstance(kw, dict) and any(id(v) in replaced for v in kw.values()):
        restore.append((lambda v: setattr(fn, "__kwdefaults__", v), kw))
        fn.__kwdefaults__ = {k: stand_in if id(v) in replaced else v for k, v in kw.items()}
