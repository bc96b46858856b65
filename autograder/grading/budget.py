"""The one definition of a submission's session budget (wall-clock seconds for all its checks).

The grading run (``autograder.grading.run``) computes it and hands it to the hidden pytest plugin
(``--budget``); the plugin computes it here too only when run by hand without one
(``python -m pytest autograder/hidden --submission PATH``).
"""

from __future__ import annotations

import time

__all__ = ["DEADLINE_RESERVE", "MARGIN", "MIN_SESSION", "RESTARTS_BUDGETED", "backstop_of", "budget_of", "too_late"]

RESTARTS_BUDGETED = 3      # crashes or timeouts after which the session's time is still enough
MARGIN = 120.0             # seconds a pytest run may take beyond the session's budget (imports, judging)
DEADLINE_RESERVE = 30.0    # seconds kept before a deadline for judging what ran and writing the results
MIN_SESSION = 15.0         # seconds below which a session could not even start pytest and load the code


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


def too_late(deadline: float | None) -> str | None:
    """Why a submission cannot be graded before ``deadline`` (``time.monotonic()``): fewer than
    ``MIN_SESSION`` seconds are left once ``DEADLINE_RESERVE`` is kept (setting up, the canary
    say, took the rest of the platform's time limit); None when there is time, or no deadline."""
    if deadline is None:
        return None
    left = deadline - time.monotonic() - DEADLINE_RESERVE
    if left >= MIN_SESSION:
        return None
    return (f"the time limit left {max(left, 0.0):.0f} s to run the checks, fewer than the {MIN_SESSION:.0f} s "
            "they need at the least (setting up took the rest); the course staff can raise the time limit")
