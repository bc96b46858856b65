"""The session's wall-clock budget grows by 1 / share under the CPU clock (a fake measured share; nothing timed).

On Gradescope every call's limit is CPU seconds and the code may get only a share of a CPU
(0.47 measured at 0.5 vCPU): those seconds then take 1 / share wall-clock seconds, and the
session's wall-clock backstop must grow by as much, so that a slow container is never cut short
by the wall clock before its CPU limits.
"""

from __future__ import annotations

import time
from types import SimpleNamespace

import pytest

from autograder.grading import budget
from autograder.channels.gradescope import bundle as gradescope
from autograder.grading import run as run_module
from autograder.inputs.config import quick_config
from autograder.inputs import build as inputs
from autograder.inputs.build import HiddenInputs
from autograder.sandbox import Isolation, ResourceLimits

CALL_SECONDS = 123.0  # what the fake checks may give student code in all, at time_scale 1


@pytest.fixture
def hidden(monkeypatch) -> HiddenInputs:
    monkeypatch.setattr(inputs, "call_seconds", lambda prepared, scale: CALL_SECONDS * scale)
    return HiddenInputs(quick_config(), None, {})


def loading(hidden: HiddenInputs) -> float:
    return hidden.config.load_timeout * (1 + budget.RESTARTS_BUDGETED)


def test_the_budget_grows_by_one_over_the_measured_share_under_the_cpu_clock(hidden):
    wall = budget.budget_of(hidden, ResourceLimits())
    assert wall == budget.budget_of(hidden) == budget.budget_of(hidden, ResourceLimits(clock="cpu", cpu_share=1.0))
    assert wall > hidden.call_seconds() + loading(hidden)
    for share in (0.47, 0.25):
        limits = ResourceLimits(clock="cpu", wall_factor=1.5 / share, cpu_share=share)
        assert budget.budget_of(hidden, limits) - loading(hidden) == pytest.approx((wall - loading(hidden)) / share)
    # The wall clock's limits are wall-clock seconds already: a share changes nothing there.
    assert budget.budget_of(hidden, ResourceLimits(clock="wall", cpu_share=0.47)) == wall


def test_the_share_is_checked():
    for bad in (0, -0.5, 1.5, float("nan"), True, "half"):
        with pytest.raises(ValueError, match="cpu_share"):
            ResourceLimits(clock="cpu", cpu_share=bad)
    limits = ResourceLimits(clock="cpu", wall_factor=3.2, cpu_share=0.47)
    assert ResourceLimits(**vars(limits)) == limits  # what Sandbox.describe/attach hand over


@pytest.fixture
def recorded(monkeypatch) -> list:
    """What the run asks its workers for (budget, timeout), none of it run: the run's workers are
    replaced by a recorder."""
    asked = []

    class Recorder:
        def run(self, argv, log, timeout):
            asked.append((float(argv[argv.index("--budget") + 1]), timeout))
            raise RuntimeError("recorded, not run")

        def kill(self):   # a run that raised is abandoned with its worker
            pass

    class Pool:
        started = 0

        def warm(self):
            pass

        def take(self):
            return Recorder()

        def close(self):
            pass

    monkeypatch.setattr(run_module, "WorkerPool", Pool)
    return asked


def fake_box(limits: ResourceLimits) -> SimpleNamespace:
    iso = Isolation("basic", None, False, False, False, (), weak=True)
    return SimpleNamespace(limits=limits, isolation=iso, describe=lambda: {})


def test_grading_gives_the_plugin_and_the_worker_the_grown_budget(hidden, recorded, tmp_path):
    (tmp_path / "sub").mkdir()
    for share in (1.0, 0.47):
        limits = ResourceLimits(clock="cpu", wall_factor=max(1.5 / share, 2.0), cpu_share=share)
        with pytest.raises(RuntimeError, match="recorded"), \
                run_module.GradingRun(hidden.config, hidden_inputs=hidden, sandbox=fake_box(limits)) as run:
            run.grade(tmp_path / "sub")
    (full, full_timeout), (half, half_timeout) = recorded
    assert full == pytest.approx(budget.budget_of(hidden)) and half == pytest.approx(budget.budget_of(hidden, limits))
    assert half - loading(hidden) == pytest.approx((full - loading(hidden)) / 0.47)
    assert half_timeout - half == pytest.approx((full_timeout - full) / 0.47)  # the pytest run's margin too


def test_a_deadline_too_close_to_grade_is_a_failure_that_says_so_not_an_internal_error(hidden, recorded, tmp_path):
    (tmp_path / "sub").mkdir()
    assert budget.too_late(None) is None
    assert budget.too_late(time.monotonic() + budget.DEADLINE_RESERVE + budget.MIN_SESSION + 60) is None
    # Setting up (the canary, say) took all but a few seconds of the platform's limit.
    deadline = time.monotonic() + budget.DEADLINE_RESERVE + budget.MIN_SESSION / 3
    with run_module.GradingRun(hidden.config, hidden_inputs=hidden, sandbox=fake_box(ResourceLimits()),
                               deadline=deadline) as run:
        staff: dict = {}
        result = run.grade(tmp_path / "sub", staff=staff)
    assert recorded == []  # no session was started to be cut short
    assert result.failure is not None and "time limit" in result.failure and "internal" not in result.failure
    assert any("time limit" in line for line in staff["log"])
    # With time left, the same run grades (here: asks its worker).
    with pytest.raises(RuntimeError, match="recorded"), \
            run_module.GradingRun(hidden.config, hidden_inputs=hidden, sandbox=fake_box(ResourceLimits()),
                                  deadline=time.monotonic() + 3600) as run:
        run.grade(tmp_path / "sub")
    assert len(recorded) == 1


def test_gradescope_measures_the_share_the_budget_uses():
    share, wall_factor = gradescope.clock_settings(2.0, 0.94)   # 0.94 CPU seconds in 2 s: 0.47 of a CPU
    assert share == pytest.approx(0.47)
    assert ResourceLimits(clock="cpu", wall_factor=wall_factor, cpu_share=share).wall_per_cpu == pytest.approx(1 / 0.47)
