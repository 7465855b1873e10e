"""The ``pipemap`` argument parser (argparse only, no heavy imports) and the settings it
parses into."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NoReturn

from pipemap import __version__
from pipemap.localizer.presets import (
    PAPER_THRESHOLD,
    ROBUST_FAST,
    ROBUST_HIGHPASS_FRACTION,
    ROBUST_THRESHOLD,
    ROBUST_ZOOMS,
)

if TYPE_CHECKING:
    from pipemap.localizer import FastConfig

__all__ = ["build_parser"]


class _OneLineParser(argparse.ArgumentParser):
    """Reports a bad command line as one line and exit status 2.

    Subcommand parsers too say ``pipemap: error:`` (not ``pipemap match: error:``):
    one prefix for every error the command reports, whichever layer found it.
    """

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"pipemap: error: {message}\n")


def _checked(
    convert: Callable[[str], float], valid: Callable[[float], bool], rule: str
) -> Callable[[str], Any]:
    """An argparse type: ``convert`` the text, then demand ``valid``, else say ``rule``."""

    def parse(text: str) -> Any:
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not valid(value):
            raise argparse.ArgumentTypeError(f"{rule}, got {text}")
        return value

    return parse


_threshold = _checked(
    float, lambda v: math.isfinite(v) and -1.0 <= v <= 1.0, "threshold must be in [-1, 1]"
)
_positive_int = _checked(int, lambda v: v >= 1, "must be at least 1")
_seed = _checked(int, lambda v: 0 <= v < 2**63, "seed must be in [0, 2^63)")
_images = _checked(int, lambda v: 2 <= v <= 72, "images per sweep must be 2..72")
_resolution = _checked(int, lambda v: 16 <= v <= 4096, "resolution must be 16..4096 px")
_node_id = _checked(int, lambda v: v >= 0, "a node id is an integer >= 0")
_fraction = _checked(float, lambda v: 0.0 < v <= 1.0, "must be in (0, 1]")
_fov_deg = _checked(float, lambda v: 0.0 < v < 360.0, "field of view must be in (0, 360) degrees")


def _degrees(text: str) -> float:
    return math.radians(_fov_deg(text))


_zoom = _checked(float, lambda v: math.isfinite(v) and 1.0 < v <= 2.0, "not in (1, 2]")
_tilt_deg = _checked(float, lambda v: math.isfinite(v) and 0.0 <= v <= 15.0, "not in [0, 15]")
_obstacles = _checked(int, lambda v: v >= 0, "an obstacle count must be >= 0")
_highpass = _checked(float, lambda v: math.isfinite(v) and 0.0 <= v <= 1.0, "must be in [0, 1]")


def _zooms(text: str) -> tuple[float, ...]:
    try:
        return tuple(_zoom(part) for part in text.split(","))
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"zoom factors are numbers in (1, 2], comma-separated, got {text}"
        ) from None


_THRESHOLD_HELP = (
    f"similarity threshold (default {PAPER_THRESHOLD}, or {ROBUST_THRESHOLD} with --robust): "
    "decides known or new with --no-verify or --no-two-view; by default the two-view "
    "check decides, and the threshold only asks for probes and decides sweeps with too "
    "few keypoints to check"
)


def apply_presets(args: argparse.Namespace) -> None:
    """Fill in what ``--robust`` stands for, and the threshold left to its default.

    Options given explicitly win over the preset's."""
    if not hasattr(args, "baseline"):
        return
    if args.robust:
        args.zoom = args.zoom or ROBUST_ZOOMS
        args.highpass = args.highpass or ROBUST_HIGHPASS_FRACTION
        args.baseline = True
    if args.threshold is None:
        args.threshold = ROBUST_THRESHOLD if args.robust else PAPER_THRESHOLD


def add_similarity_options(p: argparse.ArgumentParser) -> None:
    """The fast path's settings: ``--downsample`` trades accuracy for speed; ``--zoom``,
    ``--highpass`` and ``--baseline`` (together with their threshold: ``--robust``)
    switch on pipemap's extensions of the paper's similarity (off by default, so the
    defaults are the paper's Algorithm 2)."""
    p.add_argument(
        "--downsample",
        type=_positive_int,
        default=None,
        help="fast path: column decimation factor of the accurate stage (default 4)",
    )
    p.add_argument(
        "--zoom",
        type=_zooms,
        default=(),
        metavar="Z[,Z...]",
        help="also compare each image pair with either image zoomed in by these factors, "
        "for cameras off the junction centre (e.g. 1.15,1.3; default off)",
    )
    p.add_argument(
        "--highpass",
        type=_highpass,
        default=0.0,
        metavar="F",
        help="first subtract from every image its Gaussian blur of sigma F x image width, "
        "the lamp's brightness fall all junctions share (e.g. 0.175; default off); "
        "it lowers every similarity: tune --threshold with it",
    )
    p.add_argument(
        "--robust",
        action="store_true",
        help="pipemap's similarity for cameras off the junction centre: --zoom "
        f"{','.join(map(str, ROBUST_ZOOMS))} --highpass {ROBUST_HIGHPASS_FRACTION} --baseline, "
        f"threshold {ROBUST_THRESHOLD} unless --threshold is given",
    )
    p.add_argument(
        "--baseline",
        action="store_true",
        help="report similarity above the pair's baseline: how alike each set's own "
        "views 360/N degrees and more apart look (puts imagery of any renderer and "
        f"resolution on one scale; with it, thresholds lie near {ROBUST_THRESHOLD})",
    )


def fast_config(args: argparse.Namespace) -> FastConfig:
    """The :class:`localizer.FastConfig` of the options of :func:`add_similarity_options`."""
    from pipemap.localizer import FastConfig

    downsample = FastConfig().fine_downsample if args.downsample is None else args.downsample
    return FastConfig(
        fine_downsample=downsample,
        zooms=args.zoom,
        highpass_fraction=args.highpass,
        baseline=args.baseline,
        **(ROBUST_FAST if args.robust else {}),
    )


def add_rule_options(p: argparse.ArgumentParser) -> None:
    """The flags that turn pipemap's own localizer rules back into the paper's:
    ``--allow-repeat``, ``--no-verify`` and ``--no-two-view``."""
    p.add_argument(
        "--allow-repeat",
        action="store_true",
        help="let a visit be the junction of the visit before it, as in the paper (by "
        "default it cannot: a pipe joins two different junctions); for image sets that "
        "are not a traversal",
    )
    p.add_argument(
        "--no-verify",
        action="store_true",
        help="decide known or new by the similarity threshold, as in the paper, not by "
        "whether the keypoints of the two sweeps fit one motion",
    )
    p.add_argument(
        "--no-two-view",
        action="store_true",
        help="no keypoint geometry: the paper's decision and its rotation estimate (NCC "
        "peak shift); the two-view model needs a camera that turns about its own centre, "
        "as pipemap's does (implies --no-verify)",
    )
    p.add_argument(
        "--no-port-check",
        action="store_true",
        help="recognise a junction by its images alone, even when the robot's exits do "
        "not line up with its known pipes (by default such a match is passed over)",
    )
    p.add_argument(
        "--illumination",
        choices=["auto", "lamp", "even"],
        default="auto",
        help="lamp: divide every image by its own illumination estimate before matching "
        "(sweeps lit by the robot's lamp); even: as in the paper; auto (default): lamp "
        "when the log's camera had its lamp on, even for image folders",
    )


def port_check(args: argparse.Namespace) -> bool:
    """``port_check`` of :class:`localizer.LocalizerConfig` from ``--no-port-check``."""
    return not getattr(args, "no_port_check", False)


def illumination_setting(args: argparse.Namespace) -> bool | None:
    """``lamp`` of :class:`localizer.LocalizerConfig` from ``--illumination``."""
    return {"auto": None, "lamp": True, "even": False}[args.illumination]


def two_view_settings(args: argparse.Namespace) -> tuple[bool, bool]:
    """``two_view`` and ``verify`` of :class:`localizer.LocalizerConfig` from the flags."""
    two_view = not args.no_two_view
    return two_view, two_view and not args.no_verify


def _add_matching_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("dirs", nargs="+", metavar="DIR", help="image-set folders (camera_image1..N)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--threshold", type=_threshold, default=None, help=_THRESHOLD_HELP)
    p.add_argument(
        "--fov-deg", type=_degrees, default=None, help="horizontal field of view (default 80)"
    )
    p.add_argument(
        "--keep-top",
        type=_fraction,
        default=None,
        help="fraction of each image kept from the top (default 0.5)",
    )
    add_similarity_options(p)


def _add_run_options(p: argparse.ArgumentParser, condition: str) -> None:
    """What to simulate: network, start, seed, condition, camera; shared by sim and record."""
    p.add_argument("--network", required=True, help="paper, grid:RxC, random:N or tree:N")
    p.add_argument("--start", default=None, help="start node label (default: the entry)")
    p.add_argument("--seed", type=_seed, default=0, help="seed of every random draw (0)")
    p.add_argument(
        "--condition",
        choices=["perfect", "noise", "active", "entrance", "autonomous"],
        default=condition,
        help=f"placement at junctions, as in the paper (default {condition})",
    )
    p.add_argument("--resolution", type=_resolution, default=400, help="image size in px (400)")
    p.add_argument(
        "--lighting",
        choices=["lamp", "even"],
        default="lamp",
        help="lamp (default): a dark pipe lit only by the robot's lamp at the camera; "
        "even: every surface evenly lit, as in the paper's simulation",
    )
    p.add_argument(
        "--tilt-deg",
        type=_tilt_deg,
        default=0.0,
        metavar="DEG",
        help="the robot off level: roll and pitch drawn at each junction within +-DEG "
        "(seeded; placement conditions only; default 0, level)",
    )
    p.add_argument(
        "--obstacles",
        type=_obstacles,
        default=0,
        metavar="N",
        help="autonomous condition: floor deposits in N pipes of at least 0.9 m, drawn from "
        "the seed, each passable (on one side) or blocking (default 0: none)",
    )
    p.add_argument(
        "--images", type=_images, default=6, help="images per sweep, 360/N degrees apart (6)"
    )
    p.add_argument(
        "--explore",
        choices=["map", "right-hand"],
        default="map",
        help="autonomous condition: how the robot chooses exits; map (default): every "
        "untraversed pipe of its own map, Trémaux-style, then back to the start; "
        "right-hand: the paper's right-most-branch rule",
    )
    p.add_argument(
        "--align-sweeps",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="start each sweep at the multiple of 360/N degrees nearest the robot's heading "
        "estimate (default); --no-align-sweeps starts straight ahead, as in the paper",
    )


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
        type=_positive_int,
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


def build_parser() -> argparse.ArgumentParser:
    """The full ``pipemap`` parser with one subparser per command."""
    parser = _OneLineParser(
        prog="pipemap",
        description="Topological localization and mapping of robots in buried pipe networks.",
    )
    parser.add_argument("--version", action="version", version=f"pipemap {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_OneLineParser)
    sub.required = True

    p_match = sub.add_parser(
        "match",
        help="similarity and rotation of every pair of image sets",
        description="Compare every unordered pair of image sets, in argument order "
        "(the paper's Algorithm 2).",
    )
    _add_matching_options(p_match)
    p_match.add_argument(
        "--every-offset",
        action="store_true",
        help="fast path: refine every cyclic offset, not only the two most promising",
    )
    p_match.add_argument(
        "--reference",
        action="store_true",
        help="use the slow full-resolution reference instead of the fast path",
    )

    p_map = sub.add_parser(
        "map",
        help="build the topological map of a sequence of junction visits",
        description="Treat the folders as junction visits in order: decide known or new "
        "for each and build the topological map (Algorithms 1 and 4).",
    )
    _add_matching_options(p_map)
    add_rule_options(p_map)

    p_sim = sub.add_parser(
        "sim",
        help="run a simulated exploration and save its sweeps",
        description="Explore a pipe network by the right-most-branch rule and save every "
        "junction sweep as DIR/0001, DIR/0002, ... in the paper's folder layout.",
    )
    _add_run_options(p_sim, "perfect")
    p_sim.add_argument("--save-sweeps", required=True, metavar="DIR", help="new or empty folder")
    p_sim.add_argument(
        "--force",
        action="store_true",
        help="replace the sweep folders (0001, 0002, ...) of an earlier run in DIR",
    )

    p_record = sub.add_parser(
        "record",
        help="run a simulated exploration and write its log (MCAP)",
        description="Run an episode with the localizer online and write every sensor stream, "
        "camera sweep, ground truth and online decision to one MCAP log.",
    )
    _add_run_options(p_record, "autonomous")
    p_record.add_argument(
        "--threshold",
        type=_threshold,
        default=PAPER_THRESHOLD,
        help=f"the online localizer's similarity threshold (default {PAPER_THRESHOLD}); "
        "by default the two-view check decides known or new, and the threshold only asks "
        "for probes",
    )
    p_record.add_argument("-o", "--output", required=True, metavar="RUN.mcap", help="log file")
    p_record.add_argument("--force", action="store_true", help="overwrite an existing log")
    p_record.add_argument(
        "--view",
        action="store_true",
        help="stream the run live to a rerun viewer (spawned, or the one of --connect)",
    )
    p_record.add_argument(
        "--connect",
        metavar="URL",
        default=None,
        help="with --view: stream to the running rerun viewer or server at this gRPC URL "
        "(e.g. rerun+http://127.0.0.1:9876/proxy) instead of spawning one",
    )
    p_record.add_argument(
        "--save",
        action="store_true",
        help="with --view: write the view as RUN.rrd beside the log after the run, "
        "instead of streaming it",
    )

    for name, helptext, description in (
        (
            "replay",
            "rebuild the map from a log, deterministically",
            "Feed a log's /robot messages to the localizer in their total order and write "
            "the map as JSON (the format of pipemap map --json).",
        ),
        (
            "score",
            "replay a log and score the map against its ground truth",
            "Replay a log and compare every decision and the map with the log's /truth.",
        ),
        (
            "view",
            "show a log and its replay in the rerun viewer, or save them as .rrd",
            "Replay a log and show it in rerun on its simulated time: the network, the "
            "robot's true pose and trajectory, range rays, camera direction and images, "
            "sensor signals, controller states and the topological map as it grows, with "
            "each decision. Opens the viewer, or with --save writes a recording file.",
        ),
    ):
        p_log = sub.add_parser(name, help=helptext, description=description)
        p_log.add_argument("log", metavar="RUN.mcap", help="a pipemap log")
        p_log.add_argument("--threshold", type=_threshold, default=None, help=_THRESHOLD_HELP)
        p_log.add_argument(
            "--no-active-vision", action="store_true", help="never ask for probe sweeps"
        )
        add_similarity_options(p_log)
        add_rule_options(p_log)
        if name == "replay":
            p_log.add_argument(
                "-o",
                "--output",
                default=None,
                metavar="MAP.json",
                help="write the map here (default: standard output)",
            )
            p_log.add_argument(
                "--graphml",
                default=None,
                metavar="MAP.graphml",
                help="also write the map as GraphML",
            )
            p_log.add_argument("--force", action="store_true", help="overwrite existing files")
        elif name == "view":
            p_log.add_argument(
                "--save",
                default=None,
                metavar="OUT.rrd",
                help="write the recording to this file instead of opening the viewer",
            )
            p_log.add_argument("--force", action="store_true", help="overwrite an existing file")
        else:
            p_log.add_argument("--json", action="store_true", help="print one JSON object")
            p_log.add_argument(
                "--save-results",
                default=None,
                metavar="DIR",
                help="write score.json and visits.csv to this new or empty folder",
            )
            p_log.add_argument(
                "--force", action="store_true", help="replace the files of an earlier score"
            )

    p_route = sub.add_parser(
        "route",
        help="the way through a map from one junction to another, pipe by pipe",
        description="Plan the shortest route through a map (pipemap replay -o, pipemap map "
        "--json) and print it junction by junction: the port to arrive by and the port "
        "to leave by. Exit 1 when the map has no way between the two.",
    )
    p_route.add_argument("map", metavar="MAP.json", help="a map document with ports")
    p_route.add_argument(
        "--from",
        dest="start",
        type=_node_id,
        required=True,
        metavar="NODE",
        help="the map node (id) the route starts at",
    )
    p_route.add_argument(
        "--to",
        dest="goal",
        type=_node_id,
        required=True,
        metavar="NODE",
        help="the map node (id) the route ends at",
    )
    p_route.add_argument("--json", action="store_true", help="print the route as a JSON list")

    p_exp = sub.add_parser(
        "experiment",
        help="reproduce the paper's experiments in the simulator",
        description="Record, replay and score the runs of the paper's experiments (five "
        "conditions, 6/9/18/36 images per sweep, seven autonomous starts) and write Table 1, "
        "Table 2, Figures 6 and 7 and the starts as markdown, JSON and PNG.",
    )
    p_exp.add_argument("name", choices=["paper"], help="which experiment (paper)")
    p_exp.add_argument("--out", required=True, metavar="DIR", help="folder for the results")
    p_exp.add_argument("--resolution", type=_resolution, default=400, help="image size in px (400)")
    p_exp.add_argument("--seed", type=_seed, default=0, help="seed of every run (0)")
    p_exp.add_argument(
        "--threshold",
        type=_threshold,
        default=PAPER_THRESHOLD,
        help=f"similarity threshold (default {PAPER_THRESHOLD}); see record --threshold",
    )
    add_batch_options(p_exp)

    p_batch = sub.add_parser(
        "batch",
        help="run a grid of record + score runs on this machine or a Ray cluster",
        description="Run every run of SPEC.toml's [grid] (the Cartesian product of its "
        "lists: network, seed, start, condition, resolution, images, align_sweeps, rule, "
        "threshold) on Ray: each run is recorded, replayed and scored as pipemap record "
        "and pipemap score do. Writes DIR/runs/<run-id>/ and one table, DIR/results.csv "
        "and DIR/results.json. See docs/batch.md.",
    )
    p_batch.add_argument("spec", metavar="SPEC.toml", help="the grid to run (TOML)")
    p_batch.add_argument("--out", required=True, metavar="DIR", help="folder for the results")
    add_batch_options(p_batch)

    p_report = sub.add_parser(
        "batch-report",
        help="summarise a batch: grouped tables and figures (Markdown + PNG)",
        description="Group a batch's runs by the grid keys that vary (seeds pooled) and "
        "write DIR/report.md and report.json (mean, std, min, max per group) with a Figure 7 "
        "style box plot of same/different similarity and a Table 2 style plot of the "
        "rotation error.",
    )
    p_report.add_argument("dir", metavar="DIR", help="a folder written by pipemap batch")
    p_report.add_argument(
        "--by",
        default=None,
        metavar="KEY[,KEY...]",
        help="group by these grid keys (default: every key that varies, seed aside)",
    )

    p_info = sub.add_parser(
        "info",
        help="describe a log: channels, counts, run settings, integrity",
        description="Describe a pipemap log. A log cut short is read up to its last complete "
        "record (exit 0); a damaged one is read up to the damage (exit 1).",
    )
    p_info.add_argument("log", metavar="RUN.mcap", help="a pipemap log")
    p_info.add_argument("--json", action="store_true", help="print one JSON object")
    return parser


if __name__ == "__main__":  # pragma: no cover - convenience for `python -m`
    build_parser().print_help(sys.stdout)
