"""Recovery of areas and squared edge lengths from truncated shape differences (paper §7.1–7.2).

With ``k`` eigenfunctions ``Φ`` of a layer (the base M or its offset surface M_t) the two programs
are

- areas, eq. (8):  ``min ‖Φᵀ A(µ) Φ − D_A‖²_F + ε ‖µ − µ_M‖²``  s.t. ``µ ≥ 0``;
- squared lengths, eq. (10):  ``min ‖Φᵀ C(ℓ²; µ) Φ − diag(λ) D_C‖²_F + ε′ ‖ℓ² − ℓ²_M‖²``  s.t.
  ``ℓ² ≥ 0`` and, per triangle, ``E₃(T) ⪰ 0`` with ``det E₃(T) ≥ 4 µ(T)²`` (Props. 5–6).

Both data terms are consistent: the true metric of the target fits eq. (5) differences to
round-off and eq. (6) ones to the k_N truncation of the functional map (relative residuals
1.9e-4 for areas, 1.5e-3 for lengths on the 1,089-vertex cloth at k_M = 100, k_N = 200, against
1.6e-2 / 3.4e-2 for the base pose). What decides accuracy is ε:

**ε (measured, ``benchmarks/bench_truncated.py``).** ε is given relative to the data term's
curvature along the reference, ``σ_A = ‖Φᵀ A(µ_M) Φ‖²/‖µ_M‖²`` (= k) and ``σ_C = ‖Φᵀ C(ℓ²_M; µ)
Φ‖²/‖ℓ²_M‖²``, which makes it invariant under scaling of the mesh and of the basis. For eq. (6)
differences the data carry the k_N truncation, and a small ε fits it as if it were geometry: on
the cloth the area error is 2.5e-3 at ε = 1e-2 σ_A, 1.6e-2 at 1e-4 σ_A and 8.9e-2 at 1e-7 σ_A
(the base pose itself is at 1.5e-2). Hence a fixed ``AREA_EPSILON = 1e-2``. For lengths the
error is flat in ε′ (cloth: 1.97e-2 / 1.85e-2 / 1.75e-2 at 3e-3 / 1e-3 / 3e-4 σ_C; human
6.9e-2 / 6.8e-2 / 6.8e-2) but the reconstruction is not: Hausdorff/diagonal of the
intrinsic+extrinsic embedding on cloth drapes of 1, 2 and 3 rad/unit was 0.012 / 0.014 / 0.23 at
3e-3, 0.011 / 0.038 / 0.048 at 1e-3 and 0.009 / 0.016 / 0.033 at 3e-4, hence ``LENGTH_EPSILON =
3e-4``. There is no search that lowers ε until the viscosity term is "small": it drove ε to
~1e-8 and gave errors worse than the base pose. Eq. (5) differences are exact in the basis and
use the smaller :data:`EXACT_EPSILON` (= 1e-4), so that the result converges to the exact metric
as k grows to the full basis (µ 5e-5, ℓ² 2e-4 at k = n − 1 on a 10 × 10 sheet).

How the programs are solved:

1. **Areas: matrix-free conjugate gradients.** ``H µ = Φᵀ A(µ) Φ`` and its adjoint need only the
   mesh's sparsity pattern (``d_v = φ_vᵀ P φ_v``, ``o_e = φ_aᵀ P φ_b``), O(n k²) each; the
   regularized normal equations are solved by Jacobi-preconditioned CG (0.1–1 s for 2k–6k
   triangles, no m × m Gram). ``µ ≥ 0`` is checked afterwards; only if it is violated the
   bounded program is solved (scipy's L-BFGS-B in Jacobi-scaled variables, matrix-free).
2. **Lengths: low-rank data term.** With ``c = B_µ ℓ²`` the cotangent weights, the data term is
   ``‖H c − d‖²`` with Gram ``W = (U Uᵀ)∘²`` (``U`` the ``(E, k)`` edge differences of Φ) from
   ``⟨u uᵀ, v vᵀ⟩ = (u·v)²``; nothing of size k² × E or E × E is formed. W's spectrum falls fast
   (offset layer of the cloth, k = 100: λ_700/λ_1 = 1e-3, λ_1000/λ_1 = 1e-6, λ_1300/λ_1 = 5e-8), so
   a randomly pivoted Cholesky factor (block RPCholesky, columns ``(U U_Sᵀ)∘²`` on demand) to a
   residual trace of :data:`EDGE_GRAM_TOLERANCE` is computed once per layer and basis (cached;
   the "prep" of the benchmark) and orthonormalized through the eigenpairs of ``FᵀF``. Measured
   on the cloth's offset layer (9,148 edges): 0.9 s + 1.0 s, against 1.4 s to form W and 5.0 s for
   a rank-1,300 float64 Nyström sketch of it (same errors to three digits; float32 or rank 700
   gave errors above the base pose's). Eigenpairs are kept when ``λ ‖B_µ‖² > LOWRANK_TOLERANCE ·
   ε′`` (W lives in cotangent-weight space, ε′ in squared-length space).
3. **Constraints only where needed.** The unconstrained optimum is one Woodbury solve; if every
   triangle satisfies its constraint it is returned. Otherwise (the usual case — on the cloth
   about half the triangles violate ``det E₃ ≥ 4µ²``) ADMM with per-triangle slot copies: exact
   x-updates ``(FᵀF + D) x = r`` by Woodbury with a ``p × p`` Cholesky factor, z-updates by the
   closed-form projection onto ``{x_T : s ≥ √(16µ² + 2‖t‖²)}`` (the squared lengths of a
   triangle of area ≥ µ in coordinates where the rotated second-order cone of the paper is
   rotationally symmetric), Anderson-accelerated, ρ rebalanced on the residuals. 150–450
   iterations, 0.6–3.7 s.
   CLARABEL through cvxpy solves the same program (``tests/core/test_convex_recovery.py``
   checks agreement on a small mesh) but took 470 s for the 3,136-edge cloth layer with an
   exact factor (dense ``p × E`` block in its KKT system) — hence the hand-written solver.
4. **Feasible output.** The returned lengths satisfy every constraint (triangle inequality
   strictly; ``det E₃ ≥ 4µ²`` up to :data:`CONSTRAINT_TOLERANCE` relative), or
   :class:`RecoveryError` is raised; an iteration cap or floored areas give a
   :class:`ShapeDifferenceWarning`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .errors import RecoveryError, ShapeDifferenceWarning

#: ε of eq. (8) relative to σ_A = ‖Φᵀ A(µ_M) Φ‖²/‖µ_M‖² (see TruncatedRecovery.area_scale).
AREA_EPSILON = 1e-2
#: ε′ of eq. (10) relative to σ_C = ‖Φᵀ C(ℓ²_M; µ) Φ‖²/‖ℓ²_M‖² (TruncatedRecovery.edge_scale).
LENGTH_EPSILON = 3e-4
#: ε and ε′ (same units) for eq. (5) differences, which are exact in the basis. Measured: on the
#: 10 × 10 sheet at k = n − 1 errors µ 5e-5, ℓ² 2e-4 (1e-4) vs 5e-6, 3e-5 (1e-5); on the cloth at
#: k = 100, ℓ² 1.5e-2 in 7 s (1e-4) vs 1.7e-2 in 19 s (1e-5: slower CG and ADMM, no gain).
EXACT_EPSILON = 1e-4
#: Conjugate gradients (area program): relative residual and iteration cap. Offset layer of the
#: cloth: 1e-10 / 1e-8 / 1e-6 take 155 / 99 / 39 iterations, area error 2.3856e-2 / 2.3856e-2 / 2.3859e-2.
CG_TOLERANCE = 1e-6
CG_MAX_ITERATIONS = 2000
#: Iteration cap of the bounded area program (L-BFGS-B), used only when CG gives negative areas.
BOUNDED_MAX_ITERATIONS = 2000
#: The edge Gram's pivoted Cholesky factor stops when the trace of its residual is below this
#: fraction of the trace. Measured on the cloth (k = 100): 1e-5 / 1e-6 / 1e-7 / 1e-8 give offset
#: ranks ~1,200 / 1,383 / 1,634 / 1,886 and base ranks up to 2,010; the errors are the same to
#: three digits (ℓ² 1.73e-2 / 3.05e-2, Hausdorff 1.2 %) from 3e-6 down, 1e-5 raised the base ℓ²
#: error to 1.77e-2.
EDGE_GRAM_TOLERANCE = 3e-6
#: Keep eigenvalues λ of the edge Gram with λ‖B_µ‖² above this fraction of ε′ (measured on the
#: cloth: 1e-2 and 1 give the same errors, 100 raises the base ℓ² error from 1.73e-2 to 1.83e-2).
LOWRANK_TOLERANCE = 1.0
#: Recovered areas below this fraction of the reference area are raised to it (with a
#: ShapeDifferenceWarning): eq. (10) divides by µ, and µ ≥ 0 can be active when truncated.
AREA_FLOOR = 0.05
#: Relative tolerance on det E₃ ≥ 4µ² of the returned squared lengths.
CONSTRAINT_TOLERANCE = 1e-6
#: ADMM stopping tolerance (relative primal and fixed-point residuals) and iteration cap. 1e-5
#: changes the recovered lengths by ~1e-3 relative to their error against 1e-6 and saves ~40 %.
ADMM_TOLERANCE = 1e-5
ADMM_MAX_ITERATIONS = 3000
#: ADMM also stops when its relative residual, already below ADMM_STALL_FACTOR × the tolerance,
#: fell by less than 10 % over the last ADMM_STALL_WINDOW iterations, or so slowly that at that
#: rate the tolerance would not be reached within the iteration cap. Measured on offset layers of
#: Blender cloth: a drape (frames 40 → 48) at 1.1e-4 after 250 iterations, 6.3e-5 after 1,000,
#: 4.7e-5 after 3,000 (38 s) whatever ρ; a flag in wind (40 → 48) shrinking ~1/iterations, from
#: 5.8e-4 at 250 to 5.7e-5 at 3,000 (35 s; now stopped at 750, 9.6 s). Converging cases reach
#: 1e-5 in 150–460 iterations. The slack is far below what decides accuracy: the true lengths fit
#: the truncated data 3× (synthetic cloth) to 750× (drape) worse than the optimum does, and the
#: Hausdorff errors on 16 Blender scene pairs moved by at most 0.4 points.
ADMM_STALL_FACTOR = 30.0
ADMM_STALL_WINDOW = 250
#: ADMM penalty ρ in units of √(ε · mean diagonal of the data term's Gram), rebalanced every
#: ADMM_ADAPT_EVERY iterations (a p × p refactorization each), at most ADMM_MAX_ADAPTATIONS
#: times. Measured iterations at tolerance 1e-5 (cloth base / cloth offset / human offset):
#: ×10 fixed 130 / 140 / 445; ×30 fixed — / — / 315; ×10 with (100, 2) 155 / 155 / ~400;
#: more frequent rebalancing (25, 10) 430 / 275 / — — the rule is not monotone, so it is mild.
ADMM_RHO_SCALE = 10.0
ADMM_ADAPT_EVERY = 100
ADMM_MAX_ADAPTATIONS = 2


# ---------------------------------------------------------------------------------------------
# Public hook (called by SurfaceLayer.recover)
# ---------------------------------------------------------------------------------------------
def recover_truncated_metric(layer, area_difference, conformal_difference):
    """Areas and squared lengths of the target of one layer from its truncated differences."""
    from .reference_shape import LayerMetric

    solver = layer_solver(layer, area_difference.basis)
    # Eq. (5) differences are exact in the basis (the true metric fits them to round-off), so
    # they take the small ε of EXACT_EPSILON; eq. (6) ones carry the k_N truncation of the
    # functional map, which a small ε would fit as if it were geometry (measured: area error
    # 2.5e-3 at ε = 1e-2 σ_A but 8.9e-2 at 1e-7 σ_A on the 1,089-vertex cloth).
    exact = getattr(area_difference, "target_size", None) is None
    areas = solver.areas(area_difference.product_matrix(), epsilon=EXACT_EPSILON if exact else AREA_EPSILON)
    squared = solver.squared_lengths(
        conformal_difference.product_matrix(), areas, epsilon=EXACT_EPSILON if exact else LENGTH_EPSILON
    )
    return LayerMetric(areas, squared)


def layer_solver(layer, basis) -> "TruncatedRecovery":
    """The (cached) :class:`TruncatedRecovery` of ``layer`` for ``basis``: everything that
    depends only on the reference layer and the basis is computed once per layer and k."""
    cache = layer.__dict__.setdefault("_truncated_recovery", {})
    solver = cache.get(basis.size)
    if solver is None or not (
        solver.basis is basis or np.array_equal(solver.basis.functions, basis.functions)
    ):
        solver = TruncatedRecovery(layer, basis)
        cache[basis.size] = solver
    return solver


# ---------------------------------------------------------------------------------------------
# Low-rank factorization of explicit PSD Gram matrices
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LowRankGram:
    """``G ≈ Y diag(values) Yᵀ`` with ``Y`` ``(N, p)`` orthonormal; ``mean_diagonal`` of the exact G."""

    vectors: np.ndarray
    values: np.ndarray
    mean_diagonal: float


def randomly_pivoted_cholesky(columns, diagonal: np.ndarray, *, tolerance: float, max_rank: int,
                              block: int = 128, seed: int = 0) -> np.ndarray:
    """Block randomly pivoted Cholesky (Chen, Epperly, Tropp, Webber 2023) of a PSD matrix ``G``
    ``(N, N)`` given only its ``diagonal`` and ``columns(S)`` ``(N, |S|)``: ``G ≈ F Fᵀ`` with
    ``F`` ``(N, r)``, stopped when the trace of the residual falls below ``tolerance`` × trace(G)
    or ``r`` reaches ``max_rank``. Pivots are drawn in blocks with probability proportional to
    the residual diagonal; each block's own Cholesky is LAPACK's pivoted one (``dpstrf``), which
    drops pivots made redundant by the others in the block. Cost O(N r² + r·cost(column)),
    nothing of size N × N is formed."""
    from scipy.linalg import lapack

    n = diagonal.size
    rng = np.random.default_rng(seed)
    rows = np.empty((min(max_rank, n), n))  # Fᵀ, filled row by row: its leading rows stay contiguous
    residual = np.array(diagonal, dtype=np.float64)
    stop = tolerance * float(residual.sum())
    rank = 0
    while rank < rows.shape[0] and residual.sum() > stop:
        weights = np.maximum(residual, 0.0)
        picks = np.unique(rng.choice(n, size=min(block, rows.shape[0] - rank), p=weights / weights.sum()))
        cols = columns(picks)
        if rank:
            cols -= rows[:rank].T @ rows[:rank, picks]
        pivot_block = cols[picks]
        chol, order, found, _ = lapack.dpstrf(
            0.5 * (pivot_block + pivot_block.T), lower=1, tol=1e-12 * max(float(pivot_block.diagonal().max()), 1e-300)
        )
        if found == 0:
            break
        order = order[:found] - 1
        new = sla.solve_triangular(np.tril(chol[:found, :found]), cols[:, order].T, lower=True, check_finite=False)
        rows[rank : rank + found] = new
        rank += found
        residual -= np.einsum("ij,ij->j", new, new)
    return rows[:rank].T


def low_rank_gram(factor: np.ndarray, mean_diagonal: float) -> LowRankGram:
    """``F Fᵀ = Y diag(values) Yᵀ`` with orthonormal ``Y`` from the eigenpairs of ``FᵀF``
    (r × r; a QR of F cost 4× more, measured on 9,148 × 1,886)."""
    values, small = np.linalg.eigh(_gram_of_rows(factor.T))
    keep = values > values[-1] * np.finfo(float).eps * factor.shape[1]
    order = np.argsort(values[keep])[::-1]
    values, small = values[keep][order], small[:, keep][:, order]
    return LowRankGram((factor @ small) / np.sqrt(values), values, mean_diagonal)


# ---------------------------------------------------------------------------------------------
# Per-triangle constraint set and its projection
# ---------------------------------------------------------------------------------------------
_AXIS = np.full(3, 1.0 / np.sqrt(3.0))


def heron(x: np.ndarray) -> np.ndarray:
    """``q = 2(ab+bc+ca) − a² − b² − c²`` = 16·area² for squared lengths ``x`` ``(m, 3)``
    (= 4 det E₃)."""
    a, b, c = x[:, 0], x[:, 1], x[:, 2]
    return 2.0 * (a * b + b * c + c * a) - a * a - b * b - c * c


def project_triangles(x: np.ndarray, areas: np.ndarray) -> np.ndarray:
    """Euclidean projection of each row of ``x`` ``(m, 3)`` onto the convex set of squared
    lengths of a triangle with area ≥ ``areas`` ``(m,)``: ``s ≥ √(16µ² + 2‖t‖²)`` where ``s`` is the
    coordinate along (1,1,1)/√3 and ``t`` the orthogonal part (Props. 5–6; for µ = 0 the
    triangle-inequality cone). Vectorized bisection on the KKT condition (unique root)."""
    s0 = x @ _AXIS
    t0 = x - s0[:, None] * _AXIS
    r0 = np.linalg.norm(t0, axis=1)
    c = 16.0 * areas * areas
    bad = s0 < np.sqrt(c + 2.0 * r0 * r0)
    if not bad.any():
        return x.copy()
    s0b, r0b, cb = s0[bad], r0[bad], c[bad]
    # Boundary point (ρ, s): s² = c + 2ρ², ρ = ρ0 s / (3s − 2s0); χ(s) increasing on [lo, hi].
    lo = np.maximum(np.sqrt(cb), s0b)
    hi = np.maximum(np.sqrt(cb + 2.0 * r0b * r0b), lo)
    lo = np.maximum(lo, 1e-300)
    # Safeguarded Newton on ψ(s) = (s² − c)(3s − 2s0)² − 2ρ0² s² (same sign as χ on the bracket).
    # Start from the projection onto the tangent plane of the boundary (one Gauss–Newton step on
    # s² − 2ρ² = c from (ρ0, s0)), clipped to the bracket: near-boundary points — all of them
    # once ADMM settles — then need 2–3 Newton steps instead of ~10 from the bracket's end.
    phi0 = s0b * s0b - 2.0 * r0b * r0b - cb
    grad2 = 16.0 * r0b * r0b + 4.0 * s0b * s0b
    with np.errstate(divide="ignore", invalid="ignore"):
        start = s0b - 2.0 * s0b * phi0 / grad2
    s = np.where(np.isfinite(start), np.clip(start, lo, hi), hi)
    todo = np.arange(s.size)  # rows whose Newton iteration has not settled yet
    for _ in range(60):
        sb, s0t, ct, rt, lot, hit = s[todo], s0b[todo], cb[todo], r0b[todo], lo[todo], hi[todo]
        a = 3.0 * sb - 2.0 * s0t
        psi = (sb * sb - ct) * a * a - 2.0 * rt * rt * sb * sb
        up = psi > 0
        hit = np.where(up, sb, hit)
        lot = np.where(up, lot, sb)
        dpsi = 2.0 * sb * a * a + 6.0 * (sb * sb - ct) * a - 4.0 * rt * rt * sb
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = sb - psi / dpsi
        # Inclusive: a converged Newton step lands on the end the bracket just moved to.
        inside = np.isfinite(newton) & (newton >= lot) & (newton <= hit)
        s_new = np.where(inside, newton, 0.5 * (lot + hit))
        s[todo], lo[todo], hi[todo] = s_new, lot, hit
        moving = np.abs(s_new - sb) > 1e-13 * np.maximum(np.abs(sb), 1e-300)
        todo = todo[moving]
        if todo.size == 0:
            break
    hi = np.maximum(s, lo)
    s = hi  # on the feasible side
    rho = np.sqrt(np.maximum(s * s - cb, 0.0) / 2.0)
    rho = np.minimum(rho, r0b)
    out = x.copy()
    scale = np.divide(rho, r0b, out=np.zeros_like(rho), where=r0b > 0)
    out[bad] = s[:, None] * _AXIS + scale[:, None] * t0[bad]
    return out


# ---------------------------------------------------------------------------------------------
# ADMM for  min ½‖F x − g‖² + ½ε‖x − x0‖²  s.t.  x[slots] ∈ C
# ---------------------------------------------------------------------------------------------
class _Woodbury:
    """Solves ``(FᵀF + diag(d)) x = r`` with a ``p × p`` Cholesky factor of ``I + F D⁻¹ Fᵀ``
    (``capacitance``: that matrix when already known)."""

    def __init__(self, f: np.ndarray, d: np.ndarray, capacitance: np.ndarray | None = None):
        self.f, self.dinv = f, 1.0 / d
        if capacitance is None:
            capacitance = f @ (self.dinv[:, None] * f.T)
            capacitance[np.diag_indices_from(capacitance)] += 1.0
        self.chol = sla.cho_factor(capacitance, lower=True)

    def solve(self, r: np.ndarray) -> np.ndarray:
        y = self.dinv * r
        return y - self.dinv * (self.f.T @ sla.cho_solve(self.chol, self.f @ y, check_finite=False))


def _gram_of_rows(a: np.ndarray) -> np.ndarray:
    """``a aᵀ`` by BLAS ``syrk`` (half the flops of a general product)."""
    upper = sla.blas.dsyrk(1.0, np.asfortranarray(a))
    return np.triu(upper) + np.triu(upper, 1).T


class _SplitGram:
    """``F D⁻¹ Fᵀ`` for every ``D = ε + ρ · counts`` from one pass over ``F``: the edges fall in
    a few classes of equal slot count (1 on the boundary, 2 inside), so ``F D⁻¹ Fᵀ =
    Σ_c F_c F_cᵀ / (ε + ρ c)``. The unconstrained solve (ρ = 0) and every ADMM penalty then
    share the O(p² E) product; a new ρ costs one p × p Cholesky factorization."""

    def __init__(self, f: np.ndarray, counts: np.ndarray):
        self.f, self.counts = f, counts
        self.classes = [(float(c), counts == c) for c in np.unique(counts)]
        self.grams = [_gram_of_rows(f[:, mask]) for _, mask in self.classes]

    def woodbury(self, eps: float, rho: float) -> _Woodbury:
        capacitance = np.eye(self.f.shape[0])
        for (c, _), gram in zip(self.classes, self.grams):
            capacitance += gram / (eps + rho * c)
        return _Woodbury(self.f, eps + rho * self.counts, capacitance)


@dataclass
class _Solution:
    x: np.ndarray
    iterations: int
    converged: bool


def _admm(f, g, eps, x0, slots, counts, project, *, x_start=None, z_start=None, u_start=None,
          rho=None, tol=None, max_iter=None, memory=8, split=None):
    """Scaled-form ADMM with slot copies ``z = x[slots]`` (``project`` maps a slot vector onto the
    constraint set), accelerated by safeguarded type-II Anderson acceleration on the
    Douglas–Rachford variable ``v = z − u`` (the x-update depends on the state only through it).
    Returns the solution and ``(z, u, rho)`` for warm starts."""
    n = x0.size
    tol = ADMM_TOLERANCE if tol is None else tol
    max_iter = ADMM_MAX_ITERATIONS if max_iter is None else max_iter
    b = f.T @ g + eps * x0
    if rho is None:
        rho = ADMM_RHO_SCALE * np.sqrt(eps * max(float(np.sum(f * f)) / n, eps))
    x = x0.copy() if x_start is None else x_start.copy()
    z = project(x[slots]) if z_start is None else z_start.copy()
    u = np.zeros(slots.size) if u_start is None else u_start.copy()
    split = _SplitGram(f, counts) if split is None else split
    solver = split.woodbury(eps, rho)

    def step(v):
        x = solver.solve(b + rho * np.bincount(slots, v, minlength=n))
        xs = x[slots]
        # v = z − u; the z-update reads Sx + u = Sx + (z − v) — keep z, u implicit through
        # the reflected form: with w = 2 Sx − v, z = Π(w), u = Sx − v ... (standard DR).
        w = 2.0 * xs - v
        z = project(w)
        return v + z - xs, x, xs, z

    v = z - u
    hist_v, hist_r = [], []
    converged = False
    it = 0
    prev_res = np.inf
    checkpoint = np.inf
    adaptations = 0
    for it in range(1, max_iter + 1):
        z_prev = z
        tv, x, xs, z = step(v)
        r = tv - v
        res = np.linalg.norm(r)
        # Anderson (type II) on the fixed point v = T(v).
        hist_v.append(tv)
        hist_r.append(r)
        if len(hist_v) > memory + 1:
            hist_v.pop(0)
            hist_r.pop(0)
        v_next = tv
        if len(hist_r) >= 3 and res < 10 * prev_res:
            dr = np.diff(np.array(hist_r), axis=0)
            dv = np.diff(np.array(hist_v), axis=0)
            try:
                gamma = np.linalg.lstsq(dr.T, r, rcond=1e-10)[0]
                cand = tv - dv.T @ gamma
                if np.all(np.isfinite(cand)):
                    v_next = cand
            except np.linalg.LinAlgError:
                pass
        prev_res = min(prev_res, res)
        if it % 5 == 0:
            primal = np.linalg.norm(xs - z)
            scale = max(np.linalg.norm(xs), np.linalg.norm(z), 1e-300)
            if primal <= tol * scale and res <= tol * scale:
                converged = True
                break
            if it % ADMM_STALL_WINDOW == 0:
                # Stalled near the tolerance: stop (the caller warns that it was not reached).
                current = max(primal, res) / scale
                if current <= ADMM_STALL_FACTOR * tol:
                    # At this window's rate, would the tolerance be reached within the cap?
                    rate = current / checkpoint
                    windows_left = (max_iter - it) / ADMM_STALL_WINDOW
                    if rate > 0.9 or rate ** windows_left > tol / current:
                        break
                checkpoint = current
        if it % ADMM_ADAPT_EVERY == 0 and adaptations < ADMM_MAX_ADAPTATIONS:
            # Residual balancing (OSQP's rule on relative residuals): ρ ← ρ √(r_primal / r_dual),
            # the scaled dual u rescaled with it, Anderson's history restarted.
            u_now = z - v_next
            primal = np.linalg.norm(xs - z) / max(np.linalg.norm(xs), np.linalg.norm(z), 1e-300)
            dual = np.linalg.norm(z - z_prev) / max(np.linalg.norm(u_now), 1e-300)
            ratio = primal / max(dual, 1e-300)
            if not 0.2 <= ratio <= 5.0:
                factor = float(np.clip(np.sqrt(ratio), 0.1, 10.0))
                u_now /= factor
                rho *= factor
                solver = split.woodbury(eps, rho)
                v_next = z - u_now
                hist_v, hist_r, prev_res = [], [], np.inf
                adaptations += 1
        v = v_next
    u = z - v
    return _Solution(x, it, converged), (z, u, rho)


def _check_product(product, k, what):
    product = np.asarray(product)
    if product.shape != (k, k):
        raise RecoveryError(f"The {what} is {product.shape}, but the basis has k = {k} functions: expected ({k}, {k}).")
    if not np.all(np.isfinite(product)):
        first = np.argwhere(~np.isfinite(product))[0]
        raise RecoveryError(
            f"The {what} has a non-finite entry at {tuple(int(i) for i in first)}; "
            "recompute the shape difference."
        )


# ---------------------------------------------------------------------------------------------
# The per-layer solver
# ---------------------------------------------------------------------------------------------
class TruncatedRecovery:
    """Programs (8) and (10) for one layer and one truncated basis. Construction does all the
    target-independent work; :meth:`edge_gram` (the low-rank factor of the edge program, computed
    on first use and cached) is the only expensive part. :meth:`areas` and :meth:`squared_lengths`
    solve for one target each.

    The data terms are applied matrix-free through the mesh's sparsity pattern: for a symmetric
    ``k × k`` matrix ``M`` only ``d_v = φ_vᵀ M φ_v`` (per vertex) and ``o_e = φ_aᵀ M φ_b`` (per edge
    ``(a, b)``) are needed, so ``Hᵀ M`` costs ``O(n k²)`` and ``H x = Φᵀ X Φ`` (``X`` sparse) as much.
    """

    def __init__(self, layer, basis):
        self.layer = layer
        self.basis = basis
        topo = layer.topology
        self.topology = topo
        phi = np.ascontiguousarray(basis.functions, dtype=np.float64)
        self.phi = phi
        k = phi.shape[1]
        self.k = k
        self.U = phi[topo.edges[:, 0]] - phi[topo.edges[:, 1]]
        self._edge_gram = None
        self._area_diagonal = None
        self.last_area_info: dict = {}
        self.last_edge_info: dict = {}

    # -- matrix-free pieces ---------------------------------------------------------------------
    def reduce(self, matrix) -> np.ndarray:
        """``Φᵀ X Φ`` ``(k, k)`` for a sparse ``(n, n)`` matrix ``X``."""
        return self.phi.T @ np.asarray(matrix @ self.phi)

    def _pattern_values(self, product: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``d_v = φ_vᵀ P φ_v`` ``(n,)`` and ``o_e = φ_aᵀ P φ_b`` ``(E,)`` of the symmetric part of P."""
        p = 0.5 * (product + product.T)
        phi_p = self.phi @ p
        edges = self.topology.edges
        diagonal = np.einsum("ij,ij->i", phi_p, self.phi)
        off = np.einsum("ij,ij->i", phi_p[edges[:, 0]], self.phi[edges[:, 1]])
        return diagonal, off

    # -- areas, eq. (8) -------------------------------------------------------------------------
    def area_data(self, product: np.ndarray) -> np.ndarray:
        """``Hᵀ P`` for the area map ``H µ = Φᵀ A(µ) Φ``: ⟨Φᵀ G_T Φ, P⟩ per triangle ``(m,)`` where
        ``A(µ) = Σ_T µ_T G_T`` (diagonal 1/6, off-diagonal 1/12)."""
        diagonal, off = self._pattern_values(product)
        topo = self.topology
        return (diagonal[topo.triangles].sum(axis=1) + off[topo.triangle_edges].sum(axis=1)) / 6.0

    def area_operator(self, areas: np.ndarray) -> np.ndarray:
        """``H µ = Φᵀ A(µ) Φ`` ``(k, k)``."""
        return self.reduce(self.layer.assembler.mass_matrix(areas))

    def area_gram_diagonal(self) -> np.ndarray:
        """Diagonal of ``HᵀH`` ``(m,)``: ‖Φᵀ G_T Φ‖²_F from the 3 × 3 Gram of the rows of Φ at T."""
        if self._area_diagonal is None:
            rows = self.phi[self.topology.triangles]  # (m, 3, k)
            g = np.einsum("tik,tjk->tij", rows, rows)
            a = g.sum(axis=2)  # a_T · φ_v
            total = g.sum(axis=(1, 2))  # a_T · a_T
            self._area_diagonal = (total**2 + 2.0 * np.sum(a * a, axis=1) + np.sum(g * g, axis=(1, 2))) / 144.0
        return self._area_diagonal

    def area_gram(self):
        """Target-independent preparation of the area program (the diagonal preconditioner;
        nothing of size m × m is formed)."""
        return self.area_gram_diagonal()

    def area_scale(self) -> float:
        """σ_A = ‖H µ_M‖² / ‖µ_M‖²: the data term's curvature along the reference areas (= k for
        an A_M-orthonormal basis). ε is measured in this unit, which makes it invariant under
        scaling of the mesh and of the basis."""
        reference = self.layer.areas
        return float(np.sum(self.area_operator(reference) ** 2) / np.sum(reference**2))

    def areas(self, product: np.ndarray, *, epsilon: float | None = None, floor: bool = True) -> np.ndarray:
        """Eq. (8): ``min ‖Φᵀ A(µ) Φ − P‖²_F + ε‖µ − µ_M‖²`` s.t. ``µ ≥ 0`` (``epsilon`` relative to
        :meth:`area_scale`; default :data:`AREA_EPSILON`). With ``floor`` (default), areas below
        :data:`AREA_FLOOR` × the reference are raised to it with a warning (eq. 10 divides by µ);
        ``floor=False`` returns the optimum of eq. (8) itself."""
        from scipy.sparse.linalg import LinearOperator, cg

        _check_product(product, self.k, f"area difference of the {self.layer.name}")
        reference = self.layer.areas
        m = reference.size
        eps = (AREA_EPSILON if epsilon is None else epsilon) * self.area_scale()
        data = self.area_data(product)
        normal = LinearOperator(
            (m, m), matvec=lambda x: self.area_data(self.area_operator(np.ravel(x))) + eps * np.ravel(x), dtype=float
        )
        diag = self.area_gram_diagonal() + eps
        precond = LinearOperator((m, m), matvec=lambda x: np.ravel(x) / diag, dtype=float)
        rhs = data + eps * reference
        mu, info = cg(normal, rhs, x0=reference.copy(), rtol=CG_TOLERANCE, maxiter=CG_MAX_ITERATIONS, M=precond)
        method = "cg"
        if info < 0 or not np.all(np.isfinite(mu)):
            raise RecoveryError(
                f"The area program of the {self.layer.name} failed (conjugate gradients, status "
                f"{info}); the truncated shape difference may be corrupt."
            )
        if info > 0:
            residual = np.linalg.norm(normal.matvec(mu) - rhs) / max(np.linalg.norm(rhs), 1e-300)
            warnings.warn(
                f"The area program of the {self.layer.name} stopped after {info} conjugate-gradient "
                f"iterations at relative residual {residual:.1e} (tolerance {CG_TOLERANCE:g}); the "
                "areas are the last iterate.",
                ShapeDifferenceWarning,
                stacklevel=3,
            )
        if mu.min() < 0.0:
            mu = self._bounded_areas(normal.matvec, rhs, eps, mu)
            method = "bounded"
        self.last_area_epsilon = eps
        self.last_area_info = {"epsilon": eps, "method": method}
        lowest = AREA_FLOOR * reference
        low = (mu < lowest) if floor else np.zeros(m, dtype=bool)
        if low.any():
            warnings.warn(
                f"{int(low.sum())} recovered triangle areas of the {self.layer.name} were below "
                f"{AREA_FLOOR:g} × their reference area (first: triangle {int(np.flatnonzero(low)[0])}) "
                "and were raised to it so that edge lengths can be recovered; a larger k helps.",
                ShapeDifferenceWarning,
                stacklevel=3,
            )
            mu = np.maximum(mu, lowest)
        return mu

    def _bounded_areas(self, normal_matvec, rhs, eps, start):
        """``µ ≥ 0`` active: the quadratic of the CG solve (its normal operator ``normal_matvec`` and
        right-hand side ``rhs``) by scipy's L-BFGS-B with the bounds, in Jacobi-scaled variables
        ``y = √diag · µ`` (the bound stays ``y ≥ 0``), started from the clipped CG optimum.
        Measured on an offset layer with 5,642 triangles where CG gave negative areas (a Blender
        drape, frames 40 → 48): 1.4 s, against 170 s for scipy's bounded least squares
        (``lsq_linear``, trust-region reflective with LSMR)."""
        from scipy.optimize import minimize

        reference = self.layer.areas
        scale = np.sqrt(self.area_gram_diagonal() + eps)

        def objective(y):
            mu = y / scale
            normal = normal_matvec(mu)
            return 0.5 * float(mu @ normal) - float(rhs @ mu), (normal - rhs) / scale

        gradient_tolerance = 1e-10 * float(np.abs(rhs / scale).max())
        result = minimize(objective, np.maximum(start, 0.0) * scale, jac=True, method="L-BFGS-B",
                          bounds=[(0.0, None)] * reference.size,
                          options={"maxiter": BOUNDED_MAX_ITERATIONS, "ftol": 0.0, "gtol": gradient_tolerance})
        if not np.all(np.isfinite(result.x)):
            raise RecoveryError(f"The bounded area program of the {self.layer.name} failed ({result.message}).")
        if not result.success:
            warnings.warn(
                f"The bounded area program of the {self.layer.name} stopped before convergence "
                f"({result.message}); the areas are its last iterate.",
                ShapeDifferenceWarning,
                stacklevel=4,
            )
        return np.maximum(result.x / scale, 0.0)

    # -- squared lengths, eq. (10) --------------------------------------------------------------
    def edge_data(self, product: np.ndarray) -> np.ndarray:
        """``Hᵀ P`` for ``H c = Φᵀ C Φ = −Σ_e c_e u_e u_eᵀ``: ``−u_eᵀ P u_e`` per edge ``(E,)``."""
        diagonal, off = self._pattern_values(product)
        edges = self.topology.edges
        return -(diagonal[edges[:, 0]] + diagonal[edges[:, 1]] - 2.0 * off)

    def edge_gram(self) -> LowRankGram:
        """Low-rank factor of ``W = HᵀH = (U Uᵀ)∘²`` (edges × edges; depends on the layer and the
        basis only, cached)."""
        if self._edge_gram is None:
            u = self.U
            diagonal = np.einsum("ij,ij->i", u, u) ** 2
            factor = randomly_pivoted_cholesky(
                lambda picks: np.square(u @ u[picks].T), diagonal, tolerance=EDGE_GRAM_TOLERANCE, max_rank=u.shape[0]
            )
            self._edge_gram = low_rank_gram(factor, float(diagonal.mean()))
        return self._edge_gram

    def edge_scale(self, length_map) -> float:
        """σ_C = ‖H B_µ ℓ²_M‖² / ‖ℓ²_M‖² (same role as :meth:`area_scale`), exact."""
        reference = self.layer.squared_lengths
        c = length_map @ reference
        lap = self.layer.assembler.from_entries(self.layer.assembler.laplacian_diagonal(c), c)
        return float(np.sum(self.reduce(lap) ** 2) / np.sum(reference**2))

    def squared_lengths(self, product: np.ndarray, areas: np.ndarray, *, epsilon: float | None = None) -> np.ndarray:
        """Eq. (10): ``min ‖Φᵀ C(ℓ²; µ) Φ − P‖²_F + ε′‖ℓ² − ℓ²_M‖²`` s.t. ``ℓ² ≥ 0``, triangle
        inequality, ``det E₃ ≥ 4µ²`` (``epsilon`` relative to :meth:`edge_scale`; default
        :data:`LENGTH_EPSILON`)."""
        topo = self.topology
        _check_product(product, self.k, f"conformal difference of the {self.layer.name}")
        if not (np.all(np.isfinite(areas)) and np.all(areas > 0)):
            bad = int(np.flatnonzero(~(areas > 0))[0])
            raise RecoveryError(
                f"The recovered area of triangle {bad} of the {self.layer.name} is {areas[bad]:.3g}: "
                "edge lengths need positive areas. The truncated shape difference does not describe "
                "a valid mesh (try a larger k)."
            )
        gram = self.edge_gram()
        length_map = self.layer.assembler.length_map(areas).tocsc()  # B_µ (E, E)
        reference = self.layer.squared_lengths
        eps = (LENGTH_EPSILON if epsilon is None else epsilon) * self.edge_scale(length_map)
        # W lives in cotangent-weight space, ε′ in squared-length space: a direction of W with
        # eigenvalue λ contributes at most λ‖B_µ‖² to the objective's curvature, so it is
        # negligible next to ε′ when λ‖B_µ‖² < LOWRANK_TOLERANCE × ε′ (‖B‖² ≤ ‖B‖₁‖B‖_∞).
        gain = float(abs(length_map).sum(axis=0).max() * abs(length_map).sum(axis=1).max())
        keep = gram.values * gain > LOWRANK_TOLERANCE * eps
        y, lam = gram.vectors[:, keep], gram.values[keep]
        f = np.sqrt(lam)[:, None] * np.asarray((length_map.T @ y).T)  # (p, E) = Λ^½ Yᵀ B_µ
        g = (y.T @ self.edge_data(product)) / np.sqrt(lam)
        slots = topo.triangle_edges.ravel()
        counts = np.bincount(slots, minlength=topo.n_edges).astype(float)
        # Unconstrained optimum first (one Woodbury solve); the cone constraints only if violated.
        split = _SplitGram(f, counts)
        x = split.woodbury(eps, 0.0).solve(f.T @ g + eps * reference)
        iterations, converged = 0, True
        if not self._satisfied(x[slots].reshape(-1, 3), areas).all():
            project = lambda v: project_triangles(v.reshape(-1, 3), areas).ravel()  # noqa: E731
            sol, state = _admm(f, g, eps, reference, slots, counts, project, x_start=x, split=split)
            iterations, converged = sol.iterations, sol.converged
            x = self._feasible(sol.x, state[0], slots, counts, areas)
        self.last_edge_epsilon = eps
        self.last_edge_iterations = iterations
        self.last_edge_problem = (f, g)
        self.last_edge_info = {"epsilon": eps, "rank": int(lam.size), "iterations": iterations}
        if not converged:
            warnings.warn(
                f"The edge-length program of the {self.layer.name} stopped after {iterations} "
                "iterations before reaching its tolerance; the returned lengths satisfy every "
                "constraint but may be less accurate.",
                ShapeDifferenceWarning,
                stacklevel=3,
            )
        return x

    def _feasible(self, x, z, slots, counts, areas):
        """Edge values satisfying every triangle constraint. Start from the average of the ADMM
        slot copies; while some triangle is invalid, project the slot copies of the violated
        triangles (with a tiny safety margin on the area) and average again (averaged
        projections, convergent to a point of the intersection); finally scale all squared
        lengths by the smallest γ ≥ 1 with q(γx_T) = γ² q(x_T) ≥ 16µ² everywhere (γ − 1 is of the
        order of the ADMM residual)."""
        n = counts.size
        x = np.bincount(slots, z, minlength=n) / counts
        margin = areas * (1.0 + CONSTRAINT_TOLERANCE)
        for _ in range(500):
            xt = x[slots].reshape(-1, 3)
            q = heron(xt)
            valid = (q > 0) & (xt > 0).all(axis=1)
            gamma2 = np.max(np.divide(16.0 * margin * margin, q, out=np.full_like(q, np.inf), where=valid))
            if valid.all() and gamma2 <= 1.0 + 1e-3:
                return x * np.sqrt(max(gamma2, 1.0))
            bad = ~valid | (16.0 * margin * margin > q * (1.0 + 1e-3))
            fixed = np.where(np.repeat(bad, 3), project_triangles(xt, margin).ravel(), xt.ravel())
            x = np.bincount(slots, fixed, minlength=n) / counts
        xt = x[slots].reshape(-1, 3)
        bad = np.flatnonzero(~self._satisfied(xt, areas))
        raise RecoveryError(
            f"The edge-length program of the {self.layer.name} did not reach a point satisfying "
            f"the triangle constraints (first violated triangle {bad[0]}, {bad.size} in all). "
            "The truncated differences may be inconsistent with the recovered areas; try a larger k."
        )

    @staticmethod
    def _satisfied(xt, areas):
        q = heron(xt)
        s = xt.sum(axis=1) / np.sqrt(3.0)
        return (s > 0) & (q >= 16.0 * areas * areas * (1.0 - CONSTRAINT_TOLERANCE)) & (q > 0) & (xt > 0).all(axis=1)
