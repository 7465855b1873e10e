"""A log and its replay in the rerun viewer, or in an ``.rrd`` file (:func:`pipemap.api.view`).

The map and the decisions are the replay's, as :func:`pipemap.api.replay` makes them;
they go to rerun with the log's streams, on the log's simulated time: to a viewer
rerun starts (or one already running), or to a file.

rerun is imported only here (by :mod:`replay.view`), so other commands do not pay
for it. Its import takes 0.25-0.35 s. Where the system can fork, a child process
replays the log, on the other core, while this process imports rerun and then
reads the log's streams and logs them a window at a time; the child's decisions
come last. Each process reads the file as it goes, so neither holds the log (a
100-junction run's is 1.4 million messages). The recording is the same either way.
(Importing rerun in a thread saved nothing: the import holds the GIL.)
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import pickle
import signal
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pipemap.errors import InputError, ViewerError

if TYPE_CHECKING:
    from pipemap.localizer import LocalizerConfig
    from pipemap.recorder import LogContents
    from pipemap.replay import MessageSource, ReplayResult
    from pipemap.replay.view import Replayed

__all__ = ["RRD_SUFFIX", "Viewed", "check_display", "view"]

#: The file suffix rerun gives its recordings; another one is most likely a slip.
RRD_SUFFIX = ".rrd"
_DISPLAY_VARIABLES = ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")
#: The pickle protocol that carries the replay's result.
_PROTOCOL = pickle.HIGHEST_PROTOCOL


@dataclass(frozen=True)
class Viewed:
    """What :func:`view` showed: the replay's result (its map, decisions and
    warnings) and what the log held (``contents.damage``, ``contents.truncated``)."""

    result: ReplayResult
    contents: LogContents


def check_display() -> None:
    """The viewer is a window: on Linux without X11 or Wayland it cannot open (and rerun
    would wait some 20 s to say so)."""
    if not sys.platform.startswith("linux"):
        return
    if not any(os.environ.get(name) for name in _DISPLAY_VARIABLES):
        raise ViewerError(
            "no display for the rerun viewer (DISPLAY and WAYLAND_DISPLAY are unset); "
            "save the recording with --save and open the .rrd with rerun elsewhere"
        )


def _replay(
    log: Path,
    config: LocalizerConfig,
    progress: Callable[[int, int | None], None] | None,
    recorded_threshold: bool,
) -> ReplayResult:
    from pipemap import api

    return api.replay(
        log, config, progress, keep_prepared=False, recorded_threshold=recorded_threshold
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

    def __init__(self, replay: Callable[[], ReplayResult]) -> None:
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        read_end, write_end = os.pipe()
        self._pid = os.fork()
        if self._pid == 0:
            os.close(read_end)
            self._run(replay, write_end)  # never returns
        os.close(write_end)
        self._pipe = os.fdopen(read_end, "rb")
        self._done = False
        self._answered = False
        self._result: ReplayResult | None = None

    @staticmethod
    def _run(replay: Callable[[], ReplayResult], write_end: int) -> None:
        status = 1
        try:
            with os.fdopen(write_end, "wb") as pipe:
                try:
                    # The view needs the decisions, not the visits' image sets (not
                    # kept) or the localizer's database of junctions.
                    payload: Any = dataclasses.replace(replay(), localizer=None)
                    status = 0
                except BaseException as exc:  # noqa: BLE001  (the parent reports it)
                    payload = exc
                pickle.dump(payload, pipe, protocol=_PROTOCOL)
            sys.stderr.flush()
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


def view(
    log: str | Path,
    config: LocalizerConfig | None = None,
    save: str | Path | None = None,
    max_rate_hz: float | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    recorded_threshold: bool | None = None,
) -> Viewed:
    """Replay ``log`` and show it with its streams in a rerun viewer, or save the
    recording to ``save`` (an ``.rrd`` file, replaced if it exists).

    ``config`` is the replay's localizer (pipemap's defaults if ``None``); the
    high-rate streams (ranges, IMU, wheels) reach the view at most ``max_rate_hz``
    messages a second (``None``: :data:`replay.view_topics.DEFAULT_MAX_RATE_HZ`),
    the log keeps them all; ``progress`` and ``recorded_threshold`` as
    :func:`pipemap.api.replay` takes them.

    The log is opened (and refused if it is not one) before any work. Where the
    system can fork, a child replays it while this process imports rerun and logs
    the streams as it reads them, and the decisions last; elsewhere one process
    does it all, in that order.
    """
    from pipemap.localizer import LocalizerConfig
    from pipemap.replay import StreamSource, takes_recorded_threshold

    target = None if save is None else Path(save)
    if target is not None and target.suffix != RRD_SUFFIX:
        raise InputError(f"{target}: a rerun recording is saved as a {RRD_SUFFIX} file")
    if target is None:
        check_display()
    else:
        _quiet_rerun()
    path = Path(log)
    viewed = StreamSource(path)  # a missing, empty or foreign file: refused here
    recorded = takes_recorded_threshold(recorded_threshold, config)
    settings = LocalizerConfig() if config is None else config

    def replay() -> ReplayResult:
        return _replay(path, settings, progress, recorded)

    if not _can_fork():
        done = replay()
        _show(viewed, done, target, max_rate_hz)
    else:
        child = _Child(replay)
        try:
            # Imported here while the child replays, not after.
            import rerun  # noqa: F401

            from pipemap.replay import view as _view_module  # noqa: F401

            _show(viewed, child.result, target, max_rate_hz)
            done = child.result()
        finally:
            child.close()
    return Viewed(done, viewed.contents)
