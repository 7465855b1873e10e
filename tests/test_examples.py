"""Every script in ``examples/`` runs as a user would run it, and says what it should."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run_example(name: str, *args: str, cwd: Path) -> str:
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / name), *args],
        cwd=cwd,  # not the repository: the installed pipemap must be what runs
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr == "", done.stderr
    return done.stdout


def test_every_example_is_tested() -> None:
    assert sorted(p.name for p in EXAMPLES.glob("*.py")) == [
        "map_image_sets.py",
        "replay_and_score.py",
    ]


def test_replay_and_score_example(tmp_path: Path) -> None:
    out = run_example("replay_and_score.py", cwd=tmp_path)
    lines = out.splitlines()
    assert lines[0].startswith("paper_autonomous.mcap: network paper, condition autonomous")
    assert sum(1 for line in lines if line.lstrip().startswith("visit ")) == 13
    assert "map: 7 junctions" in out
    assert "score (defaults): map correct" in out
    # The paper's threshold alone merges look-alike junctions of this 96 px log (its
    # quarter scale leaves 24x12 px images); the example prints that result as it is.
    assert "score (paper's rule): map " in out


def test_map_image_sets_example(tmp_path: Path, paper_sets: dict[str, object]) -> None:
    out = run_example("map_image_sets.py", cwd=tmp_path)
    lines = out.splitlines()
    # Sets 1 and 2 show the same junction from two entries; 4 and 10 are others.
    assert lines[0].split() == ["1:", "new", "junction", "best", "similarity", "-"]
    assert lines[2].split()[:4] == ["2:", "known", "junction", "0"]
    assert lines[3].split()[:3] == ["10:", "new", "junction"]
    assert lines[-1] == "3 junctions, 2 pipes"


@pytest.mark.parametrize("name", ["replay_and_score.py", "map_image_sets.py"])
def test_an_example_given_a_missing_input_says_so_in_one_line(name: str, tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / name), str(tmp_path / "missing")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("error: "), done.stderr
    assert "missing" in done.stderr
