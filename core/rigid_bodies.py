"""Rigid pieces that move as one body: separate rigid pieces of a mesh whose relative rigid motion is
the identity in every key a gap's splines read (a low-poly sword's grip, guard and blade in a
character's hand), given one interpolated rigid motion, whatever the distance between them.

Each piece's own interpolated motion (its screw, its flying group's point, the deforming piece that
carries it: :mod:`core.inbetween_carried`) is splined from its own fits, which agree with the
others' only at the keys: a sword of three 8-vertex pieces on a 55,527-vertex character, each
carried by the skin of the hand nearest it, parted by up to 1.5e-3 of the diagonal between keys 8
frames apart. Pieces near each other are jointed (:mod:`core.inbetween_joints`), which composes
their motions; pieces farther apart than an edge are not, and are joined here instead: all the
members of a body take its leader's motion, so their relative placement is the base key's at every
factor. The grouping reads the pieces' rigid motions from the base key to every other key the gap
reads (not those extrapolated past a sequence's ends), so pieces that keep still relative to each
other in two keys but move apart in the others are never joined. A body holding a pinned piece or
one others are jointed to moves by that piece's motion (a pin nested in a robot arm's link moves
with the link, which its joints turn), so pins and joints are kept."""

from __future__ import annotations

import numpy as np

from .inbetween_rigid_fits import turn_spread
from .spread_groups import spread_groups

#: Least spread (radians; translations over the scene's size) of the rigid motions of two pieces of
#: one body: keys exact to double precision agree to ~1e-15, a single-precision cache to ~1e-7 of
#: the size (:func:`core.inbetween_flight.flying_groups` links the pieces turned about one point so).
BODY_MOTION_SPREAD = 0.5e-6


def rigid_bodies(motions: list, candidates: np.ndarray, nonrigidity: np.ndarray, mass: np.ndarray,
                 scale: float, links: np.ndarray | None = None, parents: np.ndarray | None = None) -> np.ndarray | None:
    """Per component (C,), the component whose interpolated rigid motion it takes (its body's
    leader; its own index where it moves alone), or None where no two pieces move as one.

    ``motions``: per key the gap reads other than its base (rotations (C, 3, 3), translations
    (C, 3): each component's best rigid motion from the base key); ``candidates`` (bool (C,)): the
    pieces that may join a body (rigid, unpinned, no piece jointed to them); ``nonrigidity`` (C,):
    each piece's RMS rigid misfit over its size over the keys, what its motions are known to
    (:func:`core.inbetween_rigid_fits.turn_spread`, at least :data:`BODY_MOTION_SPREAD`);
    ``mass`` (C,): each piece's mass (the leader is a body's heaviest piece of the first kind it
    has of ``links``, leaves (below), the rest: its fits the best known; the first of equals);
    ``scale``: the scene's size, which translations are measured against. Two pieces are one body
    where their motions in all those keys together differ by at most the sum of their spreads,
    and so is every chain of such pieces (:func:`core.spread_groups.spread_groups`).

    ``links`` (bool (C,), or None: none): firmly rigid pieces others are jointed to
    (:mod:`core.inbetween_joints`), whose interpolated motion composes their joints' turns and
    carries their children, or pinned (their motion keeps their pinned vertices): they lead a
    body, never join one. A piece
    that moves as one with a link in every key (a pin nested inside a robot arm's link, a bolt in a
    plate that turns at a hinge) takes the link's motion, the heaviest link's where several agree;
    the links keep their own. On its own screw a pin nested
    in the wrist of an arm bent 40°, 120° and 170° at three hinges took the short way of its net
    turn (18° half-way) while its link took the joints' (165°), a third of the arm's diagonal away.
    ``parents`` ((C,), or None: none jointed): each piece's parent in the joint tree
    (:func:`core.inbetween_joints.joint_tree`, −1: none). Candidates with a parent (leaves: none is
    jointed to them) lead a body without a link before its other pieces, whose own screws would
    leave their joints: a pin touching the link below it and nested in the one above, which turns
    a half turn about their joint, takes that link's way round, not the other. A leaf joins a
    body only where its leader is its parent or hangs from the same parent (a turn relative to
    that parent which holds both their joints' contacts turns both about one axis): two motions
    alike in the keys part between them where they compose different joints (a lever hinged on a
    still post turned 120° about its hinge, as the second link of an arm turned by two 60° hinges
    moves in net: on the link's motion the lever left its hinge by 4.1e-2 of the diagonal
    half-way, 0.27 at ×2)."""
    links = np.zeros(len(candidates), dtype=bool) if links is None else np.asarray(links, dtype=bool) & ~candidates
    leaves = np.zeros(len(candidates), dtype=bool) if parents is None else (np.asarray(parents) >= 0) & candidates
    rows = np.flatnonzero(candidates | links)
    if not candidates.any() or rows.size < 2 or not motions:
        return None
    vectors = np.concatenate([np.concatenate([rotations[rows].reshape(-1, 9), translations[rows] / scale], axis=1)
                              for rotations, translations in motions], axis=1)
    spread = np.maximum(turn_spread(nonrigidity[rows]), BODY_MOTION_SPREAD)
    group = spread_groups(vectors, spread)
    counts = np.bincount(group)
    if counts.max() < 2:
        return None
    # per group, its heaviest link, else its heaviest leaf, else its heaviest member (the first of
    # equals: lexsort's last of the ascending order)
    order = np.lexsort((-rows, mass[rows], leaves[rows], links[rows], group))
    last = np.r_[np.flatnonzero(np.diff(group[order])), order.size - 1]
    leaders = np.empty(counts.size, dtype=np.intp)
    leaders[group[order[last]]] = rows[order[last]]
    leader = np.arange(len(candidates))
    joining = candidates[rows]
    leader[rows[joining]] = leaders[group[joining]]
    if leaves.any():  # a leaf keeps its own joint unless its leader's holds it (its parent, or its sibling)
        parted = leaves & (leader != parents) & (parents[leader] != parents)
        leader[parted] = np.flatnonzero(parted)
    if (leader == np.arange(len(candidates))).all():
        return None
    return leader
