"""Replay throughput: how much faster than the robot a log is replayed.

    python benchmarks/bench_replay.py [--repeat N] [--no-record] [LOG ...]

Replays each log (default: every log in ``recordings/``, plus a ``paper`` run
recorded here at the default 400x400) the way ``pipemap replay`` does: read the
file as it goes (``StreamSource``), put its ``/robot`` messages in order, decode
the PNGs, localize each visit as soon as the log has told it. Prints, per log, the
best wall time of N, the simulated duration, their ratio (simulated seconds per
wall second) and images per second, and the best CPU time (``time.process_time``)
with its ratio, for a loaded machine. For the log recorded here it also prints how
long recording took.

The issue's target: replay at least 100x faster than the run itself took, that is
at least 100 simulated seconds per wall second.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from pipemap import __version__
from pipemap.allocator import keep_freed_memory
from pipemap.recorder import RecordSettings, record_run
from pipemap.replay import REPLAY_TOPICS, StreamSource, replay
from pipemap.sim.network import build_network

RECORDINGS = Path(__file__).resolve().parents[1] / "recordings"


def _replay_once(path: Path) -> tuple[float, float, float, int, int]:
    start, cpu = time.perf_counter(), time.process_time()
    # As `pipemap replay` reads it.
    result = replay(StreamSource(path, REPLAY_TOPICS), keep_sets=False)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    return wall, cpu, result.duration_ns / 1e9, result.images, len(result.visits)


def _line(name: str, path: Path, repeat: int) -> str:
    runs = [_replay_once(path) for _ in range(repeat)]
    wall, _, simulated, images, visits = min(runs)
    cpu = min(run[1] for run in runs)
    size = path.stat().st_size / 1e6
    return (
        f"  {name:<28} {size:5.1f} MB  {visits:3d} visits  {images:4d} images  "
        f"{simulated:6.1f} s simulated in {wall:5.2f} s  = {simulated / wall:6.0f}x real time, "
        f"{images / wall:6.0f} images/s; CPU {cpu:5.2f} s = {simulated / cpu:6.0f}x"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", nargs="*", type=Path)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--no-record", action="store_true", help="skip the 400 px run")
    args = parser.parse_args()
    keep_freed_memory()  # as pipemap's commands run (pipemap.allocator)
    logs = args.logs or sorted(RECORDINGS.glob("*.mcap"))
    print(f"replay, best of {args.repeat} (one core):")
    for path in logs:
        print(_line(path.name, path, args.repeat))
    if not args.no_record:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "paper_400.mcap"
            start = time.perf_counter()
            record_run(path, RecordSettings("paper"), build_network("paper", seed=0), __version__)
            recorded = time.perf_counter() - start
            print(_line("paper autonomous, 400 px", path, args.repeat))
            print(f"  (recording that log took {recorded:.2f} s wall)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
