"""The Colab route, end to end, in a Colab-like runtime built here.

What stands in for Colab:

- a kernel in its own virtual environment with Colab's widget stack: ipywidgets 7.7.x and no
  anywidget (numpy 2.0 as on Colab), made from the release's requirements.txt and cached in
  ``$HW4_COLAB_VENV`` (default build/colab-venv; .ci/run makes it, and this test makes it when
  missing, so it never skips);
- a fake ``google.colab`` imported when the kernel starts, as Colab's is: ``drive.mount(path)``
  links ``path`` to a folder of the test (the student's Google Drive), and
  ``output.enable_custom_widget_manager()`` and ``files.download(path)`` only record the call;
- a fresh ``/content`` (``$HW4_COLAB_ROOT``, the kernel's working folder) for every notebook, as
  every Colab session starts empty;
- a local git repository (file://) made from ``python -m kit release --repo-url file:///...`` as
  the "GitHub" the setup cell clones.

The student's notebooks sit in the Drive folders under the names Colab gives them ("Copy of
q3_metric_reconstruction.ipynb"), and each executed notebook is saved back there, as Colab does.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import nbformat
import pytest

from core.manifest import NOTEBOOKS
from core.paths import KIT_ROOT

pytestmark = pytest.mark.slow

COLAB_VENV = Path(os.environ.get("HW4_COLAB_VENV") or KIT_ROOT / "build" / "colab-venv")
# Colab's versions of what the kit relies on; anywidget is absent there.
COLAB_PINS = ("ipywidgets==7.7.*", "numpy==2.0.*")
NOT_ON_COLAB = ("anywidget",)
KERNEL = "hw4-colab-like"

FAKE_COLAB = {
    "__init__.py": '''\
"""A stand-in for Colab's google.colab (tests only): calls are recorded in $HW4_FAKE_COLAB_LOG."""
import json
import os
import time


def _record(call, *args):
    with open(os.environ["HW4_FAKE_COLAB_LOG"], "a", encoding="utf-8") as f:
        f.write(json.dumps({"call": call, "args": [str(a) for a in args], "time": time.time()}) + "\\n")
''',
    "drive.py": '''\
import os

from google.colab import _record


def mount(mountpoint, force_remount=False, **kwargs):
    """Link ``mountpoint`` to the test's Drive folder ($HW4_FAKE_DRIVE, which holds MyDrive/)."""
    _record("drive.mount", mountpoint)
    if os.path.islink(mountpoint):
        print("Drive already mounted at " + mountpoint)
        return
    os.makedirs(os.path.dirname(mountpoint), exist_ok=True)
    os.symlink(os.environ["HW4_FAKE_DRIVE"], mountpoint)
    print("Mounted at " + mountpoint)
''',
    "output.py": '''\
from google.colab import _record


def enable_custom_widget_manager():
    _record("output.enable_custom_widget_manager")
''',
    "files.py": '''\
import os

from google.colab import _record


def download(filename):
    if not os.path.isfile(filename):
        raise FileNotFoundError(filename)
    _record("files.download", filename)
''',
}


# ------------------------------------------------------------------------ the Colab-like kernel


def colab_requirements() -> list[str]:
    """The release's requirements with Colab's pins, without what Colab does not have."""
    pinned = {p.split("=")[0] for p in COLAB_PINS}
    out = []
    for line in (KIT_ROOT / "requirements.txt").read_text(encoding="utf-8").splitlines():
        req = line.split("#")[0].strip()
        name = req.split(">")[0].split("=")[0].split("<")[0].split("[")[0].strip().lower()
        if req and name not in pinned and name not in NOT_ON_COLAB:
            out.append(req)
    return out + list(COLAB_PINS)


def colab_python() -> Path:
    """The kernel environment's python, made (once, then cached) when missing or outdated.

    Made under a lock: .ci/run makes it in the background while the suite starts, and this test
    then waits for that instead of making it a second time over the first."""
    import fcntl

    COLAB_VENV.parent.mkdir(parents=True, exist_ok=True)
    with open(COLAB_VENV.with_name(COLAB_VENV.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return _made_colab_venv()


def _made_colab_venv() -> Path:
    py = COLAB_VENV / "bin" / "python"
    stamp = COLAB_VENV / "hw4-colab-requirements.txt"
    wanted = "\n".join(colab_requirements()) + "\n"
    if py.exists() and stamp.exists() and stamp.read_text() == wanted:
        return py
    shutil.rmtree(COLAB_VENV, ignore_errors=True)
    base = "/usr/bin/python3" if Path("/usr/bin/python3").exists() else sys.executable
    subprocess.run([base, "-m", "venv", str(COLAB_VENV)], check=True)
    pip = [str(py), "-m", "pip", "install", "--quiet", "--disable-pip-version-check"]
    subprocess.run(pip + ["--upgrade", "pip"], check=True, capture_output=True)
    done = subprocess.run(pip + colab_requirements(), capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"pip could not make the Colab-like environment:\n{done.stderr[-3000:]}")
    stamp.write_text(wanted)
    return py


@pytest.fixture(scope="module")
def colab(tmp_path_factory):
    """The kernel name, the fake google.colab, and the runtime environment (without per-run folders)."""
    py = colab_python()
    check = subprocess.run([str(py), "-c", "import ipywidgets, importlib.util as u; "
                            "print(ipywidgets.__version__, u.find_spec('anywidget') is None)"],
                           capture_output=True, text=True, check=True)
    assert check.stdout.split()[0].startswith("7.7.") and check.stdout.split()[1] == "True", check.stdout
    root = tmp_path_factory.mktemp("colab-like")
    fake = root / "fake"
    (fake / "google" / "colab").mkdir(parents=True)
    for name, text in FAKE_COLAB.items():
        (fake / "google" / "colab" / name).write_text(text, encoding="utf-8")
    # Colab's kernel has google.colab imported when the first cell runs.
    startup = root / "ipython" / "profile_default" / "startup"
    startup.mkdir(parents=True)
    (startup / "00-colab.py").write_text("import google.colab\n", encoding="utf-8")
    jupyter = root / "jupyter"
    subprocess.run([str(py), "-m", "ipykernel", "install", "--prefix", str(jupyter), "--name", KERNEL,
                    "--display-name", "Colab-like"], check=True, capture_output=True)
    env = {k: v for k, v in os.environ.items()
           if k not in ("VIRTUAL_ENV", "PYTHONPATH", "HW4_DATA", "HW4_NOTEBOOKS", "PYTHONHOME")}
    env.update(PYTHONPATH=str(fake), IPYTHONDIR=str(root / "ipython"),
               PATH=f"{py.parent}{os.pathsep}{os.environ.get('PATH', '/usr/bin:/bin')}",
               HW4_FAKE_COLAB_LOG=str(root / "colab-calls.jsonl"), MPLBACKEND="module://matplotlib_inline.backend_inline")
    return {"root": root, "jupyter": jupyter / "share" / "jupyter", "env": env, "log": root / "colab-calls.jsonl"}


@pytest.fixture(scope="module")
def github(tmp_path_factory):
    """A git repository (file://) holding the student release, and the answer key built for it."""
    root = tmp_path_factory.mktemp("github")
    repo = root / "hw4-release"
    url = repo.as_uri()
    run = dict(cwd=KIT_ROOT, check=True, capture_output=True, text=True)
    subprocess.run([sys.executable, "-m", "kit", "release", "--out", str(repo), "--repo-url", url], **run)
    git = ["git", "-c", "user.name=Course Staff", "-c", "user.email=staff@example.org", "-C", str(repo)]
    subprocess.run(["git", "init", "--quiet", "-b", "main", str(repo)], check=True)
    subprocess.run(git + ["add", "-A"], check=True)
    subprocess.run(git + ["commit", "--quiet", "-m", "release"], check=True)
    built = root / "built"
    subprocess.run([sys.executable, "-m", "kit", "notebooks", "--out", str(built), "--repo-url", url], **run)
    return {"url": url, "repo": repo, "key": built / "notebooks" / "key"}


def calls(colab, since: float) -> list[dict]:
    if not colab["log"].exists():
        return []
    rows = [json.loads(line) for line in colab["log"].read_text().splitlines()]
    return [r for r in rows if r["time"] >= since]


def run_in_fresh_runtime(colab, notebook: Path, drive: Path, monkeypatch, timeout=900) -> nbformat.NotebookNode:
    """Run ``notebook`` (a file in the fake Drive) top to bottom in a new Colab-like session, then
    save it back in place, as Colab does.  A cell that raises fails the test (nbclient)."""
    from nbclient import NotebookClient

    content = colab["root"] / f"content-{time.monotonic_ns()}"
    content.mkdir()
    env = dict(colab["env"], HW4_COLAB_ROOT=str(content), HW4_FAKE_DRIVE=str(drive))
    monkeypatch.setenv("JUPYTER_PATH", str(colab["jupyter"]))
    nb = nbformat.read(notebook, as_version=4)
    client = NotebookClient(nb, timeout=timeout, kernel_name=KERNEL, resources={"metadata": {"path": str(content)}})
    client.execute(env=env, cwd=str(content))
    nbformat.write(nb, notebook)
    return nb


def outputs(nb) -> str:
    parts = []
    for c in nb.cells:
        for o in c.get("outputs", []):
            parts.append(o.get("text", "") if o.get("output_type") == "stream" else
                         json.dumps(o.get("data", {}).get("text/plain", "")))
    return "\n".join(parts)


# ------------------------------------------------------------------------------------ the tests


def test_student_notebooks_run_unfilled_from_fresh_runtimes(colab, github, tmp_path, monkeypatch):
    """Every student notebook, saved in Drive by Colab ("Copy of ..."), runs top to bottom with its
    stubs, each in a new session; the kit is cloned into Drive once and found there afterwards."""
    drive = tmp_path / "drive"
    saved = drive / "MyDrive" / "Colab Notebooks"
    saved.mkdir(parents=True)
    times = {}
    for k, stem in enumerate(NOTEBOOKS):
        copy = saved / f"Copy of {stem}.ipynb"
        shutil.copy(github["repo"] / "notebooks" / f"{stem}.ipynb", copy)
        start = time.time()
        nb = run_in_fresh_runtime(colab, copy, drive, monkeypatch)
        times[stem] = time.time() - start
        text = outputs(nb)
        kit = drive / "MyDrive" / "hw4" / "kit"
        assert f"homework kit: {colab['root']}" in text and str(Path("MyDrive") / "hw4" / "kit") in text, text[:2000]
        assert (kit / "starter" / "__init__.py").is_file()
        if k == 0:
            (kit / ".cloned-once").write_text("the first session cloned the kit")
        else:
            assert (kit / ".cloned-once").exists(), "a later session cloned the kit again"
        made = [c["call"] for c in calls(colab, start)]
        assert "drive.mount" in made and "output.enable_custom_widget_manager" in made, made
    print("seconds per student notebook:", {s: round(t, 1) for s, t in times.items()})


def test_answer_key_copies_load_each_other_from_drive_and_hand_in(colab, github, tmp_path, monkeypatch):
    """The answer key's notebooks, named as Colab names copies and spread over the two Drive
    folders, run in fresh sessions: q3-q5 load the earlier notebooks' functions from Drive (the
    newest copy wins over an older untouched one), then the hand-in notebook writes the PDF and
    the zip into Drive and downloads them; the grader reads the zip's renamed notebooks."""
    from autograder.submission.read import load_submission

    drive = tmp_path / "drive"

    def said(text: str, start: str, path: Path) -> bool:
        """A line ``start`` + ``path`` as the kernel sees it, through /content/drive (the mount)."""
        end = "/drive/" + str(path.relative_to(drive))
        return any(line.startswith(start) and line.endswith(end) for line in text.splitlines())

    course = drive / "MyDrive" / "hw4"
    saved = drive / "MyDrive" / "Colab Notebooks"
    course.mkdir(parents=True)
    saved.mkdir(parents=True)
    # An untouched student notebook left in the course folder, older than the student's work.
    stale = course / "q2_eightpoint.ipynb"
    shutil.copy(github["repo"] / "notebooks" / "q2_eightpoint.ipynb", stale)
    os.utime(stale, (time.time() - 86400, time.time() - 86400))
    places = {stem: (saved if stem in ("q1_proofs", "q2_eightpoint") else course) / f"Copy of {stem}.ipynb"
              for stem in NOTEBOOKS}
    times = {}
    for stem in NOTEBOOKS:
        shutil.copy(github["key"] / f"{stem}.ipynb", places[stem])
        start = time.time()
        nb = run_in_fresh_runtime(colab, places[stem], drive, monkeypatch)
        times[stem] = time.time() - start
        text = outputs(nb)
        assert "not implemented yet" not in text, f"{stem}: {text[:3000]}"
        # Paths as the kernel sees them: through the mount point, /content/drive/MyDrive/...
        if stem == "q3_metric_reconstruction":
            assert said(text, "q2_eightpoint: using ", places["q2_eightpoint"]), text[:3000]
        if stem in ("q4_temple_3d", "q5_bundle_adjustment"):
            assert said(text, "q3_metric_reconstruction: using ", places["q3_metric_reconstruction"]), text[:3000]
    hand_in = saved / "Copy of hand_in.ipynb"
    shutil.copy(github["repo"] / "notebooks" / "hand_in.ipynb", hand_in)
    start = time.time()
    nb = run_in_fresh_runtime(colab, hand_in, drive, monkeypatch)
    times["hand_in"] = time.time() - start
    pdf, code = course / "hw4.pdf", course / "hw4_code.zip"
    assert pdf.stat().st_size > 50_000 and pdf.read_bytes()[:5] == b"%PDF-"
    downloads = [c["args"][0] for c in calls(colab, start) if c["call"] == "files.download"]
    assert sorted(Path(d).name for d in downloads) == ["hw4.pdf", "hw4_code.zip"]
    text = outputs(nb)
    for stem in NOTEBOOKS:
        assert said(text, f"{stem}: ", places[stem]), text[:3000]
    with zipfile.ZipFile(code) as z:
        names = z.namelist()
    assert len([n for n in names if n.endswith(".ipynb")]) == len(NOTEBOOKS), names
    submission = load_submission(code)
    assert sorted(submission.notebooks) == sorted(NOTEBOOKS) and not submission.missing_notebooks
    if shutil.which("pdftotext"):
        cover = subprocess.run(["pdftotext", "-l", "1", str(pdf), "-"], capture_output=True, text=True).stdout
        assert "Answered" in cover
    print("seconds per notebook:", {s: round(t, 1) for s, t in times.items()})


def test_point_picking_widgets_work_with_ipywidgets_7_and_no_anywidget(colab, github, tmp_path, monkeypatch):
    """The interactive epipolar tool (no points given) shows its typed x1/y1 form under Colab's
    ipywidgets 7.7 without anywidget, and its static figure, instead of failing."""
    drive = tmp_path / "drive"
    saved = drive / "MyDrive" / "Colab Notebooks"
    saved.mkdir(parents=True)
    setup = nbformat.read(github["repo"] / "notebooks" / "q2_eightpoint.ipynb", as_version=4)
    first = next(c for c in setup.cells if c.cell_type == "code")
    nb = nbformat.v4.new_notebook(cells=[first, nbformat.v4.new_code_cell(
        "from starter import load_temple\nfrom starter.interactive import displayEpipolarF\n"
        "import numpy as np\nd = load_temple()\nF = np.array([[0, 0, -1e-3], [0, 0, 0.1], [1e-3, -0.1, 0.0]])\n"
        "session = displayEpipolarF(d.im1, d.im2, F)")])
    path = saved / "widgets.ipynb"
    nbformat.write(nb, path)
    out = run_in_fresh_runtime(colab, path, drive, monkeypatch)
    kinds = {k for o in out.cells[-1].outputs for k in o.get("data", {})}
    assert "application/vnd.jupyter.widget-view+json" in kinds and "image/png" in kinds, kinds
