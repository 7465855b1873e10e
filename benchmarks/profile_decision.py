"""Where a decision's CPU time goes: ``cProfile`` on process time over the decisions
of ``bench_localizer.py --json`` (the shared sets at 400 px, each a new junction
among ``--known`` distractors, the refinement cache emptied before each, as most
decisions of a real run find it).

Usage: ``python benchmarks/profile_decision.py [--known N] [--tries K] [--top T]``;
prints the CPU time per decision without the profiler, then the profile of the
same decisions: a decision's phases (cumulative), and the ``T`` functions that
take most time of their own (``tottime``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import cProfile  # noqa: E402
import pickle  # noqa: E402
import pstats  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_localizer as bench  # noqa: E402

from pipemap.allocator import keep_freed_memory  # noqa: E402
from pipemap.imagesets import load_image_set  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=Path, default=bench.DEFAULT_SETS)
    parser.add_argument("--known", type=int, default=10, help="distractor junctions (10)")
    parser.add_argument("--tries", type=int, default=3, help="decisions per query (3)")
    parser.add_argument("--top", type=int, default=25, help="functions to print (25)")
    args = parser.parse_args()
    keep_freed_memory()
    names = sorted(p.name for p in args.sets.iterdir() if p.is_dir())
    queries = [bench.resized(load_image_set(args.sets / n), 400) for n in names]
    localizer, _ = bench._distractor_localizer(queries, args.known, np.random.default_rng(7))
    saved = pickle.dumps(localizer.map, protocol=pickle.HIGHEST_PROTOCOL)
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


if __name__ == "__main__":
    sys.exit(main())
