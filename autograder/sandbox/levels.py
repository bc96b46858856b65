"""Choosing the isolation level: try each level, strongest first, by running a trivial program in it.

Nothing here keeps state: ``choose`` returns the runtime that worked, its ``Isolation`` and the
lock that reserves its uid (the caller releases it).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from . import script
from .model import LEVELS, Isolation, ResourceLimits
from .script import Runtime
from .uids import claim_uid, pick_uid, release_uid, sweep_uid

__all__ = ["choose", "isolation_of"]


def isolation_of(rt: Runtime, notes: tuple[str, ...] = ()) -> Isolation:
    """What a runtime isolates, in the words of the results."""
    namespaced = rt.namespaced
    extra = []
    if not namespaced:
        extra.append("hidden paths stay readable and the network reachable at this level")
    if rt.uid is None:
        extra.append("the code runs as the grader's own user")
    return Isolation(rt.level, rt.uid, namespaced, namespaced, namespaced and rt.private_tmp,
                     tuple(str(p) for p in rt.hidden) if namespaced else (), notes + tuple(extra))


def choose(requested: str, *, lib: Path, hidden: tuple[Path, ...], private_tmp: bool, limits: ResourceLimits,
           scratch: Path, uid: int | None = None) -> tuple[Runtime, Isolation, int | None]:
    """(runtime, isolation, uid lock fd) of the strongest level that works ("auto") or of ``requested``.

    Raises
    ------
    RuntimeError
        When the requested level (or, for "auto", every level) does not work here.
    """
    notes: list[str] = []
    candidates = LEVELS if requested == "auto" else (requested,)
    for level in candidates:
        reason, found = _try_level(level, uid, lib, hidden, private_tmp, limits, scratch, notes)
        if reason is None:
            rt, fd = found
            return rt, isolation_of(rt, tuple(notes)), fd
        notes.append(f"{level} unavailable: {reason}")
        if requested != "auto":
            raise RuntimeError(f"isolation: {level} does not work here ({reason})")
    raise RuntimeError("isolation: no level works here: " + "; ".join(notes))


def _try_level(level, uid, lib, hidden, private_tmp, limits, scratch, notes):
    """(None, (runtime, uid fd)) when ``level`` works, else (the reason, None)."""
    root = os.geteuid() == 0
    if level == "namespaces" and not root:
        return "the grader is not root", None
    if level == "user-namespaces" and root:
        # Mapped to root inside, the code would keep the grader's real uid: never choose it
        # silently when a real unprivileged uid is available at the basic level.
        return "the grader is root, so the code would run as root", None
    if level != "basic":
        for tool in ("unshare", "mount") + (("setpriv",) if level == "namespaces" else ()):
            if shutil.which(tool) is None:
                return f"{tool} is not installed", None
    want_uid = root and level != "user-namespaces"
    if want_uid and level == "basic" and script.unreachable_python_dirs():
        # Without a mount namespace nothing can make a private Python reachable to another uid.
        notes.append("basic: Python is installed under a private folder, so the code keeps the grader's uid")
        want_uid = False
    the_uid, fd = None, None
    if want_uid:
        if uid is not None:
            the_uid = uid
            claim_uid(uid)
        else:
            the_uid, fd = pick_uid()
    rt = Runtime(level, the_uid, lib, hidden, private_tmp, limits)
    reason = _probe(rt, scratch)
    if reason is not None:
        release_uid(the_uid, fd)
        return reason, None
    return None, (rt, fd)


def _probe(rt: Runtime, scratch: Path) -> str | None:
    """None when a trivial program runs in ``rt``, else the reason."""
    jobdir = Path(tempfile.mkdtemp(prefix="probe", dir=scratch))
    os.chmod(jobdir, 0o711)
    try:
        workdir = script.make_workdir(rt, jobdir)
        program = [sys.executable, "-I", "-B", "-c", "import numpy; print('sandbox-ok')"]
        try:
            proc = subprocess.run(script.command(rt, workdir, program), capture_output=True, timeout=60,
                                  stdin=subprocess.DEVNULL, check=False, **script.popen_options(rt, workdir, 60))
        except (OSError, subprocess.SubprocessError) as exc:
            return f"{type(exc).__name__}: {exc}"
        if proc.returncode != 0 or b"sandbox-ok" not in proc.stdout:
            tail = proc.stderr.decode(errors="replace").strip().splitlines()[-1:] or [f"exit code {proc.returncode}"]
            return tail[0][:300]
        return None
    finally:
        shutil.rmtree(jobdir, ignore_errors=True)
        if rt.uid is not None:
            sweep_uid(rt.uid)
