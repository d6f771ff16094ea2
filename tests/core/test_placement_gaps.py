"""How the gaps of a sequence are solved and joined (core.inbetween_prediction,
core.inbetween_corrections, core.inbetween_keys, core.splines; issue 17 items 1 and 3): predicted
in-betweens and their corrections, the keys' relatives, the velocities at the keys. No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import core.inbetween_solver as solver
from core.errors import ShapeDifferenceWarning
from core.sequence_inbetweens import SequenceInterpolator

import meshes
from meshes import grid, icosphere
from placement_helpers import FACTORS, _rigid


def test_gaps_whose_keys_barely_differ_are_the_linear_blend():
    """A sheet that falls and then jitters in place (keys 0.02 mean edges apart, not rigidly, as a
    cloth settling on a rail): the settled gaps' in-betweens are the linear blend of their keys —
    the fit has no metric to add to a motion that small, and the splines would lend those gaps the
    velocity of the fall — while the falling gaps are not."""
    import core.inbetween_prediction as prediction

    flat, tri = grid(12)
    mean_edge = np.linalg.norm(flat[tri[:, 1]] - flat[tri[:, 0]], axis=1).mean()
    rng = np.random.default_rng(3)
    keys = [flat + [0.0, 0.0, 1.0 - h] for h in (0.0, 0.3, 0.8)]
    keys[2] = meshes.drape(keys[2], 0.2)
    for _ in range(3):
        keys.append(keys[2] + 0.02 * mean_edge * rng.standard_normal(flat.shape))
    moves = [np.sqrt(np.mean(np.sum((b - a) ** 2, axis=1))) / mean_edge for a, b in zip(keys, keys[1:])]
    assert min(moves[:2]) > 1.0 and max(moves[3:]) < prediction.STILL_MOVE
    seq = SequenceInterpolator(keys, tri)
    factors = [0.25, 0.5, 0.75]
    for gap in range(len(keys) - 1):
        blend = [(1 - s) * keys[gap] + s * keys[gap + 1] for s in factors]
        poses = seq.poses(gap, factors)
        if gap >= 3:
            np.testing.assert_allclose(poses, blend, atol=1e-12)
        elif gap < 2:
            assert np.abs(np.array(poses) - blend).max() > 1e-3


@pytest.mark.parametrize("degrees", [100.0, 178.0])
def test_a_rolling_ball_leaves_each_key_with_one_velocity(degrees):
    """A ball rolling (turning about its moving centre) ``degrees`` per key: its screw spline's
    tangent at an inner key is, from both gaps, the central difference of the steps on either
    side, so its in-betweens leave the key with one velocity (to the finite difference's error;
    before: 5 % apart at 100°, 540 % at 178°), and near a half turn per key it stays near its path
    (0.11 of its radius at 178°, the screw's own departure from rolling; before: 4.5 radii, its
    motion over two keys taken as one screw of nearly a whole turn)."""
    ball, tri = icosphere(2)

    def rolled(t):
        return Rotation.from_rotvec([0.0, np.radians(degrees) * t, 0.0]).apply(ball) + [0.3 * t, 0.0, 0.0]

    sequence = SequenceInterpolator([rolled(k) for k in range(5)], tri, start="keys")
    for gap in range(4):
        for s, x in zip(FACTORS[1:4], sequence.poses(gap, FACTORS[1:4])):
            assert np.abs(x - rolled(gap + s)).max() < 0.15
    step = 1e-4
    for key in (1, 2):
        before = (sequence.pose(key - 1, 1.0) - sequence.pose(key - 1, 1.0 - step)) / step
        after = (sequence.pose(key, step) - sequence.pose(key, 0.0)) / step
        assert np.abs(before - after).max() < 1e-3 * np.abs(after).max()


def test_gap_results_do_not_depend_on_what_was_computed_before():
    """A farm computes gaps in any order, in separate processes: the same gap and factors give
    the same poses whatever was asked before, to round-off. Not bit for bit: on AVX-512 machines
    NumPy's and OpenBLAS's small products pick their kernels by memory alignment, so the same
    computation twice in one process can differ in the last bit (measured 9e-16 of the size)."""
    flat, tri = grid(12, 9, size=1.0)
    keys = [flat + np.array([0.0, 0.0, -0.1 * k * k]) + 0.05 * np.sin(3 * flat[:, [1, 0, 0]] + k) for k in range(5)]
    factors = [0.25, 0.5, 0.75]
    fresh = SequenceInterpolator(keys, tri).poses(2, factors)
    busy = SequenceInterpolator(keys, tri)
    for gap in (3, 0, 1):
        busy.poses(gap, factors)
    np.testing.assert_allclose(busy.poses(2, factors), fresh, rtol=0, atol=1e-12)
    solved = np.stack([SequenceInterpolator(keys, tri).pose(2, f) for f in factors])
    np.testing.assert_allclose(np.stack([busy.pose(2, f) for f in factors]), solved, rtol=0, atol=1e-12)


def test_predicted_inbetweens_stay_near_the_solved_ones():
    """A batch of in-betweens solves one to three of them and predicts the rest from their
    corrections to the keys' spline: the solved ones are those of ``pose`` (three in-betweens: the
    middle; fifteen: the quarter points and the middle), the predicted ones close to them (the
    correction is smooth in the factor)."""
    flat, tri = grid(12, 9, size=1.0)
    keys = [flat + np.array([0.0, 0.0, -0.1 * k * k]) + 0.05 * np.sin(3 * flat[:, [1, 0, 0]] + k) for k in range(5)]
    seq = SequenceInterpolator(keys, tri)
    for factors, solved_factors in (([0.25, 0.5, 0.75], (0.5,)), (np.arange(1, 16) / 16, (0.25, 0.5, 0.75))):
        batch = seq.poses(2, factors)
        solved = np.stack([seq.pose(2, f) for f in factors])
        blend = np.stack([(1 - f) * keys[2] + f * keys[3] for f in factors])
        for k in [k for k, f in enumerate(factors) if f in solved_factors]:  # the same solve (to round-off)
            np.testing.assert_allclose(batch[k], solved[k], rtol=0, atol=1e-12)
        # measured 2.2 % (3 in-betweens) and 1.1 % (15) of how far the solve moves from the blend
        # (1.3 / 0.7 % with Catmull–Rom's tangents at key 2, where the five keys' tangent puts the
        # batch and the solves 15–18 % nearer the keys' own motion, z = −0.1 k² + 0.05 sin(…+ k))
        assert np.abs(batch - solved).max() < 0.025 * np.abs(solved - blend).max()


def _bent_limb(degrees, rings=41, sides=16, joint=1.0, width=0.15):
    """A tube of radius 0.1 along x from 0 to 2 (``rings`` × ``sides`` vertices) and its pose with
    the part past ``joint`` turned by ``degrees`` about z through the joint, blended linearly over
    ``joint ± width`` with smoothstep weights (linear-blend skinning of a two-bone limb)."""
    u, a = np.linspace(0.0, 2.0, rings), 2 * np.pi * np.arange(sides) / sides
    rest = np.array([(x, 0.1 * np.cos(t), 0.1 * np.sin(t)) for x in u for t in a])
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(sides), indexing="ij")
    p, q = (i * sides + j).ravel(), (i * sides + (j + 1) % sides).ravel()
    r, s = q + sides, p + sides
    tri = np.concatenate([np.stack([p, q, r], 1), np.stack([p, r, s], 1)])
    w = np.clip((rest[:, 0] - joint + width) / (2 * width), 0.0, 1.0)
    w = w * w * (3 - 2 * w)
    turned = Rotation.from_rotvec([0.0, 0.0, np.radians(degrees)]).apply(rest - [joint, 0, 0]) + [joint, 0, 0]
    return rest, (1 - w)[:, None] * rest + w[:, None] * turned, tri


def test_a_limb_bending_between_two_keys_is_predicted_no_farther_from_the_rig_than_the_solved_middle():
    """Two keys of a limb bending 100° at a joint, three in-betweens asked together: the keys'
    per-vertex spline is their chord, and the quartic through the solved middle that takes its
    velocity at the keys put the quarter points 2.7e-2 of the diagonal off the rig's bend where the
    middle is 2.4e-2 off (and solving them 1.7e-2 / 1.9e-2). The keys' slopes and the middle then
    tell corrections more than ``MAX_SLOPE_DISAGREEMENT`` mean edges apart, and the in-betweens are
    solved: the solve's miss of the rig vanishes at the keys and is largest half-way, so no
    in-between is farther from the rig's pose at its factor than the middle one."""
    rest, _, tri = _bent_limb(0.0)
    keys = [rest, _bent_limb(100.0)[1]]
    factors = [0.25, 0.5, 0.75]
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)  # nothing to say: anchored as two poses are
        batch = SequenceInterpolator(keys, tri).poses(0, factors)
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    miss = [np.sqrt(np.mean(np.sum((x - _bent_limb(100.0 * f)[1]) ** 2, axis=1))) / diagonal
            for x, f in zip(batch, factors)]
    blend = np.sqrt(np.mean(np.sum((0.5 * (keys[0] + keys[1]) - _bent_limb(50.0)[1]) ** 2, axis=1))) / diagonal
    assert miss[1] < 0.5 * blend  # the middle is the shape difference's, far nearer the rig than the blend
    assert max(miss[0], miss[2]) <= miss[1]


def test_a_folded_prediction_is_repaired_where_the_fold_is(monkeypatch):
    """A predicted in-between with a folded triangle is repaired around the fold (no flip left),
    not solved again: only the quarter points and the midpoint are solved."""
    import core.inbetween_prediction as prediction

    flat, tri = grid(12, 9, size=1.0)
    keys = [flat + np.array([0.0, 0.0, -0.1 * k * k]) + 0.05 * np.sin(3 * flat[:, [1, 0, 0]] + k) for k in range(5)]
    i, j, k = tri[len(tri) // 2]
    real_correction, real_pose = prediction.correction_polynomial, solver.Gap.pose

    def folding_correction(gap, solved):
        correction = real_correction(gap, solved)
        if len(solved) < 3:  # the consistency check of the solved corrections: left as it is
            return correction

        def folded(s):  # vertex i reflected through the midpoint of its opposite edge
            out = correction(s).copy()
            v = gap.splines["vertices"].at(s) + out
            out[i] += v[j] + v[k] - 2.0 * v[i]
            return out
        return folded

    solved, repaired, real_repaired = [], [], solver.Gap.repaired
    monkeypatch.setattr(prediction, "correction_polynomial", folding_correction)
    monkeypatch.setattr(solver.Gap, "pose", lambda self, s, **kw: solved.append(s) or real_pose(self, s, **kw))
    monkeypatch.setattr(solver.Gap, "repaired", lambda self, x, s, *rest: repaired.append(s) or real_repaired(self, x, s, *rest))
    seq = SequenceInterpolator(keys, tri)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)  # repaired: no fallback
        batch = seq.poses(2, np.arange(1, 16) / 16)  # 15 in-betweens: three solved
    assert sorted(solved) == [0.25, 0.5, 0.75] and len(repaired) == 12  # every predicted one was folded

    def normals(x):
        return np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])

    for x in batch:
        assert not ((np.sum(normals(x) * normals(keys[2]), axis=1) < 0)
                    & (np.sum(normals(x) * normals(keys[3]), axis=1) < 0)).any()


def test_rough_corrections_are_solved_densely_and_predicted_between(monkeypatch):
    """Corrections that vary smoothly with the factor are predicted from three solved ones; when the
    middle solved one is far from what the others predict (a flap between the keys), the gap is
    solved again at every eighth, all with the wide rotation limit (the three solved first too: kept
    at the narrow one among neighbours at the wide one, they stood out), and each in-between left
    is predicted from the two solved around it, never more than a sixteenth of the gap away."""
    import core.inbetween_corrections as corrections
    import core.inbetween_prediction as prediction

    flat, tri = grid(12, 9, size=1.0)
    keys = [flat + np.array([0.0, 0.0, -0.1 * k * k]) + 0.05 * np.sin(3 * flat[:, [1, 0, 0]] + k) for k in range(5)]
    gap = SequenceInterpolator(keys, tri)._gap(2)
    bump = 0.01 * np.sin(5 * flat)

    def posed(correction):  # positions whose correction to the gap's spline is ``correction(s)``
        return {s: gap.topo.apply_motion(gap.splines["vertices"].at(s) + correction(s), *gap.motion(s))
                for s in (0.25, 0.5, 0.75)}

    assert not corrections.inconsistent(gap, posed(lambda s: s * (1 - s) * bump))  # smooth: predicted
    assert corrections.inconsistent(gap, posed(lambda s: (1 if s != 0.5 else -1) * s * (1 - s) * bump))

    solved = []
    real_pose = type(gap).pose
    monkeypatch.setattr(prediction, "inconsistent", lambda gap, solved: True)
    monkeypatch.setattr(type(gap), "pose", lambda self, s, **kw: solved.append((s, self.rotation_limit)) or
                        real_pose(self, s, **kw))
    factors = np.arange(1, 16) / 16
    batch = SequenceInterpolator(keys, tri).poses(2, factors)  # three solved, then every eighth
    assert sorted(s for s, limit in solved if limit == prediction.ROUGH_ROTATION_DEVIATION) == list(np.arange(1, 8) / 8)
    assert sorted(s for s, limit in solved if limit != prediction.ROUGH_ROTATION_DEVIATION) == [0.25, 0.5, 0.75]
    assert np.isfinite(batch).all()
    # a predicted in-between lies between its solved neighbours: within the larger of their moves
    for j in range(0, 15, 2):  # 1/16, 3/16, ..., 15/16: predicted
        before = keys[2] if j == 0 else batch[j - 1]
        after = keys[3] if j == 14 else batch[j + 1]
        reach = max(np.abs(after - before).max(), 1e-12)
        assert np.abs(batch[j] - 0.5 * (before + after)).max() <= reach


@pytest.mark.parametrize("knots", [(0.25, 0.5, 0.75), tuple(np.arange(1, 8) / 8), (0.2, 0.3, 0.9)])
def test_rough_gap_correction_is_the_chord_between_neighbouring_knots(knots):
    """The correction of a rough gap is zero at the keys, the solved value at each solved factor,
    and on the chord of the two knots around any other factor: it reproduces a correction linear
    in the factor between knots and never leaves the range of the two it joins."""
    from core.inbetween_corrections import PiecewiseLinearCorrection

    rng = np.random.default_rng(3)
    values = {s: rng.normal(size=(7, 3)) for s in knots}
    correction = PiecewiseLinearCorrection(values)
    nodes = [0.0, *knots, 1.0]
    data = [np.zeros((7, 3)), *(values[s] for s in knots), np.zeros((7, 3))]
    assert np.array_equal(correction(0.0), data[0]) and np.allclose(correction(1.0), data[-1], atol=0)
    for s in knots:
        assert np.allclose(correction(s), values[s], rtol=0, atol=1e-15)
    for a, b, da, db in zip(nodes[:-1], nodes[1:], data[:-1], data[1:]):
        for w in (0.1, 0.5, 0.9):
            s = a + w * (b - a)
            assert np.allclose(correction(s), (1 - w) * da + w * db, rtol=0, atol=1e-14)
            assert (correction(s) <= np.maximum(da, db) + 1e-15).all() and (correction(s) >= np.minimum(da, db) - 1e-15).all()


@pytest.mark.parametrize("factors", [(0.25, 0.75), (0.25, 0.5, 0.75), (0.125, 0.5, 0.6875)])
def test_correction_polynomial_is_the_interpolating_polynomial_through_the_keys_zeros(factors):
    """The predicted in-betweens' correction polynomial agrees with SciPy's barycentric
    interpolation through (0, 0), the solved corrections and (1, 0), and reproduces a polynomial of
    that degree vanishing at both keys exactly."""
    from scipy.interpolate import BarycentricInterpolator

    from core.inbetween_corrections import CorrectionPolynomial

    rng = np.random.default_rng(3)
    coefficients = rng.normal(size=(len(factors), 7, 3))  # D(s) = s (1 − s) Σ_k c_k s^k

    def exact(s):
        return s * (1.0 - s) * sum(c * s ** k for k, c in enumerate(coefficients))

    polynomial = CorrectionPolynomial({s: exact(s) for s in factors})
    nodes = [0.0, *factors, 1.0]
    reference = BarycentricInterpolator(nodes, np.stack([exact(s) for s in nodes]), axis=0)
    for s in np.linspace(-0.5, 1.5, 17):
        np.testing.assert_allclose(polynomial(s), exact(s), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(polynomial(s), reference(s), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("factors", [(0.25, 0.5, 0.75), (0.125, 0.5, 0.6875)])
def test_correction_polynomial_takes_the_keys_slopes(factors):
    """With slopes at the keys the correction polynomial agrees with SciPy's Hermite interpolation
    (Krogh, the keys' nodes repeated), reproduces a polynomial of that degree with those values and
    slopes exactly, and has the slopes asked for."""
    from scipy.interpolate import KroghInterpolator

    from core.inbetween_corrections import CorrectionPolynomial

    rng = np.random.default_rng(4)
    coefficients = rng.normal(size=(len(factors) + 2, 5, 3))  # D(s) = s (1 − s) Σ_k c_k s^k

    def exact(s):
        return s * (1.0 - s) * sum(c * s ** k for k, c in enumerate(coefficients))

    def slope(s):  # of s (1 − s) p(s): (1 − 2s) p(s) + s (1 − s) p'(s)
        p = sum(c * s ** k for k, c in enumerate(coefficients))
        dp = sum(k * c * s ** (k - 1) for k, c in enumerate(coefficients) if k)
        return (1.0 - 2.0 * s) * p + s * (1.0 - s) * dp

    polynomial = CorrectionPolynomial({s: exact(s) for s in factors}, (slope(0.0), slope(1.0)))
    nodes = [0.0, 0.0, *factors, 1.0, 1.0]
    values = [exact(0.0), slope(0.0), *(exact(s) for s in factors), exact(1.0), slope(1.0)]
    reference = KroghInterpolator(nodes, np.stack(values), axis=0)
    for s in np.linspace(-0.5, 1.5, 17):
        np.testing.assert_allclose(polynomial(s), exact(s), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(polynomial(s), reference(s), rtol=1e-9, atol=1e-9)
    h = 1e-6
    np.testing.assert_allclose((polynomial(h) - polynomial(0.0)) / h, slope(0.0), rtol=1e-4, atol=1e-4)


def test_sequence_gaps_meet_at_a_key_with_one_velocity(monkeypatch):
    """Keys 9 frames apart or more (eight in-betweens asked together, three solved, the others
    predicted): the poses leaving a key into the next gap and arriving at it from the previous one
    move with the same velocity (the keys' slopes of the predicted corrections); without the slopes
    they do not."""
    import core.inbetween_corrections as corrections

    flat, tri = grid(24, 6, size=2.0)

    def bend(angle, lift):  # a strip bent onto an arc and lifted: deforming, not rigid
        r = 2.0 / angle
        th = flat[:, 0] / r
        return np.stack([r * np.sin(th), flat[:, 1], r * (1 - np.cos(th)) + lift], axis=1)

    keys = [bend(a, z) for a, z in ((0.3, 0.0), (1.0, 0.1), (1.8, 0.3), (2.4, 0.6), (2.7, 1.0))]
    h = 1e-3
    factors = [h, *np.arange(1, 16) / 16, 1.0 - h]

    def mismatch():  # at keys 1 and 2, relative to the velocity
        seq = SequenceInterpolator(keys, tri)
        out = []
        for k in (1, 2):
            leaving, arriving = seq.poses(k, factors)[0], seq.poses(k - 1, factors)[-1]
            v_out, v_in = (leaving - keys[k]) / h, (keys[k] - arriving) / h
            out.append(np.sqrt(np.sum((v_out - v_in) ** 2) / np.sum(v_out ** 2)))
        return max(out)

    assert mismatch() < 2e-3  # h and the slopes' one-sided differences
    monkeypatch.setattr(corrections, "KEY_SLOPE_SOLVED", 99)  # without the slopes
    assert mismatch() > 5e-3


def _relative(base_vertices, other_vertices, triangles):
    """The in-between solver's view of ``other_vertices`` from ``base_vertices``: (topology, base key,
    other key, relative)."""
    from core.inbetween_keys import Key, Relative
    from core.inbetween_topology import Topology
    from core.mesh_topology import mesh_topology

    topo = Topology(mesh_topology(triangles, len(base_vertices)), base_vertices)
    base, other = Key(topo, base_vertices), Key(topo, other_vertices)
    return topo, base, other, Relative(topo, base, other)


def test_triangle_sides_are_the_corner_edges_from_the_first_corner():
    """The sides ``x1 − x0`` and ``x2 − x0`` the checks read are the corner edges 0 and −2 of
    the fits' ``corner_edge_rows``, bit for bit (the same incidence rows)."""
    flat, tri = grid(15, 11, size=1.0)
    bent = flat.copy()
    bent[:, 2] = 0.3 * np.sin(2.5 * flat[:, 0]) * flat[:, 1]
    topo = _relative(flat, bent, tri)[0]
    edges = topo.corner_edge_rows(bent)
    e1, e2 = topo.triangle_sides(bent)
    np.testing.assert_array_equal(e1, edges[:, 0])
    np.testing.assert_array_equal(e2, -edges[:, 2])
    np.testing.assert_allclose(e1, (bent[tri[:, 1]] - bent[tri[:, 0]]).T, rtol=0, atol=1e-15)


def test_corner_edges_on_some_triangles_are_the_whole_meshs_there_bit_for_bit():
    """The corner edges of some triangles alone (``corner_edge_rows_on``, what the untangle-first
    guard reads) are those of the whole mesh's incidence product on those triangles, bit for bit,
    in any order of the triangles and with repeats, far from the origin too."""
    flat, tri = grid(15, 11, size=1.0)
    bent = flat.copy()
    bent[:, 2] = 0.3 * np.sin(2.5 * flat[:, 0]) * flat[:, 1]
    topo = _relative(flat, bent, tri)[0]
    rows = np.random.default_rng(3).choice(len(tri), size=40)  # unsorted, some twice
    for x in (bent, bent + 1e3):
        on = topo.corner_edge_rows_on(x, rows)
        assert on.shape == (3, 3, rows.size) and on.flags["C_CONTIGUOUS"]
        np.testing.assert_array_equal(on, topo.corner_edge_rows(x)[:, :, rows])


def test_whole_rotations_are_the_same_rotations_as_rigid_motion_and_residuals():
    """A relative's triangle rotations taken whole equal its component's rigid rotation composed
    with the residuals (both map each base triangle's frame onto the other key's triangle)."""
    from core import deformation_fields as df

    flat, tri = grid(15, 11, size=1.0)
    bent = flat.copy()
    bent[:, 2] = 0.3 * np.sin(2.5 * flat[:, 0]) * flat[:, 1]
    turned = _rigid(bent, Rotation.from_rotvec([0.3, -0.2, 2.6]).as_matrix(), np.zeros(3), (0.4, 0.1, -0.2))
    topo, base, other, relative = _relative(flat, turned, tri)
    whole = relative.whole_rotations(topo, base, other, np.ones(1, dtype=bool))
    identity = np.broadcast_to(np.eye(3), relative.motion[0].shape)
    np.testing.assert_allclose(df.rotated_frames(whole.rotvec, identity, topo.triangle_component, base.column_rows),
                               df.rotated_frames(relative.rotvec, relative.motion[0], topo.triangle_component,
                                                 base.column_rows), atol=1e-9)
    assert whole.whole.all() and not relative.whole.any()


def test_a_rigid_fit_that_turns_further_than_the_triangles_is_not_used():
    """The residuals to a component's best rigid rotation are kept where they turn the triangles
    less than their whole rotations (a rigid turn by 170° with a bend: residuals near zero), and
    given up where the rigid fit adds turn: a strip whose two halves trade places without turning
    (its best rigid fit is a half turn, its triangles turn by nothing but where the halves join)."""
    flat, tri = grid(41, 5, size=2.0)
    bent = flat.copy()
    bent[:, 2] = 0.1 * np.sin(3.0 * flat[:, 0])
    turned = _rigid(bent, Rotation.from_rotvec([0.0, 0.0, np.radians(170.0)]).as_matrix(), np.zeros(3))
    topo, base, other, relative = _relative(flat, turned, tri)
    assert not relative.residuals_add_turn(topo, base, other).any()
    swapped = flat.copy()
    swapped[:, 0] = np.where(flat[:, 0] < 1.0, flat[:, 0] + 1.0, flat[:, 0] - 1.0)
    swapped[:, 2] = 0.2 * np.sin(np.pi * flat[:, 0])  # the joins lifted: no triangle collapses
    topo, base, other, relative = _relative(flat, swapped, tri)
    assert np.degrees(np.linalg.norm(relative.screw[0, :3])) > 90.0  # the spurious half turn
    assert relative.residuals_add_turn(topo, base, other).all()


def test_a_thin_strip_takes_its_turn_about_its_length_from_its_triangles():
    """A strip 60 times longer than wide whose bow swings from one side to the other while it
    turns 20° about its length: its positions are best matched by a half turn more (the bows laid
    onto each other, -160°), which its triangles do not make. Its rigid fit is the turn its
    triangles make: by the strip's symmetry about its middle, exactly 20° about its length (to
    round-off). A strip bowed less (its positions tell the turn) is fitted so already."""
    flat, tri = grid(121, 5, size=3.0)
    flat[:, 1] -= flat[:, 1].mean()
    bow = 1.0 - (flat[:, 0] / 1.5 - 1.0) ** 2
    turn = Rotation.from_rotvec([np.radians(20.0), 0.0, 0.0]).as_matrix()
    for height in (0.15, 0.05):
        before, after = flat.copy(), flat.copy()
        before[:, 2], after[:, 2] = height * bow, -height * bow
        after = _rigid(after, turn, np.zeros(3), (0.2, -0.1, 0.3))
        fitted = _relative(before, after, tri)[3].motion[0][0]
        assert Rotation.from_matrix(fitted.T @ turn).magnitude() < 1e-9


def test_position_tangents_are_limited_at_a_stop_not_at_a_swing():
    """Per point, the incoming tangent is limited against the longer of this gap's and the next
    gap's secant: a point swinging back inside the gap (on a parabola through its turning point)
    keeps its Catmull–Rom tangent, and the spline reproduces the parabola exactly; a point that
    stops at a key and stays is limited to TANGENT_LIMIT × its secant (no overshoot past the stop)."""
    from core.splines import TANGENT_LIMIT, HermiteGap

    direction = np.array([0.6, 0.0, 0.8])
    swing = [(t - 0.5) ** 2 * direction for t in (-1.0, 0.0, 1.0, 2.0)]  # turns back mid-gap: secant 0
    stop = [np.array(p) for p in ([-3.0, 0, 0], [0.0, 0, 0], [0.1, 0, 0], [0.1, 0, 0])]
    spline = HermiteGap([np.stack([a, b]) for a, b in zip(swing, stop)], cubic=True, rows=True)
    for s in np.linspace(0.0, 1.0, 9):
        np.testing.assert_allclose(spline.at(s)[0], (s - 0.5) ** 2 * direction, atol=1e-12)
    np.testing.assert_allclose(spline.t0[1], [TANGENT_LIMIT * 0.1, 0.0, 0.0], atol=1e-12)


def test_a_point_that_settles_is_not_lent_the_next_gaps_velocity():
    """A point that moves a little into the gap and is pulled far in the next one keeps its end
    tangent within END_TANGENT_LIMIT × its secant, so it stays between its keys (Catmull–Rom's end
    tangent, half the next move, takes it back past its start); a point accelerating from rest on a
    parabola is under the limit and reproduced exactly."""
    from core.splines import END_TANGENT_LIMIT, REST_START_LIMIT, HermiteGap

    settle = [np.array(p) for p in ([0.0, 0, 0], [0.0, 0, 0], [0.1, 0, 0], [10.0, 0, 0])]
    fall = [np.array([0.0, 0.0, -0.5 * t * t]) for t in (-1.0, 0.0, 1.0, 2.0)]
    spline = HermiteGap([np.stack([a, b]) for a, b in zip(settle, fall)], cubic=True, rows=True,
                        limit=REST_START_LIMIT)
    path = np.array([spline.at(s) for s in np.linspace(0.0, 1.0, 21)])
    assert path[:, 0, 0].min() >= -1e-12 and path[:, 0, 0].max() <= 0.1 + 1e-12
    np.testing.assert_allclose(spline.t1[0], [END_TANGENT_LIMIT * 0.1, 0.0, 0.0], atol=1e-12)
    for s in np.linspace(0.0, 1.0, 9):
        np.testing.assert_allclose(spline.at(s)[1], [0.0, 0.0, -0.5 * s * s], atol=1e-12)


def test_a_first_gap_cut_from_a_motion_is_not_lent_the_next_gaps_velocity():
    """A sequence cut from a motion (start="keys") whose first gap barely moves (0.01) before the
    next one moves far (1.0, a hit): the first gap's start tangent is at most TANGENT_LIMIT × its own
    secant and its end tangent, for positions, at most END_TANGENT_LIMIT × (before: both bounded by
    the next gap's move, so the point swung 0.073 away from its keys 0.01 apart; now 0.003); a point at
    constant velocity is reproduced exactly."""
    from core.splines import START_TANGENT_LIMIT, HermiteGap

    hit = [np.array(p) for p in ([-0.01, 0, 0], [0.0, 0, 0], [0.01, 0, 0], [1.01, 0, 0])]
    steady = [np.array([0.3 * t, 0.2 * t, 0.0]) for t in (-1.0, 0.0, 1.0, 2.0)]
    spline = HermiteGap([np.stack([a, b]) for a, b in zip(hit, steady)], cubic=True, rows=True,
                        limit=START_TANGENT_LIMIT)
    path = np.array([spline.at(s) for s in np.linspace(0.0, 1.0, 21)])
    assert np.abs(path[:, 0] - np.linspace(0.0, 0.01, 21)[:, None] * [1, 0, 0]).max() < 0.01
    for s in np.linspace(0.0, 1.0, 9):
        np.testing.assert_allclose(spline.at(s)[1], [0.3 * s, 0.2 * s, 0.0], atol=1e-12)


def test_the_rigid_fit_is_given_up_per_piece():
    """In a mesh of two pieces — one turning rigidly by 170°, one whose halves trade places — only
    the second piece's rotations are taken whole; the first keeps its residuals unchanged."""
    flat, tri = grid(41, 5, size=2.0)
    turned = _rigid(flat, Rotation.from_rotvec([0.0, 0.0, np.radians(170.0)]).as_matrix(), np.zeros(3))
    swapped = flat.copy()
    swapped[:, 0] = np.where(flat[:, 0] < 1.0, flat[:, 0] + 1.0, flat[:, 0] - 1.0)
    swapped[:, 2] = 0.2 * np.sin(np.pi * flat[:, 0])
    shift = np.array([0.0, 3.0, 0.0])
    base = np.vstack([flat, flat + shift])
    other = np.vstack([turned, swapped + shift])
    topo, base_key, other_key, relative = _relative(base, other, np.vstack([tri, tri + len(flat)]))
    pieces = relative.residuals_add_turn(topo, base_key, other_key)
    assert pieces.tolist() == [False, True]
    whole = relative.whole_rotations(topo, base_key, other_key, pieces)
    first = topo.triangle_component == 0
    np.testing.assert_array_equal(whole.rotvec[first], relative.rotvec[first])
    assert not np.allclose(whole.rotvec[~first], relative.rotvec[~first])


@pytest.mark.parametrize("degrees, halves", [(20.0, False), (170.0, False), (0.0, True)])
def test_residuals_add_turn_measures_the_whole_rotations_only_where_the_residuals_can_exceed_them(
        monkeypatch, degrees, halves):
    """The whole rotations' angles are never negative, so a piece whose residuals' median is within
    SPURIOUS_RIGID_TURN cannot have residuals that exceed them by that much: there the test answers
    without measuring them (a bent sheet turned 20° or 170°: residuals' median 10°), and lets their
    frames go as measuring them would; elsewhere (a strip whose halves trade places) it measures
    them. Every answer agrees with the medians of the angles SciPy gives for the residuals and for
    the whole rotations (the component's rigid rotation composed with them)."""
    import core.inbetween_whole_rotations as whole_module
    from core.inbetween_whole_rotations import SPURIOUS_RIGID_TURN

    flat, tri = grid(41, 5, size=2.0)
    other = flat.copy()
    if halves:
        other[:, 0] = np.where(flat[:, 0] < 1.0, flat[:, 0] + 1.0, flat[:, 0] - 1.0)
        other[:, 2] = 0.2 * np.sin(np.pi * flat[:, 0])
    else:
        other[:, 2] = 0.1 * np.sin(3.0 * flat[:, 0])
        other = _rigid(other, Rotation.from_rotvec([0.0, 0.0, np.radians(degrees)]).as_matrix(), np.zeros(3))
    topo, base, other_key, relative = _relative(flat, other, tri)
    measured = []
    real = whole_module.rotation_angles
    monkeypatch.setattr(whole_module, "rotation_angles", lambda *a: measured.append(1) or real(*a))
    residual = Rotation.from_rotvec(relative.rotvec)
    whole = Rotation.from_matrix(relative.motion[0][topo.triangle_component]) * residual
    expected = np.median(residual.magnitude()) > np.median(whole.magnitude()) + SPURIOUS_RIGID_TURN
    answer = relative.residuals_add_turn(topo, base, other_key)
    assert answer.tolist() == [expected] == [halves]
    assert bool(measured) == (np.median(residual.magnitude()) > SPURIOUS_RIGID_TURN) == halves
    assert relative.__dict__.get("_plane_frames") is None and relative.__dict__.get("_whole") is None


def test_residuals_add_turn_measures_the_same_angles_from_kept_entries_as_from_frames(monkeypatch):
    """The whole rotations' angles are read from their entries where a reader (the pins' fits,
    ``turning``) kept them, else from the turned frames: the trace is summed in one order either
    way (each diagonal entry over the frame's columns, then the three), so a gap asked again after
    its entries were let go reads the same angles to the bit, and decides the same pieces. Two
    relatives of the strip whose halves trade places, one with its entries kept: the traces each
    measures are equal bit for bit (they differed in the last bits for 11 of its 320 triangles when
    the frames' trace was summed column by column)."""
    import core.deformation_fields as df

    flat, tri = grid(41, 5, size=2.0)
    other = flat.copy()
    other[:, 0] = np.where(flat[:, 0] < 1.0, flat[:, 0] + 1.0, flat[:, 0] - 1.0)
    other[:, 2] = 0.2 * np.sin(np.pi * flat[:, 0])
    traces = []
    real = df.trace_rotation_angles
    monkeypatch.setattr(df, "trace_rotation_angles", lambda trace: traces.append(trace.copy()) or real(trace))
    answers = []
    for keep in (False, True):
        topo, base, other_key, relative = _relative(flat, other, tri)
        if keep:
            relative._whole_entries(base, other_key, keep=True)  # as the pins' fits and turning keep them
            assert relative.__dict__.get("_plane_frames") is None  # the entries, not the frames, are read
        traces.clear()
        answers.append(relative.residuals_add_turn(topo, base, other_key).tolist())
        assert len(traces) == 1
        answers.append(traces[0])
    assert answers[0] == answers[2]
    np.testing.assert_array_equal(answers[1], answers[3])


def test_a_relatives_screw_is_made_once_when_first_read_and_is_the_whole_meshs_turns(monkeypatch):
    """A relative built without ``turns`` takes each piece's half turn the way the whole mesh turns
    (§5.3 rigid part). Its screw is made when first read: the key two ahead of a sequence's gap has
    its screw taken anew (``unwrap``) before anything reads it, so the constructor's would be made
    for nothing. Read, it is the screw of the components' motions toward the whole mesh's best
    rigid turn, to the bit, and ``whole_tells`` is that turn's."""
    import core.inbetween_keys as keys
    from core import deformation_fields as df
    from core.inbetween_rigid_fits import component_screws, whole_tells
    from core.rigid_alignment import rigid_alignment

    flat, tri = grid(12, 6, size=1.0)
    lifted = flat + [0.0, 0.0, 0.4]
    vertices, triangles = np.vstack([flat, lifted]), np.vstack([tri, tri + len(flat)])  # two pieces
    other = _rigid(vertices, Rotation.from_rotvec([0.3, -0.5, 2.9]).as_matrix(), np.array([0.2, 0.1, -0.3]))
    other[len(flat):, 2] += 0.05 * np.sin(3.0 * flat[:, 0])  # the upper piece bends too
    calls = []
    monkeypatch.setattr(keys, "component_screws", lambda *a: calls.append(a) or component_screws(*a))
    topo, base, nxt, relative = _relative(vertices, other, triangles)
    assert calls == []  # made when first read, not by the constructor
    whole = rigid_alignment(vertices, other, topo.weights)[0]
    turns = np.repeat(df.rotation_vectors(whole[None]), 2, axis=0)
    expected = component_screws(*relative.motion, turns, False, relative.nonrigidity)
    assert np.array_equal(relative.screw, expected) and relative.screw is relative.screw
    assert relative.whole_tells == bool(whole_tells(turns[0])) and relative.whole_tells
    assert len(calls) == 1
    calls.clear()
    _, _, _, unwrapped = _relative(vertices, other, triangles)
    unwrapped.unwrap(2.0 * expected[:, :3], np.zeros((len(triangles), 3)))
    assert len(calls) == 1  # the unwrapped screw alone: the whole mesh's turn was never needed
    assert np.array_equal(unwrapped.screw, component_screws(*unwrapped.motion, 2.0 * expected[:, :3], True,
                                                            unwrapped.nonrigidity))


def test_five_keys_give_the_positions_cubic_motion_exactly():
    """With keys two away on both sides (their ``corrections``), the positions' tangents are the five
    keys' central difference: a point on a cubic path in time is reproduced exactly over the gap, where
    Catmull–Rom's tangents (exact for quadratic motion only) leave it off by up to 0.096 × the
    cubic's coefficient; a point on a parabola stays exact either way."""
    from core.splines import HermiteGap, five_key_tangent_correction

    cubic = np.array([0.4, -0.3, 0.2])

    def path(t):
        return np.stack([cubic * t ** 3 + np.array([0.1, 0.5, -0.2]) * t, np.array([0.3 * t * t, -0.2 * t, 0.1])])

    values = [path(t) for t in (-1.0, 0.0, 1.0, 2.0)]
    corrections = (five_key_tangent_correction(path(-2.0), *values[:4]),
                   five_key_tangent_correction(*values, path(3.0)))
    five = HermiteGap(values, cubic=True, rows=True, corrections=corrections)
    four = HermiteGap(values, cubic=True, rows=True)
    for s in np.linspace(0.0, 1.0, 9):
        np.testing.assert_allclose(five.at(s), path(s), atol=1e-12)
        np.testing.assert_allclose(four.at(s)[1], path(s)[1], atol=1e-12)
    # Catmull–Rom's tangents are both off by the cubic's coefficient: s (2s − 1)(s − 1) of it at s
    np.testing.assert_allclose(four.at(0.25)[0] - path(0.25)[0], 0.09375 * cubic, atol=1e-12)


def test_five_keys_do_not_carry_a_stop_a_key_farther():
    """The five keys' correction is limited to what the smaller of the third differences on either
    side of the key gives (FIVE_KEY_LIMIT): a point moving steadily that stops dead one key after
    the tangent's key (its third difference before the key zero) keeps Catmull–Rom's tangent, its
    steady velocity, where the unlimited five keys' difference would overshoot it by a twelfth."""
    from core.splines import five_key_tangent_correction

    steady, stop = np.array([[1.0, 0.5, 0.0]]), np.array([[1.0, 0.0, 0.0]])
    keys = [t * steady for t in (-2.0, -1.0, 0.0, 1.0)] + [steady + 0.0 * stop]
    np.testing.assert_array_equal(five_key_tangent_correction(*keys), np.zeros((1, 3)))
    unlimited = (8.0 * (keys[3] - keys[1]) - (keys[4] - keys[0])) / 12.0
    np.testing.assert_allclose(unlimited, 13.0 / 12.0 * steady)
    # cubic motion: both third differences equal, the whole correction, the exact velocity
    cubic = [np.array([[t ** 3 + t, 0.5 * t ** 3, -t]]) for t in (-2.0, -1.0, 0.0, 1.0, 2.0)]
    np.testing.assert_allclose(0.5 * (cubic[3] - cubic[1]) + five_key_tangent_correction(*cubic),
                               [[1.0, 0.0, -1.0]], atol=1e-12)


def test_five_keys_keep_a_point_held_between_two_motions_still():
    """A point that moves, stays put over the two gaps around a key and moves on the same way has
    equal third differences on both sides of that key (they come from the keys two away alone), so
    the minmod limit keeps the whole correction, −1/6 of a step here: the held point would swing
    back by 4/27 of it a third into the gap. The correction is at most the longer chord at the key
    (zero for a hold): the hold's first gap keeps the point still, as Catmull–Rom's tangents (the
    start one limited by the gap's and the next gap's chords) do; where the point moves through the
    key steadily the bound does not act."""
    from core.splines import HermiteGap, five_key_tangent_correction

    step = np.array([[1.0, 0.5, 0.0]])
    keys = [0.0 * step, step, step, step, 2.0 * step]  # key times −2 … 2: held over −1 … 1
    np.testing.assert_array_equal(five_key_tangent_correction(*keys), np.zeros((1, 3)))
    spline = HermiteGap(keys[:4], cubic=True, rows=True, corrections=(None, five_key_tangent_correction(*keys)))
    for s in np.linspace(0.0, 1.0, 7):  # the gap −1 → 0
        np.testing.assert_array_equal(spline.at(s), step)
    # smooth (cubic) motion through the key: the chords bound nothing, the velocity is exact
    cubic = [np.array([[t ** 3 + t, 0.5 * t ** 3, -t]]) for t in (-2.0, -1.0, 0.0, 1.0, 2.0)]
    np.testing.assert_allclose(0.5 * (cubic[3] - cubic[1]) + five_key_tangent_correction(*cubic),
                               [[1.0, 0.0, -1.0]], atol=1e-12)


def test_five_keys_give_no_correction_and_say_nothing_on_a_symmetric_swing():
    """A point swinging out and back symmetrically about a key it rests on (keys 3, 0, 0, 0, 3: the third
    differences either side opposite, a + b = 0) keeps Catmull–Rom's tangent, and the correction's
    limit divides nothing into a NumPy overflow warning (it reached users' consoles)."""
    from core.splines import five_key_tangent_correction

    keys = [np.array([[x, 0.0, 0.0], [0.0, 2.0 * x, 1.0]]) for x in (3.0, 0.0, 0.0, 0.0, 3.0)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        correction = five_key_tangent_correction(*keys)
    np.testing.assert_array_equal(correction, 0.0)
