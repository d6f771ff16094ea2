"""Embedding of the canonical thickening by gluing triangle frames across hinges (paper §7.3,
proof of Prop. 4).

Every triangle ``T`` of the base with its face-center point ``c_T`` is a rigid tetrahedron whose
shape follows from its three squared edge lengths and the offset ``t`` alone (``c_T`` sits above
the barycenter at height ``t``): it has a local frame. Across an interior edge ``(a, b)`` the
offset edge ``|c_T1 − c_T2|`` fixes the angle between the two frames up to its sign — the two
mirror shapes of the mesh-edge tetrahedron ``(a, b, c_T1, c_T2)`` (the dihedral folds up or down by
the same amount). The lifted vertices ``a_t`` decide the signs: around each vertex, only the true
sign pattern closes the fan of frames and puts ``a_t`` at its distances from ``a`` and from all
the face centers. So:

1. **local frames**: corners and face center of every triangle in a frame of its own;
2. **hinges**: for each interior edge both rigid maps between the two frames (±angle);
3. **signs**: every vertex star tries all sign patterns of its hinges (vectorized over stars of
   the same valence, depth-first so shared prefixes are composed once) and scores each by fan
   closure and by the trilateration residual of ``a_t``; each hinge then takes the sign its two
   stars prefer (log-likelihood-like vote: the ratio of the best residuals with either sign);
4. **gluing**: frames are composed along a breadth-first tree of the dual graph; every vertex is
   the mean of its corners' positions. Rotations compose stably, so round-off grows only linearly
   with the tree depth — unlike trilateration, whose errors are amplified at every step.

With exact lengths this is exact to round-off (~1e-12 on 50k-vertex sheets). It needs no
orientation assumption beyond the upward tetrahedra (``c_T`` on the normal side of ``T``). Hinges
no star can decide (both signs fit: a valence ≤ 2 boundary fan, a flat valence-4 star) keep the
sign of a positively oriented mesh-edge tetrahedron and are counted as ``unresolved``; the
caller checks the residuals of the result and falls back to other initializers when needed.
"""

from __future__ import annotations

import numpy as np

from .geometry import connected_components, nearest_rotations, normalize, rows_dot
from .offset_surface import OffsetSurface

#: Largest number of hinges of one star whose sign patterns are enumerated (2^k patterns).
MAX_STAR_HINGES = 12
#: Residual floor of the sign votes: differences below it are round-off, not evidence.
VOTE_FLOOR = 1e-11
#: Rows (star × sign pattern) scored per batch.
PATTERN_BATCH = 1 << 16
#: Sign patterns whose fan fails to close by more than this (relative) skip the trilateration.
CLOSURE_GATE = 1e-3
#: A hinge whose vote is weaker than this factor (both signs fit about equally) is unresolved.
DECISIVE_RATIO = 10.0
#: One star's log-ratio vote is clipped to ± this, so that a star with a zero residual cannot
#: outvote all others.
VOTE_CLIP = 50.0
#: Hinges whose two signed rotations differ by less than this (Frobenius) are flat: both signs
#: give the same frames, so they are not ambiguous.
FLAT_HINGE = 1e-6
#: Relative Tikhonov term keeping the star trilateration solvable for coplanar anchors.
TRILATERATION_DAMPING = 1e-12
#: Weight (relative to the mean diagonal) pinning the synchronized frames and vertices to the
#: tree's: fixes the global gauge without pulling the least-squares fit.
SYNCHRONIZATION_PIN = 1e-8


class HingeFrameEmbedding:
    """``points`` float64 ``(n + n_offset, 3)`` glued along a tree; ``unresolved`` hinges whose
    sign no star decided (their dihedral is ~0 or the lengths leave them flexible);
    :meth:`synchronized` the least-squares gluing over all hinges (for inexact lengths)."""

    def __init__(self, surface, local, hinges, sign, rotation, shift, offset, unresolved):
        self._surface, self._local, self._hinges, self._sign = surface, local, hinges, sign
        self._rotation, self._shift, self._offset = rotation, shift, offset
        self.unresolved = unresolved
        self.points = _thickening_points(surface, local, rotation, shift, offset)

    def synchronized(self) -> np.ndarray:
        """Thickening points from frames that fit every hinge in the least-squares sense
        (rotation synchronization, then a Poisson solve for the vertices), instead of the tree's
        exact chain: inexact hinge angles average out rather than accumulate along tree paths."""
        return _synchronized_points(self._surface, self._local, self._hinges, self._sign, self._rotation,
                                    self.points[: self._surface.base.n_vertices], self._offset)


def triangle_local_points(triangle_squared: np.ndarray, offset: float) -> np.ndarray:
    """Corners and face center of every triangle in its own frame, float64 ``(m, 4, 3)``.

    ``triangle_squared`` ``(m, 3)``: squared lengths of the edges opposite corners 0, 1, 2.
    Corner 0 at the origin, corner 1 on +x, corner 2 in the upper half of the xy-plane (so the
    normal is +z), the center at the barycenter lifted by ``offset`` (as in Fig. 5)."""
    opp0, opp1, opp2 = triangle_squared.T
    l01 = np.sqrt(opp2)
    x2 = (opp2 + opp1 - opp0) / (2.0 * np.maximum(l01, np.finfo(float).tiny))
    y2 = np.sqrt(np.maximum(opp1 - x2 * x2, 0.0))
    m = triangle_squared.shape[0]
    local = np.zeros((m, 4, 3))
    local[:, 1, 0] = l01
    local[:, 2, 0], local[:, 2, 1] = x2, y2
    local[:, 3] = np.stack([(l01 + x2) / 3.0, y2 / 3.0, np.full(m, offset)], axis=1)
    return local


def _edge_frame(a, b, c):
    """Orthonormal frames ``[u, w, u × w]`` (…, 3, 3 columns) of hinge axis ``u = (b − a)/|b − a|``
    and the direction ``w`` from the axis to ``c``; also ``c``'s axial coordinate and radius."""
    u, _ = normalize(b - a)
    d = c - a
    s = rows_dot(d, u)
    w, rho = normalize(d - s[..., None] * u)
    return np.stack([u, w, np.cross(u, w)], axis=-1), s, rho


class _Hinges:
    """Rigid maps between the frames of the two triangles of every interior edge, both signs.

    ``rotation[h, sign]`` ``(H, 2, 3, 3)`` and ``shift[h, sign]`` ``(H, 2, 3)`` map points of the
    second triangle's frame to the first's (``x ↦ R x + s``); sign index 0 is the positively
    oriented mesh-edge tetrahedron ``(a, b, c_T1, c_T2)``, 1 its mirror."""

    def __init__(self, surface: OffsetSurface, local: np.ndarray, center_squared: np.ndarray):
        base = surface.base
        self.edges = base.interior_edges
        a, b = base.edges[self.edges, 0], base.edges[self.edges, 1]
        self.first, self.second = base.edge_triangles[self.edges, 0], base.edge_triangles[self.edges, 1]
        tris = base.triangles
        pick = lambda t, v: local[t, np.argmax(tris[t] == v[:, None], axis=1)]  # noqa: E731
        frame1, s1, rho1 = _edge_frame(pick(self.first, a), pick(self.first, b), local[self.first, 3])
        frame2, s2, rho2 = _edge_frame(pick(self.second, a), pick(self.second, b), local[self.second, 3])
        cos = (rho1**2 + rho2**2 + (s1 - s2) ** 2 - center_squared) / np.maximum(2 * rho1 * rho2, np.finfo(float).tiny)
        angle = np.arccos(np.clip(cos, -1.0, 1.0))
        H = self.edges.size
        self.rotation = np.empty((H, 2, 3, 3))
        self.shift = np.empty((H, 2, 3))
        a1, a2 = pick(self.first, a), pick(self.second, a)
        for k, signed in enumerate((angle, -angle)):
            c, s = np.cos(signed), np.sin(signed)
            turn = np.zeros((H, 3, 3))
            turn[:, 0, 0] = 1.0
            turn[:, 1, 1], turn[:, 1, 2], turn[:, 2, 1], turn[:, 2, 2] = c, -s, s, c
            rotation = frame1 @ turn @ np.transpose(frame2, (0, 2, 1))
            self.rotation[:, k] = rotation
            self.shift[:, k] = a1 - np.einsum("hij,hj->hi", rotation, a2)

    def maps(self, hinge: np.ndarray, sign: np.ndarray, toward_first: np.ndarray):
        """Rigid maps (R ``(…, 3, 3)``, s ``(…, 3)``) of the given hinges and signs, from the other
        triangle's frame to the first's where ``toward_first``, else the inverse."""
        rotation, shift = self.rotation[hinge, sign], self.shift[hinge, sign]
        inverse_rotation = np.swapaxes(rotation, -1, -2)
        inverse_shift = -np.einsum("...ij,...j->...i", inverse_rotation, shift)
        keep = toward_first[..., None]
        return np.where(keep[..., None], rotation, inverse_rotation), np.where(keep, shift, inverse_shift)


def _pair_lookup(pairs: np.ndarray, n: int):
    """Find rows of ``pairs`` ``(P, 2)`` (unordered) from query pairs: returns a function."""
    pairs = np.asarray(pairs, dtype=np.int64)
    keys = np.minimum(pairs[:, 0], pairs[:, 1]) * n + np.maximum(pairs[:, 0], pairs[:, 1])
    order = np.argsort(keys)
    sorted_keys = keys[order]

    def find(i: np.ndarray, j: np.ndarray) -> np.ndarray:
        i, j = np.asarray(i, dtype=np.int64), np.asarray(j, dtype=np.int64)
        q = np.minimum(i, j) * n + np.maximum(i, j)
        pos = np.clip(np.searchsorted(sorted_keys, q), 0, len(sorted_keys) - 1)
        return np.where(sorted_keys[pos] == q, order[pos], -1)

    return find


def _fans(surface: OffsetSurface, hinge_of_edge: np.ndarray):
    """Ordered fans of the base vertices that have a lifted vertex. Yields per group of equal
    size and type: (vertices (S,), triangles (S, k), corner slots (S, k), hinges (S, h),
    toward_first (S, h), closed)."""
    base = surface.base
    tris, m = base.triangles, base.n_triangles
    corner_vertex = tris.ravel()
    corner_tri = np.repeat(np.arange(m), 3)
    corner_slot = np.tile(np.arange(3), m)
    # The edge (a, w) after corner (T, a) in the fan, w the corner before a in T.
    edge_after = base.triangle_edges[corner_tri, (corner_slot + 1) % 3]
    et = base.edge_triangles[edge_after]
    other = np.where(et[:, 0] == corner_tri, et[:, 1], et[:, 0])
    successor = np.full(3 * m, -1)
    has_next = other >= 0
    other_slot = np.argmax(tris[np.maximum(other, 0)] == corner_vertex[:, None], axis=1)
    successor[has_next] = 3 * other[has_next] + other_slot[has_next]
    predecessor = np.full(3 * m, -1)
    predecessor[successor[has_next]] = np.flatnonzero(has_next)

    fan_size = np.bincount(corner_vertex, minlength=base.n_vertices)
    order = np.argsort(corner_vertex, kind="stable")
    first_corner = np.full(base.n_vertices, -1)
    starts = np.flatnonzero(predecessor < 0)  # open fans start where nothing precedes
    first_corner[corner_vertex[order[::-1]]] = order[::-1]  # any corner (closed fans)
    open_fan = np.zeros(base.n_vertices, dtype=bool)
    open_fan[corner_vertex[starts]] = True
    starts_per_vertex = np.bincount(corner_vertex[starts], minlength=base.n_vertices)
    first_corner[corner_vertex[starts]] = starts
    candidates = np.flatnonzero((surface.lift_of_vertex >= 0) & (starts_per_vertex <= 1))
    for k in np.unique(fan_size[candidates]):
        for closed in (True, False):
            group = candidates[(fan_size[candidates] == k) & (open_fan[candidates] != closed)]
            hinges = k if closed else k - 1
            if group.size == 0 or hinges < 1 or hinges > MAX_STAR_HINGES or (not closed and k < 3):
                continue
            chain = np.empty((group.size, k), dtype=np.int64)
            chain[:, 0] = first_corner[group]
            ok = np.ones(group.size, dtype=bool)
            for i in range(1, k):
                chain[:, i] = successor[chain[:, i - 1]]
                ok &= chain[:, i] >= 0
                chain[:, i] = np.maximum(chain[:, i], 0)
            ok &= (successor[chain[:, -1]] == chain[:, 0]) if closed else (successor[chain[:, -1]] < 0)
            ok &= (np.diff(np.sort(chain, axis=1), axis=1) > 0).all(axis=1)  # a single fan
            if not ok.any():
                continue
            chain, group = chain[ok], group[ok]
            edge = edge_after[chain[:, :hinges]]
            triangle = corner_tri[chain]
            hinge = hinge_of_edge[edge]
            # The map of hinge i goes from triangle i+1's frame to triangle i's.
            toward_first = base.edge_triangles[edge, 0] == triangle[:, :hinges]
            yield group, triangle, corner_slot[chain], hinge, toward_first, closed


def _trilaterate(anchors: np.ndarray, squared: np.ndarray) -> np.ndarray:
    """Max relative sphere residual of the best point at squared distances ``squared`` ``(S, q)``
    from ``anchors`` ``(S, q, 3)`` (q ≥ 4): linear least squares, then two Gauss–Newton steps."""
    center = anchors.mean(axis=1, keepdims=True)
    q = anchors - center
    qt = np.swapaxes(q, 1, 2)
    qq = rows_dot(q, q)
    rhs = 0.5 * (qq - qq.mean(axis=1, keepdims=True) - squared + squared.mean(axis=1, keepdims=True))
    scatter = qt @ q
    damping = TRILATERATION_DAMPING * np.trace(scatter, axis1=1, axis2=2)[:, None, None] * np.eye(3)
    x = np.linalg.solve(scatter + damping, (qt @ rhs[:, :, None]))[:, :, 0]
    for _ in range(2):
        diff = x[:, None, :] - q
        residual = rows_dot(diff, diff) - squared
        diff_t = np.swapaxes(diff, 1, 2)
        x = x - 0.5 * np.linalg.solve(diff_t @ diff + damping, diff_t @ residual[:, :, None])[:, :, 0]
    diff = x[:, None, :] - q
    return np.max(np.abs(rows_dot(diff, diff) - squared) / squared, axis=1)


class _StarScorer:
    """Scores sign patterns of a group of stars: fan closure (closed fans) and the residual of
    the lifted vertex trilaterated from the star's vertex and face centers."""

    def __init__(self, apex, centers, distances, scale2, closed):
        self.apex, self.centers, self.distances, self.scale2, self.closed = apex, centers, distances, scale2, closed

    def __call__(self, rows, rotation, shift, placed) -> np.ndarray:
        """``rows`` the star of every batch row; ``rotation``/``shift`` the composed map around
        the fan; ``placed`` ``(R, k, 3)`` the face centers in the first frame."""
        anchors = np.concatenate([self.apex[rows][:, None], placed], axis=1)
        spheres = self.distances[rows]
        if self.closed:  # trilaterate only where the fan closes: the others are wrong already
            score = np.sqrt(np.sum((rotation - np.eye(3)) ** 2, axis=(1, 2)) + rows_dot(shift, shift) / self.scale2[rows])
            near = np.flatnonzero(score < CLOSURE_GATE)
            if near.size:
                score[near] = np.maximum(score[near], _trilaterate(anchors[near], spheres[near]))
        else:
            score = _trilaterate(anchors, spheres)
        return np.where(np.isfinite(score), score, np.inf)


def _best_by_enumeration(scorer: _StarScorer, maps, h: int, k: int) -> np.ndarray:
    """Best score per star, hinge and sign ``(S, h, 2)``, all patterns as one batch of rows."""
    S = scorer.apex.shape[0]
    patterns = 2**h
    bits = (np.arange(patterns)[:, None] >> np.arange(h)[None, :]) & 1  # (P, h)
    rows = np.repeat(np.arange(S), patterns)  # star-major
    rotation = np.broadcast_to(np.eye(3), (rows.size, 3, 3))
    shift = np.zeros((rows.size, 3))
    placed = [scorer.centers[rows, 0]]
    for i in range(h):
        step_rotation = maps[i][0][:, bits[:, i]].reshape(rows.size, 3, 3)
        step_shift = maps[i][1][:, bits[:, i]].reshape(rows.size, 3)
        shift = (rotation @ step_shift[:, :, None])[:, :, 0] + shift
        rotation = rotation @ step_rotation
        if i + 1 < k:
            placed.append((rotation @ scorer.centers[rows, i + 1, :, None])[:, :, 0] + shift)
    score = scorer(rows, rotation, shift, np.stack(placed, axis=1)).reshape(S, patterns)
    best = np.empty((S, h, 2))
    for j in range(h):
        for sign in (0, 1):
            best[:, j, sign] = score[:, bits[:, j] == sign].min(axis=1)
    return best


def _best_by_descent(scorer: _StarScorer, maps, h: int, k: int) -> np.ndarray:
    """The same, depth-first over the hinges, vectorized over stars: a pattern prefix is
    composed once for all its completions (2^(h+1) compositions instead of h·2^h)."""
    S = scorer.apex.shape[0]
    rows = np.arange(S)
    best = np.full((S, h, 2), np.inf)
    bits = np.zeros(h, dtype=np.int64)

    def descend(i, rotation, shift, placed):
        if i == h:
            score = scorer(rows, rotation, shift, np.stack(placed, axis=1))
            for j in range(h):
                np.minimum(best[:, j, bits[j]], score, out=best[:, j, bits[j]])
            return
        for sign in (0, 1):
            bits[i] = sign
            new_rotation = rotation @ maps[i][0][:, sign]
            new_shift = (rotation @ maps[i][1][:, sign, :, None])[:, :, 0] + shift
            new_placed = placed
            if i + 1 < k:
                new_placed = placed + [(new_rotation @ scorer.centers[:, i + 1, :, None])[:, :, 0] + new_shift]
            descend(i + 1, new_rotation, new_shift, new_placed)

    descend(0, np.broadcast_to(np.eye(3), (S, 3, 3)), np.zeros((S, 3)), [scorer.centers[:, 0]])
    return best


def _star_votes(surface, local, hinges: _Hinges, offset_squared, offset_lookup, offset: float) -> np.ndarray:
    """Per hinge, the summed log-ratio of the best star residuals with its negative and its
    positive sign (> 0 favours the positive mesh-edge tetrahedron)."""
    votes = np.zeros(hinges.edges.size)
    hinge_of_edge = np.full(surface.base.n_edges, -1)
    hinge_of_edge[hinges.edges] = np.arange(hinges.edges.size)
    for vertex, triangle, slot, hinge, toward_first, closed in _fans(surface, hinge_of_edge):
        S, k = triangle.shape
        h = hinge.shape[1]
        centers = local[triangle, 3]  # (S, k, 3) each in its own frame
        lifted = surface.lift_of_vertex[vertex]
        center_ids = surface.center_of_triangle[triangle]
        rows = offset_lookup(np.repeat(lifted, k), center_ids.ravel()).reshape(S, k)
        if (rows < 0).any() or (center_ids < 0).any():
            continue
        distances = np.concatenate([np.full((S, 1), offset * offset), offset_squared[rows]], axis=1)
        apex = local[triangle[:, 0], slot[:, 0]]  # the star's vertex in the first frame
        scale2 = np.maximum(distances.max(axis=1), np.finfo(float).tiny)
        maps = [hinges.maps(hinge[:, i, None], np.array([[0, 1]]), toward_first[:, i, None]) for i in range(h)]
        scorer = _StarScorer(apex, centers, distances, scale2, closed)
        if S * 2**h <= PATTERN_BATCH:
            best = _best_by_enumeration(scorer, maps, h, k)  # few stars: all patterns in one batch
        else:
            best = _best_by_descent(scorer, maps, h, k)  # many stars: share pattern prefixes
        ratio = np.log((best[:, :, 1] + VOTE_FLOOR) / (best[:, :, 0] + VOTE_FLOOR))
        ratio = np.where(np.isfinite(ratio), ratio, 0.0)
        np.add.at(votes, hinge.ravel(), np.clip(ratio, -VOTE_CLIP, VOTE_CLIP).ravel())
    return votes


def _glue(surface, local, hinges: _Hinges, sign: np.ndarray):
    """Compose frames along breadth-first trees of the dual graph: per triangle the rigid map
    (R ``(m, 3, 3)``, s ``(m, 3)``) from its frame to the root's of its component."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order

    base = surface.base
    m = base.n_triangles
    dual = coo_matrix((np.ones(hinges.edges.size), (hinges.first, hinges.second)), shape=(m, m)).tocsr()
    count, labels = connected_components(m, np.stack([hinges.first, hinges.second], axis=1))
    rotation = np.zeros((m, 3, 3))
    shift = np.zeros((m, 3))
    find = _pair_lookup(np.stack([hinges.first, hinges.second], axis=1), m)
    for component in range(count):
        root = int(np.flatnonzero(labels == component)[0])
        order, parent = breadth_first_order(dual, root, directed=False, return_predecessors=True)
        rotation[root] = np.eye(3)
        depth = np.zeros(m, dtype=np.int64)
        parent_list, depth_list = parent.tolist(), depth.tolist()
        for node in order[1:].tolist():
            depth_list[node] = depth_list[parent_list[node]] + 1
        depth = np.asarray(depth_list)
        nodes = order[1:]
        for level in range(1, int(depth[nodes].max(initial=0)) + 1):
            at = nodes[depth[nodes] == level]
            up = parent[at]
            hinge = find(up, at)
            step_rotation, step_shift = hinges.maps(hinge, sign[hinge], hinges.first[hinge] == up)
            rotation[at] = rotation[up] @ step_rotation
            shift[at] = np.einsum("tij,tj->ti", rotation[up], step_shift) + shift[up]
    return rotation, shift


def _thickening_points(surface, local, rotation, shift, offset) -> np.ndarray:
    """Vertices from the glued frames, then the offset layer from them (exact when they are)."""
    positions = corner_mean_positions(surface.base, local, rotation, shift)
    return np.concatenate([positions, surface.positions(positions, offset)])


def corner_mean_positions(base, local, rotation, shift) -> np.ndarray:
    """Every vertex ``(n, 3)`` at the mean of its corners' positions ``R_T L_T + s_T`` in the
    triangle frames (``local`` ``(m, ≥3, 3)``, ``rotation`` ``(m, 3, 3)``, ``shift`` ``(m, 3)``)."""
    corners = np.einsum("tij,tcj->tci", rotation, local[:, :3]) + shift[:, None, :]  # (m, 3, 3)
    count_per_vertex = np.bincount(base.triangles.ravel(), minlength=base.n_vertices)
    return np.stack(
        [np.bincount(base.triangles.ravel(), corners[:, :, d].ravel(), minlength=base.n_vertices) for d in range(3)],
        axis=1,
    ) / np.maximum(count_per_vertex, 1)[:, None]


def _synchronized_points(surface, local, hinges: _Hinges, sign, tree_rotation, tree_positions, offset):
    positions = synchronized_positions(surface.base, local, hinges.first, hinges.second,
                                       hinges.rotation[np.arange(hinges.edges.size), sign], tree_rotation, tree_positions)
    return np.concatenate([positions, surface.positions(positions, offset)])


def synchronized_positions(base, local, first, second, q, pin_rotation, pin_positions) -> np.ndarray:
    """Least-squares frames: rows of the rotations solve ``R_second = R_first Q_h`` over all hinges
    (a connection Laplacian, softly pinned to the tree's frames to fix the global rotation), are
    projected onto SO(3), and the vertices solve ``x_j − x_i = R_T (L_j − L_i)`` over all triangle
    edges (a graph Laplacian, softly pinned to the tree's vertices)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    m, H = base.n_triangles, first.size  # q (H, 3, 3) maps the second triangle's frame to the first's
    # Per hinge 3 equations y_second − Qᵀ y_first = 0 for each row y of the rotations.
    rows = np.arange(3 * H).reshape(H, 3)
    ident_rows, ident_cols = rows.ravel(), (3 * second[:, None] + np.arange(3)).ravel()
    block_rows = np.repeat(rows, 3, axis=1).ravel()
    block_cols = np.tile(3 * first[:, None] + np.arange(3), (1, 3)).ravel()
    block_vals = -np.swapaxes(q, 1, 2).reshape(H, 9).ravel()
    A = sp.csr_matrix(
        (np.concatenate([np.ones(3 * H), block_vals]), (np.concatenate([ident_rows, block_rows]),
                                                        np.concatenate([ident_cols, block_cols]))),
        shape=(3 * H, 3 * m),
    )
    normal = (A.T @ A).tocsc()
    pin = SYNCHRONIZATION_PIN * float(normal.diagonal().mean())
    solve = splu((normal + pin * sp.identity(3 * m, format="csc")).tocsc()).solve
    rotation = np.stack([solve(pin * pin_rotation[:, r, :].reshape(-1)).reshape(m, 3) for r in range(3)], axis=1)
    rotation = nearest_rotations(rotation)
    # Vertices from the triangle edges in the synchronized frames.
    tris = base.triangles
    tails, heads = tris[:, [0, 1, 2]].ravel(), tris[:, [1, 2, 0]].ravel()
    local_edges = (local[:, [1, 2, 0]] - local[:, [0, 1, 2]])  # (m, 3, 3) corner k -> k+1
    world_edges = np.einsum("tij,tkj->tki", rotation, local_edges).reshape(-1, 3)
    n = base.n_vertices
    e = np.arange(tails.size)
    D = sp.csr_matrix((np.r_[-np.ones(e.size), np.ones(e.size)], (np.r_[e, e], np.r_[tails, heads])), shape=(e.size, n))
    laplacian = (D.T @ D).tocsc()
    pin = SYNCHRONIZATION_PIN * float(laplacian.diagonal().mean())
    solve = splu((laplacian + pin * sp.identity(n, format="csc")).tocsc()).solve
    rhs = D.T @ world_edges + pin * pin_positions
    return np.stack([solve(np.ascontiguousarray(rhs[:, d])) for d in range(3)], axis=1)


def hinge_frame_embedding(surface: OffsetSurface, squared: np.ndarray) -> HingeFrameEmbedding:
    """Thickening points ``(n + n_offset, 3)`` from the squared lengths of
    :attr:`OffsetSurface.thickening_edges` (validated by the caller): see the module docstring."""
    base = surface.base
    n_base_edges, n_offset_edges = base.n_edges, surface.topology.n_edges
    base_squared = squared[:n_base_edges]
    offset_squared = squared[n_base_edges : n_base_edges + n_offset_edges]
    normal_squared = squared[n_base_edges + n_offset_edges : n_base_edges + n_offset_edges + surface.lifted_vertices.size]
    offset = float(np.sqrt(np.median(normal_squared)))
    local = triangle_local_points(base_squared[base.triangle_edges], offset)
    offset_lookup = _pair_lookup(surface.topology.edges, surface.topology.n_vertices)
    hinges = _Hinges(
        surface, local,
        offset_squared[offset_lookup(surface.center_of_triangle[base.edge_triangles[base.interior_edges, 0]],
                                     surface.center_of_triangle[base.edge_triangles[base.interior_edges, 1]])],
    )
    votes = _star_votes(surface, local, hinges, offset_squared, offset_lookup, offset)
    sign = np.where(votes >= 0, 0, 1)
    rotation, shift = _glue(surface, local, hinges, sign)
    # Hinges whose dihedral is flat enough that both signs agree are not ambiguous.
    differs = np.linalg.norm(hinges.rotation[:, 0] - hinges.rotation[:, 1], axis=(1, 2)) > FLAT_HINGE
    unresolved = int(np.sum(differs & (np.abs(votes) < np.log(DECISIVE_RATIO))))
    return HingeFrameEmbedding(surface, local, hinges, sign, rotation, shift, offset, unresolved)
