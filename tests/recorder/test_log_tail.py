"""Damage at a log's end is named for what it is: a closing magic that is damaged
(the file is whole: corrupt, not cut short), bytes appended after the closing magic
(longer, not shorter), and a file that really stops inside its magic (truncated).
Every message is read in each case.
"""

from __future__ import annotations

from pathlib import Path

from pipemap.recorder import Integrity, read_log
from tests.logs import write_synthetic_log


def _whole(tmp_path: Path) -> tuple[Path, bytes, int]:
    path = tmp_path / "whole.mcap"
    topics = write_synthetic_log(path)
    return path, path.read_bytes(), len(topics)


def test_a_damaged_closing_magic_is_corrupt_not_truncated(tmp_path: Path) -> None:
    path, data, messages = _whole(tmp_path)
    damaged = bytearray(data)
    damaged[-3] ^= 0x40
    path.write_bytes(bytes(damaged))
    contents = read_log(path)
    assert contents.integrity is Integrity.CORRUPT
    assert not contents.truncated
    assert "the closing magic is damaged" in contents.problem
    assert sum(contents.counts.values()) == messages


def test_bytes_after_the_end_are_named_and_nothing_is_lost(tmp_path: Path) -> None:
    path, data, messages = _whole(tmp_path)
    path.write_bytes(data + b"appended by another program")
    contents = read_log(path)
    assert contents.integrity is Integrity.CORRUPT
    assert not contents.truncated
    assert f"27 byte(s) after the log's end (its closing magic ends at byte {len(data)})" in (
        contents.problem
    )
    assert "cut" not in contents.problem
    assert sum(contents.counts.values()) == messages


def test_a_log_cut_inside_its_closing_magic_is_still_truncated(tmp_path: Path) -> None:
    path, data, messages = _whole(tmp_path)
    path.write_bytes(data[:-3])
    contents = read_log(path)
    assert contents.integrity is Integrity.TRUNCATED
    assert "3 byte(s) short of its closing magic" in contents.truncated
    assert sum(contents.counts.values()) == messages
