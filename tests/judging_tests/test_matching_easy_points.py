"""Q4.1 judged on the easy points, Q4.2 on the 3D structure, whatever the hand-in's matcher style.

Matchers written the ways hand-ins write them (not the kit's reference) must get full Q4.1 and
Q4.2 marks on hidden draws of several secrets and on the public self-check; wrong matchers must
still lose Q4.1, and a matcher that searches the line F^T x1, or that never leaves rows y1 +- 10,
at least half of it (the hidden matching temples and their points are chosen so that they can
tell: autograder.inputs.correspondence, solutions.matching_styles.scene_problem); a
2022-2024 compute3D_pts returning (M2, C2, P), or writing to result/, is judged by its structure.
The public self-check's goals are a committed file: it must equal a fresh computation.
``benchmarks/matching_discrimination.py`` gives the same verdicts under the sweep's 20 secrets.
"""

from __future__ import annotations

import numpy as np
import pytest

from autograder.inputs.config import quick_config
from autograder.inputs.build import build_hidden_inputs
from autograder.inputs.keep import default_keep
from autograder.hidden.plugin import LocalStudent, run_here
from judging import correspondence as jc

import realstyles.snippets

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

SECRETS = ("easy-points-a", "easy-points-b")


# ------------------------------------------------------------------------ matchers in students' styles


def _line_rows(F, x1, y1, H):
    a, b, c = F @ np.array([x1, y1, 1.0])
    ys = np.arange(H)
    return -(b * ys + c) / a, ys


def ssd101_no_padding(im1, im2, F, x1, y1):
    """101-px window, Gaussian-weighted (the handout's hint), no padding: candidates whose window
    leaves the image are skipped."""
    h = 50
    H, W = im1.shape[:2]
    g = np.exp(-np.arange(-h, h + 1) ** 2 / (2 * 5.0 ** 2))
    g = np.outer(g, g)[:, :, None] if im1.ndim == 3 else np.outer(g, g)
    ref = im1[y1 - h:y1 + h + 1, x1 - h:x1 + h + 1]
    xs, ys = _line_rows(F, x1, y1, H)
    best, out = np.inf, (x1, y1)
    for x, y in zip(xs, ys):
        xi = int(round(x))
        if abs(y - y1) > 30 or not (h <= xi < W - h and h <= y < H - h):
            continue
        d = np.sum(g * (im2[y - h:y + h + 1, xi - h:xi + h + 1] - ref) ** 2)
        if d < best:
            best, out = d, (xi, int(y))
    return out


def ssd5_local_int(im1, im2, F, x1, y1):
    """5-px SSD near (x1, y1), integer coordinates in and out."""
    x1, y1 = int(x1), int(y1)
    H, W = im1.shape[:2]
    ref = im1[y1 - 2:y1 + 3, x1 - 2:x1 + 3].astype(float)
    a, b, c = F @ [x1, y1, 1]
    best, out = None, (x1, y1)
    for y in range(max(2, y1 - 25), min(H - 2, y1 + 26)):
        x = int(round(-(b * y + c) / a))
        if 2 <= x < W - 2:
            d = ((im2[y - 2:y + 3, x - 2:x + 3] - ref) ** 2).sum()
            if best is None or d < best:
                best, out = d, (x, y)
    return out


def gaussian_whole_line_float_cast(im1, im2, F, x1, y1):
    """Gaussian-weighted 15-px SSD along the whole line; float coordinates cast to int to index."""
    h, sigma = 7, 3.0
    g = np.exp(-(np.arange(-h, h + 1) ** 2) / (2 * sigma ** 2))
    g = np.outer(g, g)[:, :, None]
    H, W = im1.shape[:2]
    ref = im1[int(y1) - h:int(y1) + h + 1, int(x1) - h:int(x1) + h + 1]
    xs, ys = _line_rows(F, float(x1), float(y1), H)
    scores = np.full(len(ys), np.inf)
    for k, (x, y) in enumerate(zip(xs, ys)):
        if h <= int(x) < W - h and h <= y < H - h:
            scores[k] = np.sum(g * (im2[int(y) - h:int(y) + h + 1, int(x) - h:int(x) + h + 1] - ref) ** 2)
    k = int(np.argmin(scores))
    return xs[k], ys[k]


def sad9_whole_line_no_cast(im1, im2, F, x1, y1):
    """9-px SAD along the whole line, the images' own dtype (wraps around on uint8 images)."""
    h = 4
    H, W = im1.shape[:2]
    ref = im1[y1 - h:y1 + h + 1, x1 - h:x1 + h + 1]
    xs, ys = _line_rows(F, x1, y1, H)
    best, out = np.inf, (x1, y1)
    for x, y in zip(np.rint(xs).astype(int), ys):
        if h <= x < W - h and h <= y < H - h:
            d = np.abs(im2[y - h:y + h + 1, x - h:x + h + 1] - ref).sum()
            if d < best:
                best, out = d, (x, y)
    return out


STYLES = {"101 px Gaussian-weighted, without padding": ssd101_no_padding, "5-px SSD, int coordinates": ssd5_local_int,
          "Gaussian, whole line, floats cast to int": gaussian_whole_line_float_cast,
          "SAD, whole line, no cast": sad9_whole_line_no_cast}


def returns_the_point(im1, im2, F, x1, y1):
    return x1, y1


def swaps_x_and_y(im1, im2, F, x1, y1):
    x2, y2 = ssd5_local_int(im1, im2, F, x1, y1)
    return y2, x2


def searches_its_row(im1, im2, F, x1, y1):
    """Compares windows along the row y1 (as if the lines were horizontal), not the epipolar line."""
    x1, y1 = int(x1), int(y1)
    ref = im1[y1 - 3:y1 + 4, x1 - 3:x1 + 4].astype(float)
    W = im1.shape[1]
    d = [((im2[y1 - 3:y1 + 4, x - 3:x + 4] - ref) ** 2).sum() for x in range(3, W - 3)]
    return 3 + int(np.argmin(d)), y1


def _snippet(source):
    namespace = {"np": np}
    exec(source, namespace)  # noqa: S102 - the real-styles corpus's own source
    return namespace["epipolarCorrespondence"]


WRONG = {"returns (x1, y1)": returns_the_point, "x and y swapped": swaps_x_and_y, "searches its row": searches_its_row}
# The slips whose partial credit once kept most of Q4.1: must keep at most half of it.
HALF = {"searches F^T x1": _snippet(realstyles.snippets.EC_WRONG_LINE),
        "rows y1 +- 10 only": _snippet(realstyles.snippets.EC_SMALL_BOX)}


def _compute3D_with(matcher):
    """A compute3D_pts(im1, im2, F, x1, y1, C1, C2) that matches with ``matcher`` and triangulates."""
    from solutions import triangulate

    def compute3D_pts(im1, im2, F, x1, y1, C1, C2):
        pts1 = np.column_stack([np.ravel(x1), np.ravel(y1)])
        pts2 = np.array([matcher(im1, im2, F, int(x), int(y)) for x, y in pts1], dtype=float)
        return triangulate(C1, pts1.astype(float), C2, pts2)[0], pts2
    return compute3D_pts


# --------------------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module", params=SECRETS)
def hidden(request):
    return build_hidden_inputs(quick_config(secret=request.param), keep=default_keep())  # the suite's keep


def _questions(hidden, args=(), **replaced) -> dict:
    import solutions

    funcs = {name: getattr(solutions, name) for name in solutions.__all__}
    funcs.update(replaced)
    from autograder.hidden.plugin import HIDDEN_DIR

    result = run_here(LocalStudent(funcs), hidden, tests=(HIDDEN_DIR / "test_correspondence.py",), args=args)
    return {q.id: q for q in result.questions}


# ------------------------------------------------------------------------------------------ tests


def test_the_committed_public_goals_are_a_fresh_computation():
    from kit.check_data import GOALS_FILE, fresh

    assert GOALS_FILE.read_text(encoding="utf-8") == fresh(GOALS_FILE.name)


def test_easy_points_are_distinctive_and_the_goal_comes_from_several_styles(hidden):
    from solutions.matching_styles import BOX, NEAR, STYLES as REF_STYLES, along_line, off_transposed_line

    correspondence = hidden.prepared["correspondence"]
    for case in (*correspondence.cases, correspondence.points_case):
        assert len(case.pts1) >= 8
        assert len(case.shares) == len(REF_STYLES) >= 4
        assert case.ref_share == min(s[1] for s in case.shares) > 0
        disparity = np.linalg.norm(case.truth2 - case.pts1, axis=1)
        assert np.all(disparity > 2 * case.tol)   # returning (x1, y1) can never be right
    for case in correspondence.cases:
        # Q4.1's points: every goal style reaches their match, and it is out of reach of a box of
        # +-BOX rows and off the transposed line F^T x1 (neither slip can be right there)...
        along = along_line(case.F, case.pts1, case.truth2)
        assert np.all((along > BOX + case.tol) & (along <= NEAR)), along
        assert np.all(off_transposed_line(case.F, case.pts1, case.truth2) > case.tol)
        # ... and the correct styles do well there, so the goal is high
        assert case.ref_share >= 0.8, case.shares


@pytest.mark.parametrize("style", sorted(STYLES))
def test_correct_matcher_styles_get_full_Q41_and_Q42(hidden, style):
    matcher = STYLES[style]
    q = _questions(hidden, epipolarCorrespondence=matcher, compute3D_pts=_compute3D_with(matcher))
    for qid in ("Q4.1", "Q4.2"):
        assert q[qid].score == q[qid].max_score, (qid, [t.feedback for t in q[qid].tests])
    # judged on the easy points, against the weakest of several styles, and said so
    assert all("easy points" in t.feedback and "correct matcher styles" in t.feedback for t in q["Q4.1"].tests)


def test_a_flat_temple_loses_Q42(hidden):
    """Matches that keep (x1, y1), triangulated, make a flat temple: up to a similarity it lies near
    many points where the relief is small, but not near enough of them for the structure to be evident."""
    q42 = _questions(hidden, epipolarCorrespondence=returns_the_point,
                     compute3D_pts=_compute3D_with(returns_the_point))["Q4.2"]
    assert q42.score < q42.max_score, [t.feedback for t in q42.tests]
    assert any("a flat temple puts" in t.feedback for t in q42.tests), [t.feedback for t in q42.tests]


@pytest.mark.parametrize("wrong", sorted(WRONG) + sorted(HALF))
def test_wrong_matchers_lose_Q41(hidden, wrong):
    """Every wrong matcher keeps less than half of Q4.1; the two slips that kept most of it (the
    line F^T x1, a +-10 px box) keep at most a fifth on each scene (their matches are never right)."""
    q41 = _questions(hidden, ("-k", "test_matches"), epipolarCorrespondence={**WRONG, **HALF}[wrong])["Q4.1"]
    assert q41.score < 0.5 * q41.max_score, [t.feedback for t in q41.tests]
    if wrong in HALF:
        assert all(t.score <= 0.2 * t.max_score for t in q41.tests), [t.feedback for t in q41.tests]
    assert "not right; the first" in q41.tests[0].feedback   # says where the student's matches went


# A 2022-2024 compute3D_pts: five arguments, its own findM2 (|t| = 1), returns (M2, C2, P); the
# "result" variant saves into result/ first (a folder that does not exist: the call fails and the
# kit grades the matcher and triangulate instead).
FIVE_ARGUMENTS = '''
import numpy as np

def compute3D_pts(temple_pts1, intrinsics, F, im1, im2):
    K1, K2 = intrinsics["K1"], intrinsics["K2"]
    pts2 = np.zeros(temple_pts1.shape, dtype=int)
    for i, (x1, y1) in enumerate(temple_pts1):
        pts2[i] = epipolarCorrespondence(im1, im2, F, x1, y1)
    M2, C2, P = findM2(F, temple_pts1.astype(float), pts2.astype(float), K1, K2)
    SAVE
    return M2, C2, P
'''


@pytest.mark.parametrize("save", ["", "np.savez('result/q4_2.npz', M2=M2, C2=C2)"])
def test_another_years_compute3D_pts_returning_cameras_is_judged_by_its_structure(hidden, save, tmp_path,
                                                                                  monkeypatch):
    import solutions

    monkeypatch.chdir(tmp_path)   # no result/ here
    namespace = {"epipolarCorrespondence": ssd5_local_int, "findM2": solutions.findM2}
    exec(FIVE_ARGUMENTS.replace("SAVE", save or "pass"), namespace)  # noqa: S102 - the test's own cell
    q42 = _questions(hidden, epipolarCorrespondence=ssd5_local_int, compute3D_pts=namespace["compute3D_pts"])["Q4.2"]
    assert q42.score == q42.max_score, [t.feedback for t in q42.tests]
    feedback = q42.tests[0].feedback
    assert "on the temple's surface, up to a similarity" in feedback
    route = ("graded through your epipolarCorrespondence (Q4.1) and triangulate (Q3.2)" if save
             else "graded through your compute3D_pts(temple_pts1, intrinsics, F, im1, im2)")
    assert feedback.startswith(route), feedback


def test_read_points_finds_P_among_the_cameras_and_names_a_camera_alone():
    P = np.arange(30.0).reshape(10, 3)
    assert np.array_equal(jc.read_points((np.eye(3, 4), np.eye(3, 4), P), 10), P)
    assert np.array_equal(jc.read_points((np.eye(3, 4), np.eye(3, 4), P, np.eye(3, 4), np.eye(3, 4)), 10), P)
    with pytest.raises(ValueError, match="3 x 4 matrix"):
        jc.read_points(np.eye(3, 4), 10)


def test_structure_is_judged_up_to_a_similarity_and_not_beyond():
    rng = np.random.default_rng(3)
    truth = rng.normal(size=(30, 3))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    R = q * np.sign(np.linalg.det(q))
    moved = 0.3 * truth @ R.T + [1.0, -2.0, 5.0]
    assert jc.right_structure(moved, truth, 0.05)[0].all()
    wrong = moved.copy()
    wrong[:10, 2] += 3.0            # a third of the points far off their surface
    right = jc.right_structure(wrong, truth, 0.05)[0]
    assert right[10:].all() and not right[:10].any()


@pytest.mark.parametrize("style", sorted(STYLES))
def test_correct_matcher_styles_pass_the_public_self_checks(style):
    from starter.checks.correspondence import check_compute3D_pts, check_epipolarCorrespondence

    matcher = STYLES[style]
    matches = check_epipolarCorrespondence(matcher, verbose=False)
    structure = check_compute3D_pts(_compute3D_with(matcher), verbose=False)
    assert "1/1 passed" in matches.text() and "easy points" in matches.text(), matches.text()
    assert "1/1 passed" in structure.text(), structure.text()
    assert "surface" in structure.text()


def test_the_public_self_check_passes_images_as_the_notebooks_load_them():
    from starter.checks.correspondence import check_epipolarCorrespondence

    seen = []

    def matcher(im1, im2, F, x1, y1):
        seen.append((im1.dtype, float(im1.max())))
        return ssd5_local_int(im1, im2, F, x1, y1)

    check_epipolarCorrespondence(matcher, verbose=False)
    assert seen and all(dtype == np.float32 and top <= 1.0 for dtype, top in seen)
