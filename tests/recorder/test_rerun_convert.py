"""A log opens in rerun as it is: rerun's own MCAP converter finds its images."""

from __future__ import annotations

import re
from pathlib import Path

from pipemap.recorder import Topic, read_log
from tests.logs import rerun_cli, sweeps_started


def test_rerun_mcap_convert_decodes_the_camera_images(recorded_run: Path, tmp_path: Path) -> None:
    rrd = tmp_path / "run.rrd"
    done = rerun_cli("mcap", "convert", str(recorded_run), "-o", str(rrd))
    assert done.returncode == 0, done.stderr
    printed = rerun_cli("rrd", "print", str(rrd))
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
    assert rows["images"] == 6 * sweeps_started(recorded_run) > 0
