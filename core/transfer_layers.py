"""The target's layers in a :class:`~core.transfer.Transfer` (paper §6.2–6.3): the mesh N and its
offset surface N_t, each with its product assembler, its eigenbasis per pose (warm-started from
the previous pose's) and the eq. (6) differences through the functional map from the matching
base layer; and the offset layers' correspondence, from the base layer's map."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .functional_map import functional_map, project_near
from .inner_products import ProductAssembler, pose_products
from .laplace_basis import LaplaceBasis, laplace_basis, split_group, warm_laplace_basis

#: Target eigenbases after the first pose: warm-started subspace iterations from the previous
#: pose's functions, SUBSPACE_MARGIN × k_N of them (the extra ones speed up convergence of the k_N
#: wanted).
SUBSPACE_MARGIN = 1.5
#: ... exactly this many iterations (one gave differences 4.6e-5 off instead of 1e-5 in the
#: identity-map test), accepted when every wanted Ritz pair's residual is at most
#: WARM_RESIDUAL × λ_k (else ARPACK). Far looser than a converged basis needs
#: (:data:`~core.laplace_basis.WARM_TOLERANCE`): the target's functions only serve as the space the
#: pushed base functions are fitted in, and its top eigenpairs matter little. Measured on the
#: re-meshed drape (1,296 / 3,743 target vertices, k_N = 200, frames 20 → 40 and 20 → 21): residuals
#: 1e-2 (mesh) and 5e-2 (offset surface) after two iterations, the four differences within
#: 1.5e-3 (relative) of those with ARPACK's bases, both eigenbases 2.1–3.4× faster than ARPACK's;
#: converging to 1e-6 would take more iterations than ARPACK costs. A start far from the pose
#: (residual ≈ λ_k) still falls back.
SUBSPACE_ITERATIONS = 2
WARM_RESIDUAL = 0.1
#: ... and up to this many iterations while the residual test fails, before ARPACK: the first pose
#: of a transfer starts from the basis of the base's rest carried onto the target (computed for the
#: meshing correction), which may be far. On the 5k limb, frame 38 (joints bent 70° and 80°):
#: residual / λ_k 0.16 / 0.12 / 0.087 after 1 / 2 / 3 iterations on the mesh, 0.19 / 0.15 / 0.13 /
#: 0.11 / 0.078 after 1–5 on the offset surface (3.5 s each), against 45 s for ARPACK's bases.
SUBSPACE_MAX_ITERATIONS = 6


def whole_groups(basis: LaplaceBasis, k: int) -> LaplaceBasis:
    """``basis`` (``p > k`` eigenpairs, ascending) without its last group of equal eigenvalues
    (:func:`~core.laplace_basis.split_group`) when that group may go on past it and the ``k`` wanted
    functions stay: the start of :func:`~core.laplace_basis.warm_laplace_basis`. Its iterations
    depend only on the span of their start, and the part of an eigenspace that ``p`` functions end
    inside is the eigensolver's arbitrary choice; the few iterations that the loose
    :data:`WARM_RESIDUAL` stops after would leave that choice in the ``k`` wanted functions (a
    symmetric target's transferred pose: 1e-3 of its diagonal under a re-numbering of the target's
    vertices or a 1e-9 rad turn)."""
    group = split_group(basis.eigenvalues, basis.eigenvalues.size - 1)
    if group is None or group[0] <= k:
        return basis
    return LaplaceBasis(basis.eigenvalues[:group[0]], basis.functions[:, :group[0]])


class TargetLayer:
    """One layer of the target (N or N_t): topology, product assembler, and the push-forward
    ``Q`` ``(n_N, n_M)`` of functions from the matching base layer."""

    def __init__(self, name, topology, push):
        self.name = name
        self.topology = topology
        self.assembler = ProductAssembler(topology)
        self.push = push
        self._pushed = {}
        self._subspace = None  # (k_N, functions (n, p)) of the last pose, the next one's start

    def basis(self, mass, conformal, k: int, start=None):
        """The first ``k`` eigenpairs of this pose (§6.2). The first pose gets ARPACK's
        (:func:`~core.laplace_basis.laplace_basis`) with :data:`SUBSPACE_MARGIN` × ``k`` functions,
        or starts from ``start`` ``(n, p)`` when given (functions of a nearby surface); every later
        pose, :func:`~core.laplace_basis.warm_laplace_basis` started from the previous
        pose's functions (:data:`SUBSPACE_ITERATIONS` to :data:`SUBSPACE_MAX_ITERATIONS`,
        :data:`WARM_RESIDUAL`) — a pose of the same
        mesh, whose eigenspaces move little (measured ARPACK at k = 200: 95 % of its time in its own
        re-orthogonalization)."""
        n = mass.shape[0]
        p = min(n - 1, int(np.ceil(SUBSPACE_MARGIN * k)))
        if self._subspace is None and start is not None and start.shape[0] == n and k < start.shape[1] <= p:
            self._subspace = (k, start)
        if self._subspace is None or self._subspace[0] != k or p <= k:
            full = laplace_basis(mass, conformal, p if p > k else k, what=f"target {self.name}")
            if p > k:
                full = whole_groups(full, k)
        else:
            full = warm_laplace_basis(mass, conformal, k, self._subspace[1], iterations=SUBSPACE_MAX_ITERATIONS,
                                      min_iterations=SUBSPACE_ITERATIONS,
                                      tolerance=WARM_RESIDUAL, what=f"target {self.name}")
        self._subspace = (k, full.functions)
        return LaplaceBasis(full.eigenvalues[:k], full.functions[:, :k])

    def differences(self, base_layer, positions, k_M, k_N, start=None):
        """Eq. (6) differences ``(area, conformal)`` of a pose ``positions`` of this layer on
        ``base_layer``'s k_M functions (``start``: as for :meth:`basis`)."""
        from .shape_difference import map_differences

        base_basis = base_layer.basis(k_M)
        _, _, mass, conformal = pose_products(self.assembler, positions)
        target_basis = self.basis(mass, conformal, k_N, start)
        if k_M not in self._pushed:  # Q Φ_M depends on the base and the map only
            self._pushed = {k_M: np.asarray(self.push @ base_basis.functions)}
        fmap = functional_map(target_basis.functions, mass, self._pushed[k_M])
        return map_differences(base_basis, target_basis.eigenvalues, fmap)


def offset_surfaces_pull_back(base_surface, target_surface, image_triangles, weights, seeds, target_rest):
    """``Π_t`` ``(n_Mt, n_Nt)`` between the offset surfaces from the base layer's point-to-surface
    map (each base vertex's image: target triangle ``image_triangles`` ``(n_M,)``, barycentric
    ``weights`` ``(n_M, 3)``; ``seeds`` its matched target vertex) and the target's rest pose.

    A lifted base vertex takes its vertex's weights on the lifted target vertices at the corners
    (renormalized; the nearest lifted vertex where no corner is lifted). A base face center maps
    to the point above the mean of its corners' images: projected onto the target surface near
    the first corner's match, in target triangle ``T`` at weights ``w``, it is written on the
    vertices of the offset surface above ``T`` — ``3 min(w)`` on the face center of ``T`` (above
    its barycenter) and ``w − min(w)`` on the lifted corners (a convex combination of nearby
    offset vertices, exact for functions that are affine there)."""
    from scipy.spatial import cKDTree

    target = target_surface.base
    lift = target_surface.lift_of_vertex
    center = target_surface.center_of_triangle

    def rows(corner_lifts, corner_weights, centers, center_weights, fallback_points):
        w = np.where(corner_lifts >= 0, corner_weights, 0.0)
        c = np.where(centers >= 0, center_weights, 0.0)
        total = w.sum(axis=1) + c
        lost = ~(total > 1e-12)
        if lost.any():  # no offset vertex above the image: the nearest lifted one
            _, nearest = cKDTree(target_rest[target_surface.lifted_vertices]).query(fallback_points[lost])
            corner_lifts, w = corner_lifts.copy(), w.copy()
            corner_lifts[lost, 0], w[lost] = nearest, [1.0, 0.0, 0.0]
            total[lost] = 1.0
        columns = np.concatenate([np.maximum(corner_lifts, 0), np.maximum(centers, 0)[:, None]], axis=1)
        values = np.concatenate([w, c[:, None]], axis=1) / total[:, None]
        return columns, values

    corners = target.triangles[image_triangles]  # (n_M, 3)
    lifted = base_surface.lifted_vertices
    images = np.einsum("nk,nki->ni", weights, target_rest[corners])
    lift_cols, lift_vals = rows(lift[corners[lifted]], weights[lifted], np.full(lifted.size, -1), np.zeros(lifted.size),
                                images[lifted])

    base_corners = base_surface.base.triangles[base_surface.centered_triangles]  # (m_c, 3) base vertices
    q = images[base_corners].mean(axis=1)
    triangles, w = project_near(q, seeds[base_corners[:, 0]], target_rest, target.triangles)
    low = w.min(axis=1)
    center_cols, center_vals = rows(lift[target.triangles[triangles]], w - low[:, None], center[triangles], 3.0 * low, q)

    columns = np.concatenate([lift_cols, center_cols])
    values = np.concatenate([lift_vals, center_vals])
    n_rows = columns.shape[0]
    return sp.csr_matrix((values.ravel(), (np.repeat(np.arange(n_rows), 4), columns.ravel())),
                         shape=(n_rows, target_surface.topology.n_vertices))
