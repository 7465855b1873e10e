"""MCAP's records byte by byte: their framing, the strict reading of a record's body,
and the records whose contents the walk of :mod:`recorder.mcapfile` keeps (schemas,
channels, chunks). It knows MCAP, not pipemap; what does not parse or check raises
:class:`BadRecord`."""

from __future__ import annotations

import struct
import zlib

from mcap.opcode import Opcode

from pipemap.recorder.filebytes import ByteSource, unpack_at

__all__ = [
    "CHUNK",
    "FOOTER",
    "FOOTER_RECORD",
    "HEAD",
    "KNOWN_OPCODES",
    "MAGIC",
    "MESSAGE",
    "U32",
    "U64",
    "BadRecord",
    "Body",
    "McapHeaderError",
    "add_definition",
    "chunk_records",
    "describe",
    "read_channel",
    "read_schema",
]

MAGIC = b"\x89MCAP0\r\n"
#: Every record's frame: opcode, body length.
HEAD = struct.Struct("<BQ")
MESSAGE = struct.Struct("<HIQQ")
CHUNK = struct.Struct("<QQQI")
FOOTER = struct.Struct("<QQI")
_U16 = struct.Struct("<H")
U32 = struct.Struct("<I")
U64 = struct.Struct("<Q")
FOOTER_RECORD = HEAD.size + FOOTER.size
#: Opcodes MCAP defines (0x01-0x0F); 0x80 and above are private records, skipped.
KNOWN_OPCODES = frozenset(range(0x01, 0x10))
#: No sane chunk decompresses to more than this: a larger size is damage.
_MAX_CHUNK_BYTES = 1 << 30


class McapHeaderError(Exception):
    """The file is not MCAP, or its header cannot be read."""


class BadRecord(Exception):
    """A record does not parse or does not check."""


class Body:
    """Strict reading of one record's body: running short is an error.

    The body may lie in ``bytes`` (a chunk's records) or in a file read from disk as
    it is asked for (a record of the data section): a field is read when it is
    taken, so reading a chunk's header does not read its data."""

    def __init__(self, data: ByteSource, start: int = 0, end: int | None = None) -> None:
        self.data = data
        self.pos = start
        self.end = len(data) if end is None else end

    def take(self, n: int) -> bytes:
        """The next ``n`` bytes."""
        if n < 0 or self.pos + n > self.end:
            raise BadRecord("a field runs past the end of its record")
        value = self.data[self.pos : self.pos + n]
        self.pos += n
        return value

    def unpack(self, fmt: struct.Struct) -> tuple[int, ...]:
        """The next fields of layout ``fmt``."""
        if self.pos + fmt.size > self.end:
            raise BadRecord("a field runs past the end of its record")
        value = unpack_at(fmt, self.data, self.pos)
        self.pos += fmt.size
        return value

    def u16(self) -> int:
        """The next little-endian uint16."""
        return int(self.unpack(_U16)[0])

    def u32(self) -> int:
        """The next little-endian uint32."""
        return int(self.unpack(U32)[0])

    def u64(self) -> int:
        """The next little-endian uint64."""
        return int(self.unpack(U64)[0])

    def string(self) -> str:
        """The next length-prefixed UTF-8 string."""
        try:
            return bytes(self.take(self.u32())).decode("utf-8")
        except UnicodeDecodeError:
            raise BadRecord("a string is not UTF-8") from None

    def string_map(self) -> dict[str, str]:
        """The next length-prefixed map of strings to strings."""
        length = self.u32()
        end = self.pos + length
        if end > self.end:
            raise BadRecord("a map runs past the end of its record")
        out: dict[str, str] = {}
        while self.pos < end:
            key = self.string()
            out[key] = self.string()
        if self.pos != end:
            raise BadRecord("a map's entries overrun its length")
        return out


def read_schema(body: Body) -> tuple[int, tuple[str, str]]:
    """A schema record: its id, and its name and encoding (the schema data is skipped)."""
    schema_id = body.u16()
    name = body.string()
    encoding = body.string()
    body.take(body.u32())
    return schema_id, (name, encoding)


def read_channel(body: Body) -> tuple[int, tuple[str, int, str]]:
    """A channel record: its id, and its topic, schema id and message encoding."""
    channel_id = body.u16()
    schema_id = body.u16()
    topic = body.string()
    encoding = body.string()
    body.string_map()
    return channel_id, (topic, schema_id, encoding)


def add_definition(
    opcode: int,
    body: Body,
    schemas: dict[int, tuple[str, str]],
    channels: dict[int, tuple[str, int, str]],
) -> bool:
    """Read a schema record into ``schemas`` or a channel record into ``channels``;
    ``False`` (and nothing read) for any other record."""
    if opcode == Opcode.SCHEMA:
        key, schema = read_schema(body)
        schemas[key] = schema
    elif opcode == Opcode.CHANNEL:
        key, channel = read_channel(body)
        channels[key] = channel
    else:
        return False
    return True


def describe(exc: BaseException) -> str:
    """An exception as a problem's text: its message, else its type's name."""
    text = str(exc)
    return text if text else type(exc).__name__


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    if size > _MAX_CHUNK_BYTES:
        raise BadRecord(f"uncompressed size {size} bytes is not believable")
    if compression == "":
        return bytes(data)
    if compression == "zstd":
        import zstandard

        declared = zstandard.get_frame_parameters(bytes(data[:18])).content_size
        if declared not in (size, zstandard.CONTENTSIZE_UNKNOWN):
            raise BadRecord(f"zstd frame of {declared} bytes where the chunk says {size}")
        return bytes(zstandard.ZstdDecompressor().decompress(bytes(data), max_output_size=size))
    if compression == "lz4":
        import lz4.frame

        return bytes(lz4.frame.decompress(bytes(data)))
    raise BadRecord(f"unknown compression {compression!r}")


def chunk_records(body: Body) -> tuple[int, int, bytes]:
    """A chunk's time range and its records, uncompressed and checked."""
    start_ns, end_ns, size, crc = body.unpack(CHUNK)
    compression = body.string()
    length = body.u64()
    # Checked before the data is read, so that a damaged length does not read a long
    # stretch of the file only to refuse it; a length past the end is refused by take.
    if body.pos + length < body.end:
        raise BadRecord("the chunk's data does not fill its record")
    compressed = body.take(length)
    try:
        records = _decompress(compression, compressed, size)
    except BadRecord:
        raise
    except Exception as exc:  # any decoder's error: the compressed bytes are damaged
        raise BadRecord(f"{compression} data does not decompress ({describe(exc)})") from None
    if len(records) != size:
        raise BadRecord(f"decompresses to {len(records)} bytes, not {size}")
    if crc != 0 and zlib.crc32(records) != crc:
        raise BadRecord("CRC mismatch")
    return start_ns, end_ns, records
