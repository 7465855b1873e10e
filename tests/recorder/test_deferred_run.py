"""A simulated run that defers: a robot with poorer odometry (``--odometry-drift``)
in a network of identical fittings (``--alike 1``), where neither appearance nor
dead reckoning tells two junctions apart at once. The online decisions in the log
keep the visit open with two maps alive, a later visit settles it, the map is right,
and a replay makes the online decisions byte for byte."""

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

#: The run: found by recording small networks at these settings (docs/lookalike.md).
NETWORK, SEED = "grid:3x4", 3


@pytest.fixture(scope="module")
def deferring_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return record_drifting(tmp_path_factory.mktemp("deferred") / "run.mcap", NETWORK, SEED)


def test_the_online_decisions_defer_a_visit_and_settle_it_right(
    deferring_run: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    online = online_decisions(deferring_run)
    deferred = [k for k, m in enumerate(online) if m.deferred]
    assert deferred, "no decision was deferred"
    first = online[deferred[0]]
    assert first.hypotheses >= 2
    later = [s for m in online[deferred[0] + 1 :] for s in m.settled]
    assert any(s.visit == deferred[0] for s in later)
    status, out, err = run(["score", str(deferring_run), "--json"], capfd)
    assert status == 0, err
    doc = json.loads(out)
    assert doc["map_correct"] and doc["ports_correct"]
    assert doc["deferred"]["right"] == len(doc["deferred"]["visits"]) >= 1
    assert doc["deferred"]["wrong"] == 0 and doc["deferred"]["open"] == []


def test_the_replay_makes_the_online_decisions_byte_for_byte(deferring_run: Path) -> None:
    assert_replay_makes_the_online_decisions(deferring_run)
