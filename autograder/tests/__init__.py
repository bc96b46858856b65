"""The hidden tests: one module per solutions module, each with ``prepare``, ``calls`` and ``judge``.

- ``prepare(scenes)`` (in the grader, once per batch) cuts the module's hidden inputs from the
  scenes and computes what the reference gives on them;
- ``calls(prepared, time_scale)`` lists the sandbox calls (plain-data arguments only);
- ``judge(prepared, outcomes)`` turns what came back into the module's ``QuestionResult``s.

All calls go through the helpers of ``_child_helpers.py`` (sent as the job's last unit), so
that one call runs a student function on all its inputs.  This module puts the pieces together:
:func:`build_hidden_inputs`, :func:`all_calls`, :func:`judge_all`.
"""

from __future__ import annotations

import traceback
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from autograder.config import GradingConfig
from autograder.results import QuestionResult, TestResult
from autograder.sandbox import Call
from autograder.submission import SourceUnit
from core.manifest import QUESTIONS, question

from . import (
    bundle,
    correspondence,
    essential,
    fundamental,
    multiview,
    pose,
    triangulation,
)
from .hidden import Scenes, make_scenes

__all__ = [
    "HELPER_UNIT",
    "MODULES",
    "HiddenInputs",
    "all_calls",
    "build_hidden_inputs",
    "functions_of_question",
    "judge_all",
]

MODULES = (fundamental, essential, triangulation, pose, correspondence, bundle, multiview)

HELPER_ORIGIN = "autograder helpers"
HELPER_UNIT = SourceUnit(origin=HELPER_ORIGIN, line=1,
                         source=(Path(__file__).with_name("_child_helpers.py")).read_text(encoding="utf-8"))


@dataclass(frozen=True, eq=False)
class HiddenInputs:
    """The scenes and each module's prepared inputs and reference results (never leave the grader)."""

    config: GradingConfig
    scenes: Scenes
    prepared: dict = field(default_factory=dict)


@lru_cache(maxsize=4)
def build_hidden_inputs(config: GradingConfig) -> HiddenInputs:
    """Make (once per config and process) every hidden input and the reference's results on them."""
    scenes = make_scenes(config)
    return HiddenInputs(config, scenes, {m.__name__: m.prepare(scenes) for m in MODULES})


def all_calls(hidden: HiddenInputs) -> list[Call]:
    """Every sandbox call of every module, in manifest order."""
    scale = hidden.config.time_scale
    return [c for m in MODULES for c in m.calls(hidden.prepared[m.__name__], scale)]


def functions_of_question(qid: str) -> tuple[str, ...]:
    return question(qid).functions


def _internal_error(qid: str) -> QuestionResult:
    q = question(qid)
    return QuestionResult.of(qid, [TestResult(
        "graded", 0.0, float(q.points), False,
        "The autograder could not judge this question because of an internal error; the course staff "
        "has been told and will grade it.")])


def judge_all(hidden: HiddenInputs, outcomes: dict, staff_log: list | None = None) -> list[QuestionResult]:
    """Every autograded question's result, in manifest order.

    A failure of the grader's own judging code (a bug, not the student's) gives that question a
    zero that says so, and its traceback goes to ``staff_log``; the other questions still count.
    """
    found: dict[str, QuestionResult] = {}
    for m in MODULES:
        try:
            for qr in m.judge(hidden.prepared[m.__name__], outcomes):
                found[qr.id] = qr
        except Exception:  # noqa: BLE001 - one question's bug must not lose the others
            if staff_log is not None:
                staff_log.append(f"judging {m.__name__} failed:\n{traceback.format_exc()}")
            for qid in m.QUESTIONS:
                found[qid] = _internal_error(qid)
    return [found[q.id] for q in QUESTIONS if q.id in found]
