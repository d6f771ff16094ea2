"""The warnings the in-betweens give (:class:`~core.errors.ShapeDifferenceWarning`, "Shape-difference
interpolation: …"), shared by :mod:`core.sequence_inbetweens` and :mod:`core.two_pose_inbetweens`
(paper §8.4).

Each message says where (the keys of the gap, the factors, how many triangles or pieces), what
happened in the scene's terms and what to do, with the method's own words, where a developer needs
them, at its end in brackets. Each warning's :attr:`~core.errors.ShapeDifferenceWarning.kind` is
one of :data:`KINDS`, for a pipeline to filter on. The problems of the in-betweens asked together
(:meth:`core.SequenceInterpolator.poses`) are said once per gap and kind of problem, with how many
in-betweens have it (:func:`gap_problems`), not once per in-between.
"""

from __future__ import annotations

import re
import warnings

from .errors import ShapeDifferenceWarning

#: The kinds of the in-betweens' warnings (:attr:`ShapeDifferenceWarning.kind`), and what each is about.
KINDS = {
    "pose": "an in-between keeps flipped or collapsed triangles, or is a simpler fallback, or has triangles "
            "facing against the motion, or pinned vertices off their path",
    "non_finite": "a numerical failure: pieces of an in-between are the keys' linear blend",
    "turn": "a part turns so far between the keys that they do not tell which way round it went",
    "joint": "rigid pieces that move as jointed ones do, but are not placed as one",
    "sliver": "triangles so thin that the keys' coordinate rounding reshapes them",
    "mirror": "a piece is its own mirror image from one key to the next",
    "seam": "pieces touching along seams that cannot be joined there",
    "truncated": "the edge lengths of a truncated basis (k_M) could not be recovered",
    "extrapolation": "an exaggerated or reversed pose stretches or crushes triangles",
}

#: The numbers in a message (counts, indices, factors, frames, shares), masked by
#: :func:`message_shape` to tell messages that differ only in them.
#: A minus sign belongs to the number where no word, digit or point comes before it ("at factor -0.5",
#: not the range "samples 3-4").
_NUMBER = re.compile(r"(?<![\w.])-?\d+(?:[.,]\d+)*(?:e[-+]?\d+)?|\d+(?:[.,]\d+)*(?:e[-+]?\d+)?")
#: ... and a list of them, masked as one ("factors #, #, …, #").
_NUMBERS = re.compile(r"#(?:(?:, | and |–|-)(?:…, )?#)+")


def _warn(message: str, kind: str, defects: int = 0) -> None:
    """Warn with ``message`` (no final full stop), prefixed "Shape-difference interpolation: ",
    its :attr:`~core.errors.ShapeDifferenceWarning.kind` ``kind`` (one of :data:`KINDS`) and
    :attr:`~core.errors.ShapeDifferenceWarning.defects` ``defects`` (the flipped or collapsed
    triangles the worst in-between it is about keeps)."""
    warning = ShapeDifferenceWarning(f"Shape-difference interpolation: {message}.")
    warning.kind, warning.defects = kind, int(defects)
    warnings.warn(warning, stacklevel=3)


def message_shape(message: str) -> str:
    """``message`` with its numbers masked: messages of one shape say the same problem, and differ
    only in where (the keys, the factor) and how much (counts, indices, shares). The operators
    report such messages once (``operators.base.summarized``)."""
    return _NUMBERS.sub("#", _NUMBER.sub("#", message))


def _factors(factors: list[float]) -> str:
    """``factors`` as a message lists them: all up to six, else the first three and the last."""
    shown = [f"{f:g}" for f in factors]
    return ", ".join(shown) if len(shown) <= 6 else f"{', '.join(shown[:3])}, …, {shown[-1]}"


def gap_problems(problems: list[tuple[float, str, str, int]], asked: int,
                 names: tuple[str, str]) -> list[tuple[str, str, int]]:
    """The warnings ``(kind, message, flipped or collapsed triangles the worst keeps)`` of the
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
            out.append((kind, f"{between}, the {poses} at factor {factor:g}: {what}", kept))
            continue
        worst = max(range(len(members)), key=lambda i: (members[i][2], -i))
        factor, what, kept = members[worst]
        out.append((kind, f"{between}, {len(members)} of the {asked} {poses}s alike, the {'worst' if kept else 'first'} "
                          f"at factor {factor:g}: {what}; {poses}s alike at factors "
                          f"{_factors([f for f, *_ in members])}", kept))
    return out
