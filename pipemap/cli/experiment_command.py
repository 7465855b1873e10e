"""``pipemap experiment paper --out DIR``: run the paper's experiments, write the results."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TextIO

from pipemap.cli.outputs import output_folder

__all__ = ["run_experiment"]


def _earlier(keep_logs: bool) -> Callable[[Path], list[str]]:
    """What of an output folder the experiment would replace: its result files, and
    its logs with ``--keep-logs``."""
    from pipemap.cli.experiment_report import FILES

    def found(folder: Path) -> list[str]:
        names = [name for name in FILES if (folder / name).exists()]
        logs = folder / "logs"
        if keep_logs and logs.is_dir() and any(logs.iterdir()):
            names.append("logs/")
        return names

    return found


def run_experiment(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Run every run of the experiment, then write its markdown, JSON and figures."""
    from pipemap import __version__
    from pipemap.cli.experiment import ExperimentSettings, RunOutcome, paper_experiment
    from pipemap.cli.experiment_report import write_experiment

    folder = output_folder(args.out, "--out", args.force, _earlier(args.keep_logs))
    logs = None
    if args.keep_logs:
        logs = folder / "logs"
        logs.mkdir(parents=True, exist_ok=True)
    settings = ExperimentSettings(args.resolution, args.seed, args.threshold)
    started = time.perf_counter()

    def progress(done: int, total: int, name: str, outcome: RunOutcome | None) -> None:
        if outcome is None:
            err.write(f"[{done + 1:2d}/{total}] {name} ...")
        else:
            score = outcome.score
            verdict = "map correct" if score["map_correct"] else "map WRONG"
            err.write(f" {verdict}, {score['visits']} visits, {outcome.record_wall_s:.1f} s\n")
        err.flush()

    result = paper_experiment(settings, logs, progress)
    wall = time.perf_counter() - started
    doc = write_experiment(folder, result, wall, __version__)
    correct = sum(1 for r in doc["starts"].values() if r["map_correct"])
    out.write(
        f"experiment paper: {len(doc['conditions']['paper']) * 2} condition runs, "
        f"{len(doc['images'])} image counts, map correct from {correct}/{len(doc['starts'])} "
        f"starts; results in {folder}/experiment.md ({wall:.0f} s)\n"
    )
    return 0
