"""Low-rank factorizations of positive semidefinite Gram matrices and the solves they allow.

Used by the truncated edge-length program (eq. 10, :mod:`core.truncated_recovery`), whose data
term has the Gram ``W = (U Uᵀ)∘²`` (edges × edges) with a fast-falling spectrum: a randomly
pivoted Cholesky factor of it, orthonormalized; and ``(FᵀF + D) x = r`` solved through the
``p × p`` capacitance matrix (Woodbury identity).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .geometry import DIVISION_FLOOR

#: Pivots drawn per block of randomly pivoted Cholesky (BLAS-3 column products; pivots made
#: redundant within a block are dropped by LAPACK's pivoted Cholesky).
PIVOT_BLOCK = 128
#: Relative pivot tolerance within a block: below it a pivot depends on the others to round-off.
PIVOT_TOLERANCE = 1e-12


@dataclass(frozen=True)
class LowRankGram:
    """``G ≈ Y diag(values) Yᵀ`` with ``Y`` ``(N, p)`` orthonormal; ``mean_diagonal`` of the exact G."""

    vectors: np.ndarray
    values: np.ndarray
    mean_diagonal: float


def randomly_pivoted_cholesky(columns, diagonal: np.ndarray, *, tolerance: float, max_rank: int,
                              block: int = PIVOT_BLOCK, seed: int = 0) -> np.ndarray:
    """Block randomly pivoted Cholesky (Chen, Epperly, Tropp, Webber 2023) of a PSD matrix ``G``
    ``(N, N)`` given only its ``diagonal`` and ``columns(S)`` ``(N, |S|)``: ``G ≈ F Fᵀ`` with
    ``F`` ``(N, r)``, stopped when the trace of the residual falls below ``tolerance`` × trace(G)
    or ``r`` reaches ``max_rank``. Pivots are drawn in blocks with probability proportional to
    the residual diagonal; each block's own Cholesky is LAPACK's pivoted one (``dpstrf``), which
    drops pivots made redundant by the others in the block. Cost O(N r² + r·cost(column)),
    memory O(N r): nothing of size N × N is formed or reserved."""
    from scipy.linalg import lapack

    n = diagonal.size
    rng = np.random.default_rng(seed)
    limit = min(max_rank, n)
    # Fᵀ, filled row by row (its leading rows stay contiguous), grown as pivots are found: sized
    # for max_rank it would be N × N for a full-rank bound (a 10k-vertex offset surface's 92,160
    # edges: 63 GiB) where the factor needs a few thousand rows.
    rows = np.empty((min(limit, block), n))
    residual = np.array(diagonal, dtype=np.float64)
    stop = tolerance * float(residual.sum())
    rank = 0
    while rank < limit and residual.sum() > stop:
        weights = np.maximum(residual, 0.0)
        picks = np.unique(rng.choice(n, size=min(block, limit - rank), p=weights / weights.sum()))
        cols = columns(picks)
        if rank:
            cols -= rows[:rank].T @ rows[:rank, picks]
        pivot_block = cols[picks]
        chol, order, found, _ = lapack.dpstrf(
            0.5 * (pivot_block + pivot_block.T), lower=1, tol=PIVOT_TOLERANCE * max(float(pivot_block.diagonal().max()), DIVISION_FLOOR)
        )
        if found == 0:
            break
        order = order[:found] - 1
        new = sla.solve_triangular(np.tril(chol[:found, :found]), cols[:, order].T, lower=True, check_finite=False)
        if rank + found > rows.shape[0]:  # doubling: copies cost O(rank · N) in all
            grown = np.empty((min(limit, max(2 * rows.shape[0], rank + found)), n))
            grown[:rank] = rows[:rank]
            rows = grown
        rows[rank : rank + found] = new
        rank += found
        residual -= np.einsum("ij,ij->j", new, new)
    return rows[:rank].T


def low_rank_gram(factor: np.ndarray, mean_diagonal: float) -> LowRankGram:
    """``F Fᵀ = Y diag(values) Yᵀ`` with orthonormal ``Y`` from the eigenpairs of ``FᵀF``
    (r × r; cheaper than a QR of the tall F)."""
    values, small = np.linalg.eigh(gram_of_rows(factor.T))
    keep = values > values[-1] * np.finfo(float).eps * factor.shape[1]
    order = np.argsort(values[keep])[::-1]
    values, small = values[keep][order], small[:, keep][:, order]
    return LowRankGram((factor @ small) / np.sqrt(values), values, mean_diagonal)



class Woodbury:
    """Solves ``(FᵀF + diag(d)) x = r`` with a ``p × p`` Cholesky factor of ``I + F D⁻¹ Fᵀ``
    (``capacitance``: that matrix when already known). ``products``: ``F`` as used for the two
    products with ``F`` and ``Fᵀ`` per solve (default ``f``; a float32 copy halves their memory
    traffic, which dominates their cost, for a relative rounding of ~1e-7 in the solution)."""

    def __init__(self, f: np.ndarray, d: np.ndarray, capacitance: np.ndarray | None = None, products=None):
        self.f, self.dinv = (f if products is None else products), 1.0 / d
        if capacitance is None:
            capacitance = f @ (self.dinv[:, None] * f.T)
            capacitance[np.diag_indices_from(capacitance)] += 1.0
        if not np.isfinite(capacitance).all():  # SciPy would raise a bare ValueError
            raise FloatingPointError("the low-rank system's capacitance matrix overflowed")
        self.chol = sla.cho_factor(capacitance, lower=True)

    def solve(self, r: np.ndarray) -> np.ndarray:
        """``x`` (N,) for ``r`` (N,); FloatingPointError where a value leaves the products' range."""
        f = self.f
        # A right-hand side past float32's 3.4e38 (squared lengths of a pose ~1e19 across, against a
        # base ~1 across) becomes inf in the cast to the float32 products, then NaN in them (and one
        # an earlier step overflowed is inf or NaN already): a failure said here, once, rather than
        # NumPy's overflow and invalid-value warnings every iteration.
        with np.errstate(over="ignore", invalid="ignore"):
            y = self.dinv * r
            projected = f @ y.astype(f.dtype, copy=False)
            if not np.isfinite(projected).all():
                largest = float(np.max(np.abs(y)))  # NaN where an earlier step overflowed already
                where = f", up to {largest:.3g} where its products hold {float(np.finfo(f.dtype).max):.3g}," \
                    if np.isfinite(largest) else ""
                raise FloatingPointError(f"the low-rank system's right-hand side{where} overflowed")
            small = sla.cho_solve(self.chol, projected, check_finite=False)
            return y - self.dinv * (f.T @ small.astype(f.dtype, copy=False))


def gram_of_rows(a: np.ndarray) -> np.ndarray:
    """``a aᵀ`` by BLAS ``syrk`` (half the flops of a general product)."""
    # A C-ordered ``a`` is its transpose in Fortran order: syrk on that, without a copy.
    upper = sla.blas.dsyrk(1.0, a.T, trans=1) if a.flags.c_contiguous else sla.blas.dsyrk(1.0, np.asfortranarray(a))
    return np.triu(upper) + np.triu(upper, 1).T


class SplitGram:
    """``F D⁻¹ Fᵀ`` for every ``D = ε + ρ · counts`` from one pass over ``F``: the edges fall in
    a few classes of equal slot count (1 on the boundary, 2 inside), so ``F D⁻¹ Fᵀ =
    Σ_c F_c F_cᵀ / (ε + ρ c)``. The unconstrained solve (ρ = 0) and every ADMM penalty then
    share the O(p² E) product; a new ρ costs one p × p Cholesky factorization."""

    def __init__(self, f: np.ndarray, counts: np.ndarray):
        self.f, self.counts = f, counts
        self._single = None
        self.classes = [(float(c), counts == c) for c in np.unique(counts)]
        # One class (a closed mesh): no copy of F's columns.
        self.grams = [gram_of_rows(f if mask.all() else f[:, mask]) for _, mask in self.classes]

    def woodbury(self, eps: float, rho: float, *, single: bool = False) -> Woodbury:
        """The solver for ``D = ε + ρ · counts``; ``single``: its products with ``F`` in float32
        (:class:`Woodbury`; the capacitance matrix stays float64)."""
        capacitance = np.eye(self.f.shape[0])
        for (c, _), gram in zip(self.classes, self.grams):
            capacitance += gram / (eps + rho * c)
        return Woodbury(self.f, eps + rho * self.counts, capacitance, products=self.single() if single else None)

    def single(self) -> np.ndarray:
        """``F`` in float32 (made on first use, kept)."""
        if self._single is None:
            self._single = self.f.astype(np.float32)
        return self._single

