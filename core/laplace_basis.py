"""Laplace–Beltrami eigenbasis of a mesh (paper §6.2): ``C φ = λ A φ``, ``λ ≥ 0``, A-orthonormal."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import MeshError, RecoveryError

#: Up to this many vertices a dense generalized eigensolver is faster and more robust than ARPACK.
DENSE_EIGEN_LIMIT = 600


@dataclass(frozen=True, eq=False)
class LaplaceBasis:
    """The first ``k`` eigenpairs: ``eigenvalues`` float64 ``(k,)`` ascending (the first ≈ 0 per
    connected component) and ``functions`` float64 ``(n, k)`` with ``Φᵀ A Φ = I``."""

    eigenvalues: np.ndarray
    functions: np.ndarray

    @property
    def size(self) -> int:
        return int(self.eigenvalues.size)

    def pseudo_inverse_eigenvalues(self, relative_tolerance: float = 1e-9) -> np.ndarray:
        """``diag(λ)⁺`` of eq. (5) as a vector ``(k,)``: 1/λ, and 0 for the (near-)zero modes."""
        scale = max(float(np.max(np.abs(self.eigenvalues))), np.finfo(float).tiny)
        out = np.zeros_like(self.eigenvalues)
        keep = np.abs(self.eigenvalues) > relative_tolerance * scale
        out[keep] = 1.0 / self.eigenvalues[keep]
        return out


def basis_sizes(k_M, k_N) -> tuple[int | None, int | None]:
    """Normalize the basis sizes of eqs. (5)–(6): ``None`` or ``0`` means the full basis (the
    sidebar's convention); ``k_N`` (target basis) needs ``k_M`` (base basis)."""
    k_M, k_N = (k or None for k in (k_M, k_N))
    if k_N is not None and k_M is None:
        raise MeshError("k_N (target basis size) needs k_M (base basis size); set both or neither.")
    return k_M, k_N


def laplace_basis(mass: sp.spmatrix, conformal: sp.spmatrix, k: int, *, what: str = "mesh") -> LaplaceBasis:
    """The ``k`` smallest eigenpairs of ``(C, A)`` (scipy ``eigsh`` in shift-invert mode about a
    small negative shift, so the factorized matrix ``C − σA`` is positive definite).

    ``mass``, ``conformal``: float64 sparse ``(n, n)``. Raises :class:`MeshError` if ``k`` is not in
    ``1..n-1`` and :class:`RecoveryError` if the eigensolver fails.
    """
    n = mass.shape[0]
    if not 1 <= k < n:
        raise MeshError(
            f"The {what} has {n} vertices, so the number of Laplace–Beltrami eigenfunctions must be "
            f"between 1 and {n - 1}; got {k}. Lower k, or use 0 / None for the full basis."
        )
    if n <= DENSE_EIGEN_LIMIT:
        from scipy.linalg import eigh

        values, vectors = eigh(conformal.toarray(), mass.toarray(), subset_by_index=[0, k - 1])
        return LaplaceBasis(values, vectors)
    from scipy.sparse.linalg import ArpackNoConvergence, eigsh

    diag_ratio = conformal.diagonal() / mass.diagonal()
    shift = -1e-3 * float(np.median(diag_ratio[np.isfinite(diag_ratio)]))
    try:
        # A fixed start vector: ARPACK's own is drawn from a generator that advances with every
        # call, so repeated eigenspaces (symmetric meshes) came out rotated differently per call
        # and recoveries depended, at round-off, on what had run before in the process.
        start = np.random.default_rng(0).standard_normal(n)
        values, vectors = eigsh(conformal.tocsc(), k=k, M=mass.tocsc(), sigma=shift, which="LM", v0=start)
    except (ArpackNoConvergence, RuntimeError) as error:
        raise RecoveryError(
            f"The Laplace–Beltrami eigensolver did not converge for the {what} with k = {k} "
            f"({error}). Try a smaller k or check the mesh for nearly degenerate triangles."
        ) from error
    order = np.argsort(values)
    return LaplaceBasis(values[order], vectors[:, order])
