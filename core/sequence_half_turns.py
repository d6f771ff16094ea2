"""Which way round a piece goes that turns near a half turn between two keys of a sequence (paper
§5.3's rotations, §8.4): taken the other way round where the steps before and after tell so
(:class:`HalfTurns`), and, per piece, whether the keys tell the way at all
(:func:`untold_half_turns`: the gap warns where they do not), and whether those are the half turn
of the whole mesh turning as one (:func:`turning_as_one`: the warning is about the mesh, not a
count of pieces)."""

from __future__ import annotations

import numpy as np

from .deformation_fields import rotation_vectors
from .rotation_continuity import WRAP_CREASE, either_way, residuals_turning_whole_way, the_other_way
from .inbetween_keys import Relative
from .inbetween_rigid_fits import (NEAR_HALF_TURN, component_screws, mean_triangle_turns, rigid_fits, turn_spread,
                                   turning_against, turning_with)
from .inbetween_solver import Gap
from .rigid_alignment import rigid_alignment
from .screw_motions import TURN_SPREAD
from .sequence_turn_readings import TURNED_PART_SHARE


def untold_half_turns(segment: Gap, nxt: Relative) -> np.ndarray:
    """Per component (bool (C,)), whether its half turn in gap ``segment`` (key ``base + 1``
    seen from the base: ``nxt``) goes a way the keys do not tell: a jointed piece moves
    relative to its parent (:mod:`core.inbetween_joints`), whose relative motion the gap takes
    the short way round, told by nothing where it is a half turn as short either way (a crank
    turning 180° about its bearing in a fixed block); any other piece as
    :meth:`HalfTurns._turning_on` found (an arm's link turning 180° in the world, 90° from the link it
    hangs from, is told by that joint)."""
    untold = nxt.untold_half_turn.copy()
    if segment.joints is not None:
        parents = segment.joints[0]
        children = np.flatnonzero(parents >= 0)
        rotations = nxt.motion[0]
        relative = np.transpose(rotations[parents[children]], (0, 2, 1)) @ rotations[children]
        spread = turn_spread(nxt.nonrigidity)
        untold[children] = either_way(np.linalg.norm(rotation_vectors(relative), axis=1),
                                      np.maximum(spread[children], spread[parents[children]]))
    return untold


def turning_as_one(segment: Gap, nxt: Relative) -> bool:
    """Whether every piece of the mesh moves by the whole mesh's rigid motion between the keys of
    gap ``segment`` (key ``base + 1`` seen from the base: ``nxt``, its pieces' rigid motions) to
    within :data:`~core.screw_motions.TURN_SPREAD`, the coarsest a turn is taken to be known
    (:func:`~core.inbetween_rigid_fits.whole_tells`): each piece's rotation within that angle of the
    whole mesh's, and the two motions placing its centroid within that share of the mesh's size
    (sqrt(12 · trace of the covariance), as :meth:`~core.inbetween_topology.Topology.diagonals`)
    of each other. Where the keys leave some piece's half turn untold (:func:`untold_half_turns`)
    and this holds, the whole mesh turns that half turn and the gap says so of the mesh: the count
    of untold pieces leaves out those jointed to them (told by their parents), 6 or 42 of a rigged
    character's 59 pieces (body, clothes, props) turned exactly 180° by its root, at 1.7k / 55k
    vertices; its pieces agree with the whole to 6e-6 rad and 2e-7 of its size."""
    topo, base, other = segment.topo, segment.base.vertices, segment.next.vertices
    weights = topo.weights
    rotation, translation = rigid_alignment(base, other, weights)
    rotations, translations = nxt.motion
    apart = np.linalg.norm(rotation_vectors(np.transpose(rotations, (0, 2, 1)) @ rotation), axis=1)
    centroids = topo.centroids(base)
    shift = np.linalg.norm(centroids @ rotation.T + translation - np.einsum("cab,cb->ca", rotations, centroids)
                           - translations, axis=1)
    mass = weights.sum()
    spread = base - weights @ base / mass
    size = np.sqrt(12.0 * (weights @ np.einsum("ij,ij->i", spread, spread)) / mass)
    return bool(np.all(apart <= TURN_SPREAD) and np.all(shift <= TURN_SPREAD * size))


def _same_way(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Per row of two rotation vectors (C, 3) each, whether both turn past
    :data:`~core.rotation_continuity.WRAP_CREASE` (a way round to compare) and about axes
    within a right angle of each other (bool (C,)) (:func:`_told`); :func:`_against` the same,
    axes past it."""
    return _told(first) & _told(second) & (np.einsum("ij,ij->i", first, second) > 0.0)


def _against(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    return _told(first) & _told(second) & (np.einsum("ij,ij->i", first, second) < 0.0)


def _told(turns: np.ndarray) -> np.ndarray:
    """Per rotation vector (C, 3), whether it turns past WRAP_CREASE and is no half turn as short
    either way round to within :data:`~core.screw_motions.TURN_SPREAD` (whose way the untold
    half turns' warning is about: :func:`untold_half_turns`)."""
    theta = np.linalg.norm(turns, axis=1)
    return (theta > WRAP_CREASE) & ~either_way(theta, TURN_SPREAD)


class HalfTurns:
    """The way round of near half turns between a sequence's keys, read from the steps around them;
    mixed into :class:`~core.sequence_inbetweens.SequenceInterpolator`.

    Reads the interpolator's ``_durations``, ``_edge_pairs``, ``_raw``, ``_topo``, ``smooth`` and calls its ``_key``."""

    def _turning_on(self, base: int, relative: Relative) -> Relative:
        """``relative`` (key ``base + 1`` seen from key ``base``) with its pieces' near half turns
        taken the way the steps around tell (:meth:`_pieces_turning_on`) and, in a sequence (two
        poses take the residuals continuous across the mesh instead), the residuals of each part
        over :data:`~core.sequence_turn_readings.TURNED_PART_SHARE` of its piece's area the way
        round its whole rotation goes where its border joins the rest so
        (:func:`~core.rotation_continuity.residuals_turning_whole_way`). Depends on the keys alone."""
        relative = self._pieces_turning_on(base, relative)
        if relative._across is None:
            relative.rotvec = residuals_turning_whole_way(relative.rotvec, relative.screw[:, :3],
                                                          self._topo.triangle_component, self._edge_pairs,
                                                          self._key(base).areas, TURNED_PART_SHARE)
        return relative

    def _spin_reading(self, gap: int, surface: bool) -> np.ndarray:
        """Each piece's turn (rotation vectors (C, 3), the short way round) from key ``gap`` to the
        next: its rigid fit's (:meth:`_fits`), or, ``surface``, its triangles' as a whole
        (:func:`~core.inbetween_rigid_fits.mean_triangle_turns`); kept for every gap (a few numbers
        per piece)."""
        with self._cache_lock:
            readings = self.__dict__.setdefault("_spin_readings", {})
            known = readings.get((gap, surface))
        if known is None:
            rotations = mean_triangle_turns(self._topo, self._raw[gap], self._raw[gap + 1]) if surface else \
                self._fits(gap, gap + 1)[0]
            known = rotation_vectors(rotations)
            with self._cache_lock:
                readings[(gap, surface)] = known
        return known

    def _aliased_spin(self, gap: int) -> np.ndarray:
        """Per component (bool (C,)), whether the keys may read its spin in gap ``gap`` the wrong
        way round: by both its rigid fits and its triangles' turns as a whole
        (:meth:`_spin_reading`), this gap turns it past :data:`~core.inbetween_rigid_fits.NEAR_HALF_TURN`
        one way next to a gap turning it the other way (axes over a right angle apart, each past
        :data:`~core.rotation_continuity.WRAP_CREASE`; :func:`_told`), or it is in the run of gaps
        turning it that other way after such a gap. A piece spinning on one way a little past a
        half turn per gap reads the short way round, the other way, from there on: a sheet pinned at
        its centre in a vortex, keys 16 frames apart, turns about 190° / 225° / 283° per gap and
        reads +173° / −136° / −77°, its last two gaps 1.33 / 1.15 × the linear blend's error (the
        first 0.86 ×). Either reading alone also reads so what the in-betweens follow: a strip curled
        170° per key at one joint (its fits, reading its shape, near a half turn one way and then the
        other; its triangles 85°), a tail wagged past a half turn per key (its triangles, as a whole,
        near a half turn either way; its fits under it). A swing that goes over and comes back
        reads alike in both: the keys do not tell the two apart. The run before such a gap (a spin
        slowing down through a half turn per gap reads so) is not said: on a benchmark flag keyed
        every 16 frames it was a gap 0.56 × the blend's error."""
        out = self._reversed_near_half_turn(gap, False)
        if out.any():  # the triangles' turns only where the fits' read so (rare: made per gap then)
            out &= self._reversed_near_half_turn(gap, True)
        return out

    def _reversed_spin(self, gap: int) -> float:
        """How many times as close to the turns of the gaps either side a piece's turn in gap ``gap``
        comes taken the long way round, ``ω − 2π ω̂``, as taken the short way, ``ω``: ``|ω − e| ÷
        |ω − 2π ω̂ − e|``, ``e`` the mean of those two gaps' turns per unit of time, where both turn
        the piece the same way and this gap the other way (each turn past
        :data:`~core.rotation_continuity.WRAP_CREASE`, axes over a right angle apart: :func:`_told`),
        by its rigid fits and by its triangles' turns as a whole (:meth:`_spin_reading`; the lesser
        of the two); the largest over the pieces where it is over 1, else 0. Over 1 the keys agree
        better with a spin going on past a half turn in this gap than with one reversing for this
        gap alone, and they do not tell the two apart; the in-betweens take the short way. Below
        :data:`~core.inbetween_rigid_fits.NEAR_HALF_TURN`, where :meth:`_aliased_spin` does not look:
        a skirt twirled +218° between keys 16 frames apart, read −142° between gaps turning it +63°
        and +125°, went back round (1.53 × the linear blend's error), measure 1.80. An even wag of
        ±A per gap measures 2A ÷ (2π − 2A): over 1 past a right angle, where the keys do not tell it
        from a spin. Nothing in the in-betweens depends on it."""
        last = len(self._raw) - 1
        if not (0 < gap < last - 1):
            return 0.0
        d = self._durations
        measure = None
        for surface in (False, True):
            here, before, after = (self._spin_reading(k, surface) for k in (gap, gap - 1, gap + 1))
            pieces = _same_way(before, after) & _against(here, before) & _against(here, after)
            if measure is not None:
                pieces &= measure > 1.0
            if not pieces.any():
                return 0.0
            run = 0.5 * (before * (d[gap] / d[gap - 1]) + after * (d[gap] / d[gap + 1]))
            theta = np.linalg.norm(here, axis=1)
            ratio = np.linalg.norm(here - run, axis=1) / np.maximum(
                np.linalg.norm(the_other_way(here, theta) - run, axis=1), np.finfo(float).tiny)
            ratio = np.where(pieces, ratio, 0.0)
            measure = ratio if measure is None else np.minimum(measure, ratio)
        return float(measure.max()) if measure.max() > 1.0 else 0.0

    def _reversed_near_half_turn(self, gap: int, surface: bool) -> np.ndarray:
        """:meth:`_aliased_spin` by one reading (``surface`` as :meth:`_spin_reading`)."""
        last = len(self._raw) - 1
        count = len(self._topo.components)
        if last < 2:
            return np.zeros(count, dtype=bool)
        here = self._spin_reading(gap, surface)
        beside = np.zeros(count, dtype=bool)
        for k in (gap - 1, gap + 1):
            if 0 <= k < last:
                beside |= _against(here, self._spin_reading(k, surface))
        out = beside & (np.linalg.norm(here, axis=1) > NEAR_HALF_TURN)  # this gap's own near half turn
        # ... or this gap in the run reading the other way after an earlier gap's
        run, current = np.ones(count, dtype=bool), here
        for k in range(gap - 1, -1, -1):
            if not run.any():
                break
            earlier = self._spin_reading(k, surface)
            out |= run & _against(current, earlier) & (np.linalg.norm(earlier, axis=1) > NEAR_HALF_TURN)
            run &= _same_way(current, earlier)
            current = earlier
        return out

    def _pieces_turning_on(self, base: int, relative: Relative) -> Relative:
        """``relative`` (key ``base + 1`` seen from key ``base``) with each piece that turns past
        :data:`~core.inbetween_rigid_fits.NEAR_HALF_TURN` between the keys taken the other way round where
        that is nearer the turns of the steps before and after (per unit of time) by more than it
        turns the gap's middle further than the short way: a
        skirt spun 3.134 rad between keys 16 frames apart, turning on the same way before and
        after, was turned back the short way (rounding picked it), its waist one way and its hem
        the other (1.65 × the blend's error, 14.7 % edge deviation); a sheet flipped over a rod,
        −189° between keys, went +171° under it. Depends on the keys alone (every gap that uses
        this relative sees the same). Sets ``relative.untold_half_turn`` (bool (C,)): the pieces
        that turn a half turn, as short either way round to within what their fits are known to
        (:func:`~core.rotation_continuity.either_way`), whose way neither the whole mesh's turn
        (:func:`~core.inbetween_rigid_fits.whole_tells`, where no piece turns against it:
        :func:`~core.inbetween_rigid_fits.turning_against`, and of a piece that turns with it:
        :func:`~core.inbetween_rigid_fits.turning_with`) nor such a step tells (two poses have no
        steps): the keys do not tell which way round they went (a crank turning 180° per gap on a
        fixed block: its keys alternate between two poses)."""
        last = len(self._raw) - 1
        w = relative.screw[:, :3]
        theta = np.linalg.norm(w, axis=1)
        near = theta > NEAR_HALF_TURN
        spread = turn_spread(relative.nonrigidity)
        # the whole mesh's way tells the pieces' half turns only where no piece turns against it,
        # and only those of the pieces that turn with it
        told = np.zeros(theta.size, dtype=bool)
        if relative.whole_tells and not turning_against(w, relative.whole_turn, spread).any():
            told = turning_with(relative.motion[0], relative.whole_turn)
        relative.untold_half_turn = either_way(theta, spread) & ~told
        if not near.any() or not self.smooth or last < 2:
            return relative
        d = self._durations
        steps = []
        for a, b in ((base - 1, base), (base + 1, base + 2)):
            if 0 <= a and b <= last:
                step = rotation_vectors(rigid_fits(self._topo, self._key(a).vertices, self._key(b).vertices)[0])
                # a step near a half turn itself tells no way round
                clear = np.linalg.norm(step, axis=1) <= NEAR_HALF_TURN
                steps.append(np.where(clear[:, None], step * (d[base] / d[a]), np.nan))
        if not steps:
            return relative
        told = ~np.all(np.isnan(steps), axis=(0, 2))
        relative.untold_half_turn &= ~told
        expected = np.where(told[:, None], np.nanmean(np.where(told[None, :, None], steps, 0.0), axis=0), 0.0)
        other_way = the_other_way(w, theta)
        # the other way is taken where it is nearer the steps' turn by more than it turns the gap's
        # middle further than the short way does (π − θ): a step that barely favours it does not
        # outweigh the short way (a flag turning 160° after a step of 52° about another axis is 16°
        # nearer the steps' turn the other way round, against 20°: taken so, it went 0.76 of its
        # diagonal the wrong way round); at a half turn itself (a skirt spun 179.5°) any step decides
        nearer = np.linalg.norm(w - expected, axis=1) - np.linalg.norm(other_way - expected, axis=1)
        swap = near & told & (nearer > np.pi - theta)
        if swap.any():
            relative.screw = component_screws(*relative.motion, np.where(swap[:, None], other_way, w), True, relative.nonrigidity)
        return relative
