"""Logs for the tests: recorded by ``pipemap record``, or written by our own writer."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipemap.recorder import LogWriter, Topic, read_log, schemas
from pipemap.recorder.messages import image_message, pose_message

#: Settings of the small recorded run the end-to-end tests share. Its counts (13
#: sweeps of 6 images, 13 visits) are pinned in tests/recorder/test_record_command.py
#: alone; the other tests take them from the log (:func:`sweeps_started`), so that a
#: change of the run changes one file.
SMALL_RUN = ["--network", "paper", "--resolution", "64", "--seed", "3"]


def record(output: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    """``pipemap record`` as a user runs it: a subprocess."""
    return subprocess.run(
        [sys.executable, "-m", "pipemap", "record", *SMALL_RUN, *extra, "-o", str(output)],
        capture_output=True,
        text=True,
        timeout=600,
    )


def recorded(folders: pytest.TempPathFactory, name: str, *extra: str) -> Path:
    """The small run with ``extra`` settings, recorded (it must finish) into a new
    temporary folder ``name``: for a module's fixtures."""
    path = folders.mktemp(name) / "run.mcap"
    done = record(path, *extra)
    assert done.returncode == 0, done.stderr
    return path


def sweeps_started(log: Path) -> int:
    """How many sweeps the log's camera started (each visit's, and each probe's)."""
    return sum(
        schemas.SweepCommand.FromString(m.data).phase == schemas.SweepCommand.START
        for m in read_log(log, keep=lambda topic: topic == Topic.SWEEP).messages
    )


def rerun_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """The ``rerun`` command of rerun-sdk, without analytics (no network, no banner)."""
    found = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    assert Path(found).exists(), "the rerun CLI of rerun-sdk is not installed"
    env = {**os.environ, "RERUN_ANALYTICS": "false"}
    return subprocess.run([found, *args], capture_output=True, text=True, timeout=300, env=env)


def write_synthetic_log(
    path: Path, messages: int = 600, chunk_bytes: int = 4096, image_px: int = 16
) -> list[str]:
    """A log of ranges, poses and (by default small) images of noise in many chunks;
    returns the topics written, in order."""
    rng = np.random.default_rng(7)
    topics: list[str] = []
    with (
        path.open("wb") as f,
        LogWriter(
            f, {"pipemap_version": "test", "network": "synthetic"}, chunk_bytes=chunk_bytes
        ) as writer,
    ):
        for i in range(messages):
            t = i * 10_000_000
            if i % 50 == 0:
                image = rng.integers(0, 255, (image_px, image_px, 3), dtype=np.uint8)
                writer.write(Topic.IMAGE, t, image_message(t, image))
                topics.append(Topic.IMAGE)
            elif i % 3 == 0:
                writer.write(Topic.TRUE_POSE, t, pose_message(t, 0.01 * i, 0.0, 0.1))
                topics.append(Topic.TRUE_POSE)
            else:
                ranges = schemas.Ranges(time_ns=t, front_m=0.5 + 1e-3 * i, front_left_m=0.2)
                writer.write(Topic.RANGES, t, ranges)
                topics.append(Topic.RANGES)
        writer.finish({"status": "finished"})
    return topics
