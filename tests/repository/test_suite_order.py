"""The suite's own order: the costliest files first, read from a record of a whole run (conftest)."""

from __future__ import annotations

import json

from conftest import DURATIONS_FILE, costliest_first, recorded_durations, selection_costs


def test_recorded_files_come_costliest_first_and_the_rest_keep_their_order():
    names = ["test_a.py", "test_b.py", "test_c.py", "test_d.py", "test_e.py"]
    assert costliest_first(names, {"test_d.py": 5.0, "test_b.py": 50.0, "test_gone.py": 99.0}) == \
        ["test_b.py", "test_d.py", "test_a.py", "test_c.py", "test_e.py"]
    assert costliest_first(names, {}) == names


def test_a_record_that_cannot_be_read_orders_nothing(tmp_path):
    assert recorded_durations(tmp_path / "missing.json") == {}
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert recorded_durations(bad) == {}
    odd = tmp_path / "odd.json"
    odd.write_text(json.dumps({"test_x.py": 3, "test_y.py": "slow", "test_z.py": 1.5}))
    assert recorded_durations(odd) == {"test_x.py": 3.0, "test_z.py": 1.5}


def test_the_committed_record_names_files_of_this_suite():
    recorded = recorded_durations()
    assert recorded, f"{DURATIONS_FILE.name} is missing or unreadable"
    here = {p.name for p in DURATIONS_FILE.parent.rglob("test_*.py")}
    missing = sorted({name.split("::", 1)[0] for name in recorded} - here)
    assert not missing, f"{DURATIONS_FILE.name} names files the suite no longer has: {missing}"


def test_no_two_test_files_share_a_name():
    """The record, the cost order and pytest's own imports (each folder's files as top-level modules)
    know a test file by its name alone."""
    names = [p.name for p in DURATIONS_FILE.parent.rglob("test_*.py") if "__pycache__" not in p.parts]
    assert len(names) > 50
    assert sorted(n for n in set(names) if names.count(n) > 1) == []


def test_a_selection_costs_what_its_own_tests_recorded():
    record = {"test_a.py": 100.0, "test_a.py::fast": 2.0, "test_a.py::slow": 90.0, "test_b.py": 10.0,
              "test_c.py::t": 1.0}
    # the fast tier of a: its own test, not the file's whole run
    assert selection_costs({"test_a.py": ["test_a.py::fast"]}, record) == {"test_a.py": 2.0}
    # a test the record does not name costs what no named test of its file accounts for (100 - 92)
    assert selection_costs({"test_a.py": ["test_a.py::fast", "test_a.py::new"]}, record) == {"test_a.py": 10.0}
    # files known by their total only, by their tests only, or not at all
    assert selection_costs({"test_b.py": ["test_b.py::x"], "test_c.py": ["test_c.py::t"], "test_d.py": ["test_d.py::u"]},
                           record) == {"test_b.py": 10.0, "test_c.py": 1.0}
    assert costliest_first(["test_d.py", "test_a.py", "test_b.py"], {"test_a.py": 2.0, "test_b.py": 10.0}) == \
        ["test_b.py", "test_a.py", "test_d.py"]
