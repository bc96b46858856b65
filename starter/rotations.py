"""The handout's rotation helpers, ``rodrigues`` and ``invRodrigues``, under their student-facing module name.

Defined in :mod:`core.rotations` (below ``judging``, which uses them too); re-exported here so
that ``from starter.rotations import rodrigues`` and ``from starter import rodrigues`` keep working.
"""

from core.rotations import invRodrigues, rodrigues

__all__ = ["rodrigues", "invRodrigues"]
