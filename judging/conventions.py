"""How a homework function is called, by the convention its parameters were written for: one home
for the grader's hidden tests and the public self-checks, so one program gets the same call in both.

Students of other course years wrote other signatures for the same question; the grader and the
self-checks recognise them by the function's parameters (names and order, never by running it)
and call each the way its year's course did:

- ``findM2``: the kit's ``findM2(F, pts1, pts2, K1, K2)``; 2022-2024's
  ``findM2(F, pts1, pts2, intrinsics, filename='q3_3.npz')`` (intrinsics a dict {'K1', 'K2'});
  Fall 2023's ``findM2(pts1, pts2, F, K1, K2)`` (points first).  Whatever the order of the
  values returned (M2 alone, (M2, C2, w), or five values with M1 and C1), ``judging.pose.read_findM2``
  reads them;
- ``compute3D_pts``: the kit's ``compute3D_pts(im1, im2, F, x1, y1, C1, C2)``; 2022-2024's
  ``compute3D_pts(temple_pts1, intrinsics, F, im1, im2)`` (temple_pts1 an N x 2 array, or the dict
  of x1, y1 templeCoords.npz gives), returning P, or P among the cameras ((M2, C2, P), (M2, C2, P,
  M1, C1)): ``judging.correspondence.read_points`` reads them;
- ``ransacF``: the kit's ``ransacF(pts1, pts2, M, eightpoint, nIters, tol)`` and earlier years'
  ``ransacF(pts1, pts2, M, nIters=1000, tol=0.42)`` (a helper the kit gives: only noted).

:class:`Signature` is a function's parameters as written; the grader reads it from the syntax
tree (``autograder.submission.layout.signature_of``), a self-check from the function itself
(:func:`signature_of_callable`).  Imports numpy only.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np

__all__ = [
    "Call",
    "Signature",
    "another_years_ransacF",
    "compute3D_pts_five_calls",
    "findM2_call",
    "findM2_style",
    "five_arguments",
    "intrinsics_style",
    "points_first_style",
    "signature_of_callable",
    "with_signature",
]


@dataclass(frozen=True)
class Signature:
    """A function's parameters as written: positional (with ``defaults`` of them having one),
    ``varargs`` (``*args`` name or None), ``kwonly`` names, ``varkw`` (``**kw`` name or None)."""

    positional: tuple[str, ...]
    defaults: int = 0
    varargs: str | None = None
    kwonly: tuple[str, ...] = ()
    varkw: str | None = None

    @property
    def required(self) -> tuple[str, ...]:
        """Positional parameters without a default."""
        return self.positional[: len(self.positional) - self.defaults]

    def __str__(self) -> str:
        parts = [p if i < len(self.required) else f"{p}=..." for i, p in enumerate(self.positional)]
        if self.varargs:
            parts.append(f"*{self.varargs}")
        elif self.kwonly:
            parts.append("*")
        parts += list(self.kwonly)
        if self.varkw:
            parts.append(f"**{self.varkw}")
        return f"({', '.join(parts)})"


def signature_of_callable(fn) -> Signature | None:
    """The Signature of a function object (None when Python cannot tell: a builtin, not callable)."""
    try:
        ps = list(inspect.signature(fn).parameters.values())
    except (TypeError, ValueError):
        return None
    pos = tuple(p.name for p in ps if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD))
    defaults = sum(p.default is not p.empty for p in ps if p.name in pos)
    return Signature(pos, defaults, next((p.name for p in ps if p.kind == p.VAR_POSITIONAL), None),
                     tuple(p.name for p in ps if p.kind == p.KEYWORD_ONLY),
                     next((p.name for p in ps if p.kind == p.VAR_KEYWORD), None))


@dataclass(frozen=True)
class Call:
    """One call of a student's function: the positional ``args``, their parameter ``names`` (for
    the feedback's "called as"), and ``how`` in words when it is not the kit's signature ("")."""

    args: tuple
    names: tuple[str, ...]
    how: str = ""


def with_signature(fn, signature: Signature | None):
    """``fn`` (a callable taking ``*args, **kwargs``: a grader's stand-in for a student function)
    marked as having the student's ``signature`` (``__signature__``), so that
    :func:`signature_of_callable` and every convention below see the parameters the student wrote,
    not the stand-in's.  None leaves ``fn`` as it is.  Returns ``fn``."""
    if signature is None:
        return fn
    P = inspect.Parameter
    required = set(signature.required)
    params = [P(n, P.POSITIONAL_OR_KEYWORD, **({} if n in required else {"default": None}))
              for n in signature.positional]
    if signature.varargs:
        params.append(P(signature.varargs, P.VAR_POSITIONAL))
    params += [P(n, P.KEYWORD_ONLY, default=None) for n in signature.kwonly]
    if signature.varkw:
        params.append(P(signature.varkw, P.VAR_KEYWORD))
    try:
        fn.__signature__ = inspect.Signature(params)
    except (ValueError, TypeError):  # names Python itself refuses: the stand-in keeps its own
        pass
    return fn


# ------------------------------------------------------------------------------------ findM2

FINDM2_KIT = ("F", "pts1", "pts2", "K1", "K2")


def intrinsics_style(signature: Signature | None) -> bool:
    """True for another year's findM2(F, pts1, pts2, intrinsics, filename=...) (K1 and K2 in one dict)."""
    if signature is None or signature.varargs or "K1" in signature.positional:
        return False
    pos = signature.positional
    return len(pos) >= 4 and ("intrinsic" in pos[3].lower() or len(signature.required) == 4)


def _is_F(name: str) -> bool:
    return name.lower() in ("f", "fundamental", "fundamental_matrix", "f_matrix", "fmat")


def _is_points(name: str) -> bool:
    low = name.lower()
    return low.startswith(("pts", "pt", "points", "p")) and low[-1:] in ("1", "2")


def points_first_style(signature: Signature | None) -> bool:
    """True for Fall 2023's findM2(pts1, pts2, F, K1, K2): two point arrays, then F, then the two
    intrinsics matrices (named so: K1/K2, k1/k2), five required, read by name so that the kit's
    order is never mistaken for it."""
    if signature is None or signature.varargs or len(signature.required) != 5:
        return False
    p = signature.positional
    return (_is_points(p[0]) and _is_points(p[1]) and _is_F(p[2])
            and p[3].lower().startswith("k") and p[4].lower().startswith("k"))


def findM2_style(signature: Signature | None) -> str:
    """"kit", "intrinsics" (2022-2024) or "points_first" (Fall 2023)."""
    if points_first_style(signature):
        return "points_first"
    if intrinsics_style(signature):
        return "intrinsics"
    return "kit"


def findM2_call(signature: Signature | None, F, pts1, pts2, K1, K2) -> Call:
    """The call of findM2 on (F, pts1, pts2, K1, K2) in the convention ``signature`` was written for."""
    style = findM2_style(signature)
    if style == "intrinsics":
        args = (F, pts1, pts2, {"K1": K1, "K2": K2})
        if len(signature.required) >= 5:
            args += ("q3_3.npz",)
        return Call(args, signature.positional[:len(args)],
                    "findM2 was called as its parameters ask: findM2(F, pts1, pts2, intrinsics={'K1', 'K2'}, ...)")
    if style == "points_first":
        return Call((pts1, pts2, F, K1, K2), signature.positional[:5],
                    "findM2 was called as its parameters ask: findM2(pts1, pts2, F, K1, K2)")
    return Call((F, pts1, pts2, K1, K2), FINDM2_KIT)


# ------------------------------------------------------------------------------------ compute3D_pts

COMPUTE3D_KIT = ("im1", "im2", "F", "x1", "y1", "C1", "C2")


def five_arguments(signature: Signature | None) -> bool:
    """True for another year's compute3D_pts(temple_pts1, intrinsics, F, im1, im2) (2022-2024)."""
    return (signature is not None and len(signature.required) == 5 and not signature.varargs
            and "intrinsic" in signature.positional[1].lower())


def compute3D_pts_five_calls(signature: Signature | None, pts1, K1, K2, F, im1, im2) -> list[Call]:
    """The calls of 2022-2024's compute3D_pts(temple_pts1, intrinsics, F, im1, im2), in the order to
    try: temple_pts1 an N x 2 integer array, then the dict of x1, y1 (N, 1) as templeCoords.npz.
    ``pts1`` (N, 2) the points of image 1; images as given."""
    names = tuple(signature.positional[:5]) if signature is not None else (
        "temple_pts1", "intrinsics", "F", "im1", "im2")
    xy = np.rint(np.asarray(pts1, float)).astype(int)
    intrinsics = {"K1": np.array(K1, float), "K2": np.array(K2, float)}
    return [Call((xy, intrinsics, np.array(F, float), im1, im2), names, "temple_pts1 an Nx2 int array"),
            Call(({"x1": xy[:, :1].copy(), "y1": xy[:, 1:].copy()}, dict(intrinsics), np.array(F, float), im1, im2),
                 names, "temple_pts1 a dict of x1, y1 as templeCoords.npz")]


# ------------------------------------------------------------------------------------ ransacF

def another_years_ransacF(signature: Signature | None) -> bool:
    """True for an earlier year's ``ransacF(pts1, pts2, M, nIters=1000, tol=0.42)``: three required
    parameters and none taking the eight-point function, which the kit's
    ``ransacF(pts1, pts2, M, eightpoint, nIters=1000, tol=1.0)`` takes fourth."""
    if signature is None or signature.varargs or len(signature.positional) < 3:
        return False
    names = [p.lower() for p in (*signature.positional, *signature.kwonly)]
    return len(signature.required) == 3 and not any("eight" in p for p in names)
