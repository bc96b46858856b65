"""How many secrets the long sweeps grade under: CI's breadth, or the release sweep's.

The sweeps (tests/end_to_end/test_secret_sweep.py, tests/judging_tests/test_fundamental_goals.py) cost about 25 s of both
cores per secret together on a fresh clone (8 secrets: 143 and 68 s); 20 of them do not fit CI's
time beside the rest of the suite, nor did 8, nor 4, within its 15 minutes.  So CI grades under
the first ``CI_SECRETS`` (2: each costly program of the sweep under one of them), and ``HW4_SWEEP_ALL=1``
(the release sweep, run before a term's grades are published or after a change to the hidden
tests or scenes) under all ``RELEASE_SECRETS``, with every costly program under every secret.  ``HW4_SWEEP_SECRETS=n`` picks
n (a quick look while editing).
"""

from __future__ import annotations

import os

__all__ = ["CI_SECRETS", "RELEASE", "RELEASE_SECRETS", "secrets"]

RELEASE_SECRETS = 20
CI_SECRETS = 2
RELEASE = bool(os.environ.get("HW4_SWEEP_ALL"))


def secrets(prefix: str) -> list[str]:
    """The sweep's secrets, named ``<prefix>-00``, ``<prefix>-01``...: the same first ones at every breadth."""
    n = int(os.environ.get("HW4_SWEEP_SECRETS") or (RELEASE_SECRETS if RELEASE else CI_SECRETS))
    if n < 1:
        raise ValueError(f"HW4_SWEEP_SECRETS: expected a positive number of secrets, got {n}")
    return [f"{prefix}-{k:02d}" for k in range(n)]
