"""The in-between solver objects (paper §7.3 in local/global form): per topology the factorized
normal matrix, per key its frames, per gap the splines of the deformation fields between its keys,
the anchor and the reconstruction of a pose at any factor.

``_Topology`` (triangles only) → ``_Key`` (one pose) → ``_Relative`` (a key seen from the base key
of a gap; both in :mod:`core.inbetween_keys`) → ``_Gap`` (splines of the relatives at key times
−1, 0, 1, 2 (:mod:`core.splines`) and ``pose(s)``: Poisson solve and local/global fit
(:mod:`core.inbetween_fit`), checks and repairs (:mod:`core.inbetween_repair`)). The public classes live in :mod:`core.interpolation`.
"""

from __future__ import annotations

from functools import cached_property, partial

import numpy as np
import scipy.sparse as sp
from scipy.spatial.transform import Rotation

from . import deformation_fields as df
from .geometry import coordinate_cross, coordinate_dot, lumped_vertex_areas, scaled, shifted, vertex_labels
from .inbetween_carried import CarriedPieces
from .inbetween_fit import LOCAL_STEP_DTYPE, METRIC_TOLERANCE, LocalGlobalFit, change_tolerance, trimmed_tolerance
from .inbetween_joints import JOINT_REACH, composed, joint_screws, joint_tree
from .inbetween_keys import _Key, _Relative, turn_spread
from .inbetween_repair import Region, Repair
from .rigid_alignment import rigid_alignment
from .sparse_cholesky import SPDFactor
from .splines import REST_START_LIMIT, TANGENT_LIMIT, HermiteGap

#: Anchor weight (per unit vertex mass, mean mass 1, relative to the unit edge terms) that only
#: fixes the translation gauge of the Poisson solve: small enough to leave shapes exact to ~1e-7
#: of their size (placement is done afterwards), large enough to keep the matrix well conditioned.
GAUGE_WEIGHT = 1e-7
#: Two-pose interpolation anchors vertex ``v`` to the linear blend with weight
#: BLEND_ANCHOR_WEIGHT · (BLEND_SHORTENING_SCALE / max(c, scale))² · max(0, 1 − c / CUTOFF)², where
#: ``c`` is the blend's mean relative edge shortening around ``v`` at the middle of the gap (in
#: the world or with the component's rigid motion undone, see ``_Gap.anchor_weights``). Where the
#: blend keeps the edge lengths (the neighbourhood translates) it is accurate, so parts that do not
#: move stay put, translating parts sit where the blend puts them, and parts turning about them
#: hang from them; where the blend shortens edges (rotating parts: it cuts the chord; 10 % is a
#: turn of ~50°) the weight vanishes and the interpolated rotations alone decide. In a component
#: that keeps its edge lengths and has pins, a translating part hangs from them instead
#: (:meth:`_Gap.hung_from_pins`): its translation comes from the turns between them.
BLEND_ANCHOR_WEIGHT = 0.1
BLEND_SHORTENING_SCALE = 0.01
BLEND_SHORTENING_CUTOFF = 0.1
#: ... and the blend is taken with the component's rigid motion undone only where that motion also
#: takes the vertex to within this fraction of the component's diagonal of where it is: a part
#: that turns as the whole component does but about another pivot (the middle segment of a finger
#: curled by two equal joints) keeps its edge vectors once the turn is undone, yet the component's
#: screw motion carries it along the wrong path (curled 60° / 60°: 0.9 % of the diagonal off at
#: 0.5, edges 62 % off at × 2).
CO_MOVING_DRIFT = 0.01
#: ... and not at all at a vertex of a triangle whose blended edges make an angle whose cosine is
#: below this (143°) with the interpolated field's at the middle of the gap
#: (:meth:`_Gap.aliased_blend`): turned nearly opposite, which a fold's crumpling barely reaches.
#: On the 105 pair cells of 35 cloths only the two sheets at g = 16 changed (flips 130 → 127); at a
#: cosine of 0 four cells changed, three a little worse (the drag 1.056 → 1.057 × the blend).
ALIASED_BLEND_COSINE = -0.8
#: Anchor of the pinned vertices of a sequence (still in every key, or riding on an animated
#: object: :mod:`core.pins`), per vertex whatever its mass (the edge terms pull on a vertex per
#: edge, not per area): large enough that they stay put to ~1e-3 of the edge terms' pull (and are
#: then set exactly), small enough to leave the normal matrix well conditioned. Per unit mass, as
#: the other anchors, the pins of a flag whose triangles at its pole are 1/50 of the mean area were
#: held 50 × less firmly, missed their place by a tenth of those triangles' size and, set exactly
#: afterwards, turned slivers there over.
STATIC_ANCHOR_WEIGHT = 1e3
#: Sequences anchor every other vertex to the keys' per-vertex spline with this weight (per unit
#: vertex mass, relative to the unit edge terms of the graph Laplacian): shapes longer than about
#: 2π/√w ≈ 60 edges follow the spline, shorter ones the interpolated fields. Without it the fields
#: alone place the whole sheet and their small rotation errors add up along it (a flag pinned at
#: its pole: 1.09–1.27 × the RMS of the per-vertex Catmull–Rom spline; with it 0.96–1.11);
#: numbers for other weights in docs/inbetweens.md.
SEQUENCE_ANCHOR_WEIGHT = 1e-2
#: ... and with a stronger one in a gap where the motion is smooth: at the middle of the gap that
#: spline's corner edge lengths deviate from the keys' mean lengths by less than
#: SMOOTH_SPLINE_STRAIN (mean relative deviation) and by no more than the linear blend's (up to
#: METRIC_TOLERANCE: where the cloth barely moves both are ~1e-4 and their order is noise). A
#: spline that keeps the cloth's lengths is right at short wavelengths too: SMOOTH_ANCHOR_WEIGHT
#: where its deviation is within the fit's tolerance of the metric before trimming (the pull then
#: costs no more edge length than a fit stopped there, see :data:`core.inbetween_fit.TOLERANCE_TRIM`),
#: SMOOTH_NEAR_ANCHOR_WEIGHT elsewhere under SMOOTH_SPLINE_STRAIN (an isometric bend whose last
#: gap's spline deviates by 0.39 %: 0.1 there gave 0.25 % edge deviation, 3e-2 0.14 %). Keys 4
#: frames apart, RMS ÷ the Catmull–Rom
#: spline's: flag pinned at its pole 1.054 → 0.889, hanging sheet 1.009 → 0.936, falling sheet
#: 0.964 → 0.875 (with the start parabola); baked for a check, a soft 6,400-vertex flag 1.013 (3e-2
#: in every smooth gap: 1.035, 0.1: 0.999). Where the spline does not keep the lengths (keys 16
#: apart, turns: hanging sheet at g = 16, edge deviation 0.47 → 0.74 % with 3e-2 everywhere, bound
#: 0.47), or keeps them worse than the blend (an impact at a key: the spline overshoots; 50k
#: sheet, g = 4: 0.963 → 0.973 × without that condition), the gap keeps SEQUENCE_ANCHOR_WEIGHT.
#: So does a gap whose keys differ by a rigid motion (up to RIGID_PLACEMENT_SCALE, a sheet falling
#: flat): the fields reproduce it whatever the anchor, and a stronger one would cost a second
#: factorization (~1 s at 100k vertices) for nothing.
SMOOTH_ANCHOR_WEIGHT = 0.1
SMOOTH_NEAR_ANCHOR_WEIGHT = 3e-2
SMOOTH_SPLINE_STRAIN = 0.01
#: The sequence anchor's guide is the keys' per-vertex spline in the world where a component
#: deforms; where it turns as a whole that spline cuts the chords of its arcs (a cloth on a
#: turntable, 120° between keys 16 apart: its edges 37 % off the keys' at the middle of the gap,
#: the in-betweens 5.9 % and 0.596 × the blend's RMS). A component whose world spline's mid-gap
#: strain is over ARC_GUIDE_STRAIN_RATIO × that of its co-moving spline (the keys' shapes splined
#: with its rigid motion undone, moved by the interpolated rigid motion; 0.27 % there) plus
#: METRIC_TOLERANCE takes the co-moving spline as its guide; predicted in-betweens still leave
#: an inner key with the world spline's velocity, which the gaps on either side share
#: (:func:`core.inbetween_prediction._key_slope`; with the co-moving velocity, which each gap
#: takes from its own rigid fits, a sheet hanging from two corners jumped 2.67 × the
#: simulation's largest frame-to-frame acceleration at a key), and a sequence's last key with the
#: guide's. Components under a free-flight or impact condition (which act on the world spline)
#: keep it. Turntable 0.596 → 0.285 × the blend and edge deviation 2.39 → 0.65 % (bound 0.85 %);
#: 10k sheet hanging from two corners at g = 16 0.816 → 0.681 × Catmull–Rom; numbers in
#: docs/inbetweens.md, *Cloth that turns as a whole*.
ARC_GUIDE_STRAIN_RATIO = 2.0
#: A sequence's piece whose anchor follows the keys' spline in the world (not its co-moving
#: spline, :data:`ARC_GUIDE_STRAIN_RATIO`) has its triangles' whole rotations splined instead of
#: their residuals to its rigid rotation (:meth:`_Gap.rotations_against_guide`) where, at the
#: middle of the gap, the residuals composed with its interpolated rigid rotation turn more of its
#: triangles against that guide (normals more than 90° apart) than the whole rotations taken
#: half-way do, by over this share of its triangles. The world spline does not turn with the
#: rigid fit; where the piece deforms so much that the fit explains little of its triangles' turns,
#: the composed rotations and the guide pull the in-between two ways and the fit crumples. A sheet
#: hanging from a keyframed corner and spinning 193° about it between keys 16 frames apart
#: (residuals 96°, whole rotations 116°, median): composed, 48 % of its triangles against the
#: guide half-way (whole: 2 %), 6,117 facing away from both keys and 17 % edge deviation in the
#: middle in-between (the simulated frame: 2,093 and 3.6 %); numbers in docs/inbetweens.md.
AGAINST_GUIDE_SHARE = 0.1
#: ... measured only on pieces whose rigid fit turns by more than this between the gap's keys
#: (radians; the check costs 4–5 ms per gap of the 15k curtain): where it took pieces whole they turned
#: 99–195°, and below a quarter turn no piece of the 16 benchmark cloths (keys 4, 8 and 16 frames
#: apart) or of six others (keys 16 apart) turned over 5.5 % of its triangles more against the guide
#: than its whole rotations did.
AGAINST_GUIDE_TURN = np.pi / 2
#: A sequence's in-between whose fit is held off the metric by the spline anchor — its misfit
#: still above HELD_MISFIT × the gap's tolerance and less than HELD_PROGRESS below where the fit
#: started — is solved again with the anchor weight HELD_ANCHOR_WEIGHT, and so are the other solved
#: in-betweens of its gap (the predicted ones interpolate their corrections, which must come from
#: one anchor; mixed, a gap of the 100k sheet was found too rough to predict and all seven solved).
#: The per-vertex spline of a swinging sheet cuts the chords of its arcs: the whole sheet is too
#: small, which the local steps cannot undo against a pull at every vertex (10k sheet hanging from
#: two corners, keys 16 apart: misfit 4.75 → 4.57 % over the fit, tolerance 0.25 %). Where the fit
#: converges the anchor stays (a flag pinned at its pole: its misfit halves; there the weak anchor
#: costs 20–70 % of RMS). HELD_MISFIT is 2.5 rather than 1.5 because the weak anchor costs a
#: factorization per sequence (0.7 s at 100k vertices) and the 50k / 100k sheets' fits held at
#: 1.6–2.1 × bought no RMS (100k at g = 4: 0.108–0.112 → 0.090–0.092 × the bake); 10k hanging sheet
#: at g = 8 0.773 → 0.883 × Catmull–Rom, tablecloth at g = 4 0.717 → 0.754.
HELD_MISFIT = 2.5
HELD_PROGRESS = 0.15
HELD_ANCHOR_WEIGHT = 1e-3
#: Components without anchored vertices are placed by their centroid: along the screw motion of
#: their best rigid motion where they move rigidly (exact for any rigid motion, pieces turning
#: about a common pivot stay together), along the spline of the keys' centroids where they deform
#: (free-falling cloth: the centroid follows its own trajectory, not the rotation's arc), mixed
#: linearly in between by the component's non-rigidity (RMS misfit of the best rigid motion over
#: the gap's keys / the component's bounding-box diagonal) relative to this scale.
RIGID_PLACEMENT_SCALE = 1e-3
#: ... except where the piece's best similarity (its best rigid motion times a uniform scale, the
#: scale fitted too) between the two keys leaves a misfit well under how far its centroid's path
#: along that similarity (the spiral ``exp(s log S)``; a screw motion for a rigid one) departs from
#: the centroid spline half-way: a piece turned 60° whose vertices carry noise or the rounding of a
#: single-precision cache (non-rigidity over RIGID_PLACEMENT_SCALE) was placed on the chord of its
#: arc, 5.4e-2 of the diagonal off at 0.5 and 0.45 at ×2 for noise of 5e-4 of it; a head scaled by
#: 1.02 with its eyes, each on its own chord, had the eyes 2e-2 out of their sockets. There the
#: centroid follows the similarity by the share ``1 − (ARC_PLACEMENT_MISFIT · misfit / departure)²``
#: (at least 0): noise of RMS ε leaves the centroid at most ARC_PLACEMENT_MISFIT · ε off the arc
#: (less the smaller ε), while a cloth that deforms by as much as half its centroid's departure
#: from the chord keeps the spline (docs/inbetweens.md, *Nearly rigid and similar pieces, and what
#: carries what*).
ARC_PLACEMENT_MISFIT = 2.0
#: ... and wholly only where its best similarity misses it by at most the first share of its size
#: (noise, rounding), not at all from the second on (linearly between): a piece missed by that much
#: deforms, and its centroid keeps its own path however far it travels (free-falling cloth, above).
SIMILAR_SHAPE_MISFIT = (1e-2, 3e-2)
#: Smallest turn (radians) over a gap for which a rigid piece's axis is asked whether it flies
#: (:func:`flying_groups`); below it the screw is a translation to within the turn's arc.
FLYING_MIN_TURN = 1e-6
#: Largest difference (third, or second with one key beside the gap; :func:`flying_groups`), as a
#: fraction of the piece's bounding-box diagonal, of the positions of the point a rigid piece is
#: turned about: a point of a hinge's axis or a flying body's centre meets it to round-off (1e-15
#: of the size; a single-precision cache 1e-7).
FLYING_TOLERANCE = 1e-4
#: Free flight up to an impact. The Catmull–Rom tangent at a gap's end key averages the velocity
#: over the gap and the next one; when something stops the cloth right after that key (a sheet
#: landing on a collider) it is too slow for the gap before, which is still in free flight, and
#: the in-betweens there lag and bulge toward the landed shape. A component in free flight through
#: the gap — rigid (non-rigidity, as RIGID_PLACEMENT_SCALE, under FREE_FLIGHT_NONRIGIDITY) from the
#: key before it, or from rest at a sequence's first key, to the gap's end key, its centroid at
#: constant acceleration over the four keys up to that end (third difference under
#: FREE_FLIGHT_JERK × the gap's move: a sheet that hit a ramp flat in the gap before fails it) —
#: and deformed at the key after (non-rigidity over 2 × FREE_FLIGHT_NONRIGIDITY and over
#: FREE_FLIGHT_JUMP × the flight's: more than steady deformation from rest gives) ends the gap on
#: the parabola through its start instead (every spline of it: ``parabolic_end`` of
#: :class:`core.splines.HermiteGap`), exact for constant acceleration. RMS ÷ the linear blend's,
#: keys 8 frames apart: 14k tablecloth 0.638 → 0.353, 10k drape 0.912 → 0.549, unseen irregular
#: 10k mesh 0.913 → 0.493, unseen 30k tablecloth 0.618 → 0.317; of 93 sequence cells on 31 cloths
#: 27 closer, two farther (a 10k sheet hanging from two corners at g = 4, 0.164 → 0.184; a sheet
#: landing flat on a ramp, g = 16, 0.909 → 0.937); other scales in docs/inbetweens.md, *Free flight
#: up to an impact*.
FREE_FLIGHT_NONRIGIDITY = 5e-3
FREE_FLIGHT_JUMP = 4.0
FREE_FLIGHT_JERK = 0.5
#: After an impact. The mirror case: where the cloth hit something inside the gap before, the
#: Catmull–Rom tangent at this gap's start key averages the fast fall before it with the slow
#: settling after it, and the in-betweens overshoot the landed shape (a drape on a sphere, keys 4,
#: 20 and 36: 2.26 × the blend's RMS in the gap after the landing). A component deformed across
#: the gap before — the key before seen from this gap's start key, non-rigidity over 2 ×
#: FREE_FLIGHT_NONRIGIDITY and over FREE_FLIGHT_JUMP × this gap's own — whose centroid moved over
#: IMPACT_SLOWDOWN × as far in the gap before as in this one starts the gap on the parabola
#: through its end (value and tangent) instead (``parabolic_start`` of
#: :class:`core.splines.HermiteGap`): constant deceleration. Keys cut from the middle of a fall
#: (40 cells of 8 cloths): 13 → 6 above a peer (drape on a sphere, keys 16 apart from frame 4:
#: 1.651 → 0.874 × the blend); from frame 0 it moves four of 87 sequence cells, all closer (a 10k
#: drape at g = 8 0.548 → 0.472 × the blend, a shrinking sheet at g = 4 1.065 → 0.928); a swing's
#: turning point fails the deformation test, and at a slowdown of 2 a hanging sheet and a soft
#: flag keep every digit (numbers in docs/inbetweens.md, *After an impact*).
IMPACT_SLOWDOWN = 2.0
#: An in-between of two poses moves a deforming component toward its centroid too where the blend
#: anchor holds only a small part of it: by the share ``(1 − a / CENTROID_ANCHOR_SHARE)²`` of the
#: way, ``a`` the component's mass-weighted anchor (weights relative to BLEND_ANCHOR_WEIGHT; none
#: past this share, and none on a component with a vertex still in both keys, which fixes its
#: place). A few vertices where the blend happens to keep edge lengths otherwise hold the whole
#: piece, and the interpolated rotations' errors grow along it (two sheets crumpling onto each
#: other, keys 16 frames apart: anchored on 0.1–0.7 % of their mass, one sheet's centroid 3–5 × the
#: blend's distance from the frame's, its shape as close as the blend's). The move is a translation
#: after the fit and its repairs (shapes, edge lengths and flipped triangles unchanged; moved at
#: every fit step, some banner pairs fell back to the blend, 4.59 → 5.19 % edge deviation at g = 8).
#: Two sheets at g = 16: 1.304 → 0.861 × the blend's RMS; numbers, losses (a swinging cape 0.922
#: → 0.974) and other shares in docs/inbetweens.md, *Pieces the blend barely holds*.
CENTROID_ANCHOR_SHARE = 0.2


#: Two poses: a set of vertices that translates rigidly between them (pinned to an animated object
#: that does not turn, :func:`core.pins.riding_vertices`) lies on the linear blend at every factor,
#: where the blend anchor holds it; the move of a piece the anchor barely holds onto its centroid
#: (:data:`CENTROID_ANCHOR_SHARE`) carries it along with the rest of the piece. Where the two
#: disagree the interpolated shape of the piece does not reach the set (a sheet whipped by its
#: pinned corner, whose stretch at the corner relaxes between the keys: that corner 0.53 off, 23 %
#: of the sheet's diagonal, keys 4 frames apart), and holding the set there instead costs edge
#: length and flipped triangles elsewhere (docs/inbetweens.md, *A pinned corner off its path*).
#: An in-between whose set ends farther than this share of its piece's diagonal from the blend
#: says so in its warning: the whipped sheet's pairs miss by 0–46 %, the carried banner's pole by
#: 0–9.5 %.
HOOK_MISS_NOTED = 0.1


#: The splines of positions (their tangents are limited per point, see :class:`core.splines.HermiteGap`).
POSITIONS = ("vertices", "world", "centroids")

#: Factors whose rigid motions a gap keeps (:meth:`_Gap.motion`): a batch of in-betweens asks for
#: its factors, 0, 1, 1e-4, 1 − 1e-4 and 0.5 (20 at keys 16 apart). The cache is emptied when
#: full: it holds C × 96 bytes per factor, and a gap lives as long as its interpolator (two
#: poses asked for 300 factors held 29 MB at 1,000 pieces).
MOTION_CACHE = 32


def riding_motions(base: np.ndarray, key: np.ndarray, sets: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Each riding set's (:mod:`core.pins`) rigid motion from positions ``base`` to ``key`` (n, 3):
    rotations (S, 3, 3) and translations (S, 3) of ``x ↦ R x + t``, its turn about its centroid
    the short way round — for a set along a line (a pole) the least turn taking the line to the
    key's, since a turn about the line moves none of its vertices — and its centroid onto the
    key's."""
    rotations, translations = np.zeros((len(sets), 3, 3)), np.zeros((len(sets), 3))
    for k, rows in enumerate(sets):
        start, end = base[rows].mean(axis=0), key[rows].mean(axis=0)
        a, b = base[rows] - start, key[rows] - end
        _, spread, axes = np.linalg.svd(a, full_matrices=False)
        if spread[1] <= 1e-6 * spread[0]:  # along a line
            d0 = axes[0]
            d1 = np.linalg.svd(b, full_matrices=False)[2][0]
            d1 = d1 if d1 @ (b.T @ (a @ d0)) >= 0.0 else -d1
            axis, cosine = np.cross(d0, d1), float(np.clip(d0 @ d1, -1.0, 1.0))
            norm = np.linalg.norm(axis)
            turn = axis / norm * np.arctan2(norm, cosine) if norm > 0.0 else np.zeros(3)
            rotations[k] = Rotation.from_rotvec(turn).as_matrix()
        else:
            rotations[k] = rigid_alignment(a, b)[0]
        translations[k] = end - rotations[k] @ start
    return rotations, translations


def free_flight(before, nxt, after, start_limit: float | None, steady: np.ndarray | None) -> np.ndarray | None:
    """Per component (C,), whether it is in free flight through a gap and hit right after it (see
    :data:`FREE_FLIGHT_NONRIGIDITY`), from the non-rigidity (C,) of the keys before the gap, at its
    end and after it, each seen from its start key; or None if no component is. A first gap
    (``start_limit`` set) counts from rest only (its key before is an end condition); a later one
    needs ``steady`` (C,): the centroid at constant acceleration up to the gap's end."""
    before, nxt, after = np.asarray(before), np.asarray(nxt), np.asarray(after)
    if start_limit is None and steady is not None:
        flight = np.where(steady, np.maximum(before, nxt), np.inf)
    elif start_limit == REST_START_LIMIT:
        flight = nxt
    else:
        return None
    free = ((flight < FREE_FLIGHT_NONRIGIDITY) & (after > 2.0 * FREE_FLIGHT_NONRIGIDITY)
            & (after > FREE_FLIGHT_JUMP * flight))
    return free if free.any() else None


def after_impact(before, nxt, incoming, outgoing, start_limit: float | None) -> np.ndarray | None:
    """Per component (C,), whether a gap starts right after an impact (see :data:`IMPACT_SLOWDOWN`),
    from the non-rigidity (C,) of the keys before the gap and at its end, seen from its start key,
    and the distances (C,) its centroid moved over the gap before (``incoming``) and over this one
    (``outgoing``); or None if no component does. Not in a sequence's first gap (``start_limit``
    set), whose key before is an end condition."""
    if start_limit is not None:
        return None
    before, nxt = np.asarray(before), np.asarray(nxt)
    hit = ((before > 2.0 * FREE_FLIGHT_NONRIGIDITY) & (before > FREE_FLIGHT_JUMP * nxt)
           & (np.asarray(incoming) > IMPACT_SLOWDOWN * np.asarray(outgoing)))
    return hit if hit.any() else None


class _Topology:
    """What depends only on the triangles: edge incidence (``D``: corner edges × vertices), lumped
    vertex masses of the first pose (mean 1), components, and the factorized normal matrices."""

    def __init__(self, topo, first_pose: np.ndarray):
        n_vertices = first_pose.shape[0]
        self.n = n_vertices
        self.first_pose = first_pose  # where pieces are seen to sit on each other (inbetween_carried)
        t = self.triangles = topo.triangles
        m = t.shape[0]
        self.i, self.j = t.ravel(), t[:, [1, 2, 0]].ravel()  # corner edge c of triangle k: row 3k + c
        rows = np.arange(3 * m)
        self.D = sp.csr_matrix((np.r_[-np.ones(3 * m), np.ones(3 * m)], (np.r_[rows, rows], np.r_[self.i, self.j])),
                               shape=(3 * m, n_vertices))
        # the same incidence with rows corner-major (row c·m + k), for the fit's component-wise
        # arrays (3 coordinates, 3 corners, m): contiguous per coordinate and corner
        self.Dc = sp.csr_matrix((np.r_[-np.ones(3 * m), np.ones(3 * m)],
                                 (np.r_[rows, rows], np.r_[t.T.ravel(), t[:, [1, 2, 0]].T.ravel()])),
                                shape=(3 * m, n_vertices))
        self.Dct = self.Dc.T.tocsr()
        self.laplacian = (self.Dct @ self.Dc).tocsc()
        self._incidences: dict = {}
        edges = self.corner_edge_rows(first_pose)
        cross = coordinate_cross(edges[:, 0], edges[:, 2])
        areas = 0.5 * np.sqrt(coordinate_dot(cross, cross))
        mass = lumped_vertex_areas(t, areas, n_vertices)
        used = mass > 0
        self.mass = np.where(used, mass / mass[used].mean(), 1.0)  # loose vertices follow the guide
        self.weights = np.where(used, self.mass, 0.0)
        _, labels = topo.components()
        per_vertex = vertex_labels(t, labels, n_vertices)
        kept = np.unique(labels)
        self.triangle_component = np.searchsorted(kept, labels)
        self.piece_sizes = np.bincount(self.triangle_component)  # triangles per component
        self.vertex_component = np.where(per_vertex >= 0, np.searchsorted(kept, per_vertex), -1)
        # the vertices in triangles, their components, and in component order (each in vertex order)
        self.component_vertices = np.flatnonzero(self.vertex_component >= 0)
        self.component_labels = self.vertex_component[self.component_vertices]
        self.component_order = self.component_vertices[np.argsort(self.component_labels, kind="stable")]
        self.component_starts = np.r_[0, np.cumsum(np.bincount(self.component_labels, minlength=kept.size))[:-1]]
        self.components = np.split(self.component_order, self.component_starts[1:]) if kept.size else []
        self.pieces_in_order = np.array_equal(self.component_order, np.arange(n_vertices))  # no gather needed
        # loose vertices (in no triangle) move with the piece nearest them in the first pose: its
        # rigid motion carries them (a whole mesh turned rigidly turns them too) and undone, their
        # keys' spline is interpolated in its frame
        self.loose = np.flatnonzero(per_vertex < 0)
        self.vertex_owner = self.vertex_component.copy()
        if self.loose.size and self.components:
            from scipy.spatial import cKDTree

            used_rows = np.flatnonzero(per_vertex >= 0)
            nearest = cKDTree(first_pose[used_rows]).query(first_pose[self.loose])[1]
            self.vertex_owner[self.loose] = self.vertex_component[used_rows[nearest]]
        self.all_in_one = len(self.components) == 1 and self.components[0].size == n_vertices  # no loose vertex
        # what selects each component's vertices: a slice where they are consecutive (one component
        # and no loose vertex, or pieces joined into one object in their vertex order), so that the
        # poses per key, relative and rigid motion are views rather than (n, 3) copies
        self.component_rows = [slice(rows[0], rows[-1] + 1) if rows.size and rows[-1] - rows[0] + 1 == rows.size else rows
                               for rows in self.components]
        self.triangles_per_vertex = np.bincount(t.ravel(), minlength=n_vertices)
        adjacency = sp.csr_matrix((np.ones(3 * m, dtype=bool), (t.ravel(), np.repeat(np.arange(m), 3))),
                                  shape=(n_vertices, m))
        self.vertex_triangles = adjacency  # (n, m): the triangles around each vertex
        self.edges_per_vertex = np.bincount(self.i, minlength=n_vertices) + np.bincount(self.j, minlength=n_vertices)
        self._uniform: dict[float, object] = {}
        #: Vertices at one place in every key (pins), or None: the pieces' rigid fits keep them there
        #: (:func:`core.inbetween_keys.rigid_fits`).
        self.pinned: np.ndarray | None = None

    def factor(self, weights: np.ndarray | float = GAUGE_WEIGHT, key=None) -> SPDFactor:
        """The factor of the symmetric positive definite ``DᵀD + diag(w · mass)`` for per-vertex
        ``weights`` (n,) or one weight for all (cached per value, or per ``key`` for per-vertex
        weights)."""
        uniform = np.isscalar(weights)
        cache = weights if uniform else key
        if cache is not None and cache in self._uniform:
            return self._uniform[cache]
        w = np.full(self.n, weights) if uniform else weights
        lu = SPDFactor(self.laplacian + sp.diags(w * self.mass))
        if cache is not None:
            self._uniform[cache] = lu
        return lu

    def incidence(self, dtype=np.float64) -> sp.csr_matrix:
        """``Dc`` with its ±1 entries in ``dtype`` (the index arrays shared)."""
        if dtype == np.float64:
            return self.Dc
        cached = self._incidences.get(np.dtype(dtype))
        if cached is None:
            cached = self._incidences[np.dtype(dtype)] = sp.csr_matrix(
                (self.Dc.data.astype(dtype), self.Dc.indices, self.Dc.indptr), shape=self.Dc.shape)
        return cached

    def corner_edge_rows(self, x: np.ndarray, dtype=np.float64) -> np.ndarray:
        """Corner edge vectors of positions ``x`` (n, 3) by coordinate: (3 coordinates, 3 corners,
        m), each (m,) row contiguous (one sparse product per coordinate), in ``dtype``. Element-wise
        work on these rows is 3–5× faster than on (m, 3, 3) blocks."""
        m = len(self.triangles)
        incidence = self.incidence(dtype)
        if np.dtype(dtype) != np.float64:  # edges are differences: taken about the middle, float32
            # keeps their digits far from the origin too (1e3 units out: 1e-3 of an edge); on
            # contiguous coordinate rows (3× faster than across (n, 3) rows)
            centred = np.ascontiguousarray(x.T)
            centred -= x.mean(axis=0)[:, None]
            coordinates = centred.astype(dtype)
        else:
            coordinates = np.ascontiguousarray(x.T)
        out = np.empty((3, 3 * m), dtype=dtype)
        for d in range(3):
            out[d] = incidence @ coordinates[d]
        return out.reshape(3, 3, m)

    def component_sums(self, values: np.ndarray) -> np.ndarray:
        """Per component (C, …), the sums of the mass-weighted ``values`` (n, …) of its vertices."""
        flat = values.reshape(self.n, -1)
        sums = self.weights @ flat if self.all_in_one else self.component_weights @ flat
        return sums.reshape((len(self.components),) + values.shape[1:])

    @cached_property
    def component_weights(self) -> sp.csr_matrix:
        """(C, n): each component's row holds its vertices' weights (a product sums per component
        at any count of pieces: 40 µs at 10k vertices, where a loop over 3,000 pieces took 30 ms)."""
        rows = self.component_vertices
        return sp.csr_matrix((self.weights[rows], (self.component_labels, rows)), shape=(len(self.components), self.n))

    @cached_property
    def component_mass(self) -> np.ndarray:
        """Each component's mass (C,): the sum of its vertices' weights."""
        return self.component_sums(np.ones(self.n))

    def centroids(self, x: np.ndarray) -> np.ndarray:
        """Each component's mass-weighted centroid (C, 3) in positions ``x`` (n, 3)."""
        return self.component_sums(x) / self.component_mass[:, None]

    def diagonals(self, x: np.ndarray) -> np.ndarray:
        """Each component's bounding-box diagonal (C,) in positions ``x`` (n, 3) (at least the
        smallest float; extents along contiguous coordinate rows: reductions across (n, 3) rows
        are 5× slower)."""
        if not self.components:
            return np.zeros(0)
        by_coordinate = np.ascontiguousarray(x.T)
        if self.all_in_one:
            extent = np.ptp(by_coordinate, axis=1)[None]
        else:
            ordered = by_coordinate if self.pieces_in_order else by_coordinate[:, self.component_order]
            starts = self.component_starts
            extent = (np.maximum.reduceat(ordered, starts, axis=1) - np.minimum.reduceat(ordered, starts, axis=1)).T
        return np.maximum(np.sqrt(np.einsum("ij,ij->i", extent, extent)), np.finfo(float).tiny)

    def apply_motion(self, x: np.ndarray, rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
        """``x`` (n, 3) with each component's rigid motion (C, 3, 3), (C, 3) applied (loose vertices:
        their owner's, ``vertex_owner``)."""
        if self.all_in_one:
            out = x @ rotations[0].T
            return shifted(out, translations[0], out=out)
        if not self.components:
            return x.copy()
        c = self.vertex_owner
        if len(self.components) > df.SLICED_PIECES:
            return df.matmul(rotations[c], x[:, :, None])[:, :, 0] + translations[c]
        out = np.empty_like(x)
        for k, rows in enumerate(self.component_rows):  # one product per piece, on a view where its rows are consecutive
            out[rows] = x[rows] @ rotations[k].T + translations[k]
        if self.loose.size:
            loose = self.loose
            out[loose] = df.matmul(rotations[c[loose]], x[loose, :, None])[:, :, 0] + translations[c[loose]]
        return out

    def undo_motion(self, x: np.ndarray, rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`apply_motion`."""
        inverse = np.transpose(rotations, (0, 2, 1))
        return self.apply_motion(x, inverse, -np.einsum("cab,cb->ca", inverse, translations))


class _Splines(dict):
    """A gap's splines by name, those of ``later`` ({name: function of nothing making it}) made
    when first read."""

    def __init__(self, later: dict):
        super().__init__()
        self._later = later

    def __missing__(self, name: str) -> HermiteGap:
        if name not in self._later:
            raise KeyError(name)
        spline = self[name] = self._later[name]()  # made twice at worst by two threads: the same spline
        return spline


def _log_stretch_spline(relatives: list, cubic: bool, options: dict, rows: np.ndarray | None = None) -> HermiteGap:
    """The spline of the ``relatives``' log-stretches (``options``: the gap's for it) on the
    triangles ``rows`` (index array; None: all). Per element: on some rows, the whole spline's
    values there."""
    if rows is None:
        return HermiteGap([r.log_stretch for r in relatives], cubic, **options)
    options = {name: value[rows] if isinstance(value, np.ndarray) else value for name, value in options.items()}
    if options["entry"] is not None:
        options["entry"] = tuple(part[rows] for part in options["entry"])
    return HermiteGap([r.log_stretch_rows(rows) for r in relatives], cubic, **options)


class _Gap(LocalGlobalFit):
    """One gap between key ``base`` (s = 0) and key ``next`` (s = 1), prepared once: splines of
    the relatives at key times −1, 0, 1, 2, the target edges' constant factors, the anchor and
    its factorization. :meth:`poses` answers any factors."""

    def __init__(self, topo: _Topology, base: _Key, nxt: _Key, relatives: list[_Relative], cubic: bool,
                 use_extrinsic: bool, anchored: bool, static: np.ndarray | None = None,
                 riding: list[np.ndarray] | None = None, start_limit: float | None = None,
                 whole_rotations: np.ndarray | None = None, steady: np.ndarray | None = None, entry: tuple | None = None,
                 hooked: list[np.ndarray] | None = None):
        self.topo, self.base, self.next = topo, base, nxt
        # per component: the relatives' rotvec are whole rotations, not residuals to the rigid motion
        self.whole_rotations = np.zeros(len(topo.components), dtype=bool) if whole_rotations is None else whole_rotations
        self.relatives = relatives
        self.cubic, self.use_extrinsic = cubic, use_extrinsic
        limit = TANGENT_LIMIT if start_limit is None else start_limit  # a sequence's first gap: its own
        free = impact = None
        if cubic:
            free = free_flight(*(r.nonrigidity for r in relatives[:1] + relatives[2:]), start_limit, steady)
            moves = np.linalg.norm(np.diff([r.centroids for r in relatives[:3]], axis=0), axis=2)  # (2, C)
            impact = after_impact(relatives[0].nonrigidity, relatives[2].nonrigidity, *moves, start_limit)

        def options(name: str) -> dict:
            # a piece that swings back inside the gap keeps its turn's tangent, as a point does (onward)
            return dict(rows=name in POSITIONS, limit=limit, onward=name == "screw",
                        parabolic_end=None if free is None else self.per_element(name, free),
                        parabolic_start=None if impact is None else self.per_element(name, impact),
                        entry=None if entry is None or name not in entry[1] else
                        (self.per_element(name, entry[0]), entry[1][name]))

        def hermite(name: str, values: list) -> HermiteGap:
            return HermiteGap(values, cubic, **options(name))
        # the log-stretches' spline when first read (see stretch; its function holds the
        # relatives, not the gap)
        self._log_options = options("log_stretch")
        spline = _Splines({"log_stretch": partial(_log_stretch_spline, relatives, cubic, self._log_options)})
        for name in ("vertices", "world", "centroids"):
            spline[name] = hermite(name, [getattr(r, name) for r in relatives])
        # the key after: the screw whose Catmull–Rom tangent is the next gap's start velocity
        spline["screw"] = hermite("screw", [r.screw for r in relatives[:3]] + [relatives[3].continued_screw])
        # the rotation residuals splined in each triangle's base frame (t1, t2, n), where their
        # tangents' per-element limits do not depend on how the scene is turned (see local_rotvec)
        spline["rotvec"] = hermite("rotvec", [self.local_rotvec(r.rotvec) for r in relatives])
        # between the keys the stretch comes from the metrics G = U² (see stretch)
        spline["metric"] = hermite("log_stretch", [r.metric for r in relatives])
        self.splines = spline
        nonrigidity = np.max([r.nonrigidity for r in relatives], axis=0)  # per component, over the keys
        rigid = nonrigidity < RIGID_PLACEMENT_SCALE
        self.flying = flying_groups(topo, relatives, rigid, nonrigidity)  # before any motion is asked for
        if self.flying is not None:  # each flying group's point at the keys (the pieces' centroids elsewhere)
            labels, points = self.flying
            rows = np.flatnonzero(labels >= 0)
            at_keys = []
            for r in relatives:
                where = r.centroids.copy()
                where[rows] = r.positions_of(points[labels[rows]], rows)
                at_keys.append(where)
            spline["flying"] = hermite("centroids", at_keys)
        self.anchored = anchored
        self.static = static  # bool (n,): pinned (core.pins: still, or riding on an animated object), or None
        # the riding sets (index arrays, core.pins) and the spline of each one's rigid motion from
        # the base key (screws whose turns continue across the keys: df.key_screws)
        self.riding = riding
        self.hooked = hooked  # two poses: the sets translating rigidly between them (HOOK_MISS_NOTED)
        if riding is not None:
            screws = df.key_screws([riding_motions(base.vertices, r.world, riding) for r in relatives],
                                   cubic and not relatives[3].extrapolated)
            self.riding_screws = HermiteGap(screws, cubic, limit=limit, onward=True)
        self._anchors: dict[bool, tuple] = {}
        self.mean_edge = float(np.mean(base.lengths))
        # rigid pieces jointed to each other move relative to the piece they hang from
        self.joints = None
        if len(topo.components) > 1:
            held = None if static is None else np.bincount(topo.component_labels, static[topo.component_vertices],
                                                           minlength=len(topo.components)) > 0
            self.joints = joint_tree(topo, base.vertices, nxt.vertices, relatives[2].motion, rigid,
                                     self.piece_moves(relatives), JOINT_REACH * self.mean_edge,
                                     nonrigidity > 0.5 * RIGID_PLACEMENT_SCALE, held)
        if self.joints is not None:
            spline["joint_screw"] = hermite("screw", joint_screws(self.joints[0], [r.screw for r in relatives],
                                                                  [r.extrapolated for r in relatives],
                                                                  [getattr(r, "motion", None) for r in relatives]))
        self._motions: dict[float, tuple] = {}  # see motion (its splines, flying groups and joints are set)
        # the fit stops at the whole change's tolerance but where a batch asks for the trimmed one
        # (core.inbetween_prediction.TRIMMED_TOLERANCE_BATCH; computed then)
        self.change_tolerance = change_tolerance(base.lengths, nxt.lengths)
        self.tolerance = self.change_tolerance
        self.anchor_weight = SEQUENCE_ANCHOR_WEIGHT
        # the world spline's strains at the middle of the gap per triangle, kept for
        # turning_as_a_whole (the same measure against the same reference)
        self._mid_world_strains = None
        if not anchored and max(relatives[2].nonrigidity) > RIGID_PLACEMENT_SCALE:
            reference = self.mid_gap_reference()
            self._mid_world_strains = self._triangle_strains(spline["world"].at(0.5), reference)
            strain = float(np.mean(self._mid_world_strains))
            if strain < SMOOTH_SPLINE_STRAIN and strain <= self.mid_gap_strain(
                    0.5 * (base.vertices + nxt.vertices), reference) + METRIC_TOLERANCE:
                self.anchor_weight = SMOOTH_ANCHOR_WEIGHT if strain < self.change_tolerance else SMOOTH_NEAR_ANCHOR_WEIGHT
        self.select(0.5)
        self.rigidity = np.clip(1.0 - nonrigidity / RIGID_PLACEMENT_SCALE, 0.0, 1.0)
        self.nonrigidity = nonrigidity
        # the splines' conditions for free flight and impacts act on the world spline: not there
        self._arc_candidates = np.full(len(topo.components), cubic and not anchored)
        for condition in (free, impact, None if entry is None else entry[0]):
            if condition is not None:
                self._arc_candidates &= ~np.asarray(condition, dtype=bool)
        self.repair = Repair(self)
        self.held_factors: dict[float, bool] = {}  # in-betweens solved with the weak anchor (see pose)
        self.carried = CarriedPieces(self)

    def piece_moves(self, relatives: list) -> np.ndarray:
        """How far each component (C,) moves over the gap's keys: the sum over ``relatives`` of
        its vertices' RMS move from the base key, in the world. Positions do not alias as turns
        do: a link turning 300° between keys reads as a turn of 60° the other way, but its
        vertices still sweep round."""
        topo, base = self.topo, self.base.vertices
        owner = topo.vertex_owner
        counts = np.maximum(np.bincount(owner[owner >= 0], minlength=len(topo.components)), 1)
        total = np.zeros(len(topo.components))
        for r in relatives:
            moved = np.einsum("ij,ij->i", r.world - base, r.world - base)
            total += np.sqrt(np.bincount(owner[owner >= 0], moved[owner >= 0], minlength=len(topo.components)) / counts)
        return total

    def local_rotvec(self, rotvec: np.ndarray) -> np.ndarray:
        """Per-triangle rotation vectors (m, 3) in world coordinates → in the triangle's frame
        ``(t1, t2, n)`` in the base key (m, 3). The splines limit tangents per element; in world
        coordinates those limits depend on the world's axes, and a scene turned by a general
        rotation came back up to 5e-2 of its diagonal off the unturned scene's in-betweens (a
        balloon, keys 16 apart; 1e-6 in these frames)."""
        if not rotvec.any():  # the base key's own (no turn): zero in any frame
            return np.zeros_like(rotvec)
        w = np.ascontiguousarray(rotvec.T)
        return np.stack([coordinate_dot(self.base.column_rows[c], w) for c in range(3)], axis=1)

    def world_rotvec(self, local: np.ndarray) -> np.ndarray:
        """Rotation vectors (m, 3) in the triangles' base frames → in world coordinates (m, 3):
        the inverse of :meth:`local_rotvec` (a view of coordinate rows, as the frames take them)."""
        columns = self.base.column_rows
        out = columns[0] * local[:, 0]
        out += columns[1] * local[:, 1]
        out += columns[2] * local[:, 2]
        return out.T

    def per_element(self, name: str, per_component: np.ndarray) -> np.ndarray:
        """``per_component`` (C,) spread to the rows of spline ``name`` (a column, to broadcast):
        vertices for positions, components for rigid motions and centroids, triangles for fields
        (loose vertices: their owner's, ``_Topology.vertex_owner``)."""
        topo = self.topo
        if name in ("vertices", "world"):
            rows = per_component[topo.vertex_owner] if topo.components else np.zeros(topo.n, dtype=bool)
        elif name in ("screw", "centroids"):
            rows = per_component
        else:
            rows = per_component[topo.triangle_component]
        return rows[:, None]

    def select(self, s: float) -> None:
        """Set the anchor for factor ``s``: one pattern for in-betweens (0 < s < 1), one for
        extrapolations, each computed and factorized once (``weights``, ``co_moving``, ``system``
        and ``by_centroid``)."""
        between = 0.0 < s < 1.0
        if between not in self._anchors:
            topo = self.topo
            weights, co_moving, key = None, None, None
            if self.anchored:
                weights, co_moving = self.anchor_weights(between)
                if self.static is not None:  # still in both keys: held there as firmly as in sequences
                    weights = self.pinned_weights(weights)
                    co_moving = co_moving & ~self.static
                # by value: the two fits of an Interpolator (core.interpolation) share their topology
                # and mostly their weights, and then one factorization
                key = ("anchored", weights.tobytes())
            else:  # sequences: one pattern for the whole sequence, factorized once
                # the spline in the world where a component deforms, with its interpolated rigid
                # motion undone where it moves rigidly (exact for rigid motions; mixed by its
                # rigidity as the centroid placement is), in the world for still vertices
                still = np.zeros(topo.n, dtype=bool) if self.static is None else self.static
                weights, co_moving, key = self.sequence_weights(), ~still, ("sequence", self.anchor_weight)
            if weights is not None and not (weights > GAUGE_WEIGHT).any():
                weights = None
            w = np.full(topo.n, GAUGE_WEIGHT) if weights is None else weights
            system = (topo.factor(GAUGE_WEIGHT if weights is None else w, key), w * topo.mass)
            self._anchors[between] = (weights, co_moving, system, self.centroid_placement(w, between))
        self.weights, self.co_moving, self.system, self.by_centroid = self._anchors[between]

    def centroid_placement(self, weights: np.ndarray, between: bool) -> np.ndarray:
        """Per component (C,), the share of the move onto its placed centroid (:meth:`place`) under
        anchor ``weights`` (n,): 1 without an anchored vertex; for the in-betweens of two poses,
        ``(1 − a / CENTROID_ANCHOR_SHARE)²`` up to that anchored share ``a`` of a component with no
        still vertex (see :data:`CENTROID_ANCHOR_SHARE`); 0 otherwise."""
        topo = self.topo
        rows, labels, count = topo.component_vertices, topo.component_labels, len(topo.components)
        anchored = np.bincount(labels, weights[rows] > GAUGE_WEIGHT, minlength=count) > 0
        shares = np.where(anchored, 0.0, 1.0)
        if self.anchored and between:
            still = np.zeros(count, dtype=bool) if self.static is None else \
                np.bincount(labels, self.static[rows], minlength=count) > 0
            held = topo.component_sums(np.minimum(weights / BLEND_ANCHOR_WEIGHT, 1.0)) / topo.component_mass
            partly = anchored & ~still
            shares[partly] = np.maximum(0.0, 1.0 - held[partly] / CENTROID_ANCHOR_SHARE) ** 2
        return shares

    def mid_gap_reference(self) -> np.ndarray:
        """The corner edge lengths (3 corners, m) :meth:`mid_gap_strain` measures against: the mean of
        the two keys', in the local steps' precision."""
        mean = 0.5 * (self.base.lengths + self.next.lengths).T
        return np.maximum(mean, np.finfo(float).tiny).astype(LOCAL_STEP_DTYPE)

    def mid_gap_strain(self, x: np.ndarray, reference: np.ndarray) -> float:
        """Mean relative deviation of the corner edge lengths of positions ``x`` (n, 3) from
        ``reference`` (3 corners, m; the mean of the two keys', see :data:`SMOOTH_SPLINE_STRAIN`),
        in the local steps' precision (the thresholds are 1e-3 and above)."""
        return float(np.mean(self._triangle_strains(x, reference)))

    def _triangle_strains(self, x: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """Per triangle (m,), :meth:`mid_gap_strain` of its three corner edges."""
        edges = self.edges_of(x, LOCAL_STEP_DTYPE)
        lengths = np.sqrt(coordinate_dot(edges, edges))
        return np.mean(np.abs(lengths / reference - 1.0), axis=0, dtype=np.float64)

    @cached_property
    def trimmed_tolerance(self) -> float:
        """The fit's tolerance for batches that trim (:func:`core.inbetween_fit.trimmed_tolerance`)."""
        return trimmed_tolerance(self.base.lengths, self.next.lengths)

    @cached_property
    def arc_guided(self) -> np.ndarray:
        """Per component (bool (C,)) of a sequence, whether the anchor's guide is its co-moving
        spline because it turns as a whole (:meth:`turning_as_a_whole`; not under a free-flight or
        impact condition). Computed when a guide is first asked for: a gap whose in-betweens need
        no solve (:func:`core.inbetween_prediction.gap_poses`) does without it."""
        if not self._arc_candidates.any():
            return self._arc_candidates
        return self.turning_as_a_whole() & self._arc_candidates

    def turning_as_a_whole(self) -> np.ndarray:
        """Per component (bool (C,)), whether the keys' per-vertex spline in the world strains it
        at the middle of the gap by over :data:`ARC_GUIDE_STRAIN_RATIO` × as much as its co-moving
        spline does, plus :data:`METRIC_TOLERANCE` (see there)."""
        topo = self.topo
        reference = self.mid_gap_reference()
        counts = np.maximum(topo.piece_sizes, 1)
        world = self._mid_world_strains  # measured by the constructor where it chose the anchor
        if world is None:
            world = self._triangle_strains(self.splines["world"].at(0.5), reference)
        co_moving = topo.apply_motion(self.splines["vertices"].at(0.5), *self.motion(0.5))
        moving = self._triangle_strains(co_moving, reference)
        world, moving = (np.bincount(topo.triangle_component, strains, minlength=len(counts)) / counts
                         for strains in (world, moving))
        return world > ARC_GUIDE_STRAIN_RATIO * moving + METRIC_TOLERANCE

    def rotations_against_guide(self) -> np.ndarray:
        """Per component (bool (C,)) of a sequence, whether its rotation residuals, composed with
        its interpolated rigid rotation, turn over :data:`AGAINST_GUIDE_SHARE` more of its triangles
        against the anchor's guide at the middle of the gap (normals more than 90° apart) than its
        triangles' whole rotations from the base key to the next, taken half-way, do; only pieces
        whose guide is the world spline (not :attr:`arc_guided`), whose rotations are residuals and
        whose rigid fit turns by more than :data:`AGAINST_GUIDE_TURN` between the keys."""
        topo, count = self.topo, len(self.topo.components)
        turns = np.linalg.norm(self.relatives[2].screw[:, :3], axis=1)
        candidates = ~self.whole_rotations & (turns > AGAINST_GUIDE_TURN)
        if not (self.cubic and not self.anchored and candidates.any()):
            return np.zeros(count, dtype=bool)
        candidates &= ~self.arc_guided
        if not candidates.any():
            return candidates
        motion = self.motion(0.5)
        guide = self.edges_of(self.guide(0.5, motion))
        guide_normals = coordinate_cross(guide[:, 0], -guide[:, 2])  # (3 coordinates, m)
        pieces = topo.triangle_component
        counts = np.maximum(np.bincount(pieces, minlength=count), 1)

        def against(rotvec, rotations):  # per component, the share of its triangles turned against the guide
            normals = df.rotated_frames(rotvec, rotations, pieces, self.base.column_rows[2:])[0]  # (m, 3)
            opposed = coordinate_dot(guide_normals, np.ascontiguousarray(normals.T)) < 0.0
            return np.bincount(pieces, opposed, minlength=count) / counts

        composed = against(self.world_rotvec(self.splines["rotvec"].at(0.5)), motion[0])
        candidates &= composed > AGAINST_GUIDE_SHARE  # the whole rotations' share is at least zero
        if not candidates.any():
            return candidates
        whole = self.relatives[2].whole_rotations(topo, self.base, self.next, candidates).rotvec
        return candidates & (composed > against(0.5 * whole, np.tile(np.eye(3), (count, 1, 1))) + AGAINST_GUIDE_SHARE)

    def held(self, misfits: list) -> bool:
        """Whether a sequence's fit with these ``misfits`` (per step) was held off the metric by
        the spline anchor (see :data:`HELD_MISFIT`)."""
        return (self.anchor_weight > HELD_ANCHOR_WEIGHT and len(misfits) > 1
                and misfits[-1] > HELD_MISFIT * self.tolerance and misfits[-1] > (1.0 - HELD_PROGRESS) * misfits[0])

    def weak_system(self) -> tuple:
        """(factor, per-vertex anchor) of the sequence's anchor at :data:`HELD_ANCHOR_WEIGHT` (pinned
        vertices as firmly as ever), factorized once per sequence."""
        w = self.pinned_weights(np.full(self.topo.n, HELD_ANCHOR_WEIGHT))
        return self.topo.factor(w, ("sequence", HELD_ANCHOR_WEIGHT)), w * self.topo.mass

    def sequence_weights(self) -> np.ndarray:
        """Per-vertex anchor weights (n,) of a sequence: the gap's ``anchor_weight``
        (:data:`SEQUENCE_ANCHOR_WEIGHT`, :data:`SMOOTH_NEAR_ANCHOR_WEIGHT` or
        :data:`SMOOTH_ANCHOR_WEIGHT`) to the keys' per-vertex
        spline (in the co-moving frame), :data:`STATIC_ANCHOR_WEIGHT` where the vertex is still
        in every key."""
        return self.pinned_weights(np.full(self.topo.n, self.anchor_weight))

    def pinned_weights(self, weights: np.ndarray) -> np.ndarray:
        """``weights`` (n,, per unit mass) with :data:`STATIC_ANCHOR_WEIGHT` per vertex on the
        pinned vertices (still and riding, :mod:`core.pins`)."""
        return weights if self.static is None else np.where(self.static, STATIC_ANCHOR_WEIGHT / self.topo.mass, weights)

    def pinned_positions(self, s: float) -> np.ndarray:
        """Where the pinned vertices (``static``) are at factor ``s`` ((p, 3), in their order):
        still ones where the base key has them, each riding set moved from there by its rigid
        motion's spline (:mod:`core.pins`)."""
        if self.riding is None:
            return self.base.vertices[self.static]
        return self.ride(self.base.vertices.copy(), s)[self.static]

    def ride(self, x: np.ndarray, s: float) -> np.ndarray:
        """``x`` (n, 3) with each riding set (:mod:`core.pins`) where the spline of its rigid motion
        puts it at factor ``s`` (in place; returned)."""
        base = self.base.vertices
        rotations, translations = df.rigid_exps(self.riding_screws.at(s))
        for rows, rotation, translation in zip(self.riding, rotations, translations):
            x[rows] = base[rows] @ rotation.T + translation
        return x

    def repair_anchor(self, free: np.ndarray) -> np.ndarray:
        """Anchor (per-vertex weight × mass) of the ``free`` vertices of a repair region: the
        gap's own for two poses; for sequences only the still vertices' (a repair imposes a local
        field and the region's boundary fixes its place: a pull toward the spline would fight it)."""
        anchor = self.system[1][free]
        if self.anchored:
            return anchor
        gauge = GAUGE_WEIGHT * self.topo.mass[free]
        return gauge if self.static is None else np.where(self.static[free], anchor, gauge)

    def anchor_weights(self, between: bool) -> tuple[np.ndarray, np.ndarray]:
        """Per-vertex weights (n,) anchoring to the linear blend where it keeps the keys' edge
        lengths (in-betweens) or, for extrapolations, where the edge vectors do not change (a
        linear extrapolation is exact only for translating parts) (see
        :data:`BLEND_ANCHOR_WEIGHT`), and per vertex whether the blend is taken in
        the world or with its component's rigid motion undone (``self.co_moving``, bool (n,)):
        the latter where the vertex moves with that rigid motion (edge vectors around it within
        BLEND_SHORTENING_SCALE of the base's once it is undone) and the world leaves them less
        unchanged (bool (n,)). Parts that do not move are anchored in the world (exact: they stay
        put), a rigidly moving mesh with its motion undone (exact at every factor)."""
        topo = self.topo
        a = topo.D @ self.base.vertices  # corner edges (3m, 3)
        b = topo.D @ self.next.vertices
        undone = self.relatives[2].vertices
        c = (undone[topo.j] - undone[topo.i])
        length_a = np.linalg.norm(a, axis=1)

        def per_vertex(values):
            return (np.bincount(topo.i, values, topo.n) + np.bincount(topo.j, values, topo.n)) / np.maximum(
                topo.edges_per_vertex, 1)

        def shortening(other):
            return np.abs(np.linalg.norm(a + other, axis=1) / (length_a + np.linalg.norm(other, axis=1)) - 1.0)

        co_moving_change = per_vertex(np.linalg.norm(c - a, axis=1) / length_a)
        world_change = per_vertex(np.linalg.norm(b - a, axis=1) / length_a)
        drift = np.linalg.norm(undone - self.base.vertices, axis=1) / self.base.diagonals[topo.vertex_owner]
        loose = topo.edges_per_vertex == 0  # no edge to judge by: with their owner where it takes them
        # a jointed piece's motion is its parent's composed with the relative one (core.inbetween_joints):
        # with it undone the blend follows the joints, where in the world it is their linear blend
        # (the last of three links bent +60° / −60° only translates: 4.5e-2 of the diagonal off at 0.5)
        child = np.zeros(topo.n, dtype=bool)
        if self.joints is not None:
            owner = topo.vertex_owner
            child = (owner >= 0) & (self.joints[0] >= 0)[np.maximum(owner, 0)]
        co_moving = ((co_moving_change < BLEND_SHORTENING_SCALE) & ((co_moving_change < world_change) | loose | child)
                     & (drift < CO_MOVING_DRIFT))
        if between:
            change = np.where(co_moving, per_vertex(shortening(c)), per_vertex(shortening(b)))
        else:
            change = np.where(co_moving, co_moving_change, world_change)
        falloff = (BLEND_SHORTENING_SCALE / np.maximum(change, BLEND_SHORTENING_SCALE)) ** 2
        weight = BLEND_ANCHOR_WEIGHT * falloff * np.maximum(0.0, 1.0 - change / BLEND_SHORTENING_CUTOFF) ** 2
        stretch = per_vertex(np.abs(np.linalg.norm(b, axis=1) / length_a - 1.0))
        if between:
            weight *= self.chord_falloff(change, co_moving, per_vertex(length_a), stretch)
            if self.use_extrinsic:
                weight[self.aliased_blend()] = 0.0
        weight[self.hung_from_pins(stretch, co_moving)] = 0.0
        return np.maximum(weight, GAUGE_WEIGHT), co_moving

    def hung_from_pins(self, stretch: np.ndarray, co_moving: np.ndarray) -> np.ndarray:
        """Vertices (bool (n,)) whose blend anchor in the world is let go because what joins them
        to the pins turns: the moving vertices (not pinned, not co-moving, in an edge) of a
        component that has a pinned vertex (:mod:`core.pins`: still in both keys) and keeps its
        edge lengths between the keys everywhere (``stretch``, each vertex's mean relative change
        of its edges' lengths, under :data:`~core.inbetween_fit.METRIC_TOLERANCE`). Such a component
        moves only by turning about its pins, so a part of it whose edge vectors do not change
        translates along the arcs of the turns between it and the pins, not along the blend's
        straight line (a strip folded +60° and −60° at two joints, base still: its end only
        translates, and anchored to the blend it was 3.7e-2 of the diagonal off at 0.5 with
        edges 6.6 % off, 0.28 at × 2); let go it hangs from the pins by the interpolated
        rotations. Parts that turn, mostly let go by the blend's shortening and
        :meth:`chord_falloff` already, are let go wholly (an arm bent 10° at the elbow of a still
        upper arm, the anchor its forearm kept: 2.7e-4 → 1.4e-6 of the diagonal off half-way).
        Cloth keeps its anchor: every edge of it changes length."""
        topo = self.topo
        if self.static is None or not topo.components:
            return np.zeros(topo.n, dtype=bool)
        rows, labels, count = topo.component_vertices, topo.component_labels, len(topo.components)
        worst = np.maximum.reduceat(stretch[topo.component_order], topo.component_starts)
        hung = (np.bincount(labels, self.static[rows], minlength=count) > 0) & (worst < METRIC_TOLERANCE)
        owner = topo.vertex_component
        return ((owner >= 0) & hung[np.maximum(owner, 0)] & ~co_moving & ~self.static
                & (topo.edges_per_vertex > 0))

    def aliased_blend(self) -> np.ndarray:
        """Vertices (bool (n,)) of a triangle whose edges the linear blend turns nearly opposite
        (over 143°: :data:`ALIASED_BLEND_COSINE`) to the interpolated field's half-way:
        a part turning by nearly a whole turn between the keys (a sheet rolled into a tube, its
        free edge turned by 315°), whose edges the blend barely shortens (a turn of 315° reads as
        one of −45°) while it cuts straight across the turn. Anchored there, the in-between of a
        sheet rolled by 5.5–6.2 rad came out 0.005–0.37 of its width off before the checks (the
        half roll exact to 1e-3 up to 5.3 rad)."""
        topo = self.topo
        motion = self.motion(0.5)
        frames = self.key_frames(self.world_rotvec(self.splines["rotvec"].at(0.5)), motion[0], columns=2)
        target = self.local_targets(frames, self.stretch(0.5))["edges"]  # (m, 3 corners, 3)
        blend = self.edges_of(0.5 * (self.base.vertices + self.next.vertices)).transpose(2, 1, 0)
        cosine = np.einsum("mcd,mcd->mc", target, blend) / np.maximum(
            np.linalg.norm(target, axis=2) * np.linalg.norm(blend, axis=2), np.finfo(float).tiny)
        aliased = (cosine < ALIASED_BLEND_COSINE).any(axis=1)
        return np.bincount(topo.triangles.ravel(), np.repeat(aliased, 3), minlength=topo.n) > 0

    def chord_falloff(self, change, co_moving, edge, stretch) -> np.ndarray:
        """Per vertex (n,), the share of the blend anchor kept where the blend cuts the chord of a
        turn: a vertex whose neighbourhood keeps its edge lengths between the keys (``stretch``,
        its mean relative change, under :data:`~core.inbetween_fit.METRIC_TOLERANCE`) and turns by
        θ (from the blend's shortening ``change`` = 1 − cos(θ/2)) is off the blend by
        ``|b − a| · change / (2 sin(θ/2))`` (the sagitta of its arc); beyond
        :data:`BLEND_SHORTENING_SCALE` of its mean edge length ``edge`` the anchor falls off with its
        square. An arm bent 20° at the elbow was 2.4e-3 of the diagonal off half-way (its forearm
        held near the chord, edges 1.2 % off), now 1.4e-4; 30°: 3.8e-3 → 4e-5. Co-moving vertices
        and deforming cloth keep their anchor: on cloth every edge changes length between keys, and
        applied there too the curtain at g = 8 went from 0.911 to 1.672 × the blend's error."""
        move = np.linalg.norm(self.next.vertices - self.base.vertices, axis=1)
        half = np.arccos(np.clip(1.0 - change, -1.0, 1.0))
        sagitta = np.where(half > 1e-6, move * change / np.maximum(2.0 * np.sin(half), 1e-12), 0.0)
        sagitta = np.where(co_moving | (stretch >= METRIC_TOLERANCE), 0.0, sagitta)
        error = sagitta / np.maximum(edge, np.finfo(float).tiny)
        return (BLEND_SHORTENING_SCALE / np.maximum(error, BLEND_SHORTENING_SCALE)) ** 2

    # --- the interpolated field at one factor

    def targets(self, s: float, by_rows: bool = False):
        """Interpolated rotations as the images of the base's tangent frames (``frames`` (k, m, 3):
        ``R_T t1``, ``R_T t2`` and, for extrapolations (k = 3), ``R_T n``; with ``by_rows``, a
        :class:`_FramesByRows` that computes ``frames[:, rows]`` when asked), stretches (packed
        (m, 3)), the components' rigid motions (rotations (C, 3, 3), translations (C, 3)) and the
        guide positions (n, 3) at factor ``s``."""
        motion = self.motion(s)
        rotvec = self.world_rotvec(self.splines["rotvec"].at(s))
        columns = 2 if 0.0 < s < 1.0 else 3  # the normals only for extrapolations' flip checks
        frames = _FramesByRows(self, rotvec, motion[0], columns) if by_rows else \
            self.key_frames(rotvec, motion[0], columns=columns)
        return frames, self.stretch(s), motion, self.guide(s, motion)

    def stretch(self, s: float) -> np.ndarray:
        """The interpolated stretches (packed (m, 3)) at factor ``s``. Between the keys, the square
        root of the spline of the metrics ``G = U²`` (the first fundamental form in the base's
        tangent bases, linear in squared edge lengths): an edge a fold collapses between the keys
        shortens late, as cloth does, where the spline of ``log U`` shortens it early (numbers in
        docs/inbetweens.md, *What is interpolated*). The log spline where that metric is not
        positive definite, and outside the keys, where exaggerations need it to stay so."""
        if not 0.0 < s < 1.0:
            return df.exp_stretch(self.splines["log_stretch"].at(s))
        stretch, ok = df.sqrt_stretch(self.splines["metric"].at(s))
        if not ok.all():
            rows = np.flatnonzero(~ok)
            stretch[rows] = df.exp_stretch(self.log_stretch_rows(s, rows))
        return stretch

    def area_scale(self, s: float) -> np.ndarray:
        """``det U`` (m,) of the stretches :meth:`stretch` gives at factor ``s``, without them:
        ``√det G`` of the metric's spline between the keys, ``e^(tr L)`` of the log spline
        outside them and where that ``G`` is not positive definite."""
        if not 0.0 < s < 1.0:
            log = self.splines["log_stretch"].at(s)
            return np.exp(log[:, 0] + log[:, 2])
        scale, ok = df.sqrt_det(self.splines["metric"].at(s))
        if not ok.all():
            rows = np.flatnonzero(~ok)
            log = self.log_stretch_rows(s, rows)
            scale[rows] = np.exp(log[:, 0] + log[:, 2])
        return scale

    def log_stretch_rows(self, s: float, rows: np.ndarray) -> np.ndarray:
        """The log-stretches' spline at factor ``s`` on the triangles ``rows`` (index array): the
        whole spline's where it is made, else a spline of those rows alone (a few triangles where
        the metrics' spline is not positive definite: the keys' other log-stretches not made)."""
        if "log_stretch" in self.splines:
            return self.splines["log_stretch"].at(s)[rows]
        return _log_stretch_spline(self.relatives, self.cubic, self._log_options, rows).at(s)

    def guide(self, s: float, motion: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """The anchor's guide positions (n, 3) at factor ``s`` (``motion``: :meth:`motion` there):
        the keys' per-vertex spline (two poses: the linear blend), with each component's
        interpolated rigid motion undone where the anchor pattern says so (``co_moving``), mixed
        by rigidity in sequences; with no anchor but the gauge, the spline with the rigid motions
        undone."""
        base, offset = self._guide_parts(s, motion)
        guide = base if offset is None else base + offset
        return guide if self.riding is None else self.ride(guide, s)  # riding sets: their own motion

    def guide_offset(self, s: float, motion: tuple[np.ndarray, np.ndarray], arcs: bool = False) -> np.ndarray:
        """The guide (:meth:`guide`) less ``M(s) V(s)``, the keys' co-moving spline moved by the
        components' interpolated rigid motions (n, 3): zero at both keys, which both pass through;
        without ``arcs``, the world spline's offset on the components that turn as a whole."""
        base, offset = self._guide_parts(s, motion, arcs=arcs)
        return np.zeros_like(base) if offset is None else offset

    def _guide_parts(self, s: float, motion, arcs: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """``M(s) V(s)`` (n, 3) and the guide's offset from it (n, 3; None: no offset): the
        world spline's where no vertex moves with its component's rigid motion, otherwise that
        times one less each vertex's share of the co-moving spline: its component's rigidity, or
        all of it where the component turns as a whole (:data:`ARC_GUIDE_STRAIN_RATIO`) unless
        ``arcs`` is False (the world spline there: the velocity a key's two gaps share)."""
        base = self.topo.apply_motion(self.splines["vertices"].at(s), *motion)
        if self.weights is None:
            return base, None
        offset = self.splines["world"].at(s) - base
        if self.co_moving.any():
            if self.anchored:
                mix = self.co_moving.astype(float)
            else:  # by rigidity, or wholly where the component turns as a whole (ARC_GUIDE_STRAIN_RATIO)
                share = np.maximum(self.rigidity, self.arc_guided) if arcs else self.rigidity
                mix = self.co_moving * share[self.topo.vertex_owner]
            scaled(offset, 1.0 - mix, out=offset)  # per coordinate column: 3× faster than broadcasting
        return base, offset

    def motion(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """The components' interpolated rigid motions at factor ``s``: rotations (C, 3, 3),
        translations (C, 3); the flying pieces (:func:`flying_groups`) turned about their group's
        point on the spline of its positions at the keys. Computed once per factor (a pose, its
        guide, checks and predictions ask for the same few; copies: callers may change them), at
        most :data:`MOTION_CACHE` factors held."""
        known = self._motions.get(s)
        if known is None:
            if len(self._motions) >= MOTION_CACHE:
                self._motions.clear()  # one call (threads share the cache): a factor asked again is recomputed
            known = self._motions[s] = self._motion(s)
        return known[0].copy(), known[1].copy()

    def _motion(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        motion = df.rigid_exps(self.splines["screw"].at(s))
        if self.flying is not None:  # turned about each group's point, which follows its spline
            labels, points = self.flying
            rotations, translations = motion
            rows = np.flatnonzero(labels >= 0)
            translations[rows] = self.splines["flying"].at(s)[rows] - np.einsum(
                "cab,cb->ca", rotations[rows], points[labels[rows]])
        if self.joints is None:
            return motion
        return composed(*self.joints, *motion, df.rigid_exps(self.splines["joint_screw"].at(s)))

    def key_frames(self, rotvec: np.ndarray, rotations: np.ndarray, rows=slice(None), columns: int = 3) -> np.ndarray:
        """Frames (columns, r, 3) of the rotations ``M_c · exp(rotvec)`` (``rotvec``: residuals
        (r, 3) of the triangles ``rows``, ``rotations``: the components' (C, 3, 3)): the images of
        the base's ``t1``, ``t2`` and, with ``columns=3``, ``n``; in the components of
        ``whole_rotations``, ``exp(rotvec)`` alone)."""
        if self.whole_rotations.any():
            rotations = np.where(self.whole_rotations[:, None, None], np.eye(3), rotations)
        return df.rotated_frames(rotvec, rotations, self.topo.triangle_component[rows],
                                 self.base.column_rows[:columns, :, rows])

    def place(self, x: np.ndarray, s: float, motion, partly: bool = False) -> np.ndarray:
        """Components without anchored vertices moved to their interpolated centroid (see
        :data:`RIGID_PLACEMENT_SCALE`); with ``partly``, instead those the anchor barely holds,
        by their share ``by_centroid`` of the way (see :meth:`centroid_placement`)."""
        rotations, translations = motion
        share = self.by_centroid
        moved = ((0.0 < share) & (share < 1.0)) if partly else share == 1.0
        if not moved.any():
            return x
        topo = self.topo
        rigid = np.einsum("cab,cb->ca", rotations, self.base.centroids) + translations
        spline = self.splines["centroids"].at(s)
        trust = self.similar_placement[0]
        if (trust > 0.0).any():  # nearly rigid or similar pieces: along their similarity (ARC_PLACEMENT_MISFIT)
            spline = trust[:, None] * self.similarity_path(s) + (1.0 - trust[:, None]) * spline
        seated, seat, miss = self.seated_placement
        if seated.any():  # deforming pieces sitting on a rigid one: with it (CarriedPieces, the other way)
            k = seat[seated]
            offset = self.base.centroids[seated] - self.base.centroids[k]
            spline[seated] = rigid[k] + np.einsum("cab,cb->ca", rotations[k], offset) + s * miss[seated]
        target = self.rigidity[:, None] * rigid + (1.0 - self.rigidity[:, None]) * spline
        move = np.where(moved[:, None], share[:, None] * (target - topo.centroids(x)), 0.0)
        rows = topo.component_vertices[moved[topo.component_labels]]
        x[rows] += move[topo.vertex_component[rows]]
        return x

    @cached_property
    def similar_placement(self) -> tuple[np.ndarray, tuple]:
        """Per component, the share (C,) of its centroid placement taken along the path of its best
        similarity from the base key to the next (:data:`ARC_PLACEMENT_MISFIT`) and that similarity:
        rotation vectors (C, 3) (its best rigid motion's, as the screw spline turns it), log-scales
        (C,) and translations (C, 3). The scale of the best similarity with the rigid motion's
        rotation (the same rotation is the best for both) is ``Σ w (R b̃)·õ / Σ w |b̃|²`` over the
        vertices' offsets from their centroids ``b̃`` (base) and ``õ`` (next)."""
        topo, count = self.topo, len(self.topo.components)
        none = np.zeros(count)
        nxt = self.relatives[2]
        rotations = getattr(nxt, "motion", (None,))[0]
        if not count or rotations is None or getattr(nxt, "extrapolated", False):
            return none, (np.zeros((count, 3)), none, np.zeros((count, 3)))
        owner = np.maximum(topo.vertex_owner, 0)
        c0, c1 = self.base.centroids, nxt.centroids
        b = self.base.vertices - c0[owner]
        o = self.next.vertices - c1[owner]
        turned = topo.apply_motion(b, rotations, np.zeros((count, 3)))
        spread = topo.component_sums(np.einsum("ij,ij->i", b, b))
        scale = topo.component_sums(np.einsum("ij,ij->i", turned, o)) / np.maximum(spread, np.finfo(float).tiny)
        positive = scale > 0.0
        scale = np.where(positive, scale, 1.0)
        residual = scale[owner][:, None] * turned - o
        misfit = np.sqrt(topo.component_sums(np.einsum("ij,ij->i", residual, residual)) / topo.component_mass)
        rotvec = np.asarray(nxt.screw)[:, :3] if len(np.shape(nxt.screw)) == 2 else df.rotation_vectors(rotations)
        rotated = np.einsum("cab,cb->ca", df.rigid_exps(np.c_[rotvec, np.zeros((count, 3))])[0], c0)
        similarity = (rotvec, np.log(scale), c1 - scale[:, None] * rotated)
        half, ok = df.similarity_paths(*similarity, c0, 0.5)
        departure = np.linalg.norm(half - self.splines["centroids"].at(0.5), axis=1)
        ratio = ARC_PLACEMENT_MISFIT * misfit / np.maximum(departure, np.finfo(float).tiny)
        # ... and only pieces nearly similar in shape: the departure grows with how far a piece
        # travels, its misfit does not (a sheet crumpling while thrown 10 units and turning 60°,
        # misfit 0.038 of its diagonal, was pulled onto the arc, 0.65 of its size off its path)
        low, high = SIMILAR_SHAPE_MISFIT
        shape = np.clip((high - misfit / np.maximum(self.base.diagonals, np.finfo(float).tiny)) / (high - low), 0.0, 1.0)
        trust = np.where(positive & ok & np.isfinite(ratio), np.clip(1.0 - ratio**2, 0.0, 1.0) * shape, 0.0)
        return trust, similarity

    @cached_property
    def seated_placement(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per component, whether its centroid placement follows a rigid piece it sits on (bool
        (C,)), that piece (C,) and what of its own centroid's move that piece's rigid motion misses
        between the keys (C, 3; :meth:`place` adds that share ``s`` of it): an eye that deforms
        (blinks) in a head turned rigidly, a garment's separate piece on a rigid body, placed
        otherwise on its centroid's spline (two poses: the chord of the head's arc; an eye squashed
        to 0.6 of its height in a head turned 60° came 1.9e-2 of the diagonal out of its socket at
        0.5 and 0.15 at ×2). The seat is read in the first pose as the carriers of
        :class:`core.inbetween_carried.CarriedPieces` are: the component of rigid pieces (``rigidity``
        > 0, not much smaller than the piece: :data:`core.inbetween_carried.CARRIER_SIZE`) holding most
        of the nearest vertices of other pieces within the piece's diagonal; it seats the piece in a
        gap where its rigid motion takes the piece's centroid within
        :data:`core.inbetween_carried.CARRIED_TOLERANCE` of the piece's diagonal of where it is in
        the next key."""
        from . import inbetween_carried as carried  # noqa: PLC0415

        topo, count = self.topo, len(self.topo.components)
        seated, seat, miss = np.zeros(count, dtype=bool), np.zeros(count, dtype=int), np.zeros((count, 3))
        # seats: pieces rigid to within noise (a head whose keys carry noise 6e-4 of the diagonal
        # has rigidity 0, and its blinking eyes went on their chords, 5.5e-2 off at 0.5)
        rigid = self.nonrigidity < SIMILAR_SHAPE_MISFIT[0]
        deforming = ~rigid
        if count < 2 or not rigid.any() or not deforming.any():
            return seated, seat, miss
        from scipy.spatial import cKDTree  # noqa: PLC0415

        first = topo.first_pose
        size = topo.diagonals(first)
        holders = topo.component_vertices[rigid[topo.component_labels]]
        rows = topo.component_vertices[deforming[topo.component_labels]]
        label = topo.vertex_component[rows]
        reach = carried.CARRIER_REACH * size
        # every deforming piece's vertices at once (meshes of many pieces: no loop per piece)
        distance, nearest = cKDTree(first[holders]).query(first[rows], k=carried.CARRIER_NEIGHBOURS,
                                                          distance_upper_bound=float(reach[deforming].max()))
        found = np.isfinite(distance) & (distance < reach[label][:, None])
        piece = np.broadcast_to(label[:, None], found.shape)[found]
        owner = topo.vertex_component[holders[nearest[found]]]
        large = size[owner] >= carried.CARRIER_SIZE * size[piece]
        piece, owner = piece[large], owner[large]
        if piece.size == 0:
            return seated, seat, miss
        pairs, votes = np.unique(piece * count + owner, return_counts=True)
        pair_piece, pair_owner = np.divmod(pairs, count)
        best = np.lexsort((-votes, pair_piece))  # per piece, the owner holding most of its nearest first
        first_of = best[np.r_[True, pair_piece[best][1:] != pair_piece[best][:-1]]]
        pieces, owners = pair_piece[first_of], pair_owner[first_of]
        enough = votes[first_of] >= carried.MIN_CARRIERS  # nearest vertices on the chosen seat itself
        pieces, owners = pieces[enough], owners[enough]
        rotations, translations = self.relatives[2].motion
        c0, c1 = self.base.centroids, self.relatives[2].centroids
        missed = c1[pieces] - (np.einsum("cab,cb->ca", rotations[owners], c0[pieces]) + translations[owners])
        held = np.linalg.norm(missed, axis=1) <= carried.CARRIED_TOLERANCE * self.base.diagonals[pieces]
        seated[pieces[held]], seat[pieces[held]], miss[pieces[held]] = True, owners[held], missed[held]
        return seated, seat, miss

    def similarity_path(self, s: float) -> np.ndarray:
        """Each component's centroid (C, 3) at factor ``s`` along its best similarity between the
        keys (:attr:`similar_placement`; :func:`core.deformation_fields.similarity_paths`)."""
        return df.similarity_paths(*self.similar_placement[1], self.base.centroids, s)[0]

    def region(self, force: np.ndarray) -> Region:
        """The vertices all of whose triangles are in ``force`` (bool (m,)) with their block of
        the normal matrix factorized (a repair moves only those)."""
        return Region(self, force)

    def local_fit(self, x, region: Region, frames, stretch, guide) -> np.ndarray:
        """``x`` with the free vertices of ``region`` re-solved so that the region's corner edges
        fit the field (``frames`` (k ≥ 2, r, 3), ``stretch`` (r, 3) of the region's triangles), the
        rest of ``x`` held fixed. Every edge of the region is imposed (no local step), so one
        solve is the fit."""
        out = x.copy()
        if region.free.size:
            if region.coordinates is None:  # the base's, shared by the fields imposed on the region
                coordinates = self.base.coordinates[region.rows]
                region.coordinates = np.ascontiguousarray(coordinates[..., 0]), np.ascontiguousarray(coordinates[..., 1])
            edges = self.local_targets(frames, stretch, region.rows, region.coordinates)["edges"]
            out[region.free] = region.solve(edges, x, guide)
        return out

    def pose(self, s: float, weak: bool | None = None) -> tuple[np.ndarray, str | None]:
        """(positions (n, 3), None) or, after a fallback, (positions, what happened). ``weak``: an
        in-between of a sequence fitted with the anchor at :data:`HELD_ANCHOR_WEIGHT` (True), with
        the gap's own (False), or with the gap's own and again with the weak one if the first fit
        is held off the metric (None; what was used is kept in ``self.held_factors[s]``)."""
        self.select(s)
        frames, stretch, motion, guide = self.targets(s)
        fitted = frames if self.use_extrinsic else None
        targets = self.fit_targets(fitted, stretch)  # shared by the Poisson solve and the fit
        between = 0.0 < s < 1.0 and not self.anchored
        if not (between and weak):
            if self.use_extrinsic:
                x0 = self.place(self.solve(targets["edges"], guide), s, motion)
            else:
                x0 = self.place(guide.copy(), s, motion)
            misfits, looser = [], []
            x = self.fit(x0, stretch, fitted, guide, s, motion, targets=targets, misfits=misfits, looser=looser)
            weak = weak is None and between and self.held(misfits)
        if between and weak:
            system = self.weak_system()
            x0 = self.solve(targets["edges"], guide, system) if self.use_extrinsic else guide.copy()
            looser = []
            x = self.fit(x0, stretch, fitted, guide, s, motion, targets=targets, system=system, looser=looser)
        if between:
            self.held_factors[s] = bool(weak)
        checked = self.repair.checked(x, x0, s, frames, stretch, guide, motion, looser=looser[0] if looser else None)
        return self.finished(checked, s)

    def repaired(self, x: np.ndarray, s: float, rings=None, defects=None) -> tuple[np.ndarray, str | None]:
        """``x`` (a pose at factor ``s`` with defects, e.g. a predicted one) repaired where the
        defects are, as :meth:`pose` repairs its fit (without solving the pose again; ``rings``:
        the repair rounds, all of them by default; ``defects``: those of ``x`` (bool (m,)) if known)."""
        self.select(s)
        # in-betweens' checks use the keys' normals: the repairs need the frames on their regions only
        frames, stretch, motion, guide = self.targets(s, by_rows=0.0 < s < 1.0)
        rounds = {} if rings is None else {"rings": rings}
        return self.finished(self.repair.checked(x, x, s, frames, stretch, guide, motion, defects=defects, **rounds), s)

    def finished(self, result, s: float):
        """``(x, problem)`` at factor ``s`` with the sequence's still vertices exactly where they sit
        in the keys and the rigid pieces that deforming ones carry moved with them
        (:mod:`core.inbetween_carried`), after the pieces the anchor barely holds are moved toward
        their centroid (:data:`CENTROID_ANCHOR_SHARE`; a translation each, after the fit and its
        repairs, which it leaves as they are)."""
        if self.static is not None:
            result[0][self.static] = self.pinned_positions(s)
        if ((self.by_centroid > 0.0) & (self.by_centroid < 1.0)).any():
            self.place(result[0], s, self.motion(s), partly=True)
        if self.hooked is not None and 0.0 < s < 1.0:
            said = self.off_their_paths(result[0], s)
            if said is not None:  # before a fallback's message, which Interpolator.pose may follow with its misfit
                result = (result[0], said if result[1] is None else f"{said}; {result[1]}")
        self.carried.place(result[0], s)
        return result

    def off_their_paths(self, x: np.ndarray, s: float) -> str | None:
        """What to say where a set of an in-between ``x`` (n, 3) of two poses that translates
        rigidly between them (``hooked``) is farther than :data:`HOOK_MISS_NOTED` of its piece's
        diagonal from its path, the linear blend at factor ``s``; None elsewhere."""
        base, nxt, owner = self.base.vertices, self.next.vertices, self.topo.vertex_owner
        misses = [np.linalg.norm(np.mean((1.0 - s) * base[rows] + s * nxt[rows] - x[rows], axis=0)) for rows in self.hooked]
        shares = [miss / self.base.diagonals[owner[rows[0]]] for miss, rows in zip(misses, self.hooked)]
        worst = int(np.argmax(shares))
        if shares[worst] <= HOOK_MISS_NOTED:
            return None
        # the centroid move (CENTROID_ANCHOR_SHARE) named only where it was made: a piece with a
        # still vertex, or one the anchor holds enough of, keeps the place its fit gives it
        moved = self.by_centroid[owner[self.hooked[worst][0]]] > 0.0
        return (f"{len(self.hooked[worst])} vertices that translate as one between the poses (pinned to an animated "
                f"object?) are {misses[worst]:.3g} ({100 * shares[worst]:.0f} % of their piece's diagonal) off their "
                "path, the linear blend: the interpolated shape of the rest of the piece does not reach them there "
                "(its keys differ too much, e.g. a stretch that relaxes between them)"
                + (", and the piece was placed by its centroid" if moved else ""))


def flying_groups(topo: _Topology, relatives: list, rigid: np.ndarray,
                  nonrigidity: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The rigid pieces of a sequence's gap turned about the point of theirs whose path the keys
    say is simplest: ``(labels (C,), points (G, 3))``, each piece's group (pieces moving by one
    rigid motion from the gap's base key to its next, to 1e-6 or what their fits are known to:
    ``nonrigidity`` (C,) as :data:`~core.deformation_fields.TURN_NOISE` says) or −1, and each
    group's point in the base key; None where no piece has a key before or after the gap to tell.

    A rigid piece's screw motion (:meth:`_Gap.motion`) turns it about one axis, which a door on
    its hinge or a wheel on its axle does; a body thrown while it spins turns about its centre as
    the centre flies on, and the screw swings it along a helix around an axis far from its path (a
    box flying and spinning 10° a frame, keys 16 frames apart: 14 × the linear blend's error).
    Over the keys around the gap, the point of the piece (in the base key) whose positions have
    the smallest third difference (constant acceleration; with a key on one side only, the second:
    constant velocity) is a point of the hinge's axis for a door, whatever its speed, and the
    centre of a thrown body, under gravity too: the piece turns about it while it follows the
    spline of its positions at the keys. Of the points equally simple (along a hinge's axis) the
    one nearest the group's centroid. Where no point of the piece's reach follows such a path to
    :data:`FLYING_TOLERANCE` of its size (one key beside the gap and the body accelerating; a body
    that orbits while it spins), the group's centroid: a flying body's centre of mass follows its
    own path (a box thrown under gravity, keys 8 apart, its two end gaps so: 0.23 × Catmull–Rom's
    error over the sequence; with the screw there 4.4 ×, with the best point of the constant-velocity
    test 1.32 ×)."""
    before, base, nxt, after = relatives
    known = [r for r in (before, after) if not r.extrapolated and getattr(r, "motion", None) is not None]
    if not rigid.any() or not known or getattr(nxt, "motion", None) is None:
        return None
    rotations, translations = nxt.motion
    candidates = np.flatnonzero(rigid & (np.linalg.norm(df.rotation_vectors(rotations), axis=1) > FLYING_MIN_TURN))
    if candidates.size == 0:
        return None
    diagonals = topo.diagonals(base.vertices)
    scale = max(float(np.max(diagonals)), float(np.max(np.ptp(base.centroids, axis=0))), np.finfo(float).tiny)
    motions = np.concatenate([rotations[candidates].reshape(-1, 9), translations[candidates] / scale], axis=1)
    # pieces whose motions are within 1e-6 of each other, linked: rounding them to 6 decimals split
    # equal motions of float32 keys across a rounding boundary (a character's hat, spun rigidly with
    # it, was turned about another point: 1.5–1.9e-2 off at the middle of one gap)
    from scipy.spatial import cKDTree

    from .seams import vertex_groups

    # ... and within what the fits are known to: float32 keys of 300 cards, 10 units out and keyed
    # every half turn, differ by ~1e-5, and each card alone turned about its centroid, off its circle
    spread = np.maximum(turn_spread(nonrigidity[candidates]), 0.5e-6)
    pairs = cKDTree(motions).query_pairs(2.0 * float(spread.max()), output_type="ndarray")
    if len(pairs):
        pairs = pairs[np.linalg.norm(motions[pairs[:, 0]] - motions[pairs[:, 1]], axis=1)
                      <= spread[pairs[:, 0]] + spread[pairs[:, 1]]]
    group = vertex_groups(pairs[:, 0], pairs[:, 1], len(candidates))
    count = int(group.max()) + 1
    mass = topo.component_mass[candidates]
    first = candidates[np.unique(group, return_index=True)[1]]  # a member's motion stands for its group's
    centroid = np.stack([np.bincount(group, mass * base.centroids[candidates, d], count) for d in range(3)],
                        axis=1) / np.bincount(group, mass, count)[:, None]
    # a group's reach: the diagonal of its members' bounding box (teeth turning about the jaw's
    # axis: a tooth's own diagonal missed the axis, 0.1 of the diagonal off at 120° per key)
    of_vertex = np.full(len(topo.components), -1, dtype=np.intp)
    of_vertex[candidates] = group
    of_vertex = of_vertex[topo.vertex_owner]
    rows = of_vertex >= 0
    low, high = np.full((count, 3), np.inf), np.full((count, 3), -np.inf)
    np.minimum.at(low, of_vertex[rows], base.vertices[rows])
    np.maximum.at(high, of_vertex[rows], base.vertices[rows])
    reach = np.linalg.norm(high - low, axis=1)
    # the differences of a body point p's positions R_j p + t_j over the keys: A p + b
    eye = np.broadcast_to(np.eye(3), (count, 3, 3))
    r1, t1 = rotations[first], translations[first]
    if len(known) == 2:
        r0, t0 = before.motion[0][first], before.motion[1][first]
        r2, t2 = after.motion[0][first], after.motion[1][first]
        a, b = r2 - 3.0 * r1 + 3.0 * eye - r0, t2 - 3.0 * t1 - t0
    elif after in known:
        r2, t2 = after.motion[0][first], after.motion[1][first]
        a, b = r2 - 2.0 * r1 + eye, t2 - 2.0 * t1
    else:
        r0, t0 = before.motion[0][first], before.motion[1][first]
        a, b = r1 - 2.0 * eye + r0, t1 + t0
    residual = np.einsum("gab,gb->ga", a, centroid) + b
    # the minimum-norm move from the centroid, all groups at once; directions the keys fix only to
    # within their fits' spread left out (a noisy half turn's axis: 1e-5 there sent the point 1e6 off)
    group_spread = np.zeros(count)
    np.maximum.at(group_spread, group, spread)
    move = df.least_squares_3x3(a, -residual, np.maximum(df.SCREW_CUTOFF, group_spread))
    point = centroid + move
    simple = (np.linalg.norm(move, axis=1) <= reach) & (
        np.linalg.norm(np.einsum("gab,gb->ga", a, point) + b, axis=1) <= FLYING_TOLERANCE * reach)
    points = np.where(simple[:, None], point, centroid)
    labels = np.full(len(topo.components), -1, dtype=np.intp)
    labels[candidates] = group
    return labels, points


class _FramesByRows:
    """The interpolated rotations' frames of a gap at one factor, computed only for the triangles
    asked, ``frames[:, rows]`` → (k, r, 3): a repair of a predicted in-between needs them on its
    regions only (the full set costs 12 ms at 100k triangles)."""

    def __init__(self, gap: _Gap, rotvec: np.ndarray, rotations: np.ndarray, columns: int = 3):
        self.gap, self.rotvec, self.rotations, self.columns = gap, rotvec, rotations, columns
        # each triangle's frames computed once: the repair rounds' growing regions and their
        # defect checks ask for overlapping rows again and again
        self._frames = np.empty((columns, len(rotvec), 3))
        self._done = np.zeros(len(rotvec), dtype=bool)

    def __getitem__(self, index):
        columns, rows = index
        if columns != slice(None):
            raise IndexError("frames by rows are indexed as [:, rows]")
        rows = np.arange(len(self._done))[rows] if isinstance(rows, slice) else np.asarray(rows)
        if rows.dtype == bool:
            rows = np.flatnonzero(rows)
        new = np.unique(rows[~self._done[rows]])
        if new.size:
            self._frames[:, new] = self.gap.key_frames(self.rotvec[new], self.rotations, new, self.columns)
            self._done[new] = True
        return self._frames[:, rows]
