"""The anchor of a gap's Poisson solve and fit: per-vertex weights ``w`` pulling each vertex toward
the guide (:mod:`core.inbetween_guide`) — the linear blend where it keeps the keys' edge lengths
for two poses, the keys' spline for sequences, the pins firmly — their factorizations, and the
weaker anchor of fits it holds off the metric. Mixed into :class:`core.inbetween_solver.Gap`,
whose data it reads (``topo``, ``base``, ``next``, ``relatives``, ``splines``, ``anchored``, ``left``,
``static``, ``riding``, ``riding_screws``, ``joints``, ``use_extrinsic``, ``tolerance``,
``change_tolerance``, ``_anchors``, ``_riding_motions``) with its other parts: the field
(``world_rotvec``, ``key_frames``, ``stretch``), the fit (``solve``, ``edges_of``, ``local_targets``, ``misfit``), the
pieces' ``motion`` and the guide's mid-gap strains. It sets ``weights``, ``co_moving``, ``system``, ``by_centroid``,
``anchor_weight`` and ``_mid_world_strains``."""

from __future__ import annotations

import numpy as np

from . import screw_motions
from .cached_property import cached_property
from .geometry import grouped_medians
from .inbetween_fit import LOCAL_STEP_DTYPE, METRIC_TOLERANCE
from .inbetween_motion import RIGID_PLACEMENT_SCALE, per_factor
from .inbetween_topology import GAUGE_WEIGHT
from .pcg import pcg
from .sewn_seams import sewn_factor

#: Two-pose interpolation anchors vertex ``v`` to the linear blend with weight
#: BLEND_ANCHOR_WEIGHT · (BLEND_SHORTENING_SCALE / max(c, scale))² · max(0, 1 − c / CUTOFF)², where
#: ``c`` is the blend's mean relative edge shortening around ``v`` at the middle of the gap (in
#: the world or with the component's rigid motion undone, see :meth:`Anchor.anchor_weights`). Where the
#: blend keeps the edge lengths (the neighbourhood translates) it is accurate, so parts that do not
#: move stay put, translating parts sit where the blend puts them, and parts turning about them
#: hang from them; where the blend shortens edges (rotating parts: it cuts the chord; 10 % is a
#: turn of ~50°) the weight vanishes and the interpolated rotations alone decide. In a component
#: that keeps its edge lengths and has pins, a translating part hangs from them instead
#: (:meth:`Anchor.hung_from_pins`): its translation comes from the turns between them.
BLEND_ANCHOR_WEIGHT = 0.1
BLEND_SHORTENING_SCALE = 0.01
BLEND_SHORTENING_CUTOFF = 0.1
#: An extrapolation judges the change of the edge vectors around a vertex with the keys' noise
#: taken out: noise and motion change them independently, so the change the motion makes is
#: √(c² − ν²), ``c`` the measured change and ``ν`` the one the noise alone makes on a part that
#: does not move, estimated as NOISE_CHANGE_RATIO × the median absolute deviation of the relative
#: changes of the edge lengths of the vertex's piece between the keys (turns keep lengths, so their
#: spread is the noise's; an even stretch is not taken for noise; noise-free keys give ν ≈ 0 and
#: the plain rule). For isotropic noise of deviation σ per coordinate an edge vector changes by 2σ
#: per coordinate: its length by a normal deviate (median |·| 0.674 · 2σ), the vector by a χ₃ one
#: (mean 1.596 · 2σ), so a still vertex's mean change is 1.596 / 0.674 = 2.37 × the former.
#: Judged on the plain change, the still part of a strip bent 100° with noise 3e-3 per coordinate
#: (its edges 0.05 change by 15–30 %) lost its anchor and moved with the bent part, 0.21 / 0.51 of
#: the diagonal off at × 1.5 / × 2; with the noise taken out it is 2.8e-3 / 4.0e-3 off. In-betweens judge
#: the blend's shortening, second order in the noise, and keep the plain rule.
NOISE_CHANGE_RATIO = 2.37
#: ... and the blend is taken with the component's rigid motion undone only where that motion also
#: takes the vertex to within this fraction of the component's diagonal of where it is: a part
#: that turns as the whole component does but about another pivot (the middle segment of a finger
#: curled by two equal joints) keeps its edge vectors once the turn is undone, yet the component's
#: screw motion carries it along the wrong path (curled 60° / 60°: 0.9 % of the diagonal off at
#: 0.5, edges 62 % off at × 2).
CO_MOVING_DRIFT = 0.01
#: ... and not at all at a vertex of a triangle whose blended edges make an angle whose cosine is
#: below this (143°) with the interpolated field's at the middle of the gap
#: (:meth:`Anchor.aliased_blend`): turned nearly opposite, which a fold's crumpling barely reaches.
#: On the 105 pair cells of 35 cloths only the two sheets at g = 16 changed (flips 130 → 127); at a
#: cosine of 0 four cells changed, three a little worse (the drag 1.056 → 1.057 × the blend).
ALIASED_BLEND_COSINE = -0.8
#: Anchor of the pinned vertices of a sequence (still in every key, or riding on an animated
#: object: :mod:`core.pins`), per vertex whatever its mass (the edge terms pull on a vertex per
#: edge, not per area): large enough that they stay put to ~1e-3 of the edge terms' pull (and are
#: then set exactly), small enough to leave the normal matrix well conditioned. Per unit mass, as
#: the other anchors, the pins of a flag whose triangles at its pole are 1/50 of the mean area were
#: held 50 × less firmly, missed their place by a tenth of those triangles' size and, set exactly
#: afterwards, turned slivers there over.
STATIC_ANCHOR_WEIGHT = 1e3
#: Sequences anchor every other vertex to the keys' per-vertex spline with this weight (per unit
#: vertex mass, relative to the unit edge terms of the graph Laplacian): shapes longer than about
#: 2π/√w ≈ 60 edges follow the spline, shorter ones the interpolated fields. Without it the fields
#: alone place the whole sheet and their small rotation errors add up along it (a flag pinned at
#: its pole: 1.09–1.27 × the RMS of the per-vertex Catmull–Rom spline; with it 0.96–1.11);
#: numbers for other weights in docs/inbetweens.md.
SEQUENCE_ANCHOR_WEIGHT = 1e-2
#: ... and with a stronger one in a gap where the motion is smooth: at the middle of the gap that
#: spline's corner edge lengths deviate from the keys' mean lengths by less than
#: SMOOTH_SPLINE_STRAIN (mean relative deviation) and by no more than the linear blend's (up to
#: METRIC_TOLERANCE: where the cloth barely moves both are ~1e-4 and their order is noise). A
#: spline that keeps the cloth's lengths is right at short wavelengths too: SMOOTH_ANCHOR_WEIGHT
#: where its deviation is within the fit's tolerance of the metric before trimming (the pull then
#: costs no more edge length than a fit stopped there, see :data:`core.inbetween_fit.TOLERANCE_TRIM`),
#: SMOOTH_NEAR_ANCHOR_WEIGHT elsewhere under SMOOTH_SPLINE_STRAIN (an isometric bend whose last
#: gap's spline deviates by 0.39 %: 0.1 there gave 0.25 % edge deviation, 3e-2 0.14 %). Keys 4
#: frames apart, RMS ÷ the Catmull–Rom
#: spline's: flag pinned at its pole 1.054 → 0.889, hanging sheet 1.009 → 0.936, falling sheet
#: 0.964 → 0.875 (with the start parabola); baked for a check, a soft 6,400-vertex flag 1.013 (3e-2
#: in every smooth gap: 1.035, 0.1: 0.999). Where the spline does not keep the lengths (keys 16
#: apart, turns: hanging sheet at g = 16, edge deviation 0.47 → 0.74 % with 3e-2 everywhere, bound
#: 0.47), or keeps them worse than the blend (an impact at a key: the spline overshoots; 50k
#: sheet, g = 4: 0.963 → 0.973 × without that condition), the gap keeps SEQUENCE_ANCHOR_WEIGHT.
#: So does a gap whose keys differ by a rigid motion (up to RIGID_PLACEMENT_SCALE, a sheet falling
#: flat): the fields reproduce it whatever the anchor, and a stronger one would cost a second
#: factorization (~1 s at 100k vertices) for nothing.
SMOOTH_ANCHOR_WEIGHT = 0.1
SMOOTH_NEAR_ANCHOR_WEIGHT = 3e-2
SMOOTH_SPLINE_STRAIN = 0.01
#: A sequence's in-between whose fit is held off the metric by the spline anchor — its misfit
#: still above HELD_MISFIT × the gap's tolerance and less than HELD_PROGRESS below where the fit
#: started — is solved again with the anchor weight HELD_ANCHOR_WEIGHT, and so are the other solved
#: in-betweens of its gap (the predicted ones interpolate their corrections, which must come from
#: one anchor; mixed, a gap of the 100k sheet was found too rough to predict and all seven solved).
#: The per-vertex spline of a swinging sheet cuts the chords of its arcs: the whole sheet is too
#: small, which the local steps cannot undo against a pull at every vertex (10k sheet hanging from
#: two corners, keys 16 apart: misfit 4.75 → 4.57 % over the fit, tolerance 0.25 %). Where the fit
#: converges the anchor stays (a flag pinned at its pole: its misfit halves; there the weak anchor
#: costs 20–70 % of RMS). HELD_MISFIT is 2.5 rather than 1.5 because the weak anchor costs a
#: factorization per sequence (0.7 s at 100k vertices) and the 50k / 100k sheets' fits held at
#: 1.6–2.1 × bought no RMS (100k at g = 4: 0.108–0.112 → 0.090–0.092 × the bake); 10k hanging sheet
#: at g = 8 0.773 → 0.883 × Catmull–Rom, tablecloth at g = 4 0.717 → 0.754.
HELD_MISFIT = 2.5
HELD_PROGRESS = 0.15
HELD_ANCHOR_WEIGHT = 1e-3
#: ... and only where letting the anchor go moves the fit's start toward the metric: the Poisson
#: solve with the weak anchor RELEASE_GAIN or more closer to the interpolated metric (misfit) than
#: the gap's own. Where it is not, the anchor is not what holds the fit (the interpolated rotations
#: of a crumpling cloth do), and the weak fit changes little for a factorization and a second fit
#: (a ball through a 15k curtain: 0.2 % closer, the weak fit 8 % below the held one; the fits held
#: on the benchmark and probe cloths where the weak anchor helps: 11–71 % closer). The weak solve is
#: estimated without its factorization: its difference from the gap's own solve by conjugate
#: gradients preconditioned with the gap's factor (the two matrices differ by the anchors'
#: diagonal: the preconditioned spectrum lies within [HELD_ANCHOR_WEIGHT ÷ the gap's weight, 1]) to
#: a residual of RELEASE_TOLERANCE, at most RELEASE_ITERATIONS. The estimate only decides against
#: RELEASE_GAIN: at 3e-2 the ratio of the two misfits is within 8e-4 of its value at 1e-3 on the
#: held fits of the benchmark (100k sheet at g = 16 0.6175 → 0.6174, 12 → 7 solves, 0.1 s; 10k
#: hanging sheet 0.4282 / 0.6068 → 0.4288 / 0.6076, 9 / 8 → 6 / 6), at 1e-1 within 7e-3 (5 / 4 / 4).
#: Numbers in docs/inbetweens.md, *Reconstruction*.
RELEASE_GAIN = 0.01
RELEASE_TOLERANCE = 3e-2
RELEASE_ITERATIONS = 50
#: An in-between of two poses moves a deforming component toward its centroid too where the blend
#: anchor holds only a small part of it: by the share ``(1 − a / CENTROID_ANCHOR_SHARE)²`` of the
#: way, ``a`` the component's mass-weighted anchor (weights relative to BLEND_ANCHOR_WEIGHT; none
#: past this share, and none on a component with a vertex still in both keys, which fixes its
#: place). A few vertices where the blend happens to keep edge lengths otherwise hold the whole
#: piece, and the interpolated rotations' errors grow along it (two sheets crumpling onto each
#: other, keys 16 frames apart: anchored on 0.1–0.7 % of their mass, one sheet's centroid 3–5 × the
#: blend's distance from the frame's, its shape as close as the blend's). The move is a translation
#: after the fit and its repairs (shapes, edge lengths and flipped triangles unchanged; moved at
#: every fit step, some banner pairs fell back to the blend, 4.59 → 5.19 % edge deviation at g = 8).
#: Two sheets at g = 16: 1.304 → 0.861 × the blend's RMS; numbers, losses (a swinging cape 0.922
#: → 0.974) and other shares in docs/inbetween-measurements.md, *Pieces the blend barely holds*.
CENTROID_ANCHOR_SHARE = 0.2


class Anchor:
    """The anchor's part of a gap: its weights per factor, their factorization and its pins."""

    def choose_anchor_weight(self) -> None:
        """Set a sequence's ``anchor_weight`` (:data:`SEQUENCE_ANCHOR_WEIGHT`, or where the motion is
        smooth :data:`SMOOTH_ANCHOR_WEIGHT` or :data:`SMOOTH_NEAR_ANCHOR_WEIGHT`) and
        ``_mid_world_strains``, the world spline's strains at the middle of the gap per triangle
        (or None), kept for :meth:`~core.inbetween_guide.Guide.turning_as_a_whole` (the same measure
        against the same reference)."""
        self.anchor_weight = SEQUENCE_ANCHOR_WEIGHT
        self._mid_world_strains = None
        if not self.anchored and max(self.relatives[2].nonrigidity) > RIGID_PLACEMENT_SCALE:
            reference = self.mid_gap_reference()
            self._mid_world_strains = self._triangle_strains(self.mid_world(), reference)
            strain = float(np.mean(self._mid_world_strains))
            if strain < SMOOTH_SPLINE_STRAIN and strain <= self.mid_gap_strain(
                    0.5 * (self.base.vertices + self.next.vertices), reference) + METRIC_TOLERANCE:
                self.anchor_weight = SMOOTH_ANCHOR_WEIGHT if strain < self.change_tolerance else SMOOTH_NEAR_ANCHOR_WEIGHT

    def select(self, s: float) -> None:
        """Set the anchor for factor ``s``: one pattern for in-betweens (0 < s < 1), one for
        extrapolations, each computed and factorized once (``weights``, ``co_moving``, ``system``
        and ``by_centroid``)."""
        between = 0.0 < s < 1.0
        if between not in self._anchors:
            topo = self.topo
            weights, co_moving, key = None, None, None
            if self.anchored:
                weights, co_moving = self.anchor_weights(between)
                if self.left is not None:  # a sequence's turning pieces: its gauge, as spline_weights
                    weights = self.gauge_on(weights, self.left)
                if self.static is not None:  # still in both keys: held there as firmly as in sequences
                    weights = self.pinned_weights(weights)
                    co_moving = co_moving & ~self.static
                # by value: the two fits of an Interpolator (core.two_pose_inbetweens) share their topology
                # and mostly their weights, and then one factorization
                key = ("anchored", weights.tobytes())
            else:  # sequences: one pattern for the whole sequence, factorized once
                # the spline in the world where a component deforms, with its interpolated rigid
                # motion undone where it moves rigidly (exact for rigid motions; mixed by its
                # rigidity as the centroid placement is), in the world for still vertices
                still = np.zeros(topo.n, dtype=bool) if self.static is None else self.static
                weights, co_moving, key = self.sequence_weights(), ~still, self.spline_key(self.anchor_weight)
            if weights is not None and not (weights > GAUGE_WEIGHT).any():
                weights = None
            w = np.full(topo.n, GAUGE_WEIGHT) if weights is None else weights
            system = (sewn_factor(topo, GAUGE_WEIGHT if weights is None else w, key, self.sewn), w * topo.mass)
            self._anchors[between] = (weights, co_moving, system, self.centroid_placement(w, between))
        self.weights, self.co_moving, self.system, self.by_centroid = self._anchors[between]

    def centroid_placement(self, weights: np.ndarray, between: bool) -> np.ndarray:
        """Per component (C,), the share of the move onto its placed centroid
        (:meth:`~core.inbetween_motion.PieceMotion.place`) under anchor ``weights`` (n,): 1 without
        an anchored vertex; for the in-betweens of two poses, ``(1 − a / CENTROID_ANCHOR_SHARE)²``
        up to that anchored share ``a`` of a component with no still vertex (see
        :data:`CENTROID_ANCHOR_SHARE`); 0 otherwise."""
        topo = self.topo
        rows, labels, count = topo.component_vertices, topo.component_labels, len(topo.components)
        anchored = np.bincount(labels, weights[rows] > GAUGE_WEIGHT, minlength=count) > 0
        shares = np.where(anchored, 0.0, 1.0)
        if self.anchored and between:
            still = self.still_components
            held = topo.component_sums(np.minimum(weights / BLEND_ANCHOR_WEIGHT, 1.0)) / topo.component_mass
            partly = anchored & ~still
            shares[partly] = np.maximum(0.0, 1.0 - held[partly] / CENTROID_ANCHOR_SHARE) ** 2
        return shares

    @cached_property
    def still_components(self) -> np.ndarray:
        """Per component (C,), whether one of its vertices is still in every key (``static``); made
        once per gap (read by every pose's centroid placement and seat hold)."""
        topo, count = self.topo, len(self.topo.components)
        if self.static is None:
            return np.zeros(count, dtype=bool)
        return np.bincount(topo.component_labels, self.static[topo.component_vertices], minlength=count) > 0

    def held(self, misfits: list) -> bool:
        """Whether a sequence's fit with these ``misfits`` (per step) was held off the metric by
        the spline anchor (see :data:`HELD_MISFIT`)."""
        return (self.anchor_weight > HELD_ANCHOR_WEIGHT and len(misfits) > 1
                and misfits[-1] > HELD_MISFIT * self.tolerance and misfits[-1] > (1.0 - HELD_PROGRESS) * misfits[0])

    def released(self, edges: np.ndarray, guide: np.ndarray, targets: dict) -> bool:
        """Whether letting the anchor go moves a held fit's start toward the metric (see
        :data:`RELEASE_GAIN`): the Poisson solve of corner ``edges`` toward ``guide`` with the anchor
        at :data:`HELD_ANCHOR_WEIGHT` (:meth:`weak_poisson_solve`) against the gap's own, both
        measured against the metric of ``targets`` (the fit's) in the local steps' precision. True
        without extrinsic data: fits start from the guide whatever the anchor."""
        if not self.use_extrinsic:
            return True
        own = self.solve(edges, guide)
        weak = self.weak_poisson_solve(guide, own)
        misfits = [self.misfit(self.edges_of(x, LOCAL_STEP_DTYPE), targets) for x in (own, weak)]
        return misfits[1] < (1.0 - RELEASE_GAIN) * misfits[0]

    def weak_poisson_solve(self, guide: np.ndarray, own: np.ndarray) -> np.ndarray:
        """The Poisson solve (n, 3) toward ``guide`` with the anchor at :data:`HELD_ANCHOR_WEIGHT`,
        from the gap's own solve ``own`` of the same edges and without the weak factorization:
        ``own + δ`` with ``(L + A_w) δ = (A_w − A)(guide − own)`` (``A``, ``A_w``: the anchors'
        diagonals), by conjugate gradients preconditioned with the gap's factor (see
        :data:`RELEASE_GAIN`)."""
        factor, anchor = self.system
        weak = self.spline_weights(HELD_ANCHOR_WEIGHT) * self.topo.mass
        change = (weak - anchor)[:, None] * (guide - own)
        change = change if self.sewn is None else factor.project(change)
        laplacian = self.topo.laplacian

        # the three coordinates as one system (the same matrix on each: its spectrum), so that each
        # iteration solves with the factor once for all three
        def weak_matrix(p):
            p = p.reshape(-1, 3)
            product = laplacian @ p + weak[:, None] * p
            # a sewn gap's solves keep its groups together: the iteration runs among such positions
            return (product if self.sewn is None else factor.project(product)).ravel()

        def preconditioner(r):
            return factor.solve(r.reshape(-1, 3)).ravel()

        delta = pcg(weak_matrix, change.ravel(), preconditioner, RELEASE_ITERATIONS, RELEASE_TOLERANCE)
        return own + delta.reshape(-1, 3)

    def weak_system(self) -> tuple:
        """(factor, per-vertex anchor) of the sequence's anchor at :data:`HELD_ANCHOR_WEIGHT` (pinned
        vertices as firmly as ever), factorized once per sequence."""
        w = self.spline_weights(HELD_ANCHOR_WEIGHT)
        return sewn_factor(self.topo, w, self.spline_key(HELD_ANCHOR_WEIGHT), self.sewn), w * self.topo.mass

    def sequence_weights(self) -> np.ndarray:
        """Per-vertex anchor weights (n,) of a sequence: the gap's ``anchor_weight``
        (:data:`SEQUENCE_ANCHOR_WEIGHT`, :data:`SMOOTH_NEAR_ANCHOR_WEIGHT` or
        :data:`SMOOTH_ANCHOR_WEIGHT`) to the keys' per-vertex spline (:meth:`spline_weights`)."""
        return self.spline_weights(self.anchor_weight)

    def spline_weights(self, weight: float) -> np.ndarray:
        """Per-vertex weights (n,) anchoring a sequence to the keys' per-vertex spline (in the
        co-moving frame): ``weight``, :data:`STATIC_ANCHOR_WEIGHT` where the vertex is pinned, and
        the gauge alone on the pieces of ``turning`` (a part of them turns far from the rest
        between the keys: :meth:`core.inbetween_whole_rotations.WholeRotations.turning`), which their interpolated
        rotations place: the spline cuts
        the chord of their curl (a closed tube curled 240° per gap at the tip, anchored at
        :data:`SEQUENCE_ANCHOR_WEIGHT`: 9–11 % of the diagonal off, at 1e-4 0.2–0.3 %, 1e-3 2 %)."""
        w = np.full(self.topo.n, weight)
        if self.turning is not None:
            w = self.gauge_on(w, self.turning)
        return self.pinned_weights(w)

    def gauge_on(self, weights: np.ndarray, pieces: np.ndarray) -> np.ndarray:
        """``weights`` (n,) with :data:`~core.inbetween_topology.GAUGE_WEIGHT` on the vertices of
        ``pieces`` (bool (C,)), in place; returned."""
        owner = self.topo.vertex_owner
        weights[(owner >= 0) & pieces[np.maximum(owner, 0)]] = GAUGE_WEIGHT
        return weights

    def spline_key(self, weight: float) -> tuple:
        """The key of the factorization of :meth:`spline_weights` at ``weight`` (one per weight and
        set of turning pieces in a sequence)."""
        return ("sequence", weight) if self.turning is None else ("sequence", weight, self.turning.tobytes())

    def pinned_weights(self, weights: np.ndarray) -> np.ndarray:
        """``weights`` (n,, per unit mass) with :data:`STATIC_ANCHOR_WEIGHT` per vertex on the
        pinned vertices (still and riding, :mod:`core.pins`)."""
        return weights if self.static is None else np.where(self.static, STATIC_ANCHOR_WEIGHT / self.topo.mass, weights)

    def pinned_positions(self, s: float) -> np.ndarray:
        """Where the pinned vertices (``static``) are at factor ``s`` ((p, 3), in their order):
        still ones where the base key has them, each riding set moved from there by its rigid
        motion's spline (:mod:`core.pins`)."""
        if self.riding is None:
            return self.base.vertices[self.static]
        return self.ride(self.base.vertices.copy(), s)[self.static]

    def ride(self, x: np.ndarray, s: float) -> np.ndarray:
        """``x`` (n, 3) with each riding set (:mod:`core.pins`) where the spline of its rigid motion
        puts it at factor ``s`` (in place; returned). The motions are computed once per factor (a
        pose's guide, its pins' prediction and its finish ask for the same)."""
        base = self.base.vertices
        rotations, translations = per_factor(self._riding_motions, s, lambda f: screw_motions.rigid_exps(self.riding_screws.at(f)))
        for rows, rotation, translation in zip(self.riding, rotations, translations):
            x[rows] = base[rows] @ rotation.T + translation
        return x

    def repair_anchor(self, free: np.ndarray) -> np.ndarray:
        """Anchor (per-vertex weight × mass) of the ``free`` vertices of a repair region: the
        gap's own for two poses; for sequences the gauge alone (a repair imposes a local field and
        the region's boundary fixes its place: a pull toward the spline would fight it; pinned
        vertices are never free, :class:`~core.inbetween_repair_regions.Region`)."""
        if self.anchored:
            return self.system[1][free]
        return GAUGE_WEIGHT * self.topo.mass[free]

    def anchor_weights(self, between: bool) -> tuple[np.ndarray, np.ndarray]:
        """Per-vertex weights (n,) anchoring to the linear blend where it keeps the keys' edge
        lengths (in-betweens) or, for extrapolations, where the edge vectors do not change beyond
        the keys' noise (a linear extrapolation is exact only for translating parts) (see
        :data:`BLEND_ANCHOR_WEIGHT`, :data:`NOISE_CHANGE_RATIO`), and per vertex whether the blend is taken in
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
        drift = np.linalg.norm(undone - self.base.vertices, axis=1) / self.base.diagonals[topo.vertex_owner]
        loose = topo.edges_per_vertex == 0  # no edge to judge by: with their owner where it takes them
        # a jointed piece's motion is its parent's composed with the relative one (core.inbetween_joints):
        # with it undone the blend follows the joints, where in the world it is their linear blend
        # (the last of three links bent +60° / −60° only translates: 4.5e-2 of the diagonal off at 0.5);
        # so does a piece of a body whose leader is jointed, which takes the leader's motion (a scissor
        # lift's platform plate, on its own translation 5.0e-2 of the diagonal off its bracket at 0.5)
        child = np.zeros(topo.n, dtype=bool)
        if self.joints is not None:
            owner = topo.vertex_owner
            hung = self.joints[0] >= 0
            if self.body_members is not None:
                hung[self.body_members] |= hung[self.bodies[self.body_members]]
            child = (owner >= 0) & hung[np.maximum(owner, 0)]
        co_moving = ((co_moving_change < BLEND_SHORTENING_SCALE) & ((co_moving_change < world_change) | loose | child)
                     & (drift < CO_MOVING_DRIFT))
        if between:
            change = np.where(co_moving, per_vertex(shortening(c)), per_vertex(shortening(b)))
        else:
            # the edge vectors' change with the keys' noise taken out in quadrature (noise and
            # motion change them independently; see NOISE_CHANGE_RATIO)
            change = np.where(co_moving, co_moving_change, world_change)
            change = np.sqrt(np.maximum(change ** 2 - self.noise_change(length_a, b) ** 2, 0.0))
        falloff = (BLEND_SHORTENING_SCALE / np.maximum(change, BLEND_SHORTENING_SCALE)) ** 2
        weight = BLEND_ANCHOR_WEIGHT * falloff * np.maximum(0.0, 1.0 - change / BLEND_SHORTENING_CUTOFF) ** 2
        stretch = per_vertex(np.abs(np.linalg.norm(b, axis=1) / length_a - 1.0))
        if between:
            weight *= self.chord_falloff(change, co_moving, per_vertex(length_a), stretch)
            if self.use_extrinsic:
                weight[self.aliased_blend()] = 0.0
        weight[self.hung_from_pins(stretch, co_moving)] = 0.0
        return np.maximum(weight, GAUGE_WEIGHT), co_moving

    def noise_change(self, length_a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Per vertex (n,), the mean relative change the keys' noise alone makes to the edge vectors
        around a vertex that does not move (see :data:`NOISE_CHANGE_RATIO`): that ratio × the
        median absolute deviation, over the vertex's owning component, of its corner edges'
        relative change of length from the base key's ``length_a`` (3m,) to the next key's corner
        edges ``b`` (3m, 3); 0 on vertices with no owner."""
        topo = self.topo
        labels, count = topo.vertex_component[topo.i], len(topo.components)
        change = np.linalg.norm(b, axis=1) / length_a - 1.0
        deviation = np.abs(change - grouped_medians(change, labels, count)[labels])
        noise = np.zeros(topo.n)
        rows = topo.vertex_owner >= 0
        noise[rows] = NOISE_CHANGE_RATIO * grouped_medians(deviation, labels, count)[topo.vertex_owner[rows]]
        return noise

    def hung_from_pins(self, stretch: np.ndarray, co_moving: np.ndarray) -> np.ndarray:
        """Vertices (bool (n,)) whose blend anchor in the world is let go because what joins them
        to the pins turns: the moving vertices (not pinned, not co-moving, in an edge) of a
        component that has a pinned vertex (:mod:`core.pins`: still in both keys) and keeps its
        edge lengths between the keys everywhere (``stretch``, each vertex's mean relative change
        of its edges' lengths, under :data:`~core.inbetween_fit.METRIC_TOLERANCE`). Such a component
        moves only by turning about its pins, so a part of it whose edge vectors do not change
        translates along the arcs of the turns between it and the pins, not along the blend's
        straight line (a strip folded +60° and −60° at two joints, base still: its end only
        translates, and anchored to the blend it was 3.7e-2 of the diagonal off at 0.5 with
        edges 6.6 % off, 0.28 at × 2); let go it hangs from the pins by the interpolated
        rotations. Parts that turn, mostly let go by the blend's shortening and
        :meth:`chord_falloff` already, are let go wholly (an arm bent 10° at the elbow of a still
        upper arm, the anchor its forearm kept: 2.7e-4 → 1.4e-6 of the diagonal off half-way).
        Cloth keeps its anchor: every edge of it changes length."""
        topo = self.topo
        if self.static is None or not topo.components:
            return np.zeros(topo.n, dtype=bool)
        rows, labels, count = topo.component_vertices, topo.component_labels, len(topo.components)
        worst = np.maximum.reduceat(stretch[topo.component_order], topo.component_starts)
        hung = (np.bincount(labels, self.static[rows], minlength=count) > 0) & (worst < METRIC_TOLERANCE)
        owner = topo.vertex_component
        return ((owner >= 0) & hung[np.maximum(owner, 0)] & ~co_moving & ~self.static
                & (topo.edges_per_vertex > 0))

    def aliased_blend(self) -> np.ndarray:
        """Vertices (bool (n,)) of a triangle whose edges the linear blend turns nearly opposite
        (over 143°: :data:`ALIASED_BLEND_COSINE`) to the interpolated field's half-way:
        a part turning by nearly a whole turn between the keys (a sheet rolled into a tube, its
        free edge turned by 315°), whose edges the blend barely shortens (a turn of 315° reads as
        one of −45°) while it cuts straight across the turn. Anchored there, the in-between of a
        sheet rolled by 5.5–6.2 rad came out 0.005–0.37 of its width off before the checks (the
        half roll exact to 1e-3 up to 5.3 rad)."""
        topo = self.topo
        motion = self.motion(0.5)
        frames = self.key_frames(self.world_rotvec(self.splines["rotvec"].at(0.5)), motion[0], columns=2)
        target = self.local_targets(frames, self.stretch(0.5))["edges"]  # (m, 3 corners, 3)
        blend = self.edges_of(self.linear_blend(0.5)).transpose(2, 1, 0)
        cosine = np.einsum("mcd,mcd->mc", target, blend) / np.maximum(
            np.linalg.norm(target, axis=2) * np.linalg.norm(blend, axis=2), np.finfo(float).tiny)
        aliased = (cosine < ALIASED_BLEND_COSINE).any(axis=1)
        return np.bincount(topo.triangles.ravel(), np.repeat(aliased, 3), minlength=topo.n) > 0

    def chord_falloff(self, change, co_moving, edge, stretch) -> np.ndarray:
        """Per vertex (n,), the share of the blend anchor kept where the blend cuts the chord of a
        turn: a vertex whose neighbourhood keeps its edge lengths between the keys (``stretch``,
        its mean relative change, under :data:`~core.inbetween_fit.METRIC_TOLERANCE`) and turns by
        θ (from the blend's shortening ``change`` = 1 − cos(θ/2)) is off the blend by
        ``|b − a| · change / (2 sin(θ/2))`` (the sagitta of its arc); beyond
        :data:`BLEND_SHORTENING_SCALE` of its mean edge length ``edge`` the anchor falls off with its
        square. An arm bent 20° at the elbow was 2.4e-3 of the diagonal off half-way (its forearm
        held near the chord, edges 1.2 % off), now 1.4e-4; 30°: 3.8e-3 → 4e-5. Co-moving vertices
        and deforming cloth keep their anchor: on cloth every edge changes length between keys, and
        applied there too the curtain at g = 8 went from 0.911 to 1.672 × the blend's error."""
        move = np.linalg.norm(self.next.vertices - self.base.vertices, axis=1)
        half = np.arccos(np.clip(1.0 - change, -1.0, 1.0))
        sagitta = np.where(half > 1e-6, move * change / np.maximum(2.0 * np.sin(half), 1e-12), 0.0)
        sagitta = np.where(co_moving | (stretch >= METRIC_TOLERANCE), 0.0, sagitta)
        error = sagitta / np.maximum(edge, np.finfo(float).tiny)
        return (BLEND_SHORTENING_SCALE / np.maximum(error, BLEND_SHORTENING_SCALE)) ** 2
