"""Feedback hints for failures that lie outside the homework (pure functions of an error's text).

``numpy2_hint(error_text)``: code written for NumPy 1 that uses a name NumPy removed (the scalar
aliases np.float/np.int/np.bool/np.object/... went in NumPy 1.24, the aliases and old functions of
the main namespace in NumPy 2.0) crashes with ``AttributeError: module 'numpy' has no attribute
'X'``.  The kit does not grade such code under NumPy 1: it runs under the NumPy installed with the
kit, so the call fails and scores nothing; the hint tells the student which name to replace.

Since NumPy 1.24, ``np.array`` of a ragged list (arrays or rows of different lengths) raises
``ValueError: setting an array element with a sequence. The requested array has an inhomogeneous
shape after N dimensions...`` instead of making an object array; the message does not say what to
look for, so ``numpy2_hint`` gives that error a hint too.
"""

from __future__ import annotations

import re

__all__ = ["NUMPY_REMOVED", "RAGGED_HINT", "numpy2_hint"]

# removed name -> its replacement (NumPy 1.24 expired aliases and NumPy 2.0's main-namespace removals)
NUMPY_REMOVED: dict[str, str] = {
    # scalar-type aliases of builtins (expired in NumPy 1.24)
    "float": "float (or np.float64)", "int": "int (or np.int64)", "bool": "bool (or np.bool_)",
    "object": "object (or np.object_)", "str": "str (or np.str_)", "complex": "complex (or np.complex128)",
    "long": "int", "unicode": "str",
    # constants
    "Inf": "np.inf", "Infinity": "np.inf", "infty": "np.inf", "PINF": "np.inf", "NINF": "-np.inf",
    "NaN": "np.nan", "PZERO": "0.0", "NZERO": "-0.0",
    # type aliases
    "float_": "np.float64", "complex_": "np.complex128", "cfloat": "np.complex128", "longfloat": "np.longdouble",
    "singlecomplex": "np.complex64", "clongfloat": "np.clongdouble", "longcomplex": "np.clongdouble",
    "string_": "np.bytes_", "unicode_": "np.str_",
    # functions
    "product": "np.prod", "cumproduct": "np.cumprod", "alltrue": "np.all", "sometrue": "np.any",
    "asfarray": "np.asarray(x, dtype=float)", "msort": "np.sort(a, axis=0)", "row_stack": "np.vstack",
    "round_": "np.round", "in1d": "np.isin", "trapz": "np.trapezoid", "find_common_type": "np.result_type",
    "issubclass_": "issubclass", "mat": "np.asmatrix", "cast": "np.asarray(x, dtype=...)",
    "safe_eval": "ast.literal_eval", "deprecate": "warnings.warn(..., DeprecationWarning)",
    "source": "inspect.getsource", "who": "locals()", "recfromcsv": "np.genfromtxt(..., delimiter=',')",
    "recfromtxt": "np.genfromtxt", "disp": "print", "set_string_function": "np.set_printoptions",
    "geterrobj": "np.errstate", "seterrobj": "np.errstate", "fastCopyAndTranspose": "arr.T.copy()",
    "byte_bounds": "np.lib.array_utils.byte_bounds", "compare_chararrays": "np.char.compare_chararrays",
    "format_parser": "np.rec.format_parser", "tracemalloc_domain": "np.lib.tracemalloc_domain",
}

_PATTERN = re.compile(r"""module ['"]numpy['"] has no attribute ['"]([A-Za-z_][A-Za-z0-9_]*)['"]"""
                      r"""|`np\.([A-Za-z_][A-Za-z0-9_]*)` was (?:removed|a deprecated alias)""")


# NumPy's wording since 1.24 (the "inhomogeneous shape" part) and the older first sentence alone,
# which NumPy 1 gave for the same ragged list when a dtype was asked for.
_RAGGED = re.compile(r"inhomogeneous shape after \d+ dimension|setting an array element with a sequence")
RAGGED_HINT = ("This usually means a list of arrays (or rows) of different lengths or shapes was given to "
               "np.array (or np.vstack, np.stack...), e.g. rows of different length stacked into one array, or "
               "a number mixed with an array: check the shapes of what you put in that list.")


def numpy2_hint(error_text: str) -> str | None:
    """One feedback line for an error caused by a name NumPy removed, or by a ragged list given to
    np.array (:data:`RAGGED_HINT`), else None.

    error_text : the error's text (``str(exc)``, or "AttributeError: ..." as feedback shows it).
    Returns e.g. "np.Inf is gone from NumPy (removed in 1.24 or 2.0): use np.inf instead. The kit
    runs your code under NumPy 2.4.6, so this call failed and scored nothing." when the text names
    a removed attribute of numpy (NUMPY_REMOVED), else None.
    """
    if not isinstance(error_text, str):
        return None
    if _RAGGED.search(error_text):
        return RAGGED_HINT
    m = _PATTERN.search(error_text)
    if m is None:
        return None
    name = m.group(1) or m.group(2)
    replacement = NUMPY_REMOVED.get(name)
    if replacement is None:
        return None
    try:
        import numpy

        version = f"NumPy {numpy.__version__}"
    except ImportError:  # pragma: no cover - numpy is a dependency of the kit
        version = "the installed NumPy"
    return (f"np.{name} is gone from NumPy (removed in 1.24 or 2.0): use {replacement} instead. "
            f"The kit runs your code under {version}, so this call failed and scored nothing.")
