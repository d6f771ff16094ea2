"""Per-triangle deformation fields (core/deformation_fields.py) against independent formulas."""

import pytest
import numpy as np
from scipy.linalg import expm, logm, polar, sqrtm
from scipy.spatial.transform import Rotation

import core.deformation_fields as df
from core import rotation_continuity
from core import screw_motions


def _random_triangles(count=200, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(count, 3, 3))  # corners p0, p1, p2


def test_tangent_frames_are_orthonormal_and_project_the_edges():
    corners = _random_triangles()
    edges = corners[:, [1, 2, 0]] - corners
    column_rows, coordinate_rows = df.tangent_frame_rows(edges.transpose(2, 1, 0))
    columns, coordinates = column_rows.transpose(0, 2, 1), coordinate_rows.transpose(2, 1, 0)
    frames = columns.transpose(1, 2, 0)  # (m, 3, 3) with columns t1, t2, n
    assert np.allclose(np.einsum("kab,kac->kbc", frames, frames), np.eye(3), atol=1e-13)
    assert np.allclose(np.linalg.det(frames), 1.0)
    normals = np.cross(edges[:, 0], -edges[:, 2])
    assert np.allclose(columns[2], normals / np.linalg.norm(normals, axis=1, keepdims=True))
    # the closed-form coordinates are the projections on (t1, t2)
    assert np.allclose(coordinates, np.einsum("kcd,kdj->kcj", edges, frames[:, :, :2]), atol=1e-13)


def test_planar_polar_matches_scipy_and_exp_inverts_log():
    rng = np.random.default_rng(1)
    maps = rng.normal(size=(100, 2, 2))
    maps[np.linalg.det(maps) < 0] *= np.array([[1, 1], [-1, -1]])  # positive determinants
    (cos, sin), stretch = df.planar_polar(*(maps[:, i, j] for i in (0, 1) for j in (0, 1)))
    for k in range(len(maps)):
        rotation, symmetric = polar(maps[k])  # maps = rotation @ symmetric
        assert np.allclose([[cos[k], -sin[k]], [sin[k], cos[k]]], rotation, atol=1e-12)
        assert np.allclose(stretch[k], symmetric[[0, 0, 1], [0, 1, 1]], atol=1e-12)
    packed = lambda s: np.array([[s[0], s[1]], [s[1], s[2]]])  # noqa: E731
    logs = df.log_stretch(stretch)
    for k in range(len(maps)):
        assert np.allclose(packed(logs[k]), logm(packed(stretch[k])).real, atol=1e-10)
    small = 1e-7 * rng.normal(size=(20, 3))  # the series branch
    for log in (logs, small):
        exps = df.exp_stretch(log)
        for k in range(len(log)):
            assert np.allclose(packed(exps[k]), expm(packed(log[k])), rtol=1e-12, atol=1e-14)


def test_sqrt_and_square_of_stretches_match_scipy_and_numpy():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(300, 2, 2))
    spd = a @ a.transpose(0, 2, 1) + 1e-3 * np.eye(2)
    spd[:5] = np.diag([1e-6, 50.0])  # far from isotropic
    packed = np.stack([spd[:, 0, 0], spd[:, 0, 1], spd[:, 1, 1]], axis=1)
    root, ok = df.sqrt_stretch(packed)
    assert ok.all()
    for r, g in zip(root, spd):
        expected = sqrtm(g).real
        assert np.allclose([[r[0], r[1]], [r[1], r[2]]], expected, rtol=1e-9, atol=1e-12)
    indefinite = np.array([[1.0, 2.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, -1.0]])
    assert not df.sqrt_stretch(indefinite)[1].any()
    squared = df.squared_stretch(packed)
    for q, g in zip(squared, spd):
        np.testing.assert_allclose([[q[0], q[1]], [q[1], q[2]]], g @ g, rtol=1e-12, atol=1e-12)


def test_rotation_vectors_of_frames_match_scipy_at_every_angle():
    """Also the turned frames of several components against the products written out."""
    rng = np.random.default_rng(2)
    angles = np.r_[np.linspace(0, np.pi, 60), [1e-9, np.pi - 1e-9]]
    axes = rng.normal(size=(len(angles), 3))
    rotvecs = angles[:, None] * axes / np.linalg.norm(axes, axis=1, keepdims=True)
    base = Rotation.random(len(angles), random_state=3).as_matrix()
    columns = base.transpose(2, 0, 1).copy()
    rows = lambda frames: np.ascontiguousarray(frames.transpose(0, 2, 1))  # noqa: E731
    turned = df.rotated_frames(rotvecs, np.eye(3)[None], np.zeros(len(angles), dtype=int), rows(columns))
    recovered = df.frame_rows_rotation_vectors(rows(turned), rows(columns))
    expected = Rotation.from_rotvec(rotvecs).as_matrix()
    assert np.allclose(Rotation.from_rotvec(recovered).as_matrix(), expected, atol=1e-9)
    assert np.allclose(recovered[:-1], rotvecs[:-1], atol=1e-9)  # angle < π: the vector itself
    cos, sin = np.cos(angles), np.sin(angles)
    pieces = Rotation.random(2, random_state=4).as_matrix()
    component = np.arange(len(angles)) % 2
    turned = df.turned_frame_rows(rows(columns), (cos, sin), pieces, component)
    planar = np.zeros((len(angles), 3, 3))
    planar[:, 0, 0], planar[:, 0, 1], planar[:, 1, 0], planar[:, 1, 1], planar[:, 2, 2] = cos, -sin, sin, cos, 1
    expected = pieces[component] @ base @ planar  # columns: the images of the frame
    assert np.allclose(turned, expected.transpose(2, 1, 0), atol=1e-13)


def test_rotation_entries_of_frames_are_the_products_and_give_their_vectors_and_angles():
    """The entries of ``R = Σ_c f_c b_cᵀ`` on coordinate rows against the product written out,
    from small (series branch of the vectors) to half turns; their rotation vectors are
    :func:`frame_rows_rotation_vectors`' (the same values: one formula), their angles from the
    trace the vectors' lengths (to arccos's rounding near 0 and π, √ε)."""
    rng = np.random.default_rng(5)
    angles = np.r_[np.linspace(0, np.pi, 60), [1e-9, np.pi - 1e-9]]
    axes = rng.normal(size=(len(angles), 3))
    rotvecs = angles[:, None] * axes / np.linalg.norm(axes, axis=1, keepdims=True)
    columns = np.ascontiguousarray(Rotation.random(len(angles), random_state=6).as_matrix().transpose(2, 1, 0))
    frames = np.ascontiguousarray(np.einsum("mab,cbm->cam", Rotation.from_rotvec(rotvecs).as_matrix(), columns))
    entries = df.frame_rows_rotation_entries(frames, columns)
    matrices = Rotation.from_rotvec(rotvecs).as_matrix()
    np.testing.assert_allclose(entries, matrices.transpose(1, 2, 0), rtol=0, atol=1e-14)
    np.testing.assert_allclose(entries, np.einsum("cam,cbm->abm", frames, columns), rtol=0, atol=1e-15)
    assert np.array_equal(df.rotation_vectors_of_entries(entries), df.frame_rows_rotation_vectors(frames, columns))
    np.testing.assert_allclose(df.entries_rotation_angles(entries), angles, rtol=0, atol=1e-7)


def test_rotated_frames_of_several_components_match_the_matrices():
    """Rodrigues on coordinate rows against SciPy's matrices, small (series branch) to large angles."""
    rng = np.random.default_rng(5)
    m = 90
    rotvecs = rng.normal(size=(m, 3)) * np.r_[np.full(30, 1e-7), np.full(30, 0.3), np.full(30, 3.0)][:, None]
    base = Rotation.random(m, random_state=6).as_matrix()
    column_rows = np.ascontiguousarray(base.transpose(2, 1, 0))  # (3 columns, 3 coordinates, m)
    pieces = Rotation.random(3, random_state=7).as_matrix()
    component = np.arange(m) % 3
    frames = df.rotated_frames(rotvecs, pieces, component, column_rows)  # (3 columns, m, 3)
    expected = pieces[component] @ Rotation.from_rotvec(rotvecs).as_matrix() @ base
    assert np.allclose(frames, expected.transpose(2, 0, 1), atol=1e-14)


def test_planar_maps_take_the_base_edges_to_the_others():
    corners = _random_triangles(seed=8)
    other = corners + 0.2 * _random_triangles(seed=9)
    rows = lambda c: np.ascontiguousarray((c[:, [1, 2, 0]] - c).transpose(2, 1, 0))  # noqa: E731
    _, base_coordinates = df.tangent_frame_rows(rows(corners))
    _, coordinates = df.tangent_frame_rows(rows(other))
    a, b, c, d = df.planar_map_entries(coordinates, df.inverse_edge_rows(base_coordinates))
    maps = np.stack([np.stack([a, b], -1), np.stack([c, d], -1)], -2)  # (m, 2, 2)
    base_edges = base_coordinates.transpose(2, 0, 1)  # (m, 2, 3 corners): columns are the edges
    other_edges = coordinates.transpose(2, 0, 1)
    assert np.allclose(maps @ base_edges, other_edges, atol=1e-10)


def test_unwrapped_rotation_vectors_continue_a_turn_past_a_half_turn():
    rng = np.random.default_rng(10)
    axes = rng.normal(size=(50, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    turned = np.radians(200.0) * axes  # continuing a turn of 100° per key past the half turn
    short = Rotation.from_rotvec(turned).as_rotvec()  # the same rotations, the short way (−160°)
    reference = 2 * np.radians(100.0) * axes
    out = rotation_continuity.unwrapped_rotation_vectors(short, reference)
    assert np.allclose(out, turned, atol=1e-12)
    assert np.allclose(Rotation.from_rotvec(out).as_matrix(), Rotation.from_rotvec(short).as_matrix(), atol=1e-12)
    small = 0.3 * axes  # turns far from the half turn continuing small ones: left as they are
    assert np.array_equal(rotation_continuity.unwrapped_rotation_vectors(small, 2 * 0.2 * axes), small)


def test_unwrapped_rotation_vectors_continue_a_turn_past_three_half_turns():
    """A part of an arm turning 300° per gap is continued to 600° at the key after, which the
    representatives k = −1, 0, 1 of its principal vector (−120°) do not reach: the one nearest
    the reference is taken whatever its k."""
    axes = np.eye(3)
    turned = np.radians(600.0) * axes
    short = Rotation.from_rotvec(turned).as_rotvec()
    np.testing.assert_allclose(rotation_continuity.unwrapped_rotation_vectors(short, 2 * np.radians(300.0) * axes), turned, atol=1e-12)


def test_unwrapped_rotation_vectors_take_the_turn_nearest_the_reference_however_far():
    """Turns about an axis of 0 … 5π, each with a reference within 0.9π of it along the axis (a
    curl continued from the key before: 520° for 560°), come back whole from their principal
    vectors, whichever way round those point (past 3π the principal axis is the reverse)."""
    axis = np.array([[0.0, 0.0, 1.0]])
    for true in np.linspace(0.05, 5.0 * np.pi, 101):  # one at a time: the farthest reference sets the reach
        turned = true * axis
        short = Rotation.from_rotvec(turned).as_rotvec()
        for offset in (-0.9 * np.pi, -0.5 * np.pi, 0.0, 0.5 * np.pi, 0.9 * np.pi):
            out = rotation_continuity.unwrapped_rotation_vectors(short, (true + offset) * axis)
            np.testing.assert_allclose(out, turned, atol=1e-9)


def test_rotations_are_not_taken_continuous_across_a_crease():
    """A chain of triangles turning about y by up to 260°, in steps of 0.2 rad (a part curling
    smoothly past a half turn) is taken continuous; in steps of 1 rad (57°: the jump past the half
    turn joins triangles at a fold's crease: :func:`~core.rotation_continuity.creased` at
    :data:`~core.rotation_continuity.WRAP_CREASE` on the jump) it is told apart, and the mesh's
    continuity alone continues both."""
    for step, continued in ((0.2, True), (1.0, False)):
        angles = np.arange(0.0, np.radians(260.0), step)
        turned = np.outer(angles, [0.0, 1.0, 0.0])
        rotvec = Rotation.from_rotvec(turned).as_rotvec()
        assert not np.allclose(rotvec, turned)  # past a half turn: the principal vectors jump
        pairs = np.stack([np.arange(len(angles) - 1), np.arange(1, len(angles))], axis=1)
        pieces = np.zeros(len(angles), dtype=int)
        jumps = pairs[rotation_continuity.jumping_pairs(rotvec, pairs)]
        assert len(jumps) == 1 and rotation_continuity.creased(rotvec, jumps, rotation_continuity.WRAP_CREASE).all() != continued
        np.testing.assert_allclose(rotation_continuity.continuous_rotation_vectors(rotvec, pairs, pieces), turned, atol=1e-12)


def test_rotations_taken_continuous_turn_as_the_rigid_motion_where_both_ends_turn_as_little():
    """A chain of triangles turning about z from −60.5° at one end to −300.5° at the other in steps
    of 2° (a tail wagging: its root turns 60.5°, each joint 60° more): the tip's principal vector,
    59.5° the other way, is the least-turned one, so the chain continued from it reads +299.5° …
    +59.5°, a whole turn more of the entire chain. The two ends' least turns are 1° apart, under
    the 2° step between neighbours: taken toward the chain's rigid motion (−130° about z), it reads
    −60.5° … −300.5°, toward +130° the other way. A chain from 0° to −220° (a strip held at one end
    and curled) reads so whatever the rigid motion (its principal rotation +129°): its tip's 140° the
    other way is far from the held end's 0°."""
    def chain(first, last):
        angles = -np.radians(np.arange(first, last + 1.0, 2.0))
        turned = np.outer(angles, [0.0, 0.0, 1.0])
        pairs = np.stack([np.arange(len(angles) - 1), np.arange(1, len(angles))], axis=1)
        return turned, Rotation.from_rotvec(turned).as_rotvec(), pairs, np.zeros(len(angles), dtype=int)

    def toward(rigid, m):
        return np.tile([0.0, 0.0, np.radians(rigid)], (m, 1)), np.ones(m)

    turned, rotvec, pairs, pieces = chain(60.5, 300.5)
    whole = [0.0, 0.0, 2.0 * np.pi]
    np.testing.assert_allclose(rotation_continuity.continuous_rotation_vectors(rotvec, pairs, pieces), turned + whole, atol=1e-12)
    for rigid, expected in ((-130.0, turned), (130.0, turned + whole)):
        out = rotation_continuity.continuous_rotation_vectors(rotvec, pairs, pieces, toward=toward(rigid, len(rotvec)))
        np.testing.assert_allclose(out, expected, atol=1e-12)
    turned, rotvec, pairs, pieces = chain(0.0, 220.0)
    for rigid in (129.0, -129.0):
        out = rotation_continuity.continuous_rotation_vectors(rotvec, pairs, pieces, toward=toward(rigid, len(rotvec)))
        np.testing.assert_allclose(out, turned, atol=1e-12)


def test_rotations_taken_continuous_turn_from_the_part_whose_reading_keeps_the_axes_together():
    """A chain of triangles turning 20° about z (an arm's part that stays, turning with the whole
    arm), the rest curling on from it about y by up to 340° in steps of 2°: each triangle turns by
    the turn about z composed with its curl. The curling end's principal rotation (28°) is within
    the tie of the still end's 20°, and continued from the curling end every triangle takes a
    whole turn about its own axis, which parts where the axes swing from z to y: the chain's
    rotations at a factor are then not a turn of it (neighbours turned more than WRAP_CREASE
    apart). Whatever the rigid motion (the arm's fit reads the curl the other way round: +2 rad
    about y), it reads from the end turning 20° (toward +2 rad about y, it read the chain from
    the curling end: the part that stays 340° round)."""
    curl = np.radians(np.r_[np.zeros(10), np.arange(0.0, 340.0 + 1e-9, 2.0)])
    turns = Rotation.from_rotvec([0.0, 0.0, np.radians(20.0)]) * Rotation.from_rotvec(np.outer(-curl, [0.0, 1.0, 0.0]))
    rotvec, m = turns.as_rotvec(), len(curl)
    pairs, pieces = np.stack([np.arange(m - 1), np.arange(1, m)], axis=1), np.zeros(m, dtype=int)
    from_still = rotation_continuity.continuous_rotation_vectors(rotvec, pairs, pieces)
    np.testing.assert_allclose(from_still[:10], rotvec[:10], atol=1e-12)
    for rigid in ([0.0, 2.0, 0.0], [0.0, -2.0, 0.0], [0.0, 0.0, 0.35]):
        out = rotation_continuity.continuous_rotation_vectors(rotvec, pairs, pieces, toward=(np.tile(rigid, (m, 1)), np.ones(m)))
        np.testing.assert_allclose(out, from_still, atol=1e-12)


def test_rigid_logs_invert_the_exponential_and_take_the_reference_turn():
    """Screw coordinates of 300 rigid motions at once (angles 0 … π, translations up to 1e3) are
    each the single motion's, and the exponential gives the motions back; a half turn goes the
    way its reference turns; unwrapped, a turn continues past a half turn; whole turns (no
    rotation, references near 2π and 6π) keep the reference's v off their axis (V(2πkû) = ûûᵀ,
    whose round-off singular values must not be inverted)."""
    rng = np.random.default_rng(6)
    axes = rng.normal(size=(300, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    angles = rng.choice([0.0, 1e-7, 0.5, 2.0, 3.0, np.pi - 1e-3], 300)
    rotations = Rotation.from_rotvec(axes * angles[:, None]).as_matrix()
    translations = rng.normal(size=(300, 3)) * rng.choice([0.0, 1.0, 1e3], (300, 1))
    screws = screw_motions.rigid_logs(rotations, translations)
    back_rotations, back_translations = screw_motions.rigid_exps(screws)
    assert np.abs(back_rotations - rotations).max() < 1e-12
    assert np.abs(back_translations - translations).max() < 1e-9
    # the translation V(ω) v with NumPy's cross products, bit for bit
    w, v = screws[:, :3], screws[:, 3:]
    a, b = screw_motions._screw_coefficients(np.linalg.norm(w, axis=1))
    turned = np.cross(w, v)
    np.testing.assert_array_equal(back_translations, v + a[:, None] * turned + b[:, None] * np.cross(w, turned))
    assert np.allclose(screw_motions.rigid_log(rotations[7], translations[7]), screws[7], rtol=1e-12, atol=1e-12)

    half = Rotation.from_rotvec([0.0, 0.0, np.pi]).as_matrix()[None]
    for sign in (1.0, -1.0):
        assert screw_motions.rigid_logs(half, np.zeros((1, 3)), np.array([[0.0, 0.0, sign]]))[0, 2] == pytest.approx(sign * np.pi)
    past = Rotation.from_rotvec([0.0, 0.0, -2.0]).as_matrix()[None]  # 2π − 2 the other way round
    continued = screw_motions.rigid_logs(past, np.zeros((1, 3)), np.array([[0.0, 0.0, 4.0]]), unwrap=True)[0]
    assert continued[2] == pytest.approx(2 * np.pi - 2.0)

    references = np.array([np.r_[2 * np.pi * np.array([0.6, 0.0, 0.8]) + 0.01, 0.3, -0.2, 0.5],
                           [-10.689591752508218, 2.87024259229626, 11.60761500054216,
                            -10.035689726411743, 6.439175502723993, -1.4630745878746887]])
    shifts = np.array([[0.2, 0.1, 0.4], [-1702.633218528604, -1206.8897435037434, -779.3230025985741]])
    whole = screw_motions.rigid_logs(np.repeat(np.eye(3)[None], 2, axis=0), shifts, references, unwrap=True)
    for turns, screw, reference, t in zip((1, 3), whole, references, shifts):
        axis = reference[:3] / np.linalg.norm(reference[:3])
        assert np.allclose(screw[:3], 2 * np.pi * turns * axis)
        v = reference[3:]
        assert np.allclose(screw[3:], v + axis * (axis @ (t - v)), rtol=1e-9, atol=1e-9)


def test_framed_screws_are_the_motions_seen_in_each_frame_and_world_screws_undo_them():
    """A screw taken into a frame ``y = A (x − o)`` (:func:`~core.screw_motions.framed_screws`)
    moves the frame's points as the world screw moves the world's, for every representative of
    its turn (past a half turn and a whole one included); :func:`~core.screw_motions.world_screws`
    gives the world screw back; both with NumPy's cross products, bit for bit."""
    rng = np.random.default_rng(11)
    count = 40
    axes = Rotation.random(count, random_state=12).as_matrix()
    origins = rng.normal(size=(count, 3)) * rng.choice([1.0, 1e3], (count, 1))
    turn_axes = rng.normal(size=(count, 3))
    turn_axes /= np.linalg.norm(turn_axes, axis=1)[:, None]
    angles = rng.choice([0.0, 0.4, 3.0, np.pi + 0.5, 2 * np.pi + 0.3], count)
    screws = np.concatenate([turn_axes * angles[:, None], rng.normal(size=(count, 3))], axis=1)
    framed = screw_motions.framed_screws(screws, axes, origins)
    rotations, translations = screw_motions.rigid_exps(screws)
    framed_rotations, framed_translations = screw_motions.rigid_exps(framed)
    points = rng.normal(size=(count, 3))
    moved_in_frame = np.einsum("pab,pb->pa", axes, np.einsum("pab,pb->pa", rotations, points) + translations - origins)
    in_frame = np.einsum("pab,pb->pa", axes, points - origins)
    seen = np.einsum("pab,pb->pa", framed_rotations, in_frame) + framed_translations
    rounding = 1e-13 * (1.0 + np.abs(origins).max())  # a few ulps of the largest coordinates (origins × turns)
    np.testing.assert_allclose(seen, moved_in_frame, atol=rounding)
    np.testing.assert_allclose(screw_motions.world_screws(framed, axes, origins), screws, atol=rounding)
    w, v = screws[:, :3], screws[:, 3:]
    np.testing.assert_array_equal(framed[:, 3:], np.einsum("pab,pb->pa", axes, v - np.cross(origins, w)))
    back = np.einsum("pba,pb->pa", axes, framed[:, :3])
    np.testing.assert_array_equal(screw_motions.world_screws(framed, axes, origins)[:, 3:],
                                  np.einsum("pba,pb->pa", axes, framed[:, 3:]) + np.cross(origins, back))


def test_similarity_paths_are_the_powers_of_the_similarity():
    """``exp(s log S)`` of a rigid motion times a uniform scale (SciPy's matrix logarithm and
    exponential of the 4 × 4 matrix) at factors in and beyond [0, 1], and for a rigid motion the
    screw motion of :func:`rigid_exps`."""
    rng = np.random.default_rng(3)
    for scale in (1.0, 1.3, 0.6):
        for angle in (0.0, 1e-7, 0.4, 2.9):
            w = rng.standard_normal(3)
            w *= angle / np.linalg.norm(w)
            t, p = rng.standard_normal(3), rng.standard_normal(3)
            matrix = np.eye(4)
            matrix[:3, :3], matrix[:3, 3] = scale * Rotation.from_rotvec(w).as_matrix(), t
            for s in (0.5, 2.0, -0.5):
                x, ok = screw_motions.similarity_paths(w[None], np.array([np.log(scale)]), t[None], p[None], s)
                if scale == 1.0:
                    screw = screw_motions.rigid_logs(matrix[None, :3, :3], t[None])
                    rotation, translation = screw_motions.rigid_exps(s * screw)
                    expected = rotation[0] @ p + translation[0]
                else:
                    power = np.real(expm(s * logm(matrix)))
                    expected = power[:3, :3] @ p + power[:3, 3]
                assert ok.all()
                np.testing.assert_allclose(x[0], expected, atol=1e-12)


@pytest.mark.parametrize("short_of_half", [1e-7, 1e-3, 9e-3])
def test_a_turn_taken_the_long_way_within_its_spread_is_the_same_motion(short_of_half):
    """A rotation just short of a half turn, whose reference turns the other way, is taken the long
    way round within its spread: its screw is the same rigid motion (the inverse rotation, −ω,
    missed it by 2 (π − θ))."""
    axis = np.array([0.0, 0.0, 1.0])
    rotation = Rotation.from_rotvec((np.pi - short_of_half) * axis).as_matrix()[None]
    translation = np.array([[0.3, -0.2, 0.5]])
    screw = screw_motions.rigid_logs(rotation, translation, -axis[None], spread=0.01)
    assert screw[0, :3] @ axis < 0  # the reference's way
    back_rotation, back_translation = screw_motions.rigid_exps(screw)
    np.testing.assert_allclose(back_rotation, rotation, atol=1e-12)
    np.testing.assert_allclose(back_translation, translation, atol=1e-12)


def test_rotations_are_taken_continuous_on_many_pieces_in_one_search(monkeypatch):
    """3,000 pieces of two triangles, one of them with its second triangle's rotation vector past a
    half turn from its first's (3 rad about y, then −3 rad: the same way round, 2π − 3 on): that
    triangle takes its continuous representative and every other piece is left as it is, found by
    one breadth-first search over the regions the jumps link (a search from every region took a
    pass over all regions each: 0.33 s CPU here, 1.2 s at 10,000 pieces)."""
    import scipy.sparse.csgraph as csgraph

    pieces_count = 3000
    pairs = np.stack([2 * np.arange(pieces_count), 2 * np.arange(pieces_count) + 1], axis=1)
    pieces = np.repeat(np.arange(pieces_count), 2)
    rotvec = np.zeros((2 * pieces_count, 3))
    rotvec[0, 1], rotvec[1, 1] = 3.0, -3.0
    rotvec[2::2, 1], rotvec[3::2, 1] = 0.5, 0.6  # the other pieces turn without a jump
    searches = []
    search = csgraph.breadth_first_order
    monkeypatch.setattr(csgraph, "breadth_first_order", lambda *a, **k: searches.append(1) or search(*a, **k))
    out = rotation_continuity.continuous_rotation_vectors(rotvec, pairs, pieces)
    np.testing.assert_allclose(out[:2], [[0.0, 3.0, 0.0], [0.0, 2.0 * np.pi - 3.0, 0.0]], rtol=0.0, atol=1e-12)
    np.testing.assert_array_equal(out[2:], rotvec[2:])
    assert len(searches) == 1


def test_metrics_not_positive_definite_get_unit_roots_and_no_floating_point_error():
    """The rows of sqrt_det and sqrt_stretch that are not positive definite are set to 1 and the
    identity before their roots are taken: no invalid root is evaluated, the others are exact."""
    good = np.array([[2.0, 0.5, 1.0], [1.0, 0.0, 1.0], [4.0, -1.0, 3.0]])
    bad = np.array([[1.0, 2.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, -1.0], [1.0, 0.0, -1e-3]])
    g = np.concatenate([good, bad])[[0, 3, 1, 4, 5, 2, 6]]
    with np.errstate(all="raise"):
        root, ok = df.sqrt_det(g)
        stretch, also = df.sqrt_stretch(g)
    np.testing.assert_array_equal(ok, [True, False, True, False, False, True, False])
    np.testing.assert_array_equal(also, ok)
    np.testing.assert_array_equal(root[~ok], 1.0)
    np.testing.assert_array_equal(stretch[~ok], np.tile([1.0, 0.0, 1.0], (4, 1)))
    np.testing.assert_allclose(root[ok], np.sqrt(good[:, 0] * good[:, 2] - good[:, 1] ** 2), rtol=1e-15)
    for s, m in zip(stretch[ok], good):
        u = np.array([[s[0], s[1]], [s[1], s[2]]])
        np.testing.assert_allclose(u @ u, [[m[0], m[1]], [m[1], m[2]]], rtol=1e-14, atol=1e-15)
