"""Whether a network's world fits in this machine's memory, checked before it is built.

A world keeps every pipe and node as a PyBullet body with its mesh, collision mesh
and texture: about 30 MiB a node (measured: ``python benchmarks/bench_sim.py
--network random:20 --no-run`` adds 587 MiB for 20 nodes; the 100-node world takes
2.9 GiB). A network whose world would not fit in the memory the machine has
available is refused at once, with one line, instead of being built for minutes
and then killed; with the world in a child process restarted past a budget
(``--world-memory``, :mod:`sim.world_process`) only a budget larger than the
memory available is refused.
"""

from __future__ import annotations

from pathlib import Path

from pipemap.errors import SimError
from pipemap.sim.network import Network

__all__ = ["WORLD_MIB_PER_NODE", "available_mib", "check_world_fits"]

#: Resident memory a world takes per node of its network, MiB (measured; see above).
WORLD_MIB_PER_NODE = 30.0


def available_mib() -> float | None:
    """Memory this machine has available (Linux ``MemAvailable``), MiB; ``None``
    when it cannot be told."""
    try:
        text = Path("/proc/meminfo").read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith("MemAvailable:"):
            return int(line.split()[1]) / 1024
    return None


def check_world_fits(network: Network, name: str, world_memory_mib: int | None = None) -> None:
    """Raise :class:`SimError` when the world of ``network`` (called ``name``) would
    take more memory than this machine has available: the whole world in this process
    (``world_memory_mib`` None), or at most that budget in a child process that is
    restarted past it (:mod:`sim.world_process`), whichever is less."""
    need = WORLD_MIB_PER_NODE * len(network.nodes)
    have = available_mib()
    if have is None or need <= have:
        return
    if world_memory_mib is None:
        raise SimError(
            f"network {name!r}: its world would take about {need / 1024:.1f} GiB "
            f"({len(network.nodes)} nodes at about {WORLD_MIB_PER_NODE:.0f} MiB each), "
            f"more than the {have / 1024:.1f} GiB this machine has available "
            "(--world-memory keeps it in a child process of bounded memory)"
        )
    if world_memory_mib > have:
        raise SimError(
            f"--world-memory {world_memory_mib}: more than the {have / 1024:.1f} GiB this "
            f"machine has available (network {name!r} would take about {need / 1024:.1f} GiB "
            "whole)"
        )
