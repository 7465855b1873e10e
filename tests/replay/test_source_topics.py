"""A replay's source holds only the topics the replay reads: nine messages in ten of a
log (the IMU, wheels, ranges, controller, true poses) are never kept, and the map,
the score and the log's duration are the same as from every topic."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from pipemap.cli.app import main
from pipemap.localizer import LocalizerConfig, dumps_document
from pipemap.recorder import Topic
from pipemap.replay import (
    REPLAY_TOPICS,
    SCORE_TOPICS,
    FileSource,
    StreamSource,
    replay,
    score_replay,
)

LOG = Path(__file__).resolve().parents[2] / "recordings" / "random8_loops.mcap"


def test_a_source_of_the_replay_topics_holds_them_alone() -> None:
    whole, narrow = FileSource(LOG), FileSource(LOG, REPLAY_TOPICS)
    assert {m.topic for m in narrow.robot_messages()} == set(REPLAY_TOPICS)
    assert narrow.truth() == []
    assert len(narrow.robot_messages()) * 10 < len(whole.robot_messages())
    # What it says of the log covers every topic.
    assert narrow.contents.counts == whole.contents.counts
    assert narrow.duration_ns == whole.duration_ns > 0
    assert narrow.integrity is whole.integrity


def test_the_replay_topics_make_the_same_map_and_score() -> None:
    whole, narrow = FileSource(LOG), FileSource(LOG, SCORE_TOPICS)
    assert {m.topic for m in narrow.truth()} == {Topic.TRUE_SWEEP, Topic.NETWORK}
    full, lean = replay(whole), replay(narrow)
    assert dumps_document(lean.document()) == dumps_document(full.document())
    assert lean.duration_ns == full.duration_ns
    assert lean.images == full.images and lean.sweeps == full.sweeps
    threshold = LocalizerConfig().threshold
    scored = score_replay(full, whole, threshold).json_text(with_latency=False)
    assert score_replay(lean, narrow, threshold).json_text(with_latency=False) == scored


@pytest.mark.parametrize(
    ("command", "topics"), [("replay", REPLAY_TOPICS), ("score", SCORE_TOPICS)]
)
def test_replay_and_score_read_only_their_topics(
    command: str, topics: tuple[str, ...], monkeypatch: pytest.MonkeyPatch
) -> None:
    opened: list[Any] = []

    class Recording(StreamSource):
        def __init__(self, path: Path | str, topics: Any = None) -> None:
            opened.append(topics)
            super().__init__(path, topics)

    # Both read the file as they go (a StreamSource), and only their topics.
    monkeypatch.setattr("pipemap.replay.StreamSource", Recording)
    assert main([command, str(LOG)]) == 0
    assert opened == [topics]
