"""Retiming from every step-th frame: the plan (frame counts, kept frames, factors), kept frames
exactly the source's, in-betweens those of SequenceInterpolator, chunks concatenating bit for
bit into the single-process result, and the headless command (python -m core)."""

import os
import re
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

from core import MeshError, SequenceInterpolator, ShapeDifferenceWarning
from core.__main__ import main
from core.obj_file import read_obj, write_obj
from core.point_cache import read_pc2, write_pc2
from core.motion_ends import start_of_motion
from core.retime import iter_retime, plan_retime, retime
from meshes import grid

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]


def rolling_sheet(n_frames=9, nx=7):
    """A sheet rolling up over ``n_frames`` frames: float32 samples ``(F, n, 3)`` and triangles."""
    rest, triangles = grid(nx)
    frames = []
    for t in np.linspace(0.2, 2.0, n_frames):
        radius = 1.0 / t
        theta = rest[:, 0] / radius
        frames.append(np.stack([radius * np.sin(theta), rest[:, 1], radius * (1 - np.cos(theta))], axis=1))
    return np.array(frames, dtype=np.float32), triangles


@pytest.mark.parametrize("n_source, step, speed, n_out, keys", [
    (25, 4, 0.5, 49, [0, 4, 8, 12, 16, 20, 24]),
    (25, 4, 1.0, 25, [0, 4, 8, 12, 16, 20, 24]),
    (25, 4, 2.0, 13, [0, 4, 8, 12, 16, 20, 24]),
    (23, 5, 0.5, 45, [0, 5, 10, 15, 20, 22]),  # a shorter last gap ends on the last frame
    (11, 2, 0.3, 34, [0, 2, 4, 6, 8, 10]),
])
def test_plan(n_source, step, speed, n_out, keys):
    plan = plan_retime(n_source, step, speed)
    assert plan.n_out == n_out
    assert plan.keys.tolist() == keys
    assert plan.times[-1] <= n_source - 1
    # Output samples at a key's time show that key; every other time is strictly inside its gap.
    for k in range(plan.n_out):
        at_key = np.flatnonzero(plan.keys == plan.times[k])
        assert plan.exact_keys[k] == (at_key[0] if len(at_key) else -1)
        if plan.exact_keys[k] < 0:
            assert 0 < plan.factors[k] < 1
            g = plan.gaps[k]
            assert plan.times[k] == pytest.approx(plan.keys[g] + plan.factors[k] * (plan.keys[g + 1] - plan.keys[g]))
    assert plan.times[0] == 0 and plan.exact_keys[-1] == (len(keys) - 1 if plan.times[-1] == n_source - 1 else -1)


@pytest.mark.parametrize("n_source, step, tail, middle", [
    (25, 4, [], 22), (23, 5, [16, 18, 20, 22], 21), (18, 4, [14, 15, 16, 17], None), (12, 4, [2, 5, 8, 11], 9),
    (8, 4, [1, 4, 7], 5),
])
def test_plan_keys_a_shorter_last_gap_on_its_own_step(n_source, step, tail, middle):
    """The keys, the short last gap's own keys and the samples in the middle of the first gap (how
    the motion starts) and of the last gap (where it is at least two samples long and has two keys
    before it: how the motion ends)."""
    plan = plan_retime(n_source, step, 1.0)
    assert plan.tail.tolist() == tail
    assert plan.start_samples[3] == step // 2
    assert (plan.end_samples or (None,) * 4)[3] == middle
    assert plan.samples_read == sorted(set(plan.keys.tolist()) | set(tail) | {step // 2} | ({middle} if middle else set()))


@pytest.mark.parametrize("n_source", [17, 19])
def test_a_retime_ends_at_rest_where_the_source_eases_into_its_last_frame(n_source):
    """A sheet sliding at constant deceleration to a stop at the last sample, keyed every 4th
    (19 samples: a last gap of 2, keyed by its own sequence): the sample in the middle of the last
    gap tells the retime to end at rest (``end_of_motion``), and the last gap's half samples are
    the motion to float32 rounding. The keys' end reads the same stop from the last three keys (the
    sheet moves rigidly: its screw's slowing end, core.splines.slowing_screw_correction, λ = 0) and
    is the motion too; with the screw's linear end (before) it was off by (s³ − s²) × the gap's move."""
    flat, triangles = grid(5, 5)
    last = n_source - 1
    velocity = np.array([0.4, 0.1, -0.3])
    source = np.array([flat + velocity * (t - t * t / (2 * last)) for t in range(n_source)])
    out = retime(source, triangles, step=4, speed=0.5)
    half = 2 * (last - 1) + 1  # output sample at source time last − 0.5
    truth = flat + velocity * ((last - 0.5) - (last - 0.5) ** 2 / (2 * last))
    np.testing.assert_allclose(out[half], truth, atol=1e-6)
    slowed = retime(source, triangles, step=4, speed=0.5, end="keys")[half]
    np.testing.assert_allclose(slowed, truth, atol=1e-6)


@pytest.mark.parametrize("n_source", [18, 19, 20, 23])
def test_a_shorter_last_gap_keeps_the_timing_of_a_steady_motion(n_source):
    """A sheet turning and sliding at constant velocity (a screw: exp(t ξ)), keyed every 4th sample
    with a last gap of 1–3 samples: the in-betweens of that gap and of the one before it are the
    motion (the sequence knows the last gap is shorter; the short gap's own sequence is evenly
    keyed); read as a whole-step gap they were up to 2.5 % of its side off, in both."""
    from scipy.linalg import expm

    rest, triangles = grid(8)
    xi = np.zeros((4, 4))
    xi[:3, :3] = [[0, -0.05, 0.02], [0.05, 0, -0.01], [-0.02, 0.01, 0]]
    xi[:3, 3] = [0.1, 0.02, 0.03]
    motion = [expm(t * xi) for t in np.arange(4 * n_source - 3) / 4]
    moved = np.stack([rest @ m[:3, :3].T + m[:3, 3] for m in motion])  # every quarter sample
    plan = plan_retime(n_source, 4, 0.25)
    last_two = plan.outputs(range(plan.n_gaps - 2, plan.n_gaps))
    result = retime(moved[::4], triangles, step=4, speed=0.25, gaps=range(plan.n_gaps - 2, plan.n_gaps))
    assert len(result) == len(last_two) >= 4 + 16
    np.testing.assert_allclose(result, moved[list(last_two)], rtol=0, atol=1e-6)


@pytest.mark.parametrize("middle", [2, 6])
def test_a_middle_sample_that_is_no_pose_is_refused(middle):
    """Samples 2 and 6 of 9 keyed every 4th tell how the motion leaves the first key and reaches
    the last: one that is no pose (a non-finite coordinate) is refused, naming it, as a key is
    (before, its NaN distance to both choices chose the start from rest and the end at the keys'
    velocity without a word)."""
    samples, triangles = rolling_sheet()
    samples = samples.copy()
    samples[middle, 3, 0] = np.nan
    with pytest.raises(MeshError, match=f"sample {middle}: vertex 3 has a non-finite coordinate"):
        retime(samples, triangles, step=4, speed=1.0)


def test_plan_snaps_whole_frames():
    plan = plan_retime(4, 1, 0.1)  # 30 * 0.1 is 3.0000000000000004 in floating point
    assert plan.n_out == 31 and plan.exact_keys[30] == 3 and plan.exact_keys[10] == 1


@pytest.mark.parametrize("n_source, step, speed", [(1, 1, 1.0), (5, 5, 1.0), (9, 0, 1.0), (9, 2, 0.0),
                                                   (9, 2, float("nan")), (9, 2.5, 1.0)])
def test_plan_rejects(n_source, step, speed):
    with pytest.raises(MeshError):
        plan_retime(n_source, step, speed)


@pytest.mark.parametrize("n_source, step, remedy", [
    (5, 5, "a step of at most 4 or at least 6 frames"),
    (1, 1, "at least 2 frames"),
    # no range of Blender's frames is that long: only a smaller step makes two keys (before: "use
    # at least 2147483648 frames")
    (9, 2**31 - 1, "a step of at most 8"),
    (2 * 1_048_574 + 1, 2 * 1_048_574 + 1, "a step of at most 2097148"),
    (1, 2**31 - 1, "at least 2 frames and a smaller step")])
def test_a_step_that_leaves_one_key_is_refused_with_a_remedy_blender_allows(n_source, step, remedy):
    """Each remedy offered makes two keys and fits in Blender's frames (2,097,149 of them)."""
    with pytest.raises(MeshError, match=rf"with step {step} give fewer than two key poses: use {remedy}\.$"):
        plan_retime(n_source, step, 1.0)
    # played in two frames (speed: the range): the keys alone
    for smaller in re.findall(r"a step of at most (\d+)", remedy):
        assert len(plan_retime(n_source, int(smaller), n_source - 1).keys) == 2
    for frames in re.findall(r"at least (\d+) frames$", remedy):
        assert int(frames) <= 2 * 1_048_574 + 1 and len(plan_retime(int(frames), step, int(frames) - 1).keys) == 2


@pytest.mark.parametrize("speed, count", [(1e-7, "80,000,001"), (1e-300, "8e+300"), (8 / 1_048_574, "1,048,575")])
def test_plan_refuses_more_frames_than_blender_plays(speed, count):
    """A speed that would give more output frames than Blender's last frame is refused before the
    plan's arrays are made: at 1e-7 over 96 samples they filled the memory and the system killed
    the process (a farm node's other jobs with it)."""
    with pytest.raises(MeshError, match=re.escape(f"gives {count} output frames, more than 1,048,574")):
        plan_retime(9, 4, speed)
    assert plan_retime(9, 4, 8 / 1_048_573).n_out == 1_048_574


@pytest.mark.parametrize("speed", [8.001, 100.0, float(np.finfo(np.float32).max)])
def test_plan_refuses_a_speed_that_leaves_one_output_frame(speed):
    """Over 9 samples a speed above 8 plays the first sample alone (the largest float32, what
    Blender keeps for an infinite speed, too): refused, naming the largest speed that plays two
    (before, a one-frame "retime" was planned)."""
    with pytest.raises(MeshError, match=re.escape("gives one output frame (the first), and a retime needs at "
                                                  "least two: use a speed of at most 8 ")):
        plan_retime(9, 4, speed)
    assert plan_retime(9, 4, 8.0).n_out == 2


def test_kept_frames_exact_and_inbetweens_from_the_sequence():
    source, triangles = rolling_sheet()
    result = retime(source, triangles, step=4, speed=0.5)
    assert result.shape == (17, source.shape[1], 3) and result.dtype == np.float32
    for k, frame in enumerate(range(0, 9)):
        if frame % 4 == 0:
            np.testing.assert_array_equal(result[2 * k], source[frame])
    # the sheet is already rolling at its first frame: the start is taken from the keys
    assert start_of_motion([source[0], source[4], source[8]], source[2], 0.5) == "keys"
    sequence = SequenceInterpolator([source[f].astype(np.float64) for f in (0, 4, 8)], triangles, start="keys")
    factors = np.arange(1, 8) / 8  # each gap's seven in-betweens, asked together
    # to round-off (see test_chunks_concatenate_to_round_off): float32 of the same poses
    np.testing.assert_allclose(result[3], sequence.poses(0, factors)[2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(result[11], sequence.poses(1, factors)[2], rtol=0, atol=1e-6)
    # The dropped frames come back close to the source (a smooth roll).
    assert np.abs(result[2] - source[1]).max() < 0.02


@pytest.mark.parametrize("n_frames", [13, 14])  # 14: a last gap of one frame, keyed by its own sequence
def test_chunks_concatenate_to_round_off(n_frames):
    """Chunks of a retime (farm tasks) are the whole retime's frames, to round-off: on AVX-512
    machines NumPy's and OpenBLAS's small products choose kernels by memory alignment, so the
    same computation in another process (or later in this one) can differ in the last bit."""
    source, triangles = rolling_sheet(n_frames=n_frames)
    plan = plan_retime(n_frames, 2, 0.7)
    whole = retime(source, triangles, step=2, speed=0.7)
    for count in (2, 7):  # 7 chunks of 6 gaps: one chunk is empty
        parts = [retime(source, triangles, step=2, speed=0.7, gaps=plan.chunk(i, count)) for i in range(count)]
        assert sum(len(part) for part in parts) == plan.n_out
        np.testing.assert_allclose(np.concatenate(parts), whole, rtol=0, atol=1e-6)
    indices = [index for index, _ in iter_retime(source, triangles, plan, range(2, 4))]
    assert indices == list(plan.outputs(range(2, 4)))


def test_a_retime_leaves_the_callers_frames_writable():
    """A source given as a list of the caller's float64 frames: the retime reads them and leaves
    them as they were, writable (the caller fills them again with the next shot); float32 frames
    are converted, and their conversions kept by the sequence without a copy of their own."""
    source, triangles = rolling_sheet()
    frames = [frame.astype(np.float64) for frame in source]
    plan = plan_retime(len(frames), 4, 0.5)
    dict(iter_retime(frames, triangles, plan))
    assert all(frame.flags.writeable for frame in frames)
    frames[0][0, 0] = 1.0  # the caller's array is still its own to write


def test_obj_round_trip(tmp_path):
    vertices, triangles = grid(4)
    path = write_obj(tmp_path / "sheet.obj", vertices, triangles)
    read_vertices, read_triangles = read_obj(path)
    np.testing.assert_allclose(read_vertices, vertices, atol=1e-9)
    np.testing.assert_array_equal(read_triangles, triangles)
    (tmp_path / "quad.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 -1//1\n")
    assert read_obj(tmp_path / "quad.obj")[1].tolist() == [[0, 1, 2], [0, 2, 3]]
    (tmp_path / "bad.obj").write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.raises(MeshError, match="line 2"):
        read_obj(tmp_path / "bad.obj")


def test_command_chunks_and_merge(tmp_path, capsys):
    source, triangles = rolling_sheet(n_frames=9, nx=6)
    cache = write_pc2(tmp_path / "in.pc2", source, start=10.0)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    common = [str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5"]
    assert main(["retime", *common, "-o", str(tmp_path / "whole.pc2")]) == 0
    assert "retime: sample 17/17" in capsys.readouterr().err
    parts = [tmp_path / f"part{i}.pc2" for i in (1, 2, 3)]
    for i, part in enumerate(parts, 1):
        assert main(["retime", *common, "--chunk", f"{i}/3", "-q", "-o", str(part)]) == 0
    assert main(["merge", *map(str, parts), "-o", str(tmp_path / "merged.pc2")]) == 0
    assert (tmp_path / "merged.pc2").read_bytes() == (tmp_path / "whole.pc2").read_bytes()
    whole = read_pc2(tmp_path / "whole.pc2")
    assert (whole.start, whole.sampling, whole.n_samples) == (10.0, 1.0, 17)
    np.testing.assert_array_equal(whole.positions[8], source[4])
    assert main(["retime", *common, "--gaps", "1:2", "--start", "1", "-q", "-o", str(tmp_path / "gap.pc2")]) == 0
    gap = read_pc2(tmp_path / "gap.pc2")
    np.testing.assert_array_equal(gap.positions, whole.positions[8:17])  # the last key is in the last gap
    assert gap.start == 1 + 8


def test_command_errors_are_one_line(tmp_path):
    source, triangles = rolling_sheet(n_frames=5, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    write_obj(tmp_path / "other.obj", *grid(4))
    result = subprocess.run([sys.executable, "-m", "core", "retime", str(cache), "--topology",
                             str(tmp_path / "other.obj"), "--step", "2", "-o", str(tmp_path / "out.pc2")],
                            cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip() == (f"error: '{tmp_path / 'other.obj'}' has 16 vertices but '{cache}' has 25 "
                                     "points: export the OBJ from the same mesh, without modifiers that change "
                                     "its vertices.")
    assert not (tmp_path / "out.pc2").exists()


def test_command_names_a_topology_that_is_no_obj(tmp_path):
    """The cache and the OBJ swapped on the command line (or an Alembic or a .blend given as the
    topology): one error line saying that the file holds binary data and what it is, exit status 2,
    nothing written (before: "line 1830 cannot be read (invalid literal for int() …)" quoting the
    binary bytes that happened to start with 'f', or "has no faces")."""
    source, triangles = rolling_sheet(n_frames=5, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    alembic = tmp_path / "shot.abc"
    alembic.write_bytes(b"Ogawa\xff\x00\x01" + bytes(64))
    for given, kind in ((cache, ", a PC2 point cache"), (alembic, ", an Alembic cache")):
        result = subprocess.run([sys.executable, "-m", "core", "retime", str(cache), "--topology", str(given),
                                 "--step", "2", "-q", "-o", str(tmp_path / "out.pc2")],
                                cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert result.returncode == 2 and not (tmp_path / "out.pc2").exists()
        assert result.stderr.splitlines() == [
            f"error: '{given}' is not an OBJ file: it holds binary data{kind}. The topology is a Wavefront OBJ "
            "(text: 'v x y z' and 'f a b c' lines) exported from the mesh the cache moves; check that the cache "
            "and the OBJ are not swapped."]
    assert main(["retime", str(cache), "--topology", str(topology), "--step", "2", "-q",
                 "-o", str(tmp_path / "out.pc2")]) == 0


def test_command_says_what_it_works_on_while_no_line_comes(tmp_path, capsys, monkeypatch):
    """A retime says what was read, and how long it took, before the first in-between's line, its
    seconds counted from the start; and while no line comes for ``HEARTBEAT_SECONDS`` (at 100k
    vertices: 3 s of reading before the first line, 11 s between the lines of samples 1 and 2, a
    gap's in-betweens computed together) it says what it is working on, in whole lines. ``-q``
    prints none of them. Slowness is planted here (the OBJ reader and each in-between 0.3 s)."""
    import core.__main__ as command

    source, triangles = rolling_sheet(n_frames=9, nx=6)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    common = ["retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5"]
    monkeypatch.setattr(command, "HEARTBEAT_SECONDS", 1e9, raising=False)
    assert main([*common, "-o", str(tmp_path / "out.pc2")]) == 0
    lines = capsys.readouterr().err.splitlines()
    read = len(plan_retime(9, 4, 0.5).samples_read)
    assert re.fullmatch(rf"retime: read {read} of 9 samples \(the keys and what they need\), 36 points, \d+\.\d s; "
                        r"in-betweening 17 sample\(s\) \(key gaps 0:2 of 2\)", lines[0]), lines
    assert lines[1].startswith("retime: sample 1/17 ") and lines[-1].startswith("retime: sample 17/17 "), lines

    real_read_obj, real_iter_retime = command.read_obj, command.iter_retime

    def slow_read_obj(path):
        time.sleep(0.3)
        return real_read_obj(path)

    def slow_iter_retime(*args, **kwargs):
        for item in real_iter_retime(*args, **kwargs):
            time.sleep(0.3 if item[0] < 2 else 0.0)
            yield item

    monkeypatch.setattr(command, "HEARTBEAT_SECONDS", 0.05, raising=False)
    monkeypatch.setattr(command, "read_obj", slow_read_obj)
    monkeypatch.setattr(command, "iter_retime", slow_iter_retime)
    assert main([*common, "-o", str(tmp_path / "slow.pc2")]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert lines[0].startswith(f"retime: working on reading '{cache}' and '{topology}', "), lines
    first = next(i for i, line in enumerate(lines) if line.startswith("retime: sample 1/17 "))
    assert any(line.startswith("retime: working on sample 2/17 (gap 1/2), ") for line in lines[first:]), lines
    assert all(line.startswith("retime: ") for line in lines), lines
    seconds = [float(re.search(r", (\d+\.\d) s\b", line).group(1)) for line in lines]
    assert seconds == sorted(seconds) and seconds[-1] >= 0.9, lines
    assert main([*common, "-q", "-o", str(tmp_path / "quiet.pc2")]) == 0
    assert capsys.readouterr().err == ""


def test_command_names_an_unexpected_failure_before_its_traceback(tmp_path):
    """A failure that is no refusal (a defect, planted here in the OBJ reader) exits with status 1
    and Python's traceback, after one line naming the error, first on stderr, which a farm's log
    search finds (before: the traceback alone, the cause on its last line)."""
    source, triangles = rolling_sheet(n_frames=5, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    planted = ("import sys, core.__main__ as command\n"
               "def read_obj(path):\n    raise ZeroDivisionError('planted defect')\n"
               "command.read_obj = read_obj\nsys.exit(command.main(sys.argv[1:]))")
    result = subprocess.run([sys.executable, "-c", planted, "retime", str(cache), "--topology", str(topology),
                             "--step", "2", "-q", "-o", str(tmp_path / "out.pc2")],
                            cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 1 and not (tmp_path / "out.pc2").exists()
    lines = result.stderr.splitlines()
    assert lines[0] == ("retime: failed: ZeroDivisionError: planted defect (unexpected: the traceback follows; "
                        "please report it)")
    assert lines[1] == "Traceback (most recent call last):" and lines[-1] == "ZeroDivisionError: planted defect"


def test_command_refuses_an_output_larger_than_the_memory(tmp_path, capsys, monkeypatch):
    """An output that would take more than half the memory available, or a mesh whose in-betweens
    need more than there is, is refused before any work, with the way out (chunks); the same job
    in chunks that fit runs."""
    import core.resources

    source, triangles = rolling_sheet(n_frames=9, nx=6)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    working = 36 * 12_000  # WORKING_BYTES_PER_VERTEX for 36 vertices
    whole = 8001 * 36 * 12  # speed 0.001: 8,001 samples of 36 points, float32 (3.5 MB)
    monkeypatch.setattr(core.resources, "available_memory", lambda: 10**6)
    common = ["retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.001", "-q"]
    assert main([*common, "-o", str(tmp_path / "out.pc2")]) == 2
    assert "is 8,001 poses of 36 vertices" in capsys.readouterr().err and not (tmp_path / "out.pc2").exists()
    assert whole / 8 < 0.5 * 10**6 < whole and working < 10**6
    assert main([*common, "--chunk", "1/8", "-o", str(tmp_path / "part.pc2")]) == 0
    monkeypatch.setattr(core.resources, "available_memory", lambda: working - 1)
    assert main([*common, "--chunk", "1/8", "-o", str(tmp_path / "part2.pc2")]) == 2
    assert "In-betweening this cache (36 vertices) needs about" in capsys.readouterr().err


def test_command_counts_the_largest_gaps_in_betweens_beside_the_output(tmp_path, capsys, monkeypatch):
    """A gap's in-betweens are asked at once (float64, with their working copies: 54 bytes a vertex,
    INBETWEEN_BYTES_PER_VERTEX) while the output fills: speed 0.01 keyed every 4th of 9 samples asks
    399 in-betweens of each gap. The output alone (801 samples of 36 points, float32: 346 kB) is within
    half of 1.4 MB; with a gap's in-betweens (776 kB) it is not, and is refused before any work (it ran
    before); at speed 0.05 both fit."""
    import core.resources

    source, triangles = rolling_sheet(n_frames=9, nx=6)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    monkeypatch.setattr(core.resources, "available_memory", lambda: 1.4e6)
    common = ["retime", str(cache), "--topology", str(topology), "--step", "4", "-q"]
    assert main([*common, "--speed", "0.01", "-o", str(tmp_path / "out.pc2")]) == 2
    err = capsys.readouterr().err
    assert "is 801 poses of 36 vertices, 0.00112 GB, 0.000776 GB of it its in-betweens while they are made" in err, err
    assert not (tmp_path / "out.pc2").exists()
    assert main([*common, "--speed", "0.05", "-o", str(tmp_path / "out.pc2")]) == 0


def test_command_refuses_an_output_the_disk_has_no_room_for_before_any_work(tmp_path, capsys, monkeypatch):
    """A disk with less free space than the output takes: the retime is refused before its
    in-betweens (before, they were all computed and the write failed at the end: "No space left on
    device"), and so is a chunk whose merged output (--merged-output) would not fit; with room for
    the file to the byte it runs."""
    import core.__main__ as command
    import core.point_cache

    source, triangles = rolling_sheet(n_frames=9, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    common = ["retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5", "-q"]
    whole = 32 + 17 * 25 * 12  # 17 samples of 25 points
    in_betweens = []
    real_retime = command.iter_retime
    monkeypatch.setattr(command, "iter_retime", lambda *a, **k: in_betweens.append(1) or real_retime(*a, **k))
    monkeypatch.setattr(core.point_cache, "free_space", lambda folder: whole - 1, raising=False)
    assert main([*common, "-o", str(tmp_path / "out.pc2")]) == 2
    assert capsys.readouterr().err.strip() == (
        f"error: Cannot write '{tmp_path / 'out.pc2'}': it takes {whole / 1e6:.3g} MB and the disk holding "
        f"'{tmp_path}' has {(whole - 1) / 1e6:.3g} MB free. Free some space there or give an output on another disk.")
    assert main([*common, "--chunk", "1/2", "-o", str(tmp_path / "part1.pc2"),
                 "--merged-output", str(tmp_path / "new" / "out.pc2")]) == 2
    assert capsys.readouterr().err.startswith("error: --merged-output (the file the chunks will be merged into): "
                                              f"Cannot write '{tmp_path / 'new' / 'out.pc2'}'")
    assert not in_betweens and sorted(p.name for p in tmp_path.iterdir()) == ["in.pc2", "sheet.obj"]
    monkeypatch.setattr(core.point_cache, "free_space", lambda folder: whole)
    assert main([*common, "-o", str(tmp_path / "out.pc2")]) == 0
    assert (tmp_path / "out.pc2").stat().st_size == whole and in_betweens


@pytest.mark.parametrize("euid, blocks, expected", [(1000, 100, 30 * 4096), (0, 100, 40 * 4096), (1000, 0, None)])
def test_free_space_is_what_the_user_may_write_or_none_where_the_disk_reports_no_size(tmp_path, monkeypatch,
                                                                                       euid, blocks, expected):
    """The free space of a disk reporting 40 free blocks of 4,096 bytes, 10 of them kept back for
    root: 30 blocks for a user, 40 for root; a file system reporting 0 blocks of 0 (some network
    and FUSE mounts) is not checked, and nor is one whose query fails (ENOSYS: a FUSE mount without
    statfs; ESTALE: a stale NFS handle), where the write itself says what is wrong (before, the
    failed query refused the retime: "error: Function not implemented")."""
    import errno

    import core.point_cache as point_cache

    stats = type("Stats", (), {"f_blocks": blocks, "f_bfree": 40 if blocks else 0,
                               "f_bavail": 30 if blocks else 0, "f_frsize": 4096})
    monkeypatch.setattr(os, "statvfs", lambda path: stats, raising=False)
    monkeypatch.setattr(os, "geteuid", lambda: euid, raising=False)
    assert point_cache.free_space(tmp_path) == expected
    if expected is None:
        point_cache.check_disk_space(tmp_path / "out.pc2", 10**12)  # no size reported: unchecked
    else:  # a file that fits to the byte is written, one byte more is refused
        point_cache.check_disk_space(tmp_path / "out.pc2", expected)
        with pytest.raises(MeshError, match="MB free"):
            point_cache.check_disk_space(tmp_path / "out.pc2", expected + 1)
    for code in (errno.ENOSYS, errno.ESTALE):
        def failing(path, code=code):
            raise OSError(code, os.strerror(code), str(path))

        monkeypatch.setattr(os, "statvfs", failing, raising=False)
        monkeypatch.setattr(point_cache.shutil, "disk_usage", failing)
        assert point_cache.free_space(tmp_path) is None
        point_cache.check_disk_space(tmp_path / "out.pc2", 10**12)  # unchecked: no refusal


def test_a_disk_refusal_says_an_output_of_gigabytes_in_gigabytes(tmp_path, monkeypatch):
    """10,000 samples of 100,000 points (12.0 GB) on a disk with 3.4 GB free: said in GB, as the
    memory refusals say it (before: "1.2e+04 MB" and "3.4e+03 MB"); a small output stays in MB."""
    import core.point_cache as point_cache

    monkeypatch.setattr(point_cache, "free_space", lambda folder: 3_400_000_000)
    with pytest.raises(MeshError, match=r"it takes 12\.0 GB and the disk holding .* has 3\.4 GB free\. "):
        point_cache.check_disk_space(tmp_path / "out.pc2", point_cache.pc2_size(100_000, 10_000))
    monkeypatch.setattr(point_cache, "free_space", lambda folder: 999_000)
    with pytest.raises(MeshError, match=r"it takes 1\.2 MB and the disk holding .* has 0\.999 MB free\. "):
        point_cache.check_disk_space(tmp_path / "out.pc2", point_cache.pc2_size(1_000, 100))
    with pytest.raises(MeshError, match=r"it takes 1\.0 GB and .* has 0\.999 MB free\. "):  # not "1e+03 MB"
        point_cache.check_disk_space(tmp_path / "out.pc2", 999_600_000)


def test_command_names_a_broken_sample_of_the_cache(tmp_path, capsys):
    """A cache with NaN in a sample the retime reads (a simulation that exploded): the error names
    that sample and its frame in the cache's own numbering, before any work; NaN in a sample the
    retime does not read (between keys) does not stop it."""
    source, triangles = rolling_sheet(n_frames=9, nx=5)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    raw = write_pc2(tmp_path / "good.pc2", source, start=10.0).read_bytes()
    header, data = raw[:32], np.frombuffer(raw[32:], dtype="<f4").reshape(source.shape).copy()
    for sample, expected in ((4, "sample 5 (frame 14) has non-finite"), (5, None)):
        broken = data.copy()
        broken[sample, 3] = np.nan
        (tmp_path / "bad.pc2").write_bytes(header + broken.tobytes())
        code = main(["retime", str(tmp_path / "bad.pc2"), "--topology", str(topology), "--step", "4",
                     "-q", "-o", str(tmp_path / "out.pc2")])
        err = capsys.readouterr().err
        if expected:
            assert code == 2 and expected in err and not (tmp_path / "out.pc2").exists()
        else:
            assert code == 0 and np.isfinite(read_pc2(tmp_path / "out.pc2").positions).all()


def test_chunks_of_a_cache_sampled_in_tenths_merge_into_the_single_run(tmp_path):
    """A cache starting at frame 1.1, one sample every 0.1 frame: seven chunks merge into the
    single run's file byte for byte (before, a chunk's single-precision start read one step off
    the sum of the ones before, and the merge refused the chunks as out of order); a chunk folder
    with '#' in its name (shot#12/) is not renumbered with the chunks."""
    source, triangles = rolling_sheet(n_frames=41, nx=5)  # 10 gaps: every chunk has one
    cache = write_pc2(tmp_path / "in.pc2", source, start=1.1, sampling=0.1)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    common = ["retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5", "-q"]
    assert main([*common, "-o", str(tmp_path / "whole.pc2")]) == 0
    folder = tmp_path / "shot#12"
    for i in range(1, 8):
        assert main([*common, "--chunk", f"{i}/7", "-o", str(folder / f"chunk{i}.pc2")]) == 0
    assert main(["merge", "--numbered", str(folder / "chunk#.pc2"), "--count", "7",
                 "-o", str(tmp_path / "merged.pc2")]) == 0
    assert (tmp_path / "merged.pc2").read_bytes() == (tmp_path / "whole.pc2").read_bytes()
    # a missing chunk is still a whole sample or more off
    parts = [str(folder / f"chunk{i}.pc2") for i in (1, 2, 4)]
    assert main(["merge", *parts, "-o", str(tmp_path / "gap.pc2")]) == 2


@pytest.mark.parametrize("start, sampling", [(100_000.0, 0.1), (800_000.0, 0.01)])
def test_command_chunks_far_from_frame_zero(tmp_path, start, sampling):
    """Chunks of a cache sampled in tenths from frame 100,000, or in hundredths from 800,000 (where
    a PC2's single-precision start frame is six samples coarse): their stamps say which key gaps
    they hold, and they merge into the single run's file byte for byte (before, the merge refused
    them as out of order: "'chunk2.pc2' starts at frame 100002, expected 100002")."""
    source, triangles = rolling_sheet(n_frames=33, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source, start=start, sampling=sampling)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    settings = [str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5"]
    assert main(["retime", *settings, "-q", "-o", str(tmp_path / "whole.pc2")]) == 0
    for i in (1, 2, 3):
        assert main(["retime", *settings, "-q", "--chunk", f"{i}/3", "-o", str(tmp_path / f"chunk{i}.pc2")]) == 0
    assert main(["merge", "--numbered", str(tmp_path / "chunk#.pc2"), "--count", "3", "-o",
                 str(tmp_path / "merged.pc2"), "--retime", *settings]) == 0
    assert (tmp_path / "merged.pc2").read_bytes() == (tmp_path / "whole.pc2").read_bytes()


def test_a_chunk_is_stamped_with_the_samples_it_was_computed_from(tmp_path, monkeypatch, capsys):
    """An input cache written over in place while a chunk is computed (a simulation cached again
    under its name while the job runs; exporters rewrite the file): the chunk's stamp is of the
    samples its in-betweens were computed from, so the merge given the new cache refuses it beside
    chunks computed from that (before, the stamp was read from the file after the work, the new
    take's: a merge of two chunks run before and two after wrote 32 samples of one take and 33 of
    the other, exit 0)."""
    import core.__main__ as command

    take_a, triangles = rolling_sheet(n_frames=17, nx=5)
    take_b = take_a * np.array([1, 1, -1], dtype=np.float32)  # the sheet rolling the other way
    cache = write_pc2(tmp_path / "cloth.pc2", take_a)
    topology = write_obj(tmp_path / "cloth.obj", take_a[0], triangles)
    settings = [str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5"]
    chunks = [str(tmp_path / f"chunk{i}.pc2") for i in (1, 2)]
    computing = command.iter_retime

    def cached_again_meanwhile(*args, **options):
        for done, output in enumerate(computing(*args, **options)):
            if done == 1:
                with open(cache, "r+b") as stream:  # the same file, written over
                    stream.seek(32)
                    stream.write(take_b.tobytes())
            yield output

    monkeypatch.setattr(command, "iter_retime", cached_again_meanwhile)
    assert main(["retime", *settings, "-q", "--chunk", "1/2", "-o", chunks[0]]) == 0
    monkeypatch.undo()
    np.testing.assert_array_equal(read_pc2(cache).positions, take_b)
    assert main(["retime", *settings, "-q", "--chunk", "2/2", "-o", chunks[1]]) == 0
    assert main(["merge", *chunks, "-o", str(tmp_path / "out.pc2"), "--retime", *settings]) == 2
    assert "or the input cache or topology was written over since the chunk was computed" in capsys.readouterr().err
    assert not (tmp_path / "out.pc2").exists()


def test_merge_refuses_to_write_over_the_retimes_input(tmp_path, capsys):
    """A merge whose output names the input cache or the OBJ of the retime it checks the chunks
    against (a job's OutputCache set to its InputCache, directly or through a link): refused,
    nothing written (before, the simulation was replaced by its retime, exit 0)."""
    source, triangles = rolling_sheet(n_frames=9, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    (tmp_path / "link.pc2").symlink_to(cache)
    settings = [str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5"]
    chunks = [str(tmp_path / f"chunk{i}.pc2") for i in (1, 2)]
    for i, chunk in enumerate(chunks, 1):
        assert main(["retime", *settings, "-q", "--chunk", f"{i}/2", "-o", chunk]) == 0
    before = {path: path.read_bytes() for path in (cache, topology)}
    for output, what in ((cache, "the input cache of the retime"), (tmp_path / "link.pc2", "the input cache"),
                         (topology, "the topology OBJ")):
        assert main(["merge", *chunks, "-o", str(output), "--retime", *settings]) == 2
        assert f"is {what}" in capsys.readouterr().err
    assert {path: path.read_bytes() for path in (cache, topology)} == before


def test_command_output_names_that_are_no_text(tmp_path, monkeypatch):
    """A file name whose bytes are not text in the system's encoding (a Latin-1 'café' on a UTF-8
    worker): the commands print it escaped, as Python prints it on stderr, and exit 0 (before,
    printing it on a stdout that refuses such characters raised UnicodeEncodeError after the file
    was written: a traceback, status 1, and the farm task failed on every retry)."""
    import io

    source, triangles = rolling_sheet(n_frames=5, nx=4)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    name = os.fsdecode(os.fsencode(str(tmp_path)) + b"/caf\xe9.pc2")
    if "\udce9" not in name:
        pytest.skip("this system decodes every file name")
    stdout = io.TextIOWrapper(io.BytesIO(), encoding="utf-8", errors="strict")  # a UTF-8 locale's stdout
    monkeypatch.setattr(sys, "stdout", stdout)
    assert main(["retime", str(cache), "--topology", str(topology), "--step", "2", "-q", "-o", name]) == 0
    assert main(["info", name]) == 0
    assert main(["merge", name, "-o", name[:-4] + " merged.pc2"]) == 0
    stdout.flush()
    printed = stdout.buffer.getvalue().decode()
    assert "wrote " + str(tmp_path) + "/caf\\udce9.pc2: 5 of 5 samples" in printed
    assert str(tmp_path) + "/caf\\udce9.pc2: 5 samples" in printed
    assert "caf\\udce9 merged.pc2: 5 samples from frame 0" in printed
    assert sorted(os.listdir(os.fsencode(str(tmp_path)))) == [b"caf\xe9 merged.pc2", b"caf\xe9.pc2", b"in.pc2",
                                                               b"sheet.obj"]


def test_command_inputs_checked_before_any_work(tmp_path, capsys):
    """What a retime cannot write or read is refused in one line before the in-betweens are
    computed (before, after all of them, or as a traceback)."""
    source, triangles = rolling_sheet(n_frames=5, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    common = ["retime", str(cache), "--topology", str(topology), "--step", "2", "-q"]
    raw = cache.read_bytes()
    (tmp_path / "still.pc2").write_bytes(raw[:24] + np.float32(0.0).tobytes() + raw[28:])  # sampling 0
    (tmp_path / "flat.obj").write_text("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    cases = [([*common, "--start", "1e39", "-o", str(tmp_path / "a.pc2")], "finite single-precision"),
             ([*common, "-o", str(tmp_path / "a.mdd")], "named as an MDD file"),
             (["retime", str(tmp_path / "still.pc2"), *common[2:], "-o", str(tmp_path / "a.pc2")],
              "invalid PC2 header"),
             (["retime", str(cache), "--topology", str(tmp_path / "flat.obj"), "--step", "2", "-o",
               str(tmp_path / "a.pc2")], "line 1 cannot be read (a vertex needs three coordinates)"),
             (["merge", str(cache), "--count", "2", "-o", str(tmp_path / "a.pc2")], "--count N goes with --numbered"),
             ([*common, "--offset", "-1", "-o", str(tmp_path / "a.pc2")], "--offset -1 must be 0 or positive"),
             ([*common, "--offset", "nan", "-o", str(tmp_path / "a.pc2")], "--offset nan must be 0 or positive")]
    for argv, message in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert message in err and "retime: sample" not in err, (argv, err)
        assert not (tmp_path / "a.pc2").exists() and not (tmp_path / "a.mdd").exists()
    # an output no file can be written to: said before the first in-between (whose progress, not
    # silenced here, would show it computed)
    for output, message in ((str(tmp_path) + "/", "is a folder, not a file"), (" ", "file name is empty"),
                            (str(topology / "out.pc2"), "is a file, not a folder")):
        assert main(["retime", str(cache), "--topology", str(topology), "--step", "2", "-o", output]) == 2
        err = capsys.readouterr().err
        assert message in err and "retime: sample" not in err, (output, err)


def test_obj_with_a_byte_order_mark(tmp_path):
    vertices, triangles = grid(3)
    path = write_obj(tmp_path / "sheet.obj", vertices, triangles)
    (tmp_path / "bom.obj").write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    read_vertices, read_triangles = read_obj(tmp_path / "bom.obj")
    np.testing.assert_allclose(read_vertices, vertices, atol=1e-9)
    np.testing.assert_array_equal(read_triangles, triangles)


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-16-be"])
def test_obj_saved_as_utf16_is_read(tmp_path, encoding):
    """An OBJ saved as UTF-16 with its byte-order mark (Windows PowerShell's ``>``, ``Out-File``) reads
    as the same mesh as its UTF-8 text (before, it was refused as binary data, its ASCII
    characters' NUL bytes taken for a swapped cache)."""
    vertices, triangles = grid(3)
    path = write_obj(tmp_path / "sheet.obj", vertices, triangles)
    mark = "" if encoding == "utf-16" else "\ufeff"  # "utf-16" writes its own
    (tmp_path / "wide.obj").write_bytes((mark + path.read_text(encoding="utf-8")).encode(encoding))
    read_vertices, read_triangles = read_obj(tmp_path / "wide.obj")
    np.testing.assert_array_equal(read_vertices, read_obj(path)[0])
    np.testing.assert_allclose(read_vertices, vertices, atol=1e-9)
    np.testing.assert_array_equal(read_triangles, triangles)


def exported_sheet(nx=6):
    """An OBJ export of a sheet as modellers leave it: quads, a hexagon whose first three corners
    are on one line (two quads joined by Dissolve) and a concave quad whose second corner is
    reflex. (rest ``(n, 3)``, polygons: lists of vertex indices, the hexagon first, the concave
    quad second.)"""
    x, y = np.meshgrid(np.linspace(0.0, 1.0, nx), np.linspace(0.0, 1.0, nx))
    rest = np.stack([x.ravel(), y.ravel(), np.zeros(nx * nx)], axis=1)
    quads = [[j * nx + i, j * nx + i + 1, (j + 1) * nx + i + 1, (j + 1) * nx + i]
             for j in range(nx - 1) for i in range(nx - 1)]
    hexagon = [0, 1, 2, nx + 2, nx + 1, nx]  # quads 0 and 1 without their shared edge
    concave = quads[2 * (nx - 1) + 2]
    a, b, c, d = (rest[i] for i in concave)
    rest[concave[1]] = 0.2 * a + 0.2 * c + 0.6 * d  # past the diagonal a–c: b is reflex
    return rest, [hexagon, concave] + [q for q in quads[2:] if q != concave]


def test_obj_polygons_are_split_without_flat_or_inverted_triangles(tmp_path):
    """Each polygon's triangles face its way, none with zero area, and cover it exactly (their
    areas add up to the polygon's, by the shoelace formula): a fan from the first corner of the
    hexagon has a triangle on its straight side, and one of the concave quad is inverted."""
    rest, polygons = exported_sheet()
    path = tmp_path / "export.obj"
    path.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in rest) + "vn 0 0 1\n"
                    + "".join("f " + " ".join(f"{i + 1}//1" for i in polygon) + "\n" for polygon in polygons))
    vertices, triangles = read_obj(path)
    np.testing.assert_array_equal(vertices, rest)
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    doubled = np.cross(b - a, c - a)[:, 2]  # the sheet lies in z = 0, every polygon facing +z
    start = 0
    for polygon in polygons:
        rows = slice(start, start + len(polygon) - 2)
        start = rows.stop
        assert set(triangles[rows].ravel()) == set(polygon)
        corners = rest[polygon]
        shoelace = np.sum(corners[:, 0] * np.roll(corners[:, 1], -1) - np.roll(corners[:, 0], -1) * corners[:, 1])
        assert doubled[rows].min() > 1e-3 * shoelace
        np.testing.assert_allclose(doubled[rows].sum(), shoelace, rtol=1e-12)
    assert start == len(triangles)
    # a convex quad keeps the fan from its first corner
    assert triangles[-2:].tolist() == [[polygons[-1][0], *polygons[-1][1:3]], [polygons[-1][0], *polygons[-1][2:4]]]


def test_command_retimes_a_cache_on_an_exported_topology_with_ngons(tmp_path):
    """The retime runs on an OBJ whose hexagon has corners on one line (refused as a zero-area
    triangle when split from its first corner), its kept frames exactly the source's."""
    rest, polygons = exported_sheet()
    frames = [rest]  # flat at first, where the hexagon's straight side is straight, then rolling up
    for t in np.linspace(0.25, 2.0, 8):
        radius = 1.0 / t
        theta = rest[:, 0] / radius
        frames.append(np.stack([radius * np.sin(theta), rest[:, 1], radius * (1 - np.cos(theta))], axis=1))
    source = np.array(frames, dtype=np.float32)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = tmp_path / "export.obj"
    topology.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in rest)
                        + "".join("f " + " ".join(str(i + 1) for i in polygon) + "\n" for polygon in polygons))
    assert main(["retime", str(cache), "--topology", str(topology), "--step", "4", "--speed", "0.5", "-q",
                 "-o", str(tmp_path / "out.pc2")]) == 0
    out = read_pc2(tmp_path / "out.pc2").positions
    np.testing.assert_array_equal(out[::8], source[::4])


def test_info_and_retime_read_an_mdds_own_times(tmp_path, capsys):
    """``info`` prints an MDD's times (before: "start 0, sampling 1", read as a second per frame);
    a retime of one whose frames are unevenly spaced says it retimes them as if they were not."""
    import struct

    source, triangles = rolling_sheet(n_frames=9, nx=5)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    for name, times in (("even.mdd", np.arange(1, 10) / 24.0), ("uneven.mdd", np.r_[np.arange(1, 6) / 24.0, 0.5, 1, 2, 3])):
        data = struct.pack(">ii", 9, source.shape[1]) + times.astype(">f4").tobytes() + source.astype(">f4").tobytes()
        (tmp_path / name).write_bytes(data)
        assert main(["info", str(tmp_path / name)]) == 0
        out = capsys.readouterr().out
        assert "times 0.0416667 to" in out and ("every 0.0416667 s" in out) == (name == "even.mdd")
        assert main(["retime", str(tmp_path / name), "--topology", str(topology), "--step", "4", "-q",
                     "-o", str(tmp_path / f"{name}.pc2")]) == 0
        err = capsys.readouterr().err
        assert ("retime: warning [frame_times]: the frame times of" in err) == (name == "uneven.mdd"), err
        assert ("retime: 1 warning(s): 1 frame_times" in err) == (name == "uneven.mdd"), err


@pytest.mark.parametrize("times", [np.zeros(9), np.arange(9, 0, -1) / 24.0], ids=["all_at_one_time", "backwards"])
def test_an_mdd_whose_times_do_not_increase_is_warned(tmp_path, capsys, times):
    """Frames at one time (all zeros) or going back in time are evenly spaced by their differences
    alone (before: no warning, retimed in the file's order as a forward motion); they are said as
    uneven times are, by ``info`` and by a retime."""
    import struct

    source, triangles = rolling_sheet(n_frames=9, nx=5)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    path = tmp_path / "odd.mdd"
    path.write_bytes(struct.pack(">ii", 9, source.shape[1]) + times.astype(">f4").tobytes()
                     + source.astype(">f4").tobytes())
    assert main(["info", str(path)]) == 0
    assert "not evenly spaced and increasing" in capsys.readouterr().out
    assert main(["retime", str(path), "--topology", str(topology), "--step", "4", "-q",
                 "-o", str(tmp_path / "out.pc2")]) == 0
    err = capsys.readouterr().err
    assert "retime: warning [frame_times]: the frame times of" in err and "1 frame_times" in err, err


def test_the_short_last_gap_s_warnings_name_the_plan_s_keys(monkeypatch):
    """The short last gap is in-betweened by a sequence of its own, keyed on the plan's tail: its
    warnings name its keys as the plan numbers them, as the main sequence's do ("between key pose
    3 and key pose 4" for keys 0, 8, 16, 24, 29; its own numbering said key poses 2 and 3, which
    the Retime operator reads as the frames of keys 16 and 24 where the gap runs from 24 to 29).
    Every solved in-between reports a problem here, naming the samples its gap lies between: each gap
    says it once, for all its in-betweens."""
    from core import sequence_inbetweens

    source, triangles = rolling_sheet(n_frames=30, nx=5)
    source = source.astype(np.float64)
    plan = plan_retime(len(source), 8, 0.5)
    assert plan.keys.tolist() == [0, 8, 16, 24, 29] and plan.tail.tolist() == [14, 19, 24, 29]
    real = sequence_inbetweens.gap_poses

    def gap_poses(gap, factors, *ahead):
        moved = gap.next.vertices - gap.base.vertices
        first, second = next((i, j) for i in range(len(source)) for j in range(i + 1, len(source))
                             if np.allclose(source[j] - source[i], moved, rtol=0.0, atol=1e-9))
        return [(x, f"samples {first}-{second}") for x, _ in real(gap, factors, *ahead)]

    monkeypatch.setattr(sequence_inbetweens, "gap_poses", gap_poses)
    with pytest.warns(ShapeDifferenceWarning) as caught:
        list(iter_retime(source, triangles, plan))
    named = [re.search(r"between (key pose \d+ and key pose \d+), .*: (samples \d+-\d+)", str(w.message)).groups()
             for w in caught]
    assert len(named) == len(set(named)) == 4, named  # once per gap, not once per in-between
    keys = [int(k) for k in plan.keys]
    assert set(named) == {(f"key pose {g} and key pose {g + 1}", f"samples {keys[g]}-{keys[g + 1]}") for g in range(4)}


def test_ctrl_c_stops_a_command_in_one_line_with_nothing_written(tmp_path, capsys, monkeypatch):
    """Ctrl+C during the in-betweens: exit 130 (as a shell reports SIGINT), one line saying so and
    no traceback (the one failure the docs ask users to report), no output file."""
    import core.__main__ as command

    source, triangles = rolling_sheet(n_frames=5, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
        yield

    monkeypatch.setattr(command, "iter_retime", interrupted)
    output = tmp_path / "out.pc2"
    assert command.main(["retime", str(cache), "--topology", str(topology), "--step", "2", "-q", "-o", str(output)]) == 130
    err = capsys.readouterr().err
    assert "interrupted (Ctrl+C), nothing written" in err and "Traceback" not in err
    assert not output.exists()


@pytest.mark.skipif(os.name == "nt", reason="on Windows, //server/share is a network path")
def test_command_refuses_a_path_relative_to_a_blend(tmp_path, capsys):
    """`//…` is Blender's path relative to the saved .blend, which the command has none of: on
    Linux and macOS it names a folder at the root of the disk (`//caches/x.pc2` made `/caches`
    and wrote the retime there). Refused, naming that folder, before anything is written."""
    source, triangles = rolling_sheet(n_frames=5, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    output = tmp_path / "out.pc2"
    common = ["retime", "--topology", str(topology), "--step", "2", "-q"]
    assert main([*common, str(cache), "-o", "/" + str(output)]) == 2
    err = capsys.readouterr().err
    assert f"error: '/{output}' is relative to a saved .blend (Blender's '//')" in err
    assert f"here it would name '{output}' at the root of the disk" in err
    assert not output.exists()
    assert main([*common, "/" + str(cache), "-o", str(output)]) == 2  # an input too
    assert f"error: '/{cache}' is relative to a saved .blend" in capsys.readouterr().err
    assert main([*common, str(cache), "-o", str(output)]) == 0


def test_command_paths_under_a_tilde(tmp_path, capsys, monkeypatch):
    """A job runner passes its arguments without a shell, so `~` reaches the command as it is:
    a leading `~` is the home folder, as in a shell; a folder named `~` that does not exist is a
    `~` nobody expanded (OpenJD makes `~/x.pc2` into `<its working folder>/~/x.pc2`) and is
    refused rather than made (the command made a folder `~` in the working folder and wrote there)."""
    source, triangles = rolling_sheet(n_frames=5, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("USERPROFILE", str(tmp_path / "home"))  # what Windows reads for ~
    monkeypatch.chdir(tmp_path)
    common = ["retime", str(cache), "--topology", str(topology), "--step", "2", "-q"]
    assert main([*common, "-o", "~/caches/out.pc2"]) == 0
    assert read_pc2(tmp_path / "home" / "caches" / "out.pc2").n_samples == 5
    assert not (tmp_path / "~").exists()
    unexpanded = tmp_path / "work" / "~" / "out.pc2"
    assert main([*common, "-o", str(unexpanded)]) == 2
    assert f"error: '{unexpanded}' has a folder named '~' that does not exist" in capsys.readouterr().err
    assert not (tmp_path / "work").exists()
    (tmp_path / "work" / "~").mkdir(parents=True)  # a folder really named so is a folder like any other
    assert main([*common, "-o", str(unexpanded)]) == 0


@pytest.mark.skipif(os.name == "nt", reason="a Windows path is a path there")
@pytest.mark.parametrize("output, named", [("C:\\caches\\out.pc2", "a Windows path"),
                                           ("D:/shots/out.pc2", "a Windows path"),
                                           ("\\\\farm\\caches\\out.pc2", "a Windows path"),
                                           ("~no_such_user_here/out.pc2", "a user this machine does not have")])
def test_command_paths_of_another_machine_are_refused(tmp_path, capsys, monkeypatch, output, named):
    """A Windows path on Linux or macOS (a job made on a Windows workstation, without path mapping)
    and a `~user` of no user are names in the working folder there: refused, nothing written
    (before: a file `C:\\caches\\out.pc2`, or a folder `~no_such_user_here`, in the working folder,
    exit status 0)."""
    source, triangles = rolling_sheet(n_frames=5, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    monkeypatch.chdir(tmp_path)
    assert main(["retime", str(cache), "--topology", str(topology), "--step", "2", "-q", "-o", output]) == 2
    assert f"error: '{output}' " in (err := capsys.readouterr().err) and named in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.pc2", "sheet.obj"]


def test_command_says_the_core_s_warnings_in_one_line_and_succeeds(tmp_path, capsys):
    """A warning of the in-betweens (a piece mirrored between two keys) is said as the command's
    own, `retime: warning: …` on one line, and the retime is written with exit status 0, also
    where Python's warning filters turn warnings into errors (`PYTHONWARNINGS=error` in a studio's
    environment ended the finished retime with a traceback and status 1)."""
    rest, triangles = grid(5)
    rest[:, 2] = np.random.default_rng(0).normal(0, 0.2, len(rest))  # no mirror symmetry
    source = np.repeat(rest[None], 9, axis=0) + np.arange(9)[:, None, None] * np.array([0.1, 0, 0])
    source[5:, :, 0] *= -1  # key 8 is the mirror image of key 4
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", rest, triangles)
    output = tmp_path / "out.pc2"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["retime", str(cache), "--topology", str(topology), "--step", "4", "-q", "-o", str(output)]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert [line[:81] for line in lines] == [
        "retime: warning [mirror]: Shape-difference interpolation: 1 piece(s) of the mesh ",
        "retime: 1 warning(s): 1 mirror"], lines
    assert "mirror image of themselves from sample 5 (frame 4) to sample 9 (frame 8)" in lines[0]
    assert read_pc2(output).n_samples == 9


def test_command_warnings_end_with_how_many_of_each_kind_and_the_worst_gap(capsys):
    """Each warning line of the command names its kind (a farm log greps `warning [pose]`), one
    without a kind reads `warning:`; a last line counts them by kind and names the gap whose
    in-between keeps the most flipped or collapsed triangles (the first of them on a tie)."""
    from core.__main__ import _warnings_as_lines
    from core.sequence_warnings import said_warning

    gaps = [(f"sample {a} (frame {a - 1})", f"sample {a + 16} (frame {a + 15})") for a in (1, 17, 33)]
    said = [said_warning(f"between {gaps[0][0]} and {gaps[0][1]}, the in-between at factor 0.5: it keeps 3 triangle(s) "
                         "flipped or collapsed", "pose", 3, gaps[0], (0.5,)),
            said_warning(f"between {gaps[1][0]} and {gaps[1][1]}, 8 of the 15 in-betweens alike, the worst at factor "
                         "0.5: it keeps 121 triangle(s) flipped or collapsed", "pose", 121, gaps[1], (0.5,)),
            said_warning(f"between {gaps[2][0]} and {gaps[2][1]}, 2 triangle(s) are less high than twice the rounding",
                         "sliver", 0, gaps[2]),
            said_warning(f"between {gaps[2][0]} and {gaps[2][1]}, the in-between at factor 0.25: it keeps 121 "
                         "triangle(s) flipped or collapsed", "pose", 121, gaps[2], (0.25,)),
            ShapeDifferenceWarning("the frame times are not evenly spaced")]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with _warnings_as_lines("retime"):
            for warning in said:
                warnings.warn(warning)
    lines = capsys.readouterr().err.splitlines()
    assert [line.split(": Shape-difference")[0] for line in lines[:4]] == \
        ["retime: warning [pose]"] * 2 + ["retime: warning [sliver]", "retime: warning [pose]"], lines
    assert lines[4] == "retime: warning: the frame times are not evenly spaced", lines
    assert lines[5:] == ["retime: 5 warning(s): 3 pose, 1 sliver, 1 other; most flipped or collapsed triangles kept: "
                         "121, between sample 17 (frame 16) and sample 33 (frame 32)"], lines


def test_merge_names_a_missing_chunk_and_the_task_that_writes_it(tmp_path, capsys):
    """A chunk file missing from a merge (its task failed or never ran) is named with its place
    among the chunks and the retime task that writes it (before: only "No such file or
    directory"); nothing is written."""
    source, triangles = rolling_sheet(n_frames=9, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    settings = [str(cache), "--topology", str(topology), "--step", "2", "--speed", "0.5"]
    for i in (1, 3):
        assert main(["retime", *settings, "-q", "--chunk", f"{i}/3", "-o", str(tmp_path / f"chunk{i}.pc2")]) == 0
    capsys.readouterr()
    output = tmp_path / "out.pc2"
    assert main(["merge", "--numbered", str(tmp_path / "chunk#.pc2"), "--count", "3", "-o", str(output)]) == 2
    err = capsys.readouterr().err
    assert f"Chunk 2 of 3, '{tmp_path / 'chunk2.pc2'}', does not exist" in err
    assert "--chunk 2/3" in err and "task Chunk=2 of step RetimeChunk" in err
    assert not output.exists()


def test_commands_refuse_more_chunks_than_any_retime_has_key_gaps(tmp_path, capsys):
    """A chunk count past the key gaps any retime has (1,048,574, Blender's frames) is a typo: the
    merge listed every chunk's name before looking for the first (``--count 10**12`` filled the
    memory), and a retime's chunk of it ran as an empty chunk. Refused with the count, nothing
    written; a count of more chunks than this retime's gaps (empty chunks) still runs."""
    source, triangles = rolling_sheet(n_frames=5, nx=5)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    settings = ["retime", str(cache), "--topology", str(topology), "--step", "2", "--speed", "0.5", "-q"]
    with pytest.raises(SystemExit) as refused:  # argparse's refusal of an option's value: status 2
        main([*settings, "--chunk", "1/1048575", "-o", str(tmp_path / "part.pc2")])
    assert refused.value.code == 2
    assert "1,048,575 chunks are more than any retime has key gaps (at most 1,048,574" in capsys.readouterr().err
    assert not (tmp_path / "part.pc2").exists()
    output = tmp_path / "out.pc2"
    assert main(["merge", "--numbered", str(tmp_path / "chunk#.pc2"), "--count", str(10**12), "-o", str(output)]) == 2
    assert "--count 1000000000000: 1,000,000,000,000 chunks are more than any retime has key gaps" in \
        capsys.readouterr().err and not output.exists()
    assert main([*settings, "--chunk", "1/3", "-o", str(tmp_path / "part1.pc2")]) == 0  # 2 gaps, 3 chunks
    assert read_pc2(tmp_path / "part1.pc2").positions.shape == (0, 25, 3)  # the first one empty


def test_commands_refuse_an_output_not_named_pc2(tmp_path, capsys):
    """``-o out`` (no suffix) or another suffix: refused before any work, with the name to give
    (before, a PC2 file named 'out' was written, where the operators write 'out.pc2'); the same
    name ending in .pc2 is written."""
    source, triangles = rolling_sheet(n_frames=5, nx=4)
    cache = write_pc2(tmp_path / "in.pc2", source)
    topology = write_obj(tmp_path / "sheet.obj", source[0], triangles)
    common = ["retime", str(cache), "--topology", str(topology), "--step", "2", "-q"]
    for name in ("out", "out.cache"):
        output = str(tmp_path / name)
        for argv in ([*common, "-o", output], ["merge", str(cache), "-o", output]):
            assert main(argv) == 2
            err = capsys.readouterr().err
            assert f"'{output}' is not named .pc2" in err and f"name it '{output}.pc2'" in err, (argv, err)
            assert not os.path.exists(output)
    assert main([*common, "-o", str(tmp_path / "out.pc2")]) == 0
    assert main(["merge", str(tmp_path / "out.pc2"), "-o", str(tmp_path / "merged.PC2")]) == 0
    np.testing.assert_array_equal(read_pc2(tmp_path / "merged.PC2").positions, read_pc2(tmp_path / "out.pc2").positions)


def test_command_warnings_name_the_keys_by_the_inputs_samples_and_frames(tmp_path, capsys):
    """A core warning about the keys of a retime (a piece mirrored from one key to the next) names
    them by the input's samples and frames, as the command's own messages do (before: "key pose 1"
    and "key pose 2", indices into the keys a user never sees); the sequence refuses names that
    are not one per key."""
    vertices, triangles = grid(6, jitter=0.3, seed=1)
    vertices = np.c_[vertices[:, :2], 0.3 * vertices[:, 0] ** 2 + 0.1 * vertices[:, 1]]
    frames = np.array([vertices + [0.01 * k, 0.0, 0.0] for k in range(9)])
    frames[4] *= [-1.0, 1.0, 1.0]  # sample 5 mirrored: the keys of samples 3 → 5 and 5 → 7 reflect it
    cache = write_pc2(tmp_path / "in.pc2", frames, start=10.0)
    topology = write_obj(tmp_path / "sheet.obj", vertices, triangles)
    assert main(["retime", str(cache), "--topology", str(topology), "--step", "2", "-q",
                 "-o", str(tmp_path / "out.pc2")]) == 0
    err = capsys.readouterr().err
    assert "mirror image of themselves from sample 3 (frame 12) to sample 5 (frame 14)" in err, err
    assert "from sample 5 (frame 14) to sample 7 (frame 16)" in err and "key pose" not in err, err
    with pytest.raises(MeshError, match="key_names must name each of the 5 key poses; got 2"):
        SequenceInterpolator(list(frames[::2]), triangles, key_names=["a", "b"])


def test_each_sample_a_retime_reads_is_checked_once(monkeypatch):
    """30 samples keyed every 8th (keys 0, 8, 16, 24, 29; the short last gap keyed on its own tail
    14, 19, 24, 29): every sample read is checked as a pose once, where it is named — the first key
    was checked by ``retime`` and again by ``iter_retime``, the tail's keys 24 and 29 as keys and
    again by the short gap's sequence — and a sample of the tail that is no key is checked before
    the end of the motion is read from it: one with an infinite coordinate is refused by its name,
    where it was read first (NumPy's "invalid value" warning from the end's spline) and refused after."""
    import core.retime as retime_module

    source, triangles = rolling_sheet(n_frames=30, nx=5)
    checked, real = [], retime_module.check_vertices
    monkeypatch.setattr(retime_module, "check_vertices",
                        lambda sample, *args, name=None, **kwargs: checked.append(name) or real(sample, *args, name=name,
                                                                                                  **kwargs))
    out = retime(source, triangles, step=8, speed=0.5)
    assert len(out) == 59
    assert len(checked) == len(set(checked)), sorted(checked)
    plan = plan_retime(len(source), 8, 0.5)
    assert len(checked) == len(plan.samples_read), (sorted(checked), plan.samples_read)
    broken = source.copy()
    broken[19, 2, 1] = np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(MeshError, match="sample 19: vertex 2 has a non-finite coordinate"):
            retime(broken, triangles, step=8, speed=0.5)


def test_a_chunk_of_the_first_gaps_refuses_a_broken_sample_of_the_tail_it_reads_the_end_from():
    """A chunk (``gaps``) that does not make the short last gap still reads the end of the motion
    from the tail's samples (keys 0, 8, 16, 24, 29; tail 14, 19, 24, 29): sample 19, no key, with an
    infinite coordinate is refused by its name there too, before anything is read from it, as the
    chunk with the last gap refuses it (before, the first chunk ran on with NumPy's "invalid value"
    warning from the end's spline and only the last refused, docs/errors.md)."""
    source, triangles = rolling_sheet(n_frames=30, nx=5)
    plan = plan_retime(len(source), 8, 0.5)
    assert 19 in plan.tail.tolist() and 19 not in plan.keys.tolist()
    broken = source.copy()
    broken[19, 2, 1] = np.inf
    for gaps in (range(0, 1), range(0, plan.n_gaps)):
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            with pytest.raises(MeshError, match="sample 19: vertex 2 has a non-finite coordinate"):
                list(iter_retime(broken, triangles, plan, gaps))


def test_chunk_bounds_are_the_list_formulas_for_every_index_and_count():
    """``RetimePlan.chunk`` computes only its own two bounds (since b1a0bef); the ranges are those of
    the list of every chunk's bounds it built before (``n_gaps · i // count`` for i = 0 … count),
    for every index of every count up to past the gaps (empty chunks), for NumPy integers, and at
    the largest plans and counts a command accepts; together the chunks are the gaps, in order."""
    from core.retime import MAX_OUTPUT_SAMPLES, RetimePlan

    def old_bounds(n_gaps, count):  # the list of every chunk's bounds, as chunk built it before b1a0bef
        return [n_gaps * i // count for i in range(count + 1)]

    def plan(n_gaps):  # only the keys set the gaps a chunk splits
        empty = np.zeros(0)
        return RetimePlan(n_gaps + 1, 1, 1.0, np.arange(n_gaps + 1), empty, empty, empty, empty, empty)

    rng = np.random.default_rng(7)
    cases = [(n, c) for n in range(0, 41) for c in range(1, 47)]
    cases += [(int(rng.integers(0, MAX_OUTPUT_SAMPLES + 1)), int(rng.integers(1, 20_000))) for _ in range(30)]
    cases += [(MAX_OUTPUT_SAMPLES, 3), (MAX_OUTPUT_SAMPLES - 1, MAX_OUTPUT_SAMPLES), (7, MAX_OUTPUT_SAMPLES)]
    for n_gaps, count in cases:
        retime_plan = plan(n_gaps)
        assert retime_plan.n_gaps == n_gaps
        bounds = old_bounds(n_gaps, count)
        indices = range(count) if count <= 50 else sorted({0, count - 1, *map(int, rng.integers(0, count, 10))})
        for index in indices:
            expected = range(bounds[index], bounds[index + 1])
            assert retime_plan.chunk(index, count) == expected
            assert retime_plan.chunk(np.int64(index), np.int32(count)) == expected
        if count <= 50:
            joined = [gap for index in range(count) for gap in retime_plan.chunk(index, count)]
            assert joined == list(range(n_gaps))
