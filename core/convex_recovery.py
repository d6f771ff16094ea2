"""Recovery of areas and squared edge lengths from truncated shape differences (paper §7.1–7.2).

With ``k`` eigenfunctions ``Φ`` of a layer (the base M or its offset surface M_t) the two programs
are

- areas, eq. (8):  ``min ‖Φᵀ A(µ) Φ − D_A‖²_F + ε ‖µ − µ_M‖²``  s.t. ``µ ≥ 0``;
- squared lengths, eq. (10):  ``min ‖Φᵀ C(ℓ²; µ) Φ − diag(λ) D_C‖²_F + ε′ ‖ℓ² − ℓ²_M‖²``  s.t.
  ``ℓ² ≥ 0`` and, per triangle, ``E₃(T) ⪰ 0`` with ``det E₃(T) ≥ 4 µ(T)²`` (Props. 5–6).

How they are solved (measurements in ``benchmarks/bench_truncated.py`` and the module notes below):

1. **Factored objective.** Both data terms are ``‖H c − d‖²`` for a linear map ``H`` into the
   symmetric ``k × k`` matrices whose Gram matrix has closed form: ``⟨u uᵀ, v vᵀ⟩ = (u·v)²``.
   For lengths, ``c = B_µ ℓ²`` are the per-edge cotangent weights and ``HᵀH = W = (U Uᵀ)∘²`` with
   ``U`` the ``(E, k)`` edge differences of ``Φ`` (depends on M only); for areas the ``(m, m)``
   Gram follows from ``Φ Φᵀ`` in the same way. Nothing of size ``k² × E`` is formed.
2. **Low rank.** These Grams have rapidly decaying spectra (on the 1,089-vertex cloth at
   k = 100 only ~1,300 of 9,148 eigenvalues exceed 1e-5 of the mean diagonal, for both layers):
   a Nyström factorization ``W ≈ Y Λ Yᵀ`` of rank ``p`` (computed once per layer and basis,
   cached on the layer) turns the data term into ``‖Λ^½ Yᵀ B_µ ℓ² − g‖²`` with ``p`` rows. The
   discarded directions carry less than :data:`LOWRANK_TOLERANCE` × ε each — below what the
   viscosity term already suppresses.
3. **ADMM with exact x-updates.** The constraints are per triangle (per slot copy of the edge
   variables), so the x-update is the regularised least-squares solve ``(FᵀF + D) x = r`` —
   Woodbury with a ``p × p`` Cholesky factor — and the z-update is the closed-form projection
   onto ``{x_T : s ≥ √(16µ² + 2‖t‖²)}`` (the set of three squared lengths of a triangle of area
   ≥ µ, in the orthonormal coordinates ``s`` along (1,1,1) and ``t`` across; ``q(x) = s² − 2‖t‖²``
   is Heron's ``16·area²``). This is the rotated second-order cone of the brief written in
   coordinates where it is rotationally symmetric, so its projection is a 1-D root find.
4. **Feasible output.** The returned lengths are repaired to satisfy every constraint exactly
   (triangle inequality strictly; ``det E₃ ≥ 4µ²`` up to :data:`CONSTRAINT_TOLERANCE`
   relative), or :class:`RecoveryError` is raised — never silent garbage.

ε: ``ε = EPSILON_RELATIVE × trace(Gram)/size`` — the mean diagonal of the data term's Gram, which
makes it invariant under scaling of the mesh and of the basis; after solving, the viscosity
term's share of the objective is measured and ε is lowered (warm start) until it is below
:data:`MAX_REGULARIZATION_SHARE` (10 %, paper §8.2), within :data:`MAX_EPSILON_HALVINGS` steps.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .errors import RecoveryError, ShapeDifferenceWarning

#: ε relative to the mean diagonal of the data term's Gram matrix (both programs).
EPSILON_RELATIVE = 1e-4
#: Lower ε until the viscosity term is at most this share of the optimal objective (§8.2).
MAX_REGULARIZATION_SHARE = 0.10
#: How many times ε may be divided by :data:`EPSILON_STEP` to meet the share.
MAX_EPSILON_HALVINGS = 4
EPSILON_STEP = 10.0
#: Keep Nyström eigenvalues above this fraction of the smallest ε used.
LOWRANK_TOLERANCE = 1e-2
#: Recovered areas below this fraction of the reference area are raised to it (with a
#: ShapeDifferenceWarning): eq. (10) divides by µ, and µ ≥ 0 can be active when truncated.
AREA_FLOOR = 0.05
#: Relative tolerance on det E₃ ≥ 4µ² of the returned squared lengths.
CONSTRAINT_TOLERANCE = 1e-6
#: ADMM stopping tolerance (relative primal and dual residuals) and iteration cap.
ADMM_TOLERANCE = 1e-6
ADMM_MAX_ITERATIONS = 3000


# ---------------------------------------------------------------------------------------------
# Public hook (called by SurfaceLayer.recover)
# ---------------------------------------------------------------------------------------------
def recover_truncated_metric(layer, area_difference, conformal_difference):
    """Areas and squared lengths of the target of one layer from its truncated differences."""
    from .reference_shape import LayerMetric

    solver = layer_solver(layer, area_difference.basis)
    areas = solver.areas(area_difference.product_matrix())
    squared = solver.squared_lengths(conformal_difference.product_matrix(), areas)
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


def nystrom(gram: np.ndarray, rank: int, *, floor: float, seed: int = 0) -> LowRankGram:
    """Randomized Nyström approximation of an explicit PSD matrix (Tropp et al. 2017, Alg. 3),
    eigenvalues below ``floor`` dropped. One pass over ``gram``; float32 products (the
    eigenvalues we keep are ≥ 1e-7 of the largest, far above float32 round-off of the sketch
    in relative terms after the float64 core solve). ``rank ≥ N`` uses a dense eigensolver."""
    n = gram.shape[0]
    mean_diag = float(np.trace(gram)) / n
    if rank >= 0.5 * n:
        values, vectors = np.linalg.eigh(gram)
    else:
        rng = np.random.default_rng(seed)
        omega = np.linalg.qr(rng.standard_normal((n, rank)))[0]
        sketch = gram @ omega
        shift = np.sqrt(n) * np.finfo(float).eps * max(np.linalg.norm(sketch, 2), 1e-300)
        sketch += shift * omega
        core = omega.T @ sketch
        core = 0.5 * (core + core.T)
        chol = np.linalg.cholesky(core)
        b = sla.solve_triangular(chol, sketch.T, lower=True).T  # (n, p)
        values, small = np.linalg.eigh(b.T @ b)
        values = np.maximum(values - shift, 0.0)
        # b = Y S Vᵀ  ⇒  Y = b V S⁻¹ on the kept part.
        keep = values > floor
        vectors = (b @ small[:, keep]) / np.sqrt(values[keep] + shift)
        values = values[keep]
        order = np.argsort(values)[::-1]
        return LowRankGram(vectors[:, order], values[order], mean_diag)
    keep = values > floor
    order = np.argsort(values[keep])[::-1]
    return LowRankGram(vectors[:, keep][:, order], values[keep][order], mean_diag)


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
    s = hi.copy()
    for _ in range(60):
        a = 3.0 * s - 2.0 * s0b
        psi = (s * s - cb) * a * a - 2.0 * r0b * r0b * s * s
        up = psi > 0
        hi = np.where(up, s, hi)
        lo = np.where(up, lo, s)
        dpsi = 2.0 * s * a * a + 6.0 * (s * s - cb) * a - 4.0 * r0b * r0b * s
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = s - psi / dpsi
        inside = np.isfinite(newton) & (newton > lo) & (newton < hi)
        s_new = np.where(inside, newton, 0.5 * (lo + hi))
        if np.all(np.abs(s_new - s) <= 1e-14 * np.maximum(np.abs(s), 1e-300)):
            s = s_new
            break
        s = s_new
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
    """Solves ``(FᵀF + diag(d)) x = r`` with a ``p × p`` Cholesky factor."""

    def __init__(self, f: np.ndarray, d: np.ndarray):
        self.f, self.dinv = f, 1.0 / d
        cap = f @ (self.dinv[:, None] * f.T)
        cap[np.diag_indices_from(cap)] += 1.0
        self.chol = sla.cho_factor(cap, lower=True)

    def solve(self, r: np.ndarray) -> np.ndarray:
        y = self.dinv * r
        return y - self.dinv * (self.f.T @ sla.cho_solve(self.chol, self.f @ y))


@dataclass
class _Solution:
    x: np.ndarray
    iterations: int
    converged: bool


def _admm(f, g, eps, x0, slots, counts, project, *, x_start=None, z_start=None, u_start=None,
          rho=None, tol=ADMM_TOLERANCE, max_iter=ADMM_MAX_ITERATIONS, memory=8):
    """Scaled-form ADMM with slot copies ``z = x[slots]`` (``project`` maps a slot vector onto the
    constraint set), accelerated by safeguarded type-II Anderson acceleration on the
    Douglas–Rachford variable ``v = z − u`` (the x-update depends on the state only through it).
    Returns the solution and ``(z, u, rho)`` for warm starts."""
    n = x0.size
    b = f.T @ g + eps * x0
    if rho is None:
        rho = np.sqrt(eps * max(float(np.sum(f * f)) / n, eps))
    x = x0.copy() if x_start is None else x_start.copy()
    z = project(x[slots]) if z_start is None else z_start.copy()
    u = np.zeros(slots.size) if u_start is None else u_start.copy()
    solver = _Woodbury(f, eps + rho * counts)

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
    for it in range(1, max_iter + 1):
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
        v = v_next
    u = z - v
    return _Solution(x, it, converged), (z, u, rho)


# ---------------------------------------------------------------------------------------------
# The per-layer solver
# ---------------------------------------------------------------------------------------------
class TruncatedRecovery:
    """Programs (8) and (10) for one layer and one truncated basis. Construction does all the
    target-independent work (Grams, their low-rank factors); :meth:`areas` and
    :meth:`squared_lengths` solve for one target each."""

    def __init__(self, layer, basis, *, rank: int | None = None):
        self.layer = layer
        self.basis = basis
        topo = layer.topology
        self.topology = topo
        phi = np.ascontiguousarray(basis.functions)
        self.phi = phi
        k = phi.shape[1]
        self.k = k
        self.U = phi[topo.edges[:, 0]] - phi[topo.edges[:, 1]]
        # Rank of the Nyström factors: ~12k + 100 covers the spectrum above 1e-6 of the mean
        # diagonal on our test meshes (measured: ~1,300 at k = 100 on both cloth layers).
        self.rank = rank if rank is not None else 12 * k + 100
        self._area_gram = None
        self._edge_gram = None
        tri = topo.triangles
        self._incidence = sp.csr_matrix(
            (np.ones(tri.size), (np.repeat(np.arange(topo.n_triangles), 3), tri.ravel())),
            shape=(topo.n_triangles, topo.n_vertices),
        )

    # -- Grams (M only, cached) ---------------------------------------------------------------
    def area_gram(self) -> LowRankGram:
        if self._area_gram is None:
            s = self._incidence
            kernel = self.phi @ self.phi.T  # (n, n)
            sk = np.asarray(s @ kernel)  # (m, n): s_T · φ_v
            sks = np.asarray(s @ sk.T)  # (m, m): s_T · s_T'   (symmetric)
            gram = sks * sks
            cross = np.asarray(s @ (sk * sk).T)  # Σ_{v∈T} (s_T'·φ_v)² -> (m, m)[T, T']
            gram += cross
            gram += cross.T
            kernel *= kernel
            gram += np.asarray(s @ np.asarray(s @ kernel).T)
            gram /= 144.0
            self._area_gram = nystrom(gram, self.rank, floor=0.0)
        return self._area_gram

    def edge_gram(self) -> LowRankGram:
        if self._edge_gram is None:
            w = self.U @ self.U.T
            w *= w
            self._edge_gram = nystrom(w, self.rank, floor=0.0)
        return self._edge_gram

    # -- areas, eq. (8) -------------------------------------------------------------------------
    def area_data(self, product: np.ndarray) -> np.ndarray:
        """``K_Aᵀ d``: ⟨G_T, P⟩ per triangle ``(m,)``."""
        p = 0.5 * (product + product.T)
        phi_p = self.phi @ p
        per_vertex = np.einsum("ij,ij->i", phi_p, self.phi)
        tri = self.topology.triangles
        s = self.phi[tri].sum(axis=1)
        return (np.einsum("ij,ij->i", s @ p, s) + per_vertex[tri].sum(axis=1)) / 12.0

    def areas(self, product: np.ndarray) -> np.ndarray:
        gram = self.area_gram()
        reference = self.layer.areas
        data = self.area_data(product)
        lam, y = gram.values, gram.vectors
        keep_all = lam > 0
        lam, y = lam[keep_all], y[:, keep_all]
        eps = EPSILON_RELATIVE * gram.mean_diagonal
        target_norm2 = float(np.sum(0.5 * (product + product.T) ** 2))
        for _ in range(MAX_EPSILON_HALVINGS + 1):
            keep = lam > LOWRANK_TOLERANCE * eps
            yk, lk = y[:, keep], lam[keep]
            # Closed-form unconstrained solution: (YΛYᵀ + εI)⁻¹ (b + ε µ_M), b projected on range.
            b = yk @ (yk.T @ data)
            rhs = b + eps * reference
            coef = yk.T @ rhs
            mu = rhs / eps + yk @ (coef / (lk + eps) - coef / eps)
            if mu.min() < 0:
                f = np.sqrt(lk)[:, None] * yk.T
                g = (yk.T @ data) / np.sqrt(lk)
                n = mu.size
                sol, _ = _admm(f, g, eps, reference, np.arange(n), np.ones(n), lambda v: np.maximum(v, 0.0))
                mu = np.maximum(sol.x, 0.0)
            share = self._share_exact(self.layer.assembler.mass_matrix(mu), product, mu, reference, eps)
            if share <= MAX_REGULARIZATION_SHARE:
                break
            eps /= EPSILON_STEP
        self.last_area_epsilon, self.last_area_share = eps, share
        floor = AREA_FLOOR * reference
        low = mu < floor
        if low.any():
            warnings.warn(
                f"{int(low.sum())} recovered triangle areas of the {self.layer.name} were below "
                f"{AREA_FLOOR:g} × their reference area (first: triangle {int(np.flatnonzero(low)[0])}) "
                "and were raised to it so that edge lengths can be recovered; a larger k helps.",
                ShapeDifferenceWarning,
                stacklevel=3,
            )
            mu = np.maximum(mu, floor)
        return mu

    def _share_exact(self, matrix, product, x, x0, eps):
        """Share of the viscosity term in the objective, data term evaluated exactly
        (``Φᵀ P(x) Φ`` with the sparse product matrix: O(n k²))."""
        p = 0.5 * (product + product.T)
        fit = float(np.sum((self.phi.T @ (matrix @ self.phi) - p) ** 2))
        reg = eps * float(np.sum((x - x0) ** 2))
        return reg / max(fit + reg, 1e-300)

    # -- squared lengths, eq. (10) --------------------------------------------------------------
    def edge_data(self, product: np.ndarray) -> np.ndarray:
        """``Hᵀ d``: −u_eᵀ P u_e per edge ``(E,)`` (C = Σ_e −c_e g_e g_eᵀ)."""
        p = 0.5 * (product + product.T)
        return -np.einsum("ij,ij->i", self.U @ p, self.U)

    def squared_lengths(self, product: np.ndarray, areas: np.ndarray) -> np.ndarray:
        topo = self.topology
        if not (np.all(np.isfinite(areas)) and np.all(areas > 0)):
            bad = int(np.flatnonzero(~(areas > 0))[0])
            raise RecoveryError(
                f"The recovered area of triangle {bad} of the {self.layer.name} is {areas[bad]:.3g}: "
                "edge lengths need positive areas. The truncated shape difference does not describe "
                "a valid mesh (try a larger k)."
            )
        gram = self.edge_gram()
        lam, y = gram.values, gram.vectors
        length_map = self.layer.assembler.length_map(areas).tocsc()  # B_µ (E, E)
        reference = self.layer.squared_lengths
        hd = self.edge_data(product)
        target_norm2 = float(np.sum(0.5 * (product + product.T) ** 2))
        slots = topo.triangle_edges.ravel()
        counts = np.bincount(slots, minlength=topo.n_edges).astype(float)
        project = lambda v: project_triangles(v.reshape(-1, 3), areas).ravel()  # noqa: E731
        # Data-term scale: mean diagonal of BᵀWB (exact trace: Σ_e ‖K e_e‖² via the low-rank W
        # is what the solver sees).
        state = None
        x_start = None
        eps = None
        for _ in range(MAX_EPSILON_HALVINGS + 1):
            keep = lam > (LOWRANK_TOLERANCE * eps if eps is not None else 0.0)
            yk, lk = y[:, keep], lam[keep]
            f = np.sqrt(lk)[:, None] * np.asarray((length_map.T @ yk).T)  # (p, E) = Λ^½ Yᵀ B_µ
            if eps is None:
                eps = EPSILON_RELATIVE * float(np.sum(f * f)) / topo.n_edges
                keep = lam > LOWRANK_TOLERANCE * eps
                yk, lk = y[:, keep], lam[keep]
                f = f[keep]
            g = (yk.T @ hd) / np.sqrt(lk)
            sol, state = _admm(
                f, g, eps, reference, slots, counts, project,
                x_start=x_start,
                z_start=None if state is None else state[0],
                u_start=None if state is None else state[1] / 1.0,
                rho=None if state is None else None,
            )
            x = self._feasible(sol.x, state[0], slots, counts, areas)
            share = self._share_exact(self.layer.assembler.conformal_matrix(x, areas), product, x, reference, eps)
            if share <= MAX_REGULARIZATION_SHARE:
                break
            eps /= EPSILON_STEP
            x_start = x
            state = None
        self.last_edge_epsilon, self.last_edge_share, self.last_edge_iterations = eps, share, sol.iterations
        self.last_edge_problem = (f, g)
        if not sol.converged:
            warnings.warn(
                f"The edge-length program of the {self.layer.name} stopped after {sol.iterations} "
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
