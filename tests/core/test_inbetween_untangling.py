"""The last local untangling of a sequence's in-between that keeps flipped triangles after its
repairs (core.inbetween_untangling; issue 17: no flipped triangles); no bpy."""

from __future__ import annotations

import warnings

import numpy as np

import core.inbetween_untangling as untangling
from core.errors import ShapeDifferenceWarning
from core.inbetween_defects import COLLAPSE_RATIO
from core.inbetween_untangling import (UNTANGLE_FREE_VERTICES, UNTANGLE_ITERATIONS, UNTANGLE_MARGIN, UNTANGLE_WEIGHTS,
                                       UNTANGLE_WORK, untangle, untangle_work)
from core.sequence_inbetweens import SequenceInterpolator
from inbetween_helpers import _bend, _flipped, _normals
from meshes import grid


def _defects_said(said) -> list:
    """The warnings of ``said`` (warning messages, or recorded warnings) but the gap's off-rest ``fit``
    warning (:data:`_OFF_REST`, keeping no defect; any other ``fit`` warning is kept): a gap whose
    in-between is folded or crushed on purpose here has its edges off the keys' lengths, which that
    warning says beside the defects' warnings these tests are about."""
    said = [getattr(w, "message", w) for w in said]
    return [w for w in said if not (w.kind == "fit" and w.defects == 0 and _OFF_REST in str(w))]


#: What the gap's off-rest warning (core.sequence_edge_misfit.off_rest_warning) says, and no other
#: ``fit`` warning: the one a mocked fold or crush may add, its in-between off the keys' lengths.
_OFF_REST = "what the keys allow (twice their own deviation from it"


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


def _fits_made(monkeypatch, make) -> dict:
    """Every in-between's fit of a sequence (``core.inbetween_solver.Gap.pose``, 0 < s < 1) made
    into ``make(x)`` (a pose (n, 3) and what the test needs of it) and said to keep a flipped
    triangle, as a fold no repair removed: {factor: what ``make`` returned}, filled as they are made."""
    import core.inbetween_solver as solver

    real_pose, made = solver.Gap.pose, {}

    def pose(self, s, *args, **kwargs):
        x, problem = real_pose(self, s, *args, **kwargs)
        if not 0.0 < s < 1.0:
            return x, problem
        made[s] = make(x)
        return made[s][0].copy(), "1 triangle(s) flipped or collapsed"

    monkeypatch.setattr(solver.Gap, "pose", pose)
    return made


def _fits_folded(monkeypatch, tri, where) -> dict:
    """:func:`_fits_made` with the vertex ``where(x)`` pushed past its neighbour
    (:func:`_pushed_past`): {factor: (that pose, the vertex)}."""
    return _fits_made(monkeypatch, lambda x: (_pushed_past(x, tri, where(x)), where(x)))


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
    of the repairs unfolds): the in-between returned has no flipped triangle and no warning of one (the
    pushed vertex's ring stays off its lengths, which the gap's ``fit`` warning may say, keeping no
    defect), and only the vertices within three rings of the pushed one moved, by less than a mean edge
    (the repair limits' scale). Without the untangling the fold was kept and warned."""
    flat, tri = strip
    keys = [_bend(flat, angle) for angle in (0.0, 1.0, 2.0)]
    middle = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0))  # keyed about the origin: sequences work
    keys = [key - middle for key in keys]  # about the first key's middle, and the mock sees positions
    folded = _fits_folded(monkeypatch, tri, lambda x: int(np.argmin(np.linalg.norm(x - x.mean(axis=0), axis=1))))
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        y = SequenceInterpolator(keys, tri).pose(0, 0.5)
    assert not _defects_said(w for w in said if isinstance(w.message, ShapeDifferenceWarning))
    x, centre = folded[0.5]
    assert _flipped(x, keys[0], keys[1], tri) > 0
    assert _flipped(y, keys[0], keys[1], tri) == 0
    # the vertices within three rings of the pushed vertex (the fan, and the untangling's two rings)
    near = _within_rings(tri, centre, 3)
    assert np.array_equal(y[~near], x[~near])
    mean_edge = np.mean(np.linalg.norm(keys[0][tri[:, 1]] - keys[0][tri[:, 0]], axis=1))
    assert np.linalg.norm(y - x, axis=1).max() < mean_edge


def _predictions_folded(monkeypatch):
    """The first gap of :func:`_sheet_keys` asked at seven factors (two solved, the others
    predicted), every in-between folded near a corner (a vertex pushed past its neighbour: two
    triangles turned over) and kept so by its repair, as a fold no field removes
    (:func:`_predictions_kept`): what that returns."""
    flat, tri, _ = _sheet_keys()
    corner = _corner(flat)
    return _predictions_kept(monkeypatch, lambda s, x: _pushed_past(x, tri, corner))


def _corner(flat) -> int:
    """The vertex of :func:`_sheet_keys`' ``flat`` sheet the solved in-betweens of
    :func:`_predictions_kept` are folded at."""
    return int(np.argmin(np.linalg.norm(flat - [0.3, 0.3, 0.0], axis=1)))


def _predictions_kept(monkeypatch, fold, again=None):
    """The first gap of :func:`_sheet_keys` asked at seven factors (two solved, the others
    predicted): the solved ones folded by their fits near a corner (:func:`_corner`, a vertex
    pushed past its neighbour; :func:`_fits_made`: a gap whose solved in-betweens keep defects has
    its predictions kept as their repairs leave them, not solved), each prediction at factor ``s``
    made into ``fold(s, x)`` (``x``: the prediction (n, 3)) and kept so by its repair, as folds no
    field removes; the passes of the repairs again ``again`` (a stand-in for
    ``core.inbetween_solver.Gap.repaired_again``) if given, else the real ones. (keys, triangles,
    the poses returned by factor, the predictions made by factor, the poses the untangling of
    :func:`~core.inbetween_prediction_repairs.untangled_first` was given by factor, the corner, the
    factors of the passes of the repairs again made, the gap)."""
    import core.inbetween_prediction_repairs as prediction_repairs
    import core.inbetween_solver as solver
    from core.inbetween_repair import Outcome

    flat, tri, keys = _sheet_keys()
    corner = _corner(flat)
    _fits_made(monkeypatch, lambda x: (_pushed_past(x, tri, corner),))
    real_predicted, made, passes = prediction_repairs.predicted_positions, {}, []

    def predicted(gap, s, correction, motion):
        made[s] = fold(s, real_predicted(gap, s, correction, motion))
        return made[s].copy()

    def kept(self, x, s, rings=None, defects=None):  # the repair removes nothing
        self.outcomes[s] = Outcome(int(np.count_nonzero(defects)), False)
        return x, f"{np.count_nonzero(defects)} triangle(s) flipped or collapsed"

    real_again, real_untangled, given = again or solver.Gap.repaired_again, prediction_repairs.untangled, {}

    def untangled(gap, x, s, *args):  # what the untangling is given
        given[s] = x.copy()
        return real_untangled(gap, x, s, *args)

    monkeypatch.setattr(prediction_repairs, "untangled", untangled)
    monkeypatch.setattr(prediction_repairs, "predicted_positions", predicted)
    monkeypatch.setattr(solver.Gap, "repaired", kept)
    monkeypatch.setattr(solver.Gap, "repaired_again", lambda self, x, s, *args, **kwargs: passes.append(s)
                        or real_again(self, x, s, *args, **kwargs))
    sequence = SequenceInterpolator(keys, tri)
    factors = np.arange(1, 8) / 8
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)  # the solved in-betweens' folds may be said
        poses = dict(zip(factors, sequence.poses(0, factors)))
    return keys, tri, poses, made, given, corner, passes, sequence._gap(0)


def test_predictions_whose_repairs_keep_few_defects_are_untangled_without_a_pass(monkeypatch):
    """Predicted in-betweens whose repairs kept a few defects (two triangles of a vertex's fan
    turned over: at most UNTANGLED_FIRST_DEFECTS; :func:`_predictions_folded`) are untangled before
    the repairs again, which then make no pass on them: each comes back with no triangle facing against both keys (counted here from its
    normals), its outcome clean, and only the vertices within three rings of the pushed one moved
    (the fan and the untangling's two rings), by less than a mean edge. Before, each went through
    passes of the repairs again first."""
    from core.inbetween_prediction_repairs import UNTANGLED_FIRST_DEFECTS
    from core.inbetween_repair import Outcome

    keys, tri, poses, made, given, corner, passes, gap = _predictions_folded(monkeypatch)
    assert made and sorted(given) == sorted(made) and not set(passes) & set(made)
    near = _within_rings(tri, corner, 3)
    mean_edge = np.mean(np.linalg.norm(keys[0][tri[:, 1]] - keys[0][tri[:, 0]], axis=1))
    for s, x in given.items():
        assert 0 < _flipped(x, keys[0], keys[1], tri) <= UNTANGLED_FIRST_DEFECTS
        y = poses[s]
        assert _flipped(y, keys[0], keys[1], tri) == 0 and gap.outcomes[s] == Outcome(0, False)
        assert (y[near] != x[near]).any() and np.array_equal(y[~near], x[~near])
        assert np.linalg.norm(y - x, axis=1).max() < mean_edge


def test_a_prediction_a_pass_leaves_with_few_defects_is_untangled_then_without_more_passes(monkeypatch):
    """A predicted in-between whose repair keeps more than UNTANGLED_FIRST_DEFECTS (25 vertices of a
    40 × 40 sheet pushed past their neighbours, as folds no field of its repair removes) is repaired
    again; a pass that leaves it at most that many (here: all folds but three, near a side) has it
    untangled then (:func:`core.inbetween_prediction_repairs.untangled_first`), and where that cleans
    it no further pass runs: each prediction takes exactly one pass, the untangling is given that
    pass's pose, and the prediction comes back with no triangle facing against both keys (counted
    here from its normals), its outcome clean, only the vertices within three rings of the folds
    left moved (and of the solved in-betweens' own fold, which the predictions made from them
    inherit), by less than a mean edge. Before, a second pass ran on each (leaving the same folds)
    and the last untangling of the gap removed them."""
    from core.inbetween_prediction_repairs import UNTANGLED_FIRST_DEFECTS
    from core.inbetween_repair import Outcome

    flat, tri, _ = _sheet_keys()
    lattice = [int(np.argmin(np.linalg.norm(flat - [a, b, 0.0], axis=1)))
               for a in (0.15, 0.3, 0.45, 0.6, 0.75) for b in (0.15, 0.3, 0.45, 0.6, 0.75)]
    left, others = lattice[:3], lattice[3:]  # the folds a pass leaves, and those it removes
    clean = {}

    def fold(s, x):  # every lattice vertex pushed past its neighbour
        clean[s] = x
        for v in lattice:
            x = _pushed_past(x, tri, v)
        return x

    def again(self, x, s, *args, **kwargs):  # a pass removes every fold but those ``left``
        y = x.copy()
        if s in clean:
            y[others] = clean[s][others]
        count = int(self.repair.counted(y, s, self.repair.factor_area_scale(s)).sum())
        self.outcomes[s] = Outcome(count, False)
        return y, f"{count} triangle(s) flipped or collapsed" if count else None

    keys, tri, poses, made, given, corner, passes, gap = _predictions_kept(monkeypatch, fold, again)
    near = np.logical_or.reduce([_within_rings(tri, v, 3) for v in left + [corner]])
    mean_edge = np.mean(np.linalg.norm(keys[0][tri[:, 1]] - keys[0][tri[:, 0]], axis=1))
    assert made and sorted(given) == sorted(made)
    for s, x in given.items():
        assert passes.count(s) == 1
        assert _flipped(made[s], keys[0], keys[1], tri) > UNTANGLED_FIRST_DEFECTS
        assert 0 < _flipped(x, keys[0], keys[1], tri) <= UNTANGLED_FIRST_DEFECTS
        y = poses[s]
        assert _flipped(y, keys[0], keys[1], tri) == 0 and gap.outcomes[s] == Outcome(0, False)
        assert (y[near] != x[near]).any() and np.array_equal(y[~near], x[~near])
        assert np.linalg.norm(y - x, axis=1).max() < mean_edge


def test_an_in_between_with_more_defects_or_one_the_untangling_leaves_is_kept_for_the_repairs_again(monkeypatch):
    """:func:`core.inbetween_prediction_repairs.untangled_first` hands back the pose it is given, the
    very array with its problem and the gap's outcome untouched, where the in-between keeps more than
    UNTANGLED_FIRST_DEFECTS (the untangling not tried) and where the untangling leaves a defect (its
    pose, here a stand-in moving every vertex, not kept): the repairs again start from it as before."""
    import core.inbetween_prediction_repairs as prediction_repairs
    from core.inbetween_repair import Outcome

    flat, tri, keys = _sheet_keys(side=20)
    gap = SequenceInterpolator(keys, tri)._gap(0)
    corner = int(np.argmin(np.linalg.norm(flat - [0.3, 0.3, 0.0], axis=1)))
    x = _pushed_past(gap.pose(0.5)[0], tri, corner)
    tried = []

    def leaving_one(gap, x, s, scale, defects):
        tried.append(int(np.count_nonzero(defects)))
        return untangling.Untangling(x + 1.0, 1, 1, 1, 0)

    monkeypatch.setattr(prediction_repairs, "untangled", leaving_one)
    for most, expected in ((1, []), (prediction_repairs.UNTANGLED_FIRST_DEFECTS, [2])):
        monkeypatch.setattr(prediction_repairs, "UNTANGLED_FIRST_DEFECTS", most)
        tried.clear()
        gap.outcomes[0.5] = Outcome(2, False)
        with gap.repair.fields_kept():
            y, problem = prediction_repairs.untangled_first(gap, 0.5, (x, "2 triangle(s) flipped or collapsed"))
        assert y is x and problem is not None and tried == expected
        assert gap.outcomes[0.5] == Outcome(2, False)


def test_an_untangled_prediction_is_taken_only_where_it_stretches_the_in_between_little(monkeypatch):
    """The guard of :func:`core.inbetween_prediction_repairs.untangled_first` (``_stretched_open``)
    turns down an untangled pose exactly where the in-between's mean relative edge misfit to the
    interpolated metric, computed here over every corner edge of the mesh, rises by more than
    UNTANGLED_FIRST_STRETCH: one vertex of a 20 × 20 sheet moved along x by lengths on both sides of
    the bound (found from the whole mesh's misfit, not from the rows the guard reads), and a move
    that lowers the misfit taken whatever its size."""
    from core.inbetween_prediction_repairs import UNTANGLED_FIRST_STRETCH, _stretched_open

    flat, tri, keys = _sheet_keys(side=20)
    gap = SequenceInterpolator(keys, tri)._gap(0)
    s = 0.5
    metric = gap.metric_lengths(s)
    centre = int(np.argmin(np.linalg.norm(flat - flat.mean(axis=0), axis=1)))
    x = gap.pose(s)[0]

    def mean_misfit(z):  # over every corner edge of the mesh, (3, m) as the metric's
        p = z[tri]
        return float(np.mean(np.abs(np.linalg.norm(p[:, [1, 2, 0]] - p, axis=2).T / metric - 1.0)))

    def moved(d):
        y = x.copy()
        y[centre, 0] += d
        return y

    rises = {d: mean_misfit(moved(d)) - mean_misfit(x) for d in np.linspace(0.0, 0.05, 51)[1:]}
    assert min(rises.values()) < UNTANGLED_FIRST_STRETCH < max(rises.values())
    for d, rise in rises.items():
        if abs(rise - UNTANGLED_FIRST_STRETCH) > 1e-6:
            assert _stretched_open(gap, s, x, moved(d)) == (rise > UNTANGLED_FIRST_STRETCH)
    far = moved(0.05)
    assert mean_misfit(x) < mean_misfit(far) and not _stretched_open(gap, s, far, x)  # back toward the metric


def test_the_untangle_first_guard_measures_a_short_edge_over_the_fits_floor():
    """The guard of :func:`core.inbetween_prediction_repairs.untangled_first` measures as the fit does
    (``gap.misfit``): an edge whose metric length is under MISFIT_LENGTH_FLOOR of the mean edge
    deviates by its change over that floor, not over its own length. A 20 × 20 sheet with one edge
    2e-3 of a spacing long in every key, that edge lengthened 1, 2, 4 and 8 times its length by a move
    of one of its ends: the guard turns the move down exactly where the in-between's mean misfit
    computed here with the floor, over every corner edge of the mesh, rises past UNTANGLED_FIRST_STRETCH
    (measured without the floor it would at 2 and 4 already)."""
    from core.inbetween_fit import MISFIT_LENGTH_FLOOR
    from core.inbetween_prediction_repairs import UNTANGLED_FIRST_STRETCH, _stretched_open

    flat, tri = grid(20, 20, size=1.0)
    spacing = flat[1, 0] - flat[0, 0]
    centre = int(np.argmin(np.linalg.norm(flat - flat.mean(axis=0), axis=1)))
    right = centre + 1  # its neighbour along x
    sliver = flat.copy()
    sliver[centre, 0] = flat[right, 0] - 2e-3 * spacing
    keys = [_bend(sliver, angle, length=1.0) for angle in (0.0, 0.6, 1.2)]
    middle = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0))
    gap = SequenceInterpolator([key - middle for key in keys], tri)._gap(0)
    s = 0.5
    metric, floor = gap.metric_lengths(s), MISFIT_LENGTH_FLOOR * gap.mean_edge
    short = (metric < floor) & (metric > 0.0)
    assert short.sum() == 2  # the edge, in its two triangles
    x = gap.pose(s)[0]

    def mean_misfit(z, floored=True):  # over every corner edge of the mesh, (3, m) as the metric's
        p = z[tri]
        lengths = np.linalg.norm(p[:, [1, 2, 0]] - p, axis=2).T
        deviation = np.abs(lengths / metric - 1.0)
        if floored:
            deviation[short] = np.abs(lengths - metric)[short] / floor
        return float(np.mean(deviation))

    along = (x[right] - x[centre]) / np.linalg.norm(x[right] - x[centre])
    for times in (1, 2, 4, 8):
        y = x.copy()
        y[centre] -= times * 2e-3 * spacing * along
        rise = mean_misfit(y) - mean_misfit(x)
        assert _stretched_open(gap, s, x, y) == (rise > UNTANGLED_FIRST_STRETCH)
        if times in (2, 4):  # the floor decides these
            assert rise < UNTANGLED_FIRST_STRETCH < mean_misfit(y, floored=False) - mean_misfit(x, floored=False)


def _curling_finger():
    """A finger (a closed tube) curling by 120° at each of two joints per key, three keys about the
    first key's middle (sequences work about it): (keys, triangles, the finger curled by the
    interpolated angles half-way through the first gap, a vertex between the joints on its top)."""
    from placement_helpers import _curled_tube

    angles, joints = np.radians([120.0, 120.0]), (0.25, 0.6)
    keys = [_curled_tube(k * angles, joints, 0.35, rings=31, sides=8)[0] for k in range(3)]
    tri = _curled_tube(0.0 * angles, joints, 0.35, rings=31, sides=8)[1]
    middle = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0))
    keys = [key - middle for key in keys]
    curl = _curled_tube(0.5 * angles, joints, 0.35, rings=31, sides=8)[0] - middle
    centre = int(np.argmin(np.abs(keys[0][:, 0] + middle[0] - 0.45) + np.abs(keys[0][:, 2] + middle[2] - 0.07)))
    return keys, tri, curl, centre


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
    keys, tri, curl, centre = _curling_finger()
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


def test_repairs_again_count_the_defects_as_the_untangling_does_not_the_tip_turned_away():
    """The finger of :func:`_curling_finger` fitted half-way through its first gap (clean: its tip
    faces away from both keys as the interpolated rotations turn it, which is no defect), with a fan
    folded over between the joints (a vertex pushed past its neighbour), repaired again as an
    in-between that kept defects (``repaired_in_passes``): the fold is repaired (only vertices
    within three rings of the pushed one move, the tip still faces away from both keys as the curl
    does), and the count the gap keeps for the warning, and what is said, are those of the
    triangles facing against both keys and against the curl's own normal: none. Counted without the
    interpolated frames, the passes took the tip's 48 triangles for defects, and the pose came back
    with "it keeps 48 triangle(s) flipped or collapsed" where none faces against the curl (the
    untangling, which counts with the frames, then found nothing and the warning stood)."""
    from core.inbetween_prediction_repairs import defect_count, repaired_in_passes

    keys, tri, curl, centre = _curling_finger()
    gap = SequenceInterpolator(keys, tri, start="keys")._gap(0)
    x, problem = gap.pose(0.5)
    turned = _flipped(curl, keys[0], keys[1], tri)
    assert problem is None and turned > 0 and _flipped(x, keys[0], keys[1], tri) == turned

    def against_the_curl(y):  # facing against both keys and against the curled finger's normal
        n = _normals(y, tri)
        return int(np.sum((np.einsum("ij,ij->i", n, _normals(keys[0], tri)) < 0)
                          & (np.einsum("ij,ij->i", n, _normals(keys[1], tri)) < 0)
                          & (np.einsum("ij,ij->i", n, _normals(curl, tri)) < 0)))

    folded = _pushed_past(x, tri, centre)
    assert against_the_curl(folded) > 0
    with gap.repair.fields_kept():
        y, said = repaired_in_passes(gap, 0.5, (folded.copy(), "1 triangle(s) flipped or collapsed"))
    assert gap.outcomes[0.5].defects == against_the_curl(y) == 0 and said is None
    assert _flipped(y, keys[0], keys[1], tri) == turned
    near = _within_rings(tri, centre, 3)
    assert np.array_equal(y[~near], folded[~near])
    assert defect_count(gap, 0.5, x) == against_the_curl(x) == 0  # the count predictions are weighed by


def test_a_fold_beside_the_turned_away_tip_is_repaired_without_turning_the_tip_back():
    """The finger of :func:`_curling_finger` fitted half-way (clean: its tip faces away from both
    keys as the interpolated rotations turn it) with a fan folded over at the tip's edge (a vertex
    one ring outside the turned triangles pushed past its neighbour, each such vertex in turn), repaired again
    (``repaired_in_passes``): the fold is repaired, only vertices within three rings of it move,
    nothing is said, and every triangle of the tip still faces away from both keys as the curl
    does. A region's own check cannot tell a piece turning away as the field says (the whole
    pose's check can), so it read the tip's triangles in the repair region as flipped: the repair
    took fields that turned 1–5 of them back toward the keys."""
    from core.inbetween_prediction_repairs import repaired_in_passes

    keys, tri, curl, centre = _curling_finger()
    gap = SequenceInterpolator(keys, tri, start="keys")._gap(0)
    x, problem = gap.pose(0.5)
    n = _normals(x, tri)
    tip = (np.einsum("ij,ij->i", n, _normals(keys[0], tri)) < 0) & (np.einsum("ij,ij->i", n, _normals(keys[1], tri)) < 0)
    assert problem is None and tip.sum() == _flipped(curl, keys[0], keys[1], tri) > 0
    inside = np.zeros(len(x), dtype=bool)
    inside[tri[tip]] = True
    beside = np.flatnonzero(~inside & np.isin(np.arange(len(x)), tri[inside[tri].any(axis=1)]))
    assert beside.size
    for vertex in beside:  # each fold on its own, the tip's edge all round
        folded = _pushed_past(x, tri, int(vertex))
        with gap.repair.fields_kept():
            y, said = repaired_in_passes(gap, 0.5, (folded.copy(), "1 triangle(s) flipped or collapsed"))
        ny = _normals(y, tri)
        assert said is None and gap.outcomes[0.5].defects == 0
        assert (np.einsum("ij,ij->i", ny, _normals(curl, tri)) > 0).all()  # nothing faces against the curl
        assert ((np.einsum("ij,ij->i", ny[tip], _normals(keys[0], tri)[tip]) < 0)
                & (np.einsum("ij,ij->i", ny[tip], _normals(keys[1], tri)[tip]) < 0)).all()
        near = _within_rings(tri, int(vertex), 3)
        assert np.array_equal(y[~near], folded[~near])


def _sheet_keys(side=40):
    """A unit sheet of ``side`` × ``side`` vertices bending about y through three keys (0, 0.6 and
    1.2 radians, isometric: the interpolated areas are the flat sheet's), about the first key's
    middle: (the flat sheet, triangles, the keys)."""
    flat, tri = grid(side, side, size=1.0)
    keys = [_bend(flat, angle, length=1.0) for angle in (0.0, 0.6, 1.2)]
    middle = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0))
    return flat, tri, [key - middle for key in keys]


def _crushed(x, flat, centre, radius, ramp=16.0, inner=1e-3):
    """Positions ``x`` drawn toward vertex ``centre``: within ``radius`` grid spacings of it (on the
    ``flat`` sheet) to ``inner`` of their distance, beyond that less and less, to none ``ramp``
    spacings farther. Its triangles within the radius are crushed (area ``inner²`` of theirs: collapsed),
    those around it squeezed but not collapsed, so the vertices two rings out enclose too little
    area for the crushed ones to open: a tangle wider than the untangling's two rings."""
    spacing = flat[1, 0] - flat[0, 0]
    r = np.linalg.norm(flat[:, :2] - flat[centre, :2], axis=1) / spacing
    share = np.clip(inner + (1.0 - inner) * (r - radius) / ramp, inner, 1.0)
    return x[centre] + share[:, None] * (x - x[centre])


def _collapsed(y, key, tri) -> int:
    """Triangles of ``y`` whose area is below the collapse check's share of their area in ``key``
    (the interpolated area where the keys bend isometrically)."""
    return int(np.sum(np.linalg.norm(_normals(y, tri), axis=1) < COLLAPSE_RATIO * np.linalg.norm(_normals(key, tri), axis=1)))


def _counted_untangling(monkeypatch) -> list:
    """The number of free vertices of each system the untangling solves (its calls of
    :func:`untangle`), filled as they are made."""
    solved = []

    def counted(vertices, triangles, free, *args, **kwargs):
        solved.append(len(free))
        return untangle(vertices, triangles, free, *args, **kwargs)

    monkeypatch.setattr(untangling, "untangle", counted)
    return solved


def _tries_made(monkeypatch) -> list:
    """Each try the untangling makes, as [its free vertices f, its Gauss–Newton steps k] counted here
    from its dense solves (each of 3 f unknowns), filled as they are made."""
    from types import SimpleNamespace

    from scipy import linalg

    tries = []

    def solve(matrix, *args, **kwargs):
        assert len(matrix) == 3 * tries[-1][0]
        tries[-1][1] += 1
        return linalg.solve(matrix, *args, **kwargs)

    def counted(vertices, triangles, free, *args, **kwargs):
        tries.append([len(free), 0])
        return untangle(vertices, triangles, free, *args, **kwargs)

    monkeypatch.setattr(untangling, "linalg", SimpleNamespace(solve=solve, LinAlgError=linalg.LinAlgError))
    monkeypatch.setattr(untangling, "untangle", counted)
    return tries


def _work(tries) -> float:
    """The work of ``tries`` (:func:`_tries_made`) in steps of a system of UNTANGLE_FREE_VERTICES free
    vertices: a step's dense algebra grows with the square of its free vertices f, plus an overhead
    c (in squared free vertices), and a try's set-up costs two steps: Σ (k + 2) (f² + c) / (F² + c)."""
    c = untangling.UNTANGLE_STEP_OVERHEAD
    return sum((k + 2) * (f * f + c) / (UNTANGLE_FREE_VERTICES ** 2 + c) for f, k in tries)


def _crushed_and_folded(monkeypatch, radius):
    """The middle in-between of :func:`_sheet_keys`'s first gap made with a crush of ``radius``
    spacings at the sheet's middle (:func:`_crushed`) and a fold near a corner (a vertex pushed
    past its neighbour, :func:`_pushed_past`), as kept by the repairs: (keys, triangles, the pose
    made, the in-between returned, the folded vertex, the warnings said)."""
    flat, tri, keys = _sheet_keys()
    centre = int(np.argmin(np.linalg.norm(flat - [0.5, 0.5, 0.0], axis=1)))
    corner = int(np.argmin(np.linalg.norm(flat - [0.1, 0.1, 0.0], axis=1)))
    made = _fits_made(monkeypatch, lambda x: (_pushed_past(_crushed(x, flat, centre, radius), tri, corner),))
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        y = SequenceInterpolator(keys, tri).pose(0, 0.5)
    return keys, tri, made[0.5][0], y, corner, [w.message for w in said]


def test_a_fold_is_untangled_beside_a_crush_the_untangling_cannot_open(monkeypatch):
    """An in-between kept by the repairs with two separate tangles: a fold near a corner (a vertex
    pushed past its neighbour) and, at the middle, the cloth crushed to a point (96 triangles
    collapsed) with the cloth around it squeezed, so that two rings out there is too little room to
    open it. The fold is untangled (no flipped triangle left; only vertices within three rings of
    it moved), the crush is left as it was, bit for bit, and the warning counts its collapsed
    triangles, counted here from the areas. Accepting the untangling only where the whole
    in-between came back clean, the fold was kept too."""
    keys, tri, x, y, corner, said = _crushed_and_folded(monkeypatch, radius=4)
    assert _flipped(x, keys[0], keys[1], tri) > 0
    assert _flipped(y, keys[0], keys[1], tri) == 0
    near = _within_rings(tri, corner, 3)
    assert (y[near] != x[near]).any()
    assert np.array_equal(y[~near], x[~near])
    collapsed = _collapsed(y, keys[0], tri)
    assert collapsed > 0
    # the crush's collapsed triangles said once; the gap's ``fit`` warning may say its edges are off too
    assert [(w.kind, w.defects) for w in _defects_said(said)] == [("pose", collapsed)]


def test_a_tangle_too_large_is_not_untangled_its_work_bounded_and_said(monkeypatch):
    """As above with the crush over a radius of 9 spacings (520 triangles collapsed: more than
    UNTANGLE_FREE_VERTICES free vertices around them): the untangling never solves for more free
    vertices at once than that, nor does more work than UNTANGLE_WORK in all (counted from its
    solves); the fold is untangled, the crush left bit for bit, and the warning counts its collapsed
    triangles and says it was too large to untangle. Leaving a part that large ended the untangling
    of the whole in-between: the fold was kept too."""
    tries = _tries_made(monkeypatch)
    keys, tri, x, y, corner, said = _crushed_and_folded(monkeypatch, radius=9)
    assert tries and max(f for f, _ in tries) <= UNTANGLE_FREE_VERTICES and _work(tries) <= UNTANGLE_WORK
    assert _flipped(x, keys[0], keys[1], tri) > 0
    assert _flipped(y, keys[0], keys[1], tri) == 0
    near = _within_rings(tri, corner, 3)
    assert np.array_equal(y[~near], x[~near])
    collapsed = _collapsed(y, keys[0], tri)
    assert collapsed > 0
    assert [(w.kind, w.defects) for w in _defects_said(said)] == [("pose", collapsed)]
    assert "too large to untangle" in str(said[0])


def test_the_untangling_of_an_in_between_stops_at_its_work(monkeypatch):
    """Two folds alike far apart (a vertex pushed past its neighbour at each), with the work of an
    in-between's untangling (UNTANGLE_WORK) set short of what a try of both at once may take at its
    most steps: one is untangled, the other is left as it was, bit for bit (the work the first took
    and the most the second may take are past it), and said as too large to untangle, its flipped
    triangles counted."""
    flat, tri, keys = _sheet_keys()
    ends = [int(np.argmin(np.linalg.norm(flat - [a, 0.5, 0.0], axis=1))) for a in (0.2, 0.8)]
    solved = _counted_untangling(monkeypatch)
    made = _fits_made(monkeypatch, lambda x: (_pushed_past(_pushed_past(x, tri, ends[0]), tri, ends[1]),))

    def in_between():
        solved.clear()
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always", ShapeDifferenceWarning)
            y = SequenceInterpolator(keys, tri).pose(0, 0.5)
        return y, [w.message for w in said]

    y, said = in_between()
    assert not _defects_said(said) and _flipped(y, keys[0], keys[1], tri) == 0  # both untangled
    both = sum(solved)
    assert len(solved) == 1  # both in one try
    most = len(UNTANGLE_WEIGHTS) * UNTANGLE_ITERATIONS
    monkeypatch.setattr(untangling, "UNTANGLE_WORK", 0.999 * untangle_work(both, most))
    y, said = in_between()
    x = made[0.5][0]
    assert len(solved) == 1 and solved[0] < both
    moved = [np.array_equal(y[_within_rings(tri, end, 3)], x[_within_rings(tri, end, 3)]) for end in ends]
    assert sorted(moved) == [False, True]  # one fold untangled, the other as it was
    untangled_fold = _within_rings(tri, ends[moved.index(False)], 3)
    assert np.array_equal(y[~untangled_fold], x[~untangled_fold])
    flipped = _flipped(y, keys[0], keys[1], tri)
    assert 0 < flipped < _flipped(x, keys[0], keys[1], tri)
    said = _defects_said(said)
    assert [(w.kind, w.defects) for w in said] == [("pose", flipped)] and "too large to untangle" in str(said[0])


def test_a_fold_beside_a_crush_joined_at_the_second_ring_is_untangled_with_no_triangle_collapsed(monkeypatch):
    """A crush of 3 spacings (its triangles collapsed, the cloth around it squeezed) with a fold 6
    spacings away (a vertex pushed past its neighbour): one ring around them leaves too little room,
    and at two rings they are one place whose untangling faces every side while triangles beside
    the crush, each held only to half its own small facing, end under the collapse check. Tried
    again with the margins floored (UNTANGLE_COLLAPSE_FLOOR), the in-between comes back with no
    triangle flipped or collapsed (counted here from its normals and areas), unwarned, and only
    vertices within three rings of the crush and the fold move. Without the floored try the place
    was left, 66 triangles warned."""
    flat, tri, keys = _sheet_keys()
    spacing = flat[1, 0] - flat[0, 0]
    centre = int(np.argmin(np.linalg.norm(flat - [0.5, 0.5, 0.0], axis=1)))
    fold = int(np.argmin(np.linalg.norm(flat - (flat[centre] + [6 * spacing, 0.0, 0.0]), axis=1)))
    made = _fits_made(monkeypatch, lambda x: (_pushed_past(_crushed(x, flat, centre, 3), tri, fold),))
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        y = SequenceInterpolator(keys, tri).pose(0, 0.5)
    x = made[0.5][0]
    assert _collapsed(x, keys[0], tri) > 0 and _flipped(x, keys[0], keys[1], tri) > 0
    assert not _defects_said(said)
    assert _flipped(y, keys[0], keys[1], tri) == 0 and _collapsed(y, keys[0], tri) == 0
    near = _within_rings(tri, centre, 6) | _within_rings(tri, fold, 3)
    assert np.array_equal(y[~near], x[~near])


def test_many_small_folds_on_a_larger_sheet_are_all_untangled_within_the_work(monkeypatch):
    """Some 480 one-vertex folds five spacings apart on a sheet of 115 × 115 vertices (each a
    vertex pushed past its neighbour: 2–3 flipped triangles): each try of a run of them ends in a
    few Gauss–Newton steps, so the untangling clears every one of them, with no warning, within its
    work (counted here from its solves), and only vertices within three rings of a fold move. Its
    work counted as the free vertices solved for (2,000 an in-between, past which the ~2,100 here
    go) left most of them, warned."""
    side = 115
    flat, tri, keys = _sheet_keys(side)
    folds = [j * side + i for i in range(3, side - 3, 5) for j in range(3, side - 3, 5)]
    tries = _tries_made(monkeypatch)

    def folded(x):
        for vertex in folds:
            x = _pushed_past(x, tri, vertex)
        return (x,)

    made = _fits_made(monkeypatch, folded)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        y = SequenceInterpolator(keys, tri).pose(0, 0.5)
    x = made[0.5][0]
    assert _flipped(x, keys[0], keys[1], tri) >= 2 * len(folds)
    assert not _defects_said(said) and _flipped(y, keys[0], keys[1], tri) == 0
    assert sum(f for f, _ in tries) > 2000  # more than a count of free vertices allowed
    assert _collapsed(y, keys[0], tri) == 0
    assert _work(tries) <= UNTANGLE_WORK
    near = np.zeros(len(flat), dtype=bool)
    for vertex in folds:
        near |= _within_rings(tri, vertex, 3)
    assert np.array_equal(y[~near], x[~near])


def test_an_in_between_without_defects_is_left_bit_for_bit(monkeypatch):
    """An in-between whose fit is said to keep a flipped triangle while it has none (a problem of
    another kind): the untangling leaves it bit for bit, the same pose as the sequence gives
    without the message."""
    flat, tri, keys = _sheet_keys(side=12)
    plain = SequenceInterpolator(keys, tri).pose(0, 0.5)
    made = _fits_made(monkeypatch, lambda x: (x.copy(),))
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always", ShapeDifferenceWarning)
        y = SequenceInterpolator(keys, tri).pose(0, 0.5)
    assert np.array_equal(made[0.5][0], plain) and np.array_equal(y, plain)


def test_a_fit_near_the_blend_left_with_places_is_said_as_that_fit(monkeypatch):
    """An in-between the repairs left as a fit near the keys' linear blend (the fallback of a
    sequence's fit that is not finite), with a fold the untangling clears beside a crush it leaves:
    its warning names that fit as what it keeps, not the metric fit. Said as the metric fit, the
    warning named a pose the in-between is not."""
    import core.inbetween_solver as solver
    from core.inbetween_repair import Outcome

    real_pose = solver.Gap.pose

    def near_blend(self, s, *args, **kwargs):  # what Repair.outcome says of its fallback near the blend
        x, problem = real_pose(self, s, *args, **kwargs)
        if 0.0 < s < 1.0:
            self.outcomes[s] = Outcome(1, True)
        return x, problem

    monkeypatch.setattr(solver.Gap, "pose", near_blend)
    keys, tri, x, y, corner, said = _crushed_and_folded(monkeypatch, radius=4)
    assert _flipped(x, keys[0], keys[1], tri) > 0 and _flipped(y, keys[0], keys[1], tri) == 0  # the fold cleared
    said = _defects_said(said)
    assert [(w.kind, w.defects) for w in said] == [("pose", _collapsed(y, keys[0], tri))]
    assert "(a fit near the keys' linear blend with the fewest defects" in str(said[0])


def test_a_count_reads_the_pose_once_and_takes_the_turned_tip_out(monkeypatch):
    """``Repair.counted`` on the finger of :func:`_curling_finger` half-way through its first gap,
    with a fan folded over between the joints: it equals, triangle by triangle, the whole mesh's
    check with the interpolated frames (the fold's triangles; not the tip's, which face away from
    both keys as the interpolated rotations turn them), which the check without the frames does not
    (it holds the tip's too), and it takes the pose's triangle sides once for both checks (the
    second check reads the first one's sides and normals: the same pose)."""
    keys, tri, curl, centre = _curling_finger()
    gap = SequenceInterpolator(keys, tri, start="keys")._gap(0)
    s, scale = 0.5, gap.area_scale(0.5)
    x = _pushed_past(gap.pose(s)[0], tri, centre)
    frames, stretch = gap.repair.factor_targets(s)[:2]
    with_frames = gap.repair.defects(x, s, frames, stretch, scale=scale)
    plain = gap.repair.defects(x, s, None, None, scale=scale)
    turned = _flipped(curl, keys[0], keys[1], tri)
    assert with_frames.any() and plain.sum() >= with_frames.sum() + turned > with_frames.sum()
    read = []
    real = type(gap.topo).triangle_sides
    monkeypatch.setattr(type(gap.topo), "triangle_sides", lambda topo, y: read.append(y) or real(topo, y))
    np.testing.assert_array_equal(gap.repair.counted(x, s, scale), with_frames)
    assert len(read) == 1
