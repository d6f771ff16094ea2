"""The in-between solver objects (paper §7.3 in local/global form): per topology the factorized
normal matrix, per key its frames, per gap the splines of the deformation fields between its keys,
the anchor and the reconstruction of a pose at any factor.

``_Topology`` (triangles only) → ``_Key`` (one pose) → ``_Relative`` (a key seen from the base key
of a gap; both in :mod:`core.inbetween_keys`) → ``_Gap`` (splines of the relatives at key times
−1, 0, 1, 2 (:mod:`core.splines`) and ``pose(s)``: Poisson solve, local/global fit, checks and
repairs (:mod:`core.inbetween_repair`)). The public classes live in :mod:`core.interpolation`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import deformation_fields as df
from .geometry import coordinate_cross, coordinate_dot, lumped_vertex_areas, vertex_labels
from .inbetween_keys import _Key, _Relative
from .inbetween_repair import Region, Repair
from .splines import HermiteGap

#: Anchor weight (per unit vertex mass, mean mass 1, relative to the unit edge terms) that only
#: fixes the translation gauge of the Poisson solve: small enough to leave shapes exact to ~1e-7
#: of their size (placement is done afterwards), large enough to keep the matrix well conditioned.
GAUGE_WEIGHT = 1e-7
#: Local/global iterations after the Poisson solve, at most. They bring the edge lengths onto the
#: interpolated metric where the interpolated rotations are not integrable (crumpling cloth); the
#: numbers behind the count are in docs/inbetweens.md.
ARAP_ITERATIONS = 6
#: Past steps mixed by the Anderson acceleration of the local/global iterations.
ANDERSON_WINDOW = 3
#: The local/global fit stops when the mean relative deviation of its edge lengths from the
#: interpolated metric is below the larger of METRIC_TOLERANCE (the issue's additive slack of 0.1
#: point on edge deviation) and KEY_VARIATION_FRACTION × the mean relative change of edge lengths
#: between the gap's two keys: the simulated frames between two keys differ from any smooth
#: interpolation of their metrics by about that much, so fitting the interpolated metric closer
#: does not bring the pose closer to the frame (14k tablecloth, keys 8 frames apart, key-to-key
#: change 4.5 %: the Poisson solve alone is 0.70 × the blend's RMS, 6 fitting steps 0.75 ×; a
#: stiff 1k drape, keys 16 apart, change 0.5 %: the steps take the edge deviation 1.10 → 0.48 %).
METRIC_TOLERANCE = 1e-3
KEY_VARIATION_FRACTION = 0.5
#: Stop the iterations early when no vertex moved by more than this fraction of the mean edge.
ARAP_TOLERANCE = 1e-5
#: Largest angle between a triangle's fitted rotation and its interpolated one (radians); beyond
#: it the interpolated rotation is kept (keeps folds from flipping over during the fit).
MAX_ROTATION_DEVIATION = np.pi / 4
#: Two-pose interpolation anchors vertex ``v`` to the linear blend with weight
#: BLEND_ANCHOR_WEIGHT · (BLEND_SHORTENING_SCALE / max(c, scale))² · max(0, 1 − c / CUTOFF)², where
#: ``c`` is the blend's mean relative edge shortening around ``v`` at the middle of the gap (in
#: the world or with the component's rigid motion undone, see ``_Gap.anchor_weights``). Where the
#: blend keeps the edge lengths (the neighbourhood translates) it is accurate, so parts that do not
#: move stay put, translating parts sit where the blend puts them, and parts turning about them
#: hang from them; where the blend shortens edges (rotating parts: it cuts the chord; 10 % is a
#: turn of ~50°) the weight vanishes and the interpolated rotations alone decide.
BLEND_ANCHOR_WEIGHT = 0.1
BLEND_SHORTENING_SCALE = 0.01
BLEND_SHORTENING_CUTOFF = 0.1
#: Anchor weight (per unit vertex mass) of the vertices that sit still in every key of a sequence
#: (pinned cloth): large enough that they stay put to ~1e-3 of the edge terms' pull (and are then
#: set exactly), small enough to leave the normal matrix well conditioned.
STATIC_ANCHOR_WEIGHT = 1e3
#: Sequences anchor every other vertex to the keys' per-vertex spline with this weight (per unit
#: vertex mass, relative to the unit edge terms of the graph Laplacian): shapes longer than about
#: 2π/√w ≈ 60 edges follow the spline, shorter ones the interpolated fields. Without it the fields
#: alone place the whole sheet and their small rotation errors add up along it (a flag pinned at
#: its pole: 1.09–1.27 × the RMS of the per-vertex Catmull–Rom spline; with it 0.96–1.11);
#: numbers for other weights in docs/inbetweens.md.
SEQUENCE_ANCHOR_WEIGHT = 1e-2
#: Components without anchored vertices are placed by their centroid: along the screw motion of
#: their best rigid motion where they move rigidly (exact for any rigid motion, pieces turning
#: about a common pivot stay together), along the spline of the keys' centroids where they deform
#: (free-falling cloth: the centroid follows its own trajectory, not the rotation's arc), mixed
#: linearly in between by the component's non-rigidity (RMS misfit of the best rigid motion over
#: the gap's keys / the component's bounding-box diagonal) relative to this scale.
RIGID_PLACEMENT_SCALE = 1e-3


#: The splines of positions (their tangents are limited per point, see :class:`core.splines.HermiteGap`).
POSITIONS = ("vertices", "world", "centroids")


class _Topology:
    """What depends only on the triangles: edge incidence (``D``: corner edges × vertices), lumped
    vertex masses of the first pose (mean 1), components, and the factorized normal matrices."""

    def __init__(self, topo, first_pose: np.ndarray):
        n_vertices = first_pose.shape[0]
        self.n = n_vertices
        t = self.triangles = topo.triangles
        m = t.shape[0]
        self.i, self.j = t.ravel(), t[:, [1, 2, 0]].ravel()  # corner edge c of triangle k: row 3k + c
        rows = np.arange(3 * m)
        self.D = sp.csr_matrix((np.r_[-np.ones(3 * m), np.ones(3 * m)], (np.r_[rows, rows], np.r_[self.i, self.j])),
                               shape=(3 * m, n_vertices))
        self.Dt = self.D.T.tocsr()
        # the same incidence with rows corner-major (row c·m + k), for the fit's component-wise
        # arrays (3 coordinates, 3 corners, m): contiguous per coordinate and corner
        self.Dc = sp.csr_matrix((np.r_[-np.ones(3 * m), np.ones(3 * m)],
                                 (np.r_[rows, rows], np.r_[t.T.ravel(), t[:, [1, 2, 0]].T.ravel()])),
                                shape=(3 * m, n_vertices))
        self.Dct = self.Dc.T.tocsr()
        self.laplacian = (self.Dt @ self.D).tocsc()
        edges = df.corner_edges(first_pose, t)
        areas = 0.5 * np.linalg.norm(np.cross(edges[:, 0], edges[:, 2]), axis=1)
        mass = lumped_vertex_areas(t, areas, n_vertices)
        used = mass > 0
        self.mass = np.where(used, mass / mass[used].mean(), 1.0)  # loose vertices follow the guide
        self.weights = np.where(used, self.mass, 0.0)
        _, labels = topo.components()
        per_vertex = vertex_labels(t, labels, n_vertices)
        kept = np.unique(labels)
        self.components = [np.flatnonzero(per_vertex == c) for c in kept]
        self.triangle_component = np.searchsorted(kept, labels)
        self.vertex_component = np.where(per_vertex >= 0, np.searchsorted(kept, per_vertex), -1)
        self.all_in_one = len(self.components) == 1 and self.components[0].size == n_vertices  # no loose vertex
        self.triangles_per_vertex = np.bincount(t.ravel(), minlength=n_vertices)
        adjacency = sp.csr_matrix((np.ones(3 * m, dtype=bool), (t.ravel(), np.repeat(np.arange(m), 3))),
                                  shape=(n_vertices, m))
        self.vertex_triangles = adjacency  # (n, m): the triangles around each vertex
        self.edges_per_vertex = np.bincount(self.i, minlength=n_vertices) + np.bincount(self.j, minlength=n_vertices)
        self._uniform: dict[float, object] = {}

    def factor(self, weights: np.ndarray | float = GAUGE_WEIGHT, key=None):
        """Sparse LU of ``DᵀD + diag(w · mass)`` for per-vertex ``weights`` (n,) or one weight
        for all (cached per value, or per ``key`` for per-vertex weights). The matrix is symmetric positive definite: symmetric mode with
        a minimum-degree ordering of ``A + Aᵀ`` has about 60 % of the default ordering's fill
        and solves twice as fast."""
        uniform = np.isscalar(weights)
        cache = weights if uniform else key
        if cache is not None and cache in self._uniform:
            return self._uniform[cache]
        w = np.full(self.n, weights) if uniform else weights
        lu = spla.splu((self.laplacian + sp.diags(w * self.mass)).tocsc(), permc_spec="MMD_AT_PLUS_A",
                       diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        if cache is not None:
            self._uniform[cache] = lu
        return lu

    def centroid(self, x: np.ndarray, rows: np.ndarray) -> np.ndarray:
        w = self.weights[rows]
        return w @ x[rows] / w.sum()

    def apply_motion(self, x: np.ndarray, rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
        """``x`` (n, 3) with each component's rigid motion (C, 3, 3), (C, 3) applied (loose vertices
        unchanged)."""
        c = self.vertex_component
        if self.all_in_one:
            return x @ rotations[0].T + translations[0]
        out = x.copy()
        used = c >= 0
        out[used] = df.matmul(rotations[c[used]], x[used, :, None])[:, :, 0] + translations[c[used]]
        return out

    def undo_motion(self, x: np.ndarray, rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`apply_motion`."""
        inverse = np.transpose(rotations, (0, 2, 1))
        return self.apply_motion(x, inverse, -np.einsum("cab,cb->ca", inverse, translations))


class _Gap:
    """One gap between key ``base`` (s = 0) and key ``next`` (s = 1), prepared once: splines of
    the relatives at key times −1, 0, 1, 2, the target edges' constant factors, the anchor and
    its factorization. :meth:`poses` answers any factors."""

    def __init__(self, topo: _Topology, base: _Key, nxt: _Key, relatives: list[_Relative], cubic: bool,
                 use_extrinsic: bool, anchored: bool, static: np.ndarray | None = None):
        self.topo, self.base, self.next = topo, base, nxt
        self.relatives = relatives
        self.cubic, self.use_extrinsic = cubic, use_extrinsic
        spline = {name: HermiteGap([getattr(r, name) for r in relatives], cubic, rows=name in POSITIONS)
                  for name in ("rotvec", "log_stretch", "screw", "vertices", "world", "centroids")}
        self.splines = spline
        self.anchored = anchored
        self.static = static  # bool (n,): still in every key (pinned), or None
        self._anchors: dict[bool, tuple] = {}
        self.select(0.5)
        nonrigidity = np.max([r.nonrigidity for r in relatives], axis=0)
        self.rigidity = np.clip(1.0 - nonrigidity / RIGID_PLACEMENT_SCALE, 0.0, 1.0)
        self.mean_edge = float(np.mean(base.lengths))
        variation = float(np.mean(np.abs(nxt.lengths / base.lengths - 1.0)))
        self.tolerance = max(METRIC_TOLERANCE, KEY_VARIATION_FRACTION * variation)
        self.repair = Repair(self)

    def select(self, s: float) -> None:
        """Set the anchor for factor ``s``: one pattern for in-betweens (0 < s < 1), one for
        extrapolations, each computed and factorized once (``weights``, ``co_moving``, ``system``
        and ``placed_by_centroid``)."""
        between = 0.0 < s < 1.0
        if between not in self._anchors:
            topo = self.topo
            weights, co_moving, key = None, None, None
            if self.anchored:
                weights, co_moving = self.anchor_weights(between)
                if self.static is not None:  # still in both keys: held there as firmly as in sequences
                    weights = self.pinned_weights(weights)
                    co_moving = co_moving & ~self.static
            else:  # sequences: one pattern for the whole sequence, factorized once
                # the spline in the world where a component deforms, with its interpolated rigid
                # motion undone where it moves rigidly (exact for rigid motions; mixed by its
                # rigidity as the centroid placement is), in the world for still vertices
                still = np.zeros(topo.n, dtype=bool) if self.static is None else self.static
                weights, co_moving, key = self.sequence_weights(), ~still, "sequence"
            if weights is not None and not (weights > GAUGE_WEIGHT).any():
                weights = None
            w = np.full(topo.n, GAUGE_WEIGHT) if weights is None else weights
            system = (topo.factor(GAUGE_WEIGHT if weights is None else w, key), w * topo.mass)
            placed = [not (w[rows] > GAUGE_WEIGHT).any() for rows in topo.components]
            self._anchors[between] = (weights, co_moving, system, placed)
        self.weights, self.co_moving, self.system, self.placed_by_centroid = self._anchors[between]

    def sequence_weights(self) -> np.ndarray:
        """Per-vertex anchor weights (n,) of a sequence: :data:`SEQUENCE_ANCHOR_WEIGHT` to the
        keys' per-vertex spline (in the co-moving frame), :data:`STATIC_ANCHOR_WEIGHT` where the
        vertex is still in every key."""
        return self.pinned_weights(np.full(self.topo.n, SEQUENCE_ANCHOR_WEIGHT))

    def pinned_weights(self, weights: np.ndarray) -> np.ndarray:
        """``weights`` (n,) with :data:`STATIC_ANCHOR_WEIGHT` on the still vertices."""
        return weights if self.static is None else np.where(self.static, STATIC_ANCHOR_WEIGHT, weights)

    def repair_anchor(self, free: np.ndarray) -> np.ndarray:
        """Anchor (per-vertex weight × mass) of the ``free`` vertices of a repair region: the
        gap's own for two poses; for sequences only the still vertices' (a repair imposes a local
        field and the region's boundary fixes its place: a pull toward the spline would fight it)."""
        anchor = self.system[1][free]
        if self.anchored:
            return anchor
        gauge = GAUGE_WEIGHT * self.topo.mass[free]
        return gauge if self.static is None else np.where(self.static[free], anchor, gauge)

    def anchor_weights(self, between: bool) -> tuple[np.ndarray, np.ndarray]:
        """Per-vertex weights (n,) anchoring to the linear blend where it keeps the keys' edge
        lengths (in-betweens) or, for extrapolations, where the edge vectors do not change (a
        linear extrapolation is exact only for translating parts) (see
        :data:`BLEND_ANCHOR_WEIGHT`), and per vertex whether the blend is taken in
        the world or with its component's rigid motion undone (``self.co_moving``, bool (n,)):
        the latter where the vertex moves with that rigid motion (edge vectors around it within
        BLEND_SHORTENING_SCALE of the base's once it is undone) and the world leaves them less
        unchanged (bool (n,)). Parts that do not move are anchored in the world (exact: they stay
        put), a rigidly moving mesh with its motion undone (exact at every factor)."""
        topo = self.topo
        a = topo.D @ self.base.vertices  # corner edges (3m, 3)
        b = topo.D @ self.next.vertices
        undone = self.relatives[2].vertices
        c = (undone[topo.j] - undone[topo.i])
        length_a = np.linalg.norm(a, axis=1)

        def per_vertex(values):
            return (np.bincount(topo.i, values, topo.n) + np.bincount(topo.j, values, topo.n)) / np.maximum(
                topo.edges_per_vertex, 1)

        def shortening(other):
            return np.abs(np.linalg.norm(a + other, axis=1) / (length_a + np.linalg.norm(other, axis=1)) - 1.0)

        co_moving_change = per_vertex(np.linalg.norm(c - a, axis=1) / length_a)
        world_change = per_vertex(np.linalg.norm(b - a, axis=1) / length_a)
        co_moving = (co_moving_change < BLEND_SHORTENING_SCALE) & (co_moving_change < world_change)
        if between:
            change = np.where(co_moving, per_vertex(shortening(c)), per_vertex(shortening(b)))
        else:
            change = np.where(co_moving, co_moving_change, world_change)
        falloff = (BLEND_SHORTENING_SCALE / np.maximum(change, BLEND_SHORTENING_SCALE)) ** 2
        weight = BLEND_ANCHOR_WEIGHT * falloff * np.maximum(0.0, 1.0 - change / BLEND_SHORTENING_CUTOFF) ** 2
        return np.maximum(weight, GAUGE_WEIGHT), co_moving

    # --- the interpolated field at one factor

    def targets(self, s: float):
        """Interpolated rotations as the images of the base's tangent frames (``frames`` (3, m, 3):
        ``R_T t1``, ``R_T t2``, ``R_T n``), stretches (packed (m, 3)), the components' rigid
        motions (rotations (C, 3, 3), translations (C, 3)) and the guide positions (n, 3) at
        factor ``s``."""
        motion = self.motion(s)
        frames = self.key_frames(self.splines["rotvec"].at(s), motion[0])
        stretch = df.exp_stretch(self.splines["log_stretch"].at(s))
        if self.weights is None:  # a gauge only: the spline with the rigid motions undone
            return frames, stretch, motion, self.topo.apply_motion(self.splines["vertices"].at(s), *motion)
        guide = self.splines["world"].at(s)  # the keys' per-vertex spline (two poses: the linear blend)
        if self.co_moving.any():
            undone = self.topo.apply_motion(self.splines["vertices"].at(s), *motion)
            if self.anchored:
                mix = self.co_moving.astype(float)
            else:
                component = self.topo.vertex_component
                mix = self.co_moving * np.where(component >= 0, self.rigidity[component], 0.0)
            guide += mix[:, None] * (undone - guide)
        return frames, stretch, motion, guide

    def motion(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """The components' interpolated rigid motions at factor ``s``: rotations (C, 3, 3),
        translations (C, 3)."""
        motions = [df.rigid_exp(screw) for screw in self.splines["screw"].at(s)]
        return np.array([r for r, _ in motions]), np.array([t for _, t in motions])

    def key_frames(self, rotvec: np.ndarray, rotations: np.ndarray, rows=slice(None)) -> np.ndarray:
        """Frames (3, r, 3) of the rotations ``M_c · exp(rotvec)`` (``rotvec``: residuals (r, 3) of
        the triangles ``rows``, ``rotations``: the components' (C, 3, 3))."""
        return df.rotated_frames(rotvec, rotations, self.topo.triangle_component[rows], self.base.column_rows[:, :, rows])

    def solve(self, edges: np.ndarray, guide: np.ndarray, system=None) -> np.ndarray:
        """Positions (n, 3) fitting corner ``edges`` (3 coordinates, 3 corners, m) and the anchor
        to ``guide`` (``system``: (factor, per-vertex anchor) other than the gap's own)."""
        lu, anchor = system or self.system
        rhs = np.empty((self.topo.n, 3), order="F")
        for d in range(3):
            rhs[:, d] = self.topo.Dct @ edges[d].ravel() + anchor * guide[:, d]
        return lu.solve(rhs)

    def place(self, x: np.ndarray, s: float, motion) -> np.ndarray:
        """Components without anchored vertices moved to their interpolated centroid (see
        :data:`RIGID_PLACEMENT_SCALE`)."""
        rotations, translations = motion
        spline = self.splines["centroids"].at(s)
        for c, rows in enumerate(self.topo.components):
            if self.placed_by_centroid[c]:
                rigid = rotations[c] @ self.base.centroids[c] + translations[c]
                target = self.rigidity[c] * rigid + (1.0 - self.rigidity[c]) * spline[c]
                x[rows] += target - self.topo.centroid(x, rows)
        return x

    def edges_of(self, x: np.ndarray) -> np.ndarray:
        """Corner edge vectors of positions ``x`` (n, 3) by coordinate: (3 coordinates, 3 corners,
        m), each (m,) row contiguous (one sparse product per coordinate). The local steps work on
        these rows: 3–5× faster than on (m, 3, 3) blocks."""
        m = len(self.topo.triangles)
        coordinates = np.ascontiguousarray(x.T)
        out = np.empty((3, 3 * m))
        for d in range(3):
            out[d] = self.topo.Dc @ coordinates[d]
        return out.reshape(3, 3, m)

    def local_targets(self, frames: np.ndarray | None, stretch: np.ndarray, rows=slice(None)) -> dict:
        """The interpolated target edges ``R_T U_T e`` (r, 3, 3) of the triangles ``rows`` (a
        repair region; ``frames`` (3, r, 3) and ``stretch`` (r, 3) given for those)."""
        coordinates = self.base.coordinates[rows]
        x, y = coordinates[..., 0], coordinates[..., 1]
        s11, s12, s22 = (stretch[:, k, None] for k in range(3))
        u, v = s11 * x + s12 * y, s12 * x + s22 * y
        return {"edges": u[:, :, None] * frames[0][:, None, :] + v[:, :, None] * frames[1][:, None, :]}

    def fit_targets(self, frames: np.ndarray | None, stretch: np.ndarray) -> dict:
        """What the Poisson solve and the local steps at one factor share, by coordinate: the
        metric's corner edges in the base's tangent coordinates ``u``, ``v`` (3 corners, m) and
        their lengths, the interpolated rotations' frames ``(3 columns, 3 coordinates, m)`` (None
        without extrinsic data) and the interpolated target edges ``R_T U_T e`` (3 coordinates,
        3 corners, m)."""
        x, y = self.base.tangent_rows
        s11, s12, s22 = np.ascontiguousarray(stretch.T)
        u, v = s11 * x + s12 * y, s12 * x + s22 * y
        out = {"u": u, "v": v, "lengths": np.sqrt(u * u + v * v), "frames": None}
        if frames is not None:
            f = out["frames"] = np.ascontiguousarray(frames.transpose(0, 2, 1))
            out["edges"] = f[0][:, None, :] * u + f[1][:, None, :] * v
        return out

    def fitted_edges(self, edges: np.ndarray, targets: dict, force=None) -> np.ndarray:
        """Corner edge targets (3, 3, m) of a local step from the current corner ``edges`` (3
        coordinates, 3 corners, m): the interpolated metric turned by each triangle's rotation
        re-fitted to them (the orthonormal polar factor ``W = G (GᵀG)^-½`` of the 3×2 map ``G``
        from the base's tangent plane), or by the interpolated rotation where the two differ by
        more than :data:`MAX_ROTATION_DEVIATION` or where ``force`` (bool (m,)) is set."""
        i00, i01, i11 = self.base.inverse_rows  # upper triangular
        e1, e2 = edges[:, 0], -edges[:, 2]
        g0 = e1 * i00
        g1 = e1 * i01 + e2 * i11
        c11, c12, c22 = coordinate_dot(g0, g0), coordinate_dot(g0, g1), coordinate_dot(g1, g1)
        root_det = np.sqrt(np.maximum(c11 * c22 - c12 * c12, 0.0))
        scale = np.sqrt(np.maximum(c11 + c22 + 2.0 * root_det, np.finfo(float).tiny))
        # (GᵀG)^½ = (C + √det C · I) / √(tr C + 2 √det C) = [[a, b], [b, d]]; W = G · its inverse
        a, b, d = (c11 + root_det) / scale, c12 / scale, (c22 + root_det) / scale
        det = a * d - b * b
        det = np.where(det > 0, det, 1.0)
        w0 = (g0 * d - g1 * b) / det
        w1 = (g1 * a - g0 * b) / det
        out = w0[:, None, :] * targets["u"] + w1[:, None, :] * targets["v"]
        if targets["frames"] is None:
            return out
        f0, f1, f2 = targets["frames"]
        normal = coordinate_cross(w0, w1)
        trace = coordinate_dot(w0, f0) + coordinate_dot(w1, f1) + coordinate_dot(normal, f2)
        far = ~(0.5 * (trace - 1.0) > np.cos(MAX_ROTATION_DEVIATION))
        if force is not None:
            far |= force
        out[:, :, far] = targets["edges"][:, :, far]
        return out

    @staticmethod
    def misfit(edges: np.ndarray, targets: dict) -> float:
        """Mean relative deviation of the lengths of corner ``edges`` (3, 3, m) from the metric's."""
        lengths = np.sqrt(coordinate_dot(edges, edges))
        return float(np.mean(np.abs(lengths / targets["lengths"] - 1.0)))

    def fit(self, x, stretch, frames, guide, s, motion, iterations=ARAP_ITERATIONS, force=None, system=None,
            targets=None):
        """Local/global fit of the interpolated metric ``stretch`` from ``x`` (``frames``: the
        interpolated rotations the fit may not stray far from; None: unconstrained), the
        iterations accelerated by Anderson mixing of the last :data:`ANDERSON_WINDOW` steps
        (Peng et al., TOG 2018: local/global steps converge slowly on the smooth part of the
        error, which the mixing extrapolates); stops once the edge lengths are within the gap's
        tolerance of the metric (see :data:`METRIC_TOLERANCE`); ``targets``: ``fit_targets(frames,
        stretch)`` if the caller has them."""
        targets = self.fit_targets(frames, stretch) if targets is None else targets
        steps, images = [], []
        for _ in range(iterations):
            edges = self.edges_of(x)
            if self.misfit(edges, targets) < self.tolerance:
                break
            image = self.solve(self.fitted_edges(edges, targets, force), guide, system)
            image = image if system is not None else self.place(image, s, motion)
            residual = image - x
            step = np.max(np.abs(residual))
            if not np.isfinite(step) or step < ARAP_TOLERANCE * self.mean_edge:
                return image
            steps.append(residual.ravel())
            images.append(image.ravel())
            if len(steps) > 1:
                df_ = np.diff(np.array(steps[-ANDERSON_WINDOW - 1:]), axis=0).T
                dg = np.diff(np.array(images[-ANDERSON_WINDOW - 1:]), axis=0).T
                gamma = np.linalg.lstsq(df_, steps[-1], rcond=None)[0]
                image = (images[-1] - dg @ gamma).reshape(-1, 3)
            x = image
        return x

    def region(self, force: np.ndarray) -> Region:
        """The vertices all of whose triangles are in ``force`` (bool (m,)) with their block of
        the normal matrix factorized (a repair moves only those)."""
        return Region(self, force)

    def local_fit(self, x, region: Region, frames, stretch, guide) -> np.ndarray:
        """``x`` with the free vertices of ``region`` re-solved so that the region's corner edges
        fit the field (``frames`` (3, r, 3), ``stretch`` (r, 3) of the region's triangles), the
        rest of ``x`` held fixed. Every edge of the region is imposed (no local step), so one
        solve is the fit."""
        out = x.copy()
        if region.free.size:
            edges = self.local_targets(frames, stretch, region.rows)["edges"]
            out[region.free] = region.solve(edges, x, guide)
        return out

    def pose(self, s: float) -> tuple[np.ndarray, str | None]:
        """(positions (n, 3), None) or, after a fallback, (positions, what happened)."""
        self.select(s)
        frames, stretch, motion, guide = self.targets(s)
        fitted = frames if self.use_extrinsic else None
        targets = self.fit_targets(fitted, stretch)  # shared by the Poisson solve and the fit
        if self.use_extrinsic:
            x0 = self.place(self.solve(targets["edges"], guide), s, motion)
        else:
            x0 = self.place(guide.copy(), s, motion)
        x = self.fit(x0, stretch, fitted, guide, s, motion, targets=targets)
        return self.pinned(self.repair.checked(x, x0, s, frames, stretch, guide, motion))

    def repaired(self, x: np.ndarray, s: float) -> tuple[np.ndarray, str | None]:
        """``x`` (a pose at factor ``s`` with defects, e.g. a predicted one) repaired where the
        defects are, as :meth:`pose` repairs its fit (without solving the pose again)."""
        self.select(s)
        frames, stretch, motion, guide = self.targets(s)
        return self.pinned(self.repair.checked(x, x, s, frames, stretch, guide, motion))

    def pinned(self, result):
        """``(x, problem)`` with the sequence's still vertices exactly where they sit in the keys."""
        if self.static is not None:
            result[0][self.static] = self.base.vertices[self.static]
        return result

