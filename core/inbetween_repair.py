"""Checking and repairing an in-between (flipped or collapsed triangles, non-finite values).

A defect-free fit is returned as it is. Otherwise the fit is repaired where the defects are:
rotations and stretches are imposed on the defective triangles and a neighbourhood that grows while
defects remain (:data:`REPAIR_RINGS`); in each connected part of a neighbourhood, in turn, the
interpolated rotations, the linear blend's rotations (integrable: they come from a mesh), the
blend's rotations and stretches (its local geometry spliced in, where the interpolated metric cannot
be realized without a fold), the local geometry of the keys' per-vertex spline, and each key's own
local geometry (nearer key first); the first that leaves the part defect-free is kept, so a repair
changes as small a region as it can, and only the parts left defective grow further (folds apart
from each other are repaired each by its own field and region; two poses and extrapolations take a
neighbourhood whole, see :meth:`Repair.rounds`). Regions stop growing once they
cover :data:`MAX_REPAIR_FRACTION` of a piece of the mesh or, for a
sequence's in-between, once a round of 4 rings or more removed no defect (:data:`STALLED_ROUND`),
and a repair of a sequence's in-between that moves the pose by more than :data:`MAX_REPAIR_MOVE` of the
keys' move is not taken: either would replace the pose rather than repair it, and the neighbouring
in-betweens would not follow. If no repair is defect-free, the Poisson solve alone is returned when
it is; otherwise an in-between of a sequence (three keys or more, factor strictly between 0 and 1)
is the metric fit with the fewest defects — a repair that leaves fewer counts only if it moves the
pose by at most :data:`MAX_PARTIAL_REPAIR_MOVE` mean edge lengths: its neighbours in time are fits
too, and a whole-pose substitute (the blend, a fit near it) or a large partial repair would jump
away from them and back; so is an extrapolation (beyond the keys the "blend" is the linear
extrapolation, which lengthens whatever turns). The in-betweens of two poses try the metric fitted
near the linear blend (strongly anchored), then the linear blend — they are held to the blend's
error — and the first
without defects is returned (the blend's defects include the triangles it crushes below
:data:`CRUSHED_AREA` of their interpolated area where neither key has them so: a cloth turning
between the keys, whose every chord the blend cuts); if none is, the metric fit with the fewest
defects. The fit near the
blend is skipped when the blend itself is defective (held near a folded blend it keeps the folds: on
the benchmark cloths it repaired none of the 24 poses whose blend was defective, at ~1 s each on the
50k-vertex sheet). An in-between of two poses whose checked fit ends farther from the
interpolated metric than the blend itself (and beyond the fit's tolerance) takes the metric fitted
near the blend too, where that has no more defects (:meth:`Repair.nearer_the_metric`). Each
fallback that leaves defects comes with a message for a
:class:`~core.errors.ShapeDifferenceWarning`.
"""

from __future__ import annotations

import threading
import weakref
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

from . import deformation_fields as df
from . import screw_motions
from .geometry import coordinate_cross, coordinate_dot
from .inbetween_fit import LOCAL_STEP_DTYPE, MAX_ROTATION_DEVIATION, METRIC_TOLERANCE

#: Pieces whose rigid fits miss them by less than this share of their size (noise, rounding) may
#: turn away from both keys with their edges off the interpolated metric by the gap's tolerance
#: (:meth:`Repair._turned_away`).
NOISY_TURN_NONRIGIDITY = 3e-2

#: A triangle whose area dropped below this fraction of its interpolated target area is collapsed.
COLLAPSE_RATIO = 1e-3
#: A triangle is flipped where its normal opposes the keys' (or the interpolated) normal by more
#: than this cosine: a piece half-way through an exact half turn has normals perpendicular to both
#: keys' in exact arithmetic, and rounding (~1e-16) made some of them look flipped, so a repair
#: bent a rigidly turning lid (edge lengths off by 56 %). Far below any fold one could see.
FLIP_COSINE = 1e-9
#: Repair rounds: each grows the region by this many vertex rings around the region of the
#: previous round (the first: around the defects) and imposes each field on it (numbers behind
#: the schedule in docs/inbetweens.md).
REPAIR_RINGS = (1, 1, 2, 4, 8)
#: From this round on (regions of 4 rings and more) only the fields whose local geometry comes
#: whole from a mesh — the blend's and each key's — are imposed: on the seven benchmark cloths (96
#: repaired poses) the interpolated rotations, the blend's rotations alone and the spline's
#: geometry never repaired a region that large, and those rounds cost the most.
WHOLE_GEOMETRY_ROUND = 2
#: From this round on a round that removes no defect ends a sequence's in-between's repairs while
#: this many defects or more remain (two poses and exaggerations try every round: their fallbacks
#: are the blend's, and on the soft 20k flag two poses 16 frames apart went from 0.901 to 0.997 ×
#: the blend's error with the rule): on 25 cloths at keys 4 / 8 / 16 apart (1,179 repaired or partly repaired poses) no
#: repair succeeded after such a round, and the larger regions that follow cost the most (a ball
#: through a 15k curtain: 37.6 → 31.9 ms per in-between at keys 4 apart, 40.8 → 34.6 at 16, medians
#: of four alternated runs; flipped triangles at 16: 1,008 → 1,018, the blend 1,125); with one defect
#: left the next round removed it (10k drape, keys 8 apart).
STALLED_ROUND, STALLED_DEFECTS = 2, 2
#: Largest repair region after the first round (fraction of the triangles of any one connected
#: piece of the mesh): the rounds end at a region that would cover more (docs/inbetweens.md,
#: *Pops*: a ball thrown through a 15k curtain, keys 16 frames apart, 66 → 42–56 ms per in-between,
#: largest frame-to-frame jump 10.6 → 0.52 × the simulation's; the benchmark cloths unchanged).
MAX_REPAIR_FRACTION = 0.5
#: Largest move of a repair of a sequence's in-between, RMS over the vertices, as a fraction of the
#: keys' RMS move across the gap (at least one mean edge length): a larger one jumps away from the
#: neighbouring in-betweens, which do not follow (numbers in docs/inbetweens.md, *Pops*). A
#: predicted in-between's clean repair that moves it by more than this fraction of the keys' move
#: with the pieces' rigid motions taken out gives way to the solve if that is clean
#: (:meth:`Repair.moved_far`; a cape on a walking rig, whose walk is most of the keys' move).
MAX_REPAIR_MOVE = 0.1
#: Largest move of a repair of a sequence's in-between that still leaves defects (kept as the fit
#: with the fewest defects when no repair is defect-free), RMS over the vertices, in mean edge
#: lengths: each in-between chooses its own, so a larger one is a jump away from neighbours that
#: chose another (a sphere lifting a sheet, keys 16 apart: largest frame-to-frame jump 10.6 →
#: 0.80 × the simulation's; numbers in docs/inbetweens.md, *Pops*).
MAX_PARTIAL_REPAIR_MOVE = 1.0
#: Local/global iterations of the fallback that fits the metric near the linear blend.
REPAIR_ITERATIONS = 10
#: Anchor weight of the fallback that fits the interpolated metric near the linear blend.
FALLBACK_ANCHOR_WEIGHT = 1e-1
#: The linear blend, a fallback of two poses, counts a triangle as defective where its area is below
#: this fraction of the interpolated area and neither key's is (the keys' own crushed triangles are
#: the cloth's): a banner carried and turned between poses 16 frames apart fell back to a blend
#: whose edges were 24–29 % short (the simulated frames 2–3 %; 3,209–8,199 of 20,000 triangles
#: crushed, the frames themselves 241–433 and the keys 110–256). On eight sampled pairs of each of
#: 35 cloths at 4 / 8 / 16 frames apart, 8 of 105 cells changed: edge deviation down in all 8 (the
#: banner at 16 15.2 → 6.5 %, the soft 20k flag 7.67 → 5.08 %, under its bound 6.41), RMS ÷ the
#: blend down in 4 (banner 0.969 → 0.887, soft 20k flag 0.995 → 0.818), the same in 3 and up in
#: one (a skirt on a twisting waist, 1.040 → 1.129: a fit with one flipped triangle instead of a
#: blend 17 % short; 1.007 in both over every second start frame).
CRUSHED_AREA = 0.5


class Outcome(NamedTuple):
    """What :meth:`Repair.checked` returned at one factor: the count of its flipped or collapsed
    triangles, and whether it is the linear blend or the interpolated metric fitted near it (a
    fallback from a fit whose defects no repair removed)."""

    defects: int
    near_blend: bool


class Repair:
    """Checks and repairs of the poses of one gap (a ``core.inbetween_solver._Gap``)."""

    def __init__(self, gap):
        # a weak reference: the gap owns its Repair, and a cycle would keep a gap the
        # sequence's cache let go (~150 MB at 100k vertices) alive until a full garbage collection
        self.gap = weakref.proxy(gap)
        self._keys: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._move_limits: tuple[float, float] | None = None
        self._far_move: float | None = None  # mean squared move: see moved_far
        self._local = threading.local()  # see _rows_of

    # --- defects

    def flipped(self, cross: np.ndarray, length: np.ndarray, s: float, frames: np.ndarray | None,
                rows=slice(None), sides=None, normals=None) -> np.ndarray:
        """Triangles (bool (r,)) among ``rows`` whose normal ``cross`` (3 coordinates, r; its
        lengths ``length`` (r,)) opposes both keys' unit normals (in-betweens, 0 ≤ s ≤ 1) or, for
        extrapolations, the interpolated normal ``R_T(s) n_T`` (``frames``: (3, m, 3) of every
        triangle, ``frames[2]`` the normals; without them: the nearer key's normal), by more than
        :data:`FLIP_COSINE` (``normals``: the keys' normals on ``rows``, if the caller has them)."""
        gap = self.gap
        slack = -FLIP_COSINE * length
        if 0.0 <= s <= 1.0:
            base, nxt = normals or (gap.base.normal_rows[:, rows], gap.next.normal_rows[:, rows])
            flipped = (coordinate_dot(cross, base) < slack) & (coordinate_dot(cross, nxt) < slack)
            if frames is not None and sides is not None and sides[2] is not None and flipped.any():
                flipped[self._turned_away(cross, slack, frames, rows, np.flatnonzero(flipped), sides)] = False
            return flipped
        if frames is not None:
            return coordinate_dot(cross, frames[2][rows].T) < slack
        return coordinate_dot(cross, (gap.base if s < 0.5 else gap.next).normal_rows[:, rows]) < slack

    def defects(self, x: np.ndarray, s: float, frames, stretch, rows=None, scale=None) -> np.ndarray:
        """Flipped or collapsed triangles of ``x`` (bool (m,), or (r,) for the triangle indices
        ``rows``); all of them if ``x`` is not finite. The interpolated areas come from
        ``stretch`` (packed (m, 3)) or, if given instead, their ratios to the base's ``scale``
        (m,; :meth:`core.inbetween_field.InterpolatedField.area_scale`)."""
        m = len(self.gap.topo.triangles)
        if not np.isfinite(x).all():
            return np.ones(m if rows is None else len(rows), dtype=bool)
        if rows is None:
            e1, e2 = self.gap.topo.triangle_sides(x)  # by coordinate (3, m)
            rows = slice(None)
            normals = None
        else:
            corners, normals, areas = self._rows_of(rows)
            p = np.take(x, corners, axis=0)  # (3 corners, r, 3) in one gather
            e1, e2 = (p[1] - p[0]).T, (p[2] - p[0]).T
        cross = coordinate_cross(e1, e2)
        if scale is None:
            st = stretch[rows]
            scale = st[:, 0] * st[:, 2] - st[:, 1] ** 2
        else:
            scale = scale[rows]
        target = (self.gap.base.areas if normals is None else areas) * scale
        length = np.sqrt(coordinate_dot(cross, cross))
        collapsed = 0.5 * length < COLLAPSE_RATIO * target
        return self.flipped(cross, length, s, frames, rows, (e1, e2, stretch), normals) | collapsed

    def _rows_of(self, rows: np.ndarray) -> tuple:
        """The corners (3, r: each corner's vertices contiguous), the keys' normals (two (3, r)) and
        the base's areas (r,) of the triangles ``rows``: a repair round checks each field's fit on
        the same region, so the last rows asked (per thread: a gap's in-betweens are repaired
        concurrently) keep them."""
        cached = getattr(self._local, "rows", None)
        if cached is None or cached[0] is not rows:
            gap = self.gap
            cached = self._local.rows = (rows, np.ascontiguousarray(gap.topo.triangles[rows].T),
                                         (gap.base.normal_rows[:, rows], gap.next.normal_rows[:, rows]),
                                         gap.base.areas[rows])
        return cached[1:]

    def _turned_away(self, cross, slack, frames, rows, candidates: np.ndarray, sides) -> np.ndarray:
        """Those of the ``candidates`` (positions among ``rows``) facing away from both keys that
        the interpolated rotation itself turns away from both (a part turning by more than a half
        turn between the keys: a finger curled by 120° at each of two joints has its tip face away
        from both keys half-way), whose normal ``cross`` (``sides``: its two sides from the first
        corner by coordinate and the interpolated stretches, packed (m, 3)) follows it and whose
        edges keep the interpolated metric within :data:`~core.inbetween_fit.METRIC_TOLERANCE`,
        in a part turning a whole ring of triangles (:meth:`_carrying_a_vertex`): these are not
        flipped. Cloth folds the fit made turn away too: without the metric
        condition two poses 16 frames apart on the banner had 2,564 → 11,463 triangles facing
        against both keys (4,272 with the gap's tolerance instead), in sequences 166 → 745 at
        g = 16; with it every pair and sequence cell of six cloths is unchanged, and an arm of
        three jointed links turning 80° per key at each joint (its last link 240°) is exact. In a
        check of the whole mesh, the candidates of a piece that turns as the interpolated field
        says are all kept, to the gap's tolerance (:meth:`_turning_pieces`), and those of a piece
        turning far that are edge-on to a key to the fit's precision (:meth:`_edge_on`)."""
        triangles = candidates if isinstance(rows, slice) else np.asarray(rows)[candidates]
        columns = frames[:, triangles]
        normal = coordinate_cross(columns[0].T, columns[1].T)  # (3 coordinates, r) of the interpolated R_T t1, R_T t2
        base, nxt = self.gap.base.normal_rows[:, triangles], self.gap.next.normal_rows[:, triangles]
        following = coordinate_dot(cross[:, candidates], normal)
        away = (coordinate_dot(normal, base) < 0) & (coordinate_dot(normal, nxt) < 0)
        away &= following > -slack[candidates]  # ... that follow it
        # a whole mesh's check first keeps the pieces that turn whole; the rest, one by one (below)
        turning = self._turning_pieces(cross[:, candidates], normal, following, base, nxt, columns, sides,
                                       candidates) if isinstance(rows, slice) else None
        kept_whole = None
        if turning is not None:
            kept_whole = candidates[turning]
            away &= ~turning
        # in a fit checked whole, triangles of a far-turning piece at edge-on with a key, to the
        # fit's precision (a repair region's fields are not fitted to it)
        edge_on = self._edge_on(cross[:, candidates], following, base, nxt, triangles) \
            if isinstance(rows, slice) else None
        if edge_on is not None:
            kept_whole = candidates[edge_on] if kept_whole is None else np.union1d(kept_whole, candidates[edge_on])
            away &= ~edge_on
        # ... and whose edges keep the interpolated metric (a part turning whole; a fold does not),
        # measured on those only: most candidates face along the interpolated rotation (a fold)
        # and the metric's target edges were most of the check's cost
        candidates, triangles, columns = candidates[away], triangles[away], columns[:, away]
        if not candidates.size:
            return candidates if kept_whole is None else kept_whole
        deviation = self._metric_deviation(columns, sides, candidates, triangles)
        # pieces nearly rigid but noisy keep the metric only to the gap's tolerance (a card with
        # noise 2e-3 of its size turning 185° between keys: its side faces read as flipped and a
        # repair tore it, edges 3–15 × their length); cloth keeps the strict one (above)
        gap = self.gap
        nearly_rigid = np.asarray(gap.nonrigidity)[gap.topo.triangle_component[triangles]] < NOISY_TURN_NONRIGIDITY
        tolerance = np.where(nearly_rigid, max(METRIC_TOLERANCE, gap.tolerance), METRIC_TOLERANCE)
        kept = self._carrying_a_vertex(candidates[deviation < tolerance], rows, kept_whole)
        return kept if kept_whole is None else np.sort(np.concatenate([kept_whole, kept]))

    def _carrying_a_vertex(self, kept: np.ndarray, rows, kept_whole) -> np.ndarray:
        """Those of ``kept`` (positions among ``rows``: candidates turned away from both keys along
        their interpolated rotation, edges on the metric) that lie in a part of them, joined where
        triangles share a vertex, that turns a whole ring: a vertex off the mesh's boundary all of
        whose triangles are kept (here or in ``kept_whole``). A part turning past a half turn
        carries its vertices' rings with it; a triangle or two folded over in cloth do not (their
        neighbours face a key), and a triangle keeps its edge lengths whatever its normal does, so
        the metric alone cannot tell them apart: two 20:1 slivers of a hanging band folded 154°
        between keys 16 frames apart, read the long way round by the interpolated rotations (their
        neighbours turn the other way), face away from both keys half-way (the simulated frame and
        the blend do not), and the metric rule alone keeps them, with no warning; repaired as
        flipped, they turn back with the pose's RMS error unchanged."""
        if not kept.size:
            return kept
        topo = self.gap.topo
        positions = kept if kept_whole is None else np.concatenate([kept, kept_whole])
        triangles = positions if isinstance(rows, slice) else np.asarray(rows)[positions]
        corners = topo.triangles[triangles]
        vertices, local = np.unique(corners, return_inverse=True)
        local = local.reshape(-1, 3)
        ring = (np.bincount(local.ravel(), minlength=vertices.size) == topo.triangles_per_vertex[vertices]) \
            & topo.inner_vertices[vertices]
        if not ring.any():
            return kept[:0]
        r = len(triangles)
        labels = _corner_joined_parts(local.ravel(), vertices.size)[1]
        carrying = np.zeros(labels.max() + 1, dtype=bool)
        carrying[labels[r:][ring]] = True
        return kept[carrying[labels[:kept.size]]]

    def _edge_on(self, cross, following, base, nxt, triangles) -> np.ndarray | None:
        """Which candidates (bool (r,); ``cross`` their normals, ``following`` its products with
        their interpolated normals, ``base`` / ``nxt`` the keys' unit normals, ``triangles`` their
        indices) lie in a piece the sequence found turning far (``gap.turning``) and face away from
        a key by less than the angle ``arctan δ`` (δ the gap's tolerance) while facing along their
        interpolated normal; None where no piece turns far. The fit holds edges to a relative δ
        only, which leaves a triangle's turn that uncertain (a side whose end is δ off across it
        turns by about that angle): a triangle of a limb turning past a half turn that the field
        brings near edge-on to a key cannot be told from edge-on there, and is not flipped (a
        skinned tail wagging 300° per gap at its tip: one triangle 0.06° past edge-on with the
        first key, 3.8° from its interpolated normal and facing along the truth, read as flipped
        at the factor 0.25, with a warning). Asked of a fit checked whole: a repair imposes a
        field's local geometry on a region, which is not fitted to that precision (asked there too,
        an unevenly wagging skinned tail, 37 % of the diagonal off in a gap, kept the candidates its
        repair needed: 3 → 33 triangles against the truth, the warning gone)."""
        gap = self.gap
        if gap.turning is None:
            return None
        far = np.asarray(gap.turning)[gap.topo.triangle_component[triangles]]
        if not far.any():
            return None
        length = np.sqrt(coordinate_dot(cross, cross))
        sine = np.sin(np.arctan(max(METRIC_TOLERANCE, gap.tolerance))) * length
        near_key = (coordinate_dot(cross, base) > -sine) | (coordinate_dot(cross, nxt) > -sine)
        return far & near_key & (following > 0)

    def _metric_deviation(self, columns, sides, candidates, triangles) -> np.ndarray:
        """The mean relative deviation (r,) of the edge lengths of the ``candidates`` (positions
        among the checked rows; ``triangles``: their indices, ``columns``: their interpolated frames
        (3, r, 3), ``sides`` as in :meth:`_turned_away`) from the interpolated metric."""
        e1, e2 = sides[0][:, candidates], sides[1][:, candidates]
        target = np.linalg.norm(self.gap.local_targets(columns, sides[2][triangles], triangles)["edges"], axis=2)
        third = e2 - e1  # corner edges 0, 1, 2: e1, e2 − e1, −e2
        lengths = np.sqrt(np.stack([coordinate_dot(e1, e1), coordinate_dot(third, third), coordinate_dot(e2, e2)], axis=1))
        return np.mean(np.abs(lengths / target - 1.0), axis=1)

    def _turning_pieces(self, cross, normal, following, base, nxt, columns, sides, candidates) -> np.ndarray | None:
        """Which of the ``candidates`` (bool (r,); triangles facing away from both keys, all of
        the mesh's; ``cross`` their normals, ``normal`` their interpolated normals, ``following``
        the products of the two, ``base`` / ``nxt`` the keys' unit normals, ``columns`` their
        interpolated frames) lie in a piece where every candidate turns as the interpolated field
        says, or None if no piece does: a piece is turning where each candidate's normal is within
        the angle ``arctan δ`` of its interpolated normal (δ the gap's tolerance: a side whose end
        is a relative δ off its target across it turns by that angle; about δ where δ is small,
        and below a right angle however large the tolerance of a strongly stretching gap is), that
        normal is within the same angle of facing away from both keys, and the edges keep the
        interpolated metric to the gap's tolerance (the fit's own stop). In a piece a sequence
        found turning far from the rest of it (``gap.turning``: its rotations taken whole, not
        anchored to the keys' spline; for two poses, :meth:`_far_turning`) the normal may stray up to
        :data:`~core.inbetween_fit.MAX_ROTATION_DEVIATION` (the fit's local steps turn a triangle
        that far off its interpolated rotation, no farther), its interpolated normal may lie as far
        on a key's side of edge-on (the fit turns such a triangle past edge-on as readily as it
        strays: a skinned tail whose tip turns 300° per gap, half-way, 16 of 1,352 candidates of a
        100 × 40 tail had interpolated normals 1.8–4.4° on a key's side, their fits' 2.6–8.3° off
        them, and 734–2,274 triangles of five tessellations were read as flipped with the pose 1.2–1.3 %
        of the diagonal off the tail, none facing against it) and the metric is held on the
        candidates' mean (as the fit's stop is), to the gap's tolerance or, where larger, the mean
        relative change of the candidates' edges between the keys: the interpolated metric of
        noisy keys holds their noise, which no fit removes (a strip curled 300° at one joint with
        noise of 1e-4 of its length: its tip's fit 6.1e-3 off the metric on average, the gap's
        tolerance 5.0e-3, its edges' change between the keys 9.6e-3; read as flipped, a repair
        turned the tip the short way round, 0.63 of the diagonal off, silently): a thin arm curled
        95–170° per key at each of two joints has its fit within 0.15 % of the diagonal of the true
        curl half-way, where the interpolated field's normals are up to 18.6° off that curl's and
        the fit's 1.3–14.5° off them, single candidates 1.1–1.3 × the tolerance off the metric;
        held to ``arctan δ`` (0.8–1.8°) and to the tolerance per candidate, 28–63 of them read as
        flipped and a repair took the pose 0.02 → 0.47–0.51 % of the diagonal off, with a warning.
        Elsewhere that allowance would pass a part the interpolated field turns the wrong way
        round as a whole (a skinned arm twisting 156° between keys 8 frames apart, read the long
        way, 204°: 8,232 triangles facing against the truth, warned only under the tight limit).
        A closed tube (a finger) curled 120° at each of two knuckles bends its cross-sections, so
        its fit keeps the metric to 0.2–0.7 % where it turns away half-way, not to
        :data:`~core.inbetween_fit.METRIC_TOLERANCE`, and triangles edge-on to a key there face
        away by 1e-3 of their length where their interpolated normal does not: read as flipped,
        a repair replaces the curl by a pose 11–15 % of the diagonal off it. A cloth fold has
        other flipped triangles in its piece (compressed, or facing against the interpolated
        normal): on six benchmark cloths no piece was turning."""
        gap = self.gap
        tolerance = max(METRIC_TOLERANCE, gap.tolerance)
        angle = np.arctan(tolerance)
        pieces = gap.topo.triangle_component[candidates]
        count = len(gap.topo.piece_sizes)
        unit = normal / np.sqrt(coordinate_dot(normal, normal))
        lengths = np.sqrt(coordinate_dot(cross, cross) * coordinate_dot(normal, normal))
        per_piece = np.bincount(pieces, minlength=count)

        def whole_pieces(far_pieces: np.ndarray) -> np.ndarray:
            # the pieces each of whose candidates has its normal within the piece's angle of its
            # interpolated normal, and that one within the same angle of facing away from both keys
            limit = np.where(far_pieces, np.cos(MAX_ROTATION_DEVIATION), np.cos(angle))
            sine = np.where(far_pieces, np.sin(MAX_ROTATION_DEVIATION), np.sin(angle))
            near = following >= limit * lengths
            near &= (coordinate_dot(unit, base) < sine) & (coordinate_dot(unit, nxt) < sine)
            return (np.bincount(pieces[near], minlength=count) == per_piece) & (per_piece > 0)

        if gap.turning is not None:
            far = gap.turning[:count]
        elif whole_pieces(np.ones(len(pieces), dtype=bool)).any():
            # two poses read their far-turning parts only where a piece would pass as one (a cloth
            # fold has candidates facing against their interpolated normals, and no piece does)
            far = self._far_turning()
        else:
            return None
        turning = whole_pieces(far[pieces])
        if not turning.any():
            return None
        inside = turning[pieces]
        deviation = self._metric_deviation(columns[:, inside], sides, candidates[inside], candidates[inside])
        # a piece with a candidate off the metric (far-turning pieces: off on average, as the fit's
        # stop is, by more than the keys' own edges differ there: noisy keys' interpolated metric
        # holds their noise, which no fit removes) is not turning: its candidates go to the rule below
        rows = candidates[inside]
        changes = np.mean(np.abs(gap.next.lengths[rows] / gap.base.lengths[rows] - 1.0), axis=1)
        limit = np.maximum(tolerance, np.bincount(pieces[inside], changes, minlength=count) / np.maximum(per_piece, 1))
        off = np.where(far, np.bincount(pieces[inside], deviation, minlength=count) >= limit * per_piece,
                       np.bincount(pieces[inside][deviation >= tolerance], minlength=count) > 0)
        turning &= ~off
        return turning[pieces] if turning.any() else None

    def _far_turning(self) -> np.ndarray:
        """Per piece (bool (C,)), whether a part of it turns far from the rest between the keys as
        a sequence reads it (:meth:`core.inbetween_keys._Relative.turning`), for a gap of two poses,
        which takes every piece's turns continuous across the mesh and reads no such parts for its
        anchor (a sequence's gaps have ``gap.turning``); none elsewhere. Read once per gap, where a
        check first has candidates facing away from both keys. Two poses of a tentacle curled 270°
        over eight skinned joints are fitted to 0.16 % of the interpolated metric half-way, its tip
        facing away from both keys, two of its 2,133 such triangles 1.29° and 1.38° off their
        interpolated normals: held to the ``arctan δ`` (1.25°) of a piece not known to turn far,
        they are read as flipped and a repair falls back to the metric fitted near the blend, 0.32
        of the diagonal off the rig's own pose at 0.5 where 0.45 and 0.55 are within 1.3e-3. A part
        past a half turn whose rotations jump at a crease counts too: a sequence leaves such a part
        as it is, but two poses take its turns continuous across the crease all the same, and the
        fit follows them only to the keys' noise (a strip curled 270° over four rings of triangles,
        67.5° apart, with noise of 1e-4 of its length: its tip's fitted normals 0.4° off their
        interpolated ones, 0.98° at most, where ``arctan δ`` is 0.30°; read as flipped, a repair
        turned the tip the short way round, 0.61 of the diagonal off at 0.5, silently)."""
        known = self.__dict__.get("_far")
        if known is None:
            gap = self.gap
            relative = gap.relatives[2]
            known = np.zeros(len(gap.topo.piece_sizes), dtype=bool)
            if relative._across is not None:
                # imported here: core.sequence_inbetweens imports this module
                from .sequence_turn_readings import TURNED_PART_SHARE
                reading = relative.turning(gap.topo, gap.base, gap.next, relative._across, TURNED_PART_SHARE)
                known = (reading[0] | reading[2])[:len(known)]  # past a half turn, without or with a crease
            self._far = known
        return known

    def problem(self, x, s, frames, stretch, defects=None) -> str | None:
        """What is wrong with ``x`` in words, or None (``defects``: those of ``x``, if known)."""
        if not np.isfinite(x).all():
            return "the reconstruction produced non-finite coordinates"
        count = int((self.defects(x, s, frames, stretch) if defects is None else defects).sum())
        return f"{count} triangle(s) flipped or collapsed" if count else None

    def grow(self, triangles: np.ndarray, rings: int) -> np.ndarray:
        """The triangles (bool (m,)) within ``rings`` vertex rings of ``triangles`` (walked on the
        vertex–triangle adjacency: the cost is that of the region, not of the mesh)."""
        topo = self.gap.topo
        adjacency = topo.vertex_triangles
        out = triangles.copy()
        rows = np.flatnonzero(out)
        used = np.empty(topo.n, dtype=bool)
        for _ in range(rings):
            used[:] = False  # the rows' vertices, ascending, by a mask (a sort of their corners costs more)
            used[topo.triangles[rows]] = True
            vertices = np.flatnonzero(used)
            starts, stops = adjacency.indptr[vertices], adjacency.indptr[vertices + 1]
            counts = stops - starts
            offsets = np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
            near = adjacency.indices[offsets]
            out[near] = True
            rows = np.flatnonzero(out)
        return out

    # --- repair and fallbacks

    def checked(self, x, x0, s, frames, stretch, guide, motion, rings=REPAIR_RINGS, defects=None,
                looser=None) -> tuple[np.ndarray, str | None]:
        """:meth:`outcome`'s pose and message; the rest of it is kept in the gap's ``outcomes[s]``
        (two poses choose between their fits by it: ``core.two_pose_inbetweens.Interpolator.pose``)."""
        x, message, count, near_blend = self.outcome(x, x0, s, frames, stretch, guide, motion, rings, defects,
                                                     looser)
        self.gap.outcomes[s] = Outcome(count, near_blend)
        return x, message

    def outcome(self, x, x0, s, frames, stretch, guide, motion, rings=REPAIR_RINGS, defects=None,
                looser=None) -> tuple[np.ndarray, str | None, int, bool]:
        """``(x, None, 0, False)`` if the fit ``x`` is defect-free, else a repair or a fallback with
        the message saying which, the count of its flipped or collapsed triangles and whether it is
        the linear blend or the metric fitted near it (``x0``: the Poisson solve of the
        interpolated field, or ``x`` itself when there is none; ``rings``: the repair rounds,
        :data:`REPAIR_RINGS` or fewer; ``defects``: :meth:`defects` of ``x`` if the caller has
        them; ``looser``: the fit's step within the whole key-to-key change's tolerance, or None
        (see :data:`core.inbetween_fit.TOLERANCE_TRIM`): where the repairs fail it is returned if
        it has no defect, a fit as the fit's stop allowed before)."""
        defects = self.defects(x, s, frames, stretch) if defects is None else defects
        problem = self.problem(x, s, frames, stretch, defects)
        if problem is None:
            return x, None, 0, False
        gap = self.gap
        best = (int(defects.sum()), x) if np.isfinite(x).all() else None  # the last resort: fewest defects
        blend = gap.linear_blend(s)
        if gap.use_extrinsic and best is not None:
            z, best = self.rounds(x, defects, s, frames, stretch, guide, blend, best, rings)
            if z is not None:
                return z, None, 0, False
        if looser is not None and self.problem(looser, s, frames, stretch) is None:
            return looser, None, 0, False
        if gap.use_extrinsic and x0 is not x and self.problem(x0, s, frames, stretch) is None:
            return x0, (f"{problem}; returned the interpolated rotation field's Poisson solve without metric "
                        "fit"), 0, False
        if best is not None and (self.in_sequence(s) or not 0.0 <= s <= 1.0):
            # keeps the metric, as its neighbours in time do; beyond the keys the "blend" is the
            # linear extrapolation, which lengthens whatever turns (×2 of a 100° elbow: a forearm
            # 1.94 × its length held near it, "the interpolated metric fitted near the blend")
            return best[1], self.kept_message(problem, best[0]), best[0], False
        # the fallbacks fit and check the whole mesh: its stretches whole (a repair of a predicted
        # in-between is given them by rows, core.inbetween_field._ByRows; [:] computes the rest)
        stretch = stretch[:]
        folds = self.defects(blend, s, None, stretch)
        # a fit held near a folded blend keeps its folds: tried only where the blend has fewer
        # folds than the metric fit (two poses of a cloth folding over as it is dragged by a
        # corner, keys 16 frames apart: 713 against the blend's 59, the fit near it 243, RMS 1.61
        # → 1.00 × the blend's)
        if best is None or int(folds.sum()) < best[0]:
            y = self.fitted_near_blend(blend, s, stretch, motion)
            # the fit hands back its start when no step improves on it: then it is the blend, said so
            fitted = "the linear blend (no fit near it improved on it)" if np.array_equal(y, blend) else \
                "the interpolated metric fitted near the linear blend"
            if self.problem(y, s, None, stretch) is None:
                return y, f"{problem}; used {fitted} instead", 0, True
            if not (folds | self.crushed(blend, stretch)).any():
                return blend, (f"{problem}; the metric fit near the linear blend failed too, returned the "
                               "linear blend"), 0, True
            count = int(self.defects(y, s, frames, stretch).sum())
            if best is None or count < best[0]:
                return y, (f"{problem}; no repair or fallback removed them all, returned {fitted}, which "
                           f"has the fewest ({count} flipped or collapsed triangle(s))"), count, True
        # No candidate is free of defects: the metric fit with the fewest rather than a candidate
        # that gives up the metric (the blend shortens edges by several percent: a visible pop).
        return best[1], self.kept_message(problem, best[0]), best[0], False

    def fitted_near_blend(self, blend, s, stretch, motion) -> np.ndarray:
        """The interpolated metric (``stretch``, whole) at factor ``s`` fitted from the linear
        ``blend`` with every vertex anchored to it at :data:`FALLBACK_ANCHOR_WEIGHT` (no rotation
        limit: the blend's own turns are the start)."""
        gap = self.gap
        system = (gap.topo.factor(FALLBACK_ANCHOR_WEIGHT), np.full(gap.topo.n, FALLBACK_ANCHOR_WEIGHT) * gap.topo.mass)
        return gap.fit(blend.copy(), stretch, None, blend, s, motion, REPAIR_ITERATIONS, system=system)

    def nearer_the_metric(self, result, s, stretch, motion, targets) -> tuple[np.ndarray, str | None]:
        """An in-between of two poses ``result`` (positions, message: what :meth:`checked` returned
        at factor ``s``), or the interpolated metric fitted near the linear blend where ``result``
        ends farther from the interpolated metric than the blend itself and beyond the fit's
        tolerance (mean relative deviation of the edge lengths from ``targets``, the fit's): the
        interpolated rotations do not integrate there, and their fit failed at its own objective
        where the blend did not. The fit near the blend is taken only with no more flipped or
        collapsed triangles than ``result`` (its outcome is kept in ``outcomes[s]``, as a fallback's).
        A sheet swinging off a rod that stops dead, two poses 4 frames apart: its fit 8.6 % off the
        metric where the blend is 5.0 % (the simulated frame 0.34 %), 4.06 × the blend's RMS error;
        the fit near the blend 2.8 % off, 0.96 ×."""
        gap = self.gap
        misfit = gap.misfit(gap.edges_of(result[0], LOCAL_STEP_DTYPE), targets)
        if misfit <= gap.tolerance:
            return result
        blend = gap.linear_blend(s)
        if misfit <= gap.misfit(gap.edges_of(blend, LOCAL_STEP_DTYPE), targets):
            return result
        stretch = stretch[:]
        y = self.fitted_near_blend(blend, s, stretch, motion)
        count = int(self.defects(y, s, None, stretch).sum())
        if count > gap.outcomes[s].defects:
            return result
        gap.outcomes[s] = Outcome(count, True)
        return y, None if not count else (
            f"{count} triangle(s) flipped or collapsed; the fit ended farther from the interpolated metric than "
            "the linear blend, returned the interpolated metric fitted near the linear blend")

    def crushed(self, x: np.ndarray, stretch: np.ndarray) -> np.ndarray:
        """Triangles (bool (m,)) of ``x`` whose area is below :data:`CRUSHED_AREA` of the
        interpolated area (``stretch``: packed (m, 3) at the pose's factor) where neither key's is."""
        gap = self.gap
        cross = coordinate_cross(*gap.topo.triangle_sides(x))
        target = CRUSHED_AREA * gap.base.areas * (stretch[:, 0] * stretch[:, 2] - stretch[:, 1] ** 2)
        return (0.5 * np.sqrt(coordinate_dot(cross, cross)) < target) & (gap.base.areas >= target) \
            & (gap.next.areas >= target)

    @staticmethod
    def kept_message(problem: str, count: int) -> str:
        """The warning's text when the metric fit with the fewest defects (``count``) is returned."""
        return (f"{problem}; no repair or fallback removed them all, returned the metric fit with "
                f"the fewest ({count} flipped or collapsed triangle(s))")

    def imposed_fields(self, s, frames, stretch, blend):
        """The fields imposed around defects, in the order tried: (function of triangle indices
        ``rows`` (r,) returning (frames (3, r, 3), packed stretches (r, 3)), whether it is whole
        geometry of a mesh) — the interpolated rotations, the linear blend's rotations
        (integrable: they come from a mesh), the blend's rotations and stretches, those of the
        keys' per-vertex spline, each key's own local geometry (nearer key first)."""
        gap = self.gap
        t = gap.topo.triangles

        def interpolated(rows):
            return frames[:, rows], stretch[rows]

        m = len(t)

        def mesh_field(positions):  # the local geometry of a mesh: integrable
            # per triangle, so each triangle's is computed once for the growing regions of the rounds
            # (and once for the two fields that read the blend's): positions, frames (2, m, 3), stretches, done
            memo = []

            def field(rows):
                if not memo:
                    points = positions() if callable(positions) else positions
                    memo.extend((points, np.empty((2, m, 3)), np.empty((m, 3)), np.zeros(m, dtype=bool)))
                points, frames_of, stretches_of, done = memo
                new = rows[~done[rows]]
                if new.size:
                    edges = df.corner_edges(points, t[new]).transpose(2, 1, 0)  # by coordinate
                    columns, coordinates = df.tangent_frame_rows(edges)
                    turn, mesh_stretch = df.planar_polar(*df.planar_map_entries(coordinates, gap.base.inverse_rows[:, new]))
                    frames_of[:, new] = df.plane_turned_frames(columns, turn)[:2].transpose(0, 2, 1)  # t1, t2: all a fit reads
                    stretches_of[new] = mesh_stretch
                    done[new] = True
                return frames_of[:, rows], stretches_of[rows]
            return field

        def key_field(index):  # the key's geometry made when a round first imposes it
            def field(rows):
                frames, stretches = self.key_geometry(index)
                return frames[:, rows], stretches[rows]
            return field

        keys = (1, 2) if s < 0.5 else (2, 1)  # nearer key first
        blend_field = mesh_field(blend)
        return [(interpolated, False), (lambda rows: (blend_field(rows)[0], stretch[rows]), False), (blend_field, True),
                (mesh_field(lambda: gap.splines["world"].at(s)), False)] + [(key_field(k), True) for k in keys]

    def key_geometry(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """The rotations (frames (2, m, 3): the images of t1, t2) and stretches (m, 3) of the gap's key ``index`` (1:
        the base key, 2: the next one) seen from the base key: the same for every factor, so
        computed once per gap."""
        if index not in self._keys:
            key = self.gap.relatives[index]
            rotations = screw_motions.rigid_exps(key.screw)[0]
            # the images of t1 and t2 only (all a fit reads), contiguous: the rounds gather their rows
            self._keys[index] = (np.ascontiguousarray(self.gap.key_frames(key.rotvec, rotations, columns=2)),
                                 df.exp_stretch(key.log_stretch))
        return self._keys[index]

    def rounds(self, x, defects, s, frames, stretch, guide, blend, best, rings=REPAIR_RINGS):
        """Regions growing by ``rings`` (:data:`REPAIR_RINGS`) around the ``defects`` (bool (m,)) of ``x``,
        each connected part of a region repaired on its own (:meth:`Region.parts`: their free
        vertices share no triangle, so a field's fit of one does not depend on the others'): in
        each part, the fields of :meth:`imposed_fields` imposed in turn, the first that leaves the
        part defect-free kept (the smallest region that a field repairs wins: a repair changes as
        little as it can), and only the parts still defective grow in the next round. Returns the
        defect-free fit (or None) and the fit with the fewest defects so far ``best`` (count,
        positions). Only the region's vertices move, so only its triangles are checked. A sequence's
        in-between takes parts while their moves add up to at most :meth:`move_limits`' (the
        defect-free one, and for ``best`` the one leaving defects), counted from ``x``. Two poses
        and extrapolations take each region whole, as one part."""
        gap = self.gap
        fields = self.imposed_fields(s, frames, stretch, blend)
        start, force, left = x, defects, defects.copy()  # left: the defects of x, the pose with the parts taken
        limit, partial_limit = self.move_limits(s) or (np.inf, np.inf)
        pieces = gap.topo.triangle_component
        largest = MAX_REPAIR_FRACTION * gap.topo.piece_sizes
        stalled = False  # whether the last round left the fewest defects where they were
        for round_index, grown in enumerate(rings):
            if round_index > STALLED_ROUND and stalled and best[0] >= STALLED_DEFECTS and self.in_sequence(s):
                break  # larger regions do not repair what this size did not improve
            force = self.grow(force, grown)
            if round_index and (np.bincount(pieces[force], minlength=largest.size) > largest).any():
                break  # most of a piece: a replacement, not a repair
            region = gap.region(force)
            # a sequence's in-between by parts; two poses and extrapolations whole (their fallbacks
            # are the blend's, which a part-by-part repair cleaner of defects but farther from it skips)
            row_part, free_part, count = region.parts() if self.in_sequence(s) else region.whole()
            free = region.free
            # per part: the squared move from the start its free vertices already have in x, the
            # field taken (−1: none repairs it yet) and the fewest defects a field leaves there
            # (x's own to begin with) with that field's positions
            had = np.bincount(free_part, np.sum((x[free] - start[free]) ** 2, axis=1), minlength=count)
            own = np.bincount(row_part[left[region.rows]], minlength=count)
            fewest = own.copy()
            taken, partial = np.full(count, -1), np.full(count, -1)
            fits = {}  # field index: its positions on the free vertices
            budget = limit - float(np.sum((x - start) ** 2))  # what the parts taken may add
            for index, (field, whole) in enumerate(fields):
                if round_index >= WHOLE_GEOMETRY_ROUND and not whole:
                    continue
                fitted = gap.local_fit(x, region, *field(region.rows), guide)
                z = fits[index] = fitted[free]
                infinite = ~np.isfinite(z).all(axis=1)
                finite = np.bincount(free_part[infinite], minlength=count) == 0
                if infinite.any():  # checked with x's positions there (the rest is x's, finite)
                    fitted[free[~finite[free_part]]] = x[free[~finite[free_part]]]
                moves = np.bincount(free_part, np.sum((fitted[free] - start[free]) ** 2, axis=1), minlength=count) - had
                counts = np.bincount(row_part[self.defects(fitted, s, frames, stretch, rows=region.rows)],
                                     minlength=count)
                for part in np.flatnonzero((taken < 0) & finite & (counts == 0)):
                    if moves[part] <= budget:  # else the pose would jump away from its neighbours in time
                        taken[part], budget = index, budget - moves[part]
                better = (taken < 0) & finite & (counts < fewest)
                fewest[better], partial[better] = counts[better], index
                if (taken >= 0).all():
                    break
            out = _with_parts(x, free, free_part, taken, fits)
            if (taken >= 0).all():
                return out, best
            # the parts taken, and where no field repairs a part the field that leaves it the fewest
            # defects (else x's own): a candidate for the fit with the fewest
            stalled = True
            waiting = taken < 0
            fewer = _with_parts(out, free, free_part, np.where(waiting, partial, -1), fits)
            for candidate, total in ((fewer, int(fewest[waiting].sum())), (out, int(own[waiting].sum()))):
                if total < best[0] and float(np.sum((candidate - start) ** 2)) <= partial_limit:
                    best, stalled = (total, candidate), False
                    break
            # the parts taken are repaired; the others grow from what they cover
            done = taken[row_part] >= 0
            left[region.rows[done]] = False
            force = np.zeros_like(force)
            force[region.rows[~done]] = True
            x = out
        return None, best

    def in_sequence(self, s: float) -> bool:
        """Whether factor ``s`` is an in-between of a sequence (three keys or more, 0 < s < 1):
        one of a run of poses in time, which a pose must not jump away from."""
        return self.gap.cubic and 0.0 < s < 1.0

    def moved_far(self, z: np.ndarray, x: np.ndarray) -> bool:
        """Whether ``z`` (a repair of the sequence's in-between ``x``, (n, 3)) moved it by more
        than :data:`MAX_REPAIR_MOVE` of the keys' move with each piece's rigid motion taken out
        (and more than a mean edge length), RMS over the vertices."""
        gap = self.gap
        if self._far_move is None:
            moved = gap.topo.apply_motion(gap.base.vertices, *gap.relatives[2].motion)
            self._far_move = max(MAX_REPAIR_MOVE ** 2 * np.mean(np.sum((gap.next.vertices - moved) ** 2, axis=1)),
                                    gap.mean_edge ** 2)
        return float(np.mean(np.sum((z - x) ** 2, axis=1))) > self._far_move

    def move_limits(self, s: float) -> tuple[float, float] | None:
        """The largest sums of squared vertex moves a repair of a sequence's in-between at ``s``
        may make, defect-free (:data:`MAX_REPAIR_MOVE`) and leaving defects
        (:data:`MAX_PARTIAL_REPAIR_MOVE`); None for two poses and extrapolations."""
        gap = self.gap
        if not self.in_sequence(s):
            return None
        if self._move_limits is None:
            n = len(gap.base.vertices)
            step = np.sum((gap.next.vertices - gap.base.vertices) ** 2) / n
            edge = gap.mean_edge ** 2
            self._move_limits = (n * max(MAX_REPAIR_MOVE ** 2 * step, edge), n * MAX_PARTIAL_REPAIR_MOVE ** 2 * edge)
        return self._move_limits


def _corner_joined_parts(local: np.ndarray, count: int) -> tuple[int, np.ndarray]:
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


def _with_parts(x: np.ndarray, free: np.ndarray, free_part: np.ndarray, chosen: np.ndarray, fits: dict) -> np.ndarray:
    """``x`` (n, 3) with the ``free`` vertices of each part ``p`` (``free_part``: each one's part)
    taken from the fit ``fits[chosen[p]]`` (positions on ``free``), where ``chosen[p]`` ≥ 0."""
    out = x.copy()
    for index in np.unique(chosen[chosen >= 0]):
        rows = chosen[free_part] == index
        out[free[rows]] = fits[index][rows]
    return out


class Region:
    """A repair's region: the triangles ``rows`` (r,) of a mask, the vertices ``free`` all of whose
    triangles are in it, and the factorized block ``D_fᵀ D_f + diag(anchor_f)`` of the normal
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
        count, labels = _corner_joined_parts(local, touched)
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
            held[self._held_ends[0]] = x[self._held_ends[1]]
            held[self._held_starts[0]] -= x[self._held_starts[1]]
            self._held = (x, held)
        residual = np.asarray(edges, dtype=float).reshape(-1, 3) - self._held[1]
        rhs = self.free_t @ residual
        if self._pull is None or self._pull[0] is not guide:  # the same guide for every field of a round
            self._pull = (guide, self.anchor[:, None] * guide[self.free])
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
