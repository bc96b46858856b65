"""The code zip: what goes into the zip, what is reported missing, and that nothing runs."""

from __future__ import annotations

import zipfile

import nbformat
import numpy as np
import pytest
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook, new_output

from handin.code_zip import build_code_zip, inspect_notebook, select_notebooks, student_name
from core.manifest import NOTEBOOKS, functions_of_notebook


def _implemented(name: str) -> str:
    return f"def {name}(*args):\n    return len(args)\n"


def _stub(name: str) -> str:
    return f'def {name}(*args):\n    """Docstring."""\n    # YOUR CODE HERE\n    raise NotImplementedError()\n'


def write_notebook(folder, stem, *sources, outputs=()):
    """A notebook ``stem.ipynb`` in ``folder`` with one code cell per source."""
    cells = [new_markdown_cell(f"# {stem}")]
    cells += [new_code_cell(src) for src in sources]
    if outputs:
        cells[-1].outputs = list(outputs)
    path = folder / f"{stem}.ipynb"
    nbformat.write(new_notebook(cells=cells), path)
    return path


@pytest.fixture
def complete(tmp_path):
    """A folder with every homework notebook, each defining all of its manifest functions."""
    for stem in NOTEBOOKS:
        write_notebook(tmp_path, stem, "import numpy as np\n%matplotlib inline",
                       *[_implemented(f) for f in functions_of_notebook(stem)])
    return tmp_path


def test_complete_folder_is_ok_and_zips_every_notebook(complete, tmp_path):
    (complete / "helpers.py").write_text("def helper():\n    return 1\n")
    (complete / "points.npz").write_bytes(b"\0" * 2048)
    report = build_code_zip(complete, tmp_path / "out" / "hw4_code.zip")
    assert report.ok, report.warnings
    assert report.warnings == []
    with zipfile.ZipFile(report.zip_path) as zf:
        names = sorted(zf.namelist())
    assert names == sorted([f"{s}.ipynb" for s in NOTEBOOKS] + ["helpers.py"])
    assert report.included == [f"{s}.ipynb" for s in NOTEBOOKS] + ["helpers.py"]


def test_zipped_notebook_is_byte_identical(complete, tmp_path):
    report = build_code_zip(complete, tmp_path / "b.zip")
    with zipfile.ZipFile(report.zip_path) as zf:
        for stem in NOTEBOOKS:
            assert zf.read(f"{stem}.ipynb") == (complete / f"{stem}.ipynb").read_bytes()


def test_missing_function_and_stub_are_reported_not_raised(complete, tmp_path):
    stem = "q3_metric_reconstruction"
    names = functions_of_notebook(stem)
    absent, stubbed, kept = names[0], names[1], names[2:]
    write_notebook(complete, stem, _stub(stubbed), *[_implemented(f) for f in kept])
    report = build_code_zip(complete, tmp_path / "b.zip")
    assert not report.ok
    assert report.missing_functions == {stem: [absent]}
    assert report.stub_functions == {stem: [stubbed]}
    text = "\n".join(report.warnings)
    assert absent in text and stubbed in text and "NotImplementedError" in text
    assert f"{stem}.ipynb" in zipfile.ZipFile(report.zip_path).namelist()


def test_missing_notebook_is_reported(complete, tmp_path):
    gone = NOTEBOOKS[-1]
    (complete / f"{gone}.ipynb").unlink()
    report = build_code_zip(complete, tmp_path / "b.zip")
    assert report.missing_notebooks == [gone]
    assert any(gone in w for w in report.warnings)
    assert f"{gone}.ipynb" not in zipfile.ZipFile(report.zip_path).namelist()


def test_misnamed_copy_is_left_out_with_a_rename_hint(complete, tmp_path):
    stem = NOTEBOOKS[2]
    (complete / f"{stem}.ipynb").rename(complete / f"{stem}-Copy1.ipynb")
    report = build_code_zip(complete, tmp_path / "b.zip")
    assert report.missing_notebooks == [stem]
    reasons = {p.name: why for p, why in report.skipped}
    assert f"rename it {stem}.ipynb" in reasons[f"{stem}-Copy1.ipynb"]


def test_size_cap_flags_an_oversize_zip(complete, tmp_path):
    rng = np.random.default_rng(0)
    noise = rng.integers(0, 2**63, size=40_000).astype(str)  # incompressible text, about 0.7 MB
    write_notebook(complete, NOTEBOOKS[1], *[_implemented(f) for f in functions_of_notebook(NOTEBOOKS[1])],
                   outputs=[new_output("stream", name="stdout", text=" ".join(noise))])
    small = build_code_zip(complete, tmp_path / "small.zip", max_mb=0.25)
    assert small.too_large and not small.ok
    assert small.size_bytes > 0.25 * 2**20
    assert "limit" in small.warnings[0]
    roomy = build_code_zip(complete, tmp_path / "roomy.zip", max_mb=5)
    assert not roomy.too_large and roomy.ok


def test_stray_large_or_foreign_files_are_refused(complete, tmp_path):
    big_helper = complete / "big_helper.py"
    big_helper.write_text("# padding\n" * 40_000)
    data = complete / "frames.npz"
    data.write_bytes(b"\0" * 4096)
    listed = [complete / f"{s}.ipynb" for s in NOTEBOOKS] + [big_helper, data]
    report = build_code_zip(listed, tmp_path / "b.zip")
    names = zipfile.ZipFile(report.zip_path).namelist()
    assert "big_helper.py" not in names and "frames.npz" not in names
    skipped = {p.name: why for p, why in report.skipped}
    assert "KB" in skipped["big_helper.py"] and "frames.npz" in skipped


def test_nothing_is_executed(tmp_path):
    marker = tmp_path / "ran.txt"
    write_notebook(tmp_path, "q2_eightpoint", f"open({str(marker)!r}, 'w').write('x')\n" + _implemented("eightpoint"))
    report = build_code_zip(tmp_path, tmp_path / "b.zip")
    assert not marker.exists()
    assert "q2_eightpoint" not in report.missing_functions


def test_syntax_error_and_bad_json_are_problems_not_crashes(tmp_path):
    write_notebook(tmp_path, "q2_eightpoint", "def eightpoint(:\n    pass")
    (tmp_path / "q4_temple_3d.ipynb").write_text("{not json")
    report = build_code_zip(tmp_path, tmp_path / "b.zip")
    text = "\n".join(report.problems)
    assert "syntax error" in text and "q4_temple_3d.ipynb" in text
    assert report.missing_functions["q2_eightpoint"] == ["eightpoint"]


def test_definitions_count_imports_assignments_and_the_last_definition(tmp_path):
    path = write_notebook(
        tmp_path, "q3_metric_reconstruction",
        "from mysolution import essentialMatrix",
        "triangulate = lambda *a: a",
        _implemented("findM2"), _stub("findM2"))  # redefined as a stub afterwards
    info = inspect_notebook(path)
    assert {"essentialMatrix", "triangulate"} <= info.implemented
    assert "findM2" in info.stubs and "findM2" not in info.implemented


def test_student_name_skips_placeholders(tmp_path):
    a = inspect_notebook(write_notebook(tmp_path, "q1_proofs", 'STUDENT_NAME = "Your Name"'))
    b = inspect_notebook(write_notebook(tmp_path, "q2_eightpoint", 'STUDENT_NAME = "  Ada Lovelace "'))
    assert a.student_name is None
    assert student_name([a, b]) == "Ada Lovelace"


def test_bad_arguments_raise_naming_the_argument(tmp_path):
    with pytest.raises(ValueError, match="folder_or_notebooks"):
        build_code_zip([tmp_path / "nope.ipynb"], tmp_path / "b.zip")
    with pytest.raises(ValueError, match="folder_or_notebooks"):
        build_code_zip(tmp_path, tmp_path / "b.zip")  # empty folder
    write_notebook(tmp_path, "q2_eightpoint")
    with pytest.raises(ValueError, match="max_mb"):
        build_code_zip(tmp_path, tmp_path / "b.zip", max_mb=0)


def test_explicit_list_keeps_manifest_order_then_extras(tmp_path):
    extra = write_notebook(tmp_path, "scratch")
    q3 = write_notebook(tmp_path, "q3_metric_reconstruction")
    q2 = write_notebook(tmp_path, "q2_eightpoint")
    sel = select_notebooks([extra, q3, q2])
    assert sel.notebooks == [q2, q3, extra]
    with pytest.raises(ValueError, match="one notebook per stem"):
        select_notebooks([q2, q2])
