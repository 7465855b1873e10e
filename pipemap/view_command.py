"""``pipemap view``: a log and its replay in the rerun viewer, or in an ``.rrd`` file.

The log is replayed first (the map and the decisions are the replay's, as ``pipemap
replay`` makes them), then everything goes to rerun on the log's simulated time:
to a viewer it starts (or one already running), or with ``--save`` to a file.
Every argument is checked before the log is read; an existing file is replaced
only with ``--force``.

rerun is imported only here (by :mod:`replay.view`), so other commands do not pay
for it. Its import takes about 0.3 s: importing it in a thread while the log is
read and replayed was tried and saved nothing (the import holds the GIL).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import TextIO

from pipemap.errors import InputError, ViewerError
from pipemap.replay_commands import (
    check_output,
    localizer_config,
    open_source,
    progress_printer,
)

__all__ = ["run_view"]

#: The file suffix rerun gives its recordings; another one is most likely a slip.
RRD_SUFFIX = ".rrd"
_DISPLAY_VARIABLES = ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")


def _target(args: argparse.Namespace) -> Path | None:
    target = check_output(args.save, args.force)
    if target is not None and target.suffix != RRD_SUFFIX:
        raise InputError(f"{target}: a rerun recording is saved as a {RRD_SUFFIX} file")
    return target


def _check_display() -> None:
    """The viewer is a window: on Linux without X11 or Wayland it cannot open (and rerun
    would wait some 20 s to say so)."""
    if not sys.platform.startswith("linux"):
        return
    if not any(os.environ.get(name) for name in _DISPLAY_VARIABLES):
        raise ViewerError(
            "no display for the rerun viewer (DISPLAY and WAYLAND_DISPLAY are unset); "
            "save the recording with --save OUT.rrd and open it with rerun OUT.rrd elsewhere"
        )


def run_view(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Replay a log and show it in rerun, or save the recording with ``--save``."""
    target = _target(args)
    if target is None:
        _check_display()
    config = localizer_config(args)

    from replay import replay
    from replay.view import save_view, spawn_view

    source = open_source(args, err)
    result = replay(source, config, progress_printer(err))
    for warning in result.warnings:
        err.write(f"pipemap: note: {warning}\n")
    summary = (
        f"{args.log}: {result.sweeps} sweeps, {result.images} images, {len(result.visits)} "
        f"visits, {result.topomap.node_count} junctions"
    )
    if target is None:
        spawn_view(source, result)
        out.write(f"viewed {summary}, sent to the rerun viewer\n")
    else:
        save_view(source, result, target)
        out.write(f"viewed {summary}, written to {target}\n")
    return 0
