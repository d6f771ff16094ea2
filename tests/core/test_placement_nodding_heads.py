"""A head nodding on a still neck, skinned with a weight ramp between them (issue 17 item 3: no
flipped triangles in two-pose in-betweens, never a silent wrong result). The two poses do not
tell the ramp's edge lengths half-way (a skin's stretch there grows with the square of the turn,
the interpolated metric linearly), so the fit may crush and turn over a few of its triangles:
each in-between either has every triangle facing within a right angle of the rig's own pose or
says so. No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from core.errors import ShapeDifferenceWarning
from core.two_pose_inbetweens import Interpolator

from inbetween_helpers import RIG_WORDS, _normals
from placement_helpers import _nodded, _scanned_head

#: What an in-between with triangles turned over against their interpolated rotation says.
AGAINST_THE_FIELD = "face against their interpolated rotation"


def _poses_and_warnings(points, seed, degrees):
    """Per factor 0.25, 0.5, 0.75: the in-between, the rig's pose there and the warnings' texts."""
    head, tri = _scanned_head(points, seed)
    interpolator = Interpolator(head, _nodded(head, degrees, 1.0), tri)
    out = []
    for s in (0.25, 0.5, 0.75):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            x = interpolator.pose(s)
        out.append((x, _nodded(head, degrees, s), [str(w.message) for w in caught]))
    return head, tri, out


@pytest.mark.parametrize("points, seed, degrees", [(800, 0, 60.0), (800, 0, 100.0), (400, 1, 100.0), (800, 1, 100.0),
                                                   (None, 0, 140.0)])
def test_a_head_nodding_on_a_still_neck_faces_the_rig_or_says_so(points, seed, degrees):
    """Irregular heads (hulls of 400 / 800 random points) nodding 60° / 100°, and the regular one
    140°: at 0.25, 0.5 or 0.75, 1–14 triangles (8 of the regular head's) faced 90–147° from the
    rig's, silently, with the still neck exact and the pose 0.13–0.34 × the blend's RMS error.
    Every in-between with a triangle facing more than a right angle from the rig's says that
    triangles face against their interpolated rotation, in terms true of any mesh (no rig's words:
    the same warnings reach cloth); the neck stays where it is."""
    head, tri, poses = _poses_and_warnings(points, seed, degrees)
    neck = head[:, 1] < 0.75
    against_the_rig = 0
    for x, rig, said in poses:
        np.testing.assert_array_equal(x[neck], head[neck])
        facing = np.einsum("ij,ij->i", _normals(x, tri), _normals(rig, tri)) <= 0
        against_the_rig += int(facing.sum())
        if facing.any():
            assert any(AGAINST_THE_FIELD in message for message in said), said
        assert not any(RIG_WORDS.search(message) for message in said if AGAINST_THE_FIELD in message), said
    assert against_the_rig  # the case has such triangles to be said


@pytest.mark.parametrize("degrees", [60.0, 100.0])
def test_a_regular_head_nodding_on_a_still_neck_faces_the_rig_silently(degrees):
    """The regular head nodding 60° / 100°: every triangle faces within a right angle of the rig's
    at 0.25, 0.5 and 0.75, the neck is still, and nothing is said."""
    head, tri, poses = _poses_and_warnings(None, 0, degrees)
    neck = head[:, 1] < 0.75
    for x, rig, said in poses:
        np.testing.assert_array_equal(x[neck], head[neck])
        assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(rig, tri)) > 0).all()
        assert not said


@pytest.mark.parametrize("points, degrees, factor", [(800, 100.0, 0.25), (400, 140.0, 0.75), (1600, 100.0, 0.5)])
def test_a_head_nodding_on_a_still_neck_keeps_its_ramp_with_the_log_stretches_metric(points, degrees, factor):
    """Irregular heads (800, 400, 1,600 points) nodding 100° / 140°: the metric linear in squared
    lengths swells the weight ramp's triangles over the rig's area (a skin's stretch grows with
    the square of the turn) and the fit crushed 1–5 of them over, 0.22–0.32 × the blend's RMS
    error from the rig. Fitted again to the log-stretches' metric (within 3 % of the rig's area on
    the ramp, median; LOG_METRIC_FIT), every triangle faces within a right angle of the rig's, the
    neck stays exact and the pose is within 0.2 × the blend's error (0.15–0.16 measured; what is
    left is the log metric's own misfit)."""
    head, tri = _scanned_head(points, 0)
    end, rig = _nodded(head, degrees, 1.0), _nodded(head, degrees, factor)
    x = Interpolator(head, end, tri).pose(factor)
    neck = head[:, 1] < 0.75
    np.testing.assert_array_equal(x[neck], head[neck])
    assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(rig, tri)) > 0).all()
    blend = (1.0 - factor) * head + factor * end

    def rms(d):
        return np.sqrt(np.mean(np.sum(d * d, axis=1)))

    assert rms(x - rig) <= 0.2 * rms(blend - rig)
