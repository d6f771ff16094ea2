"""Rigid pieces that move as one body in every key stay one body in between, however far apart
their vertices (issue 17 item 3, core.rigid_bodies): a low-poly prop of several pieces on a finely
meshed deforming body. No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.rigid_alignment import rigid_alignment
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator

from meshes import cube, grid
from placement_helpers import _screw

#: A closed box of 8 vertices, 0.06 across, standing on the origin.
BOX = np.array([[x, y, z] for x in (-0.03, 0.03) for y in (-0.03, 0.03) for z in (0.0, 0.06)])
BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def _boxes(at) -> tuple[np.ndarray, np.ndarray]:
    """Boxes (:data:`BOX`) standing at the points ``at`` (k, 3): vertices (8k, 3), triangles (12k, 3)."""
    return (np.vstack([BOX + point for point in np.asarray(at, dtype=float)]),
            np.vstack([BOX_FACES + 8 * k for k in range(len(at))]))


def _arm(angle: float, length: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A strip 2 long along x (81 × 5 vertices, mean edge 0.03) curled about y into an arc of
    ``angle`` (radians) from its fixed end: it bends along its whole length, no part rigid."""
    flat, tri = grid(81, 5, size=length)
    out = flat.copy()
    if angle:
        radius = length / angle
        out[:, 0] = radius * np.sin(flat[:, 0] / radius)
        out[:, 2] = radius * (1.0 - np.cos(flat[:, 0] / radius))
    return out, tri


def _arm_holding_a_prop(angle: float, heights=(0.02, 0.02, 0.02)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arm (:func:`_arm`) curled by ``angle`` with a prop of three separate boxes lying on it
    0.25 apart along it (about 6 mean edges between their nearest corners: not jointed), the three
    moved together by the best rigid motion of the arm's patch under the middle one: one rigid body
    in every key, each box sitting on a different part of the bending arm (or ``heights`` above
    it: 0.3 is beyond the reach of a box's seat). Vertices, triangles and the prop's vertices."""
    straight, tri = _arm(0.0)
    x = _arm(angle)[0]
    patch = np.flatnonzero(np.abs(straight[:, 0] - 1.65) < 0.06)
    rotation, translation = rigid_alignment(straight[patch], x[patch])
    boxes, faces = _boxes([(at, 0.0, height) for at, height in zip((1.4, 1.65, 1.9), heights)])
    prop = len(x) + np.arange(len(boxes))
    return np.vstack([x, boxes @ rotation.T + translation]), np.vstack([tri, faces + len(x)]), prop


def _parting(rest: np.ndarray, pose: np.ndarray, rows: np.ndarray) -> float:
    """How far (÷ the rest pose's diagonal) the vertices ``rows`` of ``pose`` are from one rigid
    motion of their places in ``rest``: their largest distance from their best rigid fit."""
    rotation, translation = rigid_alignment(rest[rows], pose[rows])
    return float(np.abs(rest[rows] @ rotation.T + translation - pose[rows]).max() / np.linalg.norm(np.ptp(rest, axis=0)))


@pytest.mark.parametrize(("heights", "tolerance"), [((0.02, 0.02, 0.02), 1e-12), ((0.02, 0.3, 0.3), 1e-6)])
def test_a_prop_of_separate_pieces_far_apart_stays_one_body_on_a_bending_arm(heights, tolerance):
    """The three boxes of the prop, one rigid body in every key but each on its own part of the
    bending arm and farther apart than the arm's edges: every in-between keeps their relative
    placement — two poses (0° → 100°) at 0.25, 0.5, 0.75 and ×1.5, ×2; a sequence (0°, 30°, 70°,
    110°, 140°) at eighths of every gap and ×1.5. All three on the arm, the body is carried by
    their seats together, one rigid motion placing them: to round-off (each on its own seat, they
    parted by up to 8.4e-4 of the diagonal in-between, 7.7e-3 at ×1.5). Two lifted off it, the body keeps its one motion and
    its pieces' fits place them: to the 1e-6 a rigid motion is kept to (2.2e-8 in the sequence's end
    gaps, round-off elsewhere; the first box on its seat, the others on their screws: 0.11)."""
    rest, tri, prop = _arm_holding_a_prop(0.0, heights)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # placement is what is checked here
        pair = Interpolator(rest, _arm_holding_a_prop(np.radians(100.0), heights)[0], tri)
        poses = [pair.pose(s) for s in (0.25, 0.5, 0.75, 1.5, 2.0)]
        sequence = SequenceInterpolator([_arm_holding_a_prop(np.radians(d), heights)[0]
                                         for d in (0, 30, 70, 110, 140)], tri)
        for gap in range(len(sequence)):
            poses += list(sequence.poses(gap, list(np.arange(1, 8) / 8) + [1.5]))
    assert max(_parting(rest, x, prop) for x in poses) < tolerance


def test_pieces_together_in_the_gaps_keys_but_apart_in_the_keys_around_it_are_not_one_body():
    """Two boxes 1.0 apart turning 20° a key about an axis beside them, the second 0.1 nearer the
    first in the keys before and after a gap than in the gap's own two: one rigid body in those two
    keys alone, not in the motion the gap's splines read. Half-way through the gap the second box
    keeps its own spline (its offset from the first, in the first's frame, 0.1 / 8 beyond the
    keys' by Catmull–Rom), where one body would hold the keys' offset."""
    boxes, tri = _boxes([(1.0, 0.0, 0.0), (2.0, 0.0, 0.0)])
    first, second = np.arange(8), 8 + np.arange(8)
    keys = []
    for k, closer in enumerate((0.1, 0.0, 0.0, 0.1)):
        x = boxes.copy()
        x[second, 0] -= closer
        angle = np.radians(20.0 * k)
        turn = np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
        keys.append(x @ turn.T + [0.0, 0.0, 0.1 * k])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        half = SequenceInterpolator(keys, tri).poses(1, [0.5])[0]
    rotation, translation = rigid_alignment(keys[1][first], half[first])
    offset = ((half[second] - translation) @ rotation).mean(axis=0) - keys[1][first].mean(axis=0)
    assert max(_parting(keys[1], half, rows) for rows in (first, second)) < 1e-9  # each box rigid
    keys_offset = keys[1][second].mean(axis=0) - keys[1][first].mean(axis=0)
    assert np.linalg.norm(offset - keys_offset) > 0.1 / 16  # the spline's 0.0125 off the keys' offset


@pytest.mark.parametrize("factor", [0.25, 0.5, 1.5])
def test_a_whole_mesh_of_far_pieces_turned_rigidly_stays_exact_and_still_pieces_stay_still(factor):
    """Four boxes far apart: two still in both poses, two turned 60° with the rest of nothing about
    a general axis (one rigid body). The still ones stay exactly where they are, the turned ones
    follow the screw motion to 1e-6 of the diagonal; turned all four, the whole mesh does."""
    boxes, tri = _boxes([(0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (0.0, 2.0, 0.5), (2.0, 2.0, 1.0)])
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    angle = np.radians(60.0)
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    rotation = np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * cross @ cross
    translation = np.array([0.3, -0.2, 0.5])
    still, turned = np.arange(16), 16 + np.arange(16)
    size = np.linalg.norm(np.ptp(boxes, axis=0))
    moved = boxes.copy()
    moved[turned] = boxes[turned] @ rotation.T + translation
    x = Interpolator(boxes, moved, tri).pose(factor)
    assert np.array_equal(x[still], boxes[still])
    assert np.abs(x[turned] - _screw(boxes[turned], rotation, translation, factor)).max() < 1e-6 * size
    whole = Interpolator(boxes, boxes @ rotation.T + translation, tri).pose(factor)
    assert np.abs(whole - _screw(boxes, rotation, translation, factor)).max() < 1e-6 * size


def _lift(s: float, degrees: float) -> tuple[np.ndarray, np.ndarray]:
    """Four boxes (:func:`meshes.cube` of 26 vertices, 0.3 thick, each a separate piece): a still
    base along x ∈ [0, 1]; a link along [1, 2] hinged on it at x = 1 about y (through the middle
    of the faces that meet there), turned by ``s`` × ``degrees``; a carriage along [2, 2.6] hinged
    at the link's end and kept level (turned back as much, so it only translates, along the
    hinge's arc); and a plate 0.45 above the carriage (about two mean edges: no contact), moved with it,
    a scissor lift's platform as two separate pieces. The mechanism at ``s``: vertices, triangles."""
    box, box_triangles = cube(2)
    spans = [((0.0, 1.0), (-0.15, 0.15)), ((1.0, 2.0), (-0.15, 0.15)), ((2.0, 2.6), (-0.15, 0.15)),
             ((2.0, 2.6), (0.6, 0.9))]
    turn = Rotation.from_rotvec([0.0, -s * np.radians(degrees), 0.0])
    carried = turn.apply([1.0, 0.0, 0.0]) - [1.0, 0.0, 0.0]  # the link's end, from where it was
    parts = []
    for k, ((low, high), (bottom, top)) in enumerate(spans):
        x = (box + 1.0) / 2.0 * [high - low, 0.3, top - bottom] + [low, -0.15, bottom]
        parts.append(turn.apply(x - [1.0, 0.0, 0.0]) + [1.0, 0.0, 0.0] if k == 1 else x + carried * (k > 1))
    return np.vstack(parts), np.vstack([box_triangles + k * len(box) for k in range(len(spans))])


@pytest.mark.parametrize("degrees", [60.0, 100.0])
def test_a_plate_moving_as_one_with_a_jointed_carriage_follows_the_joints(degrees):
    """The carriage and plate of :func:`_lift` move as one body that only translates, and the
    carriage hangs from the link: between the keys it goes round the hinge's arc, not along the
    chord. Every in-between and exaggeration of two poses (×−0.5 … ×2) and of a sequence keyed
    every third of ``degrees`` (start from the keys' speed) is the mechanism at that time, plate
    included, to 1e-6 of the diagonal. On its own translation the plate left the carriage by 4.1e-2
    of the diagonal at 0.5 and 0.31 at ×2 between two poses 60° apart, by 2.3e-4–3.0e-3 in the
    sequence's gaps, silently."""
    rest, tri = _lift(0.0, degrees)
    size = np.linalg.norm(np.ptp(rest, axis=0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # placement is what is checked here
        pair = Interpolator(rest, _lift(1.0, degrees)[0], tri)
        for s in (-0.5, 0.25, 0.5, 0.75, 1.5, 2.0):
            assert np.abs(pair.pose(s) - _lift(s, degrees)[0]).max() < 1e-6 * size, s
        sequence = SequenceInterpolator([_lift(k / 3.0, degrees)[0] for k in range(5)], tri, start="keys")
        for gap in range(len(sequence)):
            for f, x in zip((0.25, 0.5, 0.75), sequence.poses(gap, [0.25, 0.5, 0.75])):
                assert np.abs(x - _lift((gap + f) / 3.0, degrees)[0]).max() < 1e-6 * size, (gap, f)
