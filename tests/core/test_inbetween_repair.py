"""Repairs of in-betweens of a sequence (core.inbetween_repair and its parts: the defects checked,
parts turning away from both keys, repair rounds and regions; issue 17) on analytic motions; no
bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import ShapeDifferenceWarning
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator
from inbetween_helpers import _bend, _edge_deviation, _flipped, _normals, _strip


def test_sequence_in_between_keeps_the_metric_fit_when_only_the_blend_is_clean(monkeypatch, strip):
    """An in-between of a sequence whose repairs all keep defects is the metric fit with the
    fewest, even when the linear blend has none: its neighbours in time are fits, and the blend
    (or a fit held near it) would jump away from them and back. No fit near the blend is tried.
    Two poses still fall back to the clean blend (they are held to its error); extrapolations keep
    the metric fit too (beyond the keys the blend is the linear extrapolation, which lengthens
    whatever turns)."""
    import core.inbetween_repair as repair
    import core.inbetween_solver as solver

    flat, tri = strip
    a, b, c = _bend(flat, 0.0), _bend(flat, 2.0), _bend(flat, 3.0)
    middle = 0.5 * (a.min(axis=0) + a.max(axis=0))  # keyed about the origin: sequences work about
    a, b, c = a - middle, b - middle, c - middle  # the first key's middle, and the mocks see positions
    blend, extrapolation = 0.5 * (a + b), -0.5 * a + 1.5 * b

    def clean(x):  # only the blend (and the linear extrapolation at 1.5) are clean
        return np.allclose(x, blend) or np.allclose(x, extrapolation)

    def defects(self, x, *args, rows=None, **kwargs):
        out = np.zeros(len(tri), dtype=bool)
        out[:0 if clean(x) else 3] = True
        return out if rows is None else out[rows]

    def problem(self, x, *args):
        return None if clean(x) else "3 triangle(s) flipped"

    near_blend, real_fit = [], solver.Gap.fit  # fits started from the blend: the fallback's
    monkeypatch.setattr(solver.Gap, "fit", lambda self, x, *args, **kwargs: near_blend.append(clean(x)) or
                        real_fit(self, x, *args, **kwargs))
    monkeypatch.setattr(repair.Repair, "problem", problem)
    monkeypatch.setattr(repair.Repair, "defects", defects)
    # the warnings name the gap by its keys, as the caller named them (the operators' frames)
    with pytest.warns(ShapeDifferenceWarning, match="between key pose 0 and key pose 1, the in-between at factor "
                      "0.5: it keeps 3 triangle.s. flipped or collapsed, the fewest of its fits") as said:
        x = SequenceInterpolator([a, b, c], tri).pose(0, 0.5)
    # the triangles it keeps flipped, for a pipeline (and the operators' summary) to rank by
    assert [(w.message.kind, w.message.defects) for w in said if "keeps 3" in str(w.message)] == [("pose", 3)]
    assert near_blend and not any(near_blend)
    assert _edge_deviation(x, flat, tri).mean() < 0.2 * _edge_deviation(blend, flat, tri).mean()
    # two poses fall back to the blend: the message leads with what the in-between is, then the fit's defects
    with pytest.warns(ShapeDifferenceWarning, match="between vertices_a and vertices_b, the in-between at factor 0.5: "
                      "it is the keys' linear blend, with no triangle flipped or collapsed but edges short where "
                      r"the cloth turns \(its fit: 3 triangle.s. flipped, which neither") as said:
        x = Interpolator(a, b, tri).pose(0.5)
    assert [w.message.defects for w in said if "linear blend" in str(w.message)] == [0]
    np.testing.assert_allclose(x, blend)
    assert any(near_blend)
    with pytest.warns(ShapeDifferenceWarning, match="between vertices_a and vertices_b, the pose at factor "
                      "1.5: it keeps 3 triangle.s. flipped or collapsed, the fewest") as said:
        x = Interpolator(a, b, tri).pose(1.5)
    assert [(w.message.kind, w.message.defects) for w in said if "keeps 3" in str(w.message)] == [("pose", 3)]
    assert _edge_deviation(x, flat, tri).mean() < 0.2 * _edge_deviation(extrapolation, flat, tri).mean()


@pytest.mark.parametrize("shift, kept", [(1e-3, True), (5.0, False)])
def test_sequence_repairs_do_not_jump(monkeypatch, strip, shift, kept):
    """A repair of a sequence's in-between that moves the pose further than ``MAX_REPAIR_MOVE`` of
    the keys' move across the gap (and more than a mean edge length) is not taken, even when
    defect-free: the neighbouring in-betweens would not follow. A small one is; two poses take
    either, and warn (kind fit) of the large one's edges, stretched far past the keys'."""
    import core.inbetween_repair as repair
    from core import sequence_inbetweens

    flat, tri = strip
    a, b, c = _bend(flat, 0.0), _bend(flat, 1.0), _bend(flat, 1.5)
    offset = shift * np.ptp(flat, axis=0).max()  # the strip is 2 long: a 4 mm or a 10 m lift
    fit = []  # the pose the repairs start from

    def moved(x):
        return bool(fit) and np.abs(x - fit[0]).max() > 0.5 * offset

    def defects(self, x, *args, rows=None, **kwargs):
        out = np.zeros(len(tri), dtype=bool)
        out[len(tri) // 2] = not moved(x)  # one defect, gone from any repair
        return out if rows is None else out[rows]

    def local_fit(self, x, region, frames, stretch, guide):
        fit[:] = fit or [x.copy()]
        z = x.copy()
        z[region.free, 2] += offset  # the region lifted
        return z

    monkeypatch.setattr(repair.Repair, "defects", defects)
    monkeypatch.setattr(repair.Repair, "problem", lambda self, x, *args: None if moved(x) else "1 triangle(s) flipped")
    # the checks are the test's own: the lift stands for a repair, its border stretched, not turned over
    monkeypatch.setattr(repair.Repair, "against_the_field", lambda self, x, frames: (None, (0, 0)))
    monkeypatch.setattr(sequence_inbetweens.Gap, "local_fit", local_fit)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        x = SequenceInterpolator([a, b, c], tri).pose(0, 0.5)
    assert fit and moved(x) == kept and bool(caught) != kept
    fit.clear()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        assert moved(Interpolator(a, b, tri).pose(0.5))
    # two poses take the repair either way; the 10 m lift's border, stretched far past the keys' edge
    # lengths, is said of its edges (kind fit: core.two_pose_inbetweens, Interpolator._edges_off)
    assert [w.message.kind for w in caught] == ([] if kept else ["fit"])


@pytest.mark.parametrize("lift, kept", [(1e-3, True), (1.0, False)])
def test_sequence_partial_repairs_do_not_jump(monkeypatch, strip, lift, kept):
    """When no repair of a sequence's in-between is defect-free, one that removes some defects is
    kept as the fit with the fewest only if it moves the pose by at most
    ``MAX_PARTIAL_REPAIR_MOVE`` mean edge lengths (RMS), however far the keys move: the
    neighbouring in-betweens choose their own, and a larger one is a jump away from them."""
    import core.inbetween_repair as repair
    from core import inbetween_repair_rounds
    from core import sequence_inbetweens

    flat, tri = strip
    travel = np.array([0.0, 0.0, 30.0])  # keys 30 apart: a tenth of their move would allow the lift
    a, b, c = _bend(flat, 0.0), _bend(flat, 1.0) + travel, _bend(flat, 1.5) + 2 * travel
    middle = 0.5 * (a.min(axis=0) + a.max(axis=0))  # keyed about the origin: sequences work about
    a, b, c = a - middle, b - middle, c - middle  # the first key's middle, and the mocks see positions
    fit = []  # the pose the repairs start from

    def moved(x):
        return bool(fit) and np.abs(x - fit[0]).max() > 0.5 * lift

    def defects(self, x, *args, rows=None, **kwargs):
        out = np.zeros(len(tri), dtype=bool)
        out[len(tri) // 2] = True  # a defect no repair removes
        out[len(tri) // 2 + 1] = not moved(x)  # and one every repair removes
        return out if rows is None else out[rows]

    def local_fit(self, x, region, frames, stretch, guide):
        fit[:] = fit or [x.copy()]
        z = x.copy()
        z[region.free, 2] += lift
        return z

    def run():
        fit.clear()
        with pytest.warns(ShapeDifferenceWarning, match="fewest"):
            return SequenceInterpolator([a, b, c], tri).pose(0, 0.5)

    monkeypatch.setattr(repair.Repair, "defects", defects)
    monkeypatch.setattr(repair.Repair, "problem", lambda self, x, s, frames, stretch, defects=None: "flipped")
    monkeypatch.setattr(sequence_inbetweens.Gap, "local_fit", local_fit)
    assert moved(run()) == kept
    monkeypatch.setattr(inbetween_repair_rounds, "MAX_PARTIAL_REPAIR_MOVE", np.inf)  # the limit is what refused it
    assert moved(run())


def _recording_fields(real_fields, imposed: list):
    """A stand-in for ``Repair.imposed_fields`` (``real_fields``) whose fields append their index in
    its list to ``imposed`` each time one is imposed."""
    def fields(self, *args):
        def tagged(index, field):
            return lambda rows: imposed.append(index) or field(rows)
        return [(tagged(index, field), whole) for index, (field, whole) in enumerate(real_fields(self, *args))]
    return fields


@pytest.mark.parametrize("sequence", [True, False])
def test_separate_folds_are_repaired_each_by_its_own_field(monkeypatch, strip, sequence):
    """Two folds far apart on a sequence's in-between, one that only the interpolated rotations
    remove and one that only the linear blend's rotations remove: each part of the repair region
    takes the first field that repairs it, so both go in the first round, without a warning (a
    field imposed on the whole region leaves one of them, whichever it is). Two poses take the
    region whole (their fallbacks are the blend's): there no field repairs both, and a fallback
    warns."""
    import core.inbetween_repair as repair
    from core import sequence_inbetweens

    flat, tri = strip
    a, b, c = _bend(flat, 0.0), _bend(flat, 1.0), _bend(flat, 1.5)
    middle = flat[tri].mean(axis=1)
    ends = [tri[np.argmin(np.linalg.norm(middle - [x, 0.5 * np.ptp(flat[:, 1]), 0.0], axis=1))] for x in (0.3, 1.7)]
    real_fit, real_local, real_fields = sequence_inbetweens.Gap.fit, sequence_inbetweens.Gap.local_fit, \
        repair.Repair.imposed_fields
    imposed = []  # the index of the field last imposed (0: the interpolated rotations, 1: the blend's)

    def fold(out, corners, free=None):
        i, j, k = corners
        if free is None or i in free:
            out[i] = out[j] + out[k] - out[i]  # a corner reflected across its opposite edge
        return out

    fields = _recording_fields(real_fields, imposed)

    def local_fit(self, x, region, frames, stretch, guide):
        out = real_local(self, x, region, frames, stretch, guide)
        for removes, corners in enumerate(ends):  # the first end's fold stays but for field 0, the other's but for 1
            if imposed[-1] != removes:
                fold(out, corners, region.free)
        return out

    def folding_fit(self, x, *args, **kwargs):
        return fold(fold(real_fit(self, x, *args, **kwargs), ends[0]), ends[1])

    monkeypatch.setattr(sequence_inbetweens.Gap, "fit", folding_fit)
    monkeypatch.setattr(sequence_inbetweens.Gap, "local_fit", local_fit)
    monkeypatch.setattr(repair.Repair, "imposed_fields", fields)
    if not sequence:
        with pytest.warns(ShapeDifferenceWarning, match="flipped"):
            Interpolator(a, b, tri).pose(0.5)
        assert max(imposed) > 1  # every field tried on the whole region
        return
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        x = SequenceInterpolator([a, b, c], tri).pose(0, 0.5)
    assert imposed and _flipped(x, a, b, tri) == 0
    assert max(imposed) == 1  # no field after the blend's rotations was needed


def test_a_fit_that_folds_past_the_whole_change_tolerance_falls_back_to_its_step_there(monkeypatch, strip):
    """A sequence's fit that ends with defects no repair removes returns, without a warning, its
    step where it would have stopped at the tolerance of the whole key-to-key change (see
    TOLERANCE_TRIM) when that step is clean."""
    import core.inbetween_repair as repair
    from core import inbetween_fit

    flat, tri = strip
    seq = SequenceInterpolator([flat, _bend(flat, 0.6), _bend(flat, 1.2)], tri)
    gap = seq._gap(0)
    _ = gap.arc_guided  # computed on first use of the guide: before the fit's steps are recorded
    gap.change_tolerance = 2.2 * gap.tolerance
    script = [3.0, 2.0, 1.5, 1.2]  # × the tolerance: within the whole change's at the second step
    steps = []

    def scripted(self, edges, targets):
        return script[min(len(steps), len(script)) - 1] * self.tolerance

    real_edges = inbetween_fit.LocalGlobalFit.edges_of

    def recording_edges(self, x, *args):
        steps.append(x)
        return real_edges(self, x, *args)

    def defects(self, x, *args, rows=None, **kwargs):
        out = np.zeros(len(tri), dtype=bool)
        out[:0 if x is steps[1] else 3] = True
        return out if rows is None else out[rows]

    monkeypatch.setattr(inbetween_fit.LocalGlobalFit, "misfit", scripted)
    monkeypatch.setattr(inbetween_fit.LocalGlobalFit, "edges_of", recording_edges)
    monkeypatch.setattr(repair.Repair, "defects", defects)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        x, problem = gap.pose(0.5)
    assert problem is None and x is steps[1]


def _predictions_flagged(monkeypatch, strip):
    """A bending strip's first gap with seven in-betweens (two solved, five predicted): the keys
    (about the first key's middle, where sequences work, so that a mock sees their positions), the
    triangles, the factors, every in-between solved {factor: positions}, and ``Repair.defects``
    mocked to flag three triangles of any pose but those solved ones."""
    import core.inbetween_prediction as prediction
    import core.inbetween_repair as repair

    flat, tri = strip
    keys = [_bend(flat, a) for a in (0.0, 0.7, 1.4)]
    middle = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0))
    keys = [k - middle for k in keys]
    factors = np.arange(1, 8) / 8
    with monkeypatch.context() as every_one_solved:
        every_one_solved.setattr(prediction, "MIN_PREDICTED_BATCH", len(factors) + 1)
        solved = dict(zip(factors, SequenceInterpolator(keys, tri).poses(0, factors)))
    moving = flat[:, 0] > 0.0  # the still vertices (x = 0) are set exactly after the check

    def defects(self, x, s, *args, rows=None, scale=None):
        out = np.zeros(len(tri), dtype=bool)
        out[:0 if np.allclose(x[moving], solved[s][moving], rtol=0, atol=1e-12) else 3] = True
        return out if rows is None else out[rows]

    monkeypatch.setattr(repair.Repair, "defects", defects)
    return keys, tri, factors, solved, moving


def test_a_prediction_no_repair_cleans_is_solved_instead(monkeypatch, strip):
    """In a gap whose solved in-betweens are clean, a predicted in-between whose defects no repair
    removes is solved: every in-between of the gap is then its solved pose, with no warning."""
    keys, tri, factors, solved, _ = _predictions_flagged(monkeypatch, strip)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        poses = SequenceInterpolator(keys, tri).poses(0, factors)
    np.testing.assert_allclose(poses, [solved[s] for s in factors], rtol=0, atol=1e-12)


def _recorded_solves(monkeypatch):
    """``Gap.fit`` and ``Gap.released`` recording each fit's start (a copy), its step limit and
    its misfits, and each release test (the fits run as they are)."""
    import core.inbetween_solver as solver

    fits, releases = [], []
    real_fit, real_released = solver.Gap.fit, solver.Gap.released

    def fit(self, x, stretch, frames, guide, s, motion, iterations=6, *args, **kwargs):
        misfits = kwargs.setdefault("misfits", [])
        out = real_fit(self, x, stretch, frames, guide, s, motion, iterations, *args, **kwargs)
        fits.append({"s": s, "start": x.copy(), "iterations": iterations, "misfits": list(misfits)})
        return out

    def released(self, *args):
        releases.append(args)
        return real_released(self, *args)

    monkeypatch.setattr(solver.Gap, "fit", fit)
    monkeypatch.setattr(solver.Gap, "released", released)
    return fits, releases


def test_a_pose_fitted_from_a_given_start_is_the_fit_from_there(strip):
    """``pose(s, start=x, iterations=k)`` is the local/global fit from ``x`` with at most ``k``
    steps (the fit run directly from a copy of ``x``, bit for bit), its misfits handed back, and
    no held test (``weak`` None means the gap's own anchor there)."""
    flat, tri = strip
    seq = SequenceInterpolator([_bend(flat, a) for a in (0.0, 0.7, 1.4)], tri)
    gap = seq._gap(0)
    s = 0.375
    start = gap.linear_blend(s)
    misfits = []
    x, _ = gap.pose(s, start=start.copy(), iterations=2, misfits=misfits)
    frames, stretch, motion, guide = gap.targets(s)
    direct = []
    y = gap.fit(start.copy(), stretch, frames, guide, s, motion, 2, misfits=direct)
    assert 1 <= len(misfits) <= 2 and misfits == direct
    assert misfits[0] == gap.misfit(gap.edges_of(start, np.float32), gap.fit_targets(frames, stretch))
    if gap.repair.defects(y, s, frames, stretch).any():
        pytest.skip("the fit from the blend has defects: the pose is its repair")
    np.testing.assert_array_equal(x, gap.finished((y, None), s)[0])
    assert gap.held_factors[s] is False


def test_a_prediction_no_repair_cleans_is_solved_from_itself(monkeypatch, strip):
    """The in-between solved in place of a prediction no repair cleans starts its fit at the
    repaired prediction, not at the Poisson solve of the field, takes at most
    SOLVED_INSTEAD_ITERATIONS steps and makes no held test (a fit from there makes little
    progress by design)."""
    import core.inbetween_prediction_repairs as prediction_repairs
    import core.inbetween_solver as solver

    keys, tri, factors, solved, moving = _predictions_flagged(monkeypatch, strip)
    repaired_poses = {}
    real_repaired = solver.Gap.repaired

    def repaired(self, x, s, rings=None, defects=None):  # what the repair hands on, kept to compare
        out = real_repaired(self, x, s, rings, defects)
        repaired_poses[s] = out[0].copy()
        return out

    monkeypatch.setattr(solver.Gap, "repaired", repaired)
    fits, releases = _recorded_solves(monkeypatch)
    seq = SequenceInterpolator(keys, tri)
    seq.poses(0, factors)
    predicted = [s for s in factors if s not in (0.25, 0.75)]
    limit = prediction_repairs.SOLVED_INSTEAD_ITERATIONS
    from_prediction = [f for f in fits if f["s"] in predicted and f["iterations"] == limit]
    assert {f["s"] for f in from_prediction} == set(predicted)
    for f in from_prediction:
        np.testing.assert_array_equal(f["start"], repaired_poses[f["s"]])
        assert len(f["misfits"]) <= limit < 6
    assert len(releases) == 0 and not any(seq._gap(0).held_factors[s] for s in predicted)


def _mark_solves_from_predictions(monkeypatch):
    """Patch :meth:`core.inbetween_solver.Gap.pose` so that the gap's ``_from_prediction`` is True
    while it solves from a given start (a prediction solved from itself), for patched checks to
    tell those solves apart."""
    import core.inbetween_solver as solver

    pose = solver.Gap.pose

    def marked_pose(self, s, weak=None, start=None, *args, **kwargs):
        self._from_prediction = start is not None
        try:
            return pose(self, s, weak, start, *args, **kwargs)
        finally:
            self._from_prediction = False

    monkeypatch.setattr(solver.Gap, "pose", marked_pose)


@pytest.mark.parametrize("at_the_metric", [True, False])
def test_a_prediction_at_the_metric_with_defects_is_solved_from_the_field_too(monkeypatch, strip, at_the_metric):
    """Where the fit from the repaired prediction ends within the gap's tolerance with defects
    left, the prediction's defects are not the metric's doing: the pose is solved from the Poisson
    solve of the field too and the one with fewer defects kept (here the solved one, clean: every
    in-between is then its solved pose). A fit that ends off the tolerance is kept without it."""
    import core.inbetween_fit as fit
    import core.inbetween_prediction_repairs as prediction_repairs

    keys, tri, factors, solved, moving = _predictions_flagged(monkeypatch, strip)
    fits, _ = _recorded_solves(monkeypatch)
    real_misfit = fit.LocalGlobalFit.misfit
    scale = 0.5 if at_the_metric else 4.0

    def misfit(self, edges, targets):  # the fits from a prediction end within the tolerance or 4 × it
        from_prediction = getattr(self, "_from_prediction", False)
        return scale * self.tolerance if from_prediction else real_misfit(self, edges, targets)

    monkeypatch.setattr(fit.LocalGlobalFit, "misfit", misfit)
    _mark_solves_from_predictions(monkeypatch)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShapeDifferenceWarning)
        poses = dict(zip(factors, SequenceInterpolator(keys, tri).poses(0, factors)))
    predicted = [s for s in factors if s not in (0.25, 0.75)]
    limit = prediction_repairs.SOLVED_INSTEAD_ITERATIONS
    fresh = [f["s"] for f in fits if f["s"] in predicted and f["iterations"] != limit]
    for s in predicted:
        assert np.allclose(poses[s][moving], solved[s][moving], rtol=0, atol=1e-12) == at_the_metric
    assert sorted(fresh) == (predicted if at_the_metric else [])
    assert (len(caught) == 0) == at_the_metric


@pytest.mark.parametrize("solve_defects", [3, 4])
def test_a_solve_of_a_prediction_with_more_defects_than_it_had_is_not_repaired(monkeypatch, strip, solve_defects):
    """The solve of a prediction no repair cleans, from the repaired prediction, is repaired only
    where its fit has at most UNREPAIRED_SOLVE_DEFECTS × the defects the prediction had before its
    repair (here 3: 1.25 × 3 = 3.75): a fit with 4 goes to the fallbacks without repair rounds (it
    loses to the repaired prediction, with 3, as it does after rounds that leave its 4: the same
    in-betweens as with every such solve repaired); a fit with 3 is repaired."""
    import core.inbetween_fit as fit
    import core.inbetween_prediction_repairs as prediction_repairs
    import core.inbetween_repair as repair

    keys, tri, factors, _, _ = _predictions_flagged(monkeypatch, strip)
    flagged = repair.Repair.defects

    def defects(self, x, s, *args, rows=None, scale=None):  # the fits from a prediction: solve_defects
        out = flagged(self, x, s, *args, rows=None, scale=scale)
        if getattr(self.gap, "_from_prediction", False) and out.any():
            out[:solve_defects] = True
        return out if rows is None else out[rows]

    real_misfit, real_rounds = fit.LocalGlobalFit.misfit, repair.Repair.rounds

    def misfit(self, edges, targets):  # off the tolerance: no solve from the Poisson solve as well
        return 4.0 * self.tolerance if getattr(self, "_from_prediction", False) else real_misfit(self, edges, targets)

    rounds_from_prediction = []

    def rounds(self, x, *args, **kwargs):
        if getattr(self.gap, "_from_prediction", False):
            rounds_from_prediction.append(args[1])
        return real_rounds(self, x, *args, **kwargs)

    monkeypatch.setattr(repair.Repair, "defects", defects)
    _mark_solves_from_predictions(monkeypatch)
    monkeypatch.setattr(fit.LocalGlobalFit, "misfit", misfit)
    monkeypatch.setattr(repair.Repair, "rounds", rounds)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        poses = dict(zip(factors, SequenceInterpolator(keys, tri).poses(0, factors)))
        repaired_with_the_rule = sorted(rounds_from_prediction)
        rounds_from_prediction.clear()
        monkeypatch.setattr(prediction_repairs, "UNREPAIRED_SOLVE_DEFECTS", np.inf)  # every solve repaired
        every_solve_repaired = dict(zip(factors, SequenceInterpolator(keys, tri).poses(0, factors)))
    predicted = [s for s in factors if s not in (0.25, 0.75)]
    assert repaired_with_the_rule == (predicted if solve_defects == 3 else [])
    assert sorted(rounds_from_prediction) == predicted
    for s in predicted:  # the same in-betweens with the rule as without it
        np.testing.assert_array_equal(poses[s], every_solve_repaired[s])


@pytest.mark.parametrize("shift, solved_instead", [(10.0, True), (0.01, False)])
def test_a_repair_that_moves_a_prediction_far_gives_way_to_the_solve(monkeypatch, strip, shift, solved_instead):
    """A predicted in-between whose clean repair moves it by more than the cloth deforms across the
    gap (a tenth of the keys' move with each piece's rigid motion taken out, at least a mean edge
    length) is solved instead when the solve is clean: its neighbours in time are predictions and
    would not follow the repair (a cape on a walking rig, keys 8 apart: a repair moved one
    in-between 1.2 mean edge lengths RMS, within a tenth of the walk, and it jumped 2.25 × the
    simulation's largest acceleration). A repair that moves it a little is kept."""
    import core.inbetween_solver as solver

    keys, tri, factors, solved, moving = _predictions_flagged(monkeypatch, strip)

    def repaired(self, x, s, rings=None, defects=None):  # clean, moved by ``shift`` mean edges
        return x + shift * self.mean_edge, None

    monkeypatch.setattr(solver.Gap, "repaired", repaired)
    poses = dict(zip(factors, SequenceInterpolator(keys, tri).poses(0, factors)))
    for s in factors:
        if s not in (0.25, 0.75):  # the predicted ones
            assert np.allclose(poses[s][moving], solved[s][moving], rtol=0, atol=1e-12) == solved_instead


def test_a_repair_by_rows_falls_back_as_a_whole_pose_does(strip):
    """A predicted in-between of a gap between two keys (not a sequence's: the fallbacks near the
    linear blend apply) whose repairs all fail reaches the fit near the blend, which reads the
    whole mesh's stretches: the repair given the targets by rows returns what it returns given
    them whole, bit for bit."""
    flat, tri = strip
    a, b = _bend(flat, 0.0), _bend(flat, 2.0)
    gap = SequenceInterpolator([a, b], tri, start="keys")._gap(0)
    assert not gap.cubic
    s = 0.5
    crumpled = 0.5 * (gap.base.vertices + gap.next.vertices) + \
        np.random.default_rng(0).normal(scale=0.1, size=a.shape)
    x, message = gap.repaired(crumpled, s)
    assert message is not None and "near the linear blend" in message
    frames, stretch, motion, guide = gap.targets(s)
    whole = gap.finished(gap.recorded(s, gap.repair.outcome(crumpled, crumpled, s, frames, stretch, guide, motion)), s)
    np.testing.assert_array_equal(x, whole[0])
    assert message == whole[1]


def test_a_triangle_tipped_against_the_turn_of_a_strongly_stretching_gap_is_flipped(strip):
    """Keys five times apart in size and a quarter turn apart: the gap's tolerance is 2, which
    read as an angle would let a triangle facing away from both keys and 107° off its interpolated
    normal pass as turning with its piece. The angle is arctan of the tolerance (63°), so it is
    flipped."""
    flat, tri = strip
    b = 5.0 * flat @ Rotation.from_rotvec([np.pi / 2, 0.0, 0.0]).as_matrix().T
    gap = SequenceInterpolator([flat, b], tri, start="keys")._gap(0)
    assert gap.tolerance >= 1.0
    s = 0.5
    x = gap.pose(s)[0]
    frames, stretch = gap.targets(s)[:2]
    assert not gap.repair.defects(x, s, frames, stretch).any()
    t = len(tri) // 2
    i, j, k = tri[t]
    base, nxt = gap.base.normal_rows[:, t], gap.next.normal_rows[:, t]
    interpolated = np.cross(frames[0][t], frames[1][t])
    # its third corner moved across its first side so that it faces mostly sideways and a little
    # away from both keys
    facing = 0.9 * np.cross(base, nxt) - 0.2 * (base + nxt)
    side = x[j] - x[i]
    across = np.cross(facing, side)
    x[k] = x[i] + 0.5 * side + np.linalg.norm(x[k] - x[i]) * across / np.linalg.norm(across)
    normal = np.cross(x[j] - x[i], x[k] - x[i])
    normal /= np.linalg.norm(normal)
    assert normal @ base < 0 and normal @ nxt < 0
    assert np.degrees(np.arccos(normal @ interpolated / np.linalg.norm(interpolated))) > 100.0
    assert gap.repair.defects(x, s, frames, stretch)[t]


def _middle_folded(monkeypatch, strip, unfolds):
    """Keys of a bending strip and its triangles, with the fit of the middle in-between (s = 1/2)
    folding a triangle over (a corner reflected across its opposite edge) and every repair's
    local fit folding it again unless the field imposed is one of ``unfolds`` (indices into
    ``Repair.imposed_fields``); the fields imposed are recorded (the list returned)."""
    import core.inbetween_corrections as corrections
    import core.inbetween_repair as repair
    from core import sequence_inbetweens

    flat, tri = strip
    keys = [_bend(flat, a) for a in (0.0, 0.7, 1.4)]
    middle = flat[tri].mean(axis=1)
    corners = tri[np.argmin(np.linalg.norm(middle - [1.0, 0.5 * np.ptp(flat[:, 1]), 0.0], axis=1))]
    real_fit, real_local, real_fields = sequence_inbetweens.Gap.fit, sequence_inbetweens.Gap.local_fit, \
        repair.Repair.imposed_fields
    imposed = []

    def fold(out, free=None):
        i, j, k = corners
        if free is None or i in free:
            out[i] = out[j] + out[k] - out[i]
        return out

    fields = _recording_fields(real_fields, imposed)

    def local_fit(self, x, region, frames, stretch, guide):
        out = real_local(self, x, region, frames, stretch, guide)
        return out if imposed[-1] in unfolds else fold(out, region.free)

    def folding_fit(self, x, stretch, frames, guide, s, *args, **kwargs):
        out = real_fit(self, x, stretch, frames, guide, s, *args, **kwargs)
        return fold(out) if s == 0.5 else out

    monkeypatch.setattr(sequence_inbetweens.Gap, "fit", folding_fit)
    monkeypatch.setattr(sequence_inbetweens.Gap, "local_fit", local_fit)
    monkeypatch.setattr(repair.Repair, "imposed_fields", fields)
    # the reflected corner is a large part of the bending strip's small correction: the gap would be
    # found too rough to predict from three solved factors, and solved at every eighth instead
    monkeypatch.setattr(corrections, "MAX_CROSS_VALIDATION", np.inf)
    return keys, tri, imposed


def test_a_middle_fold_no_field_removes_is_repaired_with_the_outer_solves_geometry(monkeypatch, strip):
    """Keys 16 frames apart (three solved in-betweens): the middle one's fit folds a triangle over
    that none of the repair's own fields unfolds, while the two solved a quarter of the gap away
    are clean. The middle and the predictions made from it are repaired again with one more field,
    the local geometry of the pose the outer two alone predict: every in-between of the gap ends
    with no flipped triangle and no warning (without that field the middle keeps its fold, and
    warns)."""
    keys, tri, imposed = _middle_folded(monkeypatch, strip, unfolds={6})
    factors = np.arange(1, 16) / 16
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        poses = SequenceInterpolator(keys, tri).poses(0, factors)
    assert max(_flipped(x, keys[0], keys[1], tri) for x in poses) == 0
    assert 6 in imposed and max(imposed) == 6  # the outer solves' geometry: the one field after each key's


def test_a_middle_fold_the_outer_solves_geometry_keeps_too_is_kept_as_it_was(monkeypatch, strip):
    """Where the outer solves' geometry unfolds nothing either, every in-between is the pose its own
    repair left (as without that field, bit for bit), and what the gap keeps of its outcome, which
    its warning counts from, is that pose's."""
    import core.inbetween_prediction as prediction
    import core.inbetween_untangling as untangling

    keys, tri, imposed = _middle_folded(monkeypatch, strip, unfolds=set())
    # the last untangling would unfold it (test_inbetween_untangling): what the repairs keep is asked here
    monkeypatch.setattr(untangling, "untangled", lambda *args: None)
    factors = np.arange(1, 16) / 16
    seq = SequenceInterpolator(keys, tri)
    with pytest.warns(ShapeDifferenceWarning, match="flipped"):
        poses = seq.poses(0, factors)
    assert 6 in imposed
    gap = seq._gap(0)
    checked = [(s, x) for s, x in zip(factors, poses) if s in gap.outcomes]  # the clean predictions need no check
    assert 0.5 in dict(checked)
    for s, x in checked:
        assert gap.outcomes[s].defects == int(gap.repair.defects(x, s, None, None, scale=gap.area_scale(s)).sum())
    monkeypatch.setattr(prediction, "_outer_correction", lambda *args: None)
    with pytest.warns(ShapeDifferenceWarning, match="flipped"):
        np.testing.assert_array_equal(SequenceInterpolator(keys, tri).poses(0, factors), poses)


def test_a_gap_rough_as_its_three_solves_come_is_solved_rough_without_repairing_them_again(monkeypatch, strip):
    """The middle fold of :func:`_middle_folded`, which no field unfolds, at the real
    ``MAX_CROSS_VALIDATION``: the three solved in-betweens are too rough to predict from as they
    come, so the gap is solved at every eighth (``_rough_poses``) without their repairs again, which
    that path solves anew; its in-betweens are bit for bit those the gap gives when its roughness is
    read only after those repairs (the order before)."""
    import core.inbetween_corrections as corrections
    import core.inbetween_prediction as prediction
    import core.inbetween_untangling as untangling

    limit = corrections.MAX_CROSS_VALIDATION
    keys, tri, _ = _middle_folded(monkeypatch, strip, unfolds=set())
    monkeypatch.setattr(corrections, "MAX_CROSS_VALIDATION", limit)
    monkeypatch.setattr(untangling, "untangled", lambda *args: None)  # the poses the repairs leave
    calls = []
    real_passes, real_rough, real_inconsistent = (prediction.repaired_in_passes, prediction._rough_poses,
                                                  prediction.inconsistent)

    def passes(gap, s, *args, **kwargs):
        calls.append(("passes", s))
        return real_passes(gap, s, *args, **kwargs)

    def rough(*args, **kwargs):
        calls.append(("rough", None))
        return real_rough(*args, **kwargs)

    monkeypatch.setattr(prediction, "repaired_in_passes", passes)
    monkeypatch.setattr(prediction, "_rough_poses", rough)
    factors = np.arange(1, 16) / 16
    with pytest.warns(ShapeDifferenceWarning, match="flipped"):
        poses = SequenceInterpolator(keys, tri).poses(0, factors)
    assert ("rough", None) in calls
    assert calls.index(("rough", None)) == 0  # no repair again before the gap went rough
    # the roughness read only after the three's repairs again (its first reading says smooth; each
    # repair again hands back a copy, as one that moved its pose does, so the check is read again)
    readings = []

    def read_after_the_repairs(gap, solved):
        readings.append(1)
        return len(readings) > 1 and real_inconsistent(gap, solved)

    def passes_copied(gap, s, pose, *args, **kwargs):
        x, problem = passes(gap, s, pose, *args, **kwargs)
        return x.copy(), problem

    monkeypatch.setattr(prediction, "inconsistent", read_after_the_repairs)
    monkeypatch.setattr(prediction, "repaired_in_passes", passes_copied)
    calls.clear()
    with pytest.warns(ShapeDifferenceWarning, match="flipped"):
        np.testing.assert_array_equal(SequenceInterpolator(keys, tri).poses(0, factors), poses)
    assert [kind for kind, _ in calls[:4]] == ["passes"] * 3 + ["rough"]


def _two_folds(monkeypatch, strip, g):
    """Keys of a bending strip, its triangles and the factors of the ``g`` − 1 in-betweens of a gap
    keyed every ``g``-th frame, with the poses at s = 1/2 — the fit and the prediction — folding two
    triangles over a vertex apart (a corner of each reflected across its opposite edge): a repair's
    local fit folds the second again unless the field imposed is the blend's local geometry (field
    2), and folds the first again wherever the pose it starts from has the second folded. A first
    repair then leaves the first folded (the blend's geometry repairs the second there, but its
    regions grow around the pose it started from, where both are); a repair from that pose unfolds
    it. The fields imposed are recorded (the list returned last)."""
    import core.inbetween_prediction_repairs as prediction_repairs
    import core.inbetween_repair as repair
    from core import sequence_inbetweens

    flat, tri = strip
    keys = [_bend(flat, a) for a in (0.0, 0.7, 1.4)]
    middle = flat[tri].mean(axis=1)
    first, second = (tri[np.argmin(np.linalg.norm(middle - [x, 0.5 * np.ptp(flat[:, 1]), 0.0], axis=1))]
                     for x in (1.0, 1.15))
    assert not set(first) & set(second)
    real_fit, real_local, real_fields = sequence_inbetweens.Gap.fit, sequence_inbetweens.Gap.local_fit, \
        repair.Repair.imposed_fields
    real_predicted = prediction_repairs.predicted_positions
    imposed = []

    def fold(out, corners, free=None):
        i, j, k = corners
        if free is None or i in free:
            out[i] = out[j] + out[k] - out[i]
        return out

    def folded(x, corners):  # facing against the first key, as a fold across the bending strip does
        i, j, k = corners
        return np.cross(x[j] - x[i], x[k] - x[i]) @ np.cross(keys[0][j] - keys[0][i], keys[0][k] - keys[0][i]) < 0

    def local_fit(self, x, region, frames, stretch, guide):
        out = real_local(self, x, region, frames, stretch, guide)
        if folded(x, second):
            fold(out, first, region.free)
            if imposed[-1] != 2:
                fold(out, second, region.free)
        return out

    def folding_fit(self, x, stretch, frames, guide, s, *args, **kwargs):
        out = real_fit(self, x, stretch, frames, guide, s, *args, **kwargs)
        return fold(fold(out, first), second) if s == 0.5 else out

    def folding_prediction(gap, s, correction, motion):
        out = real_predicted(gap, s, correction, motion)
        return fold(fold(out, first), second) if s == 0.5 else out

    monkeypatch.setattr(sequence_inbetweens.Gap, "fit", folding_fit)
    monkeypatch.setattr(sequence_inbetweens.Gap, "local_fit", local_fit)
    monkeypatch.setattr(repair.Repair, "imposed_fields", _recording_fields(real_fields, imposed))
    monkeypatch.setattr(prediction_repairs, "predicted_positions", folding_prediction)
    return keys, tri, np.arange(1, g) / g, imposed


@pytest.mark.parametrize("g", [4, 8])
def test_a_fold_a_repair_leaves_fewer_of_is_repaired_again_from_there(monkeypatch, strip, g):
    """Keys 4 frames apart (the middle solved) and 8 apart (the middle predicted from the two solved
    a quarter of the gap away): the middle's fit or prediction folds two triangles, and its first
    repair leaves one of them, which no field unfolds around the pose that repair started from. The
    in-between is repaired again from the pose that repair left: every in-between of the gap ends
    with no flipped triangle and no warning (a repair only once keeps the fold, and warns)."""
    keys, tri, factors, imposed = _two_folds(monkeypatch, strip, g)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        poses = SequenceInterpolator(keys, tri).poses(0, factors)
    assert max(_flipped(x, keys[0], keys[1], tri) for x in poses) == 0
    assert 2 in imposed


@pytest.mark.parametrize("g", [4, 8])
def test_a_fold_a_repair_again_keeps_too_is_kept_with_its_count(monkeypatch, strip, g):
    """Where no repair may move a pose (every move limit zero), the in-betweens keep their folds, and
    each warning counts, in its words and its ``defects``, the flipped or collapsed triangles of the
    poses returned — also where a solve tried after a prediction was not taken (its check stored its
    own count; with keys 8 apart the old count was the solve's 8 beside the prediction's 4)."""
    import core.inbetween_repair_rounds as rounds

    keys, tri, factors, _ = _two_folds(monkeypatch, strip, g)
    monkeypatch.setattr(rounds.RepairRounds, "move_limits", lambda self, s: (0.0, 0.0) if self.in_sequence(s) else None)
    seq = SequenceInterpolator(keys, tri)
    with pytest.warns(ShapeDifferenceWarning, match="keeps") as said:
        poses = seq.poses(0, factors)
    gap = seq._gap(0)
    kept = [int(gap.repair.defects(x, s, None, None, scale=gap.area_scale(s)).sum()) for s, x in zip(factors, poses)]
    assert kept[list(factors).index(0.5)] >= _flipped(poses[list(factors).index(0.5)], keys[0], keys[1], tri) > 0
    # each warning of the poses' defects names the factors it is about and counts the most any of
    # them keeps, in its words too (a fit's misfit, the middle's solve returned here, is another kind)
    for w in (w for w in said if w.message.kind == "pose"):
        most = max(kept[list(factors).index(f)] for f in w.message.factors)
        assert w.message.defects == most and f"keeps {most} triangle" in str(w.message)


@pytest.mark.parametrize("g", [4, 8])
def test_a_repair_again_that_leaves_some_defects_is_kept_and_warned_with_its_count(monkeypatch, strip, g):
    """The two folds above and a third triangle, away from both, that every fit, prediction and local
    fit folds again (no repair removes it): the first repair of the middle leaves the first fold and
    the third, the repair again from there the third alone, the next no fewer. The in-between kept is
    the one with the third fold only, and the gap's warning counts, in its words and its ``defects``,
    the flipped or collapsed triangles of the poses returned (a pass taken whose check stored its
    own count, then a pass not taken whose check stored another)."""
    import core.inbetween_prediction_repairs as prediction_repairs
    import core.inbetween_untangling as untangling
    from core import sequence_inbetweens

    keys, tri, factors, _ = _two_folds(monkeypatch, strip, g)
    flat, _ = strip
    middle = flat[tri].mean(axis=1)
    first, second, third = (tri[np.argmin(np.linalg.norm(middle - [x, 0.5 * np.ptp(flat[:, 1]), 0.0], axis=1))]
                            for x in (1.0, 1.15, 0.4))  # _two_folds' two, and the third
    folds_fit, folds_local, folds_predicted = sequence_inbetweens.Gap.fit, sequence_inbetweens.Gap.local_fit, \
        prediction_repairs.predicted_positions

    def fold(out, free=None):
        i, j, k = third
        if free is None or i in free:
            out[i] = out[j] + out[k] - out[i]
        return out

    def flipped(x, corners):
        i, j, k = corners
        return np.cross(x[j] - x[i], x[k] - x[i]) @ np.cross(keys[0][j] - keys[0][i], keys[0][k] - keys[0][i]) < 0

    def local_fit(self, x, region, frames, stretch, guide):
        out = folds_local(self, x, region, frames, stretch, guide)
        return out if flipped(out, third) else fold(out, region.free)

    def fit(self, x, stretch, frames, guide, s, *args, **kwargs):
        out = folds_fit(self, x, stretch, frames, guide, s, *args, **kwargs)
        return fold(out) if s == 0.5 else out

    def predicted(gap, s, correction, motion):
        out = folds_predicted(gap, s, correction, motion)
        return fold(out) if s == 0.5 else out

    monkeypatch.setattr(sequence_inbetweens.Gap, "fit", fit)
    monkeypatch.setattr(sequence_inbetweens.Gap, "local_fit", local_fit)
    monkeypatch.setattr(prediction_repairs, "predicted_positions", predicted)
    # the last untangling would unfold the third (test_inbetween_untangling): what the repairs keep is asked here
    monkeypatch.setattr(untangling, "untangled", lambda *args: None)
    seq = SequenceInterpolator(keys, tri)
    with pytest.warns(ShapeDifferenceWarning, match="keeps") as said:
        poses = seq.poses(0, factors)
    gap = seq._gap(0)
    kept = [int(gap.repair.defects(seq._to_working(x), s, None, None, scale=gap.area_scale(s)).sum())
            for s, x in zip(factors, poses)]
    half = poses[list(factors).index(0.5)]
    assert flipped(half, third) and not flipped(half, first) and not flipped(half, second)
    assert kept[list(factors).index(0.5)] >= _flipped(half, keys[0], keys[1], tri) > 0
    for w in (w for w in said if w.message.kind == "pose"):  # the defects' warnings (a fit's misfit is another kind)
        most = max(kept[list(factors).index(f)] for f in w.message.factors)
        assert w.message.defects == most and f"keeps {most} triangle" in str(w.message)


class _ScriptedGap:
    """A stand-in for a gap whose repairs of an in-between are scripted: ``passes`` (list of
    positions (n, 3)) are what its successive repairs return, each stored with its count in
    ``outcomes`` as :meth:`core.inbetween_solver.Gap.recorded` does; a triangle is flipped where its
    row of the positions has a negative first coordinate (triangle i: vertex i thrice); ``limits`` the
    repairs' move limits."""

    def __init__(self, passes, limits):
        from types import SimpleNamespace

        from core.inbetween_repair import Outcome

        self.outcome_of = lambda x: Outcome(int((x[:, 0] < 0).sum()), False)
        self.passes, self.outcomes, self.fit_misfits = list(passes), {}, {}  # as Gap keeps them (no fit here)
        n = len(self.passes[0])
        self.topo = SimpleNamespace(triangles=np.repeat(np.arange(n)[:, None], 3, axis=1))

        class Repair:
            def defects(self, x, s, frames, stretch, rows=None, scale=None):
                flipped = x[:, 0] < 0
                return flipped if rows is None else flipped[rows]

            def counted(self, x, s, scale):
                return self.defects(x, s, None, None)

            def move_limits(self, s):
                return limits

            def factor_area_scale(self, s):
                return None

        self.repair = Repair()

    def repaired_again(self, x, s, nearby=None, rings=None, defects=None):
        y = self.passes.pop(0)
        self.outcomes[s] = self.outcome_of(y)
        return y, "kept defects" if (y[:, 0] < 0).any() else None


def test_a_repair_again_beyond_the_move_limit_from_the_first_pose_is_not_taken_and_its_count_not_kept(monkeypatch):
    """Three defects, a repair that leaves two (a sum of squared moves of 1), then one that leaves
    none (2 from where it starts, within the limit of 2.5; 3 from the first pose): the second is not
    taken, and the gap's outcome at the factor, which the warning counts, is that of the pose
    returned (two defects), not that of the repair not taken (none). With no passes, the pose as it
    was and its outcome."""
    from core import inbetween_prediction_repairs as prediction_repairs

    first = np.array([[-1.0, 0, 0], [-1.0, 0, 0], [-1.0, 0, 0], [1.0, 0, 0]])
    fewer = first.copy()
    fewer[0, 0] = 0.0
    clean = fewer.copy()
    clean[1:3, 0] = 0.0
    for passes, kept in ((prediction_repairs.REPAIR_PASSES, fewer), (0, first)):
        monkeypatch.setattr(prediction_repairs, "REPAIR_PASSES", passes)
        gap = _ScriptedGap([fewer, clean], (2.5, 2.5))
        gap.outcomes[0.5] = gap.outcome_of(first)  # the first pose's own check
        x, problem = prediction_repairs.repaired_in_passes(gap, 0.5, (first, "kept defects"))
        assert np.array_equal(x, kept) and problem is not None
        assert gap.outcomes[0.5] == gap.outcome_of(kept)


def test_the_repairs_again_stop_after_a_pass_that_removes_under_its_share_of_the_defects():
    """200 defects; a first pass that leaves 199 (0.5 %, under ``REPAIR_PASS_LEAST_SHARE``) ends
    the passes: its pose is returned with its outcome, and the second scripted repair (which would
    leave 100) is never asked for. A first pass that leaves 190 (5 %) does not: the second is taken
    (and a third, which leaves as many, is asked for and ends them as before)."""
    from core import inbetween_prediction_repairs as prediction_repairs

    first = np.zeros((300, 3))
    first[:200, 0] = -1.0
    for left in (199, 190):
        once = first.copy()
        once[left:200, 0] = 0.0
        twice = first.copy()
        twice[100:200, 0] = 0.0
        assert (200 - left < prediction_repairs.REPAIR_PASS_LEAST_SHARE * 200) == (left == 199)
        gap = _ScriptedGap([once, twice, twice.copy()], (np.inf, np.inf))
        gap.outcomes[0.5] = gap.outcome_of(first)
        x, problem = prediction_repairs.repaired_in_passes(gap, 0.5, (first, "kept defects"))
        kept = once if left == 199 else twice
        assert np.array_equal(x, kept) and problem is not None
        assert gap.outcomes[0.5] == gap.outcome_of(kept)
        assert len(gap.passes) == (2 if left == 199 else 0)


def test_a_pose_its_repairs_again_leave_as_it_was_comes_back_itself_and_a_repaired_one_as_another(monkeypatch):
    """Two defects; a repair again that leaves as many (not taken), none asked for (no passes), and
    a clean pose: each is handed back as the very tuple given, its positions unchanged, which is
    how ``_gap_poses`` tells the solved in-betweens no repair again moved (it reads their roughness
    again only where one did). A repair again that leaves one is handed back as another tuple."""
    from core import inbetween_prediction_repairs as prediction_repairs

    first = np.array([[-1.0, 0, 0], [-1.0, 0, 0], [1.0, 0, 0]])
    fewer = first.copy()
    fewer[0, 0] = 0.0
    for passes, scripted, kept in ((prediction_repairs.REPAIR_PASSES, [first.copy() * 2.0], True), (0, [first], True),
                                   (prediction_repairs.REPAIR_PASSES, [fewer, fewer.copy()], False)):
        monkeypatch.setattr(prediction_repairs, "REPAIR_PASSES", passes)
        pose = (first.copy(), "kept defects")
        before = pose[0].copy()
        back = prediction_repairs.repaired_in_passes(_ScriptedGap(scripted, (np.inf, np.inf)), 0.5, pose)
        assert (back is pose) == kept
        assert np.array_equal(pose[0], before)  # the pose given is never written to
        assert np.array_equal(back[0], before if kept else fewer)
    clean = (np.abs(first), None)
    assert prediction_repairs.repaired_in_passes(_ScriptedGap([first], (np.inf, np.inf)), 0.5, clean) is clean


def test_the_repairs_of_one_in_between_share_the_blend_and_spline_geometry(monkeypatch, strip):
    """The repairs of one in-between (a prediction's, the solve from it, the repairs again: one
    scope, ``Repair.fields_kept``) compute each triangle's local geometry of the linear
    blend and of the keys' spline at its factor once: a second repair at the factor computes none,
    and each returns what it returns alone, bit for bit. Out of the scope nothing is kept."""
    import core.deformation_fields as df

    flat, tri = strip
    gap = SequenceInterpolator([_bend(flat, a) for a in (0.0, 1.0, 2.0)], tri)._gap(0)
    s = 0.5
    rng = np.random.default_rng(0)
    crumpled = [gap.linear_blend(s) + rng.normal(scale=0.05, size=flat.shape) for _ in range(2)]
    computed = []  # triangles whose mesh-field geometry each call computed
    real = df.corner_edges
    monkeypatch.setattr(df, "corner_edges", lambda points, triangles: computed.append(len(triangles))
                        or real(points, triangles))

    def repaired(x):
        computed.clear()
        out = gap.repaired(x.copy(), s)  # a pose that keeps its defects comes back as it is, its still vertices set
        return out, sum(computed)

    alone = [repaired(x) for x in crumpled]
    assert all(count > 0 for _, count in alone)  # the rounds reach the mesh fields
    with gap.repair.fields_kept():
        first, first_count = repaired(crumpled[0])
        again, again_count = repaired(crumpled[0])
        other, _ = repaired(crumpled[1])
    assert first_count > 0 and again_count == 0
    for (x, message), (y, said) in zip((first, again, other), (alone[0][0], alone[0][0], alone[1][0])):
        np.testing.assert_array_equal(x, y)
        assert message == said
    assert repaired(crumpled[0])[1] > 0  # let go at the scope's end


def test_the_repairs_again_of_one_in_between_share_its_targets_and_the_nearby_geometry(monkeypatch, strip):
    """An in-between's repair and its repairs again at one factor (one scope, ``Repair.fields_kept``)
    read the gap's interpolated rotations and stretches by rows from one set of targets, and each
    triangle's local geometry of the pose passed as ``nearby`` is computed once for all the passes
    given that very array: each repair returns what it returns alone, bit for bit (a pass computes
    no value it would not compute alone), and out of the scope nothing is kept."""
    import core.deformation_fields as df
    from core import inbetween_solver

    flat, tri = strip
    gap = SequenceInterpolator([_bend(flat, a) for a in (0.0, 1.0, 2.0)], tri)._gap(0)
    s = 0.5
    rng = np.random.default_rng(1)
    crumpled = gap.linear_blend(s) + rng.normal(scale=0.05, size=flat.shape)
    nearby = gap.linear_blend(s) + rng.normal(scale=0.01, size=flat.shape)
    made, real_targets = [], inbetween_solver.Gap.targets
    monkeypatch.setattr(inbetween_solver.Gap, "targets",
                        lambda self, s, by_rows=False: made.append(by_rows) or real_targets(self, s, by_rows))
    of_nearby = []  # triangles whose local geometry of ``nearby`` was computed
    real_edges = df.corner_edges
    monkeypatch.setattr(df, "corner_edges", lambda points, triangles: (points is nearby and of_nearby.extend(
        map(tuple, triangles))) or real_edges(points, triangles))

    def chain():  # a repair, then two repairs again from its pose with the same nearby pose
        first = gap.repaired(crumpled.copy(), s)
        return [first] + [gap.repaired_again(first[0].copy(), s, nearby) for _ in range(2)]

    alone = chain()
    # alone, each call makes its own targets and each pass the geometry of its regions
    assert made.count(True) == 3 and len(of_nearby) > len(set(of_nearby))
    made.clear(), of_nearby.clear()
    with gap.repair.fields_kept():
        kept = chain()
    assert made.count(True) == 1 and of_nearby and len(of_nearby) == len(set(of_nearby))
    for (x, message), (y, said) in zip(kept, alone):
        np.testing.assert_array_equal(x, y)
        assert message == said
    made.clear()
    gap.repaired_again(alone[0][0].copy(), s, nearby)
    assert made.count(True) == 1  # let go at the scope's end


def test_the_defects_counted_are_the_check_with_the_interpolated_frames(strip):
    """``Repair.counted`` (what the prediction's repairs, the repairs again and their passes count,
    which the untangling and the warning count too) equals, triangle by triangle, the check of the
    whole mesh with the interpolated frames and stretches, for poses with triangles flipped,
    unflipped and collapsed (and every triangle of a pose that is not finite); the check without
    the frames holds every one of them."""
    flat, tri = strip
    gap = SequenceInterpolator([_bend(flat, a) for a in (0.0, 1.0, 2.0)], tri)._gap(0)
    s, scale = 0.5, gap.area_scale(0.5)
    frames, stretch = gap.repair.factor_targets(s)[:2]
    rng = np.random.default_rng(2)
    x = gap.linear_blend(s) + rng.normal(scale=0.03, size=flat.shape)

    def whole(y):
        return gap.repair.defects(y, s, frames, stretch, scale=scale)

    before = whole(x)
    assert before.any() and not before.all()
    edge = np.median(np.linalg.norm(flat[tri[:, 1]] - flat[tri[:, 0]], axis=1))
    i, j, k = tri[len(tri) // 2]
    poses = []
    for moved in (rng.choice(len(x), size=12, replace=False), np.unique(tri[before])):
        y = x.copy()
        y[moved] += rng.normal(scale=edge, size=(len(moved), 3))
        assert (whole(y) != before).any()
        poses.append(y)
    collapsed = x.copy()
    collapsed[i] = 0.5 * (x[j] + x[k])  # on the opposite side: the triangle's area is zero
    assert whole(collapsed)[len(tri) // 2]
    for y in [x, *poses, collapsed]:
        counted = gap.repair.counted(y, s, scale)
        np.testing.assert_array_equal(counted, whole(y))
        assert not (counted & ~gap.repair.defects(y, s, None, None, scale=scale)).any()
    broken = x.copy()
    broken[i] = np.nan
    assert gap.repair.counted(broken, s, scale).all()


def test_a_count_reusing_its_first_check_is_the_whole_check_with_fresh_frames():
    """``Repair.counted`` checks a pose without the interpolated frames, then with them only where
    that finds defects, reusing the first check's sides, normals, flips against both keys and
    collapses (keyed by the pose array, ``s`` and ``scale``, held only inside the count). It counts
    what the whole check with the frames computed afresh counts, triangle by triangle, on the
    curling finger (two poses, 120° at each of two joints) at three factors: fitted, folded over
    twice between the joints (the tip flipped without the frames, not with them), curled by the
    interpolated angles, that curl folded, and the fold jittered; also where one array is
    overwritten in place with another pose between two counts, and where another pose is checked
    whole at the same ``s`` and ``scale`` inside the count (while its frames are made)."""
    from test_inbetween_untangling import _pushed_past

    keys, tri, gap, x, curl, centre = _two_pose_finger()
    repair = gap.repair
    second = int(np.argmin(np.abs(np.linalg.norm(x - x[centre], axis=1) - 0.15)
                           + 10 * (np.abs(x[:, 1] - x[centre, 1]) > 0.02)))
    folded = _pushed_past(_pushed_past(x, tri, centre), tri, second)
    poses = [x, folded, curl, _pushed_past(curl, tri, centre),
             folded + np.random.default_rng(0).normal(scale=0.02, size=folded.shape)]

    def whole(y, s, scale):
        frames, stretch = repair.factor_targets(s)[:2]
        return repair.defects(y, s, frames, stretch, scale=scale)

    taken_out = 0  # poses whose first check finds flips the frames take out: the second check's work
    for s in (0.25, 0.5, 0.75):
        scale = gap.area_scale(s)
        buffer = x.copy()
        counts = [repair.counted(y, s, scale) for y in poses] + [repair.counted(buffer, s, scale)]
        buffer[:] = folded  # the same array, another pose: counted again with nothing checked between
        counts.append(repair.counted(buffer, s, scale))
        for y, counted in zip(poses + [x, folded], counts):  # the whole checks after all the counts
            expected = whole(y, s, scale)
            taken_out += bool((repair.defects(y, s, None, None, scale=scale) & ~expected).any())
            np.testing.assert_array_equal(counted, expected)
    assert taken_out >= 3 and whole(folded, 0.5, gap.area_scale(0.5)).any()
    s, scale = 0.5, gap.area_scale(0.5)
    expected, made = whole(folded, s, scale), repair.factor_targets

    def meddling(t):  # another pose checked whole inside the count, at its s and scale
        repair.defects(poses[3], t, None, None, scale=scale)
        return made(t)

    repair.factor_targets = meddling
    try:
        counted = repair.counted(folded, s, scale)
    finally:
        del repair.factor_targets
    np.testing.assert_array_equal(counted, expected)


def test_a_count_after_another_counts_what_a_count_of_its_own_counts():
    """Inside an in-between's scope (``fields_kept``), a count after another at the same factor
    (the repair of the pose counted before, the same pose again) rechecks only the triangles at the
    vertices the pose moved, and must count what a count of its own counts, triangle by triangle:
    the curling finger fitted half-way (its tip facing away from both keys as the interpolated
    rotations turn it: no defect), one fan folded over, then a second one, then the same pose again,
    then a pose moved everywhere; a count at another factor or outside the scope likewise."""
    from core.inbetween_defects import RECHECKED_SHARE
    from test_inbetween_untangling import _pushed_past

    keys, tri, gap, x, curl, centre = _two_pose_finger()
    s = 0.5
    second = int(np.argmin(np.abs(np.linalg.norm(x - x[centre], axis=1) - 0.15)
                           + 10 * (np.abs(x[:, 1] - x[centre, 1]) > 0.02)))
    once = _pushed_past(x, tri, centre)
    twice = _pushed_past(once, tri, second)
    shaken = x + np.random.default_rng(3).normal(scale=1e-3, size=x.shape)  # every vertex moved
    scale = gap.area_scale(s)
    poses = (x, once, twice, twice.copy(), shaken, twice)
    alone = [gap.repair.counted(y, s, scale) for y in poses]  # each a count of its own
    assert alone[0].sum() == 0 < alone[1].sum() < alone[2].sum()  # the tip is no defect; the fans are
    moved = np.zeros(len(tri), dtype=bool)
    moved[gap.topo.triangles_around(np.array([centre, second]))] = True
    assert moved.sum() <= RECHECKED_SHARE * len(tri)  # the folds are rechecked, not counted whole
    other = gap.repair.counted(twice, 0.25, gap.area_scale(0.25))
    with gap.repair.fields_kept():
        for y, expected in zip(poses, alone):
            np.testing.assert_array_equal(gap.repair.counted(y, s, scale), expected)
        np.testing.assert_array_equal(gap.repair.counted(twice, 0.25, gap.area_scale(0.25)), other)
    np.testing.assert_array_equal(gap.repair.counted(twice, s, scale), alone[2])


def test_every_count_after_another_over_random_repairs_counts_what_a_count_of_its_own_counts(monkeypatch):
    """The reuse of the last count (``_rechecked``) over random series of repairs of the curling
    finger at ¼, ½, ¾ in one scope each, every count against a count of the same pose made alone:
    fans folded over, regions moved by 1e-9 to 0.05, the pose counted before changed in place,
    coordinates set to 0.0 and −0.0 (not moved to the check: no comparison reads a zero's sign),
    a corner put on another (collapsed), a vertex not finite (every triangle a defect, the next
    count against the last finite one), the whole pose moved, another factor counted between and a
    scale made anew (not the kept one). Triangle by triangle the same; most counts rechecked."""
    from concurrent.futures import ThreadPoolExecutor

    from core import inbetween_defects
    from test_inbetween_untangling import _pushed_past

    keys, tri, gap, x0, curl, centre = _two_pose_finger()
    repair, rng, rechecked = gap.repair, np.random.default_rng(7), []
    real = inbetween_defects.DefectChecks._rechecked

    def counting(self, *args):
        made = real(self, *args)
        rechecked.append(made is not None)
        return made

    monkeypatch.setattr(inbetween_defects.DefectChecks, "_rechecked", counting)

    def alone(y, s, scale):  # in another thread: outside this thread's scope, nothing reused
        return other.submit(repair.counted, y.copy(), s, scale).result()

    n, total = len(x0), 0
    with ThreadPoolExecutor(1) as other:
        for series in range(6):
            s = (0.25, 0.5, 0.75)[series % 3]
            with repair.fields_kept():
                scale = repair.factor_area_scale(s)
                y = (x0 if series % 2 else curl).copy()
                for step in range(20):
                    near = np.flatnonzero(np.linalg.norm(y - y[rng.integers(n)], axis=1) < 0.1)
                    change = rng.integers(8)
                    if change == 0:
                        y = _pushed_past(y, tri, int(rng.integers(n)))
                    elif change == 1:
                        y = y.copy()
                        y[near] += rng.normal(scale=rng.choice([1e-9, 1e-3, 0.05]), size=(near.size, 3))
                    elif change == 2:  # the array counted before, changed in place
                        y[near] += rng.normal(scale=0.02, size=(near.size, 3))
                    elif change == 3:
                        y[near, rng.integers(3)] = rng.choice([0.0, -0.0])
                    elif change == 4:
                        corners = tri[rng.integers(len(tri))]
                        y = y.copy()
                        y[corners[0]] = y[corners[1]]
                    elif change == 5:
                        y = y.copy()
                        y[rng.integers(n), rng.integers(3)] = np.nan
                    elif change == 6:
                        y = y + rng.normal(scale=1e-3, size=y.shape)
                    else:
                        between = 0.5 if s != 0.5 else 0.25  # another factor counted between
                        repair.counted(y, between, repair.factor_area_scale(between))
                        scale = scale if rng.random() < 0.5 else gap.area_scale(s)
                    expected = alone(y, s, scale)
                    np.testing.assert_array_equal(repair.counted(y, s, scale), expected)
                    total += 1
                    if not np.isfinite(y).all():
                        y = np.where(np.isfinite(y), y, x0)
    assert total == 120 and sum(rechecked) > 40  # the reuse was taken, not only the whole check


def test_a_regions_check_tests_pieces_as_turning_whole_only_where_a_candidate_field_faces_away(monkeypatch, strip):
    """What a region's check asks of the whole mesh (``_whole_may_pass``) where its candidates
    (triangles facing away from both keys) follow their interpolated normals: where none of those
    normals faces away from both keys (a triangle rolled over sideways as the field swings it past
    the keys' normals, not turned past a half turn), no piece can turn whole, and the pieces are not
    tested (they were, for every field's fit of every region); where they face away and the
    candidates follow them, the piece turns whole, and the whole mesh may pass them. Each answer is
    the pieces' own test's (``_whole_pieces`` with no piece turning far)."""
    from core import inbetween_turned_away
    from core.geometry import coordinate_dot

    flat, tri = strip
    gap = SequenceInterpolator([_bend(flat, a) for a in (0.0, 1.0, 2.0)], tri)._gap(0)
    piece = np.flatnonzero(gap.topo.triangle_component == 0)
    rows = piece  # every triangle of one piece a candidate
    r = rows.size
    base, nxt = np.tile([[0.0], [0.0], [1.0]], r), np.tile([[1.0], [0.0], [0.0]], r)  # keys' normals 90° apart
    real = inbetween_turned_away.TurnedAway._whole_pieces
    monkeypatch.setattr(gap, "turning", np.zeros(len(gap.topo.piece_sizes), dtype=bool))  # no piece turns far
    pieces_turn = []
    for normal, cross in ((np.tile([[0.3], [0.9], [0.3]], r), np.tile([[-0.1], [1.0], [-0.1]], r)),  # rolled over
                          (np.tile([[-1.0], [0.0], [-1.0]], r), np.tile([[-1.0], [0.0], [-1.0]], r))):  # turned past
        following = coordinate_dot(cross, normal)
        assert (following > 0).all() and (coordinate_dot(cross, base) < 0).all() and (coordinate_dot(cross, nxt) < 0).all()
        passes = gap.repair._whole_may_pass(cross, following, normal, base, nxt, rows)
        whole = real(gap.repair, cross, normal, following, base, nxt, gap.topo.triangle_component[rows])
        pieces_turn.append(bool(whole(np.zeros(len(gap.topo.piece_sizes), dtype=bool))[0].any()))
        assert passes == pieces_turn[-1]
    assert pieces_turn == [False, True]  # the shortcut's answer where the field faces away and where not


def test_a_regions_checks_follow_the_stretches_they_are_given(strip):
    """The checks of one region keep its target areas while they are given the same stretches; given
    others (another field's, or whole ones) on the same rows, they check against those: each equals
    the whole mesh's check on the rows."""
    flat, tri = strip
    gap = SequenceInterpolator([_bend(flat, a) for a in (0.0, 1.0, 2.0)], tri)._gap(0)
    s = 0.5
    x = gap.linear_blend(s)
    rows = np.arange(0, len(tri), 3)
    wide = gap.stretch(s).copy()
    narrow = wide.copy()
    narrow[:, 0] *= 1e4  # every interpolated area 10,000 × larger: each triangle collapsed against it
    for stretch in (wide, narrow, wide):
        expected = gap.repair.defects(x, s, None, stretch)[rows]
        np.testing.assert_array_equal(gap.repair.defects(x, s, None, stretch, rows=rows), expected)
    assert not gap.repair.defects(x, s, None, wide, rows=rows).any()
    assert gap.repair.defects(x, s, None, narrow, rows=rows).all()


def test_a_gap_repaired_on_its_regions_is_freed_at_once(strip):
    """A gap whose in-between a repair fixed region by region (the interpolated stretches computed by
    rows, each region's checks keeping its target areas) is freed when the last reference to it
    goes, not at the next full garbage collection: what the checks keep holds no reference back to
    the gap. (A sequence otherwise kept each gap it let go alive for a while: a 100k-vertex sheet
    keyed every 4th frame over 16 gaps peaked at 2.2 GB, 1.06 GB without it.)"""
    import gc
    import weakref

    flat, tri = strip
    gap = SequenceInterpolator([_bend(flat, a) for a in (0.0, 1.0, 2.0)], tri)._gap(0)
    s = 0.5
    crumpled = gap.linear_blend(s) + np.random.default_rng(1).normal(scale=0.05, size=flat.shape)
    assert gap.repair.defects(crumpled, s, None, None, scale=gap.area_scale(s)).any()
    enabled = gc.isenabled()
    gc.disable()
    try:
        x, _ = gap.repaired(crumpled.copy(), s)
        assert (x != crumpled).any()  # the repair moved its regions
        freed = weakref.ref(gap)
        del gap
        assert freed() is None
    finally:
        if enabled:
            gc.enable()


def test_a_predictions_repairs_compute_the_blends_geometry_once(monkeypatch, strip):
    """A predicted in-between no repair cleans is repaired, solved from its repair and that solve
    repaired, at one factor: each triangle's local geometry of the linear blend (and of the
    keys' spline) there is computed once for all of them (``_per_factor`` holds each factor's work
    in ``Repair.fields_kept``), and the in-betweens are what each repair alone gives, bit for bit."""
    import core.deformation_fields as df

    keys, tri, factors, _, _ = _predictions_flagged(monkeypatch, strip)
    alone = SequenceInterpolator(keys, tri).poses(0, factors)
    computed: dict = {}  # the positions' bytes: the triangles whose geometry was computed there
    real = df.corner_edges

    def corner_edges(points, triangles):
        computed.setdefault(points.tobytes(), []).extend(map(tuple, triangles))
        return real(points, triangles)

    monkeypatch.setattr(df, "corner_edges", corner_edges)
    np.testing.assert_array_equal(SequenceInterpolator(keys, tri).poses(0, factors), alone)
    blends = [computed.get(((1.0 - s) * keys[0] + s * keys[1]).tobytes()) for s in factors if s not in (0.25, 0.75)]
    assert all(blends)  # every prediction's repairs imposed the blend's geometry
    assert all(len(rows) == len(set(rows)) for rows in computed.values())


def test_a_regions_check_reads_its_own_triangles_corners_alone(strip):
    """A check on rows (a repair region's fit) equals the whole mesh's check there for a finite
    pose; a corner of theirs that is not finite makes every one of them a defect, and a vertex
    that is not finite elsewhere in the pose changes none of them (the region's check reads its
    corners alone: a repair moves only its region's vertices)."""
    flat, tri = strip
    gap = SequenceInterpolator([_bend(flat, a) for a in (0.0, 1.0, 2.0)], tri)._gap(0)
    s, scale = 0.5, gap.area_scale(0.5)
    rng = np.random.default_rng(3)
    x = gap.linear_blend(s) + rng.normal(scale=0.03, size=flat.shape)
    rows = np.arange(0, len(tri) // 2)
    whole = gap.repair.defects(x, s, None, None, scale=scale)
    checked = gap.repair.defects(x, s, None, None, rows=rows, scale=scale)
    assert whole[rows].any() and not whole[rows].all()
    np.testing.assert_array_equal(checked, whole[rows])
    inside, outside = tri[rows].ravel()[0], np.setdiff1d(np.arange(len(flat)), tri[rows])[0]
    for vertex, expected in ((inside, np.ones(len(rows), dtype=bool)), (outside, checked)):
        y = x.copy()
        y[vertex] = np.nan
        np.testing.assert_array_equal(gap.repair.defects(y, s, None, None, rows=rows, scale=scale), expected)
    y[outside] = np.nan
    assert gap.repair.defects(y, s, None, None, scale=scale).all()  # the whole mesh's check: all of them


def test_an_in_betweens_reads_of_a_spline_at_its_factor_share_one_evaluation(monkeypatch, strip):
    """Inside one in-between's scope (``Repair.fields_kept``) each spline of the gap is evaluated
    whole at the factor once, however many readers (the prediction, the guide, the stretches, the
    repairs' fields) ask, and so is the area scale of the defect checks; the values are the
    spline's own, read-only (no reader may change what the others read), evaluated anew outside
    the scope; and the in-betweens of a gap whose predictions are repaired are those made with
    every reader evaluating its own, bit for bit."""
    import core.inbetween_field as field
    import core.inbetween_repair_rounds as rounds
    import core.splines as splines

    keys, tri, factors, _, _ = _predictions_flagged(monkeypatch, strip)
    kept = SequenceInterpolator(keys, tri).poses(0, factors)
    with monkeypatch.context() as each_its_own:
        each_its_own.setattr(rounds.RepairRounds, "factor_spline", lambda self, name, s: self.gap.splines[name].at(s))
        each_its_own.setattr(rounds.RepairRounds, "factor_area_scale", lambda self, s: self.gap.area_scale(s))
        np.testing.assert_array_equal(SequenceInterpolator(keys, tri).poses(0, factors), kept)

    gap = SequenceInterpolator(keys, tri)._gap(0)
    s = 0.375
    gap.select(s)  # the anchor of in-betweens: its guide reads the world spline
    evaluated, real_at = [], splines.HermiteGap.at  # the splines evaluated whole at s

    def at(self, u, rows=None):
        if rows is None and u == s:
            evaluated.append(id(self))
        return real_at(self, u, rows)

    monkeypatch.setattr(splines.HermiteGap, "at", at)
    scales, real_scale = [], field.InterpolatedField.area_scale
    monkeypatch.setattr(field.InterpolatedField, "area_scale", lambda self, s: scales.append(s) or real_scale(self, s))

    def readers():  # the guide, the prediction's co-moving spline, the stretches, the checks' areas twice
        motion = gap.motion(s)
        return [gap.guide(s, motion), gap.spline_at("vertices", s), gap.stretch(s), gap.spline_at("world", s),
                gap.repair.factor_area_scale(s), gap.repair.factor_area_scale(s)]

    alone = readers()
    vertices, world = id(gap.splines["vertices"]), id(gap.splines["world"])
    assert evaluated.count(vertices) == 2 and evaluated.count(world) == 2 and len(scales) == 2
    evaluated.clear(), scales.clear()
    with gap.repair.fields_kept():
        shared = readers()
    assert evaluated.count(vertices) == 1 and evaluated.count(world) == 1 and len(scales) == 1
    assert len(evaluated) == len(set(evaluated))
    for a, b in zip(shared, alone):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(shared[1], real_at(gap.splines["vertices"], s))
    for value in (shared[1], shared[3], shared[4]):
        assert not value.flags.writeable
        with pytest.raises(ValueError):
            value[0] = 0.0
    evaluated.clear()
    gap.spline_at("vertices", s)
    assert evaluated == [vertices]  # let go at the scope's end


def _two_pose_finger():
    """Two poses of the finger of ``test_inbetween_untangling._curling_finger`` (curled by 120° at
    each of two joints between them) and their in-between's gap fitted half-way: (keys, triangles,
    the gap, its clean fit at 0.5, whose tip faces away from both keys as the interpolated rotations
    turn it, the finger curled by the interpolated angles, the number of the tip's triangles)."""
    from test_inbetween_untangling import _curling_finger

    keys, tri, curl, centre = _curling_finger()
    gap = Interpolator(keys[0], keys[1], tri)._sequence._gap(0)
    x, problem = gap.pose(0.5)
    turned = _flipped(curl, keys[0], keys[1], tri)
    assert problem is None and turned > 0 and _flipped(x, keys[0], keys[1], tri) == turned
    return keys, tri, gap, x, curl, centre


def _against_the_curl(y, keys, tri, curl) -> int:
    """Triangles of ``y`` facing against both keys and against the curled finger's own normal."""
    n = _normals(y, tri)
    return int(np.sum((np.einsum("ij,ij->i", n, _normals(keys[0], tri)) < 0)
                      & (np.einsum("ij,ij->i", n, _normals(keys[1], tri)) < 0)
                      & (np.einsum("ij,ij->i", n, _normals(curl, tri)) < 0)))


def test_two_poses_fallback_near_the_blend_counts_as_the_fit_is_checked_not_the_tip_turned_away(monkeypatch):
    """Two poses of a finger curling 120° at each of two joints, their in-between's fit at 0.5 with
    two fans folded over between the joints (more defects than the keys' blend has), not repaired
    (``repairable`` 0), so the fallback near the blend is tried; the fit near the blend made the
    clean fit itself (its tip faces away from both keys as the interpolated rotations turn it,
    which is no defect where the fit is checked). The fallback is taken as free of defects: count
    0, said as "with no triangle flipped or collapsed", as the independent count against the curl
    has it. Checked without the interpolated frames, the tip's triangles counted as flipped and the
    warning read "which keeps 0 triangle(s) flipped or collapsed … no repair or fallback removed
    them all"."""
    from core.inbetween_repair import Repair
    from test_inbetween_untangling import _pushed_past

    keys, tri, gap, x, curl, centre = _two_pose_finger()
    frames, stretch, motion, guide = gap.targets(0.5)[:4]
    second = int(np.argmin(np.abs(np.linalg.norm(x - x[centre], axis=1) - 0.15)
                           + 10 * (np.abs(x[:, 1] - x[centre, 1]) > 0.02)))
    folded = _pushed_past(_pushed_past(x, tri, centre), tri, second)
    blend = gap.linear_blend(0.5)
    assert gap.repair.defects(folded, 0.5, frames, stretch).sum() > gap.repair.defects(blend, 0.5, frames, stretch).sum()
    monkeypatch.setattr(Repair, "fitted_near_blend", lambda self, blend, s, stretch, motion: x.copy())
    y, said, count, near_blend = gap.repair.outcome(folded, folded, 0.5, frames, stretch, guide, motion, repairable=0)
    assert np.array_equal(y, x) and near_blend
    assert count == _against_the_curl(y, keys, tri, curl) == 0
    assert "with no triangle flipped or collapsed" in said and "keeps" not in said


def test_two_poses_fit_nearer_the_metric_counts_as_the_fit_is_checked_not_the_tip_turned_away(monkeypatch):
    """Two poses of the curling finger (above): an in-between far from the interpolated metric (the
    keys' blend with noise of 0.02, outcome clean) is replaced by the fit near the blend, made the
    clean fit itself, which has no more defects as the fit is checked (its tip turns away as the
    interpolated rotations turn it): returned with no message, counted 0, as the count against the
    curl has it. Counted without the interpolated frames, its tip's triangles were 48 defects,
    more than the in-between's 0, and the in-between far from the metric was kept."""
    from core.inbetween_repair import Outcome, Repair

    keys, tri, gap, x, curl, centre = _two_pose_finger()
    frames, stretch, motion, guide = gap.targets(0.5)[:4]
    far = gap.linear_blend(0.5) + 0.02 * np.random.default_rng(0).standard_normal(x.shape)
    gap.outcomes[0.5] = Outcome(0, False)
    targets = gap.fit_targets(frames if gap.use_extrinsic else None, stretch)
    monkeypatch.setattr(Repair, "fitted_near_blend", lambda self, blend, s, stretch, motion: x.copy())
    y, said, count, near_blend = gap.repair.nearer_the_metric((far, None), 0.5, frames, stretch, motion, targets)
    assert np.array_equal(y, x) and said is None and near_blend
    assert count == _against_the_curl(y, keys, tri, curl) == 0


def test_two_poses_fallback_is_counted_with_its_pinned_vertices_put_back(monkeypatch):
    """Two poses of a strip bent 2.5 rad about its end x = 0, whose six vertices there stay still (the
    gap's pinned ``static`` vertices, which the gap's finish puts back where the keys have them); the fit at
    0.5 with a vertex pushed past its neighbour (two flipped triangles), not repaired (``repairable`` 0),
    and a fit near the blend made the blend moved 0.2 along −x, which is clean as it stands but flips the
    ten triangles at the still end once those vertices are put back (its neighbours lie past them). The
    outcome's count and words are those of the pose as the gap returns it (its pins set): the independent
    count of triangles facing against both keys agrees. Before, the fallback was counted with its pinned
    vertices left where the fit put them: "with no triangle flipped or collapsed", count 0, and the pose
    returned had 10 (on a cape pinned to a turning arm, keys 16 frames apart, 1,457 said for 1,487)."""
    from core.inbetween_repair import Repair
    from test_inbetween_untangling import _pushed_past

    flat, tri = _strip()
    keys = [flat, _bend(flat, 2.5)]
    gap = Interpolator(keys[0], keys[1], tri)._sequence._gap(0)
    assert gap.static is not None and gap.static.sum() == 6
    x, _ = gap.pose(0.5)
    frames, stretch, motion, guide = gap.targets(0.5)[:4]
    folded = _pushed_past(x, tri, int(np.argmin(np.linalg.norm(x - x.mean(axis=0), axis=1))))
    shifted = np.array([-0.2, 0.0, 0.0])
    monkeypatch.setattr(Repair, "fitted_near_blend", lambda self, blend, s, stretch, motion: blend + shifted)
    y, said, count, _ = gap.repair.outcome(folded, folded, 0.5, frames, stretch, guide, motion, repairable=0)
    returned = y.copy()
    gap._pins_set(returned, 0.5)  # as the gap's finish does
    assert count == _flipped(returned, keys[0], keys[1], tri) > 0
    assert f"keeps {count} triangle(s) flipped or collapsed" in said
