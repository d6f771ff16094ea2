"""What the operators write lives on in .blend files: a cache written before the .blend was
first saved is kept when it is saved, cache paths do not depend on the folder Blender was started
from, a new cache never takes the file another object plays, a cache object does not inherit its
source's analysis, and a stored shape space is drawn again when the file is opened."""

import os
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import add_key, armature_scene, grid_object, played, rolled  # noqa: E402


def _new_object(names: set):
    [obj] = [obj for obj in bpy.data.objects if obj.name not in names]
    return obj


def _inbetween_frames(**properties):
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=3, output='CACHE',
                                               **properties)
    return _new_object(names)


def test_a_cache_in_the_session_folder_is_kept_when_the_blend_is_saved(bpy_empty, extension, tmp_path):
    """Written before the .blend was ever saved, the cache sits in Blender's temporary folder,
    which Blender deletes when it quits: saving copies it beside the .blend and points the
    modifier there (before, the saved file pointed into the deleted folder: the object played its
    rest mesh, 0.23 off); a *Save Copy* leaves this session's object as it was."""
    armature_scene(frames=9)
    obj = _inbetween_frames()
    modifier = obj.modifiers["Mesh Cache"]
    temporary = modifier.filepath
    assert Path(temporary).parent == Path(bpy.app.tempdir) and Path(temporary).is_file()
    before = played(extension.bridge, obj, range(1, 10))

    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "copy" / "shot.blend"), copy=True)
    assert modifier.filepath == temporary and (tmp_path / "copy" / "caches" / Path(temporary).name).is_file()

    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot" / "shot.blend"))
    assert modifier.filepath == f"//caches/{Path(temporary).name}"
    assert (tmp_path / "shot" / "caches" / Path(temporary).name).is_file()
    os.remove(temporary)  # what quitting Blender does
    name = obj.name
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "shot" / "shot.blend"))
    after = played(extension.bridge, bpy.data.objects[name], range(1, 10))
    for frame in before:
        np.testing.assert_array_equal(after[frame], before[frame])


def test_a_plain_relative_cache_file_is_beside_the_blend(bpy_empty, extension, tmp_path, monkeypatch):
    """``caches/out.pc2`` (no ``//``) goes beside the saved .blend and is stored relative to it
    (before: beside the folder Blender was started from, and stored so, which another start
    folder could not find)."""
    armature_scene(frames=9)
    (tmp_path / "shots").mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shots" / "shot.blend"))
    monkeypatch.chdir(tmp_path)
    obj = _inbetween_frames(filepath="caches/out.pc2")
    assert obj.modifiers["Mesh Cache"].filepath == "//caches/out.pc2"
    assert (tmp_path / "shots" / "caches" / "out.pc2").is_file() and not (tmp_path / "caches").exists()


def test_a_new_cache_never_takes_a_file_another_object_plays(bpy_empty, extension, tmp_path):
    """A .blend copied to a new version without its caches: the old object's path is free on disk,
    but a new run with the same Cache File takes another name (before, both objects played the
    new file)."""
    armature_scene(frames=9)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    first = _inbetween_frames(filepath="//caches/cloth.pc2")
    os.remove(tmp_path / "caches" / "cloth.pc2")
    bpy.context.view_layer.objects.active = bpy.data.objects["Grid"]
    second = _inbetween_frames(filepath="//caches/cloth.pc2")
    assert first.modifiers["Mesh Cache"].filepath == "//caches/cloth.pc2"
    assert second.modifiers["Mesh Cache"].filepath == "//caches/cloth.001.pc2"


def test_a_cache_file_the_system_refuses_is_said_before_any_work(bpy_empty, extension, tmp_path):
    armature_scene(frames=9)
    names = set(bpy.data.objects.keys())
    with pytest.raises(RuntimeError, match="Cannot use the Cache File .*File name too long") as failure:
        bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='CACHE',
                                                   filepath=str(tmp_path / ("x" * 300 + ".pc2")))
    assert "Traceback" not in str(failure.value) and set(bpy.data.objects.keys()) == names


def test_a_cache_object_does_not_inherit_its_sources_analysis(bpy_empty, extension, tmp_path):
    """Distortion maps of the source's frames and the mesh's custom properties stay on the source
    (before, a retimed object showed the map of another pose at each frame, and took the asset tags);
    the user's own attributes go along, whatever their names (before, any named "sd_…" or "SD …"
    was dropped from the new object)."""
    strip = armature_scene(frames=9)
    strip.data["asset_id"] = "chr_cape_v3"
    own = {"sd_mask": ('FLOAT', 'POINT'), "SD Paint": ('FLOAT_COLOR', 'CORNER')}  # the user's: they go along
    for name, (kind, domain) in own.items():
        strip.data.attributes.new(name, kind, domain)
    bpy.ops.shape_differences.distortion_maps(source='FRAMES', frame_start=1, frame_end=9, frame_step=4,
                                              eigenfunctions=1)
    bpy.ops.shape_differences.distortion_maps(source='FRAMES', frame_start=-3, frame_end=-3, eigenfunctions=1)
    maps = [name for name in strip.data.attributes.keys() if name.startswith(("SD ", "sd_")) and name not in own]
    assert "SD Eigen Offset Conformal 1 f5" in maps and "sd_bending_face f-3" in maps
    obj = _inbetween_frames(filepath=str(tmp_path) + "/")
    assert {name for name in obj.data.attributes.keys() if name.startswith(("SD ", "sd_"))} == set(own)
    assert not obj.data.keys() and strip.data["asset_id"] == "chr_cape_v3"


def test_the_shape_space_image_is_drawn_again_when_the_blend_is_opened(bpy_empty, extension, tmp_path):
    """A generated image is not saved with the file: it came back missing (or blank); drawn again
    from the coordinates stored on the object, pixel for pixel."""
    sheet = grid_object(6)
    rest = extension.bridge.vertex_positions(sheet.data)
    for index, angle in enumerate((0.5, 1.0, 1.5)):
        add_key(sheet, f"Bend {index}", rolled(rest, angle))
    bpy.ops.shape_differences.shape_space(source='KEYS')
    name = f"Shape Space {sheet.name}"
    pixels = np.array(bpy.data.images[name].pixels[:])
    assert np.ptp(pixels) > 0.5
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "space.blend"))
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "space.blend"))
    image = bpy.data.images.get(name)
    assert image is not None
    np.testing.assert_array_equal(np.array(image.pixels[:]), pixels)
