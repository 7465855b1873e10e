"""Peak memory of ``pipemap info``, ``replay`` and ``view --save`` against a log's length.

A long run's log is mostly its high-rate streams. This writes synthetic logs of
``--minutes`` of robot time each (default 15 and 120) with pipemap's own writer, at
the simulator's rates: ranges 20 Hz, IMU 100 Hz, wheel encoders 50 Hz, controller
and true pose 20 Hz (no sweeps, so no decisions: what is measured is what reading
the streams costs), then runs each command on each log in a child process and
reads the child's own peak resident memory (``os.wait4``). ``view`` is run at its
default ``--max-rate`` (10 Hz) and with ``--max-rate 0`` (every message).

Usage: ``python benchmarks/bench_long_log.py [--minutes 15,120] [--dir DIR]``;
prints JSON: per log its messages and size, per command its wall and CPU time, peak
memory and (for ``view``) the recording's size.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pipemap.recorder import LogWriter, Topic, schemas
from pipemap.recorder.messages import pose_message

#: The streams written, as (topic, rate in Hz).
RATES_HZ = (
    (Topic.IMU, 100),
    (Topic.WHEELS, 50),
    (Topic.RANGES, 20),
    (Topic.CONTROLLER, 20),
    (Topic.TRUE_POSE, 20),
)
_TICK_NS = 10_000_000  # 100 Hz: every stream's period is a whole number of ticks


def _message(topic: str, t_ns: int, tick: int) -> object:
    s = t_ns / 1e9
    if topic == Topic.IMU:
        return schemas.Imu(time_ns=t_ns, yaw_rate_rps=0.1 * math.sin(s), accel_forward_mps2=0.01)
    if topic == Topic.WHEELS:
        return schemas.WheelEncoders(time_ns=t_ns, left_ticks=tick, right_ticks=tick + 1)
    if topic == Topic.RANGES:
        return schemas.Ranges(
            time_ns=t_ns, front_m=1.0 + 0.5 * math.sin(s), front_left_m=0.1, front_right_m=0.1
        )
    if topic == Topic.CONTROLLER:
        state = "follow" if (tick // 3000) % 2 == 0 else "turn"
        return schemas.ControllerState(time_ns=t_ns, state=state, linear_mps=0.05)
    return pose_message(t_ns, 0.05 * s, 0.0, 0.0)


def write_long_log(path: Path, minutes: float) -> int:
    """A log of ``minutes`` of the high-rate streams; returns its message count."""
    ticks = round(minutes * 60 * 1e9 / _TICK_NS)
    count = 0
    with (
        path.open("wb") as f,
        LogWriter(f, {"pipemap_version": "bench", "network": "synthetic"}) as writer,
    ):
        for tick in range(ticks):
            t_ns = tick * _TICK_NS
            for topic, rate in RATES_HZ:
                if tick % (100 // rate) == 0:
                    writer.write(topic, t_ns, _message(topic, t_ns, tick))
                    count += 1
        writer.finish({"status": "finished"})
    return count


def run(*args: str) -> dict[str, float]:
    """``pipemap ARGS`` in a child process: its wall time, its own CPU time and peak
    memory (not those of a child it forks: ``view`` replays in one)."""
    start = time.perf_counter()
    child = subprocess.Popen(
        [sys.executable, "-m", "pipemap", *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    assert child.stderr is not None
    err = child.stderr.read().decode()
    child.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"pipemap {' '.join(args)} failed: {err}")
    return {
        "wall_s": round(wall, 2),
        "cpu_s": round(usage.ru_utime + usage.ru_stime, 2),
        "peak_mib": round(usage.ru_maxrss / 1024, 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", default="15,120", help="log lengths (15,120)")
    parser.add_argument("--dir", type=Path, default=None, help="where the logs go (a temp dir)")
    args = parser.parse_args()
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.dir if args.dir is not None else Path(tmp)
        for minutes in (float(m) for m in args.minutes.split(",")):
            log = folder / f"long{minutes:g}min.mcap"
            messages = write_long_log(log, minutes)
            row: dict[str, object] = {
                "minutes": minutes,
                "messages": messages,
                "log_mb": round(log.stat().st_size / 1e6, 1),
                "info": run("info", str(log)),
                "replay": run("replay", str(log), "-o", str(folder / "map.json"), "--force"),
            }
            for rate in ("10", "0"):
                rrd = folder / f"view{rate}.rrd"
                viewed = run("view", str(log), "--save", str(rrd), "--force", "--max-rate", rate)
                viewed["rrd_mb"] = round(rrd.stat().st_size / 1e6, 1)
                row[f"view_max_rate_{rate}"] = viewed
            results.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    print(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
