"""The in-between solver objects (paper §7.3 in local/global form): per topology the factorized
normal matrix, per key its frames, per gap the splines of the deformation fields between its keys,
the anchor and the reconstruction of a pose at any factor.

``Topology`` (triangles only; :mod:`core.inbetween_topology`) → ``Key`` (one pose) →
``Relative`` (a key seen from the base key of a gap; both in :mod:`core.inbetween_keys`) →
``Gap`` (here: splines of the relatives at key times −1, 0, 1, 2 (:mod:`core.splines`) and
``pose(s)``), its parts one module per concept (the classes named are mixed into ``Gap``):

- :mod:`core.inbetween_field` (``InterpolatedField``): the interpolated field at a factor (the
  rotations' frames, the stretches) and the splines by name;
- :mod:`core.inbetween_motion` (``PieceMotion``): the pieces' interpolated rigid motions and the
  placement of pieces by their centroid;
- :mod:`core.inbetween_flight`: free flight, impacts and flying bodies, read from the keys;
- :mod:`core.inbetween_anchor` (``Anchor``): the anchor's weights, their factorization and the pins
  (their riding sets' motions: :mod:`core.pins`);
- :mod:`core.inbetween_guide` (``Guide``): the anchor's guide (the keys' spline in the world or
  co-moving);
- :mod:`core.inbetween_fit` (``LocalGlobalFit``): the Poisson solve and the local/global fit;
- :mod:`core.inbetween_repair`: checks and repairs; :mod:`core.inbetween_carried`: rigid pieces
  that deforming ones carry; :mod:`core.inbetween_joints`: jointed rigid pieces;
  :mod:`core.inbetween_joint_doubts`: the pieces the joints cannot place faithfully (warned).

The public classes live in :mod:`core.sequence_inbetweens` and :mod:`core.two_pose_inbetweens`.
"""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from . import deformation_fields as df
from . import screw_motions
from .cached_property import cached_property
from .inbetween_anchor import Anchor
from .inbetween_carriers import screw_departures
from .inbetween_carried import CarriedPieces
from .inbetween_field import InterpolatedField, Splines, log_stretch_spline
from .inbetween_fit import ARAP_ITERATIONS, LocalGlobalFit, change_tolerance, trimmed_tolerance
from .inbetween_flight import FLYING_MIN_TURN, after_impact, flying_groups, free_flight
from .inbetween_guide import Guide
from .inbetween_joint_doubts import joint_doubts
from .inbetween_joints import JOINT_REACH, contacts, joint_tree
from .inbetween_motion import RIGID_PLACEMENT_SCALE, SIMILAR_SHAPE_MISFIT, PieceMotion
from .inbetween_repair import Outcome, Repair
from .inbetween_repair_regions import Region
from .inbetween_rigid_fits import NEAR_HALF_TURN
from .pins import riding_motions
from .rigid_alignment import principal_frames
from .rigid_bodies import rigid_bodies
from .splines import TANGENT_LIMIT, HermiteGap, ScrewGap, slowing_end_correction

if TYPE_CHECKING:
    from .inbetween_keys import Key, Relative
    from .inbetween_topology import Topology

#: Two poses: a set of vertices that translates rigidly between them (pinned to an animated object
#: that does not turn, :func:`core.pins.riding_vertices`) lies on the linear blend at every factor,
#: where the blend anchor holds it; the move of a piece the anchor barely holds onto its centroid
#: (:data:`~core.inbetween_anchor.CENTROID_ANCHOR_SHARE`) carries it along with the rest of the
#: piece. Where the two disagree the interpolated shape of the piece does not reach the set (a
#: sheet whipped by its pinned corner, whose stretch at the corner relaxes between the keys: that
#: corner 0.53 off, 23 % of the sheet's diagonal, keys 4 frames apart), and holding the set there
#: instead costs edge length and flipped triangles elsewhere (docs/inbetween-measurements.md, *A pinned corner
#: off its path*).
#: An in-between whose set ends farther than this share of its piece's diagonal from the blend
#: says so in its warning: the whipped sheet's pairs miss by 0–46 %, the carried banner's pole by
#: 0–9.5 %.
HOOK_MISS_NOTED = 0.1


#: The splines of positions (their tangents are limited per point, see :class:`core.splines.HermiteGap`).
POSITIONS = ("vertices", "world", "centroids")


class Gap(Anchor, Guide, PieceMotion, InterpolatedField, LocalGlobalFit):
    """One gap between key ``base`` (s = 0) and key ``next`` (s = 1), prepared once: splines of
    the relatives at key times −1, 0, 1, 2, the target edges' constant factors, the anchor and
    its factorization. :meth:`poses` answers any factors."""

    #: Whether a part of a piece turns past a half turn from the rest between the keys with a jump
    #: of its rotations at a fold's crease, as the sequence that prepared the gap found it
    #: (:meth:`core.inbetween_whole_rotations.WholeRotations.turning`): the way round is not known, the gap warns.
    folded_turn = False
    #: Whether a part of a piece turns past a half turn from the rest between the keys and the way
    #: round read from them and from a neighbouring gap's keys disagree
    #: (:meth:`core.sequence_turn_readings.TurnReadings._unsure`), or its part that stays is not
    #: held still and its rigid turn reads it the other way round (``Relative.turning``): the gap warns.
    unsure_turn = False
    #: How many pieces turn a half turn between the keys, as short either way round, with nothing
    #: in the keys to tell which way (``core.sequence_half_turns.untold_half_turns``): the gap warns.
    untold_half_turns = 0
    #: Whether those are the whole mesh's half turn, every piece moving with it as one
    #: (``core.sequence_half_turns.turning_as_one``): the gap warns of the mesh, not of pieces.
    whole_half_turn = False
    #: Whether the stretch between the keys is the log spline's (``exp(s log U)``), not the root
    #: of the metric's spline (:meth:`core.inbetween_field.InterpolatedField.stretch`): the further
    #: fit of two poses (:data:`core.two_pose_inbetweens.LOG_METRIC_FIT`).
    log_metric = False
    #: For a gap with a turning piece, the largest share of a piece's area whose turn half-way as
    #: interpolated and as the turn of its part that stays composed with its own are over
    #: ``WRAP_CREASE`` apart (``core.sequence_turn_readings.composed_apart``): past
    #: ``TURNED_PART_SHARE`` the gap warns.
    composed_apart = 0.0
    #: The largest share of a piece's area that spins past a half turn about the piece's turn axis
    #: from the rest of it between the keys, read from patches of the mesh, in a piece whose turns the
    #: gap does not take continuous across the mesh, and that piece's largest turn (radians)
    #: (``core.spun_parts.SpunParts._spun``): past ``TURNED_PART_SHARE`` the gap warns.
    spun_part = (0.0, 0.0)
    #: Whether a piece's spin in the gap may be read the wrong way round by the keys, a gap next to
    #: it reading a near half turn one way and it the other
    #: (``core.sequence_half_turns.HalfTurns._aliased_spin``): the gap warns.
    aliased_spin = False
    #: Where no ``aliased_spin`` is said: how much nearer the turns of the gaps either side a piece's
    #: turn in the gap is taken the other way round than the short way, where both those gaps turn
    #: it the other way (``core.sequence_half_turns.HalfTurns._reversed_spin``; 0 where none): past 1
    #: the gap warns.
    reversed_spin = 0.0
    #: The largest turn (radians) between two rigid parts of one piece from the gap's first key to
    #: its second, a part bent about a joint (``core.sequence_bent_parts.bent_part_turns``), where it is
    #: past ``core.sequence_bent_parts.BENT_PART_TURN`` (else 0), in any piece, turning or not: a gap
    #: of a sequence of three keys or more is anchored as two poses are where such a turn (or one
    #: past ``RIGID_BENT_TURN`` of parts rigid to the keys' rounding) is in a piece it does not read
    #: turning, its pieces read turning left at the gauge (``SequenceInterpolator._bent_nearby``);
    #: read by no rule after, kept to tell what the gap read.
    bent_turn = 0.0
    #: The largest turn (radians) between two parts of a piece not read turning that the gap reads
    #: isometric but not rigid where the keys' coordinate rounding is too coarse to tell a bone's
    #: rigidity (``core.sequence_bent_parts.hidden_rigid_turn``), in a gap not anchored; 0 elsewhere:
    #: past 0 the gap warns.
    hidden_rigid_turn = 0.0

    def __init__(self, topo: Topology, base: Key, nxt: Key, relatives: list[Relative], cubic: bool,
                 use_extrinsic: bool, anchored: bool, static: np.ndarray | None = None,
                 riding: list[np.ndarray] | None = None, riding_tolerance: float = 0.0,
                 start_limit: float | None = None, rest_end: bool = False,
                 whole_rotations: np.ndarray | None = None, steady: np.ndarray | None = None, entry: tuple | None = None,
                 exit: tuple | None = None,
                 hooked: list[np.ndarray] | None = None, turning: np.ndarray | None = None,
                 root: np.ndarray | None = None, log_metric: bool = False, unit: float = 1.0, sewn=None,
                 left: np.ndarray | None = None, corrections: tuple | None = None, slowing_end: bool = False):
        self.topo, self.base, self.next = topo, base, nxt
        # groups of vertices both keys keep together along a seam, each one unknown in every solve
        # (core.sewn_seams.SewnGroups), or None
        self.sewn = sewn
        # the power of two the keys were scaled by (core.working_unit): distances in messages are
        # divided by it, so that they are in the caller's units
        self.unit = unit
        self.log_metric = log_metric
        # per component: a part of it turns far from the rest between the keys (past a half turn,
        # or past a right angle without a crease: Relative.turning): not anchored to the keys' spline
        self.turning = turning if turning is not None and turning.any() else None
        # per component: the pieces an anchored gap leaves at the gauge (bool (C,), or None): a
        # sequence's turning pieces where another piece is bent past its least turn
        # (SequenceInterpolator._bent_past, _bent_nearby), placed as the sequence places them
        self.left = left if left is not None and left.any() else None
        # ... and the vertices of the part of those the rest turns from (placed by it: PieceMotion.place)
        self.turning_root = None
        if self.turning is not None and root is not None and root.any():
            self.turning_root = np.zeros(topo.n, dtype=bool)
            self.turning_root[topo.triangles[root]] = True
        # per component: the relatives' rotvec are whole rotations, not residuals to the rigid motion
        self.whole_rotations = np.zeros(len(topo.components), dtype=bool) if whole_rotations is None else whole_rotations
        self.relatives = relatives
        self.cubic, self.use_extrinsic = cubic, use_extrinsic
        limit = TANGENT_LIMIT if start_limit is None else start_limit  # a sequence's first gap: its own
        free = impact = None
        if cubic:
            free = free_flight(*(r.nonrigidity for r in relatives[:1] + relatives[2:]), start_limit, steady)
            moves = np.linalg.norm(np.diff([r.centroids for r in relatives[:3]], axis=0), axis=2)  # (2, C)
            # the key after, as free flight reads it: a key at another spacing (rescaled) has its own
            # pose's non-rigidity; a sequence's end condition has its neighbours' larger (never a hit)
            impact = after_impact(relatives[0].nonrigidity, relatives[2].nonrigidity, *moves, start_limit,
                                  relatives[3].nonrigidity)

        def options(name: str) -> dict:
            # a piece that swings back inside the gap keeps its turn's tangent, as a point does (onward)
            return dict(rows=name in POSITIONS, limit=limit, onward=name == "screw", rest_end=rest_end,
                        parabolic_end=None if free is None else self.per_element(name, free),
                        parabolic_start=None if impact is None else self.per_element(name, impact),
                        entry=None if entry is None or name not in entry[1] else
                        (self.per_element(name, entry[0]), entry[1][name]),
                        # where the gap after starts after an impact: its positions' start velocity,
                        # the next gap's secant for the other splines (see SequenceInterpolator._exit)
                        exit=None if exit is None else
                        (self.per_element(name, exit[0]), exit[1].get(name)))

        def hermite(name: str, values: list, end: np.ndarray | None = None) -> HermiteGap:
            # the corrections to the world spline's start / end tangents (each (n, 3) or None: the
            # five keys', splines.five_key_tangent_correction; at a sequence's last key the slowing
            # end's, splines.slowing_end_correction); another spline's end correction: ``end``
            own = corrections if name == "world" else None if end is None else (None, end)
            return HermiteGap(values, cubic, **options(name), corrections=own)

        nonrigidity = np.max([r.nonrigidity for r in relatives], axis=0)  # per component, over the keys
        rigid = nonrigidity < RIGID_PLACEMENT_SCALE
        rigidity = np.clip(1.0 - nonrigidity / RIGID_PLACEMENT_SCALE, 0.0, 1.0)
        # a sequence's last gap whose positions slow into the last key (``slowing_end``: end="keys",
        # evenly spaced last gaps, SequenceInterpolator._tangent_correction): the rigid motions (the
        # pieces' and joints' screws, the flying bodies' points) slow there too, by each piece's
        # rigidity, the share of its guide its rigid motion places (Guide._guide_parts): a rigid
        # piece ends as the cloth does, a deforming one keeps its screw's linear end
        slowing = rigidity if slowing_end and cubic and rigidity.any() else None

        # the pieces' screws splined in their principal frames in the base key, about their
        # centroids (see ScrewGap); a linear spline limits nothing and stays in the world's
        pieces = principal_frames(base.vertices[topo.component_vertices], topo.component_labels,
                                  len(topo.components), topo.weights[topo.component_vertices]) if cubic else None
        # the log-stretches' spline when first read (see stretch; its function holds the
        # relatives, not the gap)
        self._log_options = options("log_stretch")
        spline = Splines({"log_stretch": partial(log_stretch_spline, relatives, cubic, self._log_options)})
        for name in ("vertices", "world", "centroids"):
            spline[name] = hermite(name, [getattr(r, name) for r in relatives])
        # the world spline half-way with Catmull–Rom's tangents where the five keys' change it: the
        # readings of how far the keys' per-vertex spline cuts the chords of arcs (the anchor's
        # mid-gap strain, Guide.turning_as_a_whole) were set on it, and a piece turning as a whole
        # keeps its co-moving guide (None: the world spline's own)
        self._chords_middle = None
        if cubic and corrections is not None and any(c is not None for c in corrections):
            self._chords_middle = HermiteGap([r.world for r in relatives], cubic, **options("world")).at(0.5)
        # the key after: the screw whose Catmull–Rom tangent is the next gap's start velocity
        spline["screw"] = ScrewGap([r.screw for r in relatives[:3]] + [relatives[3].continued_screw], pieces, cubic,
                                   slowing, **options("screw"))
        # the rotation residuals splined in each triangle's base frame (t1, t2, n), where their
        # tangents' per-element limits do not depend on how the scene is turned (see local_rotvec)
        spline["rotvec"] = hermite("rotvec", [self.local_rotvec(r.rotvec) for r in relatives])
        # between the keys the stretch comes from the metrics G = U² (see stretch)
        spline["metric"] = hermite("log_stretch", [r.metric for r in relatives])
        self.splines = spline
        self._turn_about_points(rigid, nonrigidity, hermite, slowing)  # before any motion is asked for
        self.anchored = anchored
        self.static = static  # bool (n,): pinned (core.pins: still, or riding on an animated object), or None
        # the riding sets (index arrays, core.pins) and the spline of each one's rigid motion from
        # the base key (screws whose turns continue across the keys: df.key_screws; a set within the
        # keys' rounding, riding_tolerance, of a line takes the least turn onto each key's line)
        self.riding = riding
        self.riding_tolerance = riding_tolerance
        self.hooked = hooked  # two poses: the sets translating rigidly between them (HOOK_MISS_NOTED)
        if riding is not None:
            screws = screw_motions.key_screws([riding_motions(base.vertices, r.world, riding, riding_tolerance)
                                               for r in relatives], cubic and not relatives[3].extrapolated)
            sizes = [len(rows) for rows in riding]
            frames = principal_frames(base.vertices[np.concatenate(riding)], np.repeat(np.arange(len(riding)), sizes),
                                      len(riding), np.ones(sum(sizes))) if cubic else None
            self.riding_screws = ScrewGap(screws, frames, cubic, limit=limit, onward=True, rest_end=rest_end)
        self._anchors: dict[bool, tuple] = {}
        self.mean_edge = float(np.mean(base.lengths))
        # rigid pieces jointed to each other move relative to the piece they hang from
        self.joints = self.joint_doubts = None
        if len(topo.components) > 1:
            piece_edges = np.bincount(topo.triangle_component, base.lengths.sum(axis=1),
                                      minlength=len(topo.components)) / (3 * topo.piece_sizes)
            reach, misfits = JOINT_REACH * self.mean_edge, nonrigidity * base.diagonals
            touching = contacts(topo, base.vertices, nxt.vertices, relatives[2].motion, rigid, reach, misfits)
            # a smooth sequence's joint groups hang from a piece that keeps to one screw over the keys
            # about the gap (two poses and linear gaps read their two keys alone); a neighbouring key
            # rescaled to even spacing (keys unevenly timed) is a key, its screw moved along the line
            # through the base key's and its own, which a steady screw's keys share
            departures = None
            if cubic and touching is not None and touching.key.size:
                departures = screw_departures([r.screw for r in relatives[:3]] + [relatives[3].continued_screw],
                                              [r.key_world is not None for r in relatives],
                                              base.vertices[topo.component_vertices], topo.component_labels,
                                              len(topo.components), misfits)
            self.joints = joint_tree(topo, base.vertices, nxt.vertices, relatives[2].motion, rigid,
                                     self.piece_moves(relatives), reach, nonrigidity > 0.5 * RIGID_PLACEMENT_SCALE,
                                     static, piece_edges, relatives[2].screw, misfits, touching, departures)
        # firmly rigid pieces that move as one body in every key the gap reads, however far apart,
        # take one motion (core.rigid_bodies): a pinned piece's or a link's where the body holds
        # one; a piece deforming past half the rigid scale (a sheet falling while it barely
        # creases, 7.7e-4) has turns known only to ~1e-2 rad, and is no body's part
        self.bodies = None
        firm = nonrigidity <= 0.5 * RIGID_PLACEMENT_SCALE
        if len(topo.components) > 1 and firm.sum() > 1:
            # pinned pieces and those others hang from lead a body (their motion keeps their pins,
            # carries their joints), never join one; pieces hanging from another with none from
            # them (leaves) join one that their parent or a sibling leads, or lead one before
            # unjointed pieces (core.rigid_bodies)
            links, parents = self.held_pieces(), None
            if self.joints is not None:
                parents = self.joints[0]
                links[parents[parents >= 0]] = True
            links &= firm
            candidates = firm & ~links
            known = [r.motion for r in relatives[:1] + relatives[2:]
                     if not r.extrapolated and getattr(r, "motion", None) is not None]
            scale = max(float(np.max(base.diagonals)), float(np.max(np.ptp(base.centroids, axis=0))),
                        np.finfo(float).tiny)
            self.bodies = rigid_bodies(known, candidates, nonrigidity, topo.component_mass, scale, links, parents)
        # ... the members of a body that turns take its leader's motion (PieceMotion.motion); a
        # body's pieces that only translate (turns under FLYING_MIN_TURN in every key: translations
        # to within the turn's arc) keep their own, which are its translation to that arc, unless
        # the leader hangs from a joint: its motion is then its parent's composed with its turn
        # relative to it, off its own translation's line between the keys (a scissor lift's
        # platform, a plate with a bracket pinned on the top bars, rises as the sine of the bars'
        # angle: on its own translation the plate would leave the bracket, 5.0e-2 of the diagonal at 0.5)
        self.body_members = None
        if self.bodies is not None:
            turn = np.max([np.linalg.norm(df.rotation_vectors(rotations), axis=1) for rotations, _ in known], axis=0)
            hung = np.zeros(len(topo.components), dtype=bool) if parents is None else parents >= 0
            members = np.flatnonzero((self.bodies != np.arange(len(topo.components)))
                                     & ((turn[self.bodies] > FLYING_MIN_TURN) | hung[self.bodies]))
            self.body_members = members if members.size else None
        # the joint screws' spline's frames, slowing and options, for the gap's joint tree and another
        # tree (PieceMotion.hung_motions); kept as values: a closure over ``options`` would hold the
        # gap in a reference cycle, freed only by a full garbage collection
        self._joint_spline_settings = (pieces, slowing, options("screw"))
        if self.joints is not None:
            spline["joint_screw"] = self._joint_spline(self.joints[0])
        self._motions: dict[float, tuple] = {}  # see motion (its splines, flying groups and joints are set)
        self._riding_motions: dict[float, tuple] = {}  # see ride
        # the fit stops at the whole change's tolerance but where a batch asks for the trimmed one
        # (core.inbetween_prediction.TRIMMED_TOLERANCE_BATCH; computed then)
        self.change_tolerance = change_tolerance(base.lengths, nxt.lengths)
        self.tolerance = self.change_tolerance
        self.choose_anchor_weight()
        self.select(0.5)
        self.rigidity = rigidity
        self.nonrigidity = nonrigidity
        # the splines' conditions for free flight and impacts act on the world spline: not there
        self._arc_candidates = np.full(len(topo.components), cubic and not anchored)
        for condition in (free, impact, None if entry is None else entry[0]):
            if condition is not None:
                self._arc_candidates &= ~np.asarray(condition, dtype=bool)
        # ... nor a piece that deforms (past SIMILAR_SHAPE_MISFIT's first share of its size over the
        # gap's keys) while its rigid fit turns near a half turn (NEAR_HALF_TURN): the two ways round
        # swing that arc to opposite sides of the chord, and a cloth folding over turns its parts
        # both ways. A tablecloth yanked off a table, keys 16 frames apart (fit 184°, non-rigidity
        # 0.14, its triangles 44-49 % about one way, the rest the other): guided along the arc it
        # stood on its hooked edge, 1.72 × the blend's RMS in that gap, 34,065 triangles facing away
        # from both keys; on its world spline 0.86 ×, 13. A sheet keeping its shape to 0.6 % while it
        # turns over 170° keeps its arc (see ARC_GUIDE_STRAIN_RATIO)
        near_half = np.linalg.norm(relatives[2].screw[:, :3], axis=1) > NEAR_HALF_TURN
        self._arc_candidates &= ~(near_half & (nonrigidity > SIMILAR_SHAPE_MISFIT[0]))
        self.repair = Repair(self)
        self.held_factors: dict[float, bool] = {}  # in-betweens solved with the weak anchor (see pose)
        # a sequence's in-betweens fitted: the least misfit of the fit each returned (core.sequence_edge_misfit)
        self.fit_misfits: dict[float, float] = {}
        self.outcomes: dict[float, Outcome] = {}  # what the checks of each factor's in-between returned
        # two poses: how many triangles of each factor's in-between face against the field (the
        # poses' normals facing the same way, and in all; DefectChecks.against_the_field)
        self.against: dict[float, tuple[int, int]] = {}
        self.carried = CarriedPieces(self)
        # deforming pieces turning as a whole are guided by their interpolated rigid motion
        # (Guide.arc_guided): those not held by pinned vertices (still, or riding on an object:
        # they turn about those) turn about a common axis of the keys' turns or about their
        # centroid, as rigid pieces do (core.inbetween_flight.DEFORMING_AXIS_NOISE), not about the
        # screw's axis, which swings a tumbling or carried cloth's centre off its path
        loose = self._arc_candidates & ~rigid & ~self.held_pieces()
        if loose.any():
            whole = self.arc_guided & loose
            if whole.any():
                self._turn_about_points(rigid | whole, nonrigidity, hermite, slowing)
                self._motions.clear()  # the screw's motions, asked for by arc_guided (its turns are the same)
        if len(topo.components) > 1:
            # what the joints leave untold (links apart, sliding joints, joints within rounding, gears
            # turned the other way round, carriers two poses or a sequence with no piece on one screw
            # do not tell, pieces each on an axle through them jointed between two poses), the pieces
            # of a body counted with its leader: the gap warns. Read last: a sequence's carriers are
            # compared as the gap places its pieces (hung_motions)
            self.joint_doubts = joint_doubts(topo, base.vertices, nxt.vertices, touching, reach, self.joints,
                                             piece_edges, misfits, base.diagonals, self.bodies,
                                             not cubic, static, relatives[2].screw, departures,
                                             None if departures is None else self.hung_motions)

    def held_pieces(self) -> np.ndarray:
        """Per component (bool (C,)), whether it has a pinned vertex (:attr:`static`, or of a riding set)."""
        topo = self.topo
        pinned = np.zeros(topo.n, dtype=bool) if self.static is None else self.static.copy()
        for rows in self.riding or ():
            pinned[rows] = True
        held = np.zeros(len(topo.components), dtype=bool)
        held[topo.vertex_owner[pinned]] = True
        return held

    def _turn_about_points(self, pieces: np.ndarray, nonrigidity: np.ndarray, hermite,
                           slowing: np.ndarray | None = None) -> None:
        """Set ``flying`` for the components ``pieces`` (bool (C,); :func:`~core.inbetween_flight.flying_groups`)
        and the spline of each group's point at the keys (the pieces' centroids elsewhere); ``slowing``:
        None, or per component (C,) the share of the slowing end's correction
        (:func:`~core.splines.slowing_end_correction`) its point's spline takes at a sequence's last key."""
        self.flying = flying_groups(self.topo, self.relatives, pieces, nonrigidity)
        if self.flying is not None:
            labels, points = self.flying
            rows = np.flatnonzero(labels >= 0)
            at_keys = []
            for r in self.relatives:
                where = r.centroids.copy()
                where[rows] = r.positions_of(points[labels[rows]], rows)
                at_keys.append(where)
            end = None
            if slowing is not None:
                end = slowing_end_correction(*at_keys[:3])
                end *= slowing[:, None]
            self.splines["flying"] = hermite("centroids", at_keys, end)

    @cached_property
    def trimmed_tolerance(self) -> float:
        """The fit's tolerance for batches that trim (:func:`core.inbetween_fit.trimmed_tolerance`)."""
        return trimmed_tolerance(self.base.lengths, self.next.lengths)

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

    def linear_blend(self, s: float) -> np.ndarray:
        """The linear blend (n, 3) of the gap's two keys at factor ``s``."""
        return (1.0 - s) * self.base.vertices + s * self.next.vertices

    def pose(self, s: float, weak: bool | None = None, start: np.ndarray | None = None,
             iterations: int = ARAP_ITERATIONS, misfits: list | None = None,
             repairable: float | None = None) -> tuple[np.ndarray, str | None]:
        """(positions (n, 3), None) or, after a fallback (or, two poses, with triangles facing against
        the field: :meth:`~core.inbetween_defects.DefectChecks.against_the_field`), (positions, what
        happened). ``weak``: an
        in-between of a sequence fitted with the anchor at
        :data:`~core.inbetween_anchor.HELD_ANCHOR_WEIGHT` (True), with the gap's own (False), or
        with the gap's own and again with the weak one if the first fit is held off the metric
        (None; what was used is kept in ``self.held_factors[s]``). ``start``: positions (n, 3) the
        fit starts from instead of the Poisson solve of the field (a sequence's in-between solved in
        place of a prediction, :data:`core.inbetween_prediction_repairs.SOLVED_INSTEAD_ITERATIONS`); no
        held test then (``weak`` None is the gap's own anchor: the test measures a fit's progress
        from the Poisson solve). ``iterations``: the fit's local/global steps at most; ``misfits``:
        a list that receives the misfit of each step of the fit whose pose is returned; ``repairable``:
        the most flipped or collapsed triangles the fit may have for the repair rounds to run on it
        (None: any; :meth:`core.inbetween_repair.Repair.outcome`)."""
        self.select(s)
        frames, stretch, motion, guide = self.targets(s)
        fitted = frames if self.use_extrinsic else None
        targets = self.fit_targets(fitted, stretch)  # shared by the Poisson solve and the fit
        between = 0.0 < s < 1.0 and not self.anchored
        steps = []
        if not (between and weak):
            if start is not None:
                x0 = start.copy()
            elif self.use_extrinsic:
                x0 = self.place(self.solve(targets["edges"], guide, s=s), s, motion)
            else:
                x0 = self.place(guide.copy(), s, motion)
            looser = []
            x = self.fit(x0, stretch, fitted, guide, s, motion, iterations, targets=targets, misfits=steps,
                         looser=looser)
            weak = weak is None and start is None and between and self.held(steps) \
                and self.released(targets.get("edges"), guide, targets)
        if between and weak:
            system = self.weak_system()
            if start is not None:
                x0 = start.copy()
            else:
                x0 = self.solve(targets["edges"], guide, system, s) if self.use_extrinsic else guide.copy()
            looser, steps = [], []
            x = self.fit(x0, stretch, fitted, guide, s, motion, iterations, targets=targets, system=system,
                         misfits=steps, looser=looser)
        if between:
            self.held_factors[s] = bool(weak)
            if steps:
                self.fit_misfits[s] = min(steps)
        if misfits is not None:
            misfits.extend(steps)
        # a fit from a given start has no Poisson solve to fall back on (x0 is x: none)
        x0 = x0 if start is None else x
        self._pins_set(x, s)  # as finished sets them, before the check, which then sees the pose returned
        checked = self.recorded(s, self.repair.outcome(x, x0, s, frames, stretch, guide, motion,
                                                       looser=looser[0] if looser else None, repairable=repairable))
        if not (self.anchored and 0.0 < s < 1.0 and self.use_extrinsic):
            return self.finished(checked, s)
        # two poses (sequences keep their fits), which also say where triangles face against the field
        x, said = self.finished(self.recorded(s, self.repair.nearer_the_metric(checked, s, frames, stretch, motion, targets)), s)
        turned, self.against[s] = self.repair.against_the_field(x, frames)
        return x, said if turned is None else turned if said is None else f"{said}; {turned}"

    def repaired(self, x: np.ndarray, s: float, rings=None, defects=None) -> tuple[np.ndarray, str | None]:
        """``x`` (a pose at factor ``s`` with defects, e.g. a predicted one) repaired where the
        defects are, as :meth:`pose` repairs its fit (without solving the pose again; ``rings``:
        the repair rounds, all of them by default; ``defects``: those of ``x`` (bool (m,)) if known),
        and :meth:`finished`."""
        return self.finished(self._repaired(x, s, None, rings, defects), s)

    def repaired_again(self, x: np.ndarray, s: float, nearby: np.ndarray | None = None, rings=None,
                       defects=None) -> tuple[np.ndarray, str | None]:
        """``x`` (a finished in-between of a sequence at factor ``s`` that kept defects) repaired again,
        with the local geometry of ``nearby`` (positions (n, 3) of another pose at ``s``, if given) as
        the rounds' last field (``rings``: the repair rounds, all of them by default; ``defects``: those
        of ``x`` (bool (m,)) if known). Only the repair regions move: the pieces keep the placement
        :meth:`finished` gave ``x``; the still vertices are put back where they sit in the keys."""
        out = self._repaired(x, s, nearby, rings, defects)
        self._pins_set(out[0], s)
        return out

    def _pins_set(self, x: np.ndarray, s: float) -> None:
        """The sequence's still vertices of ``x`` (n, 3) at factor ``s`` set, in place, exactly where
        they sit in the keys (:meth:`pinned_positions`); nothing without any."""
        if self.static is not None:
            x[self.static] = self.pinned_positions(s)

    def _repaired(self, x: np.ndarray, s: float, nearby, rings, defects) -> tuple[np.ndarray, str | None]:
        """:meth:`repaired` and :meth:`repaired_again` before their placement: the check of ``x``
        itself (no Poisson solve to fall back on), its outcome recorded."""
        self.select(s)
        # in-betweens' checks use the keys' normals: the repairs need the frames on their regions only
        frames, stretch, motion, guide = self.repair.factor_targets(s) if 0.0 < s < 1.0 else self.targets(s)
        rounds = {} if rings is None else {"rings": rings}
        return self.recorded(s, self.repair.outcome(x, x, s, frames, stretch, guide, motion, defects=defects,
                                                    nearby=nearby, **rounds))

    def recorded(self, s: float, outcome: tuple) -> tuple[np.ndarray, str | None]:
        """The pose and message of a check's ``outcome`` at factor ``s``
        (:meth:`core.inbetween_repair.Repair.outcome`), the rest of it (the count of flipped or
        collapsed triangles, whether it is the blend or a fit near it) kept in ``outcomes[s]``: the
        in-between's warning counts from it, and two poses choose between their fits by it
        (``core.two_pose_inbetweens.Interpolator.pose``). A check of a pose the caller does not take
        records its own too: the caller puts back the outcome of the pose it returns
        (:func:`core.inbetween_prediction_repairs._put_back`)."""
        x, message, count, near_blend = outcome
        self.outcomes[s] = Outcome(count, near_blend)
        return x, message

    def finished(self, result, s: float):
        """``(x, problem)`` at factor ``s`` with the sequence's still vertices exactly where they sit
        in the keys, the deforming pieces that ride on larger ones placed by them and the rigid
        pieces that deforming ones carry moved with them (:mod:`core.inbetween_carried`), after the
        pieces the anchor barely holds are moved toward their centroid
        (:data:`~core.inbetween_anchor.CENTROID_ANCHOR_SHARE`; a translation each, after the fit and
        its repairs, which it leaves as they are)."""
        self._pins_set(result[0], s)
        partly = ((self.by_centroid > 0.0) & (self.by_centroid < 1.0)).any()
        if partly or (0.0 < s < 1.0 and self.held_on_seats().any()):
            self.place(result[0], s, self.motion(s), partly=True)
        if self.hooked is not None and 0.0 < s < 1.0:
            said = self.off_their_paths(result[0], s)
            if said is not None:  # before a fallback's message, which Interpolator.pose may follow with its misfit
                result = (result[0], said if result[1] is None else f"{said}; {result[1]}")
        self.place_riders(result[0], s)
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
                f"object?) are {misses[worst] / self.unit:.3g} ({100 * shares[worst]:.0f} % of their piece's diagonal) "
                "off their path, the linear blend: the interpolated shape of the rest of the piece does not reach them "
                "there (its keys differ too much, e.g. a stretch that relaxes between them)"
                + (", and the piece was placed by its centroid" if moved else "") + "; add a key between the poses")
