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
* a chunk that holds the very records of one read before (a copy another program
  made) is read once and named, not lost;
* a file that stops early is truncated, not damaged: everything up to the last
  complete record is kept;
* a damaged summary or footer loses nothing (every message is in the data section),
  but it is damage all the same.

The walk is a :class:`Walk`, which hands the messages out as it reads them, in file
order; :func:`scan` calls a function with each instead. Either reads the file's
``bytes`` or a :class:`FileBytes` that reads it from disk as it goes, so that a log
of gigabytes is walked holding about one chunk of it.

The records themselves are read by :mod:`recorder.mcaprecords`, the header, summary
and footer around the data section by :mod:`recorder.mcapsummary`.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

from mcap.opcode import Opcode

from pipemap.recorder.filebytes import ByteSource, FileBytes, crc32_between, unpack_at
from pipemap.recorder.mcaprecords import (
    CHUNK,
    HEAD,
    KNOWN_OPCODES,
    MAGIC,
    MESSAGE,
    U32,
    BadRecord,
    Body,
    McapHeaderError,
    add_definition,
    chunk_records,
    describe,
    read_channel,
    read_schema,
)
from pipemap.recorder.mcapsummary import (
    ChunkIndex,
    Summary,
    closing_magic_end,
    missing_magic,
    read_header,
    read_summary,
)

__all__ = [
    "MAGIC",
    "ByteSource",
    "FileBytes",
    "Lost",
    "McapHeaderError",
    "Message",
    "Scan",
    "Walk",
    "scan",
]

#: A message as the walk hands it on: topic, sequence, log time in ns, payload.
Message = tuple[str, int, int, bytes]
#: Called with (topic, sequence, log time in ns, payload) for every message read.
MessageSink = Callable[[str, int, int, bytes], None]


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
    #: (name, offset, values) of each metadata record whose name an earlier one had.
    repeated_metadata: list[tuple[str, int, dict[str, str]]] = field(default_factory=list)
    #: Where another MCAP file begins after this one's closing magic (0 where none does).
    joined_at: int = 0


class _Walker:
    def __init__(self, data: ByteSource) -> None:
        self.data = data
        self.out = Scan()
        self.summary: Summary | None = None
        self.chunk_at: dict[int, ChunkIndex] = {}
        self.chunks_seen = 0
        #: (start, end, size, CRC or digest of the records) -> where and which chunk
        #: first held them
        self.chunk_digests: dict[tuple[int, int, int, bytes], tuple[int, int | None]] = {}
        self.pending: Lost | None = None  # the last lost chunk, for its message indexes
        self.data_end_seen = False
        self.data_end_at = 0
        #: What is wrong with the summary, footer, closing magic or what follows it.
        self.tail = ""

    # -- the header and the summary -------------------------------------------------

    def header(self) -> int:
        data_start, self.out.profile, self.out.library = read_header(self.data)
        return data_start

    def read_summary(self, data_start: int) -> str:
        """Read the footer and the summary; returns what is wrong with them ("" if
        nothing, or if the file does not end in the magic: then it is cut short)."""
        summary, problem = read_summary(self.data, data_start)
        self.tail = problem
        if summary is None:
            return problem
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
        if position + HEAD.size + CHUNK.size + 4 > len(data):
            return False
        opcode, length = unpack_at(HEAD, data, position)
        end = position + HEAD.size + length
        if opcode != Opcode.CHUNK or end > len(data):
            return False
        try:
            chunk_records(Body(data, position + HEAD.size, end))
        except (BadRecord, struct.error):
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
            lost.chunk = self._number(position)
            with contextlib.suppress(struct.error):
                times = unpack_at(CHUNK, self.data, position + HEAD.size)
                lost.start_ns, lost.end_ns = times[0], times[1]
            self.pending = lost
        self.out.lost.append(lost)

    def _count_index(self, position: int, lost: Lost) -> None:
        data = self.data
        try:
            opcode, length = unpack_at(HEAD, data, position)
            if opcode != Opcode.MESSAGE_INDEX:
                return
            start = position + HEAD.size
            self._add_index(Body(data, start, start + length), lost)
        except (BadRecord, struct.error):
            return

    @staticmethod
    def _add_index(body: Body, lost: Lost) -> None:
        channel_id = body.u16()
        size = body.u32()
        if body.pos + size > body.end or size % 16:
            raise BadRecord("message index entries overrun the record")
        times = [t for t, _ in struct.iter_unpack("<QQ", body.take(size))]
        if not times:
            return
        lost.counts[channel_id] = lost.counts.get(channel_id, 0) + len(times)
        low, high = min(times), max(times)
        lost.start_ns = low if lost.start_ns is None else min(lost.start_ns, low)
        lost.end_ns = high if lost.end_ns is None else max(lost.end_ns, high)

    # -- the data section -------------------------------------------------------------

    def record(self, position: int, opcode: int, body: Body) -> list[Message]:
        """Read one record of the data section; returns the messages it holds."""
        out = self.out
        if add_definition(opcode, body, out.schemas, out.channels):
            return []
        if opcode == Opcode.CHUNK:
            self.chunks_seen += 1
            self.pending = None
            return self.chunk(body, position)
        if opcode == Opcode.MESSAGE_INDEX:
            if self.pending is not None:
                self._add_index(body, self.pending)
        elif opcode == Opcode.MESSAGE:
            channel_id, sequence, log_time, _ = body.unpack(MESSAGE)
            payload = bytes(body.take(body.end - body.pos))
            channel = out.channels.get(channel_id)
            if channel is None:
                out.unknown_channel_messages += 1
                return []
            return [(channel[0], sequence, log_time, payload)]
        elif opcode == Opcode.METADATA:
            name = body.string()
            values = body.string_map()
            if name in out.metadata:
                out.repeated_metadata.append((name, position, values))
            out.metadata.setdefault(name, values)
        elif opcode == Opcode.DATA_END:
            (expected,) = body.unpack(U32)
            if expected != 0 and not out.lost and expected != crc32_between(self.data, 0, position):
                out.lost.append(
                    Lost(
                        position,
                        "data section CRC mismatch, though every chunk's own CRC matches "
                        "(a metadata or index record is damaged)",
                    )
                )
        return []

    def known(self, messages: list[tuple[int, int, int, bytes]]) -> list[Message]:
        """``messages`` (by channel id) on the topics of their channels; those whose
        channel was never read are counted, not handed on."""
        channels = self.out.channels
        topics = {key: channel[0] for key, channel in channels.items()}
        out = [(topics[m[0]], m[1], m[2], m[3]) for m in messages if m[0] in topics]
        self.out.unknown_channel_messages += len(messages) - len(out)
        return out

    def chunk(self, body: Body, position: int) -> list[Message]:
        crc = unpack_at(CHUNK, body.data, body.pos)[3]
        start_ns, end_ns, records = chunk_records(body)
        # The records' CRC, checked by chunk_records, tells a copy from another chunk of
        # the same time range and size; a digest stands in where the writer left it 0.
        same = crc.to_bytes(4, "little") if crc else hashlib.blake2b(records).digest()
        if self._repeats(position, (start_ns, end_ns, len(records), same)):
            return []
        # Parse the whole chunk before keeping any of it: a chunk is lost or kept whole.
        schemas: list[tuple[int, tuple[str, str]]] = []
        channels: list[tuple[int, tuple[str, int, str]]] = []
        messages: list[tuple[int, int, int, bytes]] = []
        position, size = 0, len(records)
        head, message = HEAD, MESSAGE
        while position < size:
            if position + head.size > size:
                raise BadRecord("a record inside the chunk is cut short")
            opcode, length = head.unpack_from(records, position)
            start = position + head.size
            end = start + length
            if end > size:
                raise BadRecord("a record inside the chunk runs past its end")
            if opcode == Opcode.MESSAGE:
                if length < message.size:
                    raise BadRecord("a message record is too short")
                channel_id, sequence, log_time, _ = message.unpack_from(records, start)
                payload = records[start + message.size : end]
                messages.append((channel_id, sequence, log_time, payload))
            elif opcode == Opcode.SCHEMA:
                schemas.append(read_schema(Body(records, start, end)))
            elif opcode == Opcode.CHANNEL:
                channels.append(read_channel(Body(records, start, end)))
            position = end
        self.out.schemas.update(schemas)
        for key, (topic, schema_id, encoding) in channels:
            self.out.channels[key] = (topic, schema_id, encoding)
        return self.known(messages)

    def _number(self, position: int) -> int | None:
        """A chunk's number: the summary's, else its place in the file when there is no
        summary to number it (``None`` for a chunk the summary does not name)."""
        index = self.chunk_at.get(position)
        if index is not None:
            return index.number
        return None if self.summary is not None else self.chunks_seen

    def _repeats(self, position: int, key: tuple[int, int, int, bytes]) -> bool:
        """Whether the chunk at ``position`` holds the very records of one read before
        (a copy another program made): then it is read once, and the copy is named."""
        first = self.chunk_digests.setdefault(key, (position, self._number(position)))
        if first[0] == position:
            return False
        was = f"chunk {first[1]} (byte {first[0]})" if first[1] else f"the chunk at byte {first[0]}"
        problem = f"holds the same records as {was}: read once (no message is lost)"
        self.out.lost.append(Lost(position, problem, self._number(position)))
        return True

    def walk(self, position: int) -> Iterator[list[Message]]:
        """The data section from byte ``position`` on: the messages of each record
        that holds any (a chunk's all at once), in file order."""
        data = self.data
        limit = self.summary.limit if self.summary is not None else len(data)
        while True:
            if position >= limit and self.summary is not None:
                return  # a data section without a data end record
            if position + HEAD.size > len(data):
                self.cut(position, f"file ends inside the record header at byte {position}")
                return
            opcode, length = unpack_at(HEAD, data, position)
            end = position + HEAD.size + length
            if opcode not in KNOWN_OPCODES and opcode < 0x80 or opcode == Opcode.HEADER:
                problem = f"no record starts at byte {position} (opcode {opcode:#04x})"
            elif end > limit:
                if self.summary is None and end > len(data) and self.resync(position) is None:
                    self.cut(position, f"file ends inside the record at byte {position}")
                    return
                problem = f"the record at byte {position} claims {length} bytes, past the data"
            else:
                body = Body(data, position + HEAD.size, end)
                try:
                    messages = self.record(position, opcode, body)
                except (BadRecord, struct.error) as exc:
                    problem = describe(exc)
                    self.lose(position, opcode, end, problem)
                    next_at = self.after_loss(position, end)
                    if next_at is None:
                        return
                    position = next_at
                    continue
                if messages:
                    yield messages
                if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    self.data_end_seen = True
                    self.data_end_at = position
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
        if end + HEAD.size <= len(data):
            opcode, length = unpack_at(HEAD, data, end)
            known = opcode in KNOWN_OPCODES or opcode >= 0x80
            if known and end + HEAD.size + length <= len(data):
                return end
        return next_chunk

    def cut(self, position: int, where: str) -> None:
        self.out.truncated = where

    def finish(self) -> None:
        """Say how the file ends, if it stops short of its closing magic."""
        data, out = self.data, self.out
        ends = closing_magic_end(data, self.data_end_at) if self.data_end_seen else 0
        if ends and not out.truncated and data[ends : ends + len(MAGIC)] == MAGIC:
            # Two files joined end to end: the summary found is the second's.
            out.joined_at, self.tail = ends, ""
            return
        if out.truncated or self.tail or data[-len(MAGIC) :] == MAGIC:
            return
        missing = missing_magic(data)
        if ends and not missing:
            # Longer than the log, not shorter: another program appended to it.
            self.tail = f"{len(data) - ends} byte(s) after the log's end (its closing magic "
            self.tail += f"ends at byte {ends})"
        elif missing:
            out.truncated = f"file ends {missing} byte(s) short of its closing magic"
        elif self.data_end_seen:
            out.truncated = f"file ends at byte {len(data)}, in its summary, after every message"
        else:
            out.truncated = f"file ends at byte {len(data)}, before the end of its data"


class Walk:
    """A walk through an MCAP file that hands its messages out as it reads them.

    Made, it has read the header and the summary, and raises
    :class:`McapHeaderError` when the file is not MCAP or its header cannot be read.
    Iterated (once), it gives every message as ``(topic, sequence, log_time_ns,
    payload)`` in file order; :meth:`chunks` gives the same a record at a time (a
    chunk's messages together), for a reader that takes them in bulk. :attr:`scan`
    fills in as the walk goes (a metadata record is in it before the messages of
    the chunks after it are handed out) and is complete, like :attr:`tail`, once
    the walk is exhausted.

    ``data`` is the file's ``bytes``, or a :class:`FileBytes` that reads it from
    disk as it goes: then about one chunk of the file is held at a time.
    """

    def __init__(self, data: ByteSource) -> None:
        self._walker = _Walker(data)
        self._data_start = self._walker.header()
        #: What is wrong with the summary, footer or closing magic ("" when nothing is).
        self.tail = self._walker.read_summary(self._data_start)
        self._started = False
        #: Whether the walk has reached the end of the data it can read.
        self.done = False

    @property
    def scan(self) -> Scan:
        """What the walk has found so far (all it finds, once it is done)."""
        return self._walker.out

    def chunks(self) -> Iterator[list[Message]]:
        """The messages of each record that holds any, in file order."""
        if self._started:
            raise RuntimeError("an MCAP walk can be read only once")
        self._started = True
        return self._chunks()

    def _chunks(self) -> Iterator[list[Message]]:
        yield from self._walker.walk(self._data_start)
        self._walker.finish()
        self.tail = self._walker.tail
        self.done = True

    def __iter__(self) -> Iterator[Message]:
        return itertools.chain.from_iterable(self.chunks())


def scan(data: ByteSource, on_message: MessageSink) -> tuple[Scan, str]:
    """Walk ``data``, an MCAP file's bytes; ``on_message`` gets every message read.

    Returns what was found and what is wrong with the summary, footer or closing
    magic ("" when nothing is). Raises :class:`McapHeaderError` when the file is not
    MCAP or its header cannot be read.
    """
    walk = Walk(data)
    for message in walk:
        on_message(*message)
    return walk.scan, walk.tail
