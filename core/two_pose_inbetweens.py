"""In-betweens and exaggerations of two poses of one mesh (paper §8.4, Figs. 14–15).

Public API (re-exported by :mod:`core`):

- :func:`interpolate` ``(vertices_a, vertices_b, triangles, factor)`` — one pose; ``factor`` 0 gives
  ``a``, 1 gives ``b``, 0.5 an in-between, 1.5 an exaggeration, negative values reverse the motion.
- :class:`Interpolator` — the same with the preparation done once for many factors.

Both run a two-key :class:`~core.sequence_inbetweens.SequenceInterpolator` (what is interpolated and
how the poses are rebuilt: :mod:`core.sequence_inbetweens`), interpolated linearly, with the parts
that only translate between the poses anchored to their linear blend; an in-between of the full
basis is fitted a second time with every triangle's whole rotation where that keeps the metric
better, and once more to the log-stretches' metric where the kept fit turns triangles over against
their interpolated rotations (:data:`LOG_METRIC_FIT`); poses that differ by wrinkles only give their
linear blend, unless it turns triangles over or collapses them (then they are fitted).
"""

from __future__ import annotations

import copy
import threading
from collections import OrderedDict

import numpy as np
from scipy.spatial.transform import Rotation

from .allocator import keep_heap
from .concurrency import single_threaded_blas
from .inbetween_fit import MISFIT_LENGTH_FLOOR, floored_deviations, short_edges
from .inbetween_prediction import STILL_RIGIDITY
from .validation import check_factor, check_interpolation, check_key_names, numerical_failures
from .sequence_inbetweens import SequenceInterpolator
from .rotation_continuity import jumping_pairs
from .rest_pose_scale import checked_rest_pose
from .sequence_edge_misfit import (MISFIT_NOTED_FLOOR, MISFIT_NOTED_MARGIN, key_deviation, least_shared_deviation,
                                   misfit_allowed, misfit_warning, signed_deviation)
from .sequence_turn_readings import TURNED_PART_SHARE
from .sequence_warnings import warn_said
from .spun_parts import turned_back

__all__ = ["interpolate", "Interpolator"]


class Interpolator:
    """Poses between (and beyond) two poses ``vertices_a`` (factor 0) and ``vertices_b`` (factor 1)
    of one mesh, prepared once: ``pose(factor)`` returns float64 ``(n, 3)``.

    ``k_M``/``k_N``: interpolate truncated shape differences (the metric of ``b`` is the one
    recovered from them); ``None`` = full basis. ``offset``: offset distance of the extrinsic
    differences (the truncated recovery here needs only the intrinsic metric, the rotations come
    from the poses). ``use_extrinsic=False`` interpolates the intrinsic metric only (bending then
    follows the linear blend). Vertices whose neighbourhood only translates from ``a`` to ``b``
    are anchored to the linear blend: parts that do not move stay where they are at every factor.
    ``key_names``: the two poses as errors and warnings name them (such as the operators' shape
    keys), else ``"vertices_a"`` and ``"vertices_b"``.

    ``rest_pose``: the mesh's rest shape (n, 3) (the Basis a cloth was simulated from, a character's
    rest), in the poses' space and size, or None. The ``fit`` warning then holds the in-between's
    mean edge deviation from it to twice the poses' own + 0.1 point, issue 17's edge bound with the
    poses standing in for the simulation (:meth:`_edges_off`); without it two poses give no rest, and
    the fit's misfit is held to twice the least deviation they can have from any rest they share:
    poses 2–3 % off their rest but nearer each other (flags, banners between two frames) are then
    warned within the bound, and more pairs over it are silent. No pose changes.
    Refused (MeshError naming ``rest_pose``) where it is not ``(n, 3)`` of the poses' vertex count,
    not finite, or its edges a median ratio past :data:`~core.rest_pose_scale.REST_SCALE_LIMIT` (2 ×)
    or under its inverse of ``vertices_a``'s (other units, another object scale: every misfit would
    be allowed; :func:`core.rest_pose_scale.checked_rest_pose`).
    """

    @single_threaded_blas()  # as a sequence's (SequenceInterpolator): the same poses whatever ran before
    def __init__(self, vertices_a, vertices_b, triangles, *, k_M: int | None = None, k_N: int | None = None,
                 offset: float | None = None, use_extrinsic: bool = True, key_names=None, rest_pose=None):
        keep_heap()  # many mesh-sized temporaries from here on: reuse the heap's pages
        key_names = check_key_names(key_names, 2, ["vertices_a", "vertices_b"])
        poses, k_M, k_N, offset, use_extrinsic, topology = check_interpolation(
            [vertices_a, vertices_b], triangles, k_M, k_N, offset, use_extrinsic, names=key_names, kept=True)
        rest_pose = checked_rest_pose(rest_pose, poses[0], topology.triangles, first=key_names[0],
                                      without="measure the warnings from the rest nearest both poses")
        self._sequence = SequenceInterpolator.__new__(SequenceInterpolator)
        with numerical_failures(f"Preparing the in-betweens of {key_names[0]} and {key_names[1]}"):
            self._sequence._setup(poses, topology, k_M, k_N, offset, use_extrinsic, False, two_poses=True,
                                  key_names=key_names)
        self._sequence._anchored = True
        self._whole = None  # the second fit's (made when first asked)
        self._log = {}  # the log-stretches' fits', by whether their rotations are whole (made when first asked)
        self._jumping = None  # per piece, whether its turns keep a jump (made when first asked)
        edges = topology.triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        self._edges = edges
        self._squared = [self._squared_lengths(p) for p in poses]
        # the caller's rest's corner edge lengths (3m,): what the fit warning measures the poses from
        self._rest_lengths = None if rest_pose is None else np.sqrt(self._squared_lengths(rest_pose))
        # the fits' floor of short edges, in the poses' units (core.inbetween_fit.MISFIT_LENGTH_FLOOR)
        self._misfit_floor = MISFIT_LENGTH_FLOOR * float(np.mean(np.sqrt(self._squared[0])))
        self._given_poses = poses
        self._chatter = None  # whether the poses differ by wrinkles only (made when first asked)
        self._apart = None  # the poses' mean edge deviations from the rest (made when first asked: _edges_off)

    def _whole_sequence(self) -> SequenceInterpolator:
        """The same keys with every piece's rotations taken whole (:meth:`_variant`)."""
        if self._whole is None:
            self._whole = self._variant(self._sequence, _whole_rotations=True)
        return self._whole

    def _log_sequence(self, whole: bool) -> SequenceInterpolator:
        """The same keys (with every piece's rotations taken whole, or not) with the stretches
        between them from the log spline (:data:`LOG_METRIC_FIT`; :meth:`_variant`)."""
        if whole not in self._log:
            self._log[whole] = self._variant(self._whole_sequence() if whole else self._sequence, _log_metric=True)
        return self._log[whole]

    @staticmethod
    def _variant(source: SequenceInterpolator, **flags) -> SequenceInterpolator:
        """A copy of ``source`` with its class flags ``flags`` set: it shares the keys and topology,
        and has its own gaps (with their anchored systems) and their warnings (a turn reads
        otherwise with whole rotations). It starts with the relative of the second pose that
        ``source`` keeps (:meth:`~core.sequence_keys.SequenceKeys._relatives`): that depends on the
        poses alone, not on the flags, and no reader changes it in place (what it lets go and
        makes again, the same values: :func:`~core.inbetween_whole_rotations.rotation_angles`),
        so it is not built again per variant."""
        variant = copy.copy(source)
        for name, value in flags.items():
            setattr(variant, name, value)
        with source._cache_lock:
            forwards = OrderedDict(source._forwards)
        variant._gaps, variant._pending, variant._cache_lock = OrderedDict(), {}, threading.RLock()
        variant._forwards, variant._bent_turns = forwards, {}  # written under the variant's own lock
        variant._gap_messages = {}
        return variant

    def _chattering(self) -> bool:
        """Whether every piece of the mesh deforms (none moves rigidly:
        :data:`~core.inbetween_prediction.STILL_RIGIDITY`; a rigid piece's turn is no wrinkle, and
        the blend would cut its chord) and its triangles turn between the two poses with no
        coherence across it: neighbouring triangles' turns differ from each other (RMS over the
        pairs sharing an edge of the angle of one's rotation relative to the other's) by at least
        as much as the triangles turn (RMS of their rotations' residuals to the piece's rigid
        motion), and those turns are at least the piece's rigid turn. Such keys are wrinkles changing from
        one to the other, not a motion they resolve: the frames between them have wrinkles of
        their own, not the half turns of the keys' (see :data:`CHATTER_COHERENCE`), so the linear
        blend, their average, is the in-between. A piece turning as a body more than its
        wrinkles (a cushion sliding off a bar, a head turned with its keys' rounding as residuals)
        keeps its fit: the blend would cut the chord of that turn."""
        if self._chatter is None:
            topo, relative = self._sequence._topo, self._sequence._gap(0).relatives[2]
            pairs = self._sequence._edge_pairs
            rotations = Rotation.from_rotvec(relative.rotvec)
            relative_turns = (rotations[pairs[:, 0]] * rotations[pairs[:, 1]].inv()).magnitude()
            turns = np.einsum("ij,ij->i", relative.rotvec, relative.rotvec)
            count, labels = len(topo.components), topo.triangle_component
            pair_labels = labels[pairs[:, 0]]  # a pair sharing an edge lies in one piece
            turned = np.bincount(labels, turns, minlength=count) / np.maximum(np.bincount(labels, minlength=count), 1)
            differing = np.bincount(pair_labels, relative_turns ** 2, minlength=count) / \
                np.maximum(np.bincount(pair_labels, minlength=count), 1)
            rigid_turns = Rotation.from_matrix(relative.motion[0]).magnitude()
            deforming = np.asarray(relative.nonrigidity) > STILL_RIGIDITY
            wrinkling = (differing >= CHATTER_COHERENCE ** 2 * turned) & (turned >= rigid_turns ** 2)
            self._chatter = bool((deforming & wrinkling).all())
        return self._chatter

    def _blend_defects(self, factor: float) -> int:
        """How many triangles the poses' linear blend at ``factor`` (0 < factor < 1) has flipped
        (facing against both poses) or collapsed, as an in-between's defects are counted
        (:meth:`core.inbetween_defects.DefectChecks.defects`, without the interpolated rotations:
        the blend does not follow them). Where two poses differ by wrinkles alone
        (:meth:`_chattering`) the blend is their in-between unless it has any: averaging two
        wrinkle patterns can cross a fold's triangles over, which the fit does not
        (docs/inbetween-measurements.md, *Two poses that differ by wrinkles alone: a blend that
        turns triangles over*)."""
        gap = self._sequence._gap(0)
        return int(np.count_nonzero(gap.repair.defects(gap.linear_blend(factor), factor, None, None,
                                                       scale=gap.area_scale(factor))))

    def _squared_lengths(self, x: np.ndarray) -> np.ndarray:
        """The squared lengths of the mesh's corner edges (3m,) in positions ``x`` (n, 3)."""
        return np.sum((x[self._edges[:, 1]] - x[self._edges[:, 0]]) ** 2, axis=1)

    def _squared_target(self, factor: float, log: SequenceInterpolator | None = None) -> np.ndarray:
        """The squared corner edge lengths (3m,) of the interpolated metric at ``factor`` (squared
        lengths linear in it), or of the log-stretches' of the sequence ``log`` (:meth:`_log_sequence`),
        in the order of the corner edges of :meth:`_squared_lengths`; at least the smallest positive float."""
        if log is not None:  # the corner lengths (3 corners, m) in the order of self._edges
            lengths = log._gap(0).metric_lengths(factor).T.reshape(-1) / log._unit  # in the poses' units
            return np.maximum(lengths ** 2, np.finfo(float).tiny)
        return np.maximum((1.0 - factor) * self._squared[0] + factor * self._squared[1], np.finfo(float).tiny)

    def _misfit(self, x: np.ndarray, factor: float, log: SequenceInterpolator | None = None) -> float:
        """Mean relative deviation of the edge lengths of ``x`` (n, 3) from the interpolated metric's
        (squared lengths linear in ``factor``), or from the log-stretches' of the sequence ``log``
        (:meth:`_squared_target`); an edge shorter than the fits' floor is measured over the floor
        (:data:`~core.inbetween_fit.MISFIT_LENGTH_FLOOR`), as the fits measure it."""
        target = self._squared_target(factor, log)
        lengths = self._squared_lengths(x)
        deviations = np.abs(np.sqrt(lengths / target) - 1.0)
        target = np.sqrt(target)
        floored_deviations(deviations, np.sqrt(lengths), target, self._misfit_floor,
                           short_edges(target, self._misfit_floor))
        return float(np.mean(deviations))

    @single_threaded_blas()
    def pose(self, factor: float) -> np.ndarray:
        """0 → a, 1 → b (as given), 0.5 in-between, 1.5 exaggeration, negative: the motion reversed. An
        in-between of the full basis is fitted twice, with the rotations as residuals to each
        piece's rigid motion and taken whole, and the second kept where it keeps the metric better
        by :data:`WHOLE_FIT_MARGIN` without straying farther from the linear blend
        (:data:`WHOLE_FIT_BLEND_RATIO`), or where the first fell back to the blend (or the metric
        fitted near it) and the second has fewer flipped or collapsed triangles within
        :data:`WHOLE_FIT_HELD_REACH` of the blend (:data:`WHOLE_FIT_HELD_METRIC_REACH` where it is
        also nearer the interpolated metric by :data:`WHOLE_FIT_MARGIN`), or where it is no worse
        than the first on anything the keys tell (no more flipped or collapsed triangles, no
        farther from the metric) and nearer the blend by :data:`WHOLE_FIT_BLEND_RATIO`. Where the
        kept fit has triangles facing against their interpolated rotation and one pose, mostly
        where the poses face the same way, it is fitted again to the log-stretches' metric and that fit kept where
        it has fewer triangles against the field and no more flipped or collapsed ones
        (:data:`LOG_METRIC_FIT`). The warnings are the kept fit's. Poses that differ by wrinkles only
        (:meth:`_chattering`) give their linear blend where it has no triangle flipped or collapsed
        (:meth:`_blend_defects`), and are fitted where it has."""
        factor = check_factor(factor)
        if factor in (0.0, 1.0):  # the poses as given (the sequence holds vertices that barely move still)
            return self._given_poses[int(factor)].copy()
        names = self._sequence.key_names
        # a raw failure of a solver is a RecoveryError naming the pose (the sequence's own solves say theirs)
        with numerical_failures(f"The in-between at factor {factor:g} between {names[0]} and {names[1]}"):
            return self._pose(factor)

    def _pose(self, factor: float) -> np.ndarray:
        """:meth:`pose` at a checked ``factor`` other than 0 and 1."""
        first = self._sequence
        if not 0.0 < factor < 1.0 or first.k_M is not None or not first.use_extrinsic or first._hold(0):
            x = first.pose(0, factor)
            if not 0.0 <= factor <= 1.0:
                self._warn_grown(x, factor)
            return x
        # the blend, its edges held to the bound as a fit's (it averages the wrinkles away), where it
        # turns no triangle over: a fold the two wrinkle patterns cross, averaged, is fitted instead
        if self._chattering() and not self._blend_defects(factor):
            x = (1.0 - factor) * self._given_poses[0] + factor * self._given_poses[1]
            self._say(self._edges_off(x, factor, self._misfit(x, factor), None, blend=True), 0.0)
            return x
        (x,), said = first._poses(0, [factor])
        misfit, chosen = self._misfit(x, factor), first
        # a first fit within the margin of the metric cannot be bettered by it: no second fit
        if misfit > WHOLE_FIT_MARGIN and not first._gap(0).whole_rotations.all():
            second = self._whole_sequence()
            (y,), other = second._poses(0, [factor])
            blend = (1.0 - factor) * self._given_poses[0] + factor * self._given_poses[1]
            other_misfit = self._misfit(y, factor)
            away, first_away = _rms(y - blend), _rms(x - blend)  # each fit's distance from the blend
            nearer_metric = other_misfit < misfit - WHOLE_FIT_MARGIN and away <= WHOLE_FIT_BLEND_RATIO * first_away
            # a first fit held near the blend by a fallback has no distance from it to compare
            # with: there the second is kept where it has fewer flipped or collapsed triangles and
            # lies within WHOLE_FIT_HELD_REACH of the keys' distance from the blend, or within
            # WHOLE_FIT_HELD_METRIC_REACH where it is also nearer the interpolated metric
            held, kept = first._gap(0).outcomes.get(factor), second._gap(0).outcomes.get(factor)
            keys = _rms(self._given_poses[1] - self._given_poses[0])
            fewer_defects = held is not None and held.near_blend and kept is not None and \
                kept.defects < held.defects and (away <= WHOLE_FIT_HELD_REACH * keys or (
                    away <= WHOLE_FIT_HELD_METRIC_REACH * keys and other_misfit < misfit - WHOLE_FIT_MARGIN))
            # a second fit no worse than the first on anything the keys tell — no more flipped or
            # collapsed triangles, edges no farther from the metric — and nearer the blend by
            # WHOLE_FIT_BLEND_RATIO (the guard above, the other way round) is kept
            no_worse = held is not None and kept is not None and kept.defects <= held.defects and \
                other_misfit <= misfit and WHOLE_FIT_BLEND_RATIO * away <= first_away
            if nearer_metric or fewer_defects or no_worse:
                x, said, misfit, chosen = y, other, other_misfit, second
        x, said, misfit, log = self._log_fit(chosen, factor, x, said, misfit)
        self._say(said + self._spun_back(x, factor) + self._edges_off(x, factor, misfit, log), misfit)
        return x

    def _say(self, said: list, misfit: float) -> None:
        """Warn each ``(kind, message, defects, factors, excess)`` of ``said``, a fallback's (``pose``)
        with the pose's mean relative edge misfit ``misfit`` added where it is past
        :data:`FALLBACK_MISFIT_NOTED` (a crushed blend)."""
        names = self._sequence.key_names
        for kind, message, defects, about, *excess in said:
            warn_said(message if kind != "pose" or misfit <= FALLBACK_MISFIT_NOTED else
                      f"{message}; its edge lengths are {100 * misfit:.1f} % off the interpolated ones on average",
                      kind, defects, (names[0], names[1]), about, *excess)

    def _edges_off(self, x: np.ndarray, factor: float, misfit: float, log: SequenceInterpolator | None,
                   blend: bool = False) -> list[tuple[str, str, int, tuple[float, ...], float]]:
        """The ``fit`` warning ``(kind, message, defects, factors, excess)`` of the in-between ``x``
        (n, 3) at ``factor`` (``misfit``: its mean relative edge misfit to the metric it was fitted
        to, :meth:`_misfit`; of the log-stretches' where ``log`` is their sequence), else none. What is
        allowed is issue 17's edge bound with the poses standing in for the simulation: twice their
        mean edge deviation from the rest + 0.1 point, at least 0.3 %
        (:func:`core.sequence_edge_misfit.misfit_allowed`). ``blend``: ``x`` is the poses' linear blend,
        returned where they differ by wrinkles alone (:meth:`_chattering`), held to the same bound (the
        blend averages the two wrinkle patterns away, the sheet shrinks in its plane where the frames
        between have wrinkles of their own), and its message says so.

        With the caller's ``rest_pose`` the deviations are measured from it (each pose's,
        :func:`core.sequence_edge_misfit.key_deviation`) and so is the in-between's: warned where it is
        farther off the rest than allowed (excess: its deviation ÷ that), what the issue bounds, on
        the pose returned. On the benchmark's and audit bakes' pairs that warns 77 of the 122 over the
        bound and 22 of the 406 within it, where the fit's misfit held to the same allowance (the
        sequence's rule) warns 57 and 10: poses far off their rest (a curtain a ball stretched 5–10 %,
        relaxed between them) allow a misfit that hides an in-between 5 × past the bound
        (docs/inbetween-measurements.md, *Two poses' edge allowance from the rest pose given*).

        Without it two poses give no rest: warned where ``misfit`` is over twice the least deviation
        the two can have from any rest they share (:func:`core.sequence_edge_misfit.least_shared_deviation`,
        never more than from the true rest) + 0.1 point (excess: ``misfit`` ÷ that), the rule of a
        sequence's gap measured on the pose returned (their gap is anchored: its fits keep no misfit
        of their own), the same whichever pose comes first, and an edge crushed in one pose (a fold a
        collision presses) not read as a change of hundreds of percent (*Two poses' edge allowance
        from a rest they share*). The in-between's own deviation from that rest would not do: it is
        the rest nearest the poses, not the in-between.

        Either way a pair whose keys hide an impact (cloth landing just before the second) is mostly
        silent: the two poses do not tell a stretch that came in a frame from one that grew across
        the gap (docs/limits.md). Not said where the fit is within its accuracy
        (:data:`~core.sequence_edge_misfit.MISFIT_NOTED_FLOOR`: following the interpolated lengths, the
        in-between is within twice the poses' deviation) or where the poses' pieces are mirrored, as of
        a sequence's gap (:func:`core.sequence_mirrors.warn_mirrored` says why their edges are off)."""
        if misfit <= MISFIT_NOTED_FLOOR or 0 in self._sequence._mirrored_gaps:  # within the fits' accuracy; mirrored
            return []
        rest = self._rest_lengths
        if self._apart is None:
            lengths = [np.sqrt(squared) for squared in self._squared]
            self._apart = ([key_deviation(pose, rest) for pose in lengths] if rest is not None else
                           [least_shared_deviation(*lengths, self._misfit_floor)] * 2)
        names, allowed = self._sequence.key_names, misfit_allowed(self._apart)
        advice = (f"add a pose between {names[0]} and {names[1]} and in-between each half (or interpolate the three "
                  "as a sequence)")
        made = BLEND_MADE if blend else "its fit"
        if rest is not None:
            deviation = key_deviation(np.sqrt(self._squared_lengths(x)), rest)
            if deviation <= allowed:
                return []
            return [("fit", f"between {names[0]} and {names[1]}, the in-between at factor {factor:g}: its edges are "
                     f"{100 * deviation:.1f} % off the rest pose's on average, {deviation / allowed:.1f} × what the "
                     f"poses' own deviation from it allows (twice their {50 * sum(self._apart):.1f} % + "
                     f"{100 * MISFIT_NOTED_MARGIN:.1f} point, at least {100 * MISFIT_NOTED_FLOOR:.1f} %; {made} "
                     f"ends {100 * misfit:.1f} % off the edge lengths interpolated between them); {advice}", 0,
                     (factor,), deviation / allowed)]

        def signed(s):
            return signed_deviation(np.sqrt(self._squared_lengths(x)), np.sqrt(self._squared_target(s, log)))

        # the rest named as what it is, not "a rest the poses share" (the first pose is often the
        # mesh's Basis, which an artist takes for the rest, and it is not what is measured from)
        said = misfit_warning({factor: misfit}, [factor], allowed, names, signed,
                              f"the rest nearest both {names[0]} and {names[1]} (each edge at the longer of its "
                              "two lengths: the least that deviation can be)", advice=advice,
                              made=made, cause=BLEND_CAUSE if blend else None)
        return [] if said is None else [("fit", said[0], 0, said[1], said[2])]

    def _spun_back(self, x: np.ndarray, factor: float) -> list[tuple[str, str, int, tuple[float, ...], float]]:
        """The warning ``(kind, message, defects, factors, excess)`` (excess: the share ÷
        :data:`~core.sequence_turn_readings.TURNED_PART_SHARE`) where the in-between ``x`` (n, 3) at ``factor``
        turns back the short way round over :data:`~core.sequence_turn_readings.TURNED_PART_SHARE`
        of a piece that spins on past a half turn from the rest of it between the poses
        (:func:`core.spun_parts.turned_back`), in a piece whose triangles' turns are left with a jump
        past a half turn between neighbours, else none. The poses' triangles' turns are taken
        continuous across the mesh, which carries such a part the way it went where neighbouring
        triangles turn alike (a twisted tube); a wrung cloth's wrinkles part them everywhere and
        the part goes the short way round (a twirled 40k skirt, poses 16 frames apart, its hem
        spun 219° on from its waist: 1.136 × the blend's error, 95 % of it over 90° off)."""
        sequence = self._sequence
        rotations, translations, _ = sequence._fits(0, 1)
        topo = sequence._topo
        if sequence._welded_vertices is not None:  # the caller's vertices back to the solved ones
            x = x[sequence._welded_vertices]
        share, spun = turned_back(sequence._raw[0], sequence._raw[1], sequence._to_working(x), factor, topo.weights,
                                  topo.vertex_owner, sequence._key_patches(), rotations, translations,
                                  sequence._key_turns(0))
        share[~self._jumping_pieces(len(share))] = 0.0
        worst = int(np.argmax(share))
        if share[worst] <= TURNED_PART_SHARE:
            return []
        names = sequence.key_names
        return [("turn", f"between {names[0]} and {names[1]}, at factor {factor:g}, {100 * share[worst]:.0f} % of a "
                 f"piece's area spins on more than a half turn (up to {np.degrees(spun[worst]):.0f}°) from the rest "
                 "of it, and the in-between turns it back the short way round, against the rest (a pose between "
                 "the two, interpolated with them as a sequence, tells which way it went; read from patches of "
                 "the mesh turning about the piece's rigid turn axis)", 0, (factor,),
                 float(share[worst]) / TURNED_PART_SHARE)]

    def _jumping_pieces(self, pieces: int) -> np.ndarray:
        """Per piece (bool (``pieces``,)), whether the poses' triangles' turns, taken continuous
        across the mesh, keep a jump past a half turn between neighbours in it (made once: the
        poses' alone). A piece with none carries a part spun on the way it went (a sheet rolled
        355° into a tube: its patches' centroids turn about the fit's axis unlike the roll, so
        their reading is no guide there): :meth:`_spun_back` leaves it out."""
        if self._jumping is None:
            sequence = self._sequence
            edges = sequence._edge_pairs
            jumping = jumping_pairs(sequence._gap(0).relatives[2].rotvec, edges)
            self._jumping = np.bincount(sequence._topo.triangle_component[edges[jumping, 0]], minlength=pieces) > 0
        return self._jumping

    def _log_fit(self, kept: SequenceInterpolator, factor: float, x: np.ndarray,
                 said: list[tuple[str, str, int, tuple[float, ...]]],
                 misfit: float) -> tuple[np.ndarray, list[tuple[str, str, int, tuple[float, ...]]], float,
                                         SequenceInterpolator | None]:
        """``(x, said, misfit, None)`` of the fit of ``kept`` (the first or the whole-rotation sequence)
        at ``factor``, or ``(x, said, misfit, log)`` of the same fit to the log-stretches' metric (of the
        sequence ``log``) where ``x`` has triangles
        facing against their interpolated rotation and one pose, at least half of them where the
        poses face the same way, and that fit has fewer facing against it and no more flipped or
        collapsed triangles (:data:`LOG_METRIC_FIT`)."""
        same_way, against = kept._gap(0).against.get(factor, (0, 0))
        # most of them turned over by the metric, not by a turn over between the poses (a fold)
        if not (LOG_METRIC_FIT and same_way and 2 * same_way >= against):
            return x, said, misfit, None
        log = self._log_sequence(kept is not self._sequence)
        (y,), other = log._poses(0, [factor])
        gap, first = log._gap(0), kept._gap(0)
        held, logged = first.outcomes.get(factor), gap.outcomes.get(factor)
        fewer = gap.against.get(factor, (0, 0))[1] < against and \
            (held is None or logged is None or logged.defects <= held.defects)
        return (y, other, self._misfit(y, factor, log), log) if fewer else (x, said, misfit, None)

    def _warn_grown(self, x: np.ndarray, factor: float) -> None:
        """Warn where an extrapolated pose ``x`` (n, 3) has edges over :data:`EXTRAPOLATED_GROWTH`
        times as long as in either pose, or under its inverse times as short. Those triangles are
        told apart by what makes them so: the extrapolated metric itself (its corner lengths beyond
        those bounds too: a triangle nearly collapsed or stretched in one pose), or the fit alone,
        whose extrapolated rotations and stretches do not fit together there (a shear, a swirl) and
        which stretches or crushes the triangles to close them. An edge shorter than the fits' floor
        in the poses (:data:`~core.inbetween_fit.MISFIT_LENGTH_FLOOR`: near-duplicate vertices) grows
        from the floor and shrinks unsaid: no fit places its ends that finely. The warning's
        ``excess``: the most an edge grew or shrank ÷ :data:`EXTRAPOLATED_GROWTH`."""
        lengths = self._squared_lengths(x)
        # an edge far under the mesh's own (near-duplicate vertices) grows from the floor: no fit places it
        floor = self._misfit_floor ** 2
        longest, shortest = np.maximum(np.maximum(*self._squared), floor), np.minimum(*self._squared)
        grown = lengths > EXTRAPOLATED_GROWTH ** 2 * longest
        shrunk = (lengths * EXTRAPOLATED_GROWTH ** 2 < shortest) & (shortest >= floor)
        if not (grown.any() or shrunk.any()):
            return
        tiny = np.finfo(float).tiny
        growth = np.where(grown, lengths / np.maximum(longest, tiny), 0.0).reshape(-1, 3).max(axis=1)
        shrinking = np.where(shrunk, shortest / np.maximum(lengths, tiny), 0.0).reshape(-1, 3).max(axis=1)
        sequence = self._sequence
        metric = sequence._gap(0).metric_lengths(factor)  # (3 corners, m), the keys' corner order
        first, second = sequence._key(0).lengths.T, sequence._key(1).lengths.T
        by_metric = ((metric > EXTRAPOLATED_GROWTH * np.maximum(first, second)) |
                     (metric * EXTRAPOLATED_GROWTH < np.minimum(first, second))).any(axis=0)
        flagged = (growth > 0) | (shrinking > 0)
        caller = sequence._topo.caller_triangles
        if caller is not None:  # the solved triangles' (by_metric) among the caller's; those near-duplicates drop are placed, not fitted
            solved, by_metric, fitted = by_metric, np.zeros(len(flagged), dtype=bool), np.zeros(len(flagged), dtype=bool)
            by_metric[caller], fitted[caller] = solved, True
            flagged &= fitted
        names = sequence.key_names
        for rows, cause in ((np.flatnonzero(flagged & by_metric),
                             "exaggerating (or reversing) raises each triangle's stretch between the poses to the "
                             "factor's power, so a triangle nearly collapsed (or stretched) in one pose swells (or "
                             "shrinks) the other way; use a factor nearer the poses, or give those triangles their "
                             "size in the poses (the extrapolated metric)"),
                            (np.flatnonzero(flagged & ~by_metric),
                             "the exaggerated (or reversed) turns and stretches of the triangles do not fit together "
                             "there (a shear or a swirl the pose cannot follow), and the mesh is stretched or crushed "
                             "to stay closed; use a factor nearer the poses (the extrapolated metric keeps them "
                             f"within {EXTRAPOLATED_GROWTH:g} ×, the fit does not)")):
            if not rows.size:
                continue
            longer = growth[rows].max() >= shrinking[rows].max()
            ratio = np.sqrt(max(growth[rows].max(), shrinking[rows].max()))
            warn_said(f"between {names[0]} and {names[1]}, at factor {factor:g}, {rows.size} triangle(s) (e.g. triangle "
                  f"{int(rows[0])}) have edges {ratio:.3g} × as {'long' if longer else 'short'} as in either pose: "
                  f"{cause}", "extrapolation", gap=(names[0], names[1]), factors=(factor,),
                  excess=ratio / EXTRAPOLATED_GROWTH)


#: Two poses whose triangles' turns are no more alike between neighbours than this times the
#: turns themselves (RMS ratio; 1: neighbours' turns correlate by at most a half) are wrinkles that
#: change between the keys (:meth:`Interpolator._chattering`): a sewn garment lying on the floor,
#: keys 4–16 frames apart, its triangles turning 11–25° with the neighbours' turns differing
#: 1.00–1.11 × that, had in-betweens 1.00–1.08 × the blend's RMS error (its simulated middle
#: frames 6 × farther from the keys' half turns than the fitted pose); the tablecloth settling on
#: its table, keys 4 apart from frames 20 and 22, 1.014 / 1.050 × at a ratio of 1.002 / 1.001, where
#: its later pairs, at 0.92–0.996, keep their fits (0.85–1.035 ×). The soft flags' first pairs (1.08–1.13)
#: lose their fits' gain there (one pair 0.959 → 1.000 ×; *Two poses whose keys differ by wrinkles only*).
CHATTER_COHERENCE = 1.0


#: A two-pose in-between's warnings add how far its edges are from the interpolated metric where
#: that is over this (mean relative deviation): a sheet flipping over a rod, two poses 16 frames
#: apart, fell back to the metric fitted near the blend, 14–23 % off (the simulation's own 0.3–0.9
#: %), and the warning said only "used the interpolated metric fitted near the linear blend".
FALLBACK_MISFIT_NOTED = 0.02


#: What a two-pose edge warning calls the pose it measures where the poses differ by wrinkles alone
#: (:meth:`Interpolator._chattering`), and why its edges are off: the blend, not a fit.
BLEND_MADE = "it is the poses' linear blend (they differ by wrinkles alone), which"
BLEND_CAUSE = "the blend averages the two poses' wrinkles away, and the sheet shrinks in its plane"

#: An extrapolated pose warns where an edge comes out over this many times as long (or its inverse
#: as short) as in either pose: a sheet drawn out 3 × in one pose comes out 2.92 × as long at ×2;
#: ×2 of a 100° bend stays within 1.1. (A sliver under the fits' floor keeps its key's stretch
#: beyond the keys, :data:`core.inbetween_field.HELD_BEYOND_KEYS`, and does not swell.)
EXTRAPOLATED_GROWTH = 2.0


#: Two poses: an in-between is fitted again with every triangle's whole rotation (not its residual
#: to its piece's rigid motion) and that fit kept where its edge lengths are nearer the
#: interpolated metric by more than this (mean relative deviation): cloth whipping or crumpling
#: between the keys, whose residuals the fit cannot follow (a sheet swung ±60° on a hook: the
#: whole sheet turns 50–110°, its triangles' residuals 60–100°; the fit turned the free edge 15–19°
#: where the field says 44–57°). Pairs of frames g apart (stride 4), RMS ÷ the blend's: curtain
#: g = 16 1.128 → 0.891 (edge deviation 7.97 → 5.30 %, flipped 745 → 301), balloon g = 16 0.993 →
#: 0.952, two sheets g = 16 0.831 → 0.787, the hooked sheet 1.100 / 1.206 → 1.028 / 1.146 at g = 8 /
#: 16; worse: lifted sheet g = 16 0.934 → 0.962 (one of its 9 pairs); nine other cloths within
#: ±0.001. Rigid motions, half turns and bends keep the first fit (their misfits are equal).
WHOLE_FIT_MARGIN = 0.005
#: ... and where it is no farther from the linear blend than this many times the first fit: a fit
#: nearer the metric is not always nearer the motion (a flag at g = 16, frames 24 → 40: misfit 6.1 →
#: 0.4 %, but 1.085 → 1.435 × the blend's error, 0.80 → 1.06 of it away from the blend; a sheet on a
#: swinging hook whose first fit fell back to the blend: 1.00 → 1.20 ×).
#: The other way round, a second fit nearer the blend by this ratio is kept where it is no worse on
#: anything the keys tell (no more flipped or collapsed triangles, edges no farther from the
#: metric), however little nearer the metric: a 12k cloth dragged across a table by a hooked
#: corner, keys 16 frames apart, had first fits 0.118 / 0.266 of the keys' distance from the blend
#: (0 / 250 flipped) where the second's were 0.079 / 0.113 (0 / 144) and 0.0013 / 0.0031 nearer the
#: metric, and 1.167 / 1.982 × the blend's error where the second's are 0.882 / 1.012 ×. Where the
#: two are about as far from the blend (a 1k flag, g = 16: 0.141 and 0.140, a second fit 1.09 × the
#: first's error) the first stays. A first fit held near the blend by a fallback gives no distance
#: to compare with: there the fit with fewer flipped or collapsed triangles is kept (a flag draped
#: over a sphere, g = 16: 2,829 → 104 flipped, 1.000 → 1.054 × the blend's error; a tablecloth
#: pulled off a table, g = 8: 144 → 0, 1.000 → 0.886 ×) ...
WHOLE_FIT_BLEND_RATIO = 1.25
#: ... where it lies within this share of the keys' RMS distance from each other from the blend: a
#: sheet whipped by a keyframed corner, keys 8 frames apart, had second fits 0.23–0.24 of it away
#: with 25 and 7 flipped triangles where the first's fallbacks had 550 and 849, and 2.07 / 1.61 ×
#: the blend's error (the cell's median 0.961 → 1.074 ×); those kept, 0.01–0.13 of it away (0.08
#: on the flag, 0.12 on the banner), are 0.85–1.05 × (one at 0.20, 0.98 → 0.79 ×, is left out).
WHOLE_FIT_HELD_REACH = 0.15
#: ... or within this share where its edge lengths are also nearer the interpolated metric than
#: the held fit's by :data:`WHOLE_FIT_MARGIN`: a stiff (denim) flag swinging round its pole,
#: keys 16 frames apart, had first fits held near the blend with 192–454 flipped triangles (1,391
#: over the cell, 0.995–0.997 × the blend's error) whose second fits, 0.151–0.178 of the keys'
#: distance away, had 0–9 flipped, 5–7 % off the metric where the held fits were 8–10 %, and
#: 0.63–0.98 × the blend's error; a second fit 0.163 away that was farther from the metric (4.3
#: → 5.0 %) was 1.001 → 1.093 × and is left out (an unseen bake of a denim flag, g = 16). The
#: whipped sheet's pairs that lost at 0.23–0.24 stay out.
WHOLE_FIT_HELD_METRIC_REACH = 0.2


#: Two poses: where an in-between has triangles facing against their interpolated rotation and
#: one pose, at least half of them where the poses face the same way (the fit turned them over to
#: close the interpolated metric, not a fold turning them over between the poses:
#: :meth:`core.inbetween_defects.DefectChecks.against_the_field`), it is fitted again to the
#: metric of the log-stretches ``exp(s log U)`` and that fit kept where it has fewer triangles
#: against the field (of either kind) and no more flipped or collapsed ones. A skin whose weights
#: ramp between a part held still and one that turns (a head nodding on a still neck) stretches
#: its ramp as ``F(s) = R(s w θ)(I + s θ (k × p) ∇wᵀ)``, whose metric is quadratic in ``s``: at
#: 0.25–0.75 the metric linear in squared lengths gives the ramp's triangles 1.07–1.40 × the rig's
#: area (median), the log-stretches' 1.00–1.03 ×, and the fit crushed some of the swollen ones
#: over (scanned head, 60–140°: 155 → 95 triangles facing away from the rig). Only as a further
#: fit: everywhere, it costs cloth pairs edge length (a collapsing fold's edges shorten early:
#: tablecloth g = 16 3.56 → 3.81 %); as here it is kept on 2 of 640 benchmark pairs
#: (docs/design-decisions.md, *Two poses: the log-stretches' metric where the fit turns
#: triangles over*). False: never tried.
LOG_METRIC_FIT = True


def _rms(d: np.ndarray) -> float:
    """RMS over the rows of ``d`` (n, 3) of their lengths."""
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1))))


def interpolate(vertices_a, vertices_b, triangles, factor: float, *, k_M: int | None = None,
                k_N: int | None = None, offset: float | None = None, use_extrinsic: bool = True,
                rest_pose=None) -> np.ndarray:
    """One pose at ``factor`` between ``vertices_a`` (0) and ``vertices_b`` (1); see :class:`Interpolator`."""
    factor = check_factor(factor)
    return Interpolator(vertices_a, vertices_b, triangles, k_M=k_M, k_N=k_N, offset=offset,
                        use_extrinsic=use_extrinsic, rest_pose=rest_pose).pose(factor)
