"""The ``pipemap`` command: parse, configure logging, run one command, one exit path.

Library code raises :class:`pipemap.errors.PipemapError` for bad input; here alone
it is caught, printed as one line naming what is wrong, and turned into exit status
2. Any other exception is a bug and keeps its traceback. Commands import their heavy
dependencies lazily so that ``pipemap --help`` is instant.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Sequence

from pipemap.cli.parser import apply_presets, build_parser
from pipemap.errors import PipemapError

__all__ = ["main"]


def _run(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    apply_presets(args)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING,
        format="pipemap: %(levelname)s: %(message)s",
        stream=sys.stderr,
    )
    if args.command in ("match", "map"):
        from pipemap.cli import folder_commands

        runner = folder_commands.run_match if args.command == "match" else folder_commands.run_map
        return runner(args, sys.stdout)
    if args.command == "sim":
        from pipemap.cli.sim_command import run_sim

        return run_sim(args, sys.stdout)
    if args.command in ("record", "info"):
        from pipemap.cli import log_commands

        if args.command == "record":
            return log_commands.run_record(args, sys.stdout, sys.stderr)
        return log_commands.run_info(args, sys.stdout)
    if args.command in ("replay", "score"):
        from pipemap.cli import replay_commands

        if args.command == "replay":
            return replay_commands.run_replay(args, sys.stdout, sys.stderr)
        return replay_commands.run_score(args, sys.stdout, sys.stderr)
    if args.command == "route":
        from pipemap.cli.route_command import run_route

        return run_route(args, sys.stdout)
    if args.command == "experiment":
        from pipemap.cli.experiment_command import run_experiment

        return run_experiment(args, sys.stdout, sys.stderr)
    if args.command == "view":
        from pipemap.cli.view_command import run_view

        return run_view(args, sys.stdout, sys.stderr)
    raise AssertionError(f"unhandled command {args.command}")  # the parser allows no other


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pipemap`` console script; returns the exit status."""
    try:
        return _run(argv)
    except PipemapError as exc:
        print(f"pipemap: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("pipemap: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
