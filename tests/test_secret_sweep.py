"""Verdicts do not depend on the secret beyond noise (issue 9): a sweep over 20 secrets.

For each secret, hidden temple scenes are made as ``autograder.hidden.scenes.make_scenes`` makes
them (seeds ``config.seed("temple-k")`` at the sizes and noise of ``quick_config``; rendered at
``supersample=1`` to keep the sweep quick: the matches do not depend on it), and the kit's Q2
alternatives and mistakes (tests/corpus: whole programs executed in-process, and the cells of
tests/corpus/variants.py) are judged by the judging functions directly, as the hidden Q2 tests
judge them:

- on each noisy scene: ``fit`` (goal ``fit_goal`` of the reference's valid methods) and ``rank_two``;
- on each scene's noise-free matches: ``exact_fit``;
- the scene's matches as uint16: ``uint16_same``;
- with refineF switched off (``starter.checks.instrument.refineF_switched_off``, when the function
  calls it): ``exact_fit`` on the noise-free matches, ``rank_two`` on the noisy ones, ``uint16_same``.

Every valid method passes every judgment under every secret; every mistake fails at least one
under every secret (the polished transposed F through the refineF-off judgments).  The worst
margins are printed (``pytest -s``) for the report.
"""

from __future__ import annotations

import dataclasses
import functools

import corpus
import numpy as np
import pytest
from corpus import variants

pytestmark = pytest.mark.slow

SECRETS = [f"sweep-secret-{k:02d}" for k in range(20)]

# Whole corpus programs (their eightpoint), by expected outcome.
VALID_PROGRAMS = ["key_full_marks", "hartley_normalisation_full_marks", "no_refineF_full_marks"]
MISTAKE_PROGRAMS = ["transposed_F_loses_Q2", "rank2_not_enforced_loses_part_of_Q2", "F_not_unscaled_loses_Q2",
                    "uint16_wraparound_loses_part_of_Q2"]
# Cells of variants.py.
VALID_CELLS = {
    "refined_before_unscaling": variants.eightpoint_cell(refine=True),
    "refined_after_unscaling": variants.EIGHTPOINT_REFINED_AFTER_UNSCALING,
    "eigh_refined": variants.EIGHTPOINT_EIGH_REFINED,
    "eigh_not_refined": variants.eightpoint_cell(solver="eigh"),
    "hartley_refined": variants.EIGHTPOINT_HARTLEY_REFINED,
}
MISTAKE_CELLS = {
    "transposed_refined": variants.EIGHTPOINT_TRANSPOSED_REFINED,
    "transposed_refined_after_unscaling": variants.EIGHTPOINT_TRANSPOSED_REFINED_AFTER_UNSCALING,
    "rank3_refined": variants.EIGHTPOINT_RANK3_REFINED,
    "not_unscaled_refined": variants.eightpoint_cell("f_not_unscaled", refine=True),
    "unscaled_wrong_way": variants.eightpoint_cell("f_unscaled_wrong_way"),
    "xy_swapped_refined": variants.eightpoint_cell("xy_swapped", refine=True),
}


def _from_cell(source: str):
    namespace: dict = {"__name__": "sweep_cell"}
    exec("from starter import refineF\n", namespace)  # noqa: S102 - the notebook's import cell
    exec(compile(source, "<cell>", "exec"), namespace)  # noqa: S102 - the kit's own corpus
    return namespace["eightpoint"]


_HOMEWORK = {f: None for f in ("eightpoint", "essentialMatrix", "triangulate", "findM2", "epipolarCorrespondence",
                                "compute3D_pts", "rodriguesResidual", "bundleAdjustment", "MultiviewReconstruction")}


@functools.lru_cache(maxsize=None)
def _namespace(name: str) -> dict:
    """The namespace a corpus program's kept statements make (as the grader keeps them)."""
    return corpus.program_namespace(name, _HOMEWORK)


def _from_program(name: str, function: str = "eightpoint"):
    return _namespace(name)[function]


@dataclasses.dataclass
class _Scene:
    label: str
    pts1: np.ndarray     # uint16 noisy matches, as the data files hold them
    pts2: np.ndarray
    exact1: np.ndarray   # noise-free matches
    exact2: np.ndarray
    eval1: np.ndarray    # true matches of the visible points
    eval2: np.ndarray
    M: float
    scene: object = None  # the TempleScene (cameras, true pose)


@functools.lru_cache(maxsize=None)
def _scenes(secret: str) -> list[_Scene]:
    """The hidden temple scenes of ``quick_config(secret=secret)``, as make_scenes seeds them."""
    from autograder.config import quick_config
    from scenes.temple import make_temple_scene

    config = quick_config(secret=secret)
    out = []
    for k, spec in enumerate(config.temples, start=1):
        s = make_temple_scene(config.seed(f"temple-{k}"), width=spec.width, height=spec.height,
                              noise_px=spec.noise_px, supersample=1)
        keep = s.visible2
        e1, e2 = np.column_stack([s.x1, s.y1]).astype(float)[keep], s.x2_true[keep]
        out.append(_Scene(f"hidden scene {k}", np.asarray(s.pts1), np.asarray(s.pts2), s.pts1_true, s.pts2_true,
                          e1, e2, float(s.M), s))
    return out


def _rms(F, e1, e2) -> float:
    from core.geometry import symmetric_epipolar_distances

    return float(np.sqrt(np.mean(symmetric_epipolar_distances(F, e1, e2) ** 2)))


def _ratio(verdict) -> float:
    """measured / goal of a Verdict's figures ("RMS distance 0.3 px" / "<= 0.9 px"), nan if none."""
    import re

    number = r"(?<![\w^.])[-+]?\d*\.?\d+(?:e[-+]?\d+)?"   # not the 3 of "s3" nor the 2 of "px^2"
    m, g = re.findall(number, verdict.measured), re.findall(number, verdict.goal)
    if not m or not g or float(g[0]) == 0:
        return float("nan")
    return float(m[0]) / float(g[0])


def _run(fn, *args):
    try:
        return fn(*args)
    except Exception:  # noqa: BLE001 - a crash is judged as a zero F (fails every judgment)
        return np.zeros((3, 3))


def _off(fn, *args):
    """(F with refineF switched off, calls) as the hidden Q2 test gets it."""
    from starter.checks.instrument import refineF_switched_off

    try:
        return refineF_switched_off(fn, *args)
    except Exception:  # noqa: BLE001
        return np.zeros((3, 3)), 1


def q2_verdicts(fn, sc: _Scene, F_noisy, goal):
    """The Q2 verdicts of ``fn`` on one scene, cheapest first (a generator: a mistake stops at its first
    failure): with refineF switched off (noise-free exact_fit, noisy rank_two), the F as written on the
    noise-free matches (exact_fit), then on the noisy ones (fit with ``goal``, rank_two).  ``F_noisy``:
    the F as written on the noisy matches, or None to compute it."""
    from judging import fundamental as jf

    Fx_off, calls = _off(fn, sc.exact1, sc.exact2, sc.M)
    if calls:
        yield "noise-free, refineF off", jf.exact_fit(Fx_off, sc.exact1, sc.exact2, sc.M)
        yield "refineF off", jf.rank_two(_off(fn, sc.pts1.astype(float), sc.pts2.astype(float), sc.M)[0], sc.M)
    yield "noise-free", jf.exact_fit(_run(fn, sc.exact1, sc.exact2, sc.M), sc.exact1, sc.exact2, sc.M)
    if F_noisy is None:
        F_noisy = _run(fn, sc.pts1.astype(float), sc.pts2.astype(float), sc.M)
    yield "noisy", jf.fit(F_noisy, sc.eval1, sc.eval2, goal, sc.M)
    yield "noisy", jf.rank_two(F_noisy, sc.M)


def uint16_verdicts(fn, pts1, pts2, M):
    """uint16_same of ``fn`` (the F as written and, when it calls refineF, with refineF switched off)."""
    from judging import fundamental as jf

    p1, p2 = pts1.astype(float), pts2.astype(float)
    yield "uint16", jf.uint16_same(_run(fn, pts1, pts2, M), _run(fn, p1, p2, M))
    F_off, calls = _off(fn, p1, p2, M)
    if calls:
        yield "uint16, refineF off", jf.uint16_same(_off(fn, pts1, pts2, M)[0], F_off)


@pytest.fixture(scope="module")
def eightpoints():
    valid = {n: _from_program(n) for n in VALID_PROGRAMS} | {n: _from_cell(s) for n, s in VALID_CELLS.items()}
    wrong = {n: _from_program(n) for n in MISTAKE_PROGRAMS} | {n: _from_cell(s) for n, s in MISTAKE_CELLS.items()}
    return valid, wrong


# The reference's valid methods behind the fit goal (autograder/hidden/cases/fundamental.py: the reference with
# and without refineF, and with Hartley's normalisation): the corpus programs doing exactly that.
_GOAL_METHODS = ("key_full_marks", "no_refineF_full_marks", "hartley_normalisation_full_marks")
# Mistakes seen only with uint16 points whose products pass 65535.
_UINT16_ONLY = ("uint16_wraparound_loses_part_of_Q2",)


def test_q2_verdicts_do_not_depend_on_the_secret(eightpoints):
    from judging import fundamental as jf

    valid, wrong = eightpoints
    problems = []
    worst_valid: dict[str, tuple[float, str]] = {}   # judgment -> (largest measured/goal of a valid method, where)
    closest_wrong: dict[str, tuple[float, str]] = {}  # mistake -> (smallest measured/goal of its first failure, where)
    goals, ref_rms, noise = [], [], []
    for secret in SECRETS:
        for sc in _scenes(secret):
            F_noisy = {n: _run(fn, sc.pts1.astype(float), sc.pts2.astype(float), sc.M) for n, fn in valid.items()}
            refs = [_rms(F_noisy[n], sc.eval1, sc.eval2) for n in _GOAL_METHODS]
            goal = jf.fit_goal(refs)
            goals.append(goal)
            ref_rms.append(refs[0])
            noise.append(_rms(_true_F(sc), sc.pts1.astype(float), sc.pts2.astype(float)))
            for name, fn in valid.items():
                for where, v in q2_verdicts(fn, sc, F_noisy[name], goal):
                    r = _ratio(v)
                    if not np.isnan(r) and r > worst_valid.get(v.what, (-1.0, ""))[0]:
                        worst_valid[v.what] = (r, f"{name}, {secret}, {sc.label}, {where}")
                    if not v.passed:
                        problems.append(f"{secret}: valid {name} fails on {sc.label}, {where}: {v.sentence}")
            for name, fn in wrong.items():
                if name in _UINT16_ONLY:
                    continue  # float points: nothing wraps; judged on uint16 points below
                first = next(((w, v) for w, v in q2_verdicts(fn, sc, None, goal) if not v.passed), None)
                if first is None:
                    problems.append(f"{secret}: mistake {name} passes every judgment on {sc.label}")
                    continue
                r = _ratio(first[1])
                if r < closest_wrong.get(name, (np.inf, ""))[0]:
                    closest_wrong[name] = (r, f"{secret}, {sc.label}, {first[0]}: {first[1].what}")
    # uint16: as the hidden test, on the default data (640 x 480: products of coordinates wrap around)
    from scenes.defaults import default_temple

    d = default_temple()
    for name, fn in {**valid, **wrong}.items():
        vs = list(uint16_verdicts(fn, np.asarray(d.pts1), np.asarray(d.pts2), float(d.M)))
        if name in valid and not all(v.passed for _, v in vs):
            problems.append(f"valid {name} fails uint16_same on the default data")
        if name in _UINT16_ONLY and all(v.passed for _, v in vs):
            problems.append(f"mistake {name} passes uint16_same on the default data")
    print(f"\nfit goals {min(goals):.3g} to {max(goals):.3g} px; the reference's RMS {min(ref_rms):.3g} to "
          f"{max(ref_rms):.3g} px; the true F's RMS on the noisy matches {min(noise):.3g} to {max(noise):.3g} px")
    print("worst valid measured/goal per judgment:")
    for k, (r, where) in sorted(worst_valid.items()):
        print(f"  {k}: {r:.3g} ({where})")
    print("mistakes: smallest measured/goal of the first judgment they fail (over secrets and scenes):")
    for k, (r, where) in sorted(closest_wrong.items()):
        print(f"  {k}: {r:.3g} ({where})")
    assert not problems, "\n".join(problems)


def _true_F(sc: _Scene) -> np.ndarray:
    """F fitted to the noise-free matches (the scene's own F up to scale), to measure the noise."""
    from solutions import eightpoint

    return eightpoint(sc.exact1, sc.exact2, sc.M, refine=False)


def _cell_function(source: str, function: str, key_namespace: dict):
    """``function`` from a variants.py cell executed over the key's namespace (its helpers kept)."""
    namespace = dict(key_namespace)
    exec(compile(source, "<cell>", "exec"), namespace)  # noqa: S102 - the kit's own corpus
    return namespace[function]


def test_q3_triangulation_and_pose_verdicts_do_not_depend_on_the_secret():
    """Q3.2 (noisy matches: error against the reference's linear error; err reported) and Q3.3 (the
    right camera of the four, its outputs) on the hidden scenes of every secret, as the hidden tests."""
    from judging import pose as jp
    from judging import triangulation as jt
    from judging.verdict import Malformed
    from solutions import eightpoint, essentialMatrix, triangulate
    from starter import camera2

    key = _namespace("key_full_marks")
    tri_valid = {"key": key["triangulate"]}
    tri_wrong = {"mean_error": _cell_function(variants.TRIANGULATE_MEAN_ERROR, "triangulate", key),
                 "w_not_divided": _cell_function(variants.TRIANGULATE_W_NOT_DIVIDED, "triangulate", key),
                 "w_not_divided_own_err": _cell_function(variants.TRIANGULATE_W_NOT_DIVIDED_OWN_ERR, "triangulate", key),
                 "points_mirrored": _cell_function(variants.TRIANGULATE_POINTS_MIRRORED, "triangulate", key)}
    pose_valid = {"key": key["findM2"]}
    pose_wrong = {"cheirality_flipped": _namespace("cheirality_sign_flipped_loses_Q3_3")["findM2"]}
    M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    problems, worst = [], {}

    def note(kind, name, secret, label, verdicts):
        ok = all(v.passed for v in verdicts)
        if kind == "valid":
            for v in verdicts:
                r = _ratio(v)
                if not np.isnan(r) and r > worst.get(v.what, (-1.0, ""))[0]:
                    worst[v.what] = (r, f"{name}, {secret}, {label}")
            if not ok:
                problems.append(f"{secret}: valid {name} fails on {label}: "
                                + "; ".join(v.sentence for v in verdicts if not v.passed))
        elif ok:
            problems.append(f"{secret}: mistake {name} passes on {label}")

    for secret in SECRETS:
        for sc in _scenes(secret):
            s = sc.scene
            p1, p2 = sc.pts1.astype(float), sc.pts2.astype(float)
            C1, C2 = s.K1 @ M1, s.K2 @ s.M2
            linear_err = triangulate(C1, p1, C2, p2)[1]
            for kind, fns in (("valid", tri_valid), ("wrong", tri_wrong)):
                for name, fn in fns.items():
                    try:
                        w, err = jt.read_w_err(fn(C1, p1, C2, p2), len(p1))
                        vs = [jt.noisy_error(w, C1, p1, C2, p2, linear_err, s.M2),
                              jt.err_reported(err, w, C1, p1, C2, p2)]
                    except (Malformed, Exception) as exc:  # noqa: BLE001 - a crash fails the judgments
                        if kind == "valid":
                            problems.append(f"{secret}: {name} raised {exc!r}")
                        continue
                    note(kind, f"triangulate {name}", secret, sc.label, vs)
            if sc.label != "hidden scene 1":
                continue  # the hidden pose test uses the first hidden scene
            F = eightpoint(p1, p2, sc.M)
            cands = camera2(essentialMatrix(F, s.K1, s.K2))
            gaps = [max(jp.pose_gap(cands[:, :, i], s.M2)) for i in range(cands.shape[2])]
            right = cands[:, :, int(np.argmin(gaps))]
            for kind, fns in (("valid", pose_valid), ("wrong", pose_wrong)):
                for name, fn in fns.items():
                    try:
                        M2, C2s, w = jp.read_findM2(fn(F, p1, p2, s.K1, s.K2), len(p1))
                    except (Malformed, Exception) as exc:  # noqa: BLE001 - a crash fails the judgments
                        if kind == "valid":
                            problems.append(f"{secret}: {name} raised {exc!r}")
                        continue
                    lin = triangulate(s.K1 @ M1, p1, s.K2 @ M2, p2)[1] if np.all(np.isfinite(M2)) else np.inf
                    note(kind, f"findM2 {name}", secret, sc.label,
                         [jp.right_camera(M2, right), jp.outputs(M2, C2s, w, s.K1, s.K2, p1, p2, lin)])
    print("\nQ3 worst valid measured/goal per judgment:")
    for k, (r, where) in sorted(worst.items()):
        print(f"  {k}: {r:.3g} ({where})")
    assert not problems, "\n".join(problems)


# ---------------------------------------------------------------------------------------------
# outside the homework: NumPy 1 code (issue 9)

@pytest.mark.parametrize("name, replacement", [("float", "float"), ("int", "int"), ("object", "object"),
                                               ("Inf", "np.inf"), ("NaN", "np.nan"), ("infty", "np.inf"),
                                               ("PINF", "np.inf"), ("product", "np.prod"),
                                               ("cumproduct", "np.cumprod"), ("alltrue", "np.all"),
                                               ("sometrue", "np.any"), ("asfarray", "np.asarray"),
                                               ("msort", "np.sort"), ("row_stack", "np.vstack")])
def test_numpy2_hint_names_the_removed_name_and_its_replacement(name, replacement):
    from judging.hints import numpy2_hint

    hint = numpy2_hint(f"module 'numpy' has no attribute '{name}'")
    assert hint is not None and f"np.{name} " in hint and f"use {replacement}" in hint
    assert numpy2_hint("module 'numpy' has no attribute 'not_a_numpy_name'") is None
    assert numpy2_hint("index 3 is out of bounds") is None


def test_self_check_error_line_carries_the_numpy2_hint():
    from starter.checks.report import call

    src = "import numpy as np\ndef eightpoint(pts1, pts2, M):\n    return np.Inf * np.eye(3)\n"
    namespace: dict = {}
    exec(compile(src, "<cell>", "exec"), namespace)  # noqa: S102
    out = call(namespace["eightpoint"], None, None, 640)
    assert out.status == "error" and "use np.inf instead" in out.message and "scored nothing" in out.message
