"""How each gap of a :class:`~core.sequence_inbetweens.SequenceInterpolator` starts (paper §8.4): a hold
(both keys of a gap the same pose, or pieces in the same place) stays put and the motion after it
starts from rest; the first gap starts as the sequence's ``start`` says (its tangent limit,
:mod:`core.splines`); a gap after free flight into an impact starts with the parabola's velocity
(:mod:`core.inbetween_flight`), and the gap in which the cloth lands ends with it; a gap after a stop
that the after-impact start leaves alone is measured for the ``overshoot`` warning
(:meth:`GapStarts._carried_stop`)."""

from __future__ import annotations

import numpy as np

from .inbetween_flight import FREE_FLIGHT_JERK, FREE_FLIGHT_NONRIGIDITY, IMPACT_SLOWDOWN, after_impact, free_flight
from .splines import REST_START_LIMIT, START_TANGENT_LIMIT, HermiteGap

#: A gap right after a stop that the after-impact start (:data:`~core.inbetween_flight.IMPACT_SLOWDOWN`)
#: leaves alone — a piece's centroid moved over IMPACT_SLOWDOWN × as far in the gap before as in
#: this one, but the piece keeps deforming (a sheet landed on a stair and creeps down its steps) —
#: starts with Catmull–Rom's tangent, the fall's velocity, limited in length only
#: (:data:`~core.splines.TANGENT_LIMIT` × the longer chord): a fall across the creep passes that limit
#: and bulges the in-betweens sideways. The gap is warned (:meth:`GapStarts._carried_stop`) where its
#: world spline of positions strays from the keys' chord over this many times as far (RMS over the
#: slowed pieces' points at :data:`STOP_CARRY_FACTORS` of the gap) as the spline that starts it
#: slowing to a stop does (``parabolic_start`` of :class:`~core.splines.HermiteGap`, the constant
#: deceleration the after-impact start takes). Why past 2 ours is the worse: where the cloth did slow
#: so, the linear blend (the chord) is off that motion by about the stopping spline's distance from
#: the chord, and ours by at least the difference of the two distances. Read only on pieces that
#: landed as :func:`~core.inbetween_flight.after_impact` asks (non-rigidity of the key before over
#: 2 × FREE_FLIGHT_NONRIGIDITY: a rigid piece's is round-off) and deformed more across the gap before
#: than across this one (a cloth stopped on contact settles; one carried on by its own swing after its
#: carrier stops, or spinning, deforms on as fast, and there the carried speed is right), placed on
#: the keys' spline (not pieces whose rotations the gap takes whole); not in a last gap: there the end
#: condition sets the end tangent to a share of the secant (the secant itself, the keys' slowing
#: correction or rest), so the stopping spline runs along the chord, off it only in timing, and the
#: ratio measures that ours is not the blend, nothing of a stop. 3 leaves
#: the benchmark's 57 sequence cells silent (the largest ratio 2.50, a flag in wind at g = 8, its
#: spline nearer the frames than the blend) and warns an unseen sheet landing on a stair (5.22,
#: 1.61 × the blend's RMS): docs/inbetween-measurements.md, *A sheet landing on a stair* and its review.
STOP_CARRY_RATIO = 3.0
#: The factors of a gap at which :meth:`GapStarts._carried_stop` compares the two splines.
STOP_CARRY_FACTORS = (0.25, 0.5, 0.75)


class GapStarts:
    """Holds, start tangent limits, free-flight entries and landing exits of a sequence's gaps, read
    from its keys; mixed into :class:`~core.sequence_inbetweens.SequenceInterpolator`.

    Reads the interpolator's ``_centroids``, ``_durations``, ``_given``, ``_hold_tolerance``,
    ``_holds``, ``_raw``, ``_topo``, ``start`` and calls its ``_nonrigidity``."""

    def _steady(self, gap: int) -> np.ndarray | None:
        """Per component (C,), whether the keys up to the gap's end tell its flight as the parabola
        through its start: its centroid moved at constant acceleration over keys ``gap − 2`` …
        ``gap + 1`` (their third difference under :data:`FREE_FLIGHT_JERK` × the gap's move; a
        first key at rest mirrors key 1 to key −1), or it is still before a launch: the gap after
        moves it over :data:`~core.inbetween_flight.IMPACT_SLOWDOWN` × as far as this gap (keys
        evenly spaced), whatever slowed it before (a hanging curtain settling, hit by a ball after
        the gap's end key; the parabola ends the gap at the small velocity its own keys give, where
        Catmull–Rom's tangent took half the hit's move). None for the first gap and for the second
        when the keys are cut from a motion (too few keys to tell)."""
        if gap < 1 or (gap == 1 and self.start != "rest"):
            return None
        if np.ptp(self._durations[max(gap - 2, 0):gap + 1]) > 0:  # the third difference: keys evenly spaced
            return None
        c = self._centroids[[abs(i) for i in range(gap - 2, gap + 2)]]
        jerk = np.linalg.norm(c[3] - 3.0 * c[2] + 3.0 * c[1] - c[0], axis=1)
        move = np.linalg.norm(c[3] - c[2], axis=1)
        steady = jerk < FREE_FLIGHT_JERK * move
        if gap + 2 < len(self._raw) and self._durations[gap + 1] == self._durations[gap]:
            # still before a launch: the gap after moves it over IMPACT_SLOWDOWN × as far
            steady |= np.linalg.norm(self._centroids[gap + 2] - c[3], axis=1) > IMPACT_SLOWDOWN * move
        return steady

    def _entry(self, gap: int, back: np.ndarray) -> tuple | None:
        """Where the gap before ends in free flight (:func:`core.inbetween_flight.free_flight`, its
        splines on the parabola through its start), this gap starts with that parabola's velocity
        at the key, so that the two meet with one velocity: ``(per component (C,), {"world": (n,
        3), "centroids": (C, 3)})`` — the positions in the world, which place a deforming piece —
        or None. ``back``: the non-rigidity of key ``gap − 1`` seen from key ``gap`` (C,), which
        rules most gaps out before the keys are aligned."""
        k = gap - 1
        if k < 0 or not (np.asarray(back) < FREE_FLIGHT_NONRIGIDITY).any():
            return None
        steady = self._steady(k)
        if k >= 1 and (steady is None or not steady.any()):
            return None
        seen = [self._nonrigidity(k, i) if 0 <= i < len(self._raw) else np.zeros(len(self._topo.components))
                for i in (k - 1, gap, gap + 1)]
        start = self._start_limit(k)
        free = free_flight(*seen, start, steady)
        if free is None:
            return None
        x, c = self._raw, self._centroids
        d = self._durations
        if start != REST_START_LIMIT and d[k - 1] != d[k]:  # the parabola's weights below: keys evenly spaced
            return None
        scale = d[gap] / d[k]  # per unit of this gap
        if start == REST_START_LIMIT:  # from rest (free_flight said so): the parabola's velocity at the key is 2 (x₁ − x₀)
            return free, {"world": 2.0 * scale * (x[gap] - x[k]), "centroids": 2.0 * scale * (c[gap] - c[k])}
        return free, {"world": scale * (1.5 * x[gap] - 2.0 * x[k] + 0.5 * x[k - 1]),
                      "centroids": scale * (1.5 * c[gap] - 2.0 * c[k] + 0.5 * c[k - 1])}

    def _start_limit(self, gap: int) -> float | None:
        """Gap ``gap``'s start tangent limit (× its secant): the first gap's for this sequence's
        ``start``, a gap after a hold's from rest (the motion starts there), None for the others."""
        if gap == 0:
            return REST_START_LIMIT if self.start == "rest" else START_TANGENT_LIMIT
        return REST_START_LIMIT if self._hold(gap - 1) else None

    def _hold(self, gap: int) -> bool:
        """Whether gap ``gap``'s two keys are the same pose (a hold: its in-betweens are that pose;
        the keys' spline would swing out and back through it toward the keys around it)."""
        return bool(self._held(gap).all())

    def _held(self, gap: int) -> np.ndarray:
        """Per vertex (n,), whether its piece (the piece that carries it, for a loose vertex) sits
        in the same place in both keys of gap ``gap``: a hold of that piece, which stays there at
        every factor as a hold of the whole pose does (a prop set down in one key and picked up
        after the next: the keys' spline would move it toward where it goes later)."""
        if gap not in self._holds:
            a, b = self._given[gap], self._given[gap + 1]
            moved = np.any(np.abs(a - b) > self._hold_tolerance, axis=1)
            if not self._topo.components:  # no triangle: the pose is one piece
                moved = np.full(moved.shape, moved.any())
            elif not moved.all():  # where every vertex moves no piece is held (a cloth, most gaps)
                owner = self._topo.vertex_owner
                moved = np.bincount(owner, moved, minlength=len(self._topo.components))[owner] > 0
            self._holds[gap] = ~moved
        return self._holds[gap]

    def _exit(self, gap: int) -> tuple | None:
        """Where the gap after starts right after an impact (:func:`core.inbetween_flight.after_impact`:
        the cloth landed inside this gap, and the gap after starts on the parabola through its
        end), this gap ends with the velocity the gap after starts with: ``(per component (C,),
        {"world": (n, 3), "centroids": (C, 3)})`` — the positions' start tangents of the gap
        after, which place the piece; its other splines end with the next gap's secant
        (``exit`` of :class:`core.splines.HermiteGap`) — or None. The Catmull–Rom tangent
        carries the fall's speed into the key, where the gap after drops it at once: a kink
        the simulation, whose cloth slowed inside this gap, does not have (numbers in
        docs/inbetween-measurements.md, *Kinks at impact keys*). Keys evenly spaced around the key (the
        tangents are per unit of this gap)."""
        k, last = gap + 1, len(self._raw) - 1
        if k + 1 > last or self._start_limit(k) is not None:
            return None
        d = self._durations
        if np.ptp(d[gap:min(k + 2, last)]) > 0:
            return None
        c = self._centroids
        incoming, outgoing = np.linalg.norm(c[k] - c[gap], axis=1), np.linalg.norm(c[k + 1] - c[k], axis=1)
        if not (incoming > IMPACT_SLOWDOWN * outgoing).any():  # no slowdown: the rigid fits are not needed
            return None
        before, nxt = self._nonrigidity(k, gap), self._nonrigidity(k, k + 1)
        impact = after_impact(before, nxt, incoming, outgoing, None)
        if impact is not None and k + 2 <= last:  # ... unless hit again right after it, as the gap after reads
            impact = after_impact(before, nxt, incoming, outgoing, None, self._nonrigidity(k, k + 2))
        if impact is None:
            return None
        rest_end = self.end == "rest" and k == last - 1

        def start_velocity(x):  # the gap after's start tangent: its HermiteGap's under parabolic_start
            after = x[k + 2] if k + 2 <= last else 2.0 * x[k + 1] - x[k]
            return HermiteGap((x[gap], x[k], x[k + 1], after), True, rows=True, parabolic_start=np.bool_(True),
                              rest_end=rest_end).t0

        return impact, {"world": start_velocity(self._raw), "centroids": start_velocity(c)}

    def _carried_stop(self, gap: int, off_spline: np.ndarray | None = None) -> float:
        """How many times as far gap ``gap``'s world spline of positions strays from its keys' chord
        as the spline that starts it slowing to a stop does (see :data:`STOP_CARRY_RATIO`), over the
        points (n,) of the pieces (C,) that (1) moved their centroid over
        :data:`~core.inbetween_flight.IMPACT_SLOWDOWN` × as far in the gap before as in this one,
        (2) do not start this gap after an impact (:meth:`_exit` of the gap before: the after-impact
        start already slows them), (3) deformed across the gap before as a landing does (non-rigidity
        of the key before, seen from the gap's start key, over 2 ×
        :data:`~core.inbetween_flight.FREE_FLIGHT_NONRIGIDITY`, as in
        :func:`~core.inbetween_flight.after_impact`) and more than across this gap, and (4) are not in
        ``off_spline`` (bool (C,) or None: the pieces the gap does not place on the keys' spline of
        positions, their rotations taken whole; that spline's stray says nothing of their in-betweens,
        e.g. a tube curling at a steady rate, whose centroid slows as it curls in).
        ``inf`` where the stopping spline is the chord to round-off (the keys after the stop creep at
        constant speed). 0 where no piece qualifies or their spline is the chord, in a sequence's
        first or last gap, in a sequence of two keys or not ``smooth``, after a hold, or with the keys
        around the gap unevenly spaced. From the keys only."""
        k, last = gap, len(self._raw) - 1
        # a last gap's end tangent is a share of its secant (the linear end condition's secant, the
        # keys' slowing correction, :func:`~core.splines.slowing_end_correction`, or rest), so the
        # spline slowing to a stop, whose start tangent is 2 × the secant − that tangent, runs along
        # the chord and differs from the blend in timing only: the ratio would tell that ours is not
        # the blend, nothing of a stop (a cloth swinging into its last key would be warned so)
        if k < 1 or k + 1 >= last or not self.smooth or self._start_limit(k) is not None:
            return 0.0
        d = self._durations
        if np.ptp(d[k - 1:k + 2]) > 0:
            return 0.0
        c = self._centroids
        slowed = np.linalg.norm(c[k] - c[k - 1], axis=1) > IMPACT_SLOWDOWN * np.linalg.norm(c[k + 1] - c[k], axis=1)
        if not slowed.any():
            return 0.0
        impact = self._exit(k - 1)
        if impact is not None:
            slowed &= ~impact[0]
        # deformed before the gap as a landing does (a rigid piece's non-rigidity is round-off, which
        # the comparison after it would read as noise), and more than across it (a cloth stopped on
        # contact settles; one carried on by its own swing, or spinning, deforms on as fast)
        before = self._nonrigidity(k, k - 1)
        slowed &= (before > 2.0 * FREE_FLIGHT_NONRIGIDITY) & (before > self._nonrigidity(k, k + 1))
        if off_spline is not None:
            slowed &= ~off_spline
        rows = slowed[self._topo.vertex_owner]
        if not rows.any():
            return 0.0
        x = self._raw
        values = (x[k - 1][rows], x[k][rows], x[k + 1][rows], x[k + 2][rows])
        corrections = tuple(None if t is None else t[rows]
                            for t in (self._tangent_correction(k), self._tangent_correction(k + 1)))
        splines = [HermiteGap(values, True, rows=True, corrections=corrections, parabolic_start=start)
                   for start in (None, np.bool_(True))]
        chord = values[2] - values[1]
        carried, stopping = (sum(float(np.sum((h.at(s) - values[1] - s * chord) ** 2)) for s in STOP_CARRY_FACTORS)
                             for h in splines)
        if carried == 0.0:
            return 0.0
        # the stopping spline on the chord to round-off (the keys after the stop creep at constant
        # speed): no finite ratio
        return float(np.sqrt(carried / stopping)) if stopping > 1e-12 * carried else np.inf
