"""``pipemap experiment paper``: the paper's experiments, as a preset SPEC.

The experiment is a batch like any other (``experiments/paper.toml`` is its SPEC
at the defaults): every run is recorded, replayed and scored by the batch machinery,
exactly as ``pipemap record`` and ``pipemap score`` do, and each run is scored twice
from its one log, by the paper's rule (``paper``: ``pipemap score --no-two-view
--allow-repeat``) and by pipemap's defaults (``default``: ``pipemap score``), so that
every table says which rule made it and shows both side by side. Three parts, all on
the ``paper`` network:

* the five conditions (perfect, noise, active, entrance, autonomous), from S, with
  the paper's sweeps (starting straight ahead) and with pipemap's aligned sweeps:
  similarity of every pair of visits to the same junction and to different
  junctions (Table 1, Figure 7), the rotation error (Table 2), and the decisions;
* 6, 9, 18 and 36 images per sweep in the perfect condition, paper's sweeps
  (Figure 6);
* the autonomous exploration from each of the seven nodes, aligned sweeps.

This module makes the SPEC and reads its results back by part;
:mod:`batch.experiment_report` writes the files.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pipemap.batch.results import read_result
from pipemap.batch.spec import BatchSpec, RunPoint, parse_spec
from pipemap.errors import InputError

__all__ = [
    "CONDITIONS",
    "CONVENTIONS",
    "EXPERIMENT_RULES",
    "IMAGE_COUNTS",
    "STARTS",
    "ExperimentResult",
    "ExperimentSettings",
    "Pairs",
    "RunOutcome",
    "experiment_result",
    "paper_spec",
    "paper_spec_text",
    "summary",
]

CONDITIONS = ("perfect", "noise", "active", "entrance", "autonomous")
IMAGE_COUNTS = (6, 9, 18, 36)
STARTS = ("S", "A", "B", "C", "D", "E", "F")
#: The rules every run is scored by, in the order of the tables' columns.
EXPERIMENT_RULES = ("paper", "default")
#: The two sweep conventions: the paper's (each sweep starts straight ahead) and
#: pipemap's default (each starts at the multiple of 360/N degrees nearest the
#: heading estimate, so revisits from another pipe see the same views).
CONVENTIONS = {"paper": False, "aligned": True}


@dataclass(frozen=True)
class ExperimentSettings:
    """What every run of the experiment shares."""

    resolution_px: int = 400
    seed: int = 0
    threshold: float = 0.36
    #: ``record --lighting``: the robot's lamp (pipemap's default), or every surface
    #: lit evenly, as the paper's simulation was.
    lighting: str = "lamp"


def paper_spec_text(settings: ExperimentSettings | None = None) -> str:
    """The experiment's SPEC (``experiments/paper.toml`` at the default settings)."""
    s = settings if settings is not None else ExperimentSettings()
    common = (
        f'network = ["paper"]\nseed = [{s.seed}]\nresolution = [{s.resolution_px}]\n'
        f'rule = ["paper", "default"]\nthreshold = [{s.threshold!r}]\n'
        # The autonomous robot explores by the paper's right-hand rule, as published
        # (on this tree the map-driven walk is the same); placed runs ignore it.
        'explore = ["right-hand"]\n'
        + (f'lighting = ["{s.lighting}"]\n' if s.lighting != "lamp" else "")
    )
    conditions = ", ".join(f'"{c}"' for c in CONDITIONS)
    starts = ", ".join(f'"{x}"' for x in STARTS)
    return (
        "# pipemap experiment paper: the paper's experiments (Li et al. 2023) in pipemap's\n"
        "# simulator. Each run is scored by the paper's rule and by pipemap's defaults.\n"
        "#   pipemap experiment paper --out DIR      (this SPEC, and experiment.md)\n"
        "#   pipemap batch experiments/paper.toml --out DIR   (the runs and the table only)\n"
        "description = \"The paper's experiments: five conditions with the paper's and "
        "aligned sweeps, 6 to 36 images per sweep, autonomous exploration from every "
        'start"\n\n'
        "# Table 1, Table 2, Figure 7: the five conditions from S, both sweep conventions.\n"
        f'[[grid]]\n{common}start = ["S"]\ncondition = [{conditions}]\nimages = [6]\n'
        "align_sweeps = [false, true]\n\n"
        "# Figure 6: images per sweep, perfect condition, the paper's sweeps.\n"
        f'[[grid]]\n{common}start = ["S"]\ncondition = ["perfect"]\n'
        f"images = [{', '.join(map(str, IMAGE_COUNTS))}]\nalign_sweeps = [false]\n\n"
        "# The autonomous exploration from every node, aligned sweeps, by the paper's\n"
        "# right-hand rule as published (on this tree the map-driven walk is the same).\n"
        f"[[grid]]\n{common}start = [{starts}]\n"
        'condition = ["autonomous"]\nimages = [6]\nalign_sweeps = [true]\n'
    )


def paper_spec(settings: ExperimentSettings | None = None) -> BatchSpec:
    """The experiment's SPEC, validated."""
    return parse_spec(paper_spec_text(settings), "experiment paper")


@dataclass(frozen=True)
class Pairs:
    """Similarity of every pair of a run's visit sweeps, split by the true junction,
    and the rotation error of same-junction pairs (the same under every rule)."""

    same: tuple[float, ...]
    different: tuple[float, ...]
    rotation_errors_rad: tuple[float, ...]


@dataclass(frozen=True)
class RunOutcome:
    """One recorded run, scored by each rule of :data:`EXPERIMENT_RULES`."""

    name: str
    condition: str
    start: str
    images: int
    status: str
    simulated_s: float
    record_wall_s: float
    #: ``pipemap score --json``'s document, by rule.
    scores: dict[str, dict[str, Any]]
    #: The rotation errors of the revisits each rule recognised, by rule.
    known_rotation_errors_rad: dict[str, tuple[float, ...]]
    pairs: Pairs


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


def _outcome(out: Path, points: list[RunPoint]) -> RunOutcome:
    import json

    first = points[0]
    scores: dict[str, dict[str, Any]] = {}
    known: dict[str, tuple[float, ...]] = {}
    doc: dict[str, Any] | None = None
    for point in points:
        doc = read_result(out, point.run_id)
        if doc is None or doc["status"] != "ok":
            reason = "not made" if doc is None else doc["reason"]
            raise InputError(f"{out}: run {point.run_id} is not complete ({reason})")
        scores[point.rule] = json.loads((out / "runs" / point.run_id / "score.json").read_text())
        known[point.rule] = tuple(doc["known_rotation_errors_rad"])
    assert doc is not None
    record, pairs = doc["record"], doc["pairs"]
    convention = "aligned" if first.align_sweeps else "paper"
    return RunOutcome(
        name=f"paper_{first.condition}_{first.images}images_{convention}_from_{first.start}",
        condition=first.condition,
        start=first.start,
        images=first.images,
        status=record["run_status"],
        simulated_s=record["simulated_s"],
        record_wall_s=record["record_wall_s"],
        scores=scores,
        known_rotation_errors_rad=known,
        pairs=Pairs(
            tuple(pairs["same"]), tuple(pairs["different"]), tuple(pairs["rotation_error_rad"])
        ),
    )


def experiment_result(out: Path, settings: ExperimentSettings) -> ExperimentResult:
    """The experiment's parts from the finished batch in ``out``."""
    spec = paper_spec(settings)
    by_recording: dict[tuple[Any, ...], list[RunPoint]] = {}
    for point in spec.points:
        by_recording.setdefault(point.recording_key, []).append(point)
    result = ExperimentResult(settings)
    for points in by_recording.values():
        p = points[0]
        run = _outcome(out, points)
        if p.start == "S" and p.images == 6:
            convention = "aligned" if p.align_sweeps else "paper"
            result.conditions.setdefault(convention, {})[p.condition] = run
        if p.condition == "perfect" and not p.align_sweeps and p.start == "S":
            result.images[p.images] = run
        if p.condition == "autonomous" and p.align_sweeps and p.images == 6:
            result.starts[p.start] = run
    result.conditions = {c: {k: result.conditions[c][k] for k in CONDITIONS} for c in CONVENTIONS}
    result.images = {n: result.images[n] for n in IMAGE_COUNTS}
    result.starts = {s: result.starts[s] for s in STARTS}
    return result
