"""The memory a job can have (core.resources): under a container's or farm job's memory cgroup it is
the cgroup's limit less its usage, not the host's MemAvailable (a 16 GB job on a 256 GB node is
killed at 16 GB). The cgroup trees here are written as the kernel lays them out (cgroup v2's
unified hierarchy as Slurm nests a job, cgroup v1's memory controller as Docker mounts it)."""

import ctypes
import os
import sys

import numpy as np
import pytest

import core
import core.resources
from core import MeshError
from core.resources import available_memory, cgroup_headroom
from core.validation import check_output_memory

GB = 10**9


def _cgroup(folder, files):
    os.makedirs(folder, exist_ok=True)
    for name, text in files.items():
        with open(os.path.join(folder, name), "w", encoding="ascii") as file:
            file.write(text)


def _own(tmp_path, text):
    path = tmp_path / "self_cgroup"
    path.write_text(text)
    return str(path)


def test_a_slurm_jobs_limit_above_the_process_cgroup_bounds_its_memory(tmp_path):
    """cgroup v2, Slurm's layout: the limit is on the job, two levels above the task's cgroup; the
    step below it has a tighter one. The headroom is the tightest limit less its usage without the
    file pages (which the kernel reclaims before it kills); shared memory (shmem) stays counted."""
    root = tmp_path / "cg"
    job = root / "system.slice" / "slurmstepd.scope" / "job_42"
    _cgroup(root, {"memory.stat": "inactive_file 0\n"})  # the root cgroup has no memory.max
    _cgroup(job, {"memory.max": f"{16 * GB}\n", "memory.current": f"{3 * GB}\n",
                  "memory.stat": "anon 1\ninactive_file 0\n"})
    _cgroup(job / "step_0", {"memory.max": f"{8 * GB}\n", "memory.current": f"{5 * GB}\n",
                             "memory.stat": f"anon {2 * GB}\nshmem 9\nactive_file {GB // 4}\n"
                                            f"inactive_file {1 * GB}\n"})
    _cgroup(job / "step_0" / "user" / "task_0", {"memory.max": "max\n", "memory.current": "7\n"})
    own = _own(tmp_path, "0::/system.slice/slurmstepd.scope/job_42/step_0/user/task_0\n")
    assert cgroup_headroom(str(root), own) == 8 * GB - (5 * GB - GB // 4 - 1 * GB)


def test_a_docker_v1_container_reads_its_limit_at_the_mount_root(tmp_path):
    """cgroup v1 in a Docker container: /proc/self/cgroup names the host's path (/docker/<id>), but
    the container's own cgroup is mounted at /sys/fs/cgroup/memory: the path is not there, the
    mount's root is read. "Unlimited" (the largest page-aligned 63-bit number) is no limit."""
    root = tmp_path / "cg"
    _cgroup(root / "memory", {"memory.limit_in_bytes": f"{4 * GB}\n", "memory.usage_in_bytes": f"{1 * GB}\n",
                              "memory.stat": f"cache 5\ninactive_file 3\ntotal_active_file {GB // 8}\n"
                                             f"total_inactive_file {GB // 2}\n"})
    own = _own(tmp_path, "12:pids:/docker/abc\n4:memory:/docker/abc\n0::/docker/abc\n")
    assert cgroup_headroom(str(root), own) == 4 * GB - (1 * GB - GB // 8 - GB // 2)
    _cgroup(root / "memory", {"memory.limit_in_bytes": "9223372036854771712\n"})
    assert cgroup_headroom(str(root), own) is None


@pytest.mark.parametrize("own_text", [None, "", "0::/\n", "3:cpu,cpuacct:/x\n", "garbage\n"])
def test_no_memory_limit_or_no_cgroups_is_none(tmp_path, own_text):
    """No /proc/self/cgroup (macOS, Windows), no memory controller, or a cgroup with no limit: None,
    and the system's own figure is used alone."""
    root = tmp_path / "cg"
    _cgroup(root, {"memory.max": "max\n", "memory.current": f"{GB}\n"})
    own = str(tmp_path / "missing") if own_text is None else _own(tmp_path, own_text)
    assert cgroup_headroom(str(root), own) is None


def test_a_job_past_its_containers_limit_is_refused_though_the_host_has_plenty(monkeypatch):
    """Before, MemAvailable alone was read: an output of 2 GB under a 1 GB container passed the check
    on a host with 100 GB free, and the kernel killed the job when it reached the limit."""
    monkeypatch.setattr(core.resources, "_system_available", lambda: 100 * GB)
    monkeypatch.setattr(core.resources, "cgroup_headroom", lambda: 1 * GB)
    assert available_memory() == 1 * GB
    with pytest.raises(MeshError, match=r"this process \(within its container's or farm job's memory limit, if any\) "
                                        r"has 1 GB of memory available"):
        check_output_memory(100, 2 * GB // 1200, "The output", "ask for less")
    monkeypatch.setattr(core.resources, "cgroup_headroom", lambda: None)
    assert available_memory() == 100 * GB
    check_output_memory(100, 2 * GB // 1200, "The output", "ask for less")  # the host's figure alone


def test_this_processs_headroom_is_within_what_the_system_reports():
    """On the machine the tests run on: whatever its cgroups, the figure is positive and no more
    than the system's own."""
    free, system = available_memory(), core.resources._system_available()
    if free is None:
        pytest.skip("this system does not say how much memory is available")
    assert 0 <= free <= system and np.isfinite(free)


class _Kernel32:
    """Windows' kernel32 as the tests give it: ``GlobalMemoryStatusEx`` fills MEMORYSTATUSEX with
    ``available`` physical and ``commit`` committable bytes, or fails (returns 0)."""

    def __init__(self, available: int, commit: int, works: bool = True):
        self.available, self.commit, self.works = available, commit, works

    def GlobalMemoryStatusEx(self, pointer):  # noqa: N802 — Windows' name
        status = pointer._obj
        assert status.dwLength == ctypes.sizeof(status) == 64  # set by the caller, as Windows requires
        status.ullTotalPhys, status.ullAvailPhys, status.ullAvailPageFile = 32 * GB, self.available, self.commit
        return int(self.works)


def test_windows_reports_its_available_memory(monkeypatch):
    """On Windows (no /proc/meminfo, no SC_AVPHYS_PAGES) the system said nothing and no memory was
    checked: an output of 10 GB on a machine with 8 GB free was made until it swapped. Its own call
    (GlobalMemoryStatusEx) gives the available physical memory, or the commit left where that is less
    (a small page file: allocations fail there first); a call that fails leaves it unchecked."""
    monkeypatch.setattr(sys, "platform", "win32")
    monkeypatch.setattr(core.resources, "cgroup_headroom", lambda: None)
    monkeypatch.setattr(core.resources, "_kernel32", lambda: _Kernel32(8 * GB, 40 * GB), raising=False)
    assert available_memory() == 8 * GB
    with pytest.raises(MeshError, match="has 8 GB of memory available"):
        check_output_memory(100, 10 * GB // 1200, "The output", "ask for less")
    monkeypatch.setattr(core.resources, "_kernel32", lambda: _Kernel32(8 * GB, 3 * GB))
    assert available_memory() == 3 * GB
    monkeypatch.setattr(core.resources, "_kernel32", lambda: _Kernel32(8 * GB, 40 * GB, works=False))
    assert available_memory() is None


class _LibSystem:
    """macOS's C library as the tests give it: ``sysctlbyname`` of the integer sysctls ``values``."""

    def __init__(self, values: dict):
        self.values = values

    def sysctlbyname(self, name, value, size, new, new_size):
        if name not in self.values:
            return -1
        assert size._obj.value == ctypes.sizeof(value._obj) and new is None
        value._obj.value = self.values[name]
        return 0


def test_macos_reports_its_available_memory(monkeypatch):
    """macOS has no SC_AVPHYS_PAGES: nothing was checked there. The kernel's share of memory available
    (kern.memorystatus_level, percent) of its physical memory (hw.memsize) is read; a sysctl that
    fails leaves it unchecked."""
    monkeypatch.setattr(sys, "platform", "darwin")
    monkeypatch.setattr(core.resources, "cgroup_headroom", lambda: None)
    values = {b"kern.memorystatus_level": 37, b"hw.memsize": 16 * 2**30}
    monkeypatch.setattr(core.resources, "_system_library", lambda: _LibSystem(values), raising=False)
    assert available_memory() == 16 * 2**30 * 37 // 100
    with pytest.raises(MeshError, match="has 6.36 GB of memory available"):
        check_output_memory(100, 4 * GB // 1200, "The output", "ask for less")
    del values[b"kern.memorystatus_level"]
    assert available_memory() is None
