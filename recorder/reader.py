"""Reading a log back: its messages, channels and metadata, and whether it is whole.

The reader walks the file record by record itself, so that it can tell three
states apart and say where the problem is:

* ``ok``: every record parses, every CRC matches, the footer and magic close it;
* ``truncated``: the file stops before its end (a hard kill); everything up to the
  last complete record is returned;
* ``corrupt``: a record is malformed or a CRC does not match (a bit flip);
  everything before the bad record is returned.

A file that is not MCAP, is empty, or was written by another program raises
:class:`pipemap.errors.LogFormatError`.
"""

from __future__ import annotations

import contextlib
import enum
import gc
import struct
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import NamedTuple

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk

from pipemap.errors import LogFormatError
from pipemap.recorder.topics import LIBRARY, METADATA_RUN

__all__ = ["Integrity", "LogChannel", "LogContents", "LogMessage", "gc_paused", "read_log"]

_MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEAD = struct.Struct("<BQ")


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
    first_time_ns: int | None = None
    last_time_ns: int | None = None

    @property
    def duration_ns(self) -> int:
        """Time from the first message to the last (0 with none)."""
        if self.first_time_ns is None or self.last_time_ns is None:
            return 0
        return self.last_time_ns - self.first_time_ns


class _Corrupt(Exception):
    pass


class _Reader:
    def __init__(self, data: bytes, keep: Callable[[str], bool]) -> None:
        self.data = data
        self.keep = keep
        self.schemas: dict[int, str] = {}
        self.contents = LogContents(library="")
        self.footer_seen = False

    def stream(self, body: bytes) -> ReadDataStream:
        return ReadDataStream(BytesIO(body))

    def message(self, record: Message) -> None:
        channel = self.contents.channels.get(record.channel_id)
        if channel is None:
            raise _Corrupt(f"message on unknown channel {record.channel_id}")
        c = self.contents
        c.counts[channel.topic] = c.counts.get(channel.topic, 0) + 1
        t = record.log_time
        c.first_time_ns = t if c.first_time_ns is None else min(c.first_time_ns, t)
        c.last_time_ns = t if c.last_time_ns is None else max(c.last_time_ns, t)
        if self.keep(channel.topic):
            c.messages.append(LogMessage(channel.topic, t, record.sequence, bytes(record.data)))

    def inner(self, record: object) -> None:
        if isinstance(record, Schema):
            self.schemas[record.id] = record.name
        elif isinstance(record, Channel):
            name = self.schemas.get(record.schema_id, "")
            self.contents.channels[record.id] = LogChannel(record.id, record.topic, name)
            self.contents.counts.setdefault(record.topic, 0)
        elif isinstance(record, Message):
            self.message(record)

    def record(self, position: int, opcode: int, body: bytes) -> None:
        if opcode == Opcode.CHUNK:
            chunk = Chunk.read(self.stream(body))
            for inner in breakup_chunk(chunk, validate_crc=True):
                self.inner(inner)
        elif opcode == Opcode.SCHEMA:
            self.inner(Schema.read(self.stream(body)))
        elif opcode == Opcode.CHANNEL:
            self.inner(Channel.read(self.stream(body)))
        elif opcode == Opcode.MESSAGE:
            self.inner(Message.read(self.stream(body), len(body)))
        elif opcode == Opcode.METADATA:
            meta = Metadata.read(self.stream(body))
            self.contents.metadata.setdefault(meta.name, dict(meta.metadata))
        elif opcode == Opcode.DATA_END:
            expected = DataEnd.read(self.stream(body)).data_section_crc
            if expected != 0 and expected != zlib.crc32(self.data[:position]):
                raise _Corrupt("data section CRC mismatch")
        elif opcode == Opcode.FOOTER:
            footer = Footer.read(self.stream(body))
            self.check_summary(position, footer)
            self.footer_seen = True

    def check_summary(self, position: int, footer: Footer) -> None:
        if footer.summary_crc == 0:
            return
        start = footer.summary_start if footer.summary_start else position
        end = position + _RECORD_HEAD.size + 16  # through summary_offset_start
        if not 0 < start <= position or zlib.crc32(self.data[start:end]) != footer.summary_crc:
            raise _Corrupt("summary CRC mismatch")


def _check_header(reader: _Reader, path: Path) -> int:
    data = reader.data
    if len(data) == 0:
        raise LogFormatError(f"{path}: empty file, not an MCAP log")
    if not data.startswith(_MAGIC):
        raise LogFormatError(f"{path}: not an MCAP file")
    position = len(_MAGIC)
    if len(data) < position + _RECORD_HEAD.size:
        raise LogFormatError(f"{path}: MCAP file cut short before its header")
    opcode, length = _RECORD_HEAD.unpack_from(data, position)
    body_start = position + _RECORD_HEAD.size
    if opcode != Opcode.HEADER or body_start + length > len(data):
        raise LogFormatError(f"{path}: MCAP file without a readable header")
    try:
        header = Header.read(reader.stream(data[body_start : body_start + length]))
    except Exception as exc:  # any parse failure of the header is a malformed file
        raise LogFormatError(f"{path}: MCAP header is malformed ({exc})") from None
    if header.library.split(" ")[0] != LIBRARY:
        writer = header.library or "an unnamed program"
        raise LogFormatError(f"{path}: an MCAP file written by {writer}, not a pipemap log")
    reader.contents.library = str(header.library)
    return int(body_start + length)


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
        return _read(data, path, keep)


def _read(data: bytes, path: Path, keep: Callable[[str], bool] | None) -> LogContents:
    reader = _Reader(data, keep if keep is not None else (lambda _topic: True))
    position = _check_header(reader, path)
    contents = reader.contents
    # A file that still ends in the magic was written to its end: any failure in it
    # is damage, not a cut.
    complete = len(data) >= 2 * len(_MAGIC) and data.endswith(_MAGIC)
    while not reader.footer_seen:
        if position + _RECORD_HEAD.size > len(data):
            if complete:
                contents.integrity, contents.problem = Integrity.CORRUPT, "no footer"
            else:
                contents.integrity = Integrity.TRUNCATED
                contents.problem = f"file ends inside a record header at byte {position}"
            break
        opcode, length = _RECORD_HEAD.unpack_from(data, position)
        end = position + _RECORD_HEAD.size + length
        if end > len(data):
            if complete:
                contents.integrity = Integrity.CORRUPT
                contents.problem = f"record at byte {position} runs past the end of the file"
            else:
                contents.integrity = Integrity.TRUNCATED
                contents.problem = f"file ends inside the record at byte {position}"
            break
        try:
            reader.record(position, opcode, data[position + _RECORD_HEAD.size : end])
        except Exception as exc:  # CRC mismatch, bad compression, malformed record
            contents.integrity = Integrity.CORRUPT
            contents.problem = f"record at byte {position}: {exc or type(exc).__name__}"
            break
        position = end
    if reader.footer_seen and data[position:] != _MAGIC:
        contents.integrity, contents.problem = Integrity.CORRUPT, "bad magic after the footer"
    if METADATA_RUN not in contents.metadata and contents.integrity is Integrity.OK:
        raise LogFormatError(f"{path}: MCAP file without pipemap's run metadata")
    return contents
