"""Hand-ins in every layout students used, written from the answer key's functions, each named after its grade.

The function sources are the answer key's own defining cells (``corpus.notebooks("key")``, built
from solutions/), put into the files each course year handed in:

- 2018-2021: ``submission.py`` with the homework's functions (and that year's own
  ``ransacF(pts1, pts2, M, nIters, tol)``, which the kit gives and does not grade), ``helper.py`` (the student's own
  copy of refineF and the other given helpers), ``findM2.py`` and ``visualize.py`` importing
  from them, each with a script part (data loading from relative paths, plots) under
  ``if __name__ == "__main__":`` or at top level;
- 2022-2024: one file per part (``q2_1_eightpoint.py``, ``q3_1_essential_matrix.py``,
  ``q5_1_ransac.py`` with that year's ``ransacF`` ...)
  importing each other (``from q3_1_essential_matrix import essentialMatrix``) and ``helper``
  without shipping it, zipped inside nested folders under an odd name (``HW4 final (2).zip``);
- one notebook holding everything, with the cells that run it;
- the kit's per-question notebooks, renamed by Colab and a browser, nested in a zip.

``CASES`` maps each name to its builder and the questions that must lose points (all others get
full marks); ``build(name, folder)`` writes the hand-in and returns its path.
"""

from __future__ import annotations

import inspect
import re
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

__all__ = ["CASES", "Case", "build", "key_cell", "write_hand_in"]

HOMEWORK = ("eightpoint", "essentialMatrix", "triangulate", "findM2", "epipolarCorrespondence",
            "compute3D_pts", "rodriguesResidual", "bundleAdjustment", "MultiviewReconstruction",
            "plot_3d_keypoint_video")


@lru_cache(maxsize=1)
def _key_cells() -> dict[str, str]:
    import corpus

    out = {}
    for nb in corpus.notebooks("key").values():
        for cell in nb.cells:
            if cell.cell_type != "code":
                continue
            for f in HOMEWORK:
                if re.search(rf"^def {f}\(", cell.source, re.MULTILINE):
                    out[f] = cell.source
    missing = set(HOMEWORK) - set(out)
    if missing:
        raise LookupError(f"the answer key defines no {sorted(missing)}")
    return out


def key_cell(function: str, *, helper: bool = False) -> str:
    """The answer key's cell defining ``function`` (imports included); with ``helper``, the
    kit's given helpers are imported from ``helper`` as the course's students did."""
    source = _key_cells()[function].rstrip() + "\n"
    if helper:
        source = re.sub(r"^from starter import ", "from helper import ", source, flags=re.MULTILINE)
    return source


def _cells(*functions: str, helper: bool = False) -> str:
    """The key's cells of ``functions`` (a cell defining two of them only once), joined."""
    seen, out = set(), []
    for f in functions:
        text = key_cell(f, helper=helper)
        if text not in seen:
            seen.add(text)
            out.append(text)
    return "\n\n".join(out)


def _own_helper_py() -> str:
    """A 2018-style helper.py: the student's own copy of refineF (the kit's starter.epipolar, as
    text) and the other given helpers, plus a plotting helper with a GUI (defined, never run)."""
    import starter.epipolar

    return (inspect.getsource(starter.epipolar)
            + "\n\nfrom starter.pose import camera2\nfrom starter.rotations import rodrigues, invRodrigues\n\n\n"
            "def displayEpipolarF(I1, I2, F):\n    import matplotlib.pyplot as plt\n"
            "    plt.imshow(I1)\n    plt.show()\n")


SCRIPT_2018 = '''

if __name__ == "__main__":
    import matplotlib.pyplot as plt
    data = np.load("../data/some_corpus.npz")
    im1 = plt.imread("../data/im1.png")
    M = max(im1.shape)
    F8 = eightpoint(data["pts1"], data["pts2"], M)
    np.savez("q2_1.npz", F=F8, M=M)
    plt.show()
'''


# ransacF as earlier years had students write it (the kit gives its own, with an eightpoint
# argument, and grades none): recognised by its parameters, noted, never called by the grader.
RANSACF_OTHER_YEAR = '''\
def ransacF(pts1, pts2, M, nIters=1000, tol=0.42):
    """Q5.1: F of the most matches within tol px of their epipolar lines, over nIters 8-point samples."""
    rng = np.random.default_rng(0)
    pts1, pts2 = np.asarray(pts1, dtype=float), np.asarray(pts2, dtype=float)
    h1 = np.column_stack([pts1, np.ones(len(pts1))])
    h2 = np.column_stack([pts2, np.ones(len(pts2))])
    best = np.zeros(len(pts1), dtype=bool)
    for _ in range(nIters):
        sample = rng.choice(len(pts1), 8, replace=False)
        lines = h1 @ eightpoint(pts1[sample], pts2[sample], M).T
        inliers = np.abs(np.sum(h2 * lines, axis=1)) / np.hypot(lines[:, 0], lines[:, 1]) < tol
        if inliers.sum() > best.sum():
            best = inliers
    return eightpoint(pts1[best], pts2[best], M), best
'''


def submission_py(eightpoint_source: str | None = None) -> dict[str, bytes]:
    """The 2018-2021 hand-in: submission.py (with the year's own ransacF), helper.py (own refineF),
    findM2.py, visualize.py."""
    main = [key_cell("eightpoint", helper=True) if eightpoint_source is None else eightpoint_source,
            RANSACF_OTHER_YEAR]
    main += [_cells("essentialMatrix", "triangulate", "epipolarCorrespondence", "rodriguesResidual",
                    "bundleAdjustment", "MultiviewReconstruction", "plot_3d_keypoint_video", helper=True)]
    submission = ('"""\nHomework4.\nReplace \'pass\' by your implementation.\n"""\n\n'
                  "# Insert your package here\nimport numpy as np\nimport helper\n\n"
                  + "\n\n".join(main) + SCRIPT_2018)
    find_m2 = ("'''\nQ3.3:\n    1. Load point correspondences\n    2. Obtain the correct M2\n"
               "    3. Save the correct M2, C2, and P to q3_3.npz\n'''\n"
               "import numpy as np\nimport submission as sub\nfrom submission import essentialMatrix, triangulate\n\n"
               + key_cell("findM2", helper=True)
               + "\n\ndata = np.load('../data/some_corresp.npz')\nintrinsics = np.load('../data/intrinsics.npz')\n"
               "M2 = findM2(sub.eightpoint(data['pts1'], data['pts2'], 640), data['pts1'], data['pts2'],"
               " intrinsics['K1'], intrinsics['K2'])\nnp.savez('q3_3.npz', M2=M2)\n")
    visualize = ("'''\nQ4.2:\n    1. Integrating everything together.\n    2. Loads necessary files from ../data/ "
                 "and visualizes 3D reconstruction using scatter\n'''\n"
                 "import numpy as np\nimport matplotlib.pyplot as plt\nfrom mpl_toolkits.mplot3d import Axes3D\n"
                 "from submission import epipolarCorrespondence, triangulate\nimport findM2\n\n"
                 + key_cell("compute3D_pts")
                 + "\n\nif __name__ == '__main__':\n    coords = np.load('../data/templeCoords.npz')\n"
                 "    fig = plt.figure()\n    ax = fig.add_subplot(111, projection='3d')\n    plt.show()\n")
    return {"submission.py": submission.encode(), "helper.py": _own_helper_py().encode(),
            "findM2.py": find_m2.encode(), "visualize.py": visualize.encode()}


def per_part_files() -> dict[str, bytes]:
    """The 2022-2024 hand-in: one file per part importing each other, ``helper`` not shipped;
    q4_1's file keeps a wrong scratch copy of eightpoint (its name does not match Q2)."""
    from corpus import variants

    main = "\n\nif __name__ == \"__main__\":\n    import matplotlib.pyplot as plt\n    plt.show()\n"
    files = {
        "q2_1_eightpoint.py": "import numpy as np\nfrom helper import displayEpipolarF, calc_epi_error, toHomogenous\n\n"
                              + key_cell("eightpoint", helper=True)
                              + "\n\nif __name__ == \"__main__\":\n    correspondence = np.load('data/some_corresp.npz')\n"
                                "    F = eightpoint(correspondence['pts1'], correspondence['pts2'], 640)\n"
                                "    displayEpipolarF(None, None, F)\n",
        "q3_1_essential_matrix.py": "from q2_1_eightpoint import eightpoint\n\n" + key_cell("essentialMatrix") + main,
        "q3_2_triangulate.py": ("from helper import camera2\nfrom q2_1_eightpoint import eightpoint\n"
                                "from q3_1_essential_matrix import essentialMatrix\n\n"
                                + _cells("triangulate", "findM2", helper=True) + main),
        "q4_1_epipolar_correspondence.py": ("from helper import _epipoles\nfrom q2_1_eightpoint import eightpoint as _eightpoint\n\n"
                                            + key_cell("epipolarCorrespondence") + "\n\n"
                                            + variants.EIGHTPOINT_TRANSPOSED + main),
        "q4_2_visualize.py": ("from q4_1_epipolar_correspondence import epipolarCorrespondence\n"
                              "from q3_2_triangulate import findM2, triangulate\n\n" + key_cell("compute3D_pts") + main),
        "q5_1_ransac.py": ("import numpy as np\nfrom q2_1_eightpoint import eightpoint\n"
                           "from helper import displayEpipolarF, calc_epi_error, toHomogenous\n\n\n"
                           + RANSACF_OTHER_YEAR
                           + "\n\nif __name__ == \"__main__\":\n    noisy = np.load('data/some_corresp_noisy.npz')\n"
                             "    F, inliers = ransacF(noisy['pts1'], noisy['pts2'], 640)\n"),
        "q5_bundle_adjustment.py": ("from helper import displayEpipolarF, calc_epi_error, plot_3d_keypoint\n"
                                    "from q2_1_eightpoint import eightpoint\nfrom q3_2_triangulate import findM2\n\n"
                                    + _cells("rodriguesResidual", "bundleAdjustment", helper=True) + main),
        "q6_ec_multiview_reconstruction.py": ("from helper import *\nfrom q3_2_triangulate import triangulate\n\n"
                                              + _cells("MultiviewReconstruction", "plot_3d_keypoint_video") + main),
    }
    out = {f"HW4 final (2)/andrew_hw4/code/{name}": text.encode() for name, text in files.items()}
    out["HW4 final (2)/andrew_hw4/code/__pycache__/q2_1_eightpoint.cpython-310.pyc"] = b"\x00\x01compiled"
    out["HW4 final (2)/andrew_hw4/README.md"] = b"# HW4\nRun q4_2_visualize.py\n"
    return out


def one_notebook() -> dict[str, bytes]:
    """One notebook holding everything, with the cells that load the data, run and plot."""
    cells = [new_markdown_cell("# HW4: 3D reconstruction"),
             new_code_cell("%matplotlib inline\nimport numpy as np\nimport matplotlib.pyplot as plt\n"
                           "from starter import displayEpipolarF\n")]
    for f in HOMEWORK:
        text = key_cell(f)
        if not any(c.source == text for c in cells):
            cells += [new_markdown_cell(f"## {f}"), new_code_cell(text)]
    cells += [new_code_cell("data = np.load('../data/some_corresp.npz')\nF = eightpoint(data['pts1'], data['pts2'], 640)\n"
                            "displayEpipolarF(plt.imread('../data/im1.png'), plt.imread('../data/im2.png'), F)\n")]
    return {"andrew_hw4_all.ipynb": nbformat.writes(new_notebook(cells=cells)).encode()}


def kit_notebooks_renamed() -> dict[str, bytes]:
    """The kit's answer-key notebooks as a student zips them: nested, renamed by Colab or a
    browser (one with no question number at all: its metadata says which it is)."""
    import corpus

    names = {"q1_proofs": "Copy of q1_proofs.ipynb", "q2_eightpoint": "Untitled3.ipynb",
             "q3_metric_reconstruction": "q3_metric_reconstruction (1).ipynb",
             "q4_temple_3d": "Copy of q4_temple_3d (2).ipynb"}
    out = {}
    for stem, nb in corpus.notebooks("key").items():
        out[f"hw4 submission/notebooks/{names.get(stem, stem + '.ipynb')}"] = nbformat.writes(nb).encode()
    return out


def _transposed_submission_py() -> dict[str, bytes]:
    from corpus import variants

    return submission_py(variants.EIGHTPOINT_TRANSPOSED)


@dataclass(frozen=True)
class Case:
    """files: the hand-in's files (path -> bytes); archive: the zip's file name, or None for a
    folder; loses: questions that must score below full marks (all others full)."""

    files: Callable[[], dict[str, bytes]]
    archive: str | None = None
    loses: frozenset = frozenset()


CASES: dict[str, Case] = {
    "layout_submission_py_full_marks": Case(submission_py),
    "layout_submission_py_q2_transposed_loses_q2": Case(_transposed_submission_py, loses=frozenset({"Q2"})),
    "layout_per_part_files_full_marks": Case(per_part_files, archive="HW4 final (2).zip"),
    "layout_one_notebook_full_marks": Case(one_notebook),
    "layout_per_question_notebooks_full_marks": Case(kit_notebooks_renamed, archive="hw4 (andrew).zip"),
}


def build(name: str, folder: str | Path) -> Path:
    """Write the hand-in ``name`` into ``folder/name/`` (its files, or its zip) and return its path."""
    case = CASES[name]
    return write_hand_in(Path(folder) / name, case.files(), case.archive)


def write_hand_in(root: Path, files: dict, archive: str | None = None) -> Path:
    """Write ``files`` (relative path -> bytes or str) under ``root``, or into the zip ``root/archive``
    when one is named; return the folder or the zip."""
    root.mkdir(parents=True, exist_ok=True)
    if archive:
        path = root / archive
        with zipfile.ZipFile(path, "w") as zf:
            for rel, data in files.items():
                zf.writestr(rel, data)
        return path
    for rel, data in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
    return root
