"""The in-between benchmark's cost column (benchmarks/bench_inbetween.py, issue 17): the ratio to
Blender's bake from repeated, interleaved timings, and timing a bake without touching the cached
frames. Blender and the clocks are replaced by stubs: these tests check the protocol's logic,
never a speed."""

import json
import time

import numpy as np
import pytest

from bench_helpers import steady_bend
from benchmarks import bench_inbetween as bench
from benchmarks import cloth_scenes


def test_cost_ratio_is_least_over_least_with_the_per_repeat_range():
    cost = bench.cost_ratio([2.0, 1.0, 3.0], [10.0, 20.0, 5.0])
    assert cost["ratio"] == 1.0 / 5.0  # least ours (repeat 2) ÷ least bake (repeat 3)
    assert (cost["low"], cost["high"]) == (1.0 / 20.0, 3.0 / 5.0)
    assert cost["repeats"] == 3


def test_least_over_least_lies_in_the_per_repeat_range():
    rng = np.random.default_rng(0)
    for _ in range(200):
        k = int(rng.integers(1, 6))
        ours, bake = rng.uniform(0.01, 1.0, k), rng.uniform(0.1, 3.0, k)
        cost = bench.cost_ratio(ours, bake)
        assert cost["low"] <= cost["ratio"] <= cost["high"]
        assert cost["low"] == pytest.approx(min(o / b for o, b in zip(ours, bake)), rel=1e-15)


def test_a_single_timing_against_repeated_bakes():
    # The two-pose protocol is timed in the first repeat only: its one ratio uses the least bake.
    cost = bench.cost_ratio([0.5], [2.0, 1.0, 4.0])
    assert cost == {"ratio": 0.5, "low": 0.25, "high": 0.25, "repeats": 1}


@pytest.mark.parametrize("ours, bake", [([], [1.0]), ([1.0], []), ([1.0], [0.0])])
def test_cost_ratio_refuses_missing_or_empty_bakes(ours, bake):
    with pytest.raises(ValueError, match="cost_ratio"):
        bench.cost_ratio(ours, bake)


def test_cost_format():
    assert bench.format_cost({"ratio": 0.0834, "low": 0.0786, "high": 0.0971, "repeats": 3}) == "0.083 (0.079–0.097)"
    assert bench.format_cost({"ratio": 0.0834, "low": 0.0834, "high": 0.0834, "repeats": 1}) == "0.083"


# ------------------------------------------------------------------------------------------------
# A scene of 8 × 8 vertices bending about an axis, baked by a stub instead of Blender.


@pytest.fixture
def fake_scene(monkeypatch, tmp_path):
    """Scene "fake" cached in a temporary directory; ``bakes`` lists the specs the stub baked."""
    spec = cloth_scenes.SceneSpec("fake", "fake", (8, 8), frames=17)
    monkeypatch.setitem(cloth_scenes.SCENES, "fake", spec)
    monkeypatch.setattr(cloth_scenes, "OUTPUT_DIR", tmp_path)
    bakes = []

    def stub_bake(spec):
        bakes.append(spec)
        frames, triangles = steady_bend(spec.frames)
        return frames, triangles, 3.2

    monkeypatch.setattr(cloth_scenes, "bake", stub_bake)
    return spec, tmp_path / "cloth_fake.npz", bakes


def test_the_cache_is_written_only_when_missing_changed_or_asked(fake_scene, monkeypatch):
    spec, path, bakes = fake_scene
    cloth_scenes.load_scene("fake")
    assert len(bakes) == 1 and path.exists()
    before = path.read_bytes()
    cloth_scenes.load_scene("fake")
    assert len(bakes) == 1 and path.read_bytes() == before
    changed = cloth_scenes.SceneSpec("fake", "fake", (8, 8), frames=9)
    monkeypatch.setitem(cloth_scenes.SCENES, "fake", changed)
    assert cloth_scenes.load_scene("fake").frames.shape[0] == 9
    assert bakes[-1] == changed
    cloth_scenes.load_scene("fake", rebake=True)
    assert len(bakes) == 3


def test_timing_a_bake_reads_and_writes_no_frames(fake_scene, monkeypatch):
    spec, path, bakes = fake_scene
    cloth_scenes.load_scene("fake")
    before, stamp = path.read_bytes(), path.stat().st_mtime_ns
    built = []
    monkeypatch.setattr(cloth_scenes, "build", built.append)
    # The bake's wall and CPU seconds over its 16 simulated frames (frame 1 is the initial state).
    monkeypatch.setattr(cloth_scenes, "bake_all", lambda clock: np.array([4.0, 6.0]))
    assert cloth_scenes.time_bake(spec) == (0.25, 0.375)
    assert built == [spec] and len(bakes) == 1
    assert path.read_bytes() == before and path.stat().st_mtime_ns == stamp
    assert [p.name for p in path.parent.iterdir()] == ["cloth_fake.npz"]


def test_repeats_interleave_bakes_and_sequences_and_keep_every_timing(fake_scene, monkeypatch, tmp_path):
    spec, path, bakes = fake_scene
    cloth_scenes.load_scene("fake")
    before, stamp = path.read_bytes(), path.stat().st_mtime_ns
    calls = []
    bake_times = iter([(0.5, 0.6), (0.4, 0.5), (0.45, 0.7)])

    def stub_timer(name):
        calls.append("bake")
        return next(bake_times)

    timed = bench._time_sequence

    def record_sequence(keys, triangles, factors):
        calls.append(f"seq g = {len(factors) + 1}")
        return timed(keys, triangles, factors)

    monkeypatch.setattr(bench, "_time_sequence", record_sequence)
    out = tmp_path / "results.json"
    results = bench.main(["--scenes", "fake", "--gaps", "4", "8", "--repeats", "3", "--json", str(out)],
                         bake_timer=stub_timer)
    assert calls == ["bake", "seq g = 4", "seq g = 8"] * 3
    assert len(bakes) == 1 and path.read_bytes() == before and path.stat().st_mtime_ns == stamp
    saved = json.loads(out.read_text())
    assert [(r["gap"], r["protocol"]) for r in saved] == [(4, "seq"), (4, "pair"), (8, "seq"), (8, "pair")]
    for r in saved:
        t = r["timing"]
        assert t["bake_wall"] == [0.5, 0.4, 0.45] and t["bake_cpu"] == [0.6, 0.5, 0.7]
        assert len(t["ours_wall"]) == len(t["ours_cpu"]) == (3 if r["protocol"] == "seq" else 1)
        assert r["seconds"] == min(t["ours_wall"]) and r["bake"] == 0.4
        assert r["cost"] == bench.cost_ratio(t["ours_wall"], t["bake_wall"])
        assert r["cpu_cost"] == bench.cost_ratio(t["ours_cpu"], t["bake_cpu"])
    assert results[0]["ours"]["n"] == 4 * 3  # four gaps of three in-betweens, measured once


def test_repeats_that_give_other_in_betweens_stop_the_run(fake_scene, monkeypatch):
    cloth_scenes.load_scene("fake")
    timed, runs = bench._time_sequence, []

    def drifting(keys, triangles, factors):
        predicted, *times = timed(keys, triangles, factors)
        runs.append(1)
        if len(runs) > 1:
            predicted[0] = predicted[0] + 1e-15 * np.abs(predicted[0]).max()
        return predicted, *times

    monkeypatch.setattr(bench, "_time_sequence", drifting)
    with pytest.raises(RuntimeError, match="repeat 2 gives other in-betweens"):
        bench.run_scene("fake", [4], protocols=("seq",), repeats=2, bake_timer=lambda name: (1.0, 1.0),
                        log=lambda line: None)


def test_every_repeat_times_a_first_request_of_its_keys(fake_scene, monkeypatch):
    """The gap worker keeps the last sequence it built and serves the same keys asked again from it
    (nothing sent, nothing built): each repeat's sequence must meet a worker that has not seen its
    keys, ready before the timing, as a user's request on new keys does; the worker's start is
    reported apart, and the worker ended after the timing. Every repeat here gives the worker a job
    with the keys, a worker of each repeat's own; before session 77 the first repeat's worker was
    still starting and took no job, and the third repeat's job went without the keys, served from
    the second's sequence (with bakes shorter than the worker's start no repeat gave it a job at
    all); at 390c6f1 the start was reported nowhere and each worker sat idle through the next bake."""
    from core import concurrency, gap_processes

    monkeypatch.setattr(gap_processes, "CONCURRENT_VERTICES", 0)  # the 64-vertex sheet shares its gaps
    monkeypatch.setattr(concurrency, "available_cores", lambda: 2)
    monkeypatch.setattr(concurrency, "USE_PROCESSES", True)
    monkeypatch.setattr(gap_processes, "_unstartable", False)
    gap_processes.shut_down()
    cloth_scenes.load_scene("fake")
    jobs = []  # per repeat: (worker's process id, whether the keys were sent) of each job
    starts = []  # per repeat: the CPU seconds the worker's start took, as it said when ready
    submit = gap_processes._Worker.submit

    def recorded(self, job, token, arguments):
        jobs[-1].append((self.process.pid, self.kept != token))  # the keys are sent unless it keeps them
        if len(starts) < len(jobs):
            starts.append(self.cpu)  # its first job: its only message so far said it was ready
        return submit(self, job, token, arguments)

    between = []  # the worker alive at each bake (None: none)

    def stub_timer(name):
        jobs.append([])  # a repeat begins with its bake, which takes seconds: a worker started is ready after it
        worker, deadline = gap_processes._worker, time.monotonic() + 120
        between.append(worker)
        while worker is not None and worker.alive and not worker.ready and time.monotonic() < deadline:
            time.sleep(0.01)
        return 1.0, 1.0

    monkeypatch.setattr(gap_processes._Worker, "submit", recorded)
    lines = []
    try:
        [entry] = bench.run_scene("fake", [4], protocols=("seq",), repeats=3, bake_timer=stub_timer,
                                  log=lines.append)
        between.append(gap_processes._worker)
    finally:
        gap_processes.shut_down()
    assert len(jobs) == 3 and all(jobs), jobs  # a job in every repeat: the worker ready at its start
    assert all(sent for repeat in jobs for _, sent in repeat), jobs  # never served from a kept sequence
    assert len({pid for repeat in jobs for pid, _ in repeat}) == 3, jobs  # a worker of each repeat's own
    # none outlives its sequence: an idle one would let its sequence go inside a later timing (a pair's)
    assert between == [None] * 4, between
    # each start, outside the timing, is reported per in-between (4 gaps of 3) and as a share of the bake
    count = (len(bench.kept_keys(cloth_scenes.load_scene("fake").frames, 4)) - 1) * 3
    assert len(starts) == 3 and min(starts) > 0, starts
    assert entry["timing"]["worker_start_cpu"] == pytest.approx([start / count for start in starts], rel=1e-12)
    assert f"g = 4 seq +{min(starts) / count / 1.0:.3f}" in lines[-1], lines[-1]


def test_options():
    args = bench.parse_args([])
    assert args.repeats == 3 and args.rebake == [] and args.scenes == list(cloth_scenes.SCENES)
    quick = bench.parse_args(["--quick"])
    assert quick.repeats == 1 and quick.scenes == bench.QUICK_SCENES
    assert bench.parse_args(["--quick", "--repeats", "2"]).repeats == 2
    assert bench.parse_args(["--rebake", "tablecloth"]).rebake == ["tablecloth"]
    for wrong in (["--rebake"], ["--repeats", "0"], ["--scenes", "no_such_scene"], ["--rebake", "no_such_scene"]):
        with pytest.raises(SystemExit):
            bench.parse_args(wrong)
