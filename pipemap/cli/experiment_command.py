"""``pipemap experiment paper --out DIR``: run the paper's experiments, write the results."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TextIO

from pipemap.errors import InputError

__all__ = ["run_experiment"]


def _check_folder(folder: Path, force: bool) -> None:
    from pipemap.cli.experiment_report import FILES

    if folder.exists() and not folder.is_dir():
        raise InputError(f"--out {folder}: is a file, not a folder")
    if not folder.parent.is_dir():
        raise InputError(f"--out {folder}: folder {folder.parent} does not exist")
    earlier = [name for name in FILES if (folder / name).exists()]
    if earlier and not force:
        raise InputError(
            f"--out {folder}: holds earlier results ({earlier[0]}); refusing to replace "
            "them without --force"
        )


def run_experiment(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Run every run of the experiment, then write its markdown, JSON and figures."""
    from pipemap import __version__
    from pipemap.cli.experiment import ExperimentSettings, RunOutcome, paper_experiment
    from pipemap.cli.experiment_report import write_experiment

    folder = Path(args.out)
    _check_folder(folder, args.force)
    logs = None
    if args.keep_logs:
        logs = folder / "logs"
        if logs.exists() and any(logs.iterdir()) and not args.force:
            raise InputError(f"--out {folder}: logs/ is not empty; refusing without --force")
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
