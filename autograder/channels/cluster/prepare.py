"""``prepare``: the hidden inputs, the canary and the frozen manifest of a class, on shared storage.

Run once, on the machine the TA submits from, before any shard.  The hidden inputs go into
``<root>/keep`` (``autograder.inputs.keep``; ``$HW4_KEEP_INPUTS`` instead when set), which every
shard reads instead of making them again; the canary (the answer key at full marks in this sandbox and configuration) must pass before a
manifest is written, so a broken secret or environment stops the class before the cluster is
asked for anything.  Each shard still grades the canary on its own node (as every batch does).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from core.text import private_folder

from autograder.inputs.config import GradingConfig, load_config
from autograder.channels.journal import submission_digest, unique_names
from autograder.grading.run import GradingRun
from autograder.sandbox import ResourceLimits
from .manifest import Manifest, keep_of, write_manifest

__all__ = ["prepare"]


def prepare(paths: Sequence[str | os.PathLike], root: str | os.PathLike, shards: int, *,
            config: GradingConfig | None = None, extra_tests: Sequence[str | os.PathLike] = (),
            isolation: str = "auto", allow_weak: bool = False, pictures: bool = True, jobs: int = 1,
            limits: ResourceLimits | None = None, canary: bool = True) -> Manifest:
    """Make ``root`` (0700) ready for ``shards`` shards grading ``paths``; returns its manifest.

    ``config``, ``extra_tests``, ``isolation``, ``allow_weak``, ``pictures``: as
    ``autograder.channels.batch.grade_batch``, recorded in the manifest for every shard; ``jobs``: the
    submissions each shard grades at once (a cluster job's CPUs).  ``canary``: grade the answer key
    here first (only the kit's own tests of the manifest turn it off).

    Raises
    ------
    FileNotFoundError
        When a submission is missing.
    autograder.grading.canary.CanaryFailed
        When the answer key loses points here: no manifest is written.
    ManifestMismatch
        When ``root`` already holds the manifest of another class.
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs: expected a positive integer, got {jobs!r}")
    config = config or load_config()
    paths = [Path(p).resolve() for p in paths]
    missing = [str(p) for p in paths if not p.exists()]
    if missing:
        raise FileNotFoundError(f"paths: expected existing submissions, got missing {missing}")
    if not paths:
        raise ValueError("paths: expected at least one submission")
    root = private_folder(Path(root).resolve())
    extra = [Path(p).resolve() for p in extra_tests or ()]
    submissions = [{"name": name, "path": str(p), "sha256": submission_digest(p)}
                   for name, p in zip(unique_names(paths), paths)]
    run = GradingRun(config, hide=[root, *(p.parent for p in paths)], extra_tests=extra, isolation=isolation,
                     limits=limits, allow_weak=allow_weak, keep=keep_of(root))
    with run:
        run.make_inputs()
        report = run.run_canary() if canary else None
        record = run.record
    official = config.official_dir()
    options = {"config": str(config.source) if config.source is not None else None,
               "extra_tests": [str(p) for p in extra], "official_data": str(official) if official else None,
               "isolation": isolation, "allow_weak": bool(allow_weak), "pictures": bool(pictures), "jobs": jobs}
    seen = None if report is None else {"score": report.score, "max_score": report.max_score,
                                        "level": (report.isolation or {}).get("level")}
    return write_manifest(root, submissions, shards, record, options, canary=seen,
                          library_names=config.library_names())
