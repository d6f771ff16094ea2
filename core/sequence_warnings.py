"""The warnings the in-betweens give (:class:`~core.errors.ShapeDifferenceWarning`, "Shape-difference
interpolation: …"), shared by :mod:`core.sequence_inbetweens` and :mod:`core.two_pose_inbetweens`
(paper §8.4).

Each message says where (the keys of the gap, the factors, how many triangles or pieces), what
happened in the scene's terms and what to do, with the method's own words, where a developer needs
them, at its end in brackets. Each warning's :attr:`~core.errors.ShapeDifferenceWarning.kind` is
one of :data:`~core.errors.KINDS`, for a pipeline to filter on. The problems of the in-betweens asked together
(:meth:`core.SequenceInterpolator.poses`) are said once per gap and kind of problem, with how many
in-betweens have it (:func:`gap_problems`), not once per in-between.
"""

from __future__ import annotations

import re

import numpy as np

from .errors import ShapeDifferenceWarning, shape_warning, warn
from .sequence_gap_starts import STOP_CARRY_RATIO

#: The numbers in a message (counts, indices, factors, frames, shares), masked by
#: :func:`message_shape` to tell messages that differ only in them.
#: A minus sign belongs to the number where no word, digit or point comes before it ("at factor -0.5",
#: not the range "samples 3-4").
_NUMBER = re.compile(r"(?<![\w.])-?\d+(?:[.,]\d+)*(?:e[-+]?\d+)?|\d+(?:[.,]\d+)*(?:e[-+]?\d+)?")
#: ... and a list of them, masked as one ("factors #, #, …, #").
_NUMBERS = re.compile(r"#(?:(?:, | and |–|-)(?:…, )?#)+")


def said_warning(message: str, kind: str, defects: int = 0, gap: tuple[str, str] | None = None,
                 factors=(), excess: float = 0.0) -> ShapeDifferenceWarning:
    """The :class:`~core.errors.ShapeDifferenceWarning` "Shape-difference interpolation: ``message``."
    (``message`` without its final full stop) with its attributes: ``kind`` (one of :data:`~core.errors.KINDS`),
    ``defects`` (the flipped or collapsed triangles the worst in-between it is about keeps), ``gap``
    (the names of the gap's two keys, as the message says them; None where it is about no one gap),
    ``factors`` (the factors of the in-betweens it is about; empty where it holds for the whole
    gap) and ``excess`` (the worst one's measure ÷ what the warning allows, where it has one; else 0)."""
    warning = shape_warning(f"Shape-difference interpolation: {message}.", kind)
    warning.defects = int(defects)
    warning.gap, warning.factors = (None if gap is None else (str(gap[0]), str(gap[1]))), tuple(float(f) for f in factors)
    warning.excess = float(excess)
    return warning


def warn_said(message: str, kind: str, defects: int = 0, gap: tuple[str, str] | None = None, factors=(),
              excess: float = 0.0) -> None:
    """Warn with :func:`said_warning` (same arguments), at the caller's line outside the core
    (:func:`core.errors.warn`)."""
    warn(said_warning(message, kind, defects, gap, factors, excess))


#: How an in-between's own problem is placed in its gap's message (after "between A and B, "): one
#: in-between, or several alike (:func:`gap_problems`), each as an in-between or a pose past the keys.
#: :func:`message_shape` says each place in one way, so that the same problem has one shape whatever
#: the count.
_PLACES = [(f", the {p} at factor #: ", f", # of the # {p}s alike, the {w} at factor #: ", f", {p}(s) at factor #: ")
           for p in ("in-between", "pose") for w in ("worst", "first")]
#: ... and where the factors of several alike are listed, at the message's end.
_ALIKE_TAIL = [f"; {p}s alike at factors " for p in ("in-between", "pose")]


def message_shape(message: str) -> str:
    """``message`` with its numbers masked, and the place of an in-between's problem said in one way
    whether one in-between or several alike have it (the list of their factors left out): messages
    of one shape say the same problem, and differ only in where (the keys, the factors) and how
    much (counts, indices, shares). The operators report such messages once
    (``operators.base.summarized``)."""
    shape = _NUMBER.sub("#", message)
    for one, several, either in _PLACES:  # before lists are masked: a key's number and a count are no list
        shape = shape.replace(one, either).replace(several, either)
    shape = _NUMBERS.sub("#", shape)
    for tail in _ALIKE_TAIL:
        cut = shape.rfind(tail)
        if cut >= 0:  # the list runs to the message's end, its full stop kept
            shape = shape[:cut] + ("." if shape.endswith(".") else "")
    return shape


def factor_list(factors) -> str:
    """``factors`` as a message lists them: all up to six, else the first three and how many there
    are from the least to the greatest ("0.3125, 0.375, 0.4375, … (8 factors from 0.3125 to
    0.875)"), which says no more than is so where they are not one run of the factors asked."""
    shown = [f"{f:g}" for f in factors]
    if len(shown) <= 6:
        return ", ".join(shown)
    return f"{', '.join(shown[:3])}, … ({len(shown)} factors from {min(factors):g} to {max(factors):g})"


def gap_problems(problems: list[tuple[float, str, str, int]], asked: int,
                 names: tuple[str, str]) -> list[tuple[str, str, int, tuple[float, ...]]]:
    """The warnings ``(kind, message, flipped or collapsed triangles the worst keeps, factors of the
    in-betweens it is about)`` of the
    in-betweens of one gap asked together: ``problems`` ``(factor, kind, what happened, flipped or
    collapsed triangles it keeps)`` of each in-between with one, ``asked`` how many in-betweens
    were asked, ``names`` the gap's keys. In-betweens whose problems differ in their numbers only
    (counts, triangle indices, shares) are said in one message, which gives how many there are and
    the one that keeps the most flipped or collapsed triangles (the first of them where none keeps
    any), what happened there next, and their factors at the end, where a report line cut to the
    status bar's width loses them first: "between frame 1 and frame 17, 7 of the 15 in-betweens
    alike, the worst at factor 0.5: …; in-betweens alike at factors …"."""
    groups: dict[tuple[str, str], list[tuple[float, str, int]]] = {}
    for factor, kind, what, kept in problems:
        groups.setdefault((kind, message_shape(what)), []).append((factor, what, kept))
    out = []
    between = f"between {names[0]} and {names[1]}"
    for (kind, _), members in groups.items():
        # past the keys (an exaggeration, a reversal) a pose is no in-between
        poses = "in-between" if all(0.0 < f < 1.0 for f, *_ in members) else "pose"
        if len(members) == 1:
            factor, what, kept = members[0]
            out.append((kind, f"{between}, the {poses} at factor {factor:g}: {what}", kept, (factor,)))
            continue
        worst = max(range(len(members)), key=lambda i: (members[i][2], -i))
        factor, what, kept = members[worst]
        out.append((kind, f"{between}, {len(members)} of the {asked} {poses}s alike, the {'worst' if kept else 'first'} "
                          f"at factor {factor:g}: {what}; {poses}s alike at factors "
                          f"{factor_list([f for f, *_ in members])}", kept, tuple(f for f, *_ in members)))
    return out


def carried_stop_warning(ratio: float, key_names: list[str], gap: int) -> list[tuple[str, float]]:
    """The warning ``(message, excess)`` of gap ``gap`` of a sequence whose in-betweens carry on the
    speed of a motion that stopped before it, as a list (empty where none): ``ratio``, how many times
    as far its spline strays from the keys' chord as one slowing to a stop
    (:meth:`core.sequence_gap_starts.GapStarts._carried_stop`), over
    :data:`~core.sequence_gap_starts.STOP_CARRY_RATIO` (``excess``: ``ratio`` ÷ that; 0 where ``ratio`` is
    infinite: the spline slowing to a stop is the chord itself, the keys after the stop creeping at
    constant speed)."""
    if not ratio > STOP_CARRY_RATIO:
        return []
    a, b = key_names[gap], key_names[gap + 1]
    # a motion slowing to a stop may keep to the chord exactly (keys after the stop creeping at constant
    # speed): no finite ratio to say
    how = f"{ratio:.1f} × as far from the keys' straight path as a motion slowing to a stop would" if np.isfinite(ratio) \
        else "from the keys' straight path, which a motion slowing to a stop keeps to"
    return [(f"between {a} and {b}, the in-betweens may overshoot: the cloth moved far faster before {a} than after "
             f"it (it stopped, landing on something?), and the in-betweens carry that speed on: they stray "
             f"{how}; use a smaller step, or, where you pick the keys yourself, add a key a few frames after the "
             f"stop, inside this gap [the spline's start tangent keeps "
             f"the motion before {a}; the after-impact start is not taken: the cloth keeps deforming after it]",
             ratio / STOP_CARRY_RATIO if np.isfinite(ratio) else 0.0)]
