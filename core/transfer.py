"""Poses of a differently meshed target rebuilt on the base's connectivity (paper §6.3, Fig. 15).

A :class:`Transfer` holds a base mesh M (a :class:`~core.reference_shape.ReferenceShape`), a
target connectivity N with a pose of it that locates it (its rest pose), and a point-to-point
correspondence from M to N (given, or built from closest points when the two overlap at rest).
For every pose of N it computes the source- and target-truncated shape differences of eq. (6)
on M and N through the functional maps of :mod:`core.functional_map`, recovers M's edge lengths
(§7.1–7.2) and fits the base mesh to them from the target pose carried to M through the map (each
base vertex at its image on the target), which gives the fit its bending. With
``use_extrinsic=True`` it also computes the extrinsic pair, on the offset surfaces M_t and N_t at
the base's offset distance t, and embeds the canonical thickening (§7.3) instead; off by default
because at k_M = 100 the offset layer's recovered lengths are noise on cloth (:class:`Transfer`).

Prepared once per transfer and reused for every frame: the base (its eigenbases, the recovery's
factorizations, the offset surface), the target's topology and offset surface, and the
correspondences of both layers. Per frame: the target's products and its two eigenbases (the
only target-side work), two small least-squares solves for the maps, the recovery, the
embedding.

The offset layers need their own correspondence: a lifted base vertex goes to the lifted target
vertex of its matched vertex (or the nearest lifted one, at the corners of a boundary, which have
no offset vertex), a base face center to the target face center nearest to the mean of its
corners' matches — both measured on the target's rest pose.

The target's layers, with their eigenbases per pose and the offset layers' correspondence, are in
:mod:`core.transfer_layers`; what a transfer refuses or warns about in the meshes and the
correspondence is in :mod:`core.transfer_checks`.
"""

from __future__ import annotations


import numpy as np

from .concurrency import per_layer_threads
from .delaunay_flips import MAX_DIHEDRAL_DEGREES, delaunay_flips
from .embedding import FRAMES_NEARLY_EXACT
from .errors import MeshError, warn
from .functional_map import (UNMATCHED, check_correspondence, closest_point_correspondence, nearest_matched,
                             project_near, pull_back_matrix, push_forward_matrix, reject_outlying_matches, walk_near)
from .laplace_basis import basis_sizes
from .mesh_topology import check_nondegenerate, check_vertices, mesh_topology, zero_area_triangles
from .seam_welds import oriented_pieces
from .transfer_checks import (TARGET_LABEL, WELD_DISTANCE, check_covered, check_matched_fraction, check_orientation,
                              check_overlap, check_spread, check_target_resolution, coincident_vertices,
                              degenerate_at_rest, mean_edge_length, warn_non_manifold, warn_outlying_matches)
from .transfer_layers import TargetLayer, offset_surfaces_pull_back
from .validation import check_basis_sizes, numerical_failures


#: Relative stopping tolerance of the recovery's iterative solvers (area CG, edge-length ADMM)
#: for transferred differences, instead of the same-mesh 1e-6 / 1e-5: their data carry the
#: change of mesh and the k_N truncation at the 1e-2 level. Measured on the re-meshed drape
#: (frames 20–22, k 100 / 200): Hausdorff/diagonal 4.08 / 4.28 / 4.81 % at the same-mesh
#: tolerances, 4.11 / 4.34 / 4.78 % at 1e-4; ADMM iterations on the offset surface 285–350 → 95–160,
#: area CG 1.2 → 0.3 s. 5k limb, frame 40 after 38 and 39: at 1e-4 ADMM 75 / 255 iterations (mesh /
#: offset surface) and 44.7 s for both programs, 4.63 %; at 3e-4 25 / 40 and 14.1 s, 4.44 %; at 1e-3
#: 10 / 15, 4.46 % (not taken: few triangles far off move a relative residual little).
RECOVERY_TOLERANCE = 3e-4
#: ADMM's initial penalty (in :func:`~core.admm.admm`'s units) for transferred differences,
#: instead of the same-mesh :data:`~core.admm.ADMM_RHO_SCALE` = 10: on the 5k limb's offset
#: surface (frame 38, cold) 90 iterations instead of 390, lengths 1.16 % (RMS relative) from a
#: run to 1e-5 (1,575 iterations) against 1.04 % at × 10, and the pose within 0.01 point of
#: Hausdorff (2.40 / 2.41 %); × 1,000 stopped as early, 3.6 % off. (At 1e-4 and × 100: 180
#: iterations, 0.63 %.)
#: Later poses start from the previous pose's penalty.
RECOVERY_RHO_SCALE = 100.0
#: The first pose is embedded by Levenberg–Marquardt from the target pose carried to the base
#: through the map (each base vertex at its image on the target), with its offset surface: that pose
#: is within the map's error of the answer, so the fit lands in a basin near it, without the race of
#: starts and continuations from the base pose (:func:`~core.embedding.embed_thickening`), whose
#: lowest residual was not always the right basin. Two such starts are fitted (in two threads), the
#: lower residual kept: the carried pose, and its projection on the base's k_M eigenfunctions (what
#: the truncated lengths resolve). Neither the start's residual nor a race of a few iterations
#: picks the same one (re-meshed 1k drape, frame 20: the carried start 0.106 against 0.150, and
#: lower after 3 iterations, but fitted 0.0319 / 5.61 % against the projection's 0.0317 / 2.85 %).
#: With ``warm_start`` every later pose starts from the previous pose's embedding moved with the
#: target (its offset from the previous carried pose, both rigidly aligned, added to this pose's
#: carried one): 5k cloth frames 41 / 42 in 3 iterations, 4.27 / 4.18 %, where the previous
#: embedding itself lagged (1k drape frame 23 after 20–22: 6.14 % against 4.67 %). When that
#: start's RMS relative length residual, or its fit's, exceeds this factor × the previous fit's (a
#: jump in the sequence: 1k drape frame 60 after 40, 0.064 against 0.027) the carried starts are
#: fitted instead (the lowest residual kept).
WARM_EMBEDDING_GROWTH = 1.5
#: The first Levenberg–Marquardt damping of these fits (relative, see
#: :func:`~core.edge_length_fit.levenberg_marquardt`; the same-mesh default 1e-6 suits starts at
#: round-off from the answer): their starts are a few percent off in lengths (the carried pose RMS
#: 0.09 on the 5k limb), where the nearly Gauss–Newton first steps were rejected at 300 CG iterations each. 5k limb,
#: frame 40: 12.5 s (22 iterations) → 7.9 s (17), the same residual 0.0167 and pose (2.67 / 2.66 %);
#: 1e-2 stopped on stagnation at residual 0.031, short of the fit.
EMBEDDING_DAMPING = 1e-3
#: These fits stop when an accepted Levenberg–Marquardt step lowers the misfit by less than this
#: fraction (the same-mesh :data:`~core.edge_length_fit.STAGNATION` is 1e-3). Transferred lengths
#: are not realizable (RMS relative residual 0.014 on the limb, 0.03 on cloth; on the 5k cloth the
#: simulated frame itself fits them at 0.14): past that point the fit trades a fraction of a
#: percent of misfit for moves along the directions the lengths barely constrain (bending of a
#: sheet), away from its start. 5k cloth frame 40 from the carried pose, Hausdorff / diagonal
#: (cost): 4.18 % (90.6) after 8 steps, 4.55 % (87.8) after 11 (where this stops), 5.20 % (78.1)
#: after 43 (where 1e-3 stopped), 5.96 % (74.6) after 150 and still falling.
EMBEDDING_STAGNATION = 1e-2
#: The intrinsic fit (the default, :meth:`Transfer._embed`) also stops once the RMS relative residual
#: of the base mesh's edge lengths is at most this: the recovered lengths are only that accurate
#: (RMS relative error 0.047–0.063 against the simulated frame's on the 1k drape and limb), and
#: past that point the fit moves the carried pose along what those errors ask. Cold, Hausdorff /
#: diagonal at this stop against the fit to convergence (~1e-3): decimated 1k drape frames 20 / 21 /
#: 22 / 40 / 60 2.23 / 1.91 / 2.00 / 1.73 / 1.57 % against 1.99 / 2.10 / 2.06 / 1.93 / 1.60 %, hostile
#: 20–22 2.10 / 1.98 / 2.20 % against 2.24 / 2.12 / 2.37 %, sampled 20–23 1.77 / 1.42 / 1.59 / 1.62 %
#: against 1.94 / 1.60 / 1.70 / 1.74 %; 1k limb sampled frames 10–40 1.22 / 1.81 / 2.62 / 3.21 %
#: against 1.27 / 1.96 / 2.67 / 3.20 %, hostile 1.40 / 1.50 / 1.91 / 2.80 % against 1.73 / 1.91 /
#: 2.20 / 2.72 %; 3–7 Levenberg–Marquardt steps instead of 13–40 (3e-3 lay in between).
INTRINSIC_EMBEDDING_TOLERANCE = 1e-2
#: :func:`target_size` takes a target within this relative difference of the base's size as the
#: base's size: measured through a vertex map, a target of the base's own size comes out 0.3–0.5 %
#: off (the 1k limb 0.9956 with its nearest-vertex map, 0.9972 with closest points; the test sheets
#: 1.0034; 0.987 with 8 % of the target's area cut out), and a target truly 1 % larger rebuilt
#: without the scaling is about as close to its truth (test sheets, RMS / largest vertex error over
#: the diagonal: 0.68 / 1.78 % against 0.72 / 1.58 % scaled); 5 % larger it is not (1.44 / 3.83 %).
#: On the benchmark's same-size targets taking the size as 1 moves the frames within the warm
#: solvers' tolerance, both ways (mean over 42 frames 1.987 → 1.988 %; docs/design-decisions.md).
SIZE_TOLERANCE = 0.01


class Transfer:
    """Rebuild poses of a target mesh N on the connectivity of a base mesh M (module docstring).

    ``base_vertices`` float ``(n_M, 3)`` and ``triangles`` int ``(m_M, 3)``: the base (manifold;
    a non-manifold base raises :class:`MeshError` naming its edges). ``target_rest_vertices``
    ``(n_N, 3)`` and ``target_triangles`` ``(m_N, 3)``: the target's connectivity and a pose of it
    that locates it — its rest pose (any pose works when a correspondence is given; it is then
    only used to match the offset layers). A few non-manifold target edges are accepted with a
    warning. ``correspondence`` int ``(n_M,)``: for every base vertex its matched target vertex,
    or -1 (:data:`~core.functional_map.UNMATCHED`) where the map has none — a partial map, such as
    :func:`core.template_correspondence` composes from two template maps; unmatched vertices take
    their images from matched neighbours (:data:`~core.transfer_checks.MIN_MATCHED_FRACTION`). ``None``: the nearest
    target vertex of ``target_rest_vertices``, for meshes that overlap at rest. ``k_M`` / ``k_N``: base and target basis sizes (required: a functional map between
    two meshes lives in truncated bases). ``offset``, ``use_extrinsic``: as for
    :class:`~core.reference_shape.ReferenceShape`. ``reference``: an existing prepared base to
    reuse (its eigenbases and factorizations). ``warm_start`` (default): :meth:`pose` starts its
    iterations (recovery programs, embedding) from the previous call's solutions, which pays for
    the frames of an animation taken in order; results then depend, within the solvers'
    tolerances, on the poses rebuilt before (the target eigenbases always do, see
    :data:`~core.transfer_layers.SUBSPACE_ITERATIONS`). ``False``: every pose's recovery starts from the base and its
    embedding from the target pose carried through the map (:data:`WARM_EMBEDDING_GROWTH`).
    ``size``: the target's size relative to the base through the map (:func:`target_size`);
    :meth:`pose` rebuilds at the base's size and scales back by it. ``target_name``: what the
    errors about the target's rest pose call it (the add-on: the source object's name);
    ``target_label``: what the warnings about the target mesh call it (default "the target mesh";
    the add-on: the source object).

    ``use_extrinsic=False`` (the default here, unlike the same-mesh pipeline): only the intrinsic
    pair is transferred, and the pose is the base mesh fitted to the recovered edge lengths from
    the target pose carried through the map, which alone decides its bending (:meth:`_embed`).
    Measured (docs/transfer.md, k_M = 100): the offset layer's recovered lengths are the weak part
    on cloth — re-meshed 1k drape, median relative error 6.6 % against 2.3 % for the mesh's, as bad
    with the exact same-mesh differences (the truncation, not the map) — and the thickening fitted
    to them lands 2.5–6.5 % from the target where this fit (stopped at
    :data:`INTRINSIC_EMBEDDING_TOLERANCE`) lands at 1.0–2.3 % (5k: 1.3–1.7 % against 4.2–6.5 %);
    the limb 2.75 % instead of 5.22 % at its last hostile frame, but 1.22 / 2.21 % instead of
    0.89 / 1.55 % at the sampled limb's first two; 2–6 × faster per frame. ``True``: the four
    differences and the canonical thickening's embedding.
    """

    def __init__(self, base_vertices, triangles, target_rest_vertices, target_triangles, *, correspondence=None,
                 k_M: int | None = 100, k_N: int | None = 200, offset: float | None = None,
                 use_extrinsic: bool = False, reference=None, refine_map: bool = True,
                 correct_discretization: bool = True, warm_start: bool = True,
                 target_name: str = "target rest vertices", target_label: str = TARGET_LABEL):
        from .reference_shape import ReferenceShape

        k_M, k_N = basis_sizes(k_M, k_N)
        if k_M is None or k_N is None:
            raise MeshError(
                "Shape differences between two different meshes need truncated bases: set both k_M "
                "(base) and k_N (target), e.g. k_M = 100 and k_N = 200."
            )
        self.k_M, self.k_N = int(k_M), int(k_N)
        if reference is None or not reference.matches(base_vertices, triangles):
            reference = ReferenceShape(base_vertices, triangles, offset=offset, use_extrinsic=use_extrinsic)
        reference.basis_sizes(self.k_M, None)  # k_M against the base mesh (k_N is the target's)
        self.reference = reference
        rest = check_vertices(target_rest_vertices, name=target_name)
        self.n_target = rest.shape[0]
        topology = mesh_topology(target_triangles, self.n_target, allow_non_manifold=True)
        # Coincident copies of a vertex (split along UV seams or sharp edges by an exporter) are
        # welded: the surface is one piece there, and its Laplacian must see it so.
        self._welded = coincident_vertices(rest, topology.used_vertices)
        kept = topology.triangles
        if self._welded is not None:
            kept = self._welded[kept]
            whole = (kept[:, 0] != kept[:, 1]) & (kept[:, 1] != kept[:, 2]) & (kept[:, 2] != kept[:, 0])
            # pieces wound against the ones they are welded to are turned over, as the in-betweens'
            kept = oriented_pieces(kept[whole], topology.components()[1][whole])
        # slivers of a decimation: no area, no part of the surface
        flat = degenerate_at_rest(rest, kept, target_name, target_label)
        # Edges flipped towards Delaunay where the surface is flat enough (core.delaunay_flips): the
        # target's eigenbasis needs its surface, not its triangles.
        kept = delaunay_flips(rest, np.delete(kept, flat, axis=0), max_dihedral_degrees=MAX_DIHEDRAL_DEGREES)
        if not np.array_equal(kept, topology.triangles):
            topology = mesh_topology(kept, self.n_target, allow_non_manifold=True)
        warn_non_manifold(topology, target_label)
        # Target vertices in no triangle are left out (compact numbering, as for the base).
        self.target_used = topology.used_vertices
        compact = np.full(self.n_target, -1, dtype=np.int64)
        compact[self.target_used] = np.arange(self.target_used.size)
        if self._welded is not None:
            compact = compact[self._welded]  # a copy's index means its welded vertex
        if self.target_used.size != self.n_target:
            topology = mesh_topology(compact[topology.triangles], self.target_used.size, allow_non_manifold=True)
        self.target_triangles = np.asarray(target_triangles, dtype=np.int64)
        rest_used = rest[self.target_used]
        check_nondegenerate(rest_used, topology.triangles, name=target_name)
        # k_N against the target's eigenbasis, before any work (the base's k_M was checked above)
        check_basis_sizes(self.k_M, self.k_N, None, full_basis=False, target_vertices=int(self.target_used.size))
        check_target_resolution(self.k_M, int(self.target_used.size), target_label)

        base_used = reference.used_vertices
        # The map is found in the caller's units (its checks quote distances); the target's layers
        # below work in the reference's (ReferenceShape.unit).
        base = reference.given_positions
        if correspondence is None:
            nearest = closest_point_correspondence(base, rest_used)
            partly = check_overlap(base, rest_used[nearest], rest_used, topology.edges,
                                   reference.vertex_components)
            matched = self.target_used[nearest]
            self.correspondence = np.zeros(reference.n_vertices, dtype=np.int64)
            self.correspondence[base_used] = matched
        else:
            self.correspondence = check_correspondence(correspondence, reference.n_vertices, self.n_target,
                                                       allow_unmatched=True)
        used_map = self.correspondence[base_used]
        matched = used_map != UNMATCHED
        loose = np.flatnonzero(matched & (compact[used_map] < 0))
        if loose.size:  # matched to a loose target vertex (a stray point of a scan): unmatched
            i = int(base_used[loose[0]])
            warn(
                f"The correspondence maps base vertex {i} to target vertex {int(self.correspondence[i])}, "
                f"which is in no triangle of the target ({loose.size} such base vertices); these base "
                "vertices are treated as unmatched.",
                "correspondence",
            )
            matched[loose] = False
        partial = not matched.all()
        if partial:
            check_matched_fraction(matched)
        seeds = np.where(matched, compact[used_map], 0)
        if correspondence is not None:
            check_spread(rest_used[seeds[matched]], rest_used)
            # Matches their neighbours contradict (a map's stray entries) count as unmatched.
            fitted, kept = reject_outlying_matches(base, reference.topology.edges,
                                                   rest_used[seeds], matched,
                                                   mean_edge_length(rest_used, topology.edges))
            stray = matched & ~kept
            if stray.any():
                warn_outlying_matches(base_used[stray], int(matched.sum()))
                check_matched_fraction(kept, warns=not partial)  # the warning once
                matched, partial = kept, True
        if correspondence is None:
            points = base  # the meshes overlap: project the base itself
        elif refine_map or partial:
            points = fitted
        else:
            points = rest_used[seeds]
        if partial:
            # An unmatched vertex's image is found on the target by walking from the match of the
            # nearest matched vertex along the base.
            unmatched = np.flatnonzero(~matched)
            start = seeds[nearest_matched(base, reference.topology.edges, matched)[unmatched]]
            seeds[unmatched] = walk_near(points[unmatched], start, rest_used, topology.triangles)
        image_triangles, weights = project_near(points, seeds, rest_used, topology.triangles)
        if correspondence is not None:  # holes show in the fitted images (raw matches lie on the target)
            projected = (image_triangles, weights) if points is fitted else project_near(fitted, seeds, rest_used,
                                                                                         topology.triangles)
            check_covered(fitted, reference.topology, rest_used, topology, *projected, given_map=True)
        elif not partly:  # a part beside the target is warned already
            check_covered(points, reference.topology, rest_used, topology, image_triangles, weights)
        if correspondence is not None and not refine_map:
            snapped = (topology.triangles[image_triangles] == seeds[:, None]).astype(np.float64)
            weights = np.where(matched[:, None], snapped, weights)
        n_used = self.target_used.size
        pull_back = pull_back_matrix(topology.triangles[image_triangles], weights, n_used)
        self._pull_back = pull_back  # (n_M, n_N): each base vertex's image on the target
        laid = pull_back @ rest_used  # the base laid on the target's rest through the map
        if correspondence is not None:  # closest points keep the base's sides
            check_orientation(base, reference.topology, laid)
        self.size = target_size(base, laid, reference.topology.triangles)
        push = push_forward_matrix(rest_used, laid, reference.topology.triangles, topology=reference.topology)
        self.layers = [TargetLayer("mesh", topology, push)]
        self.target_surface = None
        if reference.use_extrinsic:
            from .offset_surface import offset_surface

            try:
                self.target_surface = offset_surface(topology)
            except MeshError as error:
                raise MeshError(
                    f"The target mesh has no usable offset surface ({error}) Transfer with "
                    "use_extrinsic=False (intrinsic differences only) or repair the target."
                ) from error
            offset_rest = self.target_surface.positions(rest_used * reference.unit, reference.offset)
            offset_pull_back = offset_surfaces_pull_back(reference.surface, self.target_surface, image_triangles,
                                                         weights, seeds, rest_used)
            push = push_forward_matrix(offset_rest, offset_pull_back @ offset_rest, reference.surface.topology.triangles,
                                       topology=reference.surface.topology)
            self.layers.append(TargetLayer("offset surface", self.target_surface.topology, push))
        self.discretization_error = self._discretization_error() if correct_discretization else None
        # A k_M inside a group of equal eigenvalues of the base leaves the base functions the
        # differences are written in to rounding: the transferred pose moves by 2–4e-2 of its diagonal
        # under ×1e±3 or a 1e-9 rad turn of the inputs (icospheres, k_M = 20), 5e-5 at k_M = 16. k_N is not
        # checked: a target basis ended inside a group (of the symmetric rest carried onto the target)
        # moved the pose no more than the recovery's tolerance does at a size that ends a group
        # (1.3e-5–1.7e-4 of the diagonal at k_N 14 and 18 against 1e-5–8e-5 at 16, 21 and 25).
        reference.warn_split(self.k_M)
        self.warm_start = bool(warm_start)
        self._warm_recovery = [{}, {}]  # per layer: the last pose's areas and ADMM state
        self._last_embedding = None  # the last pose's EmbeddingResult
        self._last_carried = None  # the last pose carried to the base (thickening points), finite
        self._thickening_labels = None  # connected component of every thickening point

    @property
    def _fit_edges(self) -> np.ndarray:
        """The edges ``(K, 2)`` the embedding fits: the canonical thickening's, or the base's."""
        ref = self.reference
        return ref.surface.thickening_edges if ref.use_extrinsic else ref.topology.edges

    def _start_residual(self, metric, points) -> float:
        """RMS relative length residual of embedding start ``points`` for ``metric``."""
        from .edge_length_fit import relative_residuals, rms

        ref = self.reference
        squared = ref.thickening_squared_lengths(metric) if ref.use_extrinsic else metric.base.squared_lengths
        return rms(relative_residuals(points, self._fit_edges, squared))

    def _mesh_residual(self, metric, vertices) -> float:
        """RMS relative length residual of base ``vertices`` ``(n_M_used, 3)`` on the base mesh's
        edges only (not the offset layer's, normal or side edges of the thickening).

        Of the fits from the two carried starts, the one kept has the lower misfit of the mesh
        layer, not of the whole thickening: the offset layer's recovered lengths are several times
        less accurate (5k cloth frame 40, RMS relative error of the recovered lengths: mesh 0.18,
        offset surface 1.1), so its misfit ranks poses by noise. Re-meshed 1k drape (mesh-layer
        residual / Hausdorff): frame 20 0.0291 / 2.86 % against 0.0304 / 5.60 % (the whole
        residual agrees), frame 60 after 40 0.0162 / 5.09 % against 0.0179 / 6.30 % (the whole
        residual, 0.0252 against 0.0244, kept 6.30 %); frames 21 and 40 the same choice as the
        whole residual's."""
        from .edge_length_fit import relative_residuals, rms

        return rms(relative_residuals(vertices, self.reference.topology.edges, metric.base.squared_lengths))

    # -- per pose ---------------------------------------------------------------------------
    def _target_positions(self, target_vertices) -> np.ndarray:
        """A target pose ``(n_N, 3)`` checked (messages in the caller's units), its used vertices
        ``(n_N_used, 3)`` in the reference's working units (× ``reference.unit``)."""
        full = check_vertices(target_vertices, name="target vertices")
        if full.shape[0] != self.n_target:
            raise MeshError(
                f"target vertices has {full.shape[0]} vertices but the target mesh has {self.n_target}: "
                "every target pose must be a pose of the same target mesh."
            )
        positions = full[self.target_used]
        if self._welded is not None:
            copies = np.flatnonzero(self._welded != np.arange(self.n_target))
            apart = np.linalg.norm(full[copies] - full[self._welded[copies]], axis=1)
            scale = np.linalg.norm(np.ptp(positions, axis=0))
            if apart.max() > WELD_DISTANCE * scale:
                i = int(copies[np.argmax(apart)])
                warn(
                    f"Target vertices {i} and {int(self._welded[i])} coincide at rest and were welded, but this pose "
                    f"moves them {apart.max():.3g} apart; the pose is taken as if both were at vertex "
                    f"{int(self._welded[i])}.",
                    "target",
                )
        check_nondegenerate(positions, self.layers[0].topology.triangles, name="target vertices")
        return positions if self.reference.unit == 1.0 else positions * self.reference.unit

    def _layer_differences(self, positions):
        """``[(area, conformal)]`` of eq. (6) per layer (mesh, offset surface) for a target pose of
        used vertices ``(n_N_used, 3)``, uncorrected."""
        ref = self.reference
        calls = [lambda: self.layers[0].differences(ref.base, positions, self.k_M, self.k_N)]
        if ref.use_extrinsic:
            offset_positions = self.target_surface.positions(positions, ref.offset)
            calls.append(lambda: self.layers[1].differences(ref.offset_layer, offset_positions, self.k_M, self.k_N))
        return per_layer_threads(calls)

    def _rest_layer_differences(self, positions):
        """:meth:`_layer_differences` of the first pose (the base's rest carried onto the target),
        with the base-only edge Gram factors of the recovery
        (:meth:`~core.truncated_recovery.TruncatedRecovery.edge_gram`) built on the way, and the
        target offset surface's eigenbasis started from the target mesh's, lifted (each lifted
        vertex takes its vertex's values, each face center the mean of its corners'): the offset
        surface lies a fraction of an edge above the mesh, so its low eigenfunctions are nearly the
        mesh's. 5k cloth (19,845 offset vertices, 300 functions, one thread): 4–5 s of subspace
        iterations against 19.7 s of ARPACK, eigenvalues within 3e-5. The mesh layer's thread
        computes the mesh's eigenbasis (ARPACK, 6 s) and the mesh's Gram factor (2.8 s); the
        offset layer's computes the offset surface's Gram factor (10 s) while it waits for the
        mesh's eigenbasis."""
        import threading

        ref = self.reference
        if not ref.use_extrinsic:
            result = self._layer_differences(positions)
            ref.base.truncated_solver(ref.base.basis(self.k_M)).edge_gram()
            return result
        ready = threading.Event()

        def mesh_layer():
            try:
                result = self.layers[0].differences(ref.base, positions, self.k_M, self.k_N)
            finally:
                ready.set()  # also on failure: the offset layer must not wait forever
            ref.base.truncated_solver(ref.base.basis(self.k_M)).edge_gram()
            return result

        def offset_layer():
            layer = ref.offset_layer
            layer.truncated_solver(layer.basis(self.k_M)).edge_gram()
            offset_positions = self.target_surface.positions(positions, ref.offset)
            ready.wait()
            mesh = self.layers[0]._subspace
            start = None if mesh is None else self._lifted(mesh[1])
            return self.layers[1].differences(layer, offset_positions, self.k_M, self.k_N, start)

        return per_layer_threads([mesh_layer, offset_layer])

    def _lifted(self, functions) -> np.ndarray:
        """Functions ``(n_N_used, p)`` on the target mesh carried to its offset surface's vertices
        ``(n_Nt, p)``: a lifted vertex takes its vertex's values, a face center the mean of its
        triangle's corners'."""
        surface = self.target_surface
        corners = surface.base.triangles[surface.centered_triangles]
        return np.concatenate([functions[surface.lifted_vertices], functions[corners].mean(axis=1)])

    def _discretization_error(self):
        """What eq. (6) gets wrong only because the target is meshed differently: the differences
        of the base's own rest pose carried onto the target's connectivity (each target vertex
        placed at its preimage on the base, ``Q x_M``), minus their exact value for the same
        surface (area: the identity; conformal: ``diag(λ)⁺ diag(λ)``). Subtracted from every
        pose's differences; ``None`` (with a warning) where the carried rest pose folds."""
        ref = self.reference
        on_base = np.asarray(self.layers[0].push @ ref.base_positions)
        triangles = self.layers[0].topology.triangles
        collapsed = zero_area_triangles(on_base, triangles)
        if collapsed.size:  # the map's doing, not the target's: its triangles have area at rest
            warn(
                f"The map collapses {collapsed.size} of the target's triangles (first: the one of target vertices "
                f"{self.target_used[triangles[collapsed[0]]].tolist()}) when the target is laid on the base through "
                "it: outlying matches, or a part of the target the base does not have (a fin). The differences are "
                "not corrected for the change of meshing and are less accurate; check the map there.",
                "correspondence",
            )
            return None
        try:
            carried = self._rest_layer_differences(on_base)
        except MeshError as error:
            warn(
                f"The target's connectivity could not be laid on the base surface through the map ({error}); "
                "the differences are not corrected for the change of meshing and are less accurate.",
                "correspondence",
            )
            return None
        errors = []
        for (area, conformal), layer in zip(carried, (ref.base, ref.offset_layer)):
            basis = layer.basis(self.k_M)
            exact = basis.pseudo_inverse_eigenvalues() * basis.eigenvalues
            errors.append((area.matrix - np.eye(self.k_M), conformal.matrix - np.diag(exact)))
        return errors

    def differences(self, target_vertices):
        """The four differences (eq. 6) of a target pose ``(n_N, 3)``, on the base's bases, with
        the :meth:`_discretization_error` removed: a
        :class:`~core.reference_shape.ShapeDifferences` for :func:`core.reconstruct`."""
        return self._differences(self._target_positions(target_vertices))

    def _differences(self, positions):
        """:meth:`differences` of a target pose of used vertices ``(n_N_used, 3)``."""
        from dataclasses import replace

        from .reference_shape import ShapeDifferences

        layers = self._layer_differences(positions)
        if self.discretization_error is not None:
            layers = [
                (replace(area, matrix=area.matrix - error_a), replace(conformal, matrix=conformal.matrix - error_c))
                for (area, conformal), (error_a, error_c) in zip(layers, self.discretization_error)
            ]
        (area, conformal), (offset_area, offset_conformal) = layers[0], (layers[1] if len(layers) > 1 else (None, None))
        ref = self.reference
        return ShapeDifferences(area, conformal, offset_area, offset_conformal, ref.given_offset, self.k_M, self.k_N,
                                ref)

    def pose(self, target_vertices) -> np.ndarray:
        """The target pose ``(n_N, 3)`` rebuilt on the base mesh, float64 ``(n_M, 3)``: recovered
        from its shape differences and placed by the rigid motion that brings each component
        closest to the base vertices' images on the target (the map). A target of another size
        keeps it (:attr:`size`): the pose is rebuilt at the base's size and scaled. A solver's raw
        numerical failure is a :class:`~core.errors.RecoveryError` (:func:`~core.validation.numerical_failures`)."""
        ref = self.reference
        positions = self._target_positions(target_vertices) / self.size  # at the base's size
        with numerical_failures("Transferring the pose"):
            differences = self._differences(positions)
            metric = ref.recover_metric(differences, warm=self._warm_recovery if self.warm_start else None,
                                        tolerance=RECOVERY_TOLERANCE, rho_scale=RECOVERY_RHO_SCALE)
            carried = np.asarray(self._pull_back @ positions)  # each base vertex's image on this pose
            embedded = self._embed(metric, carried)
            placed = ref.place_near(embedded.base_vertices, carried) * self.size
        return ref.expand_pose(placed)

    def _projected(self, vertices) -> np.ndarray:
        """Base ``vertices`` ``(n_M_used, 3)`` projected on the base's k_M eigenfunctions (mass
        inner product): what the truncated lengths resolve, smooth at the scale of edges."""
        ref = self.reference
        basis = ref.base.basis(self.k_M).functions
        return basis @ (basis.T @ (ref.base.mass @ vertices))

    def _embed(self, metric, carried):
        """The pose realizing a recovered metric. Intrinsic only: the base mesh fitted to its
        recovered edge lengths from ``carried`` ``(n_M_used, 3)``, the target pose carried to the
        base's vertices, every pose, to :data:`INTRINSIC_EMBEDDING_TOLERANCE` (a fit that reaches
        the lengths' accuracy needs no choice of start; the previous pose's embedding moved with the
        target fitted the new lengths no better than the carried pose). With the offset
        layer, the embedding (§7.3) of the canonical thickening (:data:`WARM_EMBEDDING_GROWTH`):
        when warm, fitted from the previous pose's embedding moved with the target; first, or after
        a jump, from ``carried`` with its offset surface, and its projection; by
        :meth:`~core.reference_shape.ReferenceShape.embed_result`'s race of starts where the
        carried pose has a collapsed triangle (no normal). Every fit stops at
        :data:`EMBEDDING_STAGNATION`."""
        ref, last = self.reference, self._last_embedding
        if not ref.use_extrinsic:
            def fit(start):
                return ref.embed_result(metric, initial=start, initial_damping=EMBEDDING_DAMPING,
                                        stagnation=EMBEDDING_STAGNATION, tolerance=INTRINSIC_EMBEDDING_TOLERANCE)

            result = fit(carried)
            if result.residual > INTRINSIC_EMBEDDING_TOLERANCE:
                # Stopped short of the lengths' accuracy: the carried pose is tangled (a sparse map's
                # extrapolated vertices). Its projection on the base's k_M functions is smooth.
                other = fit(self._projected(carried))
                result = min((result, other), key=lambda r: r.residual)
            self._last_embedding = result
            return result
        thick = lambda x: ref.surface.thickening_points(x, ref.surface.positions(x, ref.offset))  # noqa: E731
        carried_points = thick(carried)

        def from_carried():
            # As carried, and projected on the base's k_M functions (what the lengths resolve):
            # both fitted (in two threads), the lower residual kept (the module constant).
            starts = [carried_points, thick(self._projected(carried))]
            starts = [s for s in starts if np.isfinite(s).all()]
            if not starts:
                return ref.embed_result(metric)
            fits = per_layer_threads([
                lambda s=s: ref.embed_result(metric, initial=s, initial_damping=EMBEDDING_DAMPING,
                                           stagnation=EMBEDDING_STAGNATION) for s in starts
            ])
            # The mesh layer's misfit decides (see _mesh_residual).
            return min(fits, key=lambda fit: self._mesh_residual(metric, fit.base_vertices))

        if self.warm_start and last is not None:
            start = last.points
            if self._last_carried is not None and np.isfinite(carried_points).all():
                # The previous embedding moved with the target: its offset from the carried pose
                # (both rigidly aligned) added to this pose's carried one.
                from .geometry import connected_components
                from .rigid_alignment import align_components

                if self._thickening_labels is None:
                    self._thickening_labels = connected_components(start.shape[0], self._fit_edges)[1]
                aligned = align_components(start, self._last_carried, self._thickening_labels)
                start = carried_points + (aligned - self._last_carried)
            limit = WARM_EMBEDDING_GROWTH * max(last.residual, FRAMES_NEARLY_EXACT)
            if self._start_residual(metric, start) > limit:
                result = from_carried()  # a jump: the previous pose is no start
            else:
                result = ref.embed_result(metric, initial=start, initial_damping=EMBEDDING_DAMPING,
                                          stagnation=EMBEDDING_STAGNATION)
                if result.residual > limit:
                    other = from_carried()
                    result = other if other.residual < result.residual else result
        else:
            result = from_carried()
        self._last_carried = carried_points if np.isfinite(carried_points).all() else None
        self._last_embedding = result
        return result


def target_size(base, laid, triangles) -> float:
    """The size of a target relative to the base: the median over the base's ``triangles``
    ``(m, 3)`` of the square root of each one's area laid on the target's rest through the map
    (``laid`` ``(n, 3)``) over its area on the base ``base`` ``(n, 3)`` (a median: a few outlying
    matches lay long triangles across the target).

    A target modelled in other units (a scan in millimetres, a character in centimetres) has
    shape differences of that size, areas × size², which the recovery does not follow: at 1 % of
    the base's size they are past its area floor (:data:`~core.truncated_recovery.AREA_FLOOR`; the
    pose came out 3.8 × too large, 39 % of its diagonal off), and even 5 % larger the test sheet's
    pose was 3.8 % off against 1.7 % (the meshing correction, tolerances and floors are set at the
    base's size). :meth:`Transfer.pose` divides the target's poses by this, rebuilds them at the
    base's size and scales the result back. Measured through the map, not on the whole target, so
    a map onto part of a larger target (a head on a body) gives the part's size.

    A size within :data:`SIZE_TOLERANCE` of the base's is the base's own, exactly 1: a target of
    the base's size is rebuilt as without the scaling, bit for bit."""
    from .mesh_topology import triangle_areas

    ratio = np.median(triangle_areas(laid, triangles) / triangle_areas(base, triangles))
    size = float(np.sqrt(ratio)) if np.isfinite(ratio) and ratio > 0 else 1.0
    return 1.0 if abs(size - 1.0) <= SIZE_TOLERANCE else size


def transferred_keys(base_vertices, triangles, key_poses, target_triangles, *, correspondence=None,
                     target_rest_vertices=None, k_M=100, k_N=200, offset=None, use_extrinsic=False) -> list:
    """Every pose of ``key_poses`` (poses ``(n_N, 3)`` of the target mesh) rebuilt on the base mesh
    by one :class:`Transfer` (``target_rest_vertices`` defaults to the first key; ``use_extrinsic``
    as there)."""
    keys = [np.asarray(k) for k in key_poses]
    if not keys:
        raise MeshError("No target poses to transfer.")
    transfer = Transfer(base_vertices, triangles, keys[0] if target_rest_vertices is None else target_rest_vertices,
                        target_triangles, correspondence=correspondence, k_M=k_M, k_N=k_N, offset=offset,
                        use_extrinsic=use_extrinsic)
    return [transfer.pose(key) for key in keys]


def sequence_class():
    from .sequence_inbetweens import SequenceInterpolator

    class TransferSequenceInterpolator(SequenceInterpolator):
        """:class:`~core.sequence_inbetweens.SequenceInterpolator` that also takes key poses of another
        mesh: with ``target_triangles`` the keys are poses of that target mesh, first rebuilt on
        the base mesh (``base_vertices`` on ``triangles``) by a :class:`Transfer` with ``k_M`` /
        ``k_N`` (``correspondence``, ``target_rest_vertices`` as there; intrinsic, its default),
        then in-betweened on the base mesh in the full basis (``use_extrinsic`` applies to the
        in-betweens). Without ``target_triangles``: the same-mesh interpolator. ``rest_pose``: the
        rest shape of the mesh in-betweened (the base mesh's where the keys are transferred)."""

        def __init__(self, key_poses, triangles, *, k_M=None, k_N=None, offset=None, use_extrinsic=True,
                     smooth=True, start="rest", key_times=None, base_vertices=None, target_triangles=None,
                     correspondence=None, target_rest_vertices=None, end="keys", key_names=None, rest_pose=None):
            if target_triangles is not None:
                if base_vertices is None:
                    raise MeshError("Key poses of another mesh need base_vertices: the pose of the mesh to move.")
                key_poses = transferred_keys(
                    base_vertices, triangles, key_poses, target_triangles, correspondence=correspondence,
                    target_rest_vertices=target_rest_vertices, k_M=k_M, k_N=k_N, offset=offset,
                )
                k_M = k_N = None
            super().__init__(key_poses, triangles, k_M=k_M, k_N=k_N, offset=offset, use_extrinsic=use_extrinsic,
                             smooth=smooth, start=start, key_times=key_times, end=end, key_names=key_names,
                             rest_pose=rest_pose)

    TransferSequenceInterpolator.__name__ = TransferSequenceInterpolator.__qualname__ = "SequenceInterpolator"
    return TransferSequenceInterpolator
