"""Grader helpers that run INSIDE the sandbox, after the student's code, in the same namespace.

This file is not imported by the grader: its text is sent to the sandbox as the last unit of
the job (``HELPER_UNIT`` in ``autograder/tests/__init__.py``).  It lets one sandbox call run a
student function on several inputs (so a function that hangs costs one timeout, not one per
input), match many points with ``epipolarCorrespondence`` within a time budget, and chain the
matches into the student's ``triangulate``.  It uses only the standard library and numpy, and
names everything ``__hw4_*`` so that nothing clashes with the student's names.

Whatever these helpers return is untrusted (student code ran right beside them and could have
replaced them); the grader only ever judges it as data.

Return format of every helper: ``{"status": "ok", ...}`` or ``{"status": "missing", "name": f}``.
A per-call record is ``{"ok": True, "value": v}`` or ``{"ok": False, "error": "Type: message
(in f, <cell>, line n)"}``.
"""

import sys as __hw4_sys
import time as __hw4_time

import numpy as __hw4_np

__hw4_ORIGIN = "<autograder helpers>"
__hw4_MAX_DEPTH = 12
__hw4_cache = {}


class __hw4_Unreadable(Exception):
    """A returned value that is neither plain data nor convertible to a float array."""


def __hw4_describe(exc):
    """'Type: message (in f, <student cell>, line n)' with the student's innermost frame only."""
    try:
        text = str(exc)
    except Exception:  # noqa: BLE001 - a student's __str__ may fail
        text = "<message unreadable>"
    if len(text) > 400:
        text = text[:400] + " [...]"
    where = ""
    tb = exc.__traceback__
    while tb is not None:
        name = tb.tb_frame.f_code.co_filename
        if name.startswith("<") and name != __hw4_ORIGIN and not name.startswith("<frozen"):
            where = f" (in {tb.tb_frame.f_code.co_name}, {name[1:-1]}, line {tb.tb_lineno})"
        tb = tb.tb_next
    kind = type(exc).__name__
    return f"{kind}: {text}{where}" if text else f"{kind}{where}"


def __hw4_plain(value, depth=0):
    """``value`` as plain data (numbers, str, None, base-class numeric arrays, lists, tuples, dicts)."""
    if depth > __hw4_MAX_DEPTH:
        raise __hw4_Unreadable("returned data nested too deeply")
    kind = type(value)
    if value is None or kind in (bool, int, float, str):
        return value
    if kind is __hw4_np.ndarray:
        if value.dtype.kind in "biufc":
            return __hw4_np.array(value, copy=True)
        return __hw4_as_floats(value)
    if isinstance(value, (__hw4_np.bool_, __hw4_np.integer, __hw4_np.floating)) and type(value).__module__ == "numpy":
        return value.item()
    if kind in (list, tuple):
        items = [__hw4_plain(v, depth + 1) for v in (list.__iter__(value) if kind is list else tuple.__iter__(value))]
        return items if kind is list else tuple(items)
    if kind is dict:
        if not all(type(k) is str for k in dict.keys(value)):
            raise __hw4_Unreadable("returned a dict whose keys are not all strings")
        return {k: __hw4_plain(v, depth + 1) for k, v in dict.items(value)}
    return __hw4_as_floats(value)


def __hw4_as_floats(value):
    try:
        arr = __hw4_np.asarray(value, dtype=__hw4_np.float64)
    except Exception:  # noqa: BLE001 - any failure means: not convertible
        arr = None
    if type(arr) is not __hw4_np.ndarray:
        raise __hw4_Unreadable(f"returned a {type(value).__name__}, which is neither plain data "
                               "(arrays, numbers, tuples, lists) nor convertible to a float array")
    return __hw4_np.array(arr, dtype=__hw4_np.float64, copy=True)


def __hw4_copy(x):
    if type(x) is __hw4_np.ndarray:
        return x.copy()
    if type(x) in (list, tuple):
        return type(x)(__hw4_copy(v) for v in x)
    if type(x) is dict:
        return {k: __hw4_copy(v) for k, v in x.items()}
    return x


def __hw4_function(name):
    fn = globals().get(name)
    return fn if callable(fn) else None


def __hw4_call(fn, args, kwargs):
    """One call on fresh copies of the arguments, as a record."""
    try:
        value = fn(*__hw4_copy(list(args)), **__hw4_copy(dict(kwargs)))
    except Exception as exc:  # noqa: BLE001 - the student's failure is the result
        return {"ok": False, "error": __hw4_describe(exc)}
    try:
        return {"ok": True, "value": __hw4_plain(value)}
    except __hw4_Unreadable as exc:
        return {"ok": False, "error": str(exc)}


def __hw4_each(name, items, budget):
    """Call the student's ``name`` on each (args, kwargs) of ``items`` until ``budget`` seconds pass."""
    fn = __hw4_function(name)
    if fn is None:
        return {"status": "missing", "name": name}
    start = __hw4_time.monotonic()
    out = []
    for args, kwargs in items:
        if __hw4_time.monotonic() - start > budget:
            out.append({"ok": False, "error": f"not run: {name} used up its time on the earlier inputs"})
            continue
        out.append(__hw4_call(fn, args, kwargs))
    return {"status": "ok", "items": out}


def __hw4_point(value):
    """(x2, y2) from what epipolarCorrespondence returned, or None."""
    try:
        arr = __hw4_np.asarray(__hw4_plain(value), dtype=__hw4_np.float64).ravel()
    except Exception:  # noqa: BLE001 - an unreadable point is a wrong point
        return None
    return (float(arr[0]), float(arr[1])) if arr.size == 2 else None


def __hw4_match(key, im1, im2, F, xs, ys, budget):
    """Match each (xs[i], ys[i]) of im1 with the student's epipolarCorrespondence, within ``budget`` s.

    Returns pts2 (N, 2) with NaN rows for points that failed or were not reached, the number of
    errors and the first one; the matches are kept for ``__hw4_pipeline`` under ``key``.
    """
    fn = __hw4_function("epipolarCorrespondence")
    if fn is None:
        return {"status": "missing", "name": "epipolarCorrespondence"}
    n = len(xs)
    pts2 = __hw4_np.full((n, 2), __hw4_np.nan)
    errors, first, reached = 0, "", 0
    start = __hw4_time.monotonic()
    for i in range(n):
        if __hw4_time.monotonic() - start > budget:
            break
        reached += 1
        try:
            value = fn(im1.copy(), im2.copy(), F.copy(), __hw4_np.float64(xs[i]), __hw4_np.float64(ys[i]))
        except Exception as exc:  # noqa: BLE001 - counted as a failed point
            errors += 1
            first = first or __hw4_describe(exc)
            continue
        point = __hw4_point(value)
        if point is None:
            errors += 1
            first = first or "epipolarCorrespondence should return the two numbers (x2, y2)"
            continue
        pts2[i] = point
    __hw4_cache[key] = pts2
    return {"status": "ok", "pts2": pts2, "errors": errors, "first_error": first, "reached": reached}


def __hw4_pipeline(key, im1, im2, F, xs, ys, C1, C2, budget):
    """The student's matches (from ``__hw4_match`` when cached) triangulated by their ``triangulate``."""
    tri = __hw4_function("triangulate")
    if tri is None:
        return {"status": "missing", "name": "triangulate"}
    pts2 = __hw4_cache.get(key)
    if pts2 is None:
        found = __hw4_match(key, im1, im2, F, xs, ys, budget)
        if found["status"] != "ok":
            return found
        pts2 = found["pts2"]
    pts1 = __hw4_np.column_stack([__hw4_np.asarray(xs, float), __hw4_np.asarray(ys, float)])
    good = __hw4_np.all(__hw4_np.isfinite(pts2), axis=1)
    w = __hw4_np.full((len(pts1), 3), __hw4_np.nan)
    if not good.any():
        return {"status": "ok", "w": w, "error": "no point was matched", "pts2": pts2}
    record = __hw4_call(tri, (C1, pts1[good], C2, pts2[good]), {})
    if not record["ok"]:
        return {"status": "ok", "w": w, "error": "triangulate: " + record["error"], "pts2": pts2}
    value = record["value"]
    if isinstance(value, (tuple, list)) and value:
        value = value[0]
    try:
        found = __hw4_np.asarray(value, dtype=float)
        w[good] = found.reshape(int(good.sum()), 3)
    except Exception:  # noqa: BLE001 - reported as unreadable
        return {"status": "ok", "w": w, "error": "triangulate did not return (N, 3) points first", "pts2": pts2}
    return {"status": "ok", "w": w, "error": "", "pts2": pts2}


def __hw4_drawn_points(figure):
    """(K, 3) coordinates drawn in a matplotlib 3D figure or a plotly figure (empty if none)."""
    found = []
    try:
        traces = getattr(figure, "data", None)
        if isinstance(traces, (tuple, list)):
            for tr in traces:
                xyz = [getattr(tr, k, None) for k in ("x", "y", "z")]
                if all(v is not None for v in xyz):
                    found.append(__hw4_np.column_stack([__hw4_np.asarray(v, float).ravel() for v in xyz]))
        for ax in getattr(figure, "axes", None) or []:
            for line in getattr(ax, "lines", []):
                if hasattr(line, "get_data_3d"):
                    found.append(__hw4_np.column_stack([__hw4_np.asarray(v, float).ravel()
                                                        for v in line.get_data_3d()]))
            for coll in getattr(ax, "collections", []):
                offsets = getattr(coll, "_offsets3d", None)
                if offsets is not None:
                    found.append(__hw4_np.column_stack([__hw4_np.asarray(v, float).ravel() for v in offsets]))
    except Exception:  # noqa: BLE001, S110 - whatever cannot be read was not drawn
        pass
    found = [f for f in found if f.ndim == 2 and f.shape[1] == 3]
    return __hw4_np.concatenate(found) if found else __hw4_np.zeros((0, 3))


def __hw4_plot(name, args):
    """Run the student's plotting function ``name``; return the 3D points its figures show.

    The figures looked at: the returned object (a matplotlib or plotly figure, or a kit
    ``Figure3D`` holding both) and any pyplot figure the call opened.
    """
    fn = __hw4_function(name)
    if fn is None:
        return {"status": "missing", "name": name}
    plt = __hw4_sys.modules.get("matplotlib.pyplot")
    before = set(plt.get_fignums()) if plt is not None else set()
    try:
        value = fn(*__hw4_copy(list(args)))
    except Exception as exc:  # noqa: BLE001 - the student's failure is the result
        return {"status": "ok", "items": [{"ok": False, "error": __hw4_describe(exc)}]}
    figures = [value]
    for attr in ("plotly", "matplotlib", "figure", "fig"):
        try:
            figures.append(getattr(value, attr, None))
        except Exception:  # noqa: BLE001, S110 - a hostile attribute is no figure
            pass
    plt = __hw4_sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        figures += [plt.figure(k) for k in sorted(set(plt.get_fignums()) - before)]
    points = [__hw4_drawn_points(f) for f in figures if f is not None]
    drawn = __hw4_np.concatenate(points) if points else __hw4_np.zeros((0, 3))
    return {"status": "ok", "items": [{"ok": True, "value": drawn[:100000]}]}
