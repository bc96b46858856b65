"""Real students' styles are graded as the handout says (issue 16): tests/realstyles under the
grader, in process under the 20 secrets of the sweep and through the CLI, and under the public
self-checks.

- every valid program gets full marks on every autograded question, under every secret it is
  graded under; every mistake loses the questions its name gives, and only those;
- public and hidden agree: a question's self-checks pass exactly when the grader gives it full
  marks (the self-checks run on the program's own functions, as a student's notebook would);
- the CLI (``python -m autograder grade``, the sandbox) agrees with the in-process grading on
  one secret.

Wrong verdicts of today's grader are listed in ``KNOWN_WRONG`` with the reason: printed, not
failed (the lead empties it as the grader's fixes land); a listed verdict that is right again is
reported too, so that the list shrinks.  Cost (two cores): the in-process grading reuses the
sweep's machinery (``run_here`` on a ``LocalStudent``, ``parallel.fork_map``); each program is
graded under one secret, each program another (all 20 with ``HW4_SWEEP_ALL=1``: about 20 minutes);
the CLI grades one program per layout and the refineF switch's cases under one secret.
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import parallel
import pytest
import realstyles
from realstyles import PROGRAMS, QUESTION_FUNCTIONS
from realstyles import snippets as s

pytestmark = pytest.mark.slow

ALL = frozenset(QUESTION_FUNCTIONS)
SECRETS = [f"sweep-secret-{k:02d}" for k in range(20)][:int(os.environ.get("HW4_SWEEP_SECRETS") or 20)]
# Each program under every STRIDE-th secret in turn (one of the 20, a different one for each of the
# 17 programs); a grading costs 5 to 15 s per program and secret (its own matcher in Python loops).
STRIDE = 1 if os.environ.get("HW4_SWEEP_ALL") else 20
CLI_SECRET = SECRETS[0]
# One program per layout, and the mistakes whose refineF the sandbox must switch off through a module.
CLI_PROGRAMS = tuple(dict.fromkeys([*{p.layout: n for n, p in reversed(PROGRAMS.items())}.values(),
                                    "y2019_submission_py_transposed_helper_refine_loses_Q2",
                                    "y2024_per_part_transposed_refine_inside_loses_Q2"]))
KIT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Known:
    """A wrong verdict of today's grader (or a public check), found by this test and not fixed yet.

    channel: "hidden" (the in-process grading and the CLI: the same tests) or "public";
    program: its name, or None for any; question; why."""

    channel: str
    program: str | None
    question: str
    why: str

    def covers(self, channel, program, question) -> bool:
        return channel == self.channel and question == self.question and self.program in (None, program)


def _using(function: str, source: str) -> tuple[str, ...]:
    return tuple(n for n, p in PROGRAMS.items() if p.pieces.get(function) == source)


def _known(channel, programs, questions, why) -> tuple[Known, ...]:
    return tuple(Known(channel, p, q, why) for p in programs for q in questions)


_RAW = _using("eightpoint", s.EP_REFINE_RAW)
_NINE = _using("eightpoint", s.EP_REFINE_NINE_VECTOR)
_E22 = _using("essentialMatrix", s.ESS_E22)
_FIVE = _using("compute3D_pts", s.C3D_FIVE_P) + _using("compute3D_pts", s.C3D_FIVE_M2_RESULT)
_NONE = _using("compute3D_pts", None)
_INTR = _using("findM2", s.FM_INTR_BOTH) + _using("findM2", s.FM_INTR_CAM1)

# Found on base e878b8e (see the branch's report); the lead empties these as the fixes land.
KNOWN_WRONG: tuple[Known, ...] = (
    *_known("hidden", _RAW, ["Q2"], "refineF switch: rank 2 by refineF alone (the 2022-24 template's own hint) is "
            "judged with refineF switched off, where F is the raw rank-3 SVD solution: 2/10 lost"),
    *_known("hidden", _NINE, ["Q2"], "refineF given the 9-vector: the kit's refineF refuses it (the course's reshaped "
            "it), and with refineF switched off the identity returns the 9-vector to T.T @ F @ T"),
    *_known("hidden", ["y2023_submission_py_util_full"], ["Q2", "Q3.3", "Q5"],
            "the course's helpers imported as util (Fall 2023) are not given: only helper/helpers are"),
    *_known("hidden", _E22, ["Q3.1", "Q3.3"], "E / E[2, 2]: a hidden scene's true E has E[2, 2] = 0 (the scene "
            "envelope must keep E[2, 2] away from zero)"),
    *_known("hidden", ["y2023_per_part_nine_vector_refine_full"], ["Q5"],
            "scipy.optimize.minimize, as the handout says, stops a hair above the optimum (2.46 vs goal 2.43 px^2)"),
    # The public self-checks call only the kit's signatures, and their generated pair has E[2, 2] = 0.
    *_known("public", _INTR, ["Q3.3"], "check_findM2 calls findM2(F, pts1, pts2, K1, K2) only, not another "
            "year's findM2(F, pts1, pts2, intrinsics, filename)"),
    *_known("public", _FIVE, ["Q4.2"], "check_compute3D_pts calls the seven-argument signature only, not "
            "2022-24's compute3D_pts(temple_pts1, intrinsics, F, im1, im2)"),
    *_known("public", _NONE, ["Q4.2"], "no compute3D_pts (2018-21's Q4.2 was a script): the grader grades the "
            "matcher and triangulate, the self-check has nothing to call"),
    *_known("public", _E22, ["Q3.1", "Q3.3"], "E / E[2, 2]: the self-checks' generated pair has E[2, 2] = 0"),
)


# ------------------------------------------------------------------------------------ the corpus

_LOADED: dict = {}


def _secrets_of(k: int, program) -> tuple[str, ...]:
    stride = STRIDE if STRIDE > 1 or not program.costly else 1
    return tuple(SECRETS[k % stride::stride]) or (SECRETS[k % len(SECRETS)],)


@pytest.fixture(scope="module")
def corpus_here(tmp_path_factory):
    """name -> (Loaded, its secrets); the test runs in a scratch folder with results/, as the sandbox."""
    folder = tmp_path_factory.mktemp("realstyles")
    scratch = folder / "work"
    (scratch / "results").mkdir(parents=True)
    (folder / "results").mkdir()
    before = os.getcwd()
    os.chdir(scratch)
    try:
        _LOADED.clear()
        for k, name in enumerate(PROGRAMS):
            _LOADED[name] = (realstyles.load(name, folder / "built"), _secrets_of(k, PROGRAMS[name]))
        yield _LOADED
    finally:
        os.chdir(before)


def _grade_secret(secret: str):
    from autograder.config import quick_config
    from autograder.hidden.inputs import build_hidden_inputs
    from test_secret_sweep import _hidden_files, grade

    hidden = build_hidden_inputs(quick_config(secret=secret))
    concepts = tuple(_hidden_files())
    out, seconds = {}, {}
    for name, (loaded, secrets) in _LOADED.items():
        if secret in secrets:
            started = time.perf_counter()
            with loaded.active():
                out[name] = {q: (score, full, tuple((t.name, t.score, t.max_score, t.feedback) for t in tests))
                             for q, (score, full, tests) in grade(loaded.functions, hidden, concepts).items()}
            seconds[name] = time.perf_counter() - started
    return secret, out, seconds


def _public(name: str):
    """question -> (passed, lines) of the public self-checks on the program's functions."""
    from starter.checks import CHECKS

    loaded, _ = _LOADED[name]
    out = {}
    with loaded.active():
        for q, functions in QUESTION_FUNCTIONS.items():
            passed, lines = True, []
            for f in functions:
                fn = loaded.functions.get(f)
                if fn is None:
                    passed, lines = False, lines + [f"{f} is not defined"]
                    continue
                try:
                    report = CHECKS[f](fn, verbose=False)
                    passed &= bool(report.passed)
                    lines += [f"{f}: {i}" for i in report.items if not getattr(i, "passed", True)][:3]
                except Exception as exc:  # noqa: BLE001 - a check that cannot run is a failed check
                    passed, lines = False, lines + [f"{f}: the check raised {type(exc).__name__}: {exc}"]
            out[q] = (passed, tuple(str(x)[:300] for x in lines))
    return name, out


@pytest.fixture(scope="module")
def hidden_here(corpus_here):
    """secret -> program -> question -> (score, max, tests), for each program's secrets."""
    started = time.perf_counter()
    results = parallel.fork_map(_grade_secret, SECRETS)
    costs: dict[str, float] = {}
    for _, _, seconds in results:
        for n, x in seconds.items():
            costs[n] = costs.get(n, 0.0) + x
    print(f"\nreal styles: {len(PROGRAMS)} programs under {len(SECRETS)} secrets in "
          f"{time.perf_counter() - started:.0f} s; seconds per program over its secrets:")
    for n, x in sorted(costs.items(), key=lambda kv: -kv[1]):
        print(f"  {x:7.1f}  {n}")
    return {secret: per for secret, per, _ in results}


@pytest.fixture(scope="module")
def public_here(corpus_here):
    started = time.perf_counter()
    out = dict(parallel.fork_map(_public, list(PROGRAMS)))
    print(f"\npublic self-checks on {len(out)} programs in {time.perf_counter() - started:.0f} s")
    return out


def _lost(q) -> bool:
    return q[0] < q[1] - 1e-9


def _failing(q) -> str:
    return "; ".join(f"{t[0]} {t[1]:g}/{t[2]:g}: {' / '.join(t[3].splitlines()[:4])}" for t in q[2]
                     if t[1] < t[2] - 1e-9)[:900]


def _report(problems, known, channel):
    cleared = [k for k in KNOWN_WRONG if k.channel == channel and not any(k is kk for kk, _ in known)]
    if known:
        print(f"\nknown wrong verdicts ({channel}), {len(known)}:")
        for k, line in known:
            print(f"  [{k.why}] {line}")
    if cleared:
        print(f"\nKNOWN_WRONG entries ({channel}) not seen this run (fixed, or not drawn):")
        for k in cleared:
            print(f"  {k.program} {k.question}: {k.why}")
    assert not problems, "\n".join(problems)


def _verdict(name, qid, lost):
    p = PROGRAMS[name]
    if qid in p.loses and not lost:
        return "keeps full marks, but must lose it"
    if qid not in p.loses and lost:
        return "loses it, but must keep full marks"
    return None


def _judge_hidden(graded, channel="hidden"):
    problems, known = [], []
    for secret, per in graded.items():
        for name, questions in per.items():
            for qid, q in questions.items():
                wrong = _verdict(name, qid, _lost(q))
                if not wrong:
                    continue
                line = f"{name}, {secret}, {qid} {q[0]:g}/{q[1]:g}: {wrong} ({PROGRAMS[name].why})" + (
                    f": {_failing(q)}" if _lost(q) else "")
                k = next((k for k in KNOWN_WRONG if k.covers("hidden", name, qid)), None)
                (known.append((k, line)) if k else problems.append(line))
    return problems, known


def test_every_program_is_graded_on_every_question(corpus_here, hidden_here):
    assert ALL == frozenset({"Q2", "Q3.1", "Q3.2", "Q3.3", "Q4.1", "Q4.2", "Q5", "Q6"})
    for name, (loaded, secrets) in corpus_here.items():
        assert secrets, name
        assert not loaded.errors or "util" in name, (name, loaded.errors)
        for secret in secrets:
            assert set(hidden_here[secret][name]) == ALL, (name, secret)
    assert {q for p in PROGRAMS.values() for q in p.loses} >= {"Q2", "Q3.1", "Q3.3", "Q4.1", "Q4.2"}
    assert sum(p.valid for p in PROGRAMS.values()) >= 6


def test_valid_programs_full_and_mistakes_lose_their_questions_only(hidden_here):
    problems, known = _judge_hidden(hidden_here)
    _report(problems, known, "hidden")


def test_public_self_checks_agree_with_the_hidden_tests(hidden_here, public_here):
    """Per program and question: the self-checks pass exactly when the grader gives full marks
    under every secret the program was graded under."""
    problems, known = [], []
    for name, public in public_here.items():
        graded = [per[name] for per in hidden_here.values() if name in per]
        for qid, (passed, lines) in public.items():
            full = all(not _lost(g[qid]) for g in graded)
            if passed == full:
                continue
            line = (f"{name}, {qid}: public {'passes' if passed else 'fails'}, hidden "
                    f"{'full' if full else 'not full'}" + (f": {'; '.join(lines)}" if lines else ""))
            k = next((k for k in KNOWN_WRONG if k.covers("public", name, qid)), None)
            if k is None and _verdict(name, qid, not full):  # the hidden side is the wrong one
                k = next((k for k in KNOWN_WRONG if k.covers("hidden", name, qid)), None)
            (known.append((k, line)) if k else problems.append(line))
    _report(problems, known, "public")


def test_cli_grades_as_in_process(tmp_path):
    """The real grader (sandbox, submission reading, draws of its own) under one secret: the same
    verdicts (full or not per question) as expected, the known wrong ones aside."""
    built = []
    for name in CLI_PROGRAMS:  # the gradebook names a hand-in by its file or folder: the program's name
        path = realstyles.build(name, tmp_path / "built")
        built.append(path.rename(tmp_path / f"{name}.zip") if path.suffix == ".zip" else path)
    env = dict(os.environ, HW4_GRADER_SECRET=CLI_SECRET)
    env.pop("HW4_GRADER_CONFIG", None)
    started = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "autograder", "grade", *map(str, built), "--out", str(tmp_path / "out"),
                          "--jobs", str(parallel.workers()), "--quiet"], cwd=KIT, env=env, capture_output=True,
                         text=True, timeout=1500)
    print(f"\nCLI: {len(built)} programs in {time.perf_counter() - started:.0f} s")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    rows = list(csv.DictReader(open(tmp_path / "out" / "grades.csv")))
    problems, known = [], []
    for name in CLI_PROGRAMS:
        row = next((r for r in rows if r.get("student_id") == name), None)
        assert row is not None, f"{name} not in grades.csv: {rows[:1]}"
        for qid in sorted(ALL):
            score = float(row[qid] or 0)
            full = _full_points(qid)
            wrong = _verdict(name, qid, score < full - 1e-9)
            if wrong:
                line = f"{name}, CLI {CLI_SECRET}, {qid} {score:g}/{full:g}: {wrong}"
                k = next((k for k in KNOWN_WRONG if k.covers("hidden", name, qid)), None)
                (known.append((k, line)) if k else problems.append(line))
    if problems or known:
        print("\n".join(["CLI verdicts:"] + [f"  {line}" for _, line in known] + [f"  {p}" for p in problems]))
    assert not problems, "\n".join(problems)


def _full_points(qid: str) -> float:
    from core.manifest import QUESTIONS

    return float(next(q.points for q in QUESTIONS if q.id == qid))
