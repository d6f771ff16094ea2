"""Functional maps from point-to-point correspondences (core.functional_map, paper §6.3)."""

import numpy as np
import pytest
from meshes import drape, grid

from core.errors import MeshError
from core.functional_map import (OUTLIER_EDGES, check_correspondence, closest_point_correspondence,
                                 closest_points_on_triangles, functional_map, locally_affine_images, project_near,
                                 push_forward_matrix, reject_outlying_matches)
from core.mesh_topology import mesh_topology
from core.reference_shape import ReferenceShape
from core.shape_difference import functional_map as same_mesh_functional_map


def test_closest_points_on_triangles_match_dense_sampling():
    rng = np.random.default_rng(0)
    corners = rng.normal(size=(200, 3, 3))
    points = rng.normal(size=(200, 3)) * 1.5
    weights, squared = closest_points_on_triangles(points, corners)
    assert np.all(weights >= -1e-12) and np.allclose(weights.sum(axis=1), 1.0)
    # Independent check: no point of a fine barycentric grid of the triangle is closer.
    s, t = np.meshgrid(np.linspace(0, 1, 61), np.linspace(0, 1, 61))
    keep = s + t <= 1
    grid_w = np.stack([1 - s[keep] - t[keep], s[keep], t[keep]], axis=1)  # (G, 3)
    samples = np.einsum("gk,nki->ngi", grid_w, corners)
    sampled = np.min(np.sum((samples - points[:, None]) ** 2, axis=2), axis=1)
    assert np.all(squared <= sampled + 1e-12)
    assert np.all(squared >= sampled - 0.02 * np.sqrt(sampled) * np.max(np.ptp(corners, axis=1), axis=1) - 1e-12)


def test_closest_points_on_triangles_of_no_area_are_on_their_sides():
    """A triangle of no area (two corners equal: a segment; all three: a point) gives the nearest
    point of the segment, not its first corner (its plane is undefined)."""
    corners = np.array([[[0.0, 0, 0], [2, 0, 0], [2, 0, 0]], [[0.0, 0, 0], [0, 0, 0], [0, 2, 0]],
                        [[1.0, 1, 1], [1, 1, 1], [1, 1, 1]]])
    points = np.array([[1.5, 1.0, 0.0], [0.5, 1.0, 0.0], [1.0, 1.0, 3.0]])
    weights, squared = closest_points_on_triangles(points, corners)
    np.testing.assert_allclose(np.einsum("nk,nki->ni", weights, corners), [[1.5, 0, 0], [0, 1, 0], [1, 1, 1]], atol=1e-15)
    np.testing.assert_allclose(squared, [1.0, 0.25, 4.0], atol=1e-15)


def test_identity_map_is_the_same_mesh_functional_map():
    v, t = grid(12, jitter=0.3)
    target = drape(v, 1.5)
    ref = ReferenceShape(v, t, use_extrinsic=False)
    target_ref = ReferenceShape(target, t, use_extrinsic=False)
    base_basis, target_basis = ref.base.basis(15), target_ref.base.basis(30)
    push = push_forward_matrix(v, v, t)  # every vertex its own preimage
    assert np.allclose(push.toarray(), np.eye(len(v)))
    fmap = functional_map(target_basis.functions, target_ref.base.mass, push @ base_basis.functions)
    assert np.allclose(fmap, same_mesh_functional_map(base_basis, target_basis, target_ref.base.mass), atol=1e-12)


def test_push_forward_interpolates_linear_functions_exactly():
    base, base_tris = grid(9, jitter=0.3)
    target, _ = grid(13, jitter=0.3, seed=5, alternate=False)
    push = push_forward_matrix(target, base, base_tris)
    linear = base @ np.array([0.3, -1.2, 0.0]) + 0.7
    assert np.allclose(push @ linear, target @ np.array([0.3, -1.2, 0.0]) + 0.7, atol=1e-12)
    assert np.allclose(push.sum(axis=1), 1.0)


def test_push_forward_keeps_a_preimage_on_an_inner_edge_of_a_curved_image():
    # A ridge: two triangles meeting along the x axis, sloping down on both sides. A point above the
    # ridge has its closest point on the shared edge, whichever triangle reports it; extrapolated in
    # one triangle's plane instead, its preimage (and Q) jumped with the rounding that picked it.
    ridge = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, -0.5], [0.5, -1.0, -0.5]])
    triangles = np.array([[0, 1, 2], [1, 0, 3]])
    for side in (-1e-9, 0.0, 1e-9):
        row = push_forward_matrix(np.array([[0.5, side, 0.1]]), ridge, triangles).toarray()[0]
        assert np.allclose(row, [0.5, 0.5, 0.0, 0.0], rtol=0, atol=1e-8), (side, row)
    # Past a boundary edge (0–2 lies on the boundary), in the triangle's plane: still extrapolated,
    # exact for a function linear on that plane.
    corner = np.array([[-0.05, 0.2, -0.1]])  # beyond edge 0–2 of triangle 0, in its plane z = -y / 2
    row = push_forward_matrix(corner, ridge, triangles).toarray()[0]
    assert row.min() < 0.0
    assert np.allclose(row @ ridge, corner[0], atol=1e-12)


def test_push_forward_reads_the_boundary_of_a_given_topology_as_of_its_own():
    """Given the base's topology (as the Transfer has it), the push-forward is the one it builds
    from the triangles, bit for bit, where target points lie past the base's boundary (extrapolated
    there) and inside; and it is a map of linear functions, exact past the boundary too."""
    base, base_tris = grid(9, jitter=0.3)
    target, _ = grid(13, jitter=0.3, seed=5, alternate=False)
    target = 1.02 * target - 0.01  # a rim of target vertices just past the base's boundary
    own = push_forward_matrix(target, base, base_tris)
    given = push_forward_matrix(target, base, base_tris, topology=mesh_topology(base_tris, len(base)))
    assert (own != given).nnz == 0 and (own.toarray() < 0.0).any()  # some rows extrapolated
    linear = base @ np.array([0.3, -1.2, 0.0]) + 0.7
    assert np.allclose(given @ linear, target @ np.array([0.3, -1.2, 0.0]) + 0.7, atol=1e-12)


def test_locally_affine_images_keep_affine_maps_and_reduce_snapping():
    v, t = grid(15, jitter=0.3)
    edges = mesh_topology(t, len(v)).edges
    affine = np.array([[1.1, 0.2, 0.0], [-0.1, 0.9, 0.0], [0.3, 0.1, 1.0]])
    images = v @ affine.T + [0.5, -0.2, 1.0]
    assert np.allclose(locally_affine_images(v, edges, images), images, atol=1e-9)
    # A vertex map to a coarser mesh snaps each image by up to half an edge; the fit averages it out.
    target, target_tris = grid(11, jitter=0.3, seed=2, alternate=False)
    snapped = target[closest_point_correspondence(v, target)]
    smoothed = locally_affine_images(v, edges, snapped)
    error = lambda x: np.sqrt(np.mean(np.sum((x - v) ** 2, axis=1)))  # noqa: E731
    assert error(smoothed) < 0.6 * error(snapped)
    seeds = closest_point_correspondence(v, target)
    triangles, weights = project_near(smoothed, seeds, target, target_tris)
    on_surface = np.einsum("nk,nki->ni", weights, target[target_tris[triangles]])
    assert np.allclose(on_surface[:, 2], 0.0) and error(on_surface) <= error(smoothed) + 1e-12


def test_outlying_matches_are_found_and_the_affine_map_recovered_without_them():
    """An affine map of a sheet (a stretch and a turn) with 5 of its matches moved 6–26 target
    edges away: the 5, and no other, are left out — the one on the boundary, 26 edges off, pulls
    the fits of its neighbours past the bound, and they come back once it is out — and every
    vertex's image, theirs included, is the affine map's exactly (the fit is exact for affine
    maps, to round-off)."""
    from meshes import random_rotation

    v, t = grid(14, jitter=0.3)
    edges = mesh_topology(t, len(v)).edges
    images = v @ (random_rotation(3) @ np.diag([1.3, 0.8, 1.0])).T + [0.2, -0.1, 0.5]
    spacing = 1.0 / 13  # the edge length of the images, about
    stray = np.array([1, 20, 21, 100, 150])  # 20 and 21 neighbours, 1 on the boundary
    moved = images.copy()
    moved[stray] += [[0.0, 0.0, 2.0], [0.6, 0.0, 0.0], [0.0, 0.6, 0.0], [0.0, 0.0, 0.7], [0.5, 0.5, 0.0]]
    first = np.linalg.norm(locally_affine_images(v, edges, moved) - moved, axis=1) > OUTLIER_EDGES * spacing
    assert set(np.flatnonzero(first)) > set(stray)  # the case in point: good neighbours pulled past the bound
    points, kept = reject_outlying_matches(v, edges, moved, np.ones(len(v), bool), spacing)
    assert np.array_equal(np.flatnonzero(~kept), stray)
    assert np.abs(points - images).max() < 1e-9
    # a clean map keeps every match and gives locally_affine_images' result, bit for bit
    points, kept = reject_outlying_matches(v, edges, images, np.ones(len(v), bool), spacing)
    assert kept.all() and np.array_equal(points, locally_affine_images(v, edges, images))


def test_correspondence_is_checked():
    with pytest.raises(MeshError, match="shape"):
        check_correspondence(np.zeros(3, dtype=int), 4, 10)
    with pytest.raises(MeshError, match="base vertex 2 to target vertex 10"):
        check_correspondence([0, 1, 10, 3], 4, 10)
    with pytest.raises(MeshError, match="integer"):
        check_correspondence([0.5, 1, 2, 3], 4, 10)
    assert check_correspondence([0.0, 1.0, 9.0, 3.0], 4, 10).dtype == np.int64


def test_non_manifold_edges_are_named_for_a_base_and_allowed_for_a_target():
    v, t = grid(4)
    a, b = mesh_topology(t, 16).edges[mesh_topology(t, 16).interior_edges[0]]
    fin = np.vstack([t, [[a, b, 16]]])  # a third triangle on an interior edge
    with pytest.raises(MeshError, match=rf"shared by more than two triangles: \({a}, {b}\).*Non Manifold"):
        mesh_topology(fin, 17)
    topology = mesh_topology(fin, 17, allow_non_manifold=True)
    edge = np.flatnonzero((topology.edges == [a, b]).all(axis=1))[0]
    assert (topology.edge_triangles[edge] == -1).all()
    manifold = mesh_topology(t, 16)
    assert topology.interior_edges.size == manifold.interior_edges.size - 1
