"""Replay and scoring: rebuild the map from a log, deterministically, and measure it.

:func:`replay` reads a log's ``/robot`` messages only, in the total order
``(log time, topic, sequence)``, and feeds the localizer; :func:`score` compares
a replay with the log's ground truth.
"""

from __future__ import annotations

from pipemap.replay.replayer import (
    REPLAY_TOPICS,
    LoggedSweep,
    ReplayResult,
    VisitDecision,
    replay,
    sweeps_of,
    takes_recorded_threshold,
)
from pipemap.replay.score import (
    SCORE_TOPICS,
    PairStatistics,
    ScoreReport,
    VisitScore,
    pair_statistics,
    score,
    score_replay,
    true_sweeps,
)
from pipemap.replay.source import (
    FileSource,
    MemorySource,
    MessageSource,
    StreamSource,
    ordered,
)

__all__ = [
    "REPLAY_TOPICS",
    "SCORE_TOPICS",
    "FileSource",
    "LoggedSweep",
    "MemorySource",
    "MessageSource",
    "PairStatistics",
    "ReplayResult",
    "ScoreReport",
    "StreamSource",
    "VisitDecision",
    "VisitScore",
    "ordered",
    "pair_statistics",
    "replay",
    "score",
    "score_replay",
    "sweeps_of",
    "takes_recorded_threshold",
    "true_sweeps",
]
