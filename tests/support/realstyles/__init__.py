"""Hand-ins in real students' styles, each with the verdict the handout supports.

The kit's own corpus (tests/support/corpus) is the answer key with one mutation: it follows the grader's
conventions.  This corpus follows the students'.  A study of public 16-720 HW4 hand-ins (see the
branch's report) found three layouts and the habits below; each program here is a complete
submission composed from per-function snippets (``snippets``) written for this corpus in those
styles, put into its year's layout:

- ``per_part`` (2022-2024): ``q2_1_eightpoint.py``, ``q3_1_essential_matrix.py``,
  ``q3_2_triangulate.py`` (triangulate and findM2), ``q4_1_epipolar_correspondence.py``,
  ``q4_2_visualize.py``, ``q5_bundle_adjustment.py``, ``q6_ec_multi_view_reconstruction.py``
  importing each other and ``helper`` (not shipped), each with a ``__main__`` block that loads
  ``data/`` and saves to ``result/``; ``findM2(F, pts1, pts2, intrinsics, filename='q3_3.npz')``,
  ``compute3D_pts(temple_pts1, intrinsics, F, im1, im2)``; zipped inside a folder;
- ``submission_py`` (2018-2021, and Fall 2023 again): ``submission.py`` (``import helper``,
  ``helper.refineF(...)``), ``findM2.py`` (findM2(F, pts1, pts2, K1, K2) and a top-level script),
  ``visualize.py`` (Q4.2 as a script: no compute3D_pts function at all); with or without the
  student's own ``helper.py``; the Fall 2023 variant imports the course's helpers as ``util``;
- ``notebook``: one notebook holding every function (the kit's signatures), with the cells that run.

``PROGRAMS`` maps each name to its :class:`Program`: the questions it must lose (empty: full marks
on every autograded question) and why, from the handout.  The table:

=========================================================  ===============  ====================================================
program                                                    must lose        why (handout)
=========================================================  ===============  ====================================================
y2022_per_part_refine_raw_full                             -                refineF may be called before unscaling; it returns
                                                                            a rank-2 F, so rank 2 by refineF alone is enforced
y2023_per_part_nine_vector_refine_full                     -                the course's refineF took F as a 9-vector (it
                                                                            reshaped it); E / norm; whole-line SAD matcher on
                                                                            0-255 intensities; compute3D_pts writes result/
                                                                            and returns M2 (Q4.2 is the 3D points, shown);
                                                                            BA with scipy.optimize.minimize, as the handout says
y2024_per_part_refine_inside_full                          -                refineF imported inside eightpoint: still refineF
y2019_submission_py_helper_module_full                     -                helper.refineF after an SVD rank 2; findM2 keeps the
                                                                            candidate with most points in front of both
                                                                            cameras; Q4.2 is a script (no compute3D_pts)
y2021_submission_py_own_helper_full                        -                the student's own helper.py (the course's refineF,
                                                                            9-vector accepted); E / E[2, 2]
y2023_submission_py_util_full                              -                Fall 2023's helpers were util.py: util.refineF
y2025_notebook_default_arg_refine_full                     -                refineF bound as eightpoint's default argument
y2025_notebook_svd_only_full                               -                no refineF ("may"), SVD rank 2, F / norm
y2022_per_part_compute3D_mapping_full                      -                temple_pts1['x1'], ['y1']: templeCoords' N x 1 columns
y2025_notebook_compute3D_homogeneous_full                  -                compute3D_pts returns the points homogeneous (N x 4)
y2020_submission_py_saves_to_data_full                     -                eightpoint saves F to ../data/q2_1.npz
y2019_submission_py_transposed_helper_refine_loses_Q2      Q2               FAQ: a transposed F polished by refineF
y2024_per_part_transposed_refine_inside_loses_Q2           Q2               the same, refineF imported inside eightpoint
y2025_notebook_transposed_refine_default_arg_loses_Q2      Q2               the same, refineF a default argument
y2022_per_part_rank3_loses_Q2                              Q2               "you must enforce the singularity condition"
y2025_notebook_not_unscaled_loses_Q2                       Q2               "you will have to unscale F"
y2023_submission_py_inplace_divide_loses_Q2                Q2               pts1 /= M fails on the official uint16 points
y2022_per_part_E_swapped_loses_Q3_1_Q3_3                   Q3.1 Q3.3        E = K1^T F K2 (findM2 uses it)
y2022_per_part_findM2_camera1_only_loses_Q3_3              Q3.3             points in front of camera 1 only, smallest
                                                                            error among those: the twisted pair can win
y2025_notebook_matcher_returns_x1y1_loses_Q4_1_Q4_2        Q4.1 Q4.2        returns the point of image 1, not its match
y2024_per_part_matcher_wrong_line_loses_Q4_1_Q4_2         Q4.1 Q4.2        searches the line F^T x1
y2025_notebook_matcher_small_box_loses_Q4_1_Q4_2          Q4.1 Q4.2        searches rows y1 +- 10 px only
y2023_per_part_multiview_views_1_2_loses_Q6               Q6               two confident views taken as views 1 and 2 always
=========================================================  ===============  ====================================================

``build(name, folder)`` writes the hand-in (a folder, or a zip for the per-part layout) and
returns its path; ``load(name, folder)`` loads it in this process the way the sandbox child does
(``autograder.submission.read.load_submission``'s units, the student's modules served by the child's
importer) and returns a :class:`Loaded` (its functions and its modules, to be put back into
``sys.modules`` while it is called: a function may import ``helper`` when it runs).
"""

from __future__ import annotations

import contextlib
import sys
import types
from dataclasses import dataclass, field
from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

from . import snippets as s

__all__ = ["PROGRAMS", "QUESTION_FUNCTIONS", "Loaded", "Program", "build", "load"]

GRADED = ("eightpoint", "essentialMatrix", "triangulate", "findM2", "epipolarCorrespondence", "compute3D_pts",
          "rodriguesResidual", "bundleAdjustment", "MultiviewReconstruction", "plot_3d_keypoint_video")
# The functions each autograded question's public self-checks run on.
QUESTION_FUNCTIONS = {"Q2": ("eightpoint",), "Q3.1": ("essentialMatrix",), "Q3.2": ("triangulate",),
                      "Q3.3": ("findM2",), "Q4.1": ("epipolarCorrespondence",), "Q4.2": ("compute3D_pts",),
                      "Q5": ("rodriguesResidual", "bundleAdjustment"), "Q6": ("MultiviewReconstruction",)}


@dataclass(frozen=True)
class Program:
    """layout: "per_part", "submission_py", "submission_py_own_helper", "submission_py_util" or
    "notebook"; pieces: function -> its source (None: not written, as 2018-21's Q4.2 script);
    loses: the questions it must lose (all others full); why: one line, from the handout; half:
    it must lose at least half of each of them (True), or of those named (a set: the question of the
    mistaken function, where a later question that builds on it keeps the part it gets right)."""

    layout: str
    pieces: dict
    loses: frozenset = frozenset()
    why: str = ""
    # Keeps at most half of each question in ``loses``, or of the questions named (the mistakes whose
    # partial credit was found to keep most of a question; the others must only lose some).
    half: bool | frozenset = False

    def halves(self, qid: str) -> bool:
        """Whether the program must keep at most half of question ``qid``."""
        named = self.half if isinstance(self.half, frozenset) else (self.loses if self.half else frozenset())
        return qid in self.loses and qid in named

    @property
    def valid(self) -> bool:
        return not self.loses

    @property
    def costly(self) -> bool:
        """Its own optimiser costs most of a grading: minimize in bundle adjustment."""
        return "minimize" in (self.pieces.get("bundleAdjustment") or "")


def _pieces(**changes) -> dict:
    base = {"eightpoint": s.EP_REFINE_RAW, "essentialMatrix": s.ESS_E22, "triangulate": s.TRI_LOOP,
            "findM2": s.FM_INTR_BOTH, "epipolarCorrespondence": s.EC_GAUSS_LOCAL, "compute3D_pts": s.C3D_FIVE_P,
            "rodriguesResidual": s.RR_PLAIN, "bundleAdjustment": s.BA_LSQ, "MultiviewReconstruction": s.MV_LOOP,
            "plot_3d_keypoint_video": s.VIDEO}
    base.update(changes)
    return base


_OLD = dict(findM2=s.FM_K_COUNT, compute3D_pts=None)          # 2018-21: findM2 with K1, K2; Q4.2 a script
_NB = dict(findM2=s.FM_K_BOTH, compute3D_pts=s.C3D_SEVEN)     # the kit's signatures
_UTIL_EP = s.EP_SVD_THEN_HELPER_REFINE.replace("helper.", "util.")
_Q2 = frozenset({"Q2"})

PROGRAMS: dict[str, Program] = {
    # valid
    "y2022_per_part_refine_raw_full": Program("per_part", _pieces(), why="refineF before unscaling gives rank 2"),
    "y2023_per_part_nine_vector_refine_full": Program(
        "per_part", _pieces(eightpoint=s.EP_REFINE_NINE_VECTOR, essentialMatrix=s.ESS_NORM, triangulate=s.TRI_VECTOR,
                            epipolarCorrespondence=s.EC_WHOLE_LINE_UINT8, compute3D_pts=s.C3D_FIVE_M2_RESULT,
                            bundleAdjustment=s.BA_MINIMIZE),
        why="refineF of the 9-vector, E/norm, whole-line SAD, result/ writes, minimize: all the handout allows"),
    "y2024_per_part_refine_inside_full": Program(
        "per_part", _pieces(eightpoint=s.EP_REFINE_IMPORTED_INSIDE, essentialMatrix=s.ESS_PLAIN),
        why="refineF imported inside eightpoint is still the handout's refineF"),
    "y2019_submission_py_helper_module_full": Program(
        "submission_py", _pieces(eightpoint=s.EP_SVD_THEN_HELPER_REFINE, essentialMatrix=s.ESS_PLAIN, **_OLD),
        why="helper.refineF after SVD rank 2; Q4.2 through the student's matcher and triangulate"),
    "y2021_submission_py_own_helper_full": Program(
        "submission_py_own_helper", _pieces(eightpoint=s.EP_REFINE_NINE_VECTOR, triangulate=s.TRI_VECTOR,
                                            epipolarCorrespondence=s.EC_WHOLE_LINE_UINT8, **dict(_OLD, findM2=s.FM_K_BOTH)),
        why="the student's own copy of the course's helper.py"),
    "y2023_submission_py_util_full": Program(
        "submission_py_util", _pieces(eightpoint=_UTIL_EP, essentialMatrix=s.ESS_PLAIN, **_OLD),
        why="Fall 2023 gave its helpers as util.py (not shipped, like helper.py)"),
    "y2025_notebook_default_arg_refine_full": Program(
        "notebook", _pieces(eightpoint=s.EP_REFINE_DEFAULT_ARG, essentialMatrix=s.ESS_NORM, triangulate=s.TRI_VECTOR,
                            **_NB), why="refineF bound as a default argument is refineF"),
    "y2025_notebook_svd_only_full": Program(
        "notebook", _pieces(eightpoint=s.EP_SVD_ONLY, epipolarCorrespondence=s.EC_WHOLE_LINE_UINT8, **_NB),
        why="refineF is optional ('you may find it helpful')"),
    "y2022_per_part_compute3D_mapping_full": Program(
        "per_part", _pieces(compute3D_pts=s.C3D_FIVE_MAPPING),
        why="compute3D_pts(temple_pts1, ...) indexes temple_pts1['x1'] as the course's templeCoords.npz"),
    "y2025_notebook_compute3D_homogeneous_full": Program(
        "notebook", _pieces(**dict(_NB, compute3D_pts=s.C3D_SEVEN_HOMOGENEOUS)),
        why="the 3D points returned homogeneous (N x 4, last column 1) are the same points"),
    "y2020_submission_py_saves_to_data_full": Program(
        "submission_py", _pieces(eightpoint=s.EP_SAVES_TO_DATA, essentialMatrix=s.ESS_PLAIN, **_OLD),
        why="eightpoint saves its F to ../data/q2_1.npz as the course's drivers did: F is still right"),
    # mistakes
    "y2019_submission_py_transposed_helper_refine_loses_Q2": Program(
        "submission_py", _pieces(eightpoint=s.EP_TRANSPOSED_HELPER_REFINE, **_OLD), _Q2,
        why="FAQ: refineF can polish a transposed F; comment it out and the lines are wrong", half=True),
    "y2024_per_part_transposed_refine_inside_loses_Q2": Program(
        "per_part", _pieces(eightpoint=s.EP_TRANSPOSED_REFINE_INSIDE), _Q2,
        why="the FAQ's transposed F, refineF imported inside eightpoint", half=True),
    "y2025_notebook_transposed_refine_default_arg_loses_Q2": Program(
        "notebook", _pieces(eightpoint=s.EP_TRANSPOSED_REFINE_DEFAULT_ARG, **_NB), _Q2,
        why="the FAQ's transposed F, refineF a default argument", half=True),
    "y2022_per_part_rank3_loses_Q2": Program("per_part", _pieces(eightpoint=s.EP_RANK3), _Q2,
                                             why="'You must enforce the singularity condition of F'"),
    "y2025_notebook_not_unscaled_loses_Q2": Program("notebook", _pieces(eightpoint=s.EP_NOT_UNSCALED, **_NB), _Q2,
                                                    why="'After computing F, you will have to unscale it'"),
    "y2023_submission_py_inplace_divide_loses_Q2": Program(
        "submission_py", _pieces(eightpoint=s.EP_INPLACE_DIVIDE, **_OLD), _Q2,
        why="pts1 /= M raises on the official uint16 points that eightpoint(pts1, pts2, M) is given"),
    "y2022_per_part_E_swapped_loses_Q3_1_Q3_3": Program(
        "per_part", _pieces(essentialMatrix=s.ESS_SWAPPED), frozenset({"Q3.1", "Q3.3"}),
        why="E = K2^T F K1, not K1^T F K2; findM2 builds on E"),
    "y2022_per_part_findM2_camera1_only_loses_Q3_3": Program(
        "per_part", _pieces(findM2=s.FM_INTR_CAM1), frozenset({"Q3.3"}),
        why="'the correct M2' has the points in front of both cameras; camera 1 alone admits the twisted pair"),
    "y2025_notebook_matcher_returns_x1y1_loses_Q4_1_Q4_2": Program(
        "notebook", _pieces(epipolarCorrespondence=s.EC_RETURNS_X1Y1, **_NB), frozenset({"Q4.1", "Q4.2"}),
        why="returns the pixel of im1, not 'the coordinates of the pixel on im2'"),
    "y2024_per_part_matcher_wrong_line_loses_Q4_1_Q4_2": Program(
        "per_part", _pieces(epipolarCorrespondence=s.EC_WRONG_LINE), frozenset({"Q4.1", "Q4.2"}),
        why="the match lies on F x1 ('the epipolar line'), not on F^T x1; compute3D_pts builds on it",
        half=frozenset({"Q4.1"})),
    "y2025_notebook_matcher_small_box_loses_Q4_1_Q4_2": Program(
        "notebook", _pieces(epipolarCorrespondence=s.EC_SMALL_BOX, **_NB), frozenset({"Q4.1", "Q4.2"}),
        why="'search along the epipolar line': rows within 10 px of y1 miss the matches further along it",
        half=frozenset({"Q4.1"})),
    "y2023_per_part_multiview_views_1_2_loses_Q6": Program(
        "per_part", _pieces(MultiviewReconstruction=s.MV_VIEWS_1_2), frozenset({"Q6"}),
        why="'only use the points whose confidence is above Thres': two confident views are not always 1 and 2", half=True),
}

# --------------------------------------------------------------------------------- layouts

_MAIN_22 = '''

if __name__ == "__main__":
    correspondence = np.load('data/some_corresp.npz')
    intrinsics = np.load('data/intrinsics.npz')
    K1, K2 = intrinsics['K1'], intrinsics['K2']
    pts1, pts2 = correspondence['pts1'], correspondence['pts2']
    im1 = plt.imread('data/im1.png')
    im2 = plt.imread('data/im2.png')
    F = eightpoint(pts1, pts2, M=np.max([*im1.shape, *im2.shape]))
{extra}'''


def _main22(extra: str) -> str:
    return _MAIN_22.format(extra="".join(f"    {line}\n" for line in extra.splitlines()))


def _code(*parts) -> str:
    return "\n\n".join(p.rstrip("\n") for p in parts if p) + "\n"


def _per_part(p: Program) -> dict[str, str]:
    imp = "import numpy as np\nimport matplotlib.pyplot as plt\n"
    c = p.pieces
    return {
        "q2_1_eightpoint.py": _code(
            imp + "\nfrom helper import displayEpipolarF, calc_epi_error, toHomogenous, refineF, _singularize\n\n"
                  "# Insert your package here\n", c["eightpoint"],
            _main22("np.savez('result/q2_1.npz', F=F, M=640)\ndisplayEpipolarF(im1, im2, F)")),
        "q3_1_essential_matrix.py": _code(
            imp + "\nfrom helper import camera2\nfrom q2_1_eightpoint import eightpoint\n", c["essentialMatrix"],
            _main22("E = essentialMatrix(F, K1, K2)\nprint(E)\nnp.savez('result/q3_1.npz', E=E)")),
        "q3_2_triangulate.py": _code(
            imp + "\nfrom helper import camera2\nfrom q2_1_eightpoint import eightpoint\n"
                  "from q3_1_essential_matrix import essentialMatrix\n", c["triangulate"], c["findM2"],
            _main22("M2, C2, P = findM2(F, pts1, pts2, intrinsics)\nnp.savez('result/q3_3.npz', M2=M2, C2=C2, P=P)")),
        "q4_1_epipolar_correspondence.py": _code(
            imp + "\nfrom helper import _epipoles\nfrom q2_1_eightpoint import eightpoint\n",
            c["epipolarCorrespondence"],
            _main22("x2, y2 = epipolarCorrespondence(im1, im2, F, 119, 217)\n"
                    "np.savez('result/q4_1.npz', F=F, pts1=pts1, pts2=pts2)")),
        "q4_2_visualize.py": _code(
            imp + "from mpl_toolkits.mplot3d import Axes3D\n\nfrom q2_1_eightpoint import eightpoint\n"
                  "from q3_2_triangulate import findM2, triangulate\n"
                  "from q4_1_epipolar_correspondence import epipolarCorrespondence\n", c["compute3D_pts"],
            _main22("coords = np.load('data/templeCoords.npz')\n"
                    "P = compute3D_pts(np.hstack([coords['x1'], coords['y1']]), intrinsics, F, im1, im2)\n"
                    "ax = plt.axes(projection='3d')\nax.scatter3D(P[:, 0], P[:, 1], P[:, 2])\nplt.show()")),
        "q5_bundle_adjustment.py": _code(
            imp + "import scipy\nimport scipy.optimize\nfrom scipy.optimize import least_squares\n\n"
                  "from helper import displayEpipolarF, calc_epi_error, toHomogenous, rodrigues, invRodrigues\n"
                  "from q2_1_eightpoint import eightpoint\nfrom q3_2_triangulate import findM2\n",
            c["rodriguesResidual"], c["bundleAdjustment"],
            _main22("noisy = np.load('data/some_corresp_noisy.npz')\nnp.random.seed(1)")),
        "q6_ec_multi_view_reconstruction.py": _code(
            imp + "\nfrom helper import *\nfrom q3_2_triangulate import triangulate\n",
            c["MultiviewReconstruction"], c["plot_3d_keypoint_video"]),
    }


# The student's own copy of the course's helper.py (2018-21 hand-ins shipped it): refineF
# accepts F as a 3x3 or as its 9 entries, as the course's did.
OWN_HELPER = '''\
"""
Helper functions.
"""
import numpy as np
import scipy.optimize
from starter import camera2, rodrigues, invRodrigues


def _singularize(F):
    U, S, V = np.linalg.svd(F)
    S[-1] = 0
    return U.dot(np.diag(S).dot(V))


def _objective_F(f, pts1, pts2):
    F = _singularize(f.reshape([3, 3]))
    n = pts1.shape[0]
    h1 = np.concatenate([pts1, np.ones([n, 1])], axis=1)
    h2 = np.concatenate([pts2, np.ones([n, 1])], axis=1)
    Fp1 = F.dot(h1.T)
    FTp2 = F.T.dot(h2.T)
    r = 0
    for fp1, fp2, hp2 in zip(Fp1.T, FTp2.T, h2):
        r += (hp2.dot(fp1)) ** 2 * (1 / (fp1[0] ** 2 + fp1[1] ** 2) + 1 / (fp2[0] ** 2 + fp2[1] ** 2))
    return r


def refineF(F, pts1, pts2):
    f = scipy.optimize.fmin_powell(lambda x: _objective_F(x, pts1, pts2), F.reshape([-1]),
                                   maxiter=100000, maxfun=10000, disp=False)
    return _singularize(f.reshape([3, 3]))


def displayEpipolarF(I1, I2, F):
    import matplotlib.pyplot as plt
    plt.imshow(I1)
    plt.show()
'''

_SUB_HEAD = '''\
"""
Homework4.
Replace 'pass' by your implementation.
"""

# Insert your package here
import numpy as np
import scipy.optimize
from scipy.optimize import least_squares
import {mod}
from {mod} import refineF, _singularize, camera2, rodrigues, invRodrigues

'''


def _submission_py(p: Program, mod: str = "helper") -> dict[str, str]:
    c = p.pieces
    order = ("eightpoint", "essentialMatrix", "triangulate", "epipolarCorrespondence", "rodriguesResidual",
             "bundleAdjustment", "MultiviewReconstruction", "plot_3d_keypoint_video")
    labels = {"eightpoint": "Q2.1: Eight Point Algorithm", "essentialMatrix": "Q3.1: Compute the essential matrix E.",
              "triangulate": "Q3.2: Triangulate a set of 2D coordinates", "epipolarCorrespondence":
              "Q4.1: 3D visualization of the temple images.", "rodriguesResidual": "Q5.3: Rodrigues residual.",
              "bundleAdjustment": "Q5.3 Bundle adjustment.", "MultiviewReconstruction": "Q6.1 Multi-View Reconstruction",
              "plot_3d_keypoint_video": "Q6.2 Plot Spatio-temporal (3D) keypoints"}
    body = "\n\n".join(f"'''\n{labels[f]}\n'''\n{c[f].rstrip()}\n" for f in order)
    files = {
        "submission.py": _SUB_HEAD.format(mod=mod) + body,
        "findM2.py": _code(
            "'''\nQ3.3:\n    1. Load point correspondences\n    2. Obtain the correct M2\n"
            "    3. Save the correct M2, C2, and P to q3_3.npz\n'''\nimport numpy as np\n"
            f"import submission as sub\nfrom submission import essentialMatrix, triangulate\nfrom {mod} import camera2\n",
            c["findM2"],
            "data = np.load('../data/some_corresp.npz')\nintrinsics = np.load('../data/intrinsics.npz')\n"
            "F = sub.eightpoint(data['pts1'], data['pts2'], 640)\n"
            "M2, C2, P = findM2(F, data['pts1'], data['pts2'], intrinsics['K1'], intrinsics['K2'])\n"
            "np.savez('q3_3.npz', M2=M2, C2=C2, P=P)"),
        "visualize.py": _code(
            "'''\nQ4.2:\n    1. Integrating everything together.\n    2. Loads necessary files from ../data/ "
            "and visualizes 3D reconstruction using scatter\n'''\nimport numpy as np\nimport matplotlib.pyplot as plt\n"
            "from mpl_toolkits.mplot3d import Axes3D\nimport submission as sub\nfrom findM2 import findM2\n",
            "if __name__ == '__main__':\n    coords = np.load('../data/templeCoords.npz')\n"
            "    im1 = plt.imread('../data/im1.png')\n    im2 = plt.imread('../data/im2.png')\n"
            "    q = np.load('q3_3.npz')\n    x1, y1 = coords['x1'], coords['y1']\n"
            "    pts2 = np.array([sub.epipolarCorrespondence(im1, im2, F, a, b) for a, b in zip(x1[:, 0], y1[:, 0])])\n"
            "    fig = plt.figure()\n    ax = fig.add_subplot(111, projection='3d')\n    plt.show()"),
    }
    if c.get("compute3D_pts"):
        files["visualize.py"] += "\n\n" + c["compute3D_pts"]
    if p.layout == "submission_py_own_helper":
        files["helper.py"] = OWN_HELPER
    return files


def _notebook(p: Program) -> dict[str, bytes]:
    cells = [new_markdown_cell("# 16-720 HW4: 3D reconstruction"),
             new_code_cell("%matplotlib inline\nimport numpy as np\nimport matplotlib.pyplot as plt\nimport scipy.optimize\n"
                           "from scipy.optimize import least_squares\n"
                           "from helper import refineF, _singularize, camera2, rodrigues, invRodrigues, displayEpipolarF")]
    for f, src in p.pieces.items():
        if src:
            cells += [new_markdown_cell(f"## {f}"), new_code_cell(src)]
    cells += [new_code_cell("data = np.load('data/some_corresp.npz')\nF = eightpoint(data['pts1'], data['pts2'], 640)\n"
                            "displayEpipolarF(plt.imread('data/im1.png'), plt.imread('data/im2.png'), F)")]
    return {"hw4.ipynb": nbformat.writes(new_notebook(cells=cells)).encode()}


def files(name: str) -> tuple[dict[str, bytes], str | None]:
    """(path -> bytes, the zip's name or None for a folder) of program ``name``."""
    p = PROGRAMS[name]
    if p.layout == "per_part":
        return ({f"andrew_hw4/python/{k}": v.encode() for k, v in _per_part(p).items()}, "andrew_hw4.zip")
    if p.layout == "notebook":
        return _notebook(p), None
    mod = "util" if p.layout == "submission_py_util" else "helper"
    return {f"code/{k}": v.encode() for k, v in _submission_py(p, mod).items()}, None


def build(name: str, folder: str | Path) -> Path:
    """Write program ``name`` into ``folder/name/`` (its files, or its zip) and return its path."""
    from handin_layouts import write_hand_in

    data, archive = files(name)
    return write_hand_in(Path(folder) / name, data, archive)


# --------------------------------------------------------------------------------- loading here

@dataclass
class Loaded:
    """A program loaded in this process: its homework functions, the student modules it made
    (name -> module) and the loading errors."""

    name: str
    functions: dict = field(default_factory=dict)
    modules: dict = field(default_factory=dict)
    errors: list = field(default_factory=list)

    @contextlib.contextmanager
    def active(self):
        """Its modules in ``sys.modules`` while its functions run (``from helper import refineF``
        inside a function imports at call time), the earlier entries back afterwards."""
        saved = {n: sys.modules.get(n) for n in self.modules}
        sys.modules.update(self.modules)
        try:
            yield self
        finally:
            for n, m in saved.items():
                if m is None:
                    sys.modules.pop(n, None)
                else:
                    sys.modules[n] = m


def load(name: str, folder: str | Path) -> Loaded:
    """Build program ``name`` in ``folder`` and load it here as the sandbox child would (only the
    kit's own tests do this; the grader runs submissions in its sandbox)."""
    from autograder.sandbox.child import load_units, StudentModules
    from autograder.submission.read import load_submission

    sub = load_submission(build(name, folder))
    units = [u.to_job() for u in sub.units()]
    importer = StudentModules([u for u in units if u.get("module")], set(), 500)
    names = list(importer.bodies)
    saved = {n: sys.modules.pop(n) for n in names if n in sys.modules}
    module = types.ModuleType(f"realstyle_{name}")
    sys.meta_path.append(importer)
    try:
        errors = load_units([u for u in units if not u.get("module")], module, 120.0, set(), 500) + importer.errors
        modules = {n: sys.modules[n] for n in names if n in sys.modules}
    finally:
        sys.meta_path.remove(importer)
        for n in names:
            sys.modules.pop(n, None)
        sys.modules.update(saved)
    functions = {f: module.__dict__[f] for f in GRADED if callable(module.__dict__.get(f))}
    return Loaded(name, functions, modules, errors)

