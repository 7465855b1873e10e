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
"""

from __future__ import annotations

import contextlib
import enum
import gc
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

from pipemap.errors import LogFormatError
from pipemap.recorder.mcapfile import Lost, McapHeaderError, Scan, scan
from pipemap.recorder.topics import METADATA_RUN, READABLE_VERSIONS, TOPICS

__all__ = [
    "Damage",
    "Integrity",
    "LogChannel",
    "LogContents",
    "LogMessage",
    "gc_paused",
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
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise LogFormatError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise LogFormatError(f"{path}: is a folder, not a log file") from None
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read ({exc.strerror})") from None
    with gc_paused():
        return _read(data, path, keep if keep is not None else (lambda _topic: True))


class _Collector:
    """Counts every message by topic and keeps the ones asked for."""

    def __init__(self, keep: Callable[[str], bool]) -> None:
        self.keep = keep
        self.contents = LogContents(library="")
        self._kept: dict[str, bool] = {}

    def __call__(self, topic: str, sequence: int, log_time: int, data: bytes) -> None:
        c = self.contents
        kept = self._kept.get(topic)
        if kept is None:
            kept = self._kept[topic] = self.keep(topic)
        c.counts[topic] = c.counts.get(topic, 0) + 1
        if c.first_time_ns is None or log_time < c.first_time_ns:
            c.first_time_ns = log_time
        if c.last_time_ns is None or log_time > c.last_time_ns:
            c.last_time_ns = log_time
        if kept:
            c.messages.append(LogMessage(topic, log_time, sequence, data))


def _read(data: bytes, path: Path, keep: Callable[[str], bool]) -> LogContents:
    collector = _Collector(keep)
    try:
        result, tail = scan(data, collector)
    except McapHeaderError as exc:
        raise LogFormatError(f"{path}: {exc}") from None
    contents = collector.contents
    contents.library = result.library
    contents.metadata = dict(result.metadata)
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
        contents.damage.append(Damage(len(data), f"{tail} (no message is lost)"))
    contents.truncated = result.truncated
    problems = [d.describe() for d in contents.damage]
    if result.truncated:
        problems.append(result.truncated)
    contents.problem = "; ".join(problems)
    if contents.damage:
        contents.integrity = Integrity.CORRUPT
    elif result.truncated:
        contents.integrity = Integrity.TRUNCATED
    _recognise(contents, result, path)
    return contents


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
    writer = f"written by {found.library}" if found.library else "written by an unnamed program"
    run = contents.metadata.get(METADATA_RUN)
    if run is None:
        if METADATA_RUN in found.indexed_metadata and contents.damage:
            return  # the summary names it: a pipemap log whose run metadata is lost
        if contents.truncated and not contents.channels:
            raise LogFormatError(
                f"{path}: cut short before its {METADATA_RUN} metadata ({contents.truncated})"
            )
        raise LogFormatError(
            f"{path}: not a pipemap log: no {METADATA_RUN} metadata (an MCAP file {writer})"
        )
    version = run.get("format_version")
    if version not in READABLE_VERSIONS:
        got = "none" if version is None else repr(version)
        readable = " and ".join(repr(v) for v in READABLE_VERSIONS)
        raise LogFormatError(
            f"{path}: log format version {got} in {METADATA_RUN}; this pipemap reads "
            f"versions {readable}"
        )
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
