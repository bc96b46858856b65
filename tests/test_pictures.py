"""The feedback figures (starter.checks.pictures): each catalogue mistake of Q2 to Q6 is visible in
what is drawn, measured on the figure's own data (its ``measures`` and the matplotlib artists), not
on pixels.  Programs come from the corpus (tests/corpus/variants.py) over the reference solutions,
run here in the test process on the public default data.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from starter.checks import pictures
from corpus import variants as V

slow = pytest.mark.slow


def program(source: str | None = None, **extra) -> dict:
    """The reference's functions, with the corpus cell ``source`` run over them (a replacement or a wrapper)."""
    import solutions.bundle as sb
    import solutions.correspondence as sc
    import solutions.essential as se
    import solutions.fundamental as sf
    import solutions.multiview as sm
    import solutions.pose as sp
    import solutions.triangulation as st
    from starter import camera2, refineF

    ns = {"refineF": refineF, "camera2": camera2, "eightpoint": sf.eightpoint, "essentialMatrix": se.essentialMatrix,
          "triangulate": st.triangulate, "findM2": sp.findM2,
          "epipolarCorrespondence": sc.epipolarCorrespondence, "compute3D_pts": sc.compute3D_pts,
          "rodriguesResidual": sb.rodriguesResidual, "bundleAdjustment": sb.bundleAdjustment,
          "MultiviewReconstruction": sm.MultiviewReconstruction, **extra}
    if source is not None:
        exec(compile(source, "<corpus cell>", "exec"), ns)  # noqa: S102 - the kit's own corpus
    return ns


def picture(question: str, source: str | None = None):
    ns = program(source)
    return pictures.draw(question, pictures.public_outputs(question, ns))


def numbers_in(text: str) -> list[float]:
    return [float(m) for m in re.findall(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?", text)]


def states(alt: str, value: float) -> bool:
    """The alt text states ``value`` to its 3 significant digits."""
    return any(np.isclose(v, value, rtol=6e-3, atol=1e-12) for v in numbers_in(alt))


# ----------------------------------------------------------------------------- the API

def test_questions_and_functions():
    assert pictures.QUESTIONS == ("Q2", "Q3.2", "Q3.3", "Q4.1", "Q4.2", "Q5", "Q6")
    assert set(pictures.FUNCTIONS) == set(pictures.QUESTIONS)
    assert pictures.FUNCTIONS["Q2"] == ("eightpoint",)


@pytest.mark.parametrize("outputs, said", [
    ({}, "missing 'F'"),
    ({"F": np.zeros((2, 3))}, "'F'"),
    ({"F": "abc"}, "'F'"),
    ("not a mapping", "mapping"),
])
def test_draw_names_what_is_wrong(outputs, said):
    with pytest.raises(ValueError, match=said):
        pictures.draw("Q2", outputs)


def test_unknown_question():
    with pytest.raises(ValueError, match="question"):
        pictures.draw("Q9", {})


def test_a_failing_function_is_said_clearly():
    def eightpoint(pts1, pts2, M):
        raise ZeroDivisionError("boom")

    with pytest.raises(pictures.PictureRunError, match="eightpoint raised ZeroDivisionError"):
        pictures.public_outputs("Q2", {"eightpoint": eightpoint})
    with pytest.raises(ValueError, match="needs eightpoint"):
        pictures.public_outputs("Q2", {})


@slow
def test_outputs_are_plain_float_arrays_through_the_wire():
    from core import wire

    out = pictures.public_outputs("Q2", program())
    assert all(isinstance(v, np.ndarray) and v.dtype == np.float64 for v in out.values())
    back = wire.loads(wire.dumps(out))
    assert set(back) == set(out) and all(np.array_equal(back[k], out[k]) for k in out)


def test_show_never_raises(capsys):
    def eightpoint(pts1, pts2, M):
        return None

    assert pictures.show("Q2", {"eightpoint": eightpoint}) is None
    assert "figure not drawn" in capsys.readouterr().out


# ----------------------------------------------------------------------------- Q2



@slow
def test_q2_right_lines_pass_through_the_true_matches():
    p = picture("Q2")
    m = p.measures
    assert m["mean_distance_px"] < 1.0 and m["max_distance_px"] < 1.0
    assert m["true_F_mean_distance_px"] < 1e-6
    assert m["s3_over_s2"] < 1e-9
    assert m["uint16_F_change"] < 1e-9
    assert p.png.startswith(b"\x89PNG")
    assert states(p.alt, m["mean_distance_px"]) and "8 epipolar lines" in p.alt


@slow
@pytest.mark.parametrize("source, key, low", [
    (V.EIGHTPOINT_TRANSPOSED, "mean_distance_px", 2.0),
    (V.EIGHTPOINT_NOT_UNSCALED, "mean_distance_px", 100.0),
    # refineF polishes the transposed F; switched off, its lines miss again
    (V.EIGHTPOINT_TRANSPOSED_REFINED, "refineF_off_mean_distance_px", 2.0),
])
def test_q2_wrong_lines_miss_the_matches(source, key, low):
    p = picture("Q2", source)
    assert p.measures[key] > low
    assert states(p.alt, p.measures[key])


@slow
def test_q2_transposed_misses_where_drawn():
    """The artists' own data: each drawn line of a transposed F misses its dot by up to several pixels."""
    from starter.checks.pictures.drawing import line_distances
    from starter.checks.pictures.public import temple

    out = pictures.public_outputs("Q2", program(V.EIGHTPOINT_TRANSPOSED))
    s = temple().scene
    p = pictures.draw("Q2", out)
    d = line_distances(np.column_stack([s.pts1_true, np.ones(len(s.pts1_true))]) @ out["F"].T, s.pts2_true)
    assert np.max(d) > 5 > p.measures["mean_distance_px"] > 2
    right = line_distances(np.column_stack([s.pts1_true, np.ones(len(s.pts1_true))]) @ s.F_true.T, s.pts2_true)
    assert np.max(right) < 1e-6


@slow
def test_q2_rank3_is_measured():
    p = picture("Q2", V.EIGHTPOINT_RANK3)
    assert p.measures["s3_over_s2"] > 1e-3
    assert "full rank" in p.alt and states(p.alt, p.measures["s3_over_s2"])


@slow
def test_q2_uint16_changes_F():
    p = picture("Q2", V.EIGHTPOINT_UINT16)
    assert p.measures["uint16_F_change"] > 0.1
    assert states(p.alt, p.measures["uint16_F_change"])
