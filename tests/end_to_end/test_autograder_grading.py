"""The autograder end to end: hidden tests, grading orchestration, CLI, and the corpus of submissions.

The corpus (tests/support/corpus/) holds one submission per expected outcome, built from the answer key
or the untouched student notebooks by one mutation each; its names say what must happen.  All
of it is graded once, as one batch of two workers sharing a sandbox each, with the small
settings of ``quick_config`` and tight resource limits.  The hidden tests are also run
without a sandbox, in this process (``autograder.hidden.plugin.run_here``), on chosen functions
called through ``LocalStudent`` (fast, and it isolates the checks from the sandbox).
"""

from __future__ import annotations

import csv
import json
import os
import re
import zipfile

import corpus
import nbformat
import numpy as np
import pytest
from hidden_files import files_grading

from autograder.inputs.config import (
    DEV_SECRET,
    GradingConfig,
    TempleSpec,
    load_config,
    quick_config,
)
from autograder.channels.batch import grade_batch, submission_digest
from autograder.inputs.build import build_hidden_inputs
from autograder.hidden.plugin import HIDDEN_DIR, LocalStudent, run_here
from autograder.grading.key import write_key_submission
from autograder.feedback.results import autograded_question_ids
from autograder.sandbox import CallOutcome, ResourceLimits, Sandbox, live_pids_of_uid
from autograder.submission.read import load_submission
from core.manifest import NOTEBOOKS, QUESTIONS, question

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

LIMITS = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)
QIDS = autograded_question_ids()


# ---------------------------------------------------------------------------------------------
# fixtures


@pytest.fixture(scope="module")
def config() -> GradingConfig:
    return quick_config()


@pytest.fixture(scope="module")
def hidden(config):
    return build_hidden_inputs(config)  # with its scenes (the hard-coded answers come from one)


@pytest.fixture(scope="module")
def batch(tmp_path_factory, config):
    """Every corpus submission and two unreadable ones, graded as one batch with two workers."""
    root = tmp_path_factory.mktemp("corpus")
    out = root / "out"
    paths = [corpus.build(name, root / "subs", out=out) for name in corpus.CASES]
    not_a_zip = root / "subs" / "renamed_text_file_fails.zip"
    not_a_zip.write_text("this is not a zip archive")
    slip = root / "subs" / "zip_slip_archive_fails.zip"
    with zipfile.ZipFile(slip, "w") as zf:
        zf.writestr("../../q2_eightpoint.ipynb", "{}")
    paths += [not_a_zip, slip]
    records = grade_batch(paths, out, jobs=2, config=config, progress=False, pictures=False, limits=LIMITS)
    return {"out": out, "paths": paths, "records": {r.name: r for r in records}}


def _results(batch, name) -> dict:
    return json.loads((batch["out"] / name / "results.json").read_text())


def _feedback(batch, name) -> str:
    return (batch["out"] / name / "feedback.md").read_text()


def _section(feedback: str, qid: str) -> str:
    """The part of feedback.md about question ``qid``."""
    parts = re.split(r"^## ", feedback, flags=re.MULTILINE)
    return next((p for p in parts if p.startswith(f"{qid} ")), "")


# ---------------------------------------------------------------------------------------------
# the corpus


@pytest.mark.parametrize("name", list(corpus.CASES))
def test_corpus_submission_gets_the_grade_its_name_says(batch, name):
    case = corpus.CASES[name]
    rec = batch["records"][name]
    assert rec.failure is None, rec.failure
    for qid in QIDS:
        full = question(qid).points
        score = rec.scores[qid]
        if case.zero:
            assert score == 0, f"{qid}: a hostile or broken submission earned {score}"
        elif qid in case.loses:
            assert score < full, f"{qid} should lose points, got {score} / {full}"
        else:
            assert score == pytest.approx(full), f"{qid} should keep full marks, got {score} / {full}"
    if case.zero:
        assert rec.score == 0


@pytest.mark.parametrize("name", [n for n, c in corpus.CASES.items() if c.mistakes])
def test_feedback_names_the_mistake(batch, name):
    feedback = _feedback(batch, name)
    for qid, mistake_name in corpus.CASES[name].mistakes.items():
        assert f"Likely mistake: {mistake_name}" in _section(feedback, qid), _section(feedback, qid)


def test_results_json_follow_gradescope_schema_and_match_the_scores(batch):
    for name, rec in batch["records"].items():
        res = _results(batch, name)
        assert set(res) >= {"score", "output", "tests", "visibility", "stdout_visibility"}
        assert res["score"] == pytest.approx(rec.score)
        if rec.failure:
            assert res["tests"] == [] and res["score"] == 0
            continue
        assert sum(t["score"] for t in res["tests"]) == pytest.approx(res["score"])
        by_question: dict[str, float] = {}
        for t in res["tests"]:
            assert 0 <= t["score"] <= t["max_score"] and t["status"] in ("passed", "failed")
            by_question[t["name"].split()[0]] = by_question.get(t["name"].split()[0], 0) + t["max_score"]
        assert by_question == {qid: question(qid).points for qid in QIDS}


def test_unreadable_archives_get_a_failed_result_and_the_batch_goes_on(batch):
    for name in ("renamed_text_file_fails", "zip_slip_archive_fails"):
        rec = batch["records"][name]
        assert rec.failure and rec.score == 0
        assert "could not grade" in _feedback(batch, name)
    assert batch["records"]["key_full_marks"].score == sum(question(q).points for q in QIDS)


def test_grades_csv_has_one_row_per_submission_and_a_column_per_question(batch):
    with open(batch["out"] / "grades.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["student_id", "total", *QIDS]
    by_name = {r[0]: r for r in rows[1:]}
    assert set(by_name) == set(batch["records"])
    key = by_name["key_full_marks"]
    assert float(key[1]) == batch["records"]["key_full_marks"].score
    assert [float(x) for x in key[2:]] == [question(q).points for q in QIDS]


def test_feedback_shows_no_traceback_no_hidden_values_and_no_secret(batch, config):
    seeds = [str(config.seed(label)) for label in ("temple-1", "temple-2", "car", "matching", "bundle")]
    for name in batch["records"]:
        res = _results(batch, name)
        text = "\n".join([_feedback(batch, name), res["output"], *(t["output"] for t in res["tests"])])
        assert "Traceback" not in text and 'File "' not in text
        assert not re.search(r"\d\.\d{6,}", text), "long numbers could carry hidden inputs out"
        assert config.secret not in text and not any(s in text for s in seeds)
        assert "/autograder/tests" not in text and "solutions/" not in text


def test_hostile_writes_did_not_reach_the_grader(batch):
    res = _results(batch, "writes_results_files_zero")
    assert res["score"] == 0 and res["tests"]
    state = json.loads((batch["out"] / "writes_results_files_zero" / "grading.json").read_text())
    assert state["score"] == 0
    assert not corpus.trap_path(batch["out"]).exists()
    assert not corpus.trap_path(batch["out"]).parent.exists()


def test_every_submission_ran_in_the_strongest_sandbox_available(batch):
    levels = {json.loads((batch["out"] / n / "grading.json").read_text())["isolation"]["level"]
              for n, r in batch["records"].items() if r.failure is None}
    assert levels <= {"namespaces", "user-namespaces", "basic"}
    if os.geteuid() != 0:
        pytest.skip("not root: the namespaces level (own uid, hidden paths) is not available")
    try:
        Sandbox(isolation="namespaces").close()
    except RuntimeError as exc:
        pytest.skip(f"the namespaces level does not work on this machine ({exc})")
    assert levels == {"namespaces"}


def test_no_process_outlives_the_batch(batch):
    state = json.loads((batch["out"] / "process_left_running_zero" / "grading.json").read_text())
    uid = (state.get("isolation") or {}).get("uid")
    if uid is None:
        pytest.skip("the sandbox ran as the grader's own user here, so its processes cannot be told apart")
    assert live_pids_of_uid(uid) == []
    assert _results(batch, "process_left_running_zero")["score"] == 0


def test_reading_the_reference_fails_inside_the_sandbox(batch):
    feedback = _feedback(batch, "reads_grader_files_and_reference_zero")
    assert re.search(r"FileNotFoundError|PermissionError|no reference found", feedback), feedback[:2000]


def test_a_crash_costs_only_the_functions_that_crashed(batch):
    feedback = _feedback(batch, "sys_exit_and_os_exit_lose_Q2_Q3_1_Q3_3")
    assert "SystemExit" in _section(feedback, "Q2")
    assert "exit code 0" in _section(feedback, "Q3.1") or "ended" in _section(feedback, "Q3.1")
    assert batch["records"]["sys_exit_and_os_exit_lose_Q2_Q3_1_Q3_3"].scores["Q5"] == 20


def test_q42_feedback_says_which_path_was_graded(batch):
    assert "graded through your compute3D_pts" in _section(_feedback(batch, "key_full_marks"), "Q4.2")


def test_resumed_batch_skips_graded_work_and_regrades_changed_files(batch, config, tmp_path):
    paths = batch["paths"]
    again = grade_batch(paths, batch["out"], jobs=1, config=config, progress=False, pictures=False, limits=LIMITS)
    # A failed result (an unreadable archive) is not finished work: resume grades it again.
    failed = {n for n, r in batch["records"].items() if r.failure}
    assert failed and {r.name for r in again if not r.skipped} == failed
    assert {r.name: r.score for r in again} == {n: r.score for n, r in batch["records"].items()}
    changed = next(p for p in paths if p.name == "untouched_student_zero")
    nb = changed / "q1_proofs.ipynb"
    nb.write_text(nb.read_text().replace('"cells": [', '"cells": [\n', 1))
    third = grade_batch(paths, batch["out"], jobs=1, config=config, progress=False, pictures=False, limits=LIMITS)
    assert {r.name for r in third if not r.skipped} == {"untouched_student_zero", *failed}
    assert {r.name: r.score for r in third} == {n: r.score for n, r in batch["records"].items()}
    grade_batch([changed], batch["out"], jobs=1, config=config, progress=False, pictures=False, limits=LIMITS)
    with open(batch["out"] / "grades.csv", newline="") as fh:
        listed = [row[0] for row in csv.reader(fh)][1:]
    assert listed[0] == "untouched_student_zero" and set(listed) == set(batch["records"])


# ---------------------------------------------------------------------------------------------
# the checks, without a sandbox: chosen functions called in this process


def judge_all(hidden, student, files=(HIDDEN_DIR,)) -> list:
    """Every question's result of the hidden tests (``files``: all of them by default) run here on
    ``student`` (a grader error fails the test)."""
    result = run_here(student, hidden, tests=files)
    internal = [t.name for q in result.questions for t in q.tests if "internal error" in t.feedback]
    assert not internal, f"the grader broke on {internal}"
    return list(result.questions)


def _reference_functions() -> dict:
    import solutions

    return {name: getattr(solutions, name) for name in solutions.__all__}


def _scores(hidden, functions) -> dict:
    return {q.id: q.score for q in judge_all(hidden, LocalStudent(functions))}


def _question(hidden, functions, qid):
    """Question ``qid`` graded by its hidden test file alone (the others would cost their time for nothing)."""
    return next(q for q in judge_all(hidden, LocalStudent(functions), files_grading(qid)) if q.id == qid)


class _Always(LocalStudent):
    """Every call of every homework function ends with ``outcome``."""

    def __init__(self, outcome):
        super().__init__({f: None for q in QUESTIONS for f in q.functions})
        self.always = outcome

    def map(self, function, inputs, **kw):
        return [self.always] * len(inputs)


def test_reference_solutions_get_full_marks(hidden):
    scores = _scores(hidden, _reference_functions())
    assert scores == {qid: question(qid).points for qid in QIDS}


def test_a_missing_result_is_a_failure_never_a_pass(hidden):
    for student in (LocalStudent({}), _Always(CallOutcome("timeout", message="took more than 1 s")),
                    _Always(CallOutcome("crashed", message="the process running the code ended without a result"))):
        results = judge_all(hidden, student)
        assert [q.id for q in results] == QIDS
        assert all(q.score == 0 for q in results)
        assert all(t.feedback for q in results for t in q.tests)


WEIRD_VALUES = [
    None, "text", 3, -1.5, float("nan"), True, [], [1, 2], [[1, 2], [3]], {"a": 1}, (1, 2, 3),
    np.zeros((0,)), np.full((3, 3), np.nan), np.ones((3, 3), dtype=np.int8), np.ones((2, 2)) + 1j,
    np.ones((5, 4, 3)), (np.eye(3), "x"), (np.ones((3, 4)), np.ones((3, 4)), np.ones((7, 3))),
    np.full((3, 4), np.inf), (np.full((110, 3), 1e308), "err"),
]


@pytest.mark.parametrize("value", WEIRD_VALUES, ids=[f"{k}-{type(v).__name__}" for k, v in enumerate(WEIRD_VALUES)])
def test_malformed_values_score_zero_without_grader_errors(hidden, value):
    names = [f for q in QUESTIONS for f in q.functions]
    results = judge_all(hidden, LocalStudent({f: (lambda *a, **k: value) for f in names}))
    assert all(q.score == 0 for q in results), {q.id: q.score for q in results}


def test_hard_coded_answers_from_one_scene_fail_the_others(hidden):
    import solutions

    first = hidden.scenes.hidden[0]
    F_first = solutions.eightpoint(first.pts1, first.pts2, first.M)
    fake = dict(_reference_functions(), eightpoint=lambda pts1, pts2, M, refine=True: F_first)
    q2 = _question(hidden, fake, "Q2")
    fits = q2.tests[0]
    assert 0 < fits.score < fits.max_score


def test_valid_variants_of_eightpoint_pass_and_transposed_is_named(hidden):
    import solutions

    functions = _reference_functions()
    no_refine = dict(functions, eightpoint=lambda p1, p2, M: solutions.eightpoint(p1, p2, M, refine=False))
    assert _question(hidden, no_refine, "Q2").score == 10
    transposed = dict(functions, eightpoint=lambda p1, p2, M: solutions.eightpoint(p1, p2, M, refine=False).T)
    q2 = _question(hidden, transposed, "Q2")
    assert q2.score < 10 and "F transposed" in q2.tests[0].feedback


def test_triangulation_with_optimal_refinement_is_not_penalised(hidden):
    import scipy.optimize

    import solutions

    def refined(C1, pts1, C2, pts2):
        w, _ = solutions.triangulate(C1, pts1, C2, pts2)
        out = []
        for X, a, b in zip(w, np.asarray(pts1, float), np.asarray(pts2, float)):
            def res(Y, a=a, b=b):
                h1, h2 = C1 @ np.append(Y, 1), C2 @ np.append(Y, 1)
                return np.concatenate([a - h1[:2] / h1[2], b - h2[:2] / h2[2]])
            out.append(scipy.optimize.least_squares(res, X).x)
        w = np.array(out)
        h1 = w @ C1[:, :3].T + C1[:, 3]
        h2 = w @ C2[:, :3].T + C2[:, 3]
        err = np.sum((pts1 - h1[:, :2] / h1[:, 2:]) ** 2) + np.sum((pts2 - h2[:, :2] / h2[:, 2:]) ** 2)
        return w, float(err)

    assert _question(hidden, dict(_reference_functions(), triangulate=refined), "Q3.2").score == 10


def test_bundle_adjustment_that_collapses_the_scale_scores_nothing(hidden):
    def collapse(K1, M1, p1, K2, M2_init, p2, w_init):
        M2 = M2_init.copy()
        M2[:, 3] *= 1e-3
        return M2, w_init * 1e-3, 1.0, 0.5

    # A uniform scaling of the start is a similarity the handout allows: the fault is that the error
    # did not go down.
    q5 = _question(hidden, dict(_reference_functions(), bundleAdjustment=collapse), "Q5")
    ba = [t for t in q5.tests if t.name.startswith("bundle adjustment")]
    assert ba and all(t.score == 0 for t in ba)
    assert all("BA error not decreasing" in t.feedback for t in ba), [t.feedback for t in ba]


def test_error_messages_cannot_carry_hidden_inputs_out(hidden):
    def leaky(pts1, pts2, M, refine=True):
        raise ValueError("inputs: " + " ".join(f"{v:.9f}" for v in np.ravel(pts1)[:40]))

    q2 = _question(hidden, dict(_reference_functions(), eightpoint=leaky), "Q2")
    text = " ".join(t.feedback for t in q2.tests)
    assert "ValueError" in text and not re.search(r"\d\.\d{5,}", text)


_DUMPING = """
import base64
import numpy as np


def {function}(*args, **kwargs):
    data = b"".join(np.ascontiguousarray(np.asarray(a, dtype=float)).tobytes() for a in args
                    if np.asarray(a).dtype.kind in "fiu")
    raise RuntimeError("dump " + base64.b32encode(data[:3000]).decode() + "\\nsecond line " + "7" * 40)
"""


def test_an_exception_carrying_the_inputs_is_quoted_as_type_place_and_a_short_line(tmp_path, config):
    # Student code sees the hidden inputs: whatever it puts in an exception's message must not
    # reach results.json beyond the exception's type, its place and a few words.
    import base64

    folder = corpus.build("key_full_marks", tmp_path / "subs")
    nbs = {stem: nbformat.read(folder / f"{stem}.ipynb", as_version=4) for stem in NOTEBOOKS}
    for function in ("eightpoint", "essentialMatrix", "triangulate"):
        corpus.replace_function(nbs, function, _DUMPING.format(function=function))
    for stem, nb in nbs.items():
        nbformat.write(nb, folder / f"{stem}.ipynb")
    record, = grade_batch([folder], tmp_path / "out", config=config, progress=False, pictures=False, canary=False,
                          limits=LIMITS)
    text = (record.folder / "results.json").read_text() + (record.folder / "feedback.md").read_text()
    assert record.scores["Q2"] == record.scores["Q3.1"] == record.scores["Q3.2"] == 0
    assert "RuntimeError" in text and "dump" in text
    assert not re.search(r"[A-Z2-7]{33,}", text), "a base32 dump of the inputs reached the results"
    assert "second line" not in text and "7" * 20 not in text
    # The points this submission was given: its own draw (from its code), the first hidden scene.
    from autograder.inputs.build import code_salt
    from autograder.submission.read import load_submission

    hidden = build_hidden_inputs(config, salt=code_salt(load_submission(folder)))
    pts = np.asarray(hidden.prepared["fundamental"].cases[0].pts1, dtype=float)
    assert base64.b32encode(pts.tobytes())[:16].decode() not in text


# ---------------------------------------------------------------------------------------------
# pieces of the orchestration


def test_job_loads_definitions_not_the_notebooks_self_checks(tmp_path):
    sub = load_submission(corpus.build("key_full_marks", tmp_path))
    sources = [u.source for u in sub.units()]
    statements = [s for s in sources if not s.startswith(("def ", "class ", "@", "import ", "from "))]
    assert statements, "the key keeps some constants"
    assert not any(re.search(r"check_\w+\(\w+\)|try_run\(|from_notebook\(", s) for s in statements)
    assert any(s.startswith("def eightpoint(") or "\ndef eightpoint(" in s for s in sources)


def test_own_notebook_definition_wins_over_a_copy_elsewhere(tmp_path):
    folder = corpus.build("key_full_marks", tmp_path)
    import nbformat

    q5 = nbformat.read(folder / "q5_bundle_adjustment.ipynb", as_version=4)
    q5.cells.append(nbformat.v4.new_code_cell("def triangulate(C1, pts1, C2, pts2):\n    return None\n"))
    nbformat.write(q5, folder / "q5_bundle_adjustment.ipynb")
    units = load_submission(folder).units()
    last = [u for u in units if "triangulate" in u.defines][-1]
    assert last.origin.startswith("q3_metric_reconstruction")


def test_submission_digest_follows_content(tmp_path):
    a = corpus.build("key_full_marks", tmp_path / "a")
    b = corpus.build("key_full_marks", tmp_path / "b")
    assert submission_digest(a) == submission_digest(b)
    (b / "q2_eightpoint.ipynb").write_text((b / "q2_eightpoint.ipynb").read_text() + " ")
    assert submission_digest(a) != submission_digest(b)


def test_a_grader_bug_gives_a_failed_result_and_the_batch_goes_on(tmp_path, monkeypatch, config):
    from autograder.grading.run import GradingRun

    subs = [corpus.build(n, tmp_path / "subs") for n in ("untouched_student_zero", "invalid_json_q2_loses_Q2")]

    def broken(run, path, **kw):
        raise RuntimeError("a bug in the grader")

    monkeypatch.setattr(GradingRun, "grade", broken)
    records = grade_batch(subs, tmp_path / "out", config=config, progress=False, pictures=False, canary=False,
                          limits=LIMITS)
    assert [r.failure is not None for r in records] == [True, True]
    for r in records:
        assert "internal error" in (r.folder / "feedback.md").read_text()
        assert "a bug in the grader" in (r.folder / "grading.json").read_text()  # staff only
        assert "a bug in the grader" not in (r.folder / "results.json").read_text()


def test_key_command_writes_the_answer_key_submission(tmp_path):
    from autograder.__main__ import main

    assert main(["key", "--out", str(tmp_path)]) == 0
    archive = tmp_path / "hw4_key.zip"
    with zipfile.ZipFile(archive) as zf:
        names = sorted(zf.namelist())
    assert names == sorted(f"{stem}.ipynb" for stem in NOTEBOOKS)
    assert load_submission(archive).missing_notebooks == ()
    assert write_key_submission(tmp_path / "again", zip_it=False).is_dir()


def test_grade_command_grades_into_the_output_folder(tmp_path, config):
    from autograder.__main__ import main

    cfg = tmp_path / "grader.json"
    cfg.write_text(json.dumps({
        "temples": [{"width": t.width, "height": t.height, "noise_px": t.noise_px} for t in config.temples],
        "match_points": config.match_points, "ba_points": config.ba_points, "car_times": config.car_times,
        "time_scale": config.time_scale, "load_timeout": config.load_timeout}))
    assert load_config(cfg) == config
    broken = tmp_path / "broken.zip"
    broken.write_bytes(b"PK\x03\x04 not really")
    assert main(["grade", str(broken), "--out", str(tmp_path / "out"), "--config", str(cfg), "--quiet"]) == 0
    assert json.loads((tmp_path / "out" / "broken" / "results.json").read_text())["score"] == 0
    assert (tmp_path / "out" / "grades.csv").read_text().startswith("student_id,total,Q2")
    assert main(["grade", str(tmp_path / "nothing-here.zip"), "--out", str(tmp_path / "o2")]) == 2


def test_the_commands_are_the_explicit_table():
    import argparse
    import importlib

    from autograder import __main__ as entry

    parser = entry.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    # Every command of the table is listed; a ``register`` module may add companions of its own
    # (nbgrader adds nbgrader-grade), nothing else adds commands.
    assert set(entry.COMMANDS) <= set(sub.choices)
    registering = [n for n, c in entry.COMMANDS.items() if c.register]
    assert all(n in entry.COMMANDS or n.startswith(tuple(registering)) for n in sub.choices), list(sub.choices)
    for name, command in entry.COMMANDS.items():
        module = importlib.import_module("autograder.__main__" if command.module == "__main__" else command.module)
        assert callable(getattr(module, command.register or command.function)), name


# ---------------------------------------------------------------------------------------------
# configuration


def test_config_from_file_and_environment(tmp_path):
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"secret": "s3cret", "ba_points": 16, "temples": [
        {"width": 320, "height": 240, "noise_px": 0.5}, {"width": 400, "height": 300, "noise_px": 1.0}]}))
    cfg = load_config(environ={"HW4_GRADER_CONFIG": str(path)})
    assert cfg.secret == "s3cret" and cfg.ba_points == 16 and cfg.temples[1] == TempleSpec(400, 300, 1.0)
    assert cfg.source == path.resolve() and not cfg.is_dev
    assert load_config(path, environ={"HW4_GRADER_SECRET": "other"}).secret == "other"
    assert load_config(environ={}).secret == DEV_SECRET and load_config(environ={}).is_dev


def test_seeds_come_from_the_secret():
    a, b = GradingConfig(secret="one"), GradingConfig(secret="two")
    assert a.seed("temple-1") != b.seed("temple-1")
    assert a.seed("temple-1") == GradingConfig(secret="one").seed("temple-1")
    assert a.seed("temple-1") != a.seed("temple-2")
    assert a.fingerprint() != b.fingerprint()


@pytest.mark.parametrize("content, match", [
    ({"secrets": "x"}, "secrets"),
    ({"ba_points": 2}, "ba_points"),
    ({"temples": [{"width": 320}]}, "temples"),
    ({"time_scale": -1}, "time_scale"),
])
def test_bad_config_is_refused_with_the_key_named(tmp_path, content, match):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(content))
    with pytest.raises(ValueError, match=match):
        load_config(path, environ={})
