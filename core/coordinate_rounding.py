"""The rounding of a mesh's coordinates: single precision where every coordinate is a float32 (as
Blender stores them), double otherwise (:func:`coordinate_rounding`, :func:`rounding_scale`), and
what it changes a triangle's area and angles by (:func:`inverse_heights`, :func:`across_edges`) and
the shape differences by, averaged over the mesh (:func:`relative_round_off`): the tolerances of
the still and riding vertices, of coincident vertices (:func:`core.seam_welds.coincidence_tolerance`),
of folds along seams and of the distortion maps and shape space are set above it. Keys exported with a
fixed count of decimals are rounded coarser, to that decimal grid (:func:`decimal_rounding`): the rigid
parts of a sequence's pieces are read to it (:func:`core.sequence_bent_parts.rounded_tolerance`).
"""

from __future__ import annotations

import math

import numpy as np


#: The round-off of a rigid motion computed in double precision from coordinates (a piece's rigid fit,
#: motions composed, turned into a screw), as a share of the coordinates' magnitude (the largest
#: coordinate plus the pieces' extent or the joint's reach): a length under it is no motion, in a
#: piece's screws off the next key's line (:func:`core.inbetween_carriers.screw_departures`) and a
#: joint's slide along its axis (:func:`core.inbetween_joints.slide_precision`). A margin: some 1e7
#: times double precision's unit round-off (1.1e-16) for the digits those steps lose, far under any
#: motion those rules tell apart.
RIGID_ROUNDING = 1e-9


def _single_precision(poses: list[np.ndarray]) -> bool:
    """Whether every coordinate of ``poses`` (list of (n, 3)) is a float32 (as Blender stores them)."""
    return all(np.array_equal(pose, pose.astype(np.float32)) for pose in poses)


def rounding_scale(poses: list[np.ndarray]) -> float:
    """The magnitude whose single-precision rounding the coordinates of ``poses`` (list of (n, 3))
    carry: their largest coordinate where every one is a float32 (stored so: Blender, most
    caches), else the largest extent of a pose (computed in double precision from single-precision
    positions about their object, as a cache moved by its object's transform is, or double
    precision throughout, whose rounding is smaller still). The same sequence 1e4 units from the
    origin in double precision had the roundings of float32 coordinates of 2e4 (0.02 units): a
    cloth on a turntable, whose edges keep their lengths to 0.1 %, took 36 of its vertices for
    still and six sets for riding, 0.22 of its diagonal off."""
    if _single_precision(poses):
        return max((float(np.max(np.abs(pose), initial=0.0)) for pose in poses), default=0.0)
    return max((float(np.linalg.norm(np.ptp(pose, axis=0))) for pose in poses if pose.size), default=0.0)


def coordinate_rounding(poses: list[np.ndarray], single: bool | None = None) -> float:
    """The rounding of the largest coordinate of ``poses`` (list of (n, 3)): single precision
    where ``single`` (``None``: where every coordinate is a float32, as Blender stores keys), else
    double. Shape keys that only move their mesh, stored in single precision, have shape
    differences of about this over their edge lengths (1e-7 to 1e-5), not zero."""
    if not poses:
        return 0.0
    if single is None:
        single = _single_precision(poses)
    largest = max(float(np.max(np.abs(pose), initial=0.0)) for pose in poses)
    return float(np.finfo(np.float32 if single else np.float64).eps * largest)


#: The decimal places :func:`decimal_rounding` looks for (1 … 9): a cache or an OBJ sequence written
#: with a fixed count of decimals (Blender's OBJ exporter writes 6; hand-made exports 3–5). Not whole
#: units: a mesh whose every key lies on a grid that coarse is built on it, not rounded to it.
DECIMAL_PLACES = range(1, 10)
#: Largest distance of a coordinate from the decimal grid, as a share of its step, for
#: :func:`decimal_rounding` to take the coordinates as rounded to it: a coordinate not rounded so lies
#: anywhere within half a step of it, so over a mesh's coordinates some lie far past this share; one
#: read back in single precision lies within half a float32 spacing of it, far under this share where
#: the step is :data:`DECIMAL_FLOAT_STEPS` spacings or more.
DECIMAL_GRID_SHARE = 0.05
#: Least step of a decimal grid, in spacings of the largest coordinate's precision (single where every
#: coordinate is a float32, else double), that :func:`decimal_rounding` reads: finer ones are lost in
#: that precision's own rounding.
DECIMAL_FLOAT_STEPS = 16.0
#: The coordinates :func:`decimal_rounding` checks a grid on first (all of them only where these are
#: on it): a mesh's coordinates not rounded leave it at once, so the check costs little on them.
DECIMAL_SAMPLE = 1024


def decimal_rounding(poses: list[np.ndarray], edges: np.ndarray, rounding: float | None = None) -> float:
    """The step ``10**-d`` of the coarsest decimal grid that every coordinate of ``poses`` (list of
    (n, 3)) lies on (to :data:`DECIMAL_GRID_SHARE` of the step: keys exported to ``d`` decimals, read
    back in single or double precision), ``d`` in :data:`DECIMAL_PLACES`; 0 where none (a bake, a
    shape key: single precision, :func:`coordinate_rounding`) or where that step is under
    :data:`DECIMAL_FLOAT_STEPS` spacings of the largest coordinate's precision. Rounding to ``d`` decimals
    moves a coordinate by up to half the step, as single precision moves it by up to half its spacing:
    the step is the keys' rounding as :func:`coordinate_rounding` gives it, where it is the larger
    (``rounding``: that, where the caller has it).

    Only grids no coarser than the first key's shortest edge allows (``edges`` int (e, 2), its vertex
    pairs): two vertices on distinct points of a grid differ by a whole step in some coordinate, so an
    edge between them is at least the step less twice :data:`DECIMAL_GRID_SHARE` of it long. A mesh
    smaller than a twentieth of a step (a 4 mm limb in metres) lies within that share of a grid point
    of every coarser grid, on none of them."""
    poses = [np.asarray(pose, dtype=np.float64) for pose in poses if np.size(pose)]
    if not poses:
        return 0.0
    finest = DECIMAL_FLOAT_STEPS * (coordinate_rounding(poses) if rounding is None else rounding)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    shortest = float(np.linalg.norm(poses[0][edges[:, 0]] - poses[0][edges[:, 1]], axis=1).min(initial=np.inf))
    sample = poses[0].ravel()[:DECIMAL_SAMPLE]
    for places in DECIMAL_PLACES:
        step = 10.0 ** -places
        if step < finest:
            break
        if (1.0 - 2.0 * DECIMAL_GRID_SHARE) * step > shortest:
            continue  # a grid coarser than an edge holds no mesh: its coordinates sit near it by their smallness

        def on_grid(values):
            return float(np.max(np.abs(values - np.round(values, places)))) <= DECIMAL_GRID_SHARE * step

        if on_grid(sample) and all(on_grid(pose) for pose in poses):
            return step
    return 0.0


#: A grid that every key lies on, of step 1, 2 or 5 × 10^k at least this share of the first key's median
#: edge, is the mesh's own (:func:`built_on_grid`): a mesh made on it (a voxel mesh on whole units, Blender's
#: Grid primitive on 0.2, vertices moved by snapping to increments), not one rounded to it. Rounding that
#: coarse moves a corner by up to √3/2 step, a fifth of such an edge; the 19 benchmark bakes rounded to
#: 3 decimals, the coarsest export measured, keep 7.6–79 steps per median edge (the 100k sheet the fewest).
BUILT_GRID_SHARE = 0.25


def built_on_grid(poses: list[np.ndarray], edges: np.ndarray) -> bool:
    """Whether every coordinate of ``poses`` (list of (n, 3)) lies (to :data:`DECIMAL_GRID_SHARE` of
    its step) on a grid of step 1, 2 or 5 × 10^k between :data:`BUILT_GRID_SHARE` of the first pose's
    median edge (``edges`` int (e, 2), its vertex pairs) and that edge ÷ 0.9 (a coarser grid holds no
    such edge, :func:`decimal_rounding`): keys on a grid as coarse as their edges were built on it, so
    a triangle they flatten is the mesh's (a key collapsing a part, a vertex snapped onto a line),
    not a rounding's, whatever decimal grid :func:`decimal_rounding` finds them on."""
    poses = [np.asarray(pose, dtype=np.float64) for pose in poses if np.size(pose)]
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if not poses or not len(edges):
        return False
    median = float(np.median(np.linalg.norm(poses[0][edges[:, 0]] - poses[0][edges[:, 1]], axis=1)))
    low, high = BUILT_GRID_SHARE * median, median / (1.0 - 2.0 * DECIMAL_GRID_SHARE)
    if not low > 0 or not np.isfinite(high):
        return False
    steps = [factor * 10.0 ** power for power in range(math.floor(math.log10(low)), math.ceil(math.log10(high)) + 1)
             for factor in (1.0, 2.0, 5.0)]
    return any(all(float(np.max(np.abs(pose / step - np.round(pose / step)))) <= DECIMAL_GRID_SHARE for pose in poses)
               for step in steps if low <= step <= high)


def inverse_heights(pose: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Per triangle (m,) of ``pose`` (n, 3), one over its smallest height (its longest edge over
    its doubled area; inf for a flat one): times a coordinate rounding
    (:func:`coordinate_rounding`), what the rounding can change its area and angles by,
    relatively. The height, not the shortest edge: a long flat triangle (an n-gon's cap cut into
    a fan) turns by the rounding over its height; over its shortest edge, a turned cylinder's caps
    read as distortion (21 of 252 faces)."""
    a, b, c = (pose[triangles[:, k]] for k in range(3))
    longest = np.max([np.linalg.norm(p - q, axis=1) for p, q in ((a, b), (b, c), (c, a))], axis=0)
    doubled = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(doubled > 0, longest / doubled, np.inf)


def across_edges(values: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Per triangle (m,), the largest of ``values`` (m,) over it and the triangles sharing an edge
    with it: the offset surface's points above a triangle and above those across its edges move
    with their normals, so its bending's round-off is the thinnest one's
    (:func:`inverse_heights`)."""
    if not len(triangles):
        return np.asarray(values, dtype=float)
    ends = np.sort(triangles[:, [[0, 1], [1, 2], [2, 0]]], axis=2).reshape(-1, 2)
    edge = np.unique(ends, axis=0, return_inverse=True)[1].reshape(-1, 3)
    largest = np.full(int(edge.max()) + 1, -np.inf)
    np.maximum.at(largest, edge, np.asarray(values, dtype=float)[:, None])
    return largest[edge].max(axis=1)


def relative_round_off(poses: list[np.ndarray], triangles: np.ndarray, single: bool | None = None,
                       offset: float | None = None) -> float:
    """The area-weighted mean of the relative round-off (:func:`inverse_heights` times
    :func:`coordinate_rounding`) over the triangles of the first of
    ``poses``: the size of the shape differences (averages over the mesh) that the rounding of the
    coordinates alone makes; with ``offset`` t, of the offset surface's (each triangle's times
    ``1 + t / h``, h the smallest height of it and the triangles across its edges,
    :func:`across_edges`: the offset points lie t out along normals that the rounding turns by its
    size over h)."""
    if not poses or not len(triangles):
        return 0.0
    first = poses[0]
    a, b, c = (first[triangles[:, k]] for k in range(3))
    areas = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    rounding = coordinate_rounding(poses, single)
    noise = rounding * inverse_heights(first, triangles)
    if offset is not None and rounding > 0:
        noise = rounding * across_edges(noise / rounding, triangles)
        noise = noise * (1.0 + offset * noise / rounding)
    finite = np.isfinite(noise)
    return float(areas[finite] @ noise[finite] / areas[finite].sum()) if areas[finite].sum() > 0 else 0.0
