"""What the frames read from a Mesh Cache or Mesh Sequence Cache (Alembic, USD) tell: frames outside
the file's samples, the end samples held, a file of another mesh or vertex order, a cache reading no
positions. Each returns a warning or an error in the user's terms, or None.
"""

from __future__ import annotations

import os

import bpy
import numpy as np

from .cache_files import mesh_cache_file, mesh_cache_header
from .mesh_data import face_edges, vertex_positions
from .pose_runs import all_the_same, frame_span, held_run
from .scene_timing import scene_time


def frames_outside_cache(scene: bpy.types.Scene, obj: bpy.types.Object, frames: list[int],
                         movers: list) -> str | None:
    """A warning when some of ``frames`` play a time before the first or after the last sample of
    the file of an enabled Mesh Cache modifier (Play Mode Scene) of one of ``movers`` (``obj`` and
    the objects whose motion reaches its mesh): Blender holds the file's first sample before it and
    its last after it, so the poses read there stand still (a cache shorter than the frame range, or
    exported at another frame offset); None otherwise. At the scene time ``t`` (:func:`bridge.scene_timing.scene_time`)
    the modifier plays, with Time Mode Frame, sample ``t · Frame Scale − Frame Start``; with Time
    Mode Seconds, an MDD's frame at ``t / fps · Frame Scale − Frame Start`` seconds (a PC2 there is
    not checked). Where it takes the nearest sample (Interpolation None), half a sample's spacing
    outside still plays the end sample at its due time."""
    from ..core.errors import MeshError

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
            parts = ([f"{frame_span(before)} before its first sample"] if before else []) + \
                    ([f"{frame_span(after)} after its last"] if after else [])
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
    (:func:`bridge.bake_checks.still_frames` says so)."""
    caches = [(mover, m) for mover in movers for m in mover.modifiers
              if m.type == 'MESH_SEQUENCE_CACHE' and m.show_viewport]
    if not caches or len(poses) < 3 or all_the_same(poses):
        return None

    def held(indices) -> list[int]:
        return sorted(frames[index] for index in held_run(poses, indices))

    before, after = held(range(len(poses))), held(range(len(poses) - 1, -1, -1))
    if not (before or after):
        return None
    parts = ([f"its start ({frame_span(before)})"] if before else []) + \
            ([f"its end ({frame_span(after)})"] if after else [])
    mover, modifier = caches[0]
    source = f" from '{os.path.basename(modifier.cache_file.filepath)}'" if modifier.cache_file is not None else ""
    subject = f"'{obj.name}' is" if mover == obj else f"'{obj.name}' is moved by '{mover.name}', which is"
    return (f"{subject} played by the Mesh Sequence Cache '{modifier.name}'{source}, and the range reads "
            f"the same pose, to the bit, at {' and '.join(parts)}, as Blender plays a cache before its first "
            "frame and after its last (it holds the end samples; the in-betweens next to a held key slow to a "
            "stop). If the cache is shorter than the range, fit the frame range to the cache's frames (or check "
            "the Cache File's Frame Offset); a hold in the animation itself needs nothing")


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
    from ..core.vertex_order import EdgeSpread

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


def cache_reads_no_positions(obj: bpy.types.Object, frames: list[int], poses: list[np.ndarray],
                             movers: list) -> str | None:
    """The error when every pose read from ``obj`` at ``frames`` is the same (:func:`bridge.pose_runs.all_the_same`)
    while an enabled Mesh Sequence Cache (Alembic, USD) of one of ``movers`` (``obj`` and the
    objects whose motion reaches its mesh) has Vertices off in its Read Data: it then reads no
    positions from its file, and Blender shows the mesh as it was imported at every frame; None
    otherwise (with other motion on the mesh, Vertices may be off on purpose)."""
    if not all_the_same(poses):
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
