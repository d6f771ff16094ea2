"""Parts of a tube spun past a half turn between keys (issue 17: a twirled skirt whose hem spins on
while its waist turns back): the patches' turns read across the mesh, and the sequence's gap
warns where its in-betweens cannot be trusted to turn the part the way it went. No bpy."""

from __future__ import annotations

import warnings

import numpy as np

from core.errors import ShapeDifferenceWarning
from core.rigid_alignment import rigid_alignment
from core.sequence_inbetweens import SequenceInterpolator
from core.spun_parts import continued_turns, patch_turns, spin_patches, spun_shares, within_right_angle


def _skirt(spin: float, wrinkle: float = 0.0, seed: int = 0, rings: int = 30, sides: int = 60):
    """A frustum tube (a skirt: radius 0.3 at its waist z = 0, 0.6 at its hem z = −0.9) whose ring
    at height fraction s (0 at the waist, 1 at the hem) is turned about z by ``spin`` × s², with
    radial wrinkles of relative size ``wrinkle`` (normal, seeded; none at the waist). Returns the
    vertices (rings × sides, 3), the triangles and each vertex's ring turn (radians)."""
    s = np.linspace(0.0, 1.0, rings)[:, None]
    around = 2 * np.pi * np.arange(sides)[None, :] / sides
    radius = (0.3 + 0.3 * s) * (1.0 + wrinkle * np.random.default_rng(seed).standard_normal((rings, sides)) * (s > 0))
    turn = spin * s**2 + 0.0 * around
    x = np.stack([radius * np.cos(around + turn), radius * np.sin(around + turn), -0.9 * s + 0.0 * around], axis=-1)
    index = np.arange(rings * sides).reshape(rings, sides)
    a, b = index[:-1], np.roll(index[:-1], -1, axis=1)
    c, d = index[1:], np.roll(index[1:], -1, axis=1)
    triangles = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return x.reshape(-1, 3), triangles, turn.ravel()



def _spun_and_right(pose, reference: np.ndarray, hem: np.ndarray, truth: float) -> tuple[list[str], bool]:
    """The spun-part warnings ``pose()`` gives, and whether the hem's vertices ``hem`` of the pose
    turn about the vertical from ``reference`` (n, 3) by ``truth`` (radians) to within 30°."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        x = pose()
    spun = [str(w.message) for w in caught if "spins on more than a half turn" in str(w.message)]
    turned = np.angle(np.mean(np.exp(1j * (np.arctan2(x[hem, 1], x[hem, 0])
                                           - np.arctan2(reference[hem, 1], reference[hem, 0])))))
    return spun, bool(abs(np.angle(np.exp(1j * (turned - truth)))) < np.radians(30.0))

def test_patches_of_a_tube_twisted_past_a_half_turn_read_its_rings_turns():
    """A tube whose hem is twisted 270° from its waist (the principal angle of its lower rings is
    the other way round, from −180° to −90°): every patch's turn read across the mesh lies within
    the turns of its own rings (its centroid turns between them), and the share of the tube read
    past a half turn beyond its least-turned patch lies between the patches wholly past it and
    those reaching past it."""
    spin = np.radians(270.0)
    base, triangles, _ = _skirt(0.0)
    other, _, ring_turns = _skirt(spin)
    weights = np.ones(len(base))
    patches = spin_patches(base, triangles)
    rotation, translation = rigid_alignment(base, other)
    turn, least, known, piece, mass, axis = patch_turns(base, other, weights, np.zeros(len(base), dtype=int), patches,
                                                 rotation[None], translation[None])
    assert known.all()  # no patch near the axis
    turn = turn * np.sign(axis[0, 2])  # the fit turns about z (the tube's symmetry), either way round
    labels, _, count = patches
    lowest = np.full(count, np.inf)
    highest = np.full(count, -np.inf)
    np.minimum.at(lowest, labels, ring_turns)
    np.maximum.at(highest, labels, ring_turns)
    assert (turn >= lowest - 1e-9).all() and (turn <= highest + 1e-9).all()
    assert np.abs(turn).max() > np.pi  # past a half turn, as no principal angle is
    share, largest = spun_shares(base, other, weights, np.zeros(len(base), dtype=int), patches,
                                 rotation[None], translation[None])
    floor = least.min()  # the least-turned patch's turn, near the waist
    assert floor < np.radians(5.0)
    wholly, reaching = (np.sum(mass[ends - floor > np.pi]) / mass.sum() for ends in (lowest, highest))
    assert wholly <= share[0] <= reaching
    assert np.isclose(largest[0], np.max(np.abs(turn) - least))


def test_a_hem_spun_past_a_half_turn_through_wrinkles_is_right_or_warned():
    """Keys of a wrinkled skirt (5 % radial wrinkles, a new pattern per key) whose hem turns 60°,
    270° and 60° per gap: the wrinkles part neighbouring triangles' turns by more than a fold's
    crease, so the middle gap's hem is not read across the mesh triangle by triangle, and its
    in-betweens turn it the short way round, 90° back where it went 270° on (half-way −24°
    against 135°), which was not warned of. That gap warns, naming its keys, or turns the hem the
    way it went (half-way within 30° of the keys' turn halved); the gaps spinning 60° (no part past
    a half turn) do not warn, and are right (5–7° off)."""
    spins = np.radians([0.0, 60.0, 330.0, 390.0])
    keys = [_skirt(spin, 0.05, seed)[0] for seed, spin in enumerate(spins)]
    _, triangles, _ = _skirt(0.0)
    names = ["frame 1", "frame 17", "frame 33", "frame 49"]
    sequence = SequenceInterpolator(keys, triangles, start="keys", key_names=names)
    hem = np.arange(len(keys[0]))[-60:]
    for gap in range(3):
        spun, right = _spun_and_right(lambda: sequence.pose(gap, 0.5), keys[gap], hem,
                                      0.5 * (spins[gap + 1] - spins[gap]))
        if gap == 1:
            assert right or (len(spun) == 1 and f"between {names[1]} and {names[2]}" in spun[0])
        else:
            assert right and not spun


def test_a_chain_of_patches_turning_round_through_a_half_turn_leaves_the_rest_read_as_it_turns():
    """Twenty patches at one distance from a piece's turn axis, joined in a chain: seventeen turn
    57° (the piece's rigid turn), and the chain's first three 164°, 196° and 273° from there on
    (principal −164°, 164°, −87°: a flap swinging across the far side, as a banner's free end
    does). Taken continuous along the chain, only the first patch (273°) is past a half turn
    beyond the least-turned (57°): a share of 1/20. Read from the first patch's principal −87°,
    the rest came out 57° − 360° and 17/20 of the piece past a half turn."""
    turns = np.radians([-87.0, -164.0, 164.0] + [57.0] * 17)
    base = np.stack([np.ones(20), np.zeros(20), np.zeros(20)], axis=1)
    other = np.stack([np.cos(turns), np.sin(turns), np.zeros(20)], axis=1)
    patches = (np.arange(20), np.stack([np.arange(19), np.arange(1, 20)], axis=1), 20)
    angle = np.radians(57.0)
    rotation = np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    share, largest = spun_shares(base, other, np.ones(20), np.zeros(20, dtype=int), patches, rotation[None],
                                 np.zeros((1, 3)))
    assert np.isclose(share[0], 1 / 20)
    assert np.isclose(largest[0], np.radians(273.0 - 57.0))


def test_two_poses_of_a_hem_spun_past_a_half_turn_through_wrinkles_are_right_or_warned():
    """Two poses of the wrinkled skirt (5 % radial wrinkles, a new pattern per pose) whose hem
    turns 270° on from its waist between them: two poses take the triangles' turns continuous
    across the mesh, which the wrinkles break, and the in-between turned the hem the short way
    round (half-way −18° against 135°) with no warning. The in-between warns, naming the poses,
    or turns the hem the way it went (half-way within 30° of the turn halved); two poses whose hem
    turns 60° do not warn and are right, and nor do the same poses without wrinkles, whose
    triangles' turns the mesh carries the way the hem went (20 % of its area spun past a half
    turn from the waist)."""
    from core.two_pose_inbetweens import Interpolator

    spins = np.radians([0.0, 60.0, 330.0])
    poses = [_skirt(spin, 0.05, seed)[0] for seed, spin in enumerate(spins)]
    _, triangles, _ = _skirt(0.0)
    hem = np.arange(len(poses[0]))[-60:]
    for first in range(2):
        names = [f"frame {16 * first + 1}", f"frame {16 * first + 17}"]
        spun, right = _spun_and_right(
            lambda: Interpolator(poses[first], poses[first + 1], triangles, key_names=names).pose(0.5),
            poses[first], hem, 0.5 * (spins[first + 1] - spins[first]))
        if first == 1:
            assert right or (len(spun) == 1 and f"between {names[0]} and {names[1]}" in spun[0])
        else:
            assert right and not spun
    smooth = [_skirt(spin)[0] for spin in spins[1:]]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        x = Interpolator(*smooth, triangles).pose(0.5)
    turned = np.angle(np.mean(np.exp(1j * (np.arctan2(x[hem, 1], x[hem, 0]) - np.arctan2(smooth[0][hem, 1],
                                                                                            smooth[0][hem, 0])))))
    assert abs(np.angle(np.exp(1j * (turned - 0.5 * (spins[2] - spins[1]))))) < np.radians(30.0)
    assert not [w for w in caught if "spins on more than a half turn" in str(w.message)]


def test_two_poses_read_their_keys_patch_turns_once_and_say_the_same(monkeypatch):
    """Every in-between of two poses compares its patches' turns with the keys' (the spun check):
    the keys' reading is made once per interpolator, not at each in-between, and each in-between
    says what a fresh interpolator says of it (the wrinkled skirt whose hem spins 270° on)."""
    import core.spun_parts as spun_parts
    from core.two_pose_inbetweens import Interpolator

    spins = np.radians([60.0, 330.0])
    a, b = (_skirt(spin, 0.05, seed)[0] for seed, spin in enumerate(spins, 1))
    _, triangles, _ = _skirt(0.0)
    factors = (0.25, 0.5, 0.75)

    def said(pair, factor):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            x = pair.pose(factor)
        return x, [str(w.message) for w in caught if "spins on more than a half turn" in str(w.message)]

    fresh = [said(Interpolator(a, b, triangles), factor) for factor in factors]
    readings, real = [], spun_parts.principal_turns
    # the keys' reading takes turns across the patches' pairs; a pose's is only compared (no pairs)
    monkeypatch.setattr(spun_parts, "principal_turns", lambda base, other, weights, owner, patches, *args:
                        readings.append(len(patches[1]) > 0) or real(base, other, weights, owner, patches, *args))
    pair = Interpolator(a, b, triangles)
    again = [said(pair, factor) for factor in factors]
    assert sum(readings) == 1 and len(readings) == 1 + len(factors), readings  # the keys once, each pose once
    for (x, words), (y, same) in zip(fresh, again):
        np.testing.assert_array_equal(x, y)
        assert words == same


def test_patches_turning_within_a_right_angle_have_no_part_spun_past_a_half_turn():
    """Where no read patch turns past a right angle either way (:func:`within_right_angle`), the
    turns taken continuous across the mesh leave no part past a half turn from its least-turned
    one: on random principal turns up to 89.9° of random patches (some not read, two pieces)
    joined as a grid's neighbours, every continued turn is its principal one to rounding and
    :func:`spun_shares` gives no piece a share. A smooth turn growing to 300° across the grid
    (principal turns the other way round past 180°) is not decided so, and has a part past a half
    turn."""
    rng = np.random.default_rng(7)
    side = 16
    index = np.arange(side * side).reshape(side, side)
    pairs = np.concatenate([np.stack([index[:, :-1].ravel(), index[:, 1:].ravel()], 1),
                            np.stack([index[:-1].ravel(), index[1:].ravel()], 1)])
    patches = (np.arange(side * side), pairs, side * side)
    piece = np.repeat(np.arange(side) >= side // 2, side).astype(int)  # the lower rows one piece, the upper another
    ramp = np.radians(300.0) * np.tile(np.arange(side) / (side - 1), side)

    def reading(turn, known):
        principal = (turn, known, piece, rng.uniform(0.5, 2.0, side * side), np.eye(3)[:2])
        keys = continued_turns(principal, patches)
        share, _ = spun_shares(None, None, None, None, patches, np.eye(3)[None].repeat(2, 0), np.zeros((2, 3)),
                               keys=keys)
        return principal, keys[0], share

    for _ in range(40):
        known = rng.random(side * side) > 0.1
        principal, continued, share = reading(rng.uniform(-np.radians(89.9), np.radians(89.9), side * side), known)
        assert within_right_angle(principal)
        np.testing.assert_allclose(continued[known], principal[0][known], rtol=0.0, atol=1e-12)
        assert (share == 0.0).all()
        turn = ramp + rng.normal(0.0, np.radians(5.0), side * side)
        principal, continued, share = reading(np.angle(np.exp(1j * turn)), known)
        assert not within_right_angle(principal) and (share > 0.1).all()


def test_a_sequence_whose_patches_turn_within_a_right_angle_does_not_continue_them(monkeypatch):
    """A wrinkled skirt's keys whose hem turns 40° per gap (every patch within a right angle of
    none): the gaps' spun check is decided from the patches' principal turns, not taken continuous
    across the mesh (a minimum spanning tree of the patches, about 1 ms of a 10k cloth's gap), and
    says what the continued reading says: no part spun past a half turn, no warning."""
    import core.spun_parts as spun_parts

    spins = np.radians([0.0, 40.0, 80.0, 120.0])
    keys = [_skirt(spin, 0.05, seed)[0] for seed, spin in enumerate(spins)]
    _, triangles, _ = _skirt(0.0)
    continued, real = [], spun_parts._continued
    monkeypatch.setattr(spun_parts, "_continued", lambda *args: continued.append(1) or real(*args))
    sequence = SequenceInterpolator(keys, triangles, start="keys")
    for gap in range(3):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            sequence.pose(gap, 0.5)
        assert not [w for w in caught if "spins on more than a half turn" in str(w.message)]
        assert sequence._gap(gap).spun_part == (0.0, 0.0)
    assert not continued
    monkeypatch.setattr(spun_parts, "_continued", real)
    for gap in range(3):  # the continued reading of each gap's keys: no share past a half turn
        rotations, translations, _ = sequence._fits(gap, gap + 1)
        share, _ = spun_shares(sequence._raw[gap], sequence._raw[gap + 1], sequence._topo.weights,
                               sequence._topo.vertex_owner, sequence._key_patches(), rotations, translations)
        assert (share == 0.0).all()
