"""What this machine can give a job: memory available now (the cores: :mod:`core.concurrency`)."""

from __future__ import annotations

import ctypes
import os
import sys

#: A cgroup v1 memory limit at or past this many bytes is no limit: the kernel writes "unlimited"
#: as the largest page-aligned 63-bit number (9,223,372,036,854,771,712).
_NO_CGROUP_LIMIT = 2**62


def available_memory() -> int | None:
    """Bytes of memory a new allocation can get without swapping or being killed: the system's
    (:func:`_system_available`), or less where the process runs under a memory limit
    (:func:`cgroup_headroom`: a container's, a farm job's), or None where the system does not tell."""
    system = _system_available()
    limited = cgroup_headroom()
    if system is None or limited is None:
        return limited if system is None else system
    return min(system, limited)


def _system_available() -> int | None:
    """The system's memory available, as the system itself counts it: Windows
    (:func:`_windows_available`) and macOS (:func:`_macos_available`) by their own calls; elsewhere
    ``MemAvailable`` of /proc/meminfo (Linux: free pages and the caches the kernel reclaims), else free
    physical pages (``SC_AVPHYS_PAGES``: the BSDs); None where the system does not tell."""
    if sys.platform == "win32":
        return _windows_available()
    if sys.platform == "darwin":
        return _macos_available()
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


class _MemoryStatus(ctypes.Structure):
    """Windows' ``MEMORYSTATUSEX`` (64 bytes), which ``GlobalMemoryStatusEx`` fills."""

    _fields_ = [("dwLength", ctypes.c_uint32), ("dwMemoryLoad", ctypes.c_uint32),
                ("ullTotalPhys", ctypes.c_uint64), ("ullAvailPhys", ctypes.c_uint64),
                ("ullTotalPageFile", ctypes.c_uint64), ("ullAvailPageFile", ctypes.c_uint64),
                ("ullTotalVirtual", ctypes.c_uint64), ("ullAvailVirtual", ctypes.c_uint64),
                ("ullAvailExtendedVirtual", ctypes.c_uint64)]


def _kernel32():
    """Windows' kernel32 library (:mod:`ctypes`; AttributeError elsewhere)."""
    return ctypes.windll.kernel32


def _windows_available() -> int | None:
    """Windows' memory available (``GlobalMemoryStatusEx``): its available physical memory (the free,
    zeroed and standby pages: Task Manager's *Available*), or less where the commit limit is nearer
    (``ullAvailPageFile``: what the process can still commit; with a small page file an allocation
    fails there, before the physical memory is used); None where the call fails."""
    status = _MemoryStatus(dwLength=ctypes.sizeof(_MemoryStatus))
    try:
        done = _kernel32().GlobalMemoryStatusEx(ctypes.byref(status))
    except (AttributeError, OSError):
        return None
    return int(min(status.ullAvailPhys, status.ullAvailPageFile)) if done else None


def _system_library():
    """The C library's functions as the process links them (:mod:`ctypes`: ``sysctlbyname`` on macOS)."""
    return ctypes.CDLL(None)


def _macos_available() -> int | None:
    """macOS's memory available: the share of its physical memory (``hw.memsize``) the kernel counts
    available (``kern.memorystatus_level``, percent: what ``memory_pressure`` prints as the
    system-wide memory free percentage). The kernel counts there every page not wired nor compressed
    (xnu's ``AVAILABLE_NON_COMPRESSED_MEMORY``: free, speculative, inactive and *active* pages), so
    other processes' working sets count as available: an upper bound, which lets through a job that
    would make the system compress, then swap; it refuses only what the machine cannot hold at all.
    None where a call fails.
    (``SC_AVPHYS_PAGES`` does not exist there; the free pages alone leave out the file cache, most of
    an idle Mac's memory.)"""
    level, total = ctypes.c_int32(), ctypes.c_uint64()
    try:
        library = _system_library()
        for name, value in ((b"kern.memorystatus_level", level), (b"hw.memsize", total)):
            size = ctypes.c_size_t(ctypes.sizeof(value))
            if library.sysctlbyname(name, ctypes.byref(value), ctypes.byref(size), None, ctypes.c_size_t(0)) != 0:
                return None
    except (AttributeError, OSError):
        return None
    return total.value * level.value // 100 if 0 <= level.value <= 100 else None


def _read(path: str) -> str | None:
    try:
        with open(path, encoding="ascii") as file:
            return file.read()
    except (OSError, UnicodeDecodeError):
        return None


def _stat(text: str | None, key: str) -> int:
    """The value of ``key`` in a cgroup's memory.stat text, 0 where it is not there."""
    for line in (text or "").splitlines():
        name, _, value = line.partition(" ")
        if name == key and value.strip().isdigit():
            return int(value)
    return 0


def cgroup_headroom(root: str = "/sys/fs/cgroup", own: str = "/proc/self/cgroup") -> int | None:
    """Bytes this process's Linux memory cgroups let it allocate before the kernel's OOM killer ends
    it, or None where no cgroup limits its memory (or there are none: macOS, Windows).

    Containers (Docker, Kubernetes) and farm schedulers (Slurm, HTCondor, systemd's MemoryMax) limit
    a job's memory with a cgroup, while /proc/meminfo still shows the whole host's: a 16 GB job on a
    256 GB node is killed at 16 GB. For every cgroup from the process's own (``own``, read as
    ``/proc/self/cgroup``) up to the hierarchy's root (mounted at ``root``; cgroup v2
    ``memory.max`` / ``memory.current``, v1 ``memory/memory.limit_in_bytes`` /
    ``memory.usage_in_bytes``) that has a limit: its limit less its usage, the usage without the
    file pages the kernel reclaims before it kills (``active_file`` and ``inactive_file``: a
    container that has read large caches is near its limit in page cache alone, and would
    otherwise be refused every job; tmpfs and shared memory stay counted, they are not reclaimed).
    The smallest of them; cgroups not mounted where their path says (a container's own mount) are
    skipped, the mount's root is read in any case."""
    text = _read(own)
    if text is None:
        return None
    headrooms = []
    for line in text.splitlines():
        _, controllers, path = (line.split(":", 2) + ["", ""])[:3]
        if controllers == "":  # cgroup v2 (its controllers are in cgroup.controllers)
            base, files = root, ("memory.max", "memory.current", ("active_file", "inactive_file"))
        elif "memory" in controllers.split(","):
            base, files = os.path.join(root, "memory"), ("memory.limit_in_bytes", "memory.usage_in_bytes",
                                                         ("total_active_file", "total_inactive_file"))
        else:
            continue
        parts = [part for part in path.strip().split("/") if part]
        for depth in range(len(parts), -1, -1):  # the process's own cgroup up to the root
            folder = os.path.join(base, *parts[:depth])
            limit = (_read(os.path.join(folder, files[0])) or "").strip()
            usage = (_read(os.path.join(folder, files[1])) or "").strip()
            if not (limit.isdigit() and usage.isdigit()) or int(limit) >= _NO_CGROUP_LIMIT:
                continue  # "max", no such cgroup here, or no limit
            stat = _read(os.path.join(folder, "memory.stat"))
            in_use = max(int(usage) - sum(_stat(stat, key) for key in files[2]), 0)
            headrooms.append(max(int(limit) - in_use, 0))
    return min(headrooms) if headrooms else None
