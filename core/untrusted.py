"""The one boundary for text that came from a submission, made safe for where it is written.

Anything a student controls (an exception's message, the name of a file, folder or function,
printed output, code shown to staff) may hold markup, a spreadsheet formula or terminal escapes.
Before it is written, it passes the function of its destination:

- ``for_markdown``: feedback.md, results.json's ``output`` (Gradescope renders it as Markdown),
  summary.md, regrade_diff.md.  A renderer that allows raw HTML shows the text, never a tag, a
  link, an image, a heading or a list of the student's.
- ``for_html``: the class report, the look-alike pages, regrade_diff.html.
- ``for_csv_cell``: every cell of every CSV (grades, canvas, report, similarity, regrade): a cell
  a spreadsheet would read as a formula gets OWASP's leading single quote.  It is judged as the
  spreadsheet gets it, once made ``visible``: an escape sequence or spaces in front of ``=`` hide
  nothing.
- ``for_json``: every string (keys too) of a staff JSON file (similarity.json), made ``visible``;
  numbers, booleans and None stay as they are.
- ``for_terminal``: what the CLI prints.

All of them first make the text ``visible``: terminal escape sequences (CSI, OSC with its
payload, such as an OSC-8 hyperlink or a window title, DCS...) are removed, and every other
control, bidi, zero-width or format character, and every byte of a file name that was not UTF-8
(a lone surrogate from ``surrogateescape``), is shown as its Python escape (``\\x1b``,
``\\u202e``, ``\\xff``), so a reader sees that it was there and nothing acts on it.

File names stay bytes (``os.fsencode``) wherever they are identity (digests, paths); ``visible``
is for showing them.
"""

from __future__ import annotations

import csv
import html
import io
import re
import unicodedata

__all__ = ["csv_text", "for_csv_cell", "for_html", "for_json", "for_markdown", "for_terminal", "visible"]

# Long enough for any feedback of the kit (results.clean_feedback bounds a check's at 2000).
LIMIT = 4000
_CUT = " [...]"

# ESC (or its C1 form) and what follows: a CSI sequence, a string sequence (OSC, DCS, SOS, PM,
# APC) up to BEL or ST (or the end of the text), or a two-character escape.
_ANSI = re.compile(
    r"(?:\x1b\[|\x9b)[0-?]*[ -/]*[@-~]?"
    r"|(?:\x1b[\]PX^_]|[\x90\x98\x9d\x9e\x9f]).*?(?:\x07|\x1b\\|\x9c|$)"
    r"|\x1b[ -~]?",
    re.S)
# Characters shown as escapes: controls, format characters (bidi overrides and isolates,
# zero-width ones, soft hyphen...), surrogates (undecodable bytes), line and paragraph separators.
_HIDDEN_CATEGORIES = {"Cc", "Cf", "Cs", "Zl", "Zp"}


def _shown(ch: str) -> str:
    code = ord(ch)
    if 0xDC80 <= code <= 0xDCFF:  # a byte that was not UTF-8, kept by surrogateescape
        return f"\\x{code - 0xDC00:02x}"
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def visible(text, limit: int = LIMIT, *, newlines: bool = True) -> str:
    """``text`` (any object: ``str()`` of it; bytes decoded with surrogateescape) with terminal
    escape sequences removed and every control, format or undecodable character shown as its
    escape; newlines kept when ``newlines`` (tabs always kept, CRs dropped); at most ``limit``
    characters (then cut, with " [...]")."""
    if isinstance(text, bytes):
        text = text.decode("utf-8", "surrogateescape")
    text = _ANSI.sub("", str(text)).replace("\r\n", "\n")
    out = []
    for ch in text:
        if ch == "\t" or (ch == "\n" and newlines):
            out.append(ch)
        elif ch == "\n":
            out.append(" ")
        elif ch == "\r":
            continue
        elif unicodedata.category(ch) in _HIDDEN_CATEGORIES:
            out.append(_shown(ch))
        else:
            out.append(ch)
    text = "".join(out)
    return text if len(text) <= limit else text[:limit] + _CUT


# Markdown (CommonMark and GitHub's extensions): characters that open inline markup anywhere
# (emphasis, code, links, images, raw HTML, autolinks, entities, tables, strikethrough, math)
# are backslash-escaped, which every renderer shows as the bare character.  An underscore between
# two letters or digits (q2_eightpoint.ipynb) can neither open nor close emphasis: it stays bare.
_INLINE = re.compile(r"([\\`*\[\]<>&|~$]|(?<![^\W_])_|_(?![^\W_]))")
# Bare links a renderer's linkify turns into <a>: the escape splits them.
_BARE_LINK = re.compile(r"(?<=[A-Za-z])(:)(?=//)|(?<=\bwww)(\.)|(?<=\w)(@)(?=\w)", re.I)
# What starts a block at the beginning of a line: a heading, a list item, a thematic break or a
# setext underline, a numbered item.
_BLOCK_START = re.compile(r"^([#+=-])|^(\d+)([.)])")


def for_markdown(text, limit: int = LIMIT, *, newlines: bool = True) -> str:
    """``visible(text)`` escaped for Markdown: rendered (even by a renderer that passes raw HTML),
    it is one run of text, never an element of the student's.

    Lines lose their leading and trailing spaces (an indented line is a code block, two trailing
    spaces a line break) and blank lines are dropped (a paragraph break would end the kit's list
    item or table around the text); with ``newlines=False`` the text is one line.
    """
    text = visible(text, limit, newlines=newlines).replace("\t", " ")
    lines = []
    for line in text.split("\n"):
        line = line.strip()
        if not line:
            continue
        line = _INLINE.sub(r"\\\1", line)
        line = _BARE_LINK.sub(lambda m: "\\" + m.group(0), line)
        line = _BLOCK_START.sub(lambda m: f"\\{m.group(1)}" if m.group(1) else f"{m.group(2)}\\{m.group(3)}", line)
        lines.append(line)
    return "\n".join(lines)


def for_html(text, limit: int = LIMIT, *, newlines: bool = True) -> str:
    """``visible(text)`` escaped for HTML text or a quoted attribute value."""
    return html.escape(visible(text, limit, newlines=newlines), quote=True)


# A cell a spreadsheet reads as a formula (OWASP, "CSV injection"); a plain number is data.
_FORMULA_SIGNS = ("=", "+", "-", "@")
_PLAIN_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[+-]?\d+)?", re.I)


def for_csv_cell(value, limit: int = LIMIT):
    """A CSV cell: numbers as they are; text ``visible`` on one line, with a leading single quote
    when it starts with a tab, or with ``= + - @`` after any leading spaces (unless it is a plain
    number such as "-2").

    The cell is judged once it is ``visible``, as a spreadsheet gets it: an escape sequence, a CR
    or a newline in front of ``=`` is removed or made a space there, so it must not hide the
    ``=``; and an import that trims spaces may start the cell at the ``=``.
    """
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value
    cell = visible("" if value is None else value, limit, newlines=False)
    formula = cell.startswith("\t") or cell.lstrip().startswith(_FORMULA_SIGNS)
    return "'" + cell if formula and not _PLAIN_NUMBER.fullmatch(cell.strip()) else cell


def csv_text(rows) -> str:
    """The text of a CSV file of ``rows`` (lists of cells), every cell through ``for_csv_cell``."""
    buf = io.StringIO(newline="")
    writer = csv.writer(buf)
    for row in rows:
        writer.writerow([for_csv_cell(c) for c in row])
    return buf.getvalue()


def for_json(value):
    """``value`` (JSON data: dicts, lists, tuples, str, numbers, bool, None) with every string, keys
    included, made ``visible``: a reader of the file (``jq``, an editor, a script printing it)
    meets no escape sequence, control, bidi or zero-width character of a student's."""
    if isinstance(value, str):
        return visible(value)
    if isinstance(value, dict):
        return {for_json(k) if isinstance(k, str) else k: for_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [for_json(v) for v in value]
    if value is None or isinstance(value, (bool, int, float)):
        return value
    raise ValueError(f"value: expected JSON data (dict, list, str, number, bool or None), got {type(value).__name__}")


def for_terminal(text, limit: int = LIMIT) -> str:
    """``visible(text)`` for a TA's terminal: no escape sequence, control or bidi character acts."""
    return visible(text, limit)
