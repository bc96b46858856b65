"""refineF switched off, faithfully, by every route, the same in the self-check and the grader.

- Switched off, refineF keeps its contract: it accepts what it accepts switched on (F as 3x3 or any
  9 numbers) and returns the closest rank-2 matrix to F at unit norm, (3, 3) float; only the
  minimisation is gone.  An eightpoint handing refineF a 9-vector, or one with no rank-2 step of
  its own calling refineF before unscaling, keeps full Q2; the polished transposed F still loses
  the noise-free points.
- The routes that dodged the old swap (a default argument, an import inside eightpoint,
  ``starter.refineF(...)`` in the self-check) are switched off, and the public self-check and the
  grader switch off the very same routes, a student's own helper module included.

The grader is run in-process (the hidden tests' own ``request_F`` and ``judge_q2`` on a
``LocalStudent``) and once through the sandbox's child.  Everything new is imported inside the
tests, so that this file runs on the commit before the switch and shows what failed there.
"""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest
from corpus import variants

import starter
from starter.epipolar import refineF
from core.paths import KIT_ROOT

# The hidden tests register their "points" marker in their own pytest.ini, not here.
pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::pytest.PytestUnknownMarkWarning")]

DEF = "def eightpoint(pts1, pts2, M):\n    "
CALL = "F = refineF(F, p1, p2)"

# A student's helper.py with a refineF of their own (not the kit's object), polishing as the course's does.
HELPER = '''\
import numpy as np
import scipy.optimize


def _rank2(F):
    U, S, Vt = np.linalg.svd(F)
    return U @ np.diag([S[0], S[1], 0.0]) @ Vt


def refineF(F, pts1, pts2):
    F = np.reshape(F, (3, 3))
    h1 = np.column_stack([pts1, np.ones(len(pts1))])
    h2 = np.column_stack([pts2, np.ones(len(pts2))])

    def cost(f):
        G = _rank2(f.reshape(3, 3))
        l2, l1 = h1 @ G.T, h2 @ G
        r = np.sum(h2 * l2, axis=1) ** 2
        return np.sum(r / (l2[:, 0] ** 2 + l2[:, 1] ** 2) + r / (l1[:, 0] ** 2 + l1[:, 1] ** 2))

    f = scipy.optimize.minimize(cost, F.ravel() / np.linalg.norm(F), method="Powell",
                                options={"xtol": 1e-4, "ftol": 1e-4, "maxfev": 10000}).x
    out = _rank2(f.reshape(3, 3))
    return out / np.linalg.norm(out)
'''


def _helper_module() -> types.ModuleType:
    helper = types.ModuleType("helper")
    exec(compile(HELPER, "<helper.py>", "exec"), helper.__dict__)  # noqa: S102 - the test's own module
    return helper


def _route(source: str, route: str) -> tuple[str, dict]:
    """(source, namespace extras) of an eightpoint cell reaching refineF by ``route``."""
    assert source.count(DEF) == 1 and source.count(CALL) == 1
    if route == "global name":
        return source, {"refineF": refineF}
    if route == "another name":
        return source.replace(CALL, "F = polish(F, p1, p2)"), {"polish": refineF}
    if route == "starter.refineF":
        return source.replace(CALL, "F = starter.refineF(F, p1, p2)"), {"starter": starter}
    if route == "default argument":
        return (source.replace(DEF, "def eightpoint(pts1, pts2, M, _polish=refineF):\n    ")
                .replace(CALL, "F = _polish(F, p1, p2)"), {"refineF": refineF})
    if route == "imported inside":
        return source.replace(DEF, DEF + "from starter import refineF\n    "), {}
    if route == "own helper module":
        return source.replace(CALL, "F = helper.refineF(F, p1, p2)"), {"helper": sys.modules["helper"]}
    if route == "own helper imported inside":
        return source.replace(DEF, DEF + "from helper import refineF\n    "), {}
    if route == "own global function":
        return source, {"refineF": sys.modules["helper"].refineF}
    raise AssertionError(route)


ROUTES = ["global name", "another name", "starter.refineF", "default argument", "imported inside",
          "own helper module", "own helper imported inside", "own global function"]


def _defined(source: str, **extras):
    namespace = {"__name__": "student_cell", **extras}
    exec(compile(source, "<student cell>", "exec"), namespace)  # noqa: S102 - the tests' own cells
    return namespace["eightpoint"]


# A 9-vector handed to refineF (the course's helper reshapes what it gets), no rank-2 step of its own.
NINE_VECTOR = variants.EIGHTPOINT_RANK3_REFINED.replace("F = np.linalg.svd(A)[2][-1].reshape(3, 3)",
                                                        "F = np.linalg.svd(A)[2][-1]")


@pytest.fixture
def helper(monkeypatch):
    """The student's own helper module, importable as ``helper`` for the length of a test."""
    module = _helper_module()
    monkeypatch.setitem(sys.modules, "helper", module)
    return module


@pytest.fixture(scope="module")
def fundamental():
    from autograder.inputs.config import quick_config
    from autograder.inputs.fundamental import prepare_fundamental
    from autograder.inputs.scenes import make_scenes

    return prepare_fundamental(make_scenes(quick_config()))


@pytest.fixture(scope="module")
def no_data(tmp_path_factory):
    return tmp_path_factory.mktemp("empty")


def _grade(student, p) -> dict:
    """The hidden Q2 tests' grades of ``student``'s eightpoint: {test: (fraction, lines, mistakes)}."""
    from autograder.hidden.test_fundamental import judge_q2, request_F

    return judge_q2(p, request_F(student, p), request_F(student, p, {"refineF": "off"}))


def _grade_here(fn, p) -> dict:
    from autograder.hidden.plugin import LocalStudent

    return _grade(LocalStudent({"eightpoint": fn}), p)


def _full(grades) -> bool:
    return all(fraction == 1 for fraction, _, _ in grades.values())


# ------------------------------------------------------------------------ the switched-off helper's contract


def test_switched_off_refineF_returns_the_rank2_projection_at_unit_norm():
    from core.refine_switch import is_off, switched_off

    rng = np.random.default_rng(16)
    p1, p2 = rng.uniform(0, 1, (2, 12, 2))
    for F in (rng.normal(size=(3, 3)), rng.normal(size=(3, 3)) * 1e4):
        U, S, Vt = np.linalg.svd(F)
        projection = (U[:, :2] * S[:2]) @ Vt[:2]
        projection /= np.linalg.norm(projection)
        with switched_off(lambda: None) as run:
            assert is_off()
            out = refineF(F, p1, p2)
            flat = refineF(list(F.ravel()), p1, p2)
        assert not is_off() and run.calls == 2
        assert isinstance(out, np.ndarray) and out.shape == (3, 3) and out.dtype == np.float64
        s = np.linalg.svd(out, compute_uv=False)
        assert s[2] < 1e-12 * s[0] and s[1] > 1e-3 * s[0]        # rank 2, not less
        assert np.linalg.norm(out) == pytest.approx(1.0)
        np.testing.assert_allclose(out, projection, atol=1e-12)
        np.testing.assert_allclose(flat, out, atol=1e-12)


def test_refineF_takes_any_nine_numbers_and_names_F_otherwise():
    from core.refine_switch import switched_off

    two = np.random.default_rng(3).uniform(0, 1, (2, 10, 2))
    F = np.random.default_rng(4).normal(size=(3, 3))
    on = refineF(F, *two)
    assert refineF(F.ravel(), *two).shape == (3, 3)
    np.testing.assert_allclose(refineF(F.reshape(1, 9), *two), on, atol=1e-9)
    for off in (False, True):
        with switched_off(lambda: None) if off else _nothing():
            for bad, words in ((np.ones(8), "9 numbers"), (None, "None"), (np.zeros((3, 3)), "non-zero")):
                with pytest.raises(ValueError, match="^F: .*" + words):
                    refineF(bad, *two)
            with pytest.raises(ValueError, match="pts1"):     # the points are checked switched off too
                refineF(F, two[0][:5], two[1][:5])


class _nothing:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def test_the_switch_puts_everything_back(helper):
    from core.refine_switch import switched_off

    kit_before = starter.refineF
    source, extras = _route(variants.eightpoint_cell(refine=True), "default argument")
    own = helper.refineF
    fn = _defined(source.replace("_polish=refineF", "_polish=own"), own=own, helper=helper)
    with pytest.raises(RuntimeError):
        with switched_off(fn):
            assert helper.refineF is not own and fn.__defaults__[0] is not own
            raise RuntimeError("the student's code raised")
    assert helper.refineF is own and fn.__defaults__ == (own,) and starter.refineF is kit_before
    assert fn.__globals__["own"] is own


# ------------------------------------------------------------------------ the grader (in-process)


def test_a_nine_vector_handed_to_refineF_gets_full_Q2(fundamental):
    grades = _grade_here(_defined(NINE_VECTOR, refineF=refineF), fundamental)
    assert _full(grades), grades


def test_no_rank2_step_of_its_own_with_refineF_before_unscaling_keeps_the_rank_points(fundamental):
    grades = _grade_here(_defined(variants.EIGHTPOINT_RANK3_REFINED, refineF=refineF), fundamental)
    assert grades["rank"][0] == 1, grades["rank"]
    assert _full(grades), grades


# ------------------------------------------------------------------------ every route, self-check and grader alike


@pytest.mark.parametrize("route", ROUTES)
def test_the_polished_transposed_F_is_caught_by_every_route_in_both(route, helper, fundamental, no_data):
    from starter.checks.fundamental import check_eightpoint
    from starter.checks.instrument import refineF_switched_off

    source, extras = _route(variants.EIGHTPOINT_TRANSPOSED_REFINED, route)
    fn = _defined(source, **extras)
    rng = np.random.default_rng(5)
    _, calls = refineF_switched_off(fn, *rng.uniform(0, 640, (2, 12, 2)), 640.0)
    assert calls == 1

    report = check_eightpoint(fn, root=no_data, verbose=False)
    off = [i for i in report.items if "exact" in i.name and "refineF switched off" in i.name]
    assert not report.passed and off and off[0].passed is False, report.text()

    exact, lines, mistakes = _grade_here(fn, fundamental)["exact"]
    assert exact == 0, lines
    assert any("refineF switched off" in line for line in lines), lines


@pytest.mark.parametrize("route", ["default argument", "imported inside", "own helper imported inside"])
def test_a_valid_eightpoint_keeps_full_marks_by_the_new_routes(route, helper, fundamental, no_data):
    from starter.checks.fundamental import check_eightpoint

    source, extras = _route(variants.eightpoint_cell(refine=True), route)
    fn = _defined(source, **extras)
    assert check_eightpoint(fn, root=no_data, verbose=False).passed
    grades = _grade_here(fn, fundamental)
    assert _full(grades), grades


# ------------------------------------------------------------------------ through the sandbox's child


def test_the_sandbox_switches_off_faithfully(fundamental):
    from autograder.hidden.plugin import Student
    from autograder.sandbox import ResourceLimits, Sandbox
    from autograder.submission.read import SourceUnit

    limits = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)
    inner = _route(variants.EIGHTPOINT_TRANSPOSED_REFINED, "own helper imported inside")[0]
    units = [SourceUnit("helper.py", 1, HELPER, module="helper"),
             SourceUnit("nine.ipynb", 1, "from starter import refineF\n" + NINE_VECTOR),
             SourceUnit("inner.ipynb", 1, inner.replace("def eightpoint(", "def transposed_inner(")),
             SourceUnit("kit_inner.ipynb", 1, _route(variants.EIGHTPOINT_TRANSPOSED_REFINED, "imported inside")[0]
                        .replace("def eightpoint(", "def transposed_kit_inner("))]
    with Sandbox(KIT_ROOT, limits=limits) as box, box.session(units, budget=600) as session:
        student = Student(session)
        assert _full(_grade(student, fundamental))
        for name in ("transposed_inner", "transposed_kit_inner"):
            # The request as given comes first: it imports helper, which the switched-off one then finds.
            exact, lines, _ = _grade(_Renamed(student, name), fundamental)["exact"]
            assert exact == 0, (name, lines)


class _Renamed:
    """A Student whose "eightpoint" requests go to another function of the session."""

    def __init__(self, student, name):
        self.student, self.name = student, name
        self.time_scale = student.time_scale

    def each(self, function, inputs, **kw):
        return self.student.each(self.name if function == "eightpoint" else function, inputs, **kw)


# A student who reads the kit: each way of throwing the switch back on from inside the child,
# then the kit's refineF on the F given.
THROWS_THE_SWITCH = '''\
import importlib
import sys

import core.refine_switch
import starter
import starter.epipolar


def polish_anyway(F, pts1, pts2, how):
    if how == "patched is_off":
        core.refine_switch.is_off = lambda: False
    elif how == "emptied the runs":
        core.refine_switch._runs.clear()
    elif how == "dropped the grader helper":
        core.refine_switch._grader.clear()
    elif how == "reloaded the helper":
        importlib.reload(starter.epipolar)
    elif how == "imported the minimisation":
        from starter.refine_polish import polish
        return polish(F, pts1, pts2)
    elif how == "read the kit's file":
        import os
        found = []
        for folder in sys.path + [os.path.dirname(os.path.dirname(starter.__file__)), {kit!r}]:
            try:
                found.append(open(os.path.join(folder, "starter", "refine_polish.py")).read())
            except OSError:
                pass
        return found
    return starter.epipolar.refineF(F, pts1, pts2)
'''.replace("{kit!r}", repr(str(KIT_ROOT)))
HOWS = ("as given", "patched is_off", "emptied the runs", "reloaded the helper", "dropped the grader helper",
        "imported the minimisation", "read the kit's file")


def test_code_in_the_sandbox_cannot_polish_a_switched_off_run(two_view):
    """The grader, not the child, decides whether refineF minimises: switched off, every way the code
    has of turning the switch back on still gets the closest rank-2 F; switched on, the grader's
    minimisation is returned exactly.  The minimisation's module is neither importable nor readable."""
    from autograder.sandbox import ResourceLimits, Sandbox
    from core.refine_switch import closest_rank2
    from starter.refine_polish import polish

    rng = np.random.default_rng(7)
    p1, p2 = two_view["pts1"] / 640.0, two_view["pts2"] / 640.0
    F = rng.normal(size=(3, 3))            # a poor start: the minimisation moves it far
    limits = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)
    with Sandbox(KIT_ROOT, limits=limits) as box, box.session(THROWS_THE_SWITCH, budget=300) as session:
        off = session.map("polish_anyway", [((h,), {}) for h in HOWS], args=(F, p1, p2), seconds=60,
                          swap={"refineF": "off"})
        on = session.map("polish_anyway", [(("as given",), {})], args=(F, p1, p2), seconds=60)
    projected, polished = closest_rank2(F), polish(F, p1, p2)
    assert np.linalg.norm(projected - polished) > 0.1 and np.linalg.norm(projected + polished) > 0.1
    for how, outcome in zip(HOWS, off):
        # Module globals stay changed for the inputs after (the code's own state): each attack adds up.
        if how == "read the kit's file":   # the kit's own copy (its path guessed) is hidden too
            assert outcome.status == "ok" and not any("Powell" in text for text in outcome.value), outcome
            continue
        if how in ("imported the minimisation", "dropped the grader helper"):
            # Without the grader, the kit's refineF has nothing to minimise with: it fails, never polishes.
            assert outcome.status == "exception", (how, outcome)
            continue
        assert outcome.status == "ok", (how, outcome.message)
        assert np.allclose(outcome.value, projected, atol=1e-12), how
    assert on[0].status == "ok" and np.array_equal(on[0].value, polished)


def test_the_grader_polishes_each_set_of_arguments_once_and_answers_as_the_polish_does(monkeypatch):
    # The grader computes refineF for sandboxed code (autograder.sandbox.helpers); the same
    # arguments again (a regrade, copies of the key) get the remembered answer, bit for bit.
    import json
    from collections import OrderedDict

    import starter.refine_polish as refine_polish
    from autograder.sandbox import helpers
    from core import wire

    real, calls = refine_polish.polish, []
    monkeypatch.setattr(refine_polish, "polish", lambda *a: calls.append(1) or real(*a))
    monkeypatch.setattr(helpers, "_POLISHED", OrderedDict())
    rng = np.random.default_rng(11)
    p1, p2, F = rng.uniform(0, 200, (12, 2)), rng.uniform(0, 200, (12, 2)), rng.normal(size=(3, 3))

    def ask(F, p1, p2, switched_off=False):
        record = {"event": "helper", "seq": 3, "name": "refineF", "args": wire.encode((F, p1, p2))}
        reply = json.loads(helpers.answer(record, switched_off=switched_off, calls=1, limits=wire.Limits()))
        return wire.decode(reply["value"], wire.Limits())

    first = ask(F, p1, p2)
    assert np.array_equal(first, real(F, p1, p2)) and len(calls) == 1
    assert np.array_equal(ask(F.copy(), p1.copy(), p2.copy()), first) and len(calls) == 1
    moved = p2.copy()
    moved[0, 0] += 1e-9  # other points, however close: polished again
    ask(F, p1, moved)
    assert len(calls) == 2
    off = ask(F, p1, p2, switched_off=True)  # the switched-off run never polishes
    assert len(calls) == 2 and np.linalg.matrix_rank(off) == 2 and not np.allclose(off, first)


def test_the_grader_keeps_polished_results_in_the_runs_keep(monkeypatch, tmp_path):
    # With a keep (autograder.inputs.keep), a later grading process reads the polish back.
    from collections import OrderedDict

    import starter.refine_polish as refine_polish
    from autograder.inputs.keep import Keep
    from autograder.sandbox import helpers

    real, calls = refine_polish.polish, []
    monkeypatch.setattr(refine_polish, "polish", lambda *a: calls.append(1) or real(*a))
    rng = np.random.default_rng(12)
    p1, p2, F = rng.uniform(0, 200, (10, 2)), rng.uniform(0, 200, (10, 2)), rng.normal(size=(3, 3))
    keep = Keep(tmp_path / "keep")
    try:
        helpers.remember_in(keep.fetch)
        for _ in range(2):  # two grading processes: each starts with nothing in memory
            monkeypatch.setattr(helpers, "_POLISHED", OrderedDict())
            assert np.array_equal(helpers._polished(F, p1, p2), real(F, p1, p2))
    finally:
        helpers.remember_in(None)
    assert len(calls) == 1 and len(list((tmp_path / "keep").iterdir())) == 1
