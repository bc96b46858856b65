"""Shared fixtures: where the official course data is, and the scenes tests reuse."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

# Before numpy is loaded: the suite's two processes (and the kernels, graders and draws they start,
# which inherit this) already keep both cores busy, so a BLAS thread pool per process only spins:
# the draws took about a fifth more CPU with it and no less time.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# jsonschema (under nbformat) imports rfc3987_syntax when installed (jupyter-events brings it), which
# compiles 38 grammars on import: about 2 s of CPU in every test process that reads a notebook.  It
# serves only the "iri" format of draft 7 and later, checked only with a FormatChecker; nbformat
# validates with draft 4 and no format checker, and nothing in the kit uses either.
sys.modules.setdefault("rfc3987_syntax", None)

# The helpers the tests share (tests/support) import by their own names, from any test folder.
sys.path.insert(0, str(Path(__file__).with_name("support")))

import numpy as np  # noqa: E402
import pytest

from core.paths import course_data_dir


@pytest.fixture(scope="session")
def course_data() -> Path:
    """The official course data (``core.paths.course_data_dir``); the test is skipped without its temple."""
    path = course_data_dir()
    if path is None or not (path / "temple" / "some_corresp.npz").exists():
        pytest.skip("official course data not found (put it at ../shared/course-data or set HW4_COURSE_DATA)")
    return path


@pytest.fixture(scope="session")
def official_temple(course_data):
    from starter import load_temple

    return load_temple(course_data)


@pytest.fixture(scope="session")
def homework_data(tmp_path_factory):
    """The kit's default data: data/ when it is there, else generated the same way."""
    from core.paths import KIT_ROOT

    kit_data = KIT_ROOT / "data"
    if (kit_data / "temple" / "some_corresp.npz").exists() and (kit_data / "q6" / "time0.npz").exists():
        return kit_data
    from scenes.defaults import write_default_data

    out = tmp_path_factory.mktemp("default-data")
    write_default_data(out)
    return out


@pytest.fixture(scope="module")
def config_file(tmp_path_factory) -> Path:
    """The quick grading settings (``autograder.inputs.config.quick_config``) in a file of the module's."""
    import json

    from autograder.inputs.config import quick_config

    path = tmp_path_factory.mktemp("config") / "grader.json"
    path.write_text(json.dumps(quick_config().to_dict()))
    return path


@pytest.fixture(scope="module")
def public_python():
    """A venv of the public /usr/bin/python3 (the uid level refuses a Python under /root)."""
    from containers import public_folder, public_venv

    root = public_folder()
    try:
        yield public_venv(root / "venv")
    finally:
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


@pytest.fixture
def two_view(rng):
    """A small image-free two-view scene with known answers: K, M2 = [R | t] (|t| = 1), points.

    Returned as a dict: K1, K2 (3x3), M2 (3x4), X (N, 3) world points in camera-1 coordinates
    in front of both cameras, pts1, pts2 (N, 2) exact pixel projections.
    """
    from core.geometry import project
    from scenes.cameras import intrinsics, rotation_about

    K = intrinsics(800.0, 320.0, 240.0)
    R = rotation_about(rng.normal(size=3), 0.15)
    t = rng.normal(size=3)
    t /= np.linalg.norm(t)
    M2 = np.hstack([R, t[:, None]])
    X = np.column_stack([rng.uniform(-1.5, 1.5, 60), rng.uniform(-1, 1, 60), rng.uniform(5, 8, 60)])
    C1 = K @ np.hstack([np.eye(3), np.zeros((3, 1))])
    return {"K1": K, "K2": K, "M2": M2, "X": X, "C1": C1, "C2": K @ M2,
            "pts1": project(C1, X), "pts2": project(K @ M2, X)}


# The test tiers.  ``python -m pytest -m "not slow"`` is the fast tier a maintainer runs (about a
# minute: pure functions, the scenes, the notebooks' build, the self-checks' verdicts); CI runs
# everything.  A test that starts sandboxes, grading workers, kernels or a browser, or builds
# hidden draws, is marked ``slow``: one by one, or a whole file by its ``pytestmark``.


@pytest.hookimpl(wrapper=True)
def pytest_collection(session):
    """Collect with pytest's cache of rewritten test modules kept, even under PYTHONDONTWRITEBYTECODE.

    pytest rewrites every test module's asserts on import and caches the result beside it
    (tests/__pycache__, ignored by git), but writes that cache only when bytecode may be written.
    Where PYTHONDONTWRITEBYTECODE is set (as on the machines this kit is built on, see .ci/run),
    each process of each run rewrote all the suite's modules again: about 5 s of CPU per process,
    a tenth of the fast tier.  Only collection is changed; the tests run under the setting as given.
    """
    before = sys.dont_write_bytecode
    sys.dont_write_bytecode = False
    try:
        return (yield)
    finally:
        sys.dont_write_bytecode = before


def pytest_collection_modifyitems(config, items):
    if hasattr(config, "workerinput"):  # a pytest-xdist process: every one sorts alike
        _costliest_first(items)


# Two test processes (pytest-xdist), each given a whole file at a time, so that CI's two cores are
# both used (in one process, much of a file's time is spent waiting on sandboxes, kernels, workers
# or a browser).
# Set here rather than in pyproject's addopts so that it is the kit's suite only: a pytest run of an
# instructor's own checks from the kit's folder (docs/hidden-checks.md) stays one plain session.
# ``-n 0`` (or ``-s``, whose output xdist would swallow, or ``--pdb``) runs everything in this
# process, as before; ``-n 4`` more processes.
TEST_PROCESSES = 2


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    option = config.option
    if not config.pluginmanager.hasplugin("xdist") or hasattr(config, "workerinput"):
        return
    if option.numprocesses is None and not (option.capture == "no" or option.usepdb or option.collectonly):
        option.numprocesses = TEST_PROCESSES
    if option.numprocesses and option.dist == "no":
        option.dist = "loadfile"       # a module's fixtures are computed once, in one process
        option.loadscopereorder = False  # the files in the recorded cost order (xdist's: most tests first)


# One keep (autograder.inputs.keep) for the whole suite, made by the first process and inherited by
# the others and by every grader a test starts: many tests grade the same code under the same
# settings (copies of the answer key, quick_config), and each value is made once, by the first
# test that needs it.  A keep already named in the environment is used as it is, and kept.
_SUITE_KEEP: list[str] = []


def pytest_configure(config):
    from autograder.inputs.keep import ENV_KEEP

    if not hasattr(config, "workerinput") and not os.environ.get(ENV_KEEP):
        folder = tempfile.mkdtemp(prefix="kit-suite-keep-")  # 0700
        _SUITE_KEEP.append(folder)
        os.environ[ENV_KEEP] = folder


def pytest_unconfigure(config):
    from autograder.inputs.keep import ENV_KEEP

    while _SUITE_KEEP:
        shutil.rmtree(_SUITE_KEEP.pop(), ignore_errors=True)
        os.environ.pop(ENV_KEEP, None)


# The order the files run in under two processes: costliest first, from the durations a whole
# run recorded (tests/durations.json), so that a long file never starts last and leaves the other
# process idle at the end.  The record holds each file's summed setup, call and teardown seconds
# ("test_x.py") and each test's ("test_x.py::test_y[z]"): a file's cost is that of the tests this
# run selected, so the fast tier is ordered by its own share of each file, not by the whole run's.
# Files the record does not know follow in their usual order.  A whole run with
# HW4_RECORD_DURATIONS set (a path) writes the record there; copy it over tests/durations.json
# when the suite's costs have moved.
DURATIONS_FILE = Path(__file__).with_name("durations.json")
_RECORDED: dict[str, float] = {}


def recorded_durations(path: Path = DURATIONS_FILE) -> dict[str, float]:
    """Name -> seconds (a file's name, or a file's name and a test's), from a record (empty when there
    is none or it cannot be read)."""
    import json

    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return {k: float(v) for k, v in data.items() if isinstance(k, str) and isinstance(v, (int, float))}


def costliest_first(names, durations: dict[str, float]) -> list[str]:
    """``names`` (file names) with the recorded ones first, costliest first; the rest after, as given."""
    known = sorted((n for n in names if n in durations), key=lambda n: -durations[n])
    return known + [n for n in names if n not in durations]


def selection_costs(selected: dict[str, list[str]], durations: dict[str, float]) -> dict[str, float]:
    """File name -> the recorded cost of its ``selected`` tests (file name -> test keys
    ``test_x.py::test_y``): the tests' own seconds, and for tests the record does not name, the
    part of the file's total that no named test accounts for.  Files the record does not know are
    left out."""
    named: dict[str, float] = {}
    for key, seconds in durations.items():
        if "::" in key:
            file = key.split("::", 1)[0]
            named[file] = named.get(file, 0.0) + seconds
    costs = {}
    for file, tests in selected.items():
        known = [durations[t] for t in tests if t in durations]
        rest = len(known) < len(tests) and file in durations
        if known or rest:
            costs[file] = sum(known) + (max(0.0, durations[file] - named.get(file, 0.0)) if rest else 0.0)
    return costs


def _test_key(nodeid: str) -> str:
    """``tests/a/test_x.py::test_y[z]`` -> ``test_x.py::test_y[z]``: a file is known by its name alone."""
    path, _, rest = nodeid.partition("::")
    return path.rsplit("/", 1)[-1] + ("::" + rest if rest else "")


def _costliest_first(items) -> None:
    selected: dict[str, list[str]] = {}
    for item in items:
        selected.setdefault(item.path.name, []).append(_test_key(item.nodeid))
    costs = selection_costs(selected, recorded_durations())
    rank = {name: k for k, name in enumerate(costliest_first(list(selected), costs))}
    items.sort(key=lambda item: rank[item.path.name])  # stable: a file's tests keep their order


def pytest_runtest_logreport(report):
    if os.environ.get("HW4_RECORD_DURATIONS"):
        key = _test_key(report.nodeid)
        for name in (key.split("::", 1)[0], key):
            _RECORDED[name] = _RECORDED.get(name, 0.0) + float(report.duration)


def pytest_sessionfinish(session):
    import json

    target = os.environ.get("HW4_RECORD_DURATIONS")
    if target and _RECORDED and not hasattr(session.config, "workerinput"):  # the controller has every report
        ordered = dict(sorted(((k, round(v, 2)) for k, v in _RECORDED.items()), key=lambda kv: -kv[1]))
        Path(target).write_text(json.dumps(ordered, indent=1) + "\n")
