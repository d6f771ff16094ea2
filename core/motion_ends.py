"""How a sequence's in-betweens leave its first key and reach its last: the ``start``
(``"rest"`` or ``"keys"``) and the ``end`` (``"keys"`` or ``"rest"``) of
:class:`~core.sequence_inbetweens.SequenceInterpolator`, chosen from the source's frame in the middle
of the first or the last gap (:func:`start_of_motion`, :func:`end_of_motion`; the operators and
:mod:`core.retime` call them). docs/inbetween-measurements.md, *How a motion leaves its first key* and *How a
motion reaches its last key*, has the measurements.
"""

from __future__ import annotations

import numpy as np

from .splines import END_TANGENT_LIMIT, START_TANGENT_LIMIT, TANGENT_LIMIT, limited_tangent, slowing_end_correction


def start_of_motion(keys, middle, factor: float, durations=None) -> str:
    """``"rest"`` or ``"keys"`` (the ``start`` of :class:`~core.sequence_inbetweens.SequenceInterpolator`) for a sequence's
    first gap, from its first three keys ``keys`` (3, n, 3) and the source's frame ``middle``
    (n, 3) inside the first gap at ``factor`` of it (0 < factor < 1; the middle frame).
    ``durations``: the first two gaps' lengths (keys unevenly spaced), or None (even).

    Each start's per-vertex spline over the first gap — the end tangent the mean of the two
    secants per unit time (at most :data:`~core.splines.END_TANGENT_LIMIT` × the gap's secant per
    point), the start tangent zero (``"rest"``) or the parabola's through the three keys, at most
    the secant (``"keys"``, :data:`~core.splines.START_TANGENT_LIMIT`) — is compared with the
    frame: the nearer one (RMS over the vertices). The velocity at the first key does not tell
    them apart: a rig walking from rest is at rest there and at full pace two frames on, and a
    spline from rest spreads that ease over the whole gap (keys 16 frames apart: 9.2 % of the
    diagonal off, from the keys' parabola 4.1 %); a cloth falling from rest and landing in the
    second gap has the walk's keys (docs/inbetween-measurements.md, *How a motion leaves its first key*)."""
    first, second, third = (np.asarray(k, dtype=np.float64) for k in keys)
    first_gap, second_gap = (1.0, 1.0) if durations is None else (float(d) for d in durations)
    secant = second - first
    squared = np.einsum("ij,ij->i", secant, secant)
    onward = (third - second) * (first_gap / second_gap)  # the next move per unit of this gap
    end = limited_tangent(0.5 * (secant + onward), END_TANGENT_LIMIT, squared, rows=True)
    parabola = limited_tangent(1.5 * secant - 0.5 * onward, START_TANGENT_LIMIT, squared, rows=True)
    return "keys" if _nearer(middle, factor, first, secant, (np.zeros_like(secant), end), (parabola, end)) else "rest"


def end_of_motion(keys, middle, factor: float, durations=None) -> str:
    """``"keys"`` or ``"rest"`` (the ``end`` of :class:`~core.sequence_inbetweens.SequenceInterpolator`) for a sequence's
    last gap, from its last three keys ``keys`` (3, n, 3), oldest first, and the source's frame
    ``middle`` (n, 3) inside the last gap at ``factor`` of it (0 < factor < 1; the middle frame).
    ``durations``: the last two gaps' lengths (keys unevenly spaced), or None (even).

    Each end's per-vertex spline over the last gap — the start tangent the mean of the two
    secants per unit time (at most :data:`~core.splines.TANGENT_LIMIT` × the gap's secant per
    point, as the positions' spline limits it), the end tangent the gap's secant slowed where the
    keys slow into the last one, as the sequence's positions and its rigid pieces' motions end there
    (``"keys"``; the secant itself with unevenly spaced last gaps, :func:`~core.splines.slowing_end_correction`,
    :func:`~core.splines.slowing_screw_correction`) or zero
    (``"rest"``) — is compared with the frame: the nearer one (RMS over the vertices; on a tie,
    every point stopping at the last key, ``"rest"``). How
    far an ease into the last key reaches back depends on how long it is against the gap, which
    the velocity at the key does not say: a hopping character keyed in Blender (auto-clamped
    Bézier handles) slows in its last two frames, the rest end right with keys 4 frames apart and
    wrong with keys 8 apart; the frame in the middle tells both (docs/inbetween-measurements.md, *How a motion
    reaches its last key*)."""
    before, start, end = (np.asarray(k, dtype=np.float64) for k in keys)
    back, last = (1.0, 1.0) if durations is None else (float(d) for d in durations)
    secant = end - start
    tangent = limited_tangent(0.5 * ((start - before) * (last / back) + secant), TANGENT_LIMIT,
                       np.einsum("ij,ij->i", secant, secant), rows=True)
    # "keys" ends as the sequence's world spline of positions and its rigid pieces' screws do: slowed
    # where the keys slow into the last one, with evenly spaced last gaps (splines.slowing_end_correction;
    # a rigid piece by its screw's parts, per point the same for a move along a line)
    arrival = secant + slowing_end_correction(before, start, end) if back == last else secant
    # a tie (every point stops at the last key: the slowed end is the rest end) is "rest", which
    # brings every spline of the sequence, not only the positions', to rest there
    return "keys" if _nearer(middle, factor, start, secant, (tangent, np.zeros_like(secant)), (tangent, arrival)) \
        else "rest"


def _nearer(middle, factor: float, start: np.ndarray, secant: np.ndarray, tangents: tuple, other: tuple) -> bool:
    """Whether the per-vertex cubic Hermite spline from ``start`` over ``secant`` with the start
    and end tangents ``other`` is nearer (RMS over the vertices) the pose ``middle`` at ``factor``
    than the one with ``tangents``."""
    s = float(factor)
    at = lambda t0, t1: start + (3 * s * s - 2 * s ** 3) * secant + (s ** 3 - 2 * s * s + s) * t0 + (s ** 3 - s * s) * t1  # noqa: E731
    middle = np.asarray(middle, dtype=np.float64)
    rms = lambda v: float(np.sqrt(np.mean(np.sum(v * v, axis=1))))  # noqa: E731
    return rms(at(*other) - middle) < rms(at(*tangents) - middle)
