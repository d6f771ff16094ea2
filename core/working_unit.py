"""The power of two the computations scale a mesh's positions by, so that they work near unit size
whatever the caller's units (a scan in metres or micrometres, a scene in light years).

Scaling by a power of two changes no mantissa bit (barring subnormal numbers), so results scaled
back are those of the same computation on a mesh of unit size. Used by the in-betweens
(:class:`core.sequence_keys.SequenceKeys`) and by the paper pipeline's base shape
(:class:`core.reference_shape.ReferenceShape`: the truncated recovery, :func:`core.reconstruct`,
:class:`core.transfer.Transfer`).
"""

from __future__ import annotations

import math

import numpy as np

#: The largest extent of positions worked on as given (powers of two, ~1e-3 to 1e3 units);
#: positions larger or smaller are scaled by the power of two that brings it into [1, 2), and the
#: results scaled back (both exact in floating point). Parts of the computations work in single
#: precision (:data:`core.inbetween_guide.LOCAL_STEP_DTYPE`, the truncated recovery's ADMM,
#: :class:`core.low_rank.SplitGram`), whose range squared lengths and their products leave far from
#: unit size (squares overflow past ~1e19, underflow below ~1e-19): a draped sheet keyed at 2^40 ×
#: its size came out 7e-8 of its diagonal off, at 2^70 × 4e-3 (NumPy overflow warnings), at 2^90 ×
#: 2.8 diagonals, at 2^-70 × 5e-4 (a hanging sheet: 8e-3); a truncated reconstruction at 2^-70 and a
#: transfer at 2^±40 failed in the single-precision factorization, a transfer at 2^40 came out 7.5e-2
#: of the diagonal off. Scaling by 2^±10 keeps every result to the bit or to 2e-16 of the diagonal.
WORKING_EXTENT = (2.0 ** -10, 2.0 ** 10)


def working_unit(positions: list[np.ndarray]) -> float:
    """The power of two to scale ``positions`` (a list of ``(n, 3)`` arrays: poses of one mesh) by:
    1 where their largest extent (over every pose and coordinate) lies within
    :data:`WORKING_EXTENT`, else the one that brings it into [1, 2)."""
    extent = max((_largest_extent(p) for p in positions if p.size), default=0.0)
    if extent == 0.0 or WORKING_EXTENT[0] <= extent <= WORKING_EXTENT[1]:
        return 1.0
    return math.ldexp(1.0, 1 - math.frexp(extent)[1])


def _largest_extent(points: np.ndarray) -> float:
    """The largest of the extents ``max − min`` of ``points`` (n, 3) along the three coordinates
    (``np.ptp(points, axis=0).max()``, the same value), reduced along contiguous coordinate rows:
    NumPy reduces a C-contiguous (n, 3) array along its first axis three values at a time (0.47
    against 0.04 ms at 10k points, per key)."""
    rows = np.ascontiguousarray(np.asarray(points).T)
    return float(np.max(rows.max(axis=1) - rows.min(axis=1)))
