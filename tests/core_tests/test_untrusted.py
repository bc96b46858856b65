"""The boundary for student text (core/untrusted.py) and the writers that use it, without grading.

Every hostile text of the corpus (tests/support/corpus/hostile.py) goes through each destination's
function and must come out inert there: Markdown rendered by a renderer that passes raw HTML
gives one paragraph of the same text; HTML gives text only; a CSV cell never starts a formula; a
terminal gets no escape, control or bidi character.  Then the writers that take student text
without a sandbox run: the class report (mistake names from the catalogue only, safe cells, a
private folder), the regrade diff, a submission's digest with a name that is not UTF-8, and a
symbolic link in a zip named in the feedback.  tests/end_to_end/test_hostile_outputs.py grades them for real.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import stat
import unicodedata
import zipfile
from html.parser import HTMLParser
from pathlib import Path

import mistune
import pytest
from corpus.hostile import HOSTILE_TEXTS, UNDECODABLE_NAME

from autograder.channels.batch import submission_digest
from autograder.channels.regrade import Change, write_diff
from autograder.feedback.results import QuestionResult, SubmissionResult, TestResult
from autograder.review.report import build_report, write_report
from autograder.submission.read import load_submission
from core.untrusted import csv_text, for_csv_cell, for_html, for_json, for_markdown, for_terminal, visible

HOSTILE = list(HOSTILE_TEXTS.values()) + [UNDECODABLE_NAME.decode("utf-8", "surrogateescape")]
IDS = list(HOSTILE_TEXTS) + ["undecodable"]
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")

# A renderer as permissive as they come: raw HTML passes, bare URLs become links, tables, math,
# footnotes and strikethrough are on.
render_markdown = mistune.create_markdown(escape=False, plugins=["strikethrough", "footnotes", "table", "url",
                                                                 "math"])


class Elements(HTMLParser):
    """Tags (with their attributes) and text of an HTML fragment; comments and declarations too."""

    def __init__(self, html_text: str):
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict]] = []
        self.text: list[str] = []
        self.other: list[str] = []
        self.feed(html_text)
        self.close()

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))

    def handle_startendtag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))

    def handle_data(self, data):
        self.text.append(data)

    def handle_comment(self, data):
        self.other.append(f"<!--{data}-->")

    def handle_decl(self, decl):
        self.other.append(decl)


def acting_characters(text: str, *, allowed: str = "\n\t") -> list[str]:
    """Characters that act instead of showing: controls (ESC, NUL, C1...), format characters
    (bidi overrides, zero-width), surrogates, line and paragraph separators."""
    return [ch for ch in text if ch not in allowed
            and unicodedata.category(ch) in ("Cc", "Cf", "Cs", "Zl", "Zp")]


def squeeze(text: str) -> str:
    return " ".join(text.split())


@pytest.mark.parametrize("text", HOSTILE, ids=IDS)
def test_markdown_renders_one_paragraph_of_the_same_text(text):
    shown = for_markdown(text)
    assert not acting_characters(shown)
    page = Elements(render_markdown(shown))
    assert {tag for tag, _ in page.tags} <= {"p"} and not page.other, (shown, page.tags, page.other)
    assert squeeze("".join(page.text)) == squeeze(visible(text))


@pytest.mark.parametrize("text", HOSTILE, ids=IDS)
def test_html_is_text_only(text):
    page = Elements(f"<p title='{for_html(text)}'>{for_html(text)}</p>")
    assert page.tags == [("p", {"title": visible(text)})] and not page.other
    assert "".join(page.text) == visible(text)
    assert not acting_characters(for_html(text))


@pytest.mark.parametrize("text", HOSTILE, ids=IDS)
def test_a_csv_cell_never_starts_a_formula_and_reads_back(text):
    cell = for_csv_cell(text)
    assert not cell.startswith(FORMULA_START) and not acting_characters(cell, allowed="\t")
    [row] = list(csv.reader(io.StringIO(csv_text([[text, 3, "-2"]]))))
    assert row == [cell, "3", "-2"]  # numbers stay numbers, also negative ones


@pytest.mark.parametrize("text", HOSTILE, ids=IDS)
def test_a_terminal_gets_no_escape_control_or_bidi_character(text):
    shown = for_terminal(text)
    assert "\x1b" not in shown and not acting_characters(shown)
    assert len(shown) <= 4000 + len(" [...]")


def test_what_is_removed_and_what_is_made_visible():
    assert visible("\x1b]8;;http://evil.example\x1b\\click\x1b]8;;\x1b\\") == "click"  # OSC-8: the link goes
    assert visible("\x1b]0;pwned\x07title\x1b[2J") == "title"
    assert visible("a\u202eb\x00c") == "a\\u202eb\\x00c"
    assert visible(UNDECODABLE_NAME) == "notes_\\xff\\xfe.py"
    assert for_markdown("q2_eightpoint.ipynb") == "q2_eightpoint.ipynb"  # file names stay readable


def _graded(root: Path, feedback_by_student: dict[str, str]) -> Path:
    graded = root / "graded"
    for student, feedback in feedback_by_student.items():
        tests = [TestResult("F fits", 0.0, 10.0, False, feedback)]
        result = SubmissionResult((QuestionResult.of("Q2", tests),), student)
        (graded / student).mkdir(parents=True)
        result.write_gradescope(graded / student / "results.json")
    return graded


def test_the_class_report_names_catalogue_mistakes_only_writes_safe_cells_and_is_private(tmp_path):
    graded = _graded(tmp_path, {
        "+1+1": "eightpoint raised ValueError: x. Likely mistake: =1+1+cmd|' /C calc'!A0. Do it.",
        "@SUM(1+1)": "mean distance 3 px. Likely mistake: F transposed. Check the order.",
        "b": "Likely mistake: <img src=x onerror=alert(1)>.",
    })
    rep = build_report({p.parent.name: json.loads(p.read_text()) for p in graded.glob("*/results.json")})
    assert dict(rep.mistakes) == {("Q2", "F transposed"): {"@SUM(1+1)"}}
    out = tmp_path / "report"
    out.mkdir(mode=0o755)
    written = write_report(graded, out)
    assert stat.S_IMODE(out.stat().st_mode) == 0o700
    for path in out.iterdir():
        assert stat.S_IMODE(path.stat().st_mode) == 0o600, path.name
        if path.suffix == ".csv":
            for row in csv.reader(path.open(newline="")):
                assert not any(str(c).startswith(FORMULA_START) and not re.fullmatch(r"-?[\d.]+", c) for c in row), row
    page = Elements(written["html"].read_text())
    assert not {"script", "svg"} & {t for t, _ in page.tags}
    assert all(t != "img" or a["src"].startswith("data:image/png;base64,") for t, a in page.tags)
    assert "@SUM(1+1)" in "".join(page.text)  # the student is named, as text


def test_the_regrade_diff_is_escaped_and_private(tmp_path):
    changes = [Change(name, "Q2", 10.0, 0.0, (f"could not be graded now ({text})",), ())
               for name, text in (("+1+1", HOSTILE_TEXTS["img"]), ("b", HOSTILE_TEXTS["ansi_clear_colour"]))]
    files = write_diff(tmp_path, changes, old=tmp_path / "old", new=tmp_path, config_changes=[], students=2)
    for path in files.values():
        text = path.read_text()
        assert stat.S_IMODE(path.stat().st_mode) == 0o600 and not acting_characters(text, allowed="\n\t\r")
    assert not {"img", "script"} & {t for t, _ in Elements(files["html"].read_text()).tags}
    md = Elements(render_markdown(files["md"].read_text()))
    assert {t for t, _ in md.tags} <= {"h1", "ul", "li", "p", "code", "table", "thead", "tbody", "tr", "th", "td", "br"}
    assert all(not row[0].startswith(FORMULA_START) for row in csv.reader(files["csv"].open(newline="")))


def test_a_name_that_is_not_utf8_has_a_digest(tmp_path):
    folder = tmp_path / "sub"
    folder.mkdir()
    with open(os.path.join(os.fsencode(folder), UNDECODABLE_NAME), "wb") as fh:
        fh.write(b"x = 1\n")
    assert re.fullmatch(r"[0-9a-f]{64}", submission_digest(folder))


def test_a_symbolic_link_in_a_zip_is_said_with_its_name_escaped(tmp_path):
    path = tmp_path / "linked.zip"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("q2_eightpoint.py", "def eightpoint(pts1, pts2, M):\n    return None\n")
        link = zipfile.ZipInfo("<svg onload=alert(1)>.py")
        link.external_attr = (stat.S_IFLNK | 0o777) << 16
        zf.writestr(link, "/etc/passwd")
    notes = [str(n) for n in load_submission(path).notes()]
    said = [n for n in notes if "<svg onload=alert(1)>.py" in n]
    assert said and "symbolic link" in said[0]
    feedback = SubmissionResult((), "s", notes=tuple(notes)).feedback_markdown()
    page = Elements(render_markdown(feedback))
    assert "svg" not in {t for t, _ in page.tags} and "<svg onload=alert(1)>.py" in "".join(page.text)


def test_a_feedback_line_of_student_text_carries_no_escape_sequence_or_control():
    """Where the hidden tests take a student's message in (their own failure report in a TA's
    terminal prints it), the escapes are gone and the controls shown, before any writer escapes it."""
    from autograder.feedback.words import exception_sentence, tidy

    for text in HOSTILE:
        for line in (tidy(text), exception_sentence(f"ValueError: {text}")):
            assert "\x1b" not in line and "\x9b" not in line, line
            assert not any(unicodedata.category(c) in ("Cc", "Cf") for c in line), line


# Formulas that only a spreadsheet sees: what hides the sign is an escape sequence ``visible``
# removes, or spaces an import may trim.
HIDDEN_FORMULAS = {
    "csi_before_equals": "\x1b[m=1+1+cmd|' -C calc'!A0.py",
    "osc_title_before_minus": "\x1b]0;t\x07-1+1",
    "colour_before_tab": "\x1b[31m\t=1+1",
    "c1_csi_before_at": "\x9b0m@SUM(1+1)",
    "spaces_before_plus": "   +1+1",
}


@pytest.mark.parametrize("text", HIDDEN_FORMULAS.values(), ids=HIDDEN_FORMULAS)
def test_a_csv_cell_is_judged_as_the_spreadsheet_reads_it(text):
    cell = for_csv_cell(text)
    assert cell == "'" + visible(text, newlines=False)
    [[row]] = list(csv.reader(io.StringIO(csv_text([[text]]))))
    assert row == cell


def test_json_data_has_every_string_visible():
    data = {"a\u202eb": ["\x1b]0;pwned\x07name\u200b", 3, -2.5, None, True, ("t\x00",)], "n": {"k": "v"}}
    assert for_json(data) == {"a\\u202eb": ["name\\u200b", 3, -2.5, None, True, ["t\\x00"]], "n": {"k": "v"}}
    with pytest.raises(ValueError, match="value"):
        for_json({"x": object()})
