"""The trust boundary: hostile student code must not change the grader, see secrets or outlive its job.

Each hostile case is a few lines of student source run as one small job; each is bounded to a few
seconds by its call timeout.  Tests that need a capability of the machine (network namespaces,
a uid of the sandbox's own) skip with the reason when it is missing.
"""

from __future__ import annotations

import base64
import builtins
import io
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from autograder.sandbox import ResourceLimits, Sandbox, live_pids_of_uid
from autograder.sandbox.script import MPL_CACHE
from core import wire
from autograder.submission.read import parse_notebook_cells
from core.paths import KIT_ROOT

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

LIMITS = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)


@pytest.fixture(scope="module")
def box():
    with Sandbox(KIT_ROOT, limits=LIMITS) as sandbox:
        yield sandbox


@pytest.fixture
def world_readable_dir():
    """A folder under /tmp that any uid could read or write if nothing hid it."""
    path = Path(tempfile.mkdtemp(prefix="hw4-visible-"))
    os.chmod(path, 0o777)
    yield path
    shutil.rmtree(path)


@dataclass(frozen=True)
class Call:
    """One call for ``run``: ``function(*args, **kwargs)`` within ``timeout`` seconds, named ``id``."""

    id: str
    function: str
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)
    timeout: float = 10.0


class Ran(dict):
    """Outcomes by call id, and the session's info as attributes (spawns, swept, stdout...)."""

    def __getattr__(self, name):
        return getattr(self["__info__"], name)


def run(box, source, *calls, budget=120.0):
    """One session with ``source`` loaded, making ``calls`` in order."""
    with box.session(source, budget=budget) as session:
        out = Ran({c.id: session.call(c.function, *c.args, seconds=c.timeout, **c.kwargs) for c in calls})
    out["__info__"] = session.info
    return out


def no_processes_left(box) -> bool:
    return box.isolation.uid is None or live_pids_of_uid(box.isolation.uid) == []


# ---------------------------------------------------------------------------------------------
# normal jobs


def test_normal_job_round_trips_exactly(box, rng):
    src = (
        "import numpy as np\n"
        "def compute(a, n, scale=1.0):\n"
        "    return {'a': a * scale, 'ints': np.arange(n, dtype=np.uint16), 'mask': a > 0,\n"
        "            'z': np.array([1 + 2j]), 'pair': (float(a.sum()), n), 'nan': float('nan'),\n"
        "            'list': [np.float32(1.5), 'text', None, True]}\n"
    )
    a = rng.normal(size=(4, 3))
    r = run(box, src, Call("c", "compute", (a, 5), {"scale": 3.0}))
    out = r["c"]
    assert out.status == "ok", out.message
    v = out.value
    assert v["a"].dtype == np.float64 and np.array_equal(v["a"], a * 3.0)
    assert v["ints"].dtype == np.uint16 and np.array_equal(v["ints"], np.arange(5))
    assert v["mask"].dtype == bool and np.array_equal(v["mask"], a > 0)
    assert v["z"].dtype == np.complex128 and v["z"][0] == 1 + 2j
    assert v["pair"] == (float(a.sum()), 5) and type(v["pair"]) is tuple
    assert np.isnan(v["nan"])
    assert v["list"] == [1.5, "text", None, True]
    assert r.spawns == 1 and r.isolation is box.isolation


def test_student_can_import_numpy_scipy_matplotlib_and_the_kit(box):
    src = (
        "import numpy as np\nimport scipy.optimize\nimport matplotlib.pyplot as plt\n"
        "from core import validate\nimport scenes.cameras\n"
        "def f():\n"
        "    plt.figure(); plt.plot([0, 1]); plt.show()\n"
        "    return validate.as_points([[1, 2]], 'p').dtype.name, scipy.optimize.brentq(lambda x: x - 2, 0, 5)\n"
    )
    r = run(box, src, Call("f", "f"))
    assert r.load_errors == ()
    assert r["f"].status == "ok", r["f"].message
    assert r["f"].value[0] == "float64" and abs(r["f"].value[1] - 2) < 1e-9


def test_every_sandbox_of_a_process_gives_its_children_the_font_list(box):
    # The font list is made once per grader process and written into each later Sandbox's lib;
    # a child must find it in its config folder before matplotlib loads, or it scans the fonts itself.
    src = ("import os\n"
           "HAD = sorted(os.listdir(os.environ['MPLCONFIGDIR'])) if os.path.isdir(os.environ['MPLCONFIGDIR']) else []\n"
           "def had():\n    return HAD\n")
    made = sorted(p.name for p in (box.runtime.lib / MPL_CACHE).glob("fontlist-*.json"))
    assert made
    with Sandbox(KIT_ROOT, limits=LIMITS) as later:
        assert [(later.runtime.lib / MPL_CACHE / n).read_bytes() for n in made] == \
            [(box.runtime.lib / MPL_CACHE / n).read_bytes() for n in made]
        r = run(later, src, Call("h", "had"))
    assert r["h"].status == "ok" and r["h"].value == made, (r["h"].message, r["h"].value)


def test_failing_import_loses_only_that_statement(box):
    units = parse_notebook_cells(["import not_a_module_anywhere\ndef f():\n    return 1\n"],
                        stem="q2_eightpoint", filename="q2_eightpoint.ipynb").units
    r = run(box, units, Call("f", "f"))
    assert r["f"].value == 1
    (origin, message), = r.load_errors
    assert origin == "q2_eightpoint.ipynb, cell 1" and "ModuleNotFoundError" in message


def test_later_definition_is_the_one_called(box):
    units = parse_notebook_cells(["def eightpoint(a, b, M):\n    return 'first'\n", "def eightpoint(a, b, M):\n    return 'second'\n"],
                        stem="q2_eightpoint", filename="q2.ipynb").units
    r = run(box, units, Call("e", "eightpoint", (1, 2, 3)))
    assert r["e"].value == "second"


def test_exceptions_missing_functions_and_student_line_numbers(box):
    units = parse_notebook_cells(["x = 1\n", "def f(a):\n    y = a + 1\n    raise ValueError('bad input ' + str(y))\n"],
                        stem="q2_eightpoint", filename="q2.ipynb").units
    r = run(box, units, Call("f", "f", (1,)), Call("g", "not_defined"))
    assert r["f"].status == "exception"
    assert r["f"].message == "ValueError: bad input 2 (in f, q2.ipynb, cell 2, line 3)"
    assert "child.py" not in r["f"].message and "Traceback" not in r["f"].message
    assert r["g"].status == "missing"


# ---------------------------------------------------------------------------------------------
# hostile code


def test_patching_numpy_and_builtins_in_the_child_does_not_reach_the_grader(box):
    allclose, absolute = np.allclose, builtins.abs
    src = (
        "import numpy as np, builtins\n"
        "def eightpoint(pts1, pts2, M):\n"
        "    np.allclose = lambda *a, **k: True\n"
        "    np.array_equal = lambda *a, **k: True\n"
        "    builtins.abs = lambda x: 0\n"
        "    return np.zeros((3, 3))\n"
    )
    r = run(box, src, Call("e", "eightpoint", (np.zeros((8, 2)), np.zeros((8, 2)), 640)))
    assert r["e"].status == "ok"
    assert np.allclose is allclose and builtins.abs is absolute
    assert not np.allclose(r["e"].value, np.eye(3))
    assert not np.array_equal(r["e"].value, np.eye(3))


def test_object_with_always_true_eq_is_rejected_or_converted(box):
    src = (
        "import numpy as np\n"
        "class Liar:\n"
        "    def __eq__(self, other): return True\n"
        "    __hash__ = None\n"
        "class LiarArray(np.ndarray):\n"
        "    def __eq__(self, other): return np.ones(self.shape, bool)\n"
        "def liar(): return Liar()\n"
        "def liar_array(): return np.zeros(3).view(LiarArray)\n"
        "def liar_float():\n"
        "    class F(float):\n"
        "        def __eq__(self, other): return True\n"
        "    return F(0.5)\n"
    )
    r = run(box, src, Call("a", "liar"), Call("b", "liar_array"), Call("c", "liar_float"))
    assert r["a"].status == "malformed" and "Liar" in r["a"].message
    b = r["b"].value
    assert type(b) is np.ndarray and not np.array_equal(b, np.ones(3))
    c = r["c"].value
    assert type(c) is np.ndarray and c.dtype == np.float64 and c != 0.7


def test_sys_exit_is_an_exception_and_os_exit_a_crash_of_that_call_only(box):
    src = "import os, sys\ndef a(): sys.exit(3)\ndef b(): os._exit(0)\ndef c(): return 'alive'\n"
    r = run(box, src, Call("a", "a"), Call("b", "b"), Call("c", "c"))
    assert r["a"].status == "exception" and "SystemExit" in r["a"].message
    assert r["b"].status == "crashed"
    assert r["c"].value == "alive"
    assert r.spawns == 2  # restarted once, after the crash


def test_infinite_loops_time_out_even_when_the_alarm_is_ignored(box):
    src = (
        "import signal\n"
        "def polite():\n    while True: pass\n"
        "def stubborn():\n    signal.signal(signal.SIGALRM, signal.SIG_IGN)\n    while True: pass\n"
        "def fine(): return 1\n"
    )
    r = run(box, src, Call("p", "polite", timeout=1), Call("s", "stubborn", timeout=1), Call("f", "fine"))
    assert r["p"].status == "timeout" and r["s"].status == "timeout"
    assert r["s"].seconds is not None and r["s"].seconds < 1 + LIMITS.grace + 1.5
    assert r["f"].value == 1


def test_memory_bomb_is_stopped_by_the_limit(box):
    # 4 GiB: the machine could give it, the 2 GiB limit must not.
    src = "import numpy as np\ndef bomb():\n    return np.ones(2**29).sum()\n"
    r = run(box, src, Call("m", "bomb", timeout=5))
    assert r["m"].status == "exception" and "MemoryError" in r["m"].message
    assert np.ones(10).sum() == 10  # the grader is fine


def test_a_function_out_of_memory_is_not_called_again(box):
    # Each attempt fills the memory limit (seconds of zeroed pages, 30 s per memory bomb of a class
    # when every Q2 input was tried): the rest of the request is skipped, later calls are not made.
    src = ("import numpy as np\ncalls = []\n"
           "def bomb(k):\n    calls.append(k)\n    return np.ones(2**29).sum()\n"
           "def tried(): return list(calls)\n")
    with box.session(src, budget=120.0) as session:
        first = session.map("bomb", [((k,), {}) for k in range(3)], seconds=30)
        later = session.call("bomb", 9, seconds=5)
        tried = session.call("tried", seconds=5)
    assert first[0].status == "exception" and "MemoryError" in first[0].message
    assert [o.status for o in first[1:]] == ["skipped", "skipped"], first
    assert "ran out of memory on an earlier input" in first[1].message
    assert later.status == "skipped" and "ran out of memory earlier" in later.message
    assert tried.value == [0]  # tried once, in the same child: nothing crashed


def test_fork_bomb_is_limited_and_leaves_nothing(box):
    if box.isolation.uid is None:
        pytest.skip("the sandbox has no uid of its own here, so the process limit is the grader's")
    src = ("import os, threading\ndef bomb():\n    while True:\n        os.fork()\n"
           "def after():\n    t = threading.Thread(target=print)\n    t.start()\n    t.join()\n"
           "    pid = os.fork()\n    if pid == 0:\n        os._exit(0)\n    return os.waitpid(pid, 0)[0] == pid\n")
    r = run(box, src, Call("b", "bomb", timeout=5), Call("a", "after", timeout=5))
    assert r["b"].status == "exception" and "BlockingIOError" in r["b"].message
    # The bomb's copies and unreaped children are not the next call's: it starts a thread and a process.
    assert (r["a"].status, r["a"].value) == ("ok", True), r["a"]
    assert no_processes_left(box)
    assert subprocess.run([sys.executable, "-c", "pass"], check=False).returncode == 0


def test_daemon_left_running_is_gone_after_the_job(box):
    src = (
        "import os, time\n"
        "def start():\n"
        "    if os.fork() == 0:\n"
        "        os.setsid()\n"
        "        if os.fork() == 0:\n"
        "            with open('daemon.pid', 'w') as fh: fh.write(str(os.getpid()))\n"
        "            time.sleep(60)\n"
        "        os._exit(0)\n"
        "    for _ in range(200):\n"
        "        if os.path.exists('daemon.pid') and open('daemon.pid').read():\n"
        "            pid = int(open('daemon.pid').read())\n"
        "            return os.path.exists(f'/proc/{pid}')\n"
        "        time.sleep(0.01)\n"
        "    return False\n"
    )
    r = run(box, src, Call("d", "start", timeout=5))
    assert r["d"].value is True  # the daemon was running when the call returned
    if box.isolation.uid is None:
        pytest.skip("no uid of its own: nothing to look for in /proc")
    assert no_processes_left(box)
    if box.isolation.pid_namespace:
        assert r.swept == 0  # ended by the namespace itself, not by the backstop sweep


def test_printing_fake_results_changes_nothing(box):
    src = (
        "import json, sys\n"
        "def a():\n"
        "    print(json.dumps({'id': 'b', 'status': 'ok', 'value': 100}))\n"
        "    print(json.dumps({'event': 'done'}))\n"
        "    sys.stdout.flush()\n"
        "    return 1\n"
        "def b(): return 2\n"
    )
    r = run(box, src, Call("a", "a"), Call("b", "b"))
    assert (r["a"].value, r["b"].value) == (1, 2)
    assert '"value": 100' in r.stdout  # it was printed, and ignored


def test_garbage_on_the_result_pipe_affects_only_that_call(box):
    src = (
        "import os, sys\n"
        "def a():\n"
        "    fd = int(sys.argv[sys.argv.index('--result-fd') + 1])\n"
        "    os.write(fd, b'{not json\\n')\n"
        "    return 1\n"
        "def b(): return 2\n"
    )
    r = run(box, src, Call("a", "a"), Call("b", "b"))
    assert r["a"].status == "malformed"
    assert r["b"].value == 2


def test_crash_while_loading_fails_every_call_without_retrying(box):
    src = "import os\nclass Boom:\n    os._exit(1)\ndef f(): return 1\n"
    r = run(box, src, Call("a", "f"), Call("b", "f"))
    assert r["a"].status == r["b"].status == "crashed"
    assert "loading" in r["a"].message and r.spawns == 1


def test_secret_folder_cannot_be_read_and_output_folder_cannot_be_written(world_readable_dir):
    secret = world_readable_dir / "solutions"
    output = world_readable_dir / "results"
    for folder in (secret, output):
        folder.mkdir()
        os.chmod(folder, 0o777)
    (secret / "answer.txt").write_text("THE ANSWER")
    control = world_readable_dir / "public.txt"
    control.write_text("public")
    for f in (secret / "answer.txt", control):
        os.chmod(f, 0o666)
    # Without a private /tmp only the masks stand between the code and these folders.
    with Sandbox(KIT_ROOT, hidden=[secret, output], private_tmp=False, limits=LIMITS) as sandbox:
        if not sandbox.isolation.hidden_paths:
            pytest.skip(f"paths cannot be hidden at isolation level {sandbox.isolation.level}")
        src = ("def read(p):\n    return open(p).read()\n"
               "def write(p):\n    open(p, 'w').write('{\"score\": 100}')\n    return 'written'\n")
        r = run(sandbox, src, Call("s", "read", (str(secret / "answer.txt"),)), Call("c", "read", (str(control),)),
                Call("w", "write", (str(output / "results.json"),)))
    assert r["c"].value == "public"  # the folder around them is open: the masks are what stop the code
    assert r["s"].status == "exception" and "THE ANSWER" not in r["s"].message
    assert r["w"].status == "exception"
    assert not (output / "results.json").exists()


def test_kit_solutions_are_hidden_by_default(box):
    src = "import os\ndef look(p):\n    return sorted(os.listdir(p))\ndef imp():\n    import solutions\n"
    r = run(box, src, Call("l", "look", (str(KIT_ROOT / "solutions"),)), Call("i", "imp"))
    if not box.isolation.hidden_paths:
        pytest.skip("paths cannot be hidden at this isolation level")
    assert r["l"].value == [] or r["l"].status == "exception"
    assert r["i"].status == "exception" and "solutions" in r["i"].message


def test_network_is_unreachable(box):
    if not box.isolation.network_isolated:
        pytest.skip(f"no network namespace at isolation level {box.isolation.level}")
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    server.setblocking(False)
    port = server.getsockname()[1]
    try:
        src = "import socket\ndef connect(port):\n    socket.create_connection(('127.0.0.1', port), timeout=2)\n    return 'connected'\n"
        r = run(box, src, Call("n", "connect", (port,), timeout=4))
        assert r["n"].status == "exception"
        with pytest.raises(BlockingIOError):
            server.accept()
    finally:
        server.close()


KERNEL_CHANNELS = """\
import ctypes, os, threading, subprocess, multiprocessing

_libc = ctypes.CDLL(None, use_errno=True)


def _errno_of(nr, *args):
    r = _libc.syscall(ctypes.c_long(nr), *args)
    return 0 if r >= 0 else ctypes.get_errno()


def try_all():
    out = {}
    # add_key("user", "note", "...", 5, KEY_SPEC_USER_KEYRING): a note the next child of this uid could read.
    out["add_key"] = _errno_of(248, b"user", b"hw4-note", b"hello", ctypes.c_long(5), ctypes.c_long(-4))
    out["keyctl"] = _errno_of(250, ctypes.c_long(0), ctypes.c_long(-4), ctypes.c_long(0))
    try:
        os.close(os.memfd_create("big"))
        out["memfd_create"] = 0
    except OSError as exc:
        out["memfd_create"] = exc.errno
    out["unshare"] = _errno_of(272, ctypes.c_long(0x10000000))   # unshare(CLONE_NEWUSER)
    out["userfaultfd"] = _errno_of(323, ctypes.c_long(0))
    # What a homework needs still works: threads, a subprocess, a fork-based pool.
    box = []
    t = threading.Thread(target=lambda: box.append(1))
    t.start(); t.join()
    out["thread"] = box == [1]
    out["subprocess"] = subprocess.run(["/bin/true"]).returncode == 0
    with multiprocessing.get_context("fork").Pool(2) as pool:
        out["pool"] = pool.map(abs, [-1, -2]) == [1, 2]
    return out
"""


def test_keyrings_memfd_and_namespaces_are_refused_at_every_level(box):
    """Kernel objects no namespace covers (a uid's keyrings, memfd pages past RLIMIT_AS, namespaces
    of the code's own) are refused by the child's syscall filter; threads, subprocesses and a
    fork-based pool keep working."""
    import platform

    if platform.machine() != "x86_64":
        pytest.skip("the syscall numbers of this test are x86_64's")
    got = run(box, KERNEL_CHANNELS, Call("k", "try_all", timeout=20))["k"]
    assert got.status == "ok", got.message
    value = got.value
    for name in ("add_key", "keyctl", "memfd_create", "unshare", "userfaultfd"):
        assert value[name] == 13, (name, value[name])   # EACCES: the filter's answer, at every level
    assert value["thread"] and value["subprocess"] and value["pool"], value


def test_no_staff_path_in_the_namespaces_command_line_root_or_mount_table():
    """The namespace's first process runs its staging script from a file, so /proc/1/cmdline names
    no hidden path; the code's root holds only the system's folders, this Python's and its own, so
    a staff folder outside /tmp (here beside the kit's own files) is neither reachable nor named in
    the mount table, and neither is the sandbox's folder that the lib is copied from."""
    out = KIT_ROOT / "out"
    out.mkdir(exist_ok=True)
    staff = Path(tempfile.mkdtemp(prefix="grades-of-section-B-", dir=out))
    src = ("import os\ndef look(kit):\n    out = {}\n    for name in ('/proc/1/cmdline', '/proc/self/mountinfo'):\n"
           "        try:\n            out[name] = open(name, 'rb').read().decode(errors='replace')\n"
           "        except OSError as exc:\n            out[name] = repr(exc)\n"
           "    out['kit'] = sorted(os.listdir(kit)) if os.path.isdir(kit) else []\n"
           "    out['root'] = sorted(os.listdir('/'))\n    return out\n")
    try:
        with Sandbox(KIT_ROOT, hidden=[staff], limits=LIMITS) as sandbox:
            if not sandbox.isolation.level.endswith("namespaces"):
                pytest.skip(f"no namespaces at isolation level {sandbox.isolation.level}")
            seen = run(sandbox, src, Call("l", "look", (str(KIT_ROOT),)))["l"]
            hidden = [str(p) for p in sandbox.runtime.hidden]
            base = str(sandbox.runtime.lib.parent)
    finally:
        shutil.rmtree(staff)
    assert seen.status == "ok", seen.message
    cmdline, mounts = seen.value["/proc/1/cmdline"], seen.value["/proc/self/mountinfo"]
    assert "sh" in cmdline and "mount" not in cmdline
    assert [h for h in hidden if h in cmdline] == []
    assert str(staff) in hidden and "grades-of-section-B" not in mounts
    assert base not in mounts
    # Of the kit's folder, only a Python installed inside it (a .venv) can be in the root.
    python_dirs = {Path(sys.prefix).resolve(), Path(sys.base_prefix).resolve()}
    assert [n for n in seen.value["kit"] if (KIT_ROOT / n).resolve() not in python_dirs] == []
    assert "home" not in seen.value["root"] and "run" not in seen.value["root"]


def test_one_input_of_a_request_is_stopped_at_its_own_limit(box):
    """With ``each``, a hung input costs its own limit, not the whole request's; an input slower
    than its share but within ``each`` is not cut short."""
    import time

    src = ("import time\ndef hangs_first(k):\n    while k == 0:\n        pass\n    return k\n"
           "def slow_first(k):\n    time.sleep(0.6 if k == 0 else 0.0)\n    return k\n")
    with box.session(src, budget=120) as session:
        started = time.monotonic()
        hung = session.map("hangs_first", [((k,), {}) for k in range(4)], seconds=12, budget=8, each=1.5)
        took = time.monotonic() - started
        slow = session.map("slow_first", [((k,), {}) for k in range(4)], seconds=2.5, budget=2, each=1.5)
    assert hung[0].status == "timeout" and "more than 1.5 s" in hung[0].message, hung[0]
    assert [o.status for o in hung[1:]] == ["skipped"] * 3
    assert took < 8, took   # the request's 12 s were not spent
    assert [o.status for o in slow] == ["ok"] * 4 and [o.value for o in slow] == [0, 1, 2, 3]


def test_a_whole_map_of_large_returns_is_bounded_in_the_grader(box):
    """Each value may be large, but the values of one request add up to at most ``result_bytes``
    in the grader's process: a matcher returning 40 MB per point must not fill the worker."""
    src = "import numpy as np\ndef big(k):\n    return np.full(5 * 2**20, float(k))\n"
    with box.session(src, budget=120) as session:
        got = session.map("big", [((k,), {}) for k in range(4)], seconds=60)
    limit = box.runtime.limits.result_bytes
    assert 40 * 2**20 < limit < 80 * 2**20   # one value fits, two do not
    assert got[0].status == "ok" and got[0].value.nbytes == 40 * 2**20
    assert [o.status for o in got[1:]] == ["malformed"] * 3
    assert all(o.value is None and "add up to more than" in o.message for o in got[1:])


def test_environment_is_minimal_and_the_workdir_is_fresh(box, monkeypatch):
    monkeypatch.setenv("HW4_GRADER_SECRET", "token")
    src = ("import os\ndef env():\n    before = sorted(os.listdir('.'))\n"
           "    open('left-behind.txt', 'w').write('x')\n    return dict(os.environ), os.getcwd(), before\n")
    environ, cwd, _ = run(box, src, Call("e", "env"))["e"].value
    _, _, before_second = run(box, src, Call("e", "env"))["e"].value
    assert "HW4_GRADER_SECRET" not in environ and environ["MPLBACKEND"] == "Agg"
    assert environ["HOME"] == cwd and environ["OPENBLAS_NUM_THREADS"] == "1"
    assert "left-behind.txt" not in before_second


# ---------------------------------------------------------------------------------------------
# other isolation levels


@pytest.mark.skipif(os.geteuid() != 0, reason="the refusal concerns a grader running as root")
def test_user_namespaces_are_refused_to_a_root_grader():
    # Mapped to root inside, student code would keep the grader's real uid (root).
    with pytest.raises(RuntimeError, match="would run as root"):
        Sandbox(KIT_ROOT, isolation="user-namespaces", limits=LIMITS)


@pytest.mark.parametrize("level", ["user-namespaces", "uid", "basic"])
def test_fallback_levels_run_jobs_and_say_what_they_are(level):
    if level == "user-namespaces" and os.geteuid() == 0:
        pytest.skip("refused to a root grader (see the test above); runs when the grader is not root")
    weak = level in ("user-namespaces", "basic")
    try:
        sandbox = Sandbox(KIT_ROOT, isolation=level, limits=LIMITS, allow_weak=weak)
    except RuntimeError as exc:
        pytest.skip(str(exc))
    with sandbox:
        r = run(sandbox, "def f(x):\n    return x * 2\n", Call("f", "f", (np.arange(3),)))
        assert np.array_equal(r["f"].value, [0, 2, 4])
        iso = sandbox.isolation
        assert iso.level == level and iso.weak == weak
        if level == "basic":
            assert not iso.network_isolated and iso.hidden_paths == () and iso.notes
        elif level == "uid":
            assert iso.uid not in (None, 0, os.getuid()) and iso.hidden_paths and not iso.network_isolated
        else:
            assert iso.network_isolated and iso.pid_namespace


@pytest.mark.parametrize("level", ["user-namespaces", "basic"])
def test_weak_levels_need_to_be_asked_for(level):
    with pytest.raises(RuntimeError, match="allow-weak-isolation|would run as root"):
        Sandbox(KIT_ROOT, isolation=level, limits=LIMITS)


def test_unknown_isolation_level_is_refused():
    with pytest.raises(ValueError, match="isolation"):
        Sandbox(KIT_ROOT, isolation="chroot")


def test_bad_calls_are_grader_errors(box):
    with box.session("def f(x): return x\n", budget=30) as session:
        with pytest.raises(ValueError, match="plain data"):
            session.call("f", object(), seconds=5)
        with pytest.raises(ValueError, match="positive"):
            session.call("f", 1, seconds=0)
        assert session.info.spawns == 0  # refused before anything ran


def test_a_session_loads_once_maps_inputs_and_stops_a_hung_function(box):
    src = ("import signal\ndef double(x): return 2 * x\n"
           "def hang(x):\n    signal.signal(signal.SIGALRM, signal.SIG_IGN)\n    while True: pass\n")
    with box.session(src, budget=60) as session:
        doubled = session.map("double", [((k,), {}) for k in range(4)], seconds=5)
        assert [o.value for o in doubled] == [0, 2, 4, 6]
        hung = session.map("hang", [((1,), {}), ((2,), {})], seconds=1)
        assert hung[0].status == "timeout" and hung[1].status == "skipped"
        again = session.call("hang", 3, seconds=1)  # not called again: no second wait
        assert again.status == "timeout" and "not run" in again.message and again.seconds is None
        assert session.call("double", 5, seconds=5).value == 10  # restarted lazily
    assert session.info.spawns == 2


def test_session_budget_stops_calls_that_come_too_late(box):
    with box.session("import time\ndef nap(): time.sleep(0.6)\n", budget=1.0) as session:
        first = session.call("nap", seconds=5)
        later = session.call("nap", seconds=5)
    assert first.status in ("ok", "timeout") and later.status == "timeout"
    assert "budget" in later.message


def test_cpu_clock_stops_a_spinning_call_at_its_cpu_budget_and_lets_a_waiting_one_finish(box):
    src = ("import time\n"
           "def spin():\n    while True: pass\n"
           "def nap_then_answer():\n    time.sleep(1.2)\n    return 7\n")
    with box.session(src, budget=60) as session:
        spun = session.call("spin", seconds=0.6, clock="cpu")
        # 1.2 s of sleep is almost no CPU time: within a 0.5 s CPU budget (wall clock: a timeout).
        napped = session.call("nap_then_answer", seconds=0.5, clock="cpu")
        spawns = session.info.spawns
        # A fresh child (the picture step's) and a request of several inputs: spin costs its limit once.
        session.restart()
        again = session.map("spin", [((), {}), ((), {})], seconds=0.6, clock="cpu")
    assert spun.status == "timeout" and spun.stopped_by == "cpu" and "CPU time" in spun.message
    assert 0.5 <= spun.seconds < 0.6 + 1.0  # stopped by the child itself, about when its CPU ran out
    assert napped.status == "ok" and napped.value == 7
    assert spawns == 1  # the child stopped the spinning call itself: no restart
    assert [o.status for o in again] == ["timeout"] * 2 and all("not run" in o.message for o in again)
    assert session.info.spawns == 1  # nothing was started to answer it


def test_cpu_clock_kills_a_sleeping_call_at_the_wall_backstop(box):
    src = "import time\ndef sleep_forever():\n    time.sleep(3600)\ndef fine(): return 1\n"
    with box.session(src, budget=60) as session:
        slept = session.call("sleep_forever", seconds=0.4, clock="cpu")
        again = session.call("sleep_forever", seconds=0.4, clock="cpu")
        fine = session.call("fine", seconds=5, clock="cpu")
    backstop = 0.4 * LIMITS.wall_factor + LIMITS.grace
    assert slept.status == "timeout" and slept.stopped_by == "backstop" and "waiting" in slept.message
    assert backstop - 0.1 <= slept.seconds < backstop + 1.5
    assert again.stopped_by == "backstop" and "not run" in again.message  # not waited for twice
    assert fine.value == 1 and session.info.spawns == 2  # the killed child was replaced


def test_wall_clock_is_the_default_and_says_so(box):
    r = run(box, "def spin():\n    while True: pass\n", Call("s", "spin", timeout=0.5))
    assert r["s"].status == "timeout" and r["s"].stopped_by == "wall" and "CPU" not in r["s"].message


def test_clock_settings_are_checked_and_travel_with_the_limits():
    limits = ResourceLimits(clock="cpu", wall_factor=2.5)
    assert ResourceLimits(**vars(limits)) == limits  # what Sandbox.describe/attach hand over
    with pytest.raises(ValueError, match="clock"):
        ResourceLimits(clock="gpu")
    with pytest.raises(ValueError, match="wall_factor"):
        ResourceLimits(clock="cpu", wall_factor=0.5)


def test_chained_calls_feed_one_functions_results_to_another(box):
    src = "import numpy as np\ndef match(im, x):\n    return np.array([x + im.sum(), 0.0])\n" \
          "def total(pts):\n    return float(np.sum(pts))\n"
    with box.session(src, budget=60) as session:
        matched = session.map("match", [((x,), {}) for x in (1.0, 2.0)], args=(np.ones((2, 2)),), seconds=5)
        pts = np.array([o.value for o in matched])
        assert session.call("total", pts, seconds=5).value == 5.0 + 6.0


# ---------------------------------------------------------------------------------------------
# the wire format


def npy_text(arr, allow_pickle=False) -> str:
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=allow_pickle)
    return base64.b64encode(buf.getvalue()).decode()


def test_wire_round_trip_and_agreement_with_the_child(rng):
    value = {"F": rng.normal(size=(3, 3)), "n": 3, "t": (1.5, [True, None, "s"]), "inf": -np.inf,
             "big": np.arange(6, dtype=">i4").reshape(2, 3)}
    back = wire.loads(wire.dumps(value))
    assert np.array_equal(back["F"], value["F"]) and back["t"] == (1.5, [True, None, "s"])
    assert back["big"].dtype == np.int32 and back["big"].dtype.isnative and back["inf"] == -np.inf
    # What the child sends, the grader reads; what the grader sends, the child reads.
    from_child = wire.decode(json.loads(json.dumps(wire.encode_returned(value))))
    assert np.array_equal(from_child["F"], value["F"]) and from_child["t"] == value["t"]
    assert from_child["big"].dtype == np.int32


@pytest.mark.parametrize("payload, match", [
    ({"__ndarray__": npy_text(np.array([object()]), allow_pickle=True)}, "dtype"),
    ({"__ndarray__": npy_text(np.zeros(2, dtype=[("a", "f8")]))}, "dtype"),
    ({"__ndarray__": npy_text(np.array(["text"]))}, "dtype"),
    ({"__ndarray__": "not base64!"}, "base64"),
    ({"__ndarray__": npy_text(np.zeros(4))[:-8]}, "bytes"),
    ({"__pickle__": "gASVAAAA"}, "tag"),
    ({"__tuple__": [], "extra": 1}, "plain data"),
    ({"__float__": "1e308"}, "float"),
])
def test_wire_rejects_what_is_not_plain_data(payload, match):
    with pytest.raises(wire.WireError, match=match):
        wire.decode(payload)


def test_wire_limits():
    big = {"__ndarray__": npy_text(np.zeros(1000))}
    with pytest.raises(wire.WireError, match="at most"):
        wire.decode(big, wire.Limits(max_array_bytes=4000))
    with pytest.raises(wire.WireError, match="finite"):
        wire.decode({"__ndarray__": npy_text(np.array([1.0, np.nan]))}, wire.Limits(finite=True))
    deep = []
    for _ in range(40):
        deep = [deep]
    with pytest.raises(wire.WireError, match="nesting"):
        wire.decode(deep)
    with pytest.raises(wire.WireError, match="strict JSON"):
        wire.loads('{"__float__": NaN}')
    with pytest.raises(wire.WireError, match="unique keys"):
        wire.loads('{"__tuple__": [], "__tuple__": [1]}')
    with pytest.raises(wire.WireError, match="expected None"):
        wire.encode(np.zeros(3).view(np.matrix))


def test_two_grader_processes_never_share_a_uid():
    # Each grader reserves its uid with a lock that other processes see: while one process holds
    # the only uid of a range, another process finds none free in that range.
    import subprocess
    import sys

    code = ("import sys; from autograder.sandbox.uids import pick_uid; uid, fd = pick_uid(61234, 1); "
            "print(uid, flush=True); sys.stdin.read()")
    env = {**os.environ, "PYTHONPATH": str(KIT_ROOT)}
    first = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                             env=env)
    try:
        assert int(first.stdout.readline()) == 61234
        second = subprocess.run([sys.executable, "-c", code], input="", capture_output=True, text=True, env=env)
        assert second.returncode != 0 and "no free uid" in second.stderr
    finally:
        first.communicate("", timeout=30)
    # Released with its process: the uid is free again.
    again = subprocess.run([sys.executable, "-c", code], input="", capture_output=True, text=True, env=env)
    assert again.returncode == 0 and int(again.stdout) == 61234


# ---------------------------------------------------------------------------------------------
# results written by student code are never taken for the grader's

_SAVES_RESULTS = """
import os
import numpy as np
import matplotlib.pyplot as plt

def eightpoint(pts1, pts2, M):
    F = np.eye(3)
    np.savez('results/q2_1.npz', F=F, M=M)
    with open('../results/q2_1.txt', 'w') as f:
        f.write(str(M))
    plt.figure()
    plt.plot([0, 1], [0, 1])
    plt.savefig('results/f.png')
    plt.close('all')
    np.save(os.path.join('..', 'results', 'q2_1_again.npy'), F)
    return F, sorted(os.listdir('results')), sorted(os.listdir('../results')), os.getcwd()
"""


@pytest.mark.parametrize("private_tmp", [True, False])
def test_function_that_saves_into_results_and_parent_results_gets_its_result(box, private_tmp):
    def check(sandbox):
        r = run(sandbox, _SAVES_RESULTS, Call("e", "eightpoint", (np.zeros((8, 2)), np.zeros((8, 2)), 640)))
        assert r["e"].status == "ok", r["e"].message
        F, here, parent, cwd = r["e"].value
        assert np.array_equal(F, np.eye(3))
        assert here == ["f.png", "q2_1.npz"] and parent == ["q2_1.txt", "q2_1_again.npy"]
        # ../results lies inside the child's own scratch folder, never in the grader's or the kit's.
        scratch = Path(cwd).parent
        assert not str(scratch).startswith(str(KIT_ROOT)) and scratch != Path("/tmp")
        assert not (KIT_ROOT / "results" / "q2_1.txt").exists()

    if private_tmp:
        check(box)
    else:
        with Sandbox(KIT_ROOT, private_tmp=False, limits=LIMITS) as sandbox:
            check(sandbox)
