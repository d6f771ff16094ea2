"""Closed-form operations on stacks of 3×3 matrices (``(k, 3, 3)``), used where NumPy's batched
LAPACK calls pay per-matrix and thread overheads that dominate at this size (the block-Jacobi
preconditioner of :mod:`core.edge_length_fit` inverts one 3×3 block per point per step)."""

from __future__ import annotations

import numpy as np

from .geometry import rows_dot


def cofactors_3x3(matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cofactor matrices ``(k, 3, 3)`` and determinants ``(k,)`` of ``matrices`` ``(k, 3, 3)``.

    Column ``j`` of the cofactor matrix is the cross product of the other two columns (in cyclic
    order), so the inverse is ``cofactorsᵀ / det`` and the inverse transpose ``cofactors / det``.
    """
    c0, c1, c2 = matrices[:, :, 0], matrices[:, :, 1], matrices[:, :, 2]
    cofactors = np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], axis=2)
    return cofactors, rows_dot(c0, cofactors[:, :, 0])
