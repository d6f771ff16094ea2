"""The nearest few points, equally near ones taken by index (core/nearest_points.py), against a
brute-force search ordered by (distance, index), on trees built in every way."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from core.nearest_points import nearest_points, point_tree

#: k-d trees over the same points built in different ways: leaf sizes, shrunk cells or not, median
#: or sliding-midpoint splits
TREE_OPTIONS = [{}, {"compact_nodes": False}, {"leafsize": 1}, {"leafsize": 3, "compact_nodes": False},
                {"leafsize": 64, "balanced_tree": False}, {"leafsize": 7, "balanced_tree": False, "compact_nodes": False}]


def brute_force_nearest(points, queries, k, upper_bound=np.inf):
    """Every distance computed, the k smallest below ``upper_bound`` by (distance, index); missing
    ones ``inf`` and index n, as cKDTree.query gives them."""
    distance = np.sqrt(((queries[:, None, :] - points[None, :, :]) ** 2).sum(axis=2))
    distance[~(distance < upper_bound)] = np.inf
    index = np.broadcast_to(np.arange(len(points)), distance.shape)
    order = np.lexsort((index, distance), axis=-1)[:, :k]
    nearest, which = np.take_along_axis(distance, order, 1), np.take_along_axis(index, order, 1).copy()
    which[np.isinf(nearest)] = len(points)
    return nearest, which


def grids_over_each_other():
    """A 12 × 10 grid of spacing 0.25 and the same grid 0.5 above it (coordinates exact in binary:
    every squared distance is exact, so equally near points are equal to the last bit); the upper
    grid's vertices, shuffled, are the queries."""
    u, v = np.meshgrid(np.arange(12), np.arange(10))
    lower = np.stack([u.ravel(), v.ravel(), np.zeros(u.size)], axis=1) * 0.25
    upper = lower + [0.0, 0.0, 0.5]
    return lower, upper[np.random.default_rng(0).permutation(len(upper))]


@pytest.mark.parametrize("k", [1, 3, 5, 8])
@pytest.mark.parametrize("upper_bound", [np.inf, 0.6, 0.75])
def test_equally_near_points_are_taken_by_index_whatever_the_tree(k, upper_bound):
    """Vertices exactly above a grid: the one below at 0.5, four at √0.3125, four at √0.375, ...:
    ties at every k but 1. Whatever the tree, the neighbours are the brute-force search's by
    (distance, index), missing ones beyond ``upper_bound`` included (0.6 keeps one neighbour per
    vertex, 0.75 five)."""
    points, queries = grids_over_each_other()
    expected = brute_force_nearest(points, queries, k, upper_bound)
    for options in [*TREE_OPTIONS, None]:
        tree = point_tree(points) if options is None else cKDTree(points, **options)
        distance, index = nearest_points(tree, queries, k, upper_bound)
        np.testing.assert_array_equal(distance, expected[0], err_msg=str(options))
        np.testing.assert_array_equal(index, expected[1], err_msg=str(options))


def test_points_off_any_grid_are_the_trees_own_nearest():
    """Random points (no ties): the same neighbours and distances as the tree's own query, and as
    the brute-force search; fewer points than asked for leave the rest missing."""
    rng = np.random.default_rng(1)
    points, queries = rng.normal(size=(300, 3)), rng.normal(size=(200, 3))
    distance, index = nearest_points(point_tree(points), queries, 4, 1.0)
    own = cKDTree(points).query(queries, k=4, distance_upper_bound=1.0)
    np.testing.assert_array_equal(distance, own[0])
    np.testing.assert_array_equal(index, own[1])
    expected = brute_force_nearest(points, queries, 4, 1.0)
    np.testing.assert_array_equal(index, expected[1])
    np.testing.assert_allclose(distance, expected[0], rtol=1e-15)
    few = nearest_points(point_tree(points[:2]), queries, 4)
    assert np.isinf(few[0][:, 2:]).all() and (few[1][:, 2:] == 2).all()
    assert np.array_equal(few[1][:, :2], brute_force_nearest(points[:2], queries, 2)[1])
