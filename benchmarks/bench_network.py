"""Benchmark of network generation at town scale: time and shape of each layout.

Usage: ``python benchmarks/bench_network.py [--json] [SPEC ...]`` (default
``random:200 random:1000 grid:30x30 tree:300``, seed 0, or ``SPEC@SEED``). For each
spec: the wall and CPU time of :func:`pipemap.sim.build_network` (drawing and the
network's validation), the node and pipe counts, the loops (pipes beyond a spanning
tree), the nodes by number of pipes, the pipe lengths (least, median, most, total,
and how many fall in each band of metres) and ``drive_once_h``: hours the robot takes
to drive every pipe once at its cruise speed, a floor on a run's simulated time.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipemap.sim import build_network  # noqa: E402
from pipemap.sim.explorer_config import ExplorerConfig  # noqa: E402

_DEFAULT = ("random:200", "random:1000", "grid:30x30", "tree:300")
#: Bands of pipe length, metres: each counts the pipes from its bound to the next.
_BANDS_M = (0.0, 2.0, 5.0, 10.0, 20.0)


def measure(spec: str, seed: int) -> dict[str, object]:
    """Build ``spec`` from ``seed`` once and describe it."""
    wall, cpu = time.perf_counter(), time.process_time()
    net = build_network(spec, seed=seed)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    lengths = [net.length_m(p.a, p.b) for p in net.pipes]
    degrees = Counter(net.degree(label) for label in net.labels)
    return {
        "spec": spec,
        "seed": seed,
        "build_s": round(wall, 3),
        "build_cpu_s": round(cpu, 3),
        "nodes": len(net.nodes),
        "pipes": len(net.pipes),
        "loops": len(net.pipes) - len(net.nodes) + 1,
        "nodes_by_pipes": {str(k): degrees[k] for k in sorted(degrees)},
        "pipe_m": {
            "min": round(min(lengths), 2),
            "median": round(statistics.median(lengths), 2),
            "max": round(max(lengths), 2),
            "total": round(sum(lengths), 1),
        },
        "pipes_by_m": {
            f"{lo:g}-{hi:g}": sum(lo <= length < hi for length in lengths)
            for lo, hi in zip(_BANDS_M, (*_BANDS_M[1:], float("inf")), strict=True)
        },
        "drive_once_h": round(sum(lengths) / ExplorerConfig().speed_mps / 3600.0, 2),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("specs", nargs="*", default=list(_DEFAULT), help="SPEC or SPEC@SEED")
    parser.add_argument("--json", action="store_true", help="one JSON list")
    args = parser.parse_args()
    rows = []
    for item in args.specs:
        spec, _, seed = item.partition("@")
        rows.append(measure(spec, int(seed or 0)))
        if not args.json:
            print(json.dumps(rows[-1]))
    if args.json:
        print(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
