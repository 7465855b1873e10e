"""A damaged chunk loses that chunk only: ``info`` names it and what it held, and a
replay keeps every sweep whose messages all lie in intact chunks.

What each chunk holds is found here with the ``mcap`` library's own stream reader on
the undamaged file, not with pipemap's reader.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from mcap.records import Channel, Chunk, Footer, Message
from mcap.stream_reader import StreamReader, breakup_chunk

from pipemap.recorder import Integrity, Topic
from pipemap.recorder.schemas import SweepCommand
from pipemap.replay import FileSource, replay

STORED = Path(__file__).resolve().parents[2] / "recordings" / "paper_autonomous.mcap"


def chunk_contents(path: Path) -> tuple[list[tuple[int, int]], list[list[tuple[str, int, bytes]]]]:
    """Each chunk record's (start, length) and its messages as (topic, log time, data)."""
    data = path.read_bytes()
    positions: list[tuple[int, int]] = []
    at = 8
    while True:
        opcode, length = int(data[at]), int.from_bytes(data[at + 1 : at + 9], "little")
        if opcode == 0x06:
            positions.append((at, 9 + length))
        if opcode == 0x0F:  # data end
            break
        at += 9 + length
    topics: dict[int, str] = {}
    chunks: list[list[tuple[str, int, bytes]]] = []
    with path.open("rb") as f:
        for record in StreamReader(f, skip_magic=False, emit_chunks=True).records:
            if isinstance(record, Chunk):
                messages = []
                for inner in breakup_chunk(record):
                    if isinstance(inner, Channel):
                        topics[inner.id] = inner.topic
                    elif isinstance(inner, Message):
                        messages.append((topics[inner.channel_id], inner.log_time, inner.data))
                chunks.append(messages)
            elif isinstance(record, Footer):
                break
    assert len(positions) == len(chunks)
    return positions, chunks


def sweep_of_every_image(chunks: list[list[tuple[str, int, bytes]]]) -> dict[int, int]:
    """The sweep id of each image, by log time (a sweep's image command shares it)."""
    out = {}
    for messages in chunks:
        for topic, t, payload in messages:
            if topic == Topic.SWEEP:
                command = SweepCommand.FromString(payload)
                if command.phase == SweepCommand.IMAGE:
                    out[t] = command.sweep_id
    return out


def lost_sweeps(chunks: list[list[tuple[str, int, bytes]]], damaged: int) -> set[int]:
    by_time = sweep_of_every_image(chunks)
    lost = set()
    for topic, t, payload in chunks[damaged]:
        if topic == Topic.SWEEP:
            lost.add(SweepCommand.FromString(payload).sweep_id)
        elif topic == Topic.IMAGE:
            lost.add(by_time[t])
    return lost


@pytest.fixture(scope="module")
def layout() -> tuple[list[tuple[int, int]], list[list[tuple[str, int, bytes]]]]:
    return chunk_contents(STORED)


def damage_chunk(path: Path, out: Path, start: int, length: int, cut_summary: bool) -> None:
    data = bytearray(path.read_bytes())
    data[start + length // 2] ^= 0x01
    if cut_summary:  # no summary to find the next chunk by: it is found by scanning
        data = data[:-100]
    out.write_bytes(bytes(data))


@pytest.mark.parametrize("cut_summary", [False, True], ids=["whole", "summary-cut-off"])
def test_one_corrupt_chunk_keeps_every_sweep_of_the_intact_chunks(
    tmp_path: Path, layout: tuple[list[tuple[int, int]], list[list]], cut_summary: bool
) -> None:
    positions, chunks = layout
    assert len(chunks) == 19
    damaged = tmp_path / "damaged.mcap"
    damage_chunk(STORED, damaged, *positions[1], cut_summary)
    source = FileSource(damaged)
    assert source.integrity is Integrity.CORRUPT
    result = replay(source)
    whole = replay(FileSource(STORED))
    lost = lost_sweeps(chunks, 1)
    assert lost, "chunk 2 holds part of a sweep"
    kept = {v.sweep_id for v in whole.visits} - lost
    assert {v.sweep_id for v in result.visits} == kept
    # Only the lost visit is missing; the path is broken there, so no edge is invented.
    assert len(result.visits) == len(whole.visits) - len(lost)
    assert result.breaks == (1,)
    # Every message of every other chunk is kept.
    expected = Counter(t for i, ms in enumerate(chunks) if i != 1 for t, _, _ in ms)
    assert source.contents.counts == {t: expected.get(t, 0) for t in source.contents.counts}


def test_info_names_the_damaged_chunk_and_what_it_held(
    tmp_path: Path, layout: tuple[list[tuple[int, int]], list[list]]
) -> None:
    positions, chunks = layout
    damaged = tmp_path / "damaged.mcap"
    damage_chunk(STORED, damaged, *positions[1], False)
    done = subprocess.run(
        [sys.executable, "-m", "pipemap", "info", "--json", str(damaged)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1, done.stderr
    doc = json.loads(done.stdout)
    assert doc["integrity"] == "corrupt"
    [damage] = doc["damage"]
    assert (damage["chunk"], damage["chunks"], damage["offset"]) == (2, 19, positions[1][0])
    # One bit flipped in the compressed records: zstd or the chunk's CRC catches it,
    # depending on where the bit falls.
    assert damage["problem"] == "CRC mismatch" or damage["problem"].startswith(
        "zstd data does not decompress"
    )
    assert damage["lost"] == dict(Counter(topic for topic, _, _ in chunks[1]))
    times = [t for _, t, _ in chunks[1]]
    assert damage["start_s"] == min(times) / 1e9 and damage["end_s"] == max(times) / 1e9
    assert "chunk 2 of 19" in doc["problem"]
    # The sweeps a replay keeps: info and replay agree.
    assert doc["sweeps"] == 17  # of 18, probe sweeps included
