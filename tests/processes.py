"""Processes as the tests that kill wtftc see them: whether one is alive, and whether a
group of them is gone within a time."""

from __future__ import annotations

import time
from pathlib import Path


def alive(pid: int) -> bool:
    """Whether ``pid`` is a live process (a zombie waiting for its parent is not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False
    return stat.rsplit(")", 1)[1].split()[0] not in ("Z", "X")


def gone(pids, within_s: float = 5.0) -> bool:
    """Whether every process of ``pids`` has ended within ``within_s`` [s]."""
    end = time.monotonic() + within_s
    while time.monotonic() < end:
        if not any(alive(p) for p in pids):
            return True
        time.sleep(0.05)
    return False
