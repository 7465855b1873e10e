"""Reading a log as a stream: ``iter_log`` hands out the messages ``read_log`` keeps,
in the same order, and ends with the same contents, for every log, whole, cut short or
damaged; it refuses what ``read_log`` refuses, with the same message, before it hands
out a message; and it holds a small part of the file, not the file."""

from __future__ import annotations

import dataclasses
import struct
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import pytest
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from pipemap.errors import LogFormatError
from pipemap.recorder import (
    METADATA_RESULT,
    METADATA_RUN,
    LogContents,
    LogWriter,
    Topic,
    iter_log,
    read_log,
    schemas,
)
from pipemap.recorder.mcapfile import FileBytes, Walk, scan
from tests.logs import write_synthetic_log

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"
STORED = sorted(RECORDINGS.glob("*.mcap"))
Keep = Callable[[str], bool] | None


def streamed(path: Path, keep: Keep = None) -> LogContents:
    """What ``iter_log`` gives, put as ``read_log`` gives it: its contents at the end,
    with the messages it handed out."""
    with iter_log(path, keep) as stream:
        messages = list(stream)
        assert stream.closed  # at the end of the log, not only when the block ends
    assert stream.contents.messages == []
    return dataclasses.replace(stream.contents, messages=messages)


def outcome(read: Callable[[Path, Keep], LogContents], path: Path, keep: Keep) -> object:
    try:
        return read(path, keep)
    except LogFormatError as exc:
        return f"LogFormatError: {exc}"


def assert_streams_as_read(path: Path, keep: Keep = None) -> None:
    expected = outcome(read_log, path, keep)
    got = outcome(streamed, path, keep)
    assert got == expected
    if isinstance(expected, LogContents) and isinstance(got, LogContents):
        # In the same order too: ``pipemap info`` prints them in it.
        assert list(got.counts) == list(expected.counts)
        assert list(got.metadata) == list(expected.metadata)


def _starts(data: bytes, kind: int) -> list[int]:
    """Where each record of opcode ``kind`` starts in the data section, in file order."""
    starts, position = [], 8
    while position < len(data) - 8:
        opcode, length = struct.unpack_from("<BQ", data, position)
        if opcode == kind:
            starts.append(position)
        if opcode in (Opcode.DATA_END, Opcode.FOOTER):
            break
        position += 9 + length
    return starts


def _flipped(at: float, bit: int = 0x10) -> Callable[[bytes], bytes]:
    def damage(data: bytes) -> bytes:
        out = bytearray(data)
        out[min(int(len(data) * at), len(data) - 1)] ^= bit
        return bytes(out)

    return damage


def _cut(at: float) -> Callable[[bytes], bytes]:
    return lambda data: data[: int(len(data) * at)]


def _in_chunk(where: str, summary: bool) -> Callable[[bytes], bytes]:
    """The middle chunk damaged in its compressed data or its record length, and the
    summary (the index the walk resumes by) kept or cut off."""

    def damage(data: bytes) -> bytes:
        starts = _starts(data, Opcode.CHUNK)
        start = starts[len(starts) // 2]
        out = bytearray(data)
        if where == "data":
            out[start + 200] ^= 0x01
        else:
            out[start + 1 + 4] ^= 0x40  # the record's length: the framing is lost
        return bytes(out) if summary else bytes(out[:-100])

    return damage


def _in_run_metadata(summary: bool) -> Callable[[bytes], bytes]:
    """A byte of the run metadata's values changed, so that the record no longer
    parses, and the summary (which names the record) kept or cut off."""

    def damage(data: bytes) -> bytes:
        start = _starts(data, Opcode.METADATA)[0]
        out = bytearray(data)
        out[start + 9 + 4 + len(METADATA_RUN)] ^= 0x80  # the length of its map of values
        return bytes(out) if summary else bytes(out[:-100])

    return damage


def _zeroed(at: float, length: int) -> Callable[[bytes], bytes]:
    def damage(data: bytes) -> bytes:
        start = int(len(data) * at)
        return data[:start] + bytes(len(data[start : start + length])) + data[start + length :]

    return damage


#: Every way the reader tests damage a log, and more: a bit flipped all along the file
#: (header, metadata, chunks, indexes, summary, footer, magic), cuts from inside the
#: header to the last byte, a damaged chunk with and without the summary, zeroed bytes.
DAMAGE: dict[str, Callable[[bytes], bytes]] = {
    "whole": lambda data: data,
    **{f"flip-{i}": _flipped(i / 61) for i in range(61)},
    **{f"flip-low-bit-{i}": _flipped(i / 13 + 0.01, 0x01) for i in range(13)},
    **{
        f"cut-{at}": _cut(at)
        for at in (0, 0.0002, 0.001, 0.003, 0.01, 0.03, 0.05, 0.2, 0.35, 0.5, 0.65, 0.8)
    },
    **{f"cut-{at}": _cut(at) for at in (0.95, 0.98, 0.99, 0.995, 0.999)},
    "missing-last-byte": lambda data: data[:-1],
    "missing-magic": lambda data: data[:-8],
    "summary-cut-off": lambda data: data[:-100],
    "chunk-data": _in_chunk("data", summary=True),
    "chunk-length": _in_chunk("length", summary=True),
    "chunk-data-no-summary": _in_chunk("data", summary=False),
    "chunk-length-no-summary": _in_chunk("length", summary=False),
    "run-metadata": _in_run_metadata(summary=True),
    "run-metadata-no-summary": _in_run_metadata(summary=False),
    "zeroed-early": _zeroed(0.02, 300),
    "zeroed-middle": _zeroed(0.5, 3000),
    "zeroed-summary": _zeroed(0.97, 500),
}


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    path = tmp_path_factory.mktemp("logs") / "synthetic.mcap"
    write_synthetic_log(path)
    return path.read_bytes()


@pytest.mark.parametrize("name", sorted(DAMAGE))
def test_a_damaged_log_streams_as_it_reads(tmp_path: Path, synthetic: bytes, name: str) -> None:
    path = tmp_path / f"{name}.mcap"
    path.write_bytes(DAMAGE[name](synthetic))
    assert_streams_as_read(path)
    assert_streams_as_read(path, keep=lambda topic: topic == Topic.IMAGE)


@pytest.mark.parametrize("stored", STORED, ids=[p.stem for p in STORED])
def test_a_stored_recording_streams_as_it_reads(stored: Path) -> None:
    assert_streams_as_read(stored)
    assert_streams_as_read(stored, keep=lambda topic: topic.startswith("/robot/camera"))


@pytest.mark.parametrize(
    "name", ["chunk-data", "chunk-data-no-summary", "chunk-length-no-summary", "cut-0.5"]
)
def test_a_damaged_recording_streams_as_it_reads(tmp_path: Path, name: str) -> None:
    path = tmp_path / "damaged.mcap"
    path.write_bytes(DAMAGE[name]((RECORDINGS / "paper_autonomous.mcap").read_bytes()))
    assert_streams_as_read(path)


def _rewrite(source: Path, target: Path, **options: object) -> None:
    """``source`` as the ``mcap`` library's writer writes it, with ``options``."""
    with source.open("rb") as f_in, target.open("wb") as f_out:
        reader = make_reader(f_in)
        writer = McapWriter(f_out, **options)  # type: ignore[arg-type]
        writer.start(profile="", library="a rewriter")
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, record.metadata)
        summary = reader.get_summary()
        assert summary is not None
        ids = {}
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            schema_id = writer.register_schema(schema.name, schema.encoding, schema.data)
            ids[channel.id] = writer.register_channel(
                channel.topic, channel.message_encoding, schema_id
            )
        for _, channel, message in reader.iter_messages(log_time_order=False):
            writer.add_message(
                ids[channel.id], message.log_time, message.data, message.publish_time
            )
        writer.finish()


@pytest.mark.parametrize(
    "options",
    [
        {"use_chunking": False},
        {"enable_crcs": False, "compression": CompressionType.NONE},
        {"chunk_size": 2048, "compression": CompressionType.LZ4},
    ],
    ids=["unchunked", "no-crcs", "lz4"],
)
@pytest.mark.parametrize("name", ["whole", "flip-20", "flip-40", "cut-0.5", "summary-cut-off"])
def test_a_log_rewritten_by_another_writer_streams_as_it_reads(
    tmp_path: Path, synthetic: bytes, options: dict[str, object], name: str
) -> None:
    original, copy = tmp_path / "original.mcap", tmp_path / "copy.mcap"
    original.write_bytes(synthetic)
    _rewrite(original, copy, **options)
    copy.write_bytes(DAMAGE[name](copy.read_bytes()))
    assert_streams_as_read(copy)


@pytest.mark.parametrize("name", ["whole", "flip-30", "chunk-length-no-summary", "cut-0.65"])
def test_a_walk_through_the_file_is_the_scan_of_its_bytes(
    tmp_path: Path, synthetic: bytes, name: str
) -> None:
    data = DAMAGE[name](synthetic)
    path = tmp_path / "log.mcap"
    path.write_bytes(data)
    handed: list[tuple[str, int, int, bytes]] = []
    found, tail = scan(data, lambda *message: handed.append(message))
    with path.open("rb") as f:
        walk = Walk(FileBytes(f))
        assert not walk.done
        walked = list(walk)
        assert walk.done
        with pytest.raises(RuntimeError):
            list(walk)
    assert walked == handed and walk.scan == found and walk.tail == tail


def test_the_run_metadata_is_there_before_the_first_message(tmp_path: Path) -> None:
    path = tmp_path / "log.mcap"
    write_synthetic_log(path)
    with iter_log(path) as stream:
        messages = iter(stream)
        next(messages)
        assert stream.contents.metadata[METADATA_RUN]["network"] == "synthetic"
        assert METADATA_RESULT not in stream.contents.metadata  # written at the end
        list(messages)
        assert stream.contents.metadata[METADATA_RESULT] == {"status": "finished"}


def test_the_file_is_closed_however_the_reading_ends(tmp_path: Path) -> None:
    path = tmp_path / "log.mcap"
    write_synthetic_log(path)
    stream = iter_log(path)
    messages = iter(stream)
    next(messages)
    stream.close()
    assert stream.closed and list(messages) == []  # stops at once, not at the chunk's end
    stream = iter_log(path)
    for _ in stream:
        break
    assert stream.closed  # the loop's iterator is gone, and with it the reading
    with iter_log(path) as stream:
        next(iter(stream))
    assert stream.closed
    stream = iter_log(path)
    list(stream)
    with pytest.raises(RuntimeError, match="read once"):
        list(stream)


GARBAGE = [
    b"",
    b"this is not a log at all, just text\n" * 20,
    b"\x89MCAP0\r\n",
    b"\x89MCA",
    b"\x89MCAP0\r\n\x01\x05\x00\x00\x00\x00\x00\x00\x00\xff\xff\xff\xff\xff",
]


def _refusals(path: Path) -> tuple[str, str]:
    """The lines ``read_log`` and ``iter_log`` (as the stream is made) refuse ``path`` with."""
    with pytest.raises(LogFormatError) as by_read:
        read_log(path)
    with pytest.raises(LogFormatError) as by_stream:
        iter_log(path)
    return str(by_read.value), str(by_stream.value)


@pytest.mark.parametrize("content", GARBAGE, ids=["empty", "text", "magic", "cut-magic", "header"])
def test_garbage_is_refused_as_the_stream_is_made(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "bad.mcap"
    path.write_bytes(content)
    by_read, by_stream = _refusals(path)
    assert by_stream == by_read and str(path) in by_stream


def test_a_missing_file_and_a_folder_are_refused_as_the_stream_is_made(tmp_path: Path) -> None:
    for path in (tmp_path / "nothing.mcap", tmp_path):
        by_read, by_stream = _refusals(path)
        assert by_stream == by_read and str(path) in by_stream


def _foreign(path: Path) -> None:
    with path.open("wb") as f:
        writer = McapWriter(f)
        writer.start(profile="", library="someone-else 1.0")
        schema = writer.register_schema("Thing", "jsonschema", b"{}")
        channel = writer.register_channel("/elsewhere", "json", schema)
        for i in range(5):
            writer.add_message(channel, i, b"{}", i)
        writer.finish()


def _future_version(path: Path) -> None:
    with path.open("wb") as f, LogWriter(f, {"format_version": "3"}) as writer:
        for i in range(5):
            writer.write(Topic.RANGES, i, schemas.Ranges(time_ns=i, front_m=1.0))
        writer.finish()


def _json_ranges(path: Path) -> None:
    with path.open("wb") as f:
        writer = McapWriter(f)
        writer.start(profile="", library="a-robot")
        writer.add_metadata(METADATA_RUN, {"format_version": "2"})
        schema = writer.register_schema("pipemap.Ranges", "jsonschema", b"{}")
        channel = writer.register_channel(Topic.RANGES, "json", schema)
        for i in range(5):
            writer.add_message(channel, i, b"{}", i)
        writer.finish()


@pytest.mark.parametrize(
    "make,message",
    [
        (_foreign, "not a pipemap log: no pipemap.run metadata (an MCAP file written by some"),
        (_future_version, "log format version '3' in pipemap.run; this pipemap reads"),
        (_json_ranges, "has json messages, schema pipemap.Ranges (jsonschema); pipemap's"),
    ],
    ids=["foreign", "future-version", "json-channel"],
)
def test_a_log_that_is_not_pipemap_s_is_refused_before_its_first_message(
    tmp_path: Path, make: Callable[[Path], None], message: str
) -> None:
    path = tmp_path / "bad.mcap"
    make(path)
    with pytest.raises(LogFormatError) as by_read:
        read_log(path)
    assert message in str(by_read.value)
    stream = iter_log(path)
    handed = []
    with pytest.raises(LogFormatError) as by_stream:
        for m in stream:
            handed.append(m)
    assert handed == [] and str(by_stream.value) == str(by_read.value)
    assert stream.closed


def _run_metadata_after_the_messages(path: Path) -> None:
    with path.open("wb") as f:
        writer = McapWriter(f, chunk_size=256)
        writer.start(profile="", library="a-merger")
        schema = writer.register_schema("Thing", "jsonschema", b"{}")
        channel = writer.register_channel("/elsewhere", "json", schema)
        for i in range(50):
            writer.add_message(channel, i, b"{}", i)
        writer.flush()
        writer.add_metadata(METADATA_RUN, {"format_version": "2"})
        writer.finish()


def test_run_metadata_the_summary_names_may_come_after_the_first_message(tmp_path: Path) -> None:
    path = tmp_path / "late.mcap"
    _run_metadata_after_the_messages(path)
    assert_streams_as_read(path)
    with iter_log(path) as stream:
        next(iter(stream))
        assert METADATA_RUN not in stream.contents.metadata


def test_run_metadata_no_summary_names_must_come_before_the_first_message(tmp_path: Path) -> None:
    """What the stream cannot know without reading ahead: a file whose summary is cut off
    and whose run metadata comes after its first message is refused, as the
    stream's docstring says, though read_log, which reads it all first, takes it."""
    path = tmp_path / "late.mcap"
    _run_metadata_after_the_messages(path)
    path.write_bytes(path.read_bytes()[:-100])
    assert METADATA_RUN in read_log(path).metadata
    with pytest.raises(LogFormatError, match="not a pipemap log"):
        list(iter_log(path))


@pytest.fixture(scope="module")
def long_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("long") / "long.mcap"
    write_synthetic_log(path, messages=4000, image_px=128)  # noise images: ~4 MB
    return path


def _every_message_streamed(path: Path) -> None:
    for _message in iter_log(path):
        pass  # each message dropped as the next comes


def _every_message_read(path: Path) -> None:
    for _message in read_log(path).messages:
        pass


@pytest.mark.parametrize(
    "read",
    [
        pytest.param(_every_message_streamed, id="iter_log"),
        pytest.param(
            _every_message_read,
            id="read_log",
            marks=pytest.mark.xfail(strict=True, reason="read_log holds every message it keeps"),
        ),
    ],
)
def test_a_streamed_read_holds_a_small_part_of_the_file(
    long_log: Path, read: Callable[[Path], None]
) -> None:
    size = long_log.stat().st_size
    assert size > 3_000_000
    read(long_log)  # once before measuring: the decompressors are imported on first use
    tracemalloc.start()
    try:
        read(long_log)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 0.2 * size, f"peak {peak} bytes for a {size}-byte file"
