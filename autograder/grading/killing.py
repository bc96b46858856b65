"""Stopping this grader's grading processes at once (Ctrl-C of a batch): every descendant process,
then whatever still runs under the sandboxes' uids.

Processes are found through /proc (parent links), so a grading worker's sandbox children and
what student code started there are found too; a sandbox uid is never the grader's own or root.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Sequence

__all__ = ["descendants", "kill_grading_processes", "signal_all"]


def _process_tree() -> dict[int, list[int]]:
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as fh:
                stat = fh.read().decode(errors="replace")
            ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        children.setdefault(ppid, []).append(int(entry))
    return children


def descendants() -> tuple[list[int], list[int]]:
    """(this process's children, all their descendants)."""
    tree = _process_tree()
    direct = list(tree.get(os.getpid(), []))
    found, todo = [], list(direct)
    while todo:
        pid = todo.pop()
        found.append(pid)
        todo += tree.get(pid, [])
    return direct, found


def signal_all(pids: Sequence[int], sig: int) -> None:
    """Send ``sig`` to each of ``pids``; one already gone is skipped."""
    for pid in pids:
        try:
            os.kill(pid, sig)
        except OSError:
            pass


def kill_grading_processes(boxes: Sequence) -> None:
    """SIGKILL every descendant of this process, then sweep each sandbox's uid (``boxes``:
    ``Sandbox`` objects) of what still runs under it, a second at most each."""
    signal_all(descendants()[1], signal.SIGKILL)
    from autograder.sandbox.uids import sweep_uid

    for box in boxes:
        uid = box.runtime.uid if box.runtime is not None else None
        if uid is not None and uid not in (0, os.getuid()):
            try:
                sweep_uid(uid, budget=1.0)
            except (OSError, ValueError):
                pass
