"""The cluster's commands of ``python -m autograder``: prepare, grade --shard, shards, merge, slurm,
kubernetes (their arguments; ``autograder.__main__`` lists them).  Each prints what to do next."""

from __future__ import annotations

import sys

from core.untrusted import for_terminal

from .manifest import ManifestMismatch, load_manifest, parse_shard, shard_status

__all__ = ["kubernetes_arguments", "kubernetes_command", "merge_arguments", "merge_command", "prepare_command",
           "shard_command", "shards_arguments", "shards_command", "slurm_arguments", "slurm_command"]

# grade's options that a shard takes from the manifest instead (name: its default)
_FROM_MANIFEST = {"config": None, "official_data": None, "hidden_dir": None, "isolation": "auto",
                  "allow_weak_isolation": False, "no_pictures": False, "regrade": None, "regrade_all": False,
                  "regrade_into": None, "no_resume": False}


def _refused(exc: Exception) -> int:
    print(f"error: {for_terminal(exc)}", file=sys.stderr)
    return 2


def prepare_command(args, config) -> int:
    from .prepare import prepare

    try:
        manifest = prepare(args.submissions, args.root, args.shards, config=config,
                           extra_tests=[args.hidden_dir] if args.hidden_dir else (), isolation=args.isolation,
                           allow_weak=args.allow_weak_isolation, pictures=not args.no_pictures, jobs=args.jobs)
    except (ManifestMismatch, FileNotFoundError) as exc:
        return _refused(exc)
    canary = manifest.data.get("canary") or {}
    print(f"prepared {len(manifest.submissions)} submissions in {manifest.shards} shards in {manifest.root} "
          f"(manifest {manifest.digest[:16]}; canary {canary.get('score', '?')} points at the "
          f"{canary.get('level', '?')} level here)")
    print(f"next: python -m autograder slurm {manifest.root}   (or: kubernetes {manifest.root} --image ... --claim ...)")
    return 0


def shard_command(args) -> int:
    from .shard import grade_shard

    given = sorted(k for k, default in _FROM_MANIFEST.items() if getattr(args, k, default) != default)
    if args.submissions or given:
        shown = [*(["SUBMISSION..."] if args.submissions else []), *("--" + k.replace("_", "-") for k in given)]
        return _refused(ValueError(f"--shard: a shard grades the prepared class with the manifest's settings; "
                                   f"drop {', '.join(shown)}"))
    try:
        index, count = parse_shard(args.shard)
        records = grade_shard(args.out, index, count, jobs=args.jobs if args.jobs != 1 else None,
                              progress=not args.quiet)
    except (ManifestMismatch, FileNotFoundError, ValueError) as exc:
        return _refused(exc)
    failed = [r.name for r in records if r.failure]
    print(f"shard {index}/{count}: {sum(not r.skipped for r in records)} graded now, "
          f"{sum(r.skipped for r in records)} already done" + (" (nothing left to grade)" if not records else "")
          + (f"; could not be graded: {for_terminal(', '.join(failed))}" if failed else ""))
    return 0


def shards_arguments(p) -> None:
    p.add_argument("root", help="the prepared class's root folder")


def shards_command(args) -> int:
    """Each shard's progress; exit status 0 when every shard is complete, 1 otherwise."""
    try:
        manifest = load_manifest(args.root)
    except (ManifestMismatch, FileNotFoundError) as exc:
        return _refused(exc)
    status = shard_status(manifest)
    for s in status:
        state = "complete" if s.complete else ("in flight or died" if s.inflight else
                                               "incomplete" if s.started else "not started")
        print(f"shard {s.index}: {len(s.stamped)}/{len(s.owned)} graded, {state}"
              + (f" (in flight: {for_terminal(', '.join(s.inflight))})" if s.inflight else ""))
    todo = [s.index for s in status if not s.complete]
    print(f"to resubmit: shards {','.join(map(str, todo))}" if todo else
          f"every shard is complete: python -m autograder merge {manifest.root}")
    return 1 if todo else 0


def merge_arguments(p) -> None:
    p.add_argument("root", help="the prepared class's root folder")
    p.add_argument("--no-review", action="store_true", help="only the grades: no class report, no look-alike check")


def merge_command(args) -> int:
    """Exit status 0 when every submission is graded, 3 when some are not (the shards to resubmit are
    printed), 2 when refused."""
    from .merge import merge

    try:
        report = merge(args.root, review=not args.no_review)
    except (ManifestMismatch, FileNotFoundError, ValueError) as exc:
        return _refused(exc)
    print(f"merged {len(report.graded)} submissions into {report.out} (grades.csv, summary.md)")
    for name, path in report.written.items():
        if name in ("report", "similar"):
            print(f"  {name}: {path}")
    for line in report.errors:
        print(f"warning: {for_terminal(line)}", file=sys.stderr)
    if report.not_graded:
        print(f"NOT GRADED ({len(report.not_graded)}): {for_terminal(', '.join(report.not_graded))}; resubmit shards "
              f"{','.join(map(str, report.incomplete))} (python -m autograder slurm {report.out.parent} writes only "
              f"those), then merge again", file=sys.stderr)
        return 3
    return 0


def slurm_arguments(p) -> None:
    p.add_argument("root", help="the prepared class's root folder (on storage every node sees at the same path)")
    p.add_argument("--partition", default=None, help="sbatch --partition (default: the cluster's)")
    p.add_argument("--time", default="02:00:00", help="sbatch --time of each shard (default 02:00:00)")
    p.add_argument("--mem", default="4G", help="sbatch --mem of each job (default 4G)")
    p.add_argument("--max-parallel", type=int, default=None, help="array tasks running at once (sbatch's %%N)")
    p.add_argument("--python", default=None, help="the Python on the nodes (default: this one)")


def slurm_command(args) -> int:
    from .slurm import write_slurm

    try:
        written = write_slurm(args.root, partition=args.partition, time_limit=args.time, memory=args.mem,
                              max_parallel=args.max_parallel, python=args.python)
    except (ManifestMismatch, FileNotFoundError, ValueError) as exc:
        return _refused(exc)
    if written["submit"] is None:
        print(f"every shard is complete; merge with: sbatch {written['merge']}  (or python -m autograder merge "
              f"{args.root})")
        return 0
    print(f"shards {','.join(map(str, written['shards']))}: {written['grade']}\nmerge: {written['merge']}\n"
          f"submit both with: sh {written['submit']}")
    return 0


def kubernetes_arguments(p) -> None:
    p.add_argument("root", help="the prepared class's root folder")
    p.add_argument("--image", required=True, help="a container image with the kit and its Python environment")
    p.add_argument("--claim", required=True, help="the PersistentVolumeClaim holding the root and the submissions")
    p.add_argument("--mount-path", default=None,
                   help="where the claim is mounted in the pods (default: the folder holding the root and the "
                        "submissions, as here)")
    p.add_argument("--parallelism", type=int, default=None, help="pods at once (default: every shard)")
    p.add_argument("--secret", default=None,
                   help="a Kubernetes Secret whose key 'secret' is the grader's secret (HW4_GRADER_SECRET)")
    p.add_argument("--memory", default="4Gi", help="each pod's memory (default 4Gi)")
    p.add_argument("--name", default="hw4-grade", help="the grading Job's name (a new one to resume)")


def kubernetes_command(args) -> int:
    from .kubernetes import write_kubernetes

    try:
        written = write_kubernetes(args.root, image=args.image, claim=args.claim, mount_path=args.mount_path,
                                   parallelism=args.parallelism, secret=args.secret, memory=args.memory,
                                   name=args.name)
    except (ManifestMismatch, FileNotFoundError, ValueError) as exc:
        return _refused(exc)
    print(f"kubectl apply -f {written['grade']}\nkubectl wait --for=condition=complete --timeout=4h job/{args.name}\n"
          f"kubectl apply -f {written['merge']}")
    return 0
