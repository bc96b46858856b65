"""Run a student's ``eightpoint`` with refineF switched off, for the public self-check of Q2.

The handout lets ``eightpoint`` call the given ``refineF``, whose local minimisation can hide a
mistake made before it (a transposed F comes out as an unnamed near miss).  So the self-check
runs ``eightpoint`` a second time with refineF switched off, as the FAQ advises ("temporarily
comment out the call to refineF"), and judges both F's.

Switched off, refineF checks its arguments as always and returns the closest rank-2 matrix to
the F it was given, scaled to unit Frobenius norm: only the minimisation is dropped.  What is
switched off, by which route, and how everything is put back is ``core.refine_switch``'s, the
same switch the grader throws in the sandbox: the self-check and the hidden tests switch off
the very same calls.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from core.refine_switch import switched_off

__all__ = ["refineF_switched_off"]


def refineF_switched_off(fn: Callable, *args, **kwargs) -> tuple[Any, int]:
    """``(fn(*args, **kwargs), calls)`` with refineF switched off for the call (``core.refine_switch``).

    ``calls`` counts the calls of refineF during the run, by any route (0: ``fn`` does not call
    it, so its result is the same as written).  Exceptions of ``fn`` propagate; whatever was
    replaced is put back in every case.
    """
    with switched_off(fn) as run:
        value = fn(*args, **kwargs)
    return value, run.calls
