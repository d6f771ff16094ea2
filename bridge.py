"""The one place where data moves between Blender and NumPy.

Reads go through float32/int32 buffers with ``foreach_get`` and come back as the float64/int64
arrays that :mod:`core` expects; writes go the other way with ``foreach_set``. Coordinates are
always in object space. Nothing else in the extension converts.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import bpy
import numpy as np

BASIS_NAME = "Basis"


def vertex_positions(mesh: bpy.types.Mesh) -> np.ndarray:
    """Vertex positions of ``mesh`` in object space, float64 ``(n, 3)``."""
    buffer = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.attributes["position"].data.foreach_get("vector", buffer)
    return buffer.reshape(-1, 3).astype(np.float64)


def stored_key_positions(key_block: bpy.types.ShapeKey) -> np.ndarray:
    """Coordinates stored in a shape key, float64 ``(n, 3)``. Read through ``points``, the shape
    key's bulk access (``data`` copies point by point: 2 ms per key at 20k vertices, ``points``
    0.03 ms)."""
    buffer = np.empty(len(key_block.points) * 3, dtype=np.float32)
    key_block.points.foreach_get("co", buffer)
    return buffer.reshape(-1, 3).astype(np.float64)


def shape_key_positions(key_block: bpy.types.ShapeKey, obj: bpy.types.Object) -> np.ndarray:
    """The pose shape key ``key_block`` of ``obj``'s mesh shows on its own at value 1, float64
    ``(n, 3)``, as Blender blends it: reference + weight × (key − its relative key), the weight
    from its vertex group (1 without one, or where ``obj`` has no group of that name). That is
    the stored coordinates for a key relative to the reference key without a vertex group (and
    for absolute keys); a corrective relative to another key, or a left/right half masked by a
    vertex group, is not its stored coordinates."""
    co = stored_key_positions(key_block)
    key = key_block.id_data
    reference = key.reference_key
    relative = key_block.relative_key
    group = obj.vertex_groups.get(key_block.vertex_group) if key_block.vertex_group else None
    if not key.use_relative or key_block == reference or (relative == reference and group is None):
        return co
    base = stored_key_positions(reference)
    delta = co - (base if relative == reference else stored_key_positions(relative))
    if group is not None:
        delta *= vertex_group_weights(obj, group)[:, None]
    return base + delta


def vertex_group_weights(obj: bpy.types.Object, group: bpy.types.VertexGroup) -> np.ndarray:
    """Each vertex's weight in ``group`` of ``obj`` (0 where it is not in the group), float64
    ``(n,)``. A loop: the Python API has no bulk access to vertex group weights."""
    weights = np.zeros(len(obj.data.vertices))
    index = group.index
    for vertex in obj.data.vertices:
        for element in vertex.groups:
            if element.group == index:
                weights[vertex.index] = element.weight
    return weights


def mesh_triangles(mesh: bpy.types.Mesh) -> np.ndarray:
    """The loop triangles of ``mesh`` (n-gons triangulated) as int64 ``(m, 3)`` vertex indices,
    with the n-gons Blender triangulated into zero-area triangles triangulated again about their
    own centre (see :func:`_retriangulated`)."""
    mesh.calc_loop_triangles()
    buffer = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", buffer)
    triangles = buffer.reshape(-1, 3).astype(np.int64)
    if len(triangles) > len(mesh.polygons):  # n-gons
        triangles = _retriangulated(mesh, triangles)
    return triangles


def _retriangulated(mesh: bpy.types.Mesh, triangles: np.ndarray) -> np.ndarray:
    """``triangles`` with every n-gon that Blender split into a zero-area triangle (an n-gon with
    collinear corners, as Dissolve leaves) split again by Blender's *Beauty* triangulation
    (``bmesh.ops.triangulate``) in coordinates about the n-gon's centre, where the result has no
    such triangle: the loop triangles' ear clipping may cut an ear between collinear corners (at
    1e5 units from the origin, where single precision rounds them onto one line, it did). The
    n-gon's triangles keep their rows (c − 2 for c corners either way) and its winding."""
    import bmesh

    from .core.mesh_topology import DEGENERATE_TRIANGLE_RATIO

    def flat(rows):
        return _doubled_areas(positions, rows) <= DEGENERATE_TRIANGLE_RATIO * _longest(positions, rows)

    positions = vertex_positions(mesh)
    degenerate = np.flatnonzero(flat(triangles))
    if not degenerate.size:
        return triangles
    polygons = loop_triangle_polygons(mesh)
    triangles = triangles.copy()
    for polygon in np.unique(polygons[degenerate]):
        corners = np.array(mesh.polygons[polygon].vertices, dtype=np.int64)
        rows = np.flatnonzero(polygons == polygon)
        bm = bmesh.new()
        try:
            verts = [bm.verts.new(p) for p in positions[corners] - positions[corners].mean(axis=0)]
            bm.verts.index_update()
            face = bm.faces.new(verts)
            face.normal_update()  # triangulate projects along the face normal, (0, 0, 0) until computed
            bmesh.ops.triangulate(bm, faces=[face], quad_method='BEAUTY', ngon_method='BEAUTY')
            candidate = corners[np.array([[v.index for v in face.verts] for face in bm.faces], dtype=np.int64)]
        except ValueError:  # a face Blender cannot rebuild (repeated corners): keep its triangles
            continue
        finally:
            bm.free()
        if len(candidate) == len(rows) and not flat(candidate).any() and _covers(positions, candidate, triangles[rows]):
            triangles[rows] = candidate
    return triangles


def area_recoverable_triangles(mesh: bpy.types.Mesh, triangles: np.ndarray) -> np.ndarray:
    """``triangles`` (:func:`mesh_triangles` of ``mesh``, int64 ``(m, 3)``) with one quad split
    along its other diagonal in every closed part whose triangles two-colour
    (:func:`core.full_basis_recovery.two_colour_parts`: full-basis differences cannot determine
    its areas, Prop. 1): how Blender splits a quad is its choice, not the user's, and a quad mesh
    with a handle (the Torus primitive) is split into such triangles, every vertex of even
    valence. The other diagonal gives four vertices odd valence. A quad is re-split only where its
    two new triangles face its way and cover it (:func:`_covers`), neither is flat and its other
    diagonal is not already an edge (the mesh would not stay a manifold); a part
    without such a quad, or a mesh the core refuses, keeps its triangles (the core says why)."""
    from .core.errors import MeshError
    from .core.full_basis_recovery import two_colour_parts
    from .core.mesh_topology import DEGENERATE_TRIANGLE_RATIO, mesh_topology

    try:
        topology = mesh_topology(triangles, len(mesh.vertices))
    except MeshError:
        return triangles
    labels, bad = two_colour_parts(topology)
    if not bad.size:
        return triangles
    edges = set(map(tuple, topology.edges.tolist()))
    positions = vertex_positions(mesh)
    polygons = loop_triangle_polygons(mesh)
    triangles = triangles.copy()
    for part in bad:
        for polygon in np.unique(polygons[labels == part]):
            corners = np.array(mesh.polygons[polygon].vertices, dtype=np.int64)
            if corners.size != 4:
                continue
            rows = np.flatnonzero(polygons == polygon)
            splits = corners[np.array([[[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]]])]
            used = set(map(tuple, np.sort(triangles[rows], axis=1).tolist()))
            candidate = splits[1] if used == set(map(tuple, np.sort(splits[0], axis=1).tolist())) else splits[0]
            diagonal = tuple(sorted(set(candidate[0].tolist()) & set(candidate[1].tolist())))
            flat = _doubled_areas(positions, candidate) <= DEGENERATE_TRIANGLE_RATIO * _longest(positions, candidate)
            if diagonal not in edges and not flat.any() and _covers(positions, candidate, triangles[rows]):
                triangles[rows] = candidate
                break
    return triangles


def _covers(positions: np.ndarray, candidate: np.ndarray, original: np.ndarray) -> bool:
    """Whether the triangles ``candidate`` of an n-gon cover it as its loop triangles ``original``
    do: the same vector area (their area-weighted normals sum to the face's), every one facing
    the face's way, none overlapping (their areas add up to no more than the loop triangles')."""
    def vector_areas(rows):
        a, b, c = (positions[rows[:, k]] for k in range(3))
        return np.cross(b - a, c - a)

    ours, theirs = vector_areas(candidate), vector_areas(original)
    total = theirs.sum(axis=0)
    scale = np.linalg.norm(theirs, axis=1).sum()
    return bool(np.linalg.norm(ours.sum(axis=0) - total) <= 1e-6 * scale and (ours @ total > 0).all()
                and np.linalg.norm(ours, axis=1).sum() <= (1 + 1e-6) * scale)


def _doubled_areas(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    a, b, c = (positions[triangles[:, k]] for k in range(3))
    return np.linalg.norm(np.cross(b - a, c - a), axis=1)


def _longest(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    a, b, c = (positions[triangles[:, k]] for k in range(3))
    return np.max([np.einsum("ij,ij->i", p - q, p - q) for p, q in ((a, b), (b, c), (c, a))], axis=0)


def evaluated_positions(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> np.ndarray:
    """Object-space vertex positions after the modifier stack (cloth, armature, ...) at the
    depsgraph's current frame, float64 ``(n, 3)``."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        return vertex_positions(mesh)
    finally:
        evaluated.to_mesh_clear()


#: Relative spread of the singular values of an object's world matrix above which poses are
#: interpolated in the world's proportions (:class:`WorldProportions`).
SIMILARITY_TOLERANCE = 1e-6


class WorldProportions:
    """The linear part of ``obj``'s world matrix when it is not a rotation times one scale (an
    object scaled along one axis in Object Mode, not applied): the simulation (and what the artist
    sees) is in the world, where the mesh's own coordinates are stretched, so a turning fold looks
    sheared there and in-betweens computed there keep the wrong lengths (a flag keyed every 8th
    frame, scaled (2, 1, 1): edge deviation 0.79 → 2.80 %, RMS error ×2; the linear blend does not
    care). Poses go through :meth:`to` before the core and :meth:`back` after; for a similarity
    (any rotation, one scale) nothing is done. ``matrix``: the world matrix (4, 4) the poses were
    shown under (frames read: one of theirs), else ``obj``'s at the current frame (its shape keys)."""

    def __init__(self, obj: bpy.types.Object, matrix: np.ndarray | None = None):
        linear = np.array(obj.matrix_world if matrix is None else matrix, dtype=np.float64)[:3, :3]
        sigma = np.linalg.svd(linear, compute_uv=False)
        skewed = sigma[-1] > 0 and sigma[0] / sigma[-1] - 1.0 > SIMILARITY_TOLERANCE
        linear = _unmirrored(linear)
        self.matrix = linear.T if skewed else None  # row vectors: x ↦ x Lᵀ
        self.inverse = np.linalg.inv(linear).T if skewed else None

    def to(self, positions: np.ndarray, time: float | None = None) -> np.ndarray:
        """Positions (…, n, 3) in the world's proportions (the same at every ``time``)."""
        return positions if self.matrix is None else positions @ self.matrix

    def linear(self, time: float | None = None) -> np.ndarray | None:
        """The linear map (3, 3) :meth:`to` applies (the same at every ``time``), None where it
        leaves the poses in the mesh's coordinates."""
        return None if self.matrix is None else self.matrix.T

    def reading(self, times):
        """Nothing to read: the proportions are the same at every time (as :meth:`WorldFrames.reading`)."""
        yield from ()

    def read(self, times) -> None:
        """Nothing to read (as :meth:`WorldFrames.read`)."""

    def back(self, positions: np.ndarray, times=None) -> np.ndarray:
        """Positions (…, n, 3) in the world's proportions back in the mesh's coordinates (the same at
        every time of ``times``)."""
        return positions if self.inverse is None else positions @ self.inverse


def _unmirrored(matrix: np.ndarray) -> np.ndarray:
    """The world matrix ``matrix`` (4, 4), or its linear part (3, 3), with its first row's linear
    part negated where it mirrors: mirrored back in the world (an isometry there), so that the
    triangles keep their side (offset surfaces, bending's sign)."""
    matrix = np.array(matrix, dtype=np.float64)
    if np.linalg.det(matrix[:3, :3]) < 0:
        matrix[0, :3] = -matrix[0, :3]
    return matrix


def _polar(matrix) -> tuple[np.ndarray, np.ndarray]:
    """``(R, S)`` of the linear part ``L = R S`` of the world matrix ``matrix`` (4, 4): ``R`` orthogonal
    (a rotation, or a rotation and a mirror), ``S`` the symmetric stretch."""
    u, sigma, vt = np.linalg.svd(np.asarray(matrix, dtype=np.float64)[:3, :3])
    return u @ vt, (vt.T * sigma) @ vt


def with_proportions(placement, proportions) -> np.ndarray:
    """The world matrix (4, 4) that places an object where ``placement`` (4, 4) does (its turn,
    mirror and translation) and stretches it as ``proportions`` (4, 4) does (:func:`_polar`'s ``S``):
    ``placement`` itself where the two stretch alike (:func:`proportions_change`)."""
    matrix = np.array(placement, dtype=np.float64)
    if proportions_change([placement, proportions]):
        matrix[:3, :3] = _polar(placement)[0] @ _polar(proportions)[1]
    return matrix


def proportions_change(matrices) -> bool:
    """Whether the world matrices (4, 4) ``matrices`` stretch the mesh differently: the symmetric
    factors ``S`` of their linear parts (``L = R S``, :func:`_polar`) differ by more than
    :data:`SIMILARITY_TOLERANCE` of the largest scale (an object whose scale is keyframed)."""
    stretches = [_polar(matrix)[1] for matrix in matrices]
    if not stretches:
        return False
    spread = max(np.abs(stretch - stretches[0]).max() for stretch in stretches)
    return bool(spread > SIMILARITY_TOLERANCE * max(np.abs(stretch).max() for stretch in stretches))


def at_times(scene: bpy.types.Scene, times):
    """Set ``scene`` to each of ``times`` (frames; a fraction is a sub-frame) in turn, yielding
    it; the scene's current frame and sub-frame restored afterwards if it was moved (setting a
    frame is not free: at a cloth's start frame Blender builds the cloth again, ~35 ms at 10k
    vertices, where another frame of its baked cache takes ~0.5 ms)."""
    original_frame, original_subframe = scene.frame_current, scene.frame_subframe
    moved = False
    try:
        for time in times:
            whole = int(np.floor(time))
            scene.frame_set(whole, subframe=float(time - whole))
            moved = True
            yield time
    finally:
        if moved:
            scene.frame_set(original_frame, subframe=original_subframe)


class WorldFrames:
    """Poses of an object whose world matrix stretches it differently from key to key (its scale
    keyframed in Object Mode, not applied). The simulation keeps its lengths in the world, where
    the mesh's own coordinates are scaled by another factor at every frame: there a hanging sheet
    on an object scaled 1 → 1.6 → 0.8 changes its lengths with the scale, and in-betweens computed
    there and played under the object's matrix of their frame come out 4.4 / 9.4 % off their
    lengths (keys 8 / 16 frames apart; the simulation 0.7 %), 1,801 triangles turned over at
    keys 16 apart. Poses go to the world through the matrix of their own frame (:meth:`to`) and
    back through the matrix of each in-between's time (:meth:`back`, read at its sub-frame)."""

    def __init__(self, context: bpy.types.Context, obj: bpy.types.Object, matrices: dict):
        self.context, self.obj = context, obj
        self.matrices = {time: _unmirrored(matrix) for time, matrix in matrices.items()}

    def to(self, positions: np.ndarray, time: float) -> np.ndarray:
        """Positions (n, 3) of the frame ``time`` (one of the frames read) in the world."""
        matrix = self.matrices[time]
        return positions @ matrix[:3, :3].T + matrix[:3, 3]

    def linear(self, time: float) -> np.ndarray:
        """The linear part (3, 3) of the matrix :meth:`to` takes the frame ``time`` through."""
        return self.matrices[time][:3, :3]

    def reading(self, times):
        """Read the object's matrix at each of ``times`` not read yet, yielding after each: one pass
        over the scene's frames for all of them, the scene set to each time once and back to its
        current frame once at the end, rather than once per call of :meth:`back` (a 10k cloth's
        baked frame takes 0.5 ms to set, a return to its start frame 35 ms)."""
        missing = sorted(set(time for time in times if time not in self.matrices))
        for time in at_times(self.context.scene, missing):
            self.matrices[time] = _unmirrored(np.array(self.obj.matrix_world, dtype=np.float64))
            yield time

    def read(self, times) -> None:
        """:meth:`reading` ``times`` at once."""
        for _ in self.reading(times):
            pass

    def back(self, positions: np.ndarray, times) -> np.ndarray:
        """World positions (k, n, 3) of the poses at ``times`` (k) in the mesh's coordinates."""
        self.read(times)
        return np.stack([(pose - self.matrices[time][:3, 3]) @ np.linalg.inv(self.matrices[time][:3, :3]).T
                         for pose, time in zip(positions, times)])


def frames_space(context: bpy.types.Context, obj: bpy.types.Object, matrices: dict):
    """Where to interpolate frames of ``obj`` read with its world matrices ``matrices`` ({frame:
    (4, 4)}): the world through each frame's matrix (:class:`WorldFrames`) where they stretch the
    mesh differently (:func:`proportions_change`: its scale keyframed), else the world's
    proportions, the same at every frame read (:class:`WorldProportions`, those of the frames' matrices:
    the current frame, outside them, may show the object under another scale). Without ``matrices``,
    those of the current frame."""
    if proportions_change(matrices.values()):
        return WorldFrames(context, obj, matrices)
    return WorldProportions(obj, next(iter(matrices.values()), None))


def scene_time(scene: bpy.types.Scene, frame: float) -> float:
    """The time at which ``scene`` evaluates animation, caches and simulations at ``frame``: the
    frame itself, or scaled by the scene's *Time Stretching* (Output › Frame Range: old / new;
    what ``frame_current_final`` shows), where keyframes and a Mesh Cache must sit to play at
    ``frame``."""
    return frame * scene.render.frame_map_old / scene.render.frame_map_new


#: Modifiers that simulate and keep a point cache (emptied when the object's mesh data changes,
#: marked outdated when its modifiers change at a frame past its start).
SIMULATION_MODIFIERS = {'CLOTH', 'SOFT_BODY'}
#: Modifiers that replace the positions of their mesh with poses of their own (a simulation's frames,
#: a cache's samples): the mesh's shape keys do not show under them, and a generator after them works
#: on what they play (applied, it would give them other vertices than they hold).
POSE_REPLACING_MODIFIERS = SIMULATION_MODIFIERS | {'MESH_CACHE', 'MESH_SEQUENCE_CACHE'}
#: Modifiers that add or remove vertices (Blender's Generate category; Geometry Nodes apart, which
#: may carry the motion itself).
GENERATE_MODIFIERS = {'ARRAY', 'BEVEL', 'BOOLEAN', 'BUILD', 'DECIMATE', 'EDGE_SPLIT', 'MASK', 'MIRROR',
                      'MULTIRES', 'REMESH', 'SCREW', 'SKIN', 'SOLIDIFY', 'SUBSURF', 'TRIANGULATE', 'WELD',
                      'WIREFRAME'}


def simulations(objects):
    """``(object, modifier)`` for each cloth or soft body modifier of ``objects`` enabled in the
    viewport (the ones that move the mesh the frames are read from)."""
    for obj in objects:
        for modifier in obj.modifiers:
            if modifier.type in SIMULATION_MODIFIERS and modifier.show_viewport:
                yield obj, modifier


class FrameReadError(ValueError):
    """The frames of an object cannot be read as the poses of its mesh (the message says why)."""


class VertexCountChanged(FrameReadError):
    """The evaluated mesh does not have the vertex count of the original mesh at some frame."""


class NotEvaluated(FrameReadError):
    """The object is not in the depsgraph (disabled in viewports): its modifiers are not computed."""


class CacheFileMissing(FrameReadError):
    """A cache modifier of the object reads a file that is not there: every frame is its rest mesh."""


class CacheFileUnfit(FrameReadError):
    """A cache modifier of the object reads a file that Blender cannot play on its mesh: a Mesh
    Cache of another vertex count or a damaged file (every frame is its rest mesh), or a cache whose
    frames are another mesh's vertices or this one's in another order (played scrambled)."""


class BakeFilesMissing(FrameReadError):
    """A cloth or soft body baked to disk plays none of its frames (its files are not where Blender
    looks, and every frame is the rest mesh), or holds one of its frames over frames read whose
    files are missing (a copy of the folder cut short); or a Geometry Nodes simulation zone baked to
    disk has none of its files where Blender looks, and would be simulated again."""


def missing_cache_file(obj: bpy.types.Object) -> tuple[str, str] | None:
    """``(modifier name, path)`` of the first enabled Mesh Cache or Mesh Sequence Cache (Alembic,
    USD) modifier of ``obj`` whose file does not exist, or None. A file sequence (numbered files)
    is not checked."""
    for modifier in obj.modifiers:
        if not modifier.show_viewport:
            continue
        if modifier.type == 'MESH_CACHE':
            path = modifier.filepath
            absolute = mesh_cache_file(modifier) if path else ""
        elif modifier.type == 'MESH_SEQUENCE_CACHE' and modifier.cache_file is not None \
                and not modifier.cache_file.is_sequence:  # relative to the Cache File's own
            path = modifier.cache_file.filepath
            absolute = bpy.path.abspath(path, library=modifier.cache_file.library) if path else ""
        else:
            continue
        if not path or not os.path.isfile(absolute):
            return modifier.name, absolute or "(no file)"
    return None


def mesh_cache_file(modifier: bpy.types.MeshCacheModifier) -> str:
    """The absolute path of the file the Mesh Cache ``modifier`` plays (a relative path is relative
    to the file its object comes from)."""
    return bpy.path.abspath(modifier.filepath, library=modifier.id_data.library)


def mesh_cache_header(modifier: bpy.types.MeshCacheModifier) -> tuple[int, int, np.ndarray | None]:
    """``(samples, points, times)`` of the PC2 or MDD file the Mesh Cache ``modifier`` plays, read
    as its Format says (as Blender reads it: bytes after the samples do not count); ``times``: an
    MDD's frame times in seconds, None for a PC2. Raises ``core.MeshError`` for a file that is not a
    cache of that kind or is shorter than its header says."""
    from .core.point_cache import read_mdd_header, read_pc2_header

    path = mesh_cache_file(modifier)
    if modifier.cache_format == 'PC2':
        points, _start, _sampling, samples = read_pc2_header(path, whole=False)
        return samples, points, None
    points, times = read_mdd_header(path, whole=False)
    return len(times), points, times


def frames_outside_cache(scene: bpy.types.Scene, obj: bpy.types.Object, frames: list[int],
                         movers: list) -> str | None:
    """A warning when some of ``frames`` play a time before the first or after the last sample of
    the file of an enabled Mesh Cache modifier (Play Mode Scene) of one of ``movers`` (``obj`` and
    the objects whose motion reaches its mesh): Blender holds the file's first sample before it and
    its last after it, so the poses read there stand still (a cache shorter than the frame range, or
    exported at another frame offset); None otherwise. At the scene time ``t`` (:func:`scene_time`)
    the modifier plays, with Time Mode Frame, sample ``t · Frame Scale − Frame Start``; with Time
    Mode Seconds, an MDD's frame at ``t / fps · Frame Scale − Frame Start`` seconds (a PC2 there is
    not checked). Where it takes the nearest sample (Interpolation None), half a sample's spacing
    outside still plays the end sample at its due time."""
    from .core.errors import MeshError

    fps = scene.render.fps / scene.render.fps_base
    for mover in movers:
        for modifier in mover.modifiers:
            if (modifier.type != 'MESH_CACHE' or not modifier.show_viewport or modifier.play_mode != 'SCENE'
                    or not os.path.isfile(mesh_cache_file(modifier))):
                continue
            try:
                samples, _points, times = mesh_cache_header(modifier)
            except MeshError:  # refused where the frames are read (operators.motion_sources.unfit_mesh_cache)
                continue
            if samples == 0:
                continue
            if modifier.time_mode == 'FRAME':
                first, last, per_frame = 0.0, samples - 1.0, 1.0
            elif modifier.time_mode == 'TIME' and times is not None:
                first, last, per_frame = times[0], times[-1], 1.0 / fps
            else:
                continue
            spacing = (last - first) / (samples - 1) if samples > 1 else 1.0
            margin = 0.5 * spacing if modifier.interpolation == 'NONE' else 0.0
            played = {frame: scene_time(scene, frame) * per_frame * modifier.frame_scale - modifier.frame_start
                      for frame in frames}
            before = [f for f in frames if played[f] < first - margin - 1e-4 * spacing]
            after = [f for f in frames if played[f] > last + margin + 1e-4 * spacing]
            if not (before or after):
                continue
            parts = ([f"{_frame_span(before)} before its first sample"] if before else []) + \
                    ([f"{_frame_span(after)} after its last"] if after else [])
            subject = f"'{obj.name}' is" if mover == obj else f"'{obj.name}' is moved by '{mover.name}', which is"
            held = ('first and last samples' if before and after else 'first sample' if before else 'last sample')
            return (f"{subject} played by the Mesh Cache '{modifier.name}' from "
                    f"'{os.path.basename(mesh_cache_file(modifier))}' ({samples} sample{'s' if samples != 1 else ''}; "
                    f"Frame Start {modifier.frame_start:g}, Frame Scale {modifier.frame_scale:g}), and the range "
                    f"reads {' and '.join(parts)}: Blender holds the cache's {held} there, so the poses read do "
                    "not move and the motion next to them is cut short. Fit the frame range to the cache's "
                    "frames, or check the modifier's Frame Start and Frame Scale")
    return None


def frames_held_by_cache(obj: bpy.types.Object, frames: list[int], poses: list[np.ndarray],
                         movers: list) -> str | None:
    """A warning when ``obj`` is played by an enabled Mesh Sequence Cache (Alembic, USD) of one of
    ``movers`` (``obj`` and the objects whose motion reaches its mesh) and the first two or more, or
    the last two or more, of the ``poses`` read at ``frames`` are the same to the bit while the
    others move: Blender holds such a cache's first sample before its first frame and its last
    after its end, and its file's frame range is not known here, so a run of identical poses at an
    end of the range stands for it (a cache that ends one read frame before the range does reads
    no such run and is not seen); None otherwise, or when every pose is the same
    (:func:`still_frames` says so)."""
    caches = [(mover, m) for mover in movers for m in mover.modifiers
              if m.type == 'MESH_SEQUENCE_CACHE' and m.show_viewport]
    if not caches or len(poses) < 3 or _all_the_same(poses):
        return None

    def held(indices) -> list[int]:
        return sorted(frames[index] for index in _held_run(poses, indices))

    before, after = held(range(len(poses))), held(range(len(poses) - 1, -1, -1))
    if not (before or after):
        return None
    parts = ([f"its start ({_frame_span(before)})"] if before else []) + \
            ([f"its end ({_frame_span(after)})"] if after else [])
    mover, modifier = caches[0]
    source = f" from '{os.path.basename(modifier.cache_file.filepath)}'" if modifier.cache_file is not None else ""
    subject = f"'{obj.name}' is" if mover == obj else f"'{obj.name}' is moved by '{mover.name}', which is"
    return (f"{subject} played by the Mesh Sequence Cache '{modifier.name}'{source}, and the range reads "
            f"the same pose, to the bit, at {' and '.join(parts)}, as Blender plays a cache before its first "
            "frame and after its last (it holds the end samples; the in-betweens next to a held key slow to a "
            "stop). If the cache is shorter than the range, fit the frame range to the cache's frames (or check "
            "the Cache File's Frame Offset); a hold in the animation itself needs nothing")


def face_edges(mesh: bpy.types.Mesh) -> np.ndarray:
    """The edges of ``mesh`` that bound a face, int64 ``(E, 2)`` vertex indices (loose edges left out)."""
    loop_edges = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("edge_index", loop_edges)
    edges = np.empty(len(mesh.edges) * 2, dtype=np.int32)
    mesh.edges.foreach_get("vertices", edges)
    return edges.reshape(-1, 2)[np.unique(loop_edges)].astype(np.int64)


def frames_of_another_mesh(obj: bpy.types.Object, frames: list[int], poses: list[np.ndarray],
                           movers: list) -> str | None:
    """The error when ``obj`` is played by an enabled Mesh Cache or Mesh Sequence Cache of one of
    ``movers`` (``obj`` and the objects whose motion reaches its mesh) and a pose read at one of
    ``frames`` cannot be its mesh in its vertex order: its edges grew, against the size of the
    parts they make up, over :data:`core.vertex_order.FOREIGN_GROWTH` times as much as any motion
    of a mesh gives (``core.vertex_order``: the median over the edges; folding and crumpling reach
    about 3), to as long as the parts, and with their lengths changed unevenly
    (``EdgeSpread.scattered``: a part wound up tight keeps its edges short, or, if narrow, each
    as long as it was). Blender plays such a file (a cache exported from another mesh with as many
    vertices, or from this one with its vertices renumbered) scrambled, without a word; None
    otherwise. Only objects a cache moves are checked: no other motion brings another order."""
    from .core.vertex_order import EdgeSpread

    caches = [(mover, m) for mover in movers for m in mover.modifiers
              if m.type in ('MESH_CACHE', 'MESH_SEQUENCE_CACHE') and m.show_viewport]
    if not caches or not poses:
        return None
    spread = EdgeSpread(vertex_positions(obj.data), face_edges(obj.data))
    for frame, pose in zip(frames, poses):
        if spread.scattered(pose):
            growth = spread.growth(pose)
            break
    else:
        return None
    mover, modifier = caches[0]
    if modifier.type == 'MESH_CACHE':
        source = f"the Mesh Cache '{modifier.name}' from '{os.path.basename(mesh_cache_file(modifier))}'"
    else:
        path = modifier.cache_file.filepath if modifier.cache_file is not None else ""
        source = (f"the Mesh Sequence Cache '{modifier.name}' from '{os.path.basename(path)}' (object path "
                  f"'{modifier.object_path}')")
    subject = f"'{obj.name}' is played by" if mover == obj else f"'{obj.name}' is moved by '{mover.name}', played by"
    return (f"{subject} {source}, whose frames are not this mesh's vertices in their order: at frame {frame} "
            f"its edges are {growth:.0f} times as long, against the size of the mesh, as at rest (a motion "
            "stretches or folds them by 3 at most), so its neighbouring vertices are scattered and Blender "
            "plays it scrambled. The cache was made from another mesh with as many vertices, or from this one "
            "with its vertices renumbered (sorted, re-imported, remeshed): export it from this mesh, or point "
            "the modifier to the cache made for it")


def _held_run(poses: list[np.ndarray], indices) -> list[int]:
    """The first of ``indices`` and those following it (in the order given) whose ``poses`` are the
    same to the bit as its pose, when they are two or more; else empty."""
    run = [indices[0]]
    for index in indices[1:]:
        if not np.array_equal(poses[index], poses[run[0]]):
            break
        run.append(index)
    return run if len(run) >= 2 else []


def _all_the_same(poses: list[np.ndarray]) -> bool:
    """Whether there are two or more ``poses`` and all are the same, to the bit."""
    return len(poses) >= 2 and all(np.array_equal(pose, poses[0]) for pose in poses[1:])


def bake_frames_on_disk(cache, owner: bpy.types.Object, folder: str) -> set[int] | None:
    """The frames of the disk cache ``cache`` of ``owner`` (its start to end) that have a file in
    ``folder`` (where Blender looks for them), by the names Blender gives them
    (``<name>_<frame:06>_<index:02>.bphys``, the name the cache's own or the object's in hex); None
    where no frame of the bake has a file of such a name there (the folder gone or empty, or files
    named otherwise), which the poses read then tell (:func:`missing_bake`)."""
    try:
        names = set(os.listdir(folder))
    except OSError:
        return None
    if cache.name or cache.use_external:
        stem = cache.name
    else:
        stem = "".join(f"{byte:02X}" for byte in owner.name.encode())
    if cache.index < 0 and not cache.use_external:  # no index given yet: the names are not known
        return None
    index = f"_{cache.index:02d}" if cache.index >= 0 else ""
    found = {frame for frame in range(cache.frame_start, cache.frame_end + 1)
             if f"{stem}_{frame:06d}{index}.bphys" in names}
    return found or None


def bakes_of_other_names(cache, owner: bpy.types.Object, folder: str) -> list[str]:
    """The object names whose bakes ``folder`` holds in the files Blender would read for ``cache``
    of ``owner`` were it named so (``<name in hex>_<frame:06>_<index:02>.bphys``, the cache's index),
    ``owner``'s own left out: an object renamed after its bake, whose files keep the old name (Blender
    looks for the new one's and plays the rest mesh). Empty where the cache has its own name (its
    files do not follow the object's) or ``folder`` cannot be read."""
    if cache.name or cache.use_external or cache.index < 0:
        return []
    try:
        files = os.listdir(folder)
    except OSError:
        return []
    pattern = re.compile(rf"((?:[0-9A-F]{{2}})+)_\d{{6}}_{cache.index:02d}\.bphys")
    names = set()
    for file in files:
        match = pattern.fullmatch(file)
        if match:
            try:
                names.add(bytes.fromhex(match.group(1)).decode())
            except UnicodeDecodeError:
                continue
    return sorted(names - {owner.name})


def missing_bake(obj: bpy.types.Object, frames: list[int], poses: list[np.ndarray], movers: list) -> str | None:
    """The error when a cloth or soft body of ``movers`` (the objects whose motion reaches ``obj``)
    is baked to a disk cache over two or more of ``frames`` and Blender plays files there that are
    not there; None otherwise:

    - the folder lacks the files of some frames read (:func:`bake_frames_on_disk`; a copy of the
      folder cut short, or with gaps): Blender plays those frames interpolated between the files it
      finds, or holds the nearest one. Where they all come after its last file, Blender holds that
      one over them, as it does after a simulation's end, and the message says so (a bake made
      with Current Cache to Bake from a cache played part of the way ends there too; the folder
      cannot tell it from a copy cut short);
    - where no file of the bake is found by its name, every pose read the same
      (:func:`_all_the_same`): Blender found none of the bake's files (a .blend moved, or sent to a
      farm, without its cache folder) and plays the rest mesh; or two or more frames read in a row
      inside the bake the same pose while others move: Blender holds the nearest frame it found.

    A simulation that Blender plays moves some vertex between two of its frames, if only by
    round-off (cloths settled on a sphere, on the ground and hanging from pins still moved 3e-4 to
    1.2e-3 from frame 199 to 200): the same pose to the bit is one it does not play."""
    everything = _all_the_same(poses)
    for mover, modifier in simulations(movers):
        cache = modifier.point_cache
        inside = [i for i, f in enumerate(frames) if cache.frame_start <= f <= cache.frame_end]
        if not (cache.is_baked and cache.use_disk_cache and len(inside) >= 2):
            continue
        # a linked object's bake is looked for beside its library, unless told to use this file's path
        library = mover.library if cache.use_library_path else None
        if cache.use_external:
            folder = bpy.path.abspath(cache.filepath, library=library)
        else:  # Blender's own folder for disk caches, beside the file the object comes from
            blend = library.filepath if library else bpy.data.filepath
            folder = bpy.path.abspath(f"//blendcache_{os.path.splitext(os.path.basename(blend))[0]}",
                                      library=library)
        what = (f"its modifier '{modifier.name}'" if mover == obj else
                f"the modifier '{modifier.name}' of '{mover.name}', which moves it,")
        baked = (f"{what} is baked to disk over frames {cache.frame_start}–{cache.frame_end} (its cache: "
                 f"'{cache.info}')")
        on_disk = bake_frames_on_disk(cache, mover, folder)
        lacking = [frames[i] for i in inside if frames[i] not in on_disk] if on_disk else []
        if lacking:
            listed = ", ".join(str(frame) for frame in lacking[:8]) + (", …" if len(lacking) > 8 else "")
            last = max(on_disk)
            if min(lacking) > last:  # the files stop before the frames lacking them: the bake's last held
                return (f"'{obj.name}': {baked}, but '{folder}' holds its files up to frame {last} only, and "
                        f"{len(lacking)} of the {len(inside)} frames read there {'comes' if len(lacking) == 1 else 'come'} "
                        f"after it ({listed}): Blender "
                        f"holds frame {last} over them (a bake made with Current Cache to Bake from a cache played "
                        f"to frame {last}, or a copy of the folder cut short?). End the frame range at frame {last}, "
                        "bake the whole range, or copy the whole cache folder with the .blend, and run again")
            return (f"'{obj.name}': {baked}, but '{folder}' holds no file for {len(lacking)} of the {len(inside)} "
                    f"frames read there ({listed}): Blender plays them interpolated between the files it finds, "
                    "or holds the nearest one (a copy of the folder cut short, or with gaps?). Copy the whole "
                    "cache folder with the .blend (or bake again) and run again")
        if on_disk is not None:  # the files of every frame read are there
            continue
        # the first run of frames read in a row inside the bake with the same pose
        held = [] if everything else next((run for k in range(len(inside) - 1) if (run := _held_run(poses, inside[k:]))), [])
        if everything or len(held) == len(inside):
            others = bakes_of_other_names(cache, mover, folder)
            advice = (f"'{folder}' holds the bake of an object named {', '.join(repr(name) for name in others)}: "
                      f"if '{mover.name}' was renamed after its bake, name it so again (or bake again)" if others else
                      "Copy the cache folder with the .blend (or bake again)")
            return (f"'{obj.name}' reads the same pose at all {len(frames)} frames read ({frames[0]}–{frames[-1]}), "
                    f"though {baked}: Blender finds none of the bake's files in '{folder}' and plays the mesh at "
                    f"rest. {advice} and run again")
        if held:
            return (f"'{obj.name}' reads the same pose, to the bit, at {len(held)} frames read in a row inside its "
                    f"bake ({_frame_span([frames[i] for i in held])}) while other frames move, though {baked}: "
                    f"Blender finds a file of the bake in '{folder}' for one of those frames at most (a copy of the "
                    "folder cut short?) and holds the nearest one it finds at the others. Copy the whole cache "
                    "folder with the .blend (or bake again) and run again")
    return None


def cache_reads_no_positions(obj: bpy.types.Object, frames: list[int], poses: list[np.ndarray],
                             movers: list) -> str | None:
    """The error when every pose read from ``obj`` at ``frames`` is the same (:func:`_all_the_same`)
    while an enabled Mesh Sequence Cache (Alembic, USD) of one of ``movers`` (``obj`` and the
    objects whose motion reaches its mesh) has Vertices off in its Read Data: it then reads no
    positions from its file, and Blender shows the mesh as it was imported at every frame; None
    otherwise (with other motion on the mesh, Vertices may be off on purpose)."""
    if not _all_the_same(poses):
        return None
    for mover in movers:
        for modifier in mover.modifiers:
            if modifier.type == 'MESH_SEQUENCE_CACHE' and modifier.show_viewport and 'VERT' not in modifier.read_data:
                what = f"'{obj.name}'" if mover == obj else f"'{mover.name}', which moves '{obj.name}',"
                source = (f" from '{os.path.basename(modifier.cache_file.filepath)}'"
                          if modifier.cache_file is not None else "")
                return (f"'{obj.name}' reads the same pose at all {len(frames)} frames read ({frames[0]}–{frames[-1]}): "
                        f"the Mesh Sequence Cache '{modifier.name}' of {what} reads no vertex positions{source} "
                        "(Vertices is off in its Read Data), so Blender shows the mesh as imported at every "
                        "frame. Turn Vertices on in the modifier's Read Data and run again")
    return None


def still_frames(obj: bpy.types.Object, frames: list[int], poses: list[np.ndarray]) -> str | None:
    """A warning when every pose read from ``obj`` at ``frames`` (two or more) is the same, to the
    bit: a motion that never reached the mesh (outside a simulation's frames, or a baked cache of
    another kind than :func:`missing_bake` refuses) rather than a still object, which is rarely
    worth in-betweening; None otherwise."""
    if not _all_the_same(poses):
        return None
    caches = [f"{m.name} cache: '{m.point_cache.info}'" for m in obj.modifiers
              if m.show_viewport and hasattr(m, "point_cache")]
    return (f"The {len(poses)} frames read from '{obj.name}' ({frames[0]}–{frames[-1]}) are all the same pose"
            + (f" ({'; '.join(caches)})" if caches else "")
            + ": if it should move, check what moves it (a baked cache whose files are gone, a simulation "
              "outside this range)")


def frames_outside_simulation(obj: bpy.types.Object, frames: list[int], movers: list) -> str | None:
    """A warning when some of ``frames`` lie outside the frame range of an enabled cloth or soft
    body (its cache's start to end) of one of ``movers``, the objects whose motion reaches the
    mesh of ``obj`` (``obj`` and, say, the cloth proxy its Surface Deform follows): Blender holds
    the simulation's last frame after its end and its first before its start, so the poses read
    there stand still; None otherwise."""
    for mover, modifier in simulations(movers):
        cache = modifier.point_cache
        before = [f for f in frames if f < cache.frame_start]
        after = [f for f in frames if f > cache.frame_end]
        if before or after:
            parts = ([f"{_frame_span(before)} before its start"] if before else []) + \
                    ([f"{_frame_span(after)} after its end"] if after else [])
            subject = f"'{obj.name}' is" if mover == obj else f"'{obj.name}' is moved by '{mover.name}',"
            return (f"{subject} simulated by '{modifier.name}' over frames {cache.frame_start}–"
                    f"{cache.frame_end}, and the range reads {' and '.join(parts)}: Blender holds the "
                    "simulation still outside its frames, so the poses read there do not move. Fit the "
                    "frame range to the simulation's, or widen the simulation's (its Cache panel)")
    return None


def _frame_span(frames: list[int]) -> str:
    """"frame 7" or "frames 50–65" for the ascending ``frames``."""
    return f"frame {frames[0]}" if len(frames) == 1 else f"frames {frames[0]}–{frames[-1]}"


def evaluated_vertex_count(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> int:
    """The number of vertices of ``obj``'s evaluated mesh (after its modifiers) at the depsgraph's
    current frame."""
    return len(obj.evaluated_get(depsgraph).data.vertices)


def frame_positions(context: bpy.types.Context, obj: bpy.types.Object, frames: list[int],
                    first_visit: int | None = None, every_frame: bool = True, set_aside=(), stay: bool = False):
    """Yield ``(frame, positions)`` for the evaluated mesh of ``obj`` at each of ``frames``
    (ascending; yielded in the order visited).

    With ``every_frame`` (the default) every frame from the first (or from ``first_visit`` if
    earlier: where an unbaked simulation starts) to the last is visited in order, so that
    simulations that are not baked still advance one frame at a time; without it only ``frames``
    are visited (a scene whose frames do not depend on the ones before: baked caches, animation),
    the scene's current frame last where it is one of them, so that the scene is left there
    without being set to it again.
    ``stay`` (for a caller that writes to ``obj`` next): where only ``frames`` are visited and
    nothing is set aside, the scene's current frame (sub-frame 0) is read first as it is evaluated,
    without being set again, and the scene is left at the last frame read, also when the caller
    stops early: the caller sets it back to its frame once it has written (and must, whatever
    happens), so that Blender evaluates the object's change and the return to its frame at once
    (at a cloth's start frame each costs a build of the cloth: 55 ms at 15k vertices, 230 ms at 50k);
    the start frame of ``obj``'s simulations is then read after the other frames (a soft body leaving
    it is built anew, as is one whose mesh changed: the return builds it once for both).
    ``set_aside``: modifiers of ``obj`` switched off in the viewport while the frames are read
    (the generators after the motion, :func:`operators.motion_sources.modifiers_set_aside`). Raises
    :class:`NotEvaluated` for an object the depsgraph leaves out (disabled in viewports) and
    :class:`CacheFileMissing` for one whose cache modifier's file is gone, before anything is
    changed, and :class:`VertexCountChanged` for a frame whose mesh has other vertices.
    The scene's current frame (but with ``stay``) and the modifiers are restored afterwards, also
    when the caller stops early.
    """
    scene = context.scene
    missing = missing_cache_file(obj)
    if missing is not None:
        raise CacheFileMissing(
            f"The modifier '{missing[0]}' of '{obj.name}' reads '{missing[1]}', which does not exist (moved "
            "or renamed?), so every frame would read its mesh at rest. Point the modifier to the file and "
            "run again")
    if all(other != obj for other in scene.objects):
        raise NotEvaluated(
            f"'{obj.name}' is not in the scene '{scene.name}', whose frames would be read: run the operator "
            "in a scene that holds it (or link it into this one)")
    if not obj.evaluated_get(context.evaluated_depsgraph_get()).is_evaluated:
        raise NotEvaluated(
            f"'{obj.name}' is disabled in viewports (its own Disable in Viewports, or its "
            "collection's, or the collection is excluded from the view layer), so Blender does not "
            "compute its cloth, armature or other modifiers and every frame would read its rest "
            "mesh. Enable it in viewports (it may stay hidden with the eye icon) and run again")
    wanted = set(frames)
    vertex_count = len(obj.data.vertices)
    original_frame, original_subframe = scene.frame_current, scene.frame_subframe
    aside = [modifier for modifier in set_aside if modifier.show_viewport]
    # a modifier switched and evaluated at a frame past a simulation's start marks its baked cache
    # outdated (Blender then offers to compute it again): switched and evaluated at its start frame
    # it is not
    caches = [m.point_cache.frame_start for m in obj.modifiers if m.type in SIMULATION_MODIFIERS]
    switch_frame = min(caches) if aside and caches else None
    first = frames[0] if first_visit is None else min(first_visit, frames[0])
    visits = list(range(first, frames[-1] + 1) if every_frame else frames)
    # the scene left where the reading ends, for the caller to set back (``stay``)
    staying = stay and not every_frame and not aside and not original_subframe
    shown = None  # the frame the scene was last set to here
    if not every_frame and original_frame in wanted and not original_subframe:
        # frames that do not depend on the ones before: the scene's own frame is read last and the
        # scene stays there, rather than set to it once more afterwards (at a cloth's start frame,
        # where a scene often is, Blender builds the cloth again: 90 ms at 20k vertices); or first,
        # as it is evaluated, where the caller sets the scene back after writing (``stay``)
        visits.remove(original_frame)
        if staying:
            visits.insert(0, original_frame)
            shown = original_frame
        else:
            visits.append(original_frame)
    if staying:
        # a soft body leaving its start frame is built anew (Blender lists each point's springs by scanning
        # every spring: 1.5 s at 10k vertices, 6 s at 20k), and so is one whose mesh changed: the start
        # frame is read after the others, so that the return to the scene's frame once the keys are
        # written builds it once for both (the scene's own frame stays first, read as it is evaluated)
        starts = {modifier.point_cache.frame_start for modifier in obj.modifiers
                  if modifier.type in SIMULATION_MODIFIERS}
        visits.sort(key=lambda frame: frame != shown and frame in starts)
    try:
        if switch_frame is not None:
            scene.frame_set(switch_frame)
        for modifier in aside:
            modifier.show_viewport = False
        if switch_frame is not None:
            context.view_layer.update()
        for frame in visits:
            if frame != shown or not staying:
                scene.frame_set(frame)
                shown = frame
            if frame not in wanted:
                continue
            positions = evaluated_positions(obj, context.evaluated_depsgraph_get())
            if len(positions) != vertex_count:
                counts = {frame: len(positions)}
                if not every_frame:
                    # shown out of order anyway (a frame read in order is not shown ahead of its turn): the
                    # first and last frames asked tell whether the count is one frame's doing
                    for other in sorted({min(wanted), max(wanted)} - {frame}):
                        scene.frame_set(other)
                        shown = other
                        counts[other] = evaluated_vertex_count(obj, context.evaluated_depsgraph_get())
                _refuse_vertex_count(obj, counts, vertex_count, aside)
            yield frame, positions
    finally:
        if switch_frame is not None:
            scene.frame_set(switch_frame)
        for modifier in aside:
            modifier.show_viewport = True
        if switch_frame is not None:
            context.view_layer.update()
        # a scene shown at its own frame with every modifier as it was is already restored
        if not staying and (aside or shown != original_frame or original_subframe):
            scene.frame_set(original_frame, subframe=original_subframe)


def _refuse_vertex_count(obj, counts: dict, vertex_count: int, aside=()):
    """Raise :class:`VertexCountChanged` for ``obj``'s evaluated mesh having other vertices than its
    mesh's ``vertex_count`` (with the modifiers ``aside`` switched off): ``counts`` {frame: vertex
    count} of the frame where it was found and, where they were counted, of the first and last frames
    read. The message says where (at both ends of the range read where it is so at both: no one
    frame's doing) and what changes the topology and, for a generator not set aside, names it (before
    the motion, or after a cloth, soft body or Mesh Cache, whose bake or file the remedies differ in
    keeping)."""
    other = {frame: count for frame, count in counts.items() if count != vertex_count}
    ends = min(counts) in other and max(counts) in other and len(counts) > 1
    if ends:  # a modifier that changes the count from the start, or a cache of another mesh
        low, high = min(other.values()), max(other.values())
        at = f"At the first and the last frame read ({min(counts)} and {max(counts)})"
        had = f"{low}" if low == high else f"{low} to {high}"
    else:
        frame = min(other)
        at, had = f"At frame {frame}", f"{other[frame]}"
    caches = [m for m in obj.modifiers if m.type == 'MESH_SEQUENCE_CACHE' and m.show_viewport]
    if caches:
        source = caches[0].cache_file.filepath if caches[0].cache_file is not None else "its cache file"
        cause = ("its file holds another mesh than this one (or this one was edited after it was imported)"
                 if ends and low == high else
                 "its topology changes over time (a fluid, or a mesh remeshed or built frame by frame)")
        raise VertexCountChanged(
            f"{at} the mesh cache '{caches[0].name}' of '{obj.name}' ({source}) has "
            f"{had} vertices instead of {vertex_count}: {cause}, and shape differences need one mesh whose "
            "vertices persist. Pick a frame range where the vertex count stays the same, or export "
            "the cache with a fixed topology.")
    # an Ocean makes its own grid by default (Geometry › Generate): the motion and the new
    # vertices are the same modifier, which cannot be disabled or applied for the frames' sake
    oceans = [m for m in obj.modifiers if m.type == 'OCEAN' and m.geometry_mode == 'GENERATE' and m.show_viewport]
    if oceans:
        raise VertexCountChanged(
            f"{at} the evaluated mesh of '{obj.name}' has {had} vertices instead of "
            f"{vertex_count}: the Ocean modifier '{oceans[0].name}' makes its own grid (Geometry › "
            "Generate), whose vertices are not the mesh's. Set its Geometry to Displace, on a mesh "
            "with as many vertices (a Grid, or a plane with a Subdivision applied), and run again.")
    generators = [m for m in obj.modifiers if m.show_viewport and m.type in GENERATE_MODIFIERS and m not in aside]
    if generators:
        stack = list(obj.modifiers)
        # a generator with a cloth, soft body or Mesh Cache above it works on the vertices they move, not the mesh's
        played = [next((m for m in stack[:stack.index(generator)]
                        if m.show_viewport and m.type in POSE_REPLACING_MODIFIERS), None) for generator in generators]
        before = [generator for generator, source in zip(generators, played) if source is None]
        advice = (_generators_before_motion(obj, before, vertex_count) if before else
                  _generators_after_playback(obj, generators, played[0], vertex_count))
        raise VertexCountChanged(f"{at} the evaluated mesh of '{obj.name}' has {had} vertices instead of "
                                 f"{vertex_count}: " + advice)
    raise VertexCountChanged(
        f"{at} the evaluated mesh of '{obj.name}' has {had} vertices instead of "
        f"{vertex_count}: a modifier before the motion (or a Geometry Nodes modifier) changes the "
        "topology. Disable modifiers that add or remove geometry there (Subdivision, Remesh, "
        "Decimate, ...) or apply them before simulating or rigging; those after the cloth or "
        "armature are set aside by themselves.")


#: What the refusals call a modifier that plays poses of its own (:data:`POSE_REPLACING_MODIFIERS`).
_PLAYER_KINDS = {'CLOTH': "cloth", 'SOFT_BODY': "soft body", 'MESH_CACHE': "Mesh Cache"}


def _named(generators: list) -> tuple[str, str, str]:
    """``generators`` as the refusals of :func:`_refuse_vertex_count` name them: their names quoted,
    the pronoun for them, and the ending of a verb they are the subject of ("s" for one)."""
    one = len(generators) == 1
    return ", ".join(f"'{m.name}'" for m in generators), "it" if one else "them", "s" if one else ""


def _generators_before_motion(obj, generators: list, vertex_count: int) -> str:
    """What to do about ``generators``, enabled generators of ``obj`` that are not set aside (they
    come before its motion), for the refusal of :func:`_refuse_vertex_count`: apply them. A cloth or
    soft body after them simulates the vertices they make, and its baked cache holds those: applied,
    they become the mesh's and the bake keeps playing; disabled, Blender would simulate the mesh
    without them again (its cache no longer matches), another motion than the bake's."""
    names, it, s = _named(generators)
    after = list(obj.modifiers)[list(obj.modifiers).index(generators[-1]) + 1:]
    simulations = [m for m in after if m.show_viewport and m.type in SIMULATION_MODIFIERS]
    head = (f"{names} come{s} before the motion and change{s} the "
            f"vertex count, and the poses are of the mesh's own {vertex_count} vertices. Apply {it} (the "
            "modifier's menu › Apply)")
    if not simulations:
        return (f"{head}, so that the mesh has the vertices the motion after {it} moves, or disable {it}; "
                "those after the cloth or armature are set aside by themselves.")
    simulation = simulations[0]
    kind = _PLAYER_KINDS[simulation.type]
    if simulation.point_cache.is_baked:
        return (f"{head}: {it} then give{s} the mesh the vertices the {kind} "
                f"'{simulation.name}' moves, and its baked cache, which holds them, keeps playing. Disabling {it} "
                f"instead has Blender simulate the mesh without {it} again (its cache no longer matches): "
                "another motion than the bake's.")
    return (f"{head}: {it} then give{s} the mesh the vertices the {kind} '{simulation.name}' "
            "simulates (its cache is not baked: Blender simulates it again from its start, on those vertices as "
            "now).")


def _generators_after_playback(obj, generators: list, source, vertex_count: int) -> str:
    """What to do about ``generators``, enabled generators of ``obj`` that come after ``source`` (a
    cloth, soft body or cache reader: :data:`POSE_REPLACING_MODIFIERS`) and are not set aside, for the
    refusal of :func:`_refuse_vertex_count`. Where a modifier that moves the mesh follows them (an
    Armature), move them below it: at the end of the stack they are set aside while the frames are
    read; at the end already, they were not set aside for a cache switching them would outdate (a
    simulation's, not baked, or those of the objects ``obj`` collides with or pushes): bake it. Or
    disable them. Applying them, the advice for a generator before the motion, would give ``source``
    other vertices than its cache or file holds: a simulation simulates again (another motion), a
    Mesh Cache no longer plays."""
    names, it, s = _named(generators)
    kind = _PLAYER_KINDS.get(source.type, "cache")
    simulated = source.type in SIMULATION_MODIFIERS
    stack = list(obj.modifiers)
    below = [m for m in stack[stack.index(generators[-1]) + 1:] if m.show_viewport and m.type not in GENERATE_MODIFIERS]
    bake = f"the {kind} '{source.name}'" if simulated and not source.point_cache.is_baked else ""
    if below:
        remedy = (f"Move {it} below {', '.join(repr(m.name) for m in below)}, to the end of the stack"
                  + (f", and bake {bake} (Physics › Cache › Bake)" if bake else ""))
    else:
        remedy = (f"Bake {bake or 'the simulations of the objects it collides with or pushes'} (Physics › Cache › "
                  "Bake), which switching it off would outdate")
    applied = ("vertices it did not simulate: Blender would simulate it again, another motion" if simulated else
               "other vertices than its file holds, which Blender does not play")
    return (f"{names} come{s} after the {kind} '{source.name}' and "
            f"change{s} the vertex count, and the poses are of the mesh's own {vertex_count} "
            f"vertices. {remedy}: {it} {'is' if s else 'are'} then set aside while the frames are read (a new "
            f"object gets a copy); or disable {it}. Applying {it} would give the {kind} {applied}.")


@dataclass
class NewShapeKey:
    """A shape key to be written: its wanted name and coordinates. ``name`` may be shortened to
    fit Blender's limit; ``tail`` (e.g. the factor) is always kept."""

    name: str
    positions: np.ndarray
    tail: str = ""


MAX_NAME_LENGTH = 63  # bytes (UTF-8) in a Blender ID or shape key name


def shorten(text: str, limit: int) -> str:
    """``text`` within ``limit`` bytes (UTF-8), cut short with a final "…" if it is longer."""
    encoded = text.encode()
    if len(encoded) <= limit:
        return text
    ellipsis = "\u2026"
    return encoded[:max(limit - len(ellipsis.encode()), 0)].decode(errors="ignore") + ellipsis


def fit_name(head: str, tail: str = "") -> str:
    """``head + tail`` within Blender's name length: ``head`` (e.g. a key or object name) is
    shortened so that ``tail`` (the factor, the reference, a number) is always kept whole."""
    return shorten(head, MAX_NAME_LENGTH - len(tail.encode())) + tail


def unique_name(head: str, tail: str, taken) -> str:
    """``fit_name(head, tail)``, or with ``.001``, ``.002``, ... appended if that name is taken.

    Blender's own renaming cuts the end of a long name to fit its number (losing a factor) and
    reads a name ending in ``0.50`` as already numbered (``0.051``); this never does either."""
    candidate = fit_name(head, tail)
    number = 0
    while candidate in taken:
        number += 1
        candidate = fit_name(head, f"{tail}.{number:03d}")
    return candidate


def unique_key_name(obj: bpy.types.Object, name: str, tail: str = "") -> str:
    """A shape key name for ``name + tail`` not yet used on ``obj`` (see :func:`unique_name`)."""
    taken = set(obj.data.shape_keys.key_blocks.keys()) if obj.data.shape_keys else set()
    return unique_name(name, tail, taken)


def add_shape_keys(obj: bpy.types.Object, new_keys: list[NewShapeKey],
                   keyframes: list[float] | None = None) -> list[str]:
    """Add each of ``new_keys`` as a new shape key with value 0 (creating the Basis first if the
    mesh has none) and return the names they got.

    With ``keyframes`` (one increasing frame per key), the key values are animated so that
    playback steps through the keys (see :func:`keyframe_key_values`). Existing keys are never
    touched and the active key stays active; a taken name gets a ``.001`` suffix
    (:func:`unique_key_name`). If anything fails, every key added here (and a Basis created here)
    is removed again before the error propagates.
    """
    had_basis = obj.data.shape_keys is not None
    active_index = obj.active_shape_key_index
    added: list[bpy.types.ShapeKey] = []
    try:
        if not had_basis:
            obj.shape_key_add(name=BASIS_NAME, from_mix=False)
        for new_key in new_keys:
            key_block = obj.shape_key_add(name=unique_key_name(obj, new_key.name, new_key.tail),
                                           from_mix=False)
            added.append(key_block)
            key_block.value = 0.0
            # ``points``: the bulk write (:func:`stored_key_positions`)
            key_block.points.foreach_set(
                "co", np.ascontiguousarray(new_key.positions, dtype=np.float32).ravel())
        names = [key_block.name for key_block in added]
        if keyframes is not None:
            keyframe_key_values(obj, list(zip(keyframes, names)))
        obj.data.update()
        return names
    except BaseException:
        remove_shape_keys(obj, [key_block.name for key_block in added], remove_basis=not had_basis)
        raise
    finally:
        obj.active_shape_key_index = active_index


def remove_shape_keys(obj: bpy.types.Object, names: list[str], *, remove_basis: bool = False):
    """Remove the named shape keys (and the Basis too if ``remove_basis``)."""
    key = obj.data.shape_keys
    if key is None:
        return
    for name in names:
        key_block = key.key_blocks.get(name)
        if key_block is not None:
            obj.shape_key_remove(key_block)
    if remove_basis and obj.data.shape_keys is not None and len(obj.data.shape_keys.key_blocks) == 1:
        obj.shape_key_remove(obj.data.shape_keys.key_blocks[0])
    obj.data.update()


def shape_key_value_fcurve(key: bpy.types.Key, key_name: str):
    """The F-curve animating ``key_blocks[key_name].value`` (legacy and slotted actions)."""
    animation_data = key.animation_data
    data_path = f'key_blocks["{bpy.utils.escape_identifier(key_name)}"].value'
    action = animation_data.action if animation_data else None
    if action is None:
        return None
    if hasattr(animation_data, "action_slot"):  # Blender 4.4+: layered actions with slots
        from bpy_extras import anim_utils
        channelbag = anim_utils.action_get_channelbag_for_slot(action, animation_data.action_slot)
        fcurves = channelbag.fcurves if channelbag else ()
    else:
        fcurves = action.fcurves
    return next((fcurve for fcurve in fcurves if fcurve.data_path == data_path), None)


def keyframe_key_values(obj: bpy.types.Object, timeline: list[tuple[float, str]]):
    """Keyframe the values of the named shape keys so that playback steps through them.

    ``timeline`` is ``(frame, key name)`` in increasing frame order: each key gets value 1 at its
    frame and 0 at the frames of its neighbours, with linear interpolation, so between two samples
    the mesh blends linearly from one key to the next. Only F-curves of these keys are written.
    """
    key = obj.data.shape_keys
    frames = [frame for frame, _ in timeline]
    for index, (frame, name) in enumerate(timeline):
        key_block = key.key_blocks[name]
        neighbours = [frames[i] for i in (index - 1, index + 1) if 0 <= i < len(frames)]
        for when, value in [(frame, 1.0)] + [(neighbour, 0.0) for neighbour in neighbours]:
            key_block.value = value
            key_block.keyframe_insert("value", frame=when)
        key_block.value = 0.0
        fcurve = shape_key_value_fcurve(key, name)
        if fcurve is not None:
            for point in fcurve.keyframe_points:
                point.interpolation = 'LINEAR'
            fcurve.update()


# -- a new object that plays a point cache ----------------------------------------------------

# Parent types that deform the child (a virtual modifier): the copy is parented as an object
# ('OBJECT': the same world matrix, parent.matrix_world @ matrix_parent_inverse @ matrix_basis).
DEFORMING_PARENT_TYPES = {'ARMATURE', 'LATTICE', 'CURVE'}
# The object's own transform channels, copied before its animation and constraints.
TRANSFORM_CHANNELS = ("rotation_mode", "location", "rotation_euler", "rotation_quaternion",
                      "rotation_axis_angle", "scale", "delta_location", "delta_rotation_euler",
                      "delta_rotation_quaternion", "delta_scale")


def add_cache_object(context: bpy.types.Context, source: bpy.types.Object, name: str,
                     filepath: str, start: float, sampling: float, modifiers=(),
                     speed: float = 1.0, source_end: float | None = None,
                     deformed_by_parent: bool = False) -> bpy.types.Object:
    """A new object named ``name`` with a copy of ``source``'s mesh (no shape keys, no
    modifiers) and a Mesh Cache modifier that plays the PC2 file ``filepath`` whose first sample
    is at frame ``start``, one every ``sampling`` frames, followed by copies of ``source``'s
    ``modifiers`` (the generators after its motion: a Subdivision, a Solidify; or, for poses of its
    shape keys, its whole stack: an Armature), with ``source``'s
    object-linked materials and render settings (:func:`copy_object_look`).

    It is linked to the collections of ``source`` (the scene's where those are linked from a
    library or overridden) and moves as ``source`` does as a whole
    (:func:`copy_object_motion`; the cache holds object-space positions; ``speed``, ``source_end``:
    a retime that plays ``source``'s frames ``start`` … ``source_end``; ``deformed_by_parent``:
    a parent deforming ``source`` deforms the poses too, by :func:`parent_deform_modifier`);
    ``source`` stays the
    active, selected object. If anything fails, the new object and mesh are removed again.
    """
    mesh = source.data.copy()
    obj = None
    try:
        mesh.name = name
        forget_analysis(mesh)
        obj = bpy.data.objects.new(name, mesh)
        if mesh.shape_keys is not None:
            obj.shape_key_clear()
        # the source's collections that take new objects (not linked from a library, not
        # overridden, not a rigid body world's: Blender makes every object in that one a rigid body
        # of its simulation), else the scene's own
        simulated = rigid_body_collections()
        editable = [c for c in source.users_collection
                    if c.library is None and c.override_library is None and c not in simulated]
        for collection in editable or (context.scene.collection,):
            collection.objects.link(obj)
        copy_object_motion(source, obj, start, speed, source_end)
        copy_object_look(source, obj)
        modifier = obj.modifiers.new("Mesh Cache", 'MESH_CACHE')
        modifier.cache_format = 'PC2'
        modifier.filepath = filepath
        # The modifier reads sample (frame * frame_scale - frame_start) of the file.
        modifier.frame_scale = 1.0 / sampling
        modifier.frame_start = start / sampling
        if deformed_by_parent and source.parent is not None and source.parent_type in DEFORMING_PARENT_TYPES:
            parent_deform_modifier(source, obj)
        if modifiers:
            # Blender's own copy: every setting, Geometry Nodes inputs included
            with context.temp_override(object=source, active_object=source, selected_objects=[obj],
                                       selected_editable_objects=[obj]):
                for copied in modifiers:
                    bpy.ops.object.modifier_copy_to_selected(modifier=copied.name)
        return obj
    except BaseException:
        if obj is not None:
            bpy.data.objects.remove(obj)  # a shared action stays: it is the source's
        bpy.data.meshes.remove(mesh)
        raise


#: The names of the attributes the analysis operators write (operators/analysis.py, distortion
#: maps): colours "SD Area", "SD Conformal", "SD Bending", "SD Eigen Offset Area 2", values
#: "sd_area", "sd_area_face", each alone (a key's) or with the frame mapped (" f12"). Exact names,
#: not prefixes: a user's own "sd_mask" or "SD Paint" is no map.
ANALYSIS_ATTRIBUTE = re.compile(r"(SD (Area|Conformal|Bending|Eigen (Offset )?(Area|Conformal) \d+)"
                                r"|sd_(area|conformal|bending)(_face)?)( f-?\d+)?")


def forget_analysis(mesh: bpy.types.Mesh) -> None:
    """Remove from ``mesh`` (a copy of a source's mesh, for a new object playing other poses) the
    distortion maps of the source's poses and every custom property (a pipeline's asset tags
    stay with the source; the frame maps' list would show the source's maps on the new object)."""
    for attribute in [a.name for a in mesh.attributes if ANALYSIS_ATTRIBUTE.fullmatch(a.name)]:
        mesh.attributes.remove(mesh.attributes[attribute])
    for key in list(mesh.keys()):
        del mesh[key]


def parent_deform_modifier(source: bpy.types.Object, obj: bpy.types.Object) -> None:
    """Add to ``obj`` the modifier that stands for ``source``'s deforming parent (an armature,
    lattice or curve parent): Blender applies such a parent as a modifier before the whole
    stack, where the Mesh Cache would overwrite it, so ``obj`` is parented as an object
    (:func:`copy_object_motion`) and gets the modifier after its Mesh Cache — with the settings
    Blender gives it (an armature parent deforms by vertex groups and envelopes; a curve parent
    along the object's track axis)."""
    kind = source.parent_type
    modifier = obj.modifiers.new(f"{source.parent.name} (parent)", kind)
    modifier.object = source.parent
    if kind == 'ARMATURE':
        modifier.use_vertex_groups, modifier.use_bone_envelopes = True, True
    elif kind == 'CURVE':
        modifier.deform_axis = source.track_axis


# Object settings that decide how an object renders and shows (Blender 4.x / 5.x names; those a
# version lacks are skipped).
LOOK_SETTINGS = ("hide_render", "visible_camera", "visible_diffuse", "visible_glossy",
                 "visible_transmission", "visible_volume_scatter", "visible_shadow", "is_holdout",
                 "is_shadow_catcher", "pass_index", "color", "lightgroup", "display_type", "show_wire",
                 "show_all_edges", "show_in_front", "shadow_terminator_normal_offset",
                 "shadow_terminator_geometry_offset", "shadow_terminator_shading_offset")


def copy_object_look(source: bpy.types.Object, obj: bpy.types.Object) -> None:
    """Give ``obj`` (holding a copy of ``source``'s mesh) ``source``'s materials linked to the
    object rather than the mesh, and its render visibility, pass index, colour and display
    settings (:data:`LOOK_SETTINGS`), so that it renders as ``source`` does."""
    for slot, copied in zip(source.material_slots, obj.material_slots):
        if slot.link == 'OBJECT':
            copied.link = 'OBJECT'
            copied.material = slot.material
    for setting in LOOK_SETTINGS:
        if hasattr(source, setting):
            setattr(obj, setting, getattr(source, setting))


def _rigid_body_worlds() -> list:
    """The rigid body worlds of the file's scenes."""
    return [scene.rigidbody_world for scene in bpy.data.scenes if scene.rigidbody_world is not None]


def rigid_body_collections() -> list:
    """The collections of the scenes' rigid body worlds (their bodies and their constraints):
    Blender gives every object linked to the first a rigid body and simulates it with the others."""
    return [c for world in _rigid_body_worlds() for c in (world.collection, world.constraints) if c is not None]


def simulated_rigid_body(obj: bpy.types.Object) -> bool:
    """Whether ``obj`` is moved as a whole by a rigid body simulation: an active rigid body that is
    dynamic and not animated, of a scene's rigid body world that is on (the simulation sets its
    world matrix; its transform channels and mesh stay as they are)."""
    body = obj.rigid_body
    if body is None or body.type != 'ACTIVE' or not body.enabled or body.kinematic:
        return False
    return any(world.enabled and world.collection is not None and obj.name in world.collection.all_objects
               for world in _rigid_body_worlds())


def unbaked_rigid_body_shape(obj: bpy.types.Object) -> bool:
    """Whether ``obj`` is a rigid body of a rigid body world that is not baked, with a collision
    shape read from its deformed mesh (Convex Hull or Mesh from Deform or Final): shape keys added
    to it change the shapes the simulation collides, and so the simulation, when it is played
    again."""
    body = obj.rigid_body
    if body is None or body.collision_shape not in {'CONVEX_HULL', 'MESH'} or body.mesh_source == 'BASE':
        return False
    return any(world.collection is not None and obj.name in world.collection.all_objects
               and not world.point_cache.is_baked for world in _rigid_body_worlds())


#: The largest scale of an NLA strip (Blender clamps it): an action plays at most this many times slower.
NLA_MAX_SCALE = 1000.0


def copy_object_motion(source: bpy.types.Object, obj: bpy.types.Object, start: float = 0.0,
                       speed: float = 1.0, source_end: float | None = None) -> None:
    """Give the new object ``obj`` what moves ``source`` as a whole, so that object-space
    positions played on ``obj`` land where they do on ``source``: its parent (parented as an
    object where the parent deforms ``source``), its transform channels, its constraints (copies)
    and its keyframed transform (the same action, shared). ``speed`` ≠ 1: ``obj`` plays
    ``source``'s time ``start + (frame − start) · speed`` at ``frame`` up to ``source_end`` (a
    retime), its action through an NLA strip scaled by ``1 / speed``; a parent and constraints
    keep the scene's own timing. Not taken over: NLA tracks and drivers."""
    if source.parent is not None:
        obj.parent = source.parent
        obj.parent_type = 'OBJECT' if source.parent_type in DEFORMING_PARENT_TYPES else source.parent_type
        obj.parent_bone = source.parent_bone
        obj.parent_vertices = source.parent_vertices[:]  # a vertex parent's vertices ('VERTEX', 'VERTEX_3')
        obj.matrix_parent_inverse = source.matrix_parent_inverse.copy()
    for channel in TRANSFORM_CHANNELS:
        setattr(obj, channel, getattr(source, channel))
    for constraint in source.constraints:  # RNA's copy: an operator refuses a source hidden in viewports
        obj.constraints.copy(constraint)
    animation = source.animation_data
    if animation is not None and animation.action is not None:
        data = obj.animation_data_create()
        if speed == 1.0:
            data.action = animation.action
            if hasattr(animation, "action_slot"):  # Blender 4.4+: the slot the source plays
                data.action_slot = animation.action_slot
        else:
            strip = data.nla_tracks.new().strips.new(f"{source.name} at {speed:g}x", int(start), animation.action)
            if hasattr(animation, "action_slot"):
                strip.action_slot = animation.action_slot
            first, last = start, start if source_end is None else source_end
            for _ in range(2):  # each setter clamps to the other end: twice reaches any range
                strip.action_frame_start, strip.action_frame_end = first, max(last, first + 1.0)
            strip.frame_start_ui = start  # moves the strip, keeping its length
            strip.scale = 1.0 / speed


#: Custom property (on the object) holding the last shape space (operators/analysis.py).
SHAPE_SPACE_PROPERTY = "shape_space"


def stored_shape_space(obj) -> dict | None:
    """The shape space last stored on ``obj`` as a plain dict, or None."""
    if obj is None or SHAPE_SPACE_PROPERTY not in obj:
        return None
    data = obj[SHAPE_SPACE_PROPERTY]
    return data.to_dict() if hasattr(data, "to_dict") else dict(data)


def loop_triangle_polygons(mesh) -> np.ndarray:
    """The polygon of every loop triangle, int64 ``(m,)`` (same order as bridge.mesh_triangles)."""
    mesh.calc_loop_triangles()
    buffer = np.empty(len(mesh.loop_triangles), dtype=np.int32)
    mesh.loop_triangles.foreach_get("polygon_index", buffer)
    return buffer.astype(np.int64)


def write_attribute(mesh, name: str, domain: str, values: np.ndarray, *, color: bool = False):
    """Create or overwrite one attribute (FLOAT, or FLOAT_COLOR when ``color``) of ``mesh``."""
    kind = 'FLOAT_COLOR' if color else 'FLOAT'
    existing = mesh.attributes.get(name)
    if existing is not None and (existing.data_type != kind or existing.domain != domain):
        mesh.attributes.remove(existing)
        existing = None
    if existing is None:
        existing = (mesh.color_attributes.new(name, kind, domain) if color
                    else mesh.attributes.new(name, kind, domain))
    existing.data.foreach_set("color" if color else "value", np.ascontiguousarray(values, dtype=np.float32).ravel())
    return existing
