"""Where competing maps spend a decision's time: ``cProfile`` of the localizer's
decisions during a replay, at the defaults and with one map (``--hypotheses 1``).

    python benchmarks/profile_hypotheses.py LOG [--top T]

Replays LOG as ``pipemap score`` does (``api.replay``), twice, with the profiler
on only inside ``Localizer.localize`` (reading the log is left out), and prints
for each run the CPU seconds of the decisions under the profiler, the calls and
cumulative seconds of the steps competing maps add (the two-view fits asked,
``Localizer._fit``, by caller, and those computed, ``candidate_fit``: the rest
were kept from earlier in the visit, :mod:`localizer.fitcache`; the branches; the
maps' copies, visits and planarity test), and the ``T`` functions with most
cumulative time. The profiler's overhead
falls mostly on Python code; ``bench_score.py`` measures the latency itself.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import cProfile  # noqa: E402
import io  # noqa: E402
import pstats  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402

from pipemap import api  # noqa: E402
from pipemap.allocator import keep_freed_memory  # noqa: E402
from pipemap.localizer import LocalizerConfig  # noqa: E402
from pipemap.localizer import localizer as localizer_module  # noqa: E402

cv2.setNumThreads(1)

#: (function name, file name ending) of the steps competing maps add or repeat.
STEPS = (
    ("_verified", "localizer.py"),
    ("fit_once", "fitcache.py"),
    ("candidate_fit", "verify.py"),
    ("_repeats_far", "branching.py"),
    ("alike_branches", "branching.py"),
    ("new_branch", "branching.py"),
    ("_repeats", "branching.py"),
    ("visit", "hypotheses.py"),
    ("_prune", "hypotheses.py"),
    ("embeds_in_plane", "hypotheses.py"),
    ("copy", "topomap.py"),
)


def profiled_replay(log: api.Log, config: LocalizerConfig) -> tuple[pstats.Stats, int]:
    """The profile of every ``localize`` call of one replay of ``log``, and the calls."""
    profiler = cProfile.Profile(time.process_time)
    real = localizer_module.Localizer.localize
    calls = 0

    def localize(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        nonlocal calls
        calls += 1
        profiler.enable()
        try:
            return real(self, *args, **kwargs)
        finally:
            profiler.disable()

    localizer_module.Localizer.localize = localize  # type: ignore[method-assign]
    try:
        api.replay(log, config)
    finally:
        localizer_module.Localizer.localize = real  # type: ignore[method-assign]
    return pstats.Stats(profiler), calls


def report(name: str, stats: pstats.Stats, calls: int, top: int) -> None:
    total = stats.total_tt  # type: ignore[attr-defined]
    print(f"## {name}: {calls} decisions, {total:.2f} s CPU under the profiler")
    table = stats.stats  # type: ignore[attr-defined]
    for func, file_end in STEPS:
        for (path, _line, fname), (_cc, ncalls, _tt, cumtime, callers) in table.items():
            if fname != func or not path.endswith(file_end):
                continue
            print(f"  {func:<16} {ncalls:>5} calls {cumtime:7.2f} s cumulative")
            if func == "fit_once":
                for (c_path, _l, c_name), c_stats in sorted(callers.items()):
                    print(
                        f"    from {Path(c_path).name}:{c_name:<16} {c_stats[1]:>5} calls "
                        f"{c_stats[3]:7.2f} s"
                    )
    out = io.StringIO()
    stats.stream = out  # type: ignore[attr-defined]
    stats.sort_stats("cumulative").print_stats(top)
    lines = [line for line in out.getvalue().splitlines() if line.strip()]
    start = next((i for i, line in enumerate(lines) if "ncalls" in line), len(lines))
    print("\n".join(lines[start:]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--top", type=int, default=20)
    args = parser.parse_args()
    keep_freed_memory()  # as pipemap's commands run (pipemap.allocator)
    log = api.open_log(args.log)
    defaults = LocalizerConfig()
    print(f"# {args.log.name}")
    one = replace(defaults, hypotheses=1)
    for name, config in (("defaults", defaults), ("--hypotheses 1", one)):
        stats, calls = profiled_replay(log, config)
        report(name, stats, calls, args.top)
    return 0


if __name__ == "__main__":
    sys.exit(main())
