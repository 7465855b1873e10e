"""``benchmarks/bench_score.py``: what it prints, not the times (those go in the
README). Run as a user runs it, on a stored log."""

from __future__ import annotations

import re
import subprocess
import sys

from tests.conftest import REPO


def test_it_compares_the_two_rules_and_says_where_the_time_of_each_goes() -> None:
    log = REPO / "recordings" / "paper_autonomous.mcap"
    done = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "bench_score.py"), str(log), "--repeat", "1"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert re.search(r"defaults / --no-two-view \(CPU means\): \d+\.\d\dx", done.stdout)
    phases = {
        m["rule"]: {p: float(t) for p, t in re.findall(r"(\w+) (\d+\.\d)", m["spent"])}
        for m in re.finditer(
            r"^(?P<rule>\S+) +wall ms by phase \(mean\): (?P<spent>.*)$", done.stdout, re.MULTILINE
        )
    }
    assert set(phases) == {"defaults", "--no-two-view"}
    assert list(phases["defaults"]) == ["ncc", "keypoints", "check", "map"]
    # ORB runs only for the two-view check.
    assert phases["defaults"]["keypoints"] > 0.0 == phases["--no-two-view"]["keypoints"]


def test_it_compares_the_defaults_with_the_odometry_check_off() -> None:
    log = REPO / "recordings" / "random8_loops.mcap"
    done = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "bench_score.py"),
            str(log),
            "--repeat",
            "1",
            "--against",
            "no-odometry-check",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert re.search(r"defaults / --no-odometry-check \(CPU means\): \d+\.\d\dx", done.stdout)
    assert re.search(r"^--no-odometry-check +11 decisions", done.stdout, re.MULTILINE)


def test_it_compares_the_defaults_with_one_hypothesis() -> None:
    log = REPO / "recordings" / "random8_loops.mcap"
    done = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "bench_score.py"),
            str(log),
            "--repeat",
            "1",
            "--against",
            "one-hypothesis",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert re.search(r"defaults / --hypotheses 1 \(CPU means\): \d+\.\d\dx", done.stdout)
    assert re.search(r"^--hypotheses 1 +11 decisions", done.stdout, re.MULTILINE)
