"""Input checks shared by the starter helpers, the reference solutions and the checks.

Every public function of the kit validates its arguments through these few helpers so that a
wrong input always fails the same way: a ``ValueError`` whose message names the argument, says
what was expected and what arrived.  Point arrays are also cast to float64 here, which is what
protects every caller from the uint16 wrap-around of the official files
(``np.uint16(54) - np.uint16(55) == 65535``).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "as_points",
    "as_matrix",
    "as_image",
    "as_positive_scalar",
    "as_finite_scalar",
    "same_length",
    "DegenerateInputError",
]


class DegenerateInputError(ValueError):
    """The input has the right shape but its geometry does not determine an answer.

    Raised, for example, when all correspondences are collinear or identical, so that the
    eight-point system has more than one solution.  It is a ``ValueError`` so callers that
    already handle bad input keep working, and its message says what was degenerate.
    """


def _describe(a) -> str:
    arr = np.asarray(a) if not isinstance(a, np.ndarray) else a
    return f"an array of shape {arr.shape} and dtype {arr.dtype}"


def _to_array(value, name: str) -> np.ndarray:
    if value is None:
        raise ValueError(f"{name}: expected an array, got None")
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise ValueError(f"{name}: expected an array, got {type(value).__name__} ({exc})") from None
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.number) or arr.dtype == np.bool_
    ):
        raise ValueError(f"{name}: expected a numeric array, got {_describe(arr)}")
    return arr


def _check_finite(arr: np.ndarray, name: str) -> None:
    if np.issubdtype(arr.dtype, np.floating) and not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr)))
        raise ValueError(f"{name}: expected finite values, found {bad} NaN or inf")


def as_points(value, name: str, *, dims: int = 2, min_count: int = 1,
              allow_extra_columns: bool = False) -> np.ndarray:
    """Return ``value`` as a float64 array of shape (N, dims), or raise ValueError.

    Parameters
    ----------
    value : array_like, shape (N, dims)
        Points, one per row.  Integer dtypes (the official files are uint16) are cast to
        float64 *before* any arithmetic, so differences never wrap around.
    name : str
        The argument's name, used in the error message.
    dims : int
        Number of coordinates per point (2 for pixels (x, y) = (column, row), 3 for 3D).
    min_count : int
        Smallest N accepted (8 for the eight-point algorithm).
    allow_extra_columns : bool
        Accept (N, dims + k) and keep only the first ``dims`` columns (keypoints carry a
        confidence in their third column).
    """
    arr = _to_array(value, name)
    if arr.ndim != 2 or arr.shape[1] < dims or (arr.shape[1] != dims and not allow_extra_columns):
        want = f"(N, {dims})" + (" or wider" if allow_extra_columns else "")
        raise ValueError(f"{name}: expected shape {want}, got {_describe(arr)}")
    arr = arr[:, :dims].astype(np.float64)
    _check_finite(arr, name)
    if arr.shape[0] < min_count:
        raise ValueError(f"{name}: expected at least {min_count} points, got {arr.shape[0]}")
    return arr


def as_matrix(value, name: str, shape: tuple[int, int], *, any_layout: bool = False) -> np.ndarray:
    """Return ``value`` as a finite float64 matrix of exactly ``shape``, or raise ValueError.

    With ``any_layout``, any array holding as many numbers as ``shape`` (a flat 9-vector for a
    3x3, say) is accepted and reshaped row by row, as ``np.reshape`` does.
    """
    arr = _to_array(value, name)
    if any_layout and arr.shape != tuple(shape) and arr.size == int(np.prod(shape)):
        arr = arr.reshape(shape)
    if arr.shape != tuple(shape):
        numbers = f" or {int(np.prod(shape))} numbers" if any_layout else ""
        raise ValueError(f"{name}: expected shape {tuple(shape)}{numbers}, got {_describe(arr)}")
    arr = arr.astype(np.float64)
    _check_finite(arr, name)
    return arr


def as_image(value, name: str) -> np.ndarray:
    """Return an image as float64 in [0, 1], shape (H, W) or (H, W, C) with C in {1, 3, 4}.

    uint8 images are divided by 255, uint16 by 65535; float images must already lie in
    [0, 1] (what ``matplotlib.pyplot.imread`` gives for a PNG).  An alpha channel is dropped.
    """
    arr = _to_array(value, name)
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] not in (1, 3, 4)):
        raise ValueError(f"{name}: expected an image of shape (H, W) or (H, W, 3), got {_describe(arr)}")
    if arr.shape[0] < 3 or arr.shape[1] < 3:
        raise ValueError(f"{name}: expected an image at least 3x3 pixels, got {_describe(arr)}")
    if arr.dtype == np.uint8:
        out = arr.astype(np.float64) / 255.0
    elif arr.dtype == np.uint16:
        out = arr.astype(np.float64) / 65535.0
    elif np.issubdtype(arr.dtype, np.floating):
        out = arr.astype(np.float64)
        _check_finite(out, name)
        if out.min() < -1e-6 or out.max() > 1 + 1e-6:
            raise ValueError(
                f"{name}: a float image must lie in [0, 1], got values in "
                f"[{out.min():.3g}, {out.max():.3g}] (divide a 0-255 image by 255)")
    else:
        raise ValueError(f"{name}: expected dtype uint8, uint16 or float, got {_describe(arr)}")
    if out.ndim == 3 and out.shape[2] == 4:
        out = out[:, :, :3]
    return out


def as_finite_scalar(value, name: str) -> float:
    """Return a finite float (a Python number or a 0-d/1-element array), or raise ValueError."""
    try:
        v = float(np.asarray(value, dtype=float).reshape(()))
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(v):
        raise ValueError(f"{name}: expected a finite number, got {v!r}")
    return v


def as_positive_scalar(value, name: str) -> float:
    """Return a finite, strictly positive float, or raise ValueError."""
    try:
        v = as_finite_scalar(value, name)
    except ValueError:
        raise ValueError(f"{name}: expected a positive finite number, got {value!r}") from None
    if v <= 0:
        raise ValueError(f"{name}: expected a positive finite number, got {v!r}")
    return v


def same_length(**arrays: np.ndarray) -> int:
    """Check that all arrays have the same number of rows; return it."""
    lengths = {k: len(v) for k, v in arrays.items()}
    if len(set(lengths.values())) > 1:
        detail = ", ".join(f"{k} has {n}" for k, n in lengths.items())
        raise ValueError(f"expected the same number of points in {', '.join(lengths)}; {detail}")
    return next(iter(lengths.values()))
