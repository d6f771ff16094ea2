"""The co-moving correction ``D(s)`` from which the in-betweens of a gap are predicted
(:mod:`core.inbetween_prediction`), and the positions ``M(s) (V(s) + D(s))`` it predicts.

A pose ``x`` solved at factor ``s_j`` is written in the co-moving frame, less the keys'
co-moving spline: ``D_j = M(s_j)⁻¹ x − V(s_j)`` (:func:`co_moving_correction`). :func:`correction_polynomial`
makes the polynomial through ``(0, 0)``, the ``(s_j, D_j)`` and ``(1, 0)``
(:class:`CorrectionPolynomial`), with the slopes at the keys that give the pose the guide's
velocity there (:func:`_key_slope`, :data:`KEY_SLOPE_SOLVED`); a gap too rough for a polynomial
has the chords between its solved corrections (:class:`PiecewiseLinearCorrection`). Two checks
say when a polynomial is not to be predicted from: the keys' slopes and the middle alone tell
different in-betweens (:func:`slopes_disagree`), or the middle of three solved corrections is far
from the one the other two predict (:func:`inconsistent`). With three solved factors the
correction takes one local/global step toward the interpolated metric per span
(:func:`relaxed_correction`). :func:`predicted_positions` and :func:`pins_in_place` turn a
correction into positions.
"""

from __future__ import annotations

import numpy as np

from .inbetween_fit import LOCAL_STEP_DTYPE, METRIC_TOLERANCE
from .inbetween_threads import per_factor


#: With this many solved factors (batches of :data:`~core.inbetween_prediction.FULL_SAMPLE_BATCH`
#: in-betweens or more: keys 9 frames apart or more), and with the middle alone
#: (:data:`~core.inbetween_prediction.MIDDLE_SOLVED_BATCH`), the correction's slope at each key is
#: prescribed too: the one that gives the in-between the velocity of the gap's guide there — the
#: keys' per-vertex spline in the world where a piece deforms, C¹ across the keys, and its
#: interpolated rigid motion where it moves rigidly (slope zero: rigid motions stay exact).
#: Consecutive gaps then leave a key with one velocity; before, the base ``M(s) V(s)`` kinked there
#: with the rigid motions interpolated per gap, and so did the corrections. Keys 16 frames apart:
#: largest frame-to-frame jump of the soft 20k flag 3.09 → 1.25 × the simulation's, the 1k flag 2.66
#: → 1.45 ×, the banner 1.39 → 0.98 ×; edge deviation down on the scenes that miss its bound
#: (curtain 8.57 → 7.98 %, banner 6.00 → 5.51 %, balloon 2.95 → 2.66 %); RMS within −0.027 / +0.017
#: × Catmull–Rom (numbers in docs/inbetween-measurements.md, *Pops*). With two solved factors the
#: slopes cost RMS (keys 8 apart: soft flags +0.012 / +0.015 × Catmull–Rom) and the jumps there are
#: 0.4–1.6 × already.
KEY_SLOPE_SOLVED = 3
#: Step (in factor) of the one-sided differences that give the guide's and the base's velocities at
#: a key: both are cubic in ``s``, so the slope is within ~1e-4 of its value.
SLOPE_STEP = 1e-4
#: Largest difference, in mean edge lengths (RMS over the vertices, at any predicted factor),
#: between the two corrections the middle alone supports
#: (:data:`~core.inbetween_prediction.MIDDLE_SOLVED_BATCH`) in the gap of a sequence of two keys:
#: the quartic with the keys' slopes and the parabola without them. The slopes give the prediction
#: the guide's velocity at the keys, and with two keys that is their chord's, which neither key
#: tells. Where a part turns about a joint (a limb of a rig) the chord is short of the arc, the two
#: corrections part, and the prediction misses the pose solved at its factor by about as much as
#: they part (skinned arm, spine, root and a bent tube: 0.9–1.0 ×); above this the other in-betweens
#: of the gap are solved too. Two keys 4 frames apart: 0.92–3.4 mean edges on skinned characters
#: (arm bent 100°: 1.8e-2 → 5.6e-3 of the diagonal off the rig's poses, spine twisted 90° 8.9e-3 →
#: 3.1e-3, root moving with arm and head 1.13e-2 → 8.7e-3), 0.42 on a tube bent 100°, 0.15 bent 60°
#: (predicted as before). With three keys or more the check is not made: in the end gaps of 12
#: cloths it reaches 0.29 mean edges, and solving the curtain's last gap raised its RMS at g = 4 (÷
#: Catmull–Rom 0.847 → 0.903) and its CPU by a quarter (numbers in docs/inbetween-measurements.md,
#: *Two keys of a skinned character*).
MAX_SLOPE_DISAGREEMENT = 0.25
#: With this many solved in-betweens or more (keys 9 frames apart or more), the predictions get one
#: local/global step toward the interpolated metric, anchored to themselves, at the middle of each
#: span between the solved factors and the keys, and its displacement spread over the span
#: (:func:`relaxed_correction`).
RELAXED_SOLVED = 3
#: Largest relative miss (RMS over the vertices, against the correction's own RMS) of the middle
#: solved correction predicted from the others; above it the gap is solved at every eighth
#: (:data:`~core.inbetween_prediction.ROUGH_SOLVED_FACTORS`) and the in-betweens between those
#: predicted from them.
#: Measured with keys 16 frames apart: 0.01–0.38 on the benchmark cloths, 0.76 in the gap where the
#: flag pinned at its pole flaps about once (its in-betweens solved: 1.073 → 1.000 × the per-vertex
#: Catmull–Rom spline's RMS, edge deviation 2.28 → 1.50 %; every other scene unchanged).
MAX_CROSS_VALIDATION = 0.5


def co_moving_correction(gap, s: float, x: np.ndarray) -> np.ndarray:
    """``M(s)⁻¹ x − V(s)`` (n, 3): positions ``x`` at factor ``s`` in the co-moving frame, less the
    keys' co-moving spline."""
    return gap.topo.undo_motion(x, *gap.motion(s)) - gap.spline_at("vertices", s)


def correction_polynomial(gap, solved: dict) -> "CorrectionPolynomial":
    """The polynomial of the co-moving corrections ``D(s)`` (n, 3) through the keys (zero) and the
    ``solved`` poses {factor: positions}, with the keys' slopes (:data:`KEY_SLOPE_SOLVED`; with
    one solved pose too, :data:`~core.inbetween_prediction.MIDDLE_SOLVED_BATCH`)."""
    values = {s: co_moving_correction(gap, s, x) for s, x in solved.items()}
    slopes = (_key_slope(gap, 0.0), _key_slope(gap, 1.0)) if len(solved) >= KEY_SLOPE_SOLVED or len(solved) == 1 else None
    return CorrectionPolynomial(values, slopes)


def _key_slope(gap, s: float) -> np.ndarray:
    """``D'(s)`` (n, 3) at key ``s`` (0 or 1) that gives the pose ``M (V + D)`` the velocity of the
    gap's guide there: ``M(s)⁻¹ (G'(s) − (M V)'(s))`` (``D(s) = 0`` at a key), by a one-sided
    difference inside the gap (:data:`SLOPE_STEP`) of the guide's offset from ``M V``, which is
    zero at the key. On components that turn as a whole (guided by ``M V``,
    :data:`core.inbetween_guide.ARC_GUIDE_STRAIN_RATIO`) the world spline's velocity, which the
    gaps on either side of the key share, except at a sequence's last key."""
    step = SLOPE_STEP if s == 0.0 else -SLOPE_STEP
    rotations, _ = gap.motion(s)
    last = s == 1.0 and gap.relatives[3].extrapolated
    change = gap.guide_offset(s + step, gap.motion(s + step), arcs=last) / step
    return gap.topo.undo_motion(change, rotations, np.zeros((len(rotations), 3)))


class CorrectionPolynomial:
    """``D(s)``: the polynomial through ``(0, 0)``, the ``(s_j, D_j)`` of ``values`` {factor:
    (n, 3)} and ``(1, 0)``, and with ``slopes`` ((n, 3) at s = 0 and at s = 1) those derivatives
    at the keys too — the sum of each condition's value times its cardinal polynomial, whose
    monomial coefficients come from one (K × K) solve (K ≤ 7 conditions). Written out rather than
    SciPy's ``KroghInterpolator``: ``scipy.interpolate`` pulls in ``scipy.optimize`` and adds 0.1 s
    to the first in-between of a Blender session."""

    def __init__(self, values: dict, slopes: tuple[np.ndarray, np.ndarray] | None = None):
        self.factors = sorted(values)
        conditions = [(0.0, 0), *((s, 0) for s in self.factors), (1.0, 0)]  # (node, derivative order)
        data = [None, *(values[s] for s in self.factors), None]  # None: zero
        if slopes is not None:
            conditions += [(0.0, 1), (1.0, 1)]
            data += list(slopes)
        self.powers = np.arange(len(conditions))
        rows = [self.powers * node ** np.maximum(self.powers - 1, 0) if order else node ** self.powers
                for node, order in conditions]
        self.cardinal = np.linalg.inv(np.array(rows, dtype=float))  # column k: condition k's polynomial
        self.terms = [(k, value) for k, value in enumerate(data) if value is not None]

    def __call__(self, s: float) -> np.ndarray:
        weights = (float(s) ** self.powers) @ self.cardinal
        out = np.zeros_like(self.terms[0][1])
        for k, value in self.terms:
            out += weights[k] * value
        return out


class PiecewiseLinearCorrection:
    """``D(s)`` (n, 3) of a rough gap: linear between the two knots around ``s`` among the keys
    (zero) and the solved corrections ``values`` {factor: (n, 3)}. Corrections that do not vary
    smoothly give no polynomial to trust between the knots; the chord never leaves the two it
    joins (a cubic through four rough knots overshoots them)."""

    def __init__(self, values: dict):
        self.knots = [0.0, *sorted(values), 1.0]
        self.values = [None, *(values[s] for s in sorted(values)), None]  # None: zero

    def __call__(self, s: float) -> np.ndarray:
        right = min(max(int(np.searchsorted(self.knots, s, side="right")), 1), len(self.knots) - 1)
        a, b = self.knots[right - 1], self.knots[right]
        w = (float(s) - a) / (b - a)
        out = np.zeros_like(next(v for v in self.values if v is not None))
        for weight, value in ((1.0 - w, self.values[right - 1]), (w, self.values[right])):
            if value is not None:
                out += weight * value
        return out


def slopes_disagree(gap, correction: "CorrectionPolynomial", solved: dict, factors: list) -> bool:
    """Whether ``gap`` joins the only two keys of a sequence (the keys' spline is their chord) and
    ``correction`` (the quartic through the keys' zeros and slopes and the one ``solved`` pose
    {factor: positions}) and the parabola through the keys' zeros and that pose alone differ by
    more than :data:`MAX_SLOPE_DISAGREEMENT` mean edge lengths (RMS over the vertices) at one of
    ``factors``: the slopes, which no key tells, then decide the predictions there, not the solved
    pose."""
    if gap.cubic:  # three keys or more: the slope at an inner key is the neighbouring keys' central difference
        return False
    (s, x), = solved.items()
    parabola = CorrectionPolynomial({s: co_moving_correction(gap, s, x)})
    limit = (MAX_SLOPE_DISAGREEMENT * gap.mean_edge) ** 2
    return any(np.mean(np.sum((correction(f) - parabola(f)) ** 2, axis=1)) > limit for f in factors)


def inconsistent(gap, solved: dict) -> bool:
    """Whether the corrections of the ``solved`` poses {factor: positions} (three or more) do not
    vary smoothly enough to predict from: the middle one, predicted from the others, misses it by
    more than :data:`MAX_CROSS_VALIDATION` of its size."""
    factors = sorted(solved)
    middle = factors[len(factors) // 2]
    others = {s: x for s, x in solved.items() if s != middle}
    predicted = correction_polynomial(gap, others)(middle)
    actual = co_moving_correction(gap, middle, solved[middle])
    size = np.sqrt(np.mean(np.sum(actual ** 2, axis=1)))
    return bool(np.sqrt(np.mean(np.sum((predicted - actual) ** 2, axis=1))) > MAX_CROSS_VALIDATION * size)


def predicted_positions(gap, s: float, correction, motion) -> np.ndarray:
    """The prediction at ``s`` before its pins and carried pieces: the co-moving spline plus the
    ``correction`` at ``s``, moved by the gap's interpolated rigid ``motion`` there."""
    return gap.topo.apply_motion(gap.spline_at("vertices", s) + correction(s), *motion)


def pins_in_place(gap, x: np.ndarray, s: float) -> np.ndarray:
    """Predicted positions ``x`` (n, 3) at factor ``s`` with the pinned vertices moved where they
    belong (``gap.pinned_positions``), and the miss spread around them by one solve of the gap's
    anchored system ``(L + A) δ = A_pinned · miss`` (δ is the miss at the pins and fades over
    ~1/√w edges away from them). A prediction ``M(s) (V(s) + D(s))`` passes through them only at
    the keys and at the solved factors: the interpolated rigid motion of a flapping flag swings
    its pole in between (a flag with small triangles at its pole, keys 8 frames apart: by 22 % of
    the mean edge length), and setting the pins alone back afterwards (``finished``) put the whole
    miss into the triangles at the pole (131 of them turned over). No solve where the miss is under
    :data:`~core.inbetween_fit.METRIC_TOLERANCE` of the mean edge length; the pins are always set
    exactly."""
    still = gap.static
    if still is None:
        return x
    pinned = gap.pinned_positions(s)
    miss = pinned - x[still]
    if np.max(np.abs(miss)) > METRIC_TOLERANCE * gap.mean_edge:
        factor, anchor = gap.system
        rhs = np.zeros_like(x)
        rhs[still] = anchor[still, None] * miss
        x = x + factor.solve(rhs)
    # the pins exactly where they belong (the solve leaves ~1/w of the miss, and a smaller miss is
    # not spread): the defect check and its repairs, which hold the pins, see the pose as returned
    x[still] = pinned
    return x


def _relaxation(gap, s: float, correction) -> np.ndarray:
    """The co-moving displacement (n, 3) that one local/global step toward the interpolated metric
    gives the prediction at ``s``: each triangle's metric turned by its own rotation in the
    prediction (the polar factor, no limit about the interpolated rotations), the positions solved
    with the gap's anchor pulling toward the prediction itself (not the spline: its long
    wavelengths stay, its short ones take the metric's lengths)."""
    motion = gap.motion(s)
    x = pins_in_place(gap, predicted_positions(gap, s, correction, motion), s)
    targets = gap.local_step_targets(gap.fit_targets(None, gap.stretch(s)))
    y = gap.solve(gap.fitted_edges(gap.edges_of(x, LOCAL_STEP_DTYPE), targets), x, s=s)
    return gap.topo.undo_motion(y - x, motion[0], np.zeros((len(motion[0]), 3)))


def relaxed_correction(gap, correction, factors: list) -> "RelaxedCorrection":
    """``correction`` plus the relaxations (:func:`_relaxation`) at the middle of each span
    between the keys and the solved ``factors``, each spread over its span by a parabola (one at the
    middle, zero at the span's ends, where the keys and the solved poses already are fits)."""
    knots = [0.0, *factors, 1.0]
    middles = [0.5 * (a + b) for a, b in zip(knots[:-1], knots[1:])]
    return RelaxedCorrection(correction, knots, per_factor(gap, lambda s: _relaxation(gap, s, correction), middles))


class RelaxedCorrection:
    """``D(s)`` of a :class:`CorrectionPolynomial` plus relaxations spread over the spans
    between ``knots`` (see :func:`relaxed_correction`)."""

    def __init__(self, correction, knots: list, displacements: list):
        self.correction, self.knots, self.displacements = correction, knots, displacements

    def __call__(self, s: float) -> np.ndarray:
        out = self.correction(s)
        span = min(max(int(np.searchsorted(self.knots, s, side="right")) - 1, 0), len(self.displacements) - 1)
        a, b = self.knots[span], self.knots[span + 1]
        u = (2.0 * s - a - b) / (b - a)
        return out + (1.0 - u * u) * self.displacements[span] if abs(u) < 1.0 else out
