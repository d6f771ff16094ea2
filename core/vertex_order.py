"""Whether positions read for a mesh keep its vertices' order (a cache exported from the same mesh)
or scatter its neighbours (a cache of another mesh with as many vertices, or of this one with its
vertices renumbered: sorted, re-imported, remeshed to the same count).

The test is scale-free and needs no correspondence. For each connected part of the mesh (joined by
the edges given), ``S`` is the mean squared distance between two of its vertices (twice the trace
of their covariance), and each edge counts ``|edge|² / S``: how long it is against its part's size.
:meth:`EdgeSpread.growth` is the root of the median over the edges of the ratio of these, in the
positions read and in the mesh at rest: how many times more the edges grew than the parts they make
up. Moving, turning or scaling a part leaves it at 1; a surface that stretches grows its part with
it; one that folds or crumples shrinks its part while its edges keep their length, and that is all
a motion can do to it: in 124 cloth, rig and deformer sequences measured (docs/pipeline.md) at most
2.4 against any of their frames as rest, and 2.9 where Blender's cloth collapsed a shrinking tube
onto its axis for one frame. Positions in another vertex order put the two ends of an edge as far
apart as two vertices taken at random, ``|edge|² ≈ S``: the growth is then about the number of
edges across a part (9–10 on a 400-vertex sheet, 30–100 at 10k). :data:`FOREIGN_GROWTH` lies
between; a mesh whose parts are too coarse to exceed it (under about 150 vertices, or many small
rigid pieces) cannot be told this way.

Growth alone also rises where a long part is wound up tight (a rope coiled three times 5.6, a
carpet rolled up 6–8): its edges keep their length while its size shrinks many times. Such a part
still has edges far shorter than its size, which no other order keeps: :meth:`EdgeSpread.scattered`
asks, besides, that the edges' median ``|edge|² / S`` in the positions read be at least
:data:`SCATTERED_SPAN` (a rope packed into a ball ~``V^(-2/3)``, under 0.01 at a few thousand vertices;
two random vertices of a line 0.5, of a sheet about 0.8).

A narrow part wound up tight enough passes both: a low-poly strap two or four vertices wide rolled
round an inner turn one edge across (a tape measure retracting, a scroll rolled up) packs its
vertices within a few edges of each other, so its edges are a third of its size and more (median
``|edge|² / S`` 0.11–0.18, growth 6–8), as in another order. What a motion keeps there, and another
order does not, is each edge's length against the others': :meth:`EdgeSpread.scattered` asks, last,
that the edges' lengths changed unevenly, the median over the edges of ``|log(|edge| / |edge at
rest|)|`` from its part's median at least :data:`UNEVEN_LENGTHS` (such straps 0.002–0.09, the most
with their vertices jittered by a tenth of an edge; a ball squashed to a fifth 0.11; the same
positions in a random order 0.27–0.37, as the distances between random vertices of a roll or a
ball spread, and 0.35–0.44 on a sheet).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .geometry import connected_components

#: Edges grown this many times more than their parts (:meth:`EdgeSpread.growth`): positions that
#: cannot be the mesh's vertices in its order. Above the most a motion gave (2.9), below what a
#: random order gives on a part of 400 vertices (9).
FOREIGN_GROWTH = 5.0

#: The median ``|edge|² / S`` (:meth:`EdgeSpread.scattered`) from which edges are as long as the
#: parts they make up: a third of the part's spread; two vertices taken at random give 0.5 or more.
SCATTERED_SPAN = 0.1

#: The median ``|log(|edge| / |edge at rest|)|`` from its part's median (:meth:`EdgeSpread.scattered`)
#: from which the edges' lengths changed as unevenly as another order changes them: between what a
#: motion winding a part up tight gives (a cloth stretches its edges a few per cent; 0.09 with the
#: vertices jittered by a tenth of an edge) and the spread of the distances between random vertices
#: of a part (0.27 and more on a tight roll or a ball, the least spread; more on a sheet or a line).
UNEVEN_LENGTHS = 0.15

#: Edges whose growth is measured, at most (a fixed sample of them: the median of 30,000 is within
#: about 1 % of all edges'), so that a frame of a 100k-vertex mesh costs a few milliseconds.
SAMPLED_EDGES = 30_000


class EdgeSpread:
    """The rest mesh's edges against its parts' sizes, to compare positions read with
    (:meth:`growth`). ``rest``: float ``(n, 3)``; ``edges``: int ``(E, 2)``, those of faces
    (loose edges join nothing a surface keeps). Parts whose vertices all coincide at rest have no
    size and are left out."""

    def __init__(self, rest: np.ndarray, edges: np.ndarray):
        rest = np.asarray(rest, dtype=np.float64)
        self.edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
        self.count, self.labels = connected_components(len(rest), self.edges)
        if len(self.edges) > SAMPLED_EDGES:
            self.edges = self.edges[np.random.default_rng(0).choice(len(self.edges), SAMPLED_EDGES, replace=False)]
        self.rest_terms = self._terms(rest)
        self.rest_squared = self._squared(rest)

    def _squared(self, positions: np.ndarray) -> np.ndarray:
        """The squared length of each edge in ``positions``."""
        return ((positions[self.edges[:, 0]] - positions[self.edges[:, 1]]) ** 2).sum(axis=1)

    def _terms(self, positions: np.ndarray) -> np.ndarray:
        """|edge|² / the mean squared distance between two vertices of its part (twice the trace
        of their covariance), per edge; NaN where the part has no size (its vertices coincide)."""
        counts = np.bincount(self.labels, minlength=self.count).astype(np.float64)
        centred = positions - np.stack([np.bincount(self.labels, positions[:, d], self.count)
                                        for d in range(3)], axis=1)[self.labels] / counts[self.labels, None]
        sizes = 2.0 * np.bincount(self.labels, (centred ** 2).sum(axis=1), self.count) / counts
        squared = self._squared(positions)
        size = sizes[self.labels[self.edges[:, 0]]]
        with np.errstate(divide='ignore', invalid='ignore'):
            return np.where(size > 0, squared / size, np.nan)

    def growth(self, positions: np.ndarray) -> float:
        """How many times more the edges grew than their parts, from the rest mesh to
        ``positions`` ``(n, 3)``: the median over the edges of parts with a size in both (a few
        edges a simulation tangles do not count), :func:`edge_growth`; 1.0 where there is none."""
        return self._growth(self._terms(np.asarray(positions, dtype=np.float64)))

    def _growth(self, terms: np.ndarray) -> float:
        """:meth:`growth` from the positions' :meth:`_terms`."""
        kept = np.isfinite(terms) & (self.rest_terms > 0)
        return float(np.sqrt(np.median(terms[kept] / self.rest_terms[kept]))) if kept.any() else 1.0

    def scattered(self, positions: np.ndarray) -> bool:
        """Whether ``positions`` ``(n, 3)`` put the mesh's neighbours as far apart as vertices
        taken at random: edges grown over :data:`FOREIGN_GROWTH` times more than their parts
        (:meth:`growth`), in ``positions`` as long as those parts (the median ``|edge|² / S`` at
        least :data:`SCATTERED_SPAN`; a part wound up tight grows its edges without that), and
        their lengths changed unevenly (:meth:`uneven_lengths` at least :data:`UNEVEN_LENGTHS`; a
        narrow strip wound up tight has its edges as long as its size, each as long as it was)."""
        positions = np.asarray(positions, dtype=np.float64)
        terms = self._terms(positions)
        if self._growth(terms) <= FOREIGN_GROWTH:
            return False
        terms = terms[np.isfinite(terms)]
        if not terms.size or float(np.median(terms)) < SCATTERED_SPAN:
            return False
        return self.uneven_lengths(positions) >= UNEVEN_LENGTHS

    def uneven_lengths(self, positions: np.ndarray) -> float:
        """How unevenly the edges' lengths changed from the rest mesh to ``positions`` ``(n, 3)``:
        the median over the edges of ``|log(|edge| / |edge at rest|)|`` from the median of its
        part's (a part moved, turned, scaled or wound up with its edges kept reads 0; another
        vertex order, the spread of the distances between random vertices). Edges of length 0 in
        either are left out; 0.0 where none is left."""
        with np.errstate(divide='ignore', invalid='ignore'):
            logs = 0.5 * np.log(self._squared(np.asarray(positions, dtype=np.float64)) / self.rest_squared)
        kept = np.isfinite(logs)
        if not kept.any():
            return 0.0
        parts = self.labels[self.edges[kept, 0]]
        medians = np.asarray(ndimage.median(logs[kept], labels=parts, index=np.arange(self.count)))
        return float(np.median(np.abs(logs[kept] - medians[parts])))


def edge_growth(rest: np.ndarray, positions: np.ndarray, edges: np.ndarray) -> float:
    """How many times more the ``edges`` grew than the parts they make up, from ``rest`` to
    ``positions`` (the module's docstring): about 1 for a motion of the mesh, up to about 3 where
    it folds or crumples; far beyond :data:`FOREIGN_GROWTH` for positions in another vertex order."""
    return EdgeSpread(rest, edges).growth(positions)
