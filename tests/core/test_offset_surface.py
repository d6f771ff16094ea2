"""Offset surface (Fig. 5) and canonical thickening (Fig. 6)."""

import itertools

import numpy as np

from core.mesh_topology import mesh_topology
from core.offset_surface import default_offset, offset_surface
from meshes import cube_with_bump, drape, grid


def test_33x33_grid_matches_the_papers_cloth_hd_offset_mesh():
    vertices, triangles = grid(33, alternate=False)
    base = mesh_topology(triangles, len(vertices))
    surface = offset_surface(base)
    assert (base.n_vertices, base.n_triangles, base.n_edges) == (1089, 2048, 3136)
    assert (surface.topology.n_vertices, surface.topology.n_triangles, surface.topology.n_edges) == (3135, 6016, 9150)


def _thickening(vertices, triangles, offset=None):
    base = mesh_topology(triangles, len(vertices))
    surface = offset_surface(base)
    t = default_offset(vertices, triangles) if offset is None else offset
    positions = surface.positions(vertices, t)
    points = surface.thickening_points(vertices, positions)
    squared = surface.thickening_squared_lengths(base.squared_edge_lengths(vertices), surface.topology.squared_edge_lengths(positions), t)
    return surface, points, squared, t


def _volumes(points, tets):
    p = points[tets]
    return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])


def test_offset_vertices_sit_at_distance_t_along_normals():
    vertices, triangles = cube_with_bump(6)
    surface, points, _, t = _thickening(vertices, triangles)
    n = len(vertices)
    lifted = points[n : n + len(surface.lifted_vertices)]
    assert np.allclose(np.linalg.norm(lifted - vertices[surface.lifted_vertices], axis=1), t)
    centers = points[n + len(surface.lifted_vertices) :]
    barycenters = vertices[triangles[surface.centered_triangles]].mean(axis=1)
    assert np.allclose(np.linalg.norm(centers - barycenters, axis=1), t)


def test_thickening_lengths_follow_from_base_and_offset_lengths():
    vertices, triangles = grid(9, jitter=0.3)
    vertices = drape(vertices, 3.0)
    surface, points, squared, _ = _thickening(vertices, triangles)
    edges = surface.thickening_edges
    direct = np.sum((points[edges[:, 0]] - points[edges[:, 1]]) ** 2, axis=1)
    assert np.allclose(squared, direct, rtol=1e-12, atol=1e-15)
    # Every tetrahedron edge is a thickening edge, and tetrahedra fill the slab without overlap
    # on a flat sheet: all positively oriented, total volume = area × t.
    keys = {tuple(e) for e in np.sort(edges, axis=1).tolist()}
    tets = surface.thickening_tetrahedra
    assert all(tuple(sorted((int(q[i]), int(q[j])))) in keys for q in tets for i, j in itertools.combinations(range(4), 2))
    flat, flat_triangles = grid(9, jitter=0.3)
    surface, points, _, t = _thickening(flat, flat_triangles)
    volumes = _volumes(points, surface.thickening_tetrahedra) / 6.0
    assert volumes.min() > 0


def test_upward_tetrahedra_are_positive_on_any_pose():
    vertices, triangles = grid(9, jitter=0.3)
    surface, points, _, _ = _thickening(drape(vertices, 6.0), triangles)
    upward = surface.thickening_tetrahedra[: len(surface.centered_triangles)]
    assert _volumes(points, upward).min() > 0
