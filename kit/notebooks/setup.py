"""The settings of a build (the course repository the notebooks point to), the setup cell every
notebook opens with, and the "Open in Colab" link."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import nbformat

from core.notebook import METADATA_KEY

from .source import SRC_DIR

PLACEHOLDER_REPO = "https://github.com/YOUR-ORG/YOUR-HW4-RELEASE"
_GITHUB = re.compile(r"^https://github\.com/([A-Za-z0-9_.-]+)/([A-Za-z0-9_.-]+?)(?:\.git)?/?$")
_LOCAL_GIT = re.compile(r"^file:///[^\s\"'\\]+$")


# --------------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class Settings:
    """Where the published student kit lives.

    repo_url: the GitHub repository of the student release (``python -m kit release``), e.g.
    ``https://github.com/cmu-16720/hw4``, or a local git repository ``file:///path`` (tests, a
    course server): the setup cell clones it, but Colab cannot open notebooks from it, so the
    notebooks then carry no "Open in Colab" link.  ref: the branch or tag to open and to clone.
    The placeholder (:data:`PLACEHOLDER_REPO`) is accepted only for the kit's own committed build;
    anything given to students refuses it (:meth:`require_repository`).
    """

    repo_url: str = PLACEHOLDER_REPO
    ref: str = "main"

    def __post_init__(self):
        if not (_GITHUB.match(self.repo_url) or _LOCAL_GIT.match(self.repo_url)):
            raise ValueError(f"repo_url: expected a GitHub repository URL like https://github.com/ORG/REPO "
                             f"(Colab opens notebooks from GitHub) or a local git repository file:///PATH, "
                             f"got {self.repo_url!r}")
        if not re.fullmatch(r"[A-Za-z0-9_./-]+", self.ref) or self.ref.startswith("-"):
            raise ValueError(f"ref: expected a branch or tag name, got {self.ref!r}")

    @property
    def is_placeholder(self) -> bool:
        return self.repo_url == PLACEHOLDER_REPO

    def require_repository(self, what: str) -> "Settings":
        """These settings, or a ValueError saying how to name the repository when they hold the placeholder."""
        if self.is_placeholder:
            raise ValueError(
                f"repo_url: {what} needs the repository students get the kit from, got the placeholder "
                f"{PLACEHOLDER_REPO}. Pass --repo-url https://github.com/ORG/REPO (the public GitHub "
                f"repository you push the release to; --ref BRANCH if not main), or set repo_url in "
                f"notebooks/src/settings.json. The notebooks' Colab links and setup cells point there.")
        return self

    def colab_url(self, stem: str) -> str | None:
        """The "Open in Colab" address of a student notebook; None for a repository Colab cannot open."""
        m = _GITHUB.match(self.repo_url)
        if m is None:
            return None
        owner, repo = m.groups()
        return f"https://colab.research.google.com/github/{owner}/{repo}/blob/{self.ref}/notebooks/{stem}.ipynb"


def load_settings(path: Path | None = None) -> Settings:
    """The settings in ``notebooks/src/settings.json`` (defaults when the file is absent)."""
    path = Path(path) if path is not None else SRC_DIR / "settings.json"
    if not path.exists():
        return Settings()
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise ValueError(f"{path}: expected JSON with repo_url and ref ({exc})") from None
    unknown = set(data) - {"repo_url", "ref", "comment"}
    if unknown:
        raise ValueError(f"{path}: expected the keys repo_url, ref (and comment), got also {sorted(unknown)}")
    return Settings(data.get("repo_url", PLACEHOLDER_REPO), data.get("ref", "main"))


def settings_of(nb: nbformat.NotebookNode) -> Settings:
    """The settings a built notebook was made with (from its metadata)."""
    meta = nb.metadata.get(METADATA_KEY, {})
    return Settings(meta.get("repo_url", PLACEHOLDER_REPO), meta.get("ref", "main"))


# ---------------------------------------------------------------------- the setup cell


def setup_text(settings: Settings) -> str:
    return f"""\
# Setup: run this cell first.  It makes the homework kit (starter/, scenes/, data/) importable.
# On your own machine it finds the kit around this notebook.  On Colab it mounts your Google Drive,
# downloads the kit once into your course folder there (MyDrive/hw4/kit) and installs what Colab
# lacks; your notebooks are looked for in MyDrive/hw4 and MyDrive/Colab Notebooks, whatever Colab
# named them ("Copy of ..."), so later notebooks find your earlier functions in any new session.
import importlib.metadata
import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

STUDENT_NAME = "your name"  # <- your name, printed on the cover of your PDF
KIT_REPO = "{settings.repo_url}"
KIT_REF = "{settings.ref}"
COURSE_FOLDER = "hw4"  # Colab: your course folder in Google Drive (MyDrive/hw4)
USE_DRIVE = True  # Colab without Google Drive: False (then nothing is kept when the session ends)

kit_dir = next((p for p in [Path.cwd(), *Path.cwd().parents] if (p / "starter" / "__init__.py").is_file()), None)
if kit_dir is None and "google.colab" in sys.modules:
    from google.colab import output
    content = Path(os.environ.get("HW4_COLAB_ROOT", "/content"))  # Colab's working folder
    if USE_DRIVE:
        from google.colab import drive
        drive.mount(str(content / "drive"))
        course = content / "drive" / "MyDrive" / COURSE_FOLDER
        folders = [course, course.parent / "Colab Notebooks"]
    else:
        course = content / COURSE_FOLDER
        folders = [content, course]
    os.environ["HW4_NOTEBOOKS"] = os.pathsep.join(map(str, folders))  # read by from_notebook and the hand-in
    kit_dir = course / "kit"
    if not (kit_dir / "starter" / "__init__.py").is_file():
        download = course / "kit-download"
        shutil.rmtree(download, ignore_errors=True)
        course.mkdir(parents=True, exist_ok=True)
        subprocess.run(["git", "clone", "--quiet", "--depth", "1", "--branch", KIT_REF, KIT_REPO, str(download)],
                       check=True)
        download.rename(kit_dir)
    missing = []
    for line in (kit_dir / "requirements.txt").read_text().splitlines():
        requirement = line.split("#")[0].strip()
        name = re.split(r"[<>=!~\\[; ]", requirement)[0]
        if name and not requirement.startswith("-") and name != "anywidget":  # anywidget: optional (clicks)
            try:
                importlib.metadata.version(name)
            except importlib.metadata.PackageNotFoundError:
                missing.append(requirement)
    if missing:
        subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", *missing], check=True)
    output.enable_custom_widget_manager()  # the point-picking widgets
    print("your notebooks are read from:", ", ".join(map(str, folders)))
if kit_dir is None and importlib.util.find_spec("starter") is not None:
    kit_dir = Path(importlib.util.find_spec("starter").origin).parents[1]  # an installed kit
if kit_dir is None:
    raise RuntimeError("The homework kit was not found: open this notebook from the kit's notebooks/ folder, "
                       "install the kit (pip install -e .), or run it on Colab.")
if str(kit_dir) not in sys.path:
    sys.path.insert(0, str(kit_dir))
print("homework kit:", kit_dir)


# The kit's own cells run inside `with kit_cell("Q6"):` so that, whatever your functions return, a
# failure there prints one line and the cells below still run.
class kit_cell:
    def __init__(self, question):
        self.question = question

    def __enter__(self):
        pyplot = sys.modules.get("matplotlib.pyplot")
        self.figures = set(pyplot.get_fignums()) if pyplot is not None else set()

    def __exit__(self, kind, error, traceback):
        if kind is None or not issubclass(kind, Exception):
            return False
        pyplot = sys.modules.get("matplotlib.pyplot")
        for number in set(pyplot.get_fignums()) - self.figures if pyplot is not None else ():
            pyplot.close(number)  # a figure half drawn is not shown
        first = (str(error).strip().splitlines() or [""])[0][:200]
        print(f"{{self.question}}: this cell of the kit stopped ({{kind.__name__}}{{': ' + first if first else ''}}); "
              "the cells below still run.")
        return True"""


def colab_text(stem: str, settings: Settings) -> str:
    url = settings.colab_url(stem)
    if url is None:
        return (f"*Colab: this kit comes from {settings.repo_url}, which Colab cannot open; upload the "
                "notebook (File > Upload notebook) or run it in Jupyter.*")
    text = (f"[Open this notebook in Colab]({url}), then *File > Save a copy in Drive*: the setup cell "
            "mounts your Google Drive, where later notebooks and the hand-in find this one.")
    if settings.is_placeholder:
        text += ("  \n*(Placeholder link: the instructor sets the course repository with "
                 "`python -m kit release --repo-url https://github.com/ORG/REPO`.)*")
    return text
