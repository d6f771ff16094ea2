"""Laplace–Beltrami eigenbasis of a mesh (paper §6.2): ``C φ = λ A φ``, ``λ ≥ 0``, A-orthonormal."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import MeshError, RecoveryError

#: Up to this many vertices a dense generalized eigensolver is faster and more robust than ARPACK.
DENSE_EIGEN_LIMIT = 600
#: Above it, a basis of at least this fraction of the vertices is also computed densely
#: (``scipy.linalg.eigh`` with ``subset_by_index``): ARPACK's cost grows like n k², the dense
#: solve's like n³. Measured on a 2,500-vertex sheet, one BLAS thread, same (loaded) run: ARPACK
#: 1.2 / 2.2 / 6.7 / 29 s for k = 50 / 100 / 200 / 400, dense 27 s for k = 500 and 1,000, 59 s
#: for k = 2,000 (ARPACK did not finish k = 2,000 in 250 s in issue 19). LAPACK's divide and
#: conquer (``driver="gvd"``) on every eigenpair, then truncated, beats the subset driver ``gvx``
#: even for k = 500 (another loaded run: 50 s against 78 s for k = 500 and 81 s for k = 2,000).
DENSE_EIGEN_FRACTION = 1.0 / 6.0
#: Largest vertex count solved densely (two n × n float64 matrices and LAPACK's work space:
#: about 3 GB at this size); larger meshes use ARPACK whatever k.
DENSE_EIGEN_MAX_VERTICES = 12000


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


def basis_sizes(k_M, k_N, n_vertices: int | None = None) -> tuple[int | None, int | None]:
    """Normalize the basis sizes of eqs. (5)–(6): ``None`` or ``0`` means the full basis (the
    sidebar's convention); ``k_N`` (target basis) needs ``k_M`` (base basis). Whole numbers only,
    below ``n_vertices`` when given (:func:`core.validation.check_basis_sizes`)."""
    from .validation import check_basis_sizes

    return check_basis_sizes(k_M, k_N, n_vertices)


def laplace_basis(mass: sp.spmatrix, conformal: sp.spmatrix, k: int, *, what: str = "mesh") -> LaplaceBasis:
    """The ``k`` smallest eigenpairs of ``(C, A)``: scipy ``eigsh`` in shift-invert mode about a
    small negative shift (so the factorized matrix ``C − σA`` is positive definite), or a dense
    ``eigh`` for small meshes and for bases of at least :data:`DENSE_EIGEN_FRACTION` of the
    vertices.

    ``mass``, ``conformal``: float64 sparse ``(n, n)``. Raises :class:`MeshError` if ``k`` is not in
    ``1..n-1`` and :class:`RecoveryError` if the eigensolver fails.
    """
    n = mass.shape[0]
    if not 1 <= k < n:
        raise MeshError(
            f"The {what} has {n} vertices, so the number of Laplace–Beltrami eigenfunctions must be "
            f"between 1 and {n - 1}; got {k}. Lower k, or use 0 / None for the full basis."
        )
    if n <= DENSE_EIGEN_LIMIT or (k >= DENSE_EIGEN_FRACTION * n and n <= DENSE_EIGEN_MAX_VERTICES):
        from scipy.linalg import LinAlgError, eigh

        try:
            if n <= DENSE_EIGEN_LIMIT:
                values, vectors = eigh(conformal.toarray(), mass.toarray(), subset_by_index=[0, k - 1])
            else:  # divide and conquer on every pair, then the first k: faster than the subset driver
                values, vectors = eigh(conformal.toarray(), mass.toarray(), driver="gvd")
                values, vectors = values[:k], vectors[:, :k]
        except (LinAlgError, ValueError) as error:
            raise RecoveryError(
                f"The Laplace–Beltrami eigensolver failed for the {what} with k = {k} ({error}). "
                "Check the mesh for nearly degenerate triangles."
            ) from error
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
