"""``benchmarks/bench_score.py``: what it prints, not the times (those go in the
README). Run as a user runs it, on a stored log."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

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


@pytest.mark.parametrize(
    ("against", "flags"),
    [("no-odometry-check", "--no-odometry-check"), ("one-hypothesis", "--hypotheses 1")],
)
def test_it_compares_the_defaults_with_another_rule(against: str, flags: str) -> None:
    log = REPO / "recordings" / "random8_loops.mcap"
    done = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "bench_score.py"),
            str(log),
            "--repeat",
            "1",
            "--against",
            against,
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    label = re.escape(flags)
    assert re.search(rf"defaults / {label} \(CPU means\): \d+\.\d\dx", done.stdout)
    assert re.search(rf"^{label} +11 decisions", done.stdout, re.MULTILINE)
