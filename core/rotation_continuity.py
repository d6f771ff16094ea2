"""Which way round rotations turn: rotation vectors ``ω`` (angle ``|ω|``, at most π as
:func:`core.deformation_fields.rotation_vectors` gives them) taken continuous past a half turn —
across keys, the representative ``ω + 2πk ω̂`` nearest a reference (:func:`unwrapped_rotation_vectors`),
and across the mesh's edges (:func:`continuous_rotation_vectors`) unless a jump joins a fold's crease
(:func:`jumping_pairs`, :func:`creased`, :data:`WRAP_CREASE`) — and half turns, as short either way,
told apart (:func:`either_way`, :func:`the_other_way`). The pieces' rigid motions, as screws:
:mod:`core.screw_motions`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

#: Rotations within this angle (radians) of a half turn may turn either way: both are as short.
#: Far above rounding (1e-15) and far below any motion meant to turn one way.
HALF_TURN_TOLERANCE = 1e-6
#: Rotations within this angle (radians) of none are the identity when a turn is continued
#: (``unwrap``): the identity's representatives are ``2πk u`` for every axis ``u``, and the axis
#: of a rotation vector of length ~1e-16 is rounding noise (a sheet keyed every half turn: its key
#: two half turns on was continued about a random axis, 181 % edge deviation half-way).
ZERO_TURN_TOLERANCE = 1e-9
#: Neighbouring triangles whose rotation vectors jump past a half turn (:func:`continuous_rotation_vectors`)
#: while their rotations differ by more than this (radians) meet at a fold's crease, which says
#: nothing of the way round: a sequence's part turning past a half turn is taken continuous across
#: the mesh only where none of its piece's jumps is one. A closed tube or a thin arm curled 120–170°
#: per key at two joints jumps between neighbours 0.2–9.2° apart (their bend per ring of the mesh);
#: a sheet swinging off a rod that stops dead, keys 4 / 8 frames apart, 22–55 / 37–58° (medians
#: 50 / 53°): taken continuous there, its in-betweens went 0.54 / 0.50 → 5.7 / 1.4 × the linear
#: blend's error. A piece none of whose neighbours' rotations are that far apart bends without a
#: crease (:data:`core.inbetween_whole_rotations.BENT_TURN`).
WRAP_CREASE = np.pi / 6
#: A connected set of triangles whose residuals want the other way round
#: (:func:`residuals_turning_whole_way`) is turned only where over this share of the edges on its
#: border join its residuals to their neighbours' once turned (a jump past a half turn there
#: already): elsewhere the turned set tears from the rest of the mesh. A curtain flung over by a
#: paddle (keys 16 frames apart): its flap of 14,000 triangles, 82 % of its border joining, turned,
#: is half-way 32° from the simulated frames instead of 156°; a cape stopping dead wants a set of
#: 1,074 triangles turned whose border joins at 55 %, 131° from the simulation turned against 95°
#: kept; a banner's set whose border joins at 64 %, nearer the simulation turned (42° against
#: 146°), tears along the rest of its border: 0 → 97 flipped triangles in its gap.
JOINING_SHARE = 0.75


def either_way(theta: np.ndarray, spread: np.ndarray | float = 0.0) -> np.ndarray:
    """Whether rotations of angles ``theta`` (radians) are half turns as short either way round:
    within :data:`HALF_TURN_TOLERANCE` of π, or within their ``spread`` (what each is known to)."""
    return np.abs(np.asarray(theta) - np.pi) < np.maximum(HALF_TURN_TOLERANCE, spread)


def the_other_way(w: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The rotation vectors (P, 3) of the rotations ``w`` (P, 3; angles ``theta`` (P,)) taken the
    other way round, ``ω − 2π ω̂``: the same rotations (``−ω`` is their inverse); rows with a zero
    angle are left as they are."""
    return w - (2.0 * np.pi / np.where(theta > 0, theta, np.inf))[:, None] * w


def unwrapped_rotation_vectors(rotvec: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Rotation vectors (m, 3) of the rotations ``rotvec`` (m, 3), each the representative
    ``ω + 2πk ω̂`` (k = −1, 0, 1, and further where the reference is past 2π) nearest its row of
    ``reference`` (m, 3): a turn continuing across keys past a half turn (the per-row counterpart
    of :func:`~core.screw_motions.rigid_log`'s ``unwrap``). Only rows
    with ``|ω| + |reference| > π`` can change (elsewhere ``ω`` is within π of the reference and the
    other representatives are farther)."""
    theta = np.sqrt(np.einsum("ij,ij->i", rotvec, rotvec))
    reach = np.sqrt(np.einsum("ij,ij->i", reference, reference))
    identity = np.flatnonzero((theta <= ZERO_TURN_TOLERANCE) & (reach > np.pi))
    rows = np.flatnonzero((theta + reach > np.pi) & (theta > ZERO_TURN_TOLERANCE))
    if not rows.size and not identity.size:
        return rotvec
    return nearest_representatives(rotvec, theta, reference, identity, rows)


def residuals_turning_whole_way(rotvec: np.ndarray, turns: np.ndarray, components: np.ndarray, pairs: np.ndarray,
                                areas: np.ndarray, part: float) -> np.ndarray:
    """Rotation residuals (m, 3) ``q`` of a mesh's triangles to their pieces' rigid turns ``turns``
    (C, 3; rotation vectors, past π where a piece's turn is continued across keys), taken the other
    way round (:func:`the_other_way`) on each connected part of the mesh whose in-betweens then turn
    it the way its whole rotation ``W = exp(w) exp(q)`` goes and whose residuals then join their
    neighbours' across its border (paper §5.3's rotations, interpolated as ``exp(s w) exp(s q)``).
    ``components``: each triangle's piece (m,); ``pairs`` (E, 2): the triangles sharing an edge.

    The principal residual (at most π) is the short way relative to the piece's rigid fit, which is
    not the triangle's way where the fit turns one way and a part of the piece turns near a half turn
    the other (``|q| + |w| > π``): a curtain flung over by a paddle, keys 16 frames apart, fits 58°
    while a flap of it turns 152° about an axis 134° from the fit's; its residuals of 168° about the
    fit's side composed to the long way round, 156° from the simulation's frames half-way. A
    triangle wants the other way where its half-way rotation (``s = ½``) is nearer the whole
    rotation's half by more than :data:`HALF_TURN_TOLERANCE` (the whole rotation read the short way,
    or as far past a half turn as its piece's turn ``w`` goes past one: a piece tumbling 200° per
    key keeps its residuals). The two ways of one triangle are a half turn apart half-way, so a
    triangle taken the other way beside one that is not tears the field between them unless their
    residuals jump past a half turn there already (the other representative of the one nearer the
    other's than its own); the triangles wanting it are therefore taken together, per connected set
    (joined by the edges of ``pairs``), and a set is turned only where over :data:`JOINING_SHARE` of
    the edges on its border join its residuals to their neighbours' once turned, and where it is
    over ``part`` of its piece's area (``areas``: the triangles' areas (m,)): a part of the piece
    turning on its own, not a patch of a crumpled fold (patches of 10–1,000 triangles of a 15k
    curtain pushed by a ball, keys 8 frames apart, whose borders join, turned: 0.513 → 0.520 × the
    linear blend's error, though nearer the simulation's turns). The paddle's flap (14,000
    triangles, 12 % of the curtain's area, 82 % of its border) is turned, 32° from the simulation
    half-way against 156°. Rows with ``|q| + |w| ≤ π`` are returned as they are (the other way's
    half-way turns farther than any whole rotation's half); rigid pieces (``q ≈ 0``) too."""
    theta = np.sqrt(np.einsum("ij,ij->i", rotvec, rotvec))
    reach = np.sqrt(np.einsum("ij,ij->i", turns, turns))[components]
    near = (theta > ZERO_TURN_TOLERANCE) & (theta + reach > np.pi)
    # a set turned is over ``part`` of its piece's area: pieces whose rows that may want it are
    # less are left as they are
    count = len(turns)
    total = np.bincount(components, areas, minlength=count)
    large = np.bincount(components[near], areas[near], minlength=count) > part * total
    rows = np.flatnonzero(near & large[components])
    if not rows.size:
        return rotvec
    piece, angle = components[rows], theta[rows]
    axis = rotvec[rows] / angle[:, None]
    # unit quaternions (vector, scalar: SciPy's order) of the residual, of its half either way
    # round, exp(½ q) and exp(½ (q − 2π q̂)), and of the piece's turn and half turn, composed
    # here: SciPy's Rotation composes 14,000 rotations in 11 ms, and five compositions per gap
    # are 13 % of a 10k banner's in-betweens' CPU (these products: 1.3 %)
    cos, sin = np.cos(0.25 * angle), np.sin(0.25 * angle)
    kept_half = np.concatenate([sin[:, None] * axis, cos[:, None]], axis=1)
    other_half = np.concatenate([-cos[:, None] * axis, sin[:, None]], axis=1)
    residual = np.concatenate([(2.0 * sin * cos)[:, None] * axis, (cos * cos - sin * sin)[:, None]], axis=1)
    fit, half = Rotation.from_rotvec(turns).as_quat(), Rotation.from_rotvec(0.5 * turns).as_quat()
    # the whole rotation exp(w) exp(q) and its half: the short way (the quaternion with a
    # non-negative scalar, plus the identity, normalised), or as far past a half turn as the
    # piece's own turn is (a piece tumbling 200° per key: its triangles' whole turns continue its
    # way, not the short one)
    whole = _quaternion_products(fit[piece], residual)
    whole *= np.where(whole[:, 3] < 0.0, -1.0, 1.0)[:, None]
    target = whole + np.array([0.0, 0.0, 0.0, 1.0])
    target /= np.linalg.norm(target, axis=1)[:, None]
    beyond = np.where((np.sqrt(np.einsum("ij,ij->i", turns, turns)) > np.pi)[:, None],
                      turns - Rotation.from_rotvec(turns).as_rotvec(), 0.0)
    far = np.flatnonzero(np.any(beyond[piece] != 0.0, axis=1))
    if far.size:
        continued = unwrapped_rotation_vectors(Rotation.from_quat(whole[far]).as_rotvec(), beyond[piece[far]])
        target[far] = Rotation.from_rotvec(0.5 * continued).as_quat()
    # half-way, exp(½ w) exp(½ q) either way round against the whole rotation's half: the angle
    # between two rotations is 2 arccos |their quaternions' dot product|, and the dot product of
    # exp(½ w) x with the target is x's with exp(−½ w) target
    conjugate = half * np.array([-1.0, -1.0, -1.0, 1.0])
    seen = _quaternion_products(conjugate[piece], target)
    kept_angle = 2.0 * np.arccos(np.minimum(np.abs(np.einsum("ij,ij->i", seen, kept_half)), 1.0))
    other_angle = 2.0 * np.arccos(np.minimum(np.abs(np.einsum("ij,ij->i", seen, other_half)), 1.0))
    wanted = rows[other_angle < kept_angle - HALF_TURN_TOLERANCE]
    # a set is within its piece's triangles that want it: pieces where they are not over ``part``
    # of its area have none to turn
    if not np.any(np.bincount(components[wanted], areas[wanted], minlength=count) > part * total):
        return rotvec
    wants = np.zeros(len(rotvec), dtype=bool)
    wants[wanted] = True
    swap = _joining_sets(rotvec, theta, pairs, wants, areas, part * total[components])
    if not swap.any():
        return rotvec
    out = rotvec.copy()
    out[swap] = the_other_way(rotvec[swap], theta[swap])
    return out


def _quaternion_products(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Row by row, the unit quaternions (P, 4; vector then scalar, as SciPy's ``as_quat``) of the
    rotations ``first`` then ``second`` composed (``first * second`` in SciPy's Rotation)."""
    x1, y1, z1, s1 = first.T
    x2, y2, z2, s2 = second.T
    return np.stack([s1 * x2 + s2 * x1 + y1 * z2 - z1 * y2, s1 * y2 + s2 * y1 + z1 * x2 - x1 * z2,
                     s1 * z2 + s2 * z1 + x1 * y2 - y1 * x2, s1 * s2 - x1 * x2 - y1 * y2 - z1 * z2], axis=1)


def _joining_sets(rotvec: np.ndarray, theta: np.ndarray, pairs: np.ndarray, wants: np.ndarray, areas: np.ndarray,
                  least: np.ndarray) -> np.ndarray:
    """Per triangle (bool (m,)), whether it ``wants`` (bool (m,)) the other way round and its
    connected set of triangles that do (joined by ``pairs`` (E, 2) both of whose triangles want it),
    taken so, joins its neighbours outside across over :data:`JOINING_SHARE` of its border's edges:
    the other representative of the triangle inside nearer the neighbour's rotation vector
    (``rotvec`` (m, 3), angles ``theta`` (m,)) than its own, and whose area (``areas`` (m,)) is over
    ``least`` (m,; per triangle, its piece's). A set with no border (a whole piece) is not turned."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    chosen = np.flatnonzero(wants)
    local = np.full(len(rotvec), -1)
    local[chosen] = np.arange(len(chosen))
    ends = local[pairs]
    inside = ends[(ends >= 0).all(axis=1)]
    count, label = connected_components(coo_matrix((np.ones(len(inside)), (inside[:, 0], inside[:, 1])),
                                                   shape=(len(chosen), len(chosen))), directed=False)
    large = np.bincount(label, areas[chosen], minlength=count) > least[chosen[np.unique(label, return_index=True)[1]]]
    out = np.zeros(len(rotvec), dtype=bool)
    if not large.any():
        return out
    border = pairs[((ends >= 0).sum(axis=1) == 1) & large[label[ends.max(axis=1)]]]
    turning = np.where(wants[border[:, 0]], border[:, 0], border[:, 1])
    staying = np.where(wants[border[:, 0]], border[:, 1], border[:, 0])
    own = rotvec[turning] - rotvec[staying]
    other = the_other_way(rotvec[turning], theta[turning]) - rotvec[staying]
    joins = np.einsum("ij,ij->i", own, own) > np.einsum("ij,ij->i", other, other)
    joined = np.bincount(label[local[turning]], joins, minlength=count)
    parted = np.bincount(label[local[turning]], ~joins, minlength=count)
    out[chosen] = ((joined > JOINING_SHARE * (joined + parted)) & large)[label]
    return out


def continuous_rotation_vectors(rotvec: np.ndarray, pairs: np.ndarray, pieces: np.ndarray, turned=None,
                                toward=None, free=None) -> np.ndarray:
    """Rotation vectors (m, 3) of the rotations ``rotvec`` (m, 3) of a mesh's triangles, continuous
    across its edges past a half turn: ``pairs`` (E, 2) are the triangles sharing an edge. A part
    that turns by more than a half turn while the part it hangs from does not (a strip curled by
    240° on one arc: its tip turns by 240°, which the principal rotation vector, at most π, takes
    as 120° the other way) has its rotation vectors jump where their angle passes π; the
    in-between turns every triangle by its vector times the factor, so the part beyond the jump
    went the other way round. Across such a jump (a neighbour's other representative
    ``ω ± 2π ω̂`` nearer than its own: :func:`jumping_pairs`) the mesh is cut into
    regions; in each connected set of regions the one holding the least-turned triangle keeps its
    vectors, and each region reached from it across a jump takes the representatives continuous
    across it. ``pieces``: each triangle's connected piece of the mesh (m,). ``turned``: a function returning how far each triangle turns (m,) when that is not
    the angle of ``rotvec`` (residuals to a rigid motion: the part that stays put is the one whose
    whole rotation is least, whatever its residual), called only where there is a jump.
    ``toward``: the rotation vectors (m, 3) of the rigid motion each triangle's piece makes and the
    triangles' weights (m,) (their areas), or None. Continued from either end, a part turning by
    a whole turn more than the other end has the same turns between neighbours: the two readings
    differ by a whole turn of the entire piece (a tail whose root turns −60° and tip −300° read
    from the tip as +300° / +60°), and where both ends turn about as little the least-turned
    triangle picks one by the mesh's tessellation. With ``toward``, a linked set of regions whose
    least turns exceed its root's by no more than the root's own (a root that turns so is not
    known to stay) plus the step of the turn from either least-turned triangle to its neighbours
    (the mesh samples the turn no finer) is continued from the one of them whose reading
    is nearest the rigid motion's, in the weighted least squares along each triangle's axis (the
    piece as a whole turning as its rigid fit): the rigid fit's principal rotation does not tell
    the way round past a half turn itself (a strip held at one end and curled by 220° fits +129°
    the other way), so it only breaks the tie — after the count of neighbours whose readings'
    vectors lie more than :data:`WRAP_CREASE` apart: a whole turn of every triangle about its own
    axis is one turn of the piece only where those axes agree (a tail wagging about one axis), and
    where they part (an arm curling about y while it turns a little about z) a reading that keeps
    fewer than half as many neighbours that far apart as every other is taken (the arm curled
    170° per key at two joints turning 10° per key about z: its part that stays turns 10°, its
    tip 22°, and the rigid fit, reading the curl the other way round, took the tip: 27–78 % of
    the diagonal off). ``free``: per triangle
    (bool (m,)) or None, whether its linked set's least-turned region is not known to stay (the
    readings of a sequence's gaps disagree there): every region of such a set is tied, and the
    rigid motion picks.

    A connected piece left with a jump (its jumps do not close up: crumpled cloth, around whose
    folds the rotations wind by a whole turn) keeps its principal vectors: taken across the mesh
    there, two poses of a banner 8 / 16 frames apart went 0.747 / 0.832 → 0.792 / 0.923 × the
    blend's error (edge deviation 3.53 / 6.15 → 4.21 / 7.04 %). Whether a jump joins a fold's
    crease rather than a smooth part wrapping past a half turn is the caller's to tell
    (:func:`creased` on :func:`jumping_pairs`, :data:`WRAP_CREASE`). Rotations that never come near
    a half turn are returned as they are."""
    if not len(pairs):
        return rotvec
    jumps = jumping_pairs(rotvec, pairs)
    if not jumps.any():
        return rotvec
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    m = len(rotvec)
    joined = pairs[~jumps]
    count, region = connected_components(coo_matrix((np.ones(len(joined)), (joined[:, 0], joined[:, 1])), shape=(m, m)),
                                         directed=False)
    across = pairs[jumps]
    within = region[across[:, 0]] == region[across[:, 1]]
    if within.any():  # a jump inside one region cannot be undone: its piece is left as it is
        across = across[~np.isin(pieces[across[:, 0]], pieces[across[within, 0]])]
    if not across.size:
        return rotvec
    # the regions linked by jumps, one jump per linked pair of regions ((region, region) → its jump)
    ends = np.sort(region[across], axis=1)
    _, first = np.unique(ends, axis=0, return_index=True)
    links = coo_matrix((np.ones(len(first)), (ends[first, 0], ends[first, 1])), shape=(count, count))
    link = dict(zip(map(tuple, ends[first].tolist()), first.tolist()))
    theta = np.sqrt(np.einsum("ij,ij->i", rotvec, rotvec))
    least = np.full(count, np.inf)
    amount = theta if turned is None else turned()
    np.minimum.at(least, region, amount)
    # each linked set's least-turned region (the first in the order of least turn) is its root; one
    # search from a node joined to the roots reaches every linked region (a search from each root
    # costs a pass over all regions: 0.4 s at 3,000 pieces with a single jump)
    by_least = np.argsort(least, kind="stable")
    _, sets = connected_components(links, directed=False)
    _, firsts = np.unique(sets[by_least], return_index=True)
    roots = by_least[firsts]
    roots = roots[np.isin(roots, ends[first])]  # a region with no link has nothing to take
    tails, heads = np.r_[ends[first, 0], np.full(len(roots), count)], np.r_[ends[first, 1], roots]
    graph = coo_matrix((np.ones(len(tails)), (tails, heads)), shape=(count + 1, count + 1))
    order, parent = breadth_first_order(graph.tocsr(), count, directed=False, return_predecessors=True)
    turns = np.zeros(count + 1)  # whole turns added per region (and the joining node's: none)
    axis = rotvec / np.where(theta > 0, theta, 1.0)[:, None]
    for r in order[1:]:
        if parent[r] == count:  # a root keeps its vectors
            continue
        pair = across[link[(min(parent[r], r), max(parent[r], r))]]
        inside, outside = (pair[0], pair[1]) if region[pair[1]] == r else (pair[1], pair[0])
        reached = rotvec[inside] + 2.0 * np.pi * turns[parent[r]] * axis[inside]
        turns[r] = np.round(np.dot(reached - rotvec[outside], axis[outside]) / (2.0 * np.pi))
    if toward is not None:
        reference, weights = toward
        linked = np.zeros(count + 1, dtype=bool)
        linked[ends[first].ravel()] = True
        rows = np.flatnonzero(linked[region])
        # a region's continued vectors (θ + 2π·turns) â point along u = ±â (θ ≤ π, â the principal
        # axis: the reverse where turns < 0), continuous across the mesh; a whole turn k more of
        # the entire set adds 2π k u, and k = −turns·sign makes a region the root. The k nearest
        # the rigid motion (minimising Σ w (|θ + 2π·turns| + 2πk − reference · u)² over the set)
        direction = np.where(turns[:count] >= 0, 1.0, -1.0)
        along = direction[region[rows]] * np.einsum("ij,ij->i", reference[rows], axis[rows])
        off = along - np.abs(theta[rows] + 2.0 * np.pi * turns[region[rows]])
        owner = sets[region[rows]]
        total = np.bincount(owner, weights[rows], minlength=len(sets))
        nearest = np.bincount(owner, weights[rows] * off, minlength=len(sets)) \
            / (2.0 * np.pi * np.maximum(total, np.finfo(float).tiny))
        # ... among the regions whose least turn exceeds the root's by no more than the root's
        # own (a root turning by that much is not known to be the part that stays) plus the step
        # of the turn from their least-turned triangle, or the root's, to its joined neighbours
        # (the mesh samples the rotations no finer there); elsewhere the root stays
        step = turn_steps(amount, joined)
        by_turn = np.lexsort((amount, region))
        _, lowest_row = np.unique(region[by_turn], return_index=True)
        resolution = step[by_turn[lowest_row]]  # per region: the step at its least-turned triangle
        root_of = np.zeros(len(sets), dtype=np.int64)
        root_of[sets[roots]] = roots
        root = root_of[sets]
        margin = least[root] + np.maximum(resolution, resolution[root])
        loose = np.zeros(len(sets), dtype=bool)
        if free is not None:
            loose[sets[region[free]]] = True
        tied = np.flatnonzero(linked[:count] & ((least - least[root] <= margin) | loose[sets]))
        candidate = -turns[tied] * direction[tied]
        # a whole turn of the entire set is one rigid turn only where its triangles turn about one
        # axis (a wagging tail); where their axes part (an arm curling about one axis while it
        # turns a little about another) the readings differ in shape, and one that joins fewer
        # neighbours more than WRAP_CREASE apart than half of every other's is taken before the
        # rigid motion is asked (counts within twice the least do not tell: a mesh creased all
        # over keeps about as many apart either way); not where the set is free: there the
        # readings of the gaps around decide, through the rigid turn
        counts = np.zeros(len(tied))
        strict = ~loose[sets[tied]]
        counts[strict] = _creases_read(rotvec, pairs, region, sets, turns[:count], direction, axis, linked[:count],
                                       tied[strict], candidate[strict])
        fewest = np.full(len(sets), np.inf)
        np.minimum.at(fewest, sets[tied], counts)
        order = np.lexsort((np.abs(candidate - nearest[sets[tied]]), counts > 2.0 * fewest[sets[tied]], sets[tied]))
        _, best = np.unique(sets[tied[order]], return_index=True)
        shift = np.zeros(len(sets))
        shift[sets[tied[order[best]]]] = candidate[order[best]]
        turns[:count] += np.where(linked[:count], shift[sets] * direction, 0.0)
    if not turns.any():
        return rotvec
    out = rotvec + (2.0 * np.pi * turns[region])[:, None] * axis
    left = jumping_pairs(out, pairs)
    if left.any():  # the pieces with a jump left keep their principal vectors (but at a lone triangle)
        left &= ~lone_triangles(out, pairs)[pairs].any(axis=1)
        kept = np.isin(pieces, pieces[pairs[left, 0]])
        out[kept] = rotvec[kept]
    return out


def lone_triangles(rotvec: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Per triangle (bool (m,)), whether its rotation (``rotvec`` (m, 3)) lies more than
    :data:`WRAP_CREASE` from each of its neighbours' across ``pairs`` (E, 2): a triangle crushed in
    a key (a skin's fold at a weight ramp's end, a sliver of a re-meshed scan) whose polar rotation
    tells nothing of the way round the part around it turns. A jump past a half turn left at such a
    triangle after :func:`continuous_rotation_vectors` is no fold the rotations wind around, and
    does not keep its piece's principal vectors: an irregular tube skinned at two joints by 100°
    and 150° (its tip 250°, ramps 0.6 long) has one triangle crushed to a fifth of its shape at the
    second ramp's end, turning 121–128° from its three neighbours; counted, that jump alone turns
    the tip the short way round in every in-between (0.58 of the diagonal off the rig half-way)."""
    apart = creased(rotvec, pairs, WRAP_CREASE)
    m = len(rotvec)
    return np.bincount(pairs[apart].ravel(), minlength=m) == np.bincount(pairs.ravel(), minlength=m)


def _creases_read(rotvec: np.ndarray, pairs: np.ndarray, region: np.ndarray, sets: np.ndarray, turns: np.ndarray,
                  direction: np.ndarray, axis: np.ndarray, linked: np.ndarray, tied: np.ndarray,
                  candidate: np.ndarray) -> np.ndarray:
    """For each tied region ``tied`` (T,) of :func:`continuous_rotation_vectors` (its linked set read
    from it: the set's whole turns ``turns`` (per region) plus ``candidate`` (T,) × ``direction``),
    how many neighbouring triangles of its set (``pairs`` (E, 2)) get rotation vectors more than
    :data:`WRAP_CREASE` apart: the in-betweens turn each triangle by its vector times the factor,
    so those neighbours part by up to that angle. Counted only in sets with more than one tied
    region (elsewhere 0: nothing to choose). The count depends on a tied region only through its
    set and its candidate, so it is counted once per distinct pair of them: a rigid half turn of a
    smooth 55,000-vertex mesh cuts it into thousands of tied regions read with two or three
    candidates, where counting per region takes minutes."""
    out = np.zeros(len(tied))
    several = np.bincount(sets[tied], minlength=len(sets)) > 1
    chosen = np.flatnonzero(several[sets[tied]])
    if not chosen.size:
        return out
    first, second = region[pairs[:, 0]], region[pairs[:, 1]]
    inside = pairs[linked[first] & linked[second] & (sets[first] == sets[second]) & several[sets[first]]]
    owner = sets[region[inside[:, 0]]]
    readings, which = np.unique(np.stack([sets[tied[chosen]], candidate[chosen]], axis=1), axis=0,
                                return_inverse=True)
    counts = np.zeros(len(readings))
    ends_of = {}
    for k, (linked_set, turn) in enumerate(readings):
        ends = ends_of.get(linked_set)
        if ends is None:
            ends = ends_of[linked_set] = inside[owner == linked_set]
        whole = 2.0 * np.pi * (turns + turn * direction)[region[ends]]  # (P, 2)
        vectors = rotvec[ends] + whole[:, :, None] * axis[ends]
        apart = np.linalg.norm(vectors[:, 0] - vectors[:, 1], axis=1)
        counts[k] = np.count_nonzero(apart > WRAP_CREASE)
    out[chosen] = counts[np.ravel(which)]
    return out


def turn_steps(amount: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Per triangle (m,), the largest change of its turn ``amount`` (m,) to a neighbour across
    ``pairs`` (E, 2): how finely the mesh samples the turn there."""
    step = np.zeros(len(amount))
    change = np.abs(amount[pairs[:, 0]] - amount[pairs[:, 1]])
    np.maximum.at(step, pairs[:, 0], change)
    np.maximum.at(step, pairs[:, 1], change)
    return step


def creased(rotvec: np.ndarray, pairs: np.ndarray, crease: float) -> np.ndarray:
    """Per pair of triangles (bool (E,); ``pairs`` (E, 2) indices into ``rotvec`` (m, 3)), whether
    their rotations differ by more than ``crease`` (radians, whichever representative each vector
    is): the unit quaternions' ``|q₁ · q₂|``, the cosine of half that angle, below ``cos(crease / 2)``
    (composing the rotations and taking the angle costs 5 × more: 0.33 s on 270k pairs). Each
    triangle's quaternion is made once where the pairs name more rows than the mesh has."""
    if pairs.size > len(rotvec):
        quaternions = Rotation.from_rotvec(rotvec).as_quat()
        first, second = quaternions[pairs[:, 0]], quaternions[pairs[:, 1]]
    else:
        first, second = (Rotation.from_rotvec(rotvec[pairs[:, k]]).as_quat() for k in (0, 1))
    return np.abs(np.einsum("ij,ij->i", first, second)) < np.cos(0.5 * crease)


def jumping_pairs(rotvec: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Per pair of neighbouring triangles (bool (E,)), whether the second's rotation vector jumps
    past a half turn from the first's: another of its representatives is nearer the first's."""
    theta = np.sqrt(np.einsum("ij,ij->i", rotvec, rotvec))
    near = np.flatnonzero(theta[pairs[:, 0]] + theta[pairs[:, 1]] > np.pi)  # only these can jump
    out = np.zeros(len(pairs), dtype=bool)
    if near.size:
        first, second = rotvec[pairs[near, 0]], rotvec[pairs[near, 1]]
        whole = (2.0 * np.pi / np.maximum(theta[pairs[near, 1]], ZERO_TURN_TOLERANCE))[:, None] * second
        gap = second - first
        # |gap ± whole|² = |gap|² ± 2 gap·whole + |whole|²: below |gap|² where |2 gap·whole| > |whole|²
        out[near] = 2.0 * np.abs(np.einsum("ij,ij->i", gap, whole)) > np.einsum("ij,ij->i", whole, whole)
    return out


def nearest_representatives(rotvec, theta, reference, identity, rows) -> np.ndarray:
    """``rotvec`` (m, 3) (angles ``theta``) with the ``identity`` rows replaced by the whole turns
    nearest their ``reference`` rows and the ``rows`` by the representative ``ω + 2πk ω̂``
    (k = −1, 0, 1, the first of equally near ones) nearest theirs; k = ±2 … as well where a
    reference reaches past 2π (the nearest is ``k = round((r − θ) / 2π)``, ``r`` the reference along
    the axis, so ``|k| ≤ |r| / 2π + 1``: a part of an arm turning 280° per gap continued to 560° at
    the key after, its principal axis reversed past 3π, needs ``k = −2`` from a reference of 2.9π)."""
    out = rotvec.copy()
    out[identity] = _unwrapped_identity(reference[identity])
    if not rows.size:
        return out
    axis = rotvec[rows] / theta[rows, None]
    reach = np.sqrt(np.max(np.einsum("ij,ij->i", reference[rows], reference[rows])))
    turns = int(reach // (2 * np.pi)) + 1
    candidates = np.stack([(theta[rows] + 2 * np.pi * k)[:, None] * axis for k in range(-turns, turns + 1)])
    distance = np.einsum("krj,krj->kr", candidates - reference[rows], candidates - reference[rows])
    out[rows] = candidates[np.argmin(distance, axis=0), np.arange(rows.size)]
    return out


def _unwrapped_identity(reference: np.ndarray) -> np.ndarray:
    """The representatives ``2πk û`` (r, 3) of the identity nearest the rows of ``reference``
    (r, 3): along each reference, ``k`` its length in whole turns (rounded; zero for a null one)."""
    reach = np.sqrt(np.einsum("ij,ij->i", reference, reference))
    turns = np.round(reach / (2 * np.pi))
    return reference * (2 * np.pi * turns / np.where(reach > 0, reach, 1.0))[:, None]
