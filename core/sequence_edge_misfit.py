"""The warning of a sequence's gap whose in-betweens come out far off the interpolated edge
lengths (paper §7.3: the reconstruction fits the interpolated metric; §8.4: sequences).

A sequence's in-between is fitted to the metric interpolated between its keys while an anchor
holds it near the keys' per-vertex spline (:mod:`core.inbetween_anchor`). Where the keys turn the
cloth far (a fold forming, a cape swung round), that spline cuts the chords of the arcs the cloth
travels and the fit stays compressed in its plane, its edges shorter than the metric's: a walking
cape whose gap turns 131° between keys 8 frames apart came out with edges 21 % shorter half-way
where the simulation stays within 1 % of its rest. The fits measure that misfit at every step
(:meth:`core.inbetween_fit.LocalGlobalFit.misfit`; :attr:`core.inbetween_solver.Gap.fit_misfits`
keeps the least of each in-between fitted), so the check costs the caller nothing: it holds the
fit's misfit to what issue 17 allows a simulation's in-betweens, edge lengths within twice the
simulation's own deviation from its rest + 0.1 point, the keys' own deviation from the rest standing
in for the simulation's: from the caller's rest pose where given (``rest_pose`` of
:class:`core.SequenceInterpolator`), else from the first key, the rest where the keys start at a
simulation's first frame (keys cut from the middle of one are measured against a deformed shape
there: docs/inbetween-measurements.md, *The edge warnings' reference*).
"""

from __future__ import annotations

import numpy as np

from .inbetween_fit import METRIC_TOLERANCE, STALL_NEAR

__all__ = ["MISFIT_NOTED_MARGIN", "MISFIT_NOTED_FLOOR", "MORE_KEYS", "key_deviation", "least_shared_deviation",
           "misfit_allowed", "misfit_warning", "off_rest_warning", "signed_deviation"]

#: A gap's in-betweens are warned of where the fit of one of them ends farther from the interpolated
#: metric (its mean relative edge misfit) than twice its keys' mean edge deviation from the rest
#: plus this: the fit alone is then off the keys' lengths by more than issue 17 allows an in-between
#: to be off the rest (2 × the simulation's own deviation + 0.1 point), the keys standing in for the
#: simulation. On 57 benchmark and 21 unseen cells it warns all 14 cells above the bound and 12 of
#: the 64 within it; the keys' deviation taken once (the misfit added to the keys' own deviation
#: reaching the bound) warned 32 of those 64 (docs/inbetween-measurements.md).
MISFIT_NOTED_MARGIN = 1e-3
#: ... and never under this: what a fit may end at where the interpolated metric is not reachable
#: and its steps stall (:data:`core.inbetween_fit.STALL_NEAR` × :data:`~core.inbetween_fit.METRIC_TOLERANCE`),
#: the method's own accuracy. Keys that barely stretch (a sheet folding isometrically: the keys'
#: deviation 0) would otherwise be warned of at 0.2 % (edges shorter by a fifth of a percent).
MISFIT_NOTED_FLOOR = STALL_NEAR * METRIC_TOLERANCE


def misfit_allowed(key_deviations) -> float:
    """The misfit a gap's fits may end at unwarned, given its two keys' mean relative edge
    deviations from the rest (:func:`key_deviation`): twice their mean +
    :data:`MISFIT_NOTED_MARGIN`, at least :data:`MISFIT_NOTED_FLOOR`."""
    return max(2.0 * float(np.mean(key_deviations)) + MISFIT_NOTED_MARGIN, MISFIT_NOTED_FLOOR)


def _relative_changes(lengths: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """``ℓ / ℓ₀ − 1`` (k,) of corner edge lengths ``lengths`` (m, 3) against ``rest`` (m, 3), on the
    k edges of positive ``rest`` (edges of zero rest length are left out), in row-major order (a new
    array the caller may change in place)."""
    kept = rest > 0.0
    if kept.all():  # every edge: the same values in the same order without the two masked gathers,
        # which on the corner lengths' transposed views (m, 3) of (3, m) rows cost more than the division
        changes = np.divide(lengths, rest, order="C").reshape(-1)
        changes -= 1.0
        return changes
    return lengths[kept] / rest[kept] - 1.0


def key_deviation(lengths: np.ndarray, rest: np.ndarray) -> float:
    """Mean relative deviation ``|ℓ / ℓ₀ − 1|`` of a key's corner edge lengths ``lengths`` (m, 3)
    from those of the rest, ``rest`` (m, 3) (the caller's rest pose, or the first key); edges of zero
    rest length are left out."""
    changes = _relative_changes(lengths, rest)
    return float(np.mean(np.abs(changes, out=changes))) if changes.size else 0.0


def least_shared_deviation(lengths: np.ndarray, other: np.ndarray, floor: float = 0.0) -> float:
    """The least mean relative edge deviation two poses' corner edge lengths ``lengths`` and
    ``other`` (same shape, such as (m, 3) or (3m,)) can have from a rest they share, on average
    over the two (two poses, whose rest is not given: :mod:`core.two_pose_inbetweens`). Per edge,
    ``|ℓa / ℓ₀ − 1| + |ℓb / ℓ₀ − 1|`` is least at ``ℓ₀ = max(ℓa, ℓb)``, where it is
    ``|ℓa − ℓb| / max(ℓa, ℓb)``; this is half its mean over the edges of positive length in either
    pose (an edge under ``floor`` in both measured over ``floor``, as the fits measure it:
    :data:`core.inbetween_fit.MISFIT_LENGTH_FLOOR`). Symmetric in the two poses, each edge's term
    at most 1: with the first pose taken as the rest (:func:`key_deviation`) an edge reads
    ``|ℓa − ℓb| / ℓa``, no less, and one crushed to a tenth in it a change of 900 %."""
    longer = np.maximum(lengths, other)
    kept = longer > 0.0
    if not kept.any():
        return 0.0
    return 0.5 * float(np.mean(np.abs(lengths[kept] - other[kept]) / np.maximum(longer[kept], floor)))


def signed_deviation(lengths: np.ndarray, target: np.ndarray) -> float:
    """Mean signed relative deviation ``ℓ / ℓ* − 1`` of an in-between's corner edge lengths
    ``lengths`` (m, 3) from ``target`` (m, 3), the keys' edge lengths interpolated at its factor:
    negative where its edges are shorter on average (the ``signed`` of :func:`misfit_warning`)."""
    return float(np.mean(_relative_changes(lengths, target)))


#: What :func:`misfit_warning` tells a sequence to do: key the gap more often.
MORE_KEYS = "add keys in this gap or use a smaller step"


def misfit_warning(fit_misfits: dict, factors, allowed: float, names: tuple[str, str],
                   signed, reference: str = "the first key", advice: str = MORE_KEYS, made: str = "its fit",
                   cause: str | None = None) -> tuple[str, tuple[float, ...], float] | None:
    """The message, factors and excess (the worst fit's misfit ÷ ``allowed``, over 1:
    :attr:`core.errors.ShapeDifferenceWarning.excess`) of the warning of a gap (keys ``names``) whose in-betweens at
    ``factors`` include fitted ones (``fit_misfits`` {factor: the least mean relative edge misfit
    of its fit}, :attr:`core.inbetween_solver.Gap.fit_misfits`) farther than ``allowed`` off the
    interpolated metric; None where none is. ``signed(factor)``: the mean signed relative
    deviation of that in-between's edges from the keys' edge lengths interpolated, asked of the
    worst one only (it measures the pose once more). ``reference``: what the keys' deviation that
    sets ``allowed`` is from, as the message names it (the first key, or the caller's rest pose;
    two poses: the least from a rest they share, :func:`least_shared_deviation`).
    ``advice``: what the message tells the caller to do (:data:`MORE_KEYS`; two poses: a pose between
    them, :mod:`core.two_pose_inbetweens`). ``made`` and ``cause``: what the bracket calls the pose
    measured and why its edges are off, where it is no fit (two poses' blend); else the fit and the
    spline's chords or the fit's reach."""
    asked = [s for s in factors if 0.0 < s < 1.0]
    fitted = {s: fit_misfits[s] for s in asked if s in fit_misfits}
    over = sorted(s for s, m in fitted.items() if m > allowed)
    if not over:
        return None
    worst = max(over, key=lambda s: fitted[s])
    misfit, change = fitted[worst], signed(worst)
    way = "shorter" if change < -0.5 * misfit else "longer" if change > 0.5 * misfit else "off"
    what = {"shorter": "than the keys' edge lengths interpolated on average: the cloth is compressed in its plane"
                       + (", as where the keys turn it far between them" if cause is None else ""),
            "longer": "than the keys' edge lengths interpolated on average: the cloth is stretched in its plane",
            "off": "the keys' edge lengths interpolated on average, some shorter, some longer"}[way]
    # the spline's chords shorten edges; edges longer, or off both ways, no chord explains
    if cause is None:
        cause = ("the anchor toward the keys' per-vertex spline cuts the chords of the arcs" if way == "shorter" else
                 "the fit does not reach the interpolated metric near the keys' per-vertex spline")
    if len(asked) == 1:
        place = f"the in-between at factor {worst:g}"
    else:
        fitted_only = "" if len(fitted) == len(asked) else f" ({len(fitted)} fitted, the others predicted from them)"
        place = f"{len(over)} of the {len(asked)} in-betweens{fitted_only}, the worst at factor {worst:g}"
    return (f"between {names[0]} and {names[1]}, {place}: its edges are "
            f"{100 * (abs(change) if way != 'off' else misfit):.1f} % {way} {what}; {advice} "
            f"[{made} ends {100 * misfit:.1f} % off the interpolated metric (mean relative edge "
            f"misfit), over the {100 * allowed:.1f} % the keys' own edge deviation from {reference} allows (twice it + "
            f"{100 * MISFIT_NOTED_MARGIN:.1f} point, at least {100 * MISFIT_NOTED_FLOOR:.1f} %): {cause}]", tuple(over),
            misfit / allowed)


def off_rest_warning(deviation: float, key_deviations, factors, names: tuple[str, str],
                     reference: str = "the first key") -> tuple[str, tuple[float, ...], float] | None:
    """The message, factors and excess (``deviation`` ÷ what the keys allow, over 1) of the warning of
    a gap (keys ``names``) whose in-betweens at ``factors`` (in (0, 1)) are off the rest by ``deviation``
    on average (mean relative edge deviation from ``reference``, as the message names it), more than
    issue 17's bound with the keys standing in for the simulation: twice the keys' deviations
    ``key_deviations`` (the two keys', :func:`key_deviation`) interpolated at ``factors`` + 0.1 point,
    at least 0.3 % (:func:`misfit_allowed`); None where they are not. It reads what the bound reads,
    the in-betweens' own edges against the rest, where :func:`misfit_warning` reads the fits' edges
    against the interpolated metric: an in-between predicted between fitted ones, or one whose fit
    is near a metric farther off the rest than the keys' lengths interpolated, is seen here only."""
    before, after = (float(d) for d in key_deviations)
    allowed = misfit_allowed([(1.0 - s) * before + s * after for s in factors])
    if deviation <= allowed:
        return None
    return (f"between {names[0]} and {names[1]}, the in-betweens' edges are {100 * deviation:.1f} % off "
            f"{reference}'s on average, {deviation / allowed:.1f} × what the keys allow (twice their own "
            f"deviation from it, {100 * before:.1f} and {100 * after:.1f} %, interpolated at the in-betweens' factors, "
            f"+ {100 * MISFIT_NOTED_MARGIN:.1f} point, at least {100 * MISFIT_NOTED_FLOOR:.1f} %): the in-betweens "
            f"stretch or compress the cloth farther than the keys do; {MORE_KEYS}", tuple(factors), deviation / allowed)
