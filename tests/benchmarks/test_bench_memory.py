"""The in-between benchmark's memory split (benchmarks/bench_inbetween.py, ``HeapWatch``): what a
peak of resident memory holds, read against blocks of known size allocated in a fresh process."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks import bench_inbetween as bench

ROOT = Path(bench.__file__).resolve().parents[1]
# Three 40 MB arrays, below the mmap threshold keep_heap sets (served from glibc's heap), touched and
# held, then the middle one freed: a hole under the last, which the heap keeps.
SCRIPT = f"""
import json, sys, time
sys.path.insert(0, {str(ROOT)!r})
import numpy as np
from benchmarks.bench_inbetween import HeapWatch
from core.allocator import keep_heap
kept = "M_MMAP_THRESHOLD" in keep_heap()
watch = HeapWatch(interval=0.01)
blocks = [np.ones(5 << 20) for _ in range(3)]
time.sleep(0.2)
del blocks[1]
time.sleep(0.2)
held = watch.split()
after = HeapWatch(interval=0.01)
time.sleep(0.05)
print(json.dumps([kept, held, after.split()]))
"""


def test_the_split_sees_blocks_in_use_and_a_hole_freed_but_kept():
    """At the resident peak the heap holds the three arrays (in use, or the middle one freed and
    kept: resident either way); the live peak counts all three; once the middle one is freed the
    heap counts its 40 MB free, still resident."""
    probe = bench.HeapWatch()
    probe.split()  # its thread stopped
    if not probe.available:
        pytest.skip("Linux with glibc's mallinfo2 is needed")
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True)
    kept, peak, after = json.loads(out.stdout.splitlines()[-1])
    if not kept:  # glibc refused keep_heap's mmap threshold (some versions cap M_MMAP_THRESHOLD): the blocks are mapped
        pytest.skip("the heap's thresholds are not in force: 40 MB blocks are mapped on their own, not in the heap")
    assert peak["live_peak"] >= 120 and peak["heap_in_use"] + peak["heap_free"] >= 120, peak
    assert after["heap_free"] >= 40 and after["resident"] >= peak["resident"] - 1, after


@pytest.mark.parametrize("platform_name", ["linux", "darwin", "win32"])
def test_off_glibc_the_watch_starts_nothing_and_the_benchmark_prints_no_split(monkeypatch, platform_name):
    """Where ``core.allocator`` finds no glibc (Linux with musl, whose C library reads as none;
    macOS; Windows) there is no ``mallinfo2`` to read: no thread, no split, nothing printed, and the
    benchmark goes on. Before, the watch loaded ``libc.so.6`` by name, whatever the C library."""
    import platform
    import threading

    from core import allocator

    monkeypatch.setattr(platform, "libc_ver", lambda *args, **kwargs: ("", ""))
    monkeypatch.setattr(sys, "platform", platform_name)
    allocator._glibc.cache_clear()
    try:
        threads = threading.active_count()
        watch = bench.HeapWatch(interval=0.01)
        assert not watch.available and threading.active_count() == threads
        assert watch.split() is None and bench.format_split(watch.split()) == ""
    finally:
        allocator._glibc.cache_clear()  # this platform's own answer again
