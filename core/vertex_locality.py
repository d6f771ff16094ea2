"""Whether a mesh's vertex order keeps neighbours near each other in memory, and an order that does
where it does not (the in-betweens, :mod:`core.sequence_keys`).

Every product of the in-betweens' fits (the corner edges, the sparse matrices of a solve's
right-hand side, the factorization) reads the vertices of each triangle or edge together. In
Blender's own orders (grids, subdivisions, primitives, loop cuts, Decimate) an edge's two ends are
a few rows or one grid row apart; a scan's or an exporter's order can scatter them over the whole
mesh, and where the mesh's arrays no longer fit in the processor's cache each such read waits on
memory. Measured with the cube-edge sheets' vertices and triangles shuffled: at 100k the
right-hand side's sparse products 3.3–3.8 ×, the corner edges 1.1–1.7 ×, a factorization 1.2–1.3 ×
those of Blender's order; a whole sequence 1.1–1.6 × at 50k and 1.2–1.9 × at 100k, two poses
1.3–1.5 × (docs/design-decisions.md).

:func:`local_order` reads the median over the edges of ``|i − j|``, the distance in the order
between an edge's two ends, once per topology: on every benchmark bake and every unseen bake or
mesh at hand it is at most 640 (a twisted ribbon of 11,520 vertices; a grid's is one row, 316 at
100k) or, on Delaunay triangulations of random points (already in a random order), 2,800–3,900
at 10k–15k vertices, where a random order costs nothing measurable (the arrays fit in the
cache). From
:data:`SCATTERED_SPAN` the vertices are renumbered by reverse Cuthill–McKee
(``scipy.sparse.csgraph.reverse_cuthill_mckee``: neighbours get nearby numbers, the bandwidth of
the adjacency small) and the triangles sorted by their first vertex in that order
(:func:`renumbered`); the in-betweens run in that order and are given back in the caller's. A
random order reaches the span from about 28,000 vertices (its median ``|i − j|`` is about 0.29 n).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import reverse_cuthill_mckee

from .mesh_topology import MeshTopology, mesh_topology

#: The median ``|i − j|`` over the edges from which a vertex order is renumbered: 8,192 vertices
#: (192 kB of float64 coordinates), twice the most any mesh in a Blender order or any Delaunay
#: mesh at hand gives (3,943 at 13,882 vertices, whose renumbering changed no cost).
SCATTERED_SPAN = 8192


def order_span(topology: MeshTopology) -> float:
    """The median over the edges of ``topology`` of ``|i − j|``, how far apart in the vertex order
    an edge's two ends are; 0.0 for a mesh without edges."""
    edges = topology.edges
    return float(np.median(edges[:, 1] - edges[:, 0])) if len(edges) else 0.0


def local_order(topology: MeshTopology) -> np.ndarray | None:
    """The vertices of ``topology`` in a local order, int64 ``(n,)`` (the old index of each new
    vertex: reverse Cuthill–McKee over its edges), where its own order scatters them
    (:func:`order_span` at least :data:`SCATTERED_SPAN`); None where it keeps them together."""
    if order_span(topology) < SCATTERED_SPAN:
        return None
    n, edges = topology.n_vertices, topology.edges
    graph = coo_matrix((np.ones(len(edges), dtype=np.int8), (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    return reverse_cuthill_mckee(graph + graph.T, symmetric_mode=True).astype(np.int64)


def renumbered(topology: MeshTopology, order: np.ndarray) -> tuple[MeshTopology, np.ndarray]:
    """``topology`` with its vertices in ``order`` (int ``(n,)``, the old index of each new vertex)
    and its triangles sorted by their smallest new vertex: the new topology and the old index of
    each new triangle, int64 ``(m,)``. Corner order (so orientation) is kept."""
    inverse = np.empty_like(order)
    inverse[order] = np.arange(len(order))
    triangles = inverse[topology.triangles]
    triangle_order = np.argsort(triangles.min(axis=1), kind="stable")
    return mesh_topology(triangles[triangle_order], topology.n_vertices, allow_bow_ties=True), triangle_order
