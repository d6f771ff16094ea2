"""Embedding from edge lengths (paper §7.3, constructive proof of Prop. 4).

Given the squared lengths of every edge of the canonical thickening (§5.3,
:attr:`OffsetSurface.thickening_edges`), :func:`embed_thickening` returns point positions that
realize them — exactly, up to rigid motion, when the lengths are exact; in the least-squares
sense otherwise. The base layer (the first ``n`` rows) is the reconstructed pose.

Method (chosen by measurement; the paper's ARAP local/global solve started from the thickening
of M stalls for large motions, e.g. a flat sheet to a draped cloth):

0. **Hinge frames** (:mod:`core.hinge_frames`, tried first): triangle frames glued across hinges,
   the hinge signs voted by the vertex stars. Exact to round-off in linear time (1e-11 of the
   diagonal on a 50k-vertex crumpled sheet in ~3 s). When its residual is not at round-off level
   (inexact lengths), the frames are synchronized (fitted to all hinges at once) and raced
   against the caller's reference pose (the base shape, from :class:`ReferenceShape`): a few
   Levenberg–Marquardt iterations each (side by side in threads on two cores), the better one is
   polished to the end. Noisy hinge signs can fold the frames; without a reference pose the
   greedy wavefront below is the second start.
1. **Greedy wavefront initializer** following the proof of Prop. 4: tetrahedra are glued one by
   one from their edge lengths, whole wavefronts at once with NumPy.

   - A point completing an *upward* tetrahedron ``(i, j, k, c_T)`` whose other three points are
     placed goes on the side that makes it positive (true on every valid pose: ``c_T`` is offset
     along the face normal).
   - A point with ≥ 4 placed, non-coplanar neighbours is trilaterated: linear least squares on
     differences of the squared-distance equations, then two Gauss–Newton steps on all sphere
     residuals. The Gauss–Newton steps matter: the linear solution alone amplified errors by
     4–11× per wave (round-off grew to O(1) within ~100 waves on a 33×33 sheet); with them the
     whole 33×33 sheet comes out at 5e-13.
   - The orientation of mesh-edge and downward tetrahedra is never assumed. When the front is
     stuck on points with exactly 3 usable placed neighbours (a hinge between two triangles),
     both mirror positions are tried and propagated up to :data:`LOOKAHEAD_WAVES` waves ahead;
     the one whose overdetermined trilaterations agree with the lengths wins (a lookahead instead
     of backtracking). Ties are deferred until more neighbours are placed. Points whose mirror
     position no length can decide (a lifted vertex over a two-triangle boundary fan) take the
     side that makes their tetrahedron positive; counted in ``unresolved_choices``.
   - Each component is seeded by the star of a central interior vertex (valence 5–8 preferred)
     whose ``2^(k−1)`` hinge orientations are enumerated and scored by fan closure and by the
     trilateration of the lifted vertex ``a_t`` from all ``k`` face centers; a star whose best
     pattern is not unique (a flat valence-4 star can fold along its straight lines) is skipped.

2. **Levenberg–Marquardt polish** (only if the RMS relative residual exceeds ``tolerance``) of
   the residuals ``(|x_i − x_j|² − ℓ²_e) / (2ℓ²_e)`` (≈ the relative length error: every edge
   counts the same whatever its size), with a sparse Jacobian. Steps solve the damped normal
   equations by block-Jacobi preconditioned CG (inexact Newton): SuperLU took 0.4–3 s per
   factorization already on 1k-vertex thickenings. The 6-dimensional rigid gauge is handled by
   the Levenberg damping: rigid motions leave the residuals unchanged, so the gradient is
   orthogonal to them and the damped step has no gauge component.

With exact lengths the hinge frames alone are exact to round-off (~1e-12 relative) and the polish
is skipped (the greedy wavefront, by contrast, amplifies round-off along its ~√n waves: 1e-3 RMS on a
224×224 sheet); with inexact lengths (truncated or interpolated differences) the polish gives a
least-squares fit and :attr:`EmbeddingResult.residual` reports how far from realizable the lengths
were. No ARAP stage: the greedy start is already in the basin of the fit in the tests.
"""

from __future__ import annotations

import itertools
import os
import warnings
from dataclasses import dataclass

import numpy as np

from .errors import RecoveryError, ShapeDifferenceWarning
from .mesh_topology import MeshTopology
from .offset_surface import OffsetSurface
from .small_matrices import cofactors_3x3

#: Trilateration needs the neighbours' scatter to have smallest/largest eigenvalue above this.
COPLANAR_RATIO = 1e-3
#: A lookahead branch whose worst relative check residual is below this counts as consistent.
CONSISTENT_RESIDUAL = 5e-2
#: Waves propagated ahead when choosing between two mirror positions.
LOOKAHEAD_WAVES = 12
#: A lookahead stops early after this many overdetermined checks.
LOOKAHEAD_CHECKS = 6
#: Three placed neighbours locate a point only if their doubled triangle area is at least this
#: times their squared extent (nearly collinear neighbours amplify errors without bound).
WELL_SHAPED = 2e-2
#: Waves re-solved after each new wave (front relaxation against error growth).
RELAX_WAVES = 2
#: Local repair: rings of neighbours added around badly fitting edges, and the largest share of
#: the points it may free before a global polish is used instead.
LOCAL_REPAIR_RINGS = 3
LOCAL_REPAIR_FRACTION = 0.3
#: Hinge-frame starts with an RMS relative residual below this go straight to the polish.
FRAMES_NEARLY_EXACT = 1e-6
#: Largest star valence enumerated exhaustively for a seed (2^(k-1) orientation patterns).
MAX_SEED_VALENCE = 12
#: With inexact lengths several starts are polished for this many Levenberg–Marquardt iterations
#: and only the best goes on to the end; the greedy wavefront last, and only if its trial already
#: beats the others' final fit. Measured (RMS residual / Hausdorff of the base layer, truncated
#: differences k = 100 / 200): the hinge frames fold where the hinge signs are noisy — drape
#: frames 8 → 16 of a Blender cloth simulation 0.046 / 24.9 % against 0.022 / 7.5 % from the base
#: pose, a flag in wind 0.111 / 29 % against 0.065 / 10.4 % — and tie on smooth poses (synthetic
#: cloth 0.0057 both); on a 15 × 15 drape with 1e-3 noise only the wavefront avoids a fold
#: (0.023 → 2.4e-4). A full second polish cost 1–2 s on the 1,089-vertex cloth.
START_TRIAL_ITERATIONS = 3
#: When the best start still leaves an RMS relative length residual above this, the reference
#: pose is also deformed gradually into the target lengths and the lowest residual wins. Each
#: schedule of CONTINUATION_SCHEDULES is (fractions of the way, LM iterations per fraction), then a
#: fit to the end. Measured on 16 Blender cloth pairs (truncated k = 100 / 200): residuals
#: 0.0014–0.0102 where the result was within 2 % of the target, 0.022–0.058 on crumpling cloth.
#: On the 9 crumpling pairs the Hausdorff/diagonal errors summed to 125.8 % without continuation,
#: 117.4 % with the 4-step schedule alone, 115.5 % with the 8-step one alone and 113.2 % with both
#: raced (e.g. flag 40 → 48: 16.1 → 8.4 %, falling sheet rest → 95: 31.9 → 15.3 %; worst loss flag
#: rest → 48: 15.5 → 17.5 % at a lower residual).
CONTINUATION_RESIDUAL = 2e-2
CONTINUATION_SCHEDULES = (((0.25, 0.5, 0.75), 4), (tuple(np.arange(1, 8) / 8), 3))
#: Default cap on Levenberg–Marquardt iterations.
DEFAULT_MAX_ITERATIONS = 60
#: A seed star is accepted when its second-best orientation pattern is off by at least this.
SEED_MARGIN = 1e-2


@dataclass(frozen=True, eq=False)
class EmbeddingResult:
    """Output of :func:`embed_thickening` / :func:`embed_base_edges`.

    ``points`` float64 ``(n_points, 3)`` (thickening: base vertices then offset vertices);
    ``residual`` the RMS relative edge-length residual ``(|x_i − x_j| − ℓ_e) / ℓ_e`` of the result
    and ``max_residual`` its largest magnitude; ``initial_residual`` the same for the start
    (greedy or given); ``iterations`` the Levenberg–Marquardt iterations taken; ``initializer``
    ``"hinge_frames"``, ``"greedy"``, ``"initial_points"``, ``"reference_points"`` or
    ``"continuation"``; ``lookahead_choices`` / ``unresolved_choices`` how many mirror
    ambiguities the greedy resolved by lookahead / had to decide without evidence (parts
    that the lengths leave flexible, e.g. a lifted vertex above a two-triangle boundary fan);
    ``components`` the connected components embedded independently.
    """

    points: np.ndarray
    n_base: int
    residual: float
    max_residual: float
    initial_residual: float
    iterations: int
    initializer: str
    lookahead_choices: int = 0
    unresolved_choices: int = 0
    components: int = 1
    converged: bool = True

    @property
    def base_vertices(self) -> np.ndarray:
        """The base layer, float64 ``(n, 3)``: the reconstructed pose (up to rigid motion)."""
        return self.points[: self.n_base]


# ---------------------------------------------------------------------------------------------
# small vectorized geometry
# ---------------------------------------------------------------------------------------------


def _det3(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``det[a, b, c]`` row-wise for ``(P, 3)`` arrays."""
    return np.einsum("ij,ij->i", a, np.cross(b, c))


def _apex(p0, p1, p2, s0, s1, s2):
    """The two points at squared distances ``s0, s1, s2`` ``(P,)`` from ``p0, p1, p2`` ``(P, 3)``:
    returns ``foot (P, 3)``, ``lift (P, 3)`` (candidates ``foot ± lift``, ``+`` on the side of
    ``(p1 − p0) × (p2 − p0)``) and ``deficit (P,)`` ≥ 0, the relative amount by which the spheres
    miss each other (0 when they intersect; then ``lift`` is 0)."""
    e1, e2 = p1 - p0, p2 - p0
    g11 = np.einsum("ij,ij->i", e1, e1)
    g22 = np.einsum("ij,ij->i", e2, e2)
    g12 = np.einsum("ij,ij->i", e1, e2)
    r1 = 0.5 * (s0 - s1 + g11)
    r2 = 0.5 * (s0 - s2 + g22)
    det = g11 * g22 - g12 * g12
    det = np.where(det > 0, det, np.finfo(float).tiny)
    alpha = (g22 * r1 - g12 * r2) / det
    beta = (g11 * r2 - g12 * r1) / det
    in_plane = alpha[:, None] * e1 + beta[:, None] * e2
    h2 = s0 - np.einsum("ij,ij->i", in_plane, in_plane)
    normal = np.cross(e1, e2)
    normal /= np.sqrt(det)[:, None]
    scale = np.maximum(s0, np.finfo(float).tiny)
    deficit = np.where(h2 < 0, -h2 / scale, 0.0)
    lift = np.sqrt(np.maximum(h2, 0.0))[:, None] * normal
    return p0 + in_plane, lift, deficit


def _segments(indptr: np.ndarray, rows: np.ndarray):
    """Flattened CSR rows: (owner position in ``rows``, flat index into the CSR data)."""
    starts = indptr[rows]
    lengths = indptr[rows + 1] - starts
    owner = np.repeat(np.arange(rows.size), lengths)
    total = int(lengths.sum())
    offsets = np.arange(total) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return owner, np.repeat(starts, lengths) + offsets


class _Graph:
    """Symmetric CSR adjacency of the points with squared lengths, and point → tetrahedron maps."""

    def __init__(self, n_points: int, edges: np.ndarray, squared: np.ndarray, upward: np.ndarray, tets: np.ndarray):
        self.n = n_points
        heads = np.concatenate([edges[:, 0], edges[:, 1]])
        tails = np.concatenate([edges[:, 1], edges[:, 0]])
        values = np.concatenate([squared, squared])
        order = np.argsort(heads, kind="stable")
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(heads, minlength=n_points))]).astype(np.int64)
        self.neighbors = tails[order]
        self.squared = values[order]
        self.degree = np.diff(self.indptr)
        self.upward = upward
        self.up_ptr, self.up_ids = _incidence(upward, n_points)
        self.tets = tets
        self.tet_ptr, self.tet_ids = _incidence(tets, n_points)

    def rows(self, points: np.ndarray):
        owner, flat = _segments(self.indptr, points)
        return owner, self.neighbors[flat], self.squared[flat]

    def distance2(self, a: int, b: int) -> float:
        row = slice(self.indptr[a], self.indptr[a + 1])
        hit = np.flatnonzero(self.neighbors[row] == b)
        if hit.size == 0:
            raise KeyError((a, b))
        return float(self.squared[row][hit[0]])


def _incidence(cells: np.ndarray, n_points: int):
    if cells.size == 0:
        return np.zeros(n_points + 1, dtype=np.int64), np.zeros(0, dtype=np.int64)
    flat = cells.ravel()
    order = np.argsort(flat, kind="stable")
    ptr = np.concatenate([[0], np.cumsum(np.bincount(flat, minlength=n_points))]).astype(np.int64)
    return ptr, (order // cells.shape[1]).astype(np.int64)


# ---------------------------------------------------------------------------------------------
# greedy initializer (proof of Prop. 4)
# ---------------------------------------------------------------------------------------------


class _Greedy:
    """Wavefront gluing of tetrahedra; see the module docstring."""

    def __init__(self, graph: _Graph):
        self.g = graph
        n = graph.n
        self.placed = np.zeros(n, dtype=bool)
        self.pos = np.zeros((n, 3))
        self.count = np.zeros(n, dtype=np.int64)
        self.lookahead_choices = 0
        self.unresolved_choices = 0

    # -- bookkeeping --------------------------------------------------------------------------
    def place(self, points: np.ndarray, positions: np.ndarray, log: list | None = None) -> np.ndarray:
        """Place ``points`` and return the unplaced neighbours (the next front)."""
        self.placed[points] = True
        self.pos[points] = positions
        if log is not None:
            log.append(points)
        _, nbr, _ = self.g.rows(points)
        touched, counts = np.unique(nbr, return_counts=True)
        self.count[touched] += counts
        return touched[~self.placed[touched]]

    def unplace(self, log: list) -> None:
        if not log:
            return
        points = np.concatenate(log)
        self.placed[points] = False
        _, nbr, _ = self.g.rows(points)
        touched, counts = np.unique(nbr, return_counts=True)
        self.count[touched] -= counts

    # -- one wave -----------------------------------------------------------------------------
    def wave(self, front: np.ndarray):
        """Place every point of ``front`` that the rules determine. Returns (placed points, their
        positions, worst relative check residual, number of overdetermined checks)."""
        g, placed, pos = self.g, self.placed, self.pos
        front = front[~placed[front]]
        chosen, where, worst, checks = [], [], 0.0, 0
        if front.size == 0:
            return front, np.zeros((0, 3)), worst, checks
        # Rule 1: complete an upward tetrahedron (i, j, k, c_T) on its positive side.
        owner, flat = _segments(g.up_ptr, front)
        done = np.zeros(front.size, dtype=bool)
        if flat.size:
            tets = g.upward[g.up_ids[flat]]  # (R, 4)
            ok = placed[tets].sum(axis=1) == 3
            owner, tets = owner[ok], tets[ok]
            if owner.size:
                owner, first = np.unique(owner, return_index=True)
                tets = tets[first]
                missing = front[owner]
                slot = np.argmax(tets == missing[:, None], axis=1)
                others = np.sort(np.where(np.arange(4)[None, :] == slot[:, None], -1, np.arange(4)[None, :]), axis=1)[:, 1:]
                q = tets[np.arange(tets.shape[0])[:, None], others]  # (R, 3) placed points
                p = pos[q]
                s = np.stack([self._d2(missing, q[:, k]) for k in range(3)], axis=1)
                foot, lift, deficit = _apex(p[:, 0], p[:, 1], p[:, 2], s[:, 0], s[:, 1], s[:, 2])
                x = foot + lift
                corners = pos[tets].copy()
                corners[np.arange(tets.shape[0]), slot] = x
                vol = _det3(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0], corners[:, 3] - corners[:, 0])
                x = np.where((vol < 0)[:, None], foot - lift, x)
                # Polish with every placed neighbour (more constraints, better conditioning).
                o2, nbr2, sq2 = g.rows(missing)
                keep2 = placed[nbr2]
                x = self._refine(x, o2[keep2], pos[nbr2[keep2]], sq2[keep2], deficit < 1e-6)
                chosen.append(missing)
                where.append(x)
                done[owner] = True
                if deficit.size:
                    worst = max(worst, float(deficit.max()))
        # Rule 2: trilaterate from >= 4 placed, non-coplanar neighbours.
        rest = front[~done & (self.count[front] >= 4)]
        if rest.size:
            x, good, residual = self._trilaterate(rest)
            if good.any():
                chosen.append(rest[good])
                where.append(x[good])
                worst = max(worst, float(residual[good].max()))
                checks += int(good.sum())
        if not chosen:
            return front[:0], np.zeros((0, 3)), worst, checks
        return np.concatenate(chosen), np.concatenate(where), worst, checks

    def _d2(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Squared lengths of edges (a[r], b[r]) by CSR search (rows are short)."""
        g = self.g
        owner, nbr, sq = g.rows(a)
        hit = nbr == b[owner]
        out = np.full(a.size, np.nan)
        out[owner[hit]] = sq[hit]
        return out

    def _trilaterate(self, points: np.ndarray):
        """Least-squares position from all placed neighbours. Returns (x (P,3), well-conditioned
        (P,), worst relative residual (P,))."""
        owner, nbr, sq = self.g.rows(points)
        keep = self.placed[nbr]
        owner, nbr, sq = owner[keep], nbr[keep], sq[keep]
        P = points.size
        cnt = np.bincount(owner, minlength=P).astype(float)
        p = self.pos[nbr]
        center = np.stack([np.bincount(owner, p[:, k], minlength=P) for k in range(3)], axis=1) / cnt[:, None]
        q = p - center[owner]
        qq = np.einsum("ij,ij->i", q, q)
        mean_qq = np.bincount(owner, qq, minlength=P) / cnt
        mean_sq = np.bincount(owner, sq, minlength=P) / cnt
        rhs = 0.5 * (qq - mean_qq[owner] - sq + mean_sq[owner])
        A = np.zeros((P, 3, 3))
        b = np.zeros((P, 3))
        for r in range(3):
            b[:, r] = np.bincount(owner, q[:, r] * rhs, minlength=P)
            for c in range(r, 3):
                A[:, r, c] = A[:, c, r] = np.bincount(owner, q[:, r] * q[:, c], minlength=P)
        finite = np.isfinite(A).all(axis=(1, 2)) & np.isfinite(b).all(axis=1)
        A[~finite] = np.eye(3)
        b[~finite] = 0.0
        eig = np.linalg.eigvalsh(A)
        good = finite & (eig[:, 0] > COPLANAR_RATIO * np.maximum(eig[:, 2], np.finfo(float).tiny))
        A[~good] = np.eye(3)
        y = np.linalg.solve(A, b[:, :, None])[:, :, 0]
        x = center + y
        x = self._refine(x, owner, p, sq, good)
        d = x[owner] - p
        rel = np.abs(np.einsum("ij,ij->i", d, d) - sq) / np.maximum(sq, np.finfo(float).tiny)
        worst = np.maximum.reduceat(rel, np.searchsorted(owner, np.arange(P)))  # owner is sorted
        return x, good, worst

    def _relax(self, points: np.ndarray) -> None:
        owner, nbr, sq = self.g.rows(points)
        keep = self.placed[nbr]
        owner, nbr, sq = owner[keep], nbr[keep], sq[keep]
        ok = np.bincount(owner, minlength=points.size) >= 3
        self.pos[points] = self._refine(self.pos[points], owner, self.pos[nbr], sq, ok, iterations=1)

    @staticmethod
    def _refine(x, owner, p, sq, good, iterations: int = 2):
        """Gauss–Newton on the relative sphere residuals (|x − p_j|² − s_j) / s_j of each point:
        uses every constraint (the linear trilateration drops one) and is better conditioned."""
        P = x.shape[0]
        w = 1.0 / np.maximum(sq, np.finfo(float).tiny)
        for _ in range(iterations):
            d = x[owner] - p
            r = (np.einsum("ij,ij->i", d, d) - sq) * w
            jac = 2.0 * d * w[:, None]
            A = np.zeros((P, 3, 3))
            b = np.zeros((P, 3))
            for i in range(3):
                b[:, i] = np.bincount(owner, jac[:, i] * r, minlength=P)
                for j in range(i, 3):
                    A[:, i, j] = A[:, j, i] = np.bincount(owner, jac[:, i] * jac[:, j], minlength=P)
            A[~good] = np.eye(3)
            b[~good] = 0.0
            # A whisker of damping keeps degenerate stencils (inconsistent lengths) solvable.
            A += (1e-10 * np.trace(A, axis1=1, axis2=2) + np.finfo(float).tiny)[:, None, None] * np.eye(3)
            step = np.linalg.solve(A, b[:, :, None])[:, :, 0]
            x = x - np.where(np.isfinite(step).all(axis=1, keepdims=True), step, 0.0)
        return x

    def run(self, front: np.ndarray, *, max_waves: int | None = None, log: list | None = None, max_checks=None):
        """Propagate waves from ``front``. Returns (worst check residual, number of checks)."""
        worst, checks, waves = 0.0, 0, 0
        recent: list = []
        while front.size:
            new, x, w, c = self.wave(front)
            worst, checks = max(worst, w), checks + c
            if new.size == 0:
                break
            front = self.place(new, x, log)
            waves += 1
            if log is None and RELAX_WAVES:
                # Re-solve the last few waves with the neighbours placed since: points placed
                # with few constraints are corrected before errors propagate (without it,
                # round-off grew to 1e-2 over the ~700 waves of a 224×224 sheet).
                recent = (recent + [new])[-RELAX_WAVES:]
                self._relax(np.concatenate(recent))
            if max_waves is not None and waves >= max_waves:
                break
            if max_checks is not None and checks >= max_checks:
                break
        return worst, checks

    # -- ambiguity -----------------------------------------------------------------------------
    def resolve(self, point: int, *, force: bool = False) -> np.ndarray | None:
        """Place one point that has ≥ 3 placed neighbours but no determined position: try both
        mirror positions with a lookahead and keep the consistent one. Returns the next front, or
        ``None`` (deferred, unless ``force``) when the placed neighbours are collinear or both
        positions look equally consistent — another point may be decided first."""
        g = self.g
        _, nbr, sq = g.rows(np.array([point]))
        keep = self.placed[nbr]
        nbr, sq = nbr[keep], sq[keep]
        triple = self._best_triple(nbr)
        if triple is None:  # collinear neighbours: free to rotate about their line
            return self.place_free(point) if force else None
        a, b, c = triple
        foot, lift, _ = _apex(self.pos[[nbr[a]]], self.pos[[nbr[b]]], self.pos[[nbr[c]]], sq[[a]], sq[[b]], sq[[c]])
        candidates = [foot[0] + lift[0], foot[0] - lift[0]]
        if not np.any(lift):
            return self.place(np.array([point]), foot)
        if nbr.size >= 4:
            # More than three placed neighbours (nearly coplanar, so not trilaterated): their
            # distances already tell the mirror positions apart unless the fit is too flat.
            immediate = []
            for x in candidates:
                d = x[None, :] - self.pos[nbr]
                immediate.append(float(np.max(np.abs(np.einsum("ij,ij->i", d, d) - sq) / np.maximum(sq, np.finfo(float).tiny))))
            lo, hi = min(immediate), max(immediate)
            if lo < CONSISTENT_RESIDUAL and hi > max(10.0 * lo, SEED_MARGIN):
                self.lookahead_choices += 1
                x = candidates[int(np.argmin(immediate))][None, :]
                x = self._refine(x, np.zeros(nbr.size, dtype=np.int64), self.pos[nbr], sq, np.ones(1, dtype=bool))
                return self.place(np.array([point]), x)
        if g.degree[point] <= 3 or not (~self.placed[g.neighbors[g.indptr[point] : g.indptr[point + 1]]]).any():
            # Nothing further depends on it: the lengths leave this mirror choice free.
            self.unresolved_choices += 1
            return self.place(np.array([point]), candidates[self._default_side(point, candidates)][None, :])
        scores = []
        for x in candidates:
            log: list = []
            front = self.place(np.array([point]), x[None, :], log)
            worst, checks = self.run(front, max_waves=LOOKAHEAD_WAVES, log=log, max_checks=LOOKAHEAD_CHECKS)
            self.unplace(log)
            scores.append((worst if checks else np.inf, checks))
        (w0, c0), (w1, c1) = scores
        pick = None
        if min(w0, w1) < CONSISTENT_RESIDUAL and not max(w0, w1) < max(10.0 * min(w0, w1), SEED_MARGIN):
            pick = 0 if w0 <= w1 else 1
        elif not force:
            return None
        if pick is None:
            pick = self._default_side(point, candidates)
            self.unresolved_choices += 1
        else:
            self.lookahead_choices += 1
        return self.place(np.array([point]), candidates[pick][None, :])

    def _best_triple(self, nbr: np.ndarray):
        p = self.pos[nbr]
        best, area_best = None, 0.0
        scale = np.ptp(p, axis=0).max() if p.shape[0] else 0.0
        for triple in itertools.combinations(range(nbr.size), 3):
            a, b, c = p[list(triple)]
            area = np.linalg.norm(np.cross(b - a, c - a))
            if area > area_best:
                best, area_best = triple, area
        if best is None or area_best <= WELL_SHAPED * scale * scale:
            return None  # (nearly) collinear: the mirror positions are ill-determined
        return best

    def _default_side(self, point: int, candidates) -> int:
        """Without evidence: the side that makes a tetrahedron of the thickening through this point
        positive, as it is in a flat sheet (the lengths cannot tell, so either is an embedding)."""
        g = self.g
        for t in g.tet_ids[g.tet_ptr[point] : g.tet_ptr[point + 1]]:
            tet = g.tets[t]
            others = tet[tet != point]
            if self.placed[others].all():
                for side, x in enumerate(candidates):
                    corners = self.pos[tet].copy()
                    corners[tet == point] = x
                    if _det3(*(corners[1:] - corners[0])[:, None, :]).item() > 0:
                        return side
        return 0

    def place_free(self, point: int) -> np.ndarray:
        """Place a point with < 3 usable placed neighbours anywhere consistent with them (its
        position relative to the rest is not determined by the lengths)."""
        g = self.g
        _, nbr, sq = g.rows(np.array([point]))
        keep = self.placed[nbr]
        nbr, sq = nbr[keep], sq[keep]
        if nbr.size == 0:
            x = np.zeros(3)
        elif nbr.size == 1 or np.allclose(self.pos[nbr[0]], self.pos[nbr[1]]):
            x = self.pos[nbr[0]] + np.array([np.sqrt(sq[0]), 0.0, 0.0])
        else:
            p0, p1 = self.pos[nbr[0]], self.pos[nbr[1]]
            axis = p1 - p0
            length2 = axis @ axis
            along = 0.5 * (sq[0] - sq[1] + length2) / length2
            h2 = max(sq[0] - along * along * length2, 0.0)
            other = np.eye(3)[np.argmin(np.abs(axis))]
            perp = np.cross(axis, other)
            perp /= np.linalg.norm(perp)
            x = p0 + along * axis + np.sqrt(h2) * perp
        return self.place(np.array([point]), x[None, :])


def _star_seed(greedy: _Greedy, surface: OffsetSurface, vertex: int) -> np.ndarray | None:
    """Place the star of interior base vertex ``vertex`` (its fan triangles, their centers and the
    lifted vertex) by enumerating the 2^(k−1) hinge orientations around it and keeping the one
    whose fan closes and whose lifted vertex trilaterates consistently. Returns the next front,
    or None if the star is unsuitable."""
    base, n, g = surface.base, surface.base.n_vertices, greedy.g
    lifted = surface.lift_of_vertex[vertex]
    if lifted < 0:
        return None
    fan = np.flatnonzero((base.triangles == vertex).any(axis=1))
    k = fan.size
    if k < 3 or k > MAX_SEED_VALENCE:
        return None
    nxt = {}
    center = {}
    for t in fan:
        tri = base.triangles[t]
        r = int(np.flatnonzero(tri == vertex)[0])
        u, w = int(tri[(r + 1) % 3]), int(tri[(r + 2) % 3])
        if u in nxt or surface.center_of_triangle[t] < 0:
            return None
        nxt[u] = w
        center[u] = n + int(surface.center_of_triangle[t])
    ring = [next(iter(nxt))]
    for _ in range(k - 1):
        if ring[-1] not in nxt:
            return None
        ring.append(nxt[ring[-1]])
    if ring[-1] not in nxt or nxt[ring[-1]] != ring[0] or len(set(ring)) != k:
        return None  # boundary vertex (open fan)
    cents = [center[u] for u in ring]
    a_t = n + int(lifted)
    pts = [vertex, *ring, *cents, a_t]
    if greedy.placed[pts].any():
        return None
    try:
        d = g.distance2
        S = 2 ** (k - 1)
        bits = (np.arange(S)[:, None] >> np.arange(k - 1)[None, :]) & 1  # (S, k-1)
        P = {}
        # First upward tetrahedron (a, b_1, b_2, c_1), positively oriented.
        ab, aw, bw = d(vertex, ring[0]), d(vertex, ring[1]), d(ring[0], ring[1])
        la = np.sqrt(ab)
        xw = 0.5 * (aw - bw + ab) / la
        yw = np.sqrt(max(aw - xw * xw, 0.0))
        P[vertex] = np.zeros((S, 3))
        P[ring[0]] = np.tile([la, 0.0, 0.0], (S, 1))
        P[ring[1]] = np.tile([xw, yw, 0.0], (S, 1))
        foot, lift, _ = _apex(P[vertex], P[ring[0]], P[ring[1]], *(np.full(S, d(q, cents[0])) for q in (vertex, ring[0], ring[1])))
        P[cents[0]] = foot + lift  # positive side of (a, b_1, b_2)
        bad = np.zeros(S)
        for i in range(1, k):
            b_i, c_prev, c_i = ring[i], cents[i - 1], cents[i]
            foot, lift, deficit = _apex(
                P[vertex], P[b_i], P[c_prev], np.full(S, d(vertex, c_i)), np.full(S, d(b_i, c_i)), np.full(S, d(c_prev, c_i))
            )
            sign = np.where(bits[:, i - 1] == 1, -1.0, 1.0)[:, None]
            P[c_i] = foot + sign * lift
            bad = np.maximum(bad, deficit)
            if i < k - 1:
                b_next = ring[i + 1]
                foot, lift, deficit = _apex(
                    P[vertex], P[b_i], P[c_i], np.full(S, d(vertex, b_next)), np.full(S, d(b_i, b_next)), np.full(S, d(c_i, b_next))
                )
                x = foot + lift
                vol = _det3(P[b_i] - P[vertex], x - P[vertex], P[c_i] - P[vertex])
                P[b_next] = np.where((vol < 0)[:, None], foot - lift, x)
                bad = np.maximum(bad, deficit)
        # Closure: c_k to b_1 and c_1; the last upward tetrahedron must be positive.
        last = cents[k - 1]
        for q in (ring[0], cents[0]):
            diff = P[last] - P[q]
            s = d(last, q)
            bad = np.maximum(bad, np.abs(np.einsum("ij,ij->i", diff, diff) - s) / s)
        vol = _det3(P[ring[k - 1]] - P[vertex], P[ring[0]] - P[vertex], P[last] - P[vertex])
        bad = np.where(vol > 0, bad, np.inf)
        # Lifted vertex a_t from a and all centers (k + 1 >= 4 spheres).
        anchors = [vertex, *cents]
        Q = np.stack([P[q] for q in anchors], axis=1)  # (S, k+1, 3)
        s = np.array([d(a_t, q) for q in anchors])
        center_q = Q.mean(axis=1, keepdims=True)
        Qc = Q - center_q
        qq = np.einsum("sij,sij->si", Qc, Qc)
        rhs = 0.5 * (qq - qq.mean(axis=1, keepdims=True) - s + s.mean())
        A = np.einsum("sij,sik->sjk", Qc, Qc) + 1e-300 * np.eye(3)
        y = np.linalg.solve(A, np.einsum("sij,si->sj", Qc, rhs)[:, :, None])[:, :, 0]
        X = center_q[:, 0] + y
        diff = X[:, None, :] - Q
        bad = np.maximum(bad, np.max(np.abs(np.einsum("sij,sij->si", diff, diff) - s) / s, axis=1))
        P[a_t] = X
    except (KeyError, np.linalg.LinAlgError, FloatingPointError):
        return None
    bad = np.where(np.isfinite(bad), bad, np.inf)
    order = np.argsort(bad)
    best = int(order[0])
    # Unique up to rigid motion? (A flat valence-4 star folds along its straight lines.)
    if not bad[best] < CONSISTENT_RESIDUAL or (S > 1 and not bad[order[1]] > max(10.0 * bad[best], SEED_MARGIN)):
        return None
    order = np.array(pts)
    front = greedy.place(order, np.stack([P[q][best] for q in pts]))
    return front


def _greedy_embedding(surface: OffsetSurface | None, graph: _Graph, needed: np.ndarray, seed_order: np.ndarray):
    """Run the greedy initializer on all points in ``needed`` (bool (N,)). ``seed_order``: base
    vertices to try as star seeds, best first."""
    greedy = _Greedy(graph)
    seed_cursor = 0
    front = np.zeros(0, dtype=np.int64)
    deferred_at = np.full(graph.n, -1, dtype=np.int64)
    while True:
        greedy.run(front)
        remaining = needed & ~greedy.placed
        if not remaining.any():
            break
        stuck = np.flatnonzero(remaining & (greedy.count >= 3) & (greedy.count > deferred_at))
        if stuck.size:
            point = int(_pick_ambiguous(greedy, stuck))
            front = greedy.resolve(point)
            if front is None:  # undecidable now; retry once it gains a placed neighbour
                deferred_at[point] = greedy.count[point]
                front = np.zeros(0, dtype=np.int64)
            continue
        deferred = np.flatnonzero(remaining & (deferred_at >= 0))
        if deferred.size:
            # Every ambiguous point is undecidable for now: decide one as well as possible.
            front = greedy.resolve(int(_pick_ambiguous(greedy, deferred)), force=True)
            continue
        front = None
        # A new piece: the star of an interior vertex (a new component, or a part joined to the
        # placed ones by fewer than three points, whose relative placement is free).
        while surface is not None and seed_cursor < seed_order.size:
            v = int(seed_order[seed_cursor])
            seed_cursor += 1
            if remaining[v]:
                front = _star_seed(greedy, surface, v)
                if front is not None:
                    break
        if front is None:
            front = _seed_tetrahedron(greedy, remaining)
        if front is None:
            candidates = np.flatnonzero(remaining)
            front = greedy.place_free(int(candidates[np.argmax(greedy.count[candidates])]))
    return greedy


def _pick_ambiguous(greedy: _Greedy, stuck: np.ndarray) -> int:
    """Prefer an ambiguous point whose placement immediately gives a neighbour ≥ 4 placed
    neighbours (a check), then the one with most placed neighbours."""
    owner, nbr, _ = greedy.g.rows(stuck)
    ready = (~greedy.placed[nbr]) & (greedy.count[nbr] >= 3)
    has_check = np.bincount(owner, ready, minlength=stuck.size) > 0
    key = has_check * 1000 + np.minimum(greedy.count[stuck], 999)
    return int(stuck[np.argmax(key)])


def _seed_tetrahedron(greedy: _Greedy, remaining: np.ndarray):
    """Seed with one upward tetrahedron whose four points are all unplaced (positive)."""
    g = greedy.g
    if g.upward.size == 0:
        return None
    free = (~greedy.placed[g.upward]).all(axis=1) & remaining[g.upward].all(axis=1)
    if not free.any():
        return None
    tet = g.upward[np.flatnonzero(free)[0]]
    i, j, k, c = (int(q) for q in tet)
    d = g.distance2
    lij = np.sqrt(d(i, j))
    xk = 0.5 * (d(i, k) - d(j, k) + lij * lij) / lij
    yk = np.sqrt(max(d(i, k) - xk * xk, 0.0))
    pi, pj, pk = np.zeros(3), np.array([lij, 0, 0.0]), np.array([xk, yk, 0.0])
    foot, lift, _ = _apex(pi[None], pj[None], pk[None], *(np.array([d(q, c)]) for q in (i, j, k)))
    return greedy.place(tet, np.stack([pi, pj, pk, (foot + lift)[0]]))


# ---------------------------------------------------------------------------------------------
# Levenberg–Marquardt polish
# ---------------------------------------------------------------------------------------------


def _relative_residuals(x: np.ndarray, edges: np.ndarray, squared: np.ndarray):
    d = x[edges[:, 0]] - x[edges[:, 1]]
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    target = np.sqrt(squared)
    floor = np.finfo(float).tiny
    return (length - target) / np.maximum(target, floor)


#: Conjugate-gradient iterations per Gauss–Newton step (inexact Newton) and relative tolerance.
CG_ITERATIONS = 300
CG_TOLERANCE = 1e-4
#: Levenberg–Marquardt stops when an accepted step lowers the cost by less than this fraction.
STAGNATION = 1e-3


def _block_jacobi(edges_i, edges_j, g, nf, extra_diag):
    """Inverse 3×3 diagonal blocks ``(nf, 3, 3)`` of ``JᵀJ + diag(extra_diag)`` for rows
    ``± g_e`` at unknowns ``edges_i`` / ``edges_j`` (−1: fixed)."""
    blocks = np.zeros((nf, 3, 3))
    outer = g[:, :, None] * g[:, None, :]
    for cols in (edges_i, edges_j):
        ok = cols >= 0
        for r in range(3):
            for c in range(3):
                blocks[:, r, c] += np.bincount(cols[ok], outer[ok, r, c], minlength=nf)
    blocks += extra_diag.reshape(nf, 3)[:, :, None] * np.eye(3)[None]
    # Closed-form inverse; the blocks are symmetric positive definite (determinant > 0, the
    # cofactor matrix its own transpose). Kept C-contiguous: the BSR product ravels its data on
    # every call, and a transposed view made that a copy (+0.45 s on the 1k cloth's embedding).
    cofactors, det = cofactors_3x3(blocks)
    return cofactors / det[:, None, None]


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """Vector dot product without BLAS (multithreaded BLAS is slow for these sizes on a busy
    machine: measured 40× slower than a single-threaded loop under load)."""
    return float(np.einsum("i,i->", a, b))


def _pcg(apply_A, b, apply_M, iterations, tolerance):
    """Preconditioned conjugate gradients for an SPD operator (fixed small API, any SciPy)."""
    x = np.zeros_like(b)
    r = b.copy()
    z = apply_M(r)
    p = z.copy()
    rz = _dot(r, z)
    b_norm2 = _dot(b, b)
    if b_norm2 == 0:
        return x
    for _ in range(iterations):
        Ap = apply_A(p)
        pAp = _dot(p, Ap)
        if not pAp > 0:
            break
        alpha = rz / pAp
        x += alpha * p
        r -= alpha * Ap
        if _dot(r, r) <= tolerance * tolerance * b_norm2:
            break
        z = apply_M(r)
        rz_new = _dot(r, z)
        p *= rz_new / rz
        p += z
        rz = rz_new
    return x


def _levenberg_marquardt(x0, edges, squared, free, *, anchor_points=None, anchor_weight=0.0, length_scale=1.0,
                         tolerance=1e-12, max_iterations=DEFAULT_MAX_ITERATIONS, cg_iterations=CG_ITERATIONS):
    """Minimize ``Σ_e r_e² + (w / h²) Σ_v |x_v − a_v|²`` with ``r_e = (|x_i − x_j|² − ℓ²_e)/(2ℓ²_e)``.

    ``x0`` ``(N, 3)``; ``free`` bool ``(N,)`` points that move (the others stay); ``anchor_points``
    ``(N, 3)`` with NaN rows for unanchored points; ``length_scale`` ``h`` the mean edge length.
    Each step solves ``(JᵀJ + µI + A) δ = −g`` by block-Jacobi preconditioned CG (an inexact
    Newton step; SuperLU was measured 0.4–3 s per factorization already at 1k vertices). Returns
    ``(x, iterations, converged)``.
    """
    from scipy.sparse import bsr_matrix, coo_matrix

    N = x0.shape[0]
    index = np.full(N, -1, dtype=np.int64)
    index[free] = np.arange(int(free.sum()))
    nf = int(free.sum())
    use = (index[edges[:, 0]] >= 0) | (index[edges[:, 1]] >= 0)
    edges, squared = edges[use], squared[use]
    scale2 = np.maximum(squared, 1e-12 * max(float(np.mean(squared)) if squared.size else 1.0, np.finfo(float).tiny))
    inv = 1.0 / (2.0 * scale2)
    anchored = np.zeros(N, dtype=bool)
    aw = 0.0
    if anchor_points is not None and anchor_weight > 0:
        anchored = free & np.isfinite(anchor_points).all(axis=1)
        aw = float(anchor_weight) / (length_scale * length_scale)
    anchor_diag = np.zeros(3 * nf)
    if aw:
        anchor_diag.reshape(nf, 3)[index[anchored]] = aw
    x = x0.copy()
    ei, ej = index[edges[:, 0]], index[edges[:, 1]]

    def cost_of(x):
        d = x[edges[:, 0]] - x[edges[:, 1]]
        r = (np.einsum("ij,ij->i", d, d) - squared) * inv
        c = float(r @ r)
        if aw:
            da = x[anchored] - anchor_points[anchored]
            c += aw * float(np.einsum("ij,ij->", da, da))
        return c, r, d

    def scatter(values_i, values_j):
        """Σ over edges of per-edge 3-vectors into the unknowns, (nf*3,)."""
        out = np.zeros((nf, 3))
        for cols, vals in ((ei, values_i), (ej, values_j)):
            ok = cols >= 0
            for k in range(3):
                out[:, k] += np.bincount(cols[ok], vals[ok, k], minlength=nf)
        return out.ravel()

    cost, r, d = cost_of(x)
    iterations, converged = 0, False
    mu = None
    rows = np.arange(edges.shape[0])
    block_index, block_pointer = np.arange(nf), np.arange(nf + 1)
    for iterations in range(1, max_iterations + 1):
        rms = np.sqrt(np.mean(_relative_residuals(x, edges, squared) ** 2)) if edges.size else 0.0
        if rms <= tolerance and not aw:
            converged = True
            iterations -= 1
            break
        g = 2.0 * d * inv[:, None]  # ∂r_e/∂x_i = g_e, ∂r_e/∂x_j = −g_e
        grad = scatter(g * r[:, None], -g * r[:, None])
        if aw:
            grad.reshape(nf, 3)[index[anchored]] += aw * (x[anchored] - anchor_points[anchored])
        data, rr, cc = [], [], []
        for cols, sgn in ((ei, 1.0), (ej, -1.0)):
            ok = cols >= 0
            for k in range(3):
                data.append(sgn * g[ok, k])
                rr.append(rows[ok])
                cc.append(3 * cols[ok] + k)
        J = coo_matrix((np.concatenate(data), (np.concatenate(rr), np.concatenate(cc))),
                       shape=(edges.shape[0], 3 * nf)).tocsr()
        JT = J.T.tocsr()
        gg = np.einsum("ij,ij->i", g, g)
        mean_diag = float(2.0 * gg.sum() / max(3 * nf, 1) + anchor_diag.mean()) if nf else 1.0
        if mu is None:
            mu = 1e-6 * mean_diag
        floor = 1e-12 * mean_diag
        accepted = False
        for _ in range(10):
            damping = max(mu, floor)
            # Block-diagonal preconditioner as a BSR matrix: its product is 3× faster than an
            # einsum over the (nf, 3, 3) blocks (30 vs 100 µs at 4k points).
            preconditioner = bsr_matrix((_block_jacobi(ei, ej, g, nf, anchor_diag + damping), block_index,
                                         block_pointer), shape=(3 * nf, 3 * nf))
            diagonal = anchor_diag + damping

            def apply_A(v, diagonal=diagonal):
                return JT @ (J @ v) + diagonal * v

            step = -_pcg(apply_A, grad, preconditioner.__matmul__, cg_iterations, CG_TOLERANCE)
            trial = x.copy()
            trial[free] += step.reshape(-1, 3)
            new_cost, new_r, new_d = cost_of(trial)
            if np.isfinite(new_cost) and new_cost <= cost:
                improvement = cost - new_cost
                x, r, d = trial, new_r, new_d
                old_cost, cost = cost, new_cost
                mu = max(mu / 4.0, floor)
                accepted = True
                break
            mu = damping * 8.0
        if not accepted:
            converged = True  # no descent possible: a (local) minimum to working precision
            break
        if improvement <= STAGNATION * old_cost or np.abs(step).max() <= 1e-14 * length_scale:
            converged = True
            break
    return x, iterations, converged


# ---------------------------------------------------------------------------------------------
# public API
# ---------------------------------------------------------------------------------------------


def _check_lengths(squared, expected: int, what: str) -> np.ndarray:
    s = np.asarray(squared, dtype=np.float64).reshape(-1)
    if s.shape[0] != expected:
        raise RecoveryError(f"{what}: expected {expected} squared edge lengths, got {s.shape[0]}.")
    bad = np.flatnonzero(~np.isfinite(s) | (s < 0))
    if bad.size:
        e = int(bad[0])
        raise RecoveryError(
            f"{what}: squared edge length {e} is {s[e]!r} ({bad.size} negative or non-finite in all), so "
            "no embedding exists. The recovered metric is invalid: check the shape differences (a "
            "truncated basis that is too small, or an interpolation factor far outside [0, 1])."
        )
    return s


def _anchor_array(anchor, n_points: int, n_base: int):
    if anchor is None:
        return None, 0.0
    positions, weight = anchor
    a = np.asarray(positions, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] not in (n_points, n_base):
        raise RecoveryError(f"anchor positions must have shape ({n_points}, 3) or ({n_base}, 3); got {a.shape}.")
    weight = float(weight)
    if not np.isfinite(weight) or weight < 0:
        raise RecoveryError(f"anchor weight must be a non-negative number; got {weight!r}.")
    out = np.full((n_points, 3), np.nan)
    out[: a.shape[0]] = a
    return out, weight


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values * values))) if values.size else 0.0


def _finish(x, edges, squared, n_base, x_start, iterations, initializer, converged, greedy=None, components=1,
            unresolved=None):
    rel = _relative_residuals(x, edges, squared) if edges.size else np.zeros(1)
    rel0 = _relative_residuals(x_start, edges, squared) if edges.size else np.zeros(1)
    if not np.isfinite(x).all():
        raise RecoveryError("The embedding produced non-finite positions; the edge lengths are inconsistent.")
    return EmbeddingResult(
        points=x,
        n_base=n_base,
        residual=float(np.sqrt(np.mean(rel * rel))),
        max_residual=float(np.abs(rel).max()),
        initial_residual=float(np.sqrt(np.mean(rel0 * rel0))),
        iterations=int(iterations),
        initializer=initializer,
        lookahead_choices=0 if greedy is None else greedy.lookahead_choices,
        unresolved_choices=unresolved if unresolved is not None else (0 if greedy is None else greedy.unresolved_choices),
        components=components,
        converged=converged,
    )


def _components(n_points: int, edges: np.ndarray) -> tuple[int, np.ndarray]:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(edges.shape[0]), (edges[:, 0], edges[:, 1])), shape=(n_points, n_points))
    return connected_components(graph, directed=False)


def _align_components(x, reference, labels, active):
    """Rigidly move each component of ``x`` onto ``reference`` (rows with finite reference)."""
    from .rigid_alignment import rigid_alignment

    out = x.copy()
    for label in np.unique(labels[active]):
        rows = (labels == label) & active
        ok = rows & np.isfinite(reference).all(axis=1)
        if ok.sum() >= 3:
            R, t = rigid_alignment(x[ok], reference[ok])
            out[rows] = x[rows] @ R.T + t
    return out


def embed_thickening(
    surface: OffsetSurface,
    squared_lengths: np.ndarray,
    *,
    initial_points: np.ndarray | None = None,
    reference_points: np.ndarray | None = None,
    anchor: tuple[np.ndarray, float] | None = None,
    tolerance: float = 1e-8,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
) -> EmbeddingResult:
    """Positions of the canonical thickening (§5.3) realizing ``squared_lengths`` (§7.3).

    ``squared_lengths`` float ``(K,)`` for :attr:`OffsetSurface.thickening_edges` (base edges,
    offset edges, normal edges, side edges). Returns an :class:`EmbeddingResult` with ``points``
    ``(n + n_offset, 3)``; ``base_vertices`` (its first ``n`` rows) is the pose, up to rigid motion.

    - ``initial_points`` ``(n + n_offset, 3)`` warm start (a linear blend of poses, the previous
      frame): skips the greedy initializer; the fit converges to the nearest least-squares
      solution, which may be a mirror-folded one if the start is far off.
    - ``reference_points`` ``(n + n_offset, 3)``: a plausible pose (the base shape's thickening)
      raced against the hinge frames as a start when the lengths are inexact (see
      :data:`START_TRIAL_ITERATIONS`), and deformed gradually into the target lengths when the
      best fit stays far from them (:data:`CONTINUATION_RESIDUAL`); ignored with
      ``initial_points`` or exact lengths.
    - ``anchor = (positions, weight)``: positions ``(n + n_offset, 3)`` or ``(n, 3)`` (then only
      base vertices are anchored); adds ``weight · Σ_v |x_v − a_v|² / h²`` to the least-squares
      objective, ``h`` the mean edge length from ``squared_lengths``: the weight is dimensionless,
      ``weight = 1`` makes a displacement of one mean edge length cost as much as a 100% length
      error on one edge. Exact lengths are then no longer reproduced exactly. Without
      ``initial_points`` the greedy result is first moved rigidly onto the anchor (per component).
    - ``tolerance``: skip / stop the polish when the RMS relative length residual is below it
      (default 1e-8: the greedy start on exact data is ~1e-13 to 1e-10 — round-off grows
      slowly with the mesh size — far below the 1e-6 accuracy needed, and polishing it costs
      more than the greedy itself on large meshes);
      ``max_iterations``: cap on Levenberg–Marquardt iterations.

    Each connected component is embedded independently (its placement relative to the others is
    unknowable). Loose base vertices (no edge) are returned at the anchor, else the initial point,
    else the origin. Raises :class:`RecoveryError` for lengths of the wrong size, negative or
    non-finite; warns (:class:`ShapeDifferenceWarning`) if the fit did not converge.
    """
    edges = surface.thickening_edges
    n_points = surface.n_thickening_points
    n_base = surface.base.n_vertices
    squared = _check_lengths(squared_lengths, edges.shape[0], "embed_thickening")
    anchor_points, anchor_weight = _anchor_array(anchor, n_points, n_base)
    has_edge = np.zeros(n_points, dtype=bool)
    has_edge[edges.ravel()] = True
    n_comp, labels = _components(n_points, edges)
    n_comp_real = int(np.unique(labels[has_edge]).size)
    length_scale = float(np.mean(np.sqrt(squared))) if squared.size else 1.0

    fallback = np.zeros((n_points, 3))
    continuation_start = None
    if initial_points is not None:
        x0 = np.array(initial_points, dtype=np.float64)
        if x0.shape != (n_points, 3) or not np.isfinite(x0).all():
            raise RecoveryError(f"initial_points must be finite with shape ({n_points}, 3); got {x0.shape}.")
        fallback = x0.copy()
        starts = [("initial_points", x0)]
    try_greedy = False
    if initial_points is None:
        from .hinge_frames import hinge_frame_embedding

        frames = hinge_frame_embedding(surface, squared)
        x0, frames_rms = frames.points, _rms(_relative_residuals(frames.points, edges, squared))
        starts = [("hinge_frames", x0)]
        if not frames_rms <= max(tolerance, FRAMES_NEARLY_EXACT):
            # Inexact lengths: fit the frames to all hinges at once rather than chain them.
            synchronized = frames.synchronized()
            if _rms(_relative_residuals(synchronized, edges, squared)) < frames_rms:
                starts = [("hinge_frames", synchronized)]
            if reference_points is not None:
                reference = np.array(reference_points, dtype=np.float64)
                if reference.shape != (n_points, 3) or not np.isfinite(reference).all():
                    raise RecoveryError(
                        f"reference_points must be finite with shape ({n_points}, 3); got {reference.shape}."
                    )
                starts.append(("reference_points", reference))
                continuation_start = reference
            else:
                # The greedy wavefront is a last start, polished to the end only when a short
                # trial already fits better than the frames (with a reference pose it never did).
                try_greedy = True
    if anchor_points is not None:
        fallback = np.where(np.isfinite(anchor_points), anchor_points, fallback)

    def polish(start, budget, local):
        x, iterations, converged = _polish(start, edges, squared, has_edge, anchor_points, anchor_weight,
                                           length_scale, tolerance, budget, local=local)
        return [_rms(_relative_residuals(x, edges, squared)), x, iterations, converged]

    def finish(trial):
        """Polish a trial to the end (the remaining iteration budget)."""
        residual, x, iterations, converged = trial
        if converged or iterations >= max_iterations:
            return trial
        rest = polish(x, max_iterations - iterations, False)
        rest[2] += iterations
        return rest

    def prepared(start):
        if anchor_points is not None and initial_points is None:
            start = _align_components(start, anchor_points, labels, has_edge)
        start[~has_edge] = fallback[~has_edge]
        return start

    # Several starts are raced: a short trial each, the lowest residual goes on to the end.
    budget = min(START_TRIAL_ITERATIONS, max_iterations) if len(starts) > 1 or try_greedy else max_iterations
    trials = [(name, prepared(start), None) for name, start in starts]
    fits = _concurrently(lambda item: polish(item[1], budget, False), trials)
    trials = [item + (fit,) for item, fit in zip(trials, fits)]
    best = min(trials, key=lambda item: item[3][0])
    best = best[:3] + (finish(best[3]),)
    if try_greedy:
        graph = _Graph(n_points, edges, squared, _upward_tets(surface), surface.thickening_tetrahedra)
        greedy = _greedy_embedding(surface, graph, has_edge, _seed_order(surface))
        start = prepared(greedy.pos.copy())
        trial = polish(start, budget, True)
        if trial[0] < best[3][0]:
            trial = finish(trial)
        if trial[0] < best[3][0]:
            best = ("greedy", start, greedy, trial)
    if continuation_start is not None and best[3][0] > CONTINUATION_RESIDUAL:
        # Far from realizable: the fit stopped in the basin of its start. Deform the reference
        # pose gradually instead (its own lengths blended into the targets) and keep the better.
        def continued(schedule):
            fractions, steps = schedule
            x = _continuation(prepared(continuation_start.copy()), edges, squared, has_edge, anchor_points,
                              anchor_weight, length_scale, tolerance, fractions, steps)
            return polish(x, max_iterations, False)

        for trial in _concurrently(continued, CONTINUATION_SCHEDULES):
            if trial[0] < best[3][0]:
                best = ("continuation", continuation_start, None, trial)
    initializer, x0, greedy, (_, x, iterations, converged) = best
    if not converged:
        _warn_unconverged(x, edges, squared, iterations)
    unresolved = frames.unresolved if initializer == "hinge_frames" else None
    return _finish(x, edges, squared, n_base, x0, iterations, initializer, converged, greedy, n_comp_real,
                   unresolved=unresolved)


def _polish(x0, edges, squared, free, anchor_points, anchor_weight, length_scale, tolerance, max_iterations,
            local=False):
    rel = _relative_residuals(x0, edges, squared)
    if (np.sqrt(np.mean(rel * rel)) <= tolerance and not anchor_weight) or max_iterations <= 0:
        return x0, 0, True
    if local and not anchor_weight:
        # Repair first where the residual is concentrated (a boundary strip where round-off grew,
        # a point whose mirror side was decided late): a small LM on those points and a few rings
        # around them, the rest held fixed (which also fixes the gauge).
        bad = np.abs(rel) > max(tolerance, 10.0 * float(np.median(np.abs(rel))))
        region = np.zeros(x0.shape[0], dtype=bool)
        region[edges[bad].ravel()] = True
        for _ in range(LOCAL_REPAIR_RINGS):
            touching = region[edges[:, 0]] | region[edges[:, 1]]
            region[edges[touching].ravel()] = True
        region &= free
        if 0 < region.sum() <= LOCAL_REPAIR_FRACTION * free.sum():
            x1, it1, _ = _levenberg_marquardt(x0, edges, squared, region, length_scale=length_scale,
                                             tolerance=tolerance, max_iterations=max_iterations)
            rel1 = _relative_residuals(x1, edges, squared)
            if np.sqrt(np.mean(rel1 * rel1)) <= tolerance:
                return x1, it1, True
            x0 = x1
    x, iterations, converged = _levenberg_marquardt(
        x0, edges, squared, free, anchor_points=anchor_points, anchor_weight=anchor_weight,
        length_scale=length_scale, tolerance=tolerance, max_iterations=max_iterations,
    )
    return x, iterations, converged


def _warn_unconverged(x, edges, squared, iterations):
    """The public embedders' warning for a fit that stopped before converging."""
    warnings.warn(
        f"Embedding: Levenberg–Marquardt stopped after {iterations} iterations without converging "
        f"(RMS relative length residual {_rms(_relative_residuals(x, edges, squared)):.3g}); the result "
        "is the best fit found. Increase max_iterations or check the recovered lengths.",
        ShapeDifferenceWarning,
        stacklevel=3,
    )


def _concurrently(function, items) -> list:
    """``[function(item) for item in items]``, in threads when there are several items and
    cores. For independent Levenberg–Marquardt fits: their sparse products and NumPy array
    arithmetic release the GIL (2 cores, truncated k = 100 / 200 lengths: embedding the 1,089-vertex
    cloth 2.4–2.6 → 2.2 s, a Blender flag 40 → 48 with its continuations 10.6 → 8.1–8.4 s). The
    results do not depend on it."""
    items = list(items)
    workers = min(len(items), os.cpu_count() or 1)
    if workers < 2:
        return [function(item) for item in items]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(workers) as pool:
        return list(pool.map(function, items))


def _continuation(x, edges, squared, free, anchor_points, anchor_weight, length_scale, tolerance, fractions,
                  iterations):
    """Deform ``x`` ``(N, 3)`` gradually towards ``squared``: ``iterations`` LM steps on its own
    squared lengths blended into the targets by each of ``fractions`` (the full step is the
    caller's)."""
    d = x[edges[:, 0]] - x[edges[:, 1]]
    own = np.einsum("ij,ij->i", d, d)
    for fraction in fractions:  # intermediate steps are capped: not converging there is expected
        x, _, _ = _polish(x, edges, (1.0 - fraction) * own + fraction * squared, free, anchor_points,
                          anchor_weight, length_scale, tolerance, iterations)
    return x


def _upward_tets(surface: OffsetSurface) -> np.ndarray:
    return surface.thickening_tetrahedra[: surface.centered_triangles.size]


def _seed_order(surface: OffsetSurface) -> np.ndarray:
    """Base vertices to try as star seeds: interior ones, valence 5–8 first (closest to 6), as
    stars of valence 4 can be ambiguous (a flat one folds along its two straight lines)."""
    base = surface.base
    valence = np.bincount(base.edges.ravel(), minlength=base.n_vertices)
    fan = np.bincount(base.triangles.ravel(), minlength=base.n_vertices)
    ok = (valence == fan) & (valence >= 3) & (valence <= MAX_SEED_VALENCE) & (surface.lift_of_vertex >= 0)
    candidates = np.flatnonzero(ok)
    v = valence[candidates]
    key = np.where((v >= 5) & (v <= 8), 0, 10) + np.abs(v - 6)
    # Central vertices first (fewer waves): eccentricity estimated by a double BFS sweep.
    eccentricity = _approximate_eccentricity(base)[candidates]
    return candidates[np.lexsort((eccentricity, key))]


def _approximate_eccentricity(base: MeshTopology) -> np.ndarray:
    """Per vertex, max hop distance to two far-apart vertices of its component (double sweep)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import shortest_path

    n = base.n_vertices
    e = base.edges
    graph = coo_matrix((np.ones(e.shape[0]), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    _, labels = _components(n, e)
    out = np.zeros(n)
    for label in np.unique(labels[base.used_vertices]):
        start = int(np.flatnonzero(labels == label)[0])
        d0 = shortest_path(graph, unweighted=True, directed=False, indices=start)
        a = int(np.argmax(np.where(np.isfinite(d0), d0, -1)))
        da = shortest_path(graph, unweighted=True, directed=False, indices=a)
        b = int(np.argmax(np.where(np.isfinite(da), da, -1)))
        db = shortest_path(graph, unweighted=True, directed=False, indices=b)
        rows = labels == label
        out[rows] = np.maximum(da[rows], db[rows])
    return out


def embed_base_edges(
    topology: MeshTopology,
    squared_lengths: np.ndarray,
    *,
    initial_vertices: np.ndarray,
    anchor: tuple[np.ndarray, float] | None = None,
    tolerance: float = 1e-8,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
) -> EmbeddingResult:
    """Intrinsic-only embedding (no offset layer): vertex positions ``(n, 3)`` whose edge lengths
    fit ``squared_lengths`` ``(E,)`` (for ``topology.edges``) in least squares, by
    Levenberg–Marquardt from ``initial_vertices`` ``(n, 3)``.

    Edge lengths alone do not determine the extrinsic shape (isometric bending, popping of
    vertices): the result is the fit nearest the start, not necessarily the original pose.
    ``anchor`` as in :func:`embed_thickening`. Loose vertices stay at their initial positions.
    """
    squared = _check_lengths(squared_lengths, topology.n_edges, "embed_base_edges")
    x0 = np.array(initial_vertices, dtype=np.float64)
    if x0.shape != (topology.n_vertices, 3) or not np.isfinite(x0).all():
        raise RecoveryError(f"initial_vertices must be finite with shape ({topology.n_vertices}, 3); got {x0.shape}.")
    anchor_points, anchor_weight = _anchor_array(anchor, topology.n_vertices, topology.n_vertices)
    edges = topology.edges
    free = np.zeros(topology.n_vertices, dtype=bool)
    free[edges.ravel()] = True
    length_scale = float(np.mean(np.sqrt(squared))) if squared.size else 1.0
    x, iterations, converged = _polish(x0, edges, squared, free, anchor_points, anchor_weight, length_scale,
                                        tolerance, max_iterations)
    if not converged:
        _warn_unconverged(x, edges, squared, iterations)
    return _finish(x, edges, squared, topology.n_vertices, x0, iterations, "initial_points", converged)


def refine_edge_lengths(vertices: np.ndarray, edges: np.ndarray, squared_lengths: np.ndarray, *,
                        anchor_weight: float, max_iterations: int, fixed: np.ndarray | None = None,
                        cg_iterations: int = CG_ITERATIONS) -> np.ndarray:
    """A few Levenberg–Marquardt steps moving ``vertices`` ``(n, 3)`` towards the squared edge
    lengths ``squared_lengths`` ``(E,)`` of ``edges`` ``(E, 2)``, each vertex softly anchored to
    its start (``anchor_weight`` per squared mean edge length, which also fixes the rigid gauge);
    ``fixed`` bool ``(n,)`` vertices stay. Returns the new positions ``(n, 3)``; no convergence
    is required (a polish of a pose that already nearly fits); ``cg_iterations`` caps each inexact
    Newton step."""
    x0 = np.asarray(vertices, dtype=np.float64)
    squared = np.asarray(squared_lengths, dtype=np.float64)
    free = np.zeros(x0.shape[0], dtype=bool)
    free[edges.ravel()] = True
    if fixed is not None:
        free &= ~fixed
    if not free.any():
        return x0.copy()
    length_scale = float(np.mean(np.sqrt(squared)))
    x, _, _ = _levenberg_marquardt(x0, edges, squared, free, anchor_points=x0, anchor_weight=anchor_weight,
                                   length_scale=length_scale, max_iterations=max_iterations,
                                   cg_iterations=cg_iterations)
    return x
