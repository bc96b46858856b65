"""The program that runs a student's code inside the sandbox (``python -I -B child.py --result-fd N``).

Everything here runs as the student: this file imports only the standard library and numpy, never
the autograder or the solutions, and whatever it writes is judged by the grader as untrusted
data.  It must stay one self-contained file because the sandbox hides the autograder's folder.

Protocol (see ``autograder/sandbox.py`` for the grader's side):

- stdin holds one JSON job: ``units`` (``{origin, line, source, future}``: top-level code of the
  student's notebooks, executed in order in one fresh module namespace named ``__main__``),
  ``calls`` (``{id, function, args, kwargs, timeout}``, arguments in the wire format of
  ``autograder/wire.py``), ``load_timeout`` (seconds), ``sys_path`` (folders put first on
  ``sys.path``: the kit's ``starter`` and ``scenes``), ``max_result_bytes``, ``max_message``.
- the result pipe (file descriptor N) receives one JSON record per line:
  ``{"event": "loaded", "errors": [{origin, message}], "defined": [names]}``, then for each call
  ``{"event": "start", "id"}`` followed by ``{"id", "status", "value" | "message", "seconds"}``
  where status is ok, exception, timeout, missing or malformed, and finally ``{"event": "done"}``.
- stdout and stderr belong to the student; the grader keeps a bounded copy and trusts neither.
"""

import base64
import io
import json
import math
import os
import signal
import sys
import time
import types

import numpy as np

_np_save = np.save
_ndarray = np.ndarray
_MAIN_PID = os.getpid()
_MAX_DEPTH = 16


class _Timeout(BaseException):
    """Raised by the alarm handler; a BaseException so ``except Exception`` does not swallow it."""


class _Unsupported(Exception):
    """A returned value that is not plain data and could not be converted to float64."""


_armed = False


def _on_alarm(signum, frame):
    if _armed:
        raise _Timeout()


def _arm(seconds):
    global _armed
    _armed = True
    signal.signal(signal.SIGALRM, _on_alarm)
    signal.setitimer(signal.ITIMER_REAL, max(float(seconds), 0.001))


def _disarm():
    global _armed
    _armed = False
    signal.setitimer(signal.ITIMER_REAL, 0)


class _Channel:
    """Writes newline-terminated JSON records to the result pipe; only the first process may."""

    def __init__(self, fd):
        self.fd = fd

    def send(self, record):
        if os.getpid() != _MAIN_PID:
            os._exit(0)
        data = (json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n").encode()
        view = memoryview(data)
        while view:
            try:
                n = os.write(self.fd, view)
            except InterruptedError:
                continue
            except OSError:
                os._exit(3)  # the grader is gone or the student closed the pipe: nothing to report to
            view = view[n:]


# ---------------------------------------------------------------------------------------------
# wire format (a copy of autograder/wire.py's, which this file may not import)


def _decode(obj):
    if isinstance(obj, list):
        return [_decode(v) for v in obj]
    if not isinstance(obj, dict):
        return obj
    (tag, inner), = obj.items()
    if tag == "__ndarray__":
        return np.load(io.BytesIO(base64.b64decode(inner)), allow_pickle=False)
    if tag == "__float__":
        return float(inner)
    if tag == "__tuple__":
        return tuple(_decode(v) for v in inner)
    if tag == "__dict__":
        return {k: _decode(v) for k, v in inner.items()}
    raise ValueError(f"unknown tag {tag!r}")


def _encode_array(arr):
    buf = io.BytesIO()
    _np_save(buf, arr, allow_pickle=False)
    return {"__ndarray__": base64.b64encode(buf.getvalue()).decode("ascii")}


def _as_float_array(value):
    # The one conversion allowed for objects that are not plain data: whatever they claim to be,
    # what crosses is a base-class float64 array built from them here, inside the sandbox.
    try:
        arr = np.asarray(value, dtype=np.float64)
    except _Timeout:
        raise
    except BaseException:  # noqa: BLE001 - any failure means: not convertible
        arr = None
    if type(arr) is not _ndarray or arr.dtype != np.float64:
        name = type(value).__name__
        raise _Unsupported(
            f"returned a {name}, which is not plain data (numpy arrays, numbers, strings, "
            "lists, tuples or dicts of those) and could not be converted to a float64 array"
        )
    return _encode_array(np.array(arr, dtype=np.float64, copy=True))


def _encode(value, depth=0):
    if depth > _MAX_DEPTH:
        raise _Unsupported(f"returned data nested deeper than {_MAX_DEPTH} levels")
    kind = type(value)
    if value is None or kind is bool or kind is int or kind is str:
        return value
    if kind is float:
        return value if math.isfinite(value) else {"__float__": repr(value)}
    if kind is _ndarray:
        if value.dtype.kind in "biuf" or value.dtype.kind == "c":
            return _encode_array(value)
        return _as_float_array(value)
    if kind in (np.bool_,):
        return bool(value)
    if isinstance(value, np.integer) and type(value).__module__ == "numpy":
        return int(value)
    if isinstance(value, np.floating) and type(value).__module__ == "numpy":
        return _encode(float(value), depth)
    if kind is complex or (isinstance(value, np.complexfloating) and type(value).__module__ == "numpy"):
        return _encode_array(np.asarray(value, dtype=np.complex128))
    # Subclasses of the containers are read through the base class's own iteration, so an
    # overridden __iter__ or __getitem__ cannot change what is sent.
    if isinstance(value, list):
        return [_encode(v, depth + 1) for v in list.__iter__(value)]
    if isinstance(value, tuple):
        return {"__tuple__": [_encode(v, depth + 1) for v in tuple.__iter__(value)]}
    if isinstance(value, dict):
        items = list(dict.items(value))
        if not all(type(k) is str for k, _ in items):
            raise _Unsupported("returned a dict whose keys are not all strings")
        return {"__dict__": {k: _encode(v, depth + 1) for k, v in items}}
    return _as_float_array(value)


# ---------------------------------------------------------------------------------------------
# reporting student errors without any grader frame


def _describe(exc, origins, limit):
    """'Type: message (in f, <origin> line n)' with only the student's innermost frame."""
    name = type(exc).__name__
    try:
        text = str(exc)
    except _Timeout:
        raise
    except BaseException:  # noqa: BLE001 - a student's __str__ may raise anything
        text = "<the exception's message could not be read>"
    if len(text) > limit:
        text = text[:limit] + " [...]"
    where = ""
    tb = exc.__traceback__
    while tb is not None:
        code = tb.tb_frame.f_code
        if code.co_filename in origins:
            where = f" (in {code.co_name}, {code.co_filename[1:-1]}, line {tb.tb_lineno})"
        tb = tb.tb_next
    return f"{name}: {text}{where}" if text else f"{name}{where}"


# ---------------------------------------------------------------------------------------------


def _load(units, module, timeout, origins, limit):
    errors = []
    flags = 0
    _arm(timeout)
    try:
        for unit in units:
            filename = f"<{unit['origin']}>"
            origins.add(filename)
            source = "\n" * (max(int(unit.get("line", 1)), 1) - 1) + unit["source"]
            try:
                code = compile(source, filename, "exec", flags=flags, dont_inherit=True)
                exec(code, module.__dict__)  # noqa: S102 - running the student's code is the point
            except _Timeout:
                errors.append({"origin": unit["origin"], "message": f"loading took more than {timeout:g} s"})
                break
            except BaseException as exc:  # noqa: BLE001 - any failure of student code is reported
                errors.append({"origin": unit["origin"], "message": _describe(exc, origins, limit)})
            if os.getpid() != _MAIN_PID:
                os._exit(0)
            for feature in unit.get("future", ()):
                flags |= getattr(__import__("__future__"), feature).compiler_flag
    except _Timeout:
        errors.append({"origin": "loading", "message": f"loading took more than {timeout:g} s"})
    finally:
        _disarm()
    return errors


def _run_call(call, module, origins, limit, max_bytes):
    start = time.perf_counter()
    record = {"id": call["id"]}
    try:
        _arm(call["timeout"])
        try:
            name = call["function"]
            fn = module.__dict__.get(name)
            if not callable(fn):
                what = "is not defined" if name not in module.__dict__ else "is not a function"
                record.update(status="missing", message=f"{name} {what}")
            else:
                args = _decode(call.get("args", {"__tuple__": []}))
                kwargs = _decode(call.get("kwargs", {"__dict__": {}}))
                value = fn(*args, **kwargs)
                record.update(status="ok", value=_encode(value))
        except _Timeout:
            record.update(status="timeout", message=f"took more than {call['timeout']:g} s")
        except _Unsupported as exc:
            record.update(status="malformed", message=str(exc))
        except BaseException as exc:  # noqa: BLE001 - SystemExit and friends included
            record.update(status="exception", message=_describe(exc, origins, limit))
    except _Timeout:
        record.update(status="timeout", message=f"took more than {call['timeout']:g} s")
    except BaseException:  # noqa: BLE001 - e.g. a message whose __str__ itself failed
        record.update(status="exception", message="the code raised an exception that could not be described")
    finally:
        _disarm()
    if os.getpid() != _MAIN_PID:
        os._exit(0)  # a process the student forked must never report
    record["seconds"] = round(time.perf_counter() - start, 6)
    if record["status"] == "ok":
        size = len(json.dumps(record["value"], allow_nan=False))
        if size > max_bytes:
            record = {"id": call["id"], "status": "malformed", "seconds": record["seconds"],
                      "message": f"the returned value is too large ({size} bytes encoded, limit {max_bytes})"}
    return record


def main(argv):
    fd = int(argv[argv.index("--result-fd") + 1])
    os.set_inheritable(fd, False)
    channel = _Channel(fd)
    job = json.loads(sys.stdin.buffer.read())
    sys.stdin = open(os.devnull)  # noqa: SIM115 - input() in student code gets EOF instead of the job
    os.environ["MPLBACKEND"] = "Agg"
    sys.path[:0] = list(job.get("sys_path", []))
    limit = int(job.get("max_message", 500))
    max_bytes = int(job.get("max_result_bytes", 64 * 2**20))

    module = types.ModuleType("__main__")
    module.__dict__["__builtins__"] = __builtins__
    sys.modules["__main__"] = module  # classes the student defines need their module registered
    origins = set()
    errors = _load(job.get("units", []), module, float(job.get("load_timeout", 60)), origins, limit)
    defined = sorted(k for k, v in list(module.__dict__.items())
                     if not k.startswith("__") and isinstance(v, (types.FunctionType, type)))[:2000]
    channel.send({"event": "loaded", "errors": errors[:200], "defined": defined})

    for call in job.get("calls", []):
        channel.send({"event": "start", "id": call["id"]})
        channel.send(_run_call(call, module, origins, limit, max_bytes))
        plt = sys.modules.get("matplotlib.pyplot")
        if plt is not None:
            try:
                plt.close("all")  # figures of one call must not pile up in memory
            except Exception:  # noqa: BLE001, S110 - a student may have replaced pyplot
                pass
    channel.send({"event": "done"})
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except BaseException:  # noqa: BLE001, S110 - a student may have replaced the stream
            pass
    os._exit(0)  # skip interpreter teardown and any atexit hook the student registered


if __name__ == "__main__":
    main(sys.argv)
