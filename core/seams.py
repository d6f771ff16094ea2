"""Seams: pieces of one mesh whose boundary vertices coincide in every pose.

Garments exported panel by panel (Marvelous Designer's "unweld", OBJ and FBX writers that split
vertices along UV seams, an Edge Split applied before caching) arrive as pieces that touch along
seams without sharing vertices. Per-vertex interpolation keeps coincident vertices together; the
in-betweens (:mod:`core.sequence_inbetweens`, :mod:`core.two_pose_inbetweens`) reconstruct each piece from its own rotations and
stretches, and a piece has no reason to meet its neighbour there: a 10k sheet cut in two along a
row of coincident vertices opened by 1–13 mean edge lengths at keys 8 and 16 frames apart. Such
vertices are welded for the interpolation and written back to every copy.

:func:`seam_weld` finds them: boundary edges whose ends sit within :func:`coincidence_tolerance`
of another boundary edge's in every pose (pieces touching at a single point are not seams), and
loose vertices at a vertex of the mesh. Pieces wound against the ones they are welded to are turned
over in the weld (:func:`oriented_pieces`). Where two sewn sides meet at a corner, a triangle whose
three corners are all on seams would lie on its twin once welded: its corners stay apart and the
seams are welded up to them (:func:`_stacked_corners`). The weld is used only where the welded
mesh is a valid one (manifold, orientable, no triangle losing a corner); otherwise the pieces stay
apart and a warning says the seams may open. The analyses (distortion maps, shape space) compare
the pieces each on its own: :func:`seam_folds` measures how far a pose folds a seam, which they
cannot see, and :func:`warn_seam_folds` says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import MeshError, warn
from .geometry import edge_lengths, normalize, vertex_labels

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


def rounding_scale(poses: list[np.ndarray]) -> float:
    """The magnitude whose single-precision rounding the coordinates of ``poses`` (list of (n, 3))
    carry: their largest coordinate where every one is a float32 (stored so: Blender, most
    caches), else the largest extent of a pose (computed in double precision from single-precision
    positions about their object, as a cache moved by its object's transform is, or double
    precision throughout, whose rounding is smaller still). The same sequence 1e4 units from the
    origin in double precision had the roundings of float32 coordinates of 2e4 (0.02 units): a
    cloth on a turntable, whose edges keep their lengths to 0.1 %, took 36 of its vertices for
    still and six sets for riding, 0.22 of its diagonal off."""
    if all(np.array_equal(pose, pose.astype(np.float32)) for pose in poses):
        return max((float(np.max(np.abs(pose), initial=0.0)) for pose in poses), default=0.0)
    return max((float(np.linalg.norm(np.ptp(pose, axis=0))) for pose in poses if pose.size), default=0.0)


def coordinate_rounding(poses: list[np.ndarray], single: bool | None = None) -> float:
    """The rounding of the largest coordinate of ``poses`` (list of (n, 3)): single precision
    where ``single`` (``None``: where every coordinate is a float32, as Blender stores keys), else
    double. Shape keys that only move their mesh, stored in single precision, have shape
    differences of about this over their edge lengths (1e-7 to 1e-5), not zero."""
    if not poses:
        return 0.0
    if single is None:
        single = all(np.array_equal(pose, pose.astype(np.float32)) for pose in poses)
    largest = max(float(np.max(np.abs(pose), initial=0.0)) for pose in poses)
    return float(np.finfo(np.float32 if single else np.float64).eps * largest)


def inverse_heights(pose: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Per triangle (m,) of ``pose`` (n, 3), one over its smallest height (its longest edge over
    its doubled area; inf for a flat one): times a coordinate rounding
    (:func:`coordinate_rounding`), what the rounding can change its area and angles by,
    relatively. The height, not the shortest edge: a long flat triangle (an n-gon's cap cut into
    a fan) turns by the rounding over its height; over its shortest edge, a turned cylinder's caps
    read as distortion (21 of 252 faces)."""
    a, b, c = (pose[triangles[:, k]] for k in range(3))
    longest = np.max([np.linalg.norm(p - q, axis=1) for p, q in ((a, b), (b, c), (c, a))], axis=0)
    doubled = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(doubled > 0, longest / doubled, np.inf)


def across_edges(values: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Per triangle (m,), the largest of ``values`` (m,) over it and the triangles sharing an edge
    with it: the offset surface's points above a triangle and above those across its edges move
    with their normals, so its bending's round-off is the thinnest one's
    (:func:`inverse_heights`)."""
    if not len(triangles):
        return np.asarray(values, dtype=float)
    ends = np.sort(triangles[:, [[0, 1], [1, 2], [2, 0]]], axis=2).reshape(-1, 2)
    edge = np.unique(ends, axis=0, return_inverse=True)[1].reshape(-1, 3)
    largest = np.full(int(edge.max()) + 1, -np.inf)
    np.maximum.at(largest, edge, np.asarray(values, dtype=float)[:, None])
    return largest[edge].max(axis=1)


def relative_round_off(poses: list[np.ndarray], triangles: np.ndarray, single: bool | None = None,
                       offset: float | None = None) -> float:
    """The area-weighted mean of the relative round-off (:func:`inverse_heights` times
    :func:`coordinate_rounding`) over the triangles of the first of
    ``poses``: the size of the shape differences (averages over the mesh) that the rounding of the
    coordinates alone makes; with ``offset`` t, of the offset surface's (each triangle's times
    ``1 + t / h``, h the smallest height of it and the triangles across its edges,
    :func:`across_edges`: the offset points lie t out along normals that the rounding turns by its
    size over h)."""
    if not poses or not len(triangles):
        return 0.0
    first = poses[0]
    a, b, c = (first[triangles[:, k]] for k in range(3))
    areas = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    rounding = coordinate_rounding(poses, single)
    noise = rounding * inverse_heights(first, triangles)
    if offset is not None and rounding > 0:
        noise = rounding * across_edges(noise / rounding, triangles)
        noise = noise * (1.0 + offset * noise / rounding)
    finite = np.isfinite(noise)
    return float(areas[finite] @ noise[finite] / areas[finite].sum()) if areas[finite].sum() > 0 else 0.0


def coincidence_tolerance(first: np.ndarray, edges: np.ndarray, scale: float | None = None) -> float:
    """The distance (float) under which two vertices of pose ``first`` (n, 3) are at one place:
    :data:`COINCIDENCE_TOLERANCE` of its diagonal plus eight float32 roundings of ``scale``
    (:func:`rounding_scale`; by default its largest coordinate), at most
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
    (:func:`loose_copies`); None when there are none. ``seams`` False: the loose copies only.
    ``orient``: pieces wound the other way round from the ones they are welded to have their
    triangles reversed in the weld (:func:`oriented_pieces`), so that the weld does not fail on
    panels exported with opposite normals.
    Raises :class:`MeshError` when the welded mesh is not a valid one (the caller keeps the
    pieces apart)."""
    from .mesh_topology import mesh_topology

    if tolerance is None:
        tolerance = coincidence_tolerance(poses[0], topology.edges)
    a, b = _seam_pairs(poses, topology, tolerance) if seams else (np.zeros(0, dtype=np.int64),) * 2
    stacked = _stacked_corners(a, b, topology)
    if stacked.size:  # those corners apart, and the seams again without them
        a, b = _seam_pairs(poses, topology, tolerance, apart=stacked)
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
    ``b`` (:func:`_seam_pairs`) would lay onto another triangle: a triangle with all three corners
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


def _seam_pairs(poses: list[np.ndarray], topology, tolerance: float,
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


#: The analyses that compare a mesh's pieces each on its own (distortion maps, shape space) warn
#: where a pose turns the two sides of a seam against each other by more than this (radians), on
#: top of what the coordinates' rounding turns their normals by: a fold along the seam, which no
#: piece's differences see.
SEAM_FOLD_TOLERANCE = float(np.radians(1.0))


def seam_sides(poses: list[np.ndarray], topology) -> np.ndarray:
    """The triangles on either side of each seam edge of ``topology`` (a
    :class:`core.mesh_topology.MeshTopology`) in ``poses`` (list of (n, 3)), int64 ``(s, 2)``: the
    boundary edges :func:`seam_weld` would join (coinciding end for end with exactly one other in
    every pose, within :func:`coincidence_tolerance` of the first), each with its one triangle."""
    a, b = _seam_pairs(poses, topology, coincidence_tolerance(poses[0], topology.edges))
    if not a.size:
        return np.zeros((0, 2), dtype=np.int64)
    n = topology.n_vertices
    keys = topology.edges[:, 0] * n + topology.edges[:, 1]
    order = np.argsort(keys)
    sides = []
    for pairs in (a.reshape(-1, 2), b.reshape(-1, 2)):
        pairs = np.sort(pairs, axis=1)
        edge = order[np.searchsorted(keys, pairs[:, 0] * n + pairs[:, 1], sorter=order)]
        sides.append(topology.edge_triangles[edge].max(axis=1))  # a boundary edge's one triangle
    return np.stack(sides, axis=1)


def seam_folds(base: np.ndarray, pose: np.ndarray, triangles: np.ndarray, sides: np.ndarray,
               single: bool | None = None) -> np.ndarray:
    """How far ``pose`` (n, 3) folds each seam (``sides`` (s, 2) from :func:`seam_sides`) from
    ``base`` (n, 3), float (s,) radians: the change of the angle between the normals of the
    triangles (``triangles`` (m, 3)) on its two sides (the same whichever way the pieces are
    wound, and nothing for a motion of both sides together), less :data:`SEAM_FOLD_TOLERANCE` and
    what the rounding of the coordinates (:func:`coordinate_rounding`) turns those normals by (it
    over each triangle's height, :func:`inverse_heights`, in both poses); positive where the fold
    is real."""
    if not len(sides):
        return np.zeros(0)
    sided = triangles[sides.ravel()]  # the seams' triangles only, two per seam edge
    angles = []
    for positions in (base, pose):
        a, b, c = (positions[sided[:, k]] for k in range(3))
        normals = normalize(np.cross(b - a, c - a))[0].reshape(-1, 2, 3)
        angles.append(np.arccos(np.clip(np.einsum("sd,sd->s", normals[:, 0], normals[:, 1]), -1.0, 1.0)))
    rounding = coordinate_rounding([base, pose], single)
    noise = 2.0 * rounding * sum(inverse_heights(positions, sided).reshape(-1, 2).sum(axis=1) for positions in (base, pose))
    return np.abs(angles[1] - angles[0]) - SEAM_FOLD_TOLERANCE - noise


def warn_seam_folds(base: np.ndarray, poses: list[np.ndarray], triangles: np.ndarray, sides: np.ndarray,
                    single_precision: bool | None, name: str, consequence: str) -> bool:
    """ShapeDifferenceWarning where ``poses`` (list of (n, 3)) fold a mesh along its seams from
    ``base`` (:func:`seam_folds`; ``sides`` from :func:`seam_sides`):
    pieces apart along coincident vertices, whose differences each piece has on its own.
    ``name``: the poses as the message calls them; ``consequence``: what the analysis misses.
    Returns whether it warned."""
    folds = np.array([seam_folds(base, pose, triangles, sides, single_precision) for pose in poses])
    folded = (folds > 0).any(axis=0)
    if not folded.any():
        return False
    worst = float(np.degrees(folds.max() + SEAM_FOLD_TOLERANCE))
    warn(
        f"The mesh is split along seams ({len(sides)} seam edge(s): pieces whose boundary vertices coincide, "
        "as exporters and importers leave a mesh split at UV seams or hard edges), and "
        f"{int(folded.sum())} of them fold by up to {worst:.3g}° in {name}: {consequence}. Weld the seams "
        "(Merge by Distance) to measure the mesh as one surface.",
        "seam", stacklevel=4)
    return True


def loose_copies(poses: list[np.ndarray], topology, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """The loose vertices of ``topology`` (in no triangle) that sit within ``tolerance`` of a
    vertex of a triangle in every one of ``poses`` (list of (n, 3)), and that vertex (int (p,)
    each): a duplicate Merge by Distance would remove, or a point an object is parented to. Carried
    by their piece's rigid motion, a loose copy of the hand of an arm bent 100° left the hand by
    18 % of the diagonal half-way and 114 % at ×2."""
    return _loose_near(poses, topology, topology.loose_vertices, tolerance)


def _loose_near(poses: list[np.ndarray], topology, loose: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Of the vertices ``loose`` (int (p,)), those within ``reach`` of their nearest vertex of a
    triangle of ``topology`` (nearest in the first of ``poses``) in every pose, and that vertex."""
    from scipy.spatial import cKDTree

    used = topology.used_vertices
    if not loose.size or not used.size:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    distance, nearest = cKDTree(poses[0][used]).query(poses[0][loose], distance_upper_bound=reach)
    found = np.isfinite(distance)
    loose, near = loose[found], used[nearest[found]]
    together = np.ones(loose.size, dtype=bool)
    for pose in poses[1:]:
        together &= np.linalg.norm(pose[loose] - pose[near], axis=1) <= reach
    return loose[together], near[together]


#: A loose vertex within this many mean edge lengths of a vertex of a triangle in every key is
#: attached to a triangle there (:func:`attached_loose`); one farther off (a helper vertex
#: beside the mesh) moves with its piece's rigid motion.
ATTACH_REACH = 2.0


@dataclass(frozen=True)
class AttachedLoose:
    """Loose vertices ``vertices`` (p,) attached to the triangle ``corners`` (p, 3) at their nearest
    vertex, and their coordinates ``local`` (K, p, 3) in that triangle's frame
    (:func:`triangle_frames`) in each of K keys."""

    vertices: np.ndarray
    corners: np.ndarray
    local: np.ndarray

    def placed(self, pose: np.ndarray, local: np.ndarray) -> np.ndarray:
        """The attached vertices' positions (p, 3) in ``pose`` (n, 3) at ``local`` coordinates (p, 3)."""
        origin, frame = triangle_frames(pose, self.corners)
        return origin + np.einsum("pij,pj->pi", frame, local)


def triangle_frames(pose: np.ndarray, corners: np.ndarray):
    """Per triangle ``corners`` (p, 3) of ``pose`` (n, 3): its first corner (p, 3) and an orthonormal
    frame (p, 3, 3) whose columns are its first edge's direction, the direction across it in the
    triangle's plane and its normal: a rigid motion of the triangle moves the frame with it."""
    a, b, c = (pose[corners[:, k]] for k in range(3))
    along = b - a
    along = along / np.linalg.norm(along, axis=1, keepdims=True)
    normal = np.cross(b - a, c - a)
    normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    return a, np.stack([along, np.cross(normal, along), normal], axis=2)


def attached_loose(poses: list[np.ndarray], topology, still: np.ndarray | None = None) -> AttachedLoose | None:
    """The loose vertices of ``topology`` within :data:`ATTACH_REACH` mean edge lengths of their
    nearest vertex of a triangle (in the first of ``poses``) in every pose, attached to a triangle
    of that vertex; None where there are none. ``still`` (bool (n,)): vertices held where they are
    (pins), left out. Carried by their piece's rigid motion, a point 0.1 % of the diagonal off the
    hand of an arm bent 100° left it by 18 % of the diagonal half-way."""
    loose = topology.loose_vertices
    if still is not None:
        loose = loose[~still[loose]]
    if not loose.size or not topology.used_vertices.size:
        return None
    first = poses[0]
    reach = ATTACH_REACH * float(np.mean(np.linalg.norm(first[topology.edges[:, 0]] - first[topology.edges[:, 1]], axis=1)))
    loose, near = _loose_near(poses, topology, loose, reach)
    if not loose.size:
        return None
    triangles = topology.triangles
    first_triangle = np.full(topology.n_vertices, len(triangles))  # of each vertex: the first it is in
    np.minimum.at(first_triangle, triangles.ravel(), np.repeat(np.arange(len(triangles)), 3))
    corners = triangles[first_triangle[near]]
    local = []
    for pose in poses:
        origin, frame = triangle_frames(pose, corners)
        local.append(np.einsum("pji,pj->pi", frame, pose[loose] - origin))
    return AttachedLoose(loose, corners, np.array(local))


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


def seam_twins(base: np.ndarray, topology):
    """Pairs of vertices ``(a, b)`` (int (p,) each) of different pieces that meet along a seam in
    the pose ``base`` (n, 3) of ``topology``, and a problem (str) or None: every pair of boundary
    vertices of two pieces at one place (:func:`coincidence_tolerance`), also where the two sides
    number their vertices differently (a T-junction: 9 vertices on one side, 5 on the other, each
    of those on one of the 9; the edges do not match end for end, which :func:`seam_weld` needs,
    and the panels were placed apart, the seam 0.37 open). Two pieces joined by a single pair
    (panels meeting only at a corner, as the diagonal ones of four around one vertex do) are not
    seamed: glued by a point, a 2 × 2 split sheet came back 0.55 % off. Panels wound against the
    ones they meet are turned over in the weld, as the in-betweens' are (:func:`oriented_pieces`).
    None without seams; with the problem where welding them would not give a valid mesh (panels no
    choice of windings joins consistently, a triangle it would collapse)."""
    from scipy.spatial import cKDTree

    try:
        seam_weld([base], topology, orient=True)
    except MeshError as error:
        return None, str(error)
    boundary = np.unique(topology.edges[topology.boundary_edges])
    if boundary.size < 2:
        return None, None
    pairs = cKDTree(base[boundary]).query_pairs(coincidence_tolerance(base, topology.edges), output_type="ndarray")
    _, labels = topology.components()
    piece = vertex_labels(topology.triangles, labels, topology.n_vertices)
    pairs = boundary[pairs].reshape(-1, 2)
    pairs = pairs[piece[pairs[:, 0]] != piece[pairs[:, 1]]]
    if not len(pairs):
        return None, None
    ends = np.sort(piece[pairs], axis=1)
    _, which, count = np.unique(ends, axis=0, return_inverse=True, return_counts=True)
    pairs = pairs[count[which.ravel()] >= 2]
    return ((pairs[:, 0], pairs[:, 1]), None) if len(pairs) else (None, None)


#: Twins of a seam that, its two sides fitted onto each other, stay apart by more than this share
#: of the seam's length (RMS spread) part in the pose (an exact reconstruction's twins meet to
#: ~1e-10): they are let go, and where most of a seam's twins part the seam opens (a strip along a
#: body that widens under it: 15 % of the diagonal) and its pieces are placed on their own. One RMS
#: test of a whole seam at 5 % instead glues a seam opening by 0.5 % (4.6e-3 off), and two touching
#: points that part (a vent's corners) let a sewn seam's 5 twins go with them.
SEAM_OPEN_SHARE = 1e-3

#: A seam holds the angle between the pieces it joins where its twins' spread across their line
#: exceeds this many times the RMS misfit of the twins' fit (the pieces' own reconstruction error):
#: two panels folded 90° about a seam straight to 3e-4 of the diagonal, reconstructed in a
#: truncated basis to 3e-4, were glued at 32° with no warning.
SEAM_HOLD_MISFITS = 10.0


def glue_along_seams(positions: np.ndarray, labels: np.ndarray, twins, weights: np.ndarray, *,
                     find_opened: bool = True):
    """Pieces (rows of equal ``labels`` (n,)) of ``positions`` (n, 3), each placed on its own, moved
    rigidly so that the ``twins`` (pairs from :func:`seam_twins`) meet, piece by piece outward from
    the heaviest of each group of pieces joined by seams (``weights`` (n,)): each piece's twins
    fitted onto their partners, then the turn about them that the twins leave free (about a
    straight seam, a single point) chosen to keep the rest of the piece nearest where it was
    (:func:`core.rigid_alignment.pivoted_alignment`). Returns the moved positions, the labels with
    glued pieces sharing one, the pairs of labels joined along a seam straight to within
    :data:`SEAM_HOLD_MISFITS` of the twins' misfit (their angle there is the one their own
    placements gave, not the pose's: shape differences are computed per piece), and the pairs of
    pieces whose seam is dropped because its sides differ in the pose (:data:`SEAM_OPEN_SHARE`;
    only where ``find_opened``: an exact reconstruction, whose misfits are the pose's, not its own
    error's)."""
    from .rigid_alignment import PIVOT_SPREAD, pivoted_alignment, rigid_alignment

    out, labels = positions.copy(), labels.copy()
    pieces = labels.copy()  # each vertex's own piece (``labels`` join as pieces are glued)
    a, b = twins
    mass = {piece: weights[labels == piece].sum() for piece in np.unique(labels)}
    placed, hinges, roots, opened = set(), [], set(), []
    while True:
        # pairs from a placed piece to one not placed yet (either way round); none: start the next
        # group from its heaviest piece
        fixed_a, fixed_b = np.isin(labels[a], list(placed)), np.isin(labels[b], list(placed))
        across = fixed_a ^ fixed_b
        if not across.any():
            free = {int(piece) for piece in np.unique(labels[np.r_[a, b]]) if piece not in placed}
            if not free:
                _close_rings(out, pieces, a, b, roots)
                return out, labels, hinges, opened
            root = max(free, key=lambda piece: mass[piece])
            placed.add(root)
            roots.add(root)
            continue
        rows = np.flatnonzero(across)  # the pairs' places in a, b
        moving, partner = np.where(fixed_a, b, a)[rows], np.where(fixed_a, a, b)[rows]
        piece = labels[moving[0]]
        mine = labels[moving] == piece
        rows, moving, partner = rows[mine], moving[mine], partner[mine]
        if find_opened:  # pairs whose two sides part in the pose are dropped (whole seams: said so)
            parting, gone = _opened_seams(out, pieces, moving, partner)
            if parting.any():
                opened += [(int(other), int(pieces[moving[0]])) for other in gone]
                keep = np.ones(len(a), dtype=bool)
                keep[rows[parting]] = False
                a, b = a[keep], b[keep]
                continue
        rows = np.flatnonzero(labels == piece)
        rotation, translation = rigid_alignment(out[moving], out[partner])
        joined = out[rows] @ rotation.T + translation
        misfit = np.sqrt(np.mean(np.sum((joined[np.searchsorted(rows, moving)] - out[partner]) ** 2, axis=1)))
        seam = out[partner] - out[partner].mean(axis=0)
        spread = np.linalg.svd(seam, compute_uv=False) / np.sqrt(partner.size)
        held = spread.size > 1 and spread[1] > max(PIVOT_SPREAD * np.linalg.norm(np.ptp(out[rows], axis=0)),
                                                   SEAM_HOLD_MISFITS * misfit)
        # a seam that does not hold the angle: its line (or point) is the pivot of the turn left free
        pivots = out[partner] if held else _line_through(out[partner], spread)
        turn, shift = pivoted_alignment(joined, out[rows], pivots, weights[rows])
        out[rows] = joined @ turn.T + shift
        if not held:
            hinges.append((int(labels[partner[0]]), int(piece)))
        labels[rows] = labels[partner[0]]
        placed.add(int(piece))


def _line_through(points: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """Two points (2, 3) on the best line through ``points`` (p, 3) (``spread``: their singular
    values over √p), or their centre alone (1, 3) where they do not spread along one either."""
    centre = points.mean(axis=0)
    if spread[0] <= 0:
        return centre[None]
    direction = np.linalg.svd(points - centre, full_matrices=False)[2][0]
    return np.stack([centre - spread[0] * direction, centre + spread[0] * direction])


#: Sweeps of :func:`_close_rings` at most, and the change of the seams' largest gap (relative to
#: the largest gap) under which they stop.
RING_SWEEPS, RING_TOLERANCE = 200, 1e-10


def _close_rings(out: np.ndarray, pieces: np.ndarray, a: np.ndarray, b: np.ndarray, roots: set) -> None:
    """Where glued pieces close a ring (a tube of panels: the last one meets the first along a
    seam the gluing piece by piece could not hold), move each piece but the groups' first, in
    place, to fit its twins onto all their partners at once, sweep after sweep (each piece held
    by its seams on both sides: two lines, which fix it), until the gaps stop closing. Pieces
    whose twins all lie on one line keep their place (their turn about it is not determined)."""
    from .rigid_alignment import rigid_alignment

    gaps = np.linalg.norm(out[a] - out[b], axis=1)
    if not len(gaps) or gaps.max() <= 0:
        return
    movable = []
    for piece in np.unique(pieces[np.r_[a, b]]):
        if piece in roots:
            continue
        mine_a, mine_b = pieces[a] == piece, pieces[b] == piece
        own = np.r_[a[mine_a & ~mine_b], b[mine_b & ~mine_a]]
        partner = np.r_[b[mine_a & ~mine_b], a[mine_b & ~mine_a]]
        spread = np.linalg.svd(out[own] - out[own].mean(axis=0), compute_uv=False)
        if spread.size > 1 and spread[1] > 1e-3 * spread[0]:  # not one line: the twins fix the piece
            movable.append((np.flatnonzero(pieces == piece), own, partner))
    if not movable:
        return
    largest = gaps.max()
    for _ in range(RING_SWEEPS):
        for rows, own, partner in movable:
            rotation, translation = rigid_alignment(out[own], out[partner])
            out[rows] = out[rows] @ rotation.T + translation
        now = np.linalg.norm(out[a] - out[b], axis=1).max()
        if abs(largest - now) <= RING_TOLERANCE * max(largest, now) or now <= 1e-14:
            return
        largest = now


#: Twins a seam's consistency counts are taken against, at most (evenly spread along it), and the
#: share of the largest count that seeds the fit (a block of 49 % of the twins moved off keeps its
#: own distances: at 0.9 it seeded the fit with the sewn 51 %, pulled it off, and the seam opened).
SEAM_REFERENCE_TWINS = 512
SEAM_SEED_SHARE = 0.98


def _opened_seams(out: np.ndarray, pieces: np.ndarray, moving: np.ndarray, partner: np.ndarray):
    """Which of the twins ``moving`` / ``partner`` (p,) part in the pose (bool (p,)), and the pieces
    of the ``partner`` twins whose whole seam with the piece of the ``moving`` twins opens (list).
    Seam by seam: the part that stays sewn keeps the distances between its twins on both sides (a
    rigid motion keeps them), so each twin is counted against up to :data:`SEAM_REFERENCE_TWINS`
    others for the distances it keeps to :data:`SEAM_OPEN_SHARE` of the seam's length; the twins
    about as consistent as the most consistent ones (:data:`SEAM_SEED_SHARE`) seed the fit of the two sides onto each other, and
    the twins it brings within that share stay sewn (refitted on them until they stay the same). Where they are not
    most of the seam, or fewer than two, the seam opens. A seam whose top part moved off as a
    block (44 % of its twins), or whose panels also touch at a vent's corners that part, stays
    sewn where it is sewn: fits that let the farthest twins go one by one or a tenth at a time
    were pulled by the block and let sewn twins go with it."""
    from .rigid_alignment import rigid_alignment

    parting, gone = np.zeros(len(moving), dtype=bool), []
    for other in np.unique(pieces[partner]):
        seam = np.flatnonzero(pieces[partner] == other)
        mine, theirs = out[moving[seam]], out[partner[seam]]
        length = np.sqrt(np.mean(np.sum((theirs - theirs.mean(axis=0)) ** 2, axis=1)))
        tolerance = SEAM_OPEN_SHARE * length
        reference = np.linspace(0, seam.size - 1, min(seam.size, SEAM_REFERENCE_TWINS)).astype(int)
        consistent = np.concatenate([  # in blocks of rows: a (p, references, 3) array is 0.5 GB at 20k twins
            np.count_nonzero(np.abs(np.linalg.norm(mine[rows, None] - mine[reference], axis=2)
                                    - np.linalg.norm(theirs[rows, None] - theirs[reference], axis=2)) <= tolerance, axis=1)
            for rows in np.array_split(np.arange(seam.size), max(1, seam.size // 2048))])
        meet = consistent >= SEAM_SEED_SHARE * consistent.max()
        for _ in range(5):  # refitted on the twins that meet until they are the same
            if np.count_nonzero(meet) < 2:
                break
            rotation, translation = rigid_alignment(mine[meet], theirs[meet])
            fitted = np.linalg.norm(mine @ rotation.T + translation - theirs, axis=1) <= tolerance
            if np.array_equal(fitted, meet):
                break
            meet = fitted
        if np.count_nonzero(meet) < 2 or 2 * np.count_nonzero(~meet) > seam.size:  # the seam opens
            parting[seam] = True
            gone.append(int(other))
        else:
            parting[seam[~meet]] = True
    return parting, gone
