"""Shape differences core: the functional characterization of intrinsic and extrinsic geometry
(Corman, Solomon, Ben-Chen, Guibas, Ovsjanikov, ACM TOG 2017) for meshes in vertex-for-vertex
correspondence. Pure NumPy/SciPy (cvxpy only for truncated recovery); never imports bpy.

Public API (arrays: vertices float64 ``(n, 3)``, triangles int ``(m, 3)``):

- :func:`shape_differences` — the four differences (area, conformal, and both on the offset
  surface) of a target pose relative to a base, full basis or truncated (``k_M``, ``k_N``).
- :func:`reconstruct` — the pose the differences describe.
- :func:`interpolate`, :class:`Interpolator`, :class:`SequenceInterpolator` — in-betweens and
  exaggerations by interpolating shape differences (§8.4).
- :class:`ReferenceShape` — a base mesh prepared once for many targets.
- :class:`Transfer` — poses of a differently meshed target rebuilt on the base mesh through a
  functional map (§6.3, Fig. 15); ``shape_differences``, ``interpolate`` and
  ``SequenceInterpolator`` take such a target with ``target_triangles``.
- :func:`default_offset`; errors :class:`MeshError`, :class:`RecoveryError` (both
  :class:`ShapeDifferenceError`) and :class:`ShapeDifferenceWarning`.
"""

from __future__ import annotations

import numpy as np

from .errors import MeshError, RecoveryError, ShapeDifferenceError, ShapeDifferenceWarning
from .offset_surface import default_offset
from .reference_shape import RecoveredMetric, ReferenceShape, ShapeDifferences

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
    "MeshError",
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
    """
    if target_triangles is not None:
        from .transfer import Transfer

        rest = target_vertices if target_rest_vertices is None else target_rest_vertices
        transfer = Transfer(base_vertices, triangles, rest, target_triangles, correspondence=correspondence,
                            k_M=k_M, k_N=k_N, offset=offset, use_extrinsic=use_extrinsic)
        return transfer.differences(target_vertices)
    reference = ReferenceShape(base_vertices, triangles, offset=offset, use_extrinsic=use_extrinsic)
    return reference.shape_differences(target_vertices, k_M=k_M, k_N=k_N)


def reconstruct(base_vertices, triangles, differences: ShapeDifferences) -> np.ndarray:
    """Positions float64 ``(n, 3)`` of the pose that ``differences`` describe (§7).

    Recovers areas and squared edge lengths of the target and of its offset surface (linear
    solves in the full basis, convex programs when truncated), embeds the canonical thickening
    and returns its base layer. Shape differences determine a pose only up to rigid motion; the
    result is placed by the rotation and translation that bring it closest to the base (least
    squares weighted by vertex area, per connected component). Loose vertices keep their base
    positions.
    """
    reference = differences.reference
    if not reference.matches(base_vertices, triangles):
        reference = ReferenceShape(
            base_vertices, triangles, offset=differences.offset, use_extrinsic=differences.use_extrinsic
        )
    metric = reference.recover_metric(differences)
    return reference.expand_pose(reference.place_near(reference.embed(metric), reference.base_positions))


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
) -> np.ndarray:
    """The pose at ``factor`` between ``vertices_a`` (0) and ``vertices_b`` (1): 0.5 is an
    in-between, 1.5 an exaggeration, negative values reverse the motion (§8.4). See
    :class:`Interpolator` to reuse the preparation for many factors.

    With ``target_triangles``, ``vertices_b`` is a pose of another mesh: it is first rebuilt on
    the mesh of ``vertices_a`` (:class:`Transfer`, ``k_M`` / ``k_N``, ``correspondence`` and
    ``target_rest_vertices`` as in :func:`shape_differences`), then in-betweened in the full basis."""
    from .interpolation import Interpolator

    if target_triangles is not None:
        from .transfer import transferred_keys

        (vertices_b,) = transferred_keys(
            vertices_a, triangles, [vertices_b], target_triangles, correspondence=correspondence,
            target_rest_vertices=target_rest_vertices, k_M=k_M, k_N=k_N, offset=offset, use_extrinsic=use_extrinsic,
        )
        k_M = k_N = None
    return Interpolator(
        vertices_a, vertices_b, triangles, k_M=k_M, k_N=k_N, offset=offset, use_extrinsic=use_extrinsic
    ).pose(factor)


def __getattr__(name: str):
    # Interpolation classes load on first use, keeping `import core` light.
    if name == "SequenceInterpolator":  # same-mesh, or key poses of another mesh (core.transfer)
        from .transfer import _sequence_class

        globals()[name] = _sequence_class()
        return globals()[name]
    if name == "Transfer":
        from .transfer import Transfer

        return Transfer
    if name in ("Interpolator", "SequenceInterpolator"):
        from . import interpolation

        return getattr(interpolation, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
