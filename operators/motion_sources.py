"""What moves an object, and what reading its frames or changing its mesh must respect: the
modifiers that move its vertices, add or remove vertices, or only shade (:func:`moves_vertices`,
:func:`trailing_generators`), the objects whose motion reaches its mesh (:func:`objects_moving`) and
what moves it as a whole (:func:`object_motion`), Mesh Cache files Blender cannot play
(:func:`unfit_mesh_cache`), simulations and their unbaked caches (:func:`unbaked_simulations`,
:func:`frames_depend_on_earlier`, :func:`refuse_emptying_caches`), and the modifiers set aside while
frames are read or copied to a new object (:func:`modifiers_set_aside`, :func:`modifiers_under_keys`,
:func:`modifiers_under_frames`). Writing the poses: :mod:`.output`.
"""

from __future__ import annotations

import os

import bpy
import numpy as np

from ..bridge import cache_files, copied_motion, mesh_data, modifier_kinds, rigid_bodies, scene_timing
from .base import InputError

# Modifiers that do not move the mesh they are on.
PASSIVE_MODIFIERS = {'COLLISION'}


def unbaked_simulations(obj) -> list[str]:
    """Names of ``obj``'s enabled cloth / soft body modifiers whose cache is not baked."""
    return [modifier.name for _, modifier in modifier_kinds.simulations([obj]) if not modifier.point_cache.is_baked]


def objects_moving(obj) -> list:
    """``obj`` and the objects whose motion may reach its evaluated mesh: its parents and the
    objects its modifiers (Geometry Nodes inputs too) and constraints point to — a Surface Deform's
    cloth proxy, a Mesh Deform cage, an Armature — and theirs in turn."""
    found, pending = [], [obj]
    while pending:
        current = pending.pop()
        if current is None or current in found:
            continue
        found.append(current)
        pending.append(current.parent)
        for item in (*current.modifiers, *current.constraints):
            pending += [getattr(item, prop.identifier) for prop in item.bl_rna.properties
                        if prop.type == 'POINTER' and getattr(prop.fixed_type, "identifier", None) == 'Object']
            if item.type == 'NODES':
                pending += [value for value in item.values() if isinstance(value, bpy.types.Object)]
    return found


#: Modifiers that smooth or displace the mesh without animation of their own: they may follow a
#: generator in the run that is set aside.
MOVING_TOUCH_UP_MODIFIERS = {'SMOOTH', 'CORRECTIVE_SMOOTH', 'LAPLACIANSMOOTH', 'DISPLACE'}
#: Modifiers that change normals, UVs, weights or shading and never a vertex position: the new
#: object takes them over from the end of the stack even where nothing is set aside.
STILL_MODIFIERS = {'WEIGHTED_NORMAL', 'NORMAL_EDIT', 'UV_PROJECT', 'UV_WARP', 'VERTEX_WEIGHT_EDIT',
                   'VERTEX_WEIGHT_MIX', 'VERTEX_WEIGHT_PROXIMITY', 'DATA_TRANSFER', 'COLLISION'}
#: Geometry Nodes that only read fields or set shading, materials and attributes: a node group
#: made of these (Blender's *Smooth by Angle*, added by *Shade Auto Smooth*) moves nothing, adds
#: nothing and does not depend on the frames before.
ATTRIBUTE_NODES = {
    'NodeGroupInput', 'NodeGroupOutput', 'NodeReroute', 'NodeFrame', 'GeometryNodeGroup',
    'GeometryNodeSetShadeSmooth', 'GeometryNodeInputShadeSmooth', 'GeometryNodeInputEdgeSmooth',
    'GeometryNodeInputMeshEdgeAngle', 'GeometryNodeInputNormal', 'GeometryNodeInputPosition',
    'GeometryNodeInputIndex', 'GeometryNodeInputNamedAttribute', 'GeometryNodeStoreNamedAttribute',
    'GeometryNodeRemoveAttribute', 'GeometryNodeSetMaterial', 'GeometryNodeSetMaterialIndex',
    'GeometryNodeInputMaterialIndex', 'FunctionNodeCompare', 'FunctionNodeBooleanMath',
    'FunctionNodeInputBool', 'ShaderNodeMath', 'ShaderNodeVectorMath', 'ShaderNodeValue',
}


def group_nodes(tree):
    """Every node of the node tree ``tree`` and of the groups in it (each group once)."""
    trees, seen = [tree], set()
    while trees:
        tree = trees.pop()
        if tree.name_full in seen:
            continue
        seen.add(tree.name_full)
        for node in tree.nodes:
            yield node
            if node.bl_idname == 'GeometryNodeGroup' and node.node_tree is not None:
                trees.append(node.node_tree)


def attribute_only(modifier) -> bool:
    """Whether ``modifier`` is a Geometry Nodes modifier whose node group (and the groups in it)
    has only :data:`ATTRIBUTE_NODES` (and no group node without a group)."""
    if modifier.type != 'NODES' or modifier.node_group is None:
        return False
    return all(node.bl_idname in ATTRIBUTE_NODES
               and not (node.bl_idname == 'GeometryNodeGroup' and node.node_tree is None)
               for node in group_nodes(modifier.node_group))


def dynamic_paint_start(modifier) -> int | None:
    """The first frame of the active surfaces of the Dynamic Paint canvas ``modifier``, None for a
    brush or a canvas without one: Blender computes a surface that is not baked one step per frame
    shown, from the state it last computed, and resets it at its start frame, so a frame is the
    surface's only when every frame from that start was shown in order."""
    if modifier.type != 'DYNAMIC_PAINT' or modifier.canvas_settings is None:
        return None
    return min((surface.frame_start for surface in modifier.canvas_settings.canvas_surfaces if surface.is_active),
               default=None)


def simulation_zone_start(scene, modifier) -> int | None:
    """The first frame of the simulation zones of the Geometry Nodes ``modifier`` (its node group and
    the groups in it), None where it has none: a zone simulates from the scene's start, or from the
    start of its own range where its bake settings give one (Simulation Bake › Custom Range). Blender
    steps a zone that is not baked once per frame shown, from the state it last computed, so a frame
    is the zone's only when every frame from that start was shown in order."""
    if modifier.type != 'NODES' or modifier.node_group is None or not any(
            node.bl_idname == 'GeometryNodeSimulationOutput' for node in group_nodes(modifier.node_group)):
        return None
    starts = [bake.frame_start if getattr(bake, "use_custom_simulation_frame_range", False) else scene.frame_start
              for bake in zone_bakes(modifier)]
    return min(starts, default=scene.frame_start)


def zone_bakes(modifier) -> list:
    """The bake settings of the simulation zones of the Geometry Nodes ``modifier`` (those of Bake
    nodes left out where a setting names its node)."""
    return [bake for bake in getattr(modifier, "bakes", ())
            if getattr(bake, "node", None) is None or bake.node.bl_idname == 'GeometryNodeSimulationOutput']


def bake_folder(obj, modifier, bake) -> str | None:
    """The folder holding the disk bake of ``bake`` (a bake setting of the Geometry Nodes
    ``modifier`` of ``obj``), as Blender looks for it: the bake's Custom Path where it has one, else
    the modifier's Bake Path and the bake's id in it (relative paths beside the file ``obj`` comes
    from); None where the bake is not kept on disk (Packed, its own or the modifier's Bake Target)
    or no path is set (Blender has nowhere to look: the zone was never baked to disk)."""
    # Blender before 4.3 keeps every bake on disk and has no Bake Target
    target = getattr(bake, "bake_target", 'INHERIT')
    if target == 'INHERIT':
        target = getattr(modifier, "bake_target", 'DISK')
    if target != 'DISK':
        return None
    path = bake.directory if bake.use_custom_path else modifier.bake_directory
    if not path:
        return None
    folder = bpy.path.abspath(path, library=obj.library)
    return folder if bake.use_custom_path else os.path.join(folder, str(bake.bake_id))


def _holds_bake(folder: str) -> bool:
    """Whether ``folder`` holds a Geometry Nodes bake: a frame's description in its ``meta`` folder
    (Blender writes one ``.json`` per frame baked, beside the data in ``blobs``)."""
    try:
        return any(name.endswith(".json") for name in os.listdir(os.path.join(folder, "meta")))
    except OSError:
        return False


def zones_not_known_baked(scene, obj) -> list[str]:
    """The enabled Geometry Nodes modifiers of ``obj`` with a simulation zone (:func:`simulation_zone_start`)
    not known to be baked, named "'Simulation' of 'Sheet'": each one whose zones are not all baked to disk
    with their files there (:func:`bake_folder`). The Python API does not tell whether a zone is baked
    otherwise: a packed bake (Blender's default Bake Target) looks as a zone never baked."""
    names = []
    for modifier in obj.modifiers:
        if not modifier.show_viewport or simulation_zone_start(scene, modifier) is None:
            continue
        folders = [bake_folder(obj, modifier, bake) for bake in zone_bakes(modifier)]
        if not folders or not all(folder is not None and _holds_bake(folder) for folder in folders):
            names.append(f"'{modifier.name}' of '{obj.name}'")
    return names


def zone_frames_dropped(scene, obj, what: str, alternative: str = "") -> str | None:
    """A warning where changing the mesh of ``obj`` (``what``: "shape keys added to", "distortion maps
    written to") may have dropped the frames a Geometry Nodes simulation zone holds in memory, its own or
    that of an object sharing its mesh (:func:`zones_not_known_baked`): Blender simulates a zone that is
    not baked again from its start once its mesh changed, and drops the states it had simulated when the
    scene shows that start frame (as the run's return to a scene at its start does). None otherwise.
    ``alternative``: another way to the result, offered last. Warned, not refused as an unbaked cloth is
    (:func:`refuse_emptying_caches`): a baked zone cannot be told from one that is not."""
    zones = [name for user in [obj] + sharing_mesh(obj) for name in zones_not_known_baked(scene, user)]
    if not zones:
        return None
    one = len(zones) == 1
    return (f"{what[0].upper() + what[1:]} '{obj.name}' changed the mesh that the simulation zone"
            f"{'' if one else 's'} of {', '.join(zones)} simulate{'s' if one else ''}: unless "
            f"{'it is' if one else 'they are'} baked (Blender does not tell scripts whether a zone is), Blender drops "
            "the frames simulated in memory and simulates them again from the zone's start as the scene plays from "
            f"there. Bake {'it' if one else 'them'} first (Physics › Simulation Nodes › Bake) to keep those frames"
            + (f", or {alternative}" if alternative else ""))


def missing_zone_bake(obj, movers: list) -> str | None:
    """The error when a Geometry Nodes simulation zone of one of ``movers`` (``obj`` and the objects
    whose motion reaches its mesh, :func:`objects_moving`) is set to bake to disk and Blender finds
    none of its files where it looks (:func:`bake_folder`; the .blend moved, or sent to a farm,
    without its bake folder); None otherwise. Blender then simulates the zone again while the
    frames are read, from the node tree as it is now: other frames than the bake's wherever an
    input changed after baking (a bake keeps playing as baked), and a farm task simulating what the
    bake was made to spare. The Python API does not tell whether a zone is baked, so a path set
    with nothing there is read as a bake gone: Delete Bake leaves the path set, and a modifier
    where another zone's files are there is taken as one whose other zones were never baked."""
    for mover in movers:
        for modifier in mover.modifiers:
            if modifier.type != 'NODES' or not modifier.show_viewport:
                continue
            folders = [(bake, bake_folder(mover, modifier, bake)) for bake in zone_bakes(modifier)]
            folders = [(bake, folder) for bake, folder in folders if folder is not None]
            if not folders or any(_holds_bake(folder) for _, folder in folders):
                continue
            bake, folder = folders[0]
            zone = (f"the simulation zone '{bake.node.name}'" if getattr(bake, "node", None) is not None
                    else "a simulation zone in a node group inside")
            owner = f"'{mover.name}'" + (f", which moves '{obj.name}'," if mover != obj else "")
            where = ("clear the zone's Custom Path (its Simulation Bake settings)" if bake.use_custom_path else
                     "clear the modifier's Bake Path (Manage › Bake)")
            return (f"The Geometry Nodes modifier '{modifier.name}' of {owner} bakes {zone} to disk in '{folder}', "
                    "which holds none of the bake's files (the folder moved, or not copied with the .blend?): "
                    "Blender would simulate the zone again while the frames are read, from the nodes as they are "
                    "now, which gives other frames than the bake's wherever an input changed after baking. Copy "
                    f"the bake folder with the .blend (or bake again) and run again; if the bake was deleted on "
                    f"purpose, {where} to read the zone as simulated now")
    return None


def _still(modifier) -> bool:
    return modifier.type in STILL_MODIFIERS or attribute_only(modifier)


def moves_vertices(modifier) -> bool:
    """Whether ``modifier`` may move the mesh's vertices without adding or removing any (a cloth,
    an armature, a deform, a smooth): not a generator, a collider or a modifier that moves nothing."""
    return (modifier.type not in PASSIVE_MODIFIERS and modifier.type not in modifier_kinds.GENERATE_MODIFIERS
            and not _still(modifier))


def unfit_mesh_cache(obj, movers: list) -> str | None:
    """Why Blender cannot play the file of an enabled Mesh Cache modifier of one of ``movers``
    (``obj`` and the meshes whose motion reaches it, :func:`objects_moving`) on that mesh, in the
    user's words, or None: the file is not a PC2 / MDD of the modifier's Format or is cut short
    (Blender shows the rest mesh at every frame, or from where the samples stop), or it holds
    another number of points than the mesh has vertices (a cache of another mesh: Blender leaves
    that mesh at rest at every frame, 'Vertex count mismatch' on the modifier). A file that is not there is left to
    ``bridge.cache_files.missing_cache_file``; a modifier after one that adds or removes vertices (a generator, Geometry
    Nodes) is not checked against the mesh's count."""
    from ..core.errors import MeshError
    from ..core.point_cache import has_pc2_signature

    for mover in movers:
        if mover.type != 'MESH':
            continue
        owner = f"'{mover.name}'" + (f", which moves '{obj.name}'," if mover != obj else "")
        changed = False  # whether a modifier above changes the vertex count the next one gets
        for modifier in mover.modifiers:
            if not modifier.show_viewport:
                continue
            if modifier.type == 'MESH_CACHE' and os.path.isfile(cache_files.mesh_cache_file(modifier)):
                path = cache_files.mesh_cache_file(modifier)
                if modifier.cache_format == 'MDD' and has_pc2_signature(path):  # Blender's default Format is MDD
                    return (f"The Mesh Cache '{modifier.name}' of {owner} reads '{path}' as MDD (its Format), but it "
                            "is a PC2 file: Blender cannot read it so and shows the mesh at rest at every frame. Set "
                            "the modifier's Format to PC2")
                try:
                    _samples, points, _times = cache_files.mesh_cache_header(modifier)
                except MeshError as error:
                    return (f"The Mesh Cache '{modifier.name}' of {owner} cannot play its file as "
                            f"{modifier.cache_format} (its Format): {error} Blender shows the mesh at rest wherever "
                            "it cannot read a sample: check the modifier's Format (PC2 or MDD)")
                if points != len(mover.data.vertices) and not changed:
                    return (f"The Mesh Cache '{modifier.name}' of {owner} plays '{path}', "
                            f"which holds {points} points for the mesh's {len(mover.data.vertices)} vertices: Blender "
                            "leaves the mesh at rest at every frame ('Vertex count mismatch' on the modifier). Export "
                            "the cache from this mesh (its vertices, in the same order), or point the modifier to "
                            "the cache made for it")
            changed = changed or modifier.type in modifier_kinds.GENERATE_MODIFIERS or (
                modifier.type == 'NODES' and not attribute_only(modifier))
    return None


def _shown_in_one_only(obj, movers: list, viewport: bool) -> list[str]:
    """The modifiers that move vertices of ``movers`` (``obj`` and the objects that move it,
    :func:`objects_moving`) and are on in the viewport only (``viewport``) or for renders only,
    named with their object; those at the end of ``obj``'s stack that go with the new object
    (:func:`trailing_generators`, copied with their settings) are not counted."""
    copied = set(modifier.name for modifier in trailing_generators(obj))
    return [f"'{m.name}' of '{mover.name}'" for mover in movers for m in mover.modifiers
            if (m.show_viewport, m.show_render) == (viewport, not viewport) and moves_vertices(m)
            and not (mover == obj and m.name in copied)]


def render_only_motion(obj, movers: list) -> str | None:
    """A warning when modifiers that move the vertices of ``obj`` — those of ``movers``, itself and
    the objects that move it (:func:`objects_moving`: a cloth proxy through a Surface Deform) — are on for
    renders and off in the viewport (a heavy cloth kept off while animating): frames are read as
    the viewport evaluates them, so the poses lack their motion, which renders show; None otherwise."""
    names = _shown_in_one_only(obj, movers, viewport=False)
    if not names:
        return None
    return (f"{', '.join(names)} {'is' if len(names) == 1 else 'are'} on for renders only (off in "
            "the viewport), and frames are read as the viewport shows them: the poses read lack "
            f"{'its' if len(names) == 1 else 'their'} motion. Turn {'it' if len(names) == 1 else 'them'} on in the "
            "viewport (the monitor icon in the modifier's header) and run again")


def viewport_only_motion(obj, movers: list) -> str | None:
    """A warning when modifiers that move the vertices of ``obj`` (of ``movers``, as in
    :func:`render_only_motion`) are on in the viewport and off for renders (a preview deform):
    frames are read as the viewport evaluates them, so the poses carry their deformation, which a
    new object playing them renders and ``obj``'s renders lack; None otherwise."""
    names = _shown_in_one_only(obj, movers, viewport=True)
    if not names:
        return None
    one = len(names) == 1
    return (f"{', '.join(names)} {'is' if one else 'are'} on in the viewport only (off for renders), and "
            "frames are read as the viewport shows them: the poses read carry "
            f"{'its' if one else 'their'} deformation, which renders of '{obj.name}' lack. Turn "
            f"{'it' if one else 'them'} on for renders (the camera icon in the modifier's header) or off in the "
            "viewport and run again")


def trailing_generators(obj) -> list:
    """The enabled modifiers at the end of ``obj``'s stack from its first generator on, when only
    generators and touch-ups follow it: what turns the moving mesh (after the cloth, armature,
    Mesh Cache) into the displayed one, such as a Subdivision Surface after the cloth and
    *Smooth by Angle* after it. Without a generator there, the modifiers at the end that never
    move a vertex (normals, UVs, *Smooth by Angle*). Enabled in the viewport or for rendering: a
    Subdivision on for rendering only goes with the new object too, so that it renders alike."""
    enabled = [modifier for modifier in obj.modifiers if modifier.show_viewport or modifier.show_render]
    run = len(enabled)  # the last modifiers: generators and touch-ups only
    while run > 0 and (enabled[run - 1].type in modifier_kinds.GENERATE_MODIFIERS | MOVING_TOUCH_UP_MODIFIERS
                       or _still(enabled[run - 1])):
        run -= 1
    generators = [index for index in range(run, len(enabled))
                  if enabled[index].type in modifier_kinds.GENERATE_MODIFIERS]
    start = generators[0] if generators else len(enabled)
    while start > run and _still(enabled[start - 1]):  # also those that never move a vertex before it
        start -= 1
    # a Collision modifier makes the object a collider and cannot be copied (Blender refuses)
    return [modifier for modifier in enabled[start:] if modifier.type not in PASSIVE_MODIFIERS]


#: Modifiers a cache object of shape-key poses does not take over: simulations (a copy would
#: simulate again from its own start) and what reads a cache (it would replace the poses).
NOT_COPIED_UNDER_KEYS = modifier_kinds.POSE_REPLACING_MODIFIERS | {'PARTICLE_SYSTEM', 'DYNAMIC_PAINT', 'FLUID',
                                                                   'COLLISION'}


def modifiers_under_keys(obj) -> tuple[list, list]:
    """(modifiers to copy, modifiers left out) for a new object playing poses of ``obj``'s shape
    keys: Blender deforms shape keys by the whole modifier stack (an Armature, a Lattice, a
    Subdivision), so the new object takes over every enabled one but
    :data:`NOT_COPIED_UNDER_KEYS` (enabled in the viewport or for rendering)."""
    enabled = [modifier for modifier in obj.modifiers if modifier.show_viewport or modifier.show_render]
    return ([modifier for modifier in enabled if modifier.type not in NOT_COPIED_UNDER_KEYS],
            [modifier for modifier in enabled if modifier.type in NOT_COPIED_UNDER_KEYS - PASSIVE_MODIFIERS])


#: Modifiers that add what renders beside the mesh (hair, emitted particles): the poses read from
#: the evaluated mesh do not hold it, and a new object playing them does not get it.
ADDING_MODIFIERS = {'PARTICLE_SYSTEM'}


def modifiers_under_frames(obj) -> tuple[list, list]:
    """(modifiers to copy, modifiers left out) for a new object playing poses read from ``obj``'s
    evaluated mesh: its generators after the motion (:func:`trailing_generators`); left out, what
    renders beside the mesh (:data:`ADDING_MODIFIERS`, enabled in the viewport or for rendering)."""
    return trailing_generators(obj), [modifier for modifier in obj.modifiers if modifier.type in ADDING_MODIFIERS
                                      and (modifier.show_viewport or modifier.show_render)]


def acts_on_simulations(obj) -> bool:
    """Whether ``obj`` is a collider (an enabled Collision modifier) or a force field: the cloths
    and soft bodies of other objects react to it, and Blender empties their unbaked caches when it
    changes."""
    field = getattr(obj, "field", None)
    return field is not None and field.type != 'NONE' or any(
        modifier.type == 'COLLISION' and modifier.show_viewport for modifier in obj.modifiers)


def reacting_simulations(scene, objects) -> list[tuple]:
    """``(object, unbaked simulation names)`` for each other object of ``scene`` with unbaked
    simulations, where one of ``objects`` is a collider or force field they may react to
    (:func:`acts_on_simulations`); empty otherwise."""
    if not any(acts_on_simulations(obj) for obj in objects):
        return []
    return [(other, unbaked_simulations(other)) for other in scene.objects
            if other not in objects and unbaked_simulations(other)]


def _simulations_named(simulations) -> str:
    """"'Cape' ('Cloth'), …" for ``(object, simulation names)`` pairs."""
    return ", ".join(f"'{obj.name}' ({', '.join(repr(name) for name in names)})" for obj, names in simulations)


def sharing_mesh(obj) -> list:
    """The other objects whose data is the mesh of ``obj`` (linked duplicates): they show its shape
    keys and attributes too."""
    return [other for other in bpy.data.objects if other.data == obj.data and other != obj]


def simulations_emptied_by(scene, obj) -> tuple[list, list]:
    """The unbaked simulations whose caches Blender empties when the mesh of ``obj`` changes (shape
    keys or attributes added; it computes them again from their start): ``(object, simulation
    names)`` pairs of ``obj`` and the objects sharing its mesh (linked duplicates), and of the other
    objects of ``scene`` where one of those is a collider or force field (:func:`reacting_simulations`)."""
    users = [obj] + sharing_mesh(obj)
    sharing = [(user, unbaked_simulations(user)) for user in users if unbaked_simulations(user)]
    return sharing, reacting_simulations(scene, users)


def refuse_emptying_caches(scene, obj, what: str, alternative: str = "", shapes: bool = False) -> None:
    """Raise :class:`InputError` where changing the mesh of ``obj`` (``what``: "shape keys added
    to", "distortion maps written to") would empty an unbaked simulation's cache
    (:func:`simulations_emptied_by`), or, where it changes the mesh's shape (``shapes``: shape keys),
    an unbaked rigid body simulation colliding that shape (:func:`bridge.rigid_bodies.unbaked_rigid_body_shape`),
    before any work. ``alternative``: another way to the result,
    offered first."""
    def either(*advice):
        options = ([alternative] if alternative else []) + list(advice)
        return options[0] if len(options) == 1 else ", ".join(options[:-1]) + ", or " + options[-1]

    change = what[0].upper() + what[1:]
    sharing, others = simulations_emptied_by(scene, obj)
    for user, names in sharing:
        unbaked = ", ".join(repr(name) for name in names)
        if user == obj:
            raise InputError(f"{change} '{obj.name}' would empty the unbaked cache of its {unbaked} simulation: "
                             + either("bake the simulation first (Physics › Cache › Bake)"))
        raise InputError(
            f"'{obj.name}' shares its mesh with '{user.name}', and {what} that mesh would empty the unbaked "
            f"cache of the {unbaked} simulation of '{user.name}': "
            + either("bake that simulation first (Physics › Cache › Bake)", "give this object its own mesh "
                     "(Object › Relations › Make Single User › Object & Data)"))
    if others:
        raise InputError(
            f"{change} '{obj.name}' would empty the unbaked cache of {_simulations_named(others)}, which may "
            f"react to '{obj.name}' as a collider or force field (Blender simulates them again when it changes): "
            + either("bake those first (Physics › Cache › Bake)"))
    for user in ([obj] + sharing_mesh(obj)) if shapes else ():
        if rigid_bodies.unbaked_rigid_body_shape(user):
            raise InputError(
                f"{change} '{user.name}' would change its rigid body simulation, which is not baked: its collision "
                f"shape ({user.rigid_body.collision_shape.replace('_', ' ').title()}) is read from its deformed "
                "mesh, and Blender simulates the world again from the shapes the mesh shows then: "
                + either("bake the simulation first (Scene › Rigid Body World › Cache › Bake)",
                         "read the shape from the mesh's Base (Physics › Rigid Body › Collisions › Source)"))


def modifiers_set_aside(context, obj) -> list:
    """The modifiers to switch off while the frames of ``obj`` are read: its trailing generators
    (:func:`trailing_generators`) when its evaluated mesh has other vertices than its mesh (the
    poses are of the mesh's own vertices), or when a generator is among them and switching them
    costs no cache: one that keeps the vertex count at the current frame may change it at another
    (an Edge Split by angle, a Weld by distance, a Build), and a new object gets copies of them
    (:func:`modifiers_under_frames`), which would add what they do to the poses a second time (a
    Displace after a Triangulate). None otherwise. Raises :class:`InputError`, where the evaluated
    mesh has other vertices, when one of its simulations is not baked: switching a modifier of the
    object off and on again marks that cache outdated, and Blender then drops its frames."""
    aside = trailing_generators(obj)
    if mesh_data.evaluated_vertex_count(obj, context.evaluated_depsgraph_get()) == len(obj.data.vertices):
        if not any(modifier.type in modifier_kinds.GENERATE_MODIFIERS for modifier in aside) \
                or unbaked_simulations(obj):
            return []
        return [] if reacting_simulations(context.scene, [obj]) else aside
    unbaked = unbaked_simulations(obj)
    if aside and not unbaked:
        # switching a modifier of a collider or force field off and on empties the caches of
        # the unbaked simulations it acts on
        others = reacting_simulations(context.scene, [obj])
        if others:
            names = ", ".join(repr(modifier.name) for modifier in aside)
            simulations = _simulations_named(others)
            raise InputError(
                f"{names} after the motion changes the vertex count of '{obj.name}' and is set aside while "
                f"the frames are read, which would empty the unbaked cache of {simulations}: '{obj.name}' "
                f"is a collider or force field they may react to. Bake those first (Physics › Cache › "
                f"Bake), or disable {names}")
    if aside and unbaked:
        names = ", ".join(repr(modifier.name) for modifier in aside)
        raise InputError(
            f"{names} after the simulation changes the vertex count of '{obj.name}', and its "
            f"{', '.join(repr(name) for name in unbaked)} cache is not baked: bake it (Physics › "
            f"Cache › Bake) so that {names} can be set aside while the frames are read, or "
            "disable it")
    return aside


def motion_set_aside(context, obj, frames: list[int], aside: list) -> str | None:
    """A warning when the modifiers ``aside`` — set aside while ``obj``'s frames were read
    (:func:`modifiers_set_aside`) — carry its motion: its evaluated mesh, with them, differs
    between the first and last of ``frames`` (a Displace following a moving empty, or with its
    strength keyframed, after a Subdivision). Call it where every pose read is the same: nothing
    of that motion was read or in-betweened, and a new object plays it again only through its
    copies of those modifiers. None otherwise. The scene's current frame is restored."""
    if not aside or len(frames) < 2:
        return None
    shown = [mesh_data.evaluated_positions(obj, context.evaluated_depsgraph_get())
             for _ in scene_timing.at_times(context.scene, (frames[0], frames[-1]))]
    if shown[0].shape == shown[1].shape and np.array_equal(shown[0], shown[1]):
        return None
    generators = [modifier for modifier in aside if modifier.type in modifier_kinds.GENERATE_MODIFIERS]
    moving = [modifier for modifier in aside if modifier not in generators] or aside
    names = ", ".join(repr(modifier.name) for modifier in moving)
    before = ", ".join(repr(modifier.name) for modifier in generators) or "the generator before it"
    return (f"The {len(frames)} frames read from '{obj.name}' ({frames[0]}–{frames[-1]}) are all the same pose: "
            f"its motion comes from {names}, set aside with {before} while the frames are read ({before} "
            "changing the vertex count, and the poses being of the mesh's own vertices). Nothing of that motion "
            "is read or in-betweened: a new object only plays it again through its copies of them. Apply "
            f"{before} first, so that {names} moves the mesh's own vertices, and run again")


#: Modifiers whose result at a frame may depend on the frames before it and whose bakes are not
#: checked here: particles, dynamic paint, fluids, and geometry nodes (a simulation zone).
SEQUENTIAL_MODIFIERS = {'PARTICLE_SYSTEM', 'DYNAMIC_PAINT', 'FLUID', 'NODES'}


def frames_depend_on_earlier(scene) -> bool:
    """Whether evaluating a frame of ``scene`` may need the frames before it: an unbaked rigid
    body world, or on any object an unbaked cloth or soft body (:func:`unbaked_simulations`) or
    an enabled modifier of :data:`SEQUENTIAL_MODIFIERS`. Reading frames then visits every frame
    in order."""
    world = scene.rigidbody_world
    if world is not None and world.enabled and not world.point_cache.is_baked:
        return True
    return any(unbaked_simulations(obj) or any(m.type in SEQUENTIAL_MODIFIERS and m.show_viewport
                                               and not attribute_only(m) for m in obj.modifiers)
               for obj in scene.objects)


def _plays_nla(animation) -> bool:
    """Whether ``animation`` (an ID's animation data) plays NLA strips: a track that is not muted."""
    return any(not track.mute for track in animation.nla_tracks)


def _transform_drivers(animation) -> bool:
    """Whether ``animation`` (an object's animation data) drives its transform."""
    return any(driver.data_path in copied_motion.TRANSFORM_CHANNELS for driver in animation.drivers)


def _own_motion(obj) -> dict[str, str]:
    """What of ``obj``'s own moves it as a whole: {kind: the user's words} ("rigid_body",
    "keyframed", "nla", "drivers", "constraints")."""
    animation = obj.animation_data
    out = {}
    if rigid_bodies.simulated_rigid_body(obj):
        out["rigid_body"] = "its rigid body simulation"
    if animation is not None:
        if animation.action is not None:
            out["keyframed"] = "its keyframed transform"
        if _plays_nla(animation):
            out["nla"] = "its NLA tracks"
        if _transform_drivers(animation):
            out["drivers"] = "drivers"
    if obj.constraints:
        out["constraints"] = "its constraints"
    return out


def object_motion(obj) -> dict[str, str]:
    """What moves ``obj`` as a whole, {kind: the user's words} (empty: nothing): its own
    (:func:`_own_motion`) and, as "parent", a parent that moves (itself or one of its parents)."""
    out = _own_motion(obj)
    parent = obj.parent
    while parent is not None and not _own_motion(parent):
        parent = parent.parent
    if parent is not None:
        out["parent"] = f"its parent '{obj.parent.name}'"
    return out
