"""What ``sim`` and ``record`` take from their flags beyond the values themselves: the
flags that only some conditions use. A flag the chosen condition ignores is an error
(one line naming it), never silently dropped."""

from __future__ import annotations

import argparse

from pipemap.errors import InputError

__all__ = ["check_condition_flags", "explore_policy"]

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
