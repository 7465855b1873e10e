"""A chunk copied by another program (in place, or again before the data end) is read
once: every message counts once, the replay and the score are those of the log as
written, and the copy is named (``holds the same records as chunk N``), never called
lost.

Where each chunk lies is found by walking the undamaged file's records here, not with
pipemap's reader.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from pipemap.recorder import Integrity
from pipemap.replay import FileSource, replay

STORED = Path(__file__).resolve().parents[2] / "recordings" / "paper_autonomous.mcap"
CHUNK, MESSAGE_INDEX, DATA_END = 0x06, 0x07, 0x0F


def records(data: bytes) -> list[tuple[int, int, int]]:
    """(opcode, start, end) of each record of the data section, up to its data end."""
    out = []
    at = 8
    while True:
        opcode, length = data[at], int.from_bytes(data[at + 1 : at + 9], "little")
        out.append((opcode, at, at + 9 + length))
        if opcode == DATA_END:
            return out
        at += 9 + length


def with_a_chunk_repeated(data: bytes, number: int, where: str) -> tuple[bytes, int, int]:
    """``data`` with chunk ``number`` (1-based) and its message indexes copied right
    after them (``in-place``) or before the data end (``before-data-end``); returns the
    file, the chunk's offset and the copy's."""
    found = records(data)
    chunks = [i for i, (opcode, _, _) in enumerate(found) if opcode == CHUNK]
    first = chunks[number - 1]
    last = first
    while found[last + 1][0] == MESSAGE_INDEX:
        last += 1
    start, end = found[first][1], found[last][2]
    at = end if where == "in-place" else found[-1][1]
    return data[:at] + data[start:end] + data[at:], start, at


def pipemap(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, timeout=300
    )


@pytest.mark.parametrize("where", ["in-place", "before-data-end"])
def test_a_repeated_chunk_is_read_once_and_named(tmp_path: Path, where: str) -> None:
    data = STORED.read_bytes()
    copied, start, at = with_a_chunk_repeated(data, 3, where)
    path = tmp_path / "repeated.mcap"
    path.write_bytes(copied)
    whole, source = FileSource(STORED), FileSource(path)
    assert source.contents.counts == whole.contents.counts
    assert source.integrity is Integrity.CORRUPT
    assert not source.contents.truncated
    repeat = [d for d in source.contents.damage if "holds the same records" in d.problem]
    assert len(repeat) == 1
    assert repeat[0].offset == at
    assert repeat[0].problem == (
        f"holds the same records as chunk 3 (byte {start}): read once (no message is lost)"
    )
    # The copy shifts what follows it, so the footer no longer points at the summary:
    # named as such; nothing else is said to be lost.
    others = [d.problem for d in source.contents.damage if d not in repeat]
    assert others == ["summary CRC mismatch (no message is lost)"]
    assert replay(source).document() == replay(whole).document()


def test_info_replay_and_score_read_a_repeated_chunk_once_and_warn(tmp_path: Path) -> None:
    copied, start, at = with_a_chunk_repeated(STORED.read_bytes(), 3, "in-place")
    path = tmp_path / "repeated.mcap"
    path.write_bytes(copied)
    named = f"holds the same records as chunk 3 (byte {start}): read once (no message is lost)"

    info = pipemap("info", "--json", str(path))
    assert info.returncode == 1, info.stderr
    doc = json.loads(info.stdout)
    expected = json.loads(pipemap("info", "--json", str(STORED)).stdout)
    assert doc["messages"] == expected["messages"]
    assert doc["channels"] == expected["channels"]
    assert (doc["sweeps"], doc["sweeps_skipped"]) == (expected["sweeps"], [])
    assert doc["integrity"] == "corrupt"
    assert named in doc["problem"]

    replayed = pipemap("replay", str(path), "-o", str(tmp_path / "map.json"))
    assert replayed.returncode == 0, replayed.stderr
    assert f"pipemap: warning: {path}: damaged chunk 4 (byte {at}): {named}\n" in (replayed.stderr)
    assert "Traceback" not in replayed.stderr
    pipemap("replay", str(STORED), "-o", str(tmp_path / "whole.map.json"))
    assert (tmp_path / "map.json").read_bytes() == (tmp_path / "whole.map.json").read_bytes()

    scored = pipemap("score", "--json", str(path))
    assert scored.returncode == 0, scored.stderr
    assert named in scored.stderr
    whole = json.loads(pipemap("score", "--json", str(STORED)).stdout)
    report = json.loads(scored.stdout)
    ignored = {"log", "latency_ms", "integrity"}
    assert {k: v for k, v in report.items() if k not in ignored} == {
        k: v for k, v in whole.items() if k not in ignored
    }
    assert report["integrity"] == "corrupt"
