"""Best rigid motion between two point sets in correspondence (Kabsch / Umeyama without scaling).

Shape differences determine a pose only up to rigid motion (paper §5.3, Prop. 4); reconstructions
are placed by the rotation and translation that bring them closest to a reference. Rotations are
proper (``det R = +1``): a mirror image is a different shape, never a valid placement.
"""

from __future__ import annotations

import numpy as np

from .errors import ShapeDifferenceError
from .geometry import nearest_rotations, scaled, shifted


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
    rotations, translations = rigid_alignments(s, x, np.zeros(s.shape[0], dtype=np.intp), 1, w / w.sum())
    return rotations[0], translations[0]


def rigid_alignments(source: np.ndarray, target: np.ndarray, labels: np.ndarray, n_groups: int,
                     weights: np.ndarray | None = None, singular_values: bool = False) -> tuple[np.ndarray, ...]:
    """:func:`rigid_alignment` of every group of rows at once: rotations (G, 3, 3) and translations
    (G, 3) taking the rows of ``source`` (n, 3) labelled ``g`` (``labels`` int (n,), 0 ≤ g <
    ``n_groups``) closest to those of ``target`` (n, 3), weighted by ``weights`` (n,) (checked by the
    caller; ``labels`` may be None for one group). Per-group sums by ``bincount``, one batched
    SVD: a mesh of 3,000 pieces in milliseconds (a loop over the pieces took 0.1 s per call). A
    group without weight gets the identity. With ``singular_values``, also the cross-covariances'
    singular values (G, 3), largest first (of the weights normalized per group)."""
    w = np.ones(source.shape[0]) if weights is None else weights
    if n_groups == 1 and w.sum() > 0:  # one group: matrix products (a call per piece costs a third of the sums below)
        w = w / w.sum()
        s_mean, x_mean = w @ source, w @ target
        x_centred = shifted(target, -x_mean)
        s_weighted = shifted(source, -s_mean)
        scaled(s_weighted, w, out=s_weighted)
        covariance = x_centred.T @ s_weighted  # Σ w x̃ s̃ᵀ
        rotation, sigma = nearest_rotations(covariance, singular_values=True)
        if _thin(sigma[None])[0]:
            rotation = _turned_about_long_axes(rotation[None], covariance[None], shifted(source, -s_mean)[None],
                                               x_centred[None], w[None])[0]
        out = rotation[None], (x_mean - rotation @ s_mean)[None]
        return out + (sigma[None],) if singular_values else out

    covariance, s_mean, x_mean, s_centred, x_centred = group_covariances(source, target, labels, n_groups, w)
    rotations, sigma = nearest_rotations(covariance, singular_values=True)
    thin = np.flatnonzero(_thin(sigma))
    if thin.size:
        order = np.argsort(labels, kind="stable")
        counts = np.bincount(labels, minlength=n_groups)
        ends = np.cumsum(counts)
        for size in np.unique(counts[thin]):  # groups of one size at once (debris of slivers: all)
            groups = thin[counts[thin] == size]
            rows = order[(ends[groups] - size)[:, None] + np.arange(size)]  # (k, size)
            rotations[groups] = _turned_about_long_axes(rotations[groups], covariance[groups], s_centred[rows],
                                                        x_centred[rows], w[rows])
    out = rotations, x_mean - np.einsum("gab,gb->ga", rotations, s_mean)
    if singular_values:  # of the sums normalized per group, as the one-group path's
        total = np.bincount(labels, w, minlength=n_groups)
        return out + (sigma / np.where(total > 0, total, 1.0)[:, None],)
    return out


#: Kabsch's rotation about a group's long axis is known to round-off over the share
#: ``(σ₂ + σ₃) / σ₁`` of its cross-covariance's singular values (squared lengths: a needle's
#: ``(H / ℓ)²``); where that is below this, Kabsch may lose over ε / THIN_SPREAD ≈ 1e-10 rad
#: there, and the turn about that axis is solved again on the positions
#: (:func:`_turned_about_long_axes`). A sliver triangle 1e-7 wide for 1 long, a piece of its own,
#: came out turned 1.7 rad the wrong way.
THIN_SPREAD = 1e-6
#: ... unless its spread across that axis is under this fraction of its size (RMS): collinear to
#: round-off (the mesh check's thinnest triangle, :data:`core.mesh_topology.DEGENERATE_TRIANGLE_RATIO`).
COLLINEAR_SPREAD = 1e-10


def _thin(sigma: np.ndarray) -> np.ndarray:
    """Per row of singular values (G, 3), whether Kabsch's rotation is ill-conditioned there (see
    :data:`THIN_SPREAD`; a group without spread keeps its identity)."""
    return (sigma[:, 1] + sigma[:, 2] < THIN_SPREAD * sigma[:, 0]) & (sigma[:, 0] > 0)


def _turned_about_long_axes(rotations: np.ndarray, covariances: np.ndarray, source: np.ndarray,
                            target: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``rotations`` (k, 3, 3), Kabsch's for thin groups, each turned about its group's long axis
    (the cross-covariance's ``covariances`` (k, 3, 3) first left singular vector: the target's
    principal direction, which Kabsch gets to round-off) by the turn that best takes the turned
    ``source`` onto ``target`` (centred rows (k, r, 3), ``weights`` (k, r)): ``atan2(Σ w u·(p⊥ ×
    x⊥), Σ w p⊥·x⊥)`` over the rows' parts across the axis, formed before their products (so the
    turn is known to ε ℓ / H, the positions' own precision, where Kabsch's sums of products lose
    ε (ℓ / H)²; the closed form also undoes Kabsch's half turns, where Gauss–Newton steps stall)."""
    from scipy.spatial.transform import Rotation

    axes = np.linalg.svd(covariances)[0][:, :, 0]  # (k, 3)
    p = np.einsum("kab,krb->kra", rotations, source)
    p_across = p - np.einsum("kra,ka->kr", p, axes)[:, :, None] * axes[:, None, :]
    x_across = target - np.einsum("kra,ka->kr", target, axes)[:, :, None] * axes[:, None, :]
    sine = np.einsum("kr,kr->k", weights, np.einsum("kra,ka->kr", np.cross(p_across, x_across), axes))
    cosine = np.einsum("kr,kr->k", weights, np.einsum("kra,kra->kr", p_across, x_across))
    # groups collinear to round-off (across the axis under COLLINEAR_SPREAD of along it) have no
    # turn about it to find: Kabsch's choice stays
    across = np.einsum("kr,kr->k", weights, np.einsum("kra,kra->kr", x_across, x_across))
    along = np.einsum("kr,kr->k", weights, np.einsum("kra,kra->kr", target, target))
    angle = np.where(across > COLLINEAR_SPREAD**2 * along, np.arctan2(sine, cosine), 0.0)
    return Rotation.from_rotvec(angle[:, None] * axes).as_matrix() @ rotations


def group_covariances(source: np.ndarray, target: np.ndarray, labels: np.ndarray, n_groups: int,
                      weights: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per group of rows (``labels`` int (n,), 0 ≤ g < ``n_groups``) of ``source`` and ``target``
    (n, 3), weighted by ``weights`` (n,): the cross-covariances ``Σ w x̃ s̃ᵀ`` (G, 3, 3) of the rows
    about their weighted means, those means (G, 3) each, and the rows about them ``s̃``, ``x̃`` (n, 3).
    A set with itself (``target is source``, :func:`principal_frames`): its mean and rows about it
    once, and each symmetric entry once (the product of two coordinates is the same either way)."""
    def sums(values):  # per-group sums of w · values (n,)
        return np.bincount(labels, weights * values, minlength=n_groups)

    itself = target is source
    total = sums(np.ones(source.shape[0]))
    total = np.where(total > 0, total, 1.0)
    s_mean = np.stack([sums(source[:, d]) for d in range(3)], axis=1) / total[:, None]
    x_mean = s_mean if itself else np.stack([sums(target[:, d]) for d in range(3)], axis=1) / total[:, None]
    # about each group's mean: no cancellation far from the origin
    s_centred = source - s_mean[labels]
    x_centred = s_centred if itself else target - x_mean[labels]
    covariance = np.empty((n_groups, 3, 3))
    for a in range(3):
        for b in range(3):
            if itself and b < a:
                covariance[:, a, b] = covariance[:, b, a]
            else:
                covariance[:, a, b] = sums(x_centred[:, a] * s_centred[:, b])
    return covariance, s_mean, x_mean, s_centred, x_centred


def principal_frames(points: np.ndarray, labels: np.ndarray, n_groups: int,
                     weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per group of rows (``labels`` int (n,), 0 ≤ g < ``n_groups``) of ``points`` (n, 3),
    weighted by ``weights`` (n,): its principal axes (G, 3, 3), the rows of a proper rotation (the
    eigenvectors of ``Σ w x̃ x̃ᵀ``, smallest spread first), and its weighted centroid (G, 3). The
    frame turns and moves with the group; where two spreads are equal (a square sheet) its axes
    in their plane are whichever the eigensolver returns."""
    covariance, mean = group_covariances(points, points, labels, n_groups, weights)[:2]
    axes = np.swapaxes(np.linalg.eigh(covariance)[1], 1, 2)
    axes[np.linalg.det(axes) < 0, 2] *= -1.0  # a rotation, not a reflection: screws keep their sense
    return axes, mean


def reflected_fits(source: np.ndarray, target: np.ndarray, labels: np.ndarray | None, n_groups: int,
                   weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The groups of rows (as :func:`group_covariances`; ``labels`` None for one group) whose best
    orthogonal map taking ``source`` onto ``target`` is a reflection (int (k,)), and for each the
    weighted sums of squared distances left by the best rotation and by that reflection (k,) each:
    ``Σ w (|s̃|² + |x̃|²) − 2 (σ₁ + σ₂ ∓ σ₃)`` for the cross-covariance's singular values (Kabsch:
    the reflection's ``U Vᵀ`` is improper, the rotation negates its last singular direction)."""
    if labels is None:  # one group: matrix products (a cloth's check per pair of keys)
        total = weights.sum()
        s, x = shifted(source, -(weights @ source) / total), shifted(target, -(weights @ target) / total)
        covariance = ((x.T * weights) @ s)[None]
    else:
        covariance, _, _, s, x = group_covariances(source, target, labels, n_groups, weights)
    u, sigma, vt = np.linalg.svd(covariance)
    groups = np.flatnonzero(np.linalg.det(u @ vt) < 0)
    if not groups.size:
        return groups, np.zeros(0), np.zeros(0)
    squares = weights * (np.einsum("ij,ij->i", s, s) + np.einsum("ij,ij->i", x, x))
    spread = np.array([squares.sum()]) if labels is None else np.bincount(labels, squares, minlength=n_groups)
    top = spread[groups] - 2.0 * (sigma[groups, 0] + sigma[groups, 1])
    return groups, np.maximum(top + 2.0 * sigma[groups, 2], 0.0), np.maximum(top - 2.0 * sigma[groups, 2], 0.0)


#: Pivots span a line, or a plane, where their spread across it (RMS distance from their line;
#: the second singular value read the same way) exceeds this fraction of the source's diagonal.
PIVOT_SPREAD = 1e-4


def pivoted_alignment(source: np.ndarray, target: np.ndarray, pivots: np.ndarray,
                      weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rigid motion (rotation (3, 3), translation (3,)) taking ``source`` (n, 3) closest to
    ``target`` (n, 3) (least squares weighted by ``weights`` (n,)) among those that keep the points
    ``pivots`` (p, 3) where they are: none where they span a plane, the best turn about their line,
    or about their point (:data:`PIVOT_SPREAD`). Pins of a cloth, a seam two pieces are joined along."""
    from scipy.spatial.transform import Rotation

    centre = pivots.mean(axis=0)
    _, spread, directions = np.linalg.svd(pivots - centre, full_matrices=False)
    spread = spread / np.sqrt(len(pivots))
    by_coordinate = np.ascontiguousarray(source.T)  # extents along contiguous rows: 20× faster than across (n, 3) rows
    size = PIVOT_SPREAD * np.linalg.norm(np.ptp(by_coordinate, axis=1))
    if spread.size > 1 and spread[1] > size:  # a plane: nothing turns
        return np.eye(3), np.zeros(3)
    x, y = shifted(source, -centre), shifted(target, -centre)
    if spread[0] > size:  # a line: the turn about it that best takes x to y
        axis = directions[0]
        rotation = Rotation.from_rotvec(turn_about_axis(axis, (x.T * weights) @ y) * axis).as_matrix()
    else:  # a point: the best turn about it
        rotation = nearest_rotations((y.T * weights) @ x)
    return rotation, centre - rotation @ centre


def turn_about_axis(axis: np.ndarray, covariance: np.ndarray) -> float:
    """The angle (radians) of the rotation ``Q`` about the unit ``axis`` (3,) maximizing
    ``tr(Q C)`` for ``covariance`` ``C`` (3, 3): for ``C = Σ w x yᵀ``, the turn about the axis
    that best takes the points ``x`` onto ``y`` (least squares weighted by ``w``). With the parts
    along the axis taken out, ``u × v · axis = det(axis, x, y)`` and ``u · v = x · y − (x ·
    axis)(y · axis)``: ``atan2(axis · (C₁₂ − C₂₁, C₂₀ − C₀₂, C₀₁ − C₁₀), tr C − axisᵀ C
    axis)``."""
    along = axis @ covariance @ axis
    sine = axis @ np.array([covariance[1, 2] - covariance[2, 1], covariance[2, 0] - covariance[0, 2],
                            covariance[0, 1] - covariance[1, 0]])
    return float(np.arctan2(sine, np.trace(covariance) - along))


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
    groups, group = np.unique(labels[active], return_inverse=True)
    rows = np.flatnonzero(active)
    ok = np.isfinite(target[rows]).all(axis=1)
    counted = np.bincount(group[ok], minlength=groups.size)
    rotations, translations = rigid_alignments(points[rows[ok]], target[rows[ok]], group[ok], groups.size,
                                               None if weights is None else weights[rows[ok]])
    moved = counted[group] >= 3
    g = group[moved]
    out[rows[moved]] = np.einsum("rab,rb->ra", rotations[g], points[rows[moved]]) + translations[g]
    return out
