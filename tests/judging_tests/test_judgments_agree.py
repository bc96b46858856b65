"""The public self-checks and the hidden tests agree, right or wrong, on the very same inputs.

For every corpus submission (tests/support/corpus: whole student programs named by their outcome) and
every function of the homework with a self-check, the submission's functions are run here,
without a sandbox: each notebook's defining statements (core.notebook's rule set, as the grader
keeps them) are executed in one fresh namespace.  Then

- the hidden judgment: the concept's pytest file (``autograder/hidden/test_<concept>.py``) run in
  this process on the hidden inputs of a small grading config, the functions called through a
  ``LocalStudent`` (``autograder.hidden.plugin.run_here``); a function is right when every hidden
  test of it has full marks;
- the public self-check, given those same hidden inputs explicitly (``scene=``, ``cases=``,
  ``problems=``, ``inputs=``, ``probes=``/``sequence=``); right when the report passed
  (for bundle adjustment both sides also get the public scene's problem: ``prepared_for``);

must agree, and when both name known mistakes they must name the same ones.  Hostile
submissions (exits, bombs, loops: the sandbox's business) are left out.  A program is judged on
the functions its difference from the key reaches (the secret sweep's rule); what it shares with
the key is judged once, with the key.
"""

from __future__ import annotations

import re

import corpus
import numpy as np
import pytest

from judging.mistakes import KNOWN_MISTAKES

pytestmark = pytest.mark.slow

PROGRAMS = list(corpus.IN_PROCESS)

# function -> (hidden concept: autograder/hidden/test_<concept>.py, the hidden tests that judge it:
# a name prefix per question id)
FUNCTIONS = {
    "eightpoint": ("fundamental", {"Q2": ""}),
    "essentialMatrix": ("essential", {"Q3.1": ""}),
    "triangulate": ("triangulation", {"Q3.2": ""}),
    "findM2": ("pose", {"Q3.3": ""}),
    "epipolarCorrespondence": ("correspondence", {"Q4.1": ""}),
    "compute3D_pts": ("correspondence", {"Q4.2": ""}),
    "rodriguesResidual": ("bundle", {"Q5": "rodriguesResidual"}),
    "bundleAdjustment": ("bundle", {"Q5": ("bundle adjustment", "M2 holds", "o1 and o2")}),
    "MultiviewReconstruction": ("multiview", {"Q6": ("3D keypoints", "only detections")}),
}
_NAME_TO_CODE = {name: code for code, (name, _) in KNOWN_MISTAKES.items()}


# --------------------------------------------------------------------------------- programs

def program(name: str) -> dict:
    """The functions a corpus submission defines, executed here as the grader keeps its statements."""
    return functions_of(corpus.program_namespace(name, FUNCTIONS))


def functions_of(namespace: dict) -> dict:
    return {f: namespace[f] for f in (*FUNCTIONS, "plot_3d_keypoint_video") if callable(namespace.get(f))}


KEY = "key_full_marks"


def judged_apart(namespace: dict, key: dict) -> list[str]:
    """The functions whose judgment can differ from the key's: those of the hidden files the
    program's difference from the key reaches (the secret sweep's rule, ``concepts_reached``).
    The others are the key's own code on the same inputs, so both sides judge them as they judge
    the key's, which the key's program checks."""
    from sweep import concepts_reached, hidden_files_of

    reached = set(concepts_reached(namespace, key, hidden_files_of()))
    return [f for f, (concept, _) in FUNCTIONS.items() if concept in reached]


@pytest.fixture(scope="module")
def hidden():
    from autograder.inputs.config import quick_config
    from autograder.inputs.build import build_hidden_inputs

    return build_hidden_inputs(quick_config())


# --------------------------------------------------------------------------------- the inputs

def prepared_for(hidden, concept: str):
    """The concept's prepared inputs, with the public check's own problem in where a public-only
    input could hide a disagreement (bundle adjustment: the public scene's problem replaces the
    last hidden one)."""
    import dataclasses

    prepared = hidden.prepared[concept]
    if concept == "bundle":
        from starter.checks.bundle import problem_of_scene
        from starter.checks._scenes import two_view

        extra = dataclasses.replace(problem_of_scene(two_view()), label="the public scene")
        # In place of the last hidden problem: the question's points stay those of two problems.
        prepared = dataclasses.replace(prepared, problems=(*prepared.problems[:-1], extra))
    return prepared


# --------------------------------------------------------------------------------- the two sides

def hidden_outcome(hidden, functions: dict, function: str) -> tuple[bool, set[str], str]:
    """(right, mistake codes named, feedback) of the hidden tests that judge ``function``."""
    import dataclasses

    from autograder.hidden.plugin import HIDDEN_DIR, LocalStudent, run_here

    concept, tests = FUNCTIONS[function]
    inputs = dataclasses.replace(hidden, prepared={**hidden.prepared, concept: prepared_for(hidden, concept)})
    result = run_here(LocalStudent(functions), inputs, tests=[HIDDEN_DIR / f"test_{concept}.py"])
    chosen = []
    for q in result.questions:
        prefixes = tests.get(q.id)
        if prefixes is None:
            continue
        prefixes = (prefixes,) if isinstance(prefixes, str) else prefixes
        chosen += [t for t in q.tests if t.name.startswith(prefixes)]
    assert chosen, f"no hidden test judges {function}"
    feedback = "\n".join(t.feedback for t in chosen if t.score < t.max_score)
    names = set(re.findall(r"Likely mistake: ([^.]+)\.", feedback))
    return all(t.score >= t.max_score - 1e-9 for t in chosen), {_NAME_TO_CODE[n] for n in names}, feedback


def _pair_of(scene_pair, noisy1=None, noisy2=None, M=None):
    from starter.checks._scenes import NoisyPair

    p1 = np.rint(scene_pair.pts1).astype(np.uint16) if noisy1 is None else noisy1
    p2 = np.rint(scene_pair.pts2).astype(np.uint16) if noisy2 is None else noisy2
    return NoisyPair(scene_pair, p1, p2, float(M if M is not None else 640.0))


def public_reports(hidden, functions: dict, function: str) -> list:
    """The self-check reports of ``function`` on the hidden inputs of its hidden tests."""
    from starter import checks
    from starter.checks._scenes import noisy_pair

    fn = functions.get(function)
    sc = hidden.scenes
    prep = hidden.prepared
    kw = {"verbose": False}
    if function == "eightpoint":
        base = sc.default or sc.hidden[-1]
        return [checks.check_eightpoint(fn, scene=noisy_pair(base.scene), **kw)]
    if function == "essentialMatrix":
        p = prep["essential"]
        return [checks.check_essentialMatrix(fn, scene=_pair_of(sc.two_view), inputs=p.inputs, **kw)]
    if function == "triangulate":
        return [checks.check_triangulate(fn, scene=_pair_of(sc.two_view), **kw),
                *(checks.check_triangulate(fn, scene=noisy_pair(tc.scene), **kw) for tc in sc.hidden)]
    if function == "findM2":
        p = prep["pose"]
        noisy = p.cases[1]
        return [checks.check_findM2(fn, scene=_pair_of(sc.two_view), **kw),
                checks.check_findM2(fn, scene=noisy_pair(sc.hidden[0].scene), F=noisy.F, right=noisy.right, **kw)]
    if function == "epipolarCorrespondence":
        return [checks.check_epipolarCorrespondence(fn, cases=prep["correspondence"].cases, **kw)]
    if function == "compute3D_pts":
        p = prep["correspondence"]
        return [checks.check_compute3D_pts(fn, cases=[p.points_case], **kw)]
    if function == "rodriguesResidual":
        return [checks.check_rodriguesResidual(fn, inputs=prep["bundle"].residual_inputs, **kw)]
    if function == "bundleAdjustment":
        return [checks.check_bundleAdjustment(fn, problems=prepared_for(hidden, "bundle").problems, **kw)]
    if function == "MultiviewReconstruction":
        p = prep["multiview"]
        return [checks.check_MultiviewReconstruction(fn, probes=p.probes, sequence=p.sequence, **kw)]
    raise KeyError(function)


def public_outcome(hidden, functions: dict, function: str) -> tuple[bool, set[str], str]:
    reports = public_reports(hidden, functions, function)
    codes = {m.code for r in reports for m in r.mistakes}
    return all(r.passed for r in reports), codes, "\n".join(r.text() for r in reports)


def assert_agree(hidden, functions: dict, function: str, where: str) -> None:
    h_ok, h_codes, h_text = hidden_outcome(hidden, functions, function)
    p_ok, p_codes, p_text = public_outcome(hidden, functions, function)
    assert h_ok == p_ok, (f"{where}, {function}: hidden says {'right' if h_ok else 'wrong'}, the self-check says "
                          f"{'right' if p_ok else 'wrong'}\n--- hidden:\n{h_text}\n--- public:\n{p_text}")
    if h_codes and p_codes:
        assert h_codes == p_codes, f"{where}, {function}: hidden names {h_codes}, public {p_codes}"


# --------------------------------------------------------------------------------- the test

@pytest.fixture(scope="module")
def key_namespace() -> dict:
    return corpus.program_namespace(KEY, FUNCTIONS)


@pytest.mark.parametrize("name", PROGRAMS)
def test_self_checks_and_hidden_tests_agree_on_the_corpus(hidden, key_namespace, name):
    namespace = key_namespace if name == KEY else corpus.program_namespace(name, FUNCTIONS)
    functions = functions_of(namespace)
    for function in FUNCTIONS if name == KEY else judged_apart(namespace, key_namespace):
        assert_agree(hidden, functions, function, name)


def test_programs_are_the_corpus_submissions(key_namespace):
    assert KEY in PROGRAMS  # every function the others share with it is judged with the key's program
    assert set(FUNCTIONS) <= set(functions_of(key_namespace))


def test_a_program_is_judged_apart_on_what_its_difference_reaches(key_namespace):
    assert judged_apart(key_namespace, key_namespace) == []
    transposed = corpus.program_namespace("transposed_F_loses_Q2", FUNCTIONS)
    assert judged_apart(transposed, key_namespace) == ["eightpoint"]
    # triangulate is called by findM2 and compute3D_pts: their judgments are made again too
    crashed = corpus.program_namespace("syntax_error_in_triangulate_cell_loses_Q3_2_Q3_3_Q4_2", FUNCTIONS)
    assert {"triangulate", "findM2", "compute3D_pts"} <= set(judged_apart(crashed, key_namespace))
    assert "essentialMatrix" not in program("missing_essentialMatrix_loses_Q3_1_and_Q3_3")
