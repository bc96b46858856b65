"""Where things are: the kit's own folders, its data folder, and the official course data.

The rules live here once: the data folder is ``root`` when given, else ``$HW4_DATA``, else the
kit's data/; the official course data is ``$HW4_COURSE_DATA``, else ``../shared/course-data``
beside the kit, and it is used only where a caller asks for it.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["KIT_ROOT", "DATA_DIR", "NOTEBOOKS_DIR", "RESULT_FOLDERS", "data_root", "course_data_dir"]

KIT_ROOT = Path(__file__).resolve().parents[1]
DATA_DIR = KIT_ROOT / "data"
NOTEBOOKS_DIR = KIT_ROOT / "notebooks"
# The folders, relative to where a student's code runs, that the handouts told it to save its
# results into (2018-2021 `results/`, 2022-2024 `result/`, and `data/`: the course's drivers ran
# from python/ and saved beside the data, `np.savez('../data/q2_1.npz', ...)`): the grader's
# sandbox makes them in the child's throw-away scratch (``autograder.sandbox.script.RESULT_DIRS``,
# and their `../` twins), and a self-check that meets a function writing into a missing one makes
# it and calls again (``starter.checks.report.call``).
RESULT_FOLDERS = ("results", "result", "data")

ENV_DATA = "HW4_DATA"
ENV_COURSE_DATA = "HW4_COURSE_DATA"


def data_root(root: str | os.PathLike | None = None) -> Path:
    """The data folder: ``root`` if given, else $HW4_DATA, else the kit's data/.

    Raises FileNotFoundError naming the folder when it is not a directory.
    """
    if root is None:
        root = os.environ.get(ENV_DATA) or DATA_DIR
    path = Path(root).expanduser()
    if not path.is_dir():
        raise FileNotFoundError(f"root: expected a data folder, but {path} is not a directory")
    return path


def course_data_dir() -> Path | None:
    """The official course data folder ($HW4_COURSE_DATA, else ../shared/course-data), or None when absent."""
    env = os.environ.get(ENV_COURSE_DATA)
    path = Path(env).expanduser() if env else KIT_ROOT.parent / "shared" / "course-data"
    return path if (path / "temple").is_dir() or (path / "q6").is_dir() else None
