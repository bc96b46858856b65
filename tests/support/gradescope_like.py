"""A Gradescope-like folder for the tests and the benchmarks: the bundle laid out as the platform does."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

from autograder.channels.gradescope import bundle as gradescope
from autograder.inputs.config import load_config, quick_config
from core.paths import KIT_ROOT

__all__ = ["KEY", "SECRET", "SEED_LABELS", "assert_valid_results", "build_test_bundle", "put", "run_autograder",
           "unpack"]


def unpack(bundle: Path, root: Path) -> Path:
    """Lay ``bundle`` out as Gradescope does: <root>/autograder/{source,submission,results}."""
    ag = root / "autograder"
    source = ag / "source"
    source.mkdir(parents=True)
    with zipfile.ZipFile(bundle) as zf:
        for info in zf.infolist():
            path = Path(zf.extract(info, source))
            mode = (info.external_attr >> 16) & 0o777
            if mode:
                path.chmod(mode)
    (ag / "submission").mkdir()
    (ag / "results").mkdir()
    # Gradescope copies run_autograder next to source/ and runs that copy.
    shutil.copy2(source / "run_autograder", ag / "run_autograder")
    return ag


KEY = KIT_ROOT / "notebooks" / "key"


# The grading secret every hidden seed derives from; distinctive, so finding it cannot be chance.
SECRET = "gradescope-test-secret-918273645"


SEED_LABELS = ("temple-1", "temple-2", "car", "bundle", "matching", "essential", "multiview")


def build_test_bundle(folder: Path, **options) -> Path:
    """A bundle built with the kit's quick scenes (fast tests) and our secret, as an instructor's settings."""
    quick = quick_config(time_scale=1.0)
    settings = {"secret": SECRET, "temples": [dataclasses.asdict(t) for t in quick.temples],
                "match_points": quick.match_points, "ba_points": quick.ba_points, "car_times": quick.car_times}
    (folder / "grader.json").write_text(json.dumps(settings))
    env = {"HW4_GRADER_CONFIG": str(folder / "grader.json"), "HW4_GRADER_SECRET": None}
    old = {k: os.environ.get(k) for k in env}
    try:
        for k, v in env.items():
            os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)
        return gradescope.build_bundle(folder / "autograder.zip", time_limit=300, **options)
    finally:
        for k, v in old.items():
            os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)


def run_autograder(ag: Path, **env) -> dict:
    full = {**os.environ, "HW4_AUTOGRADER_ROOT": str(ag), "HW4_PYTHON": sys.executable, **env}
    proc = subprocess.run(["bash", str(ag / "run_autograder")], env=full, capture_output=True, text=True,
                          timeout=900, check=False)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    text = (ag / "results" / "results.json").read_text()
    return json.loads(text)


def assert_valid_results(data: dict) -> None:
    """Gradescope's schema, as far as the kit relies on it."""
    assert isinstance(data["score"], (int, float)) and math.isfinite(data["score"])
    assert data.get("visibility", "visible") in ("visible", "hidden", "after_due_date", "after_published")
    assert isinstance(data["output"], str) and data["output"]
    assert isinstance(data["tests"], list)
    for t in data["tests"]:
        assert isinstance(t["name"], str) and t["name"]
        if "score" in t:  # the per-question tests carry the points, the per-check ones none
            assert 0 <= t["score"] <= t["max_score"] + 1e-9
        assert t["status"] in ("passed", "failed")
        assert t.get("visibility", "visible") in ("visible", "hidden", "after_due_date", "after_published")
    text = json.dumps(data)
    assert "Traceback (most recent call last)" not in text
    config = load_config(environ={"HW4_GRADER_SECRET": SECRET})
    for secret in [SECRET] + [str(config.seed(label)) for label in SEED_LABELS]:
        assert secret not in text


def put(ag: Path, *files: Path) -> None:
    for f in files:
        shutil.copy2(f, ag / "submission" / f.name)
