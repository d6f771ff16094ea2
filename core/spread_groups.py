"""Groups of points each known to within its own spread: the connected components of the graph
linking points ``a`` and ``b`` whose distance is at most ``spread[a] + spread[b]`` (pieces whose
rigid motions agree to what their fits are known to, :func:`core.inbetween_flight.flying_groups`),
found without listing the linked pairs (thousands of pieces moving as one link every pair of them:
30,000 pieces, 450 M pairs)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: Points whose balls are queried together (each ball holds at most all the points: memory at most
#: this many times theirs).
BATCH = 64
#: Ball radii a hair over the test's, so that the KD-tree's rounding drops no linked point.
_SLACK = 1.0 + 1e-12


def spread_groups(points: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """The group int32 (n,) of each of ``points`` (n, d) with ``spread`` (n,) (non-negative): the
    connected components of the graph linking ``a`` and ``b`` where
    ``‖points[a] − points[b]‖ ≤ spread[a] + spread[b]``, numbered in the order of each group's
    first point (as :func:`scipy.sparse.csgraph.connected_components` numbers them). Two points
    far apart are in one group when a chain of linked points joins them.

    Each group is grown from its first point by ball queries (radius the point's spread plus the
    largest) on a KD-tree of the points not yet reached, rebuilt once the queries have returned
    more reached points than it holds: memory linear in the number of points, and a group of many
    coincident points costs a few queries rather than every pair among them. A point whose
    nearest other (asked in batches of :data:`BATCH`) is beyond its spread plus the largest is a
    group of its own without a ball query."""
    points = np.asarray(points, dtype=float)
    spread = np.asarray(spread, dtype=float)
    n = len(points)
    group = np.full(n, -1, dtype=np.int32)
    if n == 0:
        return group
    largest = float(spread.max())
    live = np.arange(n)  # the points in the tree: all those not yet reached, and some reached
    tree = cKDTree(points)
    unreached = n
    # reached points the queries returned since the tree was built: once they outnumber its points
    # the tree is rebuilt without the reached ones (a group of a thousand coincident points among
    # thousands of others would otherwise return all its members to each of its members' queries)
    wasted = 0

    def linked(batch):
        """The points not yet reached linked to one of ``batch`` (b,), once or more."""
        nonlocal wasted
        hits = tree.query_ball_point(points[batch], (spread[batch] + largest) * _SLACK)
        sizes = np.fromiter(map(len, hits), dtype=np.intp, count=len(hits))
        near = live[np.concatenate(hits).astype(np.intp)] if sizes.sum() else np.zeros(0, dtype=np.intp)
        source = np.repeat(batch, sizes)
        keep = group[near] < 0
        wasted += len(near) - int(np.count_nonzero(keep))
        near, source = near[keep], source[keep]
        return near[np.linalg.norm(points[near] - points[source], axis=1) <= spread[source] + spread[near]]

    alone = np.zeros(n, dtype=bool)
    asked = 0  # the points before it have been asked whether they are alone
    label = 0
    for start in range(n):
        if group[start] >= 0:
            continue
        if start >= asked:  # the next BATCH points not yet reached whose nearest other is beyond any link
            batch = np.flatnonzero(group[start:] < 0)[:BATCH] + start
            if len(live) > 1:
                second = tree.query(points[batch], k=2, distance_upper_bound=2.0 * largest * _SLACK)[0][:, 1]
                alone[batch] = second > (spread[batch] + largest) * _SLACK
            asked = int(batch[-1]) + 1
        group[start] = label
        label += 1
        unreached -= 1
        stack = [] if alone[start] else [start]
        while stack and unreached:
            batch = np.array(stack[-BATCH:])
            del stack[-BATCH:]
            fresh = np.unique(linked(batch))
            group[fresh] = label - 1
            unreached -= len(fresh)
            stack.extend(fresh.tolist())
            if unreached and wasted > len(live):
                live = np.flatnonzero(group < 0)
                tree = cKDTree(points[live])
                wasted = 0
    return group
