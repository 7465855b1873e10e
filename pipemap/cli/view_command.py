"""``pipemap view``: a log and its replay in the rerun viewer, or in an ``.rrd`` file.

The map and the decisions are the replay's, as ``pipemap replay`` makes them; they
go to rerun with the log's streams, on the log's simulated time: to a viewer it
starts (or one already running), or with ``--save`` to a file.
Every argument is checked before the log is read; an existing file is replaced
only with ``--force``.

rerun is imported only here (by :mod:`replay.view`), so other commands do not pay
for it. Its import takes 0.25-0.35 s. Where the system can fork, a child process
replays the log, on the other core, while this process imports rerun and then
reads the log's streams and logs them a window at a time; the child's decisions
come last. Each process reads the file as it goes, so neither holds the log (a
100-junction run's is 1.4 million messages). The recording is the same either way.
(Importing rerun in a thread saved nothing: the import holds the GIL.)
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import pickle
import signal
import socket
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO
from urllib.parse import urlsplit

from pipemap.cli.log_parser import WEB_PORT
from pipemap.cli.outputs import output_file
from pipemap.cli.replay_commands import localizer_config, progress_printer, report_damage
from pipemap.errors import InputError, ViewerError

if TYPE_CHECKING:
    from pipemap.localizer import LocalizerConfig
    from pipemap.replay import MessageSource, ReplayResult
    from pipemap.replay.live import LiveSummary, LiveView, LiveViewProcess
    from pipemap.replay.view import Replayed

__all__ = [
    "check_connect",
    "check_view_target",
    "live_summary",
    "live_view",
    "run_view",
    "view_recorded",
]

#: The file suffix rerun gives its recordings; another one is most likely a slip.
RRD_SUFFIX = ".rrd"
_DISPLAY_VARIABLES = ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")


def _target(args: argparse.Namespace) -> Path | None:
    target = output_file(args.save, "--save", args.force)
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
        _check_display()
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
        f"visits, {result.topomap.node_count} junctions"
    )


def _show(
    source: MessageSource, result: Replayed, target: Path | None, max_rate_hz: float | None
) -> None:
    from pipemap.replay.view import save_view, spawn_view
    from pipemap.replay.view_topics import DEFAULT_MAX_RATE_HZ

    rate = DEFAULT_MAX_RATE_HZ if max_rate_hz is None else max_rate_hz
    if target is None:
        spawn_view(source, result, rate)
    else:
        save_view(source, result, target, rate)


class _Child:
    """A forked process that replays the log and sends back the result.

    The pipe carries the replay's result without the image sets (or its error).
    Meanwhile the parent imports rerun and reads and logs the log's streams itself:
    each process reads the file as it goes, and neither holds the log.
    """

    def __init__(
        self,
        open_log: Callable[[], MessageSource],
        config: Callable[[], LocalizerConfig],
        err: TextIO,
    ) -> None:
        err.flush()
        read_end, write_end = os.pipe()
        self._pid = os.fork()
        if self._pid == 0:
            os.close(read_end)
            self._run(open_log, config, err, write_end)  # never returns
        os.close(write_end)
        self._pipe = os.fdopen(read_end, "rb")
        self._done = False
        self._answered = False
        self._result: ReplayResult | None = None

    @staticmethod
    def _run(
        open_log: Callable[[], MessageSource],
        config: Callable[[], LocalizerConfig],
        err: TextIO,
        write_end: int,
    ) -> None:
        status = 1
        try:
            with os.fdopen(write_end, "wb") as pipe:
                try:
                    from pipemap import api

                    done = api.replay(
                        open_log(), config(), progress_printer(err), keep_prepared=False
                    )
                    # The view needs the decisions, not the visits' image sets (not
                    # kept) or the localizer's database of junctions.
                    payload: Any = dataclasses.replace(done, localizer=None)
                    status = 0
                except BaseException as exc:  # noqa: BLE001  (the parent reports it)
                    payload = exc
                pickle.dump(payload, pipe, protocol=_PROTOCOL)
            err.flush()
        finally:
            os._exit(status)

    def result(self) -> ReplayResult:
        """The replay's result, once the child has it."""
        if self._result is None:
            try:
                payload = pickle.load(self._pipe)
                self._answered = True
            except (EOFError, pickle.UnpicklingError):
                self._answered = True  # the child ended already
                self.close()
                raise ViewerError("the replay process ended without a result") from None
            self.close()
            if isinstance(payload, BaseException):
                raise payload
            self._result = payload
        return self._result

    def close(self) -> None:
        """Wait for the child to end (idempotent); a child whose result was not taken
        (the view stopped: a signal, an error) is ended first, not waited for."""
        if not self._done:
            self._done = True
            self._pipe.close()
            if not self._answered:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(self._pid, signal.SIGKILL)
            os.waitpid(self._pid, 0)


#: The pickle protocol that carries the replay's result.
_PROTOCOL = pickle.HIGHEST_PROTOCOL


def _can_fork() -> bool:
    """Whether the replay can run in a forked child (else one process does it all)."""
    return hasattr(os, "fork")


def _quiet_rerun() -> None:
    """Turn rerun's own log lines off for a save, unless ``RUST_LOG`` says otherwise.

    rerun's file writer logs its failures itself (``ERROR ... Failed to write log
    stream``, ``File-writer thread shut down prematurely``) on standard error, besides
    the error it raises, which is pipemap's one line. rerun reads ``RUST_LOG`` once, as
    it is imported, so this comes before the import."""
    os.environ.setdefault("RUST_LOG", "off")


def _view(
    log: Path,
    config: Callable[[], LocalizerConfig],
    target: Path | None,
    out: TextIO,
    err: TextIO,
    where: str | None = None,
    max_rate_hz: float | None = None,
) -> None:
    """Replay the log beside the view's own work, then show or save the view
    (``where``, if given, says where the view went in the last line; the high-rate
    streams at most ``max_rate_hz`` messages a second; ``None``: the default of
    :mod:`replay.view_topics`).

    The log is opened (and refused if it is not one) before any work. Where the
    system can fork, a child replays it while this process imports rerun and logs
    the streams as it reads them, and the decisions last; elsewhere one process
    does it all, in that order. Each reads the file as it goes.
    """
    from pipemap.replay import REPLAY_TOPICS, StreamSource

    if target is not None:
        _quiet_rerun()
    viewed = StreamSource(log)  # a missing, empty or foreign file: refused here

    def open_log() -> MessageSource:
        return StreamSource(log, REPLAY_TOPICS)

    if not _can_fork():
        from pipemap import api

        done = api.replay(open_log(), config(), progress_printer(err), keep_prepared=False)
        _show(viewed, done, target, max_rate_hz)
    else:
        child = _Child(open_log, config, err)
        try:
            # Imported here while the child replays, not after.
            import rerun  # noqa: F401

            from pipemap.replay import view  # noqa: F401

            _show(viewed, child.result, target, max_rate_hz)
            done = child.result()
        finally:
            child.close()
    report_damage(str(log), viewed.contents, err)
    for warning in done.warnings:
        err.write(f"pipemap: note: {warning}\n")
    if where is None:
        where = "sent to the rerun viewer" if target is None else f"written to {target}"
    out.write(f"viewed {_summary(str(log), done)}, {where}\n")


def view_recorded(
    log: Path, target: Path | None, threshold: float, out: TextIO, err: TextIO
) -> None:
    """Right after ``pipemap record --view``: replay the new log and show or save it."""
    from pipemap.localizer import LocalizerConfig

    _view(log, lambda: LocalizerConfig(threshold=threshold), target, out, err)


def _serve_web(args: argparse.Namespace, target: Path | None, out: TextIO, err: TextIO) -> int:
    """``--web``: save the view (to ``target``, or a temporary file) and serve it in
    rerun's web viewer on the loopback interface until a stop signal ends both."""
    from pipemap.replay.web import serve_web

    with tempfile.TemporaryDirectory(prefix="pipemap-web-") as folder:
        rrd = target if target is not None else Path(folder) / "view.rrd"
        where = "for the web viewer" if target is None else f"written to {target}"
        _view(Path(args.log), lambda: localizer_config(args), rrd, out, err, where, args.max_rate)
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
        _check_display()
    _view(Path(args.log), lambda: localizer_config(args), target, out, err, None, args.max_rate)
    return 0
