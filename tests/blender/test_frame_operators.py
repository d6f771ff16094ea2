"""Frames to shape keys and in-between frames on a baked cloth simulation and an armature
animation: one key per frame with the evaluated mesh, in-betweens as core computes them, key
values keyframed, and the original animation, modifiers and current frame left alone."""

import importlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scenes import (add_key, armature_scene, cloth_scene, evaluated_frames, grid_object,  # noqa: E402
                            dynamic_paint_wave_scene, key_names, sheet_easing_off_scale_keyframed, simulation_zone_scene,
                            snapshot,
                            turning_sheet_scale_keyframed,
                            turning_sheet_stretched_before_its_frames)

TOLERANCE = 1e-4


def positions_of(bridge, obj, name):
    return bridge.mesh_data.stored_key_positions(obj.data.shape_keys.key_blocks[name])


def assert_animation_untouched(before, after):
    for field in ("modifiers", "object_animation", "frame", "positions"):
        np.testing.assert_equal(after[field], before[field])


@pytest.mark.parametrize("make_scene", [cloth_scene, armature_scene], ids=["cloth", "armature"])
def test_frames_to_shape_keys(bpy_empty, extension, make_scene):
    obj = make_scene()
    bridge = extension.bridge
    bpy.context.scene.frame_set(2)
    before = snapshot(bridge, obj)
    expected = evaluated_frames(bridge, obj, range(1, 10))
    bpy.ops.shape_differences.frames_to_shape_keys(frame_start=1, frame_end=9, frame_step=4)
    assert key_names(obj) == ["Basis", "Frame 1", "Frame 5", "Frame 9"]
    for frame in (1, 5, 9):
        np.testing.assert_allclose(positions_of(bridge, obj, f"Frame {frame}"), expected[frame],
                                   atol=TOLERANCE)
    assert not np.allclose(expected[1], expected[9], atol=0.05), "the scene should move"
    assert_animation_untouched(before, snapshot(bridge, obj))


def test_frame_range_defaults_to_the_scene(bpy_empty, extension):
    obj = armature_scene(frames=5)
    bpy.ops.shape_differences.frames_to_shape_keys()
    assert key_names(obj)[1:] == [f"Frame {frame}" for frame in range(1, 6)]


def test_frame_range_defaults_to_the_preview_range_where_it_is_on(bpy_empty, extension, tmp_path):
    """With the timeline's preview range on, playback (and Blender's Bake Action) covers it, and
    so do the operators (before, they read the whole scene range); the Redo panel shows it."""
    obj = armature_scene(frames=9)
    scene = bpy.context.scene
    scene.use_preview_range = True
    scene.frame_preview_start, scene.frame_preview_end = 3, 7
    bpy.ops.shape_differences.frames_to_shape_keys()
    assert key_names(obj)[1:] == [f"Frame {frame}" for frame in range(3, 8)]
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween(key_a="Frame 3", key_b="Frame 7", count=1, output='CACHE',
                                        filepath=str(tmp_path) + "/")
    [copy] = [o for o in bpy.data.objects if o.name not in names]
    assert copy.modifiers["Mesh Cache"].frame_start == 3  # key A at the preview range's start
    scene.use_preview_range = False
    bpy.ops.shape_differences.frames_to_shape_keys(frame_step=4)
    assert key_names(obj)[6:] == ["Frame 1", "Frame 5.001", "Frame 9"]  # the scene range again


@pytest.mark.parametrize("make_scene", [cloth_scene, armature_scene], ids=["cloth", "armature"])
def test_inbetween_frames(bpy_empty, extension, core, make_scene):
    obj = make_scene()
    bridge = extension.bridge
    before = snapshot(bridge, obj)
    frames = [1, 5, 9]
    # 3: how the motion leaves the first key; 7: how it reaches the last one
    poses = evaluated_frames(bridge, obj, [1, 3, 5, 7, 9])
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=3,
                                               output='SHAPE_KEYS')

    factors = (0.25, 0.5, 0.75)
    expected_names = ["Basis"]
    for frame, next_frame in zip(frames, frames[1:]):
        expected_names.append(f"Frame {frame}")
        expected_names += [f"Inbetween Frame {frame}-Frame {next_frame} {f:.2f}" for f in factors]
    expected_names.append("Frame 9")
    assert key_names(obj) == expected_names

    motion_ends = importlib.import_module(core.__name__ + ".motion_ends")
    start = motion_ends.start_of_motion([poses[1], poses[5], poses[9]], poses[3], 0.5)
    end = motion_ends.end_of_motion([poses[1], poses[5], poses[9]], poses[7], 0.5)
    sequence = core.SequenceInterpolator([poses[f] for f in frames],
                                         bridge.triangulation.mesh_triangles(obj.data), start=start, end=end)
    for gap, (frame, next_frame) in enumerate(zip(frames, frames[1:])):
        np.testing.assert_allclose(positions_of(bridge, obj, f"Frame {frame}"), poses[frame],
                                   atol=TOLERANCE)
        expected = sequence.poses(gap, factors)  # a gap's in-betweens together, as the operator asks
        for factor, pose in zip(factors, expected):
            name = f"Inbetween Frame {frame}-Frame {next_frame} {factor:.2f}"
            np.testing.assert_allclose(positions_of(bridge, obj, name), pose, atol=TOLERANCE)

    # Key values: 1 at the key's own frame, 0 at every other sample frame.
    key = obj.data.shape_keys
    for index, name in enumerate(expected_names[1:]):
        fcurve = bridge.shape_keys.shape_key_value_fcurve(key, name)
        for other in range(1, 10):
            assert fcurve.evaluate(other) == pytest.approx(1.0 if other == 1 + index else 0.0)
        assert all(point.interpolation == 'LINEAR' for point in fcurve.keyframe_points)
    assert_animation_untouched(before, snapshot(bridge, obj))


def test_the_benchmarks_op_protocol_builds_the_sequence_the_operator_builds(bpy_empty, extension, core):
    """The in-between benchmark's ``op`` protocol (benchmarks/bench_inbetween.py,
    ``operator_options``) gives the sequence the ends and key times *In-between Frames* gives it,
    so its row is what an artist gets from those keys."""
    from benchmarks.bench_inbetween import operator_options
    obj = armature_scene(frames=13)
    bridge = extension.bridge
    frames = [1, 5, 9, 13]
    poses = evaluated_frames(bridge, obj, range(1, 14))
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=13, frame_step=4, count=3,
                                               output='SHAPE_KEYS')
    options = operator_options(poses, frames)
    sequence = core.SequenceInterpolator([poses[f] for f in frames],
                                         bridge.triangulation.mesh_triangles(obj.data), **options)
    factors = (0.25, 0.5, 0.75)
    for gap, (frame, next_frame) in enumerate(zip(frames, frames[1:])):
        for factor, pose in zip(factors, sequence.poses(gap, factors)):
            name = f"Inbetween Frame {frame}-Frame {next_frame} {factor:.2f}"
            np.testing.assert_allclose(positions_of(bridge, obj, name), pose, atol=TOLERANCE)


@pytest.mark.parametrize("operator", ["inbetween_frames", "retime"])
def test_keyframed_shape_keys_on_absolute_keys_are_refused(bpy_empty, extension, operator):
    """Absolute shape keys play by the Key's Evaluation Time, never by the values In-between
    Frames and Retime keyframe: the new keys would never play (before, they were added and
    reported as keyframed while playback showed no change). Refused, nothing changed; a point
    cache plays."""
    from blender_scenes import add_key, grid_object, rolled
    bridge = extension.bridge
    obj = grid_object(6)
    rest = bridge.mesh_data.vertex_positions(obj.data)
    add_key(obj, "A", rolled(rest, 1.0)), add_key(obj, "B", rolled(rest, 2.0))
    key = obj.data.shape_keys
    key.use_relative = False
    key.eval_time = 10.0
    key.keyframe_insert("eval_time", frame=1)
    key.eval_time = 20.0
    key.keyframe_insert("eval_time", frame=9)
    before = snapshot(bridge, obj)
    options = dict(frame_start=1, frame_end=9, frame_step=4)
    run = getattr(bpy.ops.shape_differences, operator)
    with pytest.raises(RuntimeError, match="absolute .*Evaluation Time"):
        run(**options, output='SHAPE_KEYS')
    assert key_names(obj) == ["Basis", "A", "B"]
    assert_animation_untouched(before, snapshot(bridge, obj))
    names = set(bpy.data.objects.keys())
    run(**options, output='CACHE', filepath=bpy.app.tempdir)
    assert len(set(bpy.data.objects.keys()) - names) == 1


def test_inbetween_frames_covers_a_range_that_is_not_whole_steps(bpy_empty, extension, core):
    """Frames 1–11 every 4th: keys 1, 5, 9 and the last frame 11; the short gap 9 → 11 has
    in-betweens as many frames apart as the others (one per frame with 3 per gap of 4), from its
    own sequence on frames 7, 9, 11 (core.retime.short_gap_keys)."""
    obj = armature_scene(frames=11)
    bridge = extension.bridge
    poses = evaluated_frames(bridge, obj, range(1, 12))
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=11, frame_step=4, count=3,
                                               output='SHAPE_KEYS')
    names = key_names(obj)
    assert names[-3:] == ["Frame 9", "Inbetween Frame 9-Frame 11 0.50", "Frame 11"]
    assert len(names) == 1 + 2 * 4 + 3  # Basis, two whole gaps (key + 3), Frame 9, one in-between, Frame 11
    np.testing.assert_allclose(positions_of(bridge, obj, "Frame 11"), poses[11], atol=TOLERANCE)
    retime = importlib.import_module(core.__name__ + ".retime")
    tail = (1 + retime.short_gap_keys(8, 10)).tolist()
    assert tail == [5, 7, 9, 11]
    # how the motion reaches the last frame: told by frame 10, in the middle of the short gap
    assert retime.end_samples([1, 5, 9, 11], tail) == (7, 9, 11, 10)
    motion_ends = importlib.import_module(core.__name__ + ".motion_ends")
    end = motion_ends.end_of_motion([poses[7], poses[9], poses[11]], poses[10], 0.5, (2, 2))
    short = core.SequenceInterpolator([poses[f] for f in tail],
                                      bridge.triangulation.mesh_triangles(obj.data), start="keys",
                                      end=end)
    np.testing.assert_allclose(positions_of(bridge, obj, "Inbetween Frame 9-Frame 11 0.50"),
                               short.pose(len(short) - 1, 0.5), atol=TOLERANCE)
    fcurve = bridge.shape_keys.shape_key_value_fcurve(obj.data.shape_keys, "Inbetween Frame 9-Frame 11 0.50")
    assert fcurve.evaluate(10) == pytest.approx(1.0) and fcurve.evaluate(11) == pytest.approx(0.0)
    # the whole gaps: the sequence of the keys and the last frame, at their frames
    start = motion_ends.start_of_motion([poses[1], poses[5], poses[9]], poses[3], 0.5)
    sequence = core.SequenceInterpolator([poses[f] for f in (1, 5, 9, 11)],
                                         bridge.triangulation.mesh_triangles(obj.data),
                                         start=start, key_times=[1, 5, 9, 11], end=end)
    np.testing.assert_allclose(positions_of(bridge, obj, "Inbetween Frame 5-Frame 9 0.50"),
                               sequence.poses(1, [0.25, 0.5, 0.75])[1], atol=TOLERANCE)


def test_inbetween_frames_begin_no_gap_ahead_that_they_do_not_ask_for(bpy_empty, extension, core, monkeypatch):
    """Frames 1–15 every 4th: keys 1, 5, 9, 13 and the last frame 15, whose short gap 13 → 15 is
    keyed by a sequence of its own. The whole gaps are asked in order at one set of factors, so the
    sequence may begin the next one in the pool while a gap ends (core.sequence_gaps_ahead), but
    never the short gap, which it is not asked for (its work would run to waste after the operator
    is done)."""
    begun = []  # the gap each call may begin ahead (whether its path reaches a batch of predictions or not)
    original = core.SequenceInterpolator._beginning_ahead

    def counted(self, gap, factors):
        begun.append(gap + 1)
        return original(self, gap, factors)

    monkeypatch.setattr(core.SequenceInterpolator, "_beginning_ahead", counted)
    obj = armature_scene(frames=15)
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=15, frame_step=4, count=3,
                                               output='SHAPE_KEYS')
    assert key_names(obj)[-3:] == ["Frame 13", "Inbetween Frame 13-Frame 15 0.50", "Frame 15"]
    assert begun and max(begun) <= 2  # the whole gaps 0–2 of the keys 1, 5, 9, 13, 15


def test_inbetween_frames_inside_a_simulation_measures_edges_from_its_first_frame(bpy_empty, extension, core,
                                                                                  monkeypatch):
    """Frames 5–13 every 3rd of a cloth simulated from frame 1: the sequences (the whole gaps', the
    short last gap's) measure the edges their warnings hold the in-betweens to from frame 1, where the
    cloth is at its rest, not from frame 5, where it is already falling (core.SequenceInterpolator's
    ``rest_pose``); the in-betweens are those of the same keys without it. From frame 1 the first key is
    that rest, and it is given as such (before, none: test_operators_from_a_simulations_first_frame_give_it_as_the_rest)."""
    obj = cloth_scene(frames=13)
    bridge = extension.bridge
    poses = evaluated_frames(bridge, obj, [1, 5, 8, 11, 13])
    given, original = [], core.SequenceInterpolator
    retime = importlib.import_module(core.__name__ + ".retime")
    short_gap_sequence = retime.short_gap_sequence

    def recording(*args, **kwargs):
        given.append(kwargs.get("rest_pose"))
        return original(*args, **kwargs)

    def recording_tail(*args, **kwargs):
        given.append(kwargs.get("rest_pose"))
        return short_gap_sequence(*args, **kwargs)

    monkeypatch.setattr(core, "SequenceInterpolator", recording)
    monkeypatch.setattr(retime, "short_gap_sequence", recording_tail)
    bpy.ops.shape_differences.inbetween_frames(frame_start=5, frame_end=13, frame_step=3, count=2,
                                               output='SHAPE_KEYS')
    assert len(given) == 2  # the whole gaps' sequence and the short last gap's
    for rest in given:
        assert rest is not None  # measured from the first key, frame 5
        np.testing.assert_allclose(rest, poses[1], atol=TOLERANCE)
    assert not np.allclose(poses[5], poses[1], atol=1e-2)  # frame 5 is no rest
    triangles = bridge.triangulation.mesh_triangles(obj.data)
    plain = original([poses[f] for f in (5, 8, 11, 13)], triangles, key_times=[5, 8, 11, 13], start="keys")
    with_rest = original([poses[f] for f in (5, 8, 11, 13)], triangles, key_times=[5, 8, 11, 13], start="keys",
                         rest_pose=poses[1])
    np.testing.assert_array_equal(with_rest.poses(0, [1 / 3, 2 / 3]), plain.poses(0, [1 / 3, 2 / 3]))
    bpy.ops.wm.read_homefile(use_empty=True)
    cloth_scene(frames=13)
    given.clear()
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=10, frame_step=3, count=2,
                                               output='SHAPE_KEYS')
    assert len(given) == 1 and given[0] is not None
    np.testing.assert_allclose(given[0], poses[1], atol=TOLERANCE)


def _rests_given_to_every_sequence(core, monkeypatch) -> list:
    """The list that gets the ``rest_pose`` of every sequence made from then on, by the operators
    (``core.SequenceInterpolator``) and the retime (:mod:`core.sequence_inbetweens`'s)."""
    sequences = importlib.import_module(core.__name__ + ".sequence_inbetweens")
    given, original = [], sequences.SequenceInterpolator

    def recording(*args, **kwargs):
        given.append(kwargs.get("rest_pose"))
        return original(*args, **kwargs)

    monkeypatch.setattr(sequences, "SequenceInterpolator", recording)
    monkeypatch.setattr(core, "SequenceInterpolator", recording)
    return given


def _rebaked(obj, shrink: float) -> None:
    """``obj``'s cloth baked again with Blender's Shrinking at ``shrink``."""
    scene = bpy.context.scene
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.free_bake_all()
    obj.modifiers["Cloth"].settings.shrink_min = shrink
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    scene.frame_set(1)


def test_a_retime_inside_a_simulation_measures_edges_from_its_first_frame(bpy_empty, extension, core, monkeypatch):
    """Retime at half speed of frames 5–13 every 3rd of a cloth simulated from frame 1: every sequence
    it makes (the whole gaps', the short last gap's) measures the edges its warnings hold the
    in-betweens to from frame 1, where the cloth is at its rest, as In-between Frames does (before, from
    frame 5, where it is already falling: no ``rest_pose`` given); the retimed frames are those of the
    same keys without it. From frame 1 the first key is that rest, and it is given as such (before, none:
    test_operators_from_a_simulations_first_frame_give_it_as_the_rest)."""
    obj = cloth_scene(frames=13)
    bridge = extension.bridge
    frames_module = importlib.import_module(extension.__name__ + ".operators.frames")
    rest = evaluated_frames(bridge, obj, [1])[1]
    given = _rests_given_to_every_sequence(core, monkeypatch)
    runs = []
    for _ in range(2):  # as it runs, then with no simulation's first frame read
        bpy.ops.shape_differences.retime(frame_start=5, frame_end=13, frame_step=3, speed=0.5, output='SHAPE_KEYS')
        names = key_names(obj)[1:]
        runs.append((names, [positions_of(bridge, obj, name) for name in names]))
        obj.shape_key_clear()
        if not runs[1:]:
            assert len(given) == 2  # the whole gaps' sequence and the short last gap's
            for pose in given:
                assert pose is not None  # measured from the first key, frame 5
                np.testing.assert_allclose(pose, rest, atol=TOLERANCE)
            monkeypatch.setattr(frames_module, "simulation_first_frame", lambda *_: [])
    # the short gap's sequence is measured from frame 5 (core.retime.short_gap_sequence)
    assert len(given) == 4 and given[2] is None
    (names, with_rest), (names_without, without) = runs
    assert names_without == names and len(names) == 17
    for pose, pose_without in zip(with_rest, without):
        np.testing.assert_array_equal(pose, pose_without)
    monkeypatch.undo()
    bpy.ops.wm.read_homefile(use_empty=True)
    cloth_scene(frames=13)
    given = _rests_given_to_every_sequence(core, monkeypatch)
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=10, frame_step=3, speed=0.5, output='SHAPE_KEYS')
    assert len(given) == 1 and given[0] is not None
    np.testing.assert_allclose(given[0], rest, atol=TOLERANCE)


@pytest.mark.parametrize("operator", ["inbetween_frames", "retime"])
def test_operators_from_a_simulations_first_frame_give_it_as_the_rest(bpy_empty, extension, core, monkeypatch,
                                                                      operator):
    """In-between Frames and Retime of frames 1–10 every 3rd of a cloth simulated from frame 1, how its
    motion leaves the first key read as keys cut from a motion (``core.retime.motion_ends`` choosing
    ``start="keys"``, as it does for some bakes from their first frame: a trampoline a ball lands on keyed
    every 8th or 16th frame): the sequence is given its first key, the simulation's rest, as its
    ``rest_pose``, exactly, so it reads its keys' deviations as from a rest (a key the cloth bounces back
    from is warned of only so, core.sequence_caught_stretch) and they are those from the first key
    (the first key's 0). Before, none was given, and with ``start="keys"`` the sequence took its first key
    for a deformed one, cut from a motion."""
    obj = cloth_scene(frames=13)
    sequences = importlib.import_module(core.__name__ + ".sequence_inbetweens")
    retime = importlib.import_module(core.__name__ + ".retime")
    made, original = [], sequences.SequenceInterpolator

    def recording(*args, **kwargs):
        sequence = original(*args, **kwargs)
        made.append((sequence, np.array(args[0][0]), kwargs.get("rest_pose")))
        return sequence

    monkeypatch.setattr(sequences, "SequenceInterpolator", recording)
    monkeypatch.setattr(core, "SequenceInterpolator", recording)
    monkeypatch.setattr(retime, "motion_ends", lambda *args, **kwargs: {"start": "keys"})
    run = getattr(bpy.ops.shape_differences, operator)
    run(frame_start=1, frame_end=10, frame_step=3, output='SHAPE_KEYS',
        **({"count": 2} if operator == "inbetween_frames" else {"speed": 0.5}))
    assert len(made) == 1
    sequence, first, rest = made[0]
    assert sequence.start == "keys"
    assert rest is not None, "no rest given from the simulation's first frame"
    np.testing.assert_array_equal(rest, first)
    assert sequence._from_rest and sequence._key_deviation(0) == 0.0


def _median_edge_ratio(a, b, triangles) -> float:
    """The median ratio of the corner edges of ``a`` (n, 3) to those of ``b`` (n, 3) over ``triangles``."""
    lengths = [np.linalg.norm(x[triangles[:, [1, 2, 0]]] - x[triangles], axis=2) for x in (a, b)]
    return float(np.median(lengths[0] / lengths[1]))


def _rests_of_a_shrinking_cloth(bridge, obj, core, monkeypatch, start: int, shrink: float) -> list:
    """The rests In-between Frames and Retime of frames ``start``–13 every 4th of ``obj``, a cloth baked
    with Shrinking ``shrink``, give the sequences they make (the list, from then on), each checked: one
    per operator, its edges 1 − ``shrink`` times frame 1's (the springs' rest lengths) and within 1 % of
    frame 5's (the cloth keeps them)."""
    frames = evaluated_frames(bridge, obj, [1, 5])
    triangles = bridge.triangulation.mesh_triangles(obj.data)
    given = _rests_given_to_every_sequence(core, monkeypatch)
    bpy.ops.shape_differences.inbetween_frames(frame_start=start, frame_end=13, frame_step=4, count=1,
                                               output='SHAPE_KEYS')
    obj.shape_key_clear()
    bpy.ops.shape_differences.retime(frame_start=start, frame_end=13, frame_step=4, speed=0.5, output='SHAPE_KEYS')
    assert len(given) == 2 and all(rest is not None for rest in given)
    for rest in given:
        assert _median_edge_ratio(rest, frames[1], triangles) == pytest.approx(1.0 - shrink, rel=1e-6)
        assert _median_edge_ratio(rest, frames[5], triangles) == pytest.approx(1.0, abs=1e-2)
    return given


@pytest.mark.parametrize("shrink", [0.7, 0.1, -0.2])
def test_operators_inside_a_shrinking_simulation_measure_edges_from_its_rest_lengths(bpy_empty, extension, core,
                                                                                     monkeypatch, shrink):
    """The cloth of :func:`cloth_scene` with Blender's Shrinking: its springs' rest lengths are 1 − shrink
    times frame 1's edges, and from frame 2 on its edges keep them (frame 1 reads 3.33 ×, 1.11 ×, 0.83 ×
    frames 5–13). In-between Frames and Retime of 5–13 measure the warnings from those rest lengths:
    the rest given is frame 1 scaled by 1 − shrink, within 1 % of the keys' edges. Before: at 0.7 no
    rest (frame 1 past the core's limit, the first key stood for it), at 0.1 and −0.2 frame 1 as it
    is, every key 11 % / 17 % off it, which the warnings then allowed as misfit. The same cloth with a
    Shrinking vertex group (the factor differs over the mesh) is given no rest."""
    obj = cloth_scene(frames=13)
    _rebaked(obj, shrink)
    given = _rests_of_a_shrinking_cloth(extension.bridge, obj, core, monkeypatch, 5, shrink)
    obj.shape_key_clear()
    group = obj.vertex_groups.new(name="Shrink")
    group.add(list(range(len(obj.data.vertices) // 2)), 1.0, 'REPLACE')
    settings = obj.modifiers["Cloth"].settings
    settings.vertex_group_shrink, settings.shrink_max = group.name, shrink + 0.2  # weight 1 shrinks 0.2 more
    _rebaked(obj, shrink)
    given.clear()
    bpy.ops.shape_differences.retime(frame_start=5, frame_end=13, frame_step=4, speed=0.5, output='SHAPE_KEYS')
    assert len(given) == 1 and given[0] is None


def _cloth_with_rest_key(before: str | None, gravity: float):
    """The cloth of :func:`cloth_scene` with a Rest Shape Key 1.05 × its Basis (value 0: the mesh shows
    the Basis), ``before`` (a modifier type put before the cloth: 'WELD', which makes a new mesh of the same
    vertices (none is as near another as its merge distance); 'UV_PROJECT', which moves nothing and makes
    no vertices but is not of Blender's deform-only kind; 'SURFACE' (what a force field of shape Surface
    adds), which moves nothing and is of that kind; or 'DYNAMIC': Dynamic Mesh on) and the scene's
    gravity ``gravity`` along z, baked again."""
    obj = cloth_scene(frames=13)
    scene = bpy.context.scene
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.free_bake_all()
    basis = np.array([vertex.co[:] for vertex in obj.data.vertices])
    key = add_key(obj, "Rest", 1.05 * basis)
    key.value = 0.0
    settings = obj.modifiers["Cloth"].settings
    settings.rest_shape_key = key
    if before not in (None, 'DYNAMIC'):
        obj.modifiers.new(before, before)
        obj.modifiers.move(len(obj.modifiers) - 1, 0)
    settings.use_dynamic_mesh = before == 'DYNAMIC'
    scene.gravity = (0.0, 0.0, gravity)
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    scene.frame_set(1)
    return obj


@pytest.mark.parametrize("before", [None, 'WELD', 'DYNAMIC', 'SURFACE', 'UV_PROJECT'])
def test_a_cloths_rest_shape_key_counts_only_behind_a_modifier_not_of_blenders_deform_only_kind(
        bpy_empty, extension, core, monkeypatch, before):
    """A cloth with a Rest Shape Key 1.05 × its Basis, baked without gravity: with nothing before the cloth,
    or a Surface (a force field's modifier, of Blender's deform-only kind), Blender reads no such key (its
    cloth modifier copies the key only where it is given no mesh, which a deform-only stack never does) and the
    cloth keeps frame 1's edges (its rest); behind a Weld (a modifier that makes a new mesh, here of the
    same vertices) or a UV Project (one that moves nothing but is not of that kind) it reads the key and
    grows to 1.05 × them. These first assertions pin Blender 5.0's behaviour: a Blender that changes it
    fails them. In-between Frames 5–13 of the same cloth falling measures the warnings from frame 1 in the
    first cases, from no rest (the first key stands for it) behind the Weld and the UV Project and with
    Dynamic Mesh (the springs follow the mesh at every frame). Before session 77, frame 1 was given in every
    case; before the Surface joined ``modifier_kinds.DEFORM_ONLY_MODIFIERS`` (review r1), none behind it."""
    bridge = extension.bridge
    if before != 'DYNAMIC':
        obj = _cloth_with_rest_key(before, 0.0)
        frames = evaluated_frames(bridge, obj, [1, 13])
        triangles = bridge.triangulation.mesh_triangles(obj.data)
        read = before in ('WELD', 'UV_PROJECT')
        assert _median_edge_ratio(frames[13], frames[1], triangles) == pytest.approx(1.05 if read else 1.0, abs=2e-3)
        bpy.ops.wm.read_homefile(use_empty=True)
    obj = _cloth_with_rest_key(before, -9.81)
    first = evaluated_frames(bridge, obj, [1])[1]
    given = _rests_given_to_every_sequence(core, monkeypatch)
    bpy.ops.shape_differences.inbetween_frames(frame_start=5, frame_end=13, frame_step=4, count=1,
                                               output='CACHE')
    assert len(given) == 1
    if before in (None, 'SURFACE'):
        assert given[0] is not None, "no rest given where Blender builds the springs from frame 1"
        np.testing.assert_allclose(given[0], first, atol=TOLERANCE)
    else:
        assert given[0] is None


def test_operators_from_a_shrinking_simulations_first_frame_measure_edges_from_its_rest_lengths(
        bpy_empty, extension, core, monkeypatch):
    """The cloth of :func:`cloth_scene` with Shrinking 0.1, In-between Frames and Retime of 1–13, from the
    simulation's first frame: the first key is the mesh the cloth starts from, its springs 0.9 × its
    edges, and the warnings measure from those (the rest given: frame 1 scaled by 0.9, within 1 % of the
    later keys' edges; before, none: the first key stood for the rest, every later key 11 % off it)."""
    obj = cloth_scene(frames=13)
    _rebaked(obj, 0.1)
    _rests_of_a_shrinking_cloth(extension.bridge, obj, core, monkeypatch, 1, 0.1)


@pytest.mark.parametrize("start", [1, 2])
def test_operators_from_before_a_shrinking_simulations_start_measure_edges_from_its_rest_lengths(
        bpy_empty, extension, core, monkeypatch, start):
    """The cloth of :func:`cloth_scene` simulated from frame 5 with Shrinking 0.1, In-between Frames and
    Retime of ``start``–13 every 4th: a range that starts before the simulation. Blender itself (first
    assertions, pinning Blender 5.0's behaviour): frames 1–5 are all the mesh the cloth is given, and from
    frame 5 on its springs are 0.9 × those edges (frame 13's within 1 % of that). The rest given is frame 5
    scaled by 0.9: read as a key of 1–13, read and set aside for 2–14 (the keys 2, 6, 10 and 14). Before, none:
    the first key stood for the rest, every later key 11 % off it, which the warnings then allowed."""
    obj = cloth_scene(frames=17)
    obj.modifiers["Cloth"].point_cache.frame_start = 5
    _rebaked(obj, 0.1)
    bridge = extension.bridge
    frames = evaluated_frames(bridge, obj, [1, 3, 5, 13])
    triangles = bridge.triangulation.mesh_triangles(obj.data)
    for frame in (1, 3):  # held at the input before the simulation's start
        np.testing.assert_array_equal(frames[frame], frames[5])
    assert _median_edge_ratio(frames[13], frames[5], triangles) == pytest.approx(0.9, abs=1e-2)
    given = _rests_given_to_every_sequence(core, monkeypatch)
    end = start + 12
    bpy.ops.shape_differences.inbetween_frames(frame_start=start, frame_end=end, frame_step=4, count=1,
                                               output='SHAPE_KEYS')
    obj.shape_key_clear()
    bpy.ops.shape_differences.retime(frame_start=start, frame_end=end, frame_step=4, speed=0.5, output='SHAPE_KEYS')
    assert len(given) == 2 and all(rest is not None for rest in given), "no rest given"
    for rest in given:
        assert _median_edge_ratio(rest, frames[5], triangles) == pytest.approx(0.9, rel=1e-6)
        assert _median_edge_ratio(rest, frames[13], triangles) == pytest.approx(1.0, abs=1e-2)


@pytest.mark.parametrize("end", [4, 5])
def test_operators_ending_at_or_before_a_shrinking_simulations_start_give_no_rest(bpy_empty, extension, core,
                                                                                  monkeypatch, end):
    """The cloth of :func:`cloth_scene` simulated from frame 5 with Shrinking 0.1, In-between Frames and
    Retime of 1–``end`` (keys 1 and ``end``): nothing in the range is simulated (frame 5 is the
    mesh the cloth is given, as frames 1–4 are: first assertion), so every key is at the input's edges and
    no rest is given (the first key stands for it). Before, a range ending at frame 5 was given frame 5
    × 0.9 as the rest, which every key is 11 % off, and the warnings allowed that much more misfit."""
    obj = cloth_scene(frames=17)
    obj.modifiers["Cloth"].point_cache.frame_start = 5
    _rebaked(obj, 0.1)
    frames = evaluated_frames(extension.bridge, obj, [1, end])
    np.testing.assert_array_equal(frames[end], frames[1])
    given = _rests_given_to_every_sequence(core, monkeypatch)
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=end, frame_step=end - 1, count=1,
                                               output='SHAPE_KEYS')
    obj.shape_key_clear()
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=end, frame_step=end - 1, speed=0.5,
                                     output='SHAPE_KEYS')
    assert [rest is None for rest in given] == [True, True], "a rest given"


def _cloth_scaled_before(first_scale):
    """The cloth of :func:`cloth_scene`, its object scaled ``first_scale`` at frame 1 and (1.5, 1, 1)
    from frame 4 on, turned 0.6 rad about z from frame 4 to 11 (keyframed, baked after): the frames 5–13
    share one stretch (the world's proportions), the simulation's first frame has another."""
    obj = cloth_scene(frames=13)
    scene = bpy.context.scene
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.free_bake_all()
    obj.scale = first_scale
    obj.keyframe_insert("scale", frame=1)
    obj.scale = (1.5, 1.0, 1.0)
    obj.keyframe_insert("scale", frame=4)
    obj.keyframe_insert("rotation_euler", frame=4)  # turned over the range: its frames' matrices differ
    obj.rotation_euler.z = 0.6
    obj.keyframe_insert("rotation_euler", frame=11)
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    scene.frame_set(1)
    return obj


def _rests_given(extension, monkeypatch):
    """The operators' module and the list that gets the ``rest_pose`` of every sequence made from then on."""
    frames_module = importlib.import_module(extension.__name__ + ".operators.frames")
    core = frames_module.load_core()
    given, original = [], core.SequenceInterpolator

    def recording(*args, **kwargs):
        given.append(kwargs.get("rest_pose"))
        return original(*args, **kwargs)

    monkeypatch.setattr(core, "SequenceInterpolator", recording)
    return frames_module, given


def _inbetweens_with_and_without_the_rest_frame(bridge, obj, frames_module, monkeypatch):
    """In-between Frames 5–11 every 3rd, 2 per gap, on ``obj`` as it runs, then with no simulation's first
    frame read (:func:`operators.frames.simulation_first_frame` patched): the shape keys' names and
    positions of each run."""
    runs = []
    for _ in range(2):
        bpy.ops.shape_differences.inbetween_frames(frame_start=5, frame_end=11, frame_step=3, count=2,
                                                   output='SHAPE_KEYS')
        names = key_names(obj)[1:]
        runs.append((names, [positions_of(bridge, obj, name) for name in names]))
        obj.shape_key_clear()
        monkeypatch.setattr(frames_module, "simulation_first_frame", lambda *_: [])
    return runs


def test_inbetween_frames_inside_a_simulation_keeps_the_range_s_space(bpy_empty, extension, monkeypatch):
    """Frames 5–11 every 3rd of a cloth whose object is scaled (1, 1, 1) at the simulation's first
    frame and (1.5, 1, 1) over the whole range, turned over it: the first frame, read for the warnings'
    rest only, leaves the in-betweens as they are without it (the range's one stretch: the world's
    proportions; before, its matrix put them in the world through each frame's: 0.023 off on the
    2-unit sheet), and its rest reaches the sequence in that space, its edges those of the world at
    frame 1, which the cloth keeps."""
    obj = _cloth_scaled_before((1.0, 1.0, 1.0))
    bridge = extension.bridge
    read = evaluated_frames(bridge, obj, [1, 5])  # before the shape keys written play there
    triangles = bridge.triangulation.mesh_triangles(obj.data)
    frames_module, given = _rests_given(extension, monkeypatch)
    (names, with_rest), (names_without, without) = _inbetweens_with_and_without_the_rest_frame(
        bridge, obj, frames_module, monkeypatch)
    rest = given[0]
    assert rest is not None and given[1:] == [None]

    def lengths(x):
        return np.linalg.norm(x[triangles[:, 1]] - x[triangles[:, 0]], axis=1)

    np.testing.assert_allclose(lengths(rest), lengths(read[1]), rtol=1e-6)  # scale 1 at frame 1: the world's
    assert names_without == names
    for pose, pose_without in zip(with_rest, without):
        np.testing.assert_array_equal(pose, pose_without)


def test_inbetween_frames_inside_a_simulation_from_a_flattened_frame(bpy_empty, extension, monkeypatch):
    """The same cloth scaled (1, 1, 0) at the simulation's first frame, a frame outside the range
    asked: In-between Frames 5–11 runs (the in-betweens those without that frame), its warnings measured
    from the first key, as where no rest is read, rather than refusing a scale the range never shows."""
    obj = _cloth_scaled_before((1.0, 1.0, 0.0))
    bridge = extension.bridge
    frames_module, given = _rests_given(extension, monkeypatch)
    assert frames_module.simulation_first_frame(bpy.context.scene, obj, 5, 11) == [1]
    (names, poses), (names_without, without) = _inbetweens_with_and_without_the_rest_frame(
        bridge, obj, frames_module, monkeypatch)
    assert given == [None, None] and names_without == names
    for pose, pose_without in zip(poses, without):
        np.testing.assert_array_equal(pose, pose_without)


def test_inbetween_frames_inside_a_simulation_reads_no_earlier_frames_in_a_scene_read_frame_by_frame(
        bpy_empty, extension, monkeypatch):
    """The baked cloth of :func:`cloth_scene` beside another cloth that is not baked, from frame 4: the
    scene's frames are read one after the other (each may need the one before), so the cloth's first
    frame, read for the warnings' rest, would have frames 1–3 evaluated too (and the other cloth
    simulated there): In-between Frames 5–11 reads from frame 5 as without it, its warnings measured
    from the first key."""
    obj = cloth_scene(frames=13)
    other = grid_object(4, name="Other")
    other.location.x = 5.0
    other.modifiers.new("Cloth", 'CLOTH').point_cache.frame_start = 4
    bpy.context.view_layer.objects.active = obj
    frames_module, given = _rests_given(extension, monkeypatch)
    reading = frames_module.frame_reading
    visits, positions = [], reading.frame_positions

    def recording_reads(context, obj, frames, first_visit=None, **kwargs):
        visits.append(min(frames) if first_visit is None else min(first_visit, *frames))
        return positions(context, obj, frames, first_visit, **kwargs)

    monkeypatch.setattr(reading, "frame_positions", recording_reads)
    bpy.ops.shape_differences.inbetween_frames(frame_start=5, frame_end=11, frame_step=3, count=2,
                                               output='SHAPE_KEYS')
    assert visits == [5] and given == [None]


def test_invoke_runs_to_the_end_in_background(bpy_empty, extension):
    """From the UI, invoke() runs the work from a modal timer; in background mode (scripts,
    ``blender --background``) it runs synchronously like execute()."""
    obj = armature_scene(frames=3)
    assert bpy.app.background
    assert bpy.ops.shape_differences.frames_to_shape_keys('INVOKE_DEFAULT') == {'FINISHED'}
    assert key_names(obj)[1:] == ["Frame 1", "Frame 2", "Frame 3"]


def frames_visited_by_inbetween_frames(tmp_path) -> list[int]:
    """The frames In-between Frames sets while it reads keys 1, 5, 9 (one in-between per gap), in
    the order set, the return to the scene's current frame included."""
    visited = []

    def count(scene, *_):
        visited.append(scene.frame_current)

    bpy.app.handlers.frame_change_pre.append(count)
    try:
        bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                                   filepath=str(tmp_path / "cloth.pc2"))
    finally:
        bpy.app.handlers.frame_change_pre.remove(count)
    return visited


#: Frames read every frame from the first, the scene (at frame 1) set back to its frame after.
EVERY_FRAME = [*range(1, 10), 1]
#: Keys 1, 5, 9 and frames 3 and 7, in the middle of the first and last gaps (how the motion starts
#: and ends), read alone, the scene's own frame 1 last: the scene stays there.
KEY_FRAMES = [3, 5, 7, 9, 1]


@pytest.mark.parametrize("bake", [True, False], ids=["baked", "unbaked"])
def test_reading_keys_visits_only_the_key_frames_of_a_baked_simulation(bpy_empty, extension, bake, tmp_path):
    """A baked cache is read at the key frames alone (a frame does not depend on the ones before);
    an unbaked simulation is advanced through every frame from its start, as before."""
    from blender_scenes import pinned_cloth_scene

    pinned_cloth_scene(frames=9, bake=bake)
    assert frames_visited_by_inbetween_frames(tmp_path) == (KEY_FRAMES if bake else EVERY_FRAME)
    assert bpy.context.scene.frame_current == 1


@pytest.mark.parametrize("current, expected", [(1, [3, 5, 7, 9, 1]), (5, [1, 3, 7, 9, 5]), (4, [1, 3, 5, 7, 9, 4])])
def test_a_baked_cloth_is_read_once_at_each_frame_the_scene_left_at_its_own(bpy_empty, extension, tmp_path,
                                                                          current, expected):
    """The frames of a baked cloth are each set once: the scene's current frame, where it is a frame
    read, is read last and the scene left there, rather than set to it again afterwards (at the
    cloth's start frame Blender builds the cloth anew, 90 ms at 20k vertices); the in-betweens are
    the same whichever frame the scene is at, to the bit."""
    from blender_scenes import pinned_cloth_scene

    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    pinned_cloth_scene(frames=9, bake=True)
    scene = bpy.context.scene
    played = []
    for frame in (current, 1 if current != 1 else 4):  # the second from another frame: another order
        scene.frame_set(frame)
        (tmp_path / str(frame)).mkdir()
        visited = frames_visited_by_inbetween_frames(tmp_path / str(frame))
        assert scene.frame_current == frame and scene.frame_subframe == 0.0
        played.append(point_cache.read_pc2(tmp_path / str(frame) / "cloth.pc2").positions)
        if frame == current:
            assert visited == expected
    assert played[0].shape == (5, len(bpy.data.objects["Flag"].data.vertices), 3)  # keys 1, 5, 9 and 3, 7
    assert np.array_equal(played[0], played[1])


OPERATORS_WRITING_KEYS = {
    "frames_to_shape_keys": dict(frame_start=1, frame_end=9, frame_step=4),
    "inbetween_frames": dict(frame_start=1, frame_end=9, frame_step=4, count=1),
    "retime": dict(frame_start=1, frame_end=9, frame_step=4, speed=0.5),
}


@pytest.mark.parametrize("operator", sorted(OPERATORS_WRITING_KEYS))
@pytest.mark.parametrize("current", [1, 5])
def test_shape_keys_are_written_before_the_scene_returns_to_its_frame(bpy_empty, extension, tmp_path, operator,
                                                                      current):
    """Shape keys written on a baked cloth read at the scene's own frame: that frame is read as the
    scene shows it, the others after it, and the scene goes back to its frame once the keys are
    written, so that Blender evaluates the new keys and the return together (at the cloth's start
    frame, frame 1 here, each costs a build of the cloth); the keys are the point cache's poses of the
    same run, to the bit, and the scene ends at its frame."""
    from blender_scenes import pinned_cloth_scene

    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    obj = pinned_cloth_scene(frames=9, bake=True)
    scene = bpy.context.scene
    run = getattr(bpy.ops.shape_differences, operator)
    scene.frame_set(current)
    run(**OPERATORS_WRITING_KEYS[operator], output='CACHE', filepath=str(tmp_path / "cloth.pc2"))
    cached = point_cache.read_pc2(tmp_path / "cloth.pc2").positions
    visits = []  # each frame set, with the shape keys the cloth has then

    def count(scene, *_):
        keys = obj.data.shape_keys
        visits.append((scene.frame_current, len(keys.key_blocks) if keys else 0))

    bpy.app.handlers.frame_change_pre.append(count)
    try:
        run(**OPERATORS_WRITING_KEYS[operator], output='SHAPE_KEYS')
    finally:
        bpy.app.handlers.frame_change_pre.remove(count)
    written = obj.data.shape_keys.key_blocks[1:]
    assert [frame for frame, _ in visits].count(current) == 1 and visits[-1] == (current, 1 + len(written))
    assert all(keys == 0 for _, keys in visits[:-1])
    assert scene.frame_current == current and scene.frame_subframe == 0.0
    keys = np.array([extension.bridge.mesh_data.stored_key_positions(key_block)
                     for key_block in written], dtype=np.float32)
    assert np.array_equal(keys, cached)


@pytest.mark.parametrize("operator", sorted(OPERATORS_WRITING_KEYS))
@pytest.mark.parametrize("current", [5, 6])
def test_a_soft_bodys_start_frame_is_read_last_where_shape_keys_are_written(bpy_empty, extension, tmp_path, operator,
                                                                            current):
    """Blender builds a soft body anew when it leaves its start frame and when its mesh changes (it
    lists each point's springs by scanning every spring: 1.5 s at 10k vertices, 6 s at 20k). Shape
    keys written on a baked soft body, the scene at a frame past its start (read or not): the start
    frame is read after the others, so that the return to the scene's frame once the keys are written
    builds it once for both; the keys are the point cache's poses of the same run, to the bit."""
    from blender_scenes import soft_body_scene

    point_cache = importlib.import_module(extension.__name__ + ".core.point_cache")
    obj = soft_body_scene(frames=9)
    scene = bpy.context.scene
    run = getattr(bpy.ops.shape_differences, operator)
    scene.frame_set(current)
    run(**OPERATORS_WRITING_KEYS[operator], output='CACHE', filepath=str(tmp_path / "ball.pc2"))
    cached = point_cache.read_pc2(tmp_path / "ball.pc2").positions
    visits = []

    def count(scene, *_):
        visits.append(scene.frame_current)

    bpy.app.handlers.frame_change_pre.append(count)
    try:
        run(**OPERATORS_WRITING_KEYS[operator], output='SHAPE_KEYS')
    finally:
        bpy.app.handlers.frame_change_pre.remove(count)
    assert visits[-2:] == [1, current] and visits.count(1) == 1 and visits.count(current) == 1
    assert scene.frame_current == current and scene.frame_subframe == 0.0
    written = obj.data.shape_keys.key_blocks[1:]
    keys = np.array([extension.bridge.mesh_data.stored_key_positions(key_block)
                     for key_block in written], dtype=np.float32)
    assert np.array_equal(keys, cached)
    assert np.abs(cached[-1] - cached[0]).max() > 0.1  # the ball fell: the keys are of its motion


def test_a_run_failing_after_reading_sets_the_scene_back_to_its_frame(bpy_empty, extension, monkeypatch):
    """In-between Frames to shape keys leaves the scene at the last frame read until it has written
    them: a core error after the reading sets the scene back to its frame all the same, and nothing
    is written."""
    from blender_scenes import pinned_cloth_scene

    obj = pinned_cloth_scene(frames=9, bake=True)
    scene = bpy.context.scene
    scene.frame_set(5)
    core = extension.core

    def failing(*_args, **_kwargs):
        raise core.MeshError("the keys cannot be in-betweened")

    monkeypatch.setattr(core, "SequenceInterpolator", failing)
    with pytest.raises(RuntimeError, match="cannot be in-betweened"):
        bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=9, frame_step=4, count=1,
                                                   output='SHAPE_KEYS')
    assert scene.frame_current == 5 and scene.frame_subframe == 0.0
    assert obj.data.shape_keys is None


def test_geometry_nodes_anywhere_keep_reading_every_frame(bpy_empty, extension, tmp_path):
    """A geometry-nodes modifier may hold an unbaked simulation zone (its bakes are not checked):
    with one on another object, the keys of a baked cloth are read through every frame."""
    from blender_scenes import grid_object, pinned_cloth_scene

    pinned_cloth_scene(frames=9, bake=True)
    other = grid_object(2, name="Other")
    other.modifiers.new("Nodes", 'NODES')
    bpy.context.view_layer.objects.active = bpy.data.objects["Flag"]
    assert frames_visited_by_inbetween_frames(tmp_path) == EVERY_FRAME


def test_smooth_by_angle_does_not_make_every_frame_read(bpy_empty, extension, tmp_path):
    """*Shade Auto Smooth* adds a Geometry Nodes modifier (*Smooth by Angle*) that only sets
    shading: it cannot hold a simulation, so a baked cloth's keys are still read at the key
    frames alone; a node group that moves vertices keeps every frame read."""
    from blender_scenes import grid_object, pinned_cloth_scene

    flag = pinned_cloth_scene(frames=9, bake=True)
    other = grid_object(2, name="Other")
    for obj in (flag, other):
        with bpy.context.temp_override(active_object=obj, object=obj, selected_objects=[obj],
                                       selected_editable_objects=[obj]):
            bpy.ops.object.shade_auto_smooth()
    assert [m.type for m in flag.modifiers][-1] == 'NODES'
    bpy.context.view_layer.objects.active = flag
    assert frames_visited_by_inbetween_frames(tmp_path) == KEY_FRAMES
    group = other.modifiers[-1].node_group.copy()  # the same group with a Set Position added
    group.nodes.new("GeometryNodeSetPosition")
    other.modifiers[-1].node_group = group
    assert frames_visited_by_inbetween_frames(tmp_path) == EVERY_FRAME


def _inbetween_of_frames_1_5_9(frame: int) -> str:
    """The shape key In-between Frames names for ``frame`` (2–4, 6–8) of keys 1, 5 and 9."""
    gap = 0 if frame < 5 else 1
    return f"Inbetween Frame {1 + 4 * gap}-Frame {5 + 4 * gap} {(frame - 1 - 4 * gap) / 4:.2f}"


def test_a_turn_in_the_world_of_an_object_scaled_along_one_axis(bpy_empty, extension, tmp_path):
    """A sheet scaled (2, 1, 0.5) and not applied, played by a Mesh Cache that turns it rigidly in
    the world at a steady 15° per frame: every in-between of In-between Frames is that turn at its
    frame (before, computed in the mesh's stretched coordinates: up to 0.77 off in the world, on a
    sheet 4 wide)."""
    from blender_scenes import turning_stretched_sheet

    bridge = extension.bridge
    sheet, linear, turned = turning_stretched_sheet(extension, tmp_path)
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=3, output='SHAPE_KEYS')
    for frame in (2, 3, 4, 6, 7, 8):
        made = bridge.mesh_data.stored_key_positions(
            sheet.data.shape_keys.key_blocks[_inbetween_of_frames_1_5_9(frame)])
        np.testing.assert_allclose(made @ linear.T, turned(frame) @ linear.T, atol=2e-5)


def test_in_betweens_of_an_object_whose_scale_is_keyframed_are_the_world_motion(bpy_empty, extension, tmp_path):
    """The turning sheet on an object whose scale is keyframed: every in-between of In-between
    Frames, shown under the object's scale at its frame, is that turn to the float32 of shape keys
    (before, the keys were interpolated in the object's own coordinates, where the turning sheet
    also shrinks to half its size, and came out up to 5.7e-2 off, at frame 3, on a sheet 2 wide)."""
    bridge = extension.bridge
    sheet, scale, world = turning_sheet_scale_keyframed(extension, tmp_path)
    bpy.ops.shape_differences.inbetween_frames(frame_step=4, count=3, output='SHAPE_KEYS')
    for frame in (2, 3, 4, 6, 7, 8):
        made = bridge.mesh_data.stored_key_positions(
            sheet.data.shape_keys.key_blocks[_inbetween_of_frames_1_5_9(frame)])
        np.testing.assert_allclose(made * scale(frame), world(frame), atol=1e-6)


def frames_set_during(run) -> list[int]:
    """The frames the scene is set to (each evaluated, handlers called) while ``run()`` runs."""
    shown = []

    def record(scene, _depsgraph=None):
        shown.append(scene.frame_current)

    bpy.app.handlers.frame_change_post.append(record)
    try:
        run()
    finally:
        bpy.app.handlers.frame_change_post.remove(record)
    return shown


@pytest.mark.parametrize("operator", ["inbetween_frames", "retime"])
def test_the_matrices_of_an_object_whose_scale_is_keyframed_are_read_in_one_pass(bpy_empty, extension, tmp_path,
                                                                                 operator):
    """In-between Frames and Retime of the turning sheet whose scale is keyframed read its matrix
    at each in-between's (each output's) time: the scene goes to each of those frames once and back
    to its current frame once after them all, not after each gap or output (at a cloth's start
    frame Blender builds the cloth again: 35 ms per return on a 10k sheet, 0.5 ms per other frame
    of its bake; In-between Frames at keys 4 apart 55–60 → 45–50 ms per in-between, Retime at
    speed 1 3.3–4.3 → 1.7–2.1 s). Going back to a frame the scene is already at sets nothing."""
    bridge = extension.bridge
    turning_sheet_scale_keyframed(extension, tmp_path)
    scene = bpy.context.scene
    scene.frame_set(20)  # after the range read: each return to it is seen
    assert frames_set_during(lambda: list(bridge.scene_timing.at_times(scene, []))) == []
    if operator == "inbetween_frames":
        shown = frames_set_during(lambda: bpy.ops.shape_differences.inbetween_frames(
            frame_step=4, count=3, output='CACHE', filepath=str(tmp_path / "inbetweens.pc2")))
    else:
        shown = frames_set_during(lambda: bpy.ops.shape_differences.retime(
            frame_step=4, speed=0.5, output='CACHE', filepath=str(tmp_path / "retimed.pc2")))
    # one return after reading the keys, one after the matrices
    assert shown.count(20) == 2, shown
    assert scene.frame_current == 20


def easing_off_in_the_world(extension, core, tmp_path, last: int = 9, scale_keyed: bool = True):
    """The sheet rising from rest in the world (:func:`sheet_easing_off_scale_keyframed`, its scale
    keyframed or not), keys every 4th frame from frame 1 to ``last``: the sheet, its scale, its world
    positions and the sequence of its world keys starting from rest, the start the frame in the
    middle of the first gap gives in the world; in the object's own coordinates, shrinking from
    frame 1 on where its scale is keyframed, that frame gives the keys' parabola."""
    sheet, scale, world = sheet_easing_off_scale_keyframed(extension, tmp_path, scale_keyed=scale_keyed)
    motion_ends = importlib.import_module(core.__name__ + ".motion_ends")
    keyed = sorted({*range(1, last + 1, 4), last})
    durations = (4, keyed[2] - 5)
    assert motion_ends.start_of_motion([world(f) for f in keyed[:3]], world(3), 0.5, durations) == "rest"
    own = motion_ends.start_of_motion([world(f) / scale(f) for f in keyed[:3]], world(3) / scale(3), 0.5, durations)
    assert own == ("keys" if scale_keyed else "rest")
    sequence = core.SequenceInterpolator([world(f) for f in keyed],
                                         extension.bridge.triangulation.mesh_triangles(sheet.data),
                                         start="rest", key_times=keyed)
    return sheet, scale, world, sequence


@pytest.mark.parametrize("last, scale_keyed", [(9, True), (7, True), (7, False)])
def test_in_between_frames_choose_the_start_from_the_middle_of_the_first_gap_in_the_world(
        bpy_empty, extension, core, tmp_path, last, scale_keyed):
    """How the motion leaves the first key is told by the frame in the middle of the first gap, in
    the space the keys are interpolated in (the world, for an object whose scale is keyframed), also
    where two whole-step keys and the last frame key the sequence (frames 1, 5, 7): the first gap's
    in-betweens are the world keys' sequence from rest, to the float32 of shape keys (before, the
    start was chosen in the object's own coordinates, the keys' parabola, 6.3e-2 off at frame 2 on
    a sheet 2 wide, and with two whole-step keys it was the keys' parabola unread: 2.4e-2 off)."""
    bridge = extension.bridge
    sheet, scale, world, sequence = easing_off_in_the_world(extension, core, tmp_path, last, scale_keyed)
    bpy.ops.shape_differences.inbetween_frames(frame_start=1, frame_end=last, frame_step=4, count=3,
                                               output='SHAPE_KEYS')
    expected = sequence.poses(0, [0.25, 0.5, 0.75])
    for frame in (2, 3, 4):
        name = f"Inbetween Frame 1-Frame 5 {(frame - 1) / 4:.2f}"
        made = bridge.mesh_data.stored_key_positions(sheet.data.shape_keys.key_blocks[name])
        np.testing.assert_allclose(made * scale(frame), expected[frame - 2], atol=1e-6)


def _retimed_in_the_world(bridge, sheet, shown, output: str, speed: float, frame: int) -> np.ndarray:
    """What Retime at ``speed`` shows at ``frame`` in the world: the shape key it added to ``sheet``
    (``output`` SHAPE_KEYS: the Mesh Cache after the keys replaces them in the evaluated mesh) or the
    new object ``shown`` as evaluated (CACHE), through ``shown``'s world matrix. Sets the frame."""
    bpy.context.scene.frame_set(frame)
    if output == 'SHAPE_KEYS':
        made = bridge.mesh_data.stored_key_positions(
            sheet.data.shape_keys.key_blocks[f"Retime {speed:.2f}x frame {frame}"])
    else:
        made = bridge.mesh_data.evaluated_positions(shown, bpy.context.evaluated_depsgraph_get())
    matrix = np.array(shown.matrix_world)
    return made @ matrix[:3, :3].T + matrix[:3, 3]


@pytest.mark.parametrize("output", ['CACHE', 'SHAPE_KEYS'])
def test_a_retime_chooses_the_start_in_the_world_of_an_object_whose_scale_is_keyframed(bpy_empty, extension, core,
                                                                                       tmp_path, output):
    """Retime at speed 1 from every 4th frame of the sheet rising from rest on an object whose scale
    is keyframed: the first gap's frames are the world keys' sequence from rest, to float32 (before,
    its start was chosen in the object's own coordinates: 7.2e-2 off at frame 3)."""
    bridge = extension.bridge
    sheet, scale, world, sequence = easing_off_in_the_world(extension, core, tmp_path)
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=1.0, output=output,
                                     filepath=str(tmp_path / "retimed.pc2"))
    shown = sheet if output == 'SHAPE_KEYS' else next(o for o in bpy.data.objects if o.name not in names)
    expected = sequence.poses(0, [0.25, 0.5, 0.75])
    for frame in (2, 3, 4):
        np.testing.assert_allclose(_retimed_in_the_world(bridge, sheet, shown, output, 1.0, frame),
                                   expected[frame - 2], atol=1e-6)
    bpy.context.scene.frame_set(1)


@pytest.mark.parametrize("output", ['CACHE', 'SHAPE_KEYS'])
@pytest.mark.parametrize("speed", [1.0, 0.5])
def test_a_retime_of_an_object_whose_scale_is_keyframed_plays_the_world_motion(bpy_empty, extension, tmp_path,
                                                                               output, speed):
    """The turning sheet on an object whose scale is keyframed, retimed from every 4th frame: the
    mesh shown at every output frame ``f`` is the turn at the source's time ``1 + (f − 1) · speed``,
    to float32. A new object plays the source's scale retimed; shape keys play under the source's
    own scale at ``f`` (before, the poses were interpolated in the object's own coordinates, where
    the turning sheet also shrinks to half its size, and came out 4.7e-2 off at frame 2 on a sheet
    2 wide at speed 1, 9.0e-2 as shape keys at half speed)."""
    bridge = extension.bridge
    sheet, scale, world = turning_sheet_scale_keyframed(extension, tmp_path)
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.retime(frame_start=1, frame_end=9, frame_step=4, speed=speed, output=output,
                                     filepath=str(tmp_path / "retimed.pc2"))
    shown = sheet if output == 'SHAPE_KEYS' else next(o for o in bpy.data.objects if o.name not in names)
    out_frames = range(1, round(8 / speed) + 2)
    for frame in out_frames:
        np.testing.assert_allclose(_retimed_in_the_world(bridge, sheet, shown, output, speed, frame),
                                   world(1 + (frame - 1) * speed), atol=1e-6)
    bpy.context.scene.frame_set(1)


def test_a_mesh_moved_by_an_unbaked_cloth_proxy_reads_it_from_its_start(bpy_empty, extension):
    """A render mesh bound by a Surface Deform to a hanging cloth proxy whose memory cache a
    settings change emptied: reading frames 7–13 simulates the proxy from its start frame, so the
    keys are the frames as played from frame 1 (before, the proxy was simulated from frame 7 and
    frame 7 came out 0.016 off, a quarter of its motion)."""
    from blender_scenes import bound_to, pinned_cloth_scene

    bridge = extension.bridge
    proxy = pinned_cloth_scene(8, frames=13)  # played into its memory cache
    mesh = bound_to(proxy)
    played = evaluated_frames(bridge, mesh, [7, 10, 13])
    cloth = proxy.modifiers["Cloth"]
    cloth.settings.mass = cloth.settings.mass  # any settings change empties the cache
    bpy.context.view_layer.update()
    assert cloth.point_cache.info.startswith("0 frames")
    bpy.ops.shape_differences.inbetween_frames(frame_start=7, frame_end=13, frame_step=3, count=1,
                                               output='SHAPE_KEYS')
    for frame in (7, 10, 13):
        np.testing.assert_allclose(positions_of(bridge, mesh, f"Frame {frame}"), played[frame], atol=1e-6)


@pytest.mark.parametrize("output", ['CACHE', 'SHAPE_KEYS'])
def test_in_betweens_are_in_the_proportions_of_the_frames_read(bpy_empty, extension, tmp_path, output):
    """A sheet stretched (2, 1, 0.5) over frames 3–11, turning rigidly in the world, read while the
    scene is at frame 1, where its keyframed scale is 1: every in-between is the turn at its frame,
    to float32 (before, the world's proportions were taken at the current frame, and the in-betweens
    were computed in the mesh's stretched coordinates: 0.77 off in the world on a sheet 4 wide)."""
    bridge = extension.bridge
    sheet, linear, turned = turning_sheet_stretched_before_its_frames(extension, tmp_path)
    names = set(bpy.data.objects.keys())
    bpy.ops.shape_differences.inbetween_frames(frame_start=3, frame_end=11, frame_step=4, count=3, output=output,
                                               filepath=str(tmp_path / "inbetweens.pc2"))
    shown = next((o for o in bpy.data.objects if o.name not in names), None)
    for frame in (4, 5, 6, 8, 9, 10):
        if output == 'SHAPE_KEYS':  # the Mesh Cache after the keys replaces them in the evaluated mesh
            gap = 0 if frame < 7 else 1
            name = f"Inbetween Frame {3 + 4 * gap}-Frame {7 + 4 * gap} {(frame - 3 - 4 * gap) / 4:.2f}"
            made = bridge.mesh_data.stored_key_positions(sheet.data.shape_keys.key_blocks[name])
        else:
            made = bridge.mesh_data.evaluated_positions(shown, _depsgraph_at(frame))
        np.testing.assert_allclose(made @ linear.T, turned(frame) @ linear.T, atol=2e-5)
    bpy.context.scene.frame_set(1)


def _depsgraph_at(frame):
    bpy.context.scene.frame_set(frame)
    return bpy.context.evaluated_depsgraph_get()


def test_a_dynamic_paint_wave_not_baked_is_read_from_its_start(bpy_empty, extension):
    """A Dynamic Paint wave surface that is not baked, read over frames 9–17 while the scene is at
    its start: the keys are the frames as played from the surface's start (a jump from frame 1 to
    frame 9 steps the surface once and shows another wave, 0.18 off on a grid 2 wide)."""
    bridge = extension.bridge
    obj = dynamic_paint_wave_scene(frames=17)
    played = {frame: bridge.mesh_data.evaluated_positions(obj, _depsgraph_at(frame)) for frame in range(1, 18)}
    surface = obj.modifiers["Dynamic Paint"].canvas_settings.canvas_surfaces[0]
    surface.wave_speed = surface.wave_speed  # any change empties the surface's cache
    bpy.context.scene.frame_set(1)
    bpy.ops.shape_differences.frames_to_shape_keys(frame_start=9, frame_end=17, frame_step=4, output='SHAPE_KEYS')
    assert np.abs(played[9][:, 2]).max() > 0.01  # the brush made waves by frame 9
    for frame in (9, 13, 17):
        np.testing.assert_allclose(positions_of(bridge, obj, f"Frame {frame}"), played[frame], atol=1e-6)
    assert bpy.context.scene.frame_current == 1


@pytest.mark.parametrize("operator, properties", [
    ("frames_to_shape_keys", dict(output='SHAPE_KEYS')), ("inbetween_frames", dict(count=1, output='SHAPE_KEYS')),
    ("distortion_maps", dict(source='FRAMES', eigenfunctions=0)), ("frames_to_shape_keys", dict(output='CACHE'))])
@pytest.mark.parametrize("baked", [False, True], ids=["not baked", "baked to disk"])
def test_a_simulation_zone_whose_mesh_a_run_changes_is_warned_unless_baked(bpy_empty, extension, capfd, tmp_path,
                                                                           operator, properties, baked):
    """Shape keys or distortion maps written to an object whose Geometry Nodes simulation zone is not
    baked change the mesh it simulates: Blender drops the frames it simulated (the scene at frame 9 no
    longer shows the zone's frame 9) and says nothing. The run warns (before: no word), naming the
    modifier; a zone baked to disk keeps its frames and is not warned, nor is a run that writes a new
    object (the source's frames kept)."""
    bridge = extension.bridge
    obj = simulation_zone_scene(frames=17)
    modifier = obj.modifiers["Simulation"]
    if baked:
        modifier.bake_target, modifier.bake_directory = 'DISK', str(tmp_path / "bake")
        with bpy.context.temp_override(object=obj, active_object=obj):
            bpy.ops.object.geometry_node_bake_single(session_uid=obj.session_uid, modifier_name=modifier.name,
                                                     bake_id=modifier.bakes[0].bake_id)
    played = {frame: bridge.mesh_data.evaluated_positions(obj, _depsgraph_at(frame)) for frame in range(1, 18)}
    bpy.context.scene.frame_set(1)
    capfd.readouterr()
    writes = properties.get("output") != 'CACHE'
    path = {} if writes else dict(filepath=str(tmp_path / "out.pc2"))
    getattr(bpy.ops.shape_differences, operator)(frame_start=1, frame_end=17, frame_step=4, **properties, **path)
    out = capfd.readouterr().out
    warned = ("changed the mesh that the simulation zone of 'Simulation' of 'Simulated' simulates: unless it is "
              "baked") in out
    kept = np.allclose(bridge.mesh_data.evaluated_positions(obj, _depsgraph_at(9)), played[9], atol=1e-6)
    bpy.context.scene.frame_set(1)
    assert kept == (baked or not writes), "the warning's premise: the frames are dropped where it is given"
    assert warned == (writes and not baked), out


def test_a_simulation_zone_not_baked_is_read_from_its_start(bpy_empty, extension):
    """A Geometry Nodes simulation zone that is not baked, read over frames 9–17 while the scene is
    at its start: the keys are the frames as played from the start (before, Blender stepped the zone
    once from frame 1 to frame 9, and frame 9 came out 0.99 off, on a sheet 2 wide)."""
    bridge = extension.bridge
    obj = simulation_zone_scene(frames=17)
    played = {frame: bridge.mesh_data.evaluated_positions(obj, _depsgraph_at(frame)) for frame in range(1, 18)}
    turn = obj.modifiers["Simulation"].node_group.nodes["Vector Rotate"]
    turn.inputs["Angle"].default_value = turn.inputs["Angle"].default_value  # any change empties the zone's cache
    bpy.context.scene.frame_set(1)
    bpy.ops.shape_differences.frames_to_shape_keys(frame_start=9, frame_end=17, frame_step=4, output='SHAPE_KEYS')
    for frame in (9, 13, 17):
        np.testing.assert_allclose(positions_of(bridge, obj, f"Frame {frame}"), played[frame], atol=1e-6)
    assert bpy.context.scene.frame_current == 1
