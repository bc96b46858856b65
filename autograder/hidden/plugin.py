"""The pytest plugin of the hidden checks: options, fixtures, the ``points`` marker, the results.

    python -m pytest autograder/hidden --submission PATH [--grading-config FILE] [--results FILE]

runs every hidden check on one submission: one pytest test per check, the student's functions
called through a sandbox session (the ``student`` fixture), judged here in the pytest process.

A check is a plain pytest test::

    @pytest.mark.points(5, question="Q2")
    def test_something(student, hidden, score):
        F = student.call("eightpoint", pts1, pts2, M, seconds=5)   # fails the test if it raises
        assert rank(F) == 2, "F should have rank 2"                  # the message is the feedback
        score.fraction(0.5, "half of the points for ...")            # partial credit (optional)

A test that passes earns its points (times ``score.fraction`` when given); one that fails an
``assert`` (or whose student call failed) earns zero with the message as feedback; any other
error is the grader's: zero with "internal error" for the student and the traceback for staff.
``score.record(...)`` lets a test report finished ``TestResult``/``QuestionResult`` objects.

Options used by the grader (``autograder.grading.run``): ``--hidden-cache`` (the run's folder, saved by
``autograder.inputs.build.save``: the hidden inputs made once, their ``GradingConfig``, and the
run's configuration record; the session's one configuration, so no config file is given with it;
each submission gets its own draw of the inputs, ``autograder.inputs.build.draw``, and the result
is written finished here, stamped with the record, the sandbox level and the draw's short digest,
``configuration["draw"]``, never amended by the grader), ``--sandbox-spec`` (the grader's sandbox,
not probed again), ``--results`` (the ``SubmissionResult`` as JSON, with what staff should see),
``--student-id``, ``--budget`` (the run's, ``autograder.grading.budget``), ``--pictures`` (after the
checks, the unscored picture step of ``test_pictures.py``; its record goes into the results file
as ``pictures``, for ``autograder.feedback.pictures.figures_of``).  By hand, without ``--hidden-cache``, the
configuration is ``--grading-config`` (else ``$HW4_GRADER_CONFIG``, else the defaults), the
inputs are made in the session and the result records the draw only.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import os
import re
import time
from pathlib import Path

import pytest

from core.manifest import QUESTIONS, question
from core.untrusted import for_terminal

from autograder.feedback.words import failure, named_mistakes, notes, tidy, upstream_named

__all__ = ["HIDDEN_DIR", "CheckFailed", "Local", "config_of", "run_here", "LocalStudent", "Score", "Student", "StudentError"]

_OUTPUT_KEPT = 8000
HIDDEN_DIR = Path(__file__).resolve().parent
_loaded: dict = {}          # the run cache this process loaded (inputs.Saved), by the folder and its file
_drawn: dict = {}           # this process's last draws: (id of the batch's inputs, salt) -> (batch, draw)
_DRAWS_KEPT = 4


class StudentError(AssertionError):
    """A call of the student's function that did not return: the test fails with this sentence."""


class CheckFailed(AssertionError):
    """A check that earned nothing: the test fails, its feedback lines are kept as they are."""

    def __init__(self, lines):
        self.lines = [str(line) for line in lines] or ["the check failed"]
        super().__init__("\n".join(self.lines))


# A request of several inputs is timed as a whole, and one input may use this many times its share
# of it, or EACH_FLOOR seconds if more (``_Calls.each``; both times the config's time_scale): enough
# for what a first call may do once (imports, a JIT's compiling, a cache), while a hung input costs
# that much and not every input's time.
EACH_SHARE = 1.5
EACH_FLOOR = 10.0


class _Calls:
    time_scale = 1.0
    cpu_clock = False   # the session's limits are CPU seconds (Gradescope), not wall-clock seconds

    def each(self, function: str, inputs, *, seconds: float, args=(), slack: float = 2.0, figure: bool = False,
             swap=None, kwargs=None):
        """One ``CallOutcome`` per argument tuple of ``inputs``: ``function(*args, *inputs[k], **kwargs)``, all
        within ``seconds`` per input (times the config's ``time_scale``) plus ``slack`` s for the request,
        and one input within ``EACH_SHARE`` times ``seconds`` (at least ``EACH_FLOOR``); ``swap``: what
        is switched off for this request only (``{"refineF": "off"}``, see the child's
        ``refine_switch_for``)."""
        inputs = [(tuple(a), dict(kwargs or {})) for a in inputs]
        budget = float(seconds) * len(inputs) * self.time_scale
        each = max(float(seconds) * EACH_SHARE, EACH_FLOOR) * self.time_scale
        if self.cpu_clock:
            # CPU seconds count the student's code only (no waiting on a loaded machine), so the
            # slack scales with the limits like the budget does; a hung call then costs its budget
            # and little more (Gradescope at time_scale 0.1: 0.25 s instead of 2 to 5 s a request).
            slack = max(0.25, float(slack) * min(1.0, self.time_scale))
        return self.map(function, inputs, args=args, seconds=budget + slack, budget=budget, figure=figure,
                        each=each, **({"swap": swap} if swap else {}))


class Student(_Calls):
    """The student's code, loaded once in a sandbox session; calls are made one at a time.

    ``seconds`` are multiplied by the config's ``time_scale``.
    """

    def __init__(self, session, time_scale: float = 1.0):
        self.session = session
        self.time_scale = time_scale
        self.cpu_clock = session.rt.limits.clock == "cpu"

    @property
    def defined(self) -> tuple[str, ...]:
        """Names of the functions and classes the loaded code defines (starts the child if needed)."""
        self.session.start()
        return self.session.defined

    def outcome(self, function: str, *args, seconds: float, **kwargs):
        """The ``CallOutcome`` of ``function(*args, **kwargs)`` (never raises for the student's behaviour)."""
        return self.session.call(function, *args, seconds=seconds * self.time_scale, **kwargs)

    def fresh_child(self) -> None:
        """Later calls run in a new child that never saw what the earlier ones were given."""
        self.session.restart()

    def call(self, function: str, *args, seconds: float, **kwargs):
        """The value ``function(*args, **kwargs)`` returned; StudentError (a failed check) otherwise."""
        o = self.outcome(function, *args, seconds=seconds, **kwargs)
        if not o.ok:
            raise StudentError(failure(function, o))
        return o.value

    def map(self, function, inputs, *, args=(), seconds, budget=None, each=None, figure=False, swap=None):
        """One ``CallOutcome`` per ``(args, kwargs)`` of ``inputs`` (see ``Session.map``); times are not scaled."""
        return self.session.map(function, inputs, args=args, seconds=seconds, budget=budget, each=each,
                                figure=figure, swap=swap)


_NO_LIMIT = 10**6  # seconds: the in-process stand-in times nothing


class _Records(list):
    """The records of an in-process call, each taken through JSON as the child's pipe takes them
    (a NaN is refused alike)."""

    def send(self, record: dict) -> None:
        self.append(json.loads(json.dumps(record, allow_nan=False)))


class LocalStudent(_Calls):
    """Stand-in for a sandbox session that calls Python functions of this process (tests of the
    checks themselves, on chosen functions; no time limits).  Values cross ``core.wire`` as they would."""

    def __init__(self, functions: dict):
        self.functions = dict(functions)
        self.defined = tuple(sorted(self.functions))
        self.loaded_once, self.load_failure = True, None

    def fresh_child(self) -> None:
        """No child here: the functions are this process's own."""

    def map(self, function, inputs, *, args=(), seconds=None, budget=None, each=None, figure=False, swap=None):
        """One outcome per input, made as the sandbox's child makes them (``child.call_request``,
        read back by ``session.outcome_of``): the same copies of the arguments, refineF switch,
        figure reading and encoding of the value; no time limits."""
        import numpy as np

        from autograder.sandbox import CallOutcome
        from autograder.sandbox.child import call_request
        from autograder.sandbox.session import outcome_of
        from core import wire

        fn = self.functions.get(function)
        if not inputs:
            return []
        if fn is None:
            return [CallOutcome("missing", message=f"{function} is not defined")] * len(inputs)
        request = {"id": "here", "function": function, "args": wire.encode(tuple(args)),
                   "inputs": [{"args": wire.encode(tuple(a)), "kwargs": wire.encode(dict(k))} for a, k in inputs],
                   "seconds": _NO_LIMIT, "budget": _NO_LIMIT, "figure": figure, **({"swap": swap} if swap else {})}
        records = _Records()
        call_request(request, fn, records, set(), 2000, 2**40, wire, np, main_pid=os.getpid())
        limits = wire.Limits(max_array_bytes=2**31, max_total_bytes=2**32)
        got = {r["index"]: outcome_of(r, "wall", swap is not None, limits) for r in records if r.get("event") == "item"}
        rest = CallOutcome("skipped", message=f"not run: {function} stopped on an earlier input")
        return [got.get(k, rest) for k in range(len(inputs))]

    def call(self, function, *args, seconds=None, **kwargs):
        o = self.map(function, [(args, kwargs)])[0]
        if not o.ok:
            raise StudentError(failure(function, o))
        return o.value

    def outcome(self, function, *args, seconds=None, **kwargs):
        return self.map(function, [(args, kwargs)])[0]


class Local:
    """A plugin object that stands in for the sandbox and the hidden inputs of a run (``run_here``):
    ``student`` (a ``LocalStudent``, or anything with its ``map``, ``each``, ``call``, ``outcome`` and
    ``defined``) and ``hidden`` (``HiddenInputs``, or None for the run's own); ``result`` is the
    run's ``SubmissionResult`` once it finished."""

    def __init__(self, student, hidden=None):
        self.student, self.hidden, self.result = student, hidden, None

    def pytest_sessionfinish(self, session):
        self.result = collect_result(session.config)


def _local(config) -> Local | None:
    return next((p for p in config.pluginmanager.get_plugins() if isinstance(p, Local)), None)


def run_here(student, hidden=None, tests=(HIDDEN_DIR,), args=()):
    """The ``SubmissionResult`` of the hidden checks (``tests``: files or folders) run in this
    process on ``student`` (a ``LocalStudent``...), with ``hidden`` inputs: no sandbox, no submission."""
    local = Local(student, hidden)
    pytest.main(["-q", "-s", "-p", "no:cacheprovider", "-c", str(HIDDEN_DIR / "pytest.ini"), "--rootdir",
                 str(HIDDEN_DIR), "--no-header", "-W", "ignore::pytest.PytestAssertRewriteWarning",
                 "-p", "autograder.hidden.plugin", *[str(t) for t in tests],
                 *args], plugins=[local])
    if local.result is None:
        raise RuntimeError("run_here: the pytest session did not finish")
    return local.result


class Score:
    """What a test reports beyond pass/fail: a fraction of its points, feedback lines, finished results."""

    def __init__(self):
        self.value: float | None = None
        self.lines: list[str] = []
        self.results: list = []
        self.mistakes: tuple[str, ...] = ()   # catalogue codes the check's judging named (``grade``)

    def fraction(self, value: float, *lines: str) -> None:
        """Give ``value`` (clipped to [0, 1]) of the test's points, with feedback ``lines``."""
        value = float(value)
        self.value = min(max(value, 0.0), 1.0) if math.isfinite(value) else 0.0
        self.lines += [str(line) for line in lines]

    def feedback(self, *lines: str) -> None:
        self.lines += [str(line) for line in lines]

    def record(self, *results) -> None:
        """Report finished ``TestResult`` or ``QuestionResult`` objects instead of a fraction."""
        self.results += list(results)

    def grade(self, fraction: float, lines=(), mistakes=()) -> None:
        """The check's share of its points and its feedback: ``lines`` (same texts merged), then the
        catalogue ``mistakes`` named when not full marks.  A share of 0 fails the test."""
        fraction = float(fraction) if math.isfinite(float(fraction)) else 0.0
        text = notes(lines, mistakes, passed=fraction >= 1.0)
        # What the judging named, recorded for the class report (never read back from the words).
        self.mistakes = tuple(m.code for m in named_mistakes(mistakes, passed=fraction >= 1.0))
        if fraction <= 0.0:
            raise CheckFailed(text)
        self.fraction(fraction, *text)


# ------------------------------------------------------------------------------------------------
# options, markers and fixtures


@dataclasses.dataclass
class RunState:
    """What one pytest session of the hidden checks keeps about its submission (``config.hw4``).

    started: ``time.monotonic()`` at configuration; results: test node id -> (question id, list of
    ``TestResult``); log: notes for staff only; session: the sandbox session of the checks (None
    before the first check, or in-process); draw: the short digest of the hidden draw graded;
    failure: why the submission could not be graded (then nothing ran); pictures: question -> the
    drawn picture's record.
    """

    started: float = dataclasses.field(default_factory=time.monotonic)
    results: dict = dataclasses.field(default_factory=dict)
    log: list = dataclasses.field(default_factory=list)
    session: object | None = None
    draw: str | None = None
    failure: str | None = None
    pictures: dict = dataclasses.field(default_factory=dict)
    _submission: object | None = None

    def submission(self, path):
        """The parsed submission at ``path`` (``autograder.submission.read.Submission``): read once,
        whichever part of the session asks first.  Raises ``SubmissionError`` when unreadable."""
        if self._submission is None:
            from autograder.submission.read import load_submission

            self._submission = load_submission(path)
        return self._submission

    @property
    def parsed(self):
        """The submission when it was read, else None."""
        return self._submission


def pytest_addoption(parser):
    g = parser.getgroup("hw4", "hidden checks of the homework")
    g.addoption("--submission", default=None, help="the submission to grade (folder or .zip of notebooks)")
    g.addoption("--grading-config", default=None,
                help="grader settings by hand (JSON; default: $HW4_GRADER_CONFIG); not with --hidden-cache")
    g.addoption("--hidden-cache", default=None,
                help="the run's folder (0700): the batch's hidden inputs, their config and the run's record")
    g.addoption("--sandbox-spec", default=None, help="JSON of the grader's sandbox (Sandbox.describe)")
    g.addoption("--isolation", default="auto", help="sandbox level when no --sandbox-spec is given")
    g.addoption("--results", default=None, help="write the SubmissionResult (JSON) here")
    g.addoption("--student-id", default=None, help="the gradebook name of the submission")
    g.addoption("--budget", type=float, default=None, help="seconds for the whole submission (default: from the checks)")
    g.addoption("--keep", default=None, help="the run's keep folder (autograder.inputs.keep): draws made before")
    g.addoption("--secret-scenes", action="store_true", default=False,
                help="grade on the batch's own inputs (the scenes of the secret alone), not on the submission's "
                     "draw: the canary's session")
    g.addoption("--pictures", action="store_true", default=False,
                help="after the checks, run the unscored picture step on the public data (autograder.feedback.pictures)")


def pytest_configure(config):
    config.addinivalue_line("markers", "points(value, question, name=None, visibility='visible'): "
                                       "what a hidden check is worth and which question it counts for")
    config.addinivalue_line("markers", "picture: the unscored picture step (autograder.feedback.pictures), run after every check")
    if config.getoption("--hidden-cache", None) and config.getoption("--grading-config", None):
        # The cache holds the configuration its inputs were made under: a second one could disagree.
        raise pytest.UsageError("--grading-config: expected none with --hidden-cache (the cache holds "
                                "its configuration)")
    config.hw4 = RunState()


def _saved(config):
    """The run's cache (``autograder.inputs.build.Saved``: inputs, their config, the run's record)
    named by ``--hidden-cache``, or None.  A grading worker runs one session after another: each
    run's folder is loaded once (``inputs.load_saved`` checks it is the grader's own)."""
    cache = config.getoption("--hidden-cache", None)
    if not cache:
        return None
    from autograder.inputs import build as inputs

    folder = Path(cache).resolve()
    st = (folder / inputs.SAVED_NAME).stat()
    key = (str(folder), st.st_ino, st.st_mtime_ns, st.st_size)  # a closed run's folder name may come back
    if key not in _loaded:
        _loaded.clear()
        _loaded[key] = inputs.load_saved(folder)
    return _loaded[key]


def config_of(config):
    """The ``GradingConfig`` of a pytest run (known at collection: tests may be parametrized by it):
    a ``Local`` plugin's inputs', else the run cache's (``--hidden-cache``), else by hand
    ``--grading-config`` (``autograder.inputs.config.load_config``: the file, $HW4_GRADER_CONFIG, the defaults)."""
    local = _local(config)
    if local is not None and getattr(local, "hidden", None) is not None:
        return local.hidden.config
    saved = _saved(config)
    if saved is not None:
        return saved.hidden.config
    from autograder.inputs.config import load_config

    return load_config(config.getoption("--grading-config"))


@pytest.fixture(scope="session")
def grading_config(request):
    return config_of(request.config)


@pytest.fixture(scope="session")
def hidden(request, grading_config):
    """The hidden inputs (``autograder.inputs.build.HiddenInputs``) of this submission: its own
    draw (``inputs.draw``, seeded by the secret and the digest of its code) of the batch's inputs,
    which come from the batch's cache or are made here.  A ``Local`` plugin's inputs, or a cache
    holding a draw already, are used as they are; without ``--submission`` or with
    ``--secret-scenes`` (the canary), the batch's."""
    from autograder.inputs import build as inputs
    from autograder.inputs.keep import Keep

    local = _local(request.config)
    if local is not None and getattr(local, "hidden", None) is not None:
        return local.hidden
    saved = _saved(request.config)
    batch = saved.hidden if saved is not None else inputs.build_hidden_inputs(grading_config)
    if (batch.draw is not None or local is not None or not request.config.getoption("--submission")
            or request.config.getoption("--secret-scenes")):
        request.config.hw4.draw = batch.draw
        return batch
    keep = request.config.getoption("--keep")
    drawn = _draw(batch, inputs.code_salt(request.getfixturevalue("submission")), Keep(keep) if keep else None)
    request.config.hw4.draw = drawn.draw
    return drawn


def _draw(batch, salt: str, keep=None):
    """The draw of ``salt`` from ``batch``, made here, in the grading process (outside the sandbox).

    The same code always gets the same draw, so this process keeps its last few, by salt, and
    hands the next submission of the same code (copies of the answer key, students handing in the
    untouched notebooks, a regrade) a copy instead of making it again (about 3 s); the run's
    ``keep`` (``autograder.inputs.keep``), when it has one, holds those of earlier runs.  A
    submission of other code never sees them: its salt is another."""
    from autograder.inputs import build as inputs

    key = (id(batch), salt)
    if key not in _drawn:
        while len(_drawn) >= _DRAWS_KEPT:
            _drawn.pop(next(iter(_drawn)))
        # Kept without its scenes (the checks read only the prepared inputs); the batch kept
        # alive, as its id names it.
        _drawn[key] = (batch, dataclasses.replace(inputs.draw(batch, salt, keep=keep), scenes=None))
    kept = _drawn[key][1]
    return dataclasses.replace(kept, prepared=copy.deepcopy(kept.prepared))  # a check may change its copy only


# The order in which the questions' checks run in the one child of a submission.  A check hands the
# student's code hidden truth (Q3.1 and Q4 get the true F, Q3.2 the true cameras, Q5 a start near
# the true camera): code that keeps what it is given could return it later as another question's
# answer (an eightpoint that returns the F its matcher was given).  So every question is checked
# before any question whose inputs hold its answer: Q2 (F) first, Q3.3 (M2) before Q3.2 (C2 = K2 M2).
# Instructors' extra checks, whose inputs the kit cannot know, come after the kit's own.
CHECK_ORDER = ("Q2", "Q3.1", "Q3.3", "Q3.2", "Q4.1", "Q4.2", "Q5", "Q6")


def check_rank(item) -> tuple[int, int]:
    """Where ``item`` runs: (after every check if it is the picture step, its question's rank in
    ``CHECK_ORDER``, past the end for a check of no known question)."""
    marker = item.get_closest_marker("points")
    qid = marker.kwargs.get("question") if marker is not None else None
    rank = CHECK_ORDER.index(qid) if qid in CHECK_ORDER else len(CHECK_ORDER)
    return (item.get_closest_marker("picture") is not None, rank)


def pytest_collection_modifyitems(session, config, items):
    """Checks run question by question in ``CHECK_ORDER`` (a stable sort: a question's checks keep
    their order); the unscored picture step (marker ``picture``) runs after every check: it cannot
    delay one.  A submission that cannot be read is graded no further: no check runs, the result
    says why."""
    items.sort(key=check_rank)
    path = config.getoption("--submission")
    if not path or _local(config) is not None:
        return
    from autograder.submission.read import SubmissionError

    try:
        sub = config.hw4.submission(path)
    except SubmissionError as exc:
        config.hw4.failure = str(exc)
    else:
        if not sub.notebooks:
            config.hw4.failure = "no notebook of the homework was found (expected files such as q2_eightpoint.ipynb)"
    if config.hw4.failure:
        config.hook.pytest_deselected(items=list(items))
        items[:] = []


@pytest.fixture(scope="session")
def submission(request):
    """The parsed submission (``autograder.submission.read.Submission``), read once per run."""
    path = request.config.getoption("--submission")
    if not path:
        raise pytest.UsageError("--submission: expected the path of a submission to grade, got none")
    return request.config.hw4.submission(path)


@pytest.fixture(scope="session")
def sandbox(request):
    from autograder.sandbox import Sandbox

    spec = request.config.getoption("--sandbox-spec")
    if spec:
        box = Sandbox.attach(json.loads(Path(spec).read_text()))
    else:
        box = Sandbox(hidden=[Path(request.config.getoption("--submission")).resolve().parent],
                      isolation=request.config.getoption("--isolation"))
    yield box
    box.close()


@pytest.fixture(scope="session")
def student(request, grading_config, hidden):
    """The student's code in one sandbox session for all the checks (``Student``), or the
    student of a ``Local`` plugin (tests of the checks themselves)."""
    local = _local(request.config)
    if local is not None:
        yield local.student
        return
    sandbox = request.getfixturevalue("sandbox")
    submission = request.getfixturevalue("submission")
    # The run that started this session gives its budget; by hand, the same definition is used here.
    budget = request.config.getoption("--budget")
    if not budget:
        from autograder.grading.budget import budget_of

        budget = budget_of(hidden, sandbox.limits)
    from autograder.inputs.keep import Keep
    from autograder.sandbox import helpers

    keep = request.config.getoption("--keep")
    # The grader's refineF results (a pure function, the costliest of Q2) are kept with the draws.
    helpers.remember_in(Keep(keep).fetch if keep else None)
    session = sandbox.session(list(submission.units()), load_timeout=grading_config.load_timeout, budget=budget)
    request.config.hw4.session = session
    yield Student(session, grading_config.time_scale)
    session.close()


@pytest.fixture(scope="session")
def signatures(request):
    """``signatures(name)``: the parameters of the student's function ``name`` as written
    (``judging.conventions.Signature``), or None when unknown; lets a check call another
    year's signature as that year's course did."""
    from judging.conventions import signature_of_callable

    local = _local(request.config)
    if local is not None:
        functions = getattr(local.student, "functions", {})
        return lambda name: signature_of_callable(functions[name]) if name in functions else None
    sub = request.getfixturevalue("submission")
    return sub.signature


@pytest.fixture
def score():
    return Score()


# ------------------------------------------------------------------------------------------------
# turning test reports into results


def _marker(item):
    m = item.get_closest_marker("points")
    if m is None:
        return None
    value = m.args[0] if m.args else m.kwargs.get("value")
    qid = m.kwargs.get("question") or (m.args[1] if len(m.args) > 1 else None)
    if qid is None:
        raise pytest.UsageError(f"{item.nodeid}: @pytest.mark.points needs question=")
    name = m.kwargs.get("name") or (item.function.__doc__ or item.name).strip().splitlines()[0].rstrip(".")
    return float(value), str(qid), name, m.kwargs.get("visibility", "visible")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    marker = _marker(item)
    if marker is None or call.when == "teardown" and report.passed:
        return
    if call.when == "setup" and report.passed:
        return
    from autograder.feedback.results import QuestionResult, TestResult

    points, qid, name, visibility = marker
    store = item.config.hw4.results
    if report.skipped and call.when != "teardown":
        return
    score = item.funcargs.get("score") if hasattr(item, "funcargs") else None
    if report.passed and call.when == "call":
        if score is not None and score.results:
            tests = []
            for r in score.results:
                tests += list(r.tests) if isinstance(r, QuestionResult) else [r]
            store[item.nodeid] = (qid, tests)
            return
        fraction = 1.0 if score is None or score.value is None else score.value
        text = "  \n".join(tidy(line) for line in upstream_named(score.lines if score else [], qid))
        store[item.nodeid] = (qid, [TestResult(name, points * fraction, points, fraction >= 1.0, text, visibility,
                                               score.mistakes if score is not None else ())])
        return
    if item.nodeid in store and call.when == "teardown":
        return
    exc = call.excinfo.value if call.excinfo is not None else None
    if isinstance(exc, CheckFailed):
        feedback = "  \n".join(tidy(line) for line in upstream_named(exc.lines, qid))
    elif isinstance(exc, AssertionError):
        message = str(exc).split("\nassert ")[0].strip() or "the check failed"
        feedback = tidy(message)
    else:
        item.config.hw4.log.append(f"{item.nodeid} ({call.when}):\n{report.longreprtext}")
        feedback = ("The autograder could not judge this check because of an internal error; the course staff "
                    "has been told and will grade it.")
    recorded = score.mistakes if isinstance(exc, CheckFailed) and score is not None else ()
    store[item.nodeid] = (qid, [TestResult(name, 0.0, points, False, feedback, visibility, recorded)])


def collect_result(config):
    """The ``SubmissionResult`` of this run (questions in manifest order, then any other question), or
    a failed one when the submission could not be read."""
    from autograder.feedback.results import QuestionResult, SubmissionResult

    state = config.hw4
    if state.failure:
        isolation = _spec_isolation(config)
        return SubmissionResult.failed(state.failure, student_id=config.getoption("--student-id"),
                                       isolation=isolation, execution_time=time.monotonic() - state.started,
                                       configuration=_stamp(config, isolation, None))

    by_q: dict[str, list] = {}
    for qid, tests in state.results.values():
        by_q.setdefault(qid, []).extend(tests)
    _note_own_helpers(config, by_q)
    known = {q.id: q for q in QUESTIONS}
    order = [q.id for q in QUESTIONS if q.id in by_q] + [qid for qid in by_q if qid not in known]
    questions = []
    for qid in order:
        tests = tuple(by_q[qid])
        if qid in known:
            q = question(qid)
            total = sum(t.max_score for t in tests)
            if abs(total - q.points) > 1e-6:
                state.log.append(f"{qid}: the checks add up to {total:g} points, the manifest says {q.points}")
            questions.append(QuestionResult(q.id, q.title, tests, q.extra_credit, q.by_hand))
        else:
            questions.append(QuestionResult(qid, qid, tests))
    session = state.session
    notes: list[str] = []
    isolation = None
    try:
        path = config.getoption("--submission")
        sub = state.submission(path) if path else None
        if sub is not None:
            notes += [str(n) for n in sub.notes()]
    except Exception:  # noqa: BLE001, S110 - an unreadable submission already failed its checks
        pass
    if session is not None:
        info = session.info
        isolation = info.isolation.as_dict()
        notes += _load_notes(info.load_errors)
    isolation = isolation or _spec_isolation(config)
    # Which draw of the hidden scenes was graded, as a short digest only (never a seed or a scene).
    return SubmissionResult(tuple(questions), config.getoption("--student-id"), isolation, tuple(notes), None,
                            time.monotonic() - state.started, _stamp(config, isolation, state.draw))


def _spec_isolation(config) -> dict | None:
    """The isolation of the grader's sandbox (``--sandbox-spec``), for a result no session ran for."""
    spec = config.getoption("--sandbox-spec", None)
    if not spec:
        return None
    try:
        return json.loads(Path(spec).read_text()).get("isolation")
    except (OSError, ValueError, AttributeError):
        return None


def _stamp(config, isolation: dict | None, draw: str | None) -> dict | None:
    """How this result was graded: the run's record (saved in ``--hidden-cache`` with the inputs,
    ``autograder.inputs.config.configuration``) with the sandbox level and the draw's digest; by hand,
    without a run, the draw only."""
    saved = _saved(config)
    record = saved.record if saved is not None else None
    if not isinstance(record, dict):
        return {"draw": draw} if draw else None
    return {**record, "isolation": (isolation or {}).get("level"), "draw": draw}


def _own_helpers(config) -> dict[str, str]:
    """The kit's given helpers (``core.manifest.GIVEN_HELPERS``) the student defines -> where."""
    from core.manifest import GIVEN_HELPERS

    local = _local(config)
    if local is not None:
        return {name: "" for name in getattr(local.student, "functions", {}) if name in GIVEN_HELPERS}
    try:
        path = config.getoption("--submission")
        sub = config.hw4.submission(path) if path else None
    except Exception:  # noqa: BLE001 - an unreadable submission already failed its checks
        return {}
    return sub.own_helpers() if sub is not None else {}


def _note_own_helpers(config, by_q: dict) -> None:
    """Every check that lost points in a question using a given helper the student replaced with
    their own says so: the result may come from their helper, not from the function checked."""
    from dataclasses import replace

    from autograder.submission.read import own_helper_note
    from core.manifest import GIVEN_HELPERS

    own = _own_helpers(config)
    for qid, tests in by_q.items():
        lines = [own_helper_note(name, origin) for name, origin in own.items() if qid in GIVEN_HELPERS[name]]
        if lines:
            tests[:] = [t if t.score >= t.max_score else replace(t, feedback="  \n".join(filter(None, [
                t.feedback, *(tidy(line) for line in lines)]))) for t in tests]


def _load_notes(load_errors) -> list[str]:
    # Most failures while loading are notebook statements that need files (load_temple(), a
    # sibling notebook) and do not matter here; a failed import does, as it breaks what uses it.
    notes = []
    for origin, message in load_errors:
        if re.match(r"(ModuleNotFoundError|ImportError)\b", message):
            notes.append(f"{origin}: {message.split(' (in ', 1)[0]}; code that needs it will fail.")
    return list(dict.fromkeys(notes))[:10]


def pytest_sessionfinish(session, exitstatus):
    config = session.config
    path = config.getoption("--results", None)
    if not path or not hasattr(config, "hw4"):
        return
    result = collect_result(config)
    staff = {"log": list(config.hw4.log)}
    s = config.hw4.session
    if s is not None:
        info = s.info
        staff.update(stdout=info.stdout[:_OUTPUT_KEPT], stderr=info.stderr[:_OUTPUT_KEPT], spawns=info.spawns,
                     swept=info.swept, removed={"entries": info.removed[0], "bytes": info.removed[1],
                                                "not_removed": list(info.not_removed)},
                     over_quota=list(info.over_quota), survived=list(info.survived))
    text = json.dumps({"result": result.to_dict(), "staff": staff, "pictures": config.hw4.pictures},
                      allow_nan=False, default=str)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as fh:
        fh.write(text)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not hasattr(config, "hw4") or not (config.hw4.results or config.hw4.failure):
        return
    result = collect_result(config)
    tr = terminalreporter
    if result.failure:
        tr.section("hidden checks: not graded")
        tr.write_line(for_terminal(result.failure))
        return
    tr.section("hidden checks: points")
    for q in result.questions:
        tr.write_line(f"{q.id:6s} {q.score:7.2f} / {q.max_score:g}")
    tr.write_line(f"total  {result.score:7.2f} / {result.max_score:g}" + (" (+ extra credit)" if any(
        q.extra_credit for q in result.questions) else ""))
    for line in config.hw4.log:
        tr.write_line("grader: " + for_terminal(line.splitlines()[0]))

