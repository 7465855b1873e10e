"""``benchmarks/bench_match_memory.py``: what it prints, not the sizes (those go in
docs/performance.md). Run as a user runs it, at small sizes."""

from __future__ import annotations

import json
import subprocess
import sys

from tests.conftest import REPO


def test_it_measures_match_on_a_pair_of_sets_at_each_size() -> None:
    done = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "bench_match_memory.py"),
            "--sizes",
            "256",
            "384",
        ],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    runs = json.loads(done.stdout)["runs"]
    assert [r["side_px"] for r in runs] == [256, 384]
    for run in runs:
        assert run["exit"] == 0
        assert run["peak_mib"] > run["images_gray_mib"] > 0
        ratio = run["peak_mib"] / run["images_gray_mib"]
        assert abs(run["x_images"] - ratio) < 0.1 * ratio
        assert run["cpu_s"] > 0
