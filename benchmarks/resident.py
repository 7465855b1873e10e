"""The resident memory of this process, for the benchmarks that report it."""

from __future__ import annotations

from pathlib import Path


def rss_mib() -> float:
    """Resident memory of this process (Linux ``/proc``), MiB; NaN elsewhere."""
    status = Path("/proc/self/status")
    if not status.exists():
        return float("nan")
    for line in status.read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")
