"""The hidden inputs: made once per batch from the grader's secret config, cached for the grading processes.

``build_hidden_inputs(config)`` makes the hidden scenes and every check's prepared inputs and
reference results.  A batch makes them once and ``save``s them into a folder of the grader's own
(mode 0700, hidden from the sandbox); each grading run (one ``pytest`` session per submission)
``load``s them instead of making them again.  The cache is the grader's own data, written and read
by the grader only, never by the sandbox.
"""

from __future__ import annotations

import os
import pickle
import stat
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from autograder.config import GradingConfig

from .cases import call_seconds, prepare_all
from .scenes import Scenes, make_scenes

__all__ = ["HiddenInputs", "build_hidden_inputs", "load", "save"]

_FILE = "hidden-inputs.pickle"


@dataclass(frozen=True, eq=False)
class HiddenInputs:
    """The config, the scenes and each concept's prepared inputs (``autograder.hidden.cases``), by
    concept name ("fundamental", "essential", ...): never leave the grader."""

    config: GradingConfig
    scenes: Scenes | None
    prepared: dict = field(default_factory=dict)

    def call_seconds(self) -> float:
        """The time every check may give student code, added up (for the session's budget)."""
        return call_seconds(self.prepared, self.config.time_scale)


@lru_cache(maxsize=4)
def build_hidden_inputs(config: GradingConfig) -> HiddenInputs:
    """Make (once per config and process) every hidden input and the reference's results on them."""
    scenes = make_scenes(config)
    return HiddenInputs(config, scenes, prepare_all(scenes))


def save(hidden: HiddenInputs, folder: Path) -> Path:
    """Write ``hidden`` (without the scenes, which the checks do not need) into ``folder``, made 0700."""
    folder = Path(folder)
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    path = folder / _FILE
    tmp = folder / (_FILE + ".tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as fh:
        pickle.dump(HiddenInputs(hidden.config, None, hidden.prepared), fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)
    return path


def load(folder: Path, config: GradingConfig) -> HiddenInputs:
    """The inputs ``save`` wrote into ``folder`` for ``config``.

    Raises
    ------
    ValueError
        When the folder is not the grader's own (owner, mode 0700) or holds inputs of another config.
    """
    folder = Path(folder)
    st = folder.stat()
    if st.st_uid != os.geteuid() or stat.S_IMODE(st.st_mode) & 0o077:
        raise ValueError(f"hidden cache: expected a folder of this user with mode 0700, got {folder} "
                         f"(uid {st.st_uid}, mode {stat.S_IMODE(st.st_mode):o})")
    with open(folder / _FILE, "rb") as fh:
        hidden = pickle.load(fh)  # noqa: S301 - the grader's own file in its own 0700 folder
    if not isinstance(hidden, HiddenInputs) or hidden.config.fingerprint() != config.fingerprint():
        raise ValueError(f"hidden cache: expected inputs of config {config.fingerprint()[:12]}, got others")
    return hidden
