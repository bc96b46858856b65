"""The README stays a short door into docs/, and every link of the docs leads somewhere.

README.md is under 12 KB and links every page of docs/; every relative link of README.md,
CHANGELOG.md and docs/*.md names a file that exists (and, with ``#anchor``, a heading of that
page); no page names this machine's checkout; every requirement has its reason in
docs/dependencies.md; no comment or docstring of the kit's Python (its packages, tests/ and
benchmarks/) names an issue number, but says the behaviour instead.  The checkers are plain
functions, each shown failing on a planted case.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

from core.paths import KIT_ROOT

README_LIMIT = 12 * 1024  # bytes: the README is a door, the pages hold the rest
MACHINE_PATH = "/work/main"  # the checkout the kit is developed in; no page may depend on it

_FENCE = re.compile(r"^```.*?^```", re.S | re.M)
_CODE = re.compile(r"`[^`\n]*`")
_LINK = re.compile(r"\[[^\]\n]*\]\(([^)\s]+)\)")
_HEADING = re.compile(r"^#{1,6}\s+(.+?)\s*$", re.M)
# the word and a number, as in the planted case below: an issue's number means nothing once the
# tracker moves or the issue is closed, while the behaviour it stood for is what a reader needs
_ISSUE_NUMBER = re.compile(r"[Ii]ssues? #?[0-9]")


def pages(root: Path) -> list[Path]:
    """README.md, CHANGELOG.md and every docs/*.md under ``root`` (those that exist)."""
    found = [root / "README.md", root / "CHANGELOG.md", *sorted((root / "docs").glob("*.md"))]
    return [p for p in found if p.is_file()]


def links(text: str) -> list[str]:
    """The Markdown link targets of ``text``, outside code blocks and inline code."""
    return _LINK.findall(_CODE.sub("", _FENCE.sub("", text)))


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = _CODE.sub(lambda m: m.group(0).strip("`"), heading).lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(text: str) -> set[str]:
    return {slug(h) for h in _HEADING.findall(_FENCE.sub("", text))}


def broken_links(page: Path) -> list[str]:
    """Each relative link of ``page`` whose file (or heading, after ``#``) does not exist."""
    bad = []
    for target in links(page.read_text(encoding="utf-8")):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # https:, mailto: ... are not files
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            bad.append(f"{target} (no such file)")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest.read_text(encoding="utf-8")):
            bad.append(f"{target} (no such heading)")
    return bad


def linked_docs(readme: Path) -> set[Path]:
    """The docs/*.md pages ``readme`` links to, resolved."""
    out = set()
    for target in links(readme.read_text(encoding="utf-8")):
        path = target.partition("#")[0]
        if path.startswith("docs/") and path.endswith(".md"):
            out.add((readme.parent / path).resolve())
    return out


def machine_paths(page: Path) -> list[int]:
    """Line numbers of ``page`` that name the development checkout."""
    return [k for k, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1) if MACHINE_PATH in line]


def too_long(readme: Path) -> bool:
    return readme.stat().st_size >= README_LIMIT


def python_files(root: Path) -> list[Path]:
    """Every .py file of the kit's packages (the folders of ``root`` with an __init__.py), tests/
    and benchmarks/ under ``root``."""
    folders = [d for d in sorted(root.iterdir())
               if (d / "__init__.py").is_file() or d.name in ("tests", "benchmarks")]
    return [p for d in folders for p in sorted(d.rglob("*.py")) if "__pycache__" not in p.parts]


def issue_numbers(path: Path) -> list[int]:
    """Line numbers of ``path`` (Python source) where a comment or a docstring names an issue number
    (the same words in other strings, as test data, are not looked at)."""
    text = path.read_text(encoding="utf-8")
    if not _ISSUE_NUMBER.search(text):
        return []
    found = {tok.start[0] for tok in tokenize.generate_tokens(io.StringIO(text).readline)
             if tok.type == tokenize.COMMENT and _ISSUE_NUMBER.search(tok.string)}
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                    and isinstance(first.value.value, str):
                doc = first.value.value
                found.update(first.lineno + doc[:m.start()].count("\n") for m in _ISSUE_NUMBER.finditer(doc))
    return sorted(found)


def requirement_names(root: Path) -> list[str]:
    names = []
    for req in ("requirements.txt", "requirements-dev.txt"):
        for line in (root / req).read_text(encoding="utf-8").splitlines():
            spec = line.split("#", 1)[0].strip()
            if spec and not spec.startswith("-"):
                names.append(re.split(r"[<>=!~;\[ ]", spec, maxsplit=1)[0])
    return names


# ------------------------------------------------------------------------------------------------
# the kit's own docs


def test_readme_is_short():
    readme = KIT_ROOT / "README.md"
    size = readme.stat().st_size
    assert not too_long(readme), f"README.md is {size} bytes; move detail into docs/ (limit {README_LIMIT})"


def test_readme_links_every_docs_page_and_each_exists():
    linked = linked_docs(KIT_ROOT / "README.md")
    assert linked, "README.md links no page of docs/"
    missing = sorted(str(p.relative_to(KIT_ROOT)) for p in linked if not p.is_file())
    assert not missing, f"README.md links docs pages that do not exist: {missing}"
    unlinked = sorted(p.name for p in (KIT_ROOT / "docs").glob("*.md") if p.resolve() not in linked)
    assert not unlinked, f"docs pages the README's table does not link: {unlinked}"


@pytest.mark.parametrize("page", pages(KIT_ROOT), ids=lambda p: str(p.relative_to(KIT_ROOT)))
def test_every_relative_link_resolves(page):
    assert not broken_links(page), f"{page.relative_to(KIT_ROOT)}: {broken_links(page)}"


def test_the_link_check_sees_links():
    # Not vacuous: the pages do link each other, with anchors too.
    every = [t for p in pages(KIT_ROOT) for t in links(p.read_text(encoding="utf-8"))]
    assert len(every) >= 20 and any("#" in t for t in every)


def test_no_page_names_the_development_checkout():
    found = {str(p.relative_to(KIT_ROOT)): machine_paths(p) for p in pages(KIT_ROOT)}
    assert not {k: v for k, v in found.items() if v}, f"pages naming {MACHINE_PATH} (line numbers): {found}"


def test_no_comment_or_docstring_names_an_issue_number():
    files = python_files(KIT_ROOT)
    # tests/ and the packages are read
    assert {"test_docs.py", "conftest.py", "plugin.py", "paths.py"} <= {p.name for p in files}
    found = {str(p.relative_to(KIT_ROOT)): lines for p in files if (lines := issue_numbers(p))}
    assert not found, f"comments or docstrings naming an issue number, not the behaviour (lines): {found}"


def test_every_requirement_has_its_reason_in_the_dependencies_page():
    text = (KIT_ROOT / "docs" / "dependencies.md").read_text(encoding="utf-8").lower()
    names = requirement_names(KIT_ROOT)
    assert "numpy" in names and "pytest-xdist" in names
    missing = [n for n in names if not re.search(rf"^\| {re.escape(n.lower())} \|", text, re.M)]
    assert not missing, f"requirements without a row in docs/dependencies.md: {missing}"


# ------------------------------------------------------------------------------------------------
# each checker fails on a planted mistake


@pytest.fixture
def planted(tmp_path) -> Path:
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text("# A page\n\n## Some `code` here\n\nSee [b](b.md#top).\n")
    (tmp_path / "docs" / "b.md").write_text("# Top\n\nBack to [a](a.md#some-code-here), [web](https://example.org).\n")
    (tmp_path / "README.md").write_text("# Kit\n\n[a](docs/a.md) and [b](docs/b.md)\n")
    return tmp_path


def test_checkers_pass_a_sound_tree(planted):
    assert [broken_links(p) for p in pages(planted)] == [[], [], []]
    assert len(linked_docs(planted / "README.md")) == 2


def test_a_missing_file_a_missing_heading_and_a_missing_page_are_caught(planted):
    (planted / "docs" / "a.md").write_text("# A\n\n[gone](gone.md), [b](b.md#nowhere)\n```\n[x](in-code.md)\n```\n")
    assert broken_links(planted / "docs" / "a.md") == ["gone.md (no such file)", "b.md#nowhere (no such heading)"]
    (planted / "README.md").write_text("[c](docs/c.md)\n")
    assert not all(p.is_file() for p in linked_docs(planted / "README.md"))


def test_a_machine_path_is_caught(planted):
    (planted / "docs" / "b.md").write_text(f"# B\n\nok\ncd {MACHINE_PATH}/tests\n")
    assert machine_paths(planted / "docs" / "b.md") == [4]


def test_a_long_readme_is_caught(planted):
    assert not too_long(planted / "README.md")
    (planted / "README.md").write_text("x" * README_LIMIT)
    assert too_long(planted / "README.md")


def test_an_issue_number_in_a_comment_or_a_docstring_is_caught(tmp_path):
    sound = tmp_path / "sound.py"
    sound.write_text('"""Grades do not depend on the secret."""\n\n# why: the draws are seeded\n'
                     'NOTE = "issue 9 in a string that is data"\n')
    assert issue_numbers(sound) == []
    planted = tmp_path / "planted.py"
    planted.write_text('"""Hidden scenes are drawn per submission\n(issue 10)."""\n\n'
                       'def f():\n    """Fixed (Issue #9)."""\n    return 1  # see issues 16 and 29\n')
    assert issue_numbers(planted) == [2, 5, 6]
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "__init__.py").write_text("# issue 3\n")
    assert [p.name for p in python_files(tmp_path)] == ["__init__.py"]
