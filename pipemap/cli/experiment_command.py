"""``pipemap experiment paper --out DIR``: run the paper's preset SPEC as a batch, then
write the experiment's markdown, JSON and figures from its results."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from pipemap.cli.outputs import output_folder

__all__ = ["experiment_settings", "run_experiment"]


def experiment_settings(args: argparse.Namespace) -> Any:
    """The :class:`pipemap.batch.experiment.ExperimentSettings` of the command's flags
    (the experiment is a batch: the layer above :mod:`pipemap.api`)."""
    from pipemap.batch.experiment import ExperimentSettings

    return ExperimentSettings(args.resolution, args.seed, args.threshold, args.lighting)


def run_experiment(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Run every run of the experiment on Ray, then write its files."""
    from pipemap import __version__
    from pipemap.batch import BatchOptions, plan_batch, run_batch
    from pipemap.batch.experiment import EXPERIMENT_RULES, experiment_result, paper_spec
    from pipemap.batch.experiment_report import FILES, write_experiment
    from pipemap.cli.batch_command import format_duration, progress_printer

    folder = Path(args.out)
    settings = experiment_settings(args)
    spec = paper_spec(settings)
    options = BatchOptions(
        address=args.address,
        workers=args.workers,
        keep_logs=args.keep_logs,
        resume=args.resume,
        force=args.force,
        extra_entries=FILES,
    )
    # Writable before any work (the batch's own check then decides --resume/--force).
    output_folder(args.out, "--out", force=True)
    plan = plan_batch(spec, folder, options)
    err.write(
        f"experiment paper: {len(plan.pending)} runs to make ({spec.recordings()} recordings, "
        f"each scored by {' and '.join(EXPERIMENT_RULES)})"
        + (f"; {len(plan.complete)} complete runs kept\n" if plan.complete else "\n")
    )
    started = time.perf_counter()
    summary = run_batch(plan, progress_printer(err))
    if err.isatty():
        err.write("\n")
    if summary.interrupted:
        err.write(
            f"pipemap: interrupted: {summary.done} finished runs kept in {folder}; "
            "--resume makes the rest\n"
        )
        return 130
    if summary.failed:
        err.write(
            f"pipemap: {summary.failed} runs failed (reasons in {folder}/results.csv); "
            "--resume tries them again\n"
        )
        return 1
    wall = time.perf_counter() - started
    result = experiment_result(folder, settings)
    doc = write_experiment(folder, result, wall, __version__)
    starts = ", ".join(
        f"{sum(1 for r in doc['starts'].values() if r['rules'][rule]['map_correct'])}/"
        f"{len(doc['starts'])} ({rule})"
        for rule in EXPERIMENT_RULES
    )
    out.write(
        f"experiment paper: {len(doc['conditions']['paper']) * 2} condition runs, "
        f"{len(doc['images'])} image counts, map correct from {starts} starts; "
        f"results in {folder}/experiment.md ({format_duration(wall)})\n"
    )
    return 0
