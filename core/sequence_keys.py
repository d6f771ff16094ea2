"""The key poses of a :class:`~core.sequence_inbetweens.SequenceInterpolator`, prepared once and per key
(paper §8.4; the stretch and rotation of §4.2 and §5.3 between two keys).

:class:`SequenceKeys` (a mixin of the interpolator): ``_setup`` takes the checked keys (K arrays
``(n, 3)``) and the topology of the triangles ``(m, 3)``: pieces sewn along seams are welded
(:mod:`core.seam_welds`), still and riding vertices found (:mod:`core.pins`), the keys moved about the
middle of the first; ``_key`` keeps the per-key data (:class:`core.inbetween_keys.Key`) of the
last :data:`KEY_CACHE` keys; ``_relative`` / ``_relatives`` / ``_previous`` give one key seen from
another (:class:`core.inbetween_keys.Relative`), with the truncated recovery's metric
(§7.1–7.2) where ``k_M`` is set."""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import replace

import numpy as np

from .errors import MeshError, RecoveryError
from .concurrency import concurrently
from .inbetween_threads import CONCURRENT_VERTICES
from .inbetween_keys import Key, Relative, log_stretch_from_lengths
from .inbetween_rigid_fits import rigid_fits
from .inbetween_solver import Gap
from .inbetween_topology import Topology
from .laplace_basis import basis_sizes
from .mesh_topology import check_manifold_vertices
from .pins import moving_edges, riding_tolerance, riding_vertices, still_vertices, witnessed_riding
from .coordinate_rounding import coordinate_rounding, decimal_rounding, rounding_scale
from .loose_vertices import attached_loose
from .seam_welds import coincidence_tolerance, seam_weld
from .near_duplicates import near_duplicates
from .near_seams import near_seams
from .vertex_locality import local_order, renumbered
from .sequence_mirrors import warn_mirrored
from .sequence_warnings import warn_said
from .working_unit import working_unit

#: Gaps whose prepared data (splines, relatives) SequenceInterpolator keeps: a gap's previous-key
#: relative comes from the gap before it, so two serve in-order visits (each holds ~70 MB at 100k
#: vertices).
GAP_CACHE = 2

#: Keys whose per-key data SequenceInterpolator keeps: preparing gap k reads keys k − 1 … k + 2,
#: and the gap before it k − 2 … k + 1, so five serve in-order visits with no key built twice
#: (with four, key k − 1 was rebuilt for every gap: 0.05 s at 100k vertices); ~50 MB each at
#: 100k vertices.
KEY_CACHE = 5


#: Pairs of keys whose rigid fits (:func:`core.inbetween_rigid_fits.rigid_fits`) SequenceInterpolator
#: keeps: a gap's relatives fit its key to the next two, and the gaps around it fit those pairs
#: again where they start or end in free flight or at an impact (their non-rigidity: ``_entry``,
#: ``_exit``). Each gap adds up to five pairs, the gap after reads them, and the one after that may
#: be prepared meanwhile: sixteen serve in-order visits (13 floats per piece each).
FIT_CACHE = 16


def _with_rows(x: np.ndarray, rows: np.ndarray, source: np.ndarray) -> np.ndarray:
    """A copy of ``x`` (n, 3) with ``rows`` (bool (n,)) taken from ``source`` (n, 3)."""
    out = x.copy()
    out[rows] = source[rows]
    return out


class SequenceKeys:
    """The keys of a sequence as prepared once (seams, pins, origin), the per-key data of the last
    few keys, and keys seen from each other (relatives); mixed into
    :class:`~core.sequence_inbetweens.SequenceInterpolator`."""

    def _setup(self, key_poses, topology, k_M, k_N, offset, use_extrinsic, smooth, start="rest", key_times=None,
               two_poses=False, end="keys", key_names=None):
        """The constructor once its arguments are checked (``topology``: that of the triangles;
        ``two_poses``: for an :class:`~core.two_pose_inbetweens.Interpolator`)."""
        self.start, self.end = start, end
        self._key_times = key_times
        # the keys as messages name them (the caller's names: the operators name frames or shape keys)
        self.key_names = [f"key pose {i}" for i in range(len(key_poses))] if key_names is None else \
            [str(name) for name in key_names]
        # each gap's duration (K − 1,); evenly spaced keys: all 1
        self._durations = np.ones(len(key_poses) - 1) if key_times is None else np.diff(key_times)
        keys = [np.asarray(k) for k in key_poses]
        if len(keys) < 2:
            raise MeshError(f"A sequence needs at least two key poses; got {len(keys)}.")
        self._triangles, self._copies = topology.triangles, None
        # at one place (seams, still vertices, holds): within this distance in every key
        rounding = rounding_scale(keys)
        # the keys' rounding (single precision where every coordinate is a float32), read before the
        # keys are moved: slivers within two of it are reshaped by it (core.rounded_slivers)
        self._rounding = coordinate_rounding(keys)
        # the grid they were stored on where coarser (keys exported to a few decimals): the rigid parts
        # of a piece are read to it (core.sequence_bent_parts.rounded_tolerance)
        self._decimal_rounding = decimal_rounding(keys, topology.edges, self._rounding)
        tolerance = coincidence_tolerance(keys[0], topology.edges, rounding)
        apart = None  # why the seams cannot be joined
        try:  # pieces that touch along seams are interpolated as one, loose copies with their vertex (core.seam_welds)
            weld = seam_weld(keys, topology, tolerance, orient=True)
        except MeshError as error:
            weld, apart = None, error
        if weld is None:
            check_manifold_vertices(topology)  # bow-tie vertices the seams do not join: refused in the caller's indices
        if apart is not None:
            weld = seam_weld(keys, topology, tolerance, seams=False)  # the loose copies alone
            warn_said(f"some pieces touch along seams but cannot be joined there ({apart}): they are "
                  "interpolated apart and the seams may open in the in-betweens; where they should stay closed, "
                  "make the pieces' windings agree (Mesh > Normals > Recalculate Outside) and weld them "
                  "(Mesh > Clean Up > Merge by Distance)", "seam")
        if weld is not None:
            keys, topology, self._copies = [k[weld.kept] for k in keys], weld.topology, weld.copies
        still = still_vertices(keys, tolerance)
        # vertices far closer than the fits resolve in every key are solved as one (core.near_duplicates)
        self._near = near_duplicates(keys, topology)
        kept = None if weld is None else weld.kept  # the caller's index of each vertex solved
        if self._near is not None:
            if still[self._near.members].any():  # those stay where the first key has them, as the others
                self._near = replace(self._near, still=still[self._near.members])
            keys, topology, still = [k[self._near.kept] for k in keys], self._near.topology, still[self._near.kept]
            kept = self._near.kept if kept is None else kept[self._near.kept]
        # a vertex order that scatters neighbours over the mesh (a scan's, an exporter's) is solved in
        # one that keeps them together (core.vertex_locality); the poses are given back in the caller's
        # (_unordered: the solved index of each vertex before renumbering, or None)
        self._unordered = None
        # the caller's index of each solved triangle where it differs (Topology.caller_triangles):
        # near-duplicates drop the triangles with two corners in one cluster, the renumbering sorts them
        caller_triangles = None if self._near is None or self._near.whole.all() else np.flatnonzero(self._near.whole)
        order = local_order(topology)
        if order is not None:
            topology, triangle_order = renumbered(topology, order)
            caller_triangles = triangle_order if caller_triangles is None else caller_triangles[triangle_order]
            keys, still = [k[order] for k in keys], still[order]
            self._unordered = np.argsort(order)
            kept = order if kept is None else kept[order]
        # loose vertices near the surface follow a triangle there, not their piece's rigid motion
        self._attached = attached_loose(keys, topology, still)
        if still.any():  # set where they sit in the first key (copies: the caller's arrays stay)
            keys = [k if np.array_equal(k[still], keys[0][still]) else _with_rows(k, still, keys[0]) for k in keys]
        # pieces both keys of a gap keep together along a seam farther apart than the weld joins (left
        # unwelded, or sewn by the motion): each gap's solves keep them as its keys have them
        # (core.sewn_seams), and the in-betweens say where they still open (core.near_seams)
        self._near_seams = near_seams(keys, topology, tolerance)
        self._welded_vertices = kept
        # interpolated about the middle of the first key, the results moved back: the splines of the
        # pieces' screw motions limit their tangents per coordinate, which a translation changes
        # (a sheet keyed 1e3 units out: 0.1 of its size off in two of four gaps)
        self._given, self._still = keys, still
        self._gap_messages: dict[int, list] = {}  # per gap, its warnings (SequenceInterpolator._gap_warnings)
        # the corner edge lengths (m, 3) the edge warnings measure deviations from: the rest pose's where the caller
        # gives it, else the first key's; once asked (SequenceInterpolator._key_deviation)
        self._rest_lengths = None
        self._key_deviations: dict[int, float] = {}  # ... and each key's mean relative edge deviation from them
        self._caught_stretches: dict[int, str | None] = {}  # per key, how it catches a brief stretch, if it does (core.sequence_caught_stretch)
        # per gap, least turn and tolerance, per piece (SequenceInterpolator._bent_turn)
        self._bent_turns: dict[tuple[int, float, float], np.ndarray] = {}
        self._hold_tolerance, self._holds = tolerance, {}
        origin = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0)) if keys[0].size else np.zeros(3)
        self._origin = origin if origin.any() else None
        if self._origin is not None:
            keys = [k - origin for k in keys]
        # sized near 1 where far larger or smaller (core.working_unit.WORKING_EXTENT); the results scaled back
        self._unit = working_unit(keys)
        if self._unit != 1.0:  # in place where the keys are copies of this object's own already (moved above)
            keys = [np.multiply(k, self._unit, out=k) if self._origin is not None else k * self._unit for k in keys]
        self._raw = keys
        self._topo = Topology(topology, keys[0])
        self._topo.caller_triangles = caller_triangles
        # the gaps warned of mirrored pieces: said there once (their edges' misfit, core.sequence_edge_misfit,
        # and their rotations, which read no bend, core.sequence_bent_parts, are not said again)
        self._mirrored_gaps = warn_mirrored(self._topo, self._raw, self.key_names, kept)
        # the pairs of triangles sharing an edge (E, 2): two poses take the triangles' rotations
        # continuous across them (Relative); a sequence reads there which parts turn past a half
        # turn per gap (Relative.turning) and takes those parts' turns continuous across them
        self._edge_pairs = topology.edge_triangles[topology.interior_edges]
        self._across = self._edge_pairs if two_poses else None
        self._topo.pinned = np.flatnonzero(still) if still.any() else None
        # pins (core.pins): still vertices stay put, riding sets follow the spline of their rigid
        # motion (found in the keys as given: their float32 rounding is that of the given coordinates);
        # two keys tell only sets that translate, and those are not held: the blend anchor holds
        # them, and an in-between says where they end far off it (core.inbetween_solver.HOOK_MISS_NOTED);
        # but sets moved by the same rigid motion as a whole rigid piece are held (witnessed_riding)
        lengths = moving_edges(self._given[0], topology.edges, still)  # read by both
        self._riding_tolerance = riding_tolerance(self._given, topology.edges, still, rounding, lengths)
        moving = riding_vertices(self._given, topology.edges, self._topo.vertex_component, still, rounding,
                                 self._riding_tolerance, lengths) or None if len(keys) >= 3 or two_poses else None
        self._riding = moving if len(keys) >= 3 else None
        self._hooked = moving if two_poses else None
        if two_poses:
            self._riding = witnessed_riding(self._given, topology.edges, self._topo.vertex_component, still,
                                            self._riding_tolerance) or None
            if self._riding is not None and self._hooked is not None:  # held: no longer only noted
                held = np.zeros(len(still), dtype=bool)
                held[np.concatenate(self._riding)] = True
                self._hooked = [rows for rows in self._hooked if not held[rows].any()] or None
        if self._riding is not None:
            still = still.copy()
            still[np.concatenate(self._riding)] = True
        self._static = still if still.any() else None
        # the components' centroids in every key (K, C, 3): how steadily each piece moves
        self._centroids = np.array([self._topo.centroids(k) for k in keys])
        self._keys: OrderedDict[int, Key] = OrderedDict()
        self._fitted: OrderedDict[tuple, tuple] = OrderedDict()  # (base, other) → rigid fits (see _fits)
        self._corrections: OrderedDict[int, np.ndarray] = OrderedDict()  # key → its tangent correction (_tangent_correction)
        self._gaps: OrderedDict[int, Gap] = OrderedDict()
        # base key → its next key seen from it as the base's gap made it (_relatives): the gap after
        # reads it inverted (_previous), also where the gap's own were taken whole or let go
        self._forwards: OrderedDict[int, Relative] = OrderedDict()
        self._pending: dict = {}  # gap index → Future of its preparation in the background
        # which way round each gap reads its parts' turns (_reading: the last few), which pieces turn
        # far per gap, whether the readings of two gaps add up (per first gap) and are unsure (per gap)
        self._readings: OrderedDict[tuple, tuple] = OrderedDict()
        self._turnings: dict = {}
        self._agreements: dict = {}
        self._unsures: dict = {}
        self._cache_lock = threading.RLock()  # the caches are also filled by that preparation
        self._references: dict = {}
        self.k_M, self.k_N = basis_sizes(k_M, k_N)
        self.offset = offset
        self.use_extrinsic = bool(use_extrinsic)
        self.smooth = bool(smooth)
        self._anchored = False  # two-pose interpolation (Interpolator) anchors to the blend

    def _to_working(self, x: np.ndarray) -> np.ndarray:
        """Positions ``x`` (n, 3) in the caller's place and units as the working keys have them
        (moved about the first key's middle, scaled by :func:`working_unit`)."""
        x = x if self._origin is None else x - self._origin
        return x if self._unit == 1.0 else x * self._unit

    def _from_working(self, x: np.ndarray) -> np.ndarray:
        """Positions ``x`` (n, 3) of the working keys back in the caller's place and units."""
        x = x if self._unit == 1.0 else x * (1.0 / self._unit)
        return x if self._origin is None else x + self._origin

    def _caller_poses(self, out: np.ndarray, gap: int, factors: list[float]) -> np.ndarray:
        """Poses ``out`` (len(factors), n_solved, 3) of gap ``gap`` at ``factors`` for every vertex of
        the caller's mesh: in the caller's order where it was renumbered (:mod:`core.vertex_locality`),
        near-duplicate vertices placed about the one solved
        (:meth:`core.near_duplicates.NearDuplicates.place`), seams' copies at their welded vertex."""
        if self._unordered is not None:  # the solved vertices back in the order of the near-duplicates' and seams'
            out = out[:, self._unordered]
        if self._near is not None:
            given = (self._given[gap], self._given[gap + 1])
            if self._unordered is not None:
                given = tuple(k[self._unordered] for k in given)
            out = self._near.place(out, given, gap, factors)
        return out if self._copies is None else out[:, self._copies]

    def __len__(self) -> int:
        return len(self._raw) - 1

    @property
    def triangles(self) -> np.ndarray:
        return self._triangles

    def _cached(self, cache, name, limit: int, make):
        """``cache[name]`` (an OrderedDict), made by ``make()`` where it is not there, the last
        ``limit`` used kept (made outside the lock: two threads may make one at once, the last stored)."""
        with self._cache_lock:
            known = cache.get(name)
            if known is not None:
                cache.move_to_end(name)
                return known
        value = make()
        with self._cache_lock:
            cache[name] = value
            while len(cache) > limit:
                cache.popitem(last=False)
        return value

    def _key(self, index: int) -> Key:
        return self._cached(self._keys, index, KEY_CACHE, lambda: Key(self._topo, self._raw[index]))

    def _fits(self, base: int, other: int) -> tuple:
        """:func:`~core.inbetween_rigid_fits.rigid_fits` of key ``other`` from key ``base`` (rotations
        (C, 3, 3), translations (C, 3), misfits (C,); read-only: the relatives and the
        non-rigidity share them), kept for the last :data:`FIT_CACHE` pairs."""
        def fitted():
            fits = rigid_fits(self._topo, self._raw[base], self._raw[other])
            for value in fits:
                value.flags.writeable = False
            return fits

        return self._cached(self._fitted, (base, other), FIT_CACHE, fitted)

    def _reference(self, index: int):
        """The truncated recovery's prepared base for key ``index`` (eigenbasis, Gram factor).
        Only the intrinsic metric is recovered (rotations come from the poses): no offset surface."""
        if index not in self._references:
            from .reference_shape import ReferenceShape

            self._references.clear()  # one base at a time: gaps are visited per base key
            offset = None if self.offset is None else self.offset * self._unit  # in the keys' working size
            self._references[index] = ReferenceShape(self._raw[index], self._topo.triangles, offset=offset,
                                                      use_extrinsic=False, unit=1.0)  # keys already scaled
        return self._references[index]

    def _warn_truncated(self, base: int, other: int, why: str) -> None:
        """Warn that the stretch from key ``base`` toward key ``other`` is the keys' own, not the
        one the truncated basis recovers (``why``: what failed)."""
        warn_said(f"between {self.key_names[base]} and {self.key_names[other]}, the edge lengths could not be "
              f"recovered from the first {self.k_M} basis functions (k_M = {self.k_M}, k_N = {self.k_N}): the "
              "in-betweens there follow the keys' exact edge lengths instead, as with the full basis, and may look "
              "sharper than the other gaps; a larger k_M, or 0 for the full basis everywhere, keeps the gaps alike "
              f"({why}; truncated recovery failed)", "truncated", gap=(self.key_names[base], self.key_names[other]))

    def _truncated_log_stretch(self, base: int, other: int) -> np.ndarray | None:
        """Log-stretches (m, 3) toward key ``other`` whose edge lengths are those recovered from the
        truncated intrinsic differences; None (with a warning) when the recovery fails."""
        reference = self._reference(base)
        try:
            metric = reference.recover_metric(reference.shape_differences(self._raw[other], k_M=self.k_M, k_N=self.k_N))
        except RecoveryError as error:
            self._warn_truncated(base, other, f"the recovery failed: {error}")
            return None
        squared = np.asarray(metric.base.squared_lengths, dtype=np.float64)
        if not (np.isfinite(squared).all() and (squared > 0).all()):
            self._warn_truncated(base, other, "the recovery gave edges of no length")
            return None
        # corner edge c (corner c → c+1) is opposite corner c+2
        corner_squared = squared[reference.topology.triangle_edges[:, [2, 0, 1]]]
        return log_stretch_from_lengths(self._key(base), corner_squared)

    def _relative(self, base: int, other: int, turn: np.ndarray | None = None) -> Relative:
        log_stretch = self._truncated_log_stretch(base, other) if self.k_M is not None else None
        relative = Relative(self._topo, self._key(base), self._key(other), log_stretch, turn, self._across,
                             self._fits(base, other))
        return self._turning_on(base, relative) if turn is None and other == base + 1 else relative

    def _relatives(self, base: int, others: list[int]) -> list[Relative]:
        """``self._relative(base, k)`` for each of ``others``, in threads on large meshes (keys
        built first: the key cache is not shared with the threads) unless a truncated recovery,
        which prepares one base shape for them all, makes the metric. The relative of key
        ``base + 1`` is kept for the gap after (:meth:`_previous`) and for a later call that asks
        for it again (a neighbouring gap's reading of bent parts, :meth:`_bent_turn`, before this
        gap is prepared): it depends on the keys alone and is not changed in place after."""
        if self.k_M is not None:
            return [self._relative(base, k) for k in others]
        with self._cache_lock:
            kept = self._forwards.get(base) if others[0] == base + 1 else None
        rest = others[1:] if kept is not None else others
        topo, key = self._topo, self._key(base)
        keys = [self._key(k) for k in rest]
        relatives = concurrently(lambda pair: Relative(topo, key, pair[1], across=self._across,
                                                        fits=self._fits(base, pair[0])),
                                 zip(rest, keys), worth_it=topo.n >= CONCURRENT_VERTICES)
        relatives = [self._turning_on(base, r) if k == base + 1 else r for r, k in zip(relatives, rest)]
        if kept is not None:
            return [kept] + relatives
        if others[0] == base + 1:
            with self._cache_lock:
                self._forwards[base] = relatives[0]
                while len(self._forwards) > GAP_CACHE + 1:  # a neighbouring gap's reading adds one ahead
                    self._forwards.popitem(last=False)
        return relatives

    def _previous(self, gap: int, turns: np.ndarray, whole: np.ndarray) -> Relative:
        """Key ``gap − 1`` seen from key ``gap``: the inverse of the previous gap's relative of its
        next key as :meth:`_relatives` made it (kept for the last GAP_CACHE + 1 base keys, also where
        that gap took its rotations whole, which it did on a copy; built again only where it was
        let go: the same values whichever gaps were computed before), or, with a truncated basis (its
        metric is recovered per base key), from the poses; with the triangles' whole rotations in
        the components ``whole`` (bool (C,); :meth:`Relative.whole_rotations`), from the poses."""
        if self.k_M is not None or whole.any():
            previous = self._relative(gap, gap - 1, turns)
            return previous.whole_rotations(self._topo, self._key(gap), self._key(gap - 1), whole) \
                if whole.any() else previous
        with self._cache_lock:
            forward = self._forwards.get(gap - 1)
        forward = forward if forward is not None else self._relative(gap - 1, gap)
        return forward.inverse(self._topo, self._key(gap), self._key(gap - 1), turns)

    def _nonrigidity(self, base: int, other: int) -> np.ndarray:
        """The non-rigidity (C,) of key ``other`` seen from key ``base`` (as a gap's relatives have
        it: RMS misfit of the best rigid motion ÷ the component's diagonal in ``base``)."""
        with self._cache_lock:
            key = self._keys.get(base)  # its diagonals, where the key is at hand
        size = self._topo.diagonals(self._raw[base]) if key is None else key.diagonals
        return self._fits(base, other)[2] / size
