"""``python -m autograder slurm ROOT``: an ``sbatch --array`` of the shards and a dependent merge job.

Writes into ``<root>/slurm/``: ``grade.sbatch`` (an array job, one task per shard still to do:
task i runs ``python -m autograder grade --shard i/K --out ROOT``), ``merge.sbatch`` (``python -m
autograder merge ROOT``) and ``submit.sh``, which submits the array and then the merge with
``--dependency=afterany`` on it (the merge runs however the shards ended, and says what is not
graded).  The array lists only the shards whose journal is incomplete, so writing the scripts again
after a failure and submitting them is the resume.  Logs go to ``<root>/slurm/logs/``.  The jobs
inherit the submitting shell's environment (``--export=ALL``), so ``HW4_GRADER_SECRET`` is never
written into a file.
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from core.text import write_atomic

from .manifest import Manifest, load_manifest, shard_status

__all__ = ["write_slurm"]


def write_slurm(root: str | Path, *, partition: str | None = None, time_limit: str = "02:00:00",
                memory: str | None = "4G", max_parallel: int | None = None, python: str | None = None,
                shards: list[int] | None = None) -> dict:
    """Write the scripts for the shards of ``root`` still to do (``shards``: these instead).

    ``partition``, ``time_limit`` (sbatch's ``--time``), ``memory`` (per job), ``max_parallel``
    (array tasks at once, sbatch's ``%``), ``python`` (the interpreter on the nodes, default this
    one).  Returns ``{"grade", "merge", "submit": paths, "shards": the array's indices}``; with no
    shard left to do, only merge.sbatch is written and ``grade`` and ``submit`` are None.
    """
    manifest = load_manifest(root)
    todo = sorted(shards) if shards is not None else [s.index for s in shard_status(manifest) if not s.complete]
    bad = [i for i in todo if not 0 <= i < manifest.shards]
    if bad:
        raise ValueError(f"shards: expected indices in 0..{manifest.shards - 1}, got {bad}")
    if max_parallel is not None and max_parallel < 1:
        raise ValueError(f"max_parallel: expected a positive number, got {max_parallel!r}")
    if any(c.isspace() for c in str(manifest.root)):
        # sbatch reads its #SBATCH lines without a shell's quoting: the nodes would see another path.
        raise ValueError(f"root: expected a path without spaces for Slurm's #SBATCH lines, got {manifest.root}")
    folder = manifest.root / "slurm"
    (folder / "logs").mkdir(parents=True, exist_ok=True, mode=0o700)
    python = python or sys.executable
    cpus = int(manifest.options.get("jobs", 1))
    common = [f"#SBATCH --chdir={manifest.root}", "#SBATCH --export=ALL", f"#SBATCH --time={time_limit}",
              *([f"#SBATCH --partition={partition}"] if partition else []),
              *([f"#SBATCH --mem={memory}"] if memory else [])]
    q = shlex.quote
    merge = _script(["#SBATCH --job-name=hw4-merge", f"#SBATCH --output={folder / 'logs' / 'merge-%j.out'}",
                     "#SBATCH --cpus-per-task=1", *common],
                    f"exec {q(python)} -m autograder merge {q(str(manifest.root))}")
    written = {"merge": write_atomic(folder / "merge.sbatch", merge, mode=0o700), "grade": None, "submit": None,
               "shards": todo}
    if not todo:
        return written
    array = _ranges(todo) + (f"%{max_parallel}" if max_parallel else "")
    grade = _script(["#SBATCH --job-name=hw4-grade", f"#SBATCH --array={array}",
                     f"#SBATCH --output={folder / 'logs' / 'grade-%A_%a.out'}", f"#SBATCH --cpus-per-task={cpus}",
                     *common],
                    f'exec {q(python)} -m autograder grade --shard "${{SLURM_ARRAY_TASK_ID}}/{manifest.shards}" '
                    f"--out {q(str(manifest.root))} --quiet")
    written["grade"] = write_atomic(folder / "grade.sbatch", grade, mode=0o700)
    written["submit"] = write_atomic(folder / "submit.sh", _submit(manifest, folder, todo), mode=0o700)
    return written


def _script(directives: list[str], command: str) -> str:
    return "\n".join(["#!/bin/bash", *directives, "set -euo pipefail", command]) + "\n"


def _submit(manifest: Manifest, folder: Path, todo: list[int]) -> str:
    q = shlex.quote
    return "\n".join([
        "#!/bin/sh",
        f"# Shards {_ranges(todo)} of {manifest.shards}, then the merge once they have all ended (however).",
        "set -eu",
        f"array=$(sbatch --parsable {q(str(folder / 'grade.sbatch'))})",
        'array=${array%%;*}',
        f"merge=$(sbatch --parsable --dependency=afterany:$array {q(str(folder / 'merge.sbatch'))})",
        'merge=${merge%%;*}',
        'echo "grading: job $array; merge: job $merge"',
    ]) + "\n"


def _ranges(indices: list[int]) -> str:
    """[0, 1, 2, 5] as "0-2,5" (sbatch's --array syntax)."""
    parts, start = [], None
    for k, i in enumerate(indices):
        if start is None:
            start = i
        if k + 1 == len(indices) or indices[k + 1] != i + 1:
            parts.append(str(start) if start == i else f"{start}-{i}")
            start = None
    return ",".join(parts)

