"""``pipemap.wholefile``: a file replaced only when whole, and a device or a FIFO
given as the output written in place, never replaced by a regular file."""

from __future__ import annotations

import os
import stat
import threading
from pathlib import Path

from pipemap.wholefile import write_whole


def test_a_file_is_replaced_when_whole_and_nothing_is_left_beside_it(tmp_path: Path) -> None:
    target = tmp_path / "map.json"
    target.write_text("earlier")
    write_whole(target, "later")
    assert target.read_text() == "later"
    assert [p.name for p in tmp_path.iterdir()] == ["map.json"]


def test_a_fifo_as_the_output_is_written_in_place(tmp_path: Path) -> None:
    fifo = tmp_path / "out"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    write_whole(fifo, "through the pipe")
    reader.join(timeout=30)
    assert got == [b"through the pipe"]
    assert stat.S_ISFIFO(fifo.stat().st_mode)  # still a FIFO, not a file of its name
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_dev_null_stays_a_device() -> None:
    write_whole("/dev/null", "nothing")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
