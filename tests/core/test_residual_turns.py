"""Triangles whose rotation residuals to their piece's rigid fit pass the far side of a half turn
(paper §5.3's rotations, :func:`core.rotation_continuity.residuals_turning_whole_way`): a sequence
turns them the way their whole rotation goes, not the long way round that the principal residual
composed with the fit's turn gives. No bpy."""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from core.rotation_continuity import WHOLE_WAY_MARGIN, residuals_turning_whole_way
from core.sequence_inbetweens import SequenceInterpolator


def _whole_half(w, q):
    """The short-way half of each whole rotation exp(w) exp(q), by SciPy's Slerp (independent of
    the residual's representative)."""
    whole = Rotation.from_rotvec(w) * Rotation.from_rotvec(q)
    return Rotation.concatenate([Slerp([0.0, 1.0], Rotation.concatenate([Rotation.identity(), r]))([0.5])
                                 for r in whole])


def test_a_residual_past_the_far_side_of_a_half_turn_turns_the_whole_triangle_the_short_way():
    """A piece fit turning +58° about x and a triangle of it turning 140° the other way: its
    principal residual is +162° about x (the short way relative to the fit), which composed as
    exp(s w) exp(s q) turns it +220° (the long way, 110° half-way). Taken −198°, the composed
    rotation is the whole rotation's short geodesic at every factor (coaxial: exact), and the same
    rotation at the key."""
    w = np.array([[np.radians(58.0), 0.0, 0.0]])
    q = np.array([[np.radians(162.0), 0.0, 0.0]])
    out = residuals_turning_whole_way(q, w, np.array([0]))
    np.testing.assert_allclose(out, [[np.radians(-198.0), 0.0, 0.0]], atol=1e-12)
    key = Rotation.from_rotvec(w[0]) * Rotation.from_rotvec(out[0])
    assert (key.inv() * Rotation.from_rotvec(w[0]) * Rotation.from_rotvec(q[0])).magnitude() < 1e-12
    geodesic = Slerp([0.0, 1.0], Rotation.concatenate([Rotation.identity(), key]))
    for s in (0.25, 0.5, 0.75):
        composed = Rotation.from_rotvec(s * w[0]) * Rotation.from_rotvec(s * out[0])
        assert (composed.inv() * geodesic([s])[0]).magnitude() < 1e-12


def test_residuals_are_taken_so_that_the_half_way_is_nearer_the_whole_short_half():
    """Random fits (within a half turn) and residuals: every row returned is the same rotation as
    given; where the whole rotation is more than WHOLE_WAY_MARGIN short of a half turn, its
    composed half-way is no farther from the whole rotation's short half (Slerp) than the other way
    round's; rows with |q| + |w| <= π, or whose whole rotation is nearer a half turn, are returned
    unchanged."""
    rng = np.random.default_rng(7)
    m = 400
    w = Rotation.random(m, random_state=rng).as_rotvec() * rng.uniform(0.2, 1.0, (m, 1))
    q = Rotation.random(m, random_state=rng).as_rotvec()
    out = residuals_turning_whole_way(q, w, np.arange(m))
    same = (Rotation.from_rotvec(out).inv() * Rotation.from_rotvec(q)).magnitude()
    assert same.max() < 1e-9
    small = np.linalg.norm(q, axis=1) + np.linalg.norm(w, axis=1) <= np.pi
    near_half = (Rotation.from_rotvec(w) * Rotation.from_rotvec(q)).magnitude() >= np.pi - WHOLE_WAY_MARGIN
    kept_rows = small | near_half
    assert small.any() and near_half.any() and np.array_equal(out[kept_rows], q[kept_rows])
    assert (~small).any() and np.any(np.abs(out - q).sum(axis=1) > 1.0)  # some taken the other way
    theta = np.linalg.norm(out, axis=1, keepdims=True)
    other = out - 2 * np.pi * out / theta
    target = _whole_half(w, q)
    half = Rotation.from_rotvec(0.5 * w)
    kept = (target.inv() * half * Rotation.from_rotvec(0.5 * out)).magnitude()
    flipped = (target.inv() * half * Rotation.from_rotvec(0.5 * other)).magnitude()
    told = ~near_half
    assert np.all(kept[told] <= flipped[told] + 1e-9)


def test_a_piece_tumbling_past_a_half_turn_keeps_its_residuals():
    """A piece whose turn is continued past a half turn (200° about z, the way its keys go) with
    residuals of 10–40°: its triangles turn on with it, the residuals are left as they are."""
    w = np.array([[0.0, 0.0, np.radians(200.0)]])
    q = np.radians([[10.0, 0.0, 0.0], [0.0, 25.0, 5.0], [30.0, -20.0, 10.0]])
    np.testing.assert_array_equal(residuals_turning_whole_way(q, w, np.zeros(3, dtype=int)), q)


def _strip():
    nx, ny = 6, 41
    x, y = np.meshgrid(np.linspace(0.0, 0.5, nx), np.linspace(0.0, 2.0, ny), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    idx = np.arange(x.size).reshape(nx, ny)
    tri = np.concatenate([np.stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()], axis=1),
                          np.stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()], axis=1)])
    return v, tri


def test_a_flap_turning_against_its_sheet_is_turned_the_short_way_in_the_world():
    """A strip whose near two thirds turn +58° about x while its far end folds over to turn 144°
    the other way (−200° from the near part, about an axis tilted off x): half-way, the far end
    faces as the whole rotation's short half does (nearer it than the long half's facing, which
    is the opposite one); the principal residuals turned it the long way round."""
    v, tri = _strip()
    near = Rotation.from_rotvec([np.radians(58.0), 0.0, 0.0])
    fold_axis = np.array([1.0, 0.3, 0.0]) / np.linalg.norm([1.0, 0.3, 0.0])
    fold = Rotation.from_rotvec(np.radians(-200.0) * fold_axis)
    key = near.apply(v)
    far = v[:, 1] > 1.3
    hinge = near.apply([0.0, 1.3, 0.0])
    key[far] = hinge + (fold * near).apply(v[far] - [0.0, 1.3, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        x = SequenceInterpolator(np.stack([v, key]), tri).pose(0, 0.5)
    n = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    whole = fold * near
    short = Rotation.from_rotvec(0.5 * whole.as_rotvec()).apply([0.0, 0.0, 1.0])
    long_way = Rotation.from_rotvec(0.5 * (whole.as_rotvec() * (1 - 2 * np.pi / whole.magnitude()))).apply([0.0, 0.0, 1.0])
    tips = v[tri].mean(axis=1)[:, 1] > 1.35
    assert np.all(n[tips] @ short > n[tips] @ long_way)
