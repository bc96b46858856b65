"""Small pieces shared by the check modules: reading what a student's function returned."""

from __future__ import annotations

import numpy as np

from .report import NOT_IMPLEMENTED, CheckReport, Outcome

__all__ = ["as_array", "fig", "finish", "run_failed", "stop_if_not_implemented", "unpack"]


def fig(x, digits: int = 3) -> str:
    """A number for a report line: 3 significant digits, 'inf' and 'nan' spelled out."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return str(x)
    return f"{v:.{digits}g}"


def as_array(value, shape: tuple, what: str):
    """(float array, "") when ``value`` is numeric of exactly ``shape`` (-1 = any length);
    (None, reason) otherwise.  Finiteness is left to the caller, which knows what NaN means."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None, f"{what}: expected a numeric array, got {type(value).__name__}"
    if arr.ndim != len(shape) or any(s != -1 and s != d for s, d in zip(shape, arr.shape)):
        want = "(" + ", ".join("N" if s == -1 else str(s) for s in shape) + ")"
        return None, f"{what}: expected shape {want}, got {arr.shape}"
    return arr, ""


def unpack(value, count: int, what: str):
    """(tuple of ``count`` items, "") when ``value`` is a tuple/list of that length; (None, reason)."""
    if isinstance(value, (tuple, list)) and len(value) == count:
        return tuple(value), ""
    got = f"a {type(value).__name__} of {len(value)}" if isinstance(value, (tuple, list)) else type(value).__name__
    return None, f"{what}: expected {count} results, got {got}"


def stop_if_not_implemented(report: CheckReport, out: Outcome) -> bool:
    """Record "not implemented yet" and return True when the first call says the stub is unwritten."""
    if out.status == "not implemented":
        report.items.clear()
        report.add(f"{report.title} runs", False, NOT_IMPLEMENTED)
        return True
    return False


def run_failed(report: CheckReport, out: Outcome, where: str) -> bool:
    """Record a failed call (an exception, or a stub) as one item; True when the call did not succeed."""
    if out.ok:
        return False
    # Only the first call decides "not implemented yet"; a later None is a result that is missing.
    why = "returned None (or raised NotImplementedError) here" if out.status == "not implemented" else out.message
    report.add(f"runs on {where}", False, why)
    return True


def finish(report: CheckReport, verbose: bool) -> CheckReport:
    if verbose:
        report.show()
    return report
