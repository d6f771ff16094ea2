"""Nearest points of a piece's triangles (core.joint_points; issue 17 item 3), which
core.inbetween_joints.joint_tree measures a joint's point and the gap of a contact against. No bpy."""

from __future__ import annotations

import numpy as np

import core.joint_points as joint_points
from core.joint_points import surface_points

from meshes import grid


def _facing_grids(n: int, gap: float):
    """Two n × n grids (unit squares) facing each other ``gap`` apart: the lower's vertices (n², 3)
    and the upper's triangles (T, 3, 3)."""
    lower, triangles = grid(n)
    return lower, (lower + [0.0, 0.0, gap])[triangles]


def test_surface_points_are_points_of_the_triangles_nearer_than_any_other():
    """Each foot is a point of one of the triangles at its distance from the point, and no point of
    any triangle (their corners, edges' midpoints and centroids, and random points of them) is nearer."""
    rng = np.random.default_rng(5)
    for scale in (1e-3, 1.0, 1e3):
        corners = rng.normal(size=(40, 3, 3)) * scale
        corners[::7, 2] = corners[::7, 1]  # degenerate: segments
        points = np.r_[rng.normal(size=(30, 3)) * 2 * scale, corners[:4, 0]]
        feet, distances = surface_points(points, corners)
        np.testing.assert_allclose(np.linalg.norm(feet - points, axis=1), distances, rtol=1e-12, atol=1e-12 * scale)
        weights = np.r_[np.eye(3), np.full((1, 3), 1 / 3), [[0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5]],
                        rng.dirichlet(np.ones(3), 200)]
        samples = np.einsum("wk,tka->twa", weights, corners).reshape(-1, 3)
        least = np.linalg.norm(points[:, None] - samples[None], axis=2).min(axis=1)
        assert (distances <= least * (1 + 1e-12) + 1e-12 * scale).all()
        # each foot lies on a triangle: one triangle's nearest point to it is itself
        assert (surface_points(feet, corners)[1] <= 1e-9 * scale).all()


def test_surface_points_measure_only_the_triangles_near_each_point(monkeypatch):
    """A contact of two 40 × 40 grids 0.1 edges apart: each vertex is measured against the triangles
    whose centroids lie within its nearest corner's distance plus a triangle's reach of it (0.1 + 0.75
    edges: about π · 0.85² / 0.5 ≈ 4.5 triangles), not against all 3,042 of them, and gets the same
    nearest points (the gap under every vertex)."""
    n = 40
    edge = 1.0 / (n - 1)
    points, corners = _facing_grids(n, 0.1 * edge)
    measured = []
    kernel = getattr(joint_points, "_nearest_points", None)

    def counted(x, *abc):
        measured.append(x.shape[0])
        return kernel(x, *abc)

    monkeypatch.setattr(joint_points, "_nearest_points", counted, raising=False)
    distances = surface_points(points, corners)[1]
    assert 0 < sum(measured) <= 9 * len(points)
    np.testing.assert_allclose(distances, 0.1 * edge, rtol=1e-9)
