"""Each piece's rigid motion between two keys of a gap (:mod:`core.inbetween_keys`): the best rigid fit
of its vertices (n, 3) by mass (:func:`rigid_fits`), the fit that keeps its pins where they are
when that leaves its triangles less to turn (:func:`pin_held_fits`), its screw coordinates
(:func:`component_screws`: what the splines of paper §8.4's in-betweens take) and how well
the fit is known from how rigid the piece is (:func:`turn_spread`, :func:`component_nonrigidity`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from . import deformation_fields as df
from . import rotation_continuity
from . import screw_motions
from .geometry import grouped_medians, nearest_rotations
from .inbetween_whole_rotations import SPURIOUS_RIGID_TURN
from .rigid_alignment import pivoted_alignment, rigid_alignments, turn_about_axis

if TYPE_CHECKING:
    from .inbetween_keys import Key
    from .inbetween_topology import Topology


def component_screws(rotations: np.ndarray, translations: np.ndarray, turns: np.ndarray, unwrap: bool,
                     nonrigidity) -> np.ndarray:
    """Screw coordinates (C, 6) of the components' rigid motions (C, 3, 3), (C, 3), each rotation
    vector taken nearest its ``turns`` row (see :func:`core.screw_motions.rigid_logs`), to
    within what the components' ``nonrigidity`` (C,) says their fits are known to."""
    return screw_motions.rigid_logs(rotations, translations, turns, unwrap, turn_spread(nonrigidity))


def whole_tells(turn: np.ndarray) -> bool:
    """Whether a whole mesh's rotation vector ``turn`` (3,) has a way round to give its pieces'
    half turns: neither a turn within :data:`~core.screw_motions.TURN_SPREAD` (the coarsest a
    fit is taken to be known) of none, whose axis may be rounding (an engine's fixed block and its
    crank turning 180°: the whole mesh's turn is 1e-7 rad), nor itself a half turn as short either
    way round within it (a mesh of one piece: its own turn)."""
    theta = float(np.linalg.norm(turn))
    return theta > screw_motions.TURN_SPREAD and not rotation_continuity.either_way(theta, screw_motions.TURN_SPREAD)


def turning_against(turns: np.ndarray, whole: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """Per piece (bool (C,)), whether its rotation vector (``turns`` (C, 3)) turns against the whole
    mesh's turn ``whole`` (3,): about the whole's axis the other way by more than it is known to
    (``spread`` (C,), radians), and is itself no half turn as short either way round. Where some
    piece does, the pieces do not all turn the whole mesh's way, which then tells no piece's half
    turn its way (meshing gears turn opposite ways: the large one's +90° made the whole's turn, and
    the small one's exact −180° was taken +180° with it, silently)."""
    axis = whole / max(float(np.linalg.norm(whole)), np.finfo(float).tiny)
    theta = np.linalg.norm(turns, axis=1)
    return (turns @ axis < -spread) & ~rotation_continuity.either_way(theta, spread)


def turning_with(rotations: np.ndarray, whole: np.ndarray) -> np.ndarray:
    """Per piece (bool (C,)), whether its rotation (``rotations`` (C, 3, 3)) turns with the whole
    mesh's turn ``whole`` (a rotation vector (3,)): its rotation relative to the whole's turns it
    less than the whole's own angle, so that the piece is nearer the whole's turn than no turn at
    all. Only such a piece takes its half turn's way from the whole mesh: a piece turning a half
    turn with a mesh turned nearly as far rides with it, where one turning about its own axis apart
    from what the rest does (the small of two meshing gears turned −180° beside the large one's
    +90°: the whole's fit turns 56°, the small gear 124° from it) is told nothing by it."""
    whole_rotation = Rotation.from_rotvec(np.asarray(whole, dtype=np.float64)).as_matrix()
    apart = np.linalg.norm(df.rotation_vectors(whole_rotation.T @ rotations), axis=1)
    return apart < np.linalg.norm(whole)


def turn_spread(nonrigidity) -> np.ndarray:
    """The angles (radians, (C,)) the components' rotations are known to, from their
    ``nonrigidity`` (C,) (see :data:`core.screw_motions.TURN_NOISE`)."""
    return np.minimum(screw_motions.TURN_NOISE * np.asarray(nonrigidity, dtype=np.float64), screw_motions.TURN_SPREAD)


#: A piece is nearly one-dimensional (a ribbon, a strap, a strand of hair cards) in a key where
#: the RMS spread of its vertices across its long axis (the second singular value of the centred
#: positions, by mass) is under this share of the spread along it. Its rigid fit's turn about that
#: axis rests on the small spread across it — the ribbon's width and the bow of its bend — and a
#: bend that swings from one side to the other reads as a turn of up to a half turn about the axis
#: the material does not make: a 3.0 × 0.08 ribbon (11,520 vertices) hanging and twisting from a
#: turning hook, keys 4 frames apart, is fitted 167.5° about its length where its triangles turn
#: 20° (the frames between, 40° in all): so interpolated, its gap is 1.18 × the linear blend's
#: error and 2.10 × Catmull–Rom's; from its triangles, 0.52 × and 0.92 ×. Such a piece takes that
#: turn from its triangles where they turn it over
#: :data:`~core.inbetween_whole_rotations.SPURIOUS_RIGID_TURN` from the fit (the fit adds turn they
#: do not make; :func:`_turned_as_triangles`): nearer, the two readings differ by how the piece's
#: own twist is spread (0.1–20° on the ribbon), and the fit is kept (taken from the triangles there
#: too, the ribbon keyed every 16 frames kept 5 flipped triangles where the fit keeps none). The 19
#: cloths of the benchmark and 51 other bakes are sheets whose spread across is never under 0.14 of
#: the spread along in any frame (a flag curled in wind); the two ribbons baked (twisting, piled)
#: reach 0.025 and 0.042.
THIN_PIECE = 0.1


def rigid_fits(topo: Topology, base: np.ndarray, other: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each component's best rigid motion taking vertices ``base`` (n, 3) onto ``other``: rotations
    (C, 3, 3), translations (C, 3) and the RMS misfits (C,) it leaves (mass-weighted). A piece
    nearly one-dimensional in either key (:data:`THIN_PIECE`) takes its turn about its long axis
    from its triangles (:func:`_turned_as_triangles`)."""
    if len(topo.components) <= df.SLICED_PIECES:  # few pieces: each on its rows (views where consecutive)
        fits = [rigid_alignments(base[rows], other[rows], None, 1, topo.weights[rows], singular_values=True)
                for rows in topo.component_rows]
        rotations = np.concatenate([fit[0] for fit in fits]).reshape(-1, 3, 3)
        translations = np.concatenate([fit[1] for fit in fits]).reshape(-1, 3)
        sigma = np.concatenate([fit[2] for fit in fits]).reshape(-1, 3)
    else:  # many: all at once (a loop took 0.1 s per call on 3,000 pieces)
        rows = topo.component_vertices
        rotations, translations, sigma = rigid_alignments(base[rows], other[rows], topo.component_labels,
                                                          len(topo.components), topo.weights[rows],
                                                          singular_values=True)
    # a piece thin in either key has a thin cross-covariance (its second singular value at most
    # the share THIN_PIECE of the first, to within how far the keys' long axes part): only those
    # pieces' own spreads are measured
    maybe = np.flatnonzero(sigma[:, 1] + sigma[:, 2] < THIN_PIECE * sigma[:, 0])
    if maybe.size:
        rotations, translations = _turned_as_triangles(topo, base, other, rotations.copy(), translations.copy(),
                                                       maybe)
    return rotations, translations, fit_misfits(topo, base, other, rotations, translations)


def _thin(points: np.ndarray, weights: np.ndarray) -> bool:
    """Whether ``points`` (r, 3) weighted by ``weights`` (r,) spread across their long axis by
    under :data:`THIN_PIECE` of their spread along it (RMS: singular values of the centred rows)."""
    w = weights / weights.sum()
    centred = points - w @ points
    spread = np.sqrt(np.maximum(np.linalg.eigvalsh((centred.T * w) @ centred), 0.0))  # ascending
    return bool(spread[1] < THIN_PIECE * spread[2])


def _turned_as_triangles(topo: Topology, base: np.ndarray, other: np.ndarray, rotations: np.ndarray,
                         translations: np.ndarray, pieces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``rotations`` (C, 3, 3), ``translations`` (C, 3) (the rigid fits from ``base`` (n, 3) to
    ``other``), each of the ``pieces`` (int (k,)) thin in either key (:data:`THIN_PIECE`) turned
    about its long axis in ``other`` (the cross-covariance's first left singular vector, which the
    positions tell) by the turn that best agrees with its triangles' whole rotations (paper §8.4's
    rotation field taken whole: the polar rotations of the triangles' planar maps, as
    :class:`core.inbetween_keys.Relative` takes them), by area in ``base``: the ``Q`` maximizing
    ``Σ a_t tr(Qᵀ W_t)`` (:func:`~core.rigid_alignment.turn_about_axis`), its translation keeping
    the piece's centroid's, where that turn exceeds :data:`~core.inbetween_whole_rotations.SPURIOUS_RIGID_TURN`.
    The triangles tell that turn where the positions read the bow of a bend instead; a rigid
    motion (every ``W_t`` the fit's rotation: no turn) is left as it is."""
    for c in pieces:
        rows = topo.components[c]
        w = topo.weights[rows]
        if not w.sum() > 0 or not (_thin(base[rows], w) or _thin(other[rows], w)):
            continue
        w = w / w.sum()
        s_mean, x_mean = w @ base[rows], w @ other[rows]
        covariance = ((other[rows] - x_mean).T * w) @ (base[rows] - s_mean)
        axis = np.linalg.svd(covariance)[0][:, 0]
        entries, areas = triangle_turns(topo.triangles[topo.triangle_component == c], base, other)
        whole = entries @ areas  # Σ a_t W_t (3, 3)
        angle = turn_about_axis(axis, rotations[c] @ whole.T)
        if abs(angle) <= SPURIOUS_RIGID_TURN:  # the positions read the turn the triangles make
            continue
        rotations[c] = Rotation.from_rotvec(angle * axis).as_matrix() @ rotations[c]
        translations[c] = x_mean - rotations[c] @ s_mean
    return rotations, translations


def triangle_turns(triangles: np.ndarray, base: np.ndarray, other: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The whole rotations ``W_t`` of ``triangles`` (r, 3) from vertices ``base`` (n, 3) to
    ``other`` (the polar rotations of their planar maps, as :class:`core.inbetween_keys.Relative`
    takes them; entries (3, 3, r)) and their areas (r,) in ``base``."""
    frames = []
    for x in (base, other):
        # (3 coordinates, 3 corners, r), as the keys' corner edge rows
        edges = np.ascontiguousarray(df.corner_edges(x, triangles).transpose(2, 1, 0))
        frames.append(df.tangent_frame_rows(edges))
    (base_columns, base_rows), (other_columns, other_rows) = frames
    turn, _ = df.planar_polar(*df.planar_map_entries(other_rows, df.inverse_edge_rows(base_rows)))
    entries = df.frame_rows_rotation_entries(df.plane_turned_frames(other_columns, turn), base_columns)
    return entries, 0.5 * np.abs(base_rows[0, 0] * base_rows[1, 2])


def mean_triangle_turns(topo: Topology, base: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Each component's rotation (C, 3, 3) nearest the area-weighted sum of its triangles' whole
    rotations from ``base`` (n, 3) to ``other`` (:func:`triangle_turns`): the turn its surface
    makes as a whole, which a deforming piece's positions may not tell."""
    entries, areas = triangle_turns(topo.triangles, base, other)
    pieces, count = topo.triangle_component, len(topo.components)
    sums = np.stack([np.stack([np.bincount(pieces, areas * entries[a, b], minlength=count) for b in range(3)], axis=1)
                     for a in range(3)], axis=1)  # (C, 3, 3)
    return nearest_rotations(sums)


def fit_misfits(topo: Topology, base: np.ndarray, other: np.ndarray, rotations, translations) -> np.ndarray:
    """Each component's RMS misfit (C,) (mass-weighted) of its rigid motion taking ``base`` onto ``other``."""
    residual = topo.apply_motion(base, rotations, translations) - other
    return np.sqrt(topo.component_sums(np.einsum("ij,ij->i", residual, residual)) / topo.component_mass)


#: A triangle's rotation past this angle (radians) is near a half turn, where its rotation vector's
#: direction is lost to rounding and a spline of it may take the other way round.
NEAR_HALF_TURN = 5 * np.pi / 6

#: The pins' fit is taken only where it leaves the triangles' median rotation smaller by more than
#: this (radians): a banner hung from two points and carried past a half turn had fits within 0.2°
#: of each other (median 38.0° against 38.1°, 560 against 562 past 150°), and the switch cost its
#: gap 4 % of RMS (the sequence's median 2.2 %); the handkerchief's fit that turned 176° left 28° more.
PIN_FIT_MARGIN = np.pi / 36
#: What the triangles' angles under the two fits, each from an arc cosine of a trace, may miss the
#: triangle inequality between them by (radians; an arc cosine near zero amplifies the trace's
#: rounding to ~2e-8): the bound that spares measuring the pins' fit where it cannot win
#: (:func:`pin_held_fits`) is loosened by this much.
PIN_BOUND_ROUNDING = 1e-6


def pin_held_fits(topo: Topology, base: Key, other: Key, whole, rotations, translations, misfits):
    """The pieces' rigid motions (``rotations`` (C, 3, 3), ``translations`` (C, 3), ``misfits`` (C,)
    from :func:`rigid_fits`), where a piece holds pins (``topo.pinned``: vertices at one place in
    every key) replaced by its best rigid motion that keeps them there
    (:func:`core.rigid_alignment.pivoted_alignment`) when that leaves its triangles less turn to
    make — a median angle of their rotations from ``base`` to ``other`` (``whole``: a function
    giving their entries (3, 3, m), asked only where a piece's two fits differ) with the
    piece's rotation undone smaller by :data:`PIN_FIT_MARGIN`, and fewer of them near a half turn
    (:data:`NEAR_HALF_TURN`). The free fit of a handkerchief pinned at its four centre vertices,
    folded into a bundle that looks alike after a half turn, turned 176° about its pins between keys
    8 frames apart, leaving its triangles 110° (median; 13 % past 150°) where they turned 82° (4 %):
    splined, 4,488 flipped triangles at the middle of the gap. A sheet rolled by 191° about its
    still half keeps the free fit (28°), which leaves 4 % of its triangles past 150° where the pins'
    would leave 12.5 %."""
    pinned = np.zeros(topo.n, dtype=bool)
    pinned[topo.pinned] = True
    held_rotations, held_translations = rotations.copy(), translations.copy()
    held = np.zeros(len(topo.components), dtype=bool)
    # each piece's rows selected by a view where they are consecutive (no (n, 3) copies)
    for c, (rows, selected) in enumerate(zip(topo.components, topo.component_rows)):
        pins = rows[pinned[rows]]
        if pins.size:
            held[c] = True
            held_rotations[c], held_translations[c] = pivoted_alignment(
                base.vertices[selected], other.vertices[selected], base.vertices[pins], topo.weights[selected])
    # a triangle's angle left to turn changes by at most the angle between the two fits (the
    # triangle inequality of rotation angles), so pieces whose fits differ by PIN_FIT_MARGIN or less
    # cannot take the pins' one: measured only where some piece's differ by more
    apart = np.linalg.norm(df.rotation_vectors(np.einsum("cji,cjk->cik", held_rotations, rotations)), axis=1)
    held &= apart > PIN_FIT_MARGIN
    if not held.any():
        return rotations, translations, misfits
    entries, pieces = whole(), topo.triangle_component

    def left_to_turn(fitted):  # per component: the triangles' rotations, the fit undone: median angle, near half turns
        angles = _fit_undone_angles(entries, fitted, pieces)
        count = len(topo.components)
        return grouped_medians(angles, pieces, count), np.bincount(pieces, angles > NEAR_HALF_TURN, count)

    free_median, free_near = left_to_turn(rotations)
    # the pins' fit is measured only on the pieces where it can win: it must leave fewer triangles
    # near a half turn than the free fit (so the free fit must leave some) and a median smaller by
    # the margin, while each triangle's angle under it is at least ``apart`` less its angle under
    # the free fit (the triangle inequality), so its median at least ``apart − free_median`` (to
    # PIN_BOUND_ROUNDING); elsewhere ``use`` below is False whatever the pins' fit measures
    held &= (free_near > 0) & (np.maximum(apart - free_median, 0.0) - PIN_BOUND_ROUNDING < free_median - PIN_FIT_MARGIN)
    if not held.any():
        return rotations, translations, misfits
    held_median, held_near = left_to_turn(held_rotations)
    use = held & (held_median < free_median - PIN_FIT_MARGIN) & (held_near < free_near)
    if not use.any():
        return rotations, translations, misfits
    rotations = np.where(use[:, None, None], held_rotations, rotations)
    translations = np.where(use[:, None], held_translations, translations)
    return rotations, translations, fit_misfits(topo, base.vertices, other.vertices, rotations, translations)


def _fit_undone_angles(entries: np.ndarray, rotations: np.ndarray, pieces: np.ndarray) -> np.ndarray:
    """The angle (m,) of each triangle's rotation ``W`` (its entries (3, 3, m)) with its piece's
    rotation ``R`` (``rotations`` (C, 3, 3), ``pieces`` (m,)) undone, ``Rᵀ W``: from its trace
    ``Σ_ab R_ab W_ab``, nine products per triangle."""
    r = rotations[0] if len(rotations) == 1 else np.moveaxis(rotations[pieces], 0, -1)  # (3, 3) or (3, 3, m)
    trace = sum(r[a, b] * entries[a, b] for a in range(3) for b in range(3))
    return df.trace_rotation_angles(trace)


def component_nonrigidity(misfits, base: Key, topo: Topology) -> list[float]:
    """Each component's RMS misfit of its best rigid motion over its bounding-box diagonal in the
    ``base`` key."""
    return list(np.asarray(misfits, dtype=np.float64) / base.diagonals)
