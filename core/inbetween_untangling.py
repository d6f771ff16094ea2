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
L-BFGS took 4–440 ms an in-between on the same problems). :func:`untangled` picks the region, the
sides and takes the result only where it leaves the in-between free of defects.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy import linalg

from .geometry import coordinate_cross, coordinate_dot
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
#: Gauss–Newton steps at each weight at most.
UNTANGLE_ITERATIONS = 20
#: A connected part of the region with more free vertices than this is not untangled, and parts are
#: untangled together up to this many (the Gauss–Newton matrix is dense: 3 × this many unknowns at
#: most; the benchmark's parts have 3–16): a fold that wide is no local tangle.
UNTANGLE_FREE_VERTICES = 200


def untangle(vertices: np.ndarray, triangles: np.ndarray, free: np.ndarray, sides: np.ndarray,
             margins: np.ndarray, weights=UNTANGLE_WEIGHTS) -> tuple[np.ndarray, bool]:
    """``vertices`` (n, 3) with the ``free`` ones (f,: vertex indices, each of whose triangles is
    among ``triangles`` (r, 3)) moved so that every triangle ``t`` faces its side: its normal
    ``n_t = (p1 − p0) × (p2 − p0)`` (twice its area, along its unit normal) has ``n_t · sides[t] ≥
    margins[t] / 2`` (``sides`` (r, 3) unit vectors, ``margins`` (r,) ≥ 0), changing the triangles'
    edges little: Gauss–Newton steps (with a backtracking line search) on ``½ Σ |e − e⁰|² + ½ μ Σ
    (max(0, margins − n · sides) / ℓ)²`` over the ``triangles``' corner edges ``e`` (``e⁰``: those of
    ``vertices``; ``ℓ``: their mean length), from ``vertices``, for ``μ`` in ``weights`` in turn,
    stopped at the first iterate where every triangle faces its side. Returns (positions (n, 3),
    whether every triangle does). The other vertices stay where they are."""
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


def untangled(gap, x: np.ndarray, s: float, scale: np.ndarray) -> np.ndarray | None:
    """An in-between ``x`` (n, 3) of a sequence at factor ``s`` of ``gap`` (a
    ``core.inbetween_solver.Gap``; ``scale``: its ``area_scale(s)``) with flipped or collapsed
    triangles, as the repairs count them (triangles that turn away from both keys as the
    interpolated rotations turn them are none: :mod:`core.inbetween_turned_away`), untangled
    (:func:`untangle`) on the triangles within :data:`UNTANGLE_RINGS` rings of them: the
    defective ones to face the keys' mean unit normal (where the keys' normals are within 120°;
    else the key's their normal opposes least), by :data:`UNTANGLE_MARGIN` of twice their
    interpolated area, every other one of the region the key it faces (the larger of its normal's
    two projections) by half as much as it does or that margin, whichever is less — or, turned
    away from both keys, the way it faces —; the still vertices held. None where it has no such
    triangle, else unless the result has none and moves the pose by at most what a repair of it
    may (:meth:`~core.inbetween_repair_rounds.RepairRounds.move_limits`)."""
    repair, topo = gap.repair, gap.topo
    limit = repair.move_limits(s)[0]
    if not np.isfinite(x).all():
        return None
    # the check the in-between's outcome and warning count by (the interpolated frames on the
    # triangles the check reads: core.inbetween_solver.Gap.repaired); with the area scale the
    # collapse test is the repairs' again (core.inbetween_prediction_repairs.repaired_in_passes)
    frames, stretch = repair.factor_targets(s)[:2]
    defects = repair.defects(x, s, frames, stretch, scale=scale)
    if not defects.any():
        return None
    for rings in UNTANGLE_RINGS:
        rows = np.flatnonzero(repair.grow(defects, rings))
        corners = topo.triangles[rows]
        touched, local = np.unique(corners, return_inverse=True)
        inside = np.bincount(local, minlength=touched.size)
        movable = inside == topo.triangles_per_vertex[touched]
        if gap.static is not None:
            movable &= ~gap.static[touched]
        count, labels = corner_joined_parts(local.ravel(), touched.size)
        sizes = np.bincount(labels[rows.size:][movable], minlength=count)
        if count and sizes.max() > UNTANGLE_FREE_VERTICES:
            return None  # a fold that wide is no local tangle
        # the connected parts (their free vertices share no triangle: each one's system is its own
        # block) packed in order into groups of at most UNTANGLE_FREE_VERTICES free vertices, each
        # group untangled at once (one dense system: 91 Gauss–Newton solves on the benchmark's 18
        # in-betweens, 148 with one call per part)
        group, total = np.zeros(count, dtype=np.intp), 0
        for part, size in enumerate(sizes):
            if total + size > UNTANGLE_FREE_VERTICES:
                group[part:], total = group[part] + 1, 0
            total += size
        row_part, vertex_part = group[labels[:rows.size]], group[labels[rows.size:]]
        first, second = gap.base.normal_rows[:, rows].T, gap.next.normal_rows[:, rows].T
        first = first / np.linalg.norm(first, axis=1, keepdims=True)
        second = second / np.linalg.norm(second, axis=1, keepdims=True)
        p = x[corners]
        normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        on_first, on_second = np.einsum("ij,ij->i", normal, first), np.einsum("ij,ij->i", normal, second)
        nearer = np.where((on_first >= on_second)[:, None], first, second)
        mean = first + second
        length = np.linalg.norm(mean, axis=1)
        bad = defects[rows]
        facing = np.maximum(on_first, on_second)
        # a triangle that faces away from both keys and is no defect turns as the interpolated
        # rotations turn it: it keeps facing the way it does
        away = ~bad & (facing < 0.0)
        sides = np.where((bad & (length >= 1.0))[:, None], mean / np.maximum(length, 1e-300)[:, None], nearer)
        if away.any():
            own = np.linalg.norm(normal[away], axis=1)
            sides[away], facing[away] = normal[away] / np.maximum(own, 1e-300)[:, None], own
        least = UNTANGLE_MARGIN * 2.0 * gap.base.areas[rows] * scale[rows]
        margins = np.maximum(np.where(bad, least, np.minimum(least, 0.5 * facing)), 0.0)
        y, faces = x, True
        for part in np.unique(row_part):
            mine = row_part == part
            y, faces = untangle(y, corners[mine], touched[movable & (vertex_part == part)], sides[mine], margins[mine])
            if not faces:
                break
        if not faces or not np.isfinite(y).all():
            continue
        if float(np.sum((y - x) ** 2)) > limit:
            return None
        if not repair.defects(y, s, frames, stretch, rows=rows, scale=scale).any():  # rows hold every defect
            return y
    return None


def untangled_poses(gap, factors, results: list) -> list:
    """``results`` (positions (n, 3), problem or None) at ``factors`` of ``gap`` with each
    in-between of a sequence that keeps flipped or collapsed triangles replaced by its
    :func:`untangled` pose, clean, where there is one (its outcome then counts no defect)."""
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
    for k, y in zip(kept, done):
        if y is not None:
            out[k] = (y, None)
            gap.outcomes[factors[k]] = Outcome(0, False)
    return out
