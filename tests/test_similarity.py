"""Look-alike code: planted copies rank above every independent pair; textbook solutions are not flagged."""

from __future__ import annotations

import itertools
import json
import zipfile
from pathlib import Path

import nbformat
import pytest

from autograder.review.__main__ import main
from autograder.review.fingerprint import fingerprint_function
from autograder.review.reader import SubmissionCode, functions_in_source, read_submission
from autograder.review.similarity import FLAG, compare
from tests.corpus import variants

CORPUS = Path(__file__).parent / "review_corpus"
KIT = Path(__file__).resolve().parents[1]

# (function, a, b): the planted copies, see tests/review_corpus/README.md
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
def comparisons(tmp_path_factory):
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
    subs.append(read_submission(KIT / "notebooks" / "key", name="key"))
    for name, src in KIT_STUDENTS.items():
        subs.append(SubmissionCode(name, {f.name: f for f in functions_in_source(src, name)}))
    assert {s.name for s in subs} >= {"alice", "copy_mixed", "eve", "key"}
    for s in subs[:-len(KIT_STUDENTS)]:
        assert s.name == "copy_mixed" or {"eightpoint", "essentialMatrix", "triangulate"} <= set(s.functions), s
    return compare(subs, functions=list(PLANTED))


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


def test_identical_one_liners_are_too_short_to_flag():
    one = "def essentialMatrix(F, K1, K2):\n    return K2.T @ F @ K1\n"
    subs = [SubmissionCode(n, {f.name: f for f in functions_in_source(one, n)}) for n in ("s1", "s2")]
    comp = compare(subs, functions=["essentialMatrix"])["essentialMatrix"]
    assert comp.jaccard[0, 1] == pytest.approx(1.0)
    assert all(not p.flagged for p in comp.ranked())


def test_the_untouched_stubs_have_no_code_of_their_own(tmp_path):
    subs = [read_submission(KIT / "notebooks", name=n) for n in ("stub1", "stub2")]
    comps = compare(subs)
    for comp in comps.values():
        assert comp.names == [] and comp.skipped == ["stub1", "stub2"]


def test_command_writes_ranked_csv_json_and_an_offline_page(tmp_path):
    out = tmp_path / "out"
    code = main(["similar", *map(str, sorted(CORPUS.glob("*.py"))), str(KIT / "notebooks" / "key"), "--out", str(out)])
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
