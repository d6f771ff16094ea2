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


def _in_between_frames_keys(obj) -> list[str]:
    """Run In-between Frames (every 4th frame, one in-between) into ``obj``'s shape keys; the names added."""
    _active(obj)
    before = set(obj.data.shape_keys.key_blocks.keys()) if obj.data.shape_keys else set()
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='SHAPE_KEYS')
    return [name for name in obj.data.shape_keys.key_blocks.keys() if name not in before and name != "Basis"]


def _deleted_keys_rerun():
    """A mesh given In-between Frames' keys, which the user deletes (Blender keeps their F-curves), one of
    those F-curves given a keyframe of its own at frame 20 (an old animation of the key): the names of the
    first run, and the mesh."""
    obj = armature_scene(frames=9)
    first = _in_between_frames_keys(obj)
    for name in first:
        obj.shape_key_remove(obj.data.shape_keys.key_blocks[name])
    animation = obj.data.shape_keys.animation_data
    stale = {fcurve.data_path: fcurve for fcurve in _fcurves(animation)}[f'key_blocks["{first[2]}"].value']
    stale.keyframe_points.insert(20.0, 1.0)
    return obj, first


def test_in_between_frames_again_after_its_keys_were_deleted_names_them_as_before(bpy_empty, extension):
    """In-between Frames into a mesh, its keys deleted by the user, then run again: the new keys take the
    names of the first run's ("Frame 5", not "Frame 5.001"), each keyframed on the F-curve Blender kept for
    the deleted key of its name, emptied first (no point of the old animation left: the stale keyframe at
    frame 20 would play the new key there), every point linear, and no F-curve more than keys. Before
    (session 78, h3), every such run took new names (.001, .002, …) and left one more dead F-curve per key
    in the action each time."""
    obj, first = _deleted_keys_rerun()
    assert _in_between_frames_keys(obj) == first
    curves = _keyframes(obj.data.shape_keys.animation_data)
    assert sorted(curves) == sorted(f'key_blocks["{name}"].value' for name in first)
    scene = bpy.context.scene
    key_blocks = obj.data.shape_keys.key_blocks
    for path, points in curves.items():
        assert all(interpolation == 'LINEAR' for _, interpolation in points) and \
            all(frame <= 9 for (frame, _), _ in points), (path, points)
    scene.frame_set(20)  # the stale keyframe's frame: the key as after its last keyframe (frame 9), at 0
    assert key_blocks[first[2]].value == 0.0
    scene.frame_set(5)
    assert key_blocks[first[2]].value == 1.0


@pytest.mark.parametrize("still", ['NOISE', 'EXTRAPOLATED'])
def test_a_deleted_keys_f_curve_that_still_plays_without_its_points_keeps_its_name(bpy_empty, extension, still):
    """The mesh of the test above, the deleted "Frame 5" key's F-curve given a Noise modifier (which plays
    without keyframes) or linear extrapolation (which emptied would still extrapolate the new points): run
    again, the key for frame 5 takes "Frame 5.001" (its own F-curve) and that curve keeps its points and
    modifier; the other keys take their first names."""
    obj, first = _deleted_keys_rerun()
    animation = obj.data.shape_keys.animation_data
    path = f'key_blocks["{first[2]}"].value'
    dead = {fcurve.data_path: fcurve for fcurve in _fcurves(animation)}[path]
    if still == 'NOISE':
        dead.modifiers.new('NOISE')
    else:
        dead.extrapolation = 'LINEAR'
    kept = _keyframes(animation)[path]
    again = _in_between_frames_keys(obj)
    assert again == first[:2] + [first[2] + ".001"] + first[3:]
    curve = {fcurve.data_path: fcurve for fcurve in _fcurves(animation)}[path]
    assert _keyframes(animation)[path] == kept and len(curve.modifiers) == (still == 'NOISE')


def test_a_failed_run_gives_a_deleted_keys_f_curve_its_keyframes_back(bpy_empty, extension, core, monkeypatch):
    """The mesh of the test above (a deleted key's F-curve with a keyframe at frame 20): In-between Frames
    runs out of memory once its keys, named as the deleted ones, are keyframed on those F-curves: the
    take-back gives each F-curve the keyframes it had, and removes none."""
    from test_out_of_memory import _out_of_memory as out_of_memory, fails_out_of_memory

    obj, _first = _deleted_keys_rerun()
    kept = _keyframes(obj.data.shape_keys.animation_data)
    monkeypatch.setattr(_module("operators.output"), "zone_frames_dropped", out_of_memory)
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.inbetween_frames, "In-betweens per gap",
                        frame_step=4, count=1, output='SHAPE_KEYS')
    assert _keyframes(obj.data.shape_keys.animation_data) == kept


def test_in_between_frames_into_an_action_another_mesh_plays_through_the_nla_leaves_its_keys(bpy_empty,
                                                                                              extension):
    """Another mesh with keys "Frame 1", "Frame 5" and "Frame 9", not animated, and an animated key
    "Other", plays its action only through an NLA strip; the first strip plays that action (and slot) as its
    own with only a Basis. In-between Frames on it: its new keys take none of the other mesh's names, so
    the other mesh's keys stay unanimated and its "Other" F-curve keeps its keyframes. Before, only meshes
    playing the action as their action were looked at: the new keys took "Frame 1", … and their F-curves
    played the other mesh's keys of those names through its strip."""
    first = armature_scene(frames=9)
    second = first.copy()
    second.data = first.data.copy()
    bpy.context.scene.collection.objects.link(second)
    second.shape_key_add(name="Basis", from_mix=False)
    for name in ("Frame 1", "Frame 5", "Frame 9", "Other"):
        second.shape_key_add(name=name, from_mix=False)
    other = second.data.shape_keys.key_blocks["Other"]
    for frame, value in ((1, 0.0), (9, 1.0)):
        other.value = value
        other.keyframe_insert("value", frame=frame)
    played = second.data.shape_keys.animation_data
    action, slot = played.action, getattr(played, "action_slot", None)
    strip = played.nla_tracks.new().strips.new("Other", 1, action)
    played.action = None
    assert strip.action == action and getattr(strip, "action_slot", None) == slot
    kept = {f.data_path: [tuple(p.co) for p in f.keyframe_points] for f in _fcurves(strip)}
    first.shape_key_add(name="Basis", from_mix=False)
    animation = first.data.shape_keys.animation_data_create()
    animation.action = action
    if slot is not None:
        animation.action_slot = slot
    added = _in_between_frames_keys(first)
    assert len(added) == 5 and not set(added) & set(second.data.shape_keys.key_blocks.keys())
    curves = {f.data_path: [tuple(p.co) for p in f.keyframe_points] for f in _fcurves(strip)}
    assert {path: curves[path] for path in kept} == kept
