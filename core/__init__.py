"""Shape differences core: the functional characterization of intrinsic and extrinsic geometry
(Corman, Solomon, Ben-Chen, Guibas, Ovsjanikov, ACM TOG 2017) for meshes in vertex-for-vertex
correspondence. Pure NumPy/SciPy; never imports bpy.

Public API (arrays: vertices float64 ``(n, 3)``, triangles int ``(m, 3)``):

- :func:`shape_differences` — the four differences (area, conformal, and both on the offset
  surface) of a target pose relative to a base, full basis or truncated (``k_M``, ``k_N``).
- :func:`reconstruct` — the pose the differences describe.
- :func:`interpolate`, :class:`Interpolator`, :class:`SequenceInterpolator` — in-betweens and
  exaggerations by interpolating shape differences (§8.4).
- :class:`ReferenceShape` — a base mesh prepared once for many targets.
- :class:`Transfer` — poses of a differently meshed target rebuilt on the base mesh through a
  functional map (§6.3, Fig. 15); ``shape_differences``, ``interpolate`` and
  ``SequenceInterpolator`` take such a target with ``target_triangles``;
  :func:`template_correspondence` and :func:`read_vertex_map` turn map files into its
  correspondence.
- :func:`shape_space` — PCA of the differences of a collection of poses (§8.1);
  :func:`pull_back` — the target's metric on the base mesh: Laplacian, geodesics, WKS (§8.3);
  :func:`distortion` — per-face and per-vertex distortion maps of a pose.
- :func:`default_offset`; errors :class:`MeshError`, :class:`RecoveryError` (both
  :class:`ShapeDifferenceError`) and :class:`ShapeDifferenceWarning`.
"""

from __future__ import annotations

import numpy as np


from .errors import (MeshError, MeshIndexError, RecoveryError, ShapeDifferenceError, ShapeDifferenceWarning,
                     shape_warning, warn)
from .offset_surface import default_offset
from .reference_shape import (OFFSET_RANGE, PRECISION_TOLERANCE, RecoveredMetric, ReferenceShape, ShapeDifferences,
                              differences_reference)
from .validation import (
    check_basis_sizes,
    check_factor,
    check_flag,
    check_mesh,
    check_offset,
    check_pose,
    numerical_failures,
)

__all__ = [
    "shape_differences",
    "reconstruct",
    "interpolate",
    "Interpolator",
    "SequenceInterpolator",
    "ReferenceShape",
    "Transfer",
    "ShapeDifferences",
    "RecoveredMetric",
    "default_offset",
    "shape_space",
    "ShapeSpace",
    "pull_back",
    "PulledBackMetric",
    "template_correspondence",
    "read_vertex_map",
    "distortion",
    "Distortion",
    "MeshError",
    "MeshIndexError",
    "RecoveryError",
    "ShapeDifferenceError",
    "ShapeDifferenceWarning",
]


def shape_differences(
    base_vertices,
    target_vertices,
    triangles,
    *,
    k_M: int | None = None,
    k_N: int | None = None,
    offset: float | None = None,
    use_extrinsic: bool = True,
    target_triangles=None,
    correspondence=None,
    target_rest_vertices=None,
) -> ShapeDifferences:
    """The four shape differences of ``target_vertices`` relative to ``base_vertices`` (§6).

    ``k_M = None`` (or 0): full basis, eqs. (3)–(4) (exactly invertible). ``k_M`` only: reduced in the
    first ``k_M`` Laplace–Beltrami eigenfunctions of the base, eq. (5). ``k_M`` and ``k_N``:
    source- and target-truncated through the functional map of the vertex correspondence,
    eq. (6). ``offset``: the offset distance t in the mesh's units (``None``: half the mean edge
    length of the base). ``use_extrinsic=False`` computes the intrinsic pair only.

    Another mesh as target (§6.3, Fig. 15): ``target_triangles`` int ``(m_N, 3)`` are the
    target's triangles and ``target_vertices`` ``(n_N, 3)`` its pose; ``k_M`` and ``k_N`` are then
    required. ``correspondence`` int ``(n_M,)``: each base vertex's matched target vertex (not
    necessarily a bijection); ``None`` matches closest points, for a target that overlaps the
    base at rest. ``target_rest_vertices`` ``(n_N, 3)``: the target pose the map refers to (its
    rest pose; default ``target_vertices``). See :class:`core.transfer.Transfer`, which prepares
    all this once for many target poses.

    Raises :class:`MeshError` for invalid arguments (``docs/errors.md``); warns
    (:class:`ShapeDifferenceWarning`) when the offset is so far from the mesh's scale that the
    extrinsic differences lose precision.
    """
    if target_triangles is not None:
        from .transfer import Transfer

        rest = target_vertices if target_rest_vertices is None else target_rest_vertices
        transfer = Transfer(base_vertices, triangles, rest, target_triangles, correspondence=correspondence,
                            k_M=k_M, k_N=k_N, offset=offset, use_extrinsic=use_extrinsic)
        return transfer.differences(target_vertices)
    base, topology = check_mesh(base_vertices, triangles, name="base_vertices")
    target = check_pose(target_vertices, topology, name="target_vertices")
    k_M, k_N = check_basis_sizes(k_M, k_N, int(topology.used_vertices.size), topology.components()[0],
                                 geometry=(base, topology))
    offset, use_extrinsic = check_offset(offset), check_flag(use_extrinsic, "use_extrinsic")
    with numerical_failures("Computing the shape differences"):
        reference = ReferenceShape(base, topology.triangles, offset=offset, use_extrinsic=use_extrinsic)
        reference.check_faithful(reference.base_positions, "base_vertices")
        return reference.shape_differences(target, k_M=k_M, k_N=k_N, name="target_vertices")


#: reconstruct warns when the returned pose misses the recovered edge lengths by more than this
#: (relative, largest over the edges) for full-basis differences, which determine the lengths
#: exactly (the embedding converges to ~1e-8 on valid input; truncated differences give lengths
#: that are only approximately realizable, so they are not checked this way).
REALIZATION_TOLERANCE = 1e-3


_ANALYSIS = {
    "shape_space": ".shape_space_pca",
    "ShapeSpace": ".shape_space_pca",
    "pull_back": ".pulled_back_metric",
    "PulledBackMetric": ".pulled_back_metric",
    "distortion": ".distortion_maps",
    "Distortion": ".distortion_maps",
    "template_correspondence": ".vertex_maps",
    "read_vertex_map": ".vertex_maps",
}


def reconstruct(base_vertices, triangles, differences: ShapeDifferences) -> np.ndarray:
    """Positions float64 ``(n, 3)`` of the pose that ``differences`` describe (§7).

    Recovers areas and squared edge lengths of the target and of its offset surface (linear
    solves in the full basis, convex programs when truncated), embeds the canonical thickening
    and returns its base layer. Shape differences determine a pose only up to rigid motion; the
    result is placed by the rotation and translation that bring it closest to the base (least
    squares weighted by vertex area, per connected component). Loose vertices keep their base
    positions.

    ``base_vertices`` and ``triangles`` must be those ``differences`` were computed from
    (:class:`MeshError` otherwise). Warns (:class:`ShapeDifferenceWarning`) when the returned
    pose does not realize the recovered edge lengths (full basis).
    """
    reference = differences_reference(base_vertices, triangles, differences)
    with numerical_failures("Reconstructing the pose"):
        metric = reference.recover_metric(differences)
        _check_recovered_metric(metric, differences)
        embedding = reference.embed_result(metric)
        placed = reference.place_near(embedding.base_vertices, reference.base_positions, glue_seams=True,
                                      exact=differences.k_M is None)
        if differences.k_M is None:  # exact lengths: a miss or an undecided mirror is real
            _warn_unrealized(reference, metric, placed)
            _warn_undetermined(embedding.unresolved_choices)
        if metric.offset is None:
            _warn_bending_free(reference, placed)
        return reference.expand_pose(placed)


def _check_recovered_metric(metric: RecoveredMetric, differences: ShapeDifferences) -> None:
    """RecoveryError, in the user's terms, if the recovered lengths cannot be embedded."""
    layers = [("the target pose", metric.base)]
    if metric.offset is not None:
        layers.append(("the target's offset surface", metric.offset))
    for label, layer in layers:
        squared = layer.squared_lengths
        bad = np.flatnonzero(~np.isfinite(squared) | (squared <= 0))
        if bad.size:
            cause = (
                f"the truncated basis (k_M={differences.k_M}, k_N={differences.k_N}) is probably too "
                "small for this deformation: raise k_M, or use the full basis (k_M=None)"
                if differences.k_M is not None
                else "the full-basis differences do not describe a valid mesh (were they edited or "
                "computed on another mesh?)"
            )
            raise RecoveryError(
                f"The squared edge lengths recovered for {label} are not all positive ({bad.size} of "
                f"{squared.size}): {cause}."
            )


def _warn_unrealized(reference: ReferenceShape, metric: RecoveredMetric, placed: np.ndarray) -> None:
    """ShapeDifferenceWarning if the pose misses the recovered (exact) edge lengths."""
    wanted = np.sqrt(metric.base.squared_lengths)
    got = np.sqrt(reference.topology.squared_edge_lengths(placed))
    error = np.abs(got - wanted) / wanted
    worst = int(np.argmax(error))
    if error[worst] > REALIZATION_TOLERANCE:
        a, b = (int(reference.used_vertices[i]) for i in reference.topology.edges[worst])
        warning = shape_warning(
            f"The reconstructed pose misses the edge lengths the differences describe: edge ({a}, {b}) "
            f"is {100 * error[worst]:.3g} % off ({int(np.count_nonzero(error > REALIZATION_TOLERANCE))} "
            f"edges beyond {100 * REALIZATION_TOLERANCE:g} %). The embedding could not realize this "
            "pose (an extreme stretch, a sharp fold, or lengths beyond floating-point precision); "
            "check the result.",
            "fit",
        )
        warning.excess = float(error[worst]) / REALIZATION_TOLERANCE  # the worst edge's miss ÷ the miss allowed
        warn(warning)


def _warn_bending_free(reference: ReferenceShape, placed: np.ndarray) -> None:
    """ShapeDifferenceWarning where intrinsic differences alone (no offset surface) leave the pose
    undetermined. They fix the edge lengths (§4, Propositions 1–2), and the lengths fix a pose
    only where the surface cannot bend without changing them (§2; the extrinsic pair is what makes
    the description complete, §5.3): a part with a boundary bends freely (a sheet draped or flat,
    the same lengths), and on a closed part a vertex whose reflection through the plane of its
    neighbours keeps its edges to :data:`REALIZATION_TOLERANCE` (a valence-3 vertex exactly, a
    nearly flat star nearly) can sit on either side, as can caps of such vertices. Counted on the
    returned pose ``placed`` ``(n_used, 3)``: reflections that move a vertex by less than that
    tolerance of the diagonal leave the pose as it is to the precision it is realized to."""
    topology = reference.topology
    edges = topology.edges
    open_parts = 0
    boundary = topology.boundary_edges
    if boundary.size:
        labels = topology.components()[1]
        open_parts = np.unique(labels[topology.edge_triangles[boundary, 0]]).size
    # each vertex's neighbours, their centroid and best-fitting plane (normal: the covariance's
    # eigenvector of the least eigenvalue), the vertex reflected through it
    n = len(placed)
    source, other = np.concatenate([edges[:, 0], edges[:, 1]]), np.concatenate([edges[:, 1], edges[:, 0]])
    count = np.bincount(source, minlength=n)
    centroid = np.stack([np.bincount(source, placed[other, d], minlength=n) for d in range(3)], axis=1)
    centroid /= np.maximum(count, 1)[:, None]
    spread = placed[other] - centroid[source]
    covariance = np.zeros((n, 3, 3))
    np.add.at(covariance, source, spread[:, :, None] * spread[:, None, :])
    normal = np.linalg.eigh(covariance)[1][:, :, 0]
    height = np.einsum("ij,ij->i", placed - centroid, normal)
    reflected = placed - 2.0 * height[:, None] * normal
    before = np.linalg.norm(placed[source] - placed[other], axis=1)
    after = np.linalg.norm(reflected[source] - placed[other], axis=1)
    change = np.zeros(n)
    np.maximum.at(change, source, np.abs(after / before - 1.0))
    on_boundary = np.zeros(n, dtype=bool)
    on_boundary[edges[boundary].ravel()] = True
    diagonal = float(np.linalg.norm(np.ptp(placed, axis=0)))
    move = 2.0 * np.abs(height)
    either_side = np.flatnonzero(~on_boundary & (count >= 3) & (change < REALIZATION_TOLERANCE)
                                 & (move > REALIZATION_TOLERANCE * diagonal))
    if not open_parts and not either_side.size:
        return
    causes = []
    if open_parts:
        causes.append(f"{open_parts} part(s) with a boundary, which bend without changing their edge lengths")
    if either_side.size:
        causes.append(
            f"{either_side.size} vertex(es) (first: {int(reference.used_vertices[either_side[0]])}) that could sit "
            f"on the other side of their neighbours, up to {100 * move[either_side].max() / diagonal:.2g} % of the "
            f"diagonal away, with their edges changing by less than {100 * REALIZATION_TOLERANCE:g} %")
    warn(
        "The pose was rebuilt from intrinsic differences only (use_extrinsic=False), which fix its edge "
        f"lengths but not how it bends: the mesh has {' and '.join(causes)}. The pose has the target's edge "
        "lengths, bent as near the base as they allow, and may differ from the target there; the extrinsic "
        "differences (use_extrinsic=True) determine it.",
        "undetermined",
    )


def _warn_undetermined(choices: int) -> None:
    """ShapeDifferenceWarning if the embedding had to pick a mirror image without evidence."""
    if choices:
        warn(
            f"The differences leave part of the pose undetermined: {choices} mirror choice(s) of the "
            "embedding had no length to decide them (e.g. a fold along the only edge of a two-triangle "
            "strip, whose folded and flat shapes have the same lengths). That part may come back "
            "mirrored or flat; more triangles around the fold make it determined.",
            "undetermined",
        )


def interpolate(
    vertices_a,
    vertices_b,
    triangles,
    factor: float,
    *,
    k_M: int | None = None,
    k_N: int | None = None,
    offset: float | None = None,
    use_extrinsic: bool = True,
    target_triangles=None,
    correspondence=None,
    target_rest_vertices=None,
    rest_pose=None,
) -> np.ndarray:
    """The pose at ``factor`` between ``vertices_a`` (0) and ``vertices_b`` (1): 0.5 is an
    in-between, 1.5 an exaggeration, negative values reverse the motion (§8.4). See
    :class:`Interpolator` to reuse the preparation for many factors. ``rest_pose``: the mesh's rest
    shape (n, 3) (of ``vertices_a``'s mesh), what the edge warning measures the poses' deviation
    from (:class:`Interpolator`); no pose changes.

    With ``target_triangles``, ``vertices_b`` is a pose of another mesh: it is first rebuilt on
    the mesh of ``vertices_a`` (:class:`Transfer`, ``k_M`` / ``k_N``, ``correspondence`` and
    ``target_rest_vertices`` as in :func:`shape_differences`; intrinsic, its default), then
    in-betweened in the full basis (``use_extrinsic`` applies to the in-between)."""
    from .two_pose_inbetweens import Interpolator

    factor = check_factor(factor)
    if target_triangles is not None:
        from .transfer import transferred_keys

        (vertices_b,) = transferred_keys(
            vertices_a, triangles, [vertices_b], target_triangles, correspondence=correspondence,
            target_rest_vertices=target_rest_vertices, k_M=k_M, k_N=k_N, offset=offset,
        )
        k_M = k_N = None
    return Interpolator(
        vertices_a, vertices_b, triangles, k_M=k_M, k_N=k_N, offset=offset, use_extrinsic=use_extrinsic,
        rest_pose=rest_pose,
    ).pose(factor)


def __getattr__(name: str):
    # Analysis modules (shape space, pull-back, distortion) load on first use as well.
    if name in _ANALYSIS:
        import importlib

        return getattr(importlib.import_module(_ANALYSIS[name], __name__), name)
    # Interpolation classes load on first use, keeping `import core` light.
    if name == "SequenceInterpolator":  # same-mesh, or key poses of another mesh (core.transfer)
        from .transfer import sequence_class

        globals()[name] = sequence_class()
        return globals()[name]
    if name == "Transfer":
        from .transfer import Transfer

        return Transfer
    if name == "Interpolator":  # SequenceInterpolator is made above
        from .two_pose_inbetweens import Interpolator

        return Interpolator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
