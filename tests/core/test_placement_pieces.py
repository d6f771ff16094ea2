"""A mesh of several pieces in in-betweens and exaggerations (issue 17 item 3, issue 19 item 1):
pieces that move as one stay together, rigid pieces stay on the pieces that carry them
(core.inbetween_carried), pieces that move on their own are not carried, mirrored pieces are
warned. No bpy."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm, logm
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

import core.inbetween_anchor as anchor
from core.errors import ShapeDifferenceWarning
from core.rigid_alignment import rigid_alignment
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator

from meshes import grid, icosphere
from placement_helpers import FACTORS, HALF_TURN_UNTOLD, _arm, _head_with_eyes, _rigid, _screw


@pytest.mark.parametrize("factor", [0.5, 2.0])
def test_eyes_stay_in_their_sockets_when_the_head_turns(factor):
    """Head and eyes turned together by 60° about the neck: at 0.5 and ×2 the distances between
    the pieces are those of the rest pose (the pieces move as one)."""
    a, tri = _head_with_eyes()
    b = _rigid(a, Rotation.from_rotvec([0.0, 0.0, np.radians(60.0)]).as_matrix(), np.array([0.0, 0.0, -1.2]))
    x = Interpolator(a, b, tri).pose(factor)
    n_head = len(icosphere(2)[0])
    for eye in (slice(n_head, n_head + 42), slice(n_head + 42, None)):
        distances = np.linalg.norm(x[eye][:, None] - x[:n_head][None], axis=2)
        rest = np.linalg.norm(a[eye][:, None] - a[:n_head][None], axis=2)
        assert np.abs(distances - rest).max() < 1e-6


def _teeth(count=8, sides=8, radius=0.06, height=0.2):
    """Separate prisms on a half circle of radius 1 about the z axis (teeth on a jaw)."""
    ring = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    ring = np.c_[radius * np.cos(ring), radius * np.sin(ring)]
    j = np.arange(sides)
    k = (j + 1) % sides
    one = np.r_[np.c_[j, k, sides + k], np.c_[j, sides + k, sides + j],
                np.c_[np.full(sides, 2 * sides), k, j], np.c_[np.full(sides, 2 * sides + 1), sides + j, sides + k]]
    vertices, triangles = [], []
    for i, t in enumerate(np.linspace(0.0, np.pi, count)):
        prism = np.r_[np.c_[ring, np.zeros(sides)], np.c_[ring, np.full(sides, height)], [[0, 0, 0], [0, 0, height]]]
        vertices.append(prism + [np.cos(t), np.sin(t), 0.0])
        triangles.append(one + i * (2 * sides + 2))
    return np.vstack(vertices), np.vstack(triangles)


@pytest.mark.parametrize("step", [30.0, 120.0])
def test_separate_pieces_turning_together_about_an_axis_outside_each_turn_rigidly(step):
    """Teeth turning with their jaw at constant speed about its axis, which passes through none of
    them: the in-betweens of a sequence are the turn (before, a group's reach was its largest
    piece's diagonal, the axis lay beyond it and the group followed its centroid's spline instead:
    0.1 of the diagonal off at 120° per key)."""
    a, tri = _teeth()
    turn = lambda degrees: Rotation.from_rotvec(np.radians(degrees) * np.array([0.0, 0.0, 1.0])).as_matrix()
    keys = [a @ turn(k * step).T for k in range(5)]
    seq = SequenceInterpolator(keys, tri, start="keys")
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    for gap in range(len(keys) - 1):
        assert np.abs(seq.pose(gap, 0.5) - a @ turn((gap + 0.5) * step).T).max() < 1e-9 * diagonal


def test_pieces_spun_together_in_single_precision_stay_one_rigid_body():
    """A character's eyes, hat, buckle and sword (separate pieces) spun 270° with hops, keys every
    16 frames stored in float32 (data: the pieces of a probe's rigged character): every in-between
    is one rigid motion of them all (before, motions equal to 1e-7 were grouped by rounding to 6
    decimals, which split them across a boundary: the hat and the sword turned about another point,
    1.5e-2 off at the middle of a gap)."""
    data = np.load(Path(__file__).parent / "data" / "spun_pieces.npz")
    keys, tri = data["keys"].astype(np.float64), data["triangles"]
    seq = SequenceInterpolator(keys, tri, start="rest")
    for gap in range(len(keys) - 1):
        for s in (0.25, 0.5, 0.75):
            x = seq.pose(gap, s)
            rotation, translation = rigid_alignment(keys[0], x)
            assert np.abs(keys[0] @ rotation.T + translation - x).max() < 1e-6


def _arm_with_hand(angle):
    """:func:`_arm` and a hand: a separate sphere at the forearm's end, moved with the forearm's
    end (x > 1.7) rigidly. Returns positions, triangles, the forearm end's vertices and the hand's."""
    straight, tri = _arm(0.0)
    x, _ = _arm(angle)
    hand, hand_tri = icosphere(1, radius=0.12)
    end = np.flatnonzero(straight[:, 0] > 1.7)
    rotation, translation = rigid_alignment(straight[end], x[end])
    hand = (hand + [2.05, 0.0, 0.0]) @ rotation.T + translation
    return np.vstack([x, hand]), np.vstack([tri, hand_tri + len(straight)]), end, len(straight) + np.arange(len(hand))


@pytest.mark.parametrize("factor", [0.5, 2.0])
def test_a_long_piece_held_at_the_forearms_end_stays_on_it(factor):
    """A sword (a separate box 2.0 long, as long as the arm) whose hilt lies on the end of a
    forearm bent by 100°: carried by the forearm's end, whose spread is small against the sword (before, carriers
    had to spread 5 % of the piece's own diagonal: not carried, the sword on its own screw motion,
    as a probe's rigged character's 0.70 sword in its hand, 0.11 from the hand at ×2)."""
    straight, tri = _arm(0.0)
    box = np.array([[x, y, z] for x in (1.8, 3.8) for y in (-0.1, 0.1) for z in (0.01, 0.05)])
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    end = np.flatnonzero(straight[:, 0] > 1.7)

    def posed(angle):
        x = _arm(angle)[0]
        rotation, translation = rigid_alignment(straight[end], x[end])
        return np.vstack([x, box @ rotation.T + translation])

    t = np.vstack([tri, faces + len(straight)])
    a, b = posed(0.0), posed(np.radians(100.0))
    sword = len(straight) + np.arange(len(box))
    assert _hand_off_the_forearm(a, Interpolator(a, b, t).pose(factor), end, sword) < 1e-4


def _hand_off_the_forearm(rest, pose, end, hand):
    """Largest distance (÷ the diagonal) of the ``hand``'s vertices from where the forearm
    ``end``'s best rigid motion from ``rest`` to ``pose`` takes them."""
    rotation, translation = rigid_alignment(rest[end], pose[end])
    return np.abs(pose[hand] - (rest[hand] @ rotation.T + translation)).max() / np.linalg.norm(np.ptp(rest, axis=0))


@pytest.mark.parametrize("factor", [0.25, 0.5, 0.75, 1.5, 2.0])
def test_a_rigid_piece_stays_on_the_bending_piece_that_carries_it(factor):
    """A hand (a separate piece) on a forearm bent by 100° at the elbow: the hand turns with the
    forearm's end at every factor (without carriers, on its own screw motion: 0.37–0.57 % of the
    diagonal off it in-between, 3.9 % at ×2)."""
    a, tri, end, hand = _arm_with_hand(0.0)
    b = _arm_with_hand(np.radians(100.0))[0]
    assert _hand_off_the_forearm(a, Interpolator(a, b, tri).pose(factor), end, hand) < 1e-4


def test_a_rigid_piece_stays_on_its_carrier_in_sequences():
    """The hand on a forearm bending 0° → 20° → 70° → 140° → 170° over five keys: in-betweens of
    every gap keep it on the forearm's end (without carriers its screw motion between two keys
    leaves the forearm's spline path: up to 3.0 % of the diagonal off it; measured 1.45e-3, the
    forearm's end itself bending that much in-between)."""
    keys = [_arm_with_hand(np.radians(d))[0] for d in (0, 20, 70, 140, 170)]
    _, tri, end, hand = _arm_with_hand(0.0)
    seq = SequenceInterpolator(keys, tri)
    for gap in range(len(seq)):
        poses = seq.poses(gap, np.arange(1, 8) / 8)
        assert max(_hand_off_the_forearm(keys[0], x, end, hand) for x in poses) < 2e-3


@pytest.mark.parametrize("factor", [0.25, 0.5, 0.75])
def test_a_small_piece_that_slides_a_little_on_a_far_turning_carrier_stays_on_it(factor):
    """A ring (a separate sphere 0.17 across) on a forearm bending by 100°, slid 0.06 toward the
    elbow between the keys: the forearm's best rigid motion misses it by more than a quarter of
    its diagonal (0.043) but by a fifteenth of its move (0.9), so the forearm carries it and it
    slides along it in-between (before: kept on its own screw motion, a chord under the forearm's
    arc, as a probe's belt buckle on a character's hips turning 91° between keys, its offset from
    the hips 0.065 off against the linear blend's 0.009)."""
    straight, tri = _arm(0.0)
    ring, ring_tri = icosphere(1, radius=0.05)
    ring = ring + [1.6, 0.15, 0.06]
    end = np.flatnonzero(straight[:, 0] > 1.3)
    bent = _arm(np.radians(100.0))[0]
    rotation, translation = rigid_alignment(straight[end], bent[end])
    slide = np.array([-0.06, 0.0, 0.0])  # along the forearm, in its own frame
    a = np.vstack([straight, ring])
    b = np.vstack([bent, (ring + slide) @ rotation.T + translation])
    t = np.vstack([tri, ring_tri + len(straight)])
    rows = len(straight) + np.arange(len(ring))
    x = Interpolator(a, b, t).pose(factor)
    r, shift = rigid_alignment(a[end], x[end])  # the forearm's motion at the factor
    expected = (ring + factor * slide) @ r.T + shift
    assert np.abs(x[rows] - expected).max() / np.linalg.norm(np.ptp(a, axis=0)) < 1e-4


@pytest.mark.parametrize("shift", [0.0, 20.0])
def test_a_rigid_piece_that_moves_on_its_own_is_not_carried(shift):
    """A ball next to the forearm's end that slides sideways while the arm bends (and the whole
    second pose moved by ``shift``): nothing near it moves with it, so it keeps its own rigid
    motion (a translation, linear in the factor) wherever the pose is (a rule allowing a share of
    the ball's own move carried it once the pose was moved 20 away: 1.3e-2 off)."""
    a, tri, end, hand = _arm_with_hand(0.0)
    b = _arm_with_hand(np.radians(100.0))[0]
    b[hand] = a[hand] + [0.0, 0.6, 0.0]
    move = np.array([shift, 0.0, 0.0])
    interpolator = Interpolator(a, b + move, tri)
    for factor in (0.25, 0.5, 1.5):
        np.testing.assert_allclose(interpolator.pose(factor)[hand], a[hand] + factor * (move + [0.0, 0.6, 0.0]),
                                   atol=1e-9 * (1.0 + shift))


def _accordion(n=41, folds=4, angle=np.radians(70.0), strip=0.1):
    """A flat square sheet (side 2) and the same sheet folded like an accordion along x into
    ``folds`` panels at ±``angle``, all but a ``strip`` along one side, which stays flat."""
    flat, tri = grid(n, n, size=2.0)
    x = flat[:, 0] - flat[:, 0].min()
    panel = (2.0 - strip) / folds
    along = np.clip(x - strip, 0.0, None)
    which = np.minimum((along // panel).astype(int), folds - 1)
    folded = flat.copy()
    start = np.zeros(2)
    for k in range(folds):
        direction = np.array([np.cos(angle), np.sin(angle) * (1 if k % 2 == 0 else -1)])
        rows = (which == k) & (x >= strip)
        moved = start + np.outer(along[rows] - k * panel, direction)
        folded[rows, 0], folded[rows, 2] = flat[:, 0].min() + strip + moved[:, 0], moved[:, 1]
        start = start + panel * direction
    return flat, folded, tri


def test_a_piece_the_blend_barely_holds_is_moved_toward_the_blends_centroid(monkeypatch):
    """Two poses of a sheet that folds like an accordion while it moves: the blend keeps edge
    lengths only on a narrow strip (its anchor holds ~4 % of the sheet), from which the
    interpolated rotations would hang the whole sheet (its centroid then 4 % of the diagonal off the
    blend's). The sheet is moved most of the way onto the blend's centroid (measured: 1.5 %; what is
    left is the anchor's share, ``core.inbetween_anchor.CENTROID_ANCHOR_SHARE``), as a whole: its
    shape is the same."""
    a, b, tri = _accordion()
    b = b + np.array([0.5, 0.3, 1.5])
    diagonal = np.linalg.norm(np.ptp(a, axis=0))

    def in_between():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            return Interpolator(a, b, tri).pose(0.5)

    def centroid_offset(x):
        return np.linalg.norm(x.mean(axis=0) - 0.5 * (a + b).mean(axis=0)) / diagonal

    moved = in_between()
    monkeypatch.setattr(anchor, "CENTROID_ANCHOR_SHARE", 1e-12)  # the strip alone places the sheet
    hanging = in_between()
    assert centroid_offset(hanging) > 0.02
    assert centroid_offset(moved) < 0.5 * centroid_offset(hanging)
    np.testing.assert_allclose(np.ptp(moved - hanging, axis=0), 0.0, atol=1e-9 * diagonal)


def test_the_pieces_sizes_are_measured_alike_on_a_turned_scene():
    """The size each piece's tolerances scale with, a box's diagonal from its second moments, is
    the same however the scene is turned: two sheets of unequal sides, a square one and a loose
    vertex, turned by a general rotation and moved off, measure as unturned, and as the sheets' own
    boxes' diagonals. Measured along the world's axes a turned 1.6 × 1 sheet measured 25 % off,
    and a sheet hanging from a rod that stops, turned, decided otherwise which pieces ride rigidly
    (1.016 × the Catmull–Rom spline's error instead of 0.924 ×); along each piece's principal axes a
    square sheet's axes are any in its plane and its diagonal anything from 1 to 1.41 × its own."""
    from core.inbetween_topology import Topology
    from core.mesh_topology import mesh_topology

    flat, tri = grid(11, size=1.0)
    wide = np.c_[1.6 * flat[:, 0], flat[:, 1], 0.05 * np.sin(3.0 * flat[:, 0])]
    tall = np.c_[0.3 * flat[:, 0] + 3.0, 2.0 * flat[:, 1], 0.02 * flat[:, 1] ** 2]
    square = np.c_[flat[:, 0] - 3.0, np.zeros(len(flat)), flat[:, 1]]
    vertices = np.vstack([wide, tall, square, [[-1.0, -1.0, 0.0]]])
    triangles = np.vstack([tri, tri + len(flat), tri + 2 * len(flat)])
    turn, shift = Rotation.from_rotvec([0.3, -0.7, 0.4]), np.array([40.0, -25.0, 10.0])
    sizes = []
    for points in (vertices, turn.apply(vertices) + shift):
        sizes.append(Topology(mesh_topology(triangles, len(points)), points).diagonals(points))
    np.testing.assert_allclose(sizes[1], sizes[0], rtol=1e-12)
    # the lumped masses' second moments on a grid of spacing h: the continuous sheet's to O(h²)
    own = [np.linalg.norm(np.ptp(piece, axis=0)) for piece in (wide, tall, square)]
    np.testing.assert_allclose(sizes[0], own, rtol=2e-2)


def test_a_mesh_of_many_rigid_pieces_moves_each_by_its_screw_motion():
    """100 pieces (debris; more than SLICED_PIECES, so every per-piece step runs on all pieces at
    once), each turned by up to 150° about its own axis and moved: two poses give each piece its
    own screw motion at every factor, and a sequence keeps every piece rigid."""
    rng = np.random.default_rng(8)
    piece, piece_tri = icosphere(0, radius=0.05)
    count = len(piece)
    rest = np.vstack([piece + rng.uniform(-3.0, 3.0, 3) for _ in range(100)])
    tri = np.vstack([piece_tri + k * count for k in range(100)])
    motions = [(Rotation.from_rotvec(rng.normal(size=3) * rng.uniform(0.1, 2.6) / np.sqrt(3)).as_matrix(),
                rng.normal(size=3)) for _ in range(100)]
    moved = np.vstack([rest[k * count:(k + 1) * count] @ r.T + t for k, (r, t) in enumerate(motions)])
    interpolator = Interpolator(rest, moved, tri)
    for factor in (0.3, 0.5, 1.5):
        pose = interpolator.pose(factor)
        expected = np.vstack([_screw(rest[k * count:(k + 1) * count], r, t, factor) for k, (r, t) in enumerate(motions)])
        np.testing.assert_allclose(pose, expected, atol=1e-9)
    keys = [rest, moved, np.vstack([moved[k * count:(k + 1) * count] @ r.T + t for k, (r, t) in enumerate(motions)])]
    edges = np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    lengths = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    sequence = SequenceInterpolator(keys, tri)
    for gap in range(len(sequence)):
        for x in sequence.poses(gap, [0.25, 0.5, 0.75]):
            np.testing.assert_allclose(np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1), lengths, atol=1e-9)


def test_many_rigid_pieces_stay_on_the_bending_sheet_that_carries_them(monkeypatch):
    """80 sequins (rigid quads a little above a sheet; more than SLICED_PIECES, so the seats are
    found for all at once) on a sheet rolled by 90°: every in-between of two poses keeps each
    sequin rigid and on the sheet (its nearest sheet vertex within a grid cell)."""
    rng = np.random.default_rng(9)
    flat, tri = grid(31, 31, size=2.0)
    flat -= [1.0, 1.0, 0.0]  # centred: x, y in −1 … 1

    radius = 2.0 / np.radians(90.0)
    centres = rng.uniform(-0.9, 0.9, (80, 2))
    quad = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * 0.04  # larger than a grid cell (0.067): seated
    height = 0.005

    def sequins(theta):  # each sequin rigidly on the sheet rolled by ``theta`` (its centre's angle)
        turn = np.stack([np.cos(theta), np.zeros_like(theta), np.sin(theta)], axis=1)  # the roll's tangent
        normal = np.stack([-np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=1)
        where = np.stack([radius * np.sin(theta) - 1.0, centres[:, 1], radius * (1 - np.cos(theta))], axis=1)
        return np.vstack([where[k] + height * normal[k] + np.outer(quad[:, 0], turn[k]) + np.outer(quad[:, 1], [0, 1, 0])
                          for k in range(80)])

    theta = (flat[:, 0] + 1.0) / radius
    sheet = np.stack([radius * np.sin(theta) - 1.0, flat[:, 1], radius * (1 - np.cos(theta))], axis=1)
    sequin_tri = np.vstack([np.array([[0, 1, 2], [0, 2, 3]]) + len(flat) + 4 * k for k in range(80)])
    tri_all = np.vstack([tri, sequin_tri])
    a = np.vstack([flat, np.vstack([np.c_[c + quad, np.full(4, height)] for c in centres])])
    interpolator = Interpolator(a, np.vstack([sheet, sequins((centres[:, 0] + 1.0) / radius)]), tri_all)
    edges = np.vstack([sequin_tri[:, [0, 1]], sequin_tri[:, [1, 2]], sequin_tri[:, [2, 0]]])
    lengths = np.linalg.norm(a[edges[:, 0]] - a[edges[:, 1]], axis=1)
    from scipy.spatial import cKDTree

    import core.inbetween_carried as carried
    seats = []
    found = carried.CarriedPieces._seats
    monkeypatch.setattr(carried.CarriedPieces, "_seats", staticmethod(lambda *a: seats.extend(found(*a)) or seats[-80:]))
    for factor in (0.25, 0.5, 0.75):
        x = interpolator.pose(factor)
        np.testing.assert_allclose(np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1), lengths, atol=1e-9)
        distance = cKDTree(x[:len(flat)]).query(x[len(flat):])[0]
        assert distance.max() < height + 0.05, distance.max()  # a grid cell is 0.067 across
    assert seats and all(carriers is not None for carriers, _ in seats)  # every sequin carried by the sheet


def _turned_head(noise=0.0, dtype=np.float64, offset=0.0):
    """:func:`_head_with_eyes` turned 60° about an axis off the mesh (and shifted), with Gaussian
    noise of ``noise`` × the diagonal per coordinate on the eyes only (the head moves exactly
    rigidly), both keys stored in ``dtype`` ``offset`` units from the origin. Returns the keys,
    triangles, the head's vertices (bool), the diagonal and the true pose at a factor."""
    a, tri = _head_with_eyes()
    head = np.arange(len(a)) < len(icosphere(2)[0])
    axis = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3])
    rotation = Rotation.from_rotvec(np.radians(60.0) * axis).as_matrix()
    pivot, shift = np.array([0.4, -1.3, 0.1]), np.array([0.1, 0.2, 0.3])
    b = _rigid(a, rotation, pivot, shift)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    b = b + noise * diagonal * np.random.default_rng(0).standard_normal(b.shape) * (~head)[:, None]

    def truth(s):
        return _screw(a, rotation, shift + pivot - rotation @ pivot, s)

    keys = [(x + offset).astype(dtype) for x in (a, b)]
    return keys, tri, head, diagonal, truth


@pytest.mark.parametrize("factor", [0.5, 2.0])
@pytest.mark.parametrize("case", ["noise 5e-4", "noise 1e-4", "float32 3e4 out"])
def test_pieces_turned_rigidly_with_noise_or_rounding_stay_on_the_turn(case, factor):
    """A head and two eyes turned 60° as one, the eyes with noise (ε = 5e-4 or 1e-4 of the diagonal
    per coordinate), or the whole mesh stored in single precision 3e4 units from the origin (ε:
    half a float32 step there, 2.6e-4 of the diagonal): every vertex within 8 ε × max(1, |factor|)
    of the rigid motion (the keys' own error, combined at the factor and turned), the exactly rigid
    head exact. Before, the eyes' non-rigidity over RIGID_PLACEMENT_SCALE put them on the chord of
    their arc and they carried the head along: 5.4e-2 of the diagonal off at 0.5 and 0.45 at ×2
    (5e-4, float32); with 1e-4 the head hung from an eye in the joint tree, 3e-5 off."""
    far = case.startswith("float32")
    offset = 3e4 if far else 0.0
    keys, tri, head, diagonal, truth = _turned_head(0.0 if far else float(case.split()[1]),
                                                    np.float32 if far else np.float64, offset)
    epsilon = float(np.spacing(np.float32(offset + 3.0))) / 2 / diagonal if far else float(case.split()[1])
    x = Interpolator(*keys, tri).pose(factor) - offset
    error = np.linalg.norm(x - truth(factor), axis=1) / diagonal
    assert error.max() < 8 * epsilon * max(1.0, abs(factor)), error.max()
    if not far:
        assert error[head].max() < 1e-6, error[head].max()


@pytest.mark.parametrize("sigma", [1e-3, 2e-3])
def test_a_noisy_piece_turned_rigidly_follows_its_screw_motion(sigma):
    """One sphere turned 60° about an axis outside it, its second key with noise σ of the diagonal
    per coordinate: within 8 σ × max(1, |factor|) of the screw motion (before, with σ = 1e-3,
    non-rigidity over RIGID_PLACEMENT_SCALE put it on the chord of its arc: 4.1e-2 of the diagonal
    off at 0.5, 0.30 at ×2)."""
    a, tri = icosphere(2)
    axis = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3])
    rotation = Rotation.from_rotvec(np.radians(60.0) * axis).as_matrix()
    pivot, shift = np.array([0.4, -1.3, 0.1]), np.array([0.1, 0.2, 0.3])
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    b = _rigid(a, rotation, pivot, shift) + sigma * diagonal * np.random.default_rng(0).standard_normal(a.shape)
    interpolator = Interpolator(a, b, tri)
    for factor in (0.5, 2.0):
        truth = _screw(a, rotation, shift + pivot - rotation @ pivot, factor)
        error = np.linalg.norm(interpolator.pose(factor) - truth, axis=1).max() / diagonal
        assert error < 8 * sigma * max(1.0, factor), (factor, error)


@pytest.mark.parametrize("scale", [1.02, 1.2])
def test_pieces_turned_and_scaled_as_one_stay_together(scale):
    """A head and two eyes turned 60° about an axis off the mesh and scaled uniformly as one
    (similarity S): the eyes stay in their sockets, their centroids' offsets from the head's those
    of ``exp(s log S)`` to 1e-3 of the diagonal in-between (what is left is the size of each piece,
    from the interpolated metric), and every extrapolation is ``exp(s log S)`` to 1e-6. Before,
    each piece went along its own centroid's chord: 2e-2 of the diagonal out of its socket at 0.5,
    0.15–0.18 at ×2."""
    a, tri = _head_with_eyes()
    sizes = [len(icosphere(2)[0]), len(icosphere(1)[0]), len(icosphere(1)[0])]
    piece = np.repeat([0, 1, 2], sizes)
    axis = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3])
    rotation = Rotation.from_rotvec(np.radians(60.0) * axis).as_matrix()
    pivot = np.array([0.4, -1.3, 0.1])
    similarity = np.eye(4)
    similarity[:3, :3], similarity[:3, 3] = scale * rotation, scale * (pivot - rotation @ pivot)
    b = a @ similarity[:3, :3].T + similarity[:3, 3]
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, b, tri)
    for factor in (0.25, 0.5, 0.75, 2.0, -0.5):
        power = np.real(expm(factor * logm(similarity)))
        truth = a @ power[:3, :3].T + power[:3, 3]
        x = interpolator.pose(factor)
        for eye in (1, 2):
            off = (x[piece == eye].mean(0) - x[piece == 0].mean(0)) - (truth[piece == eye].mean(0) - truth[piece == 0].mean(0))
            assert np.linalg.norm(off) < 1e-3 * diagonal, (factor, eye, np.linalg.norm(off) / diagonal)
        if not 0.0 < factor < 1.0:
            assert np.abs(x - truth).max() < 1e-6 * diagonal, (factor, np.abs(x - truth).max() / diagonal)


def _blinking_head_turned(bulge: float = 0.0):
    """The head with eyes of :func:`_head_with_eyes` (``a``, ``tri``) and a pose ``b`` of it: the
    eyes squashed to 0.6 of their height about their centres (a blink), the back of the head
    bulged out by ``bulge`` of its radius, all turned 60° about a tilted axis through ``pivot``;
    with the head's and an eye's vertex counts and that ``rotation`` (3, 3)."""
    a, tri = _head_with_eyes()
    n_head, n_eye = len(icosphere(2)[0]), len(icosphere(1)[0])
    posed = a.copy()
    back = np.exp(-np.sum((a[:n_head] - [0.0, -1.0, 0.0]) ** 2, axis=1) / 0.3)
    posed[:n_head] += bulge * back[:, None] * a[:n_head]
    for k, centre in enumerate(((0.35, 0.85, 0.3), (-0.35, 0.85, 0.3))):
        rows = slice(n_head + k * n_eye, n_head + (k + 1) * n_eye)
        posed[rows] = (a[rows] - centre) * [1.0, 0.6, 1.0] + centre
    axis = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3])
    rotation = Rotation.from_rotvec(np.radians(60.0) * axis).as_matrix()
    pivot = np.array([0.4, -1.3, 0.1])
    return a, tri, _rigid(posed, rotation, pivot), n_head, n_eye, rotation, pivot


@pytest.mark.parametrize("factor", [0.5, 2.0])
def test_a_rigid_head_with_deforming_eyes_turns_rigidly_and_keeps_them(factor):
    """A head turned 60° rigidly while its eyes (separate pieces) squash to 0.6 of their height
    about their centres (a blink): the head is exactly its rigid motion — the small deforming
    eyes do not carry it (before: 4.3e-2 of the diagonal off at 0.5, 0.33 at ×2) — and the eyes'
    centroids follow the head's motion, whose seat they are in (before, on their chords: 2.4e-2 /
    4.6e-2 out of their sockets at 0.5)."""
    a, tri, b, n_head, n_eye, rotation, pivot = _blinking_head_turned()
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    x = Interpolator(a, b, tri).pose(factor)
    truth = _screw(a, rotation, pivot - rotation @ pivot, factor)
    assert np.abs(x[:n_head] - truth[:n_head]).max() < 1e-6 * diagonal
    for k in range(2):
        rows = slice(n_head + k * n_eye, n_head + (k + 1) * n_eye)
        assert np.linalg.norm(x[rows].mean(0) - truth[rows].mean(0)) < 1e-3 * diagonal


def test_the_seats_of_a_sequence_are_searched_once_per_set_of_rigid_pieces(monkeypatch):
    """A head turning rigidly 20° per key about a tilted axis while its eyes (separate pieces)
    close a little more at every key: in every gap the head is rigid and the eyes deform. Where a
    deforming piece may sit on a rigid one is read in the first pose (the rigid pieces' vertices
    nearest each of its vertices), so the search runs once for the sequence, not once per gap (one
    sheet lying apart over another: 110–150 ms at 5k vertices, in each gap where one was still),
    and a gap's poses are those of a sequence asked for that gap alone."""
    import scipy.spatial

    a, tri = _head_with_eyes()
    n_head, n_eye = len(icosphere(2)[0]), len(icosphere(1)[0])
    axis = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3])
    pivot = np.array([0.4, -1.3, 0.1])
    keys = []
    for k in range(4):
        posed = a.copy()
        for e, centre in enumerate(((0.35, 0.85, 0.3), (-0.35, 0.85, 0.3))):
            rows = slice(n_head + e * n_eye, n_head + (e + 1) * n_eye)
            posed[rows] = (a[rows] - centre) * [1.0, 1.0 - 0.12 * k, 1.0] + centre
        keys.append(_rigid(posed, Rotation.from_rotvec(np.radians(20.0 * k) * axis).as_matrix(), pivot))
    built = []  # the vertex counts of the k-d trees built

    class Counted(scipy.spatial.cKDTree):
        def __init__(self, data, *args, **kwargs):
            built.append(len(data))
            super().__init__(data, *args, **kwargs)

    monkeypatch.setattr(scipy.spatial, "cKDTree", Counted)
    factors = [0.25, 0.5, 0.75]
    sequence = SequenceInterpolator(keys, tri)
    poses = [sequence.poses(gap, factors) for gap in range(len(sequence))]
    assert built.count(n_head) == 1, built  # over the head's vertices (the rigid piece's), once
    for gap, made in enumerate(poses):
        np.testing.assert_array_equal(made, SequenceInterpolator(keys, tri).poses(gap, factors))


@pytest.mark.parametrize("factor", [0.25, 0.5, 2.0, -0.5])
def test_deforming_eyes_ride_in_the_sockets_of_a_deforming_head(factor):
    """A head turned 60° whose back bulges out (its best rigid motion misses it by 1.6 % of its
    diagonal: it deforms, and no rigid piece seats the eyes) while its eyes squash to 0.6 of their
    height about their centres: the front of the head only turns, and the eyes' centroids follow
    it — each within the largest error of the head's front (the seat, whose best similarity
    places them). Before, on their chords: 3.5e-2 / 4.6e-2 of the diagonal off the turn at 0.25 /
    0.5, 0.35 at ×2 and 0.14 at −0.5, with the front within 3e-3."""
    a, tri, b, n_head, n_eye, rotation, pivot = _blinking_head_turned(bulge=0.3)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    x = Interpolator(a, b, tri).pose(factor)
    truth = _screw(a, rotation, pivot - rotation @ pivot, factor)  # the eyes' centroids and the front
    front = np.flatnonzero(a[:n_head, 1] > 0.5)
    seat_error = np.linalg.norm(x[front] - truth[front], axis=1).max()
    assert seat_error < 5e-3 * diagonal
    for k in range(2):
        rows = slice(n_head + k * n_eye, n_head + (k + 1) * n_eye)
        assert np.linalg.norm(x[rows].mean(0) - truth[rows].mean(0)) <= seat_error


@pytest.mark.parametrize("factor", [0.5, 2.0])
def test_a_skinned_jaw_rides_with_its_rigid_teeth(factor):
    """A head whose jaw opens 25° about a hinge by linear blend skinning (the weight ramps over
    0.2 below the mouth) with a tooth (a separate piece) rigid on the jaw bone, two poses: the skin
    the bone moves rigidly with the tooth is held on their common rigid motion and the tooth keeps
    its own screw with it, so that both are the rig's at every factor (to 1e-6 of the diagonal, as
    rigid pieces' extrapolations; the whole pose 2.5e-4 / 5.2e-3 RMS off at 0.5 / ×2, the slider
    2.1e-3 / 1.6e-2). Before, the skin followed fields that turned the whole jaw and the tooth
    was carried by it: 2.0e-2 / 0.19 of the diagonal off at 0.5 / ×2 (RMS 4.1e-3 / 4.8e-2)."""
    head, tri = icosphere(3)
    tooth, tooth_tri = icosphere(1, radius=0.05)
    a = np.vstack([head, tooth + [0.0, 0.8, -0.55]])
    tri = np.vstack([tri, tooth_tri + len(head)])
    weight = np.clip((-a[:, 2] - 0.3) / 0.2, 0.0, 1.0) ** 2 * (3.0 - 2.0 * np.clip((-a[:, 2] - 0.3) / 0.2, 0.0, 1.0))
    weight = weight * (a[:, 1] > 0.2)
    weight[len(head):] = 1.0
    hinge = np.array([0.0, 0.0, -0.3])

    def rig(s):
        turn = Rotation.from_rotvec([np.radians(-25.0) * s, 0.0, 0.0]).as_matrix()
        return a + weight[:, None] * ((a - hinge) @ turn.T + hinge - a)

    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    if factor > 1.0:  # the rig itself turns 32 triangles of the crease over at ×2 and stretches it: said
        with pytest.warns(ShapeDifferenceWarning, match="as long as in either pose"), \
                pytest.warns(ShapeDifferenceWarning, match="flipped or collapsed"):
            x = Interpolator(a, rig(1.0), tri).pose(factor)
    else:
        x = Interpolator(a, rig(1.0), tri).pose(factor)
    on_bone = weight == 1.0
    assert on_bone[:len(head)].sum() > 6 and on_bone[len(head):].all()
    error = np.linalg.norm(x[on_bone] - rig(factor)[on_bone], axis=1).max() / diagonal
    assert error < 1e-6, error


@pytest.mark.parametrize("degrees", [60.0, 170.0])
def test_a_piece_moving_on_its_own_by_a_seat_spinning_about_it_is_not_carried(degrees):
    """A rigid ball above the middle of a rippling sheet that spins about the axis through the ball:
    the ball only translates 0.6 (1.4 of its diagonal), on its own; the sheet's turn barely moves
    it, so nothing carries it: it stays on its straight path at every factor. An allowance growing
    with the seat's turn alone carried it along the sheet's arc (0.66 of its diagonal off at 0.5
    for 170°)."""
    sheet, tri = grid(31, 31, size=2.0)
    sheet = sheet - np.array([1.0, 1.0, 0.0])
    ball, ball_triangles = icosphere(1, radius=0.12)
    ball = ball + np.array([0.0, 0.0, 0.15])
    rippled = sheet.copy()
    rippled[:, 2] = 0.04 * np.sin(3 * sheet[:, 0]) * np.cos(2 * sheet[:, 1])
    spun = rippled @ Rotation.from_rotvec(np.radians(degrees) * np.array([0.0, 0.0, 1.0])).as_matrix().T
    move = np.array([0.6, 0.0, 0.0])
    a, b = np.vstack([sheet, ball]), np.vstack([spun, ball + move])
    interpolator = Interpolator(a, b, np.vstack([tri, ball_triangles + len(sheet)]))
    for s in (0.25, 0.5, 1.5):
        np.testing.assert_allclose(interpolator.pose(s)[len(sheet):], ball + s * move, atol=1e-6)


def _tetrahedra(count=3, seed=1):
    """``count`` separate regular tetrahedra (closed pieces) scattered in a box of side 4."""
    one = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]]) * 0.3
    faces = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    centres = np.random.default_rng(seed).uniform(-2.0, 2.0, (count, 3))
    return np.vstack([one + c for c in centres]), np.vstack([faces + 4 * k for k in range(count)])


@pytest.mark.parametrize("sequence", [False, True])
def test_pieces_mirrored_between_keys_are_warned(sequence):
    """Closed pieces (tetrahedra) whose next key is their mirror image (a negative scale): no motion
    makes it, and the in-betweens flatten them (at 0.5 each tetrahedron has no volume, its edges
    18 % off): a warning names the reflection. Before, none (the mirrored tetrahedra were
    interpolated silently). Their rigid motion, and a flat piece turned over (its mirror image is
    that half turn), are not warned."""
    a, tri = _tetrahedra()
    mirror = np.diag([-1.0, 1.0, 1.0])
    flat = np.array([[3.0, 0.0, 0.0], [4.0, 0.0, 0.0], [3.0, 1.0, 0.0]])
    turn = Rotation.from_rotvec([0.3, 0.9, 0.2]).as_matrix()

    def warned(b, vertices=a, triangles=tri):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            if sequence:
                SequenceInterpolator([vertices, b, b + 0.1], triangles)
            else:
                Interpolator(vertices, b, triangles)
        return [str(w.message) for w in caught if issubclass(w.category, ShapeDifferenceWarning)
                and "mirror image" in str(w.message)]

    said = warned(a @ mirror.T)
    assert len(said) == 1 and "3 piece(s)" in said[0], said
    one, faces = a[:4] - a[:4].mean(axis=0), tri[:4]
    with warnings.catch_warnings(record=True) as caught:  # mirrored about its centroid, which stays
        warnings.simplefilter("always")
        Interpolator(one, one @ mirror.T, faces).pose(0.5)
    said = [str(w.message) for w in caught]
    assert [(w.category, w.message.kind) for w in caught if "mirror image" in str(w.message)] == \
        [(ShapeDifferenceWarning, "mirror")], said
    # its best rigid fit is a half turn to within rounding, said as such or not by the BLAS kernel's rounding
    assert all("mirror image" in m or re.search(HALF_TURN_UNTOLD, m) for m in said), said
    assert not warned(a @ turn.T + 0.5)
    assert not warned(flat @ mirror.T, flat, np.array([[0, 1, 2]]))


def test_sliver_pieces_moved_rigidly_move_by_that_motion():
    """Forty single-triangle pieces, each a sliver 1e-7 across for a length of 1 (the mesh check
    accepts down to 1e-10), turned 60° together about an axis off them: every factor is that
    motion to 1e-6 of the diagonal. Kabsch resolved each sliver's turn about its long side only to
    ε × (length / width)²: each piece went on a screw of its own, 2.2e-4 / 2.0e-3 of the diagonal
    off at 0.5 / ×2."""
    rng = np.random.default_rng(0)
    vertices = []
    for _ in range(40):
        c, d = rng.uniform(-2.0, 2.0, 3), rng.standard_normal(3)
        d /= np.linalg.norm(d)
        side = np.cross(d, rng.standard_normal(3))
        side /= np.linalg.norm(side)
        vertices += [c, c + d, c + 0.4 * d + 1e-7 * side]
    a, tri = np.array(vertices), np.arange(120).reshape(40, 3)
    axis = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])
    pivot = np.array([0.5, -1.5, 0.2])
    b = _rigid(a, Rotation.from_rotvec(np.radians(60.0) * axis).as_matrix(), pivot)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, b, tri)
    for s in FACTORS:
        truth = _rigid(a, Rotation.from_rotvec(s * np.radians(60.0) * axis).as_matrix(), pivot)
        assert np.abs(interpolator.pose(s) - truth).max() < 1e-6 * diagonal, s


def _head_turned_with_an_eye_shrinking(scale: float, in_first: bool = False, pivot=(0.4, -1.3, 0.1)):
    """The head with eyes of :func:`_head_with_eyes` turned 30° rigidly about a tilted axis through
    ``pivot`` while its first eye shrinks to ``scale`` of its size about its centre (in the second
    pose, or with ``in_first`` in the first); returns ``a``, ``tri``, ``b``, the truth ``x ↦`` its
    rigid motion at a factor, and the rows of the head and of each eye."""
    a, tri = _head_with_eyes()
    n_head, n_eye = len(icosphere(2)[0]), len(icosphere(1)[0])
    rows = (slice(0, n_head), slice(n_head, n_head + n_eye), slice(n_head + n_eye, n_head + 2 * n_eye))
    shrunk = a.copy()
    centre = a[rows[1]].mean(axis=0)
    shrunk[rows[1]] = centre + scale * (a[rows[1]] - centre)
    axis = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3])
    rotation = Rotation.from_rotvec(np.radians(30.0) * axis).as_matrix()
    pivot = np.asarray(pivot, dtype=float)

    def truth(factor):
        return _screw(a, rotation, pivot - rotation @ pivot, factor)

    if in_first:
        return shrunk, tri, _rigid(a, rotation, pivot), truth, rows
    return a, tri, _rigid(shrunk, rotation, pivot), truth, rows


@pytest.mark.parametrize("pivot", [(0.4, -1.3, 0.1), (-0.35, 0.85, 0.3)], ids=["below", "in the other eye"])
@pytest.mark.parametrize("scale", [0.6, 0.3, 1e-3])
def test_an_eye_in_its_socket_turns_with_the_rigid_head_while_the_other_shrinks(scale, pivot):
    """A head turned 30° rigidly while one eye (a separate piece) shrinks about its centre: the
    other eye, in its socket and jointed to the head, moves as one with the head — not carried by
    the shrinking eye beside it, the only deforming piece near it — also where the turn's axis
    runs through it, so that the joint tree hangs the head from it (carried by the shrinking eye it
    was 0.35–0.46 % of the diagonal off at 0.5, 0.6–4 % at ×2; turned about that eye, 0.7–1.6 % and 0.6–4 %)."""
    a, tri, b, truth, (head, _, other) = _head_turned_with_an_eye_shrinking(scale, pivot=pivot)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, b, tri)
    for factor in (0.5, 2.0):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ShapeDifferenceWarning)  # ×2 of a shrink: its own warning
            x = interpolator.pose(factor)
        assert np.abs(x[head] - truth(factor)[head]).max() < 1e-9 * diagonal
        assert np.abs(x[other] - truth(factor)[other]).max() < 1e-9 * diagonal


@pytest.mark.parametrize("scale", [0.6, 0.3, 1e-3])
def test_an_eye_shrinking_in_a_turning_head_stays_in_its_socket_half_way(scale):
    """A head turned 30° rigidly while one eye shrinks about its centre: in-betweens put the eye's
    centroid where the head's rigid motion takes it (its seat's, exact), not partly on the chord
    of that arc that the blend anchor holds it to (held there, it is 0.43–0.45 % of the diagonal out of its
    socket at 0.25 and 0.75, 0.57–0.60 % at 0.5, a tenth of its radius)."""
    a, tri, b, truth, (_, eye, _) = _head_turned_with_an_eye_shrinking(scale)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, b, tri)
    for factor in (0.25, 0.5, 0.75):
        x = interpolator.pose(factor)
        assert np.linalg.norm(x[eye].mean(axis=0) - truth(factor)[eye].mean(axis=0)) < 1e-9 * diagonal


def test_a_piece_shrunk_to_a_speck_in_the_first_pose_leaves_the_rest_on_their_motion():
    """One eye a millionth of its size in the first pose (its triangles' areas 1e-12 of the
    others', accepted) while the head turns 30°: the in-betweens and exaggerations are made (the
    anchor's gauge, weighted by the vertices' areas, is floored at MASS_FLOOR of their mean; unfloored,
    the factorization fails, "not positive definite") and the head and the other
    eye are their rigid motion."""
    a, tri, b, truth, (head, _, other) = _head_turned_with_an_eye_shrinking(1e-6, in_first=True)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, b, tri)
    for factor in (0.5, 2.0):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ShapeDifferenceWarning)  # ×2 grows the speck: warned
            x = interpolator.pose(factor)
        assert np.isfinite(x).all()
        assert np.abs(x[head] - truth(factor)[head]).max() < 1e-9 * diagonal
        assert np.abs(x[other] - truth(factor)[other]).max() < 1e-9 * diagonal


def _exact_grid(nx, ny, height, offset=(0.0, 0.0)):
    """An ``nx × ny`` grid of spacing 0.25 at ``height`` (coordinates exact in binary: vertices
    exactly above each other are equally near to the last bit), its triangles."""
    u, v = np.meshgrid(np.arange(nx), np.arange(ny))
    points = np.stack([0.25 * u.ravel() + offset[0], 0.25 * v.ravel() + offset[1], np.full(u.size, height)], axis=1)
    return points, grid(nx, ny)[1]


@pytest.mark.parametrize("options", [{}, {"compact_nodes": False}, {"leafsize": 1}, {"leafsize": 64, "balanced_tree": False}])
def test_a_plate_over_a_grid_is_seated_on_the_lowest_of_equally_near_vertices_whatever_the_tree(options):
    """A rigid 4 × 4 plate 0.5 above a 12 × 10 cloth grid of the same spacing, vertex over vertex:
    each plate vertex has one cloth vertex under it and four equally near around that one (to the
    last bit), of which two are among its three nearest. Its carriers are those of a brute-force
    search ordered by (distance, index), whichever way the k-d tree over the cloth was built."""
    from scipy.spatial import cKDTree

    import core.inbetween_carried as carried

    cloth = _exact_grid(12, 10, 0.0)[0]
    plate = _exact_grid(4, 4, 0.5, offset=(0.75, 0.5))[0]
    first = np.vstack([cloth, plate])
    rows, deforming = np.arange(len(cloth), len(first)), np.arange(len(cloth))
    distance = np.linalg.norm(plate[:, None, :] - cloth[None, :, :], axis=2)
    order = np.lexsort((np.broadcast_to(deforming, distance.shape), distance), axis=-1)
    expected = np.unique(order[:, :carried.CARRIER_NEIGHBOURS])
    assert expected.size > len(plate)  # ties decided: more than the vertices under the plate
    still = (np.eye(3)[None], np.zeros((1, 3)))
    seats = carried.CarriedPieces._seats(first, first, first, rows, np.zeros(len(rows), dtype=int), 1, deforming,
                                         cKDTree(cloth, **options), still, 0.1)
    np.testing.assert_array_equal(seats[0][0], expected)


@pytest.mark.parametrize("options", [{}, {"compact_nodes": False}, {"leafsize": 1}, {"leafsize": 64, "balanced_tree": False}])
@pytest.mark.parametrize("lower_first", [True, False])
def test_a_grid_between_two_rigid_ones_is_seated_on_the_lower_numbered_whatever_the_tree(monkeypatch, options, lower_first):
    """A deforming 6 × 6 grid halfway between two rigid ones (0.5 below and above, vertex over
    vertex, coordinates exact): each of its vertices has one vertex of each rigid grid at 0.5 and
    eight at √0.3125 (four of each), the third nearest taken by index. The seat is the rigid grid
    listed first in the mesh (it holds two of each vertex's three nearest), whichever way the k-d
    tree over the rigid grids' vertices was built."""
    import scipy.spatial

    from core.inbetween_motion import seat_candidates
    from core.inbetween_topology import Topology
    from core.mesh_topology import mesh_topology

    class Built(scipy.spatial.cKDTree):
        def __init__(self, data, *args, **kwargs):
            super().__init__(data, *args, **{**kwargs, **options})

    monkeypatch.setattr(scipy.spatial, "cKDTree", Built)
    (below, tri), above = _exact_grid(6, 6, 0.0), _exact_grid(6, 6, 1.0)[0]
    middle = _exact_grid(6, 6, 0.5)[0]
    first, second = (below, above) if lower_first else (above, below)
    points = np.vstack([first, second, middle])
    triangles = np.vstack([tri, tri + 36, tri + 72])
    topo = Topology(mesh_topology(triangles, len(points)), points)
    piece = topo.vertex_component[[0, 36, 72]]  # the first-listed rigid grid, the other, the deforming one
    rigid = np.ones(len(topo.components), dtype=bool)
    rigid[piece[2]] = False
    pieces, owners = seat_candidates(topo, rigid)
    assert pieces.tolist() == [piece[2]] and owners.tolist() == [piece[0]]



def _scan_with_floaters(angle, points=1000, floaters=30, seed=2):
    """A scan-like limb: ``points`` points sampled unevenly over an ellipsoid 3 × 0.9 × 0.5 (denser
    toward +x), triangulated by their hull and moved off it by noise (5 % of the mean edge, more
    along z, as a scanner's depth), with ``floaters`` tetrahedra 0.15 of the mean edge across
    floating 0.6 of it over vertices picked at random (a scan's floaters: within their own size of
    one vertex or two, no more). It bends about y at x = 0.2 by ``angle`` (radians), each vertex by
    its weight's share (a smooth ramp 1.2 long), each floater rigidly with the vertex under it.
    Vertices, triangles, the surface's vertices that turn rigidly (weight 1) and the floaters'
    vertices over them (one array per floater)."""
    rng = np.random.default_rng(seed)
    u = np.clip(2.0 * rng.beta(2.0, 1.0, points) - 1.0, -0.999, 0.999)
    phi = rng.uniform(0.0, 2.0 * np.pi, points)
    unit = np.vstack([np.c_[u, np.sqrt(1 - u * u) * np.cos(phi), np.sqrt(1 - u * u) * np.sin(phi)],
                      [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]])
    tri = ConvexHull(unit).simplices
    inward = np.einsum("ij,ij->i", np.cross(unit[tri[:, 1]] - unit[tri[:, 0]], unit[tri[:, 2]] - unit[tri[:, 0]]),
                       unit[tri].mean(axis=1)) < 0
    tri[inward] = tri[inward][:, [0, 2, 1]]
    surface = unit * np.array([1.5, 0.45, 0.25])
    mean_edge = float(np.linalg.norm(surface[tri[:, [1, 2, 0]]] - surface[tri], axis=2).mean())
    surface += 0.05 * mean_edge * (unit * rng.normal(size=(len(unit), 1)) + rng.normal(size=unit.shape) * [0.2, 0.2, 1.0])
    corners = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) * 0.15 * mean_edge / (2 * np.sqrt(3))
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    picked = rng.choice(len(surface), floaters, replace=False)
    rest = np.vstack([surface] + [surface[k] + 0.6 * mean_edge * unit[k] + corners for k in picked])
    triangles = np.vstack([tri] + [faces + len(surface) + 4 * j for j in range(floaters)])
    weight = np.clip((surface[:, 0] + 0.4) / 1.2, 0.0, 1.0)
    weight = np.r_[weight, np.repeat(weight[picked], 4)]
    weight = weight * weight * (3.0 - 2.0 * weight)
    turn = Rotation.from_rotvec(angle * weight[:, None] * np.array([0.0, 1.0, 0.0]))
    pivot = np.array([0.2, 0.0, 0.0])
    over = [len(surface) + 4 * j + np.arange(4) for j in range(floaters) if weight[len(surface) + 4 * j] == 1.0]
    return turn.apply(rest - pivot) + pivot, triangles, np.flatnonzero(weight[:len(surface)] == 1.0), over


@pytest.mark.parametrize("factor", [0.25, 0.5, 0.75])
def test_floaters_over_a_bending_scan_stay_with_the_surface_under_them(factor):
    """The scan-like limb bent 100° with floaters over its rigidly turning end
    (:func:`_scan_with_floaters`): those floaters, one rigid body in both keys (their motions
    agree), are carried by the surface under them, each within the end's own departure from one
    rigid motion of that motion (the surface cannot place them better than it is rigid), and the
    floaters over the part that stays stay. Each floater's seat is sought within its own size,
    where a floater smaller than the surface's edges finds fewer than four vertices, and then
    within an edge: before, the body, some floaters of which had no seat, kept its own screw, and
    the floaters left the surface by 0.19 of the mean edge half-way (the end itself rigid to 0.07)."""
    a, tri, end, over = _scan_with_floaters(0.0)
    b = _scan_with_floaters(np.radians(100.0))[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # placement is what is checked here
        x = Interpolator(a, b, tri).pose(factor)
    rotation, translation = rigid_alignment(a[end], x[end])
    surface = np.abs(a[end] @ rotation.T + translation - x[end]).max()
    assert len(over) >= 10
    assert max(np.abs(a[rows] @ rotation.T + translation - x[rows]).max() for rows in over) <= surface
    still = np.flatnonzero(np.all(a == b, axis=1))
    assert still.size
    np.testing.assert_array_equal(x[still], a[still])


def _torso_with_glasses(s, bend=60.0, turn=70.0):
    """A torso (a closed tube of radius 0.5 along y ∈ [0, 2]) skinned at the waist (y = 0.8, its
    weights ramping over 0.6) and bent about x by ``s`` × ``bend`` degrees; a head (a sphere of
    radius 0.35 above it, 0.1 clear of it) on the upper bone, turned about the vertical by ``s`` ×
    ``turn`` degrees, and glasses of three boxes (two lenses and the bridge between them, which
    touch) 0.01 in front of it, parented to the head: the rig at ``s``. Head and glasses: 4 rigid
    pieces moving as one."""
    from meshes import closed_tube, cube

    tube, tube_triangles = closed_tube(41, 24, length=2.0, radius=0.5)
    tube, tube_triangles = tube[:, [1, 0, 2]], tube_triangles[:, [0, 2, 1]]  # along y, still outward
    waist = np.array([0.0, 0.8, 0.0])
    weights = np.clip((tube[:, 1] - 0.5) / 0.6, 0.0, 1.0)
    bent = Rotation.from_rotvec(s * np.radians(bend) * weights[:, None] * [1.0, 0.0, 0.0]).apply(tube - waist) + waist
    head, head_triangles = icosphere(2, radius=0.35)
    box, box_triangles = cube(2)
    lenses = [(box + 1.0) / 2.0 * np.subtract(high, low) + low for low, high in
              (((-0.25, 2.45, 0.36), (-0.05, 2.55, 0.38)), ((0.05, 2.45, 0.36), (0.25, 2.55, 0.38)),
               ((-0.05, 2.52, 0.36), (0.05, 2.54, 0.38)))]
    neck = np.array([0.0, 2.1, 0.0])
    upper = Rotation.from_rotvec([s * np.radians(bend), 0.0, 0.0])
    turned = Rotation.from_rotvec([0.0, s * np.radians(turn), 0.0])
    on_head = [upper.apply(turned.apply(x - neck) + neck - waist) + waist for x in [head + [0.0, 2.45, 0.0]] + lenses]
    parts, triangles = [bent] + on_head, [tube_triangles, head_triangles] + [box_triangles] * 3
    offsets = np.cumsum([0] + [len(x) for x in parts[:-1]])
    return np.vstack(parts), np.vstack([t + o for t, o in zip(triangles, offsets)]), len(tube)


def test_glasses_on_a_head_that_a_bending_torso_carries_move_with_the_head():
    """A head carried by the skinned torso it sits on (core.inbetween_carried) and glasses jointed
    to it (:func:`_torso_with_glasses`): at every factor the glasses are where the head's rigid
    motion from the first pose takes them, to 1e-6 of the diagonal: the four pieces move as one
    (the head rides on the torso's in-between, which is no skin's: 5.4e-3 of the diagonal off the
    rig at 0.5, 4.5e-2 at ×2). The glasses, jointed to the head but carried by no seat of their
    own (the torso is farther than their size), kept the joint tree's placement about their own
    motion while the seat moved the head: 9.5e-2 of the diagonal off the head's motion at 0.5,
    0.48 at ×2."""
    a, tri, on_head = _torso_with_glasses(0.0)
    interpolator = Interpolator(a, _torso_with_glasses(1.0)[0], tri)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    head = slice(on_head, on_head + len(icosphere(2)[0]))
    for s in FACTORS:
        x = interpolator.pose(s)
        rotation, translation = rigid_alignment(a[head], x[head])
        np.testing.assert_allclose(x[on_head:], a[on_head:] @ rotation.T + translation, atol=1e-6 * diagonal)


@pytest.mark.parametrize("two_poses", [True, False])
def test_a_tail_curling_on_a_turning_bone_keeps_its_root_where_the_bone_holds_it(two_poses):
    """A tail (1 long, radius 0.04) lying along the end of a skinned limb's turning bone and curling
    at four joints is a rider (``core.inbetween_carried``, RIDER_SIZE): the curl moves its centroid
    against the bone while its root, which no joint turns, stays on the bone. In-between, the root
    stays there, within half the tail's radius of where the bone (fitted to the limb's in-between)
    holds it; placed by its centroid, the root came 4.1–7.0e-2 off (two poses) and 4.6–6.2e-2
    (sequence) half-way, its shape right."""
    from scipy.optimize import minimize_scalar  # noqa: PLC0415
    from test_sequence_bent_parts import _skinned, _tube  # noqa: PLC0415

    from placement_helpers import _curled_tube  # noqa: PLC0415

    rest, limb_triangles = _tube()
    joints, radius = (0.2, 0.4, 0.6, 0.8), 0.04
    tail_rest, tail_triangles = _curled_tube(np.zeros(4), joints, 0.1, radius=radius)

    def tail(bone, curl):  # along the bone's end (x 3-4 on its surface), turned with it about its joint
        curled = _curled_tube(np.radians(np.full(4, curl)), joints, 0.1, radius=radius)[0] + [3.0, 0.3 + radius, 0.0]
        return Rotation.from_euler("z", bone, degrees=True).apply(curled - [2.0, 0, 0]) + [2.0, 0, 0]

    n = len(rest)
    triangles = np.concatenate([limb_triangles, tail_triangles + n])
    bones, curls = (0.0, 100.0, 150.0), (0.0, 40.0, 80.0)
    keys = [np.concatenate([_skinned(rest, b), tail(b, c)]) for b, c in zip(bones, curls)]
    root = np.flatnonzero(tail_rest[:, 0] <= joints[0])  # the part no joint of the curl turns
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        if two_poses:
            interpolator = Interpolator(keys[0], keys[1], triangles)
            poses = [interpolator.pose(s) for s in (0.25, 0.5, 0.75)]
        else:
            poses = SequenceInterpolator(keys, triangles).poses(0, [0.25, 0.5, 0.75])
    for x in poses:
        bone = minimize_scalar(lambda b: np.sum((x[:n] - _skinned(rest, b)) ** 2),  # noqa: B023
                               bounds=(-60.0, 240.0), method="bounded").x
        held = tail(bone, 0.0)[root]
        off = np.sqrt(np.mean(np.sum((x[n:][root] - held) ** 2, axis=1)))
        assert off <= 0.5 * radius
