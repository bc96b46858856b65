"""What the sandbox is told and what it reports: limits, the isolation used, one call's outcome."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

__all__ = ["CLOCKS", "LEVELS", "MAX_REFINE_CALLS", "STATUSES", "STOPPED_BY", "WEAK_LEVELS", "CallOutcome", "Isolation",
           "IsolationRefused", "ResourceLimits", "SessionInfo"]

STATUSES = ("ok", "exception", "timeout", "crashed", "missing", "malformed", "skipped")
# How a call's time limit is counted: wall-clock seconds, or CPU seconds of the child.
CLOCKS = ("wall", "cpu")
# What stopped a call that timed out: the child's own CPU timer, its own wall-clock timer, the
# grader killing the child (the call's wall-clock backstop), or the session's budget running out.
STOPPED_BY = ("cpu", "wall", "backstop", "budget")
LEVELS = ("namespaces", "user-namespaces", "uid", "basic")
# Levels where the code keeps the grader's uid or can read the grader's files: only on request.
WEAK_LEVELS = ("user-namespaces", "basic")
# The most calls of refineF a call's outcome may report (``CallOutcome.refineF_calls``): the
# child's count is the student's process's word, so anything else is not believed.
MAX_REFINE_CALLS = 1_000_000


class IsolationRefused(RuntimeError, ValueError):
    """No level at least as strong as required works here; the message says what is missing and
    how to fix it.  A ValueError too, so that a command prints it as an error, not a traceback."""


@dataclass(frozen=True)
class ResourceLimits:
    """Limits of one sandboxed process tree.

    memory_bytes: RLIMIT_AS of each process; processes: RLIMIT_NPROC (for the sandbox's own
    uid, threads included); file_bytes: RLIMIT_FSIZE (one file); open_files: RLIMIT_NOFILE;
    tmp_bytes and tmp_files: the disk one child may fill, in bytes and in files and folders: at
    the namespace levels the size and inode count of each of its private tmpfs /tmp, /var/tmp and
    /dev/shm (its scratch folder lies in /tmp), a hard limit; at the other levels a quota the
    grader checks while calls run (``session.QUOTA_CHECK`` seconds apart) and after each, over
    its scratch folder and what its uid owns in the shared temporary folders; a call past it is
    stopped and fails; output_bytes: how much of stdout and of stderr is
    kept; result_bytes: largest encoded result; grace: seconds the grader waits beyond a call's
    own limit before killing the child (the child stops a call itself first).

    clock: how each call's ``seconds`` are counted by default (a request may say otherwise):
    "wall", wall-clock seconds (the child arms ITIMER_REAL); "cpu", CPU seconds of the child
    (ITIMER_PROF, user and system time of all its threads), so that a slow or shared machine
    does not stop a call that is computing, while a call that waits (sleep, a blocked read) is
    still killed by the grader at ``seconds * wall_factor + grace`` wall-clock seconds after it
    started.  wall_factor: that backstop's multiple (cpu clock only; at least 1; a machine that
    gives the code half a CPU needs more than 2).  cpu_share: the measured share of one CPU the
    code gets here (cpu clock only; in (0, 1]; 0.5 at 0.5 vCPU): a call's CPU seconds take
    1 / cpu_share wall-clock seconds, so the session's wall-clock budget grows by as much
    (``autograder.grading.budget.budget_of``).
    """

    memory_bytes: int = 3 * 2**30
    processes: int = 64
    file_bytes: int = 64 * 2**20
    open_files: int = 256
    tmp_bytes: int = 256 * 2**20
    tmp_files: int = 20000
    output_bytes: int = 64 * 1024
    result_bytes: int = 64 * 2**20
    grace: float = 2.0
    clock: str = "wall"
    wall_factor: float = 3.0
    cpu_share: float = 1.0

    def __post_init__(self):
        if self.clock not in CLOCKS:
            raise ValueError(f"clock: expected one of {CLOCKS}, got {self.clock!r}")
        wf = self.wall_factor
        if isinstance(wf, bool) or not isinstance(wf, (int, float)) or not 1 <= wf <= 1000:
            raise ValueError(f"wall_factor: expected a number of at least 1 (and at most 1000), got {wf!r}")
        share = self.cpu_share
        if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0.01 <= share <= 1:
            raise ValueError(f"cpu_share: expected a share of one CPU in [0.01, 1], got {share!r}")

    @property
    def wall_per_cpu(self) -> float:
        """Wall-clock seconds one CPU second of a call may take here: 1 / cpu_share under the CPU
        clock, 1 under the wall clock (its limits are wall-clock seconds already)."""
        return 1.0 / self.cpu_share if self.clock == "cpu" else 1.0


@dataclass(frozen=True)
class CallOutcome:
    """What became of one call of a student function on one input.

    status: one of ``STATUSES`` ("skipped": not run, the request's budget was used up or the
    function had been stopped before); value: the decoded return value when status is "ok";
    message: for the other statuses, a short text for the student (the student's exception
    type and message with the line of their code, never a grader traceback); seconds: run time
    (as the child measured it for calls that returned, so informative only); stopped_by: for a
    "timeout", what stopped it (one of ``STOPPED_BY``), else None; refineF_calls: for a call made
    with refineF switched off (the request's ``swap``, see the child), how many times refineF was
    called during this input, as the child counted it (``core.refine_switch.Switch.calls``): an int
    in [0, ``MAX_REFINE_CALLS``], None when the call was not switched off or the child said nothing
    believable.  Reported by the student's process: informative only, never judged.
    """

    status: str
    value: Any = None
    message: str = ""
    seconds: float | None = None
    stopped_by: str | None = None
    refineF_calls: int | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"


@dataclass(frozen=True)
class Isolation:
    """How the code was isolated (reported in the results).

    level: one of ``LEVELS``; uid: the uid the code ran as (None: the grader's own);
    pid_namespace, network_isolated, private_tmp: what those words say; hidden_paths: paths the
    code could not read (by a mount namespace, or at the ``uid`` level by permissions checked as
    the code's uid; empty when the level cannot hide paths); notes: why a stronger level was not
    used, and other caveats; weak: the code kept the grader's uid or could read the grader's
    files (only when asked for with ``allow_weak``).
    """

    level: str
    uid: int | None
    pid_namespace: bool
    network_isolated: bool
    private_tmp: bool
    hidden_paths: tuple[str, ...]
    notes: tuple[str, ...] = ()
    weak: bool = False

    def as_dict(self) -> dict:
        return asdict(self)

    def summary(self) -> str:
        parts = [self.level + (" (WEAK: allowed by --allow-weak-isolation)" if self.weak else "")]
        parts.append(f"uid {self.uid}" if self.uid is not None else "grader's uid")
        parts.append("network cut" if self.network_isolated else "network NOT cut")
        parts.append(f"{len(self.hidden_paths)} paths hidden" if self.hidden_paths else "nothing hidden")
        return ", ".join(parts)


@dataclass(frozen=True)
class SessionInfo:
    """What happened around the calls of a session (for staff, never for judging).

    load_errors: (origin, message) of units that failed to load (first start); defined: the
    functions and classes the loaded code defines; stdout, stderr: bounded, untrusted copies of
    what the child printed; spawns: child processes started; swept: processes the /proc sweeps
    had to kill (0 when the namespace already ended them all); seconds: wall-clock time;
    removed: (entries, bytes) the code's uid had left in the machine's shared temporary folders
    (/tmp, /var/tmp, /dev/shm, /run/lock), removed after each child; over_quota: what went past
    the disk quota (``ResourceLimits.tmp_bytes``, ``tmp_files``), one line per time; not_removed:
    ``"<path>: <why>"`` of what the code left that could not be removed (its scratch folder's
    included); survived: what of the code's uid still ran after the sweep, and the fresh uid the
    later code of the session (or the next submission's) ran as instead.
    """

    load_errors: tuple[tuple[str, str], ...]
    defined: tuple[str, ...]
    stdout: str
    stderr: str
    isolation: Isolation
    seconds: float
    spawns: int
    swept: int
    removed: tuple[int, int] = (0, 0)
    over_quota: tuple[str, ...] = ()
    not_removed: tuple[str, ...] = ()
    survived: tuple[str, ...] = ()
