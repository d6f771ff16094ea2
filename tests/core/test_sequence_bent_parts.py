"""Sequences of a skinned limb whose keys bend it far at a joint (issue 17): the keys' per-vertex
splines cut the arc its bent part turns along, so a gap whose splines read such a turn (read from
the keys alone) is anchored as two poses are. No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.optimize import minimize, minimize_scalar
from scipy.spatial.transform import Rotation

from core.errors import ShapeDifferenceWarning
from core.sequence_bent_parts import BENT_PART_TURN, RIGID_BENT_TURN, RIGID_METRIC
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator
from placement_helpers import _curled_tube, _remeshed_tube, _skinned_limb


def _tube(rings: int = 41, sides: int = 16, length: float = 4.0, radius: float = 0.3):
    """A closed-round open tube along x (``rings`` × ``sides`` vertices, (n, 3)) and its triangles."""
    x = np.linspace(0.0, length, rings)[:, None]
    around = 2 * np.pi * np.arange(sides)[None, :] / sides
    v = np.stack([x + 0.0 * around, radius * np.cos(around) + 0.0 * x, radius * np.sin(around) + 0.0 * x], axis=-1)
    index = np.arange(rings * sides).reshape(rings, sides)
    a, b = index[:-1], np.roll(index[:-1], -1, axis=1)
    c, d = index[1:], np.roll(index[1:], -1, axis=1)
    triangles = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return v.reshape(-1, 3), triangles


def _skinned(rest: np.ndarray, degrees: float, joint: float = 2.0, ramp: float = 0.6) -> np.ndarray:
    """Linear blend skinning of ``rest`` on two bones meeting at x = ``joint``: the second bone
    turned about z by ``degrees`` about the joint, the weights a smoothstep over ``ramp`` about it;
    the keys rounded to single precision, as a bake stores them."""
    u = np.clip((rest[:, 0] - (joint - ramp / 2)) / ramp, 0.0, 1.0)
    weight = (u * u * (3 - 2 * u))[:, None]
    pivot = np.array([joint, 0.0, 0.0])
    turned = Rotation.from_euler("z", degrees, degrees=True).apply(rest - pivot) + pivot
    return ((1 - weight) * rest + weight * turned).astype(np.float32).astype(np.float64)


def _anchored(keys, triangles, **options) -> list[bool]:
    """Whether each gap of the sequence of ``keys`` (``options`` of :class:`SequenceInterpolator`)
    is anchored as two poses are."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)  # k_M = 60 splits a pair of frequencies
        sequence = SequenceInterpolator(keys, triangles, **options)
        return [sequence._gap(gap).anchored for gap in range(len(sequence))]


def _off_the_rig(x, rig, start, end, triangles, diagonal):
    """How far the pose ``x`` (n, 3) is from the rig's own pose nearest it between the joint angles
    ``start`` and ``end`` (degrees; ``rig(angles)`` → (n, 3)), whatever the timing: the RMS
    distance ÷ ``diagonal`` at the angles that fit ``x`` best, and the count of triangles facing
    against the rig's there."""
    start, end = np.atleast_1d(np.asarray(start, float)), np.atleast_1d(np.asarray(end, float))

    def rms(angles):
        return np.sqrt(np.mean(np.sum((x - rig(angles)) ** 2, axis=1)))

    along = minimize_scalar(lambda t: rms(start + t * (end - start)), bounds=(-0.5, 1.5), method="bounded",
                            options=dict(xatol=1e-6)).x
    angles = start + along * (end - start)
    if len(angles) > 1:  # each joint at its own angle
        angles = minimize(rms, angles, method="Nelder-Mead", options=dict(xatol=1e-4, fatol=1e-12)).x
    posed = rig(angles)

    def normals(v):
        return np.cross(v[triangles[:, 1]] - v[triangles[:, 0]], v[triangles[:, 2]] - v[triangles[:, 0]])

    return rms(angles) / diagonal, int(np.count_nonzero(np.einsum("ij,ij->i", normals(x), normals(posed)) <= 0.0))


def _sequence_and_pairs(keys, triangles, factors=(0.25, 0.5, 0.75), k_M=None, smooth=True):
    """Each gap's in-betweens at ``factors`` from the sequence of ``keys`` and from two poses on the
    same pair of keys (both with ``k_M``; the sequence ``smooth`` or not): [(gap, factor, the
    sequence's pose, the two poses' pose)]."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        sequence = SequenceInterpolator(keys, triangles, k_M=k_M, smooth=smooth)
        out = []
        for gap in range(len(sequence)):
            pair = Interpolator(keys[gap], keys[gap + 1], triangles, k_M=k_M)
            out += [(gap, f, x, pair.pose(f)) for f, x in zip(factors, sequence.poses(gap, list(factors)))]
    return out


def test_a_limb_bent_past_the_limit_is_anchored_in_that_gap_and_the_gaps_next_to_it():
    # keys jittered by up to 5e-5 (edges 0.1; noise on no grid, a scan's): the bones keep their metric
    # only to a few 1e-3, isometric (ISOMETRIC) but not rigid to the keys' rounding (RIGID_METRIC), so
    # the limit is BENT_PART_TURN
    rest, triangles = _tube()
    rng = np.random.default_rng(0)

    def keys(angles):
        return [_skinned(rest, a) + rng.uniform(-5e-5, 5e-5, rest.shape) for a in angles]

    # 100° in the first gap, 50° in the second, whose cubic spline reads the first gap's keys
    assert _anchored(keys((0.0, 100.0, 150.0)), triangles) == [True, True]
    # 40° then 100°: the first gap's spline reads the second's keys; a third gap's does not
    assert _anchored(keys((0.0, 40.0, 140.0, 150.0, 160.0)), triangles) == [True, True, True, False]
    # within the limit: anchored to the keys' spline, as before
    assert _anchored(keys((0.0, 60.0, 120.0, 180.0)), triangles) == [False] * 3
    assert np.degrees(BENT_PART_TURN) > 60.0


def test_a_limb_whose_bones_are_rigid_to_the_keys_rounding_is_anchored_at_any_bend():
    # single-precision keys of a skin keep each bone's metric to ~1e-7: a joint's parts, which no
    # moving cloth has, so a gap is anchored as two poses are past RIGID_BENT_TURN (the 75° limit
    # left 0 / 60 / 120 / 180° and 0 / 40 / 140 / 150 / 160°'s last gap on the keys' spline)
    rest, triangles = _tube()
    assert _anchored([_skinned(rest, a) for a in (0.0, 60.0, 120.0, 180.0)], triangles) == [True] * 3
    assert _anchored([_skinned(rest, a) for a in (0.0, 40.0, 140.0, 150.0, 160.0)], triangles) == [True] * 4
    assert _anchored([_skinned(rest, a) for a in (0.0, 2.0, 4.0)], triangles) == [False] * 2  # within RIGID_SPREAD
    sequence = SequenceInterpolator([_skinned(rest, a) for a in (0.0, 30.0, 60.0)], triangles)
    # the turn read between the rigid parts is the joint's, to single precision
    assert np.degrees(sequence._bent_turn(0, least=RIGID_BENT_TURN, tolerance=RIGID_METRIC)) == \
        pytest.approx(30.0, abs=1e-3)


def _stored(keys, how):
    """``keys`` as an exporter stores them: to ``how`` = ``"d decimals"``, or in single precision
    ``"1000 out"`` from the origin (moved back by the caller)."""
    if how == "1000 out":
        return [(k + 1000.0).astype(np.float32).astype(np.float64) for k in keys]
    return [np.round(k, int(how.split()[0])) for k in keys]


def _warned_too_coarse(keys, triangles) -> bool:
    """Whether the sequence of ``keys``, each gap posed half-way, warns that the keys are too coarse to
    tell its bones rigid (:func:`core.sequence_bent_parts.hidden_rigid_warning`)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        sequence = SequenceInterpolator(keys, triangles)
        for gap in range(len(sequence)):
            sequence.pose(gap, 0.5)
    return any("too coarse to tell" in str(w.message) for w in caught)


def test_the_keys_decimal_rounding_is_read_from_their_coordinates():
    # keys exported to d decimals, read back in double or single precision: the grid's step exactly;
    # a bake's single-precision keys and keys jittered off any grid: none
    from core.coordinate_rounding import decimal_rounding
    from core.mesh_topology import mesh_topology

    rest, triangles = _tube()
    edges = mesh_topology(triangles, len(rest)).edges
    keys = [_skinned(rest, a) for a in (0.0, 30.0, 60.0)]
    for places in (3, 4, 5, 6):
        rounded = [np.round(k, places) for k in keys]
        assert decimal_rounding(rounded, edges) == 10.0 ** -places
        assert decimal_rounding([k.astype(np.float32) for k in rounded], edges) == \
            (10.0 ** -places if places < 6 else 0.0)
        # negative coordinates: the same grid
        assert decimal_rounding([np.round(-k, places) for k in keys], edges) == 10.0 ** -places
    assert decimal_rounding(keys, edges) == 0.0
    assert decimal_rounding([k + np.random.default_rng(0).uniform(-5e-5, 5e-5, k.shape) for k in keys], edges) == 0.0
    # one key off the grid: the keys are not on it
    assert decimal_rounding([np.round(keys[0], 4), keys[1]], edges) == 0.0


@pytest.mark.parametrize("scale", [1e-3, 1e-4])
def test_a_mesh_smaller_than_a_grid_step_is_not_read_as_stored_on_it(scale):
    # a limb 4 mm / 0.4 mm long in metres lies within 5 % of a step of the grid points 0 of every grid
    # from 0.1 / 0.01 down: read as stored to 1 / 2 decimals, a hundred times its own size, its bones
    # were read to RIGID_METRIC_CAP and its noisy keys warned that they were stored to 1 decimal. A grid
    # holds a mesh only where its step is within an edge's length (two grid points differ by a step):
    # the grid read is the one the keys were stored on, or none
    from core.coordinate_rounding import decimal_rounding
    from core.mesh_topology import mesh_topology

    rest, triangles = _tube()
    edges = mesh_topology(triangles, len(rest)).edges
    keyed = (0.0, 30.0, 60.0, 90.0)
    # scan noise on no grid (a few 1e-3 of the bones' metric, as at full size): no warning of decimals,
    # as at full size
    rng = np.random.default_rng(0)
    noisy = [(_skinned(rest, a) + rng.uniform(-5e-5, 5e-5, rest.shape)) * scale for a in keyed]
    for keys in (noisy, [k / scale for k in noisy]):
        assert not _warned_too_coarse(keys, triangles)
    small = [_skinned(rest, a) * scale for a in keyed]
    assert decimal_rounding(small, edges) == 0.0
    assert decimal_rounding([np.round(k, 9) for k in small], edges) == 1e-9


@pytest.mark.parametrize("stored", ["5 decimals", "4 decimals", "1000 out"])
def test_a_limb_whose_keys_are_rounded_coarsely_is_read_rigid_to_their_rounding(stored):
    # keys stored to 5 / 4 decimals (edges 0.1), or in single precision 1000 units out, move a bone's
    # metric by up to 2.2e-4 / 2.5e-3 / ~1.5e-3, past RIGID_METRIC: read to it alone, the LBS tube keyed
    # 30° apart read no rigid part to 4 decimals or 1000 out (no gap anchored: 3.1e-3 of the diagonal
    # off the rig at ¾ of the last gap, two poses 4.3e-4), keyed 20° apart to 5 decimals none in its last
    # gap (1.6e-3 off). Read to the keys' own rounding (rounded_tolerance), every gap is anchored and
    # no in-between is farther from the rig than two poses on the same keys.
    rest, triangles = _tube()
    shift = 1000.0 if stored == "1000 out" else 0.0
    assert _anchored(_stored([_skinned(rest, a) for a in range(0, 161, 20)], stored), triangles) == [True] * 8
    keyed = (0.0, 30.0, 60.0, 90.0)
    keys = _stored([_skinned(rest, a) for a in keyed], stored)
    assert _anchored(keys, triangles) == [True] * 3
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))

    def rig(a):
        return _skinned(rest, a[0])

    for gap, factor, x, pair in _sequence_and_pairs(keys, triangles):
        (off, against), (pair_off, _) = (_off_the_rig(y - shift, rig, keyed[gap], keyed[gap + 1], triangles, diagonal)
                                         for y in (x, pair))
        assert against == 0 and off <= pair_off, (gap, factor)


def test_a_limb_whose_keys_are_too_coarse_to_tell_its_bones_rigid_is_warned():
    # stored to 3 decimals (edges 0.1) the keys move a bone's metric by up to 1.6e-2, past
    # RIGID_METRIC_CAP: no part is read rigid, and each gap is placed by the keys' per-vertex spline
    # (3.1e-3 of the diagonal off the rig at ¾ of the last gap), silently before
    rest, triangles = _tube()
    keyed = (0.0, 30.0, 60.0, 90.0)
    keys = [np.round(_skinned(rest, a), 3) for a in keyed]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        sequence = SequenceInterpolator(keys, triangles)
        late = sequence.pose(2, 0.75)
    said = [w.message for w in caught if "too coarse to tell whether they are rigid bones" in str(w.message)]
    assert [m.gap for m in said] == [("key pose 2", "key pose 3")]
    assert said[0].kind == "turn" and "stored to 3 decimals" in str(said[0]) and "30° apart" in str(said[0])
    # its excess: the turn hidden ÷ the turn that anchors a rigid part (RIGID_BENT_TURN), as the message says it
    from core.sequence_bent_parts import RIGID_BENT_TURN
    assert said[0].excess == pytest.approx(np.radians(30.0) / RIGID_BENT_TURN, rel=0.05)
    assert not any(sequence._gap(gap).anchored for gap in range(3))
    # what it says: the spline places the bone off its arc, where the keys stored with one more decimal
    # (read rigid, anchored) place it within a twelfth of that
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))

    def rig(a):
        return _skinned(rest, a[0])

    finer = SequenceInterpolator([np.round(_skinned(rest, a), 4) for a in keyed], triangles).pose(2, 0.75)
    off, finer_off = (_off_the_rig(x, rig, 60.0, 90.0, triangles, diagonal)[0] for x in (late, finer))
    assert off > 2e-3 and off > 8.0 * finer_off
    # keys that tell the bones rigid (single precision near the origin), or a bend within a rigid
    # part's spread, say nothing of it
    for keys in ([_skinned(rest, a) for a in keyed], [np.round(_skinned(rest, a), 3) for a in (0.0, 1.0, 2.0)]):
        assert not _warned_too_coarse(keys, triangles)


@pytest.mark.parametrize("limb", ["LBS tube 30° a key", "remeshed 60° a key", "remeshed 15° a key"])
def test_a_limb_keyed_within_the_limit_follows_the_rig_no_farther_than_two_poses(limb):
    # keyed under 75° apart, the keys' per-vertex spline cut the bone's arc, most in the first and
    # last gaps, whose end tangents bend it off the arc: 1.8e-3 / 5.8e-3 / 9.6e-4 of the diagonal RMS
    # off the rig half-way in the first gap where two poses on the same keys are 4.3e-4 / 1.9e-3 /
    # 3.5e-4 off (3.1e-3 / 4.2e-3 / 1.25e-3 at ¾ of the last); the bones are rigid to the keys'
    # rounding (RIGID_METRIC), so every gap is anchored as two poses are
    lbs = limb.startswith("LBS")
    rest, triangles = _tube() if lbs else _remeshed_tube(2500, 3)
    keyed = {"LBS tube 30° a key": (0.0, 30.0, 60.0, 90.0), "remeshed 60° a key": (0.0, 60.0, 120.0, 180.0),
             "remeshed 15° a key": (0.0, 15.0, 30.0, 45.0)}[limb]
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))

    def rig(a):  # one joint: at x = 2 (LBS, weights over 0.6) or 1.5 (bones turned by weight, over 0.6)
        return _skinned(rest, a[0]) if lbs else _skinned_limb(rest, np.radians(a), (1.5,))

    still = rest[:, 0] <= (2.0 if lbs else 1.5) - 0.3  # the first bone's vertices: never moved by the rig
    keys = [rig(np.atleast_1d(a)) for a in keyed]
    for gap, factor, x, pair in _sequence_and_pairs(keys, triangles):
        (off, against), (pair_off, _) = (_off_the_rig(y, rig, keyed[gap], keyed[gap + 1], triangles, diagonal)
                                         for y in (x, pair))
        assert against == 0 and off <= pair_off, (gap, factor)
        assert np.abs(x[still] - rest[still]).max() < 1e-6 * diagonal


def test_a_limb_bent_past_the_limit_follows_the_rig_as_two_poses_do():
    # anchored to the keys' per-vertex spline, the bone turning 100° in the first gap was pulled
    # onto the chord of its arc, 2.1e-2 of the diagonal RMS off the rig half-way where two poses on
    # the same keys are 2.3e-3 off; the gap after it (50°), whose spline reads those keys, 8.0e-3 at
    # its quarter point where two poses are 3.2e-4 off. LBS pinches the joint, which no
    # interpolated metric does: the bounds are the two poses' own, not round-off.
    rest, triangles = _tube()
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    angles = (0.0, 100.0, 150.0)
    still = rest[:, 0] <= 2.0 - 0.6 / 2  # the first bone's vertices: weight 0, never moved by the rig

    def rig(a):
        return _skinned(rest, a[0])

    for gap, factor, x, pair in _sequence_and_pairs([_skinned(rest, a) for a in angles], triangles):
        (off, against), (pair_off, _) = (_off_the_rig(y, rig, angles[gap], angles[gap + 1], triangles, diagonal)
                                         for y in (x, pair))
        assert against == 0
        assert np.abs(x[still] - rest[still]).max() < 1e-6 * diagonal
        if gap == 0:  # past the limit: as near the rig as two poses (to the fit of the rig's angle)
            assert off <= 1.02 * pair_off, factor
        else:
            assert off < 1.5e-3, factor


@pytest.mark.parametrize("k_M", [60, 200])
def test_a_limb_bent_past_the_limit_is_read_from_the_keys_with_a_truncated_metric(k_M):
    # the bent parts are read from the keys' own metric: the truncated recovery's smooths a bone's
    # off the identity (at k_M = 60 no part was read, the first gap 2.1e-2 of the diagonal off the
    # rig half-way where two poses with the same k_M are 2.3e-3 off), and a neighbour's reading
    # was skipped (the 50° gap after the 100° one 8.0e-3 off at its quarter point, 3.2–4.6e-4 for
    # two poses), both unwarned
    rest, triangles = _tube()
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    angles = (0.0, 100.0, 150.0)
    keys = [_skinned(rest, a) for a in angles]
    assert _anchored(keys, triangles, k_M=k_M) == [True, True]

    def rig(a):
        return _skinned(rest, a[0])

    for gap, factor, x, pair in _sequence_and_pairs(keys, triangles, k_M=k_M):
        (off, against), (pair_off, _) = (_off_the_rig(y, rig, angles[gap], angles[gap + 1], triangles, diagonal)
                                         for y in (x, pair))
        assert against == 0
        if gap == 0:
            assert off <= 1.02 * pair_off, factor
        else:
            assert off < 1.5e-3, factor


def test_a_limb_bent_in_a_linear_sequence_follows_the_rig_as_two_poses_do():
    # smooth=False: each gap's spline is its keys' chord, as with only two keys, which the anchor
    # pulled a part bent 40° per key onto (3.4–3.7e-3 of the diagonal off the rig half-way where two
    # poses are 4.7–8.0e-4 off; keyed 20° apart 1.7e-3 against 9.6e-5): anchored as two poses are,
    # at any turn past TWO_KEY_BENT_TURN
    rest, triangles = _tube()
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    angles = (0.0, 40.0, 80.0, 120.0)
    keys = [_skinned(rest, a) for a in angles]
    assert _anchored(keys, triangles, smooth=False) == [True] * 3

    def rig(a):
        return _skinned(rest, a[0])

    for gap, factor, x, pair in _sequence_and_pairs(keys, triangles, smooth=False):
        (off, against), (pair_off, _) = (_off_the_rig(y, rig, angles[gap], angles[gap + 1], triangles, diagonal)
                                         for y in (x, pair))
        assert against == 0 and off <= 1.02 * pair_off, (gap, factor)


@pytest.mark.parametrize("limb", ["two joints", "two joints far", "three joints", "swung at the root"])
def test_remeshed_limbs_bent_past_the_limit_follow_the_rig_no_farther_than_two_poses(limb):
    # limbs re-meshed irregularly (slivers, valences 3–35), skinned on two or three bones bent
    # 90–180° per key (a part from another), one of them also swung about its root: anchored to
    # the keys' spline they came out 1.6–3.6e-2 of the diagonal RMS off the rig's pose at their own
    # joint angles where two poses on the same keys are 0.1–3.5e-2 off (2.6e-2 against 1.7e-3 in
    # the second gap of "two joints far"), with up to 8 triangles facing against it where two poses
    # have none. Gaps that read a piece turning (rotations taken whole, not anchored) are on the rig
    # either way.
    joints, keyed, seed, swing = {
        "two joints": ((1.0, 2.0), [(0, 0), (100, 40), (150, 80)], 2, 0.0),
        "two joints far": ((1.0, 2.0), [(0, 0), (90, 90), (180, 120)], 3, 0.0),
        "three joints": ((0.8, 1.6, 2.4), [(0, 0, 0), (60, 50, 40), (120, 100, 80)], 11, 0.0),
        "swung at the root": ((1.0, 2.0), [(0, 0), (100, 40), (150, 80)], 5, 0.4),
    }[limb]
    rest, triangles = _remeshed_tube(2500, seed)
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))

    def rig(a):  # the bones turned about y at their joints, the whole limb about z by swing × the first
        a = np.asarray(a, float)
        return Rotation.from_euler("z", swing * a[0], degrees=True).apply(_skinned_limb(rest, np.radians(a), joints))

    keys = [rig(a) for a in keyed]
    sequence = SequenceInterpolator(keys, triangles)
    assert all(sequence._gap(gap).bent_turn > BENT_PART_TURN for gap in range(len(sequence)))
    for gap, factor, x, pair in _sequence_and_pairs(keys, triangles):
        (off, against), (pair_off, pair_against) = (_off_the_rig(y, rig, keyed[gap], keyed[gap + 1], triangles,
                                                                 diagonal) for y in (x, pair))
        assert against <= pair_against and off <= pair_off, (gap, factor)


def test_the_turn_read_between_the_rigid_parts_is_the_rigs_joint_angle():
    # the two bones' regions are rigid to single precision: their turn is the joint's to its rounding
    rest, triangles = _tube()
    for bend in (80.0, 100.0, 150.0):
        sequence = SequenceInterpolator([_skinned(rest, a) for a in (0.0, bend)], triangles)
        assert np.degrees(sequence._gap(0).bent_turn) == pytest.approx(bend, abs=1e-3)
    # within the limit no turn is read
    assert SequenceInterpolator([_skinned(rest, a) for a in (0.0, 70.0)], triangles)._gap(0).bent_turn == 0.0


def test_a_bent_limb_turned_whole_as_one_body_is_not_anchored():
    # the keys are one bent pose turned as a rigid body by 100° per key: no part turns from another
    rest, triangles = _tube()
    bent = _skinned(rest, 45.0)
    axis = np.array([0.3, 0.9, 0.3]) / np.linalg.norm([0.3, 0.9, 0.3])
    keys = [Rotation.from_rotvec(np.radians(t) * axis).apply(bent) + [0.5 * t / 100, 0.0, 0.0]
            for t in (0.0, 100.0, 200.0)]
    sequence = SequenceInterpolator(keys, triangles)
    assert np.degrees(sequence._gap(0).bent_turn) < 1e-3
    assert _anchored(keys, triangles) == [False, False]


def test_rigid_pieces_turning_apart_are_not_anchored():
    # two separate tubes (pieces), one held, the other turned 120° per key: each is rigid alone
    rest, triangles = _tube(rings=21)
    held, turned = rest, rest + [0.0, 2.0, 0.0]
    both = np.concatenate([triangles, triangles + len(rest)])
    keys = [np.concatenate([held, Rotation.from_euler("z", a, degrees=True).apply(turned)]) for a in (0.0, 120.0, 240.0)]
    assert _anchored(keys, both) == [False, False]



def test_the_bent_parts_are_read_per_piece():
    # two separate tubes bent at their joints by 100° and 50° between the keys: each piece's own
    # joint angle (the bones are rigid to single precision), not the largest of the mesh
    rest, triangles = _tube(rings=21, length=2.0)
    second = rest + [0.0, 2.0, 0.0]
    both = np.concatenate([triangles, triangles + len(rest)])

    def keys(a, b):
        return np.concatenate([_skinned(rest, a, joint=1.0), _skinned(second, b, joint=1.0)])

    sequence = SequenceInterpolator([keys(0.0, 0.0), keys(100.0, 50.0)], both)
    np.testing.assert_allclose(np.degrees(sequence._bent_turn(0)), [100.0, 50.0], atol=1e-3)


def _tail(angle, shift):
    """A thin tail (:func:`_curled_tube`, radius 0.04, root still) curled ``angle`` degrees at each of
    four joints, moved by ``shift``: its tip turns 4 × ``angle`` from its root, which reads it turning."""
    v, t = _curled_tube(np.radians(np.full(4, angle)), (0.2, 0.4, 0.6, 0.8), 0.1, radius=0.04)
    return v + shift, t


@pytest.mark.parametrize("limb", ["LBS tube", "LBS tube, four keys", "remeshed, two joints", "LBS tube 30° a key"])
def test_a_bent_limb_beside_a_piece_read_turning_follows_the_rig_and_the_other_piece_keeps_its_place(limb):
    # a mesh of two pieces: a limb bent past the limit and a tail curling 40° per key at four joints
    # beside it, which reads turning (its rotations taken whole, not anchored to the keys' spline).
    # The anchoring was decided per mesh: the tail skipped it for the limb too, left on the keys'
    # spline, 2.8e-2 of the diagonal off the rig half-way where two poses are 2.3e-3 off (LBS tube;
    # four keys 4.8e-2 with 2 triangles against the rig, remeshed 3.4e-2 with 7). Now the limb's
    # gaps are anchored and the tail keeps the sequence's gauge: the tail comes out as it does in a
    # sequence of its own (before 1.5–6.5e-5 of its diagonal off that, now within 1e-6). The limb
    # keyed 30° apart is bent past RIGID_BENT_TURN only, its bones rigid to the keys' rounding: the
    # same per-piece rule (before, its gaps were left on the keys' spline beside the tail too)
    angles, tails, shift = {
        "LBS tube": ([(0.0,), (100.0,), (150.0,)], (0.0, 40.0, 80.0), [0.5, 2.0, 0.0]),
        "LBS tube, four keys": ([(0.0,), (120.0,), (150.0,), (40.0,)], (0.0, 40.0, 80.0, 120.0), [0.5, 2.0, 0.0]),
        "remeshed, two joints": ([(0, 0), (90, 90), (180, 120)], (0.0, 40.0, 80.0), [0.0, 1.5, 0.5]),
        "LBS tube 30° a key": ([(0.0,), (30.0,), (60.0,), (90.0,)], (0.0, 40.0, 80.0, 120.0), [0.5, 2.0, 0.0]),
    }[limb]
    if limb.startswith("LBS"):
        rest, triangles = _tube()

        def rig(a):
            return _skinned(rest, a[0])
    else:
        rest, triangles = _remeshed_tube(2500, 3)

        def rig(a):
            return _skinned_limb(rest, np.radians(np.asarray(a, float)), (1.0, 2.0))
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    tail_triangles = _tail(0.0, shift)[1]
    n = len(rest)
    both = np.concatenate([triangles, tail_triangles + n])
    keys = [np.concatenate([rig(a), _tail(t, shift)[0]]) for a, t in zip(angles, tails)]
    tail_keys = [k[n:] for k in keys]
    tail_diagonal = np.linalg.norm(np.ptp(tail_keys[0], axis=0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)  # LBS pinches the joint at 120°: said as for two poses
        sequence = SequenceInterpolator(keys, both)
        alone = SequenceInterpolator(tail_keys, tail_triangles)
        turning = [sequence._gap(gap).turning for gap in range(len(sequence))]
        assert all(t is not None and list(t) == [False, True] for t in turning)  # the tail, not the limb
        assert _anchored(keys, both) == [True] * len(sequence)
        for gap, factor, x, pair in _sequence_and_pairs(keys, both):
            (off, against), (pair_off, pair_against) = (
                _off_the_rig(y[:n], rig, angles[gap], angles[gap + 1], triangles, diagonal) for y in (x, pair))
            # as near the rig as two poses, or (a gap next to the bent one) within 1.5e-3 as the limb alone is
            assert against <= pair_against and (off <= 1.02 * pair_off or off < 1.5e-3), (gap, factor, off, pair_off)
            own = alone.pose(gap, factor)
            assert np.sqrt(np.mean(np.sum((x[n:] - own) ** 2, axis=1))) < 5e-6 * tail_diagonal, (gap, factor)


def test_a_tail_curling_past_a_right_angle_keeps_its_turn():
    # five segments of a thin tail curled 40° per key at each of four joints (each bend over 0.1 of
    # its length, within what its radius allows without the inner side folding): the tip turns 160°
    # per key from the root, and every gap reads the piece turning (its rotations taken whole and
    # continuous across the mesh, placed along its turn), which the anchor leaves as it is: on the rig
    joints, spread, radius = (0.2, 0.4, 0.6, 0.8), 0.1, 0.04
    keyed = [np.full(4, a) for a in (0.0, 40.0, 80.0, 120.0)]

    def rig(a):
        return _curled_tube(np.radians(a), joints, spread, radius=radius)[0]

    rest, triangles = _curled_tube(np.radians(keyed[0]), joints, spread, radius=radius)
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    keys = [rig(a) for a in keyed]
    assert _anchored(keys, triangles) == [False] * 3
    for gap, factor, x, pair in _sequence_and_pairs(keys, triangles, (0.5,)):
        (off, against), (pair_off, _) = (_off_the_rig(y, rig, keyed[gap], keyed[gap + 1], triangles, diagonal)
                                         for y in (x, pair))
        assert off < 1e-3 and off <= pair_off and against == 0


def test_a_limb_bent_between_only_two_keys_follows_the_rig_and_its_still_part_stays_put():
    # two keys' spline is their chord: anchored to it, the turning part was pulled inside its arc
    # (2.7e-2 of the diagonal RMS off the rig half-way); anchored to the blend where the blend keeps
    # the edge lengths, as two poses are, the bone that does not turn holds and the other follows
    # its rotations. The rig's own pose at the in-between's angle is the reference; LBS shortens the
    # joint's ring, which the interpolated metric does not, so the bound is not round-off.
    rest, triangles = _tube()
    diagonal = np.linalg.norm(rest.max(0) - rest.min(0))
    sequence = SequenceInterpolator([_skinned(rest, 0.0), _skinned(rest, 100.0)], triangles)
    still = rest[:, 0] <= 2.0 - 0.6 / 2  # the first bone's vertices: weight 0, never moved by the rig
    for factor in (0.25, 0.5, 0.75):
        with warnings.catch_warnings():  # nothing to say of it
            warnings.simplefilter("error", ShapeDifferenceWarning)
            x = sequence.pose(0, factor)
        off = np.linalg.norm(x - _skinned(rest, 100.0 * factor), axis=1) / diagonal
        assert np.sqrt(np.mean(off ** 2)) < 5e-3 and off.max() < 2.5e-2
        assert np.abs(x[still] - rest[still]).max() < 1e-6 * diagonal


@pytest.mark.parametrize("cores", [1, 8])
def test_a_gaps_in_betweens_do_not_depend_on_the_gaps_asked_before(monkeypatch, own_pool, cores):
    """A limb bent 50° per key reads its neighbouring gaps' bent parts (their relatives of the next
    key, kept by ``SequenceKeys._relatives`` and reused by the gap itself and by the gap after):
    the gaps asked for in reverse, then out of order and again after their data was let go, with
    one core and with eight (the next gap prepared in the background), give the in-betweens of a
    sequence made anew for each gap, to the bit (a kept relative changed in place after it is
    stored fails here)."""
    import core.concurrency as concurrency
    from core import sequence_inbetweens, sequence_keys

    monkeypatch.setattr(concurrency, "available_cores", lambda: cores)
    monkeypatch.setattr(sequence_inbetweens, "CONCURRENT_VERTICES", 0)  # prepared in the background too
    monkeypatch.setattr(sequence_keys, "CONCURRENT_VERTICES", 0)  # relatives built side by side
    rest, triangles = _tube()
    keys = [_skinned(rest, a) for a in (0.0, 50.0, 100.0, 150.0, 100.0, 40.0)]
    factors = [0.25, 0.5, 0.75]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        fresh = [SequenceInterpolator(keys, triangles).poses(gap, factors) for gap in range(len(keys) - 1)]
        sequence = SequenceInterpolator(keys, triangles)
        for gap in (4, 3, 2, 0, 1, 3, 0):
            np.testing.assert_array_equal(sequence.poses(gap, factors), fresh[gap])
    assert len(sequence._forwards) >= 2  # relatives were kept and read back


def _strip_reading(angle: np.ndarray, area: np.ndarray, least: float) -> float:
    """:func:`core.sequence_bent_parts.bent_part_turns` of one piece, a strip of triangles (each sharing
    an edge with the next) turned ``angle`` (m,) about z, of areas ``area`` (m,): isometric where
    turned, stretched where not (no part there)."""
    from core.sequence_bent_parts import bent_part_turns

    m = len(angle)
    rotvec = np.zeros((m, 3))
    rotvec[:, 2] = angle
    metric = np.tile([1.2, 0.0, 1.0], (m, 1))
    metric[np.abs(angle) > 0.0] = (1.0, 0.0, 1.0)
    pairs = np.stack([np.arange(m - 1), np.arange(1, m)], axis=1)
    return float(bent_part_turns(np.zeros(m, dtype=np.int64), pairs, rotvec, metric, area, least)[0])


@pytest.mark.parametrize("least", [BENT_PART_TURN, RIGID_BENT_TURN])
def test_two_parts_turned_apart_past_the_least_turn_are_read_whatever_their_triangles_turn_alone(least):
    """The reading's shortcut (no piece with ``PART_SHARE`` of its area on isometric triangles turned
    ``least / 2 − RIGID_SPREAD`` or more from its rigid turn: nothing read) never drops a pair of parts
    that turn apart past ``least``. Two parts of a strip, each 5.25 % of its area, turned either way
    about one axis: most of each part's area just short of ``least / 2`` from the rigid turn, a ramp
    of small triangles up to one 0.9 ``RIGID_SPREAD`` past it, whose area takes the part's mean turn just
    past ``least / 2`` (under 1 % of the strip is turned ``least / 2`` or more); between them triangles
    that are not isometric. The reading is the angle between the parts' mean turns."""
    from core.sequence_bent_parts import PART_SHARE, RIGID_SPREAD, SAME_TURN

    low, top = 0.5 * least - 1e-3, 0.5 * least + 0.9 * RIGID_SPREAD
    ramp = np.linspace(low, top, 6)[1:]  # steps under SAME_TURN: one region
    assert np.diff(ramp).max() < SAME_TURN
    angles = np.r_[np.full(16, low), ramp]
    areas = np.r_[np.ones(16), np.full(4, 0.01), 1.0]  # the part's area-weighted mean turn just past least / 2
    mean = Rotation.from_rotvec(angles[:, None] * [0.0, 0.0, 1.0]).mean(weights=areas).magnitude()
    assert 0.5 * least < mean < low + RIGID_SPREAD and top - mean < RIGID_SPREAD
    others = int(round(areas.sum() / 0.0525)) - 2 * len(areas)  # each part 5.25 % of the strip's area
    angle = np.r_[-angles[::-1], np.zeros(others), angles]
    area = np.r_[areas[::-1], np.ones(others), areas]
    assert (areas.sum() / area.sum() > PART_SHARE and
            area[np.abs(angle) >= 0.5 * least].sum() < 0.2 * PART_SHARE * area.sum())
    turn = _strip_reading(angle, area, least)
    assert turn > least
    assert turn == pytest.approx(2.0 * mean, abs=1e-6)


@pytest.mark.parametrize("least", [BENT_PART_TURN, RIGID_BENT_TURN])
def test_two_parts_turned_apart_past_the_least_turn_are_read_with_half_their_area_a_spread_short(least):
    """The reading's shortcut takes every triangle of a part within a whole ``RIGID_SPREAD`` of its
    mean turn (a part's mean ``least / 2`` or more from its piece's rigid turn keeps all its area at
    ``least / 2 − RIGID_SPREAD`` or more), not less: a part's triangles may sit up to that far on the
    rigid turn's side of its mean, and half its area can. Two parts of a strip about one axis, their
    means just past ``least / 2`` either way, each PART_SHARE of the strip's area and a thousandth
    more: half of each part's area 0.99 ``RIGID_SPREAD`` short of its mean, the other half 0.999 past
    it, a ramp of tiny triangles between; so under ``PART_SHARE`` of the strip is turned
    ``least / 2 − 0.98 RIGID_SPREAD`` or more, and a bound set there would drop the pair. The reading
    is the angle between the parts' mean turns."""
    from core.sequence_bent_parts import PART_SHARE, RIGID_SPREAD, SAME_TURN

    inner, outer = 0.99 * RIGID_SPREAD, 0.999 * RIGID_SPREAD
    middle = 0.5 * least + 2e-4  # the parts' mean turns, from a rigid turn half-way between them
    ramp = np.linspace(middle - inner, middle + outer, 9)  # steps under SAME_TURN: one region
    assert np.diff(ramp).max() < SAME_TURN
    angles = np.r_[np.full(8, ramp[0]), ramp[1:-1], np.full(8, ramp[-1])]
    # the blocks' areas inversely as their distances from the mean: the mean stays where it was put
    areas = np.r_[np.full(8, outer / (inner + outer)), np.full(7, 1e-4), np.full(8, inner / (inner + outer))]
    mean = Rotation.from_rotvec(angles[:, None] * [0.0, 0.0, 1.0]).mean(weights=areas).magnitude()
    assert 0.5 * least < mean and np.abs(angles - mean).max() < RIGID_SPREAD
    strip = areas.sum() / (PART_SHARE * 1.001)
    others = 40
    angle = np.r_[-angles[::-1], np.zeros(others), angles]
    area = np.r_[areas[::-1], np.full(others, (strip - 2.0 * areas.sum()) / others), areas]
    assert areas.sum() >= PART_SHARE * area.sum()
    assert area[np.abs(angle) >= 0.5 * least - 0.98 * RIGID_SPREAD].sum() < PART_SHARE * area.sum()
    turn = _strip_reading(angle, area, least)
    assert turn > least
    assert turn == pytest.approx(2.0 * mean, abs=1e-6)
