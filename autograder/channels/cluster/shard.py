"""``grade --shard i/K``: one shard of a prepared class, an ordinary batch into ``<root>/shards/<i>/``.

Before anything is set up the shard refuses (``ManifestMismatch``) a manifest edited after prepare,
a K other than the manifest's, a shard folder of another manifest, a submission whose content
changed since prepare, and an environment (versions, the grader's code, the configuration) other
than the prepared one.  Then it is a batch (``autograder.channels.batch.grade_batch``) of the submissions it
owns, with the class's names, its own lock and journal, the hidden inputs read from the keep
prepare filled (``Manifest.keep``) and the whole root hidden from student code; a shard run again
resumes as any batch does, and one whose every submission is already done returns at once,
without setting anything up.
"""

from __future__ import annotations

import json
from pathlib import Path

from core.text import write_atomic

from autograder.channels.batch import grade_batch
from autograder.inputs.config import GradingConfig, configuration, load_config, tests_fingerprint
from autograder.channels.gradebook import BatchRecord
from autograder.channels.journal import resumable, submission_digest
from .manifest import Manifest, ManifestMismatch, load_manifest

__all__ = ["SHARD_FILE", "grade_shard", "shard_config"]

SHARD_FILE = "shard.json"


def shard_config(manifest: Manifest) -> GradingConfig:
    """The grading settings the manifest names (its config file, its official data), loaded here
    (the secret, when not in the file, from this machine's ``$HW4_GRADER_SECRET``)."""
    options = manifest.options
    return load_config(options.get("config"), official_data=options.get("official_data"))


def grade_shard(root: str | Path, index: int, count: int, *, config: GradingConfig | None = None,
                jobs: int | None = None, progress: bool = True, limits=None,
                canary: bool = True) -> list[BatchRecord]:
    """Grade shard ``index`` of ``count`` of the class prepared in ``root``; its batch records
    (empty when it had nothing left to grade).

    ``config``: the settings (default ``shard_config``); ``jobs``: submissions at once (default:
    the manifest's).  ``limits`` and ``canary`` as ``grade_batch`` (for the kit's own tests).

    Raises ``ManifestMismatch`` (see the module), and whatever ``grade_batch`` raises.
    """
    manifest = load_manifest(root)
    if count != manifest.shards:
        raise ManifestMismatch(f"shard: {root} was prepared for {manifest.shards} shards, got {index}/{count}")
    owned = manifest.owned(index)
    options = manifest.options
    config = config or shard_config(manifest)
    extra = [Path(p) for p in options.get("extra_tests") or ()]
    manifest.check_environment(configuration(config, tests=tests_fingerprint(extra)))
    folder = manifest.shard_folder(index)
    _claim(folder, manifest, index)
    changed = [s["name"] for s in owned if submission_digest(Path(s["path"])) != s["sha256"]]
    if changed:
        raise ManifestMismatch(f"submissions: changed since {root} was prepared: {', '.join(changed)}; grade the "
                               f"class as prepared, or prepare it again into a new root")
    if all(resumable(folder / s["name"], s["sha256"], manifest.key) is not None for s in owned):
        return []
    return grade_batch([Path(s["path"]) for s in owned], folder, names=[s["name"] for s in owned],
                       jobs=jobs or int(options.get("jobs", 1)), config=config, progress=progress,
                       isolation=options.get("isolation", "auto"), allow_weak=bool(options.get("allow_weak")),
                       extra_tests=extra, pictures=bool(options.get("pictures", True)), limits=limits,
                       hide=[manifest.root], keep=manifest.keep(), canary=canary)


def _claim(folder: Path, manifest: Manifest, index: int) -> None:
    """Make the shard's folder, marked with the manifest it grades; refuse one of another manifest."""
    mark = folder / SHARD_FILE
    if mark.exists():
        try:
            found = json.loads(mark.read_text(encoding="utf-8")).get("manifest")
        except (OSError, ValueError, AttributeError):
            found = None
        if found != manifest.digest:
            raise ManifestMismatch(f"shard: {folder} holds results of another manifest ({found or 'unreadable'}, "
                                   f"now {manifest.digest}); prepare into a new root")
        return
    folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    write_atomic(mark, json.dumps({"manifest": manifest.digest, "index": index, "count": manifest.shards}),
                 mode=0o600)
