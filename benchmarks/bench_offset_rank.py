"""Whether the screen's ranking of cyclic offsets could spare the refinement offsets.

The localizer refines its best candidate at every cyclic offset
(``FastConfig.refine_offsets``) and takes the best refined one; ``pipemap match``
refines only the offsets its screen puts near the best (``localizer/pairwise.py``).
This replays logs (the stored ones by default) and, for every match of a visit's
or a probe's sweep, ranks the offset the refinement chose among the screen's
offset scores of that candidate (0: the screen's best too) and measures how far
below the screen's best it scored. Refining only the offsets within a margin of
the screen's best keeps every similarity only if the margin exceeds every gap.

Prints JSON, one entry a log: the matches, how many had the chosen offset at each
screen rank, the largest gap, and the largest where the similarity was at least 0.3
(plausible revisits).

Usage: ``python benchmarks/bench_offset_rank.py [LOG.mcap ...]``.
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

from pipemap.localizer import fastmatch  # noqa: E402
from pipemap.localizer.spectra import _offset_scores  # noqa: E402
from pipemap.replay import FileSource, replay  # noqa: E402

RECORDINGS = Path(__file__).resolve().parents[1] / "recordings"


def _observed(found: list[tuple[int, float, float]]):  # type: ignore[no-untyped-def]
    """``FastMatcher.match`` that also records, for the candidate refined at every
    offset, (screen rank of the chosen offset, its gap to the screen's best, the
    refined similarity) in ``found``."""
    match = fastmatch.FastMatcher.match

    def observed(self, query, exclude=None, expected=()):  # type: ignore[no-untyped-def]
        matches = match(self, query, exclude, expected)
        subset = None
        if len(self._sets) > self.index_above:
            subset = self._index.nearest(self._descriptor(query), self.shortlist, expected)
        peaks, _ = self.screen(query, subset)
        ids = list(range(len(self._sets))) if subset is None else subset.tolist()
        scores = _offset_scores(peaks)
        baseline = [(query.baseline + self._sets[i].baseline) / 2.0 for i in ids]
        rows = [r for r, i in enumerate(ids) if i != exclude]
        if rows:  # the screen's best candidate is the one refined at every offset
            top = min(rows, key=lambda r: (-(float(scores[r].max()) - baseline[r]), ids[r]))
            chosen = matches[ids[top]].image_shift
            row = scores[top]
            rank = int((row > row[chosen]).sum())
            found.append((rank, float(row.max() - row[chosen]), matches[ids[top]].similarity))
        return matches

    return observed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", nargs="*", type=Path)
    args = parser.parse_args()
    logs = args.logs or sorted(RECORDINGS.glob("*.mcap"))
    found: list[tuple[int, float, float]] = []
    fastmatch.FastMatcher.match = _observed(found)  # type: ignore[method-assign]
    result = {}
    for log in logs:
        found.clear()
        replay(FileSource(log))
        ranks = np.array([f[0] for f in found], dtype=np.int64)
        gaps = np.array([f[1] for f in found])
        sims = np.array([f[2] for f in found])
        result[log.name] = {
            "matches": len(found),
            "chosen_offset_screen_rank": np.bincount(ranks).tolist(),
            "max_gap": round(float(gaps.max(initial=0.0)), 4),
            "max_gap_similarity_0.3": round(float(gaps[sims >= 0.3].max(initial=0.0)), 4),
        }
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
