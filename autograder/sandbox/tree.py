"""Folders student code could write into, measured and removed without recursion or following links.

``shutil.rmtree`` and ``os.walk`` recurse once per level: Python 3.11 raises RecursionError on a
tree about a thousand folders deep, which a submission makes in a second, and a path string past
PATH_MAX (4096 bytes) cannot even be opened.  Here a tree is walked with descriptors: each folder
is opened relative to its parent's descriptor with ``O_NOFOLLOW | O_DIRECTORY``, listed with
``os.scandir`` on that descriptor, and its entries are removed with ``dir_fd``.  Only the folder
being listed is open (plus the top's parent): the walk goes back up by opening ``..`` and checks
that it reached the folder it came from (its ``(st_dev, st_ino)``); if something moved the tree
meanwhile, it opens the chain again from the top by name, checking each step, or stops.

Nothing here raises for what it finds in the tree: what could not be read or removed is returned
(``Tally.failed``, named for staff), so a clean-up never stops the grading of the class.  A
symbolic link is an entry like a file (removed or counted, never followed); a folder on another
filesystem (a mount point) is neither entered nor removed, and is named in ``failed``.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass, field

__all__ = ["Tally", "disk_bytes", "remove", "usage"]

_MAX_NAMED = 20          # what could not be removed, named one by one; the rest are counted
_MAX_NAME_CHARS = 240    # a name past this is shortened in the middle (a path 5,000 folders deep)
_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC


@dataclass
class Tally:
    """What a walk found or removed.

    entries: files, links and folders (the top included); bytes: the disk (or memory) they take,
    ``st_blocks * 512``; failed: ``"<path>: <why>"`` of what could not be read or removed, at most
    20 named (``failures`` counts them all).  Only the deepest failure of a branch is named: the
    folders above it that could not be removed because it is still there are not.
    """

    entries: int = 0
    bytes: int = 0
    failed: list[str] = field(default_factory=list)
    failures: int = 0

    def add(self, other: Tally) -> None:
        self.entries += other.entries
        self.bytes += other.bytes
        for line in other.failed:
            if len(self.failed) < _MAX_NAMED:
                self.failed.append(line)
        self.failures += other.failures

    def named(self) -> list[str]:
        """``failed``, and a last line counting the failures not named, if any."""
        more = self.failures - len(self.failed)
        return self.failed + ([f"... and {more} more"] if more > 0 else [])

    def fail(self, path: str, why: str) -> None:
        self.failures += 1
        if len(self.failed) < _MAX_NAMED:
            self.failed.append(f"{_short(path)}: {why}")


def usage(path: str | os.PathLike) -> Tally:
    """Entries and bytes of ``path`` and, for a folder, everything in it (links not followed)."""
    return _walk(os.fspath(path), remove=False, owner=None)


def remove(path: str | os.PathLike, *, owner: int | None = None) -> Tally:
    """Remove ``path`` (a folder with everything in it, a file or a link; links never followed);
    return what was removed and what could not be.

    ``owner``: remove ``path`` only if it still belongs to that uid when it is opened (it was
    found by owner, and a process may have put something else in its place).  A missing
    ``path`` is no failure (nothing to remove).
    """
    return _walk(os.fspath(path), remove=True, owner=owner)


def disk_bytes(st: os.stat_result) -> int:
    """What an entry takes on disk (or in memory, on a tmpfs): a sparse file takes little."""
    return st.st_blocks * 512


def _short(path: str) -> str:
    if len(path) <= _MAX_NAME_CHARS:
        return path
    half = _MAX_NAME_CHARS // 2
    return f"{path[:half]}/.../{path[-half:].split('/', 1)[-1]} ({path.count('/')} levels)"


def _why(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__


class _Frame:
    """A folder on the way down: its name in its parent, identity, size, and subfolders left to enter."""

    __slots__ = ("name", "key", "size", "pending", "failed")

    def __init__(self, name: str, st: os.stat_result):
        self.name, self.key, self.size = name, (st.st_dev, st.st_ino), disk_bytes(st)
        self.pending: list[tuple[str, os.stat_result]] = []
        self.failed = False  # something inside could not be read or removed (and is named)


def _walk(path: str, *, remove: bool, owner: int | None) -> Tally:
    tally = Tally()
    head, name = os.path.split(path.rstrip("/") or "/")
    if not name or name in (".", ".."):
        raise ValueError(f"path: expected a file or folder below another, got {path!r}")
    try:
        parent = os.open(head or ".", os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except FileNotFoundError:
        return tally
    except OSError as exc:
        tally.fail(path, _why(exc))
        return tally
    try:
        st = os.stat(name, dir_fd=parent, follow_symlinks=False)
        if owner is not None and st.st_uid != owner:
            tally.fail(path, f"no longer belongs to uid {owner}")
        elif stat.S_ISDIR(st.st_mode):
            _tree(parent, path, name, st, tally, remove)
        else:
            if remove:
                os.unlink(name, dir_fd=parent)
            tally.entries, tally.bytes = 1, disk_bytes(st)
    except FileNotFoundError:
        pass  # gone already: nothing to count or remove
    except OSError as exc:
        tally.fail(path, _why(exc))
    finally:
        os.close(parent)
    return tally


def _open_dir(dir_fd: int, name: str, st: os.stat_result) -> int:
    """``name`` in ``dir_fd``, opened as the very folder ``st`` describes (else OSError)."""
    fd = os.open(name, _DIR_FLAGS, dir_fd=dir_fd)
    got = os.fstat(fd)
    if (got.st_dev, got.st_ino) != (st.st_dev, st.st_ino):
        os.close(fd)
        raise OSError(0, "replaced while being walked")
    return fd


def _tree(parent: int, top: str, name: str, st: os.stat_result, tally: Tally, remove: bool) -> None:
    """Walk (and with ``remove``, empty and remove) the folder ``name`` of ``parent``, depth first,
    with one descriptor open at a time besides ``parent``."""
    fd = _open_dir(parent, name, st)
    root = _Frame(name, st)
    stack = [root]

    def where() -> str:  # built only to name a failure: a path 5,000 folders deep is long
        return top + "".join("/" + f.name for f in stack[1:])

    try:
        _list(fd, root, st.st_dev, tally, remove, where)
        while len(stack) > 1 or root.pending:
            frame = stack[-1]
            if frame.pending:
                sub, sub_st = frame.pending.pop()
                try:
                    child = _open_dir(fd, sub, sub_st)
                except FileNotFoundError:
                    continue
                except OSError as exc:
                    tally.fail(f"{where()}/{sub}", _why(exc))
                    frame.failed = True
                    continue
                os.close(fd)
                fd = child
                stack.append(_Frame(sub, sub_st))
                _list(fd, stack[-1], st.st_dev, tally, remove, where)
                continue
            done = stack.pop()
            try:
                up = _up(fd, stack[-1].key)
            except OSError:
                up = None
            if up is None:
                # The tree was moved while being walked: find the way down again from the top.
                up = _reopen(parent, stack)
                if up is None:
                    tally.fail(where(), "moved while being walked; the rest of this folder was left")
                    root.failed = True
                    return
            os.close(fd)
            fd = up
            if remove:
                try:
                    os.rmdir(done.name, dir_fd=fd)
                except FileNotFoundError:
                    continue
                except OSError as exc:
                    if not done.failed:  # else what is still inside was named already
                        tally.fail(f"{where()}/{done.name}", _why(exc))
                    stack[-1].failed = True
                    continue
            tally.entries += 1
            tally.bytes += done.size
    finally:
        os.close(fd)
        if remove and len(stack) == 1:
            try:
                os.rmdir(name, dir_fd=parent)
            except FileNotFoundError:
                pass
            except OSError as exc:
                if not root.failed:
                    tally.fail(top, _why(exc))
            else:
                tally.entries += 1
                tally.bytes += root.size
        elif not remove and len(stack) == 1:
            tally.entries += 1
            tally.bytes += root.size


def _list(fd: int, frame: _Frame, device: int, tally: Tally, remove: bool, where) -> None:
    """Look at every entry of the open folder ``fd``: count it, remove what is not a folder (with
    ``remove``), and keep its subfolders on ``frame.pending`` (entered later, one at a time)."""
    try:
        with os.scandir(fd) as it:
            entries = list(it)
    except OSError as exc:
        tally.fail(where(), _why(exc))
        frame.failed = True
        return
    for entry in entries:
        try:
            est = entry.stat(follow_symlinks=False)
        except FileNotFoundError:
            continue
        except OSError as exc:
            tally.fail(f"{where()}/{entry.name}", _why(exc))
            frame.failed = True
            continue
        if stat.S_ISDIR(est.st_mode):
            if est.st_dev != device:
                tally.fail(f"{where()}/{entry.name}", "another filesystem is mounted there")
                frame.failed = True
            else:
                frame.pending.append((entry.name, est))
            continue
        if remove:
            try:
                os.unlink(entry.name, dir_fd=fd)
            except FileNotFoundError:
                continue
            except OSError as exc:
                tally.fail(f"{where()}/{entry.name}", _why(exc))
                frame.failed = True
                continue
        tally.entries += 1
        tally.bytes += disk_bytes(est)


def _up(fd: int, key: tuple[int, int]) -> int | None:
    """The parent of the open folder ``fd``, if it is the folder ``key`` (else None)."""
    up = os.open("..", _DIR_FLAGS, dir_fd=fd)
    got = os.fstat(up)
    if (got.st_dev, got.st_ino) != key:
        os.close(up)
        return None
    return up


def _reopen(parent: int, stack: list[_Frame]) -> int | None:
    """The folder ``stack[-1]``, opened again from ``parent`` down the names of ``stack``, each
    step checked against the identity recorded on the way down; None when the chain is broken."""
    fd = parent
    for frame in stack:
        try:
            nxt = os.open(frame.name, _DIR_FLAGS, dir_fd=fd)
        except OSError:
            nxt = None
        if fd != parent:
            os.close(fd)
        if nxt is None:
            return None
        got = os.fstat(nxt)
        if (got.st_dev, got.st_ino) != frame.key:
            os.close(nxt)
            return None
        fd = nxt
    return fd
