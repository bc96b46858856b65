"""The printable HTML of the notebooks: nbconvert's lab template (extended in ``pdf_assets/hw4pdf``)
and the preprocessors that make every output printable.

- each output keeps one printable representation: a PNG/SVG/JPEG wins over HTML and plotly
  JSON; widget outputs give way to the static image the notebook shows beside them, and an
  interactive output with no static image becomes a short note instead of raw text;
- long text outputs keep their first and last lines; very wide images are scaled down; images a
  markdown cell links from its folder are inlined;
- every question heading and every notebook starts a new page, after the cover, and so does a
  cell the notebook builder tagged ``PAGE_START_TAG`` (a question's output printed after the next
  question's, such as Q3.2's errors);
- the kit's plumbing is not the student's work: the setup cell (and any code cell tagged
  ``PLUMBING_TAG``) prints as one line, the "Open in Colab" note (tagged, or recognised by its
  words in notebooks built before the tag) is left out;
- what the kit's own cells print (the setup cell, the cells the builder tagged ``KIT_CELL_TAG``:
  figures, checks, data) names no folder of the student's machine ("homework kit: found") and
  shows no traceback: an error there prints as one line, its type and message.
"""

from __future__ import annotations

import base64
import copy
import datetime
import html
import io
import re
from pathlib import Path

import nbformat
from nbconvert.exporters import HTMLExporter
from nbconvert.preprocessors import CoalesceStreamsPreprocessor, Preprocessor
from traitlets import Int

from .code_zip import NotebookInfo, inspect_notebook, select_notebooks, student_name
from .cover import NO_NAME, TITLE, cover_html, heading_id, question_status
from .mathjax import ensure_mathjax

__all__ = ["StaticOutputsPreprocessor", "TruncateOutputsPreprocessor", "ScaleImagesPreprocessor",
           "LocalImagesPreprocessor", "SetupCellPreprocessor", "PlumbingNotesPreprocessor", "KitOutputsPreprocessor",
           "PREPROCESSORS", "SETUP_FIRST_LINE", "PAGE_START_TAG", "PLUMBING_TAG", "KIT_CELL_TAG", "notebooks_to_html"]

ASSETS = Path(__file__).resolve().with_name("pdf_assets")
IMAGE_TYPES = ("image/png", "image/svg+xml", "image/jpeg")
# What is kept of an output, best first; anything else (scripts, widget and plotly JSON) is dropped.
PRINTABLE_TYPES = IMAGE_TYPES + ("text/html", "text/markdown", "text/latex", "text/plain")
WIDGET_TYPE = "application/vnd.jupyter.widget-view+json"
PLOTLY_TYPE = "application/vnd.plotly.v1+json"
PLOTLY_NOTE = "(interactive figure: no static image saved)"
WIDGET_NOTE = "(interactive widget: no static image of it was saved in this cell)"


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


# The first line of the homework notebooks' setup cell (kit.notebooks writes it; handin may not
# import kit): a code cell that starts with it is the kit's own code, not the student's work.
SETUP_FIRST_LINE = "# Setup: run this cell first."
# Cell tags the notebook builder (kit.notebooks, which imports them from here) writes: a cell that
# begins a printed page, and a cell of the kit's plumbing (the setup cell, the Colab note).
PAGE_START_TAG = "hw4-page-start"
PLUMBING_TAG = "hw4-kit-plumbing"
# A code cell the kit wrote (a figure, a self-check, data loading): not the student's code.
KIT_CELL_TAG = "hw4-kit-cell"
# How the Colab note of notebooks built before PLUMBING_TAG begins (kit.notebooks.setup writes it).
_COLAB_NOTE_STARTS = ("[Open this notebook in Colab](", "*Colab: this kit comes from ")


def _tags(cell) -> list:
    return list(cell.get("metadata", {}).get("tags", []))


class SetupCellPreprocessor(Preprocessor):
    """Print the setup cell (and any code cell tagged ``PLUMBING_TAG``) as one line: its code is
    the kit's, the same in every notebook.

    Its outputs (where the kit was found) are kept; a student who wrote in the cell (their name,
    say) loses nothing from the PDF that matters, as the cover shows the name.
    """

    def preprocess_cell(self, cell, resources, index):
        if cell.cell_type == "code" and (cell.source.lstrip().startswith(SETUP_FIRST_LINE)
                                         or PLUMBING_TAG in _tags(cell)):
            lines = len(cell.source.splitlines())
            cell.source = f"# Setup cell of the homework kit ({lines} lines, not printed)"
        return cell, resources


class PlumbingNotesPreprocessor(Preprocessor):
    """Leave out the markdown cells of the kit's plumbing: the "Open in Colab" note and its
    how-to (tagged ``PLUMBING_TAG``, or recognised by how it begins).  A page break the cell
    carried moves to the next cell."""

    def preprocess(self, nb, resources):
        kept, carry = [], False
        for cell in nb.cells:
            if cell.cell_type == "markdown" and (PLUMBING_TAG in _tags(cell)
                                                 or cell.source.lstrip().startswith(_COLAB_NOTE_STARTS)):
                carry = carry or PAGE_START_TAG in _tags(cell)
                continue
            if carry and PAGE_START_TAG not in _tags(cell):
                cell.metadata["tags"] = _tags(cell) + [PAGE_START_TAG]
            carry = False
            kept.append(cell)
        nb.cells = kept
        return nb, resources


# A folder of a student's machine (macOS, Linux, Colab, Windows), as a kit's cell may print it.
_MACHINE_PATH = re.compile(r"(?:[A-Za-z]:[\\/]|/)(?:Users|home|content|root|tmp|private|mnt|Volumes|opt|srv|var|"
                           r"Documents and Settings)[\\/][^\s'\"]*")
_KIT_FOUND = re.compile(r"^homework kit: .*$", re.MULTILINE)


def _is_kit_cell(cell) -> bool:
    """A code cell the kit wrote: the setup cell, a tagged cell, or one recognised by its code in
    notebooks built before the tag (a cell run inside ``kit_cell``, a self-check)."""
    if cell.cell_type != "code":
        return False
    source = cell.source.lstrip()
    return (source.startswith((SETUP_FIRST_LINE, "from starter.checks.")) or "with kit_cell(" in source
            or bool({PLUMBING_TAG, KIT_CELL_TAG} & set(_tags(cell))))


def _without_paths(text: str) -> str:
    text = _KIT_FOUND.sub("homework kit: found", text)
    return _MACHINE_PATH.sub("…", text)


class KitOutputsPreprocessor(Preprocessor):
    """The outputs of the kit's own cells hold the student's work only: no folder of their
    machine (replaced by "…"; the setup cell's "homework kit: <folder>" by "homework kit: found")
    and no traceback (an error prints as one line, its type and the first line of its message)."""

    def preprocess_cell(self, cell, resources, index):
        if not _is_kit_cell(cell):
            return cell, resources
        kept = []
        for out in cell.get("outputs", []):
            if out.output_type == "error":
                first = (str(out.get("evalue", "")).strip().splitlines() or [""])[0][:300]
                line = f"this cell of the kit stopped: {out.get('ename', 'Error')}" + (f": {first}" if first else "")
                kept.append(nbformat.v4.new_output("stream", name="stdout", text=_without_paths(line) + "\n"))
                continue
            if out.output_type == "stream":
                out.text = _without_paths("".join(out.text) if isinstance(out.text, list) else out.text)
            elif "text/plain" in out.get("data", {}):
                plain = out.data["text/plain"]
                out.data["text/plain"] = _without_paths("".join(plain) if isinstance(plain, list) else plain)
            kept.append(out)
        cell.outputs = kept
        return cell, resources


# Order matters: streams are merged before they are cut, and the kit's cells cleaned while their
# code is still theirs (before the setup cell's is shortened); a representation is chosen before
# images are scaled (so only the kept image is decoded); links are fixed before rendering.
PREPROCESSORS = (CoalesceStreamsPreprocessor, KitOutputsPreprocessor, StaticOutputsPreprocessor,
                 TruncateOutputsPreprocessor, ScaleImagesPreprocessor, LocalImagesPreprocessor, SetupCellPreprocessor,
                 PlumbingNotesPreprocessor)


# ----------------------------------------------------------------------------- questions, cover


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
            qid = heading_id(cell)
            # A repeated heading ("Q5 (continued)") stays on its page: one start per question.
            if (j == 0 or (qid and qid not in seen)) and PAGE_START_TAG not in _tags(cell):
                cell.metadata["tags"] = _tags(cell) + [PAGE_START_TAG]
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
    cover = cover_html(shown, question_status(infos), [i.path for i in infos],
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
