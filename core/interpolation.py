"""In-betweens and exaggerations by interpolating shape differences (paper §8.4, Figs. 14–15).

Public API (re-exported by :mod:`core`):

- :func:`interpolate` ``(vertices_a, vertices_b, triangles, factor)`` — one pose; ``factor`` 0 gives
  ``a``, 1 gives ``b``, 0.5 an in-between, 1.5 an exaggeration, negative values reverse the motion.
- :class:`Interpolator` — the same with the preparation (topology, factorization, per-triangle
  differences) done once for many factors.
- :class:`SequenceInterpolator` ``(key_poses, triangles)`` — in-betweens for every gap of a list of
  K key poses, ``pose(gap_index, factor)``; everything that depends on the topology or on one key
  is computed once, and the interpolation is C¹-smooth across keys (no popping between gaps).

Method
------
In the full basis the four shape differences of ``b`` relative to ``a`` are equivalent to the
metric of ``b`` (triangle areas and edge lengths, §4.2, Props. 1–2) and of its offset surface, i.e.
to the first fundamental form and to how every triangle turns relative to its neighbours
(the extrinsic part, §5.3). We interpolate exactly those two pieces of information, per triangle
``T`` (a 3×3 deformation gradient ``F_T = R_T U_T`` from ``a`` to ``b``, the triangle's unit normal
as third column, polar-decomposed):

- **intrinsic**: the stretch ``U_T`` (the metric tensor ``F_Tᵀ F_T = U_T²``, i.e. the triangle's
  area and edge lengths), interpolated log-Euclidean, ``U_T(s) = exp(s log U_T)``: exact at 0
  and 1, always positive definite (never negative lengths — the ill-posedness of linearly
  interpolated inner products that issue 3 measured), isometric motions stay isometric for every
  ``s`` including exaggerations;
- **extrinsic**: the rotation field ``R_T``, interpolated along geodesics of the rotation group
  (the short way round), ``R_T(s) = exp(s log R_T)``. A rigid motion is therefore
  interpolated rigidly (no chord shortcut, no shrinking; two-pose in-betweens of rotations by
  less than ~50° are pulled slightly towards the blend, see the anchor below).

Reconstruction (§7.3 in local/global form): positions minimizing
``Σ_T Σ_{edges ij of T} |x_j − x_i − R_T(s) U_T(s) (a_j − a_i)|² + λ Σ_v m_v |x_v − p_v|²``
(a Poisson solve with a tiny anchor ``λ`` to the placement guide ``p``), then a few
as-rigid-as-possible iterations that re-fit each triangle's rotation to the current positions
while keeping its interpolated metric ``U_T(s)`` — so that the result's edge lengths follow the
interpolated metric although the interpolated targets are never exactly realizable, and a final
polish of a few Levenberg–Marquardt steps on the interpolated metric's edge lengths (guarded
against flips). The normal matrix depends only on the topology: it is factorized once (sparse LU)
and every in-between costs a handful of back-substitutions. Two-pose in-betweens are also
anchored, per vertex, to the linear blend where the blend keeps the keys' edge lengths (there
the motion is locally a translation and the blend is accurate; see :data:`BLEND_ANCHOR_WEIGHT`);
this costs one more factorization per in-between.

Placement: each connected component's area-weighted centroid follows the cubic spline of the
keys' centroids (sequences), and its orientation is the interpolated rotation field's. Two-pose
in-betweens are placed by their anchor to the blend (the parts the blend moves accurately sit
where it puts them; the linear interpolation of the centroids where nothing is anchored).
Sequences interpolate the per-triangle rotations, stretches and centroids with cubic splines over
the neighbouring keys instead of linearly (Catmull–Rom tangents limited against overshoot: C¹
across keys where the motion is smooth; captures accelerating motion, e.g. cloth falling under
gravity).

Robustness: the result is checked for non-finite values, flipped triangles (a normal opposing
the interpolated normal ``R_T(s) n_T``) and collapsed ones; defects are first repaired locally
(the interpolated rotations, then the linear blend's, then the blend's rotations and stretches,
then each key's, imposed on a growing neighbourhood of them); if that fails, the
Poisson solve alone, the metric fitted near the linear blend (strongly anchored) and the linear
blend are tried in turn, the first without defects is returned, and if none is, the metric fit
with the fewest defects — each time with a :class:`~core.errors.ShapeDifferenceWarning` saying so.

Truncated bases (``k_M``/``k_N``): the target metric (edge lengths of ``b``) is recovered from the
truncated differences through :meth:`ReferenceShape.recover_metric` (convex recovery, §7.1–7.2)
and replaces the exact stretch of ``b``; the rotation field still comes from the poses. If the
recovery is unavailable or fails, the full-basis metric is used with a warning.
"""

from __future__ import annotations

import warnings
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial.transform import Rotation

from .errors import MeshError, ShapeDifferenceWarning
from .laplace_basis import basis_sizes
from .mesh_topology import check_nondegenerate, check_vertices, mesh_topology
from .validation import check_factor, check_gap_index, check_interpolation, check_sequence, check_time
from .small_matrices import cofactors_3x3

__all__ = ["interpolate", "Interpolator", "SequenceInterpolator"]

#: Weight of the positional anchor relative to the edge terms (per unit vertex mass, mean mass 1):
#: only fixes the translation gauge (placement is by centroids), so that rigid motions stay exact.
ANCHOR_WEIGHT = 1e-7
#: Local/global (as-rigid-as-possible) iterations after the Poisson solve.
ARAP_ITERATIONS = 10
#: Stop the iterations early when no vertex moved by more than this fraction of the mean edge.
ARAP_TOLERANCE = 1e-5
#: Largest angle between a triangle's fitted rotation and its interpolated one (radians).
MAX_ROTATION_DEVIATION = np.pi / 4
#: Anchor weight of the first fallback (metric fitted from the linear blend).
FALLBACK_ANCHOR_WEIGHT = 1e-1
#: A triangle whose area dropped below this fraction of its (interpolated) target area is collapsed.
COLLAPSE_RATIO = 1e-3
#: Repair rounds for a reconstruction with flipped or collapsed triangles: each imposes a rotation
#: field (see _Segment.pose) on the defects and this many vertex rings around the region imposed so
#: far. Measured on a 10k-vertex crumpling drape, keys 16 frames apart: one round of one ring left
#: 7 of 45 in-betweens to fallbacks (mean edge deviation 1.78 %), rounds (1, 1, 2, 4) 5 (1.72 %);
#: two-pose in-betweens at g = 4 / 16 (every 8th start) 1.46 / 3.10 % → 0.80 / 1.45 %. With the
#: blend and key passes, the round of 8 rings removed the last flipped triangle (keys 8 frames
#: apart: 1 of 49 in-betweens). The 1k scenes' results are unchanged.
REPAIR_RINGS = (1, 1, 2, 4, 8)
#: Final polish of a defect-free metric fit: Levenberg–Marquardt steps on the edge lengths of the
#: interpolated metric, anchored to the fit (weight per squared mean edge length). The local/global
#: fit leaves the lengths 0.2–1 % off the interpolated metric where the cloth crumples. On a 10k
#: crumpling drape (keys 16 frames apart) the polish (5 steps at weight 1e-2) with the blend
#: repair rounds below took the mean edge deviation from 1.72 to 1.31 % and the positional error
#: from 1.00 to 0.90 × the linear blend's (10 or 30 CG iterations per step: the same numbers).
POLISH_ITERATIONS = 5
POLISH_ANCHOR_WEIGHT = 1e-2
#: Conjugate-gradient iterations per polish step (inexact Newton steps suffice for a polish).
POLISH_CG_ITERATIONS = 10
#: Vertices held at the unpolished fit, in growing rings around triangles the polish flipped or
#: collapsed (the lengths alone do not see orientation); if defects remain, the fit is kept.
POLISH_GUARD_RINGS = (1, 2, 4)
#: Sequences: the spline tangent at the start of a gap is at most this multiple of the secant over
#: the gap, per element (Fritsch–Carlson's monotonicity bound). Unlimited Catmull–Rom tangents
#: overshot after the 10k drape's impact on the sphere (keys 8 frames apart: median RMS 1.23 × the
#: linear blend's; limited 0.95 ×).
TANGENT_LIMIT = 3.0
#: Two-pose in-betweens (0 < s < 1) are anchored to the linear blend where the blend keeps the
#: keys' edge lengths, i.e. where the motion is locally a translation and the blend is accurate:
#: per-vertex weight BLEND_ANCHOR_WEIGHT · (BLEND_SHORTENING_SCALE / max(shortening, scale))²
#: · max(0, 1 − shortening / BLEND_SHORTENING_CUTOFF)², with ``shortening`` the blend's mean
#: relative edge shortening around the vertex. Where the blend shortens edges (rotating parts: it
#: cuts the chord) the weight falls off and the interpolated rotations decide; beyond the cutoff
#: (10 %: parts turning by more than ~50°, e.g. any rigid rotation that large) they alone do.
#: Keys 4 / 8 / 16 frames apart, median RMS vs the blend (before → after, with the placement by
#: this anchor in _Segment.pose): drape 1.009 / 0.992 / 1.000 → 0.956 / 0.959 / 0.947, falling
#: sheet 1.011 / 1.026 / 0.961 → 0.951 / 0.993 / 0.956, flag 0.885 / 0.852 / 0.812 → 0.891 /
#: 0.797 / 0.953, hanging sheet 0.997 / 1.000 / 1.002 → 0.997 / 0.999 / 0.926; 10k drape 1.07 /
#: 1.01 / 0.99 → 0.98 / 0.99 / 0.99. Edge deviations within 0.05 points of before.
BLEND_ANCHOR_WEIGHT = 0.1
BLEND_SHORTENING_SCALE = 0.01
BLEND_SHORTENING_CUTOFF = 0.1
#: Per-segment caches kept by SequenceInterpolator.
SEGMENT_CACHE = 4


# ---------------------------------------------------------------------------------------------
# small batched linear algebra


def _frames(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Per-triangle frames ``[e1 | e2 | n]`` (m, 3, 3): two edge vectors and the unit normal."""
    p0 = vertices[triangles[:, 0]]
    e1 = vertices[triangles[:, 1]] - p0
    e2 = vertices[triangles[:, 2]] - p0
    n = np.cross(e1, e2)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    return np.stack([e1, e2, n], axis=2)


def _polar(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched polar decomposition ``F = R U`` (R proper rotation, U symmetric), (m, 3, 3) each."""
    u, _, vt = np.linalg.svd(f)
    d = np.sign(np.linalg.det(u @ vt))
    d[d == 0] = 1.0
    u = u * np.stack([np.ones_like(d), np.ones_like(d), d], axis=1)[:, None, :]
    r = u @ vt
    return r, np.transpose(r, (0, 2, 1)) @ f


def _rotation_part(f: np.ndarray, iterations: int = 8) -> np.ndarray:
    """Rotation of the polar decomposition of matrices with positive determinant (m, 3, 3), by
    the scaled Newton iteration X ← (γX + X⁻ᵀ/γ)/2 (Higham), ~10× faster than a batched SVD. The
    triangle frames used here are right-handed by construction, so ``det > 0``."""
    x = f
    for _ in range(iterations):
        cof, det = cofactors_3x3(x)
        bad = ~(det > 1e-300)
        det = np.where(bad, 1.0, det)
        inv_t = cof / det[:, None, None]
        gamma = np.sqrt(np.sqrt(np.einsum("kab,kab->k", inv_t, inv_t) / np.maximum(np.einsum("kab,kab->k", x, x), 1e-300)))
        new = 0.5 * (gamma[:, None, None] * x + inv_t / gamma[:, None, None])
        new[bad] = np.eye(3)
        x = new
    return x


def _sym_log(s: np.ndarray) -> np.ndarray:
    s = 0.5 * (s + np.transpose(s, (0, 2, 1)))
    w, q = np.linalg.eigh(s)
    return (q * np.log(np.maximum(w, 1e-8))[:, None, :]) @ np.transpose(q, (0, 2, 1))


def _sym_exp(s: np.ndarray) -> np.ndarray:
    s = 0.5 * (s + np.transpose(s, (0, 2, 1)))
    w, q = np.linalg.eigh(s)
    return (q * np.exp(np.clip(w, -30.0, 30.0))[:, None, :]) @ np.transpose(q, (0, 2, 1))


def _spline(values, s: float, cubic: bool):
    """Value at parameter ``s`` of the gap (0, 1) from the values at key times (−1, 0, 1, 2)
    (arrays of one shape, elementwise).

    ``cubic``: Hermite cubic with Catmull–Rom tangents ``(v₁ − v₋₁)/2`` and ``(v₂ − v₀)/2``, the
    first limited per element to :data:`TANGENT_LIMIT` × the secant ``v₁ − v₀`` over the gap: the
    velocity a gap inherits from the previous one, which a collision can stop abruptly (cloth
    landing on a collider; unlimited, the spline overshoots into the gap), whereas the velocity
    at the gap's end may legitimately be large (motion accelerating from rest). C¹ across keys
    where the limit is inactive; exact for quadratic motion. Otherwise linear."""
    before, start, end, after = values
    secant = end - start
    if not cubic:
        return start + s * secant
    limit = TANGENT_LIMIT * np.abs(secant)
    t0 = np.clip(0.5 * (end - before), -limit, limit)
    t1 = 0.5 * (after - start)
    s2, s3 = s * s, s * s * s
    return start + (3 * s2 - 2 * s3) * secant + (s3 - 2 * s2 + s) * t0 + (s3 - s2) * t1


# ---------------------------------------------------------------------------------------------
# topology-only preparation


class _Topology:
    """Everything that depends only on the triangles: edge incidence, the factorized normal
    matrix, components. ``mass`` (lumped vertex areas of the first pose, mean 1) weighs the anchor."""

    def __init__(self, triangles, n_vertices: int, first_pose: np.ndarray, anchor_weight: float):
        topo = mesh_topology(triangles, n_vertices)
        self.topology = topo
        self.n = n_vertices
        t = topo.triangles
        self.triangles = t
        m = t.shape[0]
        self.i = t[:, [0, 1, 2]].ravel()
        self.j = t[:, [1, 2, 0]].ravel()
        self.tri_of = np.repeat(np.arange(m), 3)
        rows = np.arange(3 * m)
        self.D = sp.csr_matrix(
            (np.r_[-np.ones(3 * m), np.ones(3 * m)], (np.r_[rows, rows], np.r_[self.i, self.j])), shape=(3 * m, n_vertices)
        )
        self.Dt = self.D.T.tocsr()
        p0 = first_pose[t[:, 0]]
        areas = 0.5 * np.linalg.norm(np.cross(first_pose[t[:, 1]] - p0, first_pose[t[:, 2]] - p0), axis=1)
        mass = np.bincount(t.ravel(), np.repeat(areas / 3.0, 3), n_vertices)
        used = mass > 0
        mass = mass / mass[used].mean()
        mass[~used] = 1.0  # loose vertices follow the placement guide
        self.mass = mass
        self.used = used
        self.weights = np.where(used, mass, 0.0)
        _, tri_labels = topo.components()
        labels = np.full(n_vertices, -1, dtype=np.int64)
        labels[t.ravel()] = np.repeat(tri_labels, 3)
        self.components = [np.flatnonzero(labels == c) for c in np.unique(tri_labels)]
        self._solvers: dict[float, object] = {}
        self._vertex_solver = None
        self.anchor_weight = anchor_weight
        # Unique edges and, per corner edge (the order of ``i``/``j``), its edge: corner edge k of a
        # triangle joins corners k and k+1, opposite corner k+2.
        self.edges = topo.edges
        self.edge_of_corner = topo.triangle_edges[:, [2, 0, 1]].ravel()
        self.corners_per_edge = np.bincount(self.edge_of_corner, minlength=topo.n_edges)
        self.corner_edges_per_vertex = (np.bincount(self.i, minlength=n_vertices)
                                        + np.bincount(self.j, minlength=n_vertices))

    def solver(self, weight):
        """Factorized normal matrix for an anchor ``weight``: a number (cached) or per-vertex
        weights (n,) (the last array is kept: one in-between's local/global iterations share it)."""
        if np.isscalar(weight):
            if weight not in self._solvers:
                self._solvers[weight] = spla.factorized((self.Dt @ self.D + sp.diags(weight * self.mass)).tocsc())
            return self._solvers[weight]
        if self._vertex_solver is None or self._vertex_solver[0] is not weight:
            self._vertex_solver = (weight, spla.factorized((self.Dt @ self.D + sp.diags(weight * self.mass)).tocsc()))
        return self._vertex_solver[1]

    def solve(self, edge_vectors: np.ndarray, guide: np.ndarray, weight) -> np.ndarray:
        """argmin_x Σ |x_j − x_i − d|² + Σ w_v m_v |x_v − guide_v|² for per-corner-edge ``d``
        (``weight`` a number or per-vertex (n,))."""
        rhs = self.Dt @ edge_vectors + (weight * self.mass)[:, None] * guide
        solve = self.solver(weight)
        return np.column_stack([solve(np.ascontiguousarray(rhs[:, k])) for k in range(3)])

    def centroid(self, x: np.ndarray, rows: np.ndarray) -> np.ndarray:
        w = self.weights[rows]
        return w @ x[rows] / w.sum()

    def place(self, x: np.ndarray, centroids: list[np.ndarray] | None) -> np.ndarray:
        if centroids is None:
            return x
        for rows, c in zip(self.components, centroids):
            x[rows] += c - self.centroid(x, rows)
        return x


class _Key:
    """Per-key data: positions, inverse triangle frames, unit normals, component centroids."""

    def __init__(self, topo: _Topology, vertices: np.ndarray, name: str):
        v = check_vertices(vertices, topo.n, name=name)
        check_nondegenerate(v, topo.triangles, name=name)
        self.vertices = v
        frames = _frames(v, topo.triangles)
        self.normals = frames[:, :, 2].copy()
        self.areas = 0.5 * np.linalg.norm(np.cross(frames[:, :, 0], frames[:, :, 1]), axis=1)
        self.frame_inverse = np.linalg.inv(frames)
        self.edge_vectors = v[topo.j] - v[topo.i]
        self.centroids = [topo.centroid(v, rows) for rows in topo.components]


class _Relative:
    """Differences of key ``other`` relative to the base key of a segment: per-triangle rotation
    vectors and log-stretches (the interpolated data), and the key's centroids and positions."""

    def __init__(self, topo: _Topology, base: _Key, other: _Key, stretch_override: np.ndarray | None = None):
        f = _frames(other.vertices, topo.triangles) @ base.frame_inverse
        r, u = _polar(f)
        # The short way round (angle ≤ π): the interpolated normal then never opposes both keys'
        # normals. (Choosing the way nearer the mesh's global rotation instead, for consistency
        # between neighbours turning by almost π, flipped hundreds of triangles on a flapping flag.)
        self.rotvec = Rotation.from_matrix(r).as_rotvec()
        self.log_stretch = _sym_log(u if stretch_override is None else stretch_override)
        self.centroids = other.centroids
        self.vertices = other.vertices

    @classmethod
    def identity(cls, topo: _Topology, base: _Key) -> "_Relative":
        self = cls.__new__(cls)
        m = topo.triangles.shape[0]
        self.rotvec = np.zeros((m, 3))
        self.log_stretch = np.zeros((m, 3, 3))
        self.centroids = base.centroids
        self.vertices = base.vertices
        return self

    @staticmethod
    def phantom(previous: "_Relative", current: "_Relative") -> "_Relative":
        """Linear extrapolation 2·current − previous (end condition of the spline)."""
        self = _Relative.__new__(_Relative)
        self.rotvec = 2 * current.rotvec - previous.rotvec
        self.log_stretch = 2 * current.log_stretch - previous.log_stretch
        self.centroids = [2 * c - p for c, p in zip(current.centroids, previous.centroids)]
        self.vertices = 2 * current.vertices - previous.vertices
        return self


class _Segment:
    """One gap between key ``base`` (s = 0) and the next key (s = 1), with the keys before and
    after it (real or phantom) for the cubic spline."""

    def __init__(self, topo: _Topology, base: _Key, nxt: _Key, relatives: list[_Relative], cubic: bool,
                 use_extrinsic: bool):
        self.topo, self.base, self.next = topo, base, nxt
        self.relatives = relatives  # at key times −1, 0, 1, 2 (relative to base)
        self.cubic = cubic
        self.use_extrinsic = use_extrinsic

    def _interpolate(self, s: float, attr: str):
        return _spline([getattr(rel, attr) for rel in self.relatives], s, self.cubic)

    def targets(self, s: float):
        stretch = _sym_exp(self._interpolate(s, "log_stretch"))
        rotation = Rotation.from_rotvec(self._interpolate(s, "rotvec")).as_matrix()
        centroids = [_spline([rel.centroids[c] for rel in self.relatives], s, self.cubic)
                     for c in range(len(self.topo.components))]
        guide = self._interpolate(s, "vertices")
        return rotation, stretch, centroids, guide

    def pose(self, s: float, *, iterations: int = ARAP_ITERATIONS) -> tuple[np.ndarray, str | None]:
        """(positions (n, 3), None) or, after a fallback, (positions, what happened)."""
        topo, base = self.topo, self.base
        rotation, stretch, centroids, guide = self.targets(s)
        weight = topo.anchor_weight
        if not self.cubic and 0.0 < s < 1.0:
            # Two-pose in-between: the anchor to the blend also places it (translating parts sit
            # where the blend puts them, turning parts hang from them: a sheet swinging about its
            # pins follows the arc, not the chord of its centroid), so no centroid placement.
            # Hanging sheet, keys 16 frames apart: 1.002 → 0.93 × the blend's error. (Where no
            # vertex is anchored, e.g. a rigid rotation by more than ~50°, centroids place it.)
            weights = self.anchor_weights(s)
            if weights.max() > topo.anchor_weight:
                weight, centroids = weights, None
        if self.use_extrinsic:
            x0 = topo.solve(np.einsum("kab,kb->ka", (rotation @ stretch)[topo.tri_of], base.edge_vectors), guide, weight)
            x0 = topo.place(x0, centroids)
        else:
            x0 = guide.copy()
        anchor = guide if not np.isscalar(weight) else x0.copy()  # the blend, or (gauge only) x0
        x = topo.place(self._arap(x0, stretch, rotation, anchor, weight, iterations), centroids)
        problem = self.check(x, s, rotation, stretch)
        if problem is None:
            return self.polish(x, s, rotation, stretch, centroids), None
        tried = [(self._badness(x, s), x)]
        # Repair: re-fit with rotations imposed on the defective triangles and a neighbourhood of
        # them that grows while defects remain (a local fix; most of the pose is kept): first the
        # interpolated rotations, then the linear blend's (integrable: they come from a mesh), and
        # where the interpolated metric cannot be realized there without a fold (cloth crumpled
        # below edge scale) the blend's stretches too, i.e. the blend's local geometry spliced in;
        # last, where the blend itself is folded, each key's own local geometry (nearer key first;
        # unflipped against that key by construction). 10k crumpling drape, keys 16 frames apart:
        # sequence fallbacks 5 → 0 of 45 in-betweens; two poses 12 flipped triangles → 0 over 24.
        blend = (1.0 - s) * base.vertices + s * self.next.vertices
        if self.use_extrinsic and np.isfinite(x).all():
            blend_rotation, blend_stretch = _polar(_frames(blend, topo.triangles) @ base.frame_inverse)
            keys = [(Rotation.from_rotvec(rel.rotvec).as_matrix(), _sym_exp(rel.log_stretch))
                    for rel in (self.relatives[1:3] if s < 0.5 else self.relatives[2:0:-1])]  # nearer first
            for imposed in ((rotation, stretch), (blend_rotation, stretch), (blend_rotation, blend_stretch), *keys):
                z = self._repair(x, anchor, weight, s, rotation, stretch, centroids, imposed, tried, iterations)
                if z is not None:
                    return self.polish(z, s, rotation, stretch, centroids), None
        repaired = list(tried)  # the metric fits, before any fallback
        # Fallback 1: the Poisson solve alone (rotations exactly the interpolated ones).
        if self.use_extrinsic and self.check(x0, s, rotation, stretch) is None:
            return x0, f"{problem}; returned the interpolated rotation field's Poisson solve without metric fit"
        tried.append((self._badness(x0, s), x0))
        # Fallback 2: fit the interpolated metric starting from, and strongly anchored to, the blend.
        y = self._arap(blend.copy(), stretch, None, blend, FALLBACK_ANCHOR_WEIGHT, iterations)
        if self.check(y, s, rotation, stretch, orientation=False) is None:
            return y, f"{problem}; used the interpolated metric fitted near the linear blend instead"
        tried.append((self._badness(y, s), y))
        if self.check(blend, s, rotation, stretch, orientation=False) is None:
            return blend, f"{problem}; the metric fit near the linear blend failed too, returned the linear blend"
        tried.append((self._badness(blend, s), blend))
        # No candidate is free of defects: keep the metric fit with the fewest rather than a
        # fallback that gives up the metric (on a crumpling 10k drape the linear blend had fewer
        # flipped triangles, 1 against 5, but 10 % edge deviation against 2–3 %: a visible pop).
        fits = [item for item in repaired if np.isfinite(item[0])] or tried
        defects, best = min(fits, key=lambda item: item[0])
        return best, (f"{problem}; every fallback has defects too, returned the metric fit with the fewest "
                      f"({defects:.0f} flipped or collapsed triangles)")

    def _repair(self, x, anchor, weight, s, rotation, stretch, centroids, imposed, tried, iterations):
        """Rounds of :data:`REPAIR_RINGS`: the rotations and stretches ``imposed`` (two (m, 3, 3))
        on the defects of ``x`` and rings around them; the first defect-free fit, else None (each
        fit appended to ``tried`` with its number of defects)."""
        topo = self.topo
        force = np.zeros(topo.triangles.shape[0], dtype=bool)
        z = x
        for rings in REPAIR_RINGS:
            defects = self.defects(z, s, rotation)
            if not defects.any():
                break
            force = self.grow(force | defects, rings)
            mask = force[:, None, None]
            field, metric = np.where(mask, imposed[0], rotation), np.where(mask, imposed[1], stretch)
            z = topo.place(self._arap(z, metric, field, anchor, weight, iterations, force=force), centroids)
            if self.check(z, s, rotation, stretch) is None:
                return z
            tried.append((self._badness(z, s), z))
        return None

    def anchor_weights(self, s: float) -> np.ndarray:
        """Per-vertex weights (n,) anchoring a two-pose in-between to the linear blend where the
        blend keeps the keys' edge lengths (see :data:`BLEND_ANCHOR_WEIGHT`)."""
        topo, a, b = self.topo, self.base.edge_vectors, self.next.edge_vectors
        key_lengths = (1.0 - s) * np.linalg.norm(a, axis=1) + s * np.linalg.norm(b, axis=1)
        shortening = np.abs(np.linalg.norm((1.0 - s) * a + s * b, axis=1) / key_lengths - 1.0)
        summed = np.bincount(topo.i, shortening, topo.n) + np.bincount(topo.j, shortening, topo.n)
        per_vertex = summed / np.maximum(topo.corner_edges_per_vertex, 1)
        falloff = (BLEND_SHORTENING_SCALE / np.maximum(per_vertex, BLEND_SHORTENING_SCALE)) ** 2
        weight = BLEND_ANCHOR_WEIGHT * falloff * np.maximum(0.0, 1.0 - per_vertex / BLEND_SHORTENING_CUTOFF) ** 2
        return np.maximum(weight, topo.anchor_weight)  # never below the gauge weight (nonsingular)

    def polish(self, x, s, rotation, stretch, centroids) -> np.ndarray:
        """``x`` (defect-free) moved closer to the interpolated metric's edge lengths by a few
        Levenberg–Marquardt steps; vertices around triangles the polish would flip or collapse
        are held (growing rings); ``x`` itself if defects remain."""
        from .edge_length_fit import refine_edge_lengths

        topo = self.topo
        corner = np.einsum("kab,kb->ka", stretch[topo.tri_of], self.base.edge_vectors)
        squared = np.bincount(topo.edge_of_corner, np.einsum("ij,ij->i", corner, corner),
                              topo.edges.shape[0]) / np.maximum(topo.corners_per_edge, 1)
        fixed = np.zeros(topo.n, dtype=bool)
        for rings in (0,) + POLISH_GUARD_RINGS:
            if rings:
                held = self.grow(self.defects(y, s, rotation), rings)
                fixed[topo.triangles[held].ravel()] = True
            y = topo.place(refine_edge_lengths(x, topo.edges, squared, anchor_weight=POLISH_ANCHOR_WEIGHT,
                                               max_iterations=POLISH_ITERATIONS, fixed=fixed,
                                               cg_iterations=POLISH_CG_ITERATIONS), centroids)
            if self.check(y, s, rotation, stretch) is None:
                return y
        return x

    def flipped(self, cross: np.ndarray, s: float, rotation: np.ndarray | None) -> np.ndarray:
        """Triangles (bool (m,)) whose normal ``cross`` opposes both keys' normals (in-betweens,
        0 ≤ s ≤ 1) or, for extrapolations, the interpolated normal ``R_T(s) n_T`` (else the
        nearer key's normal)."""
        if 0.0 <= s <= 1.0:
            return (np.einsum("ij,ij->i", cross, self.base.normals) < 0) & (
                np.einsum("ij,ij->i", cross, self.next.normals) < 0)
        if rotation is not None:
            return np.einsum("ij,ij->i", cross, np.einsum("kab,kb->ka", rotation, self.base.normals)) < 0
        return np.einsum("ij,ij->i", cross, (self.base if s < 0.5 else self.next).normals) < 0

    def defects(self, x, s, rotation) -> np.ndarray:
        """Flipped or collapsed triangles of ``x`` (bool (m,))."""
        t = self.topo.triangles
        cross = np.cross(x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]])
        collapsed = 0.5 * np.linalg.norm(cross, axis=1) < COLLAPSE_RATIO * self.base.areas
        return self.flipped(cross, s, rotation) | collapsed

    def grow(self, triangles: np.ndarray, rings: int) -> np.ndarray:
        """The triangles (bool (m,)) within ``rings`` vertex rings of ``triangles``."""
        t = self.topo.triangles
        for _ in range(rings):
            near = np.zeros(self.topo.n, dtype=bool)
            near[t[triangles].ravel()] = True
            triangles = near[t].any(axis=1)
        return triangles

    def _badness(self, x, s) -> float:
        """Number of defects, counting flips against both keys' normals whatever ``s``."""
        if not np.isfinite(x).all():
            return np.inf
        return float(self.defects(x, min(max(s, 0.0), 1.0), None).sum())

    def _arap(self, x, stretch, rotation, guide, weight, iterations, force=None):
        """Local/global fit of the interpolated metric ``stretch``: each triangle's rotation is
        re-fitted to the current positions, but replaced by the interpolated ``rotation`` where the
        two differ by more than :data:`MAX_ROTATION_DEVIATION` (keeps folds from flipping)."""
        topo, base = self.topo, self.base
        h = np.mean(np.linalg.norm(base.edge_vectors, axis=1))
        cos_max = np.cos(MAX_ROTATION_DEVIATION)
        for _ in range(iterations):
            r = _rotation_part(_frames(x, topo.triangles) @ base.frame_inverse)
            if rotation is not None:
                cos = 0.5 * (np.einsum("kab,kab->k", r, rotation) - 1.0)
                far = ~(cos > cos_max)
                if force is not None:
                    far |= force
                r[far] = rotation[far]
            new = topo.solve(np.einsum("kab,kb->ka", (r @ stretch)[topo.tri_of], base.edge_vectors), guide, weight)
            step = np.max(np.abs(new - x))
            x = new
            if not np.isfinite(step) or step < ARAP_TOLERANCE * h:
                break
        return x

    def check(self, x, s, rotation, stretch, orientation: bool = True) -> str | None:
        if not np.isfinite(x).all():
            return "the reconstruction produced non-finite coordinates"
        topo, base = self.topo, self.base
        frames = _frames(x, topo.triangles)
        cross = np.cross(frames[:, :, 0], frames[:, :, 1])
        area = 0.5 * np.linalg.norm(cross, axis=1)
        target_area = base.areas * np.abs(np.linalg.det(stretch))
        collapsed = int(np.sum(area < COLLAPSE_RATIO * target_area))
        if collapsed:
            return f"{collapsed} triangle(s) collapsed"
        # Flipped: the normal opposes both keys' normals (in-betweens) or the nearer key's
        # (extrapolations) and, with ``orientation``, the interpolated normal R_T(s) n_T too.
        flipped = int(np.sum(self.flipped(cross, s, rotation if orientation else None)))
        if flipped:
            return f"{flipped} triangle(s) flipped"
        return None


def _warn(message: str) -> None:
    warnings.warn(f"Shape-difference interpolation: {message}.", ShapeDifferenceWarning, stacklevel=3)


def _truncated_stretch(reference, other_vertices, k_M, k_N, topo, base_key):
    """Stretch tensors (m, 3, 3) of ``other`` relative to the base of ``reference`` (a callable
    returning the base's :class:`ReferenceShape`, built once per key) whose edge lengths are the
    ones recovered from the truncated intrinsic differences; None (with a warning) if unavailable."""
    try:
        base = reference()
        metric = base.recover_metric(base.shape_differences(other_vertices, k_M=k_M, k_N=k_N))
        squared = np.asarray(metric.base.squared_lengths, dtype=np.float64)
        edge_of_corner = base.topology.triangle_edges  # edge opposite each corner (compact)
    except Exception as error:  # noqa: BLE001 - any failure falls back to the full basis
        _warn(f"truncated recovery (k_M={k_M}, k_N={k_N}) failed ({error}); used the full-basis metric")
        return None
    if not (np.isfinite(squared).all() and (squared > 0).all()):
        _warn("truncated recovery returned non-positive squared lengths; used the full-basis metric")
        return None
    # Edge k of each triangle (corner k -> k+1) is opposite corner k+2.
    tri_sq = squared[edge_of_corner[:, [2, 0, 1]]]  # (m, 3): |e01|², |e12|², |e20|²
    return _stretch_from_lengths(base_key, topo, tri_sq)


def _stretch_from_lengths(base_key: _Key, topo: _Topology, tri_sq: np.ndarray) -> np.ndarray:
    """Symmetric stretch U (m, 3, 3) in the base key's frame whose metric U² gives the triangle's
    edges the squared lengths ``tri_sq`` (m, 3) (order e01, e12, e20); unit along the normal."""
    fr = np.linalg.inv(base_key.frame_inverse)
    e1, e2 = fr[:, :, 0], fr[:, :, 1]
    # Orthonormal tangent basis (t1, t2) and base edge coordinates in it.
    t1 = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
    t2 = np.cross(fr[:, :, 2], t1)
    edges = [e1, e2 - e1, -e2]
    coords = np.stack([np.stack([np.einsum("ij,ij->i", e, t1), np.einsum("ij,ij->i", e, t2)], 1) for e in edges], 1)
    a, b = coords[:, :, 0], coords[:, :, 1]
    system = np.stack([a * a, 2 * a * b, b * b], axis=2)  # (m, 3, 3) · (g11, g12, g22) = ℓ²
    g = np.linalg.solve(system, tri_sq[:, :, None])[:, :, 0]
    metric2 = np.stack([np.stack([g[:, 0], g[:, 1]], 1), np.stack([g[:, 1], g[:, 2]], 1)], 1)
    w, q = np.linalg.eigh(metric2)
    root2 = (q * np.sqrt(np.maximum(w, 1e-12))[:, None, :]) @ np.transpose(q, (0, 2, 1))
    basis = np.stack([t1, t2, fr[:, :, 2]], axis=2)  # (m, 3, 3) columns
    root3 = np.zeros_like(basis)
    root3[:, :2, :2] = root2
    root3[:, 2, 2] = 1.0
    return basis @ root3 @ np.transpose(basis, (0, 2, 1))


# ---------------------------------------------------------------------------------------------
# public API


class SequenceInterpolator:
    """In-betweens for every gap of K ≥ 2 key poses of one mesh (e.g. every 4th simulation frame).

    ``key_poses``: sequence of K arrays ``(n, 3)`` (or an array ``(K, n, 3)``); ``triangles`` int
    ``(m, 3)``. ``pose(gap_index, factor)`` returns float64 ``(n, 3)``: key ``gap_index`` at
    factor 0, key ``gap_index + 1`` at factor 1. ``len()`` is the number of gaps, K − 1.
    ``pose_at(time)`` takes a global time in key units (``time = gap_index + factor``).

    Rotations, stretches and centroids are interpolated with cubic splines over the neighbouring
    keys (``smooth=True``; linear with ``smooth=False``), so consecutive gaps join with matching
    velocity (unless a collision stopped the motion at the key, see :func:`_spline`). The
    topology and its factorization are built once; the data of each key and each gap on first
    use (the last few gaps are cached). ``k_M``/``k_N``/``offset``/``use_extrinsic`` as for
    :class:`Interpolator`.
    """

    def __init__(self, key_poses, triangles, *, k_M: int | None = None, k_N: int | None = None,
                 offset: float | None = None, use_extrinsic: bool = True, smooth: bool = True):
        key_poses, k_M, k_N, offset, use_extrinsic, smooth = check_sequence(key_poses, triangles, k_M, k_N, offset, use_extrinsic, smooth)  # noqa: E501
        keys = [np.asarray(k) for k in key_poses]
        if len(keys) < 2:
            raise MeshError(f"A sequence needs at least two key poses; got {len(keys)}.")
        first = check_vertices(keys[0], name="key pose 0")
        self._raw = keys
        self._topo = _Topology(triangles, first.shape[0], first, ANCHOR_WEIGHT)
        self._keys: dict[int, _Key] = {}
        self._segments: OrderedDict[int, _Segment] = OrderedDict()
        self._references: dict = {}
        self.k_M, self.k_N = basis_sizes(k_M, k_N)
        self.offset = offset
        self.use_extrinsic = bool(use_extrinsic)
        self.smooth = bool(smooth)

    def __len__(self) -> int:
        return len(self._raw) - 1

    @property
    def triangles(self) -> np.ndarray:
        return self._topo.triangles

    def _key(self, index: int) -> _Key:
        if index not in self._keys:
            self._keys[index] = _Key(self._topo, self._raw[index], f"key pose {index}")
        return self._keys[index]

    def _reference(self, index: int):
        """The truncated recovery's prepared base for key ``index`` (eigenbasis, Gram factor),
        shared by the relatives of its segment. Only the intrinsic metric is recovered (the
        rotations come from the poses), so no offset surface is built."""
        if index not in self._references:
            from .reference_shape import ReferenceShape

            self._references.clear()  # one base at a time: segments are visited per base key
            self._references[index] = ReferenceShape(self._raw[index], self._topo.triangles, offset=self.offset,
                                                      use_extrinsic=False)
        return self._references[index]

    def _relative(self, base: int, other: int) -> _Relative:
        stretch = None
        if self.k_M is not None:
            stretch = _truncated_stretch(lambda: self._reference(base), self._raw[other], self.k_M, self.k_N,
                                         self._topo, self._key(base))
        return _Relative(self._topo, self._key(base), self._key(other), stretch)

    def _segment(self, gap: int) -> _Segment:
        if gap in self._segments:
            self._segments.move_to_end(gap)
            return self._segments[gap]
        topo, base = self._topo, self._key(gap)
        last = len(self._raw) - 1
        ident = _Relative.identity(topo, base)
        nxt = self._relative(gap, gap + 1)
        cubic = self.smooth and last >= 2
        if cubic:
            prev = self._relative(gap, gap - 1) if gap >= 1 else _Relative.phantom(nxt, ident)
            after = self._relative(gap, gap + 2) if gap + 2 <= last else _Relative.phantom(ident, nxt)
        else:
            prev = after = ident
        segment = _Segment(topo, base, self._key(gap + 1), [prev, ident, nxt, after], cubic, self.use_extrinsic)
        self._segments[gap] = segment
        while len(self._segments) > SEGMENT_CACHE:
            self._segments.popitem(last=False)
        return segment

    def pose(self, gap_index: int, factor: float) -> np.ndarray:
        """The pose at ``factor`` in gap ``gap_index`` (key ``gap_index`` → ``gap_index + 1``)."""
        gap_index, factor = check_gap_index(gap_index, len(self)), check_factor(factor)
        gap = int(gap_index)
        if not 0 <= gap < len(self):
            raise IndexError(f"gap_index {gap_index} out of range for {len(self)} gap(s).")
        s = float(factor)
        if not np.isfinite(s):
            raise ValueError(f"factor must be a finite number; got {factor!r}.")
        if s == 0.0:
            return self._key(gap).vertices.copy()
        if s == 1.0:
            return self._key(gap + 1).vertices.copy()
        x, problem = self._segment(gap).pose(s)
        if problem:
            _warn(f"pose at factor {s:g} of gap {gap}: {problem}")
        return x

    def pose_at(self, time: float) -> np.ndarray:
        """The pose at global ``time`` in key units (0 = first key, K − 1 = last key); times
        outside extrapolate the first or last gap."""
        time = check_time(time, len(self))
        gap = int(np.clip(np.floor(time), 0, len(self) - 1))
        return self.pose(gap, float(time) - gap)


class Interpolator:
    """Poses between (and beyond) two poses ``vertices_a`` (factor 0) and ``vertices_b`` (factor 1)
    of one mesh, prepared once: ``pose(factor)`` returns float64 ``(n, 3)``.

    ``k_M``/``k_N``: interpolate truncated shape differences (the metric of ``b`` is the one
    recovered from them); ``None`` = full basis. ``offset``: offset distance of the extrinsic
    differences (validated; the truncated recovery here needs only the intrinsic metric, the
    rotations come from the poses). ``use_extrinsic=False`` interpolates the intrinsic metric only
    (bending then follows the linear blend).
    """

    def __init__(self, vertices_a, vertices_b, triangles, *, k_M: int | None = None, k_N: int | None = None,
                 offset: float | None = None, use_extrinsic: bool = True):
        k_M, k_N, offset, use_extrinsic = check_interpolation([vertices_a, vertices_b], triangles, k_M, k_N, offset, use_extrinsic, names=("vertices_a", "vertices_b"))  # noqa: E501
        self._sequence = SequenceInterpolator(
            [vertices_a, vertices_b], triangles, k_M=k_M, k_N=k_N, offset=offset, use_extrinsic=use_extrinsic,
            smooth=False,
        )

    def pose(self, factor: float) -> np.ndarray:
        """0 → a, 1 → b, 0.5 in-between, 1.5 exaggeration, negative: the motion reversed."""
        factor = check_factor(factor)
        return self._sequence.pose(0, factor)


def interpolate(vertices_a, vertices_b, triangles, factor: float, *, k_M: int | None = None,
                k_N: int | None = None, offset: float | None = None, use_extrinsic: bool = True) -> np.ndarray:
    """One pose at ``factor`` between ``vertices_a`` (0) and ``vertices_b`` (1); see :class:`Interpolator`."""
    factor = check_factor(factor)
    return Interpolator(vertices_a, vertices_b, triangles, k_M=k_M, k_N=k_N, offset=offset,
                        use_extrinsic=use_extrinsic).pose(factor)
