"""Parts of a piece that spin past a half turn about the piece's turn axis between two keys, read
from patches of the mesh (paper §5.3's rotations between poses, §8.4's in-betweens).

A tube twirled at one end (a skirt whose waist turns back while its hem spins on) can turn its far
part more than a half turn between keys from the rest of it. The in-betweens read each triangle's
turn between the keys the short way round, continued across the mesh only where neighbouring
triangles turn alike (:meth:`core.inbetween_whole_rotations.WholeRotations.turning`); a wrung
cloth's wrinkles part neighbours by tens of degrees everywhere, so nothing is continued and the
spun part goes the short way round, against the rest. Patches of many triangles smooth the
wrinkles out: where their centroids' turns about the piece's rigid turn axis, taken continuous from
patch to patch, put a part past a half turn from the least-turned patch, the keys read the short way
round there disagree with the mesh's own continuity, and the gap warns
(:class:`SpunParts`; :func:`core.sequence_turn_readings.turn_warnings` words it).

:func:`spin_patches` cuts a pose into patches (``vertices`` float64 (n, 3), ``triangles`` int
(m, 3)); :func:`patch_turns` reads the patches' turns between two keys (:func:`principal_turns`
the short way round, :func:`continued_turns` continuous across the mesh), :func:`spun_shares` the
share of each piece spun past a half turn, :func:`turned_back` the share an in-between turns back
the short way round (two poses: :class:`~core.two_pose_inbetweens.Interpolator`);
:class:`SpunParts` reads them per gap of a sequence, where patches that all turn less than a right
angle (:func:`within_right_angle`: every gap of the benchmark's 10k cloths at keys 4 frames apart)
decide it without the continuation.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial.transform import Rotation

#: About how many patches :func:`spin_patches` cuts a mesh into: cells of a grid whose side is the
#: square root of the surface's area over this, split where the mesh leaves a cell and comes back
#: (a fold's layers in one cell are different patches). The spun share of the twirled 40k skirt's
#: gap (keys 16 frames apart) is 0.361 / 0.371 / 0.366 / 0.371 with 158 / 380 / 1,461 / 3,385
#: patches; no gap of the benchmark's or seven unseen bakes' cloths reaches 0.02 with 256.
SPIN_PATCHES = 256
#: ... but no more than one per this many vertices: a patch of a few vertices turns with each
#: wrinkle (a sheet of 150 vertices spinning 193° about its corner while it folds, its cells one
#: vertex each, read 13 % of it past a half turn from its least-turned part where its in-betweens
#: are right; none with patches of 16).
SPIN_PATCH_VERTICES = 16
#: Patches whose centroid comes nearer the piece's turn axis than this share of the patches' RMS
#: distance from it (in either key) have no turn about it to read (a patch on the axis turns by
#: any angle with it) and are left out.
SPIN_AXIS_NEAR = 0.25


def spin_patches(vertices: np.ndarray, triangles: np.ndarray, count: int | None = None) -> tuple:
    """Patches of the mesh (``vertices`` float64 (n, 3), ``triangles`` int (m, 3)) in the pose
    given: the cells of a grid of about ``count`` cells over its surface (None:
    :data:`SPIN_PATCHES`, at most one per :data:`SPIN_PATCH_VERTICES` vertices), each split into
    the parts the mesh's edges join within it. Returns each vertex's patch (int (n,); a vertex in no
    triangle is a patch of its own), the pairs of patches an edge joins (int (E, 2), each once,
    first < second) and the number of patches."""
    n = len(vertices)
    count = max(1, min(SPIN_PATCHES, n // SPIN_PATCH_VERTICES)) if count is None else count
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    sides = np.cross(vertices[triangles[:, 1]] - vertices[triangles[:, 0]],
                     vertices[triangles[:, 2]] - vertices[triangles[:, 0]])
    area = 0.5 * np.sqrt(np.einsum("ij,ij->i", sides, sides)).sum()
    side = np.sqrt(area / count) if area > 0 else 1.0
    cells = np.floor((vertices - vertices.min(axis=0, initial=0.0)) / side).astype(np.int64)
    span = cells.max(axis=0, initial=0) + 1  # each cell one integer (unique on rows sorts 20× slower)
    cell = np.unique(cells[:, 0] + span[0] * (cells[:, 1] + span[1] * cells[:, 2]), return_inverse=True)[1].ravel()
    inside = edges[cell[edges[:, 0]] == cell[edges[:, 1]]]
    graph = sp.coo_matrix((np.ones(len(inside)), (inside[:, 0], inside[:, 1])), shape=(n, n))
    patches, labels = csgraph.connected_components(graph, directed=False)
    first, second = labels[edges[:, 0]], labels[edges[:, 1]]
    across = first != second
    joined = np.unique(np.minimum(first, second)[across].astype(np.int64) * patches + np.maximum(first, second)[across])
    return labels, np.stack([joined // patches, joined % patches], axis=1), patches


def spun_shares(base: np.ndarray, other: np.ndarray, weights: np.ndarray, owner: np.ndarray, patches: tuple,
                rotations: np.ndarray, translations: np.ndarray,
                keys: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per piece (C,), the share of its weight whose turn about the piece's rigid turn axis from
    key ``base`` to key ``other`` (vertices (n, 3) each) is past a half turn from its least-turned
    part, and its largest turn from there (radians); arguments as :func:`patch_turns`, ``keys`` its
    reading of ``base`` to ``other`` where the caller keeps it (None: read here). A piece that
    turns as one (a half turn included: its patches a rounding either side of it) has none."""
    turn, least, known, piece, mass, _ = patch_turns(base, other, weights, owner, patches, rotations, translations) \
        if keys is None else keys
    pieces = len(rotations)
    beyond = np.abs(turn) - least
    past = known & (beyond > np.pi)
    total = np.maximum(np.bincount(piece[known], mass[known], minlength=pieces), np.finfo(float).tiny)
    share = np.bincount(piece[past], mass[past], minlength=pieces) / total
    largest = np.zeros(pieces)
    np.maximum.at(largest, piece[known], beyond[known])
    return share, largest


def turned_back(base: np.ndarray, other: np.ndarray, pose: np.ndarray, factor: float, weights: np.ndarray,
                owner: np.ndarray, patches: tuple, rotations: np.ndarray,
                translations: np.ndarray, keys: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per piece (C,), the share of its weight spun past a half turn from its least-turned part
    between key ``base`` and key ``other`` (:func:`spun_shares`) that an in-between ``pose``
    (vertices (n, 3)) at ``factor`` (0 < factor < 1) turns back the short way round: its patches
    turned about the piece's rigid turn axis nearer ``factor`` × their turn less a whole turn than
    ``factor`` × their turn (more than ``min(factor, 1 − factor)`` × π from it); and that part's
    largest turn from the least-turned one (radians). Other arguments as :func:`spun_shares`."""
    turn, least, known, piece, mass, _ = patch_turns(base, other, weights, owner, patches, rotations, translations) \
        if keys is None else keys
    labels, pairs, count = patches
    # the pose's principal turns about the same axes (none taken across the mesh: only compared)
    at, _, seen, *_ = patch_turns(base, pose, weights, owner, (labels, pairs[:0], count), rotations, translations)
    beyond = np.abs(turn) - least
    back = known & seen & (beyond > np.pi) & \
        (np.abs(_wrapped(at - factor * turn)) > min(factor, 1.0 - factor) * np.pi)
    pieces = len(rotations)
    total = np.maximum(np.bincount(piece[known], mass[known], minlength=pieces), np.finfo(float).tiny)
    share = np.bincount(piece[back], mass[back], minlength=pieces) / total
    largest = np.zeros(pieces)
    np.maximum.at(largest, piece[back], beyond[back])
    return share, largest


def patch_turns(base: np.ndarray, other: np.ndarray, weights: np.ndarray, owner: np.ndarray, patches: tuple,
                rotations: np.ndarray, translations: np.ndarray) -> tuple:
    """How far each patch turns about its piece's rigid turn axis from key ``base`` to key
    ``other`` (vertices (n, 3) each). ``weights``: the vertices' masses (n,); ``owner``: each
    vertex's piece (n,; −1 in none); ``patches``: :func:`spin_patches`; ``rotations`` (C, 3, 3),
    ``translations`` (C, 3): the pieces' rigid fits from ``base`` to ``other``. Each patch's
    weighted centroid turns about the axis of its piece's fit by an angle the keys give the short
    way round (:func:`principal_turns`); those angles are taken continuous from patch to patch along the tree of the
    smallest steps between neighbours, each tree's weight-median patch within a half turn of
    none (:func:`continued_turns`). Returns the turns (P,; radians, about the axes), the least turn's size in each patch's tree (P,; its own where it is
    in none), whether each is read (bool (P,): a patch near the axis, of no
    weight or of a piece that does not turn is not), each patch's piece (P,; −1 in none), its
    weight (P,) and the pieces' unit axes (C, 3)."""
    return continued_turns(principal_turns(base, other, weights, owner, patches, rotations, translations), patches)


def principal_turns(base: np.ndarray, other: np.ndarray, weights: np.ndarray, owner: np.ndarray, patches: tuple,
                    rotations: np.ndarray, translations: np.ndarray) -> tuple:
    """The first part of :func:`patch_turns` (same arguments): each patch's turn about its piece's
    rigid turn axis the short way round (P,; radians, in [−π, π]), not yet taken continuous across
    the mesh; then, as :func:`patch_turns` returns them, whether each is read, each patch's piece,
    its weight and the pieces' unit axes."""
    labels, pairs, count = patches
    pieces = len(rotations)
    mass = np.bincount(labels, weights, minlength=count)
    piece = np.full(count, -1)
    piece[labels] = owner
    centroids = [np.stack([np.bincount(labels, weights * x[:, k], minlength=count) for k in range(3)], axis=1)
                 / np.maximum(mass, np.finfo(float).tiny)[:, None] for x in (base, other)]
    # each piece's turn axis (unit) and a point on it: the fit x ↦ R x + t turns about the line
    # through c with (I − R) c = t − (t·a) a
    vectors = Rotation.from_matrix(rotations).as_rotvec().reshape(-1, 3)
    angle = np.sqrt(np.einsum("ij,ij->i", vectors, vectors))
    axis = vectors / np.maximum(angle, np.finfo(float).tiny)[:, None]
    along = translations - np.einsum("ij,ij->i", translations, axis)[:, None] * axis
    point = np.einsum("kab,kb->ka", np.linalg.pinv(np.eye(3) - rotations), along)
    known = (piece >= 0) & (mass > 0)
    known[known] = angle[piece[known]] > 0
    a, c = axis[np.maximum(piece, 0)], point[np.maximum(piece, 0)]
    offsets = []
    for x in centroids:
        d = x - c
        offsets.append(d - np.einsum("ij,ij->i", d, a)[:, None] * a)
    radius = np.minimum(*(np.sqrt(np.einsum("ij,ij->i", d, d)) for d in offsets))
    spread = np.sqrt(np.bincount(piece[known], mass[known] * radius[known] ** 2, minlength=pieces)
                     / np.maximum(np.bincount(piece[known], mass[known], minlength=pieces), np.finfo(float).tiny))
    known &= radius > SPIN_AXIS_NEAR * spread[np.maximum(piece, 0)]
    turn = np.arctan2(np.einsum("ij,ij->i", np.cross(offsets[0], offsets[1]), a),
                      np.einsum("ij,ij->i", offsets[0], offsets[1]))
    return turn, known, piece, mass, axis


def continued_turns(principal: tuple, patches: tuple) -> tuple:
    """:func:`patch_turns` from its first part ``principal`` (:func:`principal_turns`) of the same
    ``patches``: the read patches' turns taken continuous across the pairs of read patches."""
    turn, known, piece, mass, axis = principal
    _, pairs, count = patches
    turn, least = _continued(turn, pairs[known[pairs[:, 0]] & known[pairs[:, 1]]], count, mass)
    return turn, least, known, piece, mass, axis


def within_right_angle(principal: tuple) -> bool:
    """Whether no read patch of :func:`principal_turns`' reading ``principal`` turns past a right
    angle: then no part of any piece spins past a half turn from its least-turned part
    (:func:`spun_shares` gives 0 for every piece), which is decided without taking the turns
    continuous. Neighbours turning less than a right angle each way differ by less than a half
    turn, so the continuation adds each step as it is (to rounding, 1e-15 per step), leaves every
    turn its principal value and no tree a whole turn to shift: every turn stays within a right
    angle of none, and so within a half turn of the least."""
    turn, known = principal[0], principal[1]
    return not (np.abs(turn[known]) >= 0.5 * np.pi).any()


def _wrapped(angles: np.ndarray) -> np.ndarray:
    """``angles`` (radians) taken within a half turn of none, in [−π, π)."""
    return (angles + np.pi) % (2 * np.pi) - np.pi


def _continued(turn: np.ndarray, pairs: np.ndarray, count: int, mass: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The patches' turns (``count``,; radians, principal) taken continuous across ``pairs`` (E, 2)
    along a minimum spanning tree of their principal steps (each patch the representative nearest
    its parent's), each tree shifted by whole turns so that its weight-median patch (``mass``
    (``count``,)) is within a half turn of none; patches in no pair as given, and so are the trees
    whose continued turns leave two neighbours more than a half turn apart. Also the size of each tree's least turn
    (``count``,; a patch given as is its own)."""
    out = turn.copy()
    least = np.abs(turn)
    if not len(pairs):
        return out, least
    steps = np.abs(_wrapped(turn[pairs[:, 1]] - turn[pairs[:, 0]])) + np.finfo(float).eps
    tree = csgraph.minimum_spanning_tree(sp.coo_matrix((steps, (pairs[:, 0], pairs[:, 1])), shape=(count, count)))
    tree = tree + tree.T
    trees, member = csgraph.connected_components(tree, directed=False)
    sizes = np.bincount(member, minlength=trees)
    for linked in np.flatnonzero(sizes > 1):  # a patch alone keeps its principal turn
        order, parent = csgraph.breadth_first_order(tree, np.flatnonzero(member == linked)[0], directed=False)
        for patch in order[1:]:
            out[patch] = out[parent[patch]] + _wrapped(turn[patch] - turn[parent[patch]])
        # whole turns the tree picks up along a chain of patches turning near a half turn (a flag's
        # free end swinging across the axis) are no turn of the rest: the shift takes the
        # weight-median patch, not the least-turned one, within a half turn of none
        by_turn = order[np.argsort(out[order])]
        running = np.cumsum(mass[by_turn])
        middle = by_turn[min(np.searchsorted(running, 0.5 * running[-1]), len(by_turn) - 1)]
        out[order] -= 2 * np.pi * np.round(out[middle] / (2 * np.pi))
        least[order] = np.abs(out[order]).min()
    # a tree whose turns, so continued, leave neighbours more than a half turn apart winds round
    # (a crumpled bundle's loops of patches): its way round is not read, it keeps the principal turns
    wound = np.zeros(trees, dtype=bool)
    wound[member[pairs[np.abs(out[pairs[:, 1]] - out[pairs[:, 0]]) > np.pi, 0]]] = True
    out[wound[member]] = turn[wound[member]]
    least[wound[member]] = np.abs(turn[wound[member]])
    return out, least


class SpunParts:
    """Per gap of a sequence, how far a part of a piece spins past a half turn about the piece's
    turn axis, read from the keys' patches (:func:`spun_shares`); mixed into
    :class:`~core.sequence_inbetweens.SequenceInterpolator`.

    Reads the interpolator's ``_cache_lock``, ``_raw``, ``_topo`` and calls its ``_fits``."""

    _spin_patches = None  # spin_patches of the first key, made on first use
    _spin_turns = None  # per gap, patch_turns of its keys (a dict made on first use)
    _spin_principal = None  # per gap, principal_turns of its keys until patch_turns continues them

    def _key_patches(self) -> tuple:
        """:func:`spin_patches` of the first key (made once, on first use)."""
        with self._cache_lock:
            if self._spin_patches is None:
                self._spin_patches = spin_patches(self._raw[0], self._topo.triangles)
        return self._spin_patches

    def _principal_turns(self, gap: int) -> tuple:
        """:func:`principal_turns` of key ``gap`` to the next, read once per gap (kept until
        :meth:`_key_turns` continues them)."""
        with self._cache_lock:
            if self._spin_principal is None:
                self._spin_principal = {}
            known = self._spin_principal.get(gap)
        if known is None:
            rotations, translations, _ = self._fits(gap, gap + 1)
            known = principal_turns(self._raw[gap], self._raw[gap + 1], self._topo.weights, self._topo.vertex_owner,
                                    self._key_patches(), rotations, translations)
            with self._cache_lock:
                self._spin_principal[gap] = known
        return known

    def _key_turns(self, gap: int) -> tuple:
        """:func:`patch_turns` of key ``gap`` to the next, read once per gap: the gap's spun check
        and every in-between of two poses (:meth:`core.two_pose_inbetweens.Interpolator.pose`)
        compare with it."""
        with self._cache_lock:
            if self._spin_turns is None:
                self._spin_turns = {}
            known = self._spin_turns.get(gap)
        if known is None:
            known = continued_turns(self._principal_turns(gap), self._key_patches())
            with self._cache_lock:
                self._spin_turns[gap] = known
                self._spin_principal.pop(gap, None)
        return known

    def _spun(self, gap: int, skipped: np.ndarray) -> tuple[float, float]:
        """The largest share of a piece's area spun past a half turn from the rest of it between
        key ``gap`` and the next, and that piece's largest turn from its least-turned part
        (radians), over the pieces not ``skipped`` (bool (C,): the gap takes their turns continuous
        across the mesh, or warns that they turn past a half turn across a fold). ``(0.0, 0.0)``
        where no patch turns past a right angle (:func:`within_right_angle`: no share to warn of,
        the turns not taken continuous)."""
        with self._cache_lock:
            continued = self._spin_turns is not None and gap in self._spin_turns
        if not continued and within_right_angle(self._principal_turns(gap)):
            return 0.0, 0.0
        rotations, translations, _ = self._fits(gap, gap + 1)
        share, largest = spun_shares(self._raw[gap], self._raw[gap + 1], self._topo.weights, self._topo.vertex_owner,
                                     self._key_patches(), rotations, translations, self._key_turns(gap))
        share[skipped] = 0.0
        worst = int(np.argmax(share))
        return float(share[worst]), float(largest[worst])
