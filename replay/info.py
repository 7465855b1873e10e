"""What ``pipemap info`` says of a log: its integrity, settings, sweeps and channels.

:func:`log_info` reads the log whole, or up to where it was cut or damaged, and
returns the document ``pipemap info --json`` prints (also :func:`pipemap.api.log_info`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

__all__ = ["log_info"]


class _Census:
    """What ``pipemap info`` counts, one message at a time, as the log is read: the
    messages that do not decode as their topic's type, the node arrivals, and the
    camera's messages for the sweeps."""

    def __init__(self) -> None:
        from pipemap.recorder import TOPICS

        self.classes = dict(TOPICS)
        self.undecodable: dict[str, int] = {}
        self.visits = 0

    def camera(self, messages: Iterable[Any]) -> Iterator[Any]:
        """The camera's messages of ``messages``, the others counted on the way."""
        from google.protobuf.message import DecodeError

        from pipemap.recorder import Topic
        from pipemap.recorder.schemas import NodeEvent

        for m in messages:
            message_class = self.classes.get(m.topic)
            if message_class is not None:
                try:
                    decoded = message_class.FromString(m.data)
                except DecodeError:
                    self.undecodable[m.topic] = self.undecodable.get(m.topic, 0) + 1
                else:
                    if m.topic == Topic.NODE:
                        self.visits += decoded.kind == NodeEvent.ARRIVAL
            if m.topic in (Topic.SWEEP, Topic.IMAGE):
                yield m  # undecodable too: the sweeps' own count says what it cost


def _read(path: Path) -> tuple[Any, _Census, int, list[str]]:
    """The log read as it goes: what it holds (no message kept), its census, how many
    complete sweeps it has (those a replay keeps, with every image readable) and
    the lines on those skipped. A log whose log time goes back is read again, its
    camera's messages held and ordered."""
    from pipemap.recorder import iter_log
    from pipemap.replay import ordered
    from pipemap.replay.logged import LogTimeWentBack, SweepAssembler, in_order

    with iter_log(path) as stream:
        census, sweeps, count = _Census(), SweepAssembler(str(path)), 0
        try:
            for m in in_order(census.camera(stream)):
                count += sweeps.feed(m) is not None
        except LogTimeWentBack:
            stream.close()
            with iter_log(path) as again:
                census, sweeps, count = _Census(), SweepAssembler(str(path)), 0
                for m in ordered(list(census.camera(again))):
                    count += sweeps.feed(m) is not None
                stream = again
    sweeps.finish()
    return stream.contents, census, count, sweeps.warnings


def log_info(path: str | Path) -> dict[str, Any]:
    """What ``pipemap info --json`` prints of the log at ``path``."""
    path = Path(path)
    from pipemap.recorder import METADATA_RESULT, METADATA_RUN
    from pipemap.recorder.metadata import typed_metadata

    contents, census, sweep_count, skipped = _read(path)
    undecodable, visits = census.undecodable, census.visits
    integrity, problem = contents.integrity.value, contents.problem
    if undecodable:
        lines = ", ".join(f"{topic} {count}" for topic, count in sorted(undecodable.items()))
        integrity = "corrupt"
        problem = "; ".join(p for p in (problem, f"messages that do not decode: {lines}") if p)
    metadata = typed_metadata(contents.metadata.get(METADATA_RUN, {}))
    result = contents.metadata.get(METADATA_RESULT)
    metadata["result"] = None if result is None else typed_metadata(result)
    return {
        "file": str(path),
        "writer": contents.library,
        "duration_s": contents.duration_ns / 1e9,
        "messages": sum(contents.counts.values()),
        "integrity": integrity,
        "problem": problem or None,
        "damage": [
            {
                "text": d.describe(),
                "where": d.where,
                "offset": d.offset,
                "chunk": d.chunk,
                "chunks": d.chunks,
                "problem": d.problem,
                "start_s": None if d.start_ns is None else d.start_ns / 1e9,
                "end_s": None if d.end_ns is None else d.end_ns / 1e9,
                "lost": d.lost,
            }
            for d in contents.damage
        ],
        "truncated": contents.truncated or None,
        "undecodable": undecodable,
        "channels": [
            {"topic": c.topic, "schema": c.schema_name, "count": contents.counts.get(c.topic, 0)}
            for c in sorted(contents.channels.values(), key=lambda c: c.channel_id)
        ],
        "sweeps": sweep_count,
        "sweeps_skipped": skipped,
        "visits": visits,
        "metadata": metadata,
    }
