"""Pictures of what a student's code did on the PUBLIC data: run in the sandbox, drawn by the grading worker.

Never scored, never on hidden scenes.  The steps, each in the process allowed to do it:

1. ``run_public(student, question)``, in the grading worker's pytest session (the unscored step
   ``autograder/hidden/test_pictures.py``, after every scored check):
   ``starter.checks.pictures.public_outputs`` runs with each student function replaced by a call
   through the sandbox session (``Student.outcome``/``map``), so student code runs only in the
   sandboxed child and what it returns arrives as ``core.wire`` data, decoded with the session's
   size limits.  A run with
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
   (``judging.conventions``).  That decoding is the one crossing of the trust boundary: the
   outputs are then checked once (``_checked``: str names, float64 arrays, at most
   ``_MAX_ELEMENTS`` numbers an array, ``_MAX_TOTAL`` a question) and given back as those arrays
   (a name -> array dict), or the sentence "figure not drawn: ...", or None (no picture of the
   question); nothing raised there reaches the grade.
2. ``picture_record(student, question)``, in the same worker (the grader's own process, which
   never runs student code; a batch's ``--jobs`` workers draw in parallel): ``run_public``'s
   checked arrays drawn as they are (``starter.checks.pictures.draw``, trusted, calls no student
   code) -> ``{"picture": {title, alt, png (base64), measures}}`` or ``{"error": ...}``, the
   record the worker writes to its results file.
3. ``figures_of(raw)``, in the grader, on the record a result of the grading run carries
   (``SubmissionResult.pictures``, with ``GradingRun(..., pictures=True)``): the worker's files
   are read again, so each entry is checked again (known questions, a PNG of at most ``MAX_PNG``
   bytes, bounded texts, finite measures) -> question -> ``Picture``, or the sentence "figure not
   drawn: ...".  The grader draws nothing: an entry that is not a picture nor a sentence (outputs
   to draw, from an old or hostile worker) is the sentence ``NOT_A_PICTURE``.

Every sentence may quote the student (an exception's message): its writers escape it
(``core.untrusted``).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Mapping

import numpy as np

__all__ = ["MAX_PNG", "NOT_A_PICTURE", "NOT_DRAWN", "SECONDS", "OffRunFailed", "PictureFailed", "contract",
           "figures_of", "finite_measures", "measures_in_words", "picture_record", "run_public"]

NOT_DRAWN = "figure not drawn: "
# An entry of the worker's record that is neither a picture nor a sentence (the outputs an old
# worker sent to be drawn, or a hostile one): the grader draws nothing.
NOT_A_PICTURE = f"{NOT_DRAWN}the grading worker sent no picture (the grader draws none itself)"
SECONDS = 10.0          # CPU seconds of one call of a picture (times time_scale)
_MAX_NAMES = 32         # arrays per question
_MAX_NAME = 64          # characters of an array's name
_MAX_ELEMENTS = 1_000_000   # numbers in one array (8 MB as float64)
_MAX_TOTAL = 4_000_000      # numbers in one question's outputs
_MAX_NDIM = 4               # dimensions of one array
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
            from .words import failure

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


def run_public(student, question: str, *, seconds: float = SECONDS, root=None,
               signatures=None) -> dict[str, np.ndarray] | str | None:
    """The public outputs of one question, run through the sandbox and checked once (``_checked``).

    ``student``: the plugin's ``Student`` (or ``LocalStudent``): anything with ``outcome(name,
    *args, seconds=...)`` and ``map(name, inputs, args=..., seconds=..., budget=..., swap=...)``
    (``CallOutcome``s; with ``swap``, their ``refineF_calls``); a ``session`` attribute (the
    plugin's ``Student``) is called directly, under the CPU clock.  ``signatures``: name -> the
    student's ``judging.conventions.Signature`` as written, or None (the checks' fixture).  Returns
    the checked outputs (str name -> float64 array, what ``starter.checks.pictures.draw`` takes),
    the sentence "figure not drawn: ..." (``NOT_DRAWN``), or None when the pictures module has no
    picture of ``question`` (NotImplementedError); never raises for what the student's code does
    (a bug of the picture code is named as the grader's, its type only).
    """
    pictures = contract()
    proxies = _Proxies(student, pictures.FUNCTIONS.get(question, ()), seconds, signatures)
    try:
        outputs = pictures.public_outputs(question, proxies, root=root)
    except PictureFailed as exc:
        return NOT_DRAWN + (proxies.failure or exc.sentence)
    except Exception as exc:  # noqa: BLE001 - the picture step never costs the grade
        if isinstance(exc, NotImplementedError) and proxies.failure is None:  # no picture designed: none shown
            return None
        refused = getattr(pictures, "PictureRunError", ())
        if refused and isinstance(exc, refused):  # what came back cannot be drawn: the module says why
            return NOT_DRAWN + str(exc)[:1000]
        if proxies.failure is not None:
            return NOT_DRAWN + proxies.failure
        return f"{NOT_DRAWN}the grader could not run this picture ({type(exc).__name__})"
    # Outputs came back: the module went on without any call that failed (it says so in its picture).
    try:
        return _checked(outputs)
    except (ValueError, TypeError) as exc:
        return f"{NOT_DRAWN}{exc}"


def picture_record(student, question: str, *, seconds: float = SECONDS, root=None, signatures=None) -> dict:
    """The worker's record of one question's picture (``run_public``'s arguments), JSON-able:
    ``{"picture": {title, alt, png (base64), measures}}``, ``{"error": "figure not drawn: ..."}``,
    or ``{}`` when the pictures module has no picture of ``question``.  The arrays ``run_public``
    checked are drawn as they are; never raises for what the student's code does."""
    import base64

    outputs = run_public(student, question, seconds=seconds, root=root, signatures=signatures)
    if outputs is None:
        return {}
    figure = outputs if isinstance(outputs, str) else _draw(question, outputs, root)
    if isinstance(figure, str):
        return {"error": figure[:2000]}
    return {"picture": {"title": str(figure.title), "alt": str(figure.alt), "measures": finite_measures(figure),
                        "png": base64.b64encode(figure.png).decode("ascii")}}


def _draw(question: str, outputs: dict[str, np.ndarray], root=None):
    """``starter.checks.pictures.draw`` of checked outputs: its ``Picture``, or the sentence
    "figure not drawn: ..." naming the drawing's failure as the grader's (its type only)."""
    try:
        with _draw_lock:
            picture = contract().draw(question, outputs, root=root)
        if not (isinstance(picture.png, bytes) and picture.png.startswith(b"\x89PNG")):
            raise ValueError("draw returned no PNG")
        return picture
    except Exception as exc:  # noqa: BLE001 - a figure that cannot be drawn is a note, not a failure
        return f"{NOT_DRAWN}the grader could not draw it ({type(exc).__name__})"


def _checked(outputs) -> dict[str, np.ndarray]:
    """``outputs`` as the contract says (str names -> float64 arrays: at most ``_MAX_NAMES`` names of
    ``_MAX_NAME`` characters, ``_MAX_ELEMENTS`` numbers in ``_MAX_NDIM`` dimensions an array,
    ``_MAX_TOTAL`` in all); ValueError naming what is not."""
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
        if arr.ndim > _MAX_NDIM or arr.size > _MAX_ELEMENTS:
            raise ValueError(f"{name}: expected at most {_MAX_ELEMENTS} numbers in {_MAX_NDIM} dimensions, "
                             f"got {arr.size} in {arr.ndim}")
        total += arr.size
        out[name] = arr
    if total > _MAX_TOTAL:
        raise ValueError(f"expected at most {_MAX_TOTAL} numbers in all, got {total}")
    return out


def _picture_of(question: str, data):
    """The ``Picture`` a worker drew (``picture_record``), checked; the sentence why not when it is malformed."""
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


def figures_of(raw, questions=None) -> dict:
    """The worker's ``pictures`` record (``picture_record``'s entries by question), checked again:
    question -> ``Picture`` or the sentence "figure not drawn: ..." (the worker's, escaped by its
    writer, or why the entry could not be read; ``NOT_A_PICTURE`` for anything else, such as
    outputs to draw: the grader draws nothing).  ``questions``: those read (default: the pictures
    module's ``QUESTIONS``); unknown questions and entries that are not mappings are dropped.
    Never raises (no pictures module, or anything unexpected: no figures)."""
    try:
        if questions is None:
            questions = tuple(contract().QUESTIONS)
        out: dict = {}
        if not isinstance(raw, Mapping):
            return out
        for q in questions:
            entry = raw.get(q)
            if not isinstance(entry, Mapping):
                continue
            if isinstance(entry.get("error"), str):
                text = entry["error"][:2000]
                out[q] = text if text.startswith(NOT_DRAWN) else NOT_DRAWN + text
            elif "picture" in entry:
                out[q] = _picture_of(q, entry["picture"])
            else:
                out[q] = NOT_A_PICTURE
        return out
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
