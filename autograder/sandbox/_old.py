"""Run a student's code in a separate, locked-down process and bring back only checked plain data.

The grader never executes student code itself: it starts ``child.py`` in a sandbox, sends it the
student's definitions and a list of calls, and reads one record per call from a dedicated pipe.
Judging happens afterwards, in the grader, on values decoded by ``wire.py`` (no pickle).  So a
student who patches ``numpy.allclose`` or ``builtins`` only changes the child.

Isolation, strongest available first (``Sandbox.isolation`` says which was used):

``namespaces`` (the grader runs as root, util-linux ``unshare``/``setpriv`` work)
    New pid, mount, network, ipc and uts namespaces.  Inside, still as root: an empty read-only
    tmpfs over every hidden path (solutions/, autograder/, the output folder, the course data...),
    a private /tmp, /var/tmp and /dev/shm, and the Python installation made reachable if it sits
    under a private folder such as /root.  Then ``setpriv`` drops to a uid of its own (no groups,
    no capabilities, no new privileges) and starts Python.  The namespace's first process stays a
    root shell that waits for Python, so killing the sandbox kills the whole namespace, daemons
    included; a sweep of /proc for the sandbox's uid is the backstop.
``user-namespaces`` (not root, but unprivileged user namespaces allowed)
    The same namespaces and masks inside a user namespace; the code keeps the grader's uid.
``basic``
    Resource limits, a new session killed as a group, and (as root) the dedicated uid plus the
    /proc sweep.  Hidden paths are NOT hidden and the network is NOT cut: ``Isolation`` says so.

In every level: a fresh working folder (HOME) removed afterwards, a minimal environment without
the grader's variables, rlimits (CPU, address space, processes, file size, open files, no core
files), wall-clock limits per call and per job, and bounded reads of stdout, stderr and results.

A call that times out, crashes the child or returns something unreadable gets that status; the
child is then restarted for the remaining calls, so a failure only affects the calls concerned.
"""

from __future__ import annotations

import compileall
import ctypes
import fcntl
import importlib.util
import json
import math
import os
import pwd
import resource
import selectors
import shlex
import shutil
import signal
import site
import stat
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from . import wire
from .submission import SourceUnit

__all__ = [
    "STATUSES",
    "Call",
    "CallOutcome",
    "Isolation",
    "Job",
    "JobResult",
    "ResourceLimits",
    "Sandbox",
    "run_job",
]

STATUSES = ("ok", "exception", "timeout", "crashed", "missing", "malformed")
_CHILD_STATUSES = {"ok", "exception", "timeout", "missing", "malformed"}
_LEVELS = ("namespaces", "user-namespaces", "basic")
_CHILD = Path(__file__).with_name("child.py")
_RESULT_FD_MIN = 100   # above the fds 3..9 the namespace's shell uses
_STAGE_FD_MAX = 9      # a POSIX shell redirects only single-digit fds
_MAX_LINE_SLACK = 2**20
_MPL_CACHE = "mplconfig"
_PR_SET_PDEATHSIG = 1
try:
    # Loaded here: after fork, in the pre-exec hook, nothing should need to be imported.
    _LIBC = ctypes.CDLL(None, use_errno=True)
except OSError:  # pragma: no cover - non-glibc systems
    _LIBC = None


@dataclass(frozen=True)
class ResourceLimits:
    """Limits of one sandboxed process tree.

    memory_bytes: RLIMIT_AS of each process; processes: RLIMIT_NPROC (for the sandbox's own
    uid, threads included); file_bytes: RLIMIT_FSIZE; open_files: RLIMIT_NOFILE; tmp_bytes: size
    of the private /tmp (namespace levels); output_bytes: how much of stdout and of stderr is
    kept; result_bytes: largest encoded result; grace: seconds the grader waits beyond a call's
    own limit before killing the child (the child stops a call itself first).
    """

    memory_bytes: int = 3 * 2**30
    processes: int = 64
    file_bytes: int = 64 * 2**20
    open_files: int = 256
    tmp_bytes: int = 256 * 2**20
    output_bytes: int = 64 * 1024
    result_bytes: int = 64 * 2**20
    grace: float = 2.0


@dataclass(frozen=True)
class Call:
    """One call of a student function: ``function(*args, **kwargs)``.

    id: unique within the job; args, kwargs: plain data (see ``wire``): numeric arrays, numbers,
    strings and lists/tuples/dicts of them; timeout: seconds (None: the job's ``call_timeout``).
    """

    id: str
    function: str
    args: Sequence[Any] = ()
    kwargs: dict[str, Any] = field(default_factory=dict)
    timeout: float | None = None


@dataclass(frozen=True)
class Job:
    """The code to load and the calls to make.

    units: the student's code: ``SourceUnit`` objects (see ``submission.py``) or one source
    string; calls: run in order in one process (restarted after a crash or timeout);
    call_timeout: default seconds per call; load_timeout: seconds to load the units;
    job_timeout: wall-clock limit of the whole job (None: load + all calls + a margin).
    """

    units: Sequence[SourceUnit] | str
    calls: Sequence[Call]
    call_timeout: float = 10.0
    load_timeout: float = 60.0
    job_timeout: float | None = None


@dataclass(frozen=True)
class CallOutcome:
    """What became of one call.

    status: one of ``STATUSES``; value: the decoded return value when status is "ok";
    message: for the other statuses, a short text for the student (the student's exception
    type and message with the line of their code, never a grader traceback); seconds: run time
    (as the child measured it for calls that returned, so informative only).
    """

    id: str
    status: str
    value: Any = None
    message: str = ""
    seconds: float | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"


@dataclass(frozen=True)
class Isolation:
    """How the code was isolated (reported in the results).

    level: "namespaces", "user-namespaces" or "basic"; uid: the uid the code ran as (None: the
    grader's own); pid_namespace, network_isolated, private_tmp: what those words say;
    hidden_paths: paths the code could not see (empty when the level cannot hide paths);
    notes: why a stronger level was not used, and other caveats.
    """

    level: str
    uid: int | None
    pid_namespace: bool
    network_isolated: bool
    private_tmp: bool
    hidden_paths: tuple[str, ...]
    notes: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        return asdict(self)

    def summary(self) -> str:
        parts = [self.level]
        parts.append(f"uid {self.uid}" if self.uid is not None else "grader's uid")
        parts.append("network cut" if self.network_isolated else "network NOT cut")
        parts.append(f"{len(self.hidden_paths)} paths hidden" if self.hidden_paths else "nothing hidden")
        return ", ".join(parts)


@dataclass(frozen=True)
class JobResult:
    """Outcomes of a job, by call id in call order, and what happened around them.

    load_errors: (origin, message) of units that failed to load; defined: the functions and
    classes the loaded code defines; stdout, stderr: bounded, untrusted copies of what the child
    printed (for the instructor, never for judging); spawns: child processes started; swept:
    processes the final /proc sweep had to kill (0 when the namespace already ended them all).
    """

    outcomes: dict[str, CallOutcome]
    load_errors: tuple[tuple[str, str], ...]
    defined: tuple[str, ...]
    stdout: str
    stderr: str
    isolation: Isolation
    seconds: float
    spawns: int
    swept: int = 0

    def __getitem__(self, call_id: str) -> CallOutcome:
        return self.outcomes[call_id]


# ------------------------------------------------------------------------------------------------


class Sandbox:
    """A reusable place to run jobs; runs one job at a time.  Use as a context manager.

    Parameters
    ----------
    kit_root : path, optional
        The kit's root (default: the folder above ``autograder``).  Its ``packages`` are copied
        for the student's imports; its ``solutions``, ``autograder`` and ``tests`` are hidden.
    hidden : sequence of paths
        More paths the code must not see or write (the grader's output folder, the course data,
        hidden tests...).  Missing paths are ignored.
    packages : sequence of str
        Top-level packages of the kit the student may import.
    limits : ResourceLimits
    isolation : {"auto", "namespaces", "user-namespaces", "basic"}
        "auto" takes the strongest level that works here; a named level that does not work
        raises RuntimeError.
    private_tmp : bool
        Give the code its own empty /tmp, /var/tmp and /dev/shm (namespace levels only).
    uid : int, optional
        The uid to run as when root (default: an unused one from 60000 up).
    """

    _uids_in_use: ClassVar[set[int]] = set()  # uids of live Sandboxes of this process
    _uids_lock: ClassVar[threading.Lock] = threading.Lock()

    def __init__(self, kit_root: str | Path | None = None, *, hidden: Sequence[str | Path] = (),
                 packages: Sequence[str] = ("core", "starter", "scenes"), limits: ResourceLimits = ResourceLimits(),
                 isolation: str = "auto", private_tmp: bool = True, uid: int | None = None):
        if isolation not in ("auto",) + _LEVELS:
            raise ValueError(f"isolation: expected 'auto' or one of {_LEVELS}, got {isolation!r}")
        self.kit_root = Path(kit_root).resolve() if kit_root else Path(__file__).resolve().parents[1]
        self.limits = limits
        self._lock = threading.Lock()
        self._jobs = 0
        self._swept = 0
        self._uid: int | None = None
        self._uid_fd: int | None = None
        self._base = Path(tempfile.mkdtemp(prefix="hw4-sandbox-"))
        try:
            os.chmod(self._base, 0o711)  # traversable, not listable: the lib folder must be reachable
            self._lib = self._base / "lib"
            self._build_lib(packages)
            self._hidden = self._hidden_paths(hidden)
            self._private_tmp = private_tmp
            self.isolation = self._choose(isolation, uid)
        except BaseException:
            self.close()
            raise

    # -- lifecycle --------------------------------------------------------------------------

    def close(self) -> None:
        """Remove the sandbox's files and free its uid."""
        shutil.rmtree(self._base, ignore_errors=True)
        self._release_uid()

    def __enter__(self) -> Sandbox:  # noqa: PYI034 - Self needs Python 3.11
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- running ----------------------------------------------------------------------------

    def run(self, job: Job) -> JobResult:
        """Run ``job`` and return every call's outcome (never raises for student behaviour).

        Raises
        ------
        ValueError
            When the job itself is malformed (duplicate call ids, arguments that are not plain
            data): a grader bug, not a student's.
        """
        calls = list(job.calls)
        ids = [c.id for c in calls]
        if len(set(ids)) != len(ids) or not all(isinstance(i, str) and i for i in ids):
            raise ValueError(f"job.calls: expected unique non-empty str ids, got {ids}")
        encoded = {c.id: self._encode_call(c, job) for c in calls}
        units = ([{"origin": "source", "line": 1, "source": job.units, "future": []}]
                 if isinstance(job.units, str) else [u.to_job() for u in job.units])
        total_calls = sum(e["timeout"] for e in encoded.values())
        budget = job.job_timeout if job.job_timeout is not None else (
            job.load_timeout + total_calls + 10 + self.limits.grace * (len(calls) + 1))

        with self._lock:
            start = time.monotonic()
            job_deadline = start + budget
            outcomes: dict[str, CallOutcome] = {}
            load_errors: tuple = ()
            defined: tuple = ()
            out, err = _Bounded(self.limits.output_bytes), _Bounded(self.limits.output_bytes)
            spawns = 0
            self._swept = 0
            pending = calls
            while pending:
                if time.monotonic() >= job_deadline:
                    break
                spawns += 1
                att = self._attempt(units, [encoded[c.id] for c in pending], job, job_deadline, out, err)
                if att.loaded is not None and spawns == 1:
                    load_errors, defined = att.loaded
                outcomes.update(att.results)
                if att.failure is not None:
                    status, message = att.failure
                    if att.loaded is None:
                        # Loading itself failed: restarting would fail the same way.
                        for c in pending:
                            outcomes.setdefault(c.id, CallOutcome(c.id, status, message=f"{message} while loading the notebook's code"))
                        break
                    culprit = att.current or next((c.id for c in pending if c.id not in outcomes), None)
                    if culprit is not None and culprit not in outcomes:
                        outcomes[culprit] = CallOutcome(culprit, status, message=message, seconds=att.current_seconds())
                pending = [c for c in pending if c.id not in outcomes]
                if att.failure is None and pending:
                    for c in pending:  # the child said it was done but skipped these
                        outcomes[c.id] = CallOutcome(c.id, "malformed", message="no result was reported for this call")
                    pending = []
            for c in calls:
                outcomes.setdefault(c.id, CallOutcome(c.id, "timeout", message="the job's time budget ran out before this call ran"))
            return JobResult(
                outcomes={c.id: outcomes[c.id] for c in calls},
                load_errors=tuple(load_errors),
                defined=tuple(defined),
                stdout=out.text(),
                stderr=err.text(),
                isolation=self.isolation,
                seconds=time.monotonic() - start,
                spawns=spawns,
                swept=self._swept,
            )

    def _encode_call(self, call: Call, job: Job) -> dict:
        try:
            args = wire.encode(tuple(call.args))
            kwargs = wire.encode(dict(call.kwargs))
        except wire.WireError as exc:
            raise ValueError(f"call {call.id!r}: arguments must be plain data ({exc})") from None
        timeout = float(call.timeout if call.timeout is not None else job.call_timeout)
        if not (math.isfinite(timeout) and timeout > 0):
            raise ValueError(f"call {call.id!r}: expected a positive timeout, got {timeout}")
        return {"id": call.id, "function": call.function, "args": args, "kwargs": kwargs, "timeout": timeout}

    def _attempt(self, units, calls, job: Job, job_deadline: float, out, err) -> _Attempt:
        self._jobs += 1
        jobdir = self._base / f"job{self._jobs}"
        jobdir.mkdir(mode=0o711)  # the work folder inside must be reachable by the sandbox's uid
        try:
            payload = {
                "units": units, "calls": calls, "load_timeout": float(job.load_timeout),
                "sys_path": [str(self._lib_inside())], "max_result_bytes": self.limits.result_bytes,
                "max_message": 500,
            }
            job_file = jobdir / "job.json"
            job_file.touch(mode=0o600)  # the child reads it through stdin only
            job_file.write_text(json.dumps(payload, allow_nan=False))
            workdir = self._make_workdir(jobdir)
            cpu = math.ceil(job.load_timeout + sum(c["timeout"] for c in calls)) + 5
            att = _Attempt(self, calls, job, job_deadline, out, err)
            with open(job_file, "rb") as stdin:
                att.run(lambda fd: self._command(workdir, self._python_argv(fd)), stdin,
                        self._popen_options(workdir, cpu))
            return att
        finally:
            if self._uid is not None:
                self._swept += len(_sweep_uid(self._uid))
            shutil.rmtree(jobdir, ignore_errors=True)

    # -- the command --------------------------------------------------------------------------

    def _lib_inside(self) -> Path:
        return Path("/tmp/.hw4-lib") if self._namespaced and self._private_tmp else self._lib

    @property
    def _namespaced(self) -> bool:
        return self.isolation.level in ("namespaces", "user-namespaces")

    def _make_workdir(self, jobdir: Path) -> Path:
        if self._namespaced and self._private_tmp:
            return Path("/tmp/work")  # made by the namespace's shell on the private /tmp
        work = jobdir / "work"
        work.mkdir(mode=0o700)
        if (self._lib / _MPL_CACHE).is_dir():
            shutil.copytree(self._lib / _MPL_CACHE, work / ".matplotlib")
        if self._uid is not None:
            for p in [work, *work.rglob("*")]:
                os.chown(p, self._uid, self._uid, follow_symlinks=False)
        return work

    def _env(self, workdir: Path) -> dict[str, str]:
        threads = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                    "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")}
        return {
            "PATH": "/usr/local/bin:/usr/bin:/bin",
            "HOME": str(workdir),
            "TMPDIR": str(workdir),
            "LANG": "C.UTF-8",
            "LC_ALL": "C.UTF-8",
            "MPLBACKEND": "Agg",
            "MPLCONFIGDIR": str(workdir / ".matplotlib"),
            **threads,
        }

    def _python_argv(self, result_fd: int) -> list[str]:
        return [sys.executable, "-I", "-B", str(self._lib_inside() / "child.py"), "--result-fd", str(result_fd)]

    def _popen_options(self, workdir: Path, cpu_seconds: int) -> dict:
        """Popen arguments shared by probes and jobs: environment, session, uid, rlimits."""
        options = {"env": self._env(workdir), "start_new_session": True,
                   "preexec_fn": self._preexec(cpu_seconds), "cwd": "/"}
        if self.isolation.level == "basic":
            options["cwd"] = str(workdir)
            if self._uid is not None:
                options.update(user=self._uid, group=self._uid, extra_groups=[])
        return options

    def _command(self, workdir: Path, program: list[str]) -> list[str]:
        """argv that runs ``program`` at the sandbox's isolation level."""
        level = self.isolation.level
        if level == "basic":
            return program
        flags = ["--pid", "--fork", "--kill-child", "--mount-proc", "--net", "--mount", "--ipc", "--uts"]
        if level == "user-namespaces":
            flags = ["--user", "--map-root-user"] + flags
        script = self._stage_script(workdir, program)
        return [shutil.which("unshare") or "unshare", *flags, "--", "/bin/sh", "-c", script]

    def _stage_script(self, workdir: Path, program: list[str]) -> str:
        """The root shell that prepares the namespace, then runs ``program`` without exec."""
        q = shlex.quote
        lines = ["set -e"]
        fd = 3
        binds: list[tuple[int, Path]] = []

        def keep(path: Path) -> int:
            nonlocal fd
            if fd > _STAGE_FD_MAX:
                raise RuntimeError("too many folders to keep reachable in the sandbox")
            lines.append(f"exec {fd}<{q(str(path))}")
            binds.append((fd, path))
            fd += 1
            return fd - 1

        lib_fd = keep(self._lib) if self._private_tmp else None
        # A Python under /tmp (a virtual environment made there) must survive the private /tmp.
        tmp_python = [(keep(p), p) for p in _python_dirs_in_private_tmp()] if self._private_tmp else []
        reach = _unreachable_python_dirs() if self._uid is not None else {}
        reach_fds = {top: [(keep(p), p) for p in paths] for top, paths in reach.items()}

        for p in self._hidden:
            if not os.path.lexists(p):
                continue  # gone since the sandbox was made: nothing left to hide
            if p.is_dir():
                lines.append(f"mount -t tmpfs -o ro,nosuid,nodev,noexec,size=4k,mode=0555 tmpfs {q(str(p))}")
            else:
                lines.append(f"mount --bind /dev/null {q(str(p))}")
        if self._private_tmp:
            for d in _PRIVATE_TMP_DIRS:
                if os.path.isdir(d):
                    lines.append(f"mount -t tmpfs -o nosuid,nodev,size={self.limits.tmp_bytes},mode=1777 tmpfs {d}")
        for kfd, p in tmp_python:
            lines.append(f"mkdir -p {q(str(p))}")
            lines.append(f"mount --no-canonicalize --bind /proc/self/fd/{kfd} {q(str(p))}")
            lines.append(f"mount -o remount,bind,ro {q(str(p))}")
        for top, kept in reach_fds.items():
            lines.append(f"mount -t tmpfs -o nosuid,nodev,size=64k,mode=0755 tmpfs {q(str(top))}")
            for kfd, p in kept:
                lines.append(f"mkdir -p {q(str(p))}")
                lines.append(f"mount --no-canonicalize --bind /proc/self/fd/{kfd} {q(str(p))}")
                lines.append(f"mount -o remount,bind,ro {q(str(p))}")
        if lib_fd is not None:
            lib = self._lib_inside()
            lines.append(f"mkdir -p {q(str(lib))}")
            lines.append(f"mount --no-canonicalize --bind /proc/self/fd/{lib_fd} {q(str(lib))}")
            lines.append(f"mount -o remount,bind,ro {q(str(lib))}")
            lines.append(f"mkdir -p {q(str(workdir))}")
            if (self._lib / _MPL_CACHE).is_dir():
                lines.append(f"cp -R {q(str(lib / _MPL_CACHE))} {q(str(workdir / '.matplotlib'))}")
            if self._uid is not None:
                lines.append(f"chown -R {self._uid}:{self._uid} {q(str(workdir))}")
            lines.append(f"chmod 700 {q(str(workdir))}")
        for kfd, _ in binds:
            lines.append(f"exec {kfd}<&-")
        lines.append(f"cd {q(str(workdir))}")
        lines.append("set +e")
        argv = [q(a) for a in program]
        if self._uid is not None:
            argv = [q(shutil.which("setpriv") or "setpriv"), f"--reuid={self._uid}", f"--regid={self._uid}",
                    "--clear-groups", "--no-new-privs", "--inh-caps=-all", "--bounding-set=-all", "--"] + argv
        # Not `exec`: this root shell must stay the namespace's first process so that killing
        # unshare (which sends it SIGKILL) ends the namespace and every process in it.
        lines.append(" ".join(argv))
        lines.append("rc=$?")
        lines.append("exit $rc")
        return "\n".join(lines)

    # -- setup ----------------------------------------------------------------------------------

    def _build_lib(self, packages: Sequence[str]) -> None:
        self._lib.mkdir(mode=0o755)
        shutil.copy2(_CHILD, self._lib / "child.py")
        for name in packages:
            src = self.kit_root / name
            if not (src / "__init__.py").is_file() and not any(src.glob("*.py")):
                continue
            shutil.copytree(src, self._lib / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        # Compiled here once, because the child may not write into this folder.
        compileall.compile_dir(self._lib, quiet=1, workers=1)
        if importlib.util.find_spec("matplotlib") is not None:
            # Matplotlib scans the system fonts on first use (about half a second); scan once here
            # and give every job a copy of the result.
            subprocess.run([sys.executable, "-I", "-c", "import matplotlib.font_manager"],
                           env={"MPLCONFIGDIR": str(self._lib / _MPL_CACHE), "PATH": "/usr/bin:/bin"},
                           capture_output=True, timeout=300, check=False)
        for p in [self._lib, *self._lib.rglob("*")]:
            os.chmod(p, 0o755 if p.is_dir() else 0o644)

    def _hidden_paths(self, extra: Sequence[str | Path]) -> tuple[Path, ...]:
        found = [self.kit_root / "solutions", self.kit_root / "autograder", self.kit_root / "tests"]
        for pkg in ("solutions", "autograder"):
            try:
                spec = importlib.util.find_spec(pkg)
            except (ImportError, ValueError):
                spec = None
            for loc in (spec.submodule_search_locations or []) if spec else []:
                found.append(Path(loc))
        course_data = os.environ.get("HW4_COURSE_DATA") or self.kit_root.parent / "shared" / "course-data"
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

    def _choose(self, requested: str, uid: int | None) -> Isolation:
        notes: list[str] = []
        candidates = _LEVELS if requested == "auto" else (requested,)
        for level in candidates:
            reason = self._try_level(level, uid, notes)
            if reason is None:
                return self._isolation(level, tuple(notes))
            notes.append(f"{level} unavailable: {reason}")
            if requested != "auto":
                raise RuntimeError(f"isolation: {level} does not work here ({reason})")
        raise RuntimeError("isolation: no level works here: " + "; ".join(notes))

    def _try_level(self, level: str, uid: int | None, notes: list[str]) -> str | None:
        """Set up ``level`` and probe it; None when it works, else the reason."""
        root = os.geteuid() == 0
        if level == "namespaces" and not root:
            return "the grader is not root"
        if level == "user-namespaces" and root:
            # Mapped to root inside, the code would keep the grader's real uid: never choose it
            # silently when a real unprivileged uid is available at the basic level.
            return "the grader is root, so the code would run as root"
        if level != "basic":
            for tool in ("unshare", "mount") + (("setpriv",) if level == "namespaces" else ()):
                if shutil.which(tool) is None:
                    return f"{tool} is not installed"
        self._release_uid()
        want_uid = root and level != "user-namespaces"
        if want_uid and level == "basic" and _unreachable_python_dirs():
            # Without a mount namespace nothing can make a private Python reachable to another uid.
            notes.append("basic: Python is installed under a private folder, so the code keeps the grader's uid")
            want_uid = False
        if want_uid:
            if uid is not None:
                self._uid = uid
            else:
                self._uid, self._uid_fd = _pick_uid()
            with Sandbox._uids_lock:
                Sandbox._uids_in_use.add(self._uid)
        self.isolation = self._isolation(level, ())
        return self._probe()

    def _release_uid(self) -> None:
        if self._uid is not None:
            with Sandbox._uids_lock:
                Sandbox._uids_in_use.discard(self._uid)
            self._uid = None
        if self._uid_fd is not None:
            os.close(self._uid_fd)
            self._uid_fd = None

    def _isolation(self, level: str, notes: tuple[str, ...]) -> Isolation:
        namespaced = level != "basic"
        extra = []
        if not namespaced:
            extra.append("hidden paths stay readable and the network reachable at this level")
        if self._uid is None:
            extra.append("the code runs as the grader's own user")
        return Isolation(level, self._uid, namespaced, namespaced, namespaced and self._private_tmp,
                         tuple(str(p) for p in self._hidden) if namespaced else (), notes + tuple(extra))

    def _probe(self) -> str | None:
        """None when a trivial program runs at the current level, else the reason."""
        self._jobs += 1
        jobdir = self._base / f"probe{self._jobs}"
        jobdir.mkdir(mode=0o711)
        try:
            workdir = self._make_workdir(jobdir)
            program = [sys.executable, "-I", "-B", "-c", "import numpy; print('sandbox-ok')"]
            try:
                proc = subprocess.run(self._command(workdir, program), capture_output=True, timeout=60,
                                      stdin=subprocess.DEVNULL, check=False,
                                      **self._popen_options(workdir, 60))
            except (OSError, subprocess.SubprocessError) as exc:
                return f"{type(exc).__name__}: {exc}"
            if proc.returncode != 0 or b"sandbox-ok" not in proc.stdout:
                tail = proc.stderr.decode(errors="replace").strip().splitlines()[-1:] or [f"exit code {proc.returncode}"]
                return tail[0][:300]
            return None
        finally:
            shutil.rmtree(jobdir, ignore_errors=True)
            if self._uid is not None:
                _sweep_uid(self._uid)

    def _preexec(self, cpu_seconds: int):
        """Runs in the forked child before exec (after Popen's own uid change): the rlimits."""
        limits = self.limits
        nproc = limits.processes
        if self._uid is None:
            # Without a uid of its own the process count is shared with the grader's user.
            nproc += _count_processes(os.getuid())

        def setup() -> None:
            def cap(which: int, value: int) -> None:
                hard = resource.getrlimit(which)[1]
                value = value if hard == resource.RLIM_INFINITY else min(value, hard)
                resource.setrlimit(which, (value, value))

            cap(resource.RLIMIT_CORE, 0)
            cap(resource.RLIMIT_AS, limits.memory_bytes)
            cap(resource.RLIMIT_FSIZE, limits.file_bytes)
            cap(resource.RLIMIT_NOFILE, limits.open_files)
            cap(resource.RLIMIT_NPROC, nproc)
            hard = resource.getrlimit(resource.RLIMIT_CPU)[1]
            soft = cpu_seconds if hard == resource.RLIM_INFINITY else min(cpu_seconds, hard - 1)
            resource.setrlimit(resource.RLIMIT_CPU, (soft, soft + 1 if hard == resource.RLIM_INFINITY else hard))
            if _LIBC is not None:
                # If the grader dies, the sandbox dies with it instead of running on unwatched.
                _LIBC.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)

        return setup


class _Bounded:
    """Keeps the first ``limit`` bytes written to it and counts the rest."""

    def __init__(self, limit: int):
        self.limit, self.data, self.dropped = limit, bytearray(), 0

    def add(self, chunk: bytes) -> None:
        room = self.limit - len(self.data)
        self.data += chunk[:max(room, 0)]
        self.dropped += max(len(chunk) - max(room, 0), 0)

    def text(self) -> str:
        s = self.data.decode("utf-8", errors="replace")
        return s + (f"\n[... {self.dropped} more bytes not kept]" if self.dropped else "")


class _ProtocolError(Exception):
    pass


class _Attempt:
    """One child process: start it, read its records, stop it, and say how it ended."""

    def __init__(self, box: Sandbox, calls: list[dict], job: Job, job_deadline: float, out: _Bounded, err: _Bounded):
        self.box, self.calls, self.job, self.job_deadline = box, calls, job, job_deadline
        self.out, self.err = out, err
        self.by_id = {c["id"]: c for c in calls}
        self.results: dict[str, CallOutcome] = {}
        self.loaded: tuple | None = None
        self.current: str | None = None
        self.current_start = 0.0
        self.failure: tuple[str, str] | None = None
        self.done = False
        self.wire_limits = wire.Limits(max_array_bytes=box.limits.result_bytes,
                                       max_total_bytes=box.limits.result_bytes)

    def current_seconds(self) -> float | None:
        return round(time.monotonic() - self.current_start, 3) if self.current else None

    def deadline(self, spawned: float) -> float:
        grace = self.box.limits.grace
        if self.loaded is None:
            limit = spawned + self.job.load_timeout + 10 + grace
        elif self.current is not None:
            limit = self.current_start + self.by_id[self.current]["timeout"] + grace
        else:
            limit = self.last_event + grace + 5
        return min(limit, self.job_deadline)

    def run(self, make_argv, stdin, options: dict) -> None:
        r, w = os.pipe()
        wfd = fcntl.fcntl(w, fcntl.F_DUPFD_CLOEXEC, _RESULT_FD_MIN)
        os.close(w)
        spawned = self.last_event = time.monotonic()
        try:
            proc = subprocess.Popen(make_argv(wfd), stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    pass_fds=(wfd,), **options)
        except OSError as exc:
            os.close(r)
            os.close(wfd)
            self.failure = ("crashed", f"the sandbox could not start ({exc})")
            return
        os.close(wfd)
        try:
            self._collect(proc, r, spawned)
        finally:
            _kill_tree(proc)
            os.close(r)
            for f in (proc.stdout, proc.stderr):
                f.close()

    def _collect(self, proc: subprocess.Popen, r: int, spawned: float) -> None:
        sel = selectors.DefaultSelector()
        streams = {r: None, proc.stdout.fileno(): self.out, proc.stderr.fileno(): self.err}
        for fd in streams:
            os.set_blocking(fd, False)
            sel.register(fd, selectors.EVENT_READ)
        buf = bytearray()
        max_line = self.box.limits.result_bytes * 4 // 3 + _MAX_LINE_SLACK
        open_fds = set(streams)
        done_by = None
        try:
            while True:
                now = time.monotonic()
                if self.done and done_by is None:
                    done_by = now + 1.0  # let the child flush and exit on its own
                if done_by is not None and now >= done_by:
                    return
                if done_by is None and now >= self.deadline(spawned):
                    self._timed_out(now)
                    return
                exited = proc.poll() is not None
                wait = 0 if exited else max(min(0.1, (done_by or self.deadline(spawned)) - now), 0)
                for key, _ in sel.select(timeout=wait):
                    fd = key.fd
                    try:
                        chunk = os.read(fd, 1 << 16)
                    except BlockingIOError:
                        continue
                    if not chunk:
                        sel.unregister(fd)
                        open_fds.discard(fd)
                        continue
                    if fd != r:
                        streams[fd].add(chunk)
                        continue
                    if self.done:
                        continue  # nothing after "done" counts
                    buf += chunk
                    while b"\n" in buf:
                        line, _, rest = bytes(buf).partition(b"\n")
                        buf = bytearray(rest)
                        self._record(line)
                        if self.done:
                            break
                    if len(buf) > max_line:
                        raise _ProtocolError("a result record is larger than the limit")
                if exited and not (open_fds and sel.select(timeout=0)):
                    if not self.done:
                        self._ended(proc.returncode)
                    return
        except _ProtocolError as exc:
            self.failure = ("malformed", f"the sandbox's output could not be read ({exc})")
        finally:
            sel.close()

    def _timed_out(self, now: float) -> None:
        if now >= self.job_deadline:
            self.failure = ("timeout", "the job's time budget ran out")
        elif self.loaded is None:
            self.failure = ("timeout", f"took more than {self.job.load_timeout:g} s")
        elif self.current is not None:
            self.failure = ("timeout", f"took more than {self.by_id[self.current]['timeout']:g} s and was stopped")
        else:
            self.failure = ("timeout", "the code did not start the next call in time")

    def _ended(self, returncode: int) -> None:
        self.failure = ("crashed", "the process running the code ended without a result " + _describe_exit(returncode))

    def _record(self, line: bytes) -> None:
        try:
            rec = wire.parse_json(line)
        except wire.WireError as exc:
            raise _ProtocolError(str(exc)) from None
        if not isinstance(rec, dict):
            raise _ProtocolError("a record is not a JSON object")
        self.last_event = time.monotonic()
        event = rec.get("event")
        if event == "loaded" and self.loaded is None:
            errors = rec.get("errors")
            defined = rec.get("defined")
            if not (isinstance(errors, list) and isinstance(defined, list)):
                raise _ProtocolError("bad 'loaded' record")
            errs = tuple((_short(e.get("origin")), _short(e.get("message"))) for e in errors[:200]
                         if isinstance(e, dict))
            self.loaded = (errs, tuple(_short(d, 200) for d in defined[:2000] if isinstance(d, str)))
        elif event == "start":
            cid = rec.get("id")
            if cid not in self.by_id:
                raise _ProtocolError("a record names an unknown call")
            if cid not in self.results:
                self.current, self.current_start = cid, time.monotonic()
        elif event == "done":
            self.done = True
        elif event is None and "id" in rec:
            self._result(rec)
        else:
            raise _ProtocolError(f"unexpected record {str(event)[:40]!r}")

    def _result(self, rec: dict) -> None:
        cid, status = rec.get("id"), rec.get("status")
        if cid not in self.by_id or status not in _CHILD_STATUSES:
            raise _ProtocolError("a result names an unknown call or status")
        if self.loaded is None:
            raise _ProtocolError("a result arrived before the code was loaded")
        if cid in self.results:
            return  # the first word on a call is final
        seconds = rec.get("seconds")
        seconds = float(seconds) if type(seconds) in (int, float) and math.isfinite(seconds) else None
        if status == "ok":
            try:
                value = wire.decode(rec.get("value"), self.wire_limits)
            except wire.WireError as exc:
                outcome = CallOutcome(cid, "malformed", message=f"the returned value is not plain data ({exc})", seconds=seconds)
            else:
                outcome = CallOutcome(cid, "ok", value=value, seconds=seconds)
        else:
            outcome = CallOutcome(cid, status, message=_short(rec.get("message")), seconds=seconds)
        self.results[cid] = outcome
        if cid == self.current:
            self.current = None


# ------------------------------------------------------------------------------------------------
# processes and uids


def _short(value, limit: int = 1000) -> str:
    text = value if isinstance(value, str) else ""
    return text if len(text) <= limit else text[:limit] + " [...]"


def _describe_exit(code: int | None) -> str:
    if code is None:
        return ""
    # Through the namespace's shell a signal death shows as 128 + signal number.
    sig = -code if code < 0 else code - 128 if code > 128 else None
    if sig:
        try:
            name = signal.Signals(sig).name
        except ValueError:
            name = f"signal {sig}"
        hint = {"SIGKILL": "; a memory or process limit may have been hit", "SIGXCPU": "; the CPU time limit was hit",
                "SIGSEGV": "; the interpreter crashed", "SIGXFSZ": "; a file grew past the size limit"}.get(name, "")
        return f"(killed by {name}{hint})"
    return f"(exit code {code})"


def _kill_tree(proc: subprocess.Popen) -> None:
    # The group outlives its leader while members remain, and its id is not reused meanwhile.
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    if proc.poll() is None:
        try:
            proc.kill()
        except ProcessLookupError:
            pass
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass


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


def _live_pids_of_uid(uid: int) -> list[int]:
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            info = _uids_of(entry)
            if info and uid in info[0] and info[1] != "Z":
                out.append(int(entry))
    return out


def _count_processes(uid: int) -> int:
    return len(_live_pids_of_uid(uid))


def _sweep_uid(uid: int, budget: float = 5.0) -> list[int]:
    """SIGKILL every live process of ``uid`` (the sandbox's own) until none is left; return them.

    Each process is opened as a pidfd and its uid re-checked before the signal, so a pid reused
    by an unrelated process in between is never signalled.
    """
    if uid == 0 or uid == os.getuid():
        raise ValueError(f"uid: expected the sandbox's own uid, got {uid}")
    killed: list[int] = []
    end = time.monotonic() + budget
    while True:
        pids = _live_pids_of_uid(uid)
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


_UID_LOCKS = Path(tempfile.gettempdir()) / "hw4-sandbox-uids"


def _lock_uid(uid: int) -> int | None:
    """An open, exclusively locked file descriptor that reserves ``uid``, or None when it is taken.

    The lock is shared by every grader process on the machine (two batches at once must not
    pick the same uid: one's clean-up would kill the other's processes).  It is released when
    the descriptor is closed, or when the process dies.
    """
    import fcntl

    _UID_LOCKS.mkdir(mode=0o700, exist_ok=True)
    fd = os.open(_UID_LOCKS / str(uid), os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def _pick_uid(start: int = 60000, span: int = 4000) -> tuple[int, int]:
    """(uid, lock fd): an uid with no passwd entry and no process, reserved across processes."""
    offset = os.getpid() % span
    for k in range(span):
        uid = start + (offset + k) % span
        with Sandbox._uids_lock:
            if uid in Sandbox._uids_in_use:
                continue
        try:
            pwd.getpwuid(uid)
            continue
        except KeyError:
            pass
        fd = _lock_uid(uid)
        if fd is None:
            continue
        if not _live_pids_of_uid(uid):
            return uid, fd
        os.close(fd)
    raise RuntimeError(f"no free uid between {start} and {start + span}")


_PRIVATE_TMP_DIRS = ("/tmp", "/var/tmp", "/dev/shm")


def _python_dirs() -> set[Path]:
    """The outermost folders this Python (its prefix, a virtual environment, site-packages) lives in."""
    wanted = {Path(sys.base_prefix), Path(sys.prefix), Path(os.path.realpath(sys.executable)).parent}
    try:
        wanted.update(Path(p) for p in site.getsitepackages())
    except AttributeError:
        pass
    wanted = {p.resolve() for p in wanted if p.exists()}
    return {p for p in wanted if not any(q != p and q in p.parents for q in wanted)}


def _python_dirs_in_private_tmp() -> list[Path]:
    """Python folders that the private /tmp would cover (a virtual environment made under /tmp, say)."""
    return sorted(p for p in _python_dirs()
                  if any(Path(d) in p.parents for d in _PRIVATE_TMP_DIRS if os.path.isdir(d)))


def _unreachable_python_dirs() -> dict[Path, list[Path]]:
    """Folders of this Python that another uid cannot reach, grouped by the top folder blocking them.

    Python may live under a private folder (pyenv under /root); the sandbox then covers that
    top folder with a tmpfs and binds these folders back at the same paths, read-only.
    """
    out: dict[Path, list[Path]] = {}
    for p in sorted(_python_dirs()):
        for anc in reversed(p.parents):
            if anc == Path("/"):
                continue
            if not os.stat(anc).st_mode & stat.S_IXOTH:
                out.setdefault(anc, []).append(p)
                break
    return out


def run_job(job: Job, **sandbox_options) -> JobResult:
    """Run one job in a fresh ``Sandbox(**sandbox_options)`` and clean up."""
    with Sandbox(**sandbox_options) as box:
        return box.run(job)
