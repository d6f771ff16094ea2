"""The pieces' rigid motions across a gap and their placement (paper §7.3 fixes shapes up to a rigid
motion): each component's interpolated screw motion (flying bodies turned about their point,
jointed pieces about their joints, the pieces of one rigid body by one motion), and where the
Poisson solve leaves a component free, its centroid placed along that motion, its keys' centroid
spline, its best similarity's path or with the rigid piece it sits on. Mixed into
:class:`core.inbetween_solver.Gap`, whose data it reads (``topo``, ``base``, ``next``,
``relatives``, ``splines``, ``flying``, ``joints``, ``bodies``, ``body_members``, ``rigidity``,
``nonrigidity``, ``cubic``, ``_motions``, ``_joint_spline_settings``) with the anchor's ``by_centroid``."""

from __future__ import annotations

import numpy as np

from . import deformation_fields as df
from . import screw_motions
from .cached_property import cached_property
from .inbetween_joints import composed, joint_screws
from .splines import ScrewGap

#: Components without anchored vertices are placed by their centroid: along the screw motion of
#: their best rigid motion where they move rigidly (exact for any rigid motion, pieces turning
#: about a common pivot stay together), along the spline of the keys' centroids where they deform
#: (free-falling cloth: the centroid follows its own trajectory, not the rotation's arc), mixed
#: linearly in between by the component's non-rigidity (RMS misfit of the best rigid motion over
#: the gap's keys / the component's bounding-box diagonal) relative to this scale.
RIGID_PLACEMENT_SCALE = 1e-3
#: ... except where the piece's best similarity (its best rigid motion times a uniform scale, the
#: scale fitted too) between the two keys leaves a misfit well under how far its centroid's path
#: along that similarity (the spiral ``exp(s log S)``; a screw motion for a rigid one) departs from
#: the centroid spline half-way: a piece turned 60° whose vertices carry noise or the rounding of a
#: single-precision cache (non-rigidity over RIGID_PLACEMENT_SCALE) was placed on the chord of its
#: arc, 5.4e-2 of the diagonal off at 0.5 and 0.45 at ×2 for noise of 5e-4 of it; a head scaled by
#: 1.02 with its eyes, each on its own chord, had the eyes 2e-2 out of their sockets. There the
#: centroid follows the similarity by the share ``1 − (ARC_PLACEMENT_MISFIT · misfit / departure)²``
#: (at least 0): noise of RMS ε leaves the centroid at most ARC_PLACEMENT_MISFIT · ε off the arc
#: (less the smaller ε), while a cloth that deforms by as much as half its centroid's departure
#: from the chord keeps the spline (docs/inbetween-measurements.md, *Nearly rigid and similar pieces, and what
#: carries what*).
ARC_PLACEMENT_MISFIT = 2.0
#: ... and wholly only where its best similarity misses it by at most the first share of its size
#: (noise, rounding), not at all from the second on (linearly between): a piece missed by that much
#: deforms, and its centroid keeps its own path however far it travels (free-falling cloth, above).
SIMILAR_SHAPE_MISFIT = (1e-2, 3e-2)

#: Factors whose rigid motions a gap keeps (:meth:`PieceMotion.motion`, and its riding sets' in
#: :meth:`~core.inbetween_anchor.Anchor.ride`): a batch of in-betweens asks for its factors, 0,
#: 1, 1e-4, 1 − 1e-4 and 0.5 (20 at keys 16 apart). The cache is emptied when full: it holds
#: C × 96 bytes per factor, and a gap lives as long as its interpolator (two poses asked for 300
#: factors held 29 MB at 1,000 pieces).
MOTION_CACHE = 32


def per_factor(cache: dict, s: float, compute):
    """``compute(s)``, kept in ``cache`` {factor: value} (emptied when it holds
    :data:`MOTION_CACHE` factors; one call, as threads share it: a factor asked again is recomputed)."""
    known = cache.get(s)
    if known is None:
        if len(cache) >= MOTION_CACHE:
            cache.clear()
        known = cache[s] = compute(s)
    return known


class PieceMotion:
    """The rigid motions' part of a gap: the pieces' motions at a factor and their placement."""

    def piece_moves(self, relatives: list) -> np.ndarray:
        """How far each component (C,) moves over the gap's keys: the sum over ``relatives`` of
        its vertices' RMS move from the base key, in the world. Positions do not alias as turns
        do: a link turning 300° between keys reads as a turn of 60° the other way, but its
        vertices still sweep round."""
        topo, base = self.topo, self.base.vertices
        owner = topo.vertex_owner
        counts = np.maximum(np.bincount(owner[owner >= 0], minlength=len(topo.components)), 1)
        total = np.zeros(len(topo.components))
        for r in relatives:
            moved = np.einsum("ij,ij->i", r.world - base, r.world - base)
            total += np.sqrt(np.bincount(owner[owner >= 0], moved[owner >= 0], minlength=len(topo.components)) / counts)
        return total

    def motion(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """The components' interpolated rigid motions at factor ``s``: rotations (C, 3, 3),
        translations (C, 3); the flying pieces (:func:`~core.inbetween_flight.flying_groups`) turned about their group's
        point on the spline of its positions at the keys. Computed once per factor (a pose, its
        guide, checks and predictions ask for the same few; copies: callers may change them), at
        most :data:`MOTION_CACHE` factors held."""
        known = per_factor(self._motions, s, self._motion)
        return known[0].copy(), known[1].copy()

    def _motion(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        return self._jointed_motion(s, self.joints, None if self.joints is None else self.splines["joint_screw"])

    def hung_motions(self, joints: tuple, factors) -> list[tuple[np.ndarray, np.ndarray]]:
        """The components' interpolated rigid motions (rotations (C, 3, 3), translations (C, 3)) at
        each of ``factors`` as :meth:`motion` places them, but with the joint tree ``joints``
        (``(parents (C,), order)``, parents first): the gap's own (:attr:`joints`), or its groups hung
        from other roots, each jointed piece's screw relative to its parent splined across the keys
        as the gap splines its own tree's (:func:`core.inbetween_joints.joint_screws`). What the
        keys leave a choice of carrier to, compared (:func:`core.inbetween_joint_doubts._carriers_untold`)."""
        if self.joints is not None and joints[0] is self.joints[0]:
            return [self.motion(s) for s in factors]
        spline = self._joint_spline(joints[0])
        return [self._jointed_motion(s, joints, spline) for s in factors]

    def _joint_spline(self, parents: np.ndarray) -> ScrewGap:
        """Each jointed piece's screw relative to its parent (``parents`` (C,), −1 for roots and
        unjointed pieces) at the gap's keys (:func:`core.inbetween_joints.joint_screws`), splined as
        the pieces' own screws are (about points fixed in their frames: ``pivoted``)."""
        frames, slowing, options = self._joint_spline_settings
        relatives = self.relatives
        return ScrewGap(joint_screws(parents, [r.screw for r in relatives], [r.extrapolated for r in relatives],
                                     [getattr(r, "motion", None) for r in relatives]),
                        frames, self.cubic, slowing, pivoted=True, **options)

    def _jointed_motion(self, s: float, joints: tuple | None, joint_screw) -> tuple[np.ndarray, np.ndarray]:
        # the pieces' own screws (flying ones about their point), composed along ``joints`` with the
        # spline of the jointed pieces' screws relative to their parents (``joint_screw``: ScrewGap)
        motion = screw_motions.rigid_exps(self.splines["screw"].at(s))
        if self.flying is not None:  # turned about each group's point, which follows its spline
            labels, points = self.flying
            rotations, translations = motion
            rows = np.flatnonzero(labels >= 0)
            translations[rows] = self.splines["flying"].at(s)[rows] - np.einsum(
                "cab,cb->ca", rotations[rows], points[labels[rows]])
        if joints is not None:
            motion = composed(*joints, *motion, screw_motions.rigid_exps(joint_screw.at(s)))
        if self.body_members is not None:  # a body that turns or hangs from a joint: its leader's motion (core.rigid_bodies)
            rotations, translations = motion
            members, leaders = self.body_members, self.bodies[self.body_members]
            rotations[members], translations[members] = rotations[leaders], translations[leaders]
        return motion

    def place(self, x: np.ndarray, s: float, motion, partly: bool = False) -> np.ndarray:
        """Components without anchored vertices moved to their interpolated centroid (see
        :data:`RIGID_PLACEMENT_SCALE`); with ``partly``, instead those the anchor barely holds,
        by their share ``by_centroid`` of the way (see :meth:`~core.inbetween_anchor.Anchor.centroid_placement`),
        but for the riders of :class:`core.inbetween_carried.CarriedPieces`, which their seat places."""
        rotations, translations = motion
        share = self.by_centroid
        # partly: riders are moved by their share toward their seat's place instead (place_riders)
        moved = ((0.0 < share) & (share < 1.0) & ~self.carried.riding) if partly else share == 1.0
        if partly:
            held = self.held_on_seats()
            moved |= held
            share = np.where(held, 1.0, share)
        if not moved.any():
            return x
        topo = self.topo
        rigid = np.einsum("cab,cb->ca", rotations, self.base.centroids) + translations
        spline = self.splines["centroids"].at(s)
        trust = self.similar_placement[0]
        if (trust > 0.0).any():  # nearly rigid or similar pieces: along their similarity (ARC_PLACEMENT_MISFIT)
            spline = trust[:, None] * self.similarity_path(s) + (1.0 - trust[:, None]) * spline
        seated, seat, miss = self.seated_placement
        if seated.any():  # deforming pieces sitting on a rigid one: with it (CarriedPieces, the other way)
            k = seat[seated]
            offset = self.base.centroids[seated] - self.base.centroids[k]
            spline[seated] = rigid[k] + np.einsum("cab,cb->ca", rotations[k], offset) + s * miss[seated]
        target = self.rigidity[:, None] * rigid + (1.0 - self.rigidity[:, None]) * spline
        move = target - topo.centroids(x)
        root = self.turning_root
        if root is not None:
            # a piece a part of which turns far from the rest (gap.turning): the keys' centroids
            # sample a loop (its tip curls 140-340 degrees per gap), which their spline cuts; the
            # part the rest turns from moves as the keys' per-vertex spline in the world says
            rows = np.flatnonzero(root)
            owner, mass = topo.vertex_owner[rows], topo.mass[rows]
            offset = (self.splines["world"].at(s, rows) - x[rows]) * mass[:, None]
            held = np.bincount(owner, mass, minlength=len(move))
            sums = np.stack([np.bincount(owner, offset[:, k], minlength=len(move)) for k in range(3)], axis=1)
            move[held > 0] = sums[held > 0] / held[held > 0, None]
        move = np.where(moved[:, None], share[:, None] * move, 0.0)
        rows = topo.component_vertices[moved[topo.component_labels]]
        x[rows] += move[topo.vertex_component[rows]]
        return x

    def held_on_seats(self) -> np.ndarray:
        """Per component (C,), whether it sits on a rigid piece (:attr:`seated_placement`) at least
        :data:`~core.inbetween_carried.RIDER_SIZE` times its size while the blend anchor of an
        in-between of two poses holds it (``by_centroid`` below 1) and none of its vertices is
        still: :meth:`place` then moves it all the way to where its seat takes its centroid, since
        the blend's chord cuts the seat's arc (an eye blinking in a head turned 30°, held on 0.7 %
        of its mass, came 9 % of its radius out of its socket half-way; shrunk to 0.3 of its size
        in one key and held wholly, 16 %). Never on a seat about as large: a sheet lying on another
        one that barely deforms keeps the blend's hold (the seat tells the small piece's place, not
        a piece's as large as itself)."""
        from .inbetween_carried import RIDER_SIZE  # noqa: PLC0415

        seated, seat, _ = self.seated_placement
        if not (self.anchored and seated.any()):
            return np.zeros(len(seated), dtype=bool)
        size = self.base.diagonals
        seated = seated & (size[seat] >= RIDER_SIZE * size)
        return seated & ~self.still_components & (self.by_centroid < 1.0) & ~self.carried.riding

    def place_riders(self, x: np.ndarray, s: float) -> np.ndarray:
        """``x`` (n, 3), a pose at factor ``s``, with the riders of
        :class:`core.inbetween_carried.CarriedPieces` (deforming pieces sitting on larger deforming
        ones) translated by their share ``by_centroid`` of the way to their centroid's place: along
        their best similarity by the share that :attr:`similar_placement` trusts it (exact for a
        piece scaled with its seat), where their seat puts them for the rest (instead of their
        centroid's spline, which the seat's shape leaves: :data:`core.inbetween_carried.RIDER_SIZE`)."""
        placed = self.carried.rider_places(x, s)
        if placed is None:
            return x
        components, seated = placed
        share = self.by_centroid[components]
        if not (share > 0.0).any():  # held by the anchor (sequences)
            return x
        trust = self.similar_placement[0][components]
        if (trust > 0.0).any():
            seated = trust[:, None] * self.similarity_path(s)[components] + (1.0 - trust[:, None]) * seated
        topo = self.topo
        moved = np.zeros(len(topo.components), dtype=bool)
        moved[components[share > 0.0]] = True
        move = np.zeros((len(topo.components), 3))
        move[components] = share[:, None] * (seated - topo.centroids(x)[components])
        rows = topo.component_vertices[moved[topo.component_labels]]
        x[rows] += move[topo.vertex_component[rows]]
        return x

    @cached_property
    def similar_placement(self) -> tuple[np.ndarray, tuple]:
        """Per component, the share (C,) of its centroid placement taken along the path of its best
        similarity from the base key to the next (:data:`ARC_PLACEMENT_MISFIT`) and that similarity:
        rotation vectors (C, 3) (its best rigid motion's, as the screw spline turns it), log-scales
        (C,) and translations (C, 3). The scale of the best similarity with the rigid motion's
        rotation (the same rotation is the best for both) is ``Σ w (R b̃)·õ / Σ w |b̃|²`` over the
        vertices' offsets from their centroids ``b̃`` (base) and ``õ`` (next)."""
        topo, count = self.topo, len(self.topo.components)
        none = np.zeros(count)
        nxt = self.relatives[2]
        rotations = getattr(nxt, "motion", (None,))[0]
        if not count or rotations is None or getattr(nxt, "extrapolated", False):
            return none, (np.zeros((count, 3)), none, np.zeros((count, 3)))
        owner = np.maximum(topo.vertex_owner, 0)
        c0, c1 = self.base.centroids, nxt.centroids
        b = self.base.vertices - c0[owner]
        o = self.next.vertices - c1[owner]
        turned = topo.apply_motion(b, rotations, np.zeros((count, 3)))
        spread = topo.component_sums(np.einsum("ij,ij->i", b, b))
        scale = topo.component_sums(np.einsum("ij,ij->i", turned, o)) / np.maximum(spread, np.finfo(float).tiny)
        positive = scale > 0.0
        scale = np.where(positive, scale, 1.0)
        residual = scale[owner][:, None] * turned - o
        misfit = np.sqrt(topo.component_sums(np.einsum("ij,ij->i", residual, residual)) / topo.component_mass)
        rotvec = np.asarray(nxt.screw)[:, :3] if len(np.shape(nxt.screw)) == 2 else df.rotation_vectors(rotations)
        rotated = np.einsum("cab,cb->ca", screw_motions.rigid_exps(np.c_[rotvec, np.zeros((count, 3))])[0], c0)
        similarity = (rotvec, np.log(scale), c1 - scale[:, None] * rotated)
        half, ok = screw_motions.similarity_paths(*similarity, c0, 0.5)
        departure = np.linalg.norm(half - self.splines["centroids"].at(0.5), axis=1)
        ratio = ARC_PLACEMENT_MISFIT * misfit / np.maximum(departure, np.finfo(float).tiny)
        # ... and only pieces nearly similar in shape: the departure grows with how far a piece
        # travels, its misfit does not (a sheet crumpling while thrown 10 units and turning 60°,
        # misfit 0.038 of its diagonal, was pulled onto the arc, 0.65 of its size off its path)
        low, high = SIMILAR_SHAPE_MISFIT
        shape = np.clip((high - misfit / np.maximum(self.base.diagonals, np.finfo(float).tiny)) / (high - low), 0.0, 1.0)
        # ratio ≥ 1 gives no share (capped first: a centroid that does not depart at all, as a piece
        # mirrored about it, made the square overflow)
        trust = np.where(positive & ok & np.isfinite(ratio), (1.0 - np.minimum(ratio, 1.0) ** 2) * shape, 0.0)
        return trust, similarity

    @cached_property
    def seated_placement(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per component, whether its centroid placement follows a rigid piece it sits on (bool
        (C,)), that piece (C,) and what of its own centroid's move that piece's rigid motion misses
        between the keys (C, 3; :meth:`place` adds that share ``s`` of it): an eye that deforms
        (blinks) in a head turned rigidly, a garment's separate piece on a rigid body, placed
        otherwise on its centroid's spline (two poses: the chord of the head's arc; an eye squashed
        to 0.6 of its height in a head turned 60° came 1.9e-2 of the diagonal out of its socket at
        0.5 and 0.15 at ×2). The seat is read in the first pose as the carriers of
        :class:`core.inbetween_carried.CarriedPieces` are: the component of rigid pieces (``rigidity``
        > 0, not much smaller than the piece: :data:`core.inbetween_carried.CARRIER_SIZE`) holding most
        of the nearest vertices of other pieces within the piece's diagonal; it seats the piece in a
        gap where its rigid motion takes the piece's centroid within
        :data:`core.inbetween_carried.CARRIED_TOLERANCE` of the piece's diagonal of where it is in
        the next key."""
        from . import inbetween_carried as carried  # noqa: PLC0415

        topo, count = self.topo, len(self.topo.components)
        seated, seat, miss = np.zeros(count, dtype=bool), np.zeros(count, dtype=int), np.zeros((count, 3))
        # seats: pieces rigid to within noise (a head whose keys carry noise 6e-4 of the diagonal
        # has rigidity 0, and its blinking eyes went on their chords, 5.5e-2 off at 0.5)
        rigid = self.nonrigidity < SIMILAR_SHAPE_MISFIT[0]
        if count < 2 or not rigid.any() or rigid.all():
            return seated, seat, miss
        pieces, owners = seat_candidates(topo, rigid)
        if pieces.size == 0:
            return seated, seat, miss
        rotations, translations = self.relatives[2].motion
        c0, c1 = self.base.centroids, self.relatives[2].centroids
        missed = c1[pieces] - (np.einsum("cab,cb->ca", rotations[owners], c0[pieces]) + translations[owners])
        held = np.linalg.norm(missed, axis=1) <= carried.CARRIED_TOLERANCE * self.base.diagonals[pieces]
        seated[pieces[held]], seat[pieces[held]], miss[pieces[held]] = True, owners[held], missed[held]
        return seated, seat, miss

    def similarity_path(self, s: float) -> np.ndarray:
        """Each component's centroid (C, 3) at factor ``s`` along its best similarity between the
        keys (:attr:`similar_placement`; :func:`core.screw_motions.similarity_paths`)."""
        return screw_motions.similarity_paths(*self.similar_placement[1], self.base.centroids, s)[0]


def seat_candidates(topo, rigid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The deforming pieces that may sit on a rigid one and that piece, index arrays (p,) each,
    for the components ``rigid`` (bool (C,); some rigid, some not) of ``topo``
    (:attr:`PieceMotion.seated_placement`): per deforming piece, the rigid piece (not much smaller:
    :data:`core.inbetween_carried.CARRIER_SIZE`) holding most of the nearest vertices of rigid
    pieces to its vertices within its diagonal in the first pose, where they are at least
    :data:`core.inbetween_carried.MIN_CARRIERS`. Read in the first pose alone, the same in every gap
    whose rigid pieces are these: kept on ``topo`` per set of rigid pieces (the search from one
    sheet to another lying apart over it, 5k vertices each, takes 110–150 ms)."""
    known = topo.seat_candidates.get(rigid.tobytes())
    if known is not None:
        return known
    from . import inbetween_carried as carried  # noqa: PLC0415
    from .nearest_points import nearest_points, point_tree  # noqa: PLC0415

    count = len(topo.components)
    first = topo.first_pose
    size = topo.diagonals(first)
    holders = topo.component_vertices[rigid[topo.component_labels]]
    rows = topo.component_vertices[~rigid[topo.component_labels]]
    label = topo.vertex_component[rows]
    reach = carried.CARRIER_REACH * size
    # every deforming piece's vertices at once (meshes of many pieces: no loop per piece); equally
    # near holders taken by index, whatever the tree
    distance, nearest = nearest_points(point_tree(first[holders]), first[rows], carried.CARRIER_NEIGHBOURS,
                                       float(reach[~rigid].max()))
    found = np.isfinite(distance) & (distance < reach[label][:, None])
    piece = np.broadcast_to(label[:, None], found.shape)[found]
    owner = topo.vertex_component[holders[nearest[found]]]
    large = size[owner] >= carried.CARRIER_SIZE * size[piece]
    piece, owner = piece[large], owner[large]
    pieces = owners = np.zeros(0, dtype=int)
    if piece.size:
        pairs, votes = np.unique(piece * count + owner, return_counts=True)
        pair_piece, pair_owner = np.divmod(pairs, count)
        best = np.lexsort((-votes, pair_piece))  # per piece, the owner holding most of its nearest first
        first_of = best[np.r_[True, pair_piece[best][1:] != pair_piece[best][:-1]]]
        enough = votes[first_of] >= carried.MIN_CARRIERS  # nearest vertices on the chosen seat itself
        pieces, owners = pair_piece[first_of][enough], pair_owner[first_of][enough]
    topo.seat_candidates[rigid.tobytes()] = pieces, owners
    return pieces, owners
