"""Recovery of triangle areas and squared edge lengths from full-basis products (paper §4.2,
Props. 1–2, appendix): two sparse linear solves.

- Areas µ from ``A = A(µ)``: the off-diagonal entries of ``A`` are sums of the areas of the
  triangles around an edge (``/12``); the diagonal ones are implied by them. The least-squares
  system is singular exactly when a closed connected component has a bipartite dual graph (its
  triangles two-coloured so that every edge joins both colours): areas changed by +ε on one colour
  and −ε on the other leave every edge sum unchanged. Every vertex then has even valence (Prop. 1's
  sufficient condition fails); on a sphere the converse holds too, but on a closed surface of
  genus ≥ 1 an odd cycle of triangles can go around a handle with all valences even, and then the
  areas are recoverable. The exact condition is checked combinatorially.
- Squared lengths ℓ² from the per-edge entries of ``C = C(ℓ²; µ)`` with µ fixed: a square sparse
  system ``B_µ ℓ² = c``. It is singular for rare area distributions (Fig. 2: two tetrahedra glued
  at their bases with equal areas, and every flat regular grid); Heron's formula, with the known
  areas, then supplies the missing equations (see :func:`recover_squared_lengths`).
"""

from __future__ import annotations


import numpy as np
import scipy.sparse as sp

from .errors import RecoveryError, warn
from .geometry import heron
from .inner_products import ProductAssembler
from .mesh_topology import MeshTopology

#: The direct solution is accepted when Heron's formula holds to this relative accuracy; otherwise
#: (``B_µ`` singular or ill conditioned) Gauss–Newton on both sets of equations polishes it.
HERON_CHECK = 1e-8
#: That Gauss–Newton runs until its residual stops shrinking (the rounding floor) and succeeds if
#: the residual is then below this fraction of the data's size; above it the data are no mesh's and
#: its last iterate is their least-squares fit (returned with a warning).
HERON_ACCEPTED_RESIDUAL = 1e-7
MAX_HERON_ITERATIONS = 30
#: Without a direct solution the Gauss–Newton starts from the solution of ``B_µ ℓ² = c`` nearest
#: the reference lengths: Tikhonov weight relative to ‖B_µ‖², enough to factorize the normal matrix.
TIKHONOV = 1e-10


class AreaRecovery:
    """Prop. 1 for one topology: factorizes the normal equations of µ ↦ edge entries of ``A(µ)``
    (the dual graph's pattern: 4 nonzeros per row) once,
    then recovers the areas of any number of targets with two triangular solves each."""

    def __init__(self, assembler: ProductAssembler):
        self.assembler = assembler
        check_area_recoverable(assembler.topology)
        self._map = assembler.area_map().tocsc()
        self._factor = _spd_factor((self._map.T @ self._map).tocsc())

    def solve(self, edge_values: np.ndarray) -> np.ndarray:
        """Areas µ ``(m,)`` from the per-edge entries ``(E,)`` of ``A`` (least squares)."""
        return self._factor.solve(self._map.T @ edge_values)


def two_colour_parts(topology: MeshTopology) -> tuple[np.ndarray, np.ndarray]:
    """The connected parts of ``topology`` whose areas full-basis differences cannot determine:
    (each triangle's part, int64 ``(m,)``; those parts, int64 ``(p,)``), the parts closed and with a
    bipartite dual graph (see :func:`check_area_recoverable`)."""
    from scipy.sparse.csgraph import connected_components

    count, labels = topology.components()
    has_boundary = np.zeros(count, dtype=bool)
    boundary_triangles = topology.edge_triangles[topology.boundary_edges].max(axis=1)
    has_boundary[labels[boundary_triangles]] = True
    # Bipartite double cover: triangle t has copies t and t + m, and each interior edge joins
    # opposite copies. A component is bipartite exactly when its two copies stay disconnected.
    m = topology.n_triangles
    inner = topology.edge_triangles[topology.interior_edges]
    cover = sp.coo_matrix(
        (np.ones(2 * len(inner)), (np.concatenate([inner[:, 0], inner[:, 0] + m]),
                                   np.concatenate([inner[:, 1] + m, inner[:, 1]]))),
        shape=(2 * m, 2 * m),
    )
    _, cover_labels = connected_components(cover, directed=False)
    bipartite = np.zeros(count, dtype=bool)
    bipartite[labels[cover_labels[:m] != cover_labels[m:]]] = True
    return labels, np.flatnonzero(~has_boundary & bipartite)


def check_area_recoverable(topology: MeshTopology) -> None:
    """Raise :class:`RecoveryError` if some connected component is closed and its dual graph is
    bipartite (then ``A(µ)`` does not determine µ: the kernel of µ ↦ edge entries is ±1 on the two
    colours). Otherwise the areas are determined: a boundary edge's entry is one triangle's area,
    and an odd cycle of triangles, along which a kernel vector would alternate in sign, forces it
    to vanish; flood fill along the edge sums then fixes the whole component. This is the exact
    condition; Prop. 1's (a boundary or an odd-valence vertex) is sufficient only."""
    labels, bad = two_colour_parts(topology)
    if bad.size:
        first = int(np.flatnonzero(labels == bad[0])[0])
        raise RecoveryError(
            f"The closed part of the mesh containing triangle {first} has triangles in two "
            "alternating colours (neighbours across every edge differ; all its vertices have even "
            "valence, e.g. an octahedron), so its triangle areas cannot be recovered from the "
            "area-based shape difference (paper Prop. 1). Triangulate it differently (any vertex "
            "of odd valence suffices), e.g. flip one edge (Mesh > Edge > Rotate Edge)."
        )


def recover_squared_lengths(
    assembler: ProductAssembler,
    areas: np.ndarray,
    edge_values: np.ndarray,
    *,
    reference_squared_lengths: np.ndarray | None = None,
    what: str = "mesh",
) -> np.ndarray:
    """Prop. 2: squared edge lengths ℓ² ``(E,)`` from the per-edge entries ``c`` ``(E,)`` of
    ``C(ℓ²; µ)`` and the (recovered) areas µ ``(m,)``.

    One sparse LU solve of ``B_µ ℓ² = c``, checked against Heron's formula. ``B_µ`` is singular
    for some area distributions — Fig. 2, and (measured) every flat regular grid, i.e. the rest
    pose of most cloth, where all areas are equal. The areas carry the missing information:
    Heron's formula ``16µ² = 2(x₁x₂ + x₂x₃ + x₃x₁) − (x₁² + x₂² + x₃²)`` per triangle. Then a
    sparse Gauss–Newton solve of both sets of equations, started from the direct solution (or,
    if there is none, from the Tikhonov solution nearest ``reference_squared_lengths``),
    recovers ℓ²; one step usually suffices, since the error of the direct solution lies in the
    near-kernel of ``B_µ``. Data that are no mesh's (differences edited, blended, rounded or
    noisy) leave a residual: the least-squares fit is returned with a
    :class:`ShapeDifferenceWarning` giving its misfit. :class:`RecoveryError` if even that system
    is singular, or the fit breaks a triangle inequality.
    """
    if not (np.all(np.isfinite(areas)) and np.all(areas > 0)):
        bad = int(np.flatnonzero(~(areas > 0))[0])
        raise RecoveryError(
            f"The recovered area of triangle {bad} of the {what} is {areas[bad]:.3g}: edge lengths "
            "need positive areas. The shape difference does not describe a valid mesh."
        )
    from scipy.sparse.linalg import splu

    matrix = assembler.length_map(areas).tocsc()
    target = 16.0 * areas**2
    try:
        solution = splu(matrix).solve(edge_values)
    except RuntimeError:  # exactly singular
        solution = None
    if solution is not None and np.all(np.isfinite(solution)):
        value, _ = _heron(assembler.topology, solution)
        if np.max(np.abs(value - target) / target) <= HERON_CHECK:
            return solution
    return _lengths_with_heron(assembler, matrix, areas, edge_values, solution, reference_squared_lengths, what)


def _heron(topology, squared_lengths):
    """16µ² from squared lengths per triangle ``(m,)`` and its Jacobian (sparse ``(m, E)``)."""
    x = squared_lengths[topology.triangle_edges]  # (m, 3)
    total = x.sum(axis=1, keepdims=True)
    value = heron(x)
    gradient = 2.0 * (total - 2.0 * x)  # ∂/∂x_k = 2(x_{k+1} + x_{k+2} − x_k)
    m = topology.n_triangles
    jacobian = sp.csr_matrix(
        (gradient.ravel(), (np.repeat(np.arange(m), 3), topology.triangle_edges.ravel())),
        shape=(m, topology.n_edges),
    )
    return value, jacobian


def _spd_factor(matrix):
    """The factor of a symmetric positive definite matrix (:class:`core.sparse_cholesky.SPDFactor`:
    CHOLMOD's supernodal Cholesky, or SuperLU without it)."""
    from .sparse_cholesky import SPDFactor

    return SPDFactor(matrix)


def _lengths_with_heron(assembler, matrix, areas, edge_values, start, reference, what):
    topology = assembler.topology
    target = 16.0 * areas**2
    weight = sp.diags(1.0 / target)  # Heron residuals relative to 16µ²: dimensionless like c
    if start is not None and np.all(np.isfinite(start)) and np.all(start > 0):
        x = start
    else:  # the solution of B x = c nearest the reference lengths (Tikhonov)
        x = (
            np.full(topology.n_edges, np.mean(4.0 * areas) / np.sqrt(3.0))
            if reference is None
            else np.asarray(reference, dtype=np.float64)
        )
        scale = abs(matrix).max()
        normal = (matrix.T @ matrix + TIKHONOV * scale**2 * sp.identity(topology.n_edges)).tocsc()
        x = x + _spd_factor(normal).solve(matrix.T @ (edge_values - matrix @ x))
    data_size = np.linalg.norm(edge_values) + np.sqrt(topology.n_triangles)
    previous = np.inf
    for _ in range(MAX_HERON_ITERATIONS):
        value, jacobian = _heron(topology, x)
        linear_residual = matrix @ x - edge_values
        residual = np.concatenate([linear_residual, weight @ (value - target)])
        size = np.linalg.norm(residual)
        if np.max(np.abs(value - target) / target) <= HERON_CHECK and np.linalg.norm(
            linear_residual
        ) <= HERON_CHECK * data_size:
            return x
        if size > 0.5 * previous:  # no longer converging: at the rounding floor, or stuck
            break
        previous, best = size, x
        stacked = sp.vstack([matrix, weight @ jacobian]).tocsc()
        try:
            step = _spd_factor((stacked.T @ stacked).tocsc()).solve(-(stacked.T @ residual))
        except (RuntimeError, np.linalg.LinAlgError) as error:  # singular, or not positive definite in round-off
            raise _singular_length_system(what) from error
        if not np.all(np.isfinite(step)):
            raise _singular_length_system(what)
        x = x + step
    if not previous <= HERON_ACCEPTED_RESIDUAL * data_size:
        # Gauss–Newton settled above the rounding floor: no squared lengths satisfy both sets of
        # equations, so the data are not those of a mesh with these areas (differences edited,
        # blended as in §8.4, or noisy). Its last iterate is the closest fit (least squares over
        # both), which is what the differences can still tell when it describes triangles.
        value, _ = _heron(topology, best)
        misfit = np.linalg.norm(matrix @ best - edge_values) / np.linalg.norm(edge_values)
        broken = np.any(best[topology.triangle_edges] <= 0, axis=1) | (value <= 0)
        if broken.any():
            raise RecoveryError(
                f"The conformal shape difference of the {what} is not that of any mesh with the "
                f"recovered triangle areas (differences edited, blended or noisy): the closest edge "
                f"lengths, {misfit:.2g} off its entries, break the triangle inequality in "
                f"{int(broken.sum())} of {broken.size} triangles."
            )
        warn(
            f"The differences of the {what} are not exactly those of any mesh (edited, blended or noisy): "
            f"the edge lengths returned fit them closest, {misfit:.2g} off (a mesh's own differences: "
            "round-off) (the conformal difference does not fit the recovered triangle areas).",
            "inconsistent",
        )
    return best


def _singular_length_system(what: str) -> RecoveryError:
    return RecoveryError(
        f"The conformal shape difference of the {what} does not determine its edge lengths for "
        "these triangle areas: the linear system of Prop. 2 is singular (as for two tetrahedra "
        "glued at their bases with equal areas, paper Fig. 2) and Heron's formula does not "
        "resolve it (a nearly flat triangle, a sliver, can also make it so numerically). Perturb the mesh "
        "slightly or remesh it."
    )
