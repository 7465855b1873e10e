"""Reading logs back: whole, cut short at any point, damaged, or not ours at all."""

from __future__ import annotations

import struct
import tracemalloc
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


def _chunks(data: bytes | bytearray) -> list[tuple[int, int]]:
    """(start, end) of each chunk record's body, in file order."""
    chunks = []
    position = 8
    while position < len(data) - 8:
        opcode, length = struct.unpack_from("<BQ", data, position)
        if opcode == Opcode.CHUNK:
            chunks.append((position + 9, position + 9 + length))
        if opcode == Opcode.FOOTER:
            break
        position += 9 + length
    return chunks


@pytest.mark.parametrize("where", ["data", "length"])
def test_a_damaged_chunk_loses_only_itself_and_says_what_it_held(
    tmp_path: Path, synthetic: tuple[Path, list[str]], where: str
) -> None:
    data = bytearray(synthetic[0].read_bytes())
    chunks = _chunks(data)
    number = len(chunks) // 2
    start, end = chunks[number]
    if where == "data":
        data[(start + end) // 2] ^= 0xFF  # inside the chunk's compressed messages
    else:
        data[start - 8 + 5] ^= 0x40  # the chunk record's own length: the framing is lost
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    contents = read_log(damaged)
    assert contents.integrity is Integrity.CORRUPT
    whole = read_log(synthetic[0]).messages
    [damage] = [d for d in contents.damage if d.chunk is not None]
    assert (damage.chunk, damage.chunks) == (number + 1, len(chunks))
    assert f"chunk {number + 1} of {len(chunks)}" in contents.problem
    # Exactly the chunk's messages are missing, in one stretch; it says how many per topic.
    kept = contents.messages
    lost = len(whole) - len(kept)
    assert lost == sum(damage.lost.values()) > 0
    first = next(i for i, (a, b) in enumerate(zip(whole, kept, strict=False)) if a != b)
    assert kept == whole[:first] + whole[first + lost :]
    missing = whole[first : first + lost]
    assert damage.start_ns == missing[0].log_time_ns and damage.end_ns == missing[-1].log_time_ns
    assert {t: sum(m.topic == t for m in missing) for t in damage.lost} == damage.lost


@pytest.mark.parametrize("missing", [1, 8])
def test_a_log_missing_its_last_bytes_is_truncated_not_corrupt(
    tmp_path: Path, synthetic: tuple[Path, list[str]], missing: int
) -> None:
    data = synthetic[0].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:-missing])
    contents = read_log(cut)
    assert contents.integrity is Integrity.TRUNCATED, contents.problem
    assert "closing magic" in contents.problem
    assert contents.messages == read_log(synthetic[0]).messages


@pytest.mark.parametrize(
    "content,message",
    [
        (b"", "empty file"),
        (b"this is not a log at all, just text\n" * 20, "not an MCAP file"),
        (b"\x89MCAP0\r\n", "cut short before its header"),
        (b"\x89MCA", "cut short inside its magic"),
        (
            b"\x89MCAP0\r\n\x01\x05\x00\x00\x00\x00\x00\x00\x00\xff\xff\xff\xff\xff",
            "MCAP header is malformed: a field runs past the end of its record",
        ),
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
    with pytest.raises(
        LogFormatError,
        match=r"not a pipemap log: no pipemap.run metadata \(an MCAP file written by someone-else",
    ):
        read_log(path)


def test_missing_file_and_folder_are_refused(tmp_path: Path) -> None:
    with pytest.raises(LogFormatError, match="no such file"):
        read_log(tmp_path / "nothing.mcap")
    with pytest.raises(LogFormatError, match="is a folder"):
        read_log(tmp_path)


def test_reading_holds_what_it_keeps_not_the_file(tmp_path: Path) -> None:
    """The file is read a piece at a time, never whole: a read that keeps nothing of a
    log of images holds a small part of its size."""
    path = tmp_path / "long.mcap"
    write_synthetic_log(path, messages=6000, image_px=96)
    size = path.stat().st_size
    read_log(path, keep=lambda _topic: False)  # the decompressors imported before measuring
    tracemalloc.start()
    try:
        contents = read_log(path, keep=lambda _topic: False)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert contents.integrity is Integrity.OK and contents.counts[Topic.IMAGE] == 120
    assert peak < 0.2 * size, f"peak {peak} bytes for a {size}-byte file"
