"""Closed-form operations on stacks of small matrices (``(k, 3, 3)``, ``(k, 2, 2)``), used where NumPy's
batched calls (LAPACK, ``matmul``, ``einsum``) pay per-matrix and thread overheads that dominate at
this size (the block-Jacobi preconditioner of :mod:`core.edge_length_fit` inverts one 3×3 block per
point per step; the sequences turn every piece and vertex by its rotation)."""

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


def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched products ``a @ b`` of small matrices (…, p, q) × (…, q, r), written out per entry:
    NumPy's batched ``matmul`` and ``einsum`` loop over the batch with per-matrix overhead and are
    5–10× slower for 2×2 and 3×3 blocks."""
    a, b = np.asarray(a), np.asarray(b)
    shape = np.broadcast_shapes(a.shape[:-2], b.shape[:-2]) + (a.shape[-2], b.shape[-1])
    out = np.empty(shape)
    for i in range(a.shape[-2]):
        for j in range(b.shape[-1]):
            entry = a[..., i, 0] * b[..., 0, j]
            for k in range(1, a.shape[-1]):
                entry = entry + a[..., i, k] * b[..., k, j]
            out[..., i, j] = entry
    return out


def transpose(a: np.ndarray) -> np.ndarray:
    """``a`` (…, p, q) with its last two axes swapped."""
    return np.swapaxes(a, -1, -2)
