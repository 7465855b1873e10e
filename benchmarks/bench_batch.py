"""Throughput of ``pipemap batch``: 2 workers against the same runs one after another.

    python benchmarks/bench_batch.py [--resolution PX] [--workers N] [--keep DIR]
                                     [--floor] [--address RAY_ADDRESS]

The SPEC has 12 runs, each its own recording (``paper`` and ``random:8``, seeds 0-2,
``perfect`` and ``autonomous``, 64 px, pipemap's default rule). Three measurements,
in one process, one after the other:

1. sequential: the 12 runs one after another in this process, with the very call a
   batch's worker makes (``pipemap.batch.run.run_recording``), no Ray, each log
   written in this process as a batch's task writes it;
2. the same with each log written by a writer process of its own, as ``pipemap
   record`` writes it (quicker for a run alone: it uses more than one core);
3. batch: ``pipemap batch SPEC --out DIR --workers 2`` as a user runs it, end to end
   (Python's start-up, Ray's start-up on this machine, the runs, the table).

Two more, if asked:

4. ``--floor``: the runs handed out as the batch hands them out (costliest first, in
   turn) to two plain Python processes, no engine at all, OpenCV on one thread each:
   what any scheduler could at best do with these runs on this machine;
5. ``--address``: ``pipemap batch SPEC --out DIR --address RAY_ADDRESS`` against a Ray
   cluster already running (``ray start --head ...``): no start or stop of Ray in the
   batch's time.

The issue's target: (3) takes at most 0.6 x the quicker of (1) and (2). Wall time is
what a user waits; since the machine may be shared, the load average (``uptime``) is printed before
and after each part, with the CPU seconds each part used: the runs' own CPU time
(process and log writer) in both, so that a difference in wall time can be told
from a difference in work.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SPEC = """\
description = "bench_batch: 12 recordings, 2 networks x 3 seeds x 2 conditions"

[grid]
network = ["paper", "random:8"]
seed = [0, 1, 2]
condition = ["perfect", "autonomous"]
resolution = [{resolution}]
rule = ["default"]
"""


def _uptime() -> str:
    with open("/proc/loadavg") as f:
        one, five, fifteen = f.read().split()[:3]
    return f"load average {one}, {five}, {fifteen}"


def _cpu_children() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _cpu_self() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def sequential(spec_path: Path, inline: bool) -> tuple[float, float, float]:
    """Wall s, runs' CPU s (this process and its log writers) and the sum of each
    run's own CPU figure, for the runs one after another, each log written in this
    process (``inline``, as a batch's task does) or by a writer process (as ``pipemap
    record`` does)."""
    from pipemap.batch import load_spec
    from pipemap.batch.run import run_recording

    spec = load_spec(spec_path)
    cpu0 = _cpu_self() + _cpu_children()
    started = time.perf_counter()
    task_cpu = 0.0
    for k, point in enumerate(spec.points):
        outcome = run_recording([point], inline=inline)
        task_cpu += outcome["cpu_s"]
        print(
            f"  sequential ({'inline' if inline else 'writer process'}) "
            f"{k + 1:2d}/{len(spec.points)} {point.run_id}: {outcome['wall_s']:.1f} s",
            flush=True,
        )
    wall = time.perf_counter() - started
    return wall, _cpu_self() + _cpu_children() - cpu0, task_cpu


def _child(spec_path: Path, indices: list[int]) -> None:
    """Part of ``--floor``: the given runs one after another, OpenCV on one thread."""
    import cv2

    from pipemap.batch import load_spec
    from pipemap.batch.run import run_recording

    cv2.setNumThreads(1)
    points = load_spec(spec_path).points
    for i in indices:
        run_recording([points[i]], inline=True)


def floor(spec_path: Path, processes: int) -> tuple[float, float]:
    """Wall s and CPU s of the runs split among plain processes as the batch hands
    them out (costliest first, in turn), no engine."""
    from pipemap.batch import load_spec
    from pipemap.batch.engine import _recordings

    points = load_spec(spec_path).points
    order = [points.index(group[0]) for group in _recordings(points)]
    cpu0 = _cpu_children()
    started = time.perf_counter()
    children = [
        subprocess.Popen(
            [sys.executable, __file__, "--child", str(spec_path), json.dumps(order[k::processes])]
        )
        for k in range(processes)
    ]
    if any(child.wait() != 0 for child in children):
        sys.exit("--floor: a plain process failed")
    return time.perf_counter() - started, _cpu_children() - cpu0


def batch(
    spec_path: Path, out: Path, workers: int, address: str | None = None
) -> tuple[float, float, float]:
    """Wall s of ``pipemap batch`` end to end, the CPU s of its process tree that
    this process could account (a lower bound: Ray's workers are not its children),
    and the sum of the runs' own CPU figures."""
    cpu0 = _cpu_children()
    started = time.perf_counter()
    where = ["--workers", str(workers)] if address is None else ["--address", address]
    done = subprocess.run(
        [sys.executable, "-m", "pipemap", "batch", str(spec_path), "--out", str(out), *where],
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"pipemap batch failed ({done.returncode}):\n{done.stderr}")
    rows = json.loads((out / "results.json").read_text())["runs"]
    task_cpu = 0.0
    for row in rows:
        result = json.loads((out / "runs" / row["run_id"] / "result.json").read_text())
        task_cpu += result["record"]["recording_cpu_s"]
    return wall, _cpu_children() - cpu0, task_cpu


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--resolution", type=int, default=64)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--keep", type=Path, default=None, help="keep the batch folder here")
    parser.add_argument(
        "--floor", action="store_true", help="also the runs in plain processes, no engine"
    )
    parser.add_argument(
        "--address", default=None, help="also the batch against this running Ray cluster"
    )
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        _child(Path(args.child[0]), json.loads(args.child[1]))
        return 0

    tmp = Path(tempfile.mkdtemp(prefix="pipemap-bench-batch-"))
    try:
        spec_path = tmp / "bench12.toml"
        spec_path.write_text(SPEC.format(resolution=args.resolution))
        print(
            f"# pipemap batch throughput: 12 runs at {args.resolution} px, {os.cpu_count()} cores"
        )
        print(f"before sequential: {_uptime()}", flush=True)
        s_wall, s_cpu, s_task = sequential(spec_path, inline=True)
        p_wall, p_cpu, p_task = sequential(spec_path, inline=False)
        print(f"after sequential:  {_uptime()}")
        print(f"before batch:      {_uptime()}", flush=True)
        out = tmp / "batch"
        b_wall, b_cpu, b_task = batch(spec_path, out, args.workers)
        print(f"after batch:       {_uptime()}")
        with (out / "results.csv").open() as f:
            rows = list(csv.DictReader(f))
        ok = sum(1 for r in rows if r["status"] == "ok")
        print()
        print(
            f"sequential, log inline, no Ray  : {s_wall:7.1f} s wall, "
            f"{s_task:6.1f} s CPU in the runs ({s_cpu:.1f} s in this process and its children)"
        )
        print(
            f"sequential, writer processes    : {p_wall:7.1f} s wall, "
            f"{p_task:6.1f} s CPU in the runs (as `pipemap record` writes a log)"
        )
        print(
            f"pipemap batch --workers {args.workers}        : {b_wall:7.1f} s wall, "
            f"{b_task:6.1f} s CPU in the runs ({ok}/{len(rows)} runs ok; "
            f">= {b_cpu:.1f} s CPU in its process tree)"
        )
        best = min(s_wall, p_wall)
        print(
            f"batch / sequential, wall time   : {b_wall / best:.2f} (target: at most 0.60; "
            f"against the quicker sequential way; {b_wall / s_wall:.2f} against inline, "
            f"{b_wall / p_wall:.2f} against writer processes)"
        )
        print(
            f"runs' CPU, batch / sequential   : {b_task / s_task:.2f} "
            "(above 1: the runs did the same work slower, e.g. sharing cores)"
        )
        if args.floor:
            f_wall, f_cpu = floor(spec_path, args.workers)
            print(
                f"{args.workers} plain processes, no engine: {f_wall:7.1f} s wall, {f_cpu:6.1f} s "
                f"CPU; / sequential: {f_wall / best:.2f} (the best a scheduler could do here)"
            )
        if args.address is not None:
            a_wall, _, _ = batch(spec_path, tmp / "batch-address", args.workers, args.address)
            print(
                f"pipemap batch --address        : {a_wall:7.1f} s wall (Ray already running); "
                f"/ sequential: {a_wall / best:.2f}"
            )
        if args.keep is not None:
            shutil.copytree(out, args.keep, dirs_exist_ok=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
