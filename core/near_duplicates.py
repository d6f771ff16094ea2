"""Near-duplicate vertices: clusters of vertices of one piece joined by edges far under the mesh's
scale in every key, solved as one place by the in-betweens (paper §8.4, the reconstruction of an
in-between) and placed back by the keys' offsets.

A voxel remesh and Decimate, a scanner's doubled points and photogrammetry leave vertices a
hundred-thousandth of an edge apart, joined by tiny edges and by needle triangles to the rest. The
fits place vertices to about a thousandth of an edge (:data:`core.inbetween_fit.NEAR_DUPLICATE_SHARE`):
such an edge's direction is noise to them, and the tiny triangles came out turned over (a body
remeshed in Blender, four vertices 1.4e-5 mean edges apart at the top of its head, keyed every 4
frames: 1.034 × a per-vertex Catmull–Rom's error and 2 of its tiny triangles against the rig; the
same mesh merged by distance 0.899 and none; solved as one place here, the same).

:func:`near_duplicates` finds them: the connected sets of vertices joined by edges shorter than
that share of the key's mean edge in every key, each within it of its first vertex (the
representative) in every key. Each is one vertex of the mesh the in-betweens solve (triangles
with two corners in one cluster are left out of it, and of the defect checks), as a seam weld
joins coincident vertices (:mod:`core.seam_welds`). :meth:`NearDuplicates.place` puts the others
back: the representative plus the gap's keys' offsets from it, blended in the frame of the
representative's neighbours and turned with them (a rigid motion keeps them exactly). The
clusters are used only where the mesh without them is a valid one (manifold, orientable, no
triangle repeated, every representative still in a triangle); otherwise none is (the in-betweens
then solve every vertex, as without this module).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import MeshError
from .geometry import edge_lengths
from .inbetween_fit import NEAR_DUPLICATE_SHARE
from .mesh_topology import check_manifold_vertices, mesh_topology
from .rigid_alignment import rigid_alignments
from .seam_welds import vertex_groups


@dataclass(frozen=True)
class NearDuplicates:
    """Clusters of near-duplicate vertices of a mesh of ``n`` vertices merged: ``kept`` (n_kept,) the
    vertex standing for each merged one, ``copies`` (n,) the merged vertex of each vertex
    (``x_merged[copies]`` puts every cluster at its representative), ``triangles`` (m', 3) in merged
    indices (those with two corners in one cluster left out), ``whole`` (bool (m,)) which of the
    mesh's triangles those are, ``topology`` theirs; ``members`` (p,) the vertices other than the
    representatives, ``cluster`` (p,) each one's cluster (0 ≤ c < C), ``positions`` (K, p, 3)
    theirs in each key; ``rings`` (r,) merged vertices and ``ring_of`` (r,) the cluster each
    serves: every representative with its neighbours, whose rigid turn turns the offsets;
    ``still`` (bool (p,)) or None: members no key moves (:func:`core.pins.still_vertices`), kept
    where the first key has them."""

    kept: np.ndarray
    copies: np.ndarray
    triangles: np.ndarray
    whole: np.ndarray
    topology: object
    members: np.ndarray
    cluster: np.ndarray
    positions: np.ndarray
    rings: np.ndarray
    ring_of: np.ndarray
    still: np.ndarray | None = None

    def place(self, merged: np.ndarray, keys: tuple[np.ndarray, np.ndarray], gap: int, factors) -> np.ndarray:
        """The poses (F, n, 3) of every vertex from ``merged`` (F, n_kept, 3), in-betweens at ``factors``
        (F,) of gap ``gap`` (between keys ``gap`` and ``gap + 1``, whose merged positions are ``keys``,
        each (n_kept, 3)): each member at its representative plus its offset, blended linearly
        between the two keys' in the frame of the representative's ring in key ``gap`` (the other
        key's turned back by the ring's rigid turn between the keys) and turned by the ring's rigid
        turn from key ``gap`` to the in-between. At factors 0 and 1 the members as that key has them;
        still members where the first key has them. The keys' offsets and turn are the gap's, read
        once for all the factors."""
        out = merged[:, self.copies]
        inner = [k for k, factor in enumerate(factors) if factor not in (0.0, 1.0)]
        for k, factor in enumerate(factors):
            if factor in (0.0, 1.0):
                out[k, self.members] = self.positions[gap + int(factor)]
        if not inner:
            return out
        # the gap's own: each key's offsets, the second key's turned back into the first's ring frame
        count = int(self.cluster.max()) + 1
        representative = self.copies[self.members]  # merged indices
        first = self.positions[gap] - keys[0][representative]
        second = self.positions[gap + 1] - keys[1][representative]
        base = keys[0][self.rings]
        between, _ = rigid_alignments(base, keys[1][self.rings], self.ring_of, count)
        back = np.einsum("pba,pb->pa", between[self.cluster], second)
        for k in inner:
            turned, _ = rigid_alignments(base, merged[k][self.rings], self.ring_of, count)
            blended = (1.0 - factors[k]) * first + factors[k] * back
            out[k, self.members] += np.einsum("pab,pb->pa", turned[self.cluster], blended)
            if self.still is not None:  # exactly where they sit, as the still vertices solved
                out[k, self.members[self.still]] = self.positions[0][self.still]
        return out


def near_duplicates(keys: list[np.ndarray], topology) -> NearDuplicates | None:
    """The clusters of near-duplicate vertices of ``topology`` (a
    :class:`core.mesh_topology.MeshTopology` of ``n`` vertices) in ``keys`` (list of (n, 3)): vertices
    joined by edges shorter than :data:`~core.inbetween_fit.NEAR_DUPLICATE_SHARE` × that key's mean
    edge length in every key, each set within that distance of its lowest-numbered vertex in every
    key; None where there are none, or where the mesh without them is not a valid one."""
    edges = topology.edges
    if not len(edges):
        return None
    short, means = None, []
    for key in keys:  # the first key alone decides where there is none (a mesh without them: one pass)
        lengths = edge_lengths(key, edges[:, 0], edges[:, 1])
        means.append(float(np.mean(lengths)))
        now = lengths < NEAR_DUPLICATE_SHARE * means[-1]
        short = now if short is None else short & now
        if not short.any():
            return None
    n = topology.n_vertices
    labels = vertex_groups(edges[short, 0], edges[short, 1], n)
    _, kept, copies = np.unique(labels, return_index=True, return_inverse=True)
    copies = copies.ravel()
    members = np.flatnonzero(kept[copies] != np.arange(n))
    # each cluster no wider than the share from its representative in every key: a chain of tiny
    # edges spanning the mesh's scale is no one place
    wide = np.zeros(n, dtype=bool)
    for key, mean in zip(keys, means):
        far = np.linalg.norm(key[members] - key[kept[copies[members]]], axis=1) >= NEAR_DUPLICATE_SHARE * mean
        wide[copies[members[far]]] = True
    if wide.any():  # those clusters' vertices each on its own
        apart = wide[copies]
        labels = np.where(apart, labels.max() + 1 + np.arange(n), labels)
        _, kept, copies = np.unique(labels, return_index=True, return_inverse=True)
        copies = copies.ravel()
        members = np.flatnonzero(kept[copies] != np.arange(n))
    if not members.size:
        return None
    triangles = copies[topology.triangles]
    sorted_corners = np.sort(triangles, axis=1)
    whole = (np.diff(sorted_corners, axis=1) != 0).all(axis=1)
    triangles = triangles[whole]
    clustered = np.unique(copies[members])  # merged indices of the representatives
    if np.isin(clustered, triangles.ravel(), invert=True).any():  # a cluster that is a whole piece
        return None
    if len(np.unique(sorted_corners[whole], axis=0)) < len(triangles):  # two triangles onto one
        return None
    try:
        merged = mesh_topology(triangles, kept.size, allow_bow_ties=True)
        check_manifold_vertices(merged)
    except MeshError:
        return None
    # the representatives' rings: each with its neighbours in the merged mesh
    ring_edges = merged.edges
    at = np.searchsorted(clustered, ring_edges)
    hit = clustered[np.minimum(at, clustered.size - 1)] == ring_edges
    rings = np.r_[clustered, ring_edges[:, 1][hit[:, 0]], ring_edges[:, 0][hit[:, 1]]]
    ring_of = np.r_[np.arange(clustered.size), at[:, 0][hit[:, 0]], at[:, 1][hit[:, 1]]]
    return NearDuplicates(kept, copies, triangles, whole, merged, members, np.searchsorted(clustered, copies[members]),
                          np.stack([key[members] for key in keys]), rings, ring_of)
