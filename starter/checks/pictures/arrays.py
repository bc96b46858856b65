"""Reading the arrays a student's run returned, on the trusted side: each checked by name and shape.

``public_outputs`` returns plain float arrays; ``draw`` reads them back through :func:`need` and
:func:`maybe`, which raise a ``ValueError`` naming the array, the shape expected and what came.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["PictureRunError", "call", "count", "float_array", "matrix3", "maybe", "need", "number", "read", "said"]


class PictureRunError(RuntimeError):
    """A student's function failed (raised, or returned something unusable) on the public data."""


def float_array(value, what: str) -> np.ndarray:
    """``value`` as a float64 array, or PictureRunError naming ``what`` when it is not numeric."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise PictureRunError(f"{what}: expected numbers, got {type(value).__name__} ({exc})") from None
    return a


def matrix3(value, what: str, letter: str) -> np.ndarray:
    """A returned 3x3 matrix (any shape of 9 numbers) as (3, 3) floats, or PictureRunError naming ``what``."""
    a = float_array(value, what)
    if a.size != 9:
        raise PictureRunError(f"{what}: expected a 3x3 {letter}, got shape {a.shape}")
    return a.reshape(3, 3)


def _check(a, name: str, shape: tuple) -> np.ndarray:
    want = "x".join("N" if s is None else str(s) for s in shape)
    ok = a.ndim == len(shape) and all(s is None or s == d for s, d in zip(shape, a.shape))
    if not ok:
        raise ValueError(f"outputs[{name!r}]: expected a {want} float array, got shape {a.shape}")
    return a


def need(outputs: Mapping, name: str, shape: tuple) -> np.ndarray:
    """outputs[name] as a float array of ``shape`` (None: any length); ValueError naming what is wrong."""
    if not isinstance(outputs, Mapping):
        raise ValueError(f"outputs: expected a mapping of names to arrays, got {type(outputs).__name__}")
    if name not in outputs:
        raise ValueError(f"outputs: missing {name!r} (has {sorted(map(str, outputs))})")
    try:
        a = np.asarray(outputs[name], dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"outputs[{name!r}]: expected a float array, got {type(outputs[name]).__name__}") from None
    return _check(a, name, shape)


def maybe(outputs: Mapping, name: str, shape: tuple) -> np.ndarray | None:
    """Like :func:`need`, None when ``name`` is absent (a run that was not made)."""
    return need(outputs, name, shape) if name in outputs else None


def call(fn, name: str, *args):
    """``fn(*args)``, the student's exception turned into a PictureRunError naming ``name`` (type and first line)."""
    try:
        return fn(*args)
    except Exception as exc:  # noqa: BLE001 - any exception of student code is reported, never raised as is
        if isinstance(getattr(exc, "sentence", None), str):  # the grader's sandboxed call: its sentence says it all
            raise PictureRunError(exc.sentence) from None
        first = str(exc).splitlines()[0] if str(exc) else ""
        raise PictureRunError(f"{name} raised {type(exc).__name__} on the public data: {first}") from None


def read(reader, value, *args, name: str):
    """``reader(value, *args)`` (a judging reader), its Malformed turned into a PictureRunError naming ``name``."""
    from judging.verdict import Malformed

    try:
        return reader(value, *args)
    except Malformed as exc:
        raise PictureRunError(f"{name} returned something that cannot be drawn: {exc}") from None


def number(value, name: str) -> np.ndarray:
    """A returned scalar (err, o1...) as a (1,) float array; NaN when it is not one number."""
    try:
        return np.array([float(np.asarray(value, dtype=float).reshape(()))])
    except (TypeError, ValueError):
        return np.array([np.nan])


def count(value) -> np.ndarray:
    """How many numbers a returned scalar holds, as a (1,) float array: 1 for one number, the size
    of an array returned in its place, 0 when it holds no numbers (None, text)."""
    try:
        return np.array([float(np.asarray(value, dtype=float).size)])
    except (TypeError, ValueError):
        return np.array([0.0])


def said(name: str, value: float, size: float | None = None, unit: str = "") -> str:
    """"name = value" for the alt text, or what came instead of one number ("o1 is an array of 4
    numbers, not one number"; ``size`` from :func:`count`, None when not recorded)."""
    from .picture import measure_text

    if size is not None and int(size) != 1:
        return (f"{name} is not a number" if int(size) == 0
                else f"{name} is an array of {int(size)} numbers, not one number")
    return f"{name} = {measure_text(value, unit)}"
