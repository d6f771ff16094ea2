"""Offset surface and canonical thickening (paper §5.2–5.3, Figs. 5–6, proof of Prop. 4).

The offset mesh ``M_t`` has one vertex above every vertex of ``M`` (along the unit area-weighted
vertex normal) and one above every triangle's barycenter (along the face normal), both at distance
``t``. For every interior edge ``(a, b)`` of ``M``, with ``T1`` the triangle traversing it as
``a -> b`` and ``T2`` the other one, ``M_t`` has the two triangles ``(a_t, c_T2, c_T1)`` and
``(b_t, c_T1, c_T2)`` — a √3-subdivision pattern. Vertices of ``M`` touching no interior edge get no
offset vertex (they would be loose), e.g. the two one-triangle corners of a grid: a 33×33 grid gives
3135 offset vertices, 6016 triangles and 9150 edges (paper Fig. 16, "Cloth HD").

The canonical thickening fills the slab between ``M`` and ``M_t`` with tetrahedra:
*upward* ``(i, j, k, c_T)`` over each triangle, *mesh-edge* ``(a, b, c_T1, c_T2)`` over each interior
edge and *downward* ``(a, a_t, c_T2, c_T1)`` under each offset triangle (all positively oriented on
a flat sheet). All of its squared edge
lengths follow from those of ``M`` and ``M_t`` and from ``t``: normal edges ``(a, a_t)`` have
length ``t`` and a side edge ``(v, c_T)`` has ``|v − barycenter|² + t²``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import MeshError
from .mesh_topology import MeshTopology, mesh_topology, triangle_normals

#: Default offset distance as a fraction of the mean edge length of the base mesh.
DEFAULT_OFFSET_PER_EDGE_LENGTH = 0.5


def default_offset(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """The automatic offset distance t: half the mean edge length of the mesh (scales with it).

    ``vertices`` float64 ``(n, 3)``, ``triangles`` int ``(m, 3)``; :class:`MeshError` if they are
    not a valid mesh (non-finite or out-of-range coordinates, bad or negative indices, no
    triangle).
    """
    from .validation import check_triangles, check_vertices

    v = check_vertices(vertices, name="vertices")
    t = check_triangles(triangles, v.shape[0])
    lengths = [np.linalg.norm(v[t[:, (k + 1) % 3]] - v[t[:, k]], axis=1) for k in range(3)]
    return float(DEFAULT_OFFSET_PER_EDGE_LENGTH * np.mean(lengths))


@dataclass(frozen=True, eq=False)
class OffsetSurface:
    """Topology of the offset mesh ``M_t`` of a base topology and of the canonical thickening.

    Offset vertices are numbered lifted vertices first (``lifted_vertices[i]`` is the base vertex
    under offset vertex ``i``), then face centers (``centered_triangles[j]`` is the base triangle
    under offset vertex ``len(lifted_vertices) + j``).
    """

    base: MeshTopology
    topology: MeshTopology  # of the offset mesh
    lifted_vertices: np.ndarray  # (n_lift,) base vertex of each lifted offset vertex
    centered_triangles: np.ndarray  # (m_c,) base triangle of each face-center offset vertex
    center_of_triangle: np.ndarray = field(repr=False)  # (m,) offset vertex id or -1
    lift_of_vertex: np.ndarray = field(repr=False)  # (n,) offset vertex id or -1

    def positions(self, vertices: np.ndarray, offset: float) -> np.ndarray:
        """Offset vertex positions, float64 ``(n_lift + m_c, 3)``, for base ``vertices (n, 3)``."""
        base = self.base
        lifted = vertices[self.lifted_vertices] + offset * base.vertex_normals(vertices)[self.lifted_vertices]
        tris = base.triangles[self.centered_triangles]
        centers = vertices[tris].mean(axis=1) + offset * triangle_normals(vertices, tris)
        return np.concatenate([lifted, centers])

    # -- canonical thickening ------------------------------------------------------------------
    @property
    def n_thickening_points(self) -> int:
        """Base vertices first (same indices), then offset vertices shifted by ``n``."""
        return self.base.n_vertices + self.topology.n_vertices

    def thickening_points(self, vertices: np.ndarray, offset_positions: np.ndarray) -> np.ndarray:
        """Positions of every thickening point, float64 ``(n + n_offset, 3)``."""
        return np.concatenate([vertices, offset_positions])

    @property
    def thickening_edges(self) -> np.ndarray:
        """Edges of the thickening, int64 ``(K, 2)``, in blocks: base edges, offset edges, normal
        edges ``(a, a_t)``, then side edges ``(v, c_T)`` (3 per centered triangle, corner order)."""
        return _thickening_edges(self)

    def thickening_squared_lengths(
        self, base_squared_lengths: np.ndarray, offset_squared_lengths: np.ndarray, offset: float
    ) -> np.ndarray:
        """Squared lengths of :attr:`thickening_edges`, float64 ``(K,)``, from the base ``(E,)`` and
        offset ``(E_t,)`` squared edge lengths and the offset distance ``t`` (proof of Prop. 4)."""
        edge_sq = base_squared_lengths[self.base.triangle_edges[self.centered_triangles]]  # (m_c, 3)
        # Squared distance from corner k to the barycenter: (2ℓ²_{k+1} + 2ℓ²_{k+2} − ℓ²_k) / 9.
        to_barycenter = (2.0 * edge_sq.sum(axis=1, keepdims=True) - 3.0 * edge_sq) / 9.0
        return np.concatenate(
            [
                base_squared_lengths,
                offset_squared_lengths,
                np.full(len(self.lifted_vertices), offset * offset),
                (to_barycenter + offset * offset).ravel(),
            ]
        )

    @property
    def thickening_tetrahedra(self) -> np.ndarray:
        """Tetrahedra of the thickening, int64 ``(Q, 4)`` in thickening point indices, in blocks:
        upward ``(i, j, k, c_T)``, mesh-edge ``(a, b, c_T1, c_T2)``, downward ``(a, a_t, c_T2, c_T1)``.
        All have positive volume ``det[p1−p0, p2−p0, p3−p0]`` on a flat sheet; upward ones on
        every valid pose (``c_T`` lies on the normal side of ``T`` by construction)."""
        return _thickening_tetrahedra(self)


def offset_surface(base: MeshTopology) -> OffsetSurface:
    """Build the offset-mesh topology of Fig. 5 for a base topology (see module docstring).

    Raises :class:`MeshError` if the mesh has no interior edge (nothing to offset).
    """
    inner = base.interior_edges
    if inner.size == 0:
        raise MeshError(
            "The mesh has no edge shared by two triangles, so it has no offset surface and no "
            "extrinsic shape differences. Use a connected surface, or turn off extrinsic differences."
        )
    a, b = base.edges[inner, 0], base.edges[inner, 1]
    t1, t2 = base.edge_triangles[inner, 0], base.edge_triangles[inner, 1]

    lift_of_vertex = np.full(base.n_vertices, -1, dtype=np.int64)
    lifted = np.unique(np.concatenate([a, b]))
    lift_of_vertex[lifted] = np.arange(lifted.size)
    center_of_triangle = np.full(base.n_triangles, -1, dtype=np.int64)
    centered = np.unique(np.concatenate([t1, t2]))
    center_of_triangle[centered] = lifted.size + np.arange(centered.size)

    c1, c2 = center_of_triangle[t1], center_of_triangle[t2]
    triangles = np.concatenate(
        [np.stack([lift_of_vertex[a], c2, c1], axis=1), np.stack([lift_of_vertex[b], c1, c2], axis=1)]
    )
    try:
        topology = mesh_topology(triangles, lifted.size + centered.size)
    except MeshError as error:  # its indices are the offset surface's: say it in the base's terms
        raise MeshError(
            "The offset surface of this mesh is not a valid surface, so extrinsic shape differences "
            "cannot be computed; the mesh is manifold but its triangles are arranged so that their "
            "offsets overlap. Turn off extrinsic differences (use_extrinsic=False) or remesh. "
            f"(Offset surface: {error})"
        ) from error
    return OffsetSurface(
        base=base,
        topology=topology,
        lifted_vertices=lifted,
        centered_triangles=centered,
        center_of_triangle=center_of_triangle,
        lift_of_vertex=lift_of_vertex,
    )


def _thickening_edges(surface: OffsetSurface) -> np.ndarray:
    n = surface.base.n_vertices
    lifted = surface.lifted_vertices
    centers = n + surface.center_of_triangle[surface.centered_triangles]
    corners = surface.base.triangles[surface.centered_triangles]  # (m_c, 3)
    return np.concatenate(
        [
            surface.base.edges,
            n + surface.topology.edges,
            np.stack([lifted, n + surface.lift_of_vertex[lifted]], axis=1),
            np.stack([corners.ravel(), np.repeat(centers, 3)], axis=1),
        ]
    ).astype(np.int64)


def _thickening_tetrahedra(surface: OffsetSurface) -> np.ndarray:
    base, n = surface.base, surface.base.n_vertices
    upward = np.concatenate(
        [base.triangles[surface.centered_triangles], (n + surface.center_of_triangle[surface.centered_triangles])[:, None]],
        axis=1,
    )
    inner = base.interior_edges
    c1 = n + surface.center_of_triangle[base.edge_triangles[inner, 0]]
    c2 = n + surface.center_of_triangle[base.edge_triangles[inner, 1]]
    mesh_edge = np.stack([base.edges[inner, 0], base.edges[inner, 1], c1, c2], axis=1)
    offset_tris = surface.topology.triangles + n
    apex = surface.lifted_vertices[offset_tris[:, 0] - n]
    downward = np.concatenate([apex[:, None], offset_tris], axis=1)
    return np.concatenate([upward, mesh_edge, downward]).astype(np.int64)


def check_offset_pose(surface: OffsetSurface, vertices: np.ndarray, offset: float, *, name: str = "vertices",
                      vertex_ids: np.ndarray | None = None, unit: float = 1.0) -> None:
    """Raise :class:`MeshError`, naming the base mesh's edge, if the offset surface of a pose
    ``vertices (n, 3)`` at distance ``offset`` has a degenerate triangle (the offsets of two
    neighbouring triangles collapse onto each other, e.g. a fold much sharper than the offset
    distance). Offset triangle ``j`` lies over the base's ``j % E_inner``-th interior edge;
    ``vertex_ids`` maps the base's vertex indices to the caller's (loose vertices removed);
    ``unit``: the scale of ``vertices`` and ``offset`` against the caller's units (the message quotes
    the offset in the caller's)."""
    from .mesh_topology import DEGENERATE_TRIANGLE_RATIO

    positions = surface.positions(vertices, offset)
    tris = surface.topology.triangles
    p0, p1, p2 = (positions[tris[:, k]] for k in range(3))
    doubled = np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
    longest = np.max([np.einsum("ij,ij->i", a - b, a - b) for a, b in ((p1, p2), (p2, p0), (p0, p1))], axis=0)
    bad = np.flatnonzero(~(doubled > DEGENERATE_TRIANGLE_RATIO * longest))
    if bad.size:
        inner = surface.base.interior_edges
        a, b = surface.base.edges[inner[bad[0] % inner.size]]
        if vertex_ids is not None:
            a, b = vertex_ids[a], vertex_ids[b]
        raise MeshError(
            f"{name}: the offset surface at distance {offset / unit:g} collapses over the edge ({a}, {b}) "
            f"({bad.size} offset triangle(s) in all): the triangles on either side fold onto each "
            "other at this distance. Use a smaller offset, or turn off extrinsic differences."
        )
