"""The grader's keep (autograder.inputs.keep): what it keeps is what would be made, under a name
that changes with anything it is made from; its folder is the grader's alone and hidden from
student code."""

from __future__ import annotations

import dataclasses
import os
import stat

import numpy as np
import pytest

from autograder.inputs.config import quick_config
from autograder.inputs import build as inputs, keep
from autograder.inputs.keep import ENV_KEEP, Keep
from autograder.grading.run import GradingRun


def _maker(value):
    calls = []

    def make():
        calls.append(1)
        return value

    return make, calls


def test_a_value_is_made_once_then_read_back_from_the_folder(tmp_path):
    folder = tmp_path / "keep"
    make, calls = _maker({"F": np.arange(9.0).reshape(3, 3)})
    first = Keep(folder).fetch(("batch", "abc"), make)
    again = Keep(folder).fetch(("batch", "abc"), make)  # another grader, the same folder
    assert len(calls) == 1 and np.array_equal(first["F"], again["F"]) and first is not again
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    entries = list(folder.iterdir())
    assert len(entries) == 1 and stat.S_IMODE(entries[0].stat().st_mode) == 0o600


def test_each_part_and_the_kits_code_name_another_value(tmp_path, monkeypatch):
    k = Keep(tmp_path / "keep")
    make, calls = _maker(1)
    for parts in (("draw", "fp", "salt-a"), ("draw", "fp", "salt-b"), ("draw", "fp2", "salt-a"), ("batch", "fp")):
        k.fetch(parts, make)
    assert len(calls) == 4
    # The kit's code changed (here: a kit whose one file differs): every value is made again.
    kit = tmp_path / "kit"
    (kit / "core").mkdir(parents=True)
    (kit / "core" / "a.py").write_text("X = 1\n")
    monkeypatch.setattr(keep, "KIT_ROOT", kit)
    monkeypatch.setattr(keep, "GRADER_PACKAGES", ("core",))
    keep.code_digest.cache_clear()
    try:
        k.fetch(("batch", "fp"), make)
        k.fetch(("batch", "fp"), make)
        (kit / "core" / "a.py").write_text("X = 2\n")
        keep.code_digest.cache_clear()
        k.fetch(("batch", "fp"), make)
    finally:
        keep.code_digest.cache_clear()
    assert len(calls) == 6


def test_a_folder_others_may_enter_or_a_file_is_refused(tmp_path):
    open_folder = tmp_path / "open"
    open_folder.mkdir(mode=0o755)
    os.chmod(open_folder, 0o755)
    with pytest.raises(ValueError, match=r"keep: expected a folder of this user .*open.*mode 755"):
        Keep(open_folder)
    a_file = tmp_path / "file"
    a_file.write_text("")
    with pytest.raises(ValueError, match="keep: expected a folder"):
        Keep(a_file)


def test_an_unreadable_entry_is_made_again_and_written_over(tmp_path):
    k = Keep(tmp_path / "keep")
    make, calls = _maker([1, 2, 3])
    k.fetch(("x",), make)
    (entry,) = (tmp_path / "keep").iterdir()
    entry.write_bytes(b"half a file")
    assert k.fetch(("x",), make) == [1, 2, 3] and k.fetch(("x",), make) == [1, 2, 3]
    assert len(calls) == 2


def test_a_run_takes_its_keep_from_the_environment_and_hides_it_from_student_code(tmp_path, monkeypatch):
    monkeypatch.setenv(ENV_KEEP, str(tmp_path / "from-env"))
    with GradingRun(quick_config()) as run:
        assert run.keep.folder == tmp_path / "from-env" and (tmp_path / "from-env").resolve() in run.hide
    monkeypatch.delenv(ENV_KEEP)
    with GradingRun(quick_config(), keep=tmp_path / "given") as run:
        assert run.keep.folder == tmp_path / "given" and (tmp_path / "given").resolve() in run.hide
    with GradingRun(quick_config()) as run:
        assert run.keep is None


def _same(a, b, where="") -> None:
    """Assert ``a`` and ``b`` are equal values: dataclasses, dicts, sequences and arrays, all the way down."""
    assert type(a) is type(b), where
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            _same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            _same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True), where
    else:
        assert a == b or (a != a and b != b), where  # NaN equals NaN here


@pytest.mark.slow
def test_kept_inputs_and_draws_are_those_made_afresh(tmp_path, monkeypatch):
    config = quick_config(secret="the keep's own test")
    fresh_batch = inputs.build_hidden_inputs(config)
    fresh = inputs.draw(fresh_batch, "c" * 32)
    made = inputs.build_hidden_inputs(config, keep=Keep(tmp_path / "keep"), salt="c" * 32)  # made and kept
    # Read back by a grader that could not make them: scenes are not made again.
    monkeypatch.setattr(inputs, "make_scenes", lambda *a, **k: pytest.fail("made again instead of read back"))
    k = Keep(tmp_path / "keep")
    batch = inputs.build_hidden_inputs(config, keep=k)
    kept = inputs.draw(batch, "c" * 32, keep=k)
    _same(batch.prepared, fresh_batch.prepared, "batch")
    for got in (made, kept):
        assert got.draw == fresh.draw and got.config is config and got.scenes is None
        _same(got.prepared, fresh.prepared, "draw")
