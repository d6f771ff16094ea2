"""The refusal of a frame whose evaluated mesh has other vertices than the mesh: what changes the
topology (a cache, an Ocean, a generator before or after the motion) and the way out for each.
"""

from __future__ import annotations

from .frame_errors import VertexCountChanged
from .modifier_kinds import GENERATE_MODIFIERS, POSE_REPLACING_MODIFIERS, SIMULATION_MODIFIERS


def refuse_vertex_count(obj, counts: dict, vertex_count: int, aside=()):
    """Raise :class:`bridge.frame_errors.VertexCountChanged` for ``obj``'s evaluated mesh having other vertices than its
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
