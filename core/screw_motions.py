"""Rigid motions of a mesh and of its pieces as screws, the coordinates in which they are
interpolated (a screw motion reproduces any rigid motion exactly, half turns included): the logarithm of
SE(3) — screw coordinates ``(ω, v)`` of ``x ↦ R x + t``, the short way round or continued from a
reference (:func:`rigid_logs`) — and its exponential (:func:`rigid_exps`), the keys' screws for a
spline across keys (:func:`key_screws`, :func:`continued_screws`), screws in a piece's own frame
(:func:`framed_screws`, :func:`world_screws`), and the paths of similarities, rigid motions with a
uniform scale (:func:`similarity_paths`). Which way round a turn goes: :mod:`core.rotation_continuity`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .geometry import coordinate_cross
from .deformation_fields import SERIES_THRESHOLD, rotation_vectors
from .rotation_continuity import ZERO_TURN_TOLERANCE, either_way, nearest_representatives, the_other_way
from .small_matrices import matmul, transpose

#: Relative cutoff of the singular values of ``V(ω)`` when solving for a screw's ``v``: far below
#: the smallest a turn short of a whole one has (θ = 2π − 1e-5: ~1e-6), far above round-off.
SCREW_CUTOFF = 1e-12
#: A piece's rotation fitted to keys that are not exactly rigid is known to about its RMS misfit
#: over its size (radians); this many times that is its ``spread`` (:func:`rigid_logs`), within
#: which of a half turn it may turn either way too and of none it is none: float32 keys as Blender
#: keeps them read a 0.2-wide piece 100 units out ~1e-5 rad "short of a half turn the other way"
#: (turned against the rest of its mesh) and a card keyed two half turns on ~1e-6 rad about an
#: axis of rounding (continued a whole turn about it, off its circle); 300 cards of 4 vertices 10
#: units out: their angles' errors up to 30 × their misfit over size ...
TURN_NOISE = 100.0
#: ... but never more than this (radians): a piece deforming more turns the short way.
TURN_SPREAD = 1e-2


def _screw_coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a = (1 − cos θ)/θ²`` and ``b = (θ − sin θ)/θ³`` for rotation angles ``theta`` (…), by
    their series below :data:`~core.deformation_fields.SERIES_THRESHOLD`."""
    direct = theta > SERIES_THRESHOLD
    safe = np.where(direct, theta, 1.0)
    a = np.where(direct, (1.0 - np.cos(safe)) / safe ** 2, 0.5 - theta ** 2 / 24.0)
    b = np.where(direct, (safe - np.sin(safe)) / safe ** 3, 1.0 / 6.0 - theta ** 2 / 120.0)
    return a, b


def rigid_log(rotation: np.ndarray, translation: np.ndarray, reference: np.ndarray | None = None,
              unwrap: bool = False) -> np.ndarray:
    """Screw coordinates ``(ω, v)`` (6,) of the rigid motion ``x ↦ R x + t``: one row of
    :func:`rigid_logs`."""
    references = None if reference is None else np.asarray(reference, dtype=np.float64)[None]
    return rigid_logs(rotation[None], np.asarray(translation)[None], references, unwrap)[0]


def rigid_logs(rotations: np.ndarray, translations: np.ndarray, references: np.ndarray | None = None,
               unwrap: bool = False, spread: np.ndarray | float = 0.0) -> np.ndarray:
    """Screw coordinates ``(ω, v)`` (P, 6) of the rigid motions ``x ↦ R x + t`` (rotations
    (P, 3, 3), translations (P, 3)), the short way round. With ``references`` (rotation vectors
    (P, 3), or screw coordinates (P, 6) whose first three are one): a half turn (within
    :data:`~core.rotation_continuity.HALF_TURN_TOLERANCE` of π, or the row's ``spread`` (radians, per row or one for all: what
    its rotation is known to), both directions are as short) turns the way nearer to its
    row, and with ``unwrap`` the representative ``ω + 2πk ω̂`` nearest to it is taken (a motion
    continuing across keys; k = −1 is the same rotation the other way round, ``−ω`` would be its
    inverse). A rotation within :data:`~core.rotation_continuity.ZERO_TURN_TOLERANCE` of none continued a whole turn about
    its reference's axis (or within its ``spread``) takes the part of ``v`` that no translation fixes there (``V(2πû)`` maps
    it to zero) from a reference screw: the continuation of a turn about a fixed axis stays about
    that axis. ``v`` is the least-squares (minimum-norm) solution of ``V(ω) v = t``."""
    w = rotation_vectors(rotations)
    translations = np.asarray(translations, dtype=np.float64)
    whole_turn = np.zeros(len(w), dtype=bool)
    if references is not None:
        references = np.asarray(references, dtype=np.float64)
        turn = references[:, :3]
        theta = np.linalg.norm(w, axis=1)
        if unwrap:  # every row (a half turn with a null reference goes the first way, k = −1)
            # within its spread of none only where the reference is nearer a whole turn than none
            # (|reference| ≥ π; a small real turn continuing a small reference stays what it is)
            still = (theta <= ZERO_TURN_TOLERANCE) | (
                (theta <= spread) & (np.einsum("ij,ij->i", turn, turn) >= np.pi ** 2))
            w = nearest_representatives(w, theta, turn, np.flatnonzero(still), np.flatnonzero(~still))
            whole_turn = still & w.any(axis=1)
        else:
            half = either_way(theta, spread) & (np.einsum("ij,ij->i", w, turn) < 0)
            # the same rotation the long way round, ω − 2π ω̂ (−ω, its inverse, differs from it by
            # 2(π − θ): within a spread of 1e-2 a piece jumped at every key, 4.8e-2 of its diagonal)
            w = np.where(half[:, None], the_other_way(w, theta), w)
    a, b = _screw_coefficients(np.sqrt(np.einsum("ij,ij->i", w, w)))
    h = _hats(w)  # V(ω) = I + a [ω] + b [ω]²: the translation part of SE(3)'s exponential
    matrices = np.eye(3) + a[:, None, None] * h + b[:, None, None] * (h @ h)
    # the part a whole turn's V(2πû) cannot give comes from the reference's v (the least change)
    held = whole_turn & (references is not None and references.shape[1] == 6)
    base = np.where(held[:, None], references[:, 3:], 0.0) if held.any() else np.zeros_like(translations)
    rhs = translations - np.einsum("pab,pb->pa", matrices, base)
    return np.concatenate([w, base + least_squares_3x3(matrices, rhs)], axis=1)


def _hats(w: np.ndarray) -> np.ndarray:
    """The cross-product matrices [ω] (P, 3, 3) of the rows of ``w`` (P, 3)."""
    h = np.zeros((len(w), 3, 3))
    h[:, 0, 1], h[:, 0, 2], h[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    h[:, 1, 0], h[:, 2, 0], h[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    return h


def least_squares_3x3(matrices: np.ndarray, rhs: np.ndarray, cutoff: np.ndarray | float = SCREW_CUTOFF) -> np.ndarray:
    """The minimum-norm least-squares solutions (P, 3) of ``matrices`` (P, 3, 3) ``x = rhs``
    (P, 3), singular values below ``cutoff`` (per row or one) times the largest dropped, by one batched
    SVD. ``V(2πkû) = ûûᵀ`` has rank one: its two zero singular values come out at round-off
    (2e-16–3e-16 for k = 3), within a factor of three of NumPy's ``lstsq`` cutoff (3 ε)."""
    u, sigma, vt = np.linalg.svd(matrices)
    cutoff = np.reshape(cutoff, (-1, 1)) * sigma[:, :1]
    inverse = np.where(sigma > cutoff, 1.0 / np.where(sigma > 0, sigma, 1.0), 0.0)
    return np.einsum("pji,pj->pi", vt, inverse * np.einsum("pji,pj->pi", u, rhs))


def screw_left_jacobians(screws: np.ndarray) -> np.ndarray:
    """The left Jacobians (P, 6, 6) of SE(3)'s exponential at screw coordinates ``(ω, v)``
    (P, 6): ``(d exp(S)) exp(S)⁻¹ = (J dS)^``, the series ``Σ adₛⁿ / (n + 1)!``, read off the
    exponential of a 12 × 12 block matrix (SciPy's ``expm``)."""
    block = np.zeros((len(screws), 12, 12))
    w = _hats(screws[:, :3])
    block[:, :3, :3] = block[:, 3:6, 3:6] = w
    block[:, 3:6, :3] = _hats(screws[:, 3:])
    block[:, :6, 6:] = np.eye(6)
    from scipy.linalg import expm  # lazily: scipy.linalg is not loaded by the rest of this module

    return expm(block)[:, :6, 6:]


def continued_screws(screws: np.ndarray, motions: tuple, farther: tuple, spread: np.ndarray | float = 0.0) -> np.ndarray:
    """Screw coordinates (P, 6) to stand in a Catmull–Rom spline of screws for keys two steps on,
    whose next keys are ``screws`` (P, 6) (the rigid motions ``motions``: rotations (P, 3, 3),
    translations (P, 3)) and which are the rigid motions ``farther``: ``J(S)⁻¹ (S + T)``, ``T``
    the step from the next key on (the short way round; a half turn, to within ``spread`` as
    :func:`rigid_logs` takes it, the way ``S`` turns). Half of
    it, the spline's tangent at the next key, is there the velocity ``(S + T)/2`` that the next gap
    starts with, so the two meet with one velocity; and a piece that turns by nearly a whole turn
    over the two steps is never taken as one screw, whose ``V(ω)`` is nearly singular there (a ball
    rolling 178° per key came out 4.5 radii off its path)."""
    rotations, translations = motions
    step_rotations = matmul(farther[0], transpose(rotations))
    step_translations = farther[1] - np.einsum("pab,pb->pa", step_rotations, translations)
    steps = rigid_logs(step_rotations, step_translations, screws, spread=spread)
    return np.linalg.solve(screw_left_jacobians(screws), (screws + steps)[..., None])[..., 0]


def key_screws(motions: list, farther_is_key: bool) -> list[np.ndarray]:
    """Screw coordinates (P, 6) of P bodies' rigid motions ``motions`` (per key: rotations
    (P, 3, 3), translations (P, 3)) from a gap's base key to the keys at times −1, 0, 1, 2, for a
    spline of screws: the next key's the short way round, the key before's turn continued from it
    (the representative nearest its reverse), the key after as :func:`continued_screws` takes it
    where ``farther_is_key``, else (a sequence's end condition) its turn continued to twice the
    next key's."""
    def logs(k, reference=None):
        return rigid_logs(*motions[k], reference, reference is not None)

    nxt = logs(2)
    after = continued_screws(nxt, motions[2], motions[3]) if farther_is_key else logs(3, 2.0 * nxt)
    return [logs(0, -nxt), logs(1), nxt, after]


def framed_screws(screws: np.ndarray, axes: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """Screw coordinates ``(ω, v)`` (P, 6) of motions ``x ↦ R x + t`` in world coordinates → the
    same motions' in each row's frame ``y = A (x − o)`` (``axes`` A: rows of rotations (P, 3, 3),
    ``origins`` o (P, 3)): the adjoint ``(A ω, A (v − o × ω))``, exact for every representative of
    a turn (linear, as the exponential is equivariant)."""
    w, v = screws[:, :3], screws[:, 3:]
    # o × ω by coordinate, as in rigid_exps: NumPy's np.cross spends ~20 µs handling axes per call,
    # most of a call on a few pieces' rows (the same products and differences)
    return np.concatenate([np.einsum("pab,pb->pa", axes, w),
                           np.einsum("pab,pb->pa", axes, v - coordinate_cross(origins.T, w.T).T)], axis=1)


def world_screws(framed: np.ndarray, axes: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """The inverse of :func:`framed_screws`: ``(Aᵀ ω', Aᵀ v' + o × Aᵀ ω')``."""
    w = np.einsum("pba,pb->pa", axes, framed[:, :3])
    # o × w by coordinate, as in framed_screws
    return np.concatenate([w, np.einsum("pba,pb->pa", axes, framed[:, 3:]) + coordinate_cross(origins.T, w.T).T],
                          axis=1)


def rigid_exps(screws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (P, 3, 3) and translations (P, 3) of screw coordinates ``(ω, v)`` (P, 6), the
    inverse of :func:`rigid_log` row by row: the translation ``V(ω) v = v + a ω × v + b ω × (ω ×
    v)`` with the coefficients of :func:`_screw_coefficients`."""
    w, v = screws[:, :3], screws[:, 3:]
    a, b = _screw_coefficients(np.linalg.norm(w, axis=1))
    # the cross products by coordinate (NumPy's np.cross costs ~25 µs of axis handling per call,
    # most of a call on the few rows of a mesh's pieces; the same products and differences)
    turned = coordinate_cross(w.T, v.T)
    translations = v + (a * turned).T + (b * coordinate_cross(w.T, turned)).T
    return Rotation.from_rotvec(w).as_matrix().reshape(-1, 3, 3), translations


def similarity_paths(rotvec: np.ndarray, log_scales: np.ndarray, translations: np.ndarray, points: np.ndarray,
                     s: float) -> tuple[np.ndarray, np.ndarray]:
    """Where ``S^s``, the power ``s`` (``exp(s log S)``) of each similarity ``S: x ↦ e^λ R x + t``
    (rotation vectors ``rotvec`` ω (P, 3), so ``R = exp([ω])``; log-scales λ (P,); translations
    (P, 3)), takes ``points`` (P, 3), one point per similarity: ``(positions (P, 3), ok (P,))``.
    ``ok`` is False where the logarithm has no translation part to speak of (a whole turn with no
    scale: ``S`` is a translation along its axis only if ``t`` lies along it; the positions there
    are those of the chord ``x + s t``).

    The rotation and the uniform scale commute: along the axis ``û`` the map scales by ``e^{sλ}``,
    across it, taken as the complex plane (``i`` ≡ ``û ×``), it multiplies by ``e^{s(λ + iθ)}``. Its
    translation at ``s`` is ``∫₀ˢ e^{τ(λ I + [ω])} dτ`` times the logarithm's, i.e. ``t`` times
    ``expm1(sλ) / expm1(λ)`` along the axis and ``expm1(s z) / expm1(z)`` across it (``z = λ +
    iθ``; both ``s`` in the limit of a translation). For λ = 0 this is the screw motion
    (:func:`rigid_exps` of ``s`` times :func:`rigid_logs`); for a rigid motion with a uniform scale
    the spiral that takes a piece, and everything scaled and turned with it, along one motion."""
    rotvec = np.asarray(rotvec, dtype=np.float64)
    log_scales = np.asarray(log_scales, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    theta = np.sqrt(np.einsum("ij,ij->i", rotvec, rotvec))
    axis = np.where((theta > 0)[:, None], rotvec / np.where(theta > 0, theta, 1.0)[:, None], [0.0, 0.0, 1.0])
    z = log_scales + 1j * theta

    def ratio(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # expm1(s v) / expm1(v), s where v → 0
        whole = np.expm1(values)
        small = np.abs(values) < 1e-12
        ok = small | (np.abs(whole) > 1e-6 * np.abs(values))  # not a whole turn (expm1(2πki) = 0)
        safe = np.where(ok & ~small, whole, 1.0)
        return np.where(small, s, np.expm1(s * values) / safe), ok

    along, _ = ratio(log_scales.astype(complex))
    across, ok = ratio(z)
    along = along.real
    parallel = np.einsum("ij,ij->i", translations, axis)[:, None] * axis
    perpendicular = translations - parallel
    moved_translation = (along[:, None] * parallel + across.real[:, None] * perpendicular
                         + across.imag[:, None] * np.cross(axis, perpendicular))
    rotations = Rotation.from_rotvec(s * rotvec).as_matrix().reshape(-1, 3, 3)
    out = np.exp(s * log_scales)[:, None] * np.einsum("pab,pb->pa", rotations, points) + moved_translation
    chord = points + s * translations
    return np.where(ok[:, None], out, chord), ok
