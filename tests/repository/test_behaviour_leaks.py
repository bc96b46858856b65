"""Nothing a student can import answers a graded function, by what it computes (not by its text).

tests/repository/test_leaks.py compares text: code that computes a graded answer in other words passes it.
This test runs the code instead.  Every public callable of every module of the packages that ship
to students or that student code may import in the sandbox (``core.shipping``: STUDENT_PACKAGES,
STUDENT_OPTIONAL_PACKAGES, SANDBOX_PACKAGES), functions and classes defined there, is called on the
inputs of each graded function (``core.manifest``) from a small seeded noise-free scene, in the
graded order, in other orders (every permutation up to four arguments, reversed, other years'
orders of ``judging.conventions``, by keyword), and with the cameras and the points passed as two
lists.  Every array in what it returns (nested in tuples, lists, dicts or an object's fields) is
compared with the reference answer (solutions/): on noise-free data every correct method agrees
far within ``RTOL`` of the answer's size (the grader asks 1e-6 of the scene's size,
judging.triangulation.EXACT_RTOL), and F and E are compared up to scale and sign, residuals up to
sign; a bundle adjustment is judged as the grader judges one (judging.bundle.result).

The helpers the handout gives (``starter.__all__``: refineF, camera2, ransacF, rodrigues,
invRodrigues, the loaders and the drawing helpers) are left out: they ship on purpose.  So are
the few callables that act on the machine (``MACHINE``): they install or start a browser.

The calls run in a child process (its own working folder under ``tmp_path``), each bounded in time
(``SECONDS``), every exception caught, so that what a callable changes in its process or writes
in its folder touches nothing else.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import inspect
import io
import itertools
import json
import os
import pkgutil
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from core.paths import KIT_ROOT

RTOL = 1e-4          # share of the answer's largest value (noise-free data: correct methods agree to ~1e-9)
SECONDS = 2.0        # one call
# Callables that act on the machine (install, download or start a browser): never called.
MACHINE = frozenset({"handin.browser.ensure_browser", "handin.browser.run_chromium", "handin.browser.print_playwright",
                     "handin.mathjax.ensure_mathjax", "handin.pdf.main", "handin.code_zip.main",
                     "handin.pdf.build_pdf", "handin.pdf.html_to_pdf"})
NOT_NUMERIC = ("plot_3d_keypoint_video",)   # graded by hand from its video: nothing to compare


# ------------------------------------------------------------------------------------ the scene


def _rotation(v) -> np.ndarray:
    from core.rotations import rodrigues

    return rodrigues(np.asarray(v, float))


def _project(C, X) -> np.ndarray:
    x = np.column_stack([X, np.ones(len(X))]) @ np.asarray(C, float).T
    return x[:, :2] / x[:, 2:]


def _skew(v) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]], float)


def _texture(rng, h, w) -> np.ndarray:
    """A smooth random image (H, W, 3) uint8: distinct windows, so matching has one answer."""
    from scipy.ndimage import gaussian_filter

    im = gaussian_filter(rng.uniform(0, 255, (h, w, 3)), sigma=(1.5, 1.5, 0))
    im = (im - im.min()) / np.ptp(im) * 255
    return im.astype(np.uint8)


def graded_inputs(seed: int = 2026) -> dict[str, tuple]:
    """Graded function -> its arguments, in the kit's signature (core.manifest), on one seeded scene.

    Two views of 14 points 4 to 6 in front of camera 1 = K1 [I | 0], noise-free; a third camera
    and confidences for Q6 (all above Thres); a textured image pair shifted 4 columns for Q4 (F of
    a sideways translation); a start off the truth for Q5.
    """
    rng = np.random.default_rng(seed)
    n = 14
    K1 = np.array([[520.0, 0, 160], [0, 515, 120], [0, 0, 1]])
    K2 = np.array([[540.0, 0, 150], [0, 530, 125], [0, 0, 1]])
    M1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    M2 = np.hstack([_rotation([0.02, -0.12, 0.03]), [[-1.0], [0.05], [0.1]]])
    M3 = np.hstack([_rotation([-0.03, 0.15, -0.02]), [[0.9], [-0.1], [0.2]]])
    X = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-0.8, 0.8, n), rng.uniform(4, 6, n)])
    C1, C2, C3 = K1 @ M1, K2 @ M2, K1 @ M3
    pts1, pts2, pts3 = _project(C1, X), _project(C2, X), _project(C3, X)
    E = _skew(M2[:, 3]) @ M2[:, :3]
    F = np.linalg.inv(K2).T @ E @ np.linalg.inv(K1)
    F = F / np.linalg.norm(F)
    conf = [rng.uniform(0.6, 1.0, (n, 1)) for _ in range(3)]
    # Q4: im2 is im1 moved 4 columns to the right; F of a sideways translation keeps rows.
    im1 = _texture(rng, 60, 80)
    im2 = np.roll(im1, 4, axis=1)
    F_shift = np.array([[0.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    x1, y1 = rng.uniform(20, 50, 5).round(), rng.uniform(15, 45, 5).round()
    K = np.array([[100.0, 0, 40], [0, 100, 30], [0, 0, 1]])
    Cs1, Cs2 = K @ M1, K @ np.hstack([np.eye(3), [[-0.1], [0], [0]]])
    # Q5: the start moved off the truth
    M2_init = np.hstack([_rotation([0.01, -0.005, 0.008]) @ M2[:, :3], M2[:, 3:] + [[0.02], [-0.03], [0.01]]])
    w_init = X + rng.normal(0, 0.02, X.shape)
    from core.rotations import invRodrigues

    x = np.concatenate([w_init.ravel(), invRodrigues(M2_init[:, :3]), M2_init[:, 3]])
    return {
        "eightpoint": (pts1, pts2, 320.0),
        "essentialMatrix": (F, K1, K2),
        "triangulate": (C1, pts1, C2, pts2),
        "findM2": (F, pts1, pts2, K1, K2),
        "epipolarCorrespondence": (im1, im2, F_shift, float(x1[0]), float(y1[0])),
        "compute3D_pts": (im1, im2, F_shift, x1, y1, Cs1, Cs2),
        "rodriguesResidual": (K1, M1, pts1, K2, pts2, x),
        "bundleAdjustment": (K1, M1, pts1, K2, M2_init, pts2, w_init),
        "MultiviewReconstruction": (C1, np.hstack([pts1, conf[0]]), C2, np.hstack([pts2, conf[1]]),
                                    C3, np.hstack([pts3, conf[2]]), 0.5),
    }


# How a helper may be called with a graded function's inputs: name -> (args, kwargs).
def arrangements(function: str, args: tuple, params: tuple[str, ...]) -> dict[str, tuple[tuple, dict]]:
    out = {"as graded": (args, {}), "by keyword": ((), dict(zip(params, args))),
           "reversed": (args[::-1], {})}
    if len(args) <= 4:
        for order in itertools.permutations(range(len(args))):
            out[f"order {order}"] = (tuple(args[k] for k in order), {})
    if function == "findM2":              # Fall 2023: points first; 2022-2024: intrinsics as a dict
        F, p1, p2, K1, K2 = args
        out["points first"] = ((p1, p2, F, K1, K2), {})
        out["intrinsics dict"] = ((F, p1, p2, {"K1": K1, "K2": K2}), {})
    if function == "compute3D_pts":       # 2022-2024: (temple_pts1, intrinsics, F, im1, im2)
        im1, im2, F, x1, y1, C1, C2 = args
        out["five arguments"] = ((np.column_stack([x1, y1]), {"K1": C1[:, :3], "K2": C2[:, :3]}, F, im1, im2), {})
    if function == "epipolarCorrespondence":
        im1, im2, F, x1, y1 = args
        out["point as a pair"] = ((im1, im2, F, (x1, y1)), {})
    if function == "triangulate":         # cameras and points as two lists, or stacked
        C1, p1, C2, p2 = args
        out["two lists"] = (([C1, C2], [p1, p2]), {})
        out["two lists, points first"] = (([p1, p2], [C1, C2]), {})
        out["two stacks"] = ((np.stack([C1, C2]), np.stack([p1, p2])), {})
    if function == "MultiviewReconstruction":
        C1, p1, C2, p2, C3, p3, thres = args
        for cut, label in ((slice(None), ""), (slice(0, 2), ", pixels only")):
            out[f"two lists{label}"] = (([C1, C2, C3], [p1[:, cut], p2[:, cut], p3[:, cut]]), {})
            out[f"two lists and Thres{label}"] = (([C1, C2, C3], [p1[:, cut], p2[:, cut], p3[:, cut]], thres), {})
    if function == "rodriguesResidual":
        K1, M1, p1, K2, p2, x = args
        out["cameras, then points"] = ((K1 @ M1, K2, p1, p2, x), {})
    return out


# ------------------------------------------------------------------------------------- the scan


def shipped_packages() -> tuple[str, ...]:
    from core.shipping import SANDBOX_PACKAGES, STUDENT_OPTIONAL_PACKAGES, STUDENT_PACKAGES

    return tuple(dict.fromkeys(STUDENT_PACKAGES + STUDENT_OPTIONAL_PACKAGES + SANDBOX_PACKAGES))


def given_names() -> frozenset[str]:
    """The handout's helpers, by name (what ``starter`` gives at its top level)."""
    import starter

    return frozenset(starter.__all__)


def modules(packages) -> list:
    out = []
    for name in packages:
        pkg = importlib.import_module(name)
        out.append(pkg)
        for info in pkgutil.walk_packages(getattr(pkg, "__path__", []), name + "."):
            if info.name.rsplit(".", 1)[-1] != "__main__":
                out.append(importlib.import_module(info.name))
    return out


def public_callables(packages, given=frozenset()) -> list[tuple[str, object]]:
    """(module.name, callable) of every public function and class defined in a module of ``packages``
    (re-exports are found where they are defined), and the static and class methods of those classes."""
    out = []
    for module in modules(packages):
        for name, obj in sorted(vars(module).items()):
            if name.startswith("_") or name in given or getattr(obj, "__module__", None) != module.__name__:
                continue
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            where = f"{module.__name__}.{name}"
            if where in MACHINE:
                continue
            out.append((where, obj))
            if inspect.isclass(obj):
                for attr, raw in vars(obj).items():
                    if not attr.startswith("_") and isinstance(raw, (staticmethod, classmethod)):
                        out.append((f"{where}.{attr}", getattr(obj, attr)))
    return out


class _Late(BaseException):
    """A call past its time (BaseException: the callee's ``except Exception`` lets it through)."""


def _on_alarm(signum, frame):
    raise _Late()


def _arrays(value, depth: int = 0) -> list[np.ndarray]:
    """Every float array in ``value``: itself, in tuples, lists, dicts or an object's fields (3 levels)."""
    if depth > 3 or value is None or isinstance(value, (str, bytes)):
        return []
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fiub" and 0 < value.size <= 100_000:
            return [value.astype(float)]
        return []
    out = []
    if isinstance(value, (tuple, list)):
        if 0 < len(value) <= 64:
            with contextlib.suppress(Exception):
                a = np.asarray(value, dtype=float)
                out.append(a)
            for v in value:
                out += _arrays(v, depth + 1)
        return out
    if isinstance(value, dict):
        for v in list(value.values())[:64]:
            out += _arrays(v, depth + 1)
        return out
    fields = (dataclasses.asdict(value) if dataclasses.is_dataclass(value) and not isinstance(value, type) else
              getattr(value, "__dict__", None))
    if isinstance(fields, dict) and not inspect.ismodule(value) and not callable(value):
        for v in list(fields.values())[:64]:
            out += _arrays(v, depth + 1)
    return out


def _unit(a: np.ndarray) -> np.ndarray:
    a = a / np.linalg.norm(a)
    k = np.argmax(np.abs(a))
    return a * np.sign(a.flat[k])


def _same(got: np.ndarray, answer: np.ndarray, kind: str) -> bool:
    if got.size != answer.size or not np.all(np.isfinite(got)):
        return False
    got = got.reshape(answer.shape)
    scale = float(np.abs(answer).max())
    if kind == "up to scale":
        if not np.any(got):
            return False
        return bool(np.allclose(_unit(got), _unit(answer), rtol=0, atol=RTOL))
    if kind == "up to sign":
        return bool(np.allclose(got, answer, rtol=0, atol=RTOL * scale)
                    or np.allclose(-got, answer, rtol=0, atol=RTOL * scale))
    return bool(np.allclose(got, answer, rtol=0, atol=RTOL * scale))


KINDS = {"eightpoint": "up to scale", "essentialMatrix": "up to scale", "rodriguesResidual": "up to sign"}


def references(inputs: dict) -> dict[str, list[np.ndarray]]:
    """Graded function -> the arrays its reference answer returns that a helper must not give: finite,
    not zero, not one of its inputs (a helper that hands an input back answers nothing)."""
    import solutions

    out = {}
    for function, args in inputs.items():
        given = _arrays(args)
        value = getattr(solutions, function)(*args)
        if function == "epipolarCorrespondence":
            value = np.array(value, float)
        keep = []
        for a in _arrays(value):
            if a.size < 2 or not np.all(np.isfinite(a)) or not np.any(a):
                continue
            if any(g.shape == a.shape and np.allclose(g, a, rtol=0, atol=1e-9) for g in given):
                continue
            if not any(k.shape == a.shape and np.array_equal(k, a) for k in keep):
                keep.append(a)
        out[function] = keep
    return out


def _answers(function: str, value, answer: list, args: tuple, ba_goal: float) -> bool:
    if function == "bundleAdjustment":
        from judging.bundle import result

        K1, M1, p1, K2, M2_init, p2, w_init = args
        arrays = _arrays(value)
        for M2 in (a for a in arrays if a.shape == (3, 4)):
            for w in (a for a in arrays if a.shape == w_init.shape):
                with contextlib.suppress(Exception):
                    if result(M2, w, K1, K2, p1, p2, M2_init, w_init, ba_goal).passed:
                        return True
        return False
    kind = KINDS.get(function, "as is")
    return any(_same(got, a, kind) for got in _arrays(value) for a in answer)


def _copy(value):
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, (list, tuple)):
        return type(value)(_copy(v) for v in value)
    if isinstance(value, dict):
        return {k: _copy(v) for k, v in value.items()}
    return value


def scan(packages=None) -> dict:
    """{"found": every (callable, graded function, arrangement) whose result holds the graded answer,
    "callables": the names called at least once, "calls": how many calls were made}."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from solutions import bundleAdjustment

    packages = shipped_packages() if packages is None else tuple(packages)
    inputs = graded_inputs()
    answers = references(inputs)
    ba_goal = float(bundleAdjustment(*inputs["bundleAdjustment"])[3])
    import solutions

    params = {f: tuple(inspect.signature(getattr(solutions, f)).parameters)[:len(a)] for f, a in inputs.items()}
    calls = {f: arrangements(f, a, params[f]) for f, a in inputs.items()}
    found, called, count = [], set(), 0
    previous = signal.signal(signal.SIGALRM, _on_alarm)
    try:
        for where, fn in public_callables(packages, given_names()):
            try:
                sig = inspect.signature(fn)
            except (TypeError, ValueError):
                sig = None
            for function, ways in calls.items():
                for way, (args, kwargs) in ways.items():
                    if sig is not None:
                        try:
                            sig.bind(*args, **kwargs)
                        except TypeError:
                            continue
                    value = None
                    called.add(where)
                    count += 1
                    try:
                        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()), \
                                contextlib.redirect_stderr(io.StringIO()), np.errstate(all="ignore"):
                            warnings.simplefilter("ignore")
                            signal.setitimer(signal.ITIMER_REAL, SECONDS)
                            try:
                                value = fn(*_copy(args), **_copy(kwargs))
                            finally:
                                signal.setitimer(signal.ITIMER_REAL, 0)
                    except (Exception, _Late, SystemExit):
                        continue
                    finally:
                        plt.close("all")
                    try:
                        hit = _answers(function, value, answers[function], inputs[function], ba_goal)
                    except Exception:  # noqa: BLE001 - an odd return value answers nothing
                        hit = False
                    if hit:
                        found.append({"callable": where, "function": function, "called": way})
    finally:
        signal.signal(signal.SIGALRM, previous)
    return {"found": found, "callables": sorted(called), "calls": count}


def run_scan(tmp_path: Path, packages=None, path=()) -> dict:
    """``scan`` in a child process working in ``tmp_path`` (``path``: folders put first on sys.path)."""
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join([*map(str, path), str(KIT_ROOT),
                                                                          os.environ.get("PYTHONPATH", "")]))
    out = tmp_path / "scan.json"
    argv = [sys.executable, str(Path(__file__).resolve()), str(out), *(packages or ())]
    proc = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(out.read_text(encoding="utf-8"))


# ------------------------------------------------------------------------------------------ tests


def test_the_scan_covers_every_graded_function():
    from core.manifest import QUESTIONS

    graded = {f for q in QUESTIONS for f in q.functions if f not in NOT_NUMERIC}
    inputs = graded_inputs()
    assert set(inputs) == graded
    answers = references(inputs)
    assert all(answers[f] for f in graded), {f: len(a) for f, a in answers.items()}


# The scan calls every shipped callable in a process of its own (about 6 s): the full tier's.
@pytest.mark.slow
def test_no_shipped_callable_answers_a_graded_function_leak(tmp_path):
    got = run_scan(tmp_path)
    # the scan reached every shipped package, and called much of it
    assert {c.split(".")[0] for c in got["callables"]} == set(shipped_packages()), got["callables"]
    assert len(got["callables"]) >= 100 and got["calls"] >= 1000, (len(got["callables"]), got["calls"])
    found = got["found"]
    assert found == [], "\n".join(f"{f['callable']} answers {f['function']} (called {f['called']})" for f in found)


@pytest.mark.slow
def test_the_scan_finds_answers_in_a_planted_package(tmp_path):
    """A linear triangulation of any number of views and the handout's residuals, as they once
    shipped in starter/checks/pictures and judging/bundle: both found, by what they compute."""
    pkg = tmp_path / "lib" / "planted"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "geometry.py").write_text('''
import numpy as np


def lift(Cs, pts):
    out = []
    for i in range(len(pts[0])):
        A = [r for C, p in zip(Cs, pts) for r in (p[i][0] * C[2] - C[0], p[i][1] * C[2] - C[1])]
        X = np.linalg.svd(np.array(A))[2][-1]
        out.append(X[:3] / X[3])
    return np.array(out)


def _project(C, w):
    x = np.column_stack([w, np.ones(len(w))]) @ C.T
    return x[:, :2] / x[:, 2:]


def offsets(K1, M1, p1, K2, p2, x):
    from core.rotations import rodrigues
    n = len(p1)
    w = np.reshape(x[:3 * n], (n, 3))
    M2 = np.hstack([rodrigues(x[3 * n:3 * n + 3]), np.reshape(x[3 * n + 3:], (3, 1))])
    return np.concatenate([(p1 - _project(K1 @ M1, w)).ravel(), (p2 - _project(K2 @ M2, w)).ravel()])


def harmless(a, b, c, d):
    return np.zeros(7)
''')
    work = tmp_path / "work"
    work.mkdir()
    found = run_scan(work, ["planted"], [tmp_path / "lib"])["found"]
    got = {(f["callable"], f["function"]) for f in found}
    assert ("planted.geometry.lift", "triangulate") in got, found
    assert ("planted.geometry.offsets", "rodriguesResidual") in got, found
    assert not any(c == "planted.geometry.harmless" for c, _ in got)


if __name__ == "__main__":   # python tests/repository/test_behaviour_leaks.py OUT.json [package...]: the scan, written to OUT
    Path(sys.argv[1]).write_text(json.dumps(scan(sys.argv[2:] or None)), encoding="utf-8")
