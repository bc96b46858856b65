"""Grading a class on a cluster engine (Slurm, Kubernetes): prepare, shards, merge.

Nothing here schedules: the cluster's own engine runs the shards, and each shard is an ordinary
batch (``autograder.channels.batch``).  On shared storage, under one root folder::

    <root>/manifest.json        the frozen class (``manifest``): submissions with their digests, the
                                kit's version, the environment's digest, the options, K shards
    <root>/keep/                the hidden inputs made once by prepare (``autograder.inputs.keep``)
    <root>/shards/<i>/          shard i's batch folder: its own lock, journal, results, grades.csv
    <root>/out/                 the merged class: <name>/ folders, grades.csv, summary.md
    <root>/report/, similar/    the class report and the look-alike check over all the code
    <root>/slurm/, kubernetes/  what ``slurm`` and ``kubernetes`` wrote to submit the shards

Shard i owns the manifest's submissions i, i+K, i+2K...; no lock or journal is shared between
shards, so nothing is locked across machines.  ``prepare`` (``prepare.py``), ``grade_shard``
(``shard.py``), ``merge`` (``merge.py``), ``write_slurm`` (``slurm.py``) and
``write_kubernetes`` (``kubernetes.py``); ``manifest.py`` holds the manifest and each shard's status.
"""

from __future__ import annotations

from .manifest import ManifestMismatch, load_manifest, shard_status

__all__ = ["ManifestMismatch", "load_manifest", "shard_status"]
