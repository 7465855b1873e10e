"""A file read from disk as it is asked for gives exactly what its bytes give."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from pipemap.recorder.filebytes import FileBytes, crc32_between, unpack_at

#: Larger than the block read ahead (64 KiB), so reads and searches cross blocks.
SIZE = 200_000


@pytest.fixture(scope="module")
def content(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, bytes]:
    data = np.random.default_rng(11).integers(0, 256, SIZE, dtype=np.uint8).tobytes()
    path = tmp_path_factory.mktemp("filebytes") / "noise.bin"
    path.write_bytes(data)
    return path, data


def test_slices_and_bytes_are_the_file_s(content: tuple[Path, bytes]) -> None:
    path, data = content
    rng = np.random.default_rng(1)
    with path.open("rb") as f:
        view = FileBytes(f)
        assert len(view) == len(data)
        for _ in range(2000):
            start = int(rng.integers(-SIZE - 10, SIZE + 10))
            stop = start + int(rng.choice([0, 1, 9, 100, 5000, 70_000, 300_000]))
            assert view[start:stop] == data[start:stop], (start, stop)
            index = int(rng.integers(-SIZE, SIZE))
            assert view[index] == data[index]
        assert view[:] == data and view[-8:] == data[-8:] and view[SIZE:] == b""
        with pytest.raises(IndexError):
            view[SIZE]


def test_find_finds_what_bytes_find_finds(content: tuple[Path, bytes]) -> None:
    path, data = content
    rng = np.random.default_rng(2)
    with path.open("rb") as f:
        view = FileBytes(f)
        for sub in (b"\x06", data[65_530:65_540], data[-3:], b"\x00\x01\x02\x03\x04\x05"):
            for start in [0, 1, 65_535, 65_536, SIZE - 2, SIZE, SIZE + 5, -10, -SIZE - 5]:
                assert view.find(sub, start) == data.find(sub, start), (sub, start)
        # A resync asks again and again for the next byte after the last one found.
        position = view.find(b"\x06", 0)
        expected = data.find(b"\x06", 0)
        while expected != -1:
            assert position == expected
            position, expected = view.find(b"\x06", position + 1), data.find(b"\x06", expected + 1)
        assert position == -1
        for _ in range(200):
            start = int(rng.integers(0, SIZE))
            assert view.find(b"\xff\xfe", start) == data.find(b"\xff\xfe", start)


def test_crc_and_fields_are_those_of_the_bytes(content: tuple[Path, bytes]) -> None:
    path, data = content
    head = struct.Struct("<BQ")
    with path.open("rb") as f:
        view = FileBytes(f)
        for start, end in [(0, SIZE), (0, 0), (5, 1 << 18), (1000, (1 << 18) + 1), (7, 8)]:
            assert crc32_between(view, start, end) == zlib.crc32(data[start:end])
            assert crc32_between(data, start, end) == zlib.crc32(data[start:end])
        for position in (0, 65_530, SIZE - 9):
            assert unpack_at(head, view, position) == head.unpack_from(data, position)
        for source in (view, data):
            with pytest.raises(struct.error):
                unpack_at(head, source, SIZE - 8)
            with pytest.raises(struct.error):
                unpack_at(head, source, -1)


def test_a_closed_file_is_not_read(content: tuple[Path, bytes]) -> None:
    path, _ = content
    with path.open("rb") as f:
        view = FileBytes(f)
    with pytest.raises(ValueError):
        view[100_000:100_010]


def test_bytes_gone_since_the_file_was_opened_stop_the_reading(tmp_path: Path) -> None:
    """Another program cuts the file while it is read: what is left may not be what
    the rest of the file says, so a read of bytes it had is refused, not cut short."""
    path = tmp_path / "cut.bin"
    path.write_bytes(bytes(range(256)) * 1000)
    with path.open("rb") as f:
        view = FileBytes(f)
        assert view[100:200] == bytes(range(100, 200))
        path.write_bytes(b"")  # truncated in place, as another program would
        with pytest.raises(OSError, match="cut shorter while it was being read"):
            view[150_000:150_100]
        with pytest.raises(OSError, match="cut shorter"):
            crc32_between(view, 0, len(view))
