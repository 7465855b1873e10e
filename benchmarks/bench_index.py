"""What the localizer's index keeps of the exhaustive screen's ranking.

A matcher knows ``--distractors`` augmented copies of the paper's shared sets (as
``bench_localizer.py`` draws them, 400 px) and then the 11 shared sets themselves.
Each shared set is then a query: the exhaustive screen ranks every other known set,
and the index (:mod:`pipemap.localizer.index`) ranks them by descriptor. Prints JSON:
for each query, the index's rank of the screen's best 4 (the candidates a decision
refines and checks) and of the query's true junction's other sets, and in all how
many of the screen's best 1 and best 4 fall in the index's shortlist of
``SHORTLIST`` (64); and, for each shortlist length of ``--shortlists``, how many of
those and of the sets of the query's junction seen from another entry (``1`` and
``2``, not ``1`` and ``1_noise``: what a revisit from a new pipe must find) the
shortlist holds.

Usage: ``python benchmarks/bench_index.py [--distractors 300] [--shortlists 64,128,256]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import bench_localizer as bench  # noqa: E402

from pipemap.localizer import FastMatcher  # noqa: E402
from pipemap.localizer.fastmatch import _descriptor_of  # noqa: E402
from pipemap.localizer.index import SHORTLIST  # noqa: E402
from pipemap.localizer.spectra import _offset_scores  # noqa: E402


def _ranks(scores: np.ndarray) -> np.ndarray:
    """Rank of each entry, 0 for the highest (ties to the earliest)."""
    order = np.lexsort((np.arange(scores.size), -scores))
    ranks = np.empty(scores.size, dtype=np.int64)
    ranks[order] = np.arange(scores.size)
    return ranks


def _base(name: str) -> str:
    """The sweep a shared set was made from: ``1`` for ``1``, ``1_noise``, ``1_active``."""
    return name.split("_")[0]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--distractors", type=int, default=300)
    parser.add_argument("--shortlists", default="64,128,256", help="lengths to count recall at")
    args = parser.parse_args()
    names = sorted(p.name for p in bench.DEFAULT_SETS.iterdir() if p.is_dir())
    sets = {n: bench.resized(bench.load_image_set(bench.DEFAULT_SETS / n), 400) for n in names}
    info = {n: bench.read_info(bench.DEFAULT_SETS / n) for n in names}
    rng = np.random.default_rng(7)
    matcher = FastMatcher()
    for _ in range(args.distractors):
        matcher.add(matcher.prepare(bench.augmented_set(list(sets.values()), rng)))
    first = len(matcher)
    prepared = {n: matcher.prepare(s) for n, s in sets.items()}
    for n in names:
        matcher.add(prepared[n])
    rows = []
    kept_best = kept_top4 = 0
    lengths = [int(x) for x in args.shortlists.split(",")]
    recall = {k: {"screen_best": 0, "screen_top4": 0, "other_entry": 0} for k in lengths}
    other_entries = 0
    for k, n in enumerate(names):
        query, me = prepared[n], first + k
        peaks, _ = matcher.screen(query)
        screen = _offset_scores(peaks).max(axis=1)
        screen[me] = -np.inf
        known = matcher._index._rows[: len(matcher)] @ _descriptor_of(query)
        known[me] = -np.inf
        index_rank = _ranks(known)
        top4 = np.argsort(-screen, kind="stable")[:4]
        same = [
            first + j
            for j, other in enumerate(names)
            if other != n and bench._same_junction(info[n], info[other])
        ]
        # The same junction from another entry: another base name (``1``, not ``1_noise``).
        other = [
            first + j for j, o in enumerate(names) if first + j in same and _base(o) != _base(n)
        ]
        other_entries += len(other)
        for k in lengths:
            recall[k]["screen_best"] += int(index_rank[top4[0]] < k)
            recall[k]["screen_top4"] += int((index_rank[top4] < k).sum())
            recall[k]["other_entry"] += int((index_rank[other] < k).sum())
        kept_best += int(index_rank[top4[0]] < SHORTLIST)
        kept_top4 += int((index_rank[top4] < SHORTLIST).sum())
        rows.append(
            {
                "query": n,
                "index_rank_of_screen_top4": index_rank[top4].tolist(),
                "index_rank_of_same_junction": sorted(index_rank[same].tolist()),
                "screen_rank_of_same_junction": sorted(_ranks(screen)[same].tolist()),
            }
        )
    print(
        json.dumps(
            {
                "known": len(matcher) - 1,
                "shortlist": SHORTLIST,
                "screen_best_in_shortlist": f"{kept_best}/{len(names)}",
                "screen_top4_in_shortlist": f"{kept_top4}/{4 * len(names)}",
                "recall": {
                    str(k): {
                        "screen_best": f"{r['screen_best']}/{len(names)}",
                        "screen_top4": f"{r['screen_top4']}/{4 * len(names)}",
                        "other_entry": f"{r['other_entry']}/{other_entries}",
                    }
                    for k, r in recall.items()
                },
                "queries": rows,
            },
            indent=1,
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
