"""The sandbox's own uids: reserved across grader processes, their processes found and killed, and
what they left in the machine's shared temporary folders measured and removed."""

from __future__ import annotations

import fcntl
import os
import pwd
import shutil
import signal
import stat
import tempfile
import threading
import time
from pathlib import Path

__all__ = ["SHARED_TMP_DIRS", "count_processes", "files_of_uid", "live_pids_of_uid", "pick_uid", "release_uid",
           "remove_files_of_uid", "sweep_uid", "usage_of"]

# The machine's world-writable folders where code without a private /tmp can leave files behind.
SHARED_TMP_DIRS = ("/tmp", "/var/tmp", "/dev/shm", "/run/lock", "/var/lock")

_IN_USE: set[int] = set()          # uids of live Sandboxes of this process
_IN_USE_LOCK = threading.Lock()
_UID_LOCKS = Path(tempfile.gettempdir()) / "hw4-sandbox-uids"


def _uids_of(pid: str) -> tuple[set[int], str] | None:
    try:
        with open(f"/proc/{pid}/status") as fh:
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


def live_pids_of_uid(uid: int) -> list[int]:
    """Pids of the processes (not zombies) with ``uid`` among their uids."""
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            info = _uids_of(entry)
            if info and uid in info[0] and info[1] != "Z":
                out.append(int(entry))
    return out


def count_processes(uid: int) -> int:
    return len(live_pids_of_uid(uid))


def sweep_uid(uid: int, budget: float = 5.0) -> list[int]:
    """SIGKILL every live process of ``uid`` (the sandbox's own) until none is left; return them.

    Each process is opened as a pidfd and its uid re-checked before the signal, so a pid reused
    by an unrelated process in between is never signalled.
    """
    if uid == 0 or uid == os.getuid():
        raise ValueError(f"uid: expected the sandbox's own uid, got {uid}")
    killed: list[int] = []
    end = time.monotonic() + budget
    while True:
        pids = live_pids_of_uid(uid)
        if not pids or time.monotonic() > end:
            return killed
        for pid in pids:
            try:
                pfd = os.pidfd_open(pid)
            except OSError:
                continue
            try:
                info = _uids_of(str(pid))
                if info and uid in info[0]:
                    signal.pidfd_send_signal(pfd, signal.SIGKILL)
                    killed.append(pid)
            except OSError:
                pass
            finally:
                os.close(pfd)
        time.sleep(0.01)


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


def _size(st: os.stat_result) -> int:
    return st.st_blocks * 512  # what it takes on disk (or in memory): a sparse file takes little


def usage_of(path: str | os.PathLike) -> tuple[int, int]:
    """(entries, bytes) of the folder ``path`` and everything in it, links not followed."""
    count, size = 1, 0
    for top, dirs, files in os.walk(path):  # never follows links to folders
        for name in dirs + files:
            try:
                st = os.lstat(os.path.join(top, name))
            except OSError:
                continue
            count += 1
            size += _size(st)
    return count, size


def files_of_uid(uid: int, roots=SHARED_TMP_DIRS, *, deep: bool = True):
    """``[(path, is_folder, entries, bytes)]``: what ``uid`` owns in ``roots``, found by owner.

    A folder of ``uid`` counts with everything in it.  With ``deep`` the search also descends into
    other users' folders that any user may enter (a world-writable folder inside /tmp takes the
    code's files as well as /tmp does); without it only the roots' own entries are looked at.
    Symbolic links are never followed: a link the code made is itself its entry.
    """
    if uid in (0, os.getuid()):
        raise ValueError(f"uid: expected the sandbox's own uid, got {uid}")
    found = []
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
            is_dir = stat.S_ISDIR(st.st_mode)
            if st.st_uid == uid:
                n, size = usage_of(entry.path) if is_dir else (1, 0)
                found.append((entry.path, is_dir, n, size + _size(st)))
            elif deep and is_dir and st.st_mode & stat.S_IXOTH:
                stack.append(entry.path)
    return found


def remove_files_of_uid(uid: int, roots=SHARED_TMP_DIRS) -> tuple[int, int]:
    """Remove everything ``uid`` owns in ``roots`` (``files_of_uid``); return (entries, bytes) removed.

    Call it once the uid's processes are gone (``sweep_uid``), or new files may appear meanwhile.
    """
    count = size = 0
    for path, is_dir, n, b in files_of_uid(uid, roots):
        try:
            if is_dir:
                shutil.rmtree(path)  # refuses a link put in its place, never follows one inside
            else:
                os.unlink(path)
        except OSError:
            continue
        count += n
        size += b
    return count, size
