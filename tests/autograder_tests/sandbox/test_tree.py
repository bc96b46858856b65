"""Trees thousands of folders deep are measured and removed without recursion (autograder/sandbox/tree.py).

Python 3.11's ``os.walk`` and ``shutil.rmtree`` raise RecursionError on a tree about a thousand
folders deep, and a path that deep is longer than PATH_MAX: a submission that made one in its
scratch or in /dev/shm stopped the class (every later grader too, through the sweep of a dead
grader's folders).  Everything here is made under the test's own ``tmp_path``.
"""

from __future__ import annotations

import json
import os
import shutil
import sys

import pytest

from autograder.sandbox import leftovers, tree

DEPTH = 5000


@pytest.fixture(autouse=True)
def _no_deep_tree_left(tmp_path):
    """Remove what a test made, pass or fail: pytest's own clean-up of old temporary folders
    (shutil.rmtree) would raise RecursionError on these trees in a later run."""
    yield
    os.chmod(tmp_path, 0o700)
    for name in os.listdir(tmp_path):
        tree.remove(tmp_path / name)


def deep_tree(top, depth: int = DEPTH, *, owner: int | None = None, side: int | None = None) -> None:
    """``top/d/d/.../d`` (``depth`` levels below ``top``) with a 10,000-byte file ``f`` at the bottom.

    Made through descriptors: the path is far longer than PATH_MAX.  ``owner``: chown everything
    to that uid; ``side``: at that level, also a folder ``locked`` (mode 0555) holding a file ``f``.
    """
    os.mkdir(top)
    fd = os.open(top, os.O_RDONLY | os.O_DIRECTORY)
    try:
        for level in range(1, depth + 1):
            if owner is not None:
                os.fchown(fd, owner, owner)
            os.mkdir("d", dir_fd=fd)
            if level == side:
                os.mkdir("locked", dir_fd=fd)
                lfd = os.open("locked", os.O_RDONLY | os.O_DIRECTORY, dir_fd=fd)
                with open(os.open("f", os.O_WRONLY | os.O_CREAT, 0o644, dir_fd=lfd), "wb") as fh:
                    fh.write(b"kept")
                if owner is not None:
                    os.chown("f", owner, owner, dir_fd=lfd)
                    os.fchown(lfd, owner, owner)
                os.fchmod(lfd, 0o555)
                os.close(lfd)
            nxt = os.open("d", os.O_RDONLY | os.O_DIRECTORY, dir_fd=fd)
            os.close(fd)
            fd = nxt
        if owner is not None:
            os.fchown(fd, owner, owner)
        with open(os.open("f", os.O_WRONLY | os.O_CREAT, 0o644, dir_fd=fd), "wb") as fh:
            fh.write(os.urandom(10_000))
        if owner is not None:
            os.chown("f", owner, owner, dir_fd=fd)
    finally:
        os.close(fd)


def depth_of(top) -> int:
    """How many ``d`` folders are left below ``top`` (through descriptors)."""
    fd = os.open(top, os.O_RDONLY | os.O_DIRECTORY)
    n = 0
    try:
        while True:
            try:
                nxt = os.open("d", os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW, dir_fd=fd)
            except FileNotFoundError:
                return n
            os.close(fd)
            fd, n = nxt, n + 1
    finally:
        os.close(fd)


def test_a_tree_5000_folders_deep_is_measured_and_removed_and_its_links_are_not_followed(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.bin").write_bytes(os.urandom(2**20))
    top = tmp_path / "deep"
    deep_tree(top)
    plain = tree.usage(top)
    # Two links at the bottom, to a folder and to a file outside the tree: neither is followed.
    fd = os.open(top, os.O_RDONLY)
    for _ in range(DEPTH):
        nxt = os.open("d", os.O_RDONLY, dir_fd=fd)
        os.close(fd)
        fd = nxt
    os.symlink(outside, "to_folder", dir_fd=fd)
    os.symlink(outside / "keep.bin", "to_file", dir_fd=fd)
    os.close(fd)
    if sys.version_info < (3, 12):  # os.walk is iterative from 3.12 on
        with pytest.raises(RecursionError):
            list(os.walk(top))  # what the grader used before

    used = tree.usage(top)
    assert used.failed == [] and used.failures == 0
    assert plain.entries == 1 + DEPTH + 1 and plain.bytes >= 10_000 + DEPTH * 512  # the top, its folders, the file
    assert used.entries == plain.entries + 2  # and the two links...
    assert used.bytes - plain.bytes < 2**19  # ...but not the 1 MB behind them

    gone = tree.remove(top)
    assert gone.failed == [] and (gone.entries, gone.bytes) == (used.entries, used.bytes)
    assert not os.path.lexists(top)
    assert sorted(os.listdir(outside)) == ["keep.bin"] and (outside / "keep.bin").stat().st_size == 2**20
    assert tree.remove(top).entries == 0  # gone already: nothing to do, nothing failed


def test_a_file_and_a_link_are_entries_of_their_own(tmp_path):
    (tmp_path / "target").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "target")
    (tmp_path / "file").write_bytes(b"x" * 5000)
    assert tree.usage(tmp_path / "file").entries == 1 and tree.usage(tmp_path / "file").bytes >= 4096
    assert tree.remove(tmp_path / "link").entries == 1
    assert (tmp_path / "target").is_dir() and not os.path.lexists(tmp_path / "link")
    with pytest.raises(ValueError, match="path"):
        tree.remove("/")


def _remove_as(uid: int | None, cwd, name: str) -> dict:
    """``tree.remove(name)`` in ``cwd``, in a forked process (as ``uid`` when given: root removes
    anything), as plain data."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        try:
            os.close(r)
            os.chdir(cwd)  # as root: the test's tmp_path is not open to others
            if uid is not None:
                os.setgroups([])
                os.setgid(uid)
                os.setuid(uid)
            got = tree.remove(name)
            os.write(w, json.dumps({"entries": got.entries, "failed": got.failed, "failures": got.failures}).encode())
        finally:
            os._exit(0)
    os.close(w)
    with os.fdopen(r, "rb") as fh:
        data = fh.read()
    os.waitpid(pid, 0)
    assert data, "the forked remover wrote nothing"
    return json.loads(data)


def test_what_cannot_be_removed_is_named_not_raised_and_the_rest_goes(tmp_path):
    from autograder.sandbox.uids import pick_uid, release_uid

    uid, fd = pick_uid() if os.geteuid() == 0 else (None, None)
    try:
        side = DEPTH // 2
        os.chmod(tmp_path, 0o755)  # the remover, as another uid, opens it
        deep_tree(tmp_path / "deep", owner=uid, side=side)
        # A folder without write permission: its file cannot be unlinked (as any user but root).
        got = _remove_as(uid, tmp_path, "deep")
    finally:
        release_uid(uid, fd)
        _unlock(tmp_path / "deep", side)  # for the clean-up, as any user
    # Named once, at its own depth (shortened in the middle), not raised; the folders above it
    # that stay because it stays are not named again.
    assert got["failures"] == 1 and len(got["failed"]) == 1, got["failed"]
    line = got["failed"][0]
    assert line.startswith("deep/d/d/") and line.endswith(f"/locked/f ({side + 1} levels): Permission denied"), line
    assert len(line) < 400
    # Everything else went: the branch beside the locked folder, down to the bottom file; the
    # folders above it stay.
    assert got["entries"] == (DEPTH - side + 1) + 1
    assert depth_of(tmp_path / "deep") == side - 1


def _unlock(top, side: int) -> None:
    try:
        fd = os.open(top, os.O_RDONLY | os.O_DIRECTORY)
    except FileNotFoundError:
        return
    try:
        for _ in range(side - 1):
            nxt = os.open("d", os.O_RDONLY | os.O_DIRECTORY, dir_fd=fd)
            os.close(fd)
            fd = nxt
        os.chmod("locked", 0o755, dir_fd=fd)
    except FileNotFoundError:
        pass
    finally:
        os.close(fd)


def test_a_dead_graders_folder_with_a_deep_tree_is_swept_without_raising(tmp_path):
    # A grader killed with SIGKILL left its scratch, where student code had made a tree 3,000
    # folders deep: before, the sweep raised RecursionError, and every later grader on the
    # machine failed at its start.
    dead = tmp_path / f"hw4-sandbox-{_dead_pid()}-abc123"
    dead.mkdir()
    (dead / leftovers.OWNER_FILE).write_text("0\n")  # its lock is free: the owner is dead
    deep_tree(dead / "job1", 3000)
    if sys.version_info < (3, 12):
        with pytest.raises(RecursionError):
            shutil.rmtree(dead)  # what the sweep used before (it removed part of the tree, then raised)
    failed: list[str] = []
    assert leftovers.sweep(tmp_path, failed=failed) == [dead]
    assert failed == [] and not os.path.lexists(dead)
    # The path was too long to open by name: the tree was walked through descriptors.
    assert len(str(dead) + "/job1" + "/d" * 3000) > os.pathconf("/", "PC_PATH_MAX")


def test_releasing_a_folder_removes_a_deep_tree_and_says_what_stayed(tmp_path):
    folder, fd = tmp_path / "hw4-sandbox-1-x", os.open(tmp_path, os.O_RDONLY)
    folder.mkdir()
    deep_tree(folder / "job", 1500)
    assert leftovers.release(folder, fd) == [] and not folder.exists()
    with pytest.raises(OSError):
        os.fstat(fd)  # the lock descriptor was closed too


def _dead_pid() -> int:
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        os._exit(0)
    os.waitpid(pid, 0)
    return pid
