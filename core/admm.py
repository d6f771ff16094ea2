"""ADMM for a least-squares problem with per-slot convex constraints:
``min ½‖F x − g‖² + ½ε‖x − x0‖²`` s.t. ``x[slots] ∈ C`` (slot copies ``z = x[slots]``).

The truncated edge-length program (eq. 10, :mod:`core.truncated_recovery`) is of this form, with
``C`` the per-triangle sets of :mod:`core.triangle_constraints` (an edge has one slot per triangle
it bounds). The x-update is an exact Woodbury solve (:mod:`core.low_rank`), the z-update a
projection; Anderson acceleration on the Douglas–Rachford variable, ρ rebalanced on the residuals.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import DIVISION_FLOOR
from .low_rank import SplitGram

# Measurements behind every constant: docs/design-decisions.md.
#: Stopping tolerance on the relative primal and fixed-point residuals, and iteration cap.
ADMM_TOLERANCE = 1e-5
ADMM_MAX_ITERATIONS = 3000
#: Convergence is checked every this many iterations.
ADMM_CHECK_EVERY = 5
#: Stop a stall: residual below ADMM_STALL_FACTOR × the tolerance and shrinking by less than
#: 1 − ADMM_STALL_RATE per ADMM_STALL_WINDOW iterations (or too slowly to reach the tolerance
#: within the cap); the slack is far below what decides accuracy.
ADMM_STALL_FACTOR = 30.0
ADMM_STALL_WINDOW = 250
ADMM_STALL_RATE = 0.9
#: At a tolerance of at least this, the x-updates' products with F run in float32 (their
#: rounding, ~1e-7 relative, is three orders below it; half the memory traffic, which dominates
#: an iteration: 0.16 → 0.10 s on the 5k limb's offset layer, p = 1,139, E = 44,541).
ADMM_SINGLE_PRECISION_TOLERANCE = 1e-4
#: Initial ρ in units of √(ε · mean diagonal of the data Gram); rebalanced every ADMM_ADAPT_EVERY
#: iterations (a p × p refactorization each), at most ADMM_MAX_ADAPTATIONS times.
ADMM_RHO_SCALE = 10.0
ADMM_ADAPT_EVERY = 100
ADMM_MAX_ADAPTATIONS = 2
#: Residual balancing (OSQP's rule): ρ changes only when primal/dual leaves this band, by
#: √(primal/dual) clipped to RHO_STEP_LIMIT.
RHO_BALANCE_BAND = (0.2, 5.0)
RHO_STEP_LIMIT = (0.1, 10.0)
#: Anderson acceleration: differences kept, residual growth (× best) beyond which an
#: extrapolation is not tried, and the rcond of its least-squares solve.
ANDERSON_MEMORY = 8
ANDERSON_SAFEGUARD = 10.0
ANDERSON_RCOND = 1e-10


@dataclass
class ADMMSolution:
    """``x`` the last x-iterate, after ``iterations``; ``converged`` False when stopped by the
    iteration cap or a stall."""

    x: np.ndarray
    iterations: int
    converged: bool


def admm(f, g, eps, x0, slots, counts, project, *, x_start=None, z_start=None, u_start=None,
          rho=None, tol=None, max_iter=None, memory=ANDERSON_MEMORY, split=None, rho_scale=None):
    """Scaled-form ADMM with slot copies ``z = x[slots]`` (``project`` maps a slot vector onto the
    constraint set), accelerated by safeguarded type-II Anderson acceleration on the
    Douglas–Rachford variable ``v = z − u`` (the x-update depends on the state only through it).
    ``rho``: the penalty to start with (a warm start's), else ``rho_scale`` (default
    :data:`ADMM_RHO_SCALE`) × √(ε · mean diagonal of the data Gram). Returns the solution and
    ``(z, u, rho)`` for warm starts."""
    n = x0.size
    tol = ADMM_TOLERANCE if tol is None else tol
    max_iter = ADMM_MAX_ITERATIONS if max_iter is None else max_iter
    b = f.T @ g + eps * x0
    if rho is None:
        rho = (ADMM_RHO_SCALE if rho_scale is None else rho_scale) * np.sqrt(eps * max(float(np.sum(f * f)) / n, eps))
    x = x0.copy() if x_start is None else x_start.copy()
    z = project(x[slots]) if z_start is None else z_start.copy()
    u = np.zeros(slots.size) if u_start is None else u_start.copy()
    split = SplitGram(f, counts) if split is None else split
    single = tol >= ADMM_SINGLE_PRECISION_TOLERANCE
    solver = split.woodbury(eps, rho, single=single)

    def step(v):
        x = solver.solve(b + rho * np.bincount(slots, v, minlength=n))
        xs = x[slots]
        # Douglas–Rachford form of the scaled ADMM step: z = Π(2 Sx − v), then v ← v + z − Sx.
        w = 2.0 * xs - v
        z = project(w)
        return v + z - xs, x, xs, z

    v = z - u
    hist_v, hist_r = [], []
    converged = False
    it = 0
    prev_res = np.inf
    checkpoint = np.inf
    adaptations = 0
    for it in range(1, max_iter + 1):
        z_prev = z
        tv, x, xs, z = step(v)
        r = tv - v
        res = np.linalg.norm(r)
        # Anderson (type II) on the fixed point v = T(v).
        hist_v.append(tv)
        hist_r.append(r)
        if len(hist_v) > memory + 1:
            hist_v.pop(0)
            hist_r.pop(0)
        v_next = tv
        if len(hist_r) >= 3 and res < ANDERSON_SAFEGUARD * prev_res:
            dr = np.diff(np.array(hist_r), axis=0)
            dv = np.diff(np.array(hist_v), axis=0)
            try:
                gamma = np.linalg.lstsq(dr.T, r, rcond=ANDERSON_RCOND)[0]
                cand = tv - dv.T @ gamma
                if np.all(np.isfinite(cand)):
                    v_next = cand
            except np.linalg.LinAlgError:
                pass
        prev_res = min(prev_res, res)
        if it % ADMM_CHECK_EVERY == 0:
            primal = np.linalg.norm(xs - z)
            scale = max(np.linalg.norm(xs), np.linalg.norm(z), DIVISION_FLOOR)
            if primal <= tol * scale and res <= tol * scale:
                converged = True
                break
            if it % ADMM_STALL_WINDOW == 0:
                # Stalled near the tolerance: stop (the caller warns that it was not reached).
                current = max(primal, res) / scale
                if current <= ADMM_STALL_FACTOR * tol:
                    # At this window's rate, would the tolerance be reached within the cap?
                    rate = current / checkpoint
                    windows_left = (max_iter - it) / ADMM_STALL_WINDOW
                    if rate > ADMM_STALL_RATE or rate ** windows_left > tol / current:
                        break
                checkpoint = current
        if it % ADMM_ADAPT_EVERY == 0 and adaptations < ADMM_MAX_ADAPTATIONS:
            # Residual balancing (OSQP's rule on relative residuals): ρ ← ρ √(r_primal / r_dual),
            # the scaled dual u rescaled with it, Anderson's history restarted.
            u_now = z - v_next
            primal = np.linalg.norm(xs - z) / max(np.linalg.norm(xs), np.linalg.norm(z), DIVISION_FLOOR)
            dual = np.linalg.norm(z - z_prev) / max(np.linalg.norm(u_now), DIVISION_FLOOR)
            ratio = primal / max(dual, DIVISION_FLOOR)
            if not RHO_BALANCE_BAND[0] <= ratio <= RHO_BALANCE_BAND[1]:
                factor = float(np.clip(np.sqrt(ratio), *RHO_STEP_LIMIT))
                u_now /= factor
                rho *= factor
                solver = split.woodbury(eps, rho, single=single)
                v_next = z - u_now
                hist_v, hist_r, prev_res = [], [], np.inf
                adaptations += 1
        v = v_next
    u = z - v
    return ADMMSolution(x, it, converged), (z, u, rho)

