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
from typing import TYPE_CHECKING, TextIO

from pipemap.errors import InputError, ViewerError
from pipemap.replay_commands import (
    check_output,
    localizer_config,
    open_source,
    progress_printer,
)

if TYPE_CHECKING:
    from replay import MessageSource, ReplayResult

__all__ = ["check_view_target", "run_view", "view_recorded"]

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
            "save the recording with --save and open the .rrd with rerun elsewhere"
        )


def check_view_target(log: Path, save: bool, force: bool) -> Path | None:
    """For ``pipemap record --view [--save]``, before the run: the ``.rrd`` beside the
    log when saving (refused if it exists without ``force``), else the display."""
    if not save:
        _check_display()
        return None
    return check_output(str(log.with_suffix(RRD_SUFFIX)), force)


def _show(
    source: MessageSource, result: ReplayResult, target: Path | None, summary: str, out: TextIO
) -> None:
    from replay.view import save_view, spawn_view

    if target is None:
        spawn_view(source, result)
        out.write(f"viewed {summary}, sent to the rerun viewer\n")
    else:
        save_view(source, result, target)
        out.write(f"viewed {summary}, written to {target}\n")


def view_recorded(
    log: Path, target: Path | None, threshold: float, out: TextIO, err: TextIO
) -> None:
    """Right after ``pipemap record --view``: replay the new log and show or save it."""
    from localizer import LocalizerConfig
    from replay import FileSource, replay

    source = FileSource(log)
    result = replay(source, LocalizerConfig(threshold=threshold), progress_printer(err))
    _show(source, result, target, str(log), out)


def run_view(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Replay a log and show it in rerun, or save the recording with ``--save``."""
    target = _target(args)
    if target is None:
        _check_display()
    config = localizer_config(args)

    from replay import replay

    source = open_source(args, err)
    result = replay(source, config, progress_printer(err))
    for warning in result.warnings:
        err.write(f"pipemap: note: {warning}\n")
    summary = (
        f"{args.log}: {result.sweeps} sweeps, {result.images} images, {len(result.visits)} "
        f"visits, {result.topomap.node_count} junctions"
    )
    _show(source, result, target, summary, out)
    return 0
