"""Rigid pieces carried by deforming ones: an eye in a bending head, a button on a cloth.

A connected component that moves rigidly between a gap's keys is placed by its own interpolated
rigid motion (:data:`core.inbetween_motion.RIGID_PLACEMENT_SCALE`), while a deforming component
next to it follows its fields and the keys' spline: the two paths part between the keys, and a
piece that sits on another one leaves it. Where it sits is read in the first key: its seat is the
nearest vertices of deforming components there (the cloth under a button, the socket around an
eye). In a gap where the seat's best rigid motion from the base key to the next takes the piece
near where it is in the next key (against its size, more for a seat that turns far), or where the piece touches
its seat and turns about a point of their contact (a hand at the wrist of a bending forearm,
:func:`core.inbetween_joints.joint_offset`), the seat carries it: at every factor the piece takes
the seat's best rigid motion from the base key to the pose, times the part of its own motion the
seat misses (interpolated, so that both keys are met exactly). Elsewhere the piece keeps its own
motion. Rigid pieces jointed to a carried one that no seat carries (glasses on a head riding on a
torso) move with it.

Measured (docs/inbetween-measurements.md, *Pieces carried by deforming ones*): a hand (a separate sphere) on a
forearm bent by 100°, two poses: off the forearm's end by 0.37–0.57 % of the diagonal in-between
and 3.9 % at ×2, now 2e-8 / 2e-7; six buttons on benchmark cloths, keys 16 frames apart, median
distance off the cloth under them: hanging sheet 1.53 → 0.004 mean edge lengths, banner 5.50 →
0.11, drape 0.84 → 0.018.
"""

from __future__ import annotations

import numpy as np

from . import deformation_fields as df
from . import screw_motions
from .geometry import nearest_rotations
from .inbetween_joints import JOINT_REACH, joint_groups, joint_offset, relative_motion
from .nearest_points import nearest_points, point_tree
from .rigid_alignment import group_covariances, rigid_alignment, rigid_alignments

#: A rigid piece's seat: for each of its vertices the nearest few vertices of deforming components
#: in the first key, those within this many of the piece's bounding-box diagonals of it (0.5 missed
#: sequins modelled 0.6 of their size above the cloth) ...
CARRIER_REACH = 1.0
CARRIER_NEIGHBOURS = 3
#: ... carries it in a gap if its best rigid motion from the base key to the next takes the piece
#: within this fraction of its diagonal of where it is in the next key (six buttons on the banner,
#: keys 16 apart, median distance off the cloth: 0.05: 2.69 mean edge lengths, 0.25: 0.11, 0.5: 0.10;
#: a piece that moves on its own misses by more than its size).
CARRIED_TOLERANCE = 0.25
#: ... plus this share of the piece's diagonal per radian its seat turns between the keys: a seat
#: fitted to skin weighted to several bones misses by more the farther it turns — a belt buckle
#: 0.104 across on a character's hips turning 91° between keys 8 frames apart, missed by 0.050
#: (0.48 of its diagonal; allowed now 0.25 + 1.0 × 1.59 = 1.84 of it); kept on its own screw its offset
#: from the hips was 0.065 off, the linear blend's 0.009. Independent of where the mesh is and how
#: far it travels (a share of the piece's own move, tried first, carried a ball moving 0.6 on its
#: own along a strip that translated 20).
CARRIED_SHARE = 1.0
#: ... and, beyond a quarter of its diagonal, at most this share of how far the seat's turn moves the
#: piece about the carriers' centroid: a ball on the axis of a sheet spinning 170° beside it, moving
#: 0.6 on its own, was missed by less than the turn's allowance and swung along the sheet's arc
#: (0.66 of its diagonal off half-way). The buckle: 0.014 off at keys 8 apart (0.007 without this
#: limit, the blend 0.009).
CARRIED_TURN_SHARE = 0.5
#: Fewest carriers, and their least spread: the second singular value of their centred positions
#: over their first (collinear carriers leave a turn about their line free) and over the piece's
#: diagonal (a turn read off a speck moves the piece's far end by the speck's error times their
#: ratio). One test of 0.05 of the piece's diagonal instead would miss a sword 0.70 long in a hand whose
#: 16 carriers spread 0.035 / 0.032: ×2 of a wave would leave it 0.11 from the hand
#: (the simulated 0.008); carried, 0.009 (its offset from the hand 0.18 → 0.026 off).
#: Carriers come only from deforming components whose bounding-box diagonal (first key) is at
#: least this share of the piece's own: a button rides on its cloth, a hand or a sword as long as
#: the arm on the forearm, never a head on its eyes (a head turned rigidly with two noisy eyes, each
#: 0.2 of its diagonal, followed their fit: 5.4e-2 of the diagonal off at 0.5 and 0.45 at ×2; kept
#: on its own motion, exact).
CARRIER_SIZE = 0.5
MIN_CARRIERS = 4
MIN_CARRIER_SPREAD = 0.05
MIN_CARRIER_SIZE = 0.01
#: A deforming piece the anchor leaves to its centroid's placement (wholly or in part, ``by_centroid``:
#: an eye or a tooth squashed with a head, exaggerated) rides on deforming pieces at least this
#: many times its size (bounding-box diagonal, first key), its seat chosen and checked as a rigid
#: piece's is: its centroid goes where the seat's best similarity from the base key to the pose
#: takes it, plus the share ``s`` of where it sits against the seat in the next key, instead of
#: along the keys' straight line, which the seat's interpolated shape leaves (its own shape is
#: kept; :meth:`core.inbetween_motion.PieceMotion.place_riders`). The point placed so is the
#: mean of the part the seat holds over the gap (:meth:`CarriedPieces._rider_contacts`), all of a
#: rider that moves with its seat, the root of a tail that curls on it. A squashed head's eyes were
#: 7.2e-3 / 1.8e-2 of the diagonal off their sockets at ×1.5 / ×2 (the slider 5.1e-4 / 1.3e-3).
#: Never on a piece about as large (the two sheets of a cloth lying on each other, 2.72 and 2.47
#: across: each would be placed by the other).
RIDER_SIZE = 2.0


class CarriedPieces:
    """The rigid pieces of one gap (a ``core.inbetween_solver.Gap``) that deforming pieces carry:
    per piece its vertices (k,), its carriers (j,) and the residual rigid motion (screw (6,)) from
    the carriers' motion at the next key to the piece's own."""

    def __init__(self, gap):
        self.pieces: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        topo, base, nxt = gap.topo, gap.base.vertices, gap.next.vertices
        self.riding = np.zeros(len(topo.components), dtype=bool)  # the components of the riders kept
        self._followers = None  # the rigid pieces jointed to a carried one (see _jointed_followers)
        self.base = base
        self.topo = topo
        if len(topo.components) < 2:
            return
        rigid = gap.rigidity > 0.0  # moves rigidly across the gap's keys (RIGID_PLACEMENT_SCALE)
        if rigid.all():
            return
        # deforming pieces that may ride on a deforming one at least RIDER_SIZE × their size (not
        # those a rigid piece seats: PieceMotion.seated_placement places them)
        size = topo.diagonals(topo.first_pose)
        riders = ~rigid & ~gap.seated_placement[0] & (RIDER_SIZE * size <= size[~rigid].max())
        if not (rigid.any() or riders.any()):
            return
        # every piece at once, its vertices in component order (a loop cost ~0.6 ms per piece: 2,000
        # sequins on a dress, 1.2 s per gap)
        order, labels = topo.component_order, topo.vertex_component[topo.component_order]
        deforming = order[~rigid[labels]]
        if gap.static is not None:  # still in every key: pinned where it is
            still = np.bincount(labels, gap.static[order], minlength=rigid.size)
            rigid = rigid & (still < np.bincount(labels, minlength=rigid.size))
        pieces = np.flatnonzero(rigid | riders)
        if not pieces.size:
            return
        chosen = (rigid | riders)[labels]
        rows, piece = order[chosen], np.searchsorted(pieces, labels[chosen])  # piece: index among ``pieces``
        own = rigid_alignments(base[rows], nxt[rows], piece, pieces.size)
        # deforming components much smaller than a rigid piece carry none of it (CARRIER_SIZE), a
        # rider only those at least RIDER_SIZE × its size
        least = np.where(riders[pieces], RIDER_SIZE, CARRIER_SIZE) * size[pieces]
        large = size[topo.vertex_component[deforming]] >= least.min()
        deforming = deforming[large]
        if not deforming.size:
            return
        seats = self._seats(topo.first_pose, base, nxt, rows, piece, pieces.size, deforming,
                            point_tree(topo.first_pose[deforming]), own, JOINT_REACH * gap.mean_edge,
                            (size[topo.vertex_component[deforming]], least))
        groups = np.split(rows, np.flatnonzero(np.diff(piece)) + 1)
        ridden = self._ridden(gap, base, nxt, own) & rigid[pieces]
        kept = [(k, carriers, motion) for k, (carriers, motion) in enumerate(seats)
                if carriers is not None and not ridden[k]]
        if kept and gap.joints is not None:
            # a piece jointed to a rigid one at least CARRIER_SIZE × its size that no deforming piece
            # carries moves as one with it (an eye in the socket of a rigid head, whichever of them
            # the joint tree hangs from the other), not with a deforming piece beside it (the other
            # eye shrinking shut: 0.35–0.46 % of the diagonal off at 0.5, 0.6–4 % at ×2)
            groups_of = joint_groups(gap.joints[0])
            chosen = np.zeros(len(groups_of), dtype=bool)
            chosen[pieces[[k for k, _, _ in kept]]] = True
            largest = np.zeros(len(groups_of))  # per joint group, its largest piece not carried
            np.maximum.at(largest, groups_of[~chosen], size[~chosen])
            kept = [(k, carriers, motion) for k, carriers, motion in kept
                    if largest[groups_of[pieces[k]]] < CARRIER_SIZE * size[pieces[k]]]
        if kept and gap.bodies is not None:
            kept, own = _bodies_carried(kept, gap.bodies[pieces], groups, base, nxt, own)
        if not kept:
            return
        index = np.array([k for k, _, _ in kept])
        seat_rotations = np.array([motion[0] for _, _, motion in kept])
        seat_translations = np.array([motion[1] for _, _, motion in kept])
        # each piece's own motion after its carriers' undone: applied in part at each factor
        inverse = np.transpose(seat_rotations, (0, 2, 1))
        relative = (inverse @ own[0][index], np.einsum("pab,pb->pa", inverse, own[1][index] - seat_translations))
        screws = screw_motions.rigid_logs(*relative)
        self.pieces = [(groups[k], carriers, screw) for (k, carriers, _), screw in zip(kept, screws)]
        rows, carriers, screws = zip(*self.pieces)  # concatenated for place(): vertices, carriers, base fit
        self._rows = np.concatenate(rows)
        self._row_piece = np.repeat(np.arange(len(rows)), [r.size for r in rows])
        self._carriers = np.concatenate(carriers)
        self._counts = np.array([c.size for c in carriers])
        self._starts = np.r_[0, np.cumsum(self._counts)[:-1]]
        seated = base[self._carriers]
        self._base_mean = np.add.reduceat(seated, self._starts, axis=0) / self._counts[:, None]
        self._base_centred = seated - np.repeat(self._base_mean, self._counts, axis=0)
        self._screws = np.array(screws)
        # riders (their index among the pieces kept and their component): their contact with their
        # seat (_rider_contacts) about the seat's mean in the base key, and its move to where that
        # contact in the next key sits in the coordinates of their seat's best similarity from the
        # base key to it
        self._riders = np.flatnonzero(riders[pieces[index]])
        self._rider_components = pieces[index[self._riders]]
        self.riding[self._rider_components] = True
        self._rigid_rows = ~riders[pieces[index]][self._row_piece]
        self._followers = self._jointed_followers(gap, pieces[index], riders[pieces[index]], size)
        if self._riders.size:
            similarities = self._seat_similarities(nxt)  # made once: the contacts read it too
            self._contacts = self._rider_contacts(base, nxt, similarities, JOINT_REACH * gap.mean_edge)
            _, rotations, scales, means = similarities
            rotations, scales, means = rotations[self._riders], scales[self._riders], means[self._riders]
            self._rider_starts = self._contact_points(base) - self._base_mean[self._riders]
            ends = self._contact_points(nxt) - means
            self._rider_offsets = np.einsum("pji,pj->pi", rotations, ends) / scales[:, None] - self._rider_starts

    def _rider_contacts(self, base: np.ndarray, nxt: np.ndarray, similarities: tuple,
                        reach: float) -> tuple[np.ndarray, ...]:
        """Each rider's contact with its seat in the gap: its vertices that the seat's best
        similarity from the base key to the next (``base``, ``nxt``: positions (n, 3);
        ``similarities``: :meth:`_seat_similarities` of ``nxt``) takes within
        ``reach`` of the best-held one's miss, as ``(rows (c,), rider (c,) among the riders, mass
        (c,))``. A rider that deforms on its seat (a tail curling at joints along a bone) moves its
        centroid against the seat while the part the seat holds stays where it holds it:
        :meth:`rider_places` places that part, the rest of the rider follows by its shape. A rider
        that moves with its seat is held everywhere: its contact is all of it."""
        _, rotations, scales, means = similarities
        rows, rider = [], []
        for j, k in enumerate(self._riders):
            piece = self.pieces[k][0]
            moved = means[k] + scales[k] * (base[piece] - self._base_mean[k]) @ rotations[k].T
            miss = np.linalg.norm(moved - nxt[piece], axis=1)
            held = piece[miss <= miss.min() + reach]
            rows.append(held)
            rider.append(np.full(held.size, j))
        rows = np.concatenate(rows)
        return rows, np.concatenate(rider), self.topo.mass[rows]

    def _contact_points(self, x: np.ndarray) -> np.ndarray:
        """Each rider's contact (:meth:`_rider_contacts`) mass-weighted mean (R, 3) in ``x`` (n, 3)."""
        rows, rider, mass = self._contacts
        count = self._riders.size
        sums = np.stack([np.bincount(rider, mass * x[rows, d], minlength=count) for d in range(3)], axis=1)
        return sums / np.bincount(rider, mass, minlength=count)[:, None]

    def _jointed_followers(self, gap, carried: np.ndarray, riders: np.ndarray, size: np.ndarray):
        """The rigid pieces jointed to a carried one that no seat carries (glasses on a head that
        a bending torso carries; smaller than :data:`CARRIER_SIZE` × it, else the piece is not
        carried, see above), or None: ``(leaders, rows, labels, members)``, per follower set the
        index (L,) of the carried piece it follows among :attr:`pieces` (the largest carried rigid
        piece of its joint group, :func:`~core.inbetween_joints.joint_groups`), and their vertices
        (r,) with each one's set (r,; among ``leaders``) and piece (r,; 0, 1, … in order). Placed
        by the joint tree about the piece's own motion, they part from the piece that its seat
        moves; :meth:`place` moves them with it. Pinned pieces keep their pins."""
        if gap.joints is None:
            return None
        groups_of = joint_groups(gap.joints[0])
        rigid = ~riders
        lead = np.full(len(groups_of), -1)  # per joint group, the largest carried rigid piece there
        for k in np.flatnonzero(rigid)[np.argsort(-size[carried[rigid]], kind="stable")]:
            if lead[groups_of[carried[k]]] < 0:
                lead[groups_of[carried[k]]] = k
        following = lead[groups_of] >= 0
        following[carried] = False
        following &= ~gap.held_pieces() & (gap.rigidity > 0.0)
        if not following.any():
            return None
        members = np.flatnonzero(following)
        leaders, labels = np.unique(lead[groups_of[members]], return_inverse=True)
        rows = [gap.topo.components[c] for c in members]
        sizes = [r.size for r in rows]
        return leaders, np.concatenate(rows), np.repeat(labels, sizes), np.repeat(np.arange(members.size), sizes)

    @staticmethod
    def _ridden(gap, base: np.ndarray, nxt: np.ndarray, own) -> np.ndarray:
        """Per piece (P,), whether its own best rigid motion between the gap's keys (``own``:
        rotations (P, 3, 3), translations (P, 3)) takes one of the gap's riding sets (:mod:`core.pins`,
        held on their screws) to its place in the next key within the rounding the sets were
        found to: the piece moves on the bone or object the set rides on (the lower teeth and the
        skin of an opening jaw, :func:`core.pins.witnessed_riding`) and keeps its own screw with
        the set, not carried by the skin around it (whose fields missed the teeth's place in a
        jaw opened 22° by 5.7e-3 of the diagonal half-way)."""
        ridden = np.zeros(len(own[0]), dtype=bool)
        if gap.riding is None:
            return ridden
        for rows in gap.riding:
            moved = np.einsum("pab,rb->pra", own[0], base[rows]) + own[1][:, None]
            ridden |= np.max(np.linalg.norm(moved - nxt[rows], axis=2), axis=1) <= gap.riding_tolerance
        return ridden

    @staticmethod
    def _seats(first, base, nxt, rows, piece, count, deforming, tree, own, reach, sizes=None) -> list:
        """Per rigid piece (``rows`` (r,) their vertices, ``piece`` (r,) which of the ``count``
        pieces each is, consecutive), ``(carriers (j,), (rotation, translation))``: the vertices of
        deforming pieces that carry it with their best rigid motion from the gap's base key to the
        next, or ``(None, None)`` if there are too few, too collinear, or they neither move with it
        from the gap's base key to the next nor hold it at a joint (it touches them, vertices within
        ``reach``, and turns about a point of the contact: a hand turning at the wrist of a bending
        arm, :func:`_jointed`; ``own``: the pieces' best rigid motions between the keys, rotations
        (count, 3, 3) and translations (count, 3)). They are sought (with ``tree``, a k-d tree over
        the ``deforming`` vertices; equally near ones taken by index:
        :func:`core.nearest_points.nearest_points`) where the piece sits in the first key (``first``:
        positions (n, 3)), the same seat for every gap (see :data:`CARRIER_REACH`, :data:`CARRIED_TOLERANCE`,
        :data:`CARRIED_SHARE`), among those of components no smaller than ``sizes[1]`` (per piece;
        ``sizes[0]``: per ``deforming`` vertex, its component's diagonal; :data:`CARRIER_SIZE`)."""
        starts = np.flatnonzero(np.r_[True, np.diff(piece) != 0])
        extent = np.maximum.reduceat(base[rows], starts) - np.minimum.reduceat(base[rows], starts)
        diagonal = np.sqrt(np.einsum("ij,ij->i", extent, extent))
        reachable = CARRIER_REACH * diagonal
        if not reachable.max() > 0:
            return [(None, None)] * count
        # the nearest few within the largest reach, then within each piece's own (the same sets);
        # a piece with fewer than MIN_CARRIERS so (one smaller than the edges under it: a scan's
        # floater 0.15 of an edge across, 0.6 of one off the surface) whose nearest carrier is within
        # its reach or an edge (``reach``) looks again within an edge beyond that carrier
        distance, nearest = nearest_points(tree, first[rows], max(CARRIER_NEIGHBOURS, MIN_CARRIERS),
                                           max(reachable.max(), 2.0 * reach))

        def pairs(found):  # piece × deforming.size + carrier, of the usable neighbours ``found``
            if sizes is not None:
                found[found] = sizes[0][nearest[found]] >= sizes[1][piece[np.nonzero(found)[0]]]
            return np.unique(np.broadcast_to(piece[:, None], found.shape)[found] * deforming.size + nearest[found])

        within = np.isfinite(distance) & (distance < reachable[piece][:, None])
        pair = pairs(within & (np.arange(distance.shape[1]) < CARRIER_NEIGHBOURS))
        nearest_carrier = np.minimum.reduceat(distance[:, 0], starts)  # per piece (inf: none within the bound)
        short = (np.bincount(pair // deforming.size, minlength=count) < MIN_CARRIERS) \
            & (nearest_carrier <= np.maximum(reachable, reach))
        if short.any():
            pair = np.union1d(pair, pairs(np.isfinite(distance) & short[piece][:, None]
                                          & (distance <= (nearest_carrier + reach)[piece][:, None])))
        # by piece, then in the order ``deforming`` lists them
        seat_piece, carriers = pair // deforming.size, deforming[pair % deforming.size]
        counts = np.bincount(seat_piece, minlength=count)
        seated = base[carriers]
        # the carriers' scatter about their centroid, and that centroid, per piece
        scatter, centre = group_covariances(seated, seated, seat_piece, count, np.ones(len(seated)))[:2]
        # the singular values of the centred carriers (RMS over them): second against first and size
        singular = np.sqrt(np.maximum(np.linalg.eigvalsh(scatter), 0.0) / np.maximum(counts, 1)[:, None])
        usable = (diagonal > 0) & (counts >= MIN_CARRIERS) & (singular[:, 1] >= MIN_CARRIER_SPREAD * singular[:, 2]) \
            & (singular[:, 1] >= MIN_CARRIER_SIZE * diagonal)
        rotations, translations = rigid_alignments(seated, nxt[carriers], seat_piece, count)
        moved = np.einsum("rab,rb->ra", rotations[piece], base[rows]) + translations[piece]
        miss = np.abs(moved - nxt[rows]).max(axis=1)
        worst = np.maximum.reduceat(miss, starts)
        # a seat turning far is fitted to carriers that deform with it: its miss may grow with the
        # turn, while staying a small share of how far the turn itself moves the piece about the
        # carriers (a piece moving on its own is missed by about all of that, wherever it is)
        turned = np.linalg.norm(df.rotation_vectors(rotations), axis=1)
        about = base[rows] - centre[piece]
        swung = np.maximum.reduceat(np.linalg.norm(
            np.einsum("rab,rb->ra", rotations[piece], about) - about, axis=1), starts)
        allowed = np.maximum(CARRIED_TOLERANCE * diagonal, np.minimum(
            (CARRIED_TOLERANCE + CARRIED_SHARE * turned) * diagonal, CARRIED_TURN_SHARE * swung))
        groups = np.split(carriers, np.cumsum(counts)[:-1])
        ends = np.r_[starts[1:], rows.size]
        out = []
        for k in range(count):
            if not usable[k]:
                out.append((None, None))
                continue
            motion = (rotations[k], translations[k])
            if worst[k] > allowed[k] and not _jointed(
                    base, rows[starts[k]:ends[k]], groups[k], motion, (own[0][k], own[1][k]), reach):
                out.append((None, None))
                continue
            out.append((groups[k], motion))
        return out

    def place(self, x: np.ndarray, s: float) -> np.ndarray:
        """``x`` (n, 3), a pose at factor ``s``, with each carried rigid piece moved by its carriers'
        best rigid motion from the base key to ``x``, times its residual motion at ``s``: every
        piece at once (one batched Kabsch fit: meshes with hundreds of carried pieces)."""
        if not self.pieces or not self._rigid_rows.any():
            return x
        if not np.isfinite(x[self._carriers]).all():
            return x  # a failed solve: reported as it is
        translations, rotations, _, _ = self._seat_similarities(x)
        residual_rotations, residual_translations = screw_motions.rigid_exps(s * self._screws)
        total = rotations @ residual_rotations
        shift = np.einsum("pij,pj->pi", rotations, residual_translations) + translations
        rows, piece = self._rows[self._rigid_rows], self._row_piece[self._rigid_rows]
        before = x[rows]
        x[rows] = np.einsum("kij,kj->ki", total[piece], self.base[rows]) + shift[piece]
        if self._followers is not None:
            # the pieces jointed to a carried one move with it: by the rigid motion that took it
            # from where the joint tree put it to where its seat puts it (each rigid as it moves:
            # a predicted in-between's shapes are not)
            leaders, follower_rows, labels, members = self._followers
            chosen = np.isin(piece, leaders)
            which = np.searchsorted(leaders, piece[chosen])
            moves = rigid_alignments(before[chosen], x[rows[chosen]], which, leaders.size)
            own = rigid_alignments(self.base[follower_rows], x[follower_rows], members, members[-1] + 1)
            rotations = moves[0][labels] @ own[0][members]
            translations = np.einsum("kij,kj->ki", moves[0][labels], own[1][members]) + moves[1][labels]
            x[follower_rows] = np.einsum("kij,kj->ki", rotations, self.base[follower_rows]) + translations
        return x

    def rider_places(self, x: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The riders' components (R,) and where their centroids (R, 3) go in ``x`` (n, 3), a pose
        at factor ``s``: those that put each rider's contact (:meth:`_rider_contacts`, its shape in
        ``x`` kept) where its seat's best similarity from the base key to ``x`` takes the contact in
        the base key, moved by the share ``s`` of its offset in the next key (in the seat's
        coordinates; :data:`RIDER_SIZE`); None without riders or where a seat is not finite."""
        if not self.riding.any() or not np.isfinite(x[self._carriers]).all():
            return None
        _, rotations, scales, means = self._seat_similarities(x)
        k = self._riders
        local = self._rider_starts + s * self._rider_offsets
        contact = means[k] + scales[k, None] * np.einsum("pij,pj->pi", rotations[k], local)
        # the centroid that puts the contact there, the rider's shape in ``x`` kept
        centroids = self.topo.centroids(x)[self._rider_components]
        return self._rider_components, contact + centroids - self._contact_points(x)

    def _seat_similarities(self, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """Each seat's best rigid motion from the base key to ``x`` (n, 3), translations (P, 3) and
        rotations (P, 3, 3), that rotation's best scale (P,) (``Σ (R b̃)·x̃ / Σ |b̃|²`` over the
        carriers about their means: with it, their best similarity) and the carriers' means (P, 3)
        in ``x``."""
        moved = x[self._carriers]
        counts = self._counts[:, None]
        mean = np.add.reduceat(moved, self._starts, axis=0) / counts
        centred = moved - np.repeat(mean, self._counts, axis=0)
        covariance = np.add.reduceat(centred[:, :, None] * self._base_centred[:, None, :], self._starts, axis=0)
        rotations = nearest_rotations(covariance)  # (P, 3, 3): Σ x̃ b̃ᵀ → R
        translations = mean - np.einsum("pij,pj->pi", rotations, self._base_mean)
        spread = np.add.reduceat(np.einsum("ij,ij->i", self._base_centred, self._base_centred), self._starts)
        scales = np.einsum("pij,pij->p", rotations, covariance) / np.maximum(spread, np.finfo(float).tiny)
        return translations, rotations, scales, mean


def _bodies_carried(kept: list, body: np.ndarray, groups: list, base: np.ndarray, nxt: np.ndarray, own) -> tuple:
    """The carried pieces ``kept`` (``(k, carriers, seat motion)`` per piece carried, ``k`` its index
    among the rigid pieces, ``body`` (P,) each one's rigid body: :func:`core.rigid_bodies.rigid_bodies`)
    with those of one body of several pieces made one where every piece of it is carried: carried
    by the carriers of all its pieces together, with their one best rigid motion between the gap's
    keys (``base``, ``nxt``: positions (n, 3)), its vertices those of all its pieces (``groups``:
    each piece's vertices, the first piece's entry changed to the body's), its own motion (``own``:
    rotations (P, 3, 3), translations (P, 3), a copy returned with that entry the body's). A body
    some piece of which no seat carries is carried by none, and keeps its one motion
    (:meth:`core.inbetween_motion.PieceMotion.motion`). A sword's grip and guard each carried by
    the skin of the hand nearest it rode two different fits of that skin, and the blade, not
    carried, its own screw: the three parted between the keys by up to 1.5e-3 of the diagonal; the
    grip and guard's skin carrying the whole sword, its median distance from the rig was the same
    (4.05e-3 against 4.07e-3 at keys 8 frames apart), the sword on its one screw 2.44e-3."""
    leaders = body[[k for k, _, _ in kept]]
    sizes = np.bincount(body)  # each body's pieces
    if not (sizes[np.unique(leaders)] > 1).any():
        return kept, own
    carried = np.bincount(leaders, minlength=sizes.size)  # each body's pieces carried
    rotations, translations = own[0].copy(), own[1].copy()
    out, done = [], set()
    for (k, carriers, motion), leader in zip(kept, leaders):
        if sizes[leader] == 1:
            out.append((k, carriers, motion))
            continue
        if carried[leader] < sizes[leader]:
            continue  # a piece of it moves on its own: the body keeps its one motion
        if leader in done:
            continue
        done.add(leader)
        members = np.flatnonzero(body == leader)
        seat = np.unique(np.concatenate([c for (j, c, _), other in zip(kept, leaders) if other == leader]))
        rows = np.concatenate([groups[j] for j in members])
        groups[k] = rows
        rotations[k], translations[k] = rigid_alignment(base[rows], nxt[rows])
        out.append((k, seat, rigid_alignment(base[seat], nxt[seat])))
    return out, (rotations, translations)


def _jointed(base: np.ndarray, rows: np.ndarray, carriers: np.ndarray, seat, own, reach: float) -> bool:
    """Whether the piece ``rows`` touches its ``carriers`` in the gap's base key (vertices within
    ``reach``; ``base``: positions (n, 3)) and its motion ``own`` relative to theirs (``seat``;
    each a best rigid motion between the keys, rotation and translation) holds that contact:
    jointed (:func:`core.inbetween_joints.joint_offset`)."""
    from scipy.spatial import cKDTree  # noqa: PLC0415

    near = cKDTree(base[carriers]).query_ball_point(base[rows], reach)
    pairs = [(r, c) for r, cs in zip(rows, near) for c in cs]
    if not pairs:
        return False
    piece, seated = np.array(pairs).T
    contact = 0.5 * (base[piece] + base[carriers[seated]])
    return joint_offset(contact, *relative_motion(seat, own), reach) <= reach
