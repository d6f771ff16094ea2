"""The last local untangling of a sequence's in-between that keeps flipped triangles after its
repairs (core.inbetween_untangling; issue 17: no flipped triangles); no bpy."""

from __future__ import annotations

import warnings

import numpy as np

from core.errors import ShapeDifferenceWarning
from core.inbetween_untangling import UNTANGLE_MARGIN, untangle
from core.sequence_inbetweens import SequenceInterpolator
from inbetween_helpers import _bend, _flipped, _normals
from meshes import grid


def _pushed(flat, tri, across=0.6):
    """The flat grid ``flat`` with its most central vertex pushed ``across`` of an edge length past
    its neighbour in +x, in the plane: the triangles of its fan on that side turn over."""
    centre = int(np.argmin(np.linalg.norm(flat - flat.mean(axis=0), axis=1)))
    fan = np.flatnonzero((tri == centre).any(axis=1))
    ring = np.setdiff1d(tri[fan], [centre])
    right = ring[np.argmax(flat[ring, 0])]
    x = flat.copy()
    x[centre] = flat[right] + across * (flat[right] - flat[centre])
    return x, centre, fan


def test_untangle_turns_a_folded_fan_back_and_moves_only_the_free_vertex():
    """A vertex of a flat grid pushed past a neighbour turns part of its fan over (normals along
    −z); untangled with every triangle of the fan to face +z by a margin, each of them does (by half
    the margin at least: the function's guarantee), the vertex sits inside its ring again (so its
    fan covers the ring's polygon once: the fan's areas add up to the polygon's, independently of
    the solver) and every other vertex is where it was, bit for bit."""
    flat, tri = grid(7, 7, size=1.0)
    x, centre, fan = _pushed(flat, tri)
    up = np.tile([0.0, 0.0, 1.0], (fan.size, 1))
    assert (_normals(x, tri[fan])[:, 2] < 0).any()
    rest = 0.5 * np.linalg.norm(_normals(flat, tri[fan]), axis=1)
    margins = UNTANGLE_MARGIN * 2.0 * rest
    y, faces = untangle(x, tri[fan], np.array([centre]), up, margins)
    assert faces
    facing = _normals(y, tri[fan])[:, 2]
    assert (facing >= 0.5 * margins).all()
    others = np.arange(len(flat)) != centre
    assert np.array_equal(y[others], x[others])
    # the fan's signed areas add up to the ring polygon's area (the flat fan's) only where it covers it once
    np.testing.assert_allclose(0.5 * facing.sum(), rest.sum(), rtol=1e-12)
    assert np.allclose(y[:, 2], 0.0)


def test_untangle_leaves_a_pose_that_faces_its_sides_as_it_is():
    """A region every triangle of which already faces its side by half its margin takes no step:
    the pose comes back bit for bit."""
    flat, tri = grid(5, 5, size=1.0)
    rows = np.arange(len(tri))
    inner = np.flatnonzero((np.abs(flat[:, :2] - 0.5) < 0.4).all(axis=1))
    up = np.tile([0.0, 0.0, 1.0], (len(tri), 1))
    y, faces = untangle(flat, tri[rows], inner, up, np.full(len(tri), 1e-3))
    assert faces and np.array_equal(y, flat)


def test_a_sequence_in_between_whose_repairs_keep_a_fold_is_untangled(monkeypatch, strip):
    """A strip bending through three keys whose middle in-between comes out of its fit and repairs
    with part of a vertex's fan turned over (a vertex pushed past its neighbour, as a fold no field
    of the repairs unfolds): the in-between returned has no flipped triangle and no warning, and
    only the vertices within three rings of the pushed one moved, by less than a mean edge (the repair
    limits' scale). Without the untangling the fold was kept and warned."""
    import core.inbetween_solver as solver

    flat, tri = strip
    keys = [_bend(flat, angle) for angle in (0.0, 1.0, 2.0)]
    middle = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0))  # keyed about the origin: sequences work
    keys = [key - middle for key in keys]  # about the first key's middle, and the mock sees positions
    real_pose, folded = solver.Gap.pose, {}

    def pose(self, s, *args, **kwargs):  # the fit with a fan folded over, kept as no repair removed it
        x, problem = real_pose(self, s, *args, **kwargs)
        if not 0.0 < s < 1.0:
            return x, problem
        centre = int(np.argmin(np.linalg.norm(x - x.mean(axis=0), axis=1)))
        ring = np.setdiff1d(tri[(tri == centre).any(axis=1)], [centre])
        right = ring[np.argmax(x[ring, 0])]
        x = x.copy()
        x[centre] = x[right] + 0.6 * (x[right] - x[centre])
        folded[s] = (x.copy(), centre)
        return x, "1 triangle(s) flipped or collapsed"

    monkeypatch.setattr(solver.Gap, "pose", pose)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        y = SequenceInterpolator(keys, tri).pose(0, 0.5)
    x, centre = folded[0.5]
    assert _flipped(x, keys[0], keys[1], tri) > 0
    assert _flipped(y, keys[0], keys[1], tri) == 0
    # the vertices within three rings of the pushed vertex (the fan, and the untangling's two rings)
    near = np.zeros(len(flat), dtype=bool)
    near[centre] = True
    for _ in range(3):
        near[tri[near[tri].any(axis=1)]] = True
    assert np.array_equal(y[~near], x[~near])
    mean_edge = np.mean(np.linalg.norm(keys[0][tri[:, 1]] - keys[0][tri[:, 0]], axis=1))
    assert np.linalg.norm(y - x, axis=1).max() < mean_edge
