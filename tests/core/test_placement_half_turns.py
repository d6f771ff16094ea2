"""Parts that turn by a half turn or more between keys (issue 17 item 3): curled strips, tubes and
tails keep turning the way their keys and neighbouring steps tell, and are warned where the keys
do not tell the way. No bpy."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import ShapeDifferenceWarning
from core.rigid_alignment import rigid_alignment
from core import rotation_continuity
from core.rotation_continuity import continuous_rotation_vectors, jumping_pairs, lone_triangles
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator

import meshes
from inbetween_helpers import _normals
from meshes import grid, icosphere
from placement_helpers import (FACTORS, HALF_TURN_UNTOLD, _curled_strip, _curled_tube, _head_with_eyes, _remeshed_tube,
                               _rigid, _skinned_limb)


def test_a_turn_past_a_half_turn_between_keys_goes_on_the_way_its_neighbours_turn():
    """Keys of the head spinning about a fixed axis by 100°, 190° and 170°: the middle gap's short
    way round is 170° backwards, but the gaps before and after turn forwards, and so does it: at
    every factor the mesh is turned about the axis (rigidly), forwards from the gap's first key by
    between 0 and 190° (the screws' Catmull–Rom spline of the angles 0, 100, 290, 460: 190.6° at
    the middle). The short way made the spin reverse for one gap."""
    a, tri = _head_with_eyes()
    axis, pivot = np.array([0.0, 0.3, 1.0]) / np.linalg.norm([0.0, 0.3, 1.0]), np.array([1.0, 0.5, 0.0])
    angles = np.radians([0.0, 100.0, 290.0, 460.0])
    keys = [_rigid(a, Rotation.from_rotvec(angle * axis).as_matrix(), pivot) for angle in angles]
    seq = SequenceInterpolator(keys, tri, start="keys")
    factors = (0.25, 0.5, 0.75)
    for s, x in zip(factors, seq.poses(1, factors)):
        rotation, translation = rigid_alignment(a, x)
        np.testing.assert_allclose(a @ rotation.T + translation, x, atol=1e-6)
        turn = Rotation.from_matrix(rotation).as_rotvec()
        forward = (np.degrees(np.linalg.norm(turn)) * np.sign(turn @ axis) - 100.0) % 360.0
        assert 0.0 < forward < 190.0 + 1e-6, (s, forward)
        if s == 0.5:
            assert abs(forward - 90.6) < 1.0, forward


def test_a_turn_near_a_half_turn_after_a_step_about_another_axis_goes_the_short_way():
    """Keys of the head turned 52° about an axis 123° from z, then 160° about z (a carried flag
    tilted, then swinging back round its pole): the last gap's short way round is 160° forwards
    about z. The other way round (200° backwards) is 16° nearer the step before's turn, but turns
    the gap's middle 20° further: so little evidence does not outweigh the short way, and the head
    turns forwards about z from the gap's first key, by between 0 and 160° at every factor (the
    other way round went backwards from the start, 38° at a quarter of the gap)."""
    a, tri = _head_with_eyes()
    tilt = np.radians(123.0)
    step = Rotation.from_rotvec(np.radians(52.0) * np.array([np.sin(tilt), 0.0, np.cos(tilt)])).as_matrix()
    swing = Rotation.from_rotvec(np.radians(160.0) * np.array([0.0, 0.0, 1.0])).as_matrix()
    pivot = np.array([1.0, -0.5, 0.0])
    keys = [a, _rigid(a, step, pivot)]
    keys.append(_rigid(keys[1], swing, pivot))
    seq = SequenceInterpolator(keys, tri, start="keys")
    for s, x in zip((0.25, 0.5, 0.75), seq.poses(1, (0.25, 0.5, 0.75))):
        rotation, translation = rigid_alignment(keys[1], x)
        np.testing.assert_allclose(keys[1] @ rotation.T + translation, x, atol=1e-6)
        turn = np.degrees(Rotation.from_matrix(rotation).as_rotvec())
        assert 0.0 < turn[2] and np.linalg.norm(turn) < 160.0, (s, turn)


def test_a_swing_that_reverses_at_a_key_keeps_its_turning_direction():
    """Keys of a rigid mesh swinging about a pivot, the turn reversing at key 1 (angles 0.3, 0.5,
    0.4, 0.1 rad): the in-betweens of gap 1 are the rigid turns by the cubic Hermite spline of
    the keys' angles with Catmull–Rom tangents, written out here. The turn back to key 0 seen from
    key 1 is −0.2 rad; taking +0.2 (the inverse rotation, as near the continuation of the next
    turn) reversed the start velocity."""
    a, tri = _head_with_eyes()
    axis = np.array([0.2, 0.0, 1.0]) / np.linalg.norm([0.2, 0.0, 1.0])
    pivot = np.array([0.5, -2.0, 0.3])
    angles = [0.3, 0.5, 0.4, 0.1]
    keys = [_rigid(a, Rotation.from_rotvec(angle * axis).as_matrix(), pivot) for angle in angles]
    seq = SequenceInterpolator(keys, tri, start="keys")
    start, secant = angles[1], angles[2] - angles[1]
    t0, t1 = 0.5 * (angles[2] - angles[0]), 0.5 * (angles[3] - angles[1])
    for s in (0.125, 0.25, 0.5, 0.75):
        angle = start + (3 * s**2 - 2 * s**3) * secant + (s**3 - 2 * s**2 + s) * t0 + (s**3 - s**2) * t1
        expected = _rigid(a, Rotation.from_rotvec(angle * axis).as_matrix(), pivot)
        np.testing.assert_allclose(seq.pose(1, s), expected, atol=1e-6)


def test_a_strip_curled_past_a_half_turn_keeps_curling_the_same_way():
    """Curled by 120° at each of two joints, the tip turns by 240° between the keys: half-way it
    is the strip curled by 60° / 60° (to 1e-3 of the diagonal), its tip facing away from both
    keys as the interpolated rotations say. Read as flipped against both keys' normals, the
    exact fit was “repaired” into another shape (22 % of the diagonal off, 640 triangles facing
    against the true pose's)."""
    a, tri = _curled_strip((0.0, 0.0))
    b, _ = _curled_strip((np.radians(120.0),) * 2)
    truth, _ = _curled_strip((np.radians(60.0),) * 2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        x = Interpolator(a, b, tri).pose(0.5)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < 1e-3 * diagonal
    assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


@pytest.mark.parametrize("degrees", [220.0, 270.0])
def test_a_strip_curled_past_a_half_turn_at_one_joint_keeps_curling_the_same_way(degrees):
    """Curled at one joint by more than a half turn, the tip turns further from the strip's best
    rigid motion than a half turn, whose principal rotation vector goes the other way round: the
    triangles past that point turned back (240°: 21 % of the diagonal off the strip curled by
    120° half-way, 152 of 960 triangles facing against it, no warning). Taken continuous across
    the strip, every in-between, exaggeration and reversal is the strip curled by the factor times
    the angle."""
    a, tri = _curled_strip((0.0,), joints=(0.9,))
    b, _ = _curled_strip((np.radians(degrees),), joints=(0.9,))
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    it = Interpolator(a, b, tri)
    for factor in (-0.5, 0.3, 0.5, 0.75, 1.5):
        truth, _ = _curled_strip((factor * np.radians(degrees),), joints=(0.9,))
        with warnings.catch_warnings():
            warnings.simplefilter("error", ShapeDifferenceWarning)
            x = it.pose(factor)
        assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < 1e-3 * diagonal
        assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()




@pytest.mark.parametrize("degrees, width, noise", [(270.0, 2, 3e-4), (270.0, 3, 3e-4), (270.0, 2, 1e-3),
                                                   (270.0, 3, 1e-3), (300.0, 3, 3e-4), (220.0, 3, 1e-3)])
def test_a_noisy_strip_curled_past_a_half_turn_at_one_joint_keeps_curling_the_same_way(degrees, width, noise):
    """The strip above, 61 × ``width`` vertices, curled 220°–300° at one joint over four rings of
    triangles (55–75° between neighbouring rings: a crease by
    :data:`~core.rotation_continuity.WRAP_CREASE`), with Gaussian noise of ``noise`` (1e-4–3.3e-4
    of its length) on every coordinate of both poses. Half-way its tip faces away from both poses
    as the field turns it, and the fit follows that field only to within the keys' noise (normals
    up to 1° off their interpolated ones where ``arctan δ`` is 0.3°, edges 0.4–0.7 × the keys' own
    change off the metric on average): read as flipped, a repair turned the tip the short way
    round, 0.54–0.63 of the diagonal off with most of its triangles facing against the curl,
    silently. Two poses take every piece's turns continuous across the mesh, creases included,
    and so read its far-turning parts, whose edges keep the metric to the keys' own change there.
    Where the strip's rigid fit turns the short way round its tip's residuals are within the noise
    of none; continued by a whole turn about their noisy axes they jumped, and every factor went
    the short way round (:meth:`core.inbetween_whole_rotations.WholeRotations.residuals_add_turn` takes such a
    piece's rotations whole). Each in-between and exaggeration is the noise-free strip curled by
    the factor times the angle to the gap's tolerance, every triangle facing as in it, silently."""
    angle = np.radians(degrees)
    rng = np.random.default_rng(1)
    a, tri = _curled_strip((0.0,), joints=(0.9,), width=width, n=61)
    b, _ = _curled_strip((angle,), joints=(0.9,), width=width, n=61)
    a, b = a + noise * rng.normal(size=a.shape), b + noise * rng.normal(size=b.shape)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    factors = (0.3, 0.4, 0.5, 0.6, 0.7, 1.5)
    truths = [_curled_strip((factor * angle,), joints=(0.9,), width=width, n=61)[0] for factor in factors]
    _assert_silently_true(Interpolator(a, b, tri), tri, diagonal, factors, truths)

@pytest.mark.parametrize("degrees, joints", [((120.0, 120.0), (0.9, 1.9)), ((270.0,), (0.9,))])
def test_a_strip_one_triangle_wide_curled_past_a_half_turn_keeps_curling_the_same_way(degrees, joints):
    """The strips above one triangle wide (121 × 2 vertices: no vertex off the boundary, so no
    triangle carries a whole ring, :meth:`core.inbetween_turned_away.TurnedAway._carrying_a_vertex`), their
    tips turning 240° / 270° between two poses and 170° × 2 per key in a sequence: every
    in-between, exaggeration and reversal of the two poses is the strip curled by the factor times
    the angles (to 1e-3 of the diagonal, as the wide strip), every sequence in-between the curl at
    its time (to the gap's tolerance), each triangle facing as in the truth, silently: a part
    turning past a half turn as its piece's field says is kept by the check of the whole piece."""
    angles = np.radians(degrees)
    a, tri = _curled_strip(0.0 * angles, joints=joints, width=2)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, _curled_strip(angles, joints=joints, width=2)[0], tri)
    for factor in (-0.5, 0.3, 0.5, 0.75, 1.5):
        truth, _ = _curled_strip(factor * angles, joints=joints, width=2)
        with warnings.catch_warnings():
            warnings.simplefilter("error", ShapeDifferenceWarning)
            x = interpolator.pose(factor)
        assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < 1e-3 * diagonal
        assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()
    step = np.radians([170.0] * len(joints))
    sequence = SequenceInterpolator([_curled_strip(k * step, joints=joints, width=2)[0] for k in range(3)], tri,
                                    start="keys")
    for gap in range(2):
        with warnings.catch_warnings():
            warnings.simplefilter("error", ShapeDifferenceWarning)
            poses = sequence.poses(gap, (0.3, 0.5, 0.7))
        for x, factor in zip(poses, (0.3, 0.5, 0.7)):
            truth, _ = _curled_strip((gap + factor) * step, joints=joints, width=2)
            assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < sequence._gap(gap).tolerance * diagonal
            assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()

def _assert_silently_true(interpolator, tri, diagonal, factors, truths):
    """Each pose of ``interpolator`` at ``factors`` is its truth to the gap's tolerance (RMS over
    the diagonal), every triangle facing as in it, without a warning."""
    for factor, truth in zip(factors, truths):
        with warnings.catch_warnings():
            warnings.simplefilter("error", ShapeDifferenceWarning)
            x = interpolator.pose(factor)
        tolerance = interpolator._sequence._gap(0).tolerance
        assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < tolerance * diagonal
        assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


@pytest.mark.parametrize("degrees, joints, spread", [((120.0, 120.0), (0.25, 0.6), 0.35), ((240.0,), (0.3,), 0.5)])
def test_a_closed_tube_curled_past_a_half_turn_keeps_curling_the_same_way(degrees, joints, spread):
    """A closed tube curled by 120° at each of two joints (or by 240° at one) bends its
    cross-sections, so its fit keeps the interpolated metric to 0.2–0.7 % of the edge lengths, not
    to 0.1 %, where its tip faces away from both keys between the factors 0.4 and 0.6: read as
    flipped there, the fit is “repaired” into another shape, 11–21 % of the diagonal off the tube
    curled by the factor times the angles, mostly without a warning. Every in-between is that
    tube to 1 % of the diagonal (the fit keeps the metric to its tolerance, not exactly), with
    every triangle facing as in it, silently."""
    angles = np.radians(degrees)
    a, tri = _curled_tube(0.0 * angles, joints, spread)
    b, _ = _curled_tube(angles, joints, spread)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, b, tri)
    for factor in (0.3, 0.4, 0.45, 0.5, 0.55, 0.6, 0.7):
        truth, _ = _curled_tube(factor * angles, joints, spread)
        with warnings.catch_warnings():
            warnings.simplefilter("error", ShapeDifferenceWarning)
            x = interpolator.pose(factor)
        assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < 1e-2 * diagonal
        assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


def test_a_lone_triangle_turned_off_its_neighbours_leaves_the_rest_continued_past_a_half_turn():
    """Rotations of a strip of triangles (3 rows of 60, neighbours along and across the rows)
    turning from 0 to 250° about y along it, with one triangle of the middle row, past the half
    turn, turned 150° further about another axis (a triangle crushed in a key: its rotation more
    than WRAP_CREASE from each neighbour's). The jump past a half turn left at it kept the whole
    strip's principal vectors, its far end read −110°; the far end reads 250°, and the jumps left
    are at the lone triangle alone."""
    rows, count = 3, 60
    index = np.arange(rows * count).reshape(rows, count)
    pairs = np.vstack([np.c_[index[:, :-1].ravel(), index[:, 1:].ravel()],
                       np.c_[index[:-1].ravel(), index[1:].ravel()]])
    turns = Rotation.from_rotvec(np.tile(np.linspace(0.0, np.radians(250.0), count), rows)[:, None] * [0.0, 1.0, 0.0])
    lone = index[1, 45]
    rotvec = turns.as_rotvec()
    rotvec[lone] = (Rotation.from_rotvec(np.radians(150.0) * np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)) *
                    turns[lone]).as_rotvec()
    alone = lone_triangles(rotvec, pairs)
    assert np.flatnonzero(alone).tolist() == [lone]
    out = continuous_rotation_vectors(rotvec, pairs, np.zeros(rows * count, dtype=int))
    np.testing.assert_allclose(out[index[:, -1]], np.radians(250.0) * np.array([[0.0, 1.0, 0.0]] * rows), atol=1e-12)
    left = pairs[jumping_pairs(out, pairs)]
    assert left.size and (left == lone).any(axis=1).all()


def test_an_irregular_limb_skinned_past_a_half_turn_at_two_joints_turns_its_tip_the_rigs_way():
    """A limb re-meshed irregularly (3,084 vertices, density rising 10 × along it) skinned at two
    joints by 100° and 150° (weight ramps 0.6 long): its tip turns 250°, past a half turn. One
    triangle crushed to a fifth of its shape at the second ramp's end turns 121–128° from each of
    its neighbours; the jump past a half turn left there kept the limb's principal rotations, and
    every in-between and exaggeration turned the tip the short way round (1.01–1.14 × the linear
    blend's RMS error from the rig at 0.25–0.75, the tip −27° at 0.25 where the rig turns it 62°).
    At each factor the tip turns as the rig's, to 2°, and the pose is within 0.1 × the blend's
    error from the rig (0.02–0.06 measured: a skin's ramp is no isometry, the fit keeps the
    interpolated metric)."""
    a, tri = _remeshed_tube(3000, 1)
    tip = a[:, 0] > 2.4
    for factor, x, rig, angles in _limb_poses(a, tri, (0.25, 0.5, 0.75, 1.5, -0.5)):
        rotation, _ = rigid_alignment(a[tip], x[tip])
        off = Rotation.from_matrix(rotation) * Rotation.from_rotvec([0.0, -factor * angles.sum(), 0.0])
        assert off.magnitude() < np.radians(2.0)


def _limb_poses(a, tri, factors):
    """``(factor, pose, rig's pose, angles)`` of the in-betweens of the re-meshed limb ``a`` and its
    pose skinned 100° + 150°, at each of ``factors``, each pose checked within 0.1 × the linear
    blend's RMS error from the rig (the fit keeps the interpolated metric, which a skin's ramp
    does not: 0.02–0.06 measured)."""
    angles = np.radians([100.0, 150.0])
    b = _skinned_limb(a, angles)
    interpolator = Interpolator(a, b, tri)
    for factor in factors:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            x = interpolator.pose(factor)
        rig, blend = _skinned_limb(a, factor * angles), (1.0 - factor) * a + factor * b
        rms, blend_rms = (np.sqrt(np.mean(np.sum((y - rig) ** 2, axis=1))) for y in (x, blend))
        assert rms < 0.1 * blend_rms
        yield factor, x, rig, angles


@pytest.mark.parametrize("seed", [2, 6])
def test_an_irregular_limb_whose_tip_faces_away_from_both_poses_half_way_is_not_read_as_flipped(seed):
    """Limbs re-meshed as in the test above (other seeds), skinned 100° + 150°: half-way the tip
    faces away from both poses, as its interpolated rotations turn it, and the fit follows them
    (0.05 × the blend's error) but for a few triangles of the crushed inner side of the second
    ramp's end, which their neighbours carry 46–64° off their interpolated normals (seed 6: two
    more at the second ramp's start folded 111–124° against them and against the rig). The limb
    was read as no turning piece, its ~850 turned-away triangles as flipped, and the fallback's
    fit near the linear blend returned (1.00 × the blend's error, ~2,300 triangles facing against
    the rig). Between 0.48 and 0.55 the pose is within 0.1 × the blend's error from the rig and
    fewer than 0.5 % of its triangles face against the rig's."""
    a, tri = _remeshed_tube(3000, seed)
    for _, x, rig, _ in _limb_poses(a, tri, (0.48, 0.5, 0.55)):
        against = np.einsum("ij,ij->i", _normals(x, tri), _normals(rig, tri)) <= 0.0
        assert against.sum() < 0.005 * len(tri)


@pytest.mark.parametrize("degrees, joints, spread, radius, count", [
    (60.0, (0.25, 0.6), 0.35, 0.07, 3), (90.0, (0.25, 0.6), 0.35, 0.07, 3), (120.0, (0.25, 0.6), 0.35, 0.07, 3),
    (80.0, (0.15, 0.5), 0.3, 0.03, 4), (100.0, (0.15, 0.5), 0.3, 0.03, 4), (170.0, (0.15, 0.5), 0.3, 0.03, 4)])
def test_a_tube_curling_past_a_half_turn_per_key_keeps_curling_the_same_way(degrees, joints, spread, radius, count):
    """Keys of a closed tube curling at two joints by ``degrees`` per key at each: a finger (its
    tip turning 120° / 180° / 240° per gap) and a thin arm (160° / 200° / 340°). Past a half turn
    a part of the tube turns that far from the rest in every gap, past a right angle at least
    without a crease; its rotations are then taken whole and continuous across the mesh, and the
    tube is not anchored to the keys' per-vertex spline (a chord of the curl). Every in-between
    is the tube curled by the interpolated angles to the gap's tolerance (a fit whose edges are
    off by a relative δ sits off by about δ of its size), with every triangle facing as in it
    (before, the finger at 120° was 9–12 % of the diagonal off with up to 146 triangles facing
    against the curl, the arm 12–34 %, up to 307; the finger at 90° 3.1–6.7 %, the arm at 80°
    1.7–8.9 %, silently)."""
    angles = np.radians([degrees, degrees])
    keys = [_curled_tube(k * angles, joints, spread, radius)[0] for k in range(count)]
    _, tri = _curled_tube(0.0 * angles, joints, spread, radius)
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(count - 1):
        for factor in (0.3, 0.5, 0.7):
            truth, _ = _curled_tube((gap + factor) * angles, joints, spread, radius)
            with warnings.catch_warnings():
                warnings.simplefilter("error", ShapeDifferenceWarning)
                x = sequence.pose(gap, factor)
            tolerance = sequence._gap(gap).tolerance
            assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < tolerance * diagonal
            assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


def test_a_coarse_tube_curling_past_a_half_turn_per_key_is_right_or_warned():
    """The thin arm of the test above on 13 rings of 6 sides, curled 150° per key at each joint:
    its neighbouring rings turn over 30° apart, a crease to the turn test
    (:data:`core.rotation_continuity.WRAP_CREASE`), so the way round is not known there. Every
    in-between is the curl to the gap's tolerance with every triangle facing as in it, or its
    gap warns (before, 10–33 % of the diagonal off with 28–34 triangles against the curl and no
    warning of the turn)."""
    angles, joints = np.radians([150.0, 150.0]), (0.15, 0.5)
    keys = [_curled_tube(k * angles, joints, 0.3, 0.03, rings=13, sides=6)[0] for k in range(4)]
    _, tri = _curled_tube(0.0 * angles, joints, 0.3, 0.03, rings=13, sides=6)
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(3):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            poses = sequence.poses(gap, (0.3, 0.5, 0.7))
        warned = any("turns past a half turn" in str(w.message) for w in caught)
        tolerance = sequence._gap(gap).tolerance
        for x, factor in zip(poses, (0.3, 0.5, 0.7)):
            truth, _ = _curled_tube((gap + factor) * angles, joints, 0.3, 0.03, rings=13, sides=6)
            right = np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < tolerance * diagonal and \
                (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()
            assert right or warned


def _wagged_tail(wag, rings=101, sides=12):
    """A tail (a closed tube of radius 0.03 and length 1) wagged about y by ``wag``: its root bone
    (x < 0.2) turned by 31° × ``wag`` about the root, each of its four joints (x = 0.2, 0.4, 0.6,
    0.8, each bend over 0.1) by 30° × ``wag`` more."""
    tube, tri = _curled_tube(np.radians([30.0 * wag] * 4), (0.2, 0.4, 0.6, 0.8), 0.1, 0.03, rings=rings, sides=sides)
    return Rotation.from_rotvec([0.0, -np.radians(31.0 * wag), 0.0]).apply(tube), tri


def test_a_tail_wagging_past_a_half_turn_per_key_turns_the_way_its_rigid_motion_does():
    """Keys of a tail wagged ±1 (its root turning 62° per gap, its tip 302°): the tip's whole
    rotation, 58° the other way round, is less than the root's, so the rotations taken
    continuous from there read the root as turning 298° and every in-between came out spun by a
    whole turn times the factor (130 % of the diagonal off half-way, 921–1,294 triangles facing
    against the tail, silently). Read as the tail's rigid motion turns (130° per gap), every
    in-between has every triangle facing as in the tail at the interpolated angles and is closer
    to it than the linear blend, and half-way through the middle gap (the keys either side
    mirror each other) it is the straight tail to the gap's tolerance."""
    wag = (1.0, -1.0, 1.0, -1.0)
    keys = [_wagged_tail(w)[0] for w in wag]
    _, tri = _wagged_tail(0.0)
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(len(keys) - 1):
        factors = (0.25, 0.5, 0.75)
        for x, factor in zip(sequence.poses(gap, factors), factors):
            truth, _ = _wagged_tail(wag[gap] + factor * (wag[gap + 1] - wag[gap]))
            blend = (1.0 - factor) * keys[gap] + factor * keys[gap + 1]
            assert np.sum((x - truth) ** 2) < np.sum((blend - truth) ** 2)
            assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()
    x = sequence.pose(1, 0.5)
    straight, _ = _wagged_tail(0.0)
    assert np.sqrt(np.mean(np.sum((x - straight) ** 2, axis=1))) < sequence._gap(1).tolerance * diagonal


@pytest.mark.parametrize("wag", [(1.0, -1.0, 1.2, -1.0), (1.2, -1.0, 1.0, -1.0)])
def test_a_tail_wagging_unevenly_past_a_half_turn_per_key_turns_the_way_its_rigid_motion_does(wag):
    """Keys of the tail above wagged unevenly: gaps of 2 (root 62°, tip 302° per gap) and 2.2
    (root 68°, tip 332°, whose whole rotation, 28° the other way round, is less than the root's).
    Each gap read from its own keys takes the even gaps from the root and the uneven ones from
    the tip, a whole turn of the tail apart, and the keys either side of a key are 0–30° apart:
    the readings do not add up across the key, so where they disagree the tail turns as its
    rigid motion does (before, the uneven gaps were 88–141 % of the diagonal off with up to
    1,130 triangles facing against the tail, silently). Every in-between is closer to the tail at
    the interpolated angles than the linear blend, with every triangle facing as in it, and no
    gap warns."""
    keys = [_wagged_tail(w)[0] for w in wag]
    _, tri = _wagged_tail(0.0)
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(len(keys) - 1):
        factors = (0.25, 0.5, 0.75)
        with warnings.catch_warnings():
            warnings.simplefilter("error", ShapeDifferenceWarning)
            poses = sequence.poses(gap, factors)
        for x, factor in zip(poses, factors):
            truth, _ = _wagged_tail(wag[gap] + factor * (wag[gap + 1] - wag[gap]))
            blend = (1.0 - factor) * keys[gap] + factor * keys[gap + 1]
            assert np.sum((x - truth) ** 2) < np.sum((blend - truth) ** 2)
            assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


@pytest.mark.parametrize("wag", [(1.0, -1.0, 1.4, -1.0), (1.0, -1.3, 1.0), (1.0, -1.2, 1.2, -1.3, 1.0)])
def test_a_tail_whose_way_round_the_keys_do_not_tell_is_right_or_warned(wag):
    """Keys of the tail above wagged 1, −1, 1.4, −1: the uneven gaps turn its tip 362° (root
    74°), past a whole turn, where neither its rigid motion nor its ends tell which way it went,
    and the readings of the gaps still do not add up across their keys; and wagged 1, −1.3, 1:
    both gaps turn its tip 347° (root 71°), both are read from the tip, 13° the other way round,
    and add up, but the tip is not held still and the tail's rigid motion reads it the other way
    round; and wagged 1, −1.2, 1.2, −1.3, 1: the middle gaps turn its tip 362° and 378°, a ring
    near it a whole turn, which reads as held still there alone (the readings a whole turn off
    add up across every key). Every in-between is closer to the tail at the interpolated angles than the linear
    blend with every triangle facing as in it, or its gap warns that it may turn the tail the
    other way round (before, 86–130 % of the diagonal off, up to 1,042 triangles against the
    tail, silently)."""
    keys = [_wagged_tail(w)[0] for w in wag]
    _, tri = _wagged_tail(0.0)
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(len(keys) - 1):
        factors = (0.25, 0.5, 0.75)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            poses = sequence.poses(gap, factors)
        warned = any("other way round" in str(w.message) for w in caught)
        for x, factor in zip(poses, factors):
            truth, _ = _wagged_tail(wag[gap] + factor * (wag[gap + 1] - wag[gap]))
            blend = (1.0 - factor) * keys[gap] + factor * keys[gap + 1]
            right = np.sum((x - truth) ** 2) < np.sum((blend - truth) ** 2) and \
                (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()
            assert right or warned


def _skinned_tail(wag, rings=101, sides=24):
    """A tail (a closed tube of radius 0.03 and length 1) skinned to five bones by linear blend
    skinning, each vertex's weights ramping from one bone to the next over 0.12 about each joint
    (x = 0.2, 0.4, 0.6, 0.8), wagged about y by ``wag``: the root bone turned by 30° × ``wag``
    about the root, each joint by 30° × ``wag`` more (the blend of the bones' motions pinches the
    inner side of each bent joint, as an armature's skin does)."""
    tube, tri = meshes.closed_tube(rings, sides, radius=0.03)
    joints = (0.2, 0.4, 0.6, 0.8)
    beyond = [np.ones(len(tube))] + [np.clip((tube[:, 0] - j) / 0.12 + 0.5, 0.0, 1.0) for j in joints] + [0.0]
    turn = Rotation.from_rotvec([0.0, -np.radians(30.0 * wag), 0.0])
    rotation, shift, out = turn, np.zeros(3), np.zeros_like(tube)
    for bone in range(5):
        if bone:  # this bone: the previous one turned about its joint
            joint = np.array([joints[bone - 1], 0.0, 0.0])
            shift = shift + rotation.apply(joint) - (rotation * turn).apply(joint)
            rotation = rotation * turn
        out += (beyond[bone] - beyond[bone + 1])[:, None] * (rotation.apply(tube) + shift)
    return out, tri


def test_a_skinned_tail_wagging_past_a_half_turn_per_key_is_not_read_as_flipped():
    """Keys of a skinned tail wagged 0, ±1 (its root turning 60° per gap, its tip 300°): half-way
    through the inner gaps its tip faces away from both keys, and the interpolated normals of a
    few triangles (16 of 1,352 on a 100 × 40 Blender tail) lie a few degrees on a key's side of
    edge-on where their fit's, up to 8° off them, face away. The fit's local steps turn a triangle
    up to :data:`~core.inbetween_fit.MAX_ROTATION_DEVIATION` off its interpolated rotation in such
    a piece, so it is turning whole: before, 762–794 triangles there were read as flipped and the
    fit was returned as it was with a warning. Each in-between is the skinned tail at the
    interpolated angles to the gap's tolerance with every triangle facing as in it, silently."""
    wag = (0.0, 1.0, -1.0, 1.0)
    keys = [_skinned_tail(w)[0] for w in wag]
    _, tri = _skinned_tail(0.0)
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in (1, 2):
        truth, _ = _skinned_tail(0.5 * (wag[gap] + wag[gap + 1]))
        with warnings.catch_warnings():
            warnings.simplefilter("error", ShapeDifferenceWarning)
            x = sequence.pose(gap, 0.5)
        assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < sequence._gap(gap).tolerance * diagonal
        assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


def test_two_poses_of_a_skinned_tentacle_curled_past_a_half_turn_are_not_read_as_flipped():
    """Two poses of a tentacle built in Blender (a Skin modifier on a nine-node chain 2 long,
    radius 0.12 → 0.03, one Subdivision level 2; Automatic Weights on nine bones; 1,442 vertices
    in single precision) at rest and curled 270°: each joint but the root's turned 33.75° about
    x. Half-way its tip faces away from both poses and a few of its fit's triangles stray over
    ``arctan δ`` from their interpolated normals, a strict limit for a piece not known to turn
    far; a two-pose gap reads no turning parts for its anchor, so none was known: read as flipped,
    the pose fell back to the metric fitted near the linear blend, with a warning, 0.32 of the
    diagonal off the rig's own pose at the factors' power of its bones' rotations (0.4 and 0.6
    within 2e-3). Read as a sequence reads it (a part turning past a half turn from the rest, its
    triangles may stray as far as the fit's local steps turn them), each in-between is that pose
    to the gap's tolerance, every triangle facing as in it, silently."""
    data = np.load(Path(__file__).parent / "data" / "skinned_tentacle.npz")
    rest, curled, tri = data["rest"].astype(float), data["curled"].astype(float), data["triangles"]
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    _assert_silently_true(Interpolator(rest, curled, tri), tri, diagonal, data["factors"], data["truths"].astype(float))


def test_a_skinned_tail_triangle_at_edge_on_with_a_key_is_not_read_as_flipped():
    """The skinned tail above wagged 0, ±1 over five gaps, three in-betweens of each at once: at the
    factor 0.25 of the fourth gap one triangle of its tip, which the interpolated field brings 3°
    short of edge-on with the first key, is fitted 3.8° off that, 0.06° past edge-on (the truth is
    8° short of it). The fit holds its edges to the gap's tolerance only (2.3 %), which leaves its
    turn about that uncertain (1.3°): it faces along the truth, and is not flipped (before: a
    warning of one flipped triangle). Each in-between faces as the truth does."""
    wag = (0.0, 1.0, -1.0, 1.0, -1.0, 0.0)
    keys = [_skinned_tail(w)[0] for w in wag]
    _, tri = _skinned_tail(0.0)
    sequence = SequenceInterpolator(keys, tri)
    factors = (0.25, 0.5, 0.75)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        poses = sequence.poses(3, factors)
    for x, factor in zip(poses, factors):
        truth, _ = _skinned_tail(wag[3] + factor * (wag[4] - wag[3]))
        assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


@pytest.mark.parametrize("degrees", [100.0, 170.0])
def test_a_tube_curling_past_a_half_turn_per_key_in_a_batch_is_solved_at_every_factor(degrees):
    """The thin arm of the test above through ``poses`` (keys 8 frames apart: seven in-betweens
    at once, which elsewhere solve three and predict the rest from the keys' per-vertex spline): its
    curl is not anchored to that spline, whose chord a correction polynomial does not bend back
    onto the arc, so every in-between is solved. Each is the tube curled by the interpolated
    angles to the gap's tolerance with every triangle facing as in it (predicted, at 170° the
    in-betweens were up to 21 % of the diagonal off with 231 triangles against the curl)."""
    angles, joints = np.radians([degrees, degrees]), (0.15, 0.5)
    keys = [_curled_tube(k * angles, joints, 0.3, 0.03)[0] for k in range(4)]
    _, tri = _curled_tube(0.0 * angles, joints, 0.3, 0.03)
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    sequence = SequenceInterpolator(keys, tri, start="keys")
    factors = np.arange(1, 8) / 8
    for gap in range(3):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            poses = sequence.poses(gap, factors)
        tolerance = sequence._gap(gap).tolerance
        for x, factor in zip(poses, factors):
            truth, _ = _curled_tube((gap + factor) * angles, joints, 0.3, 0.03)
            assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < tolerance * diagonal
            assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


def test_a_tube_curling_past_a_half_turn_per_key_while_it_travels_keeps_its_place():
    """The thin arm of the tests above curling 150° per key at each joint while it travels by
    (0.3, −0.2, 0.1) per key, nothing of it still: its keys' centroids sample the loop its curl
    makes, and their spline cuts it (placed there, the in-betweens were 3.9–17.9 % of the diagonal
    off, their shapes right to 0.1 %); the part the rest turns from moves as the keys' per-vertex
    spline says. Every in-between is the travelling curl to the gap's tolerance."""
    angles, joints = np.radians([150.0, 150.0]), (0.15, 0.5)
    travel = np.array([0.3, -0.2, 0.1])
    keys = [_curled_tube(k * angles, joints, 0.3, 0.03)[0] + k * travel for k in range(4)]
    _, tri = _curled_tube(0.0 * angles, joints, 0.3, 0.03)
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(3):
        for factor in (0.3, 0.5, 0.7):
            truth = _curled_tube((gap + factor) * angles, joints, 0.3, 0.03)[0] + (gap + factor) * travel
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ShapeDifferenceWarning)
                x = sequence.pose(gap, factor)
            tolerance = sequence._gap(gap).tolerance
            assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < tolerance * diagonal


def test_a_tube_curling_past_a_half_turn_per_key_while_it_turns_about_another_axis_keeps_curling():
    """The thin arm of the tests above curling 170° per key at each joint (its tip 340° per gap)
    while the whole arm turns 10° per key about z: the part that stays turns 10°, the tip's
    principal rotation 22° (its curl's 20° short of a whole turn composed with the turn about z),
    within the tie of which end stays, and the arm's rigid fit reads the curl the other way round;
    read from the tip, every triangle took a whole turn about its own axis, and the in-betweens
    were 27–78 % of the diagonal off with up to 709 triangles facing against the curl, silently.
    Each triangle's whole rotation is interpolated as one turn, not as the arm's turn about z
    composed with its curl: at a factor t the two differ by about t(1 − t)/2 × the product of
    those angles (their commutator), so a point at distance ≤ 1 along the arm sits off by at
    most about that. Every in-between is within it and faces as the truth does."""
    angles, joints, spin = np.radians([170.0, 170.0]), (0.15, 0.5), np.radians(10.0)

    def arm(t):
        return Rotation.from_rotvec([0.0, 0.0, spin * t]).apply(_curled_tube(t * angles, joints, 0.3, 0.03)[0])

    keys = [arm(k) for k in range(4)]
    _, tri = _curled_tube(0.0 * angles, joints, 0.3, 0.03)
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(3):
        for factor in (0.3, 0.5, 0.7):
            truth = arm(gap + factor)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ShapeDifferenceWarning)
                x = sequence.pose(gap, factor)
            commutator = 0.5 * factor * (1.0 - factor) * spin * angles.sum()
            assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < commutator * diagonal
            assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


@pytest.mark.parametrize("curl, spin", [(170.0, 20.0), (150.0, 10.0), (170.0, 0.0)])
def test_a_tube_curling_while_it_turns_about_another_axis_warns_where_the_turns_do_not_commute(curl, spin):
    """The thin arm above curling ``curl`` degrees per key at each joint while the whole arm turns
    ``spin`` per key about z. Each triangle's whole rotation is interpolated as one turn; the arm's
    turn about z composed with the curl also joins the keys, and half-way the two are apart by
    their commutator: at 170° turning 20°, 29 % of the arm's area over ``WRAP_CREASE`` (30°, what
    the readings take as one turn), its forearm up to 89° (tilted 88–90° off the curl in every
    gap, 47 triangles facing against it half-way through the first, silently), which the keys do
    not tell apart, so every gap warns. At 150° turning 10° they are at most 18° apart, and with
    no turn about z the curl's turns compose exactly: neither warns."""
    angles, joints = np.radians([curl, curl]), (0.15, 0.5)

    def arm(t):
        return Rotation.from_rotvec([0.0, 0.0, np.radians(spin) * t]).apply(_curled_tube(t * angles, joints, 0.3, 0.03)[0])

    keys = [arm(k) for k in range(4)]
    _, tri = _curled_tube(0.0 * angles, joints, 0.3, 0.03)
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(3):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            sequence.poses(gap, (0.3, 0.5, 0.7))
        said = [str(w.message) for w in caught if "composed" in str(w.message)]
        assert len(said) == (1 if (curl, spin) == (170.0, 20.0) else 0), said


def _rolled(vertices, angle):
    """A sheet rolled about the y axis from its x = min edge into an arc of ``angle`` radians."""
    x = vertices[:, 0] - vertices[:, 0].min()
    radius = np.ptp(vertices[:, 0]) / angle
    return np.stack([radius * np.sin(x / radius), vertices[:, 1], radius * (1.0 - np.cos(x / radius))], axis=1)


@pytest.mark.parametrize("angle", [5.5, 6.2])
def test_a_sheet_rolled_nearly_into_a_tube_is_rolled_half_as_far(angle):
    """Rolled by 5.5 and 6.2 rad (its free edge turned by 315° and 355°: read edge by edge, a turn
    of −45° and −5°, which the linear blend barely shortens), the in-betweens are the sheet rolled
    by f · angle to 2e-3 of its width, silently (before, the blend anchored the free edge across
    the turn: 0.65–0.78 of the width off, edges up to 80 % stretched, no warning)."""
    v, t = grid(20, size=2.0)
    rolled = _rolled(v, angle)
    interpolator = Interpolator(v, rolled, t)
    for factor in (0.3, 0.5, 0.7):
        with warnings.catch_warnings():
            warnings.simplefilter("error", ShapeDifferenceWarning)
            x = interpolator.pose(factor)
        truth = _rolled(v, factor * angle)
        rotation, translation = rigid_alignment(x, truth)[:2]
        assert np.abs(x @ rotation.T + translation - truth).max() < 2e-3 * 2.0


def test_a_lid_turned_by_a_half_turn_on_a_fixed_box_stays_rigid():
    """A lid (a separate piece) turned by exactly 180° about its hinge while the box stays: at
    every factor the box stays put and the lid is a rigid turn about the hinge (either way round:
    both are as short). Half-way, its triangles' normals are perpendicular to both keys' in exact
    arithmetic; read as flipped by rounding, they had a repair bend the lid (edges 56 % off)."""
    box, box_triangles = icosphere(2)
    lid, lid_triangles = icosphere(1, radius=0.4)
    lid = lid + np.array([0.0, 0.0, 1.5])
    hinge, axis = np.array([0.0, 1.0, 1.0]), np.array([1.0, 0.0, 0.0])
    turned = _rigid(lid, Rotation.from_rotvec(np.pi * axis).as_matrix(), hinge)
    tri = np.vstack([box_triangles, lid_triangles + len(box)])
    interpolator = Interpolator(np.vstack([box, lid]), np.vstack([box, turned]), tri)
    for s in FACTORS:
        x = interpolator.pose(s)
        assert np.abs(x[: len(box)] - box).max() < 1e-6
        errors = [np.abs(x[len(box):] - _rigid(lid, Rotation.from_rotvec(sign * s * np.pi * axis).as_matrix(),
                                                hinge)).max() for sign in (1, -1)]
        assert min(errors) < 1e-6, (s, errors)


def _crank(angle):
    """A block (sphere of radius 1) and a crank (a separate ellipsoid 1 long and 0.24 thick, on an
    axle along x through x = 1.12 that it crosses 0.2 from its end, touching the block there)
    turned by ``angle`` (radians) about that axle."""
    block, block_triangles = icosphere(2)
    arm, arm_triangles = icosphere(2)
    axle = np.array([1.12, 0.0, 0.0])
    arm = arm * [0.12, 0.5, 0.12] + axle + [0.0, 0.3, 0.0]
    turned = _rigid(arm, Rotation.from_rotvec([angle, 0.0, 0.0]).as_matrix(), axle)
    return np.vstack([block, turned]), np.vstack([block_triangles, arm_triangles + len(block)])


@pytest.mark.parametrize("degrees", [180.0, 120.0])
def test_a_crank_turning_a_half_turn_per_key_is_warned(degrees):
    """A crank on a fixed block keyed every 180° about its axle: its keys alternate between two
    poses, which either way round join as well (both turns are as short), and nothing tells the
    way (the whole mesh does not turn: the crank's half turn relative to the block it is jointed
    to is the motion). Every gap of a sequence and the two poses warn that the in-betweens may turn
    it the other way round (an engine's crankshaft so keyed came out turning backwards in two of
    its three gaps, 3,208 triangles against its frames per in-between, silently). Keyed every
    120°, the way is the short one and nothing warns."""
    keys = [_crank(np.radians(degrees * k))[0] for k in range(4)]
    _, tri = _crank(0.0)
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(3):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            sequence.poses(gap, (0.25, 0.5, 0.75))
            Interpolator(keys[gap], keys[gap + 1], tri).pose(0.5)
        said = [str(w.message) for w in caught if "half turn" in str(w.message)]
        assert len(said) == (2 if degrees == 180.0 else 0), said
        # the crank turns in its still block: its half turn is the crank's, not the whole mesh's
        assert all("piece(s) turn a half turn" in message for message in said), said


def test_pieces_turned_half_round_as_one_are_warned_of_as_the_whole_mesh():
    """A head and two eyes (three pieces, the eyes jointed to the head in their sockets) turned
    exactly 180° as one rigid body about an axis through none of them: nothing in the keys tells
    which way round. Two poses, and a sequence keyed every half turn, say so once per gap, of the
    whole mesh, not as a count of pieces: counting the pieces whose own half turn is untold, the
    head alone (the eyes' turns are told by their joints), said "1 piece(s)" of the three (a rigged
    character of 59 pieces turned so: 6 or 42 of 59). Each in-between is a rigid turn of the whole
    mesh, one way round or the other."""
    a, tri = _head_with_eyes()
    axis, pivot = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2]), np.array([0.5, -1.5, 0.2])
    def turned(angle):
        return _rigid(a, Rotation.from_rotvec(angle * axis).as_matrix(), pivot)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    sequence = SequenceInterpolator([turned(0.0), turned(np.pi), turned(2.0 * np.pi)], tri, start="keys")
    for gap, pose in ((0, lambda: Interpolator(a, turned(np.pi), tri).pose(0.5)),
                      (0, lambda: sequence.pose(0, 0.5)), (1, lambda: sequence.pose(1, 0.5))):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            x = pose()
        said = [str(w.message) for w in caught if "half turn" in str(w.message)]
        assert len(said) == 1 and "the whole mesh turns a half turn (180°) as one" in said[0], said
        assert "piece(s)" not in said[0], said
        errors = [np.abs(x - turned((gap + 0.5 * sign) * np.pi)).max() for sign in (1, -1)]
        assert min(errors) < 1e-6 * diagonal, errors


@pytest.mark.parametrize("turns, warned", [((170.0, 200.0, 230.0), (0, 1, 2)), ((130.0, 150.0, 170.0), ()),
                                           ((170.0, 150.0, 130.0), ())])
def test_a_spin_past_a_half_turn_per_gap_that_the_keys_read_backwards_is_warned(turns, warned):
    """A sheet spinning on about its middle 170°, 200°, 230° per gap reads +170°, −160°, −130°
    between its keys: the short way round, backwards past the first gap, which no in-between can
    undo. Each gap says that its spin may be read the wrong way round (the gap reading a near half
    turn, and the run reading the other way next to it), the last one too, whose reading (−130°)
    is no near half turn. A sheet turning on one way under a half turn per gap, speeding up or
    slowing down, is read as it turns and says nothing of it."""
    _, middles = _spun_sheet(turns)
    assert tuple(gap for gap, (_, spins) in enumerate(middles) if spins) == warned


def _spun_sheet(turns):
    """A 9 × 9 sheet about its middle turned ``turns`` (degrees) about z per gap: its keys, and per
    gap the sequence's in-between half-way with the warnings of its gap that say its spin may be
    read the wrong way round."""
    sheet, tri = grid(9, size=1.0)
    sheet -= sheet.mean(axis=0)
    angles = np.radians(np.concatenate([[0.0], np.cumsum(turns)]))
    keys = [Rotation.from_rotvec([0.0, 0.0, angle]).apply(sheet) for angle in angles]
    sequence = SequenceInterpolator(keys, tri)
    middles = []
    for gap in range(len(turns)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            middle = sequence.pose(gap, 0.5)
        middles.append((middle, [w.message for w in caught if "may spin on past a half turn per gap" in str(w.message)]))
    return keys, middles


@pytest.mark.parametrize("keys", [3, 4])
def test_a_sheet_keyed_every_half_turn_turns_about_its_axis(keys):
    """A draped sheet turning about the vertical axis through its middle, keyed every half turn
    (its middle vertex on the axis: still in every key): every in-between is the sheet turned
    about that axis (heights and distances from the axis kept, one angle for all its vertices).
    Two keys apart it has turned a whole turn, the identity, whose rotation vector's axis is
    rounding noise: continued about that axis, the in-betweens came out 181 % off in edge length."""
    sheet, tri = meshes.draped_sheet()
    posed = [Rotation.from_rotvec([0.0, 0.0, np.pi * k]).apply(sheet) for k in range(keys)]
    sequence = SequenceInterpolator(posed, tri)
    radius = np.hypot(sheet[:, 0], sheet[:, 1])
    far = radius > 0.5
    for gap in range(len(sequence)):
        with pytest.warns(ShapeDifferenceWarning, match=HALF_TURN_UNTOLD):  # keys alternating: either way
            poses = sequence.poses(gap, FACTORS)
        for x in poses:
            np.testing.assert_allclose(x[:, 2], sheet[:, 2], atol=1e-9)
            np.testing.assert_allclose(np.hypot(x[:, 0], x[:, 1]), radius, atol=1e-9)
            turned = np.angle((x[far, 0] + 1j * x[far, 1]) / (sheet[far, 0] + 1j * sheet[far, 1]))
            assert np.ptp(np.unwrap(turned)) < 1e-9


def _float32_rounding(*keys):
    """What float32 keys are known to, as a fraction of the first key's diagonal: single
    precision's rounding at the largest coordinate (Blender keeps positions so)."""
    largest = max(float(np.abs(k).max()) for k in keys)
    return np.finfo(np.float32).eps * largest / float(np.linalg.norm(np.ptp(keys[0], axis=0)))


@pytest.mark.parametrize("offset", [10.0, 100.0])
def test_a_half_turn_in_single_precision_turns_every_piece_one_way(offset):
    """A head, two eyes and a single-triangle piece turned exactly 180° about an axis through none
    of them, the keys in float32 and ``offset`` units from the origin: every factor is one rigid
    turn of them all, to float32's rounding. Rounding reads the small triangle's angle ~1e-5 rad
    off π, "short of a half turn the other way": it turned against the rest (0.50 of the
    diagonal off half-way)."""
    head, tri = _head_with_eyes()
    rest = np.vstack([head, [[1.5, 0.0, 0.0], [1.7, 0.0, 0.0], [1.5, 0.2, 0.05]]])
    tri = np.vstack([tri, [[len(head), len(head) + 1, len(head) + 2]]])
    axis, pivot = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3]), np.array([0.4, -1.3, 0.1])
    a = (rest + offset).astype(np.float32)
    b = (_rigid(rest, Rotation.from_rotvec(np.pi * axis).as_matrix(), pivot) + offset).astype(np.float32)
    tolerance = 100 * _float32_rounding(a, b)
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    interpolator = Interpolator(a, b, tri)
    for s in (0.25, 0.5):
        with pytest.warns(ShapeDifferenceWarning, match=HALF_TURN_UNTOLD):
            x = interpolator.pose(s) - offset
        errors = [np.abs(x - _rigid(rest, Rotation.from_rotvec(sign * s * np.pi * axis).as_matrix(), pivot)).max()
                  for sign in (1, -1)]
        assert min(errors) / diagonal < tolerance, (s, errors)


def test_cards_keyed_every_half_turn_in_single_precision_stay_one_rigid_body():
    """300 cards (separate quads) scattered around a vertical axis through none of them, keyed
    every half turn in float32 10 units out: the middle of every gap is all of them turned a
    quarter turn about the axis, one way (the keys cannot tell which). Rounding (~1e-5 rad on a
    card) split them: cards alone turned about their centroids (off their circle, 0.36 of the
    diagonal), steps read as half turns the other way continued nowhere, and the group's point on
    the axis was sent 1e6 away along it."""
    rng = np.random.default_rng(1)
    quad = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 0.05
    rest = np.vstack([quad @ Rotation.random(random_state=i).as_matrix().T + rng.uniform(-1, 1, 3) for i in range(300)])
    tri = np.vstack([np.array([[0, 1, 2], [0, 2, 3]]) + 4 * i for i in range(300)])
    pivot = np.array([0.0123, -0.0377, 0.0])
    def turned(angle):
        return _rigid(rest, Rotation.from_rotvec([0.0, 0.0, angle]).as_matrix(), pivot)
    keys = np.array([(turned(k * np.pi) + 10.0).astype(np.float32) for k in range(4)])
    tolerance = 100 * _float32_rounding(*keys)
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    sequence = SequenceInterpolator(keys, tri, start="keys")
    for gap in range(len(sequence)):
        with pytest.warns(ShapeDifferenceWarning, match=HALF_TURN_UNTOLD):
            x = sequence.pose(gap, 0.5) - 10.0
        errors = [np.abs(x - turned((gap + 0.5 * sign) * np.pi)).max() for sign in (1, -1)]
        assert min(errors) / diagonal < tolerance, (gap, errors)


def test_a_noisy_piece_turning_past_a_half_turn_stays_whole():
    """A small slab (98 vertices, noise 6e-4 on its vertices) spinning beside a still sphere by
    −100°, −185°, −100° per key: its middle gap turns the way its neighbours do, and half-way its
    edges stay within the keys' own spread (1.18 ×; allowed 1.25 ×). Past a half turn its side
    faces face away from both keys; read as flipped (their edges off the metric by the noise, over
    the strict tolerance), a repair tore it: edges 8.8 × their length."""
    from meshes import cube

    body, body_triangles = icosphere(2)
    slab, slab_triangles = cube(3)
    slab = slab * np.array([0.3, 0.15, 0.025])
    centre = np.array([2.5, 0.0, 0.0])
    tri = np.vstack([body_triangles, slab_triangles + len(body)])
    on_slab = np.arange(len(body) + len(slab)) >= len(body)
    edges = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    edges = edges[on_slab[edges[:, 0]]]

    def lengths(x):
        return np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1)

    rng = np.random.default_rng(0)
    keys = []
    for angle in np.radians([0.0, -100.0, -285.0, -385.0]):
        turned = slab @ Rotation.from_rotvec([0.0, 0.0, angle]).as_matrix().T + centre
        keys.append(np.vstack([body + 1e-5 * rng.standard_normal(body.shape),
                               turned + 6e-4 * rng.standard_normal(slab.shape)]))
    x = SequenceInterpolator(keys, tri).pose(1, 0.5)
    low, high = np.minimum(lengths(keys[1]), lengths(keys[2])), np.maximum(lengths(keys[1]), lengths(keys[2]))
    assert np.max(np.maximum(lengths(x) / low, high / lengths(x))) < 1.25


def test_a_skin_body_turned_half_round_reads_its_tied_regions_by_their_readings(monkeypatch):
    """A Skin-modifier body (Blender's Rigify human meta-rig, Skin + Subdivision 1, 796 vertices)
    turned half round by its root bone, in the rig's single precision: rounding cuts it into 155
    regions tied in how many whole turns they take, read with two candidates between them.
    :func:`~core.rotation_continuity._creases_read` counts each region's creases as counting it on
    its own does (the reference below, per region), and the in-between is the half turn, rigid to
    1e-6 of the diagonal. Counting per region takes minutes on the same body subdivided to 55,000
    vertices (thousands of tied regions; measured in docs/inbetween-measurements.md)."""
    data = np.load(Path(__file__).parent / "data" / "skin_body_half_turn.npz")
    a, b, tri = data["vertices_a"].astype(float), data["vertices_b"].astype(float), data["triangles"]
    seen = []
    read = rotation_continuity._creases_read

    def spy(rotvec, pairs, region, sets, turns, direction, axis, linked, tied, candidate):
        counts = read(rotvec, pairs, region, sets, turns, direction, axis, linked, tied, candidate)
        seen.append((rotvec, pairs, region, sets, turns, direction, axis, linked, tied, candidate, counts))
        return counts

    monkeypatch.setattr(rotation_continuity, "_creases_read", spy)
    x = Interpolator(a, b, tri).pose(0.5)
    rotation, translation = rigid_alignment(a, x)
    diagonal = np.linalg.norm(a.max(axis=0) - a.min(axis=0))
    assert np.abs(a @ rotation.T + translation - x).max() < 1e-6 * diagonal
    assert np.isclose(Rotation.from_matrix(rotation).magnitude(), np.pi / 2, atol=1e-6)
    assert seen
    for rotvec, pairs, region, sets, turns, direction, axis, linked, tied, candidate, counts in seen:
        several = np.bincount(sets[tied], minlength=len(sets)) > 1
        assert len(np.unique(np.stack([sets[tied], candidate], axis=1), axis=0)) < len(tied)
        for i, r in enumerate(tied):
            expected = 0
            if several[sets[r]]:
                ends = pairs[(sets[region[pairs[:, 0]]] == sets[r]) & (sets[region[pairs[:, 1]]] == sets[r])
                             & linked[region[pairs[:, 0]]] & linked[region[pairs[:, 1]]]]
                whole = 2.0 * np.pi * (turns + candidate[i] * direction)[region[ends]]
                vectors = rotvec[ends] + whole[:, :, None] * axis[ends]
                expected = np.count_nonzero(np.linalg.norm(vectors[:, 0] - vectors[:, 1], axis=1)
                                            > rotation_continuity.WRAP_CREASE)
            assert counts[i] == expected


@pytest.mark.parametrize("turns, warned, excess", [((70.0, 220.0, 110.0), (1,), 230.0 / 130.0),
                                                   ((80.0, -80.0, 80.0, -80.0), (), None),
                                                   ((100.0, -100.0, 100.0, -100.0), (1, 2), 200.0 / 160.0),
                                                   ((70.0, 140.0, 110.0), (), None)])
def test_a_spin_read_backwards_for_one_gap_under_a_near_half_turn_is_warned(turns, warned, excess):
    """A sheet twirled +70°, +220°, +110° per gap reads +70°, −140°, +110° between its keys: the
    middle gap, no near half turn, reads the short way round, backwards between two gaps that turn
    it on, and its in-betweens turn it back (over 30° half-way). Taken the long way round (+220°)
    it is 130° from the mean turn of the gaps beside (+90°), the short way 230°: that gap, and only
    it, says its spin may be read the wrong way round, with that ratio as its excess. A sheet wagged
    ±80° per gap (its long way, 280°, 200° from the turns beside it, the short way 160°), and one
    twirled on under a half turn per gap, say nothing of it; wagged ±100°, the keys do not tell it
    from a spin of +100°, +260°, +100°, … (the long way 160° from the turns beside, the short way
    200°): its middle gaps say so, their in-betweens turning it the short way, between its keys."""
    keys, middles = _spun_sheet(turns)
    said = []
    for gap, (middle, spins) in enumerate(middles):
        if not spins:
            continue
        said.append(gap)
        assert len(spins) == 1 and spins[0].kind == "turn"
        assert spins[0].excess == pytest.approx(excess, rel=1e-9)
        # half-way, the sheet's turn from the gap's first key (about its middle, z up)
        start = keys[gap] - keys[gap].mean(axis=0)
        far = np.hypot(start[:, 0], start[:, 1]) > 0.25
        moved = middle - middle.mean(axis=0)
        turned = np.degrees(np.angle((moved[far, 0] + 1j * moved[far, 1]) / (start[far, 0] + 1j * start[far, 1])))
        if turns[gap] > 180.0:  # the twirl turned back, where it went on +110°: the miss the warning is about
            assert np.all(turned < -30.0), turned.max()
        else:  # the wag's in-betweens turn it back the short way, between its keys (as it went)
            assert np.all((turned < 0.0) & (turned > turns[gap])) if turns[gap] < 0 else \
                np.all((turned > 0.0) & (turned < turns[gap])), turned
    assert tuple(said) == warned
