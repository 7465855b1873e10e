"""A log filtered or re-written by another MCAP writer is still a pipemap log.

The ``mcap`` Python library's ``Writer`` (under another library name, as ``mcap
filter``, ``mcap recover`` or a merge would write) re-writes a recorded run: only the
``/robot`` topics and the ``pipemap.run`` metadata kept, channels and schemas
registered in another order, other chunk sizes, other compressions, no CRCs, no
chunks at all. Every such copy replays to the same map bytes as the original.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, IndexType
from mcap.writer import Writer as McapWriter

from pipemap.recorder import METADATA_RUN

REWRITES = {
    "filtered": {"chunk_size": 1 << 20, "compression": CompressionType.ZSTD},
    "lz4-small-chunks": {"chunk_size": 4096, "compression": CompressionType.LZ4},
    "no-crcs-no-indexes": {
        "compression": CompressionType.NONE,
        "enable_crcs": False,
        "index_types": IndexType.NONE,
        "use_summary_offsets": False,
    },
    "unchunked": {"use_chunking": False},
}


def pipemap(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, timeout=300
    )


def rewrite(source: Path, target: Path, **options: object) -> None:
    """Copy the /robot messages and the run metadata with mcap's own Writer, channels
    registered in reverse order of first use (other ids than pipemap's)."""
    with source.open("rb") as f_in, target.open("wb") as f_out:
        reader = make_reader(f_in)
        writer = McapWriter(f_out, **options)  # type: ignore[arg-type]
        writer.start(profile="", library="mcap-filter 0.0.1")
        for record in reader.iter_metadata():
            if record.name == METADATA_RUN:
                writer.add_metadata(record.name, record.metadata)
        summary = reader.get_summary()
        assert summary is not None
        schema_ids: dict[int, int] = {}
        channel_ids: dict[int, int] = {}
        for channel in sorted(summary.channels.values(), key=lambda c: -c.id):
            if not channel.topic.startswith("/robot/"):
                continue
            schema = summary.schemas[channel.schema_id]
            if schema.id not in schema_ids:
                schema_ids[schema.id] = writer.register_schema(
                    schema.name, schema.encoding, schema.data
                )
            channel_ids[channel.id] = writer.register_channel(
                channel.topic, channel.message_encoding, schema_ids[schema.id]
            )
        for _, channel, message in reader.iter_messages(log_time_order=False):
            if channel.id in channel_ids:
                writer.add_message(
                    channel_ids[channel.id],
                    message.log_time,
                    message.data,
                    message.publish_time,
                    message.sequence,
                )
        writer.finish()


@pytest.mark.parametrize("name", sorted(REWRITES))
def test_a_log_rewritten_by_another_mcap_writer_replays_to_the_same_bytes(
    recorded_run: Path, tmp_path: Path, name: str
) -> None:
    copy = tmp_path / f"{name}.mcap"
    rewrite(recorded_run, copy, **REWRITES[name])
    info = pipemap("info", str(copy))
    assert info.returncode == 0, info.stderr
    assert "integrity  ok" in info.stdout and "written by mcap-filter 0.0.1" in info.stdout
    original, rewritten = pipemap("replay", str(recorded_run)), pipemap("replay", str(copy))
    assert rewritten.returncode == 0, rewritten.stderr
    assert rewritten.stderr == "" and rewritten.stdout == original.stdout
