"""A Subdivision Surface or Solidify after the cloth or armature (the usual set-up for display and
render) adds vertices to the evaluated mesh: frames are read with those trailing generators
switched off (the poses are of the mesh's own vertices), they are switched on again afterwards,
and the new object that plays the result gets copies of them after its Mesh Cache, so that it
looks like the source; so are those that keep the vertex count at the current frame (they may
change it at another, and their copies would add their work twice). A generator before the
motion, one between the cloth and a deformer after it, or one after an unbaked simulation (whose
cache switching it off would outdate) where it changes the vertex count, is refused naming it and
nothing changes."""

import importlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import (armature_scene, assert_unchanged, cloth_scene, evaluated_frames,  # noqa: E402
                            grid_object, key_names, pinned_cloth_scene, played, rolled, snapshot)
from test_failures import fails_without_change  # noqa: E402

TOLERANCE = 1e-5  # float32 positions


def add_display_modifiers(obj):
    subdivision = obj.modifiers.new("Subdivision", 'SUBSURF')
    subdivision.levels = 1
    solidify = obj.modifiers.new("Solidify", 'SOLIDIFY')
    solidify.thickness = 0.02
    return subdivision, solidify


def sharp_edges(mesh) -> np.ndarray:
    """The evaluated mesh's edges marked sharp (what shades it by angle)."""
    values = np.zeros(len(mesh.edges), dtype=bool)
    if "sharp_edge" in mesh.attributes:
        mesh.attributes["sharp_edge"].data.foreach_get("value", values)
    return values


def new_objects(names_before: set):
    return [obj for obj in bpy.data.objects if obj.name not in names_before]


def test_inbetween_frames_reads_the_armature_motion_under_a_subdivision(bpy_empty, extension, tmp_path):
    bridge = extension.bridge
    strip = armature_scene(frames=9)
    moving = evaluated_frames(bridge, strip, [1, 5, 9])  # the armature's motion of the mesh's vertices
    add_display_modifiers(strip)
    shown = played(bridge, strip, [1, 5, 9])
    assert len(shown[5]) > len(strip.data.vertices), "the subdivision should add vertices"
    before, names = snapshot(bridge, strip), set(bpy.data.objects.keys())

    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                               filepath=str(tmp_path / "strip.pc2"))

    after = snapshot(bridge, strip)
    after["meshes"] = before["meshes"]  # the new object brings its own mesh
    assert_unchanged(before, after)  # modifiers on again, with every setting as it was
    [copy] = new_objects(names)
    assert [m.type for m in copy.modifiers] == ['MESH_CACHE', 'SUBSURF', 'SOLIDIFY']
    assert copy.modifiers["Subdivision"].levels == 1
    assert copy.modifiers["Solidify"].thickness == pytest.approx(0.02)
    for frame in (1, 5, 9):
        # the cache holds the keys' own vertices, and the new object displays them as the source does
        copy.modifiers["Subdivision"].show_viewport = copy.modifiers["Solidify"].show_viewport = False
        np.testing.assert_allclose(evaluated_frames(bridge, copy, [frame])[frame], moving[frame],
                                   atol=TOLERANCE)
        copy.modifiers["Subdivision"].show_viewport = copy.modifiers["Solidify"].show_viewport = True
        np.testing.assert_allclose(played(bridge, copy, [frame])[frame], shown[frame], atol=TOLERANCE)


def test_frames_of_a_baked_cloth_under_a_subdivision(bpy_empty, extension):
    bridge = extension.bridge
    cloth = cloth_scene(subdivisions=10, frames=9)
    moving = evaluated_frames(bridge, cloth, [1, 5, 9])
    subdivision, _ = add_display_modifiers(cloth)
    shown = played(bridge, cloth, [9])[9]
    before = snapshot(bridge, cloth)

    bpy.ops.shape_differences.frames_to_shape_keys(frame_start=1, frame_end=9, frame_step=4,
                                                   output='SHAPE_KEYS')

    assert key_names(cloth) == ["Basis", "Frame 1", "Frame 5", "Frame 9"]
    for frame in (1, 5, 9):
        np.testing.assert_allclose(
            bridge.mesh_data.stored_key_positions(cloth.data.shape_keys.key_blocks[f"Frame {frame}"]),
            moving[frame], atol=TOLERANCE)
    assert subdivision.show_viewport
    after = snapshot(bridge, cloth)
    for field in ("modifiers", "modifier_settings", "point_caches", "frame"):
        assert after[field] == before[field], field
    # the bake still plays: the new keys are at value 0, the cloth drives the mesh
    np.testing.assert_allclose(played(bridge, cloth, [9])[9], shown, atol=TOLERANCE)


def test_a_baked_cache_is_not_left_outdated(bpy_empty, extension, tmp_path):
    """Run from the middle of the range, switching the Subdivision off and on while the frames are
    read left the bake marked outdated (Blender offers to compute it again): now switched at the
    cache's start frame, the bake's state is as it was."""
    from blender_scenes import grid_object
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 9
    cloth = grid_object(8, name="Cloth")
    cache = cloth.modifiers.new("Cloth", 'CLOTH').point_cache
    cache.frame_end = 9
    cloth.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    scene.frame_set(5)
    assert cache.is_baked and not cache.is_outdated
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                               filepath=str(tmp_path) + "/")
    assert cache.is_baked and not cache.is_outdated and bpy.context.scene.frame_current == 5


@pytest.mark.parametrize("subdivided", [True, False], ids=["subdivision", "alone"])
def test_shade_auto_smooth_after_the_motion_goes_with_the_new_object(bpy_empty, extension, subdivided, tmp_path):
    """*Shade Auto Smooth* (Blender 4.1+) ends the stack with a *Smooth by Angle* Geometry Nodes
    modifier. Behind a Subdivision it was taken for a generator before the motion and the run was
    refused ("a modifier before the motion ... changes the topology"); alone, the new object lost
    it and was shaded otherwise than the source. It is set aside with the Subdivision and copied
    after the Mesh Cache: the new object shows the source's vertices and shading."""
    bridge = extension.bridge
    cloth = armature_scene(frames=9)  # bends enough to shade by angle
    moving = evaluated_frames(bridge, cloth, [1, 5, 9])
    if subdivided:
        cloth.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    with bpy.context.temp_override(active_object=cloth, object=cloth, selected_objects=[cloth],
                                   selected_editable_objects=[cloth]):
        bpy.ops.object.shade_auto_smooth(angle=0.05)
    shown = played(bridge, cloth, [5, 9])
    names = set(bpy.data.objects.keys())

    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                               filepath=str(tmp_path / "cloth.pc2"))

    [copy] = new_objects(names)
    assert [m.type for m in copy.modifiers] == ['MESH_CACHE'] + ['SUBSURF'] * subdivided + ['NODES']
    assert copy.modifiers[-1].node_group == cloth.modifiers[-1].node_group
    assert copy.modifiers[-1]["Input_1"] == pytest.approx(0.05)  # the angle
    if not subdivided:
        np.testing.assert_allclose(evaluated_frames(bridge, copy, [5])[5], moving[5], atol=TOLERANCE)
    counts = []
    for frame in (5, 9):
        bpy.context.scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        np.testing.assert_allclose(bridge.mesh_data.evaluated_positions(copy, depsgraph), shown[frame], atol=TOLERANCE)
        sharp = [sharp_edges(obj.evaluated_get(depsgraph).data) for obj in (cloth, copy)]
        np.testing.assert_array_equal(sharp[1], sharp[0])
        counts.append((sharp[0].sum(), len(sharp[0])))
    bpy.context.scene.frame_set(1)
    assert 0 < counts[-1][0] < counts[-1][1], counts  # bent, shaded by angle: some edges sharp


def test_a_subdivision_on_for_rendering_only_goes_with_the_new_object(bpy_empty, extension, tmp_path):
    """A Subdivision switched off in the viewport and on for rendering (the usual way to keep the
    viewport fast): the new object renders as the source does (before, it lost the modifier)."""
    bridge = extension.bridge
    strip = armature_scene(frames=9)
    moving = evaluated_frames(bridge, strip, [5])
    subdivision = strip.modifiers.new("Subdivision", 'SUBSURF')
    subdivision.show_viewport, subdivision.render_levels = False, 2
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                               filepath=str(tmp_path / "strip.pc2"))
    [copy] = new_objects(names)
    assert [(m.type, m.show_viewport, m.show_render) for m in copy.modifiers] == [
        ('MESH_CACHE', True, True), ('SUBSURF', False, True)]
    assert copy.modifiers["Subdivision"].render_levels == 2
    np.testing.assert_allclose(evaluated_frames(bridge, copy, [5])[5], moving[5], atol=TOLERANCE)
    assert not subdivision.show_viewport and subdivision.show_render  # the source's as it was


def test_a_subdivision_after_an_unbaked_cloth_is_refused(bpy_empty, extension):
    flag = pinned_cloth_scene(frames=5, bake=False)
    add_display_modifiers(flag)
    bpy.context.view_layer.update()  # adding them empties the unbaked cache (Blender's doing, not ours)
    fails_without_change(extension.bridge, flag, bpy.ops.shape_differences.inbetween_frames,
                         "'Subdivision', 'Solidify' after the simulation .* 'Cloth' cache is not "
                         "baked: bake it", frame_start=1, frame_end=5, frame_step=2)


def test_a_generator_before_the_motion_is_refused(bpy_empty, extension):
    strip = armature_scene()
    decimate = strip.modifiers.new("Decimate", 'DECIMATE')
    decimate.ratio = 0.5
    strip.modifiers.move(len(strip.modifiers) - 1, 0)  # before the armature
    assert [m.type for m in strip.modifiers] == ['DECIMATE', 'ARMATURE']
    for operator in (bpy.ops.shape_differences.frames_to_shape_keys,
                     bpy.ops.shape_differences.inbetween_frames):
        fails_without_change(extension.bridge, strip, operator,
                             "instead of .* 'Decimate' comes before the motion and changes the vertex count.* "
                             "Apply it .* or disable it")


def read_with_aside(bridge, obj, frames, aside):
    """The evaluated positions of ``obj`` at ``frames`` with the modifier ``aside`` switched off, switched at
    frame 1 (a simulation's start, where switching does not outdate its bake); the scene is left at frame 1."""
    scene = bpy.context.scene
    scene.frame_set(1)
    aside.show_viewport = False
    out = played(bridge, obj, frames)
    aside.show_viewport = True
    bpy.context.view_layer.update()
    return out


def keys_of_a_run(extension, tmp_path, modifier_types: list) -> dict:
    """Run *In-between Frames* on the active object over frames 1–9 (step 4, 3 in-betweens a gap) to a point
    cache, check the new object's modifiers are of ``modifier_types``, and return its samples at the keys
    ({frame: (n, 3)})."""
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=3,
                                               filepath=str(tmp_path / "keys.pc2"))
    [copy] = new_objects(names)
    assert [m.type for m in copy.modifiers] == modifier_types
    cache = importlib.import_module(f"{extension.__name__}.core.point_cache").read_pc2(
        bpy.path.abspath(copy.modifiers[0].filepath))
    return {frame: cache.positions[frame - 1] for frame in (1, 5, 9)}


def test_a_subdivision_under_a_baked_cloth_is_named_and_applying_it_keeps_the_bake(bpy_empty, extension, tmp_path):
    """A Subdivision before a baked cloth (which simulates the subdivided vertices) and a Solidify after it:
    the refusal names the Subdivision and says to apply it, which keeps the bake playing (its cache holds
    those vertices), and the run then reads the baked frames (before: "Disable modifiers that add or remove
    geometry there (Subdivision, …) or apply them before simulating", naming none: disabled, the Subdivision
    has Blender simulate the coarser mesh again, another motion)."""
    bridge = extension.bridge
    flag = pinned_cloth_scene(frames=9)
    subdivision, solidify = add_display_modifiers(flag)
    flag.modifiers.move(len(flag.modifiers) - 2, 0)  # the Subdivision first, under the cloth
    assert [m.type for m in flag.modifiers] == ['SUBSURF', 'CLOTH', 'SOLIDIFY']
    scene = bpy.context.scene
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    scene.frame_set(1)
    baked = read_with_aside(bridge, flag, [1, 5, 9], solidify)
    assert len(baked[5]) > len(flag.data.vertices), "the cloth should simulate the subdivided vertices"
    assert np.abs(baked[9] - baked[1]).max() > 0.1, "the cloth should move"
    fails_without_change(bridge, flag, bpy.ops.shape_differences.inbetween_frames,
                         "'Subdivision' comes before the motion .* Apply it .* the cloth 'Cloth' moves, and its baked "
                         "cache, which holds them, keeps playing", frame_start=1, frame_end=9, frame_step=4)

    # the advice holds: applied, the bake plays on and the run in-betweens the baked frames
    with bpy.context.temp_override(object=flag, active_object=flag):
        bpy.ops.object.modifier_apply(modifier="Subdivision")
    assert flag.modifiers["Cloth"].point_cache.is_baked
    for frame, positions in keys_of_a_run(extension, tmp_path, ['MESH_CACHE', 'SOLIDIFY']).items():
        np.testing.assert_allclose(positions, baked[frame], atol=TOLERANCE)  # the keys, as baked


def test_a_subdivision_under_an_unbaked_cloth_is_named(bpy_empty, extension):
    """The same Subdivision under a cloth that is not baked: named, with what applying it does there (the
    cloth simulates the vertices it makes again from its start)."""
    flag = pinned_cloth_scene(frames=5)
    flag.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    flag.modifiers.move(len(flag.modifiers) - 1, 0)
    bpy.context.view_layer.update()
    fails_without_change(extension.bridge, flag, bpy.ops.shape_differences.inbetween_frames,
                         "'Subdivision' comes before the motion .* Apply it .* the cloth 'Cloth' simulates \\(its "
                         "cache is not baked", frame_start=1, frame_end=5, frame_step=2)


def baked_cloth_under(*modifiers):
    """A pinned cloth followed by ``modifiers`` ((name, type) pairs, added in that order; an Armature
    gets an armature object that leaves the mesh where it is), baked for 9 frames; the scene at frame 1.
    Returns the cloth object and the modifiers added."""
    flag = pinned_cloth_scene(frames=9)
    added = [flag.modifiers.new(name, kind) for name, kind in modifiers]
    for modifier in added:
        if modifier.type == 'ARMATURE':
            rig = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
            bpy.context.scene.collection.objects.link(rig)
            modifier.object = rig
    with bpy.context.temp_override(scene=bpy.context.scene):
        bpy.ops.ptcache.bake_all(bake=True)
    bpy.context.scene.frame_set(1)
    return flag, added


def test_a_subdivision_between_a_baked_cloth_and_an_armature_is_moved_not_applied(bpy_empty, extension, tmp_path):
    """Cloth → Subdivision → Armature: the Subdivision works on the simulated vertices and is not at the end of
    the stack, so it is not set aside. The refusal says it comes after the cloth and to move it below the
    Armature (before: "'Subdivision' comes before the motion … Apply it", and applied, it gives the cloth
    vertices its bake does not hold: Blender simulates again). The advice holds: moved to the end, the bake
    plays on and the run in-betweens the baked frames."""
    bridge = extension.bridge
    flag, (subdivision, _armature) = baked_cloth_under(("Subdivision", 'SUBSURF'), ("Armature", 'ARMATURE'))
    baked = read_with_aside(bridge, flag, [1, 5, 9], subdivision)
    fails_without_change(bridge, flag, bpy.ops.shape_differences.inbetween_frames,
                         "'Subdivision' comes after the cloth 'Cloth' and changes the vertex count.* Move it "
                         "below 'Armature', to the end of the stack: it is then set aside .* or disable it. Applying "
                         "it would give the cloth vertices it did not simulate", frame_start=1, frame_end=9,
                         frame_step=4)

    flag.modifiers.move(1, 2)
    assert flag.modifiers["Cloth"].point_cache.is_baked
    for frame, positions in keys_of_a_run(extension, tmp_path, ['MESH_CACHE', 'SUBSURF']).items():
        np.testing.assert_allclose(positions, baked[frame], atol=TOLERANCE)  # the keys, as baked


def test_a_subdivision_between_a_mesh_cache_and_an_armature_is_moved_not_applied(bpy_empty, extension, tmp_path):
    """Mesh Cache → Subdivision → Armature: refused naming the Mesh Cache and the move below the Armature
    (before: "comes before the motion … Apply it", which would leave the cache a mesh of other vertices than
    its file's); moved there, the run in-betweens the file's samples."""
    bridge = extension.bridge
    point_cache = importlib.import_module(f"{extension.__name__}.core.point_cache")
    sheet = grid_object(6)
    rest = bridge.mesh_data.vertex_positions(sheet.data)
    samples = np.array([rolled(rest, 0.1 * frame) for frame in range(1, 10)])
    cache = sheet.modifiers.new("Mesh Cache", 'MESH_CACHE')
    cache.cache_format, cache.filepath, cache.frame_start = 'PC2', str(point_cache.write_pc2(
        tmp_path / "sheet.pc2", samples, start=1.0)), 1.0
    sheet.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    rig = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
    bpy.context.scene.collection.objects.link(rig)
    sheet.modifiers.new("Armature", 'ARMATURE').object = rig
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    fails_without_change(bridge, sheet, bpy.ops.shape_differences.inbetween_frames,
                         "'Subdivision' comes after the Mesh Cache 'Mesh Cache' .* Move it below 'Armature', to the "
                         "end of the stack: .* Applying it would give the Mesh Cache other vertices than its file "
                         "holds",
                         frame_start=1, frame_end=9, frame_step=4)

    sheet.modifiers.move(1, 2)
    for frame, positions in keys_of_a_run(extension, tmp_path, ['MESH_CACHE', 'SUBSURF']).items():
        np.testing.assert_allclose(positions, samples[frame - 1], atol=TOLERANCE)  # as the file holds them


def test_an_edge_split_after_a_baked_cloth_is_set_aside_though_the_current_frame_keeps_the_count(
        bpy_empty, extension, tmp_path):
    """An Edge Split by angle after a baked cloth adds no vertex while the cloth is flat (frame 1, the current
    one) and splits its folds later: it is set aside all the same, the run reads the baked frames and the new
    object gets a copy (before: refused at frame 5, "'EdgeSplit' comes before the motion … Apply it", though
    the same run from frame 9 went through)."""
    bridge = extension.bridge
    flag, (split,) = baked_cloth_under(("EdgeSplit", 'EDGE_SPLIT'))
    split.split_angle, split.use_edge_sharp = 0.02, False
    counts = [len(positions) for positions in played(bridge, flag, [1, 5, 9]).values()]
    assert counts[0] == len(flag.data.vertices) < counts[1], "the split should add vertices as the cloth folds"
    baked = read_with_aside(bridge, flag, [1, 5, 9], split)
    before = snapshot(bridge, flag)
    keys = keys_of_a_run(extension, tmp_path, ['MESH_CACHE', 'EDGE_SPLIT'])
    after = snapshot(bridge, flag)
    after["meshes"] = before["meshes"]  # the new object brings its own mesh
    assert_unchanged(before, after)
    for frame, positions in keys.items():
        np.testing.assert_allclose(positions, baked[frame], atol=TOLERANCE)


def test_a_displace_after_a_triangulate_plays_once_on_the_new_object(bpy_empty, extension, tmp_path):
    """Triangulate → Displace after a baked cloth keep the vertex count, and the new object gets copies of
    both: the frames are read without them, so the new object shows the source's mesh at the keys (before:
    read with the Displace, which its copy then added again, 0.15 off at strength 0.3)."""
    bridge = extension.bridge
    flag, (_triangulate, displace) = baked_cloth_under(("Triangulate", 'TRIANGULATE'), ("Displace", 'DISPLACE'))
    displace.strength = 0.3
    shown = played(bridge, flag, [1, 5, 9])
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=3,
                                               filepath=str(tmp_path / "flag.pc2"))
    [copy] = new_objects(names)
    assert [m.type for m in copy.modifiers] == ['MESH_CACHE', 'TRIANGULATE', 'DISPLACE']
    for frame, positions in played(bridge, copy, [1, 5, 9]).items():
        np.testing.assert_allclose(positions, shown[frame], atol=TOLERANCE)


def test_a_displace_set_aside_is_not_named_as_deforming_the_new_keys_again(bpy_empty, extension, capfd):
    """Triangulate → Displace after a baked cloth, captured as shape keys: the frames are read without
    them, so the new keys are displaced once on playback, as the frames were. The warning names only the
    cloth (before: "deformed again by 'Cloth', 'Displace'"), and doing what it says — disabling the cloth —
    plays each key as the frame it was captured from showed."""
    bridge = extension.bridge
    flag, (_triangulate, displace) = baked_cloth_under(("Triangulate", 'TRIANGULATE'), ("Displace", 'DISPLACE'))
    displace.strength = 0.3
    shown = played(bridge, flag, [1, 5, 9])
    capfd.readouterr()
    bpy.ops.shape_differences.frames_to_shape_keys(frame_start=1, frame_end=9, frame_step=4, output='SHAPE_KEYS')
    out = capfd.readouterr().out
    assert "The new shape keys are deformed again by 'Cloth' of 'Flag':" in out, out
    assert "'Displace'" not in out, out
    flag.modifiers["Cloth"].show_viewport = False
    key_blocks = flag.data.shape_keys.key_blocks
    for frame in (5, 9):
        for key_block in key_blocks[1:]:
            key_block.value = float(key_block.name == f"Frame {frame}")
        np.testing.assert_allclose(evaluated_frames(bridge, flag, [frame])[frame], shown[frame], atol=TOLERANCE)


@pytest.mark.parametrize("operator", ["frames_to_shape_keys", "inbetween_frames", "retime"])
def test_a_vertex_count_changed_at_every_frame_is_said_so(bpy_empty, extension, operator):
    """A Decimate before the armature changes the vertex count at every frame: the refusal says it does at
    the first and the last frame read, with the count the evaluated mesh has there (before: "At frame 1" or
    "At frame 3", whichever frame was read first, for a count that is no frame's doing), and nothing
    changes."""
    strip = armature_scene()
    decimate = strip.modifiers.new("Decimate", 'DECIMATE')
    decimate.ratio = 0.5
    strip.modifiers.move(len(strip.modifiers) - 1, 0)  # before the armature
    shown = {len(positions) for positions in played(extension.bridge, strip, range(1, 10)).values()}
    assert len(shown) == 1 and shown != {len(strip.data.vertices)}, shown
    fails_without_change(extension.bridge, strip, getattr(bpy.ops.shape_differences, operator),
                         r"^Error: At the first and the last frame read \(1 and 9\) the evaluated mesh of "
                         rf"'{strip.name}' has {shown.pop()} vertices instead of {len(strip.data.vertices)}: "
                         "'Decimate' comes before the motion", frame_start=1, frame_end=9, frame_step=4)


def test_an_edge_split_after_an_unbaked_cloth_is_named_with_baking(bpy_empty, extension):
    """The same Edge Split after a cloth that is not baked cannot be set aside (switching it would outdate the
    cache): refused where it splits, with baking as the way out (before: "comes before the motion … Apply it",
    which would have the cloth simulate vertices it did not)."""
    flag = pinned_cloth_scene(frames=9)
    split = flag.modifiers.new("EdgeSplit", 'EDGE_SPLIT')
    split.split_angle, split.use_edge_sharp = 0.02, False
    for frame in range(1, 10):  # simulated again into its memory cache, which the new modifier outdated
        bpy.context.scene.frame_set(frame)
    bpy.context.scene.frame_set(1)
    fails_without_change(extension.bridge, flag, bpy.ops.shape_differences.inbetween_frames,
                         "'EdgeSplit' comes after the cloth 'Cloth' .* Bake the cloth 'Cloth' \\(Physics › Cache › Bake\\)"
                         ".* or disable it", frame_start=1, frame_end=9, frame_step=4)


def test_a_collision_modifier_at_the_end_stays_with_the_source(bpy_empty, extension, tmp_path):
    """A rigged body other cloth collides with (Armature, Subdivision, Collision): the new object
    plays the motion under the Subdivision and is no collider (before: Blender refused to copy
    the Collision and the run ended in a traceback)."""
    strip = armature_scene()
    strip.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    strip.modifiers.new("Collision", 'COLLISION')
    bridge = extension.bridge
    strip.modifiers["Subdivision"].show_viewport = False
    moving = evaluated_frames(bridge, strip, [5])
    strip.modifiers["Subdivision"].show_viewport = True
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                               filepath=str(tmp_path / "body.pc2"))
    [copy] = new_objects(names)
    assert [m.type for m in copy.modifiers] == ['MESH_CACHE', 'SUBSURF']
    copy.modifiers["Subdivision"].show_viewport = False
    np.testing.assert_allclose(evaluated_frames(bridge, copy, [5])[5], moving[5], atol=TOLERANCE)


def test_a_collider_under_a_subdivision_keeps_other_unbaked_cloth(bpy_empty, extension):
    """Setting aside the Subdivision of a collider while its frames are read would empty the
    unbaked cache of a cape colliding with it (before: emptied, the cape's frames 9–17 re-simulated
    0.2–0.29 away from what was played): refused, the cape's cache as it was."""
    from blender_scenes import grid_object
    body = armature_scene(frames=9)
    body.modifiers.new("Collision", 'COLLISION')
    body.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    cape = grid_object(6, name="Cape")
    cape.location, cape.scale = (0.3, 0.0, 0.4), (0.6, 0.3, 1.0)
    cloth = cape.modifiers.new("Cloth", 'CLOTH')
    cloth.point_cache.frame_start, cloth.point_cache.frame_end = 1, 9
    for frame in range(1, 10):  # played: the cape's cache holds its frames
        bpy.context.scene.frame_set(frame)
    bpy.context.scene.frame_set(1)
    bpy.context.view_layer.objects.active = body
    cached = cloth.point_cache.info
    assert cached.startswith("9 frames")
    for operator in (bpy.ops.shape_differences.frames_to_shape_keys,
                     bpy.ops.shape_differences.inbetween_frames):
        fails_without_change(extension.bridge, body, operator,
                             r"'Subdivision' .* empty the unbaked cache of 'Cape' \('Cloth'\)", output='CACHE')
    bpy.context.evaluated_depsgraph_get()
    assert cloth.point_cache.info == cached


def test_an_animated_displace_after_a_subdivision_is_named_as_the_motion_set_aside(bpy_empty, extension, capfd,
                                                                                  tmp_path):
    """A Displace whose strength is keyframed, after a Subdivision (a procedural surface): both are
    set aside while the frames are read (the Subdivision changes the vertex count), so every pose
    read is the mesh at rest. The run says that the motion is in the modifiers set aside and how to
    read it (before: "all the same pose … a baked cache whose files are gone, a simulation outside
    this range", neither of which was the cause). Without the Displace's keyframes the usual
    warning of a still object stays."""
    from blender_scenes import grid_object

    sheet = grid_object(4)
    sheet.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    displace = sheet.modifiers.new("Displace", 'DISPLACE')
    for frame, strength in ((1, 0.0), (9, 0.5)):
        displace.strength = strength
        sheet.keyframe_insert('modifiers["Displace"].strength', frame=frame)
    bpy.context.scene.frame_set(1)
    expected = ("its motion comes from 'Displace', set aside with 'Subdivision' while the frames are read")
    capfd.readouterr()
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                               filepath=str(tmp_path) + "/")
    out = capfd.readouterr().out
    assert expected in out and "a baked cache whose files are gone" not in out
    assert bpy.context.scene.frame_current == 1
    sheet.animation_data_clear()
    displace.strength = 0.5
    bpy.ops.shape_differences.frames_to_shape_keys(frame_start=1, frame_end=9, frame_step=4, output='CACHE',
                                                   filepath=str(tmp_path) + "/")
    out = capfd.readouterr().out
    assert "are all the same pose" in out and "its motion comes from" not in out


def test_an_ocean_making_its_own_grid_is_named(bpy_empty, extension):
    """An Ocean modifier in its default Geometry › Generate replaces the mesh with its own grid,
    and it is the motion itself: the refusal names it and its Displace setting (before: "a modifier
    before the motion … Disable modifiers that add or remove geometry there (Subdivision, …)", which
    the Ocean alone on a plane is not)."""
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    sea = bpy.context.active_object
    ocean = sea.modifiers.new("Ocean", 'OCEAN')
    ocean.resolution = 2
    ocean.time = 1.0
    sea.keyframe_insert('modifiers["Ocean"].time', frame=1)
    ocean.time = 2.0
    sea.keyframe_insert('modifiers["Ocean"].time', frame=9)
    bpy.context.scene.frame_set(1)  # the animated settings as at the current frame
    for operator in (bpy.ops.shape_differences.frames_to_shape_keys,
                     bpy.ops.shape_differences.inbetween_frames):
        fails_without_change(extension.bridge, sea, operator,
                             "the Ocean modifier 'Ocean' makes its own grid .* Set its Geometry to Displace",
                             frame_start=1, frame_end=9, frame_step=4)
