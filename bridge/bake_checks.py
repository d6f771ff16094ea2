"""What the frames read from a cloth or soft body tell: a bake to disk whose files are missing (by
the names Blender gives them), frames outside the simulation's range, every frame the same pose.
Each returns a warning or an error in the user's terms, or None.
"""

from __future__ import annotations

import os
import re

import bpy
import numpy as np

from .modifier_kinds import simulations
from .pose_runs import all_the_same, frame_span, held_run


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
      (:func:`bridge.pose_runs.all_the_same`): Blender found none of the bake's files (a .blend moved, or sent to a
      farm, without its cache folder) and plays the rest mesh; or two or more frames read in a row
      inside the bake the same pose while others move: Blender holds the nearest frame it found.

    A simulation that Blender plays moves some vertex between two of its frames, if only by
    round-off (cloths settled on a sphere, on the ground and hanging from pins still moved 3e-4 to
    1.2e-3 from frame 199 to 200): the same pose to the bit is one it does not play."""
    everything = all_the_same(poses)
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
        held = [] if everything else next((run for k in range(len(inside) - 1) if (run := held_run(poses, inside[k:]))), [])
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
                    f"bake ({frame_span([frames[i] for i in held])}) while other frames move, though {baked}: "
                    f"Blender finds a file of the bake in '{folder}' for one of those frames at most (a copy of the "
                    "folder cut short?) and holds the nearest one it finds at the others. Copy the whole cache "
                    "folder with the .blend (or bake again) and run again")
    return None


def still_frames(obj: bpy.types.Object, frames: list[int], poses: list[np.ndarray]) -> str | None:
    """A warning when every pose read from ``obj`` at ``frames`` (two or more) is the same, to the
    bit: a motion that never reached the mesh (outside a simulation's frames, or a baked cache of
    another kind than :func:`missing_bake` refuses) rather than a still object, which is rarely
    worth in-betweening; None otherwise."""
    if not all_the_same(poses):
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
            parts = ([f"{frame_span(before)} before its start"] if before else []) + \
                    ([f"{frame_span(after)} after its end"] if after else [])
            subject = f"'{obj.name}' is" if mover == obj else f"'{obj.name}' is moved by '{mover.name}',"
            return (f"{subject} simulated by '{modifier.name}' over frames {cache.frame_start}–"
                    f"{cache.frame_end}, and the range reads {' and '.join(parts)}: Blender holds the "
                    "simulation still outside its frames, so the poses read there do not move. Fit the "
                    "frame range to the simulation's, or widen the simulation's (its Cache panel)")
    return None
