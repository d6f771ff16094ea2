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
                        lambda self, job, arguments: given.append(len(job.calls)) or submit(self, job, arguments))
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
        assert given and given[0] == 2
        monkeypatch.setattr(concurrency, "USE_PROCESSES", False)
        with pytest.warns(core.ShapeDifferenceWarning):
            sequence = core.SequenceInterpolator(keys, triangles)
            alone = [sequence.poses(gap, factors) for gap in range(len(sequence))]
        assert all(x.tobytes() == y.tobytes() for x, y in zip(shared, alone))
    finally:
        gap_processes.shut_down()
