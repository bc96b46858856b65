"""Q3.3's twisted-pair case, as data: matches on which a findM2 that tests depth in camera 1 only goes wrong.

Of camera2's four candidates, the "twisted pair" (camera 2 turned half a turn about the
baseline, t kept) puts a point in front of camera 1 and behind camera 2.  On these matches (a
forward move, matches near the epipoles) every point is in front of camera 1 under both the
right candidate and the twisted pair, and the twisted pair reprojects clearly better: a findM2
that keeps the candidates with every point in front of camera 1, then the smallest error, picks
it; one that tests the depth in both cameras picks the right camera.

The case is made on the grader's side (it triangulates, so it cannot ship): the public seed's
case is committed as ``twisted_pair.json`` next to this file (``python -m kit check-data``
writes it), and read here.  Numbers are stored as Python writes floats, so the case read is the
case made, bit for bit.

Conventions: pixels (x, y) = (column, row); M = [R | t] world -> camera, camera 1 is [I | 0];
C = K M; F maps points of image 1 to lines of image 2 (x2^T F x1 = 0).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from core.geometry import CameraPair

__all__ = ["CASE_FILE", "TwistedPairCase", "decode", "encode", "public_case"]

CASE_FILE = Path(__file__).with_name("twisted_pair.json")


@dataclass(frozen=True, eq=False)
class TwistedPairCase:
    """Q3.3's twisted-pair case.

    pair : core.geometry.CameraPair, |t| = 1 (camera2's scale); pair.M2 is the right camera, pair.X
        (N, 3) the true points, pair.F the F findM2 is given.
    pts1, pts2 : (N, 2) float, the noisy matches findM2 is given.
    twisted : (3, 4) the twisted-pair candidate (every point in front of camera 1, behind camera 2).
    margin : the largest ratio, over the linear triangulations students write, of the twisted
        pair's total error to the right candidate's (below 1: the twisted pair wins on error).
    """

    pair: CameraPair
    pts1: np.ndarray
    pts2: np.ndarray
    twisted: np.ndarray
    margin: float

    @property
    def F(self) -> np.ndarray:
        return self.pair.F


def encode(case: TwistedPairCase, made_by: str = "") -> str:
    """The JSON text of ``case`` (every float as Python writes it, so it reads back exactly)."""
    p = case.pair
    data = {"made_by": made_by,
            "K1": np.asarray(p.K1, float).tolist(), "K2": np.asarray(p.K2, float).tolist(),
            "M2": np.asarray(p.M2, float).tolist(), "X": np.asarray(p.X, float).tolist(),
            "pts1": np.asarray(case.pts1, float).tolist(), "pts2": np.asarray(case.pts2, float).tolist(),
            "twisted": np.asarray(case.twisted, float).tolist(), "margin": float(case.margin)}
    return "{\n" + ",\n".join(f" {json.dumps(k)}: {json.dumps(v)}" for k, v in data.items()) + "\n}\n"


def decode(text: str) -> TwistedPairCase:
    """The case of the JSON ``text`` written by :func:`encode`."""
    d = json.loads(text)
    pair = CameraPair(np.array(d["K1"], float), np.array(d["K2"], float), np.array(d["M2"], float),
                      np.array(d["X"], float))
    return TwistedPairCase(pair, np.array(d["pts1"], float), np.array(d["pts2"], float),
                           np.array(d["twisted"], float), float(d["margin"]))


@lru_cache(maxsize=1)
def _public_text() -> str:
    return CASE_FILE.read_text(encoding="utf-8")


def public_case() -> TwistedPairCase:
    """The public self-check's case (the public seed's, read from ``twisted_pair.json``)."""
    return decode(_public_text())
