"""The rounds of a repair (:mod:`core.inbetween_repair`): regions growing by :data:`REPAIR_RINGS` vertex
rings around the defects, each connected part of a region re-fitted with the fields of
:meth:`RepairRounds.imposed_fields` imposed in turn (the interpolated rotations, the linear blend's
local geometry, the keys' spline's, each key's own; paper §8.4), the first that leaves it
defect-free kept; the limits on a region's size (:data:`MAX_REPAIR_FRACTION`), on a stalled round
(:data:`STALLED_ROUND`) and on how far a repair of a sequence's in-between may move it
(:data:`MAX_REPAIR_MOVE`, :data:`MAX_PARTIAL_REPAIR_MOVE`).
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from . import deformation_fields as df
from . import screw_motions


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
#: piece of the mesh): the rounds end at a region that would cover more (docs/inbetween-measurements.md,
#: *Pops*: a ball thrown through a 15k curtain, keys 16 frames apart, 66 → 42–56 ms per in-between,
#: largest frame-to-frame jump 10.6 → 0.52 × the simulation's; the benchmark cloths unchanged).
MAX_REPAIR_FRACTION = 0.5
#: Largest move of a repair of a sequence's in-between, RMS over the vertices, as a fraction of the
#: keys' RMS move across the gap (at least one mean edge length): a larger one jumps away from the
#: neighbouring in-betweens, which do not follow (numbers in docs/inbetween-measurements.md, *Pops*). A
#: predicted in-between's clean repair that moves it by more than this fraction of the keys' move
#: with the pieces' rigid motions taken out gives way to the solve if that is clean
#: (:meth:`RepairRounds.moved_far`; a cape on a walking rig, whose walk is most of the keys' move).
MAX_REPAIR_MOVE = 0.1
#: Largest move of a repair of a sequence's in-between that still leaves defects (kept as the fit
#: with the fewest defects when no repair is defect-free), RMS over the vertices, in mean edge
#: lengths: each in-between chooses its own, so a larger one is a jump away from neighbours that
#: chose another (a sphere lifting a sheet, keys 16 apart: largest frame-to-frame jump 10.6 →
#: 0.80 × the simulation's; numbers in docs/inbetween-measurements.md, *Pops*).
MAX_PARTIAL_REPAIR_MOVE = 1.0
#: Largest move of any vertex by a repair of an extrapolated pose (a factor below 0 or above 1),
#: in mean edge lengths. Beyond the keys the blend (the linear extrapolation) and the keys are no
#: poses of the motion, and a region grown over a turning part takes their turn: a body remeshed
#: and decimated in Blender, its elbow bent 100° (the neck nodded 10–40°), had one crease triangle
#: at ×1.4 / ×1.5 repaired by a region holding the whole forearm, which the blend's field turned
#: 115° / 117° (the linear extrapolation's) instead of 140° / 150°, 5.7–7.5 mean edges off,
#: silently (2.8e-2 / 3.7e-2 of the diagonal off the rig, the fit 2.7e-3 / 3.5e-3); bent 120° and
#: reversed to −0.5, 10.6 mean edges (4.9e-2). The repairs that removed crease defects moved no
#: vertex by more than 0.31 mean edges on the same body (−0.5 … ×2, eight motions).
MAX_EXTRAPOLATED_REPAIR_MOVE = 1.0


def _with_parts(x: np.ndarray, free: np.ndarray, free_part: np.ndarray, chosen: np.ndarray, fits: dict) -> np.ndarray:
    """``x`` (n, 3) with the ``free`` vertices of each part ``p`` (``free_part``: each one's part)
    taken from the fit ``fits[chosen[p]]`` (positions on ``free``), where ``chosen[p]`` ≥ 0."""
    out = x.copy()
    for index in np.unique(chosen[chosen >= 0]):
        rows = chosen[free_part] == index
        out[free[rows]] = fits[index][rows]
    return out


class RepairRounds:
    """Repairs of a pose by fields imposed on regions growing around its defects, part by part,
    and the moves a repair of a sequence's in-between may make; mixed into
    :class:`~core.inbetween_repair.Repair`.

    Of the Repair it is mixed into, it reads its ``_far_move``, ``_keys``, ``_local``, ``_move_limits``, ``gap``
    and calls its ``defects``."""

    def grow(self, triangles: np.ndarray, rings: int) -> np.ndarray:
        """The triangles (bool (m,)) within ``rings`` vertex rings of ``triangles`` (walked on the
        vertex–triangle adjacency: the cost is that of the region, not of the mesh)."""
        topo = self.gap.topo
        out = triangles.copy()
        rows = np.flatnonzero(out)
        used = np.empty(topo.n, dtype=bool)
        for _ in range(rings):
            used[:] = False  # the rows' vertices, ascending, by a mask (a sort of their corners costs more)
            used[topo.triangles[rows]] = True
            out[topo.triangles_around(np.flatnonzero(used))] = True
            rows = np.flatnonzero(out)
        return out

    def imposed_fields(self, s, frames, stretch, blend, nearby=None):
        """The fields imposed around defects, in the order tried: (function of triangle indices
        ``rows`` (r,) returning (frames (3, r, 3), packed stretches (r, 3)), whether it is whole
        geometry of a mesh) — the interpolated rotations, the linear blend's rotations
        (integrable: they come from a mesh), the blend's rotations and stretches, those of the
        keys' per-vertex spline, each key's own local geometry (nearer key first), and last the
        local geometry of ``nearby`` (positions (n, 3) of another pose at ``s``, if given: see
        :func:`core.inbetween_prediction_repairs.repaired_in_passes`)."""
        def interpolated(rows):
            return frames[:, rows], stretch[rows]

        def key_field(index):  # the key's geometry made when a round first imposes it
            def field(rows):
                frames, stretches = self.key_geometry(index)
                return np.take(frames, rows, axis=1), np.take(stretches, rows, axis=0)
            return field

        keys = (1, 2) if s < 0.5 else (2, 1)  # nearer key first
        blend_field, spline_field = self.factor_fields(s, blend)
        fields = [(interpolated, False), (lambda rows: (blend_field(rows)[0], stretch[rows]), False), (blend_field, True),
                  (spline_field, False)] + [(key_field(k), True) for k in keys]
        return fields if nearby is None else fields + [(self.nearby_field(nearby), True)]

    def nearby_field(self, nearby: np.ndarray):
        """The :meth:`mesh_field` of ``nearby`` (positions (n, 3) of another pose): inside
        :meth:`fields_kept`, the one this thread already made of this very array (the repairs again
        of one in-between pass the same pose to each of their passes,
        :func:`core.inbetween_prediction_repairs.repaired_in_passes`), else a new one."""
        # the array is kept with its field: its identity stays its own while the scope lasts
        return self._kept(("nearby", id(nearby)), lambda: (nearby, self.mesh_field(nearby)))[1]

    def mesh_field(self, positions):
        """The local geometry of a mesh with vertices ``positions`` ((n, 3), or a function of no
        arguments returning them, called when first needed; integrable): a function of triangle
        indices ``rows`` (r,) returning (frames (2, r, 3): the images of t1, t2, all a fit reads;
        packed stretches (r, 3)). Each triangle's is computed once, when first asked, so the growing
        regions of the rounds (and the two fields that read the blend's) share it."""
        gap = self.gap
        t = gap.topo.triangles
        m = len(t)
        memo = []  # positions, frames (2, m, 3), stretches (m, 3), which triangles are done

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
                frames_of[:, new] = df.plane_turned_frames(columns, turn)[:2].transpose(0, 2, 1)
                stretches_of[new] = mesh_stretch
                done[new] = True
            return np.take(frames_of, rows, axis=1), np.take(stretches_of, rows, axis=0)
        return field

    def factor_fields(self, s: float, blend: np.ndarray) -> tuple:
        """The :meth:`mesh_field` of the linear ``blend`` (n, 3) at factor ``s`` and that of the keys'
        per-vertex spline there: inside :meth:`fields_kept`, those this thread already made for ``s``
        (every repair of one in-between imposes them on overlapping regions: a prediction's repair,
        the solve from it and its repair, the repairs again: :func:`core.inbetween_prediction_repairs.repaired_in_passes`),
        else new ones."""
        return self._kept(s, lambda: (self.mesh_field(blend), self.mesh_field(lambda: self.factor_spline("world", s))))

    def factor_targets(self, s: float) -> tuple:
        """The gap's targets at in-between factor ``s`` by rows
        (:meth:`core.inbetween_field.InterpolatedField.targets` with ``by_rows``: frames and stretches
        computed on the rows a repair reads, the rigid motions, the guide): inside :meth:`fields_kept`,
        those this thread already made for ``s`` (a prediction's repair and each pass of its repairs
        again read them on overlapping regions), else new ones."""
        return self._kept(("targets", s), lambda: self.gap.targets(s, by_rows=True))

    def factor_spline(self, name: str, s: float) -> np.ndarray:
        """The gap's spline ``name`` evaluated whole at factor ``s`` (read-only): inside
        :meth:`fields_kept`, the values this thread already evaluated there (an in-between's
        prediction, guide, checks, repairs and repairs again read the co-moving and world splines
        at its factor several times: on the 15k curtain at keys 16 apart, 466 evaluations, 322
        distinct), else new ones."""
        def evaluated():
            value = self.gap.splines[name].at(s)
            value.flags.writeable = False  # shared by its readers: none may change it
            return value
        return self._kept(("spline", name, s), evaluated)

    def factor_area_scale(self, s: float) -> np.ndarray:
        """The gap's :meth:`~core.inbetween_field.InterpolatedField.area_scale` at ``s`` (read-only):
        inside :meth:`fields_kept`, the one this thread already made (a prediction's defect check and
        its repairs again both weigh collapses by it)."""
        def made():
            value = self.gap.area_scale(s)
            value.flags.writeable = False
            return value
        return self._kept(("area scale", s), made)

    def _kept(self, key, make):
        """``make()``, or inside :meth:`fields_kept` what it returned for ``key`` in this thread's
        scope, kept there the first time."""
        kept = getattr(self._local, "fields", None)
        if kept is None:
            return make()
        if key not in kept:
            kept[key] = make()
        return kept[key]

    @contextmanager
    def fields_kept(self):
        """A scope (one thread's work on one in-between) in which :meth:`factor_fields`,
        :meth:`factor_targets` and :meth:`nearby_field` keep what they make, let go at its end (at
        100k vertices the two fields of one factor hold ~35 MB, its targets by rows ~17 MB)."""
        outer = getattr(self._local, "fields", None)  # a scope inside another keeps the outer's
        if outer is None:
            self._local.fields = {}
        try:
            yield
        finally:
            if outer is None:
                del self._local.fields

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

    def rounds(self, x, defects, s, frames, stretch, guide, blend, best, rings=REPAIR_RINGS, nearby=None):
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
        and extrapolations take each region whole, as one part. ``nearby``: positions (n, 3) of another
        pose at ``s`` whose local geometry is the last field tried (:meth:`imposed_fields`)."""
        gap = self.gap
        fields = self.imposed_fields(s, frames, stretch, blend, nearby)
        start, force, left = x, defects, defects.copy()  # left: the defects of x, the pose with the parts taken
        limit, partial_limit = self.move_limits(s) or (np.inf, np.inf)
        # an extrapolation's parts are taken only where no vertex moves farther than this (squared)
        reach = (MAX_EXTRAPOLATED_REPAIR_MOVE * gap.mean_edge) ** 2 if not 0.0 <= s <= 1.0 else None
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
            at_start = np.take(start, free, axis=0)  # row gathers by np.take: 4–6 × NumPy's indexing of (n, 3)
            had = np.bincount(free_part, np.sum((np.take(x, free, axis=0) - at_start) ** 2, axis=1), minlength=count)
            own = np.bincount(row_part[left[region.rows]], minlength=count)
            fewest = own.copy()
            taken, partial = np.full(count, -1), np.full(count, -1)
            fits = {}  # field index: its positions on the free vertices
            budget = limit - float(np.sum((x - start) ** 2))  # what the parts taken may add
            for index, (field, whole) in enumerate(fields):
                if round_index >= WHOLE_GEOMETRY_ROUND and not whole:
                    continue
                fitted = gap.local_fit(x, region, *field(region.rows), guide)
                z = fits[index] = np.take(fitted, free, axis=0)
                infinite = ~np.isfinite(z).all(axis=1)
                finite = np.bincount(free_part[infinite], minlength=count) == 0
                if infinite.any():  # checked with x's positions there (the rest is x's, finite)
                    fitted[free[~finite[free_part]]] = x[free[~finite[free_part]]]
                squared = np.sum((np.take(fitted, free, axis=0) - at_start) ** 2, axis=1)
                moves = np.bincount(free_part, squared, minlength=count) - had
                if reach is not None:  # parts with a vertex moved too far are no candidates
                    farthest = np.zeros(count)
                    np.maximum.at(farthest, free_part, squared)
                    finite &= farthest <= reach
                counts = np.bincount(row_part[self.region_defects(fitted, s, frames, stretch, region.rows)],
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
