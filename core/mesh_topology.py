"""Mesh topology and input validation (paper §4.2: a manifold, orientable triangle mesh).

Conventions used throughout :mod:`core`:

- ``vertices``: float64 ``(n, 3)``; ``triangles``: int64 ``(m, 3)``, counter-clockwise seen from
  the outside (the side the normals point to).
- Corner ``k`` of triangle ``t`` is vertex ``triangles[t, k]``; the edge *opposite* corner ``k``
  joins corners ``k+1`` and ``k+2`` (mod 3) and is ``triangle_edges[t, k]``.
- ``edges``: int64 ``(E, 2)`` with ``edges[e, 0] < edges[e, 1]``.
- ``edge_triangles[e, 0]`` is the triangle that traverses edge ``e`` as
  ``edges[e, 0] -> edges[e, 1]``, ``edge_triangles[e, 1]`` the one traversing it backwards;
  ``-1`` where there is none (a boundary edge).
"""

from __future__ import annotations

import math

from dataclasses import dataclass, field

import numpy as np

from .coordinate_rounding import coordinate_rounding
from .errors import MeshError
from .validation import check_triangles, check_vertices  # noqa: F401 (re-exported)

#: A triangle whose doubled area is below this fraction of its longest squared edge is degenerate.
DEGENERATE_TRIANGLE_RATIO = 1e-10

_FIX_MANIFOLD = (
    "Shape differences need a manifold mesh: in Blender use Select > Select All by Trait > "
    "Non Manifold, then fix or delete the selected geometry."
)


def triangle_areas(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Triangle areas µ, float64 ``(m,)`` (paper §4.2)."""
    p0, p1, p2 = (vertices[triangles[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)


def triangle_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit face normals, float64 ``(m, 3)``, oriented by the counter-clockwise corner order."""
    p0, p1, p2 = (vertices[triangles[:, k]] for k in range(3))
    normals = np.cross(p1 - p0, p2 - p0)
    return normals / np.linalg.norm(normals, axis=1, keepdims=True)


@dataclass(frozen=True, eq=False)
class MeshTopology:
    """Connectivity of a triangle mesh, computed once and shared by every pose of it.

    Build it with :func:`mesh_topology`, which validates the input. All arrays are int64.
    """

    n_vertices: int
    triangles: np.ndarray  # (m, 3)
    edges: np.ndarray  # (E, 2), edges[:, 0] < edges[:, 1]
    triangle_edges: np.ndarray  # (m, 3), edge opposite each corner
    edge_triangles: np.ndarray  # (E, 2), forward / backward triangle, -1 if none
    used_vertices: np.ndarray = field(repr=False)  # (n_used,) vertices in at least one triangle

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    @property
    def n_edges(self) -> int:
        return int(self.edges.shape[0])

    @property
    def boundary_edges(self) -> np.ndarray:
        """Indices of edges with a single triangle, int64 ``(B,)``."""
        # the two columns compared one by one: 8× faster than any() along rows of two
        return np.flatnonzero((self.edge_triangles[:, 0] < 0) | (self.edge_triangles[:, 1] < 0))

    @property
    def interior_edges(self) -> np.ndarray:
        """Indices of edges with two triangles, int64 ``(E - B,)``."""
        # the two columns compared one by one: 8× faster than all() along rows of two
        return np.flatnonzero((self.edge_triangles[:, 0] >= 0) & (self.edge_triangles[:, 1] >= 0))

    @property
    def loose_vertices(self) -> np.ndarray:
        """Vertices in no triangle (allowed; they are carried along unchanged)."""
        mask = np.ones(self.n_vertices, dtype=bool)
        mask[self.used_vertices] = False
        return np.flatnonzero(mask)

    def squared_edge_lengths(self, vertices: np.ndarray) -> np.ndarray:
        """Squared edge lengths ℓ², float64 ``(E,)``."""
        d = vertices[self.edges[:, 0]] - vertices[self.edges[:, 1]]
        return np.einsum("ij,ij->i", d, d)

    def vertex_normals(self, vertices: np.ndarray) -> np.ndarray:
        """Unit area-weighted vertex normals, float64 ``(n, 3)`` (zero for loose vertices)."""
        t = self.triangles
        weighted = np.cross(vertices[t[:, 1]] - vertices[t[:, 0]], vertices[t[:, 2]] - vertices[t[:, 0]])
        normals = np.zeros((self.n_vertices, 3))
        for k in range(3):
            np.add.at(normals, t[:, k], weighted)
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        return np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)

    def components(self) -> tuple[int, np.ndarray]:
        """Connected components over triangles: (count, label per triangle int64 ``(m,)``). Found
        once per topology (the checks of the input and the in-betweens' setup each ask); every
        caller gets its own copy of the labels."""
        found = self.__dict__.get("_components")
        if found is None:
            from scipy.sparse import coo_matrix
            from scipy.sparse.csgraph import connected_components

            inner = self.edge_triangles[self.interior_edges]
            m = self.n_triangles
            graph = coo_matrix((np.ones(len(inner)), (inner[:, 0], inner[:, 1])), shape=(m, m))
            count, labels = connected_components(graph, directed=False)
            found = (int(count), labels.astype(np.int64))
            object.__setattr__(self, "_components", found)  # frozen: the cache is not a field
        return found[0], found[1].copy()

    def check_pose(self, vertices, *, name: str = "vertices") -> np.ndarray:
        """Validate one pose of this mesh: shape, vertex count, finite, range, size, no degenerate
        triangle (:func:`core.validation.check_pose`)."""
        from .validation import check_pose

        return check_pose(vertices, self, name=name)


def _triangle_measures(vertices: np.ndarray, triangles: np.ndarray):
    """``(by_coordinate (3, n), doubled areas (m,), squared side lengths [3 × (m,)], longest (m,))``."""
    from .geometry import coordinate_cross, coordinate_dot

    by_coordinate = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)  # contiguous rows: 3× faster
    # (3 coordinates, 3 corners, m) in one gather: 3× faster than a fancy index per corner
    p0, p1, p2 = np.moveaxis(np.take(by_coordinate, np.asarray(triangles).T, axis=1), 1, 0)
    first, second = p1 - p0, p2 - p0
    cross = coordinate_cross(first, second)
    with np.errstate(over="ignore", invalid="ignore"):
        doubled_area = np.sqrt(coordinate_dot(cross, cross))
        # the sides p2 − p0 and p0 − p1 are those of the cross product (a difference and its
        # negation square alike): one more difference per coordinate, not six
        opposite = p1 - p2
        squared = [coordinate_dot(opposite, opposite), coordinate_dot(second, second), coordinate_dot(first, first)]
        longest = np.maximum(np.maximum(squared[0], squared[1]), squared[2])
    return by_coordinate, doubled_area, squared, longest


def zero_area_triangles(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Indices of the ``triangles`` whose area is (numerically) zero, as :func:`check_nondegenerate`
    finds them (one that overflows counts too)."""
    _, doubled_area, _, longest = _triangle_measures(vertices, triangles)
    with np.errstate(over="ignore", invalid="ignore"):
        return np.flatnonzero(~(doubled_area > DEGENERATE_TRIANGLE_RATIO * longest))


def check_nondegenerate(vertices: np.ndarray, triangles: np.ndarray, *, name: str = "vertices",
                        earlier=None) -> None:
    """Raise :class:`MeshError` naming the first triangle whose area is (numerically) zero.
    ``earlier``: ``(first name, poses)``, the keys checked before this one (a list of (n, 3), the
    first named so), where ``vertices`` is a later key: flat triangles that the keys' decimal
    rounding flattened are told so (:func:`_rounded_flat_advice`), not as the mesh's."""
    by_coordinate, doubled_area, squared, longest = _triangle_measures(vertices, triangles)
    with np.errstate(over="ignore", invalid="ignore"):
        overflow = ~np.isfinite(doubled_area) | ~np.isfinite(longest)
    if overflow.any():
        t = int(np.flatnonzero(overflow)[0])
        raise MeshError(
            f"{name}: triangle {t} (vertices {triangles[t].tolist()}) is too large to measure in "
            "floating point (its squared edge lengths overflow). Scale the mesh down (in Blender: "
            "scale the object, then Object > Apply > Scale), or fix the vertices of that triangle."
        )
    bad = np.flatnonzero(~(doubled_area > DEGENERATE_TRIANGLE_RATIO * longest))
    if bad.size:
        t = int(bad[0])
        stray = _stray_vertex(t, doubled_area, squared, longest)
        if stray is not None:
            corner, edges = stray
            raise MeshError(
                f"{name}: vertex {int(triangles[t][corner])} lies {float(np.sqrt(longest[t])):.3g} from the other "
                f"corners of triangle {t} (vertices {triangles[t].tolist()}), {edges:.3g} × the mesh's median edge, "
                f"so its triangles are needles too thin to measure ({bad.size} degenerate triangle(s) in all). "
                "Fix that vertex (a simulation that exploded there, a broken frame of a cache) or leave that pose out."
            )
        raise MeshError(
            f"{name}: triangle {t} (vertices {triangles[t].tolist()}) has zero area "
            f"({bad.size} degenerate triangle(s) in all). "
            + (_far_out_advice(by_coordinate, squared) or
               (_rounded_flat_advice(by_coordinate.T, triangles, bad, name, *earlier) if earlier else None) or
               "Remove degenerate faces: in Blender use Mesh > Clean Up > Degenerate Dissolve, or Merge "
               "by Distance. If only this pose flattens them (a shape key that scales a part to a "
               "point, a frame that crushes the cloth), scale that part to a small size instead of "
               "zero, or leave that pose out.")
        )


#: Length, in median edges of the mesh, past which a degenerate triangle's longest edge is told as
#: a vertex gone astray rather than a flat face: a vertex shot 1e12 away on a 0.14-edge sheet
#: makes needles of area/edge² ~1e-14 that were reported as of "zero area".
STRAY_EDGES = 1e3


def _stray_vertex(t: int, doubled_area: np.ndarray, squared: list[np.ndarray], longest: np.ndarray):
    """``(corner, edges)`` where degenerate triangle ``t`` has an area and its longest edge is over
    :data:`STRAY_EDGES` median edges of the mesh (``edges``: how many): its corner opposite the
    shortest side lies far from the rest; else None (a flat face)."""
    median = float(np.sqrt(np.median(np.concatenate(squared))))
    if not (doubled_area[t] > 0 and np.isfinite(longest[t]) and np.sqrt(longest[t]) > STRAY_EDGES * median):
        return None
    corner = int(np.argmin([squared[k][t] for k in range(3)]))  # squared[k]: the side opposite corner k
    return corner, float(np.sqrt(longest[t])) / median


#: Rounding of the coordinates, as a share of the median edge length, above which a mesh's flat
#: triangles are blamed on the precision of coordinates far from the origin: a triangle less high
#: than the rounding can land on one line of the coordinate grid (a 1,000-vertex flag 1e6 units out
#: in single precision, rounded to 0.12 against edges of 0.06: 592 triangles flat; at the origin a
#: sliver of the mesh itself, rounded to 1e-7 of its edges).
FAR_OUT_ROUNDING = 1e-2


def _far_out_advice(by_coordinate: np.ndarray, squared: list[np.ndarray]) -> str | None:
    """The advice for flat triangles where the coordinates' own rounding (single precision where
    every coordinate is a float32, as Blender stores them) reaches :data:`FAR_OUT_ROUNDING` of the
    median edge of the mesh (``squared``: the corners' squared edge lengths, 3 arrays (m,)), else
    None: there the mesh is too far from its origin for its triangles, not degenerate itself."""
    rounding = coordinate_rounding([by_coordinate.T])
    median_edge = float(np.sqrt(np.median(np.concatenate(squared))))
    if not rounding >= FAR_OUT_ROUNDING * median_edge:
        return None
    largest = float(np.max(np.abs(by_coordinate)))
    # a mesh whose coordinates all round to a few grid points has a median edge of zero
    share = f"{rounding / median_edge:.0%} of its median edge, {median_edge:.2g}" if median_edge > 0 else \
        "more than most of its edges are long"
    return (f"The mesh lies {largest:.3g} units from its origin, where its coordinates are rounded in steps of up to "
            f"{rounding:.2g} ({share}): "
            "triangles less high than that read as flat. Move the mesh's origin near it (in Blender: "
            "Object > Set Origin > Origin to Geometry, then bake the simulation again).")


#: Decimals more than the keys' that :func:`_rounded_flat_advice` tells the user to export with: a
#: triangle the rounding flattened was at most √3 steps high (each corner moves at most √3/2 of a
#: step), how much less is lost. On the 19 benchmark bakes rounded to 4 decimals (and ×0.01 to 6),
#: where 1 to 9 keys flattened 4 to 32 triangles, 2 more kept every triangle of every key; 1 more
#: left 2 flat on the 100k sheet (docs/inbetween-measurements.md, *Keys flattened by their rounding*).
ROUNDED_FLAT_DECIMALS = 2


def _rounded_flat_advice(vertices: np.ndarray, triangles: np.ndarray, bad: np.ndarray, name: str,
                         first_name: str, keys: list) -> str | None:
    """The advice for the flat triangles ``bad`` (indices into ``triangles`` (m, 3)) of a later key
    ``vertices`` (n, 3), named ``name``, where it and the keys before it (``keys``: (n, 3) each, the
    first named ``first_name``, in which every triangle has an area) lie on a decimal grid
    (:func:`core.coordinate_rounding.decimal_rounding`: exported with a fixed count of decimals):
    the export's rounding flattened them, not the mesh (no frame of the 19 benchmark bakes, stored in
    single precision, has a flat triangle). None where the keys are on no decimal grid, or on one as
    coarse as their edges (:func:`core.coordinate_rounding.built_on_grid`: a voxel mesh, a Grid
    primitive, whose key collapsing a part is the mesh's doing)."""
    from .coordinate_rounding import built_on_grid, decimal_rounding

    poses, edges = list(keys) + [vertices], triangles[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2)
    step = decimal_rounding(poses, edges)
    if not step > 0 or built_on_grid(poses, edges):  # keys on a grid as coarse as their edges: the mesh's own
        return None
    places = round(-math.log10(step))
    more, finer = 10 ** ROUNDED_FLAT_DECIMALS, places + ROUNDED_FLAT_DECIMALS
    return (f"Every key so far is rounded to {places} decimal(s) (steps of {step:.0e}), and {first_name} has those "
            f"triangle(s) whole: {name}'s rounding flattened them (a triangle less than about two steps high "
            f"can land on one line), not the mesh. Export the keys with more decimals (try {finer}: each one "
            f"more keeps triangles 10 × thinner), or scale the object up {more:g} × before exporting them "
            "(and down after in-betweening).")


def mesh_topology(triangles, n_vertices: int, *, allow_non_manifold: bool = False,
                  allow_bow_ties: bool = False) -> MeshTopology:
    """Validate ``triangles`` (int ``(m, 3)``) of a mesh with ``n_vertices`` vertices and build its
    topology: edges, triangle→edge and edge→triangle incidence, boundary.

    Raises :class:`MeshError` (a ``ValueError``) for fewer than one triangle, indices out of range
    or not whole numbers, a vertex repeated in a triangle, an edge shared by more than two
    triangles, a non-manifold ("bow-tie") vertex, or inconsistent orientation. Geometry checks (degenerate triangles, non-finite coordinates) are in
    :meth:`MeshTopology.check_pose`. Loose vertices are allowed.

    ``allow_non_manifold`` (for targets of a cross-mesh transfer only, never a base): edges shared
    by more than two triangles or traversed twice in one direction are kept (the mass and
    conformal matrices are sums over triangles, well defined) but get no ``edge_triangles``
    (``-1, -1``: neither interior nor a hinge of the offset surface); bow-tie vertices pass.
    ``allow_bow_ties`` (for a mesh split along seams, checked once welded: the in-betweens): bow-tie
    vertices pass (:func:`check_manifold_vertices` refuses them later where the weld leaves them).
    """
    tris = check_triangles(triangles, n_vertices)

    m = tris.shape[0]
    # Half-edge opposite corner k goes from corner k+1 to corner k+2.
    tails = tris[:, [1, 2, 0]].ravel()
    heads = tris[:, [2, 0, 1]].ravel()
    low, high = np.minimum(tails, heads), np.maximum(tails, heads)
    keys = low * n_vertices + high
    unique_keys, edge_of_halfedge, counts = np.unique(keys, return_inverse=True, return_counts=True)
    edge_of_halfedge = edge_of_halfedge.reshape(-1)
    non_manifold = counts > 2
    if non_manifold.any() and not allow_non_manifold:
        _check_duplicate_triangles(tris)  # the usual cause, named as such
        bad = np.flatnonzero(non_manifold)
        e = int(bad[0])
        owners = np.flatnonzero(edge_of_halfedge == e) // 3
        named = ", ".join(str(divmod(int(unique_keys[i]), n_vertices)) for i in bad[:10])
        raise MeshError(
            f"Edge {divmod(int(unique_keys[e]), n_vertices)} is shared by {counts[e]} triangles "
            f"({owners.tolist()}); {bad.size} edge(s) are shared by more than two triangles: {named}"
            f"{', ...' if bad.size > 10 else ''}. " + _FIX_MANIFOLD
        )
    edges = np.stack(np.divmod(unique_keys, n_vertices), axis=1).astype(np.int64)
    n_edges = edges.shape[0]

    forward = tails < heads  # half-edge runs edges[e,0] -> edges[e,1]
    slot = np.where(forward, 0, 1)
    edge_triangles = np.full((n_edges, 2), -1, dtype=np.int64)
    owner = np.repeat(np.arange(m, dtype=np.int64), 3)
    # Two half-edges of one edge in the same direction means the two triangles disagree.
    occupancy = np.bincount(2 * edge_of_halfedge + slot, minlength=2 * n_edges).reshape(n_edges, 2)
    inconsistent = (occupancy > 1).any(axis=1)
    if allow_non_manifold:
        keep = ~(non_manifold | inconsistent)[edge_of_halfedge]
        edge_triangles[edge_of_halfedge[keep], slot[keep]] = owner[keep]
    elif inconsistent.any():
        e = int(np.flatnonzero((occupancy > 1).any(axis=1))[0])
        owners = np.flatnonzero(edge_of_halfedge == e) // 3
        raise MeshError(
            f"Triangles {owners[0]} and {owners[1]} traverse edge ({edges[e, 0]}, {edges[e, 1]}) "
            "in the same direction: the mesh orientation is inconsistent (or the surface is not "
            "orientable). In Blender select all and use Mesh > Normals > Recalculate Outside."
        )
    else:
        edge_triangles[edge_of_halfedge, slot] = owner

    topology = MeshTopology(
        n_vertices=int(n_vertices),
        triangles=tris,
        edges=edges,
        triangle_edges=edge_of_halfedge.reshape(m, 3).astype(np.int64),
        edge_triangles=edge_triangles,
        used_vertices=np.flatnonzero(np.bincount(tris.ravel(), minlength=n_vertices)),
    )
    if not (allow_non_manifold or allow_bow_ties):
        check_manifold_vertices(topology)
    return topology


def _check_duplicate_triangles(tris: np.ndarray) -> None:
    """Raise :class:`MeshError` naming the triangles of ``tris`` (m, 3) that use the same three
    vertices as an earlier one (a face duplicated in place, as a scan's or an importer's doubles
    leave: each of its edges is then shared by three or more triangles)."""
    _, first, inverse = np.unique(np.sort(tris, axis=1), axis=0, return_index=True, return_inverse=True)
    repeated = np.flatnonzero(first[inverse.ravel()] != np.arange(len(tris)))
    if repeated.size:
        t = int(repeated[0])
        raise MeshError(
            f"Triangle {t} uses the same three vertices as triangle {int(first[inverse.ravel()[t]])}: "
            f"{repeated.size} triangle(s) duplicate another in place. In Blender, Edit Mode, "
            "Select > Select All by Trait > Interior Faces selects them: delete one of each pair.")


def check_manifold_vertices(topology: MeshTopology) -> None:
    """Raise :class:`MeshError` naming the vertices of ``topology`` whose triangles form more than
    one fan ("bow-tie" vertices, where two sheets touch at a single vertex). Corners of one vertex
    are joined when their triangles share an edge at that vertex; a manifold vertex has one group."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    tris, n_vertices = topology.triangles, topology.n_vertices

    inner = topology.interior_edges
    # Corner 3t + k is vertex tris[t, k]; half-edge 3t + k (opposite corner k) runs from corner
    # k + 1 to corner k + 2 of triangle t, forward (slot 0 of edge_triangles) where that goes from
    # the lower vertex to the higher. The half-edge in each slot of each edge, by one scatter.
    half = topology.triangle_edges.ravel()
    corners = half.size
    at = np.empty(2 * topology.edges.shape[0], dtype=np.int64)
    at[2 * half + (tris[:, [1, 2, 0]] > tris[:, [2, 0, 1]]).ravel()] = np.arange(corners)
    forward, backward = at[2 * inner], at[2 * inner + 1]
    tail, head = np.array([1, 1, -2]), np.array([2, -1, -1])  # half-edge → its tail's, head's corner
    k1, k2 = forward % 3, backward % 3
    # an inner edge joins the forward half-edge's tail to the backward one's head (the edge's lower
    # vertex) and its head to the backward one's tail (the higher)
    rows = np.concatenate([forward + tail[k1], forward + head[k1]])
    cols = np.concatenate([backward + head[k2], backward + tail[k2]])
    graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(corners, corners))
    n_fans, fan = connected_components(graph, directed=False)
    vertex = tris.ravel()
    # the corners of a fan share its vertex (the graph joins only corners of one vertex): the fans
    # per vertex are a count of each fan's vertex
    fan_vertex = np.empty(n_fans, dtype=np.int64)
    fan_vertex[fan] = vertex
    fans = np.bincount(fan_vertex, minlength=n_vertices)
    bad = np.flatnonzero(fans > 1)
    if bad.size:
        first = int(bad[0])
        groups = [np.flatnonzero((vertex == first) & (fan == f)) // 3 for f in np.unique(fan[vertex == first])]
        shown = ", ".join(str(g.tolist()) for g in groups[:3])
        listed = bad[:10].tolist()
        raise MeshError(
            f"Vertices {listed}{' ...' if bad.size > 10 else ''} ({bad.size} in all) are non-manifold "
            f"(\"bow-tie\"): the triangles around each form separate fans that touch only at that "
            f"vertex (vertex {first}: fans of triangles {shown}). Shape differences need a manifold "
            "mesh. In Blender use Select > Select All by Trait > Non Manifold (with Vertices on), "
            "then split each selected vertex into one per fan (Vertex > Rip Vertices, V) or delete "
            "the faces that touch the rest only at that vertex."
        )
