"""A Gradescope-ready PDF of the student's notebooks, made without TeX and without internet.

The notebooks are joined into one document in manifest order, turned into HTML by nbconvert
(the lab template, extended in ``pdf_assets/hw4pdf``) and printed by a headless Chromium.
What nbconvert's own PDF routes get wrong for this homework is fixed on the way:

- every question heading (``core.manifest.QUESTION_HEADING``) and every notebook starts a new
  page, after a cover page that names the student and lists the questions answered;
- each output keeps one printable representation: a PNG/SVG/JPEG wins over HTML and plotly
  JSON; widget outputs give way to the static image the notebook shows beside them, and an
  interactive output with no static image becomes a short note instead of raw text;
- long code lines and outputs wrap instead of being cut; long text outputs keep their first and
  last lines; very wide images are scaled down;
- math is typeset by a local MathJax 2 (from the ``jupyter-server-mathjax`` wheel or Debian's
  ``libjs-mathjax``), and the browser cannot reach the network at all.

Public API: :func:`build_pdf`, :func:`notebooks_to_html`, :func:`html_to_pdf`,
:func:`find_browser`, :func:`ensure_browser`, :func:`find_mathjax`, :func:`ensure_mathjax`,
:func:`question_status`, :func:`add_cli`.
"""

from __future__ import annotations

import argparse
import base64
import copy
import datetime
import glob
import html
import importlib.util
import io
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import nbformat
from nbconvert.exporters import HTMLExporter
from nbconvert.preprocessors import CoalesceStreamsPreprocessor, Preprocessor
from traitlets import Int

from kit.bundle import NotebookInfo, build_bundle, inspect_notebook, select_notebooks, student_name
from core.manifest import QUESTION_HEADING, QUESTIONS, Question

__all__ = [
    "BrowserNotFoundError",
    "MathJaxNotFoundError",
    "PdfExportError",
    "QuestionStatus",
    "build_pdf",
    "notebooks_to_html",
    "html_to_pdf",
    "find_browser",
    "ensure_browser",
    "ensure_mathjax",
    "find_mathjax",
    "question_status",
    "add_cli",
]

ASSETS = Path(__file__).resolve().with_name("pdf_assets")
TITLE = "Homework 4: 3D Reconstruction"
ANSWER_PLACEHOLDERS = ("YOUR ANSWER HERE",)
NO_NAME = "(name not given)"

IMAGE_TYPES = ("image/png", "image/svg+xml", "image/jpeg")
# What is kept of an output, best first; anything else (scripts, widget and plotly JSON) is dropped.
PRINTABLE_TYPES = IMAGE_TYPES + ("text/html", "text/markdown", "text/latex", "text/plain")
WIDGET_TYPE = "application/vnd.jupyter.widget-view+json"
PLOTLY_TYPE = "application/vnd.plotly.v1+json"
PLOTLY_NOTE = "(interactive figure: no static image saved)"
WIDGET_NOTE = "(interactive widget: no static image of it was saved in this cell)"

BROWSER_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome", "msedge")
MAC_BROWSERS = ("/Applications/Google Chrome.app/Contents/MacOS/Google Chrome",
                "/Applications/Chromium.app/Contents/MacOS/Chromium")
BROWSER_HELP = ("no Chromium-based browser found. Install one:\n"
                "  Debian/Ubuntu:       apt-get install chromium\n"
                "  anywhere, incl. Colab: pip install playwright && python -m playwright install chromium\n"
                "or pass its path with --browser (or set HW4_BROWSER).")
MATHJAX_HELP = ("no local MathJax 2 found to typeset the math offline. Install one:\n"
                "  pip install jupyter-server-mathjax        (any system)\n"
                "  apt-get install libjs-mathjax fonts-mathjax (Debian/Ubuntu)\n"
                "or point HW4_MATHJAX at a folder holding MathJax.js.")
# Flags that keep a headless Chromium quiet, offline and printable as root in a container.
CHROMIUM_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run", "--no-default-browser-check",
    "--disable-extensions", "--disable-default-apps", "--mute-audio", "--hide-scrollbars",
    "--disable-dev-shm-usage", "--allow-file-access-from-files",
    # Nothing may wait on the network: host names fail to resolve at once, and any request (an
    # IP address in a student's HTML output too) goes to a proxy port that refuses connections.
    "--host-resolver-rules=MAP * ~NOTFOUND", "--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>",
    "--disable-domain-reliability", "--disable-client-side-phishing-detection",
)


class BrowserNotFoundError(RuntimeError):
    """No Chromium-based browser could be found; the message says how to install one."""


class MathJaxNotFoundError(RuntimeError):
    """No local MathJax 2 copy could be found; the message says how to install one."""


class PdfExportError(RuntimeError):
    """The browser ran but produced no PDF; the message carries the end of its error output."""


# ----------------------------------------------------------------------------- browser, MathJax

def _in_colab() -> bool:
    try:
        return importlib.util.find_spec("google.colab") is not None
    except (ImportError, ValueError):
        return False


def _playwright_browsers() -> list[str]:
    root = Path(os.environ.get("PLAYWRIGHT_BROWSERS_PATH") or Path.home() / ".cache" / "ms-playwright")
    # The full browser first: the headless shell prints too, but lacks some fonts on minimal systems.
    patterns = ("chromium-*/chrome-linux*/chrome",
                "chromium_headless_shell-*/chrome-linux*/headless_shell",
                "chromium_headless_shell-*/chrome-headless-shell-linux*/chrome-headless-shell",
                "chromium-*/chrome-mac*/Chromium.app/Contents/MacOS/Chromium")
    found = []
    for pattern in patterns:
        found += sorted(glob.glob(str(root / pattern)), reverse=True)  # newest revision first
    return found


def find_browser(browser: str | None = None) -> str:
    """Path of a Chromium-based browser able to print to PDF.

    Parameters
    ----------
    browser : str, optional
        A path or a command name to use instead of searching. Without it, ``$HW4_BROWSER``,
        then chromium / chromium-browser / google-chrome(-stable) on the PATH, then a browser
        installed by Playwright (``~/.cache/ms-playwright``), then the usual macOS locations.

    Raises
    ------
    BrowserNotFoundError
        When nothing is found; the message says how to install a browser.
    """
    if browser:
        path = browser if os.path.isfile(browser) and os.access(browser, os.X_OK) else shutil.which(browser)
        if not path:
            raise BrowserNotFoundError(f"browser: expected an executable path or command, got {browser!r}")
        return path
    env = os.environ.get("HW4_BROWSER")
    if env:
        return find_browser(env)
    for name in BROWSER_NAMES:
        if path := shutil.which(name):
            return path
    for path in _playwright_browsers() + list(MAC_BROWSERS):
        if os.path.isfile(path) and os.access(path, os.X_OK):
            return path
    raise BrowserNotFoundError(BROWSER_HELP)


def ensure_browser(*, install: bool | None = None) -> str:
    """Like :func:`find_browser`, but installs Chromium through Playwright when none is found.

    Parameters
    ----------
    install : bool, optional
        Install when missing. By default only in Google Colab, where students cannot be asked
        to run apt-get; elsewhere a missing browser raises :class:`BrowserNotFoundError`.
    """
    try:
        return find_browser()
    except BrowserNotFoundError:
        if not (_in_colab() if install is None else install):
            raise
    if importlib.util.find_spec("playwright") is None:
        subprocess.run([sys.executable, "-m", "pip", "install", "-q", "playwright"], check=True)
    deps = ["--with-deps"] if _in_colab() else []
    subprocess.run([sys.executable, "-m", "playwright", "install", *deps, "chromium"], check=True)
    return find_browser()


def ensure_mathjax(*, install: bool | None = None) -> Path:
    """Like :func:`find_mathjax`, but pip-installs ``jupyter-server-mathjax`` when none is found
    (by default only in Google Colab)."""
    try:
        return find_mathjax()
    except MathJaxNotFoundError:
        if not (_in_colab() if install is None else install):
            raise
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "jupyter-server-mathjax"], check=True)
    importlib.invalidate_caches()
    return find_mathjax()


def find_mathjax() -> Path:
    """Folder of a local MathJax 2 that has the TeX config and the STIX-Web fonts used here.

    Searched: ``$HW4_MATHJAX``, the ``jupyter_server_mathjax`` package, Debian's
    ``/usr/share/javascript/mathjax``, ``/usr/share/mathjax``.

    Raises
    ------
    MathJaxNotFoundError
        When no usable copy is found; the message says how to install one.
    """
    candidates = []
    if env := os.environ.get("HW4_MATHJAX"):
        candidates.append(Path(env).parent if env.endswith(".js") else Path(env))
    spec = importlib.util.find_spec("jupyter_server_mathjax")
    if spec and spec.origin:
        candidates.append(Path(spec.origin).parent / "static")
    candidates += [Path("/usr/share/javascript/mathjax"), Path("/usr/share/mathjax")]
    for folder in candidates:
        if ((folder / "MathJax.js").is_file()
                and (folder / "config" / "TeX-AMS-MML_HTMLorMML-full.js").is_file()
                and (folder / "fonts" / "HTML-CSS" / "STIX-Web" / "woff").is_dir()):
            return folder
    raise MathJaxNotFoundError(MATHJAX_HELP)


# ----------------------------------------------------------------------------- preprocessors

def _note(text: str) -> nbformat.NotebookNode:
    return nbformat.v4.new_output("display_data", data={
        "text/html": f'<div class="hw4-note">{html.escape(text)}</div>', "text/plain": text})


def _is_plotly_html(data: dict) -> bool:
    page = data.get("text/html", "")
    page = "".join(page) if isinstance(page, list) else page
    return "plotly-graph-div" in page or "Plotly.newPlot" in page


class StaticOutputsPreprocessor(Preprocessor):
    """Keep one printable representation of each rich output (a static image when there is one).

    A widget output is dropped when its cell also shows an image, and replaced by a note
    otherwise; a plotly figure without a saved image becomes a note.
    """

    def preprocess_cell(self, cell, resources, index):
        if cell.cell_type != "code":
            return cell, resources
        has_image = any(m in o.get("data", {}) for o in cell.outputs for m in IMAGE_TYPES)
        kept = []
        for out in cell.outputs:
            if out.output_type not in ("display_data", "execute_result"):
                kept.append(out)
                continue
            data = out.get("data", {})
            chosen = next((m for m in PRINTABLE_TYPES if m in data), None)
            if chosen not in IMAGE_TYPES and WIDGET_TYPE in data:
                if not has_image:
                    kept.append(_note(WIDGET_NOTE))
                continue
            if chosen not in IMAGE_TYPES and (PLOTLY_TYPE in data or _is_plotly_html(data)):
                kept.append(_note(PLOTLY_NOTE))
                continue
            if chosen is None:
                continue  # only scripts or JSON: nothing a printer can show
            out.data = {chosen: data[chosen]}
            out.metadata = {k: v for k, v in out.get("metadata", {}).items() if k == chosen}
            kept.append(out)
        cell.outputs = kept
        return cell, resources


def _shorten(text: str, max_lines: int, head: int, tail: int, max_chars: int) -> str:
    lines = text.splitlines(keepends=True)
    if len(lines) > max_lines:
        omitted = len(lines) - head - tail
        note = f"[... {omitted:,} lines omitted from the PDF; the notebook holds the full output ...]\n"
        text = "".join(lines[:head]) + note + "".join(lines[-tail:])
    if len(text) > max_chars:
        keep_head, keep_tail = max_chars * 3 // 4, max_chars // 4
        omitted = len(text) - keep_head - keep_tail
        text = (text[:keep_head] + f"\n[... {omitted:,} characters omitted from the PDF ...]\n"
                + text[-keep_tail:])
    return text


class TruncateOutputsPreprocessor(Preprocessor):
    """Bound text outputs: keep the first ``head`` and last ``tail`` lines and say what was cut.

    Applies to streams, plain-text results and tracebacks. Runs after streams are coalesced, so a
    loop printing one line per ``print`` call counts as one long output.
    """

    max_lines = Int(80, help="outputs with more lines are shortened").tag(config=True)
    head = Int(40, help="first lines kept").tag(config=True)
    tail = Int(20, help="last lines kept").tag(config=True)
    max_chars = Int(12_000, help="longest text kept, for outputs with few but huge lines").tag(config=True)

    def _cut(self, text):
        text = "".join(text) if isinstance(text, list) else text
        return _shorten(text, self.max_lines, self.head, self.tail, self.max_chars)

    def preprocess_cell(self, cell, resources, index):
        for out in cell.get("outputs", []):
            if out.output_type == "stream":
                out.text = self._cut(out.text)
            elif out.output_type == "error":
                lines = self._cut("\n".join(out.traceback)).split("\n")
                out.traceback = lines
            elif "text/plain" in out.get("data", {}):
                out.data["text/plain"] = self._cut(out.data["text/plain"])
        return cell, resources


class ScaleImagesPreprocessor(Preprocessor):
    """Downscale raster outputs wider than ``max_px``: CSS fits them to the page anyway, this
    only keeps a 4000-pixel figure from making a 40 MB PDF."""

    max_px = Int(1800, help="widest raster image kept, in pixels").tag(config=True)

    def preprocess_cell(self, cell, resources, index):
        for out in cell.get("outputs", []):
            for mime, fmt in (("image/png", "PNG"), ("image/jpeg", "JPEG")):
                if mime in out.get("data", {}):
                    out.data[mime] = self._scaled(out.data[mime], fmt)
        return cell, resources

    def _scaled(self, b64, fmt):
        from PIL import Image

        raw = base64.b64decode("".join(b64) if isinstance(b64, list) else b64)
        try:
            img = Image.open(io.BytesIO(raw))
            if img.width <= self.max_px:
                return b64
            img = img.resize((self.max_px, max(1, round(img.height * self.max_px / img.width))),
                             Image.Resampling.LANCZOS)
            buf = io.BytesIO()
            img.save(buf, format=fmt)
        except Exception:  # an image Pillow cannot read is printed as it is
            return b64
        return base64.b64encode(buf.getvalue()).decode("ascii")


_MD_IMAGE = re.compile(r"(!\[[^\]]*\]\()(<[^>]+>|[^)\s]+)")
_HTML_IMAGE = re.compile(r"""(<img\b[^>]*?\bsrc=)(["'])(.*?)\2""", re.IGNORECASE)


class LocalImagesPreprocessor(Preprocessor):
    """Point relative image links of markdown cells at absolute files.

    Cells from notebooks in different folders end up in one HTML file elsewhere, so a relative
    ``![](sketch.jpg)`` would no longer resolve; each cell carries its notebook's folder in
    ``metadata.hw4_dir``.
    """

    def preprocess_cell(self, cell, resources, index):
        folder = cell.metadata.pop("hw4_dir", None)
        if cell.cell_type != "markdown" or not folder:
            return cell, resources

        def absolute(target: str) -> str:
            bare = target.strip("<>")
            if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:|^[/#]", bare):
                return target  # a URL, an attachment, an absolute path or an anchor
            path = (Path(folder) / bare).resolve()
            return Path(path).as_uri() if path.is_file() else target

        source = _MD_IMAGE.sub(lambda m: m.group(1) + absolute(m.group(2)), cell.source)
        cell.source = _HTML_IMAGE.sub(lambda m: f"{m.group(1)}{m.group(2)}{absolute(m.group(3))}{m.group(2)}",
                                      source)
        return cell, resources


# Order matters: streams are merged before they are cut; a representation is chosen before
# images are scaled (so only the kept image is decoded); links are fixed before rendering.
PREPROCESSORS = (CoalesceStreamsPreprocessor, StaticOutputsPreprocessor, TruncateOutputsPreprocessor,
                 ScaleImagesPreprocessor, LocalImagesPreprocessor)


# ----------------------------------------------------------------------------- questions, cover

def _heading_id(cell) -> str | None:
    """The question id when the cell's first non-blank line is a question heading."""
    if cell.cell_type != "markdown":
        return None
    first = next((line for line in cell.source.splitlines() if line.strip()), "")
    m = re.match(QUESTION_HEADING, first.strip())
    return m.group(1) if m else None


def _sections(nb) -> dict[str, list]:
    """Cells of each question: from its heading to the next question heading."""
    out: dict[str, list] = {}
    current = None
    for cell in nb.cells:
        qid = _heading_id(cell)
        if qid:
            current = out.setdefault(qid, [])
        if current is not None:
            current.append(cell)
    return out


def _written_answer_given(cells) -> bool:
    """False when the section's answer cells still hold only the placeholder."""
    def is_answer_cell(c):
        meta = c.metadata.get("nbgrader", {})
        return c.cell_type == "markdown" and (meta.get("solution") or any(
            p.lower() in c.source.lower() for p in ANSWER_PLACEHOLDERS))

    answers = [c for c in cells if is_answer_cell(c)]
    if not answers:
        return True  # no answer cell to check: the student wrote straight under the heading
    for c in answers:
        text = c.source
        for p in ANSWER_PLACEHOLDERS:
            text = re.sub(re.escape(p), "", text, flags=re.IGNORECASE)
        if re.sub(r"[\s*_#>-]", "", text) or c.get("attachments"):
            return True
    return False


STATE_CLASS = {"answered": "answered", "partial": "partial", "not answered": "missing",
               "notebook missing": "missing"}


@dataclass(frozen=True)
class QuestionStatus:
    """question: the manifest entry; state: "answered", "partial", "not answered" or
    "notebook missing"; detail: what is missing, for the cover."""

    question: Question
    state: str
    detail: str = ""


def question_status(infos: list[NotebookInfo]) -> list[QuestionStatus]:
    """Status of every manifest question, from what the notebooks define (never run).

    A coding question is answered when all its functions are defined and none is a stub; a
    written question when its answer cell is no longer the untouched placeholder.
    """
    by_stem = {i.stem: i for i in infos if i.stem and i.nb is not None}
    out = []
    for q in QUESTIONS:
        info = by_stem.get(q.notebook)
        if info is None:
            out.append(QuestionStatus(q, "notebook missing", f"{q.notebook}.ipynb not included"))
        elif q.functions:
            missing = [f for f in q.functions if f not in info.implemented]
            state = ("answered" if not missing else
                     "partial" if len(missing) < len(q.functions) else "not answered")
            stubs = [f for f in missing if f in info.stubs]
            absent = [f for f in missing if f not in info.stubs]
            detail = "; ".join(([f"not defined: {', '.join(absent)}"] if absent else [])
                               + ([f"still a stub: {', '.join(stubs)}"] if stubs else []))
            out.append(QuestionStatus(q, state, detail))
        else:
            cells = _sections(info.nb).get(q.id)
            if cells is None:
                out.append(QuestionStatus(q, "not answered", f"no '{q.id}' heading in {q.notebook}.ipynb"))
            else:
                given = _written_answer_given(cells)
                out.append(QuestionStatus(q, "answered" if given else "not answered",
                                          "" if given else "answer cell still holds the placeholder"))
    return out


def _cover_html(name: str, statuses: list[QuestionStatus], notebooks: list[Path], today: str) -> str:
    answered = [s.question.id for s in statuses if s.state == "answered"]
    rows = "\n".join(
        f'<tr><td>{html.escape(s.question.id)}</td><td>{html.escape(s.question.title)}</td>'
        f'<td>{s.question.points}{" (extra)" if s.question.extra_credit else ""}</td>'
        f'<td class="hw4-status-{STATE_CLASS[s.state]}">{html.escape(s.state)}'
        f'{"<br><small>" + html.escape(s.detail) + "</small>" if s.detail else ""}</td></tr>'
        for s in statuses)
    listed = ", ".join(html.escape(p.name) for p in notebooks)
    return f"""
<section class="hw4-cover">
<h1>{html.escape(TITLE)}</h1>
<div class="hw4-subtitle">Written answers and code, for Gradescope</div>
<p class="hw4-name">Name: {html.escape(name)}</p>
<div class="hw4-date">Exported {html.escape(today)}</div>
<p class="hw4-answered">Answered: {html.escape(", ".join(answered) or "none")}
({len(answered)} of {len(statuses)})</p>
<table>
<thead><tr><th>Question</th><th>Title</th><th>Points</th><th>Status</th></tr></thead>
<tbody>
{rows}
</tbody>
</table>
<p class="hw4-help">Every question starts on a new page under its heading: in Gradescope, give each
question the pages from its heading to the next one. Notebooks: {listed}.</p>
</section>
"""


# ----------------------------------------------------------------------------- HTML

def _combined(infos: list[NotebookInfo]) -> nbformat.NotebookNode:
    """One notebook holding all cells, tagged where a printed page must start."""
    nb = nbformat.v4.new_notebook()
    nb.metadata = copy.deepcopy(infos[0].nb.metadata)
    seen: set[str] = set()
    for k, info in enumerate(infos):
        for j, cell in enumerate(info.nb.cells):
            cell = copy.deepcopy(cell)
            cell["id"] = f"hw4-{k}-{j}"  # ids must stay unique across notebooks
            cell.metadata["hw4_dir"] = str(info.path.parent.resolve())
            qid = _heading_id(cell)
            # A repeated heading ("Q5 (continued)") stays on its page: one start per question.
            if j == 0 or (qid and qid not in seen):
                cell.metadata["tags"] = list(cell.metadata.get("tags", [])) + ["hw4-page-start"]
            if qid:
                seen.add(qid)
            nb.cells.append(cell)
    return nb


def _inspect_all(notebooks) -> tuple[list[NotebookInfo], list[str]]:
    sel = select_notebooks(notebooks, argname="notebooks")
    infos = [inspect_notebook(p) for p in sel.notebooks]
    warnings = [f"left out {p.name}: {why}" for p, why in sel.skipped]
    warnings += [msg for i in infos if i.nb is None for msg in i.problems]
    readable = [i for i in infos if i.nb is not None]
    if not readable:
        raise ValueError(f"notebooks: expected at least one readable notebook, got none ({'; '.join(warnings)})")
    return readable, warnings


def notebooks_to_html(notebooks, *, name: str | None = None, mathjax: Path | None = None,
                      today: datetime.date | None = None) -> tuple[str, list[str]]:
    """The printable HTML of the student's notebooks, and warnings about files left out.

    Parameters
    ----------
    notebooks : str or Path or list of str/Path
        A folder (its homework notebooks are taken) or notebook files.
    name : str, optional
        The student's name for the cover; defaults to a ``STUDENT_NAME = "..."`` assignment
        found in the notebooks' code, else "(name not given)".
    mathjax : Path, optional
        Folder of a local MathJax 2 (default :func:`ensure_mathjax`).
    today : datetime.date, optional
        The cover's date (default today).

    Returns
    -------
    (html, warnings) : tuple of str and list of str
        A self-contained page (images inlined) that loads nothing but the local MathJax.
    """
    infos, warnings = _inspect_all(notebooks)
    mathjax = mathjax or ensure_mathjax()
    shown = (name or "").strip() or student_name(infos) or NO_NAME
    cover = _cover_html(shown, question_status(infos), [i.path for i in infos],
                        (today or datetime.date.today()).strftime("%d %B %Y"))
    exporter = HTMLExporter(template_name="hw4pdf", extra_template_basedirs=[str(ASSETS)],
                            exclude_input_prompt=True, exclude_output_prompt=True,
                            exclude_anchor_links=True)
    for pre in PREPROCESSORS:
        exporter.register_preprocessor(pre(), enabled=True)
    resources = {"hw4": {
        "css": (ASSETS / "hw4.css").read_text(encoding="utf-8"),
        "mathjax_config": (ASSETS / "mathjax-config.js").read_text(encoding="utf-8"),
        "mathjax_url": (Path(mathjax) / "MathJax.js").resolve().as_uri()
                       + "?config=TeX-AMS-MML_HTMLorMML-full,Safe",
        "cover": cover,
    }, "metadata": {"name": f"{TITLE}: {shown}"}}
    body, _ = exporter.from_notebook_node(_combined(infos), resources=resources)
    return body, warnings


# ----------------------------------------------------------------------------- printing

def _run_chromium(browser: str, url: str, out: Path, profile: str, timeout: float) -> subprocess.CompletedProcess:
    cmd = [browser, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--no-pdf-header-footer",
           "--print-to-pdf-no-header", f"--print-to-pdf={out}", "--run-all-compositor-stages-before-draw",
           # Virtual time runs MathJax's timers to completion before printing, without real waiting.
           "--virtual-time-budget=60000", url]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        # Chromium leaves helper processes behind; they share the session we started.
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise PdfExportError(f"the browser did not finish printing within {timeout:g} s "
                             f"(raise --timeout, or check {browser} runs headless)") from None
    return subprocess.CompletedProcess(cmd, proc.returncode, stdout, stderr)


def _print_playwright(browser: str, url: str, out: Path, timeout: float) -> None:
    from playwright.sync_api import sync_playwright

    args = [f for f in CHROMIUM_FLAGS if f != "--headless"]
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=browser, headless=True, args=args, timeout=timeout * 1000)
        try:
            page = b.new_page()
            page.goto(url, wait_until="load", timeout=timeout * 1000)
            page.wait_for_function("document.documentElement.getAttribute('data-hw4-math') === 'done'",
                                   timeout=timeout * 1000)
            page.pdf(path=str(out), prefer_css_page_size=True, print_background=True)
        finally:
            b.close()


def html_to_pdf(html_path, out, *, browser: str | None = None, timeout: float = 180.0,
                engine: str = "cli") -> Path:
    """Print an HTML file to PDF with a headless Chromium, offline.

    Parameters
    ----------
    html_path : str or Path
        The page to print (local images and scripts only: no host name resolves).
    out : str or Path
        The PDF to write.
    browser : str, optional
        Browser path or command (default :func:`find_browser`).
    timeout : float
        Seconds before the browser is stopped.
    engine : {"cli", "playwright"}
        "cli" runs ``chromium --print-to-pdf`` with a virtual-time budget: MathJax's timers run
        to completion before printing without real waiting (measured: a budget of 10 ms prints
        blank math, 500 ms is enough for 300 formulas; 60 s is used). "playwright" drives the same
        browser through Playwright and waits for MathJax's own end signal; it needs
        ``pip install playwright`` and is slower, since MathJax's pauses then take real time.

    Raises
    ------
    BrowserNotFoundError, PdfExportError
    """
    if engine not in ("cli", "playwright"):
        raise ValueError(f"engine: expected 'cli' or 'playwright', got {engine!r}")
    timeout = float(timeout)
    if not timeout > 0:
        raise ValueError(f"timeout: expected a positive number of seconds, got {timeout!r}")
    browser = find_browser(browser)
    out = Path(out).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    url = Path(html_path).resolve().as_uri()
    tmp_out = out.with_name(out.name + ".part")
    tmp_out.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="hw4-chromium-") as profile:
        if engine == "playwright":
            try:
                _print_playwright(browser, url, tmp_out, timeout)
            except Exception as exc:
                raise PdfExportError(f"printing with Playwright and {browser} failed: {exc}") from exc
            detail = ""
        else:
            proc = _run_chromium(browser, url, tmp_out, profile, timeout)
            detail = "\n".join(proc.stderr.strip().splitlines()[-15:])
    if not tmp_out.is_file() or tmp_out.read_bytes()[:5] != b"%PDF-":
        tmp_out.unlink(missing_ok=True)
        raise PdfExportError(f"{browser} wrote no PDF. Its last messages:\n{detail}")
    tmp_out.replace(out)
    return out


def build_pdf(notebooks, out, *, name: str | None = None, browser: str | None = None,
              timeout: float = 180.0, engine: str = "cli", keep_html: bool = False) -> Path:
    """Export the student's notebooks to one Gradescope-ready PDF.

    Parameters
    ----------
    notebooks : str or Path or list of str/Path
        A folder holding the homework notebooks (``q2_eightpoint.ipynb`` ...; other notebooks
        there are left out with a warning) or a list of notebook files (all are included, the
        homework ones first in manifest order).
    out : str or Path
        The PDF to write; its folder is created.
    name : str, optional
        The student's name for the cover (default: ``STUDENT_NAME`` from the notebooks).
    browser : str, optional
        Chromium path or command (default :func:`find_browser`).
    timeout : float
        Seconds allowed to the browser.
    engine : {"cli", "playwright"}
        How the browser is driven, see :func:`html_to_pdf`.
    keep_html : bool
        Also keep the printed HTML beside the PDF (``out`` with suffix ``.html``), for debugging.

    Returns
    -------
    Path
        The PDF written. Files left out are reported on stderr.

    Raises
    ------
    ValueError
        When ``notebooks`` holds no readable notebook or names a missing file.
    BrowserNotFoundError, MathJaxNotFoundError, PdfExportError
        With a message saying how to fix it.
    """
    out = Path(out)
    if out.suffix.lower() != ".pdf":
        raise ValueError(f"out: expected a path ending in .pdf, got {str(out)!r}")
    browser = find_browser(browser) if browser else ensure_browser()  # fail before the slower HTML step
    page, warnings = notebooks_to_html(notebooks, name=name)
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="hw4-pdf-") as tmp:
        html_path = Path(tmp) / "hw4.html"
        html_path.write_text(page, encoding="utf-8")
        if keep_html:
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(html_path, out.with_suffix(".html"))
        return html_to_pdf(html_path, out, browser=browser, timeout=timeout, engine=engine)


# ----------------------------------------------------------------------------- CLI

def _default_source() -> Path:
    local = Path("notebooks")
    return local if local.is_dir() and any(local.glob("q*.ipynb")) else Path(".")


def _cli(args: argparse.Namespace) -> int:
    source = args.notebooks or _default_source()
    if isinstance(source, list) and len(source) == 1:
        source = source[0]
    try:
        if args.bundle:
            report = build_bundle(source, args.bundle, max_mb=args.max_mb)
            print(report)
        pdf = build_pdf(source, args.out, name=args.name, browser=args.browser, timeout=args.timeout,
                        engine=args.engine, keep_html=args.keep_html)
    except (ValueError, BrowserNotFoundError, MathJaxNotFoundError, PdfExportError,
            subprocess.CalledProcessError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {pdf}")
    return 1 if args.bundle and report.too_large else 0


def add_cli(subparsers) -> argparse.ArgumentParser:
    """Register the ``pdf`` subcommand on an argparse subparsers object.

    ``python -m kit pdf [NOTEBOOK_DIR or files...] --out hw4.pdf [--name NAME] [--bundle hw4_code.zip]``.
    The parser's ``func`` default takes the parsed namespace and returns the exit code
    (0 done, 1 bundle over its size cap, 2 nothing written).
    """
    p = subparsers.add_parser(
        "pdf", help="export the notebooks to a Gradescope-ready PDF (and the code zip)",
        description="Export the homework notebooks to one PDF for Gradescope: a cover page, every "
                    "question on a new page, figures, wrapped code and typeset math, offline.")
    p.add_argument("notebooks", nargs="*", type=Path,
                   help="a folder of notebooks or notebook files (default: ./notebooks if present, else .)")
    p.add_argument("--out", type=Path, default=Path("hw4.pdf"), help="PDF to write (default hw4.pdf)")
    p.add_argument("--name", help="your name for the cover (default: STUDENT_NAME in the notebooks)")
    p.add_argument("--bundle", type=Path, metavar="ZIP", help="also write the code zip for the autograder")
    p.add_argument("--max-mb", type=float, default=50.0, help="size cap of the code zip in MB (default 50)")
    p.add_argument("--browser", help="Chromium/Chrome executable (default: searched)")
    p.add_argument("--timeout", type=float, default=180.0, help="seconds allowed to the browser (default 180)")
    p.add_argument("--engine", choices=("cli", "playwright"), default="cli",
                   help="drive the browser from its command line (default) or through Playwright")
    p.add_argument("--keep-html", action="store_true", help="keep the printed HTML beside the PDF")
    p.set_defaults(func=_cli)
    return p
