"""Recovery of triangle areas and squared edge lengths from full-basis products (paper §4.2,
Props. 1–2, appendix): two sparse linear solves.

- Areas µ from ``A = A(µ)``: the entries of ``A`` are sums of the areas of the triangles around an
  edge (``/12``) or a vertex (``/6``). The least-squares system is singular exactly when a closed
  connected component has only even-valence vertices (its dual graph is bipartite, so alternating
  ±1 areas are invisible) — Prop. 1's condition — which is checked combinatorially.
- Squared lengths ℓ² from the per-edge entries of ``C = C(ℓ²; µ)`` with µ fixed: a square sparse
  system ``B_µ ℓ² = c``. It is singular for rare area distributions (Fig. 2: two tetrahedra glued
  at their bases with equal areas); an estimate of its condition number rejects those.
"""

from __future__ import annotations

import numpy as np

from .errors import RecoveryError
from .inner_products import ProductAssembler
from .mesh_topology import MeshTopology

#: Above this estimated 1-norm condition number the length system is treated as singular.
SINGULAR_CONDITION = 1e12


class AreaRecovery:
    """Prop. 1 for one topology: factorizes the normal equations of µ ↦ entries of ``A(µ)`` once,
    then recovers the areas of any number of targets with two triangular solves each."""

    def __init__(self, assembler: ProductAssembler):
        self.assembler = assembler
        check_area_recoverable(assembler.topology)
        self._map = assembler.area_map().tocsc()
        normal = (self._map.T @ self._map).tocsc()
        from scipy.sparse.linalg import splu

        self._factor = splu(normal)

    def solve(self, diagonal: np.ndarray, edge_values: np.ndarray) -> np.ndarray:
        """Areas µ ``(m,)`` from the diagonal ``(n,)`` and per-edge ``(E,)`` entries of ``A``."""
        rhs = self._map.T @ np.concatenate([edge_values, diagonal])
        return self._factor.solve(rhs)


def check_area_recoverable(topology: MeshTopology) -> None:
    """Raise :class:`RecoveryError` if some connected component is closed and all its vertices
    have even valence (Prop. 1: then ``A(µ)`` does not determine µ)."""
    count, labels = topology.components()
    has_boundary = np.zeros(count, dtype=bool)
    boundary_triangles = topology.edge_triangles[topology.boundary_edges].max(axis=1)
    has_boundary[labels[boundary_triangles]] = True
    valence = np.bincount(topology.edges.ravel(), minlength=topology.n_vertices)
    odd_vertex = valence % 2 == 1
    has_odd = np.zeros(count, dtype=bool)
    vertex_component = np.full(topology.n_vertices, -1)
    vertex_component[topology.triangles.ravel()] = np.repeat(labels, 3)
    has_odd[vertex_component[odd_vertex & (vertex_component >= 0)]] = True
    bad = np.flatnonzero(~has_boundary & ~has_odd)
    if bad.size:
        first = int(np.flatnonzero(labels == bad[0])[0])
        raise RecoveryError(
            f"The closed part of the mesh containing triangle {first} has only even-valence "
            "vertices, so its triangle areas cannot be recovered from the area-based shape "
            "difference (paper Prop. 1; e.g. an octahedron). Triangulate it differently (any "
            "vertex of odd valence suffices), e.g. flip one edge (Mesh > Edge > Rotate Edge)."
        )


def recover_squared_lengths(
    assembler: ProductAssembler, areas: np.ndarray, edge_values: np.ndarray, *, what: str = "mesh"
) -> np.ndarray:
    """Prop. 2: squared edge lengths ℓ² ``(E,)`` from the per-edge entries ``c`` ``(E,)`` of
    ``C(ℓ²; µ)`` and the (recovered) areas µ ``(m,)`` by one sparse LU solve of ``B_µ ℓ² = c``.

    Raises :class:`RecoveryError` when ``B_µ`` is singular or nearly so (paper Fig. 2).
    """
    if not (np.all(np.isfinite(areas)) and np.all(areas > 0)):
        bad = int(np.flatnonzero(~(areas > 0))[0])
        raise RecoveryError(
            f"The recovered area of triangle {bad} of the {what} is {areas[bad]:.3g}: edge lengths "
            "need positive areas. The shape difference does not describe a valid mesh."
        )
    from scipy.sparse.linalg import LinearOperator, onenormest, splu

    matrix = assembler.length_map(areas).tocsc()
    try:
        factor = splu(matrix)
    except RuntimeError as error:  # exactly singular
        raise _singular_length_system(what) from error
    n = matrix.shape[0]
    inverse = LinearOperator(
        (n, n), matvec=factor.solve, rmatvec=lambda x: factor.solve(x, trans="T"), dtype=np.float64
    )
    condition = onenormest(matrix) * onenormest(inverse)
    if not np.isfinite(condition) or condition > SINGULAR_CONDITION:
        raise _singular_length_system(what, condition)
    return factor.solve(edge_values)


def _singular_length_system(what: str, condition: float | None = None) -> RecoveryError:
    detail = "" if condition is None else f" (condition number ≈ {condition:.2g})"
    return RecoveryError(
        f"The conformal shape difference of the {what} does not determine its edge lengths for "
        f"these triangle areas{detail}: the linear system of Prop. 2 is singular, as for two "
        "tetrahedra glued at their bases with equal areas (paper Fig. 2). Perturb the mesh "
        "slightly or remesh it."
    )
