"""``benchmarks/bench_explore.py``: the logs it keeps (``--keep``), not its results
(those go in the docs). Run as a user runs it, on the smallest loop network."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from pipemap.recorder import Topic, read_log
from tests.conftest import REPO


def test_keep_leaves_each_runs_log_with_the_decisions_the_line_counts(tmp_path: Path) -> None:
    keep = tmp_path / "logs"
    done = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "bench_explore.py"),
            *["--suite", "loops50", "--count", "1", "--resolution", "32", "--keep"],
            str(keep),
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    line = re.search(r"^random:10 seed 0 .* visits +(\d+) ", done.stdout, re.MULTILINE)
    assert line is not None, done.stdout
    assert [p.name for p in keep.iterdir()] == ["random10-seed0.mcap"]
    log = read_log(keep / "random10-seed0.mcap")
    decisions = [m for m in log.messages if m.topic == Topic.DECISION]
    assert len(decisions) == int(line.group(1))
