"""The arguments of the commands that run the simulator: ``sim`` (run by
:mod:`pipemap.cli.sim_command`) and ``record`` (:mod:`pipemap.cli.log_commands`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from pipemap.cli import arguments
from pipemap.defaults import (
    IMAGE_FORMAT,
    IMAGES_PER_SWEEP,
    LAMP_STRENGTHS,
    LIGHTING,
    RESOLUTION_PX,
    SEED,
)
from pipemap.localizer.presets import PAPER_THRESHOLD

if TYPE_CHECKING:
    from pipemap.cli.arguments import Subparsers

__all__ = ["add_record", "add_sim"]


def _add_run_options(p: argparse.ArgumentParser, condition: str) -> None:
    """What to simulate: network, start, seed, condition, camera; shared by sim and record."""
    p.add_argument("--network", required=True, help="paper, grid:RxC, random:N or tree:N")
    p.add_argument("--start", default=None, help="start node label (default: the entry)")
    p.add_argument(
        "--seed", type=arguments.seed, default=SEED, help=f"seed of every random draw ({SEED})"
    )
    p.add_argument(
        "--condition",
        choices=["perfect", "noise", "active", "entrance", "autonomous"],
        default=condition,
        help=f"placement at junctions, as in the paper (default {condition})",
    )
    p.add_argument(
        "--resolution",
        type=arguments.resolution,
        default=RESOLUTION_PX,
        help=f"image size in px ({RESOLUTION_PX})",
    )
    p.add_argument(
        "--lighting",
        choices=list(LAMP_STRENGTHS),
        default=LIGHTING,
        help="lamp: a dark pipe lit only by the robot's lamp at the camera; "
        f"even: every surface evenly lit, as in the paper's simulation (default {LIGHTING})",
    )
    p.add_argument(
        "--tilt-deg",
        type=arguments.tilt_deg,
        default=0.0,
        metavar="DEG",
        help="the robot off level: roll and pitch drawn at each junction within +-DEG "
        "(seeded; the IMU's reading is logged with each sweep; default 0, level)",
    )
    p.add_argument(
        "--obstacles",
        type=arguments.obstacles,
        default=0,
        metavar="N",
        help="autonomous condition: floor deposits in N pipes of at least 0.9 m, drawn from "
        "the seed, each passable (on one side) or blocking (default 0: none)",
    )
    p.add_argument(
        "--motor-faults",
        type=arguments.motor_faults,
        default=0,
        metavar="N",
        help="autonomous condition: the motors cut out N times while driving, 1-4 s each, "
        "drawn from the seed (default 0: never)",
    )
    p.add_argument(
        "--alike",
        type=arguments.alike,
        default=0.0,
        metavar="F",
        help="the fraction F (0..1) of junctions that take the look of another junction of "
        "their type (as many pipes, the same angles), drawn from the seed; 1: a network of "
        "identical fittings (default 0: every junction looks like itself alone)",
    )
    p.add_argument(
        "--odometry-drift",
        type=arguments.odometry_drift,
        default=1.0,
        metavar="F",
        help="a robot whose odometry is F times as poor (1..10): its wheels slip and its "
        "gyro drifts F times as much, and its localizer allows F times the drift (default "
        "1: the robot as built; docs/lookalike.md)",
    )
    p.add_argument(
        "--images",
        type=arguments.images,
        default=IMAGES_PER_SWEEP,
        help=f"images per sweep, 360/N degrees apart ({IMAGES_PER_SWEEP})",
    )
    p.add_argument(
        "--explore",
        choices=["map", "right-hand"],
        default=None,
        help="autonomous condition only: how the robot chooses exits; map (default): every "
        "untraversed pipe of its own map, Trémaux-style, then back to the start; "
        "right-hand: the paper's right-most-branch rule",
    )
    p.add_argument(
        "--world-memory",
        type=arguments.positive_int,
        default=None,
        metavar="MIB",
        help="keep the simulated world in a child process, restarted (with only the pipes "
        "near the robot rebuilt) when its memory passes MIB MiB; the log is the same bytes "
        "(default: the world in this process, its memory growing with what the robot reached)",
    )
    p.add_argument(
        "--align-sweeps",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="start each sweep at the multiple of 360/N degrees nearest the robot's heading "
        "estimate (default); --no-align-sweeps starts straight ahead, as in the paper",
    )


def add_sim(sub: Subparsers) -> None:
    """``pipemap sim``: an exploration saved as image-set folders."""
    p = sub.add_parser(
        "sim",
        help="run a simulated exploration and save its sweeps",
        description="Explore a pipe network and save every junction sweep as DIR/0001, "
        "DIR/0002, ... in the paper's folder layout: the run record makes on the same flags, "
        "with the localizer online, but no log. The placed conditions (perfect, the "
        "default; noise, active, entrance) set the robot down at each junction along the "
        "paper's right-most-branch tour; autonomous drives it, exploring by --explore.",
    )
    _add_run_options(p, "perfect")
    arguments.add_output(
        p, "--save-sweeps", required=True, metavar="DIR", helptext="new or empty folder"
    )
    arguments.add_force(p, "replace the sweep folders (0001, 0002, ...) of an earlier run in DIR")


def add_record(sub: Subparsers) -> None:
    """``pipemap record``: an exploration with the localizer online, written as a log."""
    p = sub.add_parser(
        "record",
        help="run a simulated exploration and write its log (MCAP)",
        description="Run an episode with the localizer online and write every sensor stream, "
        "camera sweep, ground truth and online decision to one MCAP log.",
    )
    _add_run_options(p, "autonomous")
    p.add_argument(
        "--threshold",
        type=arguments.threshold,
        default=PAPER_THRESHOLD,
        help=f"the online localizer's similarity threshold (default {PAPER_THRESHOLD}); "
        "by default the two-view check decides known or new, and the threshold only asks "
        "for probes",
    )
    arguments.add_output(
        p, "-o", "--output", required=True, metavar="RUN.mcap", helptext="log file"
    )
    arguments.add_force(p, "overwrite an existing log")
    arguments.add_verbose(p)
    p.add_argument(
        "--no-probe-moves",
        action="store_true",
        help="autonomous condition: the robot makes none of the probe moves active vision "
        "asks for (by default it makes them, checked by its rangers, and logs their sweeps)",
    )
    p.add_argument(
        "--image-format",
        choices=("png", "jpeg"),
        default=IMAGE_FORMAT,
        help="how the log stores the camera's images: png, lossless, or jpeg, as a real "
        "camera often gives them (the replay decodes what the log holds; default "
        f"{IMAGE_FORMAT})",
    )
    p.add_argument(
        "--jpeg-quality",
        type=arguments.jpeg_quality,
        default=None,
        metavar="Q",
        help="with --image-format jpeg: the JPEG quality, 1..100 (default 90)",
    )
    p.add_argument(
        "--view",
        action="store_true",
        help="stream the run live to a rerun viewer (spawned, or the one of --connect)",
    )
    p.add_argument(
        "--connect",
        metavar="URL",
        default=None,
        help="with --view: stream to the running rerun viewer or server at this gRPC URL "
        "(e.g. rerun+http://127.0.0.1:9876/proxy) instead of spawning one",
    )
    p.add_argument(
        "--save",
        action="store_true",
        help="with --view: write the view as RUN.rrd beside the log after the run, "
        "instead of streaming it",
    )
