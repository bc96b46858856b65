"""How a program is started at an isolation level: argv (the namespace's root shell script),
environment, working folder, uid and rlimits.  Pure builders over a ``Runtime``; nothing runs here
except the pre-exec hook in the forked child."""

from __future__ import annotations

import ctypes
import os
import resource
import shlex
import shutil
import signal
import site
import stat
import sys
from dataclasses import dataclass
from pathlib import Path

from core.paths import RESULT_FOLDERS

from .model import ResourceLimits
from .uids import SHARED_TMP_DIRS, count_processes

__all__ = ["MPL_CACHE", "PRIVATE_TMP_DIRS", "RESULT_DIRS", "SCRATCH_DIRS", "Runtime", "command", "env", "make_workdir", "popen_options",
           "python_dirs_in_private_tmp", "unreachable_python_dirs"]

MPL_CACHE = "mplconfig"
PRIVATE_TMP_DIRS = ("/tmp", "/var/tmp", "/dev/shm")
_STAGE_FD_MAX = 9      # a POSIX shell redirects only single-digit fds
_PR_SET_PDEATHSIG = 1
_PR_SET_NO_NEW_PRIVS = 38
try:
    # Loaded here: after fork, in the pre-exec hook, nothing should need to be imported.
    _LIBC = ctypes.CDLL(None, use_errno=True)
except OSError:  # pragma: no cover - non-glibc systems
    _LIBC = None


@dataclass(frozen=True)
class Runtime:
    """Where and how sandboxed programs run.

    level: the isolation level; uid: the sandbox's own uid (None: the grader's); lib: the folder
    holding child.py and the kit packages the student may import; hidden: paths covered inside
    the namespace (or, at the ``uid`` level, unreadable to ``gid``); private_tmp: own /tmp,
    /var/tmp, /dev/shm; limits: the rlimits and sizes; gid: the group the code runs in (None:
    the same number as ``uid``; at the ``uid`` level the sandbox's group that the hidden paths
    deny, ``deny.SANDBOX_GID``); deny_internet: the child refuses internet sockets to the code with a
    seccomp filter (``child.deny_internet``; the levels without a network namespace).
    """

    level: str
    uid: int | None
    lib: Path
    hidden: tuple[Path, ...]
    private_tmp: bool
    limits: ResourceLimits
    gid: int | None = None
    deny_internet: bool = False

    @property
    def namespaced(self) -> bool:
        return self.level in ("namespaces", "user-namespaces")

    def shared_tmp_dirs(self) -> tuple[str, ...]:
        """The machine's shared temporary folders (``uids.SHARED_TMP_DIRS``) the code can leave
        files in: all of them, but those its own tmpfs covers (``PRIVATE_TMP_DIRS``, at the
        namespace levels with a private /tmp), which vanish with the namespace."""
        if not (self.namespaced and self.private_tmp):
            return SHARED_TMP_DIRS
        private = {os.path.realpath(d) for d in PRIVATE_TMP_DIRS if os.path.isdir(d)}
        return tuple(d for d in SHARED_TMP_DIRS if os.path.realpath(d) not in private)

    def lib_inside(self) -> Path:
        """Where the lib folder is seen from inside the sandbox."""
        return Path("/tmp/.hw4-lib") if self.namespaced and self.private_tmp else self.lib

    def child_argv(self, result_fd: int) -> list[str]:
        return [sys.executable, "-I", "-B", str(self.lib_inside() / "child.py"), "--result-fd", str(result_fd),
                *(["--deny-internet"] if self.deny_internet else []), *(["--own-uid"] if self.uid is not None else [])]


# ------------------------------------------------------------------------------------------------
# the Python installation


def _python_dirs() -> set[Path]:
    """The outermost folders this Python (its prefix, a virtual environment, site-packages) lives in."""
    wanted = {Path(sys.base_prefix), Path(sys.prefix), Path(os.path.realpath(sys.executable)).parent}
    try:
        wanted.update(Path(p) for p in site.getsitepackages())
    except AttributeError:
        pass
    wanted = {p.resolve() for p in wanted if p.exists()}
    return {p for p in wanted if not any(q != p and q in p.parents for q in wanted)}


def python_dirs_in_private_tmp() -> list[Path]:
    """Python folders that the private /tmp would cover (a virtual environment made under /tmp, say)."""
    return sorted(p for p in _python_dirs()
                  if any(Path(d) in p.parents for d in PRIVATE_TMP_DIRS if os.path.isdir(d)))


def unreachable_python_dirs() -> dict[Path, list[Path]]:
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


# ------------------------------------------------------------------------------------------------
# the process


# Folders student code may write its results into, relative to its working folder (the
# handouts of several years said `results/` or `../results/`, 2022-2024's `result/`:
# core.paths.RESULT_FOLDERS).  All lie inside the child's own scratch area: the working folder is
# <scratch>/run, so `..` is the scratch folder itself.
RESULT_DIRS = tuple(f"{up}{name}" for up in ("", "../") for name in RESULT_FOLDERS)
# The child's own temporary folders, beside its working folder in its scratch area (0700, the
# sandbox uid's): TMPDIR, TEMP and TMP name the first, XDG_RUNTIME_DIR the second.  Every library
# that asks where to put temporary files (tempfile, matplotlib, joblib...) is sent there, never
# to the machine's shared /tmp.
SCRATCH_DIRS = ("../tmp", "../xdg-runtime")


def make_workdir(rt: Runtime, jobdir: Path) -> Path:
    """A fresh working folder (HOME and cwd) for one child, owned by the sandbox's uid.

    The folder is ``<scratch>/run`` with ``<scratch>`` private to the child (``jobdir/work``, or
    ``/tmp/work`` on the namespace's private /tmp); ``run/results``, ``run/result``,
    ``<scratch>/results`` and ``<scratch>/result`` exist and are writable (RESULT_DIRS), so code
    that saves its results before returning works.
    """
    if rt.namespaced and rt.private_tmp:
        return Path("/tmp/work/run")  # made by the namespace's shell on the private /tmp
    scratch = jobdir / "work"
    scratch.mkdir(mode=0o700)
    work = scratch / "run"
    work.mkdir(mode=0o700)
    for rel in RESULT_DIRS + SCRATCH_DIRS:
        (work / rel).mkdir(mode=0o700, exist_ok=True)
    if (rt.lib / MPL_CACHE).is_dir():
        shutil.copytree(rt.lib / MPL_CACHE, work / ".matplotlib")
    if rt.uid is not None:
        for p in [scratch, *scratch.rglob("*")]:
            os.chown(p, rt.uid, rt.uid, follow_symlinks=False)
    return work


def env(workdir: Path) -> dict[str, str]:
    """The child's whole environment: nothing of the grader's."""
    threads = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")}
    tmp = os.path.normpath(workdir / SCRATCH_DIRS[0])
    return {
        "PATH": "/usr/local/bin:/usr/bin:/bin",
        "HOME": str(workdir),
        "TMPDIR": tmp,
        "TEMP": tmp,
        "TMP": tmp,
        "JOBLIB_TEMP_FOLDER": tmp,
        "XDG_RUNTIME_DIR": os.path.normpath(workdir / SCRATCH_DIRS[1]),
        "XDG_CACHE_HOME": str(workdir / ".cache"),
        "XDG_CONFIG_HOME": str(workdir / ".config"),
        "XDG_DATA_HOME": str(workdir / ".local" / "share"),
        "LANG": "C.UTF-8",
        "LC_ALL": "C.UTF-8",
        "MPLBACKEND": "Agg",
        "MPLCONFIGDIR": str(workdir / ".matplotlib"),
        **threads,
    }


def popen_options(rt: Runtime, workdir: Path, cpu_seconds: int) -> dict:
    """Popen arguments shared by probes and sessions: environment, session, uid, rlimits."""
    options = {"env": env(workdir), "start_new_session": True, "preexec_fn": _preexec(rt, cpu_seconds), "cwd": "/"}
    if not rt.namespaced:
        options["cwd"] = str(workdir)
        if rt.uid is not None:
            options.update(user=rt.uid, group=rt.uid if rt.gid is None else rt.gid, extra_groups=[])
    return options


def _preexec(rt: Runtime, cpu_seconds: int):
    """Runs in the forked child before exec (after Popen's own uid change): the rlimits."""
    limits = rt.limits
    nproc = limits.processes
    no_new_privs = not rt.namespaced and rt.uid is not None
    if rt.uid is None:
        # Without a uid of its own the process count is shared with the grader's user.
        nproc += count_processes(os.getuid())

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
            if no_new_privs:
                # No setuid program (su, mount...) can give the code back any privilege.
                _LIBC.prctl(_PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0)

    return setup


def command(rt: Runtime, workdir: Path, program: list[str], jobdir: Path) -> list[str]:
    """argv that runs ``program`` at the runtime's isolation level.

    At the namespace levels the staging script is written to ``jobdir/stage`` (the grader's, 0600)
    and the namespace's first process runs that file: its command line, which every process of the
    namespace can read in /proc/1/cmdline, then names no hidden path, output folder or keep.
    """
    if not rt.namespaced:
        return program
    flags = ["--pid", "--fork", "--kill-child", "--mount-proc", "--net", "--mount", "--ipc", "--uts"]
    if rt.level == "user-namespaces":
        flags = ["--user", "--map-root-user"] + flags
    stage = jobdir / "stage"
    fd = os.open(stage, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
    with os.fdopen(fd, "w") as fh:
        fh.write(stage_script(rt, workdir, program) + "\n")
    return [shutil.which("unshare") or "unshare", *flags, "--", "/bin/sh", str(stage)]


def stage_script(rt: Runtime, workdir: Path, program: list[str]) -> str:
    """The root shell that prepares the namespace, then runs ``program`` without exec."""
    q = shlex.quote
    # The folders this script makes (mount points such as a venv's parents on the private /tmp)
    # must be traversable by the sandbox's uid whatever umask the grader runs with (077).
    lines = ["set -e", "umask 022"]
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

    lib_fd = keep(rt.lib) if rt.private_tmp else None
    # A Python under /tmp (a virtual environment made there) must survive the private /tmp.
    tmp_python = [(keep(p), p) for p in python_dirs_in_private_tmp()] if rt.private_tmp else []
    reach = unreachable_python_dirs() if rt.uid is not None else {}
    reach_fds = {top: [(keep(p), p) for p in paths] for top, paths in reach.items()}

    if rt.private_tmp:
        for d in PRIVATE_TMP_DIRS:
            if os.path.isdir(d):
                lines.append(f"mount -t tmpfs -o nosuid,nodev,size={rt.limits.tmp_bytes},"
                             f"nr_inodes={rt.limits.tmp_files},mode=1777 tmpfs {d}")
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
    # The hidden paths are covered last, on the tree as the code will see it: a path under a folder
    # replaced by an empty tmpfs (the private /tmp, a private folder holding Python) is already gone
    # and gets no mount, whose mount point would name it in /proc/self/mountinfo; one inside a
    # folder bound back (a virtual environment under /tmp) is covered on the bound copy, which a
    # plain bind does not carry over from the original.
    covered = [Path(d).resolve() for d in PRIVATE_TMP_DIRS if rt.private_tmp and os.path.isdir(d)]
    covered += [Path(top).resolve() for top in reach_fds]
    bound = [p.resolve() for _, p in tmp_python] + [p.resolve() for kept in reach_fds.values() for _, p in kept]
    for p in rt.hidden:
        if not os.path.lexists(p):
            continue  # gone since the sandbox was made: nothing left to hide
        if _within(p, covered) and not _within(p, bound):
            continue
        if p.is_dir():
            lines.append(f"mount -t tmpfs -o ro,nosuid,nodev,noexec,size=4k,mode=0555 tmpfs {q(str(p))}")
        else:
            lines.append(f"mount --bind /dev/null {q(str(p))}")
    if lib_fd is not None:
        lib = rt.lib_inside()
        lines.append(f"mkdir -p {q(str(lib))}")
        lines.append(f"mount --no-canonicalize --bind /proc/self/fd/{lib_fd} {q(str(lib))}")
        lines.append(f"mount -o remount,bind,ro {q(str(lib))}")
        scratch = workdir.parent
        lines.append(f"mkdir -p {q(str(workdir))}")
        lines.append("mkdir -p " + " ".join(q(os.path.normpath(workdir / rel)) for rel in RESULT_DIRS + SCRATCH_DIRS))
        if (rt.lib / MPL_CACHE).is_dir():
            lines.append(f"cp -R {q(str(lib / MPL_CACHE))} {q(str(workdir / '.matplotlib'))}")
        if rt.uid is not None:
            lines.append(f"chown -R {rt.uid}:{rt.uid} {q(str(scratch))}")
        lines.append(f"chmod 700 {q(str(scratch))} {q(str(workdir))} "
                     + " ".join(q(os.path.normpath(workdir / rel)) for rel in SCRATCH_DIRS))
    for kfd, _ in binds:
        lines.append(f"exec {kfd}<&-")
    lines.append(f"cd {q(str(workdir))}")
    lines.append("set +e")
    argv = [q(a) for a in program]
    if rt.uid is not None:
        argv = [q(shutil.which("setpriv") or "setpriv"), f"--reuid={rt.uid}", f"--regid={rt.uid}",
                "--clear-groups", "--no-new-privs", "--inh-caps=-all", "--bounding-set=-all", "--"] + argv
    # Not `exec`: this root shell must stay the namespace's first process so that killing
    # unshare (which sends it SIGKILL) ends the namespace and every process in it.
    lines.append(" ".join(argv))
    lines.append("rc=$?")
    lines.append("exit $rc")
    return "\n".join(lines)


def _within(path: Path, folders: list[Path]) -> bool:
    """Whether ``path`` is one of ``folders`` or lies inside one."""
    return any(path == f or f in path.parents for f in folders)
