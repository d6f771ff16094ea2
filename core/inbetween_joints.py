"""Rigid pieces jointed to each other (the links of a rig modelled as separate pieces of one
mesh): each moves along the screw motion of its rigid motion *relative to the piece it hangs
from*, composed with that piece's, instead of along its own screw motion in the world.

A link turning about a joint on a moving parent goes round the joint, not round the fixed axis of
its own world motion: three links of an arm each bent 60° came apart at their joints by up to
half a link length at 0.5 and 2.6 link lengths at ×2 along their own screws. Two pieces are
jointed in a gap when both are rigid over its keys (non-rigidity under
:data:`core.inbetween_motion.RIGID_PLACEMENT_SCALE`), they touch in both its keys (vertices within
:data:`JOINT_REACH` mean edge lengths: pieces that have come apart in the next key are held by no
joint) and the child's motion relative to the parent's holds the
contact (:func:`joint_offset`: a hinge's axis runs through it) without sliding along that axis,
to within what the pieces' rigid fits resolve (:data:`JOINT_SLIDE`: a joint holds a point, where
pieces touching by chance — hair cards each turning about its own root, tumbling debris — turn
relative to each other about an axis that slides), their nearest vertices within the
finer piece's own mean edge length too (a gap wider than a small piece's edges is no contact,
whatever the mesh's other pieces make its mean edge). The joints are a minimum
spanning tree of how well each contact is held, and each group hangs from the piece
that moves least over the gap's keys (a fixed base stays the root; measured by its vertices'
moves, since a link turning past a half turn reads as a small turn the other way), of those still
or turning on an axle through them where some are (:data:`ROOT_AXLE_SHARE`: a turntable carrying a
door that turns back against it, the door moving less), in a sequence
of those whose screws at the keys keep to one line where some do (:mod:`core.inbetween_carriers`:
a box carried steadily while its lid opens, the lid lifted against the carry moving less; between
two poses, where another piece of the group turns less than the one moving least, the gap warns:
:mod:`core.inbetween_joint_doubts`). At the keys the composed
motions are the pieces' own, and a rigid motion of the whole mesh has identity
relative motions, so it is reproduced exactly either way.

A rigid piece with a pinned vertex (still in the keys, or riding on an animated object:
:mod:`core.pins`) hangs from the world: its rigid motion fixes that vertex, so its own screw
motion keeps it put at every factor, where a parent's motion composed with the relative one does
not, and the pins then pull against it. Two cabinet doors 0.02 apart, each turning about its own
hinge (90° and 40°), were jointed (their relative motion's axis runs near their contact) and the
child door came back bent between its hinge's pins and its composed motion: 0.12 of the diagonal
off at 0.5, edges 4 % off, 0.24 and 60 % at × 2; now exact. Such pieces are joined to a world
node before any joint in the spanning tree, which is traversed from it first: they are roots, and
other pieces may hang from them. A pinned piece that a piece jointed to it keeps still (whose
motion keeps its pinned vertices where they are) is left to the tree, and hangs from a parent only
where that parent's motion keeps its pins: a robot's link rolling about its own axis, on which the
next joint lies, keeps that joint's point and the next link's still vertex there, and the next
link, hung from the world, had left its forward kinematics (0.36 of a link's size at 0.5).

Pieces that each turn about their own axis and touch in the same place in both keys (hair cards
on their roots, meshing gears on their axles without a vertex there) move along their own screws,
which are their motions: their relative motion turns about their contact too (the pitch point of
two gears), and composed on it a card or gear left its root or axle. They are told from a joint
by their contact, which a joint's moving parent carries between the keys and which their own
screws keep (:data:`CONTACT_CARRIED`, :data:`OWN_SCREW_FACTORS`, :func:`joint_tree`; the contact
read from the same vertex pairs in both keys where some are closest in both, :func:`shared_contacts`, elsewhere
as the centre of all its touching vertex pairs in each key where as many touch in both keys,
:data:`CONTACT_STEADY`, else as their closest pair; a contact that shrinks or grows in place on both
pieces holds the joint, :func:`contracts_in_place`), unless both
turn about the joint's own point, which then stays put (that robot's shoulder: its own screw keeps
the point but not the turn relative to the link below). Nor does a contact that rolls or slides
along both pieces, ending off itself as either piece carries it with none of its vertex pairs
touching in both keys (:data:`CONTACT_ROLLS`, :func:`_held_contacts`), where another joint places
one of its pieces: a wheel rolling on a still floor is no hinge on it.

A piece that does not turn beside one that does turns relative to it by that one's turn undone,
about an axis parallel to that one's own, which the keys fit as a hinge as well: the two are jointed
only where that axis holds a point of both pieces, of the gap between them, or of a ring their
contact makes about it (:func:`_sliding_past`, :mod:`core.joint_points`). A drawer sliding out over
a door turning 90° on its hinge, its front edge on the door's top edge, turns relative to the door
about a vertical axis 0.24 behind the door's back face: hung from the door, it went round the door's
hinge, 4.3e-2 of the diagonal off its slide at 0.5 and 0.21 at ×2, silently.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import minimum_spanning_tree

from . import deformation_fields as df
from . import rotation_continuity
from . import screw_motions
from .coordinate_rounding import RIGID_ROUNDING
from .joint_points import joint_point, surface_points, winding_numbers

#: Largest distance (in mean edge lengths of the mesh) between the nearest vertices of two rigid
#: pieces, at both keys of a gap, for them to be jointed.
JOINT_REACH = 1.0
#: A joint holds a point of the contact fixed: the relative motion of two pieces that turn about it
#: slides along its axis by at most this many times the two pieces' RMS rigid misfits over the gap's
#: keys (plus the coordinates' rounding), unless they move as one. Pieces that touch by chance in both
#: keys turn relative to each other about an axis that slides (hair cards each turning about its own
#: root, tumbling debris), and moved by a neighbour's motion composed with that they left their own.
JOINT_SLIDE = 3.0
#: Two touching pieces are not jointed where the contact stays put in the world between the keys
#: (its point — the same closest vertex pairs in both keys where there are some, else the centre of
#: its touching vertex pairs in each key — moves by at most this share of how far either piece's
#: motion carries it)...
CONTACT_CARRIED = 0.5
#: ... read as the centre of all its touching vertex pairs where as many touch in both keys to this
#: ratio (meshing teeth keep their contact's extent as they turn: 51–54 pairs on the tests' gear
#: trains), else as its closest pair; and a contact that shrinks or grows in place on both pieces
#: (:func:`contracts_in_place`: blades of scissors opening about their pivot slide off each other,
#: 95 → 48, 86 → 39, 210 → 53, 41 → 22, their seam shrinking about the pivot on each blade, while
#: their closest pair jumped between vertex pairs and stayed put in three cells where their motions
#: carried it: each blade left the pivot by up to 9.1e-2 of the diagonal at ×2) holds the joint.
#: Coarse meshing teeth change their contact's extent too (flat involute gears of 12 and 6 teeth:
#: 608 → 381–424 pairs) but roll it along both gears, off the vertices that touched...
CONTACT_STEADY = 0.75
#: ... and carried by their motions along arcs within this ratio of each other (meshing teeth roll on
#: each other, each gear carrying the contact by the same arc about its axle: the probes' gears of
#: 6–24 teeth turned 5°–80°, 1.0–1.4 ×, off it as far as the centre of their touching pairs sits off
#: the pitch point; a link turning 118° a key on a parent turning 2°: 4.1 ×)...
ROLLING_SPREAD = 2.0
#: ... and their own screw motions keep them in contact at these factors (Exaggerate's 2 and −1,
#: their in-betweens at 0.5; the farthest first, which parts most pairs that part)...
OWN_SCREW_FACTORS = (2.0, -1.0, 0.5)
#: ... to within this share of the finer piece's mean edge length of how close they are in the
#: keys (the closer of the two); and a contact shrinks or grows in place where every vertex
#: touching in the key where fewer pairs touch was within this share beyond the finer edge in the
#: other (a vertex at the contact's rim crosses the touching distance as the contact changes).
OWN_CONTACT_SLACK = 0.3
#: A joint group hangs from a piece still or turning on an axle through it — its own screw's axis
#: within this share of the piece's radius of its centroid, without sliding (:func:`_on_axles`) —
#: before one on neither that moves less: a door hinged at a turntable's rim turning back against
#: it turns less in the world than the turntable (or not at all), and the turntable hung from it
#: left its axle half-way (0.07–0.75 of the diagonal off, silently). A turntable, a wheel or a box
#: spinning about its centre measure 0 (a vertex centroid off a symmetric piece's axle by its
#: mesh's irregularity: a share of it); the door in the world 0.32–4.3, a lid about its hinge 0.71;
#: at 0.5 a blade of scissors opening on a turning pair (its world axis 0.46 from its centroid by
#: chance, the other blade's 0.55) carried the pair, 1.4e-2 / 1.7e-2 of the diagonal off.
ROOT_AXLE_SHARE = 0.1
#: A joint's contact (the centre of its touching vertex pairs) in the next key lies within this many
#: of the finer piece's mean edges, plus the contact's extent in the base key and the joint's
#: precision, of where one of its pieces' motions carries it from the base key, or one of its
#: touching vertex pairs touches in both keys: else it rolls or slides along them (a wheel on a still
#: floor) and holds no joint. Set by what the centre resolves, an edge: pairs join and leave the
#: contact's rim by the edge as the pieces turn. A cart's wheels rolling 90° / 150° on a still floor:
#: exact (were 2.2e-2 / 6.7e-2 of the diagonal off at 0.5); rolled 20° / 45° they keep a touching
#: pair or stay within the contact and stay jointed (1.0e-3 / 5.2e-3 off, as before). Only where
#: another joint places one of the pieces (the wheel's axle): a drum jointed by nothing else keeps its
#: joint, which carries it with a carried plate (6.9e-2 of the diagonal off it at 0.5 without, 2.9e-2 with).
CONTACT_ROLLS = 1.0
#: A joint's point is sought on its axis at this many points, evenly spread (by quantile) over the
#: touching vertices' extent along it (:func:`_sliding_past`).
AXIS_SAMPLES = 9


def relative_motion(parent: tuple[np.ndarray, np.ndarray], child: tuple[np.ndarray, np.ndarray]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The rigid motion ``child`` (rotation (3, 3), translation (3,)) with ``parent``'s undone:
    ``(R_pᵀ R_c, R_pᵀ (t_c − t_p))``, so that ``parent ∘ relative = child``."""
    (rotation, translation), (child_rotation, child_translation) = parent, child
    return rotation.T @ child_rotation, rotation.T @ (child_translation - translation)


def carry(rotations: np.ndarray, translations: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Each point of ``points`` (k, 3) moved by its own rigid motion ``x ↦ R x + t`` (``rotations``
    (k, 3, 3), ``translations`` (k, 3)): where that motion carries it (k, 3)."""
    return np.einsum("kab,kb->ka", rotations, points) + translations


def carry_lengths(rotations: np.ndarray, translations: np.ndarray, points: np.ndarray) -> np.ndarray:
    """How far (k,) each point of ``points`` (k, 3) is moved by its own rigid motion (``rotations``
    (k, 3, 3), ``translations`` (k, 3); :func:`carry`)."""
    return np.linalg.norm(carry(rotations, translations, points) - points, axis=1)


def joint_offset(contact: np.ndarray, rotation: np.ndarray, translation: np.ndarray, reach: float) -> float:
    """How far (≥ 0) the relative rigid motion ``x ↦ rotation · x + translation`` of two pieces
    (the child's motion with its parent's undone) is from holding their ``contact`` (points (k, 3)
    where they touch): one pair of :func:`joint_offsets`."""
    return float(joint_offsets(contact, np.zeros(len(contact), dtype=np.intp), np.array([0]), rotation[None],
                               np.asarray(translation)[None], reach)[0])


def joint_offsets(contact: np.ndarray, pair: np.ndarray, starts: np.ndarray, rotations: np.ndarray,
                  translations: np.ndarray, reach: float) -> np.ndarray:
    """Per pair of touching pieces (P,), how far (≥ 0) the relative rigid motion
    ``x ↦ R x + t`` of the two (the child's motion with its parent's undone; ``rotations`` (P, 3, 3),
    ``translations`` (P, 3)) is from holding their contact (``contact`` (k, 3) the points where they
    touch, ``pair`` (k,) whose they are, in runs beginning at ``starts`` (P,)): 0 where it moves no
    contact point by more than ``reach``; else the distance of its screw axis from the contact
    region (beyond the region's radius and ``reach``), inf if it slides along its axis by more than
    ``reach`` or does not turn. A hinge whose pivot lies inside both meshes moves every contact
    point but keeps its axis through the contact. Every pair at once (a pile of 30,000 pieces has
    50,000 touching pairs: 4 s per gap one by one)."""
    held = np.maximum.reduceat(carry_lengths(rotations[pair], translations[pair], contact), starts) <= reach
    angle, axis, slide = screw_axes(rotations, translations)
    hinged = ~held & (angle >= 1e-9) & (np.abs(slide) <= reach)
    pivot = np.zeros_like(translations)  # a point of each hinge's axis (only theirs: one small SVD each)
    if hinged.any():
        pivot[hinged] = _axis_points(rotations[hinged], translations[hinged], axis[hinged], slide[hinged])
    counts = np.diff(np.r_[starts, len(contact)])
    centre = np.add.reduceat(contact, starts) / counts[:, None]
    radius = np.maximum.reduceat(np.linalg.norm(contact - centre[pair], axis=1), starts)
    offset = centre - pivot
    distance = np.linalg.norm(offset - np.einsum("pa,pa->p", offset, axis)[:, None] * axis, axis=1)
    return np.where(held, 0.0, np.where(hinged, np.maximum(0.0, distance - radius - reach), np.inf))


def _sliding_past(topo, base: np.ndarray, c: Contacts, asked: np.ndarray, within: np.ndarray) -> np.ndarray:
    """Per touching pair of ``c`` (P,), whether it is ``asked`` (bool (P,)), one of its pieces does not
    turn over the gap while the other does (a turn moving the piece's vertices by at most, or more
    than, the pair's precision), and their relative motion's axis holds no joint's point
    (:func:`core.joint_points.joint_point`, at :data:`AXIS_SAMPLES` points of the axis spread over
    the touching vertices' extent along it): no point of it is on or in both pieces (on a surface,
    of ``topo``'s triangles at ``base``, within the gap between them where they touch — their
    touching vertices' distance from the other's triangles around its own — plus the precision) or
    in the gap between them, and not each piece encloses one of those points or, seen along the axis,
    surrounds it with its vertices as near it as its touching ones (of pairs within ``within`` (P,)):
    a pin through a ring, a wheel hanging on its axle with a clearance wider than an edge.

    The piece that does not turn moves relative to the other by the other's turn undone, about an
    axis parallel to that one's own: jointed, it rides a circle about the turning piece's axis
    through both keys, where its own motion is a straight translation (or none). The keys fit both
    readings; the contact tells them apart. A joint's point, which their relative motion keeps, is
    a point of both pieces or of the gap between them (a carriage kept level on a link's end turns
    on it about their shared face's centre, a gondola's ring about the wheel's pin through it),
    where pieces sliding past each other (a drawer sliding out over a door turning on its hinge)
    turn relative to each other about a point off one of them: the relative motion of a turn and a
    translation, whose axis is no place of the mechanism. Pieces that both turn are not asked: a
    drum rolling on a plate turns relative to it about a point inside the drum, off the plate, and
    jointed rolls on the plate to second order in its roll (its own screw leaves a carried plate)."""
    pieces, u, v = c.pieces, c.u, c.v
    radii = _piece_centres(base, c.index, c.label)[1]
    turned = [np.linalg.norm(df.rotation_vectors(c.rotations[k]), axis=1) * radii[k] > c.precision for k in (u, v)]
    out = np.zeros(u.size, dtype=bool)
    candidates = np.flatnonzero(asked & (turned[0] != turned[1]) & (c.angle >= 1e-9))
    if not candidates.size:
        return out
    run, touch = _touching_runs(base, c.ends, c.first, within)
    rotations, translations = c.relative
    axis = c.axis
    pivot = _axis_points(rotations[candidates], translations[candidates], axis[candidates], c.slide[candidates])
    order = np.argsort(topo.triangle_component, kind="stable")
    starts = np.searchsorted(topo.triangle_component[order], np.arange(len(topo.components) + 1))
    for p, at in zip(candidates, pivot):
        touching = np.unique(c.ends[touch & (run == p)])
        owner = topo.vertex_component[touching]
        ours = [touching[owner == pieces[k[p]]] for k in (u, v)]
        near = [base[topo.triangles[np.unique(topo.triangles_around(x))]] for x in ours]
        gap = min(surface_points(base[ours[0]], near[1])[1].min(), surface_points(base[ours[1]], near[0])[1].min())
        # the axis's points across the contact's extent along it: a hinge's line may meet both pieces
        # only at one end of their contact (a door standing on a turntable's rim, hinged on its edge)
        along = np.quantile(base[np.r_[ours[0], ours[1]]] @ axis[p], np.linspace(0.0, 1.0, AXIS_SAMPLES))
        points = at + (along - at @ axis[p])[:, None] * axis[p]
        whole = tuple(base[topo.triangles[order[starts[k]:starts[k + 1]]]] for k in pieces[[u[p], v[p]]])
        if joint_point(points, whole, gap + c.precision[p], within[p]):
            continue
        across = np.cross(axis[p], np.eye(3)[np.argmin(np.abs(axis[p]))])
        across /= np.linalg.norm(across)
        plane = np.stack([across, np.cross(axis[p], across)], axis=1)  # (3, 2): seen along the axis
        # each piece holds the axis: encloses one of its points, or, seen along it, its vertices as
        # near the axis as its touching ones surround it (a pin through a ring; a wheel hanging on its
        # axle with a clearance wider than an edge, its touching vertices an arc under the axle)
        held = []
        for piece, x, corners in zip(pieces[[u[p], v[p]]], ours, whole):
            seen = (base[topo.vertex_component == piece] - at) @ plane
            reach = np.linalg.norm((base[x] - at) @ plane, axis=1).max() + c.precision[p]
            held.append(_surrounds(seen[np.linalg.norm(seen, axis=1) <= reach])
                        or bool((np.abs(winding_numbers(points, corners)) >= 0.5).any()))
        out[p] = not all(held)
    return out


def _surrounds(points: np.ndarray) -> bool:
    """Whether the convex hull of ``points`` (k, 2) holds the origin (False where they span no area)."""
    from scipy.spatial import Delaunay, QhullError

    try:
        return bool(Delaunay(points).find_simplex(np.zeros((1, 2)))[0] >= 0)
    except (QhullError, ValueError):  # fewer than three points, or all on a line
        return False


def piece_vertices(topo, pieces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The vertices (k,) of ``topo``'s components ``pieces`` (P,), piece by piece, and each one's
    piece (k,; its index among ``pieces``)."""
    rows = [topo.components[c] for c in pieces]
    return np.concatenate(rows), np.concatenate([np.full(r.size, k) for k, r in enumerate(rows)])


def relative_motions(rotations: np.ndarray, translations: np.ndarray, u: np.ndarray, v: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Per pair of pieces ``u``, ``v`` (P,) of rigid motions ``rotations`` (C, 3, 3), ``translations``
    (C, 3), ``v``'s motion relative to ``u``'s (:func:`relative_motion`, every pair at once):
    rotations (P, 3, 3), translations (P, 3)."""
    inverse = np.transpose(rotations[u], (0, 2, 1))
    return inverse @ rotations[v], np.einsum("pab,pb->pa", inverse, translations[v] - translations[u])


def contact_reach(reach: float, edges: np.ndarray | None, u: np.ndarray, v: np.ndarray) -> np.ndarray | float:
    """Per pair of pieces ``u``, ``v`` (P,; components), the farthest their nearest vertices may be
    for a contact: ``reach``, and at most :data:`JOINT_REACH` of the finer piece's mean edge length
    (``edges`` (C,), or None: ``reach`` alone)."""
    return reach if edges is None else np.minimum(reach, JOINT_REACH * np.minimum(edges[u], edges[v]))


def slide_precision(base: np.ndarray, nxt: np.ndarray, reach: float, misfits: np.ndarray | None, u: np.ndarray,
                    v: np.ndarray) -> np.ndarray:
    """Per pair of pieces ``u``, ``v`` (P,; components), how far their relative motion may slide and
    still hold a point (:data:`JOINT_SLIDE`): what their rigid fits resolve (``misfits`` (C,), RMS
    lengths, or None: exact) plus the coordinates' rounding (``base``, ``nxt``: the pieces' vertices
    in the gap's keys; ``reach``: the joint distance)."""
    misfit = np.zeros(max(u.max(initial=0), v.max(initial=0)) + 1) if misfits is None else misfits
    rounding = RIGID_ROUNDING * (max(np.abs(base).max(), np.abs(nxt).max()) + reach)
    return JOINT_SLIDE * (misfit[u] + misfit[v]) + rounding


def screw_axes(rotations: np.ndarray, translations: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per rigid motion ``x ↦ R x + t`` (``rotations`` (P, 3, 3), ``translations`` (P, 3)) its turn's
    angle (P,), the unit direction of its screw axis (P, 3; any where it does not turn) and how far
    it slides along that axis (P,, signed; the whole translation's component along it)."""
    turn = df.rotation_vectors(rotations)
    angle = np.linalg.norm(turn, axis=1)
    axis = turn / np.where(angle > 0, angle, 1.0)[:, None]
    return angle, axis, np.einsum("pa,pa->p", translations, axis)


def _axis_points(rotations: np.ndarray, translations: np.ndarray, axis: np.ndarray, slide: np.ndarray) -> np.ndarray:
    """A point (P, 3) of the screw axis of each rigid motion ``x ↦ R x + t`` (``rotations``
    (P, 3, 3), ``translations`` (P, 3); ``axis`` and ``slide`` from :func:`screw_axes`): the least-
    squares solution of ``(I − R) p = t − slide · axis``."""
    return screw_motions.least_squares_3x3(np.eye(3) - rotations, translations - slide[:, None] * axis)


def contracts_in_place(base: np.ndarray, nxt: np.ndarray, index: np.ndarray, label: np.ndarray, u: np.ndarray,
                       v: np.ndarray, finer: np.ndarray, fewer_later: np.ndarray) -> np.ndarray:
    """Per pair of touching pieces ``u``, ``v`` (T,; labels of the vertices ``index``, ``label``)
    whose contact shrinks or grows between the keys ``base`` and ``nxt`` (positions (n, 3)),
    whether it does so in place on both pieces (bool (T,)): every vertex of either piece within
    ``finer`` (T,) of the other in the key where fewer vertex pairs touch (``fewer_later`` (T,) bool:
    the next key) was within :data:`OWN_CONTACT_SLACK` beyond ``finer`` of it in the other key. A
    joint's contact shrinks or grows about the joint, which each piece carries (the seam of scissors
    opening about their pivot: the touching vertices in the later key are some of those touching in
    the first, on both blades); meshing teeth roll their contact along both gears, to vertices that
    were apart. Few pairs at once (those the gear rule would free); a KD-tree per piece and key."""
    from scipy.spatial import cKDTree

    order = np.argsort(label, kind="stable")
    starts = np.searchsorted(label[order], np.arange(label.max(initial=-1) + 2))
    rows = [index[order[starts[k]:starts[k + 1]]] for k in range(starts.size - 1)]
    out = np.ones(u.size, dtype=bool)
    for k in range(u.size):
        fewer, other = (nxt, base) if fewer_later[k] else (base, nxt)
        for a, b in ((u[k], v[k]), (v[k], u[k])):
            near = cKDTree(fewer[rows[b]]).query(fewer[rows[a]], distance_upper_bound=finer[k])[0] <= finer[k]
            then = cKDTree(other[rows[b]]).query(other[rows[a][near]])[0] if near.any() else np.zeros(0)
            out[k] &= bool((then <= (1.0 + OWN_CONTACT_SLACK) * finer[k]).all())
            if not out[k]:
                break
    return out


def _rolling(chords: list, rotations: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Per pair of pieces ``u``, ``v`` (P,; their rigid motions' ``rotations`` (R, 3, 3)), whether the
    two carry their contact along arcs within :data:`ROLLING_SPREAD` of each other, as teeth rolling
    on each other do: each piece's arc ``θ ρ`` at the contact's distance ``ρ`` from its axis
    (:func:`_axis_distances` of its chord, ``chords``: two (P,) arrays, how far its motion carries the
    contact), the chord itself where the piece does not turn (no axis: the arc's limit)."""
    arcs = []
    for chord, k in zip(chords, (u, v)):
        angle = np.linalg.norm(df.rotation_vectors(rotations[k]), axis=1)
        radius = _axis_distances(chord, angle)
        turning = np.isfinite(radius)
        arcs.append(np.where(turning, angle * np.where(turning, radius, 0.0), chord))
    return np.maximum(*arcs) <= ROLLING_SPREAD * np.minimum(*arcs)


def _axis_distances(chords: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Per rigid motion turning by ``angles`` (P,, radians) that carries a point along ``chords`` (P,),
    ``chord / (2 sin(θ/2))``: the point's distance from its screw axis where the motion does not
    slide along it (a slide lengthens the chord, so this is at least that distance); inf where the
    motion does not turn (no axis)."""
    chord_per_distance = 2.0 * np.sin(0.5 * angles)  # angles in [0, π]: rotation vectors
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(chord_per_distance > 1e-12, chords / np.maximum(chord_per_distance, 1e-12), np.inf)


def _turns_about(contact: np.ndarray, centres: np.ndarray, rotations: np.ndarray, translations: np.ndarray,
                 u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Per pair of touching pieces ``u``, ``v`` (P,; their centroids ``centres`` (R, 3) and rigid
    motions ``rotations`` (R, 3, 3), ``translations`` (R, 3)), whether either piece turns about their
    ``contact`` (P, 3): its own screw axis passes nearer the contact than its centroid
    (:func:`_axis_distances`), as a joint's child turns about its end where it meets the parent; a
    piece spinning on its axle (a gear, a cube about its centre) turns about a point inside it, the
    contact at its rim."""
    out = np.zeros(u.size, dtype=bool)
    for k in (u, v):
        angle = np.linalg.norm(df.rotation_vectors(rotations[k]), axis=1)
        chord = [carry_lengths(rotations[k], translations[k], x) for x in (contact, centres[k])]
        out |= _axis_distances(chord[0], angle) < _axis_distances(chord[1], angle)
    return out


def touching_pairs(x: np.ndarray, index: np.ndarray, label: np.ndarray, count: int, reach: float) -> tuple:
    """The pairs of vertices ``index`` of different pieces (``label``: each vertex's piece, of
    ``count``) within ``reach`` of each other at positions ``x``: ``(key, ends, first)``, each pair's
    pieces ``a < b`` as ``a · count + b`` (sorted), its two vertices (rows of ``ends``) and where each
    pair of pieces' run begins in them."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(x[index]).query_pairs(reach, output_type="ndarray")
    pairs = pairs[label[pairs[:, 0]] != label[pairs[:, 1]]]
    a, b = np.sort(label[pairs], axis=1).T
    order = np.argsort(a * count + b, kind="stable")
    key = (a * count + b)[order]
    return key, index[pairs[order]].reshape(-1, 2), np.flatnonzero(np.diff(key, prepend=-1))  # keys are >= 0


def closest_pairs(x: np.ndarray, ends: np.ndarray, first: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pair of pieces of :func:`touching_pairs`, the distance of its closest two vertices ``ends``
    at positions ``x`` and their midpoint."""
    if not first.size:
        return np.zeros(0), np.zeros((0, 3))
    gap = np.linalg.norm(x[ends[:, 0]] - x[ends[:, 1]], axis=1)
    nearest = np.minimum.reduceat(gap, first)
    counts = np.diff(np.r_[first, len(ends)])
    # each run's first pair at its least distance (a reduction: sorting the pairs cost more than the rest)
    closest = np.minimum.reduceat(np.where(gap == np.repeat(nearest, counts), np.arange(len(ends)), len(ends)), first)
    return nearest, 0.5 * (x[ends[closest, 0]] + x[ends[closest, 1]])


def shared_contacts(base: np.ndarray, nxt: np.ndarray, ends: np.ndarray, first: np.ndarray, nearest_base: np.ndarray,
                    nearest_later: np.ndarray, tolerance: np.ndarray, contact_base: np.ndarray,
                    contact_later: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pair of pieces of :func:`touching_pairs` (P,; its vertex pairs ``ends`` in runs from
    ``first``, touching in the base key), where it touches in the base key and in the next
    (``base``, ``nxt``: positions (n, 3)): where some of its vertex pairs are within ``tolerance``
    (P,) of its least distance in both keys (``nearest_base``, ``nearest_later`` (P,)), the mean
    midpoint of those pairs in each key, the same points read twice; elsewhere ``contact_base``
    and ``contact_later`` (P, 3), its closest pair in each key."""
    if not first.size:
        return contact_base, contact_later
    run = np.repeat(np.arange(first.size), np.diff(np.r_[first, len(ends)]))
    apart = [np.linalg.norm(x[ends[:, 0]] - x[ends[:, 1]], axis=1) for x in (base, nxt)]
    shared = ((apart[0] - nearest_base[run] <= tolerance[run]) & (apart[1] - nearest_later[run] <= tolerance[run]))
    if not shared.any():
        return contact_base, contact_later
    out = []
    for x, contact in ((base, contact_base), (nxt, contact_later)):
        mean, counts = _mean_midpoints(x, ends, run, shared, first.size)
        out.append(np.where(counts[:, None] > 0, mean, contact))
    return out[0], out[1]


def _mean_midpoints(x: np.ndarray, ends: np.ndarray, run: np.ndarray, chosen: np.ndarray,
                    count: int) -> tuple[np.ndarray, np.ndarray]:
    """Per run (``count`` of them; ``run`` (k,) the run of each vertex pair ``ends`` (k, 2)), the mean
    midpoint (count, 3) at positions ``x`` of its ``chosen`` (bool (k,)) pairs (nan where none is), and
    how many those are (int (count,))."""
    middle = 0.5 * (x[ends[chosen, 0]] + x[ends[chosen, 1]])
    counts = np.bincount(run[chosen], minlength=count)
    sums = np.stack([np.bincount(run[chosen], middle[:, d], minlength=count) for d in range(3)], axis=1)
    return np.where(counts[:, None] > 0, sums / np.maximum(counts, 1)[:, None], np.nan), counts


def _touching_runs(x: np.ndarray, ends: np.ndarray, first: np.ndarray,
                   within: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per vertex pair ``ends`` (k, 2) of the pairs of pieces of :func:`touching_pairs` (P,; in runs
    from ``first``): its pair of pieces (int (k,)) and whether its two vertices are within
    ``within`` (P,) of each other at positions ``x`` (n, 3) (bool (k,))."""
    run = np.repeat(np.arange(first.size), np.diff(np.r_[first, len(ends)]))
    return run, np.linalg.norm(x[ends[:, 0]] - x[ends[:, 1]], axis=1) <= within[run]


def contact_centres(x: np.ndarray, ends: np.ndarray, first: np.ndarray,
                    within: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pair of pieces of :func:`touching_pairs` (P,; its vertex pairs ``ends`` in runs from
    ``first``), the centre (P, 3) of where they touch at positions ``x`` (n, 3): the mean midpoint
    of its vertex pairs within ``within`` (P,) of each other (nan where none is), and how many
    pairs that is (int (P,))."""
    run, near = _touching_runs(x, ends, first, within)
    return _mean_midpoints(x, ends, run, near, first.size)


def _held_contacts(base: np.ndarray, nxt: np.ndarray, ends: np.ndarray, first: np.ndarray, within: np.ndarray,
                   centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pair of pieces of :func:`touching_pairs` (P,; its vertex pairs ``ends`` in runs from
    ``first``): whether one of its vertex pairs is within ``within`` (P,) of each other both at
    ``base`` and at ``nxt`` (n, 3), a point of the contact held from one key to the next (bool
    (P,)); and the contact's extent at ``base`` (P,): the largest distance of a pair touching there
    (within ``within``) from its ``centres`` (P, 3; :func:`contact_centres`), 0 where none touches."""
    run, near = _touching_runs(base, ends, first, within)
    both = near & _touching_runs(nxt, ends, first, within)[1]
    extent = np.zeros(first.size)
    if near.any():
        midpoints = 0.5 * (base[ends[near, 0]] + base[ends[near, 1]])
        np.maximum.at(extent, run[near], np.linalg.norm(midpoints - centres[run[near]], axis=1))
    return np.bincount(run[both], minlength=first.size) > 0, extent


def touching_centres(x: np.ndarray, index: np.ndarray, label: np.ndarray, count: int, reach: float, keys: np.ndarray,
                     asked: np.ndarray, within: np.ndarray) -> np.ndarray:
    """Per pair of pieces ``keys`` (P,; as :func:`touching_pairs` names them), the centre (P, 3) of
    where it touches at positions ``x`` (:func:`contact_centres` of its vertices ``index`` within
    ``within`` (P,) ≤ ``reach`` of each other) where it is ``asked`` (bool (P,)), else nan (only the
    asked pairs' pieces searched), and how many vertex pairs touch there (int (P,), 0 where not asked)."""
    ends, first, here, there = _asked_pairs(x, index, label, count, reach, keys, asked)
    reaches = np.full(first.size, -1.0)  # pairs not asked for: none within
    reaches[there] = np.where(asked[here], within[here], -1.0)
    centres, counts = np.full((keys.size, 3), np.nan), np.zeros(keys.size, dtype=np.int64)
    found, touching = contact_centres(x, ends, first, reaches)
    centres[here], counts[here] = found[there], touching[there]
    return centres, counts


def _asked_pairs(x: np.ndarray, index: np.ndarray, label: np.ndarray, count: int, reach: float, keys: np.ndarray,
                 asked: np.ndarray) -> tuple:
    """The vertex pairs within ``reach`` at positions ``x`` of the pairs of pieces ``keys`` that are
    ``asked`` (:func:`touching_pairs` of their pieces' vertices: ``ends``, ``first``), and which of
    ``keys`` (``here``) each of the runs found (``there``) is."""
    kept = np.isin(label, np.divmod(keys[asked], count))
    found, ends, first = touching_pairs(x, index[kept], label[kept], count, reach)
    _, here, there = np.intersect1d(keys, found[first], assume_unique=True, return_indices=True)
    return ends, first, here, there


def _nearest(x: np.ndarray, ends: np.ndarray, first: np.ndarray) -> np.ndarray:
    """Per pair of pieces of :func:`touching_pairs`, the distance of its closest two vertices ``ends``
    at positions ``x``."""
    if not first.size:
        return np.zeros(0)
    return np.minimum.reduceat(np.linalg.norm(x[ends[:, 0]] - x[ends[:, 1]], axis=1), first)


def nearest_pairs(x: np.ndarray, index: np.ndarray, label: np.ndarray, count: int, reach: float, keys: np.ndarray,
                   asked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pair of pieces ``keys`` (as :func:`touching_pairs` names them), the distance of its closest two
    vertices ``index`` at positions ``x`` where it is ``asked`` (bool) and they are within ``reach``,
    else inf (only the asked pairs' pieces searched), and their midpoint (nan where none)."""
    ends, first, here, there = _asked_pairs(x, index, label, count, reach, keys, asked)
    nearest, where = np.full(keys.size, np.inf), np.full((keys.size, 3), np.nan)
    distance, midpoint = closest_pairs(x, ends, first)
    nearest[here], where[here] = distance[there], midpoint[there]
    return np.where(asked, nearest, np.inf), where


def _piece_centres(x: np.ndarray, index: np.ndarray, label: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per piece (vertices ``index`` in runs per piece, ``label``), the centroid (R, 3) of its
    vertices at ``x`` and its radius about it (R,)."""
    counts = np.bincount(label)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    centres = np.add.reduceat(x[index], starts) / counts[:, None]
    return centres, np.sqrt(np.maximum.reduceat(np.sum((x[index] - centres[label]) ** 2, axis=1), starts))


def _relative_moves(x: np.ndarray, index: np.ndarray, label: np.ndarray, child: np.ndarray,
                    relative: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Per pair, a bound on how far its ``relative`` rigid motion (rotations (P, 3, 3), translations
    (P, 3); or any motion per pair: the child's own) moves the vertices at ``x`` of its ``child``
    piece (vertices ``index`` in runs per piece, ``label``): the move of the piece's centroid plus
    its radius times the chord ``2 sin(θ/2)`` of the turn by θ."""
    centres, radii = _piece_centres(x, index, label)
    rotations, translations = relative
    centre = centres[child]
    shift = carry_lengths(rotations, translations, centre)
    chord = np.linalg.norm(rotations - np.eye(3), axis=(1, 2)) / np.sqrt(2.0)  # ‖R − I‖_F = 2√2 sin(θ/2)
    return shift + chord * radii[child]


@dataclass
class Contacts:
    """The rigid pieces of a gap and the pairs of them touching in its base key, with what a joint
    between each pair is judged by; :func:`joint_tree` and
    :func:`core.inbetween_joint_doubts.joint_doubts` read the same (:func:`contacts`)."""

    pieces: np.ndarray  # the rigid pieces (R,)
    index: np.ndarray  # their vertices, piece by piece, and each one's piece among them (``label``)
    label: np.ndarray
    rotations: np.ndarray  # the pieces' rigid motions from the base key to the next (R, 3, 3), (R, 3)
    translations: np.ndarray
    key: np.ndarray  # :func:`touching_pairs`: the touching vertex pairs' piece-pair keys, their ends, each pair's first
    ends: np.ndarray
    first: np.ndarray
    u: np.ndarray  # per touching pair of pieces (P,): the two pieces (among ``pieces``)
    v: np.ndarray
    relative: tuple  # v's motion relative to u's (rotations (P, 3, 3), translations (P, 3))
    angle: np.ndarray  # its screw's angle, axis and slide along it (:func:`screw_axes`)
    axis: np.ndarray
    slide: np.ndarray
    precision: np.ndarray  # the slide the pieces' rigid fits resolve (:func:`slide_precision`)
    nearest: np.ndarray  # the closest two vertices' distance and midpoint in the base key (:func:`closest_pairs`)
    nearest_at: np.ndarray
    # per touching pair (P,), whether its contact holds a joint (set by :func:`joint_tree`, whose
    # spanning tree takes one joint per piece of those: where they close a loop, the keys do not
    # tell which hold, :mod:`core.inbetween_joint_doubts`); None until then
    held: np.ndarray | None = None


def contacts(topo, base: np.ndarray, nxt: np.ndarray, motions: tuple[np.ndarray, np.ndarray], rigid: np.ndarray,
             reach: float, misfits: np.ndarray | None) -> Contacts | None:
    """The :class:`Contacts` of the ``rigid`` (bool (C,)) pieces of ``topo`` between vertices ``base``
    and ``nxt`` (n, 3), with their best rigid ``motions`` (rotations (C, 3, 3), translations (C, 3)),
    the joint distance ``reach`` and each piece's rigid ``misfits`` (C,; see :func:`joint_tree`);
    None with fewer than two rigid pieces."""
    pieces = np.flatnonzero(rigid)
    if pieces.size < 2:
        return None
    index, label = piece_vertices(topo, pieces)
    rotations, translations = motions[0][pieces], motions[1][pieces]
    key, ends, first = touching_pairs(base, index, label, pieces.size, reach)
    u, v = np.divmod(key[first], pieces.size)
    relative = relative_motions(rotations, translations, u, v)
    angle, axis, slide = screw_axes(*relative)
    precision = slide_precision(base[index], nxt[index], reach, misfits, pieces[u], pieces[v])
    return Contacts(pieces, index, label, rotations, translations, key, ends, first, u, v, relative, angle, axis,
                    slide, precision, *closest_pairs(base, ends, first))


def joint_tree(topo, base: np.ndarray, nxt: np.ndarray, motions: tuple[np.ndarray, np.ndarray], rigid: np.ndarray,
               moves: np.ndarray, reach: float, loose: np.ndarray | None = None, pins: np.ndarray | None = None,
               edges: np.ndarray | None = None, screws: np.ndarray | None = None, misfits: np.ndarray | None = None,
               touching: Contacts | None = None, departures: np.ndarray | None = None):
    """``(parents (C,), order)`` of the jointed rigid pieces of ``topo`` (a
    ``core.inbetween_topology.Topology``) between vertices ``base`` and ``nxt`` (n, 3): each piece's
    parent (−1 for roots and unjointed pieces) and the jointed pieces parents first; None when no
    two pieces are jointed. ``motions``: the pieces' best rigid motions from ``base`` to ``nxt``
    (rotations (C, 3, 3), translations (C, 3)); ``rigid``: bool (C,); ``moves``: how far each piece
    moves over the gap's keys (C,), the piece of a group that moves least is its root (in a chain
    the motions add up from the piece fixed to the world; a turn would alias past a half turn);
    ``reach``: the joint distance; ``loose``: bool (C,), pieces only nearly rigid (non-rigidity
    over half :data:`core.inbetween_motion.RIGID_PLACEMENT_SCALE`: noise, rounding), which root a
    group only where none of its pieces is firmly rigid (a head turned exactly rigidly hung from one
    of its two noisy eyes, which moved less, and left its own motion by the eye's noise: 3e-5 of the
    diagonal at 0.5 for noise of 1e-4 of it); ``pins``: bool (n,), the pinned vertices (still in
    the keys, :mod:`core.pins`): a piece with one hangs from the world, a root, unless the piece it
    is jointed to keeps them still (see the module's note); ``edges``: each piece's mean edge length
    (C,), two pieces touching only where their nearest vertices are within the finer one's, in both
    keys (a lash 0.057 from a ball, both of edges about 0.04, was the ball's joint where a coarse
    body elsewhere made the mesh's mean edge 0.080, and moved with the ball's turn: 2.8e-2 of the
    diagonal off its own at ×2); ``screws``: the pieces'
    own screw coordinates from ``base`` to ``nxt`` (C, 6), without which pieces that turn about
    their own axes touching in the same place are jointed too; ``misfits``: each piece's RMS misfit
    of its best rigid motion over the gap's keys (C,, lengths; 0 where None), what a joint's slide
    is measured against (:data:`JOINT_SLIDE`); ``touching``: :func:`contacts` of these arguments, where
    the caller has them; its ``held`` is set (the touching pairs whose contact holds a joint);
    ``departures``: in a sequence, how far each piece's screws at the keys about the gap leave one
    screw (C,; :func:`core.inbetween_carriers.screw_departures`, 0 where within its fits): where some
    piece of a group keeps to one screw, the root is the one of those that moves least (None: all 0)."""
    touching = contacts(topo, base, nxt, motions, rigid, reach, misfits) if touching is None else touching
    if touching is None or not touching.key.size:
        return None
    c = touching
    pieces, index, label, key, ends, first, u, v = c.pieces, c.index, c.label, c.key, c.ends, c.first, c.u, c.v
    rotations, translations, relative = c.rotations, c.translations, c.relative
    # per pair of touching pieces, whether the child's motion relative to the parent's holds their
    # contact (a joint); a spanning tree of the best held contacts (a chain curled onto itself
    # touches another link only in passing, and its relative motion turns about another point)
    contact = 0.5 * (base[ends[:, 0]] + base[ends[:, 1]])
    run = np.repeat(np.arange(first.size), np.diff(np.r_[first, key.size]))  # each vertex pair's pair of pieces
    offsets = joint_offsets(contact, run, first, *relative, reach)
    jointed = offsets <= reach
    # touching within the finer piece's edges, and in the next key too: a joint keeps its pieces
    # together (cubes of a shattered block that touch in the base key and have flown apart in the
    # next are no joints, wherever their relative motions' axes run)
    finer = contact_reach(reach, edges, pieces[u], pieces[v])
    nearest_base, contact_base = c.nearest, c.nearest_at
    jointed &= nearest_base <= finer
    if jointed.any():
        nearest_later, contact_later = nearest_pairs(nxt, index, label, pieces.size, reach, key[first], jointed)
        jointed &= nearest_later <= finer
    if jointed.any():
        # a joint's relative motion turns about an axis through the contact without sliding along it
        # (to within what the pieces' rigid fits resolve; pieces moving as one neither turn nor slide)
        precision, axis, slide = c.precision, c.axis, c.slide
        jointed &= np.abs(slide) <= precision
    if jointed.any():
        # a piece that does not turn beside one that does is jointed to it only where their relative
        # motion's axis holds a point of both (or of the gap between them, or through a ring)
        jointed &= ~_sliding_past(topo, base, c, jointed, finer)
    if jointed.any() and screws is not None:
        # no joint where the pieces turn about their own axes, touching in the same place: their own
        # screws are then their motions (hair cards turning about their roots, meshing gears about
        # their axles: composed on a neighbour's motion, gears left their axles by 0.2 of the
        # diagonal at ×2 and turned the long way round at 60° a key, 0.8 off). A joint stays where
        # - the pieces move as one (their relative motion moves no vertex of the child farther than
        #   their contact's reach, nor as far as the child's own motion does): the parent's motion is
        #   the child's, where their own screws, each splined in its own frame, part a little (an eye
        #   left a turning head by 0.055). Pieces each turning about their own axis move relative to
        #   each other at least as far as in the world (coarse cubes 0.1 apart turning 25° and 60°:
        #   their relative motion moves one by 1.04, within the cubes' edge of 1.14, and its own by
        #   0.87; held as one, 0.14 of the diagonal off);
        # - either turns a half turn, whose way round its own screw does not tell: the joint's
        #   relative turn tells it, or warns that nothing does (a crank keyed every 180°);
        # - the contact shrinks or grows in place on both pieces between the keys (CONTACT_STEADY,
        #   contracts_in_place: blades of scissors sliding off each other about their pivot;
        #   meshing teeth roll their contact along both gears);
        # - the contact moves with the pieces between the keys (a joint carried by a moving
        #   parent; a gear's teeth roll through the same place);
        # - their own screws part them (OWN_SCREW_FACTORS) beyond how close they are in the keys.
        #   Not where their own screws part two vertices that touch in both keys: each moves with its
        #   piece, so such a pair is carried as far as the motions carry it, and where the contact
        #   stays put it is a pair passing through the contact, not holding it (a tooth pair entering
        #   the mesh in one key and leaving it, mirrored across the line of centres, in the next; a
        #   joint's own pair moves with the contact, which the rule above then finds carried)
        relative_move = _relative_moves(base, index, label, v, relative)
        own = _relative_moves(base, index, label, v, (rotations[v], translations[v]))
        together = jointed & ((relative_move > finer) | (relative_move >= own))
        half = rotation_continuity.either_way(np.linalg.norm(screws[pieces, :3], axis=1), screw_motions.TURN_SPREAD)
        together &= ~(half[u] | half[v])
        # - both turn about the joint's point (of its axis, nearest the contact), which stays put to
        #   within the same precision: a rig's joint on a parent turning about it (a robot's shoulder
        #   pitching on the yaw axis of the link below), whose own screws keep that point too but
        #   not the child's turn relative to its parent
        if together.any():
            t = np.flatnonzero(together)
            pivot = _axis_points(relative[0][t], relative[1][t], axis[t], slide[t])
            offset = np.add.reduceat(contact, first)[t] / np.diff(np.r_[first, key.size])[t, None] - pivot
            point = pivot + np.einsum("pa,pa->p", offset, axis[t])[:, None] * axis[t]
            drift = np.maximum(*(carry_lengths(rotations[k[t]], translations[k[t]], point) for k in (u, v)))
            together[t] = drift > precision[t]
        # the contact in each key: the centre of all its vertex pairs touching (within the finer
        # piece's edges), where the closest pair of meshing teeth jumps from tooth to tooth as the
        # gears turn (half a tooth's pitch on a turn of a third of it: so read, a contact that stays
        # put between the teeth moved as far as the gears' motions carried it); and the same vertex
        # pairs read in both keys where some are closest in both (coincident vertices along a
        # hinge): the first of several equally close pairs is another pair in each key, and two
        # points of a carried hinge read as a contact that stays put
        # (the centre only where as many pairs touch in both keys, CONTACT_STEADY, else the closest
        # pair; blades sliding off each other as they open about a pivot, whose closest pair jumps
        # between vertex pairs and whose centre moves less than they carry it, hold their joint where
        # the seam shrinks in place on both blades, contracts_in_place)
        within = np.broadcast_to(finer, jointed.shape)
        centres_base, count_base = contact_centres(base, ends, first, within)
        centres_later, count_later = touching_centres(nxt, index, label, pieces.size, reach, key[first], jointed,
                                                      within)
        steady = jointed & (np.minimum(count_base, count_later) >= CONTACT_STEADY * np.maximum(count_base, count_later))
        contact_base = np.where(steady[:, None], centres_base, contact_base)
        contact_later = np.where(steady[:, None], centres_later, contact_later)
        contact_base, contact_later = shared_contacts(base, nxt, ends, first, nearest_base, nearest_later,
                                                      precision, contact_base, contact_later)
        chords = [carry_lengths(rotations[k], translations[k], contact_base) for k in (u, v)]
        carried = np.maximum(*chords)
        # - a joint's contact goes where its pieces' motions carry it (both carry a hinge's point to
        #   the same place) and keeps the vertex pairs at its axis, as a hinge does opening or folding
        #   onto its parent: one whose touching pairs' centre ends off the contact as either piece
        #   carries it (farther than the contact's extent in the base key plus what the centre
        #   resolves, CONTACT_ROLLS: a lever spinning face to face on its post moves the centre of
        #   their overlap within it) and of whose touching vertex pairs none touches in the next key
        #   (_held_contacts) rolls or slides along them: a wheel rolling on a still floor, held as
        #   a hinge on the floor, would carry a cart's body round the wheel's own screw
        reached = np.minimum(*(np.linalg.norm(carry(rotations[k], translations[k], centres_base) - centres_later,
                                              axis=1) for k in (u, v)))
        held, extent = _held_contacts(base, nxt, ends, first, within, centres_base)
        rolls = jointed & ~(held | (reached <= CONTACT_ROLLS * finer + extent + precision))
        # only where another joint places one of its pieces (a wheel on its axle), which the rolling
        # contact would then hang from the roll's screw; a piece jointed by nothing else rolls on the
        # other as its relative motion carries it, where its own screw leaves a carried parent (a
        # drum rolling 90° on a plate turned 40°: 6.9e-2 of the diagonal off the plate at 0.5,
        # silently, 2.9e-2 jointed)
        fixed = jointed & ~rolls
        others = np.bincount(np.r_[u[fixed], v[fixed]], minlength=pieces.size)
        jointed &= ~(rolls & ((others[u] > 0) | (others[v] > 0)))
        # - one of the pieces turns about the contact (its own axis nearer it than its centroid:
        #   _turns_about) and they carry it by arcs unequal beyond ROLLING_SPREAD: a link turning far
        #   on a nearly still parent whose contact was read to stay put (it moved 0.0078 where the
        #   parent carried it 0.039, under the contact's reading) turns about its end, 0.074 from
        #   the contact and 0.56 from its centroid, and carries it along an arc 4.1 × the parent's;
        #   meshing teeth roll, each gear carrying the contact along the same arc. Pieces each
        #   spinning about an axis through them (coarse cubes 0.1–0.2 apart turning 20° and 50°,
        #   the contact 0.6 from their axes through their centroids) turn about no contact, and their
        #   arcs tell nothing
        about = _turns_about(contact_base, _piece_centres(base, index, label)[0], rotations, translations, u, v)
        together &= _rolling(chords, rotations, u, v) | ~about
        together &= np.linalg.norm(contact_later - contact_base, axis=1) <= CONTACT_CARRIED * carried
        changed = np.flatnonzero(together & ~steady)
        if changed.size:
            together[changed] = ~contracts_in_place(base, nxt, index, label, u[changed], v[changed],
                                                    within[changed],
                                                    count_later[changed] < count_base[changed])
        kept = np.minimum(nearest_base, nearest_later) + OWN_CONTACT_SLACK * finer
        for s in OWN_SCREW_FACTORS:
            if not together.any():
                break
            rotations_s, translations_s = screw_motions.rigid_exps(s * screws[pieces])
            moved = carry(rotations_s[label], translations_s[label], base[index])
            together &= nearest_pairs(moved, np.arange(index.size), label, pieces.size, kept[together].max(),
                                       key[first], together)[0] <= kept
        jointed &= ~together
    touching.held = jointed
    if not jointed.any():
        return None
    # the closest the touching vertices stay at the next key: 0 where a joint is a shared point
    apart = _nearest(nxt, ends, first)
    weights = offsets[jointed] + apart[jointed] + 1e-3 * reach  # > 0: a zero is no edge to SciPy
    u, v = u[jointed], v[jointed]
    world = pieces.size  # a node for the world, which the pinned pieces hang from (the module's note)
    # per joint, whether each piece's motion keeps the other's pins still (to the joints' precision):
    # keeps[parent, child]; a pinned piece that no piece jointed to it keeps still hangs from the
    # world, before any joint
    has_pins, kept_u, kept_v = _pins_kept(base, index, label, pieces.size, pins, (u, v), (rotations, translations),
                                          precision[jointed])
    keeps = {**dict(zip(zip(v.tolist(), u.tolist()), kept_u.tolist())),
             **dict(zip(zip(u.tolist(), v.tolist()), kept_v.tolist()))}
    pinned = np.flatnonzero(has_pins & (np.bincount(np.r_[u, v], np.r_[kept_u, kept_v], minlength=pieces.size) == 0))
    if pinned.size:
        u, v = np.r_[u, np.full(pinned.size, world)], np.r_[v, pinned]
        weights = np.r_[weights, np.full(pinned.size, 0.5 * weights.min())]  # before any joint
    tree = minimum_spanning_tree(sp.csr_matrix((weights, (u, v)), shape=(world + 1,) * 2)).tocoo()
    neighbours: dict[int, list[int]] = {}
    for u, v in zip(tree.row, tree.col):
        neighbours.setdefault(int(u), []).append(int(v))
        neighbours.setdefault(int(v), []).append(int(u))
    parents = np.full(len(topo.components), -1)
    order, seen = [], set()
    loose = np.zeros(len(topo.components), dtype=bool) if loose is None else loose
    # the world's group first, then of each other group the firmly rigid piece that moves least,
    # among those that keep to one screw over a sequence's keys where some do (core.inbetween_carriers:
    # a box carried steadily while its lid opens, though the lid moves less)
    unsteady = np.zeros(len(topo.components), dtype=bool) if departures is None else departures > 0
    # (after those) a piece still or turning on an axle through it (_on_axles, ROOT_AXLE_SHARE)
    # before one whose own motion is neither: moves add up from the piece fixed to the world only
    # where the joints turn the same way, and a door turning back against the turntable it is
    # hinged on moves less than the turntable, which hung from it left its axle
    unseated = np.zeros(len(topo.components), dtype=bool)
    if screws is not None:
        unseated[pieces] = ~_on_axles(base, index, label, screws[pieces], c.precision, c.u, c.v)
    for root in sorted(neighbours, key=lambda k: (False, False, False, -np.inf) if k == world else
                       (bool(loose[pieces[k]]), bool(unsteady[pieces[k]]), bool(unseated[pieces[k]]),
                        moves[pieces[k]])):
        if root in seen:
            continue
        seen.add(root)
        queue = deque([root])
        while queue:
            k = queue.popleft()
            if k != world:
                order.append(int(pieces[k]))
            for other in neighbours[k]:
                if other not in seen:
                    seen.add(other)
                    # the world's children are roots, and so is a pinned piece whose parent's
                    # motion would move its pins
                    if k != world and (not has_pins[other] or keeps[k, other]):
                        parents[pieces[other]] = pieces[k]
                    queue.append(other)
    if not (parents >= 0).any():
        return None
    return parents, order


def own_axes(screws: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per screw ``(ω, v)`` (R, 6), its angle θ = |ω| (R,), unit axis (R, 3; ω itself where θ = 0), a
    point of its axis ``ω × v / θ²`` (R, 3) and its slide along the axis ``|v · ω̂|`` (R,)."""
    w, moved = screws[:, :3], screws[:, 3:]
    theta = np.linalg.norm(w, axis=1)
    safe = np.where(theta > 0, theta, 1.0)
    axis = w / safe[:, None]
    return theta, axis, np.cross(w, moved) / (safe ** 2)[:, None], np.abs(np.einsum("ka,ka->k", moved, axis))


def _on_axles(base: np.ndarray, index: np.ndarray, label: np.ndarray, screws: np.ndarray, precision: np.ndarray,
              u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Per rigid piece (its vertices ``index`` in runs per piece, ``label``; its own screw ``screws``
    (R, 6) from ``base``), whether it is still or turns on an axle through it: its screw moves no
    vertex by more than the precision of its joints (``precision`` per touching pair ``u``, ``v``:
    the largest), or slides along its axis by no more and the axis passes within
    :data:`ROOT_AXLE_SHARE` of the piece's radius of its centroid (a turntable, a wheel, a spinning
    box)."""
    centres, radii = _piece_centres(base, index, label)
    tolerance = np.zeros(radii.size)
    np.maximum.at(tolerance, u, precision)
    np.maximum.at(tolerance, v, precision)
    theta, axis, point, slide = own_axes(screws)
    moved = screws[:, 3:]
    off = np.linalg.norm(np.cross(centres - point, axis), axis=1)
    still = (theta * radii <= tolerance) & (np.linalg.norm(moved, axis=1) <= tolerance)
    return still | ((theta * radii > tolerance) & (slide <= tolerance) & (off <= ROOT_AXLE_SHARE * radii))


def _pins_kept(base: np.ndarray, index: np.ndarray, label: np.ndarray, count: int, pins: np.ndarray | None,
               pair: tuple[np.ndarray, np.ndarray], motions: tuple[np.ndarray, np.ndarray],
               precision: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per rigid piece (``count`` of them, vertices ``index`` at ``base`` with their ``label``)
    whether it has a pinned vertex (``pins``: bool (n,), or None: none), and per jointed pair
    (``pair``: pieces ``u``, ``v`` (P,)) whether ``v``'s rigid motion (``motions``: rotations,
    translations per piece) keeps ``u``'s pinned vertices within ``precision`` (P,) of where they
    are, and whether ``u``'s keeps ``v``'s (each True where that piece has none). A rigid motion
    keeps a set of points still if it keeps three of them: their centroid, the one farthest from it
    and the one farthest from the line through those two."""
    u, v = pair
    on = np.zeros(index.size, dtype=bool) if pins is None else pins[index]
    rows, owner = index[on], label[on]
    counts = np.bincount(owner, minlength=count)
    if not rows.size:
        return counts > 0, np.ones(u.size, dtype=bool), np.ones(u.size, dtype=bool)
    centre = np.stack([np.bincount(owner, base[rows, d], minlength=count) for d in range(3)], axis=1)
    centre /= np.maximum(counts, 1)[:, None]
    offset = base[rows] - centre[owner]

    def farthest(distance):  # per piece, its pin of the largest distance (the order puts it last)
        last = np.lexsort((distance, owner))
        out = np.zeros(count, dtype=np.intp)
        out[owner[last]] = rows[last]
        return base[out]

    away = farthest(np.linalg.norm(offset, axis=1))
    line = (away - centre) / np.maximum(np.linalg.norm(away - centre, axis=1), np.finfo(float).tiny)[:, None]
    across = offset - np.einsum("ka,ka->k", offset, line[owner])[:, None] * line[owner]
    points = (centre, away, farthest(np.linalg.norm(across, axis=1)))
    rotations, translations = motions
    kept = []
    for mover, still in ((v, u), (u, v)):
        moved = np.max([carry_lengths(rotations[mover], translations[mover], x[still]) for x in points], axis=0)
        kept.append((counts[still] == 0) | (moved <= precision))
    return counts > 0, kept[0], kept[1]


def joint_screws(parents: np.ndarray, screws: list, phantom: list, motions: list | None = None) -> list:
    """Per key (the gap's relatives' ``screws``, (C, 6) each, key times −1, 0, 1, 2), each jointed
    piece's screw coordinates relative to its parent's motion (rows of roots and unjointed pieces
    unchanged), as the pieces' own (:func:`core.screw_motions.key_screws`). Where ``phantom`` says
    the key before or after is a sequence's end condition (extrapolated screws), the relative
    screws are extrapolated the same way (linearly) instead of taken from the extrapolated ones.
    ``motions``: per key, the pieces' rigid motions (rotations (C, 3, 3), translations (C, 3)) where
    known, else None (then those of ``screws``: a whole turn's screw does not hold a translation
    across its axis, see :func:`core.screw_motions.rigid_log`)."""
    children = np.flatnonzero(parents >= 0)
    motions = [None] * len(screws) if motions is None else motions

    def local(k):  # each child's rigid motion relative to its parent's at key k (every child at once)
        rotations, translations = screw_motions.rigid_exps(screws[k]) if motions[k] is None else motions[k]
        return relative_motions(rotations, translations, parents[children], children)

    out = [screw.copy() for screw in screws]  # roots and unjointed pieces: their own
    if children.size:
        before, start, onward, after = screw_motions.key_screws([local(k) for k in range(4)], not phantom[3])
        if phantom[0]:
            before = 2.0 * start - onward
        if phantom[3]:
            after = 2.0 * onward - start
        for key, rows in zip(out, (before, start, onward, after)):
            key[children] = rows
    return out


def joint_groups(parents: np.ndarray) -> np.ndarray:
    """Per piece (C,), its joint group: the root its parents (``parents`` (C,) from
    :func:`joint_tree`, −1 for roots and unjointed pieces) lead to (a piece's own index for those)."""
    group = np.arange(parents.size)
    for _ in range(parents.size):  # one level up per pass; a tree is no deeper than its pieces
        step = np.where(parents[group] >= 0, parents[group], group)
        if (step == group).all():
            break
        group = step
    return group


def composed(parents: np.ndarray, order: list, rotations: np.ndarray, translations: np.ndarray,
             local: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The pieces' motions (rotations (C, 3, 3), translations (C, 3), the pieces' own) with each
    jointed piece's replaced by its parent's composed with its ``local`` motion relative to it
    (rotations, translations at the same factor), parents first."""
    rotations, translations = rotations.copy(), translations.copy()
    local_rotations, local_translations = local
    depth = np.zeros(len(parents), dtype=np.intp)
    for c in order:  # parents first: each child one level below its parent
        if parents[c] >= 0:
            depth[c] = depth[parents[c]] + 1
    for level in range(1, int(depth.max(initial=0)) + 1):  # a level's children at once, on their parents' motions
        c = np.flatnonzero(depth == level)
        p = parents[c]
        translations[c] = carry(rotations[p], translations[p], local_translations[c])
        rotations[c] = rotations[p] @ local_rotations[c]
    return rotations, translations
