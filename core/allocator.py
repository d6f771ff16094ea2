"""Keep NumPy's short-lived arrays off the page-fault path (glibc's malloc only).

The in-between solver works on arrays the size of the mesh (a 14,400-vertex cloth has 28k
triangles: 0.2–2 MB per array) and makes many temporaries per step. By default glibc serves
blocks above a threshold that only grows to the size of the blocks freed so far with fresh memory
mappings, and hands the top of the heap back to the system once twice that threshold is free, so
an expression with two such temporaries touches fresh pages each time it runs; every first touch
of a 4 KB page is a page fault (about 3 µs on the 2-core benchmark machine). Raising both
thresholds keeps freed blocks in the heap for reuse: on the 14k tablecloth this halves the page
faults per in-between (3,600–3,900 → 1,900–2,000) and saves about a tenth of its time; numbers in
docs/design-decisions.md. Threads share at most two heaps (:data:`ARENA_MAX`), so the
in-betweens' pool threads reuse each other's freed blocks. Only the process's C allocator settings change (no data); under another
allocator (musl, macOS, Windows, or a malloc replaced by the host, as Blender's jemalloc builds do)
this does nothing. Nor does it in an interactive Blender session, whose own allocations should go
back to the system as usual; Blender in the background (farm and batch jobs) is tuned. A process
about to stay idle hands its free heap back (:func:`give_back_heap`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import platform
import sys

#: Blocks below this size come from the heap (glibc's M_MMAP_THRESHOLD): larger than any
#: per-triangle array of a 100k-vertex mesh (200k triangles × 9 floats = 14 MB).
MMAP_THRESHOLD = 64 << 20
#: Free memory at the top of the heap kept for reuse before it is handed back (M_TRIM_THRESHOLD).
TRIM_THRESHOLD = 64 << 20
#: Heaps ("arenas") the threads share (M_ARENA_MAX): glibc gives threads heaps of their own, and
#: memory freed in one is not reused by another, so the in-betweens' pool threads
#: (core/concurrency.py) kept several sets of freed temporaries (100k sheet, keys 4 apart: peak
#: 1,324 MB with glibc's default of 8 per core, 1,016 MB with 2, no slower).
ARENA_MAX = 2
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD, _M_ARENA_MAX = -1, -3, -8  # glibc's mallopt parameter numbers
#: The settings :func:`keep_heap` makes, by name: each is set on its own, so that one glibc refuses
#: (some versions refuse an mmap threshold above HEAP_MAX_SIZE / 2) leaves the others in force.
SETTINGS = {"M_MMAP_THRESHOLD": (_M_MMAP_THRESHOLD, MMAP_THRESHOLD),
            "M_TRIM_THRESHOLD": (_M_TRIM_THRESHOLD, TRIM_THRESHOLD),
            "M_ARENA_MAX": (_M_ARENA_MAX, ARENA_MAX)}
_held: frozenset[str] | None = None  # the settings in force, once keep_heap has set them


def keep_heap() -> frozenset[str]:
    """Raise glibc's mmap and trim thresholds and cap its arenas once per process (see the
    module docstring), each setting on its own: one glibc refuses leaves the others in force.
    Returns the names of the settings in force (of :data:`SETTINGS`; empty, so false, on other
    platforms or C libraries and in an interactive Blender)."""
    global _held
    if _held is not None:
        return _held
    blender = sys.modules.get("bpy")
    if blender is not None and not getattr(getattr(blender, "app", None), "background", True):
        return frozenset()  # an interactive session: leave the host's allocator as it is
    libc = _glibc()
    try:
        _held = frozenset() if libc is None else frozenset(
            name for name, (parameter, value) in SETTINGS.items() if libc.mallopt(parameter, value))
    except AttributeError:  # no mallopt: nothing to tune
        _held = frozenset()
    return _held


def give_back_heap() -> bool:
    """Hand the free memory of glibc's heaps back to the system (``malloc_trim(0)``: the top of each
    heap and the whole free pages inside it), which :func:`keep_heap`'s thresholds otherwise keep for
    the next computation: for a process about to stay idle (the in-betweens' second process between
    jobs, :mod:`core.gap_worker`). Returns whether memory was handed back (False where there was none
    to give, or on other platforms or C libraries, where this does nothing)."""
    libc = _glibc()
    try:
        return libc is not None and bool(libc.malloc_trim(0))
    except AttributeError:  # no malloc_trim
        return False


@functools.cache
def _glibc():
    """glibc's C library (:mod:`ctypes`), or None on other platforms and C libraries or where it cannot
    be loaded; looked for once per process (:func:`platform.libc_ver` reads the interpreter's binary
    where the C library is not glibc: musl's, at every sequence built)."""
    if not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc":
        return None
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:  # no loadable C library
        return None
