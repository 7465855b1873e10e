"""An MCAP file walked record by record, losing only what is damaged.

This is the low level of :mod:`recorder.reader`: it knows MCAP, not pipemap. It
reads every record of the data section in file order and hands each message on.
Where something is wrong it does what ``mcap recover`` and ``mcap doctor`` do:

* a chunk whose CRC, compression or records are bad is lost alone: the walk goes
  on at the next record, and what the chunk held (channels, message counts, time
  range) is told from its message indexes, which lie outside it;
* where the record framing itself is broken (a length that runs off, an opcode
  that does not exist), the walk picks up again at the next intact chunk: the one
  the summary's chunk index names, or, without a summary, the next place where a
  whole chunk parses and its CRC matches;
* a file that stops early is truncated, not damaged: everything up to the last
  complete record is kept;
* a damaged summary or footer loses nothing (every message is in the data section),
  but it is damage all the same.
"""

from __future__ import annotations

import contextlib
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field

from mcap.opcode import Opcode

__all__ = ["MAGIC", "Lost", "McapHeaderError", "Scan", "scan"]

MAGIC = b"\x89MCAP0\r\n"
_HEAD = struct.Struct("<BQ")
_MESSAGE = struct.Struct("<HIQQ")
_CHUNK = struct.Struct("<QQQI")
_FOOTER = struct.Struct("<QQI")
_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_FOOTER_RECORD = _HEAD.size + _FOOTER.size
#: Opcodes MCAP defines (0x01-0x0F); 0x80 and above are private records, skipped.
_KNOWN = frozenset(range(0x01, 0x10))
#: No sane chunk decompresses to more than this: a larger size is damage.
_MAX_CHUNK_BYTES = 1 << 30

#: Called with (topic, sequence, log time in ns, payload) for every message read.
MessageSink = Callable[[str, int, int, bytes], None]


class McapHeaderError(Exception):
    """The file is not MCAP, or its header cannot be read."""


class _Bad(Exception):
    """A record does not parse or does not check."""


@dataclass
class Lost:
    """A stretch of the file that could not be read, and what it held where known."""

    offset: int
    problem: str
    #: The damaged chunk's number among the file's chunks (1-based), when known.
    chunk: int | None = None
    start_ns: int | None = None
    end_ns: int | None = None
    #: Messages lost per channel id (from the chunk's message indexes), when known.
    counts: dict[int, int] = field(default_factory=dict)


@dataclass
class Scan:
    """What a walk through a file found."""

    library: str = ""
    profile: str = ""
    #: id -> (name, encoding)
    schemas: dict[int, tuple[str, str]] = field(default_factory=dict)
    #: id -> (topic, schema id, message encoding)
    channels: dict[int, tuple[str, int, str]] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    #: Names of every metadata record the summary indexes.
    indexed_metadata: list[str] = field(default_factory=list)
    lost: list[Lost] = field(default_factory=list)
    #: How the file stops early, when it does ("" when it is whole).
    truncated: str = ""
    #: Chunks in the file, from its summary (``None`` without one).
    chunk_count: int | None = None
    #: Messages whose channel record was never read (lost with a damaged chunk).
    unknown_channel_messages: int = 0


@dataclass
class _ChunkIndex:
    number: int
    offset: int
    start_ns: int
    end_ns: int
    message_index_offsets: dict[int, int]


@dataclass
class _Summary:
    limit: int  # where the data section ends (the summary's start, or the footer's)
    chunks: list[_ChunkIndex]
    schemas: dict[int, tuple[str, str]]
    channels: dict[int, tuple[str, int, str]]
    metadata_names: list[str]


class _Body:
    """Strict reading of one record's body: running short is an error."""

    def __init__(self, data: bytes | memoryview, start: int = 0, end: int | None = None) -> None:
        self.data = data
        self.pos = start
        self.end = len(data) if end is None else end

    def take(self, n: int) -> bytes | memoryview:
        if n < 0 or self.pos + n > self.end:
            raise _Bad("a field runs past the end of its record")
        value = self.data[self.pos : self.pos + n]
        self.pos += n
        return value

    def unpack(self, fmt: struct.Struct) -> tuple[int, ...]:
        if self.pos + fmt.size > self.end:
            raise _Bad("a field runs past the end of its record")
        value = fmt.unpack_from(self.data, self.pos)
        self.pos += fmt.size
        return value

    def u16(self) -> int:
        return int(self.unpack(_U16)[0])

    def u32(self) -> int:
        return int(self.unpack(_U32)[0])

    def u64(self) -> int:
        return int(self.unpack(_U64)[0])

    def string(self) -> str:
        try:
            return bytes(self.take(self.u32())).decode("utf-8")
        except UnicodeDecodeError:
            raise _Bad("a string is not UTF-8") from None

    def string_map(self) -> dict[str, str]:
        length = self.u32()
        end = self.pos + length
        if end > self.end:
            raise _Bad("a map runs past the end of its record")
        out: dict[str, str] = {}
        while self.pos < end:
            key = self.string()
            out[key] = self.string()
        if self.pos != end:
            raise _Bad("a map's entries overrun its length")
        return out


def _schema(body: _Body) -> tuple[int, tuple[str, str]]:
    schema_id = body.u16()
    name = body.string()
    encoding = body.string()
    body.take(body.u32())
    return schema_id, (name, encoding)


def _channel(body: _Body) -> tuple[int, tuple[str, int, str]]:
    channel_id = body.u16()
    schema_id = body.u16()
    topic = body.string()
    encoding = body.string()
    body.string_map()
    return channel_id, (topic, schema_id, encoding)


def _describe(exc: BaseException) -> str:
    text = str(exc)
    return text if text else type(exc).__name__


def _decompress(compression: str, data: bytes | memoryview, size: int) -> bytes:
    if size > _MAX_CHUNK_BYTES:
        raise _Bad(f"uncompressed size {size} bytes is not believable")
    if compression == "":
        return bytes(data)
    if compression == "zstd":
        import zstandard

        declared = zstandard.get_frame_parameters(bytes(data[:18])).content_size
        if declared not in (size, zstandard.CONTENTSIZE_UNKNOWN):
            raise _Bad(f"zstd frame of {declared} bytes where the chunk says {size}")
        return bytes(zstandard.ZstdDecompressor().decompress(bytes(data), max_output_size=size))
    if compression == "lz4":
        import lz4.frame

        return bytes(lz4.frame.decompress(bytes(data)))
    raise _Bad(f"unknown compression {compression!r}")


def _chunk_records(body: _Body) -> tuple[int, int, bytes]:
    """A chunk's time range and its records, uncompressed and checked."""
    start_ns, end_ns, size, crc = body.unpack(_CHUNK)
    compression = body.string()
    compressed = body.take(body.u64())
    if body.pos != body.end:
        raise _Bad("the chunk's data does not fill its record")
    try:
        records = _decompress(compression, compressed, size)
    except _Bad:
        raise
    except Exception as exc:  # any decoder's error: the compressed bytes are damaged
        raise _Bad(f"{compression} data does not decompress ({_describe(exc)})") from None
    if len(records) != size:
        raise _Bad(f"decompresses to {len(records)} bytes, not {size}")
    if crc != 0 and zlib.crc32(records) != crc:
        raise _Bad("CRC mismatch")
    return start_ns, end_ns, records


class _Walker:
    def __init__(self, data: bytes, on_message: MessageSink) -> None:
        self.data = data
        self.on_message = on_message
        self.out = Scan()
        self.summary: _Summary | None = None
        self.chunk_at: dict[int, _ChunkIndex] = {}
        self.chunks_seen = 0
        self.pending: Lost | None = None  # the last lost chunk, for its message indexes
        self.data_end_seen = False

    # -- the header and the summary -------------------------------------------------

    def header(self) -> int:
        data = self.data
        if len(data) == 0:
            raise McapHeaderError("empty file, not an MCAP log")
        if len(data) < len(MAGIC) and MAGIC.startswith(data):
            raise McapHeaderError("MCAP file cut short inside its magic, before its header")
        if not data.startswith(MAGIC):
            raise McapHeaderError("not an MCAP file")
        position = len(MAGIC)
        if len(data) < position + _HEAD.size:
            raise McapHeaderError("MCAP file cut short before its header")
        opcode, length = _HEAD.unpack_from(data, position)
        if opcode != Opcode.HEADER:
            raise McapHeaderError(f"MCAP file whose first record is not a header (opcode {opcode})")
        end = position + _HEAD.size + length
        if end > len(data):
            raise McapHeaderError(
                f"MCAP file cut short inside its header (header of {length} bytes, "
                f"file of {len(data)})"
            )
        body = _Body(data, position + _HEAD.size, end)
        try:
            self.out.profile = body.string()
            self.out.library = body.string()
        except _Bad as exc:
            raise McapHeaderError(f"MCAP header is malformed: {exc}") from None
        return int(end)

    def read_summary(self, data_start: int) -> str:
        """Read the footer and the summary; returns what is wrong with them ("" if
        nothing, or if the file does not end in the magic: then it is cut short)."""
        data = self.data
        if len(data) < data_start + _FOOTER_RECORD + len(MAGIC) or not data.endswith(MAGIC):
            return ""
        at = len(data) - len(MAGIC) - _FOOTER_RECORD
        opcode, length = _HEAD.unpack_from(data, at)
        if opcode != Opcode.FOOTER or length != _FOOTER.size:
            return "no footer before the closing magic"
        start, _offsets, crc = _FOOTER.unpack_from(data, at + _HEAD.size)
        if start != 0 and not data_start <= start <= at:
            return f"the footer points its summary outside the file (byte {start})"
        if crc != 0 and zlib.crc32(data[start or at : at + _HEAD.size + 16]) != crc:
            return "summary CRC mismatch"
        summary = _Summary(start or at, [], {}, {}, [])
        position = start if start else at
        try:
            while position < at:
                opcode, length = _HEAD.unpack_from(data, position)
                end = position + _HEAD.size + length
                if end > at:
                    raise _Bad("a summary record runs into the footer")
                body = _Body(data, position + _HEAD.size, end)
                if opcode == Opcode.SCHEMA:
                    key, schema = _schema(body)
                    summary.schemas[key] = schema
                elif opcode == Opcode.CHANNEL:
                    key, channel = _channel(body)
                    summary.channels[key] = channel
                elif opcode == Opcode.CHUNK_INDEX:
                    begin, finish, offset, _length = body.unpack(struct.Struct("<QQQQ"))
                    offsets: dict[int, int] = {}
                    entries = body.u32()
                    entries_end = body.pos + entries
                    while body.pos < entries_end:
                        channel_id = body.u16()
                        offsets[channel_id] = body.u64()
                    number = len(summary.chunks) + 1
                    summary.chunks.append(_ChunkIndex(number, offset, begin, finish, offsets))
                elif opcode == Opcode.METADATA_INDEX:
                    body.u64()
                    body.u64()
                    summary.metadata_names.append(body.string())
                position = end
        except (_Bad, struct.error) as exc:
            return f"summary unreadable ({_describe(exc)})"
        self.summary = summary
        self.chunk_at = {c.offset: c for c in summary.chunks}
        self.out.chunk_count = len(summary.chunks)
        self.out.indexed_metadata = list(summary.metadata_names)
        # The summary repeats every schema and channel: a chunk that held them may be lost.
        self.out.schemas.update(summary.schemas)
        self.out.channels.update(summary.channels)
        return ""

    # -- finding the next intact chunk ------------------------------------------------

    def _chunk_checks(self, position: int) -> bool:
        data = self.data
        if position + _HEAD.size + _CHUNK.size + 4 > len(data):
            return False
        opcode, length = _HEAD.unpack_from(data, position)
        end = position + _HEAD.size + length
        if opcode != Opcode.CHUNK or end > len(data):
            return False
        try:
            _chunk_records(_Body(data, position + _HEAD.size, end))
        except (_Bad, struct.error):
            return False
        return True

    def resync(self, after: int) -> int | None:
        """The start of the first intact chunk after byte ``after``, if any."""
        if self.summary is not None:
            later = [c.offset for c in self.summary.chunks if c.offset > after]
            return min(later) if later else None
        data = self.data
        position = data.find(b"\x06", after + 1)
        while position != -1:
            if self._chunk_checks(position):
                return position
            position = data.find(b"\x06", position + 1)
        return None

    # -- losses -----------------------------------------------------------------------

    def lose_chunk(self, position: int, problem: str) -> None:
        index = self.chunk_at.get(position)
        lost = Lost(position, problem)
        if index is not None:
            lost.chunk, lost.start_ns, lost.end_ns = index.number, index.start_ns, index.end_ns
            for offset in index.message_index_offsets.values():
                self._count_index(offset, lost)
        else:
            lost.chunk = None if self.summary is not None else self.chunks_seen
            with contextlib.suppress(struct.error):
                times = _CHUNK.unpack_from(self.data, position + _HEAD.size)
                lost.start_ns, lost.end_ns = times[0], times[1]
            self.pending = lost
        self.out.lost.append(lost)

    def _count_index(self, position: int, lost: Lost) -> None:
        data = self.data
        try:
            opcode, length = _HEAD.unpack_from(data, position)
            if opcode != Opcode.MESSAGE_INDEX:
                return
            start = position + _HEAD.size
            self._add_index(_Body(data, start, start + length), lost)
        except (_Bad, struct.error):
            return

    @staticmethod
    def _add_index(body: _Body, lost: Lost) -> None:
        channel_id = body.u16()
        size = body.u32()
        if body.pos + size > body.end or size % 16:
            raise _Bad("message index entries overrun the record")
        times = [t for t, _ in struct.iter_unpack("<QQ", body.take(size))]
        if not times:
            return
        lost.counts[channel_id] = lost.counts.get(channel_id, 0) + len(times)
        low, high = min(times), max(times)
        lost.start_ns = low if lost.start_ns is None else min(lost.start_ns, low)
        lost.end_ns = high if lost.end_ns is None else max(lost.end_ns, high)

    # -- the data section -------------------------------------------------------------

    def record(self, position: int, opcode: int, body: _Body) -> None:
        out = self.out
        if opcode == Opcode.CHUNK:
            self.chunks_seen += 1
            self.pending = None
            self.chunk(body)
        elif opcode == Opcode.MESSAGE_INDEX:
            if self.pending is not None:
                self._add_index(body, self.pending)
        elif opcode == Opcode.SCHEMA:
            key, schema = _schema(body)
            out.schemas[key] = schema
        elif opcode == Opcode.CHANNEL:
            key, channel = _channel(body)
            out.channels[key] = channel
        elif opcode == Opcode.MESSAGE:
            channel_id, sequence, log_time, _ = body.unpack(_MESSAGE)
            self.message(channel_id, sequence, log_time, bytes(body.take(body.end - body.pos)))
        elif opcode == Opcode.METADATA:
            name = body.string()
            values = body.string_map()
            out.metadata.setdefault(name, values)
        elif opcode == Opcode.DATA_END:
            (expected,) = body.unpack(_U32)
            if expected != 0 and expected != zlib.crc32(self.data[:position]) and not out.lost:
                out.lost.append(
                    Lost(
                        position,
                        "data section CRC mismatch, though every chunk's own CRC matches "
                        "(a metadata or index record is damaged)",
                    )
                )

    def message(self, channel_id: int, sequence: int, log_time: int, payload: bytes) -> None:
        channel = self.out.channels.get(channel_id)
        if channel is None:
            self.out.unknown_channel_messages += 1
            return
        self.on_message(channel[0], sequence, log_time, payload)

    def chunk(self, body: _Body) -> None:
        _start, _end, records = _chunk_records(body)
        # Parse the whole chunk before keeping any of it: a chunk is lost or kept whole.
        schemas: list[tuple[int, tuple[str, str]]] = []
        channels: list[tuple[int, tuple[str, int, str]]] = []
        messages: list[tuple[int, int, int, bytes]] = []
        position, size = 0, len(records)
        head, message = _HEAD, _MESSAGE
        while position < size:
            if position + head.size > size:
                raise _Bad("a record inside the chunk is cut short")
            opcode, length = head.unpack_from(records, position)
            start = position + head.size
            end = start + length
            if end > size:
                raise _Bad("a record inside the chunk runs past its end")
            if opcode == Opcode.MESSAGE:
                if length < message.size:
                    raise _Bad("a message record is too short")
                channel_id, sequence, log_time, _ = message.unpack_from(records, start)
                payload = records[start + message.size : end]
                messages.append((channel_id, sequence, log_time, payload))
            elif opcode == Opcode.SCHEMA:
                schemas.append(_schema(_Body(records, start, end)))
            elif opcode == Opcode.CHANNEL:
                channels.append(_channel(_Body(records, start, end)))
            position = end
        self.out.schemas.update(schemas)
        for key, (topic, schema_id, encoding) in channels:
            self.out.channels[key] = (topic, schema_id, encoding)
        for m in messages:
            self.message(*m)

    def walk(self, position: int) -> None:
        data = self.data
        limit = self.summary.limit if self.summary is not None else len(data)
        while True:
            if position >= limit and self.summary is not None:
                return  # a data section without a data end record
            if position + _HEAD.size > len(data):
                self.cut(position, f"file ends inside the record header at byte {position}")
                return
            opcode, length = _HEAD.unpack_from(data, position)
            end = position + _HEAD.size + length
            if opcode not in _KNOWN and opcode < 0x80 or opcode == Opcode.HEADER:
                problem = f"no record starts at byte {position} (opcode {opcode:#04x})"
            elif end > limit:
                if self.summary is None and end > len(data) and self.resync(position) is None:
                    self.cut(position, f"file ends inside the record at byte {position}")
                    return
                problem = f"the record at byte {position} claims {length} bytes, past the data"
            else:
                body = _Body(data, position + _HEAD.size, end)
                try:
                    self.record(position, opcode, body)
                except (_Bad, struct.error) as exc:
                    problem = _describe(exc)
                    self.lose(position, opcode, end, problem)
                    next_at = self.after_loss(position, end)
                    if next_at is None:
                        return
                    position = next_at
                    continue
                if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    self.data_end_seen = True
                    return
                position = end
                continue
            # The framing is broken: pick up at the next intact chunk.
            self.lose(position, opcode, None, problem)
            next_at = self.resync(position)
            if next_at is None:
                return
            position = next_at

    def lose(self, position: int, opcode: int, end: int | None, problem: str) -> None:
        if opcode == Opcode.CHUNK:
            self.lose_chunk(position, problem)
            return
        lost = Lost(position, problem if end is not None else f"{problem}; the framing is lost")
        self.pending = None
        self.out.lost.append(lost)

    def after_loss(self, position: int, end: int) -> int | None:
        """Where to go on after a bad record at ``position`` whose length says ``end``:
        at ``end`` if no intact chunk starts before it (the length is believable),
        else at that chunk."""
        next_chunk = self.resync(position)
        if next_chunk is not None and next_chunk < end:
            return next_chunk
        data = self.data
        if end + _HEAD.size <= len(data):
            opcode, length = _HEAD.unpack_from(data, end)
            if (opcode in _KNOWN or opcode >= 0x80) and end + _HEAD.size + length <= len(data):
                return end
        return next_chunk

    def cut(self, position: int, where: str) -> None:
        self.out.truncated = where


def scan(data: bytes, on_message: MessageSink) -> tuple[Scan, str]:
    """Walk ``data``, an MCAP file's bytes; ``on_message`` gets every message read.

    Returns what was found and what is wrong with the summary, footer or closing
    magic ("" when nothing is). Raises :class:`McapHeaderError` when the file is not
    MCAP or its header cannot be read.
    """
    walker = _Walker(data, on_message)
    data_start = walker.header()
    tail = walker.read_summary(data_start)
    walker.walk(data_start)
    out = walker.out
    if not out.truncated and not data.endswith(MAGIC):
        missing = _missing_magic(data)
        if missing:
            out.truncated = f"file ends {missing} byte(s) short of its closing magic"
        elif walker.data_end_seen:
            out.truncated = f"file ends at byte {len(data)}, in its summary, after every message"
        else:
            out.truncated = f"file ends at byte {len(data)}, before the end of its data"
    return out, tail


def _missing_magic(data: bytes) -> int:
    """How many bytes of the closing magic are missing, if the file ends inside it
    right after a footer record; else 0."""
    for missing in range(1, len(MAGIC) + 1):
        kept = len(MAGIC) - missing
        at = len(data) - kept - _FOOTER_RECORD
        if at < 0:
            break
        if data[len(data) - kept :] == MAGIC[:kept] and data[at] == Opcode.FOOTER:
            (length,) = _U64.unpack_from(data, at + 1)
            if length == _FOOTER.size:
                return missing
    return 0
