"""The arguments of the commands on image-set folders and on the maps built from them:
``match``, ``map`` (run by :mod:`pipemap.cli.folder_commands`) and ``route``
(:mod:`pipemap.cli.route_command`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from pipemap.cli import arguments
from pipemap.cli.localizer_options import (
    add_illumination,
    add_rule_options,
    add_similarity_options,
    add_threshold,
)

if TYPE_CHECKING:
    from pipemap.cli.arguments import Subparsers

__all__ = ["add_map", "add_match", "add_route"]


def _add_matching_options(p: argparse.ArgumentParser) -> None:
    """The image-set folders and how to compare them: shared by ``match`` and ``map``."""
    p.add_argument("dirs", nargs="+", metavar="DIR", help="image-set folders (camera_image1..N)")
    arguments.add_json(p)
    add_threshold(p)
    p.add_argument(
        "--fov-deg",
        type=arguments.degrees,
        default=None,
        help="horizontal field of view (default 80)",
    )
    p.add_argument(
        "--keep-top",
        type=arguments.fraction,
        default=None,
        help="fraction of each image kept from the top (default 0.5)",
    )
    add_similarity_options(p)


def add_match(sub: Subparsers) -> None:
    """``pipemap match DIR...``: every pair of image sets."""
    p = sub.add_parser(
        "match",
        help="similarity and rotation of every pair of image sets",
        description="Compare every unordered pair of image sets, in argument order "
        "(the paper's Algorithm 2).",
    )
    _add_matching_options(p)
    p.add_argument(
        "--every-offset",
        action="store_true",
        help="fast path: refine every cyclic offset (by default, those a screen on smaller "
        "images puts within 0.035 of the best; --robust refines the two most promising only)",
    )
    p.add_argument(
        "--reference",
        action="store_true",
        help="use the slow full-resolution reference instead of the fast path",
    )
    add_illumination(p)


def add_map(sub: Subparsers) -> None:
    """``pipemap map DIR...``: the map of a sequence of junction visits."""
    p = sub.add_parser(
        "map",
        help="build the topological map of a sequence of junction visits",
        description="Treat the folders as junction visits in order: decide known or new "
        "for each and build the topological map (Algorithms 1 and 4).",
    )
    _add_matching_options(p)
    add_rule_options(p)
    arguments.add_verbose(p)


def add_route(sub: Subparsers) -> None:
    """``pipemap route MAP.json --from A --to B``: the way through a map."""
    p = sub.add_parser(
        "route",
        help="the way through a map from one junction to another, pipe by pipe",
        description="Plan the shortest route through a map (pipemap replay -o, pipemap map "
        "--json) and print it junction by junction: the port to arrive by and the port "
        "to leave by. Exit 1 when the map has no way between the two.",
    )
    p.add_argument("map", metavar="MAP.json", help="a map document with ports")
    for flag, dest, end in (("--from", "start", "starts"), ("--to", "goal", "ends")):
        p.add_argument(
            flag,
            dest=dest,
            type=arguments.node_id,
            required=True,
            metavar="NODE",
            help=f"the map node (id) the route {end} at",
        )
    p.add_argument("--json", action="store_true", help="print the route as a JSON list")
