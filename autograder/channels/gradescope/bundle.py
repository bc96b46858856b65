"""Gradescope's autograder bundle: build the zip, and grade one submission inside it.

``python -m autograder gradescope --out autograder.zip``
    Builds the zip an instructor uploads to Gradescope.  Gradescope unpacks it into
    ``/autograder/source``, runs ``setup.sh`` once to make its image, then ``run_autograder`` for
    every submission.
``python -m autograder gradescope run [--root /autograder]``
    What ``run_autograder`` calls (``autograder.channels.gradescope.run``; this module only builds): grades ``<root>/submission`` with a ``GradingRun`` (the
    same code as ``python -m autograder grade``; student code runs in the sandbox under a uid of
    its own) and writes ``<root>/results/results.json``.  Any failure still writes a valid
    result worth zero that says why; ``run_autograder`` adds a shell-level fallback for when
    Python itself cannot run.

Contents of the zip (paths relative to /autograder/source):

====================================  ==========================================================
``setup.sh``, ``run_autograder``      from ``autograder/channels/gradescope/assets/``, ``@FIELDS@`` filled
``requirements.txt``                  the kit's (what setup.sh installs)
``autograder/`` ``solutions/``        the packages of ``core.shipping.GRADER_PACKAGES``, whole,
``core/`` ``starter/`` ``scenes/``    without ``__pycache__``
``judging/``
``data/``                             the kit's default data (generated when the kit's is empty)
``grader_config.json``                the instructor's grading settings at build time, with the
                                      secret all hidden seeds derive from (``autograder.inputs.config``)
``hidden_inputs/``                    the hidden inputs made at build time from that config
                                      (``autograder.inputs.build.save``), with the answer key's
                                      draw, so that a container makes only the submission's own
                                      draw (about a second)
``answer_key.zip``                    the answer-key submission (``autograder.grading.key``), graded by
                                      the canary before every submission (a container has
                                      neither kit/ nor notebooks/key to make it)
``BUNDLE.json``                       what was built, when, with which limits and visibility
                                      (no secrets)
====================================  ==========================================================

Time limits are CPU seconds fitted to the container.  Each check's designed limit (``time_scale``
1 of the grading settings) is multiplied by ``time_factor`` (default 0.1: the answer key needs
well under a tenth of any designed limit) and by the container's measured slowness: before
grading, a fixed single-threaded loop (``calibration``) is timed against this kit's reference
machine, in CPU seconds (slower cores get more CPU seconds) and in wall-clock seconds (their
ratio is the share of a CPU the container gives: 0.5 at 0.5 vCPU).  The sandbox counts each call's
limit on the CPU clock (``ResourceLimits(clock="cpu")``): a call that computes is stopped by the
child itself when its CPU seconds run out, however slow or shared the container, and a call
that waits instead (sleep) is killed at ``wall_factor`` times its limit in wall-clock seconds
(``wall_factor`` = 1.5 / share, at least 2).  A submission whose every function hangs then costs
each function one short limit (about 50 s in all at full speed, under 120 s at 0.5 vCPU) instead
of the designed minutes.

The canary: before the submission, the answer key shipped in the bundle is graded in the very
sandbox and configuration the submission gets (``autograder.grading.canary``).  If it loses a point, the
environment is broken (a package missing, limits too tight for this container...): nothing is
graded, and results.json says that the autograder is broken, not the submission, with score 0
and the reason for staff in ``extra_data.canary`` and the log.

What students see (Gradescope's test visibility, per group, set at build time with
``--visibility GROUP=WHEN``; WHEN is visible, after_due_date, after_published or hidden):

- ``scores``: one test per question with its points (default **visible**: students see their
  points per question and the total at once);
- ``checks``: one test per hidden check with its feedback, no points (default
  **after_published**: the details of what failed, which describe the hidden inputs' outcomes,
  reach students only when the staff publish the grades).  A check the grader marks hidden stays
  hidden whatever the group says.

- pictures: after each question's tests, one unscored test with the picture of what the student's
  functions returned on the public data (``autograder.channels.gradescope.pictures``: html output, the
  figure as a ``data:`` image), shown no earlier than any test of its question; a bundle built
  with ``--no-pictures`` has none.

The summary always shows the base points and the extra credit apart ("Base points: 75 / 75",
"Extra credit: 15 / 15"); Gradescope's total is the top-level score, extra credit included.

Never included: ``tests/``, ``notebooks/`` (the answer key), ``benchmarks/``, the official course
data, version-control and build leftovers.  Gradescope students never see the bundle; what they
see is results.json, which carries the grader's feedback and never the hidden inputs.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import stat
import sys
import tempfile
import time
import zipfile
from pathlib import Path

from core.paths import KIT_ROOT
from core.shipping import GRADER_PACKAGES

from autograder.channels.shipping import data_files, grader_files

from .run import (
    BROKEN,
    CONFIG_NAME,
    DEFAULT_TIME_FACTOR,
    DEFAULT_VISIBILITY,
    HIDDEN_INPUTS_DIR,
    KEY_NAME,
    REFERENCE_CALIBRATION,
    calibrate,
    calibration,
    check_visibility,
    clock_settings,
    grade_gradescope,
    limits_scale,
)

__all__ = [
    "ASSETS",
    "CONFIG_NAME",
    "DEFAULT_TIME_FACTOR",
    "DEFAULT_TIME_LIMIT",
    "DEFAULT_VENV",
    "DEFAULT_VISIBILITY",
    "REFERENCE_CALIBRATION",
    "BROKEN",
    "HIDDEN_INPUTS_DIR",
    "KEY_NAME",
    "KIT_ROOT",
    "PACKAGES",
    "add_cli",
    "build_bundle",
    "calibrate",
    "calibration",
    "clock_settings",
    "config_file",
    "grade_gradescope",
    "limits_scale",
    "render_asset",
]

ASSETS = Path(__file__).resolve().with_name("assets")
PACKAGES = GRADER_PACKAGES  # which packages ship: core.shipping, the kit's one table
DEFAULT_TIME_LIMIT = 540   # seconds: below Gradescope's default 10-minute limit, room for the fallback
DEFAULT_VENV = "/opt/hw4-venv"
_SCRIPTS = ("setup.sh", "run_autograder")
# 1980-01-01: the earliest time a zip can hold; a fixed date makes the zip reproducible.
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


# ------------------------------------------------------------------------------------------------
# what a grading environment needs


def render_asset(name: str, *, time_limit: int = DEFAULT_TIME_LIMIT, venv: str = DEFAULT_VENV) -> str:
    """The text of ``assets/<name>`` with its ``@FIELDS@`` filled in.

    Raises
    ------
    ValueError
        For an unknown asset, a time limit that is not a positive int, a venv that is not an
        absolute path of plain characters, or a field left unfilled.
    """
    if name not in _SCRIPTS:
        raise ValueError(f"name: expected one of {_SCRIPTS}, got {name!r}")
    if isinstance(time_limit, bool) or not isinstance(time_limit, int) or time_limit <= 0:
        raise ValueError(f"time_limit: expected a positive number of seconds (int), got {time_limit!r}")
    if not (venv.startswith("/") and all(c.isalnum() or c in "/._-" for c in venv)):
        raise ValueError(f"venv: expected an absolute path of letters, digits and /._-, got {venv!r}")
    text = (ASSETS / name).read_text(encoding="utf-8")
    text = text.replace("@TIME_LIMIT@", str(time_limit)).replace("@VENV@", venv)
    if re.search(r"@[A-Z_]+@", text):
        raise ValueError(f"name: {name} still has an unfilled @FIELD@")
    return text


# ------------------------------------------------------------------------------------------------
# building the zip


def config_file(scratch: Path, *, allow_dev_secret: bool = False) -> list[tuple[str, Path]]:
    """The instructor's grading settings as found now (``autograder.inputs.config.load_config``), written
    to ``scratch/grader_config.json``: ``[("grader_config.json", path)]``.

    The secret every hidden seed derives from goes in; the official data folder does not (it is a
    path of this machine, and that data is never shipped).

    Raises
    ------
    ValueError
        When the settings use the public development secret and ``allow_dev_secret`` is False:
        grading with it would test students on scenes anyone can regenerate.
    """
    from autograder.inputs.config import ENV_CONFIG, ENV_SECRET, load_config

    config = load_config()
    if config.is_dev and not allow_dev_secret:
        raise ValueError(f"secret: expected the course's own grading secret (set {ENV_SECRET}, or "
                         f"{ENV_CONFIG} to a config file), got the public development secret")
    data = {"comment": "hw4 grader settings, copied at build time; keep private"}
    data.update({f.name: getattr(config, f.name) for f in dataclasses.fields(config)
                 if f.name not in ("source", "official_data")})
    data["temples"] = [dataclasses.asdict(t) for t in config.temples]
    path = scratch / CONFIG_NAME
    path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    copied = load_config(path, environ={})
    if dataclasses.replace(copied, source=None) != dataclasses.replace(config, source=None, official_data=None):
        raise ValueError(f"config: the settings written to {CONFIG_NAME} do not read back as the instructor's")
    return [(CONFIG_NAME, path)]


def key_file(scratch: Path) -> list[tuple[str, Path]]:
    """The answer-key submission (``autograder.grading.key``, owner-only) written under ``scratch/key``,
    as the bundle's ``KEY_NAME``: what the canary grades on Gradescope."""
    from autograder.grading.key import write_key_submission

    return [(KEY_NAME, write_key_submission(scratch / "key", zip_it=True))]


def hidden_inputs_file(scratch: Path) -> list[tuple[str, Path]]:
    """The hidden inputs of ``scratch/grader_config.json`` (written by ``config_file``), made now and
    saved by ``autograder.inputs.build.save`` under ``scratch/hidden_inputs``: the bundle's members
    (the canary grades the key on them; each submission's draw is made in its container)."""
    from autograder.inputs.config import load_config
    from autograder.inputs import build as inputs
    from autograder.inputs.keep import default_keep

    config = load_config(scratch / CONFIG_NAME, environ={})
    folder = scratch / HIDDEN_INPUTS_DIR
    # Read from the staff's keep ($HW4_KEEP_INPUTS) when these settings were made before: the
    # bundle holds no scenes, only what the checks read.
    hidden = inputs.build_hidden_inputs(config, keep=default_keep())
    inputs.save(hidden, folder)
    return [(f"{HIDDEN_INPUTS_DIR}/{p.name}", p) for p in sorted(folder.iterdir()) if p.is_file()]


def _is_dev(scratch: Path) -> bool:
    """Whether the configuration written into ``scratch`` grades with the public development secret."""
    from autograder.inputs.config import load_config

    return load_config(scratch / CONFIG_NAME, environ={}).is_dev


def build_bundle(out: str | Path, *, kit_root: str | Path = KIT_ROOT, time_limit: int = DEFAULT_TIME_LIMIT,
                 venv: str = DEFAULT_VENV, allow_dev_secret: bool = False, visibility: dict | None = None,
                 time_factor: float = DEFAULT_TIME_FACTOR, pictures: bool = True) -> Path:
    """Write Gradescope's autograder zip to ``out`` and return its path.

    Parameters
    ----------
    out : path of the zip to write (its folder must exist); replaced atomically.
    kit_root : the kit to take the grader from (default: this one).
    time_limit : seconds ``run_autograder`` lets grading run before writing a zero that says so.
        Keep it below the autograder timeout set on Gradescope.
    venv : where ``setup.sh`` makes the virtual environment on Gradescope's image.
    allow_dev_secret : build with the public development secret (for trying the bundle out only).
    visibility : ``{"scores": WHEN, "checks": WHEN}``, Gradescope's visibility of each group of
        tests (module docstring); missing groups take ``DEFAULT_VISIBILITY``.
    time_factor : the share of each check's designed time limit a call gets at the reference
        speed (scaled on Gradescope by the container's measured slowness).
    pictures : after each question's tests, the unscored picture of what the student's functions
        did on the public data (a few seconds a submission); False: text feedback only.

    Raises
    ------
    ValueError, FileNotFoundError
        For bad arguments, a kit missing a package, an ``out`` whose folder does not exist, or
        the development secret without ``allow_dev_secret`` (see ``config_file``).
    """
    out = Path(out)
    if out.suffix.lower() != ".zip":
        raise ValueError(f"out: expected a path ending in .zip, got {str(out)!r}")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"out: expected an existing folder for {out}, got none at {out.parent}")
    if isinstance(time_factor, bool) or not isinstance(time_factor, (int, float)) or not 0 < time_factor <= 10:
        raise ValueError(f"time_factor: expected a number in (0, 10], got {time_factor!r}")
    shown = check_visibility(visibility)
    root = Path(kit_root).resolve()
    scripts = {name: render_asset(name, time_limit=time_limit, venv=venv) for name in _SCRIPTS}
    with tempfile.TemporaryDirectory(prefix="hw4-gradescope-") as tmp:
        scratch = Path(tmp)
        members = grader_files(root) + data_files(root, scratch) + config_file(scratch, allow_dev_secret=allow_dev_secret)
        members += hidden_inputs_file(scratch) + key_file(scratch)
        names = [n for n, _ in members]
        if len(set(names)) != len(names) or set(names) & set(_SCRIPTS):
            raise ValueError(f"kit_root: two bundle files would share a path: {sorted(names)}")
        info = {"built": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "time_limit": time_limit, "venv": venv,
                "python_built_with": sys.version.split()[0], "files": len(members) + len(_SCRIPTS) + 1,
                "development_secret": allow_dev_secret and _is_dev(scratch), "visibility": shown,
                "time_factor": float(time_factor), "pictures": bool(pictures),
                "reference_calibration": REFERENCE_CALIBRATION}
        fd, partial = tempfile.mkstemp(dir=out.parent, prefix=".autograder-", suffix=".zip")
        os.close(fd)
        try:
            with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED) as zf:
                for name, text in scripts.items():
                    _add(zf, name, text.encode("utf-8"), executable=True)
                _add(zf, "BUNDLE.json", (json.dumps(info, indent=2) + "\n").encode("utf-8"))
                for name, path in sorted(members):
                    _add(zf, name, path.read_bytes(), private=name == KEY_NAME)
            os.replace(partial, out)
        except BaseException:
            Path(partial).unlink(missing_ok=True)
            raise
    return out


def _add(zf: zipfile.ZipFile, name: str, data: bytes, *, executable: bool = False, private: bool = False) -> None:
    info = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
    info.compress_type = zipfile.ZIP_DEFLATED
    mode = 0o755 if executable else 0o600 if private else 0o644
    info.external_attr = (stat.S_IFREG | mode) << 16
    info.create_system = 3  # Unix, so that unzip restores the modes
    zf.writestr(info, data)


# ------------------------------------------------------------------------------------------------
# command line


def _cli(args) -> int:
    if args.action == "run":
        result = grade_gradescope(args.root)
        print(f"graded: {result.score:g} points (base total {result.max_score:g}, extra credit on top)"
              + (f"; not graded: {result.failure}" if result.failure else ""))
        return 0
    if args.out is None:
        raise ValueError("--out: expected the path of the zip to write, got none")
    visibility = {}
    for item in args.visibility or ():
        group, _, when = item.partition("=")
        visibility[group.strip()] = when.strip()
    path = build_bundle(args.out, time_limit=args.time_limit, venv=args.venv, allow_dev_secret=args.allow_dev_secret,
                        visibility=visibility, time_factor=args.time_factor, pictures=not args.no_pictures)
    if args.allow_dev_secret:
        print("warning: this bundle may grade with the public development secret: try it out, do not grade with it")
    print(f"wrote {path} ({path.stat().st_size / 2**20:.1f} MB): upload it as the Gradescope autograder")
    return 0


def add_cli(subparsers) -> None:
    """Register ``python -m autograder gradescope`` (build) and ``gradescope run`` (grade)."""
    p = subparsers.add_parser(
        "gradescope", help="build Gradescope's autograder zip (or, on Gradescope, grade one submission)",
        description="Build the autograder zip to upload to Gradescope.  `gradescope run` is what the "
                    "zip's run_autograder calls on Gradescope.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default=None, help="path of the zip to write, e.g. autograder.zip")
    p.add_argument("--time-limit", type=int, default=DEFAULT_TIME_LIMIT,
                   help=f"seconds grading may run on Gradescope before a zero that says so (default {DEFAULT_TIME_LIMIT}); "
                        "keep it below the autograder timeout set on Gradescope")
    p.add_argument("--venv", default=DEFAULT_VENV, help=f"virtual environment setup.sh makes (default {DEFAULT_VENV})")
    p.add_argument("--allow-dev-secret", action="store_true",
                   help="build even without the course's grading secret (HW4_GRADER_SECRET / HW4_GRADER_CONFIG); "
                        "for trying the bundle out only")
    p.add_argument("--visibility", nargs="+", metavar="GROUP=WHEN", default=None,
                   help="Gradescope visibility of a group of tests: scores (one test per question, default "
                        "visible) or checks (each check's feedback, default after_published); WHEN is visible, "
                        "after_due_date, after_published or hidden")
    p.add_argument("--time-factor", type=float, default=DEFAULT_TIME_FACTOR,
                   help=f"share of each check's designed time limit a call gets at the reference speed "
                        f"(default {DEFAULT_TIME_FACTOR}; scaled on Gradescope by the container's measured slowness)")
    p.add_argument("--no-pictures", action="store_true",
                   help="no picture tests: feedback without the figures of each student's results on the public "
                        "data (they cost a few seconds per submission; scores do not change)")
    actions = p.add_subparsers(dest="action")
    r = actions.add_parser("run", help="grade <root>/submission into <root>/results/results.json")
    r.add_argument("--root", default=os.environ.get("HW4_AUTOGRADER_ROOT", "/autograder"),
                   help="Gradescope's folder (default: $HW4_AUTOGRADER_ROOT or /autograder)")
    p.set_defaults(func=_cli)
