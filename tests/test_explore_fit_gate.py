"""``benchmarks/explore_fit_gate.py``: what it prints on a stored log, and how it
sorts the explorer's odometry signs. Run as a user runs it."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys

from pipemap.localizer import ExploreConfig, MapExplorer
from tests.conftest import REPO

SCRIPT = REPO / "benchmarks" / "explore_fit_gate.py"


def test_a_short_loop_log_has_no_fit_and_no_false_alarm() -> None:
    log = REPO / "recordings" / "random8_loops.mcap"
    done = subprocess.run(
        [sys.executable, str(SCRIPT), str(log), "--json"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    row = json.loads(done.stdout)
    # 11 visits, 8 junctions: three loops closed, too short to pin a drift down.
    assert (row["visits"], row["first_fitted"]) == (11, None)
    alarms = {k: v for k, v in row.items() if k.startswith(("raw_", "fitted_"))}
    assert alarms == {"raw_new": [], "raw_known": [], "fitted_new": [], "fitted_known": []}


def test_each_odometry_sign_is_counted_by_its_kind() -> None:
    spec = importlib.util.spec_from_file_location("explore_fit_gate", SCRIPT)
    assert spec is not None and spec.loader is not None
    gate = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gate)
    explorer = MapExplorer(ExploreConfig())
    explorer.inconsistencies += [
        "port conflict at node 2",
        "new junction 7 is 0.20 m from known junction 3 by odometry; port conflict",
        "junction 4 is 2.10 m from where it was by odometry",
    ]
    out: dict[str, list[int]] = {"new": [], "known": []}
    gate._alarms(explorer, 1, 9, out)
    assert out == {"new": [9], "known": [9]}
