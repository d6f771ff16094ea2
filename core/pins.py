"""Pins: vertices a simulation holds rather than moves (Blender's pinned cloth).

Two kinds are found in the keys of a sequence and held by the in-betweens
(:class:`core.sequence_inbetweens.SequenceInterpolator`) instead of being reconstructed with the cloth:

- **still** vertices (:func:`still_vertices`) sit where they are in every key (a curtain's rod, a
  flag's pole that does not move): they stay exactly where the first key has them;
- **riding** vertices (:func:`riding_vertices`) are held by an animated object (a banner on a pole
  that is carried, a cape's collar on a moving character): sets of six or more vertices joined
  by edges that keep their lengths to single-precision rounding in every key, which no cloth does,
  moving as one rigid body that is only part of its piece. Each set follows the spline of its
  rigid motion (:func:`riding_motions`) through the keys as a screw, its turn continued across them
  (:func:`core.screw_motions.key_screws`), as the object's animation curves carry it.

Two keys (:class:`core.two_pose_inbetweens.Interpolator`) tell a riding set only by a whole rigid piece of
the mesh that moves with it (:func:`witnessed_riding`: the skin of a jaw with its teeth).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .rigid_alignment import align_rigidly, rigid_alignment, rigid_alignments
from .geometry import edge_lengths
from .seam_welds import vertex_groups

#: Riding sets have at least this many vertices, joined by edges whose lengths no key changes by
#: more than RIDING_ULPS float32 spacings of the keys' largest coordinate. A pole carried by its
#: object keeps them to 0.9 spacing (the float32 object matrix is orthogonal only to rounding);
#: cloth edges that happen to keep theirs over every key were found in sets of 3–9 vertices at
#: 4.8–40 spacings (a 10k sheet falling flat, keys 8 and 16 apart; the 50k sheet, 16). Each
#: set's best rigid motion must put it within the same tolerance in every key: a pole or rod
#: misses by at most 1 spacing, rounding of a rigid set by at most √3; far from the origin, where
#: the spacing is coarse, cloth beside a rod that stops dead kept its edges to 2 spacings and
#: missed its rigid motion by 5–11 (a sheet 100 units out, keys 8 and 16 apart: taken as riding
#: at four times the tolerance, 3,554 triangles flipped, 0.27 of its diagonal off).
MIN_RIDING_VERTICES = 6
RIDING_ULPS = 3.0
#: ... and in a piece at most this share of whose edges keep their lengths so: cloth around a held
#: part. A strip bent onto a cylinder keeps every ruling (a third of its edges), an articulated
#: limb its rigid segments; those are interpolated as they were, not held.
MAX_RIDING_SHARE = 0.05


def still_vertices(keys: list[np.ndarray], tolerance: float) -> np.ndarray:
    """Whether each vertex sits still in every one of ``keys`` (list of (n, 3); bool (n,)): no key
    moves it from its place in the first further than ``tolerance``
    (:func:`core.seam_welds.coincidence_tolerance`).
    Such vertices (pinned cloth) stay exactly where the first key has them. Compared exactly, the
    pins of a cache written in single precision through an object transform (moved by rounding)
    were taken for moving vertices: a 10k sheet pinned at two corners, its keys off by 1e-7 of
    the diagonal, had its corners 4.2 % of the diagonal off at keys 16 frames apart."""
    first = keys[0]
    rows = np.arange(first.shape[0])  # the candidates left: each key is read only there
    for key in keys[1:]:
        rows = rows[np.max(np.abs(key[rows] - first[rows]), axis=1) <= tolerance]
    still = np.zeros(first.shape[0], dtype=bool)
    still[rows] = True
    return still


def moving_edges(first: np.ndarray, edges: np.ndarray, still: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ``edges`` (E, 2) not between two ``still`` (n,) vertices (int indices (r,) into
    ``edges``) and their lengths (r,) in ``first`` (n, 3): what :func:`riding_tolerance` and
    :func:`riding_vertices` both read of a sequence's first key."""
    a, b = edges[:, 0], edges[:, 1]
    rows = np.flatnonzero(~(still[a] & still[b]))
    return rows, edge_lengths(first, a[rows], b[rows])


def riding_tolerance(keys: list[np.ndarray], edges: np.ndarray, still: np.ndarray, scale: float | None = None,
                     moving: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """The rounding to which riding sets keep their edges' lengths and their rigid motion in ``keys``
    (list of (n, 3)): :data:`RIDING_ULPS` single-precision spacings of ``scale``
    (:func:`core.coordinate_rounding.rounding_scale`, by default the keys' largest coordinate), at most a
    thousandth of the mean length of the ``edges`` (E, 2) not between two ``still`` vertices (far
    from the origin the roundings outgrow it); ``moving``: those edges and lengths
    (:func:`moving_edges` of the first key) when the caller has them."""
    largest = max(float(np.max(np.abs(key))) for key in keys) if scale is None else scale
    _, length = moving_edges(keys[0], edges, still) if moving is None else moving
    if not length.size:
        return 0.0
    return min(RIDING_ULPS * float(np.spacing(np.float32(largest))), 1e-3 * float(np.mean(length)))


def riding_vertices(keys: list[np.ndarray], edges: np.ndarray, component: np.ndarray,
                    still: np.ndarray, scale: float | None = None, tolerance: float | None = None,
                    moving: tuple[np.ndarray, np.ndarray] | None = None) -> list[np.ndarray]:
    """The sets of vertices (list of index arrays) that ride on an animated object in ``keys``
    (list of K ≥ 2 arrays (n, 3)). Each has at least :data:`MIN_RIDING_VERTICES` vertices joined
    by ``edges`` (E, 2) whose lengths every key keeps to single-precision rounding of ``scale``
    (:func:`riding_tolerance`, unless given), moves as one rigid body to that precision in every key
    (with two keys, translates as one), is not a whole
    piece (``component`` (n,): each vertex's piece, −1 for loose vertices; whole rigid pieces
    follow their screw motions) in a piece keeping no more than :data:`MAX_RIDING_SHARE` of its
    edges so, and is not all ``still`` (n,). ``moving``: the edges not between two still vertices
    and their lengths in the first key (:func:`moving_edges`) when the caller has them."""
    n = keys[0].shape[0]
    riding: list[np.ndarray] = []
    if len(keys) < 2 or not len(edges):
        return riding
    first = keys[0]
    # two keys: only sets that translate; a set that turns between two keys cannot be told from
    # cloth that happens to keep its edges over them (a sheet swung on a pinned corner: 17 such sets
    # of 6–9 vertices in a pair 4 frames apart, turned 15° or, along a line, 180°)
    moved = _translated if len(keys) == 2 else align_rigidly
    a, b = edges[:, 0], edges[:, 1]
    # the edges left, and their lengths in the first key: each key is read only there
    candidates, length = moving_edges(first, edges, still) if moving is None else moving
    if not candidates.size:
        return riding
    if tolerance is None:
        tolerance = riding_tolerance(keys, edges, still, scale, (candidates, length))
    for key in keys[1:]:
        close = np.abs(edge_lengths(key, a[candidates], b[candidates]) - length) <= tolerance
        candidates, length = candidates[close], length[close]
        if not candidates.size:
            return riding
    kept = np.zeros(len(edges), dtype=bool)
    kept[candidates] = True
    edge_piece = component[a]
    pieces_edges = np.bincount(edge_piece[edge_piece >= 0], minlength=int(component.max()) + 1)
    kept_edges = np.bincount(edge_piece[kept & (edge_piece >= 0)], minlength=pieces_edges.size)
    cloth = kept_edges <= MAX_RIDING_SHARE * pieces_edges  # per piece
    kept &= (edge_piece >= 0) & cloth[np.maximum(edge_piece, 0)]
    if not kept.any():
        return riding
    labels = vertex_groups(a[kept], b[kept], n)
    sizes = np.bincount(labels)
    piece_sizes = np.bincount(component[component >= 0])
    for label in np.flatnonzero(sizes >= MIN_RIDING_VERTICES):
        rows = np.flatnonzero(labels == label)
        pieces = np.unique(component[rows])
        if pieces.size != 1 or pieces[0] < 0 or rows.size == piece_sizes[pieces[0]] or still[rows].all():
            continue
        if all(np.max(np.linalg.norm(moved(first[rows], key[rows]) - key[rows], axis=1)) <= tolerance
               for key in keys[1:]):
            riding.append(rows)
    return riding


def witnessed_riding(keys: list[np.ndarray], edges: np.ndarray, component: np.ndarray, still: np.ndarray,
                     tolerance: float) -> list[np.ndarray]:
    """Two keys (``keys``: two (n, 3)): the sets of vertices of deforming pieces that ride on the
    same bone or object as a whole rigid piece of the mesh (the lower teeth and the skin of the jaw
    that opens with them): at least :data:`MIN_RIDING_VERTICES` vertices joined by ``edges`` (E, 2)
    that keep their lengths to ``tolerance`` (:func:`riding_tolerance`), not a whole piece nor all
    ``still`` (n,), that the best rigid motion of a piece (``component`` (n,), −1 for loose
    vertices) moving rigidly to ``tolerance`` takes to the second key within ``tolerance``. Two
    keys alone cannot tell a set that turns from cloth that happens to keep its edges over them
    (:func:`riding_vertices` takes only sets that translate); a separate piece moved by the same
    rigid motion to rounding can: no simulated cloth follows a body's motion that closely. Sets
    along a line are left out (a sheet rolled onto a cylinder keeps each ruling's lengths, and the
    motion of a sequin on it takes the ruling through its centre to its place to rounding). Such
    a set is held on that motion's screw in-between and beyond (a jaw opened 22° by skinning, two
    poses: 3–4.4 × the slider's error, 5.4e-3 of the diagonal at 0.5 and 4.2e-2 at ×2, its band
    of ramping weights interpolated by fields that turn the whole jaw; held, with the teeth on
    their own screw, 7.1e-4 and 6.7e-3, the slider 1.2e-3 and 9.7e-3)."""
    first, second = keys
    n = first.shape[0]
    used = np.flatnonzero(component >= 0)
    count = int(component.max()) + 1 if used.size else 0
    if count < 2 or not len(edges):
        return []
    rotations, translations = rigid_alignments(first[used], second[used], component[used], count)
    miss = np.linalg.norm(np.einsum("vab,vb->va", rotations[component[used]], first[used])
                          + translations[component[used]] - second[used], axis=1)
    worst = np.zeros(count)
    np.maximum.at(worst, component[used], miss)
    moves = np.bincount(component[used], ~still[used], minlength=count) > 0
    rigid = (worst <= tolerance) & moves
    if not rigid.any() or rigid[component[used]].all():
        return []
    a, b = edges[:, 0], edges[:, 1]
    kept = (component[a] >= 0) & ~rigid[np.maximum(component[a], 0)] & ~(still[a] & still[b])
    kept &= np.abs(np.linalg.norm(second[a] - second[b], axis=1) - np.linalg.norm(first[a] - first[b], axis=1)) <= tolerance
    if not kept.any():
        return []
    labels = vertex_groups(a[kept], b[kept], n)
    sizes, piece_sizes = np.bincount(labels), np.bincount(component[used], minlength=count)
    witnesses = np.flatnonzero(rigid)
    sets = []
    for label in np.flatnonzero(sizes >= MIN_RIDING_VERTICES):
        rows = np.flatnonzero(labels == label)
        pieces = np.unique(component[rows])
        if pieces.size != 1 or pieces[0] < 0 or rows.size == piece_sizes[pieces[0]] or still[rows].all():
            continue
        if _line(first[rows] - first[rows].mean(axis=0), tolerance) is not None:
            continue  # a line's own motion leaves a turn about it free: a ruling of a rolled sheet meets that of a sequin on it
        moved = np.einsum("wab,rb->wra", rotations[witnesses], first[rows]) + translations[witnesses][:, None]
        if np.min(np.max(np.linalg.norm(moved - second[rows], axis=2), axis=1)) <= tolerance:
            sets.append(rows)
    return sets


def riding_motions(base: np.ndarray, key: np.ndarray, sets: list[np.ndarray],
                   tolerance: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Each riding set's (:mod:`core.pins`) rigid motion from positions ``base`` to ``key`` (n, 3):
    rotations (S, 3, 3) and translations (S, 3) of ``x ↦ R x + t``, its turn about its centroid
    the short way round — for a set along a line (a pole; every vertex within the rounding
    ``tolerance``, :func:`riding_tolerance`, of it, as a set's rigid fit is) the least turn taking
    the line to the key's, since a turn about the line moves none of its vertices by more than that
    and the keys do not tell it — and its centroid onto the key's. A row of a sheet's vertices that
    goal springs carry along (graded pins under a shaken hook) is a line to the rounding: fitted as
    a body, its turn about the row is the rounding's (5–169° between keys 4 frames apart on a 19.6k
    sheet), and the spline of such turns swings rows of 7–14 vertices up to 0.24 (a sixth of the
    sheet) off their path, folding the cloth around them."""
    rotations, translations = np.zeros((len(sets), 3, 3)), np.zeros((len(sets), 3))
    for k, rows in enumerate(sets):
        start, end = base[rows].mean(axis=0), key[rows].mean(axis=0)
        a, b = base[rows] - start, key[rows] - end
        d0 = _line(a, tolerance)
        if d0 is not None:
            d1 = np.linalg.svd(b, full_matrices=False)[2][0]
            d1 = d1 if d1 @ (b.T @ (a @ d0)) >= 0.0 else -d1
            axis, cosine = np.cross(d0, d1), float(np.clip(d0 @ d1, -1.0, 1.0))
            norm = np.linalg.norm(axis)
            turn = axis / norm * np.arctan2(norm, cosine) if norm > 0.0 else np.zeros(3)
            rotations[k] = Rotation.from_rotvec(turn).as_matrix()
        else:
            rotations[k] = rigid_alignment(a, b)[0]
        translations[k] = end - rotations[k] @ start
    return rotations, translations


def _line(centred: np.ndarray, tolerance: float) -> np.ndarray | None:
    """The direction (3,) of the line the points ``centred`` (k, 3; about their mean) lie along,
    every one within ``tolerance`` of it (or collinear to round-off); None if they do not."""
    _, spread, axes = np.linalg.svd(centred, full_matrices=False)
    off_line = centred - np.outer(centred @ axes[0], axes[0])
    if spread[1] <= 1e-6 * spread[0] or np.max(np.linalg.norm(off_line, axis=1)) <= tolerance:
        return axes[0]
    return None


def _translated(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``source`` (k, 3) moved by the mean of ``target − source``: its best translation onto ``target``."""
    return source + np.mean(target - source, axis=0)
