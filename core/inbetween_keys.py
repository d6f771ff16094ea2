"""The keys of a gap for the in-between solver: per key its frames and edges (``Key``), and a key
seen from the base key of a gap (``Relative``): each component's rigid motion, the per-triangle
rotation residuals and log-stretches of :mod:`core.deformation_fields`, and the vertices with the
rigid motions undone — what :mod:`core.inbetween_solver` splines over a gap.

Each piece's rigid motion between two keys (with pins held, its screw coordinates and how far it
is known) is in :mod:`core.inbetween_rigid_fits`; the triangles' whole rotations between two keys
and the turns read from them (parts turning past a half turn, rigid fits that add turn) in
:mod:`core.inbetween_whole_rotations`, a mixin of ``Relative``.
"""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from . import deformation_fields as df
from . import rotation_continuity
from . import screw_motions
from . import small_matrices
from .cached_property import cached_property
from .concurrency import single_threaded_blas
from .geometry import coordinate_dot
from .inbetween_rigid_fits import component_nonrigidity, component_screws, pin_held_fits, rigid_fits, turn_spread, whole_tells
from .inbetween_whole_rotations import WholeRotations, rotation_angles
from .rigid_alignment import rigid_alignment
from .untold_triangles import triangle_heights

if TYPE_CHECKING:
    from .inbetween_topology import Topology


#: What a relative holds of the motion (rigid motions, positions, centroids), as opposed to the
#: deformation (rotation residuals, stretches).
KINEMATIC = ("screw", "vertices", "world", "centroids")
#: What of a relative the splines interpolate (the metric comes from the log-stretch where a key
#: is extrapolated: :meth:`Relative._extrapolated`).
SPLINED = ("rotvec", "log_stretch") + KINEMATIC


class Key:
    """Per-key data: positions, the corner edges' lengths (m, 3), their tangent coordinates
    stored by coordinate (2, 3 corners, m; ``coordinates``: the same as a (m, 3, 2) view), the
    inverse edge matrices' entries 00, 01, 11 (3, m), tangent frames (3 columns t1, t2, n;
    3 coordinates; m), normals (3, m), areas and component centroids."""

    def __init__(self, topo: Topology, vertices):
        v = np.asarray(vertices, dtype=np.float64)  # checked at the public boundary
        self.vertices = v
        edges = topo.corner_edge_rows(v)  # (3 coordinates, 3 corners, m)
        self.lengths = np.sqrt(coordinate_dot(edges, edges)).T  # (m, 3), a view
        self.column_rows, self.tangent_rows = df.tangent_frame_rows(edges)
        self.coordinates = self.tangent_rows.transpose(2, 1, 0)  # (m, 3, 2), a view: no second copy
        self.inverse_rows = df.inverse_edge_rows(self.tangent_rows)
        self.normal_rows = self.column_rows[2]
        self.areas = 0.5 * np.abs(self.tangent_rows[0, 0] * self.tangent_rows[1, 2])
        self.centroids = topo.centroids(v)
        self.diagonals = topo.diagonals(v)

    @cached_property
    def heights(self) -> np.ndarray:
        """Each triangle's smallest height (m,) (:func:`core.untold_triangles.triangle_heights`),
        made once for the several readings of a key (thin triangles, the rounding's tolerance)."""
        return triangle_heights(self.areas, self.lengths)


class Relative(WholeRotations):
    """Key ``other`` seen from the base key of a gap: each connected component's rigid motion
    (screw coordinates (C, 6)), per-triangle rotation residuals to it (rotation vectors (m, 3)),
    log-stretches and metrics ``G = U²`` (packed 2×2 in the base's tangent bases (m, 3) each) and
    the vertices with their component's rigid motion undone (n, 3)."""

    def __init__(self, topo: Topology, base: Key, other: Key, log_stretch=None, turns=None, across=None,
                 fits=None):
        # ``fits``: rigid_fits of these keys where the caller has them (a sequence keeps them per pair)
        if fits is None:
            fits = rigid_fits(topo, base.vertices, other.vertices)
        rotations, translations, self.misfits = fits
        turn, stretch = df.planar_polar(*df.planar_map_entries(other.tangent_rows, base.inverse_rows))
        # the triangles' whole rotations from the base as images of its frames: read by the pins'
        # fits (their entries, made once: _whole_entries), the residuals below and residuals_add_turn
        plane = self._plane_frames = df.plane_turned_frames(other.column_rows, turn)
        if topo.pinned is not None:
            rotations, translations, self.misfits = pin_held_fits(
                topo, base, other, partial(self._whole_entries, base, other, keep=True), rotations, translations,
                self.misfits)
        unwrap = turns is not None  # the continuation of the next key's turn
        self.nonrigidity = component_nonrigidity(self.misfits, base, topo)
        if turns is None:  # every piece's half turn goes the way the whole mesh turns: made when first read
            self._whole_of = (topo, base.vertices, other.vertices)
        else:
            self.screw = component_screws(rotations, translations, turns, unwrap, self.nonrigidity)
        # the triangles' rotations as images of the base frames, with their component's rotation undone
        frames = df.turned_coordinate_rows(plane, small_matrices.transpose(rotations), topo.triangle_component)
        self.rotvec = df.frame_rows_rotation_vectors(frames, base.column_rows)
        # two poses (``across``: the mesh's triangle pairs sharing an edge): taken continuous across
        # the mesh, so that a part turning past a half turn from the rest turns on the same way; a
        # sequence's neighbouring keys tell the way instead (continue_turns) but in the pieces where
        # a part turns past a half turn (core.sequence_turn_readings.TURNED_PART_SHARE): taken across the
        # whole mesh, a flag whipping in wind (keys 16 frames apart) jumped 2.58 → 5.45 × the simulation
        self._across = across
        if across is not None:  # the part that stays is the one whose whole rotation is least
            self.rotvec = rotation_continuity.continuous_rotation_vectors(self.rotvec, across, topo.triangle_component,
                                                                          partial(rotation_angles, plane, base.column_rows))
        if unwrap:  # kept for a key ahead of its gap's base alone: residuals_add_turn or whole_rotations reads them
            self.__dict__.pop("_plane_frames", None)
            self.__dict__.pop("_whole", None)
        if log_stretch is None:
            self._make_log = partial(_log_stretch_rows, stretch)
        else:
            self.log_stretch = log_stretch
        self.metric = df.squared_stretch(stretch) if log_stretch is None else df.exp_stretch(2.0 * log_stretch)
        self.vertices = topo.undo_motion(other.vertices, rotations, translations)
        self.world = other.vertices
        self.centroids = other.centroids
        self.turn, self.motion = turn, (rotations, translations)

    @property
    def screw(self) -> np.ndarray:
        """Screw coordinates (C, 6) of the components' rigid motions. Built without ``turns``, each
        piece's half turn goes the way the whole mesh turns (:meth:`_whole_turn`), made when first
        read: a sequence's key two ahead of a gap has its screws taken anew (:meth:`unwrap`) before
        anything reads them."""
        screw = self.__dict__.get("_screw")
        if screw is None:
            screw = self._screw = component_screws(*self.motion, self._whole_turn()[0], False, self.nonrigidity)
        return screw

    @screw.setter
    def screw(self, value: np.ndarray) -> None:
        self._screw = value

    @property
    def whole_tells(self) -> bool:
        """Whether the whole mesh's turn from the base key, which the pieces' half turns take the
        way of, has a way round itself (:func:`~core.inbetween_rigid_fits.whole_tells`); False for
        a relative built with ``turns``, or not from the poses."""
        return False if self.__dict__.get("_whole_of") is None else self._whole_turn()[1]

    @property
    def whole_turn(self) -> np.ndarray | None:
        """The whole mesh's rotation vector from the base key (3,) (:meth:`_whole_turn`); None for a
        relative built with ``turns``, or not from the poses."""
        return None if self.__dict__.get("_whole_of") is None else self._whole_turn()[0][0]

    def _whole_turn(self) -> tuple[np.ndarray, bool]:
        """The whole mesh's rotation vector from the base key repeated per component (C, 3) (its
        rigid fit; a mesh of one piece: that piece's), and :attr:`whole_tells`; made once."""
        known = self.__dict__.get("_whole_known")
        if known is None:
            topo, base, other = self._whole_of
            if len(topo.components) == 1:
                whole = self.motion[0][0]
            else:
                with single_threaded_blas():  # the fit's products summed as where the relatives are built
                    whole = rigid_alignment(base, other, topo.weights)[0]
            turns = np.repeat(df.rotation_vectors(whole[None]), len(topo.components), axis=0)
            known = self._whole_known = (turns, bool(whole_tells(turns[0])))
        return known

    #: The triangle pairs across which the rotations are taken continuous (two poses), or None.
    _across = None
    #: Per component (bool (C,)), whether its half turn's way round is not told by the keys
    #: (set by ``core.sequence_half_turns.HalfTurns._pieces_turning_on``).
    untold_half_turn = np.zeros(0, dtype=bool)
    #: The base key's and this key's positions (with the topology) that the whole mesh's turn is
    #: read from (:meth:`_whole_turn`), for a relative built from the poses without ``turns``.
    _whole_of = None
    #: Whether this is a sequence's end condition, extrapolated from the keys (:meth:`phantom`).
    extrapolated = False
    #: The log-stretches once made, and what makes them (a function of the triangles asked for,
    #: an index array or None for all; see log_stretch).
    _log = None
    _make_log = None

    @property
    def log_stretch(self) -> np.ndarray:
        """Log-stretches (m, 3), made when first read: between the keys a gap interpolates the
        metrics, and their logarithms only where the metrics' spline is not positive definite or
        outside the keys (:meth:`core.inbetween_field.InterpolatedField.stretch`)."""
        if self._log is None:  # the maker let go once they are made (it holds the stretches)
            self._log, self._make_log = self._log_source()(None), None
        return self._log

    @log_stretch.setter
    def log_stretch(self, value: np.ndarray) -> None:
        self._log, self._make_log = value, None

    def log_stretch_rows(self, rows: np.ndarray) -> np.ndarray:
        """:attr:`log_stretch` on the triangles ``rows`` (index array), the others' not made (each
        triangle's from its own stretch: the same values as the whole array's)."""
        return self._log_source()(rows)

    def _log_source(self):
        """A function of the triangles asked for (an index array, or None for all) giving
        :attr:`log_stretch` there, without holding this relative."""
        log = self._log
        if log is None:
            make = self._make_log
            if make is not None:
                return make
            log = self._log  # made meanwhile by another thread
        return partial(_rows_of, log)

    def inverse(self, topo: Topology, base: Key, other: Key, turns: np.ndarray) -> "Relative":
        """The relative of ``other`` seen from ``base`` when this one is ``base`` seen from
        ``other`` (its log-stretch from the poses), in closed form instead of from the poses
        again: the rigid motions inverted, rotation residuals ``−R_c q`` (the residual's inverse
        conjugated by its component's rotation), log-stretches ``−Q(θ) log S Q(θ)ᵀ`` (the planar
        map's inverse is ``S⁻¹ Q(−θ)``, whose stretch in the base's tangent basis is
        ``Q(θ) S⁻¹ Q(θ)ᵀ``), metrics ``(Q(θ) G Q(θ)ᵀ)⁻¹``. ``turns`` as for the constructor
        (unwrapped)."""
        out = Relative.__new__(Relative)
        rotations, translations = self.motion
        inverse_rotations = small_matrices.transpose(rotations)
        inverse_translations = -np.einsum("cab,cb->ca", inverse_rotations, translations)
        out.screw = component_screws(inverse_rotations, inverse_translations, turns, True, self.nonrigidity)
        out.misfits = list(self.misfits)
        out.nonrigidity = component_nonrigidity(self.misfits, base, topo)
        out.rotvec = -df.turned_rows(self.rotvec, rotations, topo.triangle_component)
        cos, sin = self.turn
        out._make_log = partial(_inverse_log_stretch, self._log_source(), cos, sin)
        g11, g12, g22 = _turned(self.metric, cos, sin).T  # the metric of the inverse: its inverse
        # a sliver whose height is under ~1e-8 of its side (validation accepts 1e-10) has a metric
        # whose determinant cancels to 0 or below: its inverse is then infinite or NaN, which the
        # metric's spline reads as not positive definite (the log-stretches' spline there)
        with np.errstate(divide="ignore", invalid="ignore"):
            out.metric = np.stack([g22, -g12, g11], axis=1) / (g11 * g22 - g12 * g12)[:, None]
        out.vertices = topo.apply_motion(other.vertices, rotations, translations)
        out.world = other.vertices
        out.centroids = other.centroids
        out.turn, out.motion = (cos, -sin), (inverse_rotations, inverse_translations)
        return out

    def unwrap(self, turns: np.ndarray, rotvec: np.ndarray, nxt: "Relative | None" = None) -> "Relative":
        """This relative (built without ``turns``) with its screw coordinates taken as if the
        constructor had been given ``turns`` (C, 3), its triangles' turns continued toward
        ``rotvec`` (:meth:`continue_turns`); with the relative ``nxt`` of the key between, the
        screws a spline takes for this key two steps on (:attr:`continued_screw`)."""
        self.screw = component_screws(*self.motion, turns, True, self.nonrigidity)
        if nxt is not None:
            self._continued = screw_motions.continued_screws(nxt.screw, nxt.motion, self.motion,
                                                             turn_spread(np.maximum(self.nonrigidity, nxt.nonrigidity)))
        return self.continue_turns(rotvec)

    _continued = None

    @property
    def continued_screw(self) -> np.ndarray:
        """Screw coordinates (C, 6) a Catmull–Rom spline takes for this key when it is two steps
        on (:func:`core.screw_motions.continued_screws`, set by :meth:`unwrap`), else ``screw``."""
        return self.screw if self._continued is None else self._continued

    def continue_turns(self, rotvec: np.ndarray) -> "Relative":
        """This relative with each triangle's rotation vector the representative nearest its row
        of ``rotvec`` (m, 3) (the continuation of a neighbouring key's: a triangle turning past a
        half turn between keys keeps turning the same way)."""
        self.rotvec = rotation_continuity.unwrapped_rotation_vectors(self.rotvec, rotvec)
        return self

    @classmethod
    def identity(cls, topo: Topology, base: Key) -> "Relative":
        self = cls.__new__(cls)
        m = topo.triangles.shape[0]
        self.rotvec, self.log_stretch = np.zeros((m, 3)), np.zeros((m, 3))
        self.metric = np.tile([1.0, 0.0, 1.0], (m, 1))
        self.screw = np.zeros((len(topo.components), 6))
        self.vertices = self.world = base.vertices
        self.centroids = base.centroids
        self.nonrigidity = [0.0] * len(topo.components)
        return self

    def rescaled(self, origin: "Relative", factor: float) -> "Relative":
        """The key ``origin + factor · (self − origin)`` in every splined quantity (the screw from
        :attr:`continued_screw`): a neighbouring key at another distance in time moved to where a
        spline with evenly spaced keys wants it (``factor``: the gap at hand's duration ÷ the
        neighbouring gap's), so that Catmull–Rom's tangent is the mean of the two neighbouring
        secants per unit time. Marked as an end condition (:attr:`extrapolated`): no pose has
        these values."""
        def value(name):
            here, there = (_splined(r, name) for r in (self, origin))
            return there + factor * (here - there)
        out = Relative._extrapolated(value, self.nonrigidity, ((1.0 - factor, origin), (factor, self)))
        out.rescaled_from = self
        return out

    @staticmethod
    def phantom(previous: "Relative", current: "Relative", farther: "Relative | None" = None) -> "Relative":
        """The key one step beyond ``current`` (end condition of the spline): the linear
        extrapolation 2·current − previous, or with ``farther`` (the key before ``previous``) for
        the motion (:data:`KINEMATIC`) the parabola through the three, 3·current − 3·previous +
        farther; the metric that of the extrapolated log-stretch (positive definite)."""
        def value(name):
            c, p = getattr(current, name), getattr(previous, name)
            if farther is not None and name in KINEMATIC:
                return 3 * (c - p) + _splined(farther, name)
            return 2 * c - p
        nonrigidity = np.maximum(previous.nonrigidity, current.nonrigidity)
        if farther is not None:
            nonrigidity = np.maximum(nonrigidity, farther.nonrigidity)
        recipe = ((3.0, current), (-3.0, previous), (1.0, farther)) if farther is not None else \
            ((2.0, current), (-1.0, previous))
        return Relative._extrapolated(value, nonrigidity, recipe)

    #: An end condition's positions as weights of the relatives they extrapolate ((weight,
    #: relative), …; :meth:`positions_of`), None for a key.
    recipe = None
    #: The key's own relative of an end condition that stands for a key (:meth:`rescaled`), else None.
    rescaled_from = None

    @property
    def key_world(self) -> np.ndarray | None:
        """The positions (n, 3) of the key this relative stands for — a rescaled key's are the
        key's own (:attr:`rescaled_from`) — or None for an end condition past the keys
        (:meth:`phantom`)."""
        if not self.extrapolated:
            return self.world
        return None if self.rescaled_from is None else self.rescaled_from.world

    def positions_of(self, points: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Where the points ``points`` (r, 3) of the base key, carried by the rigid motions of
        the components ``rows`` (r,), are in this key — for an end condition, extrapolated from
        the keys' by the rule its other positions were (:attr:`recipe`)."""
        if self.recipe is not None:
            return sum(weight * relative.positions_of(points, rows) for weight, relative in self.recipe)
        motion = getattr(self, "motion", None)
        if motion is None:  # the base key itself
            return points.copy()
        return np.einsum("rab,rb->ra", motion[0][rows], points) + motion[1][rows]

    @staticmethod
    def _extrapolated(value, nonrigidity, recipe=None) -> "Relative":
        """An end condition (:attr:`extrapolated`) with ``value(name)`` for each splined quantity
        (:data:`SPLINED`) and the metric of its log-stretch (positive definite); ``recipe``: its
        positions' weights of the relatives it extrapolates (:meth:`positions_of`)."""
        out = Relative.__new__(Relative)
        out.extrapolated = True
        out.recipe = recipe
        for name in SPLINED:
            setattr(out, name, value(name))
        out.metric = df.exp_stretch(2.0 * out.log_stretch)
        out.nonrigidity = nonrigidity
        return out


def _splined(relative: "Relative", name: str) -> np.ndarray:
    """The value of ``relative`` a spline takes for quantity ``name`` (the screw: its
    :attr:`Relative.continued_screw`)."""
    return relative.continued_screw if name == "screw" else getattr(relative, name)


def _log_stretch_rows(stretch: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    """The log-stretches of the packed ``stretch`` (m, 3) on the triangles ``rows`` (None: all)."""
    return df.log_stretch(stretch if rows is None else stretch[rows])


def _inverse_log_stretch(forward, cos: np.ndarray, sin: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    """The log-stretches of :meth:`Relative.inverse` on the triangles ``rows`` (None: all):
    ``−Q(θ) L Q(θ)ᵀ`` of those ``forward(rows)`` gives (the relative inverted), ``θ`` given by its
    cosines and sines (m,)."""
    if rows is not None:
        cos, sin = cos[rows], sin[rows]
    return -_turned(forward(rows), cos, sin)


def _rows_of(values: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    return values if rows is None else values[rows]


def _turned(packed: np.ndarray, cos: np.ndarray, sin: np.ndarray) -> np.ndarray:
    """``Q(θ) A Q(θ)ᵀ`` of symmetric 2×2 matrices ``A`` packed (m, 3), ``θ`` given by its cosines
    and sines (m,)."""
    a11, a12, a22 = packed.T
    return np.stack([cos * cos * a11 - 2 * cos * sin * a12 + sin * sin * a22,
                     cos * sin * (a11 - a22) + (cos * cos - sin * sin) * a12,
                     sin * sin * a11 + 2 * cos * sin * a12 + cos * cos * a22], axis=1)


def log_stretch_from_lengths(base: Key, corner_squared: np.ndarray) -> np.ndarray:
    """Packed log-stretches (m, 3) in the base's tangent bases whose metric ``U²`` gives the base's
    corner edges the squared lengths ``corner_squared`` (m, 3)."""
    a, b = base.coordinates[:, :, 0], base.coordinates[:, :, 1]
    system = np.stack([a * a, 2 * a * b, b * b], axis=2)  # (m, 3, 3) · (g11, g12, g22) = ℓ²
    metric = np.linalg.solve(system, corner_squared[:, :, None])[:, :, 0]
    return 0.5 * df.log_stretch(metric)
