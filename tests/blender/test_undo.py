"""Ctrl+Z and Shift+Ctrl+Z after every operator: undo gives back the file as it was before the
operator ran, redo the file as the operator left it (objects, meshes, shape keys, attributes,
custom properties, images' pixels, the current frame).

Blender starts the bpy module (background mode) with undo off; ``ed.undo_push`` starts it, and an
operator called with ``undo=True`` (``op('EXEC_DEFAULT', True)``, as the UI calls it) pushes its
step when it declares 'UNDO'. What this cannot reach: the modal run from the UI (background mode
runs ``execute``; the step is pushed when the operator finishes either way) and the files a cache
output writes, which undo leaves on disk (a redo plays them again)."""

import hashlib
import importlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import armature_scene, posed_grid, transfer_pair  # noqa: E402
from dev_extension import MODULE  # noqa: E402


def _digest(values) -> str:
    return hashlib.sha1(np.ascontiguousarray(values).tobytes()).hexdigest()


def file_state(bridge) -> dict:
    """What the operators may change, comparable with ``==``."""
    state = {"frame": bpy.context.scene.frame_current}
    for obj in bpy.data.objects:
        entry = {"modifiers": [(m.name, m.type) for m in obj.modifiers],
                 "properties": {name: repr(obj[name].to_dict() if hasattr(obj[name], "to_dict") else obj[name])
                                for name in obj.keys()}}
        if obj.type == 'MESH':
            mesh, key = obj.data, obj.data.shape_keys
            entry["positions"] = _digest(bridge.mesh_data.vertex_positions(mesh))
            entry["attributes"] = sorted((a.name, a.domain, a.data_type) for a in mesh.attributes)
            entry["mesh properties"] = sorted(mesh.keys())
            entry["keys"] = [(kb.name, _digest(bridge.mesh_data.stored_key_positions(kb)))
                             for kb in key.key_blocks] if key else []
            entry["keyframed"] = bool(key and key.animation_data and key.animation_data.action)
            entry["active key"] = obj.active_shape_key_index
        state[f"object {obj.name}"] = entry
    for image in bpy.data.images:
        pixels = np.empty(image.size[0] * image.size[1] * image.channels, dtype=np.float32)
        image.pixels.foreach_get(pixels)
        state[f"image {image.name}"] = (tuple(image.size), _digest(pixels))
    return state


def _keyed(bridge):
    posed_grid(bridge, 6)


def _animated(bridge):
    armature_scene(frames=9)


def _transfer_pair(bridge):
    transfer_pair(bridge, 8, 6)


def _shape_space_drawn(bridge):
    posed_grid(bridge, 6)
    bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=0)


CASES = [
    ("inbetween", _keyed, dict(count=1)),
    ("inbetween", _keyed, dict(count=1, output='CACHE')),
    ("exaggerate", _keyed, {}),
    ("reconstruct", _keyed, {}),
    ("frames_to_shape_keys", _animated, dict(frame_start=1, frame_end=9, frame_step=4, output='SHAPE_KEYS')),
    ("inbetween_frames", _animated, dict(frame_step=4, count=1)),
    ("retime", _animated, dict(frame_step=4, speed=0.5)),
    ("shape_space", _keyed, dict(source='KEYS', k_m=20, k_n=0)),
    ("shape_space_select", _shape_space_drawn, dict(kind='offset_area', rank=0)),
    ("distortion_maps", _keyed, dict(source='ACTIVE_KEY', k_m=20, eigenfunctions=1)),
    ("transfer_poses", _transfer_pair, dict(k_m=16, k_n=32)),
]


def test_every_operator_is_covered(extension):
    operators = importlib.import_module(f"{MODULE}.operators")
    assert {cls.bl_idname.split(".")[1] for cls in operators.classes} == {name for name, *_ in CASES}


@pytest.mark.parametrize("name, setup, properties", CASES,
                         ids=[f"{name}-{properties.get('output', 'default')}" for name, _, properties in CASES])
def test_undo_gives_back_the_file_before_and_redo_the_file_after(bpy_empty, extension, core, tmp_path, name, setup,
                                                                 properties):
    """Shape Space and Select Pose redraw the image from the restored shape space: undo and redo
    restore the stored coordinates and selection but not an image's pixels (before, an undone
    Select Pose stayed highlighted in the image and a redone Shape Space came back black)."""
    bridge = extension.bridge
    setup(bridge)
    operator = getattr(bpy.ops.shape_differences, name)
    if "filepath" in operator.get_rna_type().properties.keys():  # caches go to the test's folder
        properties = dict(properties, filepath=str(tmp_path) + "/")
    bpy.ops.ed.undo_push(message="before")  # starts the undo system (off at start in background mode)
    before = file_state(bridge)
    assert operator('EXEC_DEFAULT', True, **properties) == {'FINISHED'}
    after = file_state(bridge)
    assert after != before
    bpy.ops.ed.undo()
    assert file_state(bridge) == before
    bpy.ops.ed.redo()
    assert file_state(bridge) == after


def test_adjusting_the_last_run_leaves_only_the_cache_it_plays(bpy_empty, extension, core, tmp_path):
    """The Redo panel (Adjust Last Operation) undoes the run and runs it again with the new
    settings: the cache file of the undone run, which nothing plays any more, is deleted (before,
    each change of a setting left one more file on disk: 0.6 GB for 500 frames of 100k vertices);
    switched to Shape Keys, no file is left. Blender repeats the last run in a 3D View's region,
    which background mode does not give (without one, ``ed.undo_redo`` crashes Blender): one is
    named; ``undo=True`` lets the repeated run push its undo step as the UI's does."""
    armature_scene(frames=9)
    bpy.ops.ed.undo_push(message="before")
    bpy.ops.shape_differences.retime('EXEC_DEFAULT', True, frame_step=4, speed=0.5, filepath=str(tmp_path) + "/")
    window = bpy.context.window
    area = next(area for area in window.screen.areas if area.type == 'VIEW_3D')
    region = next(region for region in area.regions if region.type == 'WINDOW')
    last = bpy.context.window_manager.operators[-1]
    assert last.bl_idname == "SHAPE_DIFFERENCES_OT_retime"
    for speed in (0.25, 2.0):
        last.properties.speed = speed
        with bpy.context.temp_override(window=window, screen=window.screen, area=area, region=region):
            assert bpy.ops.ed.undo_redo('EXEC_DEFAULT', True) == {'FINISHED'}
        played = [bpy.path.abspath(m.filepath) for obj in bpy.data.objects for m in obj.modifiers
                  if m.type == 'MESH_CACHE']
        assert len(played) == 1 and sorted(str(p) for p in tmp_path.iterdir()) == played
        assert bpy.data.objects[f"Grid Retime {speed:.2f}x step 4"]
    last.properties.output = 'SHAPE_KEYS'
    with bpy.context.temp_override(window=window, screen=window.screen, area=area, region=region):
        assert bpy.ops.ed.undo_redo('EXEC_DEFAULT', True) == {'FINISHED'}
    assert not list(tmp_path.iterdir())


def test_adjusting_a_run_that_played_an_earlier_file_keeps_that_file(bpy_empty, extension, core, tmp_path):
    """A run whose poses an earlier run's file already holds plays that file without writing it
    (another version of the shot in the folder plays it: here shot_v1.blend); changing a setting in
    the Redo panel then writes the new run's file and leaves that one alone (before, it was deleted
    as the undone run's own, and shot_v1.blend played a file that was gone)."""
    armature_scene(frames=9)
    folder = str(tmp_path / "caches") + "/"
    bpy.ops.shape_differences.retime(frame_step=4, speed=0.5, filepath=folder)
    earlier = next(tmp_path.joinpath("caches").iterdir())
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot_v1.blend"))
    bpy.data.objects.remove(bpy.data.objects["Grid Retime 0.50x step 4"])
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot_v2.blend"))
    bpy.ops.ed.undo_push(message="before")
    bpy.ops.shape_differences.retime('EXEC_DEFAULT', True, frame_step=4, speed=0.5, filepath=folder)
    played = [m.filepath for obj in bpy.data.objects for m in obj.modifiers if m.type == 'MESH_CACHE']
    assert [bpy.path.abspath(path) for path in played] == [str(earlier)]  # the earlier run's file, played again
    window = bpy.context.window
    area = next(area for area in window.screen.areas if area.type == 'VIEW_3D')
    region = next(region for region in area.regions if region.type == 'WINDOW')
    last = bpy.context.window_manager.operators[-1]
    last.properties.speed = 0.25
    with bpy.context.temp_override(window=window, screen=window.screen, area=area, region=region):
        assert bpy.ops.ed.undo_redo('EXEC_DEFAULT', True) == {'FINISHED'}
    assert bpy.data.objects["Grid Retime 0.25x step 4"]
    assert earlier.is_file() and len(list(tmp_path.joinpath("caches").iterdir())) == 2
