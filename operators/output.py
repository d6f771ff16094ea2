"""Where an operator's poses go: shape keys on the active object, or a PC2 point cache played by
a Mesh Cache modifier on a new object. Any operator that writes poses uses this mixin:

    class MY_OT_thing(PoseOutput, PoseWriter, GeneratorOperator, bpy.types.Operator):
        def run(self, context):
            source = context.active_object
            self.check_output(source)              # validation step: refuses what would harm
            ...                                    # compute poses, yielding progress
            self.summary = self.write_poses(context, source, poses, names=names,
                                            frames=frames, label="Thing 1.50")

``PoseOutput`` / ``AnimationOutput`` (in :mod:`..properties`) declare the ``output`` and
``filepath`` properties; ``PoseWriter`` writes. Cache output never modifies the source object.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import bpy
import numpy as np

from .. import bridge
from .base import InputError, report

# Modifiers whose unbaked point cache Blender empties when the object's mesh data changes.
SIMULATION_MODIFIERS = bridge.SIMULATION_MODIFIERS
CACHE_FOLDER = "caches"
# Modifiers that do not move the mesh they are on.
PASSIVE_MODIFIERS = {'COLLISION'}


def unbaked_simulations(obj) -> list[str]:
    """Names of ``obj``'s enabled cloth / soft body modifiers whose cache is not baked."""
    return [modifier.name for _, modifier in bridge.simulations([obj]) if not modifier.point_cache.is_baked]


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


#: Modifiers that add or remove vertices (Blender's Generate category; Geometry Nodes apart, which
#: may carry the motion itself).
GENERATE_MODIFIERS = {'ARRAY', 'BEVEL', 'BOOLEAN', 'BUILD', 'DECIMATE', 'EDGE_SPLIT', 'MASK', 'MIRROR',
                      'MULTIRES', 'REMESH', 'SCREW', 'SKIN', 'SOLIDIFY', 'SUBSURF', 'TRIANGULATE', 'WELD',
                      'WIREFRAME'}
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
    return modifier.type not in PASSIVE_MODIFIERS and modifier.type not in GENERATE_MODIFIERS and not _still(modifier)


def unfit_mesh_cache(obj, movers: list) -> str | None:
    """Why Blender cannot play the file of an enabled Mesh Cache modifier of one of ``movers``
    (``obj`` and the meshes whose motion reaches it, :func:`objects_moving`) on that mesh, in the
    user's words, or None: the file is not a PC2 / MDD of the modifier's Format or is cut short
    (Blender shows the rest mesh at every frame, or from where the samples stop), or it holds
    another number of points than the mesh has vertices (a cache of another mesh: Blender leaves
    that mesh at rest at every frame, 'Vertex count mismatch' on the modifier). A file that is not there is left to ``bridge.missing_cache_file``;
    a modifier after one that adds or removes vertices (a generator, Geometry Nodes) is not checked
    against the mesh's count."""
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
            if modifier.type == 'MESH_CACHE' and os.path.isfile(bridge.mesh_cache_file(modifier)):
                path = bridge.mesh_cache_file(modifier)
                if modifier.cache_format == 'MDD' and has_pc2_signature(path):  # Blender's default Format is MDD
                    return (f"The Mesh Cache '{modifier.name}' of {owner} reads '{path}' as MDD (its Format), but it "
                            "is a PC2 file: Blender cannot read it so and shows the mesh at rest at every frame. Set "
                            "the modifier's Format to PC2")
                try:
                    _samples, points, _times = bridge.mesh_cache_header(modifier)
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
            changed = changed or modifier.type in GENERATE_MODIFIERS or (
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
    while run > 0 and (enabled[run - 1].type in GENERATE_MODIFIERS | MOVING_TOUCH_UP_MODIFIERS
                       or _still(enabled[run - 1])):
        run -= 1
    generators = [index for index in range(run, len(enabled)) if enabled[index].type in GENERATE_MODIFIERS]
    start = generators[0] if generators else len(enabled)
    while start > run and _still(enabled[start - 1]):  # also those that never move a vertex before it
        start -= 1
    # a Collision modifier makes the object a collider and cannot be copied (Blender refuses)
    return [modifier for modifier in enabled[start:] if modifier.type not in PASSIVE_MODIFIERS]


#: Modifiers that replace the positions of their mesh with poses of their own (a simulation's frames,
#: a cache's samples): the mesh's shape keys do not show under them.
POSE_REPLACING_MODIFIERS = SIMULATION_MODIFIERS | {'MESH_CACHE', 'MESH_SEQUENCE_CACHE'}
#: Modifiers a cache object of shape-key poses does not take over: simulations (a copy would
#: simulate again from its own start) and what reads a cache (it would replace the poses).
NOT_COPIED_UNDER_KEYS = POSE_REPLACING_MODIFIERS | {'PARTICLE_SYSTEM', 'DYNAMIC_PAINT', 'FLUID', 'COLLISION'}


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
    an unbaked rigid body simulation colliding that shape (:func:`bridge.unbaked_rigid_body_shape`),
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
        if bridge.unbaked_rigid_body_shape(user):
            raise InputError(
                f"{change} '{user.name}' would change its rigid body simulation, which is not baked: its collision "
                f"shape ({user.rigid_body.collision_shape.replace('_', ' ').title()}) is read from its deformed "
                "mesh, and Blender simulates the world again from the shapes the mesh shows then: "
                + either("bake the simulation first (Scene › Rigid Body World › Cache › Bake)",
                         "read the shape from the mesh's Base (Physics › Rigid Body › Collisions › Source)"))


def modifiers_set_aside(context, obj) -> list:
    """The modifiers to switch off while the frames of ``obj`` are read: its trailing generators
    (:func:`trailing_generators`) when its evaluated mesh has other vertices than its mesh (the
    poses are of the mesh's own vertices), none otherwise. Raises :class:`InputError` when one of
    its simulations is not baked: switching a modifier of the object off and on again marks that
    cache outdated, and Blender then drops its frames."""
    if bridge.evaluated_vertex_count(obj, context.evaluated_depsgraph_get()) == len(obj.data.vertices):
        return []
    aside = trailing_generators(obj)
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
    shown = [bridge.evaluated_positions(obj, context.evaluated_depsgraph_get())
             for _ in bridge.at_times(context.scene, (frames[0], frames[-1]))]
    if shown[0].shape == shown[1].shape and np.array_equal(shown[0], shown[1]):
        return None
    generators = [modifier for modifier in aside if modifier.type in GENERATE_MODIFIERS]
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


def require_local(obj, data, what: str, advice: str = "Make") -> None:
    """Raise :class:`InputError` if ``data`` (``obj`` itself or its mesh) is linked from a library
    or a library override (its shape keys too, for a mesh): ``what`` (e.g. "shape keys added to it
    are") would not be saved with the file — gone when it is opened again, with no warning."""
    owned = [data] + ([data.shape_keys] if getattr(data, "shape_keys", None) is not None else [])
    linked = next((item for item in owned if item.library is not None or item.override_library is not None), None)
    if linked is None:
        return
    library = linked.library or linked.override_library.reference.library
    origin = f"linked from '{library.filepath}'" if library is not None else "a library override"
    subject = f"'{obj.name}'" if data == obj else f"The mesh of '{obj.name}'"
    raise InputError(
        f"{subject} is {origin}: {what} not saved with this file (gone when it is opened again). "
        f"{advice} it local first (Object › Relations › Make Local › Selected Objects and Data)")


def cache_files_in_use() -> set[str]:
    """The files (real paths) the Mesh Cache modifiers of every object in the file play, linked
    objects' resolved against their library."""
    used = set()
    for obj in bpy.data.objects:
        for modifier in obj.modifiers:
            if modifier.type == 'MESH_CACHE' and modifier.filepath:
                used.add(os.path.realpath(bpy.path.abspath(modifier.filepath, library=obj.library)))
    return used


def numbered_files(path: Path):
    """``path``, then ``name.001.pc2``, ``name.002.pc2``, …, leaving out those a Mesh Cache modifier
    in the file plays (a .blend copied without its caches: the old object's path, empty on disk,
    would otherwise be taken and the old object play the new poses)."""
    used = cache_files_in_use()
    candidate, number = path, 0
    while True:
        if os.path.realpath(candidate) not in used:
            yield candidate
        number += 1
        candidate = path.with_name(f"{path.stem}.{number:03d}{path.suffix}")


def unique_file(path: Path) -> Path:
    """The first of :func:`numbered_files` that no file has."""
    return next(candidate for candidate in numbered_files(path) if not candidate.exists())


def holds_poses(path: Path, poses, start: float, sampling: float) -> bool:
    """Whether the file ``path`` is a PC2 of ``poses`` at ``start`` / ``sampling``: the same run
    made again (a farm task retried, a batch run twice on the saved shot), whose file no object of
    this .blend plays. Coordinates agree to 1e-6 of the poses' size: the same computation on
    another machine may round the last bit of a float32 otherwise (NumPy and OpenBLAS pick their
    kernels by memory alignment)."""
    from ..core.errors import MeshError
    from ..core.point_cache import read_pc2

    try:
        cache = read_pc2(path)
    except (MeshError, OSError):  # not a point cache (or unreadable): another file
        return False
    # compared pose by pose, as float32 (what the file holds), without a copy of them all
    shape = (len(poses), *np.shape(poses[0])) if len(poses) else (0,)
    if cache.positions.shape != shape or cache.start != np.float32(start) or cache.sampling != np.float32(sampling):
        return False
    size = max((float(np.abs(np.asarray(pose, dtype=np.float32)).max()) for pose in poses), default=0.0)
    return all(np.abs(cache.positions[i] - np.asarray(pose, dtype=np.float32)).max() <= 1e-6 * size
               for i, pose in enumerate(poses))


def write_new_cache(path: Path, poses, start: float, sampling: float) -> tuple[Path, bool]:
    """Write the PC2 of ``poses`` to ``path``, or to the first free name of :func:`numbered_files`
    (an existing file is never overwritten), and return the file and whether this call wrote it.
    A file there that holds these poses already (:func:`holds_poses`) is the file, not written
    again: a retried farm task or a batch run again plays the first run's file instead of leaving
    it beside a copy. The name is taken only once the
    file is whole, and only if no file has it then (``exclusive``): two Blender processes writing
    one name at once (two shots in one folder with the same default cache name) keep a file each
    (before, the later replaced the earlier, and one shot played the other's cache)."""
    from ..core.point_cache import write_pc2

    for candidate in numbered_files(path):
        if candidate.exists():
            if holds_poses(candidate, poses, start, sampling):
                return candidate, False
            continue
        try:
            return write_pc2(candidate, poses, start=start, sampling=sampling, exclusive=True), True
        except FileExistsError:  # another process took the name meanwhile
            continue


def in_session_folder(path: str) -> bool:
    """Whether ``path`` lies in Blender's temporary folder of this session, which Blender deletes
    when it quits."""
    folder = bpy.app.tempdir
    return bool(folder) and os.path.realpath(path).startswith(os.path.realpath(folder).rstrip(os.sep) + os.sep)


#: The cache file the last run of each operator (by idname) wrote, None for shape keys: Python
#: state, which undo leaves as it is (:meth:`PoseWriter.drop_undone_cache`).
_LAST_CACHE: dict[str, str | None] = {}

#: Mesh Cache modifiers pointed at copies by :func:`keep_session_caches`: {(object, modifier):
#: their path before}, restored after a save that was a copy (:func:`restore_after_copy`).
_MOVED_FOR_SAVE: dict[tuple[str, str], str] = {}


@bpy.app.handlers.persistent
def keep_session_caches(filepath, *_):
    """Before a save to ``filepath``: a cache written while the .blend had never been saved went
    to Blender's temporary folder (:meth:`PoseWriter.cache_path`), which Blender deletes when it
    quits; it is copied into ``caches/`` beside the .blend being saved and its Mesh Cache modifier
    pointed there (relative), so the saved file keeps it."""
    _MOVED_FOR_SAVE.clear()
    if not filepath:
        return
    folder = Path(filepath).parent / CACHE_FOLDER
    for obj in bpy.data.objects:
        if obj.library is not None:
            continue
        for modifier in obj.modifiers:
            source = bpy.path.abspath(modifier.filepath) if modifier.type == 'MESH_CACHE' and modifier.filepath else ""
            if not source or not in_session_folder(source) or not os.path.isfile(source):
                continue
            try:
                folder.mkdir(parents=True, exist_ok=True)
                target = unique_file(folder / Path(source).name)
                shutil.copy2(source, target)
            except OSError as error:
                print(f"Shape Differences: could not copy the cache '{source}' beside '{filepath}': {error}")
                continue
            _MOVED_FOR_SAVE[(obj.name, modifier.name)] = modifier.filepath
            modifier.filepath = f"//{CACHE_FOLDER}/{target.name}"


@bpy.app.handlers.persistent
def restore_after_copy(filepath, *_):
    """After a save: where it was a copy (*Save Copy*: this session's .blend is another or none),
    the session's modifiers point back to the caches they played (the copy keeps its own)."""
    if os.path.realpath(bpy.data.filepath or "") != os.path.realpath(filepath or ""):
        for (name, modifier_name), path in _MOVED_FOR_SAVE.items():
            obj = bpy.data.objects.get(name)
            modifier = obj.modifiers.get(modifier_name) if obj is not None else None
            if modifier is not None:
                modifier.filepath = path
    _MOVED_FOR_SAVE.clear()


def register_handlers():
    for handlers, handler in ((bpy.app.handlers.save_pre, keep_session_caches),
                              (bpy.app.handlers.save_post, restore_after_copy)):
        if handler not in handlers:
            handlers.append(handler)


def unregister_handlers():
    for handlers, handler in ((bpy.app.handlers.save_pre, keep_session_caches),
                              (bpy.app.handlers.save_post, restore_after_copy)):
        if handler in handlers:
            handlers.remove(handler)


class PoseWriter:
    """Writes poses according to the operator's ``output`` and ``filepath`` properties."""

    def check_output(self, source, *, keyframed: bool = False) -> None:
        """Refuse what the writing step would fail on or harm (call it in the validation step,
        before any work): shape keys on a mesh linked from a library (or overridden: they would not
        be saved), or that would empty an unbaked simulation's cache (the object's, another's
        sharing its mesh, or one reacting to it as a collider or force field:
        :func:`refuse_emptying_caches`),
        keyframed shape keys on absolute ones (``keyframed``: Blender plays those by their
        Evaluation Time, never by the values keyed) or on keys whose NLA strip is being edited (tweak
        mode), a cache file relative to a .blend that was never saved."""
        if self.output != 'SHAPE_KEYS':
            if self.filepath.startswith("//") and not bpy.data.filepath:
                raise InputError(f"The Cache File '{self.filepath}' is relative to the .blend, "
                                 "which is not saved yet: save the .blend first, or give an "
                                 "absolute path")
            from ..core.point_cache import unwritable

            path, _ = self.cache_path(source.name, warn=False)  # a path the system refuses: before any work
            reason = unwritable(path)
            if reason:
                raise InputError(f"Cannot write the cache file '{path}': {reason}. Pick another Cache File")
            return
        require_local(source, source.data, "shape keys added to it are",
                      "Choose Output › Point Cache (a new object), or make")
        key = source.data.shape_keys
        if keyframed and key is not None and not key.use_relative:
            raise InputError(f"The shape keys of '{source.name}' are absolute (Shape Keys › Relative is "
                             "off): Blender plays them by Evaluation Time and ignores the key values this "
                             "would keyframe, so the new keys would never play. Choose Output › Point "
                             "Cache (a new object), or turn Relative on")
        if keyframed and key is not None and key.animation_data is not None and key.animation_data.use_tweak_mode:
            # Blender files keyframes inserted in tweak mode in the edited strip's action, at its own time
            raise InputError(f"An NLA strip of the shape keys of '{source.name}' is being edited (tweak mode): the "
                             "new keys' keyframes would go into that strip's action and play through its timing, "
                             "scale and repeats rather than at the frames written. Leave tweak mode (Tab in the NLA "
                             "editor) and run again, or choose Output › Point Cache (a new object)")
        refuse_emptying_caches(bpy.context.scene, source, "shape keys added to",
                               "choose Output › Point Cache (a new object; this one stays as it is)", shapes=True)

    def check_captured_output(self, source, *, keyframed: bool = False) -> None:
        """``check_output`` for poses captured from the evaluated mesh: shape keys added to
        ``source`` are deformed again by what moved it, so say so (the work still runs)."""
        self.check_output(source, keyframed=keyframed)
        if self.output != 'SHAPE_KEYS':
            return
        # generators are set aside while reading (or change no vertex): they do not add twice
        movers = [f"'{m.name}'" for m in source.modifiers if m.show_viewport and moves_vertices(m)]
        key = source.data.shape_keys
        # relative keys add to the new ones; absolute keys show one key (or two blended) at a time
        if key is not None and key.use_relative:
            animation = key.animation_data
            # an action, NLA strips (an action pushed down: no active one left) or drivers play the values
            if animation is not None and (animation.action is not None or _plays_nla(animation)
                                          or len(animation.drivers)):
                movers.append("its animated shape keys")
            else:  # a key left at a value is in every captured pose, and adds its change once more
                held = [f"'{kb.name}' at {kb.value:g}" for kb in key.key_blocks[1:] if kb.value and not kb.mute]
                if held:
                    movers.append(f"its shape key{'s' if len(held) > 1 else ''} {', '.join(held)}")
        if movers:
            report(self, {'WARNING'}, f"The new shape keys are deformed again by {', '.join(movers)} "
                                      f"of '{source.name}': disable those to play them as captured, "
                                      "or use Output › Point Cache (a new object)")

    def given_path(self) -> str:
        """The Cache File as given, a plain relative path (``caches/x.pc2``) taken relative to the
        saved .blend (``//caches/x.pc2``) rather than to the folder Blender was started from, which
        differs from run to run."""
        given = self.filepath
        if given and not given.startswith("//") and not os.path.isabs(given) and bpy.data.filepath:
            return "//" + given
        return given

    def cache_path(self, object_name: str, warn: bool = True, check_free: bool = True) -> tuple[Path, str]:
        """The PC2 file to write (never an existing one, nor one a Mesh Cache in the file plays;
        ``check_free=False``: the name asked for, before that check) and the path to store in the
        modifier (:meth:`stored_path`). Raises :class:`InputError` for a path the system cannot use
        (a name too long, a folder that cannot be read) and for a device or special file
        (``/dev/null``, a named pipe: neither a cache to write nor a name to add ``.pc2`` to)."""
        base_name = bpy.path.clean_name(object_name) + ".pc2"
        given = self.given_path()
        try:
            if given:
                path = Path(os.path.abspath(bpy.path.abspath(given)))
                if given.endswith(("/", "\\")) or path.is_dir():
                    path = path / base_name
                elif path.exists() and not path.is_file():  # a device (/dev/null), a named pipe, a socket
                    raise InputError(f"The Cache File '{self.filepath}' is a device or special file, not a "
                                     "file or folder: pick a .pc2 file or a folder to write the cache in")
                elif path.suffix.lower() != ".pc2":
                    path = path.with_name(path.name + ".pc2")
            elif bpy.data.filepath:
                path = Path(bpy.path.abspath(f"//{CACHE_FOLDER}")) / base_name
            else:
                path = Path(bpy.app.tempdir or os.path.realpath(".")) / base_name
                if warn:
                    report(self, {'WARNING'}, "The .blend is not saved, so the cache went to Blender's temporary "
                                              f"folder ({path.parent}), deleted when Blender quits: saving the .blend "
                                              f"copies it into {CACHE_FOLDER}/ beside it")
            if check_free:
                path = unique_file(path)
        except OSError as error:
            raise InputError(f"Cannot use the Cache File '{self.filepath or path}': {error.strerror or error}. "
                             "Pick another Cache File") from None
        return path, self.stored_path(path)

    def stored_path(self, path: Path) -> str:
        """The path of the cache file ``path`` for the Mesh Cache modifier: relative to the .blend
        when the user gave a relative Cache File or none."""
        given = self.given_path()
        relative = bpy.data.filepath and (not given or given.startswith("//"))
        return bpy.path.relpath(str(path)) if relative else str(path)

    def write_poses(self, context, source, poses, *, names: list[str], frames: list[float],
                    label: str, tails: list[str] | None = None, keyframe: bool = False,
                    speed: float = 1.0, keyed: bool = False) -> str:
        """Write ``poses`` (float ``(n, 3)`` each) and return the summary for the report.

        Shape keys: one key per pose named ``names[i] + tails[i]`` (the tail, e.g. a factor, is
        never cut), keyframed at ``frames`` if ``keyframe``. Point cache: a PC2 of the poses at
        ``frames`` (evenly spaced) on a new object called "<source> <label>", which moves as
        ``source`` does as a whole; ``speed``: the poses play ``source``'s time
        ``frames[0] + (frame − frames[0]) · speed`` (a retime), its keyframed transform too.
        ``keyed``: the poses are of ``source``'s shape keys (before its modifiers), and the new
        object is deformed by copies of ``source``'s modifiers as the keys are
        (:func:`modifiers_under_keys`); else they are what its modifiers made, and only the
        generators after its motion are copied (:func:`trailing_generators`).
        """
        if self.output == 'SHAPE_KEYS':
            tails = tails or [""] * len(names)
            new_keys = [bridge.NewShapeKey(name, pose, tail)
                        for name, pose, tail in zip(names, poses, tails)]
            times = [bridge.scene_time(context.scene, frame) for frame in frames]
            added = bridge.add_shape_keys(source, new_keys, keyframes=times if keyframe else None)
            # the keyed values are the mesh's: its other objects play the new keys as well, unless
            # their own simulation or cache replaces what the keys show
            others = [other for other in (sharing_mesh(source) if keyframe else [])
                      if not any(modifier.show_viewport and modifier.type in POSE_REPLACING_MODIFIERS
                                 for modifier in other.modifiers)]
            if others:
                named = ", ".join(f"'{other.name}'" for other in others)
                report(self, {'WARNING'}, f"{named} {'shares' if len(others) == 1 else 'share'} the mesh of "
                                          f"'{source.name}' and now {'plays' if len(others) == 1 else 'play'} the "
                                          "new keyframed shape keys too: give "
                                          f"'{source.name}' its own mesh first (Object › Relations › Make Single "
                                          "User › Object & Data), or use Output › Point Cache (a new object)")
            motion = object_motion(source) if speed != 1.0 else {}
            if motion:
                # a new object retimes a keyframed transform, not a simulation's
                advice = (f"bake it to keyframes ({BAKE_RIGID_BODY}) and " if "rigid_body" in motion else "")
                report(self, {'WARNING'}, f"'{source.name}' is moved as a whole by "
                                          f"{', '.join(motion.values())}, at its own speed while the new "
                                          f"shape keys play at {speed:g}x: {advice}use Output › Point Cache "
                                          "(a new object) to retime its keyframed transform too")
            self.drop_undone_cache(None)
            return added_summary(added)
        return self.write_cache_object(context, source, poses, frames, label, speed, keyed)

    def drop_undone_cache(self, played: Path | None, written: bool = False) -> None:
        """Remember the cache file this run plays (``played``; None: shape keys) where it is the
        operator's own — ``written`` by this run, or by the run it repeats — and, where the run
        repeats the last one from the Redo panel (Adjust Last Operation), delete the file that one
        wrote: Blender undid it first, so nothing plays the file any more, and each change of a
        setting there would leave one more on disk. Called once the new poses are written, since a
        repeat that fails brings the undone run back; a file a Mesh Cache in the file plays stays
        (Repeat Last runs again without undoing), and so does an earlier run's file a run played
        again without writing it (:func:`write_new_cache`: another .blend in the folder, a version
        saved before, may play it)."""
        previous = _LAST_CACHE.get(self.bl_idname) if self.is_repeat() else None
        own = played is not None and (written or previous == str(played))
        _LAST_CACHE[self.bl_idname] = str(played) if own else None
        if (previous and previous != str(played) and os.path.isfile(previous)
                and os.path.realpath(previous) not in cache_files_in_use()):
            try:
                os.remove(previous)
            except OSError as error:  # left on disk: the new poses are written all the same
                print(f"Shape Differences: could not delete the undone cache '{previous}': {error}")

    def write_cache_object(self, context, source, poses, frames: list[float], label: str,
                           speed: float = 1.0, keyed: bool = False) -> str:
        sampling = float(frames[1] - frames[0]) if len(frames) > 1 else 1.0
        if len(frames) > 1 and not np.allclose(np.diff(frames), sampling, rtol=1e-6):
            raise ValueError("A point cache needs evenly spaced frames")  # a bug, not user input
        # the Mesh Cache and the object's animation play the scene's time, not its frame number
        start, sampling = bridge.scene_time(context.scene, frames[0]), bridge.scene_time(context.scene, sampling)
        name = bridge.unique_name(source.name, f" {label}", bpy.data.objects.keys())
        path, _ = self.cache_path(name, check_free=False)
        try:
            path, written = write_new_cache(path, poses, start, sampling)
        except OSError as error:
            from ..core.point_cache import unwritable

            reason = unwritable(path) or error.strerror or str(error)
            raise InputError(f"Cannot write the cache file '{path}': {reason}. Pick another Cache File") from None
        stored_path = self.stored_path(path)
        modifiers, left_out = modifiers_under_keys(source) if keyed else modifiers_under_frames(source)
        try:
            obj = bridge.add_cache_object(context, source, name, stored_path, start, sampling,
                                          modifiers=modifiers, speed=speed,
                                          source_end=start + sampling * (len(frames) - 1) * speed,
                                          deformed_by_parent=keyed)
        except BaseException:
            if written:
                path.unlink(missing_ok=True)
            raise
        if left_out:
            advice = ("use Output › Shape Keys to see them under it" if keyed else "copy them to it by hand if it "
                      "should render them (Particle Properties › Copy Active to Selected Objects)")
            report(self, {'WARNING'},
                   f"'{obj.name}' plays the poses without {', '.join(repr(m.name) for m in left_out)} "
                   f"of '{source.name}' (a simulation, a cache or a particle system is not copied): {advice}")
        # taken over (bridge.copy_object_motion): the keyframed transform at any speed, the
        # parent and constraints at the scene's own
        motion = object_motion(source)
        if "rigid_body" in motion:  # the simulation moves the source alone: the new object stays put
            report(self, {'WARNING'}, f"'{obj.name}' stands still where '{source.name}' is moved as a whole by its "
                                      f"rigid body simulation (the poses are in its own coordinates): bake that "
                                      f"motion to keyframes ({BAKE_RIGID_BODY}) and run again, so that the new "
                                      "object takes it over")
        missing = [words for kind, words in motion.items() if kind in ("nla", "drivers")]
        if missing:
            report(self, {'WARNING'}, f"'{obj.name}' is not moved by {' and '.join(missing)} of '{source.name}': "
                                      "add those to it by hand if it should follow them")
        own_speed = [words for kind, words in motion.items() if kind in ("constraints", "parent")]
        if speed != 1.0 and own_speed:
            verb = "moves" if own_speed == [motion.get("parent")] else "move"  # "its constraints" is plural
            report(self, {'WARNING'}, f"'{obj.name}' plays the motion at {speed:g}x, but "
                                      f"{' and '.join(own_speed)} {verb} it at the scene's own speed")
        self.drop_undone_cache(path, written)
        span = (f"frame {frames[0]:g}" if len(frames) == 1
                else f"frames {frames[0]:g}-{frames[-1]:g}")
        return (f"Added '{obj.name}' playing {len(frames)} pose{'s' if len(frames) != 1 else ''} "
                f"({span}) from {path}" + ("" if written else " (an earlier run's file, which holds these poses)"))


def _plays_nla(animation) -> bool:
    """Whether ``animation`` (an ID's animation data) plays NLA strips: a track that is not muted."""
    return any(not track.mute for track in animation.nla_tracks)


def _transform_drivers(animation) -> bool:
    """Whether ``animation`` (an object's animation data) drives its transform."""
    return any(driver.data_path in bridge.TRANSFORM_CHANNELS for driver in animation.drivers)


#: Where a user turns a rigid body's motion into keyframes, which a new object takes over.
BAKE_RIGID_BODY = "Object › Rigid Body › Bake To Keyframes"


def _own_motion(obj) -> dict[str, str]:
    """What of ``obj``'s own moves it as a whole: {kind: the user's words} ("rigid_body",
    "keyframed", "nla", "drivers", "constraints")."""
    animation = obj.animation_data
    out = {}
    if bridge.simulated_rigid_body(obj):
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


def added_summary(names: list[str]) -> str:
    shown = names if len(names) <= 4 else [names[0], "...", names[-1]]
    return f"Added {len(names)} shape key{'s' if len(names) != 1 else ''}: " + ", ".join(shown)
