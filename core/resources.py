"""What this machine can give a job: memory available now (the cores: :mod:`core.concurrency`)."""

from __future__ import annotations

import os


def available_memory() -> int | None:
    """Bytes of memory a new allocation can get without swapping (Linux: ``MemAvailable``; other
    systems: free physical pages), or None where the system does not tell."""
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
