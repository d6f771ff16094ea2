"""Shared geometry helpers (core/geometry.py) and per-component rigid placement."""

import warnings
import numpy as np
import pytest

from core.geometry import (
    column_means,
    connected_components,
    coordinate_cross,
    edge_lengths,
    expand_vertex_values,
    grouped_medians,
    heron,
    lumped_vertex_areas,
    nearest_rotations,
    normalize,
    rows_dot,
    vertex_labels,
)
from core.mesh_topology import triangle_areas
from core.reference_shape import ReferenceShape
from core.rigid_alignment import align_components, group_covariances, rigid_alignment, rigid_alignments
from meshes import grid, icosphere, random_rotation


def test_rows_dot_and_normalize():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    assert np.allclose(rows_dot(a, b), [x @ y for x, y in zip(a, b)], rtol=1e-14)
    stacked = rng.normal(size=(4, 5, 3))
    assert rows_dot(stacked, stacked).shape == (4, 5)
    unit, length = normalize(np.vstack([a, np.zeros(3)]))
    assert np.allclose(np.linalg.norm(unit[:-1], axis=1), 1.0) and np.allclose(length[:-1], np.linalg.norm(a, axis=1))
    assert np.array_equal(unit[-1], np.zeros(3)) and length[-1] == 0.0


def test_heron_is_sixteen_squared_areas():
    v, t = icosphere(1)
    v = v * np.array([1.0, 2.0, 0.5])
    squared = np.stack([np.sum((v[t[:, i]] - v[t[:, j]]) ** 2, axis=1) for i, j in ((1, 2), (2, 0), (0, 1))], axis=1)
    assert np.allclose(heron(squared), 16.0 * triangle_areas(v, t) ** 2, rtol=1e-10)
    assert heron(np.array([[1.0, 1.0, 4.0 + 1e-3]]))[0] < 0  # 1 + 1 < 2.0002: no triangle


def test_nearest_rotations_are_proper_and_nearest():
    rng = np.random.default_rng(1)
    rotations = np.stack([random_rotation(seed) for seed in range(6)])
    # A rotation times a positive symmetric stretch: the nearest rotation is the rotation itself.
    stretch = np.stack([np.diag(rng.uniform(0.5, 2.0, 3)) for _ in range(6)])
    assert np.allclose(nearest_rotations(rotations @ stretch), rotations, atol=1e-12)
    reflections = rotations * np.array([1.0, 1.0, -1.0])  # det −1: never returned
    found = nearest_rotations(reflections)
    assert np.allclose(np.linalg.det(found), 1.0)
    assert np.allclose(found @ np.swapaxes(found, 1, 2), np.eye(3), atol=1e-12)
    assert np.allclose(nearest_rotations(rotations[0] @ stretch[0]), rotations[0], atol=1e-12)  # one matrix


def test_components_and_vertex_labels():
    count, labels = connected_components(6, np.array([[0, 1], [1, 2], [4, 5]]))
    assert count == 3 and labels[0] == labels[1] == labels[2] and labels[4] == labels[5] != labels[0]
    assert labels[3] not in (labels[0], labels[4])  # isolated node
    triangles = np.array([[0, 1, 2], [3, 4, 5]])
    assert np.array_equal(vertex_labels(triangles, np.array([7, 9]), 7), [7, 7, 7, 9, 9, 9, -1])


def test_lumped_vertex_areas_are_the_mass_matrix_row_sums():
    v, t = icosphere(1)
    v = v * np.array([1.0, 2.0, 0.5])
    areas = triangle_areas(v, t)
    mass = ReferenceShape(v, t, use_extrinsic=False).base.mass  # the P1 mass matrix of eq. (1)
    lumped = lumped_vertex_areas(t, areas, len(v))
    assert np.allclose(lumped, np.asarray(mass.sum(axis=1)).ravel(), rtol=1e-13)
    assert np.isclose(lumped.sum(), areas.sum(), rtol=1e-13)
    # A vertex in no triangle (index 3) has no area.
    assert np.allclose(lumped_vertex_areas(np.array([[0, 1, 2]]), np.array([0.6]), 4), [0.2, 0.2, 0.2, 0.0])


def test_expand_vertex_values_fills_the_unused_vertices():
    used = np.array([0, 2, 3])
    assert np.array_equal(expand_vertex_values(used, np.array([1.0, 2.0, 3.0]), 5), [1.0, 0.0, 2.0, 3.0, 0.0])
    wide = expand_vertex_values(used, np.arange(6.0).reshape(3, 2), 4, fill=np.inf)
    assert wide.shape == (4, 2) and np.all(np.isinf(wide[1])) and np.array_equal(wide[3], [4.0, 5.0])


def test_align_components_moves_each_component_rigidly():
    v, _ = grid(5)
    points = np.vstack([v, v + 5.0])
    labels = np.repeat([0, 1], len(v))
    moved = points.copy()
    moved[labels == 0] = points[labels == 0] @ random_rotation(2).T + 1.0
    moved[labels == 1] = points[labels == 1] @ random_rotation(3).T - 2.0
    assert np.allclose(align_components(moved, points, labels), points, atol=1e-12)
    active = labels == 0
    out = align_components(moved, points, labels, active=active)
    assert np.allclose(out[active], points[active], atol=1e-12)
    assert np.array_equal(out[~active], moved[~active])  # inactive rows stay


@pytest.mark.parametrize("count", [1, 7, 100])  # one group, a partition each, one sort of all
def test_grouped_medians_are_each_groups_median(count):
    rng = np.random.default_rng(4)
    groups = np.r_[np.arange(count), rng.integers(0, count, 200 * count)]  # every group present, sizes odd and even
    values = rng.normal(size=groups.size) * 10.0 ** rng.integers(-8, 8, groups.size)
    expected = [np.median(values[groups == g]) for g in range(count)]
    assert np.array_equal(grouped_medians(values, groups, count), expected)


@pytest.mark.parametrize("count", [1, 7, 100])  # one group, a partition each, one sort of all
def test_grouped_medians_of_empty_groups_are_nan(count):
    """A group with no values has no median (NaN, as ``np.median`` of an empty array), and the
    other groups keep theirs, wherever the empty ones lie (first, inner, last)."""
    rng = np.random.default_rng(5)
    present = np.arange(count)[np.arange(count) % 3 == 1]  # groups 0, 2, 3, 5, … and the last left empty
    groups = rng.choice(present, 50 * count) if present.size else np.zeros(0, dtype=np.int64)
    values = rng.normal(size=groups.size)
    expected = [np.median(values[groups == g]) if g in present else np.nan for g in range(count)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # NaN without NumPy's warning about an empty mean
        out = grouped_medians(values, groups, count)
    assert np.array_equal(out, expected, equal_nan=True)


def test_rigid_alignments_of_many_groups_are_each_groups_alignment():
    """The batched alignment of 500 pieces (a mesh of debris) gives each piece's own Kabsch
    alignment, recovers exact rigid motions far from the origin, and the identity for a group
    without weight."""
    rng = np.random.default_rng(5)
    sizes = rng.integers(3, 9, 500)
    labels = np.repeat(np.arange(500), sizes)
    source = rng.normal(size=(labels.size, 3)) + 1e4 * rng.normal(size=(500, 3))[labels]
    rotations = np.array([random_rotation(k) for k in range(500)])
    shifts = rng.normal(size=(500, 3)) * 100.0
    target = np.einsum("rab,rb->ra", rotations[labels], source) + shifts[labels]
    weights = rng.uniform(0.5, 2.0, labels.size)
    found, moved = rigid_alignments(source, target, labels, 500, weights)
    assert np.abs(found - rotations).max() < 1e-9
    assert np.abs(np.einsum("rab,rb->ra", found[labels], source) + moved[labels] - target).max() < 1e-8
    noisy = target + 0.1 * rng.normal(size=target.shape)
    batched = rigid_alignments(source, noisy, labels, 500, weights)
    for g in (0, 17, 499):
        rows = labels == g
        rotation, translation = rigid_alignment(source[rows], noisy[rows], weights[rows])
        assert np.allclose(batched[0][g], rotation, atol=1e-12) and np.allclose(batched[1][g], translation, atol=1e-8)
    empty = rigid_alignments(source, target, labels, 501, weights)
    assert np.array_equal(empty[0][500], np.eye(3)) and np.array_equal(empty[1][500], np.zeros(3))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_coordinate_cross_is_numpys_cross_by_coordinate(dtype):
    """Cross products of vectors stored by coordinate are NumPy's, bit for bit, in the arrays'
    precision (the fits' checks compare them with thresholds)."""
    rng = np.random.default_rng(3)
    a, b = (rng.normal(size=(3, 2, 500)).astype(dtype) for _ in range(2))
    cross = coordinate_cross(a, b)
    assert cross.dtype == dtype
    np.testing.assert_array_equal(cross, np.moveaxis(np.cross(np.moveaxis(a, 0, -1), np.moveaxis(b, 0, -1)), -1, 0))


def test_coordinate_cross_of_single_vectors_and_one_against_many():
    """Single vectors ``(3,)`` and one vector against many ``(3, m)`` are NumPy's cross products
    by coordinate too (the ``…`` of ``(3, …)`` broadcast)."""
    rng = np.random.default_rng(4)
    u, v, many = rng.normal(size=3), rng.normal(size=3), rng.normal(size=(3, 7))
    np.testing.assert_array_equal(coordinate_cross(u, v), np.cross(u, v))
    np.testing.assert_array_equal(coordinate_cross(u, many), np.cross(u, many.T).T)
    np.testing.assert_array_equal(coordinate_cross(many, v), np.cross(many.T, v).T)


def test_column_means_are_numpys_means_to_the_bit():
    """The float32 local steps' edges are taken about these means: every in-between depends on
    them, so they must be NumPy's to the last bit, far from the origin too and on any layout."""
    rng = np.random.default_rng(7)
    for n in (1, 2, 7, 1000, 30_001):
        for offset in (0.0, 1e3, -3.7e5):
            points = rng.normal(size=(n, 3)) * rng.uniform(1e-3, 1e2) + offset
            assert np.array_equal(column_means(points), points.mean(axis=0))
            by_column = np.asfortranarray(points)  # NumPy sums these pairwise down each column
            assert np.array_equal(column_means(by_column), by_column.mean(axis=0))
            single = points.astype(np.float32)
            assert np.array_equal(column_means(single), single.mean(axis=0))
            rows = points[::2]  # a strided view
            assert np.array_equal(column_means(rows), rows.mean(axis=0))


def test_edge_lengths_are_numpys_norms_to_the_bit():
    """Riding sets and the coincidence tolerance compare these lengths with tolerances of a few
    float32 roundings: they must be those of ``np.linalg.norm`` to the last bit, on any layout and
    type, and agree with an independent Euclidean distance to round-off."""
    import math

    rng = np.random.default_rng(5)
    for n in (2, 9, 5000):
        for offset in (0.0, 1e3, -3.7e5):
            points = rng.normal(size=(n, 3)) * rng.uniform(1e-3, 1e2) + offset
            a, b = rng.integers(0, n, 3 * n), rng.integers(0, n, 3 * n)
            for pose in (points, np.asfortranarray(points), points.astype(np.float32), np.repeat(points, 2, axis=0)[::2]):
                lengths = edge_lengths(pose, a, b)
                assert lengths.dtype == pose.dtype
                assert np.array_equal(lengths, np.linalg.norm(pose[a] - pose[b], axis=1))
            for k in range(0, 3 * n, 97):
                assert lengths[k] == pytest.approx(math.dist(points[a[k]], points[b[k]]), rel=1e-15, abs=1e-15 * abs(offset))
    whole = np.arange(12).reshape(4, 3)  # integer positions are measured in double precision
    assert np.array_equal(edge_lengths(whole, [0, 1], [3, 3]), np.linalg.norm(whole[[0, 1]] - whole[[3, 3]], axis=1))
    assert edge_lengths(points, np.array([], dtype=int), np.array([], dtype=int)).shape == (0,)


def test_a_sets_covariance_with_itself_is_made_once_and_is_its_cross_covariance_with_a_copy():
    """principal_frames' covariance: its mean and rows about it made once and shared, each
    symmetric entry formed once, the values those of the general cross-covariance to the last bit
    (and of the weighted sum of outer products, to round-off)."""
    rng = np.random.default_rng(11)
    points = rng.normal(size=(600, 3)) @ np.diag([3.0, 1.0, 0.2]) + 50.0
    labels, weights = rng.integers(0, 3, 600), rng.uniform(0.1, 2.0, 600)
    covariance, s_mean, x_mean, s_centred, x_centred = group_covariances(points, points, labels, 3, weights)
    assert x_mean is s_mean and x_centred is s_centred
    expected = group_covariances(points, points.copy(), labels, 3, weights)
    assert np.array_equal(covariance, expected[0]) and np.array_equal(s_mean, expected[1])
    assert np.array_equal(covariance, np.swapaxes(covariance, 1, 2))
    for g in range(3):
        rows = labels == g
        mean = np.average(points[rows], axis=0, weights=weights[rows])
        centred = points[rows] - mean
        np.testing.assert_allclose(covariance[g], (centred.T * weights[rows]) @ centred, rtol=1e-12, atol=1e-9)


def test_coordinate_dot_is_the_dot_product_and_writes_into_out():
    """Vectors stored by coordinate (3, …): the dot products equal ``einsum``'s over the
    interleaved rows to rounding, in float32 and float64 and against a single vector (3,); with
    ``out`` the products land in that array (returned) and equal those without it to the bit."""
    from core.geometry import coordinate_dot

    rng = np.random.default_rng(3)
    for dtype in (np.float32, np.float64):
        a, b = rng.normal(size=(3, 2, 500)).astype(dtype), rng.normal(size=(3, 2, 500)).astype(dtype)
        expected = np.einsum("dij,dij->ij", a.astype(np.float64), b.astype(np.float64))
        plain = coordinate_dot(a, b)
        assert plain.dtype == dtype
        np.testing.assert_allclose(plain, expected, rtol=0, atol=10 * np.finfo(dtype).eps * np.abs(a * b).sum(0).max())
        out = np.full((2, 500), np.nan, dtype=dtype)
        assert coordinate_dot(a, b, out=out) is out
        assert np.array_equal(out, plain)
    single = np.array([0.5, -2.0, 3.0])
    np.testing.assert_allclose(coordinate_dot(single, b), np.einsum("d,dij->ij", single, b), rtol=1e-12, atol=1e-12)
