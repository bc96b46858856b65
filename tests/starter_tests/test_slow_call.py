"""A slow call says so while it runs, and a SciPy optimiser that gives up is named (starter.slow_call).

The last test runs Q5's notebook with a bundleAdjustment written as the handout reads
(scipy.optimize.minimize on the summed squares, about two minutes on the RANSAC inliers) and
reads the times at which its output lines reach the notebook: the warning comes within 10 s.
"""

from __future__ import annotations

import shutil
import sys
import time

import nbformat
import numpy as np
import pytest
import scipy.optimize
from scipy.optimize import minimize  # bound by name at the top level, as students write it

from core.paths import KIT_ROOT
from starter.slow_call import LEAST_SQUARES_ADVICE, watched


def test_a_slow_call_is_announced_while_it_runs():
    heard = []

    def slow(x):
        time.sleep(1.0)
        return x + 1

    start = time.perf_counter()
    run = watched(slow, after=0.2, say=lambda line: heard.append((time.perf_counter() - start, line)))
    assert run(1) == 2
    (when, line), (_, took) = heard
    assert when < 0.9 and line.startswith("slow is still running after 0.2 s") and LEAST_SQUARES_ADVICE in line
    assert took == "slow took 1 s." and run.last_watch.warned and run.last_watch.seconds >= 1.0


def test_a_quick_call_says_nothing():
    heard = []
    run = watched(lambda: 3, name="quick", after=5.0, say=heard.append)
    assert run() == 3 and heard == [] and not run.last_watch.warned


def test_an_optimiser_reporting_failure_is_named_and_the_optimisers_are_put_back():
    originals = (scipy.optimize.minimize, scipy.optimize.least_squares)
    heard = []

    def fit():
        return minimize(lambda x: float(np.sum((x - 3.0) ** 4)), np.zeros(5), options={"maxiter": 1})

    run = watched(fit, after=5.0, say=heard.append)
    assert run().success is False
    (line,) = heard
    assert line.startswith("fit: scipy.optimize.minimize reported failure (success=False: ")
    assert (scipy.optimize.minimize, scipy.optimize.least_squares) == originals
    assert fit.__globals__["minimize"] is originals[0]

    def fails():
        scipy.optimize.least_squares(lambda x: x, np.ones(2))
        raise ValueError("after the fit")

    with pytest.raises(ValueError, match="after the fit"):
        watched(fails, say=heard.append)()
    assert (scipy.optimize.minimize, scipy.optimize.least_squares) == originals


def test_a_converged_least_squares_is_not_a_failure():
    heard = []
    run = watched(lambda: scipy.optimize.least_squares(lambda x: x - 2.0, np.zeros(3)), name="ls", say=heard.append)
    run()
    assert heard == [] and [name for name, _ in run.last_watch.results] == ["least_squares"]


# --------------------------------------------------------- the notebook, as a student runs it


@pytest.fixture
def literal_minimize_q5(tmp_path):
    """Q5's answer-key notebook with the handout-literal bundleAdjustment, beside the key's q2 and q3."""
    sys.path.insert(0, str(KIT_ROOT / "tests"))
    try:
        from corpus.variants import BA_MINIMIZE
    finally:
        sys.path.remove(str(KIT_ROOT / "tests"))
    key = KIT_ROOT / "notebooks" / "key"
    for stem in ("q2_eightpoint", "q3_metric_reconstruction"):
        shutil.copy(key / f"{stem}.ipynb", tmp_path)
    nb = nbformat.read(key / "q5_bundle_adjustment.ipynb", as_version=4)
    (cell,) = [c for c in nb.cells if c.cell_type == "code" and "def bundleAdjustment(" in c.source]
    cell.source = BA_MINIMIZE
    return nb, tmp_path


@pytest.mark.slow
def test_the_before_after_cell_warns_within_10_s_with_a_literal_minimize(literal_minimize_q5):
    import asyncio

    from jupyter_core.utils import ensure_async
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError, CellTimeoutError

    nb, folder = literal_minimize_q5
    WARNING = "bundleAdjustment is still running"  # noqa: N806 - heard once: the kernel is interrupted
    (target,) = [k for k, c in enumerate(nb.cells) if c.cell_type == "code" and "watched(bundleAdjustment)" in c.source]
    started, heard = {}, []

    class Timed(NotebookClient):
        """Records when each cell starts and when each line of its printed output arrives."""

        def output(self, outs, msg, display_id, cell_index):
            if msg["msg_type"] == "stream":
                heard.append((cell_index, time.monotonic(), msg["content"]["text"]))
                if cell_index == target and WARNING in msg["content"]["text"]:
                    # Heard: the rest of the minutes-long minimize proves nothing more.
                    asyncio.ensure_future(ensure_async(self.km.interrupt_kernel()))
            return super().output(outs, msg, display_id, cell_index)

    client = Timed(nb, timeout=20, kernel_name="python3", resources={"metadata": {"path": str(folder)}},
                   on_cell_execute=lambda cell, cell_index: started.__setitem__(cell_index, time.monotonic()))
    # The literal minimize runs for minutes: the cell is interrupted once the warning is heard, or
    # stopped at its 20 s limit (twice the promise, for a loaded machine) if it never comes.
    with pytest.raises((CellExecutionError, CellTimeoutError)):
        client.execute()
    lines = [(t - started[target], text) for k, t, text in heard if k == target]
    warned = [(t, text) for t, text in lines if WARNING in text]
    assert warned, lines
    print(f"the warning came {warned[0][0]:.1f} s after the cell started")
    assert warned[0][0] < 10.0, warned
    assert "least_squares" in warned[0][1]
