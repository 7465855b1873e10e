"""The world in a child process (:mod:`sim.world_process`): the same images, ranges and
log bytes as the world in this process, however often the child is restarted; a
killed child is one line and exit 3."""

from __future__ import annotations

import logging
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pipemap.recorder.session as session
from pipemap import api
from pipemap.errors import SimError, WriteError
from pipemap.recorder import RecordSettings
from pipemap.sim import CameraSpec, World, build_network
from pipemap.sim.world_process import WorldProcess

SMALL = CameraSpec(resolution_px=40)


def _views(network: Any) -> list[tuple[tuple[float, float, float], float]]:
    views = []
    for node in network.nodes[:3]:
        for k, heading in enumerate(network.pipe_headings(node.label).values()):
            d = 0.3 * (k % 2)
            eye = (node.x_m + d * math.cos(heading) + 1e-4, node.y_m + d * math.sin(heading) + 1e-4)
            views.append(((eye[0], eye[1], 0.06), heading + 0.4 * k))
    return views


def _rays(eye: tuple[float, float, float], yaw: float) -> tuple[np.ndarray, np.ndarray]:
    dirs = [[math.cos(yaw + a), math.sin(yaw + a), 0.0] for a in (0.0, 0.6, -0.6)]
    return np.array([eye] * 3), np.array(dirs)


def _sense(world: Any, views: list[tuple[tuple[float, float, float], float]]) -> list[np.ndarray]:
    out = []
    for eye, yaw in views:
        out.append(world.render(eye, yaw, SMALL))
        out.append(world.render_tilted(eye, yaw, 0.3, 0.05, -0.04, SMALL))
        out.append(world.ray_distances_m(*_rays(eye, yaw), 1.2))
    return out


@pytest.fixture(scope="module")
def network():  # type: ignore[no-untyped-def]
    return build_network("random:8", seed=2)


@pytest.fixture(scope="module")
def in_process(network):  # type: ignore[no-untyped-def]
    with World(network, seed=7, texture_px=32) as world:
        return _sense(world, _views(network))


def test_views_before_and_after_a_restart_are_the_same(network, in_process) -> None:  # type: ignore[no-untyped-def]
    views = _views(network)
    with WorldProcess(network, seed=7, texture_px=32) as world:
        before = _sense(world, views)
        built = world.pieces_built[0]
        world.restart()
        backwards = _sense(world, list(reversed(views)))
        assert world.restarts == 1
        assert 0 < world.pieces_built[0] <= built  # a fresh child built only what it needed
    chunks = [backwards[k : k + 3] for k in range(0, len(backwards), 3)]
    after = [x for chunk in reversed(chunks) for x in chunk]  # in the order of ``views``
    assert len(before) == len(in_process) == len(after)
    for a, b, c in zip(in_process, before, after, strict=True):
        assert np.array_equal(a, b)
        assert np.array_equal(a, c)


def test_a_child_past_its_budget_is_restarted_and_draws_the_same(network, in_process) -> None:  # type: ignore[no-untyped-def]
    views = _views(network)[:2]
    # 1 MiB: every child passes it at once, so every request goes to a fresh child.
    with WorldProcess(network, seed=7, texture_px=32, memory_budget_mib=1) as world:
        got = _sense(world, views)
        assert world.restarts == len(got)  # the first child passed it when it started
        assert world.peak_child_mib > 1
    for a, b in zip(in_process, got, strict=False):
        assert np.array_equal(a, b)
    with WorldProcess(network, seed=7, texture_px=32) as roomy:  # 2 GiB: never
        _sense(roomy, views)
        assert roomy.restarts == 0
        assert not roomy.budget_warned


def test_a_budget_too_small_for_one_place_is_said_once(network, caplog) -> None:  # type: ignore[no-untyped-def]
    views = _views(network)[:3]
    with (
        caplog.at_level(logging.WARNING, logger="pipemap"),
        WorldProcess(network, seed=7, texture_px=32, memory_budget_mib=1) as world,
    ):
        _sense(world, views)
        assert world.restarts >= 2 and world.budget_warned
    said = [r.getMessage() for r in caplog.records if "holds less than one place" in r.getMessage()]
    assert len(said) == 1, said  # once, however often the child is restarted
    assert said[0].startswith("world: --world-memory 1 MiB holds less than one place")


def test_a_bad_budget_is_refused(network) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(SimError, match="budget"):
        WorldProcess(network, seed=7, memory_budget_mib=0)


def test_a_killed_child_is_a_write_error_not_a_hang(network) -> None:  # type: ignore[no-untyped-def]
    with WorldProcess(network, seed=7, texture_px=32) as world:
        eye, yaw = _views(network)[0]
        world.render(eye, yaw, SMALL)
        assert world._process is not None
        os.kill(world._process.pid, signal.SIGKILL)
        with pytest.raises(WriteError, match=r"world's process was killed \(SIGKILL\)"):
            world.render(eye, yaw, SMALL)


class _Restarted(WorldProcess):
    """A world restarted after the requests numbered ``AT``, whatever its memory: the log
    must not tell."""

    AT = (300, 1200)
    made: list[_Restarted] = []

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.requests = 0
        super().__init__(*args, **kwargs)
        _Restarted.made.append(self)

    def _take(self, reply: tuple[Any, ...]) -> Any:
        self.requests += 1
        if self.requests in self.AT:
            self.restart()
        return super()._take(reply)


@pytest.mark.parametrize("name", ["random:8", "paper"])
def test_a_log_is_the_same_bytes_with_the_world_in_a_restarted_child(
    name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    here = RecordSettings(network=name, seed=3, resolution_px=32)
    api.record(tmp_path / "here.mcap", here)
    monkeypatch.setattr(session, "WorldProcess", _Restarted)
    _Restarted.made.clear()
    child = RecordSettings(network=name, seed=3, resolution_px=32, world_memory_mib=4096)
    api.record(tmp_path / "child.mcap", child)
    (world,) = _Restarted.made
    assert world.restarts == 2, world.requests
    assert (tmp_path / "here.mcap").read_bytes() == (tmp_path / "child.mcap").read_bytes()


def _world_child_of(pid: int) -> int | None:
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        parent = int(stat[stat.rindex(")") + 2 :].split()[1])
        if parent == pid and b"pipemap.sim.world_child" in cmdline:
            return int(entry.name)
    return None


def test_record_with_its_world_killed_is_one_line_exit_3_and_a_readable_log(
    tmp_path: Path,
) -> None:
    log = tmp_path / "run.mcap"
    command = [sys.executable, "-m", "pipemap", "record", "--network", "paper"]
    command += ["--resolution", "32", "--world-memory", "2048", "-o", str(log)]
    run = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    child = None
    while child is None and time.monotonic() < deadline and run.poll() is None:
        child = _world_child_of(run.pid)
        time.sleep(0.2)
    assert child is not None, run.communicate()
    time.sleep(3.0)  # the run under way
    os.kill(child, signal.SIGKILL)
    _, err = run.communicate(timeout=120)
    assert run.returncode == 3, err
    assert err.strip().splitlines() == [
        "pipemap: error: the world's process was killed (SIGKILL); the run stops here "
        "and its log holds what was recorded before"
    ]
    info = subprocess.run(
        [sys.executable, "-m", "pipemap", "info", str(log)], capture_output=True, text=True
    )
    assert info.returncode == 0, info.stderr
