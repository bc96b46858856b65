"""Which hidden test files grade a question: a test that looks at one question runs only those.

Read from the files' ``points`` markers (``question="Q2"``), so a question moved to another file
is followed without a table to keep.
"""

from __future__ import annotations

import re
from pathlib import Path

from autograder.hidden.plugin import HIDDEN_DIR

__all__ = ["files_grading", "questions_graded"]


def questions_graded(text: str) -> frozenset[str]:
    """The questions the checks of a hidden test file's ``text`` count for."""
    return frozenset(re.findall(r'question="(Q[\d.]+)"', text))


def files_grading(*qids: str) -> list[Path]:
    """The hidden test files (autograder/hidden/test_*.py) with a check counting for one of ``qids``."""
    found = [p for p in sorted(HIDDEN_DIR.glob("test_*.py")) if questions_graded(p.read_text()) & set(qids)]
    if not found:
        raise ValueError(f"qids: expected questions a hidden test file grades, got {qids}")
    return found
