"""The screen through the index's path is the exhaustive screen when the shortlist
holds every junction: the stored logs, with the index on from the first junction
and a shortlist larger than their maps, replay exactly as committed (the shortlist's
columns, rows and records line up with the junctions they stand for).
"""

from __future__ import annotations

import pytest

from pipemap.localizer import fastmatch
from tests.replay.test_recordings import LOGS, assert_replays_as_committed


@pytest.mark.parametrize("name", LOGS)
def test_a_stored_log_replays_the_same_with_the_index_on(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(fastmatch, "INDEX_ABOVE", 0)
    monkeypatch.setattr(fastmatch, "SHORTLIST", 1000)
    assert_replays_as_committed(name)
