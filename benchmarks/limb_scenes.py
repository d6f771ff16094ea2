"""Procedural articulated scenes for the transfer benchmark (issue 21): a closed, smooth limb
(a capsule: a cylinder with hemispherical caps) bent at two joints and twisted over an animation,
meshed twice independently — like a re-meshed scan sequence of a body.

- base: a structured ring mesh (rings of equal arc-length spacing along the profile, a fan at
  each pole), as a modelled mesh would be;
- target: the convex hull of jittered samples of the same rest surface (an irregular,
  Delaunay-like triangulation of the capsule, which is convex at rest);
- both are posed by the same deformation of their rest positions, so the base's own frames are the
  ground truth of a rebuild, and the target's frames are the "other mesh" animation.
"""

from __future__ import annotations

import numpy as np

from core.delaunay_flips import delaunay_flips

#: Capsule: cylinder length and radius (the limb is 2 long, 0.2 thick: a finger or an arm).
LENGTH = 2.0
RADIUS = 0.2
#: Joints along the axis (z), the half-width of the bend around each (in radii), and the bend
#: (about x) and twist (about the axis) reached at the last frame for each joint.
JOINTS = (-LENGTH / 6, LENGTH / 6)
BLEND = 2.0
BENDS_DEGREES = (70.0, 80.0)
TWISTS_DEGREES = (20.0, 30.0)


def _profile(s: np.ndarray):
    """Radius and height of the capsule's profile at arc length ``s`` from the bottom pole."""
    quarter = 0.5 * np.pi * RADIUS
    r = np.empty_like(s)
    z = np.empty_like(s)
    low = s < quarter
    high = s > quarter + LENGTH
    mid = ~low & ~high
    a = s[low] / RADIUS
    r[low], z[low] = RADIUS * np.sin(a), -0.5 * LENGTH - RADIUS * np.cos(a)
    r[mid], z[mid] = RADIUS, s[mid] - quarter - 0.5 * LENGTH
    a = (s[high] - quarter - LENGTH) / RADIUS
    r[high], z[high] = RADIUS * np.cos(a), 0.5 * LENGTH + RADIUS * np.sin(a)
    return r, z


def _total_arc() -> float:
    return np.pi * RADIUS + LENGTH


def ring_capsule(n_vertices: int):
    """A structured capsule of about ``n_vertices`` vertices: (vertices (n, 3), triangles (m, 3)),
    outward oriented."""
    spacing = np.sqrt(2 * np.pi * RADIUS * _total_arc() / n_vertices)
    around = max(8, int(round(2 * np.pi * RADIUS / spacing)))
    rings = max(3, int(round(_total_arc() / spacing)))
    s = np.linspace(0.0, _total_arc(), rings + 1)[1:-1]
    r, z = _profile(s)
    angle = 2 * np.pi * np.arange(around) / around
    ring_points = np.stack([r[:, None] * np.cos(angle), r[:, None] * np.sin(angle), np.broadcast_to(z[:, None], (s.size, around))],
                           axis=2).reshape(-1, 3)
    bottom, top = s.size * around, s.size * around + 1
    vertices = np.concatenate([ring_points, [[0, 0, -0.5 * LENGTH - RADIUS], [0, 0, 0.5 * LENGTH + RADIUS]]])
    j = np.arange(around)
    jn = (j + 1) % around
    tris = [np.stack([np.full(around, bottom), jn, j], axis=1)]
    for i in range(s.size - 1):
        a, b = i * around + j, i * around + jn
        c, d = (i + 1) * around + j, (i + 1) * around + jn
        tris += [np.stack([a, b, d], axis=1), np.stack([a, d, c], axis=1)]
    last = (s.size - 1) * around
    tris.append(np.stack([np.full(around, top), last + j, last + jn], axis=1))
    return vertices, _outward(vertices, np.concatenate(tris).astype(np.int64))


def sampled_capsule(n_vertices: int, seed: int):
    """An irregular capsule of about ``n_vertices`` vertices: a Poisson-disk sample of the
    surface (uniform random candidates by area, kept greedily in random order when no kept
    point is closer than the disk radius) triangulated by its convex hull."""
    from scipy.spatial import ConvexHull, cKDTree

    rng = np.random.default_rng(seed)
    area = 4 * np.pi * RADIUS**2 + 2 * np.pi * RADIUS * LENGTH
    radius = 0.8 * np.sqrt(area / n_vertices)  # about n_vertices kept (measured)
    candidates = []
    while sum(len(c) for c in candidates) < 30 * n_vertices:
        s = rng.uniform(0.0, _total_arc(), 10 * n_vertices)
        r, z = _profile(s)
        keep = rng.uniform(0.0, RADIUS, s.size) < r  # density ∝ circumference: uniform by area
        theta = rng.uniform(0.0, 2 * np.pi, int(keep.sum()))
        candidates.append(np.stack([r[keep] * np.cos(theta), r[keep] * np.sin(theta), z[keep]], axis=1))
    points = np.concatenate(candidates)
    neighbours = cKDTree(points).query_ball_point(points, radius)
    free = np.ones(len(points), dtype=bool)
    kept = []
    for i in range(len(points)):
        if free[i]:
            kept.append(i)
            free[neighbours[i]] = False
    vertices = points[kept]
    hull = ConvexHull(vertices)
    # The hull joins points on a cylinder along its straight generators in slivers; flipped to
    # Delaunay on the surface, as a remesher's would be.
    return vertices, delaunay_flips(vertices, _outward(vertices, hull.simplices.astype(np.int64)))


def _outward(vertices, triangles):
    corners = vertices[triangles]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    # The capsule is convex around its axis: outward means away from the axis point nearest the
    # triangle.
    center = corners.mean(axis=1)
    axis_point = np.stack([np.zeros(len(center)), np.zeros(len(center)), np.clip(center[:, 2], -0.5 * LENGTH, 0.5 * LENGTH)], 1)
    inward = np.einsum("ij,ij->i", normals, center - axis_point) < 0
    triangles = triangles.copy()
    triangles[inward] = triangles[inward][:, ::-1]
    return triangles


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _smoothstep(t):
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3 - 2 * t)


def pose(rest: np.ndarray, phase: float) -> np.ndarray:
    """The rest positions ``(n, 3)`` posed at ``phase`` in [0, 1] (0: rest). The axis bends (about
    x) and twists at each joint gradually over :data:`BLEND` radii on either side, and every
    cross-section follows it rigidly: a point ``(x, y, z)`` goes to ``C(z) + F(z) (x, y, 0)``
    with ``F(z) = R_x(Θ(z)) R_z(Ψ(z))`` (Θ, Ψ the bend and twist accumulated up to height z) and
    the axis ``C' = F e_z`` — unstretched along the axis, compressed on the inside of a bend and
    stretched outside by the radius × the curvature, as skin over a joint. Then the whole limb
    turns by ``phase`` × 40° about a tilted axis and moves, so a rigid alignment is part of the task."""
    z_grid = np.linspace(rest[:, 2].min(), rest[:, 2].max(), 4001)
    bend = np.zeros_like(z_grid)
    twist = np.zeros_like(z_grid)
    for joint, b, t in zip(JOINTS, BENDS_DEGREES, TWISTS_DEGREES):
        w = _smoothstep((z_grid - joint) / (2 * BLEND * RADIUS) + 0.5)
        bend += np.radians(b * phase) * w
        twist += np.radians(t * phase) * w
    direction = np.stack([np.zeros_like(bend), -np.sin(bend), np.cos(bend)], axis=1)  # R_x(Θ) e_z
    steps = 0.5 * (direction[1:] + direction[:-1]) * np.diff(z_grid)[:, None]
    axis = np.concatenate([[np.zeros(3)], np.cumsum(steps, axis=0)])
    axis -= np.array([np.interp(0.0, z_grid, axis[:, k]) for k in range(3)])  # the middle stays
    z = rest[:, 2]
    theta, psi = np.interp(z, z_grid, bend), np.interp(z, z_grid, twist)
    center = np.stack([np.interp(z, z_grid, axis[:, k]) for k in range(3)], axis=1)
    u = rest[:, 0] * np.cos(psi) - rest[:, 1] * np.sin(psi)  # R_z(Ψ) (x, y)
    v = rest[:, 0] * np.sin(psi) + rest[:, 1] * np.cos(psi)
    x = center + np.stack([u, v * np.cos(theta), v * np.sin(theta)], axis=1)  # then R_x(Θ)
    turn = _rotation(np.array([0.3, 1.0, 0.2]), np.radians(40.0 * phase))
    return x @ turn.T + phase * np.array([0.5, -0.2, 0.3])


def limb_scene(n_base: int, target_ratio: float = 1.3, frames: int = 41, seed: int = 1):
    """(base frames (F, n, 3), base triangles, target frames (F, n', 3), target triangles): the
    ring-meshed limb and an independently sampled one of ``target_ratio`` × as many vertices,
    animated over ``frames`` frames from rest to the full bends."""
    base_rest, base_tris = ring_capsule(n_base)
    target_rest, target_tris = sampled_capsule(int(round(target_ratio * n_base)), seed)
    phases = np.linspace(0.0, 1.0, frames)
    base_frames = np.stack([pose(base_rest, p) for p in phases])
    target_frames = np.stack([pose(target_rest, p) for p in phases])
    return base_frames, base_tris, target_frames, target_tris
