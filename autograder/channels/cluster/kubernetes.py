"""``python -m autograder kubernetes ROOT --image IMAGE --claim PVC``: an Indexed Job and a merge Job.

Writes ``<root>/kubernetes/grade-job.yaml``: a ``batch/v1`` Job with ``completionMode: Indexed``,
``completions`` K and ``parallelism`` P, each pod grading shard ``$JOB_COMPLETION_INDEX`` (which
Kubernetes sets in an Indexed Job's pods) with ``python -m autograder grade --shard i/K --out
ROOT``; and ``merge-job.yaml``, one pod running ``python -m autograder merge ROOT``, applied once
the grading Job has ended (Kubernetes has no dependency between Jobs: ``kubectl wait``).  The
class's storage (a PersistentVolumeClaim) is mounted at the same path as where it was prepared, so
the manifest's paths hold in the pods; the secret comes from a Kubernetes Secret, never the file.

An Indexed Job cannot run only some indices: run again, the shards already done return at once
(``grade_shard`` sets nothing up for them), so resuming is applying the grading Job again under a
new name (``--name``).  The manifests are plain dicts written with PyYAML; the kit's tests load
them into the official client's ``V1Job`` without loss.
"""

from __future__ import annotations

import os
import re
import shlex
from pathlib import Path

from core.text import write_atomic

from .manifest import Manifest, load_manifest

__all__ = ["grade_job", "merge_job", "write_kubernetes"]

_NAME = re.compile(r"^[a-z0-9]([-a-z0-9]{0,50}[a-z0-9])?$")


def write_kubernetes(root: str | Path, *, image: str, claim: str, mount_path: str | None = None,
                     parallelism: int | None = None, secret: str | None = None, memory: str = "4Gi",
                     name: str = "hw4-grade", python: str = "python") -> dict:
    """Write the two Jobs of ``root``'s shards; returns ``{"grade", "merge"}`` paths.

    ``image``: a container image holding the kit and its Python environment; ``claim``: the
    PersistentVolumeClaim holding the root and the submissions, mounted at ``mount_path``
    (default: the folder holding them all); ``parallelism``: pods at once (default all K);
    ``secret``: a Kubernetes Secret whose key ``secret`` is given as ``HW4_GRADER_SECRET``;
    ``memory``: each pod's request and limit; ``name``: the grading Job's (the merge's adds ``-merge``).
    """
    import yaml

    manifest = load_manifest(root)
    if not _NAME.match(name):
        raise ValueError(f"name: expected a Kubernetes name (lower-case letters, digits, '-'), got {name!r}")
    for label, value in (("image", image), ("claim", claim)):
        if not value or not isinstance(value, str):
            raise ValueError(f"{label}: expected a non-empty string, got {value!r}")
    if parallelism is not None and (isinstance(parallelism, bool) or parallelism < 1):
        raise ValueError(f"parallelism: expected a positive number of pods, got {parallelism!r}")
    mount = mount_path or os.path.commonpath([str(manifest.root), *(s["path"] for s in manifest.submissions)])
    inside = [str(manifest.root), *(s["path"] for s in manifest.submissions)]
    outside = [p for p in inside if os.path.commonpath([mount, p]) != mount]
    if outside:
        raise ValueError(f"mount_path: expected a folder holding the root and every submission, got {mount} "
                         f"(not holding {outside[0]})")
    pod = {"image": image, "claim": claim, "mount": mount, "secret": secret, "memory": memory, "python": python}
    folder = manifest.root / "kubernetes"
    folder.mkdir(exist_ok=True, mode=0o700)
    grade = grade_job(manifest, name=name, parallelism=parallelism or manifest.shards, **pod)
    merge = merge_job(manifest, name=f"{name}-merge", **pod)
    return {"grade": write_atomic(folder / "grade-job.yaml", yaml.safe_dump(grade, sort_keys=False, width=120), mode=0o600),
            "merge": write_atomic(folder / "merge-job.yaml", yaml.safe_dump(merge, sort_keys=False, width=120), mode=0o600)}


def grade_job(manifest: Manifest, *, name: str, parallelism: int, **pod) -> dict:
    """The Indexed Job of the shards (a plain dict in the ``batch/v1`` schema)."""
    command = (f'exec {pod["python"]} -m autograder grade --shard "$JOB_COMPLETION_INDEX/{manifest.shards}" '
               f'--out {shlex.quote(str(manifest.root))} --quiet')
    cpus = int(manifest.options.get("jobs", 1))
    return _job(name, {"completionMode": "Indexed", "completions": manifest.shards,
                       "parallelism": min(parallelism, manifest.shards),
                       "backoffLimit": manifest.shards},  # each shard may be retried once on average
                _pod(command, cpus=cpus, **pod))


def merge_job(manifest: Manifest, *, name: str, **pod) -> dict:
    """The Job that merges the shards once they have ended."""
    return _job(name, {"completions": 1, "parallelism": 1, "backoffLimit": 1},
                _pod(f'exec {pod["python"]} -m autograder merge {shlex.quote(str(manifest.root))}', cpus=1, **pod))


def _job(name: str, spec: dict, pod: dict) -> dict:
    labels = {"app.kubernetes.io/name": "hw4-grader", "app.kubernetes.io/component": name}
    return {"apiVersion": "batch/v1", "kind": "Job", "metadata": {"name": name, "labels": labels},
            "spec": {**spec, "template": {"metadata": {"labels": dict(labels)}, "spec": pod}}}


def _pod(command: str, *, cpus: int, image: str, claim: str, mount: str, secret: str | None, memory: str,
         python: str) -> dict:
    resources = {"cpu": str(cpus), "memory": memory}
    container = {"name": "grader", "image": image, "command": ["/bin/sh", "-c", command],
                 "resources": {"requests": resources, "limits": dict(resources)},
                 "volumeMounts": [{"name": "class", "mountPath": mount}]}
    if secret:
        container["env"] = [{"name": "HW4_GRADER_SECRET",
                             "valueFrom": {"secretKeyRef": {"name": secret, "key": "secret"}}}]
    return {"restartPolicy": "Never", "containers": [container],
            "volumes": [{"name": "class", "persistentVolumeClaim": {"claimName": claim}}]}
