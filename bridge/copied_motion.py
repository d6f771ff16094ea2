"""What moves an object as a whole, copied to a new object: its parent (a deforming parent as a
modifier), transform channels, constraints and keyframed transform, retimed through an NLA strip.
"""

from __future__ import annotations

import bpy

# Parent types that deform the child (a virtual modifier): the copy is parented as an object
# ('OBJECT': the same world matrix, parent.matrix_world @ matrix_parent_inverse @ matrix_basis).
DEFORMING_PARENT_TYPES = {'ARMATURE', 'LATTICE', 'CURVE'}
# The object's own transform channels, copied before its animation and constraints.
TRANSFORM_CHANNELS = ("rotation_mode", "location", "rotation_euler", "rotation_quaternion",
                      "rotation_axis_angle", "scale", "delta_location", "delta_rotation_euler",
                      "delta_rotation_quaternion", "delta_scale")


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
