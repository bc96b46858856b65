"""The sandbox's own uids: reserved across grader processes, and their processes found and killed."""

from __future__ import annotations

import fcntl
import os
import pwd
import signal
import tempfile
import threading
import time
from pathlib import Path

__all__ = ["count_processes", "live_pids_of_uid", "pick_uid", "release_uid", "sweep_uid"]

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
