"""A hand-in that reaches into the kit beyond what a student is given is flagged for the staff.

autograder.review.library_calls reports, besides the listed library calls, every use of the kit's
internals (``GIVEN_KIT`` says what is given: the handout's helpers, loaders, drawing helpers, the
self-checks, the hand-in tools, what the answer key imports).  These tests read hand-ins written
for the purpose, the student notebooks as shipped and the answer key.
"""

from __future__ import annotations

import json
from pathlib import Path

import nbformat
import pytest

from autograder.review.library_calls import KIT_INTERNAL, find_in_sources, find_library_calls, kit_internal
from core.paths import NOTEBOOKS_DIR

REACHING_IN = '''
import numpy as np
import judging.bundle as jb
from starter import camera2, load_temple
from starter.checks.pictures.geometry3d import triangulate_views
from judging.bundle import handout_residuals
from scenes.temple import make_temple_scene
from core.geometry import essential_from_pose


def triangulate(C1, pts1, C2, pts2):
    w = triangulate_views([C1, C2], [pts1, pts2])
    return w, 0.0


def rodriguesResidual(K1, M1, p1, K2, p2, x):
    return jb.handout_residuals(K1, M1, p1, K2, p2, x)
'''

GIVEN_ONLY = '''
import numpy as np
from starter import camera2, load_temple, refineF, rodrigues
from starter.rotations import invRodrigues
from core.rotations import rodrigues as rod
from core.validate import as_points
from core.geometry import project
from starter.checks.bundle import check_rodriguesResidual
from handin.pdf import build_pdf
import starter

scenes = [1, 2]          # a variable, no package
scenes.append(3)
core = {"a": 1}
core.get("a")


def findM2(F, pts1, pts2, K1, K2):
    return camera2(K2.T @ F @ K1)[:, :, 0]


check_rodriguesResidual(lambda *a: None)
starter.ransacF
'''


def kit_flags(found) -> list[tuple[str, str]]:
    return sorted((c.name, c.kind) for c in found if c.replaces == KIT_INTERNAL)


def test_a_hand_in_reaching_into_the_kit_is_flagged():
    found, notes = find_in_sources([("submission.py", REACHING_IN)])
    assert notes == []
    flags = kit_flags(found)
    assert ("starter.checks.pictures.geometry3d.triangulate_views", "call") in flags
    assert ("judging.bundle.handout_residuals", "call") in flags           # through the module's alias
    assert ("judging.bundle.handout_residuals", "import") in flags         # imported, never used
    assert ("scenes.temple.make_temple_scene", "import") in flags
    assert ("core.geometry.essential_from_pose", "import") in flags
    # the given helpers of the same file are not
    assert not any(name.startswith("starter.camera2") or name.startswith("starter.load_temple") for name, _ in flags)
    use = next(c for c in found if c.name.endswith("triangulate_views") and c.kind == "call")
    assert use.function == "triangulate" and "line" in use.where


def test_the_given_helpers_and_look_alike_variables_are_not_flagged():
    found, _ = find_in_sources([("submission.py", GIVEN_ONLY)])
    assert kit_flags(found) == [], found


def test_star_imports_and_notebook_cells_share_their_imports():
    cells = [("cell 1", "from judging.bundle import *\nfrom starter import *\n"),
             ("cell 2", "from starter.checks import pictures\n"),
             ("cell 3", "P = pictures.q6_multiview.rule_points(C, pts, 0.5)\nw = pictures.show('Q6', {})\n")]
    flags = kit_flags(find_in_sources(cells)[0])
    assert ("judging.bundle.*", "import") in flags
    assert ("starter.checks.pictures.q6_multiview.rule_points", "call") in flags
    assert ("starter.checks.pictures.show", "call") in flags
    assert not any(name.startswith("starter.*") for name, _ in flags)


@pytest.mark.parametrize("name, internal", [
    ("starter.refineF", False), ("starter.checks.fundamental.check_eightpoint", False),
    ("starter.checks.check_eightpoint", False), ("core.rotations.invRodrigues", False), ("core.pose.camera2", False),
    ("starter.checks", False), ("numpy.linalg.svd", False),
    ("starter.checks.fundamental.jf", True), ("judging", True), ("solutions.triangulate", True),
    ("autograder.review", True), ("kit.check_data", True), ("core.geometry.fundamental_from_pose", True),
])
def test_what_is_given(name, internal):
    assert kit_internal(name) is internal


def _notebook_sources(path: Path) -> list[tuple[str, str]]:
    nb = nbformat.read(path, as_version=4)
    return [(f"{path.name}, cell {k}", c.source) for k, c in enumerate(nb.cells, 1) if c.cell_type == "code"]


@pytest.mark.parametrize("folder", ["", "key"], ids=["student notebooks", "answer key"])
def test_the_kits_own_notebooks_import_only_what_is_given(folder):
    """The student notebooks as shipped and the plain answer key (a hand-in of the reference) are not flagged."""
    paths = sorted((NOTEBOOKS_DIR / folder).glob("q*.ipynb"))
    assert len(paths) >= 6
    for path in paths:
        found, notes = find_in_sources(_notebook_sources(path))
        assert kit_flags(found) == [], (path.name, found)


def test_a_notebook_hand_in_is_flagged_through_the_review(tmp_path):
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell("from starter import load_temple"),
                nbformat.v4.new_code_cell(REACHING_IN)]
    path = tmp_path / "q3_metric_reconstruction.ipynb"
    path.write_text(json.dumps(nb), encoding="utf-8")
    found, _ = find_library_calls(tmp_path)
    assert ("starter.checks.pictures.geometry3d.triangulate_views", "call") in kit_flags(found)
