"""What the operators and handlers leave of the user's file, on a run that succeeds and on the odd
input: another mesh's animation in a shared action, an image the run did not make, the frame and
active key after a bug in Select Pose, and handlers that run out of memory inside Blender's frame
change, load or undo."""

import importlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import _fcurves, armature_scene, posed_grid  # noqa: E402
from dev_extension import MODULE  # noqa: E402
from test_undo import file_state  # noqa: E402


def _module(name: str):
    return importlib.import_module(f"{MODULE}.{name}")


def _keyframes(animation_data) -> dict:
    """Every F-curve of ``animation_data``'s action (its slot's) by data path: each keyframe's frame,
    value and interpolation."""
    return {fcurve.data_path: [(tuple(point.co), point.interpolation) for point in fcurve.keyframe_points]
            for fcurve in _fcurves(animation_data)}


def _active(obj) -> None:
    for other in bpy.context.view_layer.objects:
        other.select_set(other == obj)
    bpy.context.view_layer.objects.active = obj


def test_in_between_frames_into_an_action_shared_with_another_mesh_leaves_that_meshs_animation(bpy_empty,
                                                                                                extension):
    """An action (and slot) shared by two meshes' shape keys: the second strip's keys "Frame 1", … are
    keyframed in it, eased by the user (Bezier), and the first strip plays it with only a Basis.
    In-between Frames on the first strip succeeds: the second strip's F-curves keep their keyframes and
    interpolation, and the first strip's new keys take names no F-curve there animates, each keyframed on
    an F-curve of its own, linear. Before, the new keys took the second strip's names (free on the first),
    their keyframes went into the second strip's F-curves, and every point of those became linear."""
    first = armature_scene(frames=9)
    second = first.copy()
    second.data = first.data.copy()
    bpy.context.scene.collection.objects.link(second)
    _active(second)
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='SHAPE_KEYS')
    shared = second.data.shape_keys.animation_data
    for fcurve in _fcurves(shared):  # the user's easing
        for point in fcurve.keyframe_points:
            point.interpolation = 'BEZIER'
    kept = _keyframes(shared)
    first.shape_key_add(name="Basis", from_mix=False)
    animation = first.data.shape_keys.animation_data_create()
    animation.action = shared.action
    if hasattr(animation, "action_slot"):
        animation.action_slot = shared.action_slot
    _active(first)
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='SHAPE_KEYS')
    after = _keyframes(second.data.shape_keys.animation_data)
    assert {path: after[path] for path in kept} == kept  # (the slot, shared, also holds the new keys' F-curves)
    added = first.data.shape_keys.key_blocks[1:]
    assert len(added) == 5 and not {key_block.name for key_block in added} & set(second.data.shape_keys.key_blocks.keys())
    curves = _keyframes(animation)
    for key_block in added:
        points = curves[f'key_blocks["{key_block.name}"].value']
        assert points and all(interpolation == 'LINEAR' for _, interpolation in points)


def _image_digest(image) -> tuple:
    pixels = np.empty(image.size[0] * image.size[1] * image.channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return tuple(image.size), pixels.tobytes()


def _shape_space(obj) -> str:
    """Run Shape Space on ``obj`` and return the name of the image it drew into."""
    _active(obj)
    bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=0)
    return obj["shape_space"]["image"]


def test_shape_space_never_draws_over_an_image_it_did_not_make_for_the_object(bpy_empty, extension):
    """Shape Space draws into an image named after the object ("Shape Space Grid"). The user's own image
    of that name, the image of another object renamed since ("Sheet", its shape space drawn as "Grid")
    and the image of the object a grid was duplicated from (the duplicate's stored shape space names it)
    keep their pixels: the run draws into a new image, "Shape Space Grid.001" and on. A second run on
    an object draws into its own image again (no new image). Before, every run drew into "Shape Space
    <object>", whoever's image that was."""
    bridge = extension.bridge
    grid = posed_grid(bridge, 6)
    grid.name = "Grid"
    users = bpy.data.images.new("Shape Space Grid", 4, 4)
    users.pixels.foreach_set(np.full(64, 0.25, dtype=np.float32))
    theirs = _image_digest(users)
    own = _shape_space(grid)
    assert own != "Shape Space Grid" and _image_digest(users) == theirs
    drawn = _image_digest(bpy.data.images[own])
    count = len(bpy.data.images)
    grid.active_shape_key_index = 0
    assert _shape_space(grid) == own and len(bpy.data.images) == count  # its own image, drawn again
    grid.name = "Sheet"
    second = posed_grid(bridge, 5)
    second.name = "Grid"
    assert _shape_space(second) not in (own, "Shape Space Grid")
    assert _image_digest(bpy.data.images[own]) == drawn and _image_digest(users) == theirs
    copy = grid.copy()  # Shift+D: the stored shape space and its image's name come along
    copy.data = grid.data.copy()
    bpy.context.scene.collection.objects.link(copy)
    copy.data.shape_keys.key_blocks["Curl"].data[0].co.z += 0.5  # another shape space
    assert _shape_space(copy) != own and _image_digest(bpy.data.images[own]) == drawn


@pytest.mark.parametrize("source", ['KEYS', 'FRAMES'])
def test_a_bug_in_select_pose_takes_back_what_it_changed_and_shows_its_traceback(bpy_empty, extension,
                                                                                 monkeypatch, source):
    """Select Pose with a bug after it has gone to the pose (the active key, or the frame) and stored the
    selection and drawn it: Blender shows the traceback, and the active key, the frame, the stored
    selection and the image are as they were. Before, only a MemoryError was taken back; a bug left the
    new frame or active key, selection and highlight."""
    bridge = extension.bridge
    if source == 'KEYS':
        posed_grid(bridge, 6)
        bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=0)
    else:
        armature_scene(frames=9)
        bpy.ops.shape_differences.shape_space(source='FRAMES', frame_step=2, k_m=20, k_n=0)
    bpy.ops.shape_differences.shape_space_select(kind='offset_area', rank=0)
    before = file_state(bridge)

    def bug(*_args):
        raise ValueError("a bug in showing the image")

    monkeypatch.setattr(_module("operators.analysis"), "show_image", bug)
    with pytest.raises(RuntimeError, match="ValueError: a bug in showing the image"):
        bpy.ops.shape_differences.shape_space_select(kind='offset_area', rank=2)
    assert file_state(bridge) == before


def _out_of_memory(*_args, **_kwargs):
    raise MemoryError("Unable to allocate 1.21 GiB for an array with shape (54000, 3000) and data type float64")


def test_handlers_that_run_out_of_memory_skip_that_call_and_say_so_once(bpy_empty, extension, monkeypatch, capsys):
    """The frame-change handler that shows each frame's distortion map and the load / undo handler that
    draws shape space images again, each running out of memory twice: neither throws into Blender (a
    traceback at every frame of playback), each says so once on the console in the user's words. Before,
    the MemoryError went through to Blender."""
    analysis = _module("operators.analysis")
    monkeypatch.setattr(_module("operators.handler_guard"), "_SAID", set())
    posed_grid(extension.bridge, 6)
    bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=0)
    mesh = bpy.context.active_object.data
    for frame in (1, 5):  # maps of two frames, the first shown
        mesh.color_attributes.new(f"SD Area f{frame}", 'FLOAT_COLOR', 'POINT')
    mesh.color_attributes.active_color = mesh.color_attributes["SD Area f1"]
    mesh[analysis.FRAME_MAPS_PROPERTY] = {"frames": [1, 5], "map": "Area"}
    scene = bpy.context.scene
    scene.frame_current = 5
    monkeypatch.setattr(analysis, "simulations_emptied_by", _out_of_memory)
    monkeypatch.setattr(analysis, "shape_space_image", _out_of_memory)
    monkeypatch.setattr(analysis, "_DRAWN", {})  # as after a file load: every image drawn again
    capsys.readouterr()
    for _ in range(2):
        assert analysis.follow_frame(scene) is None
        assert analysis.redraw_shape_spaces() is None
    said = capsys.readouterr().err
    assert said.count("ran out of memory") == 2, said
    assert "while showing the distortion map of the frame" in said
    assert "while drawing the shape space images again" in said and "Unable to allocate 1.21 GiB" in said
    assert mesh.color_attributes.active_color.name == "SD Area f1"  # the call skipped
