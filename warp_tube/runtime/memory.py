"""How much memory this machine, and disk space a folder, has free for a run's output."""

from __future__ import annotations

import os

__all__ = ["available_memory", "available_disk"]


def available_memory() -> int | None:
    """Bytes of memory available to new allocations without swapping (Linux ``MemAvailable``;
    elsewhere the free physical pages), or None where the system does not say."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def available_disk(folder: str) -> int | None:
    """Bytes free to this user in ``folder``'s file system, or None where the system does not say."""
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError, ValueError):
        return None
    return st.f_bavail * st.f_frsize
