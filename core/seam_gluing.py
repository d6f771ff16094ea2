"""Pieces glued along seams: where a reconstruction places the pieces of a mesh each on its own
(:mod:`core.reference_shape`: shape differences are computed per piece), the pieces that meet along
seams in the base (:func:`seam_twins`) are moved rigidly so that their seams meet
(:func:`glue_along_seams`), a ring of panels closed by fitting each piece to all its seams at once
(:func:`_close_rings`), and seams whose sides differ in the pose are let open
(:func:`_opened_seams`).
"""

from __future__ import annotations

import numpy as np

from .errors import MeshError
from .geometry import vertex_labels
from .seam_welds import coincidence_tolerance, seam_weld


def seam_twins(base: np.ndarray, topology):
    """Pairs of vertices ``(a, b)`` (int (p,) each) of different pieces that meet along a seam in
    the pose ``base`` (n, 3) of ``topology``, and a problem (str) or None: every pair of boundary
    vertices of two pieces at one place (:func:`core.seam_welds.coincidence_tolerance`), also where the two sides
    number their vertices differently (a T-junction: 9 vertices on one side, 5 on the other, each
    of those on one of the 9; the edges do not match end for end, which :func:`core.seam_welds.seam_weld` needs,
    and the panels were placed apart, the seam 0.37 open). Two pieces joined by a single pair
    (panels meeting only at a corner, as the diagonal ones of four around one vertex do) are not
    seamed: glued by a point, a 2 × 2 split sheet came back 0.55 % off. Panels wound against the
    ones they meet are turned over in the weld, as the in-betweens' are (:func:`core.seam_welds.oriented_pieces`).
    None without seams; with the problem where welding them would not give a valid mesh (panels no
    choice of windings joins consistently, a triangle it would collapse)."""
    from scipy.spatial import cKDTree

    try:
        seam_weld([base], topology, orient=True)
    except MeshError as error:
        return None, str(error)
    boundary = np.unique(topology.edges[topology.boundary_edges])
    if boundary.size < 2:
        return None, None
    pairs = cKDTree(base[boundary]).query_pairs(coincidence_tolerance(base, topology.edges), output_type="ndarray")
    _, labels = topology.components()
    piece = vertex_labels(topology.triangles, labels, topology.n_vertices)
    pairs = boundary[pairs].reshape(-1, 2)
    pairs = pairs[piece[pairs[:, 0]] != piece[pairs[:, 1]]]
    if not len(pairs):
        return None, None
    ends = np.sort(piece[pairs], axis=1)
    _, which, count = np.unique(ends, axis=0, return_inverse=True, return_counts=True)
    pairs = pairs[count[which.ravel()] >= 2]
    return ((pairs[:, 0], pairs[:, 1]), None) if len(pairs) else (None, None)


#: Twins of a seam that, its two sides fitted onto each other, stay apart by more than this share
#: of the seam's length (RMS spread) part in the pose (an exact reconstruction's twins meet to
#: ~1e-10): they are let go, and where most of a seam's twins part the seam opens (a strip along a
#: body that widens under it: 15 % of the diagonal) and its pieces are placed on their own. One RMS
#: test of a whole seam at 5 % instead glues a seam opening by 0.5 % (4.6e-3 off), and two touching
#: points that part (a vent's corners) let a sewn seam's 5 twins go with them.
SEAM_OPEN_SHARE = 1e-3

#: A seam holds the angle between the pieces it joins where its twins' spread across their line
#: exceeds this many times the RMS misfit of the twins' fit (the pieces' own reconstruction error):
#: two panels folded 90° about a seam straight to 3e-4 of the diagonal, reconstructed in a
#: truncated basis to 3e-4, were glued at 32° with no warning.
SEAM_HOLD_MISFITS = 10.0


def glue_along_seams(positions: np.ndarray, labels: np.ndarray, twins, weights: np.ndarray, *,
                     find_opened: bool = True):
    """Pieces (rows of equal ``labels`` (n,)) of ``positions`` (n, 3), each placed on its own, moved
    rigidly so that the ``twins`` (pairs from :func:`seam_twins`) meet, piece by piece outward from
    the heaviest of each group of pieces joined by seams (``weights`` (n,)): each piece's twins
    fitted onto their partners, then the turn about them that the twins leave free (about a
    straight seam, a single point) chosen to keep the rest of the piece nearest where it was
    (:func:`core.rigid_alignment.pivoted_alignment`). Returns the moved positions, the labels with
    glued pieces sharing one, the pairs of labels joined along a seam straight to within
    :data:`SEAM_HOLD_MISFITS` of the twins' misfit (their angle there is the one their own
    placements gave, not the pose's: shape differences are computed per piece), and the pairs of
    pieces whose seam is dropped because its sides differ in the pose (:data:`SEAM_OPEN_SHARE`;
    only where ``find_opened``: an exact reconstruction, whose misfits are the pose's, not its own
    error's)."""
    from .rigid_alignment import PIVOT_SPREAD, pivoted_alignment, rigid_alignment

    out, labels = positions.copy(), labels.copy()
    pieces = labels.copy()  # each vertex's own piece (``labels`` join as pieces are glued)
    a, b = twins
    mass = {piece: weights[labels == piece].sum() for piece in np.unique(labels)}
    placed, hinges, roots, opened = set(), [], set(), []
    while True:
        # pairs from a placed piece to one not placed yet (either way round); none: start the next
        # group from its heaviest piece
        fixed_a, fixed_b = np.isin(labels[a], list(placed)), np.isin(labels[b], list(placed))
        across = fixed_a ^ fixed_b
        if not across.any():
            free = {int(piece) for piece in np.unique(labels[np.r_[a, b]]) if piece not in placed}
            if not free:
                _close_rings(out, pieces, a, b, roots)
                return out, labels, hinges, opened
            root = max(free, key=lambda piece: mass[piece])
            placed.add(root)
            roots.add(root)
            continue
        rows = np.flatnonzero(across)  # the pairs' places in a, b
        moving, partner = np.where(fixed_a, b, a)[rows], np.where(fixed_a, a, b)[rows]
        piece = labels[moving[0]]
        mine = labels[moving] == piece
        rows, moving, partner = rows[mine], moving[mine], partner[mine]
        if find_opened:  # pairs whose two sides part in the pose are dropped (whole seams: said so)
            parting, gone = _opened_seams(out, pieces, moving, partner)
            if parting.any():
                opened += [(int(other), int(pieces[moving[0]])) for other in gone]
                keep = np.ones(len(a), dtype=bool)
                keep[rows[parting]] = False
                a, b = a[keep], b[keep]
                continue
        rows = np.flatnonzero(labels == piece)
        rotation, translation = rigid_alignment(out[moving], out[partner])
        joined = out[rows] @ rotation.T + translation
        misfit = np.sqrt(np.mean(np.sum((joined[np.searchsorted(rows, moving)] - out[partner]) ** 2, axis=1)))
        seam = out[partner] - out[partner].mean(axis=0)
        spread = np.linalg.svd(seam, compute_uv=False) / np.sqrt(partner.size)
        held = spread.size > 1 and spread[1] > max(PIVOT_SPREAD * np.linalg.norm(np.ptp(out[rows], axis=0)),
                                                   SEAM_HOLD_MISFITS * misfit)
        # a seam that does not hold the angle: its line (or point) is the pivot of the turn left free
        pivots = out[partner] if held else _line_through(out[partner], spread)
        turn, shift = pivoted_alignment(joined, out[rows], pivots, weights[rows])
        out[rows] = joined @ turn.T + shift
        if not held:
            hinges.append((int(labels[partner[0]]), int(piece)))
        labels[rows] = labels[partner[0]]
        placed.add(int(piece))


def _line_through(points: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """Two points (2, 3) on the best line through ``points`` (p, 3) (``spread``: their singular
    values over √p), or their centre alone (1, 3) where they do not spread along one either."""
    centre = points.mean(axis=0)
    if spread[0] <= 0:
        return centre[None]
    direction = np.linalg.svd(points - centre, full_matrices=False)[2][0]
    return np.stack([centre - spread[0] * direction, centre + spread[0] * direction])


#: Sweeps of :func:`_close_rings` at most, and the change of the seams' largest gap (relative to
#: the largest gap) under which they stop.
RING_SWEEPS, RING_TOLERANCE = 200, 1e-10


def _close_rings(out: np.ndarray, pieces: np.ndarray, a: np.ndarray, b: np.ndarray, roots: set) -> None:
    """Where glued pieces close a ring (a tube of panels: the last one meets the first along a
    seam the gluing piece by piece could not hold), move each piece but the groups' first, in
    place, to fit its twins onto all their partners at once, sweep after sweep (each piece held
    by its seams on both sides: two lines, which fix it), until the gaps stop closing. Pieces
    whose twins all lie on one line keep their place (their turn about it is not determined)."""
    from .rigid_alignment import rigid_alignment

    gaps = np.linalg.norm(out[a] - out[b], axis=1)
    if not len(gaps) or gaps.max() <= 0:
        return
    movable = []
    for piece in np.unique(pieces[np.r_[a, b]]):
        if piece in roots:
            continue
        mine_a, mine_b = pieces[a] == piece, pieces[b] == piece
        own = np.r_[a[mine_a & ~mine_b], b[mine_b & ~mine_a]]
        partner = np.r_[b[mine_a & ~mine_b], a[mine_b & ~mine_a]]
        spread = np.linalg.svd(out[own] - out[own].mean(axis=0), compute_uv=False)
        if spread.size > 1 and spread[1] > 1e-3 * spread[0]:  # not one line: the twins fix the piece
            movable.append((np.flatnonzero(pieces == piece), own, partner))
    if not movable:
        return
    largest = gaps.max()
    for _ in range(RING_SWEEPS):
        for rows, own, partner in movable:
            rotation, translation = rigid_alignment(out[own], out[partner])
            out[rows] = out[rows] @ rotation.T + translation
        now = np.linalg.norm(out[a] - out[b], axis=1).max()
        if abs(largest - now) <= RING_TOLERANCE * max(largest, now) or now <= 1e-14:
            return
        largest = now


#: Twins a seam's consistency counts are taken against, at most (evenly spread along it), and the
#: share of the largest count that seeds the fit (a block of 49 % of the twins moved off keeps its
#: own distances: at 0.9 it seeded the fit with the sewn 51 %, pulled it off, and the seam opened).
SEAM_REFERENCE_TWINS = 512
SEAM_SEED_SHARE = 0.98


def _opened_seams(out: np.ndarray, pieces: np.ndarray, moving: np.ndarray, partner: np.ndarray):
    """Which of the twins ``moving`` / ``partner`` (p,) part in the pose (bool (p,)), and the pieces
    of the ``partner`` twins whose whole seam with the piece of the ``moving`` twins opens (list).
    Seam by seam: the part that stays sewn keeps the distances between its twins on both sides (a
    rigid motion keeps them), so each twin is counted against up to :data:`SEAM_REFERENCE_TWINS`
    others for the distances it keeps to :data:`SEAM_OPEN_SHARE` of the seam's length; the twins
    about as consistent as the most consistent ones (:data:`SEAM_SEED_SHARE`) seed the fit of the two sides onto each other, and
    the twins it brings within that share stay sewn (refitted on them until they stay the same). Where they are not
    most of the seam, or fewer than two, the seam opens. A seam whose top part moved off as a
    block (44 % of its twins), or whose panels also touch at a vent's corners that part, stays
    sewn where it is sewn: fits that let the farthest twins go one by one or a tenth at a time
    were pulled by the block and let sewn twins go with it."""
    from .rigid_alignment import rigid_alignment

    parting, gone = np.zeros(len(moving), dtype=bool), []
    for other in np.unique(pieces[partner]):
        seam = np.flatnonzero(pieces[partner] == other)
        mine, theirs = out[moving[seam]], out[partner[seam]]
        length = np.sqrt(np.mean(np.sum((theirs - theirs.mean(axis=0)) ** 2, axis=1)))
        tolerance = SEAM_OPEN_SHARE * length
        reference = np.linspace(0, seam.size - 1, min(seam.size, SEAM_REFERENCE_TWINS)).astype(int)
        consistent = np.concatenate([  # in blocks of rows: a (p, references, 3) array is 0.5 GB at 20k twins
            np.count_nonzero(np.abs(np.linalg.norm(mine[rows, None] - mine[reference], axis=2)
                                    - np.linalg.norm(theirs[rows, None] - theirs[reference], axis=2)) <= tolerance, axis=1)
            for rows in np.array_split(np.arange(seam.size), max(1, seam.size // 2048))])
        meet = consistent >= SEAM_SEED_SHARE * consistent.max()
        for _ in range(5):  # refitted on the twins that meet until they are the same
            if np.count_nonzero(meet) < 2:
                break
            rotation, translation = rigid_alignment(mine[meet], theirs[meet])
            fitted = np.linalg.norm(mine @ rotation.T + translation - theirs, axis=1) <= tolerance
            if np.array_equal(fitted, meet):
                break
            meet = fitted
        if np.count_nonzero(meet) < 2 or 2 * np.count_nonzero(~meet) > seam.size:  # the seam opens
            parting[seam] = True
            gone.append(int(other))
        else:
            parting[seam[~meet]] = True
    return parting, gone
