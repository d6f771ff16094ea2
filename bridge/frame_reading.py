"""Reading an object's frames: the evaluated mesh at each frame, visiting the frames as simulations
and the scene's own frame need, with the generators after the motion set aside.
"""

from __future__ import annotations

import bpy

from .cache_files import missing_cache_file
from .frame_errors import CacheFileMissing, NotEvaluated
from .mesh_data import evaluated_positions, evaluated_vertex_count
from .modifier_kinds import SIMULATION_MODIFIERS
from .vertex_count_refusal import refuse_vertex_count


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
    :class:`bridge.frame_errors.NotEvaluated` for an object the depsgraph leaves out (disabled in viewports) and
    :class:`bridge.frame_errors.CacheFileMissing` for one whose cache modifier's file is gone, before anything is
    changed, and :class:`bridge.frame_errors.VertexCountChanged` for a frame whose mesh has other vertices.
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
                refuse_vertex_count(obj, counts, vertex_count, aside)
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
