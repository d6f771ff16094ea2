"""Shape space of a collection of poses (paper §8.1, Figs. 7–9): PCA of their shape differences.

Every pose of one mesh is compared with a base (``poses[0]``) through the four truncated shape
differences — area-based and conformal on the mesh (intrinsic), and the same two on its offset
surface (extrinsic) — each a ``k_M × k_M`` matrix. PCA of each kind's matrices (flattened, so
distances are Frobenius norms) places every pose as a point: intrinsic coordinates see only the
metric, so mirror-image (isometric) poses coincide there; the offset coordinates also see
bending, so they separate those poses and lay an animation's frames along a curve (Fig. 9).

Cost: what depends only on the base (topology, offset surface, the base's ``k_M`` eigenbases) is
prepared once by one :class:`~core.reference_shape.ReferenceShape`; per pose, eq. (6) needs the
first ``k_N`` eigenpairs of the pose and of its offset surface (ARPACK; the pose's basis ends at
a spectral gap at or just above ``k_N``, :data:`SPECTRAL_GAP`), and eq. (5)
(``k_N=None``) needs none — only sparse products, ~30× cheaper. The per-pose work runs with one
BLAS thread: on a shared 2-core machine the threaded BLAS made these small dense problems far
slower (a 220 × 220 ``eigh``: 0.35 s against 0.024 s; 50 cloth frames: 9.5 s/pose before, 2.0 s
now; see docs/analysis.md). A warm-started block solver (LOBPCG from the base's eigenvectors with
the pose's exact shift-invert preconditioner) needed 3–5 iterations and was 1.5–2.5× slower than
ARPACK from scratch at k = 100 on a 2,944-vertex offset surface, so it is not used; neither is
:func:`~core.laplace_basis.warm_laplace_basis` (shift-invert subspace iteration from the previous
pose): on 50 frames spread over a 1,024-vertex cloth simulation it fell back to ARPACK on 76 of
100 solves and took 2.1–2.6× ARPACK's time, and from the base's basis far poses do not converge;
a start that depends on the previous pose would also make mirror-image poses differ at its
tolerance (1e-6) instead of at round-off.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


from .concurrency import single_threaded_blas
from .errors import MeshError, warn
from .coordinate_rounding import relative_round_off
from .seam_folds import seam_sides, warn_seam_folds
from .validation import check_count, check_key_names, check_result_memory

#: A PCA axis whose spread (singular value of the centred differences) is at most this fraction of
#: the differences' Frobenius norm is round-off, not a difference between poses: identical poses
#: spread 5e-17 of it, poses moved by 1e-9 of the mesh's size 3e-9.
ROUND_OFF_SPREAD = 1e-12
#: ... or at most this many relative round-offs of the poses' edge lengths (``ShapeSpace.round_off``)
#: times √N: 3 to 12 float32 copies of a turned and moved sphere spread up to 0.045 of them.
ROUNDING_SPREAD = 1.0
#: The four kinds of shape difference, in the order the paper plots them.
KINDS = ("area", "conformal", "offset_area", "offset_conformal")
KIND_LABELS = {
    "area": "Area-based (no offset)",
    "conformal": "Conformal (no offset)",
    "offset_area": "Area-based (with offset)",
    "offset_conformal": "Conformal (with offset)",
}


def check_kind(kind) -> str:
    """``kind`` if it is one of :data:`KINDS`, else :class:`MeshError`."""
    if not isinstance(kind, str) or kind not in KINDS:
        raise MeshError(f"kind must be one of {', '.join(KINDS)}; got {kind!r}.")
    return kind


@dataclass(frozen=True, eq=False)
class ShapeSpace:
    """PCA of the shape differences of ``len(poses)`` poses, one embedding per kind.

    ``features[kind]``: float64 ``(N, k_M²)`` flattened difference matrices (row 0 the base, whose
    differences are the identity up to truncation). Build it with :func:`shape_space`.
    """

    features: dict
    k_M: int
    k_N: int | None
    offset: float
    #: The relative change of the edge lengths that the rounding of the poses' coordinates alone
    #: makes, area-weighted over the triangles (:func:`core.coordinate_rounding.relative_round_off`): float32
    #: copies of one pose spread up to about this much (times √N), not zero.
    round_off: float = 0.0
    #: The same for the offset surface's kinds (:func:`core.coordinate_rounding.relative_round_off` with the offset).
    offset_round_off: float = 0.0
    _pca: dict = field(default_factory=dict, repr=False)

    @property
    def n_poses(self) -> int:
        return int(next(iter(self.features.values())).shape[0])

    def _decomposition(self, kind: str):
        check_kind(kind)
        if kind not in self._pca:
            data = self.features[kind]
            centered = data - data.mean(axis=0)
            u, s, vt = np.linalg.svd(centered, full_matrices=False)
            round_off = self.offset_round_off if kind.startswith("offset") else self.round_off
            noise = max(ROUND_OFF_SPREAD * np.linalg.norm(data), ROUNDING_SPREAD * round_off * np.sqrt(len(data)))
            s = np.where(s > noise, s, 0.0)  # round-off axes: no spread
            # Deterministic signs: each axis points towards its largest coordinate.
            scores = u * s
            flip = np.sign(scores[np.argmax(np.abs(scores), axis=0), np.arange(scores.shape[1])])
            flip[flip == 0] = 1.0
            self._pca[kind] = (scores * flip, s, vt * flip[:, None])
        return self._pca[kind]

    def coordinates(self, kind: str, dims: int = 2) -> np.ndarray:
        """PCA coordinates float64 ``(N, dims)`` of every pose (row ``i`` is ``poses[i]``) for one
        kind of difference; axes ordered by decreasing variance, zero beyond the rank."""
        dims = check_count(dims, "dims", minimum=1)
        check_result_memory((self.n_poses, dims), f"dims = {dims:,}",
                            f"ask for fewer (beyond the {self.n_poses} poses the coordinates are all zero)")
        scores, _, _ = self._decomposition(kind)
        out = np.zeros((self.n_poses, int(dims)))
        used = min(int(dims), scores.shape[1])
        out[:, :used] = scores[:, :used]
        return out

    def explained_variance_ratio(self, kind: str) -> np.ndarray:
        """Share of the collection's variance along each PCA axis, float64 ``(r,)`` summing to 1
        (all zeros if every pose has the same differences, to :data:`ROUND_OFF_SPREAD`)."""
        _, s, _ = self._decomposition(kind)
        variance = s**2
        total = variance.sum()
        return variance / total if total > 0 else np.zeros_like(variance)

    def components(self, kind: str, count: int = 2) -> np.ndarray:
        """The principal directions as difference matrices, float64 ``(count, k_M, k_M)``."""
        count = check_count(count, "count")
        _, _, vt = self._decomposition(kind)
        return vt[:count].reshape(-1, self.k_M, self.k_M)

    def order(self, kind: str) -> np.ndarray:
        """Pose indices sorted by the first coordinate (the paper's Fig. 8), int64 ``(N,)``."""
        return np.argsort(self.coordinates(kind, 1)[:, 0], kind="stable")


#: The pose's basis of eq. (6) ends at the first index ≥ k_N where the next eigenvalue is at least
#: this much larger (relative): a cut inside a cluster of (numerically) equal eigenvalues picks an
#: arbitrary part of it, and then mirror-image poses — equal spectra up to round-off — got
#: intrinsic points 1e-3 of the spread apart on the symmetric cube of Fig. 7 (1e-9 with the cut).
SPECTRAL_GAP = 1e-6
#: How many eigenpairs beyond k_N are computed to find that gap.
GAP_SEARCH = 8


def spectral_cut(eigenvalues: np.ndarray, k: int) -> int:
    """The number of eigenpairs to keep: the first ``c ≥ k`` with a relative gap after index
    ``c - 1`` (``k`` itself if there is none among ``eigenvalues``)."""
    for c in range(k, eigenvalues.size):
        if eigenvalues[c] - eigenvalues[c - 1] > SPECTRAL_GAP * abs(eigenvalues[c]):
            return c
    return k


def pose_differences(layer, positions: np.ndarray, k_M: int, k_N: int | None):
    """Area and conformal differences (eq. 5, or eq. 6 with the pose's basis cut at a spectral
    gap, see :data:`SPECTRAL_GAP`) of one pose of a reference layer."""
    from .inner_products import pose_products
    from .laplace_basis import LaplaceBasis, laplace_basis
    from .shape_difference import functional_map_differences, reduced_differences

    _, _, mass, conformal = pose_products(layer.assembler, positions)
    base_basis = layer.basis(k_M)
    if k_N is None:
        return reduced_differences(base_basis, mass, conformal)
    size = max(k_N, min(k_N + GAP_SEARCH, layer.topology.n_vertices - 1))
    basis = laplace_basis(mass, conformal, size, what=f"pose's {layer.name}")
    cut = spectral_cut(basis.eigenvalues, k_N)
    return functional_map_differences(base_basis, LaplaceBasis(basis.eigenvalues[:cut], basis.functions[:, :cut]), mass)


def shape_space_steps(poses, triangles, *, k_M: int = 50, k_N: int | None = 100, offset: float | None = None,
                      single_precision: bool | None = None, key_names=None):
    """:func:`shape_space` as a generator yielding progress in ``[0, 1]`` after each pose; its
    return value (``StopIteration.value``, or ``yield from``) is the :class:`ShapeSpace`."""
    from .laplace_basis import basis_sizes
    from .reference_shape import ReferenceShape

    if isinstance(poses, np.ndarray) and poses.ndim == 3:
        poses = list(poses)
    poses = list(poses)
    if len(poses) < 2:
        raise MeshError(f"A shape space needs at least two poses (a base and one more); got {len(poses)}.")
    names = check_key_names(key_names, len(poses), [f"key pose {index}" for index in range(len(poses))])
    if not k_M:
        raise MeshError(
            "A shape space compares k_M × k_M difference matrices: set k_M (e.g. 50); the full "
            "basis (k_M = 0 / None) would give |V| × |V| matrices per pose."
        )
    k_M, k_N = basis_sizes(k_M, k_N)
    try:
        # in the caller's units (unit 1): the features are differences, the offset and round-off as given
        reference = ReferenceShape(poses[0], triangles, offset=offset, name=names[0], unit=1.0)
    except MeshError as error:
        if "no edge shared by two triangles" not in str(error):
            raise
        from .mesh_topology import mesh_topology
        from .seam_welds import weld_advice

        first = np.asarray(poses[0], dtype=np.float64)  # checked by ReferenceShape before its offset surface
        raise MeshError("A shape space compares the poses' offset surfaces too, which need an edge shared by "
                        "two triangles; no triangles of this mesh share an edge. Use a connected surface."
                        + weld_advice(first, mesh_topology(triangles, len(first)))) from None
    reference.basis_sizes(k_M, k_N, full_basis=False)  # against the mesh: its vertices, its connected parts
    # The features are the differences in the base's first k_M functions: ended inside a group of
    # equal eigenvalues, they hold an arbitrary part of it and the poses' distances depend on
    # rounding. k_N needs no check: the pose's basis is cut at a spectral gap (SPECTRAL_GAP), and
    # eq. (6) is unchanged by any turn of a basis within its whole groups.
    reference.warn_split(k_M)
    features = {kind: np.empty((len(poses), k_M * k_M)) for kind in KINDS}
    compacts = []
    for index, pose in enumerate(poses):
        # the process-wide BLAS limit is held while a pose is computed, not across the yield: the
        # caller's code between steps, and the process after a generator is abandoned (an operator
        # cancelled), run with the process's own BLAS threads
        with single_threaded_blas():
            compact = reference.compact_pose(pose, name=names[index])
            compacts.append(compact)
            layers = [(reference.base, compact, KINDS[:2]),
                      (reference.offset_layer, reference.surface.positions(compact, reference.offset), KINDS[2:])]
            for layer, positions, kinds in layers:
                for kind, difference in zip(kinds, pose_differences(layer, positions, k_M, k_N)):
                    features[kind][index] = difference.matrix.ravel()
        yield (index + 1) / len(poses)
    faces = reference.topology.triangles
    sides = seam_sides(compacts, reference.topology)
    if len(sides):
        warn_seam_folds(compacts[0], compacts[1:], faces, sides, single_precision, "the poses",
                        "the shape differences describe each piece on its own, so the shape space does "
                        "not see those folds")
    space = ShapeSpace(features, k_M, k_N, reference.offset, relative_round_off(compacts, faces, single_precision),
                       relative_round_off(compacts, faces, single_precision, reference.offset))
    if not any(space.explained_variance_ratio(kind).any() for kind in KINDS):
        warn(f"The {len(poses)} poses have the same shape differences (they differ by round-off "
                      "only): the shape space has no spread, every pose is at its origin.",
                      "same_poses")
    return space


def shape_space(poses, triangles, *, k_M: int = 50, k_N: int | None = 100, offset: float | None = None,
                single_precision: bool | None = None, key_names=None) -> ShapeSpace:
    """PCA embedding of a collection of poses of one mesh by their shape differences (§8.1).

    ``poses``: a sequence of float64 ``(n, 3)`` arrays (or one ``(N, n, 3)`` array), ``poses[0]``
    the base every other pose is compared with; ``triangles`` int ``(m, 3)``. ``k_M``: base basis
    size (the differences are ``k_M × k_M``); ``k_N``: the pose's basis size of eq. (6), or
    ``None`` for eq. (5) (no per-pose eigensolve — much faster, exact in the base basis);
    ``offset``: the offset distance t (``None``: half the base's mean edge length);
    ``single_precision``: whether the poses were stored in single precision (Blender's keys and
    frames; ``None``: where every coordinate is a float32), which sizes ``ShapeSpace.round_off``;
    ``key_names``: the poses as errors name them (one string per pose, such as the operators' shape
    keys or frames; default ``"key pose i"``).
    Raises :class:`~core.errors.MeshError` for fewer than two poses, a mismatched pose (its name
    is given) or basis sizes the mesh cannot have.
    """
    steps = shape_space_steps(poses, triangles, k_M=k_M, k_N=k_N, offset=offset, single_precision=single_precision,
                              key_names=key_names)
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value
