"""Runs of identical fittings (``--alike 1``) by a robot with poorer odometry
(``--odometry-drift``): recording one, its online decisions, and the check that a
replay makes them byte for byte (``test_deferred_run``, ``test_new_branch_run``)."""

from __future__ import annotations

from pathlib import Path

from pipemap.recorder import RecordSettings, Topic, read_log, record_run, schemas
from pipemap.recorder.messages import decision_message
from pipemap.replay import FileSource, replay
from pipemap.sim.network import build_network

#: The drift and the resolution of these runs (docs/lookalike.md).
DRIFT, RESOLUTION = 10.0, 96


def record_drifting(path: Path, network: str, seed: int) -> Path:
    """``pipemap record --network NETWORK --seed SEED --alike 1 --odometry-drift 10
    --resolution 96 -o PATH``, in this process."""
    settings = RecordSettings(
        network, seed=seed, resolution_px=RESOLUTION, alike=1.0, odometry_drift=DRIFT
    )
    record_run(path, settings, build_network(network, seed=seed), "test", inline=True)
    return path


def online_decisions(path: Path) -> list[schemas.Decision]:
    """The log's ``/online/decision`` messages, in order."""
    contents = read_log(path, keep=lambda topic: topic == Topic.DECISION)
    return [schemas.Decision.FromString(m.data) for m in contents.messages]


def assert_replay_makes_the_online_decisions(path: Path) -> None:
    """A replay of the log gives every online decision message to the byte."""
    online = online_decisions(path)
    visits = replay(FileSource(path)).visits
    assert len(visits) == len(online)
    for logged, ours in zip(online, visits, strict=True):
        again = decision_message(logged.time_ns, logged.visit_id, ours.decision, logged.threshold)
        assert again.SerializeToString() == logged.SerializeToString()
