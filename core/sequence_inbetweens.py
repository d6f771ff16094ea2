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
metric. The anchor ``w`` is a gauge (:data:`core.inbetween_topology.GAUGE_WEIGHT`) except in two-pose interpolation,
where vertices whose neighbourhood only translates between the keys are anchored to the linear
blend (exact for them, at every factor: parts that do not move stay put); see
:data:`core.inbetween_anchor.BLEND_ANCHOR_WEIGHT`. Connected components with no such vertex are placed by their
centroid, moved by the interpolated rigid motion of the whole mesh plus the interpolated residual
of the component (pieces of a mesh move as one).

Defects (flipped or collapsed triangles, non-finite values) are repaired where they are, and if
that fails a documented fallback is returned with a :class:`~core.errors.ShapeDifferenceWarning`
(:mod:`core.inbetween_repair`).
"""

from __future__ import annotations

import threading
import warnings
from collections import OrderedDict

import numpy as np
from scipy.spatial.transform import Rotation

from .allocator import keep_heap
from .errors import MeshError, RecoveryError, ShapeDifferenceWarning
from .concurrency import concurrently, in_background, result, single_threaded_blas
from .inbetween_prediction import CONCURRENT_VERTICES, gap_poses
from .deformation_fields import rotation_vectors
from .rotation_continuity import WRAP_CREASE, either_way, jumping_pairs, the_other_way
from .rotation_continuity import unwrapped_rotation_vectors
from .inbetween_keys import NEAR_HALF_TURN, _Key, _log_stretch_from_lengths, _Relative, rigid_fits
from .inbetween_keys import component_screws, turn_spread
from .inbetween_motion import RIGID_PLACEMENT_SCALE, SIMILAR_SHAPE_MISFIT
from .inbetween_flight import FREE_FLIGHT_JERK, FREE_FLIGHT_NONRIGIDITY, IMPACT_SLOWDOWN, after_impact, free_flight
from .inbetween_solver import _Gap
from .inbetween_topology import _Topology
from .laplace_basis import basis_sizes
from .mesh_topology import check_manifold_vertices
from .pins import riding_tolerance, riding_vertices, still_vertices, witnessed_riding
from .rigid_alignment import reflected_fits
from .seams import attached_loose, coincidence_tolerance, rounding_scale, seam_weld
from .splines import REST_START_LIMIT, START_TANGENT_LIMIT, HermiteGap
from .validation import (check_factor, check_gap_index, check_key_times, check_real, check_end, check_sequence,
                         check_start, check_time)

__all__ = ["SequenceInterpolator"]

#: Gaps whose prepared data (splines, relatives) SequenceInterpolator keeps: a gap's previous-key
#: relative comes from the gap before it, so two serve in-order visits (each holds ~70 MB at 100k
#: vertices).
GAP_CACHE = 2
#: Keys unevenly spaced (``key_times``): a gap sees its neighbouring keys at most this many times
#: nearer or further than they are when evenly spaced. Steady motion stays exact up to it (a retime
#: keyed every 16th frame with a last gap of one); beyond it the keys' own speeds differ so much
#: that the mean of their secants swings the in-betweens out (keys at 0, 1, 1000, 1001 of a
#: draping sheet: 3.4 units beyond the keys' box, 70 flipped triangles; 0.008 with the limit).
KEY_TIME_RATIO_LIMIT = 16.0
#: Keys whose per-key data SequenceInterpolator keeps: preparing gap k reads keys k − 1 … k + 2,
#: and the gap before it k − 2 … k + 1, so five serve in-order visits with no key built twice
#: (with four, key k − 1 was rebuilt for every gap: 0.05 s at 100k vertices); ~50 MB each at
#: 100k vertices.
KEY_CACHE = 5


def _with_rows(x: np.ndarray, rows: np.ndarray, source: np.ndarray) -> np.ndarray:
    """A copy of ``x`` (n, 3) with ``rows`` (bool (n,)) taken from ``source`` (n, 3)."""
    out = x.copy()
    out[rows] = source[rows]
    return out


def _warn(message: str) -> None:
    warnings.warn(f"Shape-difference interpolation: {message}.", ShapeDifferenceWarning, stacklevel=3)


#: A piece is said to be mirrored between two keys where the best reflection (improper orthogonal
#: map) takes it onto the next key within this fraction of its diagonal (RMS; as a rigid motion
#: is told by :data:`core.inbetween_motion.RIGID_PLACEMENT_SCALE`) ...
MIRROR_FIT = RIGID_PLACEMENT_SCALE
#: ... and the best rigid motion misses it by over this fraction: it would have to deform
#: visibly (:data:`core.inbetween_motion.SIMILAR_SHAPE_MISFIT`'s upper end). A flat piece is its
#: mirror image turned over, and passes (both fit it).
MIRROR_MISS = SIMILAR_SHAPE_MISFIT[1]
#: Vertices of each piece the check reads (evenly along its vertex order).
MIRROR_SAMPLES = 256

#: A sequence's gap where a part of a piece over this share of its area turns past a half turn
#: from the rest of it between the keys (the triangles' whole rotations, taken continuous across
#: the mesh where no jump joins a fold's crease, are past π there:
#: :func:`core.rotation_continuity.continuous_rotation_vectors`, :data:`~core.rotation_continuity.WRAP_CREASE`)
#: takes that piece's rotations whole, the next key's continuous across the mesh, and does not
#: anchor it to the keys' per-vertex spline (:meth:`core.inbetween_anchor.Anchor.spline_weights`).
#: Residuals to the piece's rigid fit wrap past π where that fit does not take up the curl, and
#: the spline cuts its chord: read as residuals and anchored, a closed tube and a bent arm curling
#: 200–340° per gap at the tip (20–48 % of their area past a half turn) came out 9–34 % of the
#: diagonal off, with up to 307 triangles facing against the curl; as here, within 0.2 %, none
#: against it. Applied to every gap those changes moved 17 of 18 benchmark sequence cells (a
#: wind-blown flag's largest jump 2.58 → 3.63–5.45 × the simulation's, keys 16 frames apart); no
#: gap of theirs has over 2.6 % of a piece's area past a half turn. So does a piece that bends
#: without a crease where over this share of it turns past a right angle from the rest
#: (:data:`core.inbetween_keys.BENT_TURN`: an arm of one skin bent 70–90° per key, 1.2–12.7 % off
#: anchored to the spline, within 1e-4 so). A piece past a half turn whose rotations jump at a
#: fold's crease is left as it is and its gap warns that the in-betweens may turn it the other
#: way round: a coarse arm (13 rings, 41.7° between them) curled 150° per key is 10–33 % off, a
#: sheet swinging off a rod that stops dead (keys 4 / 8 frames apart, 26 / 73 % past a half turn)
#: is right (0.57 / 0.49 × the linear blend's error).
TURNED_PART_SHARE = 0.1


class SequenceInterpolator:
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
    simulation stopped at any frame. ``"rest"``: it comes to rest there, as an animation easing
    into its last keyframe — the last gap ends with zero velocity (every spline's end tangent;
    exact for motion at constant deceleration to a stop). :func:`~core.motion_ends.end_of_motion` chooses from the
    source's frame in the middle of the last gap.

    :attr:`key_names`: the keys as warnings name them: ``key_names`` (K strings, such as the
    frames of a cache's samples, :func:`core.retime.iter_retime`), else ``"key pose i"``; a sequence
    keyed on some of another's keys names them as that one does (:func:`core.retime.iter_retime`'s
    short last gap), so that a caller naming ``"key pose i"`` (the operators: by frame) reads one
    numbering.
    """

    def __init__(self, key_poses, triangles, *, k_M: int | None = None, k_N: int | None = None,
                 offset: float | None = None, use_extrinsic: bool = True, smooth: bool = True, start: str = "rest",
                 key_times=None, end: str = "keys", key_names=None):
        keep_heap()  # many mesh-sized temporaries from here on: reuse the heap's pages
        start, end = check_start(start), check_end(end)
        key_poses, k_M, k_N, offset, use_extrinsic, smooth, topology = check_sequence(key_poses, triangles, k_M, k_N, offset, use_extrinsic, smooth)  # noqa: E501
        key_times = check_key_times(key_times, len(key_poses))
        if key_names is not None and len(key_names) != len(key_poses):
            raise MeshError(f"key_names must name each of the {len(key_poses)} key poses; got {len(key_names)}.")
        self._setup(key_poses, topology, k_M, k_N, offset, use_extrinsic, smooth, start, key_times, end=end,
                    key_names=key_names)

    def _setup(self, key_poses, topology, k_M, k_N, offset, use_extrinsic, smooth, start="rest", key_times=None,
               two_poses=False, end="keys", key_names=None):
        """The constructor once its arguments are checked (``topology``: that of the triangles;
        ``two_poses``: for an :class:`~core.two_pose_inbetweens.Interpolator`)."""
        self.start, self.end = start, end
        self._key_times = key_times
        # the keys as messages name them (the caller's names: the operators name frames or shape keys)
        default = ["vertices_a", "vertices_b"] if two_poses else [f"key pose {i}" for i in range(len(key_poses))]
        self.key_names = default if key_names is None else [str(name) for name in key_names]
        # each gap's duration (K − 1,); evenly spaced keys: all 1
        self._durations = np.ones(len(key_poses) - 1) if key_times is None else np.diff(key_times)
        keys = [np.asarray(k) for k in key_poses]
        if len(keys) < 2:
            raise MeshError(f"A sequence needs at least two key poses; got {len(keys)}.")
        self._triangles, self._copies = topology.triangles, None
        # at one place (seams, still vertices, holds): within this distance in every key
        rounding = rounding_scale(keys)
        tolerance = coincidence_tolerance(keys[0], topology.edges, rounding)
        apart = None  # why the seams cannot be joined
        try:  # pieces that touch along seams are interpolated as one, loose copies with their vertex (core.seams)
            weld = seam_weld(keys, topology, tolerance, orient=True)
        except MeshError as error:
            weld, apart = None, error
        if weld is None:
            check_manifold_vertices(topology)  # bow-tie vertices the seams do not join: refused in the caller's indices
        if apart is not None:
            weld = seam_weld(keys, topology, tolerance, seams=False)  # the loose copies alone
            _warn(f"some pieces touch along seams but cannot be joined there ({apart}); they are "
                  "interpolated apart and the seams may open")
        if weld is not None:
            keys, topology, self._copies = [k[weld.kept] for k in keys], weld.topology, weld.copies
        still = still_vertices(keys, tolerance)
        # loose vertices near the surface follow a triangle there, not their piece's rigid motion
        self._attached = attached_loose(keys, topology, still)
        if still.any():  # set where they sit in the first key (copies: the caller's arrays stay)
            keys = [k if np.array_equal(k[still], keys[0][still]) else _with_rows(k, still, keys[0]) for k in keys]
        # interpolated about the middle of the first key, the results moved back: the splines of the
        # pieces' screw motions limit their tangents per coordinate, which a translation changes
        # (a sheet keyed 1e3 units out: 0.1 of its size off in two of four gaps)
        self._given, self._still = keys, still
        self._hold_tolerance, self._holds = tolerance, {}
        origin = 0.5 * (keys[0].min(axis=0) + keys[0].max(axis=0)) if keys[0].size else np.zeros(3)
        self._origin = origin if origin.any() else None
        if self._origin is not None:
            keys = [k - origin for k in keys]
        self._raw = keys
        self._topo = _Topology(topology, keys[0])
        self._warn_mirrored(None if weld is None else weld.kept)
        # the pairs of triangles sharing an edge (E, 2): two poses take the triangles' rotations
        # continuous across them (_Relative); a sequence reads there which parts turn past a half
        # turn per gap (_Relative.turning) and takes those parts' turns continuous across them
        self._edge_pairs = topology.edge_triangles[topology.interior_edges]
        self._across = self._edge_pairs if two_poses else None
        self._topo.pinned = np.flatnonzero(still) if still.any() else None
        # pins (core.pins): still vertices stay put, riding sets follow the spline of their rigid
        # motion (found in the keys as given: their float32 rounding is that of the given coordinates);
        # two keys tell only sets that translate, and those are not held: the blend anchor holds
        # them, and an in-between says where they end far off it (core.inbetween_solver.HOOK_MISS_NOTED);
        # but sets moved by the same rigid motion as a whole rigid piece are held (witnessed_riding)
        self._riding_tolerance = riding_tolerance(self._given, topology.edges, still, rounding)
        moving = riding_vertices(self._given, topology.edges, self._topo.vertex_component, still, rounding,
                                 self._riding_tolerance) or None if len(keys) >= 3 or two_poses else None
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
        self._keys: OrderedDict[int, _Key] = OrderedDict()
        self._gaps: OrderedDict[int, _Gap] = OrderedDict()
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

    def _warn_mirrored(self, kept: np.ndarray | None) -> None:
        """Warn where a piece is its own mirror image from one key to the next: a reflection (a
        negative scale, a mirrored copy) fits it within :data:`MIRROR_FIT` of its diagonal and no
        rigid motion within :data:`MIRROR_MISS`. No motion turns a shape into its mirror image, so
        the in-betweens deform it through a flattened shape (tetrahedra mirrored: flat at 0.5,
        edges 18 % off, silently). ``kept``: the caller's index of each vertex (seams welded), or None."""
        topo, keys = self._topo, self._raw
        count = len(topo.components)
        if not count:
            return
        # about MIRROR_SAMPLES vertices of each piece, evenly along its vertices: a reflection's
        # fit and a rotation's miss 30 × apart are told by a few hundred (a cloth's check per pair
        # of keys on all 100k vertices cost 1 % of its in-betweens)
        order, starts = topo.component_order, topo.component_starts
        sizes = np.diff(np.r_[starts, order.size])
        stride = np.maximum(sizes // MIRROR_SAMPLES, 1)
        label = np.repeat(np.arange(count), sizes)
        rows = order[(np.arange(order.size) - starts[label]) % stride[label] == 0]
        labels = None if count == 1 else topo.vertex_component[rows]
        for i in range(len(keys) - 1):
            base = keys[i]
            pieces, rotation, reflection = reflected_fits(base[rows], keys[i + 1][rows], labels, count,
                                                          topo.weights[rows])
            if not pieces.size:
                continue
            mass = np.bincount(labels, topo.weights[rows], minlength=count)[pieces] if count > 1 else \
                topo.weights[rows].sum()
            size = topo.diagonals(base)[pieces]
            fit, miss = np.sqrt(reflection / mass), np.sqrt(rotation / mass)
            mirrored = pieces[(fit <= MIRROR_FIT * size) & (miss > MIRROR_MISS * size)]
            if mirrored.size:
                first = int(topo.component_vertices[topo.component_labels == mirrored[0]][0])
                first = first if kept is None else int(kept[first])
                _warn(f"{mirrored.size} piece(s) of the mesh (e.g. the one with vertex {first}) are the mirror "
                      f"image of themselves from {self.key_names[i]} to {self.key_names[i + 1]} (a reflection, as a "
                      "negative scale gives), which no motion makes: the in-betweens deform them through a "
                      "flattened shape. Check that key (apply the scale, or mirror the mesh back)")

    #: Every piece's rotations taken whole, not as residuals to its rigid motion (the second fit of
    #: :class:`~core.two_pose_inbetweens.Interpolator`, see :data:`~core.two_pose_inbetweens.WHOLE_FIT_MARGIN`).
    _whole_rotations = False

    def __len__(self) -> int:
        return len(self._raw) - 1

    @property
    def triangles(self) -> np.ndarray:
        return self._triangles

    def _key(self, index: int) -> _Key:
        with self._cache_lock:
            key = self._keys.get(index)
            if key is not None:
                self._keys.move_to_end(index)
                return key
        key = _Key(self._topo, self._raw[index])
        with self._cache_lock:
            self._keys[index] = key
            while len(self._keys) > KEY_CACHE:
                self._keys.popitem(last=False)
        return key

    def _reference(self, index: int):
        """The truncated recovery's prepared base for key ``index`` (eigenbasis, Gram factor).
        Only the intrinsic metric is recovered (rotations come from the poses): no offset surface."""
        if index not in self._references:
            from .reference_shape import ReferenceShape

            self._references.clear()  # one base at a time: gaps are visited per base key
            self._references[index] = ReferenceShape(self._raw[index], self._topo.triangles, offset=self.offset,
                                                      use_extrinsic=False)
        return self._references[index]

    def _truncated_log_stretch(self, base: int, other: int) -> np.ndarray | None:
        """Log-stretches (m, 3) toward key ``other`` whose edge lengths are those recovered from the
        truncated intrinsic differences; None (with a warning) when the recovery fails."""
        reference = self._reference(base)
        try:
            metric = reference.recover_metric(reference.shape_differences(self._raw[other], k_M=self.k_M, k_N=self.k_N))
        except RecoveryError as error:
            _warn(f"truncated recovery (k_M={self.k_M}, k_N={self.k_N}) failed ({error}); used the full-basis metric")
            return None
        squared = np.asarray(metric.base.squared_lengths, dtype=np.float64)
        if not (np.isfinite(squared).all() and (squared > 0).all()):
            _warn("truncated recovery returned non-positive squared lengths; used the full-basis metric")
            return None
        # corner edge c (corner c → c+1) is opposite corner c+2
        corner_squared = squared[reference.topology.triangle_edges[:, [2, 0, 1]]]
        return _log_stretch_from_lengths(self._key(base), corner_squared)

    def _relative(self, base: int, other: int, turn: np.ndarray | None = None) -> _Relative:
        log_stretch = self._truncated_log_stretch(base, other) if self.k_M is not None else None
        relative = _Relative(self._topo, self._key(base), self._key(other), log_stretch, turn, self._across)
        return self._turning_on(base, relative) if turn is None and other == base + 1 else relative

    def _turning_on(self, base: int, relative: _Relative) -> _Relative:
        """``relative`` (key ``base + 1`` seen from key ``base``) with each piece that turns past
        :data:`~core.inbetween_keys.NEAR_HALF_TURN` between the keys taken the other way round where
        that is nearer the turns of the steps before and after (per unit of time) by more than it
        turns the gap's middle further than the short way: a
        skirt spun 3.134 rad between keys 16 frames apart, turning on the same way before and
        after, was turned back the short way (rounding picked it), its waist one way and its hem
        the other (1.65 × the blend's error, 14.7 % edge deviation); a sheet flipped over a rod,
        −189° between keys, went +171° under it. Depends on the keys alone (every gap that uses
        this relative sees the same). Sets ``relative.untold_half_turn`` (bool (C,)): the pieces
        that turn a half turn, as short either way round to within what their fits are known to
        (:func:`~core.rotation_continuity.either_way`), whose way neither the whole mesh's turn
        (:func:`~core.inbetween_keys.whole_tells`) nor such a step tells (two poses have no
        steps): the keys do not tell which way round they went (a crank turning 180° per gap on a
        fixed block: its keys alternate between two poses)."""
        last = len(self._raw) - 1
        w = relative.screw[:, :3]
        theta = np.linalg.norm(w, axis=1)
        near = theta > NEAR_HALF_TURN
        relative.untold_half_turn = either_way(theta, turn_spread(relative.nonrigidity)) & (not relative.whole_tells)
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

    def _untold_half_turns(self, segment: _Gap, nxt: _Relative) -> np.ndarray:
        """Per component (bool (C,)), whether its half turn in gap ``segment`` (key ``base + 1``
        seen from the base: ``nxt``) goes a way the keys do not tell: a jointed piece moves
        relative to its parent (:mod:`core.inbetween_joints`), whose relative motion the gap takes
        the short way round, told by nothing where it is a half turn as short either way (a crank
        turning 180° about its bearing in a fixed block); any other piece as
        :meth:`_turning_on` found (an arm's link turning 180° in the world, 90° from the link it
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

    def _relatives(self, base: int, others: list[int]) -> list[_Relative]:
        """``self._relative(base, k)`` for each of ``others``, in threads on large meshes (keys
        built first: the key cache is not shared with the threads) unless a truncated recovery,
        which prepares one base shape for them all, makes the metric."""
        if self.k_M is not None:
            return [self._relative(base, k) for k in others]
        topo, key = self._topo, self._key(base)
        keys = [self._key(k) for k in others]
        relatives = concurrently(lambda other: _Relative(topo, key, other, across=self._across), keys,
                                 worth_it=topo.n >= CONCURRENT_VERTICES)
        return [self._turning_on(base, r) if k == base + 1 else r for r, k in zip(relatives, others)]

    def _previous(self, gap: int, turns: np.ndarray, whole: np.ndarray) -> _Relative:
        """Key ``gap − 1`` seen from key ``gap``: the inverse of the previous gap's relative of its
        next key (the same whichever gaps were computed before), or, with a truncated basis (its
        metric is recovered per base key), from the poses; with the triangles' whole rotations in
        the components ``whole`` (bool (C,); :meth:`_Relative.whole_rotations`), from the poses."""
        if self.k_M is not None or whole.any():
            previous = self._relative(gap, gap - 1, turns)
            return previous.whole_rotations(self._topo, self._key(gap), self._key(gap - 1), whole) \
                if whole.any() else previous
        cached = self._gaps.get(gap - 1)
        forward = cached.relatives[2] if cached is not None and not cached.relatives[2].whole.any() else \
            self._relative(gap - 1, gap)
        return forward.inverse(self._topo, self._key(gap), self._key(gap - 1), turns)

    def _gap(self, gap: int) -> _Gap:
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
        one base shape) nor on small meshes."""
        if (gap >= len(self) or gap in self._gaps or gap in self._pending or self.k_M is not None
                or self._topo.n < CONCURRENT_VERTICES):
            return
        future = in_background(self._prepare, gap)
        if future is not None:
            self._pending[gap] = future

    def _prepare(self, gap: int) -> _Gap:
        """Build gap ``gap``'s data and cache it (the least recently used gap is let go first, so
        that no more than GAP_CACHE gaps are held while it is built)."""
        with self._cache_lock:
            while len(self._gaps) >= GAP_CACHE:
                self._gaps.popitem(last=False)
        topo, base = self._topo, self._key(gap)
        last = len(self._raw) - 1
        others = [gap + 1, gap + 2] if self.smooth and last >= 2 and gap + 2 <= last else [gap + 1]
        ahead = self._relatives(gap, others)
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
                apart = self._composed_apart(gap, turning, root, continued)
                free = self._unsure(gap)[topo.triangle_component]
                unsure = (self._unsure(gap, final=True) if free.any() else none) | (contested & self._wagging(gap))
                free = free if free.any() else None
        # rotation fields taken whole in the components whose rigid fits add turn (SPURIOUS_RIGID_TURN)
        # and in the turning ones
        whole = np.ones(len(topo.components), dtype=bool) if self._whole_rotations else \
            np.any([r.residuals_add_turn(topo, base, self._key(k)) for r, k in zip(ahead, others)], axis=0)
        segment = self._segment(gap, ahead, others, whole | turning, turning, root, free)
        # ... and in those whose composed rotations pull against the world spline's guide (AGAINST_GUIDE_SHARE)
        against = segment.rotations_against_guide()
        if against.any():
            segment = None  # let the first build go before the second is made (one gap held, not two)
            segment = self._segment(gap, ahead, others, whole | turning | against, turning, root, free)
        segment.folded_turn = bool(folded.any())
        segment.unsure_turn = bool(unsure.any())
        segment.untold_half_turns = int(np.count_nonzero(self._untold_half_turns(segment, ahead[0])))
        segment.composed_apart = float(apart.max(initial=0.0))
        with self._cache_lock:
            self._gaps[gap] = segment
        return segment

    def _reading(self, gap: int, final: bool = False, relative: _Relative | None = None) -> tuple:
        """Which way round gap ``gap`` reads its parts' turns: :meth:`_Relative.turning`'s answers
        (per component whether a part of it turns far from the rest, the triangles that the rest
        turns from, whether a turn is at a crease, the whole rotations (m, 3) from key ``gap`` to
        the next taken continuous across the mesh, and whether which end stays is contested).
        Each gap reads it from its own keys: from the part that turns least, or, ``final``, in the
        pieces where the readings of the gaps around disagree (:meth:`_unsure`), from the part
        nearest the piece's rigid turn. ``relative``: key ``gap + 1`` seen from key ``gap``, if
        made. The last few readings are kept where a piece turns or a neighbouring gap asked for
        one."""
        with self._cache_lock:
            known = self._readings.get((gap, final))
        if known is not None:
            return known
        free = None
        if final:
            unsure = self._unsure(gap)
            if not unsure.any():
                return self._reading(gap, relative=relative)
            free = unsure[self._topo.triangle_component]
        topo, base, nxt = self._topo, self._key(gap), self._key(gap + 1)
        # the gap's own relative: its rigid turn unwrapped as the gap takes it (_turning_on)
        made = relative is None  # asked for by a neighbouring gap
        relative = self._turning_on(gap, _Relative(topo, base, nxt)) if made else relative
        known = relative.turning(topo, base, nxt, self._edge_pairs, TURNED_PART_SHARE, free)
        with self._cache_lock:
            if not final:
                self._turnings[gap] = known[0]
            if known[0].any() or made:  # a gap with no turning piece asks for no neighbour's
                self._readings[(gap, final)] = known
                while len(self._readings) > 2 * GAP_CACHE + 2:
                    self._readings.popitem(last=False)
        return known

    def _composed_apart(self, gap: int, turning: np.ndarray, root: np.ndarray, continued: np.ndarray) -> np.ndarray:
        """Per component (C,), the share of its area whose whole rotation (``continued``, (m, 3),
        :meth:`_reading`) interpolated as one turn, as the in-betweens take it, is half-way through
        gap ``gap`` more than :data:`~core.rotation_continuity.WRAP_CREASE` from the turn of the
        part that stays (``root``, bool (m,): its mean rotation vector) composed with its own turn
        from there (zero but in the ``turning`` pieces). Both join the keys; they differ by the two
        turns' commutator where the part that stays turns about another axis than the rest curls
        (an arm curling 170° per key at two joints while it turns 20° per key about z: its forearm
        up to 89° apart, tilted 88–90° off the curl in every gap; 10° per key: 53°; 150° turning
        10°: 18°), and there the keys do not tell which of them a part went."""
        topo = self._topo
        pieces, count = topo.triangle_component, len(topo.components)
        areas = self._key(gap).areas
        held = np.where(root, areas, 0.0)
        stays = np.stack([np.bincount(pieces, held * continued[:, k], minlength=count) for k in range(3)], axis=1)
        stays /= np.maximum(np.bincount(pieces, held, minlength=count), np.finfo(float).tiny)[:, None]
        rows = np.flatnonzero(turning[pieces])
        rest = stays[pieces[rows]]
        own = (Rotation.from_rotvec(rest).inv() * Rotation.from_rotvec(continued[rows])).as_rotvec()
        own = unwrapped_rotation_vectors(own, continued[rows] - rest)
        composed = Rotation.from_rotvec(0.5 * rest) * Rotation.from_rotvec(0.5 * own)
        apart = rows[(composed.inv() * Rotation.from_rotvec(0.5 * continued[rows])).magnitude() > WRAP_CREASE]
        total = np.maximum(np.bincount(pieces, areas, minlength=count), np.finfo(float).tiny)
        return np.bincount(pieces[apart], areas[apart], minlength=count) / total

    def _held_alone(self, gap: int, held_only: np.ndarray) -> np.ndarray:
        """Per component (bool (C,)), whether the triangle its reading of gap ``gap`` holds still
        (``held_only``: per piece, the one whose hold alone keeps it from being contested, or -1;
        :meth:`_Relative.turning`) turns more than the mesh resolves in a neighbouring gap's
        reading. A part held in one gap alone tells no end that stays: every continuous turn
        crosses a whole turn somewhere, and a triangle there reads as held (a tail wagged 1, −1.2,
        1.2, −1.3: the tip winds 362° and 378° in the middle gaps and a ring near it reads 0.7°,
        held, the root read a whole turn off, 88–131 % of the diagonal off, silently) where a
        part held in every gap (a strip's pinned end) reads held in each."""
        last, out = len(self._raw) - 1, np.zeros(held_only.shape, dtype=bool)
        pieces = np.flatnonzero(held_only >= 0)
        for k in (gap - 1, gap + 1):
            if pieces.size and 0 <= k < last:
                still = self._reading(k)[6]  # None where no piece turns far there: it tells nothing
                if still is not None:
                    out[pieces] |= ~still[held_only[pieces]]
        return out

    def _turning(self, gap: int) -> np.ndarray:
        """Per component (bool (C,)), whether a part of it turns far from the rest in gap ``gap``
        (read from its own keys: :meth:`_reading`)."""
        with self._cache_lock:
            turning = self._turnings.get(gap)
        return self._reading(gap)[0] if turning is None else turning

    def _readings_disagree(self, first: int, final: bool) -> tuple[np.ndarray, np.ndarray]:
        """Per component (bool (C,) each), whether the turn from key ``first`` to key ``first + 2``
        is short across it (no jump past a half turn between neighbouring triangles: its own way
        round is not in question), and whether there the readings (:meth:`_reading`, ``final`` as
        there) of gaps ``first`` and ``first + 1`` add up to a whole turn more or less than it over
        more than :data:`TURNED_PART_SHARE` of the piece's area (kept: a few booleans per pair)."""
        with self._cache_lock:
            known = self._agreements.get((first, final))
        if known is not None:
            return known
        topo = self._topo
        pieces, count = topo.triangle_component, len(topo.components)
        a, b = self._reading(first, final)[3], self._reading(first + 1, final)[3]
        span = (Rotation.from_rotvec(b) * Rotation.from_rotvec(a)).as_rotvec()  # key first → first + 2
        pairs = self._edge_pairs
        short = np.bincount(pieces[pairs[jumping_pairs(span, pairs), 0]], minlength=count) == 0
        areas = self._key(first).areas
        area = np.maximum(np.bincount(pieces, areas, minlength=count), np.finfo(float).tiny)
        off = np.linalg.norm(a + b - span, axis=1) > np.pi
        known = short, short & (np.bincount(pieces[off], areas[off], minlength=count) / area > TURNED_PART_SHARE)
        with self._cache_lock:
            self._agreements[(first, final)] = known
        return known

    def _wagging(self, gap: int) -> np.ndarray:
        """Per component (bool (C,)), whether the keys either side of key ``gap`` or of key
        ``gap + 1`` are a short turn apart across it (:meth:`_readings_disagree`): the piece goes
        back about the way it came. There a turning piece whose part that stays is contested
        (:meth:`_Relative.turning`) warns: both its ends turn, and its rigid turn reads it the
        other way round (a tail wagged 1, −1.3, 1: 87–130 % of the diagonal off). A piece that
        keeps curling with its part that stays turning a little about another axis (an arm curled
        150° per key at two joints while turning 10° per key about a third axis) is right to 3.3 %
        and its rigid turn reads it the other way round too: it does not warn."""
        last = len(self._raw) - 1
        out = np.zeros(len(self._topo.components), dtype=bool)
        for first in (gap - 1, gap):
            if 0 <= first and first + 2 <= last:
                out |= self._readings_disagree(first, False)[0]
        return out

    def _unsure(self, gap: int, final: bool = False) -> np.ndarray:
        """Per component (bool (C,)), among those of gap ``gap`` where a part turns past a half
        turn from the rest (:meth:`_Relative.turning`), whether the way round it is read
        (:meth:`_reading`, ``final`` as there) may be wrong. Where the keys either side of a key
        are a short turn apart the readings of the gaps around that key must add up to that turn
        (:meth:`_readings_disagree`); walked from this gap through the neighbouring gaps so linked
        where the piece turns far too, a pair that does not makes every reading of the run unsure
        (one side of it is wrong, and so is each reading that adds up with a wrong one). A tail
        wagged 1, −1, 1.2, −1 (root 62° then 68° per gap, tip 302° then 332°, the tip read the
        short way, −28°) was read from the root in the first gap and from the tip, a whole turn
        of the tail off, in the two after."""
        with self._cache_lock:
            known = self._unsures.get((gap, final))
        if known is not None:
            return known
        last, turning = len(self._raw) - 1, self._turning(gap)
        out = np.zeros_like(turning)
        for step in (-1, 1):
            pieces, k = turning.copy(), gap
            while pieces.any():
                first = k - 1 if step < 0 else k
                if first < 0 or first + 2 > last:
                    break
                linked, disagree = self._readings_disagree(first, final)
                out |= pieces & disagree
                k += step
                pieces &= linked & self._turning(k)  # on through a neighbour where it turns far too
        with self._cache_lock:
            self._unsures[(gap, final)] = out
        return out

    def _segment(self, gap: int, ahead: list[_Relative], others: list[int], whole: np.ndarray,
                 turning: np.ndarray, root: np.ndarray | None = None, free: np.ndarray | None = None) -> _Gap:
        """Gap ``gap``'s data from the relatives ``ahead`` of its keys ``others`` (the next one and,
        in a cubic sequence, the one after), with the triangles' whole rotations in the components
        ``whole`` (bool (C,); :meth:`_Relative.whole_rotations`), those of the next key taken
        continuous across the mesh in the components ``turning`` (bool (C,), whole too: a part of
        them turns far from the rest, :meth:`_Relative.turning`; ``root``: their
        triangles that the rest turns from, bool (m,), or None; ``free``: the triangles whose
        turns are read from the part nearest their piece's rigid turn, :meth:`_reading`)."""
        topo, base = self._topo, self._key(gap)
        last = len(self._raw) - 1
        ident = _Relative.identity(topo, base)
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
            # tangent at most the first gap's secant (see splines.START_TANGENT_LIMIT); its end: linear
            # (or at rest: end="rest", which sets the last gap's end tangents to zero)
            prev = self._previous(gap, -back_time * turn, whole).continue_turns(-back_time * nxt.rotvec) \
                if gap >= 1 else _Relative.phantom(nxt, ident, after)
            if back_time != 1.0:
                prev = prev.rescaled(ident, 1.0 / back_time)
            after = after if after is not None else _Relative.phantom(ident, nxt)
        else:
            prev = after = ident
        return _Gap(topo, base, self._key(gap + 1), [prev, ident, nxt, after], cubic, self.use_extrinsic,
                    self._anchored, self._static, self._riding, riding_tolerance=self._riding_tolerance,
                    start_limit=self._start_limit(gap), rest_end=cubic and self.end == "rest" and gap == last - 1,
                    whole_rotations=whole, steady=self._steady(gap) if cubic else None,
                    entry=self._entry(gap, prev.nonrigidity) if cubic else None,
                    exit=self._exit(gap) if cubic else None,
                    hooked=self._hooked, turning=turning, root=root)

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

    def _exit(self, gap: int) -> tuple | None:
        """Where the gap after starts right after an impact (:func:`core.inbetween_flight.after_impact`:
        the cloth landed inside this gap, and the gap after starts on the parabola through its
        end), this gap ends with the velocity the gap after starts with: ``(per component (C,),
        {"world": (n, 3), "centroids": (C, 3)})`` — the positions' start tangents of the gap
        after, which place the piece; its other splines end with the next gap's secant
        (``exit`` of :class:`core.splines.HermiteGap`) — or None. The Catmull–Rom tangent
        carries the fall's speed into the key, where the gap after drops it at once: a kink
        the simulation, whose cloth slowed inside this gap, does not have (numbers in
        docs/inbetweens.md, *Kinks at impact keys*). Keys evenly spaced around the key (the
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
        impact = after_impact(self._nonrigidity(k, gap), self._nonrigidity(k, k + 1), incoming, outgoing, None)
        if impact is None:
            return None
        rest_end = self.end == "rest" and k == last - 1

        def start_velocity(x):  # the gap after's start tangent: its HermiteGap's under parabolic_start
            after = x[k + 2] if k + 2 <= last else 2.0 * x[k + 1] - x[k]
            return HermiteGap((x[gap], x[k], x[k + 1], after), True, rows=True, parabolic_start=np.bool_(True),
                              rest_end=rest_end).t0

        return impact, {"world": start_velocity(self._raw), "centroids": start_velocity(c)}

    def _nonrigidity(self, base: int, other: int) -> np.ndarray:
        """The non-rigidity (C,) of key ``other`` seen from key ``base`` (as a gap's relatives have
        it: RMS misfit of the best rigid motion ÷ the component's diagonal in ``base``)."""
        topo = self._topo
        return rigid_fits(topo, self._raw[base], self._raw[other])[2] / topo.diagonals(self._raw[base])

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

    def pose(self, gap_index: int, factor: float) -> np.ndarray:
        """The pose at ``factor`` in gap ``gap_index`` (key ``gap_index`` → ``gap_index + 1``)."""
        return self.poses(gap_index, [factor])[0]

    def poses(self, gap_index: int, factors) -> np.ndarray:
        """The poses (len(factors), n, 3) at ``factors`` in gap ``gap_index``, sharing the work:
        with three or more in-betweens the reconstruction is solved at one to three of them and the
        others are predicted from those (:mod:`core.inbetween_prediction`, which gives the
        measurements against solving each); :meth:`pose` solves every pose."""
        out, problems = self._poses(gap_index, factors)
        for message in problems:
            _warn(message)
        return out

    def _poses(self, gap_index: int, factors) -> tuple[np.ndarray, list[str]]:
        """:meth:`poses` and the warnings' messages, not yet given (the caller warns: a warning
        filter changed around the call would be the process's, not this thread's)."""
        gap_index, factors = check_gap_index(gap_index, len(self)), [check_factor(f) for f in np.atleast_1d(factors)]
        gap = int(gap_index)
        if not 0 <= gap < len(self):
            raise IndexError(f"gap_index {gap_index} out of range for {len(self)} gap(s).")
        factors = [float(f) for f in np.atleast_1d(factors)]
        if not all(np.isfinite(factors)):
            raise ValueError(f"factors must be finite numbers; got {factors!r}.")
        out = np.empty((len(factors), self._topo.n, 3))
        between = [k for k, s in enumerate(factors) if s not in (0.0, 1.0)]
        for k, s in enumerate(factors):
            if s in (0.0, 1.0):
                out[k] = self._given[gap + int(s)]
        if not between or self._hold(gap):  # a hold: the pose at every factor
            out[between] = self._given[gap]
            return (out if self._copies is None else out[:, self._copies]), []
        # BLAS single-threaded meanwhile: its calls here are (n, 3) × (3, 3) products, which a
        # second BLAS thread does not speed up; its workers spin on the core the other half of the
        # work needs (10k hanging sheet, keys 4 apart: 0.037 → 0.031 s per in-between in one thread)
        with single_threaded_blas():
            segment = self._gap(gap)
            self._prepare_in_background(gap + 1)
            solved = gap_poses(segment, [factors[k] for k in between])
        problems = []
        turned = (f"between {self.key_names[gap]} and {self.key_names[gap + 1]}, over "
                  f"{100 * TURNED_PART_SHARE:.0f} % of a piece's area turns past a half turn from the rest of it")
        if segment.folded_turn:
            problems.append(f"{turned} across a fold: the in-betweens may turn it the other way round (keys closer "
                            "together tell which way it went)")
        if segment.unsure_turn:
            problems.append(f"{turned}, and which way round it went is not told by these keys (the gaps next to it "
                            "read it differently, or its rigid motion reads it the other way round): the "
                            "in-betweens may turn it the other way round (keys closer together tell which way "
                            "it went)")
        if segment.composed_apart > TURNED_PART_SHARE:
            problems.append(f"{turned} while the rest turns about another axis: the in-betweens turn each part as "
                            f"one turn, {100 * segment.composed_apart:.0f} % of the piece's area over "
                            f"{np.degrees(WRAP_CREASE):.0f}° half-way from the rest's turn composed with the part's "
                            "own, and the keys do not tell which it went (keys closer together bring the two nearer)")
        if segment.untold_half_turns:
            problems.append(f"between {self.key_names[gap]} and {self.key_names[gap + 1]}, "
                            f"{segment.untold_half_turns} piece(s) turn a half turn (180°) to within what the keys "
                            "tell, and nothing in them tells which way round: the in-betweens may turn them the "
                            "other way round (keys closer together tell which way they went)")
        held = self._held(gap)
        for k, (x, problem) in zip(between, solved):
            out[k] = x if self._origin is None else x + self._origin
            if self._origin is not None and self._static is not None:
                out[k][self._still] = self._given[0][self._still]  # exactly where they sit
            if held.any():  # pieces held in this gap
                out[k][held] = self._given[gap][held]
            if problem:
                problems.append(f"pose at factor {factors[k]:g} between {self.key_names[gap]} and "
                                f"{self.key_names[gap + 1]}: {problem}")
        attached = self._attached
        if attached is not None:  # in their triangles' frames, their coordinates there blended between the keys
            moving = ~held[attached.vertices]  # held ones stay as the key has them
            for k in between:
                local = (1.0 - factors[k]) * attached.local[gap] + factors[k] * attached.local[gap + 1]
                out[k][attached.vertices[moving]] = attached.placed(out[k], local)[moving]
        return (out if self._copies is None else out[:, self._copies]), problems

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
