"""Decision latency during a replay: the defaults against the paper's NCC alone.

    python benchmarks/bench_score.py LOG [--repeat N]
                                     [--against no-two-view|no-odometry-check|one-hypothesis]

Replays LOG the way ``pipemap score`` does (``api.replay``), once at pipemap's
defaults and once without the two-view check (``--no-two-view``), N times each
(3 by default), on one core, and times every ``Localizer.localize`` call by CPU
(``time.process_time``) and wall clock. Per visit the quickest of the N tries is
kept (the others measure what else the machine was doing); prints the mean,
median and largest over the visits, the ratio of the means, and where the time of
the defaults goes (the phases of :mod:`pipemap.localizer.phases`, wall clock, each
visit's quickest try). Issue 17's target: the defaults at most 2x
``--no-two-view`` on a 400 px ``paper`` log. ``--against no-odometry-check`` compares
the defaults with the localizer's odometry check off instead, ``--against
one-hypothesis`` with one map (``--hypotheses 1``: no competing maps) (docs/lookalike.md).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402

from pipemap import api  # noqa: E402
from pipemap.allocator import keep_freed_memory  # noqa: E402
from pipemap.localizer import PHASES, LocalizerConfig  # noqa: E402
from pipemap.localizer import localizer as localizer_module  # noqa: E402

cv2.setNumThreads(1)


Timed = tuple[float, float, dict[str, float]]


def timed_replay(log: api.Log, config: LocalizerConfig) -> list[Timed]:
    """(CPU s, wall s, wall s by phase) of every localize call of one replay of ``log``."""
    calls: list[tuple[float, float]] = []
    real = localizer_module.Localizer.localize

    def localize(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        cpu, wall = time.process_time(), time.perf_counter()
        decision = real(self, *args, **kwargs)
        calls.append((time.process_time() - cpu, time.perf_counter() - wall))
        return decision

    localizer_module.Localizer.localize = localize  # type: ignore[method-assign]
    try:
        result = api.replay(log, config)
    finally:
        localizer_module.Localizer.localize = real  # type: ignore[method-assign]
    return [(*call, dict(v.phases_s)) for call, v in zip(calls, result.visits, strict=True)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--against",
        choices=["no-two-view", "no-odometry-check", "one-hypothesis"],
        default="no-two-view",
    )
    args = parser.parse_args()
    keep_freed_memory()  # as pipemap's commands run (pipemap.allocator)
    log = api.open_log(args.log)
    defaults = LocalizerConfig()
    other = "--hypotheses 1" if args.against == "one-hypothesis" else f"--{args.against}"
    against = {
        "no-two-view": replace(defaults, two_view=False, verify=False),
        "no-odometry-check": replace(defaults, odometry_check=False),
        "one-hypothesis": replace(defaults, hypotheses=1),
    }
    configs = {"defaults": defaults, other: against[args.against]}
    tries: dict[str, list[list[Timed]]] = {name: [] for name in configs}
    for _ in range(args.repeat):
        for name, config in configs.items():
            tries[name].append(timed_replay(log, config))
    means = {}
    print(f"# {args.log.name}: {args.repeat} replays each, quickest per visit, one core")
    for name, runs in tries.items():
        cpu = [min(run[v][0] for run in runs) * 1000 for v in range(len(runs[0]))]
        wall = [min(run[v][1] for run in runs) * 1000 for v in range(len(runs[0]))]
        means[name] = statistics.fmean(cpu)
        print(
            f"{name:<14} {len(cpu)} decisions  CPU ms mean {means[name]:.1f} median "
            f"{statistics.median(cpu):.1f} max {max(cpu):.1f}  wall ms mean "
            f"{statistics.fmean(wall):.1f}"
        )
    print(f"defaults / {other} (CPU means): {means['defaults'] / means[other]:.2f}x")
    for name, runs in tries.items():
        quickest = [min((run[v] for run in runs), key=lambda t: t[1]) for v in range(len(runs[0]))]
        spent = ", ".join(
            f"{p} {statistics.fmean(t[2][p] for t in quickest) * 1000:.1f}" for p in PHASES
        )
        print(f"{name:<14} wall ms by phase (mean): {spent}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
