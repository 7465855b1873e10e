"""Each command goes through :mod:`pipemap.api`, as a script does: the api function is
replaced by a spy that stops the command, and the spy must be called, with the
settings the flags parsed into. A command that goes around the api again fails here."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from pipemap import api
from pipemap.cli import main

ROOT = Path(__file__).resolve().parents[2]
STORED = ROOT / "recordings" / "paper_autonomous.mcap"


class Called(Exception):
    """What the spy raises: the command got as far as the api."""


def _spy(
    monkeypatch: pytest.MonkeyPatch, name: str
) -> list[tuple[tuple[Any, ...], dict[str, Any]]]:
    calls: list[tuple[tuple[Any, ...], dict[str, Any]]] = []

    def spy(*args: Any, **kwargs: Any) -> Any:
        calls.append((args, kwargs))
        raise Called(name)

    monkeypatch.setattr(api, name, spy)
    return calls


def test_record_calls_api_record_with_the_parsed_settings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _spy(monkeypatch, "record")
    target = tmp_path / "run.mcap"
    argv = ["record", "--network", "paper", "--resolution", "32", "--images", "9"]
    with pytest.raises(Called):
        main([*argv, "--seed", "4", "--lighting", "even", "-o", str(target)])
    (path, settings, *_), _ = calls[0]
    assert Path(path) == target
    assert (settings.network, settings.resolution_px, settings.images_per_sweep) == ("paper", 32, 9)
    assert (settings.seed, settings.lamp_strength) == (4, 0.0)


def test_sim_calls_api_simulate_with_the_parsed_settings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _spy(monkeypatch, "simulate")
    target = tmp_path / "sweeps"
    argv = ["sim", "--network", "tree:3", "--resolution", "48", "--condition", "noise"]
    with pytest.raises(Called):
        main([*argv, "--tilt-deg", "2", "--save-sweeps", str(target)])
    (folder, settings, *_), _ = calls[0]
    assert Path(folder) == target
    assert (settings.network, settings.resolution_px, settings.condition.value) == (
        "tree:3",
        48,
        "noise",
    )
    assert settings.tilt_rad == pytest.approx(0.0349, abs=1e-4)


def test_replay_calls_api_replay_with_the_parsed_config(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = _spy(monkeypatch, "replay")
    with pytest.raises(Called):
        main(["replay", str(STORED), "--threshold", "0.5"])
    (_, config, *_), _ = calls[0]
    assert config.threshold == 0.5


@pytest.mark.parametrize("logs", [1, 2])
def test_score_calls_api_score_for_each_log(monkeypatch: pytest.MonkeyPatch, logs: int) -> None:
    calls = _spy(monkeypatch, "score")
    with pytest.raises(Called):
        main(["score", *[str(STORED)] * logs, "--threshold", "0.42"])
    (_, config, *_), _ = calls[0]
    assert config.threshold == 0.42


def test_view_calls_api_view_with_the_parsed_settings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _spy(monkeypatch, "view")
    target = tmp_path / "v.rrd"
    argv = ["view", str(STORED), "--threshold", "0.3", "--max-rate", "4", "--save", str(target)]
    with pytest.raises(Called):
        main(argv)
    (path, config, save, max_rate, *_), _ = calls[0]
    assert (Path(path), Path(save), max_rate) == (STORED, target, 4.0)
    assert config.threshold == 0.3


def test_view_replays_through_api_replay(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from pipemap import viewing

    # In one process (the forked child would report the spy's exception as its own).
    monkeypatch.setattr(viewing, "_can_fork", lambda: False)
    calls = _spy(monkeypatch, "replay")
    with pytest.raises(Called):
        main(["view", str(STORED), "--threshold", "0.3", "--save", str(tmp_path / "v.rrd")])
    (_, config, *_), _ = calls[0]
    assert config.threshold == 0.3


def test_info_calls_api_log_info(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = _spy(monkeypatch, "log_info")
    with pytest.raises(Called):
        main(["info", str(STORED)])
    (path,), _ = calls[0]
    assert Path(path) == STORED


def test_route_calls_api_load_map_and_route(monkeypatch: pytest.MonkeyPatch) -> None:
    document = ROOT / "recordings" / "paper_autonomous.map.json"
    loads = _spy(monkeypatch, "load_map")
    with pytest.raises(Called):
        main(["route", str(document), "--from", "0", "--to", "3"])
    assert Path(loads[0][0][0]) == document
    monkeypatch.undo()
    routes = _spy(monkeypatch, "route")
    with pytest.raises(Called):
        main(["route", str(document), "--from", "0", "--to", "3"])
    (_, start, goal, *_), _ = routes[0]
    assert (start, goal) == (0, 3)


def test_a_batch_run_records_and_scores_through_the_api(monkeypatch: pytest.MonkeyPatch) -> None:
    """``pipemap batch``'s workers make each run as a script does: api.record, then
    api.score of the log, with the settings of the SPEC's grid point."""
    import shutil

    from pipemap.batch.run import run_recording
    from pipemap.batch.spec import parse_spec
    from pipemap.recorder import RecordResult

    spec = parse_spec('[grid]\nnetwork = ["paper"]\nresolution = [32]\nthreshold = [0.4]\n')
    recorded: list[Any] = []

    def record(path: Path, settings: Any, **kwargs: Any) -> RecordResult:
        recorded.append(settings)
        shutil.copyfile(STORED, path)  # a log to score
        return RecordResult("finished", True, 13, 13, 1.0, 1, 1, frozenset("S"), 7)

    monkeypatch.setattr(api, "record", record)
    scores = _spy(monkeypatch, "score")
    with pytest.raises(Called):
        run_recording(spec.points)
    assert recorded == [spec.points[0].record_settings()]
    (_, config), _ = scores[0]
    assert config.threshold == 0.4


def test_batch_plans_and_runs_through_pipemap_batch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``pipemap batch`` is :func:`pipemap.batch.run_batch` on the plan of
    :func:`pipemap.batch.plan_batch`, with the flags' options, as a script calls them."""
    import pipemap.batch

    plans: list[Any] = []

    def run_batch(plan: Any, progress: Any = None) -> Any:
        plans.append(plan)
        raise Called("run_batch")

    monkeypatch.setattr(pipemap.batch, "run_batch", run_batch)
    spec = ROOT / "experiments" / "small.toml"
    with pytest.raises(Called):
        main(["batch", str(spec), "--out", str(tmp_path / "b"), "--workers", "1", "--keep-logs"])
    (plan,) = plans
    assert plan.out == tmp_path / "b"
    assert (plan.options.workers, plan.options.keep_logs) == (1, True)
    assert plan.spec == pipemap.batch.load_spec(spec)
