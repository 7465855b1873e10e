"""The arguments of the commands that run many runs: ``experiment`` (run by
:mod:`pipemap.cli.experiment_command`), ``batch`` and ``batch-report``
(:mod:`pipemap.cli.batch_command`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from pipemap.cli import arguments
from pipemap.defaults import RESOLUTION_PX, SEED
from pipemap.localizer.presets import PAPER_THRESHOLD

if TYPE_CHECKING:
    from pipemap.cli.arguments import Subparsers

__all__ = ["add_batch", "add_batch_options", "add_batch_report", "add_experiment"]


def add_batch_options(p: argparse.ArgumentParser) -> None:
    """Where and how a batch runs, and what becomes of an existing output folder."""
    p.add_argument(
        "--address",
        default=None,
        metavar="HOST:PORT",
        help="run on the Ray cluster whose head is there (as `ray start --head` prints it); "
        "default: start Ray on this machine",
    )
    p.add_argument(
        "--workers",
        type=arguments.positive_int,
        default=None,
        metavar="N",
        help="runs at once (default: this machine's cores, or the cluster's CPUs)",
    )
    p.add_argument(
        "--keep-logs",
        action="store_true",
        help="keep every run's log as DIR/runs/<run-id>/run.mcap",
    )
    again = p.add_mutually_exclusive_group()
    again.add_argument(
        "--resume", action="store_true", help="keep the complete runs in DIR, make the others"
    )
    again.add_argument(
        "--force", action="store_true", help="delete earlier results in DIR and start afresh"
    )


def add_experiment(sub: Subparsers) -> None:
    """``pipemap experiment paper``: the paper's experiments, reproduced."""
    p = sub.add_parser(
        "experiment",
        help="reproduce the paper's experiments in the simulator",
        description="Record, replay and score the runs of the paper's experiments (five "
        "conditions, 6/9/18/36 images per sweep, seven autonomous starts) and write Table 1, "
        "Table 2, Figures 6 and 7 and the starts as markdown, JSON and PNG.",
    )
    p.add_argument("name", choices=["paper"], help="which experiment (paper)")
    arguments.add_output(
        p, "--out", required=True, metavar="DIR", helptext="folder for the results"
    )
    p.add_argument(
        "--resolution",
        type=arguments.resolution,
        default=RESOLUTION_PX,
        help=f"image size in px ({RESOLUTION_PX})",
    )
    p.add_argument("--seed", type=arguments.seed, default=SEED, help=f"seed of every run ({SEED})")
    p.add_argument(
        "--threshold",
        type=arguments.threshold,
        default=PAPER_THRESHOLD,
        help=f"similarity threshold (default {PAPER_THRESHOLD}); see record --threshold",
    )
    p.add_argument(
        "--lighting",
        choices=["lamp", "even"],
        default="lamp",
        help="lamp: every run lit by the robot's lamp (default); even: every surface evenly "
        "lit, as in the paper's simulation (see record --lighting)",
    )
    add_batch_options(p)


def add_batch(sub: Subparsers) -> None:
    """``pipemap batch SPEC.toml``: a grid of runs, on this machine or a Ray cluster."""
    p = sub.add_parser(
        "batch",
        help="run a grid of record + score runs on this machine or a Ray cluster",
        description="Run every run of SPEC.toml's [grid] (the Cartesian product of its "
        "lists: network, seed, start, condition, resolution, images, align_sweeps, explore, "
        "obstacles, motor_faults, tilt_deg, lighting, alike, odometry_drift, rule, threshold) "
        "on Ray: each run is recorded, replayed and scored as pipemap record and pipemap "
        "score do. Writes DIR/runs/<run-id>/ and one table, DIR/results.csv and "
        "DIR/results.json. See "
        "docs/batch.md.",
    )
    p.add_argument("spec", metavar="SPEC.toml", help="the grid to run (TOML)")
    arguments.add_output(
        p, "--out", required=True, metavar="DIR", helptext="folder for the results"
    )
    add_batch_options(p)


def add_batch_report(sub: Subparsers) -> None:
    """``pipemap batch-report DIR``: a batch's runs, grouped and summarised."""
    p = sub.add_parser(
        "batch-report",
        help="summarise a batch: grouped tables and figures (Markdown + PNG)",
        description="Group a batch's runs by the grid keys that vary (seeds pooled) and "
        "write DIR/report.md and report.json (mean, std, min, max per group) with a Figure 7 "
        "style box plot of same/different similarity and a Table 2 style plot of the "
        "rotation error.",
    )
    p.add_argument("dir", metavar="DIR", help="a folder written by pipemap batch")
    p.add_argument(
        "--by",
        default=None,
        metavar="KEY[,KEY...]",
        help="group by these grid keys (default: every key that varies, seed aside)",
    )
