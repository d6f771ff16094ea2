"""Shape differences between a base mesh M and a target N in vertex correspondence (paper §6).

Three forms, one class each:

- :class:`FullDifference`, eqs. (3)–(4): ``D = P_M⁻¹ P_N`` for an inner-product matrix pair
  ``P`` (``A`` or ``C``). The dense ``|V|×|V|`` operator is never formed: it is kept factored as
  the sparse pair, and recovery needs only ``P_M D = P_N`` (for ``C``, whose kernel is the
  constants, ``D = C_M⁺ C_N`` and ``C_M D = C_N`` all the same).
- :class:`ReducedDifference`, eq. (5): ``D_A = Φᵀ A_N Φ``, ``D_C = diag(λ)⁺ Φᵀ C_N Φ`` in the first
  ``k_M`` eigenfunctions of M.
- Functional-map (source- and target-truncated) differences, eq. (6): ``D_A = Fᵀ F``,
  ``D_C = diag(λ_M)⁺ Fᵀ diag(λ_N) F`` with ``F = Φ_Nᵀ A_N Φ_M`` the ``k_N × k_M`` functional map
  of the vertex correspondence; also a :class:`ReducedDifference` (with ``k_N`` recorded).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp

from .inner_products import ProductAssembler
from .laplace_basis import LaplaceBasis

Kind = Literal["area", "conformal"]


@dataclass(frozen=True, eq=False)
class FullDifference:
    """Full-basis shape difference ``D = P_M⁻¹ P_N`` (eqs. 3–4), stored factored.

    ``base_product`` and ``target_product`` are the sparse float64 ``(n, n)`` inner-product
    matrices of M and N (``A`` or ``C`` by ``kind``).
    """

    kind: Kind
    base_product: sp.csr_matrix
    target_product: sp.csr_matrix

    @classmethod
    def from_operator(cls, kind: Kind, base_product: sp.spmatrix, operator: np.ndarray) -> "FullDifference":
        """Wrap an explicitly given dense difference operator ``D`` (float64 ``(n, n)``), e.g. one
        computed elsewhere: ``P_N = P_M D`` is formed once (sparse times dense)."""
        return cls(kind, sp.csr_matrix(base_product), sp.csr_matrix(base_product @ np.asarray(operator)))

    def product_entries(self, assembler: ProductAssembler) -> tuple[np.ndarray, np.ndarray]:
        """Diagonal ``(n,)`` and per-edge ``(E,)`` entries of ``P_M D = P_N`` (what recovery needs)."""
        return assembler.entries(self.target_product)

    def dense(self) -> np.ndarray:
        """The dense operator ``D`` (float64 ``(n, n)``) — for inspection and tests on small meshes
        only; uses the pseudo-inverse for the conformal kind."""
        base = self.base_product.toarray()
        target = self.target_product.toarray()
        if self.kind == "area":
            return np.linalg.solve(base, target)
        return np.linalg.pinv(base, hermitian=True) @ target


@dataclass(frozen=True, eq=False)
class ReducedDifference:
    """Truncated shape difference (eq. 5, or eq. 6 when ``target_size`` is set): ``matrix`` float64
    ``(k_M, k_M)`` written in the base eigenbasis ``basis`` (``k_M`` functions)."""

    kind: Kind
    matrix: np.ndarray
    basis: LaplaceBasis
    target_size: int | None = None  # k_N for eq. (6), None for eq. (5)

    def product_matrix(self) -> np.ndarray:
        """The reduced target product the recovery programs fit (eq. 7): ``Φᵀ A_N Φ ≈ D_A`` and
        ``Φᵀ C_N Φ ≈ diag(λ) D_C``; float64 ``(k_M, k_M)``."""
        if self.kind == "area":
            return self.matrix
        return self.basis.eigenvalues[:, None] * self.matrix


def reduced_differences(
    basis: LaplaceBasis, target_mass: sp.spmatrix, target_conformal: sp.spmatrix
) -> tuple[ReducedDifference, ReducedDifference]:
    """Eq. (5): area and conformal differences of N in the first ``k_M`` eigenfunctions of M.

    ``basis``: M's eigenbasis (``Φ`` ``(n, k_M)``); ``target_*``: N's sparse ``(n, n)`` products.
    """
    phi = basis.functions
    area = phi.T @ (target_mass @ phi)
    conformal = basis.pseudo_inverse_eigenvalues()[:, None] * (phi.T @ (target_conformal @ phi))
    return ReducedDifference("area", _symmetric(area), basis), ReducedDifference("conformal", conformal, basis)


def functional_map(base_basis: LaplaceBasis, target_basis: LaplaceBasis, target_mass: sp.spmatrix) -> np.ndarray:
    """``F = Φ_Nᵀ A_N Φ_M``, float64 ``(k_N, k_M)``: the functional map of the identity vertex
    correspondence, taking M-basis coefficients to N-basis coefficients (§6.3)."""
    return target_basis.functions.T @ (target_mass @ base_basis.functions)


def functional_map_differences(
    base_basis: LaplaceBasis, target_basis: LaplaceBasis, target_mass: sp.spmatrix
) -> tuple[ReducedDifference, ReducedDifference]:
    """Eq. (6): source- and target-truncated differences ``D_A = FᵀF`` and
    ``D_C = diag(λ_M)⁺ Fᵀ diag(λ_N) F``, each float64 ``(k_M, k_M)``."""
    return map_differences(base_basis, target_basis.eigenvalues, functional_map(base_basis, target_basis, target_mass))


def map_differences(
    base_basis: LaplaceBasis, target_eigenvalues: np.ndarray, fmap: np.ndarray
) -> tuple[ReducedDifference, ReducedDifference]:
    """Eq. (6) for a given functional map ``fmap`` ``(k_N, k_M)`` (of this mesh's poses, or
    between two meshes, :mod:`core.functional_map`) and the target eigenvalues ``(k_N,)``."""
    area = fmap.T @ fmap
    conformal = base_basis.pseudo_inverse_eigenvalues()[:, None] * (fmap.T @ (target_eigenvalues[:, None] * fmap))
    k_n = int(target_eigenvalues.size)
    return (
        ReducedDifference("area", _symmetric(area), base_basis, k_n),
        ReducedDifference("conformal", conformal, base_basis, k_n),
    )


def _symmetric(matrix: np.ndarray) -> np.ndarray:
    return 0.5 * (matrix + matrix.T)
