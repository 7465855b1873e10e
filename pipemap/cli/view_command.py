"""``pipemap view``: a log and its replay in the rerun viewer, or in an ``.rrd`` file.

The work is :func:`pipemap.api.view`'s (:mod:`pipemap.viewing`); this module checks
the arguments before the log is read (an existing file is replaced only with
``--force``), serves the saved view with ``--web``, and prints what was viewed.
"""

from __future__ import annotations

import argparse
import os
import socket
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, TextIO
from urllib.parse import urlsplit

from pipemap.cli.log_parser import WEB_PORT
from pipemap.cli.outputs import output_file
from pipemap.cli.replay_commands import localizer_config, progress_printer, report_damage
from pipemap.errors import InputError, ViewerError
from pipemap.viewing import RRD_SUFFIX, check_display

if TYPE_CHECKING:
    from pipemap.localizer import LocalizerConfig
    from pipemap.replay import ReplayResult
    from pipemap.replay.live import LiveSummary, LiveView, LiveViewProcess

__all__ = [
    "check_connect",
    "check_view_target",
    "live_summary",
    "live_view",
    "run_view",
    "view_recorded",
]


def _target(args: argparse.Namespace) -> Path | None:
    target = output_file(args.save, "--save", args.force)
    if target is not None and target.suffix != RRD_SUFFIX:
        raise InputError(f"{target}: a rerun recording is saved as a {RRD_SUFFIX} file")
    return target


def check_view_target(log: Path, save: bool, force: bool, connect: str | None) -> Path | None:
    """For ``pipemap record --view [--save | --connect URL]``, before the run: the
    ``.rrd`` beside the log when saving (refused if it exists without ``force``);
    else the viewer at ``connect``, or the display for a viewer to spawn."""
    if connect is not None:
        if save:
            raise InputError("--connect: streams the run live, --save writes it after; choose one")
        check_connect(connect)
        return None
    if not save:
        check_display()
        return None
    return output_file(str(log.with_suffix(RRD_SUFFIX)), "--save", force)


_SCHEMES = {"rerun": 443, "rerun+http": 80, "rerun+https": 443}
#: How long to wait for a viewer's port to answer before the run.
_CONNECT_TIMEOUT_S = 3.0


def check_connect(url: str) -> None:
    """``--connect URL``: a rerun gRPC proxy URL (``rerun+http://HOST:PORT/proxy``) whose
    port takes a connection now, so that a wrong URL is told before the run, not lost
    in the viewer's silence."""
    parts = urlsplit(url)
    if parts.scheme not in _SCHEMES or parts.path != "/proxy" or not parts.hostname:
        raise InputError(
            f"--connect {url}: not a rerun gRPC proxy URL (rerun+http://HOST:PORT/proxy)"
        )
    try:
        port = parts.port or _SCHEMES[parts.scheme]
    except ValueError:
        raise InputError(f"--connect {url}: the port is not a number from 0 to 65535") from None
    try:
        socket.create_connection((parts.hostname, port), timeout=_CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise ViewerError(
            f"--connect {url}: no rerun viewer or server answers at "
            f"{parts.hostname}:{port} ({exc.strerror or exc})"
        ) from None


def live_view(
    run_metadata: dict[str, str], threshold: float, connect: str | None
) -> LiveView | LiveViewProcess:
    """For ``pipemap record --view``: the live view of the run about to start, in a
    spawned viewer or sent to ``connect``; in a child process where the system can
    fork (started now, before the simulator), else in this one."""
    from pipemap.localizer import LocalizerConfig
    from pipemap.replay.live import LiveView, LiveViewProcess

    config = LocalizerConfig(threshold=threshold)

    def make() -> LiveView:
        if connect is None:
            return LiveView.spawn(run_metadata, config)
        return LiveView.connect(connect, run_metadata, config)

    return LiveViewProcess(make) if hasattr(os, "fork") else make()


def live_summary(name: str, summary: LiveSummary, connect: str | None) -> str:
    """The line ``pipemap record --view`` prints after the run."""
    where = "the rerun viewer" if connect is None else connect
    return (
        f"streamed {name}: {summary.sweeps} sweeps, {summary.images} images, "
        f"{summary.visits} visits, {summary.junctions} junctions, to {where}"
    )


def _summary(name: str, result: ReplayResult) -> str:
    return (
        f"{name}: {result.sweeps} sweeps, {result.images} images, {len(result.visits)} "
        f"visits, {result.topomap.used_node_count} junctions"
    )


def _view(
    log: Path,
    config: LocalizerConfig,
    target: Path | None,
    out: TextIO,
    err: TextIO,
    where: str | None = None,
    max_rate_hz: float | None = None,
    recorded: bool = False,
) -> None:
    """View ``log`` through :func:`pipemap.api.view` and say where it went (``where``,
    if given, in the last line): the log's damage and the replay's notes on ``err``
    (``recorded``: at the threshold the log was recorded with, as ``replay`` does
    without ``--threshold``)."""
    from pipemap import api

    viewed = api.view(log, config, target, max_rate_hz, progress_printer(err), recorded)
    report_damage(str(log), viewed.contents, err)
    for warning in viewed.result.warnings:
        err.write(f"pipemap: note: {warning}\n")
    if where is None:
        where = "sent to the rerun viewer" if target is None else f"written to {target}"
    out.write(f"viewed {_summary(str(log), viewed.result)}, {where}\n")


def view_recorded(
    log: Path, target: Path | None, threshold: float, out: TextIO, err: TextIO
) -> None:
    """Right after ``pipemap record --view``: replay the new log and show or save it."""
    from pipemap.localizer import LocalizerConfig

    _view(log, LocalizerConfig(threshold=threshold), target, out, err)


def _serve_web(args: argparse.Namespace, target: Path | None, out: TextIO, err: TextIO) -> int:
    """``--web``: save the view (to ``target``, or a temporary file) and serve it in
    rerun's web viewer on the loopback interface until a stop signal ends both."""
    from pipemap.replay.web import serve_web

    with tempfile.TemporaryDirectory(prefix="pipemap-web-") as folder:
        rrd = target if target is not None else Path(folder) / "view.rrd"
        where = "for the web viewer" if target is None else f"written to {target}"
        recorded = not args.threshold_given
        _view(Path(args.log), localizer_config(args), rrd, out, err, where, args.max_rate, recorded)
        port = WEB_PORT if args.port is None else args.port
        with serve_web(rrd, port, Path(folder) / "rerun.log") as server:
            out.write(f"serving the view at {server.url} (Ctrl-C stops)\n")
            out.flush()
            status = server.process.wait()
    raise ViewerError(f"rerun's web viewer stopped by itself (status {status})")


def run_view(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Replay a log and show it in rerun, save the recording with ``--save``, or serve
    it in rerun's web viewer with ``--web``."""
    target = _target(args)
    if args.web:
        from pipemap.replay.web import check_web_port, rerun_executable

        rerun_executable()
        check_web_port(WEB_PORT if args.port is None else args.port)
        return _serve_web(args, target, out, err)
    if args.port is not None:
        raise InputError("--port: the web viewer's port, so it needs --web")
    if target is None:
        check_display()
    recorded = not args.threshold_given
    _view(Path(args.log), localizer_config(args), target, out, err, None, args.max_rate, recorded)
    return 0
