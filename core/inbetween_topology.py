"""What the in-between solver keeps per triangle mesh (paper §7.3): corner-edge incidence, lumped
vertex masses, connected components and the factorized normal matrices ``DᵀD + diag(w · mass)``
of the Poisson solve (the first of :class:`Topology` → ``Key`` → ``Relative`` → ``Gap``, see
:mod:`core.inbetween_solver`)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from . import deformation_fields as df
from . import small_matrices
from .cached_property import cached_property
from .geometry import column_means, coordinate_cross, coordinate_dot, lumped_vertex_areas, shifted, vertex_labels
from .sparse_cholesky import SPDFactor, orderings

#: Anchor weight (per unit vertex mass, mean mass 1, relative to the unit edge terms) that only
#: fixes the translation gauge of the Poisson solve: small enough to leave shapes exact to ~1e-7
#: of their size (placement is done afterwards), large enough to keep the matrix well conditioned.
GAUGE_WEIGHT = 1e-7
#: The vertices' areas (over their mean) the anchors weigh are at least this: the gauge
#: ``GAUGE_WEIGHT × mass`` of a piece a millionth of its size in the first key (areas 1e-12 of the
#: others') fell below what CHOLMOD resolves against the Laplacian's unit entries ("not positive
#: definite"); no cloth has a vertex near it.
MASS_FLOOR = 1e-6


class Topology:
    """What depends only on the triangles: edge incidence (``D``: corner edges × vertices), lumped
    vertex masses of the first pose (mean 1), components, and the factorized normal matrices."""

    def __init__(self, topo, first_pose: np.ndarray):
        n_vertices = first_pose.shape[0]
        self.n = n_vertices
        self.first_pose = first_pose  # where pieces are seen to sit on each other (inbetween_carried)
        t = self.triangles = topo.triangles
        m = t.shape[0]
        self.i, self.j = t.ravel(), t[:, [1, 2, 0]].ravel()  # corner edge c of triangle k: row 3k + c
        # the same incidence with rows corner-major (row c·m + k), for the fit's component-wise
        # arrays (3 coordinates, 3 corners, m): contiguous per coordinate and corner. Made in CSR
        # form directly, each row's two entries (−1 at its edge's start, +1 at its end) in column
        # order as the conversion from coordinates sorts them (3× faster than that conversion)
        start, end = t.T.ravel(), t[:, [1, 2, 0]].T.ravel()
        ascending = start < end
        index = np.int32 if max(6 * m, n_vertices) < np.iinfo(np.int32).max else np.int64
        columns = np.empty((3 * m, 2), dtype=index)
        columns[:, 0] = np.where(ascending, start, end)
        columns[:, 1] = np.where(ascending, end, start)
        signs = np.empty((3 * m, 2))
        signs[:, 0] = np.where(ascending, -1.0, 1.0)
        np.negative(signs[:, 0], out=signs[:, 1])
        self.Dc = sp.csr_matrix((signs.ravel(), columns.ravel(), np.arange(0, 6 * m + 1, 2, dtype=index)),
                                shape=(3 * m, n_vertices))
        self.Dct = self.Dc.T.tocsr()
        self.laplacian = (self.Dct @ self.Dc).tocsc()
        self._incidences: dict = {}
        edges = self.corner_edge_rows(first_pose)
        cross = coordinate_cross(edges[:, 0], edges[:, 2])
        areas = 0.5 * np.sqrt(coordinate_dot(cross, cross))
        mass = lumped_vertex_areas(t, areas, n_vertices)
        used = mass > 0
        # loose vertices follow the guide
        self.mass = np.where(used, np.maximum(mass / mass[used].mean(), MASS_FLOOR), 1.0)
        self.weights = np.where(used, self.mass, 0.0)
        _, labels = topo.components()
        per_vertex = vertex_labels(t, labels, n_vertices)
        kept = np.unique(labels)
        self.triangle_component = np.searchsorted(kept, labels)
        self.piece_sizes = np.bincount(self.triangle_component)  # triangles per component
        self.vertex_component = np.where(per_vertex >= 0, np.searchsorted(kept, per_vertex), -1)
        # the vertices in triangles, their components, and in component order (each in vertex order)
        self.component_vertices = np.flatnonzero(self.vertex_component >= 0)
        self.component_labels = self.vertex_component[self.component_vertices]
        self.component_order = self.component_vertices[np.argsort(self.component_labels, kind="stable")]
        self.component_starts = np.r_[0, np.cumsum(np.bincount(self.component_labels, minlength=kept.size))[:-1]]
        self.components = np.split(self.component_order, self.component_starts[1:]) if kept.size else []
        self.pieces_in_order = np.array_equal(self.component_order, np.arange(n_vertices))  # no gather needed
        # loose vertices (in no triangle) move with the piece nearest them in the first pose: its
        # rigid motion carries them (a whole mesh turned rigidly turns them too) and undone, their
        # keys' spline is interpolated in its frame
        self.loose = np.flatnonzero(per_vertex < 0)
        self.vertex_owner = self.vertex_component.copy()
        if self.loose.size and self.components:
            from scipy.spatial import cKDTree

            used_rows = np.flatnonzero(per_vertex >= 0)
            nearest = cKDTree(first_pose[used_rows]).query(first_pose[self.loose])[1]
            self.vertex_owner[self.loose] = self.vertex_component[used_rows[nearest]]
        self.all_in_one = len(self.components) == 1 and self.components[0].size == n_vertices  # no loose vertex
        # what selects each component's vertices: a slice where they are consecutive (one component
        # and no loose vertex, or pieces joined into one object in their vertex order), so that the
        # poses per key, relative and rigid motion are views rather than (n, 3) copies
        self.component_rows = [slice(rows[0], rows[-1] + 1) if rows.size and rows[-1] - rows[0] + 1 == rows.size else rows
                               for rows in self.components]
        self.triangles_per_vertex = np.bincount(t.ravel(), minlength=n_vertices)
        # vertices in a triangle and on no boundary edge: a closed ring of triangles around each
        self.inner_vertices = self.triangles_per_vertex > 0
        self.inner_vertices[topo.edges[topo.boundary_edges].ravel()] = False
        adjacency = sp.csr_matrix((np.ones(3 * m, dtype=bool), (t.ravel(), np.repeat(np.arange(m), 3))),
                                  shape=(n_vertices, m))
        self.vertex_triangles = adjacency  # (n, m): the triangles around each vertex
        self.edges_per_vertex = np.bincount(self.i, minlength=n_vertices) + np.bincount(self.j, minlength=n_vertices)
        self._uniform: dict[float, object] = {}
        #: Per set of rigid components (their mask's bytes), the deforming pieces that may sit on
        #: them and where (:func:`core.inbetween_motion.seat_candidates`: read in the first pose).
        self.seat_candidates: dict[bytes, tuple] = {}
        #: Vertices at one place in every key (pins), or None: the pieces' rigid fits keep them there
        #: (:func:`core.inbetween_rigid_fits.rigid_fits`).
        self.pinned: np.ndarray | None = None
        #: The caller's index of each triangle where the triangles were reordered
        #: (:func:`core.vertex_locality.renumbered`) or some dropped (near-duplicate vertices solved
        #: as one, :mod:`core.near_duplicates`), or None: messages name triangles by it.
        self.caller_triangles: np.ndarray | None = None
        self._edge_triangles, self._triangle_edges = topo.edge_triangles, topo.triangle_edges  # for across

    @cached_property
    def across(self) -> np.ndarray:
        """The triangle across each corner edge (int (m, 3): corner edge ``c`` from corner ``c`` to
        ``c + 1``, as ``i`` and ``j`` number them), -1 on the boundary: the other triangle of the
        mesh topology's edge (:class:`core.mesh_topology.MeshTopology`, whose ``triangle_edges[:, k]``
        is opposite corner ``k``, corner edge ``k + 1``); made when first asked for."""
        pairs = self._edge_triangles[self._triangle_edges[:, [2, 0, 1]]]  # (m, 3 corner edges, 2)
        own = np.arange(len(self.triangles))[:, None]
        return np.where(pairs[..., 0] == own, pairs[..., 1], pairs[..., 0])

    @cached_property
    def D(self) -> sp.csr_matrix:
        """Corner edges × vertices incidence (3m, n), row ``3k + c`` corner edge ``c`` of triangle
        ``k`` (two poses' blend anchor reads it; made when first asked for)."""
        rows = np.arange(3 * len(self.triangles))
        return sp.csr_matrix((np.r_[-np.ones(rows.size), np.ones(rows.size)],
                              (np.r_[rows, rows], np.r_[self.i, self.j])), shape=(rows.size, self.n))

    def factor(self, weights: np.ndarray | float = GAUGE_WEIGHT, key=None) -> SPDFactor:
        """The factor of the symmetric positive definite ``DᵀD + diag(w · mass)`` for per-vertex
        ``weights`` (n,) or one weight for all (cached per value, or per ``key`` for per-vertex
        weights)."""
        uniform = np.isscalar(weights)
        cache = weights if uniform else key
        if cache is not None and cache in self._uniform:
            return self._uniform[cache]
        w = np.full(self.n, weights) if uniform else weights
        lu = SPDFactor(self.laplacian + sp.diags(w * self.mass))
        if cache is not None:
            self._uniform[cache] = lu
        return lu

    def factor_orderings(self) -> dict:
        """The orderings of the patterns factored in this process, that of :meth:`factor`'s matrices
        (``DᵀD`` plus a positive diagonal: one pattern for every weight) made now where it was not
        (:func:`core.sparse_cholesky.orderings`): for the gap worker, which factors the same matrices
        (:mod:`core.gap_processes`)."""
        return orderings(lambda: self.laplacian + sp.diags(self.mass))

    def incidence(self, dtype=np.float64) -> sp.csr_matrix:
        """``Dc`` with its ±1 entries in ``dtype`` (the index arrays shared)."""
        if dtype == np.float64:
            return self.Dc
        cached = self._incidences.get(np.dtype(dtype))
        if cached is None:
            cached = self._incidences[np.dtype(dtype)] = sp.csr_matrix(
                (self.Dc.data.astype(dtype), self.Dc.indices, self.Dc.indptr), shape=self.Dc.shape)
        return cached

    def corner_edge_rows(self, x: np.ndarray, dtype=np.float64) -> np.ndarray:
        """Corner edge vectors of positions ``x`` (n, 3) by coordinate: (3 coordinates, 3 corners,
        m), each (m,) row contiguous (one sparse product per coordinate), in ``dtype``. Element-wise
        work on these rows is 3–5× faster than on (m, 3, 3) blocks."""
        m = len(self.triangles)
        incidence = self.incidence(dtype)
        if np.dtype(dtype) != np.float64:  # edges are differences: taken about the middle, float32
            # keeps their digits far from the origin too (1e3 units out: 1e-3 of an edge); on
            # contiguous coordinate rows (3× faster than across (n, 3) rows)
            centred = np.ascontiguousarray(x.T)
            centred -= column_means(x)[:, None]
            coordinates = centred.astype(dtype)
        else:
            coordinates = np.ascontiguousarray(x.T)
        out = np.empty((3, 3 * m), dtype=dtype)
        for d in range(3):
            out[d] = incidence @ coordinates[d]
        return out.reshape(3, 3, m)

    def corner_edge_rows_on(self, x: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """:meth:`corner_edge_rows` (float64) of the triangles ``rows`` (r,) alone: (3 coordinates, 3
        corners, r), contiguous, each edge the one difference ``x[end] − x[start]`` the incidence
        product makes (the same values), at the cost of the rows rather than of the mesh."""
        return np.ascontiguousarray(df.corner_edges(x, self.triangles[rows]).transpose(2, 1, 0))

    @cached_property
    def _side_incidence(self) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """The rows of ``Dc`` of corner edges 0 and 2 (each triangle's sides from its first corner)."""
        m = len(self.triangles)
        return self.Dc[:m], self.Dc[2 * m:]

    def triangle_sides(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sides ``x1 − x0`` and ``x2 − x0`` of every triangle of positions ``x`` (n, 3), by
        coordinate (3, m) each: corner edges 0 and −2 of :meth:`corner_edge_rows`, the same
        values without corner edge 1 (a check of normals and areas reads these two only)."""
        first, last = self._side_incidence
        coordinates = np.ascontiguousarray(x.T)
        e1, e2 = np.empty((3, len(self.triangles))), np.empty((3, len(self.triangles)))
        for d in range(3):
            e1[d] = first @ coordinates[d]
            e2[d] = last @ coordinates[d]
        np.negative(e2, out=e2)
        return e1, e2

    def triangles_around(self, vertices: np.ndarray) -> np.ndarray:
        """The triangles (indices, each as often as it has a corner among ``vertices``) around the
        ``vertices`` (ascending index array), read from :attr:`vertex_triangles` by index: the cost
        is that of the vertices, not of the mesh."""
        adjacency = self.vertex_triangles
        starts, stops = adjacency.indptr[vertices], adjacency.indptr[vertices + 1]
        counts = stops - starts
        offsets = np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
        return adjacency.indices[offsets]

    def component_sums(self, values: np.ndarray) -> np.ndarray:
        """Per component (C, …), the sums of the mass-weighted ``values`` (n, …) of its vertices."""
        flat = values.reshape(self.n, -1)
        sums = self.weights @ flat if self.all_in_one else self.component_weights @ flat
        return sums.reshape((len(self.components),) + values.shape[1:])

    @cached_property
    def component_weights(self) -> sp.csr_matrix:
        """(C, n): each component's row holds its vertices' weights (a product sums per component
        at any count of pieces: 40 µs at 10k vertices, where a loop over 3,000 pieces took 30 ms)."""
        rows = self.component_vertices
        return sp.csr_matrix((self.weights[rows], (self.component_labels, rows)), shape=(len(self.components), self.n))

    @cached_property
    def component_mass(self) -> np.ndarray:
        """Each component's mass (C,): the sum of its vertices' weights."""
        return self.component_sums(np.ones(self.n))

    def centroids(self, x: np.ndarray) -> np.ndarray:
        """Each component's mass-weighted centroid (C, 3) in positions ``x`` (n, 3)."""
        return self.component_sums(x) / self.component_mass[:, None]

    def diagonals(self, x: np.ndarray) -> np.ndarray:
        """Each component's size (C,) in positions ``x`` (n, 3): the diagonal of the box whose
        sides have the component's mass-weighted second moments about its centroid,
        sqrt(12 · trace of the covariance) (at least the smallest float): the bounding box's diagonal
        of a flat rectangle or a sphere (of a cube's surface 1.29 ×), and the same however the mesh
        is turned, so the tolerances scaled by it decide alike on a turned scene (the box along the
        world's axes did not: a sheet hanging from a rod that stops, turned, came out 1.016 × the
        Catmull–Rom spline's error instead of 0.924 ×; along the principal axes, a square sheet's
        are any in its plane)."""
        if not self.components:
            return np.zeros(0)
        centroids = self.centroids(x)
        centred = x - centroids[self.vertex_owner]  # loose vertices: their owner's (they weigh nothing)
        spread = self.component_sums(np.einsum("ij,ij->i", centred, centred)) / self.component_mass
        return np.maximum(np.sqrt(12.0 * spread), np.finfo(float).tiny)

    def apply_motion(self, x: np.ndarray, rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
        """``x`` (n, 3) with each component's rigid motion (C, 3, 3), (C, 3) applied (loose vertices:
        their owner's, ``vertex_owner``)."""
        if self.all_in_one:
            out = x @ rotations[0].T
            return shifted(out, translations[0], out=out)
        if not self.components:
            return x.copy()
        c = self.vertex_owner
        if len(self.components) > df.SLICED_PIECES:
            return small_matrices.matmul(rotations[c], x[:, :, None])[:, :, 0] + translations[c]
        out = np.empty_like(x)
        for k, rows in enumerate(self.component_rows):  # one product per piece, on a view where its rows are consecutive
            out[rows] = x[rows] @ rotations[k].T + translations[k]
        if self.loose.size:
            loose = self.loose
            out[loose] = small_matrices.matmul(rotations[c[loose]], x[loose, :, None])[:, :, 0] + translations[c[loose]]
        return out

    def undo_motion(self, x: np.ndarray, rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`apply_motion`."""
        inverse = np.transpose(rotations, (0, 2, 1))
        return self.apply_motion(x, inverse, -np.einsum("cab,cb->ca", inverse, translations))
