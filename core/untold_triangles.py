"""Triangles whose shape neither key of a gap tells: slivers and needles less high than the fits'
floor in both keys (a scan's T-junctions, 1e-9–1e-3 of their side high). Their turn and stretch
between the keys (paper §4.2, §8.4: the polar decomposition of each triangle's map) are set by
where each corner lies across the triangle's longest side, which any noise in the keys (a rigid
motion stored in single precision, a scanner's jitter) moves by more than the triangle's height:
such a triangle reads as turned by up to a half turn and stretched 1e5 × across, and the fit,
which weighs every triangle's edges alike, pulls its neighbours after it (a 5.8k scan turned
rigidly with 1e-6 noise and 40 slivers 1e-9 high: 5.8e-3 of its diagonal off at 0.5). Such a
triangle takes its target edges from the deformation of the nearest triangle across its sides
whose shape the keys tell (:func:`borrowed_edges`): what the keys tell there, its long side,
follows that neighbour's turn and stretch, as the mesh around it does. Where it is also lower than
the noise between its rigid piece's keys (:func:`unfaced_triangles`), the checks of flipped and
collapsed triangles leave it out: noise that size, or the fit's rounding, turns it over.
"""

from __future__ import annotations

import numpy as np

from .geometry import coordinate_cross


def untold_triangles(base, nxt, floor: float) -> np.ndarray:
    """Bool (m,): the triangles whose height (doubled area over the longest side) is under
    ``floor`` in both key ``base`` and key ``nxt`` (:class:`core.inbetween_keys.Key`)."""
    return (2.0 * base.areas < floor * base.lengths.max(axis=1)) & (2.0 * nxt.areas < floor * nxt.lengths.max(axis=1))


def unfaced_triangles(base, nxt, noise: np.ndarray) -> np.ndarray:
    """Bool (m,): the triangles less high in key ``base`` or key ``nxt`` than twice the
    ``noise`` (m,: the RMS misfit of the rigid motion of a triangle's piece between the keys, 0
    for a deforming piece, whose noise the keys do not tell): noise that size turns them over
    (the factor of :data:`core.rounded_slivers.ROUNDED_SLIVER`), so the keys do not tell which way
    they turn, nor which way they face in between (a sliver 1e-10 high in one key is as high as
    the noise makes it in the other)."""
    return (base.areas < noise * base.lengths.max(axis=1)) | (nxt.areas < noise * nxt.lengths.max(axis=1))


def told_donors(triangles: np.ndarray, lengths: np.ndarray, untold: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, donors)`` (index arrays (k,)): each untold triangle (bool (m,) ``untold``) that
    reaches a told one across sides, and that told triangle: the one across its longest side
    (``lengths`` (m, 3), corner edge ``c`` from corner ``c`` to ``c + 1`` of ``triangles`` (m, 3))
    if told, else, ring by ring, the donor of its neighbour across the longest side that has one.
    Untold triangles with no told triangle in their piece keep their own targets (not listed)."""
    m = len(triangles)
    donor = np.where(untold, -1, np.arange(m))
    if not untold.any():
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    # the corner edges of the untold triangles and of every triangle, by their sorted vertex pair
    start, end = triangles.ravel(), triangles[:, [1, 2, 0]].ravel()
    keys = np.minimum(start, end).astype(np.int64) * (int(triangles.max()) + 1) + np.maximum(start, end)
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    owner = order // 3
    thin_rows = np.flatnonzero(untold)
    corner_keys = keys.reshape(m, 3)[thin_rows]  # (k, 3)
    side = lengths[thin_rows]  # (k, 3)
    for _ in range(m):  # ring by ring; a ring that assigns none ends it
        open_ = donor[thin_rows] < 0
        if not open_.any():
            break
        best_length = np.full(thin_rows.size, -1.0)
        best = np.full(thin_rows.size, -1)
        for c in range(3):
            first = np.searchsorted(sorted_keys, corner_keys[:, c], side="left")
            last = np.searchsorted(sorted_keys, corner_keys[:, c], side="right")
            for offset in range(int((last - first).max(initial=0))):  # the triangles on that side
                at = first + offset
                valid = at < last
                neighbour = np.where(valid, owner[np.minimum(at, len(owner) - 1)], -1)
                valid &= (neighbour != thin_rows) & (neighbour >= 0)
                given = np.where(valid, donor[np.maximum(neighbour, 0)], -1)
                better = open_ & (given >= 0) & (side[:, c] > best_length)
                best[better], best_length[better] = given[better], side[better, c]
        if not (best >= 0).any():
            break
        donor[thin_rows[best >= 0]] = best[best >= 0]
    reached = donor[thin_rows] >= 0
    return thin_rows[reached], donor[thin_rows[reached]]


def borrowed_edges(base_columns: np.ndarray, base_coordinates: np.ndarray, rows: np.ndarray, donors: np.ndarray,
                   frames: np.ndarray, stretch: np.ndarray) -> np.ndarray:
    """Target corner edges (3 coordinates, 3 corners, k) of the triangles ``rows`` as the
    deformation of their ``donors`` maps them: the base key's corner edges of ``rows``
    (``base_columns``: the base's frames (3 columns, 3 coordinates, m), ``base_coordinates``: its
    corner edges' tangent coordinates (2, 3 corners, m)) in the donor's base frame ``(t1, t2, n)``,
    ``(x, y)`` stretched by the donor's ``stretch`` (packed (k, 3), in the donor's tangent basis)
    and turned, with ``n``, by the donor's interpolated rotation (``frames`` (2 columns, 3
    coordinates, k): the images of the donor's ``t1``, ``t2``). A rigid motion maps every
    triangle alike, so a borrowed edge is its own there, to the donor's precision."""
    x, y = base_coordinates[0][:, rows], base_coordinates[1][:, rows]  # (3 corners, k)
    t1, t2 = base_columns[0][:, rows], base_columns[1][:, rows]  # (3 coordinates, k)
    edges = x[None] * t1[:, None] + y[None] * t2[:, None]  # (3 coordinates, 3 corners, k)
    d1, d2, dn = (base_columns[c][:, donors] for c in range(3))
    along = np.einsum("dck,dk->ck", edges, d1)
    across = np.einsum("dck,dk->ck", edges, d2)
    normal = np.einsum("dck,dk->ck", edges, dn)
    s11, s12, s22 = stretch[:, 0], stretch[:, 1], stretch[:, 2]
    u, v = s11 * along + s12 * across, s12 * along + s22 * across
    f0, f1 = frames[0], frames[1]
    f2 = coordinate_cross(f0, f1)
    return f0[:, None] * u[None] + f1[:, None] * v[None] + f2[:, None] * normal[None]
