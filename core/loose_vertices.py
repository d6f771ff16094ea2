"""Loose vertices (in no triangle) that sit at the mesh: copies of a vertex of a triangle, which the
seam weld joins to it (:func:`loose_copies`, :func:`core.seam_welds.seam_weld`), and points near
the surface, attached to a triangle and carried in its frame (:func:`attached_loose`), rather than
by their piece's rigid motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import edge_lengths


def loose_copies(poses: list[np.ndarray], topology, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """The loose vertices of ``topology`` (in no triangle) that sit within ``tolerance`` of a
    vertex of a triangle in every one of ``poses`` (list of (n, 3)), and that vertex (int (p,)
    each): a duplicate Merge by Distance would remove, or a point an object is parented to. Carried
    by their piece's rigid motion, a loose copy of the hand of an arm bent 100° left the hand by
    18 % of the diagonal half-way and 114 % at ×2."""
    return _loose_near(poses, topology, topology.loose_vertices, tolerance)


def _loose_near(poses: list[np.ndarray], topology, loose: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Of the vertices ``loose`` (int (p,)), those within ``reach`` of their nearest vertex of a
    triangle of ``topology`` (nearest in the first of ``poses``) in every pose, and that vertex."""
    from scipy.spatial import cKDTree

    used = topology.used_vertices
    if not loose.size or not used.size:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    distance, nearest = cKDTree(poses[0][used]).query(poses[0][loose], distance_upper_bound=reach)
    found = np.isfinite(distance)
    loose, near = loose[found], used[nearest[found]]
    together = np.ones(loose.size, dtype=bool)
    for pose in poses[1:]:
        together &= np.linalg.norm(pose[loose] - pose[near], axis=1) <= reach
    return loose[together], near[together]


#: A loose vertex within this many mean edge lengths of a vertex of a triangle in every key is
#: attached to a triangle there (:func:`attached_loose`); one farther off (a helper vertex
#: beside the mesh) moves with its piece's rigid motion.
ATTACH_REACH = 2.0


@dataclass(frozen=True)
class AttachedLoose:
    """Loose vertices ``vertices`` (p,) attached to the triangle ``corners`` (p, 3) at their nearest
    vertex, and their coordinates ``local`` (K, p, 3) in that triangle's frame
    (:func:`triangle_frames`) in each of K keys."""

    vertices: np.ndarray
    corners: np.ndarray
    local: np.ndarray

    def placed(self, pose: np.ndarray, local: np.ndarray) -> np.ndarray:
        """The attached vertices' positions (p, 3) in ``pose`` (n, 3) at ``local`` coordinates (p, 3)."""
        origin, frame = triangle_frames(pose, self.corners)
        return origin + np.einsum("pij,pj->pi", frame, local)


def triangle_frames(pose: np.ndarray, corners: np.ndarray):
    """Per triangle ``corners`` (p, 3) of ``pose`` (n, 3): its first corner (p, 3) and an orthonormal
    frame (p, 3, 3) whose columns are its first edge's direction, the direction across it in the
    triangle's plane and its normal: a rigid motion of the triangle moves the frame with it."""
    a, b, c = (pose[corners[:, k]] for k in range(3))
    along = b - a
    along = along / np.linalg.norm(along, axis=1, keepdims=True)
    normal = np.cross(b - a, c - a)
    normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    return a, np.stack([along, np.cross(normal, along), normal], axis=2)


def attached_loose(poses: list[np.ndarray], topology, still: np.ndarray | None = None) -> AttachedLoose | None:
    """The loose vertices of ``topology`` within :data:`ATTACH_REACH` mean edge lengths of their
    nearest vertex of a triangle (in the first of ``poses``) in every pose, attached to a triangle
    of that vertex; None where there are none. ``still`` (bool (n,)): vertices held where they are
    (pins), left out. Carried by their piece's rigid motion, a point 0.1 % of the diagonal off the
    hand of an arm bent 100° left it by 18 % of the diagonal half-way."""
    loose = topology.loose_vertices
    if still is not None:
        loose = loose[~still[loose]]
    if not loose.size or not topology.used_vertices.size:
        return None
    first = poses[0]
    reach = ATTACH_REACH * float(np.mean(edge_lengths(first, topology.edges[:, 0], topology.edges[:, 1])))
    loose, near = _loose_near(poses, topology, loose, reach)
    if not loose.size:
        return None
    triangles = topology.triangles
    first_triangle = np.full(topology.n_vertices, len(triangles))  # of each vertex: the first it is in
    np.minimum.at(first_triangle, triangles.ravel(), np.repeat(np.arange(len(triangles)), 3))
    corners = triangles[first_triangle[near]]
    local = []
    for pose in poses:
        origin, frame = triangle_frames(pose, corners)
        local.append(np.einsum("pji,pj->pi", frame, pose[loose] - origin))
    return AttachedLoose(loose, corners, np.array(local))
