"""Distortion maps of a pose against its base: where and how the shape differences are not the
identity, as per-face and per-vertex scalars a user can paint on the mesh.

- **Area change** ``log(µ_N / µ_M)`` per triangle, and of the lumped vertex areas per vertex
  (what the area-based difference D_A measures; 0 where areas are kept).
- **Conformal distortion** ``σ₁/σ₂ ≥ 1`` per triangle, the ratio of the singular values of the
  linear map from the base triangle to the pose's (computed from edge lengths alone, like D_C):
  1 where angles are kept. Per vertex: the base-area-weighted mean of its triangles.
- **Bending**: the log area change of the offset surface at distance t (§5.2) minus the intrinsic
  log area change. An offset surface's area element is ``(1 + 2tH + t²K) dA``, so this is
  ≈ ``2t ΔH``: positive where the pose bulges more towards its normals than the base, negative
  where it folds in — what the extrinsic differences see and the intrinsic ones cannot. Per vertex
  from the offset triangles over it (Fig. 5: each has one lifted vertex), per face from those
  around its centre.
- **Leading eigenfunctions of each difference operator**: eigenvectors of the ``k × k``
  differences of eq. (5) in the base's first ``k`` eigenfunctions (``D_A c = ν c``;
  ``Φᵀ C_N Φ c = ν diag(λ) c`` for the conformal kinds), ordered by ``|log ν|``: the functions the
  pose stretches or shrinks most, scale by scale (the basis size bounds the finest scale). Offset
  kinds live on the offset surface and are read back at each base vertex's lifted vertex.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from . import deformation_fields as df
from .errors import MeshError
from .geometry import DIVISION_FLOOR, expand_vertex_values, lumped_vertex_areas
from .mesh_topology import triangle_areas
from .coordinate_rounding import across_edges, coordinate_rounding, inverse_heights
from .seam_folds import seam_sides, warn_seam_folds
from .shape_space_pca import KINDS, check_kind
from .validation import check_count

#: Default basis size for the eigenfunctions of the difference operators.
DEFAULT_EIGEN_BASIS = 50
#: Area change and conformal distortion per relative change of a triangle from the coordinates'
#: rounding (the rounding times :func:`core.coordinate_rounding.inverse_heights`): float32 copies of a
#: 2,000-vertex sphere, a 1,600-vertex sheet and cylinders of 32–128 sides with fan caps, turned
#: and moved up to 1,000 units, reached 1.2 of them (per face and per vertex).
ROUND_OFF_VALUES = 2.5
#: Bending per relative change of a triangle times ``1 + t / h`` (offset t; h the smallest height
#: of the triangle and of those across its edges): the offset surface's points above a triangle
#: and its neighbours lie t out along their normals, which the rounding turns by its size over
#: their height, so bending noise grows with t / h². Turned and moved in float32, up to 1,000 units
#: out: a 2,500-vertex icosphere 0.43 of this, a jittered sheet 0.57, cylinders' fan caps 0.13, a
#: scanned sphere (convex hull of random points) 0.31 — with the triangle's own height only (and
#: 2.0 here) faces beside its slivers reached 2.0. A 3 % swell on it 100 units out shows on 80 %
#: of its faces (84 % before).
BENDING_ROUND_OFF_VALUES = 1.0


@dataclass(frozen=True, eq=False)
class Distortion:
    """Distortion of one pose (see the module docstring). Face arrays ``(m,)`` follow
    ``triangles``; vertex arrays ``(n,)`` the base vertices (0 for vertices in no triangle)."""

    area_change_faces: np.ndarray
    area_change_vertices: np.ndarray
    conformal_faces: np.ndarray
    conformal_vertices: np.ndarray
    bending_faces: np.ndarray | None
    bending_vertices: np.ndarray | None
    #: Per face (m,) and per vertex (n,): the size of the area and conformal maps' values that the
    #: rounding of the coordinates alone makes (the rounding times :func:`core.coordinate_rounding.inverse_heights`
    #: times :data:`ROUND_OFF_VALUES`; a vertex: its faces', weighted as its values are), and for
    #: bending (:data:`BENDING_ROUND_OFF_VALUES`, from the thinnest of the face and the faces across
    #: its edges, :func:`core.coordinate_rounding.across_edges`; None without the offset surface): a pose that
    #: only moves its mesh has maps of at most about this size, not zero.
    round_off_faces: np.ndarray
    round_off_vertices: np.ndarray
    bending_round_off_faces: np.ndarray | None
    bending_round_off_vertices: np.ndarray | None
    _analyzer: "DistortionAnalyzer" = field(repr=False)
    _pose: np.ndarray = field(repr=False)

    def eigenfunctions(self, kind: str = "area", count: int = 4) -> tuple[np.ndarray, np.ndarray]:
        """The ``count`` leading eigenpairs of one difference operator: eigenvalues ``ν`` ``(count,)``
        (ordered by ``|log ν|``, largest first) and functions float64 ``(n, count)`` on the base
        vertices, each scaled to a maximum absolute value of 1 and signed by
        :func:`signed_unit_functions` (its sum of cubes positive; a tie, the first vertex not near
        zero positive)."""
        return self._analyzer.eigenfunctions(self._pose, kind, count)


#: :func:`signed_unit_functions` takes a function's sum of cubes as zero below this fraction of
#: its sum of absolute cubes, and a vertex value as zero below this fraction of its largest: far
#: above the eigensolver's rounding (~1e-13 of the largest value), far below what an asymmetric
#: function has.
SIGN_TIE = 1e-6


def signed_unit_functions(functions: np.ndarray) -> np.ndarray:
    """Functions ``(n, c)`` scaled to a largest absolute value of 1 and signed so that their sum of
    cubes is positive (their larger excursions positive), or, where that sum is within
    :data:`SIGN_TIE` of zero (a function odd under a symmetry of the mesh, whose maximum and minus
    its minimum tie), so that the first vertex (in the mesh's numbering) whose value is not within
    :data:`SIGN_TIE` of zero is positive. An eigenfunction's sign is arbitrary; this choice moves
    continuously with the pose except where the sum of cubes crosses the tie band; the sign of the
    largest value would flip under a 1e-9 rad turn wherever the maximum and minus the minimum tie."""
    largest = np.abs(functions).max(axis=0)
    unit = functions / np.where(largest == 0, 1.0, largest)
    cubes = np.sum(unit ** 3, axis=0)
    tied = np.abs(cubes) <= SIGN_TIE * np.sum(np.abs(unit) ** 3, axis=0)
    first = np.argmax(np.abs(unit) > SIGN_TIE, axis=0)  # every nonzero unit function has a value of 1
    sign = np.where(tied, np.sign(unit[first, np.arange(unit.shape[1])]), np.sign(cubes))
    return unit * np.where(sign == 0, 1.0, sign)


class DistortionAnalyzer:
    """A base mesh prepared once (topology, offset surface, eigenbases) for the distortion maps
    of many poses: ``DistortionAnalyzer(base, triangles).pose(vertices)``."""

    def __init__(self, base_vertices, triangles, *, offset: float | None = None, use_extrinsic: bool = True,
                 k: int | None = None, single_precision: bool | None = None):
        """``single_precision``: whether the poses' coordinates were stored in single precision
        (Blender's keys and frames, also after a transform in double precision); ``None``: where
        every coordinate is a float32. It sizes :attr:`Distortion.round_off_faces`."""
        from .reference_shape import ReferenceShape

        # in the caller's units (unit 1): the maps neither recover nor embed, and report lengths as given
        self.reference = ReferenceShape(base_vertices, triangles, offset=offset, use_extrinsic=use_extrinsic,
                                        unit=1.0)
        ref = self.reference
        # the default shrinks to a small mesh; a size given is checked against the mesh where the
        # eigenfunctions are asked for (the maps do not use it)
        self.k = min(DEFAULT_EIGEN_BASIS, ref.topology.n_vertices - 1) if k is None else check_count(k, "k", minimum=1)
        self._k_given = k is not None
        self.single_precision = single_precision
        self._inverse_heights = inverse_heights(ref.base.positions, ref.topology.triangles)  # the base's, every pose
        self._across_inverse_heights = across_edges(self._inverse_heights, ref.topology.triangles)  # bending's
        self._base_inverse = df.inverse_edge_rows(_tangent_coordinates(ref.base.positions, ref.topology.triangles))
        self._base_vertex_area = lumped_vertex_areas(ref.topology.triangles, ref.base.areas, ref.topology.n_vertices)
        self._seam_sides = seam_sides([ref.base.positions], ref.topology)  # pieces apart along seams
        self._seam_folds_told = False
        self._splits_told = set()  # basis sizes warned of splitting a group of equal eigenvalues
        if ref.use_extrinsic:
            surface = ref.surface
            offset_tris = surface.topology.triangles
            # Offset triangles are (a_t, c_T2, c_T1): corner 0 is the lifted vertex, 1–2 centres.
            self._lift_owner = surface.lifted_vertices[offset_tris[:, 0]]
            n_lift = surface.lifted_vertices.size
            self._center_owner = surface.centered_triangles[offset_tris[:, 1:] - n_lift]  # (m_t, 2)
            self._base_offset_vertex = self._offset_sums(ref.offset_layer.areas)

    # -- per-face and per-vertex maps ---------------------------------------------------------
    def pose(self, pose_vertices, *, name: str = "pose vertices") -> Distortion:
        """The maps of one pose ``(n, 3)`` (``name``: what errors about it call it)."""
        ref = self.reference
        pose = ref.compact_pose(pose_vertices, name=name)
        topo = ref.topology
        areas = triangle_areas(pose, topo.triangles)
        area_faces = np.log(areas / ref.base.areas)
        area_vertices = np.log(lumped_vertex_areas(topo.triangles, areas, topo.n_vertices) / self._base_vertex_area)
        conformal_faces = _conformal_ratio(self._base_inverse, _tangent_coordinates(pose, topo.triangles))
        # Base-area-weighted mean over each vertex's triangles (the thirds cancel).
        conformal_vertices = lumped_vertex_areas(topo.triangles, ref.base.areas * conformal_faces,
                                                 topo.n_vertices) / self._base_vertex_area
        bending_faces = bending_vertices = None
        if ref.use_extrinsic:
            offset_positions = ref.surface.positions(pose, ref.offset)
            offset_areas = triangle_areas(offset_positions, ref.surface.topology.triangles)
            vertex_sum, face_sum = self._offset_sums(offset_areas)
            base_vertex_sum, base_face_sum = self._base_offset_vertex
            with np.errstate(divide="ignore", invalid="ignore"):
                bending_vertices = np.where(base_vertex_sum > 0, np.log(vertex_sum / base_vertex_sum), 0.0)
                bending_faces = np.where(base_face_sum > 0, np.log(face_sum / base_face_sum), 0.0)
            bending_vertices = np.where(base_vertex_sum > 0, bending_vertices - area_vertices, 0.0)
            bending_faces = np.where(base_face_sum > 0, bending_faces - area_faces, 0.0)
        if len(self._seam_sides) and not self._seam_folds_told:  # once: the first pose that folds them
            self._seam_folds_told = warn_seam_folds(
                ref.base.positions, [pose], topo.triangles, self._seam_sides, self.single_precision, name,
                "the maps compare each piece on its own, so they show no bending along those seams")
        rounding = coordinate_rounding([ref.base.positions, pose], self.single_precision)
        relative = rounding * self._inverse_heights  # rounding / h

        def per_vertex(per_face):  # a vertex's values are base-area-weighted over its faces: so is their round-off
            return _scatter(ref, lumped_vertex_areas(topo.triangles, ref.base.areas * per_face,
                                                     topo.n_vertices) / self._base_vertex_area)

        round_off = ROUND_OFF_VALUES * relative
        bending_round_off = None
        if ref.use_extrinsic and rounding > 0:  # 1 + t / h
            across = rounding * self._across_inverse_heights
            bending_round_off = BENDING_ROUND_OFF_VALUES * across * (1.0 + ref.offset * across / rounding)
        elif ref.use_extrinsic:
            bending_round_off = np.zeros_like(relative)
        return Distortion(
            area_change_faces=area_faces,
            area_change_vertices=_scatter(ref, area_vertices),
            conformal_faces=conformal_faces,
            conformal_vertices=_scatter(ref, conformal_vertices),
            bending_faces=bending_faces,
            bending_vertices=None if bending_vertices is None else _scatter(ref, bending_vertices),
            round_off_faces=round_off,
            round_off_vertices=per_vertex(round_off),
            bending_round_off_faces=bending_round_off,
            bending_round_off_vertices=None if bending_round_off is None else per_vertex(bending_round_off),
            _analyzer=self,
            _pose=pose,
        )

    def _offset_sums(self, offset_areas):
        topo = self.reference.topology
        vertex_sum = np.bincount(self._lift_owner, offset_areas, topo.n_vertices)
        face_sum = np.bincount(self._center_owner.ravel(), np.repeat(offset_areas, 2), topo.n_triangles)
        return vertex_sum, face_sum

    # -- eigenfunctions of the difference operators ---------------------------------------------
    def eigenfunctions(self, pose: np.ndarray, kind: str, count: int):
        from .inner_products import pose_products

        check_kind(kind)
        count = check_count(count, "count")
        ref = self.reference
        if kind.startswith("offset"):
            if not ref.use_extrinsic:
                raise MeshError("This analyzer was built without the offset surface (use_extrinsic=False).")
            layer, positions = ref.offset_layer, ref.surface.positions(pose, ref.offset)
        else:
            layer, positions = ref.base, pose
        k = ref.basis_sizes(self.k, None, full_basis=False)[0] if self._k_given else self.k
        k = min(k, layer.topology.n_vertices - 1)
        if k not in self._splits_told and layer.split_group(k) is not None:
            # The operator restricted to the first k functions: ended inside a group of equal
            # eigenvalues, its eigenpairs depend on which part of the group rounding picked.
            self._splits_told.add(k)  # once per size: one warning names every layer's groups
            ref.warn_split(k, label="k")
        basis = layer.basis(k)
        _, _, mass, conformal = pose_products(layer.assembler, positions)
        phi = basis.functions
        if kind.endswith("area"):
            values, vectors = np.linalg.eigh(phi.T @ (mass @ phi))
        else:
            keep = basis.pseudo_inverse_eigenvalues() > 0
            reduced = phi[:, keep].T @ (conformal @ phi[:, keep])
            values, vectors = sla.eigh(0.5 * (reduced + reduced.T), np.diag(basis.eigenvalues[keep]))
            phi = phi[:, keep]
        order = np.argsort(-np.abs(np.log(np.maximum(values, DIVISION_FLOOR))), kind="stable")[:count]
        functions = phi @ vectors[:, order]
        if kind.startswith("offset"):
            functions = self._on_base_vertices(functions)
        return values[order], _scatter(ref, signed_unit_functions(functions))

    def _on_base_vertices(self, offset_values: np.ndarray) -> np.ndarray:
        """Offset-surface vertex values ``(n_t, c)`` at the base vertices ``(n, c)``: the lifted
        vertex's value, or for a vertex with none (a corner touching no interior edge) the mean of
        the centres of its triangles."""
        surface = self.reference.surface
        topo = self.reference.topology
        out = np.zeros((topo.n_vertices, offset_values.shape[1]))
        out[surface.lifted_vertices] = offset_values[: surface.lifted_vertices.size]
        missing = np.flatnonzero(surface.lift_of_vertex < 0)
        for vertex in missing:
            centers = surface.center_of_triangle[np.flatnonzero((topo.triangles == vertex).any(axis=1))]
            centers = centers[centers >= 0]
            if centers.size:
                out[vertex] = offset_values[centers].mean(axis=0)
        return out


def distortion(base_vertices, pose_vertices, triangles, *, offset: float | None = None,
               use_extrinsic: bool = True, k: int | None = None, single_precision: bool | None = None) -> Distortion:
    """Distortion maps of ``pose_vertices`` ``(n, 3)`` against ``base_vertices`` ``(n, 3)`` with
    ``triangles`` ``(m, 3)`` (see :mod:`core.distortion_maps`); ``offset`` the offset distance t
    (``None``: half the mean edge length), ``k`` the basis size for :meth:`Distortion.eigenfunctions`
    (``None``: :data:`DEFAULT_EIGEN_BASIS`, at most the vertex count less one).
    For many poses of one base, reuse a :class:`DistortionAnalyzer`."""
    return DistortionAnalyzer(base_vertices, triangles, offset=offset, use_extrinsic=use_extrinsic, k=k,
                              single_precision=single_precision).pose(pose_vertices)


# -- helpers -----------------------------------------------------------------------------------
def _scatter(reference, values):
    """Used-vertex values ``(n_used, ...)`` to all vertices ``(n, ...)``, 0 at loose vertices."""
    return expand_vertex_values(reference.used_vertices, values, reference.n_vertices)


def _tangent_coordinates(positions, triangles):
    """Corner edges of each triangle in its own tangent basis (2, 3 corners, m), from the
    positions: a triangle whose height is 1e-9 of its edges keeps it (laid out from its squared
    edge lengths it came out flat and its conformal ratio's solve was singular)."""
    return df.tangent_frame_rows(df.corner_edges(positions, triangles).transpose(2, 1, 0))[1]


def _conformal_ratio(base_inverse, pose_coordinates):
    """σ₁/σ₂ (m,) of the deformation gradients ``J`` from the base triangles (``base_inverse``:
    their inverse edge matrices, :func:`core.deformation_fields.inverse_edge_rows`) to the pose's
    (``pose_coordinates``: :func:`_tangent_coordinates`): ``σ₁² / det J`` with ``σ₁²`` the larger
    root of ``σ² − |J|²σ + det² = 0`` (no difference of nearly equal numbers)."""
    a, b, c, d = df.planar_map_entries(pose_coordinates, base_inverse)
    squared = a * a + b * b + c * c + d * d
    det = np.abs(a * d - b * c)
    largest = 0.5 * (squared + np.sqrt(np.maximum(squared * squared - 4.0 * det * det, 0.0)))
    return largest / np.maximum(det, DIVISION_FLOOR * largest)
