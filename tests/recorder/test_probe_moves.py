"""Active vision by the autonomous robot: it makes the probe moves the localizer asks for.

One small run asks for probes cheaply: the tests' small run (``paper`` at 64 px, seed 3) with the
threshold at 0.6 (new junctions then fall below it and ask; the two-view check still
decides). The robot makes the moves, its rangers refuse those toward a wall, the log
holds the probe sweeps of each visit, and a replay meets the same decisions, probe by
probe. ``--no-probe-moves`` turns the moves off, and ``score`` then says the robot
made none.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from pipemap.localizer import LocalizerConfig
from pipemap.recorder import Topic, read_log, schemas
from pipemap.replay import FileSource, replay
from tests.logs import record, recorded

THRESHOLD = 0.6
#: The tests' small run (``tests.logs.SMALL_RUN``: paper, 64 px, seed 3) at this threshold.
WEAK = ("--threshold", str(THRESHOLD))


@pytest.fixture(scope="module")
def probing(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return recorded(tmp_path_factory, "probing", *WEAK)


def _score_notes(path: Path) -> str:
    """What ``pipemap score`` says on stderr of ``path`` at :data:`THRESHOLD`."""
    done = subprocess.run(
        [sys.executable, "-m", "pipemap", "score", str(path), *WEAK],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    return done.stderr


def _probe_sweeps(path: Path) -> list[schemas.SweepCommand]:
    contents = read_log(path, keep=lambda topic: topic == Topic.SWEEP)
    starts = [schemas.SweepCommand.FromString(m.data) for m in contents.messages]
    return [s for s in starts if s.phase == schemas.SweepCommand.START and s.probe]


def _online(path: Path) -> list[schemas.Decision]:
    contents = read_log(path, keep=lambda topic: topic == Topic.DECISION)
    return [schemas.Decision.FromString(m.data) for m in contents.messages]


def _events(path: Path) -> list[str]:
    contents = read_log(path, keep=lambda topic: topic == Topic.EVENTS)
    return [schemas.Log.FromString(m.data).message for m in contents.messages]


def test_the_robot_makes_the_probe_moves_and_the_log_holds_their_sweeps(probing: Path) -> None:
    probes = _probe_sweeps(probing)
    online = _online(probing)
    asked = [(d.visit_id, p) for d in online for p in d.probes]
    made = [(v, p) for v, p in asked if p.HasField("similarity")]
    assert made, "the run should ask for probes and the robot make some"
    # One logged probe sweep per probe the localizer was answered, of that visit and kind.
    assert sorted((s.visit_id, s.probe_kind) for s in probes) == sorted(
        (v, p.kind) for v, p in made
    )
    # Each is numbered after the sweeps before it, and the visits' own stay in order.
    sweeps = read_log(probing, keep=lambda topic: topic == Topic.SWEEP).messages
    starts = [schemas.SweepCommand.FromString(m.data) for m in sweeps]
    ids = [s.sweep_id for s in starts if s.phase == schemas.SweepCommand.START]
    assert ids == list(range(1, len(ids) + 1))
    # Every probe not made was refused by the rangers, and the log says why.
    refused = [e for e in _events(probing) if " not made: " in e]
    assert len(refused) == len(asked) - len(made)
    assert all("wall" in e for e in refused)


def test_a_replay_meets_the_online_decisions_probe_for_probe(probing: Path) -> None:
    result = replay(FileSource(probing), LocalizerConfig(threshold=THRESHOLD))
    online = _online(probing)
    assert [d.visit_id for d in online] == [v.visit_id for v in result.visits]
    for logged, ours in zip(online, result.visits, strict=True):
        d = ours.decision
        assert (logged.node, logged.known, logged.similarity) == (d.node, d.known, d.similarity)
        assert [
            (p.kind, p.similarity if p.HasField("similarity") else None) for p in logged.probes
        ] == [(p.request.kind.value, p.similarity) for p in d.probes]
    assert not any("makes no probe moves" in w for w in result.warnings)


def test_the_robot_is_back_where_it_swept_after_its_probes(probing: Path) -> None:
    """Between a visit's exit scan and its departure the robot made its probe moves;
    it leaves from where it stood, facing as it did (the true pose, for the test)."""
    contents = read_log(probing, keep=lambda t: t in (Topic.NODE, Topic.TRUE_POSE))
    pose: tuple[float, float, float] | None = None
    at_exits: dict[int, tuple[float, float, float]] = {}
    moved = {s.visit_id for s in _probe_sweeps(probing)}
    checked = 0
    for m in contents.messages:
        if m.topic == Topic.TRUE_POSE:
            f = schemas.FrameTransform.FromString(m.data)
            yaw = 2.0 * math.atan2(f.rotation.z, f.rotation.w)
            pose = (f.translation.x, f.translation.y, yaw)
            continue
        event = schemas.NodeEvent.FromString(m.data)
        assert pose is not None
        if event.kind == schemas.NodeEvent.EXITS:
            at_exits[event.visit_id] = pose
        elif event.kind == schemas.NodeEvent.DEPARTURE and event.visit_id in moved:
            x, y, yaw = at_exits[event.visit_id]
            assert math.hypot(pose[0] - x, pose[1] - y) < 0.01
            assert abs(math.remainder(pose[2] - yaw, 2.0 * math.pi)) < 0.05
            checked += 1
    assert checked == len(moved)


def test_no_probe_moves_makes_none_and_score_says_so(probing: Path, tmp_path: Path) -> None:
    path = tmp_path / "off.mcap"
    done = record(path, *WEAK, "--no-probe-moves")
    assert done.returncode == 0, done.stderr
    assert not _probe_sweeps(path)
    assert read_log(path).metadata["pipemap.run"]["probe_moves"] == "false"
    asked = sum(len(d.probes) for d in _online(path))
    assert asked and all(not p.HasField("similarity") for d in _online(path) for p in d.probes)
    assert "the robot makes no probe moves" in _score_notes(path)
    assert "makes no probe moves" not in _score_notes(probing)


def test_no_probe_moves_is_refused_for_a_placed_robot(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "pipemap", "record", "--network", "paper", "--condition"]
        + ["noise", "--no-probe-moves", "-o", str(tmp_path / "x.mcap")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert done.stderr.startswith("pipemap: error: --no-probe-moves")
    assert not (tmp_path / "x.mcap").exists()
