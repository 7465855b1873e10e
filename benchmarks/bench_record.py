"""Recording cost: a ``paper`` run with and without its log, and the log's size.

    python benchmarks/bench_record.py [--resolution PX] [--repeat N]

Runs the autonomous exploration of ``paper`` from S at the default settings three
ways, each in a fresh world, and prints the wall time of each (best of N):

1. the run alone: the simulator and its explorer, nothing recorded;
2. the run with the online localizer, nothing written;
3. ``pipemap record``'s path: the run, the online localizer and the log writer.

The issue's target: writing adds less than 10% to the run's wall time (3 against 2).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from pipemap import __version__
from pipemap.recorder import RecordSettings, record_run
from pipemap.recorder.online import Explore, OnlineLocalizer, make_policy
from pipemap.sim.controller import ExplorerConfig, autonomous_run
from pipemap.sim.network import build_network
from pipemap.sim.world import CameraSpec, World


def _run_alone(resolution: int, with_localizer: bool) -> float:
    """The run without a log; with the localizer, exploring its map as ``record`` does."""
    from pipemap.localizer import Localizer

    network = build_network("paper", seed=0)
    camera = CameraSpec(resolution_px=resolution)
    config = ExplorerConfig()
    online = OnlineLocalizer(Localizer(), camera.fov_rad)
    explore = Explore.MAP if with_localizer else Explore.RIGHT_HAND
    policy = make_policy(explore, online, config)
    start = time.perf_counter()
    with World(network, seed=0) as world:
        autonomous_run(
            world, camera, 0, config=config, sink=online if with_localizer else None, policy=policy
        )
    return time.perf_counter() - start


def _record(resolution: int, folder: Path) -> tuple[float, int, int]:
    network = build_network("paper", seed=0)
    path = folder / f"bench-{time.perf_counter_ns()}.mcap"
    start = time.perf_counter()
    result = record_run(
        path, RecordSettings("paper", resolution_px=resolution), network, __version__
    )
    wall = time.perf_counter() - start
    size = path.stat().st_size
    path.unlink()
    return wall, size, result.messages


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=400)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    alone = min(_run_alone(args.resolution, False) for _ in range(args.repeat))
    online = min(_run_alone(args.resolution, True) for _ in range(args.repeat))
    with tempfile.TemporaryDirectory() as tmp:
        runs = [_record(args.resolution, Path(tmp)) for _ in range(args.repeat)]
    wall, size, count = min(runs)
    print(f"paper, autonomous from S, {args.resolution}x{args.resolution}, best of {args.repeat}:")
    print(f"  run alone                       {alone:6.2f} s")
    print(f"  run + online localizer          {online:6.2f} s")
    print(f"  run + localizer + log (record)  {wall:6.2f} s")
    print(f"  writing adds                    {100.0 * (wall - online) / online:5.1f} %")
    print(f"  log: {size / 1e6:.1f} MB, {count} messages")
    return 0


if __name__ == "__main__":
    sys.exit(main())
