"""Bad selections, settings and meshes: a report that says what is wrong and how to fix it, and
nothing changes (shape keys, vertices, modifiers, animation, current frame)."""

import re
import struct
import warnings

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import (_fcurves, add_key, armature_scene, assert_unchanged, grid_object,  # noqa: E402
                            posed_grid, rolled, snapshot, with_boundary_sliver)


def fails_without_change(bridge, obj, operator, match, **properties):
    """Run ``operator`` and check it raises with a message matching ``match`` and that
    nothing about ``obj`` changed."""
    before = snapshot(bridge, obj)
    with pytest.raises(RuntimeError, match=match) as failure:
        operator(**properties)
    assert "Traceback" not in str(failure.value), "a crash, not a report"
    assert_unchanged(before, snapshot(bridge, obj))


def test_no_active_object(bpy_empty):
    with pytest.raises(RuntimeError, match="active object must be a mesh"):
        bpy.ops.shape_differences.inbetween()


def test_active_object_is_not_a_mesh(bpy_empty):
    bpy.ops.object.empty_add()
    with pytest.raises(RuntimeError, match="active object must be a mesh"):
        bpy.ops.shape_differences.frames_to_shape_keys()


def test_a_collection_instance_is_told_how_to_reach_its_meshes(bpy_empty):
    """An Empty instancing a collection (as linking one makes) shows meshes that are not objects:
    the message says how to make them real."""
    collection = bpy.data.collections.new("Chars")
    collection.objects.link(grid_object(4))
    bpy.context.scene.collection.objects.unlink(collection.objects[0])
    bpy.ops.object.collection_instance_add(collection=collection.name)
    assert bpy.context.active_object.instance_collection == collection
    with pytest.raises(RuntimeError, match=r"must be a mesh \('Chars' is an instance of the collection 'Chars': "
                                           r"make its objects real with Object › Apply › Make Instances Real"):
        bpy.ops.shape_differences.inbetween()


def test_edit_mode(bpy_empty):
    grid_object(4)
    bpy.ops.object.mode_set(mode='EDIT')
    with pytest.raises(RuntimeError, match="Object Mode"):
        bpy.ops.shape_differences.exaggerate()


@pytest.mark.parametrize("operator", ["inbetween", "exaggerate", "reconstruct"])
def test_fewer_than_two_keys(bpy_empty, extension, operator):
    obj = grid_object(4)
    run = getattr(bpy.ops.shape_differences, operator)
    fails_without_change(extension.bridge, obj, run, "has 0 shape keys, needs at least 2")
    obj.shape_key_add(name="Basis")
    fails_without_change(extension.bridge, obj, run, "has 1 shape key, needs at least 2")


def test_unknown_key_names_the_keys_there_are(bpy_empty, extension):
    obj = posed_grid(extension.bridge, 6)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.inbetween,
                         r"no shape key 'Nope' \(for To\); pick one of 'Basis', 'Curl', 'Bend'",
                         key_b="Nope")


def test_same_key_twice(bpy_empty, extension):
    obj = posed_grid(extension.bridge, 6)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.inbetween,
                         "both 'Bend': pick two different", key_a="Bend", key_b="Bend")
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.exaggerate,
                         "both 'Basis'", key="Basis")
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.reconstruct,
                         "is the Basis", key="Basis")


def test_k_larger_than_the_mesh_allows(bpy_empty, extension):
    obj = posed_grid(extension.bridge, 6)
    vertex_count = len(obj.data.vertices)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.inbetween,
                         f"k_M = {vertex_count} is too large .* use at most {vertex_count - 1}",
                         k_m=vertex_count)
    bpy.context.scene.shape_differences.k_m = 10_000
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.reconstruct,
                         "k_M = 10000 is too large")
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.reconstruct,
                         f"k_N = {vertex_count} is too large", k_m=10, k_n=vertex_count)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.reconstruct,
                         "k_N = 12 needs k_M", k_m=0, k_n=12)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.reconstruct,
                         "k_N = 8 must be at least k_M = 10", k_m=10, k_n=8)


def test_too_few_frames(bpy_empty, extension):
    strip = armature_scene()
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.inbetween_frames,
                         "give 1 frame, at least 2", frame_start=3, frame_end=3)
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.frames_to_shape_keys,
                         "starts at 5, after its end at 2", frame_start=5, frame_end=2)


@pytest.mark.parametrize("disabled", ["object", "collection", "excluded"])
@pytest.mark.parametrize("operator", ["inbetween_frames", "retime", "frames_to_shape_keys"])
def test_an_object_disabled_in_viewports_is_refused(bpy_empty, extension, disabled, operator):
    """Blender does not evaluate an object disabled in viewports (or in a disabled or excluded
    collection): every frame would read its rest mesh, a still cache with no error. Refused, nothing
    made or changed; hidden with the eye icon it is evaluated and runs."""
    strip = armature_scene()
    if disabled == "object":
        strip.hide_viewport = True
    else:
        collection = bpy.data.collections.new("Rigged")
        bpy.context.scene.collection.children.link(collection)
        for owner in strip.users_collection:
            owner.objects.unlink(strip)
        collection.objects.link(strip)
        if disabled == "collection":
            collection.hide_viewport = True
        else:
            bpy.context.view_layer.layer_collection.children["Rigged"].exclude = True
    names = set(bpy.data.objects.keys())
    with bpy.context.temp_override(active_object=strip, object=strip, selected_objects=[strip]):
        fails_without_change(extension.bridge, strip, getattr(bpy.ops.shape_differences, operator),
                             "is disabled in viewports", frame_start=1, frame_end=9, frame_step=4,
                             output='SHAPE_KEYS')
    assert set(bpy.data.objects.keys()) == names


def test_an_object_of_another_scene_is_refused_as_such(bpy_empty, extension):
    """Run on an object that is in another scene than the context's: said so (before: "disabled in
    viewports"), nothing changed."""
    strip = armature_scene()
    other = bpy.data.scenes.new("Layout")
    with bpy.context.temp_override(scene=other, active_object=strip, object=strip, selected_objects=[strip]):
        fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.inbetween_frames,
                             "is not in the scene 'Layout'", frame_start=1, frame_end=9, frame_step=4)


@pytest.mark.parametrize("operator", ["inbetween_frames", "retime", "frames_to_shape_keys", "distortion_maps"])
def test_a_cache_modifier_whose_file_is_gone_is_refused(bpy_empty, extension, operator, tmp_path):
    """A Mesh Cache modifier whose PC2 file was moved (or a temporary cache gone after a restart):
    Blender plays the rest mesh at every frame, so every operator reading frames made a still
    result and reported it done. Refused, naming the modifier and the path; nothing changed."""
    import importlib

    from blender_scenes import grid_object

    sheet = grid_object(6)
    rest = extension.bridge.mesh_data.vertex_positions(sheet.data)
    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    path = point_cache.write_pc2(tmp_path / "sim.pc2", np.array([rest + [0.0, 0.0, 0.1 * k] for k in range(9)]),
                                 start=1.0)
    modifier = sheet.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.filepath = 'PC2', str(path)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    path.rename(tmp_path / "moved.pc2")
    names = set(bpy.data.objects.keys())
    options = dict(source='FRAMES', k_m=10, k_n=0) if operator == "distortion_maps" else dict(frame_step=4)
    fails_without_change(extension.bridge, sheet, getattr(bpy.ops.shape_differences, operator),
                         "modifier 'Mesh Cache' of 'Sheet' reads '.*sim.pc2', which does not exist", **options)
    assert set(bpy.data.objects.keys()) == names
    (tmp_path / "moved.pc2").rename(path)  # back in place: it runs
    getattr(bpy.ops.shape_differences, operator)(**options)


def test_an_alembic_cache_whose_file_is_gone_is_refused(bpy_empty, extension, tmp_path):
    """The same for a Mesh Sequence Cache (an Alembic import): refused, naming the file."""
    from blender_scenes import armature_scene

    armature_scene(frames=9)
    bpy.ops.wm.alembic_export(filepath=str(tmp_path / "strip.abc"), start=1, end=9)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.alembic_import(filepath=str(tmp_path / "strip.abc"))
    imported = next(obj for obj in bpy.data.objects if obj.type == 'MESH')
    assert [m.type for m in imported.modifiers] == ['MESH_SEQUENCE_CACHE']
    bpy.context.view_layer.objects.active = imported
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    (tmp_path / "strip.abc").rename(tmp_path / "moved.abc")
    fails_without_change(extension.bridge, imported, bpy.ops.shape_differences.frames_to_shape_keys,
                         "reads '.*strip.abc', which does not exist", frame_step=4, output='SHAPE_KEYS')


def test_an_object_hidden_with_the_eye_icon_runs(bpy_empty, extension):
    strip = armature_scene()
    strip.hide_set(True)
    with bpy.context.temp_override(active_object=strip, object=strip, selected_objects=[strip]):
        bpy.ops.shape_differences.frames_to_shape_keys(frame_start=1, frame_end=9, frame_step=4,
                                                       output='SHAPE_KEYS')
    key = strip.data.shape_keys.key_blocks["Frame 9"]
    assert np.abs(extension.bridge.mesh_data.stored_key_positions(key) - extension.bridge.mesh_data.vertex_positions(strip.data)).max() > 0.1


def test_a_range_that_starts_after_its_end(bpy_empty, extension):
    source = armature_scene(frames=9)
    fails_without_change(extension.bridge, source, bpy.ops.shape_differences.retime,
                         "starts at 9, after its end at 1: swap Start and End", frame_start=9, frame_end=1)


@pytest.mark.parametrize("operator, properties", [("inbetween_frames", {}), ("shape_space", dict(source='FRAMES'))])
def test_a_step_past_blenders_frames_is_told_to_be_smaller(bpy_empty, extension, operator, properties):
    """Frames 1–9 with Step 2³¹−1 give one frame: the only remedy is a smaller step, as no range of
    Blender's frames is that long (before: "widen the frame range or lower the step")."""
    source = armature_scene(frames=9)
    fails_without_change(extension.bridge, source, getattr(bpy.ops.shape_differences, operator),
                         r"^Error: Frames 1 to 9 with step 2147483647 give 1 frame, at least 2 are needed: use a "
                         r"step of at most 8$", frame_start=1, frame_end=9, frame_step=2**31 - 1, **properties)


@pytest.mark.parametrize("operator", ["inbetween", "inbetween_frames"])
def test_count_zero_is_an_error(bpy_empty, extension, operator):
    obj = posed_grid(extension.bridge, 5)
    fails_without_change(extension.bridge, obj, getattr(bpy.ops.shape_differences, operator),
                         "Count is 0: ask for at least 1", count=0)


@pytest.mark.parametrize("properties, match", [
    (dict(speed=0.0), r"Speed = 0 must be positive: 0\.5 plays the motion twice as slow, 2 twice as fast"),
    (dict(speed=-1.0), r"Speed = -1 must be positive: 0\.5 plays the motion twice as slow"),
    (dict(frame_start=1, frame_end=4, frame_step=4),
     r"4 frames with step 4 give fewer than two key poses: use a step of at most 3 or at least 5 frames\.$"),
    # a step past Blender's frames: the only remedy is a smaller step (before: "use at least 2147483648 frames")
    (dict(frame_start=1, frame_end=4, frame_step=2**31 - 1),
     r"4 frames with step 2147483647 give fewer than two key poses: use a step of at most 3\.$"),
])
def test_retime_settings_it_cannot_use(bpy_empty, extension, core, properties, match):
    strip = armature_scene(frames=5)
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.retime, match,
                         **properties)


@pytest.mark.parametrize("speed", [100.0, float("inf")])
def test_retime_to_fewer_than_two_frames_is_refused(bpy_empty, extension, core, speed, tmp_path):
    """Frames 1–9 at speed 100, or at an infinite speed (Blender keeps the largest float32,
    3.4e38), play the first frame alone: refused with the largest speed that plays two, nothing
    added or written (before, a one-pose "retime" object was added, at infinite speed named
    "Grid Retime 340282349999999991754788743781432688640.00x step 4")."""
    strip = armature_scene(frames=9)
    objects = set(bpy.data.objects.keys())
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.retime,
                         r"Speed [0-9.e+]+ over 9 frames gives one output frame \(the first\), and a retime "
                         "needs at least two: use a speed of at most 8 ", frame_start=1, frame_end=9,
                         frame_step=4, speed=speed, filepath=str(tmp_path) + "/")
    assert set(bpy.data.objects.keys()) == objects and not list(tmp_path.iterdir())


@pytest.mark.parametrize("special", ["named pipe", "null device"])
def test_a_cache_file_that_is_a_device_or_special_file_is_refused(bpy_empty, extension, special, tmp_path):
    """A Cache File that exists and is neither a file nor a folder (``/dev/null``, a named pipe)
    is refused before any work, nothing written (before, ``.pc2`` was added to its name and the
    cache written beside it: ``/dev/null.pc2``)."""
    import os

    if not hasattr(os, "mkfifo"):
        pytest.skip("named pipes and /dev/null are POSIX")
    if special == "named pipe":
        path = str(tmp_path / "pipe")
        os.mkfifo(path)
    else:
        path = "/dev/null"
    folder = os.path.dirname(path)
    before = set(os.listdir(folder))
    strip = armature_scene(frames=9)
    try:
        fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.retime,
                             f"The Cache File '{path}' is a device or special file, not a file or folder",
                             frame_step=4, speed=0.5, filepath=path)
    finally:
        # the cache the old behaviour wrote beside it (null.pc2, null.001.pc2): not left in /dev
        written = {name for name in set(os.listdir(folder)) - before if name.startswith(os.path.basename(path))}
        for name in written:
            os.remove(os.path.join(folder, name))
    assert not written


def test_relative_cache_file_without_a_saved_blend(bpy_empty, extension):
    strip = armature_scene(frames=5)
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.retime,
                         "relative to the .blend, which is not saved yet", filepath="//cache.pc2")


@pytest.mark.skipif(__import__("os").name == "nt", reason="a Windows path is a path there")
@pytest.mark.parametrize("filepath, named", [("C:\\shots\\caches\\", "a Windows path, which this system reads as "
                                                                       "the name of a file in the .blend's folder"),
                                             ("~no_such_user_here/x.pc2", "a user this machine does not have")])
def test_a_cache_file_of_another_machine_is_refused(bpy_empty, extension, tmp_path, filepath, named):
    """A Windows path on Linux or macOS (a sidebar's Cache File saved with the .blend on a Windows
    workstation, a script written there) and a `~user` of no user are names inside the .blend's
    folder there: refused before any work, nothing written (before: a folder `C:\\shots\\caches\\`
    beside the .blend, and a new object playing it)."""
    strip = armature_scene(frames=5)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.retime, re.escape(named),
                         filepath=filepath)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shot.blend"]
    assert len(bpy.data.objects) == 2


def test_mesh_without_faces(bpy_empty, extension):
    obj = posed_grid(extension.bridge, 5)
    bpy.ops.object.mode_set(mode='EDIT')
    bpy.ops.mesh.select_all(action='SELECT')
    bpy.ops.mesh.delete(type='ONLY_FACE')
    bpy.ops.object.mode_set(mode='OBJECT')
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.inbetween,
                         "has no faces")


def test_an_object_whose_faces_its_modifiers_make_is_told_so(bpy_empty, extension):
    """A Geometry Nodes modifier realizing cubes on a mesh of one point shows faces its mesh does
    not have: the refusal names the modifier and how to get a mesh the poses move."""
    mesh = bpy.data.meshes.new("point")
    mesh.from_pydata([(0.0, 0.0, 0.0)], [], [])
    obj = bpy.data.objects.new("shatter", mesh)
    bpy.context.collection.objects.link(obj)
    tree = bpy.data.node_groups.new("cubes", 'GeometryNodeTree')
    tree.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    cube, out = tree.nodes.new('GeometryNodeMeshCube'), tree.nodes.new('NodeGroupOutput')
    tree.links.new(cube.outputs["Mesh"], out.inputs[0])
    obj.modifiers.new("Shatter", 'NODES').node_group = tree
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    assert len(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.polygons) == 6
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.inbetween_frames,
                         re.escape("has no faces of its own (those shown are made by its modifier 'Shatter')"))


def test_a_cache_whose_topology_changes(bpy_empty, extension, tmp_path):
    """An Alembic cache of a mesh that loses faces over time (a Build modifier, reversed, when it
    was exported): the report says the cache's vertex count changes, at which frame (the first read
    after the Build starts at 5), and that a fixed topology or another frame range is needed;
    nothing changes."""
    obj = grid_object(10)
    obj.modifiers.new("Wave", 'WAVE')
    build = obj.modifiers.new("Build", 'BUILD')
    build.frame_start, build.frame_duration, build.use_reverse = 5, 30, True
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 33
    path = str(tmp_path / "shrinking.abc")
    bpy.ops.wm.alembic_export(filepath=path, start=1, end=33)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 33
    bpy.ops.wm.alembic_import(filepath=path, as_background_job=False)
    imported = [o for o in bpy.data.objects if o.type == 'MESH'][0]
    bpy.context.view_layer.objects.active = imported
    imported.select_set(True)
    fails_without_change(extension.bridge, imported, bpy.ops.shape_differences.inbetween_frames,
                         r"At frame 9 the mesh cache .* of 'Sheet' \(.*shrinking\.abc\) has \d+ vertices "
                         r"instead of 121: its topology changes over time", frame_step=4, output='CACHE')


def test_degenerate_pose(bpy_empty, extension, core):
    obj = posed_grid(extension.bridge, 6)
    flat = extension.bridge.mesh_data.stored_key_positions(obj.data.shape_keys.key_blocks["Basis"])
    flat[:, 0] = 0.0  # the flat sheet squashed onto a line: every triangle has zero area
    add_key(obj, "Collapsed", flat)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.inbetween,
                         "shape key 'Collapsed': .*zero area .* Degenerate Dissolve", key_b="Collapsed")
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.inbetween,
                         "shape key 'Collapsed': .*zero area", key_a="Collapsed", key_b="Bend")
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.reconstruct,
                         "shape key 'Collapsed': .*zero area", key="Collapsed")


def test_reconstruct_names_the_shape_key_of_a_broken_pose(bpy_empty, extension):
    """Reconstruct's messages name the shape key, as the other operators' do (before: "target
    vertices", "base vertices"), and the remedy is said of it (the core's "remove that frame" is
    said of the frames and arrays it is given)."""
    obj = posed_grid(extension.bridge, 6)
    broken = extension.bridge.mesh_data.stored_key_positions(obj.data.shape_keys.key_blocks["Bend"])
    broken[3, 0] = np.nan
    add_key(obj, "Broken Pose", broken)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.reconstruct,
                         r"shape key 'Broken Pose': vertex 3 has a non-finite coordinate .* or remove shape key "
                         r"'Broken Pose'\.$", key="Broken Pose")
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.distortion_maps,  # checked before the core
                         r"shape key 'Broken Pose' of 'Sheet': vertex 3 .* or remove shape key 'Broken Pose'\.$",
                         key="Broken Pose")


@pytest.mark.parametrize("operator", ["reconstruct", "shape_space"])
def test_a_negative_scene_offset_is_named_as_the_scenes(bpy_empty, extension, operator):
    """The scene's Offset t, taken where the operator's is not set, negative: refused as the scene's
    setting (the core said "Use None for the automatic distance", which no setting can be). The
    in-betweens, which have no offset, do not read it."""
    obj = posed_grid(extension.bridge, 6)
    bpy.context.scene.shape_differences.offset = -0.1
    fails_without_change(extension.bridge, obj, getattr(bpy.ops.shape_differences, operator),
                         r"Offset t \(the scene's, in the sidebar's Shape Diff tab\) = -0.1 must be positive, or 0 "
                         "for the automatic distance")


@pytest.mark.parametrize("setting, value, match", [
    ("k_m", -5, r"k_M \(the scene's, in the sidebar's Shape Diff tab\) = -5 must be 0 for the full basis, or a "
                r"positive number of eigenfunctions"),
    ("k_n", -5, r"k_N \(the scene's, in the sidebar's Shape Diff tab\) = -5 must be 0 for the target not "
                r"truncated")])
def test_a_negative_scene_basis_size_is_named_as_the_scenes(bpy_empty, extension, setting, value, match):
    """The scene's k_M or k_N, taken where the operator's is not set, negative: refused as the scene's
    setting (the core said "0 / None (full basis)", its terms for scripts; a negative k_N alone was
    told it "needs k_M")."""
    obj = posed_grid(extension.bridge, 6)
    setattr(bpy.context.scene.shape_differences, setting, value)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.inbetween, match)


def _sheet_with_an_ngon(n: int, cells: set, offset: float):
    """An n × n grid of quads (slightly wavy) whose ``cells`` are one n-gon keeping every grid
    corner on its boundary (collinear corners, as Dissolve Faces leaves them), ``offset`` along x."""
    def vid(i, j):
        return j * n + i
    verts = [(2 * i / (n - 1) - 1 + offset, 2 * j / (n - 1) - 1, 0.05 * np.sin(3 * i / n))
             for j in range(n) for i in range(n)]
    faces = [(vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1))
             for j in range(n - 1) for i in range(n - 1) if (i, j) not in cells]
    boundary = {}
    for i, j in cells:
        for a, b in ((vid(i, j), vid(i + 1, j)), (vid(i + 1, j), vid(i + 1, j + 1)),
                     (vid(i + 1, j + 1), vid(i, j + 1)), (vid(i, j + 1), vid(i, j))):
            if boundary.pop((b, a), None) is None:
                boundary[(a, b)] = True
    following = dict(boundary)  # (a, b) → True: each boundary vertex's next one
    following = {a: b for a, b in following}
    loop = [next(iter(following))]
    while following[loop[-1]] != loop[0]:
        loop.append(following[loop[-1]])
    faces.append(tuple(loop))
    return verts, faces


SQUARE = {(i, j) for i in range(4, 7) for j in range(4, 7)}


@pytest.mark.parametrize("cells", [SQUARE, SQUARE - {(5, 5), (5, 6)}], ids=["square", "U-shaped"])
@pytest.mark.parametrize("offset", [0.0, 1e5])
def test_an_ngon_with_collinear_corners_far_from_the_origin(bpy_empty, extension, offset, cells):
    """A sheet whose middle is one n-gon with several corners on each straight side (as Dissolve
    Faces leaves it), 1e5 units out: Blender's loop triangles cut zero-area ears there, which were
    refused as degenerate faces the mesh does not have ("Degenerate Dissolve" did not help); the
    n-gon is triangulated again about its centre (a concave one too: its triangles cover it once,
    where a face normal left uncomputed folded them over each other) and the in-between is the
    rigid lift's."""
    import bmesh

    verts, faces = _sheet_with_an_ngon(12, cells, offset)
    mesh = bpy.data.meshes.new("Ngon")
    mesh.from_pydata(verts, [], faces)
    bm = bmesh.new()
    bm.from_mesh(mesh)
    bmesh.ops.delete(bm, geom=[v for v in bm.verts if not v.link_faces], context='VERTS')
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new("Ngon", mesh)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    rest = extension.bridge.mesh_data.vertex_positions(mesh)
    add_key(obj, "Lifted", rest + [0.0, 0.0, 0.5])
    triangles = extension.bridge.triangulation.mesh_triangles(mesh)
    polygons = extension.bridge.triangulation.loop_triangle_polygons(mesh)
    corners = rest[triangles] - rest.mean(axis=0)
    vector_areas = 0.5 * np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    ngon = len(mesh.polygons) - 1
    ring = rest[list(mesh.polygons[ngon].vertices)] - rest.mean(axis=0)
    face_area = 0.5 * np.cross(ring, np.roll(ring, -1, axis=0)).sum(axis=0)  # Newell
    own = vector_areas[polygons == ngon]
    assert (own @ face_area > 0).all()  # all facing the face's way ...
    # ... once (folded over itself: 70 % more; the wavy face is not flat, a few 1e-3 more)
    assert np.linalg.norm(own, axis=1).sum() == pytest.approx(np.linalg.norm(face_area), rel=1e-2)
    bpy.ops.shape_differences.inbetween(key_a="Basis", key_b="Lifted", count=1, output='SHAPE_KEYS')
    middle = extension.bridge.mesh_data.stored_key_positions(obj.data.shape_keys.key_blocks[-1])
    tolerance = 2 * np.spacing(np.float32(offset + 1.0)) + 1e-6  # single-precision keys
    assert np.abs(middle - (rest + [0.0, 0.0, 0.25])).max() <= tolerance


@pytest.mark.parametrize("cells", [SQUARE, SQUARE - {(5, 5), (5, 6)}], ids=["square", "U-shaped"])
def test_an_ngon_whose_straight_sides_single_precision_bends(bpy_empty, extension, core, cells):
    """The n-gon sheet turned about a general axis, stored in single precision as Blender stores it:
    its n-gon's straight sides are rounded just off their lines, and Blender's loop triangles cut
    ears between those corners, 1e-9–1e-8 high against their 0.2–0.5 sides, which a key moved
    along the sheet's normal rounded onto one line: the sequence was refused as having a degenerate
    face, to be dissolved (Degenerate Dissolve leaves such a face as it is). The n-gon is
    triangulated again, no triangle is less high than twice the coordinates' rounding (the core's
    ``sliver`` warning), and the sequence lifting the sheet is that lift, without that warning."""
    verts, faces = _sheet_with_an_ngon(12, cells, 0.0)
    axis = np.array([0.3, -0.5, 0.7]) / np.linalg.norm([0.3, -0.5, 0.7])
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    turn = np.eye(3) + np.sin(0.9) * cross + (1.0 - np.cos(0.9)) * cross @ cross  # Rodrigues
    mesh = bpy.data.meshes.new("Ngon")
    mesh.from_pydata([tuple(turn @ v) for v in np.array(verts)], [], faces)
    rest = extension.bridge.mesh_data.vertex_positions(mesh)
    triangles = extension.bridge.triangulation.mesh_triangles(mesh)
    corners = rest[triangles]
    doubled = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    longest = np.max([np.linalg.norm(corners[:, a] - corners[:, b], axis=1) for a, b in ((0, 1), (1, 2), (2, 0))],
                     axis=0)
    rounding = np.finfo(np.float32).eps * np.abs(rest).max()
    assert (doubled / longest > 2 * rounding).all()  # the core's sliver height (core.rounded_slivers)
    keys = [(rest + turn @ [0.0, 0.0, lift]).astype(np.float32).astype(np.float64) for lift in (0.0, 0.5, 1.0, 1.5)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        middle = core.SequenceInterpolator(keys, triangles).pose(1, 0.5)  # a gap between two others
    assert not [str(w.message) for w in caught if "rounding" in str(w.message)]
    assert np.abs(middle - 0.5 * (keys[1] + keys[2])).max() <= 1e-6


@pytest.mark.parametrize("cells", [SQUARE, SQUARE - {(5, 5), (5, 6)}], ids=["square", "U-shaped"])
def test_an_ngon_with_collinear_corners_on_a_narrow_strip_far_from_the_origin(bpy_empty, extension, core, cells):
    """The n-gon sheet squashed to a strip 0.2 wide, 1e5 units out: Blender's loop triangles cut
    zero-area ears, and every triangulation of the n-gon has triangles less high than twice the
    coordinates' rounding (0.024 there). Beauty's has none of zero area: it is taken, and the
    sequence lifting the strip is that lift, where keeping Blender's refused the sequence as having
    a degenerate face (a zero-area ear was kept unless Beauty left no sliver)."""
    verts, faces = _sheet_with_an_ngon(12, cells, 0.0)
    mesh = bpy.data.meshes.new("Strip")
    mesh.from_pydata([tuple(v) for v in np.array(verts) * [1.0, 0.1, 1.0] + [1e5, 0.0, 0.0]], [], faces)
    rest = extension.bridge.mesh_data.vertex_positions(mesh)
    triangles = extension.bridge.triangulation.mesh_triangles(mesh)
    corners = rest[triangles]
    doubled = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    longest = np.max([np.sum((corners[:, a] - corners[:, b]) ** 2, axis=1) for a, b in ((0, 1), (1, 2), (2, 0))],
                     axis=0)
    assert (doubled > core.mesh_topology.DEGENERATE_TRIANGLE_RATIO * longest).all()  # the core's degenerate test
    keys = [rest + [0.0, 0.0, lift] for lift in (0.0, 0.5, 1.0, 1.5)]
    middle = core.SequenceInterpolator(keys, triangles).pose(1, 0.5)  # a gap between two others
    assert np.abs(middle - 0.5 * (keys[1] + keys[2])).max() <= 2 * np.spacing(np.float32(1e5))


def test_the_sliver_bound_of_quads_and_ngons(bpy_empty, extension):
    """``_sliver_bound``, which spares the n-gons no triangulation could rid of slivers a rebuild:
    per polygon it is at least the least height of its loop triangles and of every fan about one of
    its corners (triangulations that cover it), and a quad's is the higher of its two splits'."""
    triangulation = extension.bridge.triangulation
    verts, faces = _sheet_with_an_ngon(12, SQUARE - {(5, 5), (5, 6)}, 0.0)  # quads and a concave n-gon
    mesh = bpy.data.meshes.new("Sheet")
    mesh.from_pydata(verts, [], faces)
    positions = triangulation.vertex_positions(mesh)
    mesh.calc_loop_triangles()
    buffer = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", buffer)
    triangles = buffer.reshape(-1, 3).astype(np.int64)
    polygons = triangulation.loop_triangle_polygons(mesh)
    chosen = np.arange(len(mesh.polygons))
    bound = triangulation._sliver_bound(mesh, positions, triangles, polygons, chosen)

    def least_height(rows):
        a, b, c = (positions[rows[:, k]] for k in range(3))
        longest = np.max([np.linalg.norm(p - q, axis=1) for p, q in ((a, b), (b, c), (c, a))], axis=0)
        return (np.linalg.norm(np.cross(b - a, c - a), axis=1) / longest).min()

    for polygon in chosen:
        ring = np.array(mesh.polygons[polygon].vertices)
        assert bound[polygon] >= least_height(triangles[polygons == polygon]) * (1 - 1e-12)
        fans = [np.array([[ring[k], ring[(k + i) % len(ring)], ring[(k + i + 1) % len(ring)]]
                          for i in range(1, len(ring) - 1)]) for k in range(len(ring))]
        if len(ring) == 4:
            assert bound[polygon] == pytest.approx(max(least_height(fan) for fan in fans[:2]), rel=1e-12)
        for fan in fans:
            if triangulation._covers(positions, fan, triangles[polygons == polygon]):
                assert bound[polygon] >= least_height(fan) * (1 - 1e-12)


def test_non_manifold_mesh(bpy_empty, extension, core):
    """Three triangles sharing one edge: core rejects the mesh, the operator reports it."""
    mesh = bpy.data.meshes.new("Fin")
    vertices = [(0, 0, 0), (1, 0, 0), (0.5, 1, 0), (0.5, -1, 0), (0.5, 0, 1)]
    mesh.from_pydata(vertices, [], [(0, 1, 2), (1, 0, 3), (0, 1, 4)])
    obj = bpy.data.objects.new("Fin", mesh)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    add_key(obj, "Moved", np.array(vertices) * 1.1)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.exaggerate,
                         "manifold")


def test_messages_about_triangles_of_quads_name_their_faces(bpy_empty, extension):
    """A quad grid with one face flipped: the core's triangle numbers are Blender's loop triangles,
    which no editor shows; the message names the faces too (Indices overlay), here face 10."""
    obj = posed_grid(extension.bridge, 6)
    obj.data.polygons[10].flip()
    obj.data.update()
    triangles = extension.bridge.triangulation.mesh_triangles(obj.data)
    faces = extension.bridge.triangulation.loop_triangle_polygons(obj.data)
    assert len(triangles) == 2 * len(obj.data.polygons)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.exaggerate,
                         r"[Tt]riangles \d+ and \d+ .*\(of faces (10 and \d+|\d+ and 10)\)")
    assert 10 in faces


@pytest.mark.parametrize("with_keys", [False, True], ids=["no keys yet", "existing keys"])
def test_writing_is_all_or_nothing(bpy_empty, extension, with_keys):
    """If writing fails half-way, the keys written so far (and a Basis made for them) go."""
    bridge = extension.bridge
    obj = posed_grid(bridge, 5) if with_keys else grid_object(5)
    before = snapshot(bridge, obj)
    good = bridge.mesh_data.vertex_positions(obj.data)
    new_keys = [bridge.shape_keys.NewShapeKey("Good", good), bridge.shape_keys.NewShapeKey("Wrong size", good[:-1])]
    with pytest.raises((RuntimeError, TypeError, ValueError)):
        bridge.shape_keys.add_shape_keys(obj, new_keys, keyframes=[1, 2])
    assert (obj.data.shape_keys is not None) == with_keys
    assert_unchanged(before, snapshot(bridge, obj))


def test_outputs_too_large_are_refused_before_any_work(bpy_empty, extension, core, monkeypatch):
    """A retime slower than Blender can play (speed 1e-7: 80 million frames), an output larger
    than half the memory available (In-between Frames asked for 100,000 in-betweens per gap), or a
    mesh whose in-betweens need more memory than there is, is refused before any frame is read:
    before, the first filled the memory until the system killed Blender and the second ran for
    hours holding every pose."""
    import importlib

    from blender_scenes import armature_scene

    strip = armature_scene(frames=9)
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.retime,
                         "gives 80,000,00[01] output frames, more than 1,048,574", frame_step=4, speed=1e-7)
    monkeypatch.setattr(importlib.import_module(core.__name__ + ".resources"), "available_memory", lambda: 10**8)
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.inbetween_frames,
                         "The output is 200,003 poses of .* GB of memory available: lower In-betweens",
                         frame_step=4, count=100_000)
    # a mesh whose in-betweens need more memory than there is (12 kB per vertex)
    monkeypatch.setattr(importlib.import_module(core.__name__ + ".resources"), "available_memory",
                        lambda: 12_000 * len(strip.data.vertices) - 1)
    for operator in (bpy.ops.shape_differences.inbetween_frames, bpy.ops.shape_differences.retime):
        fails_without_change(extension.bridge, strip, operator,
                             f"In-betweening this mesh \\({len(strip.data.vertices)} vertices\\) needs about",
                             frame_step=4)


def test_operators_count_the_largest_gaps_in_betweens_beside_the_output(bpy_empty, extension, core, monkeypatch):
    """In-between Frames (100 in-betweens per gap) and Retime (speed 0.04: 99 in-betweens in a gap)
    hold the output poses and, while a gap is made, its in-betweens (54 bytes per vertex each) at
    once: refused before any work where the two together pass half the memory available, as the
    command's retime counts them (before, each passed its own check, the output's up front and the
    batch's in SequenceInterpolator.poses, and the job ran past half the memory)."""
    import importlib

    resources = importlib.import_module(core.__name__ + ".resources")
    validation = importlib.import_module(core.__name__ + ".validation")
    retime = importlib.import_module(core.__name__ + ".retime")
    strip = armature_scene(frames=9)
    n = len(strip.data.vertices)
    free = validation.WORKING_BYTES_PER_VERTEX * n  # just enough for the sequence's own work
    monkeypatch.setattr(resources, "available_memory", lambda: free)
    plan = retime.plan_retime(9, 4, 0.04)
    for operator, n_out, batch, properties, match in (
            (bpy.ops.shape_differences.inbetween_frames, 3 + 2 * 100, 100, {"count": 100}, "The output is 203 poses"),
            (bpy.ops.shape_differences.retime, plan.n_out, plan.batch(range(plan.n_gaps)), {"speed": 0.04},
             f"Retime at speed .* is {plan.n_out} poses")):
        output, working = n_out * n * 12, batch * n * validation.INBETWEEN_BYTES_PER_VERTEX
        # each alone within half the memory, the two together past it
        assert max(output, working) <= validation.OUTPUT_MEMORY_SHARE * free < output + working
        fails_without_change(extension.bridge, strip, operator,
                             f"{match} of {n} vertices, .* GB, .* GB of it its in-betweens while they are made",
                             frame_step=4, **properties)


def test_two_pose_captured_and_transferred_outputs_too_large_are_refused_before_any_work(bpy_empty, extension,
                                                                                          core, monkeypatch):
    """The In-between of two shape keys asked for 2,147,483,647 in-betweens (Count's largest: before,
    it built their factors one property read at a time, in one step that Esc does not interrupt, then
    filled the memory until the system killed Blender), In-between, Exaggerate and Reconstruct on a
    mesh whose computation needs more memory than there is, and Frames to Shape Keys and a Transfer of
    frames whose poses would take over half of it: refused before any work, nothing changed."""
    import importlib

    resources = importlib.import_module(core.__name__ + ".resources")
    validation = importlib.import_module(core.__name__ + ".validation")
    bridge = extension.bridge
    sheet = posed_grid(bridge, 8)
    n = len(sheet.data.vertices)
    monkeypatch.setattr(resources, "available_memory", lambda: 10**9)
    fails_without_change(bridge, sheet, bpy.ops.shape_differences.inbetween,
                         f"The output is 2,147,483,647 poses of {n} vertices, .* GB of memory available: lower Count",
                         count=2**31 - 1)
    for operator, work, per_vertex in (
            (bpy.ops.shape_differences.inbetween, "In-betweening", validation.PAIR_WORKING_BYTES_PER_VERTEX),
            (bpy.ops.shape_differences.exaggerate, "In-betweening", validation.PAIR_WORKING_BYTES_PER_VERTEX),
            (bpy.ops.shape_differences.reconstruct, "Rebuilding a pose of",
             validation.RECONSTRUCT_WORKING_BYTES_PER_VERTEX)):
        monkeypatch.setattr(resources, "available_memory", lambda: per_vertex * n - 1)
        fails_without_change(bridge, sheet, operator, f"{work} this mesh \\({n} vertices\\) needs about")
    # 9 frames of the strip: refused where they would take over half the memory available
    bpy.ops.wm.read_homefile(use_empty=True)
    strip = armature_scene(frames=9)
    need = 9 * len(strip.data.vertices) * 12
    monkeypatch.setattr(resources, "available_memory", lambda: 2 * need - 1)
    fails_without_change(bridge, strip, bpy.ops.shape_differences.frames_to_shape_keys,
                         f"The output is 9 poses of {len(strip.data.vertices)} vertices, .* raise Step")
    target = grid_object(4, name="Target")
    strip.select_set(True)
    bpy.context.view_layer.objects.active = target
    fails_without_change(bridge, target, bpy.ops.shape_differences.transfer_poses,
                         f"The output is 9 poses of {len(strip.data.vertices)} vertices, .* raise Step",
                         source='FRAMES')
    monkeypatch.setattr(resources, "available_memory", lambda: 2 * need)  # just enough: it runs
    bpy.ops.shape_differences.frames_to_shape_keys(output='CACHE')
    assert len(bpy.data.objects) == 4


def test_maps_of_more_frames_than_memory_holds_are_refused_before_any_work(bpy_empty, extension, core, monkeypatch):
    """Maps of Frames writes some 200 bytes of attributes per vertex and frame (measured with the
    poses' maps held until written: 444 on a 2,601-vertex sheet, a 54 MB .blend from 250 frames at
    the default Step 1): over half the memory available, refused before a frame is read (before, it
    ran to the end or until the system killed Blender)."""
    import importlib

    strip = armature_scene(frames=9)
    monkeypatch.setattr(importlib.import_module(core.__name__ + ".resources"), "available_memory", lambda: 10**5)
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.distortion_maps,
                         f"The output of Maps of Frames is 9 poses of {len(strip.data.vertices)} vertices, .* raise Step",
                         source='FRAMES')
    assert not [a.name for a in strip.data.attributes if a.name.startswith(("SD ", "sd_"))]


@pytest.mark.parametrize("lost, names_known", [(range(1, 10), True), (range(6, 10), True), (range(1, 9), True),
                                                (range(4, 7), True), (range(6, 10), False), (range(1, 9), False)])
def test_a_disk_bake_whose_files_are_gone_is_refused(bpy_empty, extension, tmp_path, monkeypatch, lost, names_known):
    """A cloth baked to a disk cache whose files are gone (the .blend moved, or sent to a farm,
    without its blendcache folder): Blender plays the rest mesh at every frame, "baked", 0 frames on
    disk. Refused, naming the folder Blender looks in, and nothing written (before: a still
    sheet's in-betweens written with a warning, and a batch exited 0: a farm saw success). A folder
    copied without the files of frames 6–9, 1–8 or 4–6 (a copy cut short, or with gaps): Blender
    holds the nearest frame it finds over them, or interpolates between two; refused too, naming
    the frames read without a file (before: written without a word; a retime of a 41-frame bake
    without frames 21–41 came up to 0.56 off on a sheet 2 wide, without 1–10 0.37, without 10–15
    0.075). Where the files stop before the frames lacking them (6–9), Blender holds the last one
    over them and the message says so, with the range that has files. Where the files' names are not known (``names_known=False``: another Blender's naming),
    frames read in a row with the same pose to the bit tell a hold."""
    import re

    from blender_scenes import grid_object

    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 9
    cloth = grid_object(6, name="Cloth")
    cloth.location.z = 1.0
    modifier = cloth.modifiers.new("Cloth", 'CLOTH')
    modifier.point_cache.frame_start, modifier.point_cache.frame_end = 1, 9
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    modifier.point_cache.use_disk_cache = True
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    bpy.ops.wm.save_mainfile()
    folder = tmp_path / "blendcache_shot"
    files = [path for path in folder.iterdir() if int(path.stem.split("_")[1]) in lost]
    assert len(files) == len(lost)  # one file per frame, named <object>_<frame>_<index>.bphys
    for path in files:
        path.unlink()
    if not names_known:
        monkeypatch.setattr(extension.bridge.frame_checks, "bake_frames_on_disk", lambda *args: None)
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "shot.blend"))
    cloth = bpy.data.objects["Cloth"]
    objects = set(bpy.data.objects)
    # the keys, and frames 3 and 7 in the middle of the first and last gaps (how the motion starts and ends)
    read = [frame for frame in (1, 3, 5, 7, 9) if frame in lost]
    cache = f"'Cloth' is baked to disk over frames 1–9 (its cache: '{9 - len(lost)} frames on disk.')"
    if len(lost) == 9:
        said = f"Blender finds none of the bake's files in '{folder}'"
    elif names_known and lost.stop == 10:  # the files stop at frame 5: Blender holds it after
        said = (f"'Cloth': its modifier {cache}, but '{folder}' holds its files up to frame 5 only, and 2 of the 5 "
                "frames read there come after it (7, 9): Blender holds frame 5 over them")
    elif names_known:
        said = (f"'Cloth': its modifier {cache}, but '{folder}' holds no file for {len(read)} of the 5 frames read "
                f"there ({', '.join(map(str, read))}): Blender plays them interpolated between the files it finds")
    else:
        said = ("reads the same pose, to the bit, at "
                + ("3 frames read in a row inside its bake (frames 5–9)" if lost.start == 6 else
                   "4 frames read in a row inside its bake (frames 3–9)")
                + f" while other frames move, though its modifier {cache}: Blender finds a file of the bake in "
                f"'{folder}' for one of those frames at most")
    with bpy.context.temp_override(active_object=cloth, object=cloth, selected_objects=[cloth]):
        with pytest.raises(RuntimeError, match=re.escape(said)):
            bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path) + "/")
    assert set(bpy.data.objects) == objects
    assert sorted(path.name for path in tmp_path.iterdir()) == ["blendcache_shot", "shot.blend", "shot.blend1"]


def test_a_bake_from_a_cache_played_part_of_the_way_is_said_to_end_there(bpy_empty, extension, tmp_path):
    """A cloth simulated over 1–17, played to frame 9 and baked to disk from that cache (Current
    Cache to Bake): its bake holds frames 1–9, and Blender holds frame 9 over 10–17, as after a
    simulation's end. In-between Frames over 1–17 is refused as a copy cut short is (the folder
    cannot tell them apart), but saying where the files stop and to end the range there (before:
    'Copy the whole cache folder', which is whole); over 1–9 it runs."""
    import re

    from blender_scenes import pinned_cloth_scene

    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    cloth = pinned_cloth_scene(frames=17)
    cache = cloth.modifiers["Cloth"].point_cache
    cache.use_disk_cache = True
    for frame in range(1, 10):
        bpy.context.scene.frame_set(frame)
    with bpy.context.temp_override(scene=bpy.context.scene, point_cache=cache):
        bpy.ops.ptcache.bake_from_cache()
    assert cache.is_baked and cache.info == "9 frames on disk."
    played = dict(extension.bridge.frame_reading.frame_positions(bpy.context, cloth, [9, 17]))
    np.testing.assert_array_equal(played[17], played[9])  # what the message says: frame 9, held
    folder = tmp_path / "blendcache_shot"
    with bpy.context.temp_override(active_object=cloth, object=cloth, selected_objects=[cloth]):
        with pytest.raises(RuntimeError, match=re.escape(
                f"'{folder}' holds its files up to frame 9 only, and 3 of the 7 frames read there come after it "
                "(13, 15, 17): Blender holds frame 9 over them (a bake made with Current Cache to Bake from a cache "
                "played to frame 9, or a copy of the folder cut short?). End the frame range at frame 9")):
            bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=17, frame_step=4, count=1,
                                                       filepath=str(tmp_path / "whole.pc2"))
        bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                                   filepath=str(tmp_path / "baked.pc2"))
    assert (tmp_path / "baked.pc2").is_file() and not (tmp_path / "whole.pc2").exists()


def test_a_cloth_renamed_after_its_disk_bake_is_told_by_the_name_its_files_keep(bpy_empty, extension, tmp_path):
    """A cloth 'Flag' baked to disk, then renamed 'Cape' (its files keep the old name in hex; Blender
    looks for the new one's, finds none and plays the rest mesh): refused as a
    lost bake is, naming the name the files are under and to name the object so again (before:
    'Copy the cache folder with the .blend', which is there); named 'Flag' again, it runs."""
    import re

    from blender_scenes import pinned_cloth_scene

    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    cloth = pinned_cloth_scene(frames=9)
    cloth.modifiers["Cloth"].point_cache.use_disk_cache = True
    with bpy.context.temp_override(scene=bpy.context.scene):
        bpy.ops.ptcache.bake_all(bake=True)
    cloth.name = "Cape"
    bpy.ops.wm.save_mainfile()
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "shot.blend"))
    cloth = bpy.data.objects["Cape"]
    with bpy.context.temp_override(active_object=cloth, object=cloth, selected_objects=[cloth]):
        with pytest.raises(RuntimeError, match=re.escape(
                f"plays the mesh at rest. '{tmp_path / 'blendcache_shot'}' holds the bake of an object named 'Flag': "
                "if 'Cape' was renamed after its bake, name it so again (or bake again) and run again")):
            bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path / "cape.pc2"))
        cloth.name = "Flag"
        bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path / "flag.pc2"))
    assert (tmp_path / "flag.pc2").is_file() and not (tmp_path / "cape.pc2").exists()


@pytest.mark.parametrize("custom_path", [False, True])
def test_a_simulation_zone_whose_disk_bake_is_gone_is_refused(bpy_empty, extension, tmp_path, custom_path):
    """A Geometry Nodes simulation zone baked to disk (in the modifier's Bake Path, which Blender
    sets on the first bake, or in the zone's own Custom Path), its lift then changed (Blender keeps
    playing the bake), the .blend reopened without the bake folder: Blender simulates the zone
    again from the nodes as they are now. Refused before a frame is read, naming the modifier, the
    zone and the folder (before: read and written without a word; keys 0.27–0.51 off the bake, the
    in-betweens 0.75, on a sheet 2 wide). With the path cleared (a bake deleted on purpose) the
    zone is read as simulated now."""
    import re
    import shutil

    from blender_scenes import simulation_zone_scene

    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    obj = simulation_zone_scene(frames=9)
    modifier = obj.modifiers["Simulation"]
    bake = modifier.bakes[0]
    modifier.bake_target = 'DISK'
    if custom_path:
        bake.use_custom_path, bake.directory = True, "//zone bake"
    with bpy.context.temp_override(object=obj, active_object=obj):
        bpy.ops.object.geometry_node_bake_single(session_uid=obj.session_uid, modifier_name=modifier.name,
                                                 bake_id=bake.bake_id)
    folder = (tmp_path / "zone bake" if custom_path else
              tmp_path / "blendcache_shot" / "Simulated_Simulation" / str(bake.bake_id))
    assert sorted(path.name for path in (folder / "meta").iterdir())[-1] == "00009_00000.json"  # where Blender baked it
    modifier.node_group.nodes["Vector Math"].inputs[1].default_value = (0.0, 0.0, 0.08)
    bpy.ops.wm.save_mainfile()
    shutil.rmtree(tmp_path / ("zone bake" if custom_path else "blendcache_shot"))
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "shot.blend"))
    obj = bpy.data.objects["Simulated"]
    objects = set(bpy.data.objects)
    with bpy.context.temp_override(active_object=obj, object=obj, selected_objects=[obj]):
        with pytest.raises(RuntimeError, match=re.escape(
                f"The Geometry Nodes modifier 'Simulation' of 'Simulated' bakes the simulation zone 'Simulation "
                f"Output' to disk in '{folder}', which holds none of the bake's files")):
            bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path / "lost.pc2"))
        assert set(bpy.data.objects) == objects and not (tmp_path / "lost.pc2").exists()
        if custom_path:
            obj.modifiers["Simulation"].bakes[0].directory = ""
        else:
            obj.modifiers["Simulation"].bake_directory = ""
        bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path / "now.pc2"))
    assert (tmp_path / "now.pc2").is_file()


def test_file_names_that_are_no_text_are_written_and_told_escaped(bpy_empty, extension, tmp_path):
    """A folder whose name is Latin-1 bytes on a UTF-8 system ('caf\\xe9 shot'): Python gets the
    name with a surrogate (caf\\udce9), which Blender cannot take into a report. Before, In-between
    Frames wrote its cache there and then failed reporting it (a RuntimeError after the work: a
    batch exited non-zero with its file written), and a refusal naming the folder came out as
    "Python: (null)", its message lost. Now the run succeeds, and the refusal is read with the
    name escaped as Python prints it."""
    import os
    import shutil

    from blender_scenes import pinned_cloth_scene

    folder = tmp_path / os.fsdecode(b"caf\xe9 shot")
    folder.mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "shot.blend"))
    cloth = pinned_cloth_scene(frames=9)
    with bpy.context.temp_override(active_object=cloth, object=cloth, selected_objects=[cloth]):
        bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='CACHE',
                                                   filepath=str(folder / "out.pc2"))
    assert (folder / "out.pc2").is_file()
    cloth.modifiers["Cloth"].point_cache.use_disk_cache = True
    with bpy.context.temp_override(scene=bpy.context.scene):
        bpy.ops.ptcache.bake_all(bake=True)
    bpy.ops.wm.save_mainfile()
    shutil.rmtree(folder / "blendcache_shot")
    bpy.ops.wm.open_mainfile(filepath=str(folder / "shot.blend"))
    cloth = bpy.data.objects["Flag"]
    with bpy.context.temp_override(active_object=cloth, object=cloth, selected_objects=[cloth]):
        with pytest.raises(RuntimeError) as refusal:
            bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='CACHE',
                                                       filepath=str(folder / "lost.pc2"))
    escaped = f"{tmp_path}/caf\\udce9 shot/blendcache_shot"  # as Python prints the name
    assert f"Blender finds none of the bake's files in '{escaped}'" in str(refusal.value)
    assert not (folder / "lost.pc2").exists()


def test_frames_past_the_simulation_say_the_cloth_stands_still_there(bpy_empty, extension, capfd, tmp_path):
    """Keys read after the end of a cloth's frame range are its last frame held: the run says so
    (a probe's range 1–65 over a cloth simulated 1–49 in-betweened a still cape over 49–65,
    silently); a range inside the simulation's says nothing of it."""
    from blender_scenes import pinned_cloth_scene

    cloth = pinned_cloth_scene(frames=9, bake=True)
    bpy.context.scene.frame_end = 13
    with bpy.context.temp_override(active_object=cloth, object=cloth, selected_objects=[cloth]):
        capfd.readouterr()
        bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=13, frame_step=4, count=1,
                                                   filepath=str(tmp_path / "past.pc2"))
        out = capfd.readouterr().out
        # frame 13, a key, and frame 11, in the middle of the last gap (how the motion reaches it)
        assert "'Flag' is simulated by 'Cloth' over frames 1–9, and the range reads frames 11–13 after its end" in out
        bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                                   filepath=str(tmp_path / "inside.pc2"))
        assert "is simulated by" not in capfd.readouterr().out


def test_frames_past_a_cloth_proxys_simulation_say_the_proxy_stands_still_there(bpy_empty, extension, capfd):
    """A render mesh bound by a Surface Deform to a cloth proxy simulated over frames 1–9, read over
    1–13: the proxy holds still after frame 9 and so does the mesh; the run names the proxy and its
    range (before, only the mesh's own modifiers were looked at: nothing was said); a range inside
    the proxy's says nothing of it."""
    from blender_scenes import bound_to, pinned_cloth_scene

    proxy = pinned_cloth_scene(8, frames=9, bake=True)
    bpy.context.scene.frame_end = 13
    mesh = bound_to(proxy, 12)
    with bpy.context.temp_override(object=mesh, active_object=mesh, selected_objects=[mesh]):
        capfd.readouterr()
        bpy.ops.shape_differences.frames_to_shape_keys(frame_start=1, frame_end=13, frame_step=4,
                                                       output='SHAPE_KEYS')
        assert ("'Render' is moved by 'Flag', simulated by 'Cloth' over frames 1–9, and the range reads "
                "frame 13 after its end") in capfd.readouterr().out
        bpy.ops.shape_differences.frames_to_shape_keys(frame_start=1, frame_end=9, frame_step=4,
                                                       output='SHAPE_KEYS')
        assert "simulated by" not in capfd.readouterr().out


def sheet_played_by_a_cache(extension, tmp_path, samples: int, extra_points: int = 0, **modifier_settings):
    """A 7 × 7 grid 'Sheet' played by a Mesh Cache of ``samples`` PC2 samples (sample k: the grid
    lifted by 0.1 k, plus ``extra_points`` points of another mesh), sample 0 at frame 1."""
    import importlib

    sheet = grid_object(6)
    rest = extension.bridge.mesh_data.vertex_positions(sheet.data)
    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    poses = np.array([np.concatenate([rest, rest[:extra_points]]) + [0.0, 0.0, 0.1 * k] for k in range(samples)])
    modifier = sheet.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.frame_start = 'PC2', 1.0
    modifier.filepath = str(point_cache.write_pc2(tmp_path / "shot.pc2", poses, start=1.0))
    for name, value in modifier_settings.items():
        setattr(modifier, name, value)
    return sheet


@pytest.mark.parametrize("operator", ["inbetween_frames", "retime", "frames_to_shape_keys", "distortion_maps"])
def test_a_mesh_cache_that_does_not_fit_the_mesh_is_refused(bpy_empty, extension, operator, tmp_path):
    """A Mesh Cache playing a PC2 of another mesh (5 points more: Blender says 'Vertex count
    mismatch' on the modifier and leaves the mesh at rest), or a PC2 read as MDD (its Format set
    wrong): every frame is the rest mesh, and every operator reading frames made a still result and
    reported it done (with at most a warning that the frames are all the same); a PC2 cut short
    plays the rest mesh after the cut, and the poses read jumped there. Refused, saying what does
    not fit; nothing changed. A file with bytes after its samples plays whole and runs."""
    options = dict(source='FRAMES', k_m=10, k_n=0) if operator == "distortion_maps" else dict(frame_step=4)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    sheet = sheet_played_by_a_cache(extension, tmp_path, 9, extra_points=5)
    names = set(bpy.data.objects.keys())
    fails_without_change(extension.bridge, sheet, getattr(bpy.ops.shape_differences, operator),
                         r"The Mesh Cache 'Mesh Cache' of 'Sheet' plays '.*shot\.pc2', which holds 54 points for "
                         r"the mesh's 49 vertices: Blender leaves the mesh at rest", **options)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    sheet = sheet_played_by_a_cache(extension, tmp_path, 9, cache_format='MDD')
    fails_without_change(extension.bridge, sheet, getattr(bpy.ops.shape_differences, operator),
                         r"The Mesh Cache 'Mesh Cache' of 'Sheet' reads '.*shot\.pc2' as MDD \(its Format\), but it "
                         r"is a PC2 file: .* Set the modifier's Format to PC2", **options)
    assert set(bpy.data.objects.keys()) == names
    modifier = sheet.modifiers["Mesh Cache"]
    modifier.cache_format = 'PC2'  # read as what it is, but cut short: Blender plays the rest mesh past the cut
    path = tmp_path / "shot.pc2"
    whole = path.read_bytes()
    path.write_bytes(whole[:len(whole) // 2])
    fails_without_change(extension.bridge, sheet, getattr(bpy.ops.shape_differences, operator),
                         r"cannot play its file as PC2 \(its Format\): '.*shot\.pc2' is not a complete PC2 file.* "
                         r"Blender shows the mesh at rest wherever it cannot read a sample", **options)
    assert set(bpy.data.objects.keys()) == names
    path.write_bytes(whole + bytes(100))  # bytes after the samples: Blender plays every sample, and it runs
    getattr(bpy.ops.shape_differences, operator)(**options)


def test_a_mesh_cache_that_does_not_fit_its_proxy_is_refused(bpy_empty, extension, tmp_path):
    """A render mesh bound by a Surface Deform to a proxy whose Mesh Cache plays a PC2 of another
    mesh: the proxy stays at rest, and so does the render mesh. Refused, naming the proxy; nothing
    changed."""
    from blender_scenes import bound_to

    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    proxy = sheet_played_by_a_cache(extension, tmp_path, 9, extra_points=5)
    mesh = bound_to(proxy, 8)
    with bpy.context.temp_override(object=mesh, active_object=mesh, selected_objects=[mesh]):
        fails_without_change(extension.bridge, mesh, bpy.ops.shape_differences.inbetween_frames,
                             r"The Mesh Cache 'Mesh Cache' of 'Sheet', which moves 'Render', plays '.*shot\.pc2', "
                             "which holds 54 points for the mesh's 49 vertices", frame_step=4)


def _rolled(positions):
    """Nine samples of ``positions`` (a flat sheet) rolled up about y, more at each sample."""
    return np.array([np.stack([np.sin(a * positions[:, 0]) / a, positions[:, 1], (1.0 - np.cos(a * positions[:, 0])) / a],
                              axis=1) for a in 0.2 + 0.15 * np.arange(9)])


def _renumbered_grid(bridge, subdivisions: int):
    """The rest positions of a grid whose vertices Blender sorted (Sort Mesh Elements › Randomize),
    as a re-imported or remeshed copy is numbered: the copy is removed."""
    copy = grid_object(subdivisions, name="Copy")
    bpy.ops.object.mode_set(mode='EDIT')
    bpy.ops.mesh.sort_elements(type='RANDOMIZE', elements={'VERT'}, seed=3)
    bpy.ops.object.mode_set(mode='OBJECT')
    positions = bridge.mesh_data.vertex_positions(copy.data)
    bpy.data.objects.remove(copy)
    return positions


@pytest.mark.parametrize("operator", ["inbetween_frames", "retime", "frames_to_shape_keys", "shape_space",
                                      "distortion_maps"])
def test_a_cache_in_another_vertex_order_is_refused(bpy_empty, extension, operator, tmp_path):
    """A PC2 with as many points as the mesh has vertices, exported from a copy whose vertices
    Blender sorted (a renumbered copy, as re-importing or remeshing to the same count makes):
    Blender plays it on the mesh scrambled, and every operator reading frames keyed, in-betweened
    or measured it without a word. Refused, saying the cache is not this mesh's vertices in their
    order; nothing changed. The same motion in the mesh's order, in centimetres, or reversed (on a
    grid, the grid turned half round) runs."""
    import importlib

    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    options = dict(frame_step=4) if operator in ("inbetween_frames", "retime", "frames_to_shape_keys") else \
        dict(source='FRAMES', frame_step=4, k_m=10, **({"k_n": 20} if operator == "shape_space" else {}))
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    renumbered = _renumbered_grid(extension.bridge, 24)
    sheet = grid_object(24)
    rest = extension.bridge.mesh_data.vertex_positions(sheet.data)
    modifier = sheet.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.frame_start = 'PC2', 1.0
    modifier.filepath = str(point_cache.write_pc2(tmp_path / "copy.pc2", _rolled(renumbered), start=1.0))
    names = set(bpy.data.objects.keys())
    fails_without_change(extension.bridge, sheet, getattr(bpy.ops.shape_differences, operator),
                         r"'Sheet' is played by the Mesh Cache 'Mesh Cache' from 'copy\.pc2', whose frames are not "
                         r"this mesh's vertices in their order: at frame 1 its edges are \d+ times as long, against "
                         r"the size of the mesh, as at rest .* export it from this mesh, or point the modifier to the "
                         r"cache made for it", **options)
    assert set(bpy.data.objects.keys()) == names
    for name, poses in (("own", _rolled(rest)), ("cm", 100.0 * _rolled(rest)), ("reversed", _rolled(rest)[:, ::-1])):
        modifier.filepath = str(point_cache.write_pc2(tmp_path / f"{name}.pc2", poses, start=1.0))
        getattr(bpy.ops.shape_differences, operator)(**options)


def _strap_winding_up(length: int = 50) -> tuple[np.ndarray, list, np.ndarray]:
    """A strap of 2 × ``length`` vertices 1 apart and nine samples of it winding up from its far
    end, its edges kept to 4 %, onto an Archimedean spiral 0.3 between turns whose inner radius
    shrinks from 41 to 1 (an inner turn about six edges round: a tape measure retracting):
    (rest, quads, samples)."""
    along, across = np.meshgrid(np.arange(length, dtype=float), np.arange(2.0), indexing="ij")
    rest = np.stack([along.ravel(), across.ravel(), np.zeros(along.size)], axis=1)
    quads = [(2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1) for i in range(length - 1)]
    angle = np.linspace(0.0, 40 * np.pi, 100_001)
    samples = []
    for k in range(9):
        radius = 1.0 + 40.0 * (1.0 - k / 8) ** 2 + 0.3 * angle / (2 * np.pi)
        arc = np.concatenate([[0.0], np.cumsum(np.diff(angle) * 0.5 * (radius[1:] + radius[:-1]))])
        turn = np.interp(rest[:, 0].max() - rest[:, 0], arc, angle)  # the angle at each vertex's arc length
        wound = np.interp(turn, angle, radius)
        samples.append(np.stack([wound * np.cos(turn), rest[:, 1], wound * np.sin(turn)], axis=1))
    return rest, quads, np.array(samples)


def test_a_narrow_strap_wound_up_tight_by_a_cache_is_played(bpy_empty, extension, tmp_path):
    """A low-poly strap (2 × 50 vertices) a Mesh Cache winds up tight (a tape measure retracting):
    at the last sample its vertices lie within a few edges of each other, so its edges are as long
    against its size as another order's would be (grown 8 times), and In-between Frames refused it
    as a cache of another mesh. Each edge keeps its length, so it is played; the same samples in a
    random vertex order are still refused."""
    import importlib

    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    rest, quads, samples = _strap_winding_up()
    mesh = bpy.data.meshes.new("Strap")
    mesh.from_pydata(rest.tolist(), [], quads)
    strap = bpy.data.objects.new("Strap", mesh)
    bpy.context.scene.collection.objects.link(strap)
    bpy.context.view_layer.objects.active = strap
    strap.select_set(True)
    modifier = strap.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.frame_start = 'PC2', 1.0
    modifier.filepath = str(point_cache.write_pc2(tmp_path / "strap.pc2", samples, start=1.0))
    played = dict(extension.bridge.frame_reading.frame_positions(bpy.context, strap, [9]))[9]
    edges = np.array([(a, b) for quad in quads for a, b in zip(quad, quad[1:] + quad[:1])])
    kept = np.linalg.norm(played[edges[:, 0]] - played[edges[:, 1]], axis=1)
    assert 0.95 < kept.min() and kept.max() < 1.0 + 1e-5  # wound, not stretched
    with bpy.context.temp_override(active_object=strap, object=strap, selected_objects=[strap]):
        bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path / "wound.pc2"))
    assert (tmp_path / "wound.pc2").is_file()
    scrambled = samples[:, np.random.default_rng(0).permutation(len(rest))]
    modifier.filepath = str(point_cache.write_pc2(tmp_path / "scrambled.pc2", scrambled, start=1.0))
    fails_without_change(extension.bridge, strap, bpy.ops.shape_differences.inbetween_frames,
                         r"'Strap' is played by the Mesh Cache 'Mesh Cache' from 'scrambled\.pc2', whose frames are "
                         r"not this mesh's vertices in their order", frame_step=4)


def test_an_alembic_cache_of_another_vertex_order_is_refused(bpy_empty, extension, tmp_path):
    """An Alembic exported from a renumbered copy of the mesh, read on the mesh by a Mesh Sequence
    Cache: refused as the PC2 is, naming the file and the object path in it; nothing changed."""
    import importlib

    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    renumbered = _renumbered_grid(extension.bridge, 24)
    copy = grid_object(24, name="Copy")
    modifier = copy.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.frame_start = 'PC2', 1.0
    modifier.filepath = str(point_cache.write_pc2(tmp_path / "copy.pc2", _rolled(renumbered), start=1.0))
    bpy.ops.wm.alembic_export(filepath=str(tmp_path / "copy.abc"), start=1, end=9)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    bpy.ops.wm.alembic_import(filepath=str(tmp_path / "copy.abc"), as_background_job=False)
    imported = next(obj for obj in bpy.data.objects if obj.type == 'MESH')
    cache_file, object_path = imported.modifiers["MeshSequenceCache"].cache_file, imported.modifiers[
        "MeshSequenceCache"].object_path
    bpy.data.objects.remove(imported)
    sheet = grid_object(24)
    cache = sheet.modifiers.new("MeshSequenceCache", 'MESH_SEQUENCE_CACHE')
    cache.cache_file, cache.object_path = cache_file, object_path
    fails_without_change(extension.bridge, sheet, bpy.ops.shape_differences.inbetween_frames,
                         r"'Sheet' is played by the Mesh Sequence Cache 'MeshSequenceCache' from 'copy\.abc' \(object "
                         r"path '/Copy/Grid[^']*'\), whose frames are not this mesh's vertices in their order", frame_step=4)


def test_frames_past_a_mesh_cache_say_it_stands_still_there(bpy_empty, extension, capfd, tmp_path):
    """Frames after the last sample of a Mesh Cache's file play that sample, held (a PC2 of frames
    1–9 read over 1–13, or an MDD in Time Mode Seconds whose frames end before the range does):
    the run says so (before: nothing, and the in-betweens next to the held key slowed to a stop,
    in a probe 2.4e-3 → 2.8e-2 from the frames there, on a sheet 2 wide); a range inside the cache's
    says nothing of it."""
    bridge = extension.bridge
    sheet = sheet_played_by_a_cache(extension, tmp_path, 9)
    held = dict(bridge.frame_reading.frame_positions(bpy.context, sheet, [9, 13]))
    np.testing.assert_array_equal(held[13], held[9])  # what the warning says: the last sample, held
    _said_only_past_the_cache(capfd, (1, 13, 4), (1, 9, 4), "played by the Mesh Cache",
                              "'Sheet' is played by the Mesh Cache 'Mesh Cache' from 'shot.pc2' (9 samples; Frame "
                              "Start 1, Frame Scale 1), and the range reads frame 13 after its last: Blender holds "
                              "the cache's last sample there")
    # an MDD played by its times (seconds): frames 0–8 at 24 fps, read over 0–12
    rest = bridge.mesh_data.vertex_positions(sheet.data)
    path = tmp_path / "shot.mdd"
    path.write_bytes(struct.pack(">ii", 9, len(rest)) + (np.arange(9) / 24.0).astype(">f4").tobytes()
                     + np.array([rest + [0.0, 0.0, 0.1 * k] for k in range(9)]).astype(">f4").tobytes())
    modifier = sheet.modifiers["Mesh Cache"]
    modifier.cache_format, modifier.filepath, modifier.time_mode, modifier.frame_start = 'MDD', str(path), 'TIME', 0.0
    bpy.context.scene.render.fps = 24
    held = dict(bridge.frame_reading.frame_positions(bpy.context, sheet, [8, 12]))
    np.testing.assert_array_equal(held[12], held[8])
    _said_only_past_the_cache(capfd, (0, 12, 4), (0, 8, 4), "played by the Mesh Cache",
                              "the range reads frame 12 after its last: Blender holds")


def _said_only_past_the_cache(capfd, past, within, kind: str, said: str) -> None:
    """Frames to Shape Keys over the frames ``past`` (start, end, step) reports ``said``; over
    ``within`` nothing of the ``kind``."""
    capfd.readouterr()
    for (start, end, step), expected in ((past, True), (within, False)):
        bpy.ops.shape_differences.frames_to_shape_keys(frame_start=start, frame_end=end, frame_step=step,
                                                       output='SHAPE_KEYS')
        out = capfd.readouterr().out
        assert (said in out) if expected else (kind not in out)


def test_frames_past_an_alembic_cache_say_it_stands_still_there(bpy_empty, extension, capfd, tmp_path):
    """An Alembic cache of frames 3–9 imported into a shot of frames 1–13 (its importer's frame range
    off): Blender holds the first sample before frame 3 and the last after frame 9, so the poses
    read there are the same to the bit; the run says so (before: nothing, and in a probe the
    in-betweens next to the held key slowed to a stop, 2.4e-3 → 2.8e-2 from the cache's frames on a
    sheet 2 wide); a range inside the cache's says nothing of it."""
    armature_scene(frames=9)
    bpy.ops.wm.alembic_export(filepath=str(tmp_path / "strip.abc"), start=3, end=9)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 13
    bpy.ops.wm.alembic_import(filepath=str(tmp_path / "strip.abc"), as_background_job=False, set_frame_range=False)
    strip = next(obj for obj in bpy.data.objects if obj.type == 'MESH')
    poses = dict(extension.bridge.frame_reading.frame_positions(bpy.context, strip, [1, 2, 3, 9, 10, 13]))
    np.testing.assert_array_equal(poses[1], poses[3])  # what the warning says: the ends held
    np.testing.assert_array_equal(poses[13], poses[9])
    assert not np.array_equal(poses[3], poses[9])
    with bpy.context.temp_override(active_object=strip, object=strip, selected_objects=[strip]):
        _said_only_past_the_cache(capfd, (1, 13, 1), (3, 9, 2), "Mesh Sequence Cache",
                                  "is played by the Mesh Sequence Cache 'MeshSequenceCache' from 'strip.abc', and the "
                                  "range reads the same pose, to the bit, at its start (frames 1–3) and its end "
                                  "(frames 9–13)")


@pytest.mark.parametrize("operator", ["inbetween_frames", "frames_to_shape_keys"])
def test_an_alembic_cache_reading_no_positions_is_refused(bpy_empty, extension, operator, tmp_path):
    """A Mesh Sequence Cache with Vertices off in its Read Data reads no positions from its file:
    Blender shows the mesh as imported at every frame, and the operators wrote that still mesh as
    the motion, saying only that the frames were the same ("check what moves it (a baked cache
    whose files are gone, ...)"), a batch exiting 0. Refused, naming the setting; nothing changed.
    With other motion on the mesh (a Wave after the cache) Vertices may be off on purpose: it runs."""
    armature_scene(frames=9)
    bpy.ops.wm.alembic_export(filepath=str(tmp_path / "strip.abc"), start=1, end=9)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    bpy.ops.wm.alembic_import(filepath=str(tmp_path / "strip.abc"), as_background_job=False)
    strip = next(obj for obj in bpy.data.objects if obj.type == 'MESH')
    cache = strip.modifiers["MeshSequenceCache"]
    cache.read_data = {'POLY', 'UV', 'COLOR'}
    names = set(bpy.data.objects.keys())
    with bpy.context.temp_override(active_object=strip, object=strip, selected_objects=[strip]):
        fails_without_change(extension.bridge, strip, getattr(bpy.ops.shape_differences, operator),
                             r"'Grid' reads the same pose at all \d frames read \(1–9\): the Mesh Sequence Cache "
                             r"'MeshSequenceCache' of 'Grid' reads no vertex positions from 'strip\.abc' \(Vertices "
                             r"is off in its Read Data\), .* Turn Vertices on in the modifier's Read Data",
                             frame_step=4, output='SHAPE_KEYS')
        assert set(bpy.data.objects.keys()) == names
        wave = strip.modifiers.new("Wave", 'WAVE')
        wave.height, wave.speed = 0.2, 0.1
        getattr(bpy.ops.shape_differences, operator)(frame_step=4, output='SHAPE_KEYS')


def test_a_mesh_in_edit_mode_through_a_linked_duplicate_is_refused(bpy_empty, extension):
    """The active object is in Object Mode but its mesh is in Edit Mode through a linked duplicate
    (Alt+D): the mesh has no vertices until Edit Mode is left, so the operators are unavailable and
    say why (before: a KeyError traceback from reading its positions)."""
    obj = posed_grid(extension.bridge, 4)
    twin = bpy.data.objects.new("Twin", obj.data)
    bpy.context.scene.collection.objects.link(twin)
    bpy.context.view_layer.objects.active = twin
    bpy.ops.object.mode_set(mode='EDIT')
    bpy.context.view_layer.objects.active = obj
    assert obj.mode == 'OBJECT' and obj.data.is_editmode
    for operator in ("inbetween", "exaggerate", "distortion_maps"):
        with pytest.raises(RuntimeError, match="The mesh of 'Sheet' is in Edit Mode through 'Twin', which shares it"):
            getattr(bpy.ops.shape_differences, operator)()
    bpy.context.view_layer.objects.active = twin
    bpy.ops.object.mode_set(mode='OBJECT')
    assert [k.name for k in obj.data.shape_keys.key_blocks] == ["Basis", "Curl", "Bend"]


def test_a_cloth_on_for_renders_only_is_said_to_be_missing_from_the_frames(bpy_empty, extension, capfd, tmp_path):
    """A baked cloth switched off in the viewport and on for renders (a heavy simulation kept off
    while animating): frames are read as the viewport shows them, the rest mesh, so the run names
    that modifier and how to include it (before: only "all the same pose … a baked cache whose
    files are gone, a simulation outside this range", neither of which was the cause). A Subdivision
    on for renders only after the cloth goes with the new object and is not named."""
    from blender_scenes import cloth_scene

    cloth = cloth_scene(6, frames=9)
    cloth.modifiers["Cloth"].show_viewport = False
    cloth.modifiers.new("Subdivision", 'SUBSURF').show_viewport = False
    expected = ("'Cloth' of 'Cloth' is on for renders only (off in the viewport), and frames are read as the "
                "viewport shows them: the poses read lack its motion")
    with bpy.context.temp_override(active_object=cloth, object=cloth, selected_objects=[cloth]):
        capfd.readouterr()
        bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path) + "/")
        out = capfd.readouterr().out
        assert expected in out and "'Subdivision'" not in out
        cloth.modifiers["Cloth"].show_viewport = True
        bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path) + "/")
        assert "on for renders only" not in capfd.readouterr().out


def test_a_cloth_proxy_on_for_renders_only_is_said_to_be_missing_from_the_frames(bpy_empty, extension, capfd,
                                                                                 tmp_path):
    """A render mesh bound by a Surface Deform to a cloth proxy whose cloth is off in the viewport
    and on for renders: frames are read as the viewport shows them, the proxy at rest, so the run
    names the proxy's modifier (before, only the render mesh's own modifiers were looked at)."""
    from blender_scenes import bound_to, pinned_cloth_scene

    proxy = pinned_cloth_scene(8, frames=9)
    mesh = bound_to(proxy)
    proxy.modifiers["Cloth"].show_viewport = False
    expected = f"'Cloth' of '{proxy.name}' is on for renders only (off in the viewport)"
    with bpy.context.temp_override(active_object=mesh, object=mesh, selected_objects=[mesh]):
        capfd.readouterr()
        bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path) + "/")
        assert expected in capfd.readouterr().out
        proxy.modifiers["Cloth"].show_viewport = True
        bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path) + "/")
        assert "on for renders only" not in capfd.readouterr().out


def test_a_deform_on_in_the_viewport_only_is_said_to_be_in_the_frames(bpy_empty, extension, capfd, tmp_path):
    """A Displace after the armature on in the viewport and off for renders (a preview deform):
    frames are read as the viewport shows them, so the new object plays and renders the displaced
    mesh, which the source's renders lack (before, nothing was said); a Displace on for both, and
    one in the run that goes with the new object, are not named."""
    from blender_scenes import armature_scene

    strip = armature_scene(frames=9)
    preview = strip.modifiers.new("Preview", 'DISPLACE')
    preview.strength, preview.show_render = 0.3, False
    expected = (f"'Preview' of '{strip.name}' is on in the viewport only (off for renders), and frames are read "
                "as the viewport shows them: the poses read carry its deformation")
    names = set(bpy.data.objects.keys())
    capfd.readouterr()
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path) + "/")
    assert expected in capfd.readouterr().out
    [copy] = [o for o in bpy.data.objects if o.name not in names]
    assert [m.type for m in copy.modifiers] == ['MESH_CACHE']  # the displaced poses render as they are
    preview.show_render = True
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path) + "/")
    assert "viewport only" not in capfd.readouterr().out
    preview.show_render = False
    strip.modifiers.new("Subdivision", 'SUBSURF')  # before the Displace: the run set aside and copied
    strip.modifiers.move(2, 1)
    assert [m.name for m in strip.modifiers] == ["Armature", "Subdivision", "Preview"]
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path) + "/")
    assert "viewport only" not in capfd.readouterr().out


@pytest.mark.parametrize("operator, options", [
    ("frames_to_shape_keys", dict(output='SHAPE_KEYS')), ("frames_to_shape_keys", dict(output='CACHE')),
    ("inbetween_frames", dict(frame_step=4, count=1)), ("shape_space", dict(source='FRAMES', k_m=10, k_n=20)),
    ("distortion_maps", dict(source='FRAMES', k_m=10, eigenfunctions=0))])
def test_a_frame_with_a_nan_is_refused_by_its_number(bpy_empty, extension, tmp_path, operator, options):
    """A cache frame holding a NaN (a simulation that exploded): Frames to Shape Keys wrote it into a
    key (the vertex gone wherever the key plays) or a PC2 file; the others named the core's
    "key_poses" or "base vertices". Refused, naming the frame and the object; nothing changed."""
    import importlib

    sheet = grid_object(6)
    rest = extension.bridge.mesh_data.vertex_positions(sheet.data)
    frames = np.array([rest + [0.0, 0.0, 0.1 * k * k] for k in range(9)])
    frames[4, 7, 2] = np.nan
    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    path = tmp_path / "exploded.pc2"
    with open(path, "wb") as stream:  # write_pc2 refuses a NaN: the header, then the samples as they are
        stream.write(point_cache.pc2_header(rest.shape[0], len(frames), 1.0, 1.0))
        stream.write(frames.astype("<f4").tobytes())
    modifier = sheet.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.filepath, modifier.frame_start = 'PC2', str(path), 1.0
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    if "output" in options or operator == "inbetween_frames":
        options = dict(options, filepath=str(tmp_path) + "/")
    names = set(bpy.data.objects.keys())
    fails_without_change(extension.bridge, sheet, getattr(bpy.ops.shape_differences, operator),
                         r"frame 5 of 'Sheet': vertex 7 has a non-finite coordinate", **options)
    assert set(bpy.data.objects.keys()) == names and sorted(p.name for p in tmp_path.iterdir()) == ["exploded.pc2"]


@pytest.mark.parametrize("operator, collapsed, options", [
    ("inbetween_frames", 10, dict(count=1)),  # the last frame, a key of the sequence past the whole steps
    ("retime", 7, dict(speed=1.0))])  # a key of the shorter last gap only, no key of the plan
def test_a_collapsed_frame_is_named_by_its_number(bpy_empty, extension, tmp_path, operator, collapsed, options):
    """Ten frames keyed every 4th: the key poses the core checks include frames that are no step of
    the range (the last frame; the keys of the shorter last gap), which the core names as the operator
    names them: "frame 10" (In-between Frames) and "frame 7" (Retime), not "key pose 3" nor frame 1."""
    import importlib

    sheet = grid_object(6)
    rest = extension.bridge.mesh_data.vertex_positions(sheet.data)
    frames = np.array([rest + [0.0, 0.0, 0.1 * k * k] for k in range(10)])
    frames[collapsed - 1, :, 0] = 0.0  # the sheet squashed onto a line: every triangle has zero area
    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    path = point_cache.write_pc2(tmp_path / "collapsing.pc2", frames)
    modifier = sheet.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.filepath, modifier.frame_start = 'PC2', str(path), 1.0
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 10
    fails_without_change(extension.bridge, sheet, getattr(bpy.ops.shape_differences, operator),
                         rf"Error: frame {collapsed}: triangle \d+ .* has zero area", frame_step=4,
                         output='SHAPE_KEYS', **options)


def test_a_warning_names_the_keys_by_their_frames(bpy_empty, extension, tmp_path, capfd):
    """The core's warnings about a sequence's keys name them as the operator hands them over, by
    frame, the last frame of a range that is no whole steps included (a sheet mirrored between frames 9
    and 10: "from frame 9 to frame 10", where "key pose 3" was said)."""
    import importlib

    sheet = grid_object(6)
    rest = extension.bridge.mesh_data.vertex_positions(sheet.data)
    rest = np.c_[rest[:, :2], 0.3 * rest[:, 0] ** 2 + 0.1 * rest[:, 1]]  # no plane: its mirror image is no motion
    frames = np.array([rest + [0.01 * k, 0.0, 0.0] for k in range(10)])
    frames[9] *= [-1.0, 1.0, 1.0]
    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    path = point_cache.write_pc2(tmp_path / "mirrored.pc2", frames)
    modifier = sheet.modifiers.new("Mesh Cache", 'MESH_CACHE')
    modifier.cache_format, modifier.filepath, modifier.frame_start = 'PC2', str(path), 1.0
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 10
    capfd.readouterr()
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='SHAPE_KEYS')
    out = capfd.readouterr().out
    assert "mirror image of themselves from frame 9 to frame 10" in out and "key pose" not in out, out
    # Blender's status bar shows an operator's last report: after the summary (Info), a warning
    # line saying how many warnings there are and which to look at first; each warning a Warning
    reports = [line for line in out.splitlines() if line.startswith(("Warning: ", "Info: ", "Error: "))]
    assert [line.split(": ")[0] for line in reports] == ["Warning", "Warning", "Info", "Warning"], reports
    assert reports[1].startswith("Warning: Shape-difference interpolation: 1 piece(s) of the mesh"), reports
    assert reports[2].startswith("Info: Added 6 shape keys"), reports
    assert reports[3] == "Warning: 2 warnings, each printed above; look first at: The new shape keys are " \
        "deformed again by 'Mesh Cache' of 'Sheet'", reports


@pytest.mark.parametrize("where, named", [("Bend", "shape key 'Bend' of 'Source'"),
                                          ("Basis", "shape key 'Basis' of 'Source'"),
                                          ("target", "the mesh of 'Sheet'")])
def test_transfer_names_the_mesh_and_key_holding_a_nan(bpy_empty, extension, where, named):
    """A NaN in the source's key was reported as the core's "target vertices" (the core's target
    is the source object, so a user looked at the other mesh): the key and its object are named, and
    the core's "remove that frame" is said of the key (a mesh: fixing it is the remedy)."""
    from blender_scenes import transfer_pair

    bridge = extension.bridge
    source, target = transfer_pair(bridge, 8, 6)
    if where == "target":
        positions = bridge.mesh_data.vertex_positions(target.data)
        positions[3, 0] = np.nan
        target.data.attributes["position"].data.foreach_set("vector", positions.astype(np.float32).ravel())
        target.data.update()
    else:
        key_block = source.data.shape_keys.key_blocks[where]
        positions = bridge.mesh_data.stored_key_positions(key_block)
        positions[3, 0] = np.inf
        key_block.data.foreach_set("co", positions.astype(np.float32).ravel())
    remedy = r"exploded\)\." if where == "target" else f"or remove shape key '{where}'\\."
    with pytest.raises(RuntimeError, match=rf"{named}: vertex 3 has a non-finite coordinate .*{remedy}$"):
        bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=32)
    assert target.data.shape_keys is None


def test_frames_beyond_blenders_last_frame_are_refused(bpy_empty, extension):
    """Blender shows its last frame (1,048,574) for any later one: frames 1,048,575–1,048,580 were
    captured as keys named after them holding frame 1,048,574 (a typo in a batch script). Refused."""
    strip = armature_scene(frames=9)
    for start, end in ((1_048_570, 1_048_580), (-1_048_580, -1_048_570)):
        fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.frames_to_shape_keys,
                             r"Frame -?1,048,580 is beyond Blender's frames \(-1,048,574 to 1,048,574\)",
                             frame_start=start, frame_end=end, output='SHAPE_KEYS')


def test_a_retime_past_blenders_last_frame_is_refused(bpy_empty, extension):
    """Frames 1,048,566–1,048,574 at half speed run to frame 1,048,582: Blender plays nothing past
    1,048,574, yet the retime was written and its warning asked for an End frame Blender cannot
    set. Refused before any frame is read, with the slowest speed that fits (8 / 8 = 1)."""
    strip = armature_scene(frames=9)
    fails_without_change(extension.bridge, strip, bpy.ops.shape_differences.retime,
                         r"runs to frame 1,048,582, past Blender's last frame 1,048,574, where nothing plays: "
                         r"use a speed of 1 or more", frame_start=1_048_566, frame_end=1_048_574, frame_step=4,
                         speed=0.5)


@pytest.mark.parametrize("count", [20, -1])
def test_eigenfunctions_outside_their_range_are_errors(bpy_empty, extension, count):
    """A script's Eigenfunctions 20 was clamped to 8 by Blender without a word (8 maps of each
    difference written, the summary saying 32), and -1 to 0: reported, as Step and k_M are."""
    obj = posed_grid(extension.bridge, 6)
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.distortion_maps,
                         rf"Eigenfunctions is {count}: write 0 to 8", eigenfunctions=count)


@pytest.mark.parametrize("operator", ["frames_to_shape_keys", "inbetween_frames", "retime", "shape_space",
                                      "distortion_maps"])
@pytest.mark.parametrize("step", [0, -4])
def test_a_step_below_one_is_an_error(bpy_empty, extension, operator, step):
    """A script's Step of 0 (or below) was clamped to 1 by Blender without a word, and every frame
    was read (In-between Frames: three in-betweens per frame): reported, as a Count of 0 is."""
    strip = armature_scene(frames=9)
    options = dict(source='FRAMES') if operator in ("shape_space", "distortion_maps") else {}
    fails_without_change(extension.bridge, strip, getattr(bpy.ops.shape_differences, operator),
                         rf"Step is {step}: take every frame \(Step 1\)", frame_step=step, **options)


@pytest.mark.parametrize("output", ['SHAPE_KEYS', 'CACHE'])
def test_a_mesh_without_vertices_has_nothing_to_capture(bpy_empty, extension, output, tmp_path):
    """A mesh with no vertex at all (a new mesh made by a script) has no position
    attribute: Frames to Shape Keys ended in a KeyError traceback. Refused in the user's words."""
    obj = bpy.data.objects.new("Empty", bpy.data.meshes.new("Empty"))
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    names = set(bpy.data.objects.keys())
    with pytest.raises(RuntimeError, match="The mesh of 'Empty' has no vertices: there is nothing to capture") as failure:
        bpy.ops.shape_differences.frames_to_shape_keys(output=output, filepath=str(tmp_path) + "/")
    assert "Traceback" not in str(failure.value)
    assert set(bpy.data.objects.keys()) == names and obj.data.shape_keys is None and not list(tmp_path.iterdir())


@pytest.mark.parametrize("operator, properties, match", [
    ("inbetween", dict(k_m=-5), r"k_M = -5 must be 0 for the full basis, or a positive number of eigenfunctions"),
    ("inbetween", dict(k_n=-5), r"k_N = -5 must be 0 for the target not truncated, or a positive number of "),
    ("shape_space", dict(k_m=-5), r"k_M = -5 must be a positive number of eigenfunctions \(typically"),
    ("shape_space", dict(k_n=-5), r"k_N = -5 must be 0 for the differences in the base's basis only, or a positive"),
    ("distortion_maps", dict(k_m=-5), r"k_M = -5 must be a positive number of eigenfunctions \(typically"),
    ("reconstruct", dict(k_m=20, k_n=10), "k_N = 10 must be at least k_M = 20"),
    ("reconstruct", dict(offset=-0.5), "Offset t = -0.5 must be positive, or 0 for the automatic distance"),
    ("shape_space", dict(k_m=1), "k_M .* is 1, but the first 1 Laplace–Beltrami eigenfunctions"),
    ("distortion_maps", dict(offset=-1.0), "Offset t = -1 must be positive, or 0 for the automatic distance")])
def test_sizes_and_offsets_below_their_range_are_errors(bpy_empty, extension, core, operator, properties, match):
    """A script's negative basis size or offset was clamped by Blender without a word (k_M −5 ran
    with the full basis, an offset −0.5 with the automatic one, the shape space's k_M 1 with 2): the
    core's checks report them, as they do for every other size; negative sizes and offsets the
    operators, by their labels and what 0 means there (before, the core's "0 / None (full basis)"
    for scripts, "k_N = -5 needs k_M", the full basis offered to the shape space, which has none,
    and "k must be at least 1" for the distortion maps' k_M)."""
    obj = posed_grid(extension.bridge, 6)
    fails_without_change(extension.bridge, obj, getattr(bpy.ops.shape_differences, operator), match, **properties)


def test_keyframed_shape_keys_on_a_shared_mesh_say_its_other_objects_play_them(bpy_empty, extension, capfd):
    """A baked cloth whose mesh a linked duplicate 'Twin' shares: In-between Frames to shape keys
    keys their values on the mesh, so Twin plays the cloth's motion too (0.64 in its world at frame
    13); that is said, naming Twin (before, nothing was). Keys that play nowhere (Frames to Shape Keys),
    keys written from Twin that the cloth's bake hides, and an object with a mesh of its own are not
    warned."""
    from blender_scenes import cloth_scene

    cloth = cloth_scene(10, frames=13)
    twin = cloth.copy()
    twin.name = "Twin"
    twin.modifiers.clear()
    bpy.context.scene.collection.objects.link(twin)
    still = bpy.context.scene.frame_current
    capfd.readouterr()
    bpy.ops.shape_differences.frames_to_shape_keys(frame_step=4, output='SHAPE_KEYS')
    assert "Twin" not in capfd.readouterr().out
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='SHAPE_KEYS')
    assert ("'Twin' shares the mesh of 'Cloth' and now plays the new keyframed shape keys too" in
            capfd.readouterr().out)
    assert bpy.context.scene.frame_current == still
    bpy.context.view_layer.objects.active = twin  # keys from Twin: the cloth's baked frames hide them on it
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='SHAPE_KEYS')
    assert "shares the mesh" not in capfd.readouterr().out
    bpy.context.view_layer.objects.active = cloth
    twin.data = twin.data.copy()  # a mesh of its own: nothing to say
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='SHAPE_KEYS')
    assert "Twin" not in capfd.readouterr().out


@pytest.mark.parametrize("operator, properties", [("inbetween", {}), ("exaggerate", {"factor": 1.5})])
def test_a_solver_failure_in_the_in_betweens_is_reported_and_changes_nothing(bpy_empty, extension, monkeypatch,
                                                                             operator, properties):
    """A raw failure of the in-betweens' sparse solve (forced: no input found makes it fail) is the
    core's RecoveryError, which the operator reports, not a traceback."""
    import importlib

    cholesky = importlib.import_module(f"{extension.__name__}.core.sparse_cholesky")

    def failing(self, rhs):
        raise np.linalg.LinAlgError("Matrix is not positive definite!")

    monkeypatch.setattr(cholesky.SPDFactor, "solve", failing)
    obj = posed_grid(extension.bridge, 6)
    fails_without_change(extension.bridge, obj, getattr(bpy.ops.shape_differences, operator),
                         r"between shape key 'Basis' and shape key '.*' failed numerically \(LinAlgError", **properties)


def _flattened_by_its_scale(obj, scale, scaled: str):
    """Give ``obj`` (or an Empty it is parented to) ``scale``."""
    if scaled == "itself":
        obj.scale = scale
    else:
        parent = bpy.data.objects.new("Holder", None)
        bpy.context.scene.collection.objects.link(parent)
        parent.scale = scale
        obj.parent = parent
    bpy.context.view_layer.update()


@pytest.mark.parametrize("operator", ["inbetween", "exaggerate", "distortion_maps", "shape_space", "inbetween_frames",
                                      "retime"])
@pytest.mark.parametrize("scale, scaled", [((1e12, 1.0, 1.0), "itself"), ((1e-20, 1.0, 1.0), "its parent")])
def test_an_object_its_scale_flattens_in_the_world_is_refused_for_its_scale(bpy_empty, extension, operator, scale,
                                                                             scaled):
    """The operators work in the world's proportions (``bridge.world_space.WorldProportions``, ``WorldFrames``):
    a grid scaled 1e12 along x (or under a parent scaled 1e-20 so) is flat there, though its mesh
    is fine. Refused before any work naming the object's scale, nothing changed (before: "triangle 0
    has zero area … Remove degenerate faces: Degenerate Dissolve", or, for the frame operators at
    1e-20, in-betweens taken back into the mesh through a matrix that cannot be inverted)."""
    if operator in ("inbetween_frames", "retime"):
        obj = grid_object(6)
        obj.modifiers.new("Wave", 'WAVE').height = 0.2
        bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
        properties = dict(frame_step=4)
    else:
        obj = posed_grid(extension.bridge, 6)
        properties = {}
    _flattened_by_its_scale(obj, scale, scaled)
    shown = re.escape("1e+12, 1, 1" if scale[0] > 1 else "1e-20, 1, 1")
    fails_without_change(extension.bridge, obj, getattr(bpy.ops.shape_differences, operator),
                         rf"^Error: 'Sheet' is flattened in the world \(its scale there is \({shown}\)\): .*"
                         r"Give it \(and its parents\) scales of a like size along every axis", **properties)


def _sheet_scale_keyframed_through_zero(frames: int = 9, last_scale: float = -1.0):
    """A grid bent by a shape key keyframed 0 → 1 over frames 1–``frames``, on an object whose x scale is
    keyframed linearly 2 → ``last_scale`` there: its proportions differ at the two ends, and with the
    default −1 its scale is 0 at frame 1 + 2/3 × (``frames`` − 1) (6 1/3 for 9 frames)."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    sheet = grid_object(6)
    rest = np.array([vertex.co[:] for vertex in sheet.data.vertices])
    add_key(sheet, "Bend", rolled(rest, 1.5))
    bend = sheet.data.shape_keys.key_blocks["Bend"]
    for frame, value, scale in ((1, 0.0, 2.0), (frames, 1.0, last_scale)):
        bend.value = value
        bend.keyframe_insert("value", frame=frame)
        sheet.scale = (scale, 1.0, 1.0)
        sheet.keyframe_insert("scale", frame=frame)
    for animated in (sheet.animation_data, sheet.data.shape_keys.animation_data):
        for fcurve in _fcurves(animated):
            for point in fcurve.keyframe_points:
                point.interpolation = 'LINEAR'
    scene.frame_set(1)
    return sheet


@pytest.mark.parametrize("operator, properties", [
    ("inbetween_frames", dict(frame_step=8, count=23)), ("inbetween_frames", dict(frame_step=8, count=23,
                                                                                  output='SHAPE_KEYS')),
    ("retime", dict(frame_step=8, speed=1 / 3))])
def test_an_inbetween_where_a_keyframed_scale_passes_0_is_refused_naming_its_frame(bpy_empty, extension, operator,
                                                                                   properties):
    """An object whose scale is keyframed from 2 to −1 along x over frames 1–9: both keys (1, 9) are fine, but
    the in-betweens 1/3 frame apart (23 per gap of 8, or a retime at speed 1/3) include frame 6 1/3, where the
    scale is 0 and no pose can be taken back into the mesh. Refused naming that frame, nothing changed (before:
    a NumPy traceback, "LinAlgError: Singular matrix", from ``WorldFrames.back``)."""
    sheet = _sheet_scale_keyframed_through_zero()
    fails_without_change(extension.bridge, sheet, getattr(bpy.ops.shape_differences, operator),
                         r"^Error: 'Sheet' is flattened in the world at frame 6\.3333\d* \(its scale there is \(0, 1, "
                         r"1\)\): .* cannot be taken back into its mesh\. .* a scale other than 0 along every axis there",
                         frame_start=1, frame_end=9, **properties)


@pytest.mark.parametrize("operator, properties", [
    ("inbetween_frames", dict(count=1)), ("inbetween_frames", dict(count=1, output='SHAPE_KEYS')),
    ("retime", dict(speed=0.5))])
def test_a_key_frame_at_a_scale_of_0_is_refused_naming_it(bpy_empty, extension, operator, properties):
    """An object whose x scale is keyframed from 2 to exactly 0 over frames 1–9, keyed every 8th frame: the
    key at frame 9 is flattened in the world, and no pose can be taken back into its mesh there. Refused
    naming that frame and how to leave it out, nothing changed (before: the same refusal without the frame,
    which the object's scale at the current frame, 2, does not explain)."""
    sheet = _sheet_scale_keyframed_through_zero(last_scale=0.0)
    fails_without_change(extension.bridge, sheet, getattr(bpy.ops.shape_differences, operator),
                         r"^Error: 'Sheet' is flattened in the world at frame 9 \(its scale there is \(0, 1, 1\)\): .* "
                         r"cannot be taken back into its mesh\. .* a scale other than 0 along every axis there, or a "
                         r"frame range and Step that leave that frame out$",
                         frame_start=1, frame_end=9, frame_step=8, **properties)


def test_a_degenerate_face_of_a_stretched_object_is_the_meshs_own(bpy_empty, extension):
    """A triangle with no area in the mesh itself (its corners on one line) stays the core's refusal
    with its remedy, on an object stretched along its axes: its scale is not blamed."""
    obj = posed_grid(extension.bridge, 6)
    sliver, moved = with_boundary_sliver(extension.bridge, obj.data)
    obj.shape_key_clear()
    obj.data = sliver
    add_key(obj, "Bend", moved + [0.0, 0.0, 0.1])
    _flattened_by_its_scale(obj, (3.0, 1.0, 0.2), "itself")
    fails_without_change(extension.bridge, obj, bpy.ops.shape_differences.inbetween,
                         r"^Error: shape key 'Basis': triangle \d+ \(of face \d+; vertices .*\) has zero area .*"
                         "Degenerate Dissolve")
