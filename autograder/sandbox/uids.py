"""The sandbox's own uids: reserved across grader processes, their processes found and killed, and
what they left in the machine's shared temporary folders measured and removed."""

from __future__ import annotations

import fcntl
import os
import pwd
import signal
import stat
import tempfile
import threading
import time
from pathlib import Path

from . import tree

__all__ = ["SHARED_TMP_DIRS", "count_processes", "files_of_uid", "held_open_files", "live_pids_of_uid", "pick_uid",
           "release_uid", "remove_files_of_uid", "sweep_uid", "usage_of"]

# The machine's world-writable folders where code without a private /tmp can leave files behind.
SHARED_TMP_DIRS = ("/tmp", "/var/tmp", "/dev/shm", "/run/lock", "/var/lock")

_IN_USE: set[int] = set()          # uids of live Sandboxes of this process
_IN_USE_LOCK = threading.Lock()
_UID_LOCKS = Path(tempfile.gettempdir()) / "hw4-sandbox-uids"


def _status(path: str) -> tuple[set[int], str] | None:
    """(uids, state letter) of a ``/proc/.../status`` file, or None when it cannot be read."""
    try:
        with open(path) as fh:
            text = fh.read()
    except OSError:
        return None
    uids: set[int] = set()
    state = ""
    for line in text.splitlines():
        if line.startswith("Uid:"):
            uids = {int(x) for x in line.split()[1:]}
        elif line.startswith("State:"):
            state = line.split()[1]
    return uids, state


def _uids_of(pid: str) -> tuple[set[int], str] | None:
    return _status(f"/proc/{pid}/status")


def _live_task(pid: str, uid: int) -> str | None:
    """A task (thread id) of process ``pid`` that runs as ``uid`` and is not a zombie, or None.

    The leader's own state is not enough: a leader that called exit() alone shows ``State: Z``
    while its other threads run on (and /proc/PID/fd is then empty; /proc/PID/task/TID/fd is not).
    A real zombie, all of whose threads are gone, has no live task and is left alone: SIGKILL
    cannot end it (only its parent's wait can), so counting it would make a sweep loop forever.
    """
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return None
    for tid in tids:
        info = _status(f"/proc/{pid}/task/{tid}/status")
        if info and uid in info[0] and info[1] not in ("Z", "X"):
            return tid
    return None


def _live_tasks_of_uid(uid: int) -> dict[int, str]:
    """{pid: one of its live tasks} of every process with a task running as ``uid``."""
    out = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            info = _uids_of(entry)
            # A process's threads share its credentials unless one changed its own, which takes a
            # privilege the sandbox's uid has not: the leader's uids (a zombie's too) say whose it is.
            if info and uid in info[0]:
                tid = _live_task(entry, uid)
                if tid is not None:
                    out[int(entry)] = tid
    return out


def live_pids_of_uid(uid: int) -> list[int]:
    """Pids of the processes with ``uid`` among their uids and at least one task still running:
    a process whose leader thread exited while others run (``State: Z`` in its status) counts,
    a real zombie does not."""
    return sorted(_live_tasks_of_uid(uid))


def count_processes(uid: int) -> int:
    return len(live_pids_of_uid(uid))


def sweep_uid(uid: int, budget: float = 5.0) -> list[int]:
    """SIGKILL every live process of ``uid`` (the sandbox's own) until none is left or ``budget``
    seconds have passed; return the pids signalled, each once.

    A process counts while any of its threads runs (``live_pids_of_uid``), whatever session or
    process group it made itself.  Each process is opened as a pidfd and its uid re-checked
    before the signal, so a pid reused by an unrelated process in between is never signalled.
    What still runs after the budget is for the caller to see (``live_pids_of_uid``): that uid
    must not be handed to other code.
    """
    if uid == 0 or uid == os.getuid():
        raise ValueError(f"uid: expected the sandbox's own uid, got {uid}")
    killed: dict[int, None] = {}
    end = time.monotonic() + budget
    while True:
        pids = live_pids_of_uid(uid)
        if not pids or time.monotonic() > end:
            return list(killed)
        for pid in pids:
            try:
                pfd = os.pidfd_open(pid)
            except OSError:
                continue
            try:
                info = _uids_of(str(pid))
                if info and uid in info[0]:
                    signal.pidfd_send_signal(pfd, signal.SIGKILL)
                    killed[pid] = None
            except OSError:
                pass
            finally:
                os.close(pfd)
        time.sleep(0.01)


def held_open_files(uid: int) -> tuple[int, int]:
    """(files, bytes) of the regular files that ``uid``'s live processes hold open, or have mapped,
    after they were unlinked (no folder shows them, yet they fill /dev/shm or the disk until the
    process ends), each file counted once by (device, inode)."""
    seen: dict[tuple[int, int], int] = {}
    for pid, tid in _live_tasks_of_uid(uid).items():
        task = f"/proc/{pid}/task/{tid}"
        try:
            fds = os.listdir(f"{task}/fd")
        except OSError:
            fds = []
        for fd in fds:
            try:
                st = os.stat(f"{task}/fd/{fd}")  # the open file itself, unlinked or not
            except OSError:
                continue
            if stat.S_ISREG(st.st_mode) and st.st_nlink == 0:
                seen[(st.st_dev, st.st_ino)] = max(seen.get((st.st_dev, st.st_ino), 0), tree.disk_bytes(st))
        try:
            with open(f"{task}/maps") as fh:
                maps = fh.read().splitlines()
        except OSError:
            maps = []
        for line in maps:
            # "start-end perms offset major:minor inode path (deleted)": a file mapped, then closed
            # and unlinked, keeps its pages; its mapped length stands for its size.
            parts = line.split(None, 5)
            if len(parts) == 6 and parts[5].endswith("(deleted)") and parts[4] != "0":
                start, end = (int(x, 16) for x in parts[0].split("-"))
                major, minor = (int(x, 16) for x in parts[3].split(":"))
                key = (os.makedev(major, minor), int(parts[4]))
                seen[key] = max(seen.get(key, 0), end - start)
    return len(seen), sum(seen.values())


def _lock_uid(uid: int) -> int | None:
    """An open, exclusively locked file descriptor that reserves ``uid``, or None when it is taken.

    The lock is shared by every grader process on the machine (two batches at once must not
    pick the same uid: one's clean-up would kill the other's processes).  It is released when
    the descriptor is closed, or when the process dies.
    """
    _UID_LOCKS.mkdir(mode=0o700, exist_ok=True)
    fd = os.open(_UID_LOCKS / str(uid), os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def pick_uid(start: int = 60000, span: int = 4000) -> tuple[int, int]:
    """(uid, lock fd): an uid with no passwd entry and no process, reserved across processes."""
    offset = os.getpid() % span
    for k in range(span):
        uid = start + (offset + k) % span
        with _IN_USE_LOCK:
            if uid in _IN_USE:
                continue
        try:
            pwd.getpwuid(uid)
            continue
        except KeyError:
            pass
        fd = _lock_uid(uid)
        if fd is None:
            continue
        if not live_pids_of_uid(uid):
            with _IN_USE_LOCK:
                _IN_USE.add(uid)
            return uid, fd
        os.close(fd)
    raise RuntimeError(f"no free uid between {start} and {start + span}")


def claim_uid(uid: int) -> None:
    """Mark a uid given by the caller as used by this process."""
    with _IN_USE_LOCK:
        _IN_USE.add(uid)


def release_uid(uid: int | None, fd: int | None) -> None:
    """Free a uid reserved by ``pick_uid`` (or claimed) and close its lock."""
    if uid is not None:
        with _IN_USE_LOCK:
            _IN_USE.discard(uid)
    if fd is not None:
        os.close(fd)


def _roots(roots) -> list[str]:
    """The existing folders among ``roots``, each once (/var/lock is a link to /run/lock)."""
    out: list[str] = []
    for r in roots:
        real = os.path.realpath(r)
        if os.path.isdir(real) and real not in out:
            out.append(real)
    return out


def usage_of(path: str | os.PathLike) -> tuple[int, int]:
    """(entries, bytes) of ``path`` and everything in it, links not followed (``tree.usage``: no
    recursion, any depth)."""
    got = tree.usage(path)
    return got.entries, got.bytes


def files_of_uid(uid: int, roots=SHARED_TMP_DIRS, *, deep: bool = True):
    """``[(path, is_folder, entries, bytes)]``: what ``uid`` owns in ``roots``, found by owner.

    A folder of ``uid`` counts with everything in it.  With ``deep`` the search also descends into
    other users' folders that any user may enter (a world-writable folder inside /tmp takes the
    code's files as well as /tmp does); without it only the roots' own entries are looked at.
    Symbolic links are never followed: a link the code made is itself its entry.
    """
    found = []
    for path, st in _owned_by(uid, roots, deep):
        if stat.S_ISDIR(st.st_mode):
            got = tree.usage(path)
            found.append((path, True, got.entries, got.bytes))
        else:
            found.append((path, False, 1, tree.disk_bytes(st)))
    return found


def _owned_by(uid: int, roots, deep: bool):
    """``(path, lstat)`` of each entry of ``uid`` in ``roots`` (``files_of_uid``), not entered."""
    if uid in (0, os.getuid()):
        raise ValueError(f"uid: expected the sandbox's own uid, got {uid}")
    stack = _roots(roots)
    while stack:
        top = stack.pop()
        try:
            entries = list(os.scandir(top))
        except OSError:
            continue
        for entry in entries:
            try:
                st = entry.stat(follow_symlinks=False)
            except OSError:
                continue
            if st.st_uid == uid:
                yield entry.path, st
            elif deep and stat.S_ISDIR(st.st_mode) and st.st_mode & stat.S_IXOTH:
                stack.append(entry.path)


def remove_files_of_uid(uid: int, roots=SHARED_TMP_DIRS, *, failed: list[str] | None = None) -> tuple[int, int]:
    """Remove everything ``uid`` owns in ``roots`` (``files_of_uid``); return (entries, bytes) removed.

    ``failed`` (a list) receives ``"<path>: <why>"`` for what could not be removed (named for
    staff; ``tree.Tally.failed``).  Nothing found there raises: a tree of any depth is removed
    without recursion (``tree.remove``), each entry only while it still belongs to ``uid``.
    Call it once the uid's processes are gone (``sweep_uid``), or new files may appear meanwhile.
    """
    done = tree.Tally()
    for path, _ in list(_owned_by(uid, roots, True)):
        done.add(tree.remove(path, owner=uid))
    if failed is not None:
        failed.extend(done.named())
    return done.entries, done.bytes
