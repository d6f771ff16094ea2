"""Keep NumPy's short-lived arrays off the page-fault path (glibc's malloc only).

The in-between solver works on arrays the size of the mesh (a 14,400-vertex cloth has 28k
triangles: 0.2–2 MB per array) and makes many temporaries per step. By default glibc serves
blocks above a threshold that only grows to the size of the blocks freed so far with fresh memory
mappings, and hands the top of the heap back to the system once twice that threshold is free, so
an expression with two such temporaries touches fresh pages each time it runs; every first touch
of a 4 KB page is a page fault (about 3 µs on the 2-core benchmark machine). Raising both
thresholds keeps freed blocks in the heap for reuse: on the 14k tablecloth this halves the page
faults per in-between (3,600–3,900 → 1,900–2,000) and saves about a tenth of its time; numbers in
docs/design-decisions.md. Only the process's C allocator settings change (no data); under another
allocator (musl, macOS, Windows, or a malloc replaced by the host, as Blender's jemalloc builds do)
this does nothing. Nor does it in an interactive Blender session, whose own allocations should go
back to the system as usual; Blender in the background (farm and batch jobs) is tuned.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import platform
import sys

#: Blocks below this size come from the heap (glibc's M_MMAP_THRESHOLD): larger than any
#: per-triangle array of a 100k-vertex mesh (200k triangles × 9 floats = 14 MB).
MMAP_THRESHOLD = 64 << 20
#: Free memory at the top of the heap kept for reuse before it is handed back (M_TRIM_THRESHOLD).
TRIM_THRESHOLD = 64 << 20
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameter numbers
_done = False


def keep_heap() -> bool:
    """Raise glibc's mmap and trim thresholds once per process (see the module docstring).
    Returns whether the settings are in force (False on other platforms or C libraries)."""
    global _done
    if _done:
        return True
    if not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc":
        return False
    blender = sys.modules.get("bpy")
    if blender is not None and not getattr(getattr(blender, "app", None), "background", True):
        return False  # an interactive session: leave the host's allocator as it is
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        _done = bool(libc.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(libc.mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    except (OSError, AttributeError):  # no loadable C library or no mallopt: nothing to tune
        return False
    return _done
