"""The program that runs a student's code inside the sandbox (``python -I -B child.py --result-fd N``).

Everything here runs as the student: it imports only the standard library, numpy and the kit's
``core.wire`` and ``core.refine_switch`` (from the kit packages the sandbox exposes, never the
autograder or the solutions, nor ``starter``, which would load scipy into every child), and
whatever it writes is judged by the grader as untrusted data.

The protocol is a session (the grader's side is ``autograder/sandbox/session.py``):

- stdin carries requests, one JSON object per line.  The first one says what to load:
  ``{"units": [{origin, line, source, future}], "load_timeout", "sys_path", "max_result_bytes",
  "max_message"}``: top-level code of the student's notebooks, executed in order in one fresh
  module namespace named ``__main__``.  Every later line is a call:
  ``{"id", "function", "args", "inputs", "seconds", "budget", "figure", "clock", "swap"}``: call ``function`` once
  per entry of ``inputs`` (``{"args", "kwargs"}``), each time on fresh copies of ``args`` followed
  by the entry's own arguments (all in the wire format of ``core/wire.py``); stop starting new
  inputs after ``budget`` seconds and stop the call itself after ``seconds`` (wall-clock seconds,
  or with ``clock`` "cpu" CPU seconds of this process: ITIMER_PROF and ``time.process_time``; the
  grader kills a call that waits instead of computing).  With ``figure``,
  what is reported for an input is the (K, 3) points its 3D figures show, not the returned value.
  With ``swap`` ``{"refineF": "off"}``, refineF is switched off for the duration of the call
  (``core.refine_switch.switched_off``, the switch the public self-check throws too): by every
  route to it, refineF returns the closest rank-2 matrix to its F, unit norm, without minimising;
  each input's record then says how many times refineF was called while it ran (``refineF_calls``).
- the result pipe (file descriptor N) receives one JSON record per line:
  ``{"event": "loaded", "errors": [{origin, message}], "defined": [names]}``; then per call
  ``{"event": "start", "id"}``, ``{"event": "missing", "id", "message"}`` when the function is not
  there, one ``{"event": "item", "id", "index", "status", "value" | "message", "seconds"}`` per
  input (status ok, exception, malformed, timeout or skipped; with ``swap``, also
  ``"refineF_calls"``: an int, for an input that ran) and ``{"event": "end", "id"}``, with
  ``"restart": why`` when what the call left behind could not be undone (``_Leaks``): the grader
  then starts a fresh child for the next request.
- stdout and stderr belong to the student; the grader keeps a bounded copy and trusts neither.
- the child's own stdin is /dev/null for the student's code (the requests arrive on a copy).
"""

import json
import os
import signal
import sys
import time
import types

_MAIN_PID = os.getpid()


class _Timeout(BaseException):
    """Raised by the alarm handler; a BaseException so ``except Exception`` does not swallow it."""


_armed = False


def _on_alarm(signum, frame):
    if _armed:
        raise _Timeout()


def _arm(seconds, clock="wall"):
    """Stop what runs after ``seconds``: wall-clock seconds (ITIMER_REAL, SIGALRM) or, with
    clock "cpu", CPU seconds of this process (ITIMER_PROF, SIGPROF: user and system time)."""
    global _armed
    _armed = True
    if clock == "cpu":
        signal.signal(signal.SIGPROF, _on_alarm)
        signal.setitimer(signal.ITIMER_PROF, max(float(seconds), 0.001))
    else:
        signal.signal(signal.SIGALRM, _on_alarm)
        signal.setitimer(signal.ITIMER_REAL, max(float(seconds), 0.001))


def _disarm():
    global _armed
    _armed = False
    signal.setitimer(signal.ITIMER_REAL, 0)
    signal.setitimer(signal.ITIMER_PROF, 0)


# seccomp: per machine this filter knows, the audit architecture and the numbers of the syscalls it
# refuses.  Two lists, reviewed against the whole syscall table of each machine (everything not
# listed is either harmless to other submissions or already needs a capability the code lacks):
#
# - ALWAYS, at every level, namespaces included (these kernel objects are not namespaced by the
#   pid, mount, net, ipc or uts namespaces, or escape the memory limit):
#   keyctl, add_key, request_key: a uid's keyrings outlive its processes, so one submission could
#     leave a note that the next one (the same sandbox uid) reads;
#   memfd_create, memfd_secret: anonymous files whose pages RLIMIT_AS does not count (gigabytes
#     past the memory limit);
#   userfaultfd, perf_event_open, bpf: kernel interfaces no homework needs, each a known way to
#     stall, observe or attack other processes;
#   unshare, setns, and clone with a namespace flag: new namespaces would give the code a /tmp or
#     /dev/shm of its own outside the limits and the clean-up's reach; clone3 (whose flags a
#     filter cannot read) answers ENOSYS, so the C library falls back to clone, as under Docker.
# - SOCKETS, where no network and ipc namespace exists (the uid and basic levels): socket() of every
#   family (IPv4 and IPv6, and Unix sockets, by path or in the abstract namespace, which two
#   sandboxes of one machine could meet through), io_uring_setup() (io_uring can open sockets
#   without calling socket()), and the System V and POSIX IPC objects that any uid may name:
#   shmget, semget, msgget, mq_open.  socketpair() is another syscall and stays allowed: it makes a
#   connected pair no other process can join (multiprocessing's Pipe(duplex=True) uses it).
#
# Allowed on purpose: ptrace, process_vm_readv, kill and pidfd_* reach only the code's own
# processes (its own uid; the grader's are root's or another uid's), and everything of its uid is
# killed after each child.
_SECCOMP_ARCH = {
    "x86_64": (0xC000003E, {
        "always": {"keyctl": 250, "add_key": 248, "request_key": 249, "memfd_create": 319, "memfd_secret": 447,
                   "userfaultfd": 323, "perf_event_open": 298, "bpf": 321, "unshare": 272, "setns": 308},
        "sockets": {"socket": 41, "io_uring_setup": 425, "shmget": 29, "semget": 64, "msgget": 68, "mq_open": 240},
        "clone": 56, "clone3": 435}),
    "aarch64": (0xC00000B7, {
        "always": {"keyctl": 219, "add_key": 217, "request_key": 218, "memfd_create": 279, "memfd_secret": 447,
                   "userfaultfd": 282, "perf_event_open": 241, "bpf": 280, "unshare": 97, "setns": 268},
        "sockets": {"socket": 198, "io_uring_setup": 425, "shmget": 194, "semget": 190, "msgget": 186, "mq_open": 180},
        "clone": 220, "clone3": 435}),
}
# CLONE_NEWNS, CLONE_NEWCGROUP, CLONE_NEWUTS, CLONE_NEWIPC, CLONE_NEWUSER, CLONE_NEWPID, CLONE_NEWNET.
_CLONE_NAMESPACES = 0x00020000 | 0x02000000 | 0x04000000 | 0x08000000 | 0x10000000 | 0x20000000 | 0x40000000


def _filter_program(arch, table, sockets):
    """The classic BPF program of the filter: a list of (code, jt, jf, k)."""
    ld, jeq, jge, jset, ret = 0x20, 0x15, 0x35, 0x45, 0x06   # BPF_LD|W|ABS, JMP|JEQ|K, JMP|JGE|K, JMP|JSET|K, RET|K
    allow, eacces, enosys = 0x7FFF0000, 0x00050000 | 13, 0x00050000 | 38   # SECCOMP_RET_ALLOW, RET_ERRNO|errno
    refused = sorted({**table["always"], **(table["sockets"] if sockets else {})}.values())
    # Instructions with symbolic targets, resolved below (a jump's offsets count from the next one).
    code = [(ld, None, None, 4),                              # the architecture
            (jeq, None, "deny", arch),                        # another ABI (x32, int 0x80): deny
            (ld, None, None, 0),                              # the syscall number
            (jge, "deny", None, 0x40000000)]                  # x32 syscalls: deny
    code += [(jeq, "deny", None, nr) for nr in refused]
    code += [(jeq, "enosys", None, table["clone3"]),
             (jeq, None, "allow", table["clone"]),
             (ld, None, None, 16),                            # clone's flags (the low half of args[0])
             (jset, "deny", "allow", _CLONE_NAMESPACES)]
    labels = {"allow": len(code), "deny": len(code) + 1, "enosys": len(code) + 2}
    code += [(ret, None, None, allow), (ret, None, None, eacces), (ret, None, None, enosys)]
    return [(op, 0 if jt is None else labels[jt] - i - 1, 0 if jf is None else labels[jf] - i - 1, k)
            for i, (op, jt, jf, k) in enumerate(code)]


def install_filter(sockets):
    """Refuse this process and everything it starts the syscalls of the lists above (``ALWAYS``, and
    ``SOCKETS`` too when ``sockets``): None when done, else why not.

    A seccomp filter (no capability needed once PR_SET_NO_NEW_PRIVS is set, so it works under
    Docker's default capabilities): the refused calls fail with EACCES, and so does every syscall
    of another ABI (x32, or 32-bit calls through int 0x80, which would go around the numbers
    checked).  With ``sockets``, socketpair() and pipes keep working, and so do multiprocessing's
    fork-based Process, Pool and Queue (pipes, and POSIX semaphores in /dev/shm); what needs a
    listening socket (multiprocessing's Manager, the forkserver start method) does not.  Must run
    before any thread starts (the filter covers the calling thread and those it starts later).
    """
    import ctypes
    import platform
    import struct

    found = _SECCOMP_ARCH.get(platform.machine())
    if found is None:
        return f"no seccomp filter for the {platform.machine()} architecture"
    program = _filter_program(*found, sockets)
    code = b"".join(struct.pack("HBBI", *ins) for ins in program)
    buffer = ctypes.create_string_buffer(code, len(code))

    class SockFprog(ctypes.Structure):
        _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]

    prog = SockFprog(len(program), ctypes.addressof(buffer))
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong]
    if libc.prctl(38, 1, None, 0, 0) != 0:            # PR_SET_NO_NEW_PRIVS
        return f"PR_SET_NO_NEW_PRIVS failed: {os.strerror(ctypes.get_errno())}"
    if libc.prctl(22, 2, ctypes.byref(prog), 0, 0) != 0:  # PR_SET_SECCOMP, SECCOMP_MODE_FILTER
        return f"the seccomp filter was refused: {os.strerror(ctypes.get_errno())}"
    return None


def refused_calls_that_work():
    """The names of the ALWAYS list's calls this process can still make (after ``install_filter``
    nothing: the probe of every level checks it)."""
    import ctypes
    import platform

    found = _SECCOMP_ARCH.get(platform.machine())
    if found is None:
        return ["(no filter for this architecture)"]
    libc = ctypes.CDLL(None, use_errno=True)
    works = []
    for name in ("keyctl", "add_key", "memfd_create", "unshare"):
        # Harmless arguments: KEYCTL_GET_KEYRING_ID of the session keyring without creating it, a key
        # of an unknown type, a memfd of no size, unshare of nothing.
        args = {"keyctl": (0, -3, 0), "add_key": (b"hw4-none", b"x", None, 0, -3), "memfd_create": (b"hw4", 0),
                "unshare": (0,)}[name]
        nr = found[1]["always"][name]
        result = libc.syscall(ctypes.c_long(nr), *[a if isinstance(a, bytes) or a is None else ctypes.c_long(a)
                                                    for a in args])
        errno = ctypes.get_errno()
        if result >= 0:
            if name == "memfd_create":
                os.close(result)
            works.append(name)
        elif errno != 13:  # EACCES is the filter's answer; any other error came from the kernel itself
            works.append(name)
    return works


class _Channel:
    """Writes newline-terminated JSON records to the result pipe; only the first process may."""

    def __init__(self, fd):
        self.fd = fd

    def send(self, record):
        if os.getpid() != _MAIN_PID:
            os._exit(0)
        data = (json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n").encode()
        view = memoryview(data)
        while view:
            try:
                n = os.write(self.fd, view)
            except InterruptedError:
                continue
            except OSError:
                os._exit(3)  # the grader is gone or the student closed the pipe: nothing to report to
            view = view[n:]


# ---------------------------------------------------------------------------------------------
# what one request may leave behind in this process, undone before the next


_RLIMITS = ("RLIMIT_NOFILE", "RLIMIT_NPROC", "RLIMIT_AS", "RLIMIT_FSIZE", "RLIMIT_CPU", "RLIMIT_STACK", "RLIMIT_CORE")


def _open_fds():
    """The file descriptors open in this process (the listing's own descriptor left out)."""
    import fcntl

    try:
        listed = [int(x) for x in os.listdir("/proc/self/fd")]
    except OSError:
        import resource

        listed = range(min(resource.getrlimit(resource.RLIMIT_NOFILE)[0], 65536))
    found = set()
    for fd in listed:
        try:
            fcntl.fcntl(fd, fcntl.F_GETFD)
            found.add(fd)
        except OSError:
            pass
    return found


def _thread_count():
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        import threading

        return threading.active_count()


class _Leaks:
    """The process state one request of student code may change and the next must not inherit.

    ``_Leaks(keep)`` records it before a request; ``undo()`` afterwards puts back what can be put
    back: file descriptors opened and left open are closed (not those in ``keep``, the protocol's),
    fds 0, 1 and 2 point where they pointed (a call that sent them to /dev/null, or closed them),
    the working folder, os.environ, signal handlers and the blocked-signal mask, the umask,
    sys.stdin/stdout/stderr, trace and profile hooks, the recursion limit and switch interval,
    the garbage collector's switch, numpy's floating-point error handling, the warnings filters
    and the soft resource limits; unreaped processes the request started are reaped.  ``undo``
    returns the reasons it could not (threads still running, processes the request started still
    there, a hard limit lowered, a folder that is gone): then the grader starts a fresh
    process before the next request, so one question's leak never costs another question.
    """

    def __init__(self, keep, std, own_uid=False):
        import gc
        import resource
        import threading
        import warnings

        self.keep, self.std = set(keep), tuple(std)
        self.fds = _open_fds()
        self.cwd = os.getcwd()
        self.environ = dict(os.environ)
        self.handlers = {}
        for sig in signal.valid_signals():
            if sig in (signal.SIGKILL, signal.SIGSTOP):
                continue
            try:
                self.handlers[sig] = signal.getsignal(sig)
            except (ValueError, OSError):
                pass
        self.mask = signal.pthread_sigmask(signal.SIG_BLOCK, [])
        self.umask = os.umask(0o077)
        os.umask(self.umask)
        self.streams = (sys.stdin, sys.stdout, sys.stderr)
        self.hooks = (sys.gettrace(), sys.getprofile(), threading.gettrace(), threading.getprofile())
        self.numbers = (sys.getrecursionlimit(), sys.getswitchinterval(), gc.isenabled())
        numpy = sys.modules.get("numpy")
        self.numpy_err = numpy.geterr() if numpy is not None else None
        self.warnings = list(warnings.filters)
        self.limits = {}
        for name in _RLIMITS:
            which = getattr(resource, name, None)
            if which is not None:
                self.limits[which] = resource.getrlimit(which)
        self.threads = _thread_count()
        self.own_uid = own_uid
        self.last_pid = _last_pid()
        if self.last_pid is None or self.last_pid != _LISTED[0]:
            _LISTED[:] = [self.last_pid, frozenset(_processes(own_uid))]
        self.processes = _LISTED[1]  # a pid gone since is harmless here: reusing it moves the last pid

    def undo(self):
        """Put the recorded state back; the list of what could not be."""
        import gc
        import resource
        import threading
        import warnings

        lost = []
        sys.stdin, sys.stdout, sys.stderr = self.streams
        for fd, saved in zip((0, 1, 2), self.std):
            try:
                os.dup2(saved, fd)
            except OSError:
                lost.append(f"fd {fd} could not be restored")
        for fd in sorted(_open_fds() - self.fds - self.keep - set(self.std) - {0, 1, 2}):
            try:
                os.close(fd)
            except OSError:
                pass
        try:
            os.chdir(self.cwd)
        except OSError:
            lost.append("the working folder is gone")
        if dict(os.environ) != self.environ:
            for k in [k for k in os.environ if k not in self.environ]:
                del os.environ[k]
            for k, v in self.environ.items():
                if os.environ.get(k) != v:
                    os.environ[k] = v
        for sig, handler in self.handlers.items():
            try:
                if handler is not None and signal.getsignal(sig) is not handler:
                    signal.signal(sig, handler)
            except (ValueError, OSError, TypeError):
                lost.append(f"the handler of signal {sig} could not be restored")
        signal.pthread_sigmask(signal.SIG_SETMASK, self.mask)
        os.umask(self.umask)
        sys.settrace(self.hooks[0])
        sys.setprofile(self.hooks[1])
        threading.settrace(self.hooks[2])
        threading.setprofile(self.hooks[3])
        try:
            sys.setrecursionlimit(self.numbers[0])
        except (RecursionError, ValueError):
            lost.append("the recursion limit could not be restored")
        sys.setswitchinterval(self.numbers[1])
        (gc.enable if self.numbers[2] else gc.disable)()
        numpy = sys.modules.get("numpy")
        if numpy is not None and self.numpy_err is not None:
            try:
                numpy.seterr(**self.numpy_err)
            except Exception:  # noqa: BLE001 - a student may have replaced numpy.seterr
                lost.append("numpy's error handling could not be restored")
        warnings.filters[:] = self.warnings
        getattr(warnings, "_filters_mutated", lambda: None)()  # drop the caches of the old filters
        for which, saved in self.limits.items():
            try:
                if resource.getrlimit(which) != saved:
                    resource.setrlimit(which, saved)
            except (OSError, ValueError):
                lost.append("a resource limit was lowered for good")
        # A thread just joined may still be listed for a moment (its OS thread ends after join returns).
        end = time.monotonic() + 0.5
        while _thread_count() > self.threads and time.monotonic() < end:
            time.sleep(0.01)
        if _thread_count() > self.threads:
            lost.append("threads it started are still running")
        # A process the call started and left (a fork bomb's copies, a daemon, an unreaped child)
        # holds places under the process limit that the next question's code would miss.
        if self.last_pid is None or _last_pid() != self.last_pid:  # else nothing was started
            end = time.monotonic() + 0.5
            left = self._reap_new()
            while left and time.monotonic() < end:
                time.sleep(0.01)
                left = self._reap_new()
            if left:
                lost.append(f"{len(left)} processes it started outlived the call")
        return lost

    def _reap_new(self) -> set:
        """The processes started since the request began that are still there, after reaping
        those of them that are this process's ended children."""
        new = _processes(self.own_uid) - self.processes
        for pid in new:
            try:
                os.waitpid(pid, os.WNOHANG)
            except OSError:
                pass
        return _processes(self.own_uid) - self.processes if new else new


def _last_pid():
    """The last pid the kernel handed out in this pid namespace (None if unknown): while it stays
    the same, no process or thread was created, so a listing need not be made again."""
    try:
        with open("/proc/loadavg", "rb") as f:
            return int(f.read().split()[-1])
    except (OSError, ValueError, IndexError):
        return None


_LISTED: list = [None, frozenset()]  # the last pid at the last listing, and that listing


def _processes(own_uid):
    """Pids, other than this process's, that this child answers for: every process of its uid
    when the uid is the sandbox's own (``own_uid``: a process the code started and left to the
    machine's init is still found), else its descendants (the grader's uid runs other things).
    Zombies are included: an unreaped one still holds a place under the process limit."""
    me, uid = os.getpid(), b"\nUid:\t%d\t" % os.getuid()
    parents = {}
    try:
        names = os.listdir("/proc")
    except OSError:
        return set()
    for name in names:
        if not name.isdigit() or int(name) == me:
            continue
        try:
            # status, not the folder's owner: a process that made itself undumpable shows as root's.
            fd = os.open(f"/proc/{name}/status", os.O_RDONLY)
            try:
                text = os.read(fd, 4096)
            finally:
                os.close(fd)
            if uid in text:
                at = text.index(b"\nPPid:\t") + 7
                parents[int(name)] = int(text[at:text.index(b"\n", at)])
        except (OSError, ValueError):
            continue
    found = set(parents)
    if not own_uid:
        found, grew = {me}, True
        while grew:
            grew = False
            for pid, ppid in parents.items():
                if ppid in found and pid not in found:
                    found.add(pid)
                    grew = True
        found.discard(me)
    return found


def _save_std():
    """Copies of fds 0, 1 and 2 as they are before any student code (close-on-exec, so the code's
    own processes do not inherit them); ``_Leaks.undo`` puts them back after every request."""
    import fcntl

    return tuple(fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 3) for fd in (0, 1, 2))


# ---------------------------------------------------------------------------------------------
# the kit's refineF, computed by the grader


class _GraderHelper:
    """What the kit's refineF calls in this process (``core.refine_switch.set_grader_helper``): it
    sends ``{"event": "helper", "id", "seq", "name": "refineF", "args"}`` and waits for the grader's
    ``{"reply": seq, "value" | "error"}`` line on the requests' pipe.  The grader decides whether
    the minimisation is switched off, so nothing the code changes here brings it back.  Only the
    graded function's own thread, during its call, may ask (the pipe is the protocol's)."""

    def __init__(self, channel, requests, wire):
        import threading

        self.channel, self.requests, self.wire = channel, requests, wire
        self.thread = threading.get_ident()
        self.rid = None   # the call in progress
        self.seq = 0

    def __call__(self, F, pts1, pts2):
        import threading

        if self.rid is None or os.getpid() != _MAIN_PID or threading.get_ident() != self.thread:
            raise RuntimeError("refineF: in the grader it runs only within a call of a graded function, "
                               "in its own thread and process")
        self.seq += 1
        self.channel.send({"event": "helper", "id": self.rid, "seq": self.seq, "name": "refineF",
                           "args": self.wire.encode_returned((F, pts1, pts2))})
        while True:
            line = self.requests.readline()
            if not line:
                os._exit(3)  # the grader is gone
            reply = json.loads(line)
            if reply.get("reply") == self.seq:
                break        # an older reply (its wait cut short by the call's timer) is skipped
        if "error" in reply:
            raise ValueError(str(reply["error"]))
        return self.wire.decode(reply["value"])


# ---------------------------------------------------------------------------------------------
# reporting student errors without any grader frame


def _describe(exc, origins, limit):
    """'Type: message (in f, <origin> line n)' with only the student's innermost frame."""
    name = type(exc).__name__
    try:
        text = str(exc)
    except _Timeout:
        raise
    except BaseException:  # noqa: BLE001 - a student's __str__ may raise anything
        text = "<the exception's message could not be read>"
    if len(text) > limit:
        text = text[:limit] + " [...]"
    where = ""
    tb = exc.__traceback__
    while tb is not None:
        code = tb.tb_frame.f_code
        if code.co_filename in origins:
            where = f" (in {code.co_name}, {code.co_filename[1:-1]}, line {tb.tb_lineno})"
        tb = tb.tb_next
    return f"{name}: {text}{where}" if text else f"{name}{where}"


# ---------------------------------------------------------------------------------------------


def load_units(units, module, timeout, origins, limit):
    errors = []
    flags = 0
    _arm(timeout)
    try:
        for unit in units:
            filename = f"<{unit['origin']}>"
            origins.add(filename)
            source = "\n" * (max(int(unit.get("line", 1)), 1) - 1) + unit["source"]
            try:
                code = compile(source, filename, "exec", flags=flags, dont_inherit=True)
                exec(code, module.__dict__)  # noqa: S102 - running the student's code is the point
            except _Timeout:
                errors.append({"origin": unit["origin"], "message": f"loading took more than {timeout:g} s"})
                break
            except BaseException as exc:  # noqa: BLE001 - any failure of student code is reported
                errors.append({"origin": unit["origin"], "message": _describe(exc, origins, limit)})
            if os.getpid() != _MAIN_PID:
                os._exit(0)
            for feature in unit.get("future", ()):
                flags |= getattr(__import__("__future__"), feature).compiler_flag
    except _Timeout:
        errors.append({"origin": "loading", "message": f"loading took more than {timeout:g} s"})
    finally:
        _disarm()
    return errors


class StudentModules:
    """Meta-path importer of the student's own .py files: the units with a "module" key are that
    module's body, run unit by unit like the others (served from the job, never read from disk;
    last on sys.meta_path, so the standard library and the kit's packages keep their names)."""

    def __init__(self, units, origins, limit):
        self.bodies, self.origins, self.limit, self.errors = {}, origins, limit, []
        for unit in units:
            self.bodies.setdefault(unit["module"], []).append(unit)

    def find_spec(self, name, path=None, target=None):
        if name not in self.bodies:
            return None
        from importlib.machinery import ModuleSpec

        package = any(other.startswith(name + ".") for other in self.bodies)
        return ModuleSpec(name, self, origin=self.bodies[name][0]["origin"], is_package=package)

    def create_module(self, spec):
        return None

    def exec_module(self, module):
        flags = 0
        for unit in self.bodies[module.__name__]:
            filename = f"<{unit['origin']}>"
            self.origins.add(filename)
            source = "\n" * (max(int(unit.get("line", 1)), 1) - 1) + unit["source"]
            try:
                exec(compile(source, filename, "exec", flags=flags, dont_inherit=True), module.__dict__)  # noqa: S102
            except _Timeout:
                raise
            except BaseException as exc:  # noqa: BLE001 - reported like the errors of the other units
                self.errors.append({"origin": unit["origin"], "message": _describe(exc, self.origins, self.limit)})
            if os.getpid() != _MAIN_PID:
                os._exit(0)
            for feature in unit.get("future", ()):
                flags |= getattr(__import__("__future__"), feature).compiler_flag


def copy_arguments(x, np):
    """Fresh copies, so that a function mutating its inputs cannot change the next input's."""
    if type(x) is np.ndarray:
        return x.copy()
    if type(x) in (list, tuple):
        return type(x)(copy_arguments(v, np) for v in x)
    if type(x) is dict:
        return {k: copy_arguments(v, np) for k, v in x.items()}
    return x


def _drawn_points(figure, np):
    """(K, 3) coordinates drawn in a matplotlib 3D figure or a plotly figure (empty if none)."""
    found = []
    try:
        traces = getattr(figure, "data", None)
        if isinstance(traces, (tuple, list)):
            for tr in traces:
                xyz = [getattr(tr, k, None) for k in ("x", "y", "z")]
                if all(v is not None for v in xyz):
                    found.append(np.column_stack([np.asarray(v, float).ravel() for v in xyz]))
        for ax in getattr(figure, "axes", None) or []:
            for line in getattr(ax, "lines", []):
                if hasattr(line, "get_data_3d"):
                    found.append(np.column_stack([np.asarray(v, float).ravel() for v in line.get_data_3d()]))
            for coll in getattr(ax, "collections", []):
                offsets = getattr(coll, "_offsets3d", None)
                if offsets is not None:
                    found.append(np.column_stack([np.asarray(v, float).ravel() for v in offsets]))
    except _Timeout:
        raise
    except Exception:  # noqa: BLE001, S110 - whatever cannot be read was not drawn
        pass
    found = [f for f in found if f.ndim == 2 and f.shape[1] == 3]
    return np.concatenate(found) if found else np.zeros((0, 3))


def figures_points(value, before, np):
    """The 3D points shown by the returned object (a figure, or an object holding figures) and by
    every pyplot figure opened since ``before`` (a set of figure numbers)."""
    figures = [value]
    for attr in ("plotly", "matplotlib", "figure", "fig"):
        try:
            figures.append(getattr(value, attr, None))
        except _Timeout:
            raise
        except Exception:  # noqa: BLE001, S110 - a hostile attribute is no figure
            pass
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        figures += [plt.figure(k) for k in sorted(set(plt.get_fignums()) - before)]
    points = [_drawn_points(f, np) for f in figures if f is not None]
    drawn = np.concatenate(points) if points else np.zeros((0, 3))
    return drawn[:100000]


def figure_numbers():
    plt = sys.modules.get("matplotlib.pyplot")
    try:
        return set(plt.get_fignums()) if plt is not None else set()
    except Exception:  # noqa: BLE001 - a student may have replaced pyplot
        return set()


def refine_switch_for(fn, swap):
    """The context of one call under a request's ``swap``: refineF switched off for ``fn`` with
    ``{"refineF": "off"}`` (``core.refine_switch.switched_off``), else nothing."""
    import contextlib

    if (swap or {}).get("refineF") != "off":
        return contextlib.nullcontext()
    from core import refine_switch

    return refine_switch.switched_off(fn)


def _refine_calls(run):
    """How many times refineF was called so far in ``run`` (the ``Switch`` a switched-off request
    entered, or None): an int in [0, 2**31], 0 when its count is not an int."""
    try:
        n = vars(run).get("calls", 0) if run is not None else 0
    except Exception:  # noqa: BLE001 - whatever the student did to it, nothing is counted
        return 0
    return min(max(n, 0), 2**31) if type(n) is int else 0


def call_request(request, fn, channel, origins, limit, max_bytes, wire, np, *, main_pid=None):
    """Run one request: ``fn`` on each input within the request's time limits, one record per input
    sent on ``channel`` (anything with ``send(record)``).  The one call function: the child runs
    every request with it, and the grader's in-process stand-in for tests of the checks
    (``autograder.hidden.plugin.LocalStudent``) too, passing its own pid as ``main_pid`` (the
    process whose records count; a process the code forked exits instead of reporting)."""
    main_pid = _MAIN_PID if main_pid is None else main_pid
    rid = request["id"]
    seconds = float(request["seconds"])
    budget = float(request.get("budget") or seconds)
    inputs = request.get("inputs") or [{}]
    figure = bool(request.get("figure"))
    shared = wire.decode(request.get("args", {"__tuple__": []}), wire.Limits(max_array_bytes=2**31,
                                                                            max_total_bytes=2**32))
    # An input's own limit (None: the request's): a hung first input then costs its own share, not
    # every input's.
    each = request.get("each")
    each = float(each) if type(each) in (int, float) and 0 < each < seconds else None
    clock = "cpu" if request.get("clock") == "cpu" else "wall"
    now = time.process_time if clock == "cpu" else time.monotonic

    def over(allowed):
        return f"used more than {allowed:g} s of CPU time" if clock == "cpu" else f"took more than {allowed:g} s"

    # Left in the finally below, after the timer is disarmed: no alarm may cut the putting back short.
    switch = refine_switch_for(fn, request.get("swap"))
    run = switch.__enter__()  # refineF switched off: the Switch counting its calls; else None
    start = now()
    timed_out = exhausted = False
    _arm(seconds, clock)
    try:
        for index, item in enumerate(inputs):
            record = {"event": "item", "id": rid, "index": index}
            t0 = time.perf_counter()
            if timed_out or now() - start > budget:
                record.update(status="skipped", message=f"not run: {request['function']} used up its time "
                              "on the earlier inputs")
                channel.send(record)
                continue
            if exhausted:
                record.update(status="skipped", message=f"not run: {request['function']} ran out of memory "
                              "on an earlier input")
                channel.send(record)
                continue
            counted = _refine_calls(run)
            allowed = seconds
            if each is not None and each < seconds - (now() - start):
                allowed = each
                _arm(each, clock)
            try:
                try:
                    args = list(copy_arguments(shared, np)) + list(wire.decode(item.get("args", {"__tuple__": []})))
                    kwargs = wire.decode(item.get("kwargs", {"__dict__": {}}))
                    before = figure_numbers() if figure else set()
                    value = fn(*args, **kwargs)
                    if figure:
                        value = figures_points(value, before, np)
                    record.update(status="ok", value=wire.encode_returned(value))
                except _Timeout:
                    timed_out = True
                    record.update(status="timeout", message=over(allowed))
                except wire.Unsupported as exc:
                    record.update(status="malformed", message=str(exc))
                except MemoryError as exc:
                    # Each attempt fills the memory limit (seconds of zeroed pages): never again.
                    exhausted = True
                    record.update(status="exception", message=_describe(exc, origins, limit), exhausted=True)
                except BaseException as exc:  # noqa: BLE001 - SystemExit and friends included
                    record.update(status="exception", message=_describe(exc, origins, limit))
                if run is not None:
                    record["refineF_calls"] = min(max(_refine_calls(run) - counted, 0), 2**31)
            except _Timeout:
                timed_out = True
                record.update(status="timeout", message=over(allowed))
            except BaseException:  # noqa: BLE001 - e.g. a message whose __str__ itself failed
                record.update(status="exception", message="the code raised an exception that could not be described")
            if os.getpid() != main_pid:
                os._exit(0)  # a process the student forked must never report
            if allowed != seconds:  # back to the request's own limit
                left = seconds - (now() - start)
                if left > 0:
                    _arm(left, clock)
                else:
                    _disarm()  # the budget check skips what is left
            record["seconds"] = round(time.perf_counter() - t0, 6)
            if record["status"] == "ok":
                size = len(json.dumps(record["value"], allow_nan=False))
                if size > max_bytes:
                    record = {"event": "item", "id": rid, "index": index, "status": "malformed",
                              "seconds": record["seconds"],
                              "message": f"the returned value is too large ({size} bytes encoded, limit {max_bytes})"}
            channel.send(record)
    except _Timeout:
        pass  # fired between inputs: the remaining ones are reported as skipped by the grader
    finally:
        _disarm()
        switch.__exit__(None, None, None)
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        try:
            plt.close("all")  # figures of one call must not pile up in memory
        except Exception:  # noqa: BLE001, S110 - a student may have replaced pyplot
            pass


def main(argv):
    # First, while this process has one thread: student code must never run without the filter.
    why = install_filter(sockets="--deny-internet" in argv)
    if why is not None:
        sys.stderr.write(f"sandbox: the syscall filter could not be installed ({why})\n")
        os._exit(70)
    fd = int(argv[argv.index("--result-fd") + 1])
    own_uid = "--own-uid" in argv
    os.set_inheritable(fd, False)
    channel = _Channel(fd)
    requests = os.fdopen(os.dup(0), "rb")
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)  # input() in student code gets EOF, never a request
    std = _save_std()  # before any student code: what fds 0, 1 and 2 are put back to after each request
    sys.stdin = open(os.devnull)  # noqa: SIM115
    job = json.loads(requests.readline())
    os.environ["MPLBACKEND"] = "Agg"
    sys.path[:0] = list(job.get("sys_path", []))
    import numpy as np

    from core import wire

    limit = int(job.get("max_message", 500))
    max_bytes = int(job.get("max_result_bytes", 64 * 2**20))

    from core import refine_switch

    grader = _GraderHelper(channel, requests, wire)
    refine_switch.set_grader_helper(grader)

    module = types.ModuleType("__main__")
    module.__dict__["__builtins__"] = __builtins__
    sys.modules["__main__"] = module  # classes the student defines need their module registered
    origins = set()
    units = job.get("units", [])
    modules = StudentModules([u for u in units if u.get("module")], origins, limit)
    sys.meta_path.append(modules)
    errors = load_units([u for u in units if not u.get("module")], module, float(job.get("load_timeout", 60)), origins, limit)
    errors += modules.errors
    defined = sorted(k for k, v in list(module.__dict__.items())
                     if not k.startswith("__") and isinstance(v, (types.FunctionType, type)))[:2000]
    channel.send({"event": "loaded", "errors": errors[:200], "defined": defined})

    while True:
        line = requests.readline()
        if not line:
            break
        request = json.loads(line)
        if "reply" in request:
            continue  # the grader's answer to a helper call whose wait the call's timer cut short
        rid, name = request["id"], request["function"]
        channel.send({"event": "start", "id": rid})
        fn = module.__dict__.get(name)
        end = {"event": "end", "id": rid}
        if not callable(fn):
            what = "is not defined" if name not in module.__dict__ else "is not a function"
            channel.send({"event": "missing", "id": rid, "message": f"{name} {what}"})
        else:
            # What the call leaves behind (fds, the working folder, signal handlers...) is undone
            # before the next request: the next question's functions start where this one started.
            leaks = _Leaks((fd, requests.fileno(), devnull), std, own_uid)
            grader.rid = rid
            try:
                call_request(request, fn, channel, origins, limit, max_bytes, wire, np)
            finally:
                grader.rid = None
            lost = leaks.undo()
            if lost:
                end["restart"] = "; ".join(dict.fromkeys(lost))[:500]
        channel.send(end)
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except BaseException:  # noqa: BLE001, S110 - a student may have replaced the stream
                pass
    os._exit(0)  # skip interpreter teardown and any atexit hook the student registered


if __name__ == "__main__":
    main(sys.argv)
