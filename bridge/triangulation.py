"""The triangles a mesh gives the core: its loop triangles (n-gons triangulated) as int64 ``(m, 3)``
vertex indices, the n-gons split into zero-area triangles or slivers thinner than the rounding of
the mesh's coordinates split again, the polygon of each loop
triangle, and a quad re-split where full-basis differences could not determine a part's areas
(paper Prop. 1).
"""

from __future__ import annotations

import bpy
import numpy as np

from .mesh_data import vertex_positions


def mesh_triangles(mesh: bpy.types.Mesh) -> np.ndarray:
    """The loop triangles of ``mesh`` (n-gons triangulated) as int64 ``(m, 3)`` vertex indices,
    with the n-gons Blender triangulated into zero-area triangles or rounding slivers triangulated
    again about their own centre (see :func:`_retriangulated`)."""
    mesh.calc_loop_triangles()
    buffer = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", buffer)
    triangles = buffer.reshape(-1, 3).astype(np.int64)
    if len(triangles) > len(mesh.polygons):  # n-gons
        triangles = _retriangulated(mesh, triangles)
    return triangles


def _retriangulated(mesh: bpy.types.Mesh, triangles: np.ndarray) -> np.ndarray:
    """``triangles`` with every n-gon that Blender split into a zero-area triangle (an n-gon with
    collinear corners, as Dissolve leaves) or into a sliver less high than twice the rounding of
    the mesh's coordinates (the core's ``sliver`` warning, :mod:`core.rounded_slivers`) split again
    by Blender's *Beauty* triangulation (``bmesh.ops.triangulate``) in coordinates about the
    n-gon's centre, where the result is better (:func:`_flaws`: no zero-area triangle where
    Blender's had one, no sliver where Blender's had only slivers): the loop triangles' ear clipping may cut
    an ear between collinear corners (at 1e5 units from the origin, where single precision rounds
    them onto one line, it did), and between corners that single precision rounds just off one
    line (a grid whose rows of quads were merged into 6- and 10-gons, then turned and applied: 1,019
    ears 3e-10–9e-8 high against sides of 0.02–0.04, which the core warned of as "the mesh's own
    slivers" to dissolve, and which a key moved along the normal can round to zero area, refused
    as degenerate faces: Degenerate Dissolve leaves such n-gons as they are). Only n-gons whose
    slivers another triangulation could avoid are rebuilt (:func:`_sliver_bound`), so a mesh whose
    faces are all smaller than that height (far from the origin) is read at numpy's cost. The
    n-gon's triangles keep their rows (c − 2 for c corners either way) and its winding. The
    triangles are chosen once, from the mesh's own positions, and serve every key and frame."""
    import bmesh

    from ..core.coordinate_rounding import coordinate_rounding
    from ..core.rounded_slivers import ROUNDED_SLIVER

    positions = vertex_positions(mesh)
    thin = coordinate_rounding([positions]) / ROUNDED_SLIVER  # the core's sliver height (rounded_slivers)
    flaws = _flaws(positions, triangles, thin)
    if not flaws.any():
        return triangles
    polygons = loop_triangle_polygons(mesh)
    worst = np.zeros(len(mesh.polygons), dtype=np.int64)
    np.maximum.at(worst, polygons, flaws)
    corner_counts = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_total", corner_counts)
    worst[corner_counts == 3] = 0  # a triangle has no other triangulation
    slivered = np.flatnonzero(worst == 1)  # rebuilt only where some triangulation may have no sliver
    worst[slivered[_sliver_bound(mesh, positions, triangles, polygons, slivered) <= thin]] = 0
    triangles = triangles.copy()
    order = np.argsort(polygons, kind="stable")  # each polygon's rows without a pass over all of them
    firsts = np.searchsorted(polygons[order], np.arange(len(mesh.polygons) + 1))
    for polygon in np.flatnonzero(worst):
        corners = np.array(mesh.polygons[polygon].vertices, dtype=np.int64)
        rows = order[firsts[polygon]:firsts[polygon + 1]]
        bm = bmesh.new()
        try:
            verts = [bm.verts.new(p) for p in positions[corners] - positions[corners].mean(axis=0)]
            bm.verts.index_update()
            face = bm.faces.new(verts)
            face.normal_update()  # triangulate projects along the face normal, (0, 0, 0) until computed
            bmesh.ops.triangulate(bm, faces=[face], quad_method='BEAUTY', ngon_method='BEAUTY')
            candidate = corners[np.array([[v.index for v in face.verts] for face in bm.faces], dtype=np.int64)]
        except ValueError:  # a face Blender cannot rebuild (repeated corners): keep its triangles
            continue
        finally:
            bm.free()
        if (len(candidate) == len(rows) and _flaws(positions, candidate, thin).max() < worst[polygon]
                and _covers(positions, candidate, triangles[rows])):
            triangles[rows] = candidate
    return triangles


def _flaws(positions: np.ndarray, triangles: np.ndarray, thin: float) -> np.ndarray:
    """Per triangle, int64 ``(m,)``: 2 where it has zero area (the core refuses it,
    :data:`core.mesh_topology.DEGENERATE_TRIANGLE_RATIO`), 1 where it is a sliver no higher than
    ``thin`` (the core warns of it, :mod:`core.rounded_slivers`), else 0."""
    from ..core.mesh_topology import DEGENERATE_TRIANGLE_RATIO

    doubled, longest = _doubled_areas(positions, triangles), _longest(positions, triangles)
    sliver = (doubled <= thin * np.sqrt(longest)).astype(np.int64)
    return np.where(doubled <= DEGENERATE_TRIANGLE_RATIO * longest, 2, sliver)


def _sliver_bound(mesh: bpy.types.Mesh, positions: np.ndarray, triangles: np.ndarray, polygons: np.ndarray,
                  chosen: np.ndarray) -> np.ndarray:
    """Per polygon of ``chosen`` (int ``(p,)``), float ``(p,)``: a height that every triangulation of it
    that :func:`_covers` its loop ``triangles`` (``polygons`` the polygon of each) has a triangle
    no higher than. A quad's is exact: the higher of its two splits' least heights. Else the least
    height over the triangles is at most their summed doubled areas (at most the loop triangles')
    over their summed longest sides (at least a third of the perimeter: each side of the polygon is
    a side of one triangle)."""
    doubled = np.bincount(polygons, _doubled_areas(positions, triangles), minlength=len(mesh.polygons))[chosen]
    starts, totals = (np.empty(len(mesh.polygons), dtype=np.int32) for _ in range(2))
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", totals)
    starts, totals = starts[chosen], totals[chosen]
    loop_vertices = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", loop_vertices)
    first = np.repeat(np.cumsum(totals) - totals, totals)  # each chosen loop's polygon's first, in the chosen loops
    within = np.arange(totals.sum()) - first
    loops = np.repeat(starts, totals) + within
    following = np.repeat(starts, totals) + (within + 1) % np.repeat(totals, totals)
    sides = np.linalg.norm(positions[loop_vertices[following]] - positions[loop_vertices[loops]], axis=1)
    perimeters = np.bincount(np.repeat(np.arange(len(chosen)), totals), sides, minlength=len(chosen))
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(perimeters > 0, 3.0 * (1 + 1e-6) * doubled / perimeters, 0.0)
    quads = np.flatnonzero(totals == 4)
    corners = loop_vertices[starts[quads, None] + np.arange(4)]
    splits = [corners[:, [[0, 1, 2], [0, 2, 3]]], corners[:, [[0, 1, 3], [1, 2, 3]]]]  # (q, 2, 3) each
    bound[quads] = np.max([_heights(positions, split.reshape(-1, 3)).reshape(-1, 2).min(axis=1) for split in splits],
                          axis=0)
    return bound


def _heights(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The least height of each of ``triangles`` (int ``(m, 3)``): its doubled area over its longest side."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.nan_to_num(_doubled_areas(positions, triangles) / np.sqrt(_longest(positions, triangles)))


def area_recoverable_triangles(mesh: bpy.types.Mesh, triangles: np.ndarray) -> np.ndarray:
    """``triangles`` (:func:`mesh_triangles` of ``mesh``, int64 ``(m, 3)``) with one quad split
    along its other diagonal in every closed part whose triangles two-colour
    (:func:`core.full_basis_recovery.two_colour_parts`: full-basis differences cannot determine
    its areas, Prop. 1): how Blender splits a quad is its choice, not the user's, and a quad mesh
    with a handle (the Torus primitive) is split into such triangles, every vertex of even
    valence. The other diagonal gives four vertices odd valence. A quad is re-split only where its
    two new triangles face its way and cover it (:func:`_covers`), neither is flat and its other
    diagonal is not already an edge (the mesh would not stay a manifold); a part
    without such a quad, or a mesh the core refuses, keeps its triangles (the core says why)."""
    from ..core.errors import MeshError
    from ..core.full_basis_recovery import two_colour_parts
    from ..core.mesh_topology import DEGENERATE_TRIANGLE_RATIO, mesh_topology

    try:
        topology = mesh_topology(triangles, len(mesh.vertices))
    except MeshError:
        return triangles
    labels, bad = two_colour_parts(topology)
    if not bad.size:
        return triangles
    edges = set(map(tuple, topology.edges.tolist()))
    positions = vertex_positions(mesh)
    polygons = loop_triangle_polygons(mesh)
    triangles = triangles.copy()
    for part in bad:
        for polygon in np.unique(polygons[labels == part]):
            corners = np.array(mesh.polygons[polygon].vertices, dtype=np.int64)
            if corners.size != 4:
                continue
            rows = np.flatnonzero(polygons == polygon)
            splits = corners[np.array([[[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]]])]
            used = set(map(tuple, np.sort(triangles[rows], axis=1).tolist()))
            candidate = splits[1] if used == set(map(tuple, np.sort(splits[0], axis=1).tolist())) else splits[0]
            diagonal = tuple(sorted(set(candidate[0].tolist()) & set(candidate[1].tolist())))
            flat = _doubled_areas(positions, candidate) <= DEGENERATE_TRIANGLE_RATIO * _longest(positions, candidate)
            if diagonal not in edges and not flat.any() and _covers(positions, candidate, triangles[rows]):
                triangles[rows] = candidate
                break
    return triangles


def _covers(positions: np.ndarray, candidate: np.ndarray, original: np.ndarray) -> bool:
    """Whether the triangles ``candidate`` of an n-gon cover it as its loop triangles ``original``
    do: the same vector area (their area-weighted normals sum to the face's), every one facing
    the face's way, none overlapping (their areas add up to no more than the loop triangles')."""
    def vector_areas(rows):
        a, b, c = (positions[rows[:, k]] for k in range(3))
        return np.cross(b - a, c - a)

    ours, theirs = vector_areas(candidate), vector_areas(original)
    total = theirs.sum(axis=0)
    scale = np.linalg.norm(theirs, axis=1).sum()
    return bool(np.linalg.norm(ours.sum(axis=0) - total) <= 1e-6 * scale and (ours @ total > 0).all()
                and np.linalg.norm(ours, axis=1).sum() <= (1 + 1e-6) * scale)


def _doubled_areas(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    a, b, c = (positions[triangles[:, k]] for k in range(3))
    return np.linalg.norm(np.cross(b - a, c - a), axis=1)


def _longest(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    a, b, c = (positions[triangles[:, k]] for k in range(3))
    return np.max([np.einsum("ij,ij->i", p - q, p - q) for p, q in ((a, b), (b, c), (c, a))], axis=0)


def loop_triangle_polygons(mesh) -> np.ndarray:
    """The polygon of every loop triangle, int64 ``(m,)`` (same order as bridge.triangulation.mesh_triangles)."""
    mesh.calc_loop_triangles()
    buffer = np.empty(len(mesh.loop_triangles), dtype=np.int32)
    mesh.loop_triangles.foreach_get("polygon_index", buffer)
    return buffer.astype(np.int64)
