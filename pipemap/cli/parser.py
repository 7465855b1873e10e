"""The ``pipemap`` argument parser (argparse only, no heavy imports).

Each command's arguments are added by a function of the ``*_parser`` module beside the
module that runs it; the flags several commands share are built by the helpers of
:mod:`pipemap.cli.localizer_options` and :mod:`pipemap.cli.arguments`."""

from __future__ import annotations

import argparse
import sys

from pipemap import __version__
from pipemap.cli.arguments import OneLineParser, add_verbose
from pipemap.cli.batch_parser import add_batch, add_batch_report, add_experiment
from pipemap.cli.folder_parser import add_map, add_match, add_route
from pipemap.cli.log_parser import add_info, add_replay, add_score, add_view
from pipemap.cli.ros2_parser import add_export, add_import
from pipemap.cli.sim_parser import add_record, add_sim

__all__ = ["build_parser"]

#: Each command's parser, in the order ``pipemap --help`` lists them.
_COMMANDS = (
    add_match,
    add_map,
    add_sim,
    add_record,
    add_replay,
    add_score,
    add_view,
    add_route,
    add_experiment,
    add_batch,
    add_batch_report,
    add_info,
    add_import,
    add_export,
)


def build_parser() -> argparse.ArgumentParser:
    """The full ``pipemap`` parser with one subparser per command."""
    parser = OneLineParser(
        prog="pipemap",
        description="Topological localization and mapping of robots in buried pipe networks.",
    )
    parser.add_argument("--version", action="version", version=f"pipemap {__version__}")
    add_verbose(parser, top=True)
    # Not required: without a command, pipemap prints its usage (see pipemap.cli.app).
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    for add_command in _COMMANDS:
        add_command(sub)
    return parser


if __name__ == "__main__":  # pragma: no cover - convenience for `python -m`
    build_parser().print_help(sys.stdout)
