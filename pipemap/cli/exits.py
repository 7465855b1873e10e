"""How every command ends: stop signals, and a standard output that may fail.

Stop signals: SIGINT (Ctrl-C), SIGTERM (``kill``, a scheduler) and SIGHUP (the
terminal closed) all stop a command the same way, as :class:`pipemap.errors.Interrupted`
raised in the main thread: every ``finally`` and ``with`` runs (a log is closed,
temporary files go), one line is printed, and the exit status is 128 + the signal's
number, as the shell shows for a process the signal killed (130, 143, 129). The first
signal stops the command; later ones are ignored while it cleans up.

Standard output: commands write to a guarded stream. When the reader of a pipe has
gone (``| head -c1``) the command ends quietly with status 141 (128 + SIGPIPE), as
coreutils' tools do when SIGPIPE ends them; any other failure to write it (a full
disk, ``> /dev/full``) is a :class:`pipemap.errors.WriteError`, exit status 3. The
stream is flushed before the command's status is returned, so that the failure is
caught here and not by the interpreter on its way out, where it is a traceback.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from typing import Any, TextIO

from pipemap.errors import Interrupted, WriteError
from pipemap.stops import stopping_on

__all__ = [
    "PIPE_CLOSED",
    "STOP_SIGNALS",
    "OutputClosed",
    "StandardOutputError",
    "flush_standard_output",
    "guarded_standard_output",
    "stop_signals",
    "stopped_status",
]

#: Exit status when the reader of standard output went away (128 + SIGPIPE).
PIPE_CLOSED = 128 + signal.SIGPIPE

#: The signals that stop a command as Ctrl-C does.
STOP_SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class OutputClosed(Exception):
    """The reader of standard output has gone: nothing more can be said there."""


class StandardOutputError(WriteError):
    """Standard output cannot be written (a full disk, ``/dev/full``)."""


def stopped_status(exc: KeyboardInterrupt) -> tuple[int, str]:
    """The exit status and the signal's name for a stop (plain Ctrl-C: SIGINT)."""
    signum = exc.signum if isinstance(exc, Interrupted) else int(signal.SIGINT)
    return 128 + signum, signal.Signals(signum).name


@contextlib.contextmanager
def stop_signals() -> Iterator[None]:
    """Within the block, the first stop signal raises :class:`Interrupted` and later
    ones are ignored (:func:`pipemap.stops.stopping_on`); a write past the file size
    limit (``ulimit -f``) fails as on a full disk (one line, exit 3) instead of
    SIGXFSZ killing the process."""
    size_limit = getattr(signal, "SIGXFSZ", None)
    before = signal.getsignal(size_limit) if size_limit is not None else None
    main = threading.current_thread() is threading.main_thread()
    if size_limit is not None and main:
        signal.signal(size_limit, signal.SIG_IGN)
    try:
        with stopping_on(STOP_SIGNALS):
            yield
    finally:
        if size_limit is not None and main:
            signal.signal(size_limit, before if before is not None else signal.SIG_DFL)


class _GuardedOutput:
    """A text stream whose write failures are named: :class:`OutputClosed` for a
    closed pipe, :class:`WriteError` for anything else."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream

    def _failed(self, exc: OSError) -> Exception:
        if isinstance(exc, BrokenPipeError):
            return OutputClosed()
        return StandardOutputError(f"standard output: cannot write ({exc.strerror or exc})")

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except OSError as exc:
            raise self._failed(exc) from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as exc:
            raise self._failed(exc) from None

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def _silence_stdout(stream: TextIO) -> None:
    """Point standard output's descriptor at /dev/null, so that the interpreter's own
    last flush of what is still buffered cannot fail again on its way out."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, stream.fileno())
        os.close(null)


@contextlib.contextmanager
def guarded_standard_output() -> Iterator[None]:
    """``sys.stdout`` guarded within the block; a failure to write it leaves the
    descriptor pointing at /dev/null (what was not written is lost either way)."""
    original = sys.stdout
    sys.stdout = _GuardedOutput(original)  # type: ignore[assignment,unused-ignore]
    try:
        yield
    except (OutputClosed, StandardOutputError):
        _silence_stdout(original)
        raise
    finally:
        sys.stdout = original


def flush_standard_output() -> None:
    """Flush ``sys.stdout`` (guarded within :func:`guarded_standard_output`)."""
    stream = sys.stdout
    if stream is not None:
        stream.flush()
