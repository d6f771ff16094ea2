"""Exceptions and warnings raised by the shape-difference core.

Every error says what is wrong, the first offending index where there is one, and how to fix it,
so that the Blender operators can show the message to the user unchanged.
"""

from __future__ import annotations


class ShapeDifferenceError(Exception):
    """Base class of every error raised by :mod:`core`."""


class MeshError(ShapeDifferenceError, ValueError):
    """The input mesh (or a pose of it) cannot be used: bad indices, degenerate or non-manifold
    geometry, inconsistent orientation, mismatched vertex counts, non-finite coordinates."""


class RecoveryError(ShapeDifferenceError, ArithmeticError):
    """Areas, edge lengths or an embedding cannot be recovered from the given shape differences
    (a singular system such as the paper's Fig. 2, a failed solver, an infeasible program)."""


class ShapeDifferenceWarning(UserWarning):
    """A result was computed, but through a documented fallback (e.g. an interpolated metric that
    is not exactly realizable); the message says which and why.

    ``kind``: what an in-between's warning is about, one of
    :data:`core.sequence_warnings.KINDS` (``"pose"``, ``"turn"``, ``"joint"``, …), for a pipeline
    to filter on (``w.message.kind`` of a recorded warning); None for the other warnings.
    ``defects``: how many flipped or collapsed triangles the in-between it is about keeps (of the
    in-betweens alike it speaks for, the worst); 0 where it keeps none or is about something else.
    ``gap``: the names of the two keys of the gap it is about, as the message says them (None where
    it is about no one gap); ``factors``: the factors of the in-betweens it is about (empty where
    it holds for every in-between of the gap, or is about something else)."""

    kind: str | None = None
    defects: int = 0
    gap: tuple[str, str] | None = None
    factors: tuple[float, ...] = ()


class MeshIndexError(MeshError, IndexError):
    """An index argument (e.g. a sequence's ``gap_index``) is out of range or not a whole number.
    Both a :class:`MeshError` and an ``IndexError``."""
