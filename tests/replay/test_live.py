"""``pipemap record --view``: the run streamed live to a real rerun server.

The server is rerun's own, started headless for the module on a free loopback port
with ``--save``, so that what it receives is written to an ``.rrd`` as it arrives;
it is stopped at the end, also on failure. While ``pipemap record --view --connect``
runs, the test reads what the server has received so far and checks that images,
the map and the scalars are there before the log is finished (an MCAP file ends
with its magic bytes only once the writer has closed it, after the last sweep).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from pipemap.cli import view_command
from pipemap.errors import ViewerError
from pipemap.recorder import METADATA_RESULT, Topic, read_log
from pipemap.replay import FileSource, replay
from pipemap.replay.live import LiveView, LiveViewProcess
from pipemap.replay.view import describe_decision
from pipemap.replay.web import stop
from tests.logs import SMALL_RUN, sweeps_started
from tests.replay.test_view import column, free_port, read_chunks, rows, run

#: What has to arrive while the run goes: an image, the map, a scalar series.
LIVE = ("/camera/image", "/map", "/sensors/tof/range_m")
_MCAP_MAGIC = b"\x89MCAP0\r\n"
_TIMEOUT_S = 300.0


@dataclass(frozen=True)
class Server:
    """A headless rerun server on loopback that saves what it receives."""

    url: str
    saved: Path
    process: subprocess.Popen[bytes]


def _wait_listening(port: int, process: subprocess.Popen[bytes]) -> None:
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        assert process.poll() is None, "the rerun server ended before it listened"
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1.0).close()
            return
        except OSError:
            time.sleep(0.1)
    raise AssertionError(f"the rerun server did not listen on port {port}")


def _stop(process: subprocess.Popen[Any]) -> None:
    stop(process, timeout_s=20.0)


def _stop_server(process: subprocess.Popen[Any]) -> None:
    """Stop the server, started in a session of its own, and everything in it: the
    ``rerun`` on PATH may be a wrapper (a pyenv shim, rerun-sdk's Python entry point)
    that runs the server as a child and does not pass SIGTERM on. Stopping the
    wrapper alone left the server running after the tests."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, sig)
        try:
            process.wait(timeout=20)
            return
        except subprocess.TimeoutExpired:
            continue


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    found = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    assert Path(found).exists(), "the rerun CLI of rerun-sdk is not installed"
    port = free_port()
    saved = tmp_path_factory.mktemp("server") / "received.rrd"
    process = subprocess.Popen(
        [found, "--bind", "127.0.0.1", "--port", str(port), "--save", str(saved)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "RERUN_ANALYTICS": "false"},
        start_new_session=True,
    )
    try:
        _wait_listening(port, process)
        yield Server(f"rerun+http://127.0.0.1:{port}/proxy", saved, process)
    finally:
        _stop_server(process)


def _read(path: Path) -> dict[str, list[Any]]:
    """``read_chunks`` of a stream the server saved: it has no footer, which rerun's
    reader warns about (and then reads the stream whole)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="RRD file has no footer")
        return read_chunks(path)


def _received(saved: Path, copy: Path) -> dict[str, list[Any]]:
    """What the server has written so far, read from a copy (the last message may be
    half written: the reader then gives what precedes it, or nothing)."""
    if not saved.exists():
        return {}
    shutil.copyfile(saved, copy)
    try:
        return _read(copy)
    except Exception:  # noqa: BLE001 - a stream cut mid-message; try again later
        return {}


def _finished(log: Path) -> bool:
    """Whether the recorder has closed ``log`` (an MCAP file ends with its magic)."""
    try:
        with log.open("rb") as f:
            f.seek(-len(_MCAP_MAGIC), os.SEEK_END)
            return f.read() == _MCAP_MAGIC
    except OSError:
        return False


@pytest.fixture(scope="module")
def streamed(
    server: Server, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Server, Path, dict[str, list[Any]], subprocess.CompletedProcess[str]]:
    """``pipemap record --view --connect`` of the small run; what the server had
    received at the first moment images, map and scalars were all there, checked to
    be before the log was finished; the command's outcome."""
    tmp_path = tmp_path_factory.mktemp("live")
    log = tmp_path / "live.mcap"
    command = [sys.executable, "-m", "pipemap", "record", *SMALL_RUN, "-o", str(log)]
    process = subprocess.Popen(
        [*command, "--view", "--connect", server.url],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    during: dict[str, list[Any]] | None = None
    try:
        deadline = time.monotonic() + _TIMEOUT_S
        while process.poll() is None and time.monotonic() < deadline:
            seen = _received(server.saved, tmp_path / "snapshot.rrd")
            # Read first, then look at the log: if it is still open now, what was
            # read arrived while the run was going.
            if all(entity in seen for entity in LIVE) and not _finished(log):
                during = seen
                break
            time.sleep(0.2)
        stdout, stderr = process.communicate(timeout=_TIMEOUT_S)
    finally:
        _stop(process)
    done = subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)
    assert done.returncode == 0, done.stderr
    assert during is not None, "images, map and scalars did not all arrive during the run"
    return server, log, during, done


def test_images_map_and_scalars_arrive_while_the_run_goes(
    streamed: tuple[Server, Path, dict[str, list[Any]], subprocess.CompletedProcess[str]],
) -> None:
    server, log, during, done = streamed
    assert rows(during, "/camera/image", "EncodedImage:blob") > 0
    assert rows(during, "/sensors/tof/range_m", "Scalars:scalars") > 0
    grown = rows(during, "/map", "GraphNodes:node_ids")
    visits = len(replay(FileSource(log)).visits)
    assert 0 < grown < visits  # the map had some of the run's decisions, not all yet
    last = done.stdout.splitlines()[-1]
    sweeps, replayed = sweeps_started(log), replay(FileSource(log))
    assert sweeps == visits  # a run without probe sweeps: one sweep a visit
    assert last == (
        f"streamed {log}: {sweeps} sweeps, {6 * sweeps} images, {visits} visits, "
        f"{replayed.topomap.node_count} junctions, to {server.url}"
    )


def test_the_live_view_ends_holding_the_whole_run_and_its_replay(
    streamed: tuple[Server, Path, dict[str, list[Any]], subprocess.CompletedProcess[str]],
) -> None:
    server, log, _, _ = streamed
    _stop_server(server.process)  # the server closes its file
    received = _read(server.saved)
    counts = read_log(log).counts
    assert rows(received, "/camera/image", "EncodedImage:blob") == counts[Topic.IMAGE]
    # The ranges at most 10 a second (the view's default): one in each tenth of a second.
    slots = {
        m.log_time_ns // 100_000_000 for m in read_log(log).messages if m.topic == Topic.RANGES
    }
    assert rows(received, "/sensors/tof/range_m", "Scalars:scalars") == len(slots)
    assert len(slots) < counts[Topic.RANGES]
    # The map grows at each decision into the replay's: the same decisions, in order.
    replayed = replay(FileSource(log))
    assert column(received, "/log/decisions", "TextLog:text") == [
        [describe_decision(v)] for v in replayed.visits
    ]
    nodes = column(received, "/map", "GraphNodes:node_ids")
    assert [len(n) for n in nodes] == [
        len({v.decision.node for v in replayed.visits[: i + 1]})
        for i in range(len(replayed.visits))
    ]


def test_the_log_is_the_same_bytes_with_the_live_view(
    streamed: tuple[Server, Path, dict[str, list[Any]], subprocess.CompletedProcess[str]],
    recorded_run: Path,
) -> None:
    _, log, _, _ = streamed
    assert log.read_bytes() == recorded_run.read_bytes()


def test_a_live_view_that_stops_is_reported_and_does_not_hang(
    capfd: pytest.CaptureFixture[str],
) -> None:
    def no_viewer() -> LiveView:
        raise RuntimeError("no viewer here")

    live = LiveViewProcess(no_viewer)
    live([])  # to a child that is gone, or going: dropped, not raised
    with pytest.raises(ViewerError, match="the live view stopped before the end of the run"):
        live.close()
    assert "RuntimeError: no viewer here" in capfd.readouterr().err


def test_record_goes_on_and_says_so_when_the_live_view_stops(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_viewer() -> LiveView:
        raise RuntimeError("no viewer here")

    monkeypatch.setenv("DISPLAY", ":0")  # a display to spawn on; the view fails instead
    monkeypatch.setattr(view_command, "live_view", lambda *_: LiveViewProcess(no_viewer))
    log = tmp_path / "run.mcap"
    # tree:3: a run for the view to stop in, in a cheap world.
    argv = ["record", *SMALL_RUN, "--network", "tree:3", "--condition", "perfect", "-o", str(log)]
    argv.append("--view")
    status, stdout, stderr = run(argv, capfd)
    assert status == 0, stderr
    assert stdout.startswith(f"recorded {log} ") and "streamed" not in stdout
    assert "pipemap: note: the live view stopped before the end of the run" in stderr
    assert read_log(log).metadata[METADATA_RESULT]["status"] == "complete"
