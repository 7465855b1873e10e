"""The robot's log and the localizer's decisions owe nothing to ground truth.

Each run is recorded twice: once as it is, once with every truth value the simulator
could leak poisoned where the recorder is given it (the network it is handed, the
true poses and the sweeps' true nodes), while the world the robot senses (the meshes
it renders and ranges, where the experimenter puts it) stays the true one. The
``/robot`` topics and the online decisions must come out byte for byte the same, and
the ``/truth`` topics must not (the poison took). The poisoned runs are of
``tree:3`` (a junction between two dead ends: a tour of 5 visits, at a fraction of the
paper network's cost); the exit-scan checks read runs of the paper network.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import pytest

from pipemap import __version__
from pipemap.recorder import RecordSettings, Topic, read_log, record_run, schemas, session
from pipemap.sim import Condition
from pipemap.sim.episode import Pose
from pipemap.sim.network import Network, Node, Pipe, build_network
from pipemap.sim.robot import PlanarPose
from pipemap.sim.stream import SimRecord, SweepEnd, TruePose

_SHIFT = (5.0, -3.0)
#: The network of the poisoned runs and the clean runs they are compared with.
POISONED_NETWORK = "tree:3"


def _renamed(label: str) -> str:
    return "?" if label == "?" else f"poison-{label}"


@dataclasses.dataclass(frozen=True)
class _PermutedHeadings(Network):
    """A network whose pipe headings at each node are handed round among its pipes."""

    def pipe_headings(self, label: str) -> dict[str, float]:
        true = super().pipe_headings(label)
        keys = sorted(true)
        values = [true[k] for k in keys]
        return dict(zip(keys, values[1:] + values[:1], strict=True))


def _poisoned(network: Network) -> Network:
    """``network`` renamed, shifted and with its pipe headings permuted."""
    dx, dy = _SHIFT
    return _PermutedHeadings(
        tuple(Node(_renamed(n.label), n.x_m + dx, n.y_m + dy) for n in network.nodes),
        tuple(Pipe(_renamed(p.a), _renamed(p.b)) for p in network.pipes),
        entry=_renamed(network.entry),
        diameter_m=network.diameter_m,
    )


class _Physical:
    """The world as physics and the experimenter's hands know it: the true network."""

    def __init__(self, world: Any, network: Network) -> None:
        self._world = world
        self.network = network

    def __getattr__(self, name: str) -> Any:
        return getattr(self._world, name)


def _shifted(pose: Pose) -> Pose:
    dx, dy = _SHIFT
    return dataclasses.replace(pose, x_m=pose.x_m + dx, y_m=pose.y_m + dy, yaw_rad=pose.yaw_rad + 1)


def _poison_truth(monkeypatch: pytest.MonkeyPatch, true: Network, fake: Network) -> None:
    """From here on the recorder is handed ``fake`` and poisoned truth records."""
    real_world = session.World

    def world(network: Network, **kwargs: Any) -> Any:
        built = real_world(true, **kwargs)  # the meshes the robot senses: the true ones
        built.network = fake
        return built

    monkeypatch.setattr(session, "World", world)
    real_episode = session.Episode
    monkeypatch.setattr(
        session,
        "Episode",
        lambda w, config, start=None: real_episode(_Physical(w, true), config, start),
    )
    real_run = session.autonomous_run
    monkeypatch.setattr(
        session,
        "autonomous_run",
        lambda w, *args, **kwargs: real_run(_Physical(w, true), *args, **kwargs),
    )
    real_call = session._OnlineSink.__call__

    def poisoned_call(self: Any, record: SimRecord) -> None:
        if isinstance(record, TruePose):
            p = record.pose
            dx, dy = _SHIFT
            record = TruePose(record.t_ns, PlanarPose(p.x_m + dx, p.y_m + dy, p.yaw_rad + 1))
        elif isinstance(record, SweepEnd):
            truth = record.truth
            record = dataclasses.replace(
                record,
                truth=dataclasses.replace(
                    truth, node=_renamed(truth.node), camera_pose=_shifted(truth.camera_pose)
                ),
            )
        real_call(self, record)

    monkeypatch.setattr(session._OnlineSink, "__call__", poisoned_call)


def _record(
    path: Path,
    condition: Condition,
    poison: pytest.MonkeyPatch | None,
    threshold: float = 0.36,
    seed: int = 2,
    spec: str = POISONED_NETWORK,
) -> None:
    true = build_network(spec)
    settings = RecordSettings(
        network=spec, condition=condition, resolution_px=32, seed=seed, threshold=threshold
    )
    network = true
    if poison is not None:
        network = _poisoned(true)
        _poison_truth(poison, true, network)
    record_run(path, settings, network, __version__, inline=True)


@pytest.fixture(scope="module")
def clean_run(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    """The unpoisoned run of a condition, threshold, seed and network, recorded once
    for the module."""
    made: dict[tuple[Condition, float, int, str], Path] = {}

    def run(
        condition: Condition, threshold: float = 0.36, seed: int = 2, spec: str = POISONED_NETWORK
    ) -> Path:
        key = (condition, threshold, seed, spec)
        if key not in made:
            path = tmp_path_factory.mktemp("clean") / "clean.mcap"
            _record(path, condition, None, threshold, seed, spec)
            made[key] = path
        return made[key]

    return run


def _topics(path: Path, prefix: str) -> list[tuple[str, int, bytes]]:
    return [
        (m.topic, m.log_time_ns, bytes(m.data))
        for m in read_log(path).messages
        if m.topic.startswith(prefix)
    ]


@pytest.mark.parametrize(
    ("condition", "threshold"),
    [
        (Condition.NOISE, 0.36),
        (Condition.ACTIVE, 0.36),
        (Condition.AUTONOMOUS, 0.36),
        # Weak matches at this threshold: the autonomous robot makes probe moves.
        (Condition.AUTONOMOUS, 0.6),
    ],
)
def test_poisoned_truth_changes_no_robot_message_and_no_decision(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    clean_run,  # type: ignore[no-untyped-def]
    condition: Condition,
    threshold: float,
) -> None:
    clean, poisoned = clean_run(condition, threshold), tmp_path / "poisoned.mcap"
    with monkeypatch.context() as patch:
        _record(poisoned, condition, patch, threshold)
    robot = _topics(clean, "/robot/")
    if threshold > 0.36:
        probes = [
            schemas.SweepCommand.FromString(data) for _, _, data in _topics(clean, Topic.SWEEP)
        ]
        assert any(p.probe for p in probes), "the run should make probe moves"
    assert {t for t, _, _ in robot} >= {Topic.RANGES, Topic.IMU, Topic.WHEELS, Topic.NODE}
    assert _topics(poisoned, "/robot/") == robot
    assert _topics(poisoned, "/online/") == _topics(clean, "/online/")
    # The poison reached the truth the recorder wrote.
    nodes = [
        schemas.TrueSweep.FromString(data).node
        for _, _, data in _topics(poisoned, Topic.TRUE_SWEEP)
    ]
    assert nodes and all(n.startswith("poison-") or n == "?" for n in nodes)
    assert _topics(poisoned, "/truth/") != _topics(clean, "/truth/")


# Seed 7 puts the robot down 3.5 cm towards the cap of the dead ends S (visits 1 and
# 13) and E (visit 10): turning there, its nose swings through the cap, and the scan
# once saw an exit through it (``ExplorerConfig.touch_m``).
@pytest.mark.parametrize("seed", [2, 7])
def test_a_placed_robot_logs_its_own_exit_scan(clean_run, seed: int) -> None:  # type: ignore[no-untyped-def]
    """A ``noise`` run holds the robot's range readings at every junction, and each
    visit's exits are what its scan found: the paper network's pipes, to within the
    scan's error, relative to the heading it arrived with."""
    path = clean_run(Condition.NOISE, seed=seed, spec="paper")
    network = build_network("paper")
    scans: dict[int, int] = {}
    exits: dict[int, list[float]] = {}
    visit, state = 0, ""
    for m in read_log(path).messages:
        if m.topic == Topic.NODE:
            event = schemas.NodeEvent.FromString(m.data)
            if event.kind == schemas.NodeEvent.ARRIVAL:
                visit = event.visit_id
            elif event.kind == schemas.NodeEvent.EXITS:
                exits[event.visit_id] = list(event.exits_rad)
        elif m.topic == Topic.CONTROLLER:
            state = schemas.ControllerState.FromString(m.data).state
        elif m.topic == Topic.RANGES and state == "scanning":
            scans[visit] = scans.get(visit, 0) + 1
    assert sorted(scans) == list(range(1, 14)) and min(scans.values()) > 20
    tour = ["S", "A", "B", "A", "C", "D", "C", "F", "C", "E", "C", "A", "S"]
    assert [len(exits[v]) for v in range(1, 14)] == [network.degree(n) for n in tour]
    # One exit of every revisit is straight behind: the pipe it was carried in by.
    for v in range(2, 14):
        assert min(abs(math.remainder(e - math.pi, 2 * math.pi)) for e in exits[v]) < 0.1
