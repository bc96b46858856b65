"""Grading inside Gradescope's container: what ``run_autograder`` calls for each submission.

``python -m autograder gradescope run [--root /autograder]`` grades ``<root>/submission`` and
writes ``<root>/results/results.json``; the bundle it runs in is built by
``autograder.channels.gradescope.bundle`` (which also describes its contents and the time limits).  Here only:
read the bundle's settings, measure the container (``calibration``: how slow its cores are, what
share of a CPU it gives), make the limits from that, and hand them to one
``autograder.grading.run.GradingRun`` (bundled hidden inputs, the bundled answer key for the canary,
all of ``<root>`` hidden), which grades the submission with its pictures of the public data
(added to results.json by ``autograder.channels.gradescope.pictures``).  Whatever fails, results.json is
written with a zero that says why.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
import time
import traceback
from pathlib import Path

from core.files import list_files

from .pictures import add_pictures
from autograder.feedback.results import SubmissionResult

__all__ = ["BROKEN", "CONFIG_NAME", "DEFAULT_TIME_FACTOR", "DEFAULT_VISIBILITY", "HIDDEN_INPUTS_DIR", "KEY_NAME",
           "REFERENCE_CALIBRATION", "calibrate", "calibration", "check_visibility", "clock_settings",
           "grade_gradescope", "limits_scale"]

# The bundle's members this side reads (``autograder.channels.gradescope.bundle`` writes them).
CONFIG_NAME = "grader_config.json"
HIDDEN_INPUTS_DIR = "hidden_inputs"
KEY_NAME = "answer_key.zip"
DEFAULT_TIME_FACTOR = 0.1  # of each check's designed limit, at the reference machine's speed
DEFAULT_VISIBILITY = {"scores": "visible", "checks": "after_published"}
# Seconds the calibration loop takes on the reference machine (2 cores, Python 3.11, idle).
REFERENCE_CALIBRATION = 0.19
_CALIBRATION_LOOPS = 4_000_000
_SLOWNESS_RANGE = (1.0, 8.0)  # never tighter than at the reference speed; at most 8 times looser
_WALL_FACTOR_RANGE = (2.0, 16.0)  # the wall-clock backstop of a call, in multiples of its CPU seconds
BROKEN = ("The autograder is broken right now, so this submission was not graded (score 0 for now). "
          "This is not a problem with your work: the autograder failed its own self-test (its answer key "
          "did not get full marks). The course staff can see why; please resubmit later or contact them.")


def check_visibility(visibility) -> dict:
    """``visibility`` (group -> when) checked and completed with ``DEFAULT_VISIBILITY``; ValueError otherwise."""
    from autograder.feedback.results import VISIBILITIES

    out = dict(DEFAULT_VISIBILITY)
    for group, when in dict(visibility or {}).items():
        if group not in out or when not in VISIBILITIES:
            raise ValueError(f"visibility: expected GROUP=WHEN with GROUP in {sorted(out)} and WHEN in "
                             f"{list(VISIBILITIES)}, got {group}={when}")
        out[group] = when
    return out


# ------------------------------------------------------------------------------------------------
# grading on Gradescope


def submission_candidates(folder: Path) -> list[Path]:
    # Listed without recursion: a folder thousands of levels deep must not stop the run.
    return sorted(p for p, _ in list_files(folder).files
                  if p.suffix.lower() in (".ipynb", ".py", ".zip")
                  and not any(part.startswith(".") or part == "__MACOSX"
                              for part in p.relative_to(folder).parts))


def _submission_path(folder: Path) -> tuple[Path | None, str | None]:
    """What to grade in Gradescope's submission folder, or (None, why not).

    Students upload the notebooks, or one zip of them that Gradescope may leave packed.
    """
    if not folder.is_dir():
        return None, "no submission folder was found"
    files = submission_candidates(folder)
    if not files:
        return None, ("the submission holds no notebooks: upload your .ipynb files "
                      "(q2_eightpoint.ipynb, ...) or one .zip of them")
    zips = [p for p in files if p.suffix.lower() == ".zip"]
    if len(zips) == len(files) == 1:
        return zips[0], None
    return folder, None


def grade_gradescope(root: str | Path = "/autograder") -> SubmissionResult:
    """Grade ``<root>/submission`` and write ``<root>/results/results.json``; return the result.

    Never raises for anything the submission does: an unusable submission, a sandbox that
    cannot start or a grader error gives ``SubmissionResult.failed`` with the reason (grader
    tracebacks go to stdout, which Gradescope shows to staff only).  The tests' visibility and
    the time factor come from the bundle's BUNDLE.json (defaults when it cannot be read).
    """
    root = Path(root)
    results = root / "results"
    results.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()
    settings = _bundle_settings(root / "source")
    timing: dict = {}
    staff: dict = {}
    path, why = _submission_path(root / "submission")
    if path is None:
        result = SubmissionResult.failed(why, execution_time=time.monotonic() - start)
    else:
        try:
            result = _grade(path, root, settings["time_factor"], timing, staff, deadline=_deadline(start),
                            pictures=settings["pictures"])
        except Exception:  # noqa: BLE001 - whatever broke, the student still gets a result
            traceback.print_exc(file=sys.stdout)
            result = SubmissionResult.failed("the autograder hit an internal error; the course staff can see its log",
                                             execution_time=time.monotonic() - start)
    data = result.to_gradescope(visibility=settings["visibility"])
    # The pictures of the public data the result carries (the run's picture step), as one unscored
    # test per question, never shown earlier than that question's checks.
    add_pictures(data, result, result.pictures)
    data["extra_data"]["timing"] = timing  # staff only: extra_data is not shown to students
    if "canary" in staff:
        data["extra_data"]["canary"] = staff["canary"]
    # What the code left in shared temporary folders (and could not be removed); its disk quota;
    # what of its uid outlived the sweep.
    for key in ("removed", "over_quota", "survived"):
        if staff.get(key):
            data["extra_data"][key] = staff[key]
    from core.text import write_atomic

    write_atomic(results / "results.json", json.dumps(data, indent=2, allow_nan=False), mode=0o600)
    return result


def _bundle_settings(source: Path) -> dict:
    """Visibility, time factor and pictures (a bool) from ``source/BUNDLE.json``, each checked;
    defaults otherwise."""
    out = {"visibility": dict(DEFAULT_VISIBILITY), "time_factor": DEFAULT_TIME_FACTOR, "pictures": True}
    try:
        info = json.loads((source / "BUNDLE.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        print("BUNDLE.json unreadable: default visibility and time factor")
        return out
    try:
        out["visibility"] = check_visibility(info.get("visibility"))
    except ValueError as exc:
        print(f"BUNDLE.json: {exc}; default visibility")
    factor = info.get("time_factor", DEFAULT_TIME_FACTOR)
    if isinstance(factor, (int, float)) and not isinstance(factor, bool) and 0 < factor <= 10:
        out["time_factor"] = float(factor)
    if info.get("pictures") is False:
        out["pictures"] = False
    return out


def calibration(rounds: int = 3) -> tuple[float, float]:
    """``(wall, cpu)``: the wall-clock and the CPU seconds this machine takes, now, for the fixed
    single-threaded loop (medians of ``rounds``).

    CPU seconds measure the cores (what the CPU clock of the sandbox counts); wall-clock seconds
    also count a container's CPU quota and busy neighbours, so ``cpu / wall`` is the share of a
    CPU the code gets here.
    """
    walls, cpus = [], []
    for _ in range(max(int(rounds), 1)):
        t, c = time.perf_counter(), time.process_time()
        x = 0
        for i in range(_CALIBRATION_LOOPS):
            x = (x * 31 + i) % 1_000_003
        cpus.append(time.process_time() - c)
        walls.append(time.perf_counter() - t)
    mid = len(walls) // 2
    return sorted(walls)[mid], sorted(cpus)[mid]


def calibrate(rounds: int = 3) -> float:
    """Wall-clock seconds this machine takes, now, for the fixed loop (``calibration``'s first)."""
    return calibration(rounds)[0]


def clock_settings(wall: float, cpu: float) -> tuple[float, float]:
    """``(share, wall_factor)`` from a ``calibration``: the share of a CPU the code gets here
    (``cpu / wall``, in [0.05, 1]) and the multiple of a call's CPU seconds after which the
    grader kills a call that waits instead of computing (1.5 / share, in ``_WALL_FACTOR_RANGE``)."""
    for name, v in (("wall", wall), ("cpu", cpu)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v > 0 and math.isfinite(v)):
            raise ValueError(f"{name}: expected a positive number of seconds, got {v!r}")
    share = min(max(cpu / wall, 0.05), 1.0)
    lo, hi = _WALL_FACTOR_RANGE
    return share, min(max(1.5 / share, lo), hi)


def limits_scale(measured: float, time_factor: float = DEFAULT_TIME_FACTOR) -> tuple[float, float]:
    """``(slowness, time scale)``: how much slower than the reference machine ``measured`` (the
    seconds of the calibration loop, CPU seconds on Gradescope) is, clipped to ``_SLOWNESS_RANGE``,
    and the factor every check's designed time limit is multiplied by here (``time_factor * slowness``)."""
    if not (isinstance(measured, (int, float)) and measured > 0 and math.isfinite(measured)):
        raise ValueError(f"measured: expected a positive number of seconds, got {measured!r}")
    lo, hi = _SLOWNESS_RANGE
    slowness = min(max(measured / REFERENCE_CALIBRATION, lo), hi)
    return slowness, time_factor * slowness


def _bundled_inputs(source: Path, config):
    """The hidden inputs the bundle carries for ``config``, or None (then they are made here)."""
    from autograder.inputs import build as inputs

    folder = source / HIDDEN_INPUTS_DIR
    if not folder.is_dir():
        return None
    try:
        os.chmod(folder, 0o700)  # setup.sh makes it so; an unzip by hand may not
        return inputs.load(folder, config)
    except (OSError, ValueError, EOFError, AttributeError, ImportError) as exc:
        print(f"bundled hidden inputs not used ({type(exc).__name__}: {exc}); making them now")
        return None


def _deadline(start: float) -> float | None:
    """``time.monotonic()`` by which run_autograder's ``timeout`` stops this process (it passes its limit
    as HW4_GRADE_TIME_LIMIT), less what writing results.json needs; None when no limit was passed."""
    raw = os.environ.get("HW4_GRADE_TIME_LIMIT", "")
    try:
        limit = float(raw)
    except ValueError:
        return None
    return start + limit - 10.0 if math.isfinite(limit) and limit > 0 else None


def _grade(path: Path, root: Path, time_factor: float = DEFAULT_TIME_FACTOR,
           timing: dict | None = None, staff: dict | None = None, deadline: float | None = None,
           pictures: bool = True) -> SubmissionResult:
    from autograder.grading import canary
    from autograder.inputs.config import load_config
    from autograder.inputs.build import build_hidden_inputs
    from autograder.grading.run import GradingRun
    from autograder.sandbox import ResourceLimits

    timing = timing if timing is not None else {}
    staff = staff if staff is not None else {}
    source = root / "source"
    # environ={}: on Gradescope nothing but the bundled file decides the hidden inputs.
    config = load_config(source / CONFIG_NAME, environ={})
    t = time.monotonic()
    hidden = _bundled_inputs(source, config)
    timing["hidden_inputs"] = "bundled" if hidden is not None else "made"
    hidden = hidden or build_hidden_inputs(config)
    timing["hidden_inputs_seconds"] = round(time.monotonic() - t, 3)
    wall, cpu = calibration()
    slowness, scale = limits_scale(cpu, time_factor)  # CPU seconds: how slow this container's cores are
    share, wall_factor = clock_settings(wall, cpu)
    timing.update(clock="cpu", calibration_seconds=round(wall, 4), calibration_cpu_seconds=round(cpu, 4),
                  slowness=round(slowness, 3), cpu_share=round(share, 3), wall_factor=round(wall_factor, 2),
                  time_scale=round(config.time_scale * scale, 4))
    # The same inputs with this container's limits (the checks read them from config.time_scale).
    hidden = dataclasses.replace(hidden, config=dataclasses.replace(config, time_scale=config.time_scale * scale),
                                 scenes=None)
    limits = ResourceLimits(clock="cpu", wall_factor=wall_factor, cpu_share=share)
    key = source / KEY_NAME
    # The run records the bundle's settings (``config``); it grades with this container's limits.
    # Hidden: all of root (the grader, the results, Gradescope's metadata, the answer key).
    # pictures: the submission's result carries the pictures of the public data (not the canary's),
    # unless the bundle was built without them.
    with GradingRun(config, hidden_inputs=hidden, hide=[root], limits=limits, kit_root=source, deadline=deadline,
                    key=key if key.is_file() else None, pictures=pictures) as run:
        # Wall-clock s, grown by 1 / share, ending before the platform's kill.
        timing["session_budget"] = round(run.session_budget(), 1)
        try:
            run.open()
        except canary.CanaryFailed as exc:
            timing["canary_seconds"] = run.timing.get("canary_seconds")
            staff["canary"] = {"passed": False, "reason": str(exc)}
            print(f"AUTOGRADER BROKEN (the canary failed; the submission was not graded): {exc}")
            return run.failed(BROKEN)
        timing["canary_seconds"] = run.timing.get("canary_seconds")
        report = run.canary_report
        staff["canary"] = {"passed": True, "score": report.score, "max_score": report.max_score}
        return run.grade(path, staff=staff)
