"""The log written in the recording process itself: for runs that share the cores.

:class:`~recorder.background.BackgroundWriter` hands the conversion and compression to
a second process, which shortens a run that has the machine to itself: the two
processes use more than one core between them. In a batch every core already runs a
recording, so that second process only competes for them, and it costs a Python
start-up and a pickled copy of every record besides. :class:`InlineWriter` has the
same surface and writes the same bytes (one writer, the records in the run's order),
converting each record as it comes.

Whatever ends the run, the log is closed with everything put in it; a write that
fails (a full disk) raises :class:`~errors.WriteError` naming the file, which keeps
what was written before it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import BinaryIO, Protocol, Self, cast

from pipemap.errors import InputError, WriteError
from pipemap.recorder.convert import LogRecord, RecordConverter
from pipemap.recorder.messages import ImageEncoding
from pipemap.recorder.writer import LogWriter

__all__ = ["FinishesOnExit", "InlineWriter", "NoLog", "RecordWriter"]


class RecordWriter(Protocol):
    """What a recording hands its records to: a writer process or this process."""

    messages: int

    def put(self, record: LogRecord) -> None:
        """Take a record for the log."""

    def send(self) -> None:
        """Pass on every record taken so far (the end of a sweep, the start of a run)."""

    def finish(self, result_metadata: Mapping[str, str]) -> int:
        """Write the result metadata and close the log; the number of messages."""


class FinishesOnExit:
    """A record writer as a context manager: leaving the block finishes the log, by an
    exception (Ctrl-C included) with that exception as its result."""

    _finished: bool

    def finish(self, result_metadata: Mapping[str, str]) -> int:
        """Write the result metadata and close the log; the number of messages."""
        raise NotImplementedError

    def _close(self) -> None:
        """Let go of the log when it cannot be finished."""
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._finished:
            return
        if exc_type is None:
            self.finish({"status": "finished"})
            return
        reason = "interrupted" if issubclass(exc_type, KeyboardInterrupt) else "failed"
        try:
            self.finish({"status": reason, "error": f"{exc_type.__name__}: {exc}"[:500]})
        except Exception:
            # It cannot be finished (the writer is gone, the disk full): the exception
            # that ended the run is the one to report.
            self._close()


class InlineWriter(FinishesOnExit):
    """Writes a log at ``path`` in this process. Use as a context manager.

    ``mode`` is ``"xb"`` (never overwrite) or ``"wb"``. On leaving the block by an
    exception the log is finished with that exception as its result.
    """

    def __init__(self, path: Path, mode: str, run_metadata: Mapping[str, str]) -> None:
        self._path = path
        try:
            self._output = cast(BinaryIO, open(path, mode))  # noqa: SIM115 - closed in finish
        except OSError as exc:
            raise InputError(f"cannot write the log: {path}: {exc.strerror}") from None
        try:
            self._writer = LogWriter(self._output, dict(run_metadata))
        except OSError as exc:
            raise self._failed(exc) from None
        self._convert = RecordConverter(self._writer, encoding=ImageEncoding.of_run(run_metadata))
        self._finished = False
        self.messages = 0

    def _failed(self, exc: OSError) -> WriteError:
        self._finished = True
        with contextlib.suppress(OSError):  # the buffer cannot be flushed to a full disk
            self._output.close()
        return WriteError(
            f"writing {self._path} failed: {exc.strerror or exc}; {self._path} holds what "
            "was written before, cut short (pipemap info and replay read it)"
        )

    def put(self, record: LogRecord) -> None:
        """Convert ``record`` into the log's messages and write them."""
        try:
            self._convert(record)
        except OSError as exc:
            raise self._failed(exc) from None

    def send(self) -> None:
        """Nothing to pass on: every record is written as it is put."""

    def finish(self, result_metadata: Mapping[str, str]) -> int:
        """Write the result metadata, the summary and the footer; close the file.
        Returns the number of messages written."""
        if self._finished:
            return self.messages
        try:
            self._writer.finish(dict(result_metadata))
            self._output.close()
        except OSError as exc:
            raise self._failed(exc) from None
        self._finished = True
        self.messages = self._writer.messages
        return self.messages

    def _close(self) -> None:
        with contextlib.suppress(OSError):
            self._output.close()


class NoLog(FinishesOnExit):
    """A run without a log: every record is taken and dropped. ``pipemap sim`` runs the
    episode a recording runs, through this, and keeps the sweeps its observer saw."""

    def __init__(self) -> None:
        self._finished = True  # nothing to finish, whatever ends the run
        self.messages = 0

    def put(self, record: LogRecord) -> None:
        """Drop ``record``."""

    def send(self) -> None:
        """Nothing to pass on."""

    def finish(self, result_metadata: Mapping[str, str]) -> int:
        """Nothing to close: no message was written."""
        return 0

    def _close(self) -> None:
        """Nothing to let go of."""
