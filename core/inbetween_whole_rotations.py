"""The triangles' whole rotations from the base key of a gap to another key (the rotation field of
paper §8.4's in-betweens taken whole, not as residuals to each piece's rigid rotation), and what a relative
(:class:`core.inbetween_keys.Relative`) reads from them: which pieces have a part turning past a
half turn from the rest (:meth:`WholeRotations.turning`), whether a piece's rigid fit adds turn its
triangles do not make (:data:`SPURIOUS_RIGID_TURN`), and the relative with a piece's rotations taken
whole (:meth:`WholeRotations.whole_rotations`). Rotations of m triangles as images of the base's
tangent frames (3 columns × (3, m)) or rotation vectors (m, 3).
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING

import numpy as np

from . import deformation_fields as df
from . import rotation_continuity
from .geometry import coordinate_dot, grouped_medians

if TYPE_CHECKING:
    from .inbetween_keys import Key, Relative
    from .inbetween_topology import Topology


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
#: (:meth:`WholeRotations.turning`): the keys' per-vertex spline cuts the chord of its curl already.
#: A thin arm bent 70 / 80 / 90° per key at two joints (its tip 140–180° per gap, 42–52 % of its
#: area past a right angle, neighbours 3.9–5.0° apart) came out 1.2–6.7 / 1.7–8.9 / 5.9–12.7 % of
#: the diagonal off, anchored to that spline; so, within 0.01 %. 128 gaps of the benchmark's
#: cloths and nine probe cloths (keys 4, 8, 16 frames apart) have over that share past a right
#: angle (up to 99 % of a piece's area), each with neighbours 44–180° apart; treated so
#: regardless, 101 of them had the in-between half-way farther from the simulation, up to 28 ×
#: (a sheet swinging off a rod that stops dead).
BENT_TURN = np.pi / 2


def rotation_angles(frames, columns) -> np.ndarray:
    """The angle (m,) of each triangle's rotation taking the frame ``columns`` to ``frames`` (both
    stored by coordinate, 3 columns × (3, m)): from its trace, three dot products per triangle.
    The trace is summed as :func:`~core.deformation_fields.entries_rotation_angles` sums it from
    the rotation's entries (:func:`~core.deformation_fields.frame_rows_rotation_entries`): each
    diagonal entry ``R_aa = Σ_c f_ca b_ca`` over the columns, then ``(R_00 + R_11) + R_22``, so
    that an angle is the same to the bit whichever of the two it is read from
    (:meth:`WholeRotations.residuals_add_turn` reads the entries where they are kept, else the frames)."""
    diagonal = [coordinate_dot(frames[:, a], columns[:, a]) for a in range(3)]  # R_aa, the columns summed in order
    return df.trace_rotation_angles(diagonal[0] + diagonal[1] + diagonal[2])


class WholeRotations:
    """The triangles' whole rotations between a relative's two keys, made once and let go, and
    the turns read from them; mixed into :class:`~core.inbetween_keys.Relative`.

    Of the Relative it is mixed into, it reads its ``_across``, ``rotvec``, ``screw``, ``turn``."""

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
    #: The triangles' whole rotation vectors (m, 3) from the base key, the short way round (all the
    #: triangles'), made once by :meth:`continued_turns` and read-only: a sequence's gap reads them
    #: up to four times while it is prepared (its turns, the rotations taken whole in one or two
    #: builds of the gap, :meth:`whole_rotations`, the rotations against the guide); shared by the
    #: copies :meth:`whole_rotations` makes, let go by :meth:`let_go_whole_vectors`; or None. Each
    #: row is its own (element-wise products of that triangle's frames), so a row read from them is
    #: the one made from that row's entries alone, to the bit.
    _whole_vectors = None

    def _turned_frames(self, other: Key, rows=slice(None), keep: bool = False) -> np.ndarray:
        """The triangles' whole rotations from the base to ``other`` (the key this relative was
        built from) as images of the base's frames, on the triangles ``rows`` (3 columns × (3, r)):
        the constructor's where it kept them (let go unless ``keep``), else made again."""
        plane = self.__dict__.get("_plane_frames") if keep else self.__dict__.pop("_plane_frames", None)
        if plane is None:
            return df.plane_turned_frames(other.column_rows[:, :, rows], (self.turn[0][rows], self.turn[1][rows]))
        return plane[:, :, rows]

    def _whole_entries(self, base: Key, other: Key, rows=slice(None), keep: bool = False) -> np.ndarray:
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

    def turning(self, topo: Topology, base: Key, other: Key, pairs: np.ndarray, share: float,
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

    def continued_turns(self, topo: Topology, base: Key, other: Key, pairs: np.ndarray,
                        free: np.ndarray | None = None) -> tuple:
        """The triangles' whole rotation vectors (m, 3) from ``base`` to ``other`` (the keys this
        relative was built from), the short way round, and the same taken continuous across the
        triangle pairs ``pairs`` (E, 2) from each piece's part that stays (the reading of which way
        round a part turns, :meth:`turning`), or, on the triangles ``free`` (bool (m,) or None),
        from the part nearest the rigid motion's turn
        (:func:`core.rotation_continuity.continuous_rotation_vectors`)."""
        # a copy of the kept vectors: the readers may keep or change it (SciPy's rotations take no
        # read-only array), and the gap's whole rotations read the kept rows after
        whole = self._whole_rotation_vectors(base, other).copy()
        continued = rotation_continuity.continuous_rotation_vectors(whole, pairs, topo.triangle_component,
                                                                    toward=self._rigid_turns(topo, base), free=free)
        return whole, continued

    def _whole_rotation_vectors(self, base: Key, other: Key) -> np.ndarray:
        """The triangles' whole rotation vectors (m, 3, read-only) from ``base`` to ``other`` (the
        keys this relative was built from), the short way round: :attr:`_whole_vectors`, made from
        the entries (:meth:`_whole_entries`, kept for :meth:`residuals_add_turn`) where not yet made."""
        vectors = self._whole_vectors
        if vectors is None:
            vectors = df.rotation_vectors_of_entries(self._whole_entries(base, other, keep=True))
            vectors.flags.writeable = False
            self._whole_vectors = vectors
        return vectors

    def let_go_whole_vectors(self) -> None:
        """Let go of :attr:`_whole_vectors` (24 bytes per triangle), once the gap that read them is prepared."""
        self.__dict__.pop("_whole_vectors", None)

    def _rigid_turns(self, topo: Topology, base: Key) -> tuple:
        """Each triangle's piece's rigid rotation vector (m, 3) (the screw's, unwrapped as the
        sequence reads it) and the triangles' areas in ``base``: what the whole rotations taken
        continuous across a piece turn nearest (``toward`` of
        :func:`core.rotation_continuity.continuous_rotation_vectors`)."""
        # one gather of whole rows (3–4× faster than indexing rows and columns together)
        return np.take(self.screw[:, :3], topo.triangle_component, axis=0), base.areas

    def residuals_add_turn(self, topo: Topology, base: Key, other: Key) -> np.ndarray:
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
        off, silently); taken whole, within 2.1e-3.

        Where the rotations are not taken continuous across the mesh (sequences), the whole
        rotations' angles are measured only where a piece's residuals' median exceeds
        :data:`SPURIOUS_RIGID_TURN` itself: angles are never negative, so elsewhere the residuals
        cannot exceed them by that much (keys 4 frames apart: 14–31 of the 23–31 relatives of a 10k
        flag, balloon, hanging sheet or banner are decided so, and their traces, arc cosines and
        medians per triangle are not made)."""
        made = self.__dict__.pop("_whole", None)  # the entries, where the pins' fits or turning made them
        residual = np.sqrt(np.einsum("ij,ij->i", self.rotvec, self.rotvec))
        pieces, count = topo.triangle_component, len(topo.components)
        residual_medians = grouped_medians(residual, pieces, count)
        across = self._across
        across_mesh = across is not None and len(across) > 0
        if not across_mesh and not (residual_medians > SPURIOUS_RIGID_TURN).any():
            if made is None:
                self.__dict__.pop("_plane_frames", None)  # let go, as measuring them would
            return np.zeros(count, dtype=bool)
        frames = self._turned_frames(other) if made is None else None
        whole = rotation_angles(frames, base.column_rows) if made is None else df.entries_rotation_angles(made)
        out = residual_medians > grouped_medians(whole, pieces, count) + SPURIOUS_RIGID_TURN
        if not across_mesh:
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

    def whole_rotations(self, topo: Topology, base: Key, other: Key, components: np.ndarray,
                        across: np.ndarray | None = None, free: np.ndarray | None = None) -> "Relative":
        """A copy whose ``rotvec`` (m, 3) are, on the triangles of the ``components`` (bool (C,)),
        the triangles' whole rotations from ``base`` to ``other`` (the keys it was built from), the
        components' rigid rotations not undone; taken continuous across the mesh past a half turn
        across this relative's triangle pairs (two poses) or ``across`` (E, 2), from the part
        nearest the rigid motion's turn on the triangles ``free`` (:meth:`continued_turns`)."""
        rows = np.flatnonzero(components[topo.triangle_component])
        kept = self._whole_vectors  # all the triangles', where continued_turns made them
        if kept is None:
            entries = self._whole_entries(base, other, rows)  # let go before the copy: it keeps none
        else:  # the frames and entries let go as reading them would
            self.__dict__.pop("_whole", None)
            self.__dict__.pop("_plane_frames", None)
        out = copy.copy(self)
        out.rotvec = self.rotvec.copy()
        out.rotvec[rows] = df.rotation_vectors_of_entries(entries) if kept is None else kept[rows]
        across = self._across if across is None else across
        if across is not None:
            out.rotvec = rotation_continuity.continuous_rotation_vectors(out.rotvec, across, topo.triangle_component,
                                                                         toward=self._rigid_turns(topo, base), free=free)
        out.whole = components
        return out
