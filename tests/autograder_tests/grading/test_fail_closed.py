"""The grader fails closed: never weaker isolation than it claims, and a canary first.

Deployment shapes reproduced here (see ../shared/FIELD-NOTES.md):

- a container like Gradescope's: the command runs as root with Docker's default capability set
  (``setpriv --bounding-set``), where namespaces cannot be made;
- a Python under a private folder (this machine's pyenv under /root, mode 0700);
- a public Python (Debian's /usr/bin/python3) with the kit's packages: a venv made here whose
  site-packages is a hard-linked copy of the kit's (the same wheels, cp311);
- a kit in a 0700 folder (``mktemp -d``) with its virtual environment reached through a symlink.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
import stat
import subprocess
import sys
import sysconfig
import tempfile
import textwrap
import threading
from pathlib import Path

import nbformat
import pytest

from corpus import hostile
from core.paths import KIT_ROOT
from containers import in_container, public_folder, public_venv, run

pytestmark = [pytest.mark.slow, pytest.mark.skipif(os.geteuid() != 0 or shutil.which("setpriv") is None,
                                reason="the deployment shapes need root and util-linux setpriv")]


@pytest.fixture(scope="module")
def public_root():
    root = public_folder()
    yield root
    shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(scope="module")
def public_python(public_root) -> Path:
    return public_venv(public_root / "venv")


def notebook_submission(folder: Path, cells: dict[str, str]) -> Path:
    """A submission folder with one notebook per stem, each holding one code cell."""
    folder.mkdir(parents=True)
    for stem, source in cells.items():
        nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(source)])
        nbformat.write(nb, folder / f"{stem}.ipynb")
    return folder


# What a channel does: open the sandbox, run the canary, grade; prints JSON of what happened.
DRIVER = textwrap.dedent("""\
    import json, os, sys
    from autograder.inputs.config import quick_config
    from autograder.grading.run import GradingRun
    from autograder.sandbox import Sandbox

    subs = sys.argv[2:]
    with Sandbox(hidden=[os.path.dirname(p) for p in subs[:1]], allow_weak=sys.argv[1] == "weak") as box, \
            GradingRun(quick_config(), sandbox=box) as run:
        out = {"isolation": box.isolation.as_dict(), "grader_uid": os.getuid()}
        report = run.run_canary()
        out["canary"] = [report.score, report.max_score]
        for path in subs:
            result = run.grade(path)
            out[os.path.basename(path)] = {q.id: q.score for q in result.questions}
    print("RESULT " + json.dumps(out))
""")


def driver(tmp_path: Path) -> str:
    path = tmp_path / "driver.py"
    path.write_text(DRIVER)
    os.chmod(tmp_path, 0o700)
    return str(path)


def parse(proc: subprocess.CompletedProcess) -> dict:
    line = next((x for x in proc.stdout.splitlines() if x.startswith("RESULT ")), None)
    assert line is not None, f"exit {proc.returncode}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return json.loads(line[len("RESULT "):])


@contextlib.contextmanager
def listener():
    """``(port, heard)``: a TCP server on 127.0.0.1 whose every connection's bytes go into ``heard``."""
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(0.2)
    heard: list[bytes] = []
    stop = threading.Event()

    def serve():
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            with conn:
                conn.settimeout(2)
                try:
                    heard.append(conn.recv(1000) or b"(connected)")
                except OSError:
                    heard.append(b"(connected)")

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield server.getsockname()[1], heard
    finally:
        stop.set()
        thread.join(5)
        server.close()


def phones_home(port: int) -> str:
    """A notebook cell that sends what it can reach to 127.0.0.1:``port``, on loading and in each call,
    also from a process it starts."""
    return textwrap.dedent(f"""\
        import socket, subprocess, sys
        def _send(what):
            try:
                socket.create_connection(("127.0.0.1", {port}), timeout=3).sendall(what)
            except OSError:
                pass
        _send(b"loaded")
        subprocess.run([sys.executable, "-c", "import socket; socket.create_connection(('127.0.0.1', {port}), 3).sendall(b'child')"])
        def eightpoint(pts1, pts2, M, refine=True):
            _send(b"called")
            try:
                socket.create_connection(("::1", {port}), timeout=3).sendall(b"v6")
            except OSError:
                pass
        """)


def test_internet_sockets_are_refused_in_a_container_without_namespaces(tmp_path):
    # Docker's default capabilities (no CAP_SYS_ADMIN, so no network namespace): the sandbox's child
    # installs a seccomp filter (no capability needed after PR_SET_NO_NEW_PRIVS) before any student code.
    program = textwrap.dedent("""\
        import sys
        from autograder.sandbox import Sandbox
        src = open(sys.argv[1]).read()
        with Sandbox(isolation="basic", allow_weak=True) as box:
            print("NOTES", box.isolation.notes)
            with box.session(src, budget=60) as session:
                print("CALL", session.call("eightpoint", None, None, 1, seconds=20).status)
                print("UNIX", session.call("_unix", seconds=5).value)
        """)
    (tmp_path / "program.py").write_text(program)
    (tmp_path / "cell.py").write_text("")
    with listener() as (port, heard):
        (tmp_path / "cell.py").write_text(phones_home(port) + "def _unix():\n    a, b = socket.socketpair()\n"
                                          "    a.sendall(b'x')\n    return b.recv(1).decode()\n")
        proc = run(in_container([sys.executable, str(tmp_path / "program.py"), str(tmp_path / "cell.py")]))
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "CALL ok" in proc.stdout and "UNIX x" in proc.stdout  # the code ran; Unix sockets work
    assert "refused by a seccomp filter" in proc.stdout
    assert heard == [], heard


# ---------------------------------------------------------------------------------------------
# a Python under a private folder, in a container


def test_private_python_in_a_container_is_refused_not_run_as_root(tmp_path):
    # Before: the sandbox fell to its basic level and ran student code as root, with one warning.
    assert script_python_is_private(), "this machine's Python should live under /root (mode 0700)"
    probe = "from autograder.sandbox import Sandbox\nSandbox()\n"
    proc = run(in_container([sys.executable, "-c", probe]))
    assert proc.returncode != 0
    assert "IsolationRefused" in proc.stderr and "/root" in proc.stderr and "venv" in proc.stderr
    assert "--allow-weak-isolation" in proc.stderr
    # Weaker only when asked for, and then it says so.
    weak = run(in_container([sys.executable, "-c", "from autograder.sandbox import Sandbox\n"
                             "b = Sandbox(allow_weak=True)\nprint(b.isolation.as_dict()['weak'], b.isolation.summary())\n"
                             "b.close()\n"]))
    assert weak.returncode == 0, weak.stderr
    assert weak.stdout.startswith("True basic (WEAK")


def script_python_is_private() -> bool:
    from autograder.sandbox.script import unreachable_python_dirs

    return bool(unreachable_python_dirs())


# ---------------------------------------------------------------------------------------------
# a container with a public Python: the uid level


@pytest.mark.slow
def test_container_runs_hostile_code_as_its_own_uid_and_hides_the_graders_files(tmp_path, public_python):
    # An answer key a TA wrote into a world-readable folder of /tmp (as in the issue).
    key_out = Path(tempfile.mkdtemp(prefix="kk-"))
    os.chmod(key_out, 0o755)
    subs_dir = tmp_path / "subs"
    try:
        made = run([sys.executable, "-m", "autograder", "key", "--out", str(key_out)])
        assert made.returncode == 0, made.stderr
        assert stat.S_IMODE((key_out / "hw4_key").stat().st_mode) == 0o700
        assert stat.S_IMODE((key_out / "hw4_key.zip").stat().st_mode) == 0o600
        kill = notebook_submission(subs_dir / "kills_parent", {"q2_eightpoint": hostile.KILLS_PARENT})
        steal = notebook_submission(subs_dir / "imports_solutions", {
            "q6_multiview_car": hostile.reads_grader_files(str(KIT_ROOT), str(tmp_path))})
        find = notebook_submission(subs_dir / "finds_answer_key", {
            "q6_multiview_car": hostile.finds_answer_key([str(key_out), "/tmp", "/var/tmp", str(KIT_ROOT)])})
        probe = notebook_submission(subs_dir / "reports_uid", {"q2_eightpoint": textwrap.dedent("""\
            import os
            import numpy as np
            def eightpoint(pts1, pts2, M, refine=True):
                if os.getuid() in (0,):
                    return None
                return np.zeros((3, 3))
            """)})
        with listener() as (port, heard):
            phone = notebook_submission(subs_dir / "phones_home", {"q2_eightpoint": phones_home(port)})
            proc = run(in_container([str(public_python), driver(tmp_path), "strict",
                                     str(kill), str(steal), str(find), str(probe), str(phone)]), timeout=900)
        got = parse(proc)  # the batch survived the submission that signals its parent
    finally:
        shutil.rmtree(key_out, ignore_errors=True)
    assert heard == [], heard  # no internet socket at the uid level (seccomp), though no network namespace
    assert any("refused by a seccomp filter" in n for n in got["isolation"]["notes"])
    iso = got["isolation"]
    assert iso["level"] == "uid" and not iso["weak"]
    assert iso["uid"] not in (None, 0, got["grader_uid"])
    assert str(KIT_ROOT / "solutions") in iso["hidden_paths"] and str(KIT_ROOT / "notebooks" / "key") in iso["hidden_paths"]
    assert got["canary"][0] >= got["canary"][1] > 0
    assert got["imports_solutions"]["Q6"] == 0
    assert got["finds_answer_key"]["Q6"] == 0
    assert sum(got["kills_parent"].values()) == 0


# Lists every folder above the staff folder given (and the kit's root), as the sandbox's uid.
LISTS_PARENTS = textwrap.dedent("""\
    import json, os, sys
    from autograder.sandbox import Sandbox
    src = ("import os\\ndef look(paths):\\n    out = {}\\n    for p in paths:\\n        try:\\n"
           "            out[p] = os.listdir(p)\\n        except OSError as exc:\\n            out[p] = exc.errno\\n"
           "    import numpy\\n    return out\\n")
    staff = sys.argv[1]
    above = [os.path.dirname(staff), os.path.dirname(os.path.dirname(staff)), sys.argv[2]]
    with Sandbox(hidden=[staff], isolation="uid") as box, box.session(src, budget=60) as session:
        got = session.call("look", above, seconds=30)
    print("RESULT " + json.dumps({"status": got.status, "message": got.message, "value": got.value,
                                  "above": above}))
""")


def test_uid_level_hides_the_names_of_hidden_paths_from_their_folders_listings(tmp_path, public_python, public_root):
    """Denied by an ACL, a hidden path was still named by its folder's listing: every folder above
    a hidden path (but the root and the Python's own) is pass-through only for the sandbox."""
    course = public_root / "course-of-fall"
    staff = course / "grades-of-section-B"
    staff.mkdir(parents=True)
    (course / "notes-for-tas.txt").write_text("x")
    for p in (course, staff):
        os.chmod(p, 0o755)
    script = tmp_path / "lists.py"
    script.write_text(LISTS_PARENTS)
    os.chmod(tmp_path, 0o700)
    got = parse(run(in_container([str(public_python), str(script), str(staff), str(KIT_ROOT)]), timeout=300))
    assert got["status"] == "ok", got["message"]
    seen = got["value"]
    assert seen[str(course)] == 13 and seen[str(public_root)] == 13, seen   # EACCES
    assert seen[str(KIT_ROOT)] == 13, seen   # it holds solutions/ and the other hidden folders
    # The grader and every other user list them as before.
    assert "grades-of-section-B" in os.listdir(course)


@pytest.mark.slow
def test_canary_refuses_a_sandbox_that_cannot_import_a_package(tmp_path, public_root):
    # The silent class of zeros: the sandbox's user could not read the environment
    # ("No module named 'PIL'") and every submission, the key included, scored 0-10 with exit 0.
    python = public_venv(public_root / "venv-no-pil")
    site = python.parents[1] / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
    os.chmod(site / "PIL", 0o700)  # only its owner (the grader) may read it
    sub = notebook_submission(tmp_path / "subs" / "someone", {"q2_eightpoint": "def eightpoint(a, b, M):\n    pass\n"})
    proc = run(in_container([str(python), driver(tmp_path), "strict", str(sub)]), timeout=900)
    assert proc.returncode != 0 and "RESULT" not in proc.stdout  # nothing graded
    assert "CanaryFailed" in proc.stderr and "PIL" in proc.stderr
    assert "cannot import" in proc.stderr


# ---------------------------------------------------------------------------------------------
# a kit in a private folder, its venv through a symlink


@pytest.mark.slow
def test_kit_in_a_private_folder_with_a_symlinked_venv_is_refused(tmp_path):
    private = Path(tempfile.mkdtemp())  # 0700, as mktemp -d makes
    try:
        kit = private / "kit"
        kit.mkdir()
        for name in ("autograder", "core", "scenes", "starter", "judging", "solutions", "kit", "handin",
                     "notebooks", "data", "requirements.txt", "pyproject.toml"):
            src = KIT_ROOT / name
            if src.is_dir():
                shutil.copytree(src, kit / name, symlinks=True, ignore=shutil.ignore_patterns("__pycache__"))
            elif src.exists():
                shutil.copy2(src, kit / name)
        (kit / ".venv").symlink_to(Path(sys.prefix))
        python = str(kit / ".venv" / "bin" / "python")
        # What every channel runs first: the sandbox and the canary, in the batch's configuration.
        sub = notebook_submission(tmp_path / "subs" / "someone", {"q2_eightpoint": "def eightpoint(a, b, M):\n    pass\n"})
        proc = run([python, driver(tmp_path), "strict", str(sub)], cwd=kit, timeout=900)
        assert proc.returncode != 0 and "RESULT" not in proc.stdout
        assert str(private) in proc.stderr or "/root" in proc.stderr, proc.stderr[-2000:]
        # The CLI: nonzero exit, the message names the problem, no grades.
        out = tmp_path / "out"
        cli = run([python, "-m", "autograder", "grade", str(sub), "--out", str(out), "--quiet"], cwd=kit)
        assert cli.returncode != 0, cli.stdout + cli.stderr
        assert "isolation" in cli.stderr or "canary" in cli.stderr
        assert not list(out.glob("*/results.json"))
    finally:
        shutil.rmtree(private, ignore_errors=True)


# ---------------------------------------------------------------------------------------------
# the grader's own files


def test_answer_key_is_written_owner_only(tmp_path):
    from autograder.grading.key import write_key_submission

    os.chmod(tmp_path, 0o755)
    old = os.umask(0o022)
    try:
        archive = write_key_submission(tmp_path / "kk")
    finally:
        os.umask(old)
    assert stat.S_IMODE(archive.stat().st_mode) == 0o600
    for p in [tmp_path / "kk", tmp_path / "kk" / "hw4_key"]:
        assert stat.S_IMODE(p.stat().st_mode) == 0o700
    assert all(stat.S_IMODE(p.stat().st_mode) == 0o600 for p in (tmp_path / "kk" / "hw4_key").iterdir())


@pytest.mark.slow
def test_canary_gives_the_key_full_marks_in_the_strongest_sandbox():
    from autograder.inputs.config import quick_config
    from autograder.grading.run import GradingRun
    from autograder.sandbox import Sandbox

    with Sandbox(KIT_ROOT) as box, GradingRun(quick_config(), sandbox=box) as run:
        report = run.run_canary()
    assert report.score >= report.max_score > 0 and report.isolation["level"] == box.isolation.level
    assert report.seconds < 30
