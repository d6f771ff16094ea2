"""A gap right after a stop that the after-impact start leaves alone (the cloth keeps deforming
after it lands) starts with the fall's velocity, and its in-betweens bulge across the slow creep
that follows: warned (core.sequence_gap_starts.GapStarts._carried_stop, STOP_CARRY_RATIO); a
motion that does not stop is not."""

import warnings

import numpy as np
import pytest

from core import SequenceInterpolator
from core.sequence_gap_starts import STOP_CARRY_RATIO

from meshes import grid

FACTORS = [j / 8 for j in range(1, 8)]


def _pose(vertices, height, shift, sag):
    """The flat sheet ``vertices`` (z = 0) raised by ``height``, moved by ``shift`` along x and sagged
    by ``sag`` × (y − ½)² (a fold across y): each coordinate linear in the three."""
    out = vertices.copy()
    out[:, 0] += shift
    out[:, 2] += height - sag * (vertices[:, 1] - 0.5) ** 2
    return out


def _motion(landing: bool):
    """Keys 0 … 4 of a sheet that falls 1.0 in the first gap and lands folding (``landing``), then
    creeps 0.05 per gap along x while its fold deepens 0.15 per gap (each in-between of those gaps
    is the two keys' linear blend: every coordinate is linear in the creep and the fold); or that
    creeps and folds so from the first key on."""
    vertices, triangles = grid(12, 12)
    keys = [_pose(vertices, 1.0 if landing else 0.0, 0.0, 0.0)]
    keys += [_pose(vertices, 0.0, 0.05 * i, 0.4 + 0.15 * i if landing else 0.15 * (i + 1)) for i in range(4)]
    return keys, triangles


def _overshoot_gaps(keys, triangles):
    s = SequenceInterpolator(keys, triangles)
    warned = set()
    for gap in range(len(keys) - 1):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            s.poses(gap, FACTORS)
        warned |= {gap for w in caught if getattr(w.message, "kind", None) == "overshoot"}
    return s, warned


def test_a_gap_after_a_landing_that_keeps_deforming_is_warned_where_its_in_betweens_overshoot():
    keys, triangles = _motion(landing=True)
    s, warned = _overshoot_gaps(keys, triangles)
    assert warned == {1}, warned  # the gap right after the landing, not the creep's later gaps
    assert s._exit(0) is None  # the after-impact start does not take it (the fold keeps deepening)
    assert s._carried_stop(1) > STOP_CARRY_RATIO
    # the warning is true: the motion in the gap is the keys' blend, and the in-betweens stray from it
    # by over a quarter of the gap's whole move (RMS over the points)
    rms = lambda d: np.sqrt(np.mean(np.sum(d * d, axis=1)))  # noqa: E731
    poses = s.poses(1, FACTORS)
    off = [rms(p - ((1 - f) * keys[1] + f * keys[2])) for p, f in zip(poses, FACTORS)]
    assert max(off) > 0.25 * rms(keys[2] - keys[1]), off


def test_a_motion_without_a_stop_is_not_warned():
    keys, triangles = _motion(landing=False)
    s, warned = _overshoot_gaps(keys, triangles)
    assert not warned
    assert all(s._carried_stop(gap) == 0.0 for gap in range(len(keys) - 1))


def _pendulum(phases, bend):
    """Keys of a 6 × 6 plate (0.2 wide) hanging 1 below a pivot and swinging about the y axis by
    1 rad × sin(phase), at ``phases`` (radians), bent along x by ``bend`` × sin(phase) × x² (a cloth
    swinging: deforming as it swings; 0: rigid); each key's exact pose at any phase."""
    vertices, triangles = grid(6, 6, size=0.2)
    vertices = vertices - [0.1, 0.1, 1.0]
    poses = []
    for phase in phases:
        turn = np.sin(phase)
        c, s = np.cos(turn), np.sin(turn)
        x = vertices @ np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]).T
        x[:, 2] += bend * np.sin(phase) * vertices[:, 0] ** 2
        poses.append(x)
    return poses, triangles


def test_a_pendulum_swinging_through_its_keys_is_not_warned():
    """A plate slowing toward its turning point has no landing's deformation: rigid, its
    non-rigidity is round-off, and barely bent (0.02), a hundredth of a landing's; the deformation
    test compared them (the last gap warned, keyed every 40° of the swing from 100°, rigid, and every
    90° from 20°, bent 0.02: a ratio of 4.5)."""
    for start, step, bend in ((100.0, 40.0, 0.0), (20.0, 90.0, 0.02)):
        keys, triangles = _pendulum(np.radians(start + step * np.arange(6)), bend)
        _, warned = _overshoot_gaps(keys, triangles)
        assert not warned, (start, step, bend)


@pytest.mark.parametrize("start", [60.0, 20.0, 200.0])
def test_a_swinging_cloth_slowing_into_its_last_key_is_not_warned(start):
    """A plate bending as it swings slows into its last key (keyed every 90° of its swing from
    ``start``), deforming less there. A last gap's end tangent is a share of its secant (the linear
    end condition; from 20° and 200° the keys' slowing correction shortens it), so the spline slowing
    to a stop runs along the chord, off the blend in timing only, and the spline's stray over it is
    no measure of an overshoot: it was warned as infinitely far (from 60°) and as 4.6 / 4.5 × as far
    (from 20° / 200°). The in-betweens are nearer the true swing than the blend."""
    phases = np.radians(start + 90.0 * np.arange(6))
    keys, triangles = _pendulum(phases, 1.0)
    s, warned = _overshoot_gaps(keys, triangles)
    assert not warned
    rms = lambda d: np.sqrt(np.mean(np.sum(d * d, axis=1)))  # noqa: E731
    truth, _ = _pendulum(phases[4] + np.radians(90.0) * np.array(FACTORS), 1.0)
    ours = np.median([rms(p - t) for p, t in zip(s.poses(4, FACTORS), truth)])
    blend = np.median([rms((1 - f) * keys[4] + f * keys[5] - t) for f, t in zip(FACTORS, truth)])
    assert ours < blend, (ours, blend)
