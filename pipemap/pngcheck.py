"""Whether PNG bytes are whole: shared by the log reader and the image-set reader.

libpng prints its own complaints about a damaged image to the process's standard
error, where they would leak past pipemap's one-line errors; checking the chunks and
their CRCs first lets each reader name the problem itself. Standard library only, so
that every layer may use it.
"""

from __future__ import annotations

import struct
import zlib

__all__ = ["MAX_IMAGE_SIDE_PX", "PNG_SIGNATURE", "image_size", "png_problem"]

#: The largest width or height of an image pipemap decodes (the simulator's largest
#: camera resolution): a header that claims more is refused before any decoding, so
#: that a small file cannot ask for gigabytes (an image bomb).
MAX_IMAGE_SIDE_PX = 4096

#: The eight bytes every PNG file starts with.
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_CHUNK = struct.Struct(">I4s")


def png_problem(data: bytes) -> str:
    """What is wrong with PNG bytes ("" when nothing is): every chunk must be whole,
    its CRC must match, and the image must end in IEND. libpng prints its own
    complaints to the process's standard error, so damage is caught here first."""
    if not data.startswith(PNG_SIGNATURE):
        return "not a PNG image" if data else "an empty image"
    position = len(PNG_SIGNATURE)
    while position + _PNG_CHUNK.size <= len(data):
        length, kind = _PNG_CHUNK.unpack_from(data, position)
        end = position + _PNG_CHUNK.size + length + 4
        if end > len(data):
            return "a truncated PNG image"
        (crc,) = struct.unpack_from(">I", data, end - 4)
        if zlib.crc32(data[position + 4 : end - 4]) != crc:
            return f"a corrupt PNG image (CRC mismatch in its {kind!r} chunk)"
        if kind == b"IEND":
            return ""
        position = end
    return "a truncated PNG image"


#: JPEG start-of-frame markers (SOF0..SOF15 but DHT, JPG and DAC), which hold the size.
_JPEG_FRAMES = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


def image_size(data: bytes) -> tuple[int, int] | None:
    """The (width, height) a PNG's or JPEG's header claims, read without decoding;
    ``None`` when the header does not say (another format, or damaged)."""
    if data.startswith(PNG_SIGNATURE) and data[12:16] == b"IHDR" and len(data) >= 24:
        width, height = struct.unpack_from(">II", data, 16)
        return int(width), int(height)
    if not data.startswith(b"\xff\xd8"):
        return None
    position = 2
    while position + 4 <= len(data):
        if data[position] != 0xFF:
            return None
        marker = data[position + 1]
        if marker == 0xFF:  # fill byte
            position += 1
            continue
        (length,) = struct.unpack_from(">H", data, position + 2)
        if marker in _JPEG_FRAMES:
            if position + 9 > len(data):
                return None
            height, width = struct.unpack_from(">HH", data, position + 5)
            return int(width), int(height)
        position += 2 + length
    return None
