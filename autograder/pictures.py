"""Pictures of what a student's code did on the PUBLIC data: run in the sandbox, drawn by the grader.

Never scored, never on hidden scenes.  The steps, each in the process allowed to do it:

1. ``run_public(student, question)``, in the grading worker's pytest session (the unscored step
   ``autograder/hidden/test_pictures.py``, after every scored check):
   ``starter.checks.pictures.public_outputs`` runs with each student function replaced by a call
   through the sandbox session (``Student.outcome``/``map``), so student code runs only in the
   sandboxed child and what it returns arrives as ``core.wire`` data, decoded with the session's
   size limits, then checked (``_checked``: str names, float arrays, ``LIMITS``).  A run with
   refineF switched off (Q2's second call of eightpoint) is made in the child too, with the
   request's ``swap``; the child says how many times refineF was called in it, a count the
   session believes only as an int in a range (``CallOutcome.refineF_calls``), and the pictures
   module decides from it, as in the self-check, whether that run is drawn.  Each call is given
   ``SECONDS`` of CPU time of the child (times the config's ``time_scale``; the session's ``clock``
   "cpu", as the checks' limits are on Gradescope), so a busy machine does not cost a picture; the
   question's calls stop being made once ``SECONDS`` times the session's ``wall_factor`` of
   wall-clock time have passed (code that waits instead of computing).  Each proxy carries the
   student's parameters as written (``signatures``, the checks' fixture; ``__signature__``), so
   the pictures module calls another year's findM2 or compute3D_pts as the checks do
   (``judging.conventions``).  The answer is plain JSON: ``{"outputs": <wire>}`` or ``{"error":
   "figure not drawn: ..."}``; nothing raised there reaches the grade.
2. ``drawn(question, record)``, in the same worker (the grader's own process, which never runs
   student code; a batch's ``--jobs`` workers draw in parallel): the outputs decoded again and
   drawn (``starter.checks.pictures.draw``, trusted, calls no student code) -> ``{"picture":
   {title, alt, png (base64), measures}}`` or ``{"error": ...}``, for the worker's results file.
3. ``figures_of(raw)``, in the grader, on the record a result of the grading run carries
   (``SubmissionResult.pictures``, with ``GradingRun(..., pictures=True)``): each record checked
   again (known questions, a PNG of at most ``MAX_PNG`` bytes, bounded texts, finite measures;
   ``outputs`` still to draw are drawn here) -> question -> ``Picture``, or the sentence "figure
   not drawn: ...".

Every sentence may quote the student (an exception's message): its writers escape it
(``core.untrusted``).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Mapping

import numpy as np

from core import wire

__all__ = ["LIMITS", "MAX_PNG", "NOT_DRAWN", "SECONDS", "OffRunFailed", "PictureFailed", "contract", "decode",
           "draw_all", "drawn", "figures_of", "finite_measures", "measures_in_words", "run_public"]

NOT_DRAWN = "figure not drawn: "
SECONDS = 10.0          # CPU seconds of one call of a picture (times time_scale)
_MAX_NAMES = 32         # arrays per question
_MAX_NAME = 64          # characters of an array's name
_MAX_ELEMENTS = 1_000_000   # numbers in one array (8 MB as float64)
_MAX_TOTAL = 4_000_000      # numbers in one question's outputs
LIMITS = wire.Limits(max_array_bytes=_MAX_ELEMENTS * 16, max_total_bytes=_MAX_TOTAL * 16, max_string=_MAX_NAME,
                     max_items=_MAX_NAMES * 4, max_depth=4, max_ndim=4)
MAX_PNG = 2_000_000         # bytes of one drawn picture
_MAX_TEXT = 4000            # characters of a title or an alt text
_draw_lock = threading.Lock()   # matplotlib's state is the process's: a batch's threads draw one at a time


class PictureFailed(Exception):
    """A student call of the picture step that did not return: its sentence (``sentence``, also its
    message) is the picture's note unless the pictures module goes on without that call."""

    def __init__(self, sentence: str):
        super().__init__(sentence)
        self.sentence = sentence


class OffRunFailed(Exception):
    """The call with refineF switched off did not return: only that run is left out of the picture."""


def contract():
    """The pictures module (``starter.checks.pictures``): ``QUESTIONS``, ``FUNCTIONS``,
    ``public_outputs``, ``draw``, ``Picture``.  Imported when first needed."""
    from starter.checks import pictures

    return pictures


class _Proxies(Mapping):
    """name -> a callable that calls the student's ``name`` in the sandbox; a call that fails raises
    ``PictureFailed`` and the first failure is kept: it is the picture's note unless the pictures
    module goes on without that call (Q4.2 through the matcher and triangulate when compute3D_pts
    fails) and returns its outputs.

    Each call may use ``seconds`` of CPU time (times ``time_scale``); no call starts once the
    question's wall-clock backstop (``seconds`` times the session's ``wall_factor``, times
    ``time_scale``) has passed.  Each callable has the student's parameters as ``__signature__``
    (``signatures(name)``, a ``judging.conventions.Signature`` or None), so that the pictures
    module's ``judging.conventions`` calls it as the checks do.

    Each callable also has ``map(inputs, args=())``: the values of ``fn(*args, *a)`` for each
    tuple ``a`` of ``inputs``, in one sandbox request, so that common arguments (two images)
    cross the wire once rather than once per call (a pictures module uses it when it is there);
    and ``refineF_switched_off(*args, **kwargs)``: ``(value, calls)``, the call made with refineF
    switched off in the sandbox for it (the request's ``swap``), ``calls`` how many times refineF
    was called during it as the child reported (an int >= 0; 0 when it said nothing believable),
    the signature of ``starter.checks.instrument.refineF_switched_off`` without its ``fn``, which
    the pictures module calls in its place.  A failure of that call raises ``OffRunFailed`` and is
    not kept: like the self-check, the picture only goes without that run (but one that ran out of
    time stops the function in the session, so the question's later calls fail, and the picture)."""

    def __init__(self, student, names, seconds: float, signatures=None):
        self.student, self.names = student, tuple(names)
        self.signatures = signatures
        self.scale = float(getattr(student, "time_scale", 1.0) or 1.0)
        self.session = getattr(student, "session", None)   # a sandbox session: its CPU clock is used
        limits = getattr(getattr(self.session, "rt", None), "limits", None)
        self.wall_factor = float(getattr(limits, "wall_factor", 3.0) or 3.0)
        self.cpu = seconds * self.scale
        self.deadline = time.monotonic() + self.cpu * self.wall_factor
        self.seconds = seconds
        self.failure: str | None = None

    def _seconds(self) -> float:
        """CPU seconds the next call may use; PictureFailed once the question's wall-clock backstop passed."""
        left = self.deadline - time.monotonic()
        if left <= 0.05 * self.scale:
            self.failure = (f"the picture's calls took more than {self.cpu * self.wall_factor:g} s of wall-clock "
                            f"time together (each may use {self.cpu:g} s of CPU time)")
            raise PictureFailed(self.failure)
        return min(self.cpu, left)   # CPU seconds never exceed wall-clock ones

    def _map(self, name: str, inputs, *, args=(), swap=None) -> list:
        """The outcomes of one request, under the CPU clock when the student is a sandbox session."""
        seconds = self._seconds()
        if self.session is not None:
            return self.session.map(name, inputs, args=tuple(args), seconds=seconds, budget=seconds, clock="cpu",
                                    swap=swap)
        return self.student.map(name, inputs, args=tuple(args), seconds=seconds, budget=seconds,
                                **({"swap": swap} if swap else {}))

    def _value(self, name: str, outcome):
        if not outcome.ok:
            from .hidden.feedback import failure

            self.failure = failure(name, outcome)
            raise PictureFailed(self.failure)
        return outcome.value

    def _signature(self, name: str):
        try:
            return self.signatures(name) if self.signatures is not None else None
        except Exception:  # noqa: BLE001 - an unknown signature is the kit's: called the kit's way
            return None

    def __getitem__(self, name):
        if name not in self.names:
            raise KeyError(name)
        from judging.conventions import with_signature

        def call(*args, **kwargs):
            outcome, = self._map(name, [(tuple(args), dict(kwargs))])
            return self._value(name, outcome)

        def each(inputs, args=()):
            """``[call(*args, *a) for a in inputs]`` in one request: ``args`` (the images) cross once."""
            outcomes = self._map(name, [(tuple(a), {}) for a in inputs], args=args)
            return [self._value(name, o) for o in outcomes]

        def switched_off(*args, **kwargs):
            """``(value, calls)`` of ``name(*args, **kwargs)`` with refineF switched off in the sandbox."""
            outcome, = self._map(name, [(tuple(args), dict(kwargs))], swap={"refineF": "off"})
            if not outcome.ok:
                raise OffRunFailed(name)
            # The session already read the child's count as an int in range, or None (not believed).
            return outcome.value, outcome.refineF_calls or 0

        call.__name__ = call.__qualname__ = str(name)
        call.map = each
        call.refineF_switched_off = switched_off
        return with_signature(call, self._signature(name))

    def __iter__(self):
        return iter(self.names)

    def __len__(self):
        return len(self.names)


def run_public(student, question: str, *, seconds: float = SECONDS, root=None, signatures=None) -> dict:
    """The picture step of one question, as JSON-able data for the worker's results file.

    ``student``: the plugin's ``Student`` (or ``LocalStudent``): anything with ``outcome(name,
    *args, seconds=...)`` and ``map(name, inputs, args=..., seconds=..., budget=..., swap=...)``
    (``CallOutcome``s; with ``swap``, their ``refineF_calls``); a ``session`` attribute (the
    plugin's ``Student``) is called directly, under the CPU clock.  ``signatures``: name -> the
    student's ``judging.conventions.Signature`` as written, or None (the checks' fixture).  Returns
    ``{"outputs": wire data}``, ``{"error": "figure not drawn: ..."}``, or ``{}`` when the
    pictures module has no picture of ``question`` (NotImplementedError); never raises for what
    the student's code does (a bug of the picture code is named as the grader's, its type only).
    """
    pictures = contract()
    proxies = _Proxies(student, pictures.FUNCTIONS.get(question, ()), seconds, signatures)
    try:
        outputs = pictures.public_outputs(question, proxies, root=root)
    except PictureFailed as exc:
        return {"error": NOT_DRAWN + (proxies.failure or exc.sentence)}
    except Exception as exc:  # noqa: BLE001 - the picture step never costs the grade
        if isinstance(exc, NotImplementedError) and proxies.failure is None:  # no picture designed: none shown
            return {}
        refused = getattr(pictures, "PictureRunError", ())
        if refused and isinstance(exc, refused):  # what came back cannot be drawn: the module says why
            return {"error": NOT_DRAWN + str(exc)[:1000]}
        if proxies.failure is not None:
            return {"error": NOT_DRAWN + proxies.failure}
        return {"error": f"{NOT_DRAWN}the grader could not run this picture ({type(exc).__name__})"}
    # Outputs came back: the module went on without any call that failed (it says so in its picture).
    try:
        return {"outputs": wire.encode(_checked(outputs))}
    except (ValueError, TypeError) as exc:
        return {"error": f"{NOT_DRAWN}{exc}"}


def _checked(outputs) -> dict[str, np.ndarray]:
    """``outputs`` as the contract says (str names -> float64 arrays), within ``LIMITS``; ValueError."""
    if not isinstance(outputs, Mapping) or len(outputs) > _MAX_NAMES:
        raise ValueError(f"expected at most {_MAX_NAMES} named arrays, got {type(outputs).__name__}")
    out, total = {}, 0
    for name, value in outputs.items():
        if not isinstance(name, str) or not 0 < len(name) <= _MAX_NAME:
            raise ValueError("expected array names of 1 to 64 characters")
        if isinstance(value, np.ndarray) and value.dtype.kind not in "biuf":
            raise ValueError(f"{name}: expected numbers, got {value.dtype} values")
        try:
            arr = np.array(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected numbers") from None
        if arr.ndim > LIMITS.max_ndim or arr.size > _MAX_ELEMENTS:
            raise ValueError(f"{name}: expected at most {_MAX_ELEMENTS} numbers in {LIMITS.max_ndim} dimensions, "
                             f"got {arr.size} in {arr.ndim}")
        total += arr.size
        out[name] = arr
    if total > _MAX_TOTAL:
        raise ValueError(f"expected at most {_MAX_TOTAL} numbers in all, got {total}")
    return out


def decode(raw, questions=None) -> dict:
    """The worker's ``pictures`` record, checked: question -> outputs (str -> float64 array) still
    to draw, a ``Picture`` drawn by the worker, or the sentence why there is no figure.  Unknown questions and malformed entries are dropped or
    turned into a sentence; never raises."""
    if questions is None:
        try:
            questions = tuple(contract().QUESTIONS)
        except ImportError:
            return {}
    out: dict[str, dict | str] = {}
    if not isinstance(raw, Mapping):
        return out
    for q in questions:
        entry = raw.get(q)
        if not isinstance(entry, Mapping):
            continue
        if isinstance(entry.get("error"), str):
            text = entry["error"][:2000]
            out[q] = text if text.startswith(NOT_DRAWN) else NOT_DRAWN + text
            continue
        if "picture" in entry:
            out[q] = _picture_of(q, entry["picture"])
            continue
        try:
            out[q] = _checked(wire.decode(entry.get("outputs"), LIMITS))
        except (wire.WireError, ValueError, TypeError) as exc:
            out[q] = f"{NOT_DRAWN}what came back could not be read ({str(exc)[:200]})"
    return out


def _picture_of(question: str, data):
    """The ``Picture`` a worker drew (``drawn``), checked; the sentence why not when it is malformed."""
    import base64
    import binascii

    try:
        png = base64.b64decode(data["png"], validate=True) if len(data["png"]) <= MAX_PNG * 4 // 3 + 4 else b""
        title, alt = data["title"], data["alt"]
        measures = {str(k)[:_MAX_NAME]: float(v) for k, v in dict(data.get("measures") or {}).items()}
        if not (png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) <= MAX_PNG and isinstance(title, str)
                and isinstance(alt, str) and alt.strip() and len(measures) <= _MAX_NAMES):
            raise ValueError("not a picture")
    except (KeyError, TypeError, ValueError, AttributeError, binascii.Error):
        return f"{NOT_DRAWN}the picture could not be read"
    return contract().Picture(question, title[:_MAX_TEXT], png, alt[:_MAX_TEXT], measures)


def drawn(question: str, record: dict, root=None) -> dict:
    """``record`` (``run_public``'s) with its outputs drawn: ``{"picture": {title, alt, png
    (base64), measures}}`` or ``{"error": ...}`` (the record's own, or why it could not be drawn)."""
    import base64

    figure = draw_all(decode({question: record}, (question,)), root=root).get(question)
    if figure is None:
        return {}
    if isinstance(figure, str):
        return {"error": figure}
    return {"picture": {"title": str(figure.title), "alt": str(figure.alt), "measures": finite_measures(figure),
                        "png": base64.b64encode(figure.png).decode("ascii")}}


def draw_all(decoded: Mapping, root=None) -> dict:
    """question -> ``Picture`` (``starter.checks.pictures.draw`` of its outputs; one drawn already
    stays) or the sentence "figure not drawn: ..." (the step's own, or the drawing's failure,
    named as the grader's)."""
    out: dict = {}
    for q, outputs in decoded.items():
        if not isinstance(outputs, Mapping):  # a sentence, or a Picture drawn already
            out[q] = outputs
            continue
        try:
            with _draw_lock:
                picture = contract().draw(q, outputs, root=root)
            if not (isinstance(picture.png, bytes) and picture.png.startswith(b"\x89PNG")):
                raise ValueError("draw returned no PNG")
            out[q] = picture
        except Exception as exc:  # noqa: BLE001 - a figure that cannot be drawn is a note, not a failure
            out[q] = f"{NOT_DRAWN}the grader could not draw it ({type(exc).__name__})"
    return out


def figures_of(raw, root=None) -> dict:
    """``draw_all(decode(raw))``: question -> ``Picture`` or "figure not drawn: ..."; never raises
    (no pictures module, or anything unexpected: no figures)."""
    try:
        return draw_all(decode(raw), root=root)
    except Exception:  # noqa: BLE001 - pictures never cost the results
        return {}


def finite_measures(picture) -> dict[str, float]:
    """The picture's measures that are finite numbers, by name (for text beside the figure)."""
    out = {}
    for k, v in dict(getattr(picture, "measures", {}) or {}).items():
        try:
            v = float(v)
        except (TypeError, ValueError):
            continue
        if math.isfinite(v):
            out[str(k)] = v
    return out


def measures_in_words(picture) -> list[tuple[str, str]]:
    """(what it measures, its value in its unit) of each finite measure of ``picture``, as the
    pictures module names them (``measure_in_words``); the key and the number when it has none."""
    question = str(getattr(picture, "question", ""))
    try:
        words = contract().measure_in_words
    except (ImportError, AttributeError):
        words = None
    out = []
    for key, value in finite_measures(picture).items():
        try:
            out.append(tuple(map(str, words(question, key, value))) if words else (key, f"{value:.4g}"))
        except Exception:  # noqa: BLE001 - a measure the module cannot name is shown as it is
            out.append((key, f"{value:.4g}"))
    return out
