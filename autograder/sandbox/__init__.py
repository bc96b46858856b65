"""Run a student's code in a separate, locked-down process and bring back only checked plain data.

The grader never executes student code itself.  ``Sandbox`` prepares a place (the kit packages
the student may import, an isolation level, a uid of its own); ``Sandbox.session(units)`` starts a
child there (``child.py``) that loads the student's code once and then answers calls one at a
time: "call this function on these inputs within this budget" (``session.py``).  Values cross as
JSON in the one plain-data format of ``core.wire`` (no pickle) and are judged in the grader, so a
student who patches ``numpy.allclose`` or ``builtins`` only changes the child.

Isolation, strongest available first (``Sandbox.isolation`` says which was used; ``levels.py``):

``namespaces`` (the grader runs as root, util-linux ``unshare``/``setpriv`` work)
    New pid, mount, network, ipc and uts namespaces.  Inside, still as root, a root of the code's
    own (``script.stage_script``): the system's folders and the Python installation bound
    read-only (reachable even under a private folder such as /root), a copy of the lib, a private
    /tmp, /var/tmp and /dev/shm, and nothing else of the machine's tree, so no hidden path
    (solutions/, autograder/, the output folder, the course data...) is there to be named.  Then ``setpriv`` drops to a uid of its own (no groups,
    no capabilities, no new privileges) and starts Python.  The namespace's first process stays a
    root shell that waits for Python, so killing the sandbox kills the whole namespace, daemons
    included; a sweep of /proc for the sandbox's uid is the backstop (``uids.py``).
``user-namespaces`` (not root, but unprivileged user namespaces allowed)
    The same namespaces and masks inside a user namespace; the code keeps the grader's uid.
``uid`` (root without namespaces: a container with Docker's default capabilities)
    A uid of its own and the sandbox's group (``deny.SANDBOX_GID``), no capabilities, no new
    privileges, resource limits, a new session, the /proc sweep.  Every hidden path gets an ACL
    entry that denies that group (``deny.py``), and the probe checks, as that uid, that none of
    them can be read.  The Python must be reachable without opening a private folder: a pyenv
    under /root is refused with the fix (a venv from a public Python).  There is no network
    namespace: the child refuses sockets (internet and Unix alike) and System V / POSIX IPC
    objects itself with a seccomp filter installed before any student code
    (``child.deny_internet``; no capability needed, checked by the probe); files any user may read
    stay readable (the grader writes its own files owner-only); the folders above a hidden path
    are pass-through only for that group, so no listing names one.  No private /tmp either: the
    sandbox's group may only pass through /tmp, /var/tmp and /run/lock (``deny.traverse_only``),
    /dev/shm stays writable, every child's files there are removed after it (``uids``), and its
    disk use is a quota the session checks while calls run (files its processes hold open
    or mapped after unlinking them included).
``basic`` (weak, only with ``allow_weak``)
    Resource limits, a new session killed as a group, the seccomp filter, and (as root) the
    dedicated uid plus the /proc sweep.  Hidden paths are NOT hidden: ``Isolation`` says so.

Every grader folder of the temporary directory (this Sandbox's scratch, the hidden inputs, the
canary's key) records its owner, and making a Sandbox first removes those whose owner was killed
(``leftovers.py``).

Student code never runs as root or as the grader's own user unless ``allow_weak`` is given
(``user-namespaces`` keeps the grader's uid, ``basic`` its files): without it, a machine where
only a weak level works raises ``IsolationRefused`` saying what is missing and how to fix it.

In every level: a fresh working folder (HOME) per child, with its temporary folders (TMPDIR,
XDG_RUNTIME_DIR...) beside it, removed afterwards, a minimal environment without the grader's
variables, what one request changes in the child undone before the next (``child._Leaks``), rlimits (CPU, address space, processes, file size,
open files, no core files; ``script.py``), wall-clock limits per call and per session, and
bounded reads of stdout, stderr and results.

What a child started never outlives it: after each child every process of its uid is killed,
counted by thread (a process whose leader thread exited shows as a zombie while its other threads
run), whatever session it made; a uid something still runs as after that sweep is not given to
any later child (the session takes a fresh one and tells staff, ``SessionInfo.survived``).

Modules: ``model`` (limits, isolation, outcomes), ``uids``, ``levels`` (probing), ``script``
(argv, environment, rlimits), ``session`` (the protocol's grader side), ``child`` (its child side),
``leftovers`` (the grader's temporary folders), ``tree`` (folders the code could write into,
measured and removed without recursion; what cannot be removed is named for staff, never raised).
"""

from __future__ import annotations

import compileall
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

from core.paths import KIT_ROOT
from core.shipping import NEVER_TO_STUDENTS, SANDBOX_PACKAGES, SANDBOX_WITHHELD
from core.untrusted import for_terminal

from . import leftovers, levels
from .deny import SANDBOX_GID
from .model import LEVELS, STATUSES, WEAK_LEVELS, CallOutcome, Isolation, IsolationRefused, ResourceLimits, SessionInfo
from .script import MPL_CACHE, Runtime
from .session import Session
from .uids import live_pids_of_uid, release_uid

__all__ = [
    "STATUSES",
    "CallOutcome",
    "Isolation",
    "IsolationRefused",
    "LEVELS",
    "ResourceLimits",
    "SANDBOX_GID",
    "WEAK_LEVELS",
    "Sandbox",
    "Session",
    "SessionInfo",
    "live_pids_of_uid",
]

_CHILD = Path(__file__).with_name("child.py")


class Sandbox:
    """A place to run students' code; each ``session`` is one submission.  Use as a context manager.

    Parameters
    ----------
    kit_root : path, optional
        The kit's root (default: the folder above ``autograder``).  Its ``packages`` are copied
        for the student's imports; its ``solutions``, ``autograder`` and ``tests`` are hidden.
    hidden : sequence of paths
        More paths the code must not see or write (the grader's output folder, the course data,
        hidden tests...).  Missing paths are ignored.
    packages : sequence of str
        Top-level packages of the kit the student may import (``core`` is needed by the child).
    limits : ResourceLimits
    isolation : {"auto", "namespaces", "user-namespaces", "uid", "basic"}
        "auto" takes the strongest level that works here; a named level that does not work
        raises ``IsolationRefused`` (a RuntimeError).
    allow_weak : bool
        Accept a weak level (``WEAK_LEVELS``: the code keeps the grader's uid or can read its
        files) when nothing stronger works; the result's ``Isolation.weak`` then says so.
    private_tmp : bool
        Give the code a root of its own with empty /tmp, /var/tmp and /dev/shm (namespace levels
        only).  Without it the code sees the host's tree with each hidden path covered.
    uid : int, optional
        The uid to run as when root (default: an unused one from 60000 up).
    """

    def __init__(self, kit_root: str | Path | None = None, *, hidden: Sequence[str | Path] = (),
                 packages: Sequence[str] = SANDBOX_PACKAGES, limits: ResourceLimits = ResourceLimits(),
                 isolation: str = "auto", private_tmp: bool = True, uid: int | None = None,
                 allow_weak: bool = False):
        if isolation not in ("auto",) + LEVELS:
            raise ValueError(f"isolation: expected 'auto' or one of {LEVELS}, got {isolation!r}")
        self.kit_root = Path(kit_root).resolve() if kit_root else KIT_ROOT
        self.limits = limits
        self._uid_fd: int | None = None
        self._base_fd: int | None = None
        self._owner = True
        self.runtime: Runtime | None = None
        # Every channel makes its Sandbox before grading: the time to remove what graders killed
        # with SIGKILL left behind (hidden inputs, answer keys, scratch; leftovers.py).
        # What cannot be removed is said and left: it must not stop this grader, nor every later one.
        left: list[str] = []
        leftovers.sweep(failed=left)
        _warn_left(left, "a dead grader's folders")
        # Traversable, not listable: the lib folder must be reachable by the sandbox's uid.
        self._base, self._base_fd = leftovers.owned_folder("hw4-sandbox-", mode=0o711)
        try:
            lib = self._base / "lib"
            _build_lib(lib, self.kit_root, packages)
            hidden_paths = _hidden_paths(self.kit_root, hidden)
            self.runtime, self.isolation, self._uid_fd = levels.choose(
                isolation, lib=lib, hidden=hidden_paths, private_tmp=private_tmp, limits=limits,
                scratch=self._base, uid=uid, allow_weak=allow_weak)
        except BaseException:
            self.close()
            raise

    # -- sharing with a grading process --------------------------------------------------------

    def describe(self) -> dict:
        """What another grader process needs to run sessions here (see ``attach``): plain JSON."""
        rt = self.runtime
        return {"base": str(self._base), "level": rt.level, "uid": rt.uid, "gid": rt.gid, "lib": str(rt.lib),
                "hidden": [str(p) for p in rt.hidden], "private_tmp": rt.private_tmp,
                "limits": vars(rt.limits) | {}, "isolation": self.isolation.as_dict(), "deny_internet": rt.deny_internet,
                "kit_root": str(self.kit_root)}

    @classmethod
    def attach(cls, spec: dict) -> Sandbox:
        """A Sandbox made by another process of the grader (``describe``), used without probing it
        again.  That process owns it: it keeps the uid reserved and removes the files; closing
        this one removes nothing.  ``spec`` must come from the grader (a 0700 folder of its own)."""
        box = cls.__new__(cls)
        box.kit_root = Path(spec["kit_root"])
        box.limits = ResourceLimits(**spec["limits"])
        box._uid_fd = None
        box._base_fd = None
        box._owner = False
        box._base = Path(spec["base"])
        box.runtime = Runtime(spec["level"], spec["uid"], Path(spec["lib"]), tuple(Path(p) for p in spec["hidden"]),
                              bool(spec["private_tmp"]), box.limits, spec.get("gid"), bool(spec.get("deny_internet")))
        iso = dict(spec["isolation"])
        box.isolation = Isolation(**{**iso, "hidden_paths": tuple(iso["hidden_paths"]), "notes": tuple(iso["notes"])})
        return box

    # -- lifecycle ------------------------------------------------------------------------------

    def close(self) -> None:
        """Remove the sandbox's files and free its uid (when this process made it)."""
        if not self._owner:
            return
        _warn_left(leftovers.release(self._base, self._base_fd), "the sandbox's folder")
        self._base_fd = None
        release_uid(self.runtime.uid if self.runtime else None, self._uid_fd)
        self._uid_fd = None

    def __enter__(self) -> Sandbox:  # noqa: PYI034 - Self needs Python 3.11
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- running ----------------------------------------------------------------------------

    def session(self, units, *, load_timeout: float = 60.0, budget: float = 600.0) -> Session:
        """A session with ``units`` loaded (``SourceUnit`` objects, or one source string).

        load_timeout: seconds to load the code; budget: wall-clock seconds of the whole session.
        The child starts on the first call.
        """
        if isinstance(units, str):
            payload = [{"origin": "source", "line": 1, "source": units, "future": []}]
        else:
            payload = [u.to_job() for u in units]
        json.dumps(payload)  # a grader bug if the units are not JSON
        return Session(self.runtime, self.isolation, payload, load_timeout=load_timeout, budget=budget,
                       scratch=self._base)


def _warn_left(failed: Sequence[str], what: str) -> None:
    """Tell staff (the grader's stderr) what of ``what`` could not be removed; never raises."""
    if failed:
        lines = "".join(f"\n  {for_terminal(line)}" for line in failed)
        print(f"warning: could not remove all of {what} (left in place):{lines}", file=sys.stderr)


def _build_lib(lib: Path, kit_root: Path, packages: Sequence[str]) -> None:
    lib.mkdir(mode=0o755)
    shutil.copy2(_CHILD, lib / "child.py")
    for name in packages:
        src = kit_root / name
        if not (src / "__init__.py").is_file() and not any(src.glob("*.py")):
            continue
        shutil.copytree(src, lib / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    for rel in SANDBOX_WITHHELD:
        (lib / rel).unlink(missing_ok=True)
    # Compiled here once, because the child may not write into this folder.
    compileall.compile_dir(lib, quiet=1, workers=1)
    if importlib.util.find_spec("matplotlib") is not None:
        _font_cache(lib / MPL_CACHE)
    for p in [lib, *lib.rglob("*")]:
        os.chmod(p, 0o755 if p.is_dir() else 0o644)


# The files of matplotlib's font list, made once per grader process: a batch's every Sandbox (and
# the test suite's many) would otherwise scan the same system fonts again, about 0.45 CPU s each.
_FONT_LIST: dict[str, bytes] = {}


def _font_cache(folder: Path) -> None:
    """Give ``folder`` (a matplotlib config folder for the children) the font list matplotlib makes
    on first use, so that no child scans the system fonts itself (about half a second)."""
    if not _FONT_LIST:
        subprocess.run([sys.executable, "-I", "-c", "import matplotlib.font_manager"],
                       env={"MPLCONFIGDIR": str(folder), "PATH": "/usr/bin:/bin"},
                       capture_output=True, timeout=300, check=False)
        made = {p.name: p.read_bytes() for p in folder.glob("fontlist-*.json")}
        _FONT_LIST.update(made)  # none when the scan failed: the next Sandbox tries again
        return
    folder.mkdir(exist_ok=True)
    for name, data in _FONT_LIST.items():
        (folder / name).write_bytes(data)


def _installed(pkg: str) -> list[Path]:
    """The folders this Python imports the package ``pkg`` from (none when it has none)."""
    try:
        spec = importlib.util.find_spec(pkg)
    except (ImportError, ValueError):
        spec = None
    return [Path(loc) for loc in (spec.submodule_search_locations or [])] if spec else []


def _hidden_paths(kit_root: Path, extra: Sequence[str | Path]) -> tuple[Path, ...]:
    # What never ships to students (solutions, autograder, tests, the answer-key notebooks...),
    # and the kit's history and build folders, which hold the same files.
    found = [kit_root / rel for rel in NEVER_TO_STUDENTS + SANDBOX_WITHHELD + (".git", "build")]
    for pkg in ("solutions", "autograder"):
        found.extend(_installed(pkg))
    # A withheld file wherever this Python would import its package from (an installed kit too).
    for rel in SANDBOX_WITHHELD:
        package, _, name = rel.partition("/")
        found.extend(loc / name for loc in _installed(package))
    course_data = os.environ.get("HW4_COURSE_DATA") or kit_root.parent / "shared" / "course-data"
    found.append(Path(course_data))
    found.extend(Path(p) for p in extra)
    resolved: list[Path] = []
    for p in found:
        try:
            rp = p.resolve(strict=True)
        except (OSError, RuntimeError):
            continue
        if rp != Path("/") and rp not in resolved:
            resolved.append(rp)
    # A path inside another hidden folder is already hidden (and could not be mounted on).
    return tuple(p for p in resolved if not any(q in p.parents for q in resolved))
