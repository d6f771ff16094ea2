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
changes at the key (a sheet landing flat on a floor, a bounce off it, a pulse on a still mesh), its
neighbours are nearer each other than either is to it, as a swing's are. What tells those apart
from a swing is what changes: a swing turns the cloth's triangles, a flat landing or a pulse only
stretches them. Where the key's triangles turn against each neighbour placed rigidly on it by
less, in radians, than its edges stretch from that neighbour's (:func:`stretch_alone`,
:data:`STRETCH_ALONE`: an edge's end moves less by the turn than by the stretch), and against one
neighbour as the keys give it (the cloth lies still on one side of the key: landed after it, or
on both sides of a bounce or a pulse), no motion of the keys' shape says the stretch lasts, and it
is read as caught too. A pendulum swinging rigidly, stretched most at the bottom where it is
fastest, turns against both neighbours as a whole: it turns back at its extremes as a swing does
and its stretch follows its speed, which the interpolated metric follows too (its in-betweens
within 0.02 point of the swing's stretch, 1.75 % at the bottom). A bounce that bends the
cloth back toward the shape before (bent 20°, 60° stretched, 25°) turns its triangles as a swing
does and is read by the motion in the world instead, below; the first and last keys, which have one
neighbour, stay unwarned (docs/inbetween-measurements.md, *The caught-stretch warning's limits*;
docs/limits.md).

Where the deviations are from a rest — the caller's rest pose, or a first key the sequence starts
from at rest, a simulation's first frame — a key the motion turns back at in the world (its
neighbours as given, not placed rigidly, nearer each other than the nearer is to it:
:func:`passing_through` with ``placed=False`` under :data:`PASSING_THROUGH`) is read as catching
the stretch too (``"back"``): a free swing turns back where it is slowest, and its pull, which grows
with its speed, is least there (a pendulum's stretch is at its bottom, which the motion passes
through as given), so a key stretched past both its neighbours where the cloth turns back was
pushed there: a collider pressing into it, as a ball bouncing in a hammock does, and the cloth
springs back within a few frames (a gathered hammock keyed every 16th frame, its key at the
bounce's bottom: docs/inbetween-measurements.md, *A bounce the keys straddle*). The cloth's own springs stretch it most where
it turns back too, with no collider (a sheet pinned all round sagging from flat, keyed where its first sag
bottoms out): that key reads so and its first gap is warned, its in-betweens within both peers
(docs/inbetween-measurements.md, *Review r1 of the bounce warning*). Keys cut from the middle of a motion
(``start="keys"``) without a rest pose are not read so: their first key is not the rest, and a
swing reversed at a key (a tail wagged left, right, left) reads as stretch from it.
"""

from __future__ import annotations

import numpy as np

from .geometry import coordinate_cross, coordinate_dot
from .inbetween_prediction import SOLVED_FACTORS
from .rigid_alignment import align_rigidly
from .sequence_edge_misfit import MISFIT_NOTED_FLOOR, MISFIT_NOTED_MARGIN, key_deviation, misfit_allowed

__all__ = ["PASSING_THROUGH", "STRETCH_ALONE", "caught_stretch", "caught_stretch_factors", "caught_stretch_warning",
           "passing_through", "stretch_alone"]

#: A key whose stretch its neighbours do not have (:func:`caught_stretch`) is on a motion that passes
#: through it where the RMS distance between its two neighbouring keys, each placed rigidly on it, is at
#: least this times the smaller of their distances to it: the motion goes on past the key instead of
#: turning back at it. A swing sampled at its extremes turns back (the tail wagged 1 / −1 / 1.2 and
#: 1.2 / −1 / 1: 0.40 / 0.43; 1 / −1 / 1.4: 0.81); a landing does not (the 64k sheet over five boxes,
#: keys 16 / 8 apart: 1.77 / 1.60; the other keys of the benchmark and session 71's audit bakes over
#: their neighbours' deviation: 0.85–2.54, docs/inbetween-measurements.md). 1: the key's neighbours
#: as far apart as the nearer is from it.
PASSING_THROUGH = 1.0
#: A key whose stretch its neighbours do not have, on a motion that turns back at it
#: (:func:`passing_through` under :data:`PASSING_THROUGH`), is still read as catching it where its
#: triangles turn against each neighbour placed rigidly on it, and against one of them as given (the
#: whole's turn counted: a rigid pendulum's swing turns it against both), by at most this times its
#: mean relative edge deviation from that neighbour (RMS angle between the triangles' normals,
#: radians): an edge of length ℓ turned by θ moves its end by ℓθ, stretched by ε by ℓε, so at 1 the
#: stretch moves the mesh more than the turns do and is what changes at the key (:func:`stretch_alone`).
#: The test strips landing flat (6 % along one or both ways), bouncing off a floor and pulsed in place
#: turn 0 against 3.0–6.0 % (landing from a fall tilted 10°: 0.17 rad against the fall as given, 0
#: against the floor); the swing and the bent bounce 0.28–3.1 rad against 3 % placed rigidly; a rigid
#: pendulum (±40°, stretched 4 % at the bottom, 0.5 % at the extremes) 0 placed, 0.70 rad against both
#: as given, its stretch 1.8 %. The benchmark's and three audit bakes' keys over a neighbour's
#: allowance turn 8.1–221 × what they stretch (76 keys; four hanging curtains' first keys 0, none over
#: its larger neighbour's allowance), the one it reads (curtain_ball_15k, g = 16, key 1) 12.6 × placed
#: rigidly, 11.1–12.3 × as given (docs/inbetween-measurements.md, *Edge warnings that were silent*;
#: *Review of the edge warnings and of the counts' reuse*).
STRETCH_ALONE = 1.0


def passing_through(before: np.ndarray, key: np.ndarray, after: np.ndarray, placed: bool = True) -> float:
    """RMS distance between the keys ``before`` and ``after`` (n, 3) either side of ``key`` (n, 3),
    ``after`` placed rigidly on ``before`` (Kabsch, :func:`core.rigid_alignment.align_rigidly`), ÷ the
    smaller of their RMS distances to ``key`` (each placed rigidly on it): under 1 where the motion
    turns back at ``key``, 1 or more where it goes on past it (:data:`PASSING_THROUGH`); ``inf``
    where a neighbour is ``key`` itself (the distance to it exactly 0). ``placed=False``: the keys as
    given, none placed on another (the motion in the world, a rigid swing's included)."""
    def apart(a, b):
        return float(np.sqrt(np.mean(np.sum(((align_rigidly(b, a) if placed else b) - a) ** 2, axis=1))))

    nearer = min(apart(key, before), apart(key, after))
    return apart(before, after) / nearer if nearer > 0.0 else float("inf")


def stretch_alone(key: np.ndarray, neighbours, corner_edges) -> bool:
    """Whether the stretch is what changes between ``key`` (n, 3) and each of its ``neighbours``
    ((n, 3) each): the RMS over the triangles of the angle between their normals in ``key`` and in the
    neighbour placed rigidly on it (radians) is at most :data:`STRETCH_ALONE` × the key's mean relative
    edge deviation from the neighbour (:func:`core.sequence_edge_misfit.key_deviation`) for each
    neighbour, and for one of them also with the neighbour as given (the whole's turn counted: a
    sheet landing from a tilted fall lies still after the key; a rigid pendulum turns against both).
    ``corner_edges(x)``: the corner edge vectors of positions ``x`` by coordinate (3 coordinates,
    3 corners, m), as :meth:`core.inbetween_topology.Topology.corner_edge_rows` gives them."""
    def normals_and_lengths(x):
        rows = corner_edges(x)
        normals = coordinate_cross(rows[:, 0], rows[:, 1])
        normals /= np.maximum(np.sqrt(coordinate_dot(normals, normals)), np.finfo(float).tiny)
        return normals, np.sqrt(coordinate_dot(rows, rows))

    normals, lengths = normals_and_lengths(key)
    still = False
    for other in neighbours:
        given, other_lengths = normals_and_lengths(other)
        stretch = STRETCH_ALONE * key_deviation(lengths, other_lengths)
        if _rms_turn(normals, normals_and_lengths(align_rigidly(other, key))[0]) > stretch:
            return False  # the shape bends between them (a swing, a bounce bending back)
        # as given, the whole's turn counted: a pendulum turns against both neighbours, a landing
        # lies still after the key (a bounce, a pulse on both sides)
        still = still or _rms_turn(normals, given) <= stretch
    return still


def _rms_turn(normals: np.ndarray, others: np.ndarray) -> float:
    """RMS over the triangles of the angle (radians) between unit normals ``normals`` and ``others``
    (3 coordinates, m)."""
    return float(np.sqrt(np.mean(np.arccos(np.clip(coordinate_dot(normals, others), -1.0, 1.0)) ** 2)))


def caught_stretch(deviations, shapes, corner_edges=None, from_rest: bool = False) -> str | None:
    """How the middle of three consecutive keys catches a stretch, or None where it does not: its
    mean relative edge deviation from the rest (``deviations``, the three keys',
    :func:`core.sequence_edge_misfit.key_deviation`) is over what the larger of its neighbours' allows
    an in-between (:func:`core.sequence_edge_misfit.misfit_allowed`: twice it + 0.1 point, at least
    0.3 %), and the keys ``shapes`` (three (n, 3) positions) pass on through it (``"through"``:
    :func:`passing_through` at least :data:`PASSING_THROUGH`) or, given ``corner_edges`` (as
    :func:`stretch_alone` takes it), differ from it by its stretch more than by their triangles'
    turns (``"alone"``), or, where ``from_rest`` (the deviations are from the mesh's rest, not from a
    deformed first key), turn back at it in the world (``"back"``: :func:`passing_through` of the
    keys as given under :data:`PASSING_THROUGH`)."""
    before, at, after = (float(d) for d in deviations)
    if at <= misfit_allowed([max(before, after)]):
        return None
    if passing_through(*shapes) >= PASSING_THROUGH:
        return "through"
    if corner_edges is not None and stretch_alone(shapes[1], (shapes[0], shapes[2]), corner_edges):
        return "alone"
    if from_rest and passing_through(*shapes, placed=False) < PASSING_THROUGH:
        return "back"
    return None


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
                           reference: str = "the first key",
                           how: str = "through") -> tuple[str, tuple[float, ...], float] | None:
    """The message, factors and excess (``deviation`` ÷ what ``other`` allows, over 1) of the warning of
    a gap (keys ``names``) beside the key named ``at`` that catches a stretch (:func:`caught_stretch`;
    ``key`` its mean relative edge deviation from the rest), whose in-betweens at ``factors`` are
    off the rest by ``deviation`` on average (mean relative edge deviation), more than twice the
    gap's other key's (``other``) + 0.1 point (at least 0.3 %); None where they are not. The deviations are
    from ``reference``, as the message names it (the first key, or the caller's rest pose). ``how``: how
    the key catches it (:func:`caught_stretch`), as the message says it."""
    allowed = misfit_allowed([other])
    if deviation <= allowed:
        return None
    other_key = names[1] if at == names[0] else names[0]
    return (f"between {names[0]} and {names[1]}, the in-betweens' edges are {100 * deviation:.1f} % off "
            f"{reference}'s on average, {deviation / allowed:.1f} × what {other_key} allows "
            f"(twice its {100 * other:.1f} % + {100 * MISFIT_NOTED_MARGIN:.1f} point, at least "
            f"{100 * MISFIT_NOTED_FLOOR:.1f} %): {at} catches a stretch ({100 * key:.1f} %) neither key beside it has, "
            f"{_HOW[how]}, and the in-betweens carry a share of "
            f"it across the gap where the stretch may have lasted a frame or two; add keys in this gap or use a "
            f"smaller step", tuple(factors), deviation / allowed)


#: How a key catches a stretch (:func:`caught_stretch`), as :func:`caught_stretch_warning` says it.
_HOW = {"through": "on a motion that passes through it (cloth landing just before it?)",
        "alone": ("with little else changing at it: its triangles turn less against the keys beside it than its "
                  "edges stretch (cloth landing flat, bouncing off a surface, or a pulse of stretch?)"),
        "back": ("where the motion turns back, at which a free swing is least stretched (a collider pressing "
                 "into the cloth, a ball bouncing in it?)")}
