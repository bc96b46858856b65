"""The instructor's recipe of docs/hidden-checks.md: a new hidden check is a plain pytest test.

1. write it in a folder of one's own (never in the kit: it is hidden from students anyway);
2. run it on one submission with pytest (``-p autograder.hidden.plugin --submission PATH``);
3. grade the class with it (``python -m autograder grade ... --hidden-dir FOLDER``): its points
   show up in every results.json, beside the kit's own checks.  Every batch grades the answer key
   first (the canary) with the extra checks too, and grades nothing unless the key gets full marks,
   so the class's folder holds checks the key passes; a partial-credit check is tried in step 2 only.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from autograder.inputs.config import quick_config
from autograder.grading.key import write_key_submission

from core.paths import KIT_ROOT

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

NEW_CHECK = '''
import numpy as np
import pytest


@pytest.mark.points(3, question="Q2", name="eightpoint gives F of rank 2 on random points")
def test_eightpoint_rank(student, grading_config):
    rng = np.random.default_rng(grading_config.seed("my-rank-check"))
    pts1 = rng.uniform(0, 640, size=(20, 2))
    pts2 = pts1 + rng.normal(0, 5, size=(20, 2))
    F = student.call("eightpoint", pts1, pts2, 640.0, seconds=10)
    assert np.shape(F) == (3, 3), f"F should be 3 x 3, got shape {np.shape(F)}"
    assert np.linalg.matrix_rank(F, tol=1e-9 * np.abs(F).max()) == 2, "F should have rank 2"
'''

PARTIAL_CHECK = '''
import numpy as np
import pytest


@pytest.mark.points(2, question="Q2", name="eightpoint is not the identity")
def test_partial_credit(student, score):
    rng = np.random.default_rng(7)
    pts1 = rng.uniform(0, 640, size=(12, 2))
    F = student.call("eightpoint", pts1, pts1 + rng.normal(0, 5, size=(12, 2)), 640.0, seconds=10)
    assert not np.allclose(F, np.eye(3)), "F is the identity"
    score.fraction(0.5, "half of the points: any matrix came back")
'''


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("recipe")
    checks = root / "my_checks"
    checks.mkdir()
    (checks / "test_my_checks.py").write_text(NEW_CHECK)
    partial = root / "my_partial_checks"
    partial.mkdir()
    (partial / "test_my_partial_checks.py").write_text(PARTIAL_CHECK)
    config = root / "grader.json"
    config.write_text(json.dumps(quick_config().to_dict()))
    key = write_key_submission(root / "subs")
    env = {k: v for k, v in os.environ.items() if k not in ("HW4_GRADER_SECRET", "HW4_GRADER_CONFIG")}
    return {"root": root, "checks": checks, "partial": partial, "config": config, "key": key, "env": env}


def test_new_check_runs_on_one_submission_with_pytest(setup):
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "autograder.hidden.plugin",
         str(setup["checks"]), str(setup["partial"]), "--submission", str(setup["key"]), "--grading-config", str(setup["config"]),
         "--results", str(setup["root"] / "one.json")],
        cwd=KIT_ROOT, env=setup["env"], capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "2 passed" in proc.stdout and "hidden checks: points" in proc.stdout
    result = json.loads((setup["root"] / "one.json").read_text())["result"]
    q2, = result["questions"]
    assert [(t["name"], t["score"], t["max_score"]) for t in q2["tests"]] == [
        ("eightpoint gives F of rank 2 on random points", 3.0, 3.0), ("eightpoint is not the identity", 1.0, 2.0)]


def test_class_graded_with_the_new_check_through_the_cli(setup):
    out = setup["root"] / "graded"
    proc = subprocess.run(
        [sys.executable, "-m", "autograder", "grade", str(setup["key"]), "--out", str(out), "--quiet",
         "--config", str(setup["config"]), "--hidden-dir", str(setup["checks"])],
        cwd=KIT_ROOT, env=setup["env"], capture_output=True, text=True, timeout=900, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    data = json.loads((out / "hw4_key" / "results.json").read_text())
    names = {t["name"]: t for t in data["tests"]}
    new = names["Q2 eightpoint gives F of rank 2 on random points"]
    assert (new["score"], new["max_score"]) == (3.0, 3.0)
    assert "Q2 eightpoint is not the identity" not in names
    # The kit's own checks ran too: full marks on every question, plus the new points.
    assert data["score"] == pytest.approx(90 + 3)
    # The new points are the instructor's decision, and it is said where they look: Q2 is now 13.
    assert "points differ from the handout's" in proc.stderr
    summary = (out / "summary.md").read_text()
    assert "**Points differ from the handout's:**" in summary
    assert "- Q2: its checks add up to 13 points; the handout gives it 10" in summary
    assert "- the autograded base total (extra credit aside) is 78 points; the handout's is 75" in summary
