"""The feedback figures (starter.checks.pictures): each catalogue mistake of Q2 to Q6 is visible in
what is drawn, measured on the figure's own data (its ``measures`` and the matplotlib artists), not
on pixels.  Programs come from the corpus (tests/support/corpus/variants.py) over the reference solutions,
run here in the test process on the public default data.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from starter.checks import pictures
import corpus
from corpus import variants as V

slow = pytest.mark.slow


HOMEWORK = ("eightpoint", "essentialMatrix", "triangulate", "findM2", "epipolarCorrespondence", "compute3D_pts",
            "rodriguesResidual", "bundleAdjustment", "MultiviewReconstruction")


def program(source: str | None = None) -> dict:
    """The functions of the answer key's notebooks with one corpus cell (tests/support/corpus/variants.py) put in:
    a ``WRAP_*`` cell after the cell of the function it wraps, any other in place of its function's
    cell; executed as the grader keeps a submission's statements (corpus.program_namespace)."""
    if source is None:
        return corpus.program_namespace("key_full_marks", HOMEWORK)
    name = [f for f in re.findall(r"^def (\w+)\(", source, re.MULTILINE) if f in HOMEWORK][-1]
    if "_key_" in source:
        mutate = lambda nbs, ctx: corpus.after_function(nbs, name, source)  # noqa: E731
    else:
        mutate = lambda nbs, ctx: corpus.replace_function(nbs, name, source)  # noqa: E731
    return corpus.program_namespace(f"picture_{name}", HOMEWORK, corpus.Case(mutate))


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
    assert pictures.QUESTIONS == ("Q2", "Q3.1", "Q3.2", "Q3.3", "Q4.1", "Q4.2", "Q5", "Q6")
    assert set(pictures.FUNCTIONS) == set(pictures.QUESTIONS)
    assert pictures.FUNCTIONS["Q2"] == ("eightpoint",)
    assert pictures.FUNCTIONS["Q3.1"] == ("essentialMatrix",)


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


# ----------------------------------------------------------------------------- Q3.1

E_MISSING_K = '''\
def essentialMatrix(F, K1, K2):
    """E with camera 2's intrinsics left out."""
    return F @ K1
'''
E_INVERSE_K = '''\
import numpy as np


def essentialMatrix(F, K1, K2):
    """E with inverted intrinsics (the formula of F from E)."""
    return np.linalg.inv(K2).T @ F @ np.linalg.inv(K1)
'''
E_SAME_K = '''\
def essentialMatrix(F, K1, K2):
    """E with camera 2's intrinsics on both sides."""
    return K2.T @ F @ K2
'''
E_TRANSPOSED = '''\
def essentialMatrix(F, K1, K2):
    """The transpose of the essential matrix."""
    return (K2.T @ F @ K1).T
'''


def _e_mistake(E, F, K1, K2) -> list[str]:
    from judging.mistakes import essential_mistakes

    return [m.code for m in essential_mistakes(E, F, K1, K2)]


@slow
def test_q31_right_lines_pass_through_the_true_matches():
    p = picture("Q3.1")
    m = p.measures
    assert m["mean_distance_px"] < 1e-6 and m["k_differ_mean_distance_px"] < 1e-6
    assert m["true_F_mean_distance_px"] < 1e-6 and m["lines_in_image"] == m["n_lines"] == 8
    assert p.png.startswith(b"\x89PNG") and states(p.alt, m["mean_distance_px"])


@slow
@pytest.mark.parametrize("source, code, temple_low, pair_low", [
    # K1 == K2 on the public temple: swapped or repeated intrinsics give the right E there (nothing to
    # see), the self-check's pair (K1 != K2) shows them
    (V.ESSENTIAL_K_SWAPPED, "e_k_order", None, 10.0),
    (E_SAME_K, "e_same_k", None, 5.0),
    (E_MISSING_K, "e_missing_k", 1e4, 1e4),
    (E_INVERSE_K, "e_inverse_k", 1e4, 1e4),
    (E_TRANSPOSED, "e_transposed", 2.0, 2.0),
], ids=["e_k_order", "e_same_k", "e_missing_k", "e_inverse_k", "e_transposed"])
def test_q31_each_mistake_misses_the_matches(source, code, temple_low, pair_low):
    from starter.checks._scenes import two_view

    ns = program(source)
    pair = two_view().pair
    assert _e_mistake(ns["essentialMatrix"](pair.F, pair.K1, pair.K2), pair.F, pair.K1, pair.K2) == [code]
    p = pictures.draw("Q3.1", pictures.public_outputs("Q3.1", ns))
    m = p.measures
    assert m["K1_equals_K2"] == 1.0
    assert m["k_differ_mean_distance_px"] > pair_low and states(p.alt, m["k_differ_mean_distance_px"])
    if temple_low is None:
        assert m["mean_distance_px"] < 1e-6 and "K1 == K2" in p.alt
    else:
        assert m["mean_distance_px"] > temple_low and states(p.alt, m["mean_distance_px"])


@slow
def test_q31_far_lines_are_said_to_leave_the_image():
    p = picture("Q3.1", E_MISSING_K)
    assert p.measures["lines_in_image"] == 0 and "0 of your 8 lines cross" in p.alt


@slow
def test_q31_the_drawn_lines_are_the_implied_F(monkeypatch):
    """The artists' own data: the lines drawn for a transposed E miss their dots by what is measured,
    and the red sticks show it."""
    from starter.checks.pictures import q3_essential
    from starter.checks.pictures.picture import measure_text

    figures = _captured(monkeypatch, q3_essential)
    p = picture("Q3.1", E_TRANSPOSED)
    d = _dots_to_drawn_lines(figures[-1])
    assert len(d) == 8 and d.max() > 5
    assert np.mean(d) == pytest.approx(p.measures["mean_distance_px"], rel=1e-6)
    # and without a number to read, as Q2's: a red stick from every true match, MISS_MAGNIFY times its
    # miss (tens of pixels here), on both rows; the first zoom goes to the farthest match
    from starter.checks.pictures import q2_eightpoint as q2

    temple, pair = figures[-1].axes[0], figures[-1].axes[1 + q2.N_ZOOMED]
    assert len(_sticks(temple)) > q2.N_DRAWN and len(_sticks(pair)) > q2.N_DRAWN
    assert _sticks(temple).max() == pytest.approx(q2.MISS_MAGNIFY * p.measures["largest_miss_px"], rel=1e-6)
    assert _sticks(pair).max() == pytest.approx(q2.MISS_MAGNIFY * p.measures["k_differ_largest_miss_px"], rel=1e-6)
    assert _sticks(temple).max() > 100 and _sticks(pair).max() > 100
    assert figures[-1].axes[1].get_title() == measure_text(p.measures["largest_miss_px"], "px")
    _titles_stay_over_their_panels(figures[-1])
    picture("Q3.1", E_INVERSE_K)          # the longest numbers: millions of pixels
    _titles_stay_over_their_panels(figures[-1])


# ----------------------------------------------------------------------------- Q3.2

@slow
def test_q32_right_points_reproject_onto_the_matches():
    p = picture("Q3.2")
    m = p.measures
    assert m["mean_reprojection_px_1"] < 1 and m["mean_reprojection_px_2"] < 1
    assert m["share_in_front"] == 1.0
    assert np.isclose(m["err_reported"], m["sum_of_squares"], rtol=1e-6)
    assert states(p.alt, m["err_reported"]) and states(p.alt, m["mean_reprojection_px_2"])


@slow
@pytest.mark.parametrize("source", [V.TRIANGULATE_W_NOT_DIVIDED, V.TRIANGULATE_POINTS_MIRRORED])
def test_q32_wrong_points_reproject_far(source):
    m = picture("Q3.2", source).measures
    assert m["mean_reprojection_px_2"] > 100
    assert m["share_in_front"] < 0.6


@slow
def test_q32_mean_error_differs_from_the_sum_drawn():
    p = picture("Q3.2", V.TRIANGULATE_MEAN_ERROR)
    m = p.measures
    assert m["mean_reprojection_px_2"] < 1
    assert m["err_reported"] < 0.05 * m["sum_of_squares"]
    assert states(p.alt, m["err_reported"]) and states(p.alt, m["sum_of_squares"])


# ----------------------------------------------------------------------------- Q3.3

@slow
def test_q33_right_camera_is_the_one_with_points_in_front():
    p = picture("Q3.3")
    m = p.measures
    assert m["chosen"] == m["right"] >= 0
    assert m["chosen_share_in_front"] == 1.0
    assert f"the right one is M2s[:, :, {int(m['right'])}]" in p.alt   # named as the code indexes them


@slow
@pytest.mark.parametrize("source", [V.FINDM2_CHEIRALITY_FLIPPED])
def test_q33_wrong_camera_is_framed_with_its_points_behind(source):
    p = picture("Q3.3", source)
    m = p.measures
    assert m["chosen"] >= 0 and m["chosen"] != m["right"]
    assert m["chosen_share_in_front"] == 0.0 and m["right_share_in_front"] == 1.0
    assert f"yours is M2s[:, :, {int(m['chosen'])}] (framed)" in p.alt


@slow
def test_q33_another_years_signature_is_called_its_way():
    m = picture("Q3.3", V.FINDM2_INTRINSICS).measures
    assert m["chosen"] == m["right"]


# ----------------------------------------------------------------------------- Q4.1, Q4.2

@slow
def test_q41_right_matches_land_on_the_true_ones():
    p = picture("Q4.1")
    assert p.measures["share_within_tol"] >= 0.8 and p.measures["median_distance_px"] < 1
    assert states(p.alt, p.measures["median_distance_px"])


@slow
def test_q41_and_q42_xy_swapped():
    ns = program(V.WRAP_XY_SWAPPED)
    m = pictures.draw("Q4.1", pictures.public_outputs("Q4.1", ns)).measures
    assert m["share_within_tol"] == 0.0 and m["median_distance_px"] > 50
    m = pictures.draw("Q4.2", pictures.public_outputs("Q4.2", ns)).measures
    assert m["share_near"] < 0.1 and m["median_error"] > 0.3 * m["temple_size"]


@slow
@pytest.mark.parametrize("source", [None, V.COMPUTE3D_FIVE_ARGUMENTS])
def test_q42_right_temple_lies_on_the_true_one(source):
    p = picture("Q4.2", source)
    assert p.measures["share_near"] > 0.8 and p.measures["median_error"] < 0.05 * p.measures["temple_size"]
    assert f"{p.measures['share_near']:.0%}" in p.alt


# ----------------------------------------------------------------------------- Q5

@slow
def test_q5_right_bundle_adjustment_goes_down_and_is_recorded():
    p = picture("Q5")
    m = p.measures
    assert m["end_error"] < 0.01 * m["start_error"]
    assert m["n_calls"] >= 2 and np.isclose(m["history_first"], m["start_error"], rtol=1e-6)
    assert m["history_min"] <= m["end_error"] * (1 + 1e-6)
    assert m["residual_layout_gap"] < 1e-9
    assert states(p.alt, m["start_error"]) and states(p.alt, m["end_error"])


@slow
def test_q5_returning_the_start_shows_the_drop_not_kept():
    p = picture("Q5", V.BA_RETURNS_START)
    m = p.measures
    assert m["end_error"] == pytest.approx(m["start_error"], rel=1e-9)
    assert m["history_min"] < 0.01 * m["start_error"]       # the optimiser got there; the result did not
    assert "not lower" in p.alt


@slow
def test_q5_interleaved_residuals_leave_the_handout_layout():
    p = picture("Q5", V.WRAP_RESIDUAL_INTERLEAVED)
    assert p.measures["residual_layout_gap"] > 0.5
    assert states(p.alt, p.measures["residual_layout_gap"])


@slow
@pytest.mark.parametrize("source", [V.BA_MINIMIZE, V.BA_LEAST_SQUARES])
def test_q5_other_optimisers_are_recorded(source):
    import scipy.optimize as so

    ns = program(source)
    m = pictures.draw("Q5", pictures.public_outputs("Q5", ns)).measures
    assert m["n_calls"] > 10 and m["end_error"] < 0.01 * m["start_error"]
    # everything the recording replaced is back
    assert so.least_squares.__name__ == "least_squares" and so.minimize.__name__ == "minimize"
    assert not hasattr(ns["rodriguesResidual"], "__wrapped__")


# ----------------------------------------------------------------------------- Q6

WRAP_THRESHOLD_IGNORED = '''\
_key_MultiviewReconstruction = MultiviewReconstruction


def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):
    """Every detection used, whatever its confidence."""
    return _key_MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, -1.0)
'''
WRAP_THRESHOLD_TOO_STRICT = WRAP_THRESHOLD_IGNORED.replace("-1.0", "Thres + 150").replace(
    "Every detection used, whatever its confidence", "Detections just above Thres left out")


@slow
def test_q6_right_keypoints_follow_the_handouts_rule():
    p = picture("Q6")
    m = p.measures
    assert m["nearest_rule"] == 0 and m["detections_at_thres"] >= 1 and m["n_off_rule"] == 0
    assert m["mean_reprojection_px"] < 5 and m["mean_error_3d"] < 0.05
    assert "confidence > Thres" in p.alt and states(p.alt, m["mean_reprojection_px"])


@slow
@pytest.mark.parametrize("source, rule", [(V.WRAP_THRESHOLD_INCLUSIVE, 1), (WRAP_THRESHOLD_IGNORED, 2)])
def test_q6_threshold_mistakes_follow_another_rule(source, rule, monkeypatch):
    """Named in words, and ringed in purple where the points follow detections the handout leaves out
    (a detection at exactly Thres moves two keypoints by a few pixels: without rings nothing shows)."""
    from starter.checks.pictures import q6_multiview
    from starter.checks.pictures.q6_multiview import RULES

    figures = _captured(monkeypatch, q6_multiview)
    p = picture("Q6", source)
    assert p.measures["nearest_rule"] == rule
    assert RULES[rule] in p.alt
    n = p.measures["n_off_rule"]
    rings = [a for ax in figures[-1].axes for a in ax.lines if a.get_gid() == "off_rule"]
    assert n >= 2 and len(rings) == 3 and all(len(r.get_xdata()) == n for r in rings)
    assert f"{int(n)} of your keypoint(s) follow detections at or below Thres" in p.alt


@slow
def test_q6_too_strict_leaves_keypoints_out():
    right, strict = picture("Q6").measures, picture("Q6", WRAP_THRESHOLD_TOO_STRICT).measures
    assert strict["n_reconstructed"] < right["n_reconstructed"]
    assert strict["gap_0"] > 1.0 > right["gap_0"]


@slow
def test_q6_mean_error_is_stated_as_returned(monkeypatch):
    """And drawn: the err returned beside the sum of squares recomputed, two bars of one height for the
    handout's err, a mean's bar a fraction of the other (the keypoints alone look the same)."""
    from starter.checks.pictures import q6_multiview

    figures = _captured(monkeypatch, q6_multiview)
    right = picture("Q6").measures
    assert _bars(figures[-1], "err_bars") == pytest.approx((right["err_reported"], right["sum_of_squares"]), rel=1e-9)
    assert right["err_reported"] == pytest.approx(right["sum_of_squares"], rel=1e-6)
    mean = picture("Q6", V.WRAP_MULTIVIEW_MEAN_ERR).measures
    err, squares = _bars(figures[-1], "err_bars")
    assert err == pytest.approx(mean["err_reported"]) and squares == pytest.approx(right["sum_of_squares"])
    assert mean["err_reported"] < 0.2 * right["err_reported"] and err < 0.2 * squares
    assert mean["mean_reprojection_px"] == pytest.approx(right["mean_reprojection_px"])


# ----------------------------------------------------------------------------- in a notebook

@slow
def test_a_check_shows_its_figure_in_a_notebook(monkeypatch, capsys):
    """In a notebook (IPython faked here) a check displays the PNG with its alt text; a figure that
    cannot be drawn says why and the check's report is still returned."""
    import IPython.display

    from starter.checks import check_triangulate
    from starter.checks.pictures import display

    shown = []
    monkeypatch.setattr(display, "in_notebook", lambda: True)
    monkeypatch.setattr(IPython.display, "display", lambda bundle, raw=False: shown.append(bundle))
    report = check_triangulate(program()["triangulate"])
    assert report.passed and len(shown) == 1
    assert shown[0]["image/png"].startswith(b"\x89PNG") and "alt='" in shown[0]["text/html"]

    def triangulate(C1, pts1, C2, pts2):
        raise RuntimeError("no")

    report = check_triangulate(triangulate)
    assert not report.passed and len(shown) == 1
    assert "figure not drawn: PictureRunError: triangulate raised RuntimeError" in capsys.readouterr().out


@slow
def test_default_data_only_where_truth_is_needed(tmp_path):
    """Data that is not the default (an instructor's official data) draws Q2 against its own matches
    and says Q3.2 needs the default data's cameras."""
    import shutil

    from starter.checks.pictures.public import NO_TRUTH, temple

    root = tmp_path / "data"
    shutil.copytree(temple(truth=False).data.folder, root / "temple")
    z = dict(np.load(root / "temple" / "some_corresp.npz"))
    z["pts1"] = z["pts1"].copy()
    z["pts1"][0, 0] += 1
    np.savez(root / "temple" / "some_corresp.npz", **z)

    def eightpoint(pts1, pts2, M):
        return np.eye(3)

    p = pictures.draw("Q2", {"F": np.eye(3)}, root=root)
    assert NO_TRUTH[3:] in p.alt and "true_F_mean_distance_px" not in p.measures
    with pytest.raises(ValueError, match="Q3.2's figure needs the ground truth"):
        pictures.public_outputs("Q3.2", {"triangulate": eightpoint}, root=root)


# ----------------------------------------------------------------------------- mistakes without a corpus program

_SWAP = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


@slow
@pytest.mark.parametrize("mistake", ["xy_swapped", "f_unscaled_wrong_way"])
def test_q2_other_catalogue_mistakes_miss_the_matches(mistake):
    """The catalogue's repairs (judging.mistakes._f_repairs) undone: the F each mistake makes."""
    key = program()["eightpoint"]
    M = 640.0
    T = np.diag([1 / M, 1 / M, 1.0])
    spoil = {"xy_swapped": lambda F: _SWAP @ F @ _SWAP,
             "f_unscaled_wrong_way": lambda F: np.linalg.matrix_power(np.linalg.inv(T), 2) @ F
             @ np.linalg.matrix_power(np.linalg.inv(T), 2)}

    def eightpoint(pts1, pts2, M):
        return spoil[mistake](key(pts1, pts2, M))

    p = pictures.draw("Q2", pictures.public_outputs("Q2", {"eightpoint": eightpoint}))
    assert p.measures["mean_distance_px"] > 10


@slow
def test_q2_not_unscaled_draws_no_line_in_the_image():
    p = picture("Q2", V.EIGHTPOINT_NOT_UNSCALED)
    assert p.measures["lines_in_image"] < p.measures["n_lines"]
    assert f"{int(p.measures['lines_in_image'])} of your 8 lines cross image 2" in p.alt


@slow
def test_q5_scale_collapse_is_measured():
    """A bundle adjustment whose points and t shrink together (the catalogue's BA scale collapse)."""
    key = program()["bundleAdjustment"]

    def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init):
        M2, w, o1, o2 = key(K1, M1, p1, K2, M2_init, p2, w_init)
        M2 = np.hstack([M2[:, :3], 1e-3 * M2[:, 3:]])
        return M2, 1e-3 * w, o1, o2

    m = pictures.draw("Q5", pictures.public_outputs("Q5", {"bundleAdjustment": bundleAdjustment})).measures
    assert m["t_ratio"] < 0.01 and m["end_error"] < 0.01 * m["start_error"]
    assert "residual_layout_gap" not in m     # no rodriguesResidual given: no panel, no measure


@slow
def test_q5_x_packing_shows_in_the_residuals():
    """rodriguesResidual reading each point of x as (z, y, x): its residuals leave the handout's layout."""
    ns = program()
    key = ns["rodriguesResidual"]
    out = pictures.public_outputs("Q5", {"bundleAdjustment": ns["bundleAdjustment"], "rodriguesResidual": key})
    assert pictures.draw("Q5", out).measures["residual_layout_gap"] < 1e-9

    def packed_wrong(K1, M1, p1, K2, p2, x):
        n = len(p1)
        x = np.asarray(x, float)
        w = x[:3 * n].reshape(n, 3)[:, ::-1].ravel()            # each point read as (z, y, x)
        return key(K1, M1, p1, K2, p2, np.concatenate([w, x[3 * n:]]))

    out = pictures.public_outputs("Q5", {"bundleAdjustment": ns["bundleAdjustment"], "rodriguesResidual": packed_wrong})
    assert pictures.draw("Q5", out).measures["residual_layout_gap"] > 0.1


@slow
def test_q33_depth_in_camera_1_only_picks_the_twisted_pair():
    """The catalogue's "depth tested in one camera only": on the default data it picks the right camera
    (by chance, as docs/judging.md says); on the twisted-pair row its choice has every point in front of
    camera 1 and behind camera 2."""
    ns = program()
    essentialMatrix, triangulate = ns["essentialMatrix"], ns["triangulate"]
    from starter import camera2

    def findM2(F, pts1, pts2, K1, K2):
        cands = camera2(essentialMatrix(F, K1, K2))
        best = None
        for i in range(4):
            w, err = triangulate(K1 @ np.eye(3, 4), pts1, K2 @ cands[:, :, i], pts2)
            if np.all(w[:, 2] > 0) and (best is None or err < best[0]):
                best = (err, cands[:, :, i], K2 @ cands[:, :, i], w)
        return best[1:]

    p = pictures.draw("Q3.3", pictures.public_outputs("Q3.3", {"findM2": findM2}))
    m = p.measures
    assert m["chosen"] == m["right"]
    assert m["twisted_chosen"] >= 0 and m["twisted_chosen"] != m["twisted_right"]
    assert m["twisted_chosen_share_front_1_only"] == 1.0 and m["twisted_right_share_in_front"] == 1.0
    assert "twisted-pair case" in p.alt
    right = picture("Q3.3").measures
    assert right["twisted_chosen"] == right["twisted_right"]


# ----------------------------------------------------------------------------- what is drawn, read back

def _captured(monkeypatch, module):
    """The matplotlib figure ``module.draw`` renders, kept for reading its artists."""
    figures = []
    original = module.to_picture

    def keep(question, title, fig, alt, measures):
        figures.append(fig)
        return original(question, title, fig, alt, measures)

    monkeypatch.setattr(module, "to_picture", keep)
    return figures


def _dots_to_drawn_lines(fig) -> np.ndarray:
    """Per drawn match of the first (large) panel, the distance in pixels to the line drawn for it."""
    ax = fig.axes[0]
    lines = [a for a in ax.lines if a.get_gid() == "student_line"]
    (dots,) = [a for a in ax.lines if a.get_gid() == "match"]
    xy = np.column_stack([dots.get_xdata(), dots.get_ydata()])
    out = []
    for (x, y), ln in zip(xy, lines):
        (x0, x1), (y0, y1) = ln.get_xdata(), ln.get_ydata()
        out.append(abs((x1 - x0) * (y0 - y) - (x0 - x) * (y1 - y0)) / np.hypot(x1 - x0, y1 - y0))
    return np.array(out)


@slow
def test_q2_the_drawn_lines_pass_through_the_drawn_dots(monkeypatch):
    from starter.checks.pictures import q2_eightpoint

    figures = _captured(monkeypatch, q2_eightpoint)
    right = picture("Q2")
    d = _dots_to_drawn_lines(figures[-1])
    assert len(d) == 8 and d.max() < 1.0
    assert np.mean(d) == pytest.approx(right.measures["mean_distance_px"], rel=1e-6)
    wrong = picture("Q2", V.EIGHTPOINT_TRANSPOSED)
    d = _dots_to_drawn_lines(figures[-1])
    assert d.max() > 5 and np.mean(d) > 2
    assert np.mean(d) == pytest.approx(wrong.measures["mean_distance_px"], rel=1e-6)


def _sticks(ax) -> np.ndarray:
    """The lengths in pixels of the red sticks (each match towards its line, magnified) of a large panel."""
    (sticks,) = [c for c in ax.collections if c.get_gid() == "miss"]
    return np.array([np.hypot(*(seg[1] - seg[0])) for seg in sticks.get_segments()])


@slow
def test_q2_a_polished_transposed_F_shows_where_it_misses(monkeypatch):
    """refineF polishes a transposed F into a near miss as returned; switched off, the F misses the
    matches by up to about twenty pixels, and its row shows it without a number to read: red sticks
    from every match to its line, MISS_MAGNIFY times as long, and a first zoom, framed, on the match
    farthest from its line, wide enough to show the line beside the dot."""
    from starter.checks.pictures import q2_eightpoint as q2
    from starter.checks.pictures.picture import measure_text

    figures = _captured(monkeypatch, q2)
    p = picture("Q2", V.EIGHTPOINT_TRANSPOSED_REFINED)
    m = p.measures
    assert m["mean_distance_px"] < 1.0 < 2.0 < m["refineF_off_mean_distance_px"]
    assert states(p.alt, m["refineF_off_mean_distance_px"]) and states(p.alt, m["refineF_off_largest_miss_px"])
    fig = figures[-1]
    own, off = fig.axes[0], fig.axes[1 + q2.N_ZOOMED]      # each row: its large panel, then its zooms
    assert len(_sticks(own)) == len(_sticks(off)) > q2.N_DRAWN                   # every match, not the drawn ones
    assert _sticks(own).max() == pytest.approx(q2.MISS_MAGNIFY * m["largest_miss_px"], rel=1e-6)
    assert _sticks(own).max() < 5 and _sticks(off).max() > 100                  # invisible / a fifth of the image
    assert _sticks(off).max() == pytest.approx(q2.MISS_MAGNIFY * m["refineF_off_largest_miss_px"], rel=1e-6)
    zoom = off.figure.axes[2 + q2.N_ZOOMED]
    assert zoom.get_title() == measure_text(m["refineF_off_largest_miss_px"], "px")
    (line,) = [a for a in zoom.lines if a.get_gid() == "student_line"]
    (dot,) = [a for a in zoom.lines if a.get_gid() == "match"]
    (x, y), (x0, x1), (y0, y1) = (dot.get_xdata()[0], dot.get_ydata()[0]), line.get_xdata(), line.get_ydata()
    at_dot = x0 + (x1 - x0) * (y - y0) / (y1 - y0)        # where the near-vertical line crosses the dot's row
    assert min(zoom.get_xlim()) < at_dot < max(zoom.get_xlim()) and abs(at_dot - x) > 15
    (square,) = [a for a in off.lines if a.get_gid() == "largest_miss"]
    assert (square.get_xdata()[0], square.get_ydata()[0]) == (x, y)


@slow
def test_q41_the_drawn_crosses_are_the_matches(monkeypatch):
    from starter.checks.pictures import q4_matches

    figures = _captured(monkeypatch, q4_matches)
    p = picture("Q4.1", V.WRAP_XY_SWAPPED)
    ax = figures[-1].axes[1]
    right = [a for a in ax.lines if a.get_gid() == "yours_right"][0]
    wrong = [a for a in ax.lines if a.get_gid() == "yours_wrong"][0]
    assert len(right.get_xdata()) == 0 and len(wrong.get_xdata()) == p.measures["n_points"]


@slow
def test_q2_rank3_is_said_on_the_figure(monkeypatch):
    """A rank-3 F's lines pass through the dots; the panel's own title says it is full rank."""
    from starter.checks.pictures import q2_eightpoint

    figures = _captured(monkeypatch, q2_eightpoint)
    p = picture("Q2", V.EIGHTPOINT_RANK3)
    assert "full rank" in figures[-1].axes[0].get_title()
    # and drawn: the last zoom gives way to where the drawn lines cross, scattered over hundreds of
    # pixels (a rank-2 F's cross in one point)
    (dots,) = [a for ax in figures[-1].axes for a in ax.lines if a.get_gid() == "crossings"]
    xy = np.column_stack([dots.get_xdata(), dots.get_ydata()])
    assert len(xy) == 28 and np.ptp(xy[:, 1]) > 1000 and p.measures["crossings_spread_px"] > 100
    _titles_stay_over_their_panels(figures[-1])
    picture("Q2")
    assert "full rank" not in figures[-1].axes[0].get_title()
    assert not [a for ax in figures[-1].axes for a in ax.lines if a.get_gid() == "crossings"]
    _titles_stay_over_their_panels(figures[-1])


def _titles_stay_over_their_panels(fig):
    """Each large panel's title ends left of the zooms beside it (it ran into the first zoom at 10 pt)."""
    from starter.checks.pictures import q2_eightpoint as q2

    renderer = fig.canvas.get_renderer()
    for big in fig.axes[::1 + q2.N_ZOOMED]:
        zoom = fig.axes[fig.axes.index(big) + 1]
        assert big.title.get_window_extent(renderer).x1 < zoom.get_window_extent(renderer).x0


@slow
def test_q5_scale_collapse_is_said_on_the_figure(monkeypatch):
    """Shrunk w and t reproject as well as the right ones: the image panel's title gives |t|'s factor."""
    from starter.checks.pictures import q5_bundle

    figures = _captured(monkeypatch, q5_bundle)
    key = program()["bundleAdjustment"]

    def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init):
        M2, w, o1, o2 = key(K1, M1, p1, K2, M2_init, p2, w_init)
        return np.hstack([M2[:, :3], 1e-3 * M2[:, 3:]]), 1e-3 * w, o1, o2

    m = pictures.draw("Q5", pictures.public_outputs("Q5", {"bundleAdjustment": bundleAdjustment})).measures
    title = figures[-1].axes[1].get_title()
    assert f"x{m['t_ratio']:.3g}" in title and "shrunk" in title
    # and without reading it: |t| returned, a bar beside |t| at the start, vanishes
    start, yours = _bars(figures[-1])
    assert yours == pytest.approx(m["t_ratio"] * start, rel=1e-9) and yours < 0.01 * start
    _title_below_the_figures(figures[-1])
    picture("Q5")
    assert "shrunk" not in figures[-1].axes[1].get_title()
    start, yours = _bars(figures[-1])
    assert 0.5 * start < yours < 2 * start
    _title_below_the_figures(figures[-1])


def _bars(fig, gid: str = "scale_bars") -> tuple[float, float]:
    """The heights of the two bars ``gid`` drawn in a panel's corner: Q5's |t| (at the start, returned),
    Q6's "err_bars" (err returned, sum of squares recomputed)."""
    insets = [inset for ax in fig.axes for inset in ax.child_axes]
    bars = [p for ax in insets for p in ax.patches if p.get_gid() == gid]
    assert len(bars) == 2
    return bars[0].get_height(), bars[1].get_height()


def _title_below_the_figures(fig):
    """Every panel's title stays below the figure's own (a two-line panel title ran into it)."""
    renderer = fig.canvas.get_renderer()
    (title,) = [t for t in fig.texts if t.get_text() == fig.get_suptitle()]
    top = title.get_window_extent(renderer).y0
    assert all(ax.title.get_window_extent(renderer).y1 <= top for ax in fig.axes)


@slow
def test_q6_too_strict_rings_the_keypoints_left_out(monkeypatch):
    from starter.checks.pictures import q6_multiview

    figures = _captured(monkeypatch, q6_multiview)
    right = picture("Q6")
    assert right.measures["n_left_out"] == 0
    strict = picture("Q6", WRAP_THRESHOLD_TOO_STRICT)
    n = strict.measures["n_left_out"]
    assert n == right.measures["n_reconstructed"] - strict.measures["n_reconstructed"] >= 1
    rings = [a for ax in figures[-1].axes for a in ax.lines if a.get_gid() == "left_out"]
    assert len(rings) == 3 and all(len(r.get_xdata()) == n for r in rings)
    assert f"{int(n)} keypoint(s) that confidence > Thres reconstructs are not in your P" in strict.alt
