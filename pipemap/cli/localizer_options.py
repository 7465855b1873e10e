"""The localizer's flags, shared by every command that runs it (``match``, ``map``,
``replay``, ``score``, ``view``), and the settings they parse into: the threshold, the
fast path's similarity (``--robust`` and what it stands for) and the rules that turn
pipemap's localizer back into the paper's."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from pipemap.cli import arguments
from pipemap.localizer.presets import (
    PAPER_THRESHOLD,
    ROBUST_FAST,
    ROBUST_HIGHPASS_FRACTION,
    ROBUST_THRESHOLD,
    ROBUST_ZOOMS,
)

if TYPE_CHECKING:
    from pipemap.localizer import FastConfig, LocalizerConfig

__all__ = [
    "add_rule_options",
    "add_similarity_options",
    "add_illumination",
    "add_threshold",
    "apply_presets",
    "fast_config",
    "illumination_setting",
    "port_check",
    "rule_config",
    "two_view_settings",
]

_THRESHOLD_HELP = (
    f"similarity threshold (default {PAPER_THRESHOLD}, or {ROBUST_THRESHOLD} with --robust): "
    "decides known or new with --no-verify or --no-two-view; by default the two-view "
    "check decides, and the threshold only asks for probes and decides sweeps with too "
    "few keypoints to check"
)


def add_threshold(p: argparse.ArgumentParser, recorded: bool = False) -> None:
    """``--threshold``, left ``None`` for :func:`apply_presets` to fill in; ``recorded``:
    a replay's, whose default is the threshold its log was recorded with."""
    text = _THRESHOLD_HELP
    if recorded:
        text = text.replace(
            f"default {PAPER_THRESHOLD}",
            f"default: the one the log was recorded with, else {PAPER_THRESHOLD}",
        )
    p.add_argument("--threshold", type=arguments.threshold, default=None, help=text)


def apply_presets(args: argparse.Namespace) -> None:
    """Fill in what ``--robust`` stands for, and the threshold left to its default.

    Options given explicitly win over the preset's."""
    if not hasattr(args, "baseline"):
        return
    if args.robust:
        args.zoom = args.zoom or ROBUST_ZOOMS
        args.highpass = args.highpass or ROBUST_HIGHPASS_FRACTION
        args.baseline = True
    # A replay takes the threshold its log was recorded with unless one is given.
    args.threshold_given = args.threshold is not None or args.robust
    if args.threshold is None:
        args.threshold = ROBUST_THRESHOLD if args.robust else PAPER_THRESHOLD


def add_similarity_options(p: argparse.ArgumentParser) -> None:
    """The fast path's settings: ``--downsample`` trades accuracy for speed; ``--zoom``,
    ``--highpass`` and ``--baseline`` (together with their threshold: ``--robust``)
    switch on pipemap's extensions of the paper's similarity (off by default, so the
    defaults are the paper's Algorithm 2)."""
    p.add_argument(
        "--downsample",
        type=arguments.downsample,
        default=None,
        help="fast path: column decimation factor of the accurate stage (default 4)",
    )
    p.add_argument(
        "--zoom",
        type=arguments.zooms,
        default=(),
        metavar="Z[,Z...]",
        help="also compare each image pair with either image zoomed in by these factors, "
        "for cameras off the junction centre (e.g. 1.15,1.3; default off)",
    )
    p.add_argument(
        "--highpass",
        type=arguments.highpass,
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
    """The decision rule: ``--rule paper`` (the paper's), and the flags that turn
    pipemap's own checks off one by one: ``--allow-repeat``, ``--no-verify``,
    ``--no-two-view``, ``--no-port-check`` and ``--no-odometry-check``."""
    p.add_argument(
        "--rule",
        choices=["default", "paper"],
        default="default",
        help="paper: the paper's decision rule (its Algorithm 1), none of pipemap's checks: "
        "the similarity threshold decides, every known junction competes, the NCC rotation, "
        "no port or odometry check (= --no-two-view --allow-repeat --no-port-check "
        "--no-odometry-check); default: pipemap's, with the checks the flags below turn off",
    )
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
        "--no-odometry-check",
        action="store_true",
        help="let a known junction be a candidate wherever the robot's dead reckoning puts "
        "it (by default one farther than the odometry's drift allows is not: junctions "
        "that look alike stay apart)",
    )
    p.add_argument(
        "--hypotheses",
        type=arguments.positive_int,
        default=8,
        metavar="K",
        help="where junctions that look alike fit a visit equally, keep a map for each, "
        "at most K at once, weighed by odometry, ports and later pipes (default 8; 1: one "
        "map, the best ranked junction is taken; docs/lookalike.md)",
    )
    add_illumination(p)


def add_illumination(p: argparse.ArgumentParser) -> None:
    """``--illumination auto|lamp|even`` (:func:`illumination_setting` reads it)."""
    p.add_argument(
        "--illumination",
        choices=["auto", "lamp", "even"],
        default="auto",
        help="lamp: divide every image by its own illumination estimate before matching "
        "(sweeps lit by the robot's lamp); even: as in the paper; auto (default): lamp "
        "when the log's camera had its lamp on, or when the image folders' sweep.txt say "
        "'lighting: lamp' (pipemap sim --save-sweeps writes it), else even",
    )


def rule_config(args: argparse.Namespace, config: LocalizerConfig) -> LocalizerConfig:
    """``config`` under the rule ``--rule`` names."""
    return config.paper_rule() if getattr(args, "rule", "default") == "paper" else config


def port_check(args: argparse.Namespace) -> bool:
    """``port_check`` of :class:`localizer.LocalizerConfig` from ``--no-port-check``."""
    return not getattr(args, "no_port_check", False)


def odometry_check(args: argparse.Namespace) -> bool:
    """``odometry_check`` of :class:`localizer.LocalizerConfig` from ``--no-odometry-check``."""
    return not getattr(args, "no_odometry_check", False)


def hypotheses(args: argparse.Namespace) -> int:
    """``hypotheses`` of :class:`localizer.LocalizerConfig` from ``--hypotheses``."""
    return int(getattr(args, "hypotheses", 8))


def illumination_setting(args: argparse.Namespace) -> bool | None:
    """``lamp`` of :class:`localizer.LocalizerConfig` from ``--illumination``."""
    return {"auto": None, "lamp": True, "even": False}[args.illumination]


def two_view_settings(args: argparse.Namespace) -> tuple[bool, bool]:
    """``two_view`` and ``verify`` of :class:`localizer.LocalizerConfig` from the flags."""
    two_view = not args.no_two_view
    return two_view, two_view and not args.no_verify
