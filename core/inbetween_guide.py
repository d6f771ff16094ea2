"""The anchor's guide (paper §7.3, where the reconstruction is pulled toward): the keys' per-vertex
spline (two poses: the linear blend) in the world, or moved by each piece's interpolated rigid
motion where the piece moves rigidly or turns as a whole, and the triangles whose whole rotations
are splined because their residuals would turn them against it. Mixed into
:class:`core.inbetween_solver.Gap`, whose data it reads (``topo``, ``base``, ``next``,
``relatives``, ``splines``, ``cubic``, ``anchored``, ``whole_rotations``, ``riding``, ``rigidity``,
``_mid_world_strains``, ``_chords_middle``, ``_arc_candidates``) with its other parts: the anchor (``weights``,
``co_moving``, ``ride``), the field's ``world_rotvec``, the fit's ``edges_of`` and the pieces'
``motion``."""

from __future__ import annotations

import numpy as np

from scipy.spatial.transform import Rotation

from . import deformation_fields as df
from .cached_property import cached_property
from .geometry import coordinate_cross, coordinate_dot, scaled
from .inbetween_fit import LOCAL_STEP_DTYPE, METRIC_TOLERANCE
from .inbetween_rigid_fits import rigid_fits

#: The sequence anchor's guide is the keys' per-vertex spline in the world where a component
#: deforms; where it turns as a whole that spline cuts the chords of its arcs (a cloth on a
#: turntable, 120° between keys 16 apart: its edges 37 % off the keys' at the middle of the gap,
#: the in-betweens 5.9 % and 0.596 × the blend's RMS). A component whose world spline's mid-gap
#: strain is over ARC_GUIDE_STRAIN_RATIO × that of its co-moving spline (the keys' shapes splined
#: with its rigid motion undone, moved by the interpolated rigid motion; 0.27 % there) plus
#: METRIC_TOLERANCE takes the co-moving spline as its guide; predicted in-betweens still leave
#: an inner key with the world spline's velocity, which the gaps on either side share
#: (:func:`core.inbetween_corrections._key_slope`; with the co-moving velocity, which each gap
#: takes from its own rigid fits, a sheet hanging from two corners jumped 2.67 × the
#: simulation's largest frame-to-frame acceleration at a key), and a sequence's last key with the
#: guide's. Components under a free-flight or impact condition (which act on the world spline)
#: keep it. Turntable 0.596 → 0.285 × the blend and edge deviation 2.39 → 0.65 % (bound 0.85 %);
#: 10k sheet hanging from two corners at g = 16 0.816 → 0.681 × Catmull–Rom; numbers in
#: docs/inbetween-measurements.md, *Cloth that turns as a whole*.
ARC_GUIDE_STRAIN_RATIO = 2.0
#: ... provided its rigid fits compose: the best rigid motion from key k − 1 to key k + 1 (and
#: from key k to key k + 2) within this angle (radians) of the one from k − 1 to k followed by the
#: one from k to k + 1 (and likewise on). A rigid motion composes exactly; a piece whose fits do
#: not has no turn of its own for the co-moving spline to follow. Largest mismatch over the gaps
#: guided by their co-moving splines on the benchmark's two hanging sheets, a skirt spun on a body,
#: a cape and a sheet carried on a rod that stops (keys 4, 8 and 16 apart): 0.4°, 0.6°, 0.4° and
#: 10.3°; a sheet whipped by a keyframed corner, keys 8 apart: 2° in the gaps where it swings out,
#: 34–54° where it flips over its corner (there the rigid fit from key to key turned 169° while
#: the simulated frames' fits, composed frame by frame, turned 134° about another axis: the
#: interpolated rigid turn was 128–170° off the frames' over the second half of the gap), and its
#: co-moving guide put the in-betweens at 1.3–1.8 × the Catmull–Rom spline's RMS there (the cell
#: 1.137 → 1.035 ×, 1.027 → 0.935 × the blend's). Numbers in docs/inbetween-measurements.md, *A whip's turns
#: that do not compose*.
ARC_FIT_COMPOSITION = np.pi / 6
#: A sequence's piece whose anchor follows the keys' spline in the world (not its co-moving
#: spline, :data:`ARC_GUIDE_STRAIN_RATIO`) has its triangles' whole rotations splined instead of
#: their residuals to its rigid rotation (:meth:`Guide.rotations_against_guide`) where, at the
#: middle of the gap, the residuals composed with its interpolated rigid rotation turn more of its
#: triangles against that guide (normals more than 90° apart) than the whole rotations taken
#: half-way do, by over this share of its triangles. The world spline does not turn with the
#: rigid fit; where the piece deforms so much that the fit explains little of its triangles' turns,
#: the composed rotations and the guide pull the in-between two ways and the fit crumples. A sheet
#: hanging from a keyframed corner and spinning 193° about it between keys 16 frames apart
#: (residuals 96°, whole rotations 116°, median): composed, 48 % of its triangles against the
#: guide half-way (whole: 2 %), 6,117 facing away from both keys and 17 % edge deviation in the
#: middle in-between (the simulated frame: 2,093 and 3.6 %); numbers in
#: docs/inbetween-measurements.md, *Rotations that pull against the guide*.
AGAINST_GUIDE_SHARE = 0.1
#: ... measured only on pieces whose rigid fit turns by more than this between the gap's keys
#: (radians; the check costs 4–5 ms per gap of the 15k curtain): where it took pieces whole they turned
#: 99–195°, and below a quarter turn no piece of the 16 benchmark cloths (keys 4, 8 and 16 frames
#: apart) or of six others (keys 16 apart) turned over 5.5 % of its triangles more against the guide
#: than its whole rotations did.
AGAINST_GUIDE_TURN = np.pi / 2


class Guide:
    """The guide's part of a gap: its positions at a factor and what decides them."""

    def guide(self, s: float, motion: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """The anchor's guide positions (n, 3) at factor ``s`` (``motion``:
        :meth:`~core.inbetween_motion.PieceMotion.motion` there): the keys' per-vertex spline (two
        poses: the linear blend), with each component's interpolated rigid motion undone where the
        anchor pattern says so (``co_moving``), mixed by rigidity in sequences; with no anchor but
        the gauge, the spline with the rigid motions undone."""
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
        base = self.topo.apply_motion(self.spline_at("vertices", s), *motion)
        if self.weights is None:
            return base, None
        offset = self.spline_at("world", s) - base
        if self.co_moving.any():
            if self.anchored:
                mix = self.co_moving.astype(float)
            else:  # by rigidity, or wholly where the component turns as a whole (ARC_GUIDE_STRAIN_RATIO)
                share = np.maximum(self.rigidity, self.arc_guided) if arcs else self.rigidity
                mix = self.co_moving * share[self.topo.vertex_owner]
            scaled(offset, 1.0 - mix, out=offset)  # per coordinate column: 3× faster than broadcasting
        return base, offset

    def mid_world(self) -> np.ndarray:
        """The keys' per-vertex spline in the world at the middle of the gap (n, 3) with Catmull–Rom's
        tangents (``_chords_middle`` where the five keys' tangents change the guide,
        :data:`~core.splines.FIVE_KEY_LIMIT`): what :meth:`mid_gap_strain`'s readings of the chords
        it cuts (the anchor's weight, :meth:`turning_as_a_whole`) were set on."""
        return self.splines["world"].at(0.5) if self._chords_middle is None else self._chords_middle

    def mid_gap_reference(self) -> np.ndarray:
        """The corner edge lengths (3 corners, m) :meth:`mid_gap_strain` measures against: the mean of
        the two keys', in the local steps' precision."""
        mean = 0.5 * (self.base.lengths + self.next.lengths).T
        return np.maximum(mean, np.finfo(float).tiny).astype(LOCAL_STEP_DTYPE)

    def mid_gap_strain(self, x: np.ndarray, reference: np.ndarray) -> float:
        """Mean relative deviation of the corner edge lengths of positions ``x`` (n, 3) from
        ``reference`` (3 corners, m; the mean of the two keys', see
        :data:`~core.inbetween_anchor.SMOOTH_SPLINE_STRAIN`), in the local steps' precision (the
        thresholds are 1e-3 and above)."""
        return float(np.mean(self._triangle_strains(x, reference)))

    def _triangle_strains(self, x: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """Per triangle (m,), :meth:`mid_gap_strain` of its three corner edges."""
        edges = self.edges_of(x, LOCAL_STEP_DTYPE)
        lengths = np.sqrt(coordinate_dot(edges, edges))
        return np.mean(np.abs(lengths / reference - 1.0), axis=0, dtype=np.float64)

    @cached_property
    def arc_guided(self) -> np.ndarray:
        """Per component (bool (C,)) of a sequence, whether the anchor's guide is its co-moving
        spline because it turns as a whole (:meth:`turning_as_a_whole`; not under a free-flight or
        impact condition, nor deforming while it turns near a half turn:
        :class:`core.inbetween_solver.Gap`). Computed when a guide is first asked for: a gap whose
        in-betweens need no solve (:func:`core.inbetween_prediction.gap_poses`) does without it."""
        if not self._arc_candidates.any():
            return self._arc_candidates
        return self.turning_as_a_whole() & self._arc_candidates

    def turning_as_a_whole(self) -> np.ndarray:
        """Per component (bool (C,)), whether the keys' per-vertex spline in the world strains it
        at the middle of the gap by over :data:`ARC_GUIDE_STRAIN_RATIO` × as much as its co-moving
        spline does, plus :data:`~core.inbetween_fit.METRIC_TOLERANCE` (see there), and its rigid
        fits compose (:meth:`fits_compose`)."""
        topo = self.topo
        reference = self.mid_gap_reference()
        counts = np.maximum(topo.piece_sizes, 1)
        world = self._mid_world_strains  # measured by the constructor where it chose the anchor
        if world is None:
            world = self._triangle_strains(self.mid_world(), reference)
        co_moving = topo.apply_motion(self.splines["vertices"].at(0.5), *self.motion(0.5))
        moving = self._triangle_strains(co_moving, reference)
        world, moving = (np.bincount(topo.triangle_component, strains, minlength=len(counts)) / counts
                         for strains in (world, moving))
        turning = world > ARC_GUIDE_STRAIN_RATIO * moving + METRIC_TOLERANCE
        return turning & self.fits_compose() if turning.any() else turning

    def fits_compose(self) -> np.ndarray:
        """Per component (bool (C,)), whether its best rigid motions over keys k − 1 … k + 2 compose
        (gap k): the fit from the first to the third key of each three within
        :data:`ARC_FIT_COMPOSITION` of the fit from the first to the second followed by the one from
        the second to the third. A neighbour past a sequence's end (extrapolated) is left out; an
        unevenly spaced one, which the spline moves to where an evenly spaced key would be, is
        taken as the key it is (the fits are of the poses, whatever their times)."""
        relatives, topo = self.relatives, self.topo
        keys = [relatives[0].key_world, self.base.vertices, self.next.vertices, relatives[3].key_world]
        fits: dict = {}

        def fit(i, j):  # rotations (C, 3, 3) of the best rigid motions from keys[i] to keys[j], each made once
            if (i, j) not in fits:
                fits[i, j] = rigid_fits(topo, keys[i], keys[j])[0]
            return fits[i, j]
        mismatch = np.zeros(len(topo.components))
        for first in (0, 1):
            if keys[first] is None or keys[first + 2] is None:
                continue
            composed = fit(first + 1, first + 2) @ fit(first, first + 1)
            turn = Rotation.from_matrix(fit(first, first + 2) @ np.swapaxes(composed, 1, 2)).magnitude()
            mismatch = np.maximum(mismatch, turn)
        return mismatch <= ARC_FIT_COMPOSITION

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
