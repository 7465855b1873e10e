"""Runs whose motors cut out, end to end: ``record --motor-faults``, the log's settings,
``info`` and ``score`` (bad ``--motor-faults`` values: test_obstacle_runs.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pipemap.cli import main
from pipemap.recorder import METADATA_RUN, RecordSettings, Topic, read_log, record_run
from pipemap.recorder.schemas import Log
from pipemap.replay import FileSource
from pipemap.replay.score import score
from pipemap.sim.network import build_network

#: Three cut-outs, two in pipes (one lasts through a second) and one during a back-off.
#: At 128 px: at 64 px, below what the localizer is measured at, this walk's visits
#: differ (the cut-outs shift every later pose) and two revisits are taken for new.
NETWORK, SEED = "grid:2x3", 1


@pytest.fixture(scope="module")
def cut_out_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    path = tmp_path_factory.mktemp("motor") / "run.mcap"
    settings = RecordSettings(NETWORK, seed=SEED, resolution_px=128, motor_faults=3)
    result = record_run(path, settings, build_network(NETWORK, seed=SEED), "test")
    return path, result


def test_a_run_whose_motors_cut_out_waits_and_maps_every_pipe(
    cut_out_run: tuple[Path, object],
) -> None:
    path, result = cut_out_run
    assert result.ok  # type: ignore[attr-defined]
    source = FileSource(path)
    texts = [
        Log.FromString(m.data).message for m in source.robot_messages() if m.topic == Topic.EVENTS
    ]
    assert any("motors off" in t for t in texts)
    assert not any(t.startswith("pipe blocked") for t in texts)
    report = score(source)
    assert report.map_correct and report.blocked is None  # nothing marked blocked


def test_the_log_names_its_cut_outs_and_a_run_without_them_does_not(
    cut_out_run: tuple[Path, object], capsys: pytest.CaptureFixture[str]
) -> None:
    path, _ = cut_out_run
    simulator = json.loads(read_log(path).metadata[METADATA_RUN]["simulator"])
    assert simulator["motor_faults"]["count"] == 3
    assert simulator["motor_faults"]["recovery"]["motor_waits"] == 3
    plain = RecordSettings(NETWORK, seed=SEED).metadata(build_network(NETWORK, seed=SEED), "t")
    assert "motor_faults" not in json.loads(plain["simulator"])
    assert main(["info", str(path)]) == 0
    assert ", 3 motor cut-outs" in capsys.readouterr().out
