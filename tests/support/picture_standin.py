"""A stand-in of ``starter.checks.pictures`` with its contract (``Picture``, ``QUESTIONS``,
``FUNCTIONS``, ``public_outputs``, ``draw``), for the grader's tests of the picture step: small,
fast and independent of the real figures.  Q2 calls ``eightpoint`` on fixed points; Q3.2 calls
``triangulate``; ``draw`` plots the arrays (never calls student code)."""

from __future__ import annotations

import io
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

QUESTIONS = ("Q2", "Q3.2")
FUNCTIONS: Mapping[str, tuple[str, ...]] = {"Q2": ("eightpoint",), "Q3.2": ("triangulate",)}


@dataclass(frozen=True)
class Picture:
    question: str
    title: str
    png: bytes
    alt: str
    measures: Mapping[str, float] = field(default_factory=dict)


def _points():
    rng = np.random.default_rng(0)
    return rng.uniform(0, 640, (12, 2)), rng.uniform(0, 640, (12, 2))


def public_outputs(question: str, functions: Mapping[str, Callable], root=None) -> dict[str, np.ndarray]:
    pts1, pts2 = _points()
    if question == "Q2":
        return {"F": np.array(functions["eightpoint"](pts1, pts2, 640.0), dtype=np.float64)}
    if question == "Q3.2":
        C = np.hstack([np.eye(3), np.zeros((3, 1))])
        value = functions["triangulate"](C, pts1, C, pts2)
        P = value[0] if isinstance(value, tuple) else value
        return {"P": np.array(P, dtype=np.float64)}
    raise ValueError(f"question: expected one of {QUESTIONS}, got {question!r}")


def draw(question: str, outputs: Mapping[str, np.ndarray], root=None) -> Picture:
    from matplotlib.figure import Figure

    name, arr = next(iter(outputs.items()))
    fig = Figure(figsize=(3, 2), dpi=60)
    ax = fig.add_subplot()
    ax.plot(np.ravel(arr)[:200], "o-")
    ax.set_title(f"{question}: {name}")
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return Picture(question, f"{question}: your {name} on the public points", buf.getvalue(),
                   f"A line plot of the {np.size(arr)} numbers of {name} returned on the public points.",
                   {"numbers": float(np.size(arr)), "largest": float(np.nanmax(np.abs(arr))) if np.size(arr) else 0.0})
