"""Pieces of a mesh that are their own mirror image from one key to the next (a negative scale, a
mirrored copy; paper §8.4): no motion makes that, so the in-betweens deform them through a
flattened shape and :func:`warn_mirrored` says so (the fits: :func:`core.rigid_alignment.reflected_fits`)."""

from __future__ import annotations

import numpy as np

from .inbetween_motion import RIGID_PLACEMENT_SCALE, SIMILAR_SHAPE_MISFIT
from .inbetween_topology import Topology
from .rigid_alignment import reflected_fits
from .sequence_warnings import warn_said

#: A piece is said to be mirrored between two keys where the best reflection (improper orthogonal
#: map) takes it onto the next key within this fraction of its diagonal (RMS; as a rigid motion
#: is told by :data:`core.inbetween_motion.RIGID_PLACEMENT_SCALE`) ...
MIRROR_FIT = RIGID_PLACEMENT_SCALE
#: ... and the best rigid motion misses it by over this fraction: it would have to deform
#: visibly (:data:`core.inbetween_motion.SIMILAR_SHAPE_MISFIT`'s upper end). A flat piece is its
#: mirror image turned over, and passes (both fit it).
MIRROR_MISS = SIMILAR_SHAPE_MISFIT[1]
#: Vertices of each piece the check reads (evenly along its vertex order).
MIRROR_SAMPLES = 256


def warn_mirrored(topo: Topology, keys: list[np.ndarray], key_names: list[str],
                  kept: np.ndarray | None) -> frozenset[int]:
    """Warn where a piece is its own mirror image from one key to the next: a reflection (a
    negative scale, a mirrored copy) fits it within :data:`MIRROR_FIT` of its diagonal and no
    rigid motion within :data:`MIRROR_MISS`. No motion turns a shape into its mirror image, so
    the in-betweens deform it through a flattened shape (tetrahedra mirrored: flat at 0.5,
    edges 18 % off, silently). ``topo``: the sequence's topology; ``keys``: the K key poses
    (n, 3) as interpolated; ``key_names``: the keys as warnings name them; ``kept``: the
    caller's index of each vertex (n,) (seams welded), or None. Returns the gaps warned of (their
    first keys' indices): their in-betweens' edges are off the metric by the flattening, which this
    warning says (:mod:`core.sequence_edge_misfit` does not say it again)."""
    count = len(topo.components)
    warned = set()
    if not count:
        return frozenset()
    # about MIRROR_SAMPLES vertices of each piece, evenly along its vertices: a reflection's
    # fit and a rotation's miss 30 × apart are told by a few hundred (a cloth's check per pair
    # of keys on all 100k vertices cost 1 % of its in-betweens)
    order, starts = topo.component_order, topo.component_starts
    sizes = np.diff(np.r_[starts, order.size])
    stride = np.maximum(sizes // MIRROR_SAMPLES, 1)
    label = np.repeat(np.arange(count), sizes)
    rows = order[(np.arange(order.size) - starts[label]) % stride[label] == 0]
    labels = None if count == 1 else topo.vertex_component[rows]
    for i in range(len(keys) - 1):
        base = keys[i]
        pieces, rotation, reflection = reflected_fits(base[rows], keys[i + 1][rows], labels, count,
                                                      topo.weights[rows])
        if not pieces.size:
            continue
        mass = np.bincount(labels, topo.weights[rows], minlength=count)[pieces] if count > 1 else \
            topo.weights[rows].sum()
        size = topo.diagonals(base)[pieces]
        fit, miss = np.sqrt(reflection / mass), np.sqrt(rotation / mass)
        mirrored = pieces[(fit <= MIRROR_FIT * size) & (miss > MIRROR_MISS * size)]
        if mirrored.size:
            warned.add(i)
            first = int(topo.component_vertices[topo.component_labels == mirrored[0]][0])
            first = first if kept is None else int(kept[first])
            warn_said(f"{mirrored.size} piece(s) of the mesh (e.g. the one with vertex {first}) are the mirror "
                  f"image of themselves from {key_names[i]} to {key_names[i + 1]} (a reflection, as a "
                  "negative scale gives), which no motion makes: the in-betweens deform them through a "
                  "flattened shape. Check that key (apply the scale, or mirror the mesh back)", "mirror",
                  gap=(key_names[i], key_names[i + 1]))
    return frozenset(warned)
