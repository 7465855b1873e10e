"""How fast ``pipemap import`` reads a ROS 2 bag.

    python benchmarks/bench_import.py [--repeat 3] [LOG.mcap ...]

Each log (default: the committed recordings) is exported once as a rosbag2 bag
(MCAP storage, CDR: what ``pipemap export --ros2`` writes, untimed), then imported
``--repeat`` times as ``pipemap import`` does (``pipemap.api.import_bag``: read, decode,
check, re-encode the images as PNG, write the log), and the best wall and CPU times
(this process's) are kept: on a machine shared with other work the CPU time is the
steadier of the two. Prints one row per log: the bag's messages and bytes, the
images, the best times, and messages per second of wall time. Needs
``pipemap[ros]`` (rosbags).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from pipemap import api
from pipemap.recorder import Topic

ROOT = Path(__file__).resolve().parents[1]
LOGS = ("paper_autonomous.mcap", "paper_active.mcap", "random8_loops.mcap")


def bag_bytes(folder: Path) -> int:
    """The bag's files' bytes (its storage files and metadata.yaml)."""
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "logs", nargs="*", type=Path, default=[ROOT / "recordings" / n for n in LOGS]
    )
    parser.add_argument("--repeat", type=int, default=3, help="imports per log; best kept")
    args = parser.parse_args()
    header = f"{'log':<24} {'messages':>9} {'bag MB':>7} {'images':>6} {'wall s':>7}"
    print(f"{header} {'CPU s':>6} {'msg/s':>8}")
    for log in args.logs:
        with tempfile.TemporaryDirectory() as folder:
            bag = Path(folder) / "bag"
            exported = api.export_ros2(log, bag)
            messages = sum(exported.counts.values())
            best = cpu = float("inf")
            images = 0
            for k in range(args.repeat):
                start, start_cpu = time.perf_counter(), time.process_time()
                result = api.import_bag(bag, Path(folder) / f"run{k}.mcap")
                best = min(best, time.perf_counter() - start)
                cpu = min(cpu, time.process_time() - start_cpu)
                images = result.counts.get(Topic.IMAGE, 0)
            print(
                f"{log.name:<24} {messages:>9} {bag_bytes(bag) / 1e6:>7.1f} {images:>6} "
                f"{best:>7.2f} {cpu:>6.2f} {messages / best:>8.0f}"
            )


if __name__ == "__main__":
    main()
