"""Coverage of the autonomous explorer on seeded networks (what the README quotes).

    python benchmarks/explore_networks.py tree:10 0 50
    python benchmarks/explore_networks.py grid:3x3 0 3

One line per seed: how the run ended, nodes swept of all nodes, the nodes never
swept, and the simulated duration. Images are 32 px: coverage does not depend on them.
"""

from __future__ import annotations

import sys

from pipemap.sim.controller import autonomous_run
from pipemap.sim.network import build_network
from pipemap.sim.world import CameraSpec, World


def main(spec: str, first: int, stop: int) -> None:
    complete = 0
    for seed in range(first, stop):
        network = build_network(spec, seed=seed)
        with World(network, seed=seed, texture_px=32) as world:
            result = autonomous_run(world, CameraSpec(resolution_px=32), seed)
        seen = {s.node for s in result.sweep_truths} - {"?"}
        missing = sorted(set(network.labels) - seen)
        complete += not missing
        print(
            f"{spec} seed {seed}: {result.status.value}, {len(seen)}/{len(network.nodes)} nodes,"
            f" missing {missing}, {result.duration_ns / 1e9:.0f} s simulated",
            flush=True,
        )
    print(f"# {complete}/{stop - first} runs swept every node")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
