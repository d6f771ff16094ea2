"""``ShapeDifferenceWarning.excess`` of the warnings that measure something against an allowance
(docs/errors.md, *Warnings*): the measure the message says ÷ the allowance, so a pipeline (and an
operator's last line, ``operators.base.look_first``) can rank them without parsing the text."""

import re
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import core
import core.truncated_recovery
from core.reference_shape import differences_reference

from test_hostile_inputs import sheet  # noqa: F401 — the fixture: a jittered 6 × 6 sheet and its drape


def _edges(triangles):
    """The mesh's undirected edges (E, 2), from its triangles alone."""
    pairs = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    return np.unique(pairs, axis=0)


def test_a_reconstruction_missing_its_edge_lengths_says_by_how_much_past_the_tolerance(sheet):
    """A placed pose whose worst edge is off the recovered lengths by several percent against the 0.1 %
    allowed (``REALIZATION_TOLERANCE``) has an excess of that miss ÷ 0.1 %, the miss measured here
    from the triangles' edges; it was 0 (a measure and an allowance, unranked)."""
    v, t, _ = sheet
    reference = differences_reference(v, t, core.shape_differences(v, v, t))
    metric = SimpleNamespace(base=SimpleNamespace(squared_lengths=reference.topology.squared_edge_lengths(v)))
    placed = v.copy()
    placed[14] += [0.0, 0.0, 0.1]  # an inner vertex lifted out of the sheet: its edges lengthen
    edges = _edges(t)
    rest, moved = (np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1) for p in (v, placed))
    miss = float(np.max(np.abs(moved - rest) / rest))
    assert miss > 10 * core.REALIZATION_TOLERANCE
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        core._warn_unrealized(reference, metric, placed)
    (warning,) = [w.message for w in caught if "misses the edge lengths" in str(w.message)]
    np.testing.assert_allclose(warning.excess, miss / core.REALIZATION_TOLERANCE, rtol=1e-9)


def test_an_area_program_stopped_short_says_by_how_much_past_its_tolerance(sheet, monkeypatch):
    """The truncated area program stopped after one conjugate-gradient iteration: its warning names
    the residual reached and the tolerance asked for, and its excess is their ratio (0 before)."""
    v, t, target = sheet
    monkeypatch.setattr(core.truncated_recovery, "CG_MAX_ITERATIONS", 1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        core.reconstruct(v, t, core.shape_differences(v, target, t, k_M=12, k_N=12))
    said = [w.message for w in caught if "recovered only to a relative residual" in str(w.message)]
    assert said
    for warning in said:
        residual, tolerance = map(float, re.search(r"residual of (\S+), not (\S+):", str(warning)).groups())
        assert tolerance == core.truncated_recovery.CG_TOLERANCE
        np.testing.assert_allclose(warning.excess, residual / tolerance, rtol=0.06)  # the message's 2 digits
        assert warning.excess > 1.0


def test_an_opened_seam_s_excess_is_how_much_farther_apart_than_in_the_keys_over_the_opening_allowed():
    """:meth:`NearSeams.opening`: of the pairs a pose opens (farther apart than ``allowed``), the
    most one lies farther apart than in the keys (``apart``) ÷ the opening allowed it (``allowed −
    apart``): a pair 0.01 apart in the keys, allowed 0.02 and opened to 0.05, is 4 × past; one 0
    apart, allowed 0.02 and opened to 0.03, 1.5 ×; one a key has apart (allowed: infinite) is not
    opened whatever its distance. The widest pair is the first. (The opening had no excess: its
    warning's was 0.)"""
    from core.near_seams import NearSeams

    x = np.array([[0.0, 0, 0], [0.05, 0, 0], [1.0, 0, 0], [1.03, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    seams = NearSeams(a=np.array([0, 2, 4]), b=np.array([1, 3, 5]), apart=np.array([[0.01, 0.0, 0.5]]),
                      allowed=np.array([[0.02, 0.02, np.inf]]), every=np.array([True, True, False]))
    count, widest, pair, excess = seams.opening(x, 0)
    assert (count, pair) == (2, 0)
    assert widest == pytest.approx(0.05)
    assert excess == pytest.approx(max((0.05 - 0.01) / (0.02 - 0.01), 0.03 / 0.02))
    assert seams.opening(x * 0.1, 0) == (0, 0.0, -1, 0.0)  # nothing opened: no excess


def test_a_seam_the_in_betweens_open_is_warned_past_its_allowance(monkeypatch):
    """The sewn sheet of test_seams.py whose gaps cannot join the seam (every group dropped): the
    gap that opens it warns with an excess over 1 (0 before, so an operator's last line never named
    it, however wide it opened)."""
    import core.sequence_inbetweens as sequence_inbetweens
    from test_seams import _cut, _opened_and_warned, _waving_sheet

    monkeypatch.setattr(sequence_inbetweens, "gap_groups", lambda *args: None)
    keys, tri = _waving_sheet()
    cut_keys, cut_tri, seam, copies = _cut(keys, tri)
    right = np.unique(cut_tri[keys[0][tri].mean(axis=1)[:, 0] > 0.5])
    sewn = [k.copy() for k in cut_keys]
    for k, shift in zip(sewn, [0.3, 0.3, 1e-4, 1e-4, 1e-4]):
        k[right] += [shift, 0.0, 0.0]
    said = [message for _, _, messages in _opened_and_warned(core.SequenceInterpolator(sewn, cut_tri),
                                                               np.arange(1, 8) / 8, seam, copies) for message in messages]
    assert said and all(message.kind == "seam" and message.excess > 1.0 for message in said)


def test_a_sliver_s_excess_is_the_least_height_allowed_over_the_thinnest(monkeypatch):
    """The slivered sphere of test_placement_rigid_motions.py (slivers 1e-5 high) turned 30° 1,000
    units from the origin in single precision: its ``sliver`` warning's excess is twice the keys'
    rounding (``ROUNDED_SLIVER``) ÷ the smallest height of a triangle in the gap's keys, measured
    here from the keys as given (doubled area ÷ longest side). It was 0."""
    import core.inbetween_fit as inbetween_fit
    from core.coordinate_rounding import coordinate_rounding
    from scipy.spatial.transform import Rotation
    from test_placement_rigid_motions import _screw, _slivered_sphere

    monkeypatch.setattr(inbetween_fit, "UNTOLD_HEIGHT", 0.0)  # every sliver keeps its own targets, so is counted
    vertices, triangles = _slivered_sphere(1e-5)
    rotation = Rotation.from_rotvec(np.radians(30.0) * np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2]))
    keys = [_screw(vertices + 1000.0, rotation.as_matrix(), np.zeros(3), s).astype(np.float32) for s in (0.0, 1.0, 2.0)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        core.SequenceInterpolator(keys, triangles).pose(0, 0.5)
    (warning,) = [w.message for w in caught if getattr(w.message, "kind", None) == "sliver"]
    heights = []
    for key in keys[:2]:
        corners = key.astype(np.float64)[triangles]
        sides = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2)
        area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
        heights.append(2.0 * area / sides.max(axis=1))
    rounding = coordinate_rounding(keys)  # single precision: every coordinate a float32
    assert warning.excess > 1.0
    np.testing.assert_allclose(warning.excess, 2.0 * rounding / np.min(heights), rtol=1e-6)


def test_joint_warnings_say_their_measure_over_what_their_rule_allows():
    """Eight interlocked chain links (test_placement_joints.py) clearing each other by 0.08, curled
    through four keys: the first gap's links apart stay 1.1 edge lengths from each other where they
    meet, where joints are found within one (excess that gap ÷ the contact reach, at least the
    message's edge lengths and over 1); the later gaps' joints in a loop place links 0.9 % and 12 %
    of a link from their own joint's path, where 0.1 % is warned past (excess the message's share ÷
    0.1 %, to its two digits). They were 0."""
    from test_placement_joints import _torus_chain

    tri = _torus_chain(0.0, 0.08)[1]
    sequence = core.SequenceInterpolator([_torus_chain(float(k), 0.08)[0] for k in range(4)], tri, start="keys")
    for gap in range(3):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            sequence.poses(gap, (0.25, 0.5, 0.75))
        (warning,) = [w.message for w in caught if getattr(w.message, "kind", None) == "joint"]
        text = str(warning)
        edges = re.search(r"stay up to (\S+) edge lengths", text)
        if edges:
            assert warning.excess > 1.0 and warning.excess >= float(edges.group(1)) - 0.05
        else:
            share = float(re.search(r"place them up to (\S+) % of a piece's size", text).group(1))
            np.testing.assert_allclose(warning.excess, share / 100 / 1e-3, rtol=0.06)
            assert warning.excess > 1.0


def test_a_part_spun_back_says_its_share_over_the_share_warned_past():
    """Two poses of a wrinkled skirt whose hem spins 330° from its waist (test_spun_parts.py): the
    in-between that turns it back the short way round says what share of the piece's area spins
    on, and its excess is that share ÷ the 10 % warned past (``TURNED_PART_SHARE``), to the
    message's whole percent. It was 0."""
    from test_spun_parts import _skirt

    a, b = (_skirt(spin, 0.05, seed)[0] for seed, spin in enumerate(np.radians([60.0, 330.0]), 1))
    triangles = _skirt(0.0)[1]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        core.Interpolator(a, b, triangles).pose(0.5)
    said = [w.message for w in caught if "spins on more than a half turn" in str(w.message)]
    assert said
    for warning in said:
        share = float(re.search(r"(\d+) % of a piece's area spins", str(warning)).group(1))
        assert abs(warning.excess - share / 10.0) <= 0.05 + 1e-9
        assert warning.excess > 1.0


def test_an_exaggeration_s_growth_warning_says_its_growth_over_the_growth_allowed():
    """The grid a hook pulls up (test_two_pose_inbetweens.py), exaggerated to 1.5: the fit makes a
    few edges over 2 × as long as in either pose; the warning's excess is the most an edge grew,
    measured here on the pose (its length ÷ the longer of the two poses'), ÷ 2
    (``EXTRAPOLATED_GROWTH``). It was 0."""
    from meshes import grid

    a, tri = grid(28, size=2.0)
    a[:, :2] -= 1.0
    b = a.copy()
    b[:, 2] = 0.8 * np.clip(1.0 - np.hypot(a[:, 0] + 0.6, a[:, 1] + 0.6) / 0.45, 0.0, 1.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        x = core.Interpolator(a, b, tri).pose(1.5)
    (warning,) = [w.message for w in caught if "as long as in either pose" in str(w.message)]
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    length = lambda p: np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1)  # noqa: E731
    growth = float(np.max(length(x) / np.maximum(length(a), length(b))))
    assert growth > 2.0
    np.testing.assert_allclose(warning.excess, growth / 2.0, rtol=1e-9)


def test_warnings_that_measure_nothing_against_an_allowance_keep_no_excess():
    """A rigid mesh turned exactly a half turn between two keys: nothing in the keys tells which
    way round (test_placement_half_turns.py), a warning with no measure: its excess stays 0, so
    the operators rank it below any warning past an allowance."""
    from meshes import grid

    flat, tri = grid(6, 5, size=1.0)
    turned = flat @ np.diag([-1.0, -1.0, 1.0])  # 180° about z
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        core.SequenceInterpolator([flat, turned], tri).pose(0, 0.5)
    said = [w.message for w in caught if "half turn (180°)" in str(w.message)]
    assert said and all(warning.kind == "turn" and warning.excess == 0.0 for warning in said)
