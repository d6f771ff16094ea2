"""Rigid pieces carried by deforming ones: an eye in a bending head, a button on a cloth.

A connected component that moves rigidly between a gap's keys is placed by its own interpolated
rigid motion (:data:`core.inbetween_solver.RIGID_PLACEMENT_SCALE`), while a deforming component
next to it follows its fields and the keys' spline: the two paths part between the keys, and a
piece that sits on another one leaves it. Where it sits is read in the first key: its seat is the
nearest vertices of deforming components there (the cloth under a button, the socket around an
eye). In a gap where the seat's best rigid motion from the base key to the next takes the piece
near where it is in the next key, or where the piece touches its seat and turns about a point of
their contact (a hand at the wrist of a bending forearm, :func:`core.inbetween_joints.joint_offset`),
the seat carries it: at every factor the piece takes the seat's best rigid motion from the base key
to the pose, times the part of its own motion the seat misses (interpolated, so that both keys are
met exactly). Elsewhere the piece keeps its own motion.

Measured (docs/inbetweens.md, *Pieces carried by deforming ones*): a hand (a separate sphere) on a
forearm bent by 100°, two poses: off the forearm's end by 0.37–0.57 % of the diagonal in-between
and 3.9 % at ×2, now 2e-8 / 2e-7; six buttons on benchmark cloths, keys 16 frames apart, median
distance off the cloth under them: hanging sheet 1.53 → 0.004 mean edge lengths, banner 5.50 →
0.11, drape 0.84 → 0.018.
"""

from __future__ import annotations

import numpy as np

from . import deformation_fields as df
from .geometry import nearest_rotations
from .inbetween_joints import JOINT_REACH, joint_offset, relative_motion
from .rigid_alignment import rigid_alignment

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
#: Fewest carriers, and their least spread: the second singular value of their centred positions
#: over the piece's diagonal (collinear carriers leave a turn about their line free).
MIN_CARRIERS = 4
MIN_CARRIER_SPREAD = 0.05


class CarriedPieces:
    """The rigid pieces of one gap (a ``core.inbetween_solver._Gap``) that deforming pieces carry:
    per piece its vertices (k,), its carriers (j,) and the residual rigid motion (screw (6,)) from
    the carriers' motion at the next key to the piece's own."""

    def __init__(self, gap):
        self.pieces: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        topo, base, nxt = gap.topo, gap.base.vertices, gap.next.vertices
        self.base = base
        if len(topo.components) < 2:
            return
        rigid = gap.rigidity > 0.0  # moves rigidly across the gap's keys (RIGID_PLACEMENT_SCALE)
        if rigid.all() or not rigid.any():
            return
        from scipy.spatial import cKDTree  # noqa: PLC0415 (only meshes with rigid and deforming pieces)

        deforming = np.concatenate([topo.components[c] for c in np.flatnonzero(~rigid)])
        tree = cKDTree(topo.first_pose[deforming])
        for c in np.flatnonzero(rigid):
            rows = topo.components[c]
            if gap.static is not None and gap.static[rows].all():
                continue  # still in every key: pinned where it is
            own = rigid_alignment(base[rows], nxt[rows])
            seat = self._seat(topo.first_pose, base, nxt, rows, deforming, tree, own, JOINT_REACH * gap.mean_edge)
            if seat is not None:
                carriers, rotation, translation = seat
                # the piece's own motion after the carriers' undone: applied in part at each factor
                screw = df.rigid_log(*relative_motion((rotation, translation), own))
                self.pieces.append((rows, carriers, screw))
        if self.pieces:  # concatenated for place(): pieces' vertices, carriers and their base fit
            rows, carriers, screws = zip(*self.pieces)
            self._rows = np.concatenate(rows)
            self._row_piece = np.repeat(np.arange(len(rows)), [r.size for r in rows])
            self._carriers = np.concatenate(carriers)
            self._counts = np.array([c.size for c in carriers])
            self._starts = np.r_[0, np.cumsum(self._counts)[:-1]]
            seated = base[self._carriers]
            self._base_mean = np.add.reduceat(seated, self._starts, axis=0) / self._counts[:, None]
            self._base_centred = seated - np.repeat(self._base_mean, self._counts, axis=0)
            self._screws = np.array(screws)

    @staticmethod
    def _seat(first, base, nxt, rows, deforming, tree, own, reach) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The vertices (j,) of deforming pieces that carry the rigid piece ``rows`` with their best
        rigid motion (rotation (3, 3), translation (3,)) from the gap's base key to the next, or None if
        there are too few, too collinear, or they neither move with it from the gap's base key to
        the next nor hold it at a joint (it touches them, vertices within ``reach``, and turns
        about a point of the contact: a hand turning at the wrist of a bending arm, :func:`_jointed`;
        ``own``: the piece's best rigid motion between the keys, rotation and translation). They are sought (with ``tree``,
        over the ``deforming`` vertices) where the piece sits in the first key (``first``:
        positions (n, 3)), the same seat for every gap (see :data:`CARRIER_REACH`,
        :data:`CARRIED_TOLERANCE`)."""
        piece = base[rows]
        diagonal = float(np.linalg.norm(np.ptp(piece, axis=0)))
        if not diagonal > 0:
            return None
        distance, nearest = tree.query(first[rows], k=CARRIER_NEIGHBOURS, distance_upper_bound=CARRIER_REACH * diagonal)
        carriers = deforming[np.unique(nearest[np.isfinite(distance)])]
        if carriers.size < MIN_CARRIERS:
            return None
        spread = np.linalg.svd(base[carriers] - base[carriers].mean(axis=0), compute_uv=False)
        if spread[1] / np.sqrt(carriers.size) < MIN_CARRIER_SPREAD * diagonal:
            return None
        rotation, translation = rigid_alignment(base[carriers], nxt[carriers])
        if np.abs(piece @ rotation.T + translation - nxt[rows]).max() > CARRIED_TOLERANCE * diagonal \
                and not _jointed(base, rows, carriers, (rotation, translation), own, reach):
            return None
        return carriers, rotation, translation

    def place(self, x: np.ndarray, s: float) -> np.ndarray:
        """``x`` (n, 3), a pose at factor ``s``, with each carried piece moved by its carriers' best
        rigid motion from the base key to ``x``, times its residual motion at ``s``: every piece
        at once (one batched Kabsch fit: meshes with hundreds of carried pieces)."""
        if not self.pieces:
            return x
        moved = x[self._carriers]
        if not np.isfinite(moved).all():
            return x  # a failed solve: reported as it is
        counts = self._counts[:, None]
        mean = np.add.reduceat(moved, self._starts, axis=0) / counts
        centred = moved - np.repeat(mean, self._counts, axis=0)
        covariance = np.add.reduceat(centred[:, :, None] * self._base_centred[:, None, :], self._starts, axis=0)
        rotations = nearest_rotations(covariance)  # (P, 3, 3): Σ x̃ b̃ᵀ → R
        translations = mean - np.einsum("pij,pj->pi", rotations, self._base_mean)
        residual_rotations, residual_translations = df.rigid_exps(s * self._screws)
        total = rotations @ residual_rotations
        shift = np.einsum("pij,pj->pi", rotations, residual_translations) + translations
        piece = self._row_piece
        x[self._rows] = np.einsum("kij,kj->ki", total[piece], self.base[self._rows]) + shift[piece]
        return x


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
