"""A log opens in rerun as it is: rerun's own MCAP converter finds its images."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from recorder import Topic, read_log


def _rerun() -> str:
    found = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    assert Path(found).exists(), "the rerun CLI of rerun-sdk is not installed"
    return found


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "RERUN_ANALYTICS": "false"}  # no network, no first-run banner
    return subprocess.run([_rerun(), *args], capture_output=True, text=True, timeout=300, env=env)


def test_rerun_mcap_convert_decodes_the_camera_images(recorded_run: Path, tmp_path: Path) -> None:
    rrd = tmp_path / "run.rrd"
    done = _run("mcap", "convert", str(recorded_run), "-o", str(rrd))
    assert done.returncode == 0, done.stderr
    printed = _run("rrd", "print", str(rrd))
    assert printed.returncode == 0, printed.stderr
    rows = {"images": 0, "poses": 0}
    for line in printed.stdout.splitlines():
        match = re.search(r"with (\d+) rows .* - (\S+) - data columns: \[(.*)\]", line)
        if match is None:
            continue
        count, entity, columns = int(match[1]), match[2], match[3]
        if entity == Topic.IMAGE and "EncodedImage:blob" in columns:
            rows["images"] += count
        if entity == Topic.TRUE_POSE and "Transform3D:translation" in columns:
            rows["poses"] += count
    counts = read_log(recorded_run).counts
    # Every camera image arrives as an image, every true pose as a transform.
    assert rows == {"images": counts[Topic.IMAGE], "poses": counts[Topic.TRUE_POSE]}
    assert rows["images"] == 78
