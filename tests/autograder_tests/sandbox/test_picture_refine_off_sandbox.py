"""Q2's picture through the real sandbox: the row "your F, refineF switched off" is drawn exactly
when the self-check draws it, i.e. when the student's eightpoint called refineF during its run with
refineF switched off.

The grader makes that run in the sandboxed child (the request's ``swap``), and the child reports how
many times refineF was called in it; the pictures module (``q2_eightpoint.run``) decides from that
count, as it does in the self-check.

1. In this process (fast): the picture step's switched-off call goes through the student's
   ``map`` with the swap (a ``LocalStudent`` here) and the row follows its count; ``run`` takes
   the grader's switched-off call when the function has one, and decides from its count alone.
2. A sandbox session: each input of a switched-off request reports its own count of refineF's
   calls (2 for an input calling the kit's refineF twice, 1 for one calling it once and then
   raising, 0 for one that never calls it); a count the student's code forges is believed only as
   a bounded non-negative int; a request without the swap reports none.
3. A whole batch (grading worker, sandbox, the real pictures module), on the answer key with one
   cell replaced:

   - an eightpoint that builds its design matrix for F transposed and polishes it with refineF:
     the F as returned is a near miss (its lines pass near the matches), while the F with refineF
     switched off misses them by pixels: its row is drawn, measured on the figure's own measures;
   - an eightpoint that never calls refineF: no such row.
"""

from __future__ import annotations

import json

import nbformat
import numpy as np
import pytest

import corpus
from autograder.feedback import pictures as step
from autograder.hidden.plugin import LocalStudent, Student
from autograder.sandbox import ResourceLimits, Sandbox
from corpus import variants

LIMITS = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)
SUBMISSIONS = {"transposed_refined": variants.EIGHTPOINT_TRANSPOSED_REFINED,
               "no_refineF": variants.EIGHTPOINT_NO_REFINE}


def _defined(source: str):
    """``eightpoint`` of a corpus cell, with the kit's refineF as the key's notebooks import it."""
    from starter import refineF

    scope = {"refineF": refineF}
    exec(source, scope)  # noqa: S102 - the kit's own corpus
    return scope["eightpoint"]


class _Swaps(LocalStudent):
    """A LocalStudent that notes the swap of each request."""

    def __init__(self, functions):
        super().__init__(functions)
        self.swaps = []

    def map(self, function, inputs, *, swap=None, **kw):
        self.swaps.append(swap)
        return super().map(function, inputs, swap=swap, **kw)


def _outputs(eightpoint) -> tuple[dict, list]:
    student = _Swaps({"eightpoint": eightpoint})
    return step.run_public(student, "Q2"), student.swaps


def test_the_picture_steps_switched_off_call_is_the_students_with_the_swap():
    polished, swaps = _outputs(_defined(variants.EIGHTPOINT_TRANSPOSED_REFINED))
    assert set(polished) >= {"F", "F_refineF_off"}, polished
    assert swaps.count({"refineF": "off"}) == 1, swaps   # the second of eightpoint's three requests
    plain, _ = _outputs(_defined(variants.EIGHTPOINT_NO_REFINE))
    assert "F" in plain and "F_refineF_off" not in plain, plain


def test_run_takes_the_graders_switched_off_call_and_decides_from_its_count():
    from starter.checks.pictures import q2_eightpoint

    right = _defined(variants.EIGHTPOINT_NO_REFINE)
    seen = []

    def graders(calls):
        def eightpoint(*args):
            return right(*args)

        def switched_off(*args):
            seen.append(len(args))
            return np.eye(3)[::-1], calls

        eightpoint.refineF_switched_off = switched_off
        return eightpoint

    assert "F_refineF_off" not in q2_eightpoint.run({"eightpoint": graders(0)})
    out = q2_eightpoint.run({"eightpoint": graders(2)})
    assert np.array_equal(out["F_refineF_off"], np.eye(3)[::-1])
    assert seen == [3, 3]  # (pts1, pts2, M): the grader's call made the run, not the in-process switch


COUNTED = """
import numpy as np
from starter import refineF
import core.refine_switch as _switch


def kit_twice(F):
    F = refineF(np.asarray(F, float), np.zeros((8, 2)), np.zeros((8, 2)))
    return refineF(F, np.zeros((8, 2)), np.zeros((8, 2)))


def plain(F):
    return np.asarray(F, float) * 2


def forged(F, n):
    if _switch._runs:
        _switch._runs[-1].calls = n
    return F


def raises(F):
    refineF(F, np.zeros((8, 2)), np.zeros((8, 2)))
    raise ValueError("after refineF")
"""


@pytest.mark.slow
def test_a_switched_off_request_reports_each_inputs_count_and_nothing_forged():
    F = [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [-1.0, 1.0, 0.0]]
    off = {"refineF": "off"}
    with Sandbox(limits=LIMITS) as box, box.session(COUNTED, load_timeout=30, budget=120) as session:
        student = Student(session)

        def counts(name, inputs, swap=off):
            outcomes = student.map(name, [(a, {}) for a in inputs], seconds=30, swap=swap)
            return [o.refineF_calls for o in outcomes], outcomes

        twice, outcomes = counts("kit_twice", [(F,), (F,)])
        assert twice == [2, 2] and all(o.ok for o in outcomes), outcomes   # per input, not summed
        assert counts("plain", [(F,)])[0] == [0]
        assert counts("kit_twice", [(F,)], swap=None)[0] == [None]          # not switched off: no count
        assert counts("forged", [(F, -5), (F, 10**12), (F, "7")])[0] == [0, None, 0]
        said, outcomes = counts("raises", [(F,)])
        assert said == [1] and outcomes[0].status == "exception"


@pytest.fixture(scope="module")
def q2_figures(tmp_path_factory) -> dict:
    """name -> the Q2 entry of the submission's figures index (title, alt, measures, file)."""
    pytest.importorskip("starter.checks.pictures", reason="the pictures module is not in this kit yet")
    from autograder.channels.batch import grade_batch
    from autograder.inputs.config import quick_config

    root = tmp_path_factory.mktemp("refine_off")
    paths = []
    for name, source in SUBMISSIONS.items():
        nbs = corpus.notebooks("key")
        corpus.replace_function(nbs, "eightpoint", source)
        folder = root / "subs" / name
        folder.mkdir(parents=True)
        for stem, nb in nbs.items():
            nbformat.write(nb, folder / f"{stem}.ipynb")
        paths.append(folder)
    records = grade_batch(paths, root / "out", jobs=2, config=quick_config(), progress=False, limits=LIMITS)
    out = {}
    for name, record in zip(SUBMISSIONS, records):
        assert record.failure is None, record.failure
        index = json.loads((record.folder / "figures" / "figures.json").read_text())
        assert "file" in index["Q2"], index["Q2"]
        out[name] = index["Q2"]
    return out


@pytest.mark.slow
def test_a_polished_transposed_F_gets_the_refineF_off_row(q2_figures):
    q2 = q2_figures["transposed_refined"]
    m = q2["measures"]
    assert "refineF_off_mean_distance_px" in m, m
    assert m["mean_distance_px"] < 1.0, m            # polished into a near miss
    assert m["refineF_off_mean_distance_px"] > 2.0, m  # switched off: the transposed F misses
    assert "refineF switched off" in q2["alt"]


@pytest.mark.slow
def test_an_eightpoint_without_refineF_gets_no_such_row(q2_figures):
    q2 = q2_figures["no_refineF"]
    assert "refineF_off_mean_distance_px" not in q2["measures"], q2["measures"]
    assert "refineF switched off" not in q2["alt"]
    assert q2["measures"]["mean_distance_px"] < 1.0
