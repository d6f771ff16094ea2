"""Near-seams: boundary vertices that every key keeps almost together, but farther apart than the
weld joins, and that the mesh does not join: of different pieces, or of one piece and far apart
along it, as the two sides of a tube cut open along one line (paper §8.4: the in-betweens
reconstruct each piece on its own, and a piece's boundary is free).

:func:`core.seams.seam_weld` welds vertices within :func:`core.seams.coincidence_tolerance`
(1e-5 of the diagonal): farther apart, welding would move the caller's keys, or join separate
stacked layers. A seam left 1e-4 apart (7e-5 of the diagonal, 0.07 % of an edge) is then two
pieces interpolated each on its own, which an 8 × 8 grid's in-between opened to 2.4e-3 of the
diagonal (2.4 % of an edge) half-way; a tube of one piece cut along its length, its sides 1e-4
apart while it bends and twists, opened to 6 % of an edge in a sequence and 16 % between two poses.
So are panels that the motion sews together (Blender's sewing springs pull loose edges shut over
the first frames of a bake): apart in the first keys, within a hundredth of an edge in the later
ones, which the in-betweens of two sewn panels opened by up to 5 edges between keys 16 frames
apart. Such seams are found once per sequence, gap by gap (:func:`near_seams`: a KD-tree query
over the boundary vertices of every other key, which meets every gap), and each in-between is measured on its gap's
(:meth:`NearSeams.opening`: a gather), so that the in-betweens warn (kind ``seam``) where they open
what both keys of their gap keep closed. Each gap's solves keep those pairs at their keys' offsets
(:mod:`core.sewn_seams`); the warning is for pairs a gap cannot join (joined, a triangle would
collapse). Pieces that move together keep their distance and are not warned of, whatever their
distance in the keys.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sequence_warnings import factor_list

#: Boundary vertices closer than this share of their mean adjacent edge length in both keys of a
#: gap (of different pieces, or of one piece and apart along it) are the two sides of a seam those
#: keys keep closed (cloth's collision distances, which keep layers apart, are a third of an edge
#: or more).
NEAR_SEAM_SHARE = 0.05
#: An in-between opens such a seam where a pair lies farther apart than in either key of its gap
#: (any key, for a seam every key keeps closed) by more than this share of its mean adjacent edge length (plus the weld's own distance, which covers the
#: coordinates' rounding): a gap visible at the scale of the mesh's triangles.
SEAM_OPENING_SHARE = 0.01
#: Nearest boundary vertices looked at per boundary vertex: a seam vertex's partner across the
#: seam is its nearest, or next to nearest where three pieces meet.
NEAR_SEAM_NEIGHBOURS = 4
#: Two boundary vertices of one piece are the two sides of a seam only where every path between
#: them along the mesh's edges (in the first key) is at least this many times their mean adjacent
#: edge length: nearer, the mesh joins them itself (a sliver's corners; a hem folded flat brings
#: boundary vertices two edges apart within 2–4 % of an edge in both keys of a pair in Blender's
#: bakes). With 4, no pair in any of 40 baked scenes; a tube's cut is its circumference apart.
SAME_PIECE_PATH = 4.0
#: Pairs of one piece whose paths along the mesh are measured at once (:func:`_apart_along_mesh`):
#: Dijkstra's distances are (pairs, vertices near them); the 32k pairs of a 100k-vertex sheet cut
#: into a fringe would be 23 GiB at once, 64 at a time keep them to a few MB (1.1 s CPU in all).
PATH_PAIRS_AT_ONCE = 64


@dataclass(frozen=True)
class NearSeams:
    """Pairs of boundary vertices (``a``, ``b``, int (p,) each, indices of the positions given to
    :func:`near_seams`) that the mesh does not join, kept together by both keys of at least one
    gap; ``apart`` (G, p) their larger distance in the two keys of each of the G gaps, ``allowed``
    (G, p) the distance an in-between of that gap may reach before it opens the seam
    (:data:`SEAM_OPENING_SHARE`; infinite where a key of the gap has the pair apart), ``every``
    (p,) whether every key keeps the pair together (a seam left unwelded, rather than one the
    motion closes or opens)."""

    a: np.ndarray
    b: np.ndarray
    apart: np.ndarray
    allowed: np.ndarray
    every: np.ndarray

    def opening(self, x: np.ndarray, gap: int = 0) -> tuple[int, float, int, float]:
        """How pose ``x`` (n, 3), an in-between of gap ``gap``, opens the seams its keys keep closed:
        ``(pairs opened, the widest distance of an opened pair, that pair's index, excess)``, the
        excess the most an opened pair lies farther apart than in the keys ÷ the opening allowed it
        (:data:`SEAM_OPENING_SHARE` of its edge plus the weld's distance; over 1);
        ``(0, 0.0, -1, 0.0)`` where none opens."""
        distance = np.linalg.norm(x[self.a] - x[self.b], axis=1)
        opened = distance > self.allowed[gap]
        if not opened.any():
            return 0, 0.0, -1, 0.0
        worst = int(np.argmax(np.where(opened, distance, -np.inf)))
        apart, allowed = self.apart[gap][opened], self.allowed[gap][opened]  # allowed: finite where opened
        excess = float(np.max((distance[opened] - apart) / (allowed - apart)))
        return int(np.count_nonzero(opened)), float(distance[worst]), worst, excess


def near_seams(keys: list[np.ndarray], topology, tolerance: float) -> NearSeams | None:
    """The near-seams of ``keys`` (K arrays (n, 3)) of a mesh of ``topology`` (a
    :class:`core.mesh_topology.MeshTopology`, its seams already welded): pairs of boundary vertices
    within :data:`NEAR_SEAM_SHARE` of their mean adjacent edge length in both keys of a gap (keys
    k and k + 1), of different pieces or of one piece and apart along it
    (:data:`SAME_PIECE_PATH`). ``tolerance``: the weld's distance
    (:func:`core.seams.coincidence_tolerance`), added to what an in-between may open them by. None
    where there are none (boundaries apart in every gap, no boundary)."""
    from scipy.spatial import cKDTree

    edges = topology.edges
    boundary = np.unique(edges[topology.boundary_edges])
    if boundary.size < 2 or not len(edges) or len(keys) < 2:
        return None
    n = topology.n_vertices
    on_boundary = np.zeros(n, dtype=bool)
    on_boundary[boundary] = True
    at = edges[on_boundary[edges[:, 0]] | on_boundary[edges[:, 1]]]  # the edges at boundary vertices
    degree = np.maximum(np.bincount(at.ravel(), minlength=n), 1)
    k = min(NEAR_SEAM_NEIGHBOURS + 1, boundary.size)
    candidates = []
    # the pairs near in the odd keys (each key's own edge lengths: a sheet that shrinks): every gap has
    # an odd key, and a pair both keys of a gap keep closed is within reach in each (its mean adjacent
    # edge is at most the largest); the other keys would only add pairs no gap keeps closed
    for key in keys[1::2]:
        lengths = np.linalg.norm(key[at[:, 0]] - key[at[:, 1]], axis=1)
        local = np.bincount(at.ravel(), np.repeat(lengths, 2), minlength=n) / degree
        positions = key[boundary]
        reach = NEAR_SEAM_SHARE * float(local[boundary].max())
        near = cKDTree(positions).query(positions, k=k, distance_upper_bound=reach)[1].ravel()
        rows = np.repeat(np.arange(boundary.size), k)
        found = near < boundary.size  # no neighbour within reach: index boundary.size
        a, b = boundary[rows[found]], boundary[near[found]]
        keep = a < b
        candidates.append(np.stack([a[keep], b[keep]], axis=1))
    pairs = np.unique(np.concatenate(candidates), axis=0)
    a, b = pairs[:, 0], pairs[:, 1]
    if a.size:  # ends of one edge are joined by it (a short boundary edge)
        joined = np.isin(a * n + b, edges[:, 0] * n + edges[:, 1])  # edges[:, 0] < edges[:, 1]
        a, b = a[~joined], b[~joined]
    if not a.size:
        return None
    # per key, the mean length of the edges at each pair's vertices (only those edges are measured)
    ends = np.unique(np.r_[a, b])
    touching = np.flatnonzero(np.isin(edges, ends).any(axis=1))
    inside = np.isin(edges[touching], ends)  # (t, 2): which ends of those edges are pair vertices
    near_edges = np.searchsorted(ends, edges[touching])  # their rows in ends (read where inside)
    rows_a, rows_b = np.searchsorted(ends, a), np.searchsorted(ends, b)
    count = np.bincount(near_edges[inside], minlength=ends.size)
    gaps, scales = [], []
    for key in keys:
        lengths = np.linalg.norm(key[edges[touching, 0]] - key[edges[touching, 1]], axis=1)
        mean = np.bincount(near_edges[inside], np.broadcast_to(lengths[:, None], inside.shape)[inside],
                           minlength=ends.size) / np.maximum(count, 1)
        scales.append(0.5 * (mean[rows_a] + mean[rows_b]))
        gaps.append(np.linalg.norm(key[a] - key[b], axis=1))
    gaps, scales = np.array(gaps), np.array(scales)  # (K, p)
    together = gaps < NEAR_SEAM_SHARE * scales
    closed = together[:-1] & together[1:]  # (K - 1, p): both keys of the gap
    used = closed.any(axis=0)
    pieces = topology.components()[1]
    piece = np.full(n, -1)
    piece[topology.triangles.ravel()] = np.repeat(pieces, 3)
    same = used & (piece[a] == piece[b])
    if same.any():
        used[same] = _apart_along_mesh(keys[0], edges, a[same], b[same], SAME_PIECE_PATH * scales[:, same].min(axis=0))
    if not used.any():
        return None
    a, b, gaps, scales, closed = a[used], b[used], gaps[:, used], scales[:, used], closed[:, used]
    every = together[:, used].all(axis=0)
    # a seam every key keeps closed is measured against every key (as far as any key has it apart),
    # one the motion closes against its gap's two keys
    apart = np.where(every, gaps.max(axis=0), np.maximum(gaps[:-1], gaps[1:]))
    edge = np.where(every, scales.min(axis=0), np.minimum(scales[:-1], scales[1:]))
    allowed = np.where(closed, apart + SEAM_OPENING_SHARE * edge + tolerance, np.inf)
    return NearSeams(a, b, apart, allowed, every)


def _apart_along_mesh(x: np.ndarray, edges: np.ndarray, a: np.ndarray, b: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Whether every path along ``edges`` (E, 2) in pose ``x`` (n, 3) from ``a[i]`` to ``b[i]`` (int
    (p,) each) is at least ``length[i]`` long, bool (p,): Dijkstra's distances (scipy's csgraph)
    from :data:`PATH_PAIRS_AT_ONCE` pairs at a time, each over the vertices within ``length`` of
    those pairs' ``a`` only (a shorter path cannot leave them: each of its vertices is nearer ``a``
    than the path is long), so that its cost and memory follow the pairs' neighbourhoods, not the
    mesh or the number of pairs (the distances are (pairs, vertices) at once)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra
    from scipy.spatial import cKDTree

    reach = float(length.max())
    box = np.flatnonzero(((x >= x[a].min(axis=0) - reach) & (x <= x[a].max(axis=0) + reach)).all(axis=1))
    local = np.full(x.shape[0], -1)  # each vertex's row in the box, -1 outside it
    local[box] = np.arange(box.size)
    inner = (local[edges] >= 0).all(axis=1)
    weights = np.linalg.norm(x[edges[inner, 0]] - x[edges[inner, 1]], axis=1)
    graph = csr_matrix((weights, (local[edges[inner, 0]], local[edges[inner, 1]])), shape=(box.size, box.size))
    tree = cKDTree(x[box])
    apart = np.ones(a.size, dtype=bool)
    order = cKDTree(x[a]).indices  # the pairs in the tree's leaf order: a batch's pairs lie together
    for batch in np.array_split(order, -(-a.size // PATH_PAIRS_AT_ONCE)):
        near = np.unique(np.concatenate(tree.query_ball_point(x[a[batch]], r=length[batch])).astype(int))
        starts, rows = np.unique(np.searchsorted(near, local[a[batch]]), return_inverse=True)
        distances = dijkstra(graph[near][:, near], directed=False, indices=starts, limit=float(length[batch].max()))
        at = np.minimum(np.searchsorted(near, local[b[batch]]), near.size - 1)
        reached = (local[b[batch]] >= 0) & (near[at] == local[b[batch]])  # b within the batch's neighbourhood
        apart[batch[reached]] = distances[rows[reached], at[reached]] >= length[batch[reached]]
    return apart


def seam_opening(seams: NearSeams, poses: list[np.ndarray], factors: list[float], names: tuple[str, str],
                 vertices: np.ndarray | None = None, gap: int = 0) -> tuple[str, tuple[float, ...], float] | None:
    """The warning's message, factors and excess (:meth:`NearSeams.opening`'s, the worst
    in-between's) where the in-betweens ``poses`` (list of (n, 3), in the
    positions' indices of ``seams``) at ``factors`` of gap ``gap``, between the keys ``names``, open
    the near-seams ``seams`` that both keys of the gap keep closed, once for the gap; None where
    none opens. ``vertices``: the caller's index of each vertex (int (n,)), where the poses' are
    welded ones, or None."""
    opened = [(factor, *seams.opening(x, gap)) for x, factor in zip(poses, factors)]
    opened = [o for o in opened if o[1]]
    if not opened:
        return None
    factor, count, widest, pair, _ = max(opened, key=lambda o: o[2])
    excess = max(o[4] for o in opened)
    a, b = int(seams.a[pair]), int(seams.b[pair])
    if vertices is not None:
        a, b = int(vertices[a]), int(vertices[b])
    keys = float(seams.apart[gap][np.isfinite(seams.allowed[gap])].max())
    pose = "in-between" if all(0.0 < o[0] < 1.0 for o in opened) else "pose"  # past the keys: no in-between
    separate = f"separate by up to {widest:.3g} ({count} vertex pair(s), e.g. vertices {a} and {b}) in the {pose}s"
    if seams.every[pair]:
        what = (f"the sides of a seam that is not welded (boundary vertices at most {keys:.3g} apart in every key, "
                f"farther than the weld joins, that the mesh does not join) {separate}; weld them (Mesh > Clean Up > "
                "Merge by Distance) before in-betweening")
    else:  # closed by the motion (sewing springs), open in other keys: no weld holds them for the whole range
        what = (f"pieces that the motion brings together (boundary vertices at most {keys:.3g} apart in both keys of "
                f"this gap but apart in other keys, as panels that sewing pulls shut) {separate}: no weld holds them "
                "over the whole range, so each piece is interpolated on its own; keys closer together here keep "
                "them nearer")
    between = f"between {names[0]} and {names[1]}"
    if len(opened) == 1:
        return f"{between}, the {pose} at factor {factor:g}: {what}", (factor,), excess
    # worded as core.sequence_warnings.gap_problems words several in-betweens alike (one shape for the operators)
    return (f"{between}, {len(opened)} of the {len(factors)} {pose}s alike, the worst at factor {factor:g}: {what}; "
            f"{pose}s alike at factors {factor_list([o[0] for o in opened])}",
            tuple(o[0] for o in opened), excess)
