"""A last local untangling of a sequence's in-between that keeps flipped or collapsed triangles
after its repairs (:mod:`core.inbetween_repair`, :func:`core.inbetween_prediction_repairs.repaired_in_passes`;
in-betweens of paper §8.4).

The repairs impose a field (the interpolated rotations, the blend's, the spline's or a key's
local geometry) on a region with its boundary held, in one linear solve: where the in-between is
folded over a few triangles and the region's boundary already sits where the fold needs it, every
field's solve folds them again (on the benchmark cloths the kept flips were none of them folded by
the interpolated rotations, and the region fits of every field at 1–8 rings left them folded while
moving the pose by 1e-6–1e-2 of the move a repair may make; docs/design-decisions.md, *Flipped
triangles kept by the repairs untangled*). :func:`untangle` moves the free vertices of a small
region as little as keeps the pose's own edges (least squares) while every triangle of the region
faces a given side: a quadratic penalty on each triangle's signed area toward its side, whose
weight grows (:data:`UNTANGLE_WEIGHTS`) until every triangle faces its side (Gauss–Newton steps,
each a dense solve of the part's few hundred unknowns at most; written here because SciPy's
L-BFGS took 4–440 ms an in-between on the same problems). :func:`untangled` splits the defects into places
(tangles that share no vertex), picks each one's region and sides, and keeps each place's result
where it leaves that place free of defects; the places it cannot clean, or too large for its
bounded work (:data:`UNTANGLE_FREE_VERTICES`, :data:`UNTANGLE_WORK`), are left as they were and said.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy import linalg

from .geometry import coordinate_cross, coordinate_dot
from .inbetween_defects import COLLAPSE_RATIO
from .inbetween_repair import Outcome
from .inbetween_repair_regions import corner_joined_parts
from .inbetween_threads import per_factor


#: Vertex rings around the defects whose triangles the untangling re-places, tried in turn (the next
#: where the smaller region keeps defects): one ring untangled each of the 18 in-betweens of the
#: benchmark's curtain, lifted sheet, banner, two sheets and leather flag that kept flips; the
#: second is there for a fold one ring does not hold (with L-BFGS in place of the Gauss–Newton
#: steps the curtain's 9 at g = 16, s = 7/16 needed it).
UNTANGLE_RINGS = (1, 2)
#: Weights of the penalty on a triangle facing short of its side, relative to the edges' least
#: squares (both in squared lengths: the shortfall is divided by the region's mean edge), tried in
#: turn until every triangle faces its side. The steps are solved directly, so a high weight costs
#: no conditioning; the 18 benchmark in-betweens that kept flips (with a sparse step matrix):
#: (1e2, 1e3, 1e4, 1e5) 0.76 s, (1e3, 1e5) 0.41 s, (1e5,) 0.31 s, (1e4, 1e6) 0.26 s, all clean.
UNTANGLE_WEIGHTS = (1e4, 1e6)
#: A defective triangle is to face its side with at least this fraction of twice its interpolated
#: area (its normal's length in the in-between the metric asks for): well clear of the collapse
#: check's :data:`~core.inbetween_defects.COLLAPSE_RATIO`.
UNTANGLE_MARGIN = 0.05
#: A place whose untangling faces every side but leaves a triangle collapsed (one beside the defects,
#: whose margin is half its own facing, squeezed below the collapse check) is tried once more with
#: every margin raised so that a triangle facing its side by half its margin keeps at least this many
#: times the area the collapse check asks (:data:`~core.inbetween_defects.COLLAPSE_RATIO` of its
#: interpolated area). Only there: the floor on every try moved in-betweens of the benchmark's
#: curtain and lifted sheet at g = 16 that the untangling already cleaned (up to 6e-3).
UNTANGLE_COLLAPSE_FLOOR = 2.0
#: Gauss–Newton steps at each weight at most.
UNTANGLE_ITERATIONS = 20
#: A place (tangle) whose region has more free vertices than this is not untangled: a fold that wide
#: is no local tangle, and the Gauss–Newton matrix is dense (3 × this many unknowns at most; the
#: benchmark's places have 3–16).
UNTANGLE_FREE_VERTICES = 200
#: The work one in-between's untangling may do, all its places' tries counted (a place tried at one
#: ring and then two counts both), in Gauss–Newton steps of a system of :data:`UNTANGLE_FREE_VERTICES`
#: free vertices (what a try costs, :func:`untangle_work`), for a mesh of up to
#: :data:`UNTANGLE_WORK_VERTICES` vertices and in proportion to its size beyond: a try is made only
#: where its most steps fit in what is left, so the places beyond it are left, and said. Ten tries at
#: that size that do not open (each all ``len(UNTANGLE_WEIGHTS) × UNTANGLE_ITERATIONS`` steps) take
#: about 3 s; 1,936 one-vertex folds on a 50k sheet take 1.5 s and about half of it, where a count of
#: free vertices alone (the solves' sizes, not their steps) would leave three quarters of them.
UNTANGLE_WORK = 400
#: The mesh size (vertices) :data:`UNTANGLE_WORK` is for: larger meshes may do that work per as many
#: vertices, as an in-between's own cost grows with the mesh.
UNTANGLE_WORK_VERTICES = 50_000
#: What a Gauss–Newton step of :func:`untangle` costs besides its dense algebra, in squared free
#: vertices (0.45 ms ÷ 1.8e-4 ms): one thread, 367 tries of 4–200 free vertices (1–40 steps each)
#: took 1.1 ms + 0.45 ms a step + 1.8e-4 ms × (free vertices)² a step, a step of 200 free vertices
#: 7.8 ms (a least-squares fit of the tries' CPU times; docs/design-decisions.md, *the untangling's
#: work counted by what it costs*).
UNTANGLE_STEP_OVERHEAD = 2500


def untangle(vertices: np.ndarray, triangles: np.ndarray, free: np.ndarray, sides: np.ndarray,
             margins: np.ndarray, weights=UNTANGLE_WEIGHTS, steps: list | None = None) -> tuple[np.ndarray, bool]:
    """``vertices`` (n, 3) with the ``free`` ones (f,: vertex indices, each of whose triangles is
    among ``triangles`` (r, 3)) moved so that every triangle ``t`` faces its side: its normal
    ``n_t = (p1 − p0) × (p2 − p0)`` (twice its area, along its unit normal) has ``n_t · sides[t] ≥
    margins[t] / 2`` (``sides`` (r, 3) unit vectors, ``margins`` (r,) ≥ 0), changing the triangles'
    edges little: Gauss–Newton steps (with a backtracking line search) on ``½ Σ |e − e⁰|² + ½ μ Σ
    (max(0, margins − n · sides) / ℓ)²`` over the ``triangles``' corner edges ``e`` (``e⁰``: those of
    ``vertices``; ``ℓ``: their mean length), from ``vertices``, for ``μ`` in ``weights`` in turn,
    stopped at the first iterate where every triangle faces its side. Returns (positions (n, 3),
    whether every triangle does); the Gauss–Newton steps it solved are appended to ``steps`` if
    given. The other vertices stay where they are."""
    vertices = np.asarray(vertices, dtype=float)
    out = vertices.copy()
    if not len(free) or not len(triangles):
        return out, False
    # the region's vertices numbered locally; edge 3t + c runs from corner c to corner c + 1
    touched, local = np.unique(np.asarray(triangles), return_inverse=True)
    local = local.reshape(-1, 3)
    is_free = np.isin(touched, free)
    count, r = touched.size, len(local)
    index = np.full(count, -1)
    index[is_free] = np.arange(np.count_nonzero(is_free))
    start, end = local.ravel(), local[:, [1, 2, 0]].ravel()
    edges = sp.csr_matrix((np.r_[-np.ones(start.size), np.ones(end.size)],
                           (np.r_[np.arange(start.size), np.arange(end.size)], np.r_[start, end])),
                          shape=(start.size, count))
    on_free = edges[:, is_free]
    unknowns = 3 * np.count_nonzero(is_free)
    # the edges' normal matrix on the free vertices' coordinates (vertex-major: unknown 3 i + d),
    # dense: a region has tens to a few hundred free vertices
    laplacian = np.kron((on_free.T @ on_free).toarray(), np.eye(3))
    held = vertices[touched]
    target = edges @ held
    scale = float(np.mean(np.sqrt(np.sum(target ** 2, axis=1))))
    sides = np.ascontiguousarray(np.asarray(sides, dtype=float).T)  # by coordinate (3, r)
    margins = np.asarray(margins, dtype=float)
    corner_free = index[local]  # (r, 3): each corner's free index, −1 where held

    def facing(y, derivatives=True):  # n · side (r,) and its derivatives by the corners' coordinates (r, 9)
        p = y.T  # by coordinate
        p0 = p[:, local[:, 0]]
        u, v = p[:, local[:, 1]] - p0, p[:, local[:, 2]] - p0
        projection = coordinate_dot(coordinate_cross(u, v), sides)
        if not derivatives:
            return projection
        d1, d2 = coordinate_cross(v, sides), coordinate_cross(sides, u)
        return projection, np.concatenate([-(d1 + d2), d1, d2]).T

    def energy(y, weight):
        short = np.maximum(0.0, margins - facing(y, False)) / scale
        return 0.5 * np.sum((edges @ y - target) ** 2) + 0.5 * weight * np.sum(short ** 2)

    y = held.copy()
    for weight in weights:
        for _ in range(UNTANGLE_ITERATIONS):
            projection, derivative = facing(y)
            if (projection >= 0.5 * margins).all():
                out[touched] = y
                return out, True
            short = np.maximum(0.0, margins - projection) / scale
            active = np.flatnonzero(short > 0.0)
            # the Gauss–Newton matrix and the gradient on the free vertices' coordinates: each
            # active triangle adds the outer product of its derivative on its free corners
            slots = (3 * corner_free[active][:, :, None] + np.arange(3)).reshape(-1, 9)
            slots[np.repeat(corner_free[active] < 0, 3, axis=1)] = -1
            rows = derivative[active] / scale
            rows[slots < 0] = 0.0
            slots = np.maximum(slots, 0)  # held corners carry zeros
            pairs = (slots[:, :, None] * unknowns + slots[:, None, :]).ravel()
            matrix = laplacian + weight * np.bincount(pairs, (rows[:, :, None] * rows[:, None, :]).ravel(),
                                                      minlength=unknowns * unknowns).reshape(unknowns, unknowns)
            gradient = (on_free.T @ (edges @ y - target)).ravel()
            gradient -= weight * np.bincount(slots.ravel(), (rows * short[active, None]).ravel(), minlength=unknowns)
            if steps is not None:
                steps.append(unknowns)
            try:
                step = linalg.solve(matrix, -gradient, assume_a="pos", check_finite=False)
            except linalg.LinAlgError:  # a free part held nowhere: no step
                break
            before, length = energy(y, weight), 1.0
            while length > 1e-4:
                trial = y.copy()
                trial[is_free] += length * step.reshape(-1, 3)
                if energy(trial, weight) < before:
                    break
                length *= 0.5
            else:
                break  # no descent: the next weight
            y = trial
    out[touched] = y
    return out, bool((facing(y, False) >= 0.5 * margins).all())


def untangle_work(free: int, steps: int) -> float:
    """What a try of :func:`untangle` on a system of ``free`` free vertices taking ``steps``
    Gauss–Newton steps costs, in steps of a system of :data:`UNTANGLE_FREE_VERTICES` free vertices:
    each step's dense algebra grows with the square of its unknowns (the matrix of 9 × ``free``²
    entries made and solved), its other work not (:data:`UNTANGLE_STEP_OVERHEAD`), and the try's
    set-up (1.1 ms, about two steps of a small system) is counted as two steps of its own size: about right
    for the small systems most tries solve, for large ones an over-count of under ``2 / (steps + 2)``
    of the charge, which keeps the bound on the safe side."""
    return (steps + 2) * (free ** 2 + UNTANGLE_STEP_OVERHEAD) / (UNTANGLE_FREE_VERTICES ** 2 + UNTANGLE_STEP_OVERHEAD)


class Untangling(NamedTuple):
    """What :func:`untangled` did to an in-between: the pose, and of the places where it kept
    flipped or collapsed triangles (the tangles: connected groups of them with the triangles within
    the first of :data:`UNTANGLE_RINGS` rings, sharing no vertex) how many it left, and why."""

    positions: np.ndarray  # (n, 3)
    defects: int  # the flipped or collapsed triangles the pose keeps, in the places left
    tangles: int  # the places it had
    left: int  # of those, the ones not untangled
    too_large: int  # of those left, the ones never tried: over UNTANGLE_FREE_VERTICES or the in-between's work (UNTANGLE_WORK)


def untangled(gap, x: np.ndarray, s: float, scale: np.ndarray,
              defects: np.ndarray | None = None) -> Untangling | None:
    """An in-between ``x`` (n, 3) of a sequence at factor ``s`` of ``gap`` (a
    ``core.inbetween_solver.Gap``; ``scale``: its ``area_scale(s)``) with flipped or collapsed
    triangles, as the repairs count them (triangles that turn away from both keys as the
    interpolated rotations turn them are none: :mod:`core.inbetween_turned_away`), untangled place
    by place. For each of :data:`UNTANGLE_RINGS` in turn, the defects still kept grown by that many
    rings fall into places (connected parts that share no vertex: what moves in one changes no
    triangle of another), packed in order into runs of at most :data:`UNTANGLE_FREE_VERTICES` free
    vertices (:meth:`_Region.packs`), each run untangled at once (:func:`untangle`; a run that does
    not come back facing its sides, place by place) on its triangles: the defective ones to face the keys' mean unit normal (where the keys' normals are
    within 120°; else the key's their normal opposes least), by :data:`UNTANGLE_MARGIN` of twice
    their interpolated area, every other one the key it faces (the larger of its normal's two
    projections) by half as much as it does or that margin, whichever is less — or, turned away from
    both keys, the way it faces —; the still vertices held. A place's move is kept where its region
    comes back with no defect (as the whole pose's check counts it,
    :meth:`~core.inbetween_defects.DefectChecks.region_defects`; a place that faced its sides but
    left a triangle collapsed is solved once more alone with its margins floored,
    :data:`UNTANGLE_COLLAPSE_FLOOR`) and the pose stays within what a repair of it may move
    (:meth:`~core.inbetween_repair_rounds.RepairRounds.move_limits`, a sum of squared moves over the
    whole pose, counted from ``x``); the others' are kept regardless, and the places left are tried
    again at the next ring. A place is not tried where it has more than
    :data:`UNTANGLE_FREE_VERTICES` free vertices or where its try at its most steps would take the
    in-between past its work (:data:`UNTANGLE_WORK`, counted by :func:`untangle_work`; in the
    mesh's order). None where ``x`` is not finite, has no
    such triangle, or where no place was untangled and every one was tried (the in-between as it
    was, and what was said of it, stand); the places counted are those of the first ring.
    ``defects``: those of ``x`` (bool (m,)) as that check counts them, if the caller has them
    (:func:`core.inbetween_prediction_repairs.untangled_first`, which untangles a prediction that
    keeps few before the repairs again)."""
    repair = gap.repair
    limit = repair.move_limits(s)[0]
    if not np.isfinite(x).all():
        return None
    # the check the in-between's outcome and warning count by (the interpolated frames on the
    # triangles the check reads: core.inbetween_solver.Gap.repaired); with the area scale the
    # collapse test is the repairs' again (core.inbetween_prediction_repairs.repaired_in_passes)
    frames, stretch = repair.factor_targets(s)[:2]
    defects = repair.defects(x, s, frames, stretch, scale=scale) if defects is None else defects
    if not defects.any():
        return None
    y, moved, work, first = x.copy(), 0.0, 0.0, None
    kept, tried = defects.copy(), np.zeros_like(defects)
    budget = UNTANGLE_WORK * max(1.0, len(x) / UNTANGLE_WORK_VERTICES)
    most = len(UNTANGLE_WEIGHTS) * UNTANGLE_ITERATIONS

    def fits(size) -> bool:  # whether a try of ``size`` free vertices fits in the work left at its most steps
        return work + untangle_work(size, most) <= budget

    def keep(part, z, places) -> list:  # each of ``places`` of ``part`` moved to ``z`` where that cleans it
        nonlocal moved
        collapsed = []  # the places whose region keeps a defect there
        for place in places:
            mine, rows = part.vertex_place == place, part.rows[part.row_place == place]
            vertices, new = part.vertices[mine], z[mine]
            held, start = y[vertices], x[vertices]
            step = float(np.sum((new - start) ** 2) - np.sum((held - start) ** 2))
            if not np.isfinite(new).all() or moved + step > limit:
                continue  # past what a repair of the in-between may move
            y[vertices] = new
            if repair.region_defects(y, s, frames, stretch, rows, scale=scale).any():
                y[vertices] = held  # its region holds every triangle a free vertex has
                collapsed.append(place)
                continue
            moved += step
            kept[rows] = False
        return collapsed

    def attempt(region, places, floored=False) -> bool | None:  # None: past the in-between's work, not tried
        nonlocal work
        if not fits(int(region.sizes[places].sum())):
            return None
        part = region.part(places)
        tried[part.rows[kept[part.rows]]] = True
        steps = []
        margins = np.maximum(part.margins, part.floors) if floored else part.margins
        z, faces = untangle(y[part.vertices], part.corners, part.free, part.sides, margins, steps=steps)
        work += untangle_work(part.free.size, len(steps))
        if faces:
            for place in keep(part, z, places):
                if not floored:  # facing its sides, it left a triangle collapsed: once more, each margin floored
                    attempt(region, [place], floored=True)
        return faces

    for rings in UNTANGLE_RINGS:
        if not kept.any():
            break
        region = _Region(gap, y, kept, repair.grow(kept, rings), scale)
        first = region if first is None else first
        for pack in region.packs():
            size = int(region.sizes[pack].sum())
            # past the in-between's work, each place alone while it fits
            for places in [pack] if fits(size) else [[place] for place in pack]:
                if attempt(region, places) is False and len(places) > 1:
                    for place in places:  # one place that does not untangle held the others: each alone
                        attempt(region, [place])
    # the places of the first ring: left where they keep a defect, too large where none of theirs was tried
    places = first.row_place[defects[first.rows]]
    left = np.bincount(places, kept[first.rows][defects[first.rows]], minlength=first.count) > 0
    large = left & (np.bincount(places, tried[first.rows][defects[first.rows]], minlength=first.count) == 0)
    if left.all() and not large.any():
        return None
    return Untangling(y, int(kept.sum()), first.count, int(left.sum()), int(large.sum()))


class _Region:
    """The triangles ``mask`` (bool (m,)) around the defects ``bad`` (bool (m,)) of an in-between
    ``x`` (n, 3) of ``gap``, in places (``count`` connected parts: each triangle's ``row_place``,
    each vertex's ``vertex_place``, the free vertices of each ``sizes`` (count,)), with the sides
    each triangle is to face and by how much (:func:`untangled`; ``scale``: the gap's ``area_scale(s)``)."""

    def __init__(self, gap, x: np.ndarray, bad: np.ndarray, mask: np.ndarray, scale: np.ndarray):
        topo = gap.topo
        self.rows = np.flatnonzero(mask)
        corners = topo.triangles[self.rows]
        self.touched, local = np.unique(corners, return_inverse=True)
        self.local = local.reshape(-1, 3)
        movable = np.bincount(local.ravel(), minlength=self.touched.size) == topo.triangles_per_vertex[self.touched]
        if gap.static is not None:
            movable &= ~gap.static[self.touched]
        self.movable = movable
        self.count, labels = corner_joined_parts(local.ravel(), self.touched.size)
        self.row_place, self.vertex_place = labels[:self.rows.size], labels[self.rows.size:]
        self.sizes = np.bincount(self.vertex_place[movable], minlength=self.count)
        self.sides, self.margins = _sides(gap, x, self.rows, corners, bad[self.rows], scale)
        # the margins' floor where a place is tried again: facing its side by half of it, a triangle's
        # normal (twice its area) is at least 2 × UNTANGLE_COLLAPSE_FLOOR × the collapse check's area
        self.floors = 4.0 * UNTANGLE_COLLAPSE_FLOOR * COLLAPSE_RATIO * gap.base.areas[self.rows] * scale[self.rows]

    def packs(self) -> list[list[int]]:
        """The places of at most :data:`UNTANGLE_FREE_VERTICES` free vertices, in order, packed into
        runs of at most that many free vertices in all: each run is untangled at once (one dense
        system, its places' blocks independent: 91 Gauss–Newton solves for the 18 in-betweens of
        the benchmark that kept flips, 148 with one call per place)."""
        packs, total = [], UNTANGLE_FREE_VERTICES + 1
        for place in np.flatnonzero(self.sizes <= UNTANGLE_FREE_VERTICES):
            if total + self.sizes[place] > UNTANGLE_FREE_VERTICES:
                packs.append([])
                total = 0
            packs[-1].append(int(place))
            total += self.sizes[place]
        return packs

    def part(self, places) -> SimpleNamespace:
        """The ``places`` (a list) of the region, numbered on their own: their triangles ``rows``
        (r,) and the ``corners`` (r, 3) among their ``vertices`` (v,: the pose's indices), the
        ``free`` ones (f,: among ``vertices``), ``sides`` (r, 3), ``margins`` (r,) and their
        ``floors`` (r,), and the place of each triangle and vertex, ``row_place`` (r,) and ``vertex_place`` (v,)."""
        mine = np.isin(self.row_place, places)
        vertices = np.flatnonzero(np.isin(self.vertex_place, places))
        renumbered = np.full(self.touched.size, -1)
        renumbered[vertices] = np.arange(vertices.size)
        return SimpleNamespace(rows=self.rows[mine], corners=renumbered[self.local[mine]],
                               vertices=self.touched[vertices], free=renumbered[vertices[self.movable[vertices]]],
                               sides=self.sides[mine], margins=self.margins[mine], floors=self.floors[mine],
                               row_place=self.row_place[mine],
                               vertex_place=self.vertex_place[vertices])


def _sides(gap, x: np.ndarray, rows: np.ndarray, corners: np.ndarray, bad: np.ndarray,
           scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unit side (r, 3) each of the triangles ``rows`` (corners (r, 3)) of an in-between ``x``
    (n, 3) of ``gap`` is to face in its untangling, and by how much (r,) (:func:`untangled`;
    ``bad``: which of them are defects, bool (r,); ``scale``: the gap's ``area_scale(s)``)."""
    first, second = gap.base.normal_rows[:, rows].T, gap.next.normal_rows[:, rows].T
    first = first / np.linalg.norm(first, axis=1, keepdims=True)
    second = second / np.linalg.norm(second, axis=1, keepdims=True)
    p = x[corners]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    on_first, on_second = np.einsum("ij,ij->i", normal, first), np.einsum("ij,ij->i", normal, second)
    nearer = np.where((on_first >= on_second)[:, None], first, second)
    mean = first + second
    length = np.linalg.norm(mean, axis=1)
    facing = np.maximum(on_first, on_second)
    # a triangle that faces away from both keys and is no defect turns as the interpolated
    # rotations turn it: it keeps facing the way it does
    away = ~bad & (facing < 0.0)
    sides = np.where((bad & (length >= 1.0))[:, None], mean / np.maximum(length, 1e-300)[:, None], nearer)
    if away.any():
        own = np.linalg.norm(normal[away], axis=1)
        sides[away], facing[away] = normal[away] / np.maximum(own, 1e-300)[:, None], own
    least = UNTANGLE_MARGIN * 2.0 * gap.base.areas[rows] * scale[rows]
    return sides, np.maximum(np.where(bad, least, np.minimum(least, 0.5 * facing)), 0.0)


def untangled_poses(gap, factors, results: list) -> list:
    """``results`` (positions (n, 3), problem or None) at ``factors`` of ``gap`` with each
    in-between of a sequence that keeps flipped or collapsed triangles replaced by its
    :func:`untangled` pose where there is one: clean (its outcome then counts no defect), or with
    the places it left said (its outcome then counts their defects)."""
    kept = {}
    for k, (s, (x, problem)) in enumerate(zip(factors, results)):
        if problem is not None and gap.repair.in_sequence(s):
            scale = gap.area_scale(s)
            if gap.repair.defects(x, s, None, None, scale=scale).any():  # else none as the check counts either
                kept[k] = scale
    if not kept:
        return results
    out = list(results)
    done = per_factor(gap, lambda k: untangled(gap, results[k][0], factors[k], kept[k]), list(kept))
    for k, result in zip(kept, done):
        if result is None:
            continue
        s = factors[k]
        if not result.left:
            out[k] = (result.positions, None)
            gap.outcomes[s] = Outcome(0, False)
            continue
        before = gap.outcomes.get(s)
        near_blend = before is not None and before.near_blend
        out[k] = (result.positions, left_message(result, near_blend))
        gap.outcomes[s] = Outcome(result.defects, near_blend)
    return out


def left_message(result: Untangling, near_blend: bool) -> str:
    """The warning's text for an in-between the untangling left places in (``result``): what it
    keeps first, where a report line cut to the status bar's width still shows it; ``near_blend``:
    whether the repairs left a fallback near the keys' linear blend (a sequence's fit that was not
    finite, :meth:`~core.inbetween_repair.Repair.outcome`) rather than the metric fit."""
    kept = "a fit near the keys' linear blend" if near_blend else "the metric fit"
    large = "" if not result.too_large else (
        f"; {result.too_large} of those left too large to untangle: a tangle of more than "
        f"{UNTANGLE_FREE_VERTICES} vertices, or past the work the untangling may do in the in-between")
    return (f"it keeps {result.defects} triangle(s) flipped or collapsed in {result.left} of the {result.tangles} "
            f"place(s) where its repairs left the cloth folded over or crushed ({result.tangles - result.left} "
            f"untangled{large}); keys closer together here tell the motion better, or fix those triangles by hand "
            f"({kept} with the fewest defects, untangled place by place)")
