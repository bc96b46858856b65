"""Q3.3: a findM2 that tests the depth in camera 1 only fails the public self-check and the hidden test.

Its rule (keep the candidates with every point in front of camera 1, then the smallest error)
chose the right camera on ordinary data by chance: the twisted pair's error is within a fraction
of a percent of the right one's.  The twisted-pair case (solutions.twisted_pair: it triangulates,
so it is made on the grader's side) makes it choose the twisted pair, deterministically, in the
public check (the public seed's case, committed as starter/checks/twisted_pair.json by
``python -m kit check-data``) and in the hidden test (the grader's seed of the draw), while
correct findM2s of every style keep full marks.
"""

from __future__ import annotations

import numpy as np
import pytest

from autograder.inputs.config import quick_config
from autograder.inputs.build import build_hidden_inputs
from autograder.inputs.keep import default_keep
from autograder.hidden.plugin import HIDDEN_DIR, LocalStudent, run_here
from core.geometry import IDENTITY_POSE, depths
from judging import pose as jp
from starter import camera2
from starter.checks.pose import check_findM2
from solutions.twisted_pair import MARGIN, TRIANGULATIONS, candidate_roles, twisted_pair_case
from starter.checks._scenes import PUBLIC_SEED
from starter.checks.twisted_pair import CASE_FILE, decode, public_case

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

SECRETS = ("twisted-a", "twisted-b", "twisted-c")


def _essential(F, K1, K2):
    return K2.T @ F @ K1


def _findM2(triangulate, rule):
    """A findM2 written by a student: ``triangulate`` (C1, p1, C2, p2) -> w (N, 3); ``rule`` of the depth test."""

    def findM2(F, pts1, pts2, K1, K2):
        cands = camera2(_essential(F, K1, K2))
        C1 = K1 @ IDENTITY_POSE
        best = None
        for i in range(4):
            M2 = cands[:, :, i]
            w = triangulate(C1, np.asarray(pts1, float), K2 @ M2, np.asarray(pts2, float))
            w = w[0] if isinstance(w, tuple) else w
            key = rule(w, M2, C1, K2 @ M2, pts1, pts2)
            if key is not None and (best is None or key > best[0]):
                best = (key, M2, K2 @ M2, w)
        return best[1], best[2], best[3]

    return findM2


def _error(C1, C2, pts1, pts2, w):
    from judging.triangulation import reprojection_error

    return reprojection_error(C1, pts1, C2, pts2, w)


def camera1_only(w, M2, C1, C2, p1, p2):
    # The mistake: candidates with every point in front of camera 1, then the smallest error.
    return -_error(C1, C2, p1, p2, w) if np.all(w[:, 2] > 0) else None


def both_all(w, M2, C1, C2, p1, p2):
    return 1 if np.all(w[:, 2] > 0) and np.all(depths(M2, w) > 0) else None


def both_count(w, M2, C1, C2, p1, p2):
    return int(np.sum((w[:, 2] > 0) & (depths(M2, w) > 0)))


def _reference_triangulate():
    from solutions import triangulate

    return triangulate


def _intrinsics_style(findM2):
    def findM2_old(F, pts1, pts2, intrinsics, filename="q3_3.npz"):
        return findM2(F, pts1, pts2, intrinsics["K1"], intrinsics["K2"])

    return findM2_old


# ------------------------------------------------------------------------------ the case itself

def test_the_margin_holds_under_20_seeds_for_every_triangulation_and_depth_rule():
    import solutions

    methods = {**TRIANGULATIONS, "the reference's": solutions.triangulate}
    worst = 0.0
    for seed in range(20):
        case = twisted_pair_case(np.random.default_rng(seed).integers(2**63))
        p = case.pair
        cands, right, twisted = candidate_roles(p.M2)
        C1 = p.K1 @ IDENTITY_POSE
        for name, tri in methods.items():
            res = []
            for i in range(4):
                w = tri(C1, case.pts1, p.K2 @ cands[:, :, i], case.pts2)
                w = w[0] if isinstance(w, tuple) else w
                res.append((w[:, 2] > 0, depths(cands[:, :, i], w) > 0,
                            _error(C1, p.K2 @ cands[:, :, i], case.pts1, case.pts2, w)))
            z1, z2, err = zip(*res)
            assert np.all(z1[right] & z2[right]), (seed, name)            # both rules keep the right one
            assert all(np.mean(z1[i] & z2[i]) < 0.5 for i in range(4) if i != right), (seed, name)
            assert [i for i in range(4) if np.all(z1[i])] == sorted([right, twisted]), (seed, name)
            ratio = err[twisted] / err[right]
            assert ratio < MARGIN, (seed, name, ratio)
            worst = max(worst, ratio)
        # The judged answer is the truth, and the reference chooses it.
        assert jp.right_camera(solutions.findM2(p.F, case.pts1, case.pts2, p.K1, p.K2)[0], p.M2).passed
    print(f"twisted pair: worst error ratio {worst:.3f} (goal < {MARGIN})")


def test_the_case_is_made_from_its_seed_alone():
    a, b, c = twisted_pair_case(5), twisted_pair_case(5), twisted_pair_case(6)
    assert np.array_equal(a.pts1, b.pts1) and np.array_equal(a.pair.M2, b.pair.M2)
    assert not np.allclose(a.pair.M2, c.pair.M2)


def test_the_twisted_pair_is_named_and_the_candidate_behind_both_cameras_is_not():
    case = twisted_pair_case(3)
    p = case.pair
    named = jp.right_camera(case.twisted, p.M2, p.X)
    assert not named.passed and [m.code for m in named.mistakes] == ["depth_one_camera"]
    assert "in front of camera 1 and behind camera 2" in named.mistakes[0].evidence
    cands, right, twisted = candidate_roles(p.M2)
    for i in set(range(4)) - {right, twisted}:
        codes = [m.code for m in jp.right_camera(cands[:, :, i], p.M2, p.X).mistakes]
        if np.allclose(cands[:, :3, i], p.M2[:, :3]):     # t reversed: every point behind both cameras
            assert codes == ["wrong_camera"], i
        else:                                             # the twisted pair's mirror: a camera-2-only test
            assert codes == ["depth_one_camera"], i
    assert jp.right_camera(p.M2, p.M2, p.X).passed
    # Without the true points (the default data, the official data) the generic name stays.
    assert [m.code for m in jp.right_camera(case.twisted, p.M2).mistakes] == ["wrong_camera"]


# ------------------------------------------------------------------------------ the public check

def test_the_committed_public_case_is_a_fresh_computation_and_reads_back_exactly():
    from kit.check_data import TWISTED_FILE, fresh

    assert TWISTED_FILE == CASE_FILE
    assert CASE_FILE.read_text(encoding="utf-8") == fresh(CASE_FILE.name)
    made, read = twisted_pair_case(PUBLIC_SEED), public_case()
    for a, b in [(made.pair.K1, read.pair.K1), (made.pair.K2, read.pair.K2), (made.pair.M2, read.pair.M2),
                 (made.pair.X, read.pair.X), (made.pts1, read.pts1), (made.pts2, read.pts2),
                 (made.twisted, read.twisted), (made.F, read.F)]:
        assert np.array_equal(a, b)
    assert made.margin == read.margin < MARGIN
    assert candidate_roles(read.pair.M2)[0][:, :, candidate_roles(read.pair.M2)[2]].tolist() == read.twisted.tolist()
    assert decode(CASE_FILE.read_text(encoding="utf-8")).pts1.shape == (12, 2)


def test_the_public_check_fails_depth_in_camera_1_only_and_names_it():
    report = check_findM2(_findM2(_reference_triangulate(), camera1_only), verbose=False)
    assert not report.passed
    assert "depth_one_camera" in {m.code for m in report.mistakes}, report.text()


@pytest.mark.parametrize("rule", [both_all, both_count])
@pytest.mark.parametrize("tri", ["SVD of A", "reference"])
def test_the_public_check_passes_correct_styles(rule, tri):
    triangulate = _reference_triangulate() if tri == "reference" else TRIANGULATIONS[tri]
    report = check_findM2(_findM2(triangulate, rule), verbose=False)
    assert report.passed, report.text()


# ------------------------------------------------------------------------------ the hidden test

def _q33(hidden, findM2):
    import solutions

    functions = {name: getattr(solutions, name) for name in solutions.__all__}
    # Only Q3.3's file: the others do not call findM2.
    result = run_here(LocalStudent(dict(functions, findM2=findM2)), hidden, tests=(HIDDEN_DIR / "test_pose.py",))
    return next(q for q in result.questions if q.id == "Q3.3")


@pytest.fixture(scope="module", params=SECRETS)
def hidden(request):
    return build_hidden_inputs(quick_config(secret=request.param), keep=default_keep())  # the suite's keep


def test_the_hidden_test_fails_depth_in_camera_1_only_and_names_it(hidden):
    q = _q33(hidden, _findM2(_reference_triangulate(), camera1_only))
    camera = next(t for t in q.tests if "M2 is the camera" in t.name)
    assert camera.score < camera.max_score, camera.feedback
    assert "depth tested in one camera only" in camera.feedback, camera.feedback


@pytest.mark.parametrize("style", ["all in front, own SVD of A", "most in front, reference, old signature"])
def test_the_hidden_test_gives_correct_styles_full_marks(hidden, style):
    if style.startswith("all"):
        fn = _findM2(TRIANGULATIONS["SVD of A"], both_all)
    else:
        fn = _intrinsics_style(_findM2(_reference_triangulate(), both_count))
    q = _q33(hidden, fn)
    assert q.score == q.max_score, [t.feedback for t in q.tests]
