"""Checking and repairing an in-between (flipped or collapsed triangles, non-finite values).

A defect-free fit is returned as it is. Otherwise the fit is repaired where the defects are:
rotations and stretches are imposed on the defective triangles and a neighbourhood that grows while
defects remain (:data:`~core.inbetween_repair_rounds.REPAIR_RINGS`); in each connected part of a
neighbourhood, in turn, the interpolated rotations, the linear blend's rotations (integrable: they
come from a mesh), the blend's rotations and stretches (its local geometry spliced in, where the
interpolated metric cannot be realized without a fold), the local geometry of the keys' per-vertex
spline, and each key's own local geometry (nearer key first); the first that leaves the part
defect-free is kept, so a repair changes as small a region as it can, and only the parts left
defective grow further (folds apart from each other are repaired each by its own field and region;
two poses and extrapolations take a neighbourhood whole, see
:meth:`~core.inbetween_repair_rounds.RepairRounds.rounds`). An in-between of a sequence that keeps
defects after all that is repaired again from the pose with the fewest, while that removes defects
— in a gap whose outer solved in-betweens are clean, with one more field, the local geometry of the
pose those two predict (:func:`core.inbetween_prediction_repairs.repaired_in_passes`). Regions stop growing once they cover
:data:`~core.inbetween_repair_rounds.MAX_REPAIR_FRACTION` of a piece of the mesh or, for a
sequence's in-between, once a round of 4 rings or more removed no defect
(:data:`~core.inbetween_repair_rounds.STALLED_ROUND`), and a repair of a sequence's in-between that
moves the pose by more than :data:`~core.inbetween_repair_rounds.MAX_REPAIR_MOVE` of the keys' move
is not taken: either would replace the pose rather than repair it, and the neighbouring in-betweens
would not follow. If no repair is defect-free, the Poisson solve alone is returned when it is;
otherwise an in-between of a sequence (three keys or more, factor strictly between 0 and 1) is the
metric fit with the fewest defects — a repair that leaves fewer counts only if it moves the pose by
at most :data:`~core.inbetween_repair_rounds.MAX_PARTIAL_REPAIR_MOVE` mean edge lengths: its
neighbours in time are fits too, and a whole-pose substitute (the blend, a fit near it) or a large
partial repair would jump away from them and back; so is an extrapolation (beyond the keys the
"blend" is the linear extrapolation, which lengthens whatever turns). The in-betweens of two poses
try the metric fitted near the linear blend (strongly anchored), then the linear blend — they are
held to the blend's error — and the first without defects is returned (the blend's defects include
the triangles it crushes below :data:`CRUSHED_AREA` of their interpolated area where neither key has
them so: a cloth turning between the keys, whose every chord the blend cuts); if none is, the metric
fit with the fewest defects. The fit near the blend is skipped when the blend itself is defective
(held near a folded blend it keeps the folds: on the benchmark cloths it repaired none of the 24
poses whose blend was defective, at ~1 s each on the 50k-vertex sheet). An in-between of two poses
whose checked fit ends farther from the interpolated metric than the blend itself (and beyond the
fit's tolerance) takes the metric fitted near the blend too, where that has no more defects
(:meth:`Repair.nearer_the_metric`). Each fallback that leaves defects comes with a message for a
:class:`~core.errors.ShapeDifferenceWarning`.

The parts :class:`Repair` is composed of: the defects it checks for (flipped and collapsed triangles,
:mod:`core.inbetween_defects`), the triangles facing away from both keys that are no defect (parts
turning past a half turn, :mod:`core.inbetween_turned_away`), the rounds of fields imposed on growing
regions (:mod:`core.inbetween_repair_rounds`) and the regions' own systems
(:mod:`core.inbetween_repair_regions`); the fallbacks are here.
"""

from __future__ import annotations

import threading
import weakref
from typing import NamedTuple

import numpy as np

from .geometry import coordinate_cross, coordinate_dot
from .inbetween_defects import DefectChecks
from .inbetween_fit import LOCAL_STEP_DTYPE
from .inbetween_repair_rounds import REPAIR_RINGS, RepairRounds
from .inbetween_turned_away import TurnedAway
from .sewn_seams import sewn_factor


#: Local/global iterations of the fallback that fits the metric near the linear blend.
REPAIR_ITERATIONS = 10
#: Anchor weight of the fallback that fits the interpolated metric near the linear blend.
FALLBACK_ANCHOR_WEIGHT = 1e-1
#: The linear blend, a fallback of two poses, counts a triangle as defective where its area is below
#: this fraction of the interpolated area and neither key's is (the keys' own crushed triangles are
#: the cloth's): a banner carried and turned between poses 16 frames apart fell back to a blend
#: whose edges were 24–29 % short (the simulated frames 2–3 %; 3,209–8,199 of 20,000 triangles
#: crushed, the frames themselves 241–433 and the keys 110–256). On eight sampled pairs of each of
#: 35 cloths at 4 / 8 / 16 frames apart, 8 of 105 cells changed: edge deviation down in all 8 (the
#: banner at 16 15.2 → 6.5 %, the soft 20k flag 7.67 → 5.08 %, under its bound 6.41), RMS ÷ the
#: blend down in 4 (banner 0.969 → 0.887, soft 20k flag 0.995 → 0.818), the same in 3 and up in
#: one (a skirt on a twisting waist, 1.040 → 1.129: a fit with one flipped triangle instead of a
#: blend 17 % short; 1.007 in both over every second start frame).
CRUSHED_AREA = 0.5


class Outcome(NamedTuple):
    """What :meth:`Repair.outcome` returned at one factor: the count of its flipped or collapsed
    triangles, and whether it is the linear blend or the interpolated metric fitted near it (a
    fallback from a fit whose defects no repair removed)."""

    defects: int
    near_blend: bool


class Repair(DefectChecks, TurnedAway, RepairRounds):
    """Checks and repairs of the poses of one gap (a ``core.inbetween_solver.Gap``)."""

    def __init__(self, gap):
        # a weak reference: the gap owns its Repair, and a cycle would keep a gap the
        # sequence's cache let go (~150 MB at 100k vertices) alive until a full garbage collection
        self.gap = weakref.proxy(gap)
        self._keys: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._move_limits: tuple[float, float] | None = None
        self._far_move: float | None = None  # mean squared move: see moved_far
        self._local = threading.local()  # per thread: see _rows_of and region_defects

    def outcome(self, x, x0, s, frames, stretch, guide, motion, rings=REPAIR_RINGS, defects=None,
                looser=None, nearby=None, repairable=None) -> tuple[np.ndarray, str | None, int, bool]:
        """``(x, None, 0, False)`` if the fit ``x`` is defect-free, else a repair or a fallback with
        the message saying which, the count of its flipped or collapsed triangles and whether it is
        the linear blend or the metric fitted near it (``x0``: the Poisson solve of the interpolated
        field, or ``x`` itself when there is none; ``rings``: the repair rounds,
        :data:`~core.inbetween_repair_rounds.REPAIR_RINGS` or fewer; ``defects``:
        :meth:`~core.inbetween_defects.DefectChecks.defects` of ``x`` if the caller has them;
        ``looser``: the fit's step within the whole key-to-key change's tolerance, or None (see
        :data:`core.inbetween_fit.TOLERANCE_TRIM`): where the repairs fail it is returned if it has
        no defect, a fit as the fit's stop allowed before; ``nearby``: positions (n, 3) of another pose
        at ``s`` whose local geometry the rounds try last,
        :meth:`~core.inbetween_repair_rounds.RepairRounds.rounds`; ``repairable``: the most flipped or
        collapsed triangles the fit may have for the rounds to run on it, or None for any: a fit with
        more goes straight to the fallbacks, see
        :data:`core.inbetween_prediction_repairs.UNREPAIRED_SOLVE_DEFECTS`). The gap keeps what it
        takes of it (:meth:`core.inbetween_solver.Gap.recorded`)."""
        defects = self.defects(x, s, frames, stretch) if defects is None else defects
        problem = self.problem(x, s, frames, stretch, defects)
        if problem is None:
            return x, None, 0, False
        gap = self.gap
        best = (int(defects.sum()), x) if np.isfinite(x).all() else None  # the last resort: fewest defects
        blend = gap.linear_blend(s)
        if gap.use_extrinsic and best is not None and (repairable is None or best[0] <= repairable):
            z, best = self.rounds(x, defects, s, frames, stretch, guide, blend, best, rings, nearby)
            if z is not None:
                return z, None, 0, False
        # each candidate checked and counted as the gap returns it, its pinned vertices put back
        looser = None if looser is None else self.as_finished(looser, s)
        if looser is not None and self.problem(looser, s, frames, stretch) is None:
            return looser, None, 0, False
        x0 = x0 if x0 is x else self.as_finished(x0, s)
        if gap.use_extrinsic and x0 is not x and self.problem(x0, s, frames, stretch) is None:
            return x0, (f"it is the first solve, with no triangle flipped or collapsed but its edge "
                        f"lengths less exact (its fit: {problem}, which no repair removed); keys closer together "
                        "here tell the motion better (the interpolated rotation field's Poisson solve without "
                        "metric fit)"), 0, False
        if best is not None and (self.in_sequence(s) or not 0.0 <= s <= 1.0):
            # keeps the metric, as its neighbours in time do; beyond the keys the "blend" is the
            # linear extrapolation, which lengthens whatever turns (×2 of a 100° elbow: a forearm
            # 1.94 × its length held near it, "the interpolated metric fitted near the blend")
            return best[1], self.kept_message(problem, best[0]), best[0], False
        # the fallbacks fit and check the whole mesh: its stretches whole (a repair of a predicted
        # in-between is given them by rows, core.inbetween_field._ByRows; [:] computes the rest)
        stretch = stretch[:]
        folds = self.defects(blend, s, frames, stretch)
        # a fit held near a folded blend keeps its folds: tried only where the blend has fewer
        # folds than the metric fit (two poses of a cloth folding over as it is dragged by a
        # corner, keys 16 frames apart: 713 against the blend's 59, the fit near it 243, RMS 1.61
        # → 1.00 × the blend's)
        if best is None or int(folds.sum()) < best[0]:
            y = self.fitted_near_blend(blend, s, stretch, motion)
            # the fit hands back its start when no step improves on it: then it is the blend, said so
            unmoved = np.array_equal(y, blend)
            y = self.as_finished(y, s)
            fitted = "the keys' linear blend (no fit near it improved on it)" if unmoved else \
                "a fit near the keys' linear blend"
            tail = "the linear blend" if unmoved else "the interpolated metric fitted near the linear blend"
            if self.problem(y, s, frames, stretch) is None:
                return y, (f"it is {fitted}, with no triangle flipped or collapsed but edges that may "
                           f"be short where the cloth turns (its fit: {problem}, which no repair removed); keys "
                           f"closer together here tell the motion better ({tail})"), 0, True
            if not (folds | self.crushed(blend, stretch)).any():
                return blend, (f"it is the keys' linear blend, with no triangle flipped or collapsed but "
                               f"edges short where the cloth turns (its fit: {problem}, which neither a repair nor "
                               "a fit near the blend removed); keys closer together here tell the motion better "
                               "(the metric fit near the blend failed too: returned the linear blend)"), 0, True
            count = int(self.defects(y, s, frames, stretch).sum())
            if best is None or count < best[0]:
                return y, (f"it is {fitted}, which keeps {count} triangle(s) flipped or collapsed, the "
                           f"fewest of its fits (its fit: {problem}; no repair or fallback removed them all); keys "
                           f"closer together here tell the motion better ({tail}, which has the fewest)"), count, True
        # No candidate is free of defects: the metric fit with the fewest rather than a candidate
        # that gives up the metric (the blend shortens edges by several percent: a visible pop).
        return best[1], self.kept_message(problem, best[0]), best[0], False

    def as_finished(self, x: np.ndarray, s: float) -> np.ndarray:
        """``x`` (n, 3) at factor ``s``, a candidate of this check (its own array, which the caller drops
        where it is not taken), with the gap's pinned vertices (still ones, sets riding on an animated
        object: ``static``) put where the gap's finish puts them (:meth:`core.inbetween_solver.Gap.finished`),
        in place; returned. A fallback is checked and its flipped or collapsed triangles counted so, as
        the fit is: a fit near the blend leaves vertices riding an animated object on the blend's
        chords, and the triangles beside them flip or not once they are put back on their arcs, so
        its warning counts the pose as returned (docs/inbetween-measurements.md, *A two-pose fallback
        counted as it is returned*)."""
        gap = self.gap
        if gap.static is not None:
            x[gap.static] = gap.pinned_positions(s)
        return x

    def fitted_near_blend(self, blend, s, stretch, motion) -> np.ndarray:
        """The interpolated metric (``stretch``, whole) at factor ``s`` fitted from the linear
        ``blend`` with every vertex anchored to it at :data:`FALLBACK_ANCHOR_WEIGHT` (no rotation
        limit: the blend's own turns are the start)."""
        gap = self.gap
        system = (sewn_factor(gap.topo, FALLBACK_ANCHOR_WEIGHT, None, gap.sewn),
                  np.full(gap.topo.n, FALLBACK_ANCHOR_WEIGHT) * gap.topo.mass)
        return gap.fit(blend.copy(), stretch, None, blend, s, motion, REPAIR_ITERATIONS, system=system)

    def nearer_the_metric(self, result, s, frames, stretch, motion, targets) -> tuple[np.ndarray, str | None, int, bool]:
        """An in-between of two poses ``result`` (positions, message: what :meth:`outcome` returned
        at factor ``s``, its outcome kept in the gap's ``outcomes[s]``) as :meth:`outcome` returns
        it (with that outcome; ``frames``: the interpolated frames its check counts by), or the
        interpolated metric fitted near the linear blend where ``result``
        ends farther from the interpolated metric than the blend itself and beyond the fit's
        tolerance (mean relative deviation of the edge lengths from ``targets``, the fit's): the
        interpolated rotations do not integrate there, and their fit failed at its own objective
        where the blend did not. The fit near the blend is taken only with no more flipped or
        collapsed triangles than ``result`` (its outcome that of a fallback near the blend).
        A sheet swinging off a rod that stops dead, two poses 4 frames apart: its fit 8.6 % off the
        metric where the blend is 5.0 % (the simulated frame 0.34 %), 4.06 × the blend's RMS error;
        the fit near the blend 2.8 % off, 0.96 ×."""
        gap = self.gap
        kept = (*result, *gap.outcomes[s])
        misfit = gap.misfit(gap.edges_of(result[0], LOCAL_STEP_DTYPE), targets)
        if misfit <= gap.tolerance:
            return kept
        blend = gap.linear_blend(s)
        if misfit <= gap.misfit(gap.edges_of(blend, LOCAL_STEP_DTYPE), targets):
            return kept
        stretch = stretch[:]
        y = self.as_finished(self.fitted_near_blend(blend, s, stretch, motion), s)
        count = int(self.defects(y, s, frames, stretch).sum())
        if count > gap.outcomes[s].defects:
            return kept
        return y, None if not count else (
            f"it is a fit near the keys' linear blend, which keeps {count} triangle(s) flipped or "
            "collapsed and the edge lengths better than its own fit; keys closer together here tell the motion "
            "better (the fit ended farther from the interpolated metric than the blend: returned the interpolated "
            "metric fitted near the linear blend)"), count, True

    def crushed(self, x: np.ndarray, stretch: np.ndarray) -> np.ndarray:
        """Triangles (bool (m,)) of ``x`` whose area is below :data:`CRUSHED_AREA` of the
        interpolated area (``stretch``: packed (m, 3) at the pose's factor) where neither key's is."""
        gap = self.gap
        cross = coordinate_cross(*gap.topo.triangle_sides(x))
        target = CRUSHED_AREA * gap.base.areas * (stretch[:, 0] * stretch[:, 2] - stretch[:, 1] ** 2)
        return (0.5 * np.sqrt(coordinate_dot(cross, cross)) < target) & (gap.base.areas >= target) \
            & (gap.next.areas >= target)

    @staticmethod
    def kept_message(problem: str, count: int) -> str:
        """The warning's text when the metric fit with the fewest defects (``count``) is returned;
        ``problem``: what was wrong with the first fit. What the in-between keeps comes first, where a
        report line cut to the status bar's width still shows it."""
        return (f"it keeps {count} triangle(s) flipped or collapsed, the fewest of its fits (its first "
                f"fit: {problem}; no repair or fallback removed them all); keys closer together here tell the motion "
                "better, or fix those triangles by hand (the metric fit with the fewest defects)")
