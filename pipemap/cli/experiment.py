"""``pipemap experiment paper``: the paper's experiments, run in our simulator.

Every run is recorded with ``pipemap record``'s code path and then replayed and
scored from its log, exactly as a user would, so the numbers here are the numbers
``pipemap score`` gives. Three experiments on the ``paper`` network:

* the five conditions (perfect, noise, active, entrance, autonomous), from S, with
  the paper's sweeps (starting straight ahead) and with pipemap's aligned sweeps:
  similarity of every pair of visits to the same junction and to different
  junctions (Table 1, Figure 7), the rotation error of same-junction pairs
  (Table 2), and the decisions of the replayed localizer;
* 6, 9, 18 and 36 images per sweep in the perfect condition, paper's sweeps
  (Figure 6);
* the autonomous exploration from each of the seven nodes, at pipemap's defaults.

The autonomous robot explores by the paper's right-hand rule (``--explore
right-hand``), as published. On ``paper``, a tree, pipemap's map-driven exploration
takes the same walk.

This module computes; :mod:`pipemap.cli.experiment_report` writes the files.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from pipemap import __version__
from pipemap.localizer import PAPER
from pipemap.recorder import Explore, RecordSettings, record_run
from pipemap.replay import FileSource, PairStatistics, replay, score_replay
from pipemap.sim.episode import Condition
from pipemap.sim.network import build_network

__all__ = [
    "CONDITIONS",
    "CONVENTIONS",
    "IMAGE_COUNTS",
    "ExperimentResult",
    "ExperimentSettings",
    "STARTS",
    "RunOutcome",
    "paper_experiment",
    "summary",
]

CONDITIONS = ("perfect", "noise", "active", "entrance", "autonomous")
IMAGE_COUNTS = (6, 9, 18, 36)
STARTS = ("S", "A", "B", "C", "D", "E", "F")


@dataclass(frozen=True)
class ExperimentSettings:
    """What every run of the experiment shares."""

    resolution_px: int = 400
    seed: int = 0
    threshold: float = 0.36


@dataclass(frozen=True)
class RunOutcome:
    """One recorded, replayed and scored run."""

    name: str
    condition: str
    start: str
    images: int
    status: str
    simulated_s: float
    record_wall_s: float
    score: dict[str, Any]
    pairs: PairStatistics


@dataclass
class ExperimentResult:
    """Every run of the experiment, by the part of the experiment it belongs to."""

    settings: ExperimentSettings
    #: ``conditions[convention][condition]``, convention ``paper`` or ``aligned``.
    conditions: dict[str, dict[str, RunOutcome]] = field(default_factory=dict)
    images: dict[int, RunOutcome] = field(default_factory=dict)
    starts: dict[str, RunOutcome] = field(default_factory=dict)


def summary(values: tuple[float, ...] | list[float]) -> dict[str, Any]:
    """Mean, population std, min, max and count, 4 decimals (``None`` when empty)."""
    if not values:
        return {"mean": None, "std": None, "min": None, "max": None, "n": 0}
    return {
        "mean": round(statistics.fmean(values), 4),
        "std": round(statistics.pstdev(values), 4),
        "min": round(min(values), 4),
        "max": round(max(values), 4),
        "n": len(values),
    }


def _run(
    folder: Path, name: str, record: RecordSettings, threshold: float, keep: bool
) -> RunOutcome:
    network = build_network(record.network, seed=record.seed)
    path = folder / f"{name}.mcap"
    start = time.perf_counter()
    recorded = record_run(path, record, network, __version__, overwrite=True)
    wall = time.perf_counter() - start
    source = FileSource(path)
    # The paper's method, whose tables these are; a visit still cannot be the
    # junction it just left (the robot drove a pipe between them).
    paper = replace(PAPER, threshold=threshold, distinct_consecutive=True)
    result = replay(source, paper)
    scored = score_replay(result, source, threshold)
    report = scored.document()
    report["log"] = path.name
    pairs = scored.pairs
    if not keep:
        path.unlink()
    return RunOutcome(
        name=name,
        condition=record.condition.value,
        start=record.start or network.entry,
        images=record.images_per_sweep,
        status=recorded.status,
        simulated_s=recorded.duration_ns / 1e9,
        record_wall_s=wall,
        score=report,
        pairs=pairs,
    )


#: The two sweep conventions: the paper's (each sweep starts straight ahead) and
#: pipemap's default (each starts at the multiple of 360/N degrees nearest the
#: heading estimate, so revisits from another pipe see the same views).
CONVENTIONS = {"paper": False, "aligned": True}


def _plan(settings: ExperimentSettings) -> list[tuple[str, str, RecordSettings]]:
    """Every run as (part, name, settings), without repeats: the paper-convention
    perfect run serves Figure 6 too, the aligned autonomous run from S the starts."""

    def run(
        condition: str, images: int = 6, start: str = "S", align: bool = True
    ) -> RecordSettings:
        return RecordSettings(
            "paper",
            start=start,
            seed=settings.seed,
            condition=Condition(condition),
            resolution_px=settings.resolution_px,
            images_per_sweep=images,
            align_sweeps=align,
            threshold=settings.threshold,
            explore=Explore.RIGHT_HAND,
        )

    plan = [
        (f"conditions/{convention}", f"paper_{c}_{convention}", run(c, align=align))
        for convention, align in CONVENTIONS.items()
        for c in CONDITIONS
    ]
    plan += [
        ("images", f"paper_perfect_{n}images_paper", run("perfect", n, align=False))
        for n in IMAGE_COUNTS
        if n != 6
    ]
    plan += [
        ("starts", f"paper_autonomous_from_{s}", run("autonomous", start=s)) for s in STARTS[1:]
    ]
    return plan


def paper_experiment(
    settings: ExperimentSettings,
    logs: Path | None = None,
    progress: Callable[[int, int, str, RunOutcome | None], None] | None = None,
) -> ExperimentResult:
    """Run, replay and score every run of the paper experiment.

    With ``logs`` the recorded logs are kept there; otherwise they live in a
    temporary folder for as long as their run is analysed.
    """
    plan = _plan(settings)
    result = ExperimentResult(settings)
    with tempfile.TemporaryDirectory(prefix="pipemap-experiment-") as tmp:
        folder = logs if logs is not None else Path(tmp)
        for k, (part, name, record) in enumerate(plan):
            if progress is not None:
                progress(k, len(plan), name, None)
            outcome = _run(folder, name, record, settings.threshold, logs is not None)
            if progress is not None:
                progress(k + 1, len(plan), name, outcome)
            if part == "starts":
                result.starts[outcome.start] = outcome
            elif part == "images":
                result.images[outcome.images] = outcome
            else:
                convention = part.split("/")[1]
                result.conditions.setdefault(convention, {})[outcome.condition] = outcome
    result.images[6] = result.conditions["paper"]["perfect"]
    result.starts["S"] = result.conditions["aligned"]["autonomous"]
    result.images = dict(sorted(result.images.items()))
    result.starts = {s: result.starts[s] for s in STARTS}
    return result
