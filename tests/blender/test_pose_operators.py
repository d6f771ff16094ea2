"""In-between, exaggerate and reconstruct through bpy.ops: new keys with the right names, the
positions core computes for the same input, existing keys untouched."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import add_key, key_names, posed_grid, snapshot  # noqa: E402

TOLERANCE = 1e-4  # float32 storage of a ~2 unit mesh


@pytest.fixture
def posed(bpy_empty, extension, core):
    """A grid with Basis, Curl and Bend (active), and the bridge to read it."""
    return posed_grid(extension.bridge, 10), extension.bridge


def positions_of(bridge, obj, name):
    return bridge.mesh_data.stored_key_positions(obj.data.shape_keys.key_blocks[name])


def assert_old_keys_kept(bridge, obj, before):
    for name, (coordinates, value, relative) in before["keys"].items():
        np.testing.assert_array_equal(positions_of(bridge, obj, name), coordinates)
    np.testing.assert_array_equal(bridge.mesh_data.vertex_positions(obj.data), before["positions"])
    assert obj.active_shape_key_index == before["active_key"]


def test_inbetween(posed, core):
    obj, bridge = posed
    before = snapshot(bridge, obj)
    bpy.ops.shape_differences.inbetween(key_a="Curl", key_b="Bend", count=3)
    new = [f"Inbetween Curl-Bend {f:.2f}" for f in (0.25, 0.5, 0.75)]
    assert key_names(obj) == ["Basis", "Curl", "Bend"] + new
    assert_old_keys_kept(bridge, obj, before)
    interpolator = core.Interpolator(positions_of(bridge, obj, "Curl"),
                                     positions_of(bridge, obj, "Bend"),
                                     bridge.triangulation.mesh_triangles(obj.data))
    for name, factor in zip(new, (0.25, 0.5, 0.75)):
        np.testing.assert_allclose(positions_of(bridge, obj, name), interpolator.pose(factor),
                                   atol=TOLERANCE)
        assert obj.data.shape_keys.key_blocks[name].value == 0.0


def test_keys_are_read_as_the_poses_they_show(posed, core):
    """A corrective relative to another key, and a key masked by a vertex group (a right half),
    are the poses Blender shows with each alone at value 1 — reference + weight × (key − its
    relative key) — not their stored coordinates; In-between goes to what is shown."""
    obj, bridge = posed
    blocks = obj.data.shape_keys.key_blocks
    rest, bend = positions_of(bridge, obj, "Basis"), positions_of(bridge, obj, "Bend")
    bump = 0.3 * np.exp(-4.0 * (rest[:, :2] ** 2).sum(axis=1))
    add_key(obj, "Corrective", bend + bump[:, None] * [0.0, 0.0, 1.0]).relative_key = blocks["Bend"]
    group = obj.vertex_groups.new(name="Right")
    for index, weight in enumerate(np.clip(rest[:, 0] + 0.5, 0.0, 1.0)):
        group.add([index], float(weight), 'REPLACE')
    add_key(obj, "Bend Right", bend).vertex_group = "Right"
    triangles = bridge.triangulation.mesh_triangles(obj.data)
    for name in ("Corrective", "Bend Right"):
        for block in blocks:
            block.value = 1.0 if block.name == name else 0.0
        shown = bridge.mesh_data.evaluated_positions(obj, bpy.context.evaluated_depsgraph_get())
        assert np.abs(shown - positions_of(bridge, obj, name)).max() > 0.1  # not what is stored
        np.testing.assert_allclose(bridge.mesh_data.shape_key_positions(blocks[name], obj), shown, atol=TOLERANCE)
        blocks[name].value = 0.0
        bpy.ops.shape_differences.inbetween(key_a="Basis", key_b=name, count=1)
        np.testing.assert_allclose(positions_of(bridge, obj, f"Inbetween Basis-{name} 0.50"),
                                   core.Interpolator(rest, shown, triangles).pose(0.5), atol=TOLERANCE)


def test_inbetween_defaults_and_unique_names(posed):
    obj, _bridge = posed
    bpy.ops.shape_differences.inbetween(count=1)  # Basis to the active key, Bend
    bpy.ops.shape_differences.inbetween(count=1)
    assert key_names(obj)[3:] == ["Inbetween Basis-Bend 0.50", "Inbetween Basis-Bend 0.50.001"]


def test_exaggerate(posed, core):
    obj, bridge = posed
    before = snapshot(bridge, obj)
    bpy.ops.shape_differences.exaggerate(key="Bend", factor=1.5)
    assert key_names(obj)[-1] == "Exaggerate Bend 1.50 from Basis"
    assert_old_keys_kept(bridge, obj, before)
    expected = core.Interpolator(positions_of(bridge, obj, "Basis"),
                                 positions_of(bridge, obj, "Bend"),
                                 bridge.triangulation.mesh_triangles(obj.data)).pose(1.5)
    np.testing.assert_allclose(positions_of(bridge, obj, "Exaggerate Bend 1.50 from Basis"), expected,
                               atol=TOLERANCE)


def test_reconstruct_uses_scene_settings(bpy_empty, extension, core):
    bridge = extension.bridge
    obj = posed_grid(bridge, 6)  # truncated recovery solves a convex program: keep it small
    settings = bpy.context.scene.shape_differences
    settings.k_m, settings.k_n, settings.use_extrinsic = 12, 16, True
    bpy.ops.shape_differences.reconstruct(key="Curl")
    assert key_names(obj)[-1] == "Reconstruct Curl (k 12/16)"  # k from the scene settings
    base, triangles = positions_of(bridge, obj, "Basis"), bridge.triangulation.mesh_triangles(obj.data)
    differences = core.shape_differences(base, positions_of(bridge, obj, "Curl"), triangles,
                                         k_M=12, k_N=16)
    np.testing.assert_allclose(positions_of(bridge, obj, "Reconstruct Curl (k 12/16)"),
                               core.reconstruct(base, triangles, differences), atol=TOLERANCE)


def test_operator_settings_override_the_scene(posed, core):
    obj, bridge = posed
    bpy.context.scene.shape_differences.k_m = 30
    bpy.ops.shape_differences.reconstruct(key="Bend", k_m=0, use_extrinsic=False)
    assert key_names(obj)[-1] == "Reconstruct Bend (k full/full)"
    base, triangles = positions_of(bridge, obj, "Basis"), bridge.triangulation.mesh_triangles(obj.data)
    differences = core.shape_differences(base, positions_of(bridge, obj, "Bend"), triangles,
                                         use_extrinsic=False)
    with pytest.warns(core.ShapeDifferenceWarning, match="intrinsic differences only"):  # a sheet bends freely
        expected = core.reconstruct(base, triangles, differences)
    np.testing.assert_allclose(positions_of(bridge, obj, key_names(obj)[-1]), expected, atol=TOLERANCE)


def test_ngons_are_triangulated(bpy_empty, extension, core):
    """A cylinder with n-gon caps goes through loop triangles."""
    bpy.ops.mesh.primitive_cylinder_add(vertices=12, depth=2.0, end_fill_type='NGON')
    obj = bpy.context.active_object
    bridge = extension.bridge
    rest = bridge.mesh_data.vertex_positions(obj.data)
    obj.shape_key_add(name="Basis")
    squashed = obj.shape_key_add(name="Squash")
    squashed.data.foreach_set("co", (rest * [1.2, 1.2, 0.7]).astype(np.float32).ravel())
    bpy.ops.shape_differences.inbetween(count=1)
    assert key_names(obj)[-1] == "Inbetween Basis-Squash 0.50"


def test_long_names_keep_the_factor_and_the_reference(bpy_empty, extension, core):
    bridge = extension.bridge
    obj = posed_grid(bridge, 5)
    long_a, long_b = "R_brow_raise_outer_corrective_left_side_v2", "R_brow_raise_outer_corrective_right_side_v2"
    obj.data.shape_keys.key_blocks["Curl"].name = long_a
    obj.data.shape_keys.key_blocks["Bend"].name = long_b
    for _ in range(2):
        bpy.ops.shape_differences.inbetween(key_a=long_a, key_b=long_b, count=7)
    bpy.ops.shape_differences.exaggerate(key=long_b, reference=long_a, factor=1.25)
    names = key_names(obj)[3:]
    assert len(names) == 15 and len(set(names)) == 15
    assert all(len(name.encode()) <= 63 for name in names)
    assert [name.split(" ")[-1] for name in names[:7]] == ["0.125", "0.25", "0.375", "0.50", "0.625",
                                                          "0.75", "0.875"]
    assert names[7].endswith(" 0.125.001") and names[13].endswith(" 0.875.001")
    assert names[14].startswith("Exaggerate R_brow") and " 1.25 from R_brow" in names[14]


def test_captured_keys_warn_about_double_deformation(bpy_empty, extension, capfd):
    """Keys captured from the evaluated mesh are moved again by the armature on playback (said);
    not by a Subdivision set aside while reading nor by Smooth by Angle (it moves nothing)."""
    from blender_scenes import armature_scene
    strip = armature_scene(frames=3)
    strip.modifiers.new("Subdivision", 'SUBSURF')
    with bpy.context.temp_override(active_object=strip, object=strip, selected_objects=[strip],
                                   selected_editable_objects=[strip]):
        bpy.ops.object.shade_auto_smooth()
    assert [m.type for m in strip.modifiers] == ['ARMATURE', 'SUBSURF', 'NODES']
    bpy.ops.shape_differences.frames_to_shape_keys(output='SHAPE_KEYS')
    assert f"deformed again by 'Armature' of '{strip.name}':" in capfd.readouterr().out


def test_captured_keys_warn_about_a_shape_key_left_at_a_value(bpy_empty, extension, capfd):
    """A relative key left at 0.5 is in every captured pose and adds its change once more when the
    new keys play (0.1 off at frame 1, the armature at rest): said beside the armature (before, only
    the armature was named, and disabling it left the key's change doubled)."""
    from blender_scenes import armature_scene
    strip = armature_scene(frames=3)
    rest = extension.bridge.mesh_data.vertex_positions(strip.data)
    add_key(strip, "Bump", rest + [0.0, 0.0, 0.2]).value = 0.5
    add_key(strip, "Muted", rest + [0.0, 0.0, 0.3]).mute = True
    strip.data.shape_keys.key_blocks["Muted"].value = 1.0
    bpy.ops.shape_differences.frames_to_shape_keys(output='SHAPE_KEYS')
    assert (f"deformed again by 'Armature', its shape key 'Bump' at 0.5 of '{strip.name}':"
            in capfd.readouterr().out)


def test_captured_keys_warn_about_shape_keys_played_by_nla_strips(bpy_empty, extension, capfd):
    """Shape-key values played by an NLA strip (the action pushed down, none active) move the new
    keys' mesh again on playback, as an active action does: the keyframed frames play the bend
    twice (before, nothing was said)."""
    from blender_scenes import driven_keys_scene
    obj = driven_keys_scene(frames=9)
    obj.data.shape_keys.key_blocks["Curl"].driver_remove("value")  # the strip alone moves the keys
    animation = obj.data.shape_keys.animation_data
    animation.nla_tracks.new().strips.new("Bend", 1, animation.action)
    animation.action = None
    bridge = extension.bridge
    [(_, bent)] = list(bridge.frame_reading.frame_positions(bpy.context, obj, [9]))
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=8, count=1,
                                               output='SHAPE_KEYS')
    assert f"deformed again by its animated shape keys of '{obj.name}':" in capfd.readouterr().out
    [(_, played)] = list(bridge.frame_reading.frame_positions(bpy.context, obj, [9]))
    rest = bridge.mesh_data.vertex_positions(obj.data)
    np.testing.assert_allclose(played - rest, 2 * (bent - rest), atol=1e-5)  # what the warning is about


@pytest.mark.parametrize("operator, options", [("inbetween_frames", dict(count=1)), ("retime", dict(speed=1.0))])
def test_a_refused_capture_says_nothing_of_the_keys_it_did_not_write(bpy_empty, extension, capfd, operator,
                                                                      options):
    """Keyframed shape keys that would be deformed again by the animated keys, refused by the core
    (the last frame collapses the mesh to a point): the refusal alone is said, not the warning about
    keys that were never written (before, that warning came first, then the refusal)."""
    from blender_scenes import driven_keys_scene
    obj = driven_keys_scene(frames=9)
    rest = extension.bridge.mesh_data.vertex_positions(obj.data)
    keys = obj.data.shape_keys.key_blocks
    bend, curl = (np.array([point.co[:] for point in keys[name].data]) for name in ("Bend", "Curl"))
    # at frame 9 Bend and Curl are at 1 (Curl = Bend²): with Flat at 1 too every vertex is at the origin
    flat = add_key(obj, "Flat", 2 * rest - bend - curl)
    for frame, value in ((1, 0.0), (9, 1.0)):
        flat.value = value
        flat.keyframe_insert("value", frame=frame)
    capfd.readouterr()
    with pytest.raises(RuntimeError, match="frame 9"):
        getattr(bpy.ops.shape_differences, operator)(frame_start=1, frame_end=9, frame_step=4, output='SHAPE_KEYS',
                                                     **options)
    assert "deformed again" not in capfd.readouterr().out
    assert key_names(obj) == ["Basis", "Bend", "Curl", "Flat"]


@pytest.mark.parametrize("operator, options", [("inbetween_frames", dict(count=1)), ("retime", dict(speed=1.0))])
def test_keyframed_keys_are_refused_while_an_nla_strip_of_the_keys_is_edited(bpy_empty, extension, operator,
                                                                             options):
    """With the shape keys' NLA strip in tweak mode, keyframes inserted go into that strip's action at
    its own time, so its scale and repeats replay them elsewhere (a strip scaled 2x and repeated
    twice: the last key, frame 9, not played) and the user's action gains the new keys' curves:
    refused before any work, naming tweak mode (before, written)."""
    from blender_scenes import assert_unchanged, driven_keys_scene
    obj = driven_keys_scene(frames=9)
    obj.data.shape_keys.key_blocks["Curl"].driver_remove("value")
    animation = obj.data.shape_keys.animation_data
    strip = animation.nla_tracks.new().strips.new("Bend", 1, animation.action)
    strip.scale, strip.repeat = 2.0, 2.0
    animation.action = None
    animation.use_tweak_mode = True
    before = snapshot(extension.bridge, obj)
    with pytest.raises(RuntimeError, match=r"An NLA strip of the shape keys of 'Driven' is being edited \(tweak mode\)"):
        getattr(bpy.ops.shape_differences, operator)(frame_start=1, frame_end=9, frame_step=4, output='SHAPE_KEYS',
                                                     **options)
    assert_unchanged(before, snapshot(extension.bridge, obj))
    assert key_names(obj) == ["Basis", "Bend", "Curl"]


@pytest.mark.parametrize("operator, factor", [("inbetween", 0.5), ("exaggerate", 1.5)])
def test_an_object_scaled_along_one_axis_turns_rigidly_in_the_world(bpy_empty, extension, operator, factor):
    """A sheet scaled (2, 1, 0.5) in Object Mode and not applied, whose key turns it rigidly by 80°
    in the world (what the artist sees): the in-between and the exaggeration turn it rigidly in the
    world too (before, interpolated in the mesh's own coordinates, where the turn looks sheared:
    world edge lengths 69 % off on average half-way, 270 % at ×1.5)."""
    import importlib

    from scipy.spatial.transform import Rotation

    from blender_scenes import stretched_sheet, world_turned

    bridge = extension.bridge
    sheet, linear, rest = stretched_sheet(bridge)
    turn = Rotation.from_rotvec([0.0, np.radians(80.0), 0.3]).as_matrix()
    add_key(sheet, "Turned", world_turned(rest, linear, turn))
    if operator == "inbetween":
        bpy.ops.shape_differences.inbetween(key_a="Basis", key_b="Turned", count=1)
    else:
        bpy.ops.shape_differences.exaggerate(key="Turned", reference="Basis", factor=factor)
    made = bridge.mesh_data.stored_key_positions(sheet.data.shape_keys.key_blocks[-1]) @ linear.T
    world_rest = rest @ linear.T
    edges = np.array([(e.vertices[0], e.vertices[1]) for e in sheet.data.edges])
    lengths = [np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1) for x in (world_rest, made)]
    np.testing.assert_allclose(lengths[1], lengths[0], rtol=1e-5)
    alignment = importlib.import_module(extension.__name__ + ".core.rigid_alignment")
    found = alignment.rigid_alignment(world_rest, made)[0]  # the world turn made: that fraction of the key's
    assert np.allclose(Rotation.from_matrix(found).as_rotvec(), Rotation.from_matrix(turn).as_rotvec() * factor,
                       atol=1e-4)


@pytest.mark.parametrize("through", ["armature", "lattice"])
@pytest.mark.parametrize("rig_scale", [(2.0, 1.0, 0.5), (-2.0, 1.0, 0.5)])
@pytest.mark.parametrize("operator, factor", [("inbetween", 0.5), ("exaggerate", 1.5)])
def test_a_mesh_an_armature_deforms_under_a_scaled_rig_turns_rigidly_in_the_rig_s_space(
        bpy_empty, extension, operator, factor, rig_scale, through):
    """A sheet parented to an armature object scaled (2, 1, 0.5) (and mirrored: (−2, 1, 0.5)) in
    Object Mode, deformed by it through an Armature modifier, or through a Lattice modifier whose
    lattice the armature deforms, whose key turns it rigidly by 80° in its own coordinates, which
    are the rig's space, where the armature turns its bones (and a lattice's points, which the sheet
    follows by fixed weights): the in-between and the exaggeration turn it rigidly there, by the
    factor's share of the turn, as for an unscaled rig (before, interpolated in the world's
    proportions, where the turn is a shear: a skinned limb half-way 0.23 of its diagonal off the
    rig, 0.026 unscaled; a bar in a lattice the rig bends 0.19, 0.035 in the rig's space)."""
    import importlib

    from scipy.spatial.transform import Rotation

    from blender_scenes import grid_object

    bridge = extension.bridge
    rig = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
    bpy.context.collection.objects.link(rig)
    rig.scale = rig_scale
    sheet = grid_object(8)
    sheet.parent = rig
    if through == "armature":
        sheet.modifiers.new("Armature", 'ARMATURE').object = rig
    else:
        lattice = bpy.data.objects.new("Lattice", bpy.data.lattices.new("Lattice"))
        bpy.context.collection.objects.link(lattice)
        lattice.modifiers.new("Armature", 'ARMATURE').object = rig
        sheet.modifiers.new("Lattice", 'LATTICE').object = lattice
    bpy.context.view_layer.update()
    assert not np.allclose(np.abs(np.linalg.svd(np.array(sheet.matrix_world.to_3x3()), compute_uv=False)), 1.0)
    rest = bridge.mesh_data.vertex_positions(sheet.data)
    turn = Rotation.from_rotvec([0.0, np.radians(80.0), 0.3]).as_matrix()
    add_key(sheet, "Turned", rest @ turn.T)
    if operator == "inbetween":
        bpy.ops.shape_differences.inbetween(key_a="Basis", key_b="Turned", count=1)
    else:
        bpy.ops.shape_differences.exaggerate(key="Turned", reference="Basis", factor=factor)
    made = bridge.mesh_data.stored_key_positions(sheet.data.shape_keys.key_blocks[-1]).astype(np.float64)
    edges = np.array([(e.vertices[0], e.vertices[1]) for e in sheet.data.edges])
    lengths = [np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1) for x in (rest, made)]
    np.testing.assert_allclose(lengths[1], lengths[0], rtol=1e-5)
    alignment = importlib.import_module(extension.__name__ + ".core.rigid_alignment")
    found = alignment.rigid_alignment(rest, made)[0]
    assert np.allclose(Rotation.from_matrix(found).as_rotvec(), Rotation.from_matrix(turn).as_rotvec() * factor,
                       atol=1e-4)


def test_the_rig_s_space_of_frames_read_is_that_of_their_frame(bpy_empty, extension):
    """A sheet parented to a rig scaled (2, 1, 0.5) whose object turns 90° between frame 1 and
    frame 20, deformed by it through an Armature modifier: the sheet's own coordinates are the
    rig's space at every frame (the rig carries it), so frames read at frame 1 while the scene
    stands at frame 20 are taken through no map (before, the rig's matrix of frame 20 against the
    sheet's of frame 1: a shear of the rig's stretch turned 90°); the scene is left at frame 20."""
    from blender_scenes import grid_object

    world_space = extension.bridge.world_space
    scene = bpy.context.scene
    rig = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
    bpy.context.collection.objects.link(rig)
    rig.scale = (2.0, 1.0, 0.5)
    for frame, angle in ((1, 0.0), (20, np.pi / 2)):
        rig.rotation_euler = (0.0, 0.0, angle)
        rig.keyframe_insert("rotation_euler", frame=frame)
    sheet = grid_object(4)
    sheet.parent = rig
    sheet.modifiers.new("Armature", 'ARMATURE').object = rig
    scene.frame_set(1)
    at_first = np.array(sheet.matrix_world)
    scene.frame_set(20)
    assert not np.allclose(np.array(sheet.matrix_world), at_first)  # the rig turned the sheet in the world
    space = world_space.frames_space(bpy.context, sheet, {1: at_first})
    assert space.linear() is None
    assert world_space.WorldProportions(sheet).linear() is None  # the shape keys', at frame 20
    assert scene.frame_current == 20


def _corner_map(split_positions, split_triangles, positions, triangles):
    """The vertex of a mesh (``positions``, ``triangles``) at each vertex of a copy of it split at
    seams: triangles matched by their corners' coordinates (equal in float32), corner for corner."""
    def keyed(x, t):  # (corners' coordinates, corner vertices) per triangle, from its smallest corner
        out = []
        for corners, triangle in zip(x[t].astype(np.float32), t):
            start = min(range(3), key=lambda k: tuple(corners[k]))
            order = [(start + k) % 3 for k in range(3)]
            out.append((corners[order].tobytes(), triangle[order]))
        return out
    original = dict(keyed(positions, triangles))
    out = np.full(len(split_positions), -1)
    for key, corners in keyed(split_positions, split_triangles):
        out[corners] = original[key]
    return out


def test_a_gltf_import_split_at_its_seams_is_in_betweened_as_the_welded_mesh(bpy_empty, extension, core):
    """Suzanne with Smart UV Project islands, round-tripped through glTF: the importer splits her
    vertices at the UV seams (507 → about 1,000) and shares one between two fans alike on both
    sides, a bow-tie until the seams are welded (her eyes also touch her head at seam vertices).
    In-between and Exaggerate give the in-betweens of the mesh before export, the seams closed
    (before: refused as a non-manifold mesh)."""
    import addon_utils

    try:
        addon_utils.enable("io_scene_gltf2", default_set=False)
        bpy.ops.import_scene.gltf.get_rna_type()
    except (KeyError, ImportError, ModuleNotFoundError):
        pytest.skip("Blender's glTF add-on is not available")
    import tempfile
    from pathlib import Path

    from scipy.spatial.transform import Rotation

    bridge = extension.bridge
    bpy.ops.mesh.primitive_monkey_add(size=2.0)
    original = bpy.context.active_object
    bpy.ops.object.mode_set(mode='EDIT')
    bpy.ops.mesh.select_all(action='SELECT')
    bpy.ops.uv.smart_project()
    bpy.ops.object.mode_set(mode='OBJECT')
    bpy.ops.object.shade_smooth()
    path = str(Path(tempfile.mkdtemp(prefix="gltf-seams-")) / "suzanne.glb")
    bpy.ops.export_scene.gltf(filepath=path, export_format='GLB', use_selection=True)
    bpy.ops.import_scene.gltf(filepath=path)
    obj = bpy.context.active_object
    assert obj != original and obj.type == 'MESH' and len(obj.data.vertices) > len(original.data.vertices)
    rest = bridge.mesh_data.vertex_positions(obj.data).astype(np.float64)
    triangles = bridge.triangulation.mesh_triangles(obj.data)
    welded_triangles = bridge.triangulation.mesh_triangles(original.data)
    welded = _corner_map(rest, triangles, bridge.mesh_data.vertex_positions(original.data), welded_triangles)
    first = np.unique(welded, return_index=True)[1]  # a split vertex of each welded one
    height = (rest[:, 2] - rest[:, 2].min()) / np.ptp(rest[:, 2])
    poses = {"Turned": (rest - rest.mean(axis=0)) @ Rotation.from_rotvec([0.5, 0.7, 0.4]).as_matrix().T,
             "Twisted": np.einsum("vij,vj->vi", Rotation.from_rotvec(np.outer(height, [0.0, 0.0, 1.2])).as_matrix(), rest)}
    for name, pose in poses.items():
        add_key(obj, name, pose)
    for name in poses:
        bpy.ops.shape_differences.inbetween(key_a="Basis", key_b=name, count=1)
        bpy.ops.shape_differences.exaggerate(key=name, reference="Basis", factor=2.0)
        expected = core.Interpolator(positions_of(bridge, obj, "Basis")[first], positions_of(bridge, obj, name)[first],
                                     welded_triangles)
        for key, factor in ((f"Inbetween Basis-{name} 0.50", 0.5), (f"Exaggerate {name} 2.00 from Basis", 2.0)):
            made = positions_of(bridge, obj, key)
            np.testing.assert_allclose(made, expected.pose(factor)[welded], atol=TOLERANCE)
            np.testing.assert_array_equal(made, made[first][welded])  # the seams closed


def test_a_quad_mesh_with_a_handle_is_reconstructed_exactly(bpy_empty, extension):
    """Blender's Torus splits its quads into triangles that two-colour (every vertex of even
    valence), whose areas full-basis differences cannot determine (paper Prop. 1): Reconstruct
    splits one quad the other way and recovers the key exactly (its edge lengths to float32
    precision, its shape to 1e-5 of the diagonal once laid on it)."""
    from scipy.spatial.transform import Rotation

    bridge = extension.bridge
    bpy.ops.mesh.primitive_torus_add(major_segments=48, minor_segments=12, major_radius=1.0, minor_radius=0.25)
    obj = bpy.context.active_object
    rest = bridge.mesh_data.vertex_positions(obj.data)
    bent = rest.copy()
    bent[:, 2] += 0.3 * rest[:, 0] ** 2
    add_key(obj, "Bend", bent)
    bpy.ops.shape_differences.reconstruct(key="Bend", k_m=0)
    result = positions_of(bridge, obj, key_names(obj)[-1])
    key = positions_of(bridge, obj, "Bend")
    edges = np.array([edge.vertices[:] for edge in obj.data.edges])
    lengths = [np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1) for p in (result, key)]
    np.testing.assert_allclose(lengths[0], lengths[1], rtol=1e-5)
    turn, _ = Rotation.align_vectors(key - key.mean(axis=0), result - result.mean(axis=0))
    laid = turn.apply(result - result.mean(axis=0)) + key.mean(axis=0)
    assert np.abs(laid - key).max() < 1e-5 * np.linalg.norm(np.ptp(key, axis=0))


@pytest.mark.parametrize("operator, factor", [("inbetween", 0.5), ("exaggerate", 2.0)])
def test_a_rigid_motion_keyed_in_single_precision_with_slivers_stays_rigid(bpy_empty, extension, operator, factor):
    """A tube with 28 T-junction slivers 1e-5 of their side high (a scan's), whose shape key turns
    it rigidly by 60° and shifts it, stored in single precision as Blender stores keys (rounding
    4.2e-8 of the diagonal, over the slivers' height): the in-between and the exaggeration are the
    screw motion to within the rounding the factor carries (and the new key's own). The slivers'
    turns, read from the rounding, bent the tube around them: 5.2e-7 off at 0.5, 2.7e-2 at ×2."""
    import sys
    from pathlib import Path

    from scipy.spatial.transform import Rotation

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "core"))
    from placement_helpers import _screw
    from test_placement_exaggeration import _tube, _with_slivers

    bridge = extension.bridge
    vertices, triangles = _with_slivers(*_tube(), 1e-5)
    mesh = bpy.data.meshes.new("Scan")
    mesh.from_pydata(vertices.tolist(), [], triangles.tolist())
    scan = bpy.data.objects.new("Scan", mesh)
    bpy.context.collection.objects.link(scan)
    bpy.context.view_layer.objects.active = scan
    rest = bridge.mesh_data.vertex_positions(mesh).astype(np.float64)
    axis = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])
    turn, shift = Rotation.from_rotvec(np.radians(60.0) * axis).as_matrix(), np.array([0.3, 0.2, -0.1])
    add_key(scan, "Turned", rest @ turn.T + shift)
    stored = positions_of(bridge, scan, "Turned").astype(np.float64)
    diagonal = np.linalg.norm(np.ptp(rest, axis=0))
    rounding = np.linalg.norm(stored - (rest @ turn.T + shift), axis=1).max()
    if operator == "inbetween":
        bpy.ops.shape_differences.inbetween(key_a="Basis", key_b="Turned", count=1)
    else:
        bpy.ops.shape_differences.exaggerate(key="Turned", reference="Basis", factor=factor)
    made = bridge.mesh_data.stored_key_positions(scan.data.shape_keys.key_blocks[-1]).astype(np.float64)
    off = np.linalg.norm(made - _screw(rest, turn, shift, factor), axis=1).max()
    assert off < (2.0 * max(factor, 1.0) + 1.0) * rounding, (off / diagonal, rounding / diagonal)


@pytest.fixture
def given_rests(core, monkeypatch):
    """The ``rest_pose`` each ``core.Interpolator`` the operators make is given (None where none),
    in order."""
    given, original = [], core.Interpolator

    def recording(*args, **kwargs):
        given.append(kwargs.get("rest_pose"))
        return original(*args, **kwargs)

    monkeypatch.setattr(core, "Interpolator", recording)
    return given


def test_inbetween_measures_its_edge_warning_from_the_basis(posed, core, given_rests):
    """In-between of Curl and Bend gives ``core.Interpolator`` the Basis as its ``rest_pose`` (the
    shape the keys were made on, what its edge warning measures the poses' deviation from; before,
    none: the least deviation the two can have from any rest they share), and writes the poses of the
    same keys without it. Nothing is given where the keys are absolute (the Basis is the first pose
    Evaluation Time plays, not a rest) or where the Basis is over twice the poses' size (not their
    rest: the core would refuse it)."""
    obj, bridge = posed
    given = given_rests
    bpy.ops.shape_differences.inbetween(key_a="Curl", key_b="Bend", count=1)
    (rest,) = given
    assert rest is not None
    np.testing.assert_allclose(rest, positions_of(bridge, obj, "Basis"), atol=TOLERANCE)
    triangles = bridge.triangulation.mesh_triangles(obj.data)
    np.testing.assert_allclose(positions_of(bridge, obj, "Inbetween Curl-Bend 0.50"),
                               core.two_pose_inbetweens.Interpolator(
                                   positions_of(bridge, obj, "Curl"), positions_of(bridge, obj, "Bend"),
                                   triangles).pose(0.5), atol=TOLERANCE)
    obj.data.shape_keys.use_relative = False
    bpy.ops.shape_differences.inbetween(key_a="Curl", key_b="Bend", count=1)
    obj.data.shape_keys.use_relative = True
    basis = obj.data.shape_keys.key_blocks["Basis"]
    basis.data.foreach_set("co", (3.0 * positions_of(bridge, obj, "Basis")).astype(np.float32).ravel())
    bpy.ops.shape_differences.inbetween(key_a="Curl", key_b="Bend", count=1)
    assert given[1:] == [None, None]


def test_inbetween_measures_its_edge_warning_from_the_cloths_rest(posed, given_rests):
    """Where a cloth simulates the mesh, In-between gives ``core.Interpolator`` the rest the cloth
    builds its springs from: the Basis where a Rest Shape Key is set with nothing before the cloth
    (Blender reads no such key there: test_frame_operators.py,
    ``test_a_cloths_rest_shape_key_counts_only_behind_a_modifier_not_of_blenders_deform_only_kind``; before, the
    key was given, 5 % off the springs), the Basis's edges scaled by 1 − Shrinking (0.1: springs 0.9 ×
    the mesh's edges), and none where no key is that rest: Dynamic Mesh on (the rest follows the
    modifiers before the cloth), a Subdivision Surface before the cloth (its rest is a mesh of other
    vertices), a Shrinking vertex group between two factors."""
    obj, bridge = posed
    given = given_rests
    basis = positions_of(bridge, obj, "Basis")
    rest_key = add_key(obj, "Cloth Rest", 1.05 * basis + [0.0, 0.0, 0.2])
    obj.active_shape_key_index = 2
    cloth = obj.modifiers.new("Cloth", 'CLOTH').settings
    cloth.rest_shape_key = rest_key

    def inbetween():  # to a point cache: keys added would empty the unbaked cloth's cache
        bpy.context.view_layer.objects.active = obj
        bpy.ops.shape_differences.inbetween(key_a="Curl", key_b="Bend", count=1, output='CACHE')
        return given[-1]

    np.testing.assert_allclose(inbetween(), basis, atol=TOLERANCE)  # not the key, which Blender does not read
    cloth.rest_shape_key = obj.data.shape_keys.key_blocks["Basis"]  # (Blender does not take None here)
    cloth.shrink_min = 0.1
    shrunk = inbetween()
    centre = basis.mean(axis=0)
    np.testing.assert_allclose(shrunk, centre + 0.9 * (basis - centre), atol=TOLERANCE)
    triangles = bridge.triangulation.mesh_triangles(obj.data)
    edges = [np.linalg.norm(p[triangles] - p[np.roll(triangles, 1, axis=1)], axis=2) for p in (shrunk, basis)]
    np.testing.assert_allclose(edges[0], 0.9 * edges[1], rtol=1e-5)
    obj.vertex_groups.new(name="Shrink")
    cloth.vertex_group_shrink, cloth.shrink_max = "Shrink", 0.3
    assert inbetween() is None
    cloth.vertex_group_shrink, cloth.shrink_min = "", 0.0
    cloth.use_dynamic_mesh = True
    assert inbetween() is None
    cloth.use_dynamic_mesh = False
    obj.modifiers.new("Subdivision", 'SUBSURF')
    obj.modifiers.move(1, 0)
    assert inbetween() is None
    obj.modifiers.move(0, 1)  # after the cloth: the cloth's rest is the Basis again
    np.testing.assert_allclose(inbetween(), basis, atol=TOLERANCE)
