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


def _pushed_past(x, tri, centre, across=0.6):
    """Positions ``x`` with vertex ``centre`` pushed ``across`` of an edge length past its
    neighbour farthest along +x: the triangles of its fan on that side turn over."""
    ring = np.setdiff1d(tri[(tri == centre).any(axis=1)], [centre])
    right = ring[np.argmax(x[ring, 0])]
    out = x.copy()
    out[centre] = x[right] + across * (x[right] - x[centre])
    return out


def _pushed(flat, tri, across=0.6):
    """The flat grid ``flat`` with its most central vertex pushed past its neighbour in +x
    (:func:`_pushed_past`), in the plane, that vertex and its fan."""
    centre = int(np.argmin(np.linalg.norm(flat - flat.mean(axis=0), axis=1)))
    return _pushed_past(flat, tri, centre, across), centre, np.flatnonzero((tri == centre).any(axis=1))


def _fits_folded(monkeypatch, tri, where) -> dict:
    """Every in-between's fit of a sequence (``core.inbetween_solver.Gap.pose``, 0 < s < 1) with
    the vertex ``where(x)`` pushed past its neighbour (:func:`_pushed_past`) and said to keep a
    flipped triangle, as a fold no repair removed: {factor: (that pose, the vertex)}, filled as
    they are made."""
    import core.inbetween_solver as solver

    real_pose, folded = solver.Gap.pose, {}

    def pose(self, s, *args, **kwargs):
        x, problem = real_pose(self, s, *args, **kwargs)
        if not 0.0 < s < 1.0:
            return x, problem
        centre = where(x)
        folded[s] = (_pushed_past(x, tri, centre), centre)
        return folded[s][0].copy(), "1 triangle(s) flipped or collapsed"

    monkeypatch.setattr(solver.Gap, "pose", pose)
    return folded


def _within_rings(tri, centre, rings) -> np.ndarray:
    """Vertices (bool (n,)) within ``rings`` vertex rings of vertex ``centre``."""
    near = np.zeros(tri.max() + 1, dtype=bool)
    near[centre] = True
    for _ in range(rings):
        near[tri[near[tri].any(axis=1)]] = True
    return near


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
    flat, tri = strip
    keys = [_bend(flat, angle) for angle in (0.0, 1.0, 2.0)]
    middle = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0))  # keyed about the origin: sequences work
    keys = [key - middle for key in keys]  # about the first key's middle, and the mock sees positions
    folded = _fits_folded(monkeypatch, tri, lambda x: int(np.argmin(np.linalg.norm(x - x.mean(axis=0), axis=1))))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        y = SequenceInterpolator(keys, tri).pose(0, 0.5)
    x, centre = folded[0.5]
    assert _flipped(x, keys[0], keys[1], tri) > 0
    assert _flipped(y, keys[0], keys[1], tri) == 0
    # the vertices within three rings of the pushed vertex (the fan, and the untangling's two rings)
    near = _within_rings(tri, centre, 3)
    assert np.array_equal(y[~near], x[~near])
    mean_edge = np.mean(np.linalg.norm(keys[0][tri[:, 1]] - keys[0][tri[:, 0]], axis=1))
    assert np.linalg.norm(y - x, axis=1).max() < mean_edge


def test_a_tip_turning_away_from_both_keys_is_left_as_it_turns_while_a_fold_is_untangled(monkeypatch):
    """A finger (a closed tube) curling by 120° at each of two joints per key: half-way through a
    gap its tip faces away from both keys, as the interpolated rotations turn it, which is no
    defect (core.inbetween_turned_away). The in-between comes out of its fit and repairs with a
    fan folded over between the joints (a vertex pushed past its neighbour, a fold kept and said):
    the fold is untangled, the turned tip is not (it still faces away from both keys as the finger
    curled by the interpolated angles does, its vertices exactly where the fit put them: only
    vertices within three rings of the pushed one move), and nothing is said. Counted as flipped
    against both keys, the tip was pushed to face them too: 51 vertices moved, none of its 48
    triangles left turned away, the pose 2.2 × farther from the curl than before the untangling."""
    from placement_helpers import _curled_tube

    angles, joints = np.radians([120.0, 120.0]), (0.25, 0.6)
    keys = [_curled_tube(k * angles, joints, 0.35, rings=31, sides=8)[0] for k in range(3)]
    tri = _curled_tube(0.0 * angles, joints, 0.35, rings=31, sides=8)[1]
    middle = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0))  # sequences work about the first key's middle
    keys = [key - middle for key in keys]
    curl = _curled_tube(0.5 * angles, joints, 0.35, rings=31, sides=8)[0] - middle
    # a vertex between the joints, on the tube's top
    centre = int(np.argmin(np.abs(keys[0][:, 0] + middle[0] - 0.45) + np.abs(keys[0][:, 2] + middle[2] - 0.07)))
    folded = _fits_folded(monkeypatch, tri, lambda x: centre)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        y = SequenceInterpolator(keys, tri, start="keys").pose(0, 0.5)
    x, _ = folded[0.5]
    turned = _flipped(curl, keys[0], keys[1], tri)
    assert turned > 0 and _flipped(x, keys[0], keys[1], tri) > turned  # the tip turned away, and the fold
    assert _flipped(y, keys[0], keys[1], tri) == turned
    assert (np.einsum("ij,ij->i", _normals(y, tri), _normals(curl, tri)) > 0).all()
    near = _within_rings(tri, centre, 3)
    assert np.array_equal(y[~near], x[~near])
