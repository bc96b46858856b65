"""What a submission left that could not be removed, and what of its uid outlived the sweep, reach
staff the way the sweep's counts do: grading.json's staff notes -> BatchRecord -> summary.md."""

from __future__ import annotations

from pathlib import Path

from autograder.channels.gradebook import BatchRecord, staff_of, write_summary


def test_staff_notes_carry_what_was_not_removed_and_what_survived():
    staff = {"removed": {"entries": 3001, "bytes": 12 * 2**20,
                         "not_removed": ["/dev/shm/hw4-x/d/d/locked/f (5 levels): Permission denied"]},
             "over_quota": [], "survived": ["uid 60012: 1 processes outlived the sweep (pids 4242)"]}
    got = staff_of(staff)
    assert got["removed"] == (3001, 12 * 2**20)
    assert got["not_removed"] == ("/dev/shm/hw4-x/d/d/locked/f (5 levels): Permission denied",)
    assert got["survived"] == ("uid 60012: 1 processes outlived the sweep (pids 4242)",)
    # Older grading.json files (before these notes) and malformed ones read as nothing to say.
    assert staff_of({"removed": {"entries": 1, "bytes": 2}}) == {
        "removed": (1, 2), "over_quota": (), "not_removed": (), "survived": ()}
    assert staff_of({"removed": {"not_removed": "not a list"}, "survived": 7})["not_removed"] == ()


def test_summary_names_them_for_staff_with_the_code_s_names_escaped(tmp_path):
    left = "/dev/shm/**bold**|<b>/f: Permission denied"
    records = [BatchRecord("alice", Path("alice"), tmp_path / "alice", 90.0, {}, None, False, 1.0, removed=(5, 0),
                           not_removed=(left,), survived=("uid 60012: 1 processes outlived the sweep (pids 4242); "
                                                          "this session's later processes run as uid 60400",)),
               BatchRecord("bob", Path("bob"), tmp_path / "bob", 90.0, {}, None, False, 1.0)]
    text = write_summary(tmp_path / "summary.md", records, {"key": "k"}).read_text()
    assert "## Left by the code and NOT removed (remove by hand)" in text
    assert "## Processes that outlived the sandbox's sweep" in text
    section = text.split("## Left by the code and NOT removed", 1)[1].split("##", 1)[0]
    assert "- alice: " in section and "bob" not in section
    assert "**bold**" not in section and "<b>" not in section  # the code chose that name: escaped
    assert "- alice: uid 60012: 1 processes outlived the sweep (pids 4242)" in text
    quiet = write_summary(tmp_path / "quiet.md", records[1:], {"key": "k"}).read_text()
    assert "NOT removed" not in quiet and "outlived" not in quiet
