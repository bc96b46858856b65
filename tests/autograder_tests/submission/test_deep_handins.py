"""A hand-in holding a folder thousands of levels deep is read like any other.

``os.walk`` and ``Path.rglob`` recurse in Python 3.11, so such a folder raised RecursionError
wherever a submission's files were listed: reading it, its digest (the batch's journal), the
Gradescope run's search for the hand-in, the look-alike check.  Every tree the test makes is removed
by the kit's own remover (pytest's clean-up of old temporary folders recurses too).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import corpus
import nbformat
import pytest

from autograder.sandbox import tree
from core.files import MAX_DEPTH, list_files

DEPTH = 3000

pytestmark = pytest.mark.slow   # thousands of folders made and removed: the full tier's


def _deep(top: Path, depth: int = DEPTH) -> None:
    """A chain of ``depth`` folders named "d" under ``top``, a notebook at its bottom."""
    fd = os.open(top, os.O_RDONLY)
    try:
        for _ in range(depth):
            os.mkdir("d", dir_fd=fd)
            nfd = os.open("d", os.O_RDONLY, dir_fd=fd)
            os.close(fd)
            fd = nfd
        with open(os.open("q2_eightpoint.py", os.O_WRONLY | os.O_CREAT, 0o600, dir_fd=fd), "w") as fh:
            fh.write("def eightpoint(pts1, pts2, M):\n    return None\n")
    finally:
        os.close(fd)


@pytest.fixture
def handin(tmp_path):
    folder = tmp_path / "deep_handin"
    folder.mkdir()
    for name, nb in corpus.notebooks("key").items():
        nbformat.write(nb, folder / f"{name}.ipynb")
    (folder / "nest").mkdir()
    _deep(folder / "nest")
    try:
        yield folder
    finally:
        assert tree.remove(folder / "nest").failures == 0


def test_listing_a_deep_folder_stops_at_its_depth_and_follows_no_link(tmp_path, handin):
    (handin / "link").symlink_to(tmp_path, target_is_directory=True)
    listing = list_files(handin)
    names = [p.relative_to(handin).as_posix() for p, _ in listing.files]
    assert names[:1] and all(n.endswith(".ipynb") for n in names)      # the notebooks; the deep file is past MAX_DEPTH
    assert listing.too_deep == 1 and listing.links == [handin / "link"]
    capped = list_files(handin, max_entries=3)
    assert len(capped.files) + len(capped.links) == 3 and capped.truncated
    # Allowed to go all the way down, the walk neither recurses nor raises: past PATH_MAX a folder
    # cannot be listed by its path, and is counted as unreadable.
    everything = list_files(handin, max_depth=DEPTH + 5)
    assert everything.too_deep == 0 and everything.unreadable == 1
    with pytest.raises(ValueError, match="max_depth"):
        list_files(handin, max_depth=0)
    assert MAX_DEPTH < DEPTH


def test_a_deep_handin_is_read_digested_and_found(handin):
    from autograder.channels.gradescope.run import submission_candidates
    from autograder.channels.journal import submission_digest
    from autograder.review.reader import read_submission
    from autograder.submission.read import load_submission

    assert load_submission(handin).notebooks           # the key's notebooks, read
    assert len(submission_digest(handin)) == 64
    assert {p.suffix for p in submission_candidates(handin)} == {".ipynb"}
    assert read_submission(handin).functions            # the look-alike check reads its functions
