"""Whether a network's world fits in this machine's memory, checked before it is built.

A world keeps every pipe and node as a PyBullet body with its mesh, collision mesh
and texture: about 30 MiB a node (measured: ``python benchmarks/bench_sim.py
--network random:20 --no-run`` adds 587 MiB for 20 nodes; the 100-node world takes
2.9 GiB). A network whose world would not fit in the memory the machine has
available is refused at once, with one line, instead of being built for minutes
and then killed.
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


def check_world_fits(network: Network, name: str) -> None:
    """Raise :class:`SimError` when the world of ``network`` (called ``name``) would
    take more memory than this machine has available."""
    need = WORLD_MIB_PER_NODE * len(network.nodes)
    have = available_mib()
    if have is not None and need > have:
        raise SimError(
            f"network {name!r}: its world would take about {need / 1024:.1f} GiB "
            f"({len(network.nodes)} nodes at about {WORLD_MIB_PER_NODE:.0f} MiB each), "
            f"more than the {have / 1024:.1f} GiB this machine has available"
        )
