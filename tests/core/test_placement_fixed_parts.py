"""Parts that do not move stay put in in-betweens and exaggerations (core.pins; issue 17 item 3):
fixed and pinned parts, vertices riding on an animated object, pieces still between two keys.
No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import core.inbetween_solver as solver
from core.errors import ShapeDifferenceWarning
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator

from meshes import grid, icosphere
from inbetween_helpers import _normals
from placement_helpers import _arm, _curled_strip


@pytest.mark.parametrize("factor", [0.5, 1.5, 2.0])
def test_fixed_upper_arm_stays_fixed(factor):
    """An arm bent at the elbow by 100°: the upper arm, fixed in both keys, is fixed at every
    factor, exaggerations included."""
    a, tri = _arm(0.0)
    b, _ = _arm(np.radians(100.0))
    x = Interpolator(a, b, tri).pose(factor)
    upper = a[:, 0] < 0.85
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    assert np.abs(x[upper] - a[upper]).max() < 1e-3 * diagonal



@pytest.mark.parametrize("width", [2, 3])
@pytest.mark.parametrize("noise", [1e-4, 3e-4, 1e-3, 3e-3])
def test_a_fixed_part_stays_fixed_when_noisy_keys_are_exaggerated(width, noise):
    """A strip of 61 × ``width`` vertices (edges 0.05) bent 100° at one joint, its first 0.85
    fixed, with Gaussian noise of ``noise`` per coordinate on both poses (as scans and exported
    caches carry; at 3e-3 the fixed part's edge vectors change by ~20 % between the keys): at every
    factor, exaggerations and reversals included, the fixed part stays where it is to within the
    noise. Its anchor pulls it toward the keys' linear extrapolation ``a + f (b − a)``, whose
    points lie ``1.596 σ √((1 − f)² + f²)`` from the truth on average (σ per coordinate, χ₃);
    the fixed part is held within twice that. The extrapolated noise read as motion let its anchor
    go and the bent part's rigid fit moved it: 60–180 × that distance at 3e-3 (0.21 of the
    diagonal at × 1.5, 0.51 at × 2). Up to × 2 (a bend of 200°) no triangle faces against the
    noise-free strip."""
    angle = np.radians(100.0)
    a0, tri = _curled_strip((0.0,), joints=(0.9,), width=width, n=61)
    b0, _ = _curled_strip((angle,), joints=(0.9,), width=width, n=61)
    fixed = a0[:, 0] < 0.85
    for seed in range(3):
        rng = np.random.default_rng(seed)
        a, b = a0 + noise * rng.normal(size=a0.shape), b0 + noise * rng.normal(size=b0.shape)
        interpolator = Interpolator(a, b, tri)
        for factor in (-0.5, 0.5, 1.5, 2.0, 3.0):
            truth, _ = _curled_strip((factor * angle,), joints=(0.9,), width=width, n=61)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ShapeDifferenceWarning)
                x = interpolator.pose(factor)
            target = 1.596 * noise * np.hypot(1.0 - factor, factor)
            assert np.linalg.norm(x[fixed] - truth[fixed], axis=1).mean() < 2.0 * target
            if factor <= 2.0:
                assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()


def test_a_piece_that_sits_still_between_two_keys_stays_there_in_a_sequence():
    """A ball lying on the floor while a hand (a separate sphere) moves around it, then carried off
    after the third key (a prop a Child Of constraint hands over): in the gaps where it sits in the
    same place in both keys it stays there at every factor, as a hold of the whole pose does (the
    keys' spline borrowed the velocity of the pickup in the next gap: a probe's ball picked up by a
    rigged arm moved 2.7 % of the diagonal before it was touched, as the per-vertex Catmull–Rom
    spline does)."""
    hand, hand_tri = icosphere(1, radius=0.2)
    ball, ball_tri = icosphere(1, radius=0.15)
    path = [(-1.0, 0.0, 0.5), (-0.4, 0.3, 0.4), (0.2, 0.0, 0.3), (0.0, 0.0, 0.4), (0.5, 0.5, 1.0)]
    lift = [(0.0, 0.0, 0.0)] * 3 + [(0.0, 0.0, 0.25), (0.5, 0.5, 0.85)]
    keys = [np.vstack([hand + h, ball + b]) for h, b in zip(path, lift)]
    tri = np.vstack([hand_tri, ball_tri + len(hand)])
    rows = len(hand) + np.arange(len(ball))
    seq = SequenceInterpolator(keys, tri)
    factors = np.arange(1, 8) / 8
    for gap in (0, 1):
        poses = seq.poses(gap, factors)
        assert np.array_equal(poses[:, rows], np.broadcast_to(keys[0][rows], poses[:, rows].shape))
        assert np.abs(poses[3, :len(hand)] - keys[gap][:len(hand)]).max() > 0.1  # the hand moves on
    moved = seq.poses(2, factors)[:, rows]  # lifted in the next gap: not held there
    assert np.abs(moved[-1] - keys[2][rows]).max() > 0.1


def test_pinned_vertices_stay_put_in_sequences():
    """A sheet hanging from its top edge swings and waves between the keys: the vertices that sit
    still in every key (Blender's pinned cloth) stay exactly there in every in-between, solved or
    predicted; the rest moves."""
    flat, tri = grid(14, 10, size=1.0)
    pinned = flat[:, 1] >= flat[:, 1].max() - 1e-12
    depth = flat[:, 1].max() - flat[:, 1]  # 0 along the pinned edge
    keys = []
    for k in range(6):
        angle = 0.5 * np.sin(0.9 * k) * depth  # a swing about the pinned edge, growing with depth
        wave = 0.05 * depth * np.sin(4.0 * flat[:, 0] + k)
        keys.append(np.stack([flat[:, 0], flat[:, 1].max() - depth * np.cos(angle), depth * np.sin(angle) + wave], axis=1))
    assert all(np.array_equal(k[pinned], keys[0][pinned]) for k in keys)
    seq = SequenceInterpolator(keys, tri)
    for gap in range(len(seq)):
        batch = seq.poses(gap, np.arange(1, 8) / 8)
        assert np.array_equal(batch[:, pinned], np.broadcast_to(keys[0][pinned], batch[:, pinned].shape))
        assert np.abs(batch[:, ~pinned] - keys[gap][~pinned]).max() > 1e-2
    assert np.array_equal(seq.pose_at(2.3)[pinned], keys[0][pinned])


def test_pins_jittered_by_single_precision_rounding_stay_put():
    """The hanging sheet of the test above as a single-precision cache written through an object
    transform would give it: every key's coordinates rounded to float32 after a shift, so the
    pinned vertices move by rounding (~1e-7 of the diagonal). They are still taken for pins and
    stay where the first key has them, within that rounding, in every in-between (compared
    exactly they were taken for moving vertices and ended 0.14 % of the diagonal off at g = 4);
    the caller's arrays are not changed."""
    flat, tri = grid(14, 10, size=1.0)
    pinned = flat[:, 1] >= flat[:, 1].max() - 1e-12
    depth = flat[:, 1].max() - flat[:, 1]
    shift = np.array([103.7, -58.1, 12.9])  # the object far from the origin
    keys = []
    for k in range(6):
        angle = 0.5 * np.sin(0.9 * k) * depth
        wave = 0.05 * depth * np.sin(4.0 * flat[:, 0] + k)
        exact = np.stack([flat[:, 0], flat[:, 1].max() - depth * np.cos(angle), depth * np.sin(angle) + wave], axis=1)
        keys.append((exact + shift).astype(np.float32).astype(np.float64) - shift + 1e-9 * k)
    assert not all(np.array_equal(k[pinned], keys[0][pinned]) for k in keys)
    copies = [k.copy() for k in keys]
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    seq = SequenceInterpolator(keys, tri)
    for gap in range(len(seq)):
        batch = seq.poses(gap, np.arange(1, 5) / 4)
        assert np.abs(batch[:, pinned] - keys[0][pinned]).max() < 1e-6 * diagonal
    assert all(np.array_equal(k, c) for k, c in zip(keys, copies))


def _sheet_pinned_by_slivers():
    """A sheet pinned along its top edge (14 × 10 vertices, size 1), whose row next to the pins is
    1/50 of a row away from them (slivers, as Delaunay meshes of scanned cloth have), swinging and
    curling over five keys so that its best rigid motion turns about an axis off the pinned edge:
    the keys (5 × (n, 3)), the triangles, the pinned vertices and the sliver row (bool (n,) each)."""
    flat, tri = grid(14, 10, size=1.0)
    top = flat[:, 1].max()
    pinned = flat[:, 1] >= top - 1e-12
    rows = np.unique(flat[:, 1])
    sliver = np.isclose(flat[:, 1], rows[-2])
    flat[sliver, 1] = top - 0.02 * (rows[-1] - rows[-2])
    depth = top - flat[:, 1]
    keys = []
    for k, amplitude in enumerate([0.0, 0.9, 1.8, 1.2, 0.3]):
        angle = amplitude * (depth / depth.max()) ** 2 + 0.3 * np.sin(1.3 * k) * depth
        wave = 0.05 * depth * np.sin(4.0 * flat[:, 0] + k)
        keys.append(np.stack([flat[:, 0], top - depth * np.cos(angle), depth * np.sin(angle) + wave], axis=1))
    return keys, tri, pinned, sliver


def test_slivers_at_pins_do_not_turn_over_in_predicted_in_betweens():
    """The sheet pinned by slivers (:func:`_sheet_pinned_by_slivers`) swings and curls between
    the keys. Predicted in-betweens put the pins where that motion takes them and the miss is
    spread around them (before: the pins alone were set back, 2.7e-3 = 3.5 % of a row, and 13
    slivers turned over against both keys)."""
    keys, tri, pinned, _ = _sheet_pinned_by_slivers()

    def normals(x):
        return np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])

    seq = SequenceInterpolator(keys, tri)
    for gap in range(len(seq)):
        facing = [normals(keys[gap]), normals(keys[gap + 1])]
        for x in seq.poses(gap, np.arange(1, 8) / 8):  # two solved, five predicted
            n = normals(x)
            turned = (np.einsum("ij,ij->i", n, facing[0]) < 0) & (np.einsum("ij,ij->i", n, facing[1]) < 0)
            assert not turned.any()
            assert np.array_equal(x[pinned], keys[0][pinned])


def test_the_defect_check_sees_the_pins_where_the_in_between_has_them(monkeypatch):
    """The pins are set exactly where they belong after the fit and its repairs
    (``Gap.finished``), so the check for flipped triangles and its repairs must see them there:
    a solved in-between reaches the check with its pins in place (before: the fit's anchor left
    them off by up to 1e-3 of its pull), a predicted one too, its miss at the pins small or large
    (:func:`core.inbetween_corrections.pins_in_place`; before: a miss under the metric's
    tolerance was left and a spread one kept ~1/w of it), and a repair of a sliver row folded over
    the pins holds them (before: they moved by 2.5e-6, and setting them back afterwards turned
    a sliver of a 1k flag over at its pole, one flipped triangle the check had not seen)."""
    from core.inbetween_corrections import pins_in_place
    from core.inbetween_fit import METRIC_TOLERANCE

    keys, tri, pinned, sliver = _sheet_pinned_by_slivers()
    seq = SequenceInterpolator(keys, tri)
    s, segment = 0.5, seq._gap(1)
    assert np.array_equal(segment.static, pinned)
    where = segment.pinned_positions(s)
    checked = []
    real = segment.repair.outcome
    monkeypatch.setattr(segment.repair, "outcome", lambda x, *a, **k: checked.append(x.copy()) or real(x, *a, **k))
    segment.pose(s)
    assert checked and np.array_equal(checked[0][pinned], where)
    x = seq._to_working(seq.poses(1, [s])[0])
    for miss in (0.1, 10.0):  # × the metric's tolerance of the mean edge
        off = x.copy()
        off[pinned] += miss * METRIC_TOLERANCE * segment.mean_edge * np.array([0.6, -0.8, 0.0])
        assert np.array_equal(pins_in_place(segment, off, s)[pinned], where)
    # a vertex of the sliver row folded over the pinned edge: the repair removes the fold and
    # leaves the pins where they are
    folded = x.copy()
    middle = np.flatnonzero(sliver)[np.count_nonzero(sliver) // 2]
    above = np.flatnonzero(pinned)[np.argmin(np.linalg.norm(keys[0][pinned] - keys[0][middle], axis=1))]
    folded[middle] = 2.0 * x[above] - x[middle]
    defects = segment.repair.counted(folded, s, segment.area_scale(s))
    assert defects.any()
    frames, stretch, motion, guide = segment.repair.factor_targets(s)
    repaired, problem = segment.repair.outcome(folded, folded, s, frames, stretch, guide, motion, defects=defects)[:2]
    assert problem is None
    assert np.array_equal(repaired[pinned], folded[pinned])
    assert not segment.repair.counted(repaired, s, segment.area_scale(s)).any()


def test_vertices_riding_on_an_animated_pole_follow_its_motion():
    """A banner whose pole column is carried by an animated object (exactly rigid in every key:
    turning about the pole's own axis at constant speed while the pole slides at constant
    velocity) and whose cloth flaps: the pole's vertices ride (:mod:`core.pins`), so every
    in-between, solved or predicted, has them exactly where that motion puts them (before: where
    the cloth's fields put them, up to 4e-3 off on a sheet 1.2 across)."""
    flat, tri = grid(16, 10, size=1.0)
    pole = flat[:, 0] <= 1e-12
    local = flat - [0.0, 0.5 * flat[:, 1].max(), 0.0]  # the pole along y, through the origin
    local = local[:, [0, 2, 1]]  # ... upright: the pole along z, the banner in the xz plane

    def carried(points, t):  # the object's motion at time t (keys at integers): turn about z, slide
        angle, shift = 0.35 * t, np.array([0.2 * t, 0.1 * t, 0.0])
        c, s = np.cos(angle), np.sin(angle)
        return points @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T + shift

    def key(t):
        x = local.copy()
        x[:, 1] += 0.15 * x[:, 0] * np.sin(2.0 * x[:, 0] + 1.5 * x[:, 2] + 1.1 * t)  # the cloth flaps
        return carried(x, t)

    keys = [key(t) for t in range(6)]
    seq = SequenceInterpolator(keys, tri, start="keys")  # cut from a motion at constant speed
    factors = np.arange(1, 8) / 8
    # each factor's riding motion is computed once (a pose's guide, its pins' prediction and its
    # finish ask for the same)
    first = seq._gap(0)
    spline, asked = first.riding_screws, []
    real_at = spline.at
    spline.at = lambda s: asked.append(s) or real_at(s)
    for gap in range(len(seq)):
        batch = seq.poses(gap, factors)
        for s, x in zip(factors, batch):
            np.testing.assert_allclose(x[pole], carried(local[pole], gap + s), atol=1e-9)
            assert np.isfinite(x).all()
    assert len(asked) >= len(factors) and len(asked) == len(set(asked))


def test_a_riding_row_of_vertices_off_its_line_by_the_rounding_translates_with_its_object():
    """A hanging strip whose top row of 8 vertices (7 cm) a hook carries at constant velocity
    while the cloth below flaps, the row off its line by the cloth solver's residual (5e-8 of
    coordinates near 2, under the rounding riding sets are found to) and the keys stored in single
    precision: the row rides (:mod:`core.pins`). It is along a line to the rounding, so its turn
    about the line is not told by the keys and it takes the least turn: every in-between has it on
    its path to the rounding (before: fitted as a body, it turned about the row by the noise's
    angle between keys and its spline swung it up to 0.014 off its path, a seventeenth of the strip)."""
    flat, tri = grid(8, 24, size=0.07)
    top = flat[:, 1] <= 1e-12
    hang = np.stack([flat[:, 0] + 0.3, np.zeros(len(flat)), 1.9 - flat[:, 1]], axis=1)
    velocity = np.array([0.12, 0.05, -0.02])

    def key(t):
        x = hang + t * velocity
        depth = flat[:, 1] / flat[:, 1].max()
        x[:, 1] += 0.03 * depth * np.sin(40.0 * flat[:, 0] + 1.3 * t)  # the cloth flaps and stretches
        x[:, 0] += 0.01 * depth ** 2 * np.cos(30.0 * flat[:, 1] + 0.9 * t)
        x[top, 1:] += np.random.default_rng(t).normal(0.0, 5e-8, (top.sum(), 2))  # off the row's line
        return x.astype(np.float32).astype(float)

    seq = SequenceInterpolator([key(t) for t in range(6)], tri, start="keys")  # cut from a motion at constant speed
    assert [np.flatnonzero(top).tolist()] == [rows.tolist() for rows in seq._riding]
    factors = np.arange(1, 8) / 8
    for gap in range(len(seq)):
        for s, x in zip(factors, seq.poses(gap, factors)):
            off = np.linalg.norm(x[top] - (hang[top] + (gap + s) * velocity), axis=1)
            assert off.max() <= seq._riding_tolerance


@pytest.mark.parametrize("swing, far_off", [(150.0, True), (60.0, False)])
def test_two_poses_say_where_a_translating_pinned_patch_ends_off_its_path(swing, far_off):
    """A sheet pinned at a 3 × 3-vertex corner patch that only translates between two poses while
    the rest of the sheet swirls about it (turned the more the farther from the patch: strained,
    as a sheet whipped by its pinned corner). The blend anchor holds the patch on the linear blend
    (exact for it), but it holds under 5 % of the sheet, which is then moved onto its centroid's
    path and carries the patch along. Swung 150°, the patch ends 13 % of the sheet's diagonal off
    its path; the in-between now says so, naming how far (before: no warning). Swung 60° it ends
    0.8 % off, under :data:`~core.inbetween_solver.HOOK_MISS_NOTED`: nothing is said."""
    a, tri = grid(16, 12, size=1.5)
    patch = (a[:, 0] < 0.25) & (a[:, 1] < 0.25)
    distance = np.linalg.norm(a, axis=1)
    turn = np.radians(swing) * np.clip((distance - 0.29) / 1.6, 0.0, 1.0)  # 0 on the patch
    c, s = np.cos(turn), np.sin(turn)
    shift = np.array([0.3, 0.05, 0.1])
    b = np.stack([c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1], a[:, 2]], axis=1) + shift
    assert np.array_equal(b[patch], a[patch] + shift)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        x = Interpolator(a, b, tri).pose(0.5)
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    miss = np.linalg.norm(np.mean(x[patch] - 0.5 * (a[patch] + b[patch]), axis=0)) / diagonal
    said = [str(w.message) for w in caught if "translate as one" in str(w.message)]
    assert (miss > solver.HOOK_MISS_NOTED) == far_off
    if far_off:
        assert len(said) == 1 and "9 vertices" in said[0] and f"{100 * miss:.0f} % of their piece's diagonal" in said[0]
    else:
        assert not said


def test_the_working_unit_reads_each_keys_largest_extent_as_numpys_peak_to_peak():
    """The keys' largest extent, which sets the working unit, reduced along contiguous coordinate
    rows, is NumPy's ``ptp`` along the first axis to the bit (contiguous keys, views of every other
    row, single precision, sizes from 2^-40 to 2^40 and a mesh flat in one coordinate), and so is
    the unit."""
    import math

    from core.working_unit import WORKING_EXTENT, _largest_extent, working_unit

    rng = np.random.default_rng(3)
    for exponent in (-40, -12, 0, 12, 40):
        keys = [rng.normal(size=(500, 3)) * 2.0 ** exponent + rng.normal(size=3) for _ in range(3)]
        keys[1] = keys[1][::2]
        keys[2] = keys[2].astype(np.float32)
        keys.append(np.column_stack([keys[0][:, :2], np.zeros(500)]))
        for k in keys:
            assert _largest_extent(k) == float(np.max(np.ptp(k, axis=0)))
        extent = max(float(np.max(np.ptp(k, axis=0))) for k in keys)
        expected = 1.0 if WORKING_EXTENT[0] <= extent <= WORKING_EXTENT[1] else math.ldexp(1.0, 1 - math.frexp(extent)[1])
        assert working_unit(keys) == expected


@pytest.mark.parametrize("scale", [1.0, 2.0 ** 20, 2.0 ** -20])
def test_a_translating_patch_off_its_path_is_said_in_the_callers_units(scale):
    """The swirled sheet above (swung 150°) given at ``scale`` × its size: keys outside
    :data:`core.working_unit.WORKING_EXTENT` are worked on scaled by a power of two, and the
    warning quotes how far the patch ends off its path as measured on the returned in-between, in
    the units the keys are given in (2^±20: the same share of the diagonal, the distance scaled
    with the keys)."""
    a, tri = grid(16, 12, size=1.5)
    patch = (a[:, 0] < 0.25) & (a[:, 1] < 0.25)
    distance = np.linalg.norm(a, axis=1)
    turn = np.radians(150.0) * np.clip((distance - 0.29) / 1.6, 0.0, 1.0)
    c, s = np.cos(turn), np.sin(turn)
    b = np.stack([c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1], a[:, 2]], axis=1) + np.array([0.3, 0.05, 0.1])
    a, b = a * scale, b * scale
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        interpolator = Interpolator(a, b, tri)
        x = interpolator.pose(0.5)
    assert (interpolator._sequence._unit == 1.0) == (scale == 1.0)
    miss = np.linalg.norm(np.mean(x[patch] - 0.5 * (a[patch] + b[patch]), axis=0))
    said = [str(w.message) for w in caught if "translate as one" in str(w.message)]
    assert len(said) == 1 and f"are {miss:.3g} (" in said[0]


@pytest.mark.parametrize("still", [False, True])
def test_a_translating_patch_off_its_path_names_the_centroid_move_only_where_it_was_made(still):
    """The swirled sheet above (swung 150°), its far corner held still in both poses or not. A
    piece with a still vertex keeps the place its fit gives it (no move onto its centroid's path,
    :data:`~core.inbetween_anchor.CENTROID_ANCHOR_SHARE`); its patch still ends far off its path
    (77 % of the diagonal) and the in-between says so, but not that the piece was placed by its
    centroid (before: said of every piece). Without the still corner it was moved (share 0.6) and
    says so."""
    a, tri = grid(16, 12, size=1.5)
    distance = np.linalg.norm(a, axis=1)
    turn = np.radians(150.0) * np.clip((distance - 0.29) / 1.6, 0.0, 1.0)
    c, s = np.cos(turn), np.sin(turn)
    b = np.stack([c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1], a[:, 2]], axis=1) + np.array([0.3, 0.05, 0.1])
    corner = int(np.argmax(distance))
    if still:
        b[corner] = a[corner]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        interpolator = Interpolator(a, b, tri)
        interpolator.pose(0.5)
    said = [str(w.message) for w in caught if "translate as one" in str(w.message)]
    gap = interpolator._sequence._gap(0)
    gap.select(0.5)
    assert len(said) == 1
    assert (gap.by_centroid[0] > 0.0) is not still
    assert ("placed by its centroid" in said[0]) is not still


def test_cloth_beside_a_pole_far_out_is_not_taken_for_riding():
    """100 units out, single-precision keys are spaced 7.6e-6 apart: a chain of cloth vertices
    that keeps its edges exactly but bends by up to 1.2e-3 rad (missing its best rigid motion by
    up to eight spacings, as cloth beside a rod that stops dead did) is cloth, a row carried rigidly is riding. A rigid set rounded misses by under
    two spacings; the chain passed at four times the tolerance (3 spacings) and was held rigid."""
    from core.mesh_topology import mesh_topology
    from core.pins import riding_vertices
    from core.coordinate_rounding import rounding_scale

    flat, tri = grid(20, size=1.0)
    rows = flat[:, 1].argsort(kind="stable").reshape(20, 20)  # rows of equal y, x ascending
    pole, chain = rows[19], rows[10, 5:13]
    edges = mesh_topology(tri, len(flat)).edges

    def key(k):
        x = flat + (flat - 0.5) * [0.01 * k, 0.01 * k, 0.0]  # the cloth stretches: its edges change
        x[pole] = flat[pole] + [0.1 * k, 0.0, 0.05 * k]  # carried rigidly
        bent = Rotation.from_rotvec([0.0, 0.0, 4e-4 * k])  # the chain bends at its middle, edges kept
        x[chain] = flat[chain]
        x[chain[4:]] = bent.apply(flat[chain[4:]] - flat[chain[3]]) + flat[chain[3]]
        return x

    for shift in (0.0, 100.0):
        keys = [(key(k) + shift).astype(np.float32).astype(np.float64) for k in range(4)]
        found = riding_vertices(keys, edges, np.zeros(len(flat), dtype=int), np.zeros(len(flat), dtype=bool),
                                rounding_scale(keys))
        assert [sorted(rows.tolist()) for rows in found] == [sorted(pole.tolist())]
