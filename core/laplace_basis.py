"""Laplace–Beltrami eigenbasis of a mesh (paper §6.2): ``C φ = λ A φ``, ``λ ≥ 0``, A-orthonormal."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import MeshError, RecoveryError

#: Up to this many vertices a dense generalized eigensolver is faster and more robust than ARPACK.
DENSE_EIGEN_LIMIT = 600
#: Above it, a basis of at least this fraction of the vertices is also computed densely
#: (``scipy.linalg.eigh`` with ``subset_by_index``): ARPACK's cost grows like n k², the dense
#: solve's like n³. Measured on a 2,500-vertex sheet, one BLAS thread, same (loaded) run: ARPACK
#: 1.2 / 2.2 / 6.7 / 29 s for k = 50 / 100 / 200 / 400, dense 27 s for k = 500 and 1,000, 59 s
#: for k = 2,000 (ARPACK did not finish k = 2,000 in 250 s in issue 19). LAPACK's divide and
#: conquer (``driver="gvd"``) on every eigenpair, then truncated, beats the subset driver ``gvx``
#: even for k = 500 (another loaded run: 50 s against 78 s for k = 500 and 81 s for k = 2,000).
DENSE_EIGEN_FRACTION = 1.0 / 6.0
#: Largest vertex count solved densely (two n × n float64 matrices and LAPACK's work space:
#: about 3 GB at this size); larger meshes use ARPACK whatever k.
DENSE_EIGEN_MAX_VERTICES = 12000


@dataclass(frozen=True, eq=False)
class LaplaceBasis:
    """The first ``k`` eigenpairs: ``eigenvalues`` float64 ``(k,)`` ascending (the first ≈ 0 per
    connected component) and ``functions`` float64 ``(n, k)`` with ``Φᵀ A Φ = I``."""

    eigenvalues: np.ndarray
    functions: np.ndarray

    @property
    def size(self) -> int:
        return int(self.eigenvalues.size)

    def pseudo_inverse_eigenvalues(self, relative_tolerance: float = 1e-9) -> np.ndarray:
        """``diag(λ)⁺`` of eq. (5) as a vector ``(k,)``: 1/λ, and 0 for the (near-)zero modes."""
        scale = max(float(np.max(np.abs(self.eigenvalues))), np.finfo(float).tiny)
        out = np.zeros_like(self.eigenvalues)
        keep = np.abs(self.eigenvalues) > relative_tolerance * scale
        out[keep] = 1.0 / self.eigenvalues[keep]
        return out


def basis_sizes(k_M, k_N, n_vertices: int | None = None) -> tuple[int | None, int | None]:
    """Normalize the basis sizes of eqs. (5)–(6): ``None`` or ``0`` means the full basis (the
    sidebar's convention); ``k_N`` (target basis) needs ``k_M`` (base basis). Whole numbers only,
    below ``n_vertices`` when given (:func:`core.validation.check_basis_sizes`)."""
    from .validation import check_basis_sizes

    return check_basis_sizes(k_M, k_N, n_vertices)


#: Two consecutive eigenvalues closer than this (relative to the larger) count as one repeated
#: eigenvalue for :func:`split_group`. Exactly repeated eigenvalues (an icosphere's, a regular
#: grid's) come out of the eigensolvers within 1e-15 (dense, 162 vertices) and 1e-12 (ARPACK, 10k
#: vertices) of each other; above this threshold a rounding-size change of the matrices (~1e-15
#: relative) turns the first ``k`` functions of a group split by a relative gap ``g`` by about
#: ``1e-15 / g`` ≤ 1e-5 rad (Davis–Kahan). Meshes without a symmetry have larger gaps: 5e-3 and
#: 2.4e-4 at k 50 / 100 on a 10k-vertex cloth, 2.9e-7 and 2.5e-8 on square grids of 30² and 100²
#: vertices jittered by 0.1 edge (the x ↔ y pairs of a square, split by the jitter only).
REPEATED_GAP = 1e-10
#: Eigenpairs computed past a truncated basis size ``k`` to see whether it splits a group
#: (:func:`split_group`); more are computed only where the group reaches past them.
SPLIT_LOOKAHEAD = 2


def split_group(eigenvalues: np.ndarray, k: int, gap: float = REPEATED_GAP) -> tuple[int, int] | None:
    """Whether the first ``k`` of ``eigenvalues`` (float64 ``(p,)`` ascending, ``p > k``) end inside
    a group of equal ones (consecutive relative gaps at most ``gap``): its index range
    ``(first, end)`` (``eigenvalues[first:end]``; ``end == p`` when it may go on past them), or
    ``None`` where eigenvalue ``k`` is more than ``gap`` above eigenvalue ``k − 1``. A truncated
    basis (paper §4–5) that splits a group holds an arbitrary part of its eigenspace."""
    values = np.asarray(eigenvalues, dtype=np.float64)

    def joined(i):  # eigenvalues i − 1 and i are one
        return values[i] - values[i - 1] <= gap * abs(values[i])

    if not 0 < k < values.size or not joined(k):
        return None
    first, end = k - 1, k + 1
    while first > 0 and joined(first):
        first -= 1
    while end < values.size and joined(end):
        end += 1
    return first, end


def checked_laplace_basis(mass: sp.spmatrix, conformal: sp.spmatrix, k: int, *, what: str = "mesh"):
    """:func:`laplace_basis` with :data:`SPLIT_LOOKAHEAD` more eigenpairs (up to ``n − 1``), and
    :func:`split_group` of its eigenvalues at ``k`` computed to the group's end (more eigenpairs
    only where the group reaches past those): ``(basis, group)``, ``basis`` the (larger) computed
    one, ``group`` ``None`` or ``(first, end)``."""
    n = mass.shape[0]
    _check_size(n, k, what)  # k itself: the lookahead would make a basis of 0 functions one of 2
    basis = laplace_basis(mass, conformal, max(k, min(k + SPLIT_LOOKAHEAD, n - 1)), what=what)
    group = split_group(basis.eigenvalues, k)
    while group is not None and group[1] == basis.size and basis.size < n - 1:
        basis = laplace_basis(mass, conformal, min(basis.size + 2 * (group[1] - group[0]), n - 1), what=what)
        group = split_group(basis.eigenvalues, k)
    return basis, group


def cached_split_group(bases: dict, k: int, n: int, compute) -> tuple[int, int] | None:
    """:func:`split_group` at a basis size ``k`` of the largest basis in ``bases`` ({size:
    :class:`LaplaceBasis`} of one mesh of ``n`` vertices), or of ``compute(k)`` (its
    :func:`checked_laplace_basis` ``(basis, group)``, the basis added to ``bases``) where that one
    has no eigenvalue past the first ``k`` (a cached basis of exactly ``k`` tells nothing of the
    next) or the group reaches its last and may go on."""
    computed = bases[max(bases)] if bases else None
    group = split_group(computed.eigenvalues, k) if computed is not None and computed.size > k else None
    if computed is None or computed.size <= k or (group is not None and group[1] == computed.size < n - 1):
        computed, group = compute(k)
        bases[computed.size] = computed
    return group


def _check_size(n: int, k: int, what: str) -> None:
    """:class:`MeshError` unless ``1 ≤ k < n`` (a basis of ``k`` eigenfunctions of a mesh ``what``
    of ``n`` vertices)."""
    if not 1 <= k < n:
        raise MeshError(
            f"The {what} has {n} vertices, so the number of Laplace–Beltrami eigenfunctions must be "
            f"between 1 and {n - 1}; got {k}. Lower k."
        )


def split_advice(label: str, k: int, splits, sizes) -> str:
    """The warning for a basis size ``label = k`` that splits groups of equal eigenvalues:
    ``splits`` ``[(what, (first, end)), …]`` (:func:`split_group` of each mesh ``what``), ``sizes``
    the nearest sizes that split none (at most two, possibly none)."""
    groups = " and ".join(f"a group of {end - first} equal frequencies (Laplace–Beltrami eigenvalues "
                          f"{first + 1}–{end}) of the {what}" for what, (first, end) in splits)
    use = " or ".join(str(size) for size in sizes)
    return (f"{label} = {k} splits {groups} (a symmetric shape): the result depends on rounding"
            + (f"; use {label} = {use} (the nearest size{'s' if len(sizes) > 1 else ''} that "
               f"do{'' if len(sizes) > 1 else 'es'} not split {'it' if len(splits) == 1 else 'them'})." if sizes else
               "; no other basis size avoids it: use the full basis."))


def split_warning(label: str, k: int, groups_at, smallest: int, limit: int) -> str | None:
    """The :func:`split_advice` for a basis size ``label = k``, or ``None`` where it splits no
    group: ``groups_at(size)`` lists ``[(what, (first, end)), …]``, the groups a size splits on each
    mesh the size applies to (:func:`split_group`); the sizes offered are the nearest below and above
    ``k`` that split none on any of them, within ``smallest..limit − 1`` (a candidate that splits
    another mesh's group moves on past it)."""
    splits = groups_at(k)
    if not splits:
        return None
    sizes = []
    for side in (0, 1):  # 0: down to the groups' first indices, 1: up to their ends
        size = k
        while smallest <= size < limit:
            groups = [group for _, group in groups_at(size)]
            if not groups:
                sizes.append(size)
                break
            size = min(g[0] for g in groups) if side == 0 else max(g[1] for g in groups)
    return split_advice(label, k, splits, sizes)


def warn_eigenvalue_split(label: str, k: int, named_eigenvalues, smallest: int, limit: int) -> None:
    """A ``truncated`` :class:`~core.errors.ShapeDifferenceWarning` (:func:`split_warning`) where a
    basis size ``label = k`` splits a group of equal eigenvalues of a mesh ``what`` of
    ``named_eigenvalues`` ``[(what, eigenvalues float64 (p,) ascending, p > k), …]`` (computed
    past ``k``, as :func:`checked_laplace_basis` does)."""
    from .errors import warn

    message = split_warning(label, k, lambda size: [(what, group) for what, values in named_eigenvalues
                                                    if (group := split_group(values, size)) is not None],
                            smallest, limit)
    if message is not None:
        warn(message, "truncated")


def laplace_basis(mass: sp.spmatrix, conformal: sp.spmatrix, k: int, *, what: str = "mesh") -> LaplaceBasis:
    """The ``k`` smallest eigenpairs of ``(C, A)``: scipy ``eigsh`` in shift-invert mode about a
    small negative shift (so the factorized matrix ``C − σA`` is positive definite), or a dense
    ``eigh`` for small meshes and for bases of at least :data:`DENSE_EIGEN_FRACTION` of the
    vertices.

    ``mass``, ``conformal``: float64 sparse ``(n, n)``. Raises :class:`MeshError` if ``k`` is not in
    ``1..n-1`` and :class:`RecoveryError` if the eigensolver fails.
    """
    n = mass.shape[0]
    _check_size(n, k, what)
    if n <= DENSE_EIGEN_LIMIT or (k >= DENSE_EIGEN_FRACTION * n and n <= DENSE_EIGEN_MAX_VERTICES):
        from scipy.linalg import LinAlgError, eigh

        try:
            if n <= DENSE_EIGEN_LIMIT:
                values, vectors = eigh(conformal.toarray(), mass.toarray(), subset_by_index=[0, k - 1])
            else:  # divide and conquer on every pair, then the first k: faster than the subset driver
                values, vectors = eigh(conformal.toarray(), mass.toarray(), driver="gvd")
                values, vectors = values[:k], vectors[:, :k]
        except (LinAlgError, ValueError) as error:
            raise RecoveryError(
                f"The Laplace–Beltrami eigensolver failed for the {what} with k = {k} ({error}). "
                "Check the mesh for nearly degenerate triangles."
            ) from error
        return LaplaceBasis(values, vectors)
    from scipy.sparse.linalg import ArpackNoConvergence, eigsh

    diag_ratio = conformal.diagonal() / mass.diagonal()
    shift = -1e-3 * float(np.median(diag_ratio[np.isfinite(diag_ratio)]))
    try:
        # A fixed start vector: ARPACK's own is drawn from a generator that advances with every
        # call, so repeated eigenspaces (symmetric meshes) came out rotated differently per call
        # and recoveries depended, at round-off, on what had run before in the process.
        start = np.random.default_rng(0).standard_normal(n)
        values, vectors = eigsh(conformal.tocsc(), k=k, M=mass.tocsc(), sigma=shift, which="LM", v0=start)
    except (ArpackNoConvergence, RuntimeError) as error:
        raise RecoveryError(
            f"The Laplace–Beltrami eigensolver did not converge for the {what} with k = {k} "
            f"({error}). Try a smaller k or check the mesh for nearly degenerate triangles."
        ) from error
    order = np.argsort(values)
    return LaplaceBasis(values[order], vectors[:, order])


#: :func:`warm_laplace_basis` accepts its Ritz pairs when every wanted one has a residual
#: ``‖C φ − λ A φ‖_{A⁻¹} ≤ WARM_TOLERANCE · λ_{k−1}`` (``φ`` A-normalized). A residual ``r`` puts an
#: exact eigenvalue within ``r`` of ``λ`` (and the eigenvalue error is ``O(r² / gap)``), and the
#: wanted subspace within an angle ``r / gap`` of the exact one (Davis–Kahan), where ``gap`` is the
#: distance to the first unwanted eigenvalue. Measured on consecutive frames of a 1,024-vertex
#: cloth (k = 108, 162 start functions): one iteration gave residual 3e-7 and a largest angle to
#: ARPACK's subspace of 3e-7, on the mesh and on its offset surface.
WARM_TOLERANCE = 1e-6
#: Subspace iterations :func:`warm_laplace_basis` runs at most before falling back to ARPACK (each
#: costs about a third of an ARPACK solve at that size; from a pose far away the residual falls
#: only ~2× per iteration, and ARPACK is cheaper).
WARM_ITERATIONS = 3

_log = logging.getLogger(__name__)


def _residuals(mass, conformal_x, mass_x, values, lumped):
    """``‖C x_i − λ_i A x_i‖`` per column in the lumped-mass ``A⁻¹`` norm, an upper bound of the
    Galerkin one up to a factor 2 (the P1 mass matrix lies between ¼ and 1 × its lumped diagonal)."""
    r = conformal_x - mass_x * values
    return 2.0 * np.sqrt(np.einsum("ij,ij->j", r, r / lumped[:, None]))


def warm_laplace_basis(mass: sp.spmatrix, conformal: sp.spmatrix, k: int, start, *,
                       iterations: int = WARM_ITERATIONS, min_iterations: int = 1,
                       tolerance: float = WARM_TOLERANCE, what: str = "mesh") -> LaplaceBasis:
    """The ``k`` smallest eigenpairs of ``(C, A)`` (as :func:`laplace_basis`) from a nearby basis:
    shift-invert subspace iteration with a Rayleigh–Ritz step, started from ``start`` (a
    :class:`LaplaceBasis` or float64 ``(n, p)`` functions with ``p > k``, e.g. the eigenbasis of
    another pose of the same mesh, whose eigenspaces move little). One sparse LU and ``p`` solves
    per iteration instead of a Lanczos run with ``2k + 1`` re-orthogonalized vectors.

    Returns all ``p`` Ritz pairs, ascending: the first ``k`` meet the residual test of
    :data:`WARM_TOLERANCE` (checked after every iteration from ``min_iterations`` on, at most
    ``iterations``; a caller with a loose ``tolerance`` can ask for more work); the others are
    approximate and serve as the next start (the extra columns speed up convergence, at the rate
    ``λ_k / λ_p`` per iteration). If the test still fails, the result is :func:`laplace_basis`'s
    with ``p`` eigenpairs (logged at INFO level) — never an unconverged basis.
    """
    import scipy.linalg as sla
    from scipy.sparse.linalg import splu

    functions = start.functions if isinstance(start, LaplaceBasis) else np.asarray(start, dtype=np.float64)
    n = mass.shape[0]
    p = functions.shape[1] if functions.ndim == 2 else 0
    if functions.ndim != 2 or functions.shape[0] != n or not k < p < n:
        raise MeshError(
            f"A warm start for {k} eigenfunctions of the {what} ({n} vertices) needs more than {k} and "
            f"fewer than {n} start functions on its vertices; got an array of shape {functions.shape}."
        )
    diag_ratio = conformal.diagonal() / mass.diagonal()
    shift = -1e-3 * float(np.median(diag_ratio[np.isfinite(diag_ratio)]))
    lumped = np.asarray(mass.sum(axis=1)).ravel()
    try:
        factor = splu((conformal - shift * mass).tocsc())
    except RuntimeError:
        factor = None
    worst = np.inf
    if factor is not None:
        x = functions
        for done in range(1, int(iterations) + 1):
            x = factor.solve(np.asarray(mass @ x))
            # Rayleigh–Ritz on the columns scaled to unit A-norm, without orthonormalizing them
            # first: they are an inverse-iteration step from A-orthonormal Ritz vectors, so their
            # A-Gram is well conditioned (a QR of the n × p block cost as much as the solves).
            mx = np.asarray(mass @ x)
            scale = 1.0 / np.sqrt(np.maximum(np.einsum("ij,ij->j", x, mx), np.finfo(float).tiny))
            x, mx = x * scale, mx * scale
            cx = np.asarray(conformal @ x)
            try:
                values, small = sla.eigh(x.T @ cx, x.T @ mx)
            except (sla.LinAlgError, ValueError):
                break
            x, cx, mx = x @ small, cx @ small, mx @ small
            residual = _residuals(mass, cx[:, :k], mx[:, :k], values[:k], lumped)
            worst = float(residual.max()) / max(abs(values[k - 1]), np.finfo(float).tiny)
            if worst <= tolerance and done >= min_iterations:
                return LaplaceBasis(values, x)
    _log.info("Warm-started eigensolver did not converge for the %s (k = %d, relative residual %.1e > %.0e): "
              "falling back to ARPACK.", what, k, worst, tolerance)
    return laplace_basis(mass, conformal, p, what=what)
