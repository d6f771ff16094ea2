"""The nearest few of a set of points to each of some query points, equally near ones taken by index.

A k-d tree returns, among points exactly as near as the k-th nearest, whichever its traversal met
first: which ones depends on how the tree was built (its leaf size, whether its cells are shrunk to
their points), and on regular grids lying over one another (a cloth's two sheets, vertices exactly
above each other) ties are everywhere. :func:`nearest_points` returns the k nearest ordered by
(distance, index), the lower index first among equal distances (to the last bit), so that any tree
over the same points gives the same neighbours; :func:`point_tree` builds the tree the callers
use (the seat searches of :mod:`core.inbetween_motion` and :mod:`core.inbetween_carried`).
"""

from __future__ import annotations

import numpy as np

#: Points per leaf of :func:`point_tree`, whose cells are not shrunk to their points
#: (``compact_nodes=False``). Queries far from the points gain most: the seat searches from one of
#: the benchmark's two sheets to the other lying apart over it (5,184 vertices each, nearest 0.5–0.7
#: away, edges 0.038) take 35–38 and 24–25 ms, with SciPy's default tree (16 per leaf, shrunk
#: cells) 102–107 and 50–54 ms; queries near the points cost a little more (10,000 cloth vertices
#: against 2,000 vertices of sequins 0.005 above it: 9.3 ms, the default tree 8.6 ms, 64 per leaf
#: 11.7 ms).
TREE_LEAF_SIZE = 32


def point_tree(points: np.ndarray):
    """A k-d tree (``scipy.spatial.cKDTree``) over ``points`` (n, 3) for :func:`nearest_points`."""
    from scipy.spatial import cKDTree  # noqa: PLC0415

    return cKDTree(points, leafsize=TREE_LEAF_SIZE, compact_nodes=False)


def nearest_points(tree, queries: np.ndarray, k: int, upper_bound: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
    """Per query point (``queries`` (q, 3)), its ``k`` nearest points of ``tree`` (a
    ``scipy.spatial.cKDTree`` over n points, built in any way) nearer than ``upper_bound``:
    distances (q, k) and indices (q, k), ordered by (distance, index); missing neighbours have
    distance ``inf`` and index n, as ``cKDTree.query`` gives them. Each row is asked for one more
    neighbour than wanted: where that one is farther than the k-th, every point as near as the
    k-th is among those returned; where it is as near, the row is asked again for twice as many
    until one is farther (or every point is returned)."""
    count = tree.n
    queries = np.asarray(queries, dtype=np.float64).reshape(-1, 3)
    found = tree.query(queries, k=k + 1, distance_upper_bound=upper_bound)
    near, which = found[0].reshape(len(queries), k + 1), found[1].reshape(len(queries), k + 1)
    distance, index = near[:, :k].copy(), which[:, :k].copy()
    # only rows with equal distances among those returned need ordering by index (a tree returns
    # them by distance): those are rare off regular grids
    equal = (near[:, 1:] == near[:, :-1]) & np.isfinite(near[:, 1:])
    rows = np.flatnonzero(equal.any(axis=1))
    near, which, want = near[rows], which[rows], k + 1
    while rows.size:
        order = np.lexsort((which, near), axis=-1)[:, :k]
        distance[rows], index[rows] = np.take_along_axis(near, order, 1), np.take_along_axis(which, order, 1)
        # the last one returned as near as the k-th: more may be as near
        tied = np.isfinite(near[:, -1]) & (near[:, -1] == near[:, k - 1])
        if want >= count or not tied.any():
            break
        rows, want = rows[tied], min(2 * want, count)
        found = tree.query(queries[rows], k=want, distance_upper_bound=upper_bound)
        near, which = found[0].reshape(rows.size, want), found[1].reshape(rows.size, want)
    return distance, index
