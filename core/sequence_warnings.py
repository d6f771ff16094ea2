"""The warning every in-between gives (:class:`~core.errors.ShapeDifferenceWarning`, "Shape-difference
interpolation: …"), shared by :mod:`core.sequence_inbetweens` and :mod:`core.two_pose_inbetweens`
(paper §8.4)."""

from __future__ import annotations

import warnings

from .errors import ShapeDifferenceWarning


def _warn(message: str) -> None:
    warnings.warn(f"Shape-difference interpolation: {message}.", ShapeDifferenceWarning, stacklevel=3)
