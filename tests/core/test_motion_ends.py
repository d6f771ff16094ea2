"""How a sequence leaves its first key and reaches its last (core.motion_ends; issue 3) on analytic
motions; no bpy."""

from __future__ import annotations

import pytest

from core.errors import MeshError
from core.sequence_inbetweens import SequenceInterpolator
from meshes import grid


def test_start_of_motion_tells_rest_from_motion():
    """The frame in the middle of the first gap says how the motion leaves the first key: a fall
    from rest (zero velocity; the keys' parabola gives it too), one at constant velocity (the
    keys' own), or a walk that is at rest at the first frame and at its pace a frame later (the
    keys', which a spline from rest would spread over the whole gap), whatever the step, and with
    keys unevenly spaced; a fall from rest that lands in the second gap is told from the walk,
    whose keys it has."""
    from core.motion_ends import start_of_motion

    flat, _ = grid(6, 6)
    for step in (4, 8, 16):
        T = 2 * step
        fall = [flat + [0.0, 0.0, -0.5 * t * t] for t in range(T + 1)]
        drift = [flat + [0.3 * t, 0.0, 0.1 * t] for t in range(T + 1)]
        walk = [flat + [0.3 * max(t - 0.5, 0.0), 0.0, 0.0] for t in range(T + 1)]  # at pace from frame 1 on
        # falls from rest to the second key, then lies there: its keys advance as the walk's
        land = [flat + [0.0, 0.0, -0.15 * min(t, step) ** 2 / step] for t in range(T + 1)]
        for frames, expected in ((fall, "rest"), (drift, "keys"), (walk, "keys"), (land, "rest")):
            assert start_of_motion(frames[::step][:3], frames[step // 2], 0.5) == expected
    fall = [flat + [0.0, 0.0, -0.5 * t * t] for t in range(15)]  # keys 0, 8, 14: the second gap 6 long
    assert start_of_motion([fall[0], fall[8], fall[14]], fall[4], 0.5, (8, 6)) == "rest"
    with pytest.raises(MeshError):
        SequenceInterpolator(fall[::4], grid(6, 6)[1], start="still")


def test_end_of_motion_tells_an_ease_into_the_last_key_from_motion_through_it():
    """The frame in the middle of the last gap says whether the motion comes to rest at the last
    key (a constant deceleration to a stop there) or goes on through it (at constant velocity, or
    falling), whatever the step, and with keys unevenly spaced."""
    from core.motion_ends import end_of_motion

    flat, _ = grid(6, 6)
    for step in (4, 8):
        T = 3 * step
        ease = [flat + [0.3 * (t - t * t / (2 * T)), 0.0, 0.0] for t in range(T + 1)]
        drift = [flat + [0.3 * t, 0.0, 0.1 * t] for t in range(T + 1)]
        fall = [flat + [0.0, 0.0, -0.5 * t * t] for t in range(T + 1)]
        for frames, expected in ((ease, "rest"), (drift, "keys"), (fall, "keys")):
            keys = frames[::step]
            assert end_of_motion(keys[-3:], frames[T - step // 2], 0.5) == expected
    # keys unevenly spaced (a range that is not whole steps): the last gap 6 frames, the one before 8
    T = 22
    ease = [flat + [0.3 * (t - t * t / (2 * T)), 0.0, 0.0] for t in range(T + 1)]
    assert end_of_motion([ease[8], ease[16], ease[22]], ease[19], 0.5, (8, 6)) == "rest"


@pytest.mark.parametrize("rigid", [False, True])
def test_end_of_motion_keeps_the_keys_where_they_slow_to_a_stop_just_past_the_last_key(rigid):
    """A sheet whose points decelerate at constant rates along one direction and stop a quarter step
    past the last key reaches it slowly: the linear end (the mean speed over the last gap) is farther
    from the frame in the middle than the rest end, but the sequence's ``"keys"`` end, slowed where
    the keys slow, is nearer: the choice is "keys", and the sequence's in-betweens of the last gap
    with it are nearer the frames than with "rest" (before: "rest" was chosen), whatever the step;
    a stop at the last key itself stays "rest" (the tie: the slowed end is the rest end there). Each
    point at its own rate (a deforming sheet, its positions' spline slowed:
    core.splines.slowing_end_correction), or all at one (a rigid sheet, moved by its screw's spline,
    slowed by core.splines.slowing_screw_correction: its in-betweens are then the motion, to 1e-9 of
    its size; before, its screw kept the linear end, 2.1e-3 of it off at keys 8 apart where "rest"
    is 1.0e-3 off)."""
    import numpy as np
    from core.motion_ends import end_of_motion

    flat, tri = grid(6, 6)
    rate = np.ones(len(flat)) if rigid else 1.0 + 0.3 * np.sin(3.0 * flat[:, 0])
    direction = np.array([0.3, 0.1, -0.2])
    for step in (4, 8, 16):
        T = 3 * step
        for stop, expected in ((T + 0.25 * step, "keys"), (float(T), "rest")):
            frames = [flat + ((t * stop - 0.5 * t * t) / (stop * stop) * rate)[:, None] * direction for t in range(T + 1)]
            keys = frames[::step]
            assert end_of_motion(keys[-3:], frames[T - step // 2], 0.5) == expected
            if expected == "keys":
                off = {}
                for end in ("keys", "rest"):
                    poses = SequenceInterpolator(keys, tri, start="keys", end=end).poses(2, np.arange(1, step) / step)
                    off[end] = max(np.abs(x - frames[2 * step + j]).max() for j, x in enumerate(poses, start=1))
                assert off["keys"] < off["rest"], (step, off)
                if rigid:
                    assert off["keys"] < 1e-9 * np.ptp(flat[:, 0]), (step, off)
