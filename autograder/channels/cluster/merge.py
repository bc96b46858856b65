"""``merge``: the shards of a prepared class joined into one graded folder, ``<root>/out/``.

Every submission of the manifest must have exactly one stamped result (its content's digest and
the manifest's configuration key) among the shards' folders; it is copied to ``<root>/out/<name>/``
and the class's ``grades.csv``, ``summary.md`` and ``configuration.json`` are written there with
the batch's own gradebook functions, in the manifest's order, so they are the one-machine batch's.
A submission no shard has graded (a shard that died or never ran) is "not graded": it is listed in
summary.md and by the command, never written as a zero.  Then the class report (``<root>/report/``)
and the look-alike check over all the code (``<root>/similar/``) run on the whole class.  The
merge needs no secret: what it writes comes from the manifest and the stamped results.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field, replace
from pathlib import Path

from core.untrusted import for_markdown

from autograder.channels.gradebook import record_of, write_grades_csv, write_summary
from autograder.channels.journal import lock, write_configuration
from autograder.review.library_calls import find_in_class
from .manifest import Manifest, load_manifest, shard_status, stamped

__all__ = ["MergeReport", "merge"]


@dataclass
class MergeReport:
    """What a merge did: ``graded`` and ``not_graded`` names (the manifest's order), the shards to
    resubmit (``incomplete``), the folders written and the review steps that failed (``errors``)."""

    out: Path
    graded: list[str]
    not_graded: list[str]
    incomplete: list[int]
    written: dict = field(default_factory=dict)
    errors: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return not self.not_graded


def merge(root: str | Path, *, review: bool = True) -> MergeReport:
    """Join the shards of ``root`` into ``<root>/out`` (and, with ``review``, the class report and the
    look-alike check).  Raises ``ManifestMismatch`` for an edited manifest and ``ValueError`` when a
    submission has stamped results in more than one shard folder."""
    manifest = load_manifest(root)
    found = _stamped_results(manifest)
    twice = sorted(name for name, where in found.items() if len(where) > 1)
    if twice:
        raise ValueError(f"shards: expected one result per submission, found several for {', '.join(twice)} "
                         f"(a shard folder was graded into by hand?); remove the extra ones")
    out = manifest.root / "out"
    out.mkdir(mode=0o700, exist_ok=True)
    fd = lock(out)
    try:
        records, not_graded = [], []
        for sub in manifest.submissions:
            where = found.get(sub["name"])
            if not where:
                not_graded.append(sub["name"])
                continue
            target = _copy(where[0], out / sub["name"])
            # Graded by the shards, the class's batch: summary.md counts them as graded, not resumed.
            records.append(replace(record_of(target, stamped(target, sub["sha256"], manifest.key)), skipped=False))
        incomplete = [s.index for s in shard_status(manifest) if not s.complete]
        write_grades_csv(out / "grades.csv", records)
        write_configuration(out, manifest.configuration, {r.isolation for r in records if r.isolation})
        paths = {s["name"]: Path(s["path"]) for s in manifest.submissions}
        calls = find_in_class([(r.name, paths[r.name]) for r in records], manifest.data.get("library_names") or {})
        write_summary(out / "summary.md", records, manifest.configuration, note=_note(manifest, not_graded, incomplete),
                      library_calls=calls)
    finally:
        os.close(fd)
    report = MergeReport(out, [r.name for r in records], not_graded, incomplete,
                         {"grades": out / "grades.csv", "summary": out / "summary.md"})
    if review:
        _review(manifest, report)
    return report


def _stamped_results(manifest: Manifest) -> dict[str, list[Path]]:
    """name -> the shard folders' result folders stamped for its content and the manifest's key."""
    found: dict[str, list[Path]] = {}
    for sub in manifest.submissions:
        for i in range(manifest.shards):
            folder = manifest.shard_folder(i) / sub["name"]
            if stamped(folder, sub["sha256"], manifest.key) is not None:
                found.setdefault(sub["name"], []).append(folder)
    return found


def _copy(source: Path, target: Path) -> Path:
    """``source`` copied to ``target`` (replacing an earlier merge's copy; a copy, not a link, so the
    merged folder is whole on its own and never leads back into a shard's)."""
    tmp = target.with_name(f".{target.name}.merging")
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(source, tmp, symlinks=True)
    if target.exists():
        shutil.rmtree(target)
    os.rename(tmp, target)
    return target


def _note(manifest: Manifest, not_graded: list[str], incomplete: list[int]) -> str:
    lines = [f"Merged from {manifest.shards} shards of the class prepared in {manifest.root} "
             f"(manifest {manifest.digest[:16]}, environment {manifest.data['environment']['digest']})."]
    if not_graded:
        names = ", ".join(for_markdown(n, newlines=False) for n in not_graded)
        lines += ["", f"**Not graded: {len(not_graded)} submission{'s' if len(not_graded) > 1 else ''}** (their shard did not finish; they are not in "
                      f"grades.csv, not zero): {names}. Resubmit shards {', '.join(map(str, incomplete))} "
                      f"(python -m autograder slurm/kubernetes writes only those), then merge again."]
    return "\n".join(lines)


def _review(manifest: Manifest, report: MergeReport) -> None:
    """The class report and the look-alike check over all the code; a failure is reported, not raised
    (the grades are written already)."""
    from autograder.review.__main__ import run_similar
    from autograder.review.report import write_report

    try:
        written = write_report(report.out, manifest.root / "report",
                               library_calls=manifest.data.get("library_names") or {})
        report.written["report"] = written["html"]
    except Exception as exc:  # noqa: BLE001 - the grades stand; the TA is told
        report.errors.append(f"class report: {type(exc).__name__}: {exc}")
    try:
        done = run_similar([s["path"] for s in manifest.submissions], manifest.root / "similar")
        report.written["similar"] = done["html"]
    except Exception as exc:  # noqa: BLE001
        report.errors.append(f"look-alike check: {type(exc).__name__}: {exc}")
