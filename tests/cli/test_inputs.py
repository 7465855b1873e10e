"""Inputs that could block or mislead are refused at once, in one line: a FIFO, a
device or a pipe given as a log (``/dev/stdin``), and an image whose header claims
more pixels than pipemap decodes (an image bomb), checked before any decoding.
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipemap.pngcheck import MAX_IMAGE_SIDE_PX, image_size
from tests.conftest import PAPER_SETS


def _pipemap(*args: str, **kwargs: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args],
        capture_output=True,
        text=True,
        timeout=60,  # a FIFO without a writer would block open() for ever
        **kwargs,  # type: ignore[arg-type]
    )


@pytest.mark.parametrize("command", ["info", "replay", "score", "view"])
def test_a_fifo_as_the_log_is_refused_at_once(command: str, tmp_path: Path) -> None:
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    extra = ["--save", str(tmp_path / "v.rrd")] if command == "view" else []
    done = _pipemap(command, str(fifo), *extra)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [
        f"pipemap: error: {fifo}: is a pipe, not a log file; pipemap reads a log from a "
        "file (save the stream to a file first)"
    ]


def test_a_log_piped_on_standard_input_is_not_called_empty() -> None:
    done = _pipemap("info", "/dev/stdin", input="MCAP bytes would be here")
    assert done.returncode == 2, done.stderr
    assert "/dev/stdin: is a pipe, not a log file" in done.stderr
    assert "empty" not in done.stderr


def test_a_device_as_the_log_is_refused() -> None:
    done = _pipemap("replay", "/dev/null")
    assert done.returncode == 2, done.stderr
    assert "/dev/null: is a device, not a log file" in done.stderr


def _png_claiming(width: int, height: int) -> bytes:
    """A PNG of whole chunks with good CRCs whose header claims ``width`` x ``height``
    gray pixels, with one row of data: small on disk, huge once decoded."""

    def chunk(kind: bytes, body: bytes) -> bytes:
        return (
            struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
        )

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(b"\0" * (width + 1)))
        + chunk(b"IEND", b"")
    )


def _jpeg_claiming(width: int, height: int) -> bytes:
    """The start of a JPEG whose frame header claims ``width`` x ``height`` pixels."""
    frame = struct.pack(">BHHB", 8, height, width, 1) + bytes([1, 0x11, 0])
    return b"\xff\xd8" + b"\xff\xc0" + struct.pack(">H", len(frame) + 2) + frame + b"\xff\xd9"


def test_image_sizes_are_read_from_the_header() -> None:
    assert image_size(_png_claiming(100_000, 100_000)) == (100_000, 100_000)
    assert image_size(_jpeg_claiming(60_000, 50_000)) == (60_000, 50_000)
    done, png = cv2.imencode(".png", np.zeros((7, 5), np.uint8))
    assert done and image_size(png.tobytes()) == (5, 7)
    assert image_size(b"GIF89a") is None


@pytest.mark.parametrize("command", ["match", "map"])
@pytest.mark.parametrize(
    ("name", "data"),
    [
        ("camera_image1.png", _png_claiming(100_000, 100_000)),
        ("camera_image1.jpg", _jpeg_claiming(60_000, 60_000)),
        ("camera_image1.png", _png_claiming(MAX_IMAGE_SIDE_PX + 1, 1)),
    ],
    ids=["png-bomb", "jpeg-bomb", "one-past-the-limit"],
)
def test_an_image_bomb_is_refused_before_decoding(
    command: str, name: str, data: bytes, tmp_path: Path
) -> None:
    bomb = tmp_path / "bomb"
    bomb.mkdir()
    (bomb / name).write_bytes(data)
    done = _pipemap(command, str(PAPER_SETS / "1"), str(bomb))
    assert done.returncode == 2, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"pipemap: error: {bomb / name}: an image of ")
    assert f"at most {MAX_IMAGE_SIDE_PX} pixels a side" in lines[0]
