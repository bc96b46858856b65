"""The data the self-checks and figures read instead of computing a graded answer: fresh, and right.

``python -m kit check-data`` writes starter/checks/residual_case.json (Q5's public residual check)
and figure_data.json (Q3.3's candidates, Q5's residuals at the start, Q6's threshold rules) from
solutions.expected.  These tests prove each committed file is what the command writes now, that
what the public check expects is the reference's residual, and that a figure of other data says
what it leaves out instead of failing.
"""

from __future__ import annotations

import numpy as np
import pytest

from kit.check_data import CHECKS_DIR, fresh


@pytest.mark.parametrize("name", ["residual_case.json", "figure_data.json"])
def test_the_committed_data_is_fresh(name):
    assert (CHECKS_DIR / name).read_text(encoding="utf-8") == fresh(name), \
        f"starter/checks/{name} is stale: run `python -m kit check-data --only {name}`"


def test_the_public_residual_check_expects_the_references_residuals():
    from solutions import rodriguesResidual
    from solutions.expected import residual_case
    from starter.checks._scenes import two_view
    from starter.checks.bundle import _public_misread, residual_cases

    cases = residual_cases(two_view(), _public_misread())
    assert [label for label, _ in cases] == ["exact matches", "noisy matches"]
    for label, case in cases:
        ref = residual_case(*case.args)
        np.testing.assert_allclose(case.expected, rodriguesResidual(*case.args), rtol=0, atol=1e-9, err_msg=label)
        assert set(case.misread) == set(ref.misread) and len(case.misread) >= 4
        for order, r in case.misread.items():
            np.testing.assert_allclose(r, ref.misread[order], rtol=0, atol=1e-8, err_msg=f"{label}: {order}")
    assert np.abs(cases[1][1].expected).max() > 0.1       # the noisy matches are off their projections


def test_the_figure_data_is_of_the_default_data_only():
    from starter.checks.pictures import precomputed
    from starter.checks.pictures.public import car, temple

    d = temple().data
    frame = car(truth=False).frame
    cands = precomputed.candidates("default", (d.pts1, d.pts2, d.K1, d.K2))
    assert cands is not None and len(cands) == 4 and all(len(c["x"]) == len(d.pts1) for c in cands)
    # one candidate puts the most points in front of both cameras: the right one, nearly all of them
    assert max(float(np.mean(c["front1"] & c["front2"])) for c in cands) > 0.9
    assert precomputed.rules(frame.C, frame.pts) is not None
    moved = np.asarray(d.pts1, float) + 1.0
    assert precomputed.candidates("default", (moved, d.pts2, d.K1, d.K2)) is None
    assert precomputed.rules(frame.C, [p + 1.0 for p in frame.pts]) is None


def test_q6_figure_without_the_rules_says_so(monkeypatch):
    """On data without precomputed rules (the official data), Q6 is drawn without the rule comparison."""
    from starter.checks import pictures
    from starter.checks.pictures import precomputed
    from starter.checks.pictures.public import car

    P_true = car().P_true
    outputs = {"P": P_true, "err": np.array([0.0])}
    with_rules = pictures.draw("Q6", outputs)
    assert with_rules.measures["nearest_rule"] >= 0 and "gap_0" in with_rules.measures
    monkeypatch.setattr(precomputed, "rules", lambda Cs, pts: None)
    without = pictures.draw("Q6", outputs)
    assert without.measures["nearest_rule"] == -1 and "gap_0" not in without.measures
    assert precomputed.NOT_PRECOMPUTED in without.alt
    assert without.measures["n_left_out"] == with_rules.measures["n_left_out"] == 0
