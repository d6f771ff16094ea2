"""Exceptions and warnings raised by the shape-difference core.

Every error says what is wrong, the first offending index where there is one, and how to fix it,
so that the Blender operators can show the message to the user unchanged.
"""

from __future__ import annotations

import contextlib
import os
import sys
import warnings

#: The core package's folder (with a trailing separator): frames of files under it are the library's.
_CORE = os.path.dirname(os.path.abspath(__file__)) + os.sep


class ShapeDifferenceError(Exception):
    """Base class of every error raised by :mod:`core`."""


class MeshError(ShapeDifferenceError, ValueError):
    """The input mesh (or a pose of it) cannot be used: bad indices, degenerate or non-manifold
    geometry, inconsistent orientation, mismatched vertex counts, non-finite coordinates."""


class RecoveryError(ShapeDifferenceError, ArithmeticError):
    """Areas, edge lengths or an embedding cannot be recovered from the given shape differences
    (a singular system such as the paper's Fig. 2, a failed solver, an infeasible program)."""


class ShapeDifferenceWarning(UserWarning):
    """A result was computed, but through a documented fallback (e.g. an interpolated metric that
    is not exactly realizable); the message says which and why.

    ``kind``: what the warning is about, one of :data:`KINDS` (``"pose"``, ``"turn"``,
    ``"seam"``, ``"fit"``, …), for a pipeline to filter on (``w.message.kind`` of a recorded
    warning); every warning the core gives has one (:func:`warn`).
    ``defects``: how many flipped or collapsed triangles the in-between it is about keeps (of the
    in-betweens alike it speaks for, the worst); 0 where it keeps none or is about something else.
    ``gap``: the names of the two keys of the gap it is about, as the message says them (None where
    it is about no one gap); ``factors``: the factors of the in-betweens it is about (empty where
    it holds for every in-between of the gap, or is about something else).
    ``excess``: how far past what it allows the (worst) in-between or result it is about is, its measure ÷
    the allowance, over 1 (1 exactly for a ``sliver`` or joints within rounding at their threshold, which
    they warn at; the ``fit`` warning of a sequence's gap (or of two poses' in-between): its worst fit's misfit ÷ the misfit
    allowed; of a reconstruction: its worst edge's miss ÷ ``REALIZATION_TOLERANCE``; of the truncated area
    program: the residual reached ÷ the one asked for; a ``seam`` the in-betweens open: how much farther
    apart than in the keys ÷ the opening allowed; ``sliver``: the least height allowed ÷ the thinnest
    triangle's; ``joint``: links apart, their gap ÷ the contact reach; joints in a loop, the placement
    apart ÷ the one warned past; joints within rounding, their tolerance ÷ the one warned past; a
    ``turn`` that names a share of a piece: that share ÷ the share warned past; a ``turn`` of a spin read
    backwards between gaps turning it on: how many times as closely its turn taken the long way round
    continues theirs as the short way does (1 is the allowance); ``extrapolation``: the
    growth ÷ the growth allowed); 0 for the other warnings, which measure nothing against an allowance
    (docs/errors.md, *Warnings*)."""

    kind: str | None = None
    defects: int = 0
    gap: tuple[str, str] | None = None
    factors: tuple[float, ...] = ()
    excess: float = 0.0


class MeshIndexError(MeshError, IndexError):
    """An index argument (e.g. a sequence's ``gap_index``) is out of range or not a whole number.
    Both a :class:`MeshError` and an ``IndexError``."""


#: What each warning of the core is about (:attr:`ShapeDifferenceWarning.kind`): the one list,
#: documented in docs/errors.md.
KINDS = {
    # the in-betweens, retiming and exaggeration (core.sequence_warnings words them)
    "pose": "an in-between keeps flipped or collapsed triangles, or is a simpler fallback, or has triangles "
            "facing against the motion, or pinned vertices off their path",
    "non_finite": "a numerical failure: pieces of an in-between are the keys' linear blend",
    "turn": ("a part turns so far between the keys that they do not tell which way round it went, or that the "
             "in-betweens cut its arc"),
    "joint": "rigid pieces that move as jointed ones do, but are not placed as one",
    "sliver": "triangles so thin that the keys' coordinate rounding reshapes them",
    "mirror": "a piece is its own mirror image from one key to the next",
    "extrapolation": "an exaggerated or reversed pose stretches or crushes triangles",
    "overshoot": "a sequence's in-betweens carry on the speed of a motion that stopped before their gap",
    # any computation
    "seam": "pieces touching along seams that cannot be joined there, that open, fold or hinge there",
    "truncated": ("a truncated basis (k_M, k_N, k) is too small for the deformation (areas or edge lengths not "
                  "recovered) or ends inside a group of equal eigenvalues (the result depends on rounding)"),
    "fit": "a solver stopped before converging, or its result misses what it was fitted to: the best fit is returned",
    "precision": "a triangle or an offset so far out of scale that round-off moves the recovered edge lengths",
    "inconsistent": "differences no mesh has exactly (edited, blended or noisy): the closest fit is returned",
    "undetermined": "the differences leave part of the pose open (how it bends, a mirror image)",
    "same_poses": "the poses have the same shape differences: no spread",
    "correspondence": "a transfer's map lays the meshes on each other only in part, strays or turns parts inside out",
    "target": "a transfer's target mesh has triangles, edges or vertices it cannot carry, or too few vertices",
    "frame_times": "a point cache's frame times are not evenly spaced",
    "process": ("the in-betweens' second process stopped answering and was ended: its gaps were computed in "
                "the caller's process (the same in-betweens, more slowly)"),
}


def shape_warning(message: str, kind: str) -> ShapeDifferenceWarning:
    """A :class:`ShapeDifferenceWarning` saying ``message``, its :attr:`~ShapeDifferenceWarning.kind`
    ``kind`` (a key of :data:`KINDS`; another is a mistake of the code: ``ValueError``)."""
    warning = ShapeDifferenceWarning(message)
    warning.kind = kind
    _check_kind(warning)
    return warning


def warn(message: str | ShapeDifferenceWarning, kind: str | None = None) -> None:
    """Issue :func:`shape_warning` ``(message, kind)``, or the warning ``message`` made by it (its
    other attributes set), from the frame that called the core's outermost frame on the stack: the
    one place the core warns, so that every warning has a kind and points at the line of the code
    that called the core (a script's, an operator's), where ``warnings.filterwarnings(…, module=…)``
    and the printed location find it whatever the core's calls in between."""
    warning = shape_warning(message, kind) if isinstance(message, str) else message
    _check_kind(warning)
    warnings.warn(warning, stacklevel=_outside_core() + 1)


def _outside_core() -> int:
    """The ``stacklevel`` (1: the caller of :func:`warn`) of the frame that called the core's
    outermost frame on the stack. A ``contextlib`` wrapper that calls a frame of the core (an entry
    point decorated with :func:`core.concurrency.single_threaded_blas`) is the core's. In a pool
    thread the core's outermost frame is the pool's work: the in-betweens issue their warnings in
    the caller's thread."""
    frame, level, outermost = sys._getframe(2), 1, 0  # warn's caller
    while frame is not None:
        name = frame.f_code.co_filename
        if name.startswith(_CORE) or (name == contextlib.__file__ and outermost == level - 1):
            outermost = level
        frame, level = frame.f_back, level + 1
    return outermost + 1


def _check_kind(warning: ShapeDifferenceWarning) -> None:
    if warning.kind not in KINDS:
        raise ValueError(f"{warning.kind!r} is no kind of warning (core.errors.KINDS)")


def unexpected_failure(error: BaseException) -> str:
    """One line naming an error that is no refusal (not a :class:`ShapeDifferenceError`: a defect of
    the code), said by a headless run — ``python -m core``, an operator in ``blender -b`` — before
    Python's traceback, so that a farm's log names the cause on a line of its own, where the
    traceback ends with it after dozens of lines of frames:
    ``failed: ZeroDivisionError: division by zero (unexpected: the traceback follows; please report it)``."""
    text = " ".join(str(error).split())
    return (f"failed: {type(error).__name__}{': ' + text if text else ''} "
            "(unexpected: the traceback follows; please report it)")
