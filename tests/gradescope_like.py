"""A Gradescope-like folder for the tests and the benchmarks: the bundle laid out as the platform does."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

__all__ = ["unpack"]


def unpack(bundle: Path, root: Path) -> Path:
    """Lay ``bundle`` out as Gradescope does: <root>/autograder/{source,submission,results}."""
    ag = root / "autograder"
    source = ag / "source"
    source.mkdir(parents=True)
    with zipfile.ZipFile(bundle) as zf:
        for info in zf.infolist():
            path = Path(zf.extract(info, source))
            mode = (info.external_attr >> 16) & 0o777
            if mode:
                path.chmod(mode)
    (ag / "submission").mkdir()
    (ag / "results").mkdir()
    # Gradescope copies run_autograder next to source/ and runs that copy.
    shutil.copy2(source / "run_autograder", ag / "run_autograder")
    return ag
