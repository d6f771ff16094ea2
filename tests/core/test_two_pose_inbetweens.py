"""In-betweens and exaggerations of two poses (core.two_pose_inbetweens; issue 3) on analytic
motions and a baked sheet; no bpy."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import ShapeDifferenceWarning
from core.two_pose_inbetweens import EXTRAPOLATED_GROWTH, Interpolator, interpolate
from inbetween_helpers import RIG_WORDS, _bend, _edge_deviation, _flipped, _normals, _roll
from meshes import grid


def test_exact_at_zero_and_one(strip):
    flat, tri = strip
    a, b = _bend(flat, 0.3), _bend(flat, 2.0)
    it = Interpolator(a, b, tri)
    np.testing.assert_allclose(it.pose(0.0), a, atol=1e-12)
    np.testing.assert_allclose(it.pose(1.0), b, atol=1e-12)
    # nearly 0 / 1: continuous (no jump when leaving the keys)
    np.testing.assert_allclose(it.pose(1e-6), a, atol=1e-5)
    np.testing.assert_allclose(it.pose(1 - 1e-6), b, atol=1e-5)


def test_a_sculpted_key_is_given_back_exactly_at_one():
    """A key sculpted with a soft brush moves the vertices at its falloff's tail by less than the
    distance within which a sequence's keys count a vertex as still (held where the first key has
    it): factors 0 and 1 are still the two poses as given, bit for bit (a smile's tail was
    3.8e-5 off the key at factor 1 on a head 2.3 across)."""
    flat, tri = grid(30, 30, size=1.0)
    bump = 0.05 * np.exp(-np.sum((flat[:, :2] - 0.5) ** 2, axis=1) / (2 * 0.08 ** 2))
    b = flat + bump[:, None] * [0.0, 0.0, 1.0]
    tail = (bump > 0) & (bump < 1e-5 * np.linalg.norm(np.ptp(flat, axis=0)))
    assert tail.any()  # vertices the sequence's check holds still
    it = Interpolator(flat, b, tri)
    np.testing.assert_array_equal(it.pose(1.0), b)
    np.testing.assert_array_equal(it.pose(0.0), flat)


def test_rigid_rotation_is_interpolated_rigidly():
    flat, tri = grid(12, 8, size=1.0)
    a = flat + np.array([0.2, -0.1, 0.05])
    rotation = Rotation.from_rotvec([0.3, -0.5, 1.6])  # ~97°
    center = a.mean(axis=0)
    b = (a - center) @ rotation.as_matrix().T + center
    mid = interpolate(a, b, tri, 0.5)
    expected = (a - center) @ Rotation.from_rotvec(0.5 * rotation.as_rotvec()).as_matrix().T + center
    np.testing.assert_allclose(mid, expected, atol=1e-8)
    chord = 0.5 * (a + b)
    assert _edge_deviation(chord, a, tri).mean() > 0.05  # the blend shrinks
    assert _edge_deviation(mid, a, tri).max() < 1e-8


def test_two_components_translating_and_turning_are_each_placed():
    """One sheet translating (anchored to the blend, which is exact for it) and one turning by 97°
    about its centroid (not anchored: placed by its centroid): both in-betweens are exact."""
    flat, tri = grid(8, 6, size=1.0)
    n = len(flat)
    rotation = Rotation.from_rotvec([0.3, -0.5, 1.6])
    sheet_a = flat + np.array([3.0, 0.0, 0.0])
    center = sheet_a.mean(axis=0)
    a = np.vstack([flat, sheet_a])
    b = np.vstack([flat + np.array([0.4, 0.2, -0.3]), (sheet_a - center) @ rotation.as_matrix().T + center])
    triangles = np.vstack([tri, tri + n])
    mid = interpolate(a, b, triangles, 0.5)
    half = Rotation.from_rotvec(0.5 * rotation.as_rotvec()).as_matrix()
    np.testing.assert_allclose(mid[:n], flat + np.array([0.2, 0.1, -0.15]), atol=1e-6)
    np.testing.assert_allclose(mid[n:], (sheet_a - center) @ half.T + center, atol=1e-6)


@pytest.mark.parametrize("factor", [0.25, 0.5, 0.75])
def test_bending_strip_in_betweens(strip, factor):
    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, np.pi)
    x = interpolate(a, b, tri, factor)
    assert np.isfinite(x).all()
    assert _edge_deviation(x, a, tri).mean() < 1e-3
    assert _flipped(x, a, b, tri) == 0
    truth = _bend(flat, factor * np.pi)
    chord = (1 - factor) * a + factor * b
    # the shape is the true bend (compare after removing placement)
    err = np.sqrt(np.mean(np.sum((x - x.mean(0) - (truth - truth.mean(0))) ** 2, axis=1)))
    err_chord = np.sqrt(np.mean(np.sum((chord - chord.mean(0) - (truth - truth.mean(0))) ** 2, axis=1)))
    assert err < 0.2 * err_chord


@pytest.mark.parametrize("factor", [1.5, -0.5])
def test_exaggeration_of_isometric_bend_keeps_edges(strip, factor):
    flat, tri = strip
    a, b = _bend(flat, 0.4), _bend(flat, 1.6)
    x = interpolate(a, b, tri, factor)
    lin = (1 - factor) * a + factor * b
    dev = _edge_deviation(x, flat, tri)
    assert dev.mean() < 0.01 and dev.max() < 0.03
    assert _edge_deviation(lin, flat, tri).mean() > 2 * dev.mean()  # linear extrapolation stretches


def test_rolling_sheet(strip):
    """A sheet rolled onto a cylinder, its end turned by 191°: the in-betweens keep edge lengths
    and no triangle faces against the sheet rolled part-way (its end, turned past a half turn,
    may face away from both keys half-way, as the interpolated rotations take it; read as flipped,
    a repair turned 18 triangles against the rolled sheet)."""
    flat, tri = grid(25, 10, size=2.0)
    a, b = _roll(flat, 0.0), _roll(flat, 0.5)
    for s in (0.25, 0.5, 0.75):
        x = interpolate(a, b, tri, s)
        assert np.isfinite(x).all()
        assert _edge_deviation(x, flat, tri).mean() < 0.01
        rolled = _roll(flat, 0.5 * s)
        assert _flipped(x, rolled, rolled, tri) == 0


def test_no_nan_or_flip_on_unrealizable_targets():
    flat, tri = grid(15, 15, size=1.0)
    rng = np.random.default_rng(3)
    a = _roll(flat, 0.3, radius=0.2)
    b = flat + 0.02 * rng.standard_normal(flat.shape)  # noisy, stretched, not isometric to a
    b[:, 2] += 0.3 * np.sin(3 * flat[:, 0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        for s in (0.3, 0.5, 0.8, 1.5):
            x = interpolate(a, b, tri, s)
            assert np.isfinite(x).all()
            if s <= 1:
                assert _flipped(x, a, b, tri) == 0


def test_fallback_warns(monkeypatch, strip):
    from core import sequence_inbetweens

    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 1.0)
    it = Interpolator(a, b, tri)
    real = sequence_inbetweens.Gap.fit

    def broken(self, x, *args, **kwargs):
        return np.full_like(x, np.nan)

    monkeypatch.setattr(sequence_inbetweens.Gap, "fit", broken)
    with pytest.warns(ShapeDifferenceWarning, match="non-finite"):
        x = it.pose(0.5)
    assert np.isfinite(x).all()
    monkeypatch.setattr(sequence_inbetweens.Gap, "fit", real)


def test_flipped_reconstruction_is_repaired_locally(monkeypatch, strip):
    """A reconstruction with a folded-over vertex is re-fitted with the interpolated rotations
    imposed around the defect (growing rings, only that region solved), not handed to a fallback;
    the keys' local geometry, imposed only after the other fields, is not made for it."""
    from core import sequence_inbetweens

    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 1.0)
    clean = Interpolator(a, b, tri).pose(0.5)
    real_fit, real_local = sequence_inbetweens.Gap.fit, sequence_inbetweens.Gap.local_fit
    forced = []

    def folding_fit(self, x, *args, **kwargs):
        out = real_fit(self, x, *args, **kwargs)
        i, j, k = tri[len(tri) // 2]
        out[i] = out[j] + out[k] - out[i]  # reflect a corner across its opposite edge
        return out

    def recording_local_fit(self, x, region, frames, stretch, guide):
        forced.append(region.rows.copy())
        return real_local(self, x, region, frames, stretch, guide)

    monkeypatch.setattr(sequence_inbetweens.Gap, "fit", folding_fit)
    monkeypatch.setattr(sequence_inbetweens.Gap, "local_fit", recording_local_fit)
    it = Interpolator(a, b, tri)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        x = it.pose(0.5)
    assert _flipped(x, a, b, tri) == 0
    assert forced and len(tri) // 2 in forced[0] and 1 < forced[0].size < len(tri) // 2
    assert np.abs(x - clean).max() < 1e-3 * np.ptp(clean, axis=0).max()
    assert not it._sequence._gap(0).repair._keys


def test_defective_candidates_keep_the_metric_fit(monkeypatch, strip):
    """If every candidate has defects, the metric fit with the fewest is returned, not the
    shrinking linear blend (even when the blend has fewer)."""
    import core.inbetween_repair as repair

    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 2.0)
    blend = 0.5 * (a + b)

    def defects(self, x, *args, rows=None, scale=None):
        out = np.zeros(len(tri), dtype=bool)
        out[:0 if np.allclose(x, blend) else 3] = True
        return out if rows is None else out[rows]

    monkeypatch.setattr(repair.Repair, "problem", lambda self, x, *args: "1 triangle(s) flipped")
    monkeypatch.setattr(repair.Repair, "defects", defects)
    with pytest.warns(ShapeDifferenceWarning, match="metric fit with the fewest"):
        x = Interpolator(a, b, tri).pose(0.5)
    assert _edge_deviation(x, flat, tri).mean() < 0.2 * _edge_deviation(blend, flat, tri).mean()


def _record_fits_near_the_blend(monkeypatch) -> list:
    """The fits made with the fallback's anchor system (near the blend), appended as they are made."""
    import core.inbetween_solver as solver

    near = []
    original_fit = solver.Gap.fit

    def fit(self, *args, **kwargs):
        x = original_fit(self, *args, **kwargs)
        if "system" in kwargs:
            near.append(x.copy())
        return x

    monkeypatch.setattr(solver.Gap, "fit", fit)
    return near


def _counted_defects(near: list, m: int, second_defects: int | None = None):
    """A stand-in for ``Repair.defects`` (m triangles): the linear blend has 1 flipped triangle,
    the fits near it (``near``; told apart by their vertices that are not pinned, as a fallback is
    checked with its pinned vertices put back: ``Repair.as_finished``) 2, any other fit 10 — and with
    ``second_defects``, every candidate of a whole-rotation fit that many."""
    def defects(self, x, *args, rows=None, scale=None):
        if second_defects is not None and self.gap.whole_rotations.all():
            count = second_defects
        else:
            inner_blend = 0.5 * (self.gap.base.vertices + self.gap.next.vertices)  # the gap's own coordinates
            free = slice(None) if self.gap.static is None else ~self.gap.static
            count = 1 if np.allclose(x, inner_blend) else \
                2 if any(np.array_equal(x[free], y[free]) for y in near) else 10
        out = np.zeros(m, dtype=bool)
        out[:count] = True
        return out if rows is None else out[rows]

    return defects


def test_two_poses_fall_back_to_the_metric_near_the_blend_where_the_blend_has_fewer_defects(monkeypatch, strip):
    """Two poses whose metric fit keeps more flipped triangles than the linear blend has (a cloth
    folding over as a corner drags it, keys 16 frames apart: 713 against the blend's 59): the
    interpolated metric fitted near the blend is tried and, having fewer than the fit (243 there;
    1.61 → 1.00 × the blend's RMS), returned with a warning that says so."""
    import core.inbetween_repair as repair

    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 2.0)
    blend = 0.5 * (a + b)
    near = _record_fits_near_the_blend(monkeypatch)

    defects = _counted_defects(near, len(tri))
    monkeypatch.setattr(repair.Repair, "problem", lambda self, x, *args: "1 triangle(s) flipped")
    monkeypatch.setattr(repair.Repair, "defects", defects)
    with pytest.warns(ShapeDifferenceWarning, match="fitted near the linear blend, which has the fewest"):
        x = Interpolator(a, b, tri).pose(0.5)
    assert near  # the fit near the blend ran, and keeps more of the metric than the blend does
    assert _edge_deviation(x, flat, tri).mean() < 0.7 * _edge_deviation(blend, flat, tri).mean()


@pytest.mark.parametrize("second_defects, reach, metric_reach, same_misfit, second_kept", [
    (1, None, None, False, True), (3, None, None, False, False), (1, 0.0, 0.0, False, False),
    (1, 0.0, None, False, True), (1, 0.0, None, True, False)])
def test_two_poses_held_near_the_blend_keep_the_second_fit_with_fewer_defects(monkeypatch, strip, second_defects,
                                                                               reach, metric_reach, same_misfit,
                                                                               second_kept):
    """Two poses whose first fit (residual rotations) fell back to the metric fitted near the blend
    with defects left: its distance from the blend says nothing of the motion, so the second fit
    (whole rotations), farther from the blend than WHOLE_FIT_BLEND_RATIO × it, is kept where it has
    fewer flipped or collapsed triangles (a flag draped over a sphere, keys 16 frames apart: 2,829
    → 104 flipped, 1.000 → 1.054 × the blend's RMS; a tablecloth pulled off a table, 8 apart: 144
    → 0, 1.000 → 0.886 ×), and not where it has more or strays farther from the blend than
    WHOLE_FIT_HELD_REACH of the keys' distance — unless it is within WHOLE_FIT_HELD_METRIC_REACH
    and nearer the interpolated metric than the held fit (a stiff flag swinging round its pole,
    keys 16 frames apart: 196–454 → 0–9 flipped, 0.995–0.997 → 0.63–0.98 ×); a second fit no nearer
    the metric (its misfit taken equal to the first's) is not kept beyond WHOLE_FIT_HELD_REACH."""
    import core.inbetween_repair as repair
    from core import two_pose_inbetweens

    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 2.0)
    blend = 0.5 * (a + b)
    near = _record_fits_near_the_blend(monkeypatch)

    defects = _counted_defects(near, len(tri), second_defects)
    monkeypatch.setattr(repair.Repair, "problem", lambda self, x, *args: "some triangle(s) flipped")
    monkeypatch.setattr(repair.Repair, "defects", defects)
    if reach is not None:
        monkeypatch.setattr(two_pose_inbetweens, "WHOLE_FIT_HELD_REACH", reach)
    if metric_reach is not None:
        monkeypatch.setattr(two_pose_inbetweens, "WHOLE_FIT_HELD_METRIC_REACH", metric_reach)
    if same_misfit:  # both fits equally far from the metric (and beyond the margin: the second is made)
        monkeypatch.setattr(Interpolator, "_misfit", lambda self, x, factor, log=None: 1.0)
    pair = Interpolator(a, b, tri)
    with pytest.warns(ShapeDifferenceWarning) as caught:
        x = pair.pose(0.5)
    assert pair._whole is not None  # the second fit was made ...
    origin = pair._sequence._origin
    held = near[-1] if origin is None else near[-1] + origin  # the first fit, in the poses' coordinates
    message = str(caught[0].message)
    if second_kept:  # ... farther from the blend than the guard allows a fit nearer the metric
        distance = [two_pose_inbetweens._rms(y - blend) for y in (held, x)]
        assert distance[1] > two_pose_inbetweens.WHOLE_FIT_BLEND_RATIO * distance[0]
        keys = two_pose_inbetweens._rms(b - a)
        if reach is None:
            assert distance[1] <= two_pose_inbetweens.WHOLE_FIT_HELD_REACH * keys
        else:  # beyond the reach of a fit with fewer defects alone: kept for its metric
            assert distance[1] <= two_pose_inbetweens.WHOLE_FIT_HELD_METRIC_REACH * keys
            assert pair._misfit(x, 0.5) < pair._misfit(held, 0.5) - two_pose_inbetweens.WHOLE_FIT_MARGIN
        assert "metric fit with the fewest" in message and "near the linear blend" not in message
        assert _edge_deviation(x, flat, tri).mean() < 0.5 * _edge_deviation(held, flat, tri).mean()
    else:
        np.testing.assert_array_equal(x, pair._sequence._poses(0, [0.5])[0][0])  # the first fit
        # what the in-between keeps first, the first fit's count after it
        assert "the in-between at factor 0.5: it is a fit near the keys' linear blend, which keeps 2 triangle(s) " \
            "flipped or collapsed, the fewest of its fits (its fit: some triangle(s) flipped; " in message, message
        assert caught[0].message.defects == 2
    first, second = pair._sequence._gap(0).outcomes[0.5], pair._whole_sequence()._gap(0).outcomes[0.5]
    assert first == (2, True) and second == (second_defects, False)


def test_two_poses_keep_the_second_fit_that_is_no_worse_on_anything_the_keys_tell():
    """Two keys of a baked cloth dragged across a table by a hooked corner, 16 frames apart
    (``dragged_cloth.npz``: frames 21 and 37 and the bake's frame 29 between them, single
    precision, 1,089 vertices): the whole-rotation fit has no more flipped or collapsed triangles
    than the first fit, its edge lengths are no farther from the interpolated metric (though
    nearer by less than WHOLE_FIT_MARGIN), and it lies nearer the linear blend by
    WHOLE_FIT_BLEND_RATIO. Nothing the keys tell favours the first fit, which half-way was 1.072 ×
    the blend's RMS error against the simulated frame; the second is kept, nearer the simulation
    than the blend."""
    from core import two_pose_inbetweens

    data = np.load(Path(__file__).parent / "data" / "dragged_cloth.npz")
    a, middle, b = data["frames"].astype(np.float64)
    tri = data["triangles"]
    blend = 0.5 * (a + b)
    pair = Interpolator(a, b, tri)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        x = pair.pose(0.5)
        (first,), _ = pair._sequence._poses(0, [0.5])
        (second,), _ = pair._whole_sequence()._poses(0, [0.5])
    rms = two_pose_inbetweens._rms
    # the case the rule is for: the second fit does not win by its metric alone
    assert pair._misfit(second, 0.5) <= pair._misfit(first, 0.5) < \
        pair._misfit(second, 0.5) + two_pose_inbetweens.WHOLE_FIT_MARGIN
    assert pair._whole_sequence()._gap(0).outcomes[0.5].defects <= pair._sequence._gap(0).outcomes[0.5].defects
    assert two_pose_inbetweens.WHOLE_FIT_BLEND_RATIO * rms(second - blend) <= rms(first - blend)
    np.testing.assert_array_equal(x, second)
    assert rms(x - middle) < rms(blend - middle)  # issue 17: two poses no farther than the blend


def test_two_poses_do_not_fall_back_to_a_blend_that_crushes_the_surface(monkeypatch, strip):
    """Two poses whose fits all keep defects while the linear blend has no flipped or collapsed
    triangle: a blend that crushes triangles below half their interpolated area where neither key
    does (a strip rolled up 5.5 rad: half-way the blend cuts the roll's chords, its triangles where
    the roll turns past 120° shrink to |cos(θ / 2)| of their area) is no safe fallback — the metric
    fitted near it is returned — while a blend that does not (a 2 rad bend) still is."""
    import core.inbetween_repair as repair

    flat, tri = strip
    for angle, crushes in ((5.5, True), (2.0, False)):
        a, b = _bend(flat, 0.0), _bend(flat, angle)
        blend = 0.5 * (a + b)
        blend_area = np.linalg.norm(_normals(blend, tri), axis=1) / np.linalg.norm(_normals(a, tri), axis=1)
        assert (blend_area.min() < repair.CRUSHED_AREA) == crushes  # the keys keep every area

        def defects(self, x, *args, rows=None, scale=None):
            inner_blend = 0.5 * (self.gap.base.vertices + self.gap.next.vertices)  # the gap's own coordinates
            out = np.zeros(len(tri), dtype=bool)
            out[:0 if np.allclose(x, inner_blend) else 3] = True
            return out if rows is None else out[rows]

        monkeypatch.setattr(repair.Repair, "problem", lambda self, x, *args: "3 triangle(s) flipped")
        monkeypatch.setattr(repair.Repair, "defects", defects)
        with pytest.warns(ShapeDifferenceWarning) as caught:
            x = Interpolator(a, b, tri).pose(0.5)
        message = str(caught[0].message)
        if crushes:
            assert "returned the linear blend" not in message
            assert _edge_deviation(x, flat, tri).mean() < 0.3 * _edge_deviation(blend, flat, tri).mean()
        else:
            assert "returned the linear blend" in message
            np.testing.assert_allclose(x, blend)
        monkeypatch.undo()


def test_two_poses_end_no_farther_from_the_interpolated_metric_than_the_blend():
    """Two poses 4 frames apart of a Blender cloth hanging from a rod that dashes and stops dead
    (every other row and column of its 130 × 90 vertices) and the simulated frame half-way: the
    interpolated rotations of its swing do not integrate, and their fit ended 10.8 % off the
    interpolated metric (squared edge lengths linear in the factor) where the linear blend is 5.1 %
    off and the frame 0.4 %, 5.1 × the blend's distance from the frame, with no warning. A fit that
    ends farther from the metric than the blend, beyond the fit's tolerance, gives way to the
    metric fitted near the blend."""
    data = np.load(Path(__file__).parent / "data" / "rod_sheet.npz")
    (a, b), middle, triangles = data["keys"].astype(np.float64), data["middle"].astype(np.float64), data["triangles"]
    blend = 0.5 * (a + b)

    def misfit(x):
        squared = [np.sum((p[triangles[:, [1, 2, 0]]] - p[triangles]) ** 2, axis=2) for p in (x, a, b)]
        return np.mean(np.abs(np.sqrt(squared[0] / (0.5 * (squared[1] + squared[2]))) - 1.0))

    x = Interpolator(a, b, triangles).pose(0.5)
    assert misfit(x) <= misfit(blend)
    assert np.sqrt(np.mean(np.sum((x - middle) ** 2, axis=1))) < np.sqrt(np.mean(np.sum((blend - middle) ** 2, axis=1)))


def test_two_poses_that_differ_by_wrinkles_only_are_blended():
    """Two poses of a sheet lying flat with different small wrinkles (heights of 0.3 mean edges,
    drawn independently per vertex): the keys' triangles turn with no coherence between
    neighbours, so half their turns is no motion of the sheet (a fit of it lay 1.23 × as far as
    the keys' linear blend from a third such frame). The in-between of such poses is the blend;
    a quarter-turn bend under the same wrinkles keeps its fit (nearer the bend's middle than half
    the blend's distance from it)."""
    flat, triangles = grid(40)
    edge = 1.0 / 39

    def wrinkled(seed, base=flat):
        out = base.copy()
        out[:, 2] += 0.3 * edge * np.random.default_rng(seed).standard_normal(len(base))
        return out

    def rms(x, y):
        return np.sqrt(np.mean(np.sum((x - y) ** 2, axis=1)))

    a, b = wrinkled(1), wrinkled(2)
    assert np.array_equal(Interpolator(a, b, triangles).pose(0.5), 0.5 * (a + b))
    strip = flat * [2.0, 1.0, 1.0]
    a, b = wrinkled(1, strip), wrinkled(2, _bend(strip, np.pi / 2))
    folded = _bend(strip, np.pi / 4)
    assert rms(Interpolator(a, b, triangles).pose(0.5), folded) < 0.5 * rms(0.5 * (a + b), folded)


def _said_flipped(messages) -> int:
    """The triangles the warnings ``messages`` say the in-between returned has turned over or
    flipped (not those of a fit it was not: ``its first fit: … triangle(s) flipped``)."""
    pattern = re.compile(r"(?<!fit: )\b(\d+) triangle\(s\)(?: \(e\.g\. triangle \d+\))? (?:are turned over|flipped)")
    return sum(int(count) for message in messages for count in pattern.findall(message))


def test_two_crumpled_poses_whose_blend_turns_triangles_over_are_not_blended_silently():
    """Two poses of a sheet crumpled independently (every vertex moved at random by 0.4 mean
    edges in each): neighbouring triangles turn unlike each other, so the pair reads as wrinkles
    alone (``_chattering``), whose in-between is the linear blend; but averaging the two crumples
    turns a triangle over against both poses. The in-between has no triangle flipped against
    both poses, or its warnings count them (the blend was returned with 1 flipped, unsaid)."""
    flat, triangles = grid(16)
    rng = np.random.default_rng(0)
    a, b = (flat + 0.4 / 15 * rng.standard_normal(flat.shape) for _ in range(2))
    interpolator = Interpolator(a, b, triangles)
    assert interpolator._chattering() and _flipped(0.5 * (a + b), a, b, triangles) > 0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        x = interpolator.pose(0.5)
    flipped = _flipped(x, a, b, triangles)
    assert flipped == 0 or _said_flipped(str(w.message) for w in caught) == flipped


def test_two_poses_warnings_say_flipped_only_of_triangles_flipped():
    """The tossed sheet landing (``tossed_sheet.npz``, frames 32 and 48) half-way has triangles
    facing against their interpolated rotation and one pose, said; none faces against both poses,
    and no warning says that any is turned over or flipped (they were said to be "turned over in
    the in-between", while a count of flipped triangles, against both poses, found none)."""
    data = np.load(Path(__file__).parent / "data" / "tossed_sheet.npz")
    a, b, tri = data["keys"][2].astype(np.float64), data["keys"][3].astype(np.float64), data["triangles"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        x = Interpolator(a, b, tri).pose(0.5)
    said = [str(w.message) for w in caught]
    assert any("face against their interpolated rotation" in message for message in said), said
    assert _said_flipped(said) == _flipped(x, a, b, tri), said


def test_repair_regions_stop_at_half_a_piece(monkeypatch, strip):
    """The repair rounds do not impose fields on regions beyond ``MAX_REPAIR_FRACTION`` of the
    triangles of any one piece of the mesh after the first round (that would replace the piece's
    pose, not repair it), and still try every round below it."""
    import core.inbetween_repair as repair
    from core import inbetween_repair_rounds
    from core import sequence_inbetweens

    flat, tri = strip
    two = np.vstack([flat, flat + [0.0, 2.0, 0.0]])  # two strips side by side: two pieces
    tris = np.vstack([tri, tri + len(flat)])
    a, b = _bend(two, 0.0), _bend(two, 1.0)
    regions, real_local = [], sequence_inbetweens.Gap.local_fit

    def defects(self, x, *args, rows=None, scale=None):
        out = np.zeros(len(tris), dtype=bool)
        out[len(tri) + len(tri) // 2] = True  # one defect in the second piece, no repair removes it
        return out if rows is None else out[rows]

    def local_fit(self, x, region, frames, stretch, guide):
        regions.append(region.rows.size)
        return real_local(self, x, region, frames, stretch, guide)

    monkeypatch.setattr(repair.Repair, "defects", defects)
    monkeypatch.setattr(repair.Repair, "problem", lambda self, x, *args: "1 triangle(s) flipped")
    monkeypatch.setattr(sequence_inbetweens.Gap, "local_fit", local_fit)
    with pytest.warns(ShapeDifferenceWarning, match="flipped"):
        Interpolator(a, b, tris).pose(0.5)
    assert regions and max(regions) <= inbetween_repair_rounds.MAX_REPAIR_FRACTION * len(tri)
    # without the limit the schedule grows beyond it: the limit is what stopped it
    regions.clear()
    monkeypatch.setattr(inbetween_repair_rounds, "MAX_REPAIR_FRACTION", 1.0)
    with pytest.warns(ShapeDifferenceWarning, match="flipped"):
        Interpolator(a, b, tris).pose(0.5)
    assert max(regions) > 0.5 * len(tri)


def test_no_fit_near_a_folded_blend(monkeypatch, strip):
    """When the linear blend is defective too, the metric is not fitted near it (a fit held near
    a folded blend keeps its folds): the metric fit with the fewest defects is returned at once."""
    import core.inbetween_repair as repair
    import core.inbetween_solver as solver

    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 2.0)

    def defects(self, x, *args, rows=None, scale=None):
        out = np.zeros(len(tri), dtype=bool)
        out[:3] = True  # every candidate, the blend included, keeps three defects
        return out if rows is None else out[rows]

    fits, real_fit = [], solver.Gap.fit
    monkeypatch.setattr(solver.Gap, "fit", lambda self, *args, **kwargs: fits.append(kwargs.get("system")) or
                        real_fit(self, *args, **kwargs))
    monkeypatch.setattr(repair.Repair, "problem", lambda self, x, *args: "3 triangle(s) flipped")
    monkeypatch.setattr(repair.Repair, "defects", defects)
    with pytest.warns(ShapeDifferenceWarning, match="metric fit with the fewest"):
        Interpolator(a, b, tri).pose(0.5)
    assert fits and all(system is None for system in fits)  # the pose's own fits only, none near the blend


def _folding_repairs(monkeypatch, tri, keep_fold):
    """Patch the fits so that a corner of the middle triangle is reflected after the first fit
    and after every repair fit for which ``keep_fold(frames, rows)`` is true (``frames``
    (k ≥ 2, r, 3): the imposed rotations' images of the base frames of the region's triangles
    ``rows``)."""
    from core import sequence_inbetweens

    real_fit, real_local = sequence_inbetweens.Gap.fit, sequence_inbetweens.Gap.local_fit
    i, j, k = tri[len(tri) // 2]

    def fold(out):
        out[i] = out[j] + out[k] - out[i]
        return out

    monkeypatch.setattr(sequence_inbetweens.Gap, "fit", lambda self, x, *args, **kwargs: fold(real_fit(self, x, *args, **kwargs)))

    def local_fit(self, x, region, frames, stretch, guide):
        out = real_local(self, x, region, frames, stretch, guide)
        return fold(out) if keep_fold(frames, region.rows) else out

    monkeypatch.setattr(sequence_inbetweens.Gap, "local_fit", local_fit)


def test_blend_geometry_is_spliced_where_the_interpolated_rotations_fold(monkeypatch, strip):
    """When imposing the interpolated rotations cannot remove a fold, the linear blend's local
    geometry is imposed around it: no fallback, no flip, and the metric is kept elsewhere."""
    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 1.0)
    segment = Interpolator(a, b, tri)._sequence._gap(0)
    interpolated = segment.targets(0.5)[0]
    _folding_repairs(monkeypatch, tri, lambda frames, rows: np.allclose(frames[:2], interpolated[:2, rows]))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        x = segment.pose(0.5)[0]
    blend = 0.5 * (a + b)
    assert _flipped(x, a, b, tri) == 0
    assert _edge_deviation(x, flat, tri).mean() < 0.2 * _edge_deviation(blend, flat, tri).mean()


def test_a_key_geometry_is_spliced_where_the_blend_folds_too(monkeypatch, strip):
    """When neither the interpolated nor the blend's rotations remove a fold, a key's own local
    geometry (here the first key's: identity relative to it) is imposed around it."""
    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 1.0)
    segment = Interpolator(a, b, tri)._sequence._gap(0)
    base_frames = segment.base.column_rows.transpose(0, 2, 1)  # the first key's own rotations: identity
    _folding_repairs(monkeypatch, tri, lambda frames, rows: not np.allclose(frames[:2], base_frames[:2, rows]))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        x = segment.pose(0.5)[0]
    assert _flipped(x, a, b, tri) == 0
    assert _edge_deviation(x, flat, tri).mean() < 0.2 * _edge_deviation(0.5 * (a + b), flat, tri).mean()


def test_truncated_inbetween_approaches_the_full_basis_one(strip):
    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 1.5)
    full = Interpolator(a, b, tri).pose(0.5)
    extent = np.ptp(full, axis=0).max()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        errors = [np.abs(Interpolator(a, b, tri, k_M=k).pose(0.5) - full).max() / extent
                  for k in (20, len(flat) - 1)]
    assert not [w for w in caught if "truncated recovery" in str(w.message)]  # no full-basis fallback
    assert errors[1] < 1e-3 and errors[1] < errors[0]


def test_a_fallback_that_returns_the_blend_says_so(monkeypatch, strip):
    """Two poses whose fits all keep defects, the blend clean and the fit near it making no step:
    the pose returned is the blend and the warning says the blend (before: "the interpolated metric
    fitted near the linear blend" for the blend itself)."""
    import core.inbetween_repair as repair
    import core.inbetween_solver as solver

    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 2.0)
    middle = 0.5 * (a.min(axis=0) + a.max(axis=0))
    a, b = a - middle, b - middle
    blend = 0.5 * (a + b)

    def defects(self, x, *args, rows=None, scale=None):
        out = np.zeros(len(tri), dtype=bool)
        out[:0 if np.allclose(x, blend) else 3] = True
        return out if rows is None else out[rows]

    real_fit = solver.Gap.fit
    monkeypatch.setattr(solver.Gap, "fit", lambda self, x, *args, **kwargs: x if np.allclose(x, blend) else
                        real_fit(self, x, *args, **kwargs))
    monkeypatch.setattr(repair.Repair, "problem", lambda self, x, *args: None if np.allclose(x, blend) else "3 flipped")
    monkeypatch.setattr(repair.Repair, "defects", defects)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        x = Interpolator(a, b, tri).pose(0.5)
    text = " ".join(str(w.message) for w in caught)
    np.testing.assert_allclose(x, blend)
    assert "the keys' linear blend (no fit near it improved on it)" in text and "fitted near" not in text


def test_a_reversed_sliver_keeps_its_size_and_a_stretch_that_swells_is_warned():
    """A sheet bent in its second pose, where one triangle is also left a sliver 1e-7 (or 1e-3)
    off its line, under the fits' floor of 1 % of the mean edge: reversing the motion (factor
    −0.5), the sliver keeps its size in the nearer pose (raised to the factor's power, its stretch
    swelled the sheet 259 × (3.2 ×), warned), so no edge of the reversed sheet comes out as long as
    the growth warning's EXTRAPOLATED_GROWTH × its length in either pose (1.12 × measured), and
    nothing is said. A stretch the poses do tell (the sheet drawn out 3 × along x in the second
    pose) swells at ×2, as the metric's power says (9 × against 3 ×), and is warned so."""
    a, tri = grid(6, 6)
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])

    def lengths(x):
        return np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)

    for height in (1e-7, 1e-3):
        b = a.copy()
        b[:, 2] += 0.1 * a[:, 0] ** 2
        b[7] = 0.5 * (b[1] + b[6])
        b[7, 2] += height
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            x = Interpolator(a, b, tri).pose(-0.5)
        assert (lengths(x) < EXTRAPOLATED_GROWTH * np.maximum(lengths(a), lengths(b))).all(), height
        assert not [str(w.message) for w in caught if "as long as in either pose" in str(w.message)], height
    b = a.copy()
    b[:, 0] *= 3.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Interpolator(a, b, tri).pose(2.0)
    said = [str(w.message) for w in caught if "as long as in either pose" in str(w.message)]
    assert said and "stretch between the poses to the factor's power" in said[0], said


def test_edges_the_fit_alone_grows_are_not_blamed_on_the_metric():
    """A grid pulled up by a hook on a cone of weights reaching its border (a Hook modifier's
    falloff): every edge of the pulled pose is at most 2.04 × its rest length, so the metric
    exaggerated to 1.5 keeps every edge within 2.04^0.5 ≈ 1.43 × the longer pose's. The fit at 1.5
    still makes a few edges near the border over 2 × as long (its extrapolated rotations and
    stretches do not fit together there): the warning says so, and does not send the user after
    triangles "nearly collapsed (or stretched) in one pose", which none is (it did before)."""
    a, tri = grid(28, size=2.0)
    a[:, :2] -= 1.0
    b = a.copy()
    b[:, 2] = 0.8 * np.clip(1.0 - np.hypot(a[:, 0] + 0.6, a[:, 1] + 0.6) / 0.45, 0.0, 1.0)
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    ratio = np.linalg.norm(b[edges[:, 0]] - b[edges[:, 1]], axis=1) / np.linalg.norm(a[edges[:, 0]] - a[edges[:, 1]], axis=1)
    assert ratio.min() >= 1.0 and ratio.max() ** 0.5 < 1.5  # the metric at 1.5: within 2 × of either pose
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Interpolator(a, b, tri).pose(1.5)
    said = [str(w.message) for w in caught if "as long as in either pose" in str(w.message)]
    assert len(said) == 1, said
    assert "the extrapolated metric keeps them within 2 ×" in said[0], said
    assert "to the factor's power" not in said[0], said


def test_the_second_fit_of_two_poses_keeps_no_turned_frames(strip):
    """Two poses bent far apart: the second fit (rotations taken whole, WHOLE_FIT_MARGIN) takes
    its relative's rotations whole without asking whether the residuals add turn, so its
    whole_rotations lets the constructor's turned frames go (72 bytes per triangle held for the
    interpolator's life otherwise), with the same rotations as frames turned anew."""
    import core.deformation_fields as df
    from core import rotation_continuity

    flat, tri = strip
    rng = np.random.default_rng(0)
    a, b = _bend(flat, 0.2) + 0.01 * rng.normal(size=flat.shape), _bend(flat, 5.5) + 0.01 * rng.normal(size=flat.shape)
    pair = Interpolator(a, b, tri)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        pair.pose(0.5)
    assert pair._whole is not None  # the second fit was made
    gap = pair._whole_sequence()._gap(0)
    assert gap.whole_rotations.all()
    assert all(r._plane_frames is None for r in gap.relatives)
    relative, key, other = gap.relatives[2], gap.base, gap.next
    frames = df.plane_turned_frames(other.column_rows, relative.turn)
    # taken continuous across the strip (past a half turn) as the relative takes them, to rounding
    turned = rotation_continuity.continuous_rotation_vectors(df.frame_rows_rotation_vectors(frames, key.column_rows),
                                                             relative._across, gap.topo.triangle_component)
    np.testing.assert_allclose(relative.rotvec, turned, rtol=0.0, atol=1e-12)


def test_a_second_fit_starts_from_the_relative_the_first_built_and_gives_the_same_pose(strip, monkeypatch):
    """Two poses bent far apart, fitted twice (the second with its rotations taken whole): the
    second fit reuses the relative of the second pose the first built (it depends on the poses
    alone, and no reader changes it in place), so that relative is built once per pair, not once
    per fit (twice before); and the pose is the same to the bit as where the second fit builds its
    own."""
    import core.inbetween_keys as inbetween_keys

    flat, tri = strip
    rng = np.random.default_rng(0)
    a, b = _bend(flat, 0.2) + 0.01 * rng.normal(size=flat.shape), _bend(flat, 5.5) + 0.01 * rng.normal(size=flat.shape)
    built, real_init = [], inbetween_keys.Relative.__init__

    def counted(self, topo, base, other, *args, **kwargs):
        built.append((base, other))
        real_init(self, topo, base, other, *args, **kwargs)

    monkeypatch.setattr(inbetween_keys.Relative, "__init__", counted)
    pair = Interpolator(a, b, tri)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        x = pair.pose(0.5)
    assert pair._whole is not None  # the second fit was made
    first, second = pair._sequence._key(0), pair._sequence._key(1)
    assert sum(base is first and other is second for base, other in built) == 1
    real_variant = Interpolator._variant

    def own(source, **flags):  # a variant that builds its own relative, as each did before
        variant = real_variant(source, **flags)
        variant._forwards.clear()
        return variant

    monkeypatch.setattr(Interpolator, "_variant", staticmethod(own))
    fresh = Interpolator(a, b, tri)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        np.testing.assert_array_equal(fresh.pose(0.5), x)


def test_slivers_folded_over_between_two_poses_are_repaired_or_warned():
    """Two poses 16 frames apart of a Blender cloth hanging from two corners whose middle is a band
    of 20:1 slivers (100 columns, 10,000 vertices; frames 4 and 20, and the simulated frame 12):
    two slivers fold over by 154° between the keys and the interpolated rotations read them the
    long way round, so half-way they face away from both keys, as neither the blend nor the
    simulated frame has them. A triangle keeps its edge lengths whatever its normal does, so only
    a part turning a whole ring of triangles around a vertex is let through as turning: the
    in-between has no triangle facing against both keys that the blend does not, or says so, and
    stays nearer the simulated frame than the blend."""
    data = np.load(Path(__file__).parent / "data" / "sliver_band.npz")
    (a, b), middle, triangles = data["keys"].astype(np.float64), data["middle"].astype(np.float64), data["triangles"]
    blend = 0.5 * (a + b)

    def normals(x):
        return np.cross(x[triangles[:, 1]] - x[triangles[:, 0]], x[triangles[:, 2]] - x[triangles[:, 0]])

    def against_both(x):
        n = normals(x)
        return (np.einsum("ij,ij->i", n, normals(a)) < 0) & (np.einsum("ij,ij->i", n, normals(b)) < 0)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        x = Interpolator(a, b, triangles).pose(0.5)
    warned = any(issubclass(w.category, ShapeDifferenceWarning) for w in caught)
    assert warned or not (against_both(x) & ~against_both(blend)).any()
    assert np.sqrt(np.mean(np.sum((x - middle) ** 2, axis=1))) < np.sqrt(np.mean(np.sum((blend - middle) ** 2, axis=1)))


def test_a_landing_sheet_turned_over_against_its_field_is_told_in_terms_of_its_surface():
    """Two keys of a baked sheet tossed while it crumples, 16 frames apart as it lands
    (``tossed_sheet.npz``, frames 32 and 48): half-way, triangles that both keys face the same way
    are turned over against one of them, and said so. The warning names a triangle that does face
    against one key and with the other, counts no more than the in-between has, and describes the
    surface in terms true of a cloth: no character rig's (a skin, a weight ramp)."""
    data = np.load(Path(__file__).parent / "data" / "tossed_sheet.npz")
    a, b, tri = data["keys"][2].astype(np.float64), data["keys"][3].astype(np.float64), data["triangles"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        x = Interpolator(a, b, tri).pose(0.5)
    said = [str(w.message) for w in caught if "face them the same way" in str(w.message)]
    assert len(said) == 1, [str(w.message) for w in caught]
    count, triangle = map(int, re.search(r"(\d+) triangle\(s\) \(e\.g\. triangle (\d+)\) face against their "
                                         "interpolated rotation and one pose", said[0]).groups())
    facing = [np.einsum("ij,ij->i", _normals(x, tri), _normals(key, tri)) < 0 for key in (a, b)]
    same_way = np.einsum("ij,ij->i", _normals(a, tri), _normals(b, tri)) > 0
    turned = same_way & (facing[0] != facing[1])
    assert turned[triangle] and 1 <= count <= np.count_nonzero(turned)
    assert "surface" in said[0] and not RIG_WORDS.search(said[0]), said[0]
