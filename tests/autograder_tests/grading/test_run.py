"""One grading run, set up once, grades several submissions: each result finished and stamped by
the run (configuration, sandbox level, the submission's own draw), the canary graded once, on the
secret's own scenes.  The
run's picture step: its record comes back on the result when asked for, never for the canary."""

from __future__ import annotations

import dataclasses
import os

import pytest

from autograder.grading import run as run_module
from autograder.inputs.config import configuration, quick_config
from autograder.inputs.config import tests_fingerprint as checks_fingerprint  # not a test of its own
from autograder.inputs import build as inputs
from autograder.feedback.pictures import figures_of
from autograder.feedback.results import SubmissionResult
from autograder.grading.run import GradingRun
from autograder.sandbox import ResourceLimits
from starter.checks.pictures import QUESTIONS
import corpus

pytestmark = pytest.mark.slow

LIMITS = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)
FULL = 90.0


def test_one_run_grades_two_submissions_with_one_set_up(tmp_path, monkeypatch):
    made = []
    real_build = run_module.build_hidden_inputs
    monkeypatch.setattr(run_module, "build_hidden_inputs",
                        lambda config, **kw: made.append(config) or real_build(config, **kw))
    sessions = []  # (student id option, pictures asked for) of each pytest session
    real_session = run_module.run_session

    caches = []  # (options naming a configuration, json files, the saved run) of each session's cache

    def session(pool, submission, **kw):
        sessions.append((next(o for o in kw["options"] if o.startswith("--student-id=")), kw.get("pictures"),
                         "--secret-scenes" in kw["options"]))
        folder = kw["folder"]
        caches.append(({"--grading-config", "--stamp"} & set(kw["options"]),
                       sorted(p.name for p in folder.glob("*.json") if not p.name.startswith("sandbox-")),
                       inputs.load_saved(folder)))
        assert kw["options"][kw["options"].index("--hidden-cache") + 1] == str(folder)
        return real_session(pool, submission, **kw)

    monkeypatch.setattr(run_module, "run_session", session)
    key = corpus.build("key_full_marks", tmp_path / "subs")
    transposed = corpus.build("transposed_F_loses_Q2", tmp_path / "subs")
    with GradingRun(quick_config(), hide=[tmp_path], limits=LIMITS, pictures=True) as run:
        run.open()
        first = run.grade(key, student_id="alice")
        second = run.grade(transposed, student_id="bob", pictures=False)  # this call only: no pictures
        assert run.canaries == 1 and run.canary_report.score == FULL  # (base 75 + extra credit 15)
        assert len(made) == 1 and run.pool.started == 1   # inputs made once, one worker for all three
        assert len(run.sandboxes()) == 1                  # graded one after another: one sandbox
        boxes = run.sandboxes()
    assert not any(box._base.exists() for box in boxes)   # closing removed the sandbox
    assert (first.student_id, second.student_id) == ("alice", "bob")
    assert first.failure is None and first.score == FULL
    assert second.failure is None and 0 < second.score < FULL
    q2 = {r.student_id: next(q.score for q in r.questions if q.id == "Q2") for r in (first, second)}
    assert q2["bob"] < q2["alice"]
    for result in (first, second):
        stamp = result.configuration
        assert stamp["key"] == run.record["key"] and stamp["isolation"] == result.isolation["level"]
        assert stamp["draw"] and result.execution_time > 0
        # Stamped with the run's record as it is, plus the level and the draw only.
        assert stamp == {**run.record, "isolation": result.isolation["level"], "draw": stamp["draw"]}
    # The worker reads the configuration from one place: the cache, whose one file holds the
    # inputs (with their config) and the run's record; no config or stamp file beside them.
    assert len(caches) == 3
    for named, json_files, saved in caches:
        assert named == set() and json_files == []
        assert saved.record == run.record and saved.hidden.config == run.hidden.config
    assert first.configuration["draw"] != second.configuration["draw"]  # each its own hidden draw
    # The picture step: the canary's session never ran it, the run's default did, the call's False did not.
    assert [asked for _, asked, _ in sessions] == [False, True, False]
    assert sessions[1][0] == "--student-id=alice"
    # The canary grades on the secret's own scenes (the run made them), each submission on its draw.
    assert [secret for _, _, secret in sessions] == [True, False, False]
    assert second.pictures is None and isinstance(first.pictures, dict)
    assert "pictures" not in first.to_dict() and first == SubmissionResult.from_dict(first.to_dict())
    figures = figures_of(first.pictures)
    assert set(figures) == set(QUESTIONS) and all(not isinstance(f, str) for f in figures.values()), figures
    with pytest.raises(RuntimeError, match="closed"):
        run.grade(key)


def test_a_run_cache_is_one_file_with_the_inputs_config_and_record(tmp_path):
    # What a run's worker reads: one saved object, checked as the grader's own like the inputs were.
    config = quick_config()
    record = configuration(config, tests=checks_fingerprint())
    folder = tmp_path / "cache"
    inputs.save(inputs.HiddenInputs(config, None, {}), folder, record=record)
    assert [p.name for p in folder.iterdir()] == [inputs.SAVED_NAME]
    saved = inputs.load_saved(folder)
    assert saved.record == record and saved.hidden.config == config
    assert inputs.load(folder, config).config == config
    with pytest.raises(ValueError, match="another config|of config"):
        inputs.load(folder, dataclasses.replace(config, secret=config.secret + "-other"))
    with pytest.raises(ValueError, match="record"):
        inputs.save(saved.hidden, folder, record=["not", "a", "record"])
    os.chmod(folder, 0o750)
    with pytest.raises(ValueError, match="0700"):
        inputs.load_saved(folder)
