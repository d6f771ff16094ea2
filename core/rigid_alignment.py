"""Best rigid motion between two point sets in correspondence (Kabsch / Umeyama without scaling).

Shape differences determine a pose only up to rigid motion (paper §5.3, Prop. 4); reconstructions
are placed by the rotation and translation that bring them closest to a reference. Rotations are
proper (``det R = +1``): a mirror image is a different shape, never a valid placement.
"""

from __future__ import annotations

import numpy as np

from .errors import ShapeDifferenceError
from .geometry import nearest_rotations


def rigid_alignment(source, target, weights=None) -> tuple[np.ndarray, np.ndarray]:
    """Rotation ``R`` float64 ``(3, 3)`` (``det R = +1``) and translation ``t`` ``(3,)`` minimizing
    ``Σ_i w_i |R s_i + t − x_i|²`` for ``source`` ``s`` and ``target`` ``x``, both ``(n, 3)``.

    ``weights`` ``(n,)`` non-negative (``None``: all ones). Kabsch/Umeyama: the SVD of the weighted
    cross-covariance, with the sign of the last singular vector flipped if needed to exclude
    reflections. Degenerate inputs (all points collinear, a single point) return one of the
    equally good solutions. Raises :class:`ShapeDifferenceError` on mismatched shapes, non-finite
    values or weights that are negative or sum to zero.
    """
    s = np.asarray(source, dtype=np.float64)
    x = np.asarray(target, dtype=np.float64)
    if s.ndim != 2 or s.shape[1] != 3 or s.shape != x.shape:
        raise ShapeDifferenceError(
            f"rigid_alignment needs two point sets of the same shape (n, 3); got {s.shape} and {x.shape}."
        )
    if s.shape[0] == 0:
        return np.eye(3), np.zeros(3)
    w = np.ones(s.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape[0] != s.shape[0]:
        raise ShapeDifferenceError(f"rigid_alignment: {w.shape[0]} weights for {s.shape[0]} points.")
    if not (np.isfinite(s).all() and np.isfinite(x).all() and np.isfinite(w).all()):
        raise ShapeDifferenceError("rigid_alignment: the points or weights contain NaN or infinity.")
    if (w < 0).any() or not w.sum() > 0:
        raise ShapeDifferenceError("rigid_alignment: weights must be non-negative with a positive sum.")
    w = w / w.sum()
    s_mean = w @ s
    x_mean = w @ x
    covariance = (x - x_mean).T @ ((s - s_mean) * w[:, None])  # (3, 3): Σ w x̃ s̃ᵀ
    rotation = nearest_rotations(covariance)
    translation = x_mean - rotation @ s_mean
    return rotation, translation


def align_rigidly(source, target, weights=None) -> np.ndarray:
    """``source`` ``(n, 3)`` moved by :func:`rigid_alignment` onto ``target`` ``(n, 3)``."""
    rotation, translation = rigid_alignment(source, target, weights)
    return np.asarray(source, dtype=np.float64) @ rotation.T + translation


def align_components(points, target, labels, *, weights=None, active=None) -> np.ndarray:
    """``points`` ``(n, 3)`` with each connected component (rows of equal ``labels`` ``(n,)``)
    moved by its own :func:`rigid_alignment` onto ``target`` ``(n, 3)``. Only rows where
    ``active`` (bool ``(n,)``, default all) move; within a component, rows whose target is not
    finite do not count, and a component with fewer than 3 counted rows stays where it is.
    ``weights`` ``(n,)`` as in :func:`rigid_alignment`."""
    out = points.copy()
    active = np.ones(points.shape[0], dtype=bool) if active is None else active
    for label in np.unique(labels[active]):
        rows = (labels == label) & active
        ok = rows & np.isfinite(target).all(axis=1)
        if ok.sum() >= 3:
            rotation, translation = rigid_alignment(points[ok], target[ok], None if weights is None else weights[ok])
            out[rows] = points[rows] @ rotation.T + translation
    return out
