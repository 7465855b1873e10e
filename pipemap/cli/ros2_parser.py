"""The arguments of ``pipemap import`` and ``pipemap export`` (run by
:mod:`pipemap.cli.ros2_commands`): ROS 2 bags in and out, trajectories for evo."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pipemap.cli import arguments

if TYPE_CHECKING:
    from pipemap.cli.arguments import Subparsers

__all__ = ["add_export", "add_import"]


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


def add_export(sub: Subparsers) -> None:
    """``pipemap export RUN.mcap --ros2 OUT --tum DIR``: a log for ROS 2 tools and evo."""
    p = sub.add_parser(
        "export",
        help="write a log as a ROS 2 bag (--ros2), trajectories for evo (--tum), a GIS map "
        "(--geojson)",
        description="Write a pipemap log for other tools: a rosbag2 bag (MCAP storage, CDR) "
        "that ros2 bag, rosbags, Foxglove and RViz read and pipemap import reads back "
        "(--ros2, needs pipemap[ros]); the dead-reckoned and true trajectories in the TUM "
        "format evo reads, with each visit's junction position (--tum); the replayed map "
        "as GeoJSON (--geojson), also from a map document (MAP.json). docs/ros2.md.",
    )
    p.add_argument(
        "log",
        metavar="RUN.mcap",
        help="a pipemap log; for --geojson alone, also a map document (MAP.json)",
    )
    arguments.add_output(
        p, "--ros2", metavar="OUT", helptext="write a rosbag2 bag folder here (a new folder)"
    )
    arguments.add_output(
        p,
        "--tum",
        metavar="DIR",
        helptext="write estimated.tum, truth.tum and junctions.csv to this new or empty folder",
    )
    arguments.add_output(
        p,
        "--geojson",
        metavar="OUT.geojson",
        helptext="replay the log and write its map as GeoJSON for GIS tools: junctions placed "
        "by the robot's dead reckoning, pipes as lines, in a local metric frame",
    )
    arguments.add_force(p, "replace an earlier export")
