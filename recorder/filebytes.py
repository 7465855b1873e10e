"""A file's bytes read from disk only as they are asked for, so that a walk through a
log of several gigabytes holds about one chunk of it at a time, not the file.

:class:`FileBytes` does what the walk of :mod:`recorder.mcapfile` does with the
``bytes`` of a file, and nothing more: its length, a slice (read with ``os.pread``,
so no file position is shared), one byte, and ``find``. The walk is also handed
real ``bytes`` (a chunk's records once decompressed, or a whole file in a test):
:func:`unpack_at` and :func:`crc32_between` take either, and keep the direct way for
``bytes``.
"""

from __future__ import annotations

import errno
import operator
import os
import struct
import zlib
from typing import Any, Protocol, SupportsIndex, overload

__all__ = ["ByteSource", "FileBytes", "crc32_between", "unpack_at"]

#: How much is read at a time to check a CRC over a stretch of the file: less than a
#: chunk of a pipemap log, so that the check does not raise the peak of a streamed read.
CRC_BLOCK = 1 << 18
#: How much is read ahead for a small read or a search, and kept: record headers
#: and fields lie close together, and a resync looks for the next chunk's opcode
#: many times over, finding it within a few hundred bytes.
_BLOCK = 1 << 16
#: A read up to this size is served from the block read ahead.
_SMALL_READ = 1 << 12


class ByteSource(Protocol):
    """What the walk reads a file through: ``bytes`` or a :class:`FileBytes`."""

    def __len__(self) -> int: ...

    @overload
    def __getitem__(self, key: SupportsIndex, /) -> int: ...

    @overload
    def __getitem__(self, key: slice, /) -> bytes: ...

    def find(self, sub: bytes, start: SupportsIndex, /) -> int: ...


class _OpenFile(Protocol):
    def fileno(self) -> int: ...


class FileBytes:
    """The bytes of an open file, read as they are asked for.

    The length is the file's when this is made. The file is closed by its owner,
    not here; once it is, reading raises ``ValueError`` (its descriptor is asked for
    at every read, so a number the system has since given to another file is never
    read).
    """

    def __init__(self, file: _OpenFile) -> None:
        self._file = file
        self._size = os.fstat(file.fileno()).st_size
        # The block last read ahead, for small reads and searches.
        self._block_start = 0
        self._block = b""

    def __len__(self) -> int:
        return self._size

    @overload
    def __getitem__(self, key: SupportsIndex, /) -> int: ...

    @overload
    def __getitem__(self, key: slice, /) -> bytes: ...

    def __getitem__(self, key: SupportsIndex | slice, /) -> int | bytes:
        if isinstance(key, slice):
            start, stop, step = key.indices(self._size)
            if step != 1:
                raise ValueError("only contiguous slices of a file are read")
            if stop <= start:
                return b""
            if stop - start > _SMALL_READ:
                return self._read(start, stop - start)
            if not self._block_start <= start <= stop <= self._block_start + len(self._block):
                self._block_start = start
                self._block = self._read(start, _BLOCK)
            return self._block[start - self._block_start : stop - self._block_start]
        index = operator.index(key)
        if index < 0:
            index += self._size
        if not 0 <= index < self._size:
            raise IndexError("index out of range")
        return self[index : index + 1][0]

    def find(self, sub: bytes, start: SupportsIndex, /) -> int:
        """Where ``sub`` first occurs at or after ``start``, or -1 (as ``bytes.find``)."""
        position = slice(start, None).indices(self._size)[0]
        if operator.index(start) > self._size:
            return -1
        if not sub:
            return position
        while True:
            block_end = self._block_start + len(self._block)
            if not self._block_start <= position <= block_end - len(sub):
                if position + len(sub) > self._size:
                    return -1
                self._block_start = position
                self._block = self._read(position, max(_BLOCK, len(sub)))
                block_end = position + len(self._block)
            found = self._block.find(sub, position - self._block_start)
            if found != -1:
                return self._block_start + found
            if block_end >= self._size:
                return -1
            # The next block overlaps this one: ``sub`` may straddle the two.
            position = block_end - len(sub) + 1

    def crc32(self, start: int, end: int) -> int:
        """The CRC-32 of the file's bytes from ``start`` up to ``end``, read a block at
        a time."""
        crc = 0
        position = start
        while position < end:
            block = self._read(position, min(CRC_BLOCK, end - position))
            if not block:
                break
            crc = zlib.crc32(block, crc)
            position += len(block)
            del block  # before the next block is read, not after: one block held, not two
        return crc

    def _read(self, offset: int, size: int) -> bytes:
        fd = self._file.fileno()
        data = os.pread(fd, size, offset)
        if len(data) < size:
            # A read may return less than asked (a signal, a very large read): go on.
            parts = [data]
            got = len(data)
            while got < size:
                more = os.pread(fd, size - got, offset + got)
                if not more:
                    break
                parts.append(more)
                got += len(more)
            data = b"".join(parts)
        if len(data) < min(size, self._size - offset):
            # Bytes the file had when it was opened are gone: another program cut it
            # (a recorder started again over it, say). What was read may not be what
            # the rest of the file says, so the reading stops here.
            raise OSError(errno.EIO, "the file was cut shorter while it was being read")
        return data


def unpack_at(layout: struct.Struct, data: ByteSource, position: int) -> tuple[Any, ...]:
    """The fields of ``layout`` at byte ``position`` of ``data``; raises
    :class:`struct.error` where they run past its end."""
    if isinstance(data, bytes):
        return layout.unpack_from(data, position)
    if position < 0:
        raise struct.error(f"offset {position} out of range")
    return layout.unpack(data[position : position + layout.size])


def crc32_between(data: ByteSource, start: int, end: int) -> int:
    """The CRC-32 of ``data`` from byte ``start`` up to ``end``, never copied whole: on a
    view of ``bytes``, or read from a file a block at a time."""
    if isinstance(data, FileBytes):
        return data.crc32(start, end)
    if isinstance(data, bytes):
        return zlib.crc32(memoryview(data)[start:end])
    return zlib.crc32(data[start:end])
