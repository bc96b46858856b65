"""One judgment per concept: pure functions (a student's returned values, the ground truth) -> Verdict.

Used by both the public self-checks (starter.checks: public scenes, advice) and the hidden
tests (autograder/hidden: hidden scenes, points).  The two may differ in inputs and in what they
disclose, never in what they call right.  Layer 2: imports core only (not
starter, one layer up: the helpers it needs, rodrigues and camera2, are core's).

Modules: ``verdict`` (Verdict, Malformed, the readers of returned values), ``mistakes`` (the
catalogue of known mistakes), and one per solutions module: ``fundamental``, ``essential``,
``triangulation``, ``pose``, ``correspondence``, ``bundle``, ``multiview``.
"""

from .mistakes import KNOWN_MISTAKES, Mistake, mistake
from .verdict import Malformed, Verdict, fmt, read_array, read_number, read_parts

__all__ = ["KNOWN_MISTAKES", "Malformed", "Mistake", "Verdict", "fmt", "mistake", "read_array", "read_number",
           "read_parts"]
