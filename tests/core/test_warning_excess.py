"""``ShapeDifferenceWarning.excess`` of the warnings that measure something against an allowance
(docs/errors.md, *Warnings*): the measure the message says ÷ the allowance, so a pipeline (and an
operator's last line, ``operators.base.look_first``) can rank them without parsing the text."""

import re
import warnings
from types import SimpleNamespace

import numpy as np

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
