"""Runs with floor deposits, end to end: ``record --obstacles``, replay, score, and
the bad input that is refused before any work."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pipemap.cli import main
from pipemap.recorder import RecordSettings, Topic, record_run
from pipemap.recorder.messages import blocked_visit
from pipemap.recorder.schemas import Log
from pipemap.replay import FileSource, replay
from pipemap.replay.score import score
from pipemap.sim.controller import default_time_limit_ns
from pipemap.sim.network import build_network

#: grid:2x3, seed 1, three deposits: blocking in r0c1-r0c2 and r1c0-r1c1, passable
#: in r0c2-r1c2 (tests/sim/test_obstacles.py checks placement on its own).
NETWORK, SEED, COUNT = "grid:2x3", 1, 3


@pytest.fixture(scope="module")
def obstacle_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    path = tmp_path_factory.mktemp("obstacles") / "run.mcap"
    settings = RecordSettings(NETWORK, seed=SEED, resolution_px=64, obstacles=COUNT)
    result = record_run(path, settings, build_network(NETWORK, seed=SEED), "test")
    return path, result


def _events(path: Path) -> list[Log]:
    source = FileSource(path)
    return [Log.FromString(m.data) for m in source.robot_messages() if m.topic == Topic.EVENTS]


def test_a_run_with_deposits_recovers_gives_up_the_blocked_pipes_and_finishes(
    obstacle_run: tuple[Path, object],
) -> None:
    path, result = obstacle_run
    assert result.status == "finished" and result.ok  # type: ignore[attr-defined]
    # It never hangs: well within the time limit.
    limit = default_time_limit_ns(build_network(NETWORK, seed=SEED))
    assert result.duration_ns < limit / 4  # type: ignore[attr-defined]
    texts = [e.message for e in _events(path)]
    assert any(t.startswith("stall: past it") for t in texts)  # the passable deposit
    given_up = [blocked_visit(e) for e in _events(path) if blocked_visit(e) is not None]
    assert len(given_up) >= 2  # each blocked pipe, from at least one side


def test_score_counts_the_blocked_pipes_and_the_map_is_correct(
    obstacle_run: tuple[Path, object],
) -> None:
    path, _ = obstacle_run
    report = score(FileSource(path))
    assert report.blocked is not None
    assert report.blocked.true_positives == [("r0c1", "r0c2"), ("r1c0", "r1c1")]
    assert report.blocked.false_blocked == [] and report.blocked.missed == []
    assert report.map_correct
    doc = report.document(with_latency=False)
    assert doc["blocked"]["truly_blocked"] == ["r0c1-r0c2", "r1c0-r1c1"]
    assert doc["coverage"]["open_pipes_traversed"] == doc["coverage"]["open_pipes"] == 6


def test_replay_rebuilds_the_blocked_marks_from_the_robot_alone(
    obstacle_run: tuple[Path, object],
) -> None:
    path, _ = obstacle_run
    first = replay(FileSource(path)).topomap
    again = replay(FileSource(path)).topomap
    assert first.to_json() == again.to_json()
    marks = [(n, p) for n in range(first.node_count) for p in first.blocked(n)]
    blocked_events = [e for e in _events(path) if blocked_visit(e) is not None]
    assert len(marks) == len(blocked_events)
    assert first.to_json().count('"blocked": true') == len(marks)


def test_the_log_records_the_obstacle_setting_and_the_deposits_as_truth(
    obstacle_run: tuple[Path, object],
) -> None:
    from pipemap.replay.coverage import true_network

    path, _ = obstacle_run
    source = FileSource(path)
    simulator = json.loads(source.run_metadata()["simulator"])
    assert simulator["obstacles"]["count"] == COUNT
    assert simulator["obstacles"]["recovery"]["tries"] == 3
    truth = true_network(source)
    assert truth is not None
    assert sorted(kind for _, kind in truth.deposits) == ["blocking", "blocking", "passable"]


def test_info_names_the_obstacle_setting(
    obstacle_run: tuple[Path, object], capfd: pytest.CaptureFixture[str]
) -> None:
    path, _ = obstacle_run
    assert main(["info", str(path)]) == 0
    run = next(line for line in capfd.readouterr().out.splitlines() if line.startswith("run "))
    assert run.endswith(f"64 px, 6 images, {COUNT} obstacles")


def test_without_obstacles_the_settings_say_nothing_of_them() -> None:
    network = build_network("paper")
    simulator = json.loads(RecordSettings("paper").metadata(network, "t")["simulator"])
    assert "obstacles" not in simulator
    assert RecordSettings("paper").deposits(network) == ()


def _run(argv: list[str], capfd: pytest.CaptureFixture[str]) -> tuple[int, str]:
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse errors
        status = int(exc.code or 0)
    return status, capfd.readouterr().err


@pytest.mark.parametrize("command", ["record", "sim"])
@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--obstacles", "-1"], "argument --obstacles: an obstacle count must be >= 0"),
        (["--obstacles", "x"], "argument --obstacles: not a number"),
        (["--obstacles", "40"], "--obstacles 40:"),
        (["--obstacles", "1", "--condition", "perfect"], "--obstacles: only the autonomous"),
        (["--motor-faults", "-1"], "argument --motor-faults: a cut-out count must be >= 0"),
        (["--motor-faults", "1", "--condition", "perfect"], "--motor-faults: only the autonomous"),
    ],
)
def test_bad_deposit_and_cut_out_settings_are_one_line_and_exit_2(
    command: str,
    extra: list[str],
    says: str,
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
) -> None:
    output = ["-o", str(tmp_path / "x.mcap")] if command == "record" else []
    if command == "sim":  # placed by hand by default: a robot that drives
        output = ["--save-sweeps", str(tmp_path / "sweeps")]
        extra = ["--condition", "autonomous", *extra]
    status, err = _run([command, "--network", "paper", *extra, *output], capfd)
    assert status == 2
    assert err.count("\n") == 1 and err.startswith("pipemap: error: ") and says in err
    assert not (tmp_path / "x.mcap").exists() and not (tmp_path / "sweeps").exists()


def test_sim_drives_into_the_deposits_it_is_given(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    argv = ["sim", "--network", NETWORK, "--seed", str(SEED), "--resolution", "32"]
    argv += ["--condition", "autonomous", "--save-sweeps", str(tmp_path / "s")]
    status = main([*argv, "--obstacles", str(COUNT)])
    out = capfd.readouterr().out
    # At 32 px the run visits every junction: the robot gets past the passable
    # deposit twice and gives up each blocked pipe from both of its ends.
    assert "7/7 nodes (6/8 pipes)" in out and "finished" in out, out
    assert f"{COUNT} deposits: got past 2 stall(s), gave up 4 pipe(s) as blocked" in out, out
    assert status in (0, 1)


def test_the_live_view_decides_as_the_replay_with_the_blocked_pipes(
    obstacle_run: tuple[Path, object], tmp_path: Path
) -> None:
    """A run shown live (the log's messages as the run wrote them) decides each visit as
    its replay does, the pipes given up as blocked included."""
    from pipemap.localizer import LocalizerConfig
    from pipemap.recorder import METADATA_RUN, read_log
    from pipemap.replay.live import LiveView
    from pipemap.replay.view import describe_decision, recording
    from tests.replay.test_view import column, read_chunks

    path, _ = obstacle_run
    contents = read_log(path)
    run = contents.metadata[METADATA_RUN]
    rec = recording(run)
    rec.save(tmp_path / "live.rrd")
    with LiveView(rec, run, LocalizerConfig()) as live:
        live.show(list(contents.messages))
    shown = read_chunks(tmp_path / "live.rrd")
    replayed = replay(FileSource(path))
    texts = column(shown, "/log/decisions", "TextLog:text")
    assert texts == [[describe_decision(v)] for v in replayed.visits]
    marks = [
        (n, p) for n in range(replayed.topomap.node_count) for p in replayed.topomap.blocked(n)
    ]
    assert (
        marks and [(n, p) for n in range(live.map.node_count) for p in live.map.blocked(n)] == marks
    )
