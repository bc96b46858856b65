"""Look-alike code: planted copies rank above every independent pair; textbook solutions are not flagged."""

from __future__ import annotations

import ast
import csv
import itertools
import json
import unicodedata
import zipfile
from pathlib import Path

import nbformat
import pytest

from autograder.review.__main__ import main
from autograder.review.fingerprint import fingerprint_function
from autograder.review.reader import SubmissionCode, functions_in_source, read_submission
from autograder.review.similarity import FLAG, MIN_SHARED, compare, given_hashes, groups
from corpus import variants

from core.paths import KIT_ROOT

CORPUS = KIT_ROOT / "tests" / "support" / "review_corpus"

# (function, a, b): the planted copies, see tests/support/review_corpus/README.md
PLANTED = {
    "eightpoint": {("alice", "copy_renamed"), ("bo", "copy_reordered"), ("chen", "copy_comments"),
                   ("copy_mixed", "key")},
    "essentialMatrix": {("alice", "copy_renamed"), ("bo", "copy_reordered"), ("chen", "copy_comments")},
    "triangulate": {("alice", "copy_renamed"), ("bo", "copy_reordered"), ("chen", "copy_comments"),
                    ("dana", "eve")},
}
# the kit's own valid alternatives and mistakes, each an independent student
KIT_STUDENTS = {
    "kit_hartley": variants.EIGHTPOINT_HARTLEY,
    "kit_no_refine": variants.EIGHTPOINT_NO_REFINE,
    "kit_uint16": variants.EIGHTPOINT_UINT16,
    "kit_triangulate_mean": variants.TRIANGULATE_MEAN_ERROR,
    "kit_essential_swapped": variants.ESSENTIAL_K_SWAPPED,
}


def _as_notebook(py: Path, folder: Path) -> Path:
    """The .py file as a student's notebooks: one cell per top-level block, plus a magic and a markdown cell."""
    text = py.read_text()
    blocks = [b for b in text.split("\n\n\n") if b.strip()]
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_markdown_cell("# Q2 my answers"), nbformat.v4.new_code_cell("%matplotlib inline")]
    nb.cells += [nbformat.v4.new_code_cell(b) for b in blocks]
    target = folder / py.stem
    target.mkdir(parents=True)
    nbformat.write(nb, target / "q3_metric_reconstruction.ipynb")
    return target


@pytest.fixture(scope="module")
def given() -> set[int]:
    """The handout's code hashes (compare's default ``given``), made once for the module: each
    ``compare`` would otherwise fingerprint the stubs and the starter package again (about 2 s)."""
    return given_hashes()


@pytest.fixture
def command_given(monkeypatch, given):
    """The command (``main``) reads the handout's code hashes as made once for the module."""
    from autograder.review import similarity

    monkeypatch.setattr(similarity, "given_hashes", lambda *args, **kwargs: set(given))


@pytest.fixture(scope="module")
def comparisons(tmp_path_factory, given):
    tmp = tmp_path_factory.mktemp("class")
    subs = []
    for k, py in enumerate(sorted(CORPUS.glob("*.py"))):
        if k % 3 == 0:
            path = py                                       # a plain .py
        elif k % 3 == 1:
            path = _as_notebook(py, tmp)                    # a folder of notebooks
        else:
            path = tmp / f"{py.stem}.zip"                   # a zip of a notebook
            with zipfile.ZipFile(path, "w") as zf:
                folder = _as_notebook(py, tmp / "zipped")
                zf.write(folder / "q3_metric_reconstruction.ipynb", f"{py.stem}/q3_metric_reconstruction.ipynb")
        subs.append(read_submission(path))
    subs.append(read_submission(KIT_ROOT / "notebooks" / "key", name="key"))
    for name, src in KIT_STUDENTS.items():
        subs.append(SubmissionCode(name, {f.name: f for f in functions_in_source(src, name)}))
    assert {s.name for s in subs} >= {"alice", "copy_mixed", "eve", "key"}
    for s in subs[:-len(KIT_STUDENTS)]:
        assert s.name == "copy_mixed" or {"eightpoint", "essentialMatrix", "triangulate"} <= set(s.functions), s
    return compare(subs, given, functions=list(PLANTED))


@pytest.mark.parametrize("function", list(PLANTED))
def test_every_planted_pair_ranks_above_every_independent_pair(comparisons, function):
    comp = comparisons[function]
    planted, independent = [], []
    for a, b in itertools.combinations(comp.names, 2):
        s = comp.pair_score(a, b)
        (planted if tuple(sorted((a, b))) in PLANTED[function] else independent).append((s, a, b))
    assert len(planted) == len(PLANTED[function])
    assert len(independent) >= 40
    worst_planted, best_independent = min(planted), max(independent)
    assert worst_planted[0] > best_independent[0], (worst_planted, best_independent)
    # the ranked list starts with the planted pairs
    top = comp.ranked(len(planted))
    assert {(p.a, p.b) for p in top} == PLANTED[function]


@pytest.mark.parametrize("function", list(PLANTED))
def test_independent_solutions_of_the_same_algorithm_are_not_flagged(comparisons, function):
    comp = comparisons[function]
    for p in comp.ranked():
        if (p.a, p.b) not in PLANTED[function]:
            assert not p.flagged and p.score < FLAG, p


def test_long_planted_copies_are_flagged(comparisons):
    for function in ("eightpoint", "triangulate"):
        comp = comparisons[function]
        for a, b in PLANTED[function]:
            assert comp.pair_score(a, b) >= FLAG, (function, a, b)


def test_renaming_reordering_and_comments_leave_the_fingerprints_unchanged():
    a = "def f(x, y):\n    s = x @ y  # product\n    t = x.T\n    for i in range(3):\n        s += i\n    return s, t\n"
    b = "def f(p,\n      q):\n    '''doc'''\n    tt = p.T\n    ss = p@q\n\n    for j in range(3): ss += j\n    return ss, tt\n"
    assert fingerprint_function(a).hashes == fingerprint_function(b).hashes
    # the parameters keep their position: K1.T @ F @ K2 is not K2.T @ F @ K1
    e1 = "def e(F, K1, K2):\n    return K2.T @ F @ K1\n"
    e2 = "def e(F, K1, K2):\n    return K1.T @ F @ K2\n"
    assert fingerprint_function(e1).hashes != fingerprint_function(e2).hashes


def test_identical_one_liners_are_too_short_to_flag(given):
    one = "def essentialMatrix(F, K1, K2):\n    return K2.T @ F @ K1\n"
    subs = [SubmissionCode(n, {f.name: f for f in functions_in_source(one, n)}) for n in ("s1", "s2")]
    comp = compare(subs, given, functions=["essentialMatrix"])["essentialMatrix"]
    assert comp.jaccard[0, 1] == pytest.approx(1.0)
    assert all(not p.flagged for p in comp.ranked())


def test_the_untouched_stubs_have_no_code_of_their_own(given):
    subs = [read_submission(KIT_ROOT / "notebooks", name=n) for n in ("stub1", "stub2")]
    comps = compare(subs, given)
    for comp in comps.values():
        assert comp.names == [] and comp.skipped == ["stub1", "stub2"]


def test_command_writes_ranked_csv_json_and_an_offline_page(tmp_path, command_given):
    out = tmp_path / "out"
    code = main(["similar", *map(str, sorted(CORPUS.glob("*.py"))), str(KIT_ROOT / "notebooks" / "key"), "--out", str(out)])
    assert code == 0
    data = json.loads((out / "similarity.json").read_text())
    first = data["functions"]["triangulate"]["pairs"][0]
    assert first["rank"] == 1 and first["flagged"] and (first["a"], first["b"]) in PLANTED["triangulate"]
    page = (out / "similarity.html").read_text()
    assert "look at these" in page and "class=\"hit\"" in page
    assert "cheat" not in page.lower() and "http" not in page and "<script" not in page
    rows = (out / "similarity.csv").read_text().splitlines()
    assert rows[0].startswith("function,rank,a,b,score") and len(rows) > 10
    assert main(["similar", str(tmp_path / "missing"), "--out", str(out)]) == 2


def _renamed(source: str) -> str:
    """``source`` with every variable assigned inside a function (its parameters excepted) renamed, and
    reformatted by ast.unparse, as a student disguising a copy would."""
    tree = ast.parse(source)
    for fn in [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)]:
        params = {a.arg for a in ast.walk(fn.args) if isinstance(a, ast.arg)}
        local = {n.id for n in ast.walk(fn) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)} - params
        for n in ast.walk(fn):
            if isinstance(n, ast.Name) and n.id in local:
                n.id = f"my_{n.id.lower()}_var"
    return ast.unparse(tree)


def _key_copy(folder: Path, rename: bool) -> Path:
    """A copy of the answer key's notebooks, its variables renamed when ``rename``."""
    folder.mkdir(parents=True)
    for nb_path in sorted((KIT_ROOT / "notebooks" / "key").glob("*.ipynb")):
        nb = nbformat.read(nb_path, as_version=4)
        for cell in nb.cells:
            if rename and cell.cell_type == "code" and "def " in cell.source:
                cell.source = _renamed(cell.source)
        nbformat.write(nb, folder / nb_path.name)
    return folder


def test_five_copies_of_the_key_are_one_group_whatever_the_batch_shares(tmp_path, given):
    """Five copies of the whole answer key (two renamed) among honest students: the copies are the
    only code shared by every submission that defines most functions, and still one group."""
    copies = [read_submission(_key_copy(tmp_path / f"copy{k}", rename=k < 2)) for k in range(5)]
    assert copies[0].functions["eightpoint"].source != copies[2].functions["eightpoint"].source  # renamed
    honest = [read_submission(CORPUS / f"{n}.py") for n in ("alice", "bo", "chen", "dana")]
    comps = compare(copies + honest, given)
    names = {s.name for s in copies}
    found = groups(comps)
    assert len(found) == 1 and set(found[0].members) == names, found
    # every function in which the key has enough code of its own flags every pair of the copies,
    # also the functions that only the copies define (there, every line is shared by the whole batch)
    long_enough = [f for f, c in comps.items()
                   if min(len(c.fingerprints[c.names.index(n)].hashes) for n in names) >= 2 * MIN_SHARED]
    assert {"eightpoint", "triangulate", "findM2", "bundleAdjustment"} <= set(long_enough), long_enough
    for f in long_enough:
        assert {(p.a, p.b) for p in comps[f].ranked() if p.flagged} == set(itertools.combinations(sorted(names), 2)), f


def _filled_stubs(folder: Path, answers: Path) -> Path:
    """The student notebooks with each stub's body replaced by the body of ``answers``' definition
    (the stub's def line and docstring kept), as a student who filled the stubs hands them in."""
    theirs = {f.name: f for f in functions_in_source(answers.read_text(), answers.name)}
    folder.mkdir(parents=True)
    filled = 0
    for nb_path in sorted((KIT_ROOT / "notebooks").glob("q*.ipynb")):
        nb = nbformat.read(nb_path, as_version=4)
        for cell in nb.cells:
            if cell.cell_type != "code":
                continue
            try:
                stubs = functions_in_source(cell.source, "stub")
            except SyntaxError:
                continue
            for stub in stubs:
                if stub.name in theirs:
                    node = ast.parse(stub.source).body[0]
                    keep = node.body[0] if ast.get_docstring(node) else None
                    head = stub.source.split("\n")[:(keep.end_lineno if keep else node.body[0].lineno - 1)]
                    body = ast.parse(theirs[stub.name].source).body[0].body
                    lines = theirs[stub.name].source.split("\n")
                    start = body[1 if ast.get_docstring(ast.parse(theirs[stub.name].source).body[0]) else 0].lineno
                    cell.source = cell.source.replace(stub.source, "\n".join(head + lines[start - 1:]))
                    filled += 1
        nbformat.write(nb, folder / nb_path.name)
    assert filled >= 3
    return folder


def test_a_batch_that_only_filled_the_stubs_differently_flags_nothing(tmp_path, given):
    subs = [read_submission(_filled_stubs(tmp_path / n, CORPUS / f"{n}.py")) for n in ("alice", "bo", "chen", "dana")]
    assert all({"eightpoint", "essentialMatrix", "triangulate"} <= set(s.functions) for s in subs)
    comps = compare(subs, given)
    assert sum(len(c.names) for c in comps.values()) >= 12  # their own code was compared, not skipped
    assert groups(comps) == [] and not any(p.flagged for c in comps.values() for p in c.ranked())


def test_command_reports_a_group_once_with_its_members(tmp_path, capsys, command_given):
    paths = [_key_copy(tmp_path / f"c{k}", rename=k == 0) for k in range(4)] + [CORPUS / "alice.py", CORPUS / "bo.py"]
    assert main(["similar", *map(str, paths), "--out", str(tmp_path / "out"), "--top", "1"]) == 0
    data = json.loads((tmp_path / "out" / "similarity.json").read_text())
    assert [g["members"] for g in data["groups"]] == [["c0", "c1", "c2", "c3"]]
    assert "eightpoint" in data["groups"][0]["functions"]
    page = (tmp_path / "out" / "similarity.html").read_text()
    assert "c0, c1, c2, c3" in page
    out = capsys.readouterr().out
    assert "in 1 group(s)" in out and "4: c0, c1, c2, c3" in out  # 6 flagged pairs per function, one group
    # beyond --top 1, the pairs that link the group (3 of its 6), ranked as in the full order
    pairs = data["functions"]["eightpoint"]["pairs"]
    assert len(pairs) == 3 and all(p["flagged"] for p in pairs)
    assert {p["a"] for p in pairs} | {p["b"] for p in pairs} == {"c0", "c1", "c2", "c3"}
    rows = [r for r in csv.DictReader((tmp_path / "out" / "similarity.csv").open()) if r["function"] == "eightpoint"]
    assert [r["rank"] for r in rows] == [str(p["rank"]) for p in pairs] and {r["group"] for r in rows} == {"1"}


def test_similarity_json_shows_the_hidden_characters_of_names_and_notes(tmp_path):
    """A folder and a file named with a bidi override, a zero-width space and an escape sequence:
    every string of similarity.json is as ``core.untrusted.visible`` shows it."""
    from core.untrusted import visible

    name = "al\u202eice\u200b\x1b[2J"
    folder = tmp_path / name
    folder.mkdir()
    (folder / "q2_\u2066answers.py").write_text((CORPUS / "alice.py").read_text())
    (folder / "q3_\u200bbroken.py").write_text("def triangulate(:\n")
    out = tmp_path / "out"
    assert main(["similar", str(folder), str(CORPUS / "bo.py"), "--out", str(out), "--keep-starter"]) == 0
    data = json.loads((out / "similarity.json").read_text())

    def strings(value):
        if isinstance(value, dict):
            return [s for k, v in value.items() for s in [k, *strings(v)]]
        return [s for v in value for s in strings(v)] if isinstance(value, list) else [value]

    texts = [s for s in strings(data) if isinstance(s, str)]
    assert not [s for s in texts if "\x1b" in s or any(unicodedata.category(c) in ("Cc", "Cf") for c in s)]
    assert visible(name) in data["submissions"] and visible(name) in data["notes"]
    assert any("q3_\\u200bbroken.py" in note for note in data["notes"][visible(name)])
