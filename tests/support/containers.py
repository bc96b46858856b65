"""Running a grader program in the shapes the kit is deployed in: a container's capabilities
(Docker's default set, no CAP_SYS_ADMIN) and a venv of the public Python, outside /root.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

import pytest
from core.paths import KIT_ROOT


DOCKER_CAPS = ("-all,+chown,+dac_override,+fowner,+fsetid,+kill,+setgid,+setuid,+setpcap,+net_bind_service,"
               "+net_raw,+sys_chroot,+mknod,+audit_write,+setfcap")


PUBLIC_PYTHON = Path("/usr/bin/python3")


def in_container(argv: list[str]) -> list[str]:
    """``argv`` run as root with Docker's default capabilities only (no CAP_SYS_ADMIN)."""
    return ["setpriv", "--bounding-set", DOCKER_CAPS, "--", *argv]


def run(argv, *, cwd=KIT_ROOT, timeout=900) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST", "HW4_"))}
    env["PYTHONPATH"] = str(cwd)
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout, check=False)


def public_venv(where: Path) -> Path:
    """A venv of the public /usr/bin/python3 holding the kit's packages (hard links); its python."""
    if not PUBLIC_PYTHON.is_file():
        pytest.skip("no public /usr/bin/python3 on this machine")
    ours = subprocess.run([str(PUBLIC_PYTHON), "-c", "import sys; print(sys.version_info[:2])"],
                          capture_output=True, text=True).stdout.strip()
    if ours != str(sys.version_info[:2]):
        pytest.skip(f"/usr/bin/python3 is {ours}, the kit's environment {sys.version_info[:2]}")
    subprocess.run([str(PUBLIC_PYTHON), "-m", "venv", "--without-pip", str(where)], check=True)
    site = where / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
    shutil.rmtree(site)
    subprocess.run(["cp", "-al", sysconfig.get_paths()["purelib"], str(site)], check=True)
    return where / "bin" / "python"


def public_folder() -> Path:
    """A new folder every user can enter, in the machine's shared temporary folder.

    /var/tmp first (it outlives a reboot-cleaned /tmp); some containers have only /tmp.
    """
    shared = next((d for d in ("/var/tmp", "/tmp") if os.path.isdir(d)), None)
    if shared is None:
        pytest.skip("neither /var/tmp nor /tmp exists on this machine")
    root = Path(tempfile.mkdtemp(prefix="hw4-public-", dir=shared))
    os.chmod(root, 0o755)
    return root
