"""Hidden scenes are drawn per submission: hidden inputs a submission copies out are no use to another.

Each submission is graded on its own draw of the hidden scenes, seeded by the grader's secret and
a digest of the code the grader runs (``autograder.inputs.build.code_salt``): the same code
gets the same scenes (a regrade, a folder or a zip, notebooks rewritten by nbgrader), other code
other scenes; what does not depend on the submission (the default data and the reference's
results on it) is the batch's, made once.  Results name the draw by a short digest only.
Quick settings (``quick_config``); the graded part runs the answer key and one variant in the
sandbox.
"""

from __future__ import annotations

import json
import re
import zipfile

import corpus
import nbformat
import numpy as np
import pytest

from autograder.inputs.config import quick_config
from autograder.grading.run import GradingRun
from autograder.inputs import build as inputs
from autograder.inputs.scenes import FIXED_LABELS
from autograder.sandbox import ResourceLimits, Sandbox
from autograder.submission.read import load_submission

pytestmark = pytest.mark.slow  # the full tier's: see docs/testing.md

LIMITS = ResourceLimits(memory_bytes=2 * 2**30, processes=48, grace=1.0)


@pytest.fixture(scope="module")
def batch():
    return inputs.build_hidden_inputs(quick_config())


@pytest.fixture(scope="module")
def drawn(batch):
    """Draws of the salts "a..." and "b..." (each made once for the module's tests)."""
    return {k: inputs.draw(batch, k * 32) for k in "ab"}


def _temple_points(hidden) -> np.ndarray:
    return np.concatenate([np.asarray(c.pts1, float).ravel() for c in hidden.prepared["fundamental"].cases
                           if c.label.startswith("hidden scene")])


def _car(hidden) -> np.ndarray:
    return np.asarray(hidden.prepared["multiview"].video, float)


# ---------------------------------------------------------------------------------------------
# the draw itself, in this process


def test_one_salt_draws_the_same_scenes_twice_and_another_salt_others(batch, drawn):
    a, b = drawn["a"], drawn["b"]
    again = inputs.draw(batch, "a" * 32)  # made again from nothing but the batch and the salt
    assert a is not again and a.draw == again.draw == batch.config.draw_digest("a" * 32) != b.draw
    assert np.array_equal(_temple_points(a), _temple_points(again)) and np.array_equal(_car(a), _car(again))
    assert np.array_equal(a.prepared["bundle"].problems[0].p1, again.prepared["bundle"].problems[0].p1)
    pa, pb = _temple_points(a), _temple_points(b)
    assert pa.shape != pb.shape or not np.allclose(pa, pb)
    assert not np.allclose(_car(a), _car(b))
    assert not np.allclose(a.prepared["essential"].inputs[0][0], b.prepared["essential"].inputs[0][0])
    # Neither is the secret's own draw (what every submission got before).
    assert not np.allclose(_car(a), _car(batch))


def test_a_grading_process_hands_the_same_code_a_copy_of_its_draw_and_other_code_its_own(batch, monkeypatch):
    from autograder.hidden import plugin

    monkeypatch.setattr(plugin, "_drawn", {})
    monkeypatch.setattr(plugin, "_DRAWS_KEPT", 2)
    made = []
    real = inputs.draw
    monkeypatch.setattr(inputs, "draw", lambda b, salt, **kw: made.append(salt) or real(b, salt, **kw))
    first = plugin._draw(batch, "c" * 32)
    as_made = _car(first).copy()
    first.prepared["multiview"].video[...] = -1.0  # a check that changed what it read
    again = plugin._draw(batch, "c" * 32)
    assert made == ["c" * 32] and again.draw == first.draw == batch.config.draw_digest("c" * 32)
    assert np.array_equal(_car(again), as_made)  # the draw as made, not as changed
    other = plugin._draw(batch, "d" * 32)
    assert made == ["c" * 32, "d" * 32] and other.draw != again.draw and not np.allclose(_car(other), _car(again))
    plugin._draw(batch, "e" * 32)  # only the last few are kept
    plugin._draw(batch, "c" * 32)
    assert made == ["c" * 32, "d" * 32, "e" * 32, "c" * 32] and len(plugin._drawn) == 2


def test_a_draw_keeps_the_batch_parts_and_the_shapes(batch, drawn):
    a = drawn["a"]
    for name in ("fundamental", "pose", "correspondence"):
        assert [c.label for c in a.prepared[name].cases] == [c.label for c in batch.prepared[name].cases], name
    for name in ("fundamental", "correspondence"):  # the default data's (no official data here)
        fixed = [c for c in a.prepared[name].cases if c.label in FIXED_LABELS]
        assert fixed and fixed == [c for c in batch.prepared[name].cases if c.label in FIXED_LABELS], name
    # Q2's uint16 case is cut from a hidden scene, so it is drawn like that scene.
    f, bf = a.prepared["fundamental"], batch.prepared["fundamental"]
    assert f.uint16.label == bf.uint16.label and not np.array_equal(f.uint16.pts1, bf.uint16.pts1)
    assert a.prepared["correspondence"].points_case.label == "hidden scene 2"
    # The session's budget is the batch's: a draw changes values, never how many calls are made.
    assert a.call_seconds() == batch.call_seconds()


def test_q33s_right_camera_is_the_one_the_reference_chooses_even_from_a_poor_F(monkeypatch):
    # Q3.3 gives findM2 the reference's F of a hidden scene and expects the candidate nearest the
    # true pose. From a poor F, the points in front of both cameras can pick another candidate:
    # every correct findM2 would lose. Here the reference's F is the unrefined one (poor on the
    # quick scenes); each case must still expect what the reference's findM2 chooses.
    from autograder.inputs import pose as cases_pose
    from autograder.inputs.scenes import make_scenes
    from core.geometry import fundamental_from_pose
    from solutions import eightpoint, findM2

    monkeypatch.setattr(cases_pose, "reference_F", lambda tc: eightpoint(tc.pts1, tc.pts2, tc.M, refine=False))
    replaced = 0
    for salt in ("c" * 32, "d" * 32, "e" * 32):
        scenes = make_scenes(quick_config(), salt=salt, fixed=False)
        cases = cases_pose.prepare_pose(scenes).cases
        for case in cases:
            assert np.allclose(findM2(case.F, case.pts1, case.pts2, case.K1, case.K2)[0], case.right), case.label
        tc = scenes.hidden[0]
        given = cases[1].F
        true_F = fundamental_from_pose(tc.K1, tc.K2, tc.scene.M2)
        replaced += min(np.abs(given / np.linalg.norm(given) - s * true_F).max() for s in (1, -1)) < 1e-9
    assert replaced >= 1  # the poor F was replaced somewhere: the guard was exercised


def test_the_unsalted_call_is_the_batch_and_bad_salts_are_refused(batch, drawn):
    assert inputs.build_hidden_inputs(quick_config()) is batch and batch.draw is None
    with pytest.raises(ValueError, match="salt"):
        inputs.draw(batch, "")
    with pytest.raises(ValueError, match="batch"):
        inputs.draw(drawn["a"], "f" * 32)


# ---------------------------------------------------------------------------------------------
# the salt: the code the grader runs, whatever the channel


def _nbgrader_rewrite(folder, target):
    """``folder``'s notebooks as nbgrader hands them back: notebook and cell metadata of its own,
    new cell ids, no outputs, its hidden-test cells added, written with another JSON layout."""
    target.mkdir(parents=True)
    for k, path in enumerate(sorted(folder.glob("*.ipynb"))):
        nb = nbformat.read(path, as_version=4)
        nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"}
        nb.metadata["nbgrader"] = {"__altered__": False, "__hash__": 1234 + k}
        for j, cell in enumerate(nb.cells):
            cell["id"] = f"nbgrader-{k}-{j}"
            cell.metadata["nbgrader"] = {"grade": False, "locked": False, "solution": True, "grade_id": f"cell-{j}",
                                         "schema_version": 3, "task": False}
            if cell.cell_type == "code":
                cell.outputs, cell.execution_count = [], None
        nb.cells.append(nbformat.v4.new_code_cell("# hidden checks\n### BEGIN HIDDEN TESTS\n0.0\n### END HIDDEN TESTS"))
        (target / path.name).write_text(json.dumps(nb, indent=2, sort_keys=True))
    return target


def _zip(folder, path):
    with zipfile.ZipFile(path, "w") as zf:
        for p in sorted(folder.iterdir()):
            zf.write(p, f"my-hw4/{p.name}")
    return path


def _edited(name, folder, edit):
    nbs = corpus.notebooks("key")
    edit(nbs)
    folder = folder / name
    folder.mkdir(parents=True)
    for stem, nb in nbs.items():
        nbformat.write(nb, folder / f"{stem}.ipynb")
    return folder


def _with_comment(nbs):
    for nb in nbs.values():
        for cell in nb.cells:
            if cell.cell_type == "code" and "def eightpoint(" in cell.source:
                cell.source = "# a comment the grader does not run\n\n" + cell.source.replace("\n", "  \n", 1)


def _with_body_change(nbs):
    for nb in nbs.values():
        for cell in nb.cells:
            if cell.cell_type == "code" and "def eightpoint(" in cell.source:
                head, body = cell.source.split("def eightpoint(", 1)
                signature, rest = body.split(":\n", 1)
                cell.source = f"{head}def eightpoint({signature}:\n    unused = 1\n{rest}"


def test_the_same_code_has_one_salt_whatever_the_channel_and_other_code_another(tmp_path):
    folder = corpus.build("key_full_marks", tmp_path / "subs")
    salt = inputs.code_salt(load_submission(folder))
    assert re.fullmatch(r"[0-9a-f]{32}", salt)
    same = {
        "zip": _zip(folder, tmp_path / "key.zip"),
        "nbgrader": _nbgrader_rewrite(folder, tmp_path / "nbgrader" / "hw4"),
        "comment": _edited("comment", tmp_path / "edits", _with_comment),
    }
    for channel, path in same.items():
        assert inputs.code_salt(load_submission(path)) == salt, channel
    body = _edited("body", tmp_path / "edits", _with_body_change)
    assert inputs.code_salt(load_submission(body)) != salt
    other = corpus.build("hartley_normalisation_full_marks", tmp_path / "subs")
    assert inputs.code_salt(load_submission(other)) != salt


# ---------------------------------------------------------------------------------------------
# graded in the sandbox


@pytest.fixture(scope="module")
def graded(tmp_path_factory, batch):
    root = tmp_path_factory.mktemp("draws")
    key = corpus.build("key_full_marks", root / "subs")
    other = corpus.build("transposed_F_loses_Q2", root / "subs")
    zipped = _zip(key, root / "key.zip")
    out = {}
    with Sandbox(hidden=[root], limits=LIMITS) as box, GradingRun(batch.config, hidden_inputs=batch, sandbox=box) as run:
        out["canary"] = run.run_canary()
        for name, path in (("key", key), ("again", key), ("zip", zipped), ("other", other)):
            out[name] = run.grade(path, student_id=name)
    out["paths"] = {"key": key, "other": other}
    return out


def _scores(result) -> dict:
    return {q.id: [t.score for t in q.tests] for q in result.questions}


def test_a_regrade_and_a_zip_of_the_same_code_get_the_same_draw_and_scores(graded, batch):
    key, again, zipped = graded["key"], graded["again"], graded["zip"]
    expected = batch.config.draw_digest(inputs.code_salt(load_submission(graded["paths"]["key"])))
    assert key.configuration == again.configuration == zipped.configuration
    assert key.configuration["draw"] == expected
    assert _scores(key) == _scores(again) == _scores(zipped)
    assert key.questions and all(t.score >= t.max_score for q in key.questions for t in q.tests)


def test_other_code_gets_another_draw(graded, batch):
    other = graded["other"]
    expected = batch.config.draw_digest(inputs.code_salt(load_submission(graded["paths"]["other"])))
    assert other.configuration["draw"] == expected != graded["key"].configuration["draw"]
    assert other.score < graded["key"].score


def test_the_canary_still_gets_full_marks(graded):
    report = graded["canary"]
    assert report.max_score > 0 and report.score >= report.max_score


def test_results_name_the_draw_by_a_short_digest_only(graded, batch):
    for name in ("key", "other"):
        result = graded[name]
        salt = inputs.code_salt(load_submission(graded["paths"][name]))
        text = json.dumps(result.to_dict()) + json.dumps(result.to_gradescope(visibility={}))
        assert re.fullmatch(r"[0-9a-f]{12}", result.configuration["draw"])
        assert salt not in text and salt[:16] not in text
        drawn = inputs.draw(batch, salt)
        coordinates = [*_temple_points(drawn)[:20], *_car(drawn).ravel()[:20]]
        assert not _printed(coordinates, text), "a coordinate of the drawn scenes reached the results"


def _printed(values, text: str) -> list[float]:
    """The values that ``text`` prints as a number of 3 decimals or more (rounded as printed).
    Whole numbers only, never a piece of one: "1.235" inside a timing of 21.2351 s is no leak.
    Small values need 4 decimals: at 3, a feedback figure matches one of them by chance."""
    numbers = [(float(t), len(t.split(".")[1])) for t in re.findall(r"(?<![\d.])-?\d+\.\d+", text)]
    return [v for v in values for x, d in numbers if d >= 3 and round(float(v), d) == x and (d >= 4 or abs(v) >= 10)]
