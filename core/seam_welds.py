"""Seam welds: pieces of one mesh whose boundary vertices coincide in every pose, joined into one.

Garments exported panel by panel (Marvelous Designer's "unweld", OBJ and FBX writers that split
vertices along UV seams, an Edge Split applied before caching) arrive as pieces that touch along
seams without sharing vertices. Per-vertex interpolation keeps coincident vertices together; the
in-betweens (:mod:`core.sequence_inbetweens`, :mod:`core.two_pose_inbetweens`) reconstruct each piece from its own rotations and
stretches, and a piece has no reason to meet its neighbour there: a 10k sheet cut in two along a
row of coincident vertices opened by 1–13 mean edge lengths at keys 8 and 16 frames apart. Such
vertices are welded for the interpolation and written back to every copy.

:func:`seam_weld` finds them: boundary edges whose ends sit within :func:`coincidence_tolerance`
of another boundary edge's in every pose (pieces touching at a single point are not seams), and
loose vertices at a vertex of the mesh (:func:`core.loose_vertices.loose_copies`). Pieces wound
against the ones they are welded to are turned over in the weld (:func:`oriented_pieces`). Where
two sewn sides meet at a corner, a triangle whose three corners are all on seams would lie on its
twin once welded: its corners stay apart and the seams are welded up to them
(:func:`_stacked_corners`). The weld is used only where the welded mesh is a valid one (manifold,
orientable, no triangle losing a corner); otherwise the pieces stay apart and a warning says the
seams may open. The analyses, which compare the pieces each on its own, measure the folds along
the seams (:mod:`core.seam_folds`), and a reconstruction glues its pieces along them
(:mod:`core.seam_gluing`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import MeshError
from .geometry import edge_lengths, vertex_labels
from .loose_vertices import loose_copies


#: Vertices closer than this fraction of the first pose's bounding-box diagonal (plus a few
#: float32 roundings of their coordinates) count as one place: single-precision caches written
#: through an object transform round coincident vertices apart by ~1e-7 of the diagonal ...
COINCIDENCE_TOLERANCE = 1e-5
#: ... but never farther apart than this share of the mean edge length: far from the origin the
#: float32 roundings alone grow past the edges (8 of them are 0.1 units at 1e5 units out), and
#: neighbouring vertices would count as one place.
COINCIDENCE_EDGE_SHARE = 0.01


@dataclass(frozen=True)
class SeamWeld:
    """Coincident vertices merged: ``kept`` (n_welded,) the original vertex standing for each
    welded vertex, ``copies`` (n,) the welded vertex of each original one (``x_welded[copies]``
    puts a welded pose back on every copy), ``triangles`` (m, 3) in welded indices and
    ``topology`` their :func:`core.mesh_topology.mesh_topology`."""

    kept: np.ndarray
    copies: np.ndarray
    triangles: np.ndarray
    topology: object


def coincidence_tolerance(first: np.ndarray, edges: np.ndarray, scale: float | None = None) -> float:
    """The distance (float) under which two vertices of pose ``first`` (n, 3) are at one place:
    :data:`COINCIDENCE_TOLERANCE` of its diagonal plus eight float32 roundings of ``scale``
    (:func:`core.coordinate_rounding.rounding_scale`; by default its largest coordinate), at most
    :data:`COINCIDENCE_EDGE_SHARE` of the mean length of ``edges`` (E, 2)."""
    extent = np.ptp(first, axis=0) if first.size else np.zeros(3)
    scale = np.max(np.abs(first), initial=0.0) if scale is None else scale
    tolerance = COINCIDENCE_TOLERANCE * np.linalg.norm(extent) + 8 * np.finfo(np.float32).eps * scale
    if len(edges):
        mean_edge = float(np.mean(edge_lengths(first, edges[:, 0], edges[:, 1])))
        tolerance = min(tolerance, COINCIDENCE_EDGE_SHARE * mean_edge)
    return float(tolerance)


def near_another_part(points: np.ndarray, part: np.ndarray, tolerance: float) -> np.ndarray:
    """Whether each of ``points`` (k, 3) lies within ``tolerance`` of a point of another ``part``
    (int (k,)): bool (k,). Points at one exact place are taken together first and pairs listed
    between places, so thousands of copies of one point (a part scaled to zero, a collapsed scan
    region) cost one place rather than every pair among them."""
    from scipy.spatial import cKDTree

    places, at = np.unique(points, axis=0, return_inverse=True)
    at = at.ravel()
    # the smallest and largest part at each place: equal where one part alone sits there
    low = np.full(len(places), np.iinfo(np.int64).max, dtype=np.int64)
    high = np.full(len(places), np.iinfo(np.int64).min, dtype=np.int64)
    np.minimum.at(low, at, part)
    np.maximum.at(high, at, part)
    mixed = low != high
    near = mixed.copy()  # a place of two parts: each of its points has one of another part there
    pairs = cKDTree(places).query_pairs(tolerance, output_type="ndarray").reshape(-1, 2)
    for a, b in ((pairs[:, 0], pairs[:, 1]), (pairs[:, 1], pairs[:, 0])):
        # another part sits at b when b holds two parts or its one part is not a's
        near[a[mixed[b] | (low[b] != low[a])]] = True
    return near[at]


def weld_advice(positions: np.ndarray, topology) -> str:
    """A sentence (str, with a leading space) telling the user to weld where vertices of different
    connected parts of ``topology`` (a :class:`core.mesh_topology.MeshTopology`) sit at one place
    in ``positions`` (n, 3) (:func:`coincidence_tolerance`): the faces were split apart where they
    meet (a triangle soup, as some exporters write every face on its own), which makes one
    surface many parts, and Merge by Distance is the fix. Empty where no two parts touch so."""

    used = topology.used_vertices
    if used.size < 2:
        return ""
    piece = vertex_labels(topology.triangles, topology.components()[1], topology.n_vertices)
    touching = int(np.count_nonzero(near_another_part(positions[used], piece[used],
                                                      coincidence_tolerance(positions, topology.edges))))
    if not touching:
        return ""
    return (f" {touching} of its {used.size} vertices sit at the place of a vertex of another "
            "part: its faces are split apart where they meet (as some exporters write them). Weld them: in "
            "Blender, Edit Mode, select all and use Mesh > Clean Up > Merge by Distance.")


def vertex_groups(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """The group (n,) of each of ``n`` vertices joined by the pairs ``a``, ``b`` (each (p,)): the
    connected components of the graph of those pairs."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    return connected_components(coo_matrix((np.ones(a.size), (a, b)), shape=(n, n)), directed=False)[1]


def seam_weld(poses: list[np.ndarray], topology, tolerance: float | None = None, *, seams: bool = True,
              orient: bool = False) -> SeamWeld | None:
    """The weld of the seams of ``topology`` (a :class:`core.mesh_topology.MeshTopology`): its
    boundary edges that coincide, end for end, with exactly one other boundary edge in every one of
    ``poses`` (list of (n, 3)), within ``tolerance`` (:func:`coincidence_tolerance` by default),
    and its loose vertices (in no triangle) at one place with a vertex of a triangle in every pose
    (:func:`core.loose_vertices.loose_copies`); None when there are none. ``seams`` False: the loose copies only.
    ``orient``: pieces wound the other way round from the ones they are welded to have their
    triangles reversed in the weld (:func:`oriented_pieces`), so that the weld does not fail on
    panels exported with opposite normals.
    Raises :class:`MeshError` when the welded mesh is not a valid one (the caller keeps the
    pieces apart)."""
    from .mesh_topology import mesh_topology

    if tolerance is None:
        tolerance = coincidence_tolerance(poses[0], topology.edges)
    a, b = seam_pairs(poses, topology, tolerance) if seams else (np.zeros(0, dtype=np.int64),) * 2
    stacked = _stacked_corners(a, b, topology)
    if stacked.size:  # those corners apart, and the seams again without them
        a, b = seam_pairs(poses, topology, tolerance, apart=stacked)
    loose, used = loose_copies(poses, topology, tolerance)
    if not a.size and not loose.size:
        return None
    kept, copies = np.unique(vertex_groups(np.r_[a, loose], np.r_[b, used], topology.n_vertices),
                             return_index=True, return_inverse=True)[1:]
    triangles = copies[topology.triangles]
    if (np.diff(np.sort(triangles, axis=1), axis=1) == 0).any():
        raise MeshError("welding the coincident vertices would collapse a triangle")
    if orient and a.size:
        triangles = oriented_pieces(triangles, topology.components()[1])
    return SeamWeld(kept, copies, triangles, mesh_topology(triangles, kept.size))


def _stacked_corners(a: np.ndarray, b: np.ndarray, topology) -> np.ndarray:
    """The vertices (int (q,)) of the triangles of ``topology`` that welding the seam pairs ``a``,
    ``b`` (:func:`seam_pairs`) would lay onto another triangle: a triangle with all three corners
    on seams, at a corner where two sewn sides of two panels meet (front and back panels sewn
    along three sides, as Blender's sewing springs pull them together), has the same three welded
    vertices as its twin on the other panel, and the welded mesh would not be a manifold. Empty
    where there are none."""
    if not a.size:
        return a
    triangles = topology.triangles
    welded = np.sort(vertex_groups(a, b, topology.n_vertices)[triangles], axis=1)
    _, first, inverse = np.unique(welded, axis=0, return_index=True, return_inverse=True)
    twin = first[inverse.ravel()]
    stacked = np.flatnonzero(twin != np.arange(len(triangles)))
    return np.unique(triangles[np.r_[stacked, twin[stacked]]])


def seam_pairs(poses: list[np.ndarray], topology, tolerance: float,
                apart: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of vertices (``a``, ``b``, int (p,) each) that :func:`seam_weld` joins along seams:
    the matching ends of two boundary edges whose ends are within ``tolerance`` of each other in
    every one of ``poses`` and that coincide with no third. Only ends of such edges: a piece whose
    seam vertex merely touches another's (Suzanne's eyes against her head, both split at UV seams)
    is not joined by it, which would make the welded mesh a bow-tie. ``apart``: vertices (int (q,))
    joined to none (:func:`_stacked_corners`: the seams run up to them; their panels carry them)."""
    from scipy.spatial import cKDTree

    none = np.zeros(0, dtype=np.int64)
    edges = topology.edges[topology.boundary_edges]
    boundary = np.unique(edges)
    if apart is not None:
        boundary = np.setdiff1d(boundary, apart)
    if boundary.size < 2:
        return none, none
    # vertices at one place in every pose are joined whatever the tolerance: each place is stood for
    # by its first vertex and pairs are listed between places, so thousands of copies of one point
    # (the centre of a fan exported face by face) cost one place rather than every pair among them
    _, first_at, place = np.unique(np.concatenate([pose[boundary] for pose in poses], axis=1), axis=0,
                                   return_index=True, return_inverse=True)
    places = boundary[first_at]
    pairs = cKDTree(poses[0][places]).query_pairs(tolerance, output_type="ndarray")
    if not len(pairs) and len(places) == len(boundary):
        return none, none
    a, b = places[pairs[:, 0]], places[pairs[:, 1]]
    together = np.ones(len(a), dtype=bool)
    for pose in poses[1:]:
        together &= np.linalg.norm(pose[a] - pose[b], axis=1) <= tolerance
    if not together.any() and len(places) == len(boundary):
        return none, none
    n = topology.n_vertices
    a, b = np.r_[a[together], boundary], np.r_[b[together], places[place.ravel()]]
    labels = vertex_groups(a, b, n)
    # only seams: boundary edges that coincide with exactly one other (pieces touching at a point
    # stay apart, three panels on one edge too: joined there the mesh would not be a manifold)
    ends = np.sort(labels[edges], axis=1)
    _, edge_group, count = np.unique(ends, axis=0, return_inverse=True, return_counts=True)
    edge_group = edge_group.ravel()
    seams = np.flatnonzero((count[edge_group] == 2) & (ends[:, 0] != ends[:, 1]))
    seams = seams[np.argsort(edge_group[seams], kind="stable")]
    first, second = edges[seams[0::2]], edges[seams[1::2]]  # the two edges of each seam edge
    # end for end: the second edge's ends in the order of the first's
    crossed = labels[first[:, 0]] != labels[second[:, 0]]
    second = np.where(crossed[:, None], second[:, ::-1], second)
    return first.ravel(), second.ravel()


def oriented_pieces(triangles: np.ndarray, pieces: np.ndarray) -> np.ndarray:
    """``triangles`` (m, 3) of a welded mesh with the corners of whole ``pieces`` (the component of
    each triangle before the weld, (m,)) reversed where a piece is wound against the ones it is
    welded to (two triangles run their shared edge the same way), the first piece of each group
    keeping its winding. Unchanged where that cannot be made consistent (a Möbius strip of panels):
    the weld's topology check then refuses it. Each piece is consistently wound in itself (the
    mesh check), so the winding of a piece is one sign."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m, count = len(triangles), int(pieces.max()) + 1 if len(pieces) else 0
    if not m:  # a weld that collapsed every triangle: nothing to orient (the caller's checks refuse it)
        return triangles
    tails, heads = triangles.ravel(), triangles[:, [1, 2, 0]].ravel()
    owner = np.repeat(np.arange(m), 3)
    low, high = np.minimum(tails, heads), np.maximum(tails, heads)
    _, edge, counts = np.unique(np.stack([low, high], axis=1), axis=0, return_inverse=True, return_counts=True)
    edge = edge.ravel()
    order = np.argsort(edge, kind="stable")
    shared = counts[edge[order]] == 2  # half-edges of edges with two triangles, in pairs
    first, second = order[shared][0::2], order[shared][1::2]
    p, q = pieces[owner[first]], pieces[owner[second]]
    across = p != q
    same_way = (tails[first] == tails[second])[across]  # run the same way: opposite windings
    p, q = p[across], q[across]
    # each piece as it is (node 2k) and reversed (2k + 1); a shared edge run the same way joins a
    # piece as it is to the other reversed, run opposite ways as they are
    rows = np.r_[2 * p, 2 * p + 1]
    cols = np.r_[2 * q + same_way, 2 * q + 1 - same_way]
    _, side = connected_components(coo_matrix((np.ones(rows.size), (rows, cols)), shape=(2 * count, 2 * count)),
                                   directed=False)
    side = side.reshape(count, 2)
    if (side[:, 0] == side[:, 1]).any():
        return triangles
    # a group's sides as they are: those joined to the first piece of the group as it is
    group_first = np.full(side.max() + 1, count)
    np.minimum.at(group_first, side[:, 0], np.arange(count))
    np.minimum.at(group_first, side[:, 1], np.arange(count))
    reverse = side[:, 1] == side[np.minimum(group_first[side[:, 0]], group_first[side[:, 1]]), 0]
    out = triangles.copy()
    flip = reverse[pieces]
    out[flip] = out[flip][:, ::-1]
    return out
