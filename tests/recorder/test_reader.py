"""Reading logs back: whole, cut short at any point, damaged, or not ours at all."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from mcap.opcode import Opcode
from mcap.writer import Writer as McapWriter

from pipemap.errors import LogFormatError
from pipemap.recorder import METADATA_RESULT, METADATA_RUN, Integrity, Topic, read_log
from tests.logs import write_synthetic_log


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    path = tmp_path_factory.mktemp("logs") / "synthetic.mcap"
    return path, write_synthetic_log(path)


def test_a_whole_log_reads_back_in_order(synthetic: tuple[Path, list[str]]) -> None:
    path, topics = synthetic
    contents = read_log(path)
    assert contents.integrity is Integrity.OK and contents.problem == ""
    assert [m.topic for m in contents.messages] == topics
    assert contents.counts[Topic.RANGES] == topics.count(Topic.RANGES)
    assert contents.counts[Topic.IMU] == 0  # registered, never written
    assert contents.duration_ns == (len(topics) - 1) * 10_000_000
    assert contents.metadata[METADATA_RUN]["network"] == "synthetic"
    assert contents.metadata[METADATA_RESULT] == {"status": "finished"}
    sequences = [m.sequence for m in contents.messages if m.topic == Topic.TRUE_POSE]
    assert sequences == list(range(len(sequences)))


def test_the_same_messages_give_the_same_bytes(
    tmp_path: Path, synthetic: tuple[Path, list[str]]
) -> None:
    again = tmp_path / "again.mcap"
    write_synthetic_log(again)
    assert again.read_bytes() == synthetic[0].read_bytes()


def test_keep_filters_messages_but_counts_every_topic(synthetic: tuple[Path, list[str]]) -> None:
    contents = read_log(synthetic[0], keep=lambda topic: topic == Topic.IMAGE)
    assert {m.topic for m in contents.messages} == {Topic.IMAGE}
    assert sum(contents.counts.values()) == len(synthetic[1])


@pytest.mark.parametrize("fraction", [0.05, 0.2, 0.35, 0.5, 0.65, 0.8, 0.95, 0.999])
def test_a_log_cut_short_is_read_up_to_its_last_complete_record(
    tmp_path: Path, synthetic: tuple[Path, list[str]], fraction: float
) -> None:
    data = synthetic[0].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * fraction)])
    contents = read_log(cut)
    assert contents.integrity is Integrity.TRUNCATED, contents.problem
    whole = read_log(synthetic[0]).messages
    recovered = contents.messages
    # What was recovered is exactly the start of what was written.
    assert recovered == whole[: len(recovered)]
    if fraction >= 0.35:
        assert len(recovered) > 0
    # The summary sits at the end: cutting it off loses no message.
    if fraction == 0.999:
        assert len(recovered) == len(whole)


def test_more_of_a_cut_log_gives_more_messages(
    tmp_path: Path, synthetic: tuple[Path, list[str]]
) -> None:
    data = synthetic[0].read_bytes()
    counts = []
    for fraction in (0.2, 0.4, 0.6, 0.8):
        cut = tmp_path / f"cut{fraction}.mcap"
        cut.write_bytes(data[: int(len(data) * fraction)])
        counts.append(len(read_log(cut).messages))
    assert counts == sorted(counts) and counts[0] < counts[-1]


def test_every_bit_flip_after_the_header_is_caught(
    tmp_path: Path, synthetic: tuple[Path, list[str]]
) -> None:
    data = synthetic[0].read_bytes()
    header_end = 8 + 9 + int.from_bytes(data[9:17], "little")
    damaged = tmp_path / "flipped.mcap"
    positions = range(header_end, len(data) - 8, max(1, (len(data) - header_end) // 97))
    missed = []
    for position in positions:
        flipped = bytearray(data)
        flipped[position] ^= 0x10
        damaged.write_bytes(bytes(flipped))
        contents = read_log(damaged)
        if contents.integrity is not Integrity.CORRUPT:
            missed.append((position, contents.integrity))
    assert missed == []


def test_a_corrupt_log_keeps_what_came_before_the_damage(
    tmp_path: Path, synthetic: tuple[Path, list[str]]
) -> None:
    data = bytearray(synthetic[0].read_bytes())
    chunks = []  # (start, end) of each chunk record's body
    position = 8
    while position < len(data) - 8:
        opcode, length = struct.unpack_from("<BQ", data, position)
        if opcode == Opcode.CHUNK:
            chunks.append((position + 9, position + 9 + length))
        if opcode == Opcode.FOOTER:
            break
        position += 9 + length
    start, end = chunks[len(chunks) // 2]
    data[(start + end) // 2] ^= 0xFF  # inside a chunk's compressed messages
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    contents = read_log(damaged)
    assert contents.integrity is Integrity.CORRUPT
    whole = read_log(synthetic[0]).messages
    assert 0 < len(contents.messages) < len(whole)
    assert contents.messages == whole[: len(contents.messages)]
    assert "byte" in contents.problem


@pytest.mark.parametrize(
    "content,message",
    [
        (b"", "empty file"),
        (b"this is not a log at all, just text\n" * 20, "not an MCAP file"),
        (b"\x89MCAP0\r\n", "cut short before its header"),
    ],
)
def test_garbage_is_refused(tmp_path: Path, content: bytes, message: str) -> None:
    path = tmp_path / "bad.mcap"
    path.write_bytes(content)
    with pytest.raises(LogFormatError, match=message):
        read_log(path)


def test_another_programs_mcap_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "other.mcap"
    with path.open("wb") as f:
        writer = McapWriter(f)
        writer.start(profile="", library="someone-else 1.0")
        writer.finish()
    with pytest.raises(LogFormatError, match="written by someone-else 1.0, not a pipemap log"):
        read_log(path)


def test_missing_file_and_folder_are_refused(tmp_path: Path) -> None:
    with pytest.raises(LogFormatError, match="no such file"):
        read_log(tmp_path / "nothing.mcap")
    with pytest.raises(LogFormatError, match="is a folder"):
        read_log(tmp_path)
