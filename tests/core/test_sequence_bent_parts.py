"""Sequences of a skinned limb whose keys bend it far at a joint (issue 17): the keys' splines cut
the arc its bent part turns along, and the gap warns, from the keys alone. No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import ShapeDifferenceWarning
from core.sequence_bent_parts import BENT_PART_TURN
from core.sequence_inbetweens import SequenceInterpolator

BENT = "a part of a piece turns"


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


def _bent_warnings(keys, triangles) -> dict[tuple[str, str], list[str]]:
    """The bent-part warnings of each gap of the sequence of ``keys``, by the gap's key names."""
    said: dict[tuple[str, str], list[str]] = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        sequence = SequenceInterpolator(keys, triangles)
        for gap in range(len(sequence)):
            sequence.poses(gap, [0.25, 0.5, 0.75])
    for w in caught:
        if BENT in str(w.message):
            assert w.message.kind == "turn"
            said.setdefault(w.message.gap, []).append(str(w.message))
    return said


def test_a_limb_bent_past_the_limit_between_two_keys_is_warned_in_that_gap_alone():
    rest, triangles = _tube()
    said = _bent_warnings([_skinned(rest, a) for a in (0.0, 100.0, 150.0)], triangles)
    assert list(said) == [("key pose 0", "key pose 1")]  # 100° there, 50° in the second gap
    (message,) = said[("key pose 0", "key pose 1")]
    assert "turns 100° from another part" in message and "at most about 75° between two of them" in message
    # what to do in the user's terms, the method's words last in brackets (docs/errors.md)
    advice, _, method = message.partition(" [")
    assert advice.endswith("add keys so that a bending part turns at most about 75° between two of them")
    assert method.endswith("splines cut the arc of a part turning past that].") and "(" not in method


def test_the_turn_read_between_the_rigid_parts_is_the_rigs_joint_angle():
    # the two bones' regions are rigid to single precision: their turn is the joint's to its rounding
    rest, triangles = _tube()
    for bend in (80.0, 100.0, 150.0):
        sequence = SequenceInterpolator([_skinned(rest, a) for a in (0.0, bend)], triangles)
        assert np.degrees(sequence._gap(0).bent_turn) == pytest.approx(bend, abs=1e-3)
    # within the limit no turn is read (nothing to warn of)
    assert SequenceInterpolator([_skinned(rest, a) for a in (0.0, 70.0)], triangles)._gap(0).bent_turn == 0.0


def test_a_limb_keyed_within_the_limit_is_not_warned():
    rest, triangles = _tube()
    assert _bent_warnings([_skinned(rest, a) for a in (0.0, 60.0, 120.0)], triangles) == {}
    assert np.degrees(BENT_PART_TURN) > 60.0


def test_a_bent_limb_turned_whole_as_one_body_is_not_warned():
    # the keys are one bent pose turned as a rigid body by 100° per key: exact, nothing to warn of
    rest, triangles = _tube()
    bent = _skinned(rest, 45.0)
    axis = np.array([0.3, 0.9, 0.3]) / np.linalg.norm([0.3, 0.9, 0.3])
    keys = [Rotation.from_rotvec(np.radians(t) * axis).apply(bent) + [0.5 * t / 100, 0.0, 0.0]
            for t in (0.0, 100.0, 200.0)]
    assert _bent_warnings(keys, triangles) == {}
    sequence = SequenceInterpolator(keys, triangles)
    assert np.degrees(sequence._gap(0).bent_turn) < 1e-3


def test_rigid_pieces_turning_apart_are_not_warned():
    # two separate tubes (pieces), one held, the other turned 120° per key: each is rigid alone
    rest, triangles = _tube(rings=21)
    held, turned = rest, rest + [0.0, 2.0, 0.0]
    both = np.concatenate([triangles, triangles + len(rest)])
    keys = [np.concatenate([held, Rotation.from_euler("z", a, degrees=True).apply(turned)]) for a in (0.0, 120.0, 240.0)]
    assert _bent_warnings(keys, both) == {}


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
        with warnings.catch_warnings():  # past 75° the gap warns as any gap does (tested above)
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            x = sequence.pose(0, factor)
        off = np.linalg.norm(x - _skinned(rest, 100.0 * factor), axis=1) / diagonal
        assert np.sqrt(np.mean(off ** 2)) < 5e-3 and off.max() < 2.5e-2
        assert np.abs(x[still] - rest[still]).max() < 1e-6 * diagonal
