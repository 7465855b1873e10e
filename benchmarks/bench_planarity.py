"""What the planarity test of competing maps costs (docs/lookalike.md).

    python benchmarks/bench_planarity.py [--sizes 4x4 6x5 10x10] [--repeat N]

While more than one map is alive, every map is tested after every visit
(:func:`pipemap.localizer.hypotheses.embeds_in_plane`); with one map, never. This
builds the map a robot would have of an R x C grid of crosses (every pipe driven,
each junction's pipes in its ports' clockwise order, the border's ports open),
times the test on it N times (5 by default) by CPU (``time.process_time``) and
prints the quickest, and what a visit with the most maps alive
(``LocalizerConfig().hypotheses``) adds at that size.
"""

from __future__ import annotations

import argparse
import math
import time

from pipemap.localizer import LocalizerConfig, TopoMap
from pipemap.localizer.hypotheses import embeds_in_plane

#: A cross's ports in clockwise order: north, east, south, west.
CROSS = (math.pi / 2.0, 0.0, -math.pi / 2.0, -math.pi)
NORTH, EAST, SOUTH, WEST = range(4)


def grid_map(rows: int, cols: int) -> TopoMap:
    """The map of a ``rows`` x ``cols`` grid of crosses with every pipe driven."""
    topomap = TopoMap()

    def node(r: int, c: int) -> int:
        return r * cols + c

    for _ in range(rows * cols):
        topomap.new_traversal()
        topomap.visit(topomap.node_count, CROSS)
    for r in range(rows):
        for c in range(cols):
            ends = []
            if c + 1 < cols:
                ends.append((EAST, node(r, c + 1), WEST))
            if r + 1 < rows:
                ends.append((NORTH, node(r + 1, c), SOUTH))
            for out, there, back in ends:
                topomap.new_traversal()
                topomap.visit(node(r, c))
                topomap.depart(out)
                topomap.visit(there, None, back, None)
    return topomap


def quickest_s(topomap: TopoMap, repeat: int) -> float:
    """The quickest CPU time of ``repeat`` tests of ``topomap``."""
    best = math.inf
    for _ in range(repeat):
        start = time.process_time()
        planar = embeds_in_plane(topomap)
        best = min(best, time.process_time() - start)
        assert planar, "a grid of crosses is planar"
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=["4x4", "6x5", "10x10"])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    limit = LocalizerConfig().hypotheses
    print(f"# bench_planarity: quickest of {args.repeat}, CPU time; {limit} maps at most")
    for size in args.sizes:
        rows, cols = (int(x) for x in size.split("x"))
        topomap = grid_map(rows, cols)
        seconds = quickest_s(topomap, args.repeat)
        print(
            f"grid {size:>6}: {topomap.node_count:4d} junctions {len(topomap.edges()):4d} pipes  "
            f"test {seconds * 1e3:7.2f} ms  a visit with {limit} maps alive "
            f"+{seconds * limit * 1e3:7.2f} ms"
        )


if __name__ == "__main__":
    main()
