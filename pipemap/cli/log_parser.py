"""The arguments of the commands that read a log: ``replay``, ``score`` (run by
:mod:`pipemap.cli.replay_commands`), ``view`` (:mod:`pipemap.cli.view_command`) and
``info`` (:mod:`pipemap.cli.log_commands`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from pipemap.cli import arguments
from pipemap.cli.localizer_options import add_rule_options, add_similarity_options, add_threshold

if TYPE_CHECKING:
    from pipemap.cli.arguments import Subparsers

__all__ = ["WEB_PORT", "add_info", "add_replay", "add_score", "add_view"]

#: The port ``pipemap view --web`` serves on by default: rerun's own default.
WEB_PORT = 9090


def _add_log(p: argparse.ArgumentParser, several: bool = False) -> None:
    if several:
        p.add_argument("log", metavar="RUN.mcap", nargs="+", help="pipemap logs, one or more")
    else:
        p.add_argument("log", metavar="RUN.mcap", help="a pipemap log")


def _add_replay_options(
    p: argparse.ArgumentParser, several: bool = False, recorded: bool = True
) -> None:
    """The log (``several``: logs) and the localizer that replays it: shared by
    replay, score and view (``recorded``: the threshold defaults to the log's)."""
    _add_log(p, several)
    add_threshold(p, recorded)
    p.add_argument("--no-active-vision", action="store_true", help="never ask for probe sweeps")
    add_similarity_options(p)
    add_rule_options(p)


def add_replay(sub: Subparsers) -> None:
    """``pipemap replay RUN.mcap``: the map rebuilt from a log."""
    p = sub.add_parser(
        "replay",
        help="rebuild the map from a log, deterministically",
        description="Feed a log's /robot messages to the localizer in their total order and "
        "write the map as JSON (the format of pipemap map --json).",
    )
    _add_replay_options(p)
    arguments.add_output(
        p,
        "-o",
        "--output",
        metavar="MAP.json",
        helptext="write the map here (default: standard output)",
    )
    arguments.add_output(
        p, "--graphml", metavar="MAP.graphml", helptext="also write the map as GraphML"
    )
    arguments.add_output(
        p,
        "--save-log",
        metavar="OUT.mcap",
        helptext="also write the results as an MCAP log for Foxglove: the estimated pose per "
        "visit (foxglove.PoseInFrame, /tf), the map (foxglove.SceneUpdate), the decisions",
    )
    arguments.add_force(p, "overwrite existing files")
    arguments.add_verbose(p)


def add_score(sub: Subparsers) -> None:
    """``pipemap score RUN.mcap``: a replay compared with the log's ground truth."""
    p = sub.add_parser(
        "score",
        help="replay logs and score each map against its ground truth",
        description="Replay each log and compare every decision and the map with the log's "
        "/truth; several logs are scored one after another, a report each.",
    )
    _add_replay_options(p, several=True)
    p.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object (for several logs, a JSON list of one object per log)",
    )
    arguments.add_output(
        p,
        "--save-results",
        metavar="DIR",
        helptext="write score.json and visits.csv to this new or empty folder (one log only)",
    )
    arguments.add_force(p, "replace the files of an earlier score")
    arguments.add_verbose(p)


def add_view(sub: Subparsers) -> None:
    """``pipemap view RUN.mcap``: a log and its replay in rerun."""
    p = sub.add_parser(
        "view",
        help="show a log and its replay in the rerun viewer, or save them as .rrd",
        description="Replay a log and show it in rerun on its simulated time: the network, "
        "the robot's true pose and trajectory, range rays, camera direction and images, "
        "sensor signals, controller states and the topological map as it grows, with "
        "each decision. Opens the viewer, or with --save writes a recording file.",
    )
    _add_replay_options(p, recorded=False)
    arguments.add_output(
        p,
        "--save",
        metavar="OUT.rrd",
        helptext="write the recording to this file instead of opening the viewer",
    )
    arguments.add_force(p, "overwrite an existing file")
    p.add_argument(
        "--web",
        action="store_true",
        help="serve the view in rerun's web viewer on 127.0.0.1, for a browser, until "
        "stopped (Ctrl-C); no display needed (with --save, the file is kept too)",
    )
    p.add_argument(
        "--port",
        type=int,
        metavar="P",
        help=f"with --web: the web viewer's port on 127.0.0.1, 0 for any free one "
        f"(default {WEB_PORT})",
    )
    p.add_argument(
        "--max-rate",
        type=arguments.max_rate,
        default=None,
        metavar="HZ",
        help="show the range, IMU and wheel streams at most HZ messages a second each "
        "(the log keeps all; 0 shows every message; default 10)",
    )


def add_info(sub: Subparsers) -> None:
    """``pipemap info RUN.mcap``: what a log holds, and whether it is whole."""
    p = sub.add_parser(
        "info",
        help="describe a log: channels, counts, run settings, integrity",
        description="Describe a pipemap log. A log cut short is read up to its last complete "
        "record (exit 0); a damaged one is read up to the damage (exit 1).",
    )
    _add_log(p)
    arguments.add_json(p)
