"""What a student writes never reaches a TA as code, and one bad submission never stops a class.

A class of ten, each the answer key plus one change, is graded with the CLI (``python -m autograder
grade``), then ``report`` and ``similar`` run on it.  The changes carry the hostile texts of
tests/support/corpus/hostile.py where a student controls text: an exception's message, the messages of
failed imports while loading, file names, folder names (formulas, escapes), a symbolic link in a
zip, and a file name that is not UTF-8.  Every file written is then read as its reader would:

- no file holds an escape, control or bidi character (JSON files: none in any string either);
- feedback.md, summary.md and results.json's outputs, rendered by a Markdown renderer that passes
  raw HTML, give only the kit's own elements, and the hostile text shows as text;
- the HTML pages hold no tag of the student's (no script, svg, a stray img or link);
- no CSV cell starts a formula, and the mistakes named are the catalogue's;
- what the commands print holds no escape either;
- the report and look-alike folders are the staff's alone (0700, files 0600);
- the file name that is not UTF-8 stops nothing: the ten are graded and in grades.csv.

It imports nothing of core.untrusted, so it runs (and fails) on a kit without it.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import stat
import subprocess
import sys
import unicodedata
import zipfile
from html.parser import HTMLParser
from pathlib import Path

import corpus
import mistune
import nbformat
import pytest
from corpus.hostile import HOSTILE_TEXTS, UNDECODABLE_NAME

from autograder.inputs.config import quick_config
from core.manifest import NOTEBOOKS
from core.paths import KIT_ROOT
from judging.mistakes import KNOWN_MISTAKES

FULL = 90.0
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
# The kit's own elements in its Markdown (headings, the summary's bold, notes and checks as lists,
# the checks' table, the staff line's rule) and in its HTML pages.
# "code": the kit's code spans around a library call's name and line in summary.md.
MARKDOWN_ELEMENTS = {"h1", "h2", "p", "strong", "ul", "li", "table", "thead", "tbody", "tr", "th", "td", "hr", "code"}
HTML_ELEMENTS = {"html", "head", "meta", "title", "style", "body", "h1", "h2", "p", "table", "tr", "th", "td", "div",
                 "img", "span", "a", "details", "summary", "b", "small", "pre", "ul", "li", "br"}
render_markdown = mistune.create_markdown(escape=False, plugins=["strikethrough", "footnotes", "table", "url",
                                                                 "math"])

pytestmark = pytest.mark.slow

# What three functions raise (a student's message is cut to its first 80 characters).
EXCEPTIONS = {
    "eightpoint": "Likely mistake: =1+1+cmd|' /C calc'!A0. <img src=x onerror=alert(1)>",
    "essentialMatrix": "<script>alert(1)</script> ![](http://e.example/t.png) [x](javascript:alert(1))",
    "triangulate": "\x1b]8;;http://e.example\x1b\\click\x1b]8;;\x1b\\ \x1b[2J\x1b]0;pwned\x07 nul\x00 \u202eabc",
}
ANSI_FOLDER = "\x1b]0;pwned\x07<b>bold"
FOLDERS = ["+1+1", "-1+1", "@SUM(1+1)", ANSI_FOLDER]


class Elements(HTMLParser):
    def __init__(self, text: str):
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict]] = []
        self.text: list[str] = []
        self.feed(text)
        self.close()

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))

    handle_startendtag = handle_starttag

    def handle_data(self, data):
        self.text.append(data)

    def handle_comment(self, data):
        self.tags.append(("<!--", {}))


def acting(text: str, allowed: str = "\n\t") -> list[str]:
    return [c for c in text if c not in allowed and unicodedata.category(c) in ("Cc", "Cf", "Cs", "Zl", "Zp")]


def strings(value):
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from strings(k)
            yield from strings(v)
    elif isinstance(value, list):
        for v in value:
            yield from strings(v)


def _class(root: Path) -> list[Path]:
    """The ten submissions, each the answer key plus one change."""
    key = corpus.build("key_full_marks", root / "built", out=root / "out")
    subs = root / "subs"
    subs.mkdir()

    def copy(name: str) -> Path:
        return Path(shutil.copytree(key, subs / name))

    paths = []
    for function, message in EXCEPTIONS.items():
        p = copy(f"raises_in_{function}")
        nbs = {stem: nbformat.read(p / f"{stem}.ipynb", as_version=4) for stem in NOTEBOOKS}
        corpus.replace_function(nbs, function, f"def {function}(*args):\n    raise ValueError({message!r})\n")
        for stem, nb in nbs.items():
            nbformat.write(nb, p / f"{stem}.ipynb")
        paths.append(p)
    p = copy("file_names")
    for text in HOSTILE_TEXTS.values():
        if "/" not in text and "\x00" not in text and len(text.encode()) < 200:
            (p / f"{text}.py").write_text("x = (\n")
    paths.append(p)
    p = copy("undecodable")
    with open(os.path.join(os.fsencode(p), UNDECODABLE_NAME), "wb") as fh:
        fh.write(b"x = (\n")
    paths.append(p)
    zpath = subs / "zip_link.zip"
    with zipfile.ZipFile(zpath, "w") as zf:
        for f in sorted(key.iterdir()):
            zf.write(f, f.name)
        link = zipfile.ZipInfo(f"{HOSTILE_TEXTS['svg']}.py")
        link.external_attr = (stat.S_IFLNK | 0o777) << 16
        zf.writestr(link, "/etc/passwd")
    paths.append(zpath)
    paths += [copy(name) for name in FOLDERS]
    assert len(paths) == 10
    return paths


def _run(*args, cwd=KIT_ROOT) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(KIT_ROOT)}
    env.pop("HW4_COURSE_DATA", None)
    return subprocess.run([sys.executable, "-m", "autograder", *map(os.fsdecode, args)], cwd=cwd, env=env,
                          capture_output=True, timeout=900)


@pytest.fixture(scope="module")
def graded(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("hostile")
    config = root / "grader.json"
    config.write_text(json.dumps(quick_config().to_dict()))
    paths = _class(root)
    out, report, similar = root / "grades", root / "report", root / "similar"
    runs = {"grade": _run("grade", *paths, "--out", out, "--config", config, "--quiet", "--jobs", "2")}
    runs["report"] = _run("report", out, "--out", report)
    runs["similar"] = _run("similar", *paths, "--out", similar)
    return {"root": root, "out": out, "report": report, "similar": similar, "runs": runs}


def test_the_file_name_that_is_not_utf8_stops_nothing(graded):
    run = graded["runs"]["grade"]
    assert run.returncode == 0, run.stderr.decode(errors="replace")[-3000:]
    with open(graded["out"] / "grades.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 10
    scores = {json.loads((f / "grading.json").read_text())["path"]: json.loads((f / "grading.json").read_text())
              for f in graded["out"].iterdir() if (f / "grading.json").is_file()}
    undecodable = next(s for p, s in scores.items() if p.endswith("undecodable"))
    assert undecodable["failure"] is None and undecodable["score"] == FULL
    feedback = (graded["out"] / "undecodable" / "feedback.md").read_text(encoding="utf-8")
    assert "notes_\\xff\\xfe.py" in "".join(Elements(render_markdown(feedback)).text)  # its bytes, shown
    for path, s in scores.items():  # the ones that raise lose points, the others none
        assert s["failure"] is None and (s["score"] < FULL) == ("raises_in_" in path), (path, s["score"])


def test_no_file_holds_an_escape_control_or_bidi_character(graded):
    checked = 0
    for folder in (graded["out"], graded["report"], graded["similar"]):
        for path in folder.rglob("*"):
            if path.is_file() and path.suffix in (".md", ".json", ".csv", ".html"):
                text = path.read_text(encoding="utf-8")
                assert not acting(text, allowed="\n\t\r"), (path, acting(text, "\n\t\r")[:5])
                if path.suffix == ".json":
                    bad = [s for s in strings(json.loads(text)) if acting(s)]
                    if path.name == "results.json":  # Gradescope shows it; the others are data for programs
                        assert not bad, (path, bad[:3])
                checked += 1
    assert checked > 40


def _markdown_files(graded):
    for folder in sorted(graded["out"].iterdir()):
        if (folder / "feedback.md").is_file():
            yield folder / "feedback.md", (folder / "feedback.md").read_text()
            data = json.loads((folder / "results.json").read_text())
            yield folder / "results.json", data["output"]
            for t in data["tests"]:
                yield folder / "results.json", t["output"]
    yield graded["out"] / "summary.md", (graded["out"] / "summary.md").read_text()


def test_markdown_renders_only_the_kits_elements_and_shows_the_students_text(graded):
    shown = []
    for path, text in _markdown_files(graded):
        page = Elements(render_markdown(text))
        tags = {t for t, _ in page.tags}
        assert tags <= MARKDOWN_ELEMENTS, (path, tags - MARKDOWN_ELEMENTS)
        assert all(not attrs or set(attrs) <= {"style", "align"} for _, attrs in page.tags), (path, page.tags)
        shown.append("".join(page.text))
    everything = "\n".join(shown)
    for text in (EXCEPTIONS["eightpoint"], EXCEPTIONS["essentialMatrix"], "nul\\x00 \\u202eabc",
                 f"{HOSTILE_TEXTS['svg']}.py", HOSTILE_TEXTS["js_link"] + ".py", "\\u202edcba"):
        assert text in everything, text  # shown as text, where the student put it


def test_html_pages_hold_no_tag_of_the_students(graded):
    pages = list(graded["report"].glob("*.html")) + list(graded["similar"].glob("*.html"))
    assert len(pages) == 2
    for page_path in pages:
        page = Elements(page_path.read_text())
        tags = {t for t, _ in page.tags}
        assert tags <= HTML_ELEMENTS, (page_path, tags - HTML_ELEMENTS)
        for tag, attrs in page.tags:
            assert not any(a.startswith("on") for a in attrs), (tag, attrs)
            assert tag != "img" or attrs["src"].startswith("data:image/png;base64,")
            assert tag != "a" or attrs["href"].startswith("#")
    similar = "".join(Elements((graded["similar"] / "similarity.html").read_text()).text)
    assert "<b>bold" in similar  # the folder's name, shown as text


def test_no_csv_cell_starts_a_formula_and_mistakes_are_the_catalogues(graded):
    files = [graded["out"] / "grades.csv"] + list(graded["report"].glob("*.csv")) + list(graded["similar"].glob("*.csv"))
    assert len(files) == 7 and {"grades.csv", "mistakes.csv", "library_calls.csv", "similarity.csv"} <= {p.name for p in files}
    for path in files:
        with open(path, newline="", encoding="utf-8") as fh:
            for row in csv.reader(fh):
                for cell in row:
                    number = cell.lstrip("-").replace(".", "", 1).isdigit()
                    assert number or not cell.startswith(FORMULA_START), (path.name, row)
    with open(graded["report"] / "mistakes.csv", newline="", encoding="utf-8") as fh:
        named = {r["mistake"] for r in csv.DictReader(fh)}
    assert named <= {name for name, _ in KNOWN_MISTAKES.values()}


def test_what_the_commands_print_holds_no_escape(graded):
    for name, run in graded["runs"].items():
        assert run.returncode == 0, (name, run.stderr[-2000:])
        for stream in (run.stdout, run.stderr):
            text = stream.decode("utf-8", "surrogateescape")
            assert not acting(text), (name, acting(text)[:5])


def test_staff_outputs_are_private(graded):
    for folder in (graded["report"], graded["similar"]):
        assert stat.S_IMODE(folder.stat().st_mode) == 0o700
        files = [p for p in folder.rglob("*") if p.is_file()]
        assert files and all(stat.S_IMODE(p.stat().st_mode) == 0o600 for p in files), folder
