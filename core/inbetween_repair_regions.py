"""A repair's region (:class:`Region`): the triangles ``rows`` of a mask over the mesh's m triangles
and its free vertices (those all of whose triangles are in it), which a repair re-fits against
the others held, with the block of the Poisson system's normal matrix on them (paper §8.4)
factorized once per region (:func:`_principal_block`); and the region's connected parts, joined
where triangles share a vertex (:func:`corner_joined_parts`), which a repair takes each on its
own.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components


def corner_joined_parts(local: np.ndarray, count: int) -> tuple[int, np.ndarray]:
    """The connected parts of r triangles joined where they share a vertex: ``local`` (3r,), each
    corner's vertex among ``count`` (triangle by triangle), gives (number of parts, each node's
    part (r + count,): the triangles' labels first, then the vertices'). Triangles 0 … r − 1 and
    vertices r … r + count − 1 are nodes joined by the corners; each triangle's row lists its three,
    so the matrix is made without a sort (SciPy's own int32 indices and float64 values, which its
    graph routines take as they are)."""
    r = local.size // 3
    indptr = np.full(r + count + 1, 3 * r, dtype=np.int32)
    indptr[:r + 1] = np.arange(0, 3 * r + 1, 3, dtype=np.int32)
    graph = sp.csr_matrix((np.ones(local.size), (r + local).astype(np.int32), indptr), shape=(r + count,) * 2)
    return connected_components(graph, connection="weak")


class Region:
    """A repair's region: the triangles ``rows`` (r,) of a mask, the vertices ``free`` all of whose
    triangles are in it but the pinned ones (``gap.static``: held where the pose has them, exactly
    where :meth:`~core.inbetween_solver.Gap.finished` sets them, so that the check of the repair
    counts the pose returned), and the factorized block ``D_fᵀ D_f + diag(anchor_f)`` of the normal
    matrix on them (``D_f``: the region's corner edges × free vertices); the held vertices enter
    the right-hand side."""

    def __init__(self, gap, force: np.ndarray):
        topo = gap.topo
        self.rows = np.flatnonzero(force)
        self.coordinates = None  # the base's tangent coordinates on rows, once a fit needs them
        self._pull = None  # (guide, the anchor's pull toward it on the free vertices): see solve
        self._held = None  # (x, the held vertices' part of the region's edges in x): see solve
        corners = topo.triangles[self.rows]
        used = np.zeros(topo.n, dtype=bool)  # the region's vertices in order, without a sort
        used[corners] = True
        touched = np.flatnonzero(used)
        slot = np.empty(topo.n, dtype=np.intp)
        slot[touched] = np.arange(touched.size)
        local = slot[corners].ravel()  # (3r,) each corner's vertex among the touched ones
        is_free = np.bincount(local, minlength=touched.size) == topo.triangles_per_vertex[touched]
        if gap.static is not None:  # the pins held (see the class's docstring)
            is_free &= ~gap.static[touched]
        self.free = touched[is_free]
        self._parts = (local, touched.size, is_free)  # see parts
        self.anchor = gap.repair_anchor(self.free)
        if not self.free.size:
            return
        # Every corner edge at a free vertex lies in the region, so D_fᵀ D_f is the mesh's
        # D_cᵀ D_c on the free vertices. D_fᵀ is built from index arrays (SciPy's sparse column
        # slicing and transposes cost 2–3 ms per region, several times the factorization).
        ends = local.reshape(-1, 3)
        start, end = ends.ravel(), ends[:, [1, 2, 0]].ravel()  # edge 3t + c runs from corner c to c + 1
        free_index = np.cumsum(is_free) - 1  # touched vertex → free index (where free)
        start_free, end_free = is_free[start], is_free[end]
        # D_f by rows (edge 3t + c: −1 at its free start, +1 at its free end), so D_fᵀ is its CSC
        # view: no sort (a product with it adds each row's terms in the order of the edges, as a
        # CSR D_fᵀ with sorted columns did). Its index arrays are made in SciPy's int32 (given
        # wider ones, SciPy scans them for their range and copies them)
        per_edge = start_free.astype(np.int32) + end_free
        indptr = np.zeros(start.size + 1, dtype=np.int32)
        np.cumsum(per_edge, out=indptr[1:])
        columns, values = np.empty(indptr[-1], dtype=np.int32), np.empty(indptr[-1])
        first = indptr[:-1]
        columns[first[start_free]], values[first[start_free]] = free_index[start[start_free]], -1.0
        last = first + start_free
        columns[last[end_free]], values[last[end_free]] = free_index[end[end_free]], 1.0
        self.free_t = sp.csc_matrix((values, columns, indptr), shape=(self.free.size, start.size))
        self._held_starts = (np.flatnonzero(~start_free), touched[start[~start_free]])
        self._held_ends = (np.flatnonzero(~end_free), touched[end[~end_free]])
        self.lu = spla.splu(_principal_block(topo.laplacian, self.free, self.anchor), permc_spec="MMD_AT_PLUS_A",
                            diag_pivot_thresh=0.0, options={"SymmetricMode": True})

    def parts(self) -> tuple[np.ndarray, np.ndarray, int]:
        """The region's connected parts (triangles joined where they share a vertex): each row's
        part (r,), each free vertex's part (f,) and their count. A free vertex's triangles all lie
        in its part, so the free vertices of two parts share no triangle: the region's system is
        one block per part, and a fit of one part does not move or read the free vertices of
        another (only the held vertices, which stay)."""
        local, touched, is_free = self._parts
        r = self.rows.size
        count, labels = corner_joined_parts(local, touched)
        return labels[:r], labels[r:][is_free], count

    def whole(self) -> tuple[np.ndarray, np.ndarray, int]:
        """The region as one part, as :meth:`parts` gives its parts."""
        return np.zeros(self.rows.size, dtype=np.intp), np.zeros(self.free.size, dtype=np.intp), 1

    def solve(self, edges: np.ndarray, x: np.ndarray, guide: np.ndarray) -> np.ndarray:
        """Positions (f, 3) of the free vertices fitting the region's corner ``edges`` (r, 3, 3)
        with the held vertices at ``x``."""
        if self._held is None or self._held[0] is not x:  # the same pose for every field of a round
            # per edge, its held end less its held start: an edge with a free end has one of them
            # (with both ends held it has no entry in D_fᵀ), so the edge less this is the edge less
            # its held end's position or plus its held start's, as it would be one at a time
            held = np.zeros((self.free_t.shape[1], 3))
            held[self._held_ends[0]] = np.take(x, self._held_ends[1], axis=0)
            held[self._held_starts[0]] -= np.take(x, self._held_starts[1], axis=0)
            self._held = (x, held)
        residual = np.asarray(edges, dtype=float).reshape(-1, 3) - self._held[1]
        rhs = self.free_t @ residual
        if self._pull is None or self._pull[0] is not guide:  # the same guide for every field of a round
            self._pull = (guide, self.anchor[:, None] * np.take(guide, self.free, axis=0))
        rhs += self._pull[1]
        return self.lu.solve(np.asfortranarray(rhs))


def _principal_block(matrix: sp.csc_matrix, rows: np.ndarray, diagonal: np.ndarray) -> sp.csc_matrix:
    """``matrix[rows][:, rows]`` with ``diagonal`` (len(rows),) added to its diagonal (``matrix``:
    symmetric CSC with sorted indices and every diagonal entry stored; ``rows`` ascending), gathered
    from index arrays (SciPy's two fancy-indexing passes cost about as much as a region's
    factorization)."""
    starts = matrix.indptr[rows]
    counts = matrix.indptr[rows + 1] - starts
    offsets = np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
    inside = np.full(matrix.shape[0], -1, dtype=np.intp)
    inside[rows] = np.arange(rows.size)
    position = inside[matrix.indices[offsets]]
    kept = position >= 0
    column = np.repeat(np.arange(rows.size), counts)[kept]
    indices, data = position[kept].astype(np.int32), matrix.data[offsets[kept]]  # SciPy's index type: taken as is
    data[indices == column] += diagonal
    indptr = np.zeros(rows.size + 1, dtype=np.int32)
    np.cumsum(np.bincount(column, minlength=rows.size), out=indptr[1:])
    return sp.csc_matrix((data, indices, indptr), shape=(rows.size, rows.size))
