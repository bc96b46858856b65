"""Same verdicts everywhere: five corpus submissions graded by the CLI (``python -m autograder
grade``), by Gradescope's ``run_autograder`` in a folder laid out like /autograder, and by the
nbgrader course (``nbgrader autograde`` then ``python -m autograder nbgrader-grade``) get
identical per-question scores, each on its own hidden draw, the same draw in every channel.  All
three grade through one ``autograder.grading.run.GradingRun``: each result is stamped by it with the same
configuration key.  ``nbgrader autograde`` runs with nbgrader's Execute step off (see
``nbgrader_scores``).  Slow: about two minutes on two cores (the channels run two at a time).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from autograder.channels.gradescope import bundle as gradescope
from autograder.channels.nbgrader import course as nc
from autograder.inputs.config import quick_config
from autograder.feedback.results import autograded_question_ids
import corpus
from gradescope_like import unpack
from gradescope_like import run_autograder
from core.paths import KIT_ROOT

SECRET = "channels-test-secret-6071"
FIVE = ("key_full_marks", "untouched_student_zero", "transposed_F_loses_Q2",
        "x_and_y_swapped_matches_lose_Q4_1_and_Q4_2", "hartley_normalisation_full_marks")
QIDS = autograded_question_ids()

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not __import__("importlib").util.find_spec("nbgrader"), reason="nbgrader is not installed")]


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("channels")
    quick = quick_config(time_scale=1.0)
    settings = {"secret": SECRET, "temples": [dataclasses.asdict(t) for t in quick.temples],
                "match_points": quick.match_points, "ba_points": quick.ba_points, "car_times": quick.car_times}
    config = root / "grader.json"
    config.write_text(json.dumps(settings))
    subs = {name: corpus.build(name, root / "subs") for name in FIVE}
    env = {**os.environ, "HW4_GRADER_CONFIG": str(config)}
    env.pop("HW4_GRADER_SECRET", None)
    return {"root": root, "config": config, "subs": subs, "env": env}


def cli_scores(setup) -> dict:
    out = setup["root"] / "cli"
    proc = subprocess.run([sys.executable, "-m", "autograder", "grade", *map(str, setup["subs"].values()),
                           "--out", str(out), "--quiet", "--no-pictures", "--config", str(setup["config"])],
                          cwd=KIT_ROOT, env=setup["env"], capture_output=True, text=True, timeout=1800, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    with open(out / "grades.csv", newline="") as fh:
        rows = {r["student_id"]: r for r in csv.DictReader(fh)}
    draws = {name: _stamp(json.loads((out / name / "results.json").read_text())) for name in FIVE}
    return {name: {q: float(rows[name][q]) for q in QIDS} for name in FIVE}, draws


def _stamp(results_json: dict) -> tuple:
    """``(draw, key)``: the digest of the hidden draw a results.json says the submission was graded
    on, and the key of the configuration the grading run stamped on it."""
    config = (results_json.get("extra_data") or {}).get("configuration") or {}
    return config.get("draw"), config.get("key")


def gradescope_one(setup, bundle: Path, name: str) -> tuple[dict, str | None]:
    """One submission through run_autograder in its own Gradescope-like folder."""
    ag = unpack(bundle, setup["root"] / "gradescope" / name)
    for p in sorted(setup["subs"][name].glob("*.ipynb")):
        shutil.copy2(p, ag / "submission" / p.name)
    data = run_autograder(ag)
    scored = {t["name"].split()[0]: float(t["score"]) for t in data["tests"] if "score" in t}
    return {q: scored.get(q, 0.0) for q in QIDS}, _stamp(data)


def nbgrader_scores(setup) -> dict:
    from autograder.inputs.config import load_config

    course = nc.build_course(setup["root"] / "course")
    nc.run_nbgrader(course, "generate_assignment", "hw4", "--force")
    for name, folder in setup["subs"].items():
        target = nc.submit_release(course, name)  # the folder and its timestamp
        for p in target.glob("*.ipynb"):
            p.unlink()
        for p in sorted(folder.glob("*.ipynb")):
            shutil.copy2(p, target / p.name)
    # Without nbgrader's own run of the notebooks in its kernel (about 20 CPU s a student): no
    # point of the kit's comes from it (nbgrader-grade writes every hidden-check cell's), and
    # tests/autograder_tests/channels/test_nbgrader_course.py runs it, a tampering student included.
    nc.run_nbgrader(course, "autograde", "hw4", "--force", "--Execute.enabled=False", timeout=3600)
    results = nc.grade_course(course, config=load_config(), pictures=False)
    draws = {name: ((results[name].configuration or {}).get("draw"), (results[name].configuration or {}).get("key"))
             for name in FIVE}
    return {name: {q: nc.kit_scores(course, name).get(q, 0.0) for q in QIDS} for name in FIVE}, draws


def test_cli_gradescope_and_nbgrader_give_the_same_scores(setup, monkeypatch):
    monkeypatch.setenv("HW4_GRADER_CONFIG", str(setup["config"]))
    monkeypatch.delenv("HW4_GRADER_SECRET", raising=False)
    # Scores only: every channel grades without the pictures (each costs a few seconds a submission).
    bundle = gradescope.build_bundle(setup["root"] / "autograder.zip", time_limit=600, pictures=False)
    # The channels are separate processes that each use one core: two at a time (nbgrader, the
    # longest, beside the CLI and then the five run_autograder runs) halves the test's time.
    with ThreadPoolExecutor(2) as pool:
        nb_run = pool.submit(nbgrader_scores, setup)
        cli_run = pool.submit(cli_scores, setup)
        gs_runs = {name: pool.submit(gradescope_one, setup, bundle, name) for name in FIVE}
        nb, nb_draws = nb_run.result()
        cli, cli_draws = cli_run.result()
        gs = {name: run.result()[0] for name, run in gs_runs.items()}
        gs_draws = {name: run.result()[1] for name, run in gs_runs.items()}
    # Each submission is graded on its own hidden draw, the same whichever channel grades it, and
    # stamped by the channel's grading run with one configuration key (the same settings and tests).
    assert cli_draws == gs_draws == nb_draws, (cli_draws, gs_draws, nb_draws)
    assert len({draw for draw, _ in cli_draws.values()}) == len(FIVE)
    assert len({key for _, key in cli_draws.values()}) == 1 and None not in next(iter(cli_draws.values()))
    # Each channel publishes at its own precision (grades.csv 4 decimals, results.json 6, the
    # gradebook a float): the scores must be the same at the coarsest of them.
    def published(scores):
        return {q: round(v, 4) for q, v in scores.items()}

    for name in FIVE:
        assert published(cli[name]) == published(gs[name]) == published(nb[name]), (name, cli[name], gs[name], nb[name])
    assert sum(cli["key_full_marks"].values()) == sum(cli["hartley_normalisation_full_marks"].values()) > 0
    assert sum(cli["untouched_student_zero"].values()) == 0
    assert cli["transposed_F_loses_Q2"]["Q2"] < cli["key_full_marks"]["Q2"]
    assert cli["x_and_y_swapped_matches_lose_Q4_1_and_Q4_2"]["Q4.1"] < cli["key_full_marks"]["Q4.1"]
