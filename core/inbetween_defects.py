"""The defects of an in-between a repair removes (:mod:`core.inbetween_repair`): flipped triangles, whose
normal opposes both keys' (or, beyond the keys, the interpolated normal) by more than
:data:`FLIP_COSINE`, and collapsed ones, whose area dropped below :data:`COLLAPSE_RATIO` of the
interpolated area; every triangle of a pose that is not finite. A triangle less high than the fits'
floor (:data:`core.inbetween_fit.UNTOLD_HEIGHT`) in both keys and than the noise of its rigid
piece's keys in either is neither: the keys do not tell which way it faces
(:mod:`core.untold_triangles`). Positions ``x`` (n, 3), the triangles of the gap's topology (m, 3);
in-betweens of paper §8.4.
"""

from __future__ import annotations

import weakref

import numpy as np

from .geometry import coordinate_cross, coordinate_dot


#: A triangle whose area dropped below this fraction of its interpolated target area is collapsed.
COLLAPSE_RATIO = 1e-3
#: A triangle is flipped where its normal opposes the keys' (or the interpolated) normal by more
#: than this cosine: a piece half-way through an exact half turn has normals perpendicular to both
#: keys' in exact arithmetic, and rounding (~1e-16) made some of them look flipped, so a repair
#: bent a rigidly turning lid (edge lengths off by 56 %). Far below any fold one could see.
FLIP_COSINE = 1e-9
#: A count of an in-between (:meth:`DefectChecks.counted`) after another at its factor checks anew
#: only the triangles at the vertices the pose moved since, up to this share of the vertices and of
#: the triangles (the whole check beyond it). A repair moves a region, and the in-between's next
#: count is of that repair: on the 15k curtain at keys 16 apart, 46 of its 84 counts follow one at
#: the same factor, 30 of them with at most 1,202 of its 15,400 vertices moved, 8 with none. The
#: whole check of its 30,302 triangles took 1.5–2.0 ms, the check anew of 0.6 / 2.3 / 5.5 / 10.7 /
#: 21 % of them 0.38 / 0.50 / 0.96 / 1.31 / 2.03 ms (one core, a shared machine): about even at 15 %.
RECHECKED_SHARE = 0.15


class DefectChecks:
    """The flipped and collapsed triangles of a pose of one gap, and what is wrong with it in
    words; mixed into :class:`~core.inbetween_repair.Repair`.

    Of the Repair it is mixed into, it reads its ``_local``, ``gap`` and calls its ``_turned_away``,
    ``factor_targets`` and ``_kept``."""

    def flipped(self, cross: np.ndarray, length: np.ndarray, s: float, frames: np.ndarray | None,
                rows=slice(None), sides=None, normals=None, against=None) -> np.ndarray:
        """Triangles (bool (r,)) among ``rows`` whose normal ``cross`` (3 coordinates, r; its
        lengths ``length`` (r,)) opposes both keys' unit normals (in-betweens, 0 ≤ s ≤ 1) or, for
        extrapolations, the interpolated normal ``R_T(s) n_T`` (``frames``: (3, m, 3) of every
        triangle, ``frames[2]`` the normals; without them: the nearer key's normal), by more than
        :data:`FLIP_COSINE` (``normals``: the keys' normals on ``rows``, if the caller has them;
        ``against``: the triangles whose normal opposes both keys', if the caller has them)."""
        gap = self.gap
        slack = -FLIP_COSINE * length
        if 0.0 <= s <= 1.0:
            if against is None:
                base, nxt = normals or (gap.base.normal_rows[:, rows], gap.next.normal_rows[:, rows])
                flipped = (coordinate_dot(cross, base) < slack) & (coordinate_dot(cross, nxt) < slack)
            else:
                flipped = against.copy()
            if frames is not None and sides is not None and sides[2] is not None and flipped.any():
                flipped[self._turned_away(cross, slack, frames, rows, np.flatnonzero(flipped), sides)] = False
            return flipped
        if frames is not None:
            return coordinate_dot(cross, frames[2][rows].T) < slack
        return coordinate_dot(cross, (gap.base if s < 0.5 else gap.next).normal_rows[:, rows]) < slack

    def defects(self, x: np.ndarray, s: float, frames, stretch, rows=None, scale=None) -> np.ndarray:
        """Flipped or collapsed triangles of ``x`` (bool (m,), or (r,) for the triangle indices
        ``rows``); all of them if ``x`` is not finite (with ``rows``: if a corner of theirs is not;
        the rest of the pose is not read, as the check of a repair region's fit reads the region
        alone). The interpolated areas come from ``stretch`` (packed (m, 3)) or, if given instead,
        their ratios to the base's ``scale`` (m,; :meth:`core.inbetween_field.InterpolatedField.area_scale`)."""
        if rows is None:
            if not np.isfinite(x).all():
                return np.ones(len(self.gap.topo.triangles), dtype=bool)
            e1, e2, cross, length, against, collapsed = self._whole_check(x, s, stretch, scale)
            rows, normals = slice(None), None
        else:
            corners, normals, target = self._rows_of(rows, stretch, scale)
            sides = _corner_sides(x, corners)
            if sides is None:
                return np.ones(len(rows), dtype=bool)
            e1, e2, cross, length = sides
            against, collapsed = None, _collapsed(length, target)
        defects = self.flipped(cross, length, s, frames, rows, (e1, e2, stretch), normals, against) | collapsed
        untold = self.gap.untold[2]
        if untold.any():  # a triangle whose facing neither key tells is neither (core.untold_triangles)
            defects &= ~untold[rows]
        return defects

    def counted(self, x: np.ndarray, s: float, scale: np.ndarray) -> np.ndarray:
        """The flipped or collapsed triangles (bool (m,)) of an in-between ``x`` (n, 3) at factor
        ``s`` (0 < s < 1; ``scale``: the gap's ``area_scale(s)``) as its outcome, its warning and its
        untangling count them: with the interpolated frames, so that triangles the interpolated
        rotations turn away from both keys are none (:mod:`core.inbetween_turned_away`). Checked
        first without them (the same triangles and more: the frames only take turned-away ones
        out), and with them, on the gap's targets by rows at ``s``, only where that finds any: the
        second check takes the first one's sides, normals, flips against both keys and collapses
        (:meth:`_whole_check`) and judges only those flips against the frames. Inside
        :meth:`~core.inbetween_repair_rounds.RepairRounds.fields_kept`, the first check of a count
        after another at ``s`` takes that one's entries of the triangles the pose did not move
        (:meth:`_rechecked`)."""
        self._local.sides = None  # both checks read the pose's sides and test them against the keys once
        try:
            plain = self.defects(x, s, None, None, scale=scale)
            if not plain.any():
                return plain
            frames, stretch = self.factor_targets(s)[:2]
            return self.defects(x, s, frames, stretch, scale=scale)
        finally:
            self._local.sides = False  # let go (a count inside another leaves the outer one to take its own)

    def _whole_check(self, x: np.ndarray, s: float, stretch, scale) -> tuple:
        """Of every triangle of ``x`` (n, 3): the sides from the first corner (two (3, m)), the normals
        ``cross`` (3, m) and their lengths (m,), which normals oppose both keys' (bool (m,); None
        beyond the keys, where the keys' normals do not decide) and which triangles collapsed
        (bool (m,); the interpolated areas from ``stretch`` or ``scale`` as :meth:`defects` takes
        them): none of it depends on the interpolated frames, so inside :meth:`counted`, which
        checks one pose without and with them at one ``s`` and ``scale``, the ones it made for ``x``
        first (per thread: a gap's in-betweens are counted concurrently), and from those of the last
        count at ``s`` in the in-between's scope where it moved few vertices since
        (:meth:`_rechecked`; that count's pose and what it made are kept in the scope, ~10 values a
        triangle, let go at its end)."""
        kept = getattr(self._local, "sides", False)
        if kept and kept[0] is x and kept[1] == s and kept[2] is scale:
            return kept[3]
        counting = kept is not False and scale is not None  # inside counted: the areas from ``scale``
        last = self._kept(("counted", s), list) if counting else []  # the last count's at s, in scope
        made = self._rechecked(x, s, *last) if last and last[0][1] is scale else None
        if made is None:
            e1, e2 = self.gap.topo.triangle_sides(x)  # by coordinate (3, m)
            cross = coordinate_cross(e1, e2)
            length = np.sqrt(coordinate_dot(cross, cross))
            against = self.flipped(cross, length, s, None) if 0.0 <= s <= 1.0 else None
            collapsed = _collapsed(length, self.gap.base.areas * self._area_scale(stretch, scale, slice(None)))
            made = e1, e2, cross, length, against, collapsed
        if counting:  # the same in both checks of this count, and read by the next count at s
            self._local.sides = (x, s, scale, made)
            last[:] = [(x.copy(), scale), made]
        return made

    def _rechecked(self, x: np.ndarray, s: float, checked: tuple, before: tuple) -> tuple | None:
        """What :meth:`_whole_check` makes of ``x`` (n, 3, finite) at factor ``s``, from what it made
        (``before``, arrays only the last count's scope holds) of the pose the last count at ``s``
        checked with the same area scale (``checked``: a copy of that pose, the scale): its
        entries of the triangles at vertices ``x`` moved made anew in place (each triangle's own
        corners alone decide them: the whole check's values, a zero side's sign aside, which no
        comparison reads), the others as they were; None where more than :data:`RECHECKED_SHARE` of the vertices moved or of the
        triangles are at moved vertices (checked whole: the cheaper)."""
        topo = self.gap.topo
        previous, scale = checked
        changed = x != previous  # the pose's vertices that moved, without a reduction over rows of three
        moved = np.flatnonzero(changed[:, 0] | changed[:, 1] | changed[:, 2])
        if not moved.size:
            return before
        if moved.size > RECHECKED_SHARE * topo.n:  # their triangles are as many or more: not looked up
            return None
        rows = np.zeros(len(topo.triangles), dtype=bool)
        rows[topo.triangles_around(moved)] = True
        rows = np.flatnonzero(rows)
        if rows.size > RECHECKED_SHARE * len(topo.triangles):
            return None
        e1, e2, cross, length, against, collapsed = before  # in place: the count that made them is over
        e1[:, rows], e2[:, rows], cross[:, rows], length[rows] = _corner_sides(x, topo.triangles[rows].T)
        if against is not None:
            against[rows] = self.flipped(cross[:, rows], length[rows], s, None, rows)
        collapsed[rows] = _collapsed(length[rows], self.gap.base.areas[rows] * self._area_scale(None, scale, rows))
        return e1, e2, cross, length, against, collapsed

    def region_defects(self, x: np.ndarray, s: float, frames, stretch, rows: np.ndarray, scale=None) -> np.ndarray:
        """The flipped or collapsed triangles (bool (r,)) among ``rows`` (r,) of a whole pose ``x``
        (n, 3) as the check of the whole pose counts them (:meth:`defects` without ``rows``): a
        region's own check cannot tell a piece that turns away from both keys as the interpolated
        rotations turn it (:meth:`~core.inbetween_turned_away.TurnedAway._turning_pieces`,
        ``_edge_on``), which the whole check passes. The region's check first (the same
        triangles and more); the whole pose's only where that check met a triangle the whole one
        could pass (:meth:`~core.inbetween_turned_away.TurnedAway._whole_may_pass`, or one on the
        metric whose ring the region cuts). A finger curled 120° at
        each of two joints, fitted half-way (its tip facing away from both keys, no defect):
        the check of a region around its tip alone reads 8–29 of its triangles as flipped, and a
        repair of a fold beside the tip checked so takes fields that turn some of them back toward
        the keys."""
        self._local.whole_may_pass = False  # set by the region's check (TurnedAway._turned_away)
        found = self.defects(x, s, frames, stretch, rows=rows, scale=scale)
        if not found.any() or not self._local.whole_may_pass:
            return found
        return found & self.defects(x, s, frames, stretch, scale=scale)[rows]

    @staticmethod
    def _area_scale(stretch, scale, rows) -> np.ndarray:
        """The interpolated areas' ratios to the base's on ``rows``: ``scale`` there if given, else
        the determinants of the packed ``stretch`` (m, 3)."""
        if scale is not None:
            return scale[rows]
        st = stretch[rows]
        return st[:, 0] * st[:, 2] - st[:, 1] ** 2

    def _rows_of(self, rows: np.ndarray, stretch, scale) -> tuple:
        """The corners (3, r: each corner's vertices contiguous), the keys' normals (two (3, r)) and
        the collapse check's target areas (r,: the base's times :meth:`_area_scale`) of the
        triangles ``rows``: a repair round checks each field's fit on the same region with the same
        stretches, so the last rows asked (per thread: a gap's in-betweens are repaired
        concurrently) keep them, the target areas while the same ``stretch`` and ``scale`` are
        given. ``stretch`` and ``scale`` are held by weak reference: a gap's stretches by rows
        (:class:`core.inbetween_field._ByRows`) compute from the gap, which holds this repair, and a
        strong reference here would keep a gap the sequence's cache let go (~150–200 MB at 100k
        vertices) alive until a full garbage collection."""
        cached = getattr(self._local, "rows", None)
        if cached is None or cached[0] is not rows:
            gap = self.gap
            cached = self._local.rows = [rows, np.ascontiguousarray(gap.topo.triangles[rows].T),
                                         tuple(np.take(key.normal_rows, rows, axis=1) for key in (gap.base, gap.next)),
                                         gap.base.areas[rows], None]
        if cached[4] is None or not (_held(cached[4][0], stretch) and _held(cached[4][1], scale)):
            cached[4] = (_weak(stretch), _weak(scale), cached[3] * self._area_scale(stretch, scale, rows))
        return cached[1], cached[2], cached[4][2]

    def against_the_field(self, x: np.ndarray, frames: np.ndarray) -> tuple[str | None, tuple[int, int]]:
        """(What to say, or None, and how many triangles: those where the keys face the same way,
        and all) where triangles of an in-between ``x`` (n, 3) of two poses face against
        their interpolated normal ``R_T t1 × R_T t2`` (``frames``: (k ≥ 2, m, 3) of every triangle)
        and against one key's normal (not both: those are :meth:`flipped`), each by more than
        :data:`FLIP_COSINE`; None where none does. The check against both keys passes such a
        triangle, turned over while facing the other key. Where the keys' normals face the same
        way, the fit turned it over because the interpolated metric does not fit between parts the
        fit holds (a head nodding on a still neck by ramped skin weights, whose stretch grows with
        the square of the turn where the metric's is linear: 1–30 triangles of the ramp facing
        90–147° from the rig, docs/inbetween-measurements.md, *Heads nodding on a still neck*); where they are
        more than a right angle apart, the triangle turns over between the keys, and two keys do
        not tell which way (a skinned jaw's crease, right to 2°, or the same head nodding 140°,
        8 of its triangles 96–139° from the rig). Said, not repaired: the keys cannot tell."""
        gap = self.gap
        cross = coordinate_cross(*gap.topo.triangle_sides(x))
        normal = coordinate_cross(frames[0].T, frames[1].T)
        length = np.sqrt(coordinate_dot(cross, cross))
        slack = -FLIP_COSINE * length
        against = coordinate_dot(cross, normal) < slack * np.sqrt(coordinate_dot(normal, normal))
        against &= (coordinate_dot(cross, gap.base.normal_rows) < slack) != \
            (coordinate_dot(cross, gap.next.normal_rows) < slack)
        against &= ~gap.untold[2]  # whose facing neither key tells (core.untold_triangles)
        if not against.any():
            return None, (0, 0)
        over = coordinate_dot(gap.base.normal_rows, gap.next.normal_rows) < 0  # turned over between the keys
        said = []
        # neither kind is flipped (against both poses: :meth:`flipped`), and neither message says so
        for rows, what in ((against & ~over, "face against their interpolated rotation and one pose in the in-between, "
                            "where both poses face them the same way: turned past a right angle from where their "
                            "rotation carries them, toward the other pose, not flipped against both (where the "
                            "surface stretches between a part that stays and one that turns, and two poses do not "
                            "tell its edge lengths in between); add a key between the poses"),
                           (against & over, "turn over between the poses, and two poses do not tell which way they "
                            "go over (where the surface folds over between the poses: a crease, a fold in the "
                            "cloth, a bend turned far): the in-between may turn them the other way; add a key "
                            "between the poses (they face against their interpolated rotation and one pose, not "
                            "flipped against both)")):
            if rows.any():
                first = int(np.argmax(rows))
                first = first if gap.topo.caller_triangles is None else int(gap.topo.caller_triangles[first])
                said.append(f"{int(rows.sum())} triangle(s) (e.g. triangle {first}) {what}")
        return "; ".join(said), (int(np.count_nonzero(against & ~over)), int(np.count_nonzero(against)))

    def problem(self, x, s, frames, stretch, defects=None) -> str | None:
        """What is wrong with ``x`` in words, or None (``defects``: those of ``x``, if known)."""
        if not np.isfinite(x).all():
            return "the fit came out with non-finite coordinates (a numerical failure)"
        count = int((self.defects(x, s, frames, stretch) if defects is None else defects).sum())
        return f"{count} triangle(s) flipped or collapsed" if count else None


def _corner_sides(x: np.ndarray, corners: np.ndarray) -> tuple | None:
    """The sides from the first corner (two (3, r)), the normals (3, r) and their lengths (r,) of
    the triangles whose corners are ``corners`` (3, r) in positions ``x`` (n, 3): the values of
    :meth:`core.inbetween_topology.Topology.triangle_sides` and the whole check's products on those
    triangles; None where a corner is not finite."""
    p = np.take(x, corners, axis=0)  # (3 corners, r, 3) in one gather
    if not np.isfinite(p).all():
        return None
    e1, e2 = (p[1] - p[0]).T, (p[2] - p[0]).T
    cross = coordinate_cross(e1, e2)
    return e1, e2, cross, np.sqrt(coordinate_dot(cross, cross))


def _collapsed(length: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Triangles (bool (r,)) whose area (half their normals' ``length`` (r,)) dropped below
    :data:`COLLAPSE_RATIO` of their interpolated ``target`` area (r,)."""
    return 0.5 * length < COLLAPSE_RATIO * target


def _weak(value):
    """A weak reference to ``value`` (None stays None)."""
    return None if value is None else weakref.ref(value)


def _held(reference, value) -> bool:
    """Whether the weak ``reference`` (:func:`_weak`) is to ``value`` itself, still alive."""
    if reference is None or value is None:
        return reference is None and value is None
    return reference() is value
