"""The convex set of squared edge lengths of one triangle with a given least area (paper §7.2,
Props. 5–6), its Euclidean projection, and the check of a result against it.

For squared lengths ``x = (a, b, c)`` of one triangle, ``q = 2(ab + bc + ca) − a² − b² − c²``
is 16·area² (Heron's formula, = 4 det E₃); the set ``{x : q(x) ≥ 16µ², x on the positive side}``
is a rotated second-order cone, rotationally symmetric about (1, 1, 1)/√3.
"""

from __future__ import annotations

import numpy as np

from .geometry import DIVISION_FLOOR, heron

#: Relative tolerance on det E₃ ≥ 4µ² of the returned squared lengths.
CONSTRAINT_TOLERANCE = 1e-6
#: Projection: cap and relative step tolerance of the safeguarded Newton iteration per row.
PROJECTION_NEWTON_ITERATIONS = 60
PROJECTION_NEWTON_TOLERANCE = 1e-13
#: Averaged projections to one feasible edge vector: cap of rounds, and the uniform scaling
#: (γ² ≤ 1 + slack) that may finish them.
FEASIBILITY_ROUNDS = 500
FEASIBILITY_SCALING_SLACK = 1e-3

_AXIS = np.full(3, 1.0 / np.sqrt(3.0))


def project_triangles(x: np.ndarray, areas: np.ndarray) -> np.ndarray:
    """Euclidean projection of each row of ``x`` ``(m, 3)`` onto the convex set of squared
    lengths of a triangle with area ≥ ``areas`` ``(m,)``: ``s ≥ √(16µ² + 2‖t‖²)`` where ``s`` is the
    coordinate along (1,1,1)/√3 and ``t`` the orthogonal part (Props. 5–6; for µ = 0 the
    triangle-inequality cone). Vectorized bisection on the KKT condition (unique root)."""
    s0 = x @ _AXIS
    t0 = x - s0[:, None] * _AXIS
    r0 = np.linalg.norm(t0, axis=1)
    c = 16.0 * areas * areas
    bad = s0 < np.sqrt(c + 2.0 * r0 * r0)
    if not bad.any():
        return x.copy()
    s0b, r0b, cb = s0[bad], r0[bad], c[bad]
    # Boundary point (ρ, s): s² = c + 2ρ², ρ = ρ0 s / (3s − 2s0); χ(s) increasing on [lo, hi].
    lo = np.maximum(np.sqrt(cb), s0b)
    hi = np.maximum(np.sqrt(cb + 2.0 * r0b * r0b), lo)
    lo = np.maximum(lo, DIVISION_FLOOR)
    # Safeguarded Newton on ψ(s) = (s² − c)(3s − 2s0)² − 2ρ0² s² (same sign as χ on the bracket).
    # Start from the projection onto the tangent plane of the boundary (one Gauss–Newton step on
    # s² − 2ρ² = c from (ρ0, s0)), clipped to the bracket: near-boundary points — all of them
    # once ADMM settles — then need 2–3 Newton steps instead of ~10 from the bracket's end.
    phi0 = s0b * s0b - 2.0 * r0b * r0b - cb
    grad2 = 16.0 * r0b * r0b + 4.0 * s0b * s0b
    with np.errstate(divide="ignore", invalid="ignore"):
        start = s0b - 2.0 * s0b * phi0 / grad2
    s = np.where(np.isfinite(start), np.clip(start, lo, hi), hi)
    todo = np.arange(s.size)  # rows whose Newton iteration has not settled yet
    for _ in range(PROJECTION_NEWTON_ITERATIONS):
        sb, s0t, ct, rt, lot, hit = s[todo], s0b[todo], cb[todo], r0b[todo], lo[todo], hi[todo]
        a = 3.0 * sb - 2.0 * s0t
        psi = (sb * sb - ct) * a * a - 2.0 * rt * rt * sb * sb
        up = psi > 0
        hit = np.where(up, sb, hit)
        lot = np.where(up, lot, sb)
        dpsi = 2.0 * sb * a * a + 6.0 * (sb * sb - ct) * a - 4.0 * rt * rt * sb
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = sb - psi / dpsi
        # Inclusive: a converged Newton step lands on the end the bracket just moved to.
        inside = np.isfinite(newton) & (newton >= lot) & (newton <= hit)
        s_new = np.where(inside, newton, 0.5 * (lot + hit))
        s[todo], lo[todo], hi[todo] = s_new, lot, hit
        moving = np.abs(s_new - sb) > PROJECTION_NEWTON_TOLERANCE * np.maximum(np.abs(sb), DIVISION_FLOOR)
        todo = todo[moving]
        if todo.size == 0:
            break
    hi = np.maximum(s, lo)
    s = hi  # on the feasible side
    rho = np.sqrt(np.maximum(s * s - cb, 0.0) / 2.0)
    rho = np.minimum(rho, r0b)
    out = x.copy()
    scale = np.divide(rho, r0b, out=np.zeros_like(rho), where=r0b > 0)
    out[bad] = s[:, None] * _AXIS + scale[:, None] * t0[bad]
    return out



def satisfied(xt: np.ndarray, areas: np.ndarray) -> np.ndarray:
    """Per triangle ``(m,)``: do the squared lengths ``xt`` ``(m, 3)`` bound a triangle of area at
    least ``areas`` ``(m,)`` (up to :data:`CONSTRAINT_TOLERANCE`), all lengths positive?"""
    q = heron(xt)
    s = xt.sum(axis=1) / np.sqrt(3.0)
    return (s > 0) & (q >= 16.0 * areas * areas * (1.0 - CONSTRAINT_TOLERANCE)) & (q > 0) & (xt > 0).all(axis=1)


def feasible_lengths(z: np.ndarray, slots: np.ndarray, counts: np.ndarray, areas: np.ndarray):
    """Edge values ``(E,)`` satisfying every triangle constraint from slot copies ``z``
    ``(3m,)`` (``slots`` the edge of each, ``counts`` the slots per edge): ``(x, True)``, or the
    last iterate and ``False`` when the rounds run out.

    Start from the average of the slot copies; while some triangle is invalid, project the slot
    copies of the violated triangles (with a tiny safety margin on the area) and average again
    (averaged projections, convergent to a point of the intersection); finally scale all squared
    lengths by the smallest γ ≥ 1 with q(γx_T) = γ² q(x_T) ≥ 16µ² everywhere (γ − 1 is of the
    order of the residual of the solver that produced ``z``)."""
    n = counts.size
    x = np.bincount(slots, z, minlength=n) / counts
    margin = areas * (1.0 + CONSTRAINT_TOLERANCE)
    for _ in range(FEASIBILITY_ROUNDS):
        xt = x[slots].reshape(-1, 3)
        q = heron(xt)
        valid = (q > 0) & (xt > 0).all(axis=1)
        gamma2 = np.max(np.divide(16.0 * margin * margin, q, out=np.full_like(q, np.inf), where=valid))
        if valid.all() and gamma2 <= 1.0 + FEASIBILITY_SCALING_SLACK:
            return x * np.sqrt(max(gamma2, 1.0)), True
        bad = ~valid | (16.0 * margin * margin > q * (1.0 + FEASIBILITY_SCALING_SLACK))
        fixed = np.where(np.repeat(bad, 3), project_triangles(xt, margin).ravel(), xt.ravel())
        x = np.bincount(slots, fixed, minlength=n) / counts
    return x, False
