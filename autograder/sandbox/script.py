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

__all__ = ["MPL_CACHE", "PRIVATE_TMP_DIRS", "RESULT_DIRS", "SCRATCH_DIRS", "SYSTEM_DIRS", "Runtime", "command", "env",
           "make_workdir", "popen_options", "python_dirs", "unreachable_python_dirs"]

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
        files in: all of them, but none at the namespace levels with a private root
        (``stage_script``), whose tree holds no folder of the host's but read-only ones."""
        if self.namespaced and self.private_tmp:
            return ()
        return SHARED_TMP_DIRS

    def lib_inside(self) -> Path:
        """Where the lib folder is seen from inside the sandbox."""
        return Path("/tmp/.hw4-lib") if self.namespaced and self.private_tmp else self.lib

    def child_argv(self, result_fd: int) -> list[str]:
        return [sys.executable, "-I", "-B", str(self.lib_inside() / "child.py"), "--result-fd", str(result_fd),
                *(["--deny-internet"] if self.deny_internet else []), *(["--own-uid"] if self.uid is not None else [])]


# ------------------------------------------------------------------------------------------------
# the Python installation


def python_dirs() -> set[Path]:
    """The outermost folders this Python (its prefix, a virtual environment, site-packages) lives in."""
    wanted = {Path(sys.base_prefix), Path(sys.prefix), Path(os.path.realpath(sys.executable)).parent}
    try:
        wanted.update(Path(p) for p in site.getsitepackages())
    except AttributeError:
        pass
    wanted = {p.resolve() for p in wanted if p.exists()}
    return {p for p in wanted if not any(q != p and q in p.parents for q in wanted)}


def unreachable_python_dirs() -> dict[Path, list[Path]]:
    """Folders of this Python that another uid cannot reach, grouped by the top folder blocking them.

    Python may live under a private folder (pyenv under /root); the sandbox then covers that
    top folder with a tmpfs and binds these folders back at the same paths, read-only.
    """
    out: dict[Path, list[Path]] = {}
    for p in sorted(python_dirs()):
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
    # The folders this script makes (mount points, the scratch area) must be traversable by the
    # sandbox's uid whatever umask the grader runs with (077).
    lines = ["set -e", "umask 022"]
    if rt.private_tmp:
        lines += _private_root(rt, workdir)
    else:
        lines += _covered_host_tree(rt)
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


# What the code's own root holds from the machine, read-only: the programs and libraries, the
# system's configuration (the dynamic linker's cache, locales, time zones).  Nothing else of the
# host's tree is in it, so no staff folder is there to be listed or named in the mount table.
SYSTEM_DIRS = ("/usr", "/etc", "/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32")
_DEVICES = ("null", "zero", "full", "random", "urandom")


def _private_root(rt: Runtime, workdir: Path) -> list[str]:
    """Lines that build the code's own root and move into it (``pivot_root``).

    The root is an empty tmpfs holding only: the system folders (``SYSTEM_DIRS``) and this
    Python's folders, bound read-only at their own paths; a copy of the lib (never a bind, whose
    source path the mount table would show); empty /tmp, /var/tmp and /dev/shm; the harmless
    devices; a fresh /proc.  A hidden path is then simply absent, unless it lies inside a folder
    bound in (a course's data under /usr, say), where it is covered as on the host's tree.
    """
    q = shlex.quote
    new = "/tmp"   # the new root's mount point before the move: any folder will do, this one exists
    lines: list[str] = []
    fd = 3

    def keep(path: Path) -> str:
        """A path to an open descriptor on ``path``, taken before the new root covers /tmp."""
        nonlocal fd
        if fd > _STAGE_FD_MAX:
            raise RuntimeError("too many folders to keep reachable in the sandbox")
        lines.append(f"exec {fd}<{q(str(path))}")
        fd += 1
        return f"/proc/self/fd/{fd - 1}"

    lib_src = keep(rt.lib)
    system = [d for d in SYSTEM_DIRS if os.path.lexists(d)]
    pythons = [p for p in sorted(python_dirs()) if not _within(p, [Path(d).resolve() for d in system])]
    sources = {p: keep(p) if _within(p, [Path("/tmp").resolve()]) else str(p) for p in pythons}

    def into(path) -> str:
        return q(new + str(path))

    def bind_ro(src: str, path) -> None:
        lines.append(f"mount --no-canonicalize --bind {q(src)} {into(path)}")
        lines.append(f"mount -o remount,bind,ro {into(path)}")

    lines.append(f"mount -t tmpfs -o nosuid,nodev,size=16m,mode=0755 tmpfs {new}")
    for d in system:
        if os.path.islink(d):
            lines.append(f"ln -s {q(os.readlink(d))} {into(d)}")
        elif os.path.isdir(d):
            lines.append(f"mkdir {into(d)}")
            bind_ro(d, d)
    lines.append(f"mkdir -p {into('/proc')} {into('/dev')} {into('/var')}")
    for d in PRIVATE_TMP_DIRS:
        lines.append(f"mkdir -p {into(d)}")
        lines.append(f"mount -t tmpfs -o nosuid,nodev,size={rt.limits.tmp_bytes},"
                     f"nr_inodes={rt.limits.tmp_files},mode=1777 tmpfs {into(d)}")
    for name in _DEVICES:
        if os.path.exists(f"/dev/{name}"):
            lines.append(f": > {into(f'/dev/{name}')}")
            lines.append(f"mount --bind /dev/{name} {into(f'/dev/{name}')}")
    lines.append(f"ln -s /proc/self/fd {into('/dev/fd')}")
    for k, name in enumerate(("stdin", "stdout", "stderr")):
        lines.append(f"ln -s /proc/self/fd/{k} {into(f'/dev/{name}')}")
    for p, src in sources.items():
        lines.append(f"mkdir -p {into(p)}")
        bind_ro(src, p)
    # Hidden paths inside a folder bound in are covered there; the others are not in the root.
    inside = [Path(d).resolve() for d in system if not os.path.islink(d)] + [p.resolve() for p in pythons]
    for p in rt.hidden:
        if os.path.lexists(p) and _within(p.resolve(), inside):
            if p.is_dir():
                lines.append(f"mount -t tmpfs -o ro,nosuid,nodev,noexec,size=4k,mode=0555 tmpfs {into(p.resolve())}")
            else:
                lines.append(f"mount --bind /dev/null {into(p.resolve())}")
    lib = rt.lib_inside()
    lines.append(f"mkdir -p {into(lib)}")
    lines.append(f"mount -t tmpfs -o nosuid,nodev,size=64m,mode=0755 tmpfs {into(lib)}")
    lines.append(f"cp -R {q(lib_src)}/. {into(lib)}")
    lines.append(f"mount -o remount,bind,ro,nosuid,nodev {into(lib)}")
    scratch = workdir.parent
    lines.append("mkdir -p " + " ".join(into(os.path.normpath(workdir / rel)) for rel in ("",) + RESULT_DIRS + SCRATCH_DIRS))
    if (rt.lib / MPL_CACHE).is_dir():
        lines.append(f"cp -R {into(lib / MPL_CACHE)} {into(workdir / '.matplotlib')}")
    if rt.uid is not None:
        lines.append(f"chown -R {rt.uid}:{rt.uid} {into(scratch)}")
    lines.append(f"chmod 700 {into(scratch)} {into(workdir)} "
                 + " ".join(into(os.path.normpath(workdir / rel)) for rel in SCRATCH_DIRS))
    lines.append(f"mount -t proc -o nosuid,nodev,noexec proc {into('/proc')}")
    for n in range(3, fd):
        lines.append(f"exec {n}<&-")
    # The move: the host's tree goes below the new root, then is detached whole.
    pivot = shutil.which("pivot_root") or "/usr/sbin/pivot_root"
    lines += [f"mkdir {into('/.host')}", f"cd {new}", f"{q(pivot)} . .host", "cd /",
              "umount -l /.host", "rmdir /.host", "mount -o remount,bind,ro,nosuid,nodev /"]
    return lines


def _covered_host_tree(rt: Runtime) -> list[str]:
    """Lines that leave the host's tree in place and cover each hidden path with an empty mount
    (without a private /tmp: the mount table then names what it covers)."""
    q = shlex.quote
    lines: list[str] = []
    for p in rt.hidden:
        if not os.path.lexists(p):
            continue  # gone since the sandbox was made: nothing left to hide
        if p.is_dir():
            lines.append(f"mount -t tmpfs -o ro,nosuid,nodev,noexec,size=4k,mode=0555 tmpfs {q(str(p))}")
        else:
            lines.append(f"mount --bind /dev/null {q(str(p))}")
    return lines


def _within(path: Path, folders: list[Path]) -> bool:
    """Whether ``path`` is one of ``folders`` or lies inside one."""
    return any(path == f or f in path.parents for f in folders)
