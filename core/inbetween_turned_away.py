"""Triangles of an in-between facing away from both keys that are no defect: parts turning past a half
turn between the keys (a finger curled by 120° at each of two joints, a tail wagging 300° per gap),
which the interpolated rotations (paper §8.4) turn away from both keys themselves. They
follow their interpolated normal and keep the interpolated metric, in a part that turns a whole
ring of triangles, a piece that turns as the field says, or a far-turning piece edge-on to a key
to the fit's precision; a cloth fold does not (:meth:`TurnedAway._turned_away`).
"""

from __future__ import annotations

import numpy as np

from .geometry import coordinate_cross, coordinate_dot
from .inbetween_fit import MAX_ROTATION_DEVIATION, METRIC_TOLERANCE
from .inbetween_repair_regions import corner_joined_parts


#: Pieces whose rigid fits miss them by less than this share of their size (noise, rounding) may
#: turn away from both keys with their edges off the interpolated metric by the gap's tolerance
#: (:meth:`TurnedAway._turned_away`).
NOISY_TURN_NONRIGIDITY = 3e-2
#: A piece turning far reads as turning with up to this share of its candidates off their
#: interpolated normals by more than :data:`~core.inbetween_fit.MAX_ROTATION_DEVIATION`
#: (:meth:`TurnedAway._turning_pieces`).
DEVIANT_SHARE = 0.05


class TurnedAway:
    """Which of the triangles facing away from both keys turn as the interpolated field says
    (not flipped); mixed into :class:`~core.inbetween_repair.Repair`.

    Of the Repair it is mixed into, it reads its ``gap``."""

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
        says are kept, to the gap's tolerance, but for those of a far-turning piece that stray past
        facing along their interpolated normal (:meth:`_turning_pieces`), and those of a piece
        turning far that are edge-on to a key to the fit's precision (:meth:`_edge_on`)."""
        triangles = candidates if isinstance(rows, slice) else np.asarray(rows)[candidates]
        columns = frames[:, triangles]
        normal = coordinate_cross(columns[0].T, columns[1].T)  # (3 coordinates, r) of the interpolated R_T t1, R_T t2
        base, nxt = (np.take(key.normal_rows, triangles, axis=1) for key in (self.gap.base, self.gap.next))
        cross = np.take(cross, candidates, axis=1)  # the candidates' normals, read below
        following = coordinate_dot(cross, normal)
        away = (coordinate_dot(normal, base) < 0) & (coordinate_dot(normal, nxt) < 0)
        away &= following > -slack[candidates]  # ... that follow it
        # a whole mesh's check first keeps the pieces that turn whole; the rest, one by one (below)
        whole = isinstance(rows, slice)
        turning = self._turning_pieces(cross, normal, following, base, nxt, columns, sides,
                                       candidates) if whole else None
        if not whole:  # what a region's check cannot see (DefectChecks.region_defects asks)
            self._local.whole_may_pass = self._whole_may_pass(cross, following, normal, base, nxt,
                                                              triangles)
        kept_whole = None
        if turning is not None:
            kept_whole = candidates[turning]
            away &= ~turning
        # in a fit checked whole, triangles of a far-turning piece at edge-on with a key, to the
        # fit's precision (a repair region's fields are not fitted to it)
        edge_on = self._edge_on(cross, following, base, nxt, triangles) if whole else None
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
        on_metric = candidates[deviation < tolerance]
        kept = self._carrying_a_vertex(on_metric, rows, kept_whole)
        if not whole and kept.size < on_metric.size:  # the whole mesh may complete the ring they turn
            self._local.whole_may_pass = True
        return kept if kept_whole is None else np.sort(np.concatenate([kept_whole, kept]))

    def _whole_may_pass(self, cross, following, normal, base, nxt, triangles) -> bool:
        """Whether a check of the whole mesh could pass candidates that a region's check does not
        (besides those on the metric whose ring the region cuts, :meth:`_turned_away`): the
        region's candidates are ``triangles`` (r,), with normals ``cross`` (3, r), interpolated
        normals ``normal`` (3, r), the products of the two ``following`` (r,) and the keys' unit
        normals ``base`` / ``nxt`` (3, r). The whole check passes only candidates facing along their
        interpolated normal, in a piece turning far (``gap.turning`` or, for two poses,
        :meth:`_far_turning`: :meth:`_edge_on`, :meth:`_turning_pieces`) or in a piece each of
        whose candidates is within ``arctan δ`` of its interpolated normal, that one within the same
        angle of facing away from both keys (a piece turning whole: :meth:`_whole_pieces`, the test
        :meth:`_turning_pieces` makes, here with no piece taken as turning far)."""
        gap = self.gap
        pieces = gap.topo.triangle_component[triangles]
        along = following > 0.0
        if not along.any():
            return False
        far = gap.turning if gap.turning is not None else self._far_turning()
        if (along & np.asarray(far)[pieces]).any():
            return True
        # a piece turning whole has a candidate whose interpolated normal faces away from both keys
        # to within the angle (none far): where none does, none turns whole (the common case, a fold)
        if not _facing_away(_unit(normal), base, nxt, np.sin(self._turn_angle())).any():
            return False
        whole_pieces = self._whole_pieces(cross, normal, following, base, nxt, pieces)
        return bool(whole_pieces(np.zeros(len(gap.topo.piece_sizes), dtype=bool))[0].any())

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
        labels = corner_joined_parts(local.ravel(), vertices.size)[1]
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
        interpolated frames) turn as the interpolated field says in a piece that does so, or None
        if no piece does: a piece is turning where each candidate's normal is within
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
        In a piece turning far, up to :data:`DEVIANT_SHARE` of the candidates may stray farther
        (the fit's global steps carry a triangle past the local steps' limit where its neighbours
        pull it, and a fold elsewhere in the piece faces against its field): those still facing
        along their interpolated normal are kept with the rest, the others are judged one by one
        (a limb re-meshed irregularly, skinned 100° + 150°, its tip facing away from both poses
        half-way: of its ~1,300 candidates 1–5 on the crushed inner side of the second ramp's end
        lie 46–69° off their interpolated normals, and on one mesh of eight two at the ramp's start
        are folded 111–124° against them and against the rig; held to every candidate, the fit,
        0.05 × the blend's error, was read as ~850 flipped triangles and the fallback returned a fit
        near the blend, 1.00 ×, ~2,300 triangles facing against the rig, with a warning).
        A closed tube (a finger) curled 120° at each of two knuckles bends its cross-sections, so
        its fit keeps the metric to 0.2–0.7 % where it turns away half-way, not to
        :data:`~core.inbetween_fit.METRIC_TOLERANCE`, and triangles edge-on to a key there face
        away by 1e-3 of their length where their interpolated normal does not: read as flipped,
        a repair replaces the curl by a pose 11–15 % of the diagonal off it. A cloth fold has
        other flipped triangles in its piece (compressed, or facing against the interpolated
        normal): on six benchmark cloths no piece was turning."""
        gap = self.gap
        tolerance = max(METRIC_TOLERANCE, gap.tolerance)
        pieces = gap.topo.triangle_component[candidates]
        count = len(gap.topo.piece_sizes)
        whole_pieces = self._whole_pieces(cross, normal, following, base, nxt, pieces)
        if gap.turning is not None:
            far = gap.turning[:count]
        elif whole_pieces(np.ones(count, dtype=bool))[0].any():
            # two poses read their far-turning parts only where a piece would pass as one if it
            # turned far (a cloth fold has candidates facing against their interpolated normals)
            far = self._far_turning()
        else:
            return None
        turning, following_field = whole_pieces(far)
        if not turning.any():
            return None
        inside = turning[pieces] & following_field
        per_piece = np.bincount(pieces[inside], minlength=count)
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
        return turning[pieces] & following_field if turning.any() else None

    def _whole_pieces(self, cross, normal, following, base, nxt, pieces):
        """The test of a piece turning as the interpolated field says, on candidates (r,) facing away
        from both keys (``cross`` their normals, ``normal`` their interpolated normals (3, r),
        ``following`` the products of the two, ``base`` / ``nxt`` the keys' unit normals (3, r),
        ``pieces`` their pieces (r,)), as the function of the pieces taken as turning far (``far``,
        bool (C,)) that :meth:`_turning_pieces` and :meth:`_whole_may_pass` apply: it gives the
        pieces (C,) each of whose candidates has its normal within the piece's angle (``arctan δ``,
        δ the gap's tolerance; :data:`~core.inbetween_fit.MAX_ROTATION_DEVIATION` where far) of its
        interpolated normal, and that one within the same angle of facing away from both keys, of
        the pieces turning far all but :data:`DEVIANT_SHARE` of them; and the candidates (r,) that
        turn as the field says: those, and in a piece turning far those beyond the angle facing
        along their interpolated normal still (the others are judged one by one)."""
        gap = self.gap
        angle = self._turn_angle()
        count = len(gap.topo.piece_sizes)
        unit = _unit(normal)
        lengths = np.sqrt(coordinate_dot(cross, cross) * coordinate_dot(normal, normal))
        per_piece = np.bincount(pieces, minlength=count)

        def whole_pieces(far: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            far_pieces = far[pieces]
            limit = np.where(far_pieces, np.cos(MAX_ROTATION_DEVIATION), np.cos(angle))
            sine = np.where(far_pieces, np.sin(MAX_ROTATION_DEVIATION), np.sin(angle))
            facing_away = _facing_away(unit, base, nxt, sine)
            near = (following >= limit * lengths) & facing_away
            near_count = np.bincount(pieces[near], minlength=count)
            allowed = np.where(far, np.floor(DEVIANT_SHARE * per_piece), 0)
            whole = (per_piece - near_count <= allowed) & (near_count > 0)
            return whole, near | (far_pieces & facing_away & (following > 0.0))

        return whole_pieces

    def _turn_angle(self) -> float:
        """The angle ``arctan δ`` (δ the gap's tolerance, at least
        :data:`~core.inbetween_fit.METRIC_TOLERANCE`) by which a side whose end is a relative δ off
        its target turns: how far a piece's normals may stray from their interpolated ones and
        those from facing away from both keys for the piece to turn whole (:meth:`_whole_pieces`)."""
        return np.arctan(max(METRIC_TOLERANCE, self.gap.tolerance))

    def _far_turning(self) -> np.ndarray:
        """Per piece (bool (C,)), whether a part of it turns far from the rest between the keys as
        a sequence reads it (:meth:`core.inbetween_whole_rotations.WholeRotations.turning`), for a gap of two poses,
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
                relative.let_go_whole_vectors()  # kept for a gap's preparation alone
                known = (reading[0] | reading[2])[:len(known)]  # past a half turn, without or with a crease
            self._far = known
        return known


def _unit(normal: np.ndarray) -> np.ndarray:
    """The unit vectors (3, r) of ``normal`` (3, r), by coordinate."""
    return normal / np.sqrt(coordinate_dot(normal, normal))


def _facing_away(unit: np.ndarray, base: np.ndarray, nxt: np.ndarray, sine) -> np.ndarray:
    """Whether each ``unit`` normal (3, r) lies within the angle whose sine is ``sine`` (a number,
    or (r,)) of facing away from both keys' unit normals ``base`` and ``nxt`` (3, r) (bool (r,))."""
    return (coordinate_dot(unit, base) < sine) & (coordinate_dot(unit, nxt) < sine)
