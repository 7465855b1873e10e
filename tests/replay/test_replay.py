"""Replay: deterministic, blind to /truth and /online, equal to the online decisions."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.writer import Writer as McapWriter

from pipemap.localizer import LocalizerConfig, ProbeKind, ProbeRequest, dumps_document
from pipemap.recorder import METADATA_RUN, LogMessage, LogWriter, Topic, read_log, schemas
from pipemap.recorder.messages import refused_probe
from pipemap.recorder.metadata import lamp_strength
from pipemap.replay import FileSource, LoggedSweep, replay
from pipemap.replay import replayer as replayer_module
from pipemap.replay.logged_probes import LoggedProbes
from tests.logs import sweeps_started

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


def pipemap(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, timeout=300
    )


@pytest.fixture(scope="module")
def robot_only(recorded_run: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the recorded run with every /truth and /online channel removed."""
    contents = read_log(recorded_run)
    path = tmp_path_factory.mktemp("stripped") / "robot_only.mcap"
    with path.open("wb") as f, LogWriter(f, contents.metadata[METADATA_RUN]) as writer:
        for m in contents.messages:
            if m.topic.startswith("/robot/"):
                writer.write_serialized(m.topic, m.log_time_ns, m.data)
    assert read_log(path).counts[Topic.TRUE_SWEEP] == 0
    return path


def test_replay_twice_gives_identical_bytes(recorded_run: Path, tmp_path: Path) -> None:
    first, second = tmp_path / "a.json", tmp_path / "b.json"
    for target in (first, second):
        done = pipemap("replay", str(recorded_run), "-o", str(target))
        assert done.returncode == 0, done.stderr
    assert first.read_bytes() == second.read_bytes()
    doc = json.loads(first.read_text())
    assert len(doc["visits"]) == sweeps_started(recorded_run) and doc["visits"][0]["set"] == "0001"


def test_a_log_without_truth_and_online_replays_to_the_same_bytes(
    recorded_run: Path, robot_only: Path
) -> None:
    full = dumps_document(replay(FileSource(recorded_run)).document())
    blind = dumps_document(replay(FileSource(robot_only)).document())
    assert blind == full


def test_replay_equals_the_online_decisions(recorded_run: Path) -> None:
    online = [
        schemas.Decision.FromString(m.data)
        for m in read_log(recorded_run).messages
        if m.topic == Topic.DECISION
    ]
    replayed = replay(FileSource(recorded_run)).visits
    assert [d.visit_id for d in online] == [v.visit_id for v in replayed]
    for logged, ours in zip(online, replayed, strict=True):
        d = ours.decision
        assert (logged.node, logged.known) == (d.node, d.known)
        assert logged.similarity == d.similarity
        assert (logged.candidate if logged.HasField("candidate") else None) == d.candidate
        assert (logged.margin if logged.HasField("margin") else None) == d.margin
        assert [p.kind for p in logged.probes] == [p.request.kind.value for p in d.probes]
        # Competing maps: how many lived, what the visit may still be, what it settled.
        assert (logged.hypotheses if logged.HasField("hypotheses") else 1) == d.hypotheses
        assert tuple(logged.deferred) == d.deferred
        assert tuple((s.visit, s.node) for s in logged.settled) == d.settled


def test_a_lamp_lit_log_is_normalised_as_its_camera_settings_say(recorded_run: Path) -> None:
    source = FileSource(recorded_run)
    assert lamp_strength(source.run_metadata()) == 1.0  # the default camera

    def similarities(config: LocalizerConfig | None) -> list[float]:
        return [v.decision.similarity for v in replay(source, config).visits]

    as_logged = similarities(None)
    assert as_logged == similarities(LocalizerConfig(lamp=True))
    assert as_logged != similarities(LocalizerConfig(lamp=False))


def test_a_cut_log_replays_its_complete_part(recorded_run: Path, tmp_path: Path) -> None:
    data = recorded_run.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    done = pipemap("replay", str(cut))
    assert done.returncode == 0, done.stderr
    assert "cut short" in done.stderr and "Traceback" not in done.stderr
    partial = json.loads(done.stdout)["visits"]
    whole = replay(FileSource(recorded_run)).document()["visits"]
    assert 0 < len(partial) < len(whole)
    # The last complete sweep may have lost its exit scan and its departure to the
    # cut: it is decided from its images alone, and the map does not know where the
    # robot left it by. Every visit before it is as in the whole log.
    assert partial[:-1] == whole[: len(partial) - 1]
    last, same = partial[-1], whole[len(partial) - 1]
    assert last["set"] == same["set"]
    assert last["exits_rad"] in (None, same["exits_rad"])
    assert last["departure_port"] in (None, same["departure_port"])


def test_replay_settings_change_the_decisions(recorded_run: Path) -> None:
    # Under the paper's rule the threshold decides (exits and dead reckoning are
    # not compared).
    paper = ("--threshold", "-1", "--no-verify", "--no-port-check", "--no-odometry-check")
    done = pipemap("replay", str(recorded_run), *paper, "--allow-repeat")
    assert done.returncode == 0, done.stderr
    visits = json.loads(done.stdout)["visits"]
    assert all(v["known"] for v in visits[1:])  # everything matches at -1
    assert [n["id"] for n in json.loads(done.stdout)["nodes"]] == [0]
    # By default a visit cannot be the junction it came from: the second visit is
    # new, and every later one is known as one of the two junctions it did not leave.
    done = pipemap("replay", str(recorded_run), *paper)
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert [v["known"] for v in doc["visits"][:2]] == [False, False]
    assert all(v["known"] for v in doc["visits"][2:])
    assert [n["id"] for n in doc["nodes"]] == [0, 1]
    nodes = [v["node"] for v in doc["visits"]]
    assert all(a != b for a, b in zip(nodes, nodes[1:], strict=False))


def test_by_default_geometry_decides_not_the_threshold() -> None:
    """At threshold -1 every similarity passes, yet the two-view check merges only
    true revisits: the map is the one the defaults give. (A stored 96 px log: the
    session's 32 px run has too few keypoints to check, and the threshold decides.)
    The defaults' map is the log's committed one, which tests/replay/test_recordings.py
    checks a replay gives."""
    log = str(RECORDINGS / "paper_autonomous.mcap")
    default = json.loads((RECORDINGS / "paper_autonomous.map.json").read_text())
    anything = pipemap("replay", log, "--threshold", "-1")
    assert anything.returncode == 0, anything.stderr
    doc = json.loads(anything.stdout)
    assert [v["node"] for v in doc["visits"]] == [v["node"] for v in default["visits"]]
    assert len(doc["nodes"]) == 7
    known = [v for v in doc["visits"] if v["known"]]
    assert len(known) == 6 and all(v["two_view_inliers"] >= 48 for v in known)


def test_replay_writes_graphml_and_refuses_to_overwrite(recorded_run: Path, tmp_path: Path) -> None:
    target, graph = tmp_path / "map.json", tmp_path / "map.graphml"
    done = pipemap("replay", str(recorded_run), "-o", str(target), "--graphml", str(graph))
    assert done.returncode == 0, done.stderr
    assert "<graphml" in graph.read_text()
    import networkx as nx

    read = nx.read_graphml(graph)
    doc = json.loads(target.read_text())
    assert read.number_of_edges() == len(doc["edges"])
    for edge in doc["edges"]:
        data = read.get_edge_data(str(edge["u"]), str(edge["v"]))
        if read.is_multigraph():
            data = next(iter(data.values()))
        wanted = {"label": edge["label"], "u_port": edge["u_port"], "v_port": edge["v_port"]}
        assert wanted.items() <= data.items()
    ports = [float(a) for a in read.nodes["1"]["ports"].split()]
    assert ports == [p["angle_rad"] for p in doc["nodes"][1]["ports"]]
    again = pipemap("replay", str(recorded_run), "-o", str(target))
    assert again.returncode == 2 and "--force" in again.stderr


def _foreign(path: Path) -> None:
    with path.open("wb") as f:
        writer = McapWriter(f)
        writer.start(profile="", library="another-robot 2.0")
        writer.finish()


def _no_camera(path: Path) -> None:
    with path.open("wb") as f:
        writer = McapWriter(f)
        writer.start(profile="", library="pipemap 0.1.0")
        writer.add_metadata(METADATA_RUN, {"format_version": "1", "network": "paper"})
        writer.finish()


def _json_camera(path: Path) -> None:
    with path.open("wb") as f:
        writer = McapWriter(f)
        writer.start(profile="", library="a-robot")
        writer.add_metadata(METADATA_RUN, {"format_version": "1"})
        schema = writer.register_schema("pipemap.SweepCommand", "jsonschema", b"{}")
        writer.register_channel("/robot/camera/sweep", "json", schema)
        writer.finish()


def _future_version(path: Path) -> None:
    with path.open("wb") as f:
        writer = McapWriter(f)
        writer.start(profile="", library="pipemap 9.0")
        writer.add_metadata(METADATA_RUN, {"format_version": "3"})
        writer.finish()


@pytest.mark.parametrize(
    "make,message",
    [
        (lambda p: p.write_bytes(b"not a log"), "not an MCAP file"),
        (lambda p: p.write_bytes(b""), "empty file"),
        (_foreign, "written by another-robot 2.0"),
        (_no_camera, "no /robot/camera/sweep, /robot/camera/image channel"),
        (_json_camera, "(/robot/camera/sweep) has json messages, schema pipemap.SweepCommand"),
        (
            _future_version,
            "log format version '3' in pipemap.run; this pipemap reads versions '1' and '2'",
        ),
    ],
)
@pytest.mark.parametrize("command", ["replay", "score"])
def test_bad_logs_get_one_line_and_exit_2(
    tmp_path: Path, make: object, message: str, command: str
) -> None:
    path = tmp_path / "bad.mcap"
    make(path)  # type: ignore[operator]
    done = pipemap(command, str(path))
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and message in done.stderr


def test_a_missing_log_gets_one_line(tmp_path: Path) -> None:
    done = pipemap("replay", str(tmp_path / "nothing.mcap"))
    assert done.returncode == 2 and "no such file" in done.stderr


def test_an_active_run_makes_the_probe_moves_and_replay_answers_them_from_the_log(
    tmp_path: Path,
) -> None:
    """At a threshold of 0.6 the small run's 64 px decisions are weak: the placed robot
    makes the probe moves the online localizer asks for, the log holds their sweeps,
    and a replay at the same threshold finds every one of them and decides as online.
    On ``tree:3`` (5 visits): the probes need weak decisions, not a large network."""
    from tests.logs import record

    path = tmp_path / "active.mcap"
    done = record(path, "--network", "tree:3", "--condition", "active", "--threshold", "0.6")
    assert done.returncode == 0, done.stderr
    contents = read_log(path)
    commands = [
        schemas.SweepCommand.FromString(m.data) for m in contents.messages if m.topic == Topic.SWEEP
    ]
    probe_sweeps = {c.sweep_id for c in commands if c.probe}
    assert probe_sweeps, "no probe sweep in the log"
    online = [
        schemas.Decision.FromString(m.data) for m in contents.messages if m.topic == Topic.DECISION
    ]
    from pipemap.localizer import LocalizerConfig

    replayed = replay(FileSource(path), LocalizerConfig(threshold=0.6)).visits
    assert sum(len(v.decision.probes) for v in replayed) >= len(probe_sweeps)
    assert all(v.probes_not_in_log == 0 for v in replayed)
    for logged, ours in zip(online, replayed, strict=True):
        assert (logged.node, logged.known) == (ours.decision.node, ours.decision.known)
        assert [p.kind for p in logged.probes] == [
            p.request.kind.value for p in ours.decision.probes
        ]


def test_no_active_vision_asks_for_no_probe() -> None:
    """The stored active run's weak decisions take probe sweeps from the log (10 of
    them); with ``--no-active-vision`` none is asked for, and those decisions stand on
    the visit's own sweep. (The defaults' decisions are the log's committed map, which
    tests/replay/test_recordings.py checks a replay gives.)"""
    log = str(RECORDINGS / "paper_active.mcap")
    default = json.loads((RECORDINGS / "paper_active.map.json").read_text())
    without = pipemap("replay", log, "--no-active-vision")
    assert without.returncode == 0, without.stderr
    probes = [len(v["probes"]) for v in default["visits"]]
    assert sum(probes) > 0
    assert [len(v["probes"]) for v in json.loads(without.stdout)["visits"]] == [0] * len(probes)


def _probe_sweep(kind: str, yaw: float, forward: float = 0.0, left: float = 0.0) -> LoggedSweep:
    frames = np.zeros((6, 8, 8), np.uint8)
    frames.setflags(write=False)
    return LoggedSweep(3, 1, 0, frames, 1.4, 0.0, probe=(kind, yaw, forward, left))


@pytest.mark.parametrize(
    ("logged", "asked", "answered"),
    [
        # The turn the localizer asks for moves in its last digits with the arithmetic:
        # the log's probe answers it to 1e-3 rad, across the wrap at half a turn too.
        (("rotate", 1.0), ProbeRequest(ProbeKind.ROTATE, yaw_rad=1.0 + 9e-4), True),
        (("rotate", 1.0), ProbeRequest(ProbeKind.ROTATE, yaw_rad=1.0 - 9e-4), True),
        (("rotate", math.pi - 4e-4), ProbeRequest(ProbeKind.ROTATE, yaw_rad=-math.pi + 4e-4), True),
        (("rotate", 1.0), ProbeRequest(ProbeKind.ROTATE, yaw_rad=1.0 + 2e-3), False),
        # Steps are the configured distance: exact.
        (("forward", 0.0, 0.03), ProbeRequest(ProbeKind.FORWARD, forward_m=0.03), True),
        (("forward", 0.0, 0.03), ProbeRequest(ProbeKind.FORWARD, forward_m=0.0301), False),
        (("forward", 0.0, 0.03), ProbeRequest(ProbeKind.BACK, forward_m=0.03), False),
    ],
)
def test_a_logged_probe_answers_the_request_for_its_move(
    logged: tuple[Any, ...], asked: ProbeRequest, answered: bool
) -> None:
    answers = LoggedProbes([_probe_sweep(*logged)])
    got = answers.probe(asked)
    assert (got is not None) == answered
    assert answers.not_in_log == (0 if answered else 1)


def _node_event(t: int, kind: int, visit: int, exit_rad: float = 0.0) -> LogMessage:
    event = schemas.NodeEvent(time_ns=t, kind=kind, visit_id=visit, exits=3, exit_rad=exit_rad)
    return LogMessage(Topic.NODE, t, t, event.SerializeToString())


def _blocked_event(t: int, visit: int, exit_rad: float) -> LogMessage:
    from pipemap.recorder.messages import blocked_message

    return LogMessage(Topic.EVENTS, t, t, blocked_message(t, visit, exit_rad).SerializeToString())


def test_departures_given_up_are_told_apart_from_the_one_taken() -> None:
    from pipemap.recorder.messages import log_message
    from pipemap.replay.replayer import node_events_of

    NodeEvent = schemas.NodeEvent

    other = log_message(5, "pipe blocked: visit 1, exit 0.5 rad")  # not the blocked name
    messages = [
        _node_event(1, NodeEvent.DEPARTURE, 1, 0.5),
        LogMessage(Topic.EVENTS, 5, 5, other.SerializeToString()),
        _blocked_event(6, 1, 0.5),
        _node_event(7, NodeEvent.DEPARTURE, 1, -1.5),
        _node_event(9, NodeEvent.DEPARTURE, 2, 0.0),
        _blocked_event(10, 2, 0.0),  # the run ended before it left again
    ]
    events = node_events_of(messages)
    assert (events[1].blocked_rad, events[1].departure_rad) == ((0.5,), -1.5)
    assert (events[2].blocked_rad, events[2].departure_rad) == ((0.0,), None)


def test_the_latency_clock_times_the_decision_not_unpacking_the_images(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # A sweep is kept in 8 bits and made into its float32 set on use: the visit's set
    # and its probes' are made before the clock starts, as the camera's data, so the
    # latency `pipemap score` reports is the localizer's alone. paper_active has probes.
    events: list[str] = []
    made = LoggedSweep.images

    def images(sweep: LoggedSweep) -> object:
        events.append("set")
        return made.fget(sweep)  # type: ignore[attr-defined]

    def perf_counter() -> float:
        events.append("clock")
        return 0.0

    decide = replayer_module.Localizer.localize

    def localize(self: Any, *args: Any, **kwargs: Any) -> Any:
        events.append("enter")
        decision = decide(self, *args, **kwargs)
        events.append("exit")
        return decision

    monkeypatch.setattr(LoggedSweep, "images", property(images))
    monkeypatch.setattr(replayer_module, "time", types.SimpleNamespace(perf_counter=perf_counter))
    monkeypatch.setattr(replayer_module.Localizer, "localize", localize)
    source = FileSource(Path(__file__).resolve().parents[2] / "recordings" / "paper_active.mcap")
    result = replay(source)
    assert events.count("enter") == len(result.visits)
    assert events.count("set") > len(result.visits)  # the probes' sets too
    # The latency's clock is read just before each decision and just after it (the
    # readings between are the decision's phases', by the same clock).
    for k, event in enumerate(events):
        assert event != "enter" or events[k - 1] == "clock"
        assert event != "exit" or events[k + 1] == "clock"
    timing = False
    for event in events:
        timing = event == "enter" or (timing and event != "exit")
        assert not (timing and event == "set"), "a set was made while the clock ran"


def _refusal(m: LogMessage) -> bool:
    """Whether ``m`` is the warning of a probe move the robot refused."""
    return m.topic == Topic.EVENTS and refused_probe(schemas.Log.FromString(m.data)) is not None


def test_a_refused_probe_move_is_reported_as_refused_not_missing() -> None:
    """The stored autonomous run asked for probes at visit 3 whose moves the robot
    refused (a wall within the move: three warnings in its log). The replay counts
    them as refused, not as missing from the log; without those warnings the same
    requests are gaps in the log."""
    from pipemap.replay.source import MemorySource

    contents = read_log(RECORDINGS / "paper_autonomous.mcap")
    run = dict(contents.metadata[METADATA_RUN])
    messages = list(contents.messages)
    result = replay(MemorySource(messages, run, "paper_autonomous.mcap"))
    refused = {v.visit_id: v.probes_refused for v in result.visits if v.probes_refused}
    assert refused == {3: 3}
    assert sum(v.probes_not_in_log for v in result.visits) == 0
    notes = [w for w in result.warnings if "probe" in w]
    assert notes == [
        "3 probe move(s) asked for were refused by the robot (a wall within the move, as "
        "the log says); those visits were decided without them, as online"
    ]
    unanswered = [p for v in result.visits if v.visit_id == 3 for p in v.decision.probes]
    assert sorted(p.request.kind.value for p in unanswered if p.similarity is None) == [
        "forward",
        "left",
        "right",
    ]
    # The same log without the robot's warnings: the requests are missing from it.
    bare = [m for m in messages if not _refusal(m)]
    result = replay(MemorySource(bare, run, "paper_autonomous.mcap"))
    assert sum(v.probes_refused for v in result.visits) == 0
    assert sum(v.probes_not_in_log for v in result.visits) == 3
    assert [w for w in result.warnings if "probe" in w] == [
        "3 probe sweep(s) asked for are not in the log; those visits were decided without them"
    ]


def test_the_refusal_warning_reads_back() -> None:
    """The robot's note (:data:`sim.probe_moves.REFUSED_NOTE`) is what the replay reads."""
    from pipemap.recorder.messages import log_message
    from pipemap.sim.probe_moves import REFUSED_NOTE

    text = REFUSED_NOTE.format(kind="left", visit=12, why="the wall 0.024 m ahead")
    assert refused_probe(log_message(0, text, warning=True)) == (12, "left")
    assert refused_probe(log_message(0, text, warning=False)) is None
    assert refused_probe(log_message(0, "probe sweep 4 (rotate) of visit 3")) is None


@pytest.mark.parametrize(
    ("condition", "probe_moves", "makes_probes"),
    [
        ("autonomous", "false", False),
        ("autonomous", None, True),
        ("active", None, True),
        (None, None, True),
    ],
)
def test_a_missing_probe_is_a_gap_only_where_the_robot_makes_probe_moves(
    condition: str | None, probe_moves: str | None, makes_probes: bool
) -> None:
    """At a threshold of 0.6 the stored autonomous run's matches are weak and active
    vision asks for probes its log does not hold (the robot made those asked for at
    0.36). Said to be run with its probe moves off, the replay says they were not
    made, not that the log lacks them, and no decision is marked as missing any. The
    same messages of an autonomous robot that makes its moves, an ``active`` run or
    one that does not say lack them: then they are missing. (The log's warnings of the
    moves the robot refused are left out here: those are refused, not missing; see
    the test after this one.)"""
    from pipemap.replay.source import MemorySource

    contents = read_log(RECORDINGS / "paper_autonomous.mcap")
    run = dict(contents.metadata[METADATA_RUN])
    run.pop("condition")
    if condition is not None:
        run["condition"] = condition
    if probe_moves is not None:
        run["probe_moves"] = probe_moves
    kept = [m for m in contents.messages if not _refusal(m)]
    assert len(kept) < len(contents.messages)
    source = MemorySource(kept, run, "paper_autonomous.mcap")
    result = replay(source, LocalizerConfig(threshold=0.6))
    unanswered = sum(p.similarity is None for v in result.visits for p in v.decision.probes)
    assert unanswered > 0
    missing = sum(v.probes_not_in_log for v in result.visits)
    gap = f"{unanswered} probe sweep(s) asked for are not in the log"
    not_made = f"active vision asked for {unanswered} probe sweep(s); in condition 'autonomous'"
    assert missing == (unanswered if makes_probes else 0)
    # Replayed at another threshold than recorded (0.36): a note says so.
    assert sum("though recorded at 0.36" in w for w in result.warnings) == 1
    notes = [w for w in result.warnings if "probe" in w and "recorded at" not in w]
    assert len(notes) == 1
    assert notes[0].startswith(gap if makes_probes else not_made)
