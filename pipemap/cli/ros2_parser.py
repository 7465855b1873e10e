"""The arguments of ``pipemap import`` and ``pipemap export`` (run by
:mod:`pipemap.cli.ros2_commands`): ROS 2 bags in and out, trajectories for evo."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pipemap.cli import arguments

if TYPE_CHECKING:
    from pipemap.cli.arguments import Subparsers

__all__ = ["add_import"]


def add_import(sub: Subparsers) -> None:
    """``pipemap import BAG -o RUN.mcap``: a ROS 2 bag as a pipemap log."""
    p = sub.add_parser(
        "import",
        help="make a ROS 2 bag (rosbag2: MCAP or SQLite, CDR) into a pipemap log",
        description="Read a ROS 2 bag's camera images, camera joint and (where present) IMU, "
        "ranges, odometry, /tf and sweep markers, and write a pipemap log that replay, score "
        "and view take. docs/ros2.md is the contract; --spec overrides its defaults. Needs "
        "pipemap[ros].",
    )
    p.add_argument("bag", metavar="BAG", help="a rosbag2 folder, or one of its storage files")
    arguments.add_output(
        p, "-o", "--output", metavar="RUN.mcap", helptext="write the log here", required=True
    )
    p.add_argument(
        "--spec",
        metavar="SPEC.toml",
        default=None,
        help="topics, joint, field of view and sweep gap (docs/ros2.md); default: ROS 2's usual",
    )
    arguments.add_force(p, "overwrite an existing log")
