"""Hiding the grader's files from the sandbox by permissions, where no mount namespace can hide them.

At the ``uid`` level (root grader, no namespaces: a container with Docker's default capabilities)
student code runs under a uid of its own whose only group is ``SANDBOX_GID``.  Every hidden path
gets a POSIX ACL entry ``group:SANDBOX_GID:---``: a process of that group matches the entry and is
refused, while the owner, the file's group and every other user keep the access they had.  The
entry is idempotent, shared by every sandbox uid, and left in place (it only ever denies the
sandbox's group).  Where the filesystem has no ACLs, the path loses its "other" permission bits
instead (``chmod o-rwx``), which the result's notes say.

Nothing here trusts itself: the level's probe then tries to read every hidden path as the
sandbox's uid and refuses the level if one is readable.
"""

from __future__ import annotations

import errno
import grp
import os
import stat
import struct
from pathlib import Path

__all__ = ["SANDBOX_GID", "deny_group", "traverse_only"]

_XATTR = "system.posix_acl_access"
_VERSION = 2
_USER_OBJ, _USER, _GROUP_OBJ, _GROUP, _MASK, _OTHER = 0x01, 0x02, 0x04, 0x08, 0x10, 0x20
_UNDEFINED = 0xFFFFFFFF
_ENTRY = struct.Struct("<HHI")


def _free_gid(start: int = 59999) -> int:
    """The highest gid from ``start`` down that names no group of this machine."""
    for gid in range(start, start - 1000, -1):
        try:
            grp.getgrgid(gid)
        except KeyError:
            return gid
    raise RuntimeError(f"no free gid between {start - 1000} and {start}")


SANDBOX_GID = _free_gid()


def _entries(path: Path, mode: int) -> list[tuple[int, int, int]]:
    """The path's ACL as (tag, perm, id) entries: its own, or the one its mode bits stand for."""
    try:
        raw = os.getxattr(path, _XATTR, follow_symlinks=False)
    except OSError as exc:
        if exc.errno not in (errno.ENODATA, getattr(errno, "ENOATTR", errno.ENODATA)):
            raise
        raw = b""
    if len(raw) >= 4 and struct.unpack_from("<I", raw)[0] == _VERSION and (len(raw) - 4) % _ENTRY.size == 0:
        return [_ENTRY.unpack_from(raw, 4 + k * _ENTRY.size) for k in range((len(raw) - 4) // _ENTRY.size)]
    return [(_USER_OBJ, (mode >> 6) & 7, _UNDEFINED), (_GROUP_OBJ, (mode >> 3) & 7, _UNDEFINED),
            (_OTHER, mode & 7, _UNDEFINED)]


def _deny_acl(path: Path, gid: int, perm: int = 0) -> None:
    mode = os.lstat(path).st_mode
    entries = [e for e in _entries(path, mode) if not (e[0] == _GROUP and e[2] == gid)]
    entries.append((_GROUP, perm, gid))
    if not any(e[0] == _MASK for e in entries):
        # The mask bounds the group class; equal to the owning group's bits, it changes nobody's access.
        group_obj = next((e[1] for e in entries if e[0] == _GROUP_OBJ), (mode >> 3) & 7)
        entries.append((_MASK, group_obj, _UNDEFINED))
    entries.sort(key=lambda e: (e[0], e[2]))
    raw = struct.pack("<I", _VERSION) + b"".join(_ENTRY.pack(*e) for e in entries)
    os.setxattr(path, _XATTR, raw, follow_symlinks=False)


def deny_group(paths, gid: int = SANDBOX_GID) -> list[str]:
    """Make every path in ``paths`` unreadable to processes of group ``gid``; return notes.

    Symbolic links are left alone (their target is what counts, and it is listed by its real
    path).  A path whose filesystem has no ACLs loses its "other" permission bits.

    Raises
    ------
    OSError
        When a path can be changed neither way (a read-only filesystem, not the grader's file).
    """
    notes: list[str] = []
    for p in paths:
        p = Path(p)
        try:
            st = os.lstat(p)
        except FileNotFoundError:
            continue
        if stat.S_ISLNK(st.st_mode):
            continue
        try:
            _deny_acl(p, gid)
        except OSError as exc:
            if exc.errno not in (errno.EOPNOTSUPP, errno.ENOTSUP):
                raise
            os.chmod(p, stat.S_IMODE(st.st_mode) & ~0o007)
            notes.append(f"{p}: no ACLs on its filesystem, so it was made unreadable to other users (chmod o-rwx)")
    return notes


def traverse_only(paths, gid: int = SANDBOX_GID) -> list[str]:
    """Let processes of group ``gid`` only pass through each folder of ``paths`` (ACL ``--x``):
    neither list it nor create, rename or remove anything in it; return notes.

    For the machine's shared temporary folders (/tmp, /var/tmp, /run/lock) at the ``uid`` level:
    two sandboxes graded at once cannot leave each other files there, while the paths below them
    (the sandbox's scratch, a Python under /var/tmp) stay reachable.  For the folders above a
    hidden path: their listings would name it.  Nobody else's access
    changes.  Never falls back to changing the mode bits (that would take /tmp from every user):
    a folder whose filesystem has no ACLs stays as it was, and the notes say so.
    """
    notes: list[str] = []
    for p in paths:
        p = Path(p)
        if not p.is_dir() or p.is_symlink():
            continue
        try:
            _deny_acl(p, gid, perm=1)
        except OSError as exc:
            notes.append(f"{p} stays listable and writable as before for the sandbox ({exc.strerror or exc})")
    return notes
