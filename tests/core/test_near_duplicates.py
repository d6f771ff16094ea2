"""Near-duplicate vertices (core.near_duplicates): vertices joined by edges far under what the fits
resolve in every key are solved as one place and placed back by the keys' offsets, in sequences,
two poses, exaggerations; the in-betweens of the other vertices are those of the mesh without them.
No bpy."""

from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import numpy as np
import pytest

from core.inbetween_fit import NEAR_DUPLICATE_SHARE
from core.mesh_topology import mesh_topology
from core.near_duplicates import near_duplicates
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator
from inbetween_helpers import _bend, _normals, _strip
from placement_helpers import _rigid
from meshes import random_rotation

#: how far apart the split vertices are, in mean edges (a remesh's near-duplicates: 1.4e-5)
SPLIT = 1e-5


def _split(flat, triangles, vertices):
    """``triangles`` with each interior vertex of ``vertices`` split in two (a vertex split): the
    triangles of one half of its fan take a new vertex (appended, in the order given) placed
    ``SPLIT`` mean edges from it toward that half, and two slivers join the pair. Returns the
    vertices (n + p, 3), the triangles and the slivers' rows."""
    triangles, points, slivers = triangles.copy(), [flat], []
    mean = np.mean(np.linalg.norm(flat[triangles[:, 1]] - flat[triangles[:, 0]], axis=1))
    for v in vertices:
        fan = {}
        for t in np.flatnonzero((triangles == v).any(axis=1)):
            corners = list(triangles[t])
            at = corners.index(v)
            fan[corners[(at + 1) % 3]] = (t, corners[(at + 2) % 3])  # first neighbour → (triangle, next)
        first = next(iter(fan))
        ring, order = [first], []
        while len(order) < len(fan):
            t, after = fan[ring[-1]]
            order.append(t)
            ring.append(after)
        half = len(order) // 2
        copy = len(flat) + len(points) - 1
        moved = order[half:]
        side = np.unique(triangles[moved][triangles[moved] != v])
        for t in moved:
            triangles[t][triangles[t] == v] = copy
        direction = flat[side].mean(axis=0) - flat[v]
        points.append(flat[v] + SPLIT * mean * direction / np.linalg.norm(direction))
        slivers += [[v, ring[half], copy], [copy, ring[0], v]]
    m = len(triangles)
    return np.vstack(points), np.vstack([triangles, slivers]), np.arange(m, m + len(slivers))


def _sheet():
    """A strip (30 × 6) and the same with three interior vertices split into near-duplicate pairs."""
    flat, triangles = _strip()
    split, split_triangles, slivers = _split(flat, triangles, [2 * 30 + 7, 3 * 30 + 15, 2 * 30 + 22])
    return flat, triangles, split, split_triangles, slivers


def _keys(flat, angles, stretch=0.03):
    """The strip bent by ``angles`` (radians) and stretched along it by ``stretch`` × each angle."""
    return [_bend(flat * np.array([1.0 + stretch * a, 1.0, 1.0]), a) for a in angles]


def test_a_sequence_solves_near_duplicates_as_one_place():
    """A bending strip whose three vertices are split into pairs 1e-5 mean edges apart: its
    in-betweens of the other vertices are the strip's without them to round-off, each copy stays
    within its offset of its vertex, and the slivers face as the motion has them."""
    flat, triangles, split, split_triangles, slivers = _sheet()
    angles = [0.0, 0.8, 1.8, 2.6]
    clean = SequenceInterpolator(_keys(flat, angles), triangles)
    seq = SequenceInterpolator(_keys(split, angles), split_triangles)
    n, factors = len(flat), [0.25, 0.5, 0.75]
    offset = SPLIT * np.mean(np.linalg.norm(flat[triangles[:, 1]] - flat[triangles[:, 0]], axis=1))
    for gap in range(3):
        ours, theirs = seq.poses(gap, factors), clean.poses(gap, factors)
        np.testing.assert_allclose(ours[:, :n], theirs, rtol=0, atol=1e-12)
        apart = np.linalg.norm(ours[:, n:] - ours[:, [2 * 30 + 7, 3 * 30 + 15, 2 * 30 + 22]], axis=2)
        assert apart.max() < 1.1 * offset * (1.0 + 0.03 * max(angles))
        for s, x in zip(factors, ours):  # the motion at that factor, near-duplicates included
            truth = _keys(split, [(1 - s) * angles[gap] + s * angles[gap + 1]])[0]
            facing = np.einsum("ij,ij->i", _normals(x, split_triangles[slivers]),
                               _normals(truth, split_triangles[slivers]))
            assert (facing > 0).all()


@pytest.mark.parametrize("factor", [0.5, 1.5, -0.5])
def test_two_poses_solve_near_duplicates_as_one_place(factor):
    """Two poses (and their exaggeration and reversal) of the split strip: the other vertices as
    the strip's without the copies to round-off, the copies within their offsets."""
    flat, triangles, split, split_triangles, _ = _sheet()
    a, b = _keys(flat, [0.3, 1.9])
    a2, b2 = _keys(split, [0.3, 1.9])
    ours = Interpolator(a2, b2, split_triangles).pose(factor)
    np.testing.assert_allclose(ours[:len(flat)], Interpolator(a, b, triangles).pose(factor), rtol=0, atol=1e-12)
    offset = SPLIT * np.mean(np.linalg.norm(flat[triangles[:, 1]] - flat[triangles[:, 0]], axis=1))
    assert np.linalg.norm(ours[len(flat):] - ours[[2 * 30 + 7, 3 * 30 + 15, 2 * 30 + 22]], axis=1).max() < 1.5 * offset


def test_near_duplicates_follow_a_rigid_motion_exactly():
    """A rigid motion of the split strip (an in-between and an exaggeration): every vertex, the
    copies included, where one rigid motion of the whole puts it, to 1e-9 of the strip's size."""
    _, _, split, split_triangles, _ = _sheet()
    rest = _keys(split, [1.2])[0]
    rotation = random_rotation(3)
    moved = _rigid(rest, rotation, np.array([0.4, -0.2, 0.3]), (0.5, 0.1, -0.2))
    it = Interpolator(rest, moved, split_triangles)
    for factor in (0.5, 2.0):
        x = it.pose(factor)
        # the pose is rigid: every vertex where the best rigid motion of the whole puts it
        u, _, vt = np.linalg.svd((rest - rest.mean(0)).T @ (x - x.mean(0)))
        turn = (u @ vt).T
        assert np.linalg.det(turn) > 0
        fitted = (rest - rest.mean(0)) @ turn.T + x.mean(0)
        assert np.abs(x - fitted).max() < 1e-9


def test_a_remeshed_body_keyed_every_four_frames_as_if_merged_by_distance():
    """The remeshed body (four near-duplicate vertices at its head) bending its elbow 100° and
    nodding 40° and back over 32 frames, keyed every 4: nearer the rig's frames than a per-vertex
    Catmull–Rom of the keys by medians (the mesh merged by distance: 0.899 ×), and none of its
    triangles, the tiny ones included, turned over against the rig."""
    spec = importlib.util.spec_from_file_location("body", Path(__file__).parent / "test_placement_remeshed_body.py")
    body_module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(body_module)
    body, triangles = body_module._body()
    u = np.arange(33) / 32
    frames = [body_module._posed(body, 100 * (3 * t * t - 2 * t ** 3), 40 * np.sin(np.pi * t)) for t in u]
    keys = frames[::4]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # exact handling: nothing to say
        seq = SequenceInterpolator(keys, triangles)
        ours, spline, against = [], [], 0
        for gap in range(len(keys) - 1):
            p = [keys[max(gap - 1, 0)], keys[gap], keys[gap + 1], keys[min(gap + 2, len(keys) - 1)]]
            for s, x in zip((0.25, 0.5, 0.75), seq.poses(gap, [0.25, 0.5, 0.75])):
                truth = frames[4 * gap + round(4 * s)]
                catmull_rom = 0.5 * (2 * p[1] + (p[2] - p[0]) * s + (2 * p[0] - 5 * p[1] + 4 * p[2] - p[3]) * s * s
                                     + (3 * p[1] - p[0] - 3 * p[2] + p[3]) * s ** 3)
                ours.append(np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))))
                spline.append(np.sqrt(np.mean(np.sum((catmull_rom - truth) ** 2, axis=1))))
                against += int((np.einsum("ij,ij->i", _normals(x, triangles), _normals(truth, triangles)) < 0).sum())
    assert np.median(ours) < np.median(spline)
    assert against == 0


def test_only_clusters_under_the_share_in_every_key_and_no_wider_are_one_place():
    """Which vertices are taken together: pairs nearer than NEAR_DUPLICATE_SHARE mean edges in
    every key; not where they are twice that apart in one key; none in a mesh without them."""
    flat, triangles, split, split_triangles, _ = _sheet()
    topology = mesh_topology(split_triangles, len(split))
    near = near_duplicates(_keys(split, [0.0, 1.0]), topology)
    assert near is not None and near.members.tolist() == [len(flat), len(flat) + 1, len(flat) + 2]
    np.testing.assert_array_equal(near.triangles, triangles)  # the slivers left out, the rest as the clean strip
    apart = _keys(split, [0.0, 1.0])
    mean = np.mean(np.linalg.norm(apart[1][topology.edges[:, 0]] - apart[1][topology.edges[:, 1]], axis=1))
    apart[1][len(flat):] += [0.0, 0.0, 2 * NEAR_DUPLICATE_SHARE * mean]
    assert near_duplicates(apart, topology) is None
    assert near_duplicates(_keys(flat, [0.0, 1.0]), mesh_topology(triangles, len(flat))) is None


def _half_bent(flat, angle):
    """The strip with x ≤ 0.5 still and the rest bent by ``angle`` (radians) about x = 0.5 (isometric)."""
    out = flat.copy()
    x = flat[:, 0] - 0.5
    bent = x > 0
    if angle:
        radius = 1.0 / angle
        out[bent, 0] = 0.5 + radius * np.sin(x[bent] / radius)
        out[bent, 2] = radius * (1.0 - np.cos(x[bent] / radius))
    return out


def test_still_near_duplicates_stay_exactly_where_they_sit():
    """The strip's first quarter still while the rest bends (a sequence and two poses, ×1.5 too): its
    split vertex next to the bend (half its neighbours move) and that vertex's copy exactly where
    the first key has them at every factor."""
    _, _, split, split_triangles, _ = _sheet()
    keys = [_half_bent(split, a) for a in (0.0, 0.9, 2.0)]
    copy, vertex = len(split) - 3, 2 * 30 + 7  # the split at x ≈ 0.48, still; x ≈ 0.55 bends
    poses = np.concatenate([SequenceInterpolator(keys, split_triangles).poses(gap, [0.3, 0.7]) for gap in (0, 1)]
                           + [Interpolator(keys[0], keys[2], split_triangles).pose(f)[None] for f in (0.5, 1.5)])
    for x in poses:
        np.testing.assert_array_equal(x[[vertex, copy]], split[[vertex, copy]])
