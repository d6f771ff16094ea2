"""The warning of a sequence's gap beside a key that catches a brief stretch on a motion passing
through it (paper §8.4: sequences; the interpolated metric of §7.3 between keys).

A sequence's in-betweens take the metric interpolated between their keys. Where one key catches a
stretch its neighbours do not have — cloth landing on a collider just before that key, stretched
for a frame or two by the impact — the in-betweens on either side of it carry a share of that
stretch through the whole gap, while the simulation they stand for had it for a frame or two: a
64k sheet falling onto five boxes, keyed every 16th frame, lands at frame 11 and is 4.88 % off its
rest at key 16, 1.30 % at frame 24; the in-betweens of both gaps follow the keys (1.04–1.19 × the
keys' interpolated deviation) and the cell ends over issue 17's bound (3.21 against 2.99 %) with
every fit within what :mod:`core.sequence_edge_misfit` allows (docs/inbetween-measurements.md).

Three keys alone do not tell such a stretch from a swing sampled at its extremes (a tail wagged
left, right, left: the middle key 3.4 % off the first, the third 0.5 %), whose true in-betweens
pass through the stretched shapes as the interpolated ones do. What tells them apart is the
motion: a swing turns back at the key, so the keys either side of it are nearer each other than
either is to it; where the motion passes on through the key (its neighbours farther apart than
the nearer of them is from it, :data:`PASSING_THROUGH`), nothing in the keys says the stretch
lasts, and a gap beside that key whose in-betweens end off the rest by more than the gap's
other key allows is warned of (deviations from the caller's rest pose where given, else from the
first key: :mod:`core.sequence_edge_misfit`).

The distances are between whole shapes, the stretch included: where the stretch is most of what
changes at the key (a sheet landing flat on a floor, a bounce back toward the shape before, a pulse
on a still mesh), its neighbours are nearer each other than either is to it, as a swing's are, and
nothing is warned (test strips 3–10 × past the allowance, unwarned); nor at the first and last keys,
which have one neighbour (docs/inbetween-measurements.md, *The caught-stretch warning's limits*).
"""

from __future__ import annotations

import numpy as np

from .inbetween_prediction import SOLVED_FACTORS
from .rigid_alignment import align_rigidly
from .sequence_edge_misfit import MISFIT_NOTED_FLOOR, MISFIT_NOTED_MARGIN, misfit_allowed

__all__ = ["PASSING_THROUGH", "caught_stretch", "caught_stretch_factors", "caught_stretch_warning", "passing_through"]

#: A key whose stretch its neighbours do not have (:func:`caught_stretch`) is on a motion that passes
#: through it where the RMS distance between its two neighbouring keys, each placed rigidly on it, is at
#: least this times the smaller of their distances to it: the motion goes on past the key instead of
#: turning back at it. A swing sampled at its extremes turns back (the tail wagged 1 / −1 / 1.2 and
#: 1.2 / −1 / 1: 0.40 / 0.43; 1 / −1 / 1.4: 0.81); a landing does not (the 64k sheet over five boxes,
#: keys 16 / 8 apart: 1.77 / 1.60; the other keys of the benchmark and session 71's audit bakes over
#: their neighbours' deviation: 0.85–2.54, docs/inbetween-measurements.md). 1: the key's neighbours
#: as far apart as the nearer is from it.
PASSING_THROUGH = 1.0


def passing_through(before: np.ndarray, key: np.ndarray, after: np.ndarray) -> float:
    """RMS distance between the keys ``before`` and ``after`` (n, 3) either side of ``key`` (n, 3),
    ``after`` placed rigidly on ``before`` (Kabsch, :func:`core.rigid_alignment.align_rigidly`), ÷ the
    smaller of their RMS distances to ``key`` (each placed rigidly on it): under 1 where the motion
    turns back at ``key``, 1 or more where it goes on past it (:data:`PASSING_THROUGH`); ``inf``
    where a neighbour is ``key`` itself (the distance to it exactly 0)."""
    def apart(a, b):
        return float(np.sqrt(np.mean(np.sum((align_rigidly(b, a) - a) ** 2, axis=1))))

    nearer = min(apart(key, before), apart(key, after))
    return apart(before, after) / nearer if nearer > 0.0 else float("inf")


def caught_stretch(deviations, shapes) -> bool:
    """Whether the middle of three consecutive keys catches a stretch on a motion passing through it:
    its mean relative edge deviation from the rest (``deviations``, the three keys',
    :func:`core.sequence_edge_misfit.key_deviation`) is over what the larger of its neighbours' allows
    an in-between (:func:`core.sequence_edge_misfit.misfit_allowed`: twice it + 0.1 point, at least
    0.3 %) and the keys ``shapes`` (three (n, 3) positions) pass on through it
    (:func:`passing_through` at least :data:`PASSING_THROUGH`)."""
    before, at, after = (float(d) for d in deviations)
    if at <= misfit_allowed([max(before, after)]):
        return False
    return passing_through(*shapes) >= PASSING_THROUGH


def caught_stretch_factors(factors) -> list[float]:
    """Of a gap's in-betweens asked at ``factors`` (in (0, 1)), those whose mean edge deviation
    stands for all of theirs in :func:`caught_stretch_warning`: all of them where there are three or
    fewer, else the nearest to each of :data:`core.inbetween_prediction.SOLVED_FACTORS` (¼, ½, ¾ of
    the gap), where a gap's in-betweens are solved (the others are predicted between them).
    Measuring every in-between of gaps 16 frames long cost 9 % of the tablecloth's sequence
    (docs/inbetween-measurements.md)."""
    factors = np.unique(np.asarray(factors, dtype=np.float64))
    if factors.size <= len(SOLVED_FACTORS):
        return factors.tolist()
    return np.unique(factors[np.abs(np.subtract.outer(SOLVED_FACTORS, factors)).argmin(axis=1)]).tolist()


def caught_stretch_warning(deviation: float, other: float, names: tuple[str, str], at: str, key: float, factors,
                           reference: str = "the first key") -> tuple[str, tuple[float, ...], float] | None:
    """The message, factors and excess (``deviation`` ÷ what ``other`` allows, over 1) of the warning of
    a gap (keys ``names``) beside the key named ``at`` that catches a stretch (:func:`caught_stretch`;
    ``key`` its mean relative edge deviation from the rest), whose in-betweens at ``factors`` are
    off the rest by ``deviation`` on average (mean relative edge deviation), more than twice the
    gap's other key's (``other``) + 0.1 point (at least 0.3 %); None where they are not. The deviations are
    from ``reference``, as the message names it (the first key, or the caller's rest pose)."""
    allowed = misfit_allowed([other])
    if deviation <= allowed:
        return None
    other_key = names[1] if at == names[0] else names[0]
    return (f"between {names[0]} and {names[1]}, the in-betweens' edges are {100 * deviation:.1f} % off "
            f"{reference}'s on average, {deviation / allowed:.1f} × what {other_key} allows "
            f"(twice its {100 * other:.1f} % + {100 * MISFIT_NOTED_MARGIN:.1f} point, at least "
            f"{100 * MISFIT_NOTED_FLOOR:.1f} %): {at} catches a stretch ({100 * key:.1f} %) neither key beside it has, "
            f"on a motion that passes through it (cloth landing just before it?), and the in-betweens carry a share of "
            f"it across the gap where the stretch may have lasted a frame or two; add keys in this gap or use a "
            f"smaller step", tuple(factors), deviation / allowed)
