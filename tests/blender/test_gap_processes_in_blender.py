"""The second process of a sequence's gaps (core.gap_processes) where the core is the extension's,
``bl_ext.<repo>.<id>.core``: the worker loads it from its folder under a private name and gives the
caller's in-betweens to the bit."""

import importlib
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("bpy")


def test_the_extensions_sequences_share_their_gaps_with_a_worker(core, monkeypatch):
    gap_processes = importlib.import_module(f"{core.__name__}.gap_processes")
    concurrency = importlib.import_module(f"{core.__name__}.concurrency")
    assert core.__name__.startswith("bl_ext.")
    monkeypatch.setattr(gap_processes, "CONCURRENT_VERTICES", 0)  # its 150 vertices shared too
    monkeypatch.setattr(concurrency, "available_cores", lambda: 2)
    monkeypatch.setattr(concurrency, "USE_PROCESSES", True)
    monkeypatch.setattr(gap_processes, "_unstartable", False)
    data = np.load(Path(__file__).parents[1] / "core" / "data" / "spinning_sheet.npz")
    keys, triangles, factors = list(data["keys"]), data["triangles"], list(np.arange(1, 8) / 8)
    given = []
    submit = gap_processes._Worker.submit
    monkeypatch.setattr(gap_processes._Worker, "submit",
                        lambda self, job, *arguments: given.append(len(job.calls)) or submit(self, job, *arguments))
    try:
        worker = gap_processes.kept_worker()
        deadline = time.monotonic() + 120
        while not worker.ready and worker.alive and time.monotonic() < deadline:
            time.sleep(0.01)
        assert worker.ready
        assert not [name for name in worker.modules if not name.startswith(gap_processes.PRIVATE_NAME)]
        with pytest.warns(core.ShapeDifferenceWarning):
            sequence = core.SequenceInterpolator(keys, triangles)
            shared = [sequence.poses(gap, factors) for gap in range(len(sequence))]
        assert given and given[0] == 3  # five gaps: the later three (the half rounded up, the last contested)
        monkeypatch.setattr(concurrency, "USE_PROCESSES", False)
        with pytest.warns(core.ShapeDifferenceWarning):
            sequence = core.SequenceInterpolator(keys, triangles)
            alone = [sequence.poses(gap, factors) for gap in range(len(sequence))]
        assert all(x.tobytes() == y.tobytes() for x, y in zip(shared, alone))
    finally:
        gap_processes.shut_down()


def _frame_operator_run(core, extension, monkeypatch, operator: str, eligible: bool, processes: bool = True):
    """Run ``operator`` (In-between Frames or Retime, invoked: from a script it runs at once) on the
    armature strip, keys 1, 5, 9, 13, with the vertex threshold of the gaps' sharing at its vertex
    count where ``eligible``, one more where not: (whether the worker was running at the first frame read, the number of jobs given
    to it, the shape keys' stored positions as bytes). The worker is shut down first, and waited for
    at the first frame read where it runs (so it takes its share of these millisecond gaps)."""
    from blender_scenes import armature_scene

    gap_processes = importlib.import_module(f"{core.__name__}.gap_processes")
    concurrency = importlib.import_module(f"{core.__name__}.concurrency")
    reading = extension.bridge.frame_reading
    gap_processes.shut_down()
    running, given = [], []
    with monkeypatch.context() as patch:
        patch.setattr(concurrency, "available_cores", lambda: 2)
        patch.setattr(concurrency, "USE_PROCESSES", processes)
        patch.setattr(gap_processes, "_unstartable", False)
        positions, submit = reading.frame_positions, gap_processes._Worker.submit

        def first_read(context, obj, frames, *args, **kwargs):
            if not running:
                worker = gap_processes._worker
                running.append(worker is not None)
                deadline = time.monotonic() + 120
                while worker is not None and not worker.ready and worker.alive and time.monotonic() < deadline:
                    time.sleep(0.01)
            return positions(context, obj, frames, *args, **kwargs)

        patch.setattr(reading, "frame_positions", first_read)
        patch.setattr(gap_processes._Worker, "submit",
                      lambda self, job, *arguments: given.append(len(job.calls)) or submit(self, job, *arguments))
        bpy = importlib.import_module("bpy")
        bpy.ops.wm.read_homefile(use_empty=True)
        obj = armature_scene(frames=13)
        patch.setattr(gap_processes, "CONCURRENT_VERTICES", len(obj.data.vertices) + (not eligible))
        settings = dict(frame_start=1, frame_end=13, frame_step=4, output='SHAPE_KEYS')
        if operator == "retime":
            assert bpy.ops.shape_differences.retime('INVOKE_DEFAULT', speed=0.5, **settings) == {'FINISHED'}
        else:
            assert bpy.ops.shape_differences.inbetween_frames('INVOKE_DEFAULT', count=3, **settings) == {'FINISHED'}
        stored = [extension.bridge.mesh_data.stored_key_positions(key).tobytes()
                  for key in obj.data.shape_keys.key_blocks]
        return running, len(given), stored


@pytest.mark.parametrize("operator", ["inbetween_frames", "retime"])
def test_frame_operators_start_the_worker_before_reading_an_eligible_mesh(core, extension, monkeypatch, operator):
    """In-between Frames and Retime start the worker before they read the frames where the sequence
    shares its gaps (its start overlaps the reading), which then takes its share; the shape keys are
    those of one process to the bit. On a mesh under the vertex threshold none is started."""
    try:
        running, jobs, shared = _frame_operator_run(core, extension, monkeypatch, operator, eligible=True)
        assert running == [True] and jobs >= 1
        running, jobs, small = _frame_operator_run(core, extension, monkeypatch, operator, eligible=False)
        assert running == [False] and jobs == 0
        gap_processes = importlib.import_module(f"{core.__name__}.gap_processes")
        assert gap_processes._worker is None
        running, jobs, alone = _frame_operator_run(core, extension, monkeypatch, operator, eligible=True,
                                                   processes=False)
        assert running == [False] and jobs == 0
        assert len(shared) > 5 and shared == alone == small
    finally:
        importlib.import_module(f"{core.__name__}.gap_processes").shut_down()
