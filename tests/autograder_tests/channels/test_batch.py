"""The batch always finishes and loses nothing; results record their configuration; regrades come with a diff.

Small classes of corpus submissions (tests/support/corpus) graded with ``quick_config``: a grader killed
with SIGKILL mid-batch and resumed, a double Ctrl-C, a submission in flight at two grader deaths,
an internal error graded again on resume, ``--regrade NAME``, a folder refusing another
configuration, and a regrade whose diff names exactly the students whose score moved (an
instructor's extra check whose threshold is tightened).
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import corpus
import pytest

from autograder.grading.run import GradingRun
from autograder.channels.batch import ConfigurationMismatch, grade_batch
from autograder.inputs.config import configuration_changes, load_config, quick_config
from autograder.inputs.keep import ENV_KEEP
from autograder.channels.regrade import accept, diff_folders
from autograder.sandbox import ResourceLimits, Sandbox
from core.paths import KIT_ROOT
from core.text import points

LIMITS = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)
KEY = "key_full_marks"
TRANSPOSED = "transposed_F_loses_Q2"
RANK3 = "rank2_not_enforced_loses_part_of_Q2"
FULL = 90.0

pytestmark = pytest.mark.slow

EXTRA_CHECK = '''
"""An instructor's extra check: F is singular (smallest singular value at most THRESHOLD times the largest)."""
import numpy as np
import pytest

THRESHOLD = {threshold!r}


@pytest.mark.points(1, question="Q2", name="F is singular (extra check)")
def test_f_is_singular(student):
    rng = np.random.default_rng(7)
    X = rng.uniform(-1, 1, (40, 3)) + np.array([0.0, 0.0, 6.0])
    c, s = np.cos(0.2), np.sin(0.2)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    X2 = X @ R.T + np.array([-1.0, 0.1, 0.2])
    pts1 = X[:, :2] / X[:, 2:] * 400 + 320 + rng.normal(0, 1.0, (40, 2))
    pts2 = X2[:, :2] / X2[:, 2:] * 400 + 320 + rng.normal(0, 1.0, (40, 2))
    F = np.asarray(student.call("eightpoint", pts1, pts2, 640, seconds=20), dtype=float)
    sv = np.linalg.svd(F, compute_uv=False)
    assert sv[2] <= THRESHOLD * sv[0], "F is not singular"
'''


def extra_check(folder: Path, threshold: float) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "test_extra_singular.py").write_text(EXTRA_CHECK.format(threshold=threshold))
    return folder


@pytest.fixture(scope="module")
def alone(tmp_path_factory) -> dict:
    """What the partly right corpus submissions deserve, each graded alone outside any batch (how
    much Q2 takes off is the hidden checks' business; a batch must record exactly this): the total
    by name, Q2's by (name, "Q2")."""
    root = tmp_path_factory.mktemp("alone")
    scores = {}
    with Sandbox(KIT_ROOT, limits=LIMITS) as box, GradingRun(quick_config(), sandbox=box) as run:
        for name in (TRANSPOSED, RANK3):
            result = run.grade(build(root, name))
            assert result.failure is None and 0 < result.score < FULL, (name, result.failure, result.score)
            scores[name] = result.score
            scores[name, "Q2"] = next(q.score for q in result.questions if q.id == "Q2")
    return scores


def build(root: Path, name: str, as_name: str | None = None) -> Path:
    path = corpus.build(name, root / "built", out=root / "out")
    if as_name is None:
        return path
    target = root / "subs" / as_name
    if not target.exists():
        shutil.copytree(path, target)
    return target


def cli(args, config_file: Path, *, pictures: bool = False, keep: bool = True, **kw) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(KIT_ROOT)}
    env.pop("HW4_COURSE_DATA", None)
    if not keep:  # the hidden inputs made afresh, not read from the suite's keep (tests/conftest.py)
        env.pop(ENV_KEEP, None)
    # Text feedback unless asked: the pictures' step is this file's subject once (one Ctrl-C).
    argv = [sys.executable, "-m", "autograder", "grade", *map(str, args), "--config", str(config_file), "--quiet",
            *([] if pictures else ["--no-pictures"])]
    return subprocess.Popen(argv, cwd=KIT_ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, **kw)


def wait_for(condition, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.1)


def inflight(out: Path) -> set[str]:
    return {p.stem for p in (out / ".inflight").glob("*.json")}


def gradebook(out: Path) -> list[list[str]]:
    with open(out / "grades.csv", newline="") as fh:
        return list(csv.reader(fh))[1:]


def state(out: Path, name: str) -> dict:
    return json.loads((out / name / "grading.json").read_text())


def assert_right(out: Path, expected: dict[str, float]) -> None:
    """Every recorded result has the score its submission deserves (no zero from a cancelled run)."""
    for folder in out.glob("*/grading.json"):
        name = folder.parent.name
        s = state(out, name)
        assert s["failure"] is None, (name, s["failure"])
        assert s["score"] == expected[name], (name, s["score"], s["staff"]["log"][-1:])


# ---------------------------------------------------------------------------------------------
# the journal: SIGKILL, two deaths, Ctrl-C


def test_sigkill_mid_batch_then_resume_regrades_the_one_in_flight(tmp_path, config_file, alone):
    subs = [build(tmp_path, KEY, "a_key"), build(tmp_path, TRANSPOSED, "b_transposed"), build(tmp_path, KEY, "c_key")]
    out = tmp_path / "graded"
    proc = cli([*subs, "--out", out, "--jobs", "1"], config_file)
    try:
        wait_for(lambda: (out / "a_key" / "grading.json").is_file() and "b_transposed" in inflight(out), 120,
                 "a_key graded and b_transposed in flight")
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(30)
    assert proc.returncode == -signal.SIGKILL
    assert not (out / "b_transposed" / "grading.json").exists()
    assert inflight(out) == {"b_transposed"}
    # The killed grader's hidden inputs and sandbox scratch are left behind (nobody removed them)...
    left = {p.name.split("-")[1] for p in Path(tempfile.gettempdir()).glob(f"hw4-*-{proc.pid}-*")}
    assert {"hidden", "sandbox"} <= left, left
    live = subprocess.Popen([sys.executable, "-c", LIVE_GRADER], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(KIT_ROOT)})
    live_folder = Path(live.stdout.readline().strip() or "no-folder")
    try:
        assert live_folder.name.startswith(f"hw4-hidden-{live.pid}-"), live_folder
        records = grade_batch(subs, out, config=load_config(config_file), progress=False, pictures=False,
                              canary=False, limits=LIMITS)
        # ... until the next batch swept them; a live grader's folder stays.
        assert not list(Path(tempfile.gettempdir()).glob(f"hw4-*-{proc.pid}-*"))
        assert live_folder.is_dir() and (live_folder / "hidden-inputs.pickle").is_file()
    finally:
        live.kill()
        live.wait()
        if live_folder.name.startswith("hw4-hidden-"):
            shutil.rmtree(live_folder, ignore_errors=True)
    by_name = {r.name: r for r in records}
    assert by_name["a_key"].skipped and not by_name["b_transposed"].skipped and not by_name["c_key"].skipped
    assert [by_name[n].score for n in ("a_key", "b_transposed", "c_key")] == [FULL, alone[TRANSPOSED], FULL]
    assert any("attempt 2" in line for line in state(out, "b_transposed")["staff"]["log"])
    rows = gradebook(out)
    assert sorted(r[0] for r in rows) == ["a_key", "b_transposed", "c_key"]  # nothing lost, no duplicate
    assert inflight(out) == set()


# A grader that is alive: it made its hidden-inputs folder, says where, and waits.
LIVE_GRADER = textwrap.dedent('''
    import sys, time
    from autograder.sandbox import leftovers
    folder, fd = leftovers.owned_folder("hw4-hidden-")
    (folder / "hidden-inputs.pickle").write_bytes(b"")
    print(folder, flush=True)
    time.sleep(600)
''')


DRIVER = textwrap.dedent('''
    import os, signal, sys
    from autograder.grading.run import GradingRun
    from autograder.channels.batch import grade_batch
    from autograder.inputs.config import load_config

    real = GradingRun.grade

    def deadly(run, path, **kw):
        if kw.get("student_id") == "poison":
            os.kill(os.getpid(), signal.SIGKILL)  # stands for a submission that kills or stops the grader
        return real(run, path, **kw)

    GradingRun.grade = deadly
    config, out, *subs = sys.argv[1:]
    # The deaths are the subject here, not the canary (graded by the other batches of this file).
    grade_batch(subs, out, config=load_config(config), progress=False, pictures=False, canary=False)
''')


def test_a_submission_in_flight_at_two_grader_deaths_is_recorded_as_failed(tmp_path, config_file):
    subs = [build(tmp_path, KEY, "a_key"), build(tmp_path, KEY, "poison")]
    out = tmp_path / "graded"
    env = {**os.environ, "PYTHONPATH": str(KIT_ROOT)}
    argv = [sys.executable, "-c", DRIVER, str(config_file), str(out), *map(str, subs)]
    for _ in range(2):
        run = subprocess.run(argv, cwd=KIT_ROOT, env=env, capture_output=True, text=True, timeout=300)
        assert run.returncode == -signal.SIGKILL, run.stderr[-2000:]
        assert inflight(out) == {"poison"}
    assert state(out, "a_key")["score"] == FULL
    run = subprocess.run(argv, cwd=KIT_ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    s = state(out, "poison")
    assert s["poison"] and s["score"] == 0 and "stopped while grading" in s["failure"]
    assert "died 2 times" in s["staff"]["log"][0] and "--regrade poison" in s["staff"]["log"][0]
    assert dict((r[0], r[1]) for r in gradebook(out)) == {"a_key": "90", "poison": "0"}
    assert "poison" in (out / "summary.md").read_text() and inflight(out) == set()
    # A plain resume does not try it again (it would kill the grader); naming it does.
    records = grade_batch(subs, out, config=load_config(config_file), progress=False, pictures=False, canary=False,
                          limits=LIMITS, regrade=["poison"])
    assert {r.name: (r.skipped, r.score) for r in records} == {"a_key": (True, FULL), "poison": (False, FULL)}


def _interrupt(tmp_path, config_file, signals: int, transposed: float, *, pictures: bool = False):
    names = ["a_key", "b_key", "c_transposed", "d_key"]
    subs = [build(tmp_path, TRANSPOSED if "transposed" in n else KEY, n) for n in names]
    expected = {n: transposed if "transposed" in n else FULL for n in names}
    out = tmp_path / "graded"
    proc = cli([*subs, "--out", out, "--jobs", "2"], config_file, pictures=pictures)
    try:
        wait_for(lambda: len(inflight(out)) == 2, 120, "two submissions in flight")
        time.sleep(2.0)  # inside their sandboxes now
        start = time.monotonic()
        for k in range(signals):
            os.kill(proc.pid, signal.SIGINT)
            if k + 1 < signals:
                time.sleep(0.3)
        proc.wait(30)
        elapsed = time.monotonic() - start
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(30)
    stderr = proc.stderr.read()
    assert proc.returncode == 130, stderr[-2000:]
    assert elapsed < 10, f"took {elapsed:.1f} s to stop"
    assert (out / "grades.csv").is_file()
    assert_right(out, expected)  # no wrong zero recorded from a cancelled sandbox
    recorded = {r[0] for r in gradebook(out)}
    assert recorded == {p.parent.name for p in out.glob("*/grading.json")}
    assert recorded != set(names)  # it did stop
    assert inflight(out) == set()  # a cancelled run is no strike against the student
    records = grade_batch(subs, out, config=load_config(config_file), progress=False, pictures=pictures, jobs=2,
                          canary=False, limits=LIMITS)
    assert {r.name: r.score for r in records} == expected
    assert all(r.skipped == (r.name in recorded) for r in records)
    return stderr


def test_one_ctrl_c_cancels_what_runs_records_nothing_wrong_and_writes_grades(tmp_path, config_file, alone):
    # The batch's default: each submission's picture step runs in its sandbox after its checks.
    stderr = _interrupt(tmp_path, config_file, 1, alone[TRANSPOSED], pictures=True)
    assert "interrupted:" in stderr and "run the same command again" in stderr


def test_double_ctrl_c_exits_at_once_recording_nothing_wrong(tmp_path, config_file, alone):
    # The second signal lands while the first is stopping the grading processes ("interrupted
    # twice": killed at once) or, when they stopped within 50 ms, after: either way exit 130.
    stderr = _interrupt(tmp_path, config_file, 2, alone[TRANSPOSED])
    assert "interrupted twice" in stderr or "interrupted:" in stderr


# ---------------------------------------------------------------------------------------------
# resume and --regrade


def test_resume_regrades_an_internal_error_and_regrade_names_one_student(tmp_path, monkeypatch, alone):
    subs = [build(tmp_path, KEY, "a_key"), build(tmp_path, TRANSPOSED, "b_transposed")]
    out = tmp_path / "graded"
    config = quick_config()
    real = GradingRun.grade

    def broken(run, path, **kw):
        if kw.get("student_id") == "b_transposed":
            raise RuntimeError("the grading process failed (exit code 3)")
        return real(run, path, **kw)

    # The resume is the subject here, not the canary (graded by the other batches of this file).
    options = {"config": config, "progress": False, "pictures": False, "canary": False, "limits": LIMITS}
    monkeypatch.setattr(GradingRun, "grade", broken)
    first = {r.name: r for r in grade_batch(subs, out, **options)}
    assert "internal error" in first["b_transposed"].failure and state(out, "b_transposed")["internal_errors"]
    monkeypatch.setattr(GradingRun, "grade", real)
    second = {r.name: r for r in grade_batch(subs, out, **options)}
    assert second["a_key"].skipped and not second["b_transposed"].skipped
    assert second["b_transposed"].failure is None and second["b_transposed"].score == alone[TRANSPOSED]
    third = {r.name: r for r in grade_batch(subs, out, **options, regrade=["a_key"])}
    assert not third["a_key"].skipped and third["b_transposed"].skipped and third["a_key"].score == FULL
    with pytest.raises(ValueError, match="regrade"):
        grade_batch(subs, out, config=config, progress=False, pictures=False, regrade=["nobody"])


# ---------------------------------------------------------------------------------------------
# configuration, refusal, regrade with a diff


@pytest.fixture(scope="module")
def graded_class(tmp_path_factory):
    """Three students graded with an extra check whose threshold everyone passes."""
    root = tmp_path_factory.mktemp("class")
    subs = [build(root, KEY, "alice"), build(root, RANK3, "bob"), build(root, TRANSPOSED, "carol")]
    out = root / "published"
    loose = extra_check(root / "extra-loose", 1.0)
    records = grade_batch(subs, out, config=quick_config(), jobs=2, progress=False, pictures=False, limits=LIMITS,
                          extra_tests=[loose])
    return {"root": root, "subs": subs, "out": out, "records": {r.name: r for r in records}}


def test_every_result_records_its_configuration(graded_class):
    out = graded_class["out"]
    s = state(out, "alice")
    c = s["configuration"]
    assert c["grader_version"] and c["kit_version"] and len(c["secret_fingerprint"]) == 12
    assert quick_config().secret not in json.dumps(s)
    assert c["dev_secret"] is True and c["data"] == {"default_data": True, "official_data": None,
                                                      "official_digest": None}
    assert c["isolation"] == s["isolation"]["level"]
    assert c["tests"]["extra"] and "extra/extra-loose/test_extra_singular.py" in c["tests"]["files"]
    assert any(name.startswith("hidden/test_") for name in c["tests"]["files"])
    results = json.loads((out / "alice" / "results.json").read_text())
    assert results["extra_data"]["configuration"]["key"] == c["key"] == s["configuration_key"]
    summary = (out / "summary.md").read_text()
    assert "DEVELOPMENT secret" in summary and c["key"] in summary


def test_without_pictures_the_feedback_is_text_only_and_the_scores_are_the_same(graded_class, alone):
    # graded_class was graded with pictures=False (as `grade --no-pictures`); the batch's default
    # draws them (tests/autograder_tests/sandbox/test_picture_step_sandbox.py).
    out = graded_class["out"]
    for name in ("alice", "bob", "carol"):
        assert json.loads((out / name / "figures" / "figures.json").read_text()) == {}
        page = (out / name / "feedback.html").read_text()
        assert "data:image/png" not in page and "Q2" in page
        assert state(out, name)["scores"], name
    assert graded_class["records"]["carol"].score == alone[TRANSPOSED] + 1  # the extra check's point


def test_official_data_only_when_asked_for(tmp_path):
    assert load_config(environ={}).official_dir() is None
    with pytest.raises(ValueError, match="official_data"):
        load_config(environ={}, official_data=tmp_path)
    (tmp_path / "temple").mkdir()
    (tmp_path / "temple" / "some_corresp.npz").write_bytes(b"")
    assert load_config(environ={"HW4_COURSE_DATA": str(tmp_path)}).official_dir() == tmp_path.resolve()
    assert load_config(environ={}, official_data=tmp_path).official_dir() == tmp_path.resolve()


def test_a_folder_refuses_results_of_another_configuration(graded_class, tmp_path, config_file):
    out, subs = graded_class["out"], graded_class["subs"]
    before = (out / "grades.csv").read_text()
    with pytest.raises(ConfigurationMismatch, match="secret"):
        grade_batch(subs[:1], out, config=quick_config(secret="the course's own"), progress=False, pictures=False)
    with pytest.raises(ConfigurationMismatch, match="test files changed: extra/"):
        grade_batch(subs[:1], out, config=quick_config(), progress=False, pictures=False,
                    extra_tests=[extra_check(tmp_path / "extra-strict", 1e-8)])
    env = {**os.environ, "PYTHONPATH": str(KIT_ROOT)}
    run = subprocess.run([sys.executable, "-m", "autograder", "grade", str(subs[0]), "--out", str(out), "--config",
                          str(config_file), "--quiet", "--no-pictures"], cwd=KIT_ROOT, env=env, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 2 and "--regrade-all" in run.stderr and "another configuration" in run.stderr
    assert (out / "grades.csv").read_text() == before


def test_regrade_with_a_diff_names_exactly_the_students_whose_score_moved(graded_class, tmp_path, alone):
    root, out = graded_class["root"], graded_class["out"]
    published = (out / "grades.csv").read_text()
    # Each with the loose extra check's point.
    assert {n: r.score for n, r in graded_class["records"].items()} == {
        "alice": FULL + 1, "bob": alone[RANK3] + 1, "carol": alone[TRANSPOSED] + 1}
    strict = extra_check(root / "extra-strict", 1e-8)
    new = tmp_path / "regraded"
    env = {**os.environ, "PYTHONPATH": str(KIT_ROOT)}
    config = tmp_path / "grader.json"
    config.write_text(json.dumps(quick_config().to_dict()))
    run = subprocess.run([sys.executable, "-m", "autograder", "regrade", str(out), "--into", str(new),
                          "--hidden-dir", str(strict), "--config", str(config), "--jobs", "2", "--quiet", "--no-pictures"],
                         cwd=KIT_ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "1 changed score: bob" in run.stdout and "accept" in run.stdout
    assert (out / "grades.csv").read_text() == published  # nothing published yet
    with open(new / "regrade_diff.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["student_id"] for r in rows} == {"bob"}
    bob_q2, total = alone[RANK3, "Q2"] + 1, alone[RANK3] + 1
    assert {(r["question"], r["old"], r["new"], r["change"]) for r in rows} == {
        ("Q2", points(bob_q2), points(bob_q2 - 1), "-1"), ("total", points(total), points(total - 1), "-1")}
    q2 = next(r for r in rows if r["question"] == "Q2")
    assert q2["why"] == "F is singular (extra check): 1 / 1 -> 0 / 1"
    assert "test files changed: extra/extra-" in q2["configuration"]
    md, page = (new / "regrade_diff.md").read_text(), (new / "regrade_diff.html").read_text()
    assert f"| bob | Q2 | {points(bob_q2)} | {points(bob_q2 - 1)} | -1 |" in md and "1 of 3 students changed score: bob" in md
    assert "<td>bob</td>" in page and "F is singular (extra check): 1 / 1 -&gt; 0 / 1" in page
    assert [c.student for c in diff_folders(out, new)] == ["bob", "bob"]

    run = subprocess.run([sys.executable, "-m", "autograder", "accept", str(new), "--into", str(out)],
                         cwd=KIT_ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert (out / "grades.csv").read_text() == (new / "grades.csv").read_text() != published
    history = next((out / ".history").iterdir())
    assert (history / "grades.csv").read_text() == published and (history / "bob" / "grading.json").is_file()
    assert state(out, "bob")["score"] == total - 1
    with pytest.raises(ValueError, match="into"):
        accept(new, tmp_path)


def test_configuration_changes_name_what_differs():
    from autograder.inputs.config import configuration

    a, b = configuration(quick_config()), configuration(quick_config(secret="s", match_points=30))
    said = configuration_changes(a, b)
    assert any(s.startswith("secret") for s in said) and "setting match_points 24 -> 30" in said
    assert configuration_changes(a, configuration(quick_config())) == []


# ---------------------------------------------------------------------------------------------
# Ctrl-C while the batch is being set up (hidden inputs, the canary in its sandbox)


def _descendants(pid: int) -> dict[int, int]:
    """The processes under ``pid``, each with its depth (1: a child)."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
            children.setdefault(int(stat[stat.rindex(")") + 2:].split()[1]), []).append(int(entry))
        except (OSError, ValueError, IndexError):
            continue
    found, todo = {}, [(c, 1) for c in children.get(pid, [])]
    while todo:
        p, depth = todo.pop()
        found[p] = depth
        todo += [(c, depth + 1) for c in children.get(p, [])]
    return found


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z"
    except (OSError, IndexError):
        return False


@pytest.mark.slow
@pytest.mark.parametrize("phase, sigint", [("hidden inputs", "ignored"), ("canary", "ignored"), ("canary", "default")])
def test_ctrl_c_during_set_up_stops_at_once_recording_nothing(tmp_path, config_file, phase, sigint):
    # "ignored": started as a shell starts a background job (SIGINT ignored until the grader says
    # otherwise), as in the issue; the grader's own handling must be in place before its set-up.
    names = ["a_key", "b_key"]
    subs = [build(tmp_path, KEY, n) for n in names]
    out = tmp_path / "graded"
    args = [*subs, "--out", out, "--jobs", "2"]
    ignore = (lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) if sigint == "ignored" else None
    # Made afresh, the hidden inputs take seconds: the window the first phase's signal falls in.
    proc = cli(args, config_file, preexec_fn=ignore, keep=phase != "hidden inputs")
    mine = lambda kind: list(Path(tempfile.gettempdir()).glob(f"hw4-{kind}-{proc.pid}-*"))  # noqa: E731
    seen: dict[int, int] = {}

    def setting_up() -> bool:
        seen.update(_descendants(proc.pid))
        if phase == "hidden inputs":  # the batch's configuration is written, its hidden inputs not yet
            return (out / "configuration.json").is_file()
        # The canary is being graded: its scratch folder exists and a process runs under the
        # grading worker (the key's pytest session in its sandbox).
        return bool(mine("canary")) and any(d >= 2 for d in seen.values())

    try:
        wait_for(lambda: setting_up() or proc.poll() is not None, 120, f"the set-up's {phase}")
        assert proc.poll() is None, proc.stderr.read()[-2000:]
        assert bool(mine("hidden")) == (phase == "canary"), mine("hidden")
        assert inflight(out) == set() and not list(out.glob("*/grading.json"))  # nothing started yet
        # Interrupted before the canary ends: its scratch folder (the key) is still there.
        assert phase != "canary" or mine("canary"), "the canary ended before the signal"
        start = time.monotonic()
        os.kill(proc.pid, signal.SIGINT)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            pass
        elapsed = time.monotonic() - start
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(30)
    stderr = proc.stderr.read()
    assert proc.returncode == 130, (proc.returncode, stderr[-2000:])
    assert elapsed < 10, f"took {elapsed:.1f} s to stop"
    assert "interrupted while setting up" in stderr, stderr[-2000:]
    # Nothing recorded: no student's result, no grades, no journal entry claiming work.
    assert not list(out.glob("*/grading.json")) and not list(out.glob("*/results.json"))
    assert not (out / "grades.csv").exists()
    assert inflight(out) == set()
    # The set-up's processes (the grading worker, the key's sandbox) ended with the grader, and
    # its folders (hidden inputs, sandbox, the canary's key) were removed.
    wait_for(lambda: not any(_alive(p) for p in seen), 5, "the set-up's processes to end")
    assert not mine("*")
    # The same command again grades normally (once: what is left behind is the same whichever
    # way the signal came, and a whole batch is this check's cost).
    if (phase, sigint) != ("canary", "default"):
        return
    again = cli(args, config_file)
    _, err = again.communicate(timeout=300)
    assert again.returncode == 0, err[-2000:]
    assert {r[0]: r[1] for r in gradebook(out)} == {n: "90" for n in names}


def test_a_signal_between_two_set_up_steps_stops_the_next_before_it_starts():
    # Ctrl-C that lands after the configuration is written and before the hidden inputs are made
    # (no step running to raise in) must not let that step run for its seconds first.
    import threading

    from autograder.channels.batch import _SetUpCancelled, _Signals

    ran = []
    signals = _Signals(threading.Event(), hard_exit=lambda: ran.append("hard exit"))
    assert signals.stoppable(lambda: ran.append("first") or 1) == 1
    signals._on_signal(signal.SIGINT, None)  # between steps: nothing to raise in
    with pytest.raises(_SetUpCancelled):
        signals.stoppable(lambda: ran.append("second"))
    assert ran == ["first"] and not signals.raising
