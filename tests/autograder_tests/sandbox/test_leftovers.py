"""Grader folders left by a grader killed with SIGKILL are swept; a live grader's, another user's, a symlink are not.

The folders are made in a private root (``sweep(root)``), except where a Sandbox is made, which
sweeps the temporary directory itself as every channel does before grading.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pytest

from autograder.sandbox import Sandbox, leftovers

from core.paths import KIT_ROOT

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

# A grader: makes one folder of each kind in the root given, says where, and waits to be killed.
GRADER = textwrap.dedent('''
    import sys, tempfile, time
    tempfile.tempdir = sys.argv[1]
    from autograder.sandbox import leftovers
    kept = [leftovers.owned_folder(p) for p in leftovers.PREFIXES]
    for folder, fd in kept:
        (folder / "secret").write_text("hidden inputs or an answer key")
    print(" ".join(str(f) for f, _ in kept), flush=True)
    time.sleep(600)
''')


def start_grader(root: Path) -> tuple[subprocess.Popen, list[Path]]:
    proc = subprocess.Popen([sys.executable, "-c", GRADER, str(root)], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(KIT_ROOT)})
    folders = [Path(p) for p in proc.stdout.readline().split()]
    assert len(folders) == len(leftovers.PREFIXES), folders
    return proc, folders


def dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_a_killed_graders_folders_are_swept_and_a_live_graders_stay(tmp_path):
    dead, dead_folders = start_grader(tmp_path)
    live, live_folders = start_grader(tmp_path)
    try:
        assert all(f.name.startswith(tuple(leftovers.PREFIXES)) and f"-{dead.pid}-" in f.name for f in dead_folders)
        dead.send_signal(signal.SIGKILL)
        dead.wait()
        assert all((f / "secret").is_file() for f in dead_folders)  # left behind by the kill
        removed = leftovers.sweep(tmp_path)
        assert sorted(removed) == sorted(dead_folders)
        assert not any(f.exists() for f in dead_folders)
        assert all((f / "secret").is_file() for f in live_folders)
        assert leftovers.sweep(tmp_path) == []
    finally:
        live.kill()
        live.wait()
    assert sorted(leftovers.sweep(tmp_path)) == sorted(live_folders)


def test_a_sweep_while_a_folder_is_being_made_leaves_it(tmp_path, monkeypatch):
    # A batch's threads each make a Sandbox (which sweeps) at the same moment: one thread's sweep
    # can land between another's creating its folder and locking it. Here the sweep runs right
    # there, every time; the folder being made must survive it, and be usable after.
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    real_flock = leftovers.fcntl.flock
    swept: list[list[Path]] = []

    def flock_after_a_sweep(fd, op):
        if op == leftovers.fcntl.LOCK_EX:
            swept.append(leftovers.sweep(tmp_path))
        return real_flock(fd, op)

    monkeypatch.setattr(leftovers.fcntl, "flock", flock_after_a_sweep)
    folder, fd = leftovers.owned_folder("hw4-sandbox-")
    monkeypatch.setattr(leftovers.fcntl, "flock", real_flock)
    try:
        assert swept == [[]], swept
        assert folder.is_dir() and (folder / leftovers.OWNER_FILE).is_file()
        assert leftovers.sweep(tmp_path) == [] and folder.is_dir()  # locked under its name now
    finally:
        leftovers.release(folder, fd)


def test_a_graders_own_folders_are_alive_to_its_own_sweep(tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    folder, fd = leftovers.owned_folder("hw4-hidden-")
    try:
        assert (folder.stat().st_mode & 0o777) == 0o700
        assert leftovers.sweep(tmp_path) == [] and folder.is_dir()
    finally:
        leftovers.release(folder, fd)
    assert not folder.exists()
    with pytest.raises(ValueError, match="prefix"):
        leftovers.owned_folder("hw4-other-")


def test_a_folder_without_its_lock_goes_only_when_its_pid_is_dead_and_it_is_not_new(tmp_path):
    old = time.time() - 3600
    dead = tmp_path / f"hw4-sandbox-{dead_pid()}-abc"
    alive = tmp_path / f"hw4-sandbox-{os.getpid()}-abc"
    young = tmp_path / f"hw4-hidden-{dead_pid()}-new"
    older_grader = tmp_path / "hw4-hidden-k2v9x0ab"       # a name without a pid: an older grader's
    uid_locks = tmp_path / "hw4-sandbox-uids"             # the uid reservations, not a grader folder
    for folder in (dead, alive, young, older_grader, uid_locks):
        folder.mkdir()
        if folder is not young:
            os.utime(folder, (old, old))
    assert leftovers.sweep(tmp_path) == [dead]
    assert all(f.is_dir() for f in (alive, young, older_grader, uid_locks))


@pytest.mark.skipif(os.geteuid() != 0, reason="giving a folder to another user needs root")
def test_another_users_folder_and_a_symlink_are_left_alone(tmp_path):
    pid = dead_pid()
    theirs = tmp_path / f"hw4-hidden-{pid}-theirs"
    theirs.mkdir()
    os.chown(theirs, 65534, 65534)
    target = tmp_path / "somewhere"
    target.mkdir()
    (target / "keep").write_text("not the grader's")
    link = tmp_path / f"hw4-sandbox-{pid}-link"
    link.symlink_to(target)
    old = time.time() - 3600
    os.utime(theirs, (old, old))
    os.utime(link, (old, old), follow_symlinks=False)
    assert leftovers.sweep(tmp_path) == []
    assert theirs.is_dir() and link.is_symlink() and (target / "keep").is_file()


def test_making_a_sandbox_sweeps_the_temporary_directory():
    # A killed grader's folder in the real temporary directory, as every channel would meet it.
    dead, folders = start_grader(Path(tempfile.gettempdir()))
    dead.send_signal(signal.SIGKILL)
    dead.wait()
    try:
        assert all(f.is_dir() for f in folders)
        with Sandbox(KIT_ROOT, isolation="basic", allow_weak=True) as box:
            assert f"hw4-sandbox-{os.getpid()}-" in str(box._base) and (box._base / leftovers.OWNER_FILE).is_file()
            assert not any(f.exists() for f in folders)
            assert box._base not in leftovers.sweep()  # its own, alive
        assert not box._base.exists()
    finally:
        for f in folders:
            if f.name.startswith(tuple(leftovers.PREFIXES)):
                leftovers.release(f, None)


# A grader that forks: the child (a test's process pool, say) closes the run it inherited and exits
# normally, running the atexit hooks it inherited; the parent's hidden folder and grading worker
# must outlive it (only the process that made a run's folder and workers removes or stops them).
FORKING_GRADER = textwrap.dedent('''
    import atexit, os, sys
    from autograder.inputs.config import quick_config
    from autograder.grading.run import GradingRun
    from autograder.sandbox import leftovers
    run = GradingRun(quick_config())
    run._cache, run._cache_fd = leftovers.owned_folder("hw4-hidden-")  # as make_inputs does, without the inputs
    atexit.register(run._release_cache)
    folder = run._cache
    run.pool.warm()
    pid = os.fork()
    if pid == 0:
        run.close()
        print("child closed its copy", flush=True)
        sys.exit(0)
    os.waitpid(pid, 0)
    print("folder", folder.is_dir(), "workers", [w.alive() for w in run.pool._idle], flush=True)
    run.close()
    print("closed", folder.is_dir(), flush=True)
''')


def test_a_forked_child_leaves_its_parents_folders_and_workers_alone():
    proc = subprocess.run([sys.executable, "-c", FORKING_GRADER], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(KIT_ROOT)}, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "child closed its copy" in proc.stdout, proc.stdout
    assert "folder True workers [True]" in proc.stdout, proc.stdout
    assert "closed False" in proc.stdout, proc.stdout
