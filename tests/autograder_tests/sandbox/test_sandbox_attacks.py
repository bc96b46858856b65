"""A class with students who attack the sandbox itself, graded through the CLI in both shapes the
kit runs in: as root with namespaces, and at the ``uid`` level in a container like Gradescope's
(Docker's default capabilities through ``setpriv``, a public Python's venv; ../shared/FIELD-NOTES.md).

Two attackers (tests/support/corpus/hostile.py), each graded right before an answer key:

- ``a_stashes_truth_and_throws_switch``: both in-child attacks on Q2 in one submission.  Its
  essentialMatrix and matcher keep every F the other questions' checks hand them (memory, home,
  /dev/shm); its eightpoint returns a kept F when it finds one, else it is the polished transposed
  eightpoint that first turns refineF's switch back on from inside the child.  When every
  ``STASHED`` line reads 0 (no kept F ever found, on the checks or the pictures), every call
  took the fallback, which is exactly the switch attack; Q2 then at or below half (as the
  mistake without the trick, tests/judging_tests/test_fundamental_goals.py) says the switch did not work
  either.  Alone, before their defences, the two scored 9.25 and 7 of 10; this one scores 9 of
  10 when the grader polishes its switched-off run, as a thrown switch would have it;
- ``c_kernel_and_outliving``: a note in the uid's keyring, gigabytes of memfd files, a user
  namespace; then a zombie-led process in a session of its own that kills the next processes of
  its uid, and 3,000-level folder trees in its home, /dev/shm and /run/lock.

``b_then_key`` is the plain answer key; ``d_then_key`` is the key whose essentialMatrix also
tries the kernel channels (looking for the note of ``c`` itself), with the key's answers.

Every case is contained: each key keeps full marks, the Q2 attacker stays at or below half of
Q2, the kernel refuses the channels, nothing of the sandbox's uids is left in the shared
temporary folders, and the class ends with grades.csv.  Four submissions, as many as when only
one attacker was followed by a key.
"""

from __future__ import annotations

import csv
import json
import os
import platform
import shutil
import subprocess
import sys
from pathlib import Path

import corpus
import nbformat
import pytest
from corpus import hostile, variants

from autograder.inputs.config import quick_config
from core.paths import KIT_ROOT
from containers import in_container
from graded_keys import full_marks, key_with, owned_by

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(os.geteuid() != 0 or shutil.which("setpriv") is None or shutil.which("unshare") is None,
                       reason="the levels tested need root, util-linux setpriv and unshare"),
    pytest.mark.skipif(platform.machine() != "x86_64", reason="the attacks call x86_64 syscall numbers"),
]

# Each attacker and the key graded right after it (one at a time, in the order given).
KEYS_AFTER = {"a_stashes_truth_and_throws_switch": "b_then_key", "c_kernel_and_outliving": "d_then_key"}
# The kernel channels first (their essentialMatrix prints what the kernel said), then the hunter
# and the deep trees.
_BOTH = """

_kernel_essential = essentialMatrix


def essentialMatrix(F, K1, K2):
    _kernel_essential(F, K1, K2)
    return _outlive_then_essential(F, K1, K2)
"""


def _class(root: Path) -> list[Path]:
    """The class, in the order it is graded (names sort as given; one at a time at the uid level)."""
    transposed = variants.EIGHTPOINT_TRANSPOSED_REFINED
    subs = root / "subs"
    made = [
        _key_with_cells(subs / "a_stashes_truth_and_throws_switch",
                        hostile.stashes_truth_and_throws_switch(transposed)),
        _key_with_cells(subs / "b_then_key", {}),
        key_with(subs / "c_kernel_and_outliving", "q3_metric_reconstruction",
                 hostile.KERNEL_CHANNELS + hostile.OUTLIVES_ITS_SANDBOX.replace(
                     "def essentialMatrix(", "def _outlive_then_essential(") + _BOTH),
        key_with(subs / "d_then_key", "q3_metric_reconstruction", hostile.KERNEL_CHANNELS.replace(
            "hw4-big", "hw4-big-again")),
    ]
    return made


def _key_with_cells(folder: Path, cells: dict[str, str]) -> Path:
    """The answer key with each cell of ``cells`` appended to the notebook of its stem."""
    nbs = corpus.notebooks("key")
    for stem, cell in cells.items():
        corpus.append_cell(nbs, stem, cell)
    folder.mkdir(parents=True)
    for name, nb in nbs.items():
        nbformat.write(nb, folder / f"{name}.ipynb")
    return folder


def _grade(level: str, tmp_path: Path, python: list[str], pictures: bool = True) -> dict:
    os.chmod(tmp_path, 0o755)
    config = tmp_path / "grader.json"
    config.write_text(json.dumps(quick_config().to_dict()))
    subs = _class(tmp_path)
    out = tmp_path / "out"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST", "HW4_"))}
    env["PYTHONPATH"] = str(KIT_ROOT)
    proc = subprocess.run([*python, "-m", "autograder", "grade", *map(str, subs), "--out", str(out), "--config",
                           str(config), "--jobs", "1", "--isolation", level, "--quiet",
                           *([] if pictures else ["--no-pictures"])],
                          cwd=KIT_ROOT, env=env, capture_output=True, text=True, timeout=1500, check=False)
    states = {p.name: json.loads((out / p.name / "grading.json").read_text())
              for p in subs if (out / p.name / "grading.json").is_file()}
    return {"proc": proc, "out": out, "states": states, "names": [p.name for p in subs]}


def _printed(state: dict, tag: str) -> list[str]:
    return [line.split(" ", 1)[1] for line in state["staff"]["stdout"].splitlines() if line.startswith(tag + " ")]


def _contained(graded: dict, level: str) -> None:
    proc, states = graded["proc"], graded["states"]
    assert proc.returncode == 0, proc.stderr[-3000:]
    # The class ends with its grades, every submission in them.
    with open(graded["out"] / "grades.csv", newline="", encoding="utf-8") as fh:
        assert len(list(csv.DictReader(fh))) == len(graded["names"])
    assert set(states) == set(graded["names"])
    assert {s["isolation"]["level"] for s in states.values()} == {level}

    # Each attacker is graded right before a key, and each key keeps full marks.
    names = graded["names"]
    assert set(names) == set(KEYS_AFTER) | set(KEYS_AFTER.values()), names
    for attacker, key in KEYS_AFTER.items():
        assert names.index(key) == names.index(attacker) + 1, names
        assert full_marks(states[key]["scores"]) == [], (attacker, key, states[key]["scores"])

    # Both attacks were made: F's were kept, and the switch was thrown.
    q2 = states["a_stashes_truth_and_throws_switch"]
    assert any(int(n) >= 1 for n in _printed(q2, "KEPT")), q2["staff"]["stdout"][-2000:]
    assert _printed(q2, "SWITCH-THROWN"), q2["staff"]["stdout"][-2000:]
    # Nothing crossed between checks or to the pictures (when drawn): no kept F was ever found, so
    # every call of eightpoint was the switch attack ...
    found = _printed(q2, "STASHED")
    assert found and set(found) == {"0"}, found
    # ... which earns nothing: at or below half of Q2, as the same mistake without it
    # (tests/judging_tests/test_fundamental_goals.py holds the mistake itself at or below half).
    assert q2["scores"]["Q2"] <= 5, q2["scores"]["Q2"]

    # The kernel refused the channels (EACCES from the syscall filter), in both submissions.
    for name in ("c_kernel_and_outliving", "d_then_key"):
        for tag in ("KEYRING-READ", "KEYRING-WRITE", "MEMFD", "USERNS"):
            assert _printed(states[name], tag) and set(_printed(states[name], tag)) == {"13"}, (name, tag)

    # The trees were made, and are gone with everything else of the sandbox's uids.
    assert "3000" in " ".join(_printed(states["c_kernel_and_outliving"], "DEEP"))
    uids = {s["isolation"]["uid"] for s in states.values()}
    assert not {0, os.getuid()} & uids
    assert owned_by(uids) == []


def test_attacks_are_contained_at_the_namespaces_level(tmp_path):
    _contained(_grade("namespaces", tmp_path, [sys.executable]), "namespaces")


def test_attacks_are_contained_at_the_uid_level_in_a_container(tmp_path, public_python):
    # Without the pictures here (the fresh child they run on is the same at every level): the
    # run's time goes to what differs, the uid's sweep and clean-up between submissions.
    _contained(_grade("uid", tmp_path, in_container([str(public_python)]), pictures=False), "uid")
