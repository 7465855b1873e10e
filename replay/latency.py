"""Summaries of decision latency: its spread over the decisions, and its phases.

Timing is the one part of a score that is not deterministic; ``pipemap score`` leaves
it out of every comparison (:meth:`replay.score.ScoreReport.document`).
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence

from pipemap.localizer import PHASES

__all__ = ["latency_summary", "phase_means"]


def phase_means(phases: Sequence[Mapping[str, float | None]]) -> dict[str, float | None]:
    """The mean time of the decisions (each ``{phase: ms}``, ``None`` untimed) in each
    phase of :data:`localizer.phases.PHASES` (ms, to 1e-3; ``None`` without a timed
    decision): where the latency goes."""
    means: dict[str, float | None] = {}
    for phase in PHASES:
        times = [t for p in phases if (t := p.get(phase)) is not None]
        means[phase] = round(statistics.fmean(times), 3) if times else None
    return means


def latency_summary(latencies: Sequence[float]) -> dict[str, float | None]:
    """Mean, median, 95th percentile and largest of the decisions' latencies (ms,
    to 1e-3; ``None`` without a decision). A robot waits at the junction for every
    decision, so the tail matters as much as the mean: the percentile is numpy's
    linear one (``statistics.quantiles``, inclusive), the largest itself for one
    decision."""
    if not latencies:
        return dict.fromkeys(("mean", "median", "p95", "max"))
    ordered = sorted(latencies)
    p95 = (
        ordered[0]
        if len(ordered) == 1
        else statistics.quantiles(ordered, n=20, method="inclusive")[18]
    )
    return {
        "mean": round(statistics.fmean(ordered), 3),
        "median": round(statistics.median(ordered), 3),
        "p95": round(p95, 3),
        "max": round(ordered[-1], 3),
    }
