"""The log is written by a second process, so that writing costs the run little.

Turning some 80 000 sensor readings and 80 images of a run into protobuf, PNG and
zstd chunks took about as long as a third of the simulation itself, on the same
core. Here the run sends its records in batches through a pipe to a writer process
(on the machine's other core) that converts and writes them. The bytes are the same:
one writer, records in the run's order.

Whatever ends the run, the log is closed with everything sent: the parent sends
``finish`` with the result metadata (also after Ctrl-C), and if the parent dies the
writer sees the pipe close and finishes the file itself. The writer runs in a session
of its own, so that the terminal's Ctrl-C and hang-up reach the parent alone (and it
ignores them, should one be sent to it): closing the log is the parent's call.
"""

from __future__ import annotations

import contextlib
import io
import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading
import traceback
from collections.abc import Mapping
from pathlib import Path
from typing import Any, BinaryIO, cast

from pipemap.errors import InputError, WriteError
from pipemap.recorder.convert import LogRecord, RecordConverter
from pipemap.recorder.inline import FinishesOnExit
from pipemap.recorder.messages import ImageEncoding
from pipemap.recorder.writer import LogWriter
from pipemap.wholefile import write_whole

__all__ = ["BackgroundWriter", "writer_main"]

#: Records per batch sent to the writer (a sweep's end also sends the batch).
_BATCH = 2048
_LENGTH = struct.Struct("<Q")


def _send(stream: BinaryIO, item: object) -> None:
    data = pickle.dumps(item, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_LENGTH.pack(len(data)) + data)
    stream.flush()


def _receive_frame(stream: BinaryIO) -> bytes:
    head = stream.read(_LENGTH.size)
    if len(head) < _LENGTH.size:
        raise EOFError
    (length,) = _LENGTH.unpack(head)
    data = stream.read(length)
    if len(data) < length:
        raise EOFError
    return data


def _receive(stream: BinaryIO) -> Any:
    return pickle.loads(_receive_frame(stream))


def _drain(stream: BinaryIO, frames: queue.SimpleQueue[bytes | None]) -> None:
    """Read frames as fast as they come, so that the run never waits on a full pipe
    while the writer encodes; ``None`` marks the end of the stream."""
    try:
        while True:
            frames.put(_receive_frame(stream))
    except Exception:  # noqa: BLE001
        # The pipe ended or broke. Reading may also fail when this process closes the
        # stream while exiting (seen once under load, after a Ctrl-C): either way the
        # stream is over, and the writer finishes the log with what it has.
        frames.put(None)


def _reply(replies: BinaryIO, item: object) -> None:
    """Answer the recording process; if it is gone (killed), there is no one to tell."""
    with contextlib.suppress(OSError):
        _send(replies, item)


def writer_main(records: BinaryIO, replies: BinaryIO, path: str, mode: str) -> int:
    """The writer process: open the log, write every batch received, finish.

    A write that fails (a full disk, the file size limit) is answered as one line of
    text, not a traceback: what was written before it stays in the file, cut short.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if hasattr(signal, "SIGXFSZ"):  # past the file size limit: an error, not a kill
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    run_metadata = _receive(records)
    try:
        # Opened over the placeholder log (BackgroundWriter), not emptied: the log's
        # first bytes are the placeholder's own, so the file reads at every moment.
        in_place = os.path.isfile(path)  # else a device: written as it is
        output = cast(BinaryIO, open(path, "r+b" if in_place else mode))  # noqa: SIM115
    except OSError as exc:
        _reply(replies, ("error", f"{path}: {exc.strerror}"))
        return 1
    try:
        return _write(output, records, replies, run_metadata, in_place)
    except OSError as exc:
        _reply(replies, ("failed", f"writing {path} failed: {exc.strerror or exc}"))
        return 1
    finally:
        with contextlib.suppress(OSError):  # the buffer cannot be flushed to a full disk
            output.close()


def _write(
    output: BinaryIO,
    records: BinaryIO,
    replies: BinaryIO,
    run_metadata: dict[str, str],
    in_place: bool,
) -> int:
    writer = LogWriter(output, run_metadata)
    # The header and pipemap.run, the same bytes as the placeholder's: from here the
    # file is this log, cut short where it has got to (pipemap info and replay read it).
    output.flush()
    if in_place:
        output.truncate()
    convert = RecordConverter(writer, encoding=ImageEncoding.of_run(run_metadata))
    _reply(replies, ("ready", None))
    result: dict[str, str] | None = {"status": "lost its run: the recording process ended"}
    frames: queue.SimpleQueue[bytes | None] = queue.SimpleQueue()
    threading.Thread(target=_drain, args=(records, frames), daemon=True).start()
    try:
        while True:
            frame = frames.get()
            if frame is None:
                break
            item = pickle.loads(frame)
            if isinstance(item, tuple):
                result = item[1]
                break
            for record in item:
                convert(record)
    except OSError:
        raise  # the file cannot be written: nothing more can be put in it
    except BaseException as exc:
        writer.finish({"status": "failed", "error": f"{type(exc).__name__}: {exc}"[:500]})
        _reply(replies, ("error", traceback.format_exc()))
        return 1
    writer.finish(result)
    if in_place:
        output.truncate()
    _reply(replies, ("done", writer.messages))
    return 0


#: The result a log says until its writer has written its own: the writer never started.
PLACEHOLDER_STATUS = "lost its run: the log writer ended before it wrote anything"


def _write_placeholder(path: Path, mode: str, run_metadata: Mapping[str, str]) -> None:
    """Put a whole log of no messages at ``path`` before the writer starts, so that
    from the start of a recording the named log exists and reads (a writer killed
    before its first bytes leaves this). It starts with the very bytes the writer
    writes first (the header and ``pipemap.run``), which the writer writes over it."""
    if path.exists() and not path.is_file():
        return  # a device or a FIFO (/dev/null): written as it is, nothing put in its place
    placeholder = io.BytesIO()
    LogWriter(placeholder, run_metadata).finish({"status": PLACEHOLDER_STATUS})
    try:
        write_whole(path, placeholder.getvalue(), replace=mode != "xb")
    except FileExistsError:
        raise InputError(f"{path}: exists; refusing to overwrite without --force") from None
    except WriteError as exc:
        raise WriteError(f"{exc}; no log was written") from None


class BackgroundWriter(FinishesOnExit):
    """Writes a log at ``path`` in a writer process. Use as a context manager.

    ``mode`` is ``"xb"`` (never overwrite) or ``"wb"``. On leaving the block by an
    exception the log is finished with that exception as its result.
    """

    def __init__(self, path: Path, mode: str, run_metadata: Mapping[str, str]) -> None:
        _write_placeholder(path, mode, run_metadata)
        # Two pipes of our own: the child's stdout stays free for whatever its imports print.
        records_read, records_write = os.pipe()
        replies_read, replies_write = os.pipe()
        self._path = path
        self._process = subprocess.Popen(
            [
                sys.executable,
                # -P: the working folder stays off the module path, so that a run
                # started from a checkout imports the installed pipemap, not the
                # checkout's own pipemap/ folder (which lacks the layer packages).
                "-P",
                "-m",
                "pipemap.recorder.writer_process",
                str(records_read),
                str(replies_write),
                str(path),
                mode,
            ],
            pass_fds=(records_read, replies_write),
            stdin=subprocess.DEVNULL,
            # A session of its own: the terminal's Ctrl-C and hang-up, and a signal
            # sent to the command's process group, reach the recording process alone,
            # even while the writer is still starting (before it could ignore them).
            # Ending the log is the recording process's call; if that process dies,
            # the writer sees its pipe close and finishes the file itself.
            start_new_session=True,
        )
        os.close(records_read)
        os.close(replies_write)
        self._records = os.fdopen(records_write, "wb")
        self._replies = os.fdopen(replies_read, "rb")
        try:
            _send(self._records, dict(run_metadata))
        except OSError:  # a broken pipe: the writer ended before it read the settings
            raise self._gone() from None
        self._batch: list[LogRecord] = []
        self._ready = False
        self._finished = False
        self.messages = 0

    def _wait_ready(self) -> None:
        if self._ready:
            return
        kind, detail = self._receive()
        if kind != "ready":
            self._close()
            raise InputError(f"cannot write the log: {detail}")
        self._ready = True

    def _crashed(self, why: str) -> WriteError:
        self._close()
        return WriteError(
            f"{why}; {self._path} holds what was written before, cut short "
            "(pipemap info and replay read it; a log of no messages if the writer "
            "had written nothing)"
        )

    def _receive(self) -> tuple[str, Any]:
        try:
            kind, detail = _receive(self._replies)
        except (EOFError, OSError):
            raise self._gone() from None
        if kind == "failed":
            raise self._crashed(str(detail))
        return str(kind), detail

    def _gone(self) -> WriteError:
        """The error of a writer process that ended unasked (killed, or died)."""
        code = self._process.wait()
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            return self._crashed(f"the log writer process was killed ({name})")
        return self._crashed(f"the log writer process died (exit status {code})")

    def _close(self) -> None:
        for stream in (self._records, self._replies):
            with contextlib.suppress(OSError):  # a broken pipe: the writer is gone already
                stream.close()
        self._process.wait()

    def put(self, record: LogRecord) -> None:
        """Queue a record; full batches go to the writer."""
        self._batch.append(record)
        if len(self._batch) >= _BATCH:
            self.send()

    def send(self) -> None:
        """Hand every queued record to the writer."""
        self._wait_ready()
        if self._batch:
            try:
                _send(self._records, self._batch)
            except BrokenPipeError:
                kind, detail = self._receive()  # raises WriteError if it died or failed
                raise RuntimeError(f"the log writer stopped ({kind}):\n{detail}") from None
            self._batch = []

    def finish(self, result_metadata: Mapping[str, str]) -> int:
        """Send the rest and the result; wait until the file is closed. Returns the
        number of messages written."""
        if self._finished:
            return self.messages
        self._finished = True
        self.send()
        with contextlib.suppress(BrokenPipeError):  # the writer is gone: the reply says why
            _send(self._records, ("finish", dict(result_metadata)))
        kind, detail = self._receive()
        self._close()
        if kind != "done":
            raise RuntimeError(f"the log writer failed:\n{detail}")
        self.messages = int(detail)
        return self.messages
