"""Output as a point cache on a new object, and retiming, on scenes whose motion comes from a
pinned cloth (not baked), an armature-skinned limb and shape keys driven by other keys: the
source object stays bit for bit as it was, the new object plays the source at the kept frames
and core's in-betweens elsewhere, and a second run never touches the first."""

import importlib
import re
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import (add_key, armature_scene, assert_unchanged, driven_keys_scene,  # noqa: E402
                            evaluated_frames, grid_object, key_names, pinned_cloth_scene, played, posed_grid,
                            snapshot)

TOLERANCE = 1e-5  # float32 positions


def assert_source_unchanged(bridge, obj, before, frames=()):
    after = snapshot(bridge, obj)
    after["meshes"] = before["meshes"]  # the new object brings its own mesh
    assert_unchanged(before, after)
    if frames:
        expected = before["evaluated"]
        for frame, positions in evaluated_frames(bridge, obj, frames).items():
            np.testing.assert_array_equal(positions, expected[frame])


def new_object(source_name_before: set):
    created = [obj for obj in bpy.data.objects if obj.name not in source_name_before]
    assert len(created) == 1, [obj.name for obj in created]
    return created[0]


def assert_cache_object(obj, source, path=None):
    assert obj.name.startswith(source.name + " ")
    assert [m.type for m in obj.modifiers] == ['MESH_CACHE']
    assert obj.data.shape_keys is None and obj.data is not source.data
    assert len(obj.data.vertices) == len(source.data.vertices)
    cache_file = Path(bpy.path.abspath(obj.modifiers[0].filepath))
    assert cache_file.is_file()
    if path is not None:
        assert cache_file == Path(path)
    return cache_file


SCENES = {"pinned cloth": (pinned_cloth_scene, 25),
          "armature": (lambda frames: armature_scene(frames, parented=True), 13),
          "driven keys": (driven_keys_scene, 13)}


@pytest.mark.parametrize("scene", SCENES)
def test_retime_half_speed_on_a_new_object(bpy_empty, extension, core, scene, tmp_path, capfd):
    make_scene, end = SCENES[scene]
    source = make_scene(frames=end)
    bpy.context.scene.frame_end = end
    bridge = extension.bridge
    before = snapshot(bridge, source)
    before["evaluated"] = evaluated_frames(bridge, source, range(1, end + 1))
    names = set(bpy.data.objects.keys())
    path = tmp_path / "retime.pc2"
    capfd.readouterr()
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=end, frame_step=4, speed=0.5,
                                     filepath=str(path))
    # the scene's range is left as it was, and the run says how far the motion now runs
    assert bpy.context.scene.frame_end == end
    out = capfd.readouterr().out
    assert (f"runs to frame {2 * end - 1}, past the end of playback at frame {end}: set the scene's End to "
            f"{2 * end - 1}") in out
    assert "frames between every 4th are rebuilt, not read: Step 1 keeps every frame" in out
    first = new_object(names)
    assert first.name == f"{source.name} Retime 0.50x step 4"
    assert_cache_object(first, source, path)
    assert_source_unchanged(bridge, source, before, frames=range(1, end + 1, 3))

    n_out = 2 * end - 1  # frames 1-25 at half speed: 49
    cache = importlib.import_module(f"{extension.__name__}.core.point_cache").read_pc2(path)
    assert (cache.n_samples, cache.start, cache.sampling) == (n_out, 1.0, 1.0)
    source_frames = before["evaluated"]
    keys = [source_frames[f] for f in range(1, end + 1, 4)]
    playback = played(bridge, first, range(1, n_out + 1))
    for out_frame in range(1, n_out + 1):
        time = 1 + (out_frame - 1) * 0.5
        if time == int(time) and (int(time) - 1) % 4 == 0:  # a kept frame: the source exactly
            np.testing.assert_allclose(playback[out_frame], source_frames[int(time)], atol=TOLERANCE)
    for frame in (1, end):  # placed like the source, following its parent if it has one
        bpy.context.scene.frame_set(frame)
        np.testing.assert_allclose(np.array(first.matrix_world), np.array(source.matrix_world), atol=1e-6)
    bpy.context.scene.frame_set(1)
    motion_ends = importlib.import_module(core.__name__ + ".motion_ends")
    start = motion_ends.start_of_motion([source_frames[1], source_frames[5], source_frames[9]], source_frames[3], 0.5)
    plan = importlib.import_module(core.__name__ + ".retime").plan_retime(end, 4, 0.5)
    # how the motion reaches the last key: the sample in the middle of the last gap (sample i: frame i + 1)
    before_key, start_key, last_key, middle = plan.end_samples
    ends = motion_ends.end_of_motion([source_frames[k + 1] for k in (before_key, start_key, last_key)],
                                     source_frames[middle + 1], 0.5)
    sequence = core.SequenceInterpolator(keys, bridge.triangulation.mesh_triangles(source.data), start=start, end=ends)
    for out_frame in (2, 4, 20, n_out - 1):  # in-betweens: time 1.5, 2.5, 10.5, end - 0.5
        gap = int(plan.gaps[out_frame - 1])  # each gap's in-betweens are computed together
        rows = [i for i in range(plan.n_out) if plan.gaps[i] == gap and plan.exact_keys[i] < 0]
        expected = sequence.poses(gap, plan.factors[rows])[rows.index(out_frame - 1)]
        np.testing.assert_allclose(playback[out_frame], expected, atol=TOLERANCE)

    # A second run: a second object and file; the first stays as it was.
    first_bytes, first_name = path.read_bytes(), first.name
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=end, frame_step=6, speed=1.0,
                                     filepath=str(path))
    assert "past the end of playback" not in capfd.readouterr().out
    second = new_object(names)
    second_file = assert_cache_object(second, source)
    assert second_file != path and path.read_bytes() == first_bytes
    assert bpy.data.objects[first_name].modifiers[0].filepath == str(path)
    np.testing.assert_array_equal(played(bridge, first, [5])[5], playback[5])
    assert_source_unchanged(bridge, source, before)


@pytest.mark.parametrize("speed, frames", [(1.0, 9), (2.0, 5)])
def test_retime_original_timing_and_faster(bpy_empty, extension, core, speed, frames, tmp_path):
    source = armature_scene(frames=9)
    bridge = extension.bridge
    source_frames = evaluated_frames(bridge, source, range(1, 10))
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=speed,
                                     filepath=str(tmp_path / "out.pc2"))
    playback = played(bridge, new_object(names), range(1, frames + 1))
    for out_frame in range(1, frames + 1):
        time = 1 + (out_frame - 1) * speed
        tolerance = TOLERANCE if (time - 1) % 4 == 0 else 0.05  # dropped frames: rebuilt closely
        np.testing.assert_allclose(playback[out_frame], source_frames[int(time)], atol=tolerance)


def test_retime_at_a_speed_single_precision_cannot_hold_plays_every_frame(bpy_empty, extension, core, tmp_path):
    """Speed 0.3 (kept by Blender as 0.30000001192) over 25 frames: 81 frames, the last one the
    source's last (before: 80, the source's frame 25 never played, keys off by 7e-9)."""
    from core.point_cache import read_pc2

    source = armature_scene(frames=25)
    last = evaluated_frames(extension.bridge, source, [25])[25]
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=25, frame_step=4, speed=0.3,
                                     filepath=str(tmp_path / "out.pc2"))
    new_object(names)
    cache = read_pc2(tmp_path / "out.pc2")
    assert cache.positions.shape[0] == 81
    np.testing.assert_allclose(cache.positions[-1], last, atol=TOLERANCE)


def test_cache_files_that_cannot_be_written_are_refused_before_any_work(bpy_empty, extension, core, tmp_path,
                                                                       monkeypatch):
    """A Cache File under a file (not a folder), in a folder on a read-only file system (said as
    such: its permissions allow writing, and "Permission denied" sent users to them), or past
    Blender's NLA when the source's transform is keyframed (speed under 0.001): refused before
    anything is computed, nothing added."""
    import os

    source = armature_scene(frames=9)
    (tmp_path / "afile").write_text("x")
    names = set(bpy.data.objects.keys())
    with pytest.raises(RuntimeError, match="afile' is a file, not a folder"):
        bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=0.5,
                                         filepath=str(tmp_path / "afile" / "out.pc2"))
    mount = tmp_path / "share"  # as a read-only mount shows it: writable by its mode, refused by the system
    mount.mkdir()
    access, statvfs = os.access, os.statvfs

    def read_only(call, result):
        return lambda path, *args, **kw: result(path) if os.fspath(path) == str(mount) else call(path, *args, **kw)

    monkeypatch.setattr(os, "access", read_only(access, lambda path: False))
    monkeypatch.setattr(os, "statvfs", read_only(statvfs, lambda path: type("Flags", (), {"f_flag": os.ST_RDONLY})))
    with pytest.raises(RuntimeError, match=f"the folder '{mount}' is on a read-only file system. Pick another"):
        bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=0.5,
                                         filepath=str(mount / "caches" / "out.pc2"))
    monkeypatch.undo()
    source.animation_data_create().action = bpy.data.actions.new("Move")
    source.keyframe_insert("location", frame=1)
    with pytest.raises(RuntimeError, match="NLA slows an action down 1000 times at most"):
        bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=0.0005,
                                         filepath=str(tmp_path / "slow.pc2"))
    assert set(bpy.data.objects.keys()) == names


def test_ranges_that_are_not_whole_steps(bpy_empty, extension, core, tmp_path):
    """Frames 1–12 keyed every 4th: the last gap (9 → 12) is three frames long and keyed by its own
    sequence on frames 3, 6, 9, 12 (core.retime.short_gap_keys), which the operators read too.
    Retime writes what core.retime gives for the evaluated source; In-between Frames with one
    in-between per gap plays every 2nd frame, so the short gap adds frame 11 and the last frame,
    off that spacing, is left out of its cache. Both read frame 10 too, in the short gap, for how the
    motion reaches the last frame."""
    source = armature_scene(frames=12)
    bridge = extension.bridge
    source_frames = evaluated_frames(bridge, source, range(1, 13))
    triangles = bridge.triangulation.mesh_triangles(source.data)
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=12, frame_step=4, speed=0.5,
                                     filepath=str(tmp_path / "retime.pc2"))
    playback = played(bridge, new_object(names), range(1, 24))
    retime = importlib.import_module(core.__name__ + ".retime")
    expected = retime.retime(np.stack([source_frames[f] for f in range(1, 13)]), triangles, step=4, speed=0.5)
    for out_frame in range(1, 24):
        np.testing.assert_allclose(playback[out_frame], expected[out_frame - 1], atol=TOLERANCE)

    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=12, frame_step=4, count=1,
                                               filepath=str(tmp_path / "inbetween.pc2"))
    assert_cache_object(new_object(names), source)
    cache = importlib.import_module(f"{extension.__name__}.core.point_cache").read_pc2(tmp_path / "inbetween.pc2")
    assert (cache.n_samples, cache.start, cache.sampling) == (6, 1.0, 2.0)
    np.testing.assert_allclose(cache.positions[4], source_frames[9], atol=TOLERANCE)
    # ending as frame 10, a third of the way through the short gap, says (core.retime.end_samples)
    assert retime.end_samples([1, 5, 9, 12], [3, 6, 9, 12]) == (6, 9, 12, 10)
    end = importlib.import_module(core.__name__ + ".motion_ends").end_of_motion(
        [source_frames[f] for f in (6, 9, 12)], source_frames[10], 1 / 3, (3, 3))
    short = core.SequenceInterpolator([source_frames[f] for f in (3, 6, 9, 12)], triangles, start="keys", end=end)
    np.testing.assert_allclose(cache.positions[5], short.pose(2, 2 / 3), atol=TOLERANCE)


def test_retime_as_keyframed_shape_keys(bpy_empty, extension, core):
    source = armature_scene(frames=5)
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=5, frame_step=2, speed=0.5,
                                     output='SHAPE_KEYS')
    assert key_names(source)[1:] == [f"Retime 0.50x frame {f}" for f in range(1, 10)]


def test_unbaked_cloth_cache_is_never_cleared(bpy_empty, extension, core, tmp_path):
    source = pinned_cloth_scene(frames=9)
    bridge = extension.bridge
    cache_info = source.modifiers["Cloth"].point_cache.info
    assert cache_info.startswith("9 frames")
    before = snapshot(bridge, source)
    before["evaluated"] = evaluated_frames(bridge, source, range(1, 10))
    with pytest.raises(RuntimeError, match="would empty the unbaked cache of its 'Cloth' simulation"):
        bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4,
                                                   output='SHAPE_KEYS')
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                               filepath=str(tmp_path / "cloth.pc2"))
    assert_cache_object(new_object(names), source)
    bpy.context.evaluated_depsgraph_get()
    assert source.modifiers["Cloth"].point_cache.info == cache_info
    assert_source_unchanged(bridge, source, before, frames=range(1, 10))


def test_an_unbaked_cloth_sharing_the_mesh_keeps_its_cache(bpy_empty, extension, core):
    """Shape keys added to a linked duplicate's mesh (Alt+D: one mesh, two objects) would empty the
    unbaked cache of the other object's cloth: refused, the cache kept."""
    source = pinned_cloth_scene(frames=9)
    cache = source.modifiers["Cloth"].point_cache
    cache_info = cache.info
    twin = bpy.data.objects.new("Twin", source.data)
    bpy.context.scene.collection.objects.link(twin)
    twin.shape_key_add(name="Basis")
    bend = twin.shape_key_add(name="Bend")
    co = extension.bridge.mesh_data.vertex_positions(twin.data)
    co[:, 2] += 0.3 * co[:, 0] ** 2
    bend.data.foreach_set("co", co.astype(np.float32).ravel())
    bpy.context.view_layer.update()
    assert cache.info == cache_info and not cache.is_outdated
    with bpy.context.temp_override(active_object=twin, object=twin, selected_objects=[twin]):
        with pytest.raises(RuntimeError, match=f"shares its mesh with '{source.name}'"):
            bpy.ops.shape_differences.inbetween(key_a="Basis", key_b="Bend", count=1, output='SHAPE_KEYS')
    bpy.context.view_layer.update()
    bpy.context.scene.frame_set(5)
    assert cache.info == cache_info and not cache.is_outdated
    assert [key.name for key in twin.data.shape_keys.key_blocks] == ["Basis", "Bend"]


@pytest.mark.parametrize("operator, properties, expected", [
    ("inbetween", dict(key_a="Curl", key_b="Bend", count=1),
     lambda core, k, t: [k["Curl"], core.Interpolator(k["Curl"], k["Bend"], t).pose(0.5), k["Bend"]]),
    ("exaggerate", dict(key="Bend", factor=1.5),
     lambda core, k, t: [core.Interpolator(k["Basis"], k["Bend"], t).pose(1.5)]),
    ("reconstruct", dict(key="Curl"),
     lambda core, k, t: [core.reconstruct(k["Basis"], t, core.shape_differences(k["Basis"], k["Curl"], t))]),
], ids=["inbetween", "exaggerate", "reconstruct"])
def test_pose_operators_write_a_cache_object(bpy_empty, extension, core, operator, properties,
                                             expected, tmp_path):
    bridge = extension.bridge
    source = posed_grid(bridge, 5)
    before = snapshot(bridge, source)
    names = set(bpy.data.objects.keys())
    getattr(bpy.ops.shape_differences, operator)(output='CACHE', filepath=str(tmp_path) + "/",
                                                 **properties)
    obj = new_object(names)
    assert_cache_object(obj, source)
    assert_source_unchanged(bridge, source, before)
    keys = {kb.name: bridge.mesh_data.stored_key_positions(kb) for kb in source.data.shape_keys.key_blocks}
    poses = expected(core, keys, bridge.triangulation.mesh_triangles(source.data))
    start = bpy.context.scene.frame_start
    playback = played(bridge, obj, range(start, start + len(poses)))
    for i, pose in enumerate(poses):
        np.testing.assert_allclose(playback[start + i], pose, atol=1e-4)


def test_frames_to_a_cache_object(bpy_empty, extension, core, tmp_path):
    source = armature_scene(frames=9)
    bridge = extension.bridge
    expected = evaluated_frames(bridge, source, range(1, 10))
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.frames_to_shape_keys(frame_step=2, output='CACHE',
                                                   filepath=str(tmp_path / "frames"))
    obj = new_object(names)
    assert obj.name == "Sheet Frames 1-9 step 2" or obj.name.endswith("Frames 1-9 step 2")
    assert_cache_object(obj, source, tmp_path / "frames.pc2")
    playback = played(bridge, obj, range(1, 10))
    for frame in range(1, 10):  # every 2nd frame exactly, linear between
        if frame % 2:
            np.testing.assert_allclose(playback[frame], expected[frame], atol=TOLERANCE)
        else:
            np.testing.assert_allclose(playback[frame], (expected[frame - 1] + expected[frame + 1]) / 2,
                                       atol=TOLERANCE)


def test_a_cache_object_renders_as_its_source(bpy_empty, extension, core, tmp_path):
    """Materials linked to the object (not the mesh), render visibility, pass index and display
    settings go with the new object (before, it rendered with the mesh's material, cast the
    shadow the source did not, and lost its pass index)."""
    source = armature_scene(frames=5)
    on_mesh, on_object = bpy.data.materials.new("Mesh material"), bpy.data.materials.new("Object material")
    source.data.materials.append(on_mesh)
    source.data.materials.append(on_mesh)
    source.material_slots[1].link = 'OBJECT'
    source.material_slots[1].material = on_object
    source.visible_shadow = source.visible_glossy = False
    source.pass_index, source.color, source.show_wire = 7, (1.0, 0.5, 0.25, 1.0), True
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.frames_to_shape_keys(frame_step=2, output='CACHE', filepath=str(tmp_path) + "/")
    obj = new_object(names)
    assert [(slot.link, slot.material) for slot in obj.material_slots] == [
        ('DATA', on_mesh), ('OBJECT', on_object)]
    assert not obj.visible_shadow and not obj.visible_glossy and obj.visible_camera
    assert obj.pass_index == 7 and obj.show_wire
    assert tuple(obj.color) == pytest.approx((1.0, 0.5, 0.25, 1.0))
    assert source.material_slots[1].material == on_object and source.data.materials[1] == on_mesh


def test_headless_runs_print_progress(bpy_empty, extension, core, capfd, monkeypatch, tmp_path):
    monkeypatch.setattr(extension.operators.base, "CONSOLE_PROGRESS_INTERVAL", 0.0)
    armature_scene(frames=5)
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=5, frame_step=2, speed=1.0,
                                     filepath=str(tmp_path / "a.pc2"))
    err = capfd.readouterr().err
    lines = err.splitlines()
    assert "Retime: 46%" in lines and lines[-1] == "Retime: done"


def test_headless_runs_print_a_first_progress_line_at_once(bpy_empty, extension, capfd, monkeypatch, tmp_path):
    """The first progress line comes at the run's first step, not a console interval after the
    start (a long run read frames and prepared keys for seconds without a line): with an interval
    longer than any run, the first step's line and the last line, nothing between."""
    monkeypatch.setattr(extension.operators.base, "CONSOLE_PROGRESS_INTERVAL", 1e9)
    armature_scene(frames=5)
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=5, frame_step=2, speed=1.0,
                                     filepath=str(tmp_path / "a.pc2"))
    lines = [line for line in capfd.readouterr().err.splitlines() if line.startswith("Retime: ")]
    assert len(lines) == 2 and re.fullmatch(r"Retime: \d+%", lines[0]) and lines[1] == "Retime: done", lines


def test_headless_runs_end_with_a_line_a_farm_can_read(bpy_empty, extension, capfd, monkeypatch, tmp_path):
    """Without a UI nothing cancels a run: a refused one ends its console lines with 'refused'
    (before, 'cancelled', what a farm's log reads as a user's cancel), Blender's 'Error: …' report
    naming why; a run that fails unexpectedly (a defect planted here) says so on one line naming the
    error before Blender's traceback (before, the traceback alone, the cause on its last line)."""
    armature_scene(frames=5)
    with pytest.raises(RuntimeError, match="is a device or special file"):
        bpy.ops.shape_differences.retime(frame_start=1, frame_end=5, frame_step=2, speed=1.0,
                                         filepath="/dev/null")
    out = capfd.readouterr()
    assert out.err.splitlines()[-1] == "Retime: refused" and "Error: " in out.out + out.err

    def planted(*_args):
        raise ZeroDivisionError("planted defect")
    monkeypatch.setattr(extension.operators.frames, "load_core_retime", planted)
    with pytest.raises(RuntimeError, match="planted defect"):
        bpy.ops.shape_differences.retime(frame_start=1, frame_end=5, frame_step=2, speed=1.0,
                                         filepath=str(tmp_path / "a.pc2"))
    err = capfd.readouterr().err
    line = ("Retime: failed: ZeroDivisionError: planted defect (unexpected: the traceback follows; "
            "please report it)")
    assert line in err.splitlines() and err.index(line) < err.index("Traceback")
    assert not list(tmp_path.iterdir())

    bpy.context.view_layer.objects.active = None  # a failed poll: Blender prints no report for it
    with pytest.raises(RuntimeError, match="Select a mesh object"):
        bpy.ops.shape_differences.retime(frame_start=1, frame_end=5, frame_step=2, speed=1.0,
                                         filepath=str(tmp_path / "a.pc2"))
    err = capfd.readouterr().err
    assert err.splitlines() == ["Retime: refused: Select a mesh object: the active object must be a mesh"]


def test_default_cache_file_beside_the_saved_blend(bpy_empty, extension, core, tmp_path):
    source = armature_scene(frames=3)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    source = bpy.data.objects[source.name]
    for _ in range(2):
        names = set(bpy.data.objects.keys())
        bpy.ops.shape_differences.frames_to_shape_keys(output='CACHE')
        obj = new_object(names)
    assert bpy.data.objects["Grid Frames 1-3"].modifiers[0].filepath == "//caches/Grid_Frames_1-3.pc2"
    assert obj.name == "Grid Frames 1-3.001"
    assert obj.modifiers[0].filepath == "//caches/Grid_Frames_1-3_001.pc2"
    assert sorted(p.name for p in (tmp_path / "caches").iterdir()) == ["Grid_Frames_1-3.pc2",
                                                                      "Grid_Frames_1-3_001.pc2"]


def _world(obj, positions):
    matrix = np.array(obj.matrix_world)
    return positions @ matrix[:3, :3].T + matrix[:3, 3]


def _moving_strip(frames: int, parent_type: str = 'OBJECT'):
    """The armature strip with its own keyframed transform (walking and turning, like a banner's
    pole), a constraint that lifts it after an animated empty, and its rig, which moves, as its
    parent of ``parent_type`` ('ARMATURE': the rig deforms it through the parent alone)."""
    from blender_scenes import armature_scene
    strip = armature_scene(frames=frames, parented=True)
    rig = strip.parent
    if parent_type == 'ARMATURE':
        strip.modifiers.remove(strip.modifiers["Armature"])
        strip.parent_type = 'ARMATURE'
    strip.rotation_mode = 'YXZ'
    for frame, location, turn in ((1, (0.0, 0.0, 0.0), 0.0), (frames, (1.5, 0.5, 0.2), 2.0)):
        strip.location, strip.rotation_euler = location, (0.1, 0.0, turn)
        strip.keyframe_insert("location", frame=frame)
        strip.keyframe_insert("rotation_euler", frame=frame)
    lift = bpy.data.objects.new("Lift", None)
    bpy.context.scene.collection.objects.link(lift)
    for frame, height in ((1, 0.0), (frames, 0.7)):
        lift.location.z = height
        lift.keyframe_insert("location", frame=frame)
    constraint = strip.constraints.new('COPY_LOCATION')
    constraint.target, constraint.use_x, constraint.use_y, constraint.use_offset = lift, False, False, True
    bpy.context.scene.frame_set(1)
    bpy.context.view_layer.objects.active = strip
    strip.select_set(True)
    return strip, rig


@pytest.mark.parametrize("parent_type", ['OBJECT', 'ARMATURE'])
def test_a_cache_object_moves_as_its_source_does(bpy_empty, extension, core, parent_type, tmp_path, capfd):
    """In-between Frames on an object moved by its keyframes, a constraint and a moving parent (or
    deformed by it): the new object is placed like the source at every frame (world positions at
    the keys: the source's), and not deformed again by a deforming parent."""
    source, rig = _moving_strip(9, parent_type)
    bridge = extension.bridge
    before = snapshot(bridge, source)
    world = {}
    for frame in range(1, 10):
        bpy.context.scene.frame_set(frame)
        world[frame] = (np.array(source.matrix_world),
                        _world(source,
                               bridge.mesh_data.evaluated_positions(source, bpy.context.evaluated_depsgraph_get())))
    bpy.context.scene.frame_set(1)
    names = set(bpy.data.objects.keys()) - {source.name}
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=3,
                                               output='CACHE', filepath=str(tmp_path) + "/")
    obj = new_object(names | {source.name})
    assert_source_unchanged(bridge, source, before)
    assert obj.parent is rig and obj.parent_type == 'OBJECT' and obj.animation_data.action is source.animation_data.action
    for frame in range(1, 10):
        bpy.context.scene.frame_set(frame)
        np.testing.assert_allclose(np.array(obj.matrix_world), world[frame][0], atol=1e-6)
        if frame in (1, 5, 9):
            played_world = _world(obj, bridge.mesh_data.evaluated_positions(obj, bpy.context.evaluated_depsgraph_get()))
            np.testing.assert_allclose(played_world, world[frame][1], atol=1e-4)
    bpy.context.scene.frame_set(1)
    assert "Warning" not in capfd.readouterr().out  # everything that moves the source was taken over


def _carried_cloth(frames: int):
    """A sheet pinned along one edge to its object, which is carried 1 unit and turned 90° about z
    with eased (Bezier) keys at frames 1 and ``frames``: Blender simulates the cloth in the world,
    the pins follow the object, and the mesh is read in the object's coordinates. Baked. Returns
    the object and the pinned vertices' indices."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    obj = grid_object(8, name="Cape")
    pins = [v.index for v in obj.data.vertices if v.co.y > 0.99]  # the back edge
    obj.vertex_groups.new(name="Pin").add(pins, 1.0, 'REPLACE')
    obj.rotation_euler.x = 1.2
    for frame, x, turn in ((1, 0.0, 0.0), (frames, 1.0, np.pi / 2)):
        obj.location.x, obj.rotation_euler.z = x, turn
        obj.keyframe_insert("location", frame=frame)
        obj.keyframe_insert("rotation_euler", frame=frame)
    cloth = obj.modifiers.new("Cloth", 'CLOTH')
    cloth.settings.vertex_group_mass = "Pin"
    cloth.point_cache.frame_start, cloth.point_cache.frame_end = 1, frames
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    scene.frame_set(1)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    return obj, np.array(pins)


def test_in_between_frames_of_a_carried_cloth_play_its_objects_own_motion(bpy_empty, extension, core, tmp_path):
    """In-between Frames (step 4) of a cloth pinned to an object carried and turned 90° with eased
    keys: the frames are in-betweened in the object's own space and the new object plays them
    through the object's matrix at each frame, so the pinned edge, still in that space, plays where
    the simulation has it at every in-between, to float32. In-betweened in the world instead, the
    keys 4 frames apart would turn the pins at their own pace, not the object's eased one (they were
    2.9e-2 off at frame 2 on this 2-unit sheet; docs/inbetween-measurements.md, "A cloth its object
    carries: which space")."""
    source, pins = _carried_cloth(9)
    bridge = extension.bridge
    simulated = {}
    for frame in range(1, 10):
        bpy.context.scene.frame_set(frame)
        simulated[frame] = _world(source, bridge.mesh_data.evaluated_positions(
            source, bpy.context.evaluated_depsgraph_get()))
    bpy.context.scene.frame_set(1)
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=3,
                                               output='CACHE', filepath=str(tmp_path) + "/")
    obj = new_object(names)
    moved = np.abs(simulated[5][pins] - simulated[1][pins]).max()
    assert moved > 0.3  # the object carries the pins far between the keys
    for frame in range(1, 10):
        bpy.context.scene.frame_set(frame)
        shown = _world(obj, bridge.mesh_data.evaluated_positions(obj, bpy.context.evaluated_depsgraph_get()))
        np.testing.assert_allclose(shown[pins], simulated[frame][pins], atol=TOLERANCE)
    bpy.context.scene.frame_set(1)


def test_a_retimed_cache_object_plays_its_sources_keyframed_transform_at_the_new_speed(
        bpy_empty, extension, core, tmp_path, capfd):
    """Retime at half speed of an object moved by its keyframes (and a constraint and a parent,
    which keep the scene's timing): the new object's keyframed transform plays the source's time
    1 + (frame − 1) / 2, and the warning names what keeps the scene's timing."""
    source, rig = _moving_strip(9)
    source.constraints.clear()
    source.parent = None
    rig.animation_data_clear()
    names = set(bpy.data.objects.keys())
    bpy.context.scene.frame_end = 17  # plays all of it: no warning about the scene's range
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=0.5,
                                     filepath=str(tmp_path / "slow.pc2"))
    obj = new_object(names)
    assert "Warning" not in capfd.readouterr().out
    for out_frame in (1, 2, 6, 11, 16, 17):
        time = 1 + (out_frame - 1) * 0.5
        bpy.context.scene.frame_set(int(time), subframe=time - int(time))
        expected = np.array(source.matrix_world)
        bpy.context.scene.frame_set(out_frame)
        np.testing.assert_allclose(np.array(obj.matrix_world), expected, atol=1e-6)
    bpy.context.scene.frame_set(1)

    source, rig = _moving_strip(9)  # with its constraint and moving parent: named in the warning
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=0.5,
                                     filepath=str(tmp_path / "slow2.pc2"))
    new_object(names)
    out = capfd.readouterr().out
    assert f"plays the motion at 0.5x, but its constraints and its parent '{rig.name}' move it at the scene's own speed" in out
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=0.5, output='SHAPE_KEYS')
    assert f"by its keyframed transform, its constraints, its parent '{rig.name}', at its own speed" in capfd.readouterr().out
    source.constraints.clear()  # the moving parent alone (an Alembic's Transform Cache on it, say)
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=0.5,
                                     filepath=str(tmp_path / "slow3.pc2"))
    assert f"plays the motion at 0.5x, but its parent '{rig.name}' moves it at the scene's own speed" in capfd.readouterr().out


def test_drivers_on_the_source_transform_are_named_as_left_out(bpy_empty, extension, core, tmp_path, capfd):
    source, _rig = _moving_strip(5)
    driver = source.driver_add("scale", 2).driver
    driver.expression = "1 + frame / 10"
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=5, frame_step=2, count=1,
                                               output='CACHE', filepath=str(tmp_path) + "/")
    assert f"is not moved by drivers of '{source.name}'" in capfd.readouterr().out


def _linked_sheet(bridge, tmp_path, override: bool, prepare=lambda sheet: None):
    """The posed grid saved in a library .blend inside a collection "Chars" (after ``prepare`` of
    it), linked into a fresh file (the collection linked into the scene, or overridden through a
    collection instance)."""
    from blender_scenes import posed_grid
    collection = bpy.data.collections.new("Chars")
    bpy.context.scene.collection.children.link(collection)
    sheet = posed_grid(bridge, 5)
    prepare(sheet)
    for owner in sheet.users_collection:
        owner.objects.unlink(sheet)
    collection.objects.link(sheet)
    library = tmp_path / "library.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(library))
    bpy.ops.wm.read_homefile(use_empty=True)
    with bpy.data.libraries.load(str(library), link=True) as (_source, linked):
        linked.collections = ["Chars"]
    chars = linked.collections[0]
    if override:
        instance = bpy.data.objects.new("Chars instance", None)
        instance.instance_type, instance.instance_collection = 'COLLECTION', chars
        bpy.context.scene.collection.objects.link(instance)
        chars.override_hierarchy_create(bpy.context.scene, bpy.context.view_layer, reference=instance,
                                        do_fully_editable=True)
        return next(obj for obj in bpy.context.scene.objects if obj.type == 'MESH')
    bpy.context.scene.collection.children.link(chars)
    return chars.objects[0]


@pytest.mark.parametrize("override", [False, True], ids=["linked", "overridden"])
def test_a_linked_source_gets_its_cache_object_in_the_scene_and_no_shape_keys(bpy_empty, extension, core,
                                                                              override, tmp_path):
    """A character linked from a library (or overridden): its collection takes no new object, so
    the cache object goes to the scene's collection and is saved with the file; shape keys on its
    mesh would not be saved, so they are refused."""
    sheet = _linked_sheet(extension.bridge, tmp_path, override)
    names = set(bpy.data.objects.keys())
    with bpy.context.temp_override(active_object=sheet, object=sheet, selected_objects=[sheet]):
        with pytest.raises(RuntimeError, match="shape keys added to it are not saved"):
            bpy.ops.shape_differences.inbetween(key_a="Curl", key_b="Bend", count=1, output='SHAPE_KEYS')
    assert [key.name for key in sheet.data.shape_keys.key_blocks] == ["Basis", "Curl", "Bend"]
    with bpy.context.temp_override(active_object=sheet, object=sheet, selected_objects=[sheet]):
        bpy.ops.shape_differences.inbetween(key_a="Curl", key_b="Bend", count=1, output='CACHE',
                                            filepath=str(tmp_path) + "/")
    obj = new_object(names)
    assert [c.name for c in obj.users_collection] == [bpy.context.scene.collection.name]
    name = obj.name
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "shot.blend"))
    assert name in bpy.context.scene.objects


@pytest.mark.parametrize("override", [False, True], ids=["linked", "overridden"])
@pytest.mark.parametrize("operator, match", [("distortion_maps", "maps written to it as attributes are not saved"),
                                             ("shape_space", "the shape space stored on it is not saved")])
def test_analysis_of_a_linked_source_is_refused(bpy_empty, extension, core, override, operator, match, tmp_path):
    """Distortion maps (attributes on the mesh) and the shape space (a property of the object) of
    a linked or overridden character would not be saved with the file: refused, nothing written."""
    sheet = _linked_sheet(extension.bridge, tmp_path, override)
    attributes = set(sheet.data.attributes.keys())
    with bpy.context.temp_override(active_object=sheet, object=sheet, selected_objects=[sheet]):
        with pytest.raises(RuntimeError, match=match):
            getattr(bpy.ops.shape_differences, operator)()
    assert set(sheet.data.attributes.keys()) == attributes and "shape_space" not in sheet


@pytest.mark.parametrize("override", [False, True], ids=["linked", "overridden"])
def test_selecting_a_pose_of_a_linked_source_is_refused(bpy_empty, extension, core, override, tmp_path):
    """Select Pose writes the active shape key and the selection into the stored shape space: on
    a linked or overridden character neither would be saved with the file, so it is refused and
    changes nothing."""
    def shape_space(sheet):
        with bpy.context.temp_override(active_object=sheet, object=sheet, selected_objects=[sheet]):
            bpy.ops.shape_differences.shape_space()

    sheet = _linked_sheet(extension.bridge, tmp_path, override, prepare=shape_space)
    active, stored = sheet.active_shape_key_index, sheet["shape_space"].to_dict()
    with bpy.context.temp_override(active_object=sheet, object=sheet, selected_objects=[sheet]):
        with pytest.raises(RuntimeError, match="the pose selected on it is not saved"):
            bpy.ops.shape_differences.shape_space_select(rank=0)
    assert sheet.active_shape_key_index == active and sheet["shape_space"].to_dict() == stored


@pytest.mark.parametrize("parent_type, vertices", [("VERTEX", (4, 0, 0)), ("VERTEX_3", (3, 5, 7))])
def test_a_cache_object_keeps_its_sources_vertex_parent(bpy_empty, extension, core, parent_type, vertices,
                                                        tmp_path):
    """A source parented to vertices of a moving object: the new object hangs from the same
    vertices (before, from vertex 0: up to 2.9 units off)."""
    from blender_scenes import armature_scene
    strip = armature_scene(frames=9)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=1, location=(0.0, 0.0, 2.0))
    carrier = bpy.context.active_object
    carrier.keyframe_insert("location", frame=1)
    carrier.location, carrier.rotation_euler = (1.0, 0.5, 2.5), (0.0, 0.8, 0.5)
    carrier.keyframe_insert("location", frame=9)
    carrier.keyframe_insert("rotation_euler", frame=9)
    bpy.context.scene.frame_set(1)
    strip.parent, strip.parent_type, strip.parent_vertices = carrier, parent_type, vertices
    bpy.context.view_layer.update()
    strip.matrix_parent_inverse = carrier.matrix_world.inverted()
    names = set(bpy.data.objects.keys())
    with bpy.context.temp_override(active_object=strip, object=strip, selected_objects=[strip]):
        bpy.ops.shape_differences.frames_to_shape_keys(frame_start=1, frame_end=9, frame_step=4, output='CACHE',
                                                       filepath=str(tmp_path) + "/")
    obj = new_object(names)
    assert tuple(obj.parent_vertices) == vertices
    for frame in (1, 5, 9):
        bpy.context.scene.frame_set(frame)
        np.testing.assert_allclose(np.array(obj.matrix_world), np.array(strip.matrix_world), atol=1e-6)
    bpy.context.scene.frame_set(1)


@pytest.mark.parametrize("parent_type", [None, 'ARMATURE'])
@pytest.mark.parametrize("operator, properties, frame", [
    ("exaggerate", dict(reference="Basis", key="Curl", factor=1.5), 9),  # its one pose, held
    ("inbetween", dict(key_a="Basis", key_b="Curl", count=1), 2),  # Basis, in-between, Curl from frame 1
])
def test_a_cache_object_of_shape_key_poses_is_deformed_as_the_keys_are(
        bpy_empty, extension, core, operator, properties, frame, parent_type, tmp_path, capfd):
    """Poses of the shape keys of a rigged strip (an Armature modifier after a Subdivision, or an
    armature parent): the new object plays them under the same rig, as the new shape keys play on
    the source (before, at rest: the strip straight while the rig bends it)."""
    source = armature_scene(frames=9)
    bridge = extension.bridge
    rest = bridge.mesh_data.vertex_positions(source.data)
    curl = rest.copy()
    curl[:, 2] += 0.1 * np.sin(3.0 * curl[:, 0])  # a ripple the rig then bends
    add_key(source, "Curl", curl).value = 0.0
    source.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    bpy.ops.object.modifier_move_to_index(modifier="Subdivision", index=0)
    if parent_type:  # a parent deforming it instead of the modifier
        rig = source.modifiers["Armature"].object
        source.modifiers.remove(source.modifiers["Armature"])
        source.parent, source.parent_type = rig, parent_type
    names = set(bpy.data.objects.keys())
    with bpy.context.temp_override(active_object=source, object=source, selected_objects=[source]):
        getattr(bpy.ops.shape_differences, operator)(output='CACHE', filepath=str(tmp_path) + "/", **properties)
        getattr(bpy.ops.shape_differences, operator)(output='SHAPE_KEYS', **properties)
    obj = new_object(names)
    # an armature parent goes first in Blender's stack: its modifier right after the cache
    assert [m.type for m in obj.modifiers] == (['MESH_CACHE', 'ARMATURE', 'SUBSURF'] if parent_type
                                               else ['MESH_CACHE', 'SUBSURF', 'ARMATURE'])
    assert obj.parent is source.parent and obj.parent_type == 'OBJECT'
    added = source.data.shape_keys.key_blocks[-1]  # the pose the cache shows at ``frame``, as a key
    depsgraph = bpy.context.evaluated_depsgraph_get()
    bpy.context.scene.frame_set(frame)  # the rig bent
    added.value = 1.0
    bpy.context.view_layer.update()
    keyed = bridge.mesh_data.evaluated_positions(source, depsgraph)
    added.value = 0.0
    bpy.context.view_layer.update()
    cached = bridge.mesh_data.evaluated_positions(obj, depsgraph)
    assert len(cached) == len(keyed) > len(rest)
    assert np.abs(keyed - cached).max() < 1e-5
    assert np.abs(keyed - bridge.mesh_data.vertex_positions(obj.evaluated_get(depsgraph).data)).max() < 1e-5
    assert "Warning" not in capfd.readouterr().out


def test_a_cache_object_of_shape_key_poses_names_the_simulation_it_leaves_out(bpy_empty, extension, core,
                                                                              tmp_path, capfd):
    """A cloth on the keyed mesh is not copied (it would simulate again from its own start): said."""
    source = posed_grid(extension.bridge, 5)
    source.modifiers.new("Wind cloth", 'CLOTH')
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.exaggerate(key="Bend", factor=1.5, output='CACHE', filepath=str(tmp_path) + "/")
    obj = new_object(names)
    assert [m.type for m in obj.modifiers] == ['MESH_CACHE']
    assert "plays the poses without 'Wind cloth'" in capfd.readouterr().out


def test_a_cache_object_of_frames_names_the_hair_it_leaves_out(bpy_empty, extension, core, tmp_path, capfd):
    """Hair on an armature-bent strip renders beside the mesh and is not in the poses read: the new
    object that plays the in-betweens has none, and the run says so with how to add it (before,
    silently: the cache object rendered bald; the shape-key poses' cache said it)."""
    strip = armature_scene(frames=9)
    hair = strip.modifiers.new("Hair", 'PARTICLE_SYSTEM')
    hair.particle_system.settings.type = 'HAIR'
    names = set(bpy.data.objects.keys())
    capfd.readouterr()
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, filepath=str(tmp_path) + "/")
    obj = new_object(names)
    assert [m.type for m in obj.modifiers] == ['MESH_CACHE'] and not obj.particle_systems
    assert (f"'{obj.name}' plays the poses without 'Hair' of '{strip.name}' (a simulation, a cache or a particle "
            "system is not copied): copy them to it by hand") in capfd.readouterr().out


def _world_shown(bridge, obj, frame):
    bpy.context.scene.frame_set(frame)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    matrix = np.array(obj.evaluated_get(depsgraph).matrix_world)
    return bridge.mesh_data.evaluated_positions(obj, depsgraph) @ matrix[:3, :3].T + matrix[:3, 3]


@pytest.mark.parametrize("old, new", [(100, 50), (50, 100)])
def test_outputs_play_at_the_frames_read_under_time_stretching(bpy_empty, extension, core, old, new, tmp_path):
    """Time Stretching (Output › Frame Range) evaluates frame F at time F·old/new: the cache object,
    the keyframed keys and a retime play the kept frames at the frames they were read from
    (before, each was stretched a second time: 40 % of the motion off at frame 5)."""
    bridge = extension.bridge
    kept = (1, 5, 9, 13, 17)
    for operator, properties in (("inbetween_frames", dict(frame_step=4, count=3, output='CACHE')),
                                 ("retime", dict(frame_step=4, speed=0.5, output='CACHE')),
                                 ("inbetween_frames", dict(frame_step=4, count=3, output='SHAPE_KEYS'))):
        bpy.ops.wm.read_homefile(use_empty=True)
        # a moving parent keeps the scene's speed in a retime (a warning says so)
        source = armature_scene(frames=17, parented=operator != "retime")
        bpy.context.scene.render.frame_map_old, bpy.context.scene.render.frame_map_new = old, new
        shown = {frame: _world_shown(bridge, source, frame) for frame in kept}
        names = set(bpy.data.objects.keys())
        getattr(bpy.ops.shape_differences, operator)(frame_start=1, frame_end=17, filepath=str(tmp_path) + "/",
                                                     **properties)
        if properties["output"] == 'SHAPE_KEYS':
            obj = source
            source.modifiers["Armature"].show_viewport = False  # the keys alone show what was read
        else:
            obj = new_object(names)
        speed = properties.get("speed", 1.0)
        for frame in kept:  # a retime shows source frame F at 1 + (F − 1) / speed
            np.testing.assert_allclose(_world_shown(bridge, obj, round(1 + (frame - 1) / speed)), shown[frame],
                                       atol=1e-5, err_msg=f"{operator} {properties['output']} frame {frame}")


def _collider_under_unbaked_cloth():
    """A sphere with a "Squash" key (the active one) and a Collision modifier, under a grid whose
    Cloth is not baked and has been played (its memory cache holds frames 1–9)."""
    from blender_scenes import grid_object
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 9
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, segments=16, ring_count=8)
    ball = bpy.context.active_object
    ball.modifiers.new("Collision", 'COLLISION')
    rest = np.array([v.co[:] for v in ball.data.vertices])
    add_key(ball, "Squash", rest * np.array([1.2, 1.2, 0.7]))
    ball.active_shape_key_index = 1
    sheet = grid_object(8, name="Cloth")
    sheet.location.z = 1.0
    cloth = sheet.modifiers.new("Cloth", 'CLOTH')
    cloth.point_cache.frame_start, cloth.point_cache.frame_end = 1, 9
    for frame in range(1, 10):
        bpy.context.scene.frame_set(frame)
    bpy.context.scene.frame_set(1)
    sheet.select_set(False)
    ball.select_set(True)
    bpy.context.view_layer.objects.active = ball
    return ball, cloth.point_cache


@pytest.mark.parametrize("operator, properties, match", [
    ("inbetween", dict(count=1, output='SHAPE_KEYS'), "Shape keys added to 'Sphere' would empty"),
    ("exaggerate", dict(output='SHAPE_KEYS'), "Shape keys added to 'Sphere' would empty"),
    ("distortion_maps", dict(eigenfunctions=0, k_m=10), "Distortion maps written to 'Sphere' would empty")])
def test_writes_to_a_collider_keep_the_unbaked_cache_of_a_cloth_reacting_to_it(bpy_empty, extension, core, tmp_path,
                                                                              operator, properties, match):
    """Shape keys or attributes added to a collider's mesh make Blender simulate the cloths reacting
    to it again from their start (before: written, the cloth's 9 cached frames gone): refused
    before any work, naming the cloth; the cache as it was. Point Cache output writes nothing to it."""
    ball, cache = _collider_under_unbaked_cloth()
    cached = cache.info
    assert cached.startswith("9 frames")
    before = snapshot(extension.bridge, ball)
    with pytest.raises(RuntimeError, match=match + r" the unbaked cache of 'Cloth' \('Cloth'\), which may react"):
        getattr(bpy.ops.shape_differences, operator)(**properties)
    assert_unchanged(before, snapshot(extension.bridge, ball))
    bpy.context.evaluated_depsgraph_get()
    assert cache.info == cached
    if operator == "inbetween":
        bpy.ops.shape_differences.inbetween(count=1, output='CACHE', filepath=str(tmp_path) + "/")
        bpy.context.evaluated_depsgraph_get()
        assert cache.info == cached


@pytest.mark.parametrize("twin", [False, True], ids=["own", "linked duplicate"])
def test_distortion_maps_keep_an_unbaked_cloth_cache(bpy_empty, extension, twin):
    """Attributes written to the mesh of a cloth not baked (its own, or a linked duplicate's) empty
    its cache as shape keys do (before: the maps written, 13 cached frames gone): refused as shape
    keys are, nothing changed."""
    source = pinned_cloth_scene(frames=9)
    cache = source.modifiers["Cloth"].point_cache
    cached = cache.info
    target = source
    if twin:
        target = bpy.data.objects.new("Twin", source.data)
        bpy.context.scene.collection.objects.link(target)
        bpy.context.view_layer.objects.active = target
    before = snapshot(extension.bridge, target)
    match = ("shares its mesh with 'Flag', and distortion maps written to that mesh would empty" if twin else
             "Distortion maps written to 'Flag' would empty the unbaked cache of its 'Cloth' simulation")
    with pytest.raises(RuntimeError, match=match):
        bpy.ops.shape_differences.distortion_maps(source='FRAMES', frame_step=4, eigenfunctions=0, k_m=10)
    assert_unchanged(before, snapshot(extension.bridge, target))
    bpy.context.evaluated_depsgraph_get()
    assert cache.info == cached and not cache.is_outdated


def test_a_cloth_simulated_for_the_run_is_said(bpy_empty, extension, capfd, tmp_path):
    """An unbaked cloth sent to a farm or batch with no frames in its cache is simulated by the task
    itself (hours at 100k vertices on every node): said in a warning naming it, the frames and the
    time (before, not a word). A cache already holding the frames (played and saved, or baked)
    reads without simulating, and without the warning."""
    from blender_scenes import grid_object

    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 9
    obj = grid_object(8, name="Flag")
    obj.rotation_euler.x = 1.2
    obj.modifiers.new("Cloth", 'CLOTH').point_cache.frame_end = 9
    bpy.context.view_layer.objects.active = obj
    capfd.readouterr()
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=0.5, filepath=str(tmp_path) + "/")
    assert re.search(r"'Cloth' of 'Flag' is not baked, and frames 1–9 were simulated for this run where its cache "
                     r"held none \(reading took [0-9.]+ s\)", capfd.readouterr().out)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=0.5, filepath=str(tmp_path) + "/")
    assert "not baked" not in capfd.readouterr().out  # the frames are in its memory cache now


def _rigid_body_scene(kind: str, frames: int = 17, wave: bool = True):
    """A grid 2 above a passive floor, a rigid body of ``kind`` ('ACTIVE': it falls and tumbles,
    'PASSIVE': it stays) whose relative shape key "Wave" plays 0 → 1 over ``frames`` (it deforms
    while the simulation moves it; none without ``wave``); the rigid body world not baked. Returns
    the grid, the selected active object."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    bpy.ops.mesh.primitive_plane_add(size=20)
    bpy.ops.rigidbody.object_add(type='PASSIVE')
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=8, y_subdivisions=8, size=1.0, location=(0, 0, 2),
                                    rotation=(0.5, 0.3, 0))
    grid = bpy.context.active_object
    bpy.ops.rigidbody.object_add(type=kind)
    grid.rigid_body.collision_shape = 'CONVEX_HULL'
    for obj in scene.objects:
        obj.select_set(obj == grid)
    bpy.context.view_layer.objects.active = grid
    if not wave:
        return grid
    grid.shape_key_add(name="Basis")
    wave = grid.shape_key_add(name="Wave")
    for point in wave.data:
        point.co.z += 0.2 * np.sin(3 * point.co.x)
    for frame, value in ((1, 0.0), (frames, 1.0)):
        wave.value = value
        wave.keyframe_insert("value", frame=frame)
    return grid


def _shown(bridge, obj, frames) -> dict:
    """World positions of ``obj``'s evaluated mesh at each of ``frames``, visited in order (an
    unbaked rigid body simulation steps one frame at a time); the scene is left at frame 1."""
    result = {}
    for frame in frames:
        bpy.context.scene.frame_set(frame)
        matrix = np.array(obj.matrix_world)
        result[frame] = (bridge.mesh_data.evaluated_positions(obj, bpy.context.evaluated_depsgraph_get())
                         @ matrix[:3, :3].T + matrix[:3, 3])
    bpy.context.scene.frame_set(1)
    return result


def _bake_to_keyframes(obj, frames):
    """What Object › Rigid Body › Bake To Keyframes does (its operator needs a 3D View's context):
    ``obj``'s simulated placement keyframed at each of ``frames``, its rigid body removed."""
    placed = {}
    for frame in frames:
        bpy.context.scene.frame_set(frame)
        placed[frame] = obj.matrix_world.copy()
    bpy.ops.rigidbody.object_remove()
    for frame in frames:
        obj.matrix_world = placed[frame]
        obj.keyframe_insert("location", frame=frame)
        obj.keyframe_insert("rotation_euler", frame=frame)
    bpy.context.scene.frame_set(1)


@pytest.mark.parametrize("kind", ['ACTIVE', 'PASSIVE'])
def test_a_new_object_stays_out_of_the_rigid_body_simulation(bpy_empty, extension, core, tmp_path, capfd, kind):
    """The new object is not linked into the rigid body world's collection, where Blender makes every
    object an active rigid body of the user's simulation (before: the copy of a passive grid fell
    6.7 below it; the copies of a falling grid collided with it and moved it 2.7 off its own
    motion, and the world's unbaked cache was simulated again: 5 → 8 KiB). A source moved by its
    simulation is named with the fix (Bake To Keyframes), after which the new object follows it."""
    grid = _rigid_body_scene(kind)
    world = bpy.context.scene.rigidbody_world
    frames = range(1, 18)
    shown = _shown(extension.bridge, grid, frames)
    info = world.point_cache.info
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=17, frame_step=8, count=7,
                                               output='CACHE', filepath=str(tmp_path / "first.pc2"))
    obj = new_object(names)
    out = capfd.readouterr().out
    assert obj.rigid_body is None and obj.name not in world.collection.objects
    assert world.point_cache.info == info
    after = _shown(extension.bridge, grid, frames)
    for frame in frames:  # the user's simulation plays as before
        np.testing.assert_array_equal(after[frame], shown[frame])
    new = _shown(extension.bridge, obj, frames)

    def assert_follows(new):
        """The new object shows the grid where it is: its keys (every 8th frame) to float32, the
        in-betweens within the wave's blend (0.2 high)"""
        for frame in frames:
            np.testing.assert_allclose(new[frame], shown[frame], atol=0.02 if (frame - 1) % 8 else 1e-4)

    if kind == 'PASSIVE':  # it does not move
        assert "rigid body" not in out
        assert_follows(new)
        return
    assert (f"'{obj.name}' stands still where '{grid.name}' is moved as a whole by its rigid body simulation"
            in out and "Object › Rigid Body › Bake To Keyframes" in out)
    assert np.abs(new[17] - shown[17]).max() > 1.0  # it fell; the new object stays
    _bake_to_keyframes(grid, frames)  # the fix the warning names
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=17, frame_step=8, count=7,
                                               output='CACHE', filepath=str(tmp_path / "baked.pc2"))
    obj = new_object(names)
    assert "rigid body" not in capfd.readouterr().out
    assert_follows(_shown(extension.bridge, obj, frames))  # the keyframed transform taken over


def test_a_rigid_body_moving_the_source_is_named(bpy_empty, extension, core, capfd):
    """A falling grid that does not deform, retimed to shape keys: its frames are the same pose,
    said to be moved as a whole by its rigid body (before: "check what moves it (a baked cache
    whose files are gone …)"), and the simulation keeps its own speed, with the fix named (before:
    no warning about its motion)."""
    grid = _rigid_body_scene('ACTIVE', wave=False)
    grid.rigid_body.mesh_source = 'BASE'  # keys added leave its collision shape, and so its simulation
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=17, frame_step=8, speed=0.5, output='SHAPE_KEYS')
    out = capfd.readouterr().out
    assert ("are all the same pose: its rigid body simulation moves it as a whole (its place in the world, not "
            "the vertices of its mesh)") in out
    assert (f"'{grid.name}' is moved as a whole by its rigid body simulation, at its own speed while the new shape "
            "keys play at 0.5x: bake it to keyframes (Object › Rigid Body › Bake To Keyframes)") in out


@pytest.mark.parametrize("kind", ['ACTIVE', 'PASSIVE'])
def test_shape_keys_are_refused_on_a_rigid_body_whose_unbaked_simulation_reads_its_deformed_mesh(
        bpy_empty, extension, core, kind):
    """Shape keys added to a rigid body of an unbaked world whose convex hull is read from its deformed
    mesh change what the simulation collides (keys holding frame 9's pose from frame 1 moved a fall's
    end from z = -5.27 to 0.46): refused before any work, naming the fixes; nothing changes."""
    grid = _rigid_body_scene(kind)
    world = bpy.context.scene.rigidbody_world
    before, info = snapshot(extension.bridge, grid), world.point_cache.info
    with pytest.raises(RuntimeError, match="would change its rigid body simulation, which is not baked"):
        bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=17, frame_step=8, output='SHAPE_KEYS')
    assert_unchanged(before, snapshot(extension.bridge, grid))
    assert world.point_cache.info == info
    grid.rigid_body.mesh_source = 'BASE'  # the fix the message names
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=17, frame_step=8, output='SHAPE_KEYS')
