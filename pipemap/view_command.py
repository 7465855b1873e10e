"""``pipemap view``: a log and its replay in the rerun viewer, or in an ``.rrd`` file.

The log is replayed first (the map and the decisions are the replay's, as ``pipemap
replay`` makes them), then everything goes to rerun on the log's simulated time:
to a viewer it starts (or one already running), or with ``--save`` to a file.
Every argument is checked before the log is read; an existing file is replaced
only with ``--force``.

rerun is imported only here (by :mod:`replay.view`), so other commands do not pay
for it. Its import takes about 0.3 s, and logging the log's streams some more, so
where the system can fork, the replay runs in a child process on the other core
while this one imports rerun and logs the streams; the child sends back the
decisions, which are logged last. The recording is the same either way. (Importing
rerun in a thread saved nothing: the import holds the GIL.)
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import pickle
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from pipemap.errors import InputError, ViewerError
from pipemap.replay_commands import (
    check_output,
    localizer_config,
    open_source,
    progress_printer,
)

if TYPE_CHECKING:
    from localizer import LocalizerConfig
    from replay import MessageSource, ReplayResult
    from replay.view import Replayed

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


def _summary(name: str, result: ReplayResult) -> str:
    return (
        f"{name}: {result.sweeps} sweeps, {result.images} images, {len(result.visits)} "
        f"visits, {result.topomap.node_count} junctions"
    )


def _show(source: MessageSource, result: Replayed, target: Path | None) -> None:
    from replay.view import save_view, spawn_view

    if target is None:
        spawn_view(source, result)
    else:
        save_view(source, result, target)


def _replay_beside(
    source: MessageSource, config: LocalizerConfig, err: TextIO
) -> Callable[[], ReplayResult]:
    """Start replaying ``source`` in a child process; returns a function that waits
    for the result (or raises the child's error). Without ``os.fork``, the replay
    runs here and now."""
    from replay import replay

    if not hasattr(os, "fork"):
        result = replay(source, config, progress_printer(err))
        return lambda: result
    err.flush()
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: replay, send the result, and leave without cleanup
        os.close(read_end)
        status = 0
        try:
            done = replay(source, config, progress_printer(err))
            # The view needs the decisions, not the visits' image sets.
            payload: Any = dataclasses.replace(done, visit_sets={})
        except BaseException as exc:  # noqa: BLE001  (handed to the parent to report)
            payload, status = exc, 1
        try:
            with os.fdopen(write_end, "wb") as pipe:
                pickle.dump(payload, pipe, protocol=pickle.HIGHEST_PROTOCOL)
            err.flush()
        finally:
            os._exit(status)
    os.close(write_end)

    def wait() -> ReplayResult:
        with os.fdopen(read_end, "rb") as pipe:
            data = pipe.read()
        _, status = os.waitpid(pid, 0)
        if not data:
            raise ViewerError(f"the replay process ended without a result (status {status})")
        payload = pickle.loads(data)
        if isinstance(payload, BaseException):
            raise payload
        result: ReplayResult = payload
        return result

    return wait


def _view(
    source: MessageSource,
    config: LocalizerConfig,
    target: Path | None,
    name: str,
    out: TextIO,
    err: TextIO,
) -> None:
    """Replay ``source`` beside the view's own logging, then show or save the view."""
    waiting = _replay_beside(source, config, err)
    got: list[ReplayResult] = []
    waited = False

    def result() -> ReplayResult:
        nonlocal waited
        if not waited:
            waited = True
            got.append(waiting())
        return got[0]

    try:
        _show(source, result, target)
    finally:
        if not waited:  # the view failed first: still wait for the child
            result()
    done = got[0]
    for warning in done.warnings:
        err.write(f"pipemap: note: {warning}\n")
    where = "sent to the rerun viewer" if target is None else f"written to {target}"
    out.write(f"viewed {_summary(name, done)}, {where}\n")


def view_recorded(
    log: Path, target: Path | None, threshold: float, out: TextIO, err: TextIO
) -> None:
    """Right after ``pipemap record --view``: replay the new log and show or save it."""
    from localizer import LocalizerConfig
    from replay import FileSource

    _view(FileSource(log), LocalizerConfig(threshold=threshold), target, str(log), out, err)


def run_view(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Replay a log and show it in rerun, or save the recording with ``--save``."""
    target = _target(args)
    if target is None:
        _check_display()
    config = localizer_config(args)
    source = open_source(args, err)
    _view(source, config, target, args.log, out, err)
    return 0
