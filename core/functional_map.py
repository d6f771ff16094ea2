"""Functional maps between two meshes of different connectivity (paper §6.3, eq. 6).

A point-to-point correspondence gives, for every vertex ``i`` of the base M, a matched vertex
``c[i]`` of the target N (as map files store it; not necessarily a bijection). Its pull-back of
functions is the sparse ``(n_M, n_N)`` matrix ``Π`` with ``Π[i, c[i]] = 1`` (``g ↦ g ∘ c``). The
functional map of eq. (6), ``F`` ``(k_N, k_M)``, takes coefficients of a function in the first
``k_M`` eigenfunctions ``Φ_M`` of M to coefficients in the first ``k_N`` eigenfunctions ``Φ_N`` of
N; it is the least-squares inverse of the pull-back in the reduced bases,

    F = argmin ‖Π Φ_N F − Φ_M‖²_{A_M}   ⇔   (Bᵀ A_M B) F = Bᵀ A_M Φ_M,   B = Π Φ_N  ``(n_M, k_N)``

(Φ_M is A_M-orthonormal). For the identity correspondence of one mesh and full bases this is
``Φ_N⁻¹ Φ_M = Φ_Nᵀ A_N Φ_M``, the map :func:`core.shape_difference.functional_map` builds for
poses of one mesh; truncated, both are projections of the same operator onto ``span Φ_N`` and
differ only in the norm (A_M here, A_N there), which a non-bijective map cannot provide.

Without a map, :func:`closest_point_correspondence` matches every base vertex to the nearest
target vertex of a rest pose that overlaps the base (KD-tree).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .errors import MeshError
from .mesh_topology import MeshTopology, mesh_topology
from .validation import real_array

#: Rings of base neighbours in the local affine fit that smooths a vertex map
#: (:func:`locally_affine_images`), and the relative spread below which a direction of a ring
#: counts as flat (the fit is a pseudo-inverse there: no motion along the normal of a flat ring).
AFFINE_RINGS = 2
AFFINE_CUTOFF = 1e-3
#: Target vertices past the boundary of the base's image are extrapolated from the nearest
#: triangle while no barycentric weight is below minus this (see :func:`push_forward_matrix`).
EXTRAPOLATION_LIMIT = 0.5
#: A correspondence entry for a base vertex without a matched target vertex (a partial map, such
#: as the composition of two template maps that no template vertex lands on).
UNMATCHED = -1
#: An unmatched vertex (or one with few matched neighbours) widens its ring, one ring at a time up
#: to AFFINE_MAX_RINGS, until it holds at least this many matched vertices: an affine map of a
#: curved patch needs points spread in two directions, and the snapping noise of single matches
#: averages out only over several.
AFFINE_MIN_MATCHED = 6
AFFINE_MAX_RINGS = 8
#: A matched base vertex whose target vertex lies more than this many target edge lengths (their
#: mean) from where the local affine fit of its neighbours' matches puts it is an outlying match
#: (:func:`reject_outlying_matches`): a vertex map snaps within about half a target edge, and on the
#: benchmark's re-meshed targets and maps (nearest vertex, template, 20–100 % matched; sampled,
#: decimated, hostile) every match is within 1.6 edges of its fit. One random match in a hundred
#: pulled the fits of its two rings across the target (1k limb, frame 40: 5.3 % RMS of the diagonal
#: off against 1.3 %).
OUTLIER_EDGES = 3.0
#: Rounds of :func:`reject_outlying_matches` (each refits without the matches rejected so far).
OUTLIER_ROUNDS = 4


def check_correspondence(correspondence, n_base: int, n_target: int, *, allow_unmatched: bool = False) -> np.ndarray:
    """``correspondence`` as int64 ``(n_base,)`` with values in ``0..n_target-1`` (and
    :data:`UNMATCHED`, -1, for a base vertex without a match when ``allow_unmatched``); raises
    :class:`MeshError` naming the first bad entry."""
    array = real_array(correspondence, "The correspondence", "target vertex indices")  # no booleans, text, complex
    if array.ndim != 1 or array.shape[0] != n_base:
        raise MeshError(
            f"The correspondence must give one target vertex index per base vertex, an integer "
            f"array of shape ({n_base},); got shape {array.shape}."
        )
    if array.size and not np.issubdtype(array.dtype, np.integer):
        if not (np.isfinite(array).all() and np.all(np.mod(array, 1) == 0)):
            raise MeshError("The correspondence must hold integer target vertex indices.")
    low = UNMATCHED if allow_unmatched else 0
    # in the given type: the cast to int64 wraps uint64 2^64 − 1 to −1 (read as unmatched) and
    # floats past 2^63 to another index
    bad = np.flatnonzero((array < low) | (array >= n_target))
    if bad.size:
        i = int(bad[0])
        unmatched = " or -1 for an unmatched base vertex" if allow_unmatched else ""
        raise MeshError(
            f"The correspondence maps base vertex {i} to target vertex {int(array[i])}, but the "
            f"target has {n_target} vertices (valid indices are 0..{n_target - 1}{unmatched}); "
            f"{bad.size} entries are out of range. Use a map computed for these two meshes."
        )
    return array.astype(np.int64)


def closest_point_correspondence(base_vertices: np.ndarray, target_vertices: np.ndarray) -> np.ndarray:
    """For every base vertex ``(n_M, 3)`` the index of the nearest target vertex ``(n_N, 3)``,
    int64 ``(n_M,)``: the correspondence of two meshes that overlap at rest (same place, same
    scale). A KD-tree query, O(n log n)."""
    from scipy.spatial import cKDTree

    _, index = cKDTree(np.asarray(target_vertices, dtype=np.float64)).query(np.asarray(base_vertices, dtype=np.float64))
    return np.asarray(index, dtype=np.int64)


def pull_back_matrix(triangles: np.ndarray, weights: np.ndarray, n_target: int) -> sp.csr_matrix:
    """``Π`` float64 ``(n_M, n_N)`` of a point-to-surface map: row ``i`` holds the barycentric
    ``weights[i]`` ``(3,)`` of base vertex ``i``'s image in the target triangle ``triangles[i]``
    (vertex indices ``(3,)``), so ``(Π g)[i]`` is the target function ``g`` interpolated there."""
    n = triangles.shape[0]
    return sp.csr_matrix((weights.ravel(), (np.repeat(np.arange(n), 3), triangles.ravel())), shape=(n, n_target))


def functional_map(target_functions: np.ndarray, target_mass: sp.spmatrix, pushed_base_functions: np.ndarray) -> np.ndarray:
    """``F = Φ_Nᵀ A_N (Q Φ_M)`` float64 ``(k_N, k_M)``: the base functions carried to the target
    (``Q Φ_M`` ``(n_N, k_M)``, see :func:`push_forward_matrix`) projected A_N-orthogonally onto the
    target functions ``Φ_N`` ``(n_N, k_N)`` (least squares in the reduced basis with the target's
    mass matrix ``A_N`` ``(n_N, n_N)``)."""
    return target_functions.T @ np.asarray(target_mass @ pushed_base_functions)


# ---------------------------------------------------------------------------------------------
# From a vertex map to a point-to-surface map
# ---------------------------------------------------------------------------------------------
def locally_affine_images(base_positions: np.ndarray, base_edges: np.ndarray, images: np.ndarray,
                          rings: int = AFFINE_RINGS, matched: np.ndarray | None = None) -> np.ndarray:
    """Images of the base vertices ``(n_M, 3)`` smoothed by a local affine fit: for every base
    vertex ``i``, the affine map ``x ↦ A x + b`` best taking the base positions of its
    ``rings``-ring (``base_positions`` ``(n_M, 3)``, edges ``(E, 2)``) to their ``images``
    ``(n_M, 3)`` (least squares; pseudo-inverse across a flat ring), evaluated at ``x_i``. Exact for a
    map that is affine over a ring (a rigid motion, a stretch, a bend far larger than the ring),
    while the snapping of a vertex map — up to half a target edge, in random directions — is
    averaged out; boundaries are fitted like the interior (no shrinking, unlike a diffusion).

    ``matched`` bool ``(n_M,)`` (a partial map): only matched vertices enter the fits (the other
    rows of ``images`` are ignored), so every vertex, matched or not, gets the image the fit of its
    matched neighbours gives; a ring with fewer than :data:`AFFINE_MIN_MATCHED` matched vertices
    grows, up to :data:`AFFINE_MAX_RINGS` rings; a vertex with none even then takes the fit of
    the nearest matched vertex along the mesh (:func:`nearest_matched`), extrapolated to it."""
    n = base_positions.shape[0]
    adjacency = sp.csr_matrix((np.ones(2 * len(base_edges)), (base_edges.ravel(), base_edges[:, ::-1].ravel())),
                              shape=(n, n)) + sp.identity(n, format="csr")
    ring = adjacency
    for _ in range(rings - 1):
        ring = ring @ adjacency
    ring.data[:] = 1.0
    y = images
    if matched is not None:
        matched = np.asarray(matched, dtype=bool)
        ring = _matched_rings(ring, adjacency, matched, rings)
        empty = np.flatnonzero(np.diff(ring.indptr) == 0)
        if empty.size:  # far from every match: the nearest matched vertex's fit, extrapolated
            nearest = nearest_matched(base_positions, base_edges, matched)
            ring = sp.vstack([ring, ring[nearest[empty]]]).tocsr()
            take = np.arange(n)
            take[empty] = n + np.arange(empty.size)
            ring = ring[take]
        y = np.where(matched[:, None], images, 0.0)
    ring = sp.diags(1.0 / np.asarray(ring.sum(axis=1)).ravel()) @ ring  # row means
    x = base_positions
    x_mean, y_mean = ring @ x, ring @ y
    xx = (ring @ np.einsum("ni,nj->nij", x, x).reshape(n, 9)).reshape(n, 3, 3) - np.einsum("ni,nj->nij", x_mean, x_mean)
    yx = (ring @ np.einsum("ni,nj->nij", y, x).reshape(n, 9)).reshape(n, 3, 3) - np.einsum("ni,nj->nij", y_mean, x_mean)
    values, vectors = np.linalg.eigh(xx)
    inverse = np.where(values > AFFINE_CUTOFF * values[:, -1:], 1.0 / np.maximum(values, np.finfo(float).tiny), 0.0)
    affine = yx @ np.einsum("nij,nj,nkj->nik", vectors, inverse, vectors)  # yx · pinv(xx)
    return y_mean + np.einsum("nij,nj->ni", affine, x - x_mean)


def reject_outlying_matches(base_positions: np.ndarray, base_edges: np.ndarray, images: np.ndarray,
                            matched: np.ndarray, edge_length: float) -> tuple[np.ndarray, np.ndarray]:
    """The matches of a vertex map that its neighbours contradict, and the map's smoothed images
    without them: ``(points (n_M, 3), kept bool (n_M,))`` — the map of the surface §6.3 needs,
    from a vertex map with stray entries.

    ``images`` ``(n_M, 3)``: each base vertex's matched target position (rows where ``matched``
    bool ``(n_M,)`` is False are ignored); ``base_positions`` ``(n_M, 3)``, ``base_edges``
    ``(E, 2)`` as for :func:`locally_affine_images`. A match lying more than :data:`OUTLIER_EDGES`
    × ``edge_length`` (the target's mean edge) from the local affine fit of the kept matches around
    it is left out and the fits are made again without it, up to :data:`OUTLIER_ROUNDS` times: a
    match left out is judged against its neighbours' fit alone, so a good match that an outlier's
    pull put past the bound comes back in the next round. ``points`` are
    :func:`locally_affine_images` of the kept matches (called as for a complete map where every
    match is kept and ``matched`` is all True), ``kept`` the matches kept."""
    matched = np.asarray(matched, dtype=bool)
    kept = matched
    bound = OUTLIER_EDGES * edge_length
    for _ in range(OUTLIER_ROUNDS):
        points = locally_affine_images(base_positions, base_edges, images, matched=None if kept.all() else kept)
        outlying = matched & (np.linalg.norm(points - images, axis=1) > bound)
        if np.array_equal(kept, matched & ~outlying):
            break
        kept = matched & ~outlying
    else:
        points = locally_affine_images(base_positions, base_edges, images, matched=None if kept.all() else kept)
    return points, kept


def _matched_rings(ring: sp.csr_matrix, adjacency: sp.csr_matrix, matched: np.ndarray, rings: int) -> sp.csr_matrix:
    """``ring`` ``(n, n)`` (0/1) restricted to the ``matched`` columns, each row grown one ring at
    a time (``adjacency`` with the diagonal) while it holds fewer than :data:`AFFINE_MIN_MATCHED`
    matched vertices, up to :data:`AFFINE_MAX_RINGS` (a row may be left with none)."""
    keep = sp.diags(matched.astype(np.float64))
    grown = ring
    few = np.flatnonzero(np.diff((ring @ keep).tocsr().indptr) < AFFINE_MIN_MATCHED)
    for _ in range(rings, AFFINE_MAX_RINGS):
        if not few.size:
            break
        rows = grown[few] @ adjacency
        rows.data[:] = 1.0
        # Replace the rows `few` of `grown` by their wider rings.
        select = sp.csr_matrix((np.ones(few.size), (few, np.arange(few.size))), shape=(grown.shape[0], few.size))
        others = sp.diags(np.isin(np.arange(grown.shape[0]), few, invert=True).astype(np.float64))
        grown = (others @ grown + select @ rows).tocsr()
        counts = np.diff((grown[few] @ keep).tocsr().indptr)
        few = few[counts < AFFINE_MIN_MATCHED]
    restricted = (grown @ keep).tocsr()
    restricted.eliminate_zeros()
    return restricted


def nearest_matched(base_positions: np.ndarray, base_edges: np.ndarray, matched: np.ndarray) -> np.ndarray:
    """For every base vertex ``(n_M,)`` the nearest ``matched`` vertex (bool ``(n_M,)``) along the
    mesh's edges (``base_positions`` ``(n_M, 3)``, ``base_edges`` ``(E, 2)``; Dijkstra from every
    matched vertex at once), int64 ``(n_M,)``. Raises :class:`MeshError` when a connected part of
    the base has no matched vertex."""
    from scipy.sparse.csgraph import dijkstra

    n = base_positions.shape[0]
    lengths = np.linalg.norm(base_positions[base_edges[:, 0]] - base_positions[base_edges[:, 1]], axis=1)
    graph = sp.csr_matrix((np.maximum(lengths, np.finfo(float).tiny), (base_edges[:, 0], base_edges[:, 1])), shape=(n, n))
    _, _, sources = dijkstra(graph, directed=False, indices=np.flatnonzero(matched), min_only=True,
                             return_predecessors=True)
    lost = np.flatnonzero(sources < 0)
    if lost.size:
        raise MeshError(
            f"Base vertex {int(lost[0])} is in a part of the base mesh where the map matches no vertex "
            f"({lost.size} such vertices): a map must match some vertices of every connected part."
        )
    return sources.astype(np.int64)


def plane_weights(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Barycentric weights ``(P, 3)`` of the orthogonal projection of ``points`` ``(P, 3)`` onto
    the planes of the triangles ``corners`` ``(P, 3, 3)`` (negative outside the triangle)."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    e1, e2, d = b - a, c - a, points - a
    g11, g12, g22 = (np.einsum("ij,ij->i", u, v) for u, v in ((e1, e1), (e1, e2), (e2, e2)))
    r1, r2 = np.einsum("ij,ij->i", d, e1), np.einsum("ij,ij->i", d, e2)
    det = np.maximum(g11 * g22 - g12 * g12, np.finfo(float).tiny)
    s = (g22 * r1 - g12 * r2) / det
    t = (g11 * r2 - g12 * r1) / det
    return np.stack([1.0 - s - t, s, t], axis=1)


def closest_points_on_triangles(points: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest point of each ``points`` ``(P, 3)`` on its triangle ``corners`` ``(P, 3, 3)``:
    returns barycentric weights ``(P, 3)`` and squared distances ``(P,)``. Inside the triangle
    the orthogonal projection, else the nearest point of its three sides; a triangle of no area (a
    segment, a point) by its sides alone. (Written out: no library in the extension's dependencies
    offers it vectorized.)"""
    weights = plane_weights(points, corners)
    flat = ~(np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1) > 0)
    outside = (weights < 0).any(axis=1) | flat
    if outside.any():
        best = np.full(int(outside.sum()), np.inf)
        best_w = np.zeros((best.size, 3))
        p = points[outside]
        for i, j in ((0, 1), (1, 2), (2, 0)):
            u, v = corners[outside, i], corners[outside, j]
            edge = v - u
            f = np.clip(np.einsum("ij,ij->i", p - u, edge) / np.maximum(np.einsum("ij,ij->i", edge, edge), np.finfo(float).tiny), 0.0, 1.0)
            dist = np.sum((u + f[:, None] * edge - p) ** 2, axis=1)
            closer = dist < best
            best[closer] = dist[closer]
            w = np.zeros((best.size, 3))
            w[:, i], w[:, j] = 1.0 - f, f
            best_w[closer] = w[closer]
        weights[outside] = best_w
    nearest = np.einsum("nk,nki->ni", weights, corners)
    return weights, np.sum((nearest - points) ** 2, axis=1)


def project_near(points: np.ndarray, seeds: np.ndarray, target_positions: np.ndarray,
                 target_triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each point ``(P, 3)``, its closest point on the target triangles touching the 1-ring
    of its seed vertex ``seeds`` ``(P,)``: the target triangle index ``(P,)`` and barycentric
    weights ``(P, 3)``. The search stays next to the seed, so a point is never matched across a
    fold or to another part of the surface than its vertex match says."""
    n, m = target_positions.shape[0], target_triangles.shape[0]
    incidence = sp.csr_matrix((np.ones(3 * m), (target_triangles.ravel(), np.repeat(np.arange(m), 3))), shape=(n, m))
    vertex_ring = sp.csr_matrix((incidence @ incidence.T) > 0)  # vertices sharing a triangle, and itself
    near = sp.csr_matrix((vertex_ring @ incidence) > 0)[seeds]  # (P, m) candidate triangles
    owner = np.repeat(np.arange(near.shape[0]), np.diff(near.indptr))
    candidates = near.indices
    weights, dist = closest_points_on_triangles(points[owner], target_positions[target_triangles[candidates]])
    order = np.lexsort((dist, owner))
    first = order[np.searchsorted(owner[order], np.arange(points.shape[0]))]
    return candidates[first], weights[first]


def walk_near(points: np.ndarray, seeds: np.ndarray, target_positions: np.ndarray,
              target_triangles: np.ndarray, steps: int = 64) -> np.ndarray:
    """Seeds ``(P,)`` for :func:`project_near` of ``points`` ``(P, 3)`` that may lie several
    target edges from their first ``seeds``: each step moves a seed to the corner nearest to its
    point's closest point on the triangles around it (a walk on the target surface, so it never
    jumps across a fold), until no seed moves (or ``steps``)."""
    seeds = np.array(seeds, dtype=np.int64)
    moving = np.arange(points.shape[0])
    for _ in range(steps):
        if not moving.size:
            break
        triangles, weights = project_near(points[moving], seeds[moving], target_positions, target_triangles)
        corners = target_triangles[triangles]
        nearest = corners[np.arange(moving.size), np.argmax(weights, axis=1)]
        moved = nearest != seeds[moving]
        seeds[moving[moved]] = nearest[moved]
        moving = moving[moved]
    return seeds


def push_forward_matrix(target_points: np.ndarray, base_images: np.ndarray, base_triangles: np.ndarray, *,
                        topology: MeshTopology | None = None) -> sp.csr_matrix:
    """``Q`` float64 ``(n_N, n_M)``: ``(Q f)[j]`` is the base function ``f`` interpolated at the
    preimage of target vertex ``j``. The preimages are found on the *image mesh* — the base
    triangles ``(m_M, 3)`` at the images of the base vertices on the target, ``base_images``
    ``(n_M, 3)`` — as the closest point to each target vertex ``target_points`` ``(n_N, 3)``
    (searched next to the nearest image vertex): the inverse of the base → target map, defined at
    every target vertex even where that map is not onto (extrapolated linearly past the image
    mesh's boundary).

    A closest point on an edge or vertex inside the image mesh is kept as it is: it is the same
    point whichever triangle around it reports it, so ``Q`` moves continuously with the inputs
    (extrapolated from one of the triangles that meet there, a preimage on a curved mesh would
    depend on which one rounding picks: ``Q`` would move by 4.5e-3 under a 1e-9 rad turn of an
    icosphere). ``topology``: the base's :class:`~core.mesh_topology.MeshTopology` of
    ``base_triangles`` on ``n_M`` vertices where the caller has it (its boundary is read), else
    built here."""
    from scipy.spatial import cKDTree

    _, seeds = cKDTree(base_images).query(target_points)
    triangles, weights = project_near(target_points, np.asarray(seeds, dtype=np.int64), base_images, base_triangles)
    # Outside the image mesh (a target boundary reaching past the base's), extrapolate linearly
    # from the nearest triangle instead of clamping onto its side: clamped, a row of target
    # vertices would land on one line and their triangles would collapse.
    # Only just outside (a fraction of a triangle): farther out, clamping is the safer guess.
    if topology is None:
        topology = mesh_topology(base_triangles, base_images.shape[0], allow_non_manifold=True, allow_bow_ties=True)
    clamped = (weights <= 0.0).any(axis=1) & _on_boundary(base_triangles[triangles], weights > 0.0,
                                                          topology.edges[topology.boundary_edges],
                                                          base_images.shape[0])
    outside = np.flatnonzero(clamped)
    if outside.size:
        extrapolated = plane_weights(target_points[outside], base_images[base_triangles[triangles[outside]]])
        near = extrapolated.min(axis=1) >= -EXTRAPOLATION_LIMIT
        weights[outside[near]] = extrapolated[near]
    return pull_back_matrix(base_triangles[triangles], weights, base_images.shape[0])


def _on_boundary(corners: np.ndarray, support: np.ndarray, boundary_edges: np.ndarray, n: int) -> np.ndarray:
    """bool ``(P,)``: whether each point of a triangle (corners ``(P, 3)``, the corners with a
    positive barycentric weight ``support`` bool ``(P, 3)``) lies on the boundary of a mesh on ``n``
    vertices whose boundary edges are ``boundary_edges`` ``(B, 2)``: on one of them, or at a corner
    that ends one. A point inside a triangle (three corners) is not."""
    ends = np.sort(boundary_edges, axis=1)
    boundary_keys = ends[:, 0] * n + ends[:, 1]
    boundary_vertices = np.zeros(n, dtype=bool)
    boundary_vertices[boundary_edges.ravel()] = True
    corners_in = support.sum(axis=1)
    result = np.zeros(corners.shape[0], dtype=bool)
    at_vertex = np.flatnonzero(corners_in == 1)
    result[at_vertex] = boundary_vertices[corners[at_vertex][support[at_vertex]]]
    on_edge = np.flatnonzero(corners_in == 2)
    pairs = np.sort(corners[on_edge][support[on_edge]].reshape(-1, 2), axis=1)
    result[on_edge] = np.isin(pairs[:, 0] * n + pairs[:, 1], boundary_keys)
    return result
