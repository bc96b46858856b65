"""Grading past one machine: prepare, shards, merge, on Slurm and Kubernetes (autograder.channels.cluster).

A class of three corpus submissions (the answer key and two that lose part of Q2) at the quick
settings:

- shards plus merge give the one batch's grades.csv byte for byte, after one shard was killed with
  SIGKILL while a submission was in flight: the merge then says which submissions are not graded
  (none written as zero), the status and the Slurm script name only that shard, and grading it
  again resumes it;
- a real one-node Slurm (Debian's slurm-wlm and munge, started here in the test's own folder) runs
  the generated ``sbatch --array`` and its dependent merge job;
- a manifest, a submission or an environment that changed after prepare is refused before
  anything is set up (no grading: fast), and so is a node that cannot give the sandbox level the
  class asks for (before anything is recorded);
- the Slurm array lists only the shards still to do, and a merge refuses two results of one
  submission;
- the Kubernetes Jobs load into the official client's ``V1Job`` without loss (no cluster).
"""

from __future__ import annotations

import csv
import inspect
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import corpus
import pytest
import slurm_node

from autograder.channels.batch import grade_batch
from autograder.channels.cluster.kubernetes import write_kubernetes
from autograder.channels.cluster.manifest import ManifestMismatch, load_manifest, shard_status, write_manifest
from autograder.channels.cluster.merge import merge
from autograder.channels.cluster.prepare import prepare
from autograder.channels.cluster.shard import grade_shard
from autograder.channels.cluster.slurm import _ranges, write_slurm
from autograder.inputs.config import configuration, load_config, quick_config
from autograder.channels.journal import submission_digest, unique_names
from autograder.sandbox import IsolationRefused
from core.paths import KIT_ROOT
from core.text import points

CLASS = ("key_full_marks", "transposed_F_loses_Q2", "rank2_not_enforced_loses_part_of_Q2")
SHARDS = 2   # shard 0: the key and rank2 (positions 0 and 2); shard 1: transposed


@pytest.fixture(scope="module")
def class_paths(tmp_path_factory) -> list[Path]:
    root = tmp_path_factory.mktemp("class")
    return [corpus.build(name, root / "subs", out=root / "out") for name in CLASS]


def cli(*args, **kw) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(KIT_ROOT)}
    env.pop("HW4_COURSE_DATA", None)
    return subprocess.Popen([sys.executable, "-m", "autograder", *map(str, args)], cwd=KIT_ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True, **kw)


def finished(proc: subprocess.Popen, timeout: float = 300) -> tuple[int, str]:
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out + err


@pytest.fixture(scope="module")
def one_batch(class_paths, config_file, tmp_path_factory) -> bytes:
    """The class graded by one batch on one machine: its grades.csv."""
    out = tmp_path_factory.mktemp("one-batch") / "graded"
    grade_batch(class_paths, out, config=load_config(config_file), progress=False, pictures=False, canary=False)
    return (out / "grades.csv").read_bytes()


def rows(data: bytes) -> list[list[str]]:
    return list(csv.reader(data.decode().splitlines()))


# ------------------------------------------------------------------------------------------------
# shards and merge against one batch (slow: they grade)


@pytest.mark.slow
def test_shards_and_merge_give_the_one_batch_grades_even_after_a_killed_shard(tmp_path, class_paths, config_file,
                                                                                one_batch):
    root = tmp_path / "class"
    code, text = finished(cli("prepare", *class_paths, "--root", root, "--shards", SHARDS, "--config", config_file,
                              "--no-pictures", "--quiet"))
    assert code == 0 and "canary 90.0 points" in text, text[-3000:]
    manifest = load_manifest(root)
    assert [s["name"] for s in manifest.owned(0)] == [CLASS[0], CLASS[2]]
    assert manifest.data["environment"]["configuration_key"] == manifest.key
    assert grade_shard(root, 1, SHARDS, progress=False, canary=False)  # shard 1 done, in this process

    # Shard 0 from the command line, killed (SIGKILL: a node lost) with a submission in flight.
    shard0 = root / "shards" / "0"
    proc = cli("grade", "--shard", f"0/{SHARDS}", "--out", root, "--quiet")
    try:
        end = time.monotonic() + 240
        while not list((shard0 / ".inflight").glob("*.json")):
            assert proc.poll() is None, proc.communicate()[1][-3000:]
            assert time.monotonic() < end, "timed out waiting for shard 0 to start a submission"
            time.sleep(0.1)
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(30)
    assert proc.returncode == -signal.SIGKILL

    # Reported: merge writes what is graded and names what is not, never a zero for it.
    status = {s.index: s for s in shard_status(load_manifest(root))}
    assert status[1].complete and not status[0].complete and status[0].inflight
    report = merge(root, review=False)
    missing = set(status[0].missing)
    assert set(report.not_graded) == missing and report.incomplete == [0] and missing
    assert {r[0] for r in rows((root / "out" / "grades.csv").read_bytes())[1:]} == set(CLASS) - missing
    summary = (root / "out" / "summary.md").read_text()
    assert "Not graded" in summary and all(name in summary for name in missing)
    code, text = finished(cli("merge", root, "--no-review"))
    assert code == 3 and "NOT GRADED" in text and "resubmit shards 0 " in text, text
    code, text = finished(cli("shards", root))
    assert code == 1 and "to resubmit: shards 0\n" in text, text
    assert "#SBATCH --array=0\n" in write_slurm(root)["grade"].read_text()

    # Resumable: shard 0 again grades what it lacks (the one in flight first); the merge is whole.
    again = grade_shard(root, 0, SHARDS, progress=False, canary=False)
    assert {r.name for r in again if not r.skipped} == missing
    assert all(s.complete for s in shard_status(load_manifest(root)))
    report = merge(root)
    assert report.complete and report.graded == list(CLASS) and not report.errors, report.errors
    assert (root / "out" / "grades.csv").read_bytes() == one_batch
    totals = {r[0]: r[1] for r in rows(one_batch)[1:]}
    for name in CLASS:  # each student's folder merged whole: results.json says what grades.csv says
        assert points(json.loads((root / "out" / name / "results.json").read_text())["score"]) == totals[name]
    assert (root / "report" / "report.html").is_file() and (root / "similar" / "similarity.csv").is_file()
    assert write_slurm(root)["grade"] is None  # nothing left to submit


# ------------------------------------------------------------------------------------------------
# a real one-node Slurm


@pytest.fixture(scope="module")
def slurm(tmp_path_factory):
    why = slurm_node.why_not()
    if why:
        pytest.skip(why)
    node = slurm_node.SlurmNode(tmp_path_factory.mktemp("slurm"))
    try:
        yield node.start()
    finally:
        node.stop()


@pytest.mark.slow
def test_slurm_runs_the_generated_array_and_its_merge(tmp_path, slurm, class_paths, config_file, one_batch):
    root = tmp_path / "class"
    prepare(class_paths, root, SHARDS, config=load_config(config_file), pictures=False, canary=False)
    code, text = finished(cli("slurm", root, "--mem", "1G", "--time", "00:15:00"))
    assert code == 0, text
    submit = root / "slurm" / "submit.sh"
    done = slurm.run("sh", str(submit), env={"PYTHONPATH": str(KIT_ROOT)})  # the jobs grade with this kit
    assert done.returncode == 0, done.stderr
    jobs = done.stdout.split()  # "grading: job N; merge: job M"
    array, merge_job = jobs[2].rstrip(";"), jobs[-1]
    end = time.monotonic() + 400
    while slurm.job_state(array) or slurm.job_state(merge_job):
        assert time.monotonic() < end, slurm.logs()
        time.sleep(1)
    logs = "\n".join(p.read_text() for p in sorted((root / "slurm" / "logs").glob("*.out")))
    state = slurm.run("scontrol", "show", "job", merge_job).stdout
    assert "JobState=COMPLETED" in state and "ExitCode=0:0" in state, state + logs[-3000:]
    assert len(list((root / "slurm" / "logs").glob("grade-*_*.out"))) == SHARDS
    assert (root / "out" / "grades.csv").read_bytes() == one_batch, logs[-3000:]
    assert all(s.complete for s in shard_status(load_manifest(root)))


# ------------------------------------------------------------------------------------------------
# refusals, scripts and manifests (nothing graded)


def little_class(folder: Path, n: int = 3) -> list[Path]:
    """Submissions that are never graded here: only their names and digests count."""
    paths = []
    for k in range(n):
        p = folder / f"student{k}"
        p.mkdir(parents=True)
        (p / "q2_eightpoint.py").write_text(f"def eightpoint(pts1, pts2, M):\n    return {k}\n")
        paths.append(p)
    return paths


def prepared(root: Path, paths: list[Path], config_file: Path, shards: int = SHARDS, isolation: str = "auto"):
    """A manifest as prepare writes it, without making hidden inputs or grading the canary."""
    subs = [{"name": n, "path": str(p), "sha256": submission_digest(p)} for n, p in zip(unique_names(paths), paths)]
    options = {"config": str(config_file), "extra_tests": [], "official_data": None, "isolation": isolation,
               "allow_weak": False, "pictures": False, "jobs": 1}
    root.mkdir(mode=0o700, exist_ok=True)
    return write_manifest(root, subs, shards, configuration(load_config(config_file)), options)


def test_a_manifest_submission_or_environment_that_changed_is_refused(tmp_path, config_file):
    paths = little_class(tmp_path / "subs")
    root = tmp_path / "class"
    manifest = prepared(root, paths, config_file)
    assert prepared(root, paths, config_file).digest == manifest.digest  # prepared again: the same
    with pytest.raises(ManifestMismatch, match="another manifest"):
        prepared(root, paths[:2], config_file)
    with pytest.raises(ManifestMismatch, match="prepared for 2 shards"):
        grade_shard(root, 0, 3)
    with pytest.raises(ManifestMismatch, match="secret"):
        grade_shard(root, 0, SHARDS, config=quick_config(secret="another course's"))
    with pytest.raises(ManifestMismatch, match="setting match_points"):
        grade_shard(root, 0, SHARDS, config=quick_config(match_points=30))
    (paths[2] / "q2_eightpoint.py").write_text("def eightpoint(pts1, pts2, M):\n    return 'changed'\n")
    with pytest.raises(ManifestMismatch, match="changed since .* student2"):
        grade_shard(root, 0, SHARDS)
    # A shard folder of another manifest.
    assert json.loads((root / "shards" / "0" / "shard.json").read_text())["manifest"] == manifest.digest
    mark = root / "shards" / "1" / "shard.json"
    mark.parent.mkdir(parents=True)
    mark.write_text(json.dumps({"manifest": "0" * 64}))
    with pytest.raises(ManifestMismatch, match="another manifest"):
        grade_shard(root, 1, SHARDS)
    # The manifest edited by hand (a submission's digest made to match the change).
    data = json.loads((root / "manifest.json").read_text())
    data["submissions"][2]["sha256"] = submission_digest(paths[2])
    os.chmod(root / "manifest.json", 0o600)
    (root / "manifest.json").write_text(json.dumps(data))
    with pytest.raises(ManifestMismatch, match="changed after it was prepared"):
        grade_shard(root, 0, SHARDS)
    with pytest.raises(ManifestMismatch, match="changed after it was prepared"):
        merge(root, review=False)
    assert not (root / "out").exists()


@pytest.mark.slow
def test_a_node_without_the_sandbox_level_the_class_asks_for_refuses_before_grading(tmp_path, config_file):
    # "basic" without --allow-weak-isolation: a level no node may grade at, as a node without
    # namespaces is for a class prepared with --isolation namespaces.
    root = tmp_path / "class"
    manifest = prepared(root, little_class(tmp_path / "subs"), config_file, isolation="basic")
    with pytest.raises(IsolationRefused, match="basic"):
        grade_shard(root, 0, SHARDS, progress=False)
    folder = manifest.shard_folder(0)
    assert not list(folder.glob("*/grading.json")) and not list((folder / ".inflight").glob("*"))
    assert not shard_status(manifest)[0].stamped


def test_the_command_line_refuses_a_shard_with_settings_of_its_own(tmp_path, config_file):
    root = tmp_path / "class"
    prepared(root, little_class(tmp_path / "subs"), config_file)
    code, text = finished(cli("grade", "--shard", f"0/{SHARDS}", "--out", root, "--config", config_file), 60)
    assert code == 2 and "drop --config" in text, text
    code, text = finished(cli("grade", "--shard", "2/2", "--out", root), 60)
    assert code == 2 and "0 <= i < K" in text, text


def stamp(folder: Path, sub: dict, key: str) -> None:
    """A stamped result as a batch leaves it (grading.json written last; results.json beside it)."""
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps({"score": 90.0}))
    (folder / "grading.json").write_text(json.dumps({"sha256": sub["sha256"], "configuration_key": key,
                                                     "score": 90.0, "scores": {}, "failure": None}))


def test_the_slurm_array_lists_only_the_shards_still_to_do(tmp_path, config_file):
    root = tmp_path / "class"
    manifest = prepared(root, little_class(tmp_path / "subs", 5), config_file, shards=3)
    written = write_slurm(root, partition="gpu", max_parallel=2, python="/opt/py/bin/python")
    text = written["grade"].read_text()
    assert "#SBATCH --array=0-2%2\n" in text and "#SBATCH --partition=gpu\n" in text
    assert f'/opt/py/bin/python -m autograder grade --shard "${{SLURM_ARRAY_TASK_ID}}/3" --out {root}' in text
    assert "--dependency=afterany:$array" in written["submit"].read_text()
    assert f"/opt/py/bin/python -m autograder merge {root}" in written["merge"].read_text()
    for sub in manifest.owned(1):
        stamp(manifest.shard_folder(1) / sub["name"], sub, manifest.key)
    sub = manifest.owned(2)[0]  # stamped under another configuration: still to do
    stamp(manifest.shard_folder(2) / sub["name"], sub, "another-key")
    assert [s.index for s in shard_status(manifest) if s.complete] == [1]
    assert "#SBATCH --array=0,2\n" in write_slurm(root)["grade"].read_text()
    report = merge(root, review=False)
    assert report.graded == [s["name"] for s in manifest.owned(1)] and report.incomplete == [0, 2]
    sub = manifest.owned(1)[0]  # a result in a second shard's folder too: which one counts is unknown
    stamp(manifest.shard_folder(0) / sub["name"], sub, manifest.key)
    with pytest.raises(ValueError, match=f"several for {sub['name']}"):
        merge(root, review=False)
    assert [_ranges(x) for x in ([0, 1, 2, 5], [3], [0, 2, 3, 4, 7, 8])] == ["0-2,5", "3", "0,2-4,7-8"]


def deserialize(api, data: dict, model: str):
    """``data`` read by the client's own deserializer, as it reads a response body into ``model``
    (newer clients take the body's text and its content type, older ones a response)."""
    if "content_type" in inspect.signature(api.deserialize).parameters:
        return api.deserialize(json.dumps(data), model, "application/json")

    class Response:
        def __init__(self):
            self.data = json.dumps(data)

    return api.deserialize(Response(), model)


def test_the_kubernetes_jobs_load_into_the_official_client_without_loss(tmp_path, config_file):
    client = pytest.importorskip("kubernetes.client")
    yaml = pytest.importorskip("yaml")
    root = tmp_path / "class"
    prepared(root, little_class(tmp_path / "subs", 5), config_file, shards=3)
    written = write_kubernetes(root, image="registry.example/hw4:2026", claim="hw4-class", parallelism=2,
                               secret="hw4-secret")
    api = client.ApiClient()
    jobs = {}
    for kind, path in written.items():
        data = yaml.safe_load(path.read_text())
        job = deserialize(api, data, "V1Job")
        assert isinstance(job, client.V1Job)
        assert api.sanitize_for_serialization(job) == data, kind  # every field known to the model, kept
        typo = {**data, "spec": {**data["spec"], "completionsMode": "Indexed"}}  # what a loss looks like
        assert api.sanitize_for_serialization(deserialize(api, typo, "V1Job")) != typo
        jobs[kind] = job
    spec = jobs["grade"].spec
    assert (spec.completion_mode, spec.completions, spec.parallelism) == ("Indexed", 3, 2)
    pod = spec.template.spec
    command = pod.containers[0].command[-1]
    assert '--shard "$JOB_COMPLETION_INDEX/3"' in command and f"--out {root}" in command
    assert pod.containers[0].env[0].value_from.secret_key_ref.name == "hw4-secret"
    assert pod.volumes[0].persistent_volume_claim.claim_name == "hw4-class"
    assert pod.containers[0].volume_mounts[0].mount_path == str(tmp_path)  # holds the root and the class
    assert f"merge {root}" in jobs["merge"].spec.template.spec.containers[0].command[-1]
    with pytest.raises(ValueError, match="mount_path"):
        write_kubernetes(root, image="i", claim="c", mount_path=str(root / "elsewhere"))
