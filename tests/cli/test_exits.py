"""How every command ends when its standard output fails or a stop signal arrives
(``pipemap.cli.exits``): ``> /dev/full`` is one line and exit 3, a closed pipe ends
quietly with 141, and SIGINT, SIGTERM and SIGHUP stop a command alike, with 130, 143
and 129, one line, and no temporary file left behind. Each command runs as a user
runs it, in a subprocess, on the stored recordings and the paper's image sets.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import PAPER_SETS, REPO

LOG = REPO / "recordings" / "paper_active.mcap"
MAP = REPO / "recordings" / "paper_active.map.json"


def _commands(tmp: Path) -> dict[str, list[str]]:
    """A quick form of each command that prints something on standard output."""
    sets = [str(PAPER_SETS / "1"), str(PAPER_SETS / "2")]
    return {
        "help": ["--help"],
        "info": ["info", str(LOG)],
        "replay": ["replay", str(LOG)],
        "score": ["score", "--json", str(LOG)],
        "match": ["match", *sets],
        "map": ["map", *sets],
        "route": ["route", str(MAP), "--from", "0", "--to", "1"],
        "sim": ["sim", "--network", "tree:2", "--resolution", "32", "--save-sweeps", str(tmp)],
        "batch-report": ["batch-report", str(tmp / "missing")],
    }


def _pipemap(args: list[str], stdout: int, **kwargs: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args],
        stdout=stdout,
        stderr=subprocess.PIPE,
        text=True,
        timeout=300,
        **kwargs,  # type: ignore[arg-type]
    )


@pytest.mark.parametrize(
    "name", ["help", "info", "replay", "score", "match", "map", "route", "sim"]
)
def test_standard_output_on_a_full_disk_is_one_line_and_exit_3(name: str, tmp_path: Path) -> None:
    with open("/dev/full", "w") as full:
        done = _pipemap(_commands(tmp_path)[name], stdout=full.fileno())
    assert done.returncode == 3, done.stderr
    lines = done.stderr.splitlines()
    assert lines[-1] == "pipemap: error: standard output: cannot write (No space left on device)"
    assert "Traceback" not in done.stderr and "Exception ignored" not in done.stderr


@pytest.mark.parametrize("name", ["help", "info", "replay", "route"])
def test_a_closed_pipe_ends_quietly_with_141(name: str, tmp_path: Path) -> None:
    # The reader is gone before the command writes its first byte (`| head -c0`).
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        done = _pipemap(_commands(tmp_path)[name], stdout=write_end)
    finally:
        os.close(write_end)
    assert done.returncode == 141, done.stderr
    assert done.stderr == ""


def _wait_for(condition: object, process: subprocess.Popen[str], what: str) -> None:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if condition():  # type: ignore[operator]
            return
        if process.poll() is not None:
            raise AssertionError(f"the command ended before {what}: {process.communicate()}")
        time.sleep(0.05)
    process.kill()
    raise AssertionError(f"no {what} within 120 s")


@pytest.mark.parametrize(
    ("sig", "status"),
    [(signal.SIGTERM, 143), (signal.SIGHUP, 129), (signal.SIGINT, 130)],
    ids=["SIGTERM", "SIGHUP", "SIGINT"],
)
def test_a_stop_signal_mid_save_leaves_no_partial_file_and_one_line(
    sig: signal.Signals, status: int, tmp_path: Path
) -> None:
    target = tmp_path / "view.rrd"
    for _attempt in range(3):
        process = subprocess.Popen(
            [sys.executable, "-m", "pipemap", "view", str(LOG), "--save", str(target)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        _wait_for(lambda: any(tmp_path.glob(".view.rrd*")), process, "temporary .rrd file")
        # Frozen while the temporary file exists, so the signal lands mid-save; on a
        # quick machine the save may have ended before the freeze: then again.
        process.send_signal(signal.SIGSTOP)
        if process.poll() is None:
            break
        process.communicate()
        target.unlink(missing_ok=True)
    else:
        pytest.fail("the save always ended before the signal could be sent")
    process.send_signal(sig)
    process.send_signal(signal.SIGCONT)
    out, err = process.communicate(timeout=120)
    assert process.returncode == status, err
    assert err.splitlines() == [f"pipemap: interrupted ({sig.name})"]
    assert out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("sig", "status"), [(signal.SIGTERM, 143), (signal.SIGHUP, 129)], ids=["SIGTERM", "SIGHUP"]
)
def test_a_stop_signal_stops_a_replay_as_ctrl_c_does(
    sig: signal.Signals, status: int, tmp_path: Path
) -> None:
    target = tmp_path / "map.json"
    process = subprocess.Popen(
        [sys.executable, "-m", "pipemap", "-v", "replay", str(LOG), "-o", str(target)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert process.stderr is not None
    # -v prints a line per decision: the replay is under way once the first one is out.
    process.stderr.readline()
    process.send_signal(sig)
    out, err = process.communicate(timeout=120)
    assert process.returncode == status, err
    assert err.splitlines()[-1] == f"pipemap: interrupted ({sig.name})"
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []
