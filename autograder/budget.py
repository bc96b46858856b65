"""The one definition of a submission's session budget (wall-clock seconds for all its checks).

The grading run (``autograder.run``) computes it and hands it to the hidden pytest plugin
(``--budget``); the plugin computes it here too only when run by hand without one
(``python -m pytest autograder/hidden --submission PATH``).
"""

from __future__ import annotations

import time

__all__ = ["DEADLINE_RESERVE", "MARGIN", "RESTARTS_BUDGETED", "backstop_of", "budget_of"]

RESTARTS_BUDGETED = 3      # crashes or timeouts after which the session's time is still enough
MARGIN = 120.0             # seconds a pytest run may take beyond the session's budget (imports, judging)
DEADLINE_RESERVE = 30.0    # seconds kept before a deadline for judging what ran and writing the results


def budget_of(hidden, limits=None, deadline: float | None = None) -> float:
    """Wall-clock seconds of one submission's session: every check's time, loading and restarts.

    ``hidden``: ``HiddenInputs`` (its ``call_seconds()`` and ``config.load_timeout``); ``limits``:
    the sandbox's ``ResourceLimits`` or None.  Under the CPU clock (``limits.clock == "cpu"``,
    Gradescope) the checks' seconds are CPU seconds, which take 1 / ``limits.cpu_share``
    wall-clock seconds where the code gets only a share of a CPU: that part grows by as much, so
    that a slow container is never cut short by this wall-clock backstop before its CPU limits.
    Loading is limited in wall-clock seconds (``load_timeout``) whatever the clock.  With a
    ``deadline`` (``time.monotonic()``) the session ends ``DEADLINE_RESERVE`` seconds before it,
    if sooner (never below 1 s).
    """
    stretch = limits.wall_per_cpu if limits is not None else 1.0
    budget = (hidden.call_seconds() + 30) * stretch + hidden.config.load_timeout * (1 + RESTARTS_BUDGETED)
    if deadline is not None:
        budget = max(min(budget, deadline - time.monotonic() - DEADLINE_RESERVE), 1.0)
    return budget


def backstop_of(hidden, limits=None, deadline: float | None = None) -> float:
    """Seconds the grader waits for a whole pytest run before giving up on it: the budget plus
    ``MARGIN`` (stretched like the checks), ending 5 s before ``deadline`` if sooner, never
    shorter than the budget itself."""
    budget = budget_of(hidden, limits, deadline)
    stretch = limits.wall_per_cpu if limits is not None else 1.0
    backstop = budget_of(hidden, limits) + MARGIN * stretch
    if deadline is not None:
        backstop = max(min(backstop, deadline - time.monotonic() - 5.0), budget)
    return backstop
