"""A whole world's memory against the estimate that refuses a world before it is built.

    python benchmarks/bench_world_estimate.py [SPEC[@SEED][xSPACING] ...]

For each network (default: ``tree:6`` at 1, 4 and 10 m spacing, ``random:20`` and
``paper``), builds its world whole (``World(stream=False)``) in a fresh process and
prints one JSON object: nodes, pipes, metres of pipe, the resident memory the world
added (MiB, ``/proc/self/status``), and ``sim.world_budget.world_mib``'s estimate, which
``record`` and ``sim`` check against the memory available before anything is built.
A large network needs as much memory as it says: ``random:100`` takes about 3 GiB.
"""

from __future__ import annotations

import subprocess
import sys

DEFAULT = ("tree:6x1", "tree:6x4", "tree:6x10", "random:20", "paper")

_ONE = """
import json, sys
from pipemap.sim.network import build_network
from pipemap.sim.world import World
from pipemap.sim.world_budget import pipe_metres, world_mib

def rss_mib():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS")

spec, seed, spacing = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
net = build_network(spec, seed=seed, spacing_m=spacing)
before = rss_mib()
world = World(net, seed, stream=False)
added = rss_mib() - before
print(json.dumps({
    "network": spec, "seed": seed, "spacing_m": spacing,
    "nodes": len(net.nodes), "pipes": len(net.pipes),
    "pipe_m": round(pipe_metres(net), 1),
    "built_mib": round(added, 1), "estimate_mib": round(world_mib(net), 1),
}))
"""


def parse(item: str) -> tuple[str, int, float]:
    """``SPEC[@SEED][xSPACING]``: ``tree:6x4`` is ``tree:6`` at 4 m (a grid's own
    ``RxC`` is kept: ``grid:3x3x2`` is ``grid:3x3`` at 2 m)."""
    spacing = 1.0
    head, _, tail = item.rpartition("x")
    if (
        head
        and ":" in head
        and tail.replace(".", "", 1).isdigit()
        and head.count("x") == (1 if head.startswith("grid:") else 0)
    ):
        item, spacing = head, float(tail)
    spec, _, seed = item.partition("@")
    return spec, int(seed or 0), spacing


def main() -> int:
    items = sys.argv[1:] or list(DEFAULT)
    for item in items:
        spec, seed, spacing = parse(item)
        done = subprocess.run(
            [sys.executable, "-c", _ONE, spec, str(seed), str(spacing)],
            capture_output=True,
            text=True,
            check=False,
        )
        if done.returncode != 0:
            print(f"{item}: {done.stderr.strip().splitlines()[-1]}", file=sys.stderr)
            return 1
        print(done.stdout.strip().splitlines()[-1], flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
