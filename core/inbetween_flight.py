"""Free flight, impacts and flying bodies across a gap of a sequence: the conditions under which a
gap's splines end on the parabola through its start (free flight up to an impact), start on the
one through its end (after an impact), and the point each rigid piece turns about (a hinge's
axis, a thrown body's centre), all read from the keys around the gap."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import deformation_fields as df, screw_motions
from .inbetween_rigid_fits import turn_spread
from .inbetween_motion import RIGID_PLACEMENT_SCALE, SIMILAR_SHAPE_MISFIT
from .splines import REST_START_LIMIT
from .spread_groups import spread_groups

if TYPE_CHECKING:
    from .inbetween_topology import Topology

#: Smallest turn (radians) over a gap for which a rigid piece's axis is asked whether it flies
#: (:func:`flying_groups`); below it the screw is a translation to within the turn's arc.
FLYING_MIN_TURN = 1e-6
#: Largest difference (third, or second with one key beside the gap; :func:`flying_groups`), as a
#: fraction of the piece's bounding-box diagonal, of the positions of the point a rigid piece is
#: turned about: a point of a hinge's axis or a flying body's centre meets it to round-off (1e-15
#: of the size; a single-precision cache 1e-7).
FLYING_TOLERANCE = 1e-4
#: A deforming piece turning as a whole (non-rigidity, RMS misfit of its rigid fits over its size,
#: over :data:`~core.inbetween_motion.RIGID_PLACEMENT_SCALE`; its guide is its interpolated rigid
#: motion, :data:`core.inbetween_guide.ARC_GUIDE_STRAIN_RATIO`) turns about an axis line only where
#: every key around the gap turns it about that line (:func:`_on_common_axis`: a cloth on a
#: turntable) to this many times its non-rigidity (the fits' rotations and
#: positions are known to about that; two keys' misses add up) — at most this many times the first
#: share of :data:`~core.inbetween_motion.SIMILAR_SHAPE_MISFIT`: past it the fits' turns are no
#: body's, and a tolerance growing with the non-rigidity would pass any four motions (a sheet
#: tossed while it crumples, non-rigidity 0.23: 8 × that lets every key's axis through) — else
#: about its centroid, which follows its own path. So a free cloth carried or thrown through a
#: large turn (a napkin on a sliding, spinning tray; a tumbling sheet) keeps its centre on the
#: spline of the keys' centroids, where the screw about its fixed axis swings it along a helix off
#: that path (keys 16 frames apart, a 12k sheet tossed while it crumples: 1.103 × the blend's RMS
#: and 1.457 × Catmull–Rom's with the screw, 0.722 × and 0.954 × about its centroid; a napkin on
#: the tray 1.021 and 0.948 × Catmull–Rom's; numbers in docs/inbetween-measurements.md, *A napkin
#: on a moving tray, a tossed sheet, a flag in turbulence, a sheet down a flight of steps*).
#: Four rigid motions always have a point of zero third difference somewhere
#: (the difference is an invertible map of the point but for a common axis), so a deforming body
#: that tumbles and bounces (a cushion with internal springs falling onto a block: a point 1.1 of
#: its size from its centre) would be turned about a point that is no hinge, as the screw turns it
#: about an axis that is none (keys 16 frames apart: 1.164 × the blend's RMS; about its centre
#: 1.014 ×, 0.957 × Catmull–Rom's). Numbers in docs/inbetween-measurements.md, *Deforming bodies that tumble*.
DEFORMING_AXIS_NOISE = 8.0
#: Free flight up to an impact. The Catmull–Rom tangent at a gap's end key averages the velocity
#: over the gap and the next one; when something stops the cloth right after that key (a sheet
#: landing on a collider) it is too slow for the gap before, which is still in free flight, and
#: the in-betweens there lag and bulge toward the landed shape. A component in free flight through
#: the gap — rigid (non-rigidity, as RIGID_PLACEMENT_SCALE, under FREE_FLIGHT_NONRIGIDITY) from the
#: key before it, or from rest at a sequence's first key, to the gap's end key, its centroid at
#: constant acceleration over the four keys up to that end (third difference under
#: FREE_FLIGHT_JERK × the gap's move: a sheet that hit a ramp flat in the gap before fails it) or
#: still before a launch (the gap after moves it over IMPACT_SLOWDOWN × as far: a hanging curtain
#: a ball hits right after the key, whose settling before fails the jerk test) —
#: and deformed at the key after (non-rigidity over 2 × FREE_FLIGHT_NONRIGIDITY and over
#: FREE_FLIGHT_JUMP × the flight's: more than steady deformation from rest gives) ends the gap on
#: the parabola through its start instead (every spline of it: ``parabolic_end`` of
#: :class:`core.splines.HermiteGap`), exact for constant acceleration. RMS ÷ the linear blend's,
#: keys 8 frames apart: 14k tablecloth 0.638 → 0.353, 10k drape 0.912 → 0.549, unseen irregular
#: 10k mesh 0.913 → 0.493, unseen 30k tablecloth 0.618 → 0.317; of 93 sequence cells on 31 cloths
#: 27 closer, two farther (a 10k sheet hanging from two corners at g = 4, 0.164 → 0.184; a sheet
#: landing flat on a ramp, g = 16, 0.909 → 0.937); other scales in docs/inbetween-measurements.md, *Free flight
#: up to an impact*.
FREE_FLIGHT_NONRIGIDITY = 5e-3
FREE_FLIGHT_JUMP = 4.0
FREE_FLIGHT_JERK = 0.5
#: After an impact. The mirror case: where the cloth hit something inside the gap before, the
#: Catmull–Rom tangent at this gap's start key averages the fast fall before it with the slow
#: settling after it, and the in-betweens overshoot the landed shape (a drape on a sphere, keys 4,
#: 20 and 36: 2.26 × the blend's RMS in the gap after the landing). A component deformed across
#: the gap before — the key before seen from this gap's start key, non-rigidity over 2 ×
#: FREE_FLIGHT_NONRIGIDITY and over FREE_FLIGHT_JUMP × this gap's own — whose centroid moved over
#: IMPACT_SLOWDOWN × as far in the gap before as in this one starts the gap on the parabola
#: through its end (value and tangent) instead (``parabolic_start`` of
#: :class:`core.splines.HermiteGap`): constant deceleration. Keys cut from the middle of a fall
#: (40 cells of 8 cloths): 13 → 6 above a peer (drape on a sphere, keys 16 apart from frame 4:
#: 1.651 → 0.874 × the blend); from frame 0 it moves four of 87 sequence cells, all closer (a 10k
#: drape at g = 8 0.548 → 0.472 × the blend, a shrinking sheet at g = 4 1.065 → 0.928); a swing's
#: turning point fails the deformation test, and at a slowdown of 2 a hanging sheet and a soft
#: flag keep every digit (numbers in docs/inbetween-measurements.md, *After an impact*). The gap before then
#: ends with that start velocity (its positions; its other splines with the next gap's secant), so
#: the two gaps meet with one velocity: the cloth landed inside the gap before and arrives slow (a
#: 10k drape on a sphere, keys 8 apart: the second difference across the key 5.0 → 2.1 × the
#: simulation's, the gap before it 1.02 → 0.81 × Catmull–Rom's RMS). Not where the piece is hit
#: again right after the gap (:func:`hit_again`): the parabola's end tangent then carries the second
#: hit (a sewn pillow landed and then squashed, keys 4 apart: 2.83 → 1.41 × the blend in the still
#: gap between, 1.14 → 0.39 × in the gap of the landing; docs/inbetween-measurements.md, *A second
#: hit right after a landing*).
IMPACT_SLOWDOWN = 2.0


def free_flight(before, nxt, after, start_limit: float | None, steady: np.ndarray | None) -> np.ndarray | None:
    """Per component (C,), whether it is in free flight through a gap and hit right after it (see
    :data:`FREE_FLIGHT_NONRIGIDITY`), from the non-rigidity (C,) of the keys before the gap, at its
    end and after it, each seen from its start key; or None if no component is. A first gap
    (``start_limit`` set) counts from rest only (its key before is an end condition); a later one
    needs ``steady`` (C,): the centroid at constant acceleration up to the gap's end."""
    before, nxt, after = np.asarray(before), np.asarray(nxt), np.asarray(after)
    if start_limit is None and steady is not None:
        flight = np.where(steady, np.maximum(before, nxt), np.inf)
    elif start_limit == REST_START_LIMIT:
        flight = nxt
    else:
        return None
    free = (flight < FREE_FLIGHT_NONRIGIDITY) & hit_again(flight, after)
    return free if free.any() else None


def after_impact(before, nxt, incoming, outgoing, start_limit: float | None, after=None) -> np.ndarray | None:
    """Per component (C,), whether a gap starts right after an impact (see :data:`IMPACT_SLOWDOWN`),
    from the non-rigidity (C,) of the keys before the gap and at its end, seen from its start key,
    and the distances (C,) its centroid moved over the gap before (``incoming``) and over this one
    (``outgoing``); or None if no component does. Not in a sequence's first gap (``start_limit``
    set), whose key before is an end condition, nor for a component hit again right after the gap
    (``after``: the non-rigidity (C,) of the key after the gap, seen from its start key, or None
    where there is none), which :func:`hit_again` tells."""
    if start_limit is not None:
        return None
    before, nxt = np.asarray(before), np.asarray(nxt)
    hit = ((before > 2.0 * FREE_FLIGHT_NONRIGIDITY) & (before > FREE_FLIGHT_JUMP * nxt)
           & (np.asarray(incoming) > IMPACT_SLOWDOWN * np.asarray(outgoing)))
    if after is not None:
        hit &= ~hit_again(nxt, after)
    return hit if hit.any() else None


def hit_again(nxt, after) -> np.ndarray:
    """Per component (C,), whether it is deformed at the key after a gap as an impact deforms it:
    the non-rigidity (C,) of that key, seen from the gap's start key (``after``), over 2 ×
    :data:`FREE_FLIGHT_NONRIGIDITY` and over :data:`FREE_FLIGHT_JUMP` × the gap's own (``nxt``, of
    its end key), the test :func:`free_flight` reads a hit right after a gap by. The after-impact
    start (:data:`IMPACT_SLOWDOWN`) takes the gap's end tangent, Catmull–Rom's ``(v₂ − v₀)/2``, for
    the gap's own velocity and starts on the parabola through it, ``2 (v₁ − v₀) − t₁``; where a
    second impact deforms the piece right after the gap, that tangent carries the second impact's
    motion, and the parabola mirrors it into a start velocity the other way (a pillow landed, then
    squashed by a slab: its top panel's middle started up at 92 mm per gap where Catmull–Rom's
    tangent goes down at 34, and the in-betweens bulged 3 cm above the still pillow, 2.8 × the
    blend's RMS). Such a gap keeps Catmull–Rom's start."""
    after = np.asarray(after)
    return (after > 2.0 * FREE_FLIGHT_NONRIGIDITY) & (after > FREE_FLIGHT_JUMP * np.asarray(nxt))


def flying_groups(topo: Topology, relatives: list, rigid: np.ndarray,
                  nonrigidity: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The pieces ``rigid`` (bool (C,): the rigid ones, and deforming ones turning as a whole, see
    :data:`DEFORMING_AXIS_NOISE`) of a sequence's gap turned about the point of theirs whose path
    the keys say is simplest: ``(labels (C,), points (G, 3))``, each piece's group (pieces moving by one
    rigid motion from the gap's base key to its next, to 1e-6 or what their fits are known to:
    ``nonrigidity`` (C,) as :data:`~core.screw_motions.TURN_NOISE` says) or −1, and each
    group's point in the base key; None where no piece has a key before or after the gap to tell.

    A rigid piece's screw motion (:meth:`~core.inbetween_motion.PieceMotion.motion`) turns it about
    one axis, which a door on its hinge or a wheel on its axle does; a body thrown while it spins
    turns about its centre as the centre flies on, and the screw swings it along a helix around an
    axis far from its path (a box flying and spinning 10° a frame, keys 16 frames apart: 14 × the
    linear blend's error).
    Over the keys around the gap, the point of the piece (in the base key) whose positions have
    the smallest third difference (constant acceleration; with a key on one side only, the second:
    constant velocity) is a point of the hinge's axis for a door, whatever its speed, and the
    centre of a thrown body, under gravity too: the piece turns about it while it follows the
    spline of its positions at the keys. Of the points equally simple (along a hinge's axis) the
    one nearest the group's centroid. Any four rigid motions have a point of zero third difference,
    so with keys on both sides the point must also have a steady path or lie within the group
    (:func:`_told_by_keys`). Where no point of the piece's reach follows such a path to
    :data:`FLYING_TOLERANCE` of its size (one key beside the gap and the body accelerating; a body
    that orbits while it spins), the group's centroid: a flying body's centre of mass follows its
    own path (a box thrown under gravity, keys 8 apart, its two end gaps so: 0.23 × Catmull–Rom's
    error over the sequence; with the screw there 4.4 ×, with the best point of the constant-velocity
    test 1.32 ×). A point beyond the reach is taken where it lies on an axis line that every key
    around the gap turns the group about and moves only along itself (:func:`_on_common_axis`): a
    body going round a far axis, at any speed."""
    before, base, nxt, after = relatives
    known = [r for r in (before, after) if not r.extrapolated and getattr(r, "motion", None) is not None]
    if not rigid.any() or not known or getattr(nxt, "motion", None) is None:
        return None
    rotations, translations = nxt.motion
    candidates = np.flatnonzero(rigid & (np.linalg.norm(df.rotation_vectors(rotations), axis=1) > FLYING_MIN_TURN))
    if candidates.size == 0:
        return None
    diagonals = topo.diagonals(base.vertices)
    scale = max(float(np.max(diagonals)), float(np.max(np.ptp(base.centroids, axis=0))), np.finfo(float).tiny)
    motions = np.concatenate([rotations[candidates].reshape(-1, 9), translations[candidates] / scale], axis=1)
    # pieces whose motions are within 1e-6 of each other, linked: rounding them to 6 decimals split
    # equal motions of float32 keys across a rounding boundary (a character's hat, spun rigidly with
    # it, was turned about another point: 1.5–1.9e-2 off at the middle of one gap)
    # ... and within what the fits are known to: float32 keys of 300 cards, 10 units out and keyed
    # every half turn, differ by ~1e-5, and each card alone turned about its centroid, off its circle
    spread = np.maximum(turn_spread(nonrigidity[candidates]), 0.5e-6)
    group = spread_groups(motions, spread)  # thousands of pieces moving as one: not every pair listed
    count = int(group.max()) + 1
    mass = topo.component_mass[candidates]
    first = candidates[np.unique(group, return_index=True)[1]]  # a member's motion stands for its group's
    centroid = np.stack([np.bincount(group, mass * base.centroids[candidates, d], count) for d in range(3)],
                        axis=1) / np.bincount(group, mass, count)[:, None]
    # a group's reach: the diagonal of its members' bounding box (teeth turning about the jaw's
    # axis: a tooth's own diagonal missed the axis, 0.1 of the diagonal off at 120° per key)
    of_vertex = np.full(len(topo.components), -1, dtype=np.intp)
    of_vertex[candidates] = group
    of_vertex = of_vertex[topo.vertex_owner]
    rows = of_vertex >= 0
    low, high = np.full((count, 3), np.inf), np.full((count, 3), -np.inf)
    np.minimum.at(low, of_vertex[rows], base.vertices[rows])
    np.maximum.at(high, of_vertex[rows], base.vertices[rows])
    reach = np.linalg.norm(high - low, axis=1)
    # the differences of a body point p's positions R_j p + t_j over the keys: A p + b
    eye = np.broadcast_to(np.eye(3), (count, 3, 3))
    r1, t1 = rotations[first], translations[first]
    if len(known) == 2:
        r0, t0 = before.motion[0][first], before.motion[1][first]
        r2, t2 = after.motion[0][first], after.motion[1][first]
        a, b = r2 - 3.0 * r1 + 3.0 * eye - r0, t2 - 3.0 * t1 - t0
    elif after in known:
        r2, t2 = after.motion[0][first], after.motion[1][first]
        a, b = r2 - 2.0 * r1 + eye, t2 - 2.0 * t1
    else:
        r0, t0 = before.motion[0][first], before.motion[1][first]
        a, b = r1 - 2.0 * eye + r0, t1 + t0
    residual = np.einsum("gab,gb->ga", a, centroid) + b
    # the minimum-norm move from the centroid, all groups at once; directions the keys fix only to
    # within their fits' spread left out (a noisy half turn's axis: 1e-5 there sent the point 1e6 off)
    group_spread = np.zeros(count)
    np.maximum.at(group_spread, group, spread)
    move = screw_motions.least_squares_3x3(a, -residual, np.maximum(screw_motions.SCREW_CUTOFF, group_spread))
    point = centroid + move
    # deforming groups (pieces turning as a whole: DEFORMING_AXIS_NOISE) take a point only on a common axis
    noise = np.zeros(count)
    np.maximum.at(noise, group, nonrigidity[candidates])
    deforming = noise >= RIGID_PLACEMENT_SCALE
    # four motions of any kind have a point of zero third difference (an invertible map of the
    # point unless the turns share an axis): alone it tells nothing, and the point is taken where
    # the keys say more (_told_by_keys). With one key beside the gap (three motions, the second
    # difference) the point is kept: about their centroids, smoothly tumbling boxes' end gaps came
    # out up to 14 % farther from the true frames, one of six closer.
    simple = ~deforming & (np.linalg.norm(move, axis=1) <= reach) & (
        np.linalg.norm(np.einsum("gab,gb->ga", a, point) + b, axis=1) <= FLYING_TOLERANCE * reach)
    if len(known) == 2 and simple.any():
        simple &= _told_by_keys(a, r1 - 2.0 * eye + r0, t1 + t0, point, low, high, reach, group_spread)
    # beyond the reach, a point on an axis line every key around the gap turns the group about
    # (and shifts it along): a car on a curve, a carousel's horse, a body on a far screw; turned
    # about it the group follows that turn exactly, where its centroid's spline cuts the arc
    # (a head turning 30° a key about an axis 3 diagonals away: 5.5e-2 of its diagonal off)
    distance = np.linalg.norm(move, axis=1)
    far = ~simple & ((distance > reach) | deforming)
    if far.any():
        tolerance = np.where(deforming, np.clip(DEFORMING_AXIS_NOISE * noise, FLYING_TOLERANCE,
                                                DEFORMING_AXIS_NOISE * SIMILAR_SHAPE_MISFIT[0]), FLYING_TOLERANCE)
        far[far] = _on_common_axis([nxt.motion] + [r.motion for r in known], first[far], point[far], reach[far],
                                   distance[far], tolerance[far])
    simple |= far
    points = np.where(simple[:, None], point, centroid)
    labels = np.full(len(topo.components), -1, dtype=np.intp)
    labels[candidates] = group
    return labels, points


def _told_by_keys(third: np.ndarray, second: np.ndarray, second_shift: np.ndarray, point: np.ndarray,
                  low: np.ndarray, high: np.ndarray, reach: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """Per group (G,), whether the keys around a gap tell more of its ``point`` (G, 3) than that its
    third difference vanishes: its second difference over the key before,
    the base key and the next (``second`` (G, 3, 3) · point + ``second_shift`` (G, 3)) vanishes too,
    to :data:`FLYING_TOLERANCE` of the group's ``reach`` (G,) — across the axis the turns share where
    the third difference's matrix ``third`` (G, 3, 3) has a null direction to the fits' ``spread``
    (G,) (a screw's pivot may drift along it) — or the point lies within the group's bounding box
    ``low``–``high`` (G, 3) (to the same tolerance).

    Four rigid motions of any kind have a point whose third difference vanishes (it is an
    invertible map of the point but for an axis the turns share), so that alone is no evidence. A
    vanishing second difference too is (three more equations): a door's hinge, a pendulum's pivot,
    a wheel's axle, a screw's pivot drifting along its axis. A thrown body's centre of mass lies
    within it. Elsewhere the group's centroid: a rigid box bouncing while it tumbles, keys 16 frames
    apart, had such a point 0.48 of its diagonal from its centre, outside it, and was 1.51 × the
    blend's error off across the bounce (0.38 × about its centroid); numbers in
    docs/inbetween-measurements.md, *Points no key tells*."""
    lower = np.einsum("gab,gb->ga", second, point) + second_shift
    _, sigma, vt = np.linalg.svd(third)
    shared = sigma[:, 2] <= np.maximum(screw_motions.SCREW_CUTOFF, spread) * sigma[:, 0]
    axis = vt[shared, 2]
    lower[shared] -= np.einsum("ga,ga->g", lower[shared], axis)[:, None] * axis
    margin = FLYING_TOLERANCE * reach[:, None]
    inside = np.all((point >= low - margin) & (point <= high + margin), axis=1)
    return (np.linalg.norm(lower, axis=1) <= FLYING_TOLERANCE * reach) | inside


def _on_common_axis(motions: list, first: np.ndarray, point: np.ndarray, reach: np.ndarray,
                    distance: np.ndarray, tolerance: np.ndarray) -> np.ndarray:
    """Per group (G,), whether every one of ``motions`` (rigid motions ``(rotations (C, 3, 3),
    translations (C, 3))`` of the keys around a gap seen from its base key, the gap's own first;
    each group's read at its member ``first`` (G,)) turns the group about the axis line through its
    ``point`` (G, 3) along the first motion's axis and moves that line only along itself, to
    ``tolerance`` (G,; :data:`FLYING_TOLERANCE`, or :data:`DEFORMING_AXIS_NOISE` × the group's
    non-rigidity) of the group's ``reach`` (G,): the axis within it of the size at the group's
    ends, the line within it of the size plus the line's ``distance`` (G,) from the group (a turn
    known to δ moves a point that far away by δ × distance)."""
    g, p, size = first, point, reach
    axis = df.rotation_vectors(motions[0][0][g])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)  # turns over FLYING_MIN_TURN: not zero
    ok = np.ones(len(g), dtype=bool)
    for rotations, translations in motions:
        moved = np.einsum("gab,gb->ga", rotations[g], p) + translations[g] - p
        across = moved - np.einsum("ga,ga->g", moved, axis)[:, None] * axis
        tilted = np.einsum("gab,gb->ga", rotations[g], axis) - axis
        ok &= (np.linalg.norm(across, axis=1) <= tolerance * (size + distance)) & (
            np.linalg.norm(tilted, axis=1) <= tolerance)
    return ok
