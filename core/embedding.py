"""Embedding from edge lengths (paper §7.3, constructive proof of Prop. 4).

Given the squared lengths of every edge of the canonical thickening (§5.3,
:attr:`OffsetSurface.thickening_edges`), :func:`embed_thickening` returns point positions that
realize them — exactly, up to rigid motion, when the lengths are exact; in the least-squares
sense otherwise. The base layer (the first ``n`` rows) is the reconstructed pose.

1. **Start: hinge frames** (:mod:`core.hinge_frames`): triangle frames glued across hinges, the
   hinge signs voted by the vertex stars. Exact to round-off in linear time. When its residual
   is not at round-off level (inexact lengths), the frames are synchronized (fitted to all
   hinges at once) and raced against the caller's reference pose (the base shape, from
   :class:`ReferenceShape`): a few Levenberg–Marquardt iterations each, the better one is
   polished to the end. Noisy hinge signs can fold the frames; the reference pose does not fold.
2. **Fit: Levenberg–Marquardt** (only if the RMS relative residual exceeds ``tolerance``) of the
   residuals ``(|x_i − x_j|² − ℓ²_e) / (2ℓ²_e)`` (≈ the relative length error: every edge counts
   the same whatever its size), with a sparse Jacobian; each step is an inexact Newton step by
   block-Jacobi preconditioned CG. The 6-dimensional rigid gauge is handled by the Levenberg
   damping: rigid motions leave the residuals unchanged, so the gradient is orthogonal to them
   and the damped step has no gauge component.
3. **Continuation** when the best fit stays far from realizable: the reference pose deformed
   gradually into the target lengths.

With inexact lengths (truncated or interpolated differences) the result is a least-squares fit
and :attr:`EmbeddingResult.residual` reports how far from realizable the lengths were.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass

import numpy as np

from .errors import RecoveryError, ShapeDifferenceWarning
from .mesh_topology import MeshTopology
from .offset_surface import OffsetSurface
from .small_matrices import cofactors_3x3

#: Hinge-frame starts with an RMS relative residual below this go straight to the polish.
FRAMES_NEARLY_EXACT = 1e-6
#: With inexact lengths several starts are polished for this many Levenberg–Marquardt iterations
#: and only the best goes on to the end. Measured (RMS residual / Hausdorff of the base layer, truncated
#: differences k = 100 / 200): the hinge frames fold where the hinge signs are noisy — drape
#: frames 8 → 16 of a Blender cloth simulation 0.046 / 24.9 % against 0.022 / 7.5 % from the base
#: pose, a flag in wind 0.111 / 29 % against 0.065 / 10.4 % — and tie on smooth poses (synthetic
#: cloth 0.0057 both). A full second polish cost 1–2 s on the 1,089-vertex cloth.
START_TRIAL_ITERATIONS = 3
#: When the best start still leaves an RMS relative length residual above this, the reference
#: pose is also deformed gradually into the target lengths and the lowest residual wins. Each
#: schedule of CONTINUATION_SCHEDULES is (fractions of the way, LM iterations per fraction), then a
#: fit to the end. Measured on 16 Blender cloth pairs (truncated k = 100 / 200): residuals
#: 0.0014–0.0102 where the result was within 2 % of the target, 0.022–0.058 on crumpling cloth.
#: On the 9 crumpling pairs the Hausdorff/diagonal errors summed to 125.8 % without continuation,
#: 117.4 % with the 4-step schedule alone, 115.5 % with the 8-step one alone and 113.2 % with both
#: raced (e.g. flag 40 → 48: 16.1 → 8.4 %, falling sheet rest → 95: 31.9 → 15.3 %; worst loss flag
#: rest → 48: 15.5 → 17.5 % at a lower residual).
CONTINUATION_RESIDUAL = 2e-2
CONTINUATION_SCHEDULES = (((0.25, 0.5, 0.75), 4), (tuple(np.arange(1, 8) / 8), 3))
#: Default cap on Levenberg–Marquardt iterations.
DEFAULT_MAX_ITERATIONS = 60


@dataclass(frozen=True, eq=False)
class EmbeddingResult:
    """Output of :func:`embed_thickening` / :func:`embed_base_edges`.

    ``points`` float64 ``(n_points, 3)`` (thickening: base vertices then offset vertices);
    ``residual`` the RMS relative edge-length residual ``(|x_i − x_j| − ℓ_e) / ℓ_e`` of the result
    and ``max_residual`` its largest magnitude; ``initial_residual`` the same for the start;
    ``iterations`` the Levenberg–Marquardt iterations taken; ``initializer`` ``"hinge_frames"``,
    ``"initial_points"``, ``"reference_points"`` or ``"continuation"``; ``unresolved_choices``
    the hinges whose sign no star decided (hinge-frame start only: parts that the lengths leave
    flexible, e.g. a lifted vertex above a two-triangle boundary fan);
    ``components`` the connected components embedded independently.
    """

    points: np.ndarray
    n_base: int
    residual: float
    max_residual: float
    initial_residual: float
    iterations: int
    initializer: str
    unresolved_choices: int = 0
    components: int = 1
    converged: bool = True

    @property
    def base_vertices(self) -> np.ndarray:
        """The base layer, float64 ``(n, 3)``: the reconstructed pose (up to rigid motion)."""
        return self.points[: self.n_base]


# ---------------------------------------------------------------------------------------------
# Levenberg–Marquardt polish
# ---------------------------------------------------------------------------------------------


def _relative_residuals(x: np.ndarray, edges: np.ndarray, squared: np.ndarray):
    d = x[edges[:, 0]] - x[edges[:, 1]]
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    target = np.sqrt(squared)
    floor = np.finfo(float).tiny
    return (length - target) / np.maximum(target, floor)


#: Conjugate-gradient iterations per Gauss–Newton step (inexact Newton) and relative tolerance.
CG_ITERATIONS = 300
CG_TOLERANCE = 1e-4
#: Levenberg–Marquardt stops when an accepted step lowers the cost by less than this fraction.
STAGNATION = 1e-3


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
    # every call, and a transposed view made that a copy (+0.45 s on the 1k cloth's embedding).
    cofactors, det = cofactors_3x3(blocks)
    return cofactors / det[:, None, None]


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """Vector dot product without BLAS (multithreaded BLAS is slow for these sizes on a busy
    machine: measured 40× slower than a single-threaded loop under load)."""
    return float(np.einsum("i,i->", a, b))


def _pcg(apply_A, b, apply_M, iterations, tolerance):
    """Preconditioned conjugate gradients for an SPD operator (fixed small API, any SciPy)."""
    x = np.zeros_like(b)
    r = b.copy()
    z = apply_M(r)
    p = z.copy()
    rz = _dot(r, z)
    b_norm2 = _dot(b, b)
    if b_norm2 == 0:
        return x
    for _ in range(iterations):
        Ap = apply_A(p)
        pAp = _dot(p, Ap)
        if not pAp > 0:
            break
        alpha = rz / pAp
        x += alpha * p
        r -= alpha * Ap
        if _dot(r, r) <= tolerance * tolerance * b_norm2:
            break
        z = apply_M(r)
        rz_new = _dot(r, z)
        p *= rz_new / rz
        p += z
        rz = rz_new
    return x


def _levenberg_marquardt(x0, edges, squared, free, *, anchor_points=None, anchor_weight=0.0, length_scale=1.0,
                         tolerance=1e-12, max_iterations=DEFAULT_MAX_ITERATIONS, cg_iterations=CG_ITERATIONS):
    """Minimize ``Σ_e r_e² + (w / h²) Σ_v |x_v − a_v|²`` with ``r_e = (|x_i − x_j|² − ℓ²_e)/(2ℓ²_e)``.

    ``x0`` ``(N, 3)``; ``free`` bool ``(N,)`` points that move (the others stay); ``anchor_points``
    ``(N, 3)`` with NaN rows for unanchored points; ``length_scale`` ``h`` the mean edge length.
    Each step solves ``(JᵀJ + µI + A) δ = −g`` by block-Jacobi preconditioned CG (an inexact
    Newton step; SuperLU was measured 0.4–3 s per factorization already at 1k vertices). Returns
    ``(x, iterations, converged)``.
    """
    from scipy.sparse import bsr_matrix, coo_matrix

    N = x0.shape[0]
    index = np.full(N, -1, dtype=np.int64)
    index[free] = np.arange(int(free.sum()))
    nf = int(free.sum())
    use = (index[edges[:, 0]] >= 0) | (index[edges[:, 1]] >= 0)
    edges, squared = edges[use], squared[use]
    scale2 = np.maximum(squared, 1e-12 * max(float(np.mean(squared)) if squared.size else 1.0, np.finfo(float).tiny))
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
        r = (np.einsum("ij,ij->i", d, d) - squared) * inv
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
        rms = np.sqrt(np.mean(_relative_residuals(x, edges, squared) ** 2)) if edges.size else 0.0
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
        gg = np.einsum("ij,ij->i", g, g)
        mean_diag = float(2.0 * gg.sum() / max(3 * nf, 1) + anchor_diag.mean()) if nf else 1.0
        if mu is None:
            mu = 1e-6 * mean_diag
        floor = 1e-12 * mean_diag
        accepted = False
        for _ in range(10):
            damping = max(mu, floor)
            # Block-diagonal preconditioner as a BSR matrix: its product is 3× faster than an
            # einsum over the (nf, 3, 3) blocks (30 vs 100 µs at 4k points).
            preconditioner = bsr_matrix((_block_jacobi(ei, ej, g, nf, anchor_diag + damping), block_index,
                                         block_pointer), shape=(3 * nf, 3 * nf))
            diagonal = anchor_diag + damping

            def apply_A(v, diagonal=diagonal):
                return JT @ (J @ v) + diagonal * v

            step = -_pcg(apply_A, grad, preconditioner.__matmul__, cg_iterations, CG_TOLERANCE)
            trial = x.copy()
            trial[free] += step.reshape(-1, 3)
            new_cost, new_r, new_d = cost_of(trial)
            if np.isfinite(new_cost) and new_cost <= cost:
                improvement = cost - new_cost
                x, r, d = trial, new_r, new_d
                old_cost, cost = cost, new_cost
                mu = max(mu / 4.0, floor)
                accepted = True
                break
            mu = damping * 8.0
        if not accepted:
            converged = True  # no descent possible: a (local) minimum to working precision
            break
        if improvement <= STAGNATION * old_cost or np.abs(step).max() <= 1e-14 * length_scale:
            converged = True
            break
    return x, iterations, converged


# ---------------------------------------------------------------------------------------------
# public API
# ---------------------------------------------------------------------------------------------


def _check_lengths(squared, expected: int, what: str) -> np.ndarray:
    s = np.asarray(squared, dtype=np.float64).reshape(-1)
    if s.shape[0] != expected:
        raise RecoveryError(f"{what}: expected {expected} squared edge lengths, got {s.shape[0]}.")
    bad = np.flatnonzero(~np.isfinite(s) | (s < 0))
    if bad.size:
        e = int(bad[0])
        raise RecoveryError(
            f"{what}: squared edge length {e} is {s[e]!r} ({bad.size} negative or non-finite in all), so "
            "no embedding exists. The recovered metric is invalid: check the shape differences (a "
            "truncated basis that is too small, or an interpolation factor far outside [0, 1])."
        )
    return s


def _anchor_array(anchor, n_points: int, n_base: int):
    if anchor is None:
        return None, 0.0
    positions, weight = anchor
    a = np.asarray(positions, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] not in (n_points, n_base):
        raise RecoveryError(f"anchor positions must have shape ({n_points}, 3) or ({n_base}, 3); got {a.shape}.")
    weight = float(weight)
    if not np.isfinite(weight) or weight < 0:
        raise RecoveryError(f"anchor weight must be a non-negative number; got {weight!r}.")
    out = np.full((n_points, 3), np.nan)
    out[: a.shape[0]] = a
    return out, weight


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values * values))) if values.size else 0.0


def _finish(x, edges, squared, n_base, x_start, iterations, initializer, converged, components=1,
            unresolved=0):
    rel = _relative_residuals(x, edges, squared) if edges.size else np.zeros(1)
    rel0 = _relative_residuals(x_start, edges, squared) if edges.size else np.zeros(1)
    if not np.isfinite(x).all():
        raise RecoveryError("The embedding produced non-finite positions; the edge lengths are inconsistent.")
    return EmbeddingResult(
        points=x,
        n_base=n_base,
        residual=float(np.sqrt(np.mean(rel * rel))),
        max_residual=float(np.abs(rel).max()),
        initial_residual=float(np.sqrt(np.mean(rel0 * rel0))),
        iterations=int(iterations),
        initializer=initializer,
        unresolved_choices=unresolved,
        components=components,
        converged=converged,
    )


def _components(n_points: int, edges: np.ndarray) -> tuple[int, np.ndarray]:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(edges.shape[0]), (edges[:, 0], edges[:, 1])), shape=(n_points, n_points))
    return connected_components(graph, directed=False)


def _align_components(x, reference, labels, active):
    """Rigidly move each component of ``x`` onto ``reference`` (rows with finite reference)."""
    from .rigid_alignment import rigid_alignment

    out = x.copy()
    for label in np.unique(labels[active]):
        rows = (labels == label) & active
        ok = rows & np.isfinite(reference).all(axis=1)
        if ok.sum() >= 3:
            R, t = rigid_alignment(x[ok], reference[ok])
            out[rows] = x[rows] @ R.T + t
    return out


def embed_thickening(
    surface: OffsetSurface,
    squared_lengths: np.ndarray,
    *,
    initial_points: np.ndarray | None = None,
    reference_points: np.ndarray | None = None,
    anchor: tuple[np.ndarray, float] | None = None,
    tolerance: float = 1e-8,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
) -> EmbeddingResult:
    """Positions of the canonical thickening (§5.3) realizing ``squared_lengths`` (§7.3).

    ``squared_lengths`` float ``(K,)`` for :attr:`OffsetSurface.thickening_edges` (base edges,
    offset edges, normal edges, side edges). Returns an :class:`EmbeddingResult` with ``points``
    ``(n + n_offset, 3)``; ``base_vertices`` (its first ``n`` rows) is the pose, up to rigid motion.

    - ``initial_points`` ``(n + n_offset, 3)`` warm start (a linear blend of poses, the previous
      frame): skips the hinge frames; the fit converges to the nearest least-squares
      solution, which may be a mirror-folded one if the start is far off.
    - ``reference_points`` ``(n + n_offset, 3)``: a plausible pose (the base shape's thickening)
      raced against the hinge frames as a start when the lengths are inexact (see
      :data:`START_TRIAL_ITERATIONS`), and deformed gradually into the target lengths when the
      best fit stays far from them (:data:`CONTINUATION_RESIDUAL`); ignored with
      ``initial_points`` or exact lengths.
    - ``anchor = (positions, weight)``: positions ``(n + n_offset, 3)`` or ``(n, 3)`` (then only
      base vertices are anchored); adds ``weight · Σ_v |x_v − a_v|² / h²`` to the least-squares
      objective, ``h`` the mean edge length from ``squared_lengths``: the weight is dimensionless,
      ``weight = 1`` makes a displacement of one mean edge length cost as much as a 100% length
      error on one edge. Exact lengths are then no longer reproduced exactly. Without
      ``initial_points`` the start is first moved rigidly onto the anchor (per component).
    - ``tolerance``: skip / stop the polish when the RMS relative length residual is below it
      (default 1e-8: the hinge frames on exact data are at ~1e-12, far below the 1e-6
      accuracy needed);
      ``max_iterations``: cap on Levenberg–Marquardt iterations.

    Each connected component is embedded independently (its placement relative to the others is
    unknowable). Loose base vertices (no edge) are returned at the anchor, else the initial point,
    else the origin. Raises :class:`RecoveryError` for lengths of the wrong size, negative or
    non-finite; warns (:class:`ShapeDifferenceWarning`) if the fit did not converge.
    """
    edges = surface.thickening_edges
    n_points = surface.n_thickening_points
    n_base = surface.base.n_vertices
    squared = _check_lengths(squared_lengths, edges.shape[0], "embed_thickening")
    anchor_points, anchor_weight = _anchor_array(anchor, n_points, n_base)
    has_edge = np.zeros(n_points, dtype=bool)
    has_edge[edges.ravel()] = True
    n_comp, labels = _components(n_points, edges)
    n_comp_real = int(np.unique(labels[has_edge]).size)
    length_scale = float(np.mean(np.sqrt(squared))) if squared.size else 1.0

    fallback = np.zeros((n_points, 3))
    continuation_start = None
    if initial_points is not None:
        x0 = np.array(initial_points, dtype=np.float64)
        if x0.shape != (n_points, 3) or not np.isfinite(x0).all():
            raise RecoveryError(f"initial_points must be finite with shape ({n_points}, 3); got {x0.shape}.")
        fallback = x0.copy()
        starts = [("initial_points", x0)]
    if initial_points is None:
        from .hinge_frames import hinge_frame_embedding

        frames = hinge_frame_embedding(surface, squared)
        x0, frames_rms = frames.points, _rms(_relative_residuals(frames.points, edges, squared))
        starts = [("hinge_frames", x0)]
        if not frames_rms <= max(tolerance, FRAMES_NEARLY_EXACT):
            # Inexact lengths: fit the frames to all hinges at once rather than chain them.
            synchronized = frames.synchronized()
            if _rms(_relative_residuals(synchronized, edges, squared)) < frames_rms:
                starts = [("hinge_frames", synchronized)]
            if reference_points is not None:
                reference = np.array(reference_points, dtype=np.float64)
                if reference.shape != (n_points, 3) or not np.isfinite(reference).all():
                    raise RecoveryError(
                        f"reference_points must be finite with shape ({n_points}, 3); got {reference.shape}."
                    )
                starts.append(("reference_points", reference))
                continuation_start = reference
    if anchor_points is not None:
        fallback = np.where(np.isfinite(anchor_points), anchor_points, fallback)

    def polish(start, budget):
        x, iterations, converged = _polish(start, edges, squared, has_edge, anchor_points, anchor_weight,
                                           length_scale, tolerance, budget)
        return [_rms(_relative_residuals(x, edges, squared)), x, iterations, converged]

    def finish(trial):
        """Polish a trial to the end (the remaining iteration budget)."""
        residual, x, iterations, converged = trial
        if converged or iterations >= max_iterations:
            return trial
        rest = polish(x, max_iterations - iterations)
        rest[2] += iterations
        return rest

    def prepared(start):
        if anchor_points is not None and initial_points is None:
            start = _align_components(start, anchor_points, labels, has_edge)
        start[~has_edge] = fallback[~has_edge]
        return start

    # Several starts are raced: a short trial each, the lowest residual goes on to the end.
    budget = min(START_TRIAL_ITERATIONS, max_iterations) if len(starts) > 1 else max_iterations
    trials = [(name, prepared(start), None) for name, start in starts]
    fits = _concurrently(lambda item: polish(item[1], budget), trials)
    trials = [item + (fit,) for item, fit in zip(trials, fits)]
    best = min(trials, key=lambda item: item[3][0])
    best = best[:3] + (finish(best[3]),)
    if continuation_start is not None and best[3][0] > CONTINUATION_RESIDUAL:
        # Far from realizable: the fit stopped in the basin of its start. Deform the reference
        # pose gradually instead (its own lengths blended into the targets) and keep the better.
        def continued(schedule):
            fractions, steps = schedule
            x = _continuation(prepared(continuation_start.copy()), edges, squared, has_edge, anchor_points,
                              anchor_weight, length_scale, tolerance, fractions, steps)
            return polish(x, max_iterations)

        for trial in _concurrently(continued, CONTINUATION_SCHEDULES):
            if trial[0] < best[3][0]:
                best = ("continuation", continuation_start, None, trial)
    initializer, x0, greedy, (_, x, iterations, converged) = best
    if not converged:
        _warn_unconverged(x, edges, squared, iterations)
    unresolved = frames.unresolved if initializer == "hinge_frames" else 0
    return _finish(x, edges, squared, n_base, x0, iterations, initializer, converged, n_comp_real,
                   unresolved=unresolved)


def _polish(x0, edges, squared, free, anchor_points, anchor_weight, length_scale, tolerance, max_iterations):
    rel = _relative_residuals(x0, edges, squared)
    if (np.sqrt(np.mean(rel * rel)) <= tolerance and not anchor_weight) or max_iterations <= 0:
        return x0, 0, True
    x, iterations, converged = _levenberg_marquardt(
        x0, edges, squared, free, anchor_points=anchor_points, anchor_weight=anchor_weight,
        length_scale=length_scale, tolerance=tolerance, max_iterations=max_iterations,
    )
    return x, iterations, converged


def _warn_unconverged(x, edges, squared, iterations):
    """The public embedders' warning for a fit that stopped before converging."""
    warnings.warn(
        f"Embedding: Levenberg–Marquardt stopped after {iterations} iterations without converging "
        f"(RMS relative length residual {_rms(_relative_residuals(x, edges, squared)):.3g}); the result "
        "is the best fit found. Increase max_iterations or check the recovered lengths.",
        ShapeDifferenceWarning,
        stacklevel=3,
    )


def _concurrently(function, items) -> list:
    """``[function(item) for item in items]``, in threads when there are several items and
    cores. For independent Levenberg–Marquardt fits: their sparse products and NumPy array
    arithmetic release the GIL (2 cores, truncated k = 100 / 200 lengths: embedding the 1,089-vertex
    cloth 2.4–2.6 → 2.2 s, a Blender flag 40 → 48 with its continuations 10.6 → 8.1–8.4 s). The
    results do not depend on it."""
    items = list(items)
    workers = min(len(items), os.cpu_count() or 1)
    if workers < 2:
        return [function(item) for item in items]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(workers) as pool:
        return list(pool.map(function, items))


def _continuation(x, edges, squared, free, anchor_points, anchor_weight, length_scale, tolerance, fractions,
                  iterations):
    """Deform ``x`` ``(N, 3)`` gradually towards ``squared``: ``iterations`` LM steps on its own
    squared lengths blended into the targets by each of ``fractions`` (the full step is the
    caller's)."""
    d = x[edges[:, 0]] - x[edges[:, 1]]
    own = np.einsum("ij,ij->i", d, d)
    for fraction in fractions:  # intermediate steps are capped: not converging there is expected
        x, _, _ = _polish(x, edges, (1.0 - fraction) * own + fraction * squared, free, anchor_points,
                          anchor_weight, length_scale, tolerance, iterations)
    return x


def embed_base_edges(
    topology: MeshTopology,
    squared_lengths: np.ndarray,
    *,
    initial_vertices: np.ndarray,
    anchor: tuple[np.ndarray, float] | None = None,
    tolerance: float = 1e-8,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
) -> EmbeddingResult:
    """Intrinsic-only embedding (no offset layer): vertex positions ``(n, 3)`` whose edge lengths
    fit ``squared_lengths`` ``(E,)`` (for ``topology.edges``) in least squares, by
    Levenberg–Marquardt from ``initial_vertices`` ``(n, 3)``.

    Edge lengths alone do not determine the extrinsic shape (isometric bending, popping of
    vertices): the result is the fit nearest the start, not necessarily the original pose.
    ``anchor`` as in :func:`embed_thickening`. Loose vertices stay at their initial positions.
    """
    squared = _check_lengths(squared_lengths, topology.n_edges, "embed_base_edges")
    x0 = np.array(initial_vertices, dtype=np.float64)
    if x0.shape != (topology.n_vertices, 3) or not np.isfinite(x0).all():
        raise RecoveryError(f"initial_vertices must be finite with shape ({topology.n_vertices}, 3); got {x0.shape}.")
    anchor_points, anchor_weight = _anchor_array(anchor, topology.n_vertices, topology.n_vertices)
    edges = topology.edges
    free = np.zeros(topology.n_vertices, dtype=bool)
    free[edges.ravel()] = True
    length_scale = float(np.mean(np.sqrt(squared))) if squared.size else 1.0
    x, iterations, converged = _polish(x0, edges, squared, free, anchor_points, anchor_weight, length_scale,
                                        tolerance, max_iterations)
    if not converged:
        _warn_unconverged(x, edges, squared, iterations)
    return _finish(x, edges, squared, topology.n_vertices, x0, iterations, "initial_points", converged)


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
    x, _, _ = _levenberg_marquardt(x0, edges, squared, free, anchor_points=x0, anchor_weight=anchor_weight,
                                   length_scale=length_scale, max_iterations=max_iterations,
                                   cg_iterations=cg_iterations)
    return x
