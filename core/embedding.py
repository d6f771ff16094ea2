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
2. **Fit** (:mod:`core.edge_length_fit`, only if the RMS relative residual exceeds
   ``tolerance``): Levenberg–Marquardt on the relative length residuals.
3. **Continuation** when the best fit stays far from realizable: the reference pose deformed
   gradually into the target lengths.

With inexact lengths (truncated or interpolated differences) the result is a least-squares fit
and :attr:`EmbeddingResult.residual` reports how far from realizable the lengths were.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .concurrency import concurrently
from .edge_length_fit import (DEFAULT_MAX_ITERATIONS, DEFAULT_TOLERANCE, INITIAL_DAMPING, STAGNATION, EdgeLengthFit,
                              Fit, relative_residuals, rms)
from .errors import RecoveryError, warn
from .geometry import connected_components
from .hinge_frames import hinge_frame_embedding
from .mesh_topology import MeshTopology
from .offset_surface import OffsetSurface
from .rigid_alignment import align_components

# Measurements behind every constant: docs/design-decisions.md.
#: Hinge-frame starts with an RMS relative residual below this are exact lengths up to
#: round-off: no race, straight to the (usually skipped) polish.
FRAMES_NEARLY_EXACT = 1e-6
#: With inexact lengths the starts are fitted for this many Levenberg–Marquardt iterations each
#: and only the best goes on to the end (the hinge frames fold where hinge signs are noisy; the
#: reference pose does not, but may fit worse on smooth poses).
START_TRIAL_ITERATIONS = 3
#: When the best fit's RMS relative residual stays above this, the reference pose is also
#: deformed gradually into the target lengths and the lowest residual wins; each schedule is
#: (fractions of the way, LM iterations per fraction), raced, then fitted to the end.
CONTINUATION_RESIDUAL = 2e-2
CONTINUATION_SCHEDULES = (((0.25, 0.5, 0.75), 4), (tuple(np.arange(1, 8) / 8), 3))


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


def _finish(x, edges, squared, n_base, x_start, iterations, initializer, converged, components=1,
            unresolved=0):
    rel = relative_residuals(x, edges, squared) if edges.size else np.zeros(1)
    rel0 = relative_residuals(x_start, edges, squared) if edges.size else np.zeros(1)
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


def embed_thickening(
    surface: OffsetSurface,
    squared_lengths: np.ndarray,
    *,
    initial_points: np.ndarray | None = None,
    reference_points: np.ndarray | None = None,
    anchor: tuple[np.ndarray, float] | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    continuation: bool = True,
    initial_damping: float = INITIAL_DAMPING,
    stagnation: float = STAGNATION,
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
      best fit stays far from them (:data:`CONTINUATION_RESIDUAL`; ``continuation=False``
      skips that, e.g. when the reference is a nearby pose already); ignored with
      ``initial_points`` or exact lengths.
    - ``anchor = (positions, weight)``: positions ``(n + n_offset, 3)`` or ``(n, 3)`` (then only
      base vertices are anchored); adds ``weight · Σ_v |x_v − a_v|² / h²`` to the least-squares
      objective, ``h`` the mean edge length from ``squared_lengths``: the weight is dimensionless,
      ``weight = 1`` makes a displacement of one mean edge length cost as much as a 100% length
      error on one edge. Exact lengths are then no longer reproduced exactly. Without
      ``initial_points`` the start is first moved rigidly onto the anchor (per component).
    - ``tolerance``: skip / stop the polish when the RMS relative length residual is below it
      (:data:`~core.edge_length_fit.DEFAULT_TOLERANCE`: the hinge frames on exact data are at
      ~1e-12, far below it);
      ``max_iterations``: cap on Levenberg–Marquardt iterations; ``initial_damping``: its first
      damping, ``stagnation``: the relative cost decrease below which it stops
      (:func:`~core.edge_length_fit.levenberg_marquardt`).

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
    _, labels = connected_components(n_points, edges)
    n_comp_real = int(np.unique(labels[has_edge]).size)
    length_scale = float(np.mean(np.sqrt(squared))) if squared.size else 1.0

    problem = EdgeLengthFit(edges, squared, has_edge, anchor_points, anchor_weight, length_scale, tolerance,
                            initial_damping, stagnation)

    fallback = np.zeros((n_points, 3))
    continuation_start = None
    if initial_points is not None:
        x0 = np.array(initial_points, dtype=np.float64)
        if x0.shape != (n_points, 3) or not np.isfinite(x0).all():
            raise RecoveryError(f"initial_points must be finite with shape ({n_points}, 3); got {x0.shape}.")
        fallback = x0.copy()
        starts = [_Start("initial_points", x0)]
    else:
        frames = hinge_frame_embedding(surface, squared)
        x0, frames_rms = frames.points, problem.residual(frames.points)
        starts = [_Start("hinge_frames", x0)]
        if not frames_rms <= max(tolerance, FRAMES_NEARLY_EXACT):
            # Inexact lengths: fit the frames to all hinges at once rather than chain them.
            synchronized = frames.synchronized()
            if problem.residual(synchronized) < frames_rms:
                starts = [_Start("hinge_frames", synchronized)]
            if reference_points is not None:
                reference = np.array(reference_points, dtype=np.float64)
                if reference.shape != (n_points, 3) or not np.isfinite(reference).all():
                    raise RecoveryError(
                        f"reference_points must be finite with shape ({n_points}, 3); got {reference.shape}."
                    )
                starts.append(_Start("reference_points", reference))
                continuation_start = reference if continuation else None
    if anchor_points is not None:
        fallback = np.where(np.isfinite(anchor_points), anchor_points, fallback)

    def prepared(start):
        if anchor_points is not None and initial_points is None:
            start = align_components(start, anchor_points, labels, active=has_edge)
        start[~has_edge] = fallback[~has_edge]
        return start

    # Several starts are raced: a short trial each, the lowest residual goes on to the end.
    budget = min(START_TRIAL_ITERATIONS, max_iterations) if len(starts) > 1 else max_iterations
    candidates = [_Start(start.name, prepared(start.points)) for start in starts]
    trials = concurrently(lambda start: problem.fit(start.points, budget), candidates)
    best_start, best_trial = min(zip(candidates, trials), key=lambda pair: pair[1].residual)
    best = _Embedded(best_start, problem.resume(best_trial, max_iterations))
    if continuation_start is not None and best.fit.residual > CONTINUATION_RESIDUAL:
        # Far from realizable: the fit stopped in the basin of its start. Deform the reference
        # pose gradually instead (its own lengths blended into the targets) and keep the better.
        def continued(schedule):
            fractions, steps = schedule
            x = problem.continuation(prepared(continuation_start.copy()), fractions, steps)
            return problem.fit(x, max_iterations)

        for trial in concurrently(continued, CONTINUATION_SCHEDULES):
            if trial.residual < best.fit.residual:
                best = _Embedded(_Start("continuation", continuation_start), trial)
    fit = best.fit
    if not fit.converged:
        _warn_unconverged(fit.points, edges, squared, fit.iterations)
    unresolved = frames.unresolved if best.start.name == "hinge_frames" else 0
    return _finish(fit.points, edges, squared, n_base, best.start.points, fit.iterations, best.start.name,
                   fit.converged, n_comp_real, unresolved=unresolved)


@dataclass(frozen=True, eq=False)
class _Start:
    """A start of the fit: ``name`` (the result's ``initializer``) and ``points`` ``(N, 3)``."""

    name: str
    points: np.ndarray


@dataclass(frozen=True, eq=False)
class _Embedded:
    """The chosen start and the fit from it."""

    start: _Start
    fit: Fit


def _warn_unconverged(x, edges, squared, iterations):
    """The public embedders' warning for a fit that stopped before converging."""
    warn(
        f"The pose's edges miss the recovered lengths by {rms(relative_residuals(x, edges, squared)):.3g} "
        "(RMS, relative) in the best fit found: check the result, or raise max_iterations (the embedding's "
        f"Levenberg–Marquardt stopped after {iterations} iterations without converging).",
        "fit",
    )


def embed_base_edges(
    topology: MeshTopology,
    squared_lengths: np.ndarray,
    *,
    initial_vertices: np.ndarray,
    anchor: tuple[np.ndarray, float] | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    initial_damping: float = INITIAL_DAMPING,
    stagnation: float = STAGNATION,
) -> EmbeddingResult:
    """Intrinsic-only embedding (no offset layer): vertex positions ``(n, 3)`` whose edge lengths
    fit ``squared_lengths`` ``(E,)`` (for ``topology.edges``) in least squares, by
    Levenberg–Marquardt from ``initial_vertices`` ``(n, 3)``.

    Edge lengths alone do not determine the extrinsic shape (isometric bending, popping of
    vertices): the result is the fit nearest the start, not necessarily the original pose.
    ``anchor``, ``initial_damping`` and ``stagnation`` as in :func:`embed_thickening`. Loose vertices stay at their initial positions.
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
    problem = EdgeLengthFit(edges, squared, free, anchor_points, anchor_weight, length_scale, tolerance,
                            initial_damping, stagnation)
    fit = problem.fit(x0, max_iterations)
    if not fit.converged:
        _warn_unconverged(fit.points, edges, squared, fit.iterations)
    return _finish(fit.points, edges, squared, topology.n_vertices, x0, fit.iterations, "initial_points", fit.converged)
