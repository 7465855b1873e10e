"""The closer look's scripts, run as a user runs them: ``benchmarks/why_two_view.py``,
``compare_closer_look.py`` and ``two_view_pairs.py`` on a stored log, and
``bench_closer_look.py`` on its fixture."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from tests.conftest import REPO

STORED = REPO / "recordings" / "random8_loops.mcap"  # 96 px: no closer look is taken


def _run(script: str, *args: str) -> list[str]:
    command = [sys.executable, str(REPO / "benchmarks" / script), *args]
    return subprocess.check_output(command, text=True, timeout=600).splitlines()


def test_why_two_view_prints_the_stages_of_a_fit_and_saves_its_sweeps(tmp_path: Path) -> None:
    saved = tmp_path / "pair.npz"
    lines = _run("why_two_view.py", str(STORED), "9", "--save", str(saved))
    assert lines[0].endswith("visit 9: 1 fit(s) with a known junction")
    assert "junction 6 (first seen at visit 7)" in lines[1]
    assert sum("stage 4/4" in line for line in lines) == 2  # the check's and the closer look's
    assert lines[-2].startswith("  decision: junction 6 known")
    data = np.load(saved)
    assert list(data["visits"]) == [9, 7]
    assert data["frames_9"].shape == data["frames_7"].shape and data["frames_9"].dtype == np.uint8


def test_compare_closer_look_finds_nothing_to_change_at_96_px() -> None:
    (line,) = _run("compare_closer_look.py", str(STORED))
    assert line.startswith("random8_loops.mcap: 11 decisions, 0 closer look(s); 11 the same")
    assert "outcomes changed: none" in line and "with it: map correct" in line


def test_two_view_pairs_counts_pairs_of_one_and_of_different_junctions() -> None:
    lines = _run("two_view_pairs.py", str(STORED), "--guesses", "2")
    assert lines[0] == (
        "# random8_loops.mcap: 11 visits, 3 pairs of one junction, 28 of different "
        "junctions (2 guesses and none)"
    )
    assert len(lines) == 5 and all("inliers" in line for line in lines[1:])


def test_bench_closer_look_decides_the_return_known_with_it_and_new_without() -> None:
    lines = _run("bench_closer_look.py", "--repeat", "1")
    assert "2122 keypoints" in lines[2]
    assert lines[3].startswith("revisit, closer look on:") and lines[3].endswith(
        "known, 44 inliers"
    )
    assert lines[4].startswith("revisit, closer look off:") and lines[4].endswith("new")
    kept = [line.rsplit(", ", 1) for line in lines[5:7]]
    assert [k[0].split(":")[0] for k in kept] == [
        "new junction, closer_keeps_images on",
        "new junction, closer_keeps_images off",
    ]
    images, keypoints = (float(k[1].split()[0]) for k in kept)
    # one byte a pixel ORB sees (6 images, their kept 200 of 400 rows), and the counts
    assert abs(images - (6 * 200 * 400 + 24) / 1024) < 0.05 and keypoints < images / 4
