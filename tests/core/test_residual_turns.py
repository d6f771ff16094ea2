"""Triangles whose rotation residuals to their piece's rigid fit pass the far side of a half turn
(paper §5.3's rotations, :func:`core.rotation_continuity.residuals_turning_whole_way`): a sequence
turns a connected part of them the way its whole rotation goes where its border then joins the
rest of the mesh, and leaves them where turning them would tear them from it. No bpy."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from core.mesh_topology import mesh_topology
from core.rotation_continuity import jumping_pairs, residuals_turning_whole_way
from core.sequence_turn_readings import TURNED_PART_SHARE

FIT = np.radians(58.0)  # the piece's rigid turn about x


def _strip(nx: int = 4, ny: int = 61, length: float = 2.0):
    """A strip along y (length × 0.5), its triangles (m, 3), their centroids' y (m,) and the pairs of
    triangles sharing an edge (E, 2)."""
    x, y = np.meshgrid(np.linspace(0.0, 0.5, nx), np.linspace(0.0, length, ny), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    idx = np.arange(x.size).reshape(nx, ny)
    tri = np.concatenate([np.stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()], axis=1),
                          np.stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()], axis=1)])
    topology = mesh_topology(tri, len(v))
    return tri, v[tri].mean(axis=1)[:, 1], topology.edge_triangles[topology.interior_edges]


def _principal(rotvec: np.ndarray) -> np.ndarray:
    """The representatives of at most a half turn (what the keys give)."""
    return Rotation.from_rotvec(rotvec).as_rotvec()


def test_a_part_curled_past_a_half_turn_against_its_fit_turns_the_short_way_in_the_world():
    """A strip fit turning +58° about x whose residual curls smoothly from 0 at one end to −220° at
    the other: past −180° (the last 18 % of the strip) the principal residual is up to +140° (a
    jump across the strip there), which composed with the fit turns the far end up to +198°, the
    long way round. That part's border is the jump, so it is taken −220°: the residuals are the
    continuous curl on every triangle, no jump is left, and the far end's composed rotation
    exp(s w) exp(s q) is the short geodesic of its whole rotation (up to −162°; SciPy's Slerp) at
    every factor. A part under the share of its piece's area asked for is left as it is."""
    tri, cy, pairs = _strip()
    areas = np.ones(len(tri))
    curl = np.radians(-220.0) * cy / 2.0
    continuous = np.stack([curl, np.zeros_like(curl), np.zeros_like(curl)], axis=1)
    given = _principal(continuous)
    assert jumping_pairs(given, pairs).any() and (given[:, 0] > np.pi / 2).any()
    turns = np.array([[FIT, 0.0, 0.0]])
    pieces = np.zeros(len(tri), dtype=int)
    out = residuals_turning_whole_way(given, turns, pieces, pairs, areas, TURNED_PART_SHARE)
    np.testing.assert_allclose(out, continuous, atol=1e-12)
    np.testing.assert_array_equal(residuals_turning_whole_way(given, turns, pieces, pairs, areas, 0.2), given)
    assert not jumping_pairs(out, pairs).any()
    far = np.flatnonzero(curl < -np.pi)
    fit = Rotation.from_rotvec(turns[0])
    for row in far[::7]:
        whole = fit * Rotation.from_rotvec(out[row])
        assert whole.magnitude() < np.pi - 0.3  # a rotation well short of a half turn
        geodesic = Slerp([0.0, 1.0], Rotation.concatenate([Rotation.identity(), whole]))
        for s in (0.25, 0.5, 0.75):
            composed = Rotation.from_rotvec(s * turns[0]) * Rotation.from_rotvec(s * out[row])
            assert (composed.inv() * geodesic([s])[0]).magnitude() < 1e-9


def test_a_part_wanting_the_other_way_inside_a_smooth_field_is_not_torn_from_it():
    """The same strip whose residual curls smoothly from 0 to +170° the fit's way: past +122° its
    composed turn passes a half turn (the other way round would be shorter there), but its
    residuals join the rest's without a jump; taken the other way those triangles would be half a
    turn from their neighbours half-way. The residuals are returned as they are."""
    tri, cy, pairs = _strip()
    curl = np.radians(170.0) * cy / 2.0
    given = np.stack([curl, np.zeros_like(curl), np.zeros_like(curl)], axis=1)
    assert not jumping_pairs(given, pairs).any()
    assert (FIT + curl > np.pi + 0.2).sum() > 20  # triangles whose composed turn is the long way round
    out = residuals_turning_whole_way(given, np.array([[FIT, 0.0, 0.0]]), np.zeros(len(tri), dtype=int), pairs,
                                      np.ones(len(tri)), 0.0)
    np.testing.assert_array_equal(out, given)


def test_turned_residuals_are_the_same_rotations_and_join_more_edges_than_they_part():
    """Random fits (within a half turn) and rough residual fields on a strip of two pieces, sets of
    any size: every row returned is the same rotation as given, rows with |q| + |w| <= π are
    unchanged, and the pairs of neighbours whose residuals jump past a half turn are no more than
    given (a set is turned only where it joins across most of its border)."""
    rng = np.random.default_rng(7)
    tri, cy, pairs = _strip(nx=8, ny=41)
    m = len(tri)
    components = (cy > 1.0).astype(int)
    pairs = pairs[components[pairs[:, 0]] == components[pairs[:, 1]]]
    changed = 0
    for _ in range(20):
        turns = Rotation.random(2, random_state=rng).as_rotvec() * rng.uniform(0.2, 1.0, (2, 1))
        axis = Rotation.random(random_state=rng).apply([1.0, 0.0, 0.0])
        field = np.radians(rng.uniform(120.0, 240.0)) * (cy / 2.0)[:, None] * axis \
            + 0.3 * rng.standard_normal((m, 3))
        given = _principal(field)
        out = residuals_turning_whole_way(given, turns, components, pairs, np.ones(m), 0.0)
        same = (Rotation.from_rotvec(out).inv() * Rotation.from_rotvec(given)).magnitude()
        assert same.max() < 1e-9
        small = np.linalg.norm(given, axis=1) + np.linalg.norm(turns[components], axis=1) <= np.pi
        np.testing.assert_array_equal(out[small], given[small])
        assert jumping_pairs(out, pairs).sum() <= jumping_pairs(given, pairs).sum()
        changed += np.any(out != given)
    assert changed > 0


def test_a_piece_tumbling_past_a_half_turn_keeps_its_residuals():
    """A piece whose turn is continued past a half turn (200° about z, the way its keys go) with
    residuals of 10–40°: its triangles turn on with it, the residuals are left as they are."""
    w = np.array([[0.0, 0.0, np.radians(200.0)]])
    q = np.radians([[10.0, 0.0, 0.0], [0.0, 25.0, 5.0], [30.0, -20.0, 10.0]])
    pairs = np.array([[0, 1], [1, 2]])
    np.testing.assert_array_equal(residuals_turning_whole_way(q, w, np.zeros(3, dtype=int), pairs, np.ones(3), 0.0), q)
