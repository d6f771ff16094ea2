"""Where a joint's point lies against a rigid piece of a mesh: its distance from the piece's
surface, and whether the piece encloses it (:func:`core.inbetween_joints.joint_tree` asks whether a
joint read between a piece that turns and one that does not is a point of both)."""

from __future__ import annotations

import numpy as np

from .functional_map import closest_points_on_triangles


#: Point–triangle pairs measured at once by :func:`surface_points` and :func:`winding_numbers`
#: (their arrays are pairs × 3 large: 12 MB at this many).
PAIRS_AT_ONCE = 500_000


def _batch(triangles: int) -> int:
    """How many points are measured at once against ``triangles`` triangles (:data:`PAIRS_AT_ONCE`)."""
    return max(1, PAIRS_AT_ONCE // max(triangles, 1))


#: A point is in the gap between two pieces where the directions to its nearest points on them are
#: more than 120° apart (their cosine under this): across a gap between faces, or faces turned to
#: each other by less than 60° about a hinge in it (a carriage kept level on a link turned 47°, 0.04
#: from it, its axis in the gap's middle: 133°); a point off the corner where a face meets the side
#: of another (a tray's front face above a lid's top face, 0.015 and 0.025 from them) sees them 90° apart.
GAP_SIDES = -0.5


def _nearest_points(x: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per point–triangle pair, of the points ``x`` (N, 3) and the triangles ``corners`` (N, 3, 3): the
    triangle's nearest point (N, 3) and its distance (N,)
    (:func:`core.functional_map.closest_points_on_triangles`)."""
    weights, squared = closest_points_on_triangles(x, corners)
    return np.einsum("nk,nka->na", weights, corners), np.sqrt(squared)


def _candidate_pairs(points: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The point–triangle pairs (two int (N,): the points' rows of ``points`` (k, 3), the triangles'
    of ``corners`` (T, 3, 3)) that can hold a point's nearest point of the triangles: a triangle's
    corner bounds that distance from above, and a triangle within that bound of the point has its
    centroid within the bound plus the triangle's reach (its corners' farthest from its centroid)
    of it (KD-trees of the corners and of the centroids). Every point keeps the triangles of its
    nearest corner; a contact of k vertices costs about k pairs, not k × T."""
    from scipy.spatial import cKDTree

    centres = corners.mean(axis=1)
    reach = np.linalg.norm(corners - centres[:, None], axis=2).max(axis=1)  # (T,)
    bound = cKDTree(corners.reshape(-1, 3)).query(points)[0]  # (k,)
    slack = 1.0 + 1e-9  # the balls a little wider than their radii: the sums' rounding loses no pair
    pairs = cKDTree(points).sparse_distance_matrix(cKDTree(centres), (bound.max() + reach.max()) * slack,
                                                   output_type="ndarray")
    kept = pairs["v"] <= (bound[pairs["i"]] + reach[pairs["j"]]) * slack
    return pairs["i"][kept].astype(np.int64), pairs["j"][kept].astype(np.int64)


def surface_points(points: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per point of ``points`` (k, 3), the nearest point (k, 3) of the triangles ``corners`` (T, 3, 3)
    and its distance (k,) (:func:`_nearest_points`, over :func:`_candidate_pairs`; of equally near
    triangles, the first); inf (and nan) for no triangle."""
    out, feet = np.full(len(points), np.inf), np.full((len(points), 3), np.nan)
    if not len(corners) or not len(points):
        return feet, out
    rows, columns = _candidate_pairs(points, corners)
    nearest, distance = np.empty((rows.size, 3)), np.empty(rows.size)
    for start in range(0, rows.size, PAIRS_AT_ONCE):
        i, j = rows[start:start + PAIRS_AT_ONCE], columns[start:start + PAIRS_AT_ONCE]
        nearest[start:start + i.size], distance[start:start + i.size] = _nearest_points(points[i], corners[j])
    order = np.lexsort((columns, distance, rows))  # per point, the nearest first
    first = order[np.r_[True, rows[order[1:]] != rows[order[:-1]]]]
    out[rows[first]], feet[rows[first]] = distance[first], nearest[first]
    return feet, out


def winding_numbers(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Per point of ``points`` (k, 3), how many times the triangles ``corners`` (T, 3, 3) wind about it
    (k,): the sum of the solid angles they subtend from it (Van Oosterom and Strackee's formula)
    over 4π; ±1 inside a closed surface (its sign the triangles' orientation), 0 outside, between
    on an open one."""
    out = np.zeros(len(points))
    step = _batch(len(corners))
    for start in range(0, len(points), step):
        x = points[start:start + step, None, :]
        a, b, c = (corners[None, :, k] - x for k in range(3))  # (k, T, 3) each
        la, lb, lc = (np.linalg.norm(y, axis=2) for y in (a, b, c))
        numerator = np.einsum("kta,kta->kt", a, np.cross(b, c))
        denominator = (la * lb * lc + np.einsum("kta,kta->kt", a, b) * lc + np.einsum("kta,kta->kt", b, c) * la
                       + np.einsum("kta,kta->kt", c, a) * lb)
        out[start:start + step] = 2.0 * np.arctan2(numerator, denominator).sum(axis=1) / (4.0 * np.pi)
    return out


def joint_point(points: np.ndarray, pieces: tuple[np.ndarray, np.ndarray], tolerance: float, within: float) -> bool:
    """Whether one of ``points`` (k, 3) can be the point of a joint between two pieces (their
    triangles ``pieces``: two (T, 3, 3) arrays): a point of each, within ``tolerance`` of its
    surface or enclosed by it (a winding number of at least a half, :func:`winding_numbers`), as a
    hinge's point on the faces two touching pieces turn on, or inside both (a pin sunk into both);
    or a point of the gap between them, off both within ``within`` with its nearest points on the
    two (:func:`surface_points`) on opposite sides of it (:data:`GAP_SIDES`: a hinge's axis through
    the middle of the gap between two pieces that do not touch)."""
    feet, distances = zip(*(surface_points(points, corners) for corners in pieces))
    held = [d <= tolerance for d in distances]
    if (held[0] & held[1]).any():
        return True
    for inside, d, corners in zip(held, distances, pieces):  # enclosed: only where off the surface
        off = ~inside
        inside[off] = np.abs(winding_numbers(points[off], corners)) >= 0.5
    towards = [(f - points) / np.maximum(d, np.finfo(float).tiny)[:, None] for f, d in zip(feet, distances)]
    between = (~held[0] & ~held[1] & (np.maximum(*distances) <= within)
               & (np.einsum("ka,ka->k", *towards) < GAP_SIDES))
    return bool((held[0] & held[1] | between).any())
