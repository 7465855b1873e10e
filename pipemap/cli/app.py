"""The ``pipemap`` command: parse, configure logging, run one command, one exit path.

Library code raises :class:`pipemap.errors.PipemapError` for bad input; here alone
it is caught, printed as one line naming what is wrong (a line per mistake when a
SPEC has several), and turned into exit status 2 (3 for an output that could not be
written whole: a full disk, a killed writer). Stop signals and a standard output
that cannot be written end every command the same way (:mod:`pipemap.cli.exits`).
Any other exception is a bug and keeps its traceback. Commands import their heavy
dependencies lazily so that ``pipemap --help`` is instant.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import logging
import os
import sys
from collections.abc import Callable, Sequence
from typing import TextIO

from pipemap.allocator import keep_freed_memory
from pipemap.cli.exits import (
    PIPE_CLOSED,
    OutputClosed,
    flush_standard_output,
    guarded_standard_output,
    stop_signals,
    stopped_status,
)
from pipemap.cli.localizer_options import apply_presets
from pipemap.cli.parser import build_parser
from pipemap.errors import PipemapError, WriteError

__all__ = ["BAD_INPUT", "INTERRUPTED", "WRITE_FAILED", "main", "one_blas_thread"]

#: Exit statuses besides 0 (done) and 1 (done, but the run or the log is incomplete:
#: ``sim`` and ``record`` stopped short of covering the network, ``info`` found damage).
BAD_INPUT = 2
WRITE_FAILED = 3
INTERRUPTED = 130


#: A command's runner: parsed arguments, standard output, standard error -> exit status.
Runner = Callable[[argparse.Namespace, TextIO, TextIO], int]

#: Each command and the function that runs it, as ``module:function``. The module
#: is imported only when its command runs, so that ``pipemap --help`` loads none.
COMMANDS: dict[str, str] = {
    "match": "pipemap.cli.folder_commands:run_match",
    "map": "pipemap.cli.folder_commands:run_map",
    "sim": "pipemap.cli.sim_command:run_sim",
    "record": "pipemap.cli.log_commands:run_record",
    "info": "pipemap.cli.log_commands:run_info",
    "replay": "pipemap.cli.replay_commands:run_replay",
    "score": "pipemap.cli.replay_commands:run_score",
    "route": "pipemap.cli.route_command:run_route",
    "experiment": "pipemap.cli.experiment_command:run_experiment",
    "batch": "pipemap.cli.batch_command:run_batch_command",
    "batch-report": "pipemap.cli.batch_command:run_batch_report",
    "view": "pipemap.cli.view_command:run_view",
    "import": "pipemap.cli.ros2_commands:run_import",
    "export": "pipemap.cli.ros2_commands:run_export",
}


#: The modules of the extras (``pip install "pipemap[EXTRA]"``): the core reads,
#: replays, scores and matches without them.
EXTRAS: dict[str, str] = {"pybullet": "sim", "ray": "batch", "rerun": "view"}
#: The extra modules each command needs, checked before it starts.
NEEDS: dict[str, tuple[str, ...]] = {
    "sim": ("pybullet",),
    "record": ("pybullet",),
    "experiment": ("pybullet", "ray"),
    "batch": ("pybullet", "ray"),
    "view": ("rerun",),
}


def _missing_extra(module: str, command: str) -> MissingExtra:
    extra = EXTRAS[module]
    return MissingExtra(
        f"pipemap {command} needs {module}, which comes with pipemap's {extra!r} extra: "
        f'python3 -m pip install "pipemap[{extra}]"'
    )


class MissingExtra(PipemapError):
    """A command needs a package of an extra that is not installed."""


def _check_extras(args: argparse.Namespace) -> None:
    """Every package the command needs is installed (``record --view``: rerun too)."""
    needed = NEEDS.get(args.command, ())
    if getattr(args, "view", False) is True:
        needed += ("rerun",)
    for module in needed:
        if importlib.util.find_spec(module) is None:
            raise _missing_extra(module, args.command)


def _run(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        # No command: what there is to run, as argparse reports a missing argument.
        parser.print_help(sys.stderr)
        print("pipemap: error: a command is required", file=sys.stderr)
        return BAD_INPUT
    keep_freed_memory()  # the same results, found sooner (pipemap.allocator)
    apply_presets(args)
    # Other libraries' messages stay at warnings: -v is for pipemap's own decisions.
    logging.basicConfig(
        level=logging.WARNING, format="pipemap: %(levelname)s: %(message)s", stream=sys.stderr
    )
    logging.getLogger("pipemap").setLevel(logging.DEBUG if args.verbose else logging.WARNING)
    _check_extras(args)
    module, function = COMMANDS[args.command].split(":")
    runner: Runner = getattr(importlib.import_module(module), function)
    try:
        return runner(args, sys.stdout, sys.stderr)  # sys.stdout: guarded by main
    except ModuleNotFoundError as exc:
        top = (exc.name or "").split(".")[0]
        if top in EXTRAS:  # a path of the command that NEEDS does not know of
            raise _missing_extra(top, args.command) from None
        raise


#: Environment variables that size the BLAS thread pool (OpenBLAS reads the first it
#: finds of the first three; MKL its own, then OpenMP's).
BLAS_THREAD_SETTINGS = (
    "OPENBLAS_NUM_THREADS",
    "GOTO_NUM_THREADS",
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
)


def one_blas_thread() -> bool:
    """Run numpy's matrix products on one thread, unless the user sized the pool.

    pipemap's products are small (a set's area reduction: a 25 x 400 weight matrix
    times six 400 x 800 images at 800 px), and OpenBLAS's threads spin while they
    wait for the next one: on a busy machine ``pipemap match`` on the paper's 11
    sets took 4.5 s of CPU with a thread a core, 2.7 with one, the same numbers to
    the last bit (docs/performance.md). Effective only before numpy loads, which no
    command does before :func:`main` calls this. Returns whether it set anything.
    """
    if any(name in os.environ for name in BLAS_THREAD_SETTINGS):
        return False
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    os.environ["MKL_NUM_THREADS"] = "1"
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pipemap`` console script; returns the exit status."""
    one_blas_thread()
    with guarded_standard_output(), stop_signals():
        try:
            try:
                return _run(argv)
            finally:
                # Here, not on the interpreter's way out: a failure is one line.
                flush_standard_output()
        except OutputClosed:
            return PIPE_CLOSED  # the reader has gone (| head): nothing to say, as coreutils
        except WriteError as exc:
            print(f"pipemap: error: {exc}", file=sys.stderr)
            return WRITE_FAILED
        except PipemapError as exc:
            # One line per mistake (a SPEC may have several), each with the prefix.
            for line in str(exc).splitlines() or [type(exc).__name__]:
                print(f"pipemap: error: {line}", file=sys.stderr)
            return BAD_INPUT
        except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM, SIGHUP (pipemap.cli.exits)
            status, name = stopped_status(exc)
            print(f"pipemap: interrupted ({name})", file=sys.stderr)
            return status


if __name__ == "__main__":
    sys.exit(main())
