"""The output folder of a batch: its lock, its configuration, the journal of what is in flight, each
submission's outputs and state.

``<out>/<name>/results.json`` (Gradescope's schema), ``feedback.md``, ``feedback.html`` with
``figures/`` (``autograder.feedback.page``: the pictures of the public data), ``grading.json`` (for
staff; written last, so its presence with a matching digest marks the work as done),
``<out>/configuration.json`` (the folder's one configuration), ``<out>/.inflight/<name>.json``
(written before a submission starts, removed once its results are written) and ``<out>/.lock``.
Nothing here grades: ``autograder.channels.batch`` schedules, ``autograder.grading.run`` grades.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import re
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

from core.files import list_files
from core.text import write_atomic

from autograder.feedback import page as feedback_page
from autograder.inputs.config import configuration_changes
from .gradebook import read_state
from autograder.feedback.results import SubmissionResult

__all__ = ["CONFIG_FILE", "DEATHS_TO_FAIL", "JOURNAL", "ConfigurationMismatch", "Journal", "check_folder",
           "folder_configuration", "lock", "resumable", "state_of", "submission_digest", "submission_name",
           "unique_names", "write_configuration", "write_outputs"]

JOURNAL = ".inflight"
CONFIG_FILE = "configuration.json"
DEATHS_TO_FAIL = 2          # grader deaths with a submission in flight before it is recorded as failed
_INTERNAL = "because of an internal error"


class ConfigurationMismatch(ValueError):
    """The output folder holds results of another grading configuration."""


def submission_name(path: Path) -> str:
    """The gradebook name of a submission: its file name without .zip, made safe for a folder."""
    name = path.name[:-4] if path.name.lower().endswith(".zip") else path.name
    return re.sub(r"[^A-Za-z0-9_.@+-]", "_", name).strip(".") or "submission"


def submission_digest(path: Path) -> str:
    """SHA-256 of a submission's content (a file's bytes, or a folder's relative paths and bytes).

    A path is hashed as the bytes the file system holds (``os.fsencode``): a name that is not
    UTF-8 is still a name, and the same bytes as before for one that is.
    """
    h = hashlib.sha256()
    path = Path(path)
    if path.is_dir():
        # Listed without recursion (a deep folder must not stop the batch), in sorted path order.
        for p in sorted(p for p, _ in list_files(path).files):
            h.update(os.fsencode(p.relative_to(path).as_posix()) + b"\0")
            h.update(hashlib.sha256(p.read_bytes()).digest())
    elif path.is_file():
        with open(path, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
    else:
        h.update(b"missing")
    return h.hexdigest()


def unique_names(paths: Sequence[Path]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for p in paths:
        base = submission_name(p)
        k = seen.get(base, 0)
        seen[base] = k + 1
        out.append(base if k == 0 else f"{base}-{k + 1}")
    return out


def _state_path(folder: Path) -> Path:
    return folder / "grading.json"


def resumable(folder: Path, digest: str, key: str) -> dict | None:
    """The state of a finished, successful grading of this content under this configuration, else None.

    A failure or an internal error is not finished (it is graded again), except a submission
    recorded as failed because the grader died with it twice (``poison``): only naming it grades it.
    """
    state = read_state(folder)
    if state is None or not (folder / "results.json").is_file():
        return None
    if state.get("sha256") != digest or state.get("configuration_key") != key:
        return None
    if state.get("poison"):
        return state
    if state.get("failure") or state.get("internal_errors"):
        return None
    return state


def write_outputs(folder: Path, result: SubmissionResult, state: dict, figures: Mapping | None = None) -> None:
    """results.json, feedback.md, feedback.html with ``figures`` (``autograder.feedback.pictures.figures_of``:
    the pictures of the public data, none when not drawn) and figures/, then grading.json."""
    folder.mkdir(parents=True, exist_ok=True)
    result.write_gradescope(folder / "results.json")
    write_atomic(folder / "feedback.md", result.feedback_markdown())
    feedback_page.write(folder, result, figures or {})  # feedback.html and figures/: the public data's pictures
    # grading.json last: its presence with a matching digest is what marks the work as done.
    write_atomic(_state_path(folder), json.dumps(state, indent=2, allow_nan=False, default=str))


def state_of(result: SubmissionResult, path: Path, digest: str, staff: dict, *, poison: bool = False) -> dict:
    config = result.configuration or {}
    internal = sum(_INTERNAL in t.feedback for q in result.questions for t in q.tests)
    return {
        "student_id": result.student_id, "path": str(path), "sha256": digest,
        "configuration_key": config.get("key"), "fingerprint": config.get("key"),
        "grader_version": config.get("grader_version"), "score": result.score, "max_score": result.max_score,
        "scores": {q.id: q.score for q in result.questions},
        "tests": [{"question": q.id, "name": t.name, "score": t.score, "max_score": t.max_score}
                  for q in result.questions for t in q.tests],
        "failure": result.failure, "internal_errors": internal + bool(staff.get("internal_error")),
        "poison": poison, "seconds": result.execution_time, "isolation": result.isolation,
        "configuration": config, "staff": staff,
    }


def lock(out: Path) -> int:
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise RuntimeError(f"out: another grader is writing into {out}; wait for it or use another --out") from None
    return fd


def folder_configuration(out: Path) -> dict | None:
    """The configuration the results in ``out`` were graded with (``configuration.json``, else the
    first result that records one; ``{}`` for results that record none; None for an empty folder)."""
    try:
        data = json.loads((Path(out) / CONFIG_FILE).read_text(encoding="utf-8"))
        if isinstance(data, dict) and isinstance(data.get("configuration"), dict):
            return data["configuration"]
    except (OSError, ValueError):
        pass
    for state_file in sorted(Path(out).glob("*/grading.json")):
        state = read_state(state_file.parent)
        if state is not None:
            return state.get("configuration") or {}
    return None


def check_folder(out: Path, record: dict, regrade_all: bool, stamp: str) -> str:
    """Refuse another configuration's folder (or, with ``regrade_all``, move its results aside)."""
    found = folder_configuration(out)
    if found is None or found.get("key") == record["key"] or not any(out.glob("*/grading.json")):
        return ""
    why = configuration_changes(found, record) or ["the configuration key differs"]
    if not regrade_all:
        raise ConfigurationMismatch(
            f"out: {out} holds results graded with another configuration ({'; '.join(why)}); refusing to mix "
            f"them in one grades.csv. Use --regrade-all to regrade the whole class into it (its results are "
            f"kept in {out}/.superseded-<time>/), a new --out, or --regrade-into NEW_DIR for a regrade with a "
            f"diff (python -m autograder accept NEW_DIR --into {out} publishes it).")
    aside = out / f".superseded-{stamp}"
    aside.mkdir()
    for state_file in sorted(out.glob("*/grading.json")):
        os.rename(state_file.parent, aside / state_file.parent.name)
    for name in ("grades.csv", "summary.md", CONFIG_FILE):
        if (out / name).exists():
            os.rename(out / name, aside / name)
    return f"Earlier results of another configuration ({'; '.join(why)}) were moved to {aside}."


def write_configuration(out: Path, record: dict, levels: set) -> None:
    data = {"configuration": {**record, "isolation": None}, "isolation_levels": sorted(levels),
            "dev_secret": record.get("dev_secret"), "written": time.strftime("%Y-%m-%d %H:%M:%S")}
    write_atomic(out / CONFIG_FILE, json.dumps(data, indent=2, default=str))


class Journal:
    """``<out>/.inflight/<name>.json`` per submission in flight: ``{name, sha256, key, attempts, pid}``."""

    def __init__(self, out: Path):
        self.folder = out / JOURNAL
        self.folder.mkdir(exist_ok=True)
        self.left: dict[str, dict] = {}
        for p in sorted(self.folder.glob("*.json")):
            try:
                entry = json.loads(p.read_text(encoding="utf-8"))
                self.left[str(entry["name"])] = entry
            except (OSError, ValueError, KeyError, TypeError):
                p.unlink(missing_ok=True)

    def deaths(self, name: str, digest: str, key: str) -> int:
        """How many graders died with this content in flight under this configuration."""
        entry = self.left.get(name)
        if entry is None or entry.get("sha256") != digest or entry.get("key") != key:
            return 0
        return int(entry.get("attempts", 1))

    def start(self, name: str, digest: str, key: str, attempts: int) -> None:
        entry = {"name": name, "sha256": digest, "key": key, "attempts": attempts, "pid": os.getpid(),
                 "started": time.time()}
        write_atomic(self.folder / f"{name}.json", json.dumps(entry))

    def clear(self, name: str) -> None:
        (self.folder / f"{name}.json").unlink(missing_ok=True)
