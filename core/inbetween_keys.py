"""The keys of a gap for the in-between solver: per key its frames and edges (``_Key``), and a key
seen from the base key of a gap (``_Relative``): each component's rigid motion, the per-triangle
rotation residuals and log-stretches of :mod:`core.deformation_fields`, and the vertices with the
rigid motions undone — what :mod:`core.inbetween_solver` splines over a gap.
"""

from __future__ import annotations

import copy
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from . import deformation_fields as df
from . import rotation_continuity
from . import screw_motions
from . import small_matrices
from .geometry import coordinate_dot, grouped_medians
from .rigid_alignment import pivoted_alignment, rigid_alignment, rigid_alignments

if TYPE_CHECKING:
    from .inbetween_topology import _Topology


#: A piece's rotation fields in a gap are taken whole (each triangle's own rotation from the base key,
#: not the residual to the piece's best rigid rotation) when, toward the next key or the one after,
#: its residuals' median angle exceeds the median angle of the triangles' whole rotations by more than
#: this (radians): the rigid fit then adds turn instead of explaining it. A soft flag pinned at its
#: pole, keys 16 frames apart: the best rigid rotation between two keys turns 161° about the pole,
#: the residuals 130° (median), the triangles' normals 53°; splined, the residuals and the
#: rigid motion compose to a third of the flag turned over at the middle of the gap (the simulated
#: frame: 117 triangles of 40,000). A cloth dragged by a corner and folded over (keys 16 frames
#: apart): best rigid rotation 171°, residuals 133°, whole rotations 91° (margin 42°); composed, 29 %
#: of it turned over at the middle of the gap (the simulated frame: 2 %). A rigid motion (residuals
#: zero) and cloth that does not turn as a whole keep the decomposition: on 23 other baked cloths
#: the residuals' median exceeds the whole rotations' by 7° at most (the flags' other gaps 12–26°,
#: the dragged cloth's 21°); numbers in docs/inbetweens.md.
SPURIOUS_RIGID_TURN = np.pi / 6
#: A sequence's piece that bends without a crease (no two neighbouring triangles' whole rotations
#: between the keys more than :data:`~core.rotation_continuity.WRAP_CREASE` apart: a limb of one
#: skin, not cloth) where over :data:`core.sequence_turn_readings.TURNED_PART_SHARE` of its area turns past
#: this angle (radians) from the rest of it per gap is treated as one turning past a half turn
#: (:meth:`_Relative.turning`): the keys' per-vertex spline cuts the chord of its curl already.
#: A thin arm bent 70 / 80 / 90° per key at two joints (its tip 140–180° per gap, 42–52 % of its
#: area past a right angle, neighbours 3.9–5.0° apart) came out 1.2–6.7 / 1.7–8.9 / 5.9–12.7 % of
#: the diagonal off, anchored to that spline; so, within 0.01 %. 128 gaps of the benchmark's
#: cloths and nine probe cloths (keys 4, 8, 16 frames apart) have over that share past a right
#: angle (up to 99 % of a piece's area), each with neighbours 44–180° apart; treated so
#: regardless, 101 of them had the in-between half-way farther from the simulation, up to 28 ×
#: (a sheet swinging off a rod that stops dead).
BENT_TURN = np.pi / 2

#: What a relative holds of the motion (rigid motions, positions, centroids), as opposed to the
#: deformation (rotation residuals, stretches).
KINEMATIC = ("screw", "vertices", "world", "centroids")
#: What of a relative the splines interpolate (the metric comes from the log-stretch where a key
#: is extrapolated: :meth:`_Relative._extrapolated`).
SPLINED = ("rotvec", "log_stretch") + KINEMATIC


class _Key:
    """Per-key data: positions, the corner edges' lengths (m, 3), their tangent coordinates
    stored by coordinate (2, 3 corners, m; ``coordinates``: the same as a (m, 3, 2) view), the
    inverse edge matrices' entries 00, 01, 11 (3, m), tangent frames (3 columns t1, t2, n;
    3 coordinates; m), normals (3, m), areas and component centroids."""

    def __init__(self, topo: _Topology, vertices):
        v = np.asarray(vertices, dtype=np.float64)  # checked at the public boundary
        self.vertices = v
        edges = topo.corner_edge_rows(v)  # (3 coordinates, 3 corners, m)
        self.lengths = np.sqrt(coordinate_dot(edges, edges)).T  # (m, 3), a view
        self.column_rows, self.tangent_rows = df.tangent_frame_rows(edges)
        self.coordinates = self.tangent_rows.transpose(2, 1, 0)  # (m, 3, 2), a view: no second copy
        self.inverse_rows = df.inverse_edge_rows(self.tangent_rows)
        self.normal_rows = self.column_rows[2]
        self.areas = 0.5 * np.abs(self.tangent_rows[0, 0] * self.tangent_rows[1, 2])
        self.centroids = topo.centroids(v)
        self.diagonals = topo.diagonals(v)


class _Relative:
    """Key ``other`` seen from the base key of a gap: each connected component's rigid motion
    (screw coordinates (C, 6)), per-triangle rotation residuals to it (rotation vectors (m, 3)),
    log-stretches and metrics ``G = U²`` (packed 2×2 in the base's tangent bases (m, 3) each) and
    the vertices with their component's rigid motion undone (n, 3)."""

    def __init__(self, topo: _Topology, base: _Key, other: _Key, log_stretch=None, turns=None, across=None):
        rotations, translations, self.misfits = rigid_fits(topo, base.vertices, other.vertices)
        turn, stretch = df.planar_polar(*df.planar_map_entries(other.tangent_rows, base.inverse_rows))
        # the triangles' whole rotations from the base as images of its frames: read by the pins'
        # fits (their entries, made once: _whole_entries), the residuals below and residuals_add_turn
        plane = self._plane_frames = df.plane_turned_frames(other.column_rows, turn)
        if topo.pinned is not None:
            rotations, translations, self.misfits = pin_held_fits(
                topo, base, other, partial(self._whole_entries, base, other, keep=True), rotations, translations,
                self.misfits)
        unwrap = turns is not None  # the continuation of the next key's turn
        self.nonrigidity = _nonrigidity(self.misfits, base, topo)
        if turns is None:  # every piece's half turn goes the way the whole mesh turns
            whole = rotations[0] if len(topo.components) == 1 else \
                rigid_alignment(base.vertices, other.vertices, topo.weights)[0]
            turns = np.repeat(df.rotation_vectors(whole[None]), len(topo.components), axis=0)
            self.whole_tells = bool(whole_tells(turns[0]))
        self.screw = component_screws(rotations, translations, turns, unwrap, self.nonrigidity)
        # the triangles' rotations as images of the base frames, with their component's rotation undone
        frames = df.turned_coordinate_rows(plane, small_matrices.transpose(rotations), topo.triangle_component)
        self.rotvec = df.frame_rows_rotation_vectors(frames, base.column_rows)
        # two poses (``across``: the mesh's triangle pairs sharing an edge): taken continuous across
        # the mesh, so that a part turning past a half turn from the rest turns on the same way; a
        # sequence's neighbouring keys tell the way instead (continue_turns) but in the pieces where
        # a part turns past a half turn (core.sequence_turn_readings.TURNED_PART_SHARE): taken across the
        # whole mesh, a flag whipping in wind (keys 16 frames apart) jumped 2.58 → 5.45 × the simulation
        self._across = across
        if across is not None:  # the part that stays is the one whose whole rotation is least
            self.rotvec = rotation_continuity.continuous_rotation_vectors(self.rotvec, across, topo.triangle_component,
                                                                          partial(_rotation_angles, plane, base.column_rows))
        if unwrap:  # kept for a key ahead of its gap's base alone: residuals_add_turn or whole_rotations reads them
            self.__dict__.pop("_plane_frames", None)
            self.__dict__.pop("_whole", None)
        if log_stretch is None:
            self._make_log = partial(_log_stretch_rows, stretch)
        else:
            self.log_stretch = log_stretch
        self.metric = df.squared_stretch(stretch) if log_stretch is None else df.exp_stretch(2.0 * log_stretch)
        self.vertices = topo.undo_motion(other.vertices, rotations, translations)
        self.world = other.vertices
        self.centroids = other.centroids
        self.turn, self.motion = turn, (rotations, translations)

    #: The triangle pairs across which the rotations are taken continuous (two poses), or None.
    _across = None
    #: Per component (bool (C,)), whether its half turn's way round is not told by the keys
    #: (set by ``core.sequence_half_turns.HalfTurns._turning_on``).
    untold_half_turn = np.zeros(0, dtype=bool)
    #: Whether the whole mesh's turn from the base key, which the pieces' half turns take the way
    #: of, has a way round itself (:func:`whole_tells`).
    whole_tells = False
    #: Whether this is a sequence's end condition, extrapolated from the keys (:meth:`phantom`).
    extrapolated = False
    #: Per component (bool (C,)), whether ``rotvec`` holds its triangles' whole rotations
    #: (:meth:`whole_rotations`) rather than their residuals to the component's rigid rotation.
    whole = np.zeros(0, dtype=bool)
    #: The triangles' whole rotations from the base key as images of its frames (3 columns, 3
    #: coordinates, m), kept by the constructor for :meth:`residuals_add_turn` and
    #: :meth:`whole_rotations`, which let them go (72 bytes per triangle, not held for the gap's
    #: life), or None; :meth:`_whole_entries` lets them go for the entries it makes of them.
    _plane_frames = None
    #: The entries (3, 3, m) of the triangles' whole rotations from the base key, made from
    #: ``_plane_frames`` where two readers ask for them (:meth:`_whole_entries`; the frames let go
    #: then, and these as they would be), or None.
    _whole = None
    #: The log-stretches once made, and what makes them (a function of the triangles asked for,
    #: an index array or None for all; see log_stretch).
    _log = None
    _make_log = None

    @property
    def log_stretch(self) -> np.ndarray:
        """Log-stretches (m, 3), made when first read: between the keys a gap interpolates the
        metrics, and their logarithms only where the metrics' spline is not positive definite or
        outside the keys (:meth:`core.inbetween_field.InterpolatedField.stretch`)."""
        if self._log is None:  # the maker let go once they are made (it holds the stretches)
            self._log, self._make_log = self._log_source()(None), None
        return self._log

    @log_stretch.setter
    def log_stretch(self, value: np.ndarray) -> None:
        self._log, self._make_log = value, None

    def log_stretch_rows(self, rows: np.ndarray) -> np.ndarray:
        """:attr:`log_stretch` on the triangles ``rows`` (index array), the others' not made (each
        triangle's from its own stretch: the same values as the whole array's)."""
        return self._log_source()(rows)

    def _log_source(self):
        """A function of the triangles asked for (an index array, or None for all) giving
        :attr:`log_stretch` there, without holding this relative."""
        log = self._log
        if log is None:
            make = self._make_log
            if make is not None:
                return make
            log = self._log  # made meanwhile by another thread
        return partial(_rows_of, log)

    def _turned_frames(self, other: _Key, rows=slice(None), keep: bool = False) -> np.ndarray:
        """The triangles' whole rotations from the base to ``other`` (the key this relative was
        built from) as images of the base's frames, on the triangles ``rows`` (3 columns × (3, r)):
        the constructor's where it kept them (let go unless ``keep``), else made again."""
        plane = self.__dict__.get("_plane_frames") if keep else self.__dict__.pop("_plane_frames", None)
        if plane is None:
            return df.plane_turned_frames(other.column_rows[:, :, rows], (self.turn[0][rows], self.turn[1][rows]))
        return plane[:, :, rows]

    def _whole_entries(self, base: _Key, other: _Key, rows=slice(None), keep: bool = False) -> np.ndarray:
        """The entries (3, 3, r) of the triangles' whole rotations from ``base`` to ``other`` (the
        keys this relative was built from) on the triangles ``rows``
        (:func:`~core.deformation_fields.frame_rows_rotation_entries` of :meth:`_turned_frames`):
        made once where the pins' fits and :meth:`turning` read them (``keep``, all rows), which
        lets the frames go; let go unless ``keep`` (72 bytes per triangle either)."""
        whole = self.__dict__.get("_whole") if keep else self.__dict__.pop("_whole", None)
        if whole is not None:
            return whole[:, :, rows]
        whole = df.frame_rows_rotation_entries(self._turned_frames(other, rows), base.column_rows[:, :, rows])
        if keep:
            self._whole = whole
        return whole

    def turning(self, topo: _Topology, base: _Key, other: _Key, pairs: np.ndarray, share: float,
                free: np.ndarray | None = None) -> tuple:
        """Per piece (bool (C,)), whether a part of it over ``share`` of its area turns far from the
        rest of it from ``base`` to ``other`` (the keys this relative was built from; ``pairs``
        (E, 2): the triangles sharing an edge; see :data:`core.sequence_turn_readings.TURNED_PART_SHARE`):
        where the triangles' whole rotations taken continuous across the mesh turn by over π more
        than the least-turned triangle of the piece — but for a piece with a jump past a half turn
        at a crease (:data:`core.rotation_continuity.WRAP_CREASE`) — or, in a piece that bends
        without a crease (no two neighbours' rotations more than ``WRAP_CREASE`` apart), by over
        :data:`BENT_TURN`. Read before :meth:`residuals_add_turn`, which lets the constructor's
        frames go. Also the triangles (bool (m,)) of those pieces that turn less than
        ``WRAP_CREASE`` from the least-turned one (the part the rest turns from), and per piece
        whether it turns past a half turn with a jump at a crease: which way it went is not known;
        the whole rotations taken continuous (:meth:`continued_turns`, ``free`` as there); and per
        piece whether it turns far with its part that stays not held still (turning by more than
        the mesh resolves there) while read from the part nearest its rigid turn it turns a whole
        turn otherwise: which end stays is not known; and, per piece, the triangle read as held
        still where that alone keeps the piece from being contested (-1 elsewhere), with the
        triangles (bool (m,)) turning less than the mesh resolves at them, for the neighbouring
        gaps' readings to tell whether that part is held there too."""
        whole, continued = self.continued_turns(topo, base, other, pairs, free)
        pieces, count = topo.triangle_component, len(topo.components)
        # from the least-turned part of its piece (a piece spinning by about a half turn as a
        # whole, its parts a little either side of it, turns as its rigid fit says)
        angles = np.sqrt(np.einsum("ij,ij->i", continued, continued))
        least = np.full(count, np.inf)
        np.minimum.at(least, pieces, angles)
        beyond = angles - least[pieces]
        area = np.maximum(np.bincount(pieces, base.areas, minlength=count), np.finfo(float).tiny)

        def over_share(turned: np.ndarray) -> np.ndarray:
            return np.bincount(pieces[turned], base.areas[turned], minlength=count) / area > share

        def with_crease(candidates: np.ndarray) -> np.ndarray:
            creased = rotation_continuity.creased(whole, candidates, rotation_continuity.WRAP_CREASE)
            return np.bincount(pieces[candidates[creased, 0]], minlength=count) > 0

        past = over_share(beyond > np.pi)
        folded = np.zeros(count, dtype=bool)
        if past.any():  # ... with a jump at a crease
            inside = pairs[past[pieces[pairs[:, 0]]]]
            folded = with_crease(inside[rotation_continuity.jumping_pairs(whole, inside)])
        out = past & ~folded
        bent = over_share(beyond > BENT_TURN) & ~past
        if bent.any():  # ... those without a crease
            out |= bent & ~with_crease(pairs[bent[pieces[pairs[:, 0]]]])
        # a turning piece whose part that stays itself turns by more than the mesh resolves there
        # (not held still) and whose rigid turn reads it the other way round: which end stays is
        # not known (a strip held at one end, 0°, is; a tail whose tip turns 13° the short way
        # round, 347° the long way, and whose root turns 71°, is not)
        contested = np.zeros(count, dtype=bool)
        held_only, still = np.full(count, -1), None
        if out.any():
            nearest = rotation_continuity.continuous_rotation_vectors(whole, pairs, pieces, toward=self._rigid_turns(topo, base),
                                                                      free=out[pieces])
            other = over_share(np.sqrt(np.einsum("ij,ij->i", nearest - continued, nearest - continued)) > np.pi)
            amount = np.sqrt(np.einsum("ij,ij->i", whole, whole))
            step = rotation_continuity.turn_steps(amount, pairs[~rotation_continuity.jumping_pairs(whole, pairs)])
            stays = np.full(count, -1)
            order = np.lexsort((angles, pieces))
            first = np.r_[True, pieces[order][1:] != pieces[order][:-1]]
            stays[pieces[order[first]]] = order[first]  # each piece's least-turned triangle
            still = angles <= step
            held = np.zeros(count, dtype=bool)
            held[stays >= 0] = still[stays[stays >= 0]]
            contested = out & other & ~held
            held_only = np.where(out & other & held, stays, -1)
        return out, out[pieces] & (beyond < rotation_continuity.WRAP_CREASE), folded, continued, contested, held_only, still

    def continued_turns(self, topo: _Topology, base: _Key, other: _Key, pairs: np.ndarray,
                        free: np.ndarray | None = None) -> tuple:
        """The triangles' whole rotation vectors (m, 3) from ``base`` to ``other`` (the keys this
        relative was built from), the short way round, and the same taken continuous across the
        triangle pairs ``pairs`` (E, 2) from each piece's part that stays (the reading of which way
        round a part turns, :meth:`turning`), or, on the triangles ``free`` (bool (m,) or None),
        from the part nearest the rigid motion's turn
        (:func:`core.rotation_continuity.continuous_rotation_vectors`)."""
        whole = df.rotation_vectors_of_entries(self._whole_entries(base, other, keep=True))
        continued = rotation_continuity.continuous_rotation_vectors(whole, pairs, topo.triangle_component,
                                                                    toward=self._rigid_turns(topo, base), free=free)
        return whole, continued

    def _rigid_turns(self, topo: _Topology, base: _Key) -> tuple:
        """Each triangle's piece's rigid rotation vector (m, 3) (the screw's, unwrapped as the
        sequence reads it) and the triangles' areas in ``base``: what the whole rotations taken
        continuous across a piece turn nearest (``toward`` of
        :func:`core.rotation_continuity.continuous_rotation_vectors`)."""
        # one gather of whole rows (3–4× faster than indexing rows and columns together)
        return np.take(self.screw[:, :3], topo.triangle_component, axis=0), base.areas

    def residuals_add_turn(self, topo: _Topology, base: _Key, other: _Key) -> np.ndarray:
        """Per component (bool (C,)), whether this relative's rotation residuals turn further than
        its triangles themselves (see :data:`SPURIOUS_RIGID_TURN`): the residuals' median angle
        against the median angle of the triangles' whole rotations from ``base`` to ``other``
        (from the trace of each rotation: of its entries where the pins' fits or :meth:`turning`
        made them, :meth:`_whole_entries`, else three dot products per triangle). Two poses, whose
        residuals are taken continuous across the mesh (``_across``): also the pieces whose
        residuals are left with a jump past a half turn there while their whole rotations, jumping
        too, are taken continuous with none left. A residual within the keys' noise of none has an
        axis that noise sets, and a whole turn about it parts neighbours by a whole turn times the
        angle between their axes: a strip curled 270° at one joint, whose rigid fit turns 74° the
        short way round (its tip's residuals 16°), 61 × 3 vertices with noise of 3e-4 of its length
        had its tip's residuals continued about axes up to 60° apart, a jump left, and every
        in-between and exaggeration turned the tip the short way round (0.50–0.61 of the diagonal
        off, silently); taken whole, within 2.1e-3."""
        made = self.__dict__.pop("_whole", None)  # the entries, where the pins' fits or turning made them
        frames = self._turned_frames(other) if made is None else None
        whole = _rotation_angles(frames, base.column_rows) if made is None else df.entries_rotation_angles(made)
        residual = np.sqrt(np.einsum("ij,ij->i", self.rotvec, self.rotvec))
        pieces, count = topo.triangle_component, len(topo.components)
        out = grouped_medians(residual, pieces, count) > grouped_medians(whole, pieces, count) + SPURIOUS_RIGID_TURN
        across = self._across
        if across is None or not len(across):
            return out
        # two poses: a piece whose residuals are left with a jump past a half turn (taken continuous
        # across the mesh, a part carrying a whole turn about axes its keys' noise sets: residuals
        # within that noise of none) while its whole rotations continue across the mesh with none
        left = rotation_continuity.jumping_pairs(self.rotvec, across)
        stuck = ~out & (np.bincount(pieces[across[left, 0]], minlength=count) > 0)
        if not stuck.any():
            return out
        vectors = df.frame_rows_rotation_vectors(frames, base.column_rows) if made is None else \
            df.rotation_vectors_of_entries(made)
        inside = across[stuck[pieces[across[:, 0]]]]
        wrapped = np.bincount(pieces[inside[rotation_continuity.jumping_pairs(vectors, inside), 0]],
                              minlength=count) > 0
        if not (stuck & wrapped).any():
            return out
        continued = rotation_continuity.continuous_rotation_vectors(vectors, across, pieces,
                                                                    toward=self._rigid_turns(topo, base))
        unwound = np.bincount(pieces[inside[rotation_continuity.jumping_pairs(continued, inside), 0]],
                              minlength=count) == 0
        return out | (stuck & wrapped & unwound)

    def whole_rotations(self, topo: _Topology, base: _Key, other: _Key, components: np.ndarray,
                        across: np.ndarray | None = None, free: np.ndarray | None = None) -> "_Relative":
        """A copy whose ``rotvec`` (m, 3) are, on the triangles of the ``components`` (bool (C,)),
        the triangles' whole rotations from ``base`` to ``other`` (the keys it was built from), the
        components' rigid rotations not undone; taken continuous across the mesh past a half turn
        across this relative's triangle pairs (two poses) or ``across`` (E, 2), from the part
        nearest the rigid motion's turn on the triangles ``free`` (:meth:`continued_turns`)."""
        rows = np.flatnonzero(components[topo.triangle_component])
        entries = self._whole_entries(base, other, rows)  # let go before the copy: it keeps none
        out = copy.copy(self)
        out.rotvec = self.rotvec.copy()
        out.rotvec[rows] = df.rotation_vectors_of_entries(entries)
        across = self._across if across is None else across
        if across is not None:
            out.rotvec = rotation_continuity.continuous_rotation_vectors(out.rotvec, across, topo.triangle_component,
                                                                         toward=self._rigid_turns(topo, base), free=free)
        out.whole = components
        return out

    def inverse(self, topo: _Topology, base: _Key, other: _Key, turns: np.ndarray) -> "_Relative":
        """The relative of ``other`` seen from ``base`` when this one is ``base`` seen from
        ``other`` (its log-stretch from the poses), in closed form instead of from the poses
        again: the rigid motions inverted, rotation residuals ``−R_c q`` (the residual's inverse
        conjugated by its component's rotation), log-stretches ``−Q(θ) log S Q(θ)ᵀ`` (the planar
        map's inverse is ``S⁻¹ Q(−θ)``, whose stretch in the base's tangent basis is
        ``Q(θ) S⁻¹ Q(θ)ᵀ``), metrics ``(Q(θ) G Q(θ)ᵀ)⁻¹``. ``turns`` as for the constructor
        (unwrapped)."""
        out = _Relative.__new__(_Relative)
        rotations, translations = self.motion
        inverse_rotations = small_matrices.transpose(rotations)
        inverse_translations = -np.einsum("cab,cb->ca", inverse_rotations, translations)
        out.screw = component_screws(inverse_rotations, inverse_translations, turns, True, self.nonrigidity)
        out.misfits = list(self.misfits)
        out.nonrigidity = _nonrigidity(self.misfits, base, topo)
        out.rotvec = -df.turned_rows(self.rotvec, rotations, topo.triangle_component)
        cos, sin = self.turn
        out._make_log = partial(_inverse_log_stretch, self._log_source(), cos, sin)
        g11, g12, g22 = _turned(self.metric, cos, sin).T  # the metric of the inverse: its inverse
        out.metric = np.stack([g22, -g12, g11], axis=1) / (g11 * g22 - g12 * g12)[:, None]
        out.vertices = topo.apply_motion(other.vertices, rotations, translations)
        out.world = other.vertices
        out.centroids = other.centroids
        out.turn, out.motion = (cos, -sin), (inverse_rotations, inverse_translations)
        return out

    def unwrap(self, turns: np.ndarray, rotvec: np.ndarray, nxt: "_Relative | None" = None) -> "_Relative":
        """This relative (built without ``turns``) with its screw coordinates taken as if the
        constructor had been given ``turns`` (C, 3), its triangles' turns continued toward
        ``rotvec`` (:meth:`continue_turns`); with the relative ``nxt`` of the key between, the
        screws a spline takes for this key two steps on (:attr:`continued_screw`)."""
        self.screw = component_screws(*self.motion, turns, True, self.nonrigidity)
        if nxt is not None:
            self._continued = screw_motions.continued_screws(nxt.screw, nxt.motion, self.motion,
                                                             turn_spread(np.maximum(self.nonrigidity, nxt.nonrigidity)))
        return self.continue_turns(rotvec)

    _continued = None

    @property
    def continued_screw(self) -> np.ndarray:
        """Screw coordinates (C, 6) a Catmull–Rom spline takes for this key when it is two steps
        on (:func:`core.screw_motions.continued_screws`, set by :meth:`unwrap`), else ``screw``."""
        return self.screw if self._continued is None else self._continued

    def continue_turns(self, rotvec: np.ndarray) -> "_Relative":
        """This relative with each triangle's rotation vector the representative nearest its row
        of ``rotvec`` (m, 3) (the continuation of a neighbouring key's: a triangle turning past a
        half turn between keys keeps turning the same way)."""
        self.rotvec = rotation_continuity.unwrapped_rotation_vectors(self.rotvec, rotvec)
        return self

    @classmethod
    def identity(cls, topo: _Topology, base: _Key) -> "_Relative":
        self = cls.__new__(cls)
        m = topo.triangles.shape[0]
        self.rotvec, self.log_stretch = np.zeros((m, 3)), np.zeros((m, 3))
        self.metric = np.tile([1.0, 0.0, 1.0], (m, 1))
        self.screw = np.zeros((len(topo.components), 6))
        self.vertices = self.world = base.vertices
        self.centroids = base.centroids
        self.nonrigidity = [0.0] * len(topo.components)
        return self

    def rescaled(self, origin: "_Relative", factor: float) -> "_Relative":
        """The key ``origin + factor · (self − origin)`` in every splined quantity (the screw from
        :attr:`continued_screw`): a neighbouring key at another distance in time moved to where a
        spline with evenly spaced keys wants it (``factor``: the gap at hand's duration ÷ the
        neighbouring gap's), so that Catmull–Rom's tangent is the mean of the two neighbouring
        secants per unit time. Marked as an end condition (:attr:`extrapolated`): no pose has
        these values."""
        def value(name):
            here, there = (_splined(r, name) for r in (self, origin))
            return there + factor * (here - there)
        out = _Relative._extrapolated(value, self.nonrigidity, ((1.0 - factor, origin), (factor, self)))
        out.rescaled_from = self
        return out

    @staticmethod
    def phantom(previous: "_Relative", current: "_Relative", farther: "_Relative | None" = None) -> "_Relative":
        """The key one step beyond ``current`` (end condition of the spline): the linear
        extrapolation 2·current − previous, or with ``farther`` (the key before ``previous``) for
        the motion (:data:`KINEMATIC`) the parabola through the three, 3·current − 3·previous +
        farther; the metric that of the extrapolated log-stretch (positive definite)."""
        def value(name):
            c, p = getattr(current, name), getattr(previous, name)
            if farther is not None and name in KINEMATIC:
                return 3 * (c - p) + _splined(farther, name)
            return 2 * c - p
        nonrigidity = np.maximum(previous.nonrigidity, current.nonrigidity)
        if farther is not None:
            nonrigidity = np.maximum(nonrigidity, farther.nonrigidity)
        recipe = ((3.0, current), (-3.0, previous), (1.0, farther)) if farther is not None else \
            ((2.0, current), (-1.0, previous))
        return _Relative._extrapolated(value, nonrigidity, recipe)

    #: An end condition's positions as weights of the relatives they extrapolate ((weight,
    #: relative), …; :meth:`positions_of`), None for a key.
    recipe = None
    #: The key's own relative of an end condition that stands for a key (:meth:`rescaled`), else None.
    rescaled_from = None

    @property
    def key_world(self) -> np.ndarray | None:
        """The positions (n, 3) of the key this relative stands for — a rescaled key's are the
        key's own (:attr:`rescaled_from`) — or None for an end condition past the keys
        (:meth:`phantom`)."""
        if not self.extrapolated:
            return self.world
        return None if self.rescaled_from is None else self.rescaled_from.world

    def positions_of(self, points: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Where the points ``points`` (r, 3) of the base key, carried by the rigid motions of
        the components ``rows`` (r,), are in this key — for an end condition, extrapolated from
        the keys' by the rule its other positions were (:attr:`recipe`)."""
        if self.recipe is not None:
            return sum(weight * relative.positions_of(points, rows) for weight, relative in self.recipe)
        motion = getattr(self, "motion", None)
        if motion is None:  # the base key itself
            return points.copy()
        return np.einsum("rab,rb->ra", motion[0][rows], points) + motion[1][rows]

    @staticmethod
    def _extrapolated(value, nonrigidity, recipe=None) -> "_Relative":
        """An end condition (:attr:`extrapolated`) with ``value(name)`` for each splined quantity
        (:data:`SPLINED`) and the metric of its log-stretch (positive definite); ``recipe``: its
        positions' weights of the relatives it extrapolates (:meth:`positions_of`)."""
        out = _Relative.__new__(_Relative)
        out.extrapolated = True
        out.recipe = recipe
        for name in SPLINED:
            setattr(out, name, value(name))
        out.metric = df.exp_stretch(2.0 * out.log_stretch)
        out.nonrigidity = nonrigidity
        return out


def _splined(relative: "_Relative", name: str) -> np.ndarray:
    """The value of ``relative`` a spline takes for quantity ``name`` (the screw: its
    :attr:`_Relative.continued_screw`)."""
    return relative.continued_screw if name == "screw" else getattr(relative, name)


def _log_stretch_rows(stretch: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    """The log-stretches of the packed ``stretch`` (m, 3) on the triangles ``rows`` (None: all)."""
    return df.log_stretch(stretch if rows is None else stretch[rows])


def _inverse_log_stretch(forward, cos: np.ndarray, sin: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    """The log-stretches of :meth:`_Relative.inverse` on the triangles ``rows`` (None: all):
    ``−Q(θ) L Q(θ)ᵀ`` of those ``forward(rows)`` gives (the relative inverted), ``θ`` given by its
    cosines and sines (m,)."""
    if rows is not None:
        cos, sin = cos[rows], sin[rows]
    return -_turned(forward(rows), cos, sin)


def _rows_of(values: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    return values if rows is None else values[rows]


def _turned(packed: np.ndarray, cos: np.ndarray, sin: np.ndarray) -> np.ndarray:
    """``Q(θ) A Q(θ)ᵀ`` of symmetric 2×2 matrices ``A`` packed (m, 3), ``θ`` given by its cosines
    and sines (m,)."""
    a11, a12, a22 = packed.T
    return np.stack([cos * cos * a11 - 2 * cos * sin * a12 + sin * sin * a22,
                     cos * sin * (a11 - a22) + (cos * cos - sin * sin) * a12,
                     sin * sin * a11 + 2 * cos * sin * a12 + cos * cos * a22], axis=1)


def component_screws(rotations: np.ndarray, translations: np.ndarray, turns: np.ndarray, unwrap: bool,
                     nonrigidity) -> np.ndarray:
    """Screw coordinates (C, 6) of the components' rigid motions (C, 3, 3), (C, 3), each rotation
    vector taken nearest its ``turns`` row (see :func:`core.screw_motions.rigid_logs`), to
    within what the components' ``nonrigidity`` (C,) says their fits are known to."""
    return screw_motions.rigid_logs(rotations, translations, turns, unwrap, turn_spread(nonrigidity))


def whole_tells(turn: np.ndarray) -> bool:
    """Whether a whole mesh's rotation vector ``turn`` (3,) has a way round to give its pieces'
    half turns: neither a turn within :data:`~core.screw_motions.TURN_SPREAD` (the coarsest a
    fit is taken to be known) of none, whose axis may be rounding (an engine's fixed block and its
    crank turning 180°: the whole mesh's turn is 1e-7 rad), nor itself a half turn as short either
    way round within it (a mesh of one piece: its own turn)."""
    theta = float(np.linalg.norm(turn))
    return theta > screw_motions.TURN_SPREAD and not rotation_continuity.either_way(theta, screw_motions.TURN_SPREAD)


def turn_spread(nonrigidity) -> np.ndarray:
    """The angles (radians, (C,)) the components' rotations are known to, from their
    ``nonrigidity`` (C,) (see :data:`core.screw_motions.TURN_NOISE`)."""
    return np.minimum(screw_motions.TURN_NOISE * np.asarray(nonrigidity, dtype=np.float64), screw_motions.TURN_SPREAD)


def rigid_fits(topo: _Topology, base: np.ndarray, other: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each component's best rigid motion taking vertices ``base`` (n, 3) onto ``other``: rotations
    (C, 3, 3), translations (C, 3) and the RMS misfits (C,) it leaves (mass-weighted)."""
    if len(topo.components) <= df.SLICED_PIECES:  # few pieces: each on its rows (views where consecutive)
        fits = [rigid_alignments(base[rows], other[rows], None, 1, topo.weights[rows]) for rows in topo.component_rows]
        rotations = np.concatenate([fit[0] for fit in fits]).reshape(-1, 3, 3)
        translations = np.concatenate([fit[1] for fit in fits]).reshape(-1, 3)
    else:  # many: all at once (a loop took 0.1 s per call on 3,000 pieces)
        rows = topo.component_vertices
        rotations, translations = rigid_alignments(base[rows], other[rows], topo.component_labels,
                                                   len(topo.components), topo.weights[rows])
    return rotations, translations, fit_misfits(topo, base, other, rotations, translations)


def fit_misfits(topo: _Topology, base: np.ndarray, other: np.ndarray, rotations, translations) -> np.ndarray:
    """Each component's RMS misfit (C,) (mass-weighted) of its rigid motion taking ``base`` onto ``other``."""
    residual = topo.apply_motion(base, rotations, translations) - other
    return np.sqrt(topo.component_sums(np.einsum("ij,ij->i", residual, residual)) / topo.component_mass)


#: A triangle's rotation past this angle (radians) is near a half turn, where its rotation vector's
#: direction is lost to rounding and a spline of it may take the other way round.
NEAR_HALF_TURN = 5 * np.pi / 6

#: The pins' fit is taken only where it leaves the triangles' median rotation smaller by more than
#: this (radians): a banner hung from two points and carried past a half turn had fits within 0.2°
#: of each other (median 38.0° against 38.1°, 560 against 562 past 150°), and the switch cost its
#: gap 4 % of RMS (the sequence's median 2.2 %); the handkerchief's fit that turned 176° left 28° more.
PIN_FIT_MARGIN = np.pi / 36

def pin_held_fits(topo: _Topology, base: _Key, other: _Key, whole, rotations, translations, misfits):
    """The pieces' rigid motions (``rotations`` (C, 3, 3), ``translations`` (C, 3), ``misfits`` (C,)
    from :func:`rigid_fits`), where a piece holds pins (``topo.pinned``: vertices at one place in
    every key) replaced by its best rigid motion that keeps them there
    (:func:`core.rigid_alignment.pivoted_alignment`) when that leaves its triangles less turn to
    make — a median angle of their rotations from ``base`` to ``other`` (``whole``: a function
    giving their entries (3, 3, m), asked only where a piece's two fits differ) with the
    piece's rotation undone smaller by :data:`PIN_FIT_MARGIN`, and fewer of them near a half turn
    (:data:`NEAR_HALF_TURN`). The free fit of a handkerchief pinned at its four centre vertices,
    folded into a bundle that looks alike after a half turn, turned 176° about its pins between keys
    8 frames apart, leaving its triangles 110° (median; 13 % past 150°) where they turned 82° (4 %):
    splined, 4,488 flipped triangles at the middle of the gap. A sheet rolled by 191° about its
    still half keeps the free fit (28°), which leaves 4 % of its triangles past 150° where the pins'
    would leave 12.5 %."""
    pinned = np.zeros(topo.n, dtype=bool)
    pinned[topo.pinned] = True
    held_rotations, held_translations = rotations.copy(), translations.copy()
    held = np.zeros(len(topo.components), dtype=bool)
    # each piece's rows selected by a view where they are consecutive (no (n, 3) copies)
    for c, (rows, selected) in enumerate(zip(topo.components, topo.component_rows)):
        pins = rows[pinned[rows]]
        if pins.size:
            held[c] = True
            held_rotations[c], held_translations[c] = pivoted_alignment(
                base.vertices[selected], other.vertices[selected], base.vertices[pins], topo.weights[selected])
    # a triangle's angle left to turn changes by at most the angle between the two fits (the
    # triangle inequality of rotation angles), so pieces whose fits differ by PIN_FIT_MARGIN or less
    # cannot take the pins' one: measured only where some piece's differ by more
    held &= np.linalg.norm(df.rotation_vectors(np.einsum("cji,cjk->cik", held_rotations, rotations)), axis=1) > PIN_FIT_MARGIN
    if not held.any():
        return rotations, translations, misfits
    entries, pieces = whole(), topo.triangle_component

    def left_to_turn(fitted):  # per component: the triangles' rotations, the fit undone: median angle, near half turns
        angles = _fit_undone_angles(entries, fitted, pieces)
        count = len(topo.components)
        return grouped_medians(angles, pieces, count), np.bincount(pieces, angles > NEAR_HALF_TURN, count)

    (held_median, held_near), (free_median, free_near) = left_to_turn(held_rotations), left_to_turn(rotations)
    use = held & (held_median < free_median - PIN_FIT_MARGIN) & (held_near < free_near)
    if not use.any():
        return rotations, translations, misfits
    rotations = np.where(use[:, None, None], held_rotations, rotations)
    translations = np.where(use[:, None], held_translations, translations)
    return rotations, translations, fit_misfits(topo, base.vertices, other.vertices, rotations, translations)


def _fit_undone_angles(entries: np.ndarray, rotations: np.ndarray, pieces: np.ndarray) -> np.ndarray:
    """The angle (m,) of each triangle's rotation ``W`` (its entries (3, 3, m)) with its piece's
    rotation ``R`` (``rotations`` (C, 3, 3), ``pieces`` (m,)) undone, ``Rᵀ W``: from its trace
    ``Σ_ab R_ab W_ab``, nine products per triangle."""
    r = rotations[0] if len(rotations) == 1 else np.moveaxis(rotations[pieces], 0, -1)  # (3, 3) or (3, 3, m)
    trace = sum(r[a, b] * entries[a, b] for a in range(3) for b in range(3))
    return df.trace_rotation_angles(trace)


def _rotation_angles(frames, columns) -> np.ndarray:
    """The angle (m,) of each triangle's rotation taking the frame ``columns`` to ``frames`` (both
    stored by coordinate, 3 columns × (3, m)): from its trace, three dot products per triangle."""
    trace = sum(coordinate_dot(frames[c], columns[c]) for c in range(3))
    return df.trace_rotation_angles(trace)


def _nonrigidity(misfits, base: _Key, topo: _Topology) -> list[float]:
    """Each component's RMS misfit of its best rigid motion over its bounding-box diagonal in the
    ``base`` key."""
    return list(np.asarray(misfits, dtype=np.float64) / base.diagonals)


def _log_stretch_from_lengths(base: _Key, corner_squared: np.ndarray) -> np.ndarray:
    """Packed log-stretches (m, 3) in the base's tangent bases whose metric ``U²`` gives the base's
    corner edges the squared lengths ``corner_squared`` (m, 3)."""
    a, b = base.coordinates[:, :, 0], base.coordinates[:, :, 1]
    system = np.stack([a * a, 2 * a * b, b * b], axis=2)  # (m, 3, 3) · (g11, g12, g22) = ℓ²
    metric = np.linalg.solve(system, corner_squared[:, :, None])[:, :, 0]
    return 0.5 * df.log_stretch(metric)
