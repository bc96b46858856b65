"""The given helpers the grader computes for the sandboxed child: today ``refineF``.

The kit's ``refineF`` in the child sends its checked arguments here instead of minimising
(``child._GraderHelper``, ``core.refine_switch``), and the grader answers as the call's own request
decided: polished (``starter.refine_polish``) or, for the run with refineF switched off, the
closest rank-2 matrix.  The decision lives in the grader's process, where the code under test
cannot change it, and the minimisation is not shipped to the sandbox
(``core.shipping.SANDBOX_WITHHELD``).

Everything a record holds is untrusted: decoded with the session's wire limits, checked as refineF
checks its arguments, bounded in size and in calls per request.  An error goes back to the child
as the message of a ValueError there.
"""

from __future__ import annotations

import hashlib
import json
from collections import OrderedDict

import numpy as np

from core import refine_switch, wire
from core.validate import as_points, same_length

__all__ = ["MAX_HELPER_CALLS", "MAX_HELPER_POINTS", "answer", "remember_in"]

MAX_HELPER_POINTS = 20000   # a homework's matches number in the hundreds; Powell's cost grows with them
MAX_HELPER_CALLS = 50       # per request: eightpoint calls refineF once, a careful student a few times


def answer(record: dict, *, switched_off: bool, calls: int, limits: wire.Limits) -> bytes:
    """The reply line (bytes, newline-terminated) to a child's ``helper`` record.

    switched_off: the request asked for refineF switched off; calls: how many helper calls this
    request made, this one included.
    """
    seq = record.get("seq")
    reply: dict = {"reply": seq if type(seq) is int else -1}
    try:
        reply["value"] = wire.encode(_refineF(record, switched_off, calls, limits))
    except (ValueError, wire.WireError) as exc:
        reply["error"] = str(exc)[:300]
    except Exception as exc:  # noqa: BLE001 - the minimisation failed on these arguments: the child is told
        reply["error"] = f"refineF failed in the grader ({type(exc).__name__})"
    return (json.dumps(reply, allow_nan=False, separators=(",", ":")) + "\n").encode()


def _refineF(record: dict, switched_off: bool, calls: int, limits: wire.Limits):
    if record.get("name") != "refineF":
        raise ValueError(f"the grader computes no helper named {str(record.get('name'))[:40]!r}")
    if calls > MAX_HELPER_CALLS:
        raise ValueError(f"refineF: called more than {MAX_HELPER_CALLS} times in one call of the graded function")
    args = wire.decode(record.get("args"), limits)
    if not (isinstance(args, tuple) and len(args) == 3):
        raise ValueError("refineF: expected (F, pts1, pts2)")
    F = refine_switch.as_F(args[0])
    p1 = as_points(args[1], "pts1", min_count=8)
    p2 = as_points(args[2], "pts2", min_count=8)
    same_length(pts1=p1, pts2=p2)
    if len(p1) > MAX_HELPER_POINTS:
        raise ValueError(f"pts1: expected at most {MAX_HELPER_POINTS} points in the grader, got {len(p1)}")
    if switched_off:
        return refine_switch.closest_rank2(F)
    return _polished(F, p1, p2)


_POLISHED: OrderedDict[bytes, np.ndarray] = OrderedDict()  # digest of the arguments -> F, latest last
_POLISHED_MAX = 4096
_STORE: list = [None]  # fetch(parts, make) of the run's keep, when it has one


def remember_in(fetch) -> None:
    """Keep polished results between grading runs as well: ``fetch(parts, make)`` returns the value
    kept under ``parts`` or makes and keeps it (``autograder.inputs.keep.Keep.fetch``, a folder of
    the grader's own); None: in this process only."""
    _STORE[0] = fetch


def _polished(F: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """``polish(F, p1, p2)`` (checked float arrays), remembered by the exact bytes of its arguments.

    The minimisation is a pure function and the costliest step of grading Q2 (Powell's method,
    about a fifth of a second a call); the same arguments come back whenever the same eightpoint
    meets the same points: a regrade, a resubmission, the answer key and the copies of it that
    every class holds.  Only a digest is kept per entry, so the points' size does not matter.
    """
    from starter.refine_polish import polish

    h = hashlib.sha256()
    for a in (F, p1, p2):
        a = np.ascontiguousarray(a, dtype=np.float64)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    key = h.digest()
    found = _POLISHED.get(key)
    if found is None:
        fetch = _STORE[0]
        found = np.array(fetch(("refineF-polish", key.hex()), lambda: polish(F, p1, p2)) if fetch is not None
                         else polish(F, p1, p2), dtype=np.float64)
        found.flags.writeable = False
        _POLISHED[key] = found
        if len(_POLISHED) > _POLISHED_MAX:
            _POLISHED.popitem(last=False)
    else:
        _POLISHED.move_to_end(key)
    return found.copy()
