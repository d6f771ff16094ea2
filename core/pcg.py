"""Preconditioned conjugate gradients with BLAS-free dot products (the inner solver of the
Levenberg–Marquardt steps in :mod:`core.edge_length_fit`).

Hand-written rather than ``scipy.sparse.linalg.cg``: its dot products go through BLAS, which is
multithreaded and slow for these vector sizes on a busy machine (see docs/design-decisions.md).
"""

from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """Vector dot product without BLAS (see the module docstring)."""
    return float(np.einsum("i,i->", a, b))


def pcg(apply_A, b, apply_M, iterations, tolerance):
    """Preconditioned conjugate gradients for an SPD operator (fixed small API, any SciPy)."""
    x = np.zeros_like(b)
    r = b.copy()
    z = apply_M(r)
    p = z.copy()
    rz = dot(r, z)
    b_norm2 = dot(b, b)
    if b_norm2 == 0:
        return x
    for _ in range(iterations):
        Ap = apply_A(p)
        pAp = dot(p, Ap)
        if not pAp > 0:
            break
        alpha = rz / pAp
        x += alpha * p
        r -= alpha * Ap
        if dot(r, r) <= tolerance * tolerance * b_norm2:
            break
        z = apply_M(r)
        rz_new = dot(r, z)
        p *= rz_new / rz
        p += z
        rz = rz_new
    return x
