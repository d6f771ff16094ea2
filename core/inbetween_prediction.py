"""All the in-betweens of one gap at once: the reconstruction solved at a few factors, the others
predicted from them (the sequence part of "solving all in-betweens of a gap together").

Between two keys the reconstruction ``N(s)`` of :meth:`core.inbetween_solver.Gap.pose` differs from
the gap's guide — the keys' per-vertex spline with each component's interpolated rigid motion
undone, ``V(s)``, moved by that motion ``M(s)`` — by a correction that vanishes at both keys and
varies smoothly with ``s``: the part of the motion a per-vertex spline cannot follow (arcs of
turning parts, edge lengths kept). :func:`gap_poses` solves ``N`` at the requested factors nearest
:data:`SOLVED_FACTORS`, writes their corrections in the co-moving frame,
``D_j = M(s_j)⁻¹ N(s_j) − V(s_j)``, and predicts every other in-between as ``M(s) (V(s) + D(s))`` with ``D`` the polynomial
through ``(0, 0)``, the ``(s_j, D_j)`` and ``(1, 0)`` (degree 3 for two solved factors); with three,
``D`` also takes at each key the slope that gives the pose the guide's velocity there (degree 6,
:data:`~core.inbetween_corrections.KEY_SLOPE_SOLVED`), so that consecutive gaps meet at a key with
one velocity, and so it does with the middle alone (degree 4, batches of three:
:data:`MIDDLE_SOLVED_BATCH`). A rigid motion has ``D = 0`` and is reproduced exactly at every
factor; a gap where every component moves rigidly (a cloth in free flight, one lying still) is
``M(s) V(s)`` at every factor, without a solve, and one whose keys barely differ
(:data:`STILL_MOVE`) the linear blend of its keys. The correction ``D`` and the positions it
predicts are :mod:`core.inbetween_corrections`; a predicted pose with a flipped or collapsed
triangle is repaired where its defects are, as a solved pose is
(:mod:`core.inbetween_prediction_repairs`, :meth:`core.inbetween_solver.Gap.repaired`; numbers in
docs/inbetweens.md). Measured (docs/inbetweens.md): on the 14k tablecloth, the 1k drape and the
576-vertex falling sheet with keys 4, 8 and 16 frames apart, median RMS within 1 % and mean edge
deviation within 0.05 point of solving every in-between.
"""

from __future__ import annotations

import functools

import numpy as np

from .inbetween_corrections import (RELAXED_SOLVED, PiecewiseLinearCorrection, co_moving_correction,
                                    correction_polynomial, inconsistent, relaxed_correction, slopes_disagree)
from .inbetween_fit import METRIC_TOLERANCE
from .inbetween_prediction_repairs import (REDUCED_ROUNDS, defect_count, held_before, repaired_in_passes, repaired_prediction,
                                          solve_off_metric)
from .inbetween_repair_rounds import REPAIR_RINGS
from .inbetween_threads import per_factor
from .inbetween_untangling import untangled_poses


#: The factors solved in a gap when several in-betweens are asked together: those asked nearest
#: to these. Three solved factors keep the predicted ones within 0.5 % of solved ones in RMS and
#: edge deviation at gaps of 8 and 16 frames.
SOLVED_FACTORS = (0.25, 0.5, 0.75)
#: Batches of fewer in-betweens than this (and more than :data:`MIDDLE_SOLVED_BATCH`) solve only
#: those nearest the outer two of :data:`SOLVED_FACTORS` and predict what lies between. Keys 8
#: frames apart (seven in-betweens): one round of two solves on two cores instead of two rounds, 100k sheet
#: 223–243 → 185–192 ms per in-between, 50k 93–105 → 81–92 ms; RMS ÷ Catmull–Rom within ±0.035 on
#: eight cloths (tablecloth 0.740 → 0.774, soft flag 0.978 → 0.942), edge deviation +0.1–0.2 point
#: within the bounds, flipped triangles on the 50k sheet 10 → 16 (the blend's 199).
FULL_SAMPLE_BATCH = 8
#: Batches of at most this many in-betweens (keys 4 frames apart) solve only the one nearest the
#: middle and predict the others with the keys' slopes
#: (:data:`~core.inbetween_corrections.KEY_SLOPE_SOLVED`): the correction is then the quartic
#: through the keys' zeros and slopes and the middle's value. RMS ÷ Catmull–Rom at g = 4 on 28
#: cloths, before → after: two sheets 1.055 → 1.011, tablecloth 0.754 → 0.716, curtain 0.897 →
#: 0.846, 1k flag 0.890 → 0.853, balloon 0.929 → 0.915; the largest losses a 31k tablecloth
#: baked at quality 3 0.760 → 0.786, the 400-vertex hanging sheet 0.810 → 0.836, lift 0.945 →
#: 0.956; 50k / 100k sheets 0.929 / 0.884 → 0.930 / 0.888; edge deviation +0.00–0.06 point; time
#: 0–16 % less (balloon 19.1 → 16.4, 10k hanging sheet 16.7 → 14.0 ms per in-between, alternated
#: runs). Without the slopes (the quadratic through the middle) the falling sheet was 1.24 × the
#: RMS of solving the quarter points; with keys 8 apart the middle alone lost (10k hanging sheet
#: 0.783 → 0.834, the balloon's edge deviation 1.56 → 2.00 %).
MIDDLE_SOLVED_BATCH = 3
#: Batches with three solved factors (:data:`FULL_SAMPLE_BATCH` in-betweens or more: keys 9
#: frames apart or more) fit to the tolerance without the largest key-to-key changes
#: (:data:`core.inbetween_fit.TOLERANCE_TRIM`); smaller ones to the whole change's. Where one
#: solved in-between serves three (keys 4 apart) or two serve seven (8 apart) the extra fit steps
#: cost 15–45 % per in-between on the cheapest 10k bakes, for edge deviation already within its
#: bound there (numbers in docs/inbetweens.md, *Design numbers*).
TRIMMED_TOLERANCE_BATCH = FULL_SAMPLE_BATCH
#: Batches of fewer in-betweens than this are all solved (prediction saves nothing then).
MIN_PREDICTED_BATCH = 3
#: The local steps' rotation limit (:attr:`core.inbetween_fit.LocalGlobalFit.rotation_limit`,
#: otherwise :data:`core.inbetween_fit.MAX_ROTATION_DEVIATION`, 45°) while the in-betweens of a gap
#: too rough to predict are solved: its corrections do not vary smoothly, so neither do its
#: interpolated rotations, and a fit held within 45° of them stays far from the metric (the flag
#: pinned at its pole, keys 16 frames apart, the gap where it flaps over: misfit 6.7 → 5.3 % over
#: six steps at 45°, 6.7 → 2.6 % unlimited). Mean edge deviation of that flag at g = 16, keys from
#: frame 0 / 4 / 8 / 12: 1.50 / 1.40 / 1.49 / 1.74 % → 1.42 / 1.36 / 1.44 / 1.59 % (bounds 1.17–1.31;
#: 90°: 1.42 / 1.32 / 1.50 / 1.59, 180°: 1.41 / 1.31 / 1.44 / 1.77: wider limits leave more
#: triangles flipped through, which the repairs then undo at the cost of edge length), RMS and
#: flipped triangles unchanged. The three in-betweens solved before the gap was found rough are
#: solved again with it (three more solves): kept at 45° among neighbours at 67.5°, they stood
#: out (a balloon's rough gap, keys 16 apart: its middle in-between 0.07 units, 4 % of the
#: diagonal, off its neighbours; the 1k flag's largest frame-to-frame jump 6.44 → 1.98 × the
#: simulation's in a variant of the rotation splines that made one of its gaps rough).
ROUGH_ROTATION_DEVIATION = 3 * np.pi / 8
#: The factors solved in a gap too rough to predict from three
#: (:data:`~core.inbetween_corrections.MAX_CROSS_VALIDATION`): those asked nearest to these, with
#: :data:`ROUGH_ROTATION_DEVIATION`; the others are predicted from the two solved around them
#: (:class:`~core.inbetween_corrections.PiecewiseLinearCorrection`), 1/16 of the gap away at most,
#: and solved where their repair leaves more defects than both of those. Keys 16 frames apart,
#: 18 → 10 solves per rough gap: a 40k denim sheet spun 124° by a fan in one gap 0.84 × the CPU per
#: in-between, RMS the same, edge deviation +0.16 point in that gap, fewer flipped triangles
#: (numbers in docs/inbetweens.md, *All the in-betweens of a gap at once*).
ROUGH_SOLVED_FACTORS = tuple(np.arange(1, 8) / 8)
#: A sequence's gap whose keys' vertices move by less than this many mean edge lengths (RMS over
#: each piece's vertices), and not rigidly to within :data:`STILL_RIGIDITY`, is the linear blend of
#: its keys: a chord across a turn of angle θ is short of the arc by 1 − cos(θ/2) ≈ θ²/8, which is
#: the fit's own tolerance (:data:`~core.inbetween_fit.METRIC_TOLERANCE`, a mean relative deviation)
#: at θ = √(8 · 0.1 %) ≈ 0.089, so the fit has no metric to add to such a gap and what it adds is
#: the splines' velocity borrowed from the gaps around it. A cloth lying over a rail, nearly still
#: after frame 16 (keys 0.004–0.12 mean edges apart): 1.074 / 1.037 / 2.059 → 0.897 / 1.000 / 0.804 ×
#: the blend's RMS at g = 4 / 8 / 16 (Catmull–Rom 1.000 / 1.000 / 1.069 → 0.835 / 0.964 / 0.417 ×);
#: a flat sheet settling after its landing 0.660 / 0.975 → 0.790 / 0.823 × at g = 4 / 8 (its decay is
#: smooth: the cubic follows it); the other 100 of the 105 cells of 35 cloths unchanged.
STILL_MOVE = float(np.sqrt(8.0 * METRIC_TOLERANCE))
#: ... unless every piece moves rigidly to within this fraction of its diagonal (the rigid-motion
#: guarantee's 1e-6): a rigid motion, however small, stays the rigid motion at every factor.
STILL_RIGIDITY = 1e-6


def gap_poses(gap, factors, ahead=None) -> list[tuple[np.ndarray, str | None]]:
    """``(positions (n, 3), problem or None)`` at each of ``factors`` (floats, extrapolations and
    keys included) of ``gap`` (a ``core.inbetween_solver.Gap``). The in-betweens are solved,
    and predicted, concurrently (:func:`core.concurrency.concurrently`); those that keep flipped
    or collapsed triangles after their repairs are untangled where that cleans them
    (:func:`core.inbetween_untangling.untangled_poses`). ``ahead``: a function of no arguments
    called once the batch of predictions is reached, where one in-between may run alone in the
    pool (a sequence begins its next gap there, :mod:`core.sequence_gaps_ahead`), or None."""
    return untangled_poses(gap, factors, _gap_poses(gap, factors, ahead))


def _gap_poses(gap, factors, ahead=None) -> list[tuple[np.ndarray, str | None]]:
    """:func:`gap_poses` before the untangling."""
    interior = sorted({s for s in factors if 0.0 < s < 1.0})
    if interior and not gap.anchored and _nearly_still(gap):
        blend = {s: gap.finished((gap.linear_blend(s), None), s) for s in interior}
        return _solved(gap, factors, blend)
    if interior and not gap.anchored and (gap.rigidity > 0.0).all():
        moved = _moved_rigidly(gap, interior)
        if moved is not None:
            return _solved(gap, factors, moved)
    trimmed = not gap.anchored and len(interior) >= TRIMMED_TOLERANCE_BATCH
    gap.tolerance = gap.trimmed_tolerance if trimmed else gap.change_tolerance
    # a piece a part of which turns far from the rest (gap.turning) is not anchored to the per-vertex spline, whose
    # chord of its curl a correction polynomial does not bend back onto the arc: solved at every factor
    if gap.anchored or len(interior) < MIN_PREDICTED_BATCH or gap.turning is not None:
        return _solved(gap, factors, {})
    if len(interior) <= MIDDLE_SOLVED_BATCH:
        targets = (SOLVED_FACTORS[1],)
    elif len(interior) < FULL_SAMPLE_BATCH:
        targets = (SOLVED_FACTORS[0], SOLVED_FACTORS[-1])
    else:
        targets = SOLVED_FACTORS
    solved_factors = sorted({min(interior, key=lambda s: abs(s - q)) for q in targets})
    solved = dict(zip(solved_factors, _solved(gap, solved_factors, {})))
    if len(solved) >= 3 and inconsistent(gap, {s: x for s, (x, _) in solved.items()}):
        return _rough(gap, factors, interior, ahead)  # too rough as solved: every eighth solved, no repairs again
    stubborn = any(problem for _, problem in solved.values())
    outer = _outer_correction(gap, solved)
    middle = solved_factors[1] if outer is not None else None
    as_solved = dict(solved)
    for s in solved_factors:  # those that kept defects their repair did not remove; the middle near the outer two
        with gap.repair.fields_kept():
            solved[s] = repaired_in_passes(gap, s, solved[s], outer if s == middle else None)
    repaired = any(solved[s] is not as_solved[s] for s in solved)  # a pose not repaired again comes back as it was
    positions = {s: x for s, (x, _) in solved.items()}
    correction = correction_polynomial(gap, positions)
    predicted = [s for s in interior if s not in solved]
    if len(solved) == 1 and slopes_disagree(gap, correction, positions, predicted):
        return _solved(gap, factors, solved)  # the keys' slopes and the middle tell different in-betweens
    if len(solved) >= 3 and repaired and inconsistent(gap, positions):  # a repair again can put it past the limit
        return _rough(gap, factors, interior, ahead)
    if len(solved) >= RELAXED_SOLVED and not stubborn:
        correction = relaxed_correction(gap, correction, sorted(solved))
    rings = REPAIR_RINGS[:REDUCED_ROUNDS] if stubborn else None

    held = held_before(gap)  # the solved in-betweens': read once, the same for every prediction

    def predict(s):
        return repaired_in_passes(gap, s, repaired_prediction(gap, s, correction, rings, held=held), outer, rings,
                                  untangle=True)

    if ahead is not None:
        ahead()
    solved.update(zip(predicted, per_factor(gap, predict, predicted)))
    solve_off_metric(gap, solved, solved_factors, predicted)
    return _solved(gap, factors, solved)


def _outer_correction(gap, solved: dict):
    """Of three solved in-betweens ``solved`` {factor: (positions, problem)} whose outer two came
    out clean, the correction polynomial through the keys and those two alone
    (:func:`core.inbetween_corrections.correction_polynomial`), made when first asked (a function of no
    arguments: most gaps never ask); else None (:func:`core.inbetween_prediction_repairs.repaired_in_passes`)."""
    if len(solved) != 3:
        return None
    first, _, last = sorted(solved)
    if solved[first][1] is not None or solved[last][1] is not None:
        return None
    outer = {first: solved[first][0], last: solved[last][0]}
    return functools.cache(lambda: correction_polynomial(gap, outer))


def _rough(gap, factors, interior: list, ahead=None) -> list[tuple[np.ndarray, str | None]]:
    """:func:`_rough_poses` at the wide rotation limit (:data:`ROUGH_ROTATION_DEVIATION`), for a gap
    whose three solved in-betweens are too rough to predict from
    (:func:`~core.inbetween_corrections.inconsistent`). Read in :func:`_gap_poses` on the solves
    as they come, where a gap that is rough already goes here without the repairs again of those
    three (their poses are solved again here, so those repairs would only feed the check), and
    again after those repairs where one of them moved a pose: a repair of a fold moves the
    middle's correction and can put the gap past the check's limit. Numbers in
    docs/inbetween-measurements.md, *The paddle-wheel sheet's fold read rough before the repairs
    again*."""
    gap.rotation_limit = ROUGH_ROTATION_DEVIATION
    try:
        return _rough_poses(gap, factors, interior, ahead)
    finally:
        del gap.rotation_limit  # the class's again: a gap's poses never depend on earlier calls


def _rough_poses(gap, factors, interior: list, ahead=None) -> list[tuple[np.ndarray, str | None]]:
    """The poses at ``factors`` of a gap too rough to predict from three solved factors (``ahead``:
    as for :func:`gap_poses`): those
    nearest :data:`ROUGH_SOLVED_FACTORS` solved, each other one predicted from the two solved
    (or keys) around it (:class:`~core.inbetween_corrections.PiecewiseLinearCorrection`), repaired
    as any prediction, and solved where it keeps more defects than both of those."""
    targets = sorted({min(interior, key=lambda s: abs(s - q)) for q in ROUGH_SOLVED_FACTORS})
    predicted = [s for s in interior if s not in targets]
    if not predicted:
        return _solved(gap, factors, {})
    solved = dict(zip(targets, _solved(gap, targets, {})))
    correction = PiecewiseLinearCorrection({s: co_moving_correction(gap, s, x) for s, (x, _) in solved.items()})
    rings = REPAIR_RINGS[:REDUCED_ROUNDS] if any(problem for _, problem in solved.values()) else None
    # a prediction keeps no more defects than the solved in-betweens (or keys: none) it lies between
    left = {0.0: 0, 1.0: 0, **{s: defect_count(gap, s, x) for s, (x, problem) in solved.items() if problem}}
    knots = sorted(left.keys() | solved.keys())

    held = held_before(gap)  # the solved in-betweens': read once, the same for every prediction

    def predict(s):
        after = int(np.searchsorted(knots, s))
        allowed = max(left.get(knots[after - 1], 0), left.get(knots[after], 0))
        return repaired_prediction(gap, s, correction, rings, allowed, held=held)

    if ahead is not None:
        ahead()
    solved.update(zip(predicted, per_factor(gap, predict, predicted)))
    solve_off_metric(gap, solved, targets, predicted)
    return _solved(gap, factors, solved)


def _nearly_still(gap) -> bool:
    """Whether the keys of ``gap`` differ by less than :data:`STILL_MOVE` mean edge lengths (RMS
    over each piece's vertices) by a motion that is not rigid to within :data:`STILL_RIGIDITY`."""
    topo = gap.topo
    squared = np.sum((gap.next.vertices - gap.base.vertices) ** 2, axis=1)
    limit = (STILL_MOVE * gap.mean_edge) ** 2
    if topo.components:  # each piece's mean over its vertices
        rows, labels = topo.component_vertices, topo.component_labels
        means = np.bincount(labels, squared[rows]) / np.bincount(labels)
    else:
        means = np.array([np.mean(squared)])
    return bool((means < limit).all()) and max(gap.relatives[2].nonrigidity) > STILL_RIGIDITY


def _moved_rigidly(gap, factors) -> dict | None:
    """In a gap of a sequence whose components all move rigidly across its keys (non-rigidity
    under :data:`core.inbetween_motion.RIGID_PLACEMENT_SCALE` toward each of them: a cloth in free
    flight, one lying still), the in-betweens {factor: (positions, None)} without a solve: the keys'
    co-moving spline moved by the interpolated rigid motions, ``M(s) V(s)``, which is what the
    solve returns for a rigid motion (the fields then are the rigid rotations, the stretches one)
    and what a prediction starts from. None if one of them has a flipped or collapsed triangle
    (as its check counts them, :meth:`~core.inbetween_defects.DefectChecks.counted`: then they are
    solved)."""
    out = {}
    for s in factors:
        x = gap.topo.apply_motion(gap.spline_at("vertices", s), *gap.motion(s))
        if not np.isfinite(x).all() or gap.repair.counted(x, s, gap.area_scale(s)).any():
            return None
        out[s] = gap.finished((x, None), s)
    return out


def _solved(gap, factors, known: dict) -> list[tuple[np.ndarray, str | None]]:
    """``gap.pose(s)`` for each of ``factors`` not in ``known`` {factor: result}: the in-betweens
    concurrently, once the gap's in-between anchor is selected (each solve reads it; the
    extrapolations' anchor differs, so those are solved one after the other). When some of them
    were solved with the weak anchor (held off the metric, see
    :data:`core.inbetween_anchor.HELD_MISFIT`), the others are solved with it too: the one nearest
    the middle of the gap is solved first and, if it was held, the others with the weak anchor
    straight away (the same poses, without their fits with the gap's own anchor)."""
    interior = [s for s in dict.fromkeys(factors) if 0.0 < s < 1.0 and s not in known]
    if interior:
        gap.select(interior[0])
        def weak(s):
            return gap.pose(s, weak=True)

        solve = gap.pose
        if len(interior) > 2 and not gap.anchored:
            middle = min(interior, key=lambda s: abs(s - 0.5))
            known = {**known, middle: gap.pose(middle)}  # the other core prepares the next gap meanwhile
            interior.remove(middle)
            solve = weak if gap.held_factors.get(middle) else solve
        known = {**known, **dict(zip(interior, per_factor(gap, solve, interior)))}
        held = {s: gap.held_factors.get(s, False) for s in known if 0.0 < s < 1.0}
        if any(held.values()):
            strong = [s for s, was_weak in held.items() if not was_weak]
            known.update(zip(strong, per_factor(gap, weak, strong)))
    return [known[s] if s in known else gap.pose(s) for s in factors]
