"""Memory that runs out past the checks made before any work (another program takes it meanwhile, a
system that does not say how much there is): every operator reports it in the user's terms (what ran
out, what makes the job smaller) and leaves the file as it was, also where it ran out while writing
(shape keys and their keyframes added, a new object and its cache file, distortion maps overwritten,
a shape space drawn): an operator that does not finish pushes no undo step, so half its output
would otherwise stay in the user's file."""

import importlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import _fcurves, armature_scene, posed_grid  # noqa: E402
from dev_extension import MODULE  # noqa: E402
from test_undo import file_state  # noqa: E402


def _module(name: str):
    return importlib.import_module(f"{MODULE}.{name}")


def _out_of_memory(*_args, **_kwargs):
    raise MemoryError("Unable to allocate 1.21 GiB for an array with shape (54000, 3000) and data type float64")


def fails_out_of_memory(bridge, operator, advice: str, said: str = "Unable to allocate 1.21 GiB", **properties):
    """Run ``operator``: it reports running out of memory (``said``: the words of what ran out) with
    ``advice``, not a traceback, and the file is as it was."""
    before = file_state(bridge)
    with pytest.raises(RuntimeError) as failure:
        operator(**properties)
    assert file_state(bridge) == before
    message = str(failure.value)
    assert "Traceback" not in message and "Ran out of memory" in message, "a crash, not a report"
    assert said in message and advice in message and "nothing was changed" in message, message
    assert "close other programs" in message


@pytest.mark.parametrize("output", ['SHAPE_KEYS', 'CACHE'])
def test_memory_running_out_after_the_poses_are_written_takes_them_back(bpy_empty, extension, core, monkeypatch,
                                                                       tmp_path, output):
    """In-between Frames runs out of memory once its keyframed shape keys are added (or its new object
    plays its cache file): the keys, their keyframes and action, the Basis made for them, the object,
    its mesh and the file go again. Before, Blender showed a traceback and the file kept them."""
    output_module = _module("operators.output")
    point = "zone_frames_dropped" if output == 'SHAPE_KEYS' else "object_motion"
    calls = []

    def after_the_write(*args, **kwargs):  # called once the keys are added (the object made)
        calls.append(1)
        _out_of_memory()

    strip = armature_scene(frames=9)
    assert strip.data.shape_keys is None
    monkeypatch.setattr(output_module, point, after_the_write)
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.inbetween_frames,
                        "python -m core retime in parts (--chunk I/N)", frame_step=4, count=1, output=output,
                        filepath=str(tmp_path) + "/")
    assert calls and not list(tmp_path.iterdir())  # it did write; no cache file left
    assert strip.data.shape_keys is None and not bpy.data.actions.get("KeyAction")


def test_memory_running_out_in_the_core_is_reported_in_the_users_terms(bpy_empty, extension, core, monkeypatch):
    """A MemoryError of the core (CHOLMOD's own words) while the in-betweens are made: reported with the
    operator's advice (In-between: lower Count), nothing written."""
    posed_grid(extension.bridge, 6)

    def cholmod(*_args, **_kwargs):
        raise MemoryError("CHOLMOD could not hold the factor of a matrix of 36 unknowns")

    monkeypatch.setattr(core.Interpolator, "pose", cholmod)
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.inbetween, "lower Count",
                        said="CHOLMOD could not hold the factor of a matrix of 36 unknowns", count=2)


def test_memory_running_out_while_distortion_maps_are_written_gives_the_earlier_maps_back(bpy_empty, extension,
                                                                                         core, monkeypatch):
    """Distortion Maps of another key run out of memory half-way through writing its maps over an
    earlier run's: the earlier maps are there as they were (values, active colour attribute), the
    half-written ones gone."""
    obj = posed_grid(extension.bridge, 6)
    bpy.ops.shape_differences.distortion_maps(source='ACTIVE_KEY', key="Curl", k_m=20, eigenfunctions=1)
    analysis_data = _module("bridge.analysis_data")
    write_attribute = analysis_data.write_attribute
    calls = []

    def half_way(*args, **kwargs):
        calls.append(1)
        if len(calls) == 4:
            _out_of_memory()
        return write_attribute(*args, **kwargs)

    monkeypatch.setattr(analysis_data, "write_attribute", half_way)
    before = maps(obj.data)
    active = obj.data.color_attributes.active_color_name
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.distortion_maps, "write fewer Eigenfunctions",
                        source='ACTIVE_KEY', key="Bend", k_m=20, eigenfunctions=2)
    assert len(calls) >= 4  # three of the earlier maps overwritten with Bend's (then the restore's own writes)
    after = maps(obj.data)
    assert after.keys() == before.keys() and all(np.array_equal(after[name], before[name]) for name in before)
    assert obj.data.color_attributes.active_color_name == active


def maps(mesh) -> dict:
    """The values of every attribute of ``mesh`` whose name is a distortion map's."""
    analysis_data = _module("bridge.analysis_data")
    values = {}
    for attribute in mesh.attributes:
        if analysis_data.ANALYSIS_ATTRIBUTE.fullmatch(attribute.name):
            color = attribute.data_type == 'FLOAT_COLOR'
            values[attribute.name] = np.empty(len(attribute.data) * (4 if color else 1), dtype=np.float32)
            attribute.data.foreach_get("color" if color else "value", values[attribute.name])
    return values


def test_memory_running_out_once_a_shape_space_is_drawn_takes_it_back(bpy_empty, extension, core, monkeypatch):
    """Shape Space runs out of memory once its image is drawn and its coordinates stored: the image
    goes and no shape space is stored."""
    posed_grid(extension.bridge, 6)
    monkeypatch.setattr(_module("operators.analysis"), "show_image", _out_of_memory)
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.shape_space, "lower k_M and k_N",
                        source='KEYS', k_m=20, k_n=0)
    assert not bpy.data.images


def test_memory_running_out_while_select_pose_draws_leaves_the_selection_and_image(bpy_empty, extension, core,
                                                                                    monkeypatch):
    """Select Pose runs out of memory once it has drawn the new selection into the image: the image
    shows the stored selection again (its pixels as before), the selection and active key stay."""
    posed_grid(extension.bridge, 6)
    bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=0)
    bpy.ops.shape_differences.shape_space_select(kind='offset_area', rank=0)
    analysis = _module("operators.analysis")
    drawn_from, calls = analysis.drawn_from, []

    def once(*args, **kwargs):  # after the image's pixels are written
        calls.append(1)
        if len(calls) == 1:
            _out_of_memory()
        return drawn_from(*args, **kwargs)

    monkeypatch.setattr(analysis, "drawn_from", once)
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.shape_space_select, "restart Blender",
                        kind='offset_area', rank=2)
    assert calls


def test_memory_running_out_after_keys_are_added_beside_keyframed_ones_leaves_their_action_as_it_was(
        bpy_empty, extension, core, monkeypatch):
    """A second In-between Frames into shape keys already keyframed (their action there before) runs
    out of memory once its keys are added: its keys and their F-curves go, the action and the first
    run's keys and F-curves stay."""
    strip = armature_scene(frames=9)
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='SHAPE_KEYS')
    action = strip.data.shape_keys.animation_data.action
    curves = sorted(fcurve.data_path for fcurve in _fcurves(strip.data.shape_keys.animation_data))
    monkeypatch.setattr(_module("operators.output"), "zone_frames_dropped", _out_of_memory)
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.inbetween_frames, "In-betweens per gap",
                        frame_step=4, count=2, output='SHAPE_KEYS')
    assert strip.data.shape_keys.animation_data.action == action
    assert sorted(fcurve.data_path for fcurve in _fcurves(strip.data.shape_keys.animation_data)) == curves


def _keyframes(animation_data) -> dict:
    """Every F-curve of ``animation_data``'s action (its slot's) by data path: its keyframes' frames and values."""
    return {fcurve.data_path: [(tuple(point.co), point.interpolation) for point in fcurve.keyframe_points]
            for fcurve in _fcurves(animation_data)}


def test_memory_running_out_leaves_an_action_shared_with_another_mesh_as_it_was(bpy_empty, extension, core,
                                                                                monkeypatch):
    """An action shared by two meshes' shape keys: the second strip's keys are keyframed, the first
    strip plays the same action (and slot) and has only a Basis. In-between Frames on the first strip
    runs out of memory once its keys are keyframed: the second strip's F-curves keep their keyframes
    (session 77: the new keys took the second strip's names and keyframes into its F-curves, and the
    take-back deleted them; since session 78 the new keys take names no F-curve there animates)."""
    first = armature_scene(frames=9)
    second = first.copy()
    second.data = first.data.copy()
    bpy.context.scene.collection.objects.link(second)
    bpy.context.view_layer.objects.active = second
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == second)
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=1, output='SHAPE_KEYS')
    shared = second.data.shape_keys.animation_data
    kept = _keyframes(shared)
    assert kept
    first.shape_key_add(name="Basis", from_mix=False)
    animation = first.data.shape_keys.animation_data_create()
    animation.action = shared.action
    if hasattr(animation, "action_slot"):
        animation.action_slot = shared.action_slot
    bpy.context.view_layer.objects.active = first
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == first)
    monkeypatch.setattr(_module("operators.output"), "zone_frames_dropped", _out_of_memory)
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.inbetween_frames, "In-betweens per gap",
                        frame_step=4, count=1, output='SHAPE_KEYS')
    assert second.data.shape_keys.animation_data.action == shared.action
    assert _keyframes(second.data.shape_keys.animation_data) == kept


@pytest.mark.parametrize("active", [0, 1, 2])
def test_memory_running_out_after_in_betweens_are_added_keeps_the_active_key(bpy_empty, extension, core, monkeypatch,
                                                                             active):
    """In-between runs out of memory once its keys are added to a mesh whose active key is the
    Basis, "Curl" or "Bend": the keys go and the same key is active (removing a key in Blender moves the
    active index down)."""
    obj = posed_grid(extension.bridge, 6)
    obj.active_shape_key_index = active
    monkeypatch.setattr(_module("operators.output"), "zone_frames_dropped", _out_of_memory)
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.inbetween, "lower Count", count=2)
    assert obj.active_shape_key_index == active


def test_memory_running_out_once_a_shape_space_is_drawn_gives_another_objects_image_back(bpy_empty, extension, core,
                                                                                        monkeypatch):
    """The image a new shape space is drawn into is named after the object ("Shape Space Grid"): where
    another object's image has that name (the grid it was made on was renamed "Sheet" since, then a new
    "Grid" made), Shape Space on the new grid running out of memory leaves that image's pixels as they
    were. In session 77 the run drew into it and the take-back gave its pixels back (before that, the
    renamed sheet's image kept the failed run's plot); since session 78 the run draws into an image of
    its own ("Shape Space Grid.001"), which the take-back removes."""
    first = posed_grid(extension.bridge, 6)
    first.name = "Grid"
    bpy.ops.shape_differences.shape_space(source='KEYS', k_m=20, k_n=0)
    first.name = "Sheet"
    second = posed_grid(extension.bridge, 5)
    second.name = "Grid"
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == second)
    bpy.context.view_layer.objects.active = second
    assert bpy.data.images.get("Shape Space Grid") is not None
    monkeypatch.setattr(_module("operators.analysis"), "show_image", _out_of_memory)
    fails_out_of_memory(extension.bridge, bpy.ops.shape_differences.shape_space, "lower k_M and k_N",
                        source='KEYS', k_m=20, k_n=0)
