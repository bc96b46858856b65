"""Small pieces shared by the check modules: reading what a student's function returned, finishing a report."""

from __future__ import annotations

from judging.verdict import Malformed

from .report import NOT_IMPLEMENTED, CheckReport, Outcome

__all__ = ["finish", "read_or_report", "run_failed", "stop_if_not_implemented"]


def read_or_report(report: CheckReport, reader, value, *args, label: str):
    """``reader(value, *args)`` (a judging reader), or None after adding a failed item ``label`` saying why."""
    try:
        return reader(value, *args)
    except Malformed as exc:
        report.add(label, False, str(exc))
        return None


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


def finish(report: CheckReport, verbose: bool, fn=None, root=None) -> CheckReport:
    """Print the report when ``verbose``; then, in a notebook, the figure of ``fn`` (the student's
    function) on the public data (starter.checks.pictures; "figure not drawn: why" when it cannot be)."""
    if verbose:
        report.show()
        if fn is not None:
            from .pictures import show_after_check

            show_after_check(report.title, fn, root)
    return report


