"""What a submission leaves behind: within its sandbox, one question's leak never costs
another question; on the machine, the ``uid`` level leaves nothing and keeps concurrent
submissions apart.

Both levels are tested: ``namespaces`` (this machine as root) and ``uid`` (a container like
Gradescope's: Docker's default capabilities through ``setpriv``, with a public Python's venv, see
tests/autograder_tests/grading/test_fail_closed.py and ../shared/FIELD-NOTES.md).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import corpus
import nbformat
import pytest
from corpus import hostile

from autograder.feedback.results import autograded_question_ids
from core.manifest import question
from core.paths import KIT_ROOT
from graded_keys import SHARED, full_marks, key_with, owned_by
from containers import in_container
from containers import run

LEAKER = "leaks_fds_and_cwd_in_epipolarCorrespondence_full_marks"

pytestmark = [pytest.mark.slow, pytest.mark.skipif(os.geteuid() != 0 or shutil.which("setpriv") is None or shutil.which("unshare") is None,
                                reason="the levels tested need root, util-linux setpriv and unshare")]


def python_for(level: str, public_python: Path) -> list[str]:
    """How to run a grader program at ``level``: this Python as root, or the public one in a container."""
    return [sys.executable] if level == "namespaces" else in_container([str(public_python)])


# ---------------------------------------------------------------------------------------------
# within a sandbox: a call's leaks are undone before the next request


LEAKS = textwrap.dedent("""\
    import os, signal, sys, threading, time, warnings
    def leak():
        quiet = os.open(os.devnull, os.O_WRONLY)
        os.dup2(quiet, 1)
        os.dup2(quiet, 2)
        for _ in range(20):
            os.open(os.devnull, os.O_RDONLY)
        os.chdir("/")
        os.environ["HW4_LEAKED"] = "1"
        os.umask(0o777)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        signal.pthread_sigmask(signal.SIG_BLOCK, [signal.SIGALRM])
        sys.stdout = open(os.devnull, "w")
        warnings.simplefilter("error")
        return len(os.listdir("/proc/self/fd"))
    def state():
        out = os.fstat(1)
        return {"fds": len(os.listdir("/proc/self/fd")), "cwd": os.getcwd(), "leaked": "HW4_LEAKED" in os.environ,
                "umask": os.umask(0o022), "sigterm": str(signal.getsignal(signal.SIGTERM)),
                "alarm_blocked": signal.SIGALRM in signal.pthread_sigmask(signal.SIG_BLOCK, []),
                "stdout_replaced": sys.stdout is not sys.__stdout__, "stdout_is_devnull": out.st_rdev == os.stat(os.devnull).st_rdev
                and stat_chr(out.st_mode), "warnings_error": any(f[0] == "error" for f in warnings.filters)}
    def stat_chr(mode):
        import stat
        return stat.S_ISCHR(mode)
    def spins_a_thread():
        threading.Thread(target=time.sleep, args=(60,), daemon=True).start()
        return threading.active_count()
    def threads():
        return threading.active_count()
    """)

PROGRAM = textwrap.dedent("""\
    import json, sys
    from autograder.sandbox import Sandbox
    with Sandbox(isolation=sys.argv[1]) as box:
        with box.session(sys.argv[2], budget=120) as s:
            out = {"level": box.isolation.level}
            out["before"] = s.call("state", seconds=20).value
            out["leak"] = s.call("leak", seconds=20).status
            out["after"] = s.call("state", seconds=20).value
            out["again"] = s.call("leak", seconds=20).status
            out["after_again"] = s.call("state", seconds=20).value
            out["spins"] = s.call("spins_a_thread", seconds=20).value
            out["threads"] = s.call("threads", seconds=20).value
            out["spawns"] = s.info.spawns
    print("RESULT " + json.dumps(out))
    """)


@pytest.mark.parametrize("level", ["namespaces", "uid"])
def test_what_a_call_leaves_behind_is_undone_before_the_next_request(level, tmp_path, public_python):
    # Before: a function that sent fds 1 and 2 to /dev/null through a descriptor it never closed,
    # moved to "/" and changed the environment, the umask, a signal handler, the signal mask,
    # sys.stdout and the warnings filters left all of it to every later call of the submission.
    program = tmp_path / "program.py"
    program.write_text(PROGRAM)
    os.chmod(tmp_path, 0o755)
    proc = run(python_for(level, public_python) + [str(program), level, LEAKS], timeout=300)
    line = next((x for x in proc.stdout.splitlines() if x.startswith("RESULT ")), None)
    assert line is not None, proc.stderr[-3000:]
    got = json.loads(line[len("RESULT "):])
    assert got["level"] == level and got["leak"] == got["again"] == "ok"
    before = got["before"]
    assert not before["stdout_is_devnull"] and not before["leaked"] and before["umask"] == 0o022
    for after in (got["after"], got["after_again"]):
        assert after == before, (before, after)  # fds, folder, environment, umask, handlers, mask, stdout, warnings
    # A thread still running cannot be undone in place: the next request gets a fresh process.
    assert got["spins"] == 2 and got["threads"] == 1 and got["spawns"] == 2


@pytest.mark.slow
def test_fd_leaking_matcher_costs_no_other_question_at_the_namespaces_level(tmp_path):
    # The submission (the key, with an epipolarCorrespondence that leaks a descriptor on
    # every call and moves to "/"), graded by the CLI: before, Q6's plot_3d_keypoint_video failed
    # with "Too many open files" later in the same sandbox and Q6 lost 2 points it had earned.
    sub = corpus.build(LEAKER, tmp_path / "subs")
    out = tmp_path / "out"
    proc = run([sys.executable, "-m", "autograder", "grade", str(sub), "--out", str(out), "--quiet",
                "--isolation", "namespaces", "--no-pictures"])
    assert proc.returncode == 0, proc.stderr[-3000:]
    state = json.loads((out / LEAKER / "grading.json").read_text())
    assert state["isolation"]["level"] == "namespaces"
    assert full_marks(state["scores"]) == [], state["scores"]


# ---------------------------------------------------------------------------------------------
# the uid level, in a container: one batch of hostile submissions graded two at a time


@pytest.mark.slow
def test_uid_level_batch_leaves_nothing_and_keeps_concurrent_submissions_apart(tmp_path, public_python):
    subs = tmp_path / "subs"
    # The colluding pair sorts first, so that two workers would load them at the same time.
    pair = [key_with(subs / f"colluder_{k}", "q2_eightpoint", hostile.COLLUDES, base="student") for k in (1, 2)]
    disk = key_with(subs / "fills_disk", "q3_metric_reconstruction", hostile.fills_disk(), base="student")
    inodes = key_with(subs / "fills_inodes", "q3_metric_reconstruction", hostile.fills_inodes(), base="student")
    leaker = corpus.build(LEAKER, subs)
    lister = key_with(subs / "lists_processes", "q2_eightpoint", hostile.LISTS_PROCESSES, base="student")
    out = tmp_path / "out"
    os.chmod(tmp_path, 0o755)
    try:
        proc = run(in_container([str(public_python), "-m", "autograder", "grade", *map(str, pair), str(disk),
                                 str(inodes), str(leaker), str(lister), "--out", str(out), "--jobs", "2",
                                 "--isolation", "uid", "--quiet", "--no-pictures"]), timeout=1500)
        assert proc.returncode == 0, proc.stderr[-3000:]
        states = {p.name: json.loads((out / p.name / "grading.json").read_text())
                  for p in [*pair, disk, inodes, leaker, lister]}
        uids = {name: s["isolation"]["uid"] for name, s in states.items()}
        assert {s["isolation"]["level"] for s in states.values()} == {"uid"}
        # Uids of their own (neither the grader's nor root).  --jobs 2 was lowered to 1 at this level
        # (summary.md, below): the pair never ran at the same time, whatever they tried.
        assert not {0, os.getuid()} & set(uids.values())

        # Nothing of theirs is left in /tmp, /var/tmp, /dev/shm or /run/lock.
        assert owned_by(set(uids.values())) == []

        # The pair heard nothing from each other: no abstract Unix socket, no world-writable notes.
        for name in ("colluder_1", "colluder_2"):
            heard = [x for x in states[name]["staff"]["stdout"].splitlines() if x.startswith("COLLUDERS-HEARD ")]
            assert heard and set(heard) == {"COLLUDERS-HEARD []"}, (name, heard[-1:])

        # A process listing from inside shows the grader's processes but no submission path.
        listed = next(x for x in states["lists_processes"]["staff"]["stdout"].splitlines() if x.startswith("PROCESSES "))
        assert "autograder" in listed  # the listing works: it sees the grader's command line...
        assert str(subs) not in listed and "colluder_" not in listed and str(out) not in listed  # ...not its arguments

        # The leaking matcher costs no other question (before: Q6 lost 2 points to "Too many open files").
        assert full_marks(states[LEAKER]["scores"]) == [], states[LEAKER]["scores"]

        # Past the disk quota: stopped, said to staff; what was removed is for staff, not the student.
        for name in ("fills_disk", "fills_inodes"):
            quota = states[name]["staff"]["over_quota"]
            assert quota and "disk quota" in quota[0], (name, states[name]["staff"])
        removed = states["fills_disk"]["staff"]["removed"]
        assert removed["entries"] >= 1 and removed["bytes"] >= 60 * 2**20  # its /dev/shm files
        summary = (out / "summary.md").read_text()
        assert "## Past the sandbox's disk quota" in summary and "- fills_disk:" in summary
        assert "## Left in the shared temporary folders" in summary
        assert "graded one at a time (--jobs was lowered to 1)" in summary   # /dev/shm is shared there
        for name in ("fills_disk", "fills_inodes"):
            feedback = (out / name / "feedback.md").read_text()
            assert "disk quota" in feedback and "removed" not in feedback
    finally:
        # What a failing run (the code before this change) left in the shared folders.
        for root in SHARED:
            for pattern in ("hw4-fill-*", "hw4-inode-*", "hw4-colluders-notes-*"):
                for p in Path(root).glob(pattern):
                    p.unlink(missing_ok=True)


# ---------------------------------------------------------------------------------------------
# the sweep of the shared temporary folders


def test_a_uids_leftovers_are_found_by_owner_and_links_never_followed(tmp_path):
    import pwd

    from autograder.sandbox.uids import remove_files_of_uid

    uid = next(u for u in range(64999, 60000, -1) if not _has_passwd(pwd, u))
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o1777)
    os.chmod(shared, 0o1777)
    grader = tmp_path / "grader"
    grader.mkdir()
    (grader / "keep.txt").write_text("the grader's")
    mine = shared / "fill.bin"
    mine.write_bytes(b"x" * 2**20)
    folder = shared / "folder"
    (folder / "deeper").mkdir(parents=True)
    (folder / "deeper" / "f").write_text("x")
    public = shared / "public"  # another user's world-writable folder: the code may write there too
    public.mkdir(mode=0o777)
    os.chmod(public, 0o777)
    (public / "note").write_text("x")
    (shared / "link").symlink_to(grader)
    (public / "link").symlink_to(grader / "keep.txt")
    for p in (mine, folder, folder / "deeper", folder / "deeper" / "f", public / "note", shared / "link",
              public / "link"):
        os.lchown(p, uid, uid)
    entries, size = remove_files_of_uid(uid, [str(shared)])
    # Its file, its folder with what is inside, its file in another user's folder and its two links.
    assert entries == 7 and size >= 2**20
    assert sorted(os.listdir(shared)) == ["public"] and os.listdir(public) == []
    assert (grader / "keep.txt").read_text() == "the grader's"  # a link's target is never touched


def _has_passwd(pwd, uid: int) -> bool:
    try:
        pwd.getpwuid(uid)
        return True
    except KeyError:
        return False


LEAVES_FILES = textwrap.dedent("""\
    import os
    def leave(token):
        made = []
        for folder in ("/tmp", "/var/tmp", "/dev/shm", "/run/lock"):
            if os.path.isdir(folder) and os.access(folder, os.W_OK):
                with open(os.path.join(folder, token), "w") as fh:
                    fh.write("left behind")
                made.append(folder)
        return made
    """)


@pytest.mark.slow
def test_behind_a_private_root_nothing_reaches_the_hosts_temporary_folders(tmp_path):
    # At the namespaces level the code's /tmp, /var/tmp and /dev/shm are tmpfs of its own, gone
    # with the namespace, and its root holds no other writable folder of the host's (/run/lock is
    # not there).  The host's folders never see its files, so there is nothing to sweep.
    from autograder.sandbox import Sandbox

    token = f"hw4-left-{os.getpid()}-{tmp_path.name}"
    with Sandbox(isolation="namespaces") as box:
        assert box.isolation.level == "namespaces" and box.isolation.private_tmp
        with box.session(LEAVES_FILES, budget=60) as s:
            made = s.call("leave", token, seconds=20).value
            for folder in ("/tmp", "/dev/shm", "/var/tmp"):
                assert not os.path.lexists(os.path.join(folder, token))  # its own tmpfs, not the host's
        removed = s.info.removed
    assert "/tmp" in made and "/dev/shm" in made and "/run/lock" not in made, made
    for folder in ("/tmp", "/dev/shm", "/var/tmp", "/run/lock"):
        assert not os.path.lexists(os.path.join(folder, token)), folder
    assert removed[0] == 0, removed
