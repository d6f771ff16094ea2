"""Shape Space and Distortion Maps through bpy.ops: results as core computes them, an image and
custom properties or attributes written, and positions, keys and animation left as they were."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import add_key, armature_scene, assert_unchanged, grid_object, posed_grid, rolled, snapshot  # noqa: E402,F401


@pytest.fixture
def keyed(bpy_empty, extension, core):
    """A grid with Basis, Curl, Bend and mirrored copies of both (isometric to them)."""
    obj = posed_grid(extension.bridge, 10)
    rest = extension.bridge.mesh_data.vertex_positions(obj.data)
    for name, angle in (("Curl down", 2.0), ("Bend down", 1.0)):
        add_key(obj, name, rolled(rest, angle) * np.array([1.0, 1.0, -1.0]))
    obj.active_shape_key_index = 2
    return obj, extension.bridge


def test_shape_space_of_keys(keyed, core):
    obj, bridge = keyed
    before = snapshot(bridge, obj)
    bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=40)
    assert_unchanged(before, snapshot(bridge, obj))
    data = obj["shape_space"].to_dict()
    names = [kb.name for kb in obj.data.shape_keys.key_blocks]
    assert list(data["poses"]) == names
    poses = [bridge.mesh_data.stored_key_positions(kb) for kb in obj.data.shape_keys.key_blocks]
    space = core.shape_space(poses, bridge.triangulation.mesh_triangles(obj.data), k_M=20, k_N=40)
    for kind in ("area", "offset_area"):
        stored = np.reshape(data["coordinates"][kind], (-1, 2))
        np.testing.assert_allclose(stored, space.coordinates(kind, 2), atol=1e-9 * np.abs(stored).max())
    # The mirrored keys coincide intrinsically and not with the offset.
    area = np.reshape(data["coordinates"]["area"], (-1, 2))
    offset = np.reshape(data["coordinates"]["offset_area"], (-1, 2))
    assert np.linalg.norm(area[1] - area[3]) <= 1e-6 * np.abs(area).max()
    assert np.linalg.norm(offset[1] - offset[3]) > 0.1 * np.abs(offset).max()
    image = bpy.data.images[data["image"]]
    pixels = np.empty(image.size[0] * image.size[1] * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    assert image.size[0] > 4 * image.size[1] / 2 and pixels.reshape(-1, 4)[:, :3].std() > 0.05


def test_select_pose_by_its_place_along_the_first_axis(keyed):
    obj, bridge = keyed
    bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=0)
    # A copy: a view of the ID property would dangle once the operator stores the selection.
    first = np.array(obj["shape_space"]["coordinates"]["offset_area"], dtype=float).reshape(-1, 2)[:, 0]
    keys_before = snapshot(bridge, obj)["keys"]
    bpy.ops.shape_differences.shape_space_select(kind='offset_area', rank=0)
    assert obj.active_shape_key_index == int(np.argmin(first))
    bpy.ops.shape_differences.shape_space_select(kind='offset_area', rank=-1, step=1)
    assert obj.active_shape_key_index == int(np.argsort(first)[1])
    assert snapshot(bridge, obj)["keys"].keys() == keys_before.keys()


def test_shape_space_of_frames_keeps_the_animation(bpy_empty, extension, core):
    obj = armature_scene(frames=9)
    bridge = extension.bridge
    before = snapshot(bridge, obj)
    bpy.ops.shape_differences.shape_space(source='FRAMES', frame_start=1, frame_end=9, k_m=15, k_n=30)
    assert_unchanged(before, snapshot(bridge, obj))
    data = obj["shape_space"].to_dict()
    assert list(data["frames"]) == list(range(1, 10))
    xy = np.reshape(data["coordinates"]["offset_area"], (-1, 2))
    distance = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    np.fill_diagonal(distance, np.inf)
    assert np.all(np.abs(distance.argmin(axis=1) - np.arange(9)) == 1)  # a curve in playing order
    bpy.ops.shape_differences.shape_space_select(kind='offset_area', rank=0)
    assert bpy.context.scene.frame_current in (1, 9)


def test_distortion_maps_of_the_active_key(keyed, core):
    obj, bridge = keyed
    before = snapshot(bridge, obj)
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', k_m=20, eigenfunctions=1)
    assert_unchanged(before, snapshot(bridge, obj))
    mesh = obj.data
    for name in ("SD Area", "SD Conformal", "SD Bending", "SD Eigen Offset Area 1"):
        assert mesh.color_attributes.get(name) is not None, name
    values = np.empty(len(mesh.vertices), dtype=np.float32)
    mesh.attributes["sd_bending"].data.foreach_get("value", values)
    basis, bend = (bridge.mesh_data.stored_key_positions(mesh.shape_keys.key_blocks[n]) for n in ("Basis", "Bend"))
    expected = core.distortion(basis, bend, bridge.triangulation.mesh_triangles(mesh), k=20).bending_vertices
    np.testing.assert_allclose(values, expected, atol=1e-5)
    faces = np.empty(len(mesh.polygons), dtype=np.float32)
    mesh.attributes["sd_area_face"].data.foreach_get("value", faces)
    assert np.all(np.isfinite(faces))
    assert mesh.color_attributes.active_color.name == "SD Area"


@pytest.mark.parametrize("own_color", [False, True], ids=["no colour attribute", "the user's colour attribute"])
def test_distortion_maps_leave_the_render_colour_attribute(keyed, own_color):
    """The maps become the active colour attribute, which the viewport shows, and leave the one
    renders and exporters use where none is named (a Color Attribute node left blank, an FBX or glTF
    export) as it was: on a mesh without colour attributes the first map added became it (before)."""
    obj, _bridge = keyed
    colors = obj.data.color_attributes
    if own_color:
        colors.new("Col", 'BYTE_COLOR', 'CORNER')
    before = colors.default_color_name
    assert before == ("Col" if own_color else "")
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', k_m=20, eigenfunctions=1)
    assert colors.active_color_name == "SD Area" and colors.default_color_name == before


def test_distortion_maps_of_frames(bpy_empty, extension):
    obj = armature_scene(frames=5)
    bridge = extension.bridge
    before = snapshot(bridge, obj)
    bpy.ops.shape_differences.distortion_maps(source='FRAMES', frame_start=1, frame_end=5, frame_step=2,
                                              k_m=15, eigenfunctions=0)
    assert_unchanged(before, snapshot(bridge, obj))
    for frame in (1, 3, 5):
        assert obj.data.color_attributes.get(f"SD Bending f{frame}") is not None
    # Playback shows each frame's map (the last mapped frame before it in between).
    for frame, shown in ((3, "SD Area f3"), (4, "SD Area f3"), (5, "SD Area f5")):
        bpy.context.scene.frame_set(frame)
        assert obj.data.color_attributes.active_color.name == shown
    obj.data.color_attributes.active_color = obj.data.color_attributes["SD Bending f5"]
    bpy.context.scene.frame_set(1)
    assert obj.data.color_attributes.active_color.name == "SD Bending f1"
    assert_unchanged(dict(before, frame=1), snapshot(bridge, obj))
    # maps of a second run (frames 2 and 4) beside the first's: playback follows all of them (before,
    # only the last run's frames: picking f1 at frame 1 and playing to 3 showed f4's)
    bpy.ops.shape_differences.distortion_maps(source='FRAMES', frame_start=2, frame_end=4, frame_step=2,
                                              k_m=15, eigenfunctions=0)
    obj.data.color_attributes.active_color = obj.data.color_attributes["SD Area f1"]
    bpy.context.scene.frame_set(3)
    assert obj.data.color_attributes.active_color.name == "SD Area f3"
    # a colour attribute of the user's picked: it stays (before, a frame change replaced it by "SD Area f3")
    own = obj.data.color_attributes.new("Col", 'FLOAT_COLOR', 'POINT')
    obj.data.color_attributes.active_color = own
    bpy.context.scene.frame_set(3)
    assert obj.data.color_attributes.active_color.name == "Col"


def test_errors_change_nothing(keyed):
    obj, bridge = keyed
    before = snapshot(bridge, obj)
    with pytest.raises(RuntimeError, match="is the Basis"):
        bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Basis")
    with pytest.raises(RuntimeError, match="too large"):
        bpy.ops.shape_differences.shape_space(source='KEYS', k_m=500)
    with pytest.raises(RuntimeError, match="Run Shape Space"):
        bpy.ops.shape_differences.shape_space_select(rank=0)
    assert_unchanged(before, snapshot(bridge, obj))
    assert "shape_space" not in obj and obj.data.color_attributes.get("SD Area") is None


def test_a_small_mesh_and_poses_that_do_not_differ(bpy_empty, extension, capfd):
    """On an 81-vertex grid the default basis sizes (k_M 50, k_N 100) shrink to the mesh (before,
    "k_N = 100 is too large" for a size the user never set); a size the user sets is still
    checked. A key equal to the Basis: its maps are one neutral colour and a warning says its
    eigenfunction maps are arbitrary; a shape space of poses that do not differ says it has no
    spread (before: "share of PC 1: 100 %" of round-off)."""
    obj = grid_object(8)
    rest = extension.bridge.mesh_data.vertex_positions(obj.data)
    add_key(obj, "Same", rest)
    add_key(obj, "Also same", rest)
    obj.active_shape_key_index = 1
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', eigenfunctions=1)
    out = capfd.readouterr().out
    assert "'Same' does not change the base" in out and "eigenfunction maps are arbitrary" in out
    colours = obj.data.color_attributes["SD Area"]
    values = np.zeros(len(colours.data) * 4)
    colours.data.foreach_get("color", values)
    assert len(np.unique(values.reshape(-1, 4), axis=0)) == 1
    bpy.ops.shape_differences.shape_space(source='KEYS')
    out = capfd.readouterr().out
    assert "no spread" in out and "share of PC 1: area 0 %" in out
    with pytest.raises(RuntimeError, match="k_N = 100 is too large for a mesh with 81 vertices"):
        bpy.ops.shape_differences.shape_space(source='KEYS', k_n=100)


def test_maps_of_an_object_scaled_along_one_axis_measure_the_world(bpy_empty, extension):
    """A sheet scaled (2, 1, 0.5) and not applied, its key a rigid turn in the world: no area
    change (before, measured in the mesh's stretched coordinates: log area changes up to 1.36)."""
    from scipy.spatial.transform import Rotation

    from blender_scenes import stretched_sheet, world_turned

    sheet, linear, rest = stretched_sheet(extension.bridge)
    add_key(sheet, "Turned", world_turned(rest, linear, Rotation.from_rotvec([0.0, np.radians(80.0), 0.3]).as_matrix()))
    sheet.active_shape_key_index = 1
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', eigenfunctions=0)
    values = np.zeros(len(sheet.data.vertices))
    sheet.data.attributes["sd_area"].data.foreach_get("value", values)
    assert np.abs(values).max() < 1e-5  # float32 keys


def _area_map(obj, frame: int) -> np.ndarray:
    """The area distortion Distortion Maps stored on ``obj``'s mesh for ``frame``, per vertex."""
    values = np.zeros(len(obj.data.vertices))
    obj.data.attributes[f"sd_area f{frame}"].data.foreach_get("value", values)
    return values


def test_maps_of_frames_of_an_object_whose_scale_is_keyframed_measure_the_world(bpy_empty, extension, tmp_path):
    """A sheet turning rigidly in the world while its object's scale is keyframed 1 → 2 (its own
    coordinates shrink to half): no area change at any frame, to float32 (before, every frame was
    measured in the object's own coordinates: area changes of 0.81 and 1.39 in log at frames 5
    and 9, the shrink)."""
    from blender_scenes import turning_sheet_scale_keyframed

    sheet, _scale, _world = turning_sheet_scale_keyframed(extension, tmp_path)
    bpy.context.scene.frame_set(1)
    bpy.ops.shape_differences.distortion_maps(source='FRAMES', frame_start=1, frame_end=9, frame_step=4,
                                              eigenfunctions=0)
    for frame in (1, 5, 9):
        assert np.abs(_area_map(sheet, frame)).max() < 1e-5, frame


def test_maps_of_frames_measure_the_proportions_of_the_frames_read(bpy_empty, extension, tmp_path):
    """A sheet stretched (2, 1, 0.5) over frames 3–11, turning rigidly in the world, measured while
    the scene is at frame 1, where its keyframed scale is 1: no area change at any frame read, to
    float32 (before, the world's proportions were taken at the current frame: log area changes up to
    1.06 where there are none)."""
    from blender_scenes import turning_sheet_stretched_before_its_frames

    sheet, _linear, _turned = turning_sheet_stretched_before_its_frames(extension, tmp_path)
    bpy.ops.shape_differences.distortion_maps(source='FRAMES', frame_start=3, frame_end=11, frame_step=4,
                                              eigenfunctions=0)
    for frame in (3, 7, 11):
        assert np.abs(_area_map(sheet, frame)).max() < 1e-5, frame


def test_shape_space_of_frames_of_an_object_whose_scale_is_keyframed_is_that_of_the_world(bpy_empty, extension,
                                                                                          tmp_path):
    """A sheet stretching and turning in the world while its object's scale is keyframed 1 → 2: its
    shape space is that of the same world motion on an object whose scale is not keyed (the
    distances between its points the same, to float32; before, the frames' shrink in the object's
    own coordinates was measured too: the area embeddings' distances 0.69 of the largest off)."""
    from blender_scenes import turning_sheet_scale_keyframed

    spaces = []
    for keyed in (True, False):
        sheet, _scale, _world = turning_sheet_scale_keyframed(extension, tmp_path, stretch=0.05, scale_keyed=keyed)
        bpy.context.view_layer.objects.active = sheet
        bpy.context.scene.frame_set(1)
        bpy.ops.shape_differences.shape_space(source='FRAMES', frame_start=1, frame_end=9, frame_step=2,
                                              k_m=15, k_n=30)
        data = sheet["shape_space"].to_dict()
        points = {kind: np.reshape(data["coordinates"][kind], (-1, 2)) for kind in data["coordinates"]}
        spaces.append({kind: np.linalg.norm(xy[:, None] - xy[None], axis=2) for kind, xy in points.items()})
    for kind, distances in spaces[1].items():
        assert distances.max() > 1e-2, kind  # the stretch is seen
        np.testing.assert_allclose(spaces[0][kind], distances, atol=1e-4 * distances.max(), err_msg=kind)


def test_bending_of_a_swell_keeps_its_sign_on_a_mirrored_stretched_object(bpy_empty, extension):
    """A sphere swelling outward near its top bends the same way on an object scaled (2, 1, 1)
    and (−2, 1, 1) (before, the mirrored one was measured in world coordinates with its triangles
    inside out: bending +0.31 against −0.52)."""
    bending = []
    for scale in ((2.0, 1.0, 1.0), (-2.0, 1.0, 1.0)):
        bpy.ops.wm.read_homefile(use_empty=True)
        bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=1.0)
        obj = bpy.context.active_object
        obj.scale = scale
        bpy.context.view_layer.update()
        rest = extension.bridge.mesh_data.vertex_positions(obj.data)
        add_key(obj, "Swell", rest * (1.0 + 0.15 * np.exp(-8.0 * np.sum((rest - [0, 0, 1]) ** 2, axis=1)))[:, None])
        obj.active_shape_key_index = 1
        bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', eigenfunctions=0)
        values = np.zeros(len(rest))
        obj.data.attributes["sd_bending"].data.foreach_get("value", values)
        bending.append(values)
    top = np.argmax(rest[:, 2])
    assert bending[0][top] > 0.1
    assert np.allclose(bending[1], bending[0], atol=1e-5)


def test_default_sizes_shrink_to_the_vertices_in_faces(bpy_empty, extension):
    """A 49-vertex sheet with 5 loose vertices: the default sizes shrink to 48 (before, to 53, which
    the core refused: "must be between 1 and 48; got 50" for sizes nobody set)."""
    obj = grid_object(6)
    obj.data.vertices.add(5)
    rest = extension.bridge.mesh_data.vertex_positions(obj.data)
    for index, angle in enumerate((0.5, 1.0, 1.5)):
        bent = rest.copy()
        bent[:49] = rolled(rest[:49], angle)
        add_key(obj, f"Bend {index}", bent)
    result = bpy.ops.shape_differences.shape_space(source='KEYS')
    assert result == {'FINISHED'}
    stored = extension.bridge.analysis_data.stored_shape_space(obj)
    assert (stored["k_M"], stored["k_N"]) == (48, 48)


def test_keys_that_only_move_the_mesh_and_stale_eigenfunction_maps(bpy_empty, extension, capfd):
    """Keys that turn and move an ico sphere (Blender stores them in single precision, so their
    shape differences are the coordinates' rounding, 1e-6): the shape space has no spread and says
    so, the distortion maps are one neutral colour and a warning says the pose does not change the
    base (before: PC shares of 60 / 23 / 15 %, colours spanning 0.86 of a channel, no warning).
    Eigenfunction maps of an earlier run (another key, more functions) are removed, the summary
    counts the maps written, and k_M above k_N is accepted: the maps do not use k_N."""
    from scipy.spatial.transform import Rotation

    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=1.0)
    obj = bpy.context.active_object
    rest = extension.bridge.mesh_data.vertex_positions(obj.data)
    for s in range(1, 4):
        add_key(obj, f"Moved {s}", rest @ Rotation.from_rotvec([0.4 * s, -0.3, 0.2]).as_matrix().T + [s, -s, 0.5])
    obj.active_shape_key_index = 1
    bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=0)
    assert "no spread" in capfd.readouterr().out
    add_key(obj, "Squash", rest * [1.0, 1.0, 0.6])
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Moved 1", eigenfunctions=0)
    assert "'Moved 1' does not change the base" in capfd.readouterr().out
    for name in ("SD Area", "SD Conformal", "SD Bending"):
        colours = np.zeros(len(obj.data.vertices) * 4)
        obj.data.color_attributes[name].data.foreach_get("color", colours)
        assert len(np.unique(colours.reshape(-1, 4), axis=0)) == 1, name
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Squash", eigenfunctions=4, k_m=150, k_n=100)
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Squash", eigenfunctions=1, k_m=2)
    out = capfd.readouterr().out
    eigen = sorted(a.name for a in obj.data.attributes if a.name.startswith("SD Eigen"))
    # k_M = 2: the constant and one more function; the conformal kinds drop the constant
    assert eigen == ["SD Eigen Area 1", "SD Eigen Conformal 1", "SD Eigen Offset Area 1", "SD Eigen Offset Conformal 1"]
    assert "and 4 eigenfunction maps" in out and "does not change" not in out


def test_maps_of_faces_that_share_no_edge(bpy_empty, extension, capfd):
    """Three separate triangles (no edge shared, so no offset surface): the area and conformal maps
    are written and a warning says there is no bending map (before: refused with advice to turn off
    extrinsic differences, a setting this operator does not have)."""
    mesh = bpy.data.meshes.new("Scraps")
    vertices = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 0, 0), (3, 0, 0), (2, 1, 0), (4, 0, 0), (5, 0, 0), (4, 1, 0)],
                        dtype=float)
    mesh.from_pydata(vertices.tolist(), [], [(0, 1, 2), (3, 4, 5), (6, 7, 8)])
    obj = bpy.data.objects.new("Scraps", mesh)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    add_key(obj, "Stretched", vertices * [1.5, 1.0, 1.0])
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Stretched", eigenfunctions=1, k_m=5)
    out = capfd.readouterr().out
    assert "no bending map" in out and "SD Bending" not in out.split("Wrote")[-1]
    values = np.zeros(len(vertices))
    mesh.attributes["sd_area"].data.foreach_get("value", values)
    assert np.allclose(values, np.log(1.5), atol=1e-6)
    assert "SD Bending" not in mesh.attributes


def test_round_off_neither_hides_a_small_swell_nor_shows_as_noise(bpy_empty, extension, capfd):
    """A swell over 0.6 % of a sheet is coloured (before, the whole map was neutral when its 98th
    percentile was within the round-off); on an object scaled (1.3, 1, 0.7), not applied, 1,000
    units out, a key that only moves the mesh gives neutral maps and the warning (before, the
    world's proportions, computed in double precision, read as double-precision keys: 152
    colours of noise)."""
    obj = grid_object(40)
    rest = extension.bridge.mesh_data.vertex_positions(obj.data)
    swell = rest.copy()
    r = np.linalg.norm(rest[:, :2] - [0.3, -0.4], axis=1)
    swell[:, 2] += 0.08 * np.clip(1 - r / 0.09, 0, None) ** 2  # 0.6 % of the sheet
    add_key(obj, "Swell", swell)
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Swell", eigenfunctions=0)
    colours = np.zeros(len(rest) * 4)
    obj.data.color_attributes["SD Area"].data.foreach_get("color", colours)
    assert len(np.unique(colours.reshape(-1, 4), axis=0)) > 1
    capfd.readouterr()
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=20, y_subdivisions=20, size=2.0, location=(1000.0, 0.0, 0.0))
    skewed = bpy.context.active_object
    skewed.scale = (1.3, 1.0, 0.7)
    bpy.context.view_layer.update()
    rest = extension.bridge.mesh_data.vertex_positions(skewed.data)
    add_key(skewed, "Moved", rest + [0.25, -0.5, 0.3])
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Moved", eigenfunctions=0)
    assert "'Moved' does not change the base" in capfd.readouterr().out
    for name in ("SD Area", "SD Conformal", "SD Bending"):
        colours = np.zeros(len(rest) * 4)
        skewed.data.color_attributes[name].data.foreach_get("color", colours)
        assert len(np.unique(colours.reshape(-1, 4), axis=0)) == 1, name


def test_messages_name_the_key_or_frame_and_maps_need_no_basis(bpy_empty, extension, capfd):
    """A key with a non-finite coordinate: Distortion Maps and Shape Space name it (before: "pose
    vertices", "pose 2"); maps without eigenfunctions are written whatever k_M is (before:
    "k_M = 100 is too large for a mesh with 49 vertices" for a basis they do not use)."""
    obj = posed_grid(extension.bridge, 6)
    broken = extension.bridge.mesh_data.vertex_positions(obj.data)
    broken[5, 2] = np.nan
    add_key(obj, "Broken", broken)
    with pytest.raises(RuntimeError, match="shape key 'Broken' of 'Sheet': vertex 5"):
        bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Broken", eigenfunctions=0)
    with pytest.raises(RuntimeError, match="shape key 'Broken' of 'Sheet': vertex 5"):
        bpy.ops.shape_differences.shape_space(source='KEYS', k_m=10, k_n=0)
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Bend", eigenfunctions=0, k_m=100)
    assert "sd_area" in obj.data.attributes


def test_playing_maps_of_frames_keeps_an_unbaked_cloth_cache(bpy_empty, extension):
    """Maps of a baked cloth's frames, then its bake freed (to change a setting) and played: making
    a frame's map the active colour attribute marks the cloth's cache outdated, and Blender empties
    it back at the start (before: 13 frames played, 0 left at frame 1). The map shown stays while
    the cloth is not baked; baked again, playback follows the frames."""
    from blender_scenes import pinned_cloth_scene
    obj = pinned_cloth_scene(frames=13, bake=True)
    scene = bpy.context.scene
    bpy.ops.shape_differences.distortion_maps(source='FRAMES', frame_step=4, eigenfunctions=0, k_m=10)
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.free_bake_all()
    cache = obj.modifiers["Cloth"].point_cache
    for frame in range(1, 14):
        scene.frame_set(frame)
    assert cache.info.startswith("13 frames") and not cache.is_outdated
    scene.frame_set(1)
    assert cache.info.startswith("13 frames")
    assert obj.data.color_attributes.active_color.name == "SD Area f1"
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    scene.frame_set(9)
    assert obj.data.color_attributes.active_color.name == "SD Area f9"


def test_select_pose_reports_a_shape_space_edited_by_hand(keyed):
    """A stored shape space whose lists no longer agree (edited by hand, or written by another
    version) ended Select Pose in an IndexError traceback: reported, nothing changed."""
    obj, bridge = keyed
    bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=0)
    data = obj["shape_space"].to_dict()
    data["poses"] = []
    obj["shape_space"] = data
    image = bpy.data.images[data["image"]]
    pixels = np.array(image.pixels[:])
    active = obj.active_shape_key_index
    with pytest.raises(RuntimeError, match="The shape space stored on 'Sheet' cannot be read") as failure:
        bpy.ops.shape_differences.shape_space_select(kind='offset_area', rank=4)
    assert "Traceback" not in str(failure.value)
    assert obj.active_shape_key_index == active and obj["shape_space"].to_dict() == data
    np.testing.assert_array_equal(np.array(image.pixels[:]), pixels)
