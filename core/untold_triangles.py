"""Triangles whose shape a key of a gap does not tell: slivers and needles less high (doubled area
over the longest side, :func:`triangle_heights`) than the fits' floor. Less high in either key
(:func:`thin_triangles`), a triangle keeps the nearer key's stretch beyond the keys
(:data:`core.inbetween_field.HELD_BEYOND_KEYS`: exaggerating would raise a stretch that one key
does not tell to a power). Less high in both keys (:func:`untold_triangles`: a scan's
T-junctions, 1e-9–1e-3 of their side high), neither key tells it. Their turn and stretch
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


def triangle_heights(areas: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The smallest height (m,) of each triangle: its doubled area (``areas`` (m,)) over its longest
    side (``lengths`` (m, 3)); a key's triangles are not degenerate (checked where keys are given:
    :meth:`core.mesh_topology.MeshTopology.check_pose`), so no side is 0."""
    return 2.0 * areas / lengths.max(axis=1)


def thin_triangles(base, nxt, floor: float) -> np.ndarray:
    """Indices (int (k,), ascending) of the m triangles less high (:func:`triangle_heights`) than
    the length ``floor`` in key ``base`` or ``nxt`` (:class:`core.inbetween_keys.Key`: its ``areas``
    (m,) and edge ``lengths`` (m, 3)): slivers and needles whose shape the keys tell only to the
    fits' precision (:data:`core.inbetween_field.HELD_BEYOND_KEYS`)."""
    thinnest = np.minimum(base.heights, nxt.heights)
    return np.flatnonzero(thinnest < floor)


def untold_triangles(base, nxt, floor: float) -> np.ndarray:
    """Bool (m,): the triangles less high (:func:`triangle_heights`) than the length ``floor`` in
    both key ``base`` and key ``nxt`` (:class:`core.inbetween_keys.Key`)."""
    return (base.heights < floor) & (nxt.heights < floor)


def unfaced_triangles(base, nxt, noise: np.ndarray) -> np.ndarray:
    """Bool (m,): the triangles less high (:func:`triangle_heights`) in key ``base`` or key ``nxt``
    than twice the ``noise`` (m,: the RMS misfit of the rigid motion of a triangle's piece between
    the keys, 0 for a deforming piece, whose noise the keys do not tell): noise that size turns
    them over (the factor of :data:`core.rounded_slivers.ROUNDED_SLIVER`), so the keys do not tell
    which way they turn, nor which way they face in between (a sliver 1e-10 high in one key is as
    high as the noise makes it in the other)."""
    return (base.heights < 2.0 * noise) | (nxt.heights < 2.0 * noise)


def told_donors(across: np.ndarray, lengths: np.ndarray, untold: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, donors)`` (index arrays (k,)): each untold triangle (bool (m,) ``untold``) that
    reaches a told one across sides, and that told triangle: the one across its longest side if
    told (``across`` (m, 3): the triangle across each corner edge, -1 on the boundary,
    :attr:`core.inbetween_topology.Topology.across`; ``lengths`` (m, 3): the corner edges'), else,
    ring by ring, the donor of its neighbour across the longest side that has one. Untold
    triangles with no told triangle in their piece keep their own targets (not listed)."""
    donor = np.where(untold, -1, np.arange(len(untold)))
    thin_rows = np.flatnonzero(untold)
    neighbours = across[thin_rows]  # (k, 3)
    side = lengths[thin_rows]  # (k, 3)
    for _ in range(thin_rows.size):  # ring by ring; a ring that assigns none ends it
        open_ = donor[thin_rows] < 0
        if not open_.any():
            break
        given = np.where(neighbours >= 0, donor[np.maximum(neighbours, 0)], -1)  # (k, 3)
        # the neighbour with a donor across the longest side (the first such side where two are as long)
        best = given[np.arange(thin_rows.size), np.argmax(np.where(given >= 0, side, -1.0), axis=1)]
        reached = open_ & (best >= 0)
        if not reached.any():
            break
        donor[thin_rows[reached]] = best[reached]
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
