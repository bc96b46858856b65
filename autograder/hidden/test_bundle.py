"""Q5: ``rodriguesResidual`` and ``bundleAdjustment`` on hidden two-view problems (judging.bundle).

Each problem views the points of a hidden temple scene from a second camera swung further round,
with 0.5 px of noise; the start is deliberately off (rotation 1-2 degrees, translation direction 5
degrees), |t| = 1 as ``findM2`` gives, the points triangulated from it.

- ``rodriguesResidual`` must return the handout's residuals, in the handout's layout (or their
  negatives), at the start of each problem and at a perturbed x.
- ``bundleAdjustment``, one test per problem: the reprojection error recomputed from the returned
  M2 and w, full marks within 50 % of the optimum, partial credit on a log scale from the start;
  and the reconstruction compared with the start's after a similarity alignment.  Any gauge is
  right (the handout fixes no scale); |t| is not judged.
- M2 must hold a rotation, and o1, o2 the errors before and after.
"""

from __future__ import annotations

import pytest

from autograder.inputs.cases import M1, SECONDS
from autograder.feedback.words import read_returned
from judging import bundle as jb
from judging.verdict import Malformed, figure_text

_PROBLEMS = 2   # the hidden scenes' first two (config.temples has at least two)


@pytest.fixture(scope="session")
def bundle(hidden):
    """The prepared inputs (``autograder.inputs.bundle.Bundle``)."""
    return hidden.prepared["bundle"]


@pytest.fixture(scope="session")
def adjusted(student, bundle) -> list:
    """Per problem: (result verdict, rotation verdict, reported-errors verdict), or the Malformed."""
    inputs = [(pr.K1, M1, pr.p1, pr.K2, pr.M2_init, pr.p2, pr.w_init) for pr in bundle.problems]
    outcomes = student.each("bundleAdjustment", inputs, seconds=SECONDS["bundleAdjustment"], slack=5)
    out = []
    for pr, args, o in zip(bundle.problems, inputs, outcomes):
        try:
            M2, w, o1, o2 = read_returned("bundleAdjustment", o, lambda v, n=len(pr.p1): jb.read_ba(v, n), args)
        except Malformed as exc:
            out.append(exc)
            continue
        args = (pr.K1, pr.K2, pr.p1, pr.p2, pr.M2_init, pr.w_init)
        out.append((jb.result(M2, w, *args, pr.optimum), jb.rotation(M2), jb.reported_errors(o1, o2, M2, w, *args)))
    return out


@pytest.mark.points(6, question="Q5", name="rodriguesResidual returns the handout's residuals")
def test_rodriguesResidual_returns_the_handouts_residuals(student, bundle, score):
    cases = bundle.residual_inputs
    outcomes = student.each("rodriguesResidual", [c.args for c in cases], seconds=SECONDS["rodriguesResidual"])
    right, lines, mistakes = 0, [], []
    for k, (case, o) in enumerate(zip(cases, outcomes), start=1):
        inp = case.args
        try:
            r = read_returned("rodriguesResidual", o, lambda v, n=len(inp[2]): jb.read_residuals(v, n), inp)
        except Malformed as exc:
            lines.append(f"input {k}: {exc}")
            continue
        v = jb.residuals(r, case)
        right += v.passed
        lines.append(f"input {k}: {v.sentence}")
        mistakes += v.mistakes
    score.grade(right / len(cases), lines, mistakes)


@pytest.mark.parametrize("k", [
    pytest.param(k, id=f"scene{k + 1}", marks=pytest.mark.points(5, question="Q5",
                                                                 name=f"bundle adjustment on hidden scene {k + 1}"))
    for k in range(_PROBLEMS)])
def test_bundle_adjustment(bundle, adjusted, k, score):
    """The error reached from the start, and the reconstruction's shape kept."""
    pr = bundle.problems[k]
    a = adjusted[k]
    if isinstance(a, Malformed):
        score.grade(0.0, [f"{pr.label}: {a}"])
    v = a[0]
    score.grade(v.fraction, [f"{pr.label}: {v.sentence}", *v.lines], v.mistakes)


def _lines_or_problem(adjusted, lines) -> list:
    return lines or [next((str(a) for a in adjusted if isinstance(a, Malformed)), "no result to check")]


@pytest.mark.points(2, question="Q5", name="M2 holds a rotation")
def test_M2_holds_a_rotation(bundle, adjusted, score):
    lines = [f"{pr.label}: " + ("M2[:, :3] is a rotation" if a[1].passed else
                                figure_text(False, "M2[:, :3] is not a rotation", a[1].goal))
             for pr, a in zip(bundle.problems, adjusted) if not isinstance(a, Malformed)]
    ok = all(not isinstance(a, Malformed) and a[1].passed for a in adjusted)
    score.grade(float(ok), _lines_or_problem(adjusted, lines))


@pytest.mark.points(2, question="Q5", name="o1 and o2 are the reprojection errors before and after")
def test_o1_o2_are_the_errors_before_and_after(bundle, adjusted, score):
    lines, mistakes = [], []
    for pr, a in zip(bundle.problems, adjusted):
        if isinstance(a, Malformed):
            continue
        e = a[2]
        lines.append(f"{pr.label}: " + figure_text(e.passed, f"{e.measured}; your start and result give "
                                                             f"{e.goal.split(' from')[0]} px^2"))
        mistakes += e.mistakes
    ok = all(not isinstance(a, Malformed) and a[2].passed for a in adjusted)
    score.grade(float(ok), _lines_or_problem(adjusted, lines), mistakes)
