"""A real one-node Slurm cluster in a folder of its own, for the cluster test (Debian's slurm-wlm and munge).

``SlurmNode(folder)`` writes its own munge key, slurm.conf (free ports, the node at 127.0.0.1, this
machine's CPUs and memory, state, spool, logs and pid files in ``folder``), starts munged, slurmctld
and slurmd in the foreground as children of the test, waits until the node is idle, and ``stop()``
ends the three by their pids.  Nothing of the machine's own Slurm or munge is used or touched.
``why_not()`` says why a node cannot be started here (packages missing, not root), or None.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

DAEMONS = ("munged", "slurmctld", "slurmd")
CLIENTS = ("sbatch", "squeue", "sinfo", "scontrol")


def why_not() -> str | None:
    """Why a one-node cluster cannot run here, or None."""
    missing = [d for d in DAEMONS + CLIENTS + ("mungekey",) if shutil.which(d) is None
               and not Path("/usr/sbin", d).exists()]
    if missing:
        return f"Slurm or munge not installed ({', '.join(missing)} missing: apt-get install slurm-wlm munge)"
    if os.geteuid() != 0:
        return "a one-node Slurm cluster runs its daemons as root here; not root"
    return None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _binary(name: str) -> str:
    return shutil.which(name) or str(Path("/usr/sbin", name))


def _memory_mb() -> int:
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemTotal:"):
            return int(line.split()[1]) // 1024
    return 1024


class SlurmNode:
    """munged, slurmctld and slurmd of one node, all in ``folder``; ``env`` is what a client needs."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.host = socket.gethostname().split(".")[0]
        self.procs: dict[str, subprocess.Popen] = {}
        for sub in ("munge", "state", "spool", "log"):
            (self.folder / sub).mkdir(mode=0o700, parents=True, exist_ok=True)
        self.conf = self.folder / "slurm.conf"
        self.socket = self.folder / "munge" / "munge.socket"
        self.env = {**os.environ, "SLURM_CONF": str(self.conf)}

    def _write_conf(self) -> None:
        f, host = self.folder, self.host
        self.conf.write_text("\n".join([
            "ClusterName=hw4test", f"SlurmctldHost={host}(127.0.0.1)",
            f"SlurmctldPort={_free_port()}", f"SlurmdPort={_free_port()}",
            "SlurmUser=root", "SlurmdUser=root", "AuthType=auth/munge", f"AuthInfo=socket={self.socket}",
            "CredType=cred/munge", "ProctrackType=proctrack/linuxproc", "TaskPlugin=task/none",
            "SelectType=select/cons_tres", "SelectTypeParameters=CR_CPU", "MpiDefault=none",
            "JobAcctGatherType=jobacct_gather/none", "AccountingStorageType=accounting_storage/none",
            "JobCompType=jobcomp/none", "SchedulerType=sched/backfill", "ReturnToService=2",
            "SlurmctldTimeout=30", "SlurmdTimeout=30", "MinJobAge=600",
            f"StateSaveLocation={f / 'state'}", f"SlurmdSpoolDir={f / 'spool'}",
            f"SlurmctldPidFile={f / 'slurmctld.pid'}", f"SlurmdPidFile={f / 'slurmd.pid'}",
            f"SlurmctldLogFile={f / 'log' / 'slurmctld.log'}", f"SlurmdLogFile={f / 'log' / 'slurmd.log'}",
            f"NodeName={host} NodeAddr=127.0.0.1 CPUs={os.cpu_count() or 1} RealMemory={_memory_mb()} State=UNKNOWN",
            f"PartitionName=debug Nodes={host} Default=YES MaxTime=INFINITE State=UP",
        ]) + "\n")

    def start(self, timeout: float = 60.0) -> SlurmNode:
        key = self.folder / "munge" / "munge.key"
        subprocess.run([_binary("mungekey"), "--create", f"--keyfile={key}"], check=True, capture_output=True)
        os.chmod(key, 0o400)
        self._write_conf()
        log = open(self.folder / "log" / "daemons.out", "ab")  # noqa: SIM115 - kept open while they run
        m = self.folder / "munge"
        self.procs["munged"] = subprocess.Popen(
            [_binary("munged"), "--foreground", "--force", f"--socket={self.socket}", f"--key-file={key}",
             f"--log-file={m / 'munged.log'}", f"--pid-file={m / 'munged.pid'}", f"--seed-file={m / 'munged.seed'}"],
            stdout=log, stderr=log, start_new_session=True)
        self._wait(lambda: self.socket.exists(), 15, "munged's socket")
        for daemon in ("slurmctld", "slurmd"):
            self.procs[daemon] = subprocess.Popen([_binary(daemon), "-D", "-f", str(self.conf)], env=self.env,
                                                  stdout=log, stderr=log, start_new_session=True)
        self._wait(self._idle, timeout, "the node to be idle in sinfo")
        return self

    def _idle(self) -> bool:
        for name, p in self.procs.items():
            if p.poll() is not None:
                raise RuntimeError(f"{name} exited with {p.returncode}: {self.logs()}")
        out = subprocess.run(["sinfo", "-h", "-o", "%t"], env=self.env, capture_output=True, text=True)
        return out.returncode == 0 and out.stdout.strip() in ("idle", "mix", "alloc")

    def _wait(self, condition, timeout: float, what: str) -> None:
        end = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > end:
                raise TimeoutError(f"timed out waiting for {what}: {self.logs()}")
            time.sleep(0.3)

    def run(self, *argv: str, timeout: float = 30.0, env: dict | None = None) -> subprocess.CompletedProcess:
        """A client command (``env``: more variables, which sbatch passes on to the jobs)."""
        return subprocess.run(list(argv), env={**self.env, **(env or {})}, capture_output=True, text=True,
                              timeout=timeout)

    def job_state(self, job: str) -> list[str]:
        """The states of a job's tasks (squeue while they are known to the controller)."""
        out = self.run("squeue", "-h", "-r", "-j", job, "-o", "%T")
        return out.stdout.split()

    def logs(self) -> str:
        parts = []
        for name in ("daemons.out", "slurmctld.log", "slurmd.log"):
            p = self.folder / "log" / name
            if p.exists():
                parts.append(f"--- {name}\n" + p.read_text(errors="replace")[-3000:])
        return "\n".join(parts)

    def stop(self) -> None:
        """End the three daemons (and nothing else) by their pids: slurmd, slurmctld, then munged."""
        for name in ("slurmd", "slurmctld", "munged"):
            p = self.procs.pop(name, None)
            if p is None or p.poll() is not None:
                continue
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(5)
