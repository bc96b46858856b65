"""The grader's side of the session protocol (the child's side, and the record format, are in child.py).

A ``Session`` holds one submission's code loaded in a sandboxed child and answers calls one at a
time: ``call(function, *args, seconds=...)`` for one input, ``map(function, inputs, ...)`` for
several inputs within one budget.  A call's ``seconds`` are wall-clock seconds or CPU seconds
of the child (``clock``, by default ``limits.clock``): under the CPU clock the child stops a call
that computes too long itself, and the grader kills one that waits instead (sleep, a blocked
read) at ``seconds * limits.wall_factor + limits.grace`` wall-clock seconds; ``CallOutcome.stopped_by``
says which happened.  The child is started on the first call and restarted, lazily,
after a call that crashed it, was killed for overrunning its time or broke the protocol.  A
function that ran out of time, or out of memory (MemoryError: the child skips the rest of the
request too), is not called again in the session (it would most likely do it again, at the
price of its limit each time), and the session as a whole has a time budget.  Loading that crashes or hangs fails every
call without retrying.

Every record is read from a dedicated pipe and decoded by ``core.wire`` with size limits; the
child's stdout and stderr are kept (bounded) for staff and never judged.
"""

from __future__ import annotations

import dataclasses
import fcntl
import json
import math
import os
import selectors
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from core import wire

from . import helpers, script, tree
from .model import CLOCKS, MAX_REFINE_CALLS, CallOutcome, Isolation, SessionInfo
from .script import Runtime
from .uids import (SHARED_TMP_DIRS, files_of_uid, held_open_files, live_pids_of_uid, pick_uid, release_uid,
                   remove_files_of_uid, sweep_uid, usage_of)

__all__ = ["QUOTA_CHECK", "Session", "outcome_of"]

QUOTA_CHECK = 0.25     # seconds between two checks of a child's disk use, where no tmpfs bounds it
_LEAK_RESTARTS = 5     # fresh children per session for calls that left threads running (child._Leaks)

_RESULT_FD_MIN = 100   # above the fds 3..9 the namespace's shell uses
_MAX_LINE_SLACK = 2**20
_ITEM_STATUSES = {"ok", "exception", "timeout", "malformed", "skipped"}
_START_SLACK = 5.0     # seconds the child may take to begin a call it was sent
# Seconds a pid namespace may take to end its processes after its first one was killed: that
# process ends them as it exits, after unshare itself is reaped (the sweep is the backstop).
_NAMESPACE_END = 2.0


class _ProtocolError(Exception):
    pass


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


class _Child:
    """One running child process and its pipes."""

    def __init__(self, proc: subprocess.Popen, result_fd: int, jobdir: Path):
        self.proc, self.r, self.jobdir = proc, result_fd, jobdir
        self.buf = bytearray()
        self.sel = selectors.DefaultSelector()
        self.open: set[int] = set()
        for fd in (result_fd, proc.stdout.fileno(), proc.stderr.fileno()):
            os.set_blocking(fd, False)
            self.sel.register(fd, selectors.EVENT_READ)
            self.open.add(fd)
        self.w = proc.stdin.fileno()
        os.set_blocking(self.w, False)
        self.pending = b""


class Session:
    """Calls of one submission's functions in a sandbox; use as a context manager.

    Parameters
    ----------
    runtime : Runtime
        Where and how the child runs (from the ``Sandbox``).
    isolation : Isolation
        Reported in ``info``.
    units : list of dict
        The code to load: ``{origin, line, source, future}`` (``SourceUnit.to_job()``).
    load_timeout : float
        Seconds to load the units.
    budget : float
        Wall-clock seconds of the whole session; calls after it get "timeout".
    scratch : Path
        A folder of the grader's (mode 0711) for each child's files.
    """

    def __init__(self, runtime: Runtime, isolation: Isolation, units: list[dict], *, load_timeout: float,
                 budget: float, scratch: Path):
        if not (math.isfinite(budget) and budget > 0):
            raise ValueError(f"budget: expected a positive number of seconds, got {budget}")
        self.rt, self.isolation, self.units = runtime, isolation, units
        self.load_timeout = float(load_timeout)
        self.scratch = scratch
        self.started = time.monotonic()
        self.deadline = self.started + budget
        self.out, self.err = _Bounded(runtime.limits.output_bytes), _Bounded(runtime.limits.output_bytes)
        self.wire_limits = wire.Limits(max_array_bytes=runtime.limits.result_bytes,
                                       max_total_bytes=runtime.limits.result_bytes)
        self.child: _Child | None = None
        self.load_errors: tuple = ()
        self.defined: tuple = ()
        self.loaded_once = False
        self.load_failure: CallOutcome | None = None
        self.stopped: dict[str, str | None] = {}  # function -> what stopped it
        self.exhausted: set[str] = set()           # functions that ran out of memory (MemoryError)
        self.spawns = 0
        self.swept = 0
        self.removed = [0, 0]                      # entries, bytes left in the shared temporary folders
        self.not_removed: list[str] = []           # what the code left that could not be removed
        self.survived: list[str] = []              # what of its uid outlived a sweep (for staff)
        self._uid_fd: int | None = None            # the lock of a fresh uid this session took
        self.over_quota: list[str] = []            # what went past the disk quota
        self.disk_stopped: dict[str, str] = {}     # function -> why it is not called again
        self._last_use = (0, 0)                    # the child's disk use at the last check
        self.leak_restarts = 0                     # children replaced for what a call left behind
        self.calls = 0
        self.closed = False
        self._avoid_used_uid()

    # -- public --------------------------------------------------------------------------------

    def call(self, function: str, *args, seconds: float, clock: str | None = None, **kwargs) -> CallOutcome:
        """``function(*args, **kwargs)`` in the sandbox, stopped after ``seconds`` (of ``clock``)."""
        return self.map(function, [(args, kwargs)], seconds=seconds, clock=clock)[0]

    def map(self, function: str, inputs: Sequence, *, args: Sequence = (), seconds: float,
            budget: float | None = None, each: float | None = None, figure: bool = False,
            clock: str | None = None, swap: dict | None = None) -> list[CallOutcome]:
        """``function(*args, *a, **k)`` for each ``(a, k)`` of ``inputs``, one outcome per input.

        seconds: hard limit of the whole request (the child stops it; the grader kills the child
        ``limits.grace`` later, or under the CPU clock ``seconds * limits.wall_factor + grace``
        wall-clock seconds after the request started); budget: no new input is started after it
        (default: seconds; same clock); each: the limit of one input (default: the request's; same
        clock), so that a function that hangs on its first input costs that, not the whole
        request's time; figure: report the (K, 3) points the function's 3D
        figures show instead of its value; clock: "wall" or "cpu" (default ``limits.clock``);
        swap: what is switched off for this call only (``{"refineF": "off"}``: refineF, see the child;
        each outcome's ``refineF_calls`` then says how many times refineF was called on its input).
        Arguments are plain data (``core.wire``); anything else is a grader bug (ValueError).
        """
        if self.closed:
            raise ValueError("session: expected an open session, got a closed one")
        seconds = float(seconds)
        if not (math.isfinite(seconds) and seconds > 0):
            raise ValueError(f"seconds: expected a positive number, got {seconds}")
        clock = self.rt.limits.clock if clock is None else clock
        if clock not in CLOCKS:
            raise ValueError(f"clock: expected one of {CLOCKS}, got {clock!r}")
        try:
            request = {"function": str(function), "args": wire.encode(tuple(args)),
                       "inputs": [{"args": wire.encode(tuple(a)), "kwargs": wire.encode(dict(k))} for a, k in inputs],
                       "seconds": seconds, "budget": float(budget if budget is not None else seconds),
                       "figure": bool(figure), "clock": clock}
            if each is not None:
                request["each"] = float(each)
            if swap:
                request["swap"] = {str(k): str(v) for k, v in dict(swap).items()}
        except (wire.WireError, TypeError, ValueError) as exc:
            raise ValueError(f"{function}: arguments must be plain data ({exc})") from None
        n = len(request["inputs"])
        if n == 0:
            return []
        if time.monotonic() >= self.deadline:
            return [CallOutcome("timeout", message="the submission's time budget ran out before this call ran",
                                stopped_by="budget")] * n
        if function in self.stopped:
            return [CallOutcome("timeout", message=f"not run: {function} was stopped earlier for taking too long",
                                stopped_by=self.stopped[function])] * n
        if function in self.exhausted:
            return [CallOutcome("skipped", message=f"not run: {function} ran out of memory earlier")] * n
        if function in self.disk_stopped:
            return [CallOutcome("skipped", message=f"not run: {function} went past the disk quota earlier")] * n
        if self.load_failure is None and self.child is None:
            self._spawn()
        if self.load_failure is not None:
            return [self.load_failure] * n
        self.calls += 1
        request["id"] = f"r{self.calls}"
        results = self._exchange(request, n)
        for o in results:
            if o.status == "timeout":
                self.stopped.setdefault(function, o.stopped_by)
        if request.get("exhausted"):
            self.exhausted.add(function)
        return results

    def start(self) -> None:
        """Start the child and load the code now (calls do it when needed)."""
        if not self.closed and self.load_failure is None and self.child is None and time.monotonic() < self.deadline:
            self._spawn()

    def restart(self) -> None:
        """End the child now: the next call gets a fresh one, which loads the code again and has seen
        nothing earlier calls were given (their processes and files go with the old child)."""
        self._stop()

    @property
    def info(self) -> SessionInfo:
        return SessionInfo(tuple(self.load_errors), tuple(self.defined), self.out.text(), self.err.text(),
                           self.isolation, time.monotonic() - self.started, self.spawns, self.swept,
                           (self.removed[0], self.removed[1]), tuple(self.over_quota), tuple(self.not_removed),
                           tuple(self.survived))

    def close(self) -> SessionInfo:
        """Stop the child (its whole process tree) and return what happened."""
        if not self.closed:
            self.closed = True
            try:
                self._stop(gently=True)
            finally:
                if self._uid_fd is not None:
                    release_uid(self.rt.uid, self._uid_fd)
                    self._uid_fd = None
        return self.info

    def __enter__(self) -> Session:  # noqa: PYI034
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- the child -----------------------------------------------------------------------------

    def _spawn(self) -> None:
        self.spawns += 1
        jobdir = Path(tempfile.mkdtemp(prefix="job", dir=self.scratch))
        os.chmod(jobdir, 0o711)  # the work folder inside must be reachable by the sandbox's uid
        workdir = script.make_workdir(self.rt, jobdir)
        r, w = os.pipe()
        wfd = fcntl.fcntl(w, fcntl.F_DUPFD_CLOEXEC, _RESULT_FD_MIN)
        os.close(w)
        cpu = math.ceil(max(self.deadline - time.monotonic(), 1.0)) + 5
        try:
            proc = subprocess.Popen(script.command(self.rt, workdir, self.rt.child_argv(wfd), jobdir), stdin=subprocess.PIPE,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, pass_fds=(wfd,),
                                    **script.popen_options(self.rt, workdir, cpu))
        except OSError as exc:
            os.close(r)
            os.close(wfd)
            shutil.rmtree(jobdir, ignore_errors=True)
            self.load_failure = CallOutcome("crashed", message=f"the sandbox could not start ({exc})")
            return
        os.close(wfd)
        self.child = _Child(proc, r, jobdir)
        first = {"units": self.units, "load_timeout": self.load_timeout,
                 "sys_path": [str(self.rt.lib_inside())], "max_result_bytes": self.rt.limits.result_bytes,
                 "max_message": 500}
        self.child.pending = (json.dumps(first, allow_nan=False) + "\n").encode()
        until = min(time.monotonic() + self.load_timeout + 10 + self.rt.limits.grace, self.deadline)
        state = {"loaded": False}

        def on_record(rec: dict) -> None:
            if rec.get("event") != "loaded":
                raise _ProtocolError(f"unexpected record {str(rec.get('event'))[:40]!r} before loading ended")
            errors, defined = rec.get("errors"), rec.get("defined")
            if not (isinstance(errors, list) and isinstance(defined, list)):
                raise _ProtocolError("bad 'loaded' record")
            if not self.loaded_once:
                self.load_errors = tuple((_short(e.get("origin")), _short(e.get("message"))) for e in errors[:200]
                                         if isinstance(e, dict))
                self.defined = tuple(_short(d, 200) for d in defined[:2000] if isinstance(d, str))
            self.loaded_once = True
            state["loaded"] = True

        ended = self._pump(until, on_record, lambda: state["loaded"])
        if state["loaded"]:
            return
        if ended == "deadline":
            why = ("timeout", "the submission's time budget ran out" if time.monotonic() >= self.deadline
                   else f"took more than {self.load_timeout:g} s")
        elif ended == "exited":
            why = ("crashed", "the process running the code ended without a result "
                   + _describe_exit(self.child.proc.returncode))
        elif ended == "disk":
            why = ("crashed", self._quota_message())
            self.over_quota.append(f"loading: {why[1]}")
        else:
            why = ("malformed", f"the sandbox's output could not be read ({ended})")
        self._stop()
        # Loading itself failed: restarting would fail the same way.
        self.load_failure = CallOutcome(why[0], message=f"{why[1]} while loading the notebook's code")

    def _exchange(self, request: dict, n: int) -> list[CallOutcome]:
        child = self.child
        rid = request["id"]
        found: dict[int, CallOutcome] = {}
        state = {"started": None, "ended": False, "missing": None, "current": 0}
        child.pending = (json.dumps(request, allow_nan=False, separators=(",", ":")) + "\n").encode()
        sent = time.monotonic()
        grace = self.rt.limits.grace
        cpu = request["clock"] == "cpu"
        # Under the CPU clock the child's timer never fires while the call waits: this is the backstop.
        allowed = request["seconds"] * (self.rt.limits.wall_factor if cpu else 1.0)

        def until() -> float:
            if state["started"] is None:
                limit = sent + _START_SLACK + grace
            else:
                limit = state["started"] + allowed + grace
            return min(limit, self.deadline)

        def on_record(rec: dict) -> None:
            event = rec.get("event")
            if rec.get("id") != rid:
                raise _ProtocolError("a record names an unknown call")
            if event == "start":
                state["started"] = state["started"] or time.monotonic()
            elif event == "missing":
                state["missing"] = _short(rec.get("message"))
            elif event == "item":
                index, status = rec.get("index"), rec.get("status")
                if type(index) is not int or not 0 <= index < n or status not in _ITEM_STATUSES:
                    raise _ProtocolError("a result names an unknown input or status")
                if index not in found:  # the first word on an input is final
                    outcome = self._outcome(rec, request["clock"], "swap" in request)
                    # The whole request's values stay in this process: bounded together, not only each.
                    state["bytes"] = state.get("bytes", 0) + _size_of(outcome.value)
                    if state["bytes"] > self.rt.limits.result_bytes:
                        outcome = CallOutcome("malformed", seconds=outcome.seconds, message=(
                            f"the values returned in this call add up to more than {self.rt.limits.result_bytes} "
                            "bytes"))
                    found[index] = outcome
                    if rec.get("exhausted") is True:
                        request["exhausted"] = True
                state["current"] = max(state["current"], index + 1)
            elif event == "helper":
                # The kit's refineF asks the grader (helpers.py); the answer goes back on the child's stdin.
                state["helpers"] = state.get("helpers", 0) + 1
                child.pending += helpers.answer(rec, switched_off=(request.get("swap") or {}).get("refineF") == "off",
                                                calls=state["helpers"], limits=self.wire_limits)
            elif event == "end":
                state["ended"] = True
                state["restart"] = _short(rec.get("restart"), 500) if rec.get("restart") else None
            else:
                raise _ProtocolError(f"unexpected record {str(event)[:40]!r}")

        ended = self._pump(until, on_record, lambda: state["ended"])
        if state["missing"] is not None:
            return [CallOutcome("missing", message=state["missing"])] * n
        culprit = next((k for k in range(n) if k not in found), None)
        if ended is True and self._over_quota():
            ended = "disk"  # the request ended, but what it wrote is past the quota: it fails all the same
        if ended == "disk":
            # Its files are removed with the child; the function would only fill the disk again.
            message = self._quota_message()
            self.over_quota.append(f"{request['function']}: {message}")
            self.disk_stopped[request["function"]] = message
            self._stop()
            return [CallOutcome("crashed", message=message)] * n
        if ended is True:
            for k in range(n):
                found.setdefault(k, CallOutcome("skipped", message=f"not run: {request['function']} used up its "
                                                "time on the earlier inputs"))
            if state.get("restart") and self.leak_restarts < _LEAK_RESTARTS:
                # What the call left behind in the child could not be undone there (threads still
                # running...): the next request gets a fresh child, so it costs only this question.
                # A few times only: each restart reloads the code, paid from the session's budget.
                self.leak_restarts += 1
                self._stop()
            return [found[k] for k in range(n)]
        # The child must go: it overran, ended or broke the protocol; it restarts for the next call.
        started = state["started"]
        seconds = round(time.monotonic() - started, 3) if started else None
        if ended == "deadline":
            if time.monotonic() >= self.deadline:
                first = CallOutcome("timeout", message="the submission's time budget ran out", seconds=seconds,
                                    stopped_by="budget")
            elif started is None:
                first = CallOutcome("timeout", message="the code did not start the next call in time",
                                    stopped_by="backstop")
            elif cpu:
                first = CallOutcome("timeout", message=f"took more than {allowed:g} s of wall-clock time without "
                                    f"using its {request['seconds']:g} s of CPU time (waiting, not computing) "
                                    "and was stopped", seconds=seconds, stopped_by="backstop")
            else:
                first = CallOutcome("timeout", message=f"took more than {request['seconds']:g} s and was stopped",
                                    seconds=seconds, stopped_by="backstop")
        elif ended == "exited":
            first = CallOutcome("crashed", message="the process running the code ended without a result "
                                + _describe_exit(child.proc.returncode), seconds=seconds)
        else:
            first = CallOutcome("malformed", message=f"the sandbox's output could not be read ({ended})",
                                seconds=seconds)
        self._stop()
        if culprit is not None:
            found[culprit] = first
        rest = CallOutcome("skipped", message=f"not run: {request['function']} stopped on an earlier input")
        return [found.get(k, rest) for k in range(n)]

    def _outcome(self, rec: dict, clock: str, swapped: bool = False) -> CallOutcome:
        return outcome_of(rec, clock, swapped, self.wire_limits)

    def _pump(self, until, on_record, done) -> bool | str:
        """Write the pending request and read records until ``done()``: True, or why not
        ("deadline", "exited", or a protocol error's text)."""
        child = self.child
        max_line = self.rt.limits.result_bytes * 4 // 3 + _MAX_LINE_SLACK
        streams = {child.proc.stdout.fileno(): self.out, child.proc.stderr.fileno(): self.err}
        writing = False
        next_check = time.monotonic() + QUOTA_CHECK
        try:
            while True:
                if done():
                    return True
                if time.monotonic() >= next_check:
                    if self._over_quota():
                        return "disk"
                    next_check = time.monotonic() + QUOTA_CHECK
                if child.pending and not writing:
                    child.sel.register(child.w, selectors.EVENT_WRITE)
                    writing = True
                now = time.monotonic()
                limit = until() if callable(until) else until
                if now >= limit:
                    return "deadline"
                exited = child.proc.poll() is not None
                wait = 0 if exited else max(min(0.1, limit - now), 0)
                events = child.sel.select(timeout=wait)
                for key, mask in events:
                    fd = key.fd
                    if mask & selectors.EVENT_WRITE:
                        try:
                            k = os.write(fd, child.pending[:1 << 16])
                            child.pending = child.pending[k:]
                        except BlockingIOError:
                            pass
                        except OSError:
                            child.pending = b""  # the child is gone; its exit is seen below
                        if not child.pending:
                            child.sel.unregister(fd)
                            writing = False
                        continue
                    try:
                        chunk = os.read(fd, 1 << 16)
                    except BlockingIOError:
                        continue
                    if not chunk:
                        child.sel.unregister(fd)
                        child.open.discard(fd)
                        continue
                    if fd != child.r:
                        streams[fd].add(chunk)
                        continue
                    child.buf += chunk
                    while b"\n" in child.buf and not done():
                        line, _, rest = bytes(child.buf).partition(b"\n")
                        child.buf = bytearray(rest)
                        on_record(_parse(line))
                    if len(child.buf) > max_line:
                        raise _ProtocolError("a result record is larger than the limit")
                if exited and not events:
                    return "exited"
        except _ProtocolError as exc:
            return str(exc) or "bad record"
        finally:
            if writing:
                try:
                    child.sel.unregister(child.w)
                except (KeyError, ValueError):
                    pass

    def _stop(self, gently: bool = False) -> None:
        child, self.child = self.child, None
        if child is None:
            return
        try:
            if gently:
                # End of the requests: the child exits by itself, and with it the namespace.
                try:
                    child.proc.stdin.close()
                    child.proc.wait(timeout=2)
                except (OSError, subprocess.TimeoutExpired):
                    pass
            _kill_tree(child.proc)
            # What is still in the pipes is kept for staff (bounded), as far as it can be read now.
            for fd, sink in ((child.proc.stdout.fileno(), self.out), (child.proc.stderr.fileno(), self.err)):
                if fd in child.open:
                    try:
                        while chunk := os.read(fd, 1 << 16):
                            sink.add(chunk)
                    except OSError:
                        pass
        finally:
            child.sel.close()
            os.close(child.r)
            for f in (child.proc.stdin, child.proc.stdout, child.proc.stderr):
                try:
                    f.close()
                except OSError:
                    pass
            if self.rt.uid is not None:
                if self.rt.namespaced:
                    end = time.monotonic() + _NAMESPACE_END
                    while live_pids_of_uid(self.rt.uid) and time.monotonic() < end:
                        time.sleep(0.02)
                self.swept += len(sweep_uid(self.rt.uid))
            # Removed without recursion: a tree thousands of folders deep must not stop the class.
            self.not_removed.extend(tree.remove(child.jobdir).named())
            if self.rt.uid is not None:
                # Its processes are gone and its scratch folder with them: what its uid left in /tmp,
                # /var/tmp, /dev/shm... goes too (found by owner, links not followed), counted for staff.
                # Behind a private /tmp only /run/lock is shared: walking the host's /tmp (every
                # folder in it that others may enter) would cost each session a second or more.
                n, size = remove_files_of_uid(self.rt.uid, self.rt.shared_tmp_dirs(), failed=self.not_removed)
                self.removed[0] += n
                self.removed[1] += size
                self._avoid_used_uid()

    def _avoid_used_uid(self) -> None:
        """Take a fresh uid for the next child when something of this one still runs.

        Whatever outlived the sweep (a process the kill did not end in its budget) could wait for
        the next child of its uid and read or kill it: the session's later children, and the next
        submission's (whose Sandbox still names the old uid), run under another uid, reserved
        until the session closes; ``pick_uid`` never hands out a uid while anything of it runs."""
        if self.rt.uid is None:
            return
        left = live_pids_of_uid(self.rt.uid)
        if not left:
            return
        old = self.rt.uid
        what = f"uid {old}: {len(left)} processes outlived the sweep (pids {', '.join(map(str, left[:10]))})"
        try:
            uid, fd = pick_uid()
        except RuntimeError as exc:
            self.survived.append(f"{what}, and no fresh uid was free ({exc})")
            return
        if self._uid_fd is not None:
            release_uid(old, self._uid_fd)
        self._uid_fd = fd
        self.rt = dataclasses.replace(self.rt, uid=uid)
        self.survived.append(f"{what}; this session's later processes run as uid {uid}")

    # -- the disk quota ------------------------------------------------------------------------

    def _quota_applies(self) -> bool:
        # At the namespace levels with a private /tmp, tmpfs sizes bound the child's files (hard).
        return not (self.rt.namespaced and self.rt.private_tmp)

    def _disk_use(self) -> tuple[int, int]:
        """(entries, bytes) of the running child: its scratch folder, and what its uid owns in the
        shared temporary folders (all of /dev/shm, where it may create files; the first level of the
        others, whose top it may not write into at the ``uid`` level)."""
        count, size = usage_of(self.child.jobdir)
        if self.rt.uid is not None:
            # Files unlinked while open (or mapped) take their room until the process ends, and no
            # folder shows them: counted by what the uid's processes hold, each file once.
            n, b = held_open_files(self.rt.uid)
            count += n
            size += b
            for roots, deep in ((("/dev/shm",), True), (tuple(d for d in SHARED_TMP_DIRS if d != "/dev/shm"), False)):
                for _, _, n, b in files_of_uid(self.rt.uid, roots, deep=deep):
                    count += n
                    size += b
        return count, size

    def _over_quota(self) -> bool:
        if self.child is None or not self._quota_applies():
            return False
        count, size = self._disk_use()
        limits = self.rt.limits
        self._last_use = (count, size)
        return size > limits.tmp_bytes or count > limits.tmp_files

    def _quota_message(self) -> str:
        count, size = self._last_use
        limits = self.rt.limits
        return (f"the code wrote {size / 2**20:.0f} MB in {count} files and folders, past the sandbox's disk quota "
                f"({limits.tmp_bytes / 2**20:.0f} MB or {limits.tmp_files} files), and was stopped")


def _size_of(value) -> int:
    """Bytes a decoded value (``core.wire``: arrays, numbers, text, lists, dicts) holds, roughly."""
    if hasattr(value, "nbytes"):
        return int(value.nbytes)
    if isinstance(value, (list, tuple)):
        return 8 * len(value) + sum(_size_of(v) for v in value)
    if isinstance(value, dict):
        return sum(_size_of(k) + _size_of(v) for k, v in value.items())
    if isinstance(value, (str, bytes)):
        return len(value)
    return 8


def _parse(line: bytes) -> dict:
    try:
        rec = wire.parse_json(line)
    except wire.WireError as exc:
        raise _ProtocolError(str(exc)) from None
    if not isinstance(rec, dict):
        raise _ProtocolError("a record is not a JSON object")
    return rec


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


def outcome_of(rec: dict, clock: str, swapped: bool, limits: wire.Limits) -> CallOutcome:
    """One input's item record (``child.call_request``'s) as a ``CallOutcome``, its value decoded
    within ``limits``; ``swapped``: the request switched refineF off, so the record's
    ``refineF_calls`` is read (an int in [0, MAX_REFINE_CALLS], else None).  The in-process
    stand-in of the checks' tests reads its records here too."""
    seconds = rec.get("seconds")
    seconds = float(seconds) if type(seconds) in (int, float) and math.isfinite(seconds) else None
    calls = rec.get("refineF_calls") if swapped else None
    calls = calls if type(calls) is int and 0 <= calls <= MAX_REFINE_CALLS else None
    if rec["status"] != "ok":
        return CallOutcome(rec["status"], message=_short(rec.get("message")), seconds=seconds,
                           stopped_by=clock if rec["status"] == "timeout" else None, refineF_calls=calls)
    try:
        value = wire.decode(rec.get("value"), limits)
    except wire.WireError as exc:
        return CallOutcome("malformed", message=f"the returned value is not plain data ({exc})", seconds=seconds)
    return CallOutcome("ok", value=value, seconds=seconds, refineF_calls=calls)
