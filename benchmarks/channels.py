"""Benchmark of the Gradescope channel at half a CPU: ``run_autograder`` on the answer key and on a
submission whose every function hangs, in a folder laid out like /autograder, beside the answer key
alone at full speed, in one run.  Goal: the all-hang submission within ``HANG_GOAL`` times the
answer key at the same share of a CPU (both include the canary and setting up); the run prints
the ratio, and where the all-hang's time went: each function's first request, the only one that
runs (a function that ran out of time is not called again in the session), with the seconds it
was allowed, read from its feedback.  Each row shows the limits' clock (cpu on Gradescope), the
measured CPU share, the wall-clock backstop's multiple of a call ("backstop"), the session's wall-clock budget in seconds ("session",
grown by 1 / share: ``autograder.grading.budget.budget_of``) and the seconds the canary (the bundled answer
key) took before grading.

    python benchmarks/channels.py [--vcpu 0.5] [--keep DIR]

0.5 vCPU is emulated with a cgroup (v1 ``cpu`` or v2 ``cpu.max``) whose quota is half of one CPU
per period, holding run_autograder and everything it starts (the sandbox's children included);
where no cgroup can be made (not root, read-only cgroupfs) with ``taskset -c 0`` and a competing
busy loop on that CPU.  The line "emulation:" says which was used.  The bundle is built with the
kit's default grading settings and the public development secret (timing only, never grading).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere without installing
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))  # the corpus

from autograder.channels.gradescope import bundle as gradescope  # noqa: E402
import corpus  # noqa: E402
from corpus.hangs import build_all_hang  # noqa: E402
from gradescope_like import unpack  # noqa: E402

_PERIOD = 100_000  # microseconds
HANG_GOAL = 2.0     # the all-hang submission's time, at most this multiple of the answer key's
# A check's feedback on a call stopped for its time: "<function> did not finish in time (used more
# than 8.66 s of CPU time)"; "(took more than 30 s ..." (wall-clock) where the grader's backstop did.
_STOPPED = re.compile(r"(\w+) did not finish in time \((used|took) more than ([0-9.]+) s")


@contextmanager
def half_cpu(vcpu: float):
    """(argv prefix, description) running a command at ``vcpu`` of one CPU."""
    name = f"hw4-bench-{os.getpid()}"
    v1 = Path("/sys/fs/cgroup/cpu")
    v2 = Path("/sys/fs/cgroup")
    quota = int(_PERIOD * vcpu)
    folder = None
    try:
        if (v1 / "cpu.cfs_quota_us").is_file():
            folder = v1 / name
            folder.mkdir()
            (folder / "cpu.cfs_period_us").write_text(str(_PERIOD))
            (folder / "cpu.cfs_quota_us").write_text(str(quota))
        elif (v2 / "cgroup.controllers").is_file() and "cpu" in (v2 / "cgroup.controllers").read_text():
            folder = v2 / name
            folder.mkdir()
            (folder / "cpu.max").write_text(f"{quota} {_PERIOD}")
    except OSError:
        folder = None
    if folder is not None:
        try:
            prefix = ["sh", "-c", f'echo $$ > {folder / "cgroup.procs"} && exec "$@"', "sh"]
            yield prefix, f"cgroup {folder} (quota {quota} us per {_PERIOD} us)"
        finally:
            time.sleep(1)
            try:
                folder.rmdir()
            except OSError as exc:
                print(f"note: could not remove {folder}: {exc}")
        return
    if vcpu != 0.5:
        raise SystemExit("vcpu: without cgroups only 0.5 can be emulated (taskset and one busy loop)")
    busy = subprocess.Popen(["taskset", "-c", "0", sys.executable, "-c", "while True: pass"])
    try:
        yield ["taskset", "-c", "0"], "taskset -c 0 with a competing busy loop on CPU 0"
    finally:
        busy.kill()
        busy.wait()


def run(bundle: Path, submission: Path, work: Path, prefix: list[str]) -> dict:
    ag = unpack(bundle, work)
    for p in sorted(submission.glob("*.ipynb")):
        shutil.copy2(p, ag / "submission" / p.name)
    env = {**os.environ, "HW4_AUTOGRADER_ROOT": str(ag), "HW4_PYTHON": sys.executable}
    t = time.monotonic()
    subprocess.run([*prefix, "bash", str(ag / "run_autograder")], env=env, capture_output=True, timeout=1200, check=False)
    seconds = time.monotonic() - t
    data = json.loads((ag / "results" / "results.json").read_text())
    checks = [x for x in data["tests"] if "score" not in x]
    stopped: dict[str, tuple[str, float]] = {}  # function -> ("used": CPU s, or "took": wall-clock s)
    for check in checks:
        for function, how, limit in _STOPPED.findall(check.get("output", "")):
            stopped.setdefault(function, (how, float(limit)))
    return {"seconds": seconds, "score": data["score"], "tests": len(data["tests"]), "checks": len(checks),
            "failure": data["extra_data"].get("failure"), "timing": data["extra_data"].get("timing", {}),
            "stopped": stopped}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vcpu", type=float, default=0.5, help="share of one CPU to emulate (default 0.5)")
    parser.add_argument("--keep", default=None, help="keep the work folder here")
    args = parser.parse_args(argv)
    work = Path(args.keep or tempfile.mkdtemp(prefix="hw4-bench-channels-"))
    work.mkdir(parents=True, exist_ok=True)
    for var in ("HW4_GRADER_CONFIG", "HW4_GRADER_SECRET", "HW4_COURSE_DATA"):
        os.environ.pop(var, None)
    t = time.monotonic()
    bundle = gradescope.build_bundle(work / "autograder.zip", allow_dev_secret=True)
    print(f"bundle: {bundle.stat().st_size / 2**20:.1f} MB in {time.monotonic() - t:.1f} s "
          f"(hidden inputs precomputed; time factor {gradescope.DEFAULT_TIME_FACTOR})")
    key = corpus.build("key_full_marks", work / "subs")
    hang = build_all_hang(work / "subs")
    # Other jobs on the machine move every row: the load average says how busy it was.
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    rows = [("answer key", "full speed", run(bundle, key, work / "key-full", []))]
    with half_cpu(args.vcpu) as (prefix, how):
        print(f"emulation: {args.vcpu} vCPU by {how}")
        rows.append(("answer key", f"{args.vcpu} vCPU", run(bundle, key, work / "key-half", prefix)))
        rows.append(("every function hangs", f"{args.vcpu} vCPU", run(bundle, hang, work / "hang-half", prefix)))
    print(f"{'submission':22s} {'CPU':>10s} {'seconds':>8s} {'score':>6s} {'tests':>6s} {'slowness':>9s} {'scale':>6s} "
          f"{'clock':>5s} {'share':>5s} {'backstop':>8s} {'session':>7s} {'canary':>6s}  inputs")
    nan = float("nan")
    for name, cpu, r in rows:
        tm = r["timing"]
        print(f"{name:22s} {cpu:>10s} {r['seconds']:8.1f} {r['score']:6g} {r['tests']:6d} "
              f"{tm.get('slowness', nan):9.2f} {tm.get('time_scale', nan):6.3f} {tm.get('clock', 'wall'):>5s} "
              f"{tm.get('cpu_share', nan):5.2f} {tm.get('wall_factor', nan):8.2f} {tm.get('session_budget', nan):7.0f} "
              f"{tm.get('canary_seconds', nan):6.1f}"
              f"  {tm.get('hidden_inputs')}" + (f"  FAILED: {r['failure']}" if r["failure"] else ""))
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    key, hang = rows[-2][2], rows[-1][2]
    share = hang["timing"].get("cpu_share") or args.vcpu
    wall = {f: s / share if how == "used" else s for f, (how, s) in hang["stopped"].items()}
    print(f"where the all-hang's time went: each function stopped once, at its first request's limit, in "
          f"wall-clock s at a share of {share:.2f} (CPU s as its feedback says / share):")
    print("  " + ", ".join(f"{f} {s:.1f}" for f, s in sorted(wall.items(), key=lambda x: -x[1])))
    print(f"  together {sum(wall.values()):.1f} s; setting up, the canary "
          f"({hang['timing'].get('canary_seconds', nan):.1f} s) and the rest: {hang['seconds'] - sum(wall.values()):.1f} s")
    ratio = hang["seconds"] / key["seconds"]
    print(f"every function hangs / answer key at {args.vcpu} vCPU: {hang['seconds']:.1f} s / {key['seconds']:.1f} s "
          f"= {ratio:.2f}x (goal: at most {HANG_GOAL:g}x): {'met' if ratio <= HANG_GOAL else 'MISSED'}")
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
