"""The picture step's time budget is CPU time, as the checks' limits, and its calls carry the
student's parameters as written (``autograder.feedback.pictures``, on a recording stand-in of a session)."""

from __future__ import annotations

import numpy as np

from autograder.feedback import pictures as step
from autograder.sandbox import CallOutcome
from judging.conventions import Signature, findM2_style, signature_of_callable
import picture_standin


class _Limits:
    wall_factor = 4.0


class _Session:
    """Records each request; answers with a 3x3 array."""

    rt = type("Rt", (), {"limits": _Limits()})()

    def __init__(self):
        self.requests = []

    def map(self, function, inputs, **kw):
        self.requests.append((function, kw))
        return [CallOutcome("ok", value=np.eye(3))] * len(inputs)


class _Student:
    time_scale = 0.5

    def __init__(self):
        self.session = _Session()


def test_each_call_is_given_cpu_seconds_of_the_session(monkeypatch):
    monkeypatch.setattr(step, "contract", lambda: picture_standin)
    student = _Student()
    outputs = step.run_public(student, "Q2", seconds=6.0)
    assert set(outputs) == {"F"} and np.array_equal(outputs["F"], np.eye(3)), outputs
    (function, kw), = student.session.requests
    assert function == "eightpoint" and kw["clock"] == "cpu"
    assert 0 < kw["seconds"] <= 3.0 and kw["budget"] == kw["seconds"]   # 6 s times time_scale 0.5


def test_a_proxy_carries_the_students_signature():
    intrinsics = Signature(("F", "pts1", "pts2", "intrinsics", "filename"), 1)
    proxies = step._Proxies(_Student(), ("findM2",), 1.0, {"findM2": intrinsics}.get)
    assert signature_of_callable(proxies["findM2"]) == intrinsics
    assert findM2_style(signature_of_callable(proxies["findM2"])) == "intrinsics"
    unknown = step._Proxies(_Student(), ("findM2",), 1.0, None)
    assert findM2_style(signature_of_callable(unknown["findM2"])) == "kit"
