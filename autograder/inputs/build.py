"""The hidden inputs: the batch's, made once from the grader's secret config, and each submission's draw.

``build_hidden_inputs(config)`` makes the hidden scenes of the secret and every check's prepared
inputs and reference results: the *batch's* inputs.  A batch makes them once and ``save``s them
into a folder of the grader's own (mode 0700, hidden from the sandbox); each grading run (one
``pytest`` session per submission) ``load``s them instead of making them again.  The cache is the
grader's own data, written and read by the grader only, never by the sandbox.

Each submission is graded on its own *draw* (``draw(batch, salt)``): hidden temples, cars and
the checks' random choices seeded from the secret and ``code_salt(submission)``, a digest of the
code the grader runs, so that a regrade gets the same scenes and another submission other ones
(scenes collected by one submission are worth nothing to the next).  What does not depend on the
submission (the default data, the official data and the reference's results on them) is taken
from the batch's inputs, so a draw costs only what depends on the submission (two temple
renders, the reference on them, about 2 s).  The canary grades the answer key on the batch's
inputs themselves.  ``build_hidden_inputs(config, salt=...)`` is the draw of a salt in one call.
Given a keep (``autograder.inputs.keep``), both are read back when the same kit made them before
under the same settings, and kept when made.

A saved folder describes itself: the inputs hold their ``GradingConfig``, and a grading run saves
its configuration record (``autograder.inputs.config.configuration``) with them, in the same file
(``load_saved``), so a grading session reads the one configuration of its run from one place.
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import json
import os
import pickle
import stat
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from autograder.inputs.config import GradingConfig, data_digest

from .cases import call_seconds, draw_all, prepare_all, with_fixed
from .keep import Keep
from .scenes import Scenes, make_scenes

__all__ = ["SAVED_NAME", "HiddenInputs", "Saved", "build_hidden_inputs", "code_salt", "draw", "load", "load_saved",
           "save"]

SAVED_NAME = "hidden-inputs.pickle"  # the one file ``save`` writes into its folder


@dataclass(frozen=True, eq=False)
class HiddenInputs:
    """The config, the scenes and each concept's prepared inputs (``autograder.inputs.cases``), by
    concept name ("fundamental", "essential", ...): never leave the grader.

    draw : None for the batch's inputs (the secret's own scenes), else the short digest
        (``GradingConfig.draw_digest``) of the submission's draw these are.
    """

    config: GradingConfig
    scenes: Scenes | None
    prepared: dict = field(default_factory=dict)
    draw: str | None = None

    def call_seconds(self) -> float:
        """The time every check may give student code, added up (for the session's budget)."""
        return call_seconds(self.prepared, self.config.time_scale)


@lru_cache(maxsize=4)
def build_hidden_inputs(config: GradingConfig, *, salt: str | None = None, keep: Keep | None = None) -> HiddenInputs:
    """Make (once per config, salt and process) every hidden input and the reference's results on them.

    salt : None (default): the batch's inputs, from the secret alone.  A str (``code_salt`` of a
        submission): that submission's draw (``draw`` of the batch's inputs).
    keep : a ``keep.Keep`` to read them from when they were made before (then without their
        scenes, which only their making needs), and to keep them in when made here.
    """
    if salt is not None:
        return draw(build_hidden_inputs(config, keep=keep), salt, keep=keep)
    if keep is None:
        scenes = make_scenes(config)
        return HiddenInputs(config, scenes, prepare_all(scenes))
    official = config.official_dir()
    parts = ("batch", config.fingerprint(), data_digest(official) if official is not None else "none")
    return HiddenInputs(config, None, keep.fetch(parts, lambda: prepare_all(make_scenes(config))))


def draw(batch: HiddenInputs, salt: str, *, keep: Keep | None = None) -> HiddenInputs:
    """The hidden inputs of the submission whose ``code_salt`` is ``salt``, under ``batch``'s config.

    The hidden temples, the cars and every random choice of the checks are drawn from the secret
    and ``salt``; the default and official data's parts are ``batch``'s.  The result's ``draw``
    names it (a short digest).  With a ``keep`` (``keep.Keep``), what depends on ``salt`` is read
    from it when made before, else made and kept; the result then has no scenes.

    Raises
    ------
    ValueError
        When ``salt`` is not a non-empty str or ``batch`` is itself a draw.
    """
    if not isinstance(salt, str) or not salt:
        raise ValueError(f"salt: expected a non-empty str (code_salt of a submission), got {salt!r}")
    if batch.draw is not None:
        raise ValueError(f"batch: expected the batch's inputs (draw None), got the draw {batch.draw}")
    config = batch.config
    if keep is None:
        scenes = make_scenes(config, salt=salt, fixed=False)
        return HiddenInputs(config, scenes, draw_all(scenes, batch.prepared), config.draw_digest(salt))
    own = keep.fetch(("draw", config.fingerprint(), salt),
                     lambda: prepare_all(make_scenes(config, salt=salt, fixed=False)))
    return HiddenInputs(config, None, with_fixed(own, batch.prepared, config), config.draw_digest(salt))


def code_salt(submission) -> str:
    """A digest (32 hex digits) of the code the grader runs of ``submission``
    (``autograder.submission.read.Submission``): every kept statement of every file read, each as its
    syntax tree (comments, blank lines and layout do not count), sorted (file names, cell
    numbers, notebook metadata and the order of files do not count either).  So the same code
    handed in as a folder, a zip or notebooks rewritten by nbgrader has one salt, and any change
    to what runs (a function body, a helper, a constant) gives another."""
    texts = sorted(_normalised(unit.source) for pf in submission.files.values() if pf.readable
                   for unit in pf.units)
    h = hashlib.sha256(b"hw4-code-salt\x00")
    for text in texts:
        h.update(text.encode("utf-8", "surrogatepass") + b"\x00")
    return h.hexdigest()[:32]


def _normalised(source: str) -> str:
    # The syntax tree without positions: the same statement whatever its layout or comments.
    try:
        return ast.dump(ast.parse(source))
    except (SyntaxError, ValueError):  # kept statements parse; a stray one still counts as text
        return "\n".join(line.rstrip() for line in source.strip().splitlines())


@dataclass(frozen=True, eq=False)
class Saved:
    """What ``save`` wrote into a folder: the inputs (``hidden``, without scenes; their ``config``
    is the configuration they were made under) and the configuration record the results of the
    run are stamped with (``record``: plain JSON, ``autograder.inputs.config.configuration``; None when
    saved without one, as a Gradescope bundle's inputs are)."""

    hidden: HiddenInputs
    record: dict | None = None


def save(hidden: HiddenInputs, folder: Path, *, record: dict | None = None) -> Path:
    """Write ``hidden`` (without the scenes, which the checks do not need) and ``record`` (the run's
    configuration record, taken through JSON as a result carries it) into ``folder``, made 0700:
    one file, so the folder cannot hold a record of one configuration and inputs of another.

    Raises
    ------
    ValueError
        When ``record`` is neither None nor a dict.
    """
    if record is not None and not isinstance(record, dict):
        raise ValueError(f"record: expected a configuration record (dict) or None, got {type(record).__name__}")
    saved = Saved(dataclasses.replace(hidden, scenes=None),
                  json.loads(json.dumps(record, default=str)) if record is not None else None)
    folder = Path(folder)
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    path = folder / SAVED_NAME
    tmp = folder / (SAVED_NAME + ".tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as fh:
        pickle.dump(saved, fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)
    return path


def load_saved(folder: Path) -> Saved:
    """The inputs and record ``save`` wrote into ``folder`` (the configuration is the inputs').

    Raises
    ------
    ValueError
        When the folder is not the grader's own (owner, mode 0700) or its file is not what ``save`` writes.
    """
    folder = Path(folder)
    st = folder.stat()
    if st.st_uid != os.geteuid() or stat.S_IMODE(st.st_mode) & 0o077:
        raise ValueError(f"hidden cache: expected a folder of this user with mode 0700, got {folder} "
                         f"(uid {st.st_uid}, mode {stat.S_IMODE(st.st_mode):o})")
    with open(folder / SAVED_NAME, "rb") as fh:
        saved = pickle.load(fh)  # noqa: S301 - the grader's own file in its own 0700 folder
    if not isinstance(saved, Saved) or not isinstance(saved.hidden, HiddenInputs) or not (
            saved.record is None or isinstance(saved.record, dict)):
        raise ValueError(f"hidden cache: expected the inputs saved by inputs.save in {folder}, "
                         f"got {type(saved).__name__}")
    return saved


def load(folder: Path, config: GradingConfig) -> HiddenInputs:
    """The inputs ``save`` wrote into ``folder`` for ``config``.

    Raises
    ------
    ValueError
        When the folder is not the grader's own (owner, mode 0700), is not what ``save`` writes or
        holds inputs of another config.
    """
    hidden = load_saved(folder).hidden
    if hidden.config.fingerprint() != config.fingerprint():
        raise ValueError(f"hidden cache: expected inputs of config {config.fingerprint()[:12]}, got others")
    return hidden
