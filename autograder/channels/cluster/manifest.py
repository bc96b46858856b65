"""The frozen class of a cluster grading (``<root>/manifest.json``) and what each shard has done.

The manifest is written once by ``prepare`` and never changed: a JSON object with

- ``shards``: K; shard i owns the submissions at positions i, i+K, i+2K... (``Manifest.owned``);
- ``submissions``: ``[{"name", "path", "sha256"}]`` in the class's order (the gradebook's);
  names are ``journal.unique_names`` of the whole class, digests ``journal.submission_digest``;
- ``configuration``: the configuration record every result is stamped with
  (``autograder.inputs.config.configuration``; the secret only as a fingerprint);
- ``environment``: Python, numpy and scipy versions, the kit's version, a digest of the grader's
  code and the configuration key, with ``digest`` over them all (``environment``);
- ``options``: how shards grade (config file, extra tests, official data, isolation, pictures, jobs);
- ``digest``: SHA-256 of everything else, so an edited manifest is refused.

Nothing here grades or writes results.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
from dataclasses import dataclass
from pathlib import Path

from core.text import write_atomic

from autograder.inputs.config import configuration_changes
from autograder.channels.gradebook import read_state
from autograder.channels.journal import JOURNAL

__all__ = ["MANIFEST", "Manifest", "ManifestMismatch", "ShardStatus", "environment", "keep_of", "load_manifest",
           "parse_shard", "shard_status", "stamped", "write_manifest"]

MANIFEST = "manifest.json"
FORMAT = 1


class ManifestMismatch(ValueError):
    """A manifest, a submission or an environment differs from what was prepared."""


def environment(record: dict) -> dict:
    """What a shard's results depend on besides the submissions: versions, the grader's code and
    the configuration key of ``record``; ``digest`` (16 hex digits) over them all."""
    import numpy
    import scipy

    from autograder.inputs.keep import code_digest

    env = {"python": platform.python_version(), "numpy": numpy.__version__, "scipy": scipy.__version__,
           "kit_version": record.get("kit_version"), "grader_version": record.get("grader_version"),
           "code": code_digest()[:16], "configuration_key": record.get("key")}
    env["digest"] = hashlib.sha256(json.dumps(env, sort_keys=True).encode()).hexdigest()[:16]
    return env


def keep_of(root: Path) -> Path:
    """``$HW4_KEEP_INPUTS`` when set, else ``<root>/keep`` (see ``Manifest.keep``)."""
    from autograder.inputs.keep import ENV_KEEP

    return Path(os.environ[ENV_KEEP]) if os.environ.get(ENV_KEEP) else Path(root) / "keep"


def _digest(data: dict) -> str:
    body = {k: v for k, v in data.items() if k != "digest"}
    return hashlib.sha256(json.dumps(body, sort_keys=True, default=str).encode()).hexdigest()


@dataclass(frozen=True)
class Manifest:
    """A loaded manifest (``data``, checked against its digest) and the root folder it lies in."""

    root: Path
    data: dict

    @property
    def shards(self) -> int:
        return int(self.data["shards"])

    @property
    def submissions(self) -> list[dict]:
        return list(self.data["submissions"])

    @property
    def configuration(self) -> dict:
        return dict(self.data["configuration"])

    @property
    def key(self) -> str:
        return str(self.data["configuration"]["key"])

    @property
    def options(self) -> dict:
        return dict(self.data["options"])

    @property
    def digest(self) -> str:
        return str(self.data["digest"])

    def owned(self, index: int) -> list[dict]:
        """The submissions shard ``index`` grades: positions index, index+K, ..."""
        if not 0 <= index < self.shards:
            raise ValueError(f"index: expected a shard in 0..{self.shards - 1}, got {index}")
        return self.submissions[index::self.shards]

    def shard_folder(self, index: int) -> Path:
        return self.root / "shards" / str(index)

    def keep(self) -> Path:
        """The keep of hidden inputs prepare filled and the shards read: ``$HW4_KEEP_INPUTS`` when set
        (every node must see it to share it), else ``<root>/keep``."""
        return keep_of(self.root)

    def check_environment(self, record: dict) -> None:
        """Refuse (``ManifestMismatch``) an environment whose digest differs from the prepared one."""
        here, there = environment(record), self.data["environment"]
        if here["digest"] == there.get("digest"):
            return
        why = [f"{k} {there.get(k)} -> {here[k]}" for k in sorted(here) if k != "digest" and here[k] != there.get(k)]
        why += configuration_changes(self.configuration, record)
        raise ManifestMismatch(f"environment: this machine differs from the one {self.root} was prepared on "
                               f"({'; '.join(dict.fromkeys(why)) or 'the environment digest differs'}); grade with "
                               f"the same kit, packages and configuration (secret, data, hidden tests), or prepare "
                               f"a new root")


def write_manifest(root: Path, submissions: list[dict], shards: int, record: dict, options: dict,
                   *, canary: dict | None = None, library_names: dict | None = None) -> Manifest:
    """Write ``<root>/manifest.json`` (read-only) for ``submissions`` (``{"name", "path", "sha256"}``).

    Raises ``ManifestMismatch`` when ``root`` already holds a manifest of another class or
    environment (the same class prepared again keeps the manifest it has)."""
    if isinstance(shards, bool) or not isinstance(shards, int) or not 1 <= shards <= max(len(submissions), 1):
        raise ValueError(f"shards: expected a number of shards from 1 to the {len(submissions)} submissions, "
                         f"got {shards!r}")
    data = {"format": FORMAT, "shards": shards, "submissions": submissions, "configuration": record,
            "environment": environment(record), "options": options, "library_names": library_names or {},
            "canary": canary}
    data["digest"] = _digest(data)
    path = Path(root) / MANIFEST
    if path.exists():
        old = load_manifest(root)
        if old.digest == data["digest"]:
            return old
        raise ManifestMismatch(f"root: {root} already holds a prepared class of another manifest (other "
                               f"submissions, shards, options or environment); prepare into a new root")
    write_atomic(path, json.dumps(data, indent=1, sort_keys=True, default=str), mode=0o400)
    return Manifest(Path(root), data)


def load_manifest(root: str | Path) -> Manifest:
    """The manifest of ``root``; ``ManifestMismatch`` when it was edited after prepare."""
    root = Path(root).resolve()
    path = root / MANIFEST
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(f"root: expected a prepared class with {path} "
                                f"(python -m autograder prepare SUBMISSION... --root {root} --shards K)") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ManifestMismatch(f"root: {path} is not a manifest of this kit (format {FORMAT})")
    if data.get("digest") != _digest(data):
        raise ManifestMismatch(f"root: {path} changed after it was prepared (its digest no longer matches); "
                               f"prepare the class again into a new root")
    return Manifest(root, data)


def parse_shard(text: str) -> tuple[int, int]:
    """``"i/K"`` as (i, K), 0 <= i < K."""
    try:
        i, k = (int(x) for x in str(text).split("/"))
    except ValueError:
        raise ValueError(f"shard: expected i/K (shard i of K, counting from 0), got {text!r}") from None
    if not 0 <= i < k:
        raise ValueError(f"shard: expected i/K with 0 <= i < K, got {text!r}")
    return i, k


def stamped(folder: Path, sha256: str, key: str) -> dict | None:
    """The state of a result in ``folder`` stamped for this content and configuration, else None
    (a failure recorded as such is a stamped result too: the class's zero with its reason)."""
    state = read_state(folder)
    if state is None or not (folder / "results.json").is_file():
        return None
    if state.get("sha256") != sha256 or state.get("configuration_key") != key:
        return None
    return state


@dataclass(frozen=True)
class ShardStatus:
    """What shard ``index`` has done: its ``owned`` names, those with a ``stamped`` result, those
    left ``inflight`` in its journal, and whether it ever ``started`` (its folder exists)."""

    index: int
    owned: tuple[str, ...]
    stamped: tuple[str, ...]
    inflight: tuple[str, ...]
    started: bool

    @property
    def missing(self) -> tuple[str, ...]:
        return tuple(n for n in self.owned if n not in self.stamped)

    @property
    def complete(self) -> bool:
        """Every owned submission stamped and nothing left in flight: nothing to resubmit."""
        return not self.missing and not self.inflight


def shard_status(manifest: Manifest) -> list[ShardStatus]:
    """Each shard's status, read from its folder (nothing is locked or changed)."""
    out = []
    for i in range(manifest.shards):
        folder = manifest.shard_folder(i)
        owned = manifest.owned(i)
        done = tuple(s["name"] for s in owned if stamped(folder / s["name"], s["sha256"], manifest.key) is not None)
        flying = tuple(sorted(p.stem for p in (folder / JOURNAL).glob("*.json")))
        out.append(ShardStatus(i, tuple(s["name"] for s in owned), done, flying, folder.is_dir()))
    return out
