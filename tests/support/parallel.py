"""``fork_map``: a function over items in up to two forked processes (the suite's long sweeps).

The machines this runs on have two cores; the sweeps (tests/end_to_end/test_secret_sweep.py,
tests/judging_tests/test_fundamental_goals.py) are independent per secret, so two processes halve them.  Fork,
not spawn: the children inherit the module state the parent set up (exec'd student functions,
which cannot be pickled), so only the items and the results cross.  One process where fork is
unavailable or a single core is all there is.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable

__all__ = ["fork_map", "workers"]


def workers() -> int:
    """The processes ``fork_map`` uses: the cores this process may run on, at most two."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count() or 1
    return max(1, min(2, cores))


def fork_map(fn: Callable, items: Iterable) -> list:
    """``[fn(x) for x in items]``, in order; ``fn`` must be a module-level function, its results picklable."""
    from concurrent.futures import ProcessPoolExecutor

    items = list(items)
    n = workers()
    if n > 1 and len(items) > 1 and "fork" in multiprocessing.get_all_start_methods():
        with ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("fork")) as pool:
            return list(pool.map(fn, items))
    return [fn(x) for x in items]
