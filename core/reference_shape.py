"""The base shape M prepared once (paper §6–7): everything that depends only on M — topology,
inner products, the offset surface M_t, factorizations, eigenbases — computed on first use and
reused for every target pose, frame and in-between.

A :class:`SurfaceLayer` is one of the two meshes the four differences live on: the base M
(intrinsic differences) or its offset M_t (extrinsic differences, §5.2). :class:`ReferenceShape`
holds both, turns target poses into :class:`ShapeDifferences` and back into recovered metrics and
embeddings.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .cached_property import cached_property
from .concurrency import per_layer_threads
from .errors import MeshError, warn
from .full_basis_recovery import AreaRecovery, recover_squared_lengths
from .geometry import vertex_labels
from .inner_products import ProductAssembler, pose_products
from .laplace_basis import (LaplaceBasis, cached_split_group, checked_laplace_basis, split_warning,
                           warn_eigenvalue_split)
from .mesh_topology import MeshTopology, check_vertices, mesh_topology
from .offset_surface import OffsetSurface, check_offset_pose, default_offset, offset_surface
from .rigid_alignment import align_components
from .seam_gluing import glue_along_seams, seam_twins
from .seam_welds import weld_advice
from .shape_difference import (
    FullDifference,
    ReducedDifference,
    functional_map_differences,
    reduced_differences,
)
from .truncated_recovery import TruncatedRecovery, recover_truncated_metric
from .validation import check_basis_sizes, check_flag, check_offset, check_triangles
from .working_unit import working_unit


#: Shape differences warn when round-off alone may change recovered squared edge lengths by
#: more than this (relative). The cotangent weights of eq. (2), (ℓ_k² − ℓ_i² − ℓ_j²)/(8µ), cancel
#: terms of size ℓ²_max(T) to resolve ℓ²_min(T) and 2µ(T), so they lose a factor
#: κ_T = ℓ²_max / min(ℓ²_min, 2µ) of precision (measured: one vertex of a 0.2-edge sheet pulled
#: 1e6 away, κ ≈ 2.5e13, recovered squared lengths 1e-3 off in the full basis; 1e3 away, 1e-8).
PRECISION_TOLERANCE = 1e-4
#: The extrinsic differences stay accurate for offsets between these multiples of the mean edge
#: length (thickening lengths are t² + O(ℓ²): far above, the edge information drowns in t²'s
#: round-off; far below, the offset surface's lengths differ from the base's at round-off).
OFFSET_RANGE = (1e-3, 1e3)


@dataclass(frozen=True, eq=False)
class LayerMetric:
    """Intrinsic metric of one layer of one pose: areas µ ``(m,)`` and squared lengths ℓ² ``(E,)``."""

    areas: np.ndarray
    squared_lengths: np.ndarray


class SurfaceLayer:
    """One mesh (M or M_t) with its reference pose: products, factorizations and eigenbases."""

    def __init__(self, name: str, topology: MeshTopology, positions: np.ndarray):
        self.name = name
        self.topology = topology
        self.positions = positions
        self.assembler = ProductAssembler(topology)
        self.areas, self.squared_lengths, self.mass, self.conformal = pose_products(self.assembler, positions)
        self._bases: dict[int, LaplaceBasis] = {}
        self._truncated_solvers: dict[int, TruncatedRecovery] = {}
        self._groups: dict[int, tuple[int, int] | None] = {}

    @property
    def metric(self) -> LayerMetric:
        return LayerMetric(self.areas, self.squared_lengths)

    @cached_property
    def area_recovery(self) -> AreaRecovery:
        """Prop. 1's factorization for this layer (full basis), built on first use."""
        return AreaRecovery(self.assembler)

    def truncated_solver(self, basis: LaplaceBasis) -> TruncatedRecovery:
        """The programs (8) and (10) of this layer for ``basis`` (cached per basis size):
        everything that depends only on the reference layer and the basis is computed once."""
        solver = self._truncated_solvers.get(basis.size)
        if solver is None or not (
            solver.basis is basis or np.array_equal(solver.basis.functions, basis.functions)
        ):
            solver = TruncatedRecovery(self, basis)
            self._truncated_solvers[basis.size] = solver
        return solver

    def basis(self, k: int) -> LaplaceBasis:
        """The first ``k`` eigenpairs of this layer's reference pose (cached; a larger cached
        basis is truncated rather than recomputed; computed with :func:`checked_laplace_basis`'s
        few more, for :meth:`split_group`)."""
        larger = [size for size in self._bases if size >= k]
        if not larger:
            computed, self._groups[k] = checked_laplace_basis(self.mass, self.conformal, k, what=self.name)
            self._bases[computed.size] = computed
            larger = [computed.size]
        cached = self._bases[min(larger)]
        if cached.size != k:
            cached = self._bases[k] = LaplaceBasis(cached.eigenvalues[:k], cached.functions[:, :k])
        return cached

    def split_group(self, k: int) -> tuple[int, int] | None:
        """:func:`~core.laplace_basis.split_group` of this layer's eigenvalues at a basis size ``k``
        (computing the eigenpairs it needs)."""
        if k not in self._groups:
            self._groups[k] = cached_split_group(
                self._bases, k, self.topology.n_vertices,
                lambda size: checked_laplace_basis(self.mass, self.conformal, size, what=self.name))
        return self._groups[k]

    def differences(self, target_positions: np.ndarray, k_M: int | None, k_N: int | None, *,
                    smallest: int = 2):
        """Area and conformal differences from this layer's reference to a target pose of it. Warns
        where ``k_M`` or ``k_N`` splits a group of equal eigenvalues of the reference or the target
        (:func:`~core.laplace_basis.split_group`; ``smallest``: the smallest basis size allowed)."""
        _, _, mass, conformal = pose_products(self.assembler, target_positions)
        if k_M is None:
            return FullDifference("area", self.mass, mass), FullDifference("conformal", self.conformal, conformal)
        base_basis = self.basis(k_M)
        if k_N is None:
            return reduced_differences(base_basis, mass, conformal)
        target_basis, _ = checked_laplace_basis(mass, conformal, k_N, what=f"target {self.name}")
        warn_eigenvalue_split("k_N", k_N, [(f"target pose's {self.name}", target_basis.eigenvalues)],
                              max(k_M, smallest), self.topology.n_vertices)
        if target_basis.size != k_N:
            target_basis = LaplaceBasis(target_basis.eigenvalues[:k_N], target_basis.functions[:, :k_N])
        return functional_map_differences(base_basis, target_basis, mass)

    def recover(self, area_difference, conformal_difference, warm: dict | None = None,
                tolerance: float | None = None, rho_scale: float | None = None) -> LayerMetric:
        """Areas and squared lengths of the target from its two differences: linear solves in the
        full basis (Props. 1–2), convex programs when truncated (§7.1–7.2; ``warm``: the
        warm-start record of a pose sequence, ``tolerance`` the iterative solvers', ``rho_scale`` ADMM's
        initial penalty, see
        :func:`~core.truncated_recovery.recover_truncated_metric`)."""
        if isinstance(area_difference, FullDifference):
            _, area_edge_values = area_difference.product_entries(self.assembler)
            areas = self.area_recovery.solve(area_edge_values)
            _, edge_values = conformal_difference.product_entries(self.assembler)
            squared = recover_squared_lengths(
                self.assembler, areas, edge_values, reference_squared_lengths=self.squared_lengths,
                what=f"target pose ({self.name} layer)",
            )
            return LayerMetric(areas, squared)
        solver = self.truncated_solver(area_difference.basis)
        return LayerMetric(*recover_truncated_metric(solver, area_difference, conformal_difference, warm,
                                                   tolerance, rho_scale))


def _recover_layers(jobs) -> list[LayerMetric]:
    """``layer.recover(area, conformal, warm, tolerance, rho_scale)`` for every ``(layer, area,
    conformal, warm, tolerance, rho_scale)`` of ``jobs``: truncated programs of two layers concurrently
    (:func:`per_layer_threads`), in the full basis (sparse LU solves) one after the other."""
    calls = [lambda job=job: job[0].recover(*job[1:]) for job in jobs]
    return per_layer_threads(calls, parallel=not isinstance(jobs[0][1], FullDifference))


@dataclass(frozen=True, eq=False)
class ShapeDifferences:
    """The four shape differences of a target N relative to a base M (§6).

    ``area``/``conformal``: intrinsic (on M); ``offset_area``/``offset_conformal``: extrinsic (on
    the offset surface M_t at distance ``offset``), ``None`` when ``use_extrinsic`` is off. Each is
    a :class:`~core.shape_difference.FullDifference` (``k_M is None``) or a
    :class:`~core.shape_difference.ReducedDifference`. ``reference`` is the prepared base, reused
    by :func:`core.reconstruct`.
    """

    area: FullDifference | ReducedDifference
    conformal: FullDifference | ReducedDifference
    offset_area: FullDifference | ReducedDifference | None
    offset_conformal: FullDifference | ReducedDifference | None
    offset: float
    k_M: int | None
    k_N: int | None
    reference: "ReferenceShape" = field(repr=False)

    @property
    def use_extrinsic(self) -> bool:
        return self.offset_area is not None


@dataclass(frozen=True, eq=False)
class RecoveredMetric:
    """Recovered intrinsic metric of the target and, when extrinsic, of its offset surface."""

    base: LayerMetric
    offset: LayerMetric | None


class ReferenceShape:
    """The base mesh M, validated and prepared once for many targets.

    ``vertices`` float64 ``(n, 3)``, ``triangles`` int ``(m, 3)``; ``offset`` the distance t of
    the offset surface (``None``: :func:`default_offset`, half the mean edge length);
    ``use_extrinsic`` builds the offset layer. Loose vertices (in no triangle) are allowed: they
    are left out of every computation and kept in place in results. ``name``: what error messages
    call the vertices (an operator passes the pose's name).

    Units: the base is worked on scaled by :attr:`unit`, the power of two
    :func:`~core.working_unit.working_unit` picks from its extent (1 for a base of ~1e-3 to 1e3
    units; ``unit``: a given one, 1.0 for positions already scaled), so the single-precision parts of
    the truncated recovery stay in range whatever the caller's units. Everything prepared here
    (:attr:`base_positions`, :attr:`offset`, the layers, recovered metrics, embeddings) is in those
    working units; :meth:`compact_pose` takes a pose in the caller's units to them and
    :meth:`expand_pose` brings one back, both exactly. :attr:`vertices`, :attr:`given_positions`,
    :attr:`given_offset` and every message are in the caller's units.
    """

    def __init__(self, vertices, triangles, *, offset: float | None = None, use_extrinsic: bool = True,
                 name: str = "base vertices", unit: float | None = None):
        offset, use_extrinsic = check_offset(offset), check_flag(use_extrinsic, "use_extrinsic")
        vertices = check_vertices(vertices, name=name)
        full_topology = mesh_topology(triangles, vertices.shape[0])
        self.n_vertices = vertices.shape[0]
        self.vertices = vertices
        self.used_vertices = full_topology.used_vertices
        compact_index = np.full(self.n_vertices, -1, dtype=np.int64)
        compact_index[self.used_vertices] = np.arange(self.used_vertices.size)
        topology = (
            full_topology
            if self.used_vertices.size == self.n_vertices
            else mesh_topology(compact_index[full_topology.triangles], self.used_vertices.size)
        )
        self.topology = topology
        self.triangles = full_topology.triangles
        self._full_topology = full_topology  # poses are checked in the user's numbering
        base_positions = full_topology.check_pose(vertices, name=name)[self.used_vertices]
        self.unit = working_unit([base_positions]) if unit is None else float(unit)
        if self.unit != 1.0:
            base_positions = base_positions * self.unit
        self.offset = float(default_offset(base_positions, topology.triangles) if offset is None
                            else offset * self.unit)
        if not (np.isfinite(self.offset) and self.offset > 0):
            raise MeshError(f"The offset distance t must be a positive number; got {offset!r}.")
        self.base = SurfaceLayer("base mesh", topology, base_positions)
        self.surface: OffsetSurface | None = None
        self.offset_layer: SurfaceLayer | None = None
        if use_extrinsic:
            try:
                self.surface = offset_surface(topology)
            except MeshError as error:  # no edge shared by two triangles: say to weld where faces touch
                advice = weld_advice(self.given_positions, topology)
                if not advice:
                    raise
                raise MeshError(f"{error}{advice}") from None
            self.offset_layer = SurfaceLayer(
                "offset surface", self.surface.topology, self.surface.positions(base_positions, self.offset)
            )

    @property
    def use_extrinsic(self) -> bool:
        return self.offset_layer is not None

    def matches(self, vertices, triangles) -> bool:
        """True if ``(vertices, triangles)`` is exactly the mesh this reference was built from."""
        v, t = np.asarray(vertices), np.asarray(triangles)
        return v.shape == self.vertices.shape and t.shape == self.triangles.shape and np.array_equal(
            v, self.vertices
        ) and np.array_equal(t, self.triangles)

    @property
    def given_offset(self) -> float:
        """The offset distance t in the caller's units (:attr:`offset` is in the working units)."""
        return self.offset if self.unit == 1.0 else self.offset / self.unit

    def compact_pose(self, vertices, *, name: str = "target vertices") -> np.ndarray:
        """Validate a pose ``(n, 3)`` of this mesh in the caller's units and return its used
        vertices ``(n_used, 3)`` in the working units (× :attr:`unit`)."""
        compact = self._full_topology.check_pose(vertices, name=name)[self.used_vertices]
        return compact if self.unit == 1.0 else compact * self.unit

    def expand_pose(self, compact: np.ndarray, loose_positions: np.ndarray | None = None) -> np.ndarray:
        """Scatter used-vertex positions ``(n_used, 3)`` in the working units back to ``(n, 3)`` in
        the caller's units; loose vertices take ``loose_positions`` (the caller's units; default:
        the base pose)."""
        out = np.array(self.vertices if loose_positions is None else loose_positions, dtype=np.float64)
        out[self.used_vertices] = compact if self.unit == 1.0 else compact / self.unit
        return out

    def basis_sizes(self, k_M, k_N, *, full_basis: bool = True) -> tuple[int | None, int | None]:
        """``k_M``, ``k_N`` normalized and checked against this mesh: below its vertex count (in
        triangles), above its number of connected parts (:func:`core.validation.check_basis_sizes`;
        ``full_basis=False`` where a truncated ``k_M`` is needed)."""
        return check_basis_sizes(k_M, k_N, int(self.used_vertices.size), self.topology.components()[0],
                                 full_basis=full_basis, geometry=(self.given_positions, self.topology))

    def shape_differences(self, target_vertices, *, k_M: int | None = None, k_N: int | None = None,
                          name: str = "target vertices") -> ShapeDifferences:
        """The four differences (§6) of a target pose ``(n, 3)`` (the caller's units) relative to
        this base (``name``: what error messages call the pose). Warns
        (:class:`ShapeDifferenceWarning`) where they cannot represent the pose faithfully
        (:meth:`check_faithful`) and where the offset is outside :data:`OFFSET_RANGE` × the mean
        edge length."""
        k_M, k_N = self.basis_sizes(k_M, k_N)
        target = self.compact_pose(target_vertices, name=name)
        self.check_faithful(target, name)
        if self.use_extrinsic:
            self._warn_offset_scale()
        smallest = self.topology.components()[0] + 1
        if k_M is not None:
            self.warn_split(k_M)
        area, conformal = self.base.differences(target, k_M, k_N, smallest=smallest)
        offset_area = offset_conformal = None
        if self.use_extrinsic:
            offset_target = self.surface.positions(target, self.offset)
            offset_area, offset_conformal = self.offset_layer.differences(
                offset_target, k_M, k_N, smallest=smallest)
        return ShapeDifferences(area, conformal, offset_area, offset_conformal, self.given_offset, k_M, k_N, self)

    def layers(self) -> list[SurfaceLayer]:
        """The base layer and, with the offset surface, its layer."""
        return [self.base] + ([self.offset_layer] if self.use_extrinsic else [])

    def warn_split(self, k: int, *, label: str = "k_M") -> None:
        """A ``truncated`` :class:`ShapeDifferenceWarning` where a base basis of ``k`` functions
        splits a group of equal eigenvalues of a layer (:meth:`SurfaceLayer.split_group`: a
        symmetric base), naming the nearest sizes below and above that split none in either layer
        (:func:`~core.laplace_basis.split_warning`); ``label``: what the caller calls ``k``."""
        message = split_warning(
            label, k, lambda size: [(layer.name, group) for layer in self.layers()
                                    if (group := layer.split_group(size)) is not None],
            self.topology.components()[0] + 1, self.topology.n_vertices)
        if message is not None:
            warn(message, "truncated")

    def check_faithful(self, pose: np.ndarray, name: str) -> None:
        """Checks of a pose's used vertices ``(n_used, 3)`` that depend on what the differences
        resolve: a :class:`ShapeDifferenceWarning` where round-off alone may move its recovered
        squared edge lengths by more than :data:`PRECISION_TOLERANCE`, and (with the offset
        surface) a :class:`MeshError` where its offset surface collapses over an edge."""
        self._warn_precision(pose, name)
        if self.use_extrinsic:
            check_offset_pose(self.surface, pose, self.offset, name=name, vertex_ids=self.used_vertices,
                              unit=self.unit)

    def _warn_precision(self, pose: np.ndarray, name: str) -> None:
        topology = self.topology
        squared = topology.squared_edge_lengths(pose)[topology.triangle_edges]  # (m, 3)
        from .mesh_topology import triangle_areas

        doubled = 2.0 * triangle_areas(pose, topology.triangles)
        kappa = squared.max(axis=1) / np.minimum(squared.min(axis=1), doubled)
        worst = int(np.argmax(kappa))
        loss = np.finfo(np.float64).eps * kappa[worst]
        if loss > PRECISION_TOLERANCE:
            corners = self.triangles[worst]  # same order as the compact topology's
            edges = np.sqrt(squared[worst]) / self.unit  # in the caller's units
            warn(
                f"{name}: triangle {worst} (vertices {corners.tolist()}) has edges from {edges.min():.3g} to "
                f"{edges.max():.3g} long (or is nearly flat); recovering its edge lengths from the "
                f"differences loses precision (relative error up to about {loss:.1g}). The pose may be "
                "an extreme stretch or a stray vertex: check it, or remesh.",
                "precision",
            )

    def _warn_offset_scale(self) -> None:
        mean_edge = float(np.mean(np.sqrt(self.base.squared_lengths)))
        ratio = self.offset / mean_edge
        low, high = OFFSET_RANGE
        if not low <= ratio <= high:
            warn(
                f"offset {self.given_offset:g} is {ratio:.3g} × the mean edge length {mean_edge / self.unit:.3g}; "
                f"outside {low:g}–{high:g} × the extrinsic differences lose precision and the "
                "reconstruction can be inaccurate. Use offset=None (half the mean edge length).",
                "precision",
            )

    def recover_metric(self, differences: ShapeDifferences, *, warm: list | None = None,
                       tolerance: float | None = None, rho_scale: float | None = None) -> RecoveredMetric:
        """Areas and squared lengths of the target (and of its offset surface) — §7.1–7.2.
        ``warm``: one dict per layer (base, offset) carried along a sequence of nearby poses, whose
        solutions start the next pose's iterations; ``tolerance``: the relative stopping tolerance of
        the iterative solvers, ``rho_scale`` ADMM's initial penalty (both:
        :func:`~core.truncated_recovery.recover_truncated_metric`)."""
        warm = [None, None] if warm is None else warm
        jobs = [(self.base, differences.area, differences.conformal, warm[0], tolerance, rho_scale)]
        if differences.use_extrinsic:
            if not self.use_extrinsic:
                raise MeshError("These differences are extrinsic but the reference was built without an offset surface.")
            jobs.append((self.offset_layer, differences.offset_area, differences.offset_conformal, warm[1], tolerance, rho_scale))
        metrics = _recover_layers(jobs)
        return RecoveredMetric(metrics[0], metrics[1] if len(metrics) > 1 else None)

    def pose_metric(self, vertices) -> RecoveredMetric:
        """The exact metric of a pose ``(n, 3)`` (what recovery would return in the full basis)."""
        target = self.compact_pose(vertices)
        areas, squared, _, _ = pose_products(self.base.assembler, target)
        offset = None
        if self.use_extrinsic:
            positions = self.surface.positions(target, self.offset)
            o_areas, o_squared, _, _ = pose_products(self.offset_layer.assembler, positions)
            offset = LayerMetric(o_areas, o_squared)
        return RecoveredMetric(LayerMetric(areas, squared), offset)

    def thickening_squared_lengths(self, metric: RecoveredMetric) -> np.ndarray:
        """Squared lengths of every edge of the canonical thickening (§5.3) from a metric."""
        return self.surface.thickening_squared_lengths(
            metric.base.squared_lengths, metric.offset.squared_lengths, self.offset
        )

    # -- embedding (§7.3) and placement ------------------------------------------------------
    @property
    def base_positions(self) -> np.ndarray:
        """The base pose's used vertices in the working units, float64 ``(n_used, 3)``."""
        return self.vertices[self.used_vertices] if self.unit == 1.0 else self.base.positions

    @property
    def given_positions(self) -> np.ndarray:
        """The base pose's used vertices in the caller's units, float64 ``(n_used, 3)``."""
        return self.vertices[self.used_vertices]

    @cached_property
    def vertex_weights(self) -> np.ndarray:
        """Lumped vertex areas of the base ``(n_used,)``: weights for rigid placement."""
        return np.asarray(self.base.mass.sum(axis=1)).ravel()

    @cached_property
    def vertex_components(self) -> np.ndarray:
        """Connected-component label of every used vertex ``(n_used,)``."""
        _, labels = self.topology.components()
        return vertex_labels(self.topology.triangles, labels, self.topology.n_vertices)

    def embed(self, metric: RecoveredMetric, *, initial: np.ndarray | None = None, anchor=None) -> np.ndarray:
        """Positions ``(n_used, 3)`` realizing ``metric``, up to rigid motion (§7.3): the base
        layer of the embedded canonical thickening, or — without the offset layer — a fit of the
        base edge lengths started from ``initial`` (default: the base pose)."""
        return self.embed_result(metric, initial=initial, anchor=anchor).base_vertices

    def embed_result(self, metric: RecoveredMetric, *, initial: np.ndarray | None = None, anchor=None,
                     nearby: np.ndarray | None = None, initial_damping: float | None = None,
                     stagnation: float | None = None, tolerance: float | None = None):
        """:meth:`embed` with the whole :class:`~core.embedding.EmbeddingResult` (residuals,
        mirror choices made without evidence), which :func:`core.reconstruct` warns from.
        ``nearby``: thickening points ``(n + n_offset, 3)`` of a nearby pose (the previous frame of
        an animation), raced against the hinge frames instead of the base pose, without the
        continuations from the base. ``initial_damping``: the fit's first Levenberg–Marquardt
        damping and ``stagnation`` the relative cost decrease at which it stops
        (:func:`~core.edge_length_fit.levenberg_marquardt`; default its own); ``tolerance`` the RMS
        relative length residual at which it stops (default
        :data:`~core.edge_length_fit.DEFAULT_TOLERANCE`)."""
        from .edge_length_fit import DEFAULT_TOLERANCE, INITIAL_DAMPING, STAGNATION
        from .embedding import embed_base_edges, embed_thickening

        damping = INITIAL_DAMPING if initial_damping is None else float(initial_damping)
        stagnation = STAGNATION if stagnation is None else float(stagnation)
        tolerance = DEFAULT_TOLERANCE if tolerance is None else float(tolerance)

        if metric.offset is not None:
            # The base pose is raced against the hinge frames as a start when the lengths are
            # inexact (truncated or noisy differences; see embedding.START_TRIAL_ITERATIONS).
            reference = nearby if nearby is not None else self.surface.thickening_points(
                self.base.positions, self.offset_layer.positions)
            result = embed_thickening(
                self.surface, self.thickening_squared_lengths(metric), initial_points=initial,
                reference_points=reference, anchor=anchor, continuation=nearby is None, initial_damping=damping,
                stagnation=stagnation, tolerance=tolerance,
            )
        else:
            start = next(p for p in (initial, nearby, self.base_positions) if p is not None)[: self.topology.n_vertices]
            result = embed_base_edges(self.topology, metric.base.squared_lengths, initial_vertices=start,
                                      initial_damping=damping, stagnation=stagnation, tolerance=tolerance)
        return result

    def place_near(self, positions: np.ndarray, target: np.ndarray, *, glue_seams: bool = False,
                   exact: bool = False) -> np.ndarray:
        """Rigidly move each connected component of ``positions`` ``(n_used, 3)`` as close as
        possible to ``target`` ``(n_used, 3)`` (vertex-area-weighted least squares, no reflection).
        ``glue_seams`` (where ``target`` says nothing of where the pieces sit: the base, for a
        reconstruction): pieces that meet along seams in the base (:func:`core.seam_gluing.seam_twins`:
        panels exported unwelded, vertices split along UV seams) are put together along them
        first and placed as one (each placed on its own, a rolled sheet cut in two opened by
        0.9–11 % of its diagonal); a warning names pieces joined along a seam too straight to
        hold the angle between them, which the differences (per piece) do not hold either; where
        ``exact`` (``positions`` from exact differences), a seam whose sides differ is left apart."""
        labels = self.vertex_components
        placed = align_components(positions, target, labels, weights=self.vertex_weights)
        twins, problem = self.seam_twins
        if glue_seams and problem is not None:
            warn(f"Some pieces of the mesh touch along seams but cannot be joined there ({problem}); "
                          "they are placed on their own and the seams may open.", "seam")
        if not glue_seams or twins is None:
            return placed
        glued, labels, hinges, opened = glue_along_seams(placed, labels, twins, self.vertex_weights,
                                                         find_opened=exact)
        if opened:
            warn(
                f"{len(opened)} seam(s) between pieces of the mesh in the base have two sides that differ in "
                "this pose (the seam opens): they are left apart, the pieces placed by their other seams or "
                "nearest the base.",
                "seam")
        if hinges:
            warn(
                f"{len(hinges)} piece(s) of the mesh meet another along a seam that is straight (or "
                "straight to within the reconstruction's error): the shape differences are computed "
                "piece by piece, so the angle between them about the seam is not determined; it is "
                "the one closest to the base. Weld the seams (Merge by Distance) for a reconstruction "
                "that holds it.", "seam")
        return align_components(glued, target, labels, weights=self.vertex_weights)

    @cached_property
    def seam_twins(self):
        """Pairs of vertices (compact indices) of different pieces that meet along seams in the
        base, or None, and why they cannot be joined, or None (:func:`core.seam_gluing.seam_twins`)."""
        if len(np.unique(self.vertex_components)) < 2:
            return None, None
        return seam_twins(self.base.positions, self.topology)


def differences_reference(base_vertices, triangles, differences) -> ReferenceShape:
    """The prepared base of ``differences`` (from :func:`core.shape_differences`), checked to be
    the mesh ``base_vertices`` ``(n, 3)``, ``triangles`` ``(m, 3)``: :class:`MeshError` for anything
    else than shape differences, or differences of another mesh or base pose."""
    if not isinstance(differences, ShapeDifferences):
        raise MeshError(
            f"differences must be the ShapeDifferences returned by core.shape_differences; got "
            f"{type(differences).__name__}."
        )
    reference = differences.reference
    base = check_vertices(base_vertices, name="base_vertices")
    _check_same_mesh(reference, base, check_triangles(triangles, base.shape[0]))
    return reference


def _check_same_mesh(reference: ReferenceShape, base: np.ndarray, tris: np.ndarray) -> None:
    """MeshError unless ``(base, tris)`` is the mesh the differences were computed on."""
    computed_on = (
        f"These shape differences were computed on a mesh with {reference.n_vertices} vertices and "
        f"{reference.triangles.shape[0]} triangles"
    )
    fix = "Pass the base_vertices and triangles given to shape_differences."
    if base.shape[0] != reference.n_vertices or tris.shape != reference.triangles.shape:
        raise MeshError(
            f"{computed_on}, but base_vertices has {base.shape[0]} vertices and triangles has "
            f"{tris.shape[0]} rows. {fix}"
        )
    if not np.array_equal(tris, reference.triangles):
        same_corners = np.array_equal(np.sort(tris, axis=1), np.sort(reference.triangles, axis=1))
        differ = np.flatnonzero((tris != reference.triangles).any(axis=1))
        t = int(differ[0])
        if same_corners:
            raise MeshError(
                f"{computed_on}; the triangles given list the same corners in another order "
                f"(triangle {t}: {tris[t].tolist()}, was {reference.triangles[t].tolist()}), which "
                f"reverses or rotates them ({differ.size} in all). {fix}"
            )
        raise MeshError(f"{computed_on}; triangle {t} differs ({tris[t].tolist()}, was "
                        f"{reference.triangles[t].tolist()}; {differ.size} in all). {fix}")
    if not np.array_equal(base, reference.vertices):
        moved = np.linalg.norm(base - reference.vertices, axis=1)
        v = int(np.argmax(moved))
        raise MeshError(
            f"{computed_on} from another base pose: vertex {v} of base_vertices is {moved[v]:.3g} "
            f"away from where it was ({int(np.count_nonzero(moved))} vertices differ). {fix}"
        )
