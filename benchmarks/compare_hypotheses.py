"""What competing maps changed in recorded runs: each log's online decisions against a
replay with one map.

    python benchmarks/compare_hypotheses.py LOG [LOG ...]

For each pipemap log (``bench_explore.py --keep DIR`` keeps them): the online
decisions (``/online/decision``, made with the hypotheses the run was recorded with,
8 by default) against a replay of the same log with one map (``--hypotheses 1``, as
``pipemap score LOG --hypotheses 1`` replays it), each decision as its message less
the time it was logged at (the online decision is stamped when made, a replay's at
its sweep's end). One line per log: the decisions, how many are the same message,
the first that differs, how many online decisions were made with more than one map
alive and how many were deferred, then the one-map replay's map and its decisions by
outcome as ``pipemap score`` counts them. While every decision is the same, a run
with one map drives the same path (the explorer plans on the decisions), so equal
decisions mean the competing maps changed nothing on that run.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from pipemap.localizer import LocalizerConfig
from pipemap.recorder import Topic, read_log, schemas
from pipemap.recorder.messages import decision_message
from pipemap.replay import FileSource, replay, score_replay


def _logged(path: Path) -> list[schemas.Decision]:
    return [
        schemas.Decision.FromString(m.data)
        for m in read_log(path).messages
        if m.topic == Topic.DECISION
    ]


def compare(path: Path) -> str:
    """The line for one log."""
    online = _logged(path)
    source = FileSource(path)
    one = replace(LocalizerConfig(), hypotheses=1)
    # As pipemap score LOG --hypotheses 1 replays it: the recorded threshold and drift.
    result = replay(source, one, keep_sets=False, recorded_threshold=True)
    replayed = [
        decision_message(0, v.visit_id, v.decision, d.threshold)
        for v, d in zip(result.visits, online, strict=False)
    ]
    for d in online:
        d.time_ns = 0
    same = [
        a.SerializeToString() == b.SerializeToString()
        for a, b in zip(online, replayed, strict=False)
    ]
    first = next((online[i].visit_id for i, s in enumerate(same) if not s), None)
    multi = sum(d.HasField("hypotheses") and d.hypotheses > 1 for d in online)
    deferred = sum(len(d.deferred) > 0 for d in online)
    report = score_replay(result, source, result.localizer.config.threshold, one.fast)
    counts = report.counts()
    differs = "none differs" if first is None else f"first differing: visit {first}"
    return (
        f"{path.name}: {len(online)} online decisions, {len(result.visits)} with one map, "
        f"{sum(same)} the same ({differs}); online with more than one map alive {multi}, "
        f"deferred {deferred}; one map: map {report.map_status}, "
        f"{counts['correct_known']} correct known, {counts['correct_new']} correct new, "
        f"{counts['false_merge']} false merges, {counts['false_new']} false new"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", type=Path, nargs="+", metavar="LOG")
    args = parser.parse_args()
    for path in args.logs:
        print(compare(path), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
