"""The interpolated field of a gap at one factor (paper §7.3): the splines of its keys' relatives
by name, the rotations' frames (in the triangles' base frames, whole or composed with their
pieces' rigid motions) and the stretches (from the metrics' spline between the keys, the
log-stretches' outside them — a sliver's held at the nearer key's, :data:`HELD_BEYOND_KEYS` — and
between them where the gap's ``log_metric`` says so). Mixed
into :class:`core.inbetween_solver.Gap`, whose data it reads (``topo``, ``base``, ``relatives``,
``cubic``, ``whole_rotations``, ``log_metric``,
``splines``, ``_log_options``) with the pieces' ``motion`` and the
``guide`` (:mod:`core.inbetween_guide`)."""

from __future__ import annotations

import numpy as np

from . import deformation_fields as df
from .geometry import coordinate_dot
from .inbetween_fit import MISFIT_LENGTH_FLOOR
from .splines import HermiteGap
from .untold_triangles import thin_triangles


class Splines(dict):
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


def log_stretch_spline(relatives: list, cubic: bool, options: dict, rows: np.ndarray | None = None) -> HermiteGap:
    """The spline of the ``relatives``' log-stretches (``options``: the gap's for it) on the
    triangles ``rows`` (index array; None: all). Per element: on some rows, the whole spline's
    values there."""
    if rows is None:
        return HermiteGap([r.log_stretch for r in relatives], cubic, **options)
    options = {name: value[rows] if isinstance(value, np.ndarray) else value for name, value in options.items()}
    if options["entry"] is not None:
        options["entry"] = tuple(part[rows] for part in options["entry"])
    if options.get("exit") is not None:
        options["exit"] = tuple(None if part is None else part[rows] for part in options["exit"])
    return HermiteGap([r.log_stretch_rows(rows) for r in relatives], cubic, **options)


#: Beyond the keys a triangle's stretch is that of the nearer key where the triangle is less high
#: than this share of the gap's mean edge in either key (:func:`core.untold_triangles.thin_triangles`;
#: the fits' floor, :data:`~core.inbetween_fit.MISFIT_LENGTH_FLOOR`): exaggerating raises each triangle's stretch
#: between the keys to the factor's power, and a sliver 1e-9 of its edge high in one key that a
#: skin opens to 1e-3 in the other (a scan's T-junction on a skinned limb) grows 1e6 × between the
#: keys, 1e12 × at ×2: raised so, ×2 of a 100° bend of a capsule arm with 60 such slivers is 1e4 × its
#: diagonal off the rig with 4,318 triangles flipped; held, 7.5e-2 with 20 kept (as the same arm
#: whose slivers the skin leaves closed). Between the keys the stretches are interpolated, not
#: raised to a power: nothing is held there.
HELD_BEYOND_KEYS = MISFIT_LENGTH_FLOOR


class InterpolatedField:
    """The field's part of a gap: its rotations' frames, stretches and area scales at a factor."""

    @property
    def held_beyond_keys(self) -> np.ndarray:
        """Indices (int (k,)) of the triangles whose stretch beyond the keys is the nearer key's
        (:data:`HELD_BEYOND_KEYS`), found once per gap."""
        held = self.__dict__.get("_held_beyond_keys")
        if held is None:  # made twice at worst by two threads: the same rows
            held = self.__dict__["_held_beyond_keys"] = thin_triangles(
                self.base, self.next, HELD_BEYOND_KEYS * self.mean_edge)
        return held

    def _log_stretch(self, s: float, rows: np.ndarray | None = None) -> np.ndarray:
        """The log-stretches' spline (packed (m, 3), or (r, 3) of ``rows``) at ``s``; outside the
        keys, those of the :attr:`held_beyond_keys` triangles at the nearer key."""
        def at(t):
            return self.spline_at("log_stretch", t) if rows is None else self.splines["log_stretch"].at(t, rows)

        log = at(s)
        if 0.0 <= s <= 1.0:  # between the keys nothing is held; at a key its own stretch already
            return log
        held = self.held_beyond_keys
        if held.size:
            if rows is None:
                where = held
            else:
                where = np.flatnonzero(np.isin(rows, held))
            if where.size:
                log = np.array(log, copy=True)  # the spline's own values may be read-only
                log[where] = at(min(max(s, 0.0), 1.0))[where]
        return log

    def spline_at(self, name: str, s: float) -> np.ndarray:
        """The spline ``name`` evaluated whole at factor ``s``, read-only once the gap has its repair
        (:meth:`~core.inbetween_repair_rounds.RepairRounds.factor_spline`: kept for the in-between
        a thread works on)."""
        repair = self.__dict__.get("repair")
        return self.splines[name].at(s) if repair is None else repair.factor_spline(name, s)

    def local_rotvec(self, rotvec: np.ndarray) -> np.ndarray:
        """Per-triangle rotation vectors (m, 3) in world coordinates → in the triangle's frame
        ``(t1, t2, n)`` in the base key (m, 3). The splines limit tangents per element; in world
        coordinates those limits depend on the world's axes, and a scene turned by a general
        rotation came back up to 5e-2 of its diagonal off the unturned scene's in-betweens (a
        balloon, keys 16 apart; 1e-6 in these frames)."""
        if not rotvec.any():  # the base key's own (no turn): zero in any frame
            return np.zeros_like(rotvec)
        w = np.ascontiguousarray(rotvec.T)
        out = np.empty(rotvec.shape)
        for c in range(3):
            out[:, c] = coordinate_dot(self.base.column_rows[c], w)
        return out

    def world_rotvec(self, local: np.ndarray, rows=slice(None)) -> np.ndarray:
        """Rotation vectors (r, 3) in the base frames of the triangles ``rows`` (all by default) →
        in world coordinates (r, 3): the inverse of :meth:`local_rotvec` (a view of coordinate
        rows, as the frames take them)."""
        columns = self.base.column_rows[:, :, rows]
        out = columns[0] * local[:, 0]
        out += columns[1] * local[:, 1]
        out += columns[2] * local[:, 2]
        return out.T

    def per_element(self, name: str, per_component: np.ndarray) -> np.ndarray:
        """``per_component`` (C,) spread to the rows of spline ``name`` (a column, to broadcast):
        vertices for positions, components for rigid motions and centroids, triangles for fields
        (loose vertices: their owner's, ``Topology.vertex_owner``)."""
        topo = self.topo
        if name in ("vertices", "world"):
            rows = per_component[topo.vertex_owner] if topo.components else np.zeros(topo.n, dtype=bool)
        elif name in ("screw", "centroids"):
            rows = per_component
        else:
            rows = per_component[topo.triangle_component]
        return rows[:, None]

    def targets(self, s: float, by_rows: bool = False):
        """Interpolated rotations as the images of the base's tangent frames (``frames`` (k, m, 3):
        ``R_T t1``, ``R_T t2`` and, for extrapolations (k = 3), ``R_T n``), stretches (packed
        (m, 3)), the components' rigid motions (rotations (C, 3, 3), translations (C, 3)) and the
        guide positions (n, 3) at factor ``s``. With ``by_rows`` (in-betweens, 0 < s < 1) the frames
        and stretches are :class:`_ByRows`, computing ``frames[:, rows]`` and ``stretch[rows]``
        when asked: a repair of a predicted in-between reads them on its regions only."""
        motion = self.motion(s)
        columns = 2 if 0.0 < s < 1.0 else 3  # the normals only for extrapolations' flip checks
        if by_rows:
            m = len(self.topo.triangles)

            def frames_of(rows):
                return self.key_frames(self.world_rotvec(self.splines["rotvec"].at(s, rows), rows), motion[0], rows, columns)

            frames = _ByRows(frames_of, (columns, m, 3), 1)
            stretch = _ByRows(lambda rows: self.stretch(s, rows), (m, 3), 0)
            return frames, stretch, motion, self.guide(s, motion)
        frames = self.key_frames(self.world_rotvec(self.spline_at("rotvec", s)), motion[0], columns=columns)
        return frames, self.stretch(s), motion, self.guide(s, motion)

    def stretch(self, s: float, rows: np.ndarray | None = None) -> np.ndarray:
        """The interpolated stretches (packed (m, 3), or (r, 3) of the triangles ``rows`` alone: per
        element, the same values) at factor ``s``. Between the keys, the square
        root of the spline of the metrics ``G = U²`` (the first fundamental form in the base's
        tangent bases, linear in squared edge lengths): an edge a fold collapses between the keys
        shortens late, as cloth does, where the spline of ``log U`` shortens it early (numbers in
        docs/inbetweens.md, *What is interpolated*). The log spline where that metric is not
        positive definite, outside the keys, where exaggerations need it to stay so, and in a gap
        whose ``log_metric`` is set (two poses whose fit of the metric turns triangles over:
        :data:`core.two_pose_inbetweens.LOG_METRIC_FIT`)."""
        def at(name):  # the spline on the rows, or whole
            return self.spline_at(name, s) if rows is None else self.splines[name].at(s, rows)

        if not 0.0 < s < 1.0 or self.log_metric:
            return df.exp_stretch(self._log_stretch(s, rows))
        stretch, ok = df.sqrt_stretch(at("metric"))
        if not ok.all():
            bad = np.flatnonzero(~ok)
            stretch[bad] = df.exp_stretch(self.log_stretch_rows(s, bad if rows is None else rows[bad]))
        return stretch

    def area_scale(self, s: float) -> np.ndarray:
        """``det U`` (m,) of the stretches :meth:`stretch` gives at factor ``s``, without them:
        ``√det G`` of the metric's spline between the keys, ``e^(tr L)`` of the log spline
        outside them, where that ``G`` is not positive definite and with ``log_metric``."""
        if not 0.0 < s < 1.0 or self.log_metric:
            log = self._log_stretch(s)
            return np.exp(log[:, 0] + log[:, 2])
        scale, ok = df.sqrt_det(self.spline_at("metric", s))
        if not ok.all():
            rows = np.flatnonzero(~ok)
            log = self.log_stretch_rows(s, rows)
            scale[rows] = np.exp(log[:, 0] + log[:, 2])
        return scale

    def metric_lengths(self, s: float, rows: np.ndarray | None = None) -> np.ndarray:
        """Lengths (3 corners, m) of the base's corner edges under the interpolated metric at
        factor ``s``: ``√(eᵀ G e)`` of the metric's spline ``G`` between the keys, without its square
        root ``U`` (the lengths ``|U e|`` of :meth:`stretch`'s fit targets, to rounding); ``U²`` of
        :meth:`stretch` where that ``G`` is not positive definite, outside the keys and with
        ``log_metric``. With ``rows`` (an index array, r,): (3 corners, r) of those triangles alone,
        per element the same values."""
        if 0.0 < s < 1.0 and not self.log_metric:
            metric = self.splines["metric"].at(s, rows)
            ok = df.sqrt_det(metric)[1]
            if not ok.all():
                bad = np.flatnonzero(~ok)
                metric[bad] = df.squared_stretch(self.stretch(s, bad if rows is None else rows[bad]))
        else:
            metric = df.squared_stretch(self.stretch(s, rows))
        x, y = self.base.tangent_rows if rows is None else np.ascontiguousarray(self.base.tangent_rows[:, :, rows])
        g11, g12, g22 = np.ascontiguousarray(metric.T)
        # a metric extrapolated hundreds of gaps out overflows or cancels to NaN lengths, which no
        # bound the callers compare them with holds
        with np.errstate(over="ignore", invalid="ignore"):
            return np.sqrt(g11 * (x * x) + 2.0 * g12 * (x * y) + g22 * (y * y))

    def log_stretch_rows(self, s: float, rows: np.ndarray) -> np.ndarray:
        """The log-stretches' spline at factor ``s`` on the triangles ``rows`` (index array): the
        whole spline's where it is made, else a spline of those rows alone (a few triangles where
        the metrics' spline is not positive definite: the keys' other log-stretches not made)."""
        if "log_stretch" in self.splines:
            return self.spline_at("log_stretch", s)[rows]
        return log_stretch_spline(self.relatives, self.cubic, self._log_options, rows).at(s)

    def key_frames(self, rotvec: np.ndarray, rotations: np.ndarray, rows=slice(None), columns: int = 3) -> np.ndarray:
        """Frames (columns, r, 3) of the rotations ``M_c · exp(rotvec)`` (``rotvec``: residuals
        (r, 3) of the triangles ``rows``, ``rotations``: the components' (C, 3, 3)): the images of
        the base's ``t1``, ``t2`` and, with ``columns=3``, ``n``; in the components of
        ``whole_rotations``, ``exp(rotvec)`` alone)."""
        if self.whole_rotations.any():
            rotations = np.where(self.whole_rotations[:, None, None], np.eye(3), rotations)
        return df.rotated_frames(rotvec, rotations, self.topo.triangle_component[rows],
                                 self.base.column_rows[:columns, :, rows])


class _ByRows:
    """Per-triangle values of a gap at one factor computed only for the triangles asked:
    ``values[rows]`` (``axis`` 0: stretches (r, 3)) or ``values[:, rows]`` (``axis`` 1: frames
    (k, r, 3)), ``rows`` an index array, a bool mask or a slice. A repair of a predicted in-between
    needs them on its regions only (the full set costs 12 ms at 100k triangles), and each
    triangle's are computed once: the repair rounds' growing regions and their defect checks ask
    for overlapping rows again and again. ``compute(rows)`` gives them for an ascending index array
    (per triangle, the values it would give among all)."""

    def __init__(self, compute, shape: tuple, axis: int):
        self.compute, self.axis = compute, axis
        self._values = np.empty(shape)
        self._done = np.zeros(shape[axis], dtype=bool)

    def __getitem__(self, index):
        if self.axis:
            columns, rows = index
            if columns != slice(None):
                raise IndexError("frames by rows are indexed as [:, rows]")
        elif isinstance(index, tuple):
            raise IndexError("values by rows are indexed as [rows]")
        else:
            rows = index
        rows = np.arange(len(self._done))[rows] if isinstance(rows, slice) else np.asarray(rows)
        if rows.dtype == bool:
            rows = np.flatnonzero(rows)
        pending = ~np.take(self._done, rows)
        if pending.any():
            new = np.unique(rows[pending])
            values = self._values if self.axis == 0 else self._values.transpose(1, 0, 2)  # triangles first
            values[new] = self.compute(new) if self.axis == 0 else self.compute(new).transpose(1, 0, 2)
            self._done[new] = True
        return np.take(self._values, rows, axis=self.axis)  # NumPy's indexing of rows of 3 costs 4–6 × more
