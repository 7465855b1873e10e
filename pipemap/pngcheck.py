"""Whether PNG bytes are whole: shared by the log reader and the image-set reader.

libpng prints its own complaints about a damaged image to the process's standard
error, where they would leak past pipemap's one-line errors; checking the chunks and
their CRCs first lets each reader name the problem itself. Standard library only, so
that every layer may use it.
"""

from __future__ import annotations

import struct
import zlib

__all__ = ["PNG_SIGNATURE", "png_problem"]

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
