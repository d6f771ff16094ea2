"""In-betweens for every gap of K key poses of one mesh (paper §8.4, Figs. 14–15).

:class:`SequenceInterpolator` ``(key_poses, triangles)`` (re-exported by :mod:`core`) — ``pose(gap_index,
factor)``, ``poses(gap_index, factors)`` (all in-betweens of a gap at once) and ``pose_at(time)``;
C¹-smooth across keys. Two poses (:class:`~core.two_pose_inbetweens.Interpolator`) are a two-key
sequence interpolated linearly; how a sequence leaves its first key and reaches its last:
:mod:`core.motion_ends`.

What is interpolated
--------------------
Not the shape-difference operators themselves but what they determine in the full basis
(:mod:`core.deformation_fields`): per triangle, the **stretch** (the metric: edge lengths and
area, §4.2, Props. 1–2; log-Euclidean, so lengths stay positive and isometric motions stay
isometric at every factor) and the **rotation** (the extrinsic information, §5.3; as a residual
to the whole mesh's rigid motion, which is interpolated along its screw motion, so any rigid
motion of the mesh — pieces included, half turns included — is reproduced exactly). Sequences
spline both over the neighbouring keys (:mod:`core.splines`); two poses interpolate linearly.
With a truncated basis (``k_M``/``k_N``) the stretch toward each key is the one whose edge lengths
the truncated intrinsic differences recover (§7.1–7.2, :meth:`ReferenceShape.recover_metric`);
rotations still come from the poses.

Reconstruction (§7.3 in local/global form): positions minimizing
``Σ_T Σ_{edges ij of T} |x_j − x_i − R_T(s) U_T(s) (a_j − a_i)|² + Σ_v w_v m_v |x_v − p_v(s)|²``:
a Poisson solve whose matrix depends on the topology and the anchor weights only, factorized once
(sparse LU, symmetric ordering) and reused for every in-between, then a few local/global
(as-rigid-as-possible) steps re-fitting each triangle's rotation while keeping its interpolated
metric. The anchor ``w`` is a gauge (:data:`core.inbetween_topology.GAUGE_WEIGHT`) except in two-pose interpolation
(and a sequence of only two keys, or a linear one (``smooth=False``), that bends a piece at a joint,
:data:`core.sequence_bent_parts.TWO_KEY_BENT_TURN`, or a gap of more keys whose splines read a part of
a piece turned past :data:`core.sequence_bent_parts.BENT_PART_TURN` from another, or past
:data:`core.sequence_bent_parts.RIGID_BENT_TURN` where both parts are rigid to the keys' rounding, in
it or in a gap next to it, in a piece the gap does not read turning: those keep the sequence's gauge),
where vertices whose neighbourhood only translates between the keys are anchored to the linear blend
(exact for them, at every factor: parts that do not move stay put); see
:data:`core.inbetween_anchor.BLEND_ANCHOR_WEIGHT`. Connected components with no such vertex are placed by their
centroid, moved by the interpolated rigid motion of the whole mesh plus the interpolated residual
of the component (pieces of a mesh move as one).

Defects (flipped or collapsed triangles, non-finite values) are repaired where they are, and if
that fails a documented fallback is returned with a :class:`~core.errors.ShapeDifferenceWarning`
(:mod:`core.inbetween_repair`).

The parts :class:`SequenceInterpolator` composes: its keys, their relatives and caches
(:mod:`core.sequence_keys`), how each gap starts (:mod:`core.sequence_gap_starts`), the next gap begun in
the pool while a gap ends (:mod:`core.sequence_gaps_ahead`), the later gaps computed in a second process
(:mod:`core.gap_processes`), near half turns
(:mod:`core.sequence_half_turns`), parts turned past a half turn (:mod:`core.sequence_turn_readings`),
parts spun past a half turn through a wrung cloth (:mod:`core.spun_parts`), mirrored keys
(:mod:`core.sequence_mirrors`), its warnings (:mod:`core.sequence_warnings`).
"""

from __future__ import annotations

import numpy as np

from .allocator import keep_heap
from .concurrency import in_background, result, single_threaded_blas
from .geometry import coordinate_dot
from .inbetween_prediction import gap_poses
from .inbetween_keys import Relative
from .inbetween_solver import Gap
from .inbetween_threads import CONCURRENT_VERTICES
from .validation import (INBETWEEN_BYTES_PER_VERTEX, check_factors, check_gap_index, check_key_times,
                         check_output_memory, check_real, check_end, check_sequence, check_start, check_time,
                         numerical_failures)
from .sequence_gap_starts import GapStarts
from .sequence_gaps_ahead import GapsAhead
from .gap_processes import GapProcesses
from .sequence_half_turns import HalfTurns, turning_as_one, untold_half_turns
from .sequence_keys import GAP_CACHE, KEY_CACHE, SequenceKeys
from .inbetween_joint_doubts import joint_warnings
from .sequence_bent_parts import (BENT_PART_TURN, HIDDEN_PART_MEAN, ISOMETRIC, RIGID_BENT_TURN, RIGID_METRIC,
                                  RIGID_METRIC_CAP, TWO_KEY_BENT_TURN, bent_part_turns, hidden_rigid_turn,
                                  hidden_rigid_warning, rigid_share, rounded_tolerance, rounding_hides)
from .sequence_turn_readings import TurnReadings, composed_apart, turn_warnings
from .near_seams import seam_opening
from .sewn_seams import gap_groups, sewn_offsets
from .splines import five_key_tangent_correction, slowing_end_correction
from .sequence_caught_stretch import caught_stretch, caught_stretch_factors, caught_stretch_warning
from .rest_pose_scale import checked_rest_pose
from .sequence_edge_misfit import (MISFIT_NOTED_FLOOR, key_deviation, misfit_allowed, misfit_warning, off_rest_warning,
                                   signed_deviation)
from .sequence_warnings import carried_stop_warning, gap_problems, warn_said
from .spun_parts import SpunParts
from .rounded_slivers import rounded_sliver_warning, rounded_slivers, rounding_cause, sliver_excess

__all__ = ["SequenceInterpolator"]

#: Keys unevenly spaced (``key_times``): a gap sees its neighbouring keys at most this many times
#: nearer or further than they are when evenly spaced. Steady motion stays exact up to it (a retime
#: keyed every 16th frame with a last gap of one); beyond it the keys' own speeds differ so much
#: that the mean of their secants swings the in-betweens out (keys at 0, 1, 1000, 1001 of a
#: draping sheet: 3.4 units beyond the keys' box, 70 flipped triangles; 0.008 with the limit).
KEY_TIME_RATIO_LIMIT = 16.0


class SequenceInterpolator(SequenceKeys, GapStarts, HalfTurns, TurnReadings, SpunParts, GapsAhead, GapProcesses):
    """In-betweens for every gap of K ≥ 2 key poses of one mesh (e.g. every 4th simulation frame).

    ``key_poses``: sequence of K arrays ``(n, 3)`` (or an array ``(K, n, 3)``); ``triangles`` int
    ``(m, 3)``. ``pose(gap_index, factor)`` returns float64 ``(n, 3)``: key ``gap_index`` at
    factor 0, key ``gap_index + 1`` at factor 1; ``poses(gap_index, factors)`` float64
    ``(len(factors), n, 3)``. ``len()`` is the number of gaps, K − 1. ``pose_at(time)`` takes a
    global time in key units (``time = gap_index + factor``).

    Rotations, stretches, the rigid motion and the centroids are interpolated with cubic splines
    over the neighbouring keys (``smooth=True``; linear with ``smooth=False``), so consecutive
    gaps join with matching velocity (unless a collision stopped the motion at the key, see
    :class:`core.splines.HermiteGap`). The topology and its factorization are built once; each
    gap's data on first use (the last few gaps are cached). A gap's results depend only on the
    keys, the gap and the factors asked for. ``k_M``/``k_N``/``offset``/``use_extrinsic`` as for
    :class:`~core.two_pose_inbetweens.Interpolator`.

    ``key_times``: the time (frame) of each key, strictly increasing, or None (evenly spaced). The
    splines' tangent at a key is the mean of its two neighbouring secants per unit time, so steady
    motion stays steady across unevenly spaced keys (keys every 4th frame and the last one 2 frames
    on: a range that is not whole steps). Factors stay per gap (0 → its first key, 1 → its
    second); :meth:`pose_at` then takes times in the keys' own. The free-flight and steadiness
    tests, which compare three or four keys, run only where those keys are evenly spaced.

    ``start``: how the motion enters the first key. ``"rest"`` (the default): from rest, as a
    simulation baked from its first frame or an animation from a held pose — the first gap starts
    with zero velocity. ``"keys"``: keys cut from the middle of a motion — the start velocity is
    that of the parabola through the first three keys, at most the first gap's (exact for motion
    at constant velocity or acceleration). Where the source's frames between the keys are at hand
    (the operators, :func:`core.retime.retime`), :func:`~core.motion_ends.start_of_motion` chooses from the frame in
    the middle of the first gap.

    ``end``: how the motion reaches the last key. ``"keys"`` (the default): at the last gap's mean
    velocity (the linear extrapolation past the last key, as Catmull–Rom's end condition), as a
    simulation stopped at any frame — slower where the last three keys show a point slowing into
    the last key (the positions in the world, :func:`~core.splines.slowing_end_correction`; a rigid
    piece's rigid motion, its turn and its move each from its own keys' slowing, a jointed piece's
    relative to its parent by its turn's, :func:`~core.splines.slowing_screw_correction`, by the
    piece's rigidity).
    ``"rest"``: it comes to rest there, as an animation easing into its last keyframe — the last
    gap ends with zero velocity (every spline's end tangent;
    exact for motion at constant deceleration to a stop). :func:`~core.motion_ends.end_of_motion` chooses from the
    source's frame in the middle of the last gap.

    :attr:`key_names`: the keys as errors and warnings name them: ``key_names`` (K strings, such as
    the frames of a cache's samples, :func:`core.retime.iter_retime`, or the operators' frames),
    else ``"key pose i"``; a sequence keyed on some of another's keys names them as that one does
    (:func:`core.retime.iter_retime`'s short last gap).

    ``rest_pose``: the mesh's rest shape (n, 3), in the keys' space and size (a simulation's first
    frame), or None. The sequence's ``fit`` warnings hold the in-betweens' edge lengths to what the
    keys' own deviation from the rest allows (:mod:`core.sequence_edge_misfit`,
    :mod:`core.sequence_caught_stretch`); without it the first key stands for the rest, as it does
    where the keys start at a simulation's first frame. Keys cut from the middle of a simulation,
    measured from their first key, measure the change between two deformed states instead: a
    curtain 10 % off its rest at the first key reads keys back within 1.5 % of the rest as 10 % off,
    and gaps 2.7 × past issue 17's edge bound go unwarned; a flag 1.9 % off its rest at the first key
    is allowed a misfit of 1.8 % where the rest allows 4.1 %, and in-betweens within the bound are
    warned (docs/inbetween-measurements.md, *The edge warnings' reference*). No in-between changes.
    A rest whose edges are a median ratio past :data:`~core.rest_pose_scale.REST_SCALE_LIMIT` (2 ×)
    or under its inverse of the first key's (other units, another object scale) raises MeshError
    (:mod:`core.rest_pose_scale`).
    """

    @single_threaded_blas()  # one BLAS thread, as in _poses: the same keys whatever ran before in the process
    def __init__(self, key_poses, triangles, *, k_M: int | None = None, k_N: int | None = None,
                 offset: float | None = None, use_extrinsic: bool = True, smooth: bool = True, start: str = "rest",
                 key_times=None, end: str = "keys", key_names=None, rest_pose=None):
        keep_heap()  # many mesh-sized temporaries from here on: reuse the heap's pages
        start, end = check_start(start), check_end(end)
        key_poses, k_M, k_N, offset, use_extrinsic, smooth, topology = check_sequence(
            key_poses, triangles, k_M, k_N, offset, use_extrinsic, smooth, key_names, checked=self._keys_checked)
        key_times = check_key_times(key_times, len(key_poses))
        rest_pose = checked_rest_pose(rest_pose, key_poses[0], topology.triangles)
        with numerical_failures(f"Preparing the in-betweens of {len(key_poses)} key poses"):
            self._setup(key_poses, topology, k_M, k_N, offset, use_extrinsic, smooth, start, key_times, end=end,
                        key_names=key_names)
        # in the working space of the keys (their vertices as solved: welded, merged, renumbered; moved and sized)
        kept = self._welded_vertices
        self._rest = None if rest_pose is None else self._to_working(rest_pose if kept is None else rest_pose[kept])
        # what a second process builds its own from, where it may share the gaps (core.gap_processes): the
        # sequence's own copies (the keys are, by check_sequence), never the caller's triangles, which it may
        # reuse for another mesh once the sequence is built
        self._share_gaps_later((key_poses, np.array(triangles), dict(
            k_M=k_M, k_N=k_N, offset=offset, use_extrinsic=use_extrinsic, smooth=smooth, start=start,
            key_times=key_times, end=end, key_names=self.key_names, rest_pose=rest_pose)))

    #: The keys and options as another process's sequence checked them, not checked again (the gap
    #: worker's copy of the caller's sequence, :mod:`core.gap_worker`; :func:`core.validation.check_sequence`).
    _keys_checked = False
    #: Every piece's rotations taken whole, not as residuals to its rigid motion (the second fit of
    #: :class:`~core.two_pose_inbetweens.Interpolator`, see :data:`~core.two_pose_inbetweens.WHOLE_FIT_MARGIN`).
    _whole_rotations = False
    #: The stretch between the keys from the log spline (the third fit of
    #: :class:`~core.two_pose_inbetweens.Interpolator`, see :data:`~core.two_pose_inbetweens.LOG_METRIC_FIT`).
    _log_metric = False

    def _gap(self, gap: int) -> Gap:
        pending = self._pending.pop(gap, None)
        if pending is not None:
            result(pending, self._prepare, gap)  # prepared in the background (or here if not begun): cached now
        with self._cache_lock:
            segment = self._gaps.get(gap)
            if segment is not None:
                self._gaps.move_to_end(gap)
                return segment
        return self._prepare(gap)

    def _prepare_in_background(self, gap: int) -> None:
        """Start preparing gap ``gap`` (the next one of an in-order visit) in a pool thread while
        the current gap's in-betweens are solved: its keys and relatives are half of a gap's
        serial work on large meshes. Not with a truncated metric (its recovery warns and keeps
        one base shape), on small meshes, nor for a gap a second process computes
        (:mod:`core.gap_processes`)."""
        if (gap >= len(self) or gap in self._gaps or gap in self._pending or self.k_M is not None
                or self._topo.n < CONCURRENT_VERTICES or self._worker_holds(gap)):
            return
        future = in_background(self._prepare, gap)
        if future is not None:
            self._pending[gap] = future

    def _prepare(self, gap: int) -> Gap:
        """Build gap ``gap``'s data and cache it (the least recently used gap is let go first, so
        that no more than GAP_CACHE gaps are held while it is built)."""
        with self._cache_lock:
            while len(self._gaps) >= GAP_CACHE:
                self._gaps.popitem(last=False)
        topo, base = self._topo, self._key(gap)
        last = len(self._raw) - 1
        others = [gap + 1, gap + 2] if self.smooth and last >= 2 and gap + 2 <= last else [gap + 1]
        ahead = self._relatives(gap, others)
        try:
            # parts bent about a joint far between the keys, read before the rotations are taken whole;
            # with only two keys or a linear spline (smooth=False), at any turn: the keys' spline is
            # then their chord, which the anchor would pull a bending part onto, inside its arc
            chord = (last == 1 or not self.smooth) and self._across is None
            reading = self._keys_relative(gap, ahead[0]) if self._across is None else None
            bent = self._bent_turn(gap, reading, TWO_KEY_BENT_TURN if chord else BENT_PART_TURN)
            # a chord across a piece bent at a joint: anchored to the blend where it keeps the edge
            # lengths, as two poses are (the part that does not turn holds, the turning part follows
            # its rotations)
            anchored = chord and bool((bent > TWO_KEY_BENT_TURN).any())
            # the pieces a part of which turns past a half turn from the rest of them, or past a right
            # angle where they bend without a crease (TURNED_PART_SHARE; two poses take every piece's
            # turns continuous across the mesh)
            none = np.zeros(len(topo.components), dtype=bool)
            turning, root, folded, free, unsure, apart = none, None, none, None, none, np.zeros(len(topo.components))
            if self._across is None:
                turning, root, folded, _, contested, *_ = self._reading(gap, relative=ahead[0])
                if turning.any():
                    # where the readings of the gaps around disagree, from the part nearest the rigid turn
                    turning, root, folded, continued, contested, held_only, _ = self._reading(gap, final=True,
                                                                                              relative=ahead[0])
                    contested = contested | self._held_alone(gap, held_only)
                    apart = composed_apart(self._topo, self._key(gap).areas, turning, root, continued)
                    free = self._unsure(gap)[topo.triangle_component]
                    unsure = (self._unsure(gap, final=True) if free.any() else none) | (contested & self._wagging(gap))
                    free = free if free.any() else None
            # more keys: so too where the keys' spline reads a part bent past its least turn (_bent_past:
            # BENT_PART_TURN, or RIGID_BENT_TURN for parts rigid to the keys' rounding) in a piece not read
            # turning; the pieces read turning (their rotations taken whole and continuous,
            # placed along their turn) keep the sequence's gauge in that anchor (Gap's ``left``)
            left = None
            if not chord and self._across is None:
                anchored = self._bent_nearby(gap, bent, reading, turning)
                left = turning if anchored and turning.any() else None
            # parts spun past a half turn that the keys read the short way round: patches of the mesh
            # tell them where its wrinkles keep its triangles' turns from being taken continuous (the
            # pieces read turning or folded above are taken so or warned of already)
            spun = self._spun(gap, turning | folded) if self._across is None else (0.0, 0.0)
            # rotation fields taken whole in the components whose rigid fits add turn (SPURIOUS_RIGID_TURN)
            # and in the turning ones
            whole = np.ones(len(topo.components), dtype=bool) if self._whole_rotations else \
                np.any([r.residuals_add_turn(topo, base, self._key(k)) for r, k in zip(ahead, others)], axis=0)
            segment = self._segment(gap, ahead, others, whole | turning, turning, root, free, anchored, left)
            # ... and in those whose composed rotations pull against the world spline's guide (AGAINST_GUIDE_SHARE)
            against = segment.rotations_against_guide()
            if against.any():
                segment = None  # let the first build go before the second is made (one gap held, not two)
                segment = self._segment(gap, ahead, others, whole | turning | against, turning, root, free, anchored,
                                        left)
            segment.folded_turn = bool(folded.any())
            segment.unsure_turn = bool(unsure.any())
            segment.untold_half_turns = int(np.count_nonzero(untold_half_turns(segment, ahead[0])))
            segment.whole_half_turn = bool(segment.untold_half_turns) and turning_as_one(segment, ahead[0])
            segment.composed_apart = float(apart.max(initial=0.0))
            segment.spun_part = spun
            segment.aliased_spin = bool(self._aliased_spin(gap).any())
            segment.reversed_spin = 0.0 if segment.aliased_spin else self._reversed_spin(gap)
            largest = float(bent.max(initial=0.0))  # of any piece, turning or not
            segment.bent_turn = largest if largest > BENT_PART_TURN else 0.0
            if not anchored and not chord and self._across is None:  # parts the keys' rounding may hide as bones
                segment.hidden_rigid_turn = self._hidden_rigid_turn(gap, reading, turning)
            for relative in segment.relatives:  # copies sharing the vectors: read by this preparation alone
                relative.let_go_whole_vectors()
        finally:  # the relatives ahead are cached (_forwards): let go on every path, a failed one too
            for relative in ahead:
                relative.let_go_whole_vectors()
        with self._cache_lock:
            self._gaps[gap] = segment
        return segment

    def _keys_relative(self, gap: int, relative: Relative | None = None) -> Relative:
        """Key ``gap + 1`` seen from key ``gap`` with the keys' own metric, which the rigid parts of
        a piece are read from (:func:`core.sequence_bent_parts.bent_part_turns`): ``relative`` (the
        gap's, :meth:`_relatives`, made here if None) but with a truncated metric (``k_M``), whose
        recovery smooths it off the identity on a bent limb's bones (a tube keyed 0 / 100 / 150°
        read no part at k_M = 60 and was placed 2.1e-2 of the diagonal off the rig half-way,
        unwarned)."""
        if self.k_M is None:
            return relative if relative is not None else self._relatives(gap, [gap + 1])[0]
        return self._turning_on(gap, Relative(self._topo, self._key(gap), self._key(gap + 1), across=self._across,
                                              fits=self._fits(gap, gap + 1)))

    def _bent_turn(self, gap: int, relative: Relative | None = None, least: float = BENT_PART_TURN,
                   tolerance: float = ISOMETRIC, rounded: bool = False, mean: float | None = None) -> np.ndarray:
        """Per piece (float (C,)), the largest turn (radians) between two rigid parts of it from key
        ``gap`` to the next (:func:`core.sequence_bent_parts.bent_part_turns`, ``least`` its least
        turn read, its parts' metric the identity's to ``tolerance``); 0 in a gap warned of mirrored
        pieces and for two poses. ``relative``: key ``gap + 1`` seen from key ``gap`` with the keys'
        own metric (:meth:`_keys_relative`), if at hand; ``rounded``: the tolerance raised per triangle to
        what the keys' rounding moves its metric by (:meth:`_rounded_tolerance`); ``mean``: the parts' mean
        metric the identity's to it too. Kept per gap and reading (not to be changed in place): a gap reads
        its neighbours' (:meth:`_bent_nearby`)."""
        count = len(self._topo.components)
        if self._across is not None or gap in self._mirrored_gaps:
            return np.zeros(count)
        with self._cache_lock:  # gaps are prepared on several threads; the reading depends on the keys alone
            known = self._bent_turns.get((gap, least, tolerance, rounded, mean))
        if known is not None:
            return known
        relative = relative if relative is not None else self._keys_relative(gap)
        within = self._rounded_tolerance(gap, tolerance) if rounded else tolerance
        turn = bent_part_turns(self._topo.triangle_component, self._edge_pairs, relative.rotvec, relative.metric,
                               self._key(gap).areas, least, within, mean)
        turn = np.pad(turn, (0, count - len(turn)))  # pieces with no triangle after the last that has one
        with self._cache_lock:
            self._bent_turns[(gap, least, tolerance, rounded, mean)] = turn
        return turn

    def _key_rounding(self) -> float:
        """The keys' coordinate rounding in working units: the decimal grid they were stored on
        (:func:`core.coordinate_rounding.decimal_rounding`) or their precision's spacing
        (:func:`core.coordinate_rounding.coordinate_rounding`), whichever is coarser."""
        return max(self._rounding, self._decimal_rounding) * self._unit

    def _rounded_tolerance(self, gap: int, least: float) -> np.ndarray:
        """Per triangle (m,), the metric's tolerance ``least`` raised to what the keys' rounding moves it
        by in gap ``gap`` (:func:`core.sequence_bent_parts.rounded_tolerance`, the heights of its first
        key): for parts rigid to the rounding (``least`` = ``RIGID_METRIC``) at most ``RIGID_METRIC_CAP``."""
        base = self._key(gap)
        return rounded_tolerance(base.heights, self._key_rounding(), least,
                                 RIGID_METRIC_CAP if least == RIGID_METRIC else np.inf)

    def _hidden_rigid_turn(self, gap: int, relative: Relative, turning: np.ndarray) -> float:
        """The turn (radians) between two parts of a piece not read ``turning`` (bool (C,)) that gap ``gap``
        reads isometric to the keys' rounding (their mean metric the identity's to ``HIDDEN_PART_MEAN``)
        but not rigid to it, where that rounding is too coarse to tell a bone's rigidity
        (:func:`core.sequence_bent_parts.hidden_rigid_turn`; ``relative`` as for :meth:`_bent_turn`); 0
        elsewhere. Keys finer than that (every benchmark cloth's) cost a look at their first key's heights."""
        base = self._key(gap)
        hidden = rounding_hides(self._topo.triangle_component, base.heights, base.areas, self._key_rounding())
        hidden = np.pad(hidden, (0, len(turning) - len(hidden))) & ~turning
        if not hidden.any():
            return 0.0
        return hidden_rigid_turn(hidden, self._bent_turn(gap, relative, RIGID_BENT_TURN, ISOMETRIC, rounded=True,
                                                         mean=HIDDEN_PART_MEAN),
                                 self._bent_turn(gap, relative, RIGID_BENT_TURN, RIGID_METRIC, rounded=True))

    def _bent_past(self, gap: int, pieces: np.ndarray, relative: Relative | None = None) -> bool:
        """Whether gap ``gap`` (of three keys or more) reads a part of one of ``pieces`` (bool (C,))
        turned from another past its least turn: :data:`~core.sequence_bent_parts.BENT_PART_TURN` for
        parts isometric to :data:`~core.sequence_bent_parts.ISOMETRIC`,
        :data:`~core.sequence_bent_parts.RIGID_BENT_TURN` for parts rigid to the keys' rounding
        (:data:`~core.sequence_bent_parts.RIGID_METRIC`: a skinned bone's, whose arc the keys' spline
        cuts at any turn). ``relative`` as for :meth:`_bent_turn`."""
        return bool((self._bent_turn(gap, relative)[pieces] > BENT_PART_TURN).any()) or \
            bool((self._bent_turn(gap, relative, RIGID_BENT_TURN, RIGID_METRIC, rounded=True)[pieces] >
                  RIGID_BENT_TURN).any())

    def _bent_nearby(self, gap: int, bent: np.ndarray, relative: Relative, turning: np.ndarray) -> bool:
        """Whether gap ``gap`` (of three keys or more; ``bent``: its own :meth:`_bent_turn` per piece,
        ``relative``: key ``gap + 1`` seen from key ``gap``, :meth:`_keys_relative`) is anchored as
        two poses are: where the keys' per-vertex spline it would be anchored to reads a part of a
        piece turning from another past its least turn (:meth:`_bent_past`), whose arc that spline
        cuts — in the gap itself or, for a cubic spline (keys ``gap − 1`` … ``gap + 2``), in a gap
        next to it, whose keys' tangents bend the spline inside the arc too — in a piece the gap does
        not read ``turning`` (bool (C,)): those take their rotations whole and keep the sequence's
        gauge in the anchor (:class:`~core.inbetween_solver.Gap`'s ``left``), so a bent limb is
        anchored beside a curling tail of another piece. The neighbours are read only where the
        gap's own keys keep room for two rigid parts
        (:func:`core.sequence_bent_parts.rigid_share`; a free cloth has none, a pinned one may)."""
        if (bent[~turning] > BENT_PART_TURN).any():
            return True
        if not rigid_share(self._topo.triangle_component, relative.metric, self._key(gap).areas):
            return False
        return any(self._bent_past(near, ~turning, relative if near == gap else None)
                   for near in (gap, gap - 1, gap + 1) if 0 <= near < len(self))

    def _segment(self, gap: int, ahead: list[Relative], others: list[int], whole: np.ndarray,
                 turning: np.ndarray, root: np.ndarray | None = None, free: np.ndarray | None = None,
                 anchored: bool = False, left: np.ndarray | None = None) -> Gap:
        """Gap ``gap``'s data from the relatives ``ahead`` of its keys ``others`` (the next one and,
        in a cubic sequence, the one after), with the triangles' whole rotations in the components
        ``whole`` (bool (C,); :meth:`Relative.whole_rotations`), those of the next key taken
        continuous across the mesh in the components ``turning`` (bool (C,), whole too: a part of
        them turns far from the rest, :meth:`Relative.turning`; ``root``: their
        triangles that the rest turns from, bool (m,), or None; ``free``: the triangles whose
        turns are read from the part nearest their piece's rigid turn, :meth:`_reading`; ``anchored``:
        anchored to the linear blend as two poses are, whatever the sequence's own anchor; ``left``:
        bool (C,) or None, the pieces such an anchor leaves at the gauge, :meth:`_bent_nearby`)."""
        topo, base = self._topo, self._key(gap)
        last = len(self._raw) - 1
        ident = Relative.identity(topo, base)
        cubic = self.smooth and last >= 2
        if whole.any():
            pairs = self._edge_pairs
            across = pairs[turning[topo.triangle_component[pairs[:, 0]]]] if turning.any() else None
            ahead = [r.whole_rotations(topo, base, self._key(k), whole, *((across, free) if k == gap + 1 else ()))
                     for r, k in zip(ahead, others)]
        nxt = ahead[0]
        if cubic:
            # keys unevenly spaced: the neighbours' times in units of this gap (1 when even)
            d, limit = self._durations, KEY_TIME_RATIO_LIMIT
            ahead_time = 1.0 + np.clip(d[gap + 1] / d[gap], 1.0 / limit, limit) if gap + 2 <= last else 2.0
            back_time = np.clip(d[gap - 1] / d[gap], 1.0 / limit, limit) if gap >= 1 else 1.0
            # rigid motions: the rotation vector nearest the continuation of the next key's
            turn = nxt.screw  # screws: a whole turn between keys continues about the same axis
            after = ahead[1].unwrap(ahead_time * turn, ahead_time * nxt.rotvec, nxt) if gap + 2 <= last else None
            if after is not None and ahead_time != 2.0:  # where an evenly spaced key would be
                after = after.rescaled(nxt, 1.0 / (ahead_time - 1.0))
            # the sequence's start: from rest, or the parabola through the first three keys, its
            # tangent at most the first gap's secant (see splines.START_TANGENT_LIMIT); its end: linear,
            # the positions and the rigid pieces' motions slowed where the last keys slow
            # (_tangent_correction, Gap's slowing_end), or at rest
            # (end="rest", which sets the last gap's end tangents to zero)
            prev = self._previous(gap, -back_time * turn, whole).continue_turns(-back_time * nxt.rotvec) \
                if gap >= 1 else Relative.phantom(nxt, ident, after)
            if back_time != 1.0:
                prev = prev.rescaled(ident, 1.0 / back_time)
            after = after if after is not None else Relative.phantom(ident, nxt)
        else:
            prev = after = ident
        corrections = (self._tangent_correction(gap), self._tangent_correction(gap + 1)) if cubic else None
        return Gap(topo, base, self._key(gap + 1), [prev, ident, nxt, after], cubic, self.use_extrinsic,
                    self._anchored or anchored, self._static, self._riding, riding_tolerance=self._riding_tolerance * self._unit,
                    start_limit=self._start_limit(gap), rest_end=cubic and self.end == "rest" and gap == last - 1,
                    whole_rotations=whole, steady=self._steady(gap) if cubic else None,
                    entry=self._entry(gap, prev.nonrigidity) if cubic else None,
                    exit=self._exit(gap) if cubic else None,
                    hooked=self._hooked, turning=turning, root=root, left=left, log_metric=self._log_metric,
                    unit=self._unit,
                    sewn=gap_groups(self._near_seams, gap, topo.triangles, topo.n, self._rounding * self._unit),
                    corrections=corrections,
                    # the last key's slowing end (its correction made: end="keys", evenly spaced) for the
                    # rigid motions too
                    slowing_end=cubic and gap + 1 == last and corrections[1] is not None)

    def _tangent_correction(self, key: int) -> np.ndarray | None:
        """The five keys' correction to Catmull–Rom's tangent of the world spline of positions at key
        ``key`` (n, 3; :func:`~core.splines.five_key_tangent_correction`, :data:`~core.splines.FIVE_KEY_LIMIT`),
        or None where a key two away on either side is missing (a sequence's end: no phantom key) or
        the five keys are unevenly spaced; at the last key of an ``end="keys"`` sequence the slowing
        end's correction to the linear end condition (:func:`~core.splines.slowing_end_correction`;
        None where the last two gaps are unevenly spaced). Made once for both gaps that meet at the
        key (read-only), kept for the last :data:`KEY_CACHE` keys."""
        x, d, last = self._raw, self._durations, len(self._raw) - 1
        if key == last:
            # the last key (end="keys"; end="rest" makes the tangent zero): the linear end condition's
            # tangent, slowed where the last three keys show the motion slowing into the key
            if last < 2 or self.end != "keys" or d[-1] != d[-2]:
                return None

            def slowed():
                correction = slowing_end_correction(*x[last - 2:])
                correction.flags.writeable = False
                return correction

            return self._cached(self._corrections, key, KEY_CACHE, slowed)
        if not 2 <= key <= last - 2 or np.ptp(d[key - 2:key + 2]) != 0:
            return None

        def corrected():
            correction = five_key_tangent_correction(*x[key - 2:key + 3])
            correction.flags.writeable = False
            return correction

        return self._cached(self._corrections, key, KEY_CACHE, corrected)

    def _gap_warnings(self, gap: int, segment: Gap) -> list[tuple[str, str, int, tuple[float, ...], float]]:
        """The warnings ``(kind, message, 0, (), excess)`` of gap ``gap`` (its data ``segment``) that hold for every
        in-between of it: how its pieces turn, their joints, and the triangles thin against the
        keys' rounding (:func:`core.rounded_slivers.rounded_slivers`) that keep their own targets
        (no told neighbour: :mod:`core.untold_triangles`; excess: :func:`core.rounded_slivers.sliver_excess`).
        Made once per gap: they depend on the keys only."""
        if gap not in self._gap_messages:
            names = self.key_names
            # the keys' heights, as the untold and rounding readings have them (in the working keys' units)
            heights = [segment.base.heights, segment.next.heights]
            slivers = rounded_slivers(heights, self._rounding * self._unit)
            # those that take a told neighbour's targets follow the mesh (core.untold_triangles): not said
            slivers = np.setdiff1d(slivers, segment.untold[0], assume_unique=True)
            thin = sliver_excess(heights, slivers, self._rounding * self._unit)
            cause = rounding_cause(self._given, (gap, gap + 1), names) if slivers.size else ""  # read where said
            self._gap_messages[gap] = [("turn", m, 0, (), e) for m, e in turn_warnings(segment, names, gap)] + \
                [("joint", m, 0, (), e) for m, e in joint_warnings(segment.joint_doubts, names, gap)] + \
                [("sliver", m, 0, (), thin) for m in rounded_sliver_warning(slivers.size, self._rounding,
                                                                            (names[gap], names[gap + 1]), cause)] + \
                [("turn", m, 0, (), segment.hidden_rigid_turn / RIGID_BENT_TURN) for m in hidden_rigid_warning(
                    segment.hidden_rigid_turn, max(self._rounding, self._decimal_rounding),
                    self._decimal_rounding > self._rounding, (names[gap], names[gap + 1]))] + \
                [("overshoot", m, 0, (), e) for m, e in carried_stop_warning(  # off the keys' spline: pieces
                    # whose rotations are taken whole, or with a part turning far (not anchored to it)
                    self._carried_stop(gap, segment.whole_rotations if segment.turning is None
                                       else segment.whole_rotations | segment.turning), names, gap)]
        return self._gap_messages[gap]

    def pose(self, gap_index: int, factor: float) -> np.ndarray:
        """The pose at ``factor`` in gap ``gap_index`` (key ``gap_index`` → ``gap_index + 1``)."""
        return self.poses(gap_index, [factor])[0]

    def poses(self, gap_index: int, factors, *, ahead: bool = True) -> np.ndarray:
        """The poses (len(factors), n, 3) at ``factors`` in gap ``gap_index``, sharing the work:
        with three or more in-betweens the reconstruction is solved at one to three of them and the
        others are predicted from those (:mod:`core.inbetween_prediction`, which gives the
        measurements against solving each); :meth:`pose` solves every pose. ``ahead``: False where
        the caller asks nothing of gap ``gap_index + 1`` next (its last gap): the next gap is then not
        begun in the pool while this one ends (:mod:`core.sequence_gaps_ahead`); the poses are the same."""
        out, problems = self._poses(gap_index, factors, bool(ahead))
        gap = (self.key_names[int(gap_index)], self.key_names[int(gap_index) + 1]) if problems else None  # checked
        for kind, message, defects, about, *excess in problems:  # excess: a measure ÷ its allowance, where one is
            warn_said(message, kind, defects, gap, about, *excess)
        return out

    # BLAS single-threaded: its calls here are (n, 3) × (3, 3) products, which a second BLAS thread
    # does not speed up; its workers spin on the core the other half of the work needs (10k hanging
    # sheet, keys 4 apart: 0.037 → 0.031 s per in-between in one thread). One thread also whatever
    # ran before in the process: the same poses to the bit (core.concurrency).
    @single_threaded_blas()
    def _poses(self, gap_index: int, factors, ahead: bool = True) -> tuple[np.ndarray, list[tuple]]:
        """:meth:`poses` (``ahead`` as there) and the warnings ``(kind, message, defects, factors)`` (those with a measure
        against an allowance with their ``excess`` after them), not yet given (the caller warns: a warning filter changed
        around the call would be the process's, not this thread's)."""
        # a gap index in range and finite factors within ±MAX_FACTOR, as Python ints and floats
        gap, factors = check_gap_index(gap_index, len(self)), check_factors(factors)
        # the poses (float64) and their working copies within half the memory available, as every output,
        # refused before any work in the user's terms
        check_output_memory(len(factors), self._topo.n, f"The in-betweens asked of gap {gap} at once",
                            "ask for fewer factors at a time", bytes_per_point=INBETWEEN_BYTES_PER_VERTEX)
        taken = self._taken_ahead(gap, factors, ahead)  # the call begun ahead settled first (core.sequence_gaps_ahead)
        # the later gaps given to a second process, or this one taken from it (core.gap_processes)
        shared = self._from_worker(gap, factors, ahead, taken is not None)
        if taken is not None or shared is not None:
            return taken if taken is not None else shared
        with self._sharing():  # one thread while that process has gaps of this sequence
            return self._computed_poses(gap, factors, ahead)

    def _computed_poses(self, gap: int, factors: list[float], ahead: bool) -> tuple[np.ndarray, list[tuple]]:
        """:meth:`_poses` of gap ``gap`` at ``factors`` (checked) computed; ``ahead``: the next gap's
        call may be begun in the pool while this one ends (:class:`~core.sequence_gaps_ahead.GapsAhead`;
        False in that call itself)."""
        out = np.empty((len(factors), self._topo.n, 3))
        between = [k for k, s in enumerate(factors) if s not in (0.0, 1.0)]
        for k, s in enumerate(factors):
            if s in (0.0, 1.0):
                out[k] = self._given[gap + int(s)]
        # a raw failure of a solver is a RecoveryError naming the poses; the sequence is left as it was
        asked = [factors[k] for k in between]
        at = f"at factor {asked[0]:g}" if len(asked) == 1 else \
            f"at factors {', '.join(f'{f:g}' for f in asked)}" if len(asked) <= 4 else f"at {len(asked)} factors"
        with numerical_failures(f"The in-between{'s' if len(asked) > 1 else ''} {at} between {self.key_names[gap]} "
                                f"and {self.key_names[gap + 1]}"):
            return self._solved_poses(gap, factors, out, between, ahead)

    def _solved_poses(self, gap: int, factors: list[float], out: np.ndarray, between: list[int],
                      ahead: bool = False) -> tuple[np.ndarray, list[tuple[str, str, int, tuple[float, ...]]]]:
        """:meth:`_poses` once its arguments are checked: ``out`` (len(factors), n, 3) holds the keys
        at factors 0 and 1, the rows ``between`` are solved here (``ahead``: as for
        :meth:`_computed_poses`). The warnings: the gap's
        (:meth:`_gap_warnings`), then the in-betweens' own, one per kind of problem
        (:func:`core.sequence_warnings.gap_problems`)."""
        if not between or self._hold(gap):  # a hold: the pose at every factor
            out[between] = self._given[gap]
            return self._caller_poses(out, gap, [0.0 if k in between else f for k, f in enumerate(factors)]), []
        segment = self._gap(gap)
        self._prepare_in_background(gap + 1)
        segment.fit_misfits.clear()  # this call's fits only
        solved = gap_poses(segment, [factors[k] for k in between], self._beginning_ahead(gap, factors) if ahead else None)
        problems = []  # (factor, kind, what happened, defects kept) of each in-between with a problem
        held = self._held(gap)
        for k, (x, problem) in zip(between, solved):
            if segment.sewn is not None:  # what a repair moved apart (core.sewn_seams)
                offsets = sewn_offsets(segment, factors[k])
                if segment.sewn.opening(x, offsets) > 0.0:
                    x = segment.sewn.join(x.copy(), offsets, self._topo.mass, segment.static)
            out[k] = self._from_working(x)
            if (self._origin is not None or self._unit != 1.0) and self._static is not None:
                out[k][self._still] = self._given[0][self._still]  # exactly where they sit
            if held.any():  # pieces held in this gap
                out[k][held] = self._given[gap][held]
            if problem:
                outcome = segment.outcomes.get(factors[k])
                problems.append((factors[k], "pose", problem, 0 if outcome is None else outcome.defects))
        attached = self._attached
        if attached is not None:  # in their triangles' frames, their coordinates there blended between the keys
            moving = ~held[attached.vertices]  # held ones stay as the key has them
            for k in between:
                local = (1.0 - factors[k]) * attached.local[gap] + factors[k] * attached.local[gap + 1]
                out[k][attached.vertices[moving]] = attached.placed(out[k], local)[moving]
        for k in between:
            problem = self._finite(out[k], gap, factors[k])
            if problem:
                problems.append((factors[k], "non_finite", problem, 0))
        said = self._gap_warnings(gap, segment) + \
            gap_problems(problems, len(between), (self.key_names[gap], self.key_names[gap + 1]))
        poses = {factors[k]: x for k, (x, _) in zip(between, solved)}
        misfit = self._misfit_warning(gap, segment, poses)
        measured = {}  # the in-betweens' deviation from the rest: measured once, for both readings below
        if misfit is None:  # fits within what their keys allow: the keys may still alias a brief stretch
            misfit = self._caught_stretch_warning(gap, segment, poses, measured)
        if misfit is None:  # ... and the in-betweens themselves may still be off the rest farther than the keys
            misfit = self._off_rest_warning(gap, segment, poses, measured)
        if misfit is not None:
            said.append(("fit", misfit[0], 0, misfit[1], misfit[2]))
        if self._near_seams is not None:  # seams the gap's keys keep closed, not welded: opened by the in-betweens?
            opening = seam_opening(self._near_seams, [out[k] for k in between], [factors[k] for k in between],
                                   (self.key_names[gap], self.key_names[gap + 1]), self._welded_vertices, gap)
            if opening is not None:
                said.append(("seam", opening[0], 0, opening[1], opening[2]))
        return self._caller_poses(out, gap, factors), said

    def _misfit_warning(self, gap: int, segment: Gap, poses: dict) -> tuple[str, tuple[float, ...], float] | None:
        """The warning (message, factors, excess) of gap ``gap`` (its data ``segment``) whose in-betweens
        ``poses`` {factor: working positions (n, 3)} include fitted ones farther off the interpolated
        metric than the keys' own edge deviation from the rest allows (the rest pose where given, else
        the first key: :meth:`_key_deviation`; :func:`core.sequence_edge_misfit.misfit_warning`); None
        where none is. The fits' misfits are the solve's; the keys' deviations are measured only where a
        fit ends past
        :data:`~core.sequence_edge_misfit.MISFIT_NOTED_FLOOR`. Not said of a gap whose pieces are
        mirrored (:func:`core.sequence_mirrors.warn_mirrored` says why its edges are off)."""
        fitted = [m for s, m in segment.fit_misfits.items() if s in poses]
        if not fitted or max(fitted) <= MISFIT_NOTED_FLOOR or gap in self._mirrored_gaps:
            return None
        keys = (segment.base.lengths, segment.next.lengths)
        allowed = misfit_allowed([self._key_deviation(gap, keys[0]), self._key_deviation(gap + 1, keys[1])])

        def signed(s):
            return signed_deviation(self._corner_lengths(poses[s]), (1.0 - s) * keys[0] + s * keys[1])

        return misfit_warning(segment.fit_misfits, list(poses), allowed, (self.key_names[gap], self.key_names[gap + 1]),
                              signed, self._rest_named)

    def _corner_lengths(self, x: np.ndarray) -> np.ndarray:
        """Corner edge lengths (m, 3) of working positions ``x`` (n, 3), as :class:`Key` has them."""
        edges = self._topo.corner_edge_rows(x)  # (3 coordinates, 3 corners, m), as the fit's
        squared = coordinate_dot(edges, edges)
        return np.sqrt(squared, out=squared).T

    @property
    def _from_rest(self) -> bool:
        """Whether the ``fit`` warnings' deviations are from the mesh's rest: the caller's ``rest_pose``,
        or a first key the sequence starts from at rest (``start="rest"``, a simulation's first frame),
        not a deformed first key of keys cut from a motion (:func:`core.sequence_caught_stretch.caught_stretch`)."""
        return self._rest is not None or self.start == "rest"

    @property
    def _rest_named(self) -> str:
        """What the ``fit`` warnings measure deviation from, as they name it."""
        return "the first key" if self._rest is None else "the rest pose"

    def _key_deviation(self, index: int, lengths: np.ndarray | None = None) -> float:
        """Key ``index``'s mean relative edge deviation from the rest (:func:`core.sequence_edge_misfit.key_deviation`):
        from the caller's ``rest_pose`` where given, else from the first key; measured once (a key is in two
        gaps) from its corner edge ``lengths`` (m, 3) where the caller has them (its gap's :class:`Key`), else
        from it."""
        if self._rest_lengths is None:  # its corner edges alone: no key built, none let go
            self._rest_lengths = self._corner_lengths(self._raw[0] if self._rest is None else self._rest)
        if index not in self._key_deviations:
            lengths = self._corner_lengths(self._raw[index]) if lengths is None else lengths
            self._key_deviations[index] = key_deviation(lengths, self._rest_lengths)
        return self._key_deviations[index]

    def _rest_deviation(self, poses: dict, measured: dict) -> tuple[list[float], float]:
        """The factors of the in-betweens ``poses`` {factor: working positions (n, 3)} that stand for a
        gap's (:func:`core.sequence_caught_stretch.caught_stretch_factors`: at most three) and their mean
        relative edge deviation from the rest (:meth:`_key_deviation`'s); kept in ``measured`` (a dict
        of this call's) and read from it where it is there already."""
        if not measured:
            factors = caught_stretch_factors([s for s in poses if 0.0 < s < 1.0])
            measured["factors"] = factors
            measured["deviation"] = float(np.mean([key_deviation(self._corner_lengths(poses[s]), self._rest_lengths)
                                                   for s in factors]))
        return measured["factors"], measured["deviation"]

    def _off_rest_warning(self, gap: int, segment: Gap, poses: dict,
                          measured: dict) -> tuple[str, tuple[float, ...], float] | None:
        """The warning (message, factors, excess) of gap ``gap`` (its data ``segment``) whose in-betweens
        ``poses`` {factor: working positions (n, 3)} are off the rest (:meth:`_key_deviation`'s) farther
        than twice the keys' own deviation interpolated at their factors + 0.1 point
        (:func:`core.sequence_edge_misfit.off_rest_warning`); None elsewhere, and in a gap whose pieces
        are mirrored (:func:`core.sequence_mirrors.warn_mirrored` says why its edges are off) and in
        two poses' (anchored: :class:`core.two_pose_inbetweens.Interpolator` holds its pose to the bound
        itself). ``measured``: as :meth:`_rest_deviation` keeps it."""
        if self._anchored or not any(0.0 < s < 1.0 for s in poses) or gap in self._mirrored_gaps:
            return None
        ends = (self._key_deviation(gap, segment.base.lengths), self._key_deviation(gap + 1, segment.next.lengths))
        factors, deviation = self._rest_deviation(poses, measured)
        return off_rest_warning(deviation, ends, factors, (self.key_names[gap], self.key_names[gap + 1]),
                                self._rest_named)

    def _caught_stretch_warning(self, gap: int, segment: Gap, poses: dict,
                                measured: dict) -> tuple[str, tuple[float, ...], float] | None:
        """The warning (message, factors, excess) of gap ``gap`` (its data ``segment``) beside a key
        that catches a brief stretch on a motion passing through it, whose in-betweens ``poses``
        {factor: working positions (n, 3)} end farther off the rest (:meth:`_key_deviation`) than the gap's
        other key allows (:mod:`core.sequence_caught_stretch`); None elsewhere, and in a gap whose pieces are
        mirrored (:func:`core.sequence_mirrors.warn_mirrored` says why its edges are off). Each key is
        read once (its deviation; its neighbour outside the gap and the shapes around it only where
        that is over what its neighbour inside the gap allows); the in-betweens are measured only
        beside a key that catches a stretch, at most three of them
        (:func:`core.sequence_caught_stretch.caught_stretch_factors`; ``measured``: as
        :meth:`_rest_deviation` keeps it)."""
        asked = [s for s in poses if 0.0 < s < 1.0]
        if not asked or gap in self._mirrored_gaps:
            return None
        ends = (gap, gap + 1)
        lengths = dict(zip(ends, (segment.base.lengths, segment.next.lengths)))
        for at, other in zip(ends, reversed(ends)):
            if not 0 < at < len(self._raw) - 1:  # the first and last keys have one neighbour
                continue
            if at not in self._caught_stretches:  # each key's once: it is in two gaps
                # the neighbour outside this gap (its lengths not at hand) read only where the one inside allows less
                three = (at - 1, at, at + 1)
                if self._key_deviation(at, lengths[at]) <= misfit_allowed([self._key_deviation(other, lengths[other])]):
                    self._caught_stretches[at] = None
                else:
                    self._caught_stretches[at] = caught_stretch([self._key_deviation(k, lengths.get(k)) for k in three],
                                                                [self._raw[k] for k in three],
                                                                self._topo.corner_edge_rows, self._from_rest)
            if not self._caught_stretches[at]:
                continue
            deviation = self._rest_deviation(poses, measured)[1]
            said = caught_stretch_warning(deviation, self._key_deviations[other], (self.key_names[gap],
                                          self.key_names[gap + 1]), self.key_names[at], self._key_deviations[at], asked,
                                          self._rest_named, self._caught_stretches[at])
            if said is not None:
                return said
        return None

    def _finite(self, x: np.ndarray, gap: int, factor: float) -> str | None:
        """None where the pose ``x`` (n, 3) at ``factor`` in gap ``gap`` is finite (the check is
        0.09 ms at 100k vertices); else the pieces holding a non-finite coordinate are given the keys'
        linear blend (extrapolated beyond them) in place, and the warning's message says so. The
        fits and repairs return finite poses on every input found (:mod:`core.inbetween_repair`
        falls back past a non-finite fit); this keeps a numerical failure past them from reaching
        the caller as NaN or infinite coordinates."""
        if np.isfinite(x).all():
            return None
        owner = self._topo.vertex_owner
        bad = ~np.isfinite(x).all(axis=1)
        pieces = np.unique(owner[bad])
        rows = np.isin(owner, pieces) | bad
        x[rows] = (1.0 - factor) * self._given[gap][rows] + factor * self._given[gap + 1][rows]
        blend = "linear blend" if 0.0 <= factor <= 1.0 else "linear extrapolation"
        return (f"{int(np.count_nonzero(bad))} vertex(es) came out with non-finite coordinates (a numerical "
                f"failure of the fit); their {pieces.size} piece(s) ({int(np.count_nonzero(rows))} vertices) are "
                f"the keys' {blend} instead. Check the keys there (a piece nearly flat or far smaller than the "
                "rest), or report it with the mesh")

    def pose_at(self, time: float) -> np.ndarray:
        """The pose at global ``time``: in the keys' own times where ``key_times`` was given, else
        in key units (0 = first key, K − 1 = last key); times outside extrapolate the first or
        last gap."""
        if self._key_times is None:
            time = check_time(time, len(self))
            gap = int(np.clip(np.floor(time), 0, len(self) - 1))
            return self.pose(gap, float(time) - gap)
        times = self._key_times
        value = check_real(time, "time")
        gap = int(np.clip(np.searchsorted(times, value, side="right") - 1, 0, len(self) - 1))
        factor = (value - times[gap]) / (times[gap + 1] - times[gap])
        check_time(gap + factor, len(self))  # the same bound on extrapolation, in gaps
        return self.pose(gap, float(factor))
