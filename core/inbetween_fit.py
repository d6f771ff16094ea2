"""The local/global (as-rigid-as-possible) fit of an in-between (paper §7.3 in local/global form):
the Poisson solve of target corner edges with the gap's anchor, and the local steps that re-fit
each triangle's rotation to the current positions while keeping the interpolated metric.

Edges are stored by coordinate — arrays (3 coordinates, 3 corners, m) whose (m,) rows are
contiguous, from the corner-major incidence ``Dc`` of :class:`core.inbetween_topology.Topology`
— because NumPy's element-wise work on rows of three interleaved numbers is 3–5× slower.
:class:`LocalGlobalFit` is mixed into :class:`core.inbetween_solver.Gap`, which provides
``topo``, ``base`` (a :class:`core.inbetween_keys.Key`), ``system`` (factor, anchor),
``tolerance``, ``change_tolerance``, ``mean_edge`` and ``place``.
"""

from __future__ import annotations

import numpy as np

from .geometry import coordinate_dot
from .inbetween_motion import RIGID_PLACEMENT_SCALE
from .sewn_seams import sewn_offsets
from .untold_triangles import borrowed_edges, told_donors, unfaced_triangles, untold_triangles

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
#: In large batches (:data:`core.inbetween_prediction.TRIMMED_TOLERANCE_BATCH`) the key-to-key
#: change behind the fit's stop leaves out its TOLERANCE_TRIM largest share: a few edges the
#: simulation collapses between the keys (folds forming) otherwise set it (10k drape, keys 16
#: apart: a tolerance of 3.61 % with them, 0.85 % without, and every fit stopped at its Poisson
#: solve). The whole change still sets the gap's anchor (see
#: :data:`core.inbetween_anchor.SMOOTH_ANCHOR_WEIGHT`), and a fit that ends with defects no repair
#: removes falls back to its step at that looser tolerance where the step is free of them.
TOLERANCE_TRIM = 0.01
#: The fit also stops when its misfit is below STALL_NEAR × the tolerance and fell by less than
#: STALL_FRACTION over the last two steps: the interpolated metric is not reachable there (the
#: anchor and the interpolated rotations hold it). 100k sheet over a cube edge: fits stalled at
#: 2.4 × the tolerance for five steps; stopping took 0.47–0.53 → 0.35–0.41 s per in-between with
#: every quality digit of the eight benchmark cloths unchanged (without the STALL_NEAR condition
#: the flag and the hanging sheet at g = 16 got worse: fits far from the tolerance still improve
#: the pose while their misfit barely moves).
STALL_FRACTION = 0.01
STALL_NEAR = 3.0
#: ... and wherever it is, when its misfit fell by less than FLAT_FRACTION over the last two steps.
FLAT_FRACTION = 1e-3
#: The fit's misfit (mean relative deviation of the edge lengths) measures an edge whose target
#: length is under this fraction of the gap's mean edge length by its deviation over that floor,
#: not over its own length: a fit places vertices to the mesh's scale, and an edge a thousand times
#: shorter than the others (near-duplicate vertices a voxel remesh and Decimate leave, a scanner's
#: doubled points) has a relative deviation no fit resolves. A body remeshed and decimated in
#: Blender (1,938 vertices) keeps five edges of 1.4e-5 mean edge lengths at the top of its head;
#: nodded 60° on its neck, their relative deviations (up to 1,766) made its fit 3.8 % off the
#: metric against the linear blend's 2.4 %, and two poses fell back, silently, to a fit near the
#: blend (1.06e-2 of the diagonal off the rig half-way, as the blend; 8.8e-4 with the floor).
MISFIT_LENGTH_FLOOR = 0.01
#: Vertices joined by edges shorter than this fraction of the key's mean edge length in every key,
#: in clusters no wider than it from one of their vertices in every key, are solved as one place
#: (:mod:`core.near_duplicates`). The fits stop at a mean relative misfit of METRIC_TOLERANCE at
#: best, so they place a vertex relative to its neighbours to about that share of a mean edge: an
#: edge shorter than it has a length and a direction no fit resolves, and the tiny and needle
#: triangles on such edges came out turned over against the motion (a body remeshed in Blender,
#: four vertices 1.4e-5 mean edges apart at its head: 39–99 of them in its sequences when left out
#: of the checks alone). Cloth simulations crush single edges to 1e-4–5e-4 of the mean edge in a frame
#: (tablecloth, lift_10k), but no benchmark bake holds one under this share in two keys; at 0.01
#: (the misfit's floor) two_sheets_10k's frames 44 and 48 did, a crushed fold, not a duplicate.
NEAR_DUPLICATE_SHARE = METRIC_TOLERANCE
#: Stop the iterations early when no vertex moved by more than this fraction of the mean edge.
ARAP_TOLERANCE = 1e-5
#: Largest angle between a triangle's fitted rotation and its interpolated one (radians); beyond
#: it the interpolated rotation is kept (keeps folds from flipping over during the fit).
MAX_ROTATION_DEVIATION = np.pi / 4
#: A triangle less high than this share of the gap's mean edge in both keys (the fits' floor,
#: :data:`MISFIT_LENGTH_FLOOR`) is untold (:mod:`core.untold_triangles`): its target edges are
#: those of the nearest told triangle's deformation and the local steps keep them; where it is also
#: lower than the noise of its rigid piece's keys in either key the checks do not count it flipped
#: or collapsed (the keys do not tell which way it faces). A 5.8k scan with 40 T-junction slivers
#: 1e-9–1e-5 of their side high, turned rigidly with 1e-6 noise: 5.8e-3 of its diagonal off at 0.5
#: with their own targets, 1.2e-6 (the noise's) with their donors'; exactly rigid, ×2: 9.7e-3 → 6e-13.
UNTOLD_HEIGHT = MISFIT_LENGTH_FLOOR
#: The local steps' per-triangle arithmetic runs in this precision: their edge targets carry
#: ~3e-7 relative error, far below the fit's tolerance (METRIC_TOLERANCE, 1e-3) and the
#: simulations' own edge noise, and the arrays they stream are half the size (100k sheet: 33 → 13.5
#: ms per local step). Positions, the Poisson solves and the checks stay in double precision; a
#: rigid motion never reaches a local step (its misfit is zero) and stays exact.
LOCAL_STEP_DTYPE = np.float32


def _stops(misfits: list, tolerance: float) -> bool:
    """Whether a fit with these ``misfits`` (per step) stops at ``tolerance``: within it, or
    stalled near it or anywhere without progress (not reachable from there; see
    :data:`STALL_FRACTION`)."""
    if misfits[-1] < tolerance:
        return True
    return len(misfits) > 2 and misfits[-1] > (1.0 - STALL_FRACTION) * misfits[-3] \
        and (misfits[-1] < STALL_NEAR * tolerance or misfits[-1] > (1.0 - FLAT_FRACTION) * misfits[-3])


def change_tolerance(base_lengths: np.ndarray, next_lengths: np.ndarray) -> float:
    """The whole change's tolerance of a gap between keys with corner edge lengths
    ``base_lengths`` and ``next_lengths`` (any matching shape): :data:`KEY_VARIATION_FRACTION` ×
    the mean relative change of the edges, at least :data:`METRIC_TOLERANCE`."""
    return max(METRIC_TOLERANCE, KEY_VARIATION_FRACTION * float(np.mean(_key_changes(base_lengths, next_lengths))))


def trimmed_tolerance(base_lengths: np.ndarray, next_lengths: np.ndarray) -> float:
    """The fit's tolerance of the gap of :func:`change_tolerance`: the same without the
    :data:`TOLERANCE_TRIM` largest share of the edges' changes (a partial sort of them: asked for
    only by batches that trim, see :data:`core.inbetween_prediction.TRIMMED_TOLERANCE_BATCH`)."""
    change = _key_changes(base_lengths, next_lengths)
    kept = int(len(change) * (1.0 - TOLERANCE_TRIM))
    trimmed = float(np.mean(np.partition(change, kept - 1)[:kept])) if kept > 0 else 0.0
    return max(METRIC_TOLERANCE, KEY_VARIATION_FRACTION * trimmed)


def short_edges(targets: np.ndarray, floor: float) -> np.ndarray:
    """Flat indices of the edges whose target lengths ``targets`` (any shape) are under ``floor``
    and not zero (see :data:`MISFIT_LENGTH_FLOOR`)."""
    return np.flatnonzero((targets < floor) & (targets > 0.0))


def floored_deviations(deviations: np.ndarray, lengths: np.ndarray, targets: np.ndarray, floor: float,
                       short: np.ndarray) -> None:
    """Set the relative deviations ``|ℓ / t − 1|`` (``deviations``, any shape, in place) of the
    edges ``short`` (flat indices, :func:`short_edges`) of ``lengths`` from ``targets`` (same
    shape) to ``|ℓ − t| / floor``; the others are left as they are."""
    if short.size:
        # np.put writes through to ``deviations`` whatever its layout (a reshape of a strided
        # slice would be a copy, and the floor lost)
        np.put(deviations, short, np.abs(lengths.reshape(-1)[short] - targets.reshape(-1)[short]) / floor)


def _key_changes(base_lengths: np.ndarray, next_lengths: np.ndarray) -> np.ndarray:
    """The edges' relative changes ``|ℓ₁ / ℓ₀ − 1|`` between two keys (flat)."""
    return np.abs(next_lengths / base_lengths - 1.0).ravel()


class LocalGlobalFit:
    """The Poisson solve and the local/global fit of a gap's in-betweens (see the module docstring)."""

    #: The local steps' largest turn away from the interpolated rotations (radians); a gap too
    #: rough to predict widens it while its in-betweens are solved
    #: (:data:`core.inbetween_prediction.ROUGH_ROTATION_DEVIATION`).
    rotation_limit = MAX_ROTATION_DEVIATION

    @property
    def untold(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(rows, donors, unfaced)``: of the triangles less high than :data:`UNTOLD_HEIGHT` × the
        mean edge in both keys, those that take their target edges from a told triangle (``rows``)
        and that triangle (``donors``; :mod:`core.untold_triangles`), and (bool (m,) ``unfaced``)
        those also less high in either key than twice their rigid piece's misfit over the gap's keys
        (the noise between keys of a rigid motion: :func:`core.untold_triangles.unfaced_triangles`),
        whose facing the keys do not tell; found once per gap."""
        untold = self.__dict__.get("_untold")
        if untold is None:  # made twice at worst by two threads: the same rows
            mask = untold_triangles(self.base, self.next, UNTOLD_HEIGHT * self.mean_edge)
            rows = donors = np.zeros(0, dtype=np.int64)
            unfaced = mask.copy()
            if mask.any():
                rows, donors = told_donors(self.topo.across, self.base.lengths, mask)
                known = [r for r in self.relatives if getattr(r, "misfits", None) is not None]
                noise = np.zeros(len(self.topo.components))
                if known:  # a rigid piece's misfit is the noise between its keys; a deforming one's is not
                    misfits = np.max([np.asarray(r.misfits) for r in known], axis=0)
                    rigid = np.max([r.nonrigidity for r in known], axis=0) < RIGID_PLACEMENT_SCALE
                    noise[rigid] = misfits[rigid]
                unfaced = unfaced_triangles(self.base, self.next, noise[self.topo.triangle_component]) & mask
            untold = self.__dict__["_untold"] = (rows, donors, unfaced)
        return untold

    def _borrowed(self, edges: np.ndarray, frames: np.ndarray, stretch: np.ndarray, rows=None) -> None:
        """Set the target edges ``edges`` (3 coordinates, 3 corners, r) of the untold triangles
        among ``rows`` (index array of the r triangles; None: all) whose donors are among them too to
        their donors' (:func:`core.untold_triangles.borrowed_edges`; ``frames`` (≥ 2 columns, 3
        coordinates, r) and ``stretch`` (r, 3) of the same rows)."""
        untold, donors, _ = self.untold
        if not untold.size:
            return
        if rows is None:
            at, by = untold, donors
        else:
            position = np.full(len(self.topo.triangles), -1)
            position[rows] = np.arange(len(rows))
            kept = (position[untold] >= 0) & (position[donors] >= 0)
            untold, donors = untold[kept], donors[kept]
            if not untold.size:
                return
            at, by = position[untold], position[donors]
        edges[:, :, at] = borrowed_edges(self.base.column_rows, self.base.tangent_rows, untold, donors,
                                         frames[:2, :, by], np.asarray(stretch)[by])

    def solve(self, edges: np.ndarray, guide: np.ndarray, system=None, s: float | None = None) -> np.ndarray:
        """Positions (n, 3) fitting corner ``edges`` (3 coordinates, 3 corners, m) and the anchor
        to ``guide`` (``system``: (factor, per-vertex anchor) other than the gap's own); in a gap
        with sewn seams, their groups together as at factor ``s`` (:mod:`core.sewn_seams`)."""
        lu, anchor = system or self.system
        rhs = np.empty((self.topo.n, 3))
        for d in range(3):
            rhs[:, d] = self.topo.Dct @ edges[d].ravel() + anchor * guide[:, d]
        return lu.solve(rhs) if s is None or self.sewn is None else lu.solve(rhs, sewn_offsets(self, s))

    def edges_of(self, x: np.ndarray, dtype=np.float64) -> np.ndarray:
        """Corner edge vectors of positions ``x`` (n, 3) by coordinate (3 coordinates, 3 corners,
        m) in ``dtype`` (the local steps': :data:`LOCAL_STEP_DTYPE`); see
        :meth:`core.inbetween_topology.Topology.corner_edge_rows`."""
        return self.topo.corner_edge_rows(x, dtype)

    def local_targets(self, frames: np.ndarray | None, stretch: np.ndarray, rows=slice(None), coordinates=None) -> dict:
        """The interpolated target edges ``R_T U_T e`` (r, 3, 3) of the triangles ``rows`` (a
        repair region; ``frames`` (k ≥ 2, r, 3) and ``stretch`` (r, 3) given for those;
        ``coordinates``: the base's tangent coordinates ``x``, ``y`` (r, 3 corners) of the rows' corner
        edges if the caller has them)."""
        if coordinates is None:
            coordinates = self.base.coordinates[rows]
            coordinates = coordinates[..., 0], coordinates[..., 1]
        x, y = coordinates  # (r, 3 corners) each
        s11, s12, s22 = stretch.T
        f0, f1 = frames[0].T, frames[1].T  # (3 coordinates, r)
        edges = np.empty((len(s11), 3, 3))
        # one (r,) row per corner and coordinate: broadcast across the (r, 3) and (r, 3, 3) blocks,
        # NumPy runs its inner loop over three values (2.5–6× slower at 1,500–15,000 triangles)
        for c in range(3):
            u = s11 * x[:, c]
            u += s12 * y[:, c]
            v = s12 * x[:, c]
            v += s22 * y[:, c]
            for d in range(3):
                edge = np.multiply(u, f0[d], out=edges[:, c, d])
                edge += v * f1[d]
        if self.untold[0].size:  # the untold triangles' targets are their donors' (on the rows that hold both)
            rows = None if isinstance(rows, slice) else np.asarray(rows)
            by_coordinate = edges.transpose(2, 1, 0)  # a view (3 coordinates, 3 corners, r)
            self._borrowed(by_coordinate, np.asarray(frames).transpose(0, 2, 1), stretch, rows)
        return {"edges": edges}

    def fit_targets(self, frames: np.ndarray | None, stretch: np.ndarray) -> dict:
        """What the Poisson solve and the local steps at one factor share, by coordinate: the
        metric's corner edges in the base's tangent coordinates ``u``, ``v`` (3 corners, m) and
        their lengths, the interpolated rotations' frames ``(3 columns, 3 coordinates, m)`` (None
        without extrinsic data) and the interpolated target edges ``R_T U_T e`` (3 coordinates,
        3 corners, m)."""
        x, y = self.base.tangent_rows
        s11, s12, s22 = np.ascontiguousarray(stretch.T)
        u, v = s11 * x + s12 * y, s12 * x + s22 * y
        out = {"u": u, "v": v, "lengths": np.sqrt(u * u + v * v), "frames": None, "inverse": self.base.inverse_rows}
        if frames is not None:
            f = out["frames"] = np.ascontiguousarray(frames.transpose(0, 2, 1))
            out["edges"] = f[0][:, None, :] * u + f[1][:, None, :] * v
            self._borrowed(out["edges"], f, stretch)  # the untold triangles' are their donors'
        return out

    @staticmethod
    def local_step_targets(targets: dict) -> dict:
        """What :meth:`fitted_edges` reads of ``targets``, in :data:`LOCAL_STEP_DTYPE`."""
        return {name: None if targets.get(name) is None else targets[name].astype(LOCAL_STEP_DTYPE)
                for name in ("u", "v", "frames", "edges", "inverse")}

    def fitted_edges(self, edges: np.ndarray, targets: dict, force=None) -> np.ndarray:
        """Corner edge targets (3, 3, m) of a local step from the current corner ``edges`` (3
        coordinates, 3 corners, m; ``targets`` from :meth:`fit_targets`, or
        :meth:`local_step_targets` of them, in whose precision the step runs): the interpolated
        metric turned by each triangle's rotation
        re-fitted to them (the orthonormal polar factor ``W = G (GᵀG)^-½`` of the 3×2 map ``G``
        from the base's tangent plane), or by the interpolated rotation where the two differ by
        more than :attr:`rotation_limit` or where ``force`` (bool (m,)) is set."""
        # a pose exaggerated far past its keys (×1000) has single-precision squared edges beyond
        # float32's range: the overflow is silenced here, and the caller warns about that pose
        with np.errstate(over="ignore", invalid="ignore"):
            return self._fitted_edges(edges, targets, force)

    def _fitted_edges(self, edges: np.ndarray, targets: dict, force) -> np.ndarray:
        """:meth:`fitted_edges`, floating-point errors as they are. Each product and sum is the
        one of the formulas in the comments, in their order (the same values); the results go into
        a few (m,) rows reused along the way, since a new array per operation costs the 100k sheet's
        step a third more time (10–12 against 14–16 ms, docs/inbetween-measurements.md, *The 50k / 100k
        sheets at g = 16*)."""
        i00, i01, i11 = targets["inverse"]  # upper triangular
        e1, e2 = edges[:, 0], edges[:, 2]  # the second side is −e2
        g0 = e1 * i00
        g1 = e1 * i01
        g1 -= e2 * i11  # e1 i01 + (−e2) i11
        c11, c12, c22 = coordinate_dot(g0, g0), coordinate_dot(g0, g1), coordinate_dot(g1, g1)
        row = np.empty_like(c11)  # one (m,) row for the products of the sums below
        # (GᵀG)^½ = (C + √det C · I) / √(tr C + 2 √det C) = [[a, b], [b, d]]; W = G · its inverse
        root_det = np.multiply(c11, c22)
        root_det -= np.multiply(c12, c12, out=row)
        np.maximum(root_det, 0.0, out=root_det)
        np.sqrt(root_det, out=root_det)
        scale = np.add(c11, c22)
        scale += np.multiply(2.0, root_det, out=row)
        np.maximum(scale, np.finfo(c11.dtype).tiny, out=scale)
        np.sqrt(scale, out=scale)
        a = np.add(c11, root_det, out=c11)
        a /= scale
        b = np.divide(c12, scale, out=c12)
        d = np.add(c22, root_det, out=c22)
        d /= scale
        det = np.multiply(a, d, out=root_det)
        det -= np.multiply(b, b, out=row)
        det[~(det > 0)] = 1.0  # before the division (see deformation_fields.sqrt_det)
        inverse_det = np.divide(1.0, det, out=scale)
        d *= inverse_det  # per triangle before per coordinate
        b *= inverse_det
        a *= inverse_det
        w0 = g0 * d
        w0 -= g1 * b  # g0 d − g1 b
        w1 = np.multiply(g1, a, out=g1)
        w1 -= np.multiply(g0, b, out=g0)  # g1 a − g0 b
        u, v = targets["u"], targets["v"]
        out = np.empty((3,) + u.shape, dtype=np.result_type(w0, u))
        corners = np.empty_like(u)
        for k in range(3):  # w0 u + w1 v, coordinate k of every corner
            np.multiply(w0[k], u, out=out[k])
            out[k] += np.multiply(w1[k], v, out=corners)
        if targets["frames"] is None:
            return out
        untold = self.untold[0]
        if untold.size:  # the untold triangles keep their donors' edges: their own fit turns them by the noise
            force = np.zeros(out.shape[-1], dtype=bool) if force is None else force.copy()
            force[untold] = True
        f0, f1 = targets["frames"][:2]
        # trace of the turn from the interpolated rotation [f0, f1, f0×f1] to [w0, w1, w0×w1]; by
        # Binet–Cauchy (w0×w1)·(f0×f1) = (w0·f0)(w1·f1) − (w0·f1)(w1·f0), no cross product needed
        p, q = coordinate_dot(w0, f0), coordinate_dot(w1, f1)
        trace = p + q
        trace += np.multiply(p, q, out=p)
        trace -= np.multiply(coordinate_dot(w0, f1, out=q), coordinate_dot(w1, f0, out=c11), out=q)
        far = ~(0.5 * (trace - 1.0) > np.cos(self.rotation_limit))
        if force is not None:
            far |= force
        far = np.flatnonzero(far)  # usually few: set by index (a mask over every triangle costs ~20× more)
        out[:, :, far] = targets["edges"][:, :, far]
        return out

    def misfit(self, edges: np.ndarray, targets: dict) -> float:
        """Mean relative deviation of the lengths of corner ``edges`` (3, 3, m) from the metric's,
        each edge's relative to its target length or, if longer, :data:`MISFIT_LENGTH_FLOOR` ×
        the gap's mean edge length."""
        # float32 squares of a pose exaggerated far past its keys (fitted_edges); a metric extrapolated
        # so far that its shrinking lengths underflow to zero gives an infinite misfit
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            lengths = np.sqrt(coordinate_dot(edges, edges))
            deviation = np.abs(lengths / targets["lengths"] - 1.0)
            floor = MISFIT_LENGTH_FLOOR * self.mean_edge
            short = targets.get("short")
            if short is None:  # found once per set of targets (a fit measures each of its steps)
                short = targets["short"] = short_edges(targets["lengths"], floor)
            floored_deviations(deviation, lengths, targets["lengths"], floor, short)
            return float(np.mean(deviation, dtype=np.float64))

    def fit(self, x, stretch, frames, guide, s, motion, iterations=ARAP_ITERATIONS, force=None, system=None,
            targets=None, misfits=None, looser=None):
        """Local/global fit of the interpolated metric ``stretch`` from ``x`` (``frames``: the
        interpolated rotations the fit may not stray far from; None: unconstrained), the
        iterations accelerated by Anderson mixing of the last :data:`ANDERSON_WINDOW` steps
        (Peng et al., TOG 2018: local/global steps converge slowly on the smooth part of the
        error, which the mixing extrapolates); stops once the edge lengths are within the gap's
        tolerance of the metric (see :data:`METRIC_TOLERANCE`), or within :data:`STALL_NEAR` × it
        and no longer improving (:data:`STALL_FRACTION`), and then returns its step of lowest
        misfit; ``targets``: ``fit_targets(frames,
        stretch)`` if the caller has them; ``misfits``: a list the misfit of each step is appended to;
        ``looser``: a list the first step where the fit would stop at ``self.change_tolerance`` is
        appended to (see :data:`TOLERANCE_TRIM`) when it goes on past it."""
        targets = self.fit_targets(frames, stretch) if targets is None else targets
        local = None  # the local steps' targets in single precision, made at the first step
        misfits = [] if misfits is None else misfits
        previous, step_changes, image_changes, best = None, [], [], None
        for _ in range(iterations):
            edges = self.edges_of(x, LOCAL_STEP_DTYPE)  # the misfit too: its tolerance is 1e-3
            misfits.append(self.misfit(edges, targets))
            best = (misfits[-1], x) if best is None or misfits[-1] < best[0] else best
            if _stops(misfits, self.tolerance):
                return best[1]  # a stalled fit whose last steps lost ground: its best step
            if looser is not None and not looser and _stops(misfits, self.change_tolerance):
                looser.append(x)
            local = self.local_step_targets(targets) if local is None else local
            image = self.solve(self.fitted_edges(edges, local, force), guide, system, s)
            image = image if system is not None else self.place(image, s, motion)
            residual = image - x
            step = np.max(np.abs(residual))
            if not np.isfinite(step) or step < ARAP_TOLERANCE * self.mean_edge:
                return image
            current = (residual.ravel(), image.ravel())
            if previous is not None:
                # the last ANDERSON_WINDOW changes of step and image, and the mixing weights by
                # least squares through their k × k normal equations (a pseudo-inverse drops
                # nearly parallel changes): no (3n, k) matrices formed
                step_changes = (step_changes + [current[0] - previous[0]])[-ANDERSON_WINDOW:]
                image_changes = (image_changes + [current[1] - previous[1]])[-ANDERSON_WINDOW:]
                gram = np.array([[a @ b for b in step_changes] for a in step_changes])
                gamma = np.linalg.lstsq(gram, np.array([a @ current[0] for a in step_changes]), rcond=None)[0]
                mixed = current[1].copy()
                for weight, change in zip(gamma, image_changes):
                    mixed -= weight * change
                image = mixed.reshape(-1, 3)
            previous = current
            x = image
        return x
