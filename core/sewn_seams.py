"""Sewn seams: boundary vertices of different pieces (or far apart along one piece) that both keys
of a gap keep together, solved as one unknown in that gap's in-betweens (paper §7.3: the Poisson
solve and the local/global fit with those vertices' positions shared).

A garment simulated from separate panels (Blender's sewing springs, panels exported on their own)
has seams that the motion closes: apart in the first keys, together in the later ones.
:func:`core.seam_welds.seam_weld` welds only vertices at one place in every key, and each panel
reconstructed on its own opened the seams a 13.8k dress's bake keeps shut by 1.4 / 2.2 / 5.1 mean
edge lengths with keys 4 / 8 / 16 frames apart. Closing them after the solve (each pair moved to its
middle, the move spread by a screened Laplacian) doubled the edge deviation and flipped triangles:
the fit had placed each panel's edges without the seam.

Here a gap whose two keys keep pairs together (:class:`core.near_seams.NearSeams`: within
:data:`core.near_seams.NEAR_SEAM_SHARE` of their edges in both keys) joins them into groups
(:func:`gap_groups`), and every solve with the gap's normal matrix ``A`` keeps each group's vertices
at their offsets ``t`` from its first vertex: ``x = P y + t`` with ``Pᵀ A P y = Pᵀ (b − A t)`` (``P``
(n, n − k + g) copies each group's unknown to its vertices), the minimizer of the same energy under
those constraints, so the fit keeps the seam while it fits the metric (:class:`SewnFactor`). The
offsets are the keys' own, blended between them and turned with the piece
(:func:`sewn_offsets`; zero where the keys have the seam exactly shut). ``Pᵀ A P`` is factorized once
per anchor and set of groups (gaps sewing the same vertices share it: :func:`sewn_factor`), in place
of the gap's own factor: cheaper than keeping the gap's factor and adding the constraints by their
Schur complement (13.8k dress, 240 pairs: 0.09 s against 0.12–0.16 s to set up, each solve 2 ms
against 8–12 ms). In-betweens predicted from solved ones (:mod:`core.inbetween_prediction_repairs`)
interpolate each piece's motion on its own: they are brought onto the constraints by one solve in
the same energy (:func:`sewn_together`), and a repair that moves one side is followed by
:meth:`SewnGroups.join`. A gap without such pairs solves as before, with the same factor.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from .cached_property import cached_property
from .seam_welds import vertex_groups
from .sparse_cholesky import SPDFactor


@dataclass(frozen=True)
class SewnGroups:
    """Vertices joined for one gap: ``vertices`` (int (k,)) the vertices in a group, ``group`` (int
    (k,)) the group of each (0 … g − 1); ``unknown`` (n,) the unknown of each of the n vertices
    (groups first, then every vertex on its own), ``count`` the unknowns, n − k + g."""

    vertices: np.ndarray
    group: np.ndarray
    unknown: np.ndarray
    count: int
    #: The keys' coordinate rounding (:func:`core.coordinate_rounding.coordinate_rounding`, in the working keys'
    #: units): offsets that differ by less between the keys are the same (:func:`sewn_offsets`).
    rounding: float = 0.0
    #: The groups of the pairs that this gap and every later gap sewing any keep together, where
    #: they are fewer (None otherwise): the factor they share takes each gap's further joins as
    #: constraints (:func:`sewn_factor`), where seams that sewing springs stretch come and go.
    core: "SewnGroups | None" = None

    @property
    def key(self) -> bytes:
        """What identifies the groups (the factorizations are kept per groups and anchor)."""
        return self.vertices.tobytes() + self.group.tobytes()

    def spread(self) -> sp.csr_matrix:
        """``P`` (n, count): one 1 per row, in the column of the vertex's unknown."""
        n = self.unknown.size
        return sp.csr_matrix((np.ones(n), self.unknown, np.arange(n + 1)), shape=(n, self.count))

    @cached_property
    def _projector(self) -> sp.csr_matrix:
        """``P (PᵀP)⁻¹ Pᵀ`` (n, n): each group's rows to their mean, the others kept."""
        spread = self.spread()
        sizes = np.bincount(self.unknown, minlength=self.count).astype(float)
        return (spread @ sp.diags(1.0 / sizes) @ spread.T).tocsr()

    def project(self, values: np.ndarray) -> np.ndarray:
        """``values`` (n, …) with each group's rows replaced by their mean: the orthogonal projection
        onto the positions whose groups sit at one place (conjugate gradients preconditioned by a
        sewn factor's solves run in that space: :meth:`core.inbetween_anchor.Anchor.weak_poisson_solve`)."""
        return self._projector @ values

    @cached_property
    def first(self) -> np.ndarray:
        """The first vertex (int (k,)) of the group of each vertex of :attr:`vertices`: its place is
        the group's unknown, the others sit at their offsets from it (:func:`sewn_offsets`)."""
        first = np.zeros(int(self.group.max()) + 1, dtype=np.int64)
        first[self.group[::-1]] = self.vertices[::-1]
        return first[self.group]

    def opening(self, x: np.ndarray, offsets: np.ndarray) -> float:
        """The largest distance (float) of a vertex of a group in ``x`` (n, 3) from its place at
        ``offsets`` (n, 3; :func:`sewn_offsets`) from its group's first vertex."""
        rows = self.vertices
        return float(np.max(np.linalg.norm(x[rows] - x[self.first] - offsets[rows], axis=1), initial=0.0))

    def join(self, x: np.ndarray, offsets: np.ndarray, mass: np.ndarray, fixed: np.ndarray | None = None) -> np.ndarray:
        """``x`` (n, 3) with each group's vertices set, in place, at their ``offsets`` (n, 3) from one
        place, the one that moves them least (their ``mass``-weighted (n,) mean move), or where a group
        holds a ``fixed`` (bool (n,)) vertex, the one that keeps that vertex where it is."""
        rows = self.vertices
        weights = mass[rows].astype(float)
        if fixed is not None:
            held = fixed[rows]
            if held.any():  # a pinned vertex decides its group's place
                heavy = np.zeros(int(self.group.max()) + 1, dtype=bool)
                heavy[self.group[held]] = True
                weights = np.where(heavy[self.group], held.astype(float), weights)
        total = np.bincount(self.group, weights)
        base = x[rows] - offsets[rows]  # where each puts its group's first vertex
        place = np.stack([np.bincount(self.group, weights * base[:, d]) for d in range(3)], axis=1)
        x[rows] = place[self.group] / total[self.group, None] + offsets[rows]
        return x


def sewn_groups(a: np.ndarray, b: np.ndarray, triangles: np.ndarray, n: int,
                rounding: float = 0.0) -> SewnGroups | None:
    """The groups of the pairs ``a``, ``b`` (int (p,) each) of vertices of a mesh of ``triangles``
    (m, 3) and ``n`` vertices (``rounding``: :attr:`SewnGroups.rounding`): the connected components
    of the pairs, less those that would join two corners of one triangle (pairs found near each
    other in a key can chain along a seam onto an edge: joined, the triangle would collapse; those
    vertices stay apart). None where no group is left."""
    if not a.size:
        return None
    label = vertex_groups(a, b, n)
    sizes = np.bincount(label)
    corners = label[triangles]
    collapsing = np.zeros(sizes.size, dtype=bool)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        same = corners[:, i] == corners[:, j]
        collapsing[corners[same, i]] = True
    kept = (sizes > 1) & ~collapsing
    vertices = np.flatnonzero(kept[label])
    if not vertices.size:
        return None
    _, group = np.unique(label[vertices], return_inverse=True)
    group = group.ravel()
    count = int(group.max()) + 1
    unknown = np.empty(n, dtype=np.int64)
    alone = np.ones(n, dtype=bool)
    alone[vertices] = False
    unknown[vertices] = group
    unknown[alone] = count + np.arange(int(np.count_nonzero(alone)))
    return SewnGroups(vertices, group, unknown, count + int(np.count_nonzero(alone)), rounding)


def gap_groups(seams, gap: int, triangles: np.ndarray, n: int, rounding: float = 0.0) -> SewnGroups | None:
    """The :func:`sewn_groups` of the pairs of ``seams`` (a :class:`core.near_seams.NearSeams`, or
    None) that both keys of gap ``gap`` keep together (their allowed opening is finite there), with
    their :attr:`SewnGroups.core`."""
    if seams is None:
        return None
    closed = np.isfinite(seams.allowed[gap:])
    if not closed[0].any():
        return None
    groups = sewn_groups(seams.a[closed[0]], seams.b[closed[0]], triangles, n, rounding)
    kept = closed[closed.any(axis=1)].all(axis=0)  # in this gap and every later one that sews
    if groups is None or not kept.any() or kept.sum() == closed[0].sum():
        return groups
    core = sewn_groups(seams.a[kept], seams.b[kept], triangles, n, rounding)
    return groups if core is None else replace(groups, core=core)


class SewnFactor:
    """Solves of ``A x = b`` (``A`` (n, n) symmetric positive definite) with the vertices of each
    group of ``groups`` (:class:`SewnGroups`) one unknown: ``x = P (Pᵀ A P)⁻¹ Pᵀ b``, the minimizer
    of ``½ xᵀ A x − bᵀ x`` over the positions whose groups sit at one place. :meth:`solve` takes
    right-hand sides (n,) or (n, k) as :class:`core.sparse_cholesky.SPDFactor` does."""

    def __init__(self, matrix: sp.spmatrix, groups: SewnGroups):
        self.groups = groups
        self.shape = matrix.shape
        self._matrix = matrix.tocsr()
        self._spread = groups.spread()
        self._gather = self._spread.T.tocsr()
        self._factor = SPDFactor((self._gather @ matrix @ self._spread).tocsc())

    @property
    def backend(self) -> str:
        return self._factor.backend

    def reduced(self, rhs: np.ndarray, offsets: np.ndarray | None = None) -> np.ndarray:
        """``Pᵀ (b − A t)`` (count, …) of right-hand sides ``rhs`` and ``offsets`` (n, 3) or None."""
        return self._gather @ (rhs if offsets is None else rhs - self._matrix @ offsets)

    def solve(self, rhs: np.ndarray, offsets: np.ndarray | None = None) -> np.ndarray:
        """The solution (shape of ``rhs``) with the groups' vertices at one place, or with
        ``offsets`` (n, 3), at those from their group's first vertex (``x = P y + t``,
        ``Pᵀ A P y = Pᵀ (b − A t)``)."""
        x = self._spread @ self._factor.solve(self.reduced(rhs, offsets))
        return x if offsets is None else x + offsets

    def project(self, values: np.ndarray) -> np.ndarray:
        """``values`` (n, …) with each group's rows replaced by their mean (:meth:`SewnGroups.project`)."""
        return self.groups.project(values)


#: A gap whose groups join those of a factor already made (its groups each within one of the
#: gap's) adds the joins that are left as constraints on that factor, through their Schur
#: complement, where they are at most this many; more, and it is factorized on its own. Each
#: constraint costs a solve with the factor once and a column of (unknowns,) floats that every
#: later solve reads (memory-bound): on the 13.8k dress hanging on its sewing springs, up to 256
#: constraints per gap set up in 0.03–0.04 s (a factorization 0.09 s) and made each solve 11 ms
#: against 2 ms, for the same CPU per in-between as 48. The seams of a dress sewn as it falls close
#: over a few gaps, 13–42 more sewn vertices each.
ADDED_JOINS = 48


class AddedJoins:
    """:class:`SewnFactor`'s solves for ``groups`` (:class:`SewnGroups`) from a ``base``
    :class:`SewnFactor` whose groups each lie within one of ``groups``: the joins ``base`` lacks as
    constraints ``C y = 0`` on its unknowns (each further unknown of a group equal to its first),
    solved by their Schur complement ``K = C S⁻¹ Cᵀ`` (``S`` the base's reduced matrix), the same
    minimizer to round-off without a factorization of its own."""

    def __init__(self, base: SewnFactor, groups: SewnGroups, constraints: sp.csr_matrix):
        from scipy.linalg import cho_factor

        self.groups, self.shape, self._base = groups, base.shape, base
        self._constraints = constraints
        self._columns = base._factor.solve(np.ascontiguousarray(constraints.T.toarray()))  # S⁻¹ Cᵀ
        self._schur = cho_factor(constraints @ self._columns)

    @property
    def backend(self) -> str:
        return self._base.backend

    def solve(self, rhs: np.ndarray, offsets: np.ndarray | None = None) -> np.ndarray:
        """As :meth:`SewnFactor.solve`, with this object's groups."""
        from scipy.linalg import cho_solve

        base = self._base
        y = base._factor.solve(base.reduced(rhs, offsets))
        y = y - self._columns @ cho_solve(self._schur, self._constraints @ y)
        x = base._spread @ y
        return x if offsets is None else x + offsets

    def project(self, values: np.ndarray) -> np.ndarray:
        """``values`` (n, …) with each group's rows replaced by their mean (:meth:`SewnGroups.project`)."""
        return self.groups.project(values)


def _added_joins(known: SewnGroups, groups: SewnGroups) -> sp.csr_matrix | None:
    """The constraints ``C`` (k, unknowns of ``known``) that join the unknowns of ``known`` into
    ``groups``: where every group of ``known`` lies within one of ``groups`` and k is at most
    :data:`ADDED_JOINS`; else None."""
    if not np.isin(known.vertices, groups.vertices).all():
        return None
    label = np.full(groups.unknown.size, -1)
    label[groups.vertices] = groups.group
    within = label[known.vertices]
    low = np.full(int(known.group.max()) + 1, np.iinfo(np.int64).max)
    high = np.full(low.size, -1)
    np.minimum.at(low, known.group, within)
    np.maximum.at(high, known.group, within)
    if (low != high).any():  # a base group across two of the gap's
        return None
    unknowns = known.unknown[groups.vertices]  # the base unknown of each vertex of the gap's groups
    pairs = np.unique(np.stack([groups.group, unknowns], axis=1), axis=0)
    first = np.zeros(int(groups.group.max()) + 1, dtype=np.int64)
    first[pairs[::-1, 0]] = pairs[::-1, 1]
    further = pairs[pairs[:, 1] != first[pairs[:, 0]]]
    k = len(further)
    if k > ADDED_JOINS:
        return None
    rows = np.arange(k)
    columns = np.r_[further[:, 1], first[further[:, 0]]]
    return sp.csr_matrix((np.r_[np.ones(k), -np.ones(k)], (np.r_[rows, rows], columns)),
                         shape=(k, known.count))


#: Held while :func:`sewn_factor` looks up, builds and keeps a sewn factor and its bases.
_bases_lock = threading.Lock()


def _new_lock_after_fork() -> None:
    """In a child forked from this process: a lock a parent's thread held at the fork is never given back."""
    global _bases_lock
    _bases_lock = threading.Lock()


if hasattr(os, "register_at_fork"):  # not on Windows, which does not fork
    os.register_at_fork(after_in_child=_new_lock_after_fork)


def sewn_factor(topo, weights, key, groups: SewnGroups | None):
    """The factor of ``DᵀD + diag(w · mass)`` of ``topo`` (a :class:`core.inbetween_topology.Topology`)
    for ``weights`` (see its ``factor``): its own where ``groups`` is None, else a :class:`SewnFactor`
    with those groups, kept with the topology's factors per ``key`` and groups (a gap whose keys sew
    the same vertices as the gap before reuses it), or an :class:`AddedJoins` on one made for fewer
    joins with the same weights (seams closing from gap to gap). One thread at a time: two gaps solved
    at once (a gap begun ahead, :mod:`core.sequence_gaps_ahead`) must find the same bases, or a later
    gap would build on another and its in-betweens differ in their last bits from run to run."""
    if groups is None:
        return topo.factor(weights, key)
    with _bases_lock:
        return _sewn_factor(topo, weights, key, groups)


def _sewn_factor(topo, weights, key, groups: SewnGroups):
    """:func:`sewn_factor` with groups, under its lock."""
    weight_key = weights if np.isscalar(weights) else key
    cache = ("sewn", weight_key, groups.key)
    found = topo._uniform.get(cache) if weight_key is not None else None
    if found is not None:
        return found
    factor = None
    bases = topo._uniform.get(("sewn bases", weight_key), []) if weight_key is not None else []
    for base in reversed(bases):
        constraints = _added_joins(base.groups, groups)
        if constraints is not None:
            factor = AddedJoins(base, groups, constraints) if constraints.shape[0] else base
            break
    if factor is None:  # a base of its own: the groups later gaps keep too, where they are fewer
        w = np.full(topo.n, weights) if np.isscalar(weights) else weights
        constraints = None if groups.core is None else _added_joins(groups.core, groups)
        base = SewnFactor(topo.laplacian + sp.diags(w * topo.mass), groups if constraints is None else groups.core)
        factor = base if constraints is None or not constraints.shape[0] else AddedJoins(base, groups, constraints)
        if weight_key is not None:
            topo._uniform[("sewn bases", weight_key)] = bases + [base]
    if weight_key is not None:
        topo._uniform[cache] = factor
    return factor


#: Factors whose sewn offsets a gap keeps (:func:`sewn_offsets`: every solve of a fit at one factor
#: asks for them; a batch solves up to three factors and predicts the rest).
OFFSET_CACHE = 8


def sewn_offsets(gap, s: float) -> np.ndarray:
    """The offsets (n, 3) of the sewn vertices of ``gap`` (a :class:`core.inbetween_solver.Gap`
    with ``sewn`` groups) from their group's first vertex at factor ``s`` (zero elsewhere), the
    keys' own at s = 0 and 1: where both keys have the same offset in the world (within their
    rounding: a seam left 1e-4 open, stacked layers moving together), that one; elsewhere blended
    between the keys in the frame of the first vertex's piece and turned by its interpolated rigid
    motion (:meth:`core.inbetween_motion.PieceMotion.motion`), so that a group moved rigidly keeps
    them exactly. Read-only; kept for the last :data:`OFFSET_CACHE` factors."""
    groups = gap.sewn
    cache = gap.__dict__.setdefault("_sewn_offsets", {})
    known = cache.get(s)
    if known is not None:
        return known
    keys = cache.get("keys")
    owner = gap.topo.vertex_owner[groups.first]
    if keys is None:  # per gap: each key's offsets, the next key's in the base frame of the first vertex's piece
        rows, first = groups.vertices, groups.first
        at_base = gap.base.vertices[rows] - gap.base.vertices[first]
        at_next = gap.next.vertices[rows] - gap.next.vertices[first]
        scale = np.max(np.abs(np.r_[gap.base.vertices[rows], gap.next.vertices[rows]]), initial=0.0)
        same = np.all(np.abs(at_next - at_base) <= 4 * (groups.rounding + np.finfo(float).eps * scale), axis=1)
        world = at_base[same]
        if not same.all():
            at_next = np.einsum("kba,kb->ka", gap.motion(1.0)[0][owner], at_next)
            at_base = np.einsum("kba,kb->ka", gap.motion(0.0)[0][owner], at_base)
        keys = cache["keys"] = (at_base, at_next, same, world)
    at_base, at_next, same, world = keys
    out = np.zeros((gap.topo.n, 3))
    if same.all():
        out[groups.vertices] = world
    else:
        turned = np.einsum("kab,kb->ka", gap.motion(s)[0][owner], (1.0 - s) * at_base + s * at_next)
        turned[same] = world
        out[groups.vertices] = turned
    out.flags.writeable = False
    if len(cache) > OFFSET_CACHE:  # the oldest factor (a snapshot of the keys: fits run in threads)
        cache.pop([key for key in list(cache) if key != "keys"][0], None)
    cache[s] = out
    return out


def sewn_together(gap, x: np.ndarray, s: float) -> np.ndarray:
    """Positions ``x`` (n, 3) of an in-between of ``gap`` (a :class:`core.inbetween_solver.Gap`)
    at factor ``s`` with its sewn groups together (:func:`sewn_offsets`): ``x`` itself where they
    are (a solved pose), else the nearest such positions in the energy of the gap's normal matrix
    ``A`` (``P (Pᵀ A P)⁻¹ Pᵀ A (x − t) + t``: one solve with its sewn factor), so that the move that
    joins them spreads over the cloth around them as the anchor lets it rather than bending the
    seam's own triangles. A prediction from solved poses (:mod:`core.inbetween_prediction_repairs`)
    interpolates each piece's motion on its own and parts a seam's sides by up to half an edge of
    the 13.8k dress's between its solved factors. The pinned vertices (``gap.static``) stay where
    ``x`` has them."""
    groups = gap.sewn
    if groups is None:
        return x
    offsets = sewn_offsets(gap, s)
    if groups.opening(x, offsets) == 0.0:
        return x
    factor, anchor = gap.system
    y = factor.solve(gap.topo.laplacian @ x + anchor[:, None] * x, offsets)
    if gap.static is not None:
        y[gap.static] = x[gap.static]
        groups.join(y, offsets, gap.topo.mass, gap.static)
    return y
