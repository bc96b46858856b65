"""Nothing a submission starts outlives it, and nothing it leaves stops the next one.

- A forked process whose main thread exits while another thread runs shows ``State: Z`` in
  /proc/PID/status; the uid sweep skipped zombies, and ``setsid`` put it out of ``killpg``'s
  reach: it waited for the next child of its uid and killed it (an untouched answer key graded
  next lost half its points, "killed by SIGKILL").  The sweep now counts every task.
- A tree 3,000 folders deep in /dev/shm and in the scratch folder made ``os.walk`` and
  ``shutil.rmtree`` raise RecursionError (every call an internal error, no grades.csv).
- Files unlinked while open in /dev/shm were invisible to the disk quota.

The uid level runs as in a container like Gradescope's (Docker's default capabilities through
``setpriv``, a venv of the public Python: tests/autograder_tests/grading/test_fail_closed.py, ../shared/FIELD-NOTES.md).
"""

from __future__ import annotations

import ctypes
import json
import os
import platform
import shutil
import subprocess
import textwrap
import threading
import time
from pathlib import Path

import pytest

from core.paths import KIT_ROOT

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(os.geteuid() != 0 or shutil.which("setpriv") is None or shutil.which("unshare") is None,
                       reason="the levels tested need root, util-linux setpriv and unshare"),
]

# exit(2) of the calling thread only (glibc's exit() ends every thread): the leader becomes a zombie.
SYS_EXIT = {"x86_64": 60, "aarch64": 93}.get(platform.machine())


def live_tasks(uid: int) -> list[str]:
    """``pid/tid`` of every thread running as ``uid`` that is not a zombie, read from
    /proc/*/task/*/status (independently of the grader's own sweep)."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for tid in tids:
            try:
                with open(f"/proc/{pid}/task/{tid}/status") as fh:
                    fields = dict(line.split(":", 1) for line in fh if ":" in line)
            except OSError:
                continue
            if str(uid) in fields.get("Uid", "").split() and fields.get("State", "").split()[:1] not in (["Z"], ["X"]):
                found.append(f"{pid}/{tid}")
    return found


# The student's code: (a) a process in a session of its own whose leader thread exits while a
# thread of it kills every new process of its uid; (b) a tree `depth` folders deep in /dev/shm
# and in its working folder.
ATTACK = textwrap.dedent("""\
    import ctypes, os, threading, time

    def _uid_pids():
        out = set()
        for p in os.listdir("/proc"):
            try:
                with open(f"/proc/{p}/status") as fh:
                    if any(l.startswith("Uid:") and str(os.getuid()) in l.split() for l in fh):
                        out.add(int(p))
            except (OSError, ValueError):
                pass
        return out

    def _killer(known):
        while True:
            for pid in _uid_pids() - known - {os.getpid()}:
                try:
                    os.kill(pid, 9)
                except OSError:
                    pass
            time.sleep(0.002)

    def _deep(base, depth):
        top = os.path.join(base, f"hw4-deep-{os.getpid()}")
        os.mkdir(top)
        fd = os.open(top, os.O_RDONLY)
        for _ in range(depth):
            os.mkdir("d", dir_fd=fd)
            nxt = os.open("d", os.O_RDONLY, dir_fd=fd)
            os.close(fd)
            fd = nxt
        os.close(fd)
        return top

    def attack(depth, sys_exit):
        tops = [_deep("/dev/shm", depth), _deep(os.getcwd(), depth)]
        known = _uid_pids()
        pid = os.fork()
        if pid == 0:
            os.setsid()
            threading.Thread(target=_killer, args=(known,)).start()
            ctypes.CDLL(None).syscall(sys_exit, 0)
        for _ in range(500):  # until the leader is a zombie and its thread runs on
            with open(f"/proc/{pid}/status") as fh:
                zombie = "State:\\tZ" in fh.read()
            if zombie and len(os.listdir(f"/proc/{pid}/task")) > 1:
                return {"survivor": pid, "tops": tops}
            time.sleep(0.01)
        return {"survivor": None, "tops": tops}
    """)

# A plain session graded next: the answer key's eight-point algorithm, and a pause that gives a
# survivor every chance to find the child.
PAUSE = "import time\ndef pause(seconds):\n    time.sleep(seconds)\n    return seconds\n"

PROGRAM = textwrap.dedent("""\
    import json, os, sys
    import numpy as np
    sys.path.insert(0, sys.argv[1])
    from test_sandbox_survivors import live_tasks
    from autograder.sandbox import Sandbox
    from solutions.fundamental import eightpoint

    attack, key, sys_exit = sys.argv[2], sys.argv[3], int(sys.argv[4])
    rng = np.random.default_rng(7)
    X = np.c_[rng.uniform(-1, 1, (20, 2)), rng.uniform(4, 6, 20)]
    pts1 = X[:, :2] / X[:, 2:] * 500 + 320
    Y = X + [0.5, 0.1, 0.2]
    pts2 = Y[:, :2] / Y[:, 2:] * 500 + 320
    expected = eightpoint(pts1, pts2, 640.0, refine=False)
    out = {}
    with Sandbox(isolation="uid") as box:
        uid = out["uid"] = box.isolation.uid
        out["level"] = box.isolation.level
        with box.session(attack, budget=60) as s:
            a = s.call("attack", 3000, sys_exit, seconds=30)
            out["attack"] = a.value if a.status == "ok" else {"error": f"{a.status}: {a.message}", "tops": []}
        info = s.info
        out["attack_info"] = {"swept": info.swept, "removed": info.removed, "not_removed": info.not_removed,
                              "survived": info.survived}
        out["left_after_attack"] = live_tasks(uid)
        out["tops_left"] = [t for t in out["attack"]["tops"] if os.path.lexists(t)]
        with box.session(key, budget=60) as s:
            calls = [s.call("eightpoint", pts1, pts2, 640.0, refine=False, seconds=20), s.call("pause", 0.5, seconds=20),
                     s.call("eightpoint", pts1, pts2, 640.0, refine=False, seconds=20)]
        out["key"] = [c.status + ("" if c.status == "ok" else ": " + c.message) for c in calls]
        F = [np.asarray(c.value) for c in (calls[0], calls[2]) if c.status == "ok"]
        out["key_right"] = [bool(np.allclose(f / np.linalg.norm(f), expected / np.linalg.norm(expected)) or
                                 np.allclose(f / np.linalg.norm(f), -expected / np.linalg.norm(expected))) for f in F]
        out["key_info"] = {"spawns": s.info.spawns, "survived": s.info.survived}
        out["left_at_end"] = live_tasks(uid)
    print("RESULT " + json.dumps(out))
    """)


def key_source() -> str:
    text = (KIT_ROOT / "solutions" / "fundamental.py").read_text()
    return text.replace("from __future__ import annotations\n", "") + "\n" + PAUSE


def run_in_container(python: Path, program: Path, *args: str) -> dict:
    from containers import in_container, run

    proc = run(in_container([str(python), str(program), *args]), timeout=300)
    line = next((x for x in proc.stdout.splitlines() if x.startswith("RESULT ")), None)
    assert line is not None, proc.stderr[-3000:]
    return json.loads(line[len("RESULT "):])


@pytest.mark.skipif(SYS_EXIT is None, reason="exit(2)'s number is known here for x86_64 and aarch64 only")
def test_a_zombie_led_survivor_and_deep_trees_cost_the_next_submission_nothing(tmp_path, public_python):
    program = tmp_path / "program.py"
    program.write_text(PROGRAM)
    os.chmod(tmp_path, 0o755)
    got = run_in_container(public_python, program, str(Path(__file__).parent), ATTACK, key_source(), str(SYS_EXIT))
    assert got["level"] == "uid"
    # The attack was set up: a leader in State Z whose other thread ran, and two deep trees.
    assert got["attack"].get("survivor") is not None, got["attack"]
    info = got["attack_info"]
    assert info["swept"] >= 1 and info["survived"] == [], info   # the sweep found it and ended it
    assert got["left_after_attack"] == [], got["left_after_attack"]
    assert got["tops_left"] == [] and info["not_removed"] == [], info
    assert info["removed"][0] >= 3001  # the /dev/shm tree, found by owner and removed, for staff
    # The key graded next in the same sandbox: every call ran in its one child, with the right F.
    assert got["key"] == ["ok", "ok", "ok"], got["key"]
    assert got["key_right"] == [True, True] and got["key_info"] == {"spawns": 1, "survived": []}
    assert got["left_at_end"] == []


HOLDS = textwrap.dedent("""\
    import mmap, os, time
    kept = []
    def holds_open(mb):
        path = f"/dev/shm/hw4-held-{os.getpid()}"
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
        os.unlink(path)  # no folder shows it; it fills /dev/shm until the process ends
        os.write(fd, b"x" * (mb << 20))
        kept.append(fd)
        time.sleep(1.5)
        return "not stopped"
    def maps(mb):
        path = f"/dev/shm/hw4-mapped-{os.getpid()}"
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
        os.ftruncate(fd, mb << 20)
        m = mmap.mmap(fd, mb << 20)
        os.close(fd)
        os.unlink(path)  # nor any descriptor: only the mapping keeps it
        m.write(b"x" * (mb << 20))
        kept.append(m)
        time.sleep(1.5)
        return "not stopped"
    """)


@pytest.fixture(scope="module")
def box():
    """A namespaces-level sandbox without a private /tmp: the disk quota applies (as at the uid
    level; 8 MB here), and /dev/shm is the machine's."""
    from autograder.sandbox import ResourceLimits, Sandbox

    with Sandbox(isolation="namespaces", private_tmp=False, limits=ResourceLimits(tmp_bytes=8 * 2**20)) as made:
        yield made


def test_files_unlinked_while_open_or_mapped_in_dev_shm_count_for_the_quota(box):
    with box.session(HOLDS, budget=60) as s:
        held = s.call("holds_open", 24, seconds=20)
        mapped = s.call("maps", 24, seconds=20)
    info = s.info
    for outcome in (held, mapped):
        assert outcome.status == "crashed" and "disk quota" in outcome.message, outcome
    assert [line.split(":")[0] for line in info.over_quota] == ["holds_open", "maps"], info.over_quota
    assert all("past the sandbox's disk quota" in line for line in info.over_quota)
    assert info.survived == ()


def test_a_uid_something_still_runs_as_is_not_handed_to_the_next_session(box):
    # What outlives the sweep must not meet the next child of its uid: the next session takes a
    # fresh uid, reserved until it closes, and says so to staff.
    old = box.isolation.uid
    # A process of the sandbox's uid that no sweep of this test ends (as if SIGKILL had not worked
    # within the sweep's budget).
    stray = subprocess.Popen(["sleep", "60"], user=old, group=old, extra_groups=[], start_new_session=True)
    try:
        with box.session("import os\ndef uid():\n    return os.getuid()\n", budget=60) as s:
            first = s.call("uid", seconds=20).value
            second = s.call("uid", seconds=20).value
        info = s.info
    finally:
        stray.kill()
        stray.wait()
    assert first == second and first not in (old, 0, os.getuid()), (first, old)
    assert len(info.survived) == 1 and f"uid {old}: 1 processes" in info.survived[0]
    assert f"pids {stray.pid}" in info.survived[0] and f"run as uid {first}" in info.survived[0]
    assert live_tasks(first) == []


@pytest.mark.skipif(SYS_EXIT is None, reason="exit(2)'s number is known here for x86_64 and aarch64 only")
def test_the_sweep_ends_a_zombie_led_thread_group_and_is_not_held_by_a_real_zombie():
    from autograder.sandbox.uids import live_pids_of_uid, pick_uid, release_uid, sweep_uid

    uid, lock = pick_uid()
    children = []
    try:
        for kind in ("real zombie", "zombie-led"):
            pid = os.fork()
            if pid == 0:  # pragma: no cover - the child, as the test's own uid
                try:
                    os.setgroups([])
                    os.setgid(uid)
                    os.setuid(uid)
                    if kind == "zombie-led":
                        os.setsid()
                        threading.Thread(target=time.sleep, args=(60,)).start()
                        ctypes.CDLL(None).syscall(SYS_EXIT, 0)  # this thread only
                        time.sleep(60)
                finally:
                    os._exit(0)  # the real zombie: its parent (this test) waits for it only later
            children.append(pid)
        real, led = children
        deadline = time.monotonic() + 10
        while not (state_of(real) == "Z" and state_of(led) == "Z" and len(os.listdir(f"/proc/{led}/task")) > 1):
            assert time.monotonic() < deadline, (state_of(real), state_of(led))
            time.sleep(0.01)
        # Both leaders show State: Z; only one of them has a thread still running.
        assert live_pids_of_uid(uid) == [led]
        start = time.monotonic()
        assert sweep_uid(uid, budget=10) == [led]
        assert time.monotonic() - start < 5  # the real zombie, which no signal ends, held nothing up
        assert live_pids_of_uid(uid) == [] and live_tasks(uid) == []
    finally:
        for pid in children:
            try:
                os.kill(pid, 9)
            except ProcessLookupError:
                pass
            os.waitpid(pid, 0)
        release_uid(uid, lock)


def state_of(pid: int) -> str:
    with open(f"/proc/{pid}/status") as fh:
        return next(line.split()[1] for line in fh if line.startswith("State:"))
