"""PC2 and MDD files: written samples read back exactly, headers as Blender's Mesh Cache modifier
reads them, chunks merged byte for byte, and bad files rejected with MeshError."""

import os
import struct
from pathlib import Path

import numpy as np
import pytest

from core import MeshError
from core import atomic_files, point_cache
from core.point_cache import merge_pc2, read_mdd, read_pc2, read_point_cache, write_pc2


def samples(n_samples=5, n_points=7, seed=0):
    return np.random.default_rng(seed).normal(size=(n_samples, n_points, 3)).astype(np.float32)


def test_pc2_round_trip_and_header(tmp_path):
    data = samples()
    path = write_pc2(tmp_path / "a.pc2", data, start=3.0, sampling=0.5)
    raw = path.read_bytes()
    # The header layout Blender's Mesh Cache modifier and other packages read.
    assert struct.unpack("<12siiffi", raw[:32]) == (b"POINTCACHE2\0", 1, 7, 3.0, 0.5, 5)
    assert len(raw) == 32 + data.nbytes
    cache = read_pc2(path)
    np.testing.assert_array_equal(cache.positions, data)
    assert (cache.start, cache.sampling, cache.n_samples, cache.n_points) == (3.0, 0.5, 5, 7)


def test_single_pose_is_one_sample(tmp_path):
    pose = samples(1)[0]
    cache = read_point_cache(write_pc2(tmp_path / "pose.pc2", pose))
    np.testing.assert_array_equal(cache.positions, pose[None])


def test_mdd_read(tmp_path):
    data = samples(4, 6)
    times = np.array([0.0, 0.04, 0.08, 0.12], dtype=">f4")
    path = tmp_path / "a.mdd"
    path.write_bytes(struct.pack(">ii", 4, 6) + times.tobytes() + data.astype(">f4").tobytes())
    cache = read_point_cache(path)
    np.testing.assert_array_equal(cache.positions, data)
    np.testing.assert_array_equal(cache.times, times.astype(np.float64))
    np.testing.assert_array_equal(read_mdd(path).positions, data)


def test_merge_is_byte_for_byte(tmp_path):
    data = samples(9)
    whole = write_pc2(tmp_path / "whole.pc2", data, start=1.0)
    parts = [write_pc2(tmp_path / f"part{i}.pc2", data[a:b], start=1.0 + a)
             for i, (a, b) in enumerate([(0, 4), (4, 4), (4, 9)])]
    merged = merge_pc2(parts, tmp_path / "merged.pc2")
    assert merged.read_bytes() == whole.read_bytes()


def test_merge_rejects_gaps_and_mismatches(tmp_path):
    data = samples(6)
    first = write_pc2(tmp_path / "1.pc2", data[:3], start=1.0)
    third = write_pc2(tmp_path / "3.pc2", data[4:], start=5.0)
    with pytest.raises(MeshError, match="starts at frame 5, expected 4"):
        merge_pc2([first, third], tmp_path / "out.pc2")
    other = write_pc2(tmp_path / "other.pc2", samples(3, 8), start=4.0)
    with pytest.raises(MeshError, match="not chunks of one cache"):
        merge_pc2([first, other], tmp_path / "out.pc2")
    assert not (tmp_path / "out.pc2").exists()


@pytest.mark.parametrize("start", [100_000.0, -100_000.0])
def test_merge_of_parts_far_from_frame_zero(tmp_path, start):
    """Parts of a cache sampled in tenths from frame ±100,000 merge into the whole file byte for byte: each part's start is the single-precision rounding of its frame
    (0.0078 apart at 100,000), which the check allows (before, the merge refused in-order parts as
    "starts at frame 100000.1, expected 100000.1"); a part left out is still refused."""
    data, sampling = samples(12), 0.1
    whole = write_pc2(tmp_path / "whole.pc2", data, start=start, sampling=sampling)
    bounds = [(0, 1), (1, 3), (3, 7), (7, 12)]
    parts = [write_pc2(tmp_path / f"part{i}.pc2", data[a:b], start=start + a * sampling, sampling=sampling)
             for i, (a, b) in enumerate(bounds)]
    assert merge_pc2(parts, tmp_path / "merged.pc2").read_bytes() == whole.read_bytes()
    for left_out in (1, 2):  # a middle part (the first or last left out makes a shorter cache)
        with pytest.raises(MeshError, match="give the chunks in order, with none missing"):
            merge_pc2(parts[:left_out] + parts[left_out + 1:], tmp_path / "gap.pc2")
    assert not (tmp_path / "gap.pc2").exists()


def test_merge_refuses_parts_whose_starts_cannot_tell_a_missing_sample(tmp_path):
    """At frame 800,000 a PC2's single-precision start frame is 0.0625 frames coarse, six samples of
    a cache sampled in hundredths: without stamps a missing part cannot be told from the starts, so
    the merge refuses, saying why, rather than merge parts it cannot check (chunks written with
    their stamps say which key gaps they hold, :func:`test_command_chunks_far_from_frame_zero`)."""
    data = samples(4)
    parts = [write_pc2(tmp_path / f"part{i}.pc2", data[a:b], start=800_000 + a * 0.01, sampling=0.01)
             for i, (a, b) in enumerate([(0, 2), (2, 4)])]
    with pytest.raises(MeshError, match="cannot tell one sample from the next .* whether a part is missing"):
        merge_pc2(parts, tmp_path / "merged.pc2")
    assert not (tmp_path / "merged.pc2").exists()


@pytest.mark.parametrize("failure", [OSError(28, "No space left on device"), SystemExit(143)])
def test_a_chunk_whose_stamp_cannot_be_written_is_not_left(tmp_path, monkeypatch, failure):
    """A chunk is written, then its stamp: a disk that fills up in between (or a SIGTERM there)
    removes the chunk again, so that the failed or cancelled task leaves nothing written (before,
    the chunk stayed without its stamp, and the merge blamed another job for it)."""
    write = point_cache.write_atomically

    def full_at_the_stamp(path, chunks, **options):
        if str(path).endswith(point_cache.STAMP_SUFFIX):
            raise failure
        return write(path, chunks, **options)

    monkeypatch.setattr(point_cache, "write_atomically", full_at_the_stamp)
    with pytest.raises(type(failure)):
        write_pc2(tmp_path / "chunk1.pc2", samples(3), stamp=dict(job="j", gaps=[0, 1], key_gaps=2))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("damage, match", [
    (lambda raw: b"NOTACACHE!!!" + raw[12:], "is not a PC2 point cache .* give an MDD file its .mdd name"),
    (lambda raw: raw[:-4], "not a complete PC2 file"),
    (lambda raw: raw[:20], "is not a PC2|invalid PC2|not a complete"),
    (lambda raw: raw[:12] + struct.pack("<i", 2) + raw[16:], "invalid PC2 header"),
    (lambda raw: b"", "is empty"),
])
def test_bad_files(tmp_path, damage, match):
    good = write_pc2(tmp_path / "good.pc2", samples()).read_bytes()
    bad = tmp_path / "bad.pc2"
    bad.write_bytes(damage(good))
    with pytest.raises(MeshError, match=match):
        read_point_cache(bad)


def test_missing_file_and_bad_positions(tmp_path):
    with pytest.raises(MeshError, match="does not exist"):
        read_point_cache(tmp_path / "nope.pc2")
    data = samples()
    data[2, 1, 0] = np.nan
    with pytest.raises(MeshError, match="sample 2 has non-finite"):
        write_pc2(tmp_path / "nan.pc2", data)
    with pytest.raises(MeshError, match="shape"):
        write_pc2(tmp_path / "flat.pc2", np.zeros((4, 2)))
    assert not list(tmp_path.iterdir())


def test_a_pc2_is_written_one_sample_at_a_time(tmp_path):
    """Writing holds at most one sample's float32 copy (and its finiteness mask) besides the poses
    given, not a copy of the whole output: an operator's poses (float64 keys among float32
    in-betweens) made into one float64 array, a float32 one and its bytes take four times the 12
    bytes per point that check_output_memory allows for. The file holds every sample as float32,
    and a list of poses writes the same bytes as their array."""
    import tracemalloc

    n_samples, n_points = 40, 5000
    poses = [np.full((n_points, 3), i / 7, dtype=np.float64 if i % 4 == 0 else np.float32) for i in range(n_samples)]
    one_sample = n_points * 3 * 4
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        path = write_pc2(tmp_path / "poses.pc2", poses, start=1.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2 * one_sample  # the whole output is 40 samples
    assert read_pc2(path).positions.tobytes() == np.asarray(poses, dtype="<f4").tobytes()
    assert write_pc2(tmp_path / "array.pc2", np.asarray(poses, dtype=np.float32), start=1.0).read_bytes() == \
        path.read_bytes()
    with pytest.raises(MeshError, match="one shape"):
        write_pc2(tmp_path / "mixed.pc2", [np.zeros((3, 3)), np.zeros((4, 3))])


def test_a_file_that_is_no_point_cache_is_said_to_be_none(tmp_path):
    """An OBJ given as the cache (the arguments swapped): "not a point cache" (it read as an MDD
    whose header "promises 18439727604560280776 bytes"); a damaged .mdd keeps the MDD message."""
    obj = tmp_path / "sheet.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(MeshError, match="is not a point cache: neither PC2 .* nor MDD"):
        read_point_cache(obj)
    (tmp_path / "cut.mdd").write_bytes(obj.read_bytes())
    with pytest.raises(MeshError, match="not a complete MDD file"):
        read_point_cache(tmp_path / "cut.mdd")


def test_a_killed_writers_temporary_file_is_removed_by_the_next_write(tmp_path):
    """A writer killed with SIGKILL (OpenJD's default cancellation, a lost node) leaves its temporary
    file beside the output, as large as what it had written; the next write of that output (the
    task retried) removes it (before, every kill left one more). A temporary file a live writer
    holds stays, and so do other outputs' temporary files."""
    out = tmp_path / "out.pc2"
    killed = tmp_path / ".out.pc2.k1ll3d_x.part"
    killed.write_bytes(b"\0" * 4096)  # no process holds it: its writer died
    others = tmp_path / ".other.pc2.k1ll3d_x.part"
    others.write_bytes(b"\0")
    write_pc2(out, np.zeros((2, 3, 3)))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["out.pc2", others.name])

    handle, live = atomic_files.open_part(out)  # another writer of out.pc2, alive and writing
    try:
        write_pc2(out, np.zeros((2, 3, 3)))
        assert Path(live).exists()
    finally:
        os.close(handle)
        os.unlink(live)


def test_an_exclusive_write_never_replaces_a_file(tmp_path):
    """``exclusive=True`` (a new cache from Blender) takes the name only if no file has it once the
    file is whole: a file that appeared meanwhile is kept and the write raises FileExistsError,
    leaving no temporary file."""
    out = tmp_path / "out.pc2"
    out.write_bytes(b"another process's cache")
    with pytest.raises(FileExistsError):
        write_pc2(out, np.zeros((2, 3, 3)), exclusive=True)
    assert out.read_bytes() == b"another process's cache"
    assert [p.name for p in tmp_path.iterdir()] == ["out.pc2"]
    assert read_pc2(write_pc2(tmp_path / "new.pc2", np.ones((2, 3, 3)), exclusive=True)).positions.sum() == 18


def _pc2_of(data: np.ndarray, order: str = "<", dtype: str = "f4", n_samples: int | None = None) -> bytes:
    """A PC2 file's bytes of ``data`` (samples, points, 3), written in byte ``order`` with
    coordinates of ``dtype`` and a header counting ``n_samples`` (default: the samples given)."""
    count = len(data) if n_samples is None else n_samples
    header = struct.pack(order + "12siiffi", b"POINTCACHE2\0", 1, data.shape[1], 1.0, 1.0, count)
    return header + data.astype(order + dtype).tobytes()


def _mdd_of(data: np.ndarray, order: str = ">", dtype: str = "f4") -> bytes:
    """An MDD file's bytes of ``data`` in byte ``order`` with coordinates of ``dtype``."""
    times = np.arange(len(data), dtype=order + "f4") / 24
    return struct.pack(order + "ii", *data.shape[:2]) + times.tobytes() + data.astype(order + dtype).tobytes()


@pytest.mark.parametrize("name, raw, match", [
    # another package's export in double precision: twice the bytes the header counts (it read "cut off")
    ("f64.pc2", lambda data: _pc2_of(data, dtype="f8"), r"holds its coordinates in double precision .* "
     r"twice the 420 of its 5 samples of 7 points .* export the cache again as float32"),
    ("f64.mdd", lambda data: _mdd_of(data, dtype="f8"), r"holds its coordinates in double precision .* "
     r"5 frames of 7 points"),
    # written byte-swapped: the PC2 read as a header of version 16777216, the MDD as ~1e18 bytes promised
    ("big.pc2", lambda data: _pc2_of(data, order=">"), r"is a PC2 file written big-endian .* PC2 files are "
     r"little-endian"),
    ("little.mdd", lambda data: _mdd_of(data, order="<"), r"is an MDD file written little-endian .* 5 frames "
     r"of 7 points\), but MDD files are big-endian"),
    # a header counting fewer samples than the file holds (it read "cut off while copying")
    ("short_count.pc2", lambda data: _pc2_of(data, n_samples=3), r"is longer than its header says: 3 samples "
     r"of 7 points take 284 bytes, the file has 452"),
])
def test_a_cache_of_another_layout_is_named_as_such(tmp_path, name, raw, match):
    """Caches other packages write in a layout PC2 and MDD do not have (double precision, the
    other byte order, a header counting less than the file holds) are refused saying so, not as a
    file cut off while copying or a header of absurd numbers; the standard layouts of the same
    samples read back exactly."""
    data = samples()
    path = tmp_path / name
    path.write_bytes(raw(data))
    with pytest.raises(MeshError, match=match):
        read_point_cache(path)
    standard = tmp_path / ("standard" + path.suffix)
    standard.write_bytes(_pc2_of(data) if path.suffix == ".pc2" else _mdd_of(data))
    np.testing.assert_array_equal(read_point_cache(standard).positions, data)


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="the system gives no /proc/self/status")
def test_a_write_gives_the_umasks_mode_without_setting_the_umask(tmp_path, monkeypatch):
    # Setting the mask to read it leaves it 0 for a moment in which another thread's new file is
    # world-writable; where the system gives the mask, a write reads it there and never sets it.
    old = os.umask(0o027)
    try:
        def no_setting(mask):
            raise AssertionError(f"the umask was set to {mask:o}")

        monkeypatch.setattr(os, "umask", no_setting)
        write_pc2(tmp_path / "out.pc2", samples())
    finally:
        monkeypatch.undo()
        os.umask(old)
    assert (tmp_path / "out.pc2").stat().st_mode & 0o777 == 0o640
