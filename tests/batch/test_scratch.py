"""A task's folder: removed when the task ends, and swept by a later task when a
killed worker (a batch stopped by Ctrl-C) could not remove it."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from pipemap.batch.run import SCRATCH_PREFIX, run_recording, sweep_stale_folders
from pipemap.batch.spec import parse_spec


def _ended_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def _folder(root: Path, host: str, pid: int, tail: str) -> Path:
    path = root / f"{SCRATCH_PREFIX}{host}-{pid}-{tail}"
    path.mkdir()
    (path / "run.mcap").write_bytes(b"partial")
    return path


def test_only_folders_of_ended_processes_of_this_host_are_swept(tmp_path: Path) -> None:
    host, gone = socket.gethostname(), _ended_pid()
    stale = _folder(tmp_path, host, gone, "a1")
    live = _folder(tmp_path, host, os.getpid(), "b2")
    elsewhere = _folder(tmp_path, "other-host", gone, "c3")
    unrelated = tmp_path / f"{SCRATCH_PREFIX}notes"
    unrelated.mkdir()
    assert sweep_stale_folders(tmp_path) == [stale]
    assert not stale.exists()
    assert live.is_dir() and elsewhere.is_dir() and unrelated.is_dir()


def test_a_task_sweeps_what_a_killed_one_left_and_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    stale = _folder(tmp_path, socket.gethostname(), _ended_pid(), "x9")
    spec = parse_spec(
        "[grid]\nnetwork = ['paper']\ncondition = ['perfect']\nresolution = [32]\n", "t.toml"
    )
    outcome = run_recording(spec.points[:1])
    assert outcome["record"]["run_ok"]
    assert not stale.exists()
    assert list(tmp_path.iterdir()) == []  # its own folder gone too
