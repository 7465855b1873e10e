"""A network whose world would not fit in memory is refused before anything is built."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipemap import api
from pipemap.errors import SimError
from pipemap.recorder import RecordSettings
from pipemap.sim import world_budget
from pipemap.sim.network import build_network
from pipemap.sim.world_budget import check_world_fits, pipe_metres, world_mib
from tests.cli.common import run


def test_a_world_that_fits_passes_and_one_that_does_not_is_refused(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    paper = build_network("paper")  # 7 nodes, 6 pipes, 7 m
    monkeypatch.setattr(world_budget, "available_mib", lambda: world_mib(paper) + 1)
    check_world_fits(paper, "paper")
    monkeypatch.setattr(world_budget, "available_mib", lambda: world_mib(paper) - 1)
    with pytest.raises(SimError, match=r"network 'paper': its world would take about 0\.2 GiB"):
        check_world_fits(paper, "paper")
    monkeypatch.setattr(world_budget, "available_mib", lambda: None)  # cannot tell: go on
    check_world_fits(paper, "paper")


def test_a_world_in_a_child_process_is_refused_only_past_its_budget(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    town = build_network("random:1000")  # about 46 GiB whole
    monkeypatch.setattr(world_budget, "available_mib", lambda: 4096.0)
    with pytest.raises(SimError, match="its world would take about 46.2 GiB"):
        check_world_fits(town, "random:1000")
    check_world_fits(town, "random:1000", world_memory_mib=2048)
    with pytest.raises(SimError, match=r"--world-memory 5000: more than the 4\.0 GiB"):
        check_world_fits(town, "random:1000", world_memory_mib=5000)


def test_the_estimate_follows_the_metres_of_pipe_not_the_nodes_alone() -> None:
    # The same tree with pipes four and ten times as long: the same nodes and pipes,
    # built whole 184, 348 and 690 MiB (the module's docstring).
    worlds = [build_network("tree:6", seed=0, spacing_m=s) for s in (1.0, 4.0, 10.0)]
    assert [round(pipe_metres(w), 1) for w in worlds] == [6.3, 25.1, 62.7]
    for world, built_mib in zip(worlds, (184.0, 348.0, 690.0), strict=True):
        assert abs(world_mib(world) - built_mib) < 0.15 * built_mib
    # A town grid's long pipes: about 10 GiB, three times what 30 MiB a node said.
    grid = build_network("grid:11x11", seed=1)
    assert 9.0 * 1024 < world_mib(grid) < 11.0 * 1024
    assert world_mib(grid) > 2.5 * 30.0 * len(grid.nodes)


def test_the_machine_says_what_it_has_available() -> None:
    have = world_budget.available_mib()
    assert have is None or have > 0


@pytest.mark.parametrize("command", ["record", "sim"])
def test_the_commands_refuse_it_with_one_line_and_write_nothing(
    command: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capfd: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr(world_budget, "available_mib", lambda: 100.0)
    out = tmp_path / "out"
    flag = ["-o", str(out)] if command == "record" else ["--save-sweeps", str(out)]
    status, _, err = run([command, "--network", "paper", *flag], capfd)
    assert status == 2
    assert err.splitlines() == [
        "pipemap: error: network 'paper': its world would take about 0.2 GiB (7 nodes, "
        "6 pipes, 7 m of pipe), more than the 0.1 GiB this machine has available "
        "(--world-memory keeps it in a child process of bounded memory)"
    ]
    assert not out.exists()


def test_the_api_refuses_it_before_the_log_is_opened(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(world_budget, "available_mib", lambda: 100.0)
    with pytest.raises(SimError, match="its world would take"):
        api.record(tmp_path / "run.mcap", RecordSettings(network="paper"))
    assert not (tmp_path / "run.mcap").exists()
