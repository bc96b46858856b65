"""Gradescope's autograder zip: what it holds, and run_autograder in a folder laid out like Gradescope's.

The zip is built once per session and unpacked into ``<tmp>/autograder/source``; each case puts a
submission in ``<tmp>/autograder/submission`` and runs the real ``run_autograder`` (bash) with
``HW4_AUTOGRADER_ROOT`` pointing at ``<tmp>/autograder``, then reads ``results/results.json``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import re
import shutil
import stat
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from autograder.channels.gradescope import bundle as gradescope
from autograder.inputs.config import load_config, quick_config
from autograder.feedback.results import autograded_question_ids
from core.manifest import NOTEBOOKS, QUESTIONS
from gradescope_like import unpack

from core.paths import KIT_ROOT, course_data_dir
from gradescope_like import KEY, SECRET, assert_valid_results, build_test_bundle, put, run_autograder

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md
STUDENT = KIT_ROOT / "notebooks"
@pytest.fixture(scope="session")
def bundle(tmp_path_factory) -> Path:
    # Text feedback only: the picture tests cost a few seconds a run, and this file's runs are
    # about grading; tests/end_to_end/test_feedback_browser.py grades with a bundle that draws them.
    return build_test_bundle(tmp_path_factory.mktemp("bundle"), pictures=False)


@pytest.fixture(scope="session")
def names(bundle) -> list[str]:
    with zipfile.ZipFile(bundle) as zf:
        return zf.namelist()


# ------------------------------------------------------------------------------------------------
# the zip


def test_bundle_holds_the_scripts_and_the_grader(bundle, names):
    assert {"setup.sh", "run_autograder", "requirements.txt", "BUNDLE.json"} <= set(names)
    with zipfile.ZipFile(bundle) as zf:
        for script in ("setup.sh", "run_autograder"):
            mode = zf.getinfo(script).external_attr >> 16
            assert mode & stat.S_IXUSR, f"{script} is not executable"
            text = zf.read(script).decode()
            assert text.startswith("#!/usr/bin/env bash") and "@TIME_LIMIT@" not in text and "@VENV@" not in text
        assert "300" in zf.read("run_autograder").decode()
        info = json.loads(zf.read("BUNDLE.json"))
    assert info["time_limit"] == 300
    for package in gradescope.PACKAGES:
        assert f"{package}/__init__.py" in names
    assert "autograder/grading/grade.py" in names and "autograder/sandbox/child.py" in names
    # The hidden checks are pytest tests: the bundle runs them with their plugin and settings.
    assert {"autograder/hidden/conftest.py", "autograder/hidden/plugin.py", "autograder/hidden/pytest.ini"} <= set(names)
    assert any(n.startswith("autograder/hidden/test_") for n in names)
    assert any(n.startswith("data/temple/") for n in names) and any(n.startswith("data/q6/") for n in names)


def test_bundle_leaks_nothing_it_does_not_need(bundle, names):
    forbidden = ("tests/", "notebooks/", "benchmarks/", ".git/", "hw4_twoview_kit.egg-info/")
    assert not [n for n in names if n.startswith(forbidden)]
    assert not [n for n in names if "__pycache__" in n or n.endswith((".pyc", ".ipynb"))]
    # Only the packages the grader needs (core.shipping), not the instructor's commands.
    assert not [n for n in names if n.startswith("kit/")]


def test_bundle_carries_the_instructors_secret_in_its_config_only(bundle, names):
    with zipfile.ZipFile(bundle) as zf:
        settings = json.loads(zf.read(gradescope.CONFIG_NAME))
        info = zf.read("BUNDLE.json").decode()
    assert settings["secret"] == SECRET and "official_data" not in settings
    assert settings["match_points"] == quick_config().match_points  # the build-time settings, not defaults
    assert SECRET not in info and json.loads(info)["development_secret"] is False


def test_build_refuses_the_development_secret(tmp_path, monkeypatch):
    monkeypatch.delenv("HW4_GRADER_SECRET", raising=False)
    monkeypatch.delenv("HW4_GRADER_CONFIG", raising=False)
    with pytest.raises(ValueError, match="development secret"):
        gradescope.build_bundle(tmp_path / "autograder.zip")
    assert not (tmp_path / "autograder.zip").exists()


def test_bundle_holds_none_of_the_official_data(bundle):
    data = course_data_dir()
    if data is None:
        pytest.skip("official course data not found (../shared/course-data or HW4_COURSE_DATA)")
    official = {hashlib.sha256(p.read_bytes()).hexdigest() for p in data.rglob("*") if p.is_file()}
    with zipfile.ZipFile(bundle) as zf:
        shipped = {hashlib.sha256(zf.read(n)).hexdigest() for n in zf.namelist() if not n.endswith("/")}
    assert not official & shipped


def test_render_asset_fills_every_field_and_checks_its_arguments():
    text = gradescope.render_asset("run_autograder", time_limit=123, venv="/opt/x-venv")
    assert "123" in text and "/opt/x-venv/bin/python" in text and not re.search(r"@[A-Z_]+@", text)
    with pytest.raises(ValueError, match="time_limit"):
        gradescope.render_asset("setup.sh", time_limit=0)
    with pytest.raises(ValueError, match="venv"):
        gradescope.render_asset("setup.sh", venv="relative/venv")
    with pytest.raises(ValueError, match="name"):
        gradescope.render_asset("grade.sh")


def test_cli_registers_build_and_run():
    from autograder.__main__ import build_parser

    build = build_parser().parse_args(["gradescope", "--out", "autograder.zip", "--time-limit", "100"])
    assert build.func is gradescope._cli and build.action is None and build.time_limit == 100
    run = build_parser().parse_args(["gradescope", "run", "--root", "/somewhere"])
    assert run.func is gradescope._cli and run.action == "run" and run.root == "/somewhere"


def test_build_refuses_a_path_that_is_not_a_zip(tmp_path):
    with pytest.raises(ValueError, match="out"):
        gradescope.build_bundle(tmp_path / "autograder.tar")


def test_setup_locks_the_grader_files(bundle, tmp_path):
    ag = unpack(bundle, tmp_path)
    env = {**os.environ, "HW4_AUTOGRADER_ROOT": str(ag), "HW4_SETUP_SKIP_INSTALL": "1"}
    proc = subprocess.run(["bash", str(ag / "source" / "setup.sh")], cwd=ag / "source", env=env,
                          capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 0, proc.stderr
    for path in [ag / "source", *(ag / "source").rglob("*")]:
        assert path.stat().st_mode & 0o077 == 0, f"{path} is readable by others"


# ------------------------------------------------------------------------------------------------
# run_autograder


@pytest.fixture
def gradescope_dir(bundle, tmp_path) -> Path:
    return unpack(bundle, tmp_path)


@pytest.mark.slow
def test_answer_key_gets_full_marks(gradescope_dir):
    key = sorted(KEY.glob("*.ipynb"))
    assert [p.stem for p in key] == sorted(NOTEBOOKS)
    put(gradescope_dir, *key)
    data = run_autograder(gradescope_dir)
    assert_valid_results(data)
    assert data["extra_data"]["failure"] is None, data["output"]
    full = sum(t.get("max_score", 0) for t in data["tests"])
    assert full == pytest.approx(sum(q.points for q in QUESTIONS if not q.by_hand))
    assert data["score"] == pytest.approx(full)
    graded = {t["name"].split()[0] for t in data["tests"]}
    assert graded == set(autograded_question_ids())
    iso = data["extra_data"]["isolation"]
    if os.geteuid() == 0:
        # Student code never runs as root: the sandbox takes a uid of its own.
        assert iso["uid"] not in (None, 0)


@pytest.mark.slow
def test_untouched_notebooks_score_zero(gradescope_dir):
    put(gradescope_dir, *sorted(STUDENT.glob("*.ipynb")))
    data = run_autograder(gradescope_dir)
    assert_valid_results(data)
    assert data["score"] == 0 and data["tests"]
    assert all(t["status"] == "failed" for t in data["tests"])


@pytest.mark.slow
def test_a_zip_of_the_key_inside_the_submission_folder_is_graded(gradescope_dir):
    with zipfile.ZipFile(gradescope_dir / "submission" / "hw4.zip", "w") as zf:
        for p in sorted(KEY.glob("q2_*.ipynb")):
            zf.write(p, f"hw4/{p.name}")
    data = run_autograder(gradescope_dir)
    assert_valid_results(data)
    q2 = [t for t in data["tests"] if t["name"].startswith("Q2 ")]
    assert q2 and all(t["status"] == "passed" for t in q2)
    assert 0 < data["score"] < sum(t.get("max_score", 0) for t in data["tests"])


@pytest.mark.parametrize("case", ["empty", "bad-zip", "unsafe-zip"])
def test_unusable_submissions_score_zero_with_a_reason(gradescope_dir, case):
    sub = gradescope_dir / "submission"
    if case == "bad-zip":
        (sub / "submission.zip").write_bytes(b"PK\x03\x04 this is not really a zip")
    elif case == "unsafe-zip":
        with zipfile.ZipFile(sub / "submission.zip", "w") as zf:
            zf.writestr("../../q2_eightpoint.ipynb", "{}")
    data = run_autograder(gradescope_dir)
    assert_valid_results(data)
    assert data["score"] == 0 and data["tests"] == []
    assert "could not grade" in data["output"] and data["extra_data"]["failure"]


def test_shell_fallback_when_python_cannot_run(gradescope_dir):
    put(gradescope_dir, *sorted(KEY.glob("*.ipynb")))
    data = run_autograder(gradescope_dir, HW4_PYTHON=str(gradescope_dir / "no-such-python"))
    assert_valid_results(data)
    assert data["score"] == 0 and "could not grade" in data["output"]
    assert "exit code 127" in data["extra_data"]["failure"]


def test_shell_fallback_when_grading_is_too_slow(gradescope_dir, tmp_path):
    # A Python that hangs when asked to grade (and only then): the time limit must stop it.
    slow = tmp_path / "slow-python"
    slow.write_text(f'#!/bin/sh\nif [ "$1" = "-m" ]; then exec sleep 60; fi\nexec {sys.executable} "$@"\n')
    slow.chmod(0o755)
    put(gradescope_dir, *sorted(KEY.glob("*.ipynb")))
    data = run_autograder(gradescope_dir, HW4_PYTHON=str(slow), HW4_GRADE_TIME_LIMIT="1")
    assert_valid_results(data)
    assert data["score"] == 0 and "longer than 1 seconds" in data["output"]


def test_broken_kit_still_gives_a_result(gradescope_dir):
    (gradescope_dir / "source" / "autograder" / "grading" / "grade.py").write_text("raise ImportError('broken on purpose')\n")
    put(gradescope_dir, *sorted(KEY.glob("*.ipynb")))
    data = run_autograder(gradescope_dir)
    assert_valid_results(data)
    assert data["score"] == 0 and "internal error" in data["output"] and "broken on purpose" not in data["output"]


# ------------------------------------------------------------------------------------------------
# the canary: the bundled answer key graded before every submission


def test_bundle_ships_the_answer_key_owner_only(bundle, names):
    assert gradescope.KEY_NAME in names
    with zipfile.ZipFile(bundle) as zf:
        assert (zf.getinfo(gradescope.KEY_NAME).external_attr >> 16) & 0o077 == 0
        with zipfile.ZipFile(zf.open(gradescope.KEY_NAME)) as key:
            assert sorted(Path(n).stem for n in key.namelist()) == sorted(NOTEBOOKS)
    assert "umask 077" in gradescope.render_asset("run_autograder")


def assert_autograder_broken(data: dict) -> str:
    """The results.json of a failed canary: a zero that blames the autograder, the reason for staff."""
    assert_valid_results(data)
    assert data["score"] == 0 and data["tests"] == []
    assert "autograder is broken" in data["output"] and "not a problem with your work" in data["output"]
    canary = data["extra_data"]["canary"]
    assert canary["passed"] is False and canary["reason"].startswith("canary:")
    assert canary["reason"] not in data["output"]  # the why is for staff (extra_data, the log)
    return canary["reason"]


def test_a_damaged_answer_key_in_the_bundle_says_the_autograder_is_broken(gradescope_dir):
    (gradescope_dir / "source" / gradescope.KEY_NAME).write_bytes(b"PK\x03\x04 truncated upload")
    put(gradescope_dir, *sorted(KEY.glob("*.ipynb")))
    reason = assert_autograder_broken(run_autograder(gradescope_dir))
    assert "not graded" in reason


def test_limits_too_tight_for_the_container_say_the_autograder_is_broken(gradescope_dir):
    # Time limits far too short for this container (a time factor of 1e-5 in the bundle): the key
    # runs out of time everywhere, so the student's submission must not be graded at all.
    info_path = gradescope_dir / "source" / "BUNDLE.json"
    info = json.loads(info_path.read_text())
    info_path.write_text(json.dumps({**info, "time_factor": 1e-5}))
    put(gradescope_dir, *sorted(KEY.glob("*.ipynb")))
    data = run_autograder(gradescope_dir)
    reason = assert_autograder_broken(data)
    assert "full marks" in reason and "out of time" in reason
    assert data["extra_data"]["timing"]["clock"] == "cpu" and data["extra_data"]["timing"]["canary_seconds"] > 0


# ------------------------------------------------------------------------------------------------
# fitting the platform: precomputed inputs, calibrated limits, visibility, extra credit apart


def test_bundle_carries_the_hidden_inputs_and_its_display_settings(bundle, names):
    assert any(n.startswith(gradescope.HIDDEN_INPUTS_DIR + "/") for n in names)
    with zipfile.ZipFile(bundle) as zf:
        info = json.loads(zf.read("BUNDLE.json"))
    assert info["visibility"] == gradescope.DEFAULT_VISIBILITY == {"scores": "visible", "checks": "after_published"}
    assert info["time_factor"] == gradescope.DEFAULT_TIME_FACTOR


def test_bundle_carries_the_secrets_own_inputs_which_the_canary_grades_on(bundle, tmp_path):
    from autograder.inputs import build as inputs
    from autograder.inputs.cases import CONCEPTS

    source = unpack(bundle, tmp_path) / "source"
    config = load_config(source / gradescope.CONFIG_NAME, environ={})
    os.chmod(source / gradescope.HIDDEN_INPUTS_DIR, 0o700)
    hidden = inputs.load(source / gradescope.HIDDEN_INPUTS_DIR, config)
    # The batch's inputs (no submission's draw), every concept's, without the scenes themselves.
    assert hidden.draw is None and hidden.scenes is None and set(hidden.prepared) == set(CONCEPTS)
    assert (source / gradescope.KEY_NAME).is_file()


def test_visibility_and_time_factor_are_checked_at_build(tmp_path):
    with pytest.raises(ValueError, match="visibility"):
        gradescope.build_bundle(tmp_path / "a.zip", visibility={"checks": "sometimes"}, allow_dev_secret=True)
    with pytest.raises(ValueError, match="visibility"):
        gradescope.build_bundle(tmp_path / "a.zip", visibility={"everything": "hidden"}, allow_dev_secret=True)
    with pytest.raises(ValueError, match="time_factor"):
        gradescope.build_bundle(tmp_path / "a.zip", time_factor=0, allow_dev_secret=True)
    args = __import__("autograder.__main__", fromlist=["build_parser"]).build_parser().parse_args(
        ["gradescope", "--out", "a.zip", "--visibility", "checks=hidden", "scores=after_due_date", "--time-factor", "0.2"])
    assert args.visibility == ["checks=hidden", "scores=after_due_date"] and args.time_factor == 0.2


def test_limits_scale_with_the_measured_slowness():
    ref = gradescope.REFERENCE_CALIBRATION
    assert gradescope.limits_scale(ref, 0.1) == pytest.approx((1.0, 0.1))
    # Half a CPU: the loop takes twice as long, and so does every limit (the same CPU seconds).
    assert gradescope.limits_scale(2 * ref, 0.1) == pytest.approx((2.0, 0.2))
    assert gradescope.limits_scale(ref / 3, 0.1) == pytest.approx((1.0, 0.1))  # never tighter than the reference
    assert gradescope.limits_scale(100 * ref, 0.1)[0] == 8.0
    with pytest.raises(ValueError, match="measured"):
        gradescope.limits_scale(0)
    assert 0 < gradescope.calibrate(rounds=1) < 60


def test_cpu_clock_settings_follow_the_measured_share_of_a_cpu():
    wall, cpu = gradescope.calibration(rounds=1)
    assert 0 < cpu <= wall * 1.05 + 0.01
    assert gradescope.clock_settings(1.0, 1.0) == pytest.approx((1.0, 2.0))   # a whole CPU: backstop at 2x
    assert gradescope.clock_settings(2.0, 1.0) == pytest.approx((0.5, 3.0))   # 0.5 vCPU: 1.5 / 0.5
    assert gradescope.clock_settings(1000.0, 1.0) == pytest.approx((0.05, 16.0))
    with pytest.raises(ValueError, match="cpu"):
        gradescope.clock_settings(1.0, 0)


def test_results_show_base_points_and_extra_credit_apart_with_per_group_visibility():
    from autograder.feedback.results import QuestionResult, SubmissionResult, TestResult
    from core.manifest import question

    q2 = QuestionResult.of("Q2", [TestResult("F fits", 6, 6), TestResult("rank 2", 0, 4, feedback="F has rank 3")])
    q6 = QuestionResult.of("Q6", [TestResult("points", question("Q6").points, question("Q6").points,
                                             feedback="", visibility="hidden")])
    result = SubmissionResult((q2, q6))
    data = result.to_gradescope(visibility={"checks": "after_published"})
    assert data["score"] == 6 + question("Q6").points
    assert "Base points: 6 / 10" in data["output"] and f"Extra credit: {question('Q6').points} / " in data["output"]
    scored = [t for t in data["tests"] if "score" in t]
    checks = [t for t in data["tests"] if "score" not in t]
    assert [(t["name"].split()[0], t["score"], t["max_score"], t["visibility"]) for t in scored] == [
        ("Q2", 6, 10, "visible"), ("Q6", question("Q6").points, question("Q6").points, "visible")]
    assert "extra credit" in scored[1]["name"]
    assert [t["visibility"] for t in checks] == ["after_published", "after_published", "hidden"]
    assert "F has rank 3" in checks[1]["output"] and "F has rank 3" not in data["output"]
    assert "when the course staff publish" in data["output"]
    everything = result.to_gradescope(visibility={"checks": "visible"})
    assert [t["visibility"] for t in everything["tests"] if "score" not in t] == ["visible", "visible", "hidden"]


@pytest.mark.slow
def test_results_json_uses_the_bundled_inputs_and_calibrated_limits(gradescope_dir):
    put(gradescope_dir, *sorted(KEY.glob("q2_*.ipynb")))
    data = run_autograder(gradescope_dir)
    assert_valid_results(data)
    timing = data["extra_data"]["timing"]
    assert timing["hidden_inputs"] == "bundled" and timing["slowness"] >= 1 and timing["time_scale"] > 0
    assert timing["clock"] == "cpu" and timing["wall_factor"] >= 2 and 0 < timing["cpu_share"] <= 1
    assert data["extra_data"]["canary"]["passed"] is True and timing["canary_seconds"] > 0
    assert {t["visibility"] for t in data["tests"] if "score" in t} == {"visible"}
    assert {t["visibility"] for t in data["tests"] if "score" not in t} <= {"after_published", "hidden"}
    assert "Base points:" in data["output"]
    # The result records how it was graded; of the submission's own hidden draw, a digest only.
    record = data["extra_data"]["configuration"]
    assert re.fullmatch(r"[0-9a-f]{12}", record["draw"]) and record["secret_fingerprint"] and record["isolation"]
    assert SECRET not in json.dumps(data)
    assert not [t["name"] for t in data["tests"] if " picture: " in t["name"]]  # built with pictures=False


@pytest.mark.slow
def test_a_bundle_of_the_development_secret_says_so_and_records_its_options(tmp_path, monkeypatch):
    # (The pictures' default, on, is graded in tests/end_to_end/test_feedback_browser.py.)
    monkeypatch.delenv("HW4_GRADER_SECRET", raising=False)
    monkeypatch.delenv("HW4_GRADER_CONFIG", raising=False)
    path = gradescope.build_bundle(tmp_path / "try.zip", allow_dev_secret=True, pictures=False, time_factor=2.0)
    with zipfile.ZipFile(path) as zf:
        info = json.loads(zf.read("BUNDLE.json"))
    assert info["development_secret"] is True and info["pictures"] is False and info["time_factor"] == 2.0


@pytest.mark.slow
def test_every_function_hanging_still_gets_feedback_per_test(gradescope_dir, tmp_path):
    from corpus.hangs import build_all_hang

    put(gradescope_dir, *sorted(build_all_hang(tmp_path / "hang").glob("*.ipynb")))
    data = run_autograder(gradescope_dir)
    assert_valid_results(data)
    assert data["extra_data"]["failure"] is None and data["score"] == 0
    checks = [t for t in data["tests"] if "score" not in t]
    assert checks and all(t["status"] == "failed" for t in checks)
    assert all("took more than" in t["output"] or "not run" in t["output"] or "did not finish" in t["output"]
               or "time" in t["output"] for t in checks), [t["output"] for t in checks]


@pytest.mark.slow
def test_a_time_limit_below_the_session_budget_ends_the_session_before_it(gradescope_dir, tmp_path):
    # run_autograder passes its limit on; the grader's session must end before the shell's kill, so
    # the checks that ran are reported by the grader (not the shell's fallback zero).  The limit
    # leaves room for a setup slowed by a loaded machine (the canary alone took 15 s on two busy
    # cores) and the budget's minimum (autograder.grading.budget.too_late), and is far below the session's
    # budget without it.
    from corpus.hangs import build_all_hang

    limit = 90
    put(gradescope_dir, *sorted(build_all_hang(tmp_path / "hang").glob("*.ipynb")))
    data = run_autograder(gradescope_dir, HW4_GRADE_TIME_LIMIT=str(limit))
    assert_valid_results(data)
    assert data["extra_data"]["failure"] is None, data["output"]
    timing = data["extra_data"]["timing"]
    assert timing["session_budget"] < limit
    assert data["execution_time"] < limit
    checks = [t for t in data["tests"] if "score" not in t]
    assert checks and all(t["status"] == "failed" for t in checks)
