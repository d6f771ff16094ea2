"""Rigid pieces the joint rules of :mod:`core.inbetween_joints` cannot place faithfully, which the
gap warns of (a mesh of several pieces should move as one; where it cannot be told how, the user
is told).

:func:`core.inbetween_joints.joint_tree` joints two rigid pieces where they touch (nearest vertices
within an edge) in both keys of a gap and the child's motion relative to the parent's turns about a
point of their contact without sliding, one joint per piece (a spanning tree). Four kinds of pieces
fall outside it, moved by their own rigid motions or by joints other than theirs, which can leave
the other piece (numbers in docs/inbetween-measurements.md, *Joints the keys do not tell*):

- **links apart** (:data:`JOINT_NEAR`): pieces that turn relative to each other about a point in
  the gap between them, near each other in both keys against their size but farther apart than the
  finer one's edges (chain links clearing each other by more than an edge: 0.64 of a link off at
  0.5);
- **joints in a loop**: pieces whose contact holds a joint as the joint tree's do, which the tree
  joins through other pieces (each piece hangs from one other: of held contacts that close a loop
  it keeps all but one), where the tree places them otherwise than their own joint would (a chain
  curled so that links come within an edge of the next-but-one as of the links they hold: 5.4e-3 of
  a link off in the in-betweens where the tree kept the passing contacts; the keys do not tell
  which, so the gap warns where it kept the right ones too);
- **sliding joints**: pieces that touch in both keys and turn together while one slides along the
  other (a finger sliding in a hand; the relative motion a translation, no joint point): no
  prismatic joint is modelled (3.0e-2 of a finger off at 0.5 for a slide of 0.05);
- **joints within rounding** (:data:`JOINT_DOUBT`): joints whose slide is told apart from a chance
  contact's only to within the rigid fits' precision, a share of the pieces' size at which pieces
  touching by chance pass as jointed (hair cards in single precision 1,000 from the origin: 18 of
  200 cards jointed, 4.1e-3 of the diagonal off at 0.5);
- **carriers the keys do not tell** (:func:`_carriers_untold`): a joint group hangs from the piece
  that moves least (in a chain the moves add up from the piece fixed to the world, and so do the
  turns); where another piece of the group turns less than that one, the two readings disagree,
  and two poses have nothing else to tell which piece carries the others (a sequence's keys do
  where a piece of the group keeps to one screw over them: :mod:`core.inbetween_carriers`; where
  none does, they do not either). A box carried while its lid opens, the lid lifted against the
  carry: the box, hung from the lid, left its own path by 7.5e-2–0.20 of the diagonal at ×2; an
  arm carried along a translation, no link on one screw, hung from its outer link (which moved
  0.07 % less than the base): 6.1e-2 off in a sequence.
- **gears turned the other way round** (:func:`_rolled_the_other_way`): pieces touching in both
  keys, each turning about its own axis, the axes parallel, their contact staying put, as meshing
  gears do, whose roll on each other tells a turn more than a half turn from the one the keys are
  read as (the short way round): a gear turned −190° by its mate is read +170°, its teeth through
  the mate's half-way; or both gears past a half turn, which roll on each other taken the other
  way round and not as read (16 and 12 teeth turned +200° / −267°, read −160° / +93°: 0.50 of
  the diagonal off).
- **pieces each on an axle through them, jointed** (:func:`_spun_jointed`, :data:`AXLE_SHARE`):
  a joint held between two pieces that each turn about their own axis through them, as meshing
  gears turned less than their teeth resolve (the same vertex pairs touching in both keys) or
  coarse pieces spinning side by side within an edge of each other do; two poses fit both readings
  (rolling turns about the contact to first order, as a hinge does), and the joint is kept (gears of
  8 and 4 teeth turned 11°: 3.0e-2 of the diagonal off at ×2; cubes 0.1 apart turning −30° / 45°:
  9.9e-2), read between two keys alone. Two gears of equal teeth both past a half turn are not among these: their keys are those
  of the gears turned the short way, to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import screw_motions
from .deformation_fields import rotation_vectors
from .inbetween_joints import (CONTACT_CARRIED, JOINT_REACH, Contacts, _piece_centres, _turns_about, carry,
                               carry_lengths, composed, contact_reach, joint_groups, nearest_pairs, own_axes,
                               relative_motions, screw_axes, slide_precision)
from .inbetween_rigid_fits import turn_spread
from .rotation_continuity import either_way

#: Two rigid pieces whose nearest vertices lie within this share of the smaller one's size in both
#: keys of a gap are near each other, as linked chain links are (a link 1.0 across clearing the next
#: by 0.08); farther apart than their contact reach, and turning relative to each other about a point
#: in the gap between them (their relative screw axis within the gap's width of the midpoint of
#: their nearest vertices, without sliding), they are links apart (the gap warns).
JOINT_NEAR = 0.25
#: A joint whose slide tolerance (:func:`core.inbetween_joints.slide_precision`) is at least this
#: share of the smaller piece's size is told from pieces touching by chance only to within the
#: coordinates' precision: neighbouring hair cards turning about their own roots slide relative to
#: each other by 5e-6–4e-4 (median 2e-3) on cards 0.35 long, which single precision 1,000 from the
#: origin (a tolerance of 2–8e-4, 7e-4 of a card) cannot resolve and at the origin (7e-7) can.
JOINT_DOUBT = 1e-4
#: A joint matters where it would move the child otherwise than the child's own motion does, half-way,
#: by more than this many times the joint's slide tolerance: the composed and own motions of pieces
#: moving as one part by up to 2.2 × it (5,000 tetrahedra turned as one in single precision 1,000
#: from the origin), those of hair cards jointed by chance there by 5–79 ×.
JOINT_STAKE = 3.0
#: Held contacts in a loop are warned only where the joint tree places a piece otherwise than its own
#: joint by more than this share of the piece's size: below it the two placements are one to the eye
#: (80 sequins overlapping on a rolled sheet: 1.6e-4; a curled chain taking passing links: 9e-3 and more).
JOINT_LOOP_SHARE = 1e-3
#: Two jointed pieces each turn about an axle through them (:func:`_spun_jointed`, the gap warns)
#: where each one's own screw axis passes within this share of its contact's distance from its
#: centroid: gears on their axles and coarse pieces spinning about their centres 0 (≤ 4e-14 over
#: the probes' 168 pieces); a link turning about its far end, where it meets the next, ties at 1
#: (arm probe seed 1, no. 30: 0.93, beside a link whose own turn happened to pass 0.23 from its
#: centroid); a knob turning on a lever's end 6–11.
AXLE_SHARE = 0.5


@dataclass
class JointDoubts:
    """What a gap's rigid pieces leave untold: per kind the pieces concerned and the farthest such a
    piece's own rigid motion half-way is from where the pieces' joint would take it (a share of its
    size), or for joints within rounding their tolerance (a share of the smaller piece's size)."""

    apart: int = 0
    apart_share: float = 0.0
    apart_edges: float = 0.0  # the widest gap where links apart meet, in the finer piece's mean edge lengths
    apart_excess: float = 0.0  # the widest such gap ÷ the contact reach joints are found within (over 1)
    looped: int = 0  # pieces of held contacts the joint tree joins through other pieces
    looped_share: float = 0.0
    looped_excess: float = 0.0  # the farthest such placement ÷ the one warned past (JOINT_LOOP_SHARE, JOINT_STAKE)
    sliding: int = 0
    sliding_share: float = 0.0
    rounded: int = 0
    rounded_share: float = 0.0
    carried: int = 0  # pieces of joint groups whose carrier the keys do not tell (_carriers_untold)
    carried_unsteady: bool = False  # read in a sequence whose keys keep none of the group to one screw
    carried_share: float = 0.0
    carried_excess: float = 0.0  # the farthest such placement ÷ the one warned past (JOINT_LOOP_SHARE, JOINT_STAKE)

    rolled: int = 0  # pieces whose roll on a piece they touch tells another way round than they turn
    rolled_turn: float = 0.0  # the farthest such piece's turn rolling tells, taken to a whole turn of its read (radians,
    # signed about the piece's axis as read: its read ± 2π, which the keys give as exactly as the read)
    rolled_read: float = 0.0  # that piece's turn as read (radians, the short way round: ≥ 0 about its axis)
    rolled_excess: float = 0.0  # the farthest a told turn is from the one read ÷ a half turn (over 1)
    spun: int = 0  # jointed pieces that each turn about their own axis through them (_spun_jointed)
    spun_share: float = 0.0
    spun_excess: float = 0.0  # the farthest such placement ÷ the one warned past (JOINT_LOOP_SHARE, JOINT_STAKE)

    def __bool__(self) -> bool:
        return bool(self.apart or self.looped or self.sliding or self.rounded or self.carried or self.rolled
                    or self.spun)


def joint_doubts(topo, base: np.ndarray, nxt: np.ndarray, touching: Contacts | None, reach: float,
                 joints: tuple | None, edges: np.ndarray, misfits: np.ndarray, sizes: np.ndarray,
                 bodies: np.ndarray | None = None, two_poses: bool = False,
                 pins: np.ndarray | None = None, screws: np.ndarray | None = None,
                 departures: np.ndarray | None = None, placements=None) -> JointDoubts | None:
    """The :class:`JointDoubts` of a gap between vertices ``base`` and ``nxt`` (n, 3) of ``topo`` (a
    ``core.inbetween_topology.Topology``), or None where it has none. ``touching``: the rigid
    pieces' :func:`core.inbetween_joints.contacts` between the keys (None: fewer than two);
    ``reach``: the joint distance; ``joints``: :func:`core.inbetween_joints.joint_tree`'s answer
    (``(parents (C,), order)`` or None); ``edges``: each piece's mean edge length (C,); ``misfits``:
    each piece's RMS rigid misfit over the gap's keys (C,); ``sizes``: each piece's size (C,,
    :meth:`~core.inbetween_topology.Topology.diagonals`); ``bodies`` (C,): each piece's body
    leader (:func:`core.rigid_bodies.rigid_bodies`, None: none), whose motion and joint group its
    pieces take; ``two_poses``: the gap reads no key beyond its two (two poses, a linear sequence:
    its carriers are read from those alone, :func:`_carriers_untold`); ``pins``: bool (n,), the
    pinned vertices (a group with one hangs from the world), or None; ``screws`` (C, 6): the
    pieces' own screws from ``base`` to ``nxt`` as the in-betweens take them (None: gears turned
    the other way round are not sought); ``departures`` (C,): in a smooth sequence, how far each
    piece's screws at the keys about the gap leave one screw
    (:func:`core.inbetween_carriers.screw_departures`, 0 where within its fits): a group whose root
    leaves it has its carrier read as two poses' are (None: not read), its two placements compared as
    the gap places them (``placements``, given with ``departures``:
    :meth:`core.inbetween_motion.PieceMotion.hung_motions`). Only pairs of pieces in
    different joint groups (in one group: held contacts the tree joins through other pieces,
    :func:`_joints_in_loops`), and where the joint would move the child otherwise than its own
    motion (or the tree) does (a card turning about its root above a still scalp moves as it would
    on it), count."""
    if touching is None:
        return None
    doubts = JointDoubts()
    parents = np.full(len(topo.components), -1) if joints is None else joints[0]
    c = touching
    pieces, index, label, rotations, translations = c.pieces, c.index, c.label, c.rotations, c.translations
    size = sizes[pieces]
    group = joint_groups(parents)
    group = (group if bodies is None else group[bodies])[pieces]
    stakes = _Stakes(base, index, label, rotations, translations, turn_spread(misfits[pieces] / size))
    children = np.flatnonzero(parents[pieces] >= 0)
    if children.size:  # joints whose slide tolerance is a share of their pieces' size, where they move a piece
        child = pieces[children]
        precision = slide_precision(base[index], nxt[index], reach, misfits, parents[child], child)
        share = precision / np.minimum(sizes[parents[child]], sizes[child])
        doubtful = np.flatnonzero(share >= JOINT_DOUBT)
        if doubtful.size:
            stake = stakes.distances(np.searchsorted(pieces, parents[child[doubtful]]), children[doubtful])
            doubtful = doubtful[stake > JOINT_STAKE * precision[doubtful]]
            doubts.rounded = int(doubtful.size)
            doubts.rounded_share = float(share[doubtful].max(initial=0.0))
    key, first, u, v, relative, precision = c.key, c.first, c.u, c.v, c.relative, c.precision
    if joints is not None and c.held is not None:
        _joints_in_loops(doubts, c, joints, group, size, stakes)
    if joints is not None and (two_poses or departures is not None):
        _carriers_untold(doubts, c, joints, size, stakes, slide_precision(base[index], nxt[index], reach, misfits,
                                                                          pieces, pieces), pins,
                         None if two_poses else departures[pieces] > 0, placements)
    if key.size:  # touching in both keys and turning together, one sliding along the other
        near = (c.nearest <= contact_reach(reach, edges, pieces[u], pieces[v])) & (group[u] != group[v])
        angle = c.angle
        smaller = np.minimum(size[u], size[v])
        sliding = near & (angle * smaller <= precision) & (np.linalg.norm(relative[1], axis=1) > precision)
        if sliding.any():
            # still touching in the next key: a vertex sliding over the other piece's faces stays
            # within that piece's edges of its vertices
            coarser = JOINT_REACH * np.maximum(edges[pieces[u]], edges[pieces[v]])
            sliding &= nearest_pairs(nxt, index, label, pieces.size, float(coarser[sliding].max()), key[first],
                                      sliding)[0] <= coarser
        if sliding.any():
            child = np.where(size[u] <= size[v], u, v)  # the smaller piece slides along the larger
            parent = np.where(size[u] <= size[v], v, u)
            stake = stakes.distances(parent[sliding], child[sliding])
            off = stake > JOINT_STAKE * precision[sliding]
            if off.any():
                doubts.sliding = int(np.unique(child[sliding][off]).size)
                doubts.sliding_share = float(np.max(stake[off] / size[child[sliding][off]]))
    _links_apart(doubts, base, nxt, index, label, pieces, (rotations, translations), reach, edges, misfits, size,
                 group, stakes)
    if two_poses and screws is not None and joints is not None and key.size:
        _spun_jointed(doubts, c, base, joints[0], screws[pieces], size, stakes)
    if screws is not None and key.size:
        _rolled_the_other_way(doubts, c, nxt, screws[pieces], contact_reach(reach, edges, pieces[u], pieces[v]), size,
                              group, turn_spread(misfits[pieces] / size))
    return doubts if doubts else None


def _joints_in_loops(doubts: JointDoubts, c: Contacts, joints: tuple, group: np.ndarray, size: np.ndarray,
                     stakes: _Stakes) -> None:
    """Count in ``doubts`` the rigid pieces of the touching pairs of ``c`` whose contact holds a joint
    (``c.held``) that the joint tree (``joints``: ``(parents (C,), order)``; each rigid piece's joint ``group`` and
    ``size`` (R,)) joins through other pieces instead, where the tree places the smaller piece
    otherwise than their own joint would (:data:`JOINT_STAKE`): the held contacts close a loop, the
    tree keeps all but one of them, and the keys do not tell which one the pieces do not hold (a
    chain curled so that links meet the next-but-one as closely as the links they hold)."""
    u, v = c.u, c.v
    jointed = _rigid_parents(c.pieces, joints[0])
    # pieces that turn relative to each other (those moving as one, as a pile turned whole, stay
    # together whichever contacts the tree keeps)
    turning = c.angle * np.minimum(size[u], size[v]) > c.precision
    looped = np.flatnonzero(c.held & turning & (jointed[u] != v) & (jointed[v] != u) & (group[u] == group[v]))
    if not looped.size:
        return
    child = np.where(size[u] <= size[v], u, v)[looped]  # the smaller piece hangs from the larger
    parent = np.where(size[u] <= size[v], v, u)[looped]
    stake = stakes.distances(parent, child, stakes.jointed(jointed, np.searchsorted(c.pieces, joints[1])))
    off = (stake > JOINT_STAKE * c.precision[looped]) & (stake > JOINT_LOOP_SHARE * size[child])
    if off.any():
        doubts.looped = int(np.unique(np.r_[child[off], parent[off]]).size)
        doubts.looped_share = float(np.max(stake[off] / size[child[off]]))
        allowed = np.maximum(JOINT_STAKE * c.precision[looped][off], JOINT_LOOP_SHARE * size[child[off]])
        doubts.looped_excess = float(np.max(stake[off] / allowed))


def _rigid_parents(pieces: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Per rigid piece (``pieces`` (R,), components ascending), its parent's index among them (−1: a
    root or unjointed); ``parents`` (C,): :func:`core.inbetween_joints.joint_tree`'s."""
    jointed = np.full(pieces.size, -1)
    has_parent = parents[pieces] >= 0
    jointed[has_parent] = np.searchsorted(pieces, parents[pieces[has_parent]])
    return jointed


def _carriers_untold(doubts: JointDoubts, c: Contacts, joints: tuple, size: np.ndarray, stakes: "_Stakes",
                     precision: np.ndarray, pins: np.ndarray | None, unsteady: np.ndarray | None = None,
                     placements=None) -> None:
    """Count in ``doubts`` the rigid pieces of ``c`` in joint groups (``joints``: ``(parents (C,),
    order)``) whose carrier the keys do not tell: two poses, or in a smooth sequence a group whose
    root leaves one screw over the keys about the gap (``unsteady`` (R,) per rigid piece, None: two
    poses; the tree takes a piece on one screw for the root where the group has one, and the
    group's path is then told). The group hangs from its piece that moves least
    (:func:`core.inbetween_joints.joint_tree`: in a chain the moves add up from the piece fixed to
    the world, as the turns do), and another of its pieces turns less than that one (beyond both
    turns' spread: what their rigid fits resolve); counted where the group hung from that piece
    instead places a piece otherwise by more than :data:`JOINT_STAKE` times the group's joint
    precision (``precision`` (R,) per rigid piece) and :data:`JOINT_LOOP_SHARE` of the piece's size
    (a root still, or turning about the joints' axes, places every piece the same either way).
    Groups with a pinned vertex (``pins``: bool (n,) or None) hang from the world, which tells.

    Two poses place the pieces half-way by their two keys' screws (:class:`_Stakes`). A sequence
    splines both trees' screws through the same keys, where they agree, and places a piece by the
    splines (``placements``: :meth:`core.inbetween_motion.PieceMotion.hung_motions`, the gap's
    motions with a given tree at given factors): the two placements differ by the splines' error,
    of order h⁴ in the key spacing h where the two-pose half-way difference is of order h², so
    they are compared as the sequence places them, where they differ most between the keys
    (read at :data:`CARRIER_FACTORS`, :func:`_peak_between`)."""
    jointed = _rigid_parents(c.pieces, joints[0])
    group = joint_groups(joints[0])[c.pieces]
    pinned = np.zeros(c.pieces.size, dtype=bool) if pins is None else \
        np.bincount(c.label, pins[c.index], minlength=c.pieces.size) > 0
    angle = np.linalg.norm(rotation_vectors(c.rotations), axis=1)
    hung = []  # per group whose carrier is in doubt: its members and the piece it would hang from instead
    for root in np.flatnonzero((jointed < 0) & np.isin(np.arange(c.pieces.size), jointed)):
        if unsteady is not None and not unsteady[root]:
            continue  # a piece on one screw carries the group: the keys about the gap tell it
        members = np.flatnonzero(group == group[root])
        least = members[np.argmin(angle[members])]
        if pinned[members].any() or angle[least] >= angle[root] - stakes.spread[root] - stakes.spread[least]:
            continue
        hung.append((members, least))
    if not hung:
        return
    if unsteady is not None:
        apart = _splined_apart(c, joints, stakes, hung, placements)
    else:
        placed = stakes.jointed(jointed, np.searchsorted(c.pieces, joints[1]))
        apart = np.concatenate([_halfway_apart(c, stakes, jointed, placed, members, least) for members, least in hung])
    members = np.concatenate([m for m, _ in hung])
    group_precision = np.concatenate([np.full(m.size, float(precision[m].max())) for m, _ in hung])
    allowed = np.maximum(JOINT_STAKE * group_precision, JOINT_LOOP_SHARE * size[members])
    off = apart > allowed
    if off.any():
        doubts.carried = int(off.sum())
        doubts.carried_unsteady = unsteady is not None
        doubts.carried_share = float(np.max(apart[off] / size[members[off]]))
        doubts.carried_excess = float(np.max(apart[off] / allowed[off]))


#: The factors at which a sequence's two placements of a group whose carrier the keys do not tell
#: are compared (:func:`_carriers_untold`). They agree at the keys, so each vertex's difference is
#: read as ``s (1 − s) q(s)``, ``q`` the quadratic through the three factors' readings
#: (:func:`_peak_between`): exact for a difference of degree four or less vanishing at the keys,
#: as a cubic's ``s (1 − s)(a + b s)`` is. Read at the factors alone, such a cubic peaked as little
#: as 0.914 × as high there as between them (a = b / 4: its peak at s = 0.63).
CARRIER_FACTORS = (0.25, 0.5, 0.75)

#: The steps per gap at which :func:`_peak_between` seeks each vertex's largest difference between
#: the keys (its fitted ``s (1 − s) q(s)``, of degree four: a peak between two steps of 1/64 read
#: to within 0.1 %); the steps hold :data:`CARRIER_FACTORS`, so it never reads less than they do.
CARRIER_PEAK_STEPS = 64

#: Vertices per block in :func:`_peak_between` (memory only: 63 steps × 4,096 vertices, 2 MB).
CARRIER_PEAK_BLOCK = 4096


def _hang_from(parents: np.ndarray, piece: int) -> None:
    """The tree ``parents`` (an index array, −1 for roots) re-rooted in place at ``piece``: the path
    from it to its root reversed."""
    k, below = piece, -1
    while k >= 0:
        parents[k], below, k = below, k, parents[k]


def _depths(parents: np.ndarray) -> np.ndarray:
    """Each node's depth in the forest ``parents`` (an index array, −1 for roots): 0 at the roots."""
    depth = np.zeros(parents.size, dtype=np.intp)
    for _ in range(parents.size):  # one level down per pass; a tree is no deeper than its nodes
        deeper = np.where(parents >= 0, depth[np.maximum(parents, 0)] + 1, 0)
        if np.array_equal(deeper, depth):
            break
        depth = deeper
    return depth


def _halfway_apart(c: Contacts, stakes: "_Stakes", jointed: np.ndarray, placed: tuple, members: np.ndarray,
                   least: int) -> np.ndarray:
    """Per piece of ``members`` (rigid pieces' indices), the farthest its vertices are placed apart
    half-way between two poses by the group's tree (``jointed``: each rigid piece's parent among them;
    ``placed``: the rigid pieces' motions half-way so, :meth:`_Stakes.jointed`) and by the group hung
    from ``least`` instead."""
    # the group's own tree hung from ``least``, the other pieces left unjointed: only the group's
    # members are compared, and composing the others' joints for every group made the check
    # quadratic in the pieces (3,000 hinged cubes: 1.7 s a gap)
    other = np.full(jointed.size, -1)
    other[members] = jointed[members]
    _hang_from(other, least)
    depth = _depths(other)
    rotations, translations = stakes.jointed(other, members[np.argsort(depth[members], kind="stable")])
    out = np.zeros(members.size)
    for i, m in enumerate(members):
        x = stakes.points[stakes.starts[m]:stakes.starts[m] + stakes.counts[m]]
        out[i] = np.linalg.norm(x @ (placed[0][m] - rotations[m]).T + placed[1][m] - translations[m], axis=1).max()
    return out


def _splined_apart(c: Contacts, joints: tuple, stakes: "_Stakes", hung: list, placements) -> np.ndarray:
    """Per piece of the groups ``hung`` (``(members, least)``, rigid pieces' indices), the farthest its
    vertices are placed apart between the keys (read at :data:`CARRIER_FACTORS`, their peak
    :func:`_peak_between`) by the sequence with the gap's joint tree
    (``joints``) and with every such group hung from its ``least`` instead (``placements``: see
    :func:`_carriers_untold`), all groups in one tree."""
    parents = joints[0].copy()
    for _, least in hung:
        _hang_from(parents, int(c.pieces[least]))
    depth = _depths(parents)
    members = np.concatenate([m for m, _ in hung])
    counts = stakes.counts[members]
    first = np.r_[0, np.cumsum(counts)[:-1]]
    x = stakes.points[np.repeat(stakes.starts[members] - first, counts) + np.arange(counts.sum())]
    piece = np.repeat(c.pieces[members], counts)  # every member vertex's component
    apart = [np.einsum("kab,kb->ka", own_rotations[piece] - rotations[piece], x) + own_translations[piece]
             - translations[piece] for (own_rotations, own_translations), (rotations, translations) in zip(
                 placements(joints, CARRIER_FACTORS),
                 placements((parents, np.argsort(depth, kind="stable")), CARRIER_FACTORS))]
    return np.maximum.reduceat(_peak_between(np.array(apart)), first)


def _peak_between(differences: np.ndarray) -> np.ndarray:
    """Per vertex, the largest length between the keys of a difference ``d(s)`` (vectors) read at
    :data:`CARRIER_FACTORS` (``differences`` (3, N, 3)) and zero at both keys: ``d(s) = s (1 − s) q(s)``
    with ``q`` the quadratic through ``d(f) / (f (1 − f))`` at the factors (Lagrange's form), sought
    at :data:`CARRIER_PEAK_STEPS` steps (N,)."""
    factors = np.array(CARRIER_FACTORS)
    s = np.arange(1, CARRIER_PEAK_STEPS) / CARRIER_PEAK_STEPS
    weights = np.outer(s * (1.0 - s), 1.0 / (factors * (1.0 - factors)))  # (steps, 3): d(s) from the readings
    for k in range(factors.size):
        for j in range(factors.size):
            if j != k:
                weights[:, k] *= (s - factors[j]) / (factors[k] - factors[j])
    # |d(s)|² = Σ_kl w_k(s) w_l(s) (D_k · D_l): the readings' six dot products per vertex, then one
    # product for every step (a block of vertices at a time: (steps, block) floats, not (steps, N, 3))
    pairs = [(k, j) for k in range(factors.size) for j in range(k, factors.size)]
    products = np.stack([weights[:, k] * weights[:, j] * (1.0 if k == j else 2.0) for k, j in pairs], axis=1)
    dots = np.stack([np.einsum("na,na->n", differences[k], differences[j]) for k, j in pairs])
    peak = np.concatenate([(products @ dots[:, i:i + CARRIER_PEAK_BLOCK]).max(axis=0, initial=0.0)
                           for i in range(0, dots.shape[1], CARRIER_PEAK_BLOCK)])
    return np.sqrt(np.maximum(peak, 0.0))


class _Stakes:
    """How far a child's own rigid motion half-way (its screw at 0.5) is from its parent's composed
    with the child's motion relative to it (both screws at 0.5), the farthest over the child's
    vertices: what a joint between them would change. A child turning a half turn (as short either
    way, within its ``spread``: the angle its rotation is known to, per rigid piece) is taken the
    way round its parent turns, as the in-betweens turn pieces that move as one: taken its own way,
    pieces of a character turned half round as one rigid body (hair cards, buttons, chain links
    beside the body) read up to 2.7 × their size off the joint's path, the opposite way round."""

    def __init__(self, base, index, label, rotations, translations, spread):
        self.points = base[index]  # the rigid pieces' vertices, piece by piece (``label`` ascending)
        self.counts = np.bincount(label, minlength=len(rotations))
        self.starts = np.r_[0, np.cumsum(self.counts)[:-1]]
        self.motions = rotations, translations
        self.logs = screw_motions.rigid_logs(rotations, translations)
        self.half = screw_motions.rigid_exps(0.5 * self.logs)
        self.spread = spread

    def distances(self, parent: np.ndarray, child: np.ndarray, placed: tuple | None = None) -> np.ndarray:
        """Per pair of pieces ``parent``, ``child`` (P,; indices among the rigid pieces), that distance;
        ``placed``: the pieces' motions half-way to compare instead of their own screws' (rotations
        (K, 3, 3), translations (K, 3); :meth:`jointed`)."""
        if not child.size:
            return np.zeros(0)
        local_rotations, local_translations = self._local_halves(parent, child)
        if placed is None:
            rotations, translations = self.half
            own_rotations, own_translations = self._own_halves(parent, child)
        else:
            rotations, translations = placed
            own_rotations, own_translations = rotations[child], translations[child]
        counts = self.counts[child]
        pair = np.repeat(np.arange(child.size), counts)  # every child vertex's pair, pair by pair
        first = np.r_[0, np.cumsum(counts)[:-1]]
        x = self.points[np.repeat(self.starts[child] - first, counts) + np.arange(counts.sum())]
        p = parent[pair]
        own = carry(own_rotations[pair], own_translations[pair], x)
        local = carry(local_rotations[pair], local_translations[pair], x)
        joint = carry(rotations[p], translations[p], local)
        return np.maximum.reduceat(np.linalg.norm(own - joint, axis=1), first)

    def _own_halves(self, parent: np.ndarray, child: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per pair (P,), the child's own screw half-way (rotations, translations), a half turn
        the way round its parent's screw turns."""
        rotations, translations = self.motions
        return screw_motions.rigid_exps(0.5 * screw_motions.rigid_logs(
            rotations[child], translations[child], self.logs[parent, :3], spread=self.spread[child]))

    def jointed(self, parents: np.ndarray, order: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rigid pieces' motions half-way as the joint tree places them (rotations (K, 3, 3),
        translations (K, 3)): a root by its own screw, a child by its parent's placement composed
        with its screw relative to the parent (``parents`` (K,): each piece's parent among the rigid
        pieces, −1 for a root; ``order``: the jointed ones among them, parents first), as
        :func:`core.inbetween_joints.composed` composes the in-betweens' motions."""
        local_rotations = np.repeat(np.eye(3)[None], parents.size, axis=0)
        local_translations = np.zeros((parents.size, 3))
        children = np.flatnonzero(parents >= 0)
        local_rotations[children], local_translations[children] = self._local_halves(parents[children], children)
        return composed(parents, order, *self.half, (local_rotations, local_translations))

    def _local_halves(self, parent: np.ndarray, child: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per pair (P,), the child's screw relative to the parent half-way (rotations, translations)."""
        return screw_motions.rigid_exps(0.5 * screw_motions.rigid_logs(*relative_motions(*self.motions, parent, child)))


def _links_apart(doubts: JointDoubts, base, nxt, index, label, pieces, motions, reach, edges, misfits, size,
                 group, stakes: _Stakes) -> None:
    """Count in ``doubts`` the rigid pieces (``pieces``, their vertices ``index`` with their ``label``;
    ``motions``, ``size``, joint ``group``: theirs) that are links apart (:data:`JOINT_NEAR`): sought
    among the pieces whose near distance exceeds their contact reach (the others are
    :func:`core.inbetween_joints.joint_tree`'s), pair by pair over their vertices' KD-trees."""
    from scipy.spatial import cKDTree  # noqa: PLC0415 (only meshes of several rigid pieces)

    finest = contact_reach(reach, edges, pieces, pieces)
    large = np.flatnonzero(JOINT_NEAR * size > finest)
    if large.size < 2:
        return
    counts = np.bincount(label, minlength=pieces.size)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    centres = np.add.reduceat(base[index], starts) / counts[:, None]
    radii = np.sqrt(np.maximum.reduceat(np.sum((base[index] - centres[label]) ** 2, axis=1), starts))
    pairs = cKDTree(centres[large]).query_pairs(2.0 * radii[large].max() + JOINT_NEAR * size[large].max(),
                                                output_type="ndarray")
    if not pairs.size:
        return
    u, v = large[pairs[:, 0]], large[pairs[:, 1]]
    smaller = np.minimum(size[u], size[v])
    close = (np.linalg.norm(centres[u] - centres[v], axis=1) <= radii[u] + radii[v] + JOINT_NEAR * smaller) \
        & (group[u] != group[v])
    u, v, smaller = u[close], v[close], smaller[close]
    relative_rotations, relative_translations = relative_motions(*motions, u, v)
    angle, axis, slide = screw_axes(relative_rotations, relative_translations)
    precision = slide_precision(base[index], nxt[index], reach, misfits, pieces[u], pieces[v])
    finer = contact_reach(reach, edges, pieces[u], pieces[v])
    turning = np.flatnonzero((np.abs(slide) <= precision) & (angle * smaller > precision))
    if not turning.size:
        return
    # what a joint would change (the smaller piece the child): nothing where the larger one is still
    child = np.where(size[u] <= size[v], u, v)[turning]
    parent = np.where(size[u] <= size[v], v, u)[turning]
    stake = stakes.distances(parent, child)
    trees: dict[tuple[int, int], cKDTree] = {}

    def nearest(x, a, b, bound):  # the nearest vertices of pieces a and b in x (distance, midpoint) within bound
        tree = trees.get((id(x), b))
        if tree is None:
            tree = trees[id(x), b] = cKDTree(x[index[label == b]])
        points = x[index[label == a]]
        distance, which = tree.query(points, distance_upper_bound=bound)
        k = int(np.argmin(distance))
        if not np.isfinite(distance[k]):
            return np.inf, None
        return float(distance[k]), 0.5 * (points[k] + tree.data[which[k]])

    apart = set()
    for p, a, b, risk in zip(turning, u[turning], v[turning], stake):
        if not risk > JOINT_STAKE * precision[p]:
            continue
        bound = JOINT_NEAR * smaller[p]
        gap_base, midpoint = nearest(base, a, b, bound)
        if not finer[p] < gap_base <= bound:
            continue
        gap_next, _ = nearest(nxt, a, b, bound)
        if not gap_next <= bound:
            continue
        # a point of the relative screw axis (x ↦ R x + t holds every p + λ · axis), in the base key
        # as the midpoint is (the parent's motion undone)
        held = np.linalg.lstsq(np.eye(3) - relative_rotations[p], relative_translations[p] - slide[p] * axis[p],
                               rcond=None)[0]
        offset = midpoint - held
        # the nearest vertices stand for the pieces' nearest points to within the coarser one's
        # edge (links whose tips overlap: their surfaces cross where no vertex lies)
        sampled = max(edges[pieces[a]], edges[pieces[b]])
        if np.linalg.norm(offset - (offset @ axis[p]) * axis[p]) <= max(gap_base, gap_next) + sampled + precision[p]:
            apart.update((int(a), int(b)))
            doubts.apart_share = max(doubts.apart_share, float(risk / smaller[p]))
            doubts.apart_edges = max(doubts.apart_edges, gap_base / float(min(edges[pieces[a]], edges[pieces[b]])))
            doubts.apart_excess = max(doubts.apart_excess, gap_base / float(finer[p]))
    doubts.apart = len(apart)


def _rolled_the_other_way(doubts: JointDoubts, c: Contacts, nxt: np.ndarray, screws: np.ndarray, finer: np.ndarray,
                          size: np.ndarray, group: np.ndarray, spread: np.ndarray) -> None:
    """Count in ``doubts`` the rigid pieces of the touching pairs of ``c`` that roll on each other as
    meshing gears do but turn, as read, the other way round: pairs of different joint ``group``s
    within the finer piece's edges (``finer`` (P,)) of each other in both keys, each turning about
    its own axis without sliding along it (``screws`` (R, 6): the rigid pieces' own, as the
    in-betweens take them), the axes parallel (to the pair's slide precision over the smaller
    piece's ``size``), their contact (its closest vertex pair) staying put between the keys
    (:data:`core.inbetween_joints.CONTACT_CARRIED`). Meshing gears roll: at their contact their
    surfaces move alike, so one's turn tells the other's (in the inverse ratio of the contact's
    distances from the axles), which the keys give only to a whole turn. Where the turn so told is
    past a half turn and more than a half turn from the piece's own (two gears of 20 and 10 teeth,
    the large one turned 95°: the small one −190°, read +170°, its teeth through the other's
    half-way), the keys were read the short way round; where it is past a half turn but nearer the
    piece's own, and the mate's turn the other way round rolls the piece onto its own the other way
    round closer than the two turns read roll on each other, both were (both pieces counted); a
    piece turning a half turn (within its ``spread`` (R,): either way) is warned of as such
    elsewhere."""
    u, v, precision = c.u, c.v, c.precision
    w = screws[:, :3]
    theta, axis, point, slide = own_axes(screws)
    smaller = np.minimum(size[u], size[v])
    tilt = np.linalg.norm(np.cross(axis[u], axis[v]), axis=1)
    asked = ((c.nearest <= finer) & (group[u] != group[v]) & (theta[u] * size[u] > precision)
             & (theta[v] * size[v] > precision) & (slide[u] <= precision) & (slide[v] <= precision)
             & (tilt * smaller <= precision))
    if not asked.any():
        return
    nearest, later = nearest_pairs(nxt, c.index, c.label, c.pieces.size, float(finer[asked].max()), c.key[c.first],
                                   asked)
    contact = c.nearest_at
    carried = np.maximum(*(carry_lengths(c.rotations[k], c.translations[k], contact) for k in (u, v)))
    asked &= (nearest <= finer) & (np.linalg.norm(np.nan_to_num(later) - contact, axis=1) <= CONTACT_CARRIED * carried)
    pairs = np.flatnonzero(asked)
    if not pairs.size:
        return
    rolled = set()
    for a, b in ((u, v), (v, u)):
        a, b = a[pairs], b[pairs]
        # b's turn about its axis that moves its surface at the contact as a's own turn moves a's
        velocity = np.cross(w[a], contact[pairs] - point[a])
        lever = np.cross(axis[b], contact[pairs] - point[b])
        told = np.einsum("pa,pa->p", velocity, lever) / np.maximum(np.einsum("pa,pa->p", lever, lever),
                                                                   np.finfo(float).tiny)
        # past a half turn, and more than one from the turn read: the keys' short way round is its alias
        other = (np.abs(told) > np.pi) & (np.abs(told - theta[b]) > np.pi) & ~either_way(theta[b], spread[b])
        # past a half turn but nearer the turn read, where a's alias (its turn the other way round,
        # θ_a − 2π) rolls b onto b's alias (θ_b − 2π) closer than the reads roll on each other:
        # both gears past a half turn (16 and 12 teeth turned +200° / −267°, read −160° / +93°: the
        # large one's read rolls the small one +213°, 120° from its read; its alias +200° rolls it
        # −267°, its alias exactly). Reads that are right, the told turn off only by the contact's
        # place off the pitch point (a ratio 1 + δ), give the aliases the larger residual where
        # the gears' ratio is 1 or more: theirs |δ θ_b − 2π (ρ − 1)| against δ θ_b
        told_alias = told * (1.0 - 2.0 * np.pi / theta[a])
        nearer = np.abs(told_alias - theta[b] + 2.0 * np.pi) < np.abs(told - theta[b])
        both = (np.abs(told) > np.pi) & ~other & nearer & ~either_way(theta[a], spread[a]) \
            & ~either_way(theta[b], spread[b])
        for k in np.flatnonzero(other | both):
            rolled.update((int(b[k]), int(a[k])) if both[k] else (int(b[k]),))
            turn = float(told_alias[k] if both[k] else told[k])
            excess = float(abs(turn - theta[b[k]]) / np.pi)
            if excess > doubts.rolled_excess:
                # the turn said is the read's whole-turn alias nearest the told turn: the keys give
                # it exactly (the told one is off by the contact's place off the pitch point)
                whole = float(theta[b[k]] + 2.0 * np.pi * np.round((turn - theta[b[k]]) / (2.0 * np.pi)))
                doubts.rolled_turn, doubts.rolled_read = whole, float(theta[b[k]])
            doubts.rolled_excess = max(doubts.rolled_excess, excess)
    doubts.rolled = len(rolled)


def _spun_jointed(doubts: JointDoubts, c: Contacts, base: np.ndarray, parents: np.ndarray, screws: np.ndarray,
                  size: np.ndarray, stakes: _Stakes) -> None:
    """Count in ``doubts`` the jointed pieces (``parents`` (C,): the joint tree's) of the touching
    pairs of ``c`` that each turn about their own axis through them: each piece's own screw
    (``screws`` (R, 6), as the in-betweens take them) turns without sliding along its axis (to the
    pair's slide precision over the piece's ``size`` (R,)) and passes within :data:`AXLE_SHARE` of
    the contact's distance from the piece's centroid (in ``base``) of that centroid (an axle through
    it) and nearer it than the contact (:func:`core.inbetween_joints._turns_about` false), the two
    not on one axle (each axis that near the other's centroid too: two pieces turning on a shared
    axle, a propeller on its shaft, turn relative to each other about it as a hinge's do, and
    nothing rolls between them), where the joint places the child otherwise than its own screw
    half-way (``stakes``) by more than :data:`JOINT_STAKE` × the precision and
    :data:`JOINT_LOOP_SHARE` of its size. Two poses fit both readings: meshing gears turned less
    than their teeth are resolved (the contact's place moves
    with both gears by under an edge), or pieces spinning side by side within an edge of each other,
    turn relative to each other about a point of their contact as a hinge's pieces do, and a hinge
    whose two pieces happen to turn about axles through them reads the same (warned too: the keys
    do not tell). A link turning about its far end, where it meets the next, ties at the share's 1,
    a knob turning on a lever's end at 6–11: neither is read so. Read only where the gap reads its
    two keys alone (:func:`joint_doubts`' ``two_poses``): a smooth sequence splines the joint's
    relative screw across the keys, which follows the roll, and the two poses' stake overstates
    where it places the child (involute gears keyed 5°–12° a key: gaps 1.9e-6 of the diagonal off
    read past it)."""
    u, v, precision = c.u, c.v, c.precision
    pieces = c.pieces
    forward = parents[pieces[v]] == pieces[u]
    held = forward | (parents[pieces[u]] == pieces[v])
    if not held.any():
        return
    theta, axis, point, slide = own_axes(screws)
    spinning = held & (theta[u] * size[u] > precision) & (theta[v] * size[v] > precision) \
        & (slide[u] <= precision) & (slide[v] <= precision)
    if not spinning.any():
        return
    pairs = np.flatnonzero(spinning)
    centres = _piece_centres(base, c.index, c.label)[0]
    contact = c.nearest_at[pairs]
    # each on an axle through it: its own axis passes within AXLE_SHARE of the contact's distance
    # from its centroid (a gear's axle, a cube's centre: 0; a link turning about its far end ties
    # there, 1; a knob turning on a lever's end turns about a point out beyond it, 6–11); and the
    # two not on one axle (each axis within that share of the other's centroid too): pieces turning
    # on a shared axle, as a propeller on its shaft, turn relative to each other about that axle, a
    # hinge's turn, and nothing rolls between them; and each axis nearer its centroid than the
    # contact (_turns_about false)
    one, two = u[pairs], v[pairs]
    reach = [AXLE_SHARE * np.linalg.norm(contact - centres[k], axis=1) for k in (one, two)]
    apart = [[np.linalg.norm(np.cross(centres[m] - point[k], axis[k]), axis=1) for m in (one, two)] for k in (one, two)]
    shared = (apart[0][1] < reach[1]) & (apart[1][0] < reach[0])
    through = (~_turns_about(contact, centres, c.rotations, c.translations, one, two)
               & (apart[0][0] < reach[0]) & (apart[1][1] < reach[1]) & ~shared)
    pairs = pairs[through]
    if not pairs.size:
        return
    parent = np.where(forward[pairs], u[pairs], v[pairs])
    child = np.where(forward[pairs], v[pairs], u[pairs])
    stake = stakes.distances(parent, child)
    allowed = np.maximum(JOINT_STAKE * precision[pairs], JOINT_LOOP_SHARE * size[child])
    off = stake > allowed
    if off.any():
        doubts.spun = int(np.unique(np.r_[parent[off], child[off]]).size)
        doubts.spun_share = float(np.max(stake[off] / size[child[off]]))
        doubts.spun_excess = float(np.max(stake[off] / allowed[off]))


def joint_warnings(doubts: JointDoubts | None, key_names: list[str], gap: int) -> list[tuple[str, float]]:
    """The warnings ``(message, excess)`` of gap ``gap`` of a sequence about its rigid pieces'
    joints (:func:`joint_doubts`); ``key_names``: the keys as warnings name them. ``excess``
    (:attr:`core.errors.ShapeDifferenceWarning.excess`): the message's measure ÷ what the rule
    allows it, where it has an allowance: links apart, their gap ÷ the contact reach joints are
    found within; joints in a loop, the placement apart ÷ the one warned past; joints within
    rounding, their slide tolerance ÷ :data:`JOINT_DOUBT`; carriers the keys do not tell, the
    placement apart ÷ the one warned past; gears turned the other way round, how far
    the turn their roll tells is from the one read ÷ a half turn; pieces each on an axle through them,
    jointed, the placement apart ÷ the one warned past. Sliding joints have no allowance (not
    modelled: any slide is warned past the fits' precision): 0."""
    if not doubts:
        return []
    between = f"between {key_names[gap]} and {key_names[gap + 1]}"
    problems = []
    if doubts.apart:
        problems.append((f"{between}, {doubts.apart} rigid piece(s) turn about a point between them and a piece "
                         f"near them as jointed links do but stay up to {doubts.apart_edges:.1f} edge lengths from it "
                         "where they meet (joints are found within one): each moves by its own rigid motion, up to "
                         f"{100 * doubts.apart_share:.1f} % of its size off the joint's path half-way (links modelled "
                         "within an edge length of each other where they meet are jointed)", doubts.apart_excess))
    if doubts.looped:
        problems.append((f"{between}, {doubts.looped} rigid piece(s) touch and turn about a point where they meet "
                         "as jointed pieces do, as well as the pieces the joints join them through (each piece "
                         "hangs from one other: a loop of such contacts, as in a chain curled so that every other "
                         "link comes as close to the next-but-one as to the links it holds): the joints place "
                         f"them up to {100 * doubts.looped_share:.2g} % of a piece's size from where a joint "
                         "between the two would half-way, and the keys do not tell which pieces hold each other "
                         "(keys closer together, before the pieces come that close, leave no loop)",
                         doubts.looped_excess))
    if doubts.sliding:
        problems.append((f"{between}, {doubts.sliding} rigid piece(s) slide along a piece they touch while turning "
                         "with it (as a finger sliding in a hand): sliding joints are not modelled, and each moves "
                         f"by its own rigid motion, up to {100 * doubts.sliding_share:.1f} % of its size off the "
                         "sliding joint's path half-way (keys closer together bring them nearer)", 0.0))
    if doubts.rounded:
        problems.append((f"{between}, {doubts.rounded} joint(s) between rigid pieces are told from pieces touching "
                         f"by chance only to {100 * doubts.rounded_share:.2g} % of their size (coordinates rounded in "
                         "single precision far from the origin, or noise): pieces that merely touch (hair cards, debris) "
                         "may be moved as jointed (keys with the mesh nearer its object's origin tell them apart)",
                         doubts.rounded_share / JOINT_DOUBT))
    if doubts.carried:
        told = ("and none of them keeps to one screw over the keys about the gap, so the keys do not tell which "
                "piece carries the others (as an arm carried along a path on which no link moves steadily; "
                "keys closer together bring the two placements nearer)") if doubts.carried_unsteady else (
                "and two keys alone do not tell which piece carries the others (as a box carried while its lid "
                "opens; a smooth sequence's keys on either side tell it)")
        problems.append((f"{between}, {doubts.carried} rigid piece(s) jointed to each other are placed as carried by "
                         "the piece of theirs they hang from (one still or turning on an axle through it, else the one that "
                         "moves least), which turns more than another of them: carried by "
                         f"that one instead, they would be up to {100 * doubts.carried_share:.2g} % of a piece's size "
                         f"elsewhere {'between the keys' if doubts.carried_unsteady else 'half-way'}, {told}",
                         doubts.carried_excess))
    if doubts.rolled:
        problems.append((f"{between}, {doubts.rolled} rigid piece(s) touch a piece in both keys and turn about axes "
                         "parallel to its, their contact staying put, as meshing gears do, but rolling on it turns "
                         f"one {np.degrees(doubts.rolled_turn):+.0f}° where the keys, read the short way round, turn it "
                         f"{np.degrees(doubts.rolled_read):+.0f}° about the same axis (the same keys: they give a turn "
                         "only to a whole turn): each moves by its own rigid motion, the short way (keys closer together, "
                         "each gear turning under a half turn between them, tell the way round)",
                         doubts.rolled_excess))
    if doubts.spun:
        problems.append((f"{between}, {doubts.spun} rigid piece(s) touch and each turn about their own axis through "
                         "them, as meshing gears or pieces spinning side by side do, but turn relative to each other "
                         "about where they touch, as jointed pieces do: they are moved as jointed, up to "
                         f"{100 * doubts.spun_share:.2g} % of a piece's size from where each piece's own turn would "
                         "take it half-way, and two keys do not tell which they are (pieces modelled more than an "
                         "edge length apart are never jointed; gears turned by a tooth or more between keys, or "
                         "a finer mesh where they touch, show their contact rolling; pieces hinged there, as a door "
                         "on a turntable, are placed right)", doubts.spun_excess))
    return problems
