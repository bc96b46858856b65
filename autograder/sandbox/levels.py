"""Choosing the isolation level: try each level, strongest first, by running a trivial program in it.

The levels, and what a level must prove before it is used:

``namespaces``       the grader is root and may make namespaces (``unshare``); the probe runs.
``user-namespaces``  the grader is not root: weak (the code keeps the grader's uid), so only with
                     ``allow_weak``.
``uid``              the grader is root without namespaces (a container with Docker's default
                     capabilities): the code runs under a uid and group of its own; the Python
                     it runs must be reachable by that uid (never a pyenv under /root), and every
                     hidden path is denied to its group (``deny.py``), which the probe checks by
                     trying to read each one as that uid.
``basic``            weak: the code may keep the grader's uid and read the grader's files; only
                     with ``allow_weak``.

When nothing strong enough works, ``choose`` raises ``IsolationRefused`` naming what each level
lacked and how to fix it.  Nothing here keeps state: ``choose`` returns the runtime that worked,
its ``Isolation`` and the lock that reserves its uid (the caller releases it).
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from . import script
from .deny import SANDBOX_GID, deny_group, traverse_only
from .model import LEVELS, WEAK_LEVELS, Isolation, IsolationRefused, ResourceLimits
from .script import Runtime
from .uids import claim_uid, pick_uid, release_uid, remove_files_of_uid, sweep_uid

__all__ = ["SHARED_TMP_DIRS_NO_WRITE", "choose", "isolation_of", "listed_parents", "python_fix"]

# The shared temporary folders the code may only pass through at the ``uid`` level (/dev/shm stays
# writable: multiprocessing makes its semaphores there).
SHARED_TMP_DIRS_NO_WRITE = ("/tmp", "/var/tmp", "/run/lock")

# Reads every path given on its command line and tries to create a file in the shared temporary
# folders; prints what it could read and where it could write, as JSON.
_READ_PROBE = """\
import json, os, socket, sys
sys.path.insert(0, sys.argv[2])
import child
net = child.install_filter(sockets=sys.argv[1] == "deny")
if net is None:
    works = child.refused_calls_that_work()
    if works:
        net = "the syscall filter let through " + ", ".join(works)
if net is None and sys.argv[1] == "deny":
    for family, what in ((socket.AF_INET, "an internet socket"), (socket.AF_UNIX, "a Unix socket")):
        if net is None:
            try:
                socket.socket(family).close()
                net = what + " could still be made"
            except PermissionError:
                pass
import numpy
seen = []
for p in sys.argv[3:]:
    try:
        if os.path.isdir(p):
            os.listdir(p)
        else:
            open(p, 'rb').close()
        seen.append(p)
    except OSError:
        pass
wrote = []
for d in ("/tmp", "/var/tmp", "/run/lock"):
    try:
        os.close(os.open(os.path.join(d, ".hw4-probe-%d" % os.getuid()), os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
        os.unlink(os.path.join(d, ".hw4-probe-%d" % os.getuid()))
        wrote.append(d)
    except OSError:
        pass
print('sandbox-ok ' + json.dumps([os.getuid(), os.getgid(), seen, net, wrote]))
"""


def isolation_of(rt: Runtime, notes: tuple[str, ...] = (), weak: bool = False) -> Isolation:
    """What a runtime isolates, in the words of the results."""
    namespaced = rt.namespaced
    extra = []
    net = ("sockets (internet and Unix sockets alike) and System V and POSIX IPC objects are refused by a "
           "seccomp filter (checked; socketpair() and pipes work)" if rt.deny_internet
           else "the network and local Unix sockets stay reachable")
    if rt.level == "uid":
        extra.append(f"no namespaces here: the hidden paths are unreadable to the code's uid (checked), {net}, "
                     "and files that other users may read stay readable")
        extra.append("the code's temporary folders are in its scratch folder; /tmp, /var/tmp and /run/lock only "
                     "let it pass through (checked), /dev/shm stays writable (multiprocessing's semaphores), so "
                     "submissions graded at the same time could exchange files there; what its uid leaves in any "
                     "of them is removed after each child; its disk use is a quota checked while calls run")
    elif not namespaced:
        extra.append(f"hidden paths stay readable at this level; {net}")
    if rt.uid is None:
        extra.append("the code runs as the grader's own user")
    extra.append("keyrings, memfd files, new namespaces, userfaultfd, perf events and BPF are refused by a "
                 "seccomp filter (checked)")
    hidden = tuple(str(p) for p in rt.hidden) if namespaced or rt.level == "uid" else ()
    return Isolation(rt.level, rt.uid, namespaced, namespaced, namespaced and rt.private_tmp, hidden,
                     notes + tuple(extra), weak)


def python_fix() -> str:
    """What to do when this Python lies under a folder other users cannot enter."""
    blocked = script.unreachable_python_dirs()
    where = ", ".join(f"{top} (mode {os.stat(top).st_mode & 0o777:o}) holds {', '.join(map(str, kept))}"
                      for top, kept in blocked.items())
    return (f"the Python running the grader ({sys.executable}) lies under a folder the sandbox's user cannot "
            f"enter: {where}. Fix: make a virtual environment from a public Python and grade with it, e.g. "
            f"`/usr/bin/python3 -m venv /opt/hw4-venv && /opt/hw4-venv/bin/pip install -r requirements.txt && "
            f"/opt/hw4-venv/bin/pip install -e .`, then run `/opt/hw4-venv/bin/python -m autograder ...` "
            f"(or grade where namespaces work: as root with CAP_SYS_ADMIN)")


def choose(requested: str, *, lib: Path, hidden: tuple[Path, ...], private_tmp: bool, limits: ResourceLimits,
           scratch: Path, uid: int | None = None, allow_weak: bool = False
           ) -> tuple[Runtime, Isolation, int | None]:
    """(runtime, isolation, uid lock fd) of the strongest level that works ("auto") or of ``requested``.

    A weak level (``WEAK_LEVELS``) is tried only with ``allow_weak``.

    Raises
    ------
    IsolationRefused
        When the requested level (or, for "auto", every level allowed) does not work here; the
        message says why for each and how to fix it.
    """
    notes: list[str] = []
    candidates = LEVELS if requested == "auto" else (requested,)
    for level in candidates:
        if level in WEAK_LEVELS and not allow_weak and not (level == "user-namespaces" and os.geteuid() == 0):
            why = ("the code would keep the grader's own uid" if level == "user-namespaces"
                   else "the code could read the grader's files (and may keep its uid)")
            notes.append(f"{level} not tried: it is weak ({why}); pass --allow-weak-isolation to accept it")
            continue
        reason, found = _try_level(level, uid, lib, hidden, private_tmp, limits, scratch, notes)
        if reason is None:
            rt, fd = found
            return rt, isolation_of(rt, tuple(notes), weak=level in WEAK_LEVELS), fd
        notes.append(f"{level} unavailable: {reason}")
    head = (f"isolation: {requested} does not work here" if requested != "auto"
            else "isolation: no level safe enough works here, so nothing is graded")
    raise IsolationRefused(head + ": " + "; ".join(notes))


def listed_parents(hidden) -> list[Path]:
    """The folders whose listing would name a hidden path at the ``uid`` level: every folder
    above one, but the root, the shared temporary folders (already pass-through), and the folders
    Python lists to import from: this Python's, and a package's (an editable install of the kit
    imports ``starter`` from the kit's own folder)."""
    pythons = [p.resolve() for p in script.python_dirs()]
    out: set[Path] = set()
    for p in hidden:
        for folder in Path(os.path.abspath(p)).parents:
            if folder == Path("/") or str(folder) in SHARED_TMP_DIRS_NO_WRITE:
                continue
            if any(folder == q or q in folder.parents for q in pythons) or (folder / "__init__.py").is_file():
                continue
            out.add(folder)
    return sorted(out)


def _try_level(level, uid, lib, hidden, private_tmp, limits, scratch, notes):
    """(None, (runtime, uid fd)) when ``level`` works, else (the reason, None)."""
    root = os.geteuid() == 0
    if level in ("namespaces", "uid") and not root:
        return "the grader is not root (only root can run the code under a uid of its own)", None
    if level == "user-namespaces" and root:
        # Mapped to root inside, the code would keep the grader's real uid: never choose it
        # silently when a real unprivileged uid is available at the basic level.
        return "the grader is root, so the code would run as root", None
    if level in ("namespaces", "user-namespaces"):
        for tool in ("unshare", "mount") + (("setpriv",) if level == "namespaces" else ()):
            if shutil.which(tool) is None:
                return f"{tool} is not installed", None
    gid = None
    if level == "uid":
        if script.unreachable_python_dirs():
            # Without a mount namespace nothing can make a private Python reachable to another uid
            # short of opening the private folder, which would open everything else in it.
            return python_fix(), None
        try:
            notes.extend(deny_group(hidden, SANDBOX_GID))
            # No namespace gives the code a /tmp of its own: it may not write into the shared ones
            # (two sandboxes of a --jobs batch would meet there); its temporary folders are in its scratch.
            notes.extend(traverse_only(SHARED_TMP_DIRS_NO_WRITE, SANDBOX_GID))
            # Denied, a hidden path is still named by its folder's listing: those folders are
            # passed through, not listed (never a folder Python lists to import from).
            notes.extend(traverse_only(listed_parents(hidden), SANDBOX_GID))
        except OSError as exc:
            return (f"the hidden paths could not be made unreadable to the sandbox's group ({exc}); run the "
                    f"grader as the owner of its files, on a writable filesystem"), None
        gid = SANDBOX_GID
    want_uid = root and level != "user-namespaces"
    if want_uid and level == "basic" and script.unreachable_python_dirs():
        notes.append("basic: Python is installed under a private folder, so the code keeps the grader's uid")
        want_uid = False
    the_uid, fd = None, None
    if want_uid:
        if uid is not None:
            the_uid = uid
            claim_uid(uid)
        else:
            the_uid, fd = pick_uid()
    # Without a network namespace, the child refuses internet sockets itself (seccomp), when the
    # probe shows the filter works here.
    rt = Runtime(level, the_uid, lib, hidden, private_tmp, limits, gid, deny_internet=level in ("uid", "basic"))
    reason, net, tmp_note = _probe(rt, scratch)
    if rt.deny_internet and (reason is not None or net is not None):
        plain = dataclasses.replace(rt, deny_internet=False)
        plain_reason, plain_net, tmp_note = _probe(plain, scratch)
        if plain_reason is None and plain_net is None:
            # The sockets' part of the filter is what failed: the level works, the network stays reachable.
            notes.append(f"{level}: internet sockets could not be refused ({net or reason})")
            rt, reason, net = plain, None, None
    if reason is None and net is not None:
        # The part of the filter every level needs (keyrings, memfd, namespaces) did not hold.
        reason = f"the sandbox's syscall filter does not work here ({net})"
    if reason is not None:
        release_uid(the_uid, fd)
        return reason, None
    if tmp_note:
        notes.append(tmp_note)
    return None, (rt, fd)


def _probe(rt: Runtime, scratch: Path) -> tuple[str | None, str | None, str | None]:
    """``(reason, net, tmp)``: reason is None when a trivial program runs in ``rt`` (at the ``uid``
    level: as its uid, reading none of the hidden paths), else why not; net is None when the seccomp
    filter (``child.install_filter``) was installed and refused what it must (keyrings, memfd,
    namespaces; with ``rt.deny_internet`` an internet and a Unix socket too), else why not; tmp (``uid`` level) names the shared temporary folders the code
    could still create files in, else None."""
    jobdir = Path(tempfile.mkdtemp(prefix="probe", dir=scratch))
    os.chmod(jobdir, 0o711)
    try:
        workdir = script.make_workdir(rt, jobdir)
        program = [sys.executable, "-I", "-B", "-c", _READ_PROBE, "deny" if rt.deny_internet else "-",
                   str(rt.lib_inside()), *[str(p) for p in rt.hidden]]
        try:
            proc = subprocess.run(script.command(rt, workdir, program, jobdir), capture_output=True, timeout=60,
                                  stdin=subprocess.DEVNULL, check=False, **script.popen_options(rt, workdir, 60))
        except (OSError, subprocess.SubprocessError) as exc:
            return f"{type(exc).__name__}: {exc}", None, None
        out = proc.stdout.decode(errors="replace")
        if proc.returncode != 0 or "sandbox-ok " not in out:
            tail = proc.stderr.decode(errors="replace").strip().splitlines()[-1:] or [f"exit code {proc.returncode}"]
            return tail[0][:300], None, None
        got_uid, got_gid, seen, net, wrote = json.loads(out.split("sandbox-ok ", 1)[1].splitlines()[0])
        if rt.uid is not None and (got_uid != rt.uid or got_uid in (0, os.getuid())):
            return f"the code ran as uid {got_uid}, not the sandbox's {rt.uid}", None, None
        if rt.level == "uid" and seen:
            return (f"the sandbox's uid can still read {', '.join(seen[:5])}; make these paths unreadable to "
                    f"other users (chmod o-rwx) or grade where namespaces work"), None, None
        if rt.level == "uid" and wrote:
            return None, net, f"uid: the code can still create files in {', '.join(wrote)} (no ACL took)"
        return None, net, None
    finally:
        shutil.rmtree(jobdir, ignore_errors=True)
        if rt.uid is not None:
            sweep_uid(rt.uid)
            remove_files_of_uid(rt.uid, rt.shared_tmp_dirs())
