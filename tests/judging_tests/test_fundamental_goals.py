"""Q2's goals hold under every secret: valid methods keep full Q2, mistakes lose it.

For each secret (CI's 4, the release sweep's 20: tests/support/breadth.py) the hidden Q2 inputs are prepared as the grader prepares them
(``autograder.inputs.fundamental.prepare_fundamental`` on the hidden scenes of
``quick_config(secret=...)``; the default data, the same under every secret, under the first),
every eightpoint below is called through a ``LocalStudent`` as the hidden tests call it
(``request_F``: as given, and with refineF switched off by the sandbox's own switch), and graded by
the hidden tests' own ``judge_q2``:

- every valid method (1/M or Hartley scaling, refineF before or after unscaling or not at all,
  SVD or eigh; no rank-2 step of its own when refineF, rank 2 switched off too, comes before
  unscaling) gets 10/10 under every secret;
- the polished transposed F (the design matrix of F^T, then refineF, then unscaling; also with
  refineF after unscaling) keeps at most half of Q2 under every secret, named "F transposed";
- every other mistake of the catalogue (transposed, rank 3 without refineF, not unscaled, unscaled
  the wrong way, x/y swapped, uint16 wrap-around; with and without refineF) loses Q2 and is named, under the
  first secrets (tests/end_to_end/test_secret_sweep.py judges them under all its secrets).

The margins (measured / goal of every judgment: the largest of the valid methods, and for each
mistake the judgment that rejects it most clearly) are printed for the report (``pytest -s``).
"""

from __future__ import annotations

import re
from functools import lru_cache

import breadth
import corpus
import numpy as np
import parallel
import pytest
from corpus import variants

# The hidden tests register their "points" marker in their own pytest.ini, not here.
pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::pytest.PytestUnknownMarkWarning")]

SECRETS = breadth.secrets("goal-secret")   # CI's breadth, 20 with HW4_SWEEP_ALL=1 (tests/support/breadth.py)
# The other mistakes of the catalogue (each also judged by tests/end_to_end/test_secret_sweep.py) under the
# first few secrets: refineF's cost (about 0.2 s a call) makes every secret count.
MISTAKE_SECRETS = SECRETS[:5]
@lru_cache(maxsize=None)
def _points() -> dict:
    """The points of each Q2 test: the markers of autograder/hidden/test_fundamental.py (read when
    a test runs: importing it registers no "points" marker here)."""
    from autograder.hidden import test_fundamental as tf

    tests = {"fits": tf.test_F_fits_the_true_matches, "rank": tf.test_F_has_rank_2,
             "exact": tf.test_noise_free_matches_give_an_exact_F, "uint16": tf.test_uint16_points_work_as_float_ones}
    return {k: float(next(m.args[0] for m in f.pytestmark if m.name == "points")) for k, f in tests.items()}


HALF_OF_Q2 = 0.5   # the share of Q2 the polished transposed F may keep at most

VALID = {
    "answer key (refineF before unscaling)": ("program", "key_full_marks"),
    "no refineF": ("program", "no_refineF_full_marks"),
    "Hartley": ("program", "hartley_normalisation_full_marks"),
    "Hartley, refineF": ("cell", variants.EIGHTPOINT_HARTLEY_REFINED),
    "refineF after unscaling": ("cell", variants.EIGHTPOINT_REFINED_AFTER_UNSCALING),
    "eigh, refineF": ("cell", variants.EIGHTPOINT_EIGH_REFINED),
    "eigh": ("cell", variants.eightpoint_cell(solver="eigh")),
    # refineF's output is rank 2 (switched off too): the SVD step of its own is then not needed.
    "no rank-2 step, refineF before unscaling": ("cell", variants.EIGHTPOINT_RANK3_REFINED),
}
# name -> (source, the catalogue code its feedback must name)
POLISHED_TRANSPOSED = {
    "polished transposed F": (variants.EIGHTPOINT_TRANSPOSED_REFINED, "f_transposed"),
    "polished transposed F, refineF after unscaling": (variants.EIGHTPOINT_TRANSPOSED_REFINED_AFTER_UNSCALING,
                                                       "f_transposed"),
}
MISTAKES = {
    "transposed F": (variants.eightpoint_cell("f_transposed"), "f_transposed"),
    "rank 3": (variants.eightpoint_cell("f_rank3"), "f_rank3"),
    "not unscaled, refineF": (variants.eightpoint_cell("f_not_unscaled", refine=True), "f_not_unscaled"),
    "unscaled the wrong way": (variants.eightpoint_cell("f_unscaled_wrong_way"), "f_unscaled_wrong_way"),
    "x/y swapped, refineF": (variants.eightpoint_cell("xy_swapped", refine=True), "xy_swapped"),
    "uint16 wrap-around": (variants.eightpoint_cell("uint16_wraparound"), "uint16_wraparound"),
    "uint16 wrap-around, refineF": (variants.eightpoint_cell("uint16_wraparound", refine=True), "uint16_wraparound"),
}


def _from_cell(source: str):
    namespace: dict = {"__name__": "goal_cell"}
    exec("from starter import refineF\n", namespace)  # noqa: S102 - the notebook's import cell
    exec(compile(source, "<cell>", "exec"), namespace)  # noqa: S102 - the kit's own corpus
    return namespace["eightpoint"]


def _function(kind: str, what: str):
    if kind == "program":
        return corpus.program_namespace(what, {"eightpoint": None})["eightpoint"]
    return _from_cell(what)


def _light_scenes(secret: str, default: bool = True):
    """The Scenes of ``quick_config(secret=secret)`` as far as Q2 uses them (hidden temples, the
    default data unless ``default`` is False, the two-view pair): the car scenes are left out.  The temples are rendered as the
    grader renders them: the matches are picked among fully covered pixels, which the supersampling
    changes."""
    from autograder.inputs.config import quick_config
    from autograder.inputs import scenes as hs
    from scenes.defaults import default_temple
    from scenes.temple import make_temple_scene

    config = quick_config(secret=secret)
    hidden = tuple(hs.TempleCase(f"hidden scene {k}", make_temple_scene(
        config.seed(f"temple-{k}"), width=spec.width, height=spec.height, noise_px=spec.noise_px))
        for k, spec in enumerate(config.temples, start=1))
    fixed = hs.TempleCase("the default data", default_temple()) if default else None
    return hs.Scenes(config=config, hidden=hidden, default=fixed,
                     official=None, car=None, probe_car=None, two_view=hs._two_view(hidden[-1].scene))


@lru_cache(maxsize=None)
def _prepared(secret: str):
    from autograder.inputs.fundamental import prepare_fundamental

    # The default data do not depend on the secret: judged under the first secret only.
    return prepare_fundamental(_light_scenes(secret, default=secret == SECRETS[0]))


def _grade(fn, p) -> tuple[dict, dict, dict]:
    """(judge_q2's grades, F by case, F with refineF off by case) of ``fn`` on the prepared ``p``."""
    from autograder.hidden.plugin import LocalStudent
    from autograder.hidden.test_fundamental import judge_q2, request_F

    student = LocalStudent({"eightpoint": fn})
    F, F_off = request_F(student, p), request_F(student, p, {"refineF": "off"})
    return judge_q2(p, F, F_off), F, F_off


def _score(grades: dict) -> float:
    return sum(points * grades[k][0] for k, points in _points().items())


def _ratios(p, F, F_off) -> dict:
    """measured / goal of each judgment with a figure, the worst over the cases: fit (RMS / goal) on
    the noisy scenes, exact (max distance / EXACT_TOL * M) on the noise-free ones, as given and with
    refineF off, and rank (s3/s2 / RANK_RTOL) with refineF off."""
    from judging import fundamental as jf
    from judging.mistakes import epipolar_statistic
    from judging.verdict import Malformed

    def usable(G):
        return not isinstance(G, Malformed)

    out = {"fit": max(epipolar_statistic(F[c], c.eval1, c.eval2, "rms") / c.goal if usable(F[c]) else np.inf
                      for c in p.cases)}
    for key, Fs in (("exact", F), ("exact, refineF off", F_off)):
        out[key] = max(epipolar_statistic(Fs[c], c.eval1, c.eval2, "max") / c.goal if usable(Fs[c]) else np.inf
                       for c in p.exact)
    s = []
    for c in p.cases:
        if usable(F_off[c]):
            S = np.diag([c.M, c.M, 1.0])
            sv = np.linalg.svd(S @ F_off[c] @ S, compute_uv=False)
            s.append(sv[2] / sv[1] / jf.RANK_RTOL)
    out["rank, refineF off"] = max(s) if s else np.inf
    return out


def test_light_scenes_are_the_graders():
    """The scenes this test prepares from are the grader's (same seeds, same matches)."""
    from autograder.inputs.config import quick_config
    from autograder.inputs.scenes import make_scenes

    secret = SECRETS[0]
    light, full = _light_scenes(secret), make_scenes(quick_config(secret=secret))
    assert [t.label for t in light.temple_cases()] == [t.label for t in full.temple_cases()]
    for a, b in zip(light.temple_cases(), full.temple_cases()):
        assert np.array_equal(a.pts1, b.pts1) and np.array_equal(a.pts2, b.pts2) and a.M == b.M
    assert np.array_equal(light.two_view.pts2, full.two_view.pts2)


def test_the_uint16_case_overflows_and_is_a_valid_scene():
    from autograder.inputs.fundamental import prepare_fundamental  # noqa: F401 - the module under test
    from core.geometry import symmetric_epipolar_distances

    p = _prepared(SECRETS[0])
    u = p.uint16.pts1.astype(np.int64), p.uint16.pts2.astype(np.int64)
    assert p.uint16.pts1.dtype == np.uint16
    # every product of two coordinates (of one image or across both) passes 65535
    assert min(u[0].min(), u[1].min()) ** 2 > 65535
    big = next(c for c in p.exact if c.label.endswith("enlarged"))
    from solutions import eightpoint

    F = eightpoint(big.pts1, big.pts2, big.M, refine=False)
    assert np.max(symmetric_epipolar_distances(F, big.pts1, big.pts2)) < 1e-6 * big.M
    assert p.float_twin().pts1.dtype == np.float64 and np.array_equal(p.float_twin().pts1, p.uint16.pts1)


# What _judge_secret grades, set before the processes fork (exec'd functions cannot be pickled).
_JOB: dict = {}


def _judge_secret(secret: str) -> dict:
    """One secret of ``_judge_all``: problems, the ratios of the valid methods and of the mistakes,
    the mistakes' scores, and the fit goals."""
    valid, wrong, must_lose = _JOB["valid"], _JOB["wrong"], _JOB["must_lose"]
    out = {"problems": [], "valid": [], "wrong": {}, "scores": {}, "goals": []}
    p = _prepared(secret)
    out["goals"] = [(c.goal, c.label) for c in p.cases]
    for name, fn in valid.items():
        grades, F, F_off = _grade(fn, p)
        for k, (fraction, lines, _) in grades.items():
            if fraction < 1.0:
                out["problems"].append(f"{secret}: valid {name} loses points in {k}: " + " | ".join(lines))
        out["valid"] += [(k, r, f"{name}, {secret}") for k, r in _ratios(p, F, F_off).items()]
    for name, (fn, code) in wrong.items():
        grades, F, F_off = _grade(fn, p)
        score = out["scores"][name] = _score(grades)
        named = {m.code for _, _, ms in grades.values() for m in ms}
        if score >= 10 - 1e-9:
            out["problems"].append(f"{secret}: mistake {name} keeps full Q2")
        elif name in POLISHED_TRANSPOSED and score > HALF_OF_Q2 * sum(_points().values()) + 1e-9:
            out["problems"].append(f"{secret}: mistake {name} keeps {score:g} of Q2's 10 (more than half)")
        elif code not in named:
            out["problems"].append(f"{secret}: mistake {name} loses Q2 but {code} is not named (named: {named})")
        out["problems"] += [f"{secret}: mistake {name} keeps {grades[k][0]:.2f} of the {k} test"
                            for k in must_lose if grades[k][0] > 0.5]
        if code == "uint16_wraparound":
            continue   # judged by "same F or not": no figure
        r = _ratios(p, F, F_off)
        judged = max(r, key=lambda k: r[k])   # the judgment that rejects it most clearly
        out["wrong"][name] = (r[judged], f"{judged}, {secret}")
    return out


def _judge_all(secrets, valid: dict, wrong: dict, must_lose: tuple[str, ...] = ()) -> list[str]:
    """Grade ``valid`` and ``wrong`` ({name: (function, code)}) under ``secrets`` (two processes,
    ``parallel.fork_map``); print the margins; return the problems (a valid method losing points,
    a mistake keeping full Q2, not named, or keeping the points of a test named in ``must_lose``)."""
    _JOB.update(valid=valid, wrong=wrong, must_lose=must_lose)
    per_secret = parallel.fork_map(_judge_secret, secrets)
    problems = [line for r in per_secret for line in r["problems"]]
    worst_valid: dict[str, tuple[float, str]] = {}
    closest_wrong: dict[str, tuple[float, str]] = {}
    for r in per_secret:
        for k, ratio, where in r["valid"]:
            if ratio > worst_valid.get(k, (-1.0, ""))[0]:
                worst_valid[k] = (ratio, where)
        for name, (ratio, where) in r["wrong"].items():
            if ratio < closest_wrong.get(name, (np.inf, ""))[0]:
                closest_wrong[name] = (ratio, where)
    scores = {name: [r["scores"][name] for r in per_secret] for name in wrong}
    by_label: dict[str, list[float]] = {}
    for goal, label in (g for r in per_secret for g in r["goals"]):
        by_label.setdefault(re.sub(r" \d+$", " k", label), []).append(goal)
    print(f"\nQ2 under {len(secrets)} secrets; fit goals (px) by scene: "
          + "; ".join(f"{k}: {min(v):.3g} to {max(v):.3g}" for k, v in by_label.items()))
    if valid:
        print("valid methods, the largest measured / goal of each judgment (must stay below 1):")
        for k, (r, where) in sorted(worst_valid.items()):
            print(f"  {k}: {r:.3g} ({where})")
    print("mistakes: Q2 score range; over secrets, the smallest of the largest measured / goal (must pass 1):")
    for name in wrong:
        r, where = closest_wrong.get(name, (float("nan"), "uint16: same F or not, no figure"))
        print(f"  {name}: {min(scores[name]):g} to {max(scores[name]):g} / 10; {r:.3g} ({where})")
    return problems


def test_valid_methods_keep_full_Q2_and_the_polished_transposed_F_loses_it_under_every_secret():
    valid = {name: _function(*how) for name, how in VALID.items()}
    wrong = {name: (_from_cell(source), code) for name, (source, code) in POLISHED_TRANSPOSED.items()}
    # Polished by refineF, the transposed design matrix's F fits noisy matches as well as the
    # reference's (and, unpolished, too where F is nearly skew-symmetric): the noise-free matches
    # are what must take its points, as returned or with refineF off.
    problems = _judge_all(SECRETS, valid, wrong, must_lose=("exact",))
    assert not problems, "\n".join(problems)


def test_every_other_mistake_loses_Q2_and_is_named():
    wrong = {name: (_from_cell(source), code) for name, (source, code) in MISTAKES.items()}
    problems = _judge_all(MISTAKE_SECRETS, {}, wrong)
    assert not problems, "\n".join(problems)
