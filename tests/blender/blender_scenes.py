"""Small real scenes for the operator tests: a grid with posed shape keys, a baked cloth
simulation, an armature animation; and a snapshot of everything an operator must not change."""

import bpy
import numpy as np


def grid_object(subdivisions: int = 12, name: str = "Sheet"):
    """A flat subdivided grid (about ``subdivisions**2`` vertices), active and selected."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=subdivisions, y_subdivisions=subdivisions,
                                    size=2.0)
    obj = bpy.context.active_object
    obj.name = name
    return obj


def stretched_sheet(bridge, scale=(2.0, 1.0, 0.5)):
    """A grid scaled along its axes in Object Mode and not applied: (the object, the linear part
    of its world matrix (3, 3), its rest positions in its own coordinates)."""
    sheet = grid_object(8)
    sheet.scale = scale
    bpy.context.view_layer.update()
    return sheet, np.array(sheet.matrix_world.to_3x3()), bridge.mesh_data.vertex_positions(sheet.data)


def world_turned(positions: np.ndarray, linear: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """``positions`` (an object's own coordinates, its world matrix's linear part ``linear``)
    turned by the rotation ``turn`` (3, 3) in the world, in the object's own coordinates."""
    return positions @ linear.T @ turn.T @ np.linalg.inv(linear).T


def _played_under_keyed_scale(extension, path, sheet, scale, world, scale_keyed: bool):
    """Play ``sheet`` by a Mesh Cache at ``path`` whose frames 1–9 show ``world(f)`` in the world under
    the object scale ``scale(f)``, keyframed linearly at frames 1 and 9 where ``scale_keyed``; scene
    frames 1–9."""
    import importlib

    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    path = point_cache.write_pc2(path, np.array([world(f) / scale(f) for f in range(1, 10)]), start=1.0)
    modifier = sheet.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.filepath = 'PC2', str(path)
    modifier.frame_start = 1.0
    if scale_keyed:
        for frame in (1, 9):
            sheet.scale = (scale(frame),) * 3
            sheet.keyframe_insert("scale", frame=frame)
        for fcurve in _fcurves(sheet.animation_data):
            for point in fcurve.keyframe_points:
                point.interpolation = 'LINEAR'
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9


def turning_sheet_scale_keyframed(extension, tmp_path, stretch: float = 0.0, scale_keyed: bool = True):
    """A sheet turning rigidly in the world at a steady 15° per frame (and stretched along its x
    axis by ``stretch`` more per frame), played by a Mesh Cache on an object whose (unapplied)
    scale is keyframed 1 → 2 linearly over frames 1–9 (held after), or held at 1 where not
    ``scale_keyed``: the sheet, its scale and its world positions as functions of the (fractional)
    frame."""
    from scipy.spatial.transform import Rotation

    sheet = grid_object(8)
    rest = extension.bridge.mesh_data.vertex_positions(sheet.data)

    def scale(frame):
        return 1.0 + 0.125 * (min(frame, 9) - 1) if scale_keyed else 1.0

    def world(frame):  # the sheet as the world shows it at ``frame``
        turn = Rotation.from_rotvec(np.radians(15.0 * (frame - 1)) * np.array([0.0, 0.8, 0.6])).as_matrix()
        return rest * np.array([1.0 + stretch * (frame - 1), 1.0, 1.0]) @ turn.T

    _played_under_keyed_scale(extension, tmp_path / f"turn_{sheet.name}.pc2", sheet, scale, world, scale_keyed)
    return sheet, scale, world


def sheet_easing_off_scale_keyframed(extension, tmp_path, lift: float = 0.003, scale_keyed: bool = True):
    """A flat sheet rising in the world as ``lift · (f − 1)³`` (from rest, speeding up), played by
    a Mesh Cache on an object whose (unapplied) scale is keyframed 1 → 2 linearly over frames 1–9,
    or held at 1 where not ``scale_keyed``: the sheet, its scale and its world positions as
    functions of the frame. In the object's own coordinates a sheet scaled up shrinks from frame 1
    on, so it leaves its first frame moving; in the world it leaves it from rest."""
    sheet = grid_object(8)
    rest = extension.bridge.mesh_data.vertex_positions(sheet.data)

    def scale(frame):
        return 1.0 + 0.125 * (min(frame, 9) - 1) if scale_keyed else 1.0

    def world(frame):
        return rest + np.array([0.0, 0.0, lift * (frame - 1) ** 3])

    _played_under_keyed_scale(extension, tmp_path / f"rise_{sheet.name}.pc2", sheet, scale, world, scale_keyed)
    return sheet, scale, world


def turning_stretched_sheet(extension, tmp_path, first: int = 1, last: int = 9):
    """A sheet scaled (2, 1, 0.5) in Object Mode and not applied, played by a Mesh Cache that turns it
    rigidly in the world at a steady 15° per frame from frame ``first`` on (scene frames 1–``last``):
    (the sheet, the linear part of its world matrix, its turn at a frame in the mesh's coordinates)."""
    import importlib

    from scipy.spatial.transform import Rotation

    sheet, linear, rest = stretched_sheet(extension.bridge)

    def turned(frame):
        turn = Rotation.from_rotvec(np.radians(15.0 * (frame - first)) * np.array([0.0, 0.8, 0.6])).as_matrix()
        return world_turned(rest, linear, turn)

    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    path = point_cache.write_pc2(tmp_path / "turn.pc2", np.array([turned(f) for f in range(1, last + 1)]), start=1.0)
    modifier = sheet.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.filepath = 'PC2', str(path)
    modifier.frame_start = 1.0  # sample 0 at frame 1 (the modifier reads sample frame − frame_start)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, last
    return sheet, linear, turned


def turning_sheet_stretched_before_its_frames(extension, tmp_path):
    """:func:`turning_stretched_sheet` turning from frame 3, its scale keyframed from 1 at frame 1 to
    (2, 1, 0.5) at frame 3 (held after): frames 3–11 all show it under the one stretch, the scene's
    current frame 1 under none. (the sheet, the linear part of its world matrix from frame 3 on, its
    turn at a frame from 3 on in the mesh's coordinates)."""
    sheet, linear, turned = turning_stretched_sheet(extension, tmp_path, first=3, last=11)
    stretch = tuple(sheet.scale)
    for frame, scale in ((1, (1.0, 1.0, 1.0)), (3, stretch)):
        sheet.scale = scale
        sheet.keyframe_insert("scale", frame=frame)
    bpy.context.scene.frame_set(1)
    return sheet, linear, turned


def simulation_zone_scene(frames: int = 17):
    """A grid whose Geometry Nodes simulation zone (not baked) turns it 6° about z and lifts it by 0.05
    at each step, from the state of the frame before; scene frames 1 to ``frames``, at frame 1."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    obj = grid_object(6, name="Simulated")
    group = bpy.data.node_groups.new("Turn and lift", 'GeometryNodeTree')
    group.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
    group.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    nodes, links = group.nodes, group.links
    given, result = nodes.new('NodeGroupInput'), nodes.new('NodeGroupOutput')
    zone_in, zone_out = nodes.new('GeometryNodeSimulationInput'), nodes.new('GeometryNodeSimulationOutput')
    zone_in.pair_with_output(zone_out)
    move, position = nodes.new('GeometryNodeSetPosition'), nodes.new('GeometryNodeInputPosition')
    turn = nodes.new('ShaderNodeVectorRotate')
    turn.rotation_type, turn.inputs["Angle"].default_value = 'Z_AXIS', np.radians(6.0)
    lift = nodes.new('ShaderNodeVectorMath')
    lift.operation, lift.inputs[1].default_value = 'ADD', (0.0, 0.0, 0.05)
    links.new(given.outputs[0], zone_in.inputs[0])
    links.new(zone_in.outputs[1], move.inputs["Geometry"])
    links.new(position.outputs[0], turn.inputs["Vector"])
    links.new(turn.outputs[0], lift.inputs[0])
    links.new(lift.outputs[0], move.inputs["Position"])
    links.new(move.outputs[0], zone_out.inputs[1])
    links.new(zone_out.outputs[0], result.inputs[0])
    obj.modifiers.new("Simulation", 'NODES').node_group = group
    scene.frame_set(1)
    return obj


def dynamic_paint_wave_scene(frames: int = 17):
    """A grid as a Dynamic Paint canvas with a Wave surface (not baked: it moves the vertices along
    their normals, each frame stepped from the state of the frame before) and a sphere brush
    sweeping through it from frame 1; scene frames 1 to ``frames``, at frame 1."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    canvas = grid_object(24, name="Pond")
    canvas.modifiers.new("Dynamic Paint", 'DYNAMIC_PAINT').ui_type = 'CANVAS'
    bpy.ops.dpaint.type_toggle(type='CANVAS')  # fills the modifier of the active object
    surface = canvas.modifiers["Dynamic Paint"].canvas_settings.canvas_surfaces[0]
    surface.surface_type = 'WAVE'
    surface.frame_start, surface.frame_end = 1, frames
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(-0.8, 0.0, 0.1))
    brush = bpy.context.active_object
    brush.modifiers.new("Dynamic Paint", 'DYNAMIC_PAINT').ui_type = 'BRUSH'
    bpy.ops.dpaint.type_toggle(type='BRUSH')
    brush.keyframe_insert("location", frame=1)
    brush.location = (0.8, 0.0, 0.1)
    brush.keyframe_insert("location", frame=frames)
    for obj in scene.objects:
        obj.select_set(obj == canvas)
    bpy.context.view_layer.objects.active = canvas
    scene.frame_set(1)
    return canvas


def rolled(positions: np.ndarray, angle: float) -> np.ndarray:
    """The grid rolled about the y axis into an arc of ``angle`` radians (a bending pose)."""
    x, y = positions[:, 0], positions[:, 1]
    width = x.max() - x.min()
    radius = width / angle
    theta = (x - x.min()) / radius
    return np.stack([radius * np.sin(theta) + x.min(), y, radius * (1 - np.cos(theta))], axis=1)


def add_key(obj, name: str, positions: np.ndarray):
    """Add a shape key with the given positions (creating the Basis first)."""
    if obj.data.shape_keys is None:
        obj.shape_key_add(name="Basis", from_mix=False)
    key_block = obj.shape_key_add(name=name, from_mix=False)
    key_block.data.foreach_set("co", positions.astype(np.float32).ravel())
    obj.data.update()
    return key_block


def with_boundary_sliver(bridge, mesh):
    """A copy of ``mesh`` with one triangle of no area more: a boundary edge (a, b) and the midpoint
    of it (a new last vertex), running along the edge the other way from the face it bounds, as a
    decimation or a careless edit leaves one. Returns the new mesh and its positions (n + 1, 3)."""
    rest = bridge.mesh_data.vertex_positions(mesh)
    faces = [tuple(polygon.vertices) for polygon in mesh.polygons]
    uses = {}
    for face in faces:
        for edge in zip(face, face[1:] + face[:1]):
            uses[frozenset(edge)] = uses.get(frozenset(edge), 0) + 1
    a, b = next(edge for face in faces for edge in zip(face, face[1:] + face[:1]) if uses[frozenset(edge)] == 1)
    positions = np.vstack([rest, (rest[a] + rest[b]) / 2])
    sliver = bpy.data.meshes.new("Sliver")
    sliver.from_pydata([*map(tuple, positions)], [], faces + [(b, a, len(rest))])
    return sliver, positions


def posed_grid(bridge, subdivisions: int = 12):
    """A grid with a Basis and two rolled poses, "Bend" (the active key) and "Curl"."""
    obj = grid_object(subdivisions)
    rest = bridge.mesh_data.vertex_positions(obj.data)
    add_key(obj, "Curl", rolled(rest, 2.0))
    add_key(obj, "Bend", rolled(rest, 1.0))
    obj.active_shape_key_index = 2
    return obj


def transfer_pair(bridge, source_subdivisions: int, target_subdivisions: int):
    """A "Source" grid with a "Bend" key and a "Sheet" grid (active) over it, both selected: the
    selection Transfer reads (the source beside the active target)."""
    source = grid_object(source_subdivisions, name="Source")
    add_key(source, "Bend", rolled(bridge.mesh_data.vertex_positions(source.data), 1.0))
    target = grid_object(target_subdivisions, name="Sheet")
    source.select_set(True)
    target.select_set(True)
    bpy.context.view_layer.objects.active = target
    return source, target


def bound_to(proxy, subdivisions: int = 16, name: str = "Render"):
    """A grid (the render mesh) placed as ``proxy`` and bound to it by a Surface Deform: it moves
    as the proxy's evaluated mesh does."""
    mesh = grid_object(subdivisions, name=name)
    mesh.rotation_euler.x = proxy.rotation_euler.x
    bind = mesh.modifiers.new("Surface Deform", 'SURFACE_DEFORM')
    bind.target = proxy
    with bpy.context.temp_override(object=mesh, active_object=mesh):
        bpy.ops.object.surfacedeform_bind(modifier=bind.name)
    return mesh


def cloth_scene(subdivisions: int = 14, frames: int = 13):
    """A grid falling onto a sphere with a Cloth modifier, baked for ``frames`` frames."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, location=(0, 0, 0), segments=16,
                                         ring_count=8)
    bpy.context.active_object.modifiers.new("Collision", 'COLLISION')
    obj = grid_object(subdivisions, name="Cloth")
    obj.location.z = 1.0
    cloth = obj.modifiers.new("Cloth", 'CLOTH')
    cloth.point_cache.frame_start, cloth.point_cache.frame_end = 1, frames
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    scene.frame_set(1)
    return obj


def pinned_cloth_scene(subdivisions: int = 8, frames: int = 13, bake: bool = False):
    """A grid hanging from its pinned back edge (a Cloth modifier with a pin group), simulated
    into its memory cache frame by frame (``bake=False``: the cache is not baked) or baked."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    obj = grid_object(subdivisions, name="Flag")
    obj.rotation_euler.x = 1.2
    pinned = obj.vertex_groups.new(name="Pin")
    pinned.add([v.index for v in obj.data.vertices if v.co.y > 0.99], 1.0, 'REPLACE')
    cloth = obj.modifiers.new("Cloth", 'CLOTH')
    cloth.settings.vertex_group_mass = "Pin"
    cloth.point_cache.frame_start, cloth.point_cache.frame_end = 1, frames
    if bake:
        with bpy.context.temp_override(scene=scene):
            bpy.ops.ptcache.bake_all(bake=True)
    else:
        for frame in range(1, frames + 1):
            scene.frame_set(frame)
    scene.frame_set(1)
    return obj


def soft_body_scene(frames: int = 9):
    """A UV sphere with Soft Body physics (no goal, edge springs) dropped onto a plane with a Collision
    modifier, baked for ``frames`` frames: it squashes where it lands."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0, 0, 0))
    bpy.context.active_object.modifiers.new("Collision", 'COLLISION')
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0, 0, 0.8), segments=16, ring_count=8)
    obj = bpy.context.active_object
    obj.name = "Ball"
    soft_body = obj.modifiers.new("Softbody", 'SOFT_BODY')
    obj.soft_body.use_goal = False
    obj.soft_body.use_edges = True
    soft_body.point_cache.frame_start, soft_body.point_cache.frame_end = 1, frames
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    scene.frame_set(1)
    return obj


def driven_keys_scene(frames: int = 9):
    """A grid whose "Bend" key value is keyframed 0 → 1 and whose "Curl" key value is driven by
    Bend's value (a driver), so the animation comes from keys driven by other keys."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    obj = grid_object(6, name="Driven")
    rest = np.array([v.co[:] for v in obj.data.vertices])
    add_key(obj, "Bend", rolled(rest, 1.5))
    curl = rest.copy()
    curl[:, 2] += 0.3 * curl[:, 1] ** 2
    add_key(obj, "Curl", curl)
    bend = obj.data.shape_keys.key_blocks["Bend"]
    for frame, value in ((1, 0.0), (frames, 1.0)):
        bend.value = value
        bend.keyframe_insert("value", frame=frame)
    driver = obj.data.shape_keys.key_blocks["Curl"].driver_add("value").driver
    variable = driver.variables.new()
    variable.targets[0].id_type = 'KEY'
    variable.targets[0].id = obj.data.shape_keys
    variable.targets[0].data_path = 'key_blocks["Bend"].value'
    driver.expression = f"{variable.name} * {variable.name}"
    scene.frame_set(1)
    return obj


def armature_scene(frames: int = 9, parented: bool = False):
    """A grid strip bent by a two-bone armature whose second bone rotates from frame 1 to
    ``frames``; the vertices are weighted to the bones by their x coordinate. ``parented``: the
    strip is also the armature object's child, and the armature object moves."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=20, y_subdivisions=5, size=2.0)
    strip = bpy.context.active_object
    strip.scale.y = 0.25
    bpy.ops.object.transform_apply(scale=True)

    bpy.ops.object.armature_add(enter_editmode=True, location=(-1, 0, 0))
    rig = bpy.context.active_object
    first = rig.data.edit_bones[0]
    first.name, first.head, first.tail = "Root", (0, 0, 0), (1, 0, 0)
    second = rig.data.edit_bones.new("Tip")
    second.head, second.tail, second.parent = (1, 0, 0), (2, 0, 0), first
    bpy.ops.object.mode_set(mode='OBJECT')

    x = np.array([v.co.x for v in strip.data.vertices])
    tip_weight = np.clip((x + 0.2) / 0.4, 0.0, 1.0)
    root_group, tip_group = strip.vertex_groups.new(name="Root"), strip.vertex_groups.new(name="Tip")
    for index, weight in enumerate(tip_weight):
        root_group.add([index], 1.0 - weight, 'REPLACE')
        tip_group.add([index], weight, 'REPLACE')
    strip.modifiers.new("Armature", 'ARMATURE').object = rig

    tip = rig.pose.bones["Tip"]
    tip.rotation_mode = 'XYZ'
    for frame, angle in ((1, 0.0), (frames, 1.2)):
        tip.rotation_euler = (0.0, -angle, 0.0)
        tip.keyframe_insert("rotation_euler", frame=frame)
    if parented:
        strip.parent = rig
        strip.matrix_parent_inverse = rig.matrix_world.inverted()
        for frame, height in ((1, 0.0), (frames, 0.5)):
            rig.location.z = height
            rig.keyframe_insert("location", frame=frame)
    scene.frame_set(1)
    bpy.context.view_layer.objects.active = strip
    strip.select_set(True)
    return strip


def played(bridge, obj, frames) -> dict:
    """The evaluated mesh of ``obj`` at each of ``frames``, whatever its vertex count (a cache
    object, or one with a Subdivision after its motion); the scene is left at frame 1."""
    result = {}
    for frame in frames:
        bpy.context.scene.frame_set(frame)
        result[frame] = bridge.mesh_data.evaluated_positions(obj, bpy.context.evaluated_depsgraph_get())
    bpy.context.scene.frame_set(1)
    return result


def evaluated_frames(bridge, obj, frames):
    """The evaluated positions of ``obj`` at each of ``frames`` (restores the current frame)."""
    return dict(bridge.frame_reading.frame_positions(bpy.context, obj, list(frames)))


def snapshot(bridge, obj) -> dict:
    """Everything about ``obj`` and the scene that a failed operator must leave as it was."""
    mesh = obj.data
    positions = bridge.mesh_data.vertex_positions(mesh)
    keys = {}
    animation = None
    if mesh.shape_keys is not None:
        for key_block in mesh.shape_keys.key_blocks:
            keys[key_block.name] = (bridge.mesh_data.stored_key_positions(key_block), key_block.value,
                                    key_block.relative_key.name)
        animation_data = mesh.shape_keys.animation_data
        animation = animation_data.action.name if animation_data and animation_data.action else None
    key_fcurves, drivers = [], []
    if mesh.shape_keys is not None and mesh.shape_keys.animation_data is not None:
        animation_data = mesh.shape_keys.animation_data
        drivers = [(d.data_path, d.driver.expression) for d in animation_data.drivers]
        if animation_data.action is not None:
            key_fcurves = [(point.co[:], point.interpolation)
                           for fcurve in _fcurves(animation_data)
                           for point in fcurve.keyframe_points]
    return {
        "positions": positions,
        "key_fcurves": key_fcurves,
        "drivers": drivers,
        "modifier_settings": [_rna_values(m) for m in obj.modifiers],
        "point_caches": [(m.name, m.point_cache.info, m.point_cache.is_baked)
                         for m in obj.modifiers if hasattr(m, "point_cache")],
        "matrix": [tuple(row) for row in obj.matrix_world],
        "keys": keys,
        "key_animation": animation,
        "active_key": obj.active_shape_key_index,
        "modifiers": [(m.name, m.type, m.show_viewport, m.show_render) for m in obj.modifiers],
        "object_animation": (obj.animation_data.action.name
                             if obj.animation_data and obj.animation_data.action else None),
        "frame": bpy.context.scene.frame_current,
        "actions": sorted(action.name for action in bpy.data.actions),
        "meshes": len(bpy.data.meshes),
    }


def _fcurves(animation_data):
    action = animation_data.action
    if hasattr(animation_data, "action_slot"):
        from bpy_extras import anim_utils
        channelbag = anim_utils.action_get_channelbag_for_slot(action, animation_data.action_slot)
        return channelbag.fcurves if channelbag else ()
    return action.fcurves


def _rna_values(struct) -> dict:
    """Every plain property of ``struct`` (a modifier), for before/after comparisons."""
    values = {}
    for prop in struct.bl_rna.properties:
        if prop.type in ('BOOLEAN', 'INT', 'FLOAT', 'STRING', 'ENUM') and not prop.is_readonly:
            value = getattr(struct, prop.identifier)
            values[prop.identifier] = tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else value
    return values


def assert_unchanged(before: dict, after: dict):
    assert after["keys"].keys() == before["keys"].keys()
    for name, (coordinates, value, relative) in before["keys"].items():
        np.testing.assert_array_equal(after["keys"][name][0], coordinates)
        assert after["keys"][name][1:] == (value, relative)
    np.testing.assert_array_equal(after["positions"], before["positions"])
    for field in ("key_animation", "active_key", "modifiers", "object_animation", "frame",
                  "actions", "meshes", "key_fcurves", "drivers", "modifier_settings",
                  "point_caches", "matrix"):
        assert after[field] == before[field], field


def key_names(obj) -> list[str]:
    return [key_block.name for key_block in obj.data.shape_keys.key_blocks]
