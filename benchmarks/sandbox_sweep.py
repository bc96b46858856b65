"""What the sweep after each sandboxed child costs: every shared temporary folder beside those a
namespace-level child can reach.

    python benchmarks/sandbox_sweep.py [--runs 5]

After a child stops, the grader looks for what the sandbox's uid left in the machine's shared
temporary folders (``autograder.sandbox.uids.files_of_uid``, searching other users' folders that
anyone may enter).  At the ``uid`` level that is /tmp, /var/tmp, /dev/shm and /run/lock; behind a
namespace level's private tmpfs only the folders it does not cover (``Runtime.shared_tmp_dirs``).
Both searches run here, in turn, on this machine's folders as they are (a clone of the kit and its
virtual environments under /tmp make the first one long); printed: the median seconds of each
and their ratio.  Run as root (it reads every folder).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere without installing
from autograder.sandbox.model import ResourceLimits  # noqa: E402
from autograder.sandbox.script import Runtime  # noqa: E402
from autograder.sandbox.uids import SHARED_TMP_DIRS, files_of_uid  # noqa: E402

UNUSED_UID = 64_999  # no file has this owner here: the search looks at everything and finds nothing


def _median_seconds(roots, runs: int) -> float:
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        files_of_uid(UNUSED_UID, roots)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    runs = parser.parse_args().runs
    behind_tmpfs = Runtime("namespaces", UNUSED_UID, Path("."), (), True, ResourceLimits()).shared_tmp_dirs()
    every = _median_seconds(SHARED_TMP_DIRS, runs)
    reachable = _median_seconds(behind_tmpfs, runs)
    print(f"every shared folder ({', '.join(d for d in SHARED_TMP_DIRS if os.path.isdir(d))}): {every:.3f} s")
    present = [d for d in behind_tmpfs if os.path.isdir(d)]
    print(f"behind a private /tmp, {', '.join(present) or 'none'}: {reachable * 1e3:.3f} ms")
    print(f"ratio: {every / max(reachable, 1e-6):.0f}x (median of {runs} runs each)")


if __name__ == "__main__":
    main()
