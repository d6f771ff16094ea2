"""Rigid pieces jointed to each other (core.inbetween_joints; issue 17 item 3): each turns about its
joints, as links, doors, gears, hair cards and robot arms do; pieces that only touch are no
joints. No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import ShapeDifferenceWarning
from core.rigid_alignment import rigid_alignment
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator

import meshes
from meshes import cube, grid, icosphere
from placement_helpers import FACTORS, _curled_strip, _rigid, _screw


def _keyed_four_times_follows(rig, triangles, atol):
    """Keys of ``rig`` (time → vertices (n, 3)) at times 0–3 as a sequence (``start="keys"``): every
    in-between at 0.25 / 0.5 / 0.75 of each gap is ``rig`` at its time, to ``atol``."""
    sequence = SequenceInterpolator([rig(float(k)) for k in range(4)], triangles, start="keys")
    for gap in range(3):
        for factor, pose in zip((0.25, 0.5, 0.75), sequence.poses(gap, (0.25, 0.5, 0.75))):
            np.testing.assert_allclose(pose, rig(gap + factor), atol=atol)


def _follows_its_rig(rig, triangles, atol):
    """``rig`` (factor → vertices (n, 3)) between two poses (its factors 0 and 1) at every factor of
    ``FACTORS``, and keyed at every third of it four times (:func:`_keyed_four_times_follows`): every
    in-between and exaggeration is ``rig`` at its factor, to ``atol``."""
    pair = Interpolator(rig(0.0), rig(1.0), triangles)
    for s in FACTORS:
        np.testing.assert_allclose(pair.pose(s), rig(s), atol=atol)
    _keyed_four_times_follows(lambda t: rig(t / 3.0), triangles, atol)


def _chain(angles):
    """Three links (thin ellipsoids of length 1, each a separate piece) end to end along x from the
    origin, each turned about y at its root joint by ``angles`` (radians) relative to the link
    before it (the first about the origin): an arm rigged as separate rigid pieces."""
    link, link_triangles = icosphere(2)
    link = link * [0.5, 0.12, 0.12] + [0.5, 0.0, 0.0]
    parts, joint, rotation = [], np.zeros(3), np.eye(3)
    for angle in angles:
        rotation = rotation @ Rotation.from_rotvec([0.0, -angle, 0.0]).as_matrix()
        parts.append(link @ rotation.T + joint)
        joint = joint + rotation @ [1.0, 0.0, 0.0]
    triangles = np.vstack([link_triangles + k * len(link) for k in range(len(angles))])
    return np.vstack(parts), triangles


@pytest.mark.parametrize("degrees", [60.0, 90.0, 100.0, 130.0])
def test_jointed_rigid_pieces_turn_about_their_joints(degrees):
    """Three links of an arm, separate pieces touching at their joints, each bent by the same angle:
    every factor of two poses is the arm bent by that factor of the angles, to 1e-6 (each link
    along its own screw motion: apart at the joints by up to 0.56 link lengths at 0.5 of 60° and
    2.6 at ×2). At 100° and 130° the last link turns 300° and 390° in the world, which reads as a
    small turn: the arm hangs from the link that moves least (it had hung from that last link, 2.2
    link lengths off)."""
    a, tri = _chain((0.0,) * 3)
    b, _ = _chain((np.radians(degrees),) * 3)
    interpolator = Interpolator(a, b, tri)
    for s in FACTORS:
        np.testing.assert_allclose(interpolator.pose(s), _chain((s * np.radians(degrees),) * 3)[0], atol=1e-6)


@pytest.mark.parametrize("step", [40.0, 80.0])
def test_jointed_rigid_pieces_in_a_sequence(step):
    """The same arm's joints turning at constant speed, ``step`` degrees per key each (its last
    link 3 × that in the world: 240° per gap at 80°): every in-between of every gap is the arm at
    that time, to 1e-6."""
    _, tri = _chain((0.0,) * 3)
    keys = [_chain((np.radians(step * k),) * 3)[0] for k in range(5)]
    sequence = SequenceInterpolator(keys, tri, start="keys")
    factors = np.arange(1, 4) / 4
    for gap in range(4):
        for factor, pose in zip(factors, sequence.poses(gap, factors)):
            np.testing.assert_allclose(pose, _chain((np.radians(step * (gap + factor)),) * 3)[0], atol=1e-6)


def test_jointed_rigid_pieces_whose_joints_speed_up():
    """The arm's joints speeding up (60° per key + 15° per key², each): the in-betweens of the inner
    gaps, whose Catmull–Rom splines of the joints' screws are exact for an angle quadratic in time,
    are the arm at that time, to 1e-6 (before: 2.5 link lengths off where the last link's world turn
    passed a half turn per key and the arm hung from it, 0.15 where the joints' spline took the key
    after as a screw of a whole turn)."""
    _, tri = _chain((0.0,) * 3)

    def angle(t):
        return np.radians(60.0 * t + 7.5 * t * t)

    sequence = SequenceInterpolator([_chain((angle(k),) * 3)[0] for k in range(5)], tri, start="keys")
    factors = np.arange(1, 4) / 4
    for gap in (1, 2):
        for factor, pose in zip(factors, sequence.poses(gap, factors)):
            np.testing.assert_allclose(pose, _chain((angle(gap + factor),) * 3)[0], atol=1e-6)


def _gear(teeth, radius, hole, centre, phase):
    """A flat gear of ``teeth`` teeth (0.08 above and below ``radius``, each a quarter of its pitch
    at the tip and at the root) round a hole of radius ``hole``, about ``centre`` in the plane z = 0,
    turned by ``phase``: no vertex on its axle. Returns vertices and triangles."""
    count = 4 * teeth
    angle = phase + 2.0 * np.pi * np.arange(count) / count
    outer = radius + 0.08 * np.tile([1.0, 1.0, -1.0, -1.0], teeth)
    ring = np.concatenate([np.stack([r * np.cos(angle), r * np.sin(angle), np.zeros(count)], axis=1)
                           for r in (np.full(count, hole), outer)]) + centre
    i = np.arange(count)
    j = (i + 1) % count
    return ring, np.concatenate([np.stack([i, j, count + j], axis=1), np.stack([i, count + j, count + i], axis=1)])


def _gear_train(degrees, clearance=0.03):
    """Two meshing gears with holes, 20 teeth about radius 1 at the origin and 10 about radius 0.5
    beside it (tip to root ``clearance`` apart), the first turned by ``degrees`` about its axle and
    the second twice as far the other way about its own: vertices, triangles, each gear's rows."""
    pitch_a, pitch_b = 2.0 * np.pi / 20, 2.0 * np.pi / 10
    axles = np.array([[0.0, 0.0, 0.0], [1.5 + clearance, 0.0, 0.0]])
    a, a_tri = _gear(20, 1.0, 0.3, axles[0], -pitch_a / 8)  # a tip facing the other gear's root
    b, b_tri = _gear(10, 0.5, 0.15, axles[1], np.pi - 5 * pitch_b / 8)
    rows = [np.arange(len(a)), len(a) + np.arange(len(b))]
    vertices = np.vstack([a, b])
    for k, rate in enumerate((1.0, -2.0)):
        turn = Rotation.from_rotvec([0.0, 0.0, rate * np.radians(degrees)]).as_matrix()
        vertices[rows[k]] = _rigid(vertices[rows[k]], turn, axles[k])
    return vertices, np.vstack([a_tri, b_tri + len(a)]), rows


@pytest.mark.parametrize("degrees", [30.0, 45.0])
def test_meshing_gears_turn_about_their_own_axles(degrees):
    """Two meshing gears with holes (nothing on their axles), the large one turned by ``degrees``,
    the small one twice as far the other way: every factor of two poses (exaggerations included)
    is both gears turned by that factor about their own axles, to 1e-6. Their motion relative to
    each other turns about where their teeth mesh, which jointed them: composed on the other's
    motion, a gear left its axle by 2.9e-2 (30°) and 7.2e-2 (45°) of the pair's diagonal at 0.5,
    0.20 and 0.40 at × 2."""
    a, tri, _ = _gear_train(0.0)
    interpolator = Interpolator(a, _gear_train(degrees)[0], tri)
    for s in FACTORS + (-1.0, 3.0):
        np.testing.assert_allclose(interpolator.pose(s), _gear_train(s * degrees)[0], atol=1e-6)


@pytest.mark.parametrize("degrees", [5.0, 9.0, 13.0])
def test_meshing_gears_turned_less_than_a_tooth_turn_about_their_own_axles(degrees):
    """The gear train turned by less than a tooth's pitch (18° on the large gear): every factor of
    two poses is both gears turned by that factor about their own axles, to 1e-6, and so is every
    in-between of a sequence turning by as much a key. The closest pair of teeth jumps to the next
    tooth between the keys (by half a tooth's pitch), further than the gears' short turns carry
    the contact, which read so seemed carried by a moving parent: the small gear hung from the large
    one, 6.1e-3 (5°), 2.0e-2 (9°) and 4.0e-2 (13°) of the pair's diagonal off its axle (at ×2 and
    −0.5), and 4.3e-4–2.5e-3 in the sequences' end gaps; the centre of the whole contact stays put."""
    a, tri, _ = _gear_train(0.0)
    interpolator = Interpolator(a, _gear_train(degrees)[0], tri)
    for s in FACTORS + (-1.0, 3.0):
        np.testing.assert_allclose(interpolator.pose(s), _gear_train(s * degrees)[0], atol=1e-6)
    sequence = SequenceInterpolator([_gear_train(k * degrees)[0] for k in range(5)], tri, start="keys")
    factors = (0.25, 0.5, 0.75)
    for gap in range(4):
        for factor, pose in zip(factors, sequence.poses(gap, factors)):
            np.testing.assert_allclose(pose, _gear_train((gap + factor) * degrees)[0], atol=1e-6)


@pytest.mark.parametrize("degrees", [18.0, 21.0])
def test_meshing_gears_with_teeth_straddling_the_line_of_centres_turn_about_their_own_axles(degrees):
    """The gear train with its tips touching the other gear's roots (no clearance), the large gear
    turned by ``degrees``: a tooth pair entering the mesh in the first key leaves it, mirrored
    across the line of centres, in the second, the same two vertices touching in both keys. Every
    factor of two poses is both gears turned by that factor about their own axles, to 1e-6. Such a
    pair was read as a joint's own (its vertices parted along the gears' own screws): the small
    gear hung from the large one, 8e-2 (18°) and 0.1 (21°) of the pair's diagonal off its axle."""
    a, tri, _ = _gear_train(0.0, clearance=0.0)
    interpolator = Interpolator(a, _gear_train(degrees, clearance=0.0)[0], tri)
    for s in FACTORS + (-1.0, 3.0):
        np.testing.assert_allclose(interpolator.pose(s), _gear_train(s * degrees, clearance=0.0)[0], atol=1e-6)


def _involute_gear(teeth, module, centre, phase, backlash=0.01, flank=6):
    """A flat spur gear of ``teeth`` involute teeth (pressure angle 20°, addendum ``module``, dedendum
    1.25 ``module``, ``flank`` vertices up each flank, 3 across each tip and root, the tooth
    thinned by ``backlash`` at the pitch circle) round a hole of 0.3 of its pitch radius, tooth 0
    on angle ``phase`` about ``centre`` in the plane z = 0: vertices, triangles (the rim's vertex k
    joined to the hole's)."""
    pitch, alpha = module * teeth / 2, np.radians(20.0)
    base, tip, root = pitch * np.cos(alpha), pitch + module, pitch - 1.25 * module
    radii = np.linspace(max(base, root), tip, flank)
    involute = np.tan(alpha) - alpha - (np.tan(np.arccos(base / radii)) - np.arccos(base / radii))
    half = np.pi / (2 * teeth) - backlash / (2 * pitch) + involute  # half the tooth's angle at each radius
    step = 2 * np.pi / teeth
    angle, radius = [], []
    for k in range(teeth):
        c = phase + k * step
        angle += [*np.linspace(c - step / 2, c - half[0], 4)[:-1], *(c - half), *np.linspace(c - half[-1], c + half[-1], 5)[1:-1],
                  *(c + half[::-1]), *np.linspace(c + half[0], c + step / 2, 4)[1:-1]]
        radius += [*[root] * 3, *radii, *[tip] * 3, *radii[::-1], *[root] * 2]
    angle, radius = np.array(angle), np.array(radius)
    count = angle.size
    ring = np.concatenate([np.stack([r * np.cos(angle), r * np.sin(angle), np.zeros(count)], axis=1)
                           for r in (np.full(count, 0.3 * pitch), radius)]) + centre
    i = np.arange(count)
    j = (i + 1) % count
    return ring, np.concatenate([np.stack([i, j, count + j], axis=1), np.stack([i, count + j, count + i], axis=1)])


def _coarse_gear_pair(degrees):
    """Two meshing flat involute gears of 12 and 6 teeth (module 0.1: pitch radii 0.6 and 0.3), the
    large one at the origin turned by ``degrees`` about its axle, the small one beside it twice as
    far the other way about its own: vertices, triangles."""
    axles = np.array([[0.0, 0.0, 0.0], [0.9, 0.0, 0.0]])
    a, a_tri = _involute_gear(12, 0.1, axles[0], 0.0)
    b, b_tri = _involute_gear(6, 0.1, axles[1], np.pi + np.pi / 6)  # a root facing the large gear's tooth
    turns = [Rotation.from_rotvec([0.0, 0.0, rate * np.radians(degrees)]).as_matrix() for rate in (1.0, -2.0)]
    return (np.vstack([_rigid(a, turns[0], axles[0]), _rigid(b, turns[1], axles[1])]),
            np.vstack([a_tri, b_tri + len(a)]))


@pytest.mark.parametrize("degrees", [20.0, 45.0, 80.0])
def test_coarse_meshing_gears_whose_contact_changes_extent_turn_about_their_own_axles(degrees):
    """Two flat involute gears of 12 and 6 teeth, finely outlined: as their coarse teeth engage and
    disengage, the vertex pairs touching within the finer gear's edge go from 608 to 381–424
    (fewer than CONTACT_STEADY's share), their contact rolled along both gears to vertices that were
    apart (:func:`core.inbetween_joints.contracts_in_place`). Every factor of two poses is both gears
    turned by that factor about their own axles, to 1e-6, and every in-between of a sequence
    turning by 25° a key. Where a contact that changed its extent held the joint (fe02c72), the small
    gear hung from the large one, silently: 8.8e-2 (20°), 0.37 (45°) and 1.3 (80°) of the pair's
    diagonal off its axle."""
    a, tri = _coarse_gear_pair(0.0)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, _coarse_gear_pair(degrees)[0], tri)
    for s in FACTORS + (-1.0,):
        np.testing.assert_allclose(interpolator.pose(s), _coarse_gear_pair(s * degrees)[0], atol=1e-6 * diagonal)


def test_coarse_meshing_gears_keyed_every_25_degrees_turn_about_their_own_axles():
    """:func:`_coarse_gear_pair` keyed every 25°: every in-between of the sequence is both gears
    turned about their own axles, to 1e-6 (where a contact that changed its extent held the joint,
    5.6e-4 of the diagonal off, silently)."""
    _, tri = _coarse_gear_pair(0.0)
    diagonal = np.linalg.norm(np.ptp(_coarse_gear_pair(0.0)[0], axis=0))
    _keyed_four_times_follows(lambda t: _coarse_gear_pair(25.0 * t)[0], tri, 1e-6 * diagonal)


def _three_gear_train(degrees):
    """:func:`_gear_train` (tip to root 0.03 apart) and a third gear of 30 teeth about radius 1.5
    meshing with the large one on its other side, turned 2/3 as far the other way about its own
    axle: vertices, triangles, each gear's rows."""
    vertices, triangles, rows = _gear_train(degrees)
    axle = np.array([-2.53, 0.0, 0.0])
    c, c_tri = _gear(30, 1.5, 0.45, axle, -5 * (2.0 * np.pi / 30) / 8)  # a root facing the large gear's tip
    turn = Rotation.from_rotvec([0.0, 0.0, -2.0 / 3.0 * np.radians(degrees)]).as_matrix()
    rows = rows + [len(vertices) + np.arange(len(c))]
    return np.vstack([vertices, _rigid(c, turn, axle)]), np.vstack([triangles, c_tri + len(vertices)]), rows


def test_a_gear_turned_a_half_turn_among_gears_turning_both_ways_is_warned():
    """Three meshing gears, the large one turned 90°: the small one turns −180°, which gives the
    same keys as +180°, and the third −60°. The pieces' half turns take the way the whole mesh
    turns, which is no way of theirs where pieces turn both ways round it: the gap warns that the
    keys do not tell which way the half turn goes (silent before), and the third gear turns about
    its own axle, to 1e-6 (the half-turned one either way round; the large one, jointed to it by its
    half turn, is left up to 5.2 off, under this warning)."""
    a, tri, rows = _three_gear_train(0.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        interpolator = Interpolator(a, _three_gear_train(90.0)[0], tri)
        poses = [interpolator.pose(s) for s in FACTORS]
    assert _said(caught, "turn a half turn"), [str(w.message) for w in caught]
    for s, pose in zip(FACTORS, poses):
        truth = _three_gear_train(s * 90.0)[0]
        np.testing.assert_allclose(pose[rows[2]], truth[rows[2]], atol=1e-6)


def _folded_arm(turn, fold):
    """Two links (thin ellipsoids of length 1, separate pieces) jointed end to end at x = 1, the
    second folded back by ``fold`` (radians, about z) to lie along the first, both turned by
    ``turn`` about z at the first's root (the origin): an arm folded onto itself."""
    link, link_triangles = icosphere(2)
    link = link * [0.5, 0.12, 0.12] + [0.5, 0.0, 0.0]
    folded = link @ Rotation.from_rotvec([0.0, 0.0, fold]).as_matrix().T + [1.0, 0.0, 0.0]
    turn_matrix = Rotation.from_rotvec([0.0, 0.0, turn]).as_matrix()
    return np.vstack([link, folded]) @ turn_matrix.T, np.vstack([link_triangles, link_triangles + len(link)])


@pytest.mark.parametrize(("turn", "folds"), [(40.0, (150.0, 165.0)), (-60.0, (160.0, 140.0))])
def test_an_arm_folded_onto_itself_turns_about_its_joints(turn, folds):
    """The forearm folded back along the upper arm (touching it along its length as well as at the
    elbow), the fold opening or closing while the arm turns at the shoulder: every factor of two
    poses is the arm at that factor of the turn and the fold, to 1e-6. The elbow's own vertex pair
    moves with the contact, which the arm's turn carries: a joint, wherever the links' own screws
    keep them touching (the case the gear rule's shared-pair part, now removed, was written for)."""
    turn, folds = np.radians(turn), np.radians(folds)
    a, tri = _folded_arm(0.0, folds[0])
    interpolator = Interpolator(a, _folded_arm(turn, folds[1])[0], tri)
    for s in FACTORS + (-1.0,):
        truth, _ = _folded_arm(s * turn, folds[0] + s * (folds[1] - folds[0]))
        np.testing.assert_allclose(interpolator.pose(s), truth, atol=1e-6)


def _forearm_and_hand(bend, swing, n=60, k=16, radius=0.1):
    """A tube forearm (x ∈ [0, 2], radius 0.1) bent about y by ``bend`` over x ∈ [0.9, 1.5], and a
    hand (an ellipsoid, a separate piece overlapping the tube's end) turned at the wrist by
    ``swing`` more (radians). Returns positions, triangles and the forearm's vertex count."""
    angle = np.linspace(0.0, 2.0 * np.pi, k, endpoint=False)
    x = np.repeat(np.linspace(0.0, 2.0, n), k)
    tube = np.stack([x, radius * np.tile(np.cos(angle), n), radius * np.tile(np.sin(angle), n)], axis=1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(k), indexing="ij")
    a, b, c, d = i * k + j, i * k + (j + 1) % k, (i + 1) * k + j, (i + 1) * k + (j + 1) % k
    triangles = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    out, wrist = tube.copy(), np.array([2.0, 0.0, 0.0])
    if bend:
        bent = 0.6 / bend
        turn = np.clip(x - 0.9, 0.0, 0.6) / bent
        out[:, 0] = np.where(x < 0.9, x, 0.9 + (bent - tube[:, 2]) * np.sin(turn))
        out[:, 2] = np.where(x < 0.9, tube[:, 2], bent - (bent - tube[:, 2]) * np.cos(turn))
        past = x > 1.5
        out[past, 0] += (x[past] - 1.5) * np.cos(bend)
        out[past, 2] += (x[past] - 1.5) * np.sin(bend)
        wrist = np.array([0.9 + bent * np.sin(bend) + 0.5 * np.cos(bend), 0.0, bent * (1 - np.cos(bend)) + 0.5 * np.sin(bend)])
    hand, hand_triangles = icosphere(2, radius=0.15)
    hand = (hand * [1.5, 1.0, 1.0] + [0.2, 0.0, 0.0]) @ Rotation.from_rotvec([0.0, -(bend + swing), 0.0]).as_matrix().T + wrist
    return np.vstack([out, hand]), np.vstack([triangles, hand_triangles + len(tube)]), len(tube)


def test_a_hand_turning_at_the_wrist_of_a_bending_forearm_stays_on_it():
    """A forearm bent by 90° while the hand (a separate rigid piece overlapping its end) turns 60°
    more at the wrist: the forearm's end does not carry the hand (it turns further), but holds it
    at a joint, so the hand turns about the wrist on the moving forearm. At 0.5 and ×2 the hand
    is within 2e-3 and 1e-2 of the diagonal of where it belongs (the forearm's own error: 5e-4
    and 3.4e-3); along its own screw it was 9.4e-2 and 0.50 off."""
    a, tri, arm = _forearm_and_hand(0.0, 0.0)
    b, _, _ = _forearm_and_hand(np.radians(90.0), np.radians(60.0))
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, b, tri)
    for factor, bound in ((0.5, 2e-3), (2.0, 1e-2)):
        x = interpolator.pose(factor)
        truth, _, _ = _forearm_and_hand(factor * np.radians(90.0), factor * np.radians(60.0))
        assert np.sqrt(np.mean(np.sum((x[arm:] - truth[arm:]) ** 2, axis=1))) < bound * diagonal


@pytest.mark.parametrize("degrees", [60.0, 90.0])
def test_a_strip_curled_at_two_joints_is_exaggerated_about_its_joints(degrees):
    """Two joints curled by the same angle: the middle segment turns as the whole strip's best
    rigid motion does, but about its own joint. Exaggerated ×1.5 and ×2 it is the strip curled by
    1.5 and 2 × the angles (to 1e-3 of the diagonal: the joints' chords shorten a little as they
    curl further) with the first segment fixed; taken along the whole strip's screw motion instead,
    the middle segment left its joint (×2 of 60° / 60°: 7 % of the diagonal, edges 62 % off)."""
    a, tri = _curled_strip((0.0, 0.0))
    b, _ = _curled_strip((np.radians(degrees),) * 2)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, b, tri)
    fixed = a[:, 0] < 0.85
    for factor in (1.5, 2.0):
        x = interpolator.pose(factor)
        truth, _ = _curled_strip((factor * np.radians(degrees),) * 2)
        assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < 1e-3 * diagonal
        assert np.abs(x[fixed] - a[fixed]).max() < 1e-6 * diagonal


def _doors(left, right, gap=0.05):
    """Two cabinet doors (1 × 1.67 panels, separate pieces ``gap`` apart, nearer than an edge),
    the left one turned by ``left`` about its left edge, the right one by ``right`` about its
    right edge (radians; both swing toward +z): each door's hinge vertices still."""
    panel, panel_triangles = grid(4, 6, size=1.0)
    a = np.vstack([panel, panel + [1.0 + gap, 0.0, 0.0]])
    out, n = a.copy(), len(panel)
    for rows, angle, hinge in ((slice(0, n), -left, [0.0, 0.0, 0.0]), (slice(n, 2 * n), right, [2.0 + gap, 0.0, 0.0])):
        out[rows] = _rigid(a[rows], Rotation.from_rotvec([0.0, angle, 0.0]).as_matrix(), np.array(hinge))
    return out, np.vstack([panel_triangles, panel_triangles + n])


@pytest.mark.parametrize("degrees", [(90.0, 40.0), (40.0, 90.0), (120.0, 30.0)])
def test_neighbouring_doors_each_turn_about_their_own_hinge(degrees):
    """Two doors side by side, each turning rigidly about its own hinge, whose vertices stay
    still: every factor of two poses (and every time of a sequence) is each door turned by that
    factor of its angle, to 1e-6. They touch (within an edge) and their relative motion's axis
    runs near the contact, so the joint tree had hung one from the other: moved by the other's
    motion composed with the relative one while its hinge's pins held it, it bent between the two
    (0.31 off at ×2, edges 60 % off). A piece with a pinned vertex hangs from the world."""
    left, right = np.radians(degrees)
    a, tri = _doors(0.0, 0.0)
    interpolator = Interpolator(a, _doors(left, right)[0], tri)
    for s in FACTORS:
        np.testing.assert_allclose(interpolator.pose(s), _doors(s * left, s * right)[0], atol=1e-6)
    sequence = SequenceInterpolator([_doors(k * left / 3, k * right / 3)[0] for k in range(4)], tri, start="keys")
    for gap in range(3):
        for factor in (0.25, 0.5, 0.75):
            np.testing.assert_allclose(sequence.pose(gap, factor),
                                       _doors((gap + factor) * left / 3, (gap + factor) * right / 3)[0], atol=1e-6)


@pytest.mark.parametrize("degrees", [60.0, 90.0])
def test_links_bent_back_carry_the_last_link_round_the_joints(degrees):
    """Three links (separate pieces) on a fixed first link, the second bent by ``degrees`` and the
    third bent back by as much: the last link only translates between the keys, along the arc the
    second one turns. Every factor of two poses is the arm bent by that factor of the angles, to
    1e-6. Anchored to the linear blend in the world it stayed on the straight line (60°: 0.79 off
    at ×2, its joint opened); a jointed piece's blend is taken with its composed motion undone."""
    a, tri = _chain((0.0,) * 3)
    angles = np.radians([0.0, degrees, -degrees])
    interpolator = Interpolator(a, _chain(angles)[0], tri)
    for s in FACTORS:
        np.testing.assert_allclose(interpolator.pose(s), _chain(s * angles)[0], atol=1e-6)


@pytest.mark.parametrize("degrees", [60.0, 90.0])
def test_a_strip_folded_back_at_two_joints_hangs_its_end_from_its_fixed_base(degrees):
    """A strip on a still base folded by ``degrees`` at one joint and back by as much at the next
    (a Z): its end only translates between the keys. At −0.5, 0.5 and ×2 it is the strip folded
    by that factor of the angles to 1e-3 of the diagonal (RMS; the joints' chords shorten a little
    as they curl), its edges within 1 % of their lengths and its base fixed to 1e-6. Anchored to
    the linear blend, the end stayed on the blend's straight line: 60° half-way 4.2e-2 of the
    diagonal off with edges 8 % off, ×2 0.31 and 41 %. A component that keeps its edge lengths
    and has pins moves only by turning about them: its parts hang from the pins."""
    a, tri = _curled_strip((0.0, 0.0))
    angles = np.radians([degrees, -degrees])
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    edges = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    rest = np.linalg.norm(a[edges[:, 1]] - a[edges[:, 0]], axis=1)
    fixed = a[:, 0] < 0.85
    interpolator = Interpolator(a, _curled_strip(angles)[0], tri)
    for factor in (-0.5, 0.5, 2.0):
        x = interpolator.pose(factor)
        truth, _ = _curled_strip(factor * angles)
        assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < 1e-3 * diagonal, factor
        assert np.abs(np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1) / rest - 1.0).max() < 1e-2, factor
        assert np.abs(x[fixed] - a[fixed]).max() < 1e-6 * diagonal, factor


def test_a_small_piece_near_a_turning_ball_is_no_joint_of_it_whatever_else_the_mesh_holds():
    """A ball (radius 0.14) turning 25° about its vertical axis and a lash in front of it (one thin
    triangle 0.06 long, 0.06 from the ball: as far as it is long) turning 40° about the ball's
    horizontal axis, beside a coarse still body whose edges make the mesh's mean edge longer than
    the lash. Each piece moves by its own rigid motion, so every factor is each piece's rotation by
    that factor, to 1e-6. The lash was taken for a joint of the ball (touching within one of the
    mesh's mean edges, its relative motion's axis within two of them of the contact) and moved
    with the ball's turn composed with its own relative to it: 3.1e-3 of the diagonal off at 0.5,
    2.8e-2 at ×2, while without the body elsewhere in the mesh it was exact."""
    ball, ball_triangles = icosphere(2, radius=0.14)
    body, body_triangles = icosphere(1, radius=0.4)
    base = np.array([0.130, -0.123, 0.075])
    lash = np.array([base, base + [0.006, 0.0, 0.0], base + [0.003, -0.05, 0.03]])
    parts = [ball, lash, body + [0.0, 0.7, 0.0]]
    a = np.vstack(parts)
    tri = np.vstack([ball_triangles, np.array([[0, 1, 2]]) + len(ball), body_triangles + len(ball) + 3])
    turns = [np.array([0.0, 0.0, -np.radians(25.0)]), np.array([np.radians(40.0), 0.0, 0.0]), np.zeros(3)]
    piece = np.repeat(np.arange(3), [len(p) for p in parts])

    def pose(s):  # every piece turns about the ball's centre, the origin
        return np.einsum("nij,nj->ni", Rotation.from_rotvec(s * np.array(turns)[piece]).as_matrix(), a)

    interpolator = Interpolator(a, pose(1.0), tri)
    for s in FACTORS:
        np.testing.assert_allclose(interpolator.pose(s), pose(s), atol=1e-6)


def test_pieces_of_a_shattered_block_that_fly_apart_are_no_joints():
    """A block shattered into 3 × 3 × 3 cubes (separate pieces, neighbours' faces coincident in the
    first key) that fly apart: each cube turns 60–150° about an axis through its centre while its
    centre moves 2.5 × as far from the block's, so that no two cubes touch in the second key. Each
    cube moves by its own rigid motion: every factor is each cube's screw motion by that factor, to
    1e-6. Cubes touching in the first key were jointed where their relative motion's axis ran near
    their contact, and moved with a neighbour's motion composed with their own relative to it,
    although nothing held them together in the second key (the closest two 0.81 apart, the mesh's
    mean edge 0.58): 16 of the 27 cubes up to 1.1 of the diagonal off at 0.5 and 1.4 at × 2."""
    unit, unit_triangles = cube(2)
    rng = np.random.default_rng(4)
    cells = np.array([(i, j, k) for i in range(3) for j in range(3) for k in range(3)], dtype=float)
    a = np.vstack([0.5 * unit + cell for cell in cells])
    tri = np.vstack([unit_triangles + len(unit) * k for k in range(len(cells))])
    middle = cells.mean(axis=0)
    motions = []
    for cell in cells:
        axis = rng.normal(size=3)
        rotation = Rotation.from_rotvec(np.radians(rng.uniform(60.0, 150.0)) * axis / np.linalg.norm(axis)).as_matrix()
        motions.append((rotation, middle + 2.5 * (cell - middle) - rotation @ cell))
    piece = np.repeat(np.arange(len(cells)), len(unit))

    def pose(s):
        return np.vstack([_screw(a[piece == k], *motions[k], s) for k in range(len(cells))])

    interpolator = Interpolator(a, pose(1.0), tri)
    for s in FACTORS:
        np.testing.assert_allclose(interpolator.pose(s), pose(s), atol=1e-6 * np.linalg.norm(np.ptp(a, axis=0)))


def _hair(s, count=200, seed=0):
    """A still scalp (a sphere of radius 1) and ``count`` hair cards (strips of 8 × 2 vertices, 0.35
    long and 0.03 wide, separate pieces) rooted 0.08 above it at random on its upper part, combed
    down with some spread, so that many lie along a neighbour; each card turned by ``s`` times its
    own turn (20–50° about an axis of its own through its root, along the scalp). Vertices,
    triangles."""
    rng = np.random.default_rng(seed)
    scalp, scalp_triangles = icosphere(3)
    strip, strip_triangles = grid(8, 2, size=1.0)
    strip = strip * [0.35, 0.21, 1.0]
    parts, triangles = [scalp], [scalp_triangles]
    while len(parts) <= count:
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        if normal[2] < 0.2:
            continue
        down = np.array([0.0, 0.0, -1.0]) + 0.4 * rng.normal(size=3)
        along = down - normal * (down @ normal)
        along = along / np.linalg.norm(along) + 0.3 * normal
        along /= np.linalg.norm(along)
        across = np.cross(normal, along)
        across /= np.linalg.norm(across)
        root = 1.08 * normal
        axis = rng.normal(size=3)
        axis -= normal * (axis @ normal)
        turn = np.radians(rng.uniform(20.0, 50.0)) * axis / np.linalg.norm(axis)
        card = root + strip[:, :1] * along + (strip[:, 1:2] - 0.015) * across
        triangles.append(strip_triangles + sum(len(p) for p in parts))
        parts.append(_rigid(card, Rotation.from_rotvec(s * turn).as_matrix(), root))
    return np.vstack(parts), np.vstack(triangles)


def test_hair_cards_lying_along_each_other_turn_about_their_own_roots():
    """200 hair cards on a still scalp, many lying along a neighbour in one key, each turning about
    its own root: every factor of two poses, either way round (exaggerations included), is each card
    turned by that factor about its root, to 1e-6 of the diagonal. Cards touching in both keys (at
    least near their roots) whose relative motion held their contact to within the mesh's mean edge
    were taken for joints: 77 of the 200 moved with a neighbour's motion composed with their relative
    one, up to 0.13 of a card's size off at 0.5 and 0.84 at ×2, silently. The relative motion of two
    cards turning about their own roots slides along its axis, which a joint's does not
    (`JOINT_SLIDE`)."""
    a, tri = _hair(0.0)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    for start, end in ((0.0, 1.0), (1.0, 0.0)):
        interpolator = Interpolator(_hair(start)[0], _hair(end)[0], tri)
        for s in FACTORS:
            np.testing.assert_allclose(interpolator.pose(s), _hair(start + s * (end - start))[0], atol=1e-6 * diagonal)


def _debris(count=(3, 3, 2), seed=2):
    """Debris: ``count`` pieces (cubes and tetrahedra about 0.1 across, turned at random) in a
    lattice 0.115 apart, most touching their neighbours, each tumbling 20–90° about its centre while
    all fall 0.3 (each a little differently). Vertices, triangles, each piece's rigid motion
    (rotation, translation) and each vertex's piece."""
    rng = np.random.default_rng(seed)
    box, box_triangles = cube(1)
    tetrahedron = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]]) / np.sqrt(3.0)
    tetrahedron_triangles = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    parts, triangles, motions, offset = [], [], [], 0
    for k, cell in enumerate(np.ndindex(*count)):
        centre = 0.115 * np.array(cell, dtype=float)
        piece, piece_triangles = (box, box_triangles) if k % 2 else (tetrahedron, tetrahedron_triangles)
        parts.append(0.05 * piece @ Rotation.random(random_state=rng.integers(1 << 30)).as_matrix().T + centre)
        triangles.append(piece_triangles + offset)
        offset += len(piece)
        axis = rng.normal(size=3)
        rotation = Rotation.from_rotvec(np.radians(rng.uniform(20.0, 90.0)) * axis / np.linalg.norm(axis)).as_matrix()
        motions.append((rotation, centre + [0.0, 0.0, -0.3] + rng.uniform(-0.01, 0.01, 3) - rotation @ centre))
    piece = np.repeat(np.arange(len(parts)), [len(p) for p in parts])
    return np.vstack(parts), np.vstack(triangles), motions, piece


@pytest.mark.parametrize("sequence", [False, True])
def test_tumbling_debris_that_touches_in_both_keys_moves_each_piece_by_its_own_motion(sequence):
    """Debris tumbling as it falls, neighbours touching (within an edge, which is about a piece's
    size) in both keys: every factor of two poses, and every in-between of a sequence tumbling at
    constant speed, is each piece's own screw motion, to 1e-6 of the diagonal. Touching pairs whose
    relative motion held their contact to within that edge were jointed: 17 of the 18 pieces moved
    with a neighbour's motion composed with their relative one, up to 0.53 of a piece's size off at
    0.5 and 3.1 at ×2 (the sequence's first gap 0.28), silently; a joint's relative motion turns
    without sliding along its axis."""
    a, tri, motions, piece = _debris()

    def pose(s):
        return np.vstack([_screw(a[piece == k], *motion, s) for k, motion in enumerate(motions)])

    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    if not sequence:
        interpolator = Interpolator(a, pose(1.0), tri)
        for s in FACTORS:
            np.testing.assert_allclose(interpolator.pose(s), pose(s), atol=1e-6 * diagonal)
        return
    _keyed_four_times_follows(pose, tri, 1e-6 * diagonal)



def _coarse_cubes_spinning(s, gap, turns, tilt):
    """Two cubes of one cell a face (8 vertices, edges 1 and 1.41), 1 across and ``gap`` apart along
    x, each turning about its own centre by ``s`` × ``turns`` (degrees): the first about z, the
    second about z tilted by ``tilt`` (radians) toward x; the scene turned off the axes. Vertices,
    triangles."""
    cube_vertices, cube_triangles = cube(1)
    cube_vertices = 0.5 * cube_vertices
    second_axis = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    first = cube_vertices @ Rotation.from_rotvec([0.0, 0.0, np.radians(s * turns[0])]).as_matrix().T
    second = cube_vertices @ Rotation.from_rotvec(np.radians(s * turns[1]) * second_axis).as_matrix().T
    x = np.vstack([first, second + [1.0 + gap, 0.0, 0.0]])
    return (x @ Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix().T,
            np.vstack([cube_triangles, cube_triangles + len(cube_vertices)]))


@pytest.mark.parametrize("gap, turns, tilt", [(0.2, (20.0, 50.0), 0.0), (0.1, (25.0, 60.0), 0.4)])
def test_coarse_pieces_spinning_side_by_side_are_not_moved_as_one(gap, turns, tilt):
    """:func:`_coarse_cubes_spinning`: the cubes' nearest vertices are within an edge of each other
    in both keys, so they touch, and their relative motion turns about a point near them without
    sliding; it moves the second cube by 0.87 / 1.04 (a bound), within their contact's reach (an edge,
    1.14), and they were taken to move as one: the second hung from the first, 6.0e-2 / 0.14 of the
    diagonal off at × 2, silently. Each turns about its own axis, which moves the second cube by
    0.73 / 0.87 only: pieces moving as one move against each other less than in the world. Every
    factor of two poses is each cube's own turn, to 1e-6."""
    a, tri = _coarse_cubes_spinning(0.0, gap, turns, tilt)
    poses, _ = _poses_and_warnings(Interpolator(a, _coarse_cubes_spinning(1.0, gap, turns, tilt)[0], tri), FACTORS)
    for s, pose in zip(FACTORS, poses):
        np.testing.assert_allclose(pose, _coarse_cubes_spinning(s, gap, turns, tilt)[0], atol=1e-6)


@pytest.mark.parametrize("axles, turns, about", [
    (((0.0, 0.0), (1.2, 0.0)), (20.0, 50.0), False),  # cubes spinning side by side, each on its centre
    (((0.0, 0.0), (1.2, 0.0)), (10.0, -70.0), False),
    (((-1.0, 0.0), (0.62, 0.0)), (2.0, 118.0), True),  # a parent on its far shoulder, a link on its end
    (((0.0, 0.4), (1.2, -0.3)), (-35.0, 80.0), False),  # axles off the centres, still nearer them
])
def test_a_piece_turns_about_a_contact_only_where_its_axis_is_nearer_it_than_its_centroid(axles, turns, about):
    """``_turns_about`` against distances measured in the plane: two pieces with centroids (0, 0)
    and (1.2, 0), their contact at (0.6, 0), each turning by ``turns`` (degrees) about z through its
    point of ``axles``. A piece turns about the contact where its axle is nearer the contact than
    its centroid (a link turning about its end where it meets its parent; a cube or gear spinning on
    an axle through it turns about no contact): the link on its end at (0.62, 0), 0.02 from the
    contact and 0.62 from its centroid, does; pieces spinning on axles nearer their centroids do
    not."""
    from core.inbetween_joints import _axis_distances, _turns_about

    axles = np.array([[*a, 0.0] for a in axles])
    centres = np.array([[0.0, 0.0, 0.0], [1.2, 0.0, 0.0]])
    contact = np.array([[0.6, 0.0, 0.0]])
    rotations = Rotation.from_rotvec(np.radians(turns)[:, None] * [0.0, 0.0, 1.0]).as_matrix()
    translations = axles - np.einsum("kab,kb->ka", rotations, axles)
    for k in (0, 1):  # the distances from the axle that the chords give are the plane's
        for x in (contact[0], centres[k]):
            chord = np.linalg.norm(rotations[k] @ x + translations[k] - x)
            np.testing.assert_allclose(_axis_distances(np.array([chord]), np.radians([abs(turns[k])])),
                                       [np.linalg.norm(x - axles[k])], rtol=1e-12)
    expected = any(np.linalg.norm(contact[0] - axles[k]) < np.linalg.norm(centres[k] - axles[k]) for k in (0, 1))
    assert expected == about
    assert bool(_turns_about(contact, centres, rotations, translations, np.array([0]), np.array([1]))[0]) == about


_FRESH = """
import hashlib, sys
import numpy as np
sys.path.insert(0, {root!r})
from core import Interpolator, SequenceInterpolator
given = np.load({path!r})
keys, triangles = list(given["keys"]), given["triangles"]
digest = hashlib.sha1(Interpolator(keys[0], keys[1], triangles).pose(0.5).tobytes())
digest.update(Interpolator(keys[0], keys[1], triangles).pose(2.0).tobytes())
sequence = SequenceInterpolator(keys, triangles)
for gap in range(len(keys) - 1):
    digest.update(np.ascontiguousarray(sequence.poses(gap, [0.25, 0.5, 0.75])).tobytes())
print(digest.hexdigest())
"""


def test_many_pieces_give_the_same_bits_in_every_fresh_process(tmp_path):
    """Farm chunks of one job run in separate processes and must agree: tumbling debris (18 pieces,
    joint contacts sought between them), as two poses and as a sequence, gives the same in-betweens
    to the bit in fresh processes whatever Python's string hashing (PYTHONHASHSEED) and BLAS's
    thread count. The keys are made once and handed to both: SciPy's matrix logarithm (which the
    test's screw motions use) estimates norms from NumPy's unseeded global random numbers, so keys
    made in each process differ at round-off (1e-15)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    a, tri, motions, piece = _debris()
    keys = [np.vstack([_screw(a[piece == k], *motion, s) for k, motion in enumerate(motions)]) for s in (0, 1, 2)]
    path = tmp_path / "keys.npz"
    np.savez(path, keys=np.array(keys), triangles=tri)
    code = _FRESH.format(root=str(Path(__file__).resolve().parents[2]), path=str(path))
    digests = []
    for seed, threads in (("0", "1"), ("1", "2")):
        env = {**os.environ, "PYTHONHASHSEED": seed, "OMP_NUM_THREADS": threads, "OPENBLAS_NUM_THREADS": threads}
        digests.append(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                      timeout=300, check=True).stdout.strip())
    assert digests[0] == digests[1]

def _robot(s, capped=True, angles=(58.0, 36.0, 22.0, 21.0, 69.0, 75.0), axes="xyyxyx", pins=None):
    """A robot arm of seven tubes (0.6 long along x, radius 0.08, neighbours' end rings coincident;
    ``capped``: each cap a fan about a vertex on the tube's axis, else open) on a fixed base link,
    its joints at the links' roots turned about ``axes`` by ``s`` times ``angles`` (degrees): forward
    kinematics. About x a link rolls on its own axis, on which the next joint lies, so that joint's
    point (and the cap vertices there) stays still. ``pins``: each link holds a separate pin (a closed
    tube 0.2 long, radius 0.025) on its axis, nested in it without touching its wall (0.055 from
    it) and moved with it, starting ``pins`` from the link's root (0.2: midway, more than an edge
    from everything, so no joint; −0.1: a hinge pin through the joint, into the link below, which
    it is jointed to; None: no pins). Vertices, triangles."""
    tube, tube_triangles = meshes.closed_tube(13, 12, length=0.6, radius=0.08)
    if not capped:
        tube, tube_triangles = tube[:-2], tube_triangles[np.all(tube_triangles < len(tube) - 2, axis=1)]
    pin, pin_triangles = meshes.closed_tube(5, 8, length=0.2, radius=0.025)
    if pins is not None:
        tube_triangles = np.vstack([tube_triangles, pin_triangles + len(tube)])
        tube = np.vstack([tube, pin + [pins, 0.0, 0.0]])
    rotation, translation, parts = np.eye(3), np.zeros(3), [tube]
    for k, (axis, angle) in enumerate(zip(axes, angles), start=1):
        joint = np.array([0.6 * k, 0.0, 0.0])
        turn = Rotation.from_rotvec(s * np.radians(angle) * np.eye(3)["xyz".index(axis)]).as_matrix()
        translation = rotation @ (joint - turn @ joint) + translation
        rotation = rotation @ turn
        parts.append((tube + joint) @ rotation.T + translation)
    return np.vstack(parts), np.vstack([tube_triangles + k * len(tube) for k in range(len(parts))])


@pytest.mark.parametrize("capped", [True, False])
def test_a_robot_arm_jointed_at_points_its_links_turn_about_is_its_forward_kinematics(capped):
    """A robot arm whose first joint rolls its link about the axis the next joint lies on (a
    shoulder pitching on the yaw axis below it): every factor of two poses (exaggerations included)
    and every in-between of a sequence at constant joint speeds is the arm at that factor of its
    angles, to 1e-6 of the diagonal. Capped, the links with a still vertex (on a rolling axis) hung
    from the world, each on its own screw motion, although the link below keeps that vertex still
    too: five links up to 0.29 of a link's size off at 0.5 and 0.86 at ×2 (the sequence 1e-2),
    silently; a pinned piece hangs from the world only where the piece it is jointed to would move
    its pins. Open, the shoulder's joint was taken for two pieces each turning about its own axis
    (their contact stays put, their own screws keep it), as far off: both turn about the joint's
    point, which stays put, and their own screws keep the point but not the turn of one relative
    to the other."""
    a, tri = _robot(0.0, capped)
    _follows_its_rig(lambda s: _robot(s, capped)[0], tri, 1e-6 * np.linalg.norm(np.ptp(a, axis=0)))


def test_a_robot_arm_slowing_into_its_last_key_is_its_forward_kinematics():
    """The robot arm's joints slowing at a constant deceleration to a stop a quarter of a gap past
    the last key (keys at 0–3): the in-betweens of the gaps with a key before them, the last one
    included, are the arm at their time, to 1e-6 of the diagonal, and its base link, still in every
    key, is where the keys have it: the joints' screws slow into the last key as the positions do
    (core.splines.slowing_screw_correction). With their linear end the last gap was 9.5e-3 of the
    diagonal off (the rest end 4.7e-3)."""
    stop = 3.25

    def rig(t):
        return _robot((t - t * t / (2.0 * stop)) / 2.0)[0]

    a, tri = _robot(0.0)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    base = np.arange(len(a) // 7)  # the first of the seven tubes
    sequence = SequenceInterpolator([rig(float(k)) for k in range(4)], tri, start="keys")
    for gap in (1, 2):
        for factor, pose in zip((0.25, 0.5, 0.75), sequence.poses(gap, (0.25, 0.5, 0.75))):
            np.testing.assert_allclose(pose, rig(gap + factor), atol=1e-6 * diagonal)
            np.testing.assert_array_equal(pose[base], a[base])


@pytest.mark.parametrize("stop", [3.0, 3.25])
def test_ball_joints_slowing_into_the_last_key_stay_shut(stop):
    """Three capped tubes on a fixed base, each turned at its root (its cap's centre on the parent's
    end cap's) by a ball joint whose turn decelerates to a stop at time ``stop`` (keys at 0–3) while
    its axis swings (rotation vector ``u a + 0.4 u² b``, ``u = t − t²/(2 stop)``): at every factor
    of the last two gaps each joint's two cap centres coincide, to 1e-9 of the diagonal, and the
    base is where the keys have it. The joints' screws relative to their parents turn about the
    joint (``v = p × ω`` at every key, ``v`` no multiple of ``ω`` as the axis swings); the last
    key's slowing takes the turn's share for the whole screw (core.splines.slowing_screw_correction,
    ``pivoted``), which keeps that relation. With the turn and the move slowed each by its own
    share (cbeb9a6) the joints opened in the last gap by 2.3e-4 / 2.7e-4 of the diagonal."""
    tube, tube_triangles = meshes.closed_tube(13, 12, length=0.6, radius=0.08)
    n = len(tube)
    root_cap, end_cap = n - 2 + np.argsort(tube[-2:, 0])  # the caps' centres at x = 0 and x = 0.6
    sweeps = np.array([[[1.0, 0.2, 0.0], [0.0, 1.0, 0.5]], [[0.0, 1.0, 0.3], [0.8, 0.0, 1.0]],
                       [[0.3, 0.0, 1.0], [1.0, 0.6, 0.0]]])

    def rig(t):
        u = t - t * t / (2.0 * stop)
        rotation, translation, parts = np.eye(3), np.zeros(3), [tube]
        for k, (a, b) in enumerate(sweeps, start=1):
            joint = np.array([0.6 * k, 0.0, 0.0])
            turn = Rotation.from_rotvec(np.radians(25.0) * (u * a + 0.4 * u * u * b)).as_matrix()
            translation = rotation @ (joint - turn @ joint) + translation
            rotation = rotation @ turn
            parts.append((tube + joint) @ rotation.T + translation)
        return np.vstack(parts)

    triangles = np.vstack([tube_triangles + k * n for k in range(4)])
    a = rig(0.0)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    sequence = SequenceInterpolator([rig(float(k)) for k in range(4)], triangles, start="keys")
    factors = np.linspace(0.05, 0.95, 19)
    for gap in (1, 2):
        for pose in sequence.poses(gap, factors):
            for k in range(3):
                assert np.linalg.norm(pose[k * n + end_cap] - pose[(k + 1) * n + root_cap]) < 1e-9 * diagonal, (gap, k)
            np.testing.assert_array_equal(pose[:n], a[:n])


@pytest.mark.parametrize(("angles", "pins"), [((40.0, 120.0, 100.0, 30.0, 170.0, 60.0), 0.2),
                                             ((58.0, 36.0, 22.0, 21.0, 69.0, 75.0), 0.2),
                                             ((0.0, 0.0, 60.0, 180.0, 0.0, 0.0), -0.1)])
def test_pins_nested_in_a_robot_arms_links_move_with_their_links(angles, pins):
    """The robot arm (:func:`_robot`) with a pin nested in each link: every factor of two poses
    (exaggerations included) and every in-between of a sequence is the arm at that factor of its
    angles, pins included, to 1e-6 of the diagonal, and no warning says a piece moves by its own
    rigid motion off a joint's path. Each pin moves as one with its link in every key, so it takes
    its link's motion, which its joints compose (core.rigid_bodies). Midway in its link, on its own
    screw each pin took the short way of its net turn (a link turned 390° about y over the joints
    below it: 30°) while its link took the joints' way: pins up to 0.6 of the diagonal out of their
    links half-way and 0.8 at ×2 (the default angles: 0.1 and 1.0), in the sequences 0.1 (0.01).
    Through the joint, jointed to the link below as its link is, the hinge pin of a link rolled
    exactly half round took the other way round than its link: 1e-2 of the diagonal off."""
    a, tri = _robot(0.0, angles=angles, pins=pins)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, _robot(1.0, angles=angles, pins=pins)[0], tri)
    poses, caught = _poses_and_warnings(interpolator, FACTORS)
    for s, x in zip(FACTORS, poses):
        np.testing.assert_allclose(x, _robot(s, angles=angles, pins=pins)[0], atol=1e-6 * diagonal)
    assert not _said(caught, "by its own rigid motion")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sequence = SequenceInterpolator([_robot(k / 3, angles=angles, pins=pins)[0] for k in range(4)], tri,
                                        start="keys")
        for gap in range(3):
            for s, x in zip((0.25, 0.5, 0.75), sequence.poses(gap, (0.25, 0.5, 0.75))):
                np.testing.assert_allclose(x, _robot((gap + s) / 3, angles=angles, pins=pins)[0],
                                           atol=1e-6 * diagonal)
    assert not _said(caught, "by its own rigid motion")


def _lever_beside_an_arm(s):
    """A still slab (4.5 × 4 × 0.1), an arm of two bars lying on it (2.2 × 0.2 × 0.1, the second on
    top of the first), each turned about z by ``s`` × 60° at its hinge (x = 0 on the slab, x = 2
    on the first bar), and a lever (a 0.23 × 0.23 × 0.1 box) on a still post (0.33 × 0.33 × 0.1,
    level with the slab), turned about z by ``s`` × 120° at a hinge c of its own: c is the point
    the arm's two hinges turn its second bar about in net, so that the lever and the second bar
    move alike between the poses and apart between them. Forward kinematics: vertices,
    triangles, each vertex's piece (slab, bars, lever, post)."""
    box, box_triangles = cube(8)

    def placed(lo, hi, motion):
        lo, hi = np.asarray(lo), np.asarray(hi)
        return (lo + (box + 1.0) * 0.5 * (hi - lo)) @ motion[0].T + motion[1]

    def turn(degrees, about):
        rotation = Rotation.from_rotvec([0.0, 0.0, np.radians(degrees)]).as_matrix()
        return rotation, np.asarray(about, dtype=float) - rotation @ about

    def then(first, second):
        return first[0] @ second[0], first[0] @ second[1] + first[1]

    net = then(turn(60.0, [0.0, 0.0, 0.0]), turn(60.0, [2.0, 0.0, 0.0]))
    c = np.r_[np.linalg.solve(np.eye(2) - net[0][:2, :2], net[1][:2]), 0.0]
    parts = [placed([-1.0, -1.5, -0.1], [3.5, 2.5, 0.0], (np.eye(3), np.zeros(3))),
             placed([-0.1, -0.1, 0.0], [2.1, 0.1, 0.1], turn(s * 60.0, [0.0, 0.0, 0.0])),
             placed([1.9, -0.1, 0.1], [4.1, 0.1, 0.2],
                    then(turn(s * 60.0, [0.0, 0.0, 0.0]), turn(s * 60.0, [2.0, 0.0, 0.0]))),
             placed(c - [0.1, 0.1, 0.0], c + [0.13, 0.13, 0.1], turn(s * 120.0, c)),
             placed(c - [0.15, 0.15, -0.1], c + [0.18, 0.18, 0.0], (np.eye(3), np.zeros(3)))]
    return (np.vstack(parts), np.vstack([box_triangles + k * len(box) for k in range(len(parts))]),
            np.repeat(np.arange(len(parts)), len(box)))


def test_a_lever_moving_as_an_arms_link_between_two_poses_keeps_its_own_hinge():
    """Two poses of :func:`_lever_beside_an_arm`: the lever, hinged on the still slab, and the
    arm's second bar, hinged on the first, move by one rigid motion between the poses but about
    different hinges between them; each piece is at its forward kinematics to 1e-6 of the diagonal
    at every factor. Each is jointed to a different piece, so neither takes the other's motion
    (core.rigid_bodies): on the second bar's motion the lever left its hinge by 4.1e-2 of the
    diagonal half-way and 0.27 at ×2, silently."""
    a, tri, piece = _lever_beside_an_arm(0.0)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, _lever_beside_an_arm(1.0)[0], tri)
    for s, x in zip(FACTORS, _poses_and_warnings(interpolator, FACTORS)[0]):
        truth = _lever_beside_an_arm(s)[0]
        for k in range(5):
            np.testing.assert_allclose(x[piece == k], truth[piece == k], atol=1e-6 * diagonal, err_msg=f"piece {k}")


def _said(caught, words):
    """Whether any caught ShapeDifferenceWarning's message contains ``words``."""
    return any(issubclass(w.category, ShapeDifferenceWarning) and words in str(w.message) for w in caught)


def _poses_and_warnings(interpolator, factors):
    """The poses of ``interpolator`` at ``factors`` and the warnings they gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        poses = [interpolator.pose(s) for s in factors]
    return poses, caught


def _torus_chain(s, clearance, count=8, degrees=25.0):
    """``count`` interlocked torus links (major radius 0.3, minor 0.06, 24 × 8 vertices: a mean edge
    of 0.072), alternately in the xy and xz planes, each clearing the next by ``clearance``, every
    joint (the midpoint of two links' centres) curled by ``s`` × ``degrees`` about z: forward
    kinematics from the first, still link. Vertices, triangles, each vertex's link."""
    link, link_triangles = meshes.twisted_torus(24, 8, major=0.3, minor=0.06)
    flip = Rotation.from_rotvec([np.pi / 2, 0.0, 0.0]).as_matrix()
    step = 0.6 - 0.12 - clearance
    rotation, translation, parts = np.eye(3), np.zeros(3), []
    for k in range(count):
        rest = link @ (flip.T if k % 2 else np.eye(3)) + [k * step, 0.0, 0.0]
        if k:
            joint = np.array([(k - 0.5) * step, 0.0, 0.0])
            turn = Rotation.from_rotvec([0.0, 0.0, np.radians(s * degrees)]).as_matrix()
            translation = rotation @ (joint - turn @ joint) + translation
            rotation = rotation @ turn
        parts.append(rest @ rotation.T + translation)
    triangles = np.vstack([link_triangles + k * len(link) for k in range(count)])
    return np.vstack(parts), triangles, np.repeat(np.arange(count), len(link))


@pytest.mark.parametrize("clearance", [0.04, 0.08])
def test_chain_links_clearing_each_other_are_jointed_or_warned(clearance):
    """Eight interlocked links curled 25° at every joint. Clearing each other by 0.04 (0.6 of an
    edge) they are jointed: every factor is the chain's forward kinematics to 1e-6 of the diagonal,
    silently. Clearing by 0.08 (1.1 edges) no joint is found (contacts are sought within an edge)
    and each link moves by its own screw, 0.64 of a link off at 0.5 and 2.65 at ×2: the in-betweens
    warn that such links turn about a point between them as jointed links do (before, silently)."""
    a, tri, _ = _torus_chain(0.0, clearance)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    poses, caught = _poses_and_warnings(Interpolator(a, _torus_chain(1.0, clearance)[0], tri), FACTORS)
    right = all(np.abs(x - _torus_chain(s, clearance)[0]).max() <= 1e-6 * diagonal for x, s in zip(poses, FACTORS))
    warned = _said(caught, "as jointed links do")
    assert right != warned
    if clearance < 0.072:
        assert right


@pytest.mark.parametrize("clearance", [0.04, 0.08])
def test_a_chain_curling_through_a_sequence_is_right_or_warned_gap_by_gap(clearance):
    """The eight interlocked links above as four keys, every joint curling 25° more per key. As the
    chain curls, links come within an edge of the next-but-one as closely as of the links they
    hold: their contacts hold a joint too and close loops, of which the joint tree keeps all but
    one contact each. Clearing each other by 0.08 the tree of gaps 1 and 2 takes every other link's
    passing contact (6.3e-5 and 5.4e-3 of a link off in the in-betweens): each gap's in-betweens
    are the chain's forward kinematics to 1e-6 of the diagonal or warn (gap 0, no joint: links
    apart; gaps 1 and 2: joints in a loop). Clearing by 0.04 the
    first two gaps, before any loop, are exact and silent."""
    tri = _torus_chain(0.0, clearance)[1]
    keys = [_torus_chain(float(k), clearance)[0] for k in range(4)]
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    sequence = SequenceInterpolator(keys, tri, start="keys")
    factors = (0.25, 0.5, 0.75)
    for gap in range(3):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            poses = sequence.poses(gap, factors)
        right = all(np.abs(x - _torus_chain(gap + s, clearance)[0]).max() <= 1e-6 * diagonal
                    for x, s in zip(poses, factors))
        warned = _said(caught, "as jointed")
        assert right or warned
        if clearance < 0.072 and gap < 2:
            assert right and not warned

def _gripper(s, slide):
    """A hand (a box 0.4 × 0.2 × 0.1) and two fingers (boxes 0.05 × 0.04 × 0.15 under it), the hand
    moving by ``s`` times the screw of a turn of 42° with a shift, the fingers sliding apart along
    the hand by ``s`` × ``slide`` each (prismatic joints). Vertices, triangles."""
    box, box_triangles = cube(4)
    hand = box * [0.2, 0.1, 0.05]
    finger = box * [0.025, 0.02, 0.075]
    rest = [hand, finger + [-0.1, 0.0, -0.125], finger + [0.1, 0.0, -0.125]]
    local = [rest[0], rest[1] - [s * slide, 0.0, 0.0], rest[2] + [s * slide, 0.0, 0.0]]
    rotation = Rotation.from_rotvec([0.2, 0.3, np.radians(40.0)]).as_matrix()
    moved = [_screw(part, rotation, np.array([0.3, 0.1, 0.2]), s) for part in local]
    return np.vstack(moved), np.vstack([box_triangles + k * len(box) for k in range(3)])


@pytest.mark.parametrize("slide", [0.01, 0.05])
def test_fingers_sliding_in_a_turning_hand_are_placed_or_warned(slide):
    """Two fingers sliding along a hand that turns and moves (their contact slides, so it holds no
    point, and no joint is found): each finger moves by its own screw, 0.6 % / 3.0 % of a finger's
    size off the sliding joint at 0.5 and 4.5 % / 23 % at ×2. Every factor is the hand's motion
    composed with the fingers' slides to 1e-6 of the diagonal, or the in-betweens warn that the
    fingers slide along a piece they touch (before, silently)."""
    a, tri = _gripper(0.0, slide)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    poses, caught = _poses_and_warnings(Interpolator(a, _gripper(1.0, slide)[0], tri), FACTORS)
    right = all(np.abs(x - _gripper(s, slide)[0]).max() <= 1e-6 * diagonal for x, s in zip(poses, FACTORS))
    assert right != _said(caught, "slide along a piece they touch")


@pytest.mark.parametrize("offset", [0.0, 1e3])
def test_hair_cards_in_single_precision_are_right_or_warned(offset):
    """The 200 hair cards above, their coordinates rounded to single precision ``offset`` from the
    origin (as a mesh cached far from its object's origin). Neighbouring cards slide relative to
    each other by 5e-6–4e-4 (median 2e-3), which rounding at 1,000 (6e-5) leaves unresolved: 18
    cards were jointed, 4.1e-3 of the diagonal off at 0.5, silently. Every factor is each card
    turned about its own root to 1e-3 of the diagonal (ten times what rounding at 1,000 moves a
    vertex, against the diagonal), or the in-betweens warn that joints are told from chance
    contacts only to the coordinates' precision; at the origin the cards are right, silently."""
    def rounded(x):
        return (x + offset).astype(np.float32).astype(np.float64)

    a, tri = _hair(0.0)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    factors = (0.5, 2.0)
    poses, caught = _poses_and_warnings(Interpolator(rounded(a), rounded(_hair(1.0)[0]), tri), factors)
    right = all(np.abs(x - offset - _hair(s)[0]).max() <= 1e-3 * diagonal for x, s in zip(poses, factors))
    warned = _said(caught, "told from pieces touching by chance")
    assert right or warned
    if offset == 0.0:
        assert right and not warned


def test_pieces_turned_half_round_with_the_body_they_hang_near_are_no_links_apart():
    """Hair cards, a chain's rings and buttons of a character skinned in Blender (Rigify's meta-rig,
    Automatic Weights on the body, the pieces weighted as the body under them, the rings to a hand)
    turned half round by the root bone, as the rig gives them (single precision, 624 vertices, 53
    pieces): each piece's rotation is a half turn to within its rounding, and the short way round
    of one card is the other way of its neighbour's. The in-between is the half turn, rigid to 1e-6
    of the diagonal (warned only that the way round is untold), and no pieces are said to turn as
    jointed links about a point between them: taken each its own way round, eleven read up to
    2.7 × their size off the joint's path half-way, which no in-between does."""
    from pathlib import Path

    data = np.load(Path(__file__).parent / "data" / "skin_pieces_half_turn.npz")
    a, b, tri = data["vertices_a"].astype(float), data["vertices_b"].astype(float), data["triangles"]
    diagonal = np.linalg.norm(a.max(axis=0) - a.min(axis=0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        interpolator = Interpolator(a, b, tri)
        poses = [interpolator.pose(s) for s in (0.25, 0.5, 1.5)]
    for degrees, x in zip((45.0, 90.0, 90.0), poses):  # 270° at 1.5 is 90° the other way round
        rotation, translation = rigid_alignment(a, x)
        assert np.abs(a @ rotation.T + translation - x).max() < 1e-6 * diagonal
        assert np.isclose(Rotation.from_matrix(rotation).magnitude(), np.radians(degrees), atol=1e-5)
    assert _said(caught, "which way round")
    assert not _said(caught, "as jointed links do")


def _boxes_arm(s, angles=(10.0, 30.0, 40.0)):
    """A robot arm of six boxes (0.3 thick, each a separate piece of 26 vertices) meeting face to
    face along x: a still base of two, then three links on joints at x = 1.6 (about z), 3.0 and 3.8
    (about y, through the middle of the faces that meet there), the links of two, one and one
    boxes, each joint turned by ``s`` × its angle (degrees): the forward kinematics at ``s``. The
    boxes' vertices along each hinge coincide, and some across it at a right angle."""
    box, box_triangles = cube(2)
    spans = [(0.0, 1.0, 0), (1.0, 1.6, 0), (1.6, 2.4, 1), (2.4, 3.0, 1), (3.0, 3.8, 2), (3.8, 4.4, 3)]
    joints = [([1.6, 0.0, 0.0], [0.0, 0.0, 1.0]), ([3.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
              ([3.8, 0.0, 0.0], [0.0, 1.0, 0.0])]
    parts = []
    for low, high, link in spans:
        x = (box + 1.0) / 2.0 * [high - low, 0.3, 0.3] + [low, -0.15, -0.15]
        for j in reversed(range(link)):
            pivot, axis = np.array(joints[j][0]), np.array(joints[j][1])
            x = Rotation.from_rotvec(s * np.radians(angles[j]) * axis).apply(x - pivot) + pivot
        parts.append(x)
    return np.vstack(parts), np.vstack([box_triangles + k * len(box) for k in range(len(spans))])


def test_a_robot_arm_of_boxes_meeting_face_to_face_is_its_forward_kinematics_in_every_gap():
    """The arm of :func:`_boxes_arm` keyed at constant joint speeds (10°, 30°, 40° per key): every
    in-between of every gap of a sequence is the arm at that time, to 1e-6 of the diagonal. The
    boxes' coincident vertices make many vertex pairs equally closest, and the first of them was
    another pair in each key: in the gap where the elbow reaches a right angle the joint read as a
    contact that stays put (0.055 moved where the yaw carries it 0.245), so the elbow was taken for
    two pieces turning about their own axes and left unjointed, its two links on their own screws
    1.2e-3 of the diagonal off (3 of 24 random arms so keyed were off by 0.9–2.6e-3)."""
    _, tri = _boxes_arm(0.0)
    diagonal = np.linalg.norm(np.ptp(_boxes_arm(0.0)[0], axis=0))
    _keyed_four_times_follows(lambda t: _boxes_arm(t)[0], tri, 1e-6 * diagonal)


def _lid_on_box(s, opened, opening, move, turn=0.2):
    """A box (the cube [−1, 1]³, 4 × 4 vertices a face) and its lid (a separate 2 × 2 plate of
    5 × 5 vertices on its top) hinged along the edge x = −1, z = 1 and open by ``opened + s ·
    opening`` (radians), the pair carried by ``s`` times the screw of the rigid motion that turns by
    ``turn`` about the z axis through (0, 2, 0) and then moves by ``move`` (the constant-velocity
    motion of :func:`placement_helpers._screw`), the scene turned: vertices, triangles."""
    box, box_triangles = cube(4)
    lid, lid_triangles = grid(5, 5, size=2.0)
    lid = lid - [1.0, 1.0, 0.0]
    lid[:, 2] = 1.0
    hinge = Rotation.from_rotvec([0.0, -(opened + s * opening), 0.0]).as_matrix()
    carry = Rotation.from_rotvec([0.0, 0.0, turn]).as_matrix()
    shift = (np.eye(3) - carry) @ [0.0, 2.0, 0.0] + np.asarray(move)
    x = _screw(np.vstack([box, _rigid(lid, hinge, np.array([-1.0, 0.0, 1.0]))]), carry, shift, s)
    scene = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix()
    return x @ scene.T, np.vstack([box_triangles, lid_triangles + len(box)])


def _box_under_lid(s, opened, opening, move, turn=0.2):
    """The box and lid of :func:`_lid_on_box` the other way round: the lid carried by ``s`` times
    that screw while the box swings about the hinge the lid carries, open by ``opened + s ·
    opening`` (radians) from it: vertices, triangles."""
    box, box_triangles = cube(4)
    lid, lid_triangles = grid(5, 5, size=2.0)
    lid = lid - [1.0, 1.0, 0.0]
    lid[:, 2] = 1.0
    hinge = Rotation.from_rotvec([0.0, opened + s * opening, 0.0]).as_matrix()
    carry = Rotation.from_rotvec([0.0, 0.0, turn]).as_matrix()
    shift = (np.eye(3) - carry) @ [0.0, 2.0, 0.0] + np.asarray(move)
    x = _screw(np.vstack([_rigid(box, hinge, np.array([-1.0, 0.0, 1.0])), lid]), carry, shift, s)
    scene = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix()
    return x @ scene.T, np.vstack([box_triangles, lid_triangles + len(box)])


@pytest.mark.parametrize("build", [_lid_on_box, _box_under_lid])
@pytest.mark.parametrize(("opened", "opening"), [(0.2, 0.3), (0.2, 1.0), (0.0, 0.3)])
def test_the_piece_carried_steadily_carries_its_hinged_partner_in_a_sequence(build, opened, opening):
    """A box carried steadily (moved by 1, turned 11° a key) while its lid opens about the hinge
    (:func:`_lid_on_box`), and the other way round, the lid carried while the box swings from the
    hinge it carries (:func:`_box_under_lid`), keyed four times: every in-between of every gap is
    the carried piece along its own screw with the other turned about the hinge it carries, to 1e-6.
    The carried piece's screws at the keys lie on one line, its partner's (the carry composed with
    the hinge's turn) do not, so it is the root whichever moves less (core.inbetween_carriers): the
    lid, lifted against the carry, moves 8–23 % less than the box, and the group hung from it put
    the box off its own path by 1.2e-3–2.5e-2 (the box 2 across), silently."""
    move = (1.0, 0.0, 0.2)
    _, tri = build(0.0, opened, opening, move)
    _keyed_four_times_follows(lambda t: build(t, opened, opening, move)[0], tri, 1e-6)


@pytest.mark.parametrize(("build", "opened", "opening", "times"), [
    (_lid_on_box, 0.2, 1.0, (0.0, 1.0, 3.0, 4.0)), (_lid_on_box, 0.0, 0.3, (0.0, 2.0, 3.0, 5.0)),
    (_box_under_lid, 0.2, 0.3, (0.0, 1.0, 3.0, 4.0)), (_box_under_lid, 0.0, 0.3, (0.0, 2.0, 3.0, 5.0))])
def test_a_carried_box_and_lid_keyed_at_uneven_times_hang_from_the_steady_piece(build, opened, opening, times):
    """The box and lid of the two tests above keyed at uneven times: every in-between of every gap
    is the truth at its time, to 1e-6. A neighbouring key at another distance in time is rescaled to
    where an evenly spaced key would be, which marks it as a sequence's end condition; read as no
    key, a gap between a key one step and one two steps away (or at the sequence's end) read no key
    beyond its two, every piece kept to its screw, and the group hung from the piece that moved
    least: 1.8e-2–0.19 off (the box 2 across), silently. The rescaled key moves its screw along the line through the
    base key's and its own, so a steady piece's keys stay on one line and it is read as a key."""
    move = (1.0, 0.0, 0.2)
    _, tri = build(0.0, opened, opening, move)
    sequence = SequenceInterpolator([build(t, opened, opening, move)[0] for t in times], tri, start="keys",
                                    key_times=times)
    for gap in range(3):
        for factor, pose in zip((0.25, 0.5, 0.75), sequence.poses(gap, (0.25, 0.5, 0.75))):
            time = times[gap] + factor * (times[gap + 1] - times[gap])
            np.testing.assert_allclose(pose, build(time, opened, opening, move)[0], atol=1e-6)


@pytest.mark.parametrize(("opened", "opening"), [(0.2, 0.3), (0.2, 1.0)])
def test_a_box_carried_while_its_lid_opens_between_two_poses_is_warned(opened, opening):
    """Two poses of the box of the tests above, the lid open 11° at the first: the group hangs from
    the piece that moves least, the lid (lifted against the carry, it moves 1–3 % less than the
    box), and the box, composed on the lid's motion, leaves its own screw (7.5e-2 / 0.20 of the
    diagonal at ×2). Every piece keeps to its own screw between two poses, and the lid moving by its
    own screw with the box hinged to it fits the keys as well; but the lid turns more than the box,
    so the least move and the least turn name different carriers: the gap warns that two keys alone
    do not tell which piece carries the other (before: silent). Each piece stays rigid, to 1e-6."""
    move = (1.0, 0.0, 0.2)
    a, tri = _lid_on_box(0.0, opened, opening, move)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        interpolator = Interpolator(a, _lid_on_box(1.0, opened, opening, move)[0], tri)
        poses = [interpolator.pose(s) for s in FACTORS + (-1.0,)]
    assert _said(caught, "two keys alone do not tell which piece carries the others"), [str(w.message) for w in caught]
    box = np.arange(64)
    for s, pose in zip(FACTORS + (-1.0,), poses):
        truth = _lid_on_box(s, opened, opening, move)[0]
        for rows in (box, np.arange(64, len(a))):  # each piece rigid
            rotation, translation = rigid_alignment(truth[rows], pose[rows])
            np.testing.assert_allclose(truth[rows] @ rotation.T + translation, pose[rows], atol=1e-6)


@pytest.mark.parametrize(("opened", "opening", "turn"), [(0.0, 0.3, 0.2), (0.2, 1.0, 0.0)])
def test_a_box_carried_while_its_lid_opens_from_its_top_between_two_poses_carries_the_lid_silently(
        opened, opening, turn):
    """The counterparts: the lid opening from the box's top while the box is carried as above, or
    the box only moved (not turned) while its lid opens: the box moves least and turns least, which
    tells the carrier, and every factor is the truth to 1e-6, without a warning."""
    move = (1.0, 0.0, 0.2)
    a, tri = _lid_on_box(0.0, opened, opening, move, turn)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        interpolator = Interpolator(a, _lid_on_box(1.0, opened, opening, move, turn)[0], tri)
        poses = [interpolator.pose(s) for s in FACTORS + (-1.0,)]
    assert not _said(caught, "carries the others"), [str(w.message) for w in caught]
    for s, pose in zip(FACTORS + (-1.0,), poses):
        np.testing.assert_allclose(pose, _lid_on_box(s, opened, opening, move, turn)[0], atol=1e-6)


def _sunk_arm(s):
    """Three separate ellipsoid links (of 42, 162 and 42 vertices) jointed end to end, each tip sunk
    into the link before it (0.043, 0.033), the first turned ``s`` × 0.5° at its root and the second
    ``s`` × 1.5° on it about general axes, the third ``s`` × 118° at its joint: the arm placed off
    the origin (session 74's arm probe, seed 0, no. 6): vertices, triangles."""
    lengths, radii, spins = (0.67, 1.17, 1.23), (0.17, 0.105, 0.17), (1.42, 2.28, 2.63)
    levels, sunk = (1, 2, 1), (0.0, 0.043, 0.033)
    turns = (np.radians(0.5) * np.array([-0.371, -0.555, 0.744]), np.radians(1.5) * np.array([0.295, -0.079, 0.952]),
             np.radians(118.4) * np.array([0.0, 0.0, 1.0]))
    parts, triangles, count, joint, rotation = [], [], 0, np.zeros(3), Rotation.identity()
    for k in range(3):
        link, link_triangles = icosphere(levels[k])
        link = Rotation.from_rotvec([spins[k], 0.0, 0.0]).apply(link) * [lengths[k] / 2, radii[k], radii[k]]
        rotation = rotation * Rotation.from_rotvec(s * turns[k])
        parts.append(rotation.apply(link + [lengths[k] / 2 - sunk[k], 0.0, 0.0]) + joint)
        triangles.append(link_triangles + count)
        count += len(link)
        joint = joint + rotation.apply([lengths[k] - (sunk[k + 1] if k < 2 else 0.0), 0.0, 0.0])
    scene = Rotation.from_rotvec([-0.976, -0.022, 0.035])
    return scene.apply(np.vstack(parts)) + [-2.2, -3.9, 4.3], np.vstack(triangles)


def test_a_link_turning_far_on_a_nearly_still_parent_is_jointed_not_geared():
    """The arm of :func:`_sunk_arm` keyed four times: every in-between of every gap is the arm at that
    time, to 1e-6 of the diagonal. In the middle gap the contact of the outer joint, read as the
    centre of its touching vertex pairs, moved 0.0078 where the parent's 2° carried it 0.039 (under
    the finer link's edge, 0.095), so it read as a contact that stays put, and the pair as meshing
    gears: the outer link moved along its own screw, 6.1e-2 of the diagonal off, silently. Meshing
    teeth roll, each gear carrying the contact along the same arc about its axle; here the outer
    link carries it 4 × farther than its parent, which no rolling does (``ROLLING_SPREAD``)."""
    tri = _sunk_arm(0.0)[1]
    diagonal = np.linalg.norm(np.ptp(_sunk_arm(0.0)[0], axis=0))
    _keyed_four_times_follows(lambda t: _sunk_arm(t)[0], tri, 1e-6 * diagonal)


def _carried_sunk_arm(s, shift, wobble=0.0, bend=1.0):
    """The arm of :func:`_sunk_arm` at ``bend`` × ``s`` (0: held still) carried along ``s`` ×
    ``shift`` times (1, 0.4, −0.2), and turned ``wobble`` × sin(s) rad about the z axis through its
    first key's centroid (a path no screw follows where ``wobble`` is not 0): vertices, triangles."""
    x, triangles = _sunk_arm(bend * s)
    centre = _sunk_arm(0.0)[0].mean(axis=0)
    sway = Rotation.from_rotvec([0.0, 0.0, wobble * np.sin(s)]).as_matrix()
    return (x - centre) @ sway.T + centre + s * shift * np.array([1.0, 0.4, -0.2]), triangles


def _sequence_warnings(rig, triangles):
    """The ShapeDifferenceWarning messages of a sequence of ``rig`` (time → vertices) keyed at
    times 0–3 (``start="keys"``), every gap's in-betweens at 0.25 / 0.5 / 0.75 asked."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sequence = SequenceInterpolator([rig(float(k)) for k in range(4)], triangles, start="keys")
        for gap in range(3):
            sequence.poses(gap, (0.25, 0.5, 0.75))
    return [str(w.message) for w in caught if issubclass(w.category, ShapeDifferenceWarning)]


@pytest.mark.parametrize("shift", [5.0, 2.0])
def test_an_arm_carried_along_a_path_on_which_no_link_keeps_to_one_screw_is_warned(shift):
    """The arm of :func:`_sunk_arm` carried along a translation of ``shift`` a key, keyed four times:
    its base turns 0.5° a key about its root while the carry moves it far, which no one screw does
    (its key screws leave the line by 0.044 at 5 a key), and the other links turn on it, so no piece
    keeps to one screw and the group hangs from the piece that moves least, the outer link (0.07 %
    less than the base at 5 a key): 6.1e-2 of the diagonal off in the middle gap (at 2 a key 3.4e-4
    in the first), silently. The base turns least; carried by it the arm would be elsewhere, and
    the keys do not tell which piece carries the others: the gap warns (a kind the operators
    report, ``joint``)."""
    triangles = _sunk_arm(0.0)[1]
    said = _sequence_warnings(lambda t: _carried_sunk_arm(t, shift)[0], triangles)
    assert any("none of them keeps to one screw" in m for m in said), said


@pytest.mark.parametrize(("shift", "wobble", "bend"), [(0.0, 0.0, 1.0), (5.0, 0.3, 0.0)])
def test_an_arm_whose_carrier_the_keys_tell_or_that_moves_as_one_is_not_warned_of_its_carrier(
        shift, wobble, bend):
    """The counterparts: the arm of :func:`_sunk_arm` alone, its base turning steadily about its root
    (one screw: it carries the others, every in-between exact to 1e-6), and the arm held still
    (``bend`` 0: the links never turn on each other) while carried along a swaying path no screw
    follows, every piece moving as one (whichever piece carries the others places them the same):
    no warning of the carrier."""
    triangles = _sunk_arm(0.0)[1]

    def rig(t):
        return _carried_sunk_arm(t, shift, wobble, bend)[0]

    said = _sequence_warnings(rig, triangles)
    assert not any("carries the others" in m for m in said), said
    if bend:
        _keyed_four_times_follows(rig, triangles, 1e-6 * np.linalg.norm(np.ptp(rig(0.0), axis=0)))


def _reaching_arm(s):
    """A base (an ellipsoid 0.6 long) moving along a parabola, (s, 0.3 s², 0), and yawing 0.2 s rad,
    and two links (1.04 and 0.93 long, each sunk into the piece before it) on it whose tip follows
    the world line (1.2 + 0.8 s, 0.3 s² + 0.4 sin s, 0.6) by inverse kinematics (session 76's IK
    arm): vertices, triangles."""
    base = np.array([s, 0.3 * s * s, 0.0])
    yaw = Rotation.from_rotvec([0.0, 0.0, 0.2 * s])
    tip = yaw.inv().apply(np.array([1.2 + 0.8 * s, 0.3 * s * s + 0.4 * np.sin(s), 0.6]) - base - [0.0, 0.0, 0.3])
    first, second = 1.0, 0.9
    reach = min(float(np.linalg.norm(tip)), first + second - 1e-3)
    bend = np.arccos(np.clip((reach ** 2 - first ** 2 - second ** 2) / (2 * first * second), -1.0, 1.0))
    lift = np.arctan2(tip[2], np.hypot(tip[0], tip[1])) + np.arctan2(second * np.sin(bend), first + second * np.cos(bend))
    turns = (Rotation.identity(), Rotation.from_rotvec([0.0, 0.0, np.arctan2(tip[1], tip[0])])
             * Rotation.from_rotvec([0.0, -lift, 0.0]), Rotation.from_rotvec([0.0, bend, 0.0]))
    shapes = ((2, 0.6, 0.3, 0.0), (1, first + 0.04, 0.1, 0.04), (1, second + 0.03, 0.08, 0.03))
    mounts = (np.zeros(3), np.array([0.3, 0.0, 0.0]), np.array([first, 0.0, 0.0]))
    parts, triangles, count, rotation, joint = [], [], 0, Rotation.identity(), np.zeros(3)
    for k, ((level, length, radius, sunk), turn, mount) in enumerate(zip(shapes, turns, mounts)):
        link, link_triangles = icosphere(level)
        link = Rotation.from_rotvec([1.3 + 0.7 * k, 0.0, 0.0]).apply(link) * [length / 2, radius, radius]
        joint = joint + rotation.apply(mount)
        rotation = rotation * turn
        parts.append(rotation.apply(link + [length / 2 - sunk, 0.0, 0.0]) + joint)
        triangles.append(link_triangles + count)
        count += len(link)
    return yaw.apply(np.vstack(parts)) + base, np.vstack(triangles)


def test_an_arm_on_a_moving_base_keyed_closely_is_not_warned_of_its_carrier():
    """The arm of :func:`_reaching_arm` keyed every 0.25 of its time, four times: no piece keeps to
    one screw and another piece turns less than the root, but both carriers are splined through the
    same keys and place the arm alike (their difference shrinks with the fourth power of the key
    spacing; the two poses' half-way, which the check read, with its square: "up to 0.19 %" of a
    piece's size, over the allowed 1e-3): every in-between of the middle gap is the arm at its time
    to 1e-4 of the diagonal (4.9e-5), the end gaps to 2e-3 (their end conditions'), and no gap is
    warned of its carrier."""
    triangles = _reaching_arm(0.0)[1]

    def rig(t):
        return _reaching_arm(0.25 * t)[0]

    said = _sequence_warnings(rig, triangles)
    assert not any("carries the others" in m for m in said), said
    sequence = SequenceInterpolator([rig(float(k)) for k in range(4)], triangles, start="keys")
    diagonal = np.linalg.norm(np.ptp(rig(0.0), axis=0))
    for gap, atol in ((0, 2e-3), (1, 1e-4), (2, 2e-3)):
        for factor, pose in zip((0.25, 0.5, 0.75), sequence.poses(gap, (0.25, 0.5, 0.75))):
            np.testing.assert_allclose(pose, rig(gap + factor), atol=atol * diagonal)


@pytest.mark.parametrize("gap", [0, 1, 2])
def test_a_sequences_other_carrier_is_placed_as_a_gap_hung_from_it_places_it(monkeypatch, gap):
    """The arm of :func:`_reaching_arm` keyed four times (its first gap's end condition, a middle
    gap, the last gap slowing into its last key): the motions the carrier check reads for the arm
    hung from another of its pieces (``Gap.hung_motions``) are, bit for bit, those of the gap built
    with that tree (``joint_tree`` made to return it), for each other piece as the root."""
    import core.inbetween_solver as solver
    from core.inbetween_joint_doubts import CARRIER_FACTORS, _hang_from

    keys = [_reaching_arm(0.25 * k)[0] for k in range(4)]
    triangles = _reaching_arm(0.0)[1]
    chosen = SequenceInterpolator(keys, triangles, start="keys")._gap(gap)
    parents = chosen.joints[0]
    jointed = np.flatnonzero((parents >= 0) | np.isin(np.arange(parents.size), parents))
    assert jointed.size == 3
    for piece in jointed[parents[jointed] >= 0]:
        other = parents.copy()
        _hang_from(other, int(piece))
        order = [int(piece)]  # parents first
        while len(order) < jointed.size:
            order += [int(c) for c in np.flatnonzero(np.isin(other, order)) if c not in order]
        tree = (other, np.array(order))
        hung = chosen.hung_motions(tree, CARRIER_FACTORS)
        monkeypatch.setattr(solver, "joint_tree", lambda *args, **kwargs: (tree[0].copy(), tree[1].copy()))
        built = SequenceInterpolator(keys, triangles, start="keys")._gap(gap)
        monkeypatch.undo()
        np.testing.assert_array_equal(built.joints[0], other)
        for (rotations, translations), s in zip(hung, CARRIER_FACTORS):
            expected = built.motion(s)
            np.testing.assert_array_equal(rotations, expected[0])
            np.testing.assert_array_equal(translations, expected[1])


def test_a_sequences_carriers_are_compared_where_their_placements_differ_most():
    """Two placements of a two-piece group that agree at the keys and differ by a translation
    ``s (1 − s)(1/4 + s)`` of the factor s (a cubic, as two splines through the same keys differ)
    along x: the check reads the difference's peak between the keys, 0.2051 at s = 0.63, to 0.1 %,
    where read at 0.25 / 0.5 / 0.75 alone it was 0.914 × that (0.1875 at 0.75)."""
    from types import SimpleNamespace

    from core.inbetween_joint_doubts import CARRIER_FACTORS, _splined_apart

    def apart(s):
        return s * (1.0 - s) * (0.25 + s)

    points = np.random.default_rng(3).normal(size=(10, 3))  # five vertices a piece
    c = SimpleNamespace(pieces=np.array([0, 1]))
    stakes = SimpleNamespace(points=points, starts=np.array([0, 5]), counts=np.array([5, 5]))
    tree = (np.array([-1, 0]), np.array([0, 1]))

    def placements(joints, factors):
        assert tuple(factors) == CARRIER_FACTORS
        turned = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
        own = joints[0] is tree[0]
        return [(np.stack([turned, turned]), np.zeros((2, 3)) if own else np.tile([apart(s), 0.0, 0.0], (2, 1)))
                for s in factors]

    times = np.linspace(0.0, 1.0, 100001)
    np.testing.assert_allclose(_splined_apart(c, tree, stakes, [(np.array([0, 1]), 1)], placements),
                               apart(times).max(), rtol=1e-3)


def test_two_gears_one_turned_a_half_turn_beside_the_others_quarter_turn_is_warned():
    """The two-gear train with the large gear turned 90°: the small one turns −180°, which gives the
    same keys as +180°. The whole mesh's fit turns 56° (the large gear's way), and the small gear,
    turning about its own axle 124° from it, does not turn with it, so the whole's way tells it
    nothing: the gap warns that the keys do not tell which way the half turn goes. Before, the
    small gear took the whole's way, +180°, silently (0.3 of the diagonal off at 0.5); the large
    one turns about its own axle, to 1e-6."""
    a, tri, rows = _gear_train(0.0)
    poses, caught = _poses_and_warnings(Interpolator(a, _gear_train(90.0)[0], tri), FACTORS)
    assert _said(caught, "turn a half turn"), [str(w.message) for w in caught]
    for s, pose in zip(FACTORS, poses):
        np.testing.assert_allclose(pose[rows[0]], _gear_train(s * 90.0)[0][rows[0]], atol=1e-6)


def test_a_gear_turned_a_half_turn_with_the_whole_mesh_takes_its_way_silently():
    """The counterpart: the gear train turned 170° as one rigid body while the small gear turns 10°
    further on its axle, a half turn in all; the small gear turns with the whole (10° from its
    turn), which tells its way: every factor is the truth to 1e-6, without a warning."""
    a, tri, rows = _gear_train(0.0)

    def turned(s):
        x = _gear_train(0.0)[0]
        small = Rotation.from_rotvec([0.0, 0.0, np.radians(10.0 * s)]).as_matrix()
        x[rows[1]] = _rigid(x[rows[1]], small, np.array([1.53, 0.0, 0.0]))
        return _rigid(x, Rotation.from_rotvec([0.0, 0.0, np.radians(170.0 * s)]).as_matrix(), np.zeros(3))

    poses, caught = _poses_and_warnings(Interpolator(a, turned(1.0), tri), FACTORS)
    assert not _said(caught, "half turn"), [str(w.message) for w in caught]
    for s, pose in zip(FACTORS, poses):
        np.testing.assert_allclose(pose, turned(s), atol=1e-6)



@pytest.mark.parametrize("degrees", [95.0, 110.0])
def test_a_gear_turned_past_a_half_turn_by_its_mate_is_warned(degrees):
    """The two-gear train with the large gear turned 95° / 110°: the small one turns −190° / −220°,
    which the keys give as +170° / +140°, and is read so (the short way round, as every piece of
    two poses is), its teeth through the large one's half-way (0.3 of the diagonal off at 0.5). The
    gears touch in both keys and turn about parallel axles, their contact staying put: rolling on
    the large gear the small one would turn about −190° / −220°, more than a half turn from the
    turn read, and the gap warns (before, silently). The large gear turns about its own axle, to
    1e-6."""
    a, tri, rows = _gear_train(0.0)
    poses, caught = _poses_and_warnings(Interpolator(a, _gear_train(degrees)[0], tri), FACTORS)
    assert _said(caught, "as meshing gears do"), [str(w.message) for w in caught]
    for s, pose in zip(FACTORS, poses):
        np.testing.assert_allclose(pose[rows[0]], _gear_train(s * degrees)[0][rows[0]], atol=1e-6)


@pytest.mark.parametrize("degrees", [30.0, 85.0])
def test_meshing_gears_turned_under_a_half_turn_are_not_warned_of_rolling_the_other_way(degrees):
    """The counterpart: the large gear turned 30° / 85°, the small one −60° / −170°, which the keys
    read right: both gears about their own axles at every factor, to 1e-6, and no warning of gears
    turned the other way round (their roll tells each one's turn to within the contact's place)."""
    a, tri, _ = _gear_train(0.0)
    poses, caught = _poses_and_warnings(Interpolator(a, _gear_train(degrees)[0], tri), FACTORS)
    assert not _said(caught, "as meshing gears do"), [str(w.message) for w in caught]
    for s, pose in zip(FACTORS, poses):
        np.testing.assert_allclose(pose, _gear_train(s * degrees)[0], atol=1e-6)


def _sixteen_twelve_train(degrees, clearance):
    """Two meshing gears of :func:`_gear`, 16 teeth about radius 1 at the origin and 12 about radius
    0.75 beside it (tip to root ``clearance`` apart), the first turned by ``degrees`` about its axle
    and the second 16 / 12 times as far the other way about its own: vertices, triangles."""
    pitch_a, pitch_b = 2.0 * np.pi / 16, 2.0 * np.pi / 12
    axles = np.array([[0.0, 0.0, 0.0], [1.75 + clearance, 0.0, 0.0]])
    a, a_tri = _gear(16, 1.0, 0.3, axles[0], -pitch_a / 8)
    b, b_tri = _gear(12, 0.75, 0.225, axles[1], np.pi - 5 * pitch_b / 8)
    rows = [np.arange(len(a)), len(a) + np.arange(len(b))]
    vertices = np.vstack([a, b])
    for k, rate in enumerate((1.0, -16.0 / 12.0)):
        turn = Rotation.from_rotvec([0.0, 0.0, rate * np.radians(degrees)]).as_matrix()
        vertices[rows[k]] = _rigid(vertices[rows[k]], turn, axles[k])
    return vertices, np.vstack([a_tri, b_tri + len(a)])


@pytest.mark.parametrize("clearance", [0.0, 0.03])
def test_two_meshing_gears_both_turned_past_a_half_turn_are_warned(clearance):
    """Gears of 16 and 12 teeth, the large one turned 200°, the small one −267°: the keys give them
    as −160° and +93° (each the short way round), and each is read so, 0.50 of the diagonal off.
    Rolling on the large gear as read, the small one would turn +213°: past a half turn, so the
    reads do not roll on each other, but only 120° from the small one's read, which alone was
    warned of. The large gear taken the other way round (+200°) rolls the small one −267°, its read
    taken the other way round, exactly: both were read the short way, and the gap warns (before,
    silently). Each gear stays rigid, to 1e-6."""
    a, tri = _sixteen_twelve_train(0.0, clearance)
    poses, caught = _poses_and_warnings(Interpolator(a, _sixteen_twelve_train(200.0, clearance)[0], tri), FACTORS)
    assert _said(caught, "as meshing gears do"), [str(w.message) for w in caught]
    for s, pose in zip(FACTORS, poses):
        truth = _sixteen_twelve_train(s * 200.0, clearance)[0]
        for rows in (np.arange(128), np.arange(128, len(a))):
            rotation, translation = rigid_alignment(truth[rows], pose[rows])
            np.testing.assert_allclose(truth[rows] @ rotation.T + translation, pose[rows], atol=1e-6)


@pytest.mark.parametrize("degrees", [100.0, 130.0])
def test_gears_of_sixteen_and_twelve_teeth_read_right_are_not_warned_of_rolling_the_other_way(degrees):
    """The counterpart: the large gear turned 100° / 130°, the small one −133° / −173°, which the keys
    read right: both gears about their own axles at every factor, to 1e-6, and no warning of gears
    turned the other way round."""
    a, tri = _sixteen_twelve_train(0.0, 0.03)
    poses, caught = _poses_and_warnings(Interpolator(a, _sixteen_twelve_train(degrees, 0.03)[0], tri), FACTORS)
    assert not _said(caught, "as meshing gears do"), [str(w.message) for w in caught]
    for s, pose in zip(FACTORS, poses):
        np.testing.assert_allclose(pose, _sixteen_twelve_train(s * degrees, 0.03)[0], atol=1e-6)


@pytest.mark.parametrize(("train", "degrees", "turn", "read"),
                         [("20/10", 95.0, -190, 170), ("20/10", 110.0, -220, 140), ("16/12", 200.0, -267, 93)])
def test_gears_turned_the_other_way_round_are_told_of_their_true_turn(train, degrees, turn, read):
    """The warning of gears turned the other way round names the small gear's true turn (−190° /
    −220° beside the 20-tooth gear turned 95° / 110°, −267° beside the 16-tooth one turned 200°) and
    its read (+170° / +140° / +93°), 360° apart: the keys give both exactly, to a whole turn. The
    turn rolling tells is off by the contact's place off the pitch point (the closest vertex pair,
    a tooth's tip on the mate's root): the message printed that one, −237° / −274° / −317°, which
    no key gives, and an artist reading "−317° where the keys turn it +93°" looks for a turn of
    410° between the keys."""
    if train == "20/10":
        a, tri, _ = _gear_train(0.0)
        b = _gear_train(degrees)[0]
    else:
        a, tri = _sixteen_twelve_train(0.0, 0.03)
        b = _sixteen_twelve_train(degrees, 0.03)[0]
    caught = _poses_and_warnings(Interpolator(a, b, tri), (0.5,))[1]
    said = [str(w.message) for w in caught if "as meshing gears do" in str(w.message)]
    assert len(said) == 1, said
    assert f"turns one {turn:+d}° where the keys, read the short way round, turn it {read:+d}°" in said[0], said


def _spun_share(caught):
    """The share of a piece's size (a fraction) the warning of jointed pieces each turning about
    their own axis gives, or None where it is not given."""
    said = [str(w.message) for w in caught if "each turn about their own axis through them" in str(w.message)]
    assert len(said) <= 1, said
    return float(said[0].split("up to ")[1].split(" %")[0]) / 100.0 if said else None


def _off_own_turns(pose, truth, rows):
    """Per piece (``rows``: each piece's vertex rows), the farthest its vertices in ``pose`` are from
    ``truth`` ÷ the piece's bounding-box diagonal."""
    return [float(np.linalg.norm(pose[r] - truth[r], axis=1).max() / np.linalg.norm(np.ptp(truth[r], axis=0)))
            for r in rows]


@pytest.mark.parametrize("degrees", [4.0])
def test_meshing_gears_turned_too_little_to_show_their_roll_are_warned(degrees):
    """The two-gear train with the large gear turned 4° (the small one −8°), under a quarter of a
    tooth: the same vertex pairs touch in both keys and their centre moves with the gears, so the
    contact reads as carried and the small gear hangs from the large one at it, as a hinge's child
    does; two poses fit that as well as each gear on its axle. Half-way it is off its axle's turn by
    some 4 % of its size (3.9e-3 of the diagonal at ×2), silently before; now the gap warns, and the
    share the warning gives is the small gear's distance from its own turn half-way (to the
    difference between a gear's mass-weighted size and its bounding box). The large gear turns about
    its axle, to 1e-6."""
    a, tri, rows = _gear_train(0.0)
    poses, caught = _poses_and_warnings(Interpolator(a, _gear_train(degrees)[0], tri), (0.5,))
    share = _spun_share(caught)
    assert share is not None, [str(w.message) for w in caught]
    large, small = _off_own_turns(poses[0], _gear_train(0.5 * degrees)[0], rows)
    assert large <= 1e-6
    assert 1e-3 < small and 0.7 < share / small < 1.4, (share, small)


@pytest.mark.parametrize("gap, turns", [(0.1, (20.0, 50.0)), (0.1, (-30.0, 45.0)), (0.2, (-30.0, 45.0))])
def test_coarse_pieces_spinning_side_by_side_read_as_jointed_are_warned(gap, turns):
    """:func:`_coarse_cubes_spinning` about parallel axes (the cells of session 74's probe left
    jointed): the cubes' contact (their nearest vertices, within an edge in both keys) moves with
    them by under an edge, so it reads as carried, and the second cube hangs from the first at it;
    each turns about an axis through its centre, which the joint does not keep (5.7e-2–0.11 of the
    diagonal off at × 2, silently before). Now the gap warns, the share it gives is the cube's
    distance from its own turn half-way, and the first cube turns about its own centre, to 1e-6."""
    a, tri = _coarse_cubes_spinning(0.0, gap, turns, 0.0)
    poses, caught = _poses_and_warnings(Interpolator(a, _coarse_cubes_spinning(1.0, gap, turns, 0.0)[0], tri), (0.5,))
    share = _spun_share(caught)
    assert share is not None, [str(w.message) for w in caught]
    off = _off_own_turns(poses[0], _coarse_cubes_spinning(0.5, gap, turns, 0.0)[0], (np.arange(8), np.arange(8, 16)))
    assert min(off) <= 1e-6
    assert 1e-3 < max(off) and 0.7 < share / max(off) < 1.4, (share, off)


def _knob_on_lever(s, lever_turn):
    """A lever (a box 2 × 0.2 × 0.2 of three cells a side from the origin along x) turning by ``s`` ×
    ``lever_turn`` degrees about z at the origin, and a knob (a box 0.16 across) on its far end,
    touching it, turning on its own axle there by ``s`` × (180 − ``lever_turn``)°: a half turn in
    all. Vertices, triangles."""
    lever, lever_triangles = cube(3)
    lever = lever * [1.0, 0.1, 0.1] + [1.0, 0.0, 0.0]
    knob, knob_triangles = cube(2)
    knob = knob * 0.08 + [1.9, 0.0, 0.18]
    turn = lambda degrees: Rotation.from_rotvec([0.0, 0.0, np.radians(degrees)]).as_matrix()
    knob = _rigid(knob, turn(s * (180.0 - lever_turn)), np.array([1.9, 0.0, 0.0]))
    x = np.vstack([_rigid(lever, turn(s * lever_turn), np.zeros(3)), _rigid(knob, turn(s * lever_turn), np.zeros(3))])
    return x, np.vstack([lever_triangles, knob_triangles + len(lever)])


@pytest.mark.parametrize("rig, turn", [("knob", 100.0), ("knob", 130.0), ("gears", 9.0), ("gears", 30.0)])
def test_jointed_pieces_and_gears_read_right_are_not_warned_of_turning_each_about_their_own_axis(rig, turn):
    """The counterparts: a knob jointed to a turning lever's end (the lever turned 100° / 130°, the
    knob 80° / 50° on it), whose own turn is about a point beyond it, 1.5–1.7 from the knob 0.16
    across, not an axle through it (a first reading of the rule warned it); and the gear train
    turned 9° / 30°, its contact rolling, each gear on its axle. Every factor of two poses is the
    rig's, to 1e-6, and no warning of pieces each turning about their own axis."""
    rig = _knob_on_lever if rig == "knob" else (lambda s, turn: _gear_train(s * turn)[:2])
    a, tri = rig(0.0, turn)
    poses, caught = _poses_and_warnings(Interpolator(a, rig(1.0, turn)[0], tri), FACTORS)
    assert _spun_share(caught) is None, [str(w.message) for w in caught]
    for s, pose in zip(FACTORS, poses):
        np.testing.assert_allclose(pose, rig(s, turn)[0], atol=1e-6 * np.linalg.norm(np.ptp(a, axis=0)))


def _propeller_on_shaft(s, shaft_turn, blade_turn):
    """A shaft (a box 0.2 × 0.2 × 2 about the z axis) turning by ``s`` × ``shaft_turn`` degrees
    about z, and a blade (a box 2 × 0.2 × 0.04) on its top end turning on the same axle by ``s`` ×
    (``shaft_turn`` + ``blade_turn``)°, as a Blender child keyed on its parent: vertices, triangles."""
    shaft, shaft_triangles = cube(2)
    blade, blade_triangles = cube(3)
    turn = lambda degrees: Rotation.from_rotvec([0.0, 0.0, np.radians(degrees)]).as_matrix()
    x = np.vstack([(shaft * [0.1, 0.1, 1.0]) @ turn(s * shaft_turn).T,
                   (blade * [1.0, 0.1, 0.02] + [0.0, 0.0, 1.02]) @ turn(s * (shaft_turn + blade_turn)).T])
    return x, np.vstack([shaft_triangles, blade_triangles + len(shaft)])


@pytest.mark.parametrize("shaft_turn, blade_turn", [(120.0, 90.0), (60.0, 90.0)])
def test_a_propeller_turning_on_its_shaft_is_not_warned_of_turning_each_about_their_own_axis(shaft_turn,
                                                                                              blade_turn):
    """A propeller jointed to its shaft, both turning about the one axle: relative to each other they
    turn about that axle, a hinge's turn, and nothing rolls between them, so the joint is all the
    keys tell. With the blade turned 210° in all (120° + 90°) its own screw, read the short way, is
    −150° while the joint turns it the keyed +105° half-way: the joint is right, and the gap warned
    that the two keys do not tell jointed pieces from pieces each on its own axle (7669abd). Every
    factor of two poses is the rig's, to 1e-6, and no such warning; at 60° + 90° (both under a half
    turn) the two readings agree."""
    a, tri = _propeller_on_shaft(0.0, shaft_turn, blade_turn)
    poses, caught = _poses_and_warnings(Interpolator(a, _propeller_on_shaft(1.0, shaft_turn, blade_turn)[0], tri),
                                        FACTORS)
    assert _spun_share(caught) is None, [str(w.message) for w in caught]
    for s, pose in zip(FACTORS, poses):
        np.testing.assert_allclose(pose, _propeller_on_shaft(s, shaft_turn, blade_turn)[0],
                                   atol=1e-6 * np.linalg.norm(np.ptp(a, axis=0)))


def _overlapping_links(s, sunk=0.042, bend_angle=0.872):
    """Two separate links jointed end to end, the second's tip ``sunk`` into the first's (a box of
    one cell a face, 0.76 long, and a finely meshed ellipsoid 1.05 long: their surfaces cross where
    no vertex lies), the first turned ``s`` × 7.7° at its root, the second ``s`` × ``bend_angle``
    (radians) at the joint, about general axes, the arm placed off the origin: vertices, triangles."""
    def link(kind, level, length, radius, spin):
        if kind == "box":
            v, t = cube(level)
            v = v / np.abs(v).max()
        else:
            v, t = icosphere(level)
        v = Rotation.from_rotvec([spin, 0.0, 0.0]).apply(v)
        return v * [length / 2, radius, radius] + [length / 2, 0.0, 0.0], t

    first, first_triangles = link("box", 1, 0.76, 0.144, 2.94)
    second, second_triangles = link("ellipsoid", 3, 1.049, 0.18, 5.228)
    def about(angle, axis):
        return Rotation.from_rotvec(angle * np.asarray(axis) / np.linalg.norm(axis))

    turn = about(s * 0.134, [-0.575, -0.497, 0.649])
    bend = turn * about(s * bend_angle, [0.492, -0.351, 0.797])
    joint = turn.apply([0.76 - sunk, 0.0, 0.0])
    x = np.vstack([turn.apply(first), bend.apply(second - [sunk, 0.0, 0.0]) + joint])
    return (Rotation.from_rotvec([-2.516, -0.313, 0.144]).apply(x) + [1.444, 0.456, -1.907],
            np.vstack([first_triangles, second_triangles + len(first)]))


@pytest.mark.parametrize("sunk", [0.03, 0.055])
def test_links_whose_tips_overlap_are_jointed_or_warned(sunk):
    """:func:`_overlapping_links`: the links' nearest vertices are 0.107 / 0.088 apart in the first
    key (1.8–2.2 of the fine link's edges), 0.026 / 0.042 in the second, so no joint is found and
    each link moves by its own screw (4.7e-2 of the diagonal off at ×2). They turn about a point
    inside both tips, 0.16 / 0.17 from the midpoint of those vertices, which stand for where the
    surfaces cross only to within the coarse link's edge: the gap warns that they turn about a
    point between them as jointed links do (before, silently: the point was sought within the
    vertices' gap alone)."""
    a, tri = _overlapping_links(0.0, sunk)
    poses, caught = _poses_and_warnings(Interpolator(a, _overlapping_links(1.0, sunk)[0], tri), FACTORS)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    off = max(np.abs(pose - _overlapping_links(s, sunk)[0]).max() for s, pose in zip(FACTORS, poses)) / diagonal
    assert off <= 1e-6 or _said(caught, "turn about a point between them"), (off, [str(w.message) for w in caught])


def _door_on_turntable(s, table_turn, door_turn):
    """A turntable (a box 2 × 2 × 0.2 about the origin) turning by ``s`` × ``table_turn`` degrees
    about z, and a door (a box 0.1 × 1 × 1 standing on its rim) hinged on it at its edge (the
    vertical line through (1, 0)) and turning there by ``s`` × ``door_turn``°, as a Blender child
    keyed on its parent: vertices, triangles."""
    table, table_triangles = cube(3)
    door, door_triangles = cube(2)
    turn = lambda degrees: Rotation.from_rotvec([0.0, 0.0, np.radians(degrees)]).as_matrix()
    hinge = np.array([1.0, 0.0, 0.0])
    door = _rigid(door * [0.05, 0.5, 0.5] + [1.05, 0.5, 0.6], turn(s * door_turn), hinge)
    x = np.vstack([(table * [1.0, 1.0, 0.1]) @ turn(s * table_turn).T, door @ turn(s * table_turn).T])
    return x, np.vstack([table_triangles, door_triangles + len(table)])


@pytest.mark.parametrize("table_turn, door_turn", [(30.0, -60.0), (60.0, -60.0), (90.0, -120.0), (30.0, 60.0)])
def test_a_door_turning_back_against_its_turntable_hangs_from_the_turntable(table_turn, door_turn):
    """A door hinged at a turntable's rim, turning back against it: in the world it turns less than
    the turntable, or not at all (60° / −60°: it only moves along a chord), so it moved least and
    the turntable hung from it, its centre off its axle half-way (0.16–0.75 of the diagonal off,
    silently). The turntable turns on an axle through its centroid and the door does not: the group
    hangs from it, and every factor of two poses is the rig's to 1e-6 (the gap may still warn that
    two keys do not tell the carrier: they do not). 30° / +60° (the door turning with the turntable)
    is a guard."""
    a, tri = _door_on_turntable(0.0, table_turn, door_turn)
    poses, caught = _poses_and_warnings(Interpolator(a, _door_on_turntable(1.0, table_turn, door_turn)[0], tri),
                                        FACTORS)
    for s, pose in zip(FACTORS, poses):
        np.testing.assert_allclose(pose, _door_on_turntable(s, table_turn, door_turn)[0],
                                   atol=1e-6 * np.linalg.norm(np.ptp(a, axis=0)))


def _rolling_cart(angle: float):
    """A cart on a still floor (a flat box 4 × 2 × 0.05, its top at z = 0): a body (a box 1.2 × 0.6
    × 0.3) and two wheels (32-sided cylinders of radius 0.3 and width 0.1, their caps fans as
    Blender splits an n-gon) 0.005 from its sides, their rims on the floor; the wheels turned by
    ``angle`` degrees on their axles and the cart moved on by the arc they roll. Vertices, triangles
    and the floor's vertex indices."""
    radius, width = 0.3, 0.1
    floor, floor_triangles = cube(8)
    floor = floor * [2.0, 1.0, 0.025] - [0.0, 0.0, 0.025]
    body, body_triangles = cube(4)
    body = body * [0.6, 0.3, 0.15] + [0.0, 0.0, 0.35]
    wheel, wheel_triangles = meshes.capped_cylinder(32)
    wheel = (wheel * [radius, radius, width / 2]) @ Rotation.from_rotvec([np.pi / 2, 0.0, 0.0]).as_matrix().T
    roll = np.radians(angle) * radius
    turn = Rotation.from_rotvec([0.0, np.radians(angle), 0.0]).as_matrix()
    parts = [(floor, floor_triangles), (body + [roll, 0.0, 0.0], body_triangles)]
    for side in (-1.0, 1.0):
        centre = np.array([0.0, side * (0.3 + width / 2 + 0.005), radius])
        parts.append((wheel @ turn.T + centre + [roll, 0.0, 0.0], wheel_triangles))
    offsets = np.cumsum([0] + [len(v) for v, _ in parts])
    return (np.vstack([v for v, _ in parts]), np.vstack([t + o for (_, t), o in zip(parts, offsets)]),
            np.arange(len(floor)))


@pytest.mark.parametrize("angle", [90.0, 150.0])
def test_wheels_rolling_on_a_still_floor_are_no_hinges_on_it(angle):
    """A cart whose wheels roll on a still floor, two poses: at every factor (exaggerations
    included) the body has moved on by that share of the roll and the wheels turned that share on
    their axles, to 1e-6 of the diagonal, and the floor has not moved. The wheels touch the floor in
    both poses and their own screws turn about a point near where they touch it, so a wheel was
    jointed to the floor as to a hinge and the body hung from it, moved round the wheel's own screw:
    everything but the floor off by 2.2e-2 / 6.7e-2 of the diagonal at 0.5 (90° / 150°), silently.
    A hinge's contact goes where its pieces carry it and keeps the vertex pairs at its axis; a
    rolling one moves along the floor, which carries it nowhere, onto other vertices."""
    a, tri, floor = _rolling_cart(0.0)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    interpolator = Interpolator(a, _rolling_cart(angle)[0], tri)
    for s in FACTORS:
        pose = interpolator.pose(s)
        np.testing.assert_allclose(pose, _rolling_cart(s * angle)[0], atol=1e-6 * diagonal)
        np.testing.assert_array_equal(pose[floor], a[floor])


def _drum_on_plate(angle: float, carried: bool):
    """A drum (a closed tube of radius 0.2 and length 0.1, 32 sides, its axis along y) lying on a
    plate (a box 1.6 × 0.6 × 1.0, its top at z = 0), rolled ``angle`` degrees along x (turned on its
    axis and moved on by the arc it rolls); ``carried``: the plate and the drum on it turned 40° about
    a skew axis and shifted as one. Vertices, triangles and the plate's vertex indices."""
    radius = 0.2
    plate, plate_triangles = cube(8)
    plate = plate * [0.8, 0.3, 0.5] - [0.0, 0.0, 0.5]
    drum, drum_triangles = meshes.closed_tube(6, 32, length=0.1, radius=radius)
    drum = drum[:, [1, 0, 2]] - [0.0, 0.05, -radius]
    drum = _rigid(drum, Rotation.from_rotvec([0.0, np.radians(angle), 0.0]).as_matrix(), [0.0, 0.0, radius],
                  [np.radians(angle) * radius, 0.0, 0.0])
    vertices = np.vstack([plate, drum])
    if carried:
        carry = Rotation.from_rotvec(np.radians(40.0) * np.array([1.0, 1.0, 0.3]) / np.linalg.norm([1.0, 1.0, 0.3]))
        vertices = _rigid(vertices, carry.as_matrix(), [0.2, -0.1, -0.3], [0.3, 0.1, 0.2])
    return vertices, np.vstack([plate_triangles, drum_triangles[:, ::-1] + len(plate)]), np.arange(len(plate))


@pytest.mark.parametrize("angle", [90.0, 150.0])
def test_a_drum_rolling_on_a_carried_plate_sits_on_it_as_on_a_still_one(angle):
    """A drum rolling on a plate, two poses, the plate still or carried (turned 40° and shifted with
    the drum on it): at every factor (exaggerations included) the drum sits on the plate, in the
    plate's own frame, as it does on the still plate, to 1e-6 of the diagonal: carrying both pieces
    changes nothing between them. The roll takes the contact along both pieces, which holds no joint
    where another joint places one of them (a cart's wheel on its axle); a drum with no other joint
    left the carried plate's motion for its own screw, 6.9e-2 / 0.18 of the diagonal off the plate
    at 0.5 (90° / 150°, silently) where on the still plate it sits 2.9e-2 / 9.1e-2 off it."""
    a, tri, plate = _drum_on_plate(0.0, False)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    still = Interpolator(a, _drum_on_plate(angle, False)[0], tri)
    carried = Interpolator(a, _drum_on_plate(angle, True)[0], tri)
    for s in FACTORS:
        on_still, on_carried = still.pose(s), carried.pose(s)
        rotation, translation = rigid_alignment(on_carried[plate], a[plate])  # back into the plate's frame
        np.testing.assert_allclose(on_carried @ rotation.T + translation, on_still, atol=1e-6 * diagonal)


def _cabinet(s: float, n: int):
    """A cabinet of three boxes (:func:`meshes.cube` of ``n`` × ``n`` quads a face): a still back (1 ×
    0.1 × 1.5), a door below (1 × 0.04 × 1) turned ``s`` × 90° out about its hinge (the vertical line
    x = y = 0) and a drawer above it (1 × 0.54 × 0.4) slid out ``s`` × 0.4 along −y, the drawer's
    front bottom edge on the door's top front edge at ``s`` = 0 (its bottom over the door's top near
    the hinge at 1): vertices, triangles."""
    box, box_triangles = cube(n)
    turn = Rotation.from_rotvec([0.0, 0.0, -s * np.pi / 2]).as_matrix()

    def placed(lo, hi):
        return np.asarray(lo) + (box + 1.0) * 0.5 * (np.asarray(hi) - np.asarray(lo))

    parts = [placed([0.0, 0.6, 0.0], [1.0, 0.7, 1.5]), placed([0.0, -0.04, 0.0], [1.0, 0.0, 1.0]) @ turn.T,
             placed([0.0, -0.04, 1.0], [1.0, 0.5, 1.4]) + [0.0, -0.4 * s, 0.0]]
    return np.vstack(parts), np.vstack([box_triangles + k * len(box) for k in range(3)])


@pytest.mark.parametrize("n", [2, 6])
def test_a_drawer_sliding_out_over_a_turning_door_slides(n):
    """:func:`_cabinet` between two poses and keyed four times: every in-between and exaggeration
    is the cabinet at its factor to 1e-9 of the diagonal, the drawer on its straight slide. The
    door's turn and the drawer's slide compose to a turn about a vertical axis 0.24 behind the
    door's back face (over the drawer's bottom): read as a hinge, the drawer hung from the door and
    went round a circle about the door's hinge, 4.3e-2 of the diagonal off at 0.5 and 0.21 at ×2,
    2.6e-3 in the sequence's first and last gaps, silently. A joint's point is a point of both
    pieces (or of the gap between them); a piece that does not turn beside one that does, about an
    axis off one of them, slides past it."""
    rest, tri = _cabinet(0.0, n)
    _follows_its_rig(lambda s: _cabinet(s, n)[0], tri, 1e-9 * np.linalg.norm(np.ptp(rest, axis=0)))


def _level_carriage(s: float, gap: float):
    """A still base (:func:`meshes.cube` of 2 × 2 quads a face, 1 × 0.3 × 0.3 along x ∈ [0, 1]), a
    link along [1, 2] turned ``s`` × 70° about y at x = 1, and a carriage (0.6 long) ``gap`` beyond
    its end hinged there, the hinge's axis through the middle of the gap, kept level (translated
    round the hinge's arc): vertices, triangles."""
    box, box_triangles = cube(2)
    turn = Rotation.from_rotvec([0.0, -s * np.radians(70.0), 0.0])
    hinge = np.array([2.0 + gap / 2, 0.0, 0.0])
    parts = [(box + 1.0) * 0.5 * [length, 0.3, 0.3] + [start, -0.15, -0.15]
             for start, length in ((0.0, 1.0), (1.0, 1.0), (2.0 + gap, 0.6))]
    parts[1] = turn.apply(parts[1] - [1.0, 0.0, 0.0]) + [1.0, 0.0, 0.0]
    parts[2] = parts[2] + turn.apply(hinge - [1.0, 0.0, 0.0]) + [1.0, 0.0, 0.0] - hinge
    return np.vstack(parts), np.vstack([box_triangles + k * len(box) for k in range(3)])


def _gondola(s: float):
    """An arm (:func:`meshes.cube` of 2 × 2 quads a face) turned ``s`` × 90° about z at the origin,
    a pin on its end (:func:`meshes.closed_tube` of radius 0.05 along z, 11 rings) moving with it,
    and a ring round the pin touching it (:func:`meshes.twisted_torus`, major radius 0.07, minor
    0.02), kept level (translated round the arc of the pin's axis): vertices, triangles."""
    arm, arm_triangles = cube(2)
    arm = (arm + 1.0) * 0.5 * [1.1, 0.1, 0.1] + [-0.1, -0.05, -0.2]
    pin, pin_triangles = meshes.closed_tube(11, 24, length=0.2, radius=0.05)
    pin = pin[:, [1, 2, 0]] + [1.0, 0.0, -0.1]
    ring, ring_triangles = meshes.twisted_torus(24, 8, major=0.07, minor=0.02)
    turn = Rotation.from_rotvec([0.0, 0.0, s * np.pi / 2])
    end = turn.apply([1.0, 0.0, 0.0])
    vertices = np.vstack([turn.apply(arm), turn.apply(pin), ring + end])
    triangles = np.vstack([arm_triangles, pin_triangles + len(arm), ring_triangles + len(arm) + len(pin)])
    return vertices, triangles


@pytest.mark.parametrize("rig", ["touching", "apart", "ring"])
def test_a_piece_kept_level_on_a_hinge_goes_round_it(rig):
    """Pieces that do not turn hinged on one that turns (:func:`_level_carriage` touching its link's
    end or 0.04 from it, the hinge in the gap's middle; :func:`_gondola`'s ring on its pin): between
    two poses and keyed four times, every in-between and exaggeration is the rig at its factor to
    1e-9 of the diagonal, the piece going round the hinge. Their joint's point is a point of both
    pieces (the shared face's centre), of the gap between them (the link turned 47° in the third
    key: its end face 133° from the carriage's seen from the hinge), or surrounded by both (the pin
    through the ring's hole, off the ring): a joint, not pieces sliding past each other."""
    def make(s):
        return _gondola(s) if rig == "ring" else _level_carriage(s, 0.0 if rig == "touching" else 0.04)

    rest, tri = make(0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # placement is what is checked here (the ring moves least: its carrier untold)
        _follows_its_rig(lambda s: make(s)[0], tri, 1e-9 * np.linalg.norm(np.ptp(rest, axis=0)))


def test_a_wheel_hanging_on_its_axle_with_clearance_turns_about_its_own_centre():
    """A wheel (a torus of 72 × 12 quads, its hole 0.15 wide) hanging on a carried axle (a tube of
    radius 0.1) with a clearance of 0.05, wider than the wheel's edges (0.013): the axle slides
    while the wheel turns 70° about its own centre, 0.05 below the axle's axis. Their relative axis
    is inside the axle and in the wheel's hole; the wheel's touching vertices are an arc under the
    axle, but its vertices as near the axis surround it: jointed, the wheel follows the axle exactly
    (freed, it took its own screw: 4.8e-2 of the diagonal off at 0.5, 0.35 at ×2)."""
    axle, axle_triangles = meshes.closed_tube(5, 24, length=0.6, radius=0.1)
    axle = axle[:, [1, 2, 0]] - [0.0, 0.0, 0.3]  # along z, its axis through the origin
    wheel, wheel_triangles = meshes.twisted_torus(72, 12, major=0.3, minor=0.15)
    wheel = wheel + [0.0, -0.05, 0.0]  # hanging: its hole's top on the axle's top
    rest = np.vstack([axle, wheel])
    triangles = np.vstack([axle_triangles, wheel_triangles + len(axle)])
    centre = np.array([0.0, -0.05, 0.0])
    travel = np.radians(70.0) * 0.45

    def rig(s):
        turn = Rotation.from_rotvec([0.0, 0.0, -np.radians(70.0) * s]).as_matrix()
        carried = np.array([travel * s, 0.0, 0.0])
        return np.vstack([axle + carried, (wheel - centre) @ turn.T + centre + carried])

    _follows_its_rig(rig, triangles, 1e-9 * np.linalg.norm(np.ptp(np.vstack([rig(0.0), rig(1.0)]), axis=0)))
