"""Run a student's function with a given helper swapped for an instrumented one, then put it back.

The handout lets ``eightpoint`` call the given ``refineF``, which polishes an F by a local
minimisation: it can hide a mistake made before it (a transposed F comes out as an unnamed
near miss, a missing rank-2 step disappears, since refineF returns a rank-2 matrix).  So the
self-check runs ``eightpoint`` a second time with ``refineF`` switched off, as the handout's
FAQ advises ("temporarily comment out the call to refineF"), and judges both F's.

A notebook's functions look their helpers up in the notebook's namespace, which is the
function's ``__globals__``.  :func:`swapped` replaces names there for the length of one call
and always restores them (also when the call raises): the student's namespace is never left
changed.  The names replaced are ``refineF`` itself and any other global bound to the kit's
``refineF`` (``from starter import refineF as rf``).

Used by starter.checks.fundamental; the hidden tests do the same in the sandbox (see
plan/JUDGING_API.md).  Imports nothing from the kit but starter.epipolar.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

__all__ = ["RefineSwitch", "helper_names", "refineF_switched_off", "swapped"]

_MISSING = object()


def helper_names(fn: Callable, name: str, original: Any = None) -> list[str]:
    """The globals of ``fn`` that stand for the helper ``name``: ``name`` itself when defined there,
    and every other global bound to ``original`` (the kit's helper object), in that order."""
    names = getattr(fn, "__globals__", None)
    if not isinstance(names, dict):
        return []
    out = [name] if name in names else []
    if original is not None:
        out += [k for k, v in list(names.items()) if v is original and k != name]
    return out


@contextmanager
def swapped(fn: Callable, replacements: dict[str, Any]):
    """Within the block, each global ``name`` of ``fn`` in ``replacements`` is replaced; restored after.

    A name that ``fn``'s globals do not define is added for the block and removed afterwards.
    Functions without ``__globals__`` (builtins, callable objects) are left alone.
    """
    names = getattr(fn, "__globals__", None)
    if not isinstance(names, dict) or not replacements:
        yield
        return
    saved = {k: names.get(k, _MISSING) for k in replacements}
    try:
        names.update(replacements)
        yield
    finally:
        for k, v in saved.items():
            if v is _MISSING:
                names.pop(k, None)
            else:
                names[k] = v


@dataclass
class RefineSwitch:
    """A stand-in for refineF(F, pts1, pts2) that returns F unchanged and records its calls.

    calls : the number of calls.  inputs : (F, pts1, pts2) of the last call, as arrays.
    """

    calls: int = 0
    inputs: tuple = field(default=(), repr=False)

    def __call__(self, F, pts1, pts2):
        import numpy as np

        self.calls += 1
        self.inputs = (np.array(F, dtype=float), np.array(pts1, dtype=float), np.array(pts2, dtype=float))
        return F


def refineF_switched_off(fn: Callable, *args, **kwargs) -> tuple[Any, int]:
    """``(fn(*args, **kwargs), calls)`` with every refineF of ``fn``'s globals returning F unchanged.

    ``calls`` counts the calls of refineF during the run (0: ``fn`` does not call it by a global
    name, so its result is the same as written).  Exceptions of ``fn`` propagate; the globals
    are restored in every case.
    """
    from starter.epipolar import refineF

    switch = RefineSwitch()
    names = helper_names(fn, "refineF", refineF) or ["refineF"]
    with swapped(fn, {k: switch for k in names}):
        value = fn(*args, **kwargs)
    return value, switch.calls
