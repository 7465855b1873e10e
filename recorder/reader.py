"""Reading a log back: its messages, channels and metadata, and what was lost.

A pipemap log is recognised by its content, not by the program that wrote it: the
``pipemap.run`` metadata record and, for every channel on one of pipemap's topics,
the protobuf schema that topic carries (``docs/log_format.md`` states the
contract). So a log filtered, merged, recovered or re-compressed by any MCAP tool
stays a pipemap log.

The file is walked by :mod:`recorder.mcapfile`, which loses only what is damaged.
A log is then in one of three states:

* ``ok``: every record parses, every CRC matches, the footer and magic close it;
* ``truncated``: the file stops before its end (a hard kill, a full disk);
  everything up to the last complete record is kept;
* ``corrupt``: a chunk, a record, the summary or the magic is damaged; every
  intact chunk is kept, and :attr:`LogContents.damage` says what each damaged
  one held.

A file that is not MCAP, is empty, or is not a pipemap log raises
:class:`pipemap.errors.LogFormatError`.

:func:`read_log` holds every message it keeps; :func:`iter_log` hands them out one
at a time as the file is read, holding about one chunk of it, for a log too long to
hold. Both read the file the same way, a piece at a time, never whole.
"""

from __future__ import annotations

import contextlib
import enum
import gc
import itertools
import stat
import weakref
from collections import Counter
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import BinaryIO, NamedTuple

from pipemap.errors import LogFormatError
from pipemap.recorder.mcapfile import FileBytes, Lost, McapHeaderError, Message, Scan, Walk
from pipemap.recorder.runs import indexed_runs, several_runs
from pipemap.recorder.topics import METADATA_RUN, READABLE_VERSIONS, TOPICS

__all__ = [
    "Damage",
    "Integrity",
    "LogChannel",
    "LogContents",
    "LogMessage",
    "LogStream",
    "gc_paused",
    "iter_log",
    "read_log",
]

#: The message type each of pipemap's topics carries.
_TYPE_OF_TOPIC = {topic: message_class.DESCRIPTOR.full_name for topic, message_class in TOPICS}
_NS_PER_S = 1e9


class Integrity(enum.Enum):
    """Whether a log was read whole."""

    OK = "ok"
    TRUNCATED = "truncated"
    CORRUPT = "corrupt"


@dataclass(frozen=True)
class LogChannel:
    """A channel of the log: its topic and the name of its message schema."""

    channel_id: int
    topic: str
    schema_name: str


class LogMessage(NamedTuple):
    """One message, still encoded: decode ``data`` with the topic's message class.

    A named tuple, not a frozen dataclass: a log holds some 84 000 of these, and a
    tuple is made five times faster.
    """

    topic: str
    log_time_ns: int
    sequence: int
    data: bytes


@dataclass(frozen=True)
class Damage:
    """A damaged part of a log: where, what is wrong, and what it held, where known."""

    offset: int
    problem: str
    #: The damaged chunk's number and how many the file has, when known.
    chunk: int | None = None
    chunks: int | None = None
    start_ns: int | None = None
    end_ns: int | None = None
    #: Messages lost, per topic (from the chunk's message indexes), when known.
    lost: dict[str, int] = field(default_factory=dict)

    @property
    def where(self) -> str:
        """``chunk 2 of 14 (byte 123)``, or ``byte 123``."""
        if self.chunk is None:
            return f"byte {self.offset}"
        of = f" of {self.chunks}" if self.chunks is not None else ""
        return f"chunk {self.chunk}{of} (byte {self.offset})"

    def describe(self) -> str:
        """One line: where, the problem, and what it held."""
        text = f"{self.where}: {self.problem}"
        held = []
        if self.start_ns is not None and self.end_ns is not None:
            held.append(f"{self.start_ns / _NS_PER_S:.3f}-{self.end_ns / _NS_PER_S:.3f} s")
        if self.lost:
            held.append(", ".join(f"{topic} {count}" for topic, count in sorted(self.lost.items())))
        return f"{text}; held {': '.join(held)}" if held else text


@dataclass
class LogContents:
    """What a log holds, as far as it could be read."""

    library: str
    channels: dict[int, LogChannel] = field(default_factory=dict)
    messages: list[LogMessage] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    integrity: Integrity = Integrity.OK
    #: Where and what the problem is, when ``integrity`` is not ``ok``.
    problem: str = ""
    #: Every damaged part, in file order (empty unless ``corrupt``).
    damage: list[Damage] = field(default_factory=list)
    #: How the file stops early ("" unless it does).
    truncated: str = ""
    first_time_ns: int | None = None
    last_time_ns: int | None = None
    #: What a file of several runs holds, and how to part them ("" for one run): a
    #: replay, a score and a view refuse such a file; ``info`` describes it.
    several_runs: str = ""

    @property
    def duration_ns(self) -> int:
        """Time from the first message to the last (0 with none)."""
        if self.first_time_ns is None or self.last_time_ns is None:
            return 0
        return self.last_time_ns - self.first_time_ns


@contextlib.contextmanager
def gc_paused() -> Iterator[None]:
    """Pause Python's cyclic garbage collector for a bulk read. A log holds tens of
    thousands of small messages with no reference cycles among them, and the
    collector's passes over them took a quarter of the reading time."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def read_log(path: Path | str, keep: Callable[[str], bool] | None = None) -> LogContents:
    """Read the log at ``path``; keep the messages of the topics ``keep`` accepts
    (default: all). Counts, times and metadata cover every topic."""
    with gc_paused(), LogStream(path, keep) as stream:
        messages = stream.contents.messages
        for kept in stream._read(check_first=False):
            messages.extend(kept)
    return stream.contents


def iter_log(path: Path | str, keep: Callable[[str], bool] | None = None) -> LogStream:
    """The log at ``path`` read as a stream: its messages of the topics ``keep``
    accepts (default: all), one at a time in file order, holding about one chunk of
    the file at a time. See :class:`LogStream`."""
    return LogStream(path, keep)


class LogStream:
    """A log read one message at a time, in file order, as the file is read from disk.

    Iterate it (once) for the :class:`LogMessage` of the kept topics. A file that is
    missing, not MCAP or cut short inside its header raises
    :class:`~pipemap.errors.LogFormatError` as the stream is made, with the message
    :func:`read_log` gives. One that is not a pipemap log, or of a format version
    this pipemap does not read, raises it before the first message is handed out,
    from the metadata and channels read so far (pipemap writes its run metadata
    before the first chunk; a file whose run metadata comes only after its first
    message, unnamed by a summary, is refused here where :func:`read_log` would
    take it). A log whose run metadata the summary names but which is not read
    before the first message (damaged, or further on), or a channel that turns out
    wrong further on, is judged at the end, as :func:`read_log` judges it.

    :attr:`contents` fills in as the file is read: the run metadata is in it before
    the first message is handed out, where it comes before the file's first chunk,
    as pipemap writes it. Once the stream is exhausted, counts, times, channels,
    metadata and damage are those :func:`read_log` gives; its ``messages`` stay
    empty. The file is closed when the stream is exhausted or :meth:`close` is
    called (also as a context manager's exit), or when a loop over it is left early
    and its iterator is let go.
    """

    def __init__(self, path: Path | str, keep: Callable[[str], bool] | None = None) -> None:
        self.path = Path(path)
        self._keep = keep if keep is not None else _keep_all
        self._file = _open(self.path)
        try:
            self._data = FileBytes(self._file)
            self._walk = Walk(self._data)
        except McapHeaderError as exc:
            self._file.close()
            raise LogFormatError(f"{self.path}: {exc}") from None
        except OSError as exc:
            self._file.close()
            raise _unreadable(self.path, exc) from None
        except BaseException:
            self._file.close()
            raise
        #: What the log holds, as far as it has been read.
        self.contents = LogContents(library=self._walk.scan.library)
        # The summary tells it before the walk does.
        self.contents.several_runs = indexed_runs(self._walk.scan.indexed_metadata)
        self._kept: dict[str, bool] = {}
        # Weakly: the reading refers to this stream, and a loop left early must free
        # it (and so close the file) without waiting for the cycle collector.
        self._reading: weakref.ref[Generator[list[LogMessage], None, None]] | None = None
        # The chunk's messages being handed out, emptied on close so that a loop over
        # the stream stops at once, not at the end of the chunk already read.
        self._handing: list[LogMessage] = []

    def __iter__(self) -> Iterator[LogMessage]:
        return itertools.chain.from_iterable(self._read(check_first=True))

    def __enter__(self) -> LogStream:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """Whether the file is closed: at the end of the log, or by :meth:`close`."""
        return bool(self._file.closed)

    def close(self) -> None:
        """Stop reading and close the file (done on its own at the end of the log)."""
        self._handing.clear()
        reading = self._reading() if self._reading is not None else None
        if reading is not None:
            reading.close()
        self._file.close()

    def _read(self, check_first: bool) -> Iterator[list[LogMessage]]:
        """The kept messages, a chunk at a time. ``check_first``: refuse a file that
        is not a pipemap log before handing out its first message, not at its end."""
        if self._reading is not None or self._file.closed:
            raise RuntimeError(f"{self.path}: a log stream is read once, and not once closed")
        reading = self._chunks(check_first)
        self._reading = weakref.ref(reading)
        return reading

    def _chunks(self, check_first: bool) -> Generator[list[LogMessage], None, None]:
        batches = self._walk.chunks()
        try:
            while True:
                # The collector is paused while a chunk is read, as for a whole log in
                # read_log, but not while the caller works on the messages handed out.
                with gc_paused():
                    try:
                        batch = next(batches, None)
                    except OSError as exc:
                        raise _unreadable(self.path, exc) from None
                    if batch is None:
                        break
                    kept = self._tally(batch)
                self._sync_metadata()
                if check_first:
                    self._check_first()
                    check_first = False
                if kept:
                    self._handing = kept
                    yield kept
            self._finish()
        finally:
            self._file.close()

    def _tally(self, batch: list[Message]) -> list[LogMessage]:
        """Count a chunk's messages by topic, widen the time range by theirs, and
        return those kept. A chunk at a time: the work per message is done by
        builtins, not by a call per message."""
        c = self.contents
        kept_of, any_kept = self._kept, False
        for topic, count in Counter([m[0] for m in batch]).items():
            c.counts[topic] = c.counts.get(topic, 0) + count
            kept = kept_of.get(topic)
            if kept is None:
                kept = kept_of[topic] = self._keep(topic)
            any_kept = any_kept or kept
        times = [m[2] for m in batch]
        low, high = min(times), max(times)
        if c.first_time_ns is None or low < c.first_time_ns:
            c.first_time_ns = low
        if c.last_time_ns is None or high > c.last_time_ns:
            c.last_time_ns = high
        if not any_kept:
            return []
        return [LogMessage(t, ns, sequence, data) for t, sequence, ns, data in batch if kept_of[t]]

    def _sync_metadata(self) -> None:
        # A metadata record is read once and never changes: only new names are added.
        found = self._walk.scan.metadata
        if len(found) != len(self.contents.metadata):
            self.contents.metadata.update(found)

    def _check_first(self) -> None:
        """Before the first message is handed out: refuse a file that is not a
        pipemap log, or not of a version this pipemap reads, as :func:`read_log`
        would at its end."""
        found = self._walk.scan
        run = self.contents.metadata.get(METADATA_RUN)
        if run is None:
            if METADATA_RUN in found.indexed_metadata:
                return  # the summary names it: further on, or damaged; decided at the end
            raise LogFormatError(_not_pipemap(self.path, found))
        _check_version(run, self.path)
        _check_channels(found, self.path)

    def _finish(self) -> None:
        """What the walk found, once it is over: channels, damage and integrity."""
        walk, contents = self._walk, self.contents
        result, tail = walk.scan, walk.tail
        contents.library = result.library
        contents.metadata.update(result.metadata)
        for channel_id, (topic, schema_id, _encoding) in sorted(result.channels.items()):
            schema = result.schemas.get(schema_id, ("", ""))[0]
            contents.channels[channel_id] = LogChannel(channel_id, topic, schema)
            contents.counts.setdefault(topic, 0)
        contents.damage = [_damage(lost, result) for lost in result.lost]
        if result.unknown_channel_messages:
            contents.damage.append(
                Damage(
                    0,
                    f"{result.unknown_channel_messages} message(s) on channels whose channel "
                    "record was lost",
                )
            )
        if tail:
            contents.damage.append(Damage(len(self._data), f"{tail} (no message is lost)"))
        damage, several = several_runs(contents.metadata, result, len(self._data))
        contents.damage += [Damage(at, problem) for at, problem in damage]
        contents.several_runs = several or contents.several_runs
        contents.truncated = result.truncated
        problems = [d.describe() for d in contents.damage]
        if result.truncated:
            problems.append(result.truncated)
        contents.problem = "; ".join(problems)
        if contents.damage:
            contents.integrity = Integrity.CORRUPT
        elif result.truncated:
            contents.integrity = Integrity.TRUNCATED
        _recognise(contents, result, self.path)


def _keep_all(_topic: str) -> bool:
    return True


def _open(path: Path) -> BinaryIO:
    # Looked at before it is opened: opening a FIFO blocks until a writer comes, and
    # a pipe or a device has no length to read a log's summary from.
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise LogFormatError(f"{path}: no such file") from None
    except OSError as exc:
        raise _unreadable(path, exc) from None
    if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):
        kind = (
            "a pipe" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "a device"
        )
        raise LogFormatError(
            f"{path}: is {kind}, not a log file; pipemap reads a log from a file "
            "(save the stream to a file first)"
        )
    try:
        return path.open("rb", buffering=0)
    except FileNotFoundError:
        raise LogFormatError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise LogFormatError(f"{path}: is a folder, not a log file") from None
    except OSError as exc:
        raise _unreadable(path, exc) from None


def _unreadable(path: Path, exc: OSError) -> LogFormatError:
    return LogFormatError(f"{path}: cannot read ({exc.strerror})")


def _damage(lost: Lost, found: Scan) -> Damage:
    topics: dict[str, int] = {}
    for channel_id, count in lost.counts.items():
        topic = found.channels.get(channel_id, (f"channel {channel_id}", 0, ""))[0]
        topics[topic] = topics.get(topic, 0) + count
    return Damage(
        lost.offset,
        lost.problem,
        lost.chunk,
        found.chunk_count if lost.chunk is not None else None,
        lost.start_ns,
        lost.end_ns,
        topics,
    )


def _recognise(contents: LogContents, found: Scan, path: Path) -> None:
    """Refuse a file that is not a pipemap log by its content (docs/log_format.md)."""
    run = contents.metadata.get(METADATA_RUN)
    if run is None:
        if METADATA_RUN in found.indexed_metadata and contents.damage:
            return  # the summary names it: a pipemap log whose run metadata is lost
        if contents.truncated and not contents.channels:
            raise LogFormatError(
                f"{path}: cut short before its {METADATA_RUN} metadata ({contents.truncated})"
            )
        raise LogFormatError(_not_pipemap(path, found))
    _check_version(run, path)
    _check_channels(found, path)


def _not_pipemap(path: Path, found: Scan) -> str:
    writer = f"written by {found.library}" if found.library else "written by an unnamed program"
    return f"{path}: not a pipemap log: no {METADATA_RUN} metadata (an MCAP file {writer})"


def _check_version(run: dict[str, str], path: Path) -> None:
    version = run.get("format_version")
    if version not in READABLE_VERSIONS:
        got = "none" if version is None else repr(version)
        readable = " and ".join(repr(v) for v in READABLE_VERSIONS)
        raise LogFormatError(
            f"{path}: log format version {got} in {METADATA_RUN}; this pipemap reads "
            f"versions {readable}"
        )


def _check_channels(found: Scan, path: Path) -> None:
    for channel_id, (topic, schema_id, encoding) in found.channels.items():
        expected = _TYPE_OF_TOPIC.get(topic)
        if expected is None:
            continue  # a topic pipemap does not read: allowed, and ignored
        schema_name, schema_encoding = found.schemas.get(schema_id, ("", ""))
        if encoding != "protobuf" or schema_encoding != "protobuf" or schema_name != expected:
            got = f"{encoding or 'no'} messages, schema {schema_name or 'none'!s}"
            if schema_encoding and schema_encoding != "protobuf":
                got += f" ({schema_encoding})"
            raise LogFormatError(
                f"{path}: channel {channel_id} ({topic}) has {got}; pipemap's log format "
                f"has protobuf {expected} there"
            )
