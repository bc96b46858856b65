"""Plain-data encoding for values that cross the sandbox boundary, checked strictly when decoded.

Arguments travel from the grader to the sandboxed child and results travel back as JSON text.
Everything that arrives from the child is untrusted, so the decoder accepts only plain data and
bounds its size; nothing is ever unpickled.  This module is the one encoder of both sides: the
grader imports it from ``core`` and so does the sandboxed child (``autograder/sandbox/child.py``),
which finds ``core`` among the kit packages the sandbox exposes.  It uses only the standard
library and numpy.

``encode`` is strict (the grader's own arguments: anything unexpected is a grader bug);
``encode_returned`` is what the child applies to whatever student code returned: objects that are
not plain data are converted to a base-class float64 array when they can be, else refused.

The format:

=====================================  ===========================================================
Python value                           JSON
=====================================  ===========================================================
None, bool, int, str                   themselves
float                                  itself; NaN and infinities as ``{"__float__": "nan"}`` etc.
list                                   a JSON list of encoded items
tuple                                  ``{"__tuple__": [items]}``
dict with str keys                     ``{"__dict__": {key: item}}``
numpy.ndarray (bool, int, uint,        ``{"__ndarray__": base64 of the .npy bytes}``
float, complex dtypes only)            (``np.save(..., allow_pickle=False)``)
=====================================  ===========================================================

A JSON object is always one of the tags above with exactly one key, so a value can never be
mistaken for another one.  Numpy scalars are sent as the Python number of the same value.
"""

from __future__ import annotations

import base64
import binascii
import io
import json
import math
from dataclasses import dataclass

import numpy as np
import numpy.lib.format as npy_format

__all__ = [
    "ALLOWED_DTYPES",
    "Limits",
    "Unsupported",
    "WireError",
    "decode",
    "decode_array",
    "dumps",
    "encode",
    "encode_array",
    "encode_returned",
    "loads",
    "parse_json",
]

ALLOWED_DTYPES: frozenset[np.dtype] = frozenset(
    np.dtype(name)
    for name in (
        "bool", "int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64",
        "float16", "float32", "float64", "complex64", "complex128",
    )
)

_NONFINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}
# Bound at import, before any student code runs in the child: a student who replaces numpy.save
# or numpy.ndarray later changes nothing here.
_np_save = np.save
_ndarray = np.ndarray


class WireError(ValueError):
    """The data is not plain data of the wire format, or is larger than the limits allow."""


@dataclass(frozen=True)
class Limits:
    """Bounds applied while decoding untrusted data.

    max_array_bytes: largest array payload (bytes of the array's data, not of the base64 text);
    max_total_bytes: largest sum of array payloads in one value; max_string: longest str;
    max_items: most list/tuple/dict entries in one value, counted over all levels;
    max_depth: deepest nesting of containers; max_ndim: most array dimensions;
    finite: reject NaN and infinities in floats and float/complex arrays.
    """

    max_array_bytes: int = 64 * 2**20
    max_total_bytes: int = 128 * 2**20
    max_string: int = 100_000
    max_items: int = 100_000
    max_depth: int = 16
    max_ndim: int = 8
    finite: bool = False


# --------------------------------------------------------------------------------------------
# encoding (used by the grader for arguments; strict: anything unexpected is a grader bug)


def encode_array(arr: np.ndarray) -> str:
    """Base64 text of ``arr`` saved as .npy without pickle.

    Parameters
    ----------
    arr : numpy.ndarray, any shape, dtype in ``ALLOWED_DTYPES`` (any byte order)

    Raises
    ------
    WireError
        When ``arr`` is not an exact ndarray or its dtype is not allowed.
    """
    if type(arr) is not np.ndarray:
        raise WireError(f"arr: expected a numpy.ndarray, got {type(arr).__name__}")
    if arr.dtype.newbyteorder("=") not in ALLOWED_DTYPES:
        raise WireError(f"arr: expected a dtype among {_dtype_names()}, got {arr.dtype}")
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def encode(value, *, _depth: int = 0):
    """JSON-compatible form of ``value`` (see the module docstring for what is accepted).

    Raises
    ------
    WireError
        For any other type (including subclasses of ndarray and of the container types), for
        dict keys that are not str, and for nesting deeper than ``Limits().max_depth``.
    """
    if _depth > Limits.max_depth:
        raise WireError(f"value: expected nesting of at most {Limits.max_depth} levels")
    kind = type(value)
    if value is None or kind in (bool, int, str):
        return value
    if kind is float:
        return value if math.isfinite(value) else {"__float__": repr(value)}
    if isinstance(value, (np.bool_, np.integer, np.floating)):
        return encode(value.item(), _depth=_depth)
    if kind is np.ndarray:
        return {"__ndarray__": encode_array(value)}
    if kind is list:
        return [encode(v, _depth=_depth + 1) for v in value]
    if kind is tuple:
        return {"__tuple__": [encode(v, _depth=_depth + 1) for v in value]}
    if kind is dict:
        bad = [k for k in value if type(k) is not str]
        if bad:
            raise WireError(f"value: expected dict keys of type str, got {type(bad[0]).__name__}")
        return {"__dict__": {k: encode(v, _depth=_depth + 1) for k, v in value.items()}}
    raise WireError(
        "value: expected None, bool, int, float, str, list, tuple, dict or numpy.ndarray, "
        f"got {kind.__module__}.{kind.__qualname__}"
    )


def dumps(value) -> str:
    """Strict JSON text of ``encode(value)`` (no NaN literals)."""
    return json.dumps(encode(value), allow_nan=False, separators=(",", ":"))


# --------------------------------------------------------------------------------------------
# encoding what student code returned (in the sandboxed child; lenient, then checked by decode)


class Unsupported(WireError):
    """A returned value that is not plain data and cannot be converted to a float64 array."""


def _npy_text(arr) -> str:
    buf = io.BytesIO()
    _np_save(buf, arr, allow_pickle=False)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _as_float_array(value):
    # The one conversion allowed for objects that are not plain data: whatever they claim to be,
    # what crosses is a base-class float64 array built from them here.
    try:
        arr = np.asarray(value, dtype=np.float64)
    except Exception:  # noqa: BLE001 - any failure means: not convertible
        arr = None
    if type(arr) is not _ndarray or arr.dtype != np.float64:
        raise Unsupported(
            f"returned a {type(value).__name__}, which is not plain data (numpy arrays, numbers, strings, "
            "lists, tuples or dicts of those) and could not be converted to a float64 array")
    return {"__ndarray__": _npy_text(np.array(arr, dtype=np.float64, copy=True))}


def encode_returned(value, _depth: int = 0):
    """JSON-compatible form of a value returned by untrusted code (the child's encoder).

    Like ``encode``, but subclasses of list, tuple and dict are read through the base class's own
    iteration (an overridden ``__iter__`` cannot change what is sent), numpy scalars become Python
    numbers, arrays of other dtypes and any other object become float64 arrays when
    ``numpy.asarray(value, float64)`` gives a base-class array.

    Raises
    ------
    Unsupported
        For anything else, dict keys that are not str, or nesting deeper than ``Limits().max_depth``.
    """
    if _depth > Limits.max_depth:
        raise Unsupported(f"returned data nested deeper than {Limits.max_depth} levels")
    kind = type(value)
    if value is None or kind is bool or kind is int or kind is str:
        return value
    if kind is float:
        return value if math.isfinite(value) else {"__float__": repr(value)}
    if kind is _ndarray:
        if value.dtype.kind in "biufc" and value.dtype.newbyteorder("=") in ALLOWED_DTYPES:
            return {"__ndarray__": _npy_text(value)}
        return _as_float_array(value)
    if kind is np.bool_:
        return bool(value)
    if isinstance(value, np.integer) and kind.__module__ == "numpy":
        return int(value)
    if isinstance(value, np.floating) and kind.__module__ == "numpy":
        return encode_returned(float(value), _depth)
    if kind is complex or (isinstance(value, np.complexfloating) and kind.__module__ == "numpy"):
        return {"__ndarray__": _npy_text(np.asarray(value, dtype=np.complex128))}
    if isinstance(value, list):
        return [encode_returned(v, _depth + 1) for v in list.__iter__(value)]
    if isinstance(value, tuple):
        return {"__tuple__": [encode_returned(v, _depth + 1) for v in tuple.__iter__(value)]}
    if isinstance(value, dict):
        items = list(dict.items(value))
        if not all(type(k) is str for k, _ in items):
            raise Unsupported("returned a dict whose keys are not all strings")
        return {"__dict__": {k: encode_returned(v, _depth + 1) for k, v in items}}
    return _as_float_array(value)


# --------------------------------------------------------------------------------------------
# decoding (used by the grader for results: untrusted input)


def decode_array(text: str, limits: Limits = Limits()) -> np.ndarray:
    """The array whose .npy bytes ``text`` holds in base64, checked before any data is read.

    Parameters
    ----------
    text : str
        Base64 text of an .npy file.
    limits : Limits
        Size, dimension and finiteness bounds.

    Returns
    -------
    numpy.ndarray
        A writable, native byte order array (its own memory) of an allowed dtype.

    Raises
    ------
    WireError
        On bad base64, a malformed header, a dtype outside ``ALLOWED_DTYPES`` (object and
        structured dtypes included), too many dimensions, a payload larger than the limit or of
        the wrong length, or non-finite values when ``limits.finite``.
    """
    if type(text) is not str:
        raise WireError(f"array: expected base64 text, got {type(text).__name__}")
    # base64 is 4/3 of the payload; the header adds at most a few hundred bytes.
    if len(text) > (limits.max_array_bytes + 4096) * 4 // 3 + 8:
        raise WireError(f"array: expected at most {limits.max_array_bytes} bytes, got more")
    try:
        raw = base64.b64decode(text.encode("ascii"), validate=True)
    except (binascii.Error, UnicodeEncodeError) as exc:
        raise WireError(f"array: expected base64 text ({exc})") from None
    buf = io.BytesIO(raw)
    try:
        version = npy_format.read_magic(buf)
        if version == (1, 0):
            shape, fortran, dtype = npy_format.read_array_header_1_0(buf)
        elif version == (2, 0):
            shape, fortran, dtype = npy_format.read_array_header_2_0(buf)
        else:
            raise WireError(f"array: expected .npy format 1.0 or 2.0, got {version}")
    except WireError:
        raise
    except Exception as exc:  # noqa: BLE001 - numpy raises ValueError and friends on a bad header
        raise WireError(f"array: malformed .npy header ({exc})") from None
    if dtype.hasobject or dtype.fields is not None or dtype.newbyteorder("=") not in ALLOWED_DTYPES:
        raise WireError(f"array: expected a dtype among {_dtype_names()}, got {dtype}")
    if len(shape) > limits.max_ndim or any(type(n) is not int or n < 0 for n in shape):
        raise WireError(f"array: expected at most {limits.max_ndim} non-negative dimensions, got {shape}")
    count = math.prod(shape)
    nbytes = count * dtype.itemsize
    if nbytes > limits.max_array_bytes:
        raise WireError(f"array: expected at most {limits.max_array_bytes} bytes, got {nbytes} for {shape}")
    offset = buf.tell()
    if len(raw) - offset != nbytes:
        raise WireError(f"array: header says {nbytes} bytes of data, got {len(raw) - offset}")
    flat = np.frombuffer(raw, dtype=dtype, count=count, offset=offset)
    arr = flat.reshape(shape, order="F" if fortran else "C").astype(dtype.newbyteorder("="), order="C")
    if limits.finite and arr.dtype.kind in "fc" and not np.all(np.isfinite(arr)):
        raise WireError("array: expected finite values, found NaN or inf")
    return arr


def decode(obj, limits: Limits = Limits()):
    """Python value of the JSON-compatible ``obj`` (the inverse of ``encode``), checked.

    Raises
    ------
    WireError
        When ``obj`` is not in the format or exceeds ``limits``.
    """
    budget = {"items": limits.max_items, "bytes": limits.max_total_bytes}
    return _decode(obj, limits, 0, budget)


def loads(text: str | bytes, limits: Limits = Limits()):
    """``decode`` of the JSON text ``text`` (NaN literals and duplicate keys rejected)."""
    return decode(parse_json(text), limits)


def parse_json(text: str | bytes):
    """Strict JSON parse: no NaN/Infinity literals, no duplicate keys; WireError otherwise."""

    def no_constants(name):
        raise WireError(f"json: expected strict JSON, got the literal {name}")

    def no_duplicates(pairs):
        keys = [k for k, _ in pairs]
        if len(set(keys)) != len(keys):
            raise WireError("json: expected unique keys in every object")
        return dict(pairs)

    try:
        return json.loads(text, parse_constant=no_constants, object_pairs_hook=no_duplicates)
    except WireError:
        raise
    except (ValueError, RecursionError, UnicodeDecodeError) as exc:
        raise WireError(f"json: expected JSON text ({type(exc).__name__}: {str(exc)[:200]})") from None


def _decode(obj, limits: Limits, depth: int, budget: dict):
    if depth > limits.max_depth:
        raise WireError(f"value: expected nesting of at most {limits.max_depth} levels")
    kind = type(obj)
    if obj is None or kind in (bool, int):
        return obj
    if kind is float:
        if limits.finite and not math.isfinite(obj):
            raise WireError("value: expected a finite float")
        return obj
    if kind is str:
        if len(obj) > limits.max_string:
            raise WireError(f"value: expected a string of at most {limits.max_string} characters, got {len(obj)}")
        return obj
    if kind is list:
        _spend(budget, "items", len(obj), limits.max_items)
        return [_decode(v, limits, depth + 1, budget) for v in obj]
    if kind is not dict or len(obj) != 1:
        raise WireError(f"value: expected plain data, got a {kind.__name__} that is not in the format")
    (tag, inner), = obj.items()
    if tag == "__ndarray__":
        arr = decode_array(inner, limits)
        _spend(budget, "bytes", arr.nbytes, limits.max_total_bytes)
        return arr
    if tag == "__float__":
        if inner not in _NONFINITE or limits.finite:
            raise WireError(f"value: expected a finite float or one of {sorted(_NONFINITE)}, got {inner!r}")
        return _NONFINITE[inner]
    if tag == "__tuple__" and type(inner) is list:
        _spend(budget, "items", len(inner), limits.max_items)
        return tuple(_decode(v, limits, depth + 1, budget) for v in inner)
    if tag == "__dict__" and type(inner) is dict:
        _spend(budget, "items", len(inner), limits.max_items)
        for key in inner:
            if len(key) > limits.max_string:
                raise WireError("value: expected dict keys of bounded length")
        return {k: _decode(v, limits, depth + 1, budget) for k, v in inner.items()}
    raise WireError(f"value: expected one of the tags __ndarray__, __float__, __tuple__, __dict__, got {tag[:40]!r}")


def _spend(budget: dict, key: str, amount: int, limit: int) -> None:
    budget[key] -= amount
    if budget[key] < 0:
        what = "container entries" if key == "items" else "array bytes"
        raise WireError(f"value: expected at most {limit} {what} in one value")


def _dtype_names() -> list[str]:
    return sorted(str(d) for d in ALLOWED_DTYPES)
