"""Map-driven exploration end to end: the simulator, the online localizer, the log.

* a loop network is explored completely, its map and ports are right, and a replay
  of the log makes the same decisions and, re-running the explorer, the same choices;
* a localizer forced wrong (every visit new; every visit merged) still ends the
  run, with the status ``map inconsistent``;
* ``pipemap route`` on a replayed map gives routes that the robot, driving them in
  the simulator by its localizer, follows to the asked junction.

96 px: the two-view check decides there (at 32 px the threshold does, and grid
junctions look alike to it; see the forced false merge).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from pipemap import __version__
from pipemap.localizer import Localizer, LocalizerConfig, MapExplorer, RouteStep
from pipemap.recorder import (
    METADATA_RESULT,
    Explore,
    RecordSettings,
    Topic,
    read_log,
    record_run,
    session,
)
from pipemap.recorder.schemas import Decision, Log
from pipemap.replay import FileSource, replay, score_replay
from pipemap.sim.network import build_network

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


def _record(path: Path, spec: str, resolution: int = 96, **settings: object) -> object:
    network = build_network(spec, seed=int(settings.get("seed", 0)))  # type: ignore[arg-type]
    return record_run(
        path,
        RecordSettings(network=spec, resolution_px=resolution, **settings),  # type: ignore[arg-type]
        network,
        __version__,
    )


@pytest.fixture(scope="module")
def grid_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    path = tmp_path_factory.mktemp("explore") / "grid.mcap"
    return path, _record(path, "grid:3x3")


def _events(path: Path) -> list[str]:
    contents = read_log(path, keep=lambda topic: topic == Topic.EVENTS)
    return [Log.FromString(m.data).message for m in contents.messages]


def test_a_loop_network_is_mapped_completely(grid_run: tuple[Path, object]) -> None:
    path, result = grid_run
    assert result.status == "finished" and result.ok  # type: ignore[attr-defined]
    events = _events(path)
    assert not any(e.startswith("watchdog") for e in events)
    assert "explored: every known pipe traversed" in events and events[-1] == "back at the start"
    source = FileSource(path)
    report = score_replay(replay(source), source, 0.36)
    assert report.coverage is not None and report.coverage.complete
    assert report.coverage.document() == {
        "nodes_visited": 10,
        "nodes_total": 10,
        "pipes_traversed": 13,
        "pipes_total": 13,
    }
    assert report.map_correct and report.map_status == "correct"
    assert report.ports_correct is True
    # The right-hand rule never enters the central cross r1c1 of this grid.
    assert "r1c1" in {v.true_node for v in report.visits}
    assert read_log(path).metadata["pipemap.run"]["explore"] == "map"


def test_replay_makes_the_online_decisions_and_the_explorer_its_choices(
    grid_run: tuple[Path, object],
) -> None:
    path, _ = grid_run
    contents = read_log(path, keep=lambda topic: topic == Topic.DECISION)
    online = [Decision.FromString(m.data) for m in contents.messages]
    source = FileSource(path)
    result = replay(source)
    assert len(online) == len(result.visits)
    for logged, visit in zip(online, result.visits, strict=True):
        d = visit.decision
        assert (logged.node, logged.known) == (d.node, d.known)
        assert list(logged.exit_ports) == list(d.exit_ports or ())
        assert (logged.arrival_port if logged.HasField("arrival_port") else None) == d.arrival_port
    # The explorer, fed the replay's decisions and the logged odometry, chooses every
    # port the robot left by, and stops where the robot stopped.
    localizer, explorer = Localizer(), MapExplorer()
    for visit in result.visits:
        scan = visit.exits
        assert scan is not None and scan.exits_rad is not None
        decision = localizer.localize(
            result.visit_sets[visit.sweep_id], None, scan.exits_rad, scan.odometer_m
        )
        step = explorer.step(localizer.map, decision, scan.x_m, scan.y_m, scan.odometer_m or 0.0)
        if scan.departure_rad is None:
            assert step.stop is not None and step.stop.value == "finished"
        else:
            assert localizer.depart(scan.departure_rad) == step.port


def test_a_false_new_node_every_visit_ends_the_run(tmp_path: Path) -> None:
    # At 32 px the threshold decides; at 1.0 no revisit reaches it. Every revisit
    # makes a new junction with pipes to explore: without a stop, this never ends.
    # tree:3 (S n1 n2) shows it at its first revisit, n1 on the way back.
    path = tmp_path / "new.mcap"
    result = _record(path, "tree:3", 32, threshold=1.0)
    assert result.status == "map inconsistent" and not result.ok  # type: ignore[attr-defined]
    events = _events(path)
    assert events[-1] == "stopped: map inconsistent"
    assert any("by odometry" in e for e in events)
    source = FileSource(path)
    report = score_replay(replay(source, LocalizerConfig(threshold=1.0)), source, 1.0)
    assert report.counts()["false_new"] >= 1
    assert report.map_status != "correct"
    meta = read_log(path).metadata[METADATA_RESULT]
    assert meta["status"] == "map inconsistent"
    assert int(meta["duration_ns"]) < 600 * 10**9  # far from the one-hour watchdog


def _images_alone(threshold: float, **_: object) -> LocalizerConfig:
    """The online localizer deciding by the similarity threshold alone: no two-view
    check, and neither the exits nor the dead reckoning compared (a fault injected for
    the test; the session's own settings are ignored)."""
    return LocalizerConfig(
        threshold=threshold,
        two_view=False,
        verify=False,
        port_check=False,
        odometry_check=False,
    )


#: The loop network of the forced-decision runs below (32 px, a few junctions).
LOOP = "grid:2x2"


def test_a_false_merge_every_visit_ends_the_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # At -1, with the exits not compared, every visit is taken for a known junction.
    # (With them compared, this run maps right: the test below.) The smallest loop,
    # grid:2x2, stops as grid:3x3 does, after two false merges, at half the cost.
    monkeypatch.setattr(session, "LocalizerConfig", _images_alone)
    path = tmp_path / "merge.mcap"
    result = _record(path, LOOP, 32, threshold=-1.0)
    assert result.status == "map inconsistent"  # type: ignore[attr-defined]
    assert result.duration_ns < 600 * 10**9  # type: ignore[attr-defined]
    source = FileSource(path)
    report = score_replay(replay(source, _images_alone(-1.0)), source, -1.0)
    assert report.counts()["false_merge"] >= 1
    assert _events(path)[-1] == "stopped: map inconsistent"


def test_the_exits_alone_keep_a_threshold_of_minus_1_from_merging(tmp_path: Path) -> None:
    # The same run as above, the exits compared (the default): at -1 every candidate
    # passes the threshold, and every wrong one is passed over because its ports do
    # not line up with the visit's exits through the images' rotation.
    # Evenly lit: under the lamp the 32 px NCC turns crosses by a quarter or a half,
    # so true revisits fail the port check too (false new junctions, and the run
    # stops `map inconsistent`): the exits need a right rotation to judge by.
    # The odometry check off, online and in the replay: the dead reckoning would pass
    # over most wrong candidates before their ports are compared.
    path = tmp_path / "checked.mcap"
    # On grid:2x2 every corner has the same two ports at a right angle: only their
    # rotation, measured from the images, tells the candidates apart (three visits
    # pass a wrong one over).
    settings = {"threshold": -1.0, "lamp_strength": 0.0, "odometry_check": False}
    result = _record(path, LOOP, 32, **settings)
    assert result.status == "finished" and result.ok  # type: ignore[attr-defined]
    source = FileSource(path)
    config = LocalizerConfig(threshold=-1.0, odometry_check=False)
    report = score_replay(replay(source, config), source, -1.0)
    assert report.map_status == "correct" and report.counts()["false_merge"] == 0
    assert any(v.decision.rejected for v in replay(source, config).visits)


def test_the_right_hand_rule_is_still_there_and_its_map_is_partial(tmp_path: Path) -> None:
    path = tmp_path / "rh.mcap"
    result = _record(path, "grid:2x3", explore=Explore.RIGHT_HAND)
    # It goes round the outside of the grid: every junction, but never the middle pipe
    # r0c1-r1c1. The robot believes it is done; the truth says it is not.
    assert result.status == "finished" and not result.ok  # type: ignore[attr-defined]
    assert (result.pipes_driven, result.pipe_count) == (7, 8)  # type: ignore[attr-defined]
    assert len(result.true_nodes) == 7  # type: ignore[attr-defined]
    assert read_log(path).metadata["pipemap.run"]["explore"] == "right-hand"
    source = FileSource(path)
    report = score_replay(replay(source), source, 0.36)
    # Every decision right and the map right as far as it goes, but not the network.
    assert report.counts()["false_merge"] == report.counts()["false_new"] == 0
    assert not report.map_correct and report.map_status == "partial"
    assert report.ports_correct is True


# --- routes ---------------------------------------------------------------------------


def pipemap(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, timeout=300
    )


def test_routes_on_a_replayed_map_lead_the_robot_to_the_asked_junction(tmp_path: Path) -> None:
    from pipemap.recorder.online import drive_route
    from pipemap.replay.score import true_sweeps
    from pipemap.sim.world import CameraSpec, World

    log = RECORDINGS / "random8_loops.mcap"  # random:8 seed 0, a loop, 96 px
    source = FileSource(log)
    result = replay(source)
    truth = true_sweeps(source)
    true_node = {}  # map node -> the true junction it stands for
    for v in result.visits:
        true_node.setdefault(v.decision.node, truth[v.sweep_id].node)
    map_json = tmp_path / "map.json"
    map_json.write_text(json.dumps(result.document()))
    assert result.localizer is not None
    localizer = result.localizer
    camera = CameraSpec(resolution_px=96)
    arrived = []
    with World(build_network("random:8", seed=0), seed=0) as world:
        # Round the loop both ways, and down the branch off it.
        for goal in (4, 6, 7):
            done = pipemap("route", str(map_json), "--from", "0", "--to", str(goal), "--json")
            assert done.returncode == 0, done.stderr
            route = json.loads(done.stdout)
            assert route[0]["node"] == 0 and route[-1]["node"] == goal
            steps = [
                RouteStep(s["node"], s["arrive_port"], s["leave_port"], s["edge"]) for s in route
            ]
            run, online = drive_route(world, camera, localizer, steps, seed=goal)
            assert run.status.value == "finished"
            last = run.sweep_truths[-1].node
            visited = [s.node for s in run.sweep_truths]
            assert last == true_node[goal], (goal, visited)
            # It went the planned way: one sweep per junction of the route.
            assert visited == [true_node[s.node] for s in steps]
            assert all(d.known for d in online.decisions.values())
            arrived.append(last)
    assert len(set(arrived)) == 3


def test_route_prints_the_way_junction_by_junction() -> None:
    done = pipemap("route", str(RECORDINGS / "random8_loops.map.json"), "--from", "0", "--to", "5")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "at node 0, leave by port 0"
    assert lines[1].startswith("at node 1, arriving by port 0, leave by port ")
    assert lines[-2].startswith("arrive at node 5 by port ")
    assert lines[-1].endswith("m by the map")
    assert math.isfinite(float(lines[-1].split(", ")[1].split()[0]))


@pytest.mark.parametrize(
    "args, message",
    [
        (("--from", "0", "--to", "42"), "--to 42: no such node"),
        (("--from", "x", "--to", "1"), "argument --from"),
        (("--from", "-1", "--to", "1"), "argument --from"),
    ],
)
def test_route_with_an_unknown_node_is_one_line_and_exit_2(
    args: tuple[str, ...], message: str
) -> None:
    done = pipemap("route", str(RECORDINGS / "random8_loops.map.json"), *args)
    assert done.returncode == 2
    assert done.stdout == ""
    assert len(done.stderr.splitlines()) == 1 and message in done.stderr


def test_route_to_an_id_the_map_leaves_unused_is_one_line_and_exit_2(tmp_path: Path) -> None:
    # Competing maps draw junction ids from one pool; the map that won may leave one
    # unused (docs/lookalike.md). It is no junction to route to.
    doc = json.loads((RECORDINGS / "random8_loops.map.json").read_text())
    unused = len(doc["nodes"])
    doc["nodes"].append({"id": unused, "unused": True, "ports": []})
    path = tmp_path / "pooled.json"
    path.write_text(json.dumps(doc))
    done = pipemap("route", str(path), "--from", "0", "--to", str(unused))
    assert done.returncode == 2 and done.stdout == ""
    assert len(done.stderr.splitlines()) == 1
    assert f"--to {unused}: {path} leaves that id unused" in done.stderr


def _map_without_ports(tmp_path: Path) -> Path:
    doc = json.loads((RECORDINGS / "random8_loops.map.json").read_text())
    for node in doc["nodes"]:
        node["ports"] = []
    for edge in doc["edges"]:
        edge["u_port"] = edge["v_port"] = None
    path = tmp_path / "portless.json"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(
    "make, message",
    [
        (_map_without_ports, "the map has no ports"),
        (lambda t: _write(t, "not json {"), "not a JSON map document"),
        (lambda t: _write(t, "[1, 2]"), "malformed map"),
        (lambda t: _write(t, '{"nodes": [{"id": 0}], "edges": [{"u": 0}]}'), "malformed map"),
        (lambda t: t / "missing.json", "no such file"),
    ],
)
def test_route_on_a_bad_map_is_one_line_and_exit_2(tmp_path: Path, make, message: str) -> None:  # type: ignore[no-untyped-def]
    path = make(tmp_path)
    done = pipemap("route", str(path), "--from", "0", "--to", "1")
    assert done.returncode == 2
    assert len(done.stderr.splitlines()) == 1 and message in done.stderr, done.stderr


def _write(folder: Path, text: str) -> Path:
    path = folder / "bad.json"
    path.write_text(text)
    return path


def test_no_route_is_exit_1(tmp_path: Path) -> None:
    doc = json.loads((RECORDINGS / "random8_loops.map.json").read_text())
    doc["edges"] = [e for e in doc["edges"] if 7 not in (e["u"], e["v"])]
    path = tmp_path / "cut.json"
    path.write_text(json.dumps(doc))
    done = pipemap("route", str(path), "--from", "0", "--to", "7", "--json")
    assert done.returncode == 1
    assert "no route from node 0 to node 7" in done.stdout
