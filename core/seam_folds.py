"""Folds along seams: the analyses (distortion maps, shape space) compare the pieces of a mesh
split along seams (:mod:`core.seam_welds`) each on its own, so a pose that turns the two sides of a
seam against each other shows in neither piece's differences. :func:`seam_sides` finds the
triangles on either side of each seam edge, :func:`seam_folds` measures how far a pose folds each
seam beyond what the coordinates' rounding turns them by, and :func:`warn_seam_folds` says so.
"""

from __future__ import annotations

import numpy as np

from .coordinate_rounding import coordinate_rounding, inverse_heights
from .errors import warn
from .geometry import normalize
from .seam_welds import coincidence_tolerance, seam_pairs


#: The analyses that compare a mesh's pieces each on its own (distortion maps, shape space) warn
#: where a pose turns the two sides of a seam against each other by more than this (radians), on
#: top of what the coordinates' rounding turns their normals by: a fold along the seam, which no
#: piece's differences see.
SEAM_FOLD_TOLERANCE = float(np.radians(1.0))


def seam_sides(poses: list[np.ndarray], topology) -> np.ndarray:
    """The triangles on either side of each seam edge of ``topology`` (a
    :class:`core.mesh_topology.MeshTopology`) in ``poses`` (list of (n, 3)), int64 ``(s, 2)``: the
    boundary edges :func:`core.seam_welds.seam_weld` would join (coinciding end for end with exactly one other in
    every pose, within :func:`core.seam_welds.coincidence_tolerance` of the first), each with its one triangle."""
    a, b = seam_pairs(poses, topology, coincidence_tolerance(poses[0], topology.edges))
    if not a.size:
        return np.zeros((0, 2), dtype=np.int64)
    n = topology.n_vertices
    keys = topology.edges[:, 0] * n + topology.edges[:, 1]
    order = np.argsort(keys)
    sides = []
    for pairs in (a.reshape(-1, 2), b.reshape(-1, 2)):
        pairs = np.sort(pairs, axis=1)
        edge = order[np.searchsorted(keys, pairs[:, 0] * n + pairs[:, 1], sorter=order)]
        sides.append(topology.edge_triangles[edge].max(axis=1))  # a boundary edge's one triangle
    return np.stack(sides, axis=1)


def seam_folds(base: np.ndarray, pose: np.ndarray, triangles: np.ndarray, sides: np.ndarray,
               single: bool | None = None) -> np.ndarray:
    """How far ``pose`` (n, 3) folds each seam (``sides`` (s, 2) from :func:`seam_sides`) from
    ``base`` (n, 3), float (s,) radians: the change of the angle between the normals of the
    triangles (``triangles`` (m, 3)) on its two sides (the same whichever way the pieces are wound,
    and nothing for a motion of both sides together), less :data:`SEAM_FOLD_TOLERANCE` and what the
    rounding of the coordinates (:func:`core.coordinate_rounding.coordinate_rounding`) turns those
    normals by (it over each triangle's height, :func:`core.coordinate_rounding.inverse_heights`, in
    both poses); positive where the fold is real."""
    if not len(sides):
        return np.zeros(0)
    sided = triangles[sides.ravel()]  # the seams' triangles only, two per seam edge
    angles = []
    for positions in (base, pose):
        a, b, c = (positions[sided[:, k]] for k in range(3))
        normals = normalize(np.cross(b - a, c - a))[0].reshape(-1, 2, 3)
        angles.append(np.arccos(np.clip(np.einsum("sd,sd->s", normals[:, 0], normals[:, 1]), -1.0, 1.0)))
    rounding = coordinate_rounding([base, pose], single)
    noise = 2.0 * rounding * sum(inverse_heights(positions, sided).reshape(-1, 2).sum(axis=1) for positions in (base, pose))
    return np.abs(angles[1] - angles[0]) - SEAM_FOLD_TOLERANCE - noise


def warn_seam_folds(base: np.ndarray, poses: list[np.ndarray], triangles: np.ndarray, sides: np.ndarray,
                    single_precision: bool | None, name: str, consequence: str) -> bool:
    """ShapeDifferenceWarning where ``poses`` (list of (n, 3)) fold a mesh along its seams from
    ``base`` (:func:`seam_folds`; ``sides`` from :func:`seam_sides`):
    pieces apart along coincident vertices, whose differences each piece has on its own.
    ``name``: the poses as the message calls them; ``consequence``: what the analysis misses.
    Returns whether it warned."""
    folds = np.array([seam_folds(base, pose, triangles, sides, single_precision) for pose in poses])
    folded = (folds > 0).any(axis=0)
    if not folded.any():
        return False
    worst = float(np.degrees(folds.max() + SEAM_FOLD_TOLERANCE))
    warn(
        f"The mesh is split along seams ({len(sides)} seam edge(s): pieces whose boundary vertices coincide, "
        "as exporters and importers leave a mesh split at UV seams or hard edges), and "
        f"{int(folded.sum())} of them fold by up to {worst:.3g}° in {name}: {consequence}. Weld the seams "
        "(Merge by Distance) to measure the mesh as one surface.",
        "seam")
    return True
