"""Targets re-meshed the way real data are, and maps made the way data sets make them (issue 21).

- :func:`decimated`: a mesh subdivided (midpoints, the surface unchanged) and then simplified by
  quadric edge collapse (``fast-simplification``, dev only) to a vertex count: irregular
  triangles, density following curvature (on a flat sheet, wherever the collapses fell);
- :func:`varying_density_sheet`: points of a flat sheet four times denser on one side than on the
  other, Delaunay triangulated;
- :func:`hostile`: what a re-mesh may also carry — a few holes (a vertex's fan cut out; the vertex
  is then in no triangle), a tiny extra component (two triangles floating next to the surface),
  a seam of duplicated vertices (coincident copies, the triangles on one side using the copies),
  and a few unreferenced vertices on the surface;
- :func:`nearest_vertex_map` and :func:`template_maps`: the map as data sets ship it — the nearest
  target vertex of each base vertex at rest, or ``.vts``-style template maps (for each vertex of
  a third mesh, the 1-based index of its nearest vertex on each shape) composed by
  :func:`core.template_correspondence`;
- what goes wrong in real data (the transfer's probes): :func:`cut_hole` (a scan that missed a
  patch) and :func:`stray_matches` (a map with a few entries anywhere on the target).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, cKDTree


def subdivided(vertices, triangles):
    """Each triangle split in four at its edge midpoints: (vertices, triangles)."""
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    m = len(triangles)
    mid = len(vertices) + inverse.reshape(3, m).T  # (m, 3): midpoints of edges 01, 12, 20
    points = np.concatenate([vertices, vertices[unique].mean(axis=1)])
    a, b, c = triangles.T
    ab, bc, ca = mid.T
    tris = np.concatenate([np.stack(x, axis=1) for x in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return points, tris


def decimated(vertices, triangles, n_vertices: int):
    """``vertices``/``triangles`` subdivided once, then simplified by quadric edge collapse to
    about ``n_vertices`` vertices: (vertices, triangles), every vertex used."""
    import fast_simplification

    points, tris = subdivided(np.asarray(vertices, dtype=np.float64), np.asarray(triangles, dtype=np.int64))
    target_faces = int(round(len(tris) * n_vertices / len(points)))
    out_v, out_t = fast_simplification.simplify(points, tris.astype(np.int32), target_count=target_faces)
    out_t = np.asarray(out_t, dtype=np.int64)
    used, compact = np.unique(out_t, return_inverse=True)
    return np.asarray(out_v, dtype=np.float64)[used], compact.reshape(out_t.shape)


def varying_density_sheet(lo, hi, n_points: int, seed: int, ratio: float = 4.0):
    """About ``n_points`` points of the rectangle ``lo``–``hi`` (2-D), ``ratio`` × denser at the
    high-x side than at the low one (the boundary sampled too), Delaunay triangulated: (points
    (n, 2), triangles (m, 3), counter-clockwise)."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    # Density ∝ 1 + (ratio − 1) u along x: sample u by inverting its cumulative distribution.
    def along(count):
        r = rng.uniform(0, 1, count)
        a = ratio - 1.0
        return (np.sqrt(1 + a * (a + 2) * r) - 1) / a

    interior = np.stack([along(n_points), rng.uniform(0, 1, n_points)], axis=1)
    side = int(np.sqrt(n_points))
    ends = np.linspace(0, 1, side)
    border = np.concatenate([np.stack([along(side), np.zeros(side)], 1), np.stack([along(side), np.ones(side)], 1),
                             np.stack([np.zeros(side), ends], 1), np.stack([np.ones(3 * side), np.linspace(0, 1, 3 * side)], 1)])
    unit = np.concatenate([interior, border])
    # Drop one of two points closer than a fraction of the densest spacing (a sampler would not
    # keep both), the interior one where one is on the border.
    keep = np.ones(len(unit), bool)
    for i, j in cKDTree(unit).query_pairs(0.3 / np.sqrt(ratio * n_points)):
        if keep[i] and keep[j]:
            keep[min(i, j) if max(i, j) >= len(interior) > min(i, j) else max(i, j)] = False
    unit = unit[keep]
    points = lo + unit * (hi - lo)
    triangles = Delaunay(points).simplices.astype(np.int64)
    q = points[triangles]
    flip = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]) < 0
    triangles[flip] = triangles[flip][:, ::-1]
    return points, triangles


def hostile(vertices, triangles, seed: int, holes: int = 3, seam: int = 12, stray: int = 4, extra: bool = True):
    """The re-mesh ``vertices`` / ``triangles`` with hostile-but-valid defects (module
    docstring): (vertices, triangles, source) where ``source`` ``(n', 3)`` int / float describes
    each new vertex as a convex combination of old ones — (indices (n', 3), weights (n', 3)) — so
    any pose of the old mesh gives the pose of the new one."""
    from core.mesh_topology import mesh_topology

    rng = np.random.default_rng(seed)
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).copy()
    n = len(v)
    topo = mesh_topology(t, n, allow_non_manifold=True)
    on_boundary = np.zeros(n, bool)
    on_boundary[topo.edges[topo.boundary_edges].ravel()] = True
    interior = np.flatnonzero(~on_boundary)
    # Holes: the fans of a few interior vertices far from each other removed.
    centers = []
    for i in rng.permutation(interior):
        if len(centers) >= holes:
            break
        if all(np.linalg.norm(v[i] - v[c]) > 0.2 * np.ptp(v, axis=0).max() for c in centers):
            centers.append(i)
    t = t[~np.isin(t, centers).any(axis=1)]
    # A seam: a chain of interior edges (a shortest path between two interior vertices) whose
    # vertices are duplicated; the triangles on one side of the chain use the copies.
    topo = mesh_topology(t, n, allow_non_manifold=True)
    free = np.ones(n, bool)
    free[topo.edges[topo.boundary_edges].ravel()] = False
    free[centers] = False
    start = rng.choice(np.flatnonzero(free))
    chain = [int(start)]
    neighbours = [set() for _ in range(n)]
    for a, b in topo.edges:
        neighbours[a].add(int(b))
        neighbours[b].add(int(a))
    direction = rng.normal(size=3)
    while 0 < len(chain) < seam:
        options = [j for j in neighbours[chain[-1]] if free[j] and j not in chain
                   and not any(j in neighbours[c] for c in chain[:-1])]
        if not options:
            break
        chain.append(max(options, key=lambda j: (v[j] - v[chain[-1]]) @ direction))
    copies = {c: n + k for k, c in enumerate(chain[1:-1])}  # the ends stay shared (a slit)
    # The triangles left of the path (those holding a chain edge in its direction, and the rest of
    # each chain vertex's fan on that side) take the copies.
    def left_of(a, b):
        return int(np.flatnonzero(((t == a) & (np.roll(t, -1, axis=1) == b)).any(axis=1))[0])

    replace = []
    for k in range(1, len(chain) - 1):
        c, before, after = chain[k], chain[k - 1], chain[k + 1]
        fan = set(np.flatnonzero((t == c).any(axis=1)).tolist())
        side, todo = set(), [left_of(c, after)]
        while todo:  # across the fan's edges at c, but never across the chain
            f = todo.pop()
            if f in side:
                continue
            side.add(f)
            for x in t[f]:
                if x not in (c, before, after):
                    todo += [g for g in fan if g not in side and x in t[g]]
        replace += [(f, c) for f in side]
    for f, c in replace:
        t[f][t[f] == c] = copies[c]
    index = [np.stack([np.arange(n), np.zeros(n, int), np.zeros(n, int)], 1)]
    weight = [np.tile([1.0, 0.0, 0.0], (n, 1))]
    dup = np.array(list(copies), dtype=np.int64)
    index.append(np.stack([dup, dup, dup], 1))
    weight.append(np.tile([1.0, 0.0, 0.0], (len(dup), 1)))
    # A tiny extra component: two triangles over a random triangle, a third of an edge off.
    f = t[rng.integers(len(t))]
    base_index = len(v) + len(dup)
    quad = np.stack([f, f, f, f])
    quad_w = np.array([[0.8, 0.1, 0.1], [0.1, 0.8, 0.1], [0.1, 0.1, 0.8], [0.4, 0.4, 0.2]])
    index.append(quad)
    weight.append(quad_w)
    floating = np.array([[0, 1, 2], [0, 3, 1]])[: 2 if extra else 0] + base_index
    # Unreferenced vertices: at the barycenters of random triangles.
    stray_faces = t[rng.choice(len(t), stray, replace=False)].reshape(stray, 3)
    index.append(stray_faces)
    weight.append(np.full((stray, 3), 1.0 / 3.0))
    index, weight = np.concatenate(index), np.concatenate(weight)
    t = np.concatenate([t, floating])
    new_v = np.einsum("nk,nki->ni", weight, v[index])
    # The extra component floats a third of an edge off the surface.
    corners = v[f]
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    edge = np.linalg.norm(corners[1] - corners[0])
    lift = normal / np.linalg.norm(normal) * edge / 3
    new_v[base_index:base_index + 4] += lift
    return new_v, t, (index, weight, base_index, lift)


def hostile_pose(pose, source, rest_pose):
    """A pose ``(n, 3)`` of the original re-mesh carried to :func:`hostile`'s mesh (``source``:
    its last result; ``rest_pose`` the original re-mesh's rest, to move the floating component
    rigidly with the triangle it floats over)."""
    index, weight, first, lift = source
    new = np.einsum("nk,nki->ni", weight, pose[index])
    f = index[first]
    corners = pose[f]
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    new[first:first + 4] += normal / np.linalg.norm(normal) * np.linalg.norm(lift)
    return new


def nearest_vertex_map(base_rest, target_rest):
    """For every base vertex, the index of the nearest target vertex at rest (0-based)."""
    return cKDTree(target_rest).query(base_rest)[1].astype(np.int64)


def template_maps(template_rest, base_rest, target_rest):
    """``.vts``-style maps of a template: for each template vertex the 1-based index of its nearest
    vertex on the base and on the target, at rest: (base_vts, target_vts)."""
    return nearest_vertex_map(template_rest, base_rest) + 1, nearest_vertex_map(template_rest, target_rest) + 1


def cut_hole(vertices, triangles, share: float):
    """A round patch of ``share`` of the mesh's area cut out (the triangles whose centroids are
    nearest to the vertex nearest the mesh's centroid), vertices left in no triangle dropped:
    (vertices (n', 3), triangles (m', 3), kept (n',): each new vertex's old index)."""
    from core.mesh_topology import triangle_areas

    v, t = np.asarray(vertices, dtype=np.float64), np.asarray(triangles, dtype=np.int64)
    centre = v[cKDTree(v).query(v.mean(axis=0))[1]]
    areas = triangle_areas(v, t)
    order = np.argsort(np.linalg.norm(v[t].mean(axis=1) - centre, axis=1))
    cut = order[: np.searchsorted(np.cumsum(areas[order]), share * areas.sum())]
    kept, compact = np.unique(np.delete(t, cut, axis=0), return_inverse=True)
    return v[kept], compact.reshape(-1, 3), kept


def stray_matches(vertex_map, n_target: int, fraction: float, seed: int):
    """``vertex_map`` (n,) with a random ``fraction`` of its matched entries sent to random
    target vertices (of ``n_target``), as a map file or a functional map's conversion may hold."""
    rng = np.random.default_rng(seed)
    strayed = np.array(vertex_map, dtype=np.int64)
    matched = np.flatnonzero(strayed >= 0)
    pick = rng.choice(matched, int(round(fraction * matched.size)), replace=False)
    strayed[pick] = rng.integers(0, n_target, pick.size)
    return strayed
