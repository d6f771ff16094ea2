"""All the in-betweens of one gap at once: the reconstruction solved at a few factors, the others
predicted from them (the sequence part of "solving all in-betweens of a gap together").

Between two keys the reconstruction ``N(s)`` of :meth:`core.inbetween_solver._Gap.pose` differs
from the gap's guide — the keys' per-vertex spline with each component's interpolated rigid
motion undone, ``V(s)``, moved by that motion ``M(s)`` — by a correction that vanishes at both
keys and varies smoothly with ``s``: the part of the motion a per-vertex spline cannot follow
(arcs of turning parts, edge lengths kept). :func:`gap_poses` solves ``N`` at the requested
factors nearest :data:`SOLVED_FACTORS`, writes their corrections in the co-moving frame,
``D_j = M(s_j)⁻¹ N(s_j) − V(s_j)``, and predicts every other in-between as
``M(s) (V(s) + D(s))`` with ``D`` the polynomial through ``(0, 0)``, the ``(s_j, D_j)`` and
``(1, 0)`` (degree 3 for two solved factors); with three, ``D`` also takes at each key the slope
that gives the pose the guide's velocity there (degree 6, :data:`KEY_SLOPE_SOLVED`), so that
consecutive gaps meet at a key with one velocity, and so it does with the middle alone (degree 4,
batches of three: :data:`MIDDLE_SOLVED_BATCH`). A rigid motion has ``D = 0`` and is reproduced
exactly at every factor; a gap where every component moves rigidly (a cloth in free flight, one
lying still) is ``M(s) V(s)`` at every factor, without a solve, and one whose keys barely differ
(:data:`STILL_MOVE`) the linear blend of its keys. A predicted pose with a flipped or collapsed
triangle is repaired where its defects are, as a solved pose is (:meth:`core.inbetween_solver._Gap.repaired`;
numbers in docs/inbetweens.md). Measured (docs/inbetweens.md): on the
14k tablecloth, the 1k drape and the 576-vertex falling sheet with keys 4, 8 and 16 frames apart,
median RMS within 1 % and mean edge deviation within 0.05 point of solving every in-between.
"""

from __future__ import annotations

import functools

import numpy as np

from .concurrency import concurrently
from .inbetween_fit import KEY_VARIATION_FRACTION, LOCAL_STEP_DTYPE, METRIC_TOLERANCE
from .inbetween_repair_rounds import REPAIR_RINGS


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
#: With this many solved factors (batches of :data:`FULL_SAMPLE_BATCH` in-betweens or more: keys 9
#: frames apart or more), and with the middle alone (:data:`MIDDLE_SOLVED_BATCH`), the correction's
#: slope at each key is prescribed too: the one that gives
#: the in-between the velocity of the gap's guide there — the keys' per-vertex spline in the world
#: where a piece deforms, C¹ across the keys, and its interpolated rigid motion where it moves
#: rigidly (slope zero: rigid motions stay exact). Consecutive gaps then leave a key with one
#: velocity; before, the base ``M(s) V(s)`` kinked there with the rigid motions interpolated per
#: gap, and so did the corrections. Keys 16 frames apart: largest frame-to-frame jump of the soft 20k
#: flag 3.09 → 1.25 × the simulation's, the 1k flag 2.66 → 1.45 ×, the banner 1.39 → 0.98 ×; edge
#: deviation down on the scenes that miss its bound (curtain 8.57 → 7.98 %, banner 6.00 → 5.51 %,
#: balloon 2.95 → 2.66 %); RMS within −0.027 / +0.017 × Catmull–Rom (numbers in docs/inbetween-measurements.md,
#: *Pops*). With two solved factors the slopes cost RMS (keys 8 apart: soft flags +0.012 / +0.015 ×
#: Catmull–Rom) and the jumps there are 0.4–1.6 × already.
KEY_SLOPE_SOLVED = 3
#: Step (in factor) of the one-sided differences that give the guide's and the base's velocities at
#: a key: both are cubic in ``s``, so the slope is within ~1e-4 of its value.
SLOPE_STEP = 1e-4
#: Batches of at most this many in-betweens (keys 4 frames apart) solve only the one nearest the
#: middle and predict the others with the keys' slopes (:data:`KEY_SLOPE_SOLVED`): the correction is
#: then the quartic through the keys' zeros and slopes and the middle's value. RMS ÷ Catmull–Rom at
#: g = 4 on 28 cloths, before → after: two sheets 1.055 → 1.011, tablecloth 0.754 → 0.716, curtain
#: 0.897 → 0.846, 1k flag 0.890 → 0.853, balloon 0.929 → 0.915; the largest losses a 31k tablecloth
#: baked at quality 3 0.760 → 0.786, the 400-vertex hanging sheet 0.810 → 0.836, lift 0.945 →
#: 0.956; 50k / 100k sheets 0.929 / 0.884 → 0.930 / 0.888; edge deviation +0.00–0.06 point; time
#: 0–16 % less (balloon 19.1 → 16.4, 10k hanging sheet 16.7 → 14.0 ms per in-between, alternated
#: runs). Without the slopes (the quadratic through the middle) the falling sheet was 1.24 × the
#: RMS of solving the quarter points; with keys 8 apart the middle alone lost (10k hanging sheet
#: 0.783 → 0.834, the balloon's edge deviation 1.56 → 2.00 %).
MIDDLE_SOLVED_BATCH = 3
#: Largest difference, in mean edge lengths (RMS over the vertices, at any predicted factor), between
#: the two corrections the middle alone supports (:data:`MIDDLE_SOLVED_BATCH`) in the gap of a
#: sequence of two keys: the quartic with the keys' slopes and the parabola without them. The slopes
#: give the prediction the guide's velocity at the keys, and with two keys that is their chord's,
#: which neither key tells. Where a part turns about a joint (a limb of a rig) the chord is short of
#: the arc, the two corrections part, and the prediction misses the pose solved at its factor by about
#: as much as they part (skinned arm, spine, root and a bent tube: 0.9–1.0 ×); above this the other
#: in-betweens of the gap are solved too. Two keys 4 frames apart: 0.92–3.4 mean edges on skinned
#: characters (arm bent 100°: 1.8e-2 → 5.6e-3 of the diagonal off the rig's poses, spine twisted 90°
#: 8.9e-3 → 3.1e-3, root moving with arm and head 1.13e-2 → 8.7e-3), 0.42 on a tube bent 100°, 0.15 bent
#: 60° (predicted as before). With three keys or more the check is not made: in the end gaps of 12
#: cloths it reaches 0.29 mean edges, and solving the curtain's last gap raised its RMS at g = 4
#: (÷ Catmull–Rom 0.847 → 0.903) and its CPU by a quarter (numbers in docs/inbetween-measurements.md,
#: *Two keys of a skinned character*).
MAX_SLOPE_DISAGREEMENT = 0.25
#: Batches with three solved factors (:data:`FULL_SAMPLE_BATCH` in-betweens or more: keys 9
#: frames apart or more) fit to the tolerance without the largest key-to-key changes
#: (:data:`core.inbetween_fit.TOLERANCE_TRIM`); smaller ones to the whole change's. Where one
#: solved in-between serves three (keys 4 apart) or two serve seven (8 apart) the extra fit steps
#: cost 15–45 % per in-between on the cheapest 10k bakes, for edge deviation already within its
#: bound there (numbers in docs/inbetweens.md, *Design numbers*).
TRIMMED_TOLERANCE_BATCH = FULL_SAMPLE_BATCH
#: In a gap above the tolerance's floor predicted from two solved factors (keys 5–8 frames apart),
#: a middle prediction farther from the interpolated metric than the solved ones reached by more
#: than this many times the keys' mean relative edge change has every prediction of the gap solved
#: in its place (:func:`_stretched_predictions`): an in-between's metric lies between the keys', so
#: a pose off it by twice the whole key-to-key change is stretched by the correction polynomial,
#: not by the motion. Stiff cloth whose triangles turn far between keys 8 apart (Blender's denim
#: and leather presets): a 12k denim flag's middle predictions 2.5 and 5.5 × its change past the
#: solved ones' misfit in two of six gaps, a leather tablecloth's 7.1 ×; the benchmark cloths at
#: most 1.6 × (the balloon's first gap). The whole gap, not only the predictions that are off: the
#: denim flag's frames otherwise alternate between solves and predictions (largest frame-to-frame
#: jump 3.18 × the simulation's with the off ones solved, 0.91 × with the gap; numbers in
#: docs/inbetweens.md, *All the in-betweens of a gap at once*).
STRETCHED_PREDICTION_CHANGES = 2.0
#: Batches of fewer in-betweens than this are all solved (prediction saves nothing then).
MIN_PREDICTED_BATCH = 3
#: Most repairs of an in-between that kept defects, each from the last one's pose while it leaves
#: fewer (:func:`_repaired_again`; in gaps predicted from solved in-betweens: a gap solved at every
#: factor keeps each in-between's first repair). The leather flag at keys 8 frames apart, the curtain and the
#: lifted sheet at 16: no in-between took more than five; with at most two the curtain keeps 46
#: flipped triangles, with three 34, with five or more 33.
REPAIR_PASSES = 8
#: A prediction that no repair cleans (or, in a rough gap, that keeps more defects than the solved
#: in-betweens around it) is solved in its place from the repaired prediction rather than from the
#: Poisson solve of the field, with at most this many local/global steps (not
#: :data:`~core.inbetween_fit.ARAP_ITERATIONS`): the prediction interpolates the corrections of the
#: solved in-betweens around it, which are fits, so it is near the metric everywhere but where the
#: folds are, and a few steps settle those (a fit from the Poisson solve starts 1.5–2.3 × the
#: tolerance farther off). Where that fit ends within the tolerance with defects left, the
#: prediction's defects are not the metric's doing and the pose is solved from the Poisson solve
#: too (the one with fewer defects kept, that one on a tie). Keys 16 frames apart, six steps from
#: the Poisson solve → this: 100k sheet edge deviation 3.33 → 3.30 %, flipped triangles 7 → 5, its
#: two such solves 422 / 431 → 201 / 248 ms; 50k sheet 3.23 → 3.23 %, 4 → 4; two sheets 4.01 →
#: 3.99 %, 15 → 14; curtain the same (its two fall back to the Poisson solve); keys 8 apart,
#: curtain 4.12 → 4.10 %, 48 → 41; RMS the same to four digits in every cell. A fit from the
#: Poisson solve with this many steps leaves the edges farther off (50k sheet 3.26 %, curtain at
#: g = 8 4.13 %); six steps from the prediction cost as much as six from the Poisson solve for
#: 0.00–0.02 point less (numbers in docs/inbetween-measurements.md, *Predictions solved in place
#: from themselves*).
SOLVED_INSTEAD_ITERATIONS = 3
#: The solve of a prediction from itself (:data:`SOLVED_INSTEAD_ITERATIONS`) whose fit has more
#: than this many times the flipped or collapsed triangles the prediction had before its repair is
#: not repaired (its fallbacks are still tried): it is kept only with no more defects than the
#: repaired prediction, and a repair leaves more defects the more its start has. Of 28 such solves
#: in the sequences of 21 cloths at keys 4, 8 and 16 apart, the eight whose fits had 1.30–12.5 ×
#: the prediction's defects all kept more after their repairs than the repaired prediction; the
#: most a kept one had was 1.02 × (427 against 417, repaired to 8 against 9). The repairs not run
#: were 0.30 s of the 4.6 s a waved 17.6k flag's sequence costs at keys 8 apart (0.94 × its CPU),
#: every in-between the same bit for bit (numbers in docs/inbetween-measurements.md, *Solves of
#: predictions not repaired where they cannot win*).
UNREPAIRED_SOLVE_DEFECTS = 1.25
#: With this many solved in-betweens or more (keys 9 frames apart or more), the predictions get one
#: local/global step toward the interpolated metric, anchored to themselves, at the middle of each
#: span between the solved factors and the keys, and its displacement spread over the span
#: (:func:`_relaxed_correction`).
RELAXED_SOLVED = 3
#: Largest relative miss (RMS over the vertices, against the correction's own RMS) of the middle
#: solved correction predicted from the others; above it the gap is solved at every eighth
#: (:data:`ROUGH_SOLVED_FACTORS`) and the in-betweens between those predicted from them.
#: Measured with keys 16 frames apart: 0.01–0.38 on the benchmark cloths, 0.76 in the gap where the
#: flag pinned at its pole flaps about once (its in-betweens solved: 1.073 → 1.000 × the per-vertex
#: Catmull–Rom spline's RMS, edge deviation 2.28 → 1.50 %; every other scene unchanged).
MAX_CROSS_VALIDATION = 0.5
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
#: The factors solved in a gap too rough to predict from three (:data:`MAX_CROSS_VALIDATION`): those
#: asked nearest to these, with :data:`ROUGH_ROTATION_DEVIATION`; the others are predicted from the
#: two solved around them (:class:`_PiecewiseLinearCorrection`), 1/16 of the gap away at most, and
#: solved where their repair leaves more defects than both of those. Keys 16 frames apart,
#: 18 → 10 solves per rough gap: a 40k denim sheet spun 124° by a fan in one gap 0.84 × the CPU per
#: in-between, RMS the same, edge deviation +0.16 point in that gap, fewer flipped triangles
#: (numbers in docs/inbetweens.md, *All the in-betweens of a gap at once*).
ROUGH_SOLVED_FACTORS = tuple(np.arange(1, 8) / 8)
#: Repair rounds of a predicted in-between when a solved one of the same gap kept defects that no
#: repair removed (a gap where the keys fold triangles through): the regions up to 4 rings only.
#: 50k sheet over a cube edge, keys 16 frames apart: 0.37 → 0.25 s per in-between, flipped
#: triangles unchanged (113; keys 8 apart: 10); 10k drape on a sphere, keys 8 apart: 1 → 2.
REDUCED_ROUNDS = 3
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
#: In-betweens of meshes with at least this many vertices are solved and predicted in threads
#: (:func:`core.concurrency.concurrently`); on smaller meshes the arrays are too short for NumPy's
#: released global lock to outweigh handing the work over (1,024-vertex drape, keys 4 frames
#: apart: 4.2 → 5.0 ms per in-between in two threads).
CONCURRENT_VERTICES = 5000


def gap_poses(gap, factors) -> list[tuple[np.ndarray, str | None]]:
    """``(positions (n, 3), problem or None)`` at each of ``factors`` (floats, extrapolations and
    keys included) of ``gap`` (a ``core.inbetween_solver._Gap``). The in-betweens are solved,
    and predicted, concurrently (:func:`core.concurrency.concurrently`)."""
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
    stubborn = any(problem for _, problem in solved.values())
    outer = _outer_correction(gap, solved)
    middle = solved_factors[1] if outer is not None else None
    for s in solved_factors:  # those that kept defects their repair did not remove; the middle near the outer two
        with gap.repair.fields_kept():
            solved[s] = _repaired_again(gap, s, solved[s], outer if s == middle else None)
    positions = {s: x for s, (x, _) in solved.items()}
    correction = _correction(gap, positions)
    predicted = [s for s in interior if s not in solved]
    if len(solved) == 1 and _slopes_disagree(gap, correction, positions, predicted):
        return _solved(gap, factors, solved)  # the keys' slopes and the middle tell different in-betweens
    if len(solved) >= 3 and _inconsistent(gap, positions):  # too rough to predict from three: every eighth solved, all at the wide limit
        gap.rotation_limit = ROUGH_ROTATION_DEVIATION
        try:
            return _rough_poses(gap, factors, interior)
        finally:
            del gap.rotation_limit  # the class's again: a gap's poses never depend on earlier calls
    if len(solved) >= RELAXED_SOLVED and not stubborn:
        correction = _relaxed_correction(gap, correction, sorted(solved))
    rings = REPAIR_RINGS[:REDUCED_ROUNDS] if stubborn else None

    def predict(s):
        return _repaired_again(gap, s, _predicted(gap, s, correction, rings), outer, rings)

    solved.update(zip(predicted, _per_factor(gap, predict, predicted)))
    _solve_off_metric(gap, solved, solved_factors, predicted)
    return _solved(gap, factors, solved)


def _outer_correction(gap, solved: dict):
    """Of three solved in-betweens ``solved`` {factor: (positions, problem)} whose outer two came
    out clean, the correction polynomial through the keys and those two alone
    (:func:`_correction`), made when first asked (a function of no arguments: most gaps never ask);
    else None (:func:`_repaired_again`)."""
    if len(solved) != 3:
        return None
    first, _, last = sorted(solved)
    if solved[first][1] is not None or solved[last][1] is not None:
        return None
    outer = {first: solved[first][0], last: solved[last][0]}
    return functools.cache(lambda: _correction(gap, outer))


def _repaired_again(gap, s: float, pose: tuple, outer=None, rings=None) -> tuple[np.ndarray, str | None]:
    """``pose`` (positions, problem), an in-between at ``s`` that kept defects no repair removed,
    repaired again from itself (:meth:`core.inbetween_solver._Gap.repaired_again`; ``rings``: the
    repair rounds), and again from each repair that leaves fewer defects, up to
    :data:`REPAIR_PASSES` times: a repair that fails keeps the fit with the fewest defects, whose
    parts its rounds repaired partly by a field that left some, and grows its regions around what
    the pose it started from kept, so it never tries again around the fewer left; a repair started
    from that fit does. Its moves are counted from ``pose``: a pass that takes the pose farther
    than one repair may move it (:meth:`~core.inbetween_repair_rounds.RepairRounds.move_limits`)
    is not taken. In a gap whose outer two solved in-betweens are clean (``outer()``,
    :func:`_outer_correction`), each pass has one more field, tried last in every region: the local
    geometry of the pose that the correction polynomial through the keys and those two alone predicts
    at ``s``. Where the keys fold triangles through, the middle's fit folds some of them the wrong
    way and no field of its repair unfolds them (the interpolated rotations, the blend's, the keys'
    and their spline's geometry fold them too), and the predictions made from it inherit them; the
    solves a quarter of the gap away came out clean, and the pose they predict has folds of its own,
    elsewhere, but not those. The last pose that kept fewer defects is returned, else ``pose`` (the
    rounds start from it: never more). Clean poses are returned as they are. Keys 8 frames apart,
    the leather flag swinging round its pole keeps 1 flipped triangle instead of 117 (the middle of
    its fourth gap: 1,285 in the prediction, 115 after its repair, 29 after one more); keys 16
    apart, the sphere lifting a 10k sheet keeps 10 instead of 18, the ball through the 15k curtain
    33 instead of 104 (numbers in docs/inbetween-measurements.md, *Repairs again from the fewest
    defects*)."""
    if pose[1] is None:
        return pose
    scale = gap.area_scale(s)
    defects = gap.repair.defects(pose[0], s, None, None, scale=scale)
    count = int(defects.sum())
    if not count:  # a fallback without flipped or collapsed triangles: nothing to repair
        return pose
    nearby = None if outer is None else _predicted_positions(gap, s, outer(), gap.motion(s))
    start, (limit, partial_limit) = pose[0], gap.repair.move_limits(s) or (np.inf, np.inf)  # none for two keys
    outcome = gap.outcomes.get(s)
    for _ in range(REPAIR_PASSES):
        # never more defects: the rounds start from pose
        repaired = gap.repaired_again(pose[0], s, nearby, rings, defects)
        fewer = gap.repair.defects(repaired[0], s, None, None, scale=scale)
        moved = float(np.sum((repaired[0] - start) ** 2))
        if fewer.sum() >= count or moved > (partial_limit if fewer.any() else limit):
            break
        pose, defects, count, outcome = repaired, fewer, int(fewer.sum()), gap.outcomes.get(s)
        if not count:
            break
    _put_back(gap, s, outcome)
    return pose


def _rough_poses(gap, factors, interior: list) -> list[tuple[np.ndarray, str | None]]:
    """The poses at ``factors`` of a gap too rough to predict from three solved factors: those
    nearest :data:`ROUGH_SOLVED_FACTORS` solved, each other one predicted from the two solved
    (or keys) around it (:class:`_PiecewiseLinearCorrection`), repaired as any prediction, and
    solved where it keeps more defects than both of those."""
    targets = sorted({min(interior, key=lambda s: abs(s - q)) for q in ROUGH_SOLVED_FACTORS})
    predicted = [s for s in interior if s not in targets]
    if not predicted:
        return _solved(gap, factors, {})
    solved = dict(zip(targets, _solved(gap, targets, {})))
    correction = _PiecewiseLinearCorrection({s: _co_moving_correction(gap, s, x) for s, (x, _) in solved.items()})
    rings = REPAIR_RINGS[:REDUCED_ROUNDS] if any(problem for _, problem in solved.values()) else None
    # a prediction keeps no more defects than the solved in-betweens (or keys: none) it lies between
    left = {0.0: 0, 1.0: 0, **{s: int(gap.repair.defects(x, s, None, None, scale=gap.area_scale(s)).sum())
                               for s, (x, problem) in solved.items() if problem}}
    knots = sorted(left.keys() | solved.keys())

    def predict(s):
        after = int(np.searchsorted(knots, s))
        allowed = max(left.get(knots[after - 1], 0), left.get(knots[after], 0))
        return _predicted(gap, s, correction, rings, allowed)

    solved.update(zip(predicted, _per_factor(gap, predict, predicted)))
    _solve_off_metric(gap, solved, targets, predicted)
    return _solved(gap, factors, solved)


def _solve_off_metric(gap, results: dict, solved: list, predicted: list) -> None:
    """Replaces in ``results`` {factor: (positions, problem)} poses at ``predicted`` factors by
    their solves: in a gap whose keys are of one metric (the tolerance at its floor), those that
    end off the metric the ``solved`` ones reached (:func:`_off_metric`); in a gap above the floor
    predicted from two solved factors, every one where the middle prediction is stretched
    (:func:`_stretched_predictions`). A prediction that kept defects is replaced only where its
    solve keeps no more, a clean one only by a clean solve."""
    if gap.tolerance <= METRIC_TOLERANCE:
        off = _off_metric(gap, {s: results[s][0] for s in solved}, {s: results[s][0] for s in predicted})
    elif len(solved) == 2:
        off = _stretched_predictions(gap, results, solved, predicted)
    else:
        return
    def solve(s):  # where both keep defects, the solve repaired again as the prediction was
        pose = _solved_instead(gap, s)
        return _repaired_again(gap, s, pose) if results[s][1] is not None else pose

    before = {s: gap.outcomes.get(s) for s in off}  # the predictions' (their solves store their own)
    for s, pose in zip(off, _per_factor(gap, solve, off)):
        if pose[1] is None:
            results[s] = pose
        elif results[s][1] is not None and _defect_count(gap, s, pose[0]) <= _defect_count(gap, s, results[s][0]):
            results[s] = pose  # both keep defects: the solve where it keeps no more
        else:
            _put_back(gap, s, before[s])


def _defect_count(gap, s: float, x: np.ndarray, scale: np.ndarray | None = None) -> int:
    """The flipped and collapsed triangles of positions ``x`` (n, 3) at factor ``s`` (``scale``:
    the gap's ``area_scale(s)``, if made already)."""
    scale = gap.area_scale(s) if scale is None else scale
    return int(gap.repair.defects(x, s, None, None, scale=scale).sum())


def _stretched_predictions(gap, results: dict, solved: list, predicted: list) -> list:
    """All the ``predicted`` factors of ``results`` {factor: (positions, problem)} if the prediction
    nearest the middle of the gap (the farthest from both ``solved`` factors: the cubic
    correction's bulge) is farther from the interpolated metric than the two solved ones reached
    by more than :data:`STRETCHED_PREDICTION_CHANGES` × the keys' mean relative edge change (the
    gap's tolerance over :data:`~core.inbetween_fit.KEY_VARIATION_FRACTION` above its floor);
    else none. The solved ones' misfits are measured only where the middle's exceeds that
    excess."""
    excess = STRETCHED_PREDICTION_CHANGES * gap.tolerance / KEY_VARIATION_FRACTION
    middle = min(predicted, key=lambda s: abs(s - 0.5))
    misfit = _misfit(gap, middle, results[middle][0])
    if misfit <= excess:  # not off, whatever the solved reached (a misfit is not negative)
        return []
    limit = max(_misfit(gap, s, results[s][0]) for s in solved) + excess
    if misfit <= limit:
        return []
    return list(predicted)


def _misfit(gap, s: float, x: np.ndarray) -> float:
    """The misfit of positions ``x`` at factor ``s`` (the fit's measure: mean relative deviation of
    the edge lengths from the interpolated metric's, whose lengths come from the metric's spline
    without its square root: :meth:`~core.inbetween_field.InterpolatedField.metric_lengths`)."""
    return gap.misfit(gap.edges_of(x, LOCAL_STEP_DTYPE), {"lengths": gap.metric_lengths(s)})


def _off_metric(gap, solved: dict, predicted: dict) -> list:
    """The factors of the ``predicted`` poses {factor: positions} farther from the interpolated
    metric than the ``solved`` ones {factor: positions} reached by more than the gap's tolerance
    (the misfit a fit accepts): such a prediction is no stand-in for a solve, and is solved.
    Asked only in gaps whose keys' edges change by less than twice
    :data:`~core.inbetween_fit.METRIC_TOLERANCE` (the tolerance at its floor: a stiff cloth, a
    sheet bending without stretch), where the metric to keep is the keys' own and the correction
    polynomial's stretch is all the prediction's; elsewhere the check (~3 ms per in-between at 15k
    vertices) would cost the cheapest bakes' margin. Leather draped over a turning cylinder (12k
    vertices, the simulation's edges 0.09 % off), keys 4 frames apart: predictions 0.2–1.2 % off the
    metric beside solved middles at 0.1–0.7 %, the cell's edge deviation 0.49 → 0.27 % (bound
    0.29 %), RMS 0.828 → 0.824 × Catmull–Rom, 31 → 48 ms per in-between (0.029 → 0.044 × the
    bake's CPU). The predictions' misfits are measured first: where none is beyond the tolerance
    none is off whatever the solved ones reached (a misfit is not negative), and those are not
    measured."""
    misfits = {s: _misfit(gap, s, x) for s, x in predicted.items()}
    if max(misfits.values(), default=0.0) <= gap.tolerance:  # none is off, whatever the solved reached
        return []
    reached = max(_misfit(gap, s, x) for s, x in solved.items())
    return [s for s, misfit in misfits.items() if misfit > reached + gap.tolerance]


def _solved_instead(gap, s: float) -> tuple[np.ndarray, str | None]:
    """The pose solved at ``s`` in place of a prediction, with the weak anchor if the gap's solved
    in-betweens were (see :func:`_solved`)."""
    return gap.pose(s, weak=True if any(gap.held_factors.values()) else None)


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
    (then they are solved)."""
    out = {}
    for s in factors:
        x = gap.topo.apply_motion(gap.splines["vertices"].at(s), *gap.motion(s))
        if not np.isfinite(x).all() or gap.repair.defects(x, s, None, None, scale=gap.area_scale(s)).any():
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
        known = {**known, **dict(zip(interior, _per_factor(gap, solve, interior)))}
        held = {s: gap.held_factors.get(s, False) for s in known if 0.0 < s < 1.0}
        if any(held.values()):
            strong = [s for s, was_weak in held.items() if not was_weak]
            known.update(zip(strong, _per_factor(gap, weak, strong)))
    return [known[s] if s in known else gap.pose(s) for s in factors]


def _per_factor(gap, function, factors) -> list:
    """``[function(s) for s in factors]``, in threads on meshes of :data:`CONCURRENT_VERTICES` or more;
    each call's repairs share the blend's and the spline's local geometry at its factor
    (:meth:`~core.inbetween_repair_rounds.RepairRounds.fields_kept`)."""
    def kept(s):
        with gap.repair.fields_kept():
            return function(s)
    return concurrently(kept, factors, worth_it=gap.topo.n >= CONCURRENT_VERTICES)


def _co_moving_correction(gap, s: float, x: np.ndarray) -> np.ndarray:
    """``M(s)⁻¹ x − V(s)`` (n, 3): positions ``x`` at factor ``s`` in the co-moving frame, less the
    keys' co-moving spline."""
    return gap.topo.undo_motion(x, *gap.motion(s)) - gap.splines["vertices"].at(s)


def _correction(gap, solved: dict) -> "_CorrectionPolynomial":
    """The polynomial of the co-moving corrections ``D(s)`` (n, 3) through the keys (zero) and the
    ``solved`` poses {factor: positions}, with the keys' slopes (:data:`KEY_SLOPE_SOLVED`; with
    one solved pose too, :data:`MIDDLE_SOLVED_BATCH`)."""
    values = {s: _co_moving_correction(gap, s, x) for s, x in solved.items()}
    slopes = (_key_slope(gap, 0.0), _key_slope(gap, 1.0)) if len(solved) >= KEY_SLOPE_SOLVED or len(solved) == 1 else None
    return _CorrectionPolynomial(values, slopes)


def _key_slope(gap, s: float) -> np.ndarray:
    """``D'(s)`` (n, 3) at key ``s`` (0 or 1) that gives the pose ``M (V + D)`` the velocity of the
    gap's guide there: ``M(s)⁻¹ (G'(s) − (M V)'(s))`` (``D(s) = 0`` at a key), by a one-sided
    difference inside the gap (:data:`SLOPE_STEP`) of the guide's offset from ``M V``, which is
    zero at the key. On components that turn as a whole (guided by ``M V``,
    :data:`core.inbetween_guide.ARC_GUIDE_STRAIN_RATIO`) the world spline's velocity, which the
    gaps on either side of the key share, except at a sequence's last key."""
    step = SLOPE_STEP if s == 0.0 else -SLOPE_STEP
    rotations, _ = gap.motion(s)
    last = s == 1.0 and gap.relatives[3].extrapolated
    change = gap.guide_offset(s + step, gap.motion(s + step), arcs=last) / step
    return gap.topo.undo_motion(change, rotations, np.zeros((len(rotations), 3)))


class _CorrectionPolynomial:
    """``D(s)``: the polynomial through ``(0, 0)``, the ``(s_j, D_j)`` of ``values`` {factor:
    (n, 3)} and ``(1, 0)``, and with ``slopes`` ((n, 3) at s = 0 and at s = 1) those derivatives
    at the keys too — the sum of each condition's value times its cardinal polynomial, whose
    monomial coefficients come from one (K × K) solve (K ≤ 7 conditions). Written out rather than
    SciPy's ``KroghInterpolator``: ``scipy.interpolate`` pulls in ``scipy.optimize`` and adds 0.1 s
    to the first in-between of a Blender session."""

    def __init__(self, values: dict, slopes: tuple[np.ndarray, np.ndarray] | None = None):
        self.factors = sorted(values)
        conditions = [(0.0, 0), *((s, 0) for s in self.factors), (1.0, 0)]  # (node, derivative order)
        data = [None, *(values[s] for s in self.factors), None]  # None: zero
        if slopes is not None:
            conditions += [(0.0, 1), (1.0, 1)]
            data += list(slopes)
        self.powers = np.arange(len(conditions))
        rows = [self.powers * node ** np.maximum(self.powers - 1, 0) if order else node ** self.powers
                for node, order in conditions]
        self.cardinal = np.linalg.inv(np.array(rows, dtype=float))  # column k: condition k's polynomial
        self.terms = [(k, value) for k, value in enumerate(data) if value is not None]

    def __call__(self, s: float) -> np.ndarray:
        weights = (float(s) ** self.powers) @ self.cardinal
        out = np.zeros_like(self.terms[0][1])
        for k, value in self.terms:
            out += weights[k] * value
        return out


class _PiecewiseLinearCorrection:
    """``D(s)`` (n, 3) of a rough gap: linear between the two knots around ``s`` among the keys
    (zero) and the solved corrections ``values`` {factor: (n, 3)}. Corrections that do not vary
    smoothly give no polynomial to trust between the knots; the chord never leaves the two it
    joins (a cubic through four rough knots overshoots them)."""

    def __init__(self, values: dict):
        self.knots = [0.0, *sorted(values), 1.0]
        self.values = [None, *(values[s] for s in sorted(values)), None]  # None: zero

    def __call__(self, s: float) -> np.ndarray:
        right = min(max(int(np.searchsorted(self.knots, s, side="right")), 1), len(self.knots) - 1)
        a, b = self.knots[right - 1], self.knots[right]
        w = (float(s) - a) / (b - a)
        out = np.zeros_like(next(v for v in self.values if v is not None))
        for weight, value in ((1.0 - w, self.values[right - 1]), (w, self.values[right])):
            if value is not None:
                out += weight * value
        return out


def _slopes_disagree(gap, correction: "_CorrectionPolynomial", solved: dict, factors: list) -> bool:
    """Whether ``gap`` joins the only two keys of a sequence (the keys' spline is their chord) and
    ``correction`` (the quartic through the keys' zeros and slopes and the one ``solved`` pose
    {factor: positions}) and the parabola through the keys' zeros and that pose alone differ by
    more than :data:`MAX_SLOPE_DISAGREEMENT` mean edge lengths (RMS over the vertices) at one of
    ``factors``: the slopes, which no key tells, then decide the predictions there, not the solved
    pose."""
    if gap.cubic:  # three keys or more: the slope at an inner key is the neighbouring keys' central difference
        return False
    (s, x), = solved.items()
    parabola = _CorrectionPolynomial({s: _co_moving_correction(gap, s, x)})
    limit = (MAX_SLOPE_DISAGREEMENT * gap.mean_edge) ** 2
    return any(np.mean(np.sum((correction(f) - parabola(f)) ** 2, axis=1)) > limit for f in factors)


def _inconsistent(gap, solved: dict) -> bool:
    """Whether the corrections of the ``solved`` poses {factor: positions} (three or more) do not
    vary smoothly enough to predict from: the middle one, predicted from the others, misses it by
    more than :data:`MAX_CROSS_VALIDATION` of its size."""
    factors = sorted(solved)
    middle = factors[len(factors) // 2]
    others = {s: x for s, x in solved.items() if s != middle}
    predicted = _correction(gap, others)(middle)
    actual = _co_moving_correction(gap, middle, solved[middle])
    size = np.sqrt(np.mean(np.sum(actual ** 2, axis=1)))
    return bool(np.sqrt(np.mean(np.sum((predicted - actual) ** 2, axis=1))) > MAX_CROSS_VALIDATION * size)


def _pins_in_place(gap, x: np.ndarray, s: float) -> np.ndarray:
    """Predicted positions ``x`` (n, 3) at factor ``s`` with the pinned vertices moved where they
    belong (``gap.pinned_positions``), and the miss spread around them by one solve of the gap's
    anchored system ``(L + A) δ = A_pinned · miss`` (δ is the miss at the pins and fades over
    ~1/√w edges away from them). A prediction ``M(s) (V(s) + D(s))`` passes through them only at
    the keys and at the solved factors: the interpolated rigid motion of a flapping flag swings
    its pole in between (a flag with small triangles at its pole, keys 8 frames apart: by 22 % of
    the mean edge length), and setting the pins alone back afterwards (``finished``) put the whole
    miss into the triangles at the pole (131 of them turned over). Unchanged where the miss is
    under :data:`~core.inbetween_fit.METRIC_TOLERANCE` of the mean edge length."""
    still = gap.static
    if still is None:
        return x
    miss = gap.pinned_positions(s) - x[still]
    if np.max(np.abs(miss)) <= METRIC_TOLERANCE * gap.mean_edge:
        return x
    factor, anchor = gap.system
    rhs = np.zeros_like(x)
    rhs[still] = anchor[still, None] * miss
    return x + factor.solve(rhs)


def _predicted(gap, s: float, correction: _CorrectionPolynomial, rings=None,
               allowed: int | None = None) -> tuple[np.ndarray, str | None]:
    """The predicted pose at ``s``, repaired (rounds ``rings``, all by default) where it has a
    defect; where no repair removes every defect and ``rings`` is None (the solved in-betweens
    had none left), or more than ``allowed`` defects are left, the pose solved at ``s`` from the
    repaired one (:data:`SOLVED_INSTEAD_ITERATIONS`; repaired only where its fit has at most
    :data:`UNREPAIRED_SOLVE_DEFECTS` × the prediction's defects) instead if it has no more."""
    motion = gap.motion(s)
    x = _predicted_positions(gap, s, correction, motion)
    if not np.isfinite(x).all():
        return gap.pose(s)
    x = _pins_in_place(gap, x, s)
    gap.carried.place(x, s)  # carried pieces rigid before the check: their predicted shapes are not
    scale = gap.area_scale(s)  # the stretches themselves only if there is something to repair
    defects = gap.repair.defects(x, s, None, None, scale=scale)
    if defects.any() and isinstance(correction, _RelaxedCorrection):
        # the relaxation is kept only where it adds no defect to the plain prediction
        plain = _pins_in_place(gap, _predicted_positions(gap, s, correction.correction, motion), s)
        gap.carried.place(plain, s)
        fewer = gap.repair.defects(plain, s, None, None, scale=scale)
        if fewer.sum() < defects.sum():
            x, defects = plain, fewer
    if not defects.any():
        return gap.finished((x, None), s)
    result = gap.repaired(x, s, rings, defects)
    if result[1] is None and gap.repair.moved_far(result[0], x):
        # a clean repair that moves the pose by more than the cloth deforms: the solve, if clean
        solved = _solved_instead(gap, s)
        return solved if solved[1] is None else result
    if result[1] is None or (rings is not None and allowed is None):
        return result

    def count(pose):
        return _defect_count(gap, s, pose, scale)

    kept = count(result[0])  # once: it decides the solve and then weighs against it
    if rings is not None and kept <= allowed:
        return result
    # no repair cleans this prediction where the gap's solved in-betweens are clean, or it keeps more
    # defects than ``allowed``: solve it too, with the weak anchor if they were (see _solved), from
    # the repaired prediction (SOLVED_INSTEAD_ITERATIONS); the solve where it has no more defects,
    # repaired only where its fit has at most UNREPAIRED_SOLVE_DEFECTS × the prediction's defects
    misfits = []
    repaired = gap.outcomes.get(s)  # each check below stores its own: the one of the pose returned is kept
    solved = gap.pose(s, weak=any(gap.held_factors.values()), start=result[0],
                      iterations=SOLVED_INSTEAD_ITERATIONS, misfits=misfits,
                      repairable=UNREPAIRED_SOLVE_DEFECTS * np.count_nonzero(defects))
    defects, outcome = count(solved[0]), gap.outcomes.get(s)
    if solved[1] is not None and misfits[-1] < gap.tolerance:
        # the prediction fits the metric and its fit keeps defects: they are not the metric's doing,
        # the solve from the field's Poisson solve is tried too, and kept on a tie
        fresh = _solved_instead(gap, s)
        fewer = count(fresh[0])
        if fewer <= defects:
            solved, defects, outcome = fresh, fewer, gap.outcomes.get(s)
    if defects <= kept:
        _put_back(gap, s, outcome)
        return solved
    _put_back(gap, s, repaired)
    return result


def _put_back(gap, s: float, outcome) -> None:
    """The gap's outcome at ``s`` set to ``outcome``, the one the check of the pose returned there
    stored (None: that pose was not checked): a later check of a pose not taken stores its own, and
    the in-between's warning counts the flipped or collapsed triangles from it
    (:meth:`core.SequenceInterpolator.poses`)."""
    if outcome is None:
        gap.outcomes.pop(s, None)
    else:
        gap.outcomes[s] = outcome


def _predicted_positions(gap, s: float, correction, motion) -> np.ndarray:
    """The prediction at ``s`` before its pins and carried pieces: the co-moving spline plus the
    ``correction`` at ``s``, moved by the gap's interpolated rigid ``motion`` there."""
    return gap.topo.apply_motion(gap.splines["vertices"].at(s) + correction(s), *motion)


def _relaxation(gap, s: float, correction) -> np.ndarray:
    """The co-moving displacement (n, 3) that one local/global step toward the interpolated metric
    gives the prediction at ``s``: each triangle's metric turned by its own rotation in the
    prediction (the polar factor, no limit about the interpolated rotations), the positions solved
    with the gap's anchor pulling toward the prediction itself (not the spline: its long
    wavelengths stay, its short ones take the metric's lengths)."""
    motion = gap.motion(s)
    x = _pins_in_place(gap, _predicted_positions(gap, s, correction, motion), s)
    targets = gap.local_step_targets(gap.fit_targets(None, gap.stretch(s)))
    y = gap.solve(gap.fitted_edges(gap.edges_of(x, LOCAL_STEP_DTYPE), targets), x)
    return gap.topo.undo_motion(y - x, motion[0], np.zeros((len(motion[0]), 3)))


def _relaxed_correction(gap, correction, factors: list) -> "_RelaxedCorrection":
    """``correction`` plus the relaxations (:func:`_relaxation`) at the middle of each span
    between the keys and the solved ``factors``, each spread over its span by a parabola (one at the
    middle, zero at the span's ends, where the keys and the solved poses already are fits)."""
    knots = [0.0, *factors, 1.0]
    middles = [0.5 * (a + b) for a, b in zip(knots[:-1], knots[1:])]
    return _RelaxedCorrection(correction, knots, _per_factor(gap, lambda s: _relaxation(gap, s, correction), middles))


class _RelaxedCorrection:
    """``D(s)`` of a :class:`_CorrectionPolynomial` plus relaxations spread over the spans
    between ``knots`` (see :func:`_relaxed_correction`)."""

    def __init__(self, correction, knots: list, displacements: list):
        self.correction, self.knots, self.displacements = correction, knots, displacements

    def __call__(self, s: float) -> np.ndarray:
        out = self.correction(s)
        span = min(max(int(np.searchsorted(self.knots, s, side="right")) - 1, 0), len(self.displacements) - 1)
        a, b = self.knots[span], self.knots[span + 1]
        u = (2.0 * s - a - b) / (b - a)
        return out + (1.0 - u * u) * self.displacements[span] if abs(u) < 1.0 else out
