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
    bpy.ops.shape_differences.inbetween_frames(**{**dict(frame_start=1, frame_end=9, frame_step=4, count=3,
                                                         output='CACHE'), **properties})
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


def test_a_cache_file_under_a_tilde_is_in_the_home_folder(bpy_empty, extension, tmp_path, monkeypatch):
    """``~/caches/out.pc2`` given in a script is in the home folder, as a shell and ``python -m core``
    take it, and stored in full (before: a folder named ``~`` beside the saved .blend)."""
    armature_scene(frames=9)
    (tmp_path / "shots").mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shots" / "shot.blend"))
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    obj = _inbetween_frames(filepath="~/caches/out.pc2")
    assert obj.modifiers["Mesh Cache"].filepath == str(tmp_path / "home" / "caches" / "out.pc2")
    assert (tmp_path / "home" / "caches" / "out.pc2").is_file() and not (tmp_path / "shots" / "~").exists()


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
    rest = extension.bridge.mesh_data.vertex_positions(sheet.data)
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


def test_a_run_made_again_plays_its_earlier_file(bpy_empty, extension, tmp_path):
    """A farm task retried, or a batch run again, on the saved shot: the first run's file (no object
    of the shot plays it, as the shot was opened again unsaved) holds exactly these poses, so the new
    object plays it (before, each run wrote `cloth.001.pc2`, `cloth.002.pc2`, … beside it: 0.6 GB each
    at 100k vertices x 500 frames). Other poses under that name still go to a new file, and an earlier
    file a Mesh Cache of the shot plays is never taken (test above)."""
    armature_scene(frames=9)
    shot = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(shot))
    _inbetween_frames(filepath="//caches/cloth.pc2")
    written = (tmp_path / "caches" / "cloth.pc2").read_bytes()
    for _ in range(2):  # the task again, twice
        bpy.ops.wm.open_mainfile(filepath=str(shot))
        bpy.context.view_layer.objects.active = bpy.data.objects["Grid"]
        again = _inbetween_frames(filepath="//caches/cloth.pc2")
        assert again.modifiers["Mesh Cache"].filepath == "//caches/cloth.pc2"
    assert sorted(os.listdir(tmp_path / "caches")) == ["cloth.pc2"]
    assert (tmp_path / "caches" / "cloth.pc2").read_bytes() == written

    bpy.ops.wm.open_mainfile(filepath=str(shot))
    bpy.context.view_layer.objects.active = bpy.data.objects["Grid"]
    other = _inbetween_frames(filepath="//caches/cloth.pc2", count=2)  # other poses, same name
    assert other.modifiers["Mesh Cache"].filepath == "//caches/cloth.001.pc2"
    assert (tmp_path / "caches" / "cloth.pc2").read_bytes() == written


def test_two_processes_writing_one_cache_name_keep_a_file_each(bpy_empty, extension, tmp_path, monkeypatch):
    """Two shots in one folder, each with an object of the same name, retimed on one machine at once:
    both pick the free name `caches/cloth.pc2`, and another process's file lands there while this
    one is writing. The name is taken only if still free once the file is whole: this run's poses go
    to `cloth.001.pc2` and the other file stays (before, the later write replaced the earlier, and
    one shot played the other's cloth)."""
    armature_scene(frames=9)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot_a.blend"))
    other_shot = b"the other shot's cache"
    target = tmp_path / "caches" / "cloth.pc2"

    def landing_first(rename):
        def call(source, destination, *args, **kwargs):
            if Path(destination) == target and not target.exists():
                target.write_bytes(other_shot)
            return rename(source, destination, *args, **kwargs)
        return call

    monkeypatch.setattr(os, "replace", landing_first(os.replace))
    monkeypatch.setattr(os, "link", landing_first(os.link))
    obj = _inbetween_frames(filepath="//caches/cloth.pc2")
    monkeypatch.undo()
    assert target.read_bytes() == other_shot
    assert obj.modifiers["Mesh Cache"].filepath == "//caches/cloth.001.pc2"
    assert sorted(os.listdir(tmp_path / "caches")) == ["cloth.001.pc2", "cloth.pc2"]  # no temporary file left
