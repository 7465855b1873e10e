"""A file that holds two runs is named as such and never replayed as one: two logs
merged by another MCAP writer (two ``pipemap.run`` records, messages interleaved by
time), or two log files joined end to end (``cat a.mcap b.mcap``). ``info`` says
what the file holds (exit 1); ``replay``, ``score`` and ``view`` refuse it in one line
(exit 2) rather than pick a run or mix both into one map.

The merge is written here with the ``mcap`` library's own reader and writer, as a
merging tool does: every message in log-time order, each input's channels apart,
every metadata record of both.
"""

from __future__ import annotations

import heapq
import json
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from tests.test_faults import STORED, assert_one_line, pipemap

OTHER = STORED.parent / "paper_active.mcap"


def merged(inputs: list[Path], out: Path) -> None:
    writer = Writer(out.open("wb"))
    writer.start(profile="", library="a merging tool")
    readers = [make_reader(path.open("rb")) for path in inputs]
    for reader in readers:
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, record.metadata)

    def messages(k: int, reader: Any) -> Iterator[tuple[int, int, int, int, Any]]:
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            if schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(
                    schema.name, schema.encoding, schema.data
                )
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id], channel.metadata
                )
            yield message.log_time, k, message.sequence, channels[channel.id], message

    streams = [messages(k, reader) for k, reader in enumerate(readers)]
    for _, _, _, channel_id, m in heapq.merge(*streams, key=lambda x: x[:3]):
        writer.add_message(channel_id, m.log_time, m.data, m.publish_time, m.sequence)
    writer.finish()


@pytest.fixture(scope="module")
def two_merged(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("runs") / "merged.mcap"
    merged([STORED, OTHER], path)
    return path


def test_info_names_the_second_run_of_a_merge(two_merged: Path) -> None:
    done = pipemap("info", "--json", str(two_merged))
    assert done.returncode == 1, done.stderr
    doc = json.loads(done.stdout)
    assert doc["integrity"] == "corrupt"
    [damage] = doc["damage"]
    assert damage["problem"] == (
        "another pipemap.run record (network paper, seed 0, condition active): the file "
        "holds 2 runs, merged by another program"
    )
    assert doc["metadata"]["condition"] == "autonomous"  # the first run's, as the line says


@pytest.mark.parametrize("summary", [True, False], ids=["summary", "summary-cut-off"])
@pytest.mark.parametrize("command", ["replay", "score", "view"])
def test_a_merge_of_two_runs_is_refused_in_one_line(
    tmp_path: Path, two_merged: Path, command: str, summary: bool
) -> None:
    log = two_merged
    if not summary:  # the runs are found by the walk, not told by the summary's index
        log = tmp_path / "merged_cut.mcap"
        log.write_bytes(two_merged.read_bytes()[:-40])
    out = tmp_path / ("out.rrd" if command == "view" else "out.json")
    saved = {"replay": ["-o", str(out)], "score": ["--save-results", str(out)]}
    done = pipemap(command, str(log), *saved.get(command, ["--save", str(out)]))
    assert_one_line(done, 2, f"pipemap: error: {log}: holds 2 runs (2 pipemap.run records")
    assert "keep each run in a file of its own" in done.stderr
    assert list(tmp_path.iterdir()) == ([] if summary else [log])


def test_two_logs_joined_end_to_end_are_named_and_parted_as_said(tmp_path: Path) -> None:
    first, second = STORED.read_bytes(), OTHER.read_bytes()
    joined = tmp_path / "joined.mcap"
    joined.write_bytes(first + second)
    at = len(first)

    info = pipemap("info", "--json", str(joined))
    assert info.returncode == 1, info.stderr
    doc = json.loads(info.stdout)
    [damage] = doc["damage"]
    assert damage["offset"] == at
    assert damage["problem"] == (
        f"another MCAP file of {len(second)} bytes begins after the log's closing magic "
        "(two files joined end to end): it is not read"
    )
    assert doc["messages"] == json.loads(pipemap("info", "--json", str(STORED)).stdout)["messages"]

    for command in ("replay", "score"):
        done = pipemap(command, str(joined))
        assert_one_line(
            done, 2, f"holds two MCAP files joined end to end (the second begins at byte {at})"
        )
        assert f"part them with head -c {at} and tail -c +{at + 1}" in done.stderr

    # What the line says to do parts them into two logs that read whole.
    for name, tool in (
        ("first", ["head", "-c", str(at)]),
        ("second", ["tail", "-c", f"+{at + 1}"]),
    ):
        part = tmp_path / f"{name}.mcap"
        with part.open("wb") as f:
            subprocess.run([*tool, str(joined)], stdout=f, check=True, timeout=60)
        done = pipemap("info", str(part))
        assert done.returncode == 0, done.stderr
        assert "integrity  ok" in done.stdout
