"""The frame of an MCAP file around its data section: the header it opens with, and the
summary, footer and closing magic it ends with. A damaged summary loses nothing (every
message is in the data section), but :func:`read_summary` says what is wrong with it;
a summary that reads gives the walk of :mod:`recorder.mcapfile` the chunks to resume at
after damage, and the schemas and channels a lost chunk held."""

from __future__ import annotations

import struct
from dataclasses import dataclass

from mcap.opcode import Opcode

from pipemap.recorder.filebytes import ByteSource, crc32_between, unpack_at
from pipemap.recorder.mcaprecords import (
    FOOTER,
    FOOTER_RECORD,
    HEAD,
    MAGIC,
    U64,
    BadRecord,
    Body,
    McapHeaderError,
    add_definition,
    describe,
)

__all__ = [
    "ChunkIndex",
    "Summary",
    "closing_magic_end",
    "missing_magic",
    "read_header",
    "read_summary",
]

_CHUNK_INDEX = struct.Struct("<QQQQ")


@dataclass
class ChunkIndex:
    """Where the summary says a chunk is, the time range it holds and its message indexes."""

    #: The chunk's number among the file's chunks (1-based).
    number: int
    offset: int
    start_ns: int
    end_ns: int
    #: channel id -> file offset of the chunk's message index record for it
    message_index_offsets: dict[int, int]


@dataclass
class Summary:
    """What a file's summary section holds."""

    limit: int  # where the data section ends (the summary's start, or the footer's)
    chunks: list[ChunkIndex]
    schemas: dict[int, tuple[str, str]]
    channels: dict[int, tuple[str, int, str]]
    metadata_names: list[str]


def read_header(data: ByteSource) -> tuple[int, str, str]:
    """Where the data section starts, and the header's profile and library.

    Raises :class:`McapHeaderError` when the file is not MCAP or its header cannot
    be read."""
    size = len(data)
    if size == 0:
        raise McapHeaderError("empty file, not an MCAP log")
    opening = data[: len(MAGIC)]
    if size < len(MAGIC) and MAGIC.startswith(opening):
        raise McapHeaderError("MCAP file cut short inside its magic, before its header")
    if opening != MAGIC:
        raise McapHeaderError("not an MCAP file")
    position = len(MAGIC)
    if size < position + HEAD.size:
        raise McapHeaderError("MCAP file cut short before its header")
    opcode, length = unpack_at(HEAD, data, position)
    if opcode != Opcode.HEADER:
        raise McapHeaderError(f"MCAP file whose first record is not a header (opcode {opcode})")
    end = position + HEAD.size + length
    if end > size:
        raise McapHeaderError(
            f"MCAP file cut short inside its header (header of {length} bytes, file of {size})"
        )
    body = Body(data, position + HEAD.size, end)
    try:
        profile = body.string()
        library = body.string()
    except BadRecord as exc:
        raise McapHeaderError(f"MCAP header is malformed: {exc}") from None
    return int(end), profile, library


def read_summary(data: ByteSource, data_start: int) -> tuple[Summary | None, str]:
    """The footer and the summary, and what is wrong with them ("" if nothing, or if
    the file does not end in the magic: then it is cut short, and has no summary)."""
    size = len(data)
    if size < data_start + FOOTER_RECORD + len(MAGIC):
        return None, ""
    at = size - len(MAGIC) - FOOTER_RECORD
    if data[-len(MAGIC) :] != MAGIC:
        # A footer where it belongs, then eight bytes that are not the magic: the file
        # is whole to its last byte and its closing magic is damaged (not cut short).
        opcode, length = unpack_at(HEAD, data, at)
        if opcode == Opcode.FOOTER and length == FOOTER.size and not missing_magic(data):
            return None, "the closing magic is damaged (the file's last 8 bytes)"
        return None, ""
    footer = data[at : at + FOOTER_RECORD]
    opcode, length = HEAD.unpack_from(footer, 0)
    if opcode != Opcode.FOOTER or length != FOOTER.size:
        return None, "no footer before the closing magic"
    start, _offsets, crc = FOOTER.unpack_from(footer, HEAD.size)
    if start != 0 and not data_start <= start <= at:
        return None, f"the footer points its summary outside the file (byte {start})"
    # The CRC is checked before the summary is read into memory: a damaged footer may
    # point its summary at the start of a file of gigabytes.
    first = start or at
    if crc != 0 and crc32_between(data, first, at + HEAD.size + 16) != crc:
        return None, "summary CRC mismatch"
    section = data[first : at + HEAD.size + 16]
    summary = Summary(first, [], {}, {}, [])
    position, records_end = 0, at - first
    try:
        while position < records_end:
            opcode, length = HEAD.unpack_from(section, position)
            end = position + HEAD.size + length
            if end > records_end:
                raise BadRecord("a summary record runs into the footer")
            _add_summary_record(summary, opcode, Body(section, position + HEAD.size, end))
            position = end
    except (BadRecord, struct.error) as exc:
        return None, f"summary unreadable ({describe(exc)})"
    return summary, ""


def _add_summary_record(summary: Summary, opcode: int, body: Body) -> None:
    if add_definition(opcode, body, summary.schemas, summary.channels):
        return
    if opcode == Opcode.CHUNK_INDEX:
        begin, finish, offset, _length = body.unpack(_CHUNK_INDEX)
        offsets: dict[int, int] = {}
        entries = body.u32()
        entries_end = body.pos + entries
        while body.pos < entries_end:
            channel_id = body.u16()
            offsets[channel_id] = body.u64()
        number = len(summary.chunks) + 1
        summary.chunks.append(ChunkIndex(number, offset, begin, finish, offsets))
    elif opcode == Opcode.METADATA_INDEX:
        body.u64()
        body.u64()
        summary.metadata_names.append(body.string())


def missing_magic(data: ByteSource) -> int:
    """How many bytes of the closing magic are missing, if the file ends inside it
    right after a footer record; else 0."""
    size = len(data)
    for missing in range(1, len(MAGIC) + 1):
        kept = len(MAGIC) - missing
        at = size - kept - FOOTER_RECORD
        if at < 0:
            break
        if data[size - kept :] == MAGIC[:kept] and data[at] == Opcode.FOOTER:
            (length,) = unpack_at(U64, data, at + 1)
            if length == FOOTER.size:
                return missing
    return 0


def closing_magic_end(data: ByteSource, data_end_at: int) -> int:
    """Where the first footer and closing magic after the data end record at
    ``data_end_at`` stop (0 if none does): the summary is small, so the search is short."""
    found = data.find(MAGIC, data_end_at)
    while found != -1:
        at = found - FOOTER_RECORD
        if at >= data_end_at and data[at] == Opcode.FOOTER:
            return int(found + len(MAGIC))
        found = data.find(MAGIC, found + 1)
    return 0
