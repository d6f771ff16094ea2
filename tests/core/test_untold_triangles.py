"""Triangles whose shape neither key tells (slivers under the fits' floor in both keys,
core/untold_triangles.py): their target edges are their told neighbour's deformation, so a noisy or
exaggerated rigid motion of a mesh with a scan's slivers follows the motion to the noise (issue 17
item 3: rigid motions exact to 1e-6). No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import ShapeDifferenceWarning
from core.inbetween_keys import Key
from core.inbetween_topology import Topology
from core.mesh_topology import mesh_topology
from core.two_pose_inbetweens import Interpolator
from core.untold_triangles import (borrowed_edges, thin_triangles, told_donors, triangle_heights, unfaced_triangles,
                                   untold_triangles)

from placement_helpers import _screw
from test_placement_rigid_motions import _sphere_turned_far_in_single_precision
from test_placement_exaggeration import _tube, _with_slivers

_AXIS = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])
_TURN = Rotation.from_rotvec(np.radians(60.0) * _AXIS).as_matrix()
_SHIFT = np.array([0.3, 0.2, -0.1])


def _slivered_tube(height):
    """The tube with 28 T-junction slivers ``height`` × their long side high, its diagonal, and
    the slivers' rows (the last of each four triangles the T-junctions add)."""
    vertices, triangles = _with_slivers(*_tube(), height)
    added = len(triangles) - len(_tube()[1]) + 2 * 28
    slivers = np.arange(len(triangles) - added, len(triangles))[3::4]
    return vertices, triangles, float(np.linalg.norm(np.ptp(vertices, axis=0))), slivers


def _keys(vertices, triangles, other):
    topology = Topology(mesh_topology(triangles, len(vertices)), vertices)
    return topology, Key(topology, vertices), Key(topology, other)


def test_slivers_take_the_triangle_across_their_long_side_as_donor():
    """Each T-junction sliver (1e-9 high) is untold in both keys of a rigid motion, the triangles
    around it are told, and its donor is the triangle across its longest side (the quad's other
    half, which shares the diagonal the sliver stands on)."""
    vertices, triangles, _, slivers = _slivered_tube(1e-9)
    topology, base, nxt = _keys(vertices, triangles, vertices @ _TURN.T + _SHIFT)
    mean_edge = float(np.mean(base.lengths))
    untold = untold_triangles(base, nxt, 0.01 * mean_edge)
    assert np.array_equal(np.flatnonzero(untold), slivers)
    rows, donors = told_donors(topology.across, base.lengths, untold)
    assert np.array_equal(rows, slivers)
    for row, donor in zip(rows, donors):
        longest = int(np.argmax(base.lengths[row]))
        side = {triangles[row, longest], triangles[row, (longest + 1) % 3]}
        assert side <= set(triangles[donor]) and not untold[donor]


def test_one_height_tells_thin_untold_and_unfaced_triangles():
    """The height of each triangle is its cross product's length over its longest side (an
    independent formula, per triangle); thin triangles are those under the floor in either key,
    untold ones those under it in both (so untold ⊆ thin), unfaced ones those under twice the noise
    in either key, each read against that height. The tube with 1e-5 slivers, its second key
    squashed along its axis on its first half, so that the triangles there are low in that key only."""
    vertices, triangles, _, _ = _slivered_tube(1e-5)
    other = vertices.copy()
    other[vertices[:, 0] < 1.0, 0] *= 1e-4  # the tube runs 0 … 2 along x
    _, base, nxt = _keys(vertices, triangles, other)
    def heights(x):
        corners = x[triangles]
        cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        longest = np.linalg.norm(corners[:, [1, 2, 0]] - corners, axis=2).max(axis=1)
        return np.linalg.norm(cross, axis=1) / longest
    expected = heights(vertices), heights(other)
    assert np.allclose(triangle_heights(base.areas, base.lengths), expected[0], rtol=1e-9, atol=0.0)
    assert np.allclose(triangle_heights(nxt.areas, nxt.lengths), expected[1], rtol=1e-9, atol=0.0)
    floor = 0.01 * float(np.mean(base.lengths))
    # away from the floor by more than the heights' rounding, so either formula reads each alike
    clear = (np.abs(expected[0] / floor - 1.0) > 1e-6) & (np.abs(expected[1] / floor - 1.0) > 1e-6)
    thin, untold = thin_triangles(base, nxt, floor), untold_triangles(base, nxt, floor)
    low = (expected[0] < floor, expected[1] < floor)
    assert np.array_equal(np.isin(np.flatnonzero(clear), thin), (low[0] | low[1])[clear])
    assert np.array_equal(untold[clear], (low[0] & low[1])[clear])
    assert np.isin(np.flatnonzero(untold), thin).all() and 0 < untold.sum() < thin.size
    noise = np.full(len(triangles), 0.5 * floor)
    assert np.array_equal(unfaced_triangles(base, nxt, noise)[clear], (low[0] | low[1])[clear])


def test_across_is_the_triangle_sharing_each_corner_edge():
    """``Topology.across``: for corner edge c of each triangle (corners c, c + 1) the other
    triangle holding both its vertices, -1 where none does (the tube's open ends), read against a
    search of every triangle's vertex pairs."""
    vertices, triangles, _, _ = _slivered_tube(1e-5)
    topology, _, _ = _keys(vertices, triangles, vertices)
    owners = {}
    for t, corners in enumerate(triangles.tolist()):
        for c in range(3):
            owners.setdefault(frozenset((corners[c], corners[(c + 1) % 3])), []).append(t)
    expected = np.array([[next((o for o in owners[frozenset((row[c], row[(c + 1) % 3]))] if o != t), -1)
                          for c in range(3)] for t, row in enumerate(triangles.tolist())])
    assert np.array_equal(topology.across, expected)
    assert (expected < 0).any()


def test_triangles_ringed_by_untold_ones_take_their_donor_ring_by_ring():
    """Untold triangles with no told neighbour take, ring by ring, the donor of their neighbour
    across the longest side among those one ring nearer the told triangles, read against a
    breadth-first search over the neighbours; every donor is told, and an untold piece with no
    told triangle lists none. A band of the tube's triangles untold around each sliver."""
    vertices, triangles, _, slivers = _slivered_tube(1e-5)
    topology, base, _ = _keys(vertices, triangles, vertices)
    across, lengths = topology.across, base.lengths
    untold = np.zeros(len(triangles), dtype=bool)
    untold[slivers] = True
    for _ in range(2):  # two rings around the slivers
        untold[across[untold][across[untold] >= 0]] = True
    ring = np.where(untold, -1, 0)
    donor = np.where(untold, -1, np.arange(len(triangles)))
    for depth in range(1, len(triangles)):
        reached = {}
        for t in np.flatnonzero(ring < 0):
            near = [(lengths[t, c], -c, across[t, c]) for c in range(3)
                    if across[t, c] >= 0 and ring[across[t, c]] == depth - 1]
            if near:
                reached[t] = donor[max(near)[2]]  # the longest side, the first of two as long
        if not reached:
            break
        for t, d in reached.items():
            ring[t], donor[t] = depth, d
    rows, donors = told_donors(across, lengths, untold)
    assert ring.max() >= 2 and np.array_equal(rows, np.flatnonzero(untold & (ring > 0)))
    assert np.array_equal(donors, donor[rows]) and not untold[donors].any()
    everything = np.ones(len(triangles), dtype=bool)
    assert told_donors(across, lengths, everything)[0].size == 0


def test_borrowed_edges_are_the_donors_map_of_the_edges():
    """The borrowed target edges are the donor's interpolated map — its rotation of its base
    frame, its stretch in its tangent plane, its normal turned with it — applied to the untold
    triangle's base edges, as the 3×3 matrix ``R · B diag(S, 1) Bᵀ`` gives them (an independent
    formula: one matrix product per edge)."""
    vertices, triangles, _, slivers = _slivered_tube(1e-5)
    topology, base, nxt = _keys(vertices, triangles, vertices)
    rows, donors = told_donors(topology.across, base.lengths, untold_triangles(base, nxt, 0.01 * np.mean(base.lengths)))
    rng = np.random.default_rng(4)
    turns = Rotation.random(len(rows), random_state=5).as_matrix()  # (k, 3, 3)
    count = len(rows)
    stretch = np.c_[rng.uniform(0.5, 2.0, count), rng.uniform(-0.3, 0.3, count), rng.uniform(0.5, 2.0, count)]
    frames = np.einsum("kab,cbk->cak", turns, base.column_rows[:2][:, :, donors])  # (2 columns, 3, k)
    got = borrowed_edges(base.column_rows, base.tangent_rows, rows, donors, frames, stretch)
    for i, (row, donor) in enumerate(zip(rows, donors)):
        frame = base.column_rows[:, :, donor]  # rows t1, t2, n
        packed = np.array([[stretch[i, 0], stretch[i, 1], 0.0], [stretch[i, 1], stretch[i, 2], 0.0], [0.0, 0.0, 1.0]])
        whole = turns[i] @ frame.T @ packed @ frame
        corners = vertices[triangles[row]]
        edges = corners[[1, 2, 0]] - corners  # corner edge c from corner c to c + 1
        assert np.allclose(got[:, :, i].T, edges @ whole.T, rtol=0.0, atol=1e-12)


@pytest.mark.parametrize("height", [1e-9, 1e-5, 1e-3])
def test_a_noisy_rigid_motion_of_a_slivered_mesh_follows_the_noise(height):
    """A scan-like tube with 28 slivers turned 60° about an oblique axis and shifted, the second
    pose carrying 1e-6 of the diagonal of noise (a rigid motion stored in single precision, a
    scanner's jitter): every factor is the screw motion to within the noise the factor carries
    (at most twice its largest displacement times the factor), silently. With the slivers' own
    turns and stretches, read from the noise across triangles lower than it, 1e-9 / 1e-5 high
    slivers came out 0.13 / 8.6e-3 of the diagonal off at 0.5 and 1e-3 ones 8.4e-5 at ×2."""
    vertices, triangles, diagonal, _ = _slivered_tube(height)
    noise = np.random.default_rng(3).normal(size=vertices.shape) * 1e-6 * diagonal / np.sqrt(3)
    largest = np.linalg.norm(noise, axis=1).max()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        interpolator = Interpolator(vertices, vertices @ _TURN.T + _SHIFT + noise, triangles)
        for s in (0.25, 0.5, 2.0, -0.5):
            off = np.linalg.norm(interpolator.pose(s) - _screw(vertices, _TURN, _SHIFT, s), axis=1).max()
            assert off < 2.0 * max(abs(s), 1.0) * largest, s


@pytest.mark.parametrize("factor", [1.5, 2.0, -0.5])
def test_an_exaggerated_rigid_motion_of_a_mesh_with_1e_9_slivers_is_exact(factor):
    """The same tube with slivers 1e-9 high turned exactly: exaggerated or reversed it is the screw
    motion to 1e-12 of the diagonal (the issue asks 1e-6), silently. Counted as flipped where the
    fit's rounding (1e-10 of the diagonal) turned them over, the slivers were repaired into the
    mesh around them: 1.9e-2 / 7.8e-3 off at ×2 / −0.5, warned as flipped triangles kept."""
    vertices, triangles, diagonal, _ = _slivered_tube(1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        x = Interpolator(vertices, vertices @ _TURN.T + _SHIFT, triangles).pose(factor)
    assert np.linalg.norm(x - _screw(vertices, _TURN, _SHIFT, factor), axis=1).max() < 1e-12 * diagonal


@pytest.mark.parametrize("height", [1e-5, 3e-5, 1e-4])
def test_slivers_under_the_keys_rounding_far_from_the_origin_turn_rigidly_and_silently(height):
    """A sphere with four slivers ``height`` high turned rigidly 60° 1,000 units from the origin,
    keyed in single precision (rounding 1.2e-4, over the slivers' height): at 0.5 and ×2 it is the
    rigid motion to within twice the keys' rounding (the rounding the factor carries), and no
    warning says the in-betweens bend around the slivers. With their own targets the in-betweens
    bent the sphere around what the rounding made of them: 396 / 181 / 73 roundings off, warned."""
    off, said, rounding = _sphere_turned_far_in_single_precision(height)
    assert off < 2.0 * rounding and not said, (off / rounding, said)
