"""Where a decision's CPU time goes: ``cProfile`` on process time over the decisions
of ``bench_localizer.py --json`` (the shared sets at 400 px, each a new junction
among ``--known`` distractors, the refinement cache emptied before each, as most
decisions of a real run find it).

Usage: ``python benchmarks/profile_decision.py [--known N] [--tries K] [--top T]
[--px P] [--phases]`` (``--px``: the sets' size, 400 by default); prints the CPU
time per decision without the profiler, then the profile of the same decisions: a
decision's phases (cumulative), and the ``T`` functions that take most time of
their own (``tottime``). With ``--phases``, it
prints instead, as JSON, the median CPU time of each phase of a decision timed by
the localizer's own clock (:mod:`localizer.phases`), the matcher's preparation of
the sweep split from the rest of ``ncc``, without the profiler's overhead (which
falls mostly on Python code and so shifts the shares).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import cProfile  # noqa: E402
import json  # noqa: E402
import pickle  # noqa: E402
import pstats  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_localizer as bench  # noqa: E402

from pipemap.allocator import keep_freed_memory  # noqa: E402
from pipemap.imagesets import load_image_set  # noqa: E402
from pipemap.localizer import Localizer  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=Path, default=bench.DEFAULT_SETS)
    parser.add_argument("--known", type=int, default=10, help="distractor junctions (10)")
    parser.add_argument("--tries", type=int, default=3, help="decisions per query (3)")
    parser.add_argument("--top", type=int, default=25, help="functions to print (25)")
    parser.add_argument("--px", type=int, default=400, help="image size (400)")
    parser.add_argument(
        "--phases", action="store_true", help="median CPU ms of each phase, as JSON"
    )
    args = parser.parse_args()
    keep_freed_memory()
    names = sorted(p.name for p in args.sets.iterdir() if p.is_dir())
    queries = [bench.resized(load_image_set(args.sets / n), args.px) for n in names]
    localizer, _ = bench._distractor_localizer(queries, args.known, np.random.default_rng(7))
    saved = pickle.dumps(localizer.map, protocol=pickle.HIGHEST_PROTOCOL)
    if args.phases:
        print(json.dumps(phases(localizer, queries, args.known, args.tries, saved), indent=1))
        return 0
    profile = cProfile.Profile(time.process_time)

    def decide(profiled: bool) -> float:
        spent = 0.0
        for query in queries:
            for _ in range(args.tries):
                localizer._matcher._fine_cache.clear()
                start = time.process_time()
                if profiled:
                    profile.runcall(localizer.localize, query)
                else:
                    localizer.localize(query)
                spent += time.process_time() - start
                bench._forget_after(localizer, args.known, saved)
        return spent / (len(queries) * args.tries)

    decide(False)  # warm up (imports, allocator)
    print(f"{args.known} known junctions: {decide(False) * 1000:.1f} ms CPU a decision")
    decide(True)
    stats = pstats.Stats(profile)
    # A decision's phases: prepare, screen and refine (``_best``), the keypoints of
    # the sweep (``stored_features``), the two-view check (``_verified``).
    stats.sort_stats("cumulative").print_stats(r"\((localize|_best|stored_features|_verified)\)")
    stats.sort_stats("tottime").print_stats(args.top)
    return 0


#: The phases as printed: a decision's own order (``ncc`` less ``prepare``), then the whole.
_PHASE_ORDER = ("prepare", "ncc", "keypoints", "check", "map", "decision")


def phases(localizer: Localizer, queries: list, known: int, tries: int, saved: bytes) -> dict:  # type: ignore[type-arg]
    """Median CPU ms of each phase over ``tries`` decisions of every query (after one
    to warm up), each a new junction's with the refinement cache emptied; ``prepare``
    (the matcher's preparation of the sweep) is taken out of ``ncc``."""
    matcher = localizer._matcher
    prepare = matcher.prepare
    spent = [0.0]

    def timed_prepare(image_set):  # type: ignore[no-untyped-def]
        start = time.process_time()
        try:
            return prepare(image_set)
        finally:
            spent[0] += time.process_time() - start

    matcher.prepare = timed_prepare  # type: ignore[method-assign]
    localizer._clock = time.process_time
    per_phase: dict[str, list[float]] = {}
    for attempt in range(tries + 1):
        for query in queries:
            matcher._fine_cache.clear()
            spent[0] = 0.0
            start = time.process_time()
            localizer.localize(query)
            whole = time.process_time() - start
            if attempt:  # the first round warms up
                laps = dict(localizer.last_phases, prepare=spent[0], decision=whole)
                laps["ncc"] -= spent[0]
                for phase, seconds in laps.items():
                    per_phase.setdefault(phase, []).append(seconds * 1000)
            bench._forget_after(localizer, known, saved)
    return {
        "resolution_px": queries[0].width,
        "known": known,
        "decisions": len(queries) * tries,
        "cpu_ms": {k: round(statistics.median(per_phase[k]), 2) for k in _PHASE_ORDER},
    }


if __name__ == "__main__":
    sys.exit(main())
