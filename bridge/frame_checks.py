"""What the frames read tell of the cache or simulation that played them. From a Mesh Cache or Mesh
Sequence Cache (Alembic, USD): frames outside the file's samples, the end samples held, a file of
another mesh or vertex order, a cache reading no positions. From a cloth or soft body: a bake to disk
whose files are missing (by the names Blender gives them), frames outside the simulation's range,
every frame the same pose. Each check returns a warning or an error in the user's terms, or None;
runs of poses read that are the same to the bit, and spans of frames as the messages name them, are
shared by both.
"""

from __future__ import annotations

import os
import re

import bpy
import numpy as np

from .cache_files import mesh_cache_file, mesh_cache_header
from .mesh_data import face_edges, vertex_positions
from .modifier_kinds import simulations
from .scene_timing import scene_time


# -- runs of poses read, spans of frames (both kinds of check)

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


def _frame_span(frames: list[int]) -> str:
    """"frame 7" or "frames 50–65" for the ascending ``frames``."""
    return f"frame {frames[0]}" if len(frames) == 1 else f"frames {frames[0]}–{frames[-1]}"


# -- a Mesh Cache or Mesh Sequence Cache (Alembic, USD)

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


# -- a cloth or soft body

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
        held = [] if everything else next(
            (run for k in range(len(inside) - 1) if (run := _held_run(poses, inside[k:]))), [])
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
