"""The grader's keep: hidden inputs kept between grading runs, in a folder of the grader's own (opt-in).

Making a run's hidden inputs costs about 3 s and each submission's draw about 2.5 s of the
grader's CPU.  Grading the same code again under the same settings (a class graded again after a
late hand-in, a regrade, a resumed batch, two copies of the answer key) makes exactly the same
values again, and the grader's refineF (``autograder.sandbox.helpers``) polishes the same
matrices again.  With a keep (``GradingRun(keep=FOLDER)``, or ``$HW4_KEEP_INPUTS`` naming the
folder), what was made once is read back instead.

A kept value is named by a digest of everything it is made from: the kit's code (every file of
the grader's packages, ``core.shipping.GRADER_PACKAGES``), the Python, numpy and scipy versions,
and the caller's parts (the config's fingerprint, which covers the secret; the official data's
files; a submission's code salt).  Change any of them and the name is another, so a kept value
is never stale; nothing is ever looked up by anything else.

The folder is the grader's alone: made 0700, and refused when it is not this user's or others
may enter it.  Entries are pickles the grader writes there and nobody else can (each written
to a temporary file, then renamed); the grading run hides the folder from student code like its
own cache.  Nothing is removed: a draw is about 0.5 MB at the kit's quick settings; remove the
folder to empty it.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import platform
import stat
import threading
import zlib
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

from autograder.inputs.config import tree_digest
from core.paths import KIT_ROOT
from core.shipping import GRADER_PACKAGES

__all__ = ["ENV_KEEP", "Keep", "code_digest", "default_keep"]

ENV_KEEP = "HW4_KEEP_INPUTS"


class Keep:
    """The keep folder ``folder`` (made, mode 0700, when missing).

    Raises
    ------
    ValueError
        When ``folder`` exists and is not a folder of this user that only this user may enter.
    """

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder).expanduser().absolute()
        if not self.folder.exists():
            self.folder.mkdir(mode=0o700, parents=True)
        st = self.folder.stat()
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.geteuid() or stat.S_IMODE(st.st_mode) & 0o077:
            raise ValueError(f"keep: expected a folder of this user that only it may enter (mode 700), got "
                             f"{self.folder} (uid {st.st_uid}, mode {stat.S_IMODE(st.st_mode):o}); "
                             f"`chmod 700` it or name another")

    def __repr__(self) -> str:
        return f"Keep({str(self.folder)!r})"

    def fetch(self, parts: tuple[str, ...], make: Callable[[], object]) -> object:
        """The value kept under ``parts`` (strs) for this kit's code, else ``make()``, kept now."""
        name = hashlib.sha256("\x00".join(("hw4-keep", code_digest(), *parts)).encode()).hexdigest()[:40]
        path = self.folder / f"{name}.pickle.z"
        try:
            return pickle.loads(zlib.decompress(path.read_bytes()))  # noqa: S301 - the grader's own 0700 folder
        except Exception:  # noqa: BLE001 - missing, or unreadable (a disk that filled up): made, written over
            pass
        value = make()
        tmp = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(zlib.compress(pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL), 1))
        os.replace(tmp, path)  # two graders making the same value: either file is the value
        return value


def default_keep() -> Keep | None:
    """The keep ``$HW4_KEEP_INPUTS`` names, or None when it is unset or empty."""
    folder = os.environ.get(ENV_KEEP)
    return Keep(folder) if folder else None


@lru_cache(maxsize=1)
def code_digest() -> str:
    """A digest of the grader's code (its packages' .py files) and of the Python, numpy and scipy
    versions, which the kept values were made with."""
    import numpy
    import scipy

    parts = [platform.python_version(), numpy.__version__, scipy.__version__,
             *(tree_digest(KIT_ROOT / package, "**/*.py", package) for package in GRADER_PACKAGES)]
    return hashlib.sha256("\x00".join(parts).encode()).hexdigest()
