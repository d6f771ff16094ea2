"""A new object that plays a point cache (a Mesh Cache modifier on a copy of the source's mesh),
rendering as the source does.
"""

from __future__ import annotations

import bpy

from .analysis_data import forget_analysis
from .copied_motion import DEFORMING_PARENT_TYPES, copy_object_motion, parent_deform_modifier
from .rigid_bodies import rigid_body_collections


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
    (:func:`bridge.copied_motion.copy_object_motion`; the cache holds object-space positions; ``speed``, ``source_end``:
    a retime that plays ``source``'s frames ``start`` … ``source_end``; ``deformed_by_parent``:
    a parent deforming ``source`` deforms the poses too, by :func:`bridge.copied_motion.parent_deform_modifier`);
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
