"""The machine's available memory, and a check of a request's estimated footprint against it before work starts."""

from __future__ import annotations

import os
from pathlib import Path

MEMINFO = Path("/proc/meminfo")  # Linux: MemAvailable, what can be allocated without swapping [kB]


def available_bytes() -> int | None:
    """Memory a new allocation can use without swapping [bytes]: Linux's MemAvailable, else the free physical pages;
    None where neither is known."""
    try:
        for line in MEMINFO.read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, OSError, ValueError):
        return None


def check_memory(estimate_bytes: float, what: str) -> None:
    """``ValueError`` giving the estimate and what is available when ``what``'s footprint exceeds the memory."""
    available = available_bytes()
    if available is not None and estimate_bytes > available:
        raise ValueError(
            f"{what} needs about {estimate_bytes / 1e9:.1f} GB of memory; {available / 1e9:.1f} GB are available"
        )
