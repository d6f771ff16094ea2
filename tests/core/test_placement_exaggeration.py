"""Exaggerated and small bends (issue 17 item 3): an exaggeration flips no triangle and is not the
linear extrapolation; a small bend is interpolated as a bend. No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import ShapeDifferenceWarning
from core.two_pose_inbetweens import Interpolator

from inbetween_helpers import _normals
from placement_helpers import _arm


@pytest.mark.parametrize("degrees", [10.0, 20.0, 30.0, 45.0])
def test_a_small_bend_is_interpolated_as_a_bend(degrees):
    """An arm bent at the elbow by a small angle: half-way it is the arm bent by half the angle, to
    5e-4 of the diagonal, its edges within 0.5 %. The linear blend's chord is 7.5e-4 / 3.0e-3 /
    6.7e-3 / 1.5e-2 off; anchored to it where it barely shortens edges, the forearm was 6.2e-4 /
    2.4e-3 / 3.8e-3 / 2.2e-3 off with edges up to 1.8 % off."""
    a, tri = _arm(0.0)
    b, _ = _arm(np.radians(degrees))
    x = Interpolator(a, b, tri).pose(0.5)
    truth, _ = _arm(np.radians(degrees / 2))
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < 5e-4 * diagonal
    lengths = np.linalg.norm(x[tri[:, 1]] - x[tri[:, 0]], axis=1)
    rest = np.linalg.norm(a[tri[:, 1]] - a[tri[:, 0]], axis=1)
    assert np.abs(lengths / rest - 1.0).max() < 5e-3


def test_exaggerated_bend_does_not_flip():
    """×2 of a 100° bend: no triangle faces against the 200° bend's, and the forearm keeps its
    length (the exaggeration is a bend, not a stretch)."""
    a, tri = _arm(0.0)
    b, _ = _arm(np.radians(100.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        x = Interpolator(a, b, tri).pose(2.0)
    truth, _ = _arm(np.radians(200.0))
    assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    lengths = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
    rest = np.linalg.norm(a[edges[:, 0]] - a[edges[:, 1]], axis=1)
    assert np.abs(lengths / rest - 1).max() < 0.02


def test_an_exaggerated_bend_is_not_the_linear_extrapolation():
    """×2 of a tube bent 100° at its elbow about an oblique axis: where the fit keeps a few
    defects, the pose is still a bend (the forearm keeps its length) with a warning that says so;
    before, the fit held near the linear extrapolation 2b − a was returned (forearm 1.94 × its
    length, 0.88 of the diagonal off the 200° bend) as "the interpolated metric fitted near the
    linear blend"."""
    sides, rings = 12, 41
    angles = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    a = np.vstack([np.c_[np.full(sides, x), 0.15 * np.cos(angles), 0.15 * np.sin(angles)]
                   for x in np.linspace(0.0, 2.0, rings)])
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(sides), indexing="ij")
    i, j = i.ravel(), j.ravel()
    tri = np.r_[np.c_[i * sides + j, i * sides + (j + 1) % sides, (i + 1) * sides + (j + 1) % sides],
                np.c_[i * sides + j, (i + 1) * sides + (j + 1) % sides, (i + 1) * sides + j]]
    t = np.clip((a[:, 0] - 0.6) / 0.8, 0.0, 1.0)
    t = t * t * (3.0 - 2.0 * t)
    axis = np.array([0.3, 0.5, 1.0]) / np.linalg.norm([0.3, 0.5, 1.0])
    joint = np.array([1.0, 0.0, 0.0])
    b = np.einsum("nij,nj->ni", Rotation.from_rotvec(np.outer(t * np.radians(100.0), axis)).as_matrix(), a - joint) + joint
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        x = Interpolator(a, b, tri).pose(2.0)
    tip = a[:, 0] == a[:, 0].max()
    assert abs(np.linalg.norm(x[tip].mean(axis=0) - joint) - 1.0) < 0.05
    assert all("near the linear blend" not in str(w.message) for w in caught)
