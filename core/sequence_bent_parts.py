"""Parts of a piece that turn as rigid bodies far from each other between two keys (a skinned
limb bent at a joint), read from the triangles' rotations and stretches of a key seen from the
gap's base key (:class:`~core.inbetween_keys.Relative`, paper §8.4).

The in-betweens of a sequence are anchored to the keys' per-vertex splines; a part that turns about
a joint by θ between two keys would be pulled onto the spline's chord of its arc, which falls inside
the arc by a share growing with θ (a uniform Catmull–Rom through points turned evenly by θ per key,
at mid-gap: 6.0 / 11.6 / 16.9 % of the radius at 75 / 90 / 100°). The keys alone tell such parts:
regions of triangles kept isometric (metric ``G ≈ I``) with one rotation, each a share of its piece,
turning from one another, read per piece. A gap whose splines read such a turn in a piece it does
not read turning is anchored as two poses are, its pieces read turning left at the sequence's gauge
(:meth:`core.sequence_inbetweens.SequenceInterpolator._bent_nearby`): past ``BENT_PART_TURN`` for
parts isometric to ``ISOMETRIC`` (a cloth's flat patches are too), past ``RIGID_BENT_TURN`` for parts
rigid to the keys' rounding (``RIGID_METRIC``: a skinned bone's; a cloth's only where it is pinned,
two pinned shares of its piece on carriers turning apart, whose gaps are then anchored too, their
in-betweens at most 2.4 % farther from the simulation: docs/inbetween-measurements.md). Rigid to the
keys' rounding means to what their coordinates' rounding (a decimal grid they were stored on, or their
precision) moves each triangle's metric by, up to ``RIGID_METRIC_CAP`` (:func:`rounded_tolerance`);
past it a gap whose parts only the rounding keeps from being read rigid warns
(:func:`hidden_rigid_turn`).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

#: Rotation between two triangles sharing an edge (radians) under which they turn as one.
SAME_TURN = 1e-2
#: Largest deviation of the metric ``G`` from the identity (entries) of a triangle kept isometric.
ISOMETRIC = 5e-3
#: Largest angle (radians) of a region's triangles from its mean rotation: a rigid part, not a
#: slow bend whose neighbours each turn alike.
RIGID_SPREAD = np.radians(2.0)
#: Least share of its piece's area that a rigid part covers.
PART_SHARE = 0.05
#: Turn between two rigid parts of a piece (radians) past which the keys' per-vertex spline cuts
#: their arc measurably (6.0 % of the radius at mid-gap): a gap whose spline reads such a turn (its
#: own, or a neighbouring gap's) is anchored as two poses are.
BENT_PART_TURN = np.radians(75.0)
#: Turn between two rigid parts of a piece (radians) past which a sequence of only two keys, or a
#: linear one (``smooth=False``: each gap's spline is its keys' chord), anchors its gaps as two
#: poses do: twice the spread a rigid part may have (``RIGID_SPREAD``), so a piece read as two parts
#: turned apart is bent at a joint, not a part's own rounding.
TWO_KEY_BENT_TURN = 2.0 * RIGID_SPREAD
#: Largest deviation of the metric ``G`` from the identity (entries) of a triangle kept rigid to the
#: keys' rounding: a skinned bone's region (weight 1) is moved as a rigid body, its metric off only by
#: the single-precision keys' rounding (1e-7–1e-6), where a cloth's patches keep their metric only to
#: their stretch (the hanging sheet's parts read past ``ISOMETRIC``'s 5e-3 at 1.7–4.5e-3, turning
#: 7–10.5° apart; no moving cloth of the benchmark keeps a tenth of a piece within 1e-4, though a
#: cloth pinned over two shares of its piece does: pins move as rigid bodies too).
RIGID_METRIC = 1e-4
#: Turn between two parts of a piece rigid to the keys' rounding (``RIGID_METRIC``; radians) past which
#: a sequence's gap is anchored as two poses are, whatever its spline: the keys' per-vertex spline cuts
#: a turning part's arc at any turn, most in the first and last gaps, whose end tangents bend it off
#: the arc (an LBS tube keyed 30° apart: 1.8e-3 of the diagonal off the rig half-way in its first gap,
#: two poses 4.3e-4), and parts rigid to the rounding are a joint's or a pin's, not a free cloth's
#: (no moving cloth of the benchmark has them; a cloth pinned to two carriers turning apart is
#: anchored, its in-betweens at most 2.4 % farther from the simulation, docs/inbetween-measurements.md).
#: The same least turn as two keys' (``TWO_KEY_BENT_TURN``): a bend, not a part's rounding.
RIGID_BENT_TURN = TWO_KEY_BENT_TURN
#: Largest deviation of a rigid triangle's metric from the identity (entries) per unit of the keys'
#: rounding over its smallest height (``q / h``, :func:`rounded_tolerance`): rounding each corner's
#: coordinates by up to half a step ``q`` changes its edges by up to √3 q and its metric, taken from both
#: keys, by a few ``q / h``; measured on the LBS tube of tests/core/test_sequence_bent_parts.py stored
#: to 3–6 decimals, its bones' triangles at most 1.2–1.9 ``q / h`` off (99th percentile 1.0–1.3).
ROUNDED_RIGID = 4.0
#: Largest tolerance (entries of ``G − I``) a triangle rigid to the keys' rounding is read with, however
#: coarse the rounding (:func:`rounded_tolerance`): at 1e-3 the 16 cloth scenes of the benchmark read at
#: most 1.6° between parts at g = 4 / 8 / 16 (flag_wind), under ``RIGID_BENT_TURN``, where at
#: ``ISOMETRIC``'s 5e-3 a hanging sheet reads parts 7–10.5° apart (docs/inbetween-measurements.md).
#: Keys rounded coarser than that allows (``ROUNDED_RIGID q / h`` past it) may hide a bone's rigidity:
#: the gap warns where it reads parts turned apart only as isometric (:func:`hidden_rigid_turn`).
#: A cloth's parts are read to this only where its keys are rounded so coarsely (float32 keys of the
#: benchmark's cloths: only their crushed triangles, whose metric is far off the identity anyway).
RIGID_METRIC_CAP = 1e-3
#: Largest deviation (entries) of a part's area-weighted mean metric from the identity for the gap to
#: warn that the keys' rounding may hide a bone (:func:`hidden_rigid_turn`): a bone's triangles are off
#: by the rounding alone, which averages out over the part, where a cloth's patch keeps its stretch.
#: The LBS tube of tests/core/test_sequence_bent_parts.py stored to 3 decimals reads its bones within
#: it in every gap (30° apart); the hanging sheet (hang_corners) stored to 4 decimals reads no patch
#: within it, where its patches read 7–23.6° apart to 2e-3 and up to 2.3° to 1e-3.
HIDDEN_PART_MEAN = 6e-4


def _isometric(metric: np.ndarray, tolerance: float = ISOMETRIC) -> np.ndarray:
    """Whether each triangle is kept isometric (bool (m,)): every entry of its metric ``G``
    (``metric`` (m, 3), packed ``(g11, g12, g22)``) within ``tolerance`` of the identity's."""
    g11, g12, g22 = metric[:, 0], metric[:, 1], metric[:, 2]
    return (np.abs(g11 - 1.0) < tolerance) & (np.abs(g12) < tolerance) & (np.abs(g22 - 1.0) < tolerance)


def rigid_share(triangle_component: np.ndarray, metric: np.ndarray, areas: np.ndarray) -> bool:
    """Whether a piece keeps room for two rigid parts from a key to another: twice the least part's
    share of its area (``PART_SHARE``) kept isometric (``ISOMETRIC``; no free cloth of the benchmark
    has it, a cloth pinned over two shares of its piece does).

    ``triangle_component`` int (m,): each triangle's piece; ``metric`` (m, 3): each triangle's metric
    ``G`` packed ``(g11, g12, g22)``; ``areas`` (m,): the triangles' areas in the base key."""
    return _room(triangle_component, metric, areas)[2]


def _room(triangle_component: np.ndarray, metric: np.ndarray, areas: np.ndarray,
          tolerance: float = ISOMETRIC) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(isometric, piece_area, room)``: :func:`_isometric` (to ``tolerance``), each piece's area (C,)
    and :func:`rigid_share`'s answer, for :func:`bent_part_turns` to read on without computing them again."""
    isometric = _isometric(metric, tolerance)
    piece_area = np.bincount(triangle_component, areas)
    room = bool((np.bincount(triangle_component[isometric], areas[isometric], minlength=len(piece_area))
                 >= 2 * PART_SHARE * piece_area).any())
    return isometric, piece_area, room


def _far_turn(least: float) -> float:
    """The least angle (radians) from its piece's rigid turn of every triangle of a rigid part turned
    ``least`` / 2 or more from it (:func:`bent_part_turns`): ``least`` / 2 − ``RIGID_SPREAD``, taken a
    millionth short so that round-off in the angles read never lets a part through."""
    return max(0.5 * least - RIGID_SPREAD, 0.0) * (1.0 - 1e-6)


def _far_share(triangle_component: np.ndarray, areas: np.ndarray, piece_area: np.ndarray, far: np.ndarray) -> bool:
    """Whether some piece (``piece_area`` (C,)) has ``PART_SHARE`` of its area on the triangles ``far``
    (bool (m,); ``triangle_component`` int (m,), ``areas`` (m,)), to within round-off of the sums."""
    held = np.bincount(triangle_component[far], areas[far], minlength=len(piece_area))
    return bool((held >= PART_SHARE * piece_area * (1.0 - 1e-9)).any())


def bent_part_turns(triangle_component: np.ndarray, edge_pairs: np.ndarray, rotvec: np.ndarray,
                    metric: np.ndarray, areas: np.ndarray, least: float = BENT_PART_TURN,
                    tolerance: float | np.ndarray = ISOMETRIC, mean: float | None = None) -> np.ndarray:
    """Per piece (float (C,), C = ``triangle_component.max() + 1``), the largest turn (radians)
    between two rigid parts of it from a key to another; 0 for a piece without two parts, and for
    every piece where none can turn over ``least`` (radians) from another (no isometric triangle
    turns by ``least`` / 2 from its piece's rigid turn, or no piece has ``PART_SHARE`` of its area on
    isometric triangles turned ``least`` / 2 − ``RIGID_SPREAD`` from it): the callers compare with
    ``least``.

    ``triangle_component`` int (m,): each triangle's piece; ``edge_pairs`` int (e, 2): the
    triangles sharing each interior edge; ``rotvec`` (m, 3): each triangle's rotation with its
    piece's rigid rotation undone (rotation vectors, :attr:`core.inbetween_keys.Relative.rotvec`);
    ``metric`` (m, 3): each triangle's metric ``G`` packed ``(g11, g12, g22)`` in the base key's
    tangent basis; ``areas`` (m,): the triangles' areas in the base key.

    A rigid part is a connected region of isometric triangles (every metric entry within
    ``tolerance`` of the identity's: ``ISOMETRIC``, or ``RIGID_METRIC`` for parts rigid to the keys'
    rounding; per triangle (m,) where raised to it, :func:`rounded_tolerance`) whose neighbours turn
    alike (``SAME_TURN``), each within ``RIGID_SPREAD`` of the region's mean rotation and covering
    ``PART_SHARE`` of its piece's area; with ``mean``, only a region whose area-weighted mean metric
    is the identity's to ``mean`` (every entry): a rigid part's triangles are off by the keys'
    rounding alone, which averages out over the region, where a cloth's patch keeps its stretch. Per
    piece, so that a gap can anchor a bent piece while another piece of the mesh keeps its own
    placement (:meth:`core.sequence_inbetweens.SequenceInterpolator._bent_nearby`)."""
    m = len(rotvec)
    largest = np.zeros(0 if m == 0 else int(triangle_component.max()) + 1)
    if m == 0 or len(edge_pairs) == 0:
        return largest
    isometric, piece_area, room = _room(triangle_component, metric, areas, tolerance)
    largest = np.zeros(len(piece_area))
    if not room:
        return largest
    # two parts turned from each other by θ turn at least θ / 2 from the piece's rigid turn, which
    # ``rotvec`` is taken from in a sequence: a piece near it throughout has none (a cloth at rest)
    squared = np.einsum("ij,ij->i", rotvec, rotvec)
    if 2.0 * np.sqrt(squared[isometric].max()) <= least:
        return largest
    # ... and each triangle of such a part within RIGID_SPREAD of its mean turn: a part's whole area,
    # PART_SHARE of its piece's, on isometric triangles turned least / 2 − RIGID_SPREAD or more (a
    # rotation vector is no shorter than its angle); where no piece has that much, none turns over
    # ``least`` (crumpled cloth: isometric triangles turned far, each alone or in small patches)
    if not _far_share(triangle_component, areas, piece_area, isometric & (squared >= _far_turn(least) ** 2)):
        return largest
    rows = np.flatnonzero(isometric)  # the isometric triangles, numbered 0 … len(rows) − 1 below
    number = np.full(m, -1)
    number[rows] = np.arange(rows.size)
    a, b = number[edge_pairs[:, 0]], number[edge_pairs[:, 1]]
    candidate = (a >= 0) & (b >= 0)
    a, b = a[candidate], b[candidate]
    # unit quaternions: two rotations are θ apart where |q · q'| = cos(θ / 2)
    quaternions = Rotation.from_rotvec(rotvec[rows]).as_quat()
    alike = np.abs(np.einsum("ij,ij->i", quaternions[a], quaternions[b])) > np.cos(SAME_TURN / 2)
    a, b = a[alike], b[alike]
    graph = coo_matrix((np.ones(a.size), (a, b)), shape=(rows.size, rows.size))
    _, labels = connected_components(graph, directed=False)
    pieces, weights = triangle_component[rows], areas[rows]
    region_area = np.bincount(labels, weights)
    first = np.zeros(labels.max() + 1, dtype=np.int64)
    first[labels[::-1]] = np.arange(rows.size)[::-1]  # a triangle of each region: its piece
    large = np.flatnonzero(region_area >= PART_SHARE * piece_area[pieces[first]])
    if np.bincount(pieces[first[large]], minlength=len(piece_area)).max(initial=0) < 2:
        return largest  # no piece has two
    parts: dict[int, list[np.ndarray]] = {}
    for region in large:
        inside = np.flatnonzero(labels == region)
        turn = Rotation.from_quat(quaternions[inside]).mean(weights=weights[inside]).as_quat()
        if np.abs(quaternions[inside] @ turn).min() < np.cos(RIGID_SPREAD / 2):
            continue
        if mean is not None:
            off = weights[inside] @ (metric[rows[inside]] - (1.0, 0.0, 1.0)) / weights[inside].sum()
            if np.abs(off).max() > mean:
                continue
        parts.setdefault(int(pieces[inside[0]]), []).append(turn)
    for piece, means in parts.items():
        for i in range(len(means)):
            for j in range(i + 1, len(means)):
                largest[piece] = max(largest[piece], 2.0 * float(np.arccos(min(1.0, abs(float(means[i] @ means[j]))))))
    return largest


def rounded_tolerance(heights: np.ndarray, rounding: float, least: float, most: float = np.inf) -> np.ndarray:
    """Per triangle (m,), a tolerance of the metric's deviation from the identity (entries) raised to
    what the keys' coordinate ``rounding`` (their grid's step,
    :func:`core.coordinate_rounding.decimal_rounding`, or their precision's spacing,
    :func:`core.coordinate_rounding.coordinate_rounding`, in the units of ``heights``) moves it by:
    ``ROUNDED_RIGID`` × ``rounding`` over its smallest height (``heights`` (m,)), at least ``least``,
    at most ``most``. Rigid to the keys' rounding: ``least`` = ``RIGID_METRIC``, ``most`` =
    ``RIGID_METRIC_CAP`` (keys stored to 5 decimals on edges of 0.1 move a bone's metric by up to
    2.2e-4: at ``RIGID_METRIC`` alone a limb keyed 20° apart read no rigid part in its last gap and was
    placed by the keys' spline, 1.6e-3 of its diagonal off the rig)."""
    return np.clip(ROUNDED_RIGID * rounding / heights, least, most)


def rounding_hides(triangle_component: np.ndarray, heights: np.ndarray, areas: np.ndarray,
                   rounding: float) -> np.ndarray:
    """Per piece (bool (C,)), whether the keys' coordinate ``rounding`` moves the metric of
    ``PART_SHARE`` of its area or more past ``RIGID_METRIC_CAP`` (``ROUNDED_RIGID`` × ``rounding`` over
    the triangles' smallest ``heights`` (m,); ``areas`` (m,), ``triangle_component`` int (m,)): the keys
    may hide whether its parts are rigid bones (a part is ``PART_SHARE`` of its piece)."""
    piece_area = np.bincount(triangle_component, areas)
    coarse = ROUNDED_RIGID * rounding / heights > RIGID_METRIC_CAP
    return np.bincount(triangle_component[coarse], areas[coarse], minlength=len(piece_area)) >= \
        PART_SHARE * piece_area


def hidden_rigid_turn(hidden: np.ndarray, isometric_turn: np.ndarray, rigid_turn: np.ndarray) -> float:
    """The largest turn (radians) between two parts of a piece that the gap reads isometric to the keys'
    rounding, their mean metric the identity's to ``HIDDEN_PART_MEAN`` (``isometric_turn`` (C,),
    :func:`bent_part_turns` from ``RIGID_BENT_TURN`` to :func:`rounded_tolerance` from ``ISOMETRIC``,
    ``mean`` = ``HIDDEN_PART_MEAN``) past ``RIGID_BENT_TURN`` but not rigid (``rigid_turn``
    (C,), to it from ``RIGID_METRIC``), in a piece whose keys' rounding may hide a skinned bone's rigidity
    (``hidden`` bool (C,), :func:`rounding_hides`): such a gap is placed by the keys' per-vertex spline,
    which cuts a bone's arc (an LBS tube keyed 0 / 30 / 60 / 90° to 3 decimals, edges 0.1: 3.1e-3 of its
    diagonal off the rig, two poses 4.3e-4). 0 where no piece is so."""
    turn = np.where(hidden & (rigid_turn <= RIGID_BENT_TURN), isometric_turn, 0.0)
    return float(turn.max(initial=0.0)) if (turn > RIGID_BENT_TURN).any() else 0.0


def hidden_rigid_warning(turn: float, rounding: float, decimals: bool, names: tuple[str, str]) -> list[str]:
    """The gap's warning (list of at most one message) of parts of a piece turned ``turn`` (radians,
    :func:`hidden_rigid_turn`; none where 0) apart between the keys ``names``, whose coordinate
    ``rounding`` (a decimal grid's step where ``decimals``, else single precision's spacing) hides
    whether they are a joint's rigid bones."""
    if not turn > 0.0:
        return []
    places = max(0, int(round(-np.log10(rounding))))
    how = (f"stored to {places} decimal{'' if places == 1 else 's'}" if decimals else
           f"rounded to {rounding:.2g} (single precision this far from the origin)")
    way = ("store them with more decimals" if decimals else
           "move the mesh's origin near it, or give the keys relative to it")
    return [f"between {names[0]} and {names[1]}, parts of a piece turn {np.degrees(turn):.0f}° apart, but the keys "
            f"are {how}, too coarse to tell whether they are rigid bones at a joint: they are placed as a cloth is, "
            "by the keys' per-vertex splines, which cut a bone's arc (up to a few thousandths of the mesh's size); "
            f"if it is a limb, {way}"]
