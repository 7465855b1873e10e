"""What the two-view check's closer look changes in recorded runs: each log replayed at
the defaults against the same replay without it.

    python benchmarks/compare_closer_look.py LOG [LOG ...]

The closer look (:mod:`pipemap.localizer.closer`) fits the junction the map expects
once more on keypoints at full detail when the fit on reduced images falls short.
For each pipemap log, one line: the decisions, how many closer looks the replay at
the defaults took, how many decisions are the same message without it and the first
that is not, the visits whose outcome as ``pipemap score`` counts them changes, and
both replays' maps and decisions by outcome. Both replays take the recorded
threshold, as ``pipemap score LOG`` does.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from pipemap.localizer import LocalizerConfig
from pipemap.recorder.messages import decision_message
from pipemap.replay import FileSource, ReplayResult, replay, score_replay
from pipemap.replay.score import ScoreReport


def _scored(path: Path, config: LocalizerConfig) -> tuple[ReplayResult, ScoreReport]:
    source = FileSource(path)
    result = replay(source, config, keep_sets=False, recorded_threshold=True)
    return result, score_replay(result, source, result.localizer.config.threshold, config.fast)


def _outcome(report: ScoreReport) -> str:
    counts = report.counts()
    return (
        f"map {report.map_status}, {counts['correct_known']} correct known, "
        f"{counts['correct_new']} correct new, {counts['false_merge']} false merges, "
        f"{counts['false_new']} false new"
    )


def compare(path: Path) -> str:
    """The line for one log."""
    on, on_report = _scored(path, LocalizerConfig())
    off, off_report = _scored(path, replace(LocalizerConfig(), closer_keypoints_per_image=0))
    messages = [
        [decision_message(0, v.visit_id, v.decision, 0.0).SerializeToString() for v in r.visits]
        for r in (on, off)
    ]
    same = sum(a == b for a, b in zip(*messages, strict=True))
    first = next((v.visit_id for v, a, b in zip(on.visits, *messages, strict=True) if a != b), None)
    outcomes = [
        f"{a.visit} {b.outcome} -> {a.outcome}"
        for a, b in zip(on_report.visits, off_report.visits, strict=True)
        if a.outcome != b.outcome
    ]
    return (
        f"{path.name}: {len(on.visits)} decisions, {on.localizer._closer.taken} closer "
        f"look(s); {same} the same as without it (first differing: visit {first}); "
        f"outcomes changed: {', '.join(outcomes) or 'none'}; with it: {_outcome(on_report)}; "
        f"without: {_outcome(off_report)}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", type=Path, nargs="+", metavar="LOG")
    for line in map(compare, parser.parse_args(argv).logs):
        print(line, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
