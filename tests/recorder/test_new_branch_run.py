"""A simulated run where a look-alike's first visit may be its twin: in a 3 x 4 grid of
identical fittings (``--alike 1``) a robot with poorer odometry (``--odometry-drift
10``) enters a T fitting from below, and it looks, turned half round, like the T
above it, 1 m away, whose pipe it seems to come in by is free. The localizer keeps
both maps (the T above, and a new junction: :mod:`localizer.branching`); the pipe
it leaves by settles it as new, the map is right, and a replay makes the online
decisions byte for byte."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.cli.common import run
from tests.recorder.drifting import (
    assert_replay_makes_the_online_decisions,
    online_decisions,
    record_drifting,
)

#: The run (docs/lookalike.md): with one map it merges the T's first visit.
NETWORK, SEED = "grid:3x4", 1


@pytest.fixture(scope="module")
def twin_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return record_drifting(tmp_path_factory.mktemp("newbranch") / "run.mcap", NETWORK, SEED)


def test_a_visit_kept_open_as_known_or_new_settles_as_new_and_the_map_is_right(
    twin_run: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    online = online_decisions(twin_run)
    # A decision taken as a known junction, with a new junction (an id no visit
    # before had) among the others it may be, settled later as that new junction.
    seen: set[int] = set()
    settled_new = []
    for k, m in enumerate(online):
        fresh = [n for n in m.deferred if n not in seen]
        if m.known and fresh:
            later = {s.visit: s.node for d in online[k + 1 :] for s in d.settled}
            if later.get(k) in fresh:
                settled_new.append(k)
        seen.add(m.node)
    assert settled_new, "no visit was kept open as new and settled as new"
    status, out, err = run(["score", str(twin_run), "--json"], capfd)
    assert status == 0, err
    doc = json.loads(out)
    assert doc["map_correct"] and doc["ports_correct"]
    assert doc["coverage"]["nodes_visited"] == doc["coverage"]["nodes_total"]
    assert doc["decisions"]["false_merge"] == 0 and doc["decisions"]["false_new"] == 0
    assert doc["deferred"]["wrong"] == 0 and doc["deferred"]["open"] == []
    # The same log with one map merges the T into its twin.
    status, out, err = run(["score", str(twin_run), "--json", "--hypotheses", "1"], capfd)
    assert status == 0, err
    assert json.loads(out)["decisions"]["false_merge"] >= 1


def test_the_replay_makes_the_online_decisions_byte_for_byte(twin_run: Path) -> None:
    assert_replay_makes_the_online_decisions(twin_run)
