"""The target's metric pulled back to the base mesh (paper §8.3, Figs. 11–12).

The areas µ and squared edge lengths ℓ² recovered from the intrinsic shape differences (§7.1–7.2:
linear solves in the full basis, convex programs when truncated) are the target N's metric written
on the connectivity of the base M. Everything intrinsic can then be computed on M as if it were N,
without an embedding of N: the Laplacian ``C(ℓ²; µ)φ = λ A(µ)φ`` of eq. (2) and its eigenpairs,
geodesic distances (the heat method, Crane et al. 2013) and the wave kernel signature (Aubry et al.
2011).

The heat method here is intrinsic — each triangle is laid out in the plane from its three edge
lengths, where gradients and divergences are taken, on the intrinsic Delaunay triangulation of
the metric's tufted cover, as geometry-central's robust heat method — and hand-written because the libraries'
heat methods (potpourri3d, libigl, geometry-central's Python bindings) take vertex positions,
which a pulled-back metric does not have.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .errors import MeshError, RecoveryError
from .geometry import DIVISION_FLOOR, expand_vertex_values, heron, lumped_vertex_areas, normalize, vertex_labels
from .laplace_basis import LaplaceBasis, cached_split_group, checked_laplace_basis, warn_eigenvalue_split
from .validation import check_count, check_energies, check_positive, check_result_memory

#: Heat method time step t = HEAT_TIME_FACTOR × (mean edge length)² (Crane et al.'s choice, m = 1).
HEAT_TIME_FACTOR = 1.0
#: WKS: Gaussian width in units of the log-energy step (Aubry et al. use 6–7), and the number of
#: those widths kept clear of the extreme log-eigenvalues at both ends.
WKS_VARIANCE = 7.0
WKS_MARGIN = 2.0


def heron_areas(squared_lengths_per_triangle: np.ndarray) -> np.ndarray:
    """Triangle areas from squared edge lengths ``(m, 3)`` (Heron's formula in squared lengths);
    NaN where the triangle inequality fails."""
    q = heron(squared_lengths_per_triangle)  # 16 area²
    return np.sqrt(np.where(q > 0, q, np.nan)) / 4.0


def planar_layouts(squared_lengths_per_triangle: np.ndarray) -> np.ndarray:
    """Corner positions ``(m, 3, 2)`` of each triangle laid out in the plane from its squared edge
    lengths ``(m, 3)`` (edge ``c`` opposite corner ``c``): corner 0 at the origin, corner 1 on the
    x axis, corner 2 above it (counter-clockwise)."""
    x = squared_lengths_per_triangle
    length_01 = np.sqrt(x[:, 2])
    x2 = (x[:, 1] + x[:, 2] - x[:, 0]) / (2.0 * length_01)
    corners = np.zeros((x.shape[0], 3, 2))
    corners[:, 1, 0] = length_01
    corners[:, 2, 0] = x2
    corners[:, 2, 1] = np.sqrt(np.maximum(x[:, 1] - x2 * x2, 0.0))
    return corners


class IntrinsicTriangulation:
    """A triangle mesh known by its edge lengths only: per-triangle planar layouts, the gradient
    of piecewise-linear functions, the cotangent Laplacian and the heat method.

    ``topology``: :class:`~core.mesh_topology.MeshTopology`; ``squared_lengths`` ``(E,)``.
    :meth:`from_corners` makes one of triangles given by their own three squared lengths (an
    intrinsic triangulation in which two triangles may share several edges, or an edge may join a
    vertex to itself), which has no ``topology``.
    """

    def __init__(self, topology, squared_lengths: np.ndarray):
        self.topology = topology
        self.squared_lengths = np.asarray(squared_lengths, dtype=np.float64)
        self._lay_out(topology.triangles, self.squared_lengths[topology.triangle_edges], topology.n_vertices)

    @classmethod
    def from_corners(cls, triangles: np.ndarray, corner_squared_lengths: np.ndarray, n_vertices: int):
        """``triangles`` ``(m, 3)`` with the squared lengths ``(m, 3)`` of the edge opposite each corner."""
        self = cls.__new__(cls)
        self.topology = self.squared_lengths = None
        self._lay_out(triangles, corner_squared_lengths, n_vertices)
        return self

    def _lay_out(self, triangles, per_triangle, n_vertices):
        self.triangles, self.n_vertices = triangles, n_vertices
        self.corner_squared_lengths = per_triangle  # opposite each corner
        self.areas = heron_areas(per_triangle)
        if not np.all(np.isfinite(self.areas) & (self.areas > 0)):
            bad = int(np.flatnonzero(~(self.areas > 0))[0])
            raise RecoveryError(
                f"Triangle {bad}'s edge lengths violate the triangle inequality: the metric is not "
                "a valid triangulation (recover it from less truncated differences)."
            )
        corners = planar_layouts(per_triangle)
        # Gradient of the hat function of corner c: the opposite edge turned by 90°, / (2 area).
        opposite = corners[:, [2, 0, 1]] - corners[:, [1, 2, 0]]
        self.hat_gradients = np.stack([-opposite[..., 1], opposite[..., 0]], axis=-1) / (2.0 * self.areas[:, None, None])

    def gradient(self, values: np.ndarray) -> np.ndarray:
        """Per-triangle gradient ``(m, 2)`` (in each triangle's layout) of vertex values ``(n,)``."""
        return np.einsum("tc,tcd->td", values[self.triangles], self.hat_gradients)

    def divergence(self, field_: np.ndarray) -> np.ndarray:
        """Integrated divergence ``(n,)`` of a per-triangle vector field ``(m, 2)``:
        ``Σ_T area_T ⟨∇φ_v, X_T⟩`` (the weak form, so that ``C u = div ∇u``)."""
        local = self.areas[:, None] * np.einsum("tcd,td->tc", self.hat_gradients, field_)
        return np.bincount(self.triangles.ravel(), local.ravel(), self.n_vertices)

    def cotangent_laplacian(self) -> sp.csr_matrix:
        """``C_vw = Σ_T area_T ⟨∇φ_v, ∇φ_w⟩``: the cotangent stiffness matrix ``C(ℓ²; µ)`` of
        eq. (2) with the Heron areas of these lengths, PSD (an edge from a vertex to itself adds
        nothing: its two ends' hat functions are summed)."""
        local = self.areas[:, None, None] * np.einsum("tcd,ted->tce", self.hat_gradients, self.hat_gradients)
        rows = np.repeat(self.triangles, 3, axis=1).ravel()
        cols = np.tile(self.triangles, (1, 3)).ravel()
        return sp.csr_matrix((local.ravel(), (rows, cols)), shape=(self.n_vertices, self.n_vertices))

    def lumped_mass(self) -> np.ndarray:
        """Vertex areas ``(n,)``: a third of the areas of the triangles around each vertex."""
        return lumped_vertex_areas(self.triangles, self.areas, self.n_vertices)

    def heat_method(self):
        """A :class:`HeatMethod` factored for this metric (reuse it for many sources), as
        geometry-central's robust heat method (Sharp & Crane 2020) does it: on the intrinsic
        Delaunay triangulation (:func:`~core.delaunay_flips.intrinsic_delaunay`) of the mesh's
        tufted cover (:func:`~core.delaunay_flips.tufted_cover`), whose cotangent weights are all
        non-negative, which the heat method needs (Crane et al. 2013, §3.2; Sharp et al. 2019).
        Flips of the mesh itself cannot reach an obtuse triangle along the boundary (a boundary
        edge has one triangle): on a random-point triangulation of a sheet, whose hull is lined
        with such slivers, distances on the mesh's own Delaunay flips measured up to 0.99 of the
        largest distance off against exact polyhedral geodesics, on the cover's 0.01–0.06. The cover
        doubles the triangles, not the vertices: same matrices' size, twice the assembly."""
        from .delaunay_flips import intrinsic_delaunay, side_twins, tufted_cover

        triangles, corners, twins = intrinsic_delaunay(*tufted_cover(
            self.topology.triangles, self.corner_squared_lengths, side_twins(self.topology)))
        once = twins > np.arange(twins.size)  # each edge of the cover (it has no boundary) once
        mean_edge_length = float(np.mean(np.sqrt(corners.reshape(-1)[once])))
        count, labels = self.topology.components()
        component = vertex_labels(self.topology.triangles, labels, self.n_vertices)
        return HeatMethod(IntrinsicTriangulation.from_corners(triangles, corners, self.n_vertices),
                          mean_edge_length=mean_edge_length, vertex_component=component, components=count)


class HeatMethod:
    """Geodesic distances by the heat method (Crane, Weischedel, Wardetzky 2013) on an intrinsic
    triangulation: heat flow ``(M + tC) u = δ_s`` for ``t = h²`` (``h`` the mean edge length),
    the normalized field ``X = −∇u/|∇u|``, then the Poisson problem ``C φ = div X``. Both
    matrices are factored once. ``vertex_component`` ``(n,)``: each vertex's connected component
    (``components`` of them), in which the Poisson problem is pinned."""

    def __init__(self, triangulation: IntrinsicTriangulation, *, mean_edge_length: float,
                 vertex_component: np.ndarray, components: int):
        from scipy.sparse.linalg import splu

        self.triangulation = triangulation
        stiffness = triangulation.cotangent_laplacian()
        self.mass = triangulation.lumped_mass()
        time = HEAT_TIME_FACTOR * mean_edge_length**2
        self._heat = splu(sp.csc_matrix(sp.diags(self.mass) + time * stiffness))
        # The Poisson problem is singular (constants) per connected component: pin one vertex of
        # each component, after which the matrix is positive definite.
        n = triangulation.n_vertices
        self.vertex_component = vertex_component
        pinned = np.array([np.flatnonzero(vertex_component == c)[0] for c in range(components)])
        self._pinned = pinned
        keep = np.ones(n)
        keep[pinned] = 0.0
        mask = sp.diags(keep)
        poisson = mask @ stiffness @ mask + sp.diags(1.0 - keep)
        self._poisson = splu(sp.csc_matrix(poisson))
        self._keep = keep

    def distances(self, source: int) -> np.ndarray:
        """Geodesic distance of every vertex to ``source`` ``(n,)``; ``inf`` on other components."""
        tri = self.triangulation
        impulse = np.zeros(tri.n_vertices)
        impulse[source] = 1.0
        heat = self._heat.solve(impulse)
        gradient = tri.gradient(heat)
        direction = -normalize(gradient)[0]
        rhs = tri.divergence(direction) * self._keep
        phi = self._poisson.solve(rhs)
        # The pinned vertex has φ = 0; shift each component so the source is at distance 0.
        same = self.vertex_component == self.vertex_component[source]
        out = np.full(tri.n_vertices, np.inf)
        out[same] = phi[same] - phi[source]
        return out


@dataclass(eq=False)
class PulledBackMetric:
    """The target's metric on the base mesh's connectivity (§8.3).

    ``areas`` µ float64 ``(m,)`` per triangle of ``triangles``; ``squared_lengths`` ℓ² float64
    ``(E,)`` per edge of ``edges`` (int64 ``(E, 2)``, vertex indices of the base mesh). Vertex
    arrays returned have one row per base vertex; vertices in no triangle get 0 (eigenfunctions,
    WKS) or ``inf`` (distances).
    """

    reference: object = field(repr=False)
    areas: np.ndarray
    squared_lengths: np.ndarray
    _bases: dict = field(default_factory=dict, repr=False)
    _heat: HeatMethod | None = field(default=None, repr=False)

    @property
    def triangles(self) -> np.ndarray:
        return self.reference.triangles

    @property
    def edges(self) -> np.ndarray:
        return self.reference.used_vertices[self.reference.topology.edges]

    @property
    def edge_lengths(self) -> np.ndarray:
        return np.sqrt(self.squared_lengths)

    def mass_matrix(self) -> sp.csr_matrix:
        """``A(µ)`` of eq. (1) on the used vertices, sparse ``(n_used, n_used)``."""
        return self.reference.base.assembler.mass_matrix(self.areas)

    def laplacian(self) -> sp.csr_matrix:
        """``C(ℓ²; µ)`` of eq. (2) on the used vertices: the pulled-back Laplacian (Fig. 11)."""
        return self.reference.base.assembler.conformal_matrix(self.squared_lengths, self.areas)

    def laplace_basis(self, k: int) -> LaplaceBasis:
        """The first ``k`` eigenpairs of the pulled-back Laplacian (on the used vertices); computed
        with :func:`~core.laplace_basis.checked_laplace_basis`'s few more (for :meth:`_warn_split`).
        Eigenpairs within a group of equal eigenvalues are one arbitrary orthonormal choice of its
        eigenspace, as from any eigensolver, at any ``k``."""
        # a whole number (text, fractions, booleans refused); below 1 it reaches the size check of
        # checked_laplace_basis, not a cached basis cut at k (a negative k would drop its last −k)
        k = check_count(k, "k", minimum=None)
        larger = [size for size in self._bases if size >= k] if k >= 1 else []
        if not larger:
            computed, _ = checked_laplace_basis(self.mass_matrix(), self.laplacian(), k, what="pulled-back metric")
            self._bases[computed.size] = computed
            larger = [computed.size]
        cached = self._bases[min(larger)]
        return cached if cached.size == k else LaplaceBasis(cached.eigenvalues[:k], cached.functions[:, :k])

    def _warn_split(self, k: int) -> None:
        """A ``truncated`` warning where the first ``k`` eigenpairs end inside a group of equal
        eigenvalues (a symmetric metric): a sum over them that weighs a group's functions alike
        (the WKS) holds an arbitrary part of it."""
        n = self.reference.topology.n_vertices
        cached_split_group(self._bases, k, n, lambda size: checked_laplace_basis(
            self.mass_matrix(), self.laplacian(), size, what="pulled-back metric"))  # past k, to the group's end
        warn_eigenvalue_split("k", k, [("pulled-back metric", self._bases[max(self._bases)].eigenvalues)], 2, n)

    def laplacian_eigenvalues(self, k: int) -> np.ndarray:
        """The ``k`` smallest eigenvalues ``(k,)`` of ``C(ℓ²; µ) φ = λ A(µ) φ`` (ascending)."""
        return self.laplace_basis(k).eigenvalues.copy()

    def eigenfunctions(self, k: int) -> np.ndarray:
        """The first ``k`` eigenfunctions, float64 ``(n, k)``, A(µ)-orthonormal."""
        return self._expand(self.laplace_basis(k).functions, 0.0)

    def geodesic_distances(self, source_vertex: int) -> np.ndarray:
        """Geodesic distances ``(n,)`` from ``source_vertex`` in the pulled-back metric (the heat
        method on the intrinsic triangulation; the heat and Poisson factors are reused for
        further sources)."""
        used = self._compact_vertex(source_vertex)
        if self._heat is None:
            self._heat = IntrinsicTriangulation(self.reference.topology, self.squared_lengths).heat_method()
        return self._expand(self._heat.distances(used), np.inf)

    def wave_kernel_signature(self, energies: int | np.ndarray = 100, *, k: int = 100, variance: float = WKS_VARIANCE) -> np.ndarray:
        """Wave kernel signature (Aubry et al. 2011), float64 ``(n, len(energies))``:
        ``WKS(x, e) = Σ_i φ_i(x)² exp(−(e − log λ_i)²/2σ²) / Σ_i exp(−(e − log λ_i)²/2σ²)`` over
        the first ``k`` nonzero eigenpairs. ``energies``: a count (evenly spaced log-energies
        between the extreme log-eigenvalues, ``WKS_MARGIN`` widths inside) or explicit values (to
        compare several metrics at the same energies, see :meth:`wks_energies`)."""
        k = min(check_count(k, "k", minimum=1), self.reference.topology.n_vertices - 1)
        energies, variance = check_energies(energies), check_positive(variance, "variance")
        if np.ndim(energies) == 0:
            check_result_memory((self.reference.n_vertices, energies), f"energies = {energies:,}", "ask for fewer")
        basis = self.laplace_basis(k)
        self._warn_split(k)
        return self._expand(wave_kernel_signature(basis, energies, variance=variance), 0.0)

    def wks_energies(self, count: int = 100, *, k: int = 100, variance: float = WKS_VARIANCE) -> np.ndarray:
        """The log-energies ``(count,)`` :meth:`wave_kernel_signature` uses for ``count``."""
        count, variance = check_count(count, "count", minimum=1), check_positive(variance, "variance")
        check_result_memory((count,), f"count = {count:,}", "ask for fewer")
        basis = self.laplace_basis(min(check_count(k, "k", minimum=1), self.reference.topology.n_vertices - 1))
        return wks_energies(basis.eigenvalues, count, variance=variance)[0]

    # -- vertex numbering --------------------------------------------------------------------------
    def _compact_vertex(self, vertex: int) -> int:
        try:  # a whole number: True, 1.5, NaN, text are no vertex index
            index = check_count(vertex, "source_vertex", minimum=None)
        except MeshError:
            index = None
        if index is None or not 0 <= index < self.reference.n_vertices:
            raise MeshError(
                f"source_vertex must be a vertex index in 0..{self.reference.n_vertices - 1}; got {vertex!r}."
            )
        vertex = index
        position = np.searchsorted(self.reference.used_vertices, vertex)
        if position >= self.reference.used_vertices.size or self.reference.used_vertices[position] != vertex:
            raise MeshError(f"Vertex {vertex} is in no triangle, so it has no geodesic distances.")
        return int(position)

    def _expand(self, values: np.ndarray, fill: float) -> np.ndarray:
        return expand_vertex_values(self.reference.used_vertices, values, self.reference.n_vertices, fill=fill)


def _wks_spectrum(eigenvalues: np.ndarray, count: int, variance: float):
    """Mask of the nonzero ``eigenvalues``, their extreme log-eigenvalues and the Gaussian width
    σ for ``count`` energies."""
    nonzero = eigenvalues > 1e-9 * max(float(eigenvalues.max()), DIVISION_FLOOR)
    positive = eigenvalues[nonzero]
    if positive.size < 2:
        raise MeshError("The wave kernel signature needs at least two nonzero eigenvalues: raise k.")
    low, high = np.log(positive[0]), np.log(positive[-1])
    return nonzero, low, high, variance * (high - low) / count


def wks_energies(eigenvalues: np.ndarray, count: int, *, variance: float = WKS_VARIANCE):
    """Evenly spaced log-energies ``(count,)`` and the Gaussian width σ for the nonzero
    ``eigenvalues``."""
    _, low, high, sigma = _wks_spectrum(eigenvalues, count, variance)
    return np.linspace(low + WKS_MARGIN * sigma, high - WKS_MARGIN * sigma, count), sigma


def wave_kernel_signature(basis: LaplaceBasis, energies, *, variance: float = WKS_VARIANCE) -> np.ndarray:
    """WKS ``(n, len(energies))`` of an eigenbasis (see :meth:`PulledBackMetric.wave_kernel_signature`)."""
    values = basis.eigenvalues
    if np.ndim(energies) == 0:
        energies, _ = wks_energies(values, int(energies), variance=variance)
    energies = np.asarray(energies, dtype=np.float64)
    nonzero, _, _, sigma = _wks_spectrum(values, energies.size, variance)
    logs = np.log(values[nonzero])
    weights = np.exp(-((energies[None, :] - logs[:, None]) ** 2) / (2.0 * sigma**2))  # (k, e)
    return (basis.functions[:, nonzero] ** 2 @ weights) / np.maximum(weights.sum(axis=0), DIVISION_FLOOR)


def pull_back(base_vertices, triangles, differences) -> PulledBackMetric:
    """The target's metric on the base mesh from its shape differences (§8.3).

    ``base_vertices`` float64 ``(n, 3)``, ``triangles`` int ``(m, 3)``; ``differences`` from
    :func:`core.shape_differences` (full basis: exact linear recovery; truncated ``k_M``/``k_N``:
    the convex programs of §7). Only the intrinsic pair is used. ``base_vertices`` and
    ``triangles`` must be those ``differences`` were computed from (:class:`MeshError` otherwise).
    """
    from .reference_shape import differences_reference

    reference = differences_reference(base_vertices, triangles, differences)
    metric = reference.base.recover(differences.area, differences.conformal)
    if reference.unit == 1.0:
        return PulledBackMetric(reference, metric.areas, metric.squared_lengths)
    square = reference.unit ** 2  # recovered in the reference's working units, returned in the caller's
    return PulledBackMetric(reference, metric.areas / square, metric.squared_lengths / square)
