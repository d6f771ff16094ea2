"""Transfer Poses through bpy.ops: poses of a differently meshed object rebuilt on the active mesh
as new shape keys, with the map from closest points or from a vertex attribute."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import (add_key, cloth_scene, grid_object, key_names, rolled, snapshot,  # noqa: E402
                            transfer_pair, with_boundary_sliver)

TOLERANCE = 1e-4  # float32 storage of a ~2 unit mesh


def hausdorff(a, b):
    from scipy.spatial import cKDTree

    return max(cKDTree(a).query(b)[0].max(), cKDTree(b).query(a)[0].max())


@pytest.fixture
def pair(bpy_empty, extension, core):
    """A 15 × 15 source grid with a "Bend" key and an 11 × 11 grid (active) over it, both selected."""
    bridge = extension.bridge
    source, target = transfer_pair(bridge, 14, 10)
    return source, target, bridge


def test_transfer_keys_by_closest_points(pair, core):
    source, target, bridge = pair
    bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=32)
    assert key_names(target) == ["Basis", "Source Bend"]
    rebuilt = bridge.mesh_data.stored_key_positions(target.data.shape_keys.key_blocks["Source Bend"])
    rest = bridge.mesh_data.vertex_positions(target.data)
    expected = core.Transfer(rest, bridge.triangulation.mesh_triangles(target.data),
                             bridge.mesh_data.vertex_positions(source.data),
                             bridge.triangulation.mesh_triangles(source.data), k_M=16, k_N=32).pose(
        bridge.mesh_data.stored_key_positions(source.data.shape_keys.key_blocks["Bend"]))
    np.testing.assert_allclose(rebuilt, expected, atol=TOLERANCE)
    truth = rolled(rest, 1.0)  # the source's pose is this surface; the rebuild is placed on it
    assert hausdorff(rebuilt, truth) < 0.5 * hausdorff(rest, truth)


def test_default_bases_of_a_source_smaller_than_the_base_basis(bpy_empty, extension, core):
    """A 64-vertex source onto a 225-vertex mesh with the default sizes: k_N is the source's 63 and
    k_M what the source resolves, 21 (core.transfer_checks.resolved_functions; before: k_M = 100
    against k_N = 63, which the core now refuses: the k_N × k_M map has rank 63 at most and leaves
    the differences singular; a tapering stretch came back 0.24 off the rebuild at k_M = 63, and
    k_M = 63 on 64 source vertices is warned as more than the source resolves)."""
    bridge = extension.bridge
    source, target = transfer_pair(bridge, 7, 14)
    rest = bridge.mesh_data.vertex_positions(source.data)
    taper = rest.copy()
    taper[:, 1] *= 1.0 + 0.3 * (rest[:, 0] - rest[:, 0].min())
    add_key(source, "Taper", taper)
    assert bpy.ops.shape_differences.transfer_poses() == {'FINISHED'}
    rebuilt = bridge.mesh_data.stored_key_positions(target.data.shape_keys.key_blocks["Source Taper"])
    transfer = core.Transfer(bridge.mesh_data.vertex_positions(target.data),
                             bridge.triangulation.mesh_triangles(target.data), rest,
                             bridge.triangulation.mesh_triangles(source.data), k_M=21, k_N=63)
    transfer.pose(bridge.mesh_data.stored_key_positions(source.data.shape_keys.key_blocks["Bend"]))  # the poses in turn
    expected = transfer.pose(bridge.mesh_data.stored_key_positions(source.data.shape_keys.key_blocks["Taper"]))  # as stored
    np.testing.assert_allclose(rebuilt, expected, atol=TOLERANCE)


def test_k_n_is_the_sources_basis(pair, core):
    """k_N is checked against the source's 225 vertices, not the 121 of the active mesh (before:
    "k_N = 140 is too large for a mesh with 121 vertices", while 0 chose 200)."""
    source, target, bridge = pair
    assert bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=140) == {'FINISHED'}
    with pytest.raises(RuntimeError, match="k_N = 225 is too large for a mesh with 225 vertices"):
        bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=225)


def test_transfer_with_a_map_attribute_and_bad_maps(pair, core):
    source, target, bridge = pair
    from scipy.spatial import cKDTree

    _, matched = cKDTree(bridge.mesh_data.vertex_positions(source.data)).query(
        bridge.mesh_data.vertex_positions(target.data))
    attribute = target.data.attributes.new("map", 'INT', 'POINT')
    attribute.data.foreach_set("value", matched.astype(np.int32))
    before = snapshot(bridge, target)
    with pytest.raises(RuntimeError, match="no integer vertex attribute 'missing'"):
        bpy.ops.shape_differences.transfer_poses(matching='ATTRIBUTE', map_attribute="missing", k_m=16, k_n=32)
    attribute.data[3].value = 10_000
    with pytest.raises(RuntimeError, match="maps vertex 3 of 'Sheet' to source vertex 10000"):
        bpy.ops.shape_differences.transfer_poses(matching='ATTRIBUTE', map_attribute="map", k_m=16, k_n=32)
    assert target.data.shape_keys is None and before["positions"].shape == bridge.mesh_data.vertex_positions(target.data).shape
    attribute.data[3].value = int(matched[3])
    bpy.ops.shape_differences.transfer_poses(matching='ATTRIBUTE', map_attribute="map", k_m=16, k_n=32)
    assert key_names(target) == ["Basis", "Source Bend"]
    # an 8-bit integer attribute is read as one (before: "no integer vertex attribute"); this one,
    # never filled, maps every vertex to source vertex 0: refused (before: the sheet squashed to it)
    small = target.data.attributes.new("map8", 'INT8', 'POINT')
    small.data.foreach_set("value", np.zeros(len(matched), dtype=np.int32))
    with pytest.raises(RuntimeError, match="lays the base on a point of the target"):
        bpy.ops.shape_differences.transfer_poses(matching='ATTRIBUTE', map_attribute="map8", k_m=16, k_n=32)


def test_transfer_with_map_files(pair, core, tmp_path):
    """Map = File: a per-vertex map (1-based, then 0-based) gives the attribute's result; two
    template maps (.vts, 1-based) that cover part of the sheet are composed, the rest filled in;
    bad files are refused in the user's terms and change nothing."""
    source, target, bridge = pair
    from scipy.spatial import cKDTree

    sheet, grid = bridge.mesh_data.vertex_positions(target.data), bridge.mesh_data.vertex_positions(source.data)
    _, matched = cKDTree(grid).query(sheet)
    np.savetxt(tmp_path / "map1.txt", matched + 1, fmt="%d")
    np.savetxt(tmp_path / "map0.txt", matched, fmt="%d")
    run = lambda **kw: bpy.ops.shape_differences.transfer_poses(matching='FILE', k_m=16, k_n=32, **kw)  # noqa: E731
    with pytest.raises(RuntimeError, match=r"Entry \d+ of the Map File .* is 0, but 1-based .*map is 0-based"):
        run(map_file=str(tmp_path / "map0.txt"))
    with pytest.raises(RuntimeError, match="Set the Map File"):
        run()
    with pytest.raises(RuntimeError, match=r"The Map File has 225 entries but 'Sheet' has 121 vertices"):
        np.savetxt(tmp_path / "long.txt", np.arange(1, 226), fmt="%d")
        run(map_file=str(tmp_path / "long.txt"))
    with pytest.raises(RuntimeError, match="is a folder"):
        run(map_file=str(tmp_path))
    assert target.data.shape_keys is None
    (tmp_path / "bom.txt").write_bytes(b"\xef\xbb\xbf" + (tmp_path / "map1.txt").read_bytes())  # saved by Notepad
    run(map_file=str(tmp_path / "bom.txt"))
    target.shape_key_clear()
    run(map_file=str(tmp_path / "map1.txt"))
    run(map_file=str(tmp_path / "map0.txt"), one_based=False)
    keys = target.data.shape_keys.key_blocks
    expected = core.Transfer(sheet, bridge.triangulation.mesh_triangles(target.data), grid,
                             bridge.triangulation.mesh_triangles(source.data),
                             correspondence=matched, k_M=16, k_N=32).pose(
        bridge.mesh_data.stored_key_positions(source.data.shape_keys.key_blocks["Bend"]))
    for key in list(keys)[1:]:
        np.testing.assert_allclose(bridge.mesh_data.stored_key_positions(key), expected, atol=TOLERANCE)
    # Template maps: a 9 x 9 template over the same square; each file lists, per template vertex,
    # the 1-based index of the nearest vertex of one mesh. Fewer template vertices than sheet
    # vertices: some sheet vertices are unmatched.
    xs, ys = np.meshgrid(np.linspace(sheet[:, 0].min(), sheet[:, 0].max(), 9),
                         np.linspace(sheet[:, 1].min(), sheet[:, 1].max(), 9))
    template = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, sheet[0, 2])], axis=1)
    np.savetxt(tmp_path / "sheet.vts", cKDTree(sheet).query(template)[1] + 1, fmt="%d")
    np.savetxt(tmp_path / "grid.vts", cKDTree(grid).query(template)[1] + 1, fmt="%d")
    np.savetxt(tmp_path / "short.vts", cKDTree(grid).query(template[:-1])[1] + 1, fmt="%d")
    with pytest.raises(RuntimeError, match="different lengths"):
        run(map_file=str(tmp_path / "sheet.vts"), source_map_file=str(tmp_path / "short.vts"))
    run(map_file=str(tmp_path / "sheet.vts"), source_map_file=str(tmp_path / "grid.vts"))
    rebuilt = bridge.mesh_data.stored_key_positions(list(target.data.shape_keys.key_blocks)[-1])
    truth = rolled(sheet, 1.0)
    assert hausdorff(rebuilt, truth) < 0.5 * hausdorff(sheet, truth)


def test_transfer_needs_a_second_mesh(bpy_empty, extension, core):
    grid_object(6)
    with pytest.raises(RuntimeError, match="Also select the mesh"):
        bpy.ops.shape_differences.transfer_poses()


def test_transfer_cloth_frames(bpy_empty, extension, core):
    bridge = extension.bridge
    cloth = cloth_scene(14, frames=9)
    target = grid_object(10, name="Sheet")
    target.location.z = 1.0  # over the cloth's rest pose, in world space
    cloth.select_set(True)
    bpy.context.view_layer.objects.active = target
    bpy.ops.shape_differences.transfer_poses(source='FRAMES', frame_start=9, frame_end=9, k_m=16, k_n=32)
    assert key_names(target) == ["Basis", "Cloth Frame 9"]
    rebuilt = bridge.mesh_data.stored_key_positions(target.data.shape_keys.key_blocks["Cloth Frame 9"])
    assert np.isfinite(rebuilt).all() and bpy.context.scene.frame_current == 1


def test_transfer_to_a_point_cache(pair, tmp_path):
    source, target, bridge = pair
    bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=32, output='CACHE', filepath=str(tmp_path / "moved.pc2"))
    assert target.data.shape_keys is None  # the active mesh is left as it was
    cached = [o for o in bpy.data.objects if o.name.startswith("Sheet Transfer Source")]
    assert len(cached) == 1 and any(m.type == 'MESH_CACHE' for m in cached[0].modifiers)


def test_transfer_frames_of_a_source_moved_as_a_whole(bpy_empty, extension, core):
    """Frames of a strip bent by its armature and carried by the armature object (its parent, which
    rises 0.5): each frame is taken where the source is at that frame, so the rebuilt frames on a
    remeshed strip follow the source in world space (before, every frame went through the source's
    placement at the current frame: 0.5 units off at the last)."""
    from blender_scenes import armature_scene
    bridge = extension.bridge
    source = armature_scene(frames=9, parented=True)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=13, y_subdivisions=4, size=2.0)
    target = bpy.context.active_object
    target.name = "Remeshed"
    target.scale.y = 0.25
    bpy.ops.object.transform_apply(scale=True)
    bpy.context.scene.frame_set(9)
    world = _world_of(source, bridge.mesh_data.evaluated_positions(source, bpy.context.evaluated_depsgraph_get()))
    bpy.context.scene.frame_set(1)
    source.select_set(True)
    target.select_set(True)
    bpy.context.view_layer.objects.active = target
    bpy.ops.shape_differences.transfer_poses(source='FRAMES', frame_start=1, frame_end=9, frame_step=8, k_m=16, k_n=32)
    rebuilt = bridge.mesh_data.stored_key_positions(target.data.shape_keys.key_blocks[f"{source.name} Frame 9"])
    assert hausdorff(_world_of(target, rebuilt), world) < 0.1  # the rig rose 0.5


def _world_of(obj, positions):
    matrix = np.array(obj.matrix_world)
    return positions @ matrix[:3, :3].T + matrix[:3, 3]


def test_a_source_in_edit_mode_is_refused(pair):
    """A source whose mesh is in Edit Mode (a script left it there while another object is active)
    has no vertices in its mesh until Edit Mode is left: refused in the user's words (before: a
    KeyError traceback from reading its positions)."""
    source, target, bridge = pair
    before = snapshot(bridge, target)
    target.select_set(False)  # or it enters Edit Mode with the source
    bpy.context.view_layer.objects.active = source
    bpy.ops.object.mode_set(mode='EDIT')
    target.select_set(True)
    bpy.context.view_layer.objects.active = target
    with pytest.raises(RuntimeError, match="'Source' is in Edit Mode: switch to Object Mode first"):
        bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=32)
    assert target.data.shape_keys is None and before["meshes"] == snapshot(bridge, target)["meshes"]


def test_frames_of_an_unbaked_cloth_are_simulated_from_its_start(bpy_empty, extension, core):
    """Frames 7–13 of a hanging cloth whose memory cache a settings change emptied: the source is
    simulated from its start frame, as the frame operators read it, so the poses transferred are
    those of the cloth played from frame 1 (before, the simulation began at frame 7 and the rebuilt
    frames were up to 0.010 off on a sheet 2 wide)."""
    from blender_scenes import pinned_cloth_scene

    bridge = extension.bridge

    def transferred(empty_cache: bool):
        bpy.ops.wm.read_homefile(use_empty=True)
        source = pinned_cloth_scene(8, frames=13)  # played into its memory cache
        if empty_cache:
            cloth = source.modifiers["Cloth"]
            cloth.settings.mass = cloth.settings.mass  # any settings change empties the cache
            bpy.context.view_layer.update()
            assert cloth.point_cache.info.startswith("0 frames")
        target = grid_object(6, name="Sheet")
        target.rotation_euler.x = source.rotation_euler.x
        source.select_set(True)
        bpy.context.view_layer.objects.active = target
        bpy.ops.shape_differences.transfer_poses(source='FRAMES', frame_start=7, frame_end=13, frame_step=3,
                                                 k_m=16, k_n=32)
        return [bridge.mesh_data.stored_key_positions(k) for k in target.data.shape_keys.key_blocks[1:]]

    for emptied, played in zip(transferred(True), transferred(False)):
        np.testing.assert_allclose(emptied, played, atol=1e-6)


def test_transferred_keys_in_a_cache_play_from_the_start_of_the_shot(pair, tmp_path):
    """A shot from frame 1001: the cache of transferred keys plays them one a frame from 1001, as
    In-between's and Exaggerate's caches do (before, at frames 1 and 2, so that the whole shot
    showed the last key held)."""
    source, target, bridge = pair
    add_key(source, "Curl", rolled(bridge.mesh_data.vertex_positions(source.data), 2.0))
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1001, 1100
    bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=32)  # the same poses as shape keys
    keys = {name: bridge.mesh_data.stored_key_positions(target.data.shape_keys.key_blocks[name])
            for name in ("Source Bend", "Source Curl")}
    bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=32, output='CACHE', filepath=str(tmp_path / "shot.pc2"))
    cached = bpy.data.objects["Sheet Transfer Source"]
    for frame, name in ((1001, "Source Bend"), (1002, "Source Curl")):
        scene.frame_set(frame)
        played = bridge.mesh_data.evaluated_positions(cached, bpy.context.evaluated_depsgraph_get())
        np.testing.assert_allclose(played, keys[name], atol=1e-6)


@pytest.mark.parametrize("current", [1, 9])
def test_frames_of_a_source_whose_scale_is_keyframed_are_measured_in_their_proportions(bpy_empty, extension, core,
                                                                                        tmp_path, current):
    """A sheet turning rigidly in the world while its object's scale is keyframed 1 → 2, its frames
    transferred onto a finer grid laid on its rest with the scene at frame 1 or 9: every transferred
    frame keeps the grid's areas (a turn), to the float32 of shape keys, wherever the current frame
    is (before, the rest was laid in the world through the current frame's matrix: at frame 9, the
    sheet twice its size, and the areas came out up to 12.4 times the grid's)."""
    from blender_scenes import turning_sheet_scale_keyframed

    bridge = extension.bridge
    source, _scale, _world = turning_sheet_scale_keyframed(extension, tmp_path)
    target = grid_object(10, name="Target")
    source.select_set(True)
    bpy.context.view_layer.objects.active = target
    bpy.context.scene.frame_set(current)
    bpy.ops.shape_differences.transfer_poses(source='FRAMES', frame_start=1, frame_end=9, frame_step=4, k_m=16, k_n=32)
    triangles = bridge.triangulation.mesh_triangles(target.data)

    def areas(positions):
        a, b, c = (positions[triangles[:, k]] for k in range(3))
        return np.linalg.norm(np.cross(b - a, c - a), axis=1)

    rest = areas(bridge.mesh_data.vertex_positions(target.data))
    for frame in (1, 5, 9):
        moved = areas(
            bridge.mesh_data.stored_key_positions(target.data.shape_keys.key_blocks[f"{source.name} Frame {frame}"]))
        np.testing.assert_allclose(moved / rest, 1.0, atol=1e-4, err_msg=f"frame {frame}")


def _refused_without_change(bridge, obj, match):
    from blender_scenes import assert_unchanged

    before = snapshot(bridge, obj)
    with pytest.raises(RuntimeError, match=match) as refusal:
        bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=32)
    assert "Traceback" not in str(refusal.value), "a crash, not a report"
    assert_unchanged(before, snapshot(bridge, obj))


@pytest.mark.parametrize("scaled", ["itself", "its parent"])
def test_an_active_mesh_flattened_by_a_zero_scale_is_refused(pair, scaled):
    """The poses are rebuilt in the world and taken back into the active mesh through its world
    matrix: scaled to 0 along an axis (its own scale or a parent's) there is no way back (before: a
    NumPy "Singular matrix" traceback after the whole transfer)."""
    source, target, bridge = pair
    if scaled == "itself":
        target.scale = (1.0, 1.0, 0.0)
    else:
        parent = bpy.data.objects.new("Holder", None)
        bpy.context.scene.collection.objects.link(parent)
        parent.scale = (0.0, 1.0, 1.0)
        target.parent = parent
    bpy.context.view_layer.update()
    _refused_without_change(bridge, target, r"^Error: 'Sheet' is flattened in the world \(its scale there is "
                                            r"\((1, 1, 0|0, 1, 1)\)\).* a scale other than 0 along every axis$")
    assert target.data.shape_keys is None


def test_refusals_name_the_mesh_at_fault(pair):
    """Two meshes are in play: a refusal of the active mesh's faces names it and its faces (before:
    "Triangle 200 uses the same three vertices as triangle 0", of either mesh, numbered by loop
    triangle), and a source flattened in the world by its scale is named (before: a NumPy traceback
    from welding its rest pose, which left no triangle)."""
    source, target, bridge = pair
    mesh = target.data
    faces = [tuple(polygon.vertices) for polygon in mesh.polygons]
    doubled = bpy.data.meshes.new("Doubled")  # face 0 again, as the last face: a duplicate in place
    doubled.from_pydata([vertex.co[:] for vertex in mesh.vertices], [], faces + faces[:1])
    target.data = doubled
    _refused_without_change(bridge, target, rf"^Error: 'Sheet' \(the mesh the poses move\): Triangle {2 * len(faces)} "
                                            rf"\(of face {len(faces)}\) uses the same three vertices as triangle 0 "
                                            r"\(of face 0\)")
    target.data = mesh
    source.scale = (1e-20, 1.0, 1.0)
    bpy.context.view_layer.update()
    _refused_without_change(bridge, target, r"^Error: the rest pose of 'Source' in the world: every triangle has "
                                            r"zero area")


def test_an_active_mesh_its_scale_flattens_in_the_world_is_refused_for_its_scale(pair):
    """Scaled 1e12 along x, the active mesh is flat in the world, where the poses are rebuilt,
    though its mesh is fine: refused naming its scale, nothing changed (before: "the mesh of
    'Sheet': triangle 0 … has zero area … Degenerate Dissolve")."""
    source, target, bridge = pair
    target.scale = (1e12, 1.0, 1.0)
    bpy.context.view_layer.update()
    _refused_without_change(bridge, target, r"^Error: 'Sheet' is flattened in the world \(its scale there is "
                                            r"\(1e\+12, 1, 1\)\): the poses are rebuilt in the world, and there "
                                            r"\d+ of its triangles have no area, which they have in its mesh")


def test_warnings_about_the_source_mesh_name_it(bpy_empty, extension, core, capfd):
    """The core calls the mesh whose poses are transferred "the target mesh"; to the user that is the
    source, beside the active mesh that the poses move. A source with a sliver (a triangle of no area
    along its boundary) is transferred with the warning naming it (before: "The target mesh has 1
    triangle(s) of zero area at rest")."""
    bridge = extension.bridge
    source = grid_object(14, name="Source")
    source.data, rest = with_boundary_sliver(bridge, source.data)
    add_key(source, "Bend", rolled(rest, 1.0))
    target = grid_object(10, name="Sheet")
    source.select_set(True)
    target.select_set(True)
    bpy.context.view_layer.objects.active = target
    capfd.readouterr()
    bpy.ops.shape_differences.transfer_poses(k_m=16, k_n=32)
    out = capfd.readouterr().out
    assert "'Source' (the source of the poses) has 1 triangle(s) of zero area at rest" in out, out
    assert "target mesh" not in out
    assert "Source Bend" in key_names(target)
