"""Checking and repairing an in-between (flipped or collapsed triangles, non-finite values).

A defect-free fit is returned as it is. Otherwise the fit is repaired where the defects are:
rotations and stretches are imposed on the defective triangles and a neighbourhood that grows
while defects remain (:data:`REPAIR_RINGS`), first the interpolated rotations, then the linear
blend's rotations (integrable: they come from a mesh), then the blend's rotations and stretches
(its local geometry spliced in, where the interpolated metric cannot be realized without a fold),
last each key's own local geometry (nearer key first). If no repair is defect-free, the fallbacks
are tried in turn — the Poisson solve alone, the metric fitted near the linear blend (strongly
anchored), the linear blend — and the first without defects is returned; if none is, the metric
fit with the fewest defects. Each fallback comes with a message for a
:class:`~core.errors.ShapeDifferenceWarning`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from . import deformation_fields as df
from .geometry import rows_dot

#: A triangle whose area dropped below this fraction of its interpolated target area is collapsed.
COLLAPSE_RATIO = 1e-3
#: Repair rounds: each imposes a field on the defects and this many vertex rings around the
#: region imposed so far (numbers behind the schedule in docs/inbetweens.md).
REPAIR_RINGS = (1, 1, 2, 4, 8)
#: Local/global iterations of each repair fit (repairs run only where a defect is).
REPAIR_ITERATIONS = 10
#: Anchor weight of the fallback that fits the interpolated metric near the linear blend.
FALLBACK_ANCHOR_WEIGHT = 1e-1


class Repair:
    """Checks and repairs of the poses of one gap (a ``core.interpolation._Gap``)."""

    def __init__(self, gap):
        self.gap = gap

    # --- defects

    def flipped(self, cross: np.ndarray, s: float, rotation: np.ndarray | None, rows=slice(None)) -> np.ndarray:
        """Triangles (bool (r,)) among ``rows`` whose normal ``cross`` (r, 3) opposes both keys'
        normals (in-betweens, 0 ≤ s ≤ 1) or, for extrapolations, the interpolated normal
        ``R_T(s) n_T`` (``rotation``: (m, 3, 3) of every triangle; without it: the nearer key's
        normal)."""
        gap = self.gap
        if 0.0 <= s <= 1.0:
            return (rows_dot(cross, gap.base.normals[rows]) < 0) & (rows_dot(cross, gap.next.normals[rows]) < 0)
        if rotation is not None:
            return rows_dot(cross, np.einsum("kab,kb->ka", rotation[rows], gap.base.normals[rows])) < 0
        return rows_dot(cross, (gap.base if s < 0.5 else gap.next).normals[rows]) < 0

    def defects(self, x: np.ndarray, s: float, rotation, stretch, rows=None) -> np.ndarray:
        """Flipped or collapsed triangles of ``x`` (bool (m,), or (r,) for the triangle indices
        ``rows``); all of them if ``x`` is not finite."""
        m = len(self.gap.topo.triangles)
        if not np.isfinite(x).all():
            return np.ones(m if rows is None else len(rows), dtype=bool)
        rows = slice(None) if rows is None else rows
        t = self.gap.topo.triangles[rows]
        e1, e2 = x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]]
        cross = np.cross(e1, e2)
        st = stretch[rows]
        target = self.gap.base.areas[rows] * (st[:, 0] * st[:, 2] - st[:, 1] ** 2)
        collapsed = 0.5 * np.linalg.norm(cross, axis=1) < COLLAPSE_RATIO * target
        return self.flipped(cross, s, rotation, rows) | collapsed

    def problem(self, x, s, rotation, stretch, defects=None) -> str | None:
        """What is wrong with ``x`` in words, or None (``defects``: those of ``x``, if known)."""
        if not np.isfinite(x).all():
            return "the reconstruction produced non-finite coordinates"
        count = int((self.defects(x, s, rotation, stretch) if defects is None else defects).sum())
        return f"{count} triangle(s) flipped or collapsed" if count else None

    def grow(self, triangles: np.ndarray, rings: int) -> np.ndarray:
        """The triangles (bool (m,)) within ``rings`` vertex rings of ``triangles``."""
        t = self.gap.topo.triangles
        for _ in range(rings):
            near = np.zeros(self.gap.topo.n, dtype=bool)
            near[t[triangles].ravel()] = True
            triangles = near[t].any(axis=1)
        return triangles

    # --- repair and fallbacks

    def checked(self, x, x0, s, rotation, stretch, guide, motion) -> tuple[np.ndarray, str | None]:
        """``(x, None)`` if the fit ``x`` is defect-free, else a repair or a fallback with the
        message saying which (``x0``: the Poisson solve of the interpolated field)."""
        defects = self.defects(x, s, rotation, stretch)
        problem = self.problem(x, s, rotation, stretch, defects)
        if problem is None:
            return x, None
        gap = self.gap
        fits = [x] if np.isfinite(x).all() else []  # metric fits, candidates of the last resort
        blend = (1.0 - s) * gap.base.vertices + s * gap.next.vertices
        if gap.use_extrinsic and fits:
            for imposed in self.imposed_fields(blend, s):
                z = self.rounds(x, defects, s, rotation, stretch, guide, motion, imposed, fits)
                if z is not None:
                    return z, None
        if gap.use_extrinsic and self.problem(x0, s, rotation, stretch) is None:
            return x0, f"{problem}; returned the interpolated rotation field's Poisson solve without metric fit"
        system = (gap.topo.factor(FALLBACK_ANCHOR_WEIGHT), np.full(gap.topo.n, FALLBACK_ANCHOR_WEIGHT) * gap.topo.mass)
        y = gap.fit(blend.copy(), stretch, None, blend, s, motion, REPAIR_ITERATIONS, system=system)
        if self.problem(y, s, None, stretch) is None:
            return y, f"{problem}; used the interpolated metric fitted near the linear blend instead"
        if self.problem(blend, s, None, stretch) is None:
            return blend, f"{problem}; the metric fit near the linear blend failed too, returned the linear blend"
        # No candidate is free of defects: the metric fit with the fewest rather than a candidate
        # that gives up the metric (the blend shortens edges by several percent: a visible pop).
        fits = fits or [y]
        counts = [int(self.defects(z, s, rotation, stretch).sum()) for z in fits]
        best = int(np.argmin(counts))
        return fits[best], (f"{problem}; every repair and fallback has defects too, returned the metric fit with "
                            f"the fewest ({counts[best]} flipped or collapsed triangle(s))")

    def imposed_fields(self, blend, s):
        """The (rotations, packed stretches) imposed around defects, in the order tried."""
        gap = self.gap
        t = gap.topo.triangles
        rotation, stretch, _, _ = gap.targets(s)
        yield rotation, stretch
        bases = df.tangent_bases(blend, t)
        coordinates = df.tangent_coordinates(df.corner_edges(blend, t), bases)
        angle, blend_stretch = df.planar_polar(df.planar_maps(coordinates, gap.base.inverse))
        blend_rotation = df.triangle_rotations(bases, gap.base.bases, angle)
        yield blend_rotation, stretch
        yield blend_rotation, blend_stretch
        keys = gap.relatives[1:3] if s < 0.5 else gap.relatives[2:0:-1]  # nearer key first
        for key in keys:
            motion = np.array([df.rigid_exp(screw)[0] for screw in key.screw])
            residual = Rotation.from_rotvec(key.rotvec).as_matrix()
            yield df.matmul(motion[gap.topo.triangle_component], residual), df.exp_stretch(key.log_stretch)

    def rounds(self, x, defects, s, rotation, stretch, guide, motion, imposed, fits):
        """Rounds of :data:`REPAIR_RINGS` imposing ``imposed`` (rotations, stretches) on the
        ``defects`` (bool (m,)) of ``x`` and rings around them; the first defect-free fit, else
        None (fits kept in ``fits``). A round moves only vertices all of whose triangles are
        imposed, so only the imposed triangles are checked again."""
        gap = self.gap
        force = np.zeros(len(gap.topo.triangles), dtype=bool)
        for rings in REPAIR_RINGS:
            force = self.grow(force | defects, rings)
            field = np.where(force[:, None, None], imposed[0], rotation)
            metric = np.where(force[:, None], imposed[1], stretch)
            x = gap.local_fit(x, metric, field, guide, force, REPAIR_ITERATIONS)
            if not np.isfinite(x).all():
                defects = np.ones_like(force)
                continue
            defects = defects.copy()
            rows = np.flatnonzero(force)
            defects[rows] = self.defects(x, s, rotation, stretch, rows=rows)
            if not defects.any():
                return x
            fits.append(x)
        return None
