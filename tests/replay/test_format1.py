"""Logs of format 1 (before the exit scans) still replay: the same decisions, a map
without ports."""

from __future__ import annotations

from pathlib import Path

from pipemap.localizer import LocalizerConfig
from pipemap.recorder import METADATA_RESULT, METADATA_RUN, LogWriter, Topic, read_log
from pipemap.recorder.schemas import NodeEvent
from pipemap.replay import FileSource, replay

REPO = Path(__file__).resolve().parents[2]
STORED = REPO / "recordings" / "random8_loops.mcap"


def _as_format_1(source: Path, target: Path) -> int:
    """Copy ``source`` as a format 1 log would have it: no EXITS node events, no
    ``explore`` metadata. Returns how many events were left out."""
    contents = read_log(source)
    run = {k: v for k, v in contents.metadata[METADATA_RUN].items() if k != "explore"}
    run["format_version"] = "1"
    dropped = 0
    with target.open("wb") as f, LogWriter(f, run) as writer:
        for m in contents.messages:
            if m.topic == Topic.NODE and NodeEvent.FromString(m.data).kind == NodeEvent.EXITS:
                dropped += 1
                continue
            writer.write_serialized(m.topic, m.log_time_ns, m.data)
        writer.finish(contents.metadata[METADATA_RESULT])
    return dropped


def test_a_format_1_log_replays_with_the_same_decisions_and_no_ports(tmp_path: Path) -> None:
    old = tmp_path / "format1.mcap"
    assert _as_format_1(STORED, old) > 0
    assert read_log(old).metadata[METADATA_RUN]["format_version"] == "1"
    config = LocalizerConfig()
    now = replay(FileSource(STORED), config)
    before = replay(FileSource(old), config)
    assert [v.decision.node for v in before.visits] == [v.decision.node for v in now.visits]
    assert [v.decision.known for v in before.visits] == [v.decision.known for v in now.visits]
    assert now.topomap.has_ports
    assert before.topomap.node_count == now.topomap.node_count
    assert all(before.topomap.ports(n) is None for n in range(before.topomap.node_count))
    assert all(e.u_port is None and e.v_port is None for e in before.topomap.edges())
    # Without ports an edge records adjacency: the same pairs of junctions.
    pairs = {frozenset((e.u, e.v)) for e in now.topomap.edges()}
    assert {frozenset((e.u, e.v)) for e in before.topomap.edges()} == pairs
