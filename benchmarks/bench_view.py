"""Viewing cost: a replay alone against a replay and its rerun recording saved to a file.

    python benchmarks/bench_view.py [--repeat N] [--log RUN.mcap ...] [--no-record]

For the stored logs (``recordings/*.mcap``, 96 px) and a 400 px ``pipemap record
--network paper`` log (recorded into a temporary folder unless ``--no-record``),
prints, best of N:

* in one process, rerun and pipemap already imported: the replay (read the log,
  rebuild the map) and the replay followed by ``save_view`` (the work ``pipemap view
  --save`` adds);
* end to end, as a user runs them: ``pipemap replay LOG -o MAP.json`` against
  ``pipemap view LOG --save OUT.rrd``, each in a fresh interpreter (this includes
  importing rerun, about 0.3 s).

The issue's target: viewing (saving to a file) adds at most 20% to the replay.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rerun  # noqa: F401  (imported up front: the in-process times leave it out)

from pipemap.replay import FileSource, replay
from pipemap.replay.view import save_view

REPO = Path(__file__).resolve().parents[1]


def _in_process(log: Path, out: Path, repeat: int) -> tuple[float, float]:
    replay_s, view_s = [], []
    for _ in range(repeat):
        # A new file each time, as a first save makes it: replacing a file on ext4
        # makes the kernel write the new one out first (auto_da_alloc), some 17 ms
        # for 23 MB, which is the file system's cost, not the view's.
        out.unlink(missing_ok=True)
        start = time.perf_counter()
        source = FileSource(log)
        result = replay(source)
        replayed = time.perf_counter()
        save_view(source, result, out)
        replay_s.append(replayed - start)
        view_s.append(time.perf_counter() - replayed)
    return min(replay_s), min(view_s)


def _cli(*args: str) -> float:
    env = {**os.environ, "RERUN_ANALYTICS": "false", "PYTHONPATH": str(REPO)}
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, env=env
    )
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"pipemap {' '.join(args)} failed: {done.stderr}")
    return wall


def _end_to_end(log: Path, folder: Path, repeat: int) -> tuple[float, float]:
    replay_s = [
        _cli("replay", str(log), "-o", str(folder / "map.json"), "--force") for _ in range(repeat)
    ]
    view_s = []
    for _ in range(repeat):
        (folder / "cli.rrd").unlink(missing_ok=True)
        view_s.append(_cli("view", str(log), "--save", str(folder / "cli.rrd")))
    return min(replay_s), min(view_s)


def _row(name: str, base: float, extra: float) -> str:
    return f"  {name:<34} {base:7.3f} s  {base + extra:7.3f} s  {100 * extra / base:+6.1f} %"


def main() -> None:
    """Print replay against replay + save for every log."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--log", type=Path, nargs="*", default=None)
    parser.add_argument("--no-record", action="store_true", help="skip the 400 px log")
    args = parser.parse_args()
    logs = list(args.log) if args.log else sorted((REPO / "recordings").glob("*.mcap"))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if not args.no_record and not args.log:
            big = folder / "paper_400px.mcap"
            _cli("record", "--network", "paper", "-o", str(big))
            logs.append(big)
        print(f"# replay vs replay + save (pipemap view --save), best of {args.repeat}")
        print(f"  {'log':<34} {'replay':>9}  {'+ save':>9}  {'added':>8}")
        for log in logs:
            mb = log.stat().st_size / 1e6
            name = f"{log.name} ({mb:.1f} MB)"
            base, extra = _in_process(log, folder / "view.rrd", args.repeat)
            rrd_mb = (folder / "view.rrd").stat().st_size / 1e6
            print(_row(name, base, extra) + f"   in process, .rrd {rrd_mb:.1f} MB")
            replay_s, view_s = _end_to_end(log, folder, args.repeat)
            print(_row("", replay_s, view_s - replay_s) + "   end to end (CLI)")


if __name__ == "__main__":
    main()
