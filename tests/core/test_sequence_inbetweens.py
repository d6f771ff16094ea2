"""Sequence in-betweens (core.sequence_inbetweens and the modules it composes: the keys, the gaps'
starts, half turns, turned parts; issue 3) on analytic motions; no bpy."""

from __future__ import annotations

import warnings
import weakref
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import MeshError, ShapeDifferenceWarning
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator, interpolate
from inbetween_helpers import _bend, _edge_deviation, _flipped, _roll, _strip
from meshes import drape, grid


def _catmull_rom(p0, p1, p2, p3, s):
    """The uniform Catmull–Rom spline through p0…p3 at factor s of the segment p1 → p2."""
    return 0.5 * (2 * p1 + (p2 - p0) * s + (2 * p0 - 5 * p1 + 4 * p2 - p3) * s ** 2 + (3 * p1 - p0 - 3 * p2 + p3) * s ** 3)


def test_sequence_is_coherent_across_gaps(strip):
    flat, tri = strip
    angles = np.linspace(0.0, 2.4, 5)
    keys = [_bend(flat, t) + np.array([0.0, 0.0, -0.3 * t * t]) for t in angles]  # bending + accelerating fall
    seq = SequenceInterpolator(keys, tri)
    assert len(seq) == 4
    for k in range(len(seq)):
        np.testing.assert_allclose(seq.pose(k, 0.0), keys[k], atol=1e-12)
        np.testing.assert_allclose(seq.pose(k, 1.0), keys[k + 1], atol=1e-12)
    # continuity and no popping: consecutive samples across gap boundaries move by similar steps
    times = np.linspace(0.0, 4.0, 81)
    poses = np.array([seq.pose_at(t) for t in times])
    steps = np.linalg.norm(np.diff(poses, axis=0), axis=2).max(axis=1)
    assert steps.max() < 2.0 * np.median(steps)
    # velocity continuity at a key: one-sided differences agree (C¹, Catmull–Rom)
    eps = 1e-3
    left = (seq.pose(0, 1.0) - seq.pose(0, 1.0 - eps)) / eps
    right = (seq.pose(1, eps) - seq.pose(1, 0.0)) / eps
    assert np.linalg.norm(left - right) / np.linalg.norm(left) < 0.05
    for t in times:
        x = seq.pose_at(t)
        assert _edge_deviation(x, flat, tri).mean() < 2e-3


def _swinging_flap():
    """A sheet whose lower half swings about a hinge while the upper half stays put (an isometric
    motion), keys about 50° apart: the flat sheet, its triangles, the nine keys and the swing at
    any time."""
    flat, tri = grid(60, 60)
    hinge = np.array([0.0, 0.5, 0.0])

    def swung(time):
        x = flat.copy()
        below = x[:, 1] < hinge[1]
        x[below] = (x[below] - hinge) @ Rotation.from_rotvec([1.3 * np.sin(0.9 * time), 0.0, 0.0]).as_matrix().T + hinge
        return x

    return flat, tri, [swung(t) for t in range(9)], swung


def _jittered(keys, size=5e-6, seed=0):
    """``keys`` with every coordinate moved by up to ``size`` at random: noise the size of keys stored
    to 5 decimals, on no grid (a scan's), so the flap's halves keep their metric only to it and are not
    read rigid to the keys' rounding (:func:`core.sequence_bent_parts.rounded_tolerance`)."""
    rng = np.random.default_rng(seed)
    return [k + rng.uniform(-size, size, k.shape) for k in keys]


@pytest.mark.parametrize("jitter", [None, 5e-6])
def test_swinging_flap_keeps_its_edge_lengths(jitter):
    """The swinging flap (:func:`_swinging_flap`): the keys' per-vertex spline cuts the chords of
    the flap's arcs (edges up to 2.9 % short). Keys jittered by 5e-6 (:func:`_jittered`) keep the
    flap's halves rigid only to that noise, and the first gaps keep the spline anchor, which held the
    fit there: solved again with the weak anchor the in-betweens keep the lengths to within the fit's
    tolerance (0.1 %) a few times over. Keys as computed keep the halves rigid to round-off, a hinge's
    parts (``RIGID_METRIC``), and every gap is anchored as two poses are. Either way the in-betweens
    sit closer to the true swing than the spline."""
    flat, tri, keys, swung = _swinging_flap()
    keys = keys if jitter is None else _jittered(keys, jitter)
    seq = SequenceInterpolator(keys, tri)
    # which path each gap takes: the weak anchor's (jittered, first gap) or two poses' (as computed)
    assert seq._gap(0).anchored == (jitter is None)
    ours, spline = [], []
    for k in range(len(seq)):
        p0, p3 = (keys[k - 1] if k else 2 * keys[0] - keys[1]), (keys[k + 2] if k + 2 < len(keys) else 2 * keys[-1] - keys[-2])
        for s in (0.25, 0.5, 0.75):
            x, truth = seq.pose(k, s), swung(k + s)
            assert _edge_deviation(x, flat, tri).mean() < 5e-3
            cubic = _catmull_rom(p0, keys[k], keys[k + 1], p3, s)
            ours.append(np.linalg.norm(x - truth))
            spline.append(np.linalg.norm(cubic - truth))
    assert np.median(ours) < 0.75 * np.median(spline)


def test_weak_anchor_only_where_letting_go_starts_the_fit_closer():
    """A fit the spline anchor holds off the metric is solved again with the weak anchor only where
    letting the anchor go moves the fit's start toward the metric: the Poisson solve with the weak
    anchor RELEASE_GAIN or more closer to it than the gap's own. That solve is estimated without
    the weak factorization, by conjugate gradients preconditioned with the gap's factor (the two
    matrices differ by the anchors' diagonal: the preconditioned spectrum lies within
    [HELD_ANCHOR_WEIGHT ÷ the gap's weight, 1]), to a residual of RELEASE_TOLERANCE: the estimate is
    within 1 % of the difference between the two solves (1.4e-4 here; the ratio of the misfits within
    8e-4 of its value at a residual of 1e-3 on the held fits of the benchmark), far inside the
    decision's margins (0.2 % closer against 11–71 %).
    The swinging flap's middle in-between of its first gap stalls far off the metric toward the
    keys' spline, which cuts the chords of the flap's arcs; letting the anchor go starts the fit
    less than half as far off. Where the guide is what the target edges integrate to (their
    Poisson solve with the gauge anchor alone, moved as a whole), the anchor holds nothing back,
    however far off the metric those edges are (perturbed here): letting it go moves nothing, and
    the fit is not solved again. The keys are jittered by 5e-6 (:func:`_jittered`): the flap's halves
    then keep their metric only to that noise, so the gap keeps the spline anchor (halves rigid to the
    keys' rounding are a hinge's, anchored as two poses: core.sequence_bent_parts)."""
    from core.inbetween_topology import GAUGE_WEIGHT

    _, tri, keys, _ = _swinging_flap()
    gap = SequenceInterpolator(_jittered(keys), tri)._gap(0)
    assert not gap.anchored
    s = 0.5
    gap.select(s)
    frames, stretch, motion, guide = gap.targets(s)
    targets = gap.fit_targets(frames, stretch)
    own = gap.solve(targets["edges"], guide)
    weak = gap.solve(targets["edges"], guide, gap.weak_system())
    estimate = gap.weak_poisson_solve(guide, own)
    assert np.linalg.norm(estimate - weak) <= 0.01 * np.linalg.norm(weak - own)
    misfits = []
    gap.fit(gap.place(own.copy(), s, motion), stretch, frames, guide, s, motion, targets=targets, misfits=misfits)
    assert gap.held(misfits)
    assert gap.misfit(gap.edges_of(estimate, np.float32), targets) < 0.5 * misfits[0]
    assert gap.released(targets["edges"], guide, targets)
    edges = targets["edges"] * (1.0 + 0.05 * np.random.default_rng(0).standard_normal(targets["edges"].shape))
    moved = gap.solve(edges, guide, (gap.topo.factor(GAUGE_WEIGHT), GAUGE_WEIGHT * gap.topo.mass)) + [0.3, 0.0, 0.0]
    assert gap.misfit(gap.edges_of(moved, np.float32), targets) > 10 * gap.tolerance
    assert not gap.released(edges, moved, targets)


def test_sequence_beats_blend_on_accelerating_fall(strip):
    flat, tri = strip
    times = np.arange(0, 9)
    frames = [_bend(flat, 0.2 * t) + np.array([0.0, 0.0, -0.05 * t * t]) for t in times]
    keys = frames[::2]
    seq = SequenceInterpolator(keys, tri)
    for k in range(len(seq)):
        truth = frames[2 * k + 1]
        ours = seq.pose(k, 0.5)
        blend = 0.5 * (keys[k] + keys[k + 1])
        # interior gaps see both neighbours (Catmull–Rom); end gaps extrapolate one of them
        ratio = 0.25 if 0 < k < len(seq) - 1 else 0.6
        assert np.linalg.norm(ours - truth) < ratio * np.linalg.norm(blend - truth)


@pytest.mark.parametrize("start", ["rest", "keys"])
def test_fall_from_rest_is_exact_from_the_first_gap(strip, start):
    """A sheet dropped from rest, p(t) = p₀ + ½·a·t²: the first gap starts from rest
    (``start="rest"``) or on the parabola through the first three keys (``"keys"``, which has zero
    velocity at the first key too), so every in-between of it is exact (as the interior gaps are
    with Catmull–Rom tangents), where the linear end condition starts at the first gap's mean
    velocity (off by a·s(1 − s)²/2 at factor s)."""
    flat, tri = strip
    acceleration = np.array([0.1, -0.2, -1.0])
    keys = [flat + 0.5 * acceleration * t * t for t in range(5)]
    seq = SequenceInterpolator(keys, tri, start=start)
    for gap in range(len(seq) - 1):  # the last gap ends on a linear extrapolation
        for s in (0.25, 0.5, 0.75):
            truth = flat + 0.5 * acceleration * (gap + s) ** 2
            np.testing.assert_allclose(seq.pose(gap, s), truth, atol=1e-9)


def test_free_flight_up_to_an_impact_stays_on_its_parabola(strip):
    """A sheet dropped from rest, p(t) = p₀ + ½·a·t², lands right after the third key and is bent
    by the fourth: the gap before the landing is still free flight, so its in-betweens are on the
    parabola, exactly, and stay flat. The Catmull–Rom tangent at its end would take the velocity
    from the gap of the landing (and the bend from the fourth key: the shape would bulge)."""
    flat, tri = strip
    acceleration = np.array([0.05, 0.0, -1.0])
    keys = [flat + 0.5 * acceleration * t * t for t in range(3)]
    keys += [_bend(flat, 1.5) + 0.5 * acceleration * 4.0] * 2
    seq = SequenceInterpolator(keys, tri)
    for gap in (0, 1):
        for s in (0.25, 0.5, 0.75):
            truth = flat + 0.5 * acceleration * (gap + s) ** 2
            np.testing.assert_allclose(seq.pose(gap, s), truth, atol=1e-9)


def test_the_gap_of_an_impact_starts_with_the_free_flight_velocity(strip):
    """The same fall, landing half a gap after the third key: the gap of the landing starts with
    the velocity the free flight ends with (the mean velocities within the limit that keeps a
    stopping spline from overshooting, 11 % here; Catmull–Rom's start tangent is 46 % off), so no
    frame-to-frame jump at the key; the flight itself stays exact."""
    flat, tri = strip
    acceleration = np.array([0.05, 0.0, -1.0])
    keys = [flat + 0.5 * acceleration * t * t for t in range(3)]
    keys += [_bend(flat, 1.5) + 0.5 * acceleration * 2.5 ** 2] * 2
    seq = SequenceInterpolator(keys, tri)
    eps = 1e-4
    leaving = (seq.pose(2, eps) - seq.pose(2, 0.0)).mean(axis=0) / eps
    arriving = (seq.pose(1, 1.0) - seq.pose(1, 1.0 - eps)).mean(axis=0) / eps
    np.testing.assert_allclose(arriving, 2.0 * acceleration, rtol=1e-3, atol=1e-3)
    assert np.linalg.norm(leaving - arriving) < 0.15 * np.linalg.norm(arriving)
    np.testing.assert_allclose(seq.pose(1, 0.5), flat + 0.5 * acceleration * 1.5 ** 2, atol=1e-9)


def test_the_gap_after_an_impact_starts_on_the_parabola_through_its_end(strip):
    """Keys cut from a fall (``start="keys"``): flat at the first two keys, bent by the landing
    at the third, then sliding slowly at constant velocity. The gap after the landing starts on
    the parabola through its end (here the slide's straight line) and keeps the landed shape, exactly;
    the Catmull–Rom tangents at its start (the mean of the fall and the slide, of flat and bent)
    would carry the sheet on past the key and unbend it."""
    flat, tri = strip
    bent = _bend(flat, 1.5)
    drift = np.array([0.02, 0.0, 0.0])
    keys = [flat + [0.0, 0.0, 3.0], flat + [0.0, 0.0, 2.0], bent, bent + drift, bent + 2.0 * drift]
    seq = SequenceInterpolator(keys, tri, start="keys")
    for s in (0.25, 0.5, 0.75):
        np.testing.assert_allclose(seq.pose(2, s), bent + s * drift, atol=1e-9)


def test_the_gap_of_a_landing_arrives_with_the_velocity_the_gap_after_leaves_with(strip):
    """The same keys: the sheet lands inside the gap before the bent key, so it arrives there at
    the slide's velocity, the one the gap after leaves with (Catmull–Rom's end tangent, the mean of
    the fall and the slide, arrives at 0.8 per gap, 40 × the slide's speed, and stops at once: a
    kink at the key); the arrival never passes below the landed shape."""
    flat, tri = strip
    bent = _bend(flat, 1.5)
    drift = np.array([0.02, 0.0, 0.0])
    keys = [flat + [0.0, 0.0, 3.0], flat + [0.0, 0.0, 2.0], bent, bent + drift, bent + 2.0 * drift]
    seq = SequenceInterpolator(keys, tri, start="keys")
    eps = 1e-4
    leaving = (seq.pose(2, eps) - seq.pose(2, 0.0)) / eps
    arriving = (seq.pose(1, 1.0) - seq.pose(1, 1.0 - eps)) / eps
    np.testing.assert_allclose(leaving, np.broadcast_to(drift, leaving.shape), atol=1e-6)
    # one-sided differences: within ε × the gap's deceleration (about 6 here) of each other
    assert np.linalg.norm(arriving - leaving, axis=1).max() < 1e-3
    for s in np.linspace(0.05, 0.95, 19):
        assert (seq.pose(1, s)[:, 2] >= bent[:, 2] - 1e-9).all()


def test_a_still_sheet_hit_after_a_key_stays_still_in_the_gap_before(strip):
    """A sheet settles from rest (it sinks 0.03, then 0.005) and is bent right after the key that
    ends its still gap (a ball hitting a hanging curtain): the still gap ends on the parabola
    through its start, the velocity its own keys give at the key, ``(3 x₂ − 4 x₁ + x₀) / 2``, so
    its in-betweens stay within the cubic's bound (4/27 of the tangents' differences from the
    secant, 3.7e-3 here) of the keys' blend. Catmull–Rom's end tangent, half the move to the
    bent key, carried the hit back into it: 0.11 off the blend, arriving at 0.74 per gap."""
    flat, tri = strip
    down = np.array([0.0, 0.0, 1.0])
    keys = [flat, flat - 0.03 * down, flat - 0.035 * down, _bend(flat, 1.5) - 0.035 * down,
            _bend(flat, 2.5) - 0.035 * down]
    seq = SequenceInterpolator(keys, tri)
    start_tangent = 0.5 * (keys[2] - keys[0])  # Catmull–Rom's at key 1
    secant = keys[2] - keys[1]
    end_tangent = 2.0 * secant - start_tangent  # the parabola's at key 2
    bound = 4.0 / 27.0 * (np.linalg.norm(start_tangent - secant, axis=1)
                          + np.linalg.norm(end_tangent - secant, axis=1)).max()
    for s in np.linspace(0.05, 0.95, 19):
        blend = (1.0 - s) * keys[1] + s * keys[2]
        assert np.linalg.norm(seq.pose(1, s) - blend, axis=1).max() <= bound + 1e-9
    eps = 1e-4
    arriving = (seq.pose(1, 1.0) - seq.pose(1, 1.0 - eps)) / eps
    # one-sided difference of fitted poses: within ε × the gap's acceleration (2 (t₁ − t₀) ≈ 0.05
    # here) and the fit's tolerance (~1e-8 of the positions) ÷ ε of it, against 0.74 of old
    assert np.linalg.norm(arriving - end_tangent, axis=1).max() < 1e-3


def test_a_gap_between_a_landing_and_a_second_hit_keeps_catmull_roms_start(strip):
    """Keys cut from a fall (``start="keys"``): flat, bent by a landing at the third key, sliding
    0.02 by the fourth, then bent further by a second hit right after it (a pillow landed, then
    squashed by a slab). The after-impact start (the parabola through the gap's end) would take
    Catmull–Rom's end tangent, which carries the second hit, for the gap's own velocity, and
    mirror it into a start velocity the other way: the in-betweens strayed 0.212 from the keys'
    blend. The gap keeps Catmull–Rom's start, and its in-betweens stay within the cubic's bound
    (4/27 of the tangents' differences from the secant, 0.180) of the blend."""
    flat, tri = strip
    bent = _bend(flat, 1.0)
    drift = np.array([0.02, 0.0, 0.0])
    hit = _bend(flat, 3.0)
    keys = [flat + [0.0, 0.0, 0.4], flat + [0.0, 0.0, 0.2], bent, bent + drift, hit + 2.0 * drift,
            hit + 3.0 * drift]
    seq = SequenceInterpolator(keys, tri, start="keys")
    secant = keys[3] - keys[2]
    start_tangent, end_tangent = 0.5 * (keys[3] - keys[1]), 0.5 * (keys[4] - keys[2])  # Catmull–Rom's
    bound = 4.0 / 27.0 * (np.linalg.norm(start_tangent - secant, axis=1)
                          + np.linalg.norm(end_tangent - secant, axis=1)).max()
    for s in np.linspace(0.05, 0.95, 19):
        blend = (1.0 - s) * keys[2] + s * keys[3]
        assert np.linalg.norm(seq.pose(2, s) - blend, axis=1).max() <= bound
    # nor does the gap of the landing end with the after-impact start's velocity (its exit reads the
    # second hit as the gap after does)
    assert seq._exit(1) is None


@pytest.mark.parametrize("key_times", [[0, 2, 4, 6, 7, 8], [0, 3, 6, 9, 11, 12]])
def test_a_second_hit_after_keys_unevenly_spaced_keeps_catmull_roms_start(strip, key_times):
    """The landing and the second hit of the test above, the gap after the still gap ½ / ⅔ as long:
    the key after stands rescaled to where an evenly spaced key would be (an end condition in form,
    with its pose's own non-rigidity), farther out, and the gap still reads it as a second hit. The
    after-impact start strayed 0.418 / 0.315 from the blend; the in-betweens stay within the cubic's
    bound with Catmull–Rom's tangents of the rescaled key (0.300 / 0.240)."""
    flat, tri = strip
    bent, hit, drift = _bend(flat, 1.0), _bend(flat, 3.0), np.array([0.02, 0.0, 0.0])
    keys = [flat + [0.0, 0.0, 0.4], flat + [0.0, 0.0, 0.2], bent, bent + drift, hit + 2.0 * drift,
            hit + 3.0 * drift]
    seq = SequenceInterpolator(keys, tri, start="keys", key_times=key_times)
    scale = (key_times[3] - key_times[2]) / (key_times[4] - key_times[3])
    after = keys[3] + scale * (keys[4] - keys[3])  # the key after, evenly spaced
    secant = keys[3] - keys[2]
    start_tangent, end_tangent = 0.5 * (keys[3] - keys[1]), 0.5 * (after - keys[2])
    bound = 4.0 / 27.0 * (np.linalg.norm(start_tangent - secant, axis=1)
                          + np.linalg.norm(end_tangent - secant, axis=1)).max()
    for s in np.linspace(0.05, 0.95, 19):
        blend = (1.0 - s) * keys[2] + s * keys[3]
        assert np.linalg.norm(seq.pose(2, s) - blend, axis=1).max() <= bound


def test_motion_from_rest_leaves_the_first_key_with_zero_velocity(strip):
    """A fall that stops at the second key (an impact): ``start="rest"`` leaves the first key with
    zero velocity (displacement O(ε²) at factor ε), ``"keys"`` with the first gap's secant (the
    parabola's tangent, 1.5 × the secant here, limited to it)."""
    flat, tri = strip
    keys = [flat, flat + [0.0, 0.0, -1.0], flat + [0.0, 0.0, -1.0], flat + [0.0, 0.0, -1.0]]
    eps = 1e-3
    rest = np.abs(SequenceInterpolator(keys, tri).pose(0, eps) - flat).max()
    moving = np.abs(SequenceInterpolator(keys, tri, start="keys").pose(0, eps) - flat).max()
    assert rest < 1e-5 and abs(moving - eps) < 1e-5


@pytest.mark.parametrize("times", [[0, 4, 8, 12, 13], [0, 4, 8, 12, 14], [0, 4, 8, 12, 15], [0, 3, 8, 10, 17]])
def test_unevenly_spaced_keys_keep_the_timing_of_every_gap(times):
    """Keys of a steady screw motion (exp(t ξ)) at ``times``: with ``key_times`` every in-between
    is the motion (each key's neighbours seen per unit of the gap at hand); taken as evenly spaced,
    the gaps next to a shorter or longer one were up to 2.5 % of the sheet's side off (4.2 % at 0, 3,
    8, 10, 17)."""
    from scipy.linalg import expm

    rest, tri = grid(8, 8)
    xi = np.zeros((4, 4))
    xi[:3, :3] = [[0, -0.05, 0.02], [0.05, 0, -0.01], [-0.02, 0.01, 0]]
    xi[:3, 3] = [0.1, 0.02, 0.03]

    def pose(t):
        m = expm(t * xi)
        return rest @ m[:3, :3].T + m[:3, 3]

    sequence = SequenceInterpolator([pose(t) for t in times], tri, start="keys", key_times=times)
    factors = np.linspace(0.0, 1.0, 9)[1:-1]
    for gap in range(len(times) - 1):
        a, b = times[gap], times[gap + 1]
        for factor, x in zip(factors, sequence.poses(gap, factors)):
            np.testing.assert_allclose(x, pose(a + factor * (b - a)), rtol=0, atol=1e-9)
    for t in (1.5, times[2], 0.5 * (times[-2] + times[-1])):  # pose_at takes the keys' own times
        np.testing.assert_allclose(sequence.pose_at(t), pose(t), rtol=0, atol=1e-9)
    # keys whose own speeds differ a thousandfold (a draping sheet moved as much in one frame as in
    # 999): the in-betweens stay by the keys (KEY_TIME_RATIO_LIMIT; 3.4 units out without it)
    flat, flat_tri = grid(10, 10)
    draped = [drape(flat, a) for a in (0.0, 0.3, 0.6, 1.0)]
    uneven = SequenceInterpolator(draped, flat_tri, key_times=[0, 1, 1000, 1001])
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)  # no fallback needed either
        poses = np.concatenate([uneven.poses(gap, factors) for gap in range(3)])
    assert np.all(poses >= np.min(draped, axis=(0, 1)) - 0.01) and np.all(poses <= np.max(draped, axis=(0, 1)) + 0.01)
    for bad in ([0, 4, 4, 12, 13], [0, 4, 8, 12], [0, 4, 8, 12, float("nan")], [True] * 5, "times"):
        with pytest.raises(MeshError, match="key_times"):
            SequenceInterpolator([pose(t) for t in times], tri, key_times=bad)


def test_a_motion_easing_into_its_last_key_ends_there_at_rest(strip):
    """A sheet sliding and sinking at constant deceleration to a stop at its last key,
    p(t) = p₀ + v·(t − t²/(2T)): with ``end="rest"`` the last gap ends with zero velocity and is
    exact (as the interior gaps are with Catmull–Rom tangents, exact for quadratic motion). The
    default end reads the stop from the last three keys and is exact too: the sheet moves rigidly,
    by its screw's spline, which slows there as the positions' does (its share of the parabola's
    tangent λ = 0: core.splines.slowing_screw_correction); with the screw's linear end (before) it
    arrived at the last gap's mean velocity, off by exactly (s³ − s²) × the gap's secant at factor s."""
    flat, tri = strip
    velocity, T = np.array([0.4, 0.1, -0.3]), 4.0
    keys = [flat + velocity * (t - t * t / (2 * T)) for t in range(5)]
    at_rest, slowed = SequenceInterpolator(keys, tri, end="rest"), SequenceInterpolator(keys, tri)
    gap = len(at_rest) - 1
    for s in (0.25, 0.5, 0.75):
        truth = flat + velocity * ((gap + s) - (gap + s) ** 2 / (2 * T))
        np.testing.assert_allclose(at_rest.pose(gap, s), truth, atol=1e-9)
        np.testing.assert_allclose(slowed.pose(gap, s), truth, atol=1e-9)
    for k in range(gap):  # the other gaps do not see the end
        np.testing.assert_array_equal(at_rest.poses(k, [0.25, 0.5]), slowed.poses(k, [0.25, 0.5]))
    with pytest.raises(MeshError, match="end must be"):
        SequenceInterpolator(keys, tri, end="stop")


def test_sequence_does_not_overshoot_after_an_abrupt_stop(strip):
    """Keys moving at constant speed, then (almost) at rest, as cloth landing on a collider: the
    gap after the stop stays near its keys instead of carrying the earlier speed on."""
    flat, tri = strip
    speed = np.array([0.5, 0.0, 0.0])
    keys = [flat + k * speed for k in range(3)] + [flat + 2 * speed + 0.01 * k * speed for k in (1, 2)]
    seq = SequenceInterpolator(keys, tri)
    shift = (seq.pose(2, 0.5) - keys[2]).mean(axis=0)
    # Catmull–Rom would move 0.5·0.01 + 0.125·(keys[3] − keys[1])/2 ≈ 0.068 of the speed.
    assert 0.0 <= shift[0] <= 0.02 * speed[0]


def test_truncated_sequence_prepares_each_key_once(monkeypatch, strip):
    """The truncated recovery's base (eigenbasis, Gram factor) is built once per key and without
    an offset surface (only the intrinsic metric is recovered)."""
    import core.reference_shape as rs

    built = []

    class Counting(rs.ReferenceShape):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            built.append(self)

    monkeypatch.setattr(rs, "ReferenceShape", Counting)
    flat, tri = strip
    keys = [_bend(flat, angle) for angle in (0.0, 0.5, 1.0, 1.5)]
    seq = SequenceInterpolator(keys, tri, k_M=20, k_N=30)
    for gap in range(len(seq)):
        assert np.isfinite(seq.pose(gap, 0.5)).all()
    assert len(built) == len(seq) and not any(reference.use_extrinsic for reference in built)


def test_a_failed_truncated_recovery_says_which_keys_and_uses_their_exact_lengths(monkeypatch, strip):
    """Where the truncated recovery fails for a pair of keys, that gap follows the keys' exact edge
    lengths (the full basis's in-betweens, to the bit), and the warning names the keys and k_M and
    says what to do, with its kind."""
    import core.reference_shape as rs
    from core.errors import RecoveryError

    def failing(self, *args, **kwargs):
        raise RecoveryError("the program is infeasible")

    flat, tri = strip
    keys = [_bend(flat, angle) for angle in (0.0, 0.5, 1.0)]
    full = SequenceInterpolator(keys, tri).pose(0, 0.5)
    monkeypatch.setattr(rs.ReferenceShape, "recover_metric", failing)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        x = SequenceInterpolator(keys, tri, k_M=20, k_N=30, key_names=["frame 1", "frame 5", "frame 9"]).pose(0, 0.5)
    np.testing.assert_array_equal(x, full)
    said = [w.message for w in caught if getattr(w.message, "kind", None) == "truncated"]
    assert said and all(isinstance(m, ShapeDifferenceWarning) for m in said), [str(w.message) for w in caught]
    assert "between frame 1 and frame 5, the edge lengths could not be recovered from the first 20 basis " \
           "functions (k_M = 20, k_N = 30)" in str(said[0]) and "a larger k_M, or 0 for the full basis" in str(said[0])


def test_in_betweens_alike_are_said_once_with_the_worst():
    """The problems of a gap's in-betweens asked together that differ only in their numbers are
    one message with how many in-betweens have them and the one keeping the most flipped or
    collapsed triangles, what happened there before their factors (a report line cut to the status
    bar's width keeps the problem), and that count for the operators to rank gaps by; another
    problem is said on its own, and a lone one names its factor."""
    from core.sequence_warnings import gap_problems

    kept = "{} triangle(s) flipped or collapsed, and no repair removed them all: the fit keeps {}"
    problems = [(0.25, "pose", kept.format(30, 1), 1), (0.5, "pose", kept.format(9, 7), 7),
                (0.75, "pose", kept.format(4, 2), 2), (0.5, "non_finite", "1 vertex(es) came out non-finite", 0)]
    said = gap_problems(problems, 3, ("frame 1", "frame 5"))
    assert said == [("pose", "between frame 1 and frame 5, 3 of the 3 in-betweens alike, the worst at factor 0.5: "
                             + kept.format(9, 7) + "; in-betweens alike at factors 0.25, 0.5, 0.75", 7, (0.25, 0.5, 0.75)),
                    ("non_finite", "between frame 1 and frame 5, the in-between at factor 0.5: 1 vertex(es) came out "
                                   "non-finite", 0, (0.5,))], said
    assert gap_problems(problems[:1], 1, ("a", "b")) == [("pose", "between a and b, the in-between at factor 0.25: "
                                                          + kept.format(30, 1), 1, (0.25,))]


def test_a_problem_has_one_shape_whether_one_in_between_or_several_have_it():
    """The same problem in two gaps, at one in-between of one and at several of the other, is one
    shape (the operators report it once); another problem, or the same past the keys (a pose, not
    an in-between), is another; the worst of several is still the one said."""
    from core.sequence_warnings import gap_problems, message_shape

    kept = "it keeps {} triangle(s) flipped or collapsed (e.g. triangle {})"
    lone = gap_problems([(0.5, "pose", kept.format(3, 40), 3)], 15, ("frame 1", "frame 17"))[0][1]
    several, = gap_problems([(f, "pose", kept.format(n, 7 * n), n) for f, n in ((0.25, 1), (0.5, 121), (0.5625, 4))],
                            15, ("frame 17", "frame 33"))
    assert "the in-between at factor 0.5:" in lone and "3 of the 15 in-betweens alike, the worst at factor 0.5: " \
        "it keeps 121" in several[1], (lone, several)
    assert message_shape(lone + ".") == message_shape(several[1] + "."), (lone, several)
    assert several[2:] == (121, (0.25, 0.5, 0.5625))  # the worst's count, and the factors it speaks for
    other = gap_problems([(0.5, "pose", "3 vertices are off their path", 0)], 15, ("frame 1", "frame 17"))[0][1]
    past = gap_problems([(1.5, "pose", kept.format(3, 40), 3)], 1, ("frame 1", "frame 17"))[0][1]
    assert len({message_shape(m) for m in (lone, other, past)}) == 3


def test_a_long_list_of_factors_says_how_many_and_from_where_to_where():
    """Factors alike beyond six, not one run of those asked, are not shortened as a run ("0.125,
    0.25, 0.375, …, 0.9375" read as every factor between): the message gives how many there are
    and their least and greatest, and is of one shape with a shorter list."""
    from core.sequence_warnings import gap_problems, message_shape

    factors = [0.125, 0.25, 0.375, 0.6875, 0.75, 0.8125, 0.9375]  # 7 of the 15, not 0.4375-0.625 nor 0.875
    said = gap_problems([(f, "pose", "it keeps 2 triangle(s)", 2) for f in factors], 15, ("a", "b"))[0]
    assert said[1].endswith("; in-betweens alike at factors 0.125, 0.25, 0.375, … (7 factors from 0.125 to 0.9375)"), said
    short = gap_problems([(f, "pose", "it keeps 2 triangle(s)", 2) for f in factors[:2]], 15, ("a", "b"))[0][1]
    assert short.endswith("at factors 0.125, 0.25") and message_shape(short) == message_shape(said[1])
    assert said[3] == tuple(factors)


def test_message_shapes_mask_numbers_only():
    """Messages of one shape differ only in their numbers: key names with digits, negative and
    tiny factors, lists and ranges of numbers; words, and messages without numbers, stay."""
    from core.sequence_warnings import message_shape

    said = "between {} and {}, the pose at factor {}: 3 triangle(s) (e.g. triangle {}) flipped"
    shapes = {message_shape(said.format(*place)) for place in
              [("Key 12", "Key 13", 1.5, 7), ("Key 1", "Key 2", -0.5, 120), ("Key 017", "Key 033", 1e-05, 0),
               ("Key 2.1", "Key 2.2", -2.5e-07, 3)]}
    assert shapes == {"between Key # and Key #, pose(s) at factor #: # triangle(s) (e.g. triangle #) flipped"}, shapes
    assert message_shape("samples 3-4: 0.25, 0.5, …, 0.75 of x-1") == "samples #: # of x-#"
    assert message_shape("no numbers here") == "no numbers here"
    assert message_shape("the in-between at factor 0.5: x") != message_shape("the pose at factor 0.5: x")


def test_in_order_visit_builds_each_key_once(monkeypatch, strip):
    """Gap k reads keys k − 1 … k + 2: visited in order, every key's frames are built once."""
    import core.inbetween_keys as keys_module
    from core import sequence_keys

    built = []

    class Counting(keys_module.Key):
        def __init__(self, topo, vertices):
            super().__init__(topo, vertices)
            built.append(self)

    monkeypatch.setattr(sequence_keys, "Key", Counting)
    flat, tri = strip
    keys = [_bend(flat, 0.3 * k) + np.array([0.0, 0.0, -0.1 * k * k]) for k in range(7)]
    seq = SequenceInterpolator(keys, tri)
    for gap in range(len(seq)):
        seq.poses(gap, [0.25, 0.5, 0.75])
    assert len(built) == len(keys)


def test_rigidly_moving_sequence_factorizes_once(monkeypatch, strip):
    """Keys that differ by rigid motions (a sheet falling and turning without deforming) keep the
    default spline anchor, as the gaps where the sheet bends fast do: one factorization for the
    whole sequence, and at most one more for the weak anchor of fits the spline holds off the
    metric (the fast bends)."""
    import core.inbetween_anchor as anchor
    import core.inbetween_topology as topology

    built = []

    class Counting(topology.SPDFactor):
        def __init__(self, matrix):
            super().__init__(matrix)
            built.append(self)

    monkeypatch.setattr(topology, "SPDFactor", Counting)
    flat, tri = strip
    turns = Rotation.from_rotvec(np.outer(np.arange(5), [0.0, 0.3, 0.1])).as_matrix()
    keys = [flat @ r.T + np.array([0.0, 0.0, -0.2 * k * k]) for k, r in enumerate(turns)]
    # then bent fast while the fall goes on (not put back where it started: that jump and the
    # slow gap after it would read as a landing, see IMPACT_SLOWDOWN)
    keys += [_bend(keys[-1], angle) + np.array([0.0, 0.0, -0.2 * k * k]) for k, angle in ((5, 1.5), (6, 3.0))]
    seq = SequenceInterpolator(keys, tri)
    for gap in range(len(seq)):
        seq.poses(gap, [0.25, 0.5, 0.75])
    factors = set(seq._topo._uniform)
    assert factors <= {("sequence", anchor.SEQUENCE_ANCHOR_WEIGHT), ("sequence", anchor.HELD_ANCHOR_WEIGHT)}
    assert ("sequence", anchor.SEQUENCE_ANCHOR_WEIGHT) in factors
    assert len(built) == len(factors)


def test_gaps_of_rigid_motion_are_their_screw_motion_without_a_solve(monkeypatch, strip):
    """Gaps where every component moves rigidly (a sheet in free flight, turning; one lying still)
    are in-betweened by their keys' co-moving spline moved by the interpolated rigid motion, which
    a solve would return, without one (a 10k sheet falling flat, keys 4 frames apart: 12.5 → 9.7
    ms per in-between); the gaps where it bends are solved."""
    import core.inbetween_solver as solver

    solved = []
    original = solver.Gap.pose

    def counting(self, s, *args, **kwargs):
        solved.append(s)
        return original(self, s, *args, **kwargs)

    monkeypatch.setattr(solver.Gap, "pose", counting)
    flat, tri = strip
    turns = Rotation.from_rotvec(np.outer(np.arange(6), [0.0, 0.3, 0.1]))
    keys = [turns[k].apply(flat) + [0.0, 0.0, -0.2 * k * k] for k in range(5)]
    keys.append(_bend(keys[-1], 1.5) + [0.0, 0.0, -0.2 * 25])
    seq = SequenceInterpolator(keys, tri)
    factors = np.arange(1, 8) / 8
    batches = [seq.poses(gap, factors) for gap in range(3)]  # the rigid gaps, away from the bend
    assert not solved
    for gap, batch in enumerate(batches):
        for s, x in zip(factors, batch):  # what the solve gives
            np.testing.assert_allclose(x, original(seq._gap(gap), s)[0] + seq._origin, atol=1e-9)
    solved.clear()
    seq.poses(4, factors)  # the bend
    assert solved


def test_blas_threads_are_given_back(strip):
    """In-betweens run with BLAS single-threaded and leave the process's BLAS settings as they were."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    flat, tri = strip
    keys = [_bend(flat, 0.3 * k) for k in range(4)]
    before = [info["num_threads"] for info in threadpoolctl.threadpool_info()]
    SequenceInterpolator(keys, tri).poses(1, [0.25, 0.5, 0.75])
    assert [info["num_threads"] for info in threadpoolctl.threadpool_info()] == before


#: In-betweens of a 5,184-vertex draped sheet (over CONCURRENT_VERTICES: the next gap is prepared in the
#: background): a sequence's at 0.5 of each gap, two poses' at 0.5 (:func:`test_same_in_betweens_whatever_ran_before`).
_REPEATED = """
import hashlib, sys
sys.path[:0] = [{root!r}, {tests!r}]
from core import Interpolator, SequenceInterpolator
from meshes import drape, grid

flat, triangles = grid(72, jitter=0.3)
keys = [drape(flat, 0.2 + 0.4 * k) for k in range(5)]

def sequence(gaps=4):
    seq = SequenceInterpolator(keys, triangles)
    return seq, hashlib.sha1(b"".join(seq.pose(k, 0.5).tobytes() for k in range(gaps))).hexdigest()

def two_poses():
    return hashlib.sha1(Interpolator(keys[1], keys[2], triangles).pose(0.5).tobytes()).hexdigest()
"""


def test_same_in_betweens_whatever_ran_before(monkeypatch):
    """A sequence's in-betweens, and two poses' computed after it, are to the bit those of a fresh
    process, also after or while a gap prepared in the background outlasts the in-betweens asked
    for (slowed here): BLAS's thread count is the process's, and that work holds its own limit of
    one thread (core.concurrency) instead of leaving the limit it found under what follows."""
    import subprocess
    import sys
    import threading
    import time
    from concurrent.futures import wait

    from core import concurrency, sequence_keys

    if concurrency.available_cores() < 2:
        pytest.skip("one core: no gap is prepared in the background")
    tests = str(Path(__file__).resolve().parent)
    code = _REPEATED.format(root=str(Path(tests).parents[1]), tests=tests)
    fresh = subprocess.run([sys.executable, "-c", code + "print(two_poses()); print(sequence()[1])"],
                           capture_output=True, text=True, timeout=300, check=True).stdout.split()
    original = sequence_keys.concurrently

    def slowed(function, items, **options):  # a background gap's relatives finish late
        if threading.current_thread() is threading.main_thread():
            return original(function, items, **options)
        return original(lambda item: (function(item), time.sleep(0.2))[0], items, **options)

    monkeypatch.setattr(sequence_keys, "concurrently", slowed)
    scope: dict = {}
    exec(code, scope)
    assert scope["sequence"]()[1] == fresh[1]
    assert scope["two_poses"]() == fresh[0]
    seq, _ = scope["sequence"](gaps=1)
    assert scope["two_poses"]() == fresh[0]  # the next gap being prepared meanwhile
    wait(list(seq._pending.values()))
    seq, _ = scope["sequence"](gaps=1)
    wait(list(seq._pending.values()))  # ... and done
    assert scope["two_poses"]() == fresh[0]


def test_background_work_holds_its_own_blas_limit():
    """Work handed to the background runs with one BLAS thread after its caller's limit is let go,
    and the process's BLAS thread counts are back as they were once every holder has let go, in
    whatever order (here the background work's own limit, taken inside the caller's, last)."""
    import threading

    pytest.importorskip("threadpoolctl")
    from core import concurrency

    if concurrency.available_cores() < 2:
        pytest.skip("one core: no work in the background")
    controller = concurrency._blas_controller()  # NumPy's and SciPy's BLAS (not those loaded later, as cvxpy's)

    def counts():
        return [info["num_threads"] for info in controller.info() if info["user_api"] == "blas"]

    # work earlier tests left in the pool (a sequence's next gap prepared in the background) ends
    # first: it holds the limit, which gives back the counts found when it was taken
    cores = concurrency.available_cores()
    idle = threading.Barrier(cores)
    for future in [concurrency.in_background(idle.wait, 60) for _ in range(cores)]:
        future.result()
    started, release = threading.Event(), threading.Event()

    def work():
        with concurrency.single_threaded_blas():  # as concurrently() does within a gap prepared there
            started.set()
            release.wait(60)
        return counts()

    with controller.limit(limits=2, user_api="blas"):  # the process's own setting
        before = counts()
        with concurrency.single_threaded_blas():
            future = concurrency.in_background(work)
            assert started.wait(60)
        release.set()
        assert future.result() == [1] * len(before)
        assert counts() == before and max(before) == 2  # (a BLAS built single-threaded stays at 1)


def test_intrinsic_only_and_input_errors(strip):
    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 1.0)
    x = interpolate(a, b, tri, 0.5, use_extrinsic=False)
    assert np.isfinite(x).all() and _edge_deviation(x, flat, tri).mean() < 0.01
    with pytest.raises(MeshError):
        interpolate(a, b[:-1], tri, 0.5)
    with pytest.raises(MeshError):
        SequenceInterpolator([a], tri)
    with pytest.raises(IndexError):
        SequenceInterpolator([a, b], tri).pose(1, 0.5)


def test_errors_name_the_keys_by_the_callers_names(strip):
    """A key the in-betweens refuse is named by ``key_names`` (the operators' frames and shape
    keys), a sequence's and two poses' alike; without them, by its place ("key pose 2",
    "vertices_b")."""
    flat, tri = strip
    keys = [_bend(flat, 0.3 * k) for k in range(4)]
    keys[2] = keys[2] * [0.0, 1.0, 0.0]  # squashed onto a line: every triangle has zero area
    named = [f"frame {1 + 4 * k}" for k in range(4)]
    with pytest.raises(MeshError, match="^frame 9: triangle .* zero area"):
        SequenceInterpolator(keys, tri, key_names=named)
    with pytest.raises(MeshError, match="^key pose 2: triangle .* zero area"):
        SequenceInterpolator(keys, tri)
    with pytest.raises(MeshError, match="^frame 5 has 179 vertices but"):
        SequenceInterpolator([keys[0], keys[1][:-1]], tri, key_names=named[:2])
    with pytest.raises(MeshError, match="^shape key 'Squashed': triangle .* zero area"):
        Interpolator(keys[0], keys[2], tri, key_names=("shape key 'Basis'", "shape key 'Squashed'"))
    with pytest.raises(MeshError, match="^vertices_b: triangle .* zero area"):
        Interpolator(keys[0], keys[2], tri)
    with pytest.raises(MeshError, match="key_names must name each of the 2 poses; got 3"):
        Interpolator(keys[0], keys[1], tri, key_names=named[:3])
    # names that are not a list of names are refused as such, not read letter by letter or
    # failing inside the check with a TypeError
    for given in ("ab", iter(named[:2]), 2):
        with pytest.raises(MeshError, match="key_names must be a list of names, one for each of the 2 poses"):
            Interpolator(keys[0], keys[1], tri, key_names=given)
    with pytest.raises(MeshError, match="one for each of the 4 key poses; got str"):
        SequenceInterpolator(keys, tri, key_names="abcd")
    # an array of names is taken as the list of its names, not read by its (ambiguous) truth value
    with pytest.raises(MeshError, match="^frame 9: triangle .* zero area"):
        SequenceInterpolator(keys, tri, key_names=np.array(named))


def test_evicted_gaps_are_freed_at_once(strip):
    """A gap the sequence's cache lets go is freed when it is dropped, not at the next full garbage
    collection (no reference cycle through its repair: at 100k vertices each holds ~150 MB)."""
    import gc
    import weakref

    from core import sequence_keys

    flat, tri = strip
    keys = [_bend(flat, 0.3 * k) for k in range(sequence_keys.GAP_CACHE + 3)]
    seq = SequenceInterpolator(keys, tri)
    seq.poses(0, [0.25, 0.5, 0.75])
    first = weakref.ref(seq._gaps[0])
    enabled = gc.isenabled()
    gc.disable()
    try:
        for k in range(1, len(seq)):
            seq.poses(k, [0.5])
        assert first() is None
    finally:
        if enabled:
            gc.enable()


def test_rotation_limit_of_the_local_steps(strip):
    """A triangle whose current edges are its interpolated target edges turned by 60° keeps that
    turn in a local step only where the rotation limit exceeds 60° (the limit a gap too rough to
    predict uses, 67.5°); at the default 45° it gets its interpolated rotation back."""
    from core import inbetween_fit, inbetween_prediction

    flat, tri = strip
    seq = SequenceInterpolator([flat, _bend(flat, 0.6), _bend(flat, 1.2)], tri)
    gap = seq._gap(0)
    gap.select(0.5)
    frames, stretch, _, _ = gap.targets(0.5)
    targets = gap.fit_targets(frames, stretch)
    turn = Rotation.from_rotvec([0.0, np.pi / 3, 0.0]).as_matrix()
    turned = np.einsum("ij,jcm->icm", turn, targets["edges"])
    assert gap.rotation_limit == inbetween_fit.MAX_ROTATION_DEVIATION < np.pi / 3 < inbetween_prediction.ROUGH_ROTATION_DEVIATION
    np.testing.assert_allclose(gap.fitted_edges(turned, targets), targets["edges"], atol=1e-12)
    gap.rotation_limit = inbetween_prediction.ROUGH_ROTATION_DEVIATION
    try:
        np.testing.assert_allclose(gap.fitted_edges(turned, targets), turned, atol=1e-9)
    finally:
        del gap.rotation_limit


def test_a_rough_gap_is_solved_with_the_wide_rotation_limit_and_gives_it_back(monkeypatch, strip):
    """In a gap found too rough to predict, the in-betweens solved after the check fit with
    ROUGH_ROTATION_DEVIATION, the three solved before it with the default limit; afterwards the
    gap has its default again, so asking the same poses twice gives the same poses."""
    from core import inbetween_fit, inbetween_prediction, inbetween_solver

    flat, tri = strip
    keys = [_bend(flat, a) for a in (0.0, 0.8, 1.6, 2.4)]
    seq = SequenceInterpolator(keys, tri)
    limits = []
    real_fit = inbetween_solver.Gap.fit

    def recording_fit(self, *args, **kwargs):
        limits.append(self.rotation_limit)
        return real_fit(self, *args, **kwargs)

    checked = []  # fits before the roughness check
    monkeypatch.setattr(inbetween_solver.Gap, "fit", recording_fit)
    monkeypatch.setattr(inbetween_prediction, "inconsistent", lambda gap, solved: checked.append(len(limits)) or True)
    factors = np.arange(1, 16) / 16
    first = seq.poses(1, factors)
    before, after = limits[:checked[0]], limits[checked[0]:]
    assert len(before) >= 3 and set(before) == {inbetween_fit.MAX_ROTATION_DEVIATION}
    # every eighth solved after the check (the rest predicted, or solved where their repair fails)
    assert len(after) >= len(inbetween_prediction.ROUGH_SOLVED_FACTORS)
    assert set(after) == {inbetween_prediction.ROUGH_ROTATION_DEVIATION}
    assert seq._gap(1).rotation_limit == inbetween_fit.MAX_ROTATION_DEVIATION
    np.testing.assert_allclose(seq.poses(1, factors), first, atol=1e-12)


def test_a_stalled_fit_returns_its_best_step(monkeypatch, strip):
    """A fit whose misfit rises again before it stalls returns the positions of its lowest misfit,
    not its last step."""
    from core import inbetween_fit

    flat, tri = strip
    seq = SequenceInterpolator([flat, _bend(flat, 0.6), _bend(flat, 1.2)], tri)
    gap = seq._gap(0)
    gap.select(0.5)
    frames, stretch, motion, guide = gap.targets(0.5)
    script = iter([3.0, 2.0, 2.5, 2.6, 2.7, 2.8])  # × the tolerance: stalls at the fourth step
    steps = []

    def scripted(self, edges, targets):
        return next(script) * self.tolerance

    real_edges = inbetween_fit.LocalGlobalFit.edges_of

    def recording_edges(self, x, *args):
        steps.append(x)
        return real_edges(self, x, *args)

    monkeypatch.setattr(inbetween_fit.LocalGlobalFit, "misfit", scripted)
    monkeypatch.setattr(inbetween_fit.LocalGlobalFit, "edges_of", recording_edges)
    misfits = []
    x = gap.fit(guide.copy(), stretch, frames, guide, 0.5, motion, misfits=misfits)
    assert len(misfits) == 4 and x is steps[1]


def test_predictions_between_keys_of_one_metric_keep_it_as_the_solved_middle_does():
    """Keys that keep their edge lengths (a sheet rolling onto a cylinder, an isometric motion)
    four frames apart: the middle in-between is solved and the quarter ones predicted from it. The
    correction polynomial stretched the predictions (edges 0.28–0.50 % off their lengths beside a
    middle 0.09–0.17 % off); a prediction farther from the interpolated metric than the solved
    middle by more than the fit's tolerance is solved instead, so none is."""
    from core.inbetween_fit import METRIC_TOLERANCE

    flat, tri = grid(25, 10, size=2.0)
    keys = [_roll(flat, t) for t in np.linspace(0.0, 0.8, 5)]
    seq = SequenceInterpolator(keys, tri)
    for k in range(len(seq)):
        quarter, middle, three_quarters = (_edge_deviation(x, flat, tri).mean() for x in seq.poses(k, [0.25, 0.5, 0.75]))
        assert max(quarter, three_quarters) <= middle + METRIC_TOLERANCE


def test_area_scale_is_the_determinant_of_the_stretch(strip):
    """A gap's area ratios (what the defect check of a predicted in-between reads) are det U of
    its interpolated stretches, between the keys and outside them."""
    flat, tri = strip
    keys = [_bend(flat, 0.0), 1.1 * _bend(flat, 0.8), _bend(flat, 1.6)]
    gap = SequenceInterpolator(keys, tri)._gap(0)
    for s in (0.3, 0.5, 1.5, -0.5):
        u = gap.stretch(s)
        np.testing.assert_allclose(gap.area_scale(s), u[:, 0] * u[:, 2] - u[:, 1] ** 2, rtol=1e-12)


def test_relatives_carry_the_metric_of_their_log_stretch():
    """Every relative of a gap — from the poses, inverted from the gap before, the identity and the
    phantoms past the ends — carries G = exp(2 log U), what the gap's metric spline interpolates."""
    import core.deformation_fields as df

    flat, tri = _strip()
    rng = np.random.default_rng(7)
    keys = [_bend(flat, a) * (1.0 + 0.05 * rng.normal(size=flat.shape)) for a in (0.0, 0.7, 1.4, 2.1)]
    seq = SequenceInterpolator(keys, tri)
    for k in range(len(seq)):
        for r in seq._gap(k).relatives:
            np.testing.assert_allclose(r.metric, df.exp_stretch(2.0 * r.log_stretch), rtol=1e-9, atol=1e-12)


def test_stretch_falls_back_to_the_log_spline_where_the_metric_spline_is_not_positive_definite(monkeypatch, strip):
    """Where the cubic spline of the metric leaves the positive definite matrices (it can, between
    keys far apart) the stretch and its area ratio are the log spline's there, and the metric's
    square root elsewhere."""
    import core.deformation_fields as df

    flat, tri = strip
    keys = [_bend(flat, 0.0), 1.1 * _bend(flat, 0.8), _bend(flat, 1.6)]
    gap = SequenceInterpolator(keys, tri)._gap(0)
    spline, real_at = gap.splines["metric"], gap.splines["metric"].at
    broken = np.zeros(len(tri), dtype=bool)
    broken[::7] = True

    def at(s):
        g = real_at(s)
        g[broken] = (1.0, 2.0, 1.0)  # eigenvalues 3 and −1
        return g

    monkeypatch.setattr(spline, "at", at)
    u = gap.stretch(0.4)
    assert "log_stretch" not in gap.splines  # the log spline of the broken rows alone: the same values
    np.testing.assert_array_equal(u[broken], df.exp_stretch(gap.splines["log_stretch"].at(0.4)[broken]))
    np.testing.assert_allclose(u[~broken], df.sqrt_stretch(real_at(0.4))[0][~broken], rtol=1e-12)
    np.testing.assert_allclose(gap.area_scale(0.4), u[:, 0] * u[:, 2] - u[:, 1] ** 2, rtol=1e-12)


def test_metric_lengths_are_the_lengths_of_the_stretched_edges(monkeypatch, strip):
    """The lengths a gap's predictions are checked against where the keys keep one metric
    (√(eᵀ G e) of the metric's spline, without its square root U) are the fit targets' |U e|, between
    the keys and outside them, and the log spline's where the metric's spline is not positive
    definite."""
    flat, tri = strip
    keys = [_bend(flat, 0.0), 1.1 * _bend(flat, 0.8), _bend(flat, 1.6)]
    gap = SequenceInterpolator(keys, tri)._gap(0)
    for s in (0.3, 0.5, 1.5, -0.5):
        np.testing.assert_allclose(gap.metric_lengths(s), gap.fit_targets(None, gap.stretch(s))["lengths"], rtol=1e-12)
    _metric_spline_broken(monkeypatch, gap)
    np.testing.assert_allclose(gap.metric_lengths(0.4), gap.fit_targets(None, gap.stretch(0.4))["lengths"], rtol=1e-12)


def _metric_spline_broken(monkeypatch, gap) -> np.ndarray:
    """The metric's spline of ``gap`` made not positive definite on every seventh triangle (whole or
    on rows): those triangles (bool (m,))."""
    spline, real_at = gap.splines["metric"], gap.splines["metric"].at
    broken = np.zeros(len(gap.topo.triangles), dtype=bool)
    broken[::7] = True

    def at(s, rows=None):
        g = real_at(s) if rows is None else real_at(s, rows)
        g[broken if rows is None else broken[rows]] = (1.0, 2.0, 1.0)  # eigenvalues 3 and −1
        return g

    monkeypatch.setattr(spline, "at", at)
    return broken


def test_metric_lengths_on_some_triangles_are_the_whole_ones_there_bit_for_bit(monkeypatch, strip):
    """The metric's lengths of some triangles alone (``metric_lengths(s, rows)``, what the
    untangle-first guard reads) are the whole mesh's on those triangles, bit for bit: between the
    keys, outside them, and where the metric's spline is not positive definite (the log spline's
    there), the rows in any order."""
    flat, tri = strip
    keys = [_bend(flat, 0.0), 1.1 * _bend(flat, 0.8), _bend(flat, 1.6)]
    gap = SequenceInterpolator(keys, tri)._gap(0)
    rows = np.random.default_rng(5).permutation(len(tri))[: len(tri) // 3]
    for s in (0.3, 0.5, 1.5, -0.5):
        np.testing.assert_array_equal(gap.metric_lengths(s, rows), gap.metric_lengths(s)[:, rows])
    broken = _metric_spline_broken(monkeypatch, gap)
    assert broken[rows].any() and not broken[rows].all()
    np.testing.assert_array_equal(gap.metric_lengths(0.4, rows), gap.metric_lengths(0.4)[:, rows])


def test_a_hold_stays_put_and_the_motion_after_it_starts_from_rest():
    """A sheet swings up to a pose, holds it for a gap (two equal keys: an animator's held pose, a
    cache that holds a pose), then falls from rest (p₀ + ½at²): the held gap's in-betweens are the
    pose itself, and the gap after it starts from rest, so the fall is exact there (before: the
    keys' spline swung out of the hold toward the keys around it and entered the fall moving, both
    gaps 0.037 off on a first drop of 0.5)."""
    flat, tri = grid(8, 6, size=1.0)
    flat = flat + [0.0, 0.0, 0.02] * np.sin(3.0 * flat[:, [0]])  # not flat: a shape to keep
    fall = np.array([0.1, -0.05, -1.0])
    keys = [flat + [0.0, 0.0, 0.3], flat, flat] + [flat + 0.5 * fall * t ** 2 for t in (1.0, 2.0, 3.0)]
    sequence = SequenceInterpolator(keys, tri)
    factors = np.arange(1, 8) / 8
    np.testing.assert_array_equal(sequence.poses(1, factors), np.broadcast_to(flat, (7, *flat.shape)))
    for s, pose in zip(factors, sequence.poses(2, factors)):
        np.testing.assert_allclose(pose, flat + 0.5 * fall * s ** 2, atol=1e-9)


def _fold(flat, share, angle, radius=0.04):
    """The sheet (x ∈ [0, 2]) with the part beyond ``1 − share`` of its length rolled over a hinge
    of ``radius`` by ``angle`` (isometric: a fold, the rest flat where it was)."""
    hinge = flat[:, 0].max() * (1.0 - share)
    out = flat.copy()
    d = flat[:, 0] - hinge
    arc = np.clip(d, 0.0, radius * angle)
    beyond = np.maximum(d - radius * angle, 0.0)
    folded = d > 0
    out[folded, 0] = (hinge + radius * np.sin(arc / radius) + beyond * np.cos(angle))[folded]
    out[folded, 2] = (radius * (1.0 - np.cos(arc / radius)) + beyond * np.sin(angle))[folded]
    return out


def test_a_rigid_fit_that_adds_turn_takes_the_rotations_whole():
    """A sheet with 45 % of it folded over by 150° and the rest where it was: its best rigid
    rotation turns 38° although more than half its triangles do not turn at all, so residuals to
    it would turn them by 38° (on a cloth dragged by a corner and folded over, splined and composed
    with the rigid motion they turned 29 % of it over at the middle of the gap): the piece's whole
    rotations are splined instead (``core.inbetween_whole_rotations.SPURIOUS_RIGID_TURN``). A fold whose rigid
    fit turns the sheet less (14°) and the folded sheet turned rigidly (residuals zero) keep the
    residuals, which make a rigid motion exact."""
    flat, triangles = grid(41, 13, size=2.0)
    turned = Rotation.from_rotvec([0.3, -0.5, 1.2]).apply(_fold(flat, 0.45, np.radians(150))) + [0.4, 0.1, 0.2]
    cases = [(_fold(flat, 0.45, np.radians(150)), True), (_fold(flat, 0.3, np.radians(90)), False), (turned, False)]
    for key, whole in cases:
        gap = SequenceInterpolator([flat, key, key + [0.5, 0.0, 0.0]], triangles)._gap(0)
        assert bool(gap.relatives[2].whole.any()) is whole


def test_rotations_that_pull_against_the_guide_are_taken_whole():
    """Keys 16 frames apart of a Blender cloth hanging from a keyframed corner, 150 of its 12,600
    vertices (every tenth row and column) and the simulated frame between keys 3 and 4: between
    them the sheet spins 193° about its corner while it folds (the rigid fit leaves 7.5 % of its
    diagonal; its triangles' residuals to it turn 96°, median). Composed with the interpolated rigid
    turn, the residuals turned 71 triangles of the in-between half-way against both keys (the
    simulated frame: 25), their normals against the keys' per-vertex spline that anchors the fit
    (``core.inbetween_guide.AGAINST_GUIDE_SHARE``); the whole rotations are splined there instead."""
    data = np.load(Path(__file__).parent / "data" / "spinning_sheet.npz")
    keys, middle, triangles = data["keys"].astype(np.float64), data["middle"].astype(np.float64), data["triangles"]
    a, b = keys[3], keys[4]
    x = SequenceInterpolator(keys, triangles).pose(3, 0.5)
    assert _flipped(x, a, b, triangles) <= _flipped(middle, a, b, triangles)
    nearer_key = min(np.sqrt(np.mean(np.sum((k - middle) ** 2, axis=1))) for k in (a, b))
    assert np.sqrt(np.mean(np.sum((x - middle) ** 2, axis=1))) < nearer_key


def test_a_piece_whose_rigid_fits_do_not_compose_is_not_guided_along_their_turn():
    """Keys 8 frames apart of a Blender cloth whipped by a keyframed corner, 150 of its 12,600
    vertices (every tenth row and column), and the simulated frames half-way between keys 3 and 4
    and keys 4 and 5, where the sheet flips over its corner: its world spline is strained over
    twice as much as its co-moving spline (``core.inbetween_guide.ARC_GUIDE_STRAIN_RATIO``), but
    its rigid fits over keys 2 … 6 do not compose (the fit from key 3 to key 5 is 54° off the fit
    from 3 to 4 followed by the one from 4 to 5), so the interpolated rigid turn is no path of the
    sheet's: guided along it, the in-betweens were 1.4 × and 1.2 × the blend's distance from those
    frames (``ARC_FIT_COMPOSITION``)."""
    data = np.load(Path(__file__).parent / "data" / "whipped_sheet.npz")
    keys, middles, triangles = data["keys"].astype(np.float64), data["middles"].astype(np.float64), data["triangles"]
    sequence = SequenceInterpolator(keys, triangles)
    for gap, middle in zip((3, 4), middles):
        a, b = keys[gap], keys[gap + 1]
        with warnings.catch_warnings():  # gap 3 keeps 4 of its 252 triangles flipped (the blend 43) and says so
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            x = sequence.pose(gap, 0.5)
        assert np.sqrt(np.mean(np.sum((x - middle) ** 2, axis=1))) < np.sqrt(np.mean(np.sum((0.5 * (a + b) - middle) ** 2, axis=1)))
        assert not sequence._gap(gap).arc_guided.any()


def test_rigid_fits_that_do_not_compose_are_found_between_unevenly_spaced_keys():
    """The whipped sheet's keys with every other one 0.4 frames late: the spline moves the
    neighbouring keys to where evenly spaced ones would be (end conditions that no pose has), but
    the fits that compose or not are the keys' own, whatever their times. Left out as
    extrapolated, no fit was compared in gaps 3 and 4 and the sheet was guided along the turn
    that is no path of its: 1.39 × and 1.22 × the blend's distance from the frames half-way."""
    data = np.load(Path(__file__).parent / "data" / "whipped_sheet.npz")
    keys, middles, triangles = data["keys"].astype(np.float64), data["middles"].astype(np.float64), data["triangles"]
    times = 8.0 * np.arange(len(keys)) + 0.4 * (np.arange(len(keys)) % 2)
    sequence = SequenceInterpolator(keys, triangles, key_times=times)
    for gap, middle in zip((3, 4), middles):
        assert sequence._gap(gap).relatives[0].extrapolated and sequence._gap(gap).relatives[3].extrapolated
        a, b = keys[gap], keys[gap + 1]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            x = sequence.pose(gap, 0.5)
        assert not sequence._gap(gap).arc_guided.any()
        blend = 0.5 * (a + b)
        assert np.sqrt(np.mean(np.sum((x - middle) ** 2, axis=1))) < np.sqrt(np.mean(np.sum((blend - middle) ** 2, axis=1)))


def test_a_cloth_folding_over_near_a_half_turn_is_not_guided_along_its_rigid_arc():
    """Keys 16 frames apart of a Blender tablecloth yanked off a table by its hooked edge, 2,592 of
    its 22,400 vertices (every third row and column), and the simulated frames at a half and three
    quarters of gap 1, where it slides off and turns over: its rigid fit turns 184° between the
    keys while it deforms (non-rigidity 0.14 over the gap's keys), and its parts turn over both
    ways round (44–49 % of its triangles about +y, the rest about −y). Guided along the arc of
    that rigid turn, its co-moving spline stood the cloth up on its hooked edge (centroid 1.85
    high at the middle of the gap, the simulation's 0.30): 1.62 × and 1.29 × the blend's distance
    from those frames (``core.inbetween_solver``: no co-moving guide for a deforming piece near a
    half turn)."""
    data = np.load(Path(__file__).parent / "data" / "pulled_tablecloth.npz")
    keys, middles, triangles = data["keys"].astype(np.float64), data["middles"].astype(np.float64), data["triangles"]
    sequence = SequenceInterpolator(keys, triangles)
    a, b = keys[1], keys[2]
    with warnings.catch_warnings():  # repairs that leave a few triangles flipped say so
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        poses = sequence.poses(1, (0.5, 0.75))
    for s, x, middle in zip((0.5, 0.75), poses, middles):
        blend = (1.0 - s) * a + s * b
        assert np.sqrt(np.mean(np.sum((x - middle) ** 2, axis=1))) < np.sqrt(np.mean(np.sum((blend - middle) ** 2, axis=1)))
    assert not sequence._gap(1).arc_guided.any()


def test_a_sheet_keeping_its_shape_while_it_turns_over_keeps_its_arc():
    """A 2-unit sheet sagging by 3 % (non-rigidity 0.6 % of its size) turned over about its own
    centre, 8°, 8°, 170° and 10° between keys, while it travels 1.5 per key in a straight line:
    near a half turn but keeping its shape, so the arc of its rigid turn is its path and the gap
    is guided along it (``core.inbetween_solver``: only pieces that deform past 1 % of their size
    are not): half-way its in-between is within the sag's amplitude of the truth (0.018; left to
    the world spline, which cuts the turn's chords, 0.114, the blend 0.55)."""
    from scipy.interpolate import PchipInterpolator

    flat, triangles = grid(21, size=2.0)
    centre = flat.mean(axis=0)
    angle = PchipInterpolator(np.arange(5), np.radians([0.0, 8.0, 16.0, 186.0, 196.0]))

    def pose(t):
        sag = 0.03 * np.sin(2 * t + 0.5) * np.cos(np.pi * (flat[:, 0] - 1.0) / 2.0)
        turn = Rotation.from_rotvec(angle(t) * np.array([0.0, 1.0, 0.0])).as_matrix()
        return (flat - centre + np.outer(sag, [0.0, 0.0, 1.0])) @ turn.T + centre + [1.5 * t, 0.0, 0.0]

    sequence = SequenceInterpolator([pose(k) for k in range(5)], triangles)
    x = sequence.pose(2, 0.5)
    assert sequence._gap(2).arc_guided.all()
    assert np.sqrt(np.mean(np.sum((x - pose(2.5)) ** 2, axis=1))) < 0.03


def test_a_gap_prepared_again_lets_its_first_build_go_first(monkeypatch):
    """The spinning sheet's gap 3 is built twice (its whole rotations taken, AGAINST_GUIDE_SHARE):
    the first build is let go before the second is made, so that preparing it holds one gap's
    data, not two (before: both at once)."""
    data = np.load(Path(__file__).parent / "data" / "spinning_sheet.npz")
    keys, triangles = data["keys"].astype(np.float64), data["triangles"]
    sequence = SequenceInterpolator(keys, triangles)
    built, alive = [], []
    segment = SequenceInterpolator._segment

    def recorded(self, *args):
        alive.append([ref() is not None for ref in built])
        gap = segment(self, *args)
        built.append(weakref.ref(gap))
        return gap

    monkeypatch.setattr(SequenceInterpolator, "_segment", recorded)
    sequence._prepare(3)
    assert alive == [[], [False]]


def _turning_sheet(wobble):
    """A draped 21 × 21 sheet turned 100° per key about the z axis, off its centre, with its shape
    changed by ``wobble(t)`` (n, 3) at key time t; returns (pose(t), triangles)."""
    from meshes import draped_sheet, turned

    shape, triangles = draped_sheet()

    def pose(t):
        return turned(shape + wobble(t) + [0.37, 0.23, 0.0], t)
    return pose, triangles


def test_a_sheet_turning_as_a_whole_is_turned_between_the_keys():
    """A sheet turning 100° between keys while it sags and lifts by a few percent (so it is not
    rigid): the keys' per-vertex spline cuts the chords of its arcs (a cloth on a turntable, keys 16
    frames apart: 37 % of its edge lengths at mid-gap), so the anchor's guide is its co-moving
    spline there (``core.inbetween_guide.ARC_GUIDE_STRAIN_RATIO``); the in-betweens follow the
    turn to a fifth of the wobble's amplitude (0.035 off the 2-unit sheet before, the blend 0.3).
    """
    pose, triangles = _turning_sheet(lambda t: np.outer(0.03 * np.sin(2 * t) * np.ones(441), [0.0, 0.0, 1.0])
                                     * np.cos(np.linspace(0, 6, 441))[:, None])
    keys = [pose(k) for k in range(5)]
    sequence = SequenceInterpolator(keys, triangles)
    for gap in (1, 2):  # the first gap starts from rest and the last ends linearly, unlike the turn
        factors = np.arange(1, 8) / 8
        for s, x in zip(factors, sequence.poses(gap, factors)):
            truth = pose(gap + s)
            assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < 0.2 * 0.03
            assert _edge_deviation(x, truth, triangles).mean() < 0.1 * 0.03


def test_a_sheet_keeping_its_shape_while_it_turns_about_an_axis_off_it_keeps_that_axis():
    """The turning sheet with a wobble of a third of the amplitude (non-rigidity 0.1–1 % of its
    size: it keeps its shape, so it is turned about the axis line the keys share or else about its
    centroid, ``core.inbetween_flight.DEFORMING_AXIS_NOISE``): the keys turn it about one axis off
    its centre, which is found, and the in-betweens follow the turn to a fifth of the wobble's
    amplitude (about its centroid: its centre on the chord of its circle)."""
    from core.inbetween_motion import RIGID_PLACEMENT_SCALE, SIMILAR_SHAPE_MISFIT

    pose, triangles = _turning_sheet(lambda t: np.outer(0.01 * np.sin(2 * t) * np.ones(441), [0.0, 0.0, 1.0])
                                     * np.cos(np.linspace(0, 6, 441))[:, None])
    keys = [pose(k) for k in range(5)]
    sequence = SequenceInterpolator(keys, triangles)
    for gap in (1, 2):
        assert RIGID_PLACEMENT_SCALE <= sequence._gap(gap).nonrigidity[0] < SIMILAR_SHAPE_MISFIT[0]
        factors = np.arange(1, 8) / 8
        for s, x in zip(factors, sequence.poses(gap, factors)):
            assert np.sqrt(np.mean(np.sum((x - pose(gap + s)) ** 2, axis=1))) < 0.2 * 0.01


def test_a_deforming_sheet_thrown_while_it_tumbles_keeps_its_centre_on_its_path():
    """A draped sheet thrown (its centre on a parabola) while it tumbles 100° a key about a tilted
    axis through its centre and wobbles by 0.06 (non-rigidity past SIMILAR_SHAPE_MISFIT's first
    share: its shape is no body's): the keys turn it about no common axis, so it is turned about its
    centroid, whose spline is the parabola, not about the screw's axis, which swings its centre
    along a helix off the path (0.036–0.049 off at mid-gap; ``core.inbetween_flight.DEFORMING_AXIS_NOISE``).
    The in-betweens follow the throw to a quarter of the wobble's amplitude."""
    from scipy.spatial.transform import Rotation

    from core.inbetween_motion import SIMILAR_SHAPE_MISFIT
    from meshes import draped_sheet

    shape, triangles = draped_sheet()
    centre = shape.mean(axis=0)
    axis = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])
    wobble = np.outer(np.cos(np.linspace(0, 6, 441)), [0.0, 0.0, 0.06])

    def pose(t):
        path = np.array([0.9 * t, 0.1 * t, 1.2 * t - 0.35 * t * t])
        return Rotation.from_rotvec(np.radians(100.0 * t) * axis).apply(shape - centre + np.sin(2 * t) * wobble) + centre + path

    sequence = SequenceInterpolator([pose(k) for k in range(5)], triangles)
    for gap in (1, 2):  # the first gap starts from rest and the last ends linearly, unlike the throw
        assert sequence._gap(gap).nonrigidity[0] > SIMILAR_SHAPE_MISFIT[0]
        factors = np.arange(1, 8) / 8
        for s, x in zip(factors, sequence.poses(gap, factors)):
            assert np.sqrt(np.mean(np.sum((x - pose(gap + s)) ** 2, axis=1))) < 0.25 * 0.06


def test_a_baked_sheet_tossed_while_it_crumples_is_turned_about_its_centre():
    """A 3,025-vertex cotton sheet thrown with a spin in Blender (every vertex pinned to the object's
    throw for six frames, then let go) tumbles in free flight and lands; keys every 16 frames
    (``tossed_sheet.npz``: frames 0, 16, 32, 48 and the bake's frame 24, single precision). Gap 1
    turns it 123° while it crumples (non-rigidity 0.22): turned about the screw's axis its centre
    swings along a helix below the chord of its flight (1.08 × the blend's RMS at mid-gap), and a
    common-axis tolerance growing with that non-rigidity would pass a point the four keys' turns do
    not share (2.5 ×; ``core.inbetween_flight.DEFORMING_AXIS_NOISE``). Turned about its centroid the
    in-between is nearer the bake's frame than the blend, issue 17's bound for sequences."""
    data = np.load(Path(__file__).parent / "data" / "tossed_sheet.npz")
    keys, middle = data["keys"].astype(np.float64), data["middle"].astype(np.float64)
    sequence = SequenceInterpolator(keys, data["triangles"])
    ours, blend = sequence.pose(1, 0.5), 0.5 * (keys[1] + keys[2])
    assert np.sqrt(np.mean(np.sum((ours - middle) ** 2, axis=1))) < np.sqrt(np.mean(np.sum((blend - middle) ** 2, axis=1)))


def test_pins_on_an_object_turning_past_a_half_turn_over_two_gaps_keep_turning():
    """A sheet whose middle row keeps its length while the sheet turns 100° per key (the row is a
    riding set, :mod:`core.pins`: pinned to a moving object): its rigid motion is splined as a
    screw whose turns continue across the keys (200° to the key after next: the short way round
    turned it 160° back, and the row missed by 0.4 of the 2-unit sheet at mid-gap)."""
    pose, triangles = _turning_sheet(lambda t: 0.0)  # the drape keeps the row x = 0.5 straight and still
    column = np.linspace(-1.0, 1.0, 21)[np.arange(441) % 21]
    row = np.flatnonzero(np.isclose(column, 0.5))
    along = np.linspace(0.0, 1.0, 21)[np.arange(441) // 21]
    lift = np.outer(np.abs(column - 0.5) * (1.0 + along * along), [0.0, 0.0, 0.02])  # zero on the row
    keys = [pose(k) + np.sin(2 * k) * lift for k in range(5)]  # the rest of the sheet not rigid
    sequence = SequenceInterpolator(keys, triangles)
    for gap in (1, 2):
        for s, x in zip((0.25, 0.5, 0.75), sequence.poses(gap, [0.25, 0.5, 0.75])):
            np.testing.assert_allclose(x[row], pose(gap + s)[row], atol=1e-9)


def test_a_gap_does_no_work_its_in_betweens_do_not_need(monkeypatch, strip):
    """The middle gap of a bending strip, three in-betweens: each factor's rigid motion is computed
    once however many times the solve, checks and predictions ask for it; the trimmed tolerance
    (a partial sort of the edges' changes, read by batches of TRIMMED_TOLERANCE_BATCH or more) is
    not computed; nor, while the metrics' spline stays positive definite at the factors, the
    log-stretches' spline, nor its keys' log-stretches, nor the corner-major incidence of two
    poses' blend anchor; the relatives keep no turned frames nor their rotations' entries. What
    is made on demand is what would have been made up front."""
    import core.deformation_fields as df
    from core import screw_motions
    import core.inbetween_solver as solver
    from core.inbetween_prediction import TRIMMED_TOLERANCE_BATCH

    flat, tri = strip
    rng = np.random.default_rng(11)
    keys = [_bend(flat, a) + 0.002 * rng.normal(size=flat.shape) for a in (0.0, 0.5, 1.0, 1.5, 2.0)]
    factors = [0.25, 0.5, 0.75]
    assert len(factors) < TRIMMED_TOLERANCE_BATCH
    seq = SequenceInterpolator(keys, tri)
    asked, made = set(), []
    real_motion, real_exps = solver.Gap.motion, screw_motions.rigid_exps
    monkeypatch.setattr(solver.Gap, "motion", lambda self, s: asked.add(s) or real_motion(self, s))
    monkeypatch.setattr(screw_motions, "rigid_exps", lambda screws: made.append(1) or real_exps(screws))
    seq.poses(2, factors)
    gap = seq._gap(2)
    assert len(asked) >= 3 and len(made) == len(asked)
    assert "trimmed_tolerance" not in gap.__dict__
    assert all(df.sqrt_det(gap.splines["metric"].at(s))[1].all() for s in factors)
    assert "log_stretch" not in gap.splines
    assert all(r._log is None for r in gap.relatives if not r.extrapolated and r.rotvec.any())
    assert all(r._plane_frames is None for r in gap.relatives)  # the constructor's frames let go once read
    assert all(r._whole is None for r in gap.relatives)  # ... and the entries made from them
    assert "D" not in seq._topo.__dict__  # two poses' incidence: a sequence never reads it
    # made when read: the spline of the keys' log-stretches, the tolerance of the partial sort
    from core.inbetween_fit import trimmed_tolerance
    from core.splines import HermiteGap

    spline = gap.splines["log_stretch"]
    assert isinstance(spline, HermiteGap)
    np.testing.assert_array_equal(spline.at(0.0), gap.relatives[1].log_stretch)
    np.testing.assert_allclose(spline.at(1.0), gap.relatives[2].log_stretch, rtol=1e-12, atol=1e-15)
    assert gap.trimmed_tolerance == trimmed_tolerance(gap.base.lengths, gap.next.lengths)


def test_targets_by_rows_are_the_targets_on_those_rows(strip):
    """The frames and stretches a repair of a predicted in-between reads on its regions alone are
    the whole targets' on those rows, bit for bit, whatever the order the rows are asked in."""
    flat, tri = strip
    rng = np.random.default_rng(5)
    keys = [_bend(flat, a) + 0.002 * rng.normal(size=flat.shape) for a in (0.0, 0.7, 1.4, 2.1)]
    gap = SequenceInterpolator(keys, tri)._gap(1)
    for s in (0.3, 0.5):
        frames, stretch = gap.targets(s)[:2]
        by_rows, stretch_rows = gap.targets(s, by_rows=True)[:2]
        for rows in (np.array([40, 3, 17, 3]), np.arange(10, 60), len(tri) // 2 + np.arange(5)):
            np.testing.assert_array_equal(by_rows[:, rows], frames[:, rows])
            np.testing.assert_array_equal(stretch_rows[rows], stretch[rows])
        np.testing.assert_array_equal(by_rows[:, slice(None)], frames)
        np.testing.assert_array_equal(stretch_rows[np.ones(len(tri), dtype=bool)], stretch)


def test_a_gap_keeps_the_rigid_motions_of_a_bounded_number_of_factors(monkeypatch, strip):
    """A gap lives as long as its interpolator: two poses asked for one factor after another keep
    at most MOTION_CACHE factors' rigid motions (each pose ask kept before, 29 MB after 300
    factors at 1,000 pieces), and a batch larger than the cache gives the poses it gives with
    every factor's motion kept."""
    import core.inbetween_motion as motion

    flat, tri = strip
    pair = Interpolator(_bend(flat, 0.3), _bend(flat, 1.5), tri)
    factors = np.linspace(0.01, 0.99, 64)
    for s in factors:
        pair.pose(float(s))
    held = len(pair._sequence._gap(0)._motions)
    assert 0 < held < len(factors), held  # not one per factor ever asked for
    assert held <= motion.MOTION_CACHE
    np.testing.assert_array_equal(pair.pose(float(factors[0])), Interpolator(_bend(flat, 0.3), _bend(flat, 1.5), tri)
                                  .pose(float(factors[0])))
    keys = [_bend(flat, a) for a in (0.0, 0.5, 1.0, 1.5)]
    batch = [float(s) for s in np.linspace(0.01, 0.99, 2 * motion.MOTION_CACHE)]
    bounded = SequenceInterpolator(keys, tri).poses(1, batch)
    monkeypatch.setattr(motion, "MOTION_CACHE", 10 ** 6)
    np.testing.assert_array_equal(bounded, SequenceInterpolator(keys, tri).poses(1, batch))


def test_each_pair_of_keys_is_fitted_rigidly_once_and_keeping_the_fits_changes_nothing(strip, monkeypatch):
    """A sheet in free flight, then landing: the gaps' relatives fit each key to the next two, and
    the gaps around read the non-rigidity of those pairs again where a gap starts in free flight or
    ends at an impact (``_entry``, ``_exit``). Each pair of keys is fitted once (the sequence keeps
    the fits: ``FIT_CACHE``), and the in-betweens are those made without keeping any, to the bit."""
    import core.inbetween_keys as inbetween_keys
    import core.sequence_keys as sequence_keys
    from core.inbetween_rigid_fits import rigid_fits

    flat, tri = strip
    acceleration = np.array([0.05, 0.0, -1.0])
    keys = [flat + 0.5 * acceleration * t * t for t in range(4)]
    keys += [_bend(flat, 1.5) + 0.5 * acceleration * 3.5 ** 2] * 3
    fitted = []

    def counted(topo, base, other):
        fitted.append((id(base), id(other)))
        return rigid_fits(topo, base, other)

    monkeypatch.setattr(inbetween_keys, "rigid_fits", counted)
    monkeypatch.setattr(sequence_keys, "rigid_fits", counted)
    factors = np.arange(1, 4) / 4
    seq = SequenceInterpolator(keys, tri)
    kept = [seq.poses(k, factors) for k in range(len(seq))]
    assert len(set(fitted)) >= 2 * len(seq) - 1  # the relatives' pairs at least
    assert len(fitted) == len(set(fitted))  # no pair twice
    assert all(not value.flags.writeable for fits in seq._fitted.values() for value in fits)
    monkeypatch.setattr(sequence_keys, "FIT_CACHE", 0)  # every fit made anew where it is asked for
    fitted.clear()
    again = SequenceInterpolator(keys, tri)
    anew = [again.poses(k, factors) for k in range(len(again))]
    assert len(fitted) > len(set(fitted))  # the gaps around do ask again
    assert all(np.array_equal(a, b) for a, b in zip(kept, anew))


@pytest.mark.parametrize("changes, solved", [(3.0, True), (1.0, False)])
def test_predictions_stretched_past_twice_the_keys_change_are_solved(monkeypatch, strip, changes, solved):
    """Keys 8 frames apart whose edges change (a strip bending as it widens 2 % per key): two
    in-betweens are solved, five predicted. Predictions made ``changes`` × the keys' mean edge
    change longer (scaled about the corner that stays still: every edge that much farther from
    the metric the solves reached) are solved in their place past
    :data:`~core.inbetween_prediction_repairs.STRETCHED_PREDICTION_CHANGES` (2) ×, each the pose solved at
    its factor, and kept below it."""
    from core import inbetween_prediction
    from core.inbetween_fit import KEY_VARIATION_FRACTION, METRIC_TOLERANCE

    flat, tri = strip
    keys = [_bend(flat, a) for a in (0.0, 0.8, 1.6)]
    for i, x in enumerate(keys):
        x[:, 1] *= 1.0 + 0.02 * i
    factors = list(np.arange(1, 8) / 8)
    seq = SequenceInterpolator(keys, tri)
    gap = seq._gap(0)
    assert gap.tolerance > METRIC_TOLERANCE  # the keys' edges change: the tolerance above its floor
    change = gap.tolerance / KEY_VARIATION_FRACTION
    predicted_factors = [s for s in factors if s not in (0.25, 0.75)]
    real = inbetween_prediction.repaired_prediction

    def stretched(gap, s, correction, rings=None, allowed=None, **held):
        x, problem = real(gap, s, correction, rings, allowed, **held)
        return x[0] + (1.0 + changes * change) * (x - x[0]), problem  # about the corner that stays still

    monkeypatch.setattr(inbetween_prediction, "repaired_prediction", stretched)
    poses = dict(zip(factors, seq.poses(0, factors)))
    for s in predicted_factors:
        alone = seq.pose(0, s)
        deviation = _edge_deviation(poses[s], alone, tri).mean()
        if solved:
            np.testing.assert_allclose(poses[s], alone, atol=1e-9)
        else:  # the stretched prediction kept: its edges that much longer than the solve's
            assert deviation > 0.5 * changes * change


def _off_metric_predictions_and_collapsed_solves(monkeypatch, strip):
    """Keys of one metric (a strip bending without stretch, the tolerance at its floor) and the
    factors of in-betweens 8 frames apart, with predictions made 1 % longer along the strip (ten
    tolerances) that keep a defect no repair removed (said by their problem) and solves in their
    place with triangles collapsed (two vertices merged): ``(sequence, factors, made)``, ``made``
    filled with the predictions {factor: positions} as they are made."""
    from core import inbetween_prediction, inbetween_prediction_repairs
    from core.inbetween_fit import METRIC_TOLERANCE

    flat, tri = strip
    seq = SequenceInterpolator([_bend(flat, a) for a in (0.0, 0.8, 1.6)], tri)
    assert seq._gap(0).tolerance == METRIC_TOLERANCE
    real_predicted, real_solve = inbetween_prediction.repaired_prediction, inbetween_prediction_repairs._solved_instead
    made = {}

    def stretched(gap, s, correction, rings=None, allowed=None, **held):
        x, _ = real_predicted(gap, s, correction, rings, allowed, **held)
        made[s] = x.copy()  # stretched along x from the edge x = 0, which stays still
        made[s][:, 0] = x[0, 0] + (1.0 + 10.0 * METRIC_TOLERANCE) * (x[:, 0] - x[0, 0])
        return made[s], "kept a defect"

    def collapsed(gap, s, *held):
        x, _ = real_solve(gap, s, *held)
        x = x.copy()
        a, b = tri[len(tri) // 2, :2]
        x[a] = x[b]  # the triangles on that edge collapsed
        return x, "kept defects"

    monkeypatch.setattr(inbetween_prediction, "repaired_prediction", stretched)
    monkeypatch.setattr(inbetween_prediction_repairs, "_solved_instead", collapsed)
    return seq, list(np.arange(1, 8) / 8), made


def test_an_off_metric_prediction_with_defects_is_kept_where_its_solve_keeps_more(monkeypatch, strip):
    """In-betweens 8 frames apart of keys of one metric whose predictions end off it and keep a
    defect (:func:`_off_metric_predictions_and_collapsed_solves`) are solved in their place only
    where the solve keeps no more defects: a solve with triangles collapsed leaves the prediction
    as it was. (The repairs again of a solve that kept defects are off here: this stand-in's
    collapse, which no repair of its own went through, is what they remove.)"""
    from core import inbetween_prediction_repairs

    seq, factors, made = _off_metric_predictions_and_collapsed_solves(monkeypatch, strip)
    monkeypatch.setattr(inbetween_prediction_repairs, "REPAIR_PASSES", 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        poses = dict(zip(factors, seq.poses(0, factors)))
    assert set(made) == {s for s in factors if s not in (0.25, 0.75)}
    for s, x in made.items():  # the prediction, in the caller's frame (the sequence's origin added back)
        np.testing.assert_allclose(poses[s] - x, np.broadcast_to(poses[s][0] - x[0], x.shape), atol=1e-12)


def test_an_off_metric_solve_with_defects_is_repaired_again_before_it_is_weighed(monkeypatch, strip):
    """The setting above with the repairs again on: the solve that replaces an off-metric
    prediction kept defects (two vertices merged), so it is repaired again as any in-between that
    keeps defects is, comes out with none, and is taken in the prediction's place."""
    from core.inbetween_fit import METRIC_TOLERANCE

    flat, _ = strip
    seq, factors, made = _off_metric_predictions_and_collapsed_solves(monkeypatch, strip)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        poses = dict(zip(factors, seq.poses(0, factors)))
    gap = seq._gap(0)
    assert set(made) == {s for s in factors if s not in (0.25, 0.75)}
    for s, x in made.items():
        assert not gap.repair.defects(seq._to_working(poses[s]), s, None, None, scale=gap.area_scale(s)).any()
        # not the prediction (1 % longer): the solve, repaired
        assert np.abs((poses[s] - x) - (poses[s][0] - x[0])).max() > METRIC_TOLERANCE * np.ptp(flat[:, 0])


@pytest.mark.parametrize("order", ["reversed", "from the middle out"])
def test_off_metric_solves_take_one_anchor_whatever_order_they_run_in(monkeypatch, strip, order):
    """The off-metric predictions of keys of one metric (:func:`_off_metric_predictions_and_collapsed_solves`,
    its predictions only) solved in their place run concurrently, so in an order the threads'
    timing decides. Where one of those solves is held off the metric (standing in: the fit at
    5/8 with the gap's own anchor, which takes the weak anchor) and none solved before was, every
    other is solved with the weak anchor too, as the gap's solved in-betweens are: the
    in-betweens are the same to the bit in whichever order the solves run, and all of them
    weakly anchored. (Where each solve read what the others had recorded so far, those solved
    before the held one kept the gap's anchor and those after took the weak one.)"""
    from core import inbetween_prediction_repairs
    from core.inbetween_solver import Gap

    real_pose, real_solved_instead = Gap.pose, inbetween_prediction_repairs._solved_instead
    held_here = 0.625

    def pose(gap, s, weak=None, start=None, **options):
        if weak is None and start is None and 0.0 < s < 1.0:  # the held test, decided here
            weak = abs(s - held_here) < 1e-12
        return real_pose(gap, s, weak=weak, start=start, **options)

    monkeypatch.setattr(Gap, "pose", pose)
    monkeypatch.setattr(inbetween_prediction_repairs, "REPAIR_PASSES", 0)
    real_per_factor = inbetween_prediction_repairs.per_factor

    def in_order(gap, function, factors):
        factors = list(factors)
        if order == "reversed":
            ran = factors[::-1]
        else:
            ran = sorted(factors, key=lambda s: abs(s - 0.5))
        out = dict(zip(ran, real_per_factor(gap, function, ran)))
        return [out[s] for s in factors]

    results = {}
    for how in ("given", order):
        seq, factors, made = _off_metric_predictions_and_collapsed_solves(monkeypatch, strip)
        monkeypatch.setattr(inbetween_prediction_repairs, "_solved_instead", real_solved_instead)  # the real solves
        monkeypatch.setattr(inbetween_prediction_repairs, "per_factor", in_order if how == order else real_per_factor)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            results[how] = np.stack(seq.poses(0, factors))
        gap = seq._gap(0)
        off = sorted(made)
        assert held_here in off and len(off) >= 3
        assert all(gap.held_factors[s] for s in off)
    np.testing.assert_array_equal(results["given"], results[order])


def test_thousands_of_pieces_moving_as_one_are_in_betweened_as_one():
    """6,000 separate triangles (a shattered plate, keyed before it breaks) thrown spinning as one
    over three keys: every in-between is one rigid motion of the first key, to round-off of
    its rigid fit (1e-6 of its 100-unit size), their group found without listing the 18 M pairs of
    pieces (core.spread_groups)."""
    rng = np.random.default_rng(0)
    m = 6000
    corners = np.repeat(np.c_[rng.uniform(0.0, 100.0, (m, 2)), np.zeros(m)], 3, axis=0)
    flat = corners + np.tile([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0]], (m, 1))
    triangles = np.arange(3 * m).reshape(m, 3)
    centre = np.array([50.0, 50.0, 0.0])  # spun about its centre as the centre flies on: no hinge
    turns = Rotation.from_rotvec(np.outer(np.arange(3), [0.0, 0.1, 0.3]))
    keys = [turns[k].apply(flat - centre) + centre + [20.0 * k, 5.0 * k, 10.0 * k] for k in range(3)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        seq = SequenceInterpolator(keys, triangles)
        poses = [p for gap in range(2) for p in seq.poses(gap, [0.25, 0.5, 0.75])]
    for x in poses:
        rotation, _ = Rotation.align_vectors(x - x.mean(axis=0), flat - flat.mean(axis=0))
        assert np.abs(rotation.apply(flat - flat.mean(axis=0)) - (x - x.mean(axis=0))).max() < 1e-6


@pytest.mark.parametrize("cores", [1, 8])
def test_next_key_relative_built_once_after_whole_rotations(monkeypatch, strip, own_pool, cores):
    """A gap whose rotations are taken whole (forced here in the second gap, as where its pieces'
    rigid fits add turn) keeps the relative of its next key it built from the poses for the gap
    after, which reads it inverted: visited in order, each key pair's relative is built once, with
    one core and with eight (the next gap prepared in the background), and the in-betweens are the
    same to the bit as a sequence whose caches start empty for every gap."""
    import core.concurrency as concurrency
    import core.inbetween_keys as keys_module
    from core import sequence_inbetweens

    monkeypatch.setattr(concurrency, "available_cores", lambda: cores)
    monkeypatch.setattr(sequence_inbetweens, "CONCURRENT_VERTICES", 0)  # the strip prepared in the background too
    flat, tri = strip
    keys = [_bend(flat, 0.3 * k) + np.array([0.0, 0.0, -0.1 * k * k]) for k in range(6)]
    add_turn = keys_module.Relative.residuals_add_turn

    def forced(relative, topo, base, other):  # every piece taken whole in the gap from key 1
        told = add_turn(relative, topo, base, other)
        return np.ones_like(told) if np.array_equal(base.vertices, seq._raw[1]) else told

    monkeypatch.setattr(keys_module.Relative, "residuals_add_turn", forced)
    built = []
    init = keys_module.Relative.__init__

    def counting(relative, topo, base, other, *arguments, **options):
        init(relative, topo, base, other, *arguments, **options)
        built.append(tuple(next(k for k in range(len(keys)) if np.array_equal(key.vertices, seq._raw[k]))
                           for key in (base, other)))

    seq = SequenceInterpolator(keys, tri)
    fresh = SequenceInterpolator(keys, tri)
    monkeypatch.setattr(keys_module.Relative, "__init__", counting)
    ours = [seq.poses(gap, [0.25, 0.5, 0.75]) for gap in range(len(seq))]
    forward = [pair for pair in built if pair[1] == pair[0] + 1]
    assert sorted(forward) == [(k, k + 1) for k in range(len(seq))], str(built)
    for gap in range(len(fresh)):
        fresh._gaps.clear()
        fresh._forwards.clear()
        np.testing.assert_array_equal(fresh.poses(gap, [0.25, 0.5, 0.75]), ours[gap])


def test_the_guide_of_a_gap_inside_five_keys_follows_cubic_motion(strip):
    """The anchor's guide (the keys' per-vertex spline in the world) of a gap with two keys beyond
    each of its neighbours follows vertices moving on cubic paths in time exactly (the five keys'
    tangents, core.splines.FIVE_KEY_LIMIT): a strip bending and sliding, keys at t = 0 … 6. Its
    Catmull–Rom spline is off by 8.7e-5 of the strip's length a quarter into gap 2; the last gap,
    with no key two beyond its start and the linear extrapolation past its end, keeps Catmull–Rom's."""
    flat, tri = strip
    bend = np.sin(np.pi * flat[:, 0] / np.ptp(flat[:, 0]))

    def pose(t):
        x = flat.copy()
        x[:, 2] += 0.05 * bend * t ** 3 / 27.0
        x[:, 0] += 0.1 * t + 0.01 * t ** 3 / 27.0 * bend
        return x

    seq = SequenceInterpolator([pose(t) for t in range(7)], tri)
    scale = np.ptp(seq._to_working(flat)[:, 0])
    for s in (0.25, 0.5, 0.75):
        off = np.abs(seq._gap(2).splines["world"].at(s) - seq._to_working(pose(2.0 + s))).max()
        assert off < 1e-9 * scale
    last = [pose(t) for t in (4.0, 5.0, 6.0)]
    catmull_rom = seq._to_working(_catmull_rom(*last, 2.0 * last[2] - last[1], 0.5))
    np.testing.assert_allclose(seq._gap(5).splines["world"].at(0.5), catmull_rom, atol=1e-9 * scale)


def test_a_sequence_slowing_into_its_last_key_ends_on_its_parabola(strip):
    """The last gap's guide (the keys' per-vertex spline in the world) of a strip whose vertices
    slow down along lines at constant deceleration, each at its own rate, reaches the last key on
    the motion's parabola (core.splines.slowing_end_correction): exact at every factor, where the
    linear end condition (the secant's velocity, Catmull–Rom's) is off by 5.9e-3 of the strip's
    length (the vertices that stop at the last key); the vertices that speed up
    keep the linear end's tangent, the last gap's secant."""
    flat, tri = strip
    bend = np.sin(np.pi * flat[:, 0] / np.ptp(flat[:, 0]))
    direction = np.stack([0.3 + 0.2 * bend, np.zeros_like(bend), 0.1 + 0.3 * bend], axis=1)
    slowing = flat[:, 0] < np.median(flat[:, 0])  # those stop at t = 3 + bend; the others speed up

    def pose(t):
        travel = np.where(slowing, (3.0 + bend) * t - 0.5 * t * t, t + 0.1 * t * t)
        return flat + travel[:, None] * direction

    seq = SequenceInterpolator([pose(float(t)) for t in range(4)], tri, start="keys")
    scale = np.ptp(seq._to_working(flat)[:, 0])
    world = seq._gap(2).splines["world"]
    for s in (0.25, 0.5, 0.75):
        off = np.abs(world.at(s)[slowing] - seq._to_working(pose(2.0 + s))[slowing]).max()
        assert off < 1e-9 * scale
    secant = seq._to_working(pose(3.0)) - seq._to_working(pose(2.0))
    np.testing.assert_allclose(world.t1[~slowing], secant[~slowing], atol=1e-12 * scale)


def test_a_cloth_landing_in_the_last_gap_reaches_the_last_key_at_rest_without_passing_it(strip):
    """A strip falling from rest (z = −t²/2 per key step squared, each vertex from its own height)
    onto a floor it reaches inside the last gap: the last gap's guide never passes the floor at any
    factor, and the vertices that moved three times as far in the gap before as in the last one
    reach the last key at rest (zero end tangent; the linear end condition ends them at their mean
    velocity into the floor)."""
    flat, tri = strip
    height = 2.05 + 0.4 * np.sin(np.pi * flat[:, 0] / np.ptp(flat[:, 0]))

    def pose(t):
        x = flat.copy()
        x[:, 2] = np.maximum(height - 0.5 * t * t, 0.0)  # lands at t = √(2 h), early in gap 2 (t 2 … 3)
        return x

    seq = SequenceInterpolator([pose(float(t)) for t in range(4)], tri)
    working = [seq._to_working(pose(float(t))) for t in range(4)]
    floor = working[3][:, 2].min()
    scale = np.ptp(working[0][:, 0])
    world = seq._gap(2).splines["world"]
    for s in np.linspace(0.0, 1.0, 41):
        assert world.at(s)[:, 2].min() >= floor - 1e-12 * scale
    before, last = working[2] - working[1], working[3] - working[2]
    stopped = np.einsum("ij,ij->i", before, last) >= 3.0 * np.einsum("ij,ij->i", last, last)
    assert stopped.any()
    assert np.abs(world.t1[stopped]).max() < 1e-12 * scale


def test_each_keys_five_key_correction_is_made_once_for_both_its_gaps(monkeypatch, strip):
    """A key's correction to the world spline's tangent (core.splines.five_key_tangent_correction)
    is the same for the gap that ends there and the gap that starts there: the sequence makes it
    once per key (keys 2 … 4 of seven evenly spaced keys: three; made per gap end, six), and
    each gap's tangents are the ones the corrections made from its keys give, bit for bit."""
    import core.sequence_inbetweens as sequence_module
    import core.splines as splines

    flat, tri = strip
    bend = np.sin(np.pi * flat[:, 0] / np.ptp(flat[:, 0]))

    def pose(t):
        x = flat.copy()
        x[:, 2] += 0.05 * bend * np.sin(0.9 * t)
        x[:, 0] += 0.1 * t + 0.02 * bend * np.cos(0.7 * t)
        return x

    made = []
    original = splines.five_key_tangent_correction

    def counted(*keys):
        made.append(1)
        return original(*keys)

    for module in (sequence_module, splines):
        monkeypatch.setattr(module, "five_key_tangent_correction", counted, raising=False)
    seq = SequenceInterpolator([pose(t) for t in range(7)], tri)
    gaps = [seq._gap(gap) for gap in range(len(seq))]
    assert len(made) == 3
    x = [seq._to_working(pose(t)) for t in range(7)]
    for gap in (1, 2, 3, 4):
        world = gaps[gap].splines["world"]
        corrections = [original(*x[k - 2:k + 3]) if 2 <= k <= 4 else None for k in (gap, gap + 1)]
        expected = splines.HermiteGap(x[gap - 1:gap + 3], True, rows=True, corrections=corrections)
        np.testing.assert_array_equal(world.t0, expected.t0)
        np.testing.assert_array_equal(world.t1, expected.t1)


def test_kept_whole_rotation_vectors_are_the_rows_made_from_the_entries(strip):
    """A relative's whole rotation vectors, made once for all triangles where its turns are read
    (``continued_turns``) and kept while its gap is prepared, give :meth:`whole_rotations` the same
    rows to the bit as the entries made for those rows alone (a relative that kept none), on the
    triangles of one piece of two (strips bent, turned and moved apart); read-only, and let go."""
    from core.inbetween_keys import Key, Relative
    from core.inbetween_topology import Topology
    from core.mesh_topology import mesh_topology

    flat, tri = strip
    twin = flat + [0.0, 3.0, 0.0]
    vertices = np.vstack([flat, twin])
    triangles = np.vstack([tri, tri + len(flat)])
    turn = Rotation.from_rotvec([0.4, -1.9, 0.7])
    moved = np.vstack([turn.apply(_bend(flat, 2.6)) + [0.3, 0.0, 0.2], _bend(twin, -1.4) + [0.0, 0.5, -0.1]])
    mesh = mesh_topology(triangles, len(vertices))
    topo = Topology(mesh, vertices)
    base, other = Key(topo, vertices), Key(topo, moved)
    pairs = mesh.edge_triangles[mesh.interior_edges]
    kept, fresh = Relative(topo, base, other), Relative(topo, base, other)
    whole, _ = kept.continued_turns(topo, base, other, pairs)
    assert kept._whole_vectors is not None and not kept._whole_vectors.flags.writeable
    np.testing.assert_array_equal(whole, kept._whole_vectors)
    for components in (np.array([True, False]), np.array([False, True]), np.array([True, True])):
        ours = kept.whole_rotations(topo, base, other, components)
        theirs = Relative(topo, base, other).whole_rotations(topo, base, other, components)
        np.testing.assert_array_equal(ours.rotvec, theirs.rotvec)
        assert np.abs(ours.rotvec - fresh.rotvec).max() > 0.1  # the whole rotations, not the residuals
    kept.let_go_whole_vectors()
    assert kept._whole_vectors is None


def test_a_gap_built_twice_reads_its_kept_whole_rotations_to_the_bit(monkeypatch, strip):
    """A gap whose rotations are taken whole and which is built a second time for the rotations
    against the guide (both forced here in every gap) reads its next key's whole rotation vectors
    kept from its turns' reading: the in-betweens are those of a sequence that makes them from the
    entries at every reading, to the bit, and no gap holds them once prepared."""
    import core.inbetween_keys as keys_module
    from core import deformation_fields as df
    from core.inbetween_solver import Gap
    from core.inbetween_whole_rotations import WholeRotations

    flat, tri = strip
    keys = [_bend(flat, 0.9 * k) + np.array([0.0, 0.1 * k, -0.1 * k * k]) for k in range(5)]
    monkeypatch.setattr(keys_module.Relative, "residuals_add_turn",
                        lambda relative, topo, base, other: np.ones(len(topo.components), dtype=bool))
    monkeypatch.setattr(Gap, "rotations_against_guide", lambda gap: np.ones(len(gap.topo.components), dtype=bool))
    built = []
    segment = SequenceInterpolator._segment

    def counted(seq, gap, *arguments, **options):
        built.append(gap)
        return segment(seq, gap, *arguments, **options)

    monkeypatch.setattr(SequenceInterpolator, "_segment", counted)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        seq = SequenceInterpolator(keys, tri)
        ours = [seq.poses(gap, [0.25, 0.5, 0.75]) for gap in range(len(seq))]
        assert sorted(built) == sorted(2 * list(range(len(seq))))  # each gap built twice
        assert all(r._whole_vectors is None for g in seq._gaps.values() for r in g.relatives)
        monkeypatch.setattr(WholeRotations, "_whole_rotation_vectors", lambda relative, base, other:
                            df.rotation_vectors_of_entries(relative._whole_entries(base, other, keep=True)))
        made = SequenceInterpolator(keys, tri)
        for gap in range(len(made)):
            np.testing.assert_array_equal(made.poses(gap, [0.25, 0.5, 0.75]), ours[gap])


def test_a_gap_whose_preparation_fails_lets_go_of_its_kept_whole_rotations():
    """A sheet half of which turns about a hinge past a half turn between keys (its turns read,
    the whole rotation vectors made for all its triangles) whose gap's build then fails (a
    MemoryError, as a large mesh's may): the relatives the sequence keeps for the gaps around
    (``_forwards``) hold no whole rotation vectors after, and the gap asked again gives the
    in-betweens of a sequence that never failed, to the bit. Before, a failed preparation left
    them on the kept relative (24 bytes a triangle) for as long as the sequence lived."""
    from core.inbetween_whole_rotations import WholeRotations

    sheet, tri = grid(15, 15, size=1.0)
    sheet = sheet - [0.5, 0.5, 0.0]
    right = sheet[:, 0] > 0.0

    def hinged(degrees):
        x = sheet.copy()
        x[right] = Rotation.from_rotvec([0.0, np.radians(degrees), 0.0]).apply(sheet[right])
        return x

    keys = [hinged(a) for a in (0.0, 100.0, 220.0, 330.0)]
    made = []
    making = WholeRotations._whole_rotation_vectors

    def counted(relative, base, other):
        made.append(relative)
        return making(relative, base, other)

    def failing(*arguments, **options):
        raise MemoryError("a gap's build ran out of memory")

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        seq = SequenceInterpolator(keys, tri)
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(WholeRotations, "_whole_rotation_vectors", counted)
            patch.setattr(SequenceInterpolator, "_segment", failing)
            with pytest.raises(MemoryError):
                seq.poses(1, [0.25, 0.5, 0.75], ahead=False)
        assert made  # the turns were read and the vectors made before the build failed
        assert seq._forwards and all(r._whole_vectors is None for r in seq._forwards.values())
        again = seq.poses(1, [0.25, 0.5, 0.75], ahead=False)
        np.testing.assert_array_equal(again, SequenceInterpolator(keys, tri).poses(1, [0.25, 0.5, 0.75], ahead=False))
