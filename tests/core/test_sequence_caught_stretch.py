"""A key that catches a stretch its neighbours do not have, on a motion passing through it (cloth
landing just before the key), warns the gaps beside it whose in-betweens carry that stretch
(core.sequence_caught_stretch); a swing sampled at its extremes, whose in-betweens pass through the
stretched shape as the interpolated ones do, does not."""

import warnings

import numpy as np
import pytest

from core import SequenceInterpolator
from core.sequence_caught_stretch import (PASSING_THROUGH, caught_stretch, caught_stretch_warning, passing_through,
                                          stretch_alone)
from core.sequence_edge_misfit import misfit_allowed

from meshes import grid

FACTORS = [j / 8 for j in range(1, 8)]
QUARTERS = (0.25, 0.5, 0.75)  # the in-betweens the warning measures of those (caught_stretch_factors)


def _draped(vertices, angle, stretch, drop=0.0):
    """``vertices`` of a flat strip along x (at z = 0) stretched along x by the factor 1 + ``stretch``
    and its far half bent down by ``angle`` over a quarter of its length (a circular arc), lowered
    by ``drop``: a sheet draped over an edge."""
    x0 = vertices[:, 0].min()
    length = vertices[:, 0].max() - x0
    u = np.linspace(0.0, (1.0 + stretch) * length, 4001)
    start, bend = 0.4 * length, 0.25 * length
    turn = -angle * np.clip((u - start) / bend, 0.0, 1.0)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (np.cos(turn[1:]) + np.cos(turn[:-1])) * np.diff(u))])
    z = np.concatenate([[0.0], np.cumsum(0.5 * (np.sin(turn[1:]) + np.sin(turn[:-1])) * np.diff(u))])
    out = vertices.copy()
    arc = (1.0 + stretch) * (vertices[:, 0] - x0)
    out[:, 0], out[:, 2] = np.interp(arc, u, x), np.interp(arc, u, z) - drop
    return out


def _lengths(x, triangles):
    p = x[triangles]
    return np.linalg.norm(p[:, [1, 2, 0]] - p, axis=2)


def _deviation(x, rest, triangles):
    return float(np.mean(np.abs(_lengths(x, triangles) / rest - 1.0)))


def _warned(keys, triangles, **options):
    """Per gap of ``keys``: the caught-stretch warnings of its in-betweens at FACTORS, and the mean
    relative edge deviation from the first key of those at QUARTERS (``options`` to the sequence)."""
    rest = _lengths(keys[0], triangles)
    sequence = SequenceInterpolator(keys, triangles, **options)
    quarters = [FACTORS.index(s) for s in QUARTERS]

    def asked(gap):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            poses = sequence.poses(gap, FACTORS)
        deviation = np.mean([_deviation(poses[k], rest, triangles) for k in quarters])
        return [w.message for w in caught if "catches a stretch" in str(w.message)], float(deviation)

    return [asked(gap) for gap in range(len(sequence))]


def _landing():
    """A flat strip falling (key 0), landing over an edge stretched 6 % along itself (key 1, bent
    60°), and draped further with the stretch let go to 1 % (key 2, bent 120°)."""
    vertices, triangles = grid(41, 9, size=2.0)
    keys = [_draped(vertices, 0.0, 0.0), _draped(vertices, np.radians(60.0), 0.06, drop=0.8),
            _draped(vertices, np.radians(120.0), 0.01, drop=0.9)]
    return keys, triangles


def test_a_stretch_caught_at_a_key_the_motion_passes_through_is_warned_beside_it():
    """The landing: the middle key is 3.0 % off the first key (its neighbours 0 and 0.5 %) and the
    keys either side are 2.2 × farther apart than the nearer is from it (the strip goes on bending);
    the first gap's in-betweens, 1.1 % off the first key on average where the first key allows 0.3 %,
    are warned (kind ``fit``, an excess of their deviation ÷ that), and so is the second, whose 1.9 %
    is over the 1.05 % its last key allows. Before, both were silent: every fit is within what its
    keys allow the misfit (core.sequence_edge_misfit)."""
    keys, triangles = _landing()
    rest = _lengths(keys[0], triangles)
    deviations = [_deviation(k, rest, triangles) for k in keys]
    assert deviations[1] > misfit_allowed([max(deviations[0], deviations[2])])
    assert passing_through(*keys) >= PASSING_THROUGH
    for (said, deviation), other in zip(_warned(keys, triangles), (deviations[0], deviations[2])):
        assert deviation > misfit_allowed([other])
        assert len(said) == 1 and said[0].kind == "fit" and "key pose 1 catches a stretch" in str(said[0])
        assert said[0].excess == pytest.approx(deviation / misfit_allowed([other]), rel=1e-6)


def test_a_stretch_at_the_key_a_swing_cut_from_its_motion_turns_back_at_is_not_warned():
    """The same strip swung up 60° (key 0), down 60° stretched 6 % (key 1) and up 70° stretched 1 %
    (key 2), keyed from the middle of its motion (``start="keys"``, no rest pose: the first key is
    not the rest): the middle key has the same stretch against its neighbours, but the swing turns
    back at it (the keys either side 0.11 × as far apart as the nearer is from it, placed rigidly),
    and from a first key that is not the rest a swing's bend reversed reads as stretch (a tail
    wagged left, right, left), so neither gap is warned, though their in-betweens are farther off
    the first key than the landing's (1.5 / 2.0 %)."""
    vertices, triangles = grid(41, 9, size=2.0)
    keys = [_draped(vertices, np.radians(-60.0), 0.0), _draped(vertices, np.radians(60.0), 0.06),
            _draped(vertices, np.radians(-70.0), 0.01)]
    rest = _lengths(keys[0], triangles)
    deviations = [_deviation(k, rest, triangles) for k in keys]
    assert deviations[1] > misfit_allowed([max(deviations[0], deviations[2])])
    assert passing_through(*keys) < PASSING_THROUGH
    assert caught_stretch(deviations, keys, _corner_edges(triangles)) is None
    out = _warned(keys, triangles, start="keys")
    assert out[0][1] > misfit_allowed([deviations[0]])  # the gap the landing warns is over its allowance too
    assert all(not said for said, _ in out)


def _bounce():
    """The strip bent 20° (key 0), pressed down to 60° and stretched 6 % along itself (key 1), and
    sprung back to 25° stretched 0.5 % (key 2): a bounce that bends the cloth back toward the shape
    before."""
    vertices, triangles = grid(41, 9, size=2.0)
    keys = [_draped(vertices, np.radians(20.0), 0.0), _draped(vertices, np.radians(60.0), 0.06),
            _draped(vertices, np.radians(25.0), 0.005)]
    return keys, triangles


@pytest.mark.parametrize("options", [{}, {"start": "keys", "rest_pose": "first key"}])
def test_a_stretch_at_a_key_the_cloth_bounces_back_from_is_warned_beside_it(options):
    """The bounce, from rest (a simulation's first frame: ``start="rest"``, the default) or keyed
    from its motion with the rest pose given: the middle key is 3.0 % off the rest (its neighbours
    0 and 0.25 %) and the motion turns back at it, placed rigidly (0.13) and as given (0.13, under
    PASSING_THROUGH), its triangles turning as a swing's (not the stretch alone). A free swing is
    least stretched where it turns back, so the stretch was a push (a ball bouncing in a hammock),
    which the keys do not say lasts: each gap whose in-betweens are off the rest by more than its
    other key allows (1.3 / 1.7 % against 0.3 / 0.6 %) is warned (kind ``fit``), saying the motion
    turns back there; the excess is their deviation ÷ that allowance. Before, both gaps were
    silent (docs/inbetween-measurements.md, *The caught-stretch warning's limits*)."""
    keys, triangles = _bounce()
    rest = _lengths(keys[0], triangles)
    deviations = [_deviation(k, rest, triangles) for k in keys]
    edges = _corner_edges(triangles)
    assert passing_through(*keys) < PASSING_THROUGH and passing_through(*keys, placed=False) < PASSING_THROUGH
    assert not stretch_alone(keys[1], (keys[0], keys[2]), edges)
    assert caught_stretch(deviations, keys, edges) is None  # keys cut from a motion, no rest pose: not read
    assert caught_stretch(deviations, keys, edges, from_rest=True) == "back"
    options = {key: keys[0] if value == "first key" else value for key, value in options.items()}
    for (said, deviation), other in zip(_warned(keys, triangles, **options), (deviations[0], deviations[2])):
        assert deviation > misfit_allowed([other])
        assert len(said) == 1 and said[0].kind == "fit" and "key pose 1 catches a stretch" in str(said[0])
        assert "where the motion turns back" in str(said[0])
        assert said[0].excess == pytest.approx(deviation / misfit_allowed([other]), rel=1e-6)
    assert all(not said for said, _ in _warned(keys, triangles, start="keys"))  # the first key not the rest


def test_the_motion_passes_through_a_key_midway_and_turns_back_at_a_key_its_neighbours_share():
    """passing_through: keys on a straight path of shapes (the strip bent 0°, 30°, 60°) are twice as
    far apart as the middle is from either (2 to the bends' discretisation); a key whose neighbours
    are one shape is a turning point (0); a neighbour the key itself up to a rigid motion is not a
    step away from it (the ratio past 1e6: rounding is all that separates them)."""
    vertices, _ = grid(41, 9, size=2.0)
    bent = [_draped(vertices, np.radians(a), 0.0) for a in (0.0, 30.0, 60.0)]
    assert passing_through(*bent) == pytest.approx(2.0, rel=0.05)
    assert passing_through(bent[0], bent[1], bent[0] + 3.0) == pytest.approx(0.0, abs=1e-9)
    assert passing_through(bent[0], bent[1], bent[1][:, [1, 0, 2]] * [1, -1, 1] + 2.0) > 1e6


@pytest.mark.parametrize("deviations, caught", [((0.0, 0.024, 0.004), True), ((0.0, 0.0099, 0.0044), True),
                                                ((0.0, 0.0097, 0.0044), False), ((0.0, 0.0029, 0.0), False)])
def test_a_key_catches_a_stretch_over_what_its_larger_neighbour_allows(deviations, caught):
    """The deviation test of caught_stretch is misfit_allowed of the larger neighbour (twice it +
    0.1 point, at least 0.3 %), on keys the motion passes through."""
    vertices, _ = grid(41, 9, size=2.0)
    bent = [_draped(vertices, np.radians(a), 0.0) for a in (0.0, 30.0, 60.0)]
    assert caught_stretch(deviations, bent) == ("through" if caught else None)


def _flat(vertices, stretch, height):
    """The flat strip stretched by the factor 1 + ``stretch`` along x and raised by ``height``."""
    return vertices * [1.0 + stretch, 1.0, 1.0] + [0.0, 0.0, height]


def _corner_edges(triangles):
    """Corner edge vectors by coordinate (3, 3, m) of positions, as the sequence's topology gives them."""
    def rows(x):
        p = x[triangles]
        return np.ascontiguousarray((p[:, [1, 2, 0]] - p).transpose(2, 1, 0))
    return rows


@pytest.mark.parametrize("case", ["flat landing", "bounce off a floor", "pulse in place", "landing from a tilted fall"])
def test_a_stretch_that_is_all_that_changes_at_a_key_is_warned_beside_it(case):
    """The strip falling flat and landing on a floor stretched 6 % (key 1), lying there 0.5 % (key 2);
    bouncing off the floor (up, down stretched 6 %, up again 0.5 %); lying still with a 6 % pulse at
    the middle key; falling turned 10° and landing flat. Aligned rigidly, the middle key's neighbours
    are nearer each other than it is to either (passing_through 0–0.09, as at a swing's extreme), so
    before session 74, both gaps were silent with in-betweens 1.5–1.9 % off the first key where
    0.3–0.6 % is allowed (5–6 × past). Its triangles turn 0 against its neighbours placed rigidly,
    and against one as given, where its edges stretch 3 % from theirs (stretch_alone): each gap
    whose in-betweens are over what its other key allows is warned (kind fit), naming the key and
    saying little else changes at it; the excess is their deviation ÷ that allowance."""
    vertices, triangles = grid(41, 9, size=2.0)
    heights = {"flat landing": (1.0, 0.0, 0.0), "bounce off a floor": (0.5, 0.0, 0.4),
               "pulse in place": (0.0, 0.0, 0.0), "landing from a tilted fall": (1.0, 0.0, 0.0)}[case]
    keys = [_flat(vertices, s, h) for s, h in zip((0.0, 0.06, 0.0 if case == "pulse in place" else 0.005), heights)]
    if case == "landing from a tilted fall":  # falling turned 10° about y, landed flat
        tilt = np.radians(10.0)
        keys[0] = keys[0] @ np.array([[np.cos(tilt), 0.0, -np.sin(tilt)], [0.0, 1.0, 0.0],
                                      [np.sin(tilt), 0.0, np.cos(tilt)]])
    rest = _lengths(keys[0], triangles)
    deviations = [_deviation(k, rest, triangles) for k in keys]
    assert passing_through(*keys) < PASSING_THROUGH  # the motion reads as turning back at the key
    assert caught_stretch(deviations, keys, _corner_edges(triangles)) == "alone"
    for (said, deviation), other in zip(_warned(keys, triangles), (deviations[0], deviations[2])):
        assert deviation > misfit_allowed([other])
        assert len(said) == 1 and said[0].kind == "fit" and "key pose 1 catches a stretch" in str(said[0])
        assert "with little else changing at it" in str(said[0])
        assert said[0].excess == pytest.approx(deviation / misfit_allowed([other]), rel=1e-6)


def test_the_stretch_is_all_that_changes_where_the_triangles_turn_less_than_the_edges_stretch():
    """stretch_alone: the strip stretched 6 % and shifted against the flat one: its triangles turn 0
    against it, its edges 3 % longer: the stretch is all that changes. Turned 40° as a whole against
    both neighbours (a pendulum's swing), its triangles turn 0.70 rad against each as given, over the
    0.03 its edges stretch: not the stretch alone; against one of them only (a sheet falling turned,
    landed and lying still), the stretch alone still. With its far half bent 30° against one
    neighbour (0.24 rad RMS placed rigidly) not: one bent neighbour is enough to say no."""
    vertices, triangles = grid(41, 9, size=2.0)
    edges = _corner_edges(triangles)
    turn = np.array([[np.cos(0.7), 0.0, np.sin(0.7)], [0.0, 1.0, 0.0], [-np.sin(0.7), 0.0, np.cos(0.7)]])
    flat, stretched = _flat(vertices, 0.0, 0.0), _flat(vertices, 0.06, 0.0) + [0.3, -1.0, 2.0]
    assert stretch_alone(stretched, (flat, flat + 5.0), edges)
    assert not stretch_alone(stretched @ turn.T, (flat, flat + 5.0), edges)
    assert stretch_alone(stretched, (flat @ turn.T, flat + 5.0), edges)
    bent = _draped(vertices, np.radians(30.0), 0.0)
    assert not stretch_alone(stretched, (flat, bent), edges)
    assert not stretch_alone(_draped(vertices, np.radians(30.0), 0.06), (flat,), edges)


def _pendulum(vertices, phase, swing=np.radians(40.0), least=0.005, most=0.04):
    """The flat strip hanging from its short edge at x = min and swinging rigidly about it (the y axis)
    by ``swing`` cos ``phase``, stretched along its length by ``least`` at the extremes to ``most`` at
    the bottom, where it is fastest (the pull grows with the speed squared, sin² ``phase``)."""
    along = vertices[:, 0] - vertices[:, 0].min()
    angle = swing * np.cos(phase)
    down = -(1.0 + least + (most - least) * np.sin(phase) ** 2) * along
    return np.stack([down * np.sin(angle), vertices[:, 1], down * np.cos(angle)], axis=1)


def test_a_rigid_pendulum_whose_stretch_follows_its_speed_is_not_warned():
    """A strip swinging rigidly ±40° about its pinned edge, keyed at its extremes and at the bottom
    (a quarter swing apart), stretched 4 % at the bottom and 0.5 % at the extremes: the middle keys
    are 1.75 % off the first key, over what their neighbours allow, and the swing turns back at
    them (passing_through 0), as a flat landing's does. But the whole turns 40° against each
    neighbour, far more than its edges stretch (stretch_alone: no), and the in-betweens follow the
    true swing's stretch (the truth's deviation from the first key at every in-between, within 0.02
    point, 0.26 in the last gap; 0.87 % at the quarters, over the 0.3 % the extremes allow): nothing
    is caught, no gap is warned. Before, every gap was warned "with little else
    changing at it": the neighbours placed rigidly on the key took the swing out. As given, the
    swing passes on through its bottom (its neighbours at ±40° farther apart than either is from
    it), so it is not read as a key the motion turns back at either."""
    vertices, triangles = grid(41, 9, size=2.0)
    phases = np.arange(5) * np.pi / 2
    keys = [_pendulum(vertices, p) for p in phases]
    rest = _lengths(keys[0], triangles)
    deviations = [_deviation(k, rest, triangles) for k in keys]
    assert deviations[1] > misfit_allowed([max(deviations[0], deviations[2])])
    assert passing_through(*keys[:3]) < PASSING_THROUGH
    assert passing_through(*keys[:3], placed=False) >= PASSING_THROUGH  # in the world it swings on through
    assert not stretch_alone(keys[1], (keys[0], keys[2]), _corner_edges(triangles))
    sequence = SequenceInterpolator(keys, triangles)
    for gap in range(len(sequence)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            poses = sequence.poses(gap, FACTORS)
        truth = [_deviation(_pendulum(vertices, phases[gap] + s * np.pi / 2), rest, triangles) for s in FACTORS]
        off = [abs(_deviation(pose, rest, triangles) - true) for pose, true in zip(poses, truth)]
        assert max(off) < (3e-3 if gap == len(sequence) - 1 else 5e-4)  # the in-betweens' stretch is the swing's
        assert np.mean([truth[FACTORS.index(s)] for s in QUARTERS]) > misfit_allowed([0.0])  # as far off as warned
        assert not [w for w in caught if "catches a stretch" in str(w.message)]


def test_the_warning_says_the_deviation_against_what_the_other_key_allows():
    """caught_stretch_warning: None at or under the other key's allowance; over it, the excess is
    the deviation ÷ the allowance and the message names the key that catches the stretch."""
    names = ("frame 1", "frame 17")
    assert caught_stretch_warning(0.003, 0.0, names, "frame 17", 0.05, (0.5,)) is None
    message, factors, excess = caught_stretch_warning(0.025, 0.0, names, "frame 17", 0.0488, (0.25, 0.5))
    assert factors == (0.25, 0.5) and excess == pytest.approx(0.025 / 0.003)
    assert "frame 17 catches a stretch (4.9 %)" in message and "what frame 1 allows" in message
