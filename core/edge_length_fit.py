"""Fitting point positions to target edge lengths (paper §7.3): Levenberg–Marquardt on the
relative residuals ``r_e = (|x_i − x_j|² − ℓ²_e) / (2ℓ²_e)`` (≈ the relative length error: every
edge counts the same whatever its size), with a sparse Jacobian and inexact Newton steps
(block-Jacobi preconditioned CG, :mod:`core.pcg`).

The 6-dimensional rigid gauge is handled by the Levenberg damping: rigid motions leave the
residuals unchanged, so the gradient is orthogonal to them and the damped step has no gauge
component. An optional soft anchor ``(w / h²) Σ_v |x_v − a_v|²`` pulls points towards given
positions (``h`` the mean edge length, so ``w`` is dimensionless).

:class:`EdgeLengthFit` holds one problem (edges, target lengths, free points, anchor) and fits it
from any start (:meth:`EdgeLengthFit.fit`) or deforms a start gradually into it
(:meth:`EdgeLengthFit.continuation`); :func:`refine_edge_lengths` is a few anchored steps on a
pose that nearly fits (the in-betweens' polish).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .geometry import rows_dot
from .pcg import pcg
from .small_matrices import cofactors_3x3

# Measurements behind every constant: docs/design-decisions.md.
#: Default RMS relative length residual at which the public fits stop.
DEFAULT_TOLERANCE = 1e-8
#: Tolerance of refine_edge_lengths: it runs its iteration budget unless the fit is at round-off.
REFINE_TOLERANCE = 1e-12
#: Default cap on Levenberg–Marquardt iterations.
DEFAULT_MAX_ITERATIONS = 60
#: Conjugate-gradient iterations per Gauss–Newton step (inexact Newton) and relative tolerance.
CG_ITERATIONS = 300
CG_TOLERANCE = 1e-4
#: Levenberg–Marquardt stops when an accepted step lowers the cost by less than this fraction,
#: or when no point moves more than STEP_FLOOR mean edge lengths.
STAGNATION = 1e-3
STEP_FLOOR = 1e-14
#: Levenberg damping relative to the mean diagonal of JᵀJ: the first value (nearly Gauss–Newton)
#: and the floor that keeps the damped system definite along the rigid gauge.
INITIAL_DAMPING = 1e-6
DAMPING_FLOOR = 1e-12
#: Damping divided after an accepted step, multiplied after a rejected one; that many
#: rejections in a row mean no descent is left (a local minimum to working precision).
DAMPING_DECREASE = 4.0
DAMPING_INCREASE = 8.0
DAMPING_TRIES = 10
#: Target squared lengths below this fraction of their mean are floored in the residual weights.
LENGTH_FLOOR = 1e-12


def relative_residuals(x: np.ndarray, edges: np.ndarray, squared: np.ndarray):
    d = x[edges[:, 0]] - x[edges[:, 1]]
    length = np.sqrt(rows_dot(d, d))
    target = np.sqrt(squared)
    floor = np.finfo(float).tiny
    return (length - target) / np.maximum(target, floor)


def rms(values: np.ndarray) -> float:
    """Root mean square of ``values`` (0 for none)."""
    return float(np.sqrt(np.mean(values * values))) if values.size else 0.0


@dataclass(frozen=True)
class Fit:
    """One fit: ``points`` ``(N, 3)``, their RMS relative length ``residual``, the LM
    ``iterations`` taken and whether it ``converged`` (tolerance reached or no descent left)."""

    residual: float
    points: np.ndarray
    iterations: int
    converged: bool


@dataclass(frozen=True, eq=False)
class EdgeLengthFit:
    """Points ``(N, 3)`` to fit to the squared lengths ``squared`` ``(E,)`` of ``edges``
    ``(E, 2)``: ``free`` bool ``(N,)`` the points that move; ``anchor_points`` ``(N, 3)`` (NaN rows
    unanchored) with dimensionless ``anchor_weight``; ``length_scale`` the mean edge length;
    the fit stops at RMS relative residual ``tolerance``; ``initial_damping`` and ``stagnation`` as in
    :func:`levenberg_marquardt`."""

    edges: np.ndarray
    squared: np.ndarray
    free: np.ndarray
    anchor_points: np.ndarray | None
    anchor_weight: float
    length_scale: float
    tolerance: float
    initial_damping: float = INITIAL_DAMPING
    stagnation: float = STAGNATION

    def residual(self, x: np.ndarray) -> float:
        """RMS relative length residual of points ``x`` ``(N, 3)``."""
        return rms(relative_residuals(x, self.edges, self.squared))

    def fit(self, start: np.ndarray, max_iterations: int) -> Fit:
        """Levenberg–Marquardt from ``start`` (skipped when it already fits to the tolerance)."""
        x, iterations, converged = self._polish(start, max_iterations)
        return Fit(self.residual(x), x, iterations, converged)

    def resume(self, fit: Fit, max_iterations: int) -> Fit:
        """Continue ``fit`` to the end of a budget of ``max_iterations`` in all."""
        if fit.converged or fit.iterations >= max_iterations:
            return fit
        rest = self.fit(fit.points, max_iterations - fit.iterations)
        return replace(rest, iterations=rest.iterations + fit.iterations)

    def continuation(self, x: np.ndarray, fractions, iterations: int) -> np.ndarray:
        """Deform ``x`` ``(N, 3)`` gradually towards the target: ``iterations`` LM steps on its own
        squared lengths blended into the targets by each of ``fractions`` (the full step is the
        caller's)."""
        d = x[self.edges[:, 0]] - x[self.edges[:, 1]]
        own = rows_dot(d, d)
        for fraction in fractions:  # intermediate steps are capped: not converging there is expected
            blended = replace(self, squared=(1.0 - fraction) * own + fraction * self.squared)
            x, _, _ = blended._polish(x, iterations)
        return x

    def _polish(self, x0, max_iterations):
        rel = relative_residuals(x0, self.edges, self.squared)
        if (np.sqrt(np.mean(rel * rel)) <= self.tolerance and not self.anchor_weight) or max_iterations <= 0:
            return x0, 0, True
        return levenberg_marquardt(
            x0, self.edges, self.squared, self.free, anchor_points=self.anchor_points,
            anchor_weight=self.anchor_weight, length_scale=self.length_scale, tolerance=self.tolerance,
            max_iterations=max_iterations, initial_damping=self.initial_damping, stagnation=self.stagnation,
        )


def _block_jacobi(edges_i, edges_j, g, nf, extra_diag):
    """Inverse 3×3 diagonal blocks ``(nf, 3, 3)`` of ``JᵀJ + diag(extra_diag)`` for rows
    ``± g_e`` at unknowns ``edges_i`` / ``edges_j`` (−1: fixed)."""
    blocks = np.zeros((nf, 3, 3))
    outer = g[:, :, None] * g[:, None, :]
    for cols in (edges_i, edges_j):
        ok = cols >= 0
        for r in range(3):
            for c in range(3):
                blocks[:, r, c] += np.bincount(cols[ok], outer[ok, r, c], minlength=nf)
    blocks += extra_diag.reshape(nf, 3)[:, :, None] * np.eye(3)[None]
    # Closed-form inverse; the blocks are symmetric positive definite (determinant > 0, the
    # cofactor matrix its own transpose). Kept C-contiguous: the BSR product ravels its data on
    # every call, and a transposed view would make that a copy.
    cofactors, det = cofactors_3x3(blocks)
    return cofactors / det[:, None, None]


def levenberg_marquardt(x0, edges, squared, free, *, anchor_points=None, anchor_weight=0.0, length_scale=1.0,
                         tolerance=REFINE_TOLERANCE, max_iterations=DEFAULT_MAX_ITERATIONS, cg_iterations=CG_ITERATIONS,
                         initial_damping=INITIAL_DAMPING, stagnation=STAGNATION):
    """Minimize ``Σ_e r_e² + (w / h²) Σ_v |x_v − a_v|²`` with ``r_e = (|x_i − x_j|² − ℓ²_e)/(2ℓ²_e)``.

    ``x0`` ``(N, 3)``; ``free`` bool ``(N,)`` points that move (the others stay); ``anchor_points``
    ``(N, 3)`` with NaN rows for unanchored points; ``length_scale`` ``h`` the mean edge length.
    Each step solves ``(JᵀJ + µI + A) δ = −g`` by block-Jacobi preconditioned CG (an inexact
    Newton step: a sparse factorization per step costs far more). ``initial_damping``: the first
    µ relative to the mean diagonal of ``JᵀJ`` (a start far from the fit takes fewer rejected
    steps with a larger one); ``stagnation``: stop when an accepted step lowers the cost by less than
    this fraction (:data:`STAGNATION`). Returns ``(x, iterations, converged)``.
    """
    from scipy.sparse import bsr_matrix, coo_matrix

    N = x0.shape[0]
    index = np.full(N, -1, dtype=np.int64)
    index[free] = np.arange(int(free.sum()))
    nf = int(free.sum())
    use = (index[edges[:, 0]] >= 0) | (index[edges[:, 1]] >= 0)
    edges, squared = edges[use], squared[use]
    scale2 = np.maximum(squared, LENGTH_FLOOR * max(float(np.mean(squared)) if squared.size else 1.0, np.finfo(float).tiny))
    inv = 1.0 / (2.0 * scale2)
    anchored = np.zeros(N, dtype=bool)
    aw = 0.0
    if anchor_points is not None and anchor_weight > 0:
        anchored = free & np.isfinite(anchor_points).all(axis=1)
        aw = float(anchor_weight) / (length_scale * length_scale)
    anchor_diag = np.zeros(3 * nf)
    if aw:
        anchor_diag.reshape(nf, 3)[index[anchored]] = aw
    x = x0.copy()
    ei, ej = index[edges[:, 0]], index[edges[:, 1]]

    def cost_of(x):
        d = x[edges[:, 0]] - x[edges[:, 1]]
        r = (rows_dot(d, d) - squared) * inv
        c = float(r @ r)
        if aw:
            da = x[anchored] - anchor_points[anchored]
            c += aw * float(np.einsum("ij,ij->", da, da))
        return c, r, d

    def scatter(values_i, values_j):
        """Σ over edges of per-edge 3-vectors into the unknowns, (nf*3,)."""
        out = np.zeros((nf, 3))
        for cols, vals in ((ei, values_i), (ej, values_j)):
            ok = cols >= 0
            for k in range(3):
                out[:, k] += np.bincount(cols[ok], vals[ok, k], minlength=nf)
        return out.ravel()

    cost, r, d = cost_of(x)
    iterations, converged = 0, False
    mu = None
    rows = np.arange(edges.shape[0])
    block_index, block_pointer = np.arange(nf), np.arange(nf + 1)
    for iterations in range(1, max_iterations + 1):
        rms = np.sqrt(np.mean(relative_residuals(x, edges, squared) ** 2)) if edges.size else 0.0
        if rms <= tolerance and not aw:
            converged = True
            iterations -= 1
            break
        g = 2.0 * d * inv[:, None]  # ∂r_e/∂x_i = g_e, ∂r_e/∂x_j = −g_e
        grad = scatter(g * r[:, None], -g * r[:, None])
        if aw:
            grad.reshape(nf, 3)[index[anchored]] += aw * (x[anchored] - anchor_points[anchored])
        data, rr, cc = [], [], []
        for cols, sgn in ((ei, 1.0), (ej, -1.0)):
            ok = cols >= 0
            for k in range(3):
                data.append(sgn * g[ok, k])
                rr.append(rows[ok])
                cc.append(3 * cols[ok] + k)
        J = coo_matrix((np.concatenate(data), (np.concatenate(rr), np.concatenate(cc))),
                       shape=(edges.shape[0], 3 * nf)).tocsr()
        JT = J.T.tocsr()
        gg = rows_dot(g, g)
        mean_diag = float(2.0 * gg.sum() / max(3 * nf, 1) + anchor_diag.mean()) if nf else 1.0
        if mu is None:
            mu = initial_damping * mean_diag
        floor = DAMPING_FLOOR * mean_diag
        accepted = False
        for _ in range(DAMPING_TRIES):
            damping = max(mu, floor)
            # Block-diagonal preconditioner as a BSR matrix (a faster product than an einsum
            # over the (nf, 3, 3) blocks).
            preconditioner = bsr_matrix((_block_jacobi(ei, ej, g, nf, anchor_diag + damping), block_index,
                                         block_pointer), shape=(3 * nf, 3 * nf))
            diagonal = anchor_diag + damping

            def apply_A(v, diagonal=diagonal):
                return JT @ (J @ v) + diagonal * v

            step = -pcg(apply_A, grad, preconditioner.__matmul__, cg_iterations, CG_TOLERANCE)
            trial = x.copy()
            trial[free] += step.reshape(-1, 3)
            new_cost, new_r, new_d = cost_of(trial)
            if np.isfinite(new_cost) and new_cost <= cost:
                improvement = cost - new_cost
                x, r, d = trial, new_r, new_d
                old_cost, cost = cost, new_cost
                mu = max(mu / DAMPING_DECREASE, floor)
                accepted = True
                break
            mu = damping * DAMPING_INCREASE
        if not accepted:
            converged = True  # no descent possible: a (local) minimum to working precision
            break
        if improvement <= stagnation * old_cost or np.abs(step).max() <= STEP_FLOOR * length_scale:
            converged = True
            break
    return x, iterations, converged


def refine_edge_lengths(vertices: np.ndarray, edges: np.ndarray, squared_lengths: np.ndarray, *,
                        anchor_weight: float, max_iterations: int, fixed: np.ndarray | None = None,
                        cg_iterations: int = CG_ITERATIONS) -> np.ndarray:
    """A few Levenberg–Marquardt steps moving ``vertices`` ``(n, 3)`` towards the squared edge
    lengths ``squared_lengths`` ``(E,)`` of ``edges`` ``(E, 2)``, each vertex softly anchored to
    its start (``anchor_weight`` per squared mean edge length, which also fixes the rigid gauge);
    ``fixed`` bool ``(n,)`` vertices stay. Returns the new positions ``(n, 3)``; no convergence
    is required (a polish of a pose that already nearly fits); ``cg_iterations`` caps each inexact
    Newton step."""
    x0 = np.asarray(vertices, dtype=np.float64)
    squared = np.asarray(squared_lengths, dtype=np.float64)
    free = np.zeros(x0.shape[0], dtype=bool)
    free[edges.ravel()] = True
    if fixed is not None:
        free &= ~fixed
    if not free.any():
        return x0.copy()
    length_scale = float(np.mean(np.sqrt(squared)))
    x, _, _ = levenberg_marquardt(x0, edges, squared, free, anchor_points=x0, anchor_weight=anchor_weight,
                                   length_scale=length_scale, max_iterations=max_iterations,
                                   cg_iterations=cg_iterations)
    return x
