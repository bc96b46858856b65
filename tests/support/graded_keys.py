"""What a graded answer key must show after a student's leak or attack: full marks, and nothing
of the sandbox's uid left in the shared temporary folders.
"""

from __future__ import annotations

import os
from pathlib import Path

import corpus
import nbformat
from autograder.feedback.results import autograded_question_ids
from core.manifest import question


SHARED = ("/tmp", "/var/tmp", "/dev/shm", "/run/lock")


def owned_by(uids: set[int]) -> list[str]:
    """The entries of the shared temporary folders' top level owned by one of ``uids`` (links not
    followed).  Only the top level is looked at: the sandbox's group may create nothing deeper in
    them (/tmp, /var/tmp and /run/lock let it only pass through), and the test must not walk what
    other users of the machine keep there (a folder thousands of levels deep, say)."""
    found = []
    for root in SHARED:
        try:
            entries = list(os.scandir(root))
        except OSError:
            continue
        for entry in entries:
            try:
                if entry.stat(follow_symlinks=False).st_uid in uids:
                    found.append(entry.path)
            except OSError:
                pass
    return found


def key_with(folder: Path, stem: str, cell: str, base: str = "key") -> Path:
    """The answer key (or the student notebooks) with ``cell`` appended to notebook ``stem``."""
    nbs = corpus.notebooks(base)
    corpus.append_cell(nbs, stem, cell)
    folder.mkdir(parents=True)
    for name, nb in nbs.items():
        nbformat.write(nb, folder / f"{name}.ipynb")
    return folder


def full_marks(scores: dict) -> list[str]:
    """The autograded questions of ``scores`` below full marks."""
    return [q for q in autograded_question_ids() if scores.get(q, 0) < question(q).points - 1e-9]
