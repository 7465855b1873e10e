"""What ``sim`` and ``record`` take from their flags: the run's
:class:`~pipemap.recorder.RecordSettings`, built in one place for both, and the flags
that only some conditions use. A flag the chosen condition ignores is an error (one
line naming it), never silently dropped."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from pipemap.defaults import LAMP_STRENGTHS
from pipemap.errors import InputError

if TYPE_CHECKING:  # the simulator loads lazily: pipemap --help stays instant
    from pipemap.recorder import RecordSettings

__all__ = ["check_condition_flags", "explore_policy", "record_settings"]

#: The exploration of the autonomous robot when ``--explore`` is not given.
DEFAULT_EXPLORE = "map"


def check_condition_flags(args: argparse.Namespace) -> None:
    """Refuse ``--explore``, ``--obstacles`` and ``--motor-faults`` with a condition that
    places the robot at each junction: only the autonomous robot chooses its exits and
    drives."""
    if args.condition == "autonomous":
        return
    placed = f"placed by hand ({args.condition})"
    ignored = (
        (
            args.explore is not None,
            f"--explore {args.explore}: only the autonomous robot chooses its exits; "
            f"{placed} it follows the paper's tour (use --condition autonomous)",
        ),
        (
            args.obstacles,
            f"--obstacles: only the autonomous robot drives into deposits; {placed} it "
            "never meets one",
        ),
        (
            args.motor_faults,
            f"--motor-faults: only the autonomous robot drives; {placed} its motors never cut out",
        ),
    )
    for given, why in ignored:
        if given:
            raise InputError(why)


def explore_policy(args: argparse.Namespace) -> str:
    """``--explore``'s policy, :data:`DEFAULT_EXPLORE` when not given."""
    return DEFAULT_EXPLORE if args.explore is None else str(args.explore)


def record_settings(args: argparse.Namespace) -> RecordSettings:
    """The run that ``sim``'s or ``record``'s flags ask for; a flag the command does not
    have (``sim`` has no ``--threshold``) leaves the library's default."""
    from pipemap.recorder import Explore, RecordSettings
    from pipemap.sim.episode import Condition

    values: dict[str, Any] = {
        "network": args.network,
        "start": args.start,
        "seed": args.seed,
        "condition": Condition(args.condition),
        "resolution_px": args.resolution,
        "images_per_sweep": args.images,
        "align_sweeps": args.align_sweeps,
        "explore": Explore(explore_policy(args)),
        "lamp_strength": LAMP_STRENGTHS[args.lighting],
        "tilt_rad": math.radians(args.tilt_deg),
        "obstacles": args.obstacles,
        "motor_faults": args.motor_faults,
        "alike": args.alike,
        "odometry_drift": args.odometry_drift,
        # ``record --no-probe-moves``; ``sim`` always makes the moves asked for.
        "probe_moves": not getattr(args, "no_probe_moves", False),
        "world_memory_mib": args.world_memory,
    }
    for flag, key in (("threshold", "threshold"), ("image_format", "image_format")):
        if getattr(args, flag, None) is not None:
            values[key] = getattr(args, flag)
    if getattr(args, "jpeg_quality", None) is not None:
        values["jpeg_quality"] = args.jpeg_quality
    return RecordSettings(**values)
