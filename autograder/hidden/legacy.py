"""Bridge to the judges of ``autograder/tests/<module>.py`` not yet rewritten on ``judging/``.

Those modules describe their sandbox calls as ``Call`` specs naming in-sandbox helpers
(``__hw4_each``, ``__hw4_match``, ``__hw4_pipeline``, ``__hw4_plot``) and judge records in the
helpers' format.  Here each spec becomes requests of the session protocol (one function, its
inputs, a budget), and the outcomes are put back into the records those judges read.  A module
moves off this bridge when its test in ``autograder/hidden/`` calls ``judging`` directly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Call", "HelperOutcome", "run_calls"]


@dataclass(frozen=True)
class Call:
    """One helper call of a legacy module: ``function`` (a helper name) on ``args`` within ``timeout`` s."""

    id: str
    function: str
    args: tuple = ()
    kwargs: dict | None = None
    timeout: float | None = None


@dataclass(frozen=True)
class HelperOutcome:
    """What the legacy judges read (``_common.Outcome``): status, the helper's record, a message."""

    status: str
    value: Any = None
    message: str = ""

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def _error(name: str, o) -> str:
    if o.status == "exception" or o.status == "malformed" or o.status == "skipped":
        return o.message
    if o.status == "timeout":
        return f"{name} {o.message}" if o.message.startswith("took") else f"{name} did not finish in time ({o.message})"
    return f"{name}: {o.message}"


def _whole(name: str, outcomes) -> HelperOutcome | None:
    """The outcome of the whole helper call when nothing came back from the function itself."""
    if outcomes and all(o.status == "missing" for o in outcomes):
        return HelperOutcome("ok", {"status": "missing", "name": name})
    if outcomes and not any(o.ok for o in outcomes) and outcomes[0].status in ("timeout", "crashed"):
        return HelperOutcome(outcomes[0].status, message=outcomes[0].message)
    return None


def _items(name: str, outcomes) -> HelperOutcome:
    whole = _whole(name, outcomes)
    if whole is not None:
        return whole
    return HelperOutcome("ok", {"status": "ok", "items": [
        {"ok": True, "value": o.value} if o.ok else {"ok": False, "error": _error(name, o)} for o in outcomes]})


def _point(value):
    try:
        arr = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        return None
    return (float(arr[0]), float(arr[1])) if arr.size == 2 else None


def _match(student, key, im1, im2, F, xs, ys, budget, timeout, cache):
    name = "epipolarCorrespondence"
    outcomes = student.map(name, [((float(x), float(y)), {}) for x, y in zip(xs, ys)], args=(im1, im2, F),
                           seconds=timeout, budget=budget)
    whole = _whole(name, outcomes)
    if whole is not None:
        return whole
    pts2 = np.full((len(xs), 2), np.nan)
    errors, first, reached = 0, "", 0
    for k, o in enumerate(outcomes):
        if o.status == "skipped":
            continue
        reached += 1
        point = _point(o.value) if o.ok else None
        if point is None:
            errors += 1
            first = first or (_error(name, o) if not o.ok else
                              "epipolarCorrespondence should return the two numbers (x2, y2)")
            continue
        pts2[k] = point
    cache[key] = pts2
    return HelperOutcome("ok", {"status": "ok", "pts2": pts2, "errors": errors, "first_error": first,
                                "reached": reached})


def _pipeline(student, key, im1, im2, F, xs, ys, C1, C2, budget, timeout, cache):
    if "triangulate" not in student.defined:
        return HelperOutcome("ok", {"status": "missing", "name": "triangulate"})
    pts2 = cache.get(key)
    if pts2 is None:
        found = _match(student, key, im1, im2, F, xs, ys, budget, timeout, cache)
        if found.status != "ok" or found.value.get("status") != "ok":
            return found
        pts2 = found.value["pts2"]
    pts1 = np.column_stack([np.asarray(xs, float), np.asarray(ys, float)])
    good = np.all(np.isfinite(pts2), axis=1)
    w = np.full((len(pts1), 3), np.nan)
    if not good.any():
        return HelperOutcome("ok", {"status": "ok", "w": w, "error": "no point was matched", "pts2": pts2})
    # The second call of the chain: the student's matches into the student's triangulate.
    o = student.map("triangulate", [((C1, pts1[good], C2, pts2[good]), {})], seconds=timeout)[0]
    if not o.ok:
        return HelperOutcome("ok", {"status": "ok", "w": w, "error": "triangulate: " + _error("triangulate", o),
                                    "pts2": pts2})
    value = o.value
    if isinstance(value, (tuple, list)) and value:
        value = value[0]
    try:
        w[good] = np.asarray(value, dtype=float).reshape(int(good.sum()), 3)
    except (TypeError, ValueError):
        return HelperOutcome("ok", {"status": "ok", "w": w, "error": "triangulate did not return (N, 3) points first",
                                    "pts2": pts2})
    return HelperOutcome("ok", {"status": "ok", "w": w, "error": "", "pts2": pts2})


def run_calls(student, calls) -> dict[str, HelperOutcome]:
    """The outcome of every legacy helper call, by call id, made through ``student.map``.

    ``student`` has ``map(function, inputs, args=, seconds=, budget=, figure=)`` and ``defined``
    (a sandbox ``Session`` or ``LocalStudent``).
    """
    out: dict[str, HelperOutcome] = {}
    cache: dict = {}
    for c in calls:
        timeout = float(c.timeout)
        if c.function == "__hw4_each":
            name, items, budget = c.args
            out[c.id] = _items(name, student.map(name, list(items), seconds=timeout, budget=budget))
        elif c.function == "__hw4_match":
            out[c.id] = _match(student, *c.args, timeout, cache)
        elif c.function == "__hw4_pipeline":
            out[c.id] = _pipeline(student, *c.args, timeout, cache)
        elif c.function == "__hw4_plot":
            name, args = c.args
            out[c.id] = _items(name, student.map(name, [(tuple(args), {})], seconds=timeout, figure=True))
        else:
            raise ValueError(f"calls: expected a helper call, got {c.function!r}")
    return out
