"""Recovery of areas and squared edge lengths from truncated shape differences (paper §7.1–7.2).

With ``k`` eigenfunctions ``Φ`` of a layer (the base M or its offset surface M_t) the two programs
are

- areas, eq. (8):  ``min ‖Φᵀ A(µ) Φ − D_A‖²_F + ε ‖µ − µ_M‖²``  s.t. ``µ ≥ 0``;
- squared lengths, eq. (10):  ``min ‖Φᵀ C(ℓ²; µ) Φ − diag(λ) D_C‖²_F + ε′ ‖ℓ² − ℓ²_M‖²``  s.t.
  ``ℓ² ≥ 0`` and, per triangle, ``E₃(T) ⪰ 0`` with ``det E₃(T) ≥ 4 µ(T)²`` (Props. 5–6).

ε and ε′ are given relative to the data term's curvature along the reference,
``σ_A = ‖Φᵀ A(µ_M) Φ‖²/‖µ_M‖²`` (= k) and ``σ_C = ‖Φᵀ C(ℓ²_M; µ) Φ‖²/‖ℓ²_M‖²``, which makes them
invariant under scaling of the mesh and of the basis. Eq. (5) differences are exact in the basis
and take the small :data:`EXACT_EPSILON`, so that the result converges to the exact metric as k
grows; eq. (6) ones carry the k_N truncation of the functional map, which a small ε would fit as
if it were geometry (:data:`AREA_EPSILON`, :data:`LENGTH_EPSILON`).

How the programs are solved (the measurements behind each choice: docs/design-decisions.md):

1. **Areas: matrix-free conjugate gradients.** ``H µ = Φᵀ A(µ) Φ`` and its adjoint need only the
   mesh's sparsity pattern (``d_v = φ_vᵀ P φ_v``, ``o_e = φ_aᵀ P φ_b``), O(n k²) each; the
   regularized normal equations are solved by Jacobi-preconditioned CG. ``µ ≥ 0`` is checked
   afterwards; only if it is violated the bounded program is solved (scipy's L-BFGS-B in
   Jacobi-scaled variables, matrix-free).
2. **Lengths: low-rank data term.** With ``c = B_µ ℓ²`` the cotangent weights, the data term is
   ``‖H c − d‖²`` with Gram ``W = (U Uᵀ)∘²`` (``U`` the ``(E, k)`` edge differences of Φ) from
   ``⟨u uᵀ, v vᵀ⟩ = (u·v)²``; nothing of size k² × E or E × E is formed. W's spectrum falls fast,
   so a randomly pivoted Cholesky factor (:mod:`core.low_rank`, columns ``(U U_Sᵀ)∘²`` on demand)
   to a residual trace of :data:`EDGE_GRAM_TOLERANCE` is computed once per layer and basis and
   orthonormalized. Eigenpairs are kept when ``λ ‖B_µ‖² > LOWRANK_TOLERANCE · ε′`` (W lives in
   cotangent-weight space, ε′ in squared-length space).
3. **Constraints only where needed.** The unconstrained optimum is one Woodbury solve; if every
   triangle satisfies its constraint it is returned. Otherwise ADMM (:mod:`core.admm`) with
   per-triangle slot copies: exact x-updates by Woodbury, z-updates by the projection onto each
   triangle's set (:mod:`core.triangle_constraints`).
4. **Feasible output.** The returned lengths satisfy every constraint (triangle inequality
   strictly; ``det E₃ ≥ 4µ²`` up to :data:`~core.triangle_constraints.CONSTRAINT_TOLERANCE`
   relative), or :class:`RecoveryError` is raised; an iteration cap or floored areas give a
   :class:`ShapeDifferenceWarning`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .admm import admm
from .errors import RecoveryError, shape_warning, warn
from .geometry import DIVISION_FLOOR, rows_dot
from .low_rank import LowRankGram, SplitGram, low_rank_gram, randomly_pivoted_cholesky
from .triangle_constraints import feasible_lengths, project_triangles, satisfied

# Measurements behind every constant: docs/design-decisions.md.
#: ε of eq. (8) relative to σ_A (:meth:`TruncatedRecovery.area_scale`) for eq. (6) differences.
AREA_EPSILON = 1e-2
#: ε′ of eq. (10) relative to σ_C (:meth:`TruncatedRecovery.edge_scale`) for eq. (6) differences.
LENGTH_EPSILON = 3e-4
#: ε and ε′ (same units) for eq. (5) differences, which are exact in the basis.
EXACT_EPSILON = 1e-4
#: Conjugate gradients of the area program: relative residual and iteration cap.
CG_TOLERANCE = 1e-6
CG_MAX_ITERATIONS = 2000
#: Bounded area program (L-BFGS-B, only when CG gives negative areas): iteration cap and
#: projected-gradient tolerance relative to the largest scaled right-hand side.
BOUNDED_MAX_ITERATIONS = 2000
BOUNDED_GRADIENT_TOLERANCE = 1e-10
#: A line search that can no longer decrease the quadratic (L-BFGS-B's ABNORMAL, round-off) is
#: converged when the projected gradient is within the CG solve's own relative tolerance.
BOUNDED_STALL_TOLERANCE = CG_TOLERANCE
#: The edge Gram's pivoted Cholesky factor stops at this fraction of the trace left.
EDGE_GRAM_TOLERANCE = 3e-6
#: Keep eigenvalues λ of the edge Gram with λ‖B_µ‖² above this fraction of ε′.
LOWRANK_TOLERANCE = 1.0
#: Recovered areas below this fraction of the reference area are raised to it (with a
#: ShapeDifferenceWarning): eq. (10) divides by µ, and µ ≥ 0 can be active when truncated.
AREA_FLOOR = 0.05


def recover_truncated_metric(solver: "TruncatedRecovery", area_difference, conformal_difference, warm=None,
                             tolerance: float | None = None, rho_scale: float | None = None):
    """Areas ``(m,)`` and squared lengths ``(E,)`` of the target of one layer from its truncated
    differences, by the layer's :class:`TruncatedRecovery` for their basis.

    ``warm``: ``None``, or a dict carried from one pose to the next of a sequence (empty at
    first): it holds the last areas and ADMM state, which start the next pose's iterations, and
    is updated in place. The programs are the same; only the starts differ. ``tolerance``: the
    relative stopping tolerance of both iterative solvers (default: :data:`CG_TOLERANCE` for the
    areas, :data:`~core.admm.ADMM_TOLERANCE` for the lengths); ``rho_scale``: ADMM's initial
    penalty without a warm one (:func:`~core.admm.admm`)."""
    # Eq. (5) differences are exact in the basis (the true metric fits them to round-off), so
    # they take the small ε of EXACT_EPSILON; eq. (6) ones carry the k_N truncation of the
    # functional map, which a small ε would fit as if it were geometry.
    exact = getattr(area_difference, "target_size", None) is None
    warm_areas = None if warm is None else warm.get("areas")
    areas = solver.areas(area_difference.product_matrix(), epsilon=EXACT_EPSILON if exact else AREA_EPSILON,
                         start=warm_areas, tolerance=tolerance).areas
    lengths = solver.squared_lengths(
        conformal_difference.product_matrix(), areas, epsilon=EXACT_EPSILON if exact else LENGTH_EPSILON,
        warm=None if warm is None else warm.get("admm"), tolerance=tolerance, rho_scale=rho_scale,
    )
    if warm is not None:
        warm["areas"] = areas
        if lengths.state is not None:
            warm["admm"] = lengths.state
    return areas, lengths.squared_lengths


@dataclass(frozen=True, eq=False)
class AreaSolution:
    """Result of eq. (8): ``areas`` ``(m,)``; ``epsilon`` the absolute ε used; ``method``
    ``"cg"`` (the unconstrained optimum was feasible) or ``"bounded"`` (µ ≥ 0 active)."""

    areas: np.ndarray
    epsilon: float
    method: str


@dataclass(frozen=True, eq=False)
class EdgeProgram:
    """Eq. (10) in the low-rank form solved here: ``min ½‖F x − g‖² + ½ε‖x − x_M‖²`` over the
    squared lengths ``x`` ``(E,)``; ``factor`` ``F`` ``(p, E)``, ``target`` ``g`` ``(p,)``, ``epsilon``
    the absolute ε′, ``reference`` ``x_M`` the reference layer's squared lengths."""

    factor: np.ndarray
    target: np.ndarray
    epsilon: float
    reference: np.ndarray

    @property
    def rank(self) -> int:
        return self.target.size


@dataclass(frozen=True, eq=False)
class LengthSolution:
    """Result of eq. (10): ``squared_lengths`` ``(E,)``; ``epsilon`` the absolute ε′; ``rank`` of
    the data term kept; ``iterations`` of ADMM (0: the unconstrained optimum was feasible);
    ``converged`` False when ADMM stopped before its tolerance (with a warning)."""

    squared_lengths: np.ndarray
    epsilon: float
    rank: int
    iterations: int
    converged: bool
    state: tuple | None = None  # ADMM's (z, u, ρ) when it ran: a warm start for a nearby pose


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

    # -- matrix-free pieces ---------------------------------------------------------------------
    def reduce(self, matrix) -> np.ndarray:
        """``Φᵀ X Φ`` ``(k, k)`` for a sparse ``(n, n)`` matrix ``X``."""
        return self.phi.T @ np.asarray(matrix @ self.phi)

    def _pattern_values(self, product: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``d_v = φ_vᵀ P φ_v`` ``(n,)`` and ``o_e = φ_aᵀ P φ_b`` ``(E,)`` of the symmetric part of P."""
        p = 0.5 * (product + product.T)
        phi_p = self.phi @ p
        edges = self.topology.edges
        diagonal = rows_dot(phi_p, self.phi)
        off = rows_dot(phi_p[edges[:, 0]], self.phi[edges[:, 1]])
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

    def areas(self, product: np.ndarray, *, epsilon: float | None = None, floor: bool = True,
              start: np.ndarray | None = None, tolerance: float | None = None) -> AreaSolution:
        """Eq. (8): ``min ‖Φᵀ A(µ) Φ − P‖²_F + ε‖µ − µ_M‖²`` s.t. ``µ ≥ 0`` (``epsilon`` relative to
        :meth:`area_scale`; default :data:`AREA_EPSILON`). With ``floor`` (default), areas below
        :data:`AREA_FLOOR` × the reference are raised to it with a warning (eq. 10 divides by µ);
        ``floor=False`` returns the optimum of eq. (8) itself. ``start`` ``(m,)``: the first CG
        iterate (default: the reference areas), e.g. the areas of a nearby pose; ``tolerance``: CG's
        relative residual (default :data:`CG_TOLERANCE`)."""
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
        x0 = reference.copy() if start is None else np.array(start, dtype=np.float64)
        rtol = CG_TOLERANCE if tolerance is None else float(tolerance)
        mu, info = cg(normal, rhs, x0=x0, rtol=rtol, maxiter=CG_MAX_ITERATIONS, M=precond)
        method = "cg"
        if info < 0 or not np.all(np.isfinite(mu)):
            raise RecoveryError(
                f"The area program of the {self.layer.name} failed (conjugate gradients, status "
                f"{info}); the truncated shape difference may be corrupt."
            )
        if info > 0:
            residual = np.linalg.norm(normal.matvec(mu) - rhs) / max(np.linalg.norm(rhs), DIVISION_FLOOR)
            warning = shape_warning(
                f"The triangle areas of the {self.layer.name} are recovered only to a relative residual of "
                f"{residual:.1e}, not {rtol:g}: check the result, or use the full basis (k_M = 0), "
                f"which recovers them exactly (the area program stopped after {info} conjugate-gradient "
                "iterations; its last iterate is used).",
                "fit",
            )
            warning.excess = float(residual) / rtol  # the residual reached ÷ the one asked for
            warn(warning)
        if mu.min() < 0.0:
            mu = self._bounded_areas(normal.matvec, rhs, eps, mu)
            method = "bounded"
        lowest = AREA_FLOOR * reference
        low = (mu < lowest) if floor else np.zeros(m, dtype=bool)
        if low.any():
            warn(
                f"{int(low.sum())} triangle(s) of the {self.layer.name} (first: triangle "
                f"{int(np.flatnonzero(low)[0])}) came out with almost no area and were given {AREA_FLOOR:g} × "
                "their rest area, so that their edge lengths can be recovered: the basis is too small for this "
                f"deformation; a larger k_M helps (recovered areas below {AREA_FLOOR:g} × the reference raised "
                "to it).",
                "truncated",
            )
            mu = np.maximum(mu, lowest)
        return AreaSolution(mu, eps, method)

    def _bounded_areas(self, normal_matvec, rhs, eps, start):
        """``µ ≥ 0`` active: the quadratic of the CG solve (its normal operator ``normal_matvec`` and
        right-hand side ``rhs``) by scipy's L-BFGS-B with the bounds, in Jacobi-scaled variables
        ``y = √diag · µ`` (the bound stays ``y ≥ 0``), started from the clipped CG optimum
        (two orders of magnitude faster than ``scipy.optimize.lsq_linear`` here)."""
        from scipy.optimize import minimize

        reference = self.layer.areas
        scale = np.sqrt(self.area_gram_diagonal() + eps)

        def objective(y):
            mu = y / scale
            normal = normal_matvec(mu)
            return 0.5 * float(mu @ normal) - float(rhs @ mu), (normal - rhs) / scale

        gradient_scale = float(np.abs(rhs / scale).max())
        result = minimize(objective, np.maximum(start, 0.0) * scale, jac=True, method="L-BFGS-B",
                          bounds=[(0.0, None)] * reference.size,
                          options={"maxiter": BOUNDED_MAX_ITERATIONS, "ftol": 0.0,
                                   "gtol": BOUNDED_GRADIENT_TOLERANCE * gradient_scale})
        if not np.all(np.isfinite(result.x)):
            raise RecoveryError(f"The bounded area program of the {self.layer.name} failed ({result.message}).")
        gradient = objective(result.x)[1]
        projected = np.abs(np.where(result.x > 0.0, gradient, np.minimum(gradient, 0.0))).max()
        stalled_at_optimum = result.status == 2 and projected <= BOUNDED_STALL_TOLERANCE * gradient_scale
        if not result.success and not stalled_at_optimum:
            warn(
                f"The triangle areas of the {self.layer.name} may be inexact: check the result, or use the full "
                f"basis (k_M = 0), which recovers them exactly (the bounded area program stopped before "
                f"convergence: {result.message}; its last iterate is used).",
                "fit",
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
            diagonal = rows_dot(u, u) ** 2
            factor = randomly_pivoted_cholesky(
                lambda picks: np.square(u @ u[picks].T), diagonal, tolerance=EDGE_GRAM_TOLERANCE, max_rank=u.shape[0]
            )
            self._edge_gram = low_rank_gram(factor, float(diagonal.mean()))
        return self._edge_gram

    def reference_product(self, length_map) -> np.ndarray:
        """``H B_µ ℓ²_M`` ``(k, k)``: the reduced conformal product of the reference lengths with the
        recovered areas' length map ``length_map`` (eq. 10 at ``ℓ² = ℓ²_M``), exact."""
        c = length_map @ self.layer.squared_lengths
        lap = self.layer.assembler.from_entries(self.layer.assembler.laplacian_diagonal(c), c)
        return self.reduce(lap)

    def edge_scale(self, length_map, reference_product: np.ndarray | None = None) -> float:
        """σ_C = ‖H B_µ ℓ²_M‖² / ‖ℓ²_M‖² (same role as :meth:`area_scale`), exact."""
        product = self.reference_product(length_map) if reference_product is None else reference_product
        return float(np.sum(product**2) / np.sum(self.layer.squared_lengths**2))

    def edge_program(self, product: np.ndarray, areas: np.ndarray, *, epsilon: float | None = None) -> EdgeProgram:
        """Eq. (10)'s data term and regularization in low-rank form for the conformal product
        ``product`` ``(k, k)`` and the recovered areas ``areas`` ``(m,)`` (``epsilon`` relative to
        :meth:`edge_scale`; default :data:`LENGTH_EPSILON`)."""
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
        at_reference = self.reference_product(length_map)
        eps = (LENGTH_EPSILON if epsilon is None else epsilon) * self.edge_scale(length_map, at_reference)
        # W lives in cotangent-weight space, ε′ in squared-length space: a direction of W with
        # eigenvalue λ contributes at most λ‖B_µ‖² to the objective's curvature, so it is
        # negligible next to ε′ when λ‖B_µ‖² < LOWRANK_TOLERANCE × ε′ (‖B‖² ≤ ‖B‖₁‖B‖_∞).
        gain = float(abs(length_map).sum(axis=0).max() * abs(length_map).sum(axis=1).max())
        # The values are descending: the kept ones are a prefix (a view, no copy of the E × p vectors).
        rank = int(np.count_nonzero(gram.values * gain > LOWRANK_TOLERANCE * eps))
        y, lam = gram.vectors[:, :rank], gram.values[:rank]
        f = np.sqrt(lam)[:, None] * np.asarray((length_map.T @ y).T)  # (p, E) = Λ^½ Yᵀ B_µ
        # The data term about the reference, ‖F (ℓ² − ℓ²_M) − Λ^-½ Yᵀ Hᵀ (P − H B_µ ℓ²_M)‖², with the
        # product at the reference exact: a pose whose differences are the base's (a rigid motion)
        # recovers ℓ²_M exactly, where Λ^-½ Yᵀ Hᵀ P alone carried the low-rank factor's error
        # (squared lengths 1.7e-3 off on a jittered grid at k_M = 30).
        reference = self.layer.squared_lengths
        g = (y.T @ self.edge_data(product - at_reference)) / np.sqrt(lam) + f @ reference
        return EdgeProgram(f, g, eps, reference)

    def squared_lengths(self, product: np.ndarray, areas: np.ndarray, *, epsilon: float | None = None,
                        warm: tuple | None = None, tolerance: float | None = None,
                        rho_scale: float | None = None) -> LengthSolution:
        """Eq. (10): ``min ‖Φᵀ C(ℓ²; µ) Φ − P‖²_F + ε′‖ℓ² − ℓ²_M‖²`` s.t. ``ℓ² ≥ 0``, triangle
        inequality, ``det E₃ ≥ 4µ²`` (``epsilon`` relative to :meth:`edge_scale`; default
        :data:`LENGTH_EPSILON`). ``warm``: the :attr:`LengthSolution.state` of a nearby pose, which
        starts ADMM's slot copies, scaled duals and ρ; ``tolerance``: ADMM's (default
        :data:`~core.admm.ADMM_TOLERANCE`); ``rho_scale``: ADMM's initial penalty without a warm
        one (:func:`~core.admm.admm`)."""
        topo = self.topology
        program = self.edge_program(product, areas, epsilon=epsilon)
        f, g, eps, reference = program.factor, program.target, program.epsilon, program.reference
        slots = topo.triangle_edges.ravel()
        counts = np.bincount(slots, minlength=topo.n_edges).astype(float)
        # Unconstrained optimum first (one Woodbury solve); the cone constraints only if violated.
        split = SplitGram(f, counts)
        x = split.woodbury(eps, 0.0).solve(f.T @ g + eps * reference)
        iterations, converged, state = 0, True, None
        if not satisfied(x[slots].reshape(-1, 3), areas).all():
            project = lambda v: project_triangles(v.reshape(-1, 3), areas).ravel()  # noqa: E731
            z0, u0, rho0 = warm if warm is not None else (None, None, None)
            sol, state = admm(f, g, eps, reference, slots, counts, project, x_start=x, split=split,
                              z_start=z0, u_start=u0, rho=rho0, tol=tolerance,
                              rho_scale=rho_scale)
            iterations, converged = sol.iterations, sol.converged
            x, reached = feasible_lengths(state[0], slots, counts, areas)
            if not reached:
                bad = np.flatnonzero(~satisfied(x[slots].reshape(-1, 3), areas))
                raise RecoveryError(
                    f"The edge-length program of the {self.layer.name} did not reach a point satisfying "
                    f"the triangle constraints (first violated triangle {bad[0]}, {bad.size} in all). "
                    "The truncated differences may be inconsistent with the recovered areas; try a larger k."
                )
        if not converged:
            warn(
                f"The edge lengths of the {self.layer.name} may be less accurate than the differences allow "
                "(every triangle stays sound): a larger k_M, or the full basis (k_M = 0), helps (the edge-length "
                f"program stopped after {iterations} iterations before reaching its tolerance).",
                "fit",
            )
        return LengthSolution(x, eps, program.rank, iterations, converged, state)
