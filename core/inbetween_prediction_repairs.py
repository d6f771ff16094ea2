"""The repairs of the predicted in-betweens of a gap (:mod:`core.inbetween_prediction`).

A prediction with a flipped or collapsed triangle is repaired where its defects are, as a solved
pose is (:meth:`core.inbetween_solver.Gap.repaired`), and solved in its place where no repair
cleans it (:func:`repaired_prediction`); an in-between, solved or predicted, that kept defects is repaired
again from each repair that leaves fewer (:func:`repaired_in_passes`); and predictions that end off
the interpolated metric are solved in their place (:func:`solve_off_metric`). Numbers in
docs/inbetweens.md and docs/inbetween-measurements.md.
"""

from __future__ import annotations

import numpy as np

from .inbetween_corrections import CorrectionPolynomial, RelaxedCorrection, pins_in_place, predicted_positions
from .inbetween_fit import KEY_VARIATION_FRACTION, LOCAL_STEP_DTYPE, METRIC_TOLERANCE
from .inbetween_repair import Outcome
from .inbetween_threads import per_factor
from .inbetween_untangling import untangled
from .sequence_edge_misfit import MISFIT_NOTED_MARGIN
from .sewn_seams import sewn_together


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
#: Most repairs of an in-between that kept defects, each from the last one's pose while it leaves
#: fewer (:func:`repaired_in_passes`; in gaps predicted from solved in-betweens: a gap solved at every
#: factor keeps each in-between's first repair). The leather flag at keys 8 frames apart, the curtain and the
#: lifted sheet at 16: no in-between took more than five; with at most two the curtain keeps 46
#: flipped triangles, with three 34, with five or more 33.
REPAIR_PASSES = 8
#: A pass of the repairs again that removes fewer than this share of the defects it started from is
#: the last (its pose taken, :func:`repaired_in_passes`): where a fold turns most of the cloth over,
#: every field's region solve folds it again, and each pass removes a smaller share at the cost of
#: a whole repair's rounds; passes that remove a real share of few defects go on as before (under
#: 100 defects one removed is 1 %, so no pass stops for it there). Numbers in docs/inbetweens.md's
#: table and docs/inbetween-measurements.md, *The paddle-wheel sheet's fold at g = 16*.
REPAIR_PASS_LEAST_SHARE = 0.01
#: A sequence's predicted in-between whose repair, or a pass of its repairs again, keeps at most
#: this many flipped or collapsed triangles is untangled then (:func:`untangled_first`: the step
#: every in-between that keeps defects goes through last, :mod:`core.inbetween_untangling`) and,
#: where that leaves it clean, is not repaired again (:func:`repaired_in_passes`). The few defects
#: a repair or a pass leaves are where every field's solve folds them again (the region's boundary
#: sits where the fold needs it): each further pass runs a whole repair's rounds to remove a few,
#: the untangling solves each tangle directly, for a fraction of a pass; with more defects the
#: tangles grow and their untangling costs more than the passes it saves. Not the solved
#: in-betweens, which the predictions are made from: their untangling's local moves reach the
#: predictions and raise the frame-to-frame jumps. Numbers in docs/inbetweens.md's table and
#: docs/inbetween-measurements.md, *Predictions with few defects untangled before the repairs
#: again* and *Predictions untangled after any pass of their repairs again that leaves few defects*.
UNTANGLED_FIRST_DEFECTS = 30
#: ... where the untangling raises the in-between's mean relative edge misfit to the interpolated
#: metric by at most this (the 0.1 point the edge criterion grants beyond twice the keys' own
#: deviation, :data:`core.sequence_edge_misfit.MISFIT_NOTED_MARGIN`): the untangling holds the
#: pose's own edges while it turns each triangle to its side, so a corner reflected across its
#: edge is opened near the edge line, stretched, where a pass of the repairs again puts it back
#: along a field. Where it would cost more, the passes run as before. Measured: a reflected corner
#: on a 180-vertex strip +0.16 point (passes run), a vertex pushed 0.6 edge past its neighbour on a
#: 1,600-vertex sheet +0.005, the 15k curtain's eleven at g = 16 −0.013 … +0.007 point (taken).
UNTANGLED_FIRST_STRETCH = MISFIT_NOTED_MARGIN
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
#: Repair rounds of a predicted in-between when a solved one of the same gap kept defects that no
#: repair removed (a gap where the keys fold triangles through): the regions up to 4 rings only.
#: 50k sheet over a cube edge, keys 16 frames apart: 0.37 → 0.25 s per in-between, flipped
#: triangles unchanged (113; keys 8 apart: 10); 10k drape on a sphere, keys 8 apart: 1 → 2.
REDUCED_ROUNDS = 3


def repaired_prediction(gap, s: float, correction: CorrectionPolynomial, rings=None,
               allowed: int | None = None, held: bool = False) -> tuple[np.ndarray, str | None]:
    """The predicted pose at ``s``, repaired (rounds ``rings``, all by default) where it has a
    defect; where no repair removes every defect and ``rings`` is None (the solved in-betweens
    had none left), or more than ``allowed`` defects are left, the pose solved at ``s`` from the
    repaired one (:data:`SOLVED_INSTEAD_ITERATIONS`; repaired only where its fit has at most
    :data:`UNREPAIRED_SOLVE_DEFECTS` × the prediction's defects) instead if it has no more.
    ``held``: whether the gap's in-betweens solved before the predictions were held off the metric
    (:func:`held_before`), which decides the anchor of those solves. Where what it returns keeps
    at most :data:`UNTANGLED_FIRST_DEFECTS`, that untangled where this cleans it
    (:func:`untangled_first`)."""
    return untangled_first(gap, s, _repaired_prediction(gap, s, correction, rings, allowed, held))


def untangled_first(gap, s: float, pose: tuple) -> tuple[np.ndarray, str | None]:
    """``pose`` (positions (n, 3), problem), a sequence's in-between at ``s`` (0 < s < 1) that keeps
    at most :data:`UNTANGLED_FIRST_DEFECTS` flipped or collapsed triangles as its warning counts
    them, untangled (:func:`core.inbetween_untangling.untangled`) where that leaves it clean and
    raises its mean edge misfit to the metric by at most :data:`UNTANGLED_FIRST_STRETCH`: then
    clean, recorded so in the gap's outcome at ``s`` (as :func:`core.inbetween_untangling.untangled_poses`
    records it), and not repaired again (:func:`repaired_in_passes` returns a clean pose as it is);
    else ``pose`` as it is."""
    if pose[1] is None or not gap.repair.in_sequence(s):
        return pose
    scale = gap.repair.factor_area_scale(s)
    defects = gap.repair.counted(pose[0], s, scale)
    if not defects.any() or np.count_nonzero(defects) > UNTANGLED_FIRST_DEFECTS:
        return pose
    done = untangled(gap, pose[0], s, scale, defects)
    if done is None or done.defects or _stretched_open(gap, s, pose[0], done.positions):
        return pose
    gap.outcomes[s] = Outcome(0, False)
    return done.positions, None


def _stretched_open(gap, s, x, y) -> bool:
    """Whether the untangled ``y`` (n, 3) raises the in-between's misfit to the interpolated metric
    (the fit's measure, ``gap.misfit``, against ``gap.metric_lengths(s)``) above that of ``x``
    (n, 3) by more than :data:`UNTANGLED_FIRST_STRETCH`: measured on the triangles at the vertices
    it moved (the others are the same), their mean's rise scaled to all the mesh's triangles. The
    edges and the metric's lengths are made on those triangles alone (a tangle moves a few dozen of
    the mesh's triangles), and their short edges are measured over the fit's floor, as ``gap.misfit``
    measures them (:func:`~core.inbetween_fit.floored_deviations`)."""
    topo = gap.topo
    rows = np.unique(topo.triangles_around(np.flatnonzero((y != x).any(axis=1))))
    if rows.size == 0:
        return False
    targets = {"lengths": gap.metric_lengths(s, rows)}
    rise = gap.misfit(topo.corner_edge_rows_on(y, rows), targets) - gap.misfit(topo.corner_edge_rows_on(x, rows), targets)
    return rise * rows.size > UNTANGLED_FIRST_STRETCH * len(topo.triangles)


def _repaired_prediction(gap, s: float, correction: CorrectionPolynomial, rings, allowed,
                         held: bool) -> tuple[np.ndarray, str | None]:
    """:func:`repaired_prediction` before :func:`untangled_first`."""
    motion = gap.motion(s)
    x = predicted_positions(gap, s, correction, motion)
    if not np.isfinite(x).all():
        return gap.pose(s)
    x = _placed(gap, x, s)
    scale = gap.repair.factor_area_scale(s)  # the stretches themselves only if there is something to repair
    defects = gap.repair.counted(x, s, scale)
    if defects.any() and isinstance(correction, RelaxedCorrection):
        # the relaxation is kept only where it adds no defect to the plain prediction
        plain = _placed(gap, predicted_positions(gap, s, correction.correction, motion), s)
        fewer = gap.repair.counted(plain, s, scale)
        if fewer.sum() < defects.sum():
            x, defects = plain, fewer
    if not defects.any():
        return gap.finished((x, None), s)
    result = gap.repaired(x, s, rings, defects)
    if result[1] is None and gap.repair.moved_far(result[0], x):
        # a clean repair that moves the pose by more than the cloth deforms: the solve, if clean
        solved = _solved_instead(gap, s, held)
        return solved if solved[1] is None else result
    if result[1] is None or (rings is not None and allowed is None):
        return result

    def count(pose):
        return defect_count(gap, s, pose, scale)

    kept = count(result[0])  # once: it decides the solve and then weighs against it
    if rings is not None and kept <= allowed:
        return result
    # no repair cleans this prediction where the gap's solved in-betweens are clean, or it keeps more
    # defects than ``allowed``: solve it too, with the weak anchor if they were (see
    # core.inbetween_prediction._solved), from the repaired prediction (SOLVED_INSTEAD_ITERATIONS);
    # the solve where it has no more defects, repaired only where its fit has at most
    # UNREPAIRED_SOLVE_DEFECTS × the prediction's defects
    misfits = []
    repaired = _taken(gap, s)  # each check and fit below stores its own: those of the pose returned are kept
    solved = gap.pose(s, weak=held, start=result[0],
                      iterations=SOLVED_INSTEAD_ITERATIONS, misfits=misfits,
                      repairable=UNREPAIRED_SOLVE_DEFECTS * np.count_nonzero(defects))
    defects, outcome = count(solved[0]), _taken(gap, s)
    if solved[1] is not None and misfits[-1] < gap.tolerance:
        # the prediction fits the metric and its fit keeps defects: they are not the metric's doing,
        # the solve from the field's Poisson solve is tried too, and kept on a tie
        fresh = _solved_instead(gap, s, held)
        fewer = count(fresh[0])
        if fewer <= defects:
            solved, defects, outcome = fresh, fewer, _taken(gap, s)
    if defects <= kept:
        _put_back(gap, s, outcome)
        return solved
    _put_back(gap, s, repaired)
    return result


def _placed(gap, x: np.ndarray, s: float) -> np.ndarray:
    """Predicted positions ``x`` (n, 3) at factor ``s`` ready for the defect check: the pinned
    vertices in place (:func:`~core.inbetween_corrections.pins_in_place`), the sewn seams joined
    again (each piece has its own interpolated motion: :func:`core.sewn_seams.sewn_together`) and
    the carried pieces rigid (their predicted shapes are not)."""
    x = sewn_together(gap, pins_in_place(gap, x, s), s)
    gap.carried.place(x, s)
    return x


def _taken(gap, s: float) -> tuple:
    """What the gap holds at ``s`` of the pose just made there, to be put back (:func:`_put_back`)
    where a later pose at ``s`` is not taken: the outcome its check stored and the misfit its fit
    ended at (:attr:`core.inbetween_solver.Gap.fit_misfits`), each None where it has none (a
    prediction has no fit)."""
    return gap.outcomes.get(s), gap.fit_misfits.get(s)


def _put_back(gap, s: float, taken: tuple) -> None:
    """The gap's outcome and fit misfit at ``s`` set to ``taken`` (:func:`_taken` of the pose
    returned there; None: that pose has none): a later check or fit of a pose not taken stores its
    own, and the in-between's warnings count the flipped or collapsed triangles from the outcome
    and read its misfit from the fit (:meth:`core.SequenceInterpolator.poses`)."""
    for held, value in zip((gap.outcomes, gap.fit_misfits), taken):
        if value is None:
            held.pop(s, None)
        else:
            held[s] = value


def repaired_in_passes(gap, s: float, pose: tuple, outer=None, rings=None,
                       untangle: bool = False) -> tuple[np.ndarray, str | None]:
    """``pose`` (positions, problem), an in-between at ``s`` that kept defects no repair removed,
    repaired again from itself (:meth:`core.inbetween_solver.Gap.repaired_again`; ``rings``: the
    repair rounds), and again from each repair that leaves fewer defects, up to
    :data:`REPAIR_PASSES` times: a repair that fails keeps the fit with the fewest defects, whose
    parts its rounds repaired partly by a field that left some, and grows its regions around what
    the pose it started from kept, so it never tries again around the fewer left; a repair started
    from that fit does. Its moves are counted from ``pose``: a pass that takes the pose farther
    than one repair may move it (:meth:`~core.inbetween_repair_rounds.RepairRounds.move_limits`)
    is not taken. In a gap whose outer two solved in-betweens are clean (``outer()``,
    :func:`core.inbetween_prediction._outer_correction`), each pass has one more field, tried last
    in every region: the local geometry of the pose that the correction polynomial through the keys
    and those two alone predicts at ``s``. Where the keys fold triangles through, the middle's fit
    folds some of them the wrong way and no field of its repair unfolds them (the interpolated
    rotations, the blend's, the keys' and their spline's geometry fold them too), and the
    predictions made from it inherit them; the solves a quarter of the gap away came out clean, and
    the pose they predict has folds of its own, elsewhere, but not those. The last pose that kept
    fewer defects is returned (a new tuple), else ``pose`` itself, its positions unchanged (the
    rounds start from it: never more; :func:`core.inbetween_prediction._gap_poses` tells a solved
    in-between not repaired again by that identity). Clean poses are returned as they are. Keys 8 frames apart, the leather flag swinging round its pole keeps 1
    flipped triangle instead of 117 (the middle of its fourth gap: 1,285 in the prediction, 115
    after its repair, 29 after one more); keys 16 apart, the sphere lifting a 10k sheet keeps 10
    instead of 18, the ball through the 15k curtain 33 instead of 104 (numbers in
    docs/inbetween-measurements.md, *Repairs again from the fewest defects*). ``untangle``: a
    prediction's passes (:func:`core.inbetween_prediction._gap_poses`), each of which that leaves
    at most :data:`UNTANGLED_FIRST_DEFECTS` has the pose untangled then (:func:`untangled_first`),
    returned where that cleans it, the passes going on where it does not."""
    if pose[1] is None:
        return pose
    scale = gap.repair.factor_area_scale(s)
    defects = gap.repair.counted(pose[0], s, scale)
    count = int(defects.sum())
    if not count:  # a fallback without flipped or collapsed triangles: nothing to repair
        return pose
    nearby = None if outer is None else predicted_positions(gap, s, outer(), gap.motion(s))
    start, (limit, partial_limit) = pose[0], gap.repair.move_limits(s) or (np.inf, np.inf)  # none for two keys
    outcome = _taken(gap, s)
    for _ in range(REPAIR_PASSES):
        # never more defects: the rounds start from pose
        repaired = gap.repaired_again(pose[0], s, nearby, rings, defects)
        fewer = gap.repair.counted(repaired[0], s, scale)
        moved, left = float(np.sum((repaired[0] - start) ** 2)), int(fewer.sum())
        if left >= count or moved > (partial_limit if left else limit):
            break
        # clean, or a fold no field unfolds (the passes after it remove fewer still): the last pass
        last = not left or count - left < REPAIR_PASS_LEAST_SHARE * count
        pose, defects, count, outcome = repaired, fewer, left, _taken(gap, s)
        if last:
            break
        if untangle and count <= UNTANGLED_FIRST_DEFECTS:  # a prediction a pass left with few: untangled now
            done = untangled_first(gap, s, pose)
            if done[1] is None:  # clean, its outcome recorded so
                return done
    _put_back(gap, s, outcome)
    return pose


def solve_off_metric(gap, results: dict, solved: list, predicted: list) -> None:
    """Replaces in ``results`` {factor: (positions, problem)} poses at ``predicted`` factors by
    their solves: in a gap whose keys are of one metric (the tolerance at its floor), those that
    end off the metric the ``solved`` ones reached (:func:`_off_metric`); in a gap above the floor
    predicted from two solved factors, every one where the middle prediction is stretched
    (:func:`_stretched_predictions`). A prediction that kept defects is replaced only where its
    solve keeps no more, a clean one only by a clean solve."""
    held = held_before(gap)
    if gap.tolerance <= METRIC_TOLERANCE:
        off = _off_metric(gap, {s: results[s][0] for s in solved}, {s: results[s][0] for s in predicted})
    elif len(solved) == 2:
        off = _stretched_predictions(gap, results, solved, predicted)
    else:
        return
    def solve(s, weak=held):  # where both keep defects, the solve repaired again as the prediction was
        pose = _solved_instead(gap, s, weak)
        return repaired_in_passes(gap, s, pose) if results[s][1] is not None else pose

    before = {s: _taken(gap, s) for s in off}  # the predictions' (their solves store their own)
    poses = dict(zip(off, per_factor(gap, solve, off)))
    if not held and any(gap.held_factors.get(s) for s in off):
        # some were held off the metric: the others solved with the weak anchor too, as the gap's
        # solved in-betweens are (core.inbetween_prediction._solved), whatever order they ran in
        strong = [s for s in off if not gap.held_factors.get(s)]
        poses.update(zip(strong, per_factor(gap, lambda s: solve(s, True), strong)))
    for s, pose in poses.items():
        if pose[1] is None:
            results[s] = pose
        elif results[s][1] is not None and defect_count(gap, s, pose[0]) <= defect_count(gap, s, results[s][0]):
            results[s] = pose  # both keep defects: the solve where it keeps no more
        else:
            _put_back(gap, s, before[s])


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


def held_before(gap) -> bool:
    """Whether any in-between of ``gap`` solved so far was held off the metric and solved with the
    weak anchor (``gap.held_factors``; see :func:`core.inbetween_prediction._solved`). Read once
    before in-betweens are solved in place of predictions, concurrently: each of those solves may
    itself be held and record it, so a read inside them would depend on which ran first (the
    threads' timing) and the in-betweens with it."""
    return any(gap.held_factors.values())


def _solved_instead(gap, s: float, held: bool) -> tuple[np.ndarray, str | None]:
    """The pose solved at ``s`` in place of a prediction, with the weak anchor if ``held`` (the
    gap's in-betweens solved before were: :func:`held_before`), else with the gap's own and the
    weak one if its fit is held (:meth:`core.inbetween_solver.Gap.pose`)."""
    return gap.pose(s, weak=True if held else None)


def defect_count(gap, s: float, x: np.ndarray, scale: np.ndarray | None = None) -> int:
    """The flipped and collapsed triangles of positions ``x`` (n, 3) at factor ``s`` as the
    in-between's warning counts them (:meth:`~core.inbetween_defects.DefectChecks.counted`;
    ``scale``: the gap's ``area_scale(s)``, if made already)."""
    scale = gap.repair.factor_area_scale(s) if scale is None else scale
    return int(gap.repair.counted(x, s, scale).sum())
