"""Discrete inner products of piecewise-linear functions (paper §4.2).

- ``A(µ)``: the non-lumped Galerkin mass matrix, eq. (1). Linear in the triangle areas µ.
- ``C(ℓ²; µ)``: the conformal (cotangent stiffness) matrix, eq. (2), positive semidefinite with
  ``C φ = λ A φ``, ``λ ≥ 0``. Linear in the squared edge lengths ℓ² for fixed µ.

Both matrices have the sparsity of the mesh graph (diagonal + one entry per edge each side). A
:class:`ProductAssembler` computes that pattern once per topology so that building the matrices of
any pose is a couple of vectorised sums. The linear maps µ ↦ A and ℓ² ↦ C (for fixed µ) that
recovery inverts are :meth:`ProductAssembler.area_map` and :meth:`ProductAssembler.length_map`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .mesh_topology import MeshTopology


class ProductAssembler:
    """Builds ``A(µ)`` and ``C(ℓ²; µ)`` for one topology; reuse it for every pose.

    The CSR pattern stores, for every vertex ``v``, its diagonal entry and one entry per edge
    ``(v, w)``. ``edge_values`` below always means one value per edge (the symmetric off-diagonal
    entry ``M[v, w] = M[w, v]``).
    """

    def __init__(self, topology: MeshTopology):
        self.topology = topology
        n, edges = topology.n_vertices, topology.edges
        rows = np.concatenate([np.arange(n), edges[:, 0], edges[:, 1]])
        cols = np.concatenate([np.arange(n), edges[:, 1], edges[:, 0]])
        order = np.lexsort((cols, rows))
        self._rows, self._cols = rows[order], cols[order]
        self._indptr = np.searchsorted(self._rows, np.arange(n + 1)).astype(np.int64)
        # Position in the CSR data array of each source slot (diagonal, upper, lower).
        position = np.empty_like(order)
        position[order] = np.arange(order.size)
        self._diag_pos = position[:n]
        self._upper_pos = position[n : n + len(edges)]
        self._lower_pos = position[n + len(edges) :]

    # -- assembly ---------------------------------------------------------------------------
    def from_entries(self, diagonal: np.ndarray, edge_values: np.ndarray) -> sp.csr_matrix:
        """Symmetric sparse matrix, float64 ``(n, n)``, from its diagonal ``(n,)`` and per-edge
        off-diagonal values ``(E,)``."""
        data = np.empty(self._rows.size)
        data[self._diag_pos] = diagonal
        data[self._upper_pos] = edge_values
        data[self._lower_pos] = edge_values
        n = self.topology.n_vertices
        return sp.csr_matrix((data, self._cols.copy(), self._indptr.copy()), shape=(n, n))

    def entries(self, matrix) -> tuple[np.ndarray, np.ndarray]:
        """Inverse of :meth:`from_entries`: the diagonal ``(n,)`` and per-edge values ``(E,)`` of a
        matrix on this pattern (sparse or dense); entries outside the pattern are ignored."""
        edges = self.topology.edges
        if sp.issparse(matrix):
            csr = sp.csr_matrix(matrix)
            csr.sum_duplicates()
            if csr.has_sorted_indices and np.array_equal(csr.indptr, self._indptr) and np.array_equal(
                csr.indices, self._cols
            ):
                return csr.data[self._diag_pos].copy(), csr.data[self._upper_pos].copy()
            diagonal = np.asarray(csr.diagonal()).ravel()
            upper = np.asarray(csr[edges[:, 0], edges[:, 1]]).ravel()
            return diagonal, upper
        dense = np.asarray(matrix)
        return np.diag(dense).copy(), dense[edges[:, 0], edges[:, 1]].copy()

    def mass_matrix(self, areas: np.ndarray) -> sp.csr_matrix:
        """Galerkin mass matrix ``A(µ)``, eq. (1): float64 ``(n, n)`` from areas µ ``(m,)``.

        ``A_vv = Σ_{T∋v} µ(T) / 6`` and ``A_vw = Σ_{T∋(v,w)} µ(T) / 12``; it integrates products
        of piecewise-linear functions exactly.
        """
        diagonal, edge_values = self.mass_entries(areas)
        return self.from_entries(diagonal, edge_values)

    def mass_entries(self, areas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Diagonal ``(n,)`` and per-edge ``(E,)`` entries of ``A(µ)``."""
        topo = self.topology
        diagonal = np.bincount(topo.triangles.ravel(), np.repeat(areas, 3), topo.n_vertices) / 6.0
        edge_values = np.bincount(topo.triangle_edges.ravel(), np.repeat(areas, 3), topo.n_edges) / 12.0
        return diagonal, edge_values

    def conformal_matrix(self, squared_lengths: np.ndarray, areas: np.ndarray) -> sp.csr_matrix:
        """Conformal product ``C(ℓ²; µ)``, eq. (2): float64 ``(n, n)`` from squared edge lengths
        ``(E,)`` and areas ``(m,)``. Positive semidefinite cotangent stiffness matrix:
        ``C_vw = Σ_{T∋(v,w)} (ℓ²_vw − ℓ²_v − ℓ²_w) / (8 µ(T))``, ``C_vv = −Σ_w C_vw``.
        """
        edge_values = self.conformal_edge_values(squared_lengths, areas)
        return self.from_entries(self.laplacian_diagonal(edge_values), edge_values)

    def conformal_edge_values(self, squared_lengths: np.ndarray, areas: np.ndarray) -> np.ndarray:
        """Per-edge off-diagonal entries ``c = B_µ ℓ²`` of ``C(ℓ²; µ)``, float64 ``(E,)``."""
        topo = self.topology
        edge_sq = squared_lengths[topo.triangle_edges]  # (m, 3), opposite each corner
        # For the edge opposite corner k: (ℓ²_k − ℓ²_{k+1} − ℓ²_{k+2}) / (8 µ).
        local = (2.0 * edge_sq - edge_sq.sum(axis=1, keepdims=True)) / (8.0 * areas[:, None])
        return np.bincount(topo.triangle_edges.ravel(), local.ravel(), topo.n_edges)

    def laplacian_diagonal(self, edge_values: np.ndarray) -> np.ndarray:
        """Diagonal making every row sum to zero: ``d_v = −Σ_{(v,w)} edge_values``, ``(n,)``."""
        topo = self.topology
        n = topo.n_vertices
        return -(
            np.bincount(topo.edges[:, 0], edge_values, n) + np.bincount(topo.edges[:, 1], edge_values, n)
        )

    # -- the linear maps recovery inverts ---------------------------------------------------
    def area_map(self) -> sp.csr_matrix:
        """The linear map µ ↦ per-edge entries of ``A(µ)``, ``A_vw = Σ_{T∋(v,w)} µ(T) / 12``, as a
        sparse float64 ``(E, m)`` matrix. Prop. 1 inverts it. The diagonal entries add nothing:
        ``A_vv`` is half the sum of the edge entries around ``v`` (every triangle at ``v`` has
        two edges at ``v``)."""
        topo = self.topology
        m = topo.n_triangles
        rows = topo.triangle_edges.ravel()
        cols = np.repeat(np.arange(m), 3)
        return sp.csr_matrix((np.full(3 * m, 1.0 / 12.0), (rows, cols)), shape=(topo.n_edges, m))

    def length_map(self, areas: np.ndarray) -> sp.csr_matrix:
        """``B_µ``: the linear map ℓ² ↦ per-edge entries of ``C(ℓ²; µ)`` for fixed areas µ, float64
        ``(E, E)`` (paper §4.2, Prop. 2)."""
        topo = self.topology
        te = topo.triangle_edges
        weight = 1.0 / (8.0 * areas)
        rows = np.concatenate([te[:, k] for k in range(3) for _ in range(3)])
        cols = np.concatenate([te[:, (k + j) % 3] for k in range(3) for j in range(3)])
        vals = np.concatenate([weight if j == 0 else -weight for k in range(3) for j in range(3)])
        return sp.csr_matrix((vals, (rows, cols)), shape=(topo.n_edges, topo.n_edges))


def pose_products(assembler: ProductAssembler, vertices: np.ndarray):
    """Everything §4.2 defines for one pose: areas µ ``(m,)``, squared edge lengths ℓ² ``(E,)``,
    and the sparse ``(n, n)`` products ``A(µ)`` and ``C(ℓ²; µ)``."""
    from .mesh_topology import triangle_areas

    areas = triangle_areas(vertices, assembler.topology.triangles)
    squared = assembler.topology.squared_edge_lengths(vertices)
    return areas, squared, assembler.mass_matrix(areas), assembler.conformal_matrix(squared, areas)
