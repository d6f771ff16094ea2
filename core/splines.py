"""Splines through the keys of a sequence, per element (the in-betweens of §8.4 over many keys).

A gap runs from key time 0 to 1; its neighbours sit at −1 and 2. :class:`HermiteGap` is prepared
once per gap from the values at the four key times (arrays of one shape) and evaluated at any
factor with a handful of vector operations, so every in-between of a gap shares the preparation.
"""

from __future__ import annotations

import numpy as np

from . import screw_motions

#: The spline's tangent at the start of a gap is at most this multiple of the secant over the gap,
#: per element (Fritsch–Carlson's monotonicity bound): the velocity a gap inherits from the
#: previous one, which a collision can stop abruptly (cloth landing on a collider); unlimited
#: Catmull–Rom tangents overshoot into the gap after such a stop. For positions the secant is the
#: longer of this gap's and the next one's, per point: a point that stops at a collider stays slow
#: in both, a point that swings back inside the gap (a flapping flag) moves on in the next, and
#: its tangent is kept (a soft 20k flag, keys 8 frames apart: 1.018 → 0.949 × the per-vertex
#: Catmull–Rom spline's RMS; 10k hanging sheet 0.898 → 0.783). The numbers behind the values are
#: in docs/inbetweens.md.
TANGENT_LIMIT = 3.0
#: The first gap of a sequence has no key before it. A motion that starts at its first key from
#: rest (a simulation baked from its first frame, an animation from a held pose) starts with zero
#: tangents (:data:`REST_START_LIMIT`, the sequence's ``start="rest"``); one cut from the middle of
#: a motion (``start="keys"``) with the tangent of the parabola through the first three keys (exact
#: for motion at constant acceleration; the linear end condition gives it the whole gap's velocity
#: at once), at most the gap's secant per element (START_TANGENT_LIMIT): where the motion stops at
#: the second key (an impact) the parabola's tangent exceeds the secant and overshoots, the secant
#: does not. Numbers in docs/inbetweens.md.
START_TANGENT_LIMIT = 1.0
REST_START_LIMIT = 0.0
#: A sequence's first gap ends with a tangent of at most this multiple of its secant, per
#: element, per point for positions: its Catmull–Rom end tangent is taken from the next gap, which
#: can lend it a velocity it never had — a cloth that settled inside the gap and is pulled away in
#: the next one (a tablecloth dragged off a box, keys 16 frames apart: 1.061 → 0.972 × the
#: per-vertex Catmull–Rom spline's RMS). Motion accelerating from rest ends it at twice its secant.
#: Only there: the next gap starts with the unlimited tangent, and limited at every key the two
#: gaps met with two velocities (a balloon bouncing, keys 16 apart: largest frame-to-frame
#: acceleration 0.65 → 2.31 × the simulation's). A first gap cut from a motion
#: (:data:`START_TANGENT_LIMIT`) too, for positions (its screws and fields keep one velocity at the
#: second key: a ball rolling 178° per key), and its start tangent's bound from the next gap is
#: at most :data:`TANGENT_LIMIT` × its own secant: a curtain barely moving before a ball hits it in
#: the next gap, keys 8 apart, had tangents ~40 × the first gap's secant (its first in-betweens
#: 6.9 × further from the source than the better of the blend and Catmull–Rom; now 1.12).
#: Numbers in docs/inbetweens.md.
END_TANGENT_LIMIT = 3.0
#: The positions' tangent at a key with two evenly spaced keys on either side is the five keys'
#: central difference (:func:`five_key_tangent_correction`): Catmull–Rom's plus ``−(a + b) / 12``,
#: ``a`` and ``b`` the third differences on either side of the key. Smooth motion has ``a ≈ b``;
#: where something stops or hits the cloth between the keys one of them is large, and the wider
#: stencil would carry the kink a key farther than Catmull–Rom's does (a sheet draping on a
#: sphere, keys 4 frames apart: its free fall 4.6 × farther from the frames in the gap before the
#: impact). The correction's length is limited to FIVE_KEY_LIMIT × the shorter of ``a`` and ``b``
#: over 12 (a minmod limiter, as slope limiters take the smoother side): the whole of it where they
#: agree, none where they point apart (10k drape, keys 4 apart: 0.727 × Catmull–Rom's RMS with
#: its tangents, 0.920 with the five keys' unlimited, 0.704 limited), and to the longer chord at
#: the key (a point's own hold keeps Catmull–Rom's zero tangent). Numbers in docs/inbetweens.md.
FIVE_KEY_LIMIT = 2.0


class HermiteGap:
    """Cubic Hermite interpolation over one gap with Catmull–Rom tangents ``(v₁ − v₋₁)/2`` and
    ``(v₂ − v₀)/2``, the first limited per element to :data:`TANGENT_LIMIT` × the secant
    ``v₁ − v₀`` (and in a first gap from rest the second to :data:`END_TANGENT_LIMIT` × the
    secant). C¹ across keys where the limits are inactive; exact for quadratic motion.
    ``cubic=False``: linear in the two keys (``before``/``after`` are ignored).

    ``values``: ``(before, start, end, after)`` at key times −1, 0, 1, 2, arrays of one shape.
    ``rows=True`` limits the length of each row (points in space) instead of each element, against
    the longer of this gap's secant and the next gap's ``v₂ − v₁``; ``onward=True`` limits each
    element's start tangent against the longer of the two too (a swing turning back inside the gap);
    ``limit``: the multiple of the secant (:data:`START_TANGENT_LIMIT` or :data:`REST_START_LIMIT`
    for a sequence's first gap; 0 gives a zero start tangent).
    ``parabolic_end``: bool, broadcastable to the values' shape, or None: where True the end
    tangent is the one of the parabola through the start (value and tangent) and the end,
    ``2 (v₁ − v₀) − t₀`` (exact for constant acceleration; ``(3v₁ − 4v₀ + v₋₁)/2`` with an
    unlimited start tangent, ``2 (v₁ − v₀)`` from rest), instead of the Catmull–Rom one, which
    takes the velocity at the gap's end from the next gap: for motion that something stops
    right after the end (see :data:`core.inbetween_flight.FREE_FLIGHT_NONRIGIDITY`).
    ``entry``: ``(mask, tangent)`` or None: where ``mask`` the start tangent is ``tangent`` (the
    velocity the gap before ends with on its parabola, so that the two meet with one velocity),
    limited as any start tangent.
    ``exit``: ``(mask, tangent)`` or None: where ``mask`` the end tangent is ``tangent`` (the
    velocity the gap after starts with after an impact, so that the two meet with one velocity),
    or, with ``tangent`` None, the one-sided tangent ``v₂ − v₁`` (the next gap's secant: the
    velocity the next gap's keys give, without this gap's; see
    :data:`core.inbetween_flight.IMPACT_SLOWDOWN`).
    ``parabolic_start``: bool like ``parabolic_end``, or None: where True the start tangent is the
    one of the parabola through the end (value and tangent) and the start, ``2 (v₁ − v₀) − t₁``,
    limited as any start tangent: for motion that something stopped right before the start (see
    :data:`core.inbetween_flight.IMPACT_SLOWDOWN`).
    ``rest_end``: the end tangent is zero (a sequence's last gap whose motion comes to rest at the
    last key: ``end="rest"`` of :class:`core.SequenceInterpolator`).
    ``corrections``: ``(c₀, c₁)``, each an array of the values' shape or None: added to Catmull–Rom's
    start / end tangent before any limit or replacement above — at a key with evenly spaced keys two
    away on both sides, the five keys' :func:`five_key_tangent_correction` (a sequence makes each
    key's once for the two gaps that meet there); at a sequence's last key, to the linear end
    condition's tangent, :func:`slowing_end_correction` (bodies' screws:
    :func:`slowing_screw_correction`, :class:`ScrewGap`'s ``slowing``).
    """

    def __init__(self, values, cubic: bool, rows: bool = False, limit: float = TANGENT_LIMIT,
                 parabolic_end: np.ndarray | None = None, entry: tuple | None = None,
                 parabolic_start: np.ndarray | None = None, onward: bool = False, rest_end: bool = False,
                 exit: tuple | None = None, corrections: tuple | None = None):
        before, start, end, after = values
        start_correction, end_correction = (None, None) if corrections is None else corrections
        self.start = start
        self.secant = end - start
        self.cubic = cubic
        if cubic:
            t0 = end - before
            t0 *= 0.5
            if start_correction is not None:
                t0 += start_correction
            if entry is not None:
                t0 = np.where(entry[0], entry[1], t0)
            # positions: each row's length is limited (rotation invariant, keeps C¹ per point),
            # against squared lengths: one square root per limited row
            bound = np.einsum("...i,...i->...", self.secant, self.secant) if rows else np.abs(self.secant)
            start_bound = bound
            starts_here = limit <= START_TANGENT_LIMIT  # a sequence's first gap, a gap after a hold
            if (rows or onward) and limit > 0:  # a point that only turns back in this gap moves on in the next one
                step = after - end
                start_bound = np.maximum(bound, np.einsum("...i,...i->...", step, step) if rows else np.abs(step))
                if starts_here:  # ... but a first gap cut from a motion starts at most TANGENT_LIMIT × its own secant
                    start_bound = np.minimum(start_bound, (TANGENT_LIMIT ** 2 if rows else TANGENT_LIMIT) * bound)
            self.t0 = limited_tangent(t0, limit, start_bound, rows)
            self.t1 = after - start
            self.t1 *= 0.5
            if end_correction is not None:
                self.t1 += end_correction
            if parabolic_end is not None:
                self.t1 = np.where(parabolic_end, 2.0 * self.secant - self.t0, self.t1)
            if exit is not None:
                self.t1 = np.where(exit[0], after - end if exit[1] is None else exit[1], self.t1)
            if rest_end:
                self.t1 = np.zeros_like(self.t1)
            if limit == REST_START_LIMIT or (starts_here and rows):  # see END_TANGENT_LIMIT
                self.t1 = limited_tangent(self.t1, END_TANGENT_LIMIT, bound, rows)
            if parabolic_start is not None:
                self.t0 = np.where(parabolic_start, limited_tangent(2.0 * self.secant - self.t1, limit, start_bound, rows),
                                   self.t0)

    def at(self, s: float, rows=None) -> np.ndarray:
        """The interpolated value at factor ``s`` (0 → start, 1 → end; outside: extrapolated); on
        the rows ``rows`` (an index array) alone if given: per element, the same values."""
        start, secant = (self.start, self.secant) if rows is None else (self.start[rows], self.secant[rows])
        if not self.cubic:
            return start + s * secant
        s2, s3 = s * s, s * s * s
        out = (3 * s2 - 2 * s3) * secant
        out += start
        out += (s3 - 2 * s2 + s) * (self.t0 if rows is None else self.t0[rows])
        out += (s3 - s2) * (self.t1 if rows is None else self.t1[rows])
        return out


def five_key_tangent_correction(v_2: np.ndarray, v_1: np.ndarray, v0: np.ndarray, v1: np.ndarray,
                                v2: np.ndarray) -> np.ndarray:
    """What the five keys' central difference ``(8 (v₁ − v₋₁) − (v₂ − v₋₂)) / 12`` adds to Catmull–Rom's
    tangent ``(v₁ − v₋₁) / 2`` at the key ``v0`` from evenly spaced keys ``v_2 … v2`` (points (n, 3)
    at key times −2 … 2), per point (n, 3): ``−(a + b) / 12``, ``a`` and ``b`` the third differences
    over keys −2 … 1 and −1 … 2, limited where they disagree (see :data:`FIVE_KEY_LIMIT`) and to the
    longer of the chords ``v0 − v₋₁`` and ``v₁ − v0``: where both are zero (a point held still over
    the two gaps around the key, moving the same way before and after) the third differences come
    from the keys two away alone, and the correction would move the held point back and forth
    (4/27 of it at a third of each gap; Catmull–Rom's tangent there is zero).

    Catmull–Rom's tangent is exact for quadratic motion; the five keys' for cubic motion too (there
    ``a = b``, the correction is whole), and the cubic Hermite spline with it reproduces cubic motion. A motion smooth over the keys but sampled
    coarsely loses less of its speed: at ``θ`` radians of an oscillation per key Catmull–Rom's
    tangent is ``sin θ / θ`` of the velocity (0.90 at 45°, 0.64 at 90°), the five keys'
    ``(8 sin θ − sin 2θ) / 6θ`` (0.99, 0.85)."""
    before, after = v0 - v_1, v1 - v0  # the chords either side of the key
    a = v1 - v_2
    a -= 3.0 * before
    b = v2 - v_1
    b -= 3.0 * after
    aa, bb, ab = (np.einsum("ij,ij->i", x, y) for x, y in ((a, a), (b, b), (a, b)))
    tt = aa + bb + 2.0 * ab  # |a + b|²
    with np.errstate(over="ignore"):  # a + b = 0 (a symmetric swing): inf here, zeroed below (ab < 0)
        share = np.sqrt(np.minimum(aa, bb) / np.maximum(tt, np.finfo(float).tiny))
    share *= FIVE_KEY_LIMIT
    np.minimum(share, 1.0, out=share)
    share[ab <= 0.0] = 0.0
    share *= -1.0 / 12.0
    # at most the longer chord at the key: a point still over both gaps around it (its own hold
    # between two motions, which the keys beyond it agree on) keeps Catmull–Rom's tangent, zero
    chord = np.maximum(np.einsum("ij,ij->i", before, before), np.einsum("ij,ij->i", after, after))
    length2 = share * share
    length2 *= tt
    over = length2 > chord
    if over.any():
        share[over] *= np.sqrt(chord[over] / length2[over])
    a += b
    a *= share[:, None]
    return a


def slowing_end_correction(v_1: np.ndarray, v0: np.ndarray, v1: np.ndarray) -> np.ndarray:
    """What the positions' tangent at a sequence's last key ``v1`` gets added to the linear end
    condition's, the last gap's secant ``d = v₁ − v₀``, from the keys ``v_1``, ``v0``, ``v1`` (points
    (n, 3) at key times −1, 0, 1, evenly spaced), per point (n, 3): the tangent becomes ``λ d`` with
    ``λ`` the part along ``d`` of the tangent of the parabola through the three keys,
    ``(3 d − d′) / 2`` with ``d′ = v₀ − v₋₁``, as a share of ``d``, held to [0, 1].

    A point that slows into the last key (an arm easing into its stop, a swing nearing its turning
    point, a cloth settling) moved farther in the gap before along its last chord than in the last
    gap, ``d′ · d > |d|²``, and reaches the key at less than its mean speed over the gap: exact for
    motion at constant deceleration along a line (the start tangent, Catmull–Rom's, is exact for
    it too), at rest where it moved three times as far before (``λ`` = 0: it stopped inside the
    gap). A point moving steadily or speeding up keeps the secant (``λ`` = 1): the parabola would
    carry its acceleration past a key where an impact may stop it. With ``λ`` in [0, 1] and a start
    tangent within 3 × the secant (:data:`TANGENT_LIMIT`) a point moving along a line never passes
    the last key inside the gap (Fritsch–Carlson)."""
    secant = v1 - v0
    secant *= _slowing_share(v0 - v_1, secant)[:, None]
    return secant


def _slowing_share(before: np.ndarray, secant: np.ndarray) -> np.ndarray:
    """``λ − 1`` per row (n,) of :func:`slowing_end_correction` from the chords ``d′`` (``before``)
    and ``d`` (``secant``), rows (n, k) of any one inner product's coordinates."""
    length2 = np.einsum("ij,ij->i", secant, secant)
    share = np.einsum("ij,ij->i", before, secant)
    share /= np.maximum(length2, np.finfo(float).tiny)
    share *= -0.5
    share += 0.5  # λ − 1 = (3 d − d′) · d / 2|d|² − 1
    np.clip(share, -1.0, 0.0, out=share)
    return share


def slowing_screw_correction(s_1: np.ndarray, s0: np.ndarray, s1: np.ndarray, pivoted: bool = False) -> np.ndarray:
    """:func:`slowing_end_correction` of bodies' screw coordinates ``(ω, v)`` (P, 6) at key times −1,
    0, 1 (a sequence's last key ``s1``), per body (P, 6): the turn ``ω`` and the translation part ``v``
    each slowed by its own share ``λ``, read from its own chords. Apart, as radians and lengths do
    not add: one ``λ`` from the six coordinates would weigh the turn against the move by the scene's
    units; and the turn's own ``λ`` depends on the turn only, not on the point its screw is taken
    about, so pieces moving as one (each's screw about its own centroid) turn as one. A body turning
    about a fixed axis at a constant deceleration has both parts proportional to its angle (``ω = θ
    â``, ``v = θ (p × â)`` for an axis through ``p``): both read its ``λ``, and the screw's spline
    with it is exact, as the positions' is for a point slowing along a line.

    ``pivoted``: each body turns about a point ``p`` fixed in its frame at every key, ``v = p × ω``
    (a jointed piece's screw relative to its parent, about their joint): the whole screw takes the
    turn's ``λ``, which keeps that relation at every factor. With ``v``'s own ``λ`` a ball joint,
    whose axis swings (``v`` is not a multiple of ``ω`` then), opened as it decelerated into the
    last key (2.7e-4 of the diagonal)."""
    turn = slice(0, 3)
    if not pivoted:
        return np.concatenate([slowing_end_correction(s_1[:, part], s0[:, part], s1[:, part])
                               for part in (turn, slice(3, 6))], axis=1)
    secant = s1 - s0
    secant *= _slowing_share(s0[:, turn] - s_1[:, turn], secant[:, turn])[:, None]
    return secant


def limited_tangent(tangent: np.ndarray, limit: float, bound: np.ndarray, rows: bool) -> np.ndarray:
    """``tangent`` limited in place to ``limit`` × ``bound``: each row's length against the squared
    lengths ``bound`` (``rows``), or each element against the magnitudes ``bound``."""
    if rows:
        length2 = np.einsum("...i,...i->...", tangent, tangent)
        over = length2 > limit * limit * bound
        if over.any():
            tangent[over] *= (limit * np.sqrt(bound[over] / length2[over]))[:, None]
        return tangent
    bound = limit * bound
    return np.clip(tangent, -bound, bound, out=tangent)


class ScrewGap:
    """A :class:`HermiteGap` of bodies' screw coordinates (P, 6) splined in a frame per body
    (``frames``: axes (P, 3, 3) and origins (P, 3), see :func:`core.screw_motions.framed_screws`;
    :func:`core.rigid_alignment.principal_frames` gives ones that turn and move with the bodies),
    evaluated in world coordinates. Its tangents are limited per element: in world coordinates
    those limits depend on the world's axes and origin, and a scene turned by a general rotation
    came back up to 9.0e-3 of its diagonal off the unturned one's in-betweens (a flag keyed every
    8th frame; 1.7e-7, its keys' single-precision rounding, in the flag's principal frame).
    ``frames`` None: in world coordinates (a linear spline, where no limit acts). ``slowing``: None,
    or per body (P,) the share of :func:`slowing_screw_correction` (in the bodies' frames) its end
    tangent takes at a sequence's last key (``end="keys"``: each piece's rigidity, so that its rigid
    motion slows into the last key as the positions' spline does); ``pivoted``: the bodies turn
    about points fixed in their frames (jointed pieces relative to their parents), see
    :func:`slowing_screw_correction`. Other arguments as :class:`HermiteGap`'s."""

    def __init__(self, values, frames: tuple | None, cubic: bool, slowing: np.ndarray | None = None,
                 pivoted: bool = False, **options):
        self.frames = frames
        if frames is not None:
            values = [screw_motions.framed_screws(value, *frames) for value in values]
        if slowing is not None and cubic:
            correction = slowing_screw_correction(*values[:3], pivoted)
            correction *= slowing[:, None]
            options["corrections"] = (None, correction)
        self.gap = HermiteGap(values, cubic, **options)

    def at(self, s: float) -> np.ndarray:
        """The interpolated screws (P, 6) at factor ``s``, in world coordinates."""
        value = self.gap.at(s)
        return value if self.frames is None else screw_motions.world_screws(value, *self.frames)
