"""The grader's private temporary folders: made with their owner recorded, swept when the owner died.

A grader keeps the hidden inputs (``hw4-hidden-``), each Sandbox's scratch (``hw4-sandbox-``) and
the canary's answer key (``hw4-canary-``) in folders of its own under the temporary directory,
removed when it ends.  A grader killed with SIGKILL (or by the out-of-memory killer) cannot remove
them, so every folder records its owner twice: the pid in its name
(``hw4-sandbox-<pid>-<random>``) and an exclusive ``flock`` that the owner holds on the file
``.owner`` inside for as long as it lives (the kernel drops the lock when the process dies, so a
reused pid or another pid namespace cannot make a dead owner look alive, or the other way round).

``sweep`` removes the folders of this user whose owner is dead: the lock on ``.owner`` is free
(the file only gets that name once locked), or, for a folder without one (in the making, or
killed before its lock), its pid is not running and the folder is over a minute old.  It never
removes a folder whose owner is alive, a folder of another user, anything that is not a plain
folder (a symlink of that name is left, and not followed), nor folders named otherwise (those of
graders older than this module included).
Every channel sweeps when it makes its Sandbox (``Sandbox.__init__``), before grading.

Both remove with ``tree.remove`` (no recursion, links never followed, any depth): a folder student
code filled with a tree thousands of folders deep is removed like any other, and what cannot be
removed is returned for staff, never raised (a sweep that raised would stop every later grader
on the machine at its start).
"""

from __future__ import annotations

import fcntl
import os
import re
import stat
import tempfile
import time
from pathlib import Path

from . import tree

__all__ = ["PREFIXES", "owned_folder", "release", "sweep"]

PREFIXES = ("hw4-hidden-", "hw4-sandbox-", "hw4-canary-")
OWNER_FILE = ".owner"
_NAME = re.compile(r"^(" + "|".join(re.escape(p) for p in PREFIXES) + r")(\d+)-[A-Za-z0-9_]+$")
_YOUNG = 60.0   # seconds: a folder without its lock file yet may be in the making


def owned_folder(prefix: str, *, mode: int = 0o700) -> tuple[Path, int]:
    """``(folder, fd)``: a new folder ``<tmp>/<prefix><pid>-<random>`` (``mode``) and the open,
    exclusively locked descriptor of its ``.owner`` file.  Keep ``fd`` open while the folder is in
    use; ``release(folder, fd)`` removes the folder and closes it."""
    if prefix not in PREFIXES:
        raise ValueError(f"prefix: expected one of {PREFIXES}, got {prefix!r}")
    folder = Path(tempfile.mkdtemp(prefix=f"{prefix}{os.getpid()}-"))  # 0700 until told otherwise
    try:
        # Locked under another name, then renamed: a sweep (in another process, or another thread
        # of this one making its own Sandbox) never finds ``.owner`` unlocked while its owner lives.
        # Created and locked in place, a sweep between the two took the new folder for a dead
        # grader's and removed it (a batch's second thread then failed with FileNotFoundError).
        pending = folder / (OWNER_FILE + ".new")
        fd = os.open(pending, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)  # a new file: nobody else holds it
            os.write(fd, f"{os.getpid()}\n".encode())
            os.rename(pending, folder / OWNER_FILE)
        except BaseException:
            os.close(fd)
            raise
        os.chmod(folder, mode)
    except BaseException:
        tree.remove(folder)
        raise
    return folder, fd


def release(folder: Path | None, fd: int | None) -> list[str]:
    """Remove ``folder`` and then close its lock ``fd`` (either may be None); return what could not
    be removed (``"<path>: <why>"``, for staff; the lock is closed all the same, and a later sweep
    tries again)."""
    failed = tree.remove(folder).named() if folder is not None else []
    if fd is not None:
        try:
            os.close(fd)
        except OSError:
            pass
    return failed


def _pid_running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # EPERM: it exists, as another user
        return True
    return True


def _owner_alive(folder: Path, pid: int, made: float) -> bool:
    """Whether the grader that made ``folder`` may still use it (when unsure: yes)."""
    try:
        fd = os.open(folder / OWNER_FILE, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except FileNotFoundError:
        return _pid_running(pid) or time.time() - made < _YOUNG
    except OSError:
        return True
    try:
        # The owner holds LOCK_EX on its own open file; this process's other descriptor conflicts
        # with it too, so a grader sweeping never takes its own folders for dead ones.
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)
    return False


def sweep(root: str | os.PathLike | None = None, *, failed: list[str] | None = None) -> list[Path]:
    """Remove the grader folders in ``root`` (default: the temporary directory) that belong to
    this user and whose owner died; return them.  ``failed`` (a list) receives ``"<path>: <why>"``
    for what could not be removed (the folder stays, and the next sweep tries again)."""
    root = Path(root) if root is not None else Path(tempfile.gettempdir())
    me = os.geteuid()
    removed: list[Path] = []
    try:
        entries = list(os.scandir(root))
    except OSError:
        return removed
    for entry in entries:
        found = _NAME.match(entry.name)
        if found is None:
            continue
        try:
            st = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != me:
            continue
        path = Path(entry.path)
        if _owner_alive(path, int(found.group(2)), st.st_mtime):
            continue
        # tree.remove refuses a symlink put in its place meanwhile and never follows one inside.
        left = tree.remove(path, owner=me).named()
        if failed is not None:
            failed.extend(left)
        if not os.path.lexists(path):
            removed.append(path)
    return removed
