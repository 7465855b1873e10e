"""``pipemap -v``: every decision on stderr as it is made, one line each, and nothing
of the kind without it; other libraries' debug messages stay out."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

from tests.cli.common import ROOT, run_subprocess
from tests.conftest import PAPER_SETS


def _debug_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("pipemap: DEBUG:")]


def test_replay_prints_each_decision(tmp_path: Path) -> None:
    log = str(ROOT / "recordings" / "paper_autonomous.mcap")
    quiet = run_subprocess(["replay", log], tmp_path)
    loud = run_subprocess(["-v", "replay", log], tmp_path)
    assert quiet.returncode == 0 and loud.returncode == 0, loud.stderr
    assert loud.stdout == quiet.stdout  # the same map
    assert _debug_lines(quiet.stderr) == []
    lines = _debug_lines(loud.stderr)
    visits = json.loads(loud.stdout)["visits"]
    assert len(lines) == len(visits) == 13
    for number, (line, visit) in enumerate(zip(lines, visits, strict=True), start=1):
        said = "known" if visit["known"] else "new"
        assert line.startswith(f"pipemap: DEBUG: visit {number}: junction {visit['node']} {said}")
        assert re.search(r"; \d+\.\d ms$", line), line
        if visit["two_view_inliers"] is not None:
            assert f"two-view {visit['two_view_inliers']} inliers" in line


def test_map_prints_each_folders_decision(tmp_path: Path) -> None:
    dirs = [str(PAPER_SETS / n) for n in ("1", "2", "1_noise")]
    done = run_subprocess(["-v", "map", *dirs], tmp_path)
    assert done.returncode == 0, done.stderr
    lines = _debug_lines(done.stderr)
    assert [line.split(": ")[2] for line in lines] == dirs
    assert [line.split(": ")[3].split(";")[0] for line in lines] == [
        "junction 0 new",
        "junction 1 new",
        "junction 0 known",
    ]


def test_record_prints_each_online_decision(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    # tree:3: 5 visits, each decision printed, in a cheap world.
    argv = ["-v", "record", "--network", "tree:3", "--resolution", "32", "-o", str(path)]
    done = subprocess.run(
        [sys.executable, "-m", "pipemap", *argv], capture_output=True, text=True, timeout=600
    )
    assert done.returncode in (0, 1), done.stderr  # 32 px: the map may come out wrong
    lines = _debug_lines(done.stderr)
    assert lines, done.stderr
    assert all(re.match(r"pipemap: DEBUG: visit \d+ at \d+\.\d s: junction \d+ ", x) for x in lines)
    visits = [int(line.split()[3]) for line in lines]
    assert visits == list(range(1, len(lines) + 1))
