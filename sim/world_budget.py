"""Whether a network's world fits in this machine's memory, checked before it is built.

A world keeps every pipe and node as a PyBullet body with its mesh, collision mesh
and texture. A texture is the same size whatever the piece, but a pipe's meshes grow
with its length, so the memory follows the pieces and the metres of pipe: about
:data:`WORLD_MIB_BASE` plus :data:`WORLD_MIB_PER_PIECE` a piece (a node or a pipe)
plus :data:`WORLD_MIB_PER_METRE` a metre of pipe (:func:`world_mib`). Fitted to worlds
built whole (``World(stream=False)``, resident memory added): ``tree:6`` with 1, 4
and 10 m spacing (6.3, 25.1, 62.7 m of pipe) 184, 348 and 690 MiB; ``random:20`` (42
pieces, 32.8 m) 589 MiB; the 100-node world (215 pieces, 179 m) 2.9 GiB. A
``grid:11x11`` town grid (265 pieces, 967 m) is about 10 GiB, where 30 MiB a node
said 3.6 GiB. A network whose world would not fit in the memory the machine has
available is refused at once, with one line, instead of being built for minutes
and then killed; with the world in a child process restarted past a budget
(``--world-memory``, :mod:`sim.world_process`) only a budget larger than the
memory available is refused.
"""

from __future__ import annotations

from pathlib import Path

from pipemap.errors import SimError
from pipemap.sim.network import Network

__all__ = [
    "WORLD_MIB_BASE",
    "WORLD_MIB_PER_METRE",
    "WORLD_MIB_PER_PIECE",
    "available_mib",
    "check_world_fits",
    "pipe_metres",
    "world_mib",
]

#: Resident memory of a world (MiB; fitted, see above): a world's own ...
WORLD_MIB_BASE = 70.0
#: ... each piece's (a node or a pipe: its texture, bodies and the node's chamber) ...
WORLD_MIB_PER_PIECE = 5.5
#: ... and each metre of pipe's (its meshes).
WORLD_MIB_PER_METRE = 9.0


def pipe_metres(network: Network) -> float:
    """The length of all the pipes of ``network``, m."""
    return sum(network.length_m(p.a, p.b) for p in network.pipes)


def world_mib(network: Network) -> float:
    """The resident memory, MiB, the world of ``network`` takes built whole."""
    metres = pipe_metres(network)
    pieces = len(network.nodes) + len(network.pipes)
    return WORLD_MIB_BASE + WORLD_MIB_PER_PIECE * pieces + WORLD_MIB_PER_METRE * metres


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
    need = world_mib(network)
    have = available_mib()
    if have is None or need <= have:
        return
    if world_memory_mib is None:
        raise SimError(
            f"network {name!r}: its world would take about {need / 1024:.1f} GiB "
            f"({len(network.nodes)} nodes, {len(network.pipes)} pipes, "
            f"{pipe_metres(network):.0f} m of pipe), "
            f"more than the {have / 1024:.1f} GiB this machine has available "
            "(--world-memory keeps it in a child process of bounded memory)"
        )
    if world_memory_mib > have:
        raise SimError(
            f"--world-memory {world_memory_mib}: more than the {have / 1024:.1f} GiB this "
            f"machine has available (network {name!r} would take about {need / 1024:.1f} GiB "
            "whole)"
        )
