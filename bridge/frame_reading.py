"""Reading an object's frames: the evaluated mesh at each frame, visiting the frames as simulations
and the scene's own frame need, with the generators after the motion set aside (:func:`frame_positions`);
the refusals of reading them (:class:`FrameReadError` and its kinds), and the refusal of a frame whose
evaluated mesh has other vertices than the mesh: what changes the topology (a cache, an Ocean, a
generator before or after the motion) and the way out for each (:func:`refuse_vertex_count`).
"""

from __future__ import annotations

import bpy

from .cache_files import missing_cache_file
from .mesh_data import evaluated_positions, evaluated_vertex_count
from .modifier_kinds import GENERATE_MODIFIERS, POSE_REPLACING_MODIFIERS, SIMULATION_MODIFIERS


# -- the refusals of reading frames

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


# -- a frame whose evaluated mesh has other vertices

def refuse_vertex_count(obj, counts: dict, vertex_count: int, aside=()):
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


#: What the refusals call a modifier that plays poses of its own
#: (:data:`bridge.modifier_kinds.POSE_REPLACING_MODIFIERS`).
_PLAYER_KINDS = {'CLOTH': "cloth", 'SOFT_BODY': "soft body", 'MESH_CACHE': "Mesh Cache"}


def _named(generators: list) -> tuple[str, str, str]:
    """``generators`` as the refusals of :func:`refuse_vertex_count` name them: their names quoted,
    the pronoun for them, and the ending of a verb they are the subject of ("s" for one)."""
    one = len(generators) == 1
    return ", ".join(f"'{m.name}'" for m in generators), "it" if one else "them", "s" if one else ""


def _generators_before_motion(obj, generators: list, vertex_count: int) -> str:
    """What to do about ``generators``, enabled generators of ``obj`` that are not set aside (they
    come before its motion), for the refusal of :func:`refuse_vertex_count`: apply them. A cloth or
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
    cloth, soft body or cache reader: :data:`bridge.modifier_kinds.POSE_REPLACING_MODIFIERS`) and are not set aside, for
    the refusal of :func:`refuse_vertex_count`. Where a modifier that moves the mesh follows them (an
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


# -- reading the frames

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

    def show_aside(show: bool):
        # the modifiers set aside switched off (or back on) at ``switch_frame``
        if switch_frame is not None:
            scene.frame_set(switch_frame)
        for modifier in aside:
            modifier.show_viewport = show
        if switch_frame is not None:
            context.view_layer.update()

    try:
        show_aside(False)
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
        show_aside(True)
        # a scene shown at its own frame with every modifier as it was is already restored
        if not staying and (aside or shown != original_frame or original_subframe):
            scene.frame_set(original_frame, subframe=original_subframe)
